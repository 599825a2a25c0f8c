// SPEC §10 zones: axis-aligned boxes in the base frame. The TCP is a sphere of
// tool.radius_mm, the link-frame origins 2..6 are points. A keep_in box must contain
// every sphere and point whole; a keep_out box must touch none -> else ZONE_VIOLATION
// naming the zone. A `reduced` box only makes reduced mode active while the TCP is in it.
#include <cmath>

#include "safestate/core/monitors.hpp"

namespace safestate::core {

namespace {

constexpr std::size_t kFirstLinkPoint = 2U;  // origins 2..6 (SPEC §10)

bool inside(const Zone& z, const Vec3& p) noexcept {
  return (p[0] >= z.min_mm[0]) && (p[0] <= z.max_mm[0]) && (p[1] >= z.min_mm[1]) && (p[1] <= z.max_mm[1]) &&
         (p[2] >= z.min_mm[2]) && (p[2] <= z.max_mm[2]);
}

float max_of(float a, float b) noexcept { return (a > b) ? a : b; }

// Keep-in: how far a sphere of radius r about p reaches beyond the box (<= 0 inside).
float beyond(const Zone& z, const Vec3& p, float r) noexcept {
  float worst = -1.0e30F;
  for (std::size_t k = 0; k < 3U; ++k) {
    worst = max_of(worst, max_of((z.min_mm[k] + r) - p[k], p[k] - (z.max_mm[k] - r)));
  }
  return worst;
}

// Keep-out: how deep a sphere of radius r about p reaches into the box (<= 0: apart).
float depth(const Zone& z, const Vec3& p, float r) noexcept {
  if (inside(z, p)) {
    float to_face = 1.0e30F;
    for (std::size_t k = 0; k < 3U; ++k) {
      const float d = (p[k] - z.min_mm[k] < z.max_mm[k] - p[k]) ? (p[k] - z.min_mm[k]) : (z.max_mm[k] - p[k]);
      to_face = (d < to_face) ? d : to_face;
    }
    // A point on the face itself touches: a sphere of radius 0 is "in" by a hair.
    return r + to_face + ((r > 0.0F) ? 0.0F : 1.0e-3F);
  }
  float d2 = 0.0F;
  for (std::size_t k = 0; k < 3U; ++k) {
    const float below = z.min_mm[k] - p[k];
    const float above = p[k] - z.max_mm[k];
    const float gap = max_of(max_of(below, above), 0.0F);
    d2 += gap * gap;
  }
  return r - std::sqrt(d2);
}

// The box around every point a zone is checked against (the TCP sphere, the link-frame
// origins 2..6), once per cycle. `known` is false when a coordinate is NaN.
struct Bounds {
  Vec3 lo;  // every member is written by bounds_of(): no zeroing first (a byte-wise
  Vec3 hi;  // memset in newlib-nano, a tenth of this monitor's cost on the Cortex-M4)
  bool known;
};

Bounds bounds_of(const ArmPose& p, float r) noexcept {
  Bounds b;  // NOLINT(cppcoreguidelines-pro-type-member-init,hicpp-member-init): each member written below
  float sum = 0.0F;  // NaN if any coordinate is (one test instead of eighteen)
  for (std::size_t k = 0; k < 3U; ++k) {
    b.lo[k] = p.tcp[k] - r;
    b.hi[k] = p.tcp[k] + r;
    sum += p.tcp[k];
  }
  for (std::size_t i = kFirstLinkPoint; i < kArmFrames; ++i) {
    for (std::size_t k = 0; k < 3U; ++k) {
      const float v = p.origin[i][k];
      b.lo[k] = (v < b.lo[k]) ? v : b.lo[k];
      b.hi[k] = (v > b.hi[k]) ? v : b.hi[k];
      sum += v;
    }
  }
  b.known = !std::isnan(sum);  // an infinity too can make it NaN: then per point, as for NaN
  return b;
}

// True when the zone is respected by every point in `b` for certain: a keep_out box that
// the bounds do not reach, a keep_in box that holds them whole. Then no per-point distance
// is needed: how far a zone is violated matters only when it is (recovery, SPEC §10).
bool clearly_respected(const Zone& z, const Bounds& b) noexcept {
  if (!b.known) {
    return false;
  }
  if (z.kind == ZoneKind::keep_out) {
    return (b.hi[0] < z.min_mm[0]) || (b.lo[0] > z.max_mm[0]) || (b.hi[1] < z.min_mm[1]) ||
           (b.lo[1] > z.max_mm[1]) || (b.hi[2] < z.min_mm[2]) || (b.lo[2] > z.max_mm[2]);
  }
  return (b.lo[0] >= z.min_mm[0]) && (b.hi[0] <= z.max_mm[0]) && (b.lo[1] >= z.min_mm[1]) &&
         (b.hi[1] <= z.max_mm[1]) && (b.lo[2] >= z.min_mm[2]) && (b.hi[2] <= z.max_mm[2]);
}

}  // namespace

float ZoneMonitor::outside_mm(const Zone& z, const ArmPose& p, float radius_mm) noexcept {
  if (z.kind == ZoneKind::reduced) {
    return 0.0F;
  }
  const bool keep_in = z.kind == ZoneKind::keep_in;
  float worst = keep_in ? beyond(z, p.tcp, radius_mm) : depth(z, p.tcp, radius_mm);
  for (std::size_t k = kFirstLinkPoint; k < kArmFrames; ++k) {
    const Vec3& o = p.origin[k];
    const float m = keep_in ? beyond(z, o, 0.0F) : depth(z, o, 0.0F);
    worst = (m > worst || m != m) ? m : worst;  // NaN wins: unknown is unsafe
  }
  return worst;
}

// @req LIM-ZONE
void ZoneMonitor::check(const LimitContext& c, LimitReport& r) noexcept {
  const std::size_t n = (c.limits.zone_count < kMaxZones) ? c.limits.zone_count : kMaxZones;
  // cppcheck-suppress knownConditionTrueFalse ; false positive of cppcheck 2.10: zone_count is data (0..16)
  if (n == 0U) {
    return;
  }
  const Bounds b = bounds_of(c.pose, c.limits.tool_radius_mm);
  // cppcheck-suppress knownConditionTrueFalse ; false positive of cppcheck 2.10: zone_count is data (0..16)
  for (std::size_t i = 0; i < n; ++i) {
    const Zone& z = c.limits.zones[i];
    if (z.kind == ZoneKind::reduced) {
      if (!r.in_reduced_zone && inside(z, c.pose.tcp)) {
        r.in_reduced_zone = true;
        r.reduced_zone = static_cast<std::uint8_t>(i + 1U);  // REDUCED_SPEED names it
      }
      continue;
    }
    // Far from the arm (the common case): respected, without the per-point distances. What
    // track_violation() would do with a respected zone: it is a limit again, not recovered.
    if (clearly_respected(z, b)) {
      track_[i].recovering = false;
      continue;
    }
    const float outside = outside_mm(z, c.pose, c.limits.tool_radius_mm);
    const bool trips = track_violation(track_[i], outside, c.powered, kWorseZoneMm);
    r.outside = r.outside || !(outside <= 0.0F);
    r.recovering = r.recovering || track_[i].recovering;
    if (trips && !r.zone.hit) {
      r.zone.hit = true;
      r.zone.detail.signal = Signal::zone;
      r.zone.detail.code = static_cast<std::uint16_t>(i);
    }
  }
}

}  // namespace safestate::core

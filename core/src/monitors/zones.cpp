// SPEC §10 zones: axis-aligned boxes in the base frame. The TCP is a sphere of
// tool.radius_mm, the link-frame origins 2..6 are points. A keep_in box must contain
// every sphere and point whole; a keep_out box must touch none -> else ZONE_VIOLATION
// naming the zone. A `reduced` box only makes reduced mode active while the TCP is in it.
#include <bit>
#include <cmath>
#include <limits>

#include "safestate/core/monitor.hpp"

namespace safestate::core {

namespace {

constexpr std::size_t kFirstLinkPoint = 2U;  // origins 2..6 (SPEC §10)

bool inside(const Zone& z, const Vec3& p) noexcept {
  return (p[0] >= z.min_mm[0]) && (p[0] <= z.max_mm[0]) && (p[1] >= z.min_mm[1]) && (p[1] <= z.max_mm[1]) &&
         (p[2] >= z.min_mm[2]) && (p[2] <= z.max_mm[2]);
}

float max_of(float a, float b) noexcept { return (a > b) ? a : b; }
float min_of(float a, float b) noexcept { return (a < b) ? a : b; }

// Keep-in: how far a sphere of radius r about p reaches beyond the box (<= 0 inside).
float beyond(const Zone& z, const Vec3& p, float r) noexcept {
  float worst = -1.0e30F;
  for (std::size_t k = 0; k < 3U; ++k) {
    worst = max_of(worst, max_of((z.min_mm[k] + r) - p[k], p[k] - (z.max_mm[k] - r)));
  }
  return worst;
}

// Keep-out: how deep a sphere of radius r about p reaches into the box (<= 0: apart; NaN
// for a point that is not a number, which the callers count as inside: unknown is unsafe).
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
    const float apart = max_of(below, above);
    const float gap = (apart < 0.0F) ? 0.0F : apart;  // NaN stays NaN: an unknown point is in
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
  // In six named scalars: on a Cortex-M4F at -Os the box stays in FPU registers instead of
  // a load, compare, store per coordinate (docs/performance.md, M4 instructions per cycle).
  float lx = p.tcp[0] - r;  // NOLINT(readability-isolate-declaration)
  float ly = p.tcp[1] - r;
  float lz = p.tcp[2] - r;
  float hx = p.tcp[0] + r;
  float hy = p.tcp[1] + r;
  float hz = p.tcp[2] + r;
  float sum = p.tcp[0] + p.tcp[1] + p.tcp[2];  // NaN if any coordinate is (one test instead of eighteen)
  for (std::size_t i = kFirstLinkPoint; i < kArmFrames; ++i) {
    const float x = p.origin[i][0];
    const float y = p.origin[i][1];
    const float z = p.origin[i][2];
    lx = min_of(x, lx);
    hx = max_of(x, hx);
    ly = min_of(y, ly);
    hy = max_of(y, hy);
    lz = min_of(z, lz);
    hz = max_of(z, hz);
    sum += x + y + z;
  }
  Bounds b;  // NOLINT(cppcoreguidelines-pro-type-member-init,hicpp-member-init): each member written below
  b.lo = {lx, ly, lz};
  b.hi = {hx, hy, hz};
  b.known = !std::isnan(sum);  // an infinity too can make it NaN: then per point, as for NaN
  return b;
}

// How far the zone is clear of the box `b` for certain, mm (<= 0: not clear for certain;
// then the per-point distances decide). For a keep_out box the first axis along which they
// are apart, by how much (one separating axis is proof; a smaller gap than the largest only
// means the zone is tested again sooner), for a keep_in box the smallest slack inside it.
// NaN bounds: never clear.
float clearance(const Zone& z, const Bounds& b) noexcept {
  if (!b.known) {
    return -1.0F;
  }
  if (z.kind == ZoneKind::keep_out) {
    for (std::size_t k = 0; k < 3U; ++k) {
      const float below = z.min_mm[k] - b.hi[k];
      if (below > 0.0F) {
        return below;
      }
      const float above = b.lo[k] - z.max_mm[k];
      if (above > 0.0F) {
        return above;
      }
    }
    return -1.0F;
  }
  float s = b.lo[0] - z.min_mm[0];
  s = min_of(s, z.max_mm[0] - b.hi[0]);
  s = min_of(s, b.lo[1] - z.min_mm[1]);
  s = min_of(s, z.max_mm[1] - b.hi[1]);
  s = min_of(s, b.lo[2] - z.min_mm[2]);
  return min_of(s, z.max_mm[2] - b.hi[2]);
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

void ZoneMonitor::restart() noexcept {
  travel_ = 0.0F;
  next_due_ = -1.0F;
  for (float& t : clear_until_) {
    t = -1.0F;  // below any travel: tested
  }
}

void ZoneMonitor::reset(const PreparedArm& arm, const Vec3& tcp_flange_mm) noexcept {
  // reach_k: the fixed offsets of every frame after joint k (joints k+1..6, the flange) plus
  // the TCP offset (L1 norms, above the straight-line distances): no point after joint k is
  // further from its axis, in any pose.
  const auto l1 = [](const Vec3& v) { return std::fabs(v[0]) + std::fabs(v[1]) + std::fabs(v[2]); };
  float tail = l1(tcp_flange_mm) + l1(arm.geometry.flange.origin_mm);
  for (std::size_t k = kAxes; k > 0U; --k) {
    reach_[k - 1U] = tail;
    tail += l1(arm.geometry.joint[k - 1U].frame.origin_mm);
  }
  cull_ = !std::isnan(tail) && !std::isinf(tail);
  restart();
  have_last_ = false;
}

// @req LIM-ZONE
void ZoneMonitor::check(const CycleView& v, Reporter& rep) noexcept {
  const SafetyLimits& l = *v.limits;
  const ArmPose& pose = *v.facts.pose;
  const JointArray& q = v.facts.q;
  LimitReport& r = rep.facts().limits;
  const std::size_t n = (l.zone_count < kMaxZones) ? l.zone_count : kMaxZones;
  // cppcheck-suppress knownConditionTrueFalse ; false positive of cppcheck 2.10: zone_count is data (0..16)
  if (n == 0U) {
    return;
  }
  float step = 0.0F;
  for (std::size_t k = 0; k < kAxes; ++k) {
    step += reach_[k] * std::fabs(q[k] - last_q_[k]);  // NaN q: NaN step
    last_q_[k] = q[k];
  }
  travel_ += step + kTravelFloorMm;
  if (!cull_ || !have_last_ || !(step <= kMaxStepMm) || !(travel_ <= kRebaseMm)) {
    restart();  // not set up, unknown, implausible or long: every zone is tested this cycle
  }
  have_last_ = true;
  const float travel = travel_;
  if (travel < next_due_) {
    // No keep_in / keep_out zone can have been reached: only the reduced ones are looked at.
    for (std::uint32_t m = reduced_mask_; m != 0U; m &= (m - 1U)) {  // each set bit, lowest first
      const auto i = static_cast<std::size_t>(std::countr_zero(m));
      if (inside(l.zones[i], pose.tcp)) {
        r.in_reduced_zone = true;
        r.reduced_zone = static_cast<std::uint8_t>(i + 1U);  // REDUCED_SPEED names it
        break;
      }
    }
    return;
  }
  const Bounds b = bounds_of(pose, l.tool_radius_mm);
  float next = std::numeric_limits<float>::max();
  std::uint16_t reduced = 0U;
  // cppcheck-suppress knownConditionTrueFalse ; false positive of cppcheck 2.10: zone_count is data (0..16)
  for (std::size_t i = 0; i < n; ++i) {
    const Zone& z = l.zones[i];
    if (z.kind == ZoneKind::reduced) {
      reduced = static_cast<std::uint16_t>(reduced | (1U << i));
      if (!r.in_reduced_zone && inside(z, pose.tcp)) {
        r.in_reduced_zone = true;
        r.reduced_zone = static_cast<std::uint8_t>(i + 1U);  // REDUCED_SPEED names it
      }
      continue;
    }
    // Far from the arm (the common case): respected, without the per-point distances, while
    // the points cannot have travelled the gap found when the zone was last tested.
    if (travel < clear_until_[i]) {
      next = min_of(next, clear_until_[i]);
      continue;  // track_[i].recovering was cleared when the gap was found
    }
    // What track_violation() would do with a respected zone: it is a limit again, not recovered.
    const float gap = clearance(z, b) - kGapMarginMm;
    if (gap > 0.0F) {
      clear_until_[i] = travel + gap;
      next = min_of(next, clear_until_[i]);
      track_[i].recovering = false;
      continue;
    }
    clear_until_[i] = -1.0F;
    next = -1.0F;
    const float outside = outside_mm(z, pose, l.tool_radius_mm);
    const bool trips = track_violation(track_[i], outside, v.powered, kWorseZoneMm);
    r.outside = r.outside || !(outside <= 0.0F);
    r.recovering = r.recovering || track_[i].recovering;
    if (trips) {
      AlarmDetail d{};
      d.signal = Signal::zone;
      d.code = static_cast<std::uint16_t>(i);
      rep.trip(AlarmId::ZONE_VIOLATION, d);  // the first zone of the cycle is named
    }
  }
  next_due_ = next;
  reduced_mask_ = reduced;
}

}  // namespace safestate::core

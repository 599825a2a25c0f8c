#include "safestate/motion/limits.hpp"

#include <cmath>

namespace safestate::motion {
namespace {

constexpr float kFar = 1.0e9F;  // the clearance of a limit that does not apply

float minf(float a, float b) noexcept { return (b < a) ? b : a; }
float maxf(float a, float b) noexcept { return (b > a) ? b : a; }
float absf(float x) noexcept { return (x < 0.0F) ? -x : x; }
float positive(float x) noexcept { return (x > 0.0F) ? x : 0.0F; }  // NaN -> 0

// Signed Euclidean distance from p to the box: > 0 outside, minus the distance to the
// nearest face inside. 1-Lipschitz in p, which path_clear relies on.
float signed_distance(const Vec3& p, const std::array<float, 3>& mn, const std::array<float, 3>& mx) noexcept {
  float outside = 0.0F;
  float inside = -kFar;
  for (std::size_t k = 0; k < 3; ++k) {
    const float e = maxf(mn[k] - p[k], p[k] - mx[k]);  // > 0: outside on this axis
    outside += positive(e) * positive(e);
    inside = maxf(inside, e);
  }
  return std::sqrt(outside) + minf(inside, 0.0F);
}

}  // namespace

void LimitPlanner::configure(const core::SafetyLimits& limits, const RobotModel& model,
                             float robot_margin_rad) noexcept {
  model_ = model;
  for (std::size_t i = 0; i < kJoints; ++i) {
    const core::JointLimit& j = limits.joints[i];
    lo_[i] = maxf(model.q_min_rad[i] + robot_margin_rad, j.min_rad + kJointMarginRad);
    hi_[i] = minf(model.q_max_rad[i] - robot_margin_rad, j.max_rad - kJointMarginRad);
    qd_[i] = minf(model.qd_max_rad_s[i], kSpeedFactor * positive(j.max_speed_rad_s));
  }
  const float tcp_len = std::sqrt((model.tcp_offset_mm[0] * model.tcp_offset_mm[0]) +
                                  (model.tcp_offset_mm[1] * model.tcp_offset_mm[1]) +
                                  (model.tcp_offset_mm[2] * model.tcp_offset_mm[2]));
  float chain = tcp_len;
  for (std::size_t k = kJoints; k-- > 0U;) {  // lever_j: from axis j (joint j's origin) to the TCP
    const Vec3f& o = (k + 1U < kJoints) ? model.joints[k + 1U].origin.xyz_mm : model.flange.xyz_mm;
    chain += absf(o[0]) + absf(o[1]) + absf(o[2]);
    lever_[k] = chain;
  }
  tcp_ = kSpeedFactor * positive(limits.tcp_max_speed_mm_s);
  tcp_reduced_ = kSpeedFactor * minf(positive(limits.reduced_tcp_max_speed_mm_s), positive(limits.tcp_max_speed_mm_s));
  ramp_s_ = static_cast<float>(limits.reduced_ramp_ms) * 0.001F;
  radius_ = positive(limits.tool_radius_mm);
  zone_count_ = (limits.zone_count <= core::kMaxZones) ? limits.zone_count : static_cast<std::uint8_t>(core::kMaxZones);
  zones_ = limits.zones;
  cartesian_ = false;
  for (std::size_t z = 0; z < zone_count_; ++z) {
    cartesian_ = cartesian_ || (zones_[z].kind != core::ZoneKind::reduced);
  }
  const Vec3& a = limits.orientation_axis;
  const float n = std::sqrt((a[0] * a[0]) + (a[1] * a[1]) + (a[2] * a[2]));
  orientation_ = limits.orientation_enabled && (n > 0.0F);
  if (orientation_) {
    axis_ = {a[0] / n, a[1] / n, a[2] / n};
    max_dev_ = limits.orientation_max_deviation_rad;
  }
  cartesian_ = cartesian_ || orientation_;
  configured_ = true;
}

void LimitPlanner::clearance(const Frames& f, Clearance& out) const noexcept {
  for (std::size_t z = 0; z < core::kMaxZones; ++z) {
    const bool applies = (z < zone_count_) && (zones_[z].kind != core::ZoneKind::reduced);
    for (std::size_t p = 0; p < kZonePoints; ++p) {
      if (!applies) {
        out.zone_mm[z][p] = kFar;
        continue;
      }
      const bool tcp = (p == kZonePoints - 1U);
      const Vec3& at = tcp ? f.tcp : f.origin[p + 2U];  // link-frame origins 2..6, then the TCP
      const float r = tcp ? radius_ : 0.0F;
      const float sd = signed_distance(at, zones_[z].min_mm, zones_[z].max_mm);
      out.zone_mm[z][p] = (zones_[z].kind == core::ZoneKind::keep_in) ? (-sd - r) : (sd - r);
    }
  }
  out.orientation_rad = kFar;
  if (orientation_) {
    const float c = (f.R[0][2] * axis_[0]) + (f.R[1][2] * axis_[1]) + (f.R[2][2] * axis_[2]);
    out.orientation_rad = max_dev_ - std::acos(maxf(-1.0F, minf(1.0F, c)));
  }
}

void LimitPlanner::margins(Clearance& thr) const noexcept {
  for (auto& zone : thr.zone_mm) {
    zone.fill(kZoneMarginMm);
  }
  thr.orientation_rad = kOrientationMarginRad;
}

void LimitPlanner::thresholds(const Joints& q, Clearance& thr) const noexcept {
  Frames f{};
  forward(model_, q, f);
  Clearance c{};
  clearance(f, c);
  for (std::size_t z = 0; z < core::kMaxZones; ++z) {
    for (std::size_t p = 0; p < kZonePoints; ++p) {
      thr.zone_mm[z][p] = minf(kZoneMarginMm, c.zone_mm[z][p]);
    }
  }
  thr.orientation_rad = minf(kOrientationMarginRad, c.orientation_rad);
}

bool LimitPlanner::slack(const Joints& q, const Clearance& thr, float& mm, float& rad) const noexcept {
  Frames f{};
  forward(model_, q, f);
  Clearance c{};
  clearance(f, c);
  mm = kFar;
  for (std::size_t z = 0; z < zone_count_; ++z) {
    for (std::size_t p = 0; p < kZonePoints; ++p) {
      const float s = c.zone_mm[z][p] - thr.zone_mm[z][p];
      mm = (s < mm || !std::isfinite(s)) ? s : mm;
    }
  }
  rad = c.orientation_rad - thr.orientation_rad;
  return (mm >= 0.0F) && (rad >= 0.0F);  // NaN anywhere: false
}

bool LimitPlanner::path_clear(const Joints& a, const Joints& b, const Clearance& thr,
                              std::uint32_t max_samples) const noexcept {
  if (!cartesian_) {
    return true;
  }
  Joints d{};
  float len_mm = 0.0F;   // the most any point moves over the whole path
  float len_rad = 0.0F;  // the most the tool axis turns
  for (std::size_t i = 0; i < kJoints; ++i) {
    d[i] = b[i] - a[i];
    len_mm += absf(d[i]) * lever_[i];
    len_rad += absf(d[i]);
  }
  float s = 0.0F;
  for (std::uint32_t n = 0; n < max_samples; ++n) {
    Joints q{};
    for (std::size_t i = 0; i < kJoints; ++i) {
      q[i] = a[i] + (d[i] * s);
    }
    float mm = 0.0F;
    float rad = 0.0F;
    if (!slack(q, thr, mm, rad)) {
      return false;
    }
    if (s >= 1.0F) {
      return true;
    }
    const float ds_mm = (len_mm > 0.0F) ? (maxf(mm, kStepFloorMm) / len_mm) : 1.0F;
    const float ds_rad = (len_rad > 0.0F) ? (maxf(rad, kStepFloorRad) / len_rad) : 1.0F;
    s = minf(1.0F, s + minf(ds_mm, ds_rad));
  }
  return false;
}

bool LimitPlanner::joints_inside(const Joints& q) const noexcept {
  for (std::size_t i = 0; i < kJoints; ++i) {
    if (!((q[i] >= lo_[i]) && (q[i] <= hi_[i]))) {
      return false;
    }
  }
  return true;
}

float tcp_scale(const RobotModel& model, const Joints& q, const Joints& qdot, float limit_mm_s) noexcept {
  if (!(limit_mm_s > 0.0F)) {
    return 0.0F;
  }
  PointSpeeds ps{};
  point_speeds(model, q, qdot, ps);
  const float v = ps.speed[kTcpPoint];
  if (!std::isfinite(v)) {
    return 0.0F;
  }
  return (v <= limit_mm_s) ? 1.0F : (limit_mm_s / v);
}

}  // namespace safestate::motion

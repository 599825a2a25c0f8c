// SPEC §11 formulas: see collaborative.hpp.
#include "safestate/core/collaborative.hpp"

#include <cmath>
#include <cstring>

namespace safestate::core {

namespace {

bool positive_finite(float x) noexcept { return std::isfinite(x) && (x > 0.0F); }

// v_h for a separation d: the configured speed, at least 2000 mm/s within 500 mm (ISO 13855).
float human_speed(float separation_mm, const SsmParams& p) noexcept {
  const bool near = !(separation_mm > kSsmNearMm);  // NaN counts as near
  return (near && (p.human_speed_mm_s < kHumanSpeedNearMmS)) ? kHumanSpeedNearMmS : p.human_speed_mm_s;
}

}  // namespace

bool parse_body_region(const char* name, BodyRegion& out) noexcept {
  if (name == nullptr) {
    return false;
  }
  for (const BodyRegionLimits& r : kBodyRegions) {
    if (std::strcmp(r.name, name) == 0) {
      out = r.id;
      return true;
    }
  }
  return false;
}

// @req COL-PFL
float pfl_speed_cap_mm_s(BodyRegion r, float robot_mass_kg, float payload_kg) noexcept {
  const BodyRegionLimits& b = body_region(r);
  const float m_r = (robot_mass_kg / 2.0F) + payload_kg;
  if (!transient_contact_allowed(r) || !positive_finite(robot_mass_kg) || !std::isfinite(payload_kg) ||
      (payload_kg < 0.0F) || !positive_finite(m_r)) {
    return 0.0F;
  }
  const float mu = 1.0F / ((1.0F / b.m_h_kg) + (1.0F / m_r));  // kg
  const float k_n_per_m = b.k_n_per_mm * 1000.0F;
  const float v_m_s = b.f_tr_n / std::sqrt(mu * k_n_per_m);
  return v_m_s * 1000.0F;
}

namespace {
// v_allowed(d) with the person's speed taken where `vh_at_mm` is (SPEC §11: at d itself).
float allowed_speed(float separation_mm, float vh_at_mm, const SsmParams& p, float limit_mm_s) noexcept {
  const float limit = (std::isfinite(limit_mm_s) && (limit_mm_s > 0.0F)) ? limit_mm_s : 0.0F;
  if (!std::isfinite(separation_mm) || (separation_mm < 0.0F) || !positive_finite(p.decel_mm_s2) ||
      !positive_finite(p.reaction_s)) {
    return 0.0F;
  }
  const float v_h = human_speed(vh_at_mm, p);
  const float a_tr = p.decel_mm_s2 * p.reaction_s;
  const float radicand =
      (v_h * v_h) + (a_tr * a_tr) + (2.0F * p.decel_mm_s2 * (separation_mm - p.intrusion_mm - p.uncertainty_mm));
  if (!(radicand > 0.0F)) {
    return 0.0F;
  }
  const float v = std::sqrt(radicand) - (v_h + a_tr);
  if (!(v > 0.0F)) {
    return 0.0F;
  }
  return (v < limit) ? v : limit;
}
}  // namespace

// @req COL-SSM
float ssm_allowed_speed_mm_s(float separation_mm, const SsmParams& p, float limit_mm_s) noexcept {
  return allowed_speed(separation_mm, separation_mm, p, limit_mm_s);
}

// @req COL-SSM-MOTION
float ssm_planning_speed_mm_s(float separation_mm, const SsmParams& p, float limit_mm_s) noexcept {
  const float lookahead = kHumanSpeedNearMmS * (positive_finite(p.reaction_s) ? p.reaction_s : 0.0F);
  return allowed_speed(separation_mm, separation_mm - lookahead, p, limit_mm_s);
}

float ssm_protective_distance_mm(float speed_mm_s, float separation_mm, const SsmParams& p) noexcept {
  const float v_h = human_speed(separation_mm, p);
  float t_s = 0.0F;      // the robot's stopping time v/a
  float braking = 0.0F;  // and distance v^2/(2a); both 0 without a deceleration
  if (positive_finite(p.decel_mm_s2)) {
    t_s = speed_mm_s / p.decel_mm_s2;
    braking = (speed_mm_s * t_s) / 2.0F;
  }
  return (v_h * (p.reaction_s + t_s)) + (speed_mm_s * p.reaction_s) + braking + p.intrusion_mm + p.uncertainty_mm;
}

}  // namespace safestate::core

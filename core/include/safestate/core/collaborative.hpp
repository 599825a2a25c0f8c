// Collaborative operation, SPEC §11 (ISO 10218-2:2025, formerly ISO/TS 15066): the body
// region table of power and force limiting and the two formulas the core and the motion
// layer share: the speed and separation monitoring limit v_allowed(d) and the transient
// contact speed cap v_pfl. Pure functions on floats: no heap, no state, no OS; the M4
// image builds them too.
//
// docs/collaborative.md's region table is generated from kBodyRegions (gen_docs), and the
// safety configuration's parser takes its region names from it: one table.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace safestate::core {

// ISO/TS 15066 Annex A body regions, in the order of SPEC §11.
enum class BodyRegion : std::uint8_t {
  skull, face, neck, back, chest, abdomen, pelvis, upper_arm, lower_arm, hand, thigh, lower_leg
};
inline constexpr std::size_t kBodyRegionCount = 12;

struct BodyRegionLimits {
  BodyRegion id;
  const char* name;       // as in the safety configuration (`pfl.body_region`)
  float f_qs_n;           // quasi-static contact force limit (N)
  float f_tr_n;           // transient contact force limit (N); 0: no transient contact allowed
  float k_n_per_mm;       // effective spring constant (N/mm)
  float m_h_kg;           // effective mass of the body region (kg)
};

// SPEC §11 (ISO/TS 15066 Annex A, F_tr = 2 x F_qs; skull and face: no transient contact).
inline constexpr std::array<BodyRegionLimits, kBodyRegionCount> kBodyRegions{{
    {BodyRegion::skull, "skull", 130.0F, 0.0F, 150.0F, 4.4F},
    {BodyRegion::face, "face", 65.0F, 0.0F, 75.0F, 4.4F},
    {BodyRegion::neck, "neck", 150.0F, 300.0F, 50.0F, 1.2F},
    {BodyRegion::back, "back", 210.0F, 420.0F, 35.0F, 40.0F},
    {BodyRegion::chest, "chest", 140.0F, 280.0F, 25.0F, 40.0F},
    {BodyRegion::abdomen, "abdomen", 110.0F, 220.0F, 10.0F, 40.0F},
    {BodyRegion::pelvis, "pelvis", 180.0F, 360.0F, 25.0F, 40.0F},
    {BodyRegion::upper_arm, "upper_arm", 150.0F, 300.0F, 30.0F, 3.0F},
    {BodyRegion::lower_arm, "lower_arm", 160.0F, 320.0F, 40.0F, 2.0F},
    {BodyRegion::hand, "hand", 140.0F, 280.0F, 75.0F, 0.6F},
    {BodyRegion::thigh, "thigh", 220.0F, 440.0F, 50.0F, 75.0F},
    {BodyRegion::lower_leg, "lower_leg", 130.0F, 260.0F, 60.0F, 75.0F},
}};

[[nodiscard]] constexpr const BodyRegionLimits& body_region(BodyRegion r) noexcept {
  return kBodyRegions[static_cast<std::size_t>(r) % kBodyRegionCount];
}
// Transient contact allowed (ISO/TS 15066: not for skull and face).
[[nodiscard]] constexpr bool transient_contact_allowed(BodyRegion r) noexcept {
  return body_region(r).f_tr_n > 0.0F;
}
// Name to region; false for an unknown name (nothing written).
[[nodiscard]] bool parse_body_region(const char* name, BodyRegion& out) noexcept;

// PFL transient speed cap (SPEC §11): v_pfl = F_tr / sqrt(mu * k), mu = (1/m_H + 1/m_R)^-1,
// m_R = robot_mass_kg / 2 + payload_kg, k in N/m; returned in mm/s. 0 for a region that
// allows no transient contact, and for masses that are not positive finite numbers.
[[nodiscard]] float pfl_speed_cap_mm_s(BodyRegion r, float robot_mass_kg, float payload_kg) noexcept;

// SSM parameters in the formula's units (SPEC §11): mm, mm/s, mm/s^2, s.
struct SsmParams {
  float human_speed_mm_s = 1600.0F;  // v_h; at d <= kSsmNearMm at least kHumanSpeedNearMmS
  float decel_mm_s2 = 0.0F;          // a, the robot's guaranteed deceleration
  float reaction_s = 0.0F;           // T_r, the whole chain
  float intrusion_mm = 0.0F;         // C
  float uncertainty_mm = 0.0F;       // Z
};
// ISO 13855: a person within 500 mm is assumed to move at 2000 mm/s.
inline constexpr float kSsmNearMm = 500.0F;
inline constexpr float kHumanSpeedNearMmS = 2000.0F;

// v_allowed(d) = sqrt(v_h^2 + (a T_r)^2 + 2 a (d - C - Z)) - (v_h + a T_r), clamped to
// [0, limit]. A separation that is not a finite number >= 0 counts as 0 (unknown is
// unsafe), as do parameters that are not positive (a, T_r).
[[nodiscard]] float ssm_allowed_speed_mm_s(float separation_mm, const SsmParams& p, float limit_mm_s) noexcept;

// What the motion layer plans to (SPEC §11 "scales the speed so that the TCP stays at or below
// v_allowed"): v_allowed(d) with v_h 2000 already within 500 mm + the distance a person
// covers at 2000 mm/s in T_r. v_allowed itself jumps down where d crosses 500 mm (v_h 1600 ->
// 2000); a robot still moving at v_allowed(501 mm) would then be one reaction's worth
// closer than S_p (the SSM benchmark measured 48 mm). Planned so, the speed is already
// v_allowed with v_h 2000 when the person reaches 500 mm: 0 there, continuously. Never above
// ssm_allowed_speed_mm_s; the monitor keeps judging against that.
[[nodiscard]] float ssm_planning_speed_mm_s(float separation_mm, const SsmParams& p, float limit_mm_s) noexcept;

// The protective separation distance S_p for a robot at speed v (SPEC §11 with T_s the
// stopping time v / a): v_h (T_r + T_s) + v T_r + v^2 / (2a) + C + Z, mm. The inverse of
// ssm_allowed_speed_mm_s (used by tests and the benchmark).
[[nodiscard]] float ssm_protective_distance_mm(float speed_mm_s, float separation_mm, const SsmParams& p) noexcept;

}  // namespace safestate::core

// The core's own forward kinematics (SPEC §10: the safe limits are monitored from the
// measured joint positions with the core's own model, never with values the motion
// layer hands over, so that a fault in the planner cannot blind the monitor).
//
// Written apart from motion/kinematics on purpose (diverse implementation, ISO 13849-1
// 7.2 common-cause thinking): frames are carried as three axis vectors and an origin,
// each joint applied as rotations of those vectors, no matrix products. The geometry
// (the Denavit-Hartenberg table) is data given at start-up; both implementations read
// the same robot, and a unit test compares them on random poses.
//
// Units: mm, rad, rad/s, mm/s. Float only, no heap: builds for a Cortex-M4.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/core/types.hpp"

namespace safestate::core {

using Vec3 = std::array<float, 3>;
using JointArray = std::array<float, kAxes>;

// One row of the standard (distal) DH convention:
// A_k = Rot_z(q_k + theta_offset) * Trans_z(d) * Trans_x(a) * Rot_x(alpha).
struct DhParam {
  float a_mm = 0.0F;
  float alpha_rad = 0.0F;
  float d_mm = 0.0F;
  float theta_offset_rad = 0.0F;
};

struct ArmGeometry {
  std::array<DhParam, kAxes> dh{};
};

// The geometry with what does not change from cycle to cycle computed once, at start-up
// (the cosines and sines of the constant alphas): what the cycle's arm_forward() reads.
enum class AlphaKind : std::uint8_t { general, zero, plus_half_pi, minus_half_pi };
struct PreparedArm {
  ArmGeometry geometry{};
  std::array<float, kAxes> cos_alpha{};
  std::array<float, kAxes> sin_alpha{};
  std::array<AlphaKind, kAxes> alpha_kind{};
};
[[nodiscard]] PreparedArm prepare_arm(const ArmGeometry& g) noexcept;

// sin(x) and cos(x) for the cycle (rad): x reduced by multiples of pi/2 (Cody-Waite, two
// constants), then Taylor polynomials on [-pi/4, pi/4] to degree 9 (sin) and 10 (cos).
// Absolute error below 1e-6 for |x| <= kSinCosFastRange (a test compares it with the
// library in double); beyond that, and for NaN and infinities, the library's sin/cos
// (NaN in, NaN out). About a fifth of newlib's sinf + cosf on a Cortex-M4F.
inline constexpr float kSinCosFastRange = 1000.0F;
void sin_cos(float x, float& s, float& c) noexcept;

// Frame k = 0 (base) .. 6 (flange): its origin and unit axes in the base frame.
inline constexpr std::size_t kArmFrames = kAxes + 1U;
struct ArmPose {
  std::array<Vec3, kArmFrames> origin{};
  std::array<Vec3, kArmFrames> z{};
  Vec3 tcp{};     // the tool's TCP (flange frame offset applied)
  Vec3 tool_z{};  // the tool's z axis (= the flange's)
};

// Pose of every frame and of the TCP at joint positions q; `tcp_flange_mm` is the TCP in
// the flange frame. The cycle uses the prepared form; the other prepares first (tests).
void arm_forward(const PreparedArm& g, const JointArray& q, const Vec3& tcp_flange_mm, ArmPose& out) noexcept;
void arm_forward(const ArmGeometry& g, const JointArray& q, const Vec3& tcp_flange_mm, ArmPose& out) noexcept;

// Linear speed (mm/s) of `point` when the joints turn at qd: |sum_k z_{k-1} x (point -
// o_{k-1}) qd_k| over the joints that move the point (the first `joints` of them).
// NaN in, NaN out: the callers compare with `!(v <= limit)`.
float point_speed(const ArmPose& pose, const Vec3& point, std::size_t joints, const JointArray& qd) noexcept;

}  // namespace safestate::core

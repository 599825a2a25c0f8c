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

// Frame k = 0 (base) .. 6 (flange): its origin and unit axes in the base frame.
inline constexpr std::size_t kArmFrames = kAxes + 1U;
struct ArmPose {
  std::array<Vec3, kArmFrames> origin{};
  std::array<Vec3, kArmFrames> x{};
  std::array<Vec3, kArmFrames> z{};
  Vec3 tcp{};     // the tool's TCP (flange frame offset applied)
  Vec3 tool_z{};  // the tool's z axis (= the flange's)
};

// Pose of every frame and of the TCP at joint positions q; `tcp_flange_mm` is the TCP in
// the flange frame.
void arm_forward(const ArmGeometry& g, const JointArray& q, const Vec3& tcp_flange_mm, ArmPose& out) noexcept;

// Linear speed (mm/s) of `point` when the joints turn at qd: |sum_k z_{k-1} x (point -
// o_{k-1}) qd_k| over the joints that move the point (the first `joints` of them).
// NaN in, NaN out: the callers compare with `!(v <= limit)`.
float point_speed(const ArmPose& pose, const Vec3& point, std::size_t joints, const JointArray& qd) noexcept;

}  // namespace safestate::core

// The core's own forward kinematics (SPEC §10: the safe limits are monitored from the
// measured joint positions with the core's own model, never with values the motion
// layer hands over, so that a fault in the planner cannot blind the monitor).
//
// Written apart from motion/kinematics on purpose (diverse implementation, ISO 13849-1
// 7.2 common-cause thinking): frames are carried as three axis vectors and an origin,
// each joint applied as rotations of those vectors, no matrix products. The geometry (a
// chain of six joints read from the robot's URDF, robot/) is data given at start-up; both
// implementations read the same robot, and unit tests compare them on random poses.
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
// Row-major: rotation[r][c]; column c is the child frame's axis c in the parent frame.
using Rotation3 = std::array<Vec3, 3>;
inline constexpr Rotation3 kIdentityRotation{{{1.0F, 0.0F, 0.0F}, {0.0F, 1.0F, 0.0F}, {0.0F, 0.0F, 1.0F}}};

// A frame fixed in its parent: a URDF joint's <origin> (xyz in mm, rpy as a rotation),
// with the fixed joints between two moving ones folded in.
struct ArmFrame {
  Vec3 origin_mm{};
  Rotation3 rotation = kIdentityRotation;
};

// Joint k of the chain: its frame in joint k-1's frame (the base link's for joint 1), at
// joint k-1's angle zero, and the unit axis it turns about, in its own frame. The flange is
// fixed in joint 6's frame. This is URDF's model of a serial arm (robot/ reads it).
struct ArmJoint {
  ArmFrame frame{};
  Vec3 axis{0.0F, 0.0F, 1.0F};
};

struct ArmGeometry {
  std::array<ArmJoint, kAxes> joint{};
  ArmFrame flange{};
};

// One row of the standard (distal) DH convention:
// A_k = Rot_z(q_k + theta_offset) * Trans_z(d) * Trans_x(a) * Rot_x(alpha). A DH table is one
// way to write a chain: arm_from_dh() turns it into the general form (joint k+1's frame is DH
// frame k, its axis z; the flange is DH frame 6). Start-up and tests only.
struct DhParam {
  float a_mm = 0.0F;
  float alpha_rad = 0.0F;
  float d_mm = 0.0F;
  float theta_offset_rad = 0.0F;
};
[[nodiscard]] ArmGeometry arm_from_dh(const std::array<DhParam, kAxes>& dh) noexcept;

// The geometry with what does not change from cycle to cycle worked out once, at start-up:
// which fixed rotations are the identity, which translations lie along one axis of their
// parent, which joint axes are an axis of their own frame (URDF's usual 1 0 0 / 0 1 0 /
// 0 0 1, or minus one of them). What the cycle's arm_forward() reads.
enum class AxisKind : std::uint8_t { x, y, z, minus_x, minus_y, minus_z, general };
enum class ShiftKind : std::uint8_t { none, x, y, z, general };
struct PreparedFrame {
  ShiftKind shift = ShiftKind::none;
  float shift_mm = 0.0F;  // the one non-zero coordinate when shift is x, y or z
  bool turned = false;    // rotation is not the identity
};
struct PreparedArm {
  ArmGeometry geometry{};
  std::array<PreparedFrame, kAxes> frame{};
  std::array<AxisKind, kAxes> axis_kind{};
  PreparedFrame flange{};
};
[[nodiscard]] PreparedArm prepare_arm(const ArmGeometry& g) noexcept;

// sin(x) and cos(x) for the cycle (rad): x reduced by multiples of pi/2 (Cody-Waite, two
// constants), then Taylor polynomials on [-pi/4, pi/4] to degree 9 (sin) and 10 (cos).
// Absolute error below 1e-6 for |x| <= kSinCosFastRange (a test compares it with the
// library in double); beyond that, and for NaN and infinities, the library's sin/cos
// (NaN in, NaN out). About a fifth of newlib's sinf + cosf on a Cortex-M4F.
inline constexpr float kSinCosFastRange = 1000.0F;
void sin_cos(float x, float& s, float& c) noexcept;

// Points k = 0..5: the origin of joint k+1's frame (a point on its axis; the link origins,
// moved by joints 1..k only) and that joint's unit axis, in the base frame; k = 6: the flange
// and its z axis.
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
// o_{k-1}) qd_k| over the joints that move the point (the first `joints` of them: k for
// origin[k], 6 for the flange and the TCP).
// NaN in, NaN out: the callers compare with `!(v <= limit)`.
float point_speed(const ArmPose& pose, const Vec3& point, std::size_t joints, const JointArray& qd) noexcept;

}  // namespace safestate::core

// Forward kinematics and exact point speeds of the arm in safestate/motion/robot.hpp.
// Built for the supervisor's scan loop and for a Cortex-M4: float only (single-precision
// FPU), no heap, no exceptions, every result written to caller-owned storage.
//
// Units: mm, rad, s. All vectors are in the base frame (the URDF's base link).
#pragma once

#include <array>
#include <cstdint>

#include "safestate/motion/robot.hpp"

namespace safestate::motion {

using Vec3 = std::array<float, 3>;
using Mat3 = std::array<Vec3, 3>;  // row-major: R[row][col]; columns are frame axes
using Joints = std::array<float, kJoints>;

struct Pose {
  Vec3 p;
  Mat3 R;
};

// Z-Y-X (yaw about z, then pitch about the rotated y, then roll about the rotated x):
// R = Rz(yaw) * Ry(pitch) * Rx(roll).
struct Rpy {
  float roll;
  float pitch;
  float yaw;
};

// Point numbering used by Frames and PointSpeeds: k = 0..5 = origin of joint k+1's frame
// (the link origins: 0 never moves, k is moved by joints 1..k only), 6 = the flange, 7 = TCP.
// On the IRB 120: 0 = base, 1 = on axis 2 (shoulder), 2 = on axis 3 (elbow), 3 = on axis 4
// at the elbow offset, 4 = 5 = wrist centre, 6 = flange centre (tool0).
inline constexpr std::size_t kPoints = kLinks + 1;
inline constexpr std::uint8_t kTcpPoint = 7;

struct Frames {
  std::array<Vec3, kLinks> origin;  // point k (above), mm
  std::array<Vec3, kLinks> z;       // joint k+1 turns about the unit z[k] through origin[k]; z[6]: the flange's z
  Vec3 tcp;                         // mm
  Mat3 R;  // TCP orientation; equals the flange's because the tool offset is a translation
};

struct PointSpeeds {
  std::array<Vec3, kPoints> velocity;  // mm/s, indexed by point number
  std::array<float, kPoints> speed;    // mm/s; a non-finite result is stored as +inf
  float max_speed;                     // mm/s; +inf if any input was not finite
  std::uint8_t fastest_point;          // 1..7, 0 if nothing moves; ties: most distal point
  std::uint8_t fastest_axis;           // link (= last joint moving it) of that point, 1..6; 0 if none
};

void forward(const RobotModel& model, const Joints& q, Frames& out) noexcept;

Pose tcp_pose(const Frames& frames) noexcept;

// At pitch = +-90 deg roll and yaw share one axis; yaw is then reported as 0.
Rpy to_rpy(const Mat3& R) noexcept;

void point_speeds(const RobotModel& model, const Joints& q, const Joints& qdot,
                  PointSpeeds& out) noexcept;

// For a caller that already holds the frames of q (saves one forward()).
void point_speeds(const Frames& frames, const Joints& qdot, PointSpeeds& out) noexcept;

// Factor to multiply qdot by so that no point (frame origins and TCP) exceeds
// limit_mm_s: min(1, limit / max_speed), exact because speeds are linear in qdot at fixed q.
// Returns 0 (stop) when limit_mm_s is not > 0 or when q/qdot hold NaN or inf.
float t1_scale(const RobotModel& model, const Joints& q, const Joints& qdot,
               float limit_mm_s) noexcept;

}  // namespace safestate::motion

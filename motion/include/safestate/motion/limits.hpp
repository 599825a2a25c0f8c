// The motion layer's side of the safe limits of SPEC §10: it plans inside the limits less
// the planning margins, so that in normal use the core's monitors (which trip at the
// limits themselves, from their own forward kinematics) never trip. Same rules as core/:
// float, no heap, no exceptions, no clock; every result written to caller-owned storage.
//
// Margins (SPEC §10 gives the first three; the fourth is ours):
//   joints       1 deg inside [min, max] (and inside the robot's own range less
//                MotionConfig::limit_margin_rad, whichever is tighter)
//   zones        10 mm: a keep_in box shrunk, a keep_out box grown, by 10 mm
//   speeds       5 %: every joint <= 0.95 max_speed, the TCP <= 0.95 of the normal or the
//                reduced TCP limit
//   orientation  1 deg inside orientation.max_deviation (our choice: the same angle as the
//                joints' margin; at the TCP radius of a typical tool, 150 mm, it is ~2.6 mm)
//
// Clearance, and what "worse" means (recovery, SPEC §10). Every Cartesian limit is a set of
// scalar clearances, each >= 0 while that limit holds, measured from the limit itself:
//   zone z, point p   p = the link-frame origins 2..6 (radius 0) and the TCP (radius
//                     tool.radius_mm); sd = signed Euclidean distance from the point to the
//                     box (> 0 outside, minus the distance to the nearest face inside):
//                     keep_in  c = -sd - radius   (the sphere whole inside the box)
//                     keep_out c =  sd - radius   (the sphere not touching the box)
//                     reduced  no clearance (a reduced zone changes the speed only)
//   orientation       c = max_deviation - angle(tool z axis, orientation.axis)   (rad)
// Joints are handled per axis in joint space: c = q - min and max - q.
// A motion makes a limit WORSE when, for any single (zone, point) pair, for the orientation,
// or for any joint, the clearance becomes smaller than it is now while it is below the
// margin. Not per zone: a point going deeper while another comes out is still worse. The
// planner never commands that (resolution: kStepFloorMm / kStepFloorRad between path
// samples). No tolerance is added to "now": one would let a held jog creep by it every
// cycle (tried: 0.05 mm a cycle crept straight through a zone). So a recovery jog (a limit violated,
// clearance < 0) can only move the joint back toward its range, the sphere toward the
// inside of a keep_in box or out of a keep_out box, the tool axis toward the cone.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/core/safety_limits.hpp"
#include "safestate/motion/kinematics.hpp"
#include "safestate/motion/robot.hpp"

namespace safestate::motion {

inline constexpr float kJointMarginRad = deg(1.0F);
inline constexpr float kZoneMarginMm = 10.0F;
inline constexpr float kSpeedFactor = 0.95F;
inline constexpr float kOrientationMarginRad = deg(1.0F);

// Path sampling (see path_clear): the next sample is as far as the clearance left allows,
// never closer than these (the most a point / the tool axis can go past a sample).
inline constexpr float kStepFloorMm = 0.5F;
inline constexpr float kStepFloorRad = 0.001F;

// Points checked against the zones: link-frame origins 2..6, then the TCP sphere.
inline constexpr std::size_t kZonePoints = 6;

struct Clearance {
  std::array<std::array<float, kZonePoints>, core::kMaxZones> zone_mm{};  // [zone][point]
  float orientation_rad = 0.0F;
};

class LimitPlanner {
 public:
  // `model` must already carry the tool's TCP (tcp_offset_mm = limits.tcp_mm);
  // `robot_margin_rad` keeps the bounds inside the robot's own range as well.
  void configure(const core::SafetyLimits& limits, const RobotModel& model, float robot_margin_rad) noexcept;

  [[nodiscard]] bool configured() const noexcept { return configured_; }
  [[nodiscard]] bool cartesian() const noexcept { return cartesian_; }  // any zone or orientation limit
  [[nodiscard]] float joint_lo(std::size_t i) const noexcept { return lo_[i]; }
  [[nodiscard]] float joint_hi(std::size_t i) const noexcept { return hi_[i]; }
  [[nodiscard]] float joint_speed(std::size_t i) const noexcept { return qd_[i]; }  // 0.95 x limit
  [[nodiscard]] float tcp_speed() const noexcept { return tcp_; }                   // 0.95 x normal
  [[nodiscard]] float reduced_tcp_speed() const noexcept { return tcp_reduced_; }  // 0.95 x reduced
  [[nodiscard]] float reduced_ramp_s() const noexcept { return ramp_s_; }

  // Every clearance of the pose in `frames` (unused zones and reduced zones: a large value).
  void clearance(const Frames& frames, Clearance& out) const noexcept;
  // What a motion starting at q must keep: the margin, or (where q is already inside the
  // margin) not worse than now.
  void thresholds(const Joints& q, Clearance& thr) const noexcept;
  // The margin everywhere (a program's waypoints and paths).
  void margins(Clearance& thr) const noexcept;

  // The straight joint-space path a -> b keeps every clearance >= thr (Cartesian limits
  // only; joints are linear along it and are checked at the ends by the caller).
  // Conservative advancement: at each sample the slack s = c - thr of every clearance
  // bounds how far the next sample may be; a point moves at most sum_j |dq_j| * lever_j
  // (lever_j: the chain length from axis j to the TCP, an upper bound of every point's
  // distance to that axis) and the tool axis at most sum_j |dq_j|, so nothing in between
  // is missed by more than kStepFloorMm / kStepFloorRad. More than max_samples samples:
  // false (the caller holds; bounded time).
  [[nodiscard]] bool path_clear(const Joints& a, const Joints& b, const Clearance& thr,
                                std::uint32_t max_samples) const noexcept;

  // q inside every joint's planning bounds.
  [[nodiscard]] bool joints_inside(const Joints& q) const noexcept;

 private:
  // Smallest slack over the zones (mm) and the orientation (rad); false if any is below 0.
  bool slack(const Joints& q, const Clearance& thr, float& mm, float& rad) const noexcept;

  RobotModel model_{};
  bool configured_ = false;
  bool cartesian_ = false;
  Joints lo_{};
  Joints hi_{};
  Joints qd_{};
  Joints lever_{};
  float tcp_ = 0.0F;
  float tcp_reduced_ = 0.0F;
  float ramp_s_ = 0.5F;
  float radius_ = 0.0F;
  std::uint8_t zone_count_ = 0;
  std::array<core::Zone, core::kMaxZones> zones_{};
  bool orientation_ = false;
  Vec3 axis_{0.0F, 0.0F, -1.0F};
  float max_dev_ = 0.0F;
};

// Factor (<= 1) to multiply qdot by so that the TCP alone runs at no more than limit_mm_s
// (the TCP limits of SPEC §10 concern the TCP, unlike T1 which limits every point).
// 0 when the limit is not > 0 or the speed is not finite.
float tcp_scale(const RobotModel& model, const Joints& q, const Joints& qdot, float limit_mm_s) noexcept;

}  // namespace safestate::motion

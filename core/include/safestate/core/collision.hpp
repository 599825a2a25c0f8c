// SPEC §11 collision detection (ISO 10218-2:2025 power and force limiting): the drives report
// their torque (CiA 402 0x6077, per mille of rated torque); the core compares it with its own
// model of the arm's gravity and inertia torques (a recursive Newton-Euler pass over the arm's
// chain, ArmGeometry, and its links' inertials, core/dynamics.hpp, both from the robot's
// description and prepared at start-up into one fixed-size table; each cycle in float: no heap,
// no state, builds for the M4) and estimates the external force at the TCP that explains the
// difference. Above the body region's quasi-static limit F_qs it is rule 8, COLLISION.
//
// The estimate: the residual r = tau_measured - tau_model is what an external force F at the
// TCP would cause, r = -J^T F (J: the TCP's translational Jacobian, 3 x 6). F is its damped
// least-squares solution, F = -(J J^T + lambda^2 I)^-1 J r: the damping (kDampingM, 1 cm)
// keeps a residual near a singular pose from being read as a huge force, and a residual on
// a joint that no force at the TCP can turn (axis 6 with the TCP on its axis) is ignored.
//
// The joint accelerations come from the drives' velocities, differenced over one cycle. On
// the simulated cell the model and the plant agree to float rounding; on a real arm friction,
// motor inertia and noise would need identification and a filtered observer (docs/collaborative.md).
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/arm.hpp"
#include "safestate/core/dynamics.hpp"
#include "safestate/core/interfaces.hpp"
#include "safestate/core/findings.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

struct CycleView;  // monitor.hpp
class Reporter;    // monitor.hpp

// The damping of the force estimate, m (see above).
inline constexpr float kDampingM = 0.01F;
// Cycles the estimate must stay above F_qs: a single sample (one late frame, one cycle's
// acceleration differenced over two) never stops the robot; two in a row do.
inline constexpr std::uint8_t kCollisionConfirmCycles = 2;

struct ArmDynamicsState {
  JointArray tau_nm{};                  // the model's joint torques, N m
  std::array<Vec3, kAxes> jacobian{};  // column k: d tcp / d q_k, m/rad (base frame)
  Vec3 tcp_m{};                         // the TCP, base frame, m
};

// Joint k of the model: where it sits in joint k-1's frame (the base's for joint 1), m, and
// its fixed rotation; its unit axis in its own frame; its link's inertial. `turned` and
// `axis_kind` are worked out at start-up (prepare_arm's): an identity rotation is skipped,
// an axis along +-x, +-y, +-z turns two of the frame's vectors, any other by Rodrigues.
struct DynamicsJoint {
  Vec3 origin_m{};
  Rotation3 rotation = kIdentityRotation;  // row-major; column c: the joint frame's axis c
  bool turned = false;
  Vec3 axis{0.0F, 0.0F, 1.0F};
  AxisKind axis_kind = AxisKind::z;
  LinkInertial inertial{};
};

// The arm as the collision estimator evaluates it: fixed-size, prepared once at start-up.
struct ArmDynamicsModel {
  std::array<DynamicsJoint, kAxes> joint{};
  Vec3 flange_origin_m{};  // the flange (the TCP's frame) in joint 6's frame
  Rotation3 flange_rotation = kIdentityRotation;
  JointArray rated_torque_nm{};
};

// Start-up: the chain (mm) and the links' inertials into the model (m). No heap.
[[nodiscard]] ArmDynamicsModel prepare_dynamics(const ArmGeometry& arm, const ArmInertials& inertials) noexcept;

// The model's joint torques for (q, qd, qdd) with `payload_kg` as a point mass at the TCP
// (`tcp_flange_mm`, in the flange frame), and the TCP's Jacobian.
void arm_dynamics(const ArmDynamicsModel& m, const JointArray& q, const JointArray& qd, const JointArray& qdd,
                  float payload_kg, const Vec3& tcp_flange_mm, ArmDynamicsState& out) noexcept;

// The external force at the TCP (N, base frame) that explains a torque residual (N m), by
// the damped least squares above. Returns its magnitude; NaN in, NaN out (over the limit).
float estimate_tcp_force(const ArmDynamicsState& s, const JointArray& residual_nm, Vec3& force_n) noexcept;

// The same from the drives' torque actual (per mille of `rated_torque_nm`) against the model
// `s` of this cycle's motion: the residual, then the estimate.
float tcp_force_from_drives(const Feedback& fb, const JointArray& rated_torque_nm, const ArmDynamicsState& s,
                            Vec3& force_n) noexcept;

struct CollisionReport {
  bool acting = false;     // collaborative and pfl on: detection in every mode (SPEC §11)
  bool evaluated = false;  // this cycle's torques were compared (the arm free, drives on)
  float force_n = 0.0F;    // the estimated external force at the TCP
  float limit_n = 0.0F;    // the region's F_qs
};

class CollisionMonitor {
 public:
  // The arm: its chain (`arm`, the one the safe limits use) and limits.inertials.
  void configure(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us) noexcept;
  // COLLISION (rule 8): over the limit kCollisionConfirmCycles in a row, only while the
  // drives hold the arm with its brakes released and no brake test pushes (OPERATIONAL
  // but BRAKE_TEST, or a Cat 2 stop): only then do the drives' torques follow the model.
  void check(const CycleView& v, Reporter& r) noexcept;
  [[nodiscard]] bool enabled() const noexcept { return enabled_; }

 private:
  bool enabled_ = false;
  ArmDynamicsModel model_{};
  float limit_n_ = 0.0F;
  float payload_kg_ = 0.0F;
  float inv_dt_ = 0.0F;
  Vec3 tcp_mm_{};
  JointArray qd_prev_{};
  bool have_prev_ = false;
  std::uint8_t over_ = 0;
};

}  // namespace safestate::core

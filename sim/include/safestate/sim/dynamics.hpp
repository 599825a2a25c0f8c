// The simulated arm's rigid-body dynamics (issue 20 item 4, issue 38): the joint torques the
// drives must apply for a motion of the arm under gravity, plus a force the environment
// exerts on the TCP. Orocos KDL's recursive Newton-Euler solver (ChainIdSolver_RNE) on a
// chain built from the robot's URDF (robot::Robot: joint frames, axes and each moving link's
// inertial with its fixed links folded in); Pinocchio checks it from outside, loading the same
// URDF itself (tests/integration/test_dynamics_vs_pinocchio.py). Not modelled: friction, motor (rotor)
// inertia, gear elasticity (docs/robot.md "Dynamics").
//
// Real-time use: the constructor and set_payload() allocate (KDL's chain and solvers);
// torques() and tcp() do not, every KDL array they touch is a member sized at construction
// (tests/unit/test_sim_dynamics_alloc.cpp counts). Not thread-safe: one instance per thread.
#pragma once

#include <array>
#include <cstddef>
#include <memory>

namespace safestate::robot {
struct Robot;
}

namespace safestate::sim {

inline constexpr std::size_t kDynAxes = 6;
using JointVec = std::array<double, kDynAxes>;
using Vec3 = std::array<double, 3>;

class ArmDynamics {
 public:
  // Builds the unloaded arm's chain (6 revolute segments) and its solvers: of the active
  // robot (robot::active()), or of `r`. "tool0" below is the robot's flange link.
  ArmDynamics();
  explicit ArmDynamics(const robot::Robot& r);
  ~ArmDynamics();
  // KDL's solvers keep a reference to the chain: the object stays where it was built.
  ArmDynamics(const ArmDynamics&) = delete;
  ArmDynamics& operator=(const ArmDynamics&) = delete;
  ArmDynamics(ArmDynamics&&) = delete;
  ArmDynamics& operator=(ArmDynamics&&) = delete;

  // A point mass `kg` at the TCP (`tcp_tool0_m`, in tool0 coordinates) added to link 6's
  // inertia. Rebuilds the chain and the solvers: start-up only. kg <= 0 (or not finite)
  // is the unloaded arm.
  void set_payload(double kg, const Vec3& tcp_tool0_m);

  // tau = ID(q, qd, qdd) - J_v(tcp)^T f_world: the torques (N m) the drives must apply for
  // this motion while the environment pushes the TCP point (`tcp_tool0_m`) with
  // `f_world_n` (N, base frame). A contact pushing against the motion makes the drives work
  // harder. False (tau_nm all NaN) when an input is not finite or KDL reports an error.
  bool torques(const JointVec& q, const JointVec& qd, const JointVec& qdd, const Vec3& f_world_n,
               const Vec3& tcp_tool0_m, JointVec& tau_nm) noexcept;

  // The TCP (`tcp_tool0_m` in tool0 coordinates) in the base frame, m.
  void tcp(const JointVec& q, const Vec3& tcp_tool0_m, Vec3& p_world_m) noexcept;

  // The simulated drives' rated torques, N m (their torque actual is per mille of these): the
  // description's efforts, the same numbers the core's collision model reads (robot::Robot::
  // inertials). A joint whose URDF gives no effort keeps the IRB 120's rating for its axis
  // (core::kIrb120Inertials), an arbitrary scale: PFL is refused on such an arm.
  [[nodiscard]] const JointVec& rated_torque_nm() const noexcept;

 private:
  struct Impl;  // KDL's chain, solvers and preallocated arrays (sim/src/dynamics.cpp)
  std::unique_ptr<Impl> impl_;
};

}  // namespace safestate::sim

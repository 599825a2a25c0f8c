#include "safestate/sim/dynamics.hpp"

#include <cmath>
#include <limits>

#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl/frames.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/rotationalinertia.hpp>
#include <kdl/segment.hpp>

#include "safestate/core/dynamics.hpp"
#include "safestate/robot/description.hpp"

namespace safestate::sim {
namespace {

constexpr unsigned int kN = kDynAxes;  // KDL sizes and indexes with unsigned int

double d(float v) noexcept { return static_cast<double>(v); }

KDL::Vector vec(const robot::Vec3d& v) noexcept { return {v[0], v[1], v[2]}; }

KDL::Rotation rot(const robot::Mat3d& r) noexcept {
  return {r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2]};
}

KDL::Frame frame(const robot::FrameD& f) noexcept { return {rot(f.R), vec(f.xyz_m)}; }

template <std::size_t N>
bool finite(const std::array<double, N>& v) noexcept {
  for (const double x : v) {
    if (!std::isfinite(x)) {
      return false;
    }
  }
  return true;
}

}  // namespace

struct ArmDynamics::Impl {
  KDL::Chain chain;
  // Both solvers keep a reference to `chain`; rebuilt with it in build().
  std::unique_ptr<KDL::ChainIdSolver_RNE> id;
  std::unique_ptr<KDL::ChainFkSolverPos_recursive> fk;
  KDL::JntArray q = KDL::JntArray(kN);
  KDL::JntArray qd = KDL::JntArray(kN);
  KDL::JntArray qdd = KDL::JntArray(kN);
  KDL::JntArray tau = KDL::JntArray(kN);
  KDL::Wrenches f_ext = KDL::Wrenches(kN, KDL::Wrench::Zero());
  KDL::Frame link6;
  KDL::Frame flange;  // the flange (tool0) in link 6's frame
  robot::Description desc;
  JointVec rated{};

  explicit Impl(const robot::Robot& r) : flange(frame(r.d.flange_frame)), desc(r.d) {
    for (std::size_t k = 0; k < kDynAxes; ++k) {
      const double e = r.d.joints[k].effort_nm;
      rated[k] = (e > 0.0) ? e : d(core::kIrb120Inertials.rated_torque_nm[k]);
    }
  }

  // A point in flange (tool0) coordinates, in link 6's frame.
  [[nodiscard]] KDL::Vector in_link6(const Vec3& p) const noexcept { return flange * KDL::Vector(p[0], p[1], p[2]); }

  void build(double payload_kg, const Vec3& payload_tool0_m) {
    KDL::Chain c;
    for (std::size_t k = 0; k < kDynAxes; ++k) {
      const robot::Joint& j = desc.joints[k];
      const KDL::Frame origin = frame(j.origin);
      // Joint k turns about `axis` (in its own frame, placed at `origin` in joint k-1's) through
      // the origin's point. KDL's Joint(origin, axis) takes both in the segment's root frame
      // (joint k-1's) and stores f_tip relative to the joint's pose at q = 0, so passing
      // `origin` as the tip makes the segment's tip frame joint k's (its child link's) frame.
      const KDL::Joint joint(origin.p, origin.M * vec(j.axis), KDL::Joint::RotAxis);
      const robot::Inertial& in = j.inertial;
      const KDL::RotationalInertia ic(in.inertia[0][0], in.inertia[1][1], in.inertia[2][2], in.inertia[0][1],
                                      in.inertia[0][2], in.inertia[1][2]);
      KDL::RigidBodyInertia inertia(in.mass_kg, vec(in.com_m), ic);  // about the COM, moved to the origin
      if (k + 1 == kDynAxes && std::isfinite(payload_kg) && payload_kg > 0.0) {
        inertia = inertia + KDL::RigidBodyInertia(payload_kg, in_link6(payload_tool0_m));
      }
      c.addSegment(KDL::Segment(joint, origin, inertia));
    }
    id.reset();
    fk.reset();
    chain = c;
    id = std::make_unique<KDL::ChainIdSolver_RNE>(chain, KDL::Vector(0.0, 0.0, -d(core::kGravityM_S2)));
    fk = std::make_unique<KDL::ChainFkSolverPos_recursive>(chain);
  }

  // Link 6's frame in the base frame at q (q already copied into `q`).
  bool link6_frame() noexcept { return fk->JntToCart(q, link6) >= 0; }
};

ArmDynamics::ArmDynamics() : ArmDynamics(robot::active()) {}

ArmDynamics::ArmDynamics(const robot::Robot& r) : impl_(std::make_unique<Impl>(r)) {
  impl_->build(0.0, Vec3{0.0, 0.0, 0.0});
}

ArmDynamics::~ArmDynamics() = default;

const JointVec& ArmDynamics::rated_torque_nm() const noexcept { return impl_->rated; }

void ArmDynamics::set_payload(double kg, const Vec3& tcp_tool0_m) { impl_->build(kg, tcp_tool0_m); }

bool ArmDynamics::torques(const JointVec& q, const JointVec& qd, const JointVec& qdd, const Vec3& f_world_n,
                          const Vec3& tcp_tool0_m, JointVec& tau_nm) noexcept {
  tau_nm.fill(std::numeric_limits<double>::quiet_NaN());
  if (!finite(q) || !finite(qd) || !finite(qdd) || !finite(f_world_n) || !finite(tcp_tool0_m)) {
    return false;
  }
  Impl& m = *impl_;
  for (std::size_t i = 0; i < kDynAxes; ++i) {
    const auto r = static_cast<unsigned int>(i);
    m.q(r) = q[i];
    m.qd(r) = qd[i];
    m.qdd(r) = qdd[i];
  }
  if (!m.link6_frame()) {
    return false;
  }
  // KDL's RNE (ChainIdSolver_RNE::CartToJnt) computes f_i = I a + v x* I v - f_ext[i]:
  // f_ext[i] is the wrench the environment applies to segment i, in segment i's frame, about
  // segment i's origin. The environment's force on the TCP, in link 6's frame, with its
  // moment about link 6's origin, therefore gives tau = ID - J^T f (checked numerically by
  // tests/unit/test_sim_dynamics.cpp against finite differences of tcp()).
  const KDL::Vector f6 = m.link6.M.Inverse(KDL::Vector(f_world_n[0], f_world_n[1], f_world_n[2]));
  const KDL::Vector r6 = m.in_link6(tcp_tool0_m);
  m.f_ext[kDynAxes - 1] = KDL::Wrench(f6, r6 * f6);
  const int rc = m.id->CartToJnt(m.q, m.qd, m.qdd, m.f_ext, m.tau);
  m.f_ext[kDynAxes - 1] = KDL::Wrench::Zero();
  if (rc < 0) {
    return false;
  }
  for (std::size_t i = 0; i < kDynAxes; ++i) {
    tau_nm[i] = m.tau(static_cast<unsigned int>(i));
  }
  return true;
}

void ArmDynamics::tcp(const JointVec& q, const Vec3& tcp_tool0_m, Vec3& p_world_m) noexcept {
  Impl& m = *impl_;
  for (std::size_t i = 0; i < kDynAxes; ++i) {
    m.q(static_cast<unsigned int>(i)) = q[i];
  }
  if (!m.link6_frame()) {
    p_world_m.fill(std::numeric_limits<double>::quiet_NaN());
    return;
  }
  const KDL::Vector p = m.link6 * m.in_link6(tcp_tool0_m);
  p_world_m = {p.x(), p.y(), p.z()};
}

}  // namespace safestate::sim

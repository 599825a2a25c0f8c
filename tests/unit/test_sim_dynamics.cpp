// The simulated arm's rigid-body dynamics (sim::ArmDynamics, KDL's RNE on the built-in IRB 120's
// description) against hand computations from its numbers (motion::kRobot's joint origins,
// core::kIrb120Inertials' masses and centres of mass): gravity about axis 1 at home, axis 2's gravity
// torque with the arm turned forward, the external force's torques as -J^T f with J from
// finite differences of tcp() (this pins KDL's f_ext convention), and the payload's lever.
// Pinocchio checks the inertial terms on random states (tests/integration/
// test_dynamics_vs_pinocchio.py).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

#include "safestate/core/dynamics.hpp"
#include "safestate/motion/kinematics.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/sim/dynamics.hpp"

using safestate::sim::ArmDynamics;
using safestate::sim::JointVec;
using safestate::sim::Vec3;
namespace core = safestate::core;

namespace {

constexpr double kPi = 3.14159265358979323846;
const JointVec kZero{0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
const Vec3 kNoForce{0.0, 0.0, 0.0};
const Vec3 kTool0{0.0, 0.0, 0.0};

double d(float v) { return static_cast<double>(v); }
double g() { return d(core::kGravityM_S2); }
// Joint j's origin (1-based) in joint j-1's frame, m; every IRB 120 frame is parallel at q = 0.
double origin(std::size_t j, std::size_t c) {
  return d(safestate::motion::kRobot.joints[j - 1].origin.xyz_mm[c]) / 1000.0;
}
const core::LinkInertial& link(std::size_t k) { return core::kIrb120Inertials.link[k - 1]; }

JointVec gravity(ArmDynamics& dyn, const JointVec& q, const Vec3& tcp = kTool0) {
  JointVec tau{};
  EXPECT_TRUE(dyn.torques(q, kZero, kZero, kNoForce, tcp, tau));
  return tau;
}

// Centre of mass of link k (1-based, k >= 2) in link 2's coordinates with q3..q6 = 0 (every
// frame from link 2 on is then parallel to link 2's): joint origins 3..k plus com_k.
std::array<double, 3> com_in_link2(std::size_t k) {
  std::array<double, 3> p{0.0, 0.0, 0.0};
  for (std::size_t j = 3; j <= k; ++j) {
    for (std::size_t c = 0; c < 3; ++c) p[c] += origin(j, c);
  }
  for (std::size_t c = 0; c < 3; ++c) p[c] += d(link(k).com_m[c]);
  return p;
}

// The flange's (tool0's) origin in link 2's coordinates with q3..q6 = 0.
std::array<double, 3> link6_in_link2() {
  std::array<double, 3> p{0.0, 0.0, 0.0};
  for (std::size_t j = 3; j <= 6; ++j) {
    for (std::size_t c = 0; c < 3; ++c) p[c] += origin(j, c);
  }
  for (std::size_t c = 0; c < 3; ++c) p[c] += d(safestate::motion::kRobot.flange.xyz_mm[c]) / 1000.0;
  return p;
}

void expect_rel(double actual, double expected, double rel, const char* what) {
  EXPECT_NEAR(actual, expected, rel * std::abs(expected)) << what;
}

}  // namespace

TEST(ArmDynamics, TcpAtHomeIsTheFlangeOfTheDescription) {
  ArmDynamics dyn;
  Vec3 p{};
  dyn.tcp(kZero, kTool0, p);
  // tool0's origin: the sum of the joint origins and the flange's offset (the IRB 120's joint
  // frames are all parallel at q = 0, examples/robots/abb_irb120.urdf).
  const safestate::robot::Robot& r = safestate::robot::active();
  std::array<double, 3> o{0.0, 0.0, 0.0};
  for (const auto& j : r.d.joints) {
    for (std::size_t c = 0; c < 3; ++c) o[c] += j.origin.xyz_m[c];
  }
  for (std::size_t c = 0; c < 3; ++c) o[c] += r.d.flange_frame.xyz_m[c];
  for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(p[c], o[c], 1e-12) << c;
  EXPECT_NEAR(p[0], 0.374, 1e-6);  // 302 + 72 mm forward
  EXPECT_NEAR(p[2], 0.630, 1e-6);  // 290 + 270 + 70 mm up
  // tool0 z is link 6 x (forward at home), tool0 x is link 6 -z (down at home).
  dyn.tcp(kZero, Vec3{0.0, 0.0, 0.1}, p);
  EXPECT_NEAR(p[0], o[0] + 0.1, 1e-12);
  EXPECT_NEAR(p[2], o[2], 1e-12);
  dyn.tcp(kZero, Vec3{0.1, 0.0, 0.0}, p);
  EXPECT_NEAR(p[0], o[0], 1e-12);
  EXPECT_NEAR(p[2], o[2] - 0.1, 1e-12);
  dyn.tcp(kZero, Vec3{0.0, 0.1, 0.0}, p);
  EXPECT_NEAR(p[1], o[1] + 0.1, 1e-12);
}

TEST(ArmDynamics, TheChainIsTheDhModelsArmAtEveryPose) {
  // The table's header says the joint angles and signs are the DH model's: the KDL chain's
  // tool0 (position and axes) must be motion::forward()'s frame 6 (= tool0) for any q.
  ArmDynamics dyn;
  std::mt19937 rng(4);
  for (int trial = 0; trial < 200; ++trial) {
    safestate::motion::Joints qf{};
    JointVec q{};
    for (std::size_t i = 0; i < 6; ++i) {
      const float lo = safestate::motion::kRobot.q_min_rad[i];
      const float hi = safestate::motion::kRobot.q_max_rad[i];
      qf[i] = std::uniform_real_distribution<float>(lo, hi)(rng);
      q[i] = d(qf[i]);
    }
    safestate::motion::Frames frames{};
    safestate::motion::forward(safestate::motion::kRobot, qf, frames);
    Vec3 p{};
    dyn.tcp(q, kTool0, p);
    for (std::size_t c = 0; c < 3; ++c) {
      EXPECT_NEAR(p[c] * 1000.0, d(frames.origin[6][c]), 5e-3) << "trial " << trial << " coordinate " << c;
    }
    // tool0's axis a in the base frame: the TCP moved 1 m along it, minus the flange.
    for (std::size_t a = 0; a < 3; ++a) {
      Vec3 off{0.0, 0.0, 0.0};
      off[a] = 1.0;
      Vec3 pa{};
      dyn.tcp(q, off, pa);
      for (std::size_t c = 0; c < 3; ++c) {
        EXPECT_NEAR(pa[c] - p[c], d(frames.R[c][a]), 1e-5) << "trial " << trial << " axis " << a;
      }
    }
  }
}

TEST(ArmDynamics, GravityAtHomeLeavesAxisOneAlone) {
  ArmDynamics dyn;
  const JointVec tau = gravity(dyn, kZero);
  // Gravity is parallel to axis 1: no moment about it, whatever the masses.
  EXPECT_NEAR(tau[0], 0.0, 1e-12);
  // Every axis 1 pose gives the same (axis 1 is vertical).
  const JointVec tau_turned = gravity(dyn, JointVec{1.0, 0.0, 0.0, 0.0, 0.0, 0.0});
  EXPECT_NEAR(tau_turned[0], 0.0, 1e-12);
  for (std::size_t i = 1; i < 6; ++i) EXPECT_NEAR(tau_turned[i], tau[i], 1e-9) << i;
}

TEST(ArmDynamics, AxisTwoGravityWithTheArmForwardIsSumOfMassTimesLever) {
  ArmDynamics dyn;
  const JointVec q{0.0, kPi / 2.0, 0.0, 0.0, 0.0, 0.0};
  const JointVec tau = gravity(dyn, q);
  // q2 = +90 deg turns link 2 about +y: its z goes to the base's +x, its x to -z. Each link's
  // centre of mass (k = 2..6) is then at base x = its z in link 2's coordinates (joint 2
  // sits on the base's z axis). Gravity's moment about +y is m g x, so the drive holds with
  // tau2 = -g sum(m_k x_k).
  double sum = 0.0;
  for (std::size_t k = 2; k <= 6; ++k) sum += d(link(k).mass_kg) * com_in_link2(k)[2];
  const double expected = -g() * sum;
  expect_rel(tau[1], expected, 1e-6, "axis 2");
  EXPECT_LT(tau[1], -10.0);  // some 20 N m of unloaded arm held forward
  // Axis 3 holds links 3..6 about joint 3 (base x 0.27 from joint 2's).
  double sum3 = 0.0;
  const double x3 = origin(3, 2);
  for (std::size_t k = 3; k <= 6; ++k) sum3 += d(link(k).mass_kg) * (com_in_link2(k)[2] - x3);
  expect_rel(tau[2], -g() * sum3, 1e-6, "axis 3");
  // The same with q2 = 0 (upper arm up): axis 2 now holds the forearm's forward lever only.
  const JointVec tau0 = gravity(dyn, kZero);
  double sum0 = 0.0;
  for (std::size_t k = 2; k <= 6; ++k) sum0 += d(link(k).mass_kg) * com_in_link2(k)[0];
  expect_rel(tau0[1], -g() * sum0, 1e-6, "axis 2 at home");
}

TEST(ArmDynamics, ExternalForceGivesMinusJacobianTransposeTimesForce) {
  ArmDynamics dyn;
  std::mt19937 rng(20);
  std::uniform_real_distribution<double> angle(-2.0, 2.0);
  std::uniform_real_distribution<double> force(-200.0, 200.0);
  std::uniform_real_distribution<double> offset(-0.15, 0.15);
  for (int trial = 0; trial < 50; ++trial) {
    JointVec q{};
    for (auto& v : q) v = angle(rng);
    const Vec3 f{force(rng), force(rng), force(rng)};
    const Vec3 tcp = (trial % 2 == 0) ? kTool0 : Vec3{offset(rng), offset(rng), offset(rng)};
    JointVec with{};
    JointVec without{};
    ASSERT_TRUE(dyn.torques(q, kZero, kZero, f, tcp, with));
    ASSERT_TRUE(dyn.torques(q, kZero, kZero, kNoForce, tcp, without));
    // J_v column i by central differences of the TCP's position.
    constexpr double h = 1e-6;
    for (std::size_t i = 0; i < 6; ++i) {
      JointVec qp = q;
      JointVec qm = q;
      qp[i] += h;
      qm[i] -= h;
      Vec3 pp{};
      Vec3 pm{};
      dyn.tcp(qp, tcp, pp);
      dyn.tcp(qm, tcp, pm);
      double jt_f = 0.0;
      for (std::size_t c = 0; c < 3; ++c) jt_f += (pp[c] - pm[c]) / (2.0 * h) * f[c];
      EXPECT_NEAR(with[i] - without[i], -jt_f, 1e-6 * (1.0 + std::abs(jt_f)))
          << "trial " << trial << " axis " << i + 1;
    }
  }
}

TEST(ArmDynamics, ForceAgainstTheArmAtHomeLoadsAxisTwoTheRightWay) {
  // The environment pushes the flange back (-x) at home, 0.63 - 0.29 = 0.34 m above axis 2:
  // its moment about +y is r_z F_x = 0.34 (-100) (tips the arm backwards), so the drive
  // must push forward: tau2 = +34 N m. Axis 3 (0.07 m lever): +7 N m.
  ArmDynamics dyn;
  JointVec with{};
  JointVec without{};
  ASSERT_TRUE(dyn.torques(kZero, kZero, kZero, Vec3{-100.0, 0.0, 0.0}, kTool0, with));
  ASSERT_TRUE(dyn.torques(kZero, kZero, kZero, kNoForce, kTool0, without));
  EXPECT_NEAR(with[1] - without[1], 34.0, 1e-5);
  EXPECT_NEAR(with[2] - without[2], 7.0, 1e-5);
  EXPECT_NEAR(with[0] - without[0], 0.0, 1e-9);
}

TEST(ArmDynamics, PayloadAddsMassTimesGravityTimesLever) {
  ArmDynamics bare;
  ArmDynamics loaded;
  const double kg = 3.0;
  const Vec3 tcp{0.0, 0.0, 0.1};  // 100 mm out of the flange (along link 6 x)
  loaded.set_payload(kg, tcp);
  const JointVec q{0.0, kPi / 2.0, 0.0, 0.0, 0.0, 0.0};
  const JointVec t0 = gravity(bare, q);
  const JointVec t1 = gravity(loaded, q);
  // At q2 = +90 deg the flange's z offset in link 2 (0.27 + 0.07 m) is its base x; tool0 z
  // (link 6 x) points down, so the 0.1 m adds no lever about axes 2 and 3.
  const double x_tcp = link6_in_link2()[2];
  expect_rel(t1[1] - t0[1], -kg * g() * x_tcp, 1e-6, "axis 2");
  const double x3 = origin(3, 2);
  expect_rel(t1[2] - t0[2], -kg * g() * (x_tcp - x3), 1e-6, "axis 3");
  EXPECT_NEAR(t1[0] - t0[0], 0.0, 1e-9);
  // At home the 0.1 m lengthens the lever (link 6 x is forward): axis 2 holds
  // m g (0.374 + 0.1) against the payload, axis 5 m g (0.072 + 0.1).
  const JointVec h0 = gravity(bare, kZero);
  const JointVec h1 = gravity(loaded, kZero);
  const double x_home = link6_in_link2()[0] + 0.1;
  expect_rel(h1[1] - h0[1], -kg * g() * x_home, 1e-6, "axis 2 at home");
  expect_rel(h1[4] - h0[4], -kg * g() * (origin(6, 0) + (d(safestate::motion::kRobot.flange.xyz_mm[0]) / 1000.0) + 0.1), 1e-6,
             "axis 5 at home");
  // A payload of 0 is the bare arm again.
  loaded.set_payload(0.0, tcp);
  const JointVec t2 = gravity(loaded, q);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_DOUBLE_EQ(t2[i], t0[i]) << i;
}

TEST(ArmDynamics, InertiaMakesAccelerationCostTorque) {
  // qdd on axis 1 alone at home: tau1 = I_zz(about axis 1) qdd, positive and linear.
  ArmDynamics dyn;
  const JointVec g0 = gravity(dyn, kZero);
  JointVec t1{};
  JointVec t2{};
  ASSERT_TRUE(dyn.torques(kZero, kZero, JointVec{1.0, 0, 0, 0, 0, 0}, kNoForce, kTool0, t1));
  ASSERT_TRUE(dyn.torques(kZero, kZero, JointVec{2.0, 0, 0, 0, 0, 0}, kNoForce, kTool0, t2));
  EXPECT_GT(t1[0] - g0[0], 0.1);
  EXPECT_NEAR(t2[0] - g0[0], 2.0 * (t1[0] - g0[0]), 1e-9);
}

TEST(ArmDynamics, RefusesNonFiniteInput) {
  ArmDynamics dyn;
  JointVec tau{};
  JointVec q = kZero;
  q[3] = std::nan("");
  EXPECT_FALSE(dyn.torques(q, kZero, kZero, kNoForce, kTool0, tau));
  EXPECT_TRUE(std::isnan(tau[0]));
  EXPECT_FALSE(dyn.torques(kZero, kZero, kZero, Vec3{0.0, HUGE_VAL, 0.0}, kTool0, tau));
  EXPECT_TRUE(dyn.torques(kZero, kZero, kZero, kNoForce, kTool0, tau));
  EXPECT_FALSE(std::isnan(tau[1]));
}

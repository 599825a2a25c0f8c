// SPEC §11 collision detection: the core's fixed-size model of the arm against the simulated
// arm's (Orocos KDL, itself checked against Pinocchio by test_dynamics_vs_pinocchio.py), the
// force estimate against known forces, the monitor's thresholds and gating, and the whole
// cell: a contact stops the robot (rule 8), it backs off and holds, a torque bias below the
// limit does not stop it.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "safestate/core/collision.hpp"
#include "safestate/core/dynamics.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/sim/dynamics.hpp"
#include "monitor_harness.hpp"

using namespace safestate::core;

namespace {

// The built-in IRB 120: its chain as the description gives it, its inertials as the constants
// (test_robot_description checks that the description gives those too).
const ArmGeometry& irb_arm() { return safestate::robot::active().geometry; }
const ArmDynamicsModel& irb() {
  static const ArmDynamicsModel m = prepare_dynamics(irb_arm(), kIrb120Inertials);
  return m;
}
const JointArray& kRatedTorqueNm = kIrb120Inertials.rated_torque_nm;

JointArray random_q(std::mt19937& g) {
  // Inside the IRB 120's ranges (docs/robot.md), away from the ends.
  const std::array<float, kAxes> lo{-2.8F, -1.9F, -1.9F, -2.7F, -2.0F, -3.0F};
  const std::array<float, kAxes> hi{2.8F, 1.9F, 1.2F, 2.7F, 2.0F, 3.0F};
  JointArray q{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    q[k] = std::uniform_real_distribution<float>(lo[k], hi[k])(g);
  }
  return q;
}

JointArray uniform(std::mt19937& g, float m) {
  JointArray v{};
  for (float& x : v) {
    x = std::uniform_real_distribution<float>(-m, m)(g);
  }
  return v;
}

safestate::sim::JointVec to_d(const JointArray& a) {
  safestate::sim::JointVec d{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    d[k] = static_cast<double>(a[k]);
  }
  return d;
}

}  // namespace

// @req COL-COLLISION
TEST(CollisionModel, AgreesWithTheSimulatorsKdlModelOnRandomStates) {
  std::mt19937 g(20261127U);
  safestate::sim::ArmDynamics kdl;
  const Vec3 tcp_mm{0.0F, 0.0F, 120.0F};
  kdl.set_payload(1.5, {0.0, 0.0, 0.12});
  for (int n = 0; n < 500; ++n) {
    const JointArray q = random_q(g);
    const JointArray qd = uniform(g, 3.0F);
    const JointArray qdd = uniform(g, 20.0F);
    ArmDynamicsState s{};
    arm_dynamics(irb(), q, qd, qdd, 1.5F, tcp_mm, s);
    safestate::sim::JointVec tau{};
    ASSERT_TRUE(kdl.torques(to_d(q), to_d(qd), to_d(qdd), {0.0, 0.0, 0.0}, {0.0, 0.0, 0.12}, tau));
    safestate::sim::Vec3 p{};
    kdl.tcp(to_d(q), {0.0, 0.0, 0.12}, p);
    for (std::size_t k = 0; k < 3U; ++k) {
      EXPECT_NEAR(s.tcp_m[k], p[k], 1.0e-5) << "tcp " << k << " sample " << n;
    }
    for (std::size_t k = 0; k < kAxes; ++k) {
      // float against double: 1e-3 relative to the axis' rated torque.
      EXPECT_NEAR(s.tau_nm[k], tau[k], 1.0e-3 * kRatedTorqueNm[k]) << "axis " << (k + 1) << " sample " << n;
    }
  }
}

// Any arm from its description: turned joint frames, an axis along minus z, a skew axis, a
// turned flange, fixed links folded in. The core's model (prepared from the description's
// chain and inertials) against the simulator's KDL chain of the same description.
// @req COL-COLLISION
TEST(CollisionModel, AgreesWithKdlOnAGeneralArm) {
  const auto link = [](const std::string& name, const std::string& com, double mass) {
    return "<link name=\"" + name + "\"><inertial><origin xyz=\"" + com + "\" rpy=\"0.2 -0.1 0.3\"/><mass value=\"" +
           std::to_string(mass) + "\"/><inertia ixx=\"0.03\" ixy=\"0.001\" ixz=\"-0.002\" iyy=\"0.02\" "
           "iyz=\"0.0015\" izz=\"0.025\"/></inertial></link>";
  };
  const auto joint = [](const std::string& name, const std::string& parent, const std::string& child,
                        const std::string& xyz, const std::string& rpy, const std::string& axis, const std::string& effort) {
    return "<joint name=\"" + name + "\" type=\"revolute\"><parent link=\"" + parent + "\"/><child link=\"" + child +
           "\"/><origin xyz=\"" + xyz + "\" rpy=\"" + rpy + "\"/><axis xyz=\"" + axis +
           "\"/><limit lower=\"-3\" upper=\"3\" velocity=\"2\" effort=\"" + effort + "\"/></joint>";
  };
  const std::string urdf =
      "<?xml version=\"1.0\"?><robot name=\"general\"><link name=\"base\"/>" + link("l1", "0 0.01 0.1", 4.0) +
      link("l2", "0.2 0 0.02", 6.0) + link("l3", "0.15 0.01 0", 3.0) + link("l4", "0 0.02 0.03", 1.2) +
      link("l5", "0.01 0 0.02", 1.0) + link("l6", "0 0 0.02", 0.3) + link("tool0", "0 0 0.01", 0.2) +
      joint("j1", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1", "150") +
      joint("j2", "l1", "l2", "0 0.13 0.05", "0 1.5707963267948966 0", "0 1 0", "150") +
      joint("j3", "l2", "l3", "0 -0.12 0.42", "0.3 -0.2 0.1", "0 0 -1", "150") +
      joint("j4", "l3", "l4", "0.39 0 0.01", "0 1.5707963267948966 0", "0.6 0 0.8", "28") +
      joint("j5", "l4", "l5", "0 0.09 0", "0 0 0", "1 0 0", "28") +
      joint("j6", "l5", "l6", "0 0 0.09", "0 0 0", "0 -1 0", "28") +
      "<joint name=\"flange\" type=\"fixed\"><parent link=\"l6\"/><child link=\"tool0\"/><origin "
      "xyz=\"0 0.08 0\" rpy=\"-1.5707963267948966 0 0\"/></joint></robot>";
  std::string error;
  const auto r = safestate::robot::load_text(urdf, "test", "", "", error);
  ASSERT_NE(r, nullptr) << error;
  const ArmDynamicsModel m = prepare_dynamics(r->geometry, r->inertials);
  EXPECT_TRUE(m.joint[1].turned);
  EXPECT_EQ(m.joint[2].axis_kind, AxisKind::minus_z);
  EXPECT_EQ(m.joint[3].axis_kind, AxisKind::general);
  EXPECT_EQ(m.joint[5].axis_kind, AxisKind::minus_y);
  EXPECT_EQ(m.rated_torque_nm[3], 28.0F);
  safestate::sim::ArmDynamics kdl(*r);
  const Vec3 tcp_mm{10.0F, -5.0F, 120.0F};
  const safestate::sim::Vec3 tcp_m{0.01, -0.005, 0.12};
  kdl.set_payload(2.0, tcp_m);
  std::mt19937 g(11U);
  float worst = 0.0F;
  for (int n = 0; n < 500; ++n) {
    JointArray q{};
    for (float& x : q) x = std::uniform_real_distribution<float>(-3.0F, 3.0F)(g);
    const JointArray qd = uniform(g, 3.0F);
    const JointArray qdd = uniform(g, 20.0F);
    ArmDynamicsState s{};
    arm_dynamics(m, q, qd, qdd, 2.0F, tcp_mm, s);
    safestate::sim::JointVec tau{};
    ASSERT_TRUE(kdl.torques(to_d(q), to_d(qd), to_d(qdd), {0.0, 0.0, 0.0}, tcp_m, tau));
    safestate::sim::Vec3 p{};
    kdl.tcp(to_d(q), tcp_m, p);
    for (std::size_t k = 0; k < 3U; ++k) {
      EXPECT_NEAR(s.tcp_m[k], p[k], 1.0e-5) << "tcp " << k << " sample " << n;
    }
    for (std::size_t k = 0; k < kAxes; ++k) {
      EXPECT_NEAR(s.tau_nm[k], tau[k], 1.0e-3 * m.rated_torque_nm[k]) << "axis " << (k + 1) << " sample " << n;
      worst = std::fmax(worst, std::fabs(static_cast<float>(tau[k])));
    }
  }
  EXPECT_GT(worst, 20.0F) << "not vacuous: the states load the axes";
}

// @req COL-COLLISION
TEST(CollisionModel, JacobianIsTheDerivativeOfTheTcp) {
  std::mt19937 g(7U);
  for (int n = 0; n < 50; ++n) {
    const JointArray q = random_q(g);
    ArmDynamicsState s{};
    arm_dynamics(irb(), q, {}, {}, 0.0F, {10.0F, -20.0F, 100.0F}, s);
    for (std::size_t k = 0; k < kAxes; ++k) {
      JointArray qp = q;
      JointArray qm = q;
      qp[k] += 1.0e-3F;
      qm[k] -= 1.0e-3F;
      ArmDynamicsState sp{};
      ArmDynamicsState sm{};
      arm_dynamics(irb(), qp, {}, {}, 0.0F, {10.0F, -20.0F, 100.0F}, sp);
      arm_dynamics(irb(), qm, {}, {}, 0.0F, {10.0F, -20.0F, 100.0F}, sm);
      for (std::size_t i = 0; i < 3U; ++i) {
        EXPECT_NEAR(s.jacobian[k][i], (sp.tcp_m[i] - sm.tcp_m[i]) / 2.0e-3F, 2.0e-3F) << "joint " << k;
      }
    }
  }
}

// @req COL-COLLISION
TEST(CollisionModel, GravityAtTheZeroPoseLoadsAxes2And3NotAxis1) {
  ArmDynamicsState s{};
  arm_dynamics(irb(), {}, {}, {}, 0.0F, {}, s);
  EXPECT_NEAR(s.tau_nm[0], 0.0F, 1.0e-5F);  // gravity is parallel to axis 1
  // q = 0: upper arm upright, forearm forward: axis 2 and 3 hold the forearm's weight, which
  // pulls forward-down (a negative torque about +y tips it further: the drive holds with -).
  EXPECT_LT(s.tau_nm[1], -1.0F);
  EXPECT_LT(s.tau_nm[2], -1.0F);
}

// @req COL-COLLISION
TEST(CollisionEstimate, RecoversAKnownForceAtTheTcp) {
  std::mt19937 g(3U);
  int tested = 0;
  for (int n = 0; n < 200; ++n) {
    const JointArray q = random_q(g);
    ArmDynamicsState s{};
    arm_dynamics(irb(), q, {}, {}, 0.0F, {0.0F, 0.0F, 100.0F}, s);
    const Vec3 f{std::uniform_real_distribution<float>(-200.0F, 200.0F)(g),
                 std::uniform_real_distribution<float>(-200.0F, 200.0F)(g),
                 std::uniform_real_distribution<float>(-200.0F, 200.0F)(g)};
    JointArray r{};  // the drives' torque over the model: r = -J^T F
    for (std::size_t k = 0; k < kAxes; ++k) {
      r[k] = -((s.jacobian[k][0] * f[0]) + (s.jacobian[k][1] * f[1]) + (s.jacobian[k][2] * f[2]));
    }
    Vec3 est{};
    const float mag = estimate_tcp_force(s, r, est);
    // Well-conditioned poses only: the smallest singular value of J well above the damping.
    const float fmag = std::sqrt((f[0] * f[0]) + (f[1] * f[1]) + (f[2] * f[2]));
    if (fmag < 50.0F) {
      continue;
    }
    ++tested;
    EXPECT_LE(mag, fmag * 1.0001F) << "damping never overestimates";
    float sigma_ok = 0.0F;
    for (std::size_t i = 0; i < 3U; ++i) {
      sigma_ok += std::fabs(est[i] - f[i]);
    }
    if (mag > 0.9F * fmag) {
      EXPECT_LT(sigma_ok, 0.1F * fmag);
    }
  }
  EXPECT_GT(tested, 100);
}

// @req COL-COLLISION
TEST(CollisionEstimate, NaNResidualIsNaN) {
  ArmDynamicsState s{};
  arm_dynamics(irb(), {0.1F, 0.2F, 0.3F, 0.4F, 0.5F, 0.6F}, {}, {}, 0.0F, {}, s);
  JointArray r{};
  r[1] = std::numeric_limits<float>::quiet_NaN();
  Vec3 f{};
  EXPECT_TRUE(std::isnan(estimate_tcp_force(s, r, f)));
}

namespace {

SafetyLimits pfl_limits() {
  SafetyLimits l{};
  l.collaborative.enabled = true;
  l.collaborative.pfl_enabled = true;
  l.collaborative.f_qs_n = 140.0F;  // hand
  return l;
}

// Feedback as the drives would report it for (q, qd, qdd), with a force on the TCP and a bias.
Feedback drives_for(const JointArray& q, const JointArray& qd, const JointArray& qdd, const Vec3& f_env,
                    std::size_t bias_axis = 0, float bias_permille = 0.0F) {
  ArmDynamicsState s{};
  arm_dynamics(irb(), q, qd, qdd, 0.0F, {}, s);
  Feedback fb{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    const float tau = s.tau_nm[k] - ((s.jacobian[k][0] * f_env[0]) + (s.jacobian[k][1] * f_env[1]) +
                                     (s.jacobian[k][2] * f_env[2]));
    float permille = 1000.0F * tau / kRatedTorqueNm[k];
    if (k + 1U == bias_axis) {
      permille += bias_permille;
    }
    fb.drive[k].position_rad = q[k];
    fb.drive[k].velocity_rad_s = qd[k];
    fb.drive[k].torque_permille = static_cast<std::int16_t>(std::lround(permille));
  }
  return fb;
}

const JointArray kPose{0.3F, 0.4F, -0.2F, 0.1F, 0.6F, 0.0F};

}  // namespace

// @req COL-COLLISION
TEST(CollisionMonitor, AForceOverFqsTwoCyclesInARowTrips) {
  CollisionMonitor m;
  m.configure(pfl_limits(), irb_arm(), 1000U);
  safestate::test::CollisionResult r{};
  safestate::test::collide(m, drives_for(kPose, {}, {}, {}), true, r);
  EXPECT_TRUE(r.acting);
  EXPECT_TRUE(r.evaluated);
  EXPECT_LT(r.force_n, 2.0F) << "the model explains the drives' torques: no force";
  EXPECT_FALSE(r.hit.hit);
  const Feedback pushed = drives_for(kPose, {}, {}, {0.0F, 0.0F, 150.0F});
  safestate::test::collide(m, pushed, true, r);
  EXPECT_NEAR(r.force_n, 150.0F, 5.0F);
  EXPECT_FALSE(r.hit.hit) << "one sample never trips";
  safestate::test::collide(m, pushed, true, r);
  EXPECT_TRUE(r.hit.hit);
  EXPECT_EQ(r.hit.detail.signal, Signal::tcp);
  EXPECT_NEAR(static_cast<float>(r.hit.detail.code), 150.0F, 5.0F);
}

// @req COL-COLLISION
TEST(CollisionMonitor, AForceBelowFqsNeverTrips) {
  CollisionMonitor m;
  m.configure(pfl_limits(), irb_arm(), 1000U);
  safestate::test::CollisionResult r{};
  for (int i = 0; i < 10; ++i) {
    safestate::test::collide(m, drives_for(kPose, {}, {}, {0.0F, 0.0F, 120.0F}), true, r);
    EXPECT_FALSE(r.hit.hit);
  }
  EXPECT_NEAR(r.force_n, 120.0F, 5.0F);
}

// @req COL-COLLISION
TEST(CollisionMonitor, AnEstimateThatIsNotANumberCountsAsOver) {
  // A drive whose velocity reads NaN (a corrupted sample) leaves the force unknown: unknown
  // is unsafe (SPEC §2's principle), so it counts as over F_qs and trips like a force would.
  CollisionMonitor m;
  m.configure(pfl_limits(), irb_arm(), 1000U);
  safestate::test::CollisionResult r{};
  safestate::test::collide(m, drives_for(kPose, {}, {}, {}), true, r);
  ASSERT_FALSE(r.hit.hit);
  Feedback bad = drives_for(kPose, {}, {}, {});
  bad.drive[1].velocity_rad_s = std::numeric_limits<float>::quiet_NaN();
  safestate::test::collide(m, bad, true, r);
  EXPECT_FALSE(r.hit.hit) << "one sample never trips";
  safestate::test::collide(m, bad, true, r);
  EXPECT_TRUE(std::isnan(r.force_n)) << r.force_n;
  EXPECT_TRUE(r.hit.hit) << "a NaN estimate is over the limit";
}

// @req COL-COLLISION
TEST(CollisionMonitor, ATorqueBiasIsReadAsTheForceItWouldTake) {
  // 5 % of rated on axis 2 (3 N m): far below what 140 N at the TCP would take.
  CollisionMonitor m;
  m.configure(pfl_limits(), irb_arm(), 1000U);
  safestate::test::CollisionResult r{};
  for (int i = 0; i < 5; ++i) {
    safestate::test::collide(m, drives_for(kPose, {}, {}, {}, 2U, 50.0F), true, r);
  }
  EXPECT_FALSE(r.hit.hit);
  EXPECT_GT(r.force_n, 1.0F);
  EXPECT_LT(r.force_n, 30.0F);
  // 200 % on axis 2 (120 N m) is more than any region allows.
  for (int i = 0; i < 2; ++i) {
    safestate::test::collide(m, drives_for(kPose, {}, {}, {}, 2U, 2000.0F), true, r);
  }
  EXPECT_TRUE(r.hit.hit);
}

// @req COL-COLLISION
TEST(CollisionMonitor, InertiaIsModelledFromTheDrivesVelocities) {
  // Accelerating: the drives' torque includes M qdd; the monitor derives qdd from two
  // velocity samples a cycle apart and finds no force.
  CollisionMonitor m;
  m.configure(pfl_limits(), irb_arm(), 1000U);
  safestate::test::CollisionResult r{};
  const JointArray qdd{10.0F, -15.0F, 12.0F, 20.0F, -20.0F, 25.0F};
  JointArray qd{};
  safestate::test::collide(m, drives_for(kPose, qd, {}, {}), true, r);
  for (int i = 0; i < 50; ++i) {
    for (std::size_t k = 0; k < kAxes; ++k) {
      qd[k] += qdd[k] * 0.001F;
    }
    safestate::test::collide(m, drives_for(kPose, qd, qdd, {}), true, r);
    EXPECT_LT(r.force_n, 3.0F) << "cycle " << i;
    EXPECT_FALSE(r.hit.hit);
  }
}

// @req COL-COLLISION
TEST(CollisionMonitor, OffWithoutPflAndWhileTheArmIsNotFree) {
  CollisionMonitor off;
  SafetyLimits l = pfl_limits();
  l.collaborative.pfl_enabled = false;
  off.configure(l, irb_arm(), 1000U);
  safestate::test::CollisionResult r{};
  const Feedback pushed = drives_for(kPose, {}, {}, {0.0F, 0.0F, 500.0F});
  for (int i = 0; i < 3; ++i) {
    safestate::test::collide(off, pushed, true, r);
  }
  EXPECT_FALSE(r.acting);
  EXPECT_FALSE(r.hit.hit);
  CollisionMonitor on;
  on.configure(pfl_limits(), irb_arm(), 1000U);
  for (int i = 0; i < 3; ++i) {
    safestate::test::collide(on, pushed, false, r);  // brakes engaged, power off, brake test
  }
  EXPECT_TRUE(r.acting);
  EXPECT_FALSE(r.evaluated);
  EXPECT_FALSE(r.hit.hit);
  safestate::test::collide(on, pushed, true, r);
  EXPECT_FALSE(r.hit.hit) << "the count starts again when the arm is free";
  safestate::test::collide(on, pushed, true, r);
  EXPECT_TRUE(r.hit.hit);
  // No cycle time, no velocity to differentiate the inertia from: off rather than guessing.
  CollisionMonitor timeless;
  timeless.configure(pfl_limits(), irb_arm(), 0U);
  EXPECT_FALSE(timeless.enabled());
  EXPECT_TRUE(on.enabled());
}

// ---- the whole cell: the simulated arm's dynamics, the contact, rule 8, the back-off -------

#include "safestate/core/config.hpp"
#include "safestate/safety/safety_config.hpp"
#include "safestate/sim/cell.hpp"

namespace {

struct PflCell {
  safestate::sim::Cell cell;
  std::uint32_t seq = 0;
  explicit PflCell(const Config& cfg = Config{}) : cell{cfg} {
    SafetyLimits l = safestate::safety::default_safety().limits;
    l.collaborative.enabled = true;
    l.collaborative.pfl_enabled = true;
    l.collaborative.f_qs_n = 110.0F;  // abdomen
    l.payload_kg = 1.5F;
    l.tcp_mm = {0.0F, 0.0F, 120.0F};
    cell.configure_limits(l, true);
  }
  Result cmd(CommandId id) {
    Command c{};
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    EXPECT_EQ(cell.submit(c), Result::OK);
    cell.step();
    for (std::size_t i = 0; i < cell.out().reply_count; ++i) {
      if (cell.out().replies[i].seq == c.seq) return cell.out().replies[i].result;
    }
    return Result::QUEUE_FULL;
  }
  void run_auto() {
    for (int k = 0; k < 100 && cell.out().state != State::ESTOP_RESET_NEEDED; ++k) cell.step();
    ASSERT_EQ(cmd(CommandId::reset), Result::OK);
    ASSERT_EQ(cmd(CommandId::servo_on), Result::OK);
    for (int k = 0; k < 1000 && cell.out().sub != Sub::AUTO_IDLE; ++k) cell.step();
    ASSERT_EQ(cmd(CommandId::start), Result::OK);
  }
  [[nodiscard]] Vec3 tcp() const {
    const auto& t = cell.view().tcp;
    return {t[0], t[1], t[2]};
  }
};

float dist(const Vec3& a, const Vec3& b) {
  return std::sqrt(((a[0] - b[0]) * (a[0] - b[0])) + ((a[1] - b[1]) * (a[1] - b[1])) + ((a[2] - b[2]) * (a[2] - b[2])));
}

}  // namespace

// @req COL-COLLISION COL-SIM-DYNAMICS
TEST(CollisionCell, TheRunningProgramShowsNoForceWithoutAContact) {
  PflCell c;
  c.run_auto();
  float worst = 0.0F;
  for (int k = 0; k < 3000; ++k) {
    c.cell.step();
    worst = std::fmax(worst, c.cell.out().safety.contact_force_n);
    ASSERT_FALSE(c.cell.alarms().active(AlarmId::COLLISION)) << "cycle " << k;
  }
  EXPECT_TRUE(c.cell.out().safety.pfl);
  // The model and the plant's dynamics differ only by float rounding and the drives' per
  // mille resolution (0.06 N m on axes 1 and 2).
  EXPECT_LT(worst, 5.0F);
}

namespace {

// Runs the program at speed, pushes 150 N against the TCP and follows rule 8 through: Cat 2,
// the turn, the 10 mm back-off at <= 100 mm/s, AUTO_PAUSED only once it is done, and the hold.
void contact_backs_off_and_holds(PflCell& c) {
  c.run_auto();
  for (int k = 0; k < 3000 && c.cell.view().tcp_speed_mm_s < 300.0F; ++k) c.cell.step();
  ASSERT_EQ(c.cell.out().sub, Sub::AUTO_RUNNING);
  ASSERT_GE(c.cell.view().tcp_speed_mm_s, 300.0F);
  c.cell.inject({safestate::sim::FaultKind::contact, 0, 1500});  // 150 N
  int detected = -1;
  for (int k = 0; k < 5 && detected < 0; ++k) {
    c.cell.step();
    if (c.cell.alarms().active(AlarmId::COLLISION)) detected = k;
  }
  ASSERT_GE(detected, 0) << "rule 8 within two samples of the contact";
  EXPECT_EQ(c.cell.out().state, State::STOPPING);
  EXPECT_EQ(c.cell.out().stop, StopCat::CAT2);
  // Through the Cat 2 ramp to the turning point, then the back-off.
  Vec3 stopped{};
  bool turned = false;
  Vec3 prev = c.tcp();
  float back_peak = 0.0F;
  int k = 0;
  for (; k < 3000 && c.cell.out().state == State::STOPPING; ++k) {
    c.cell.step();
    const Vec3 p = c.tcp();
    if (!turned && c.cell.out().motion.back_off && dist(p, prev) < 1e-4F) {
      turned = true;
      stopped = p;
    }
    if (turned) back_peak = std::fmax(back_peak, c.cell.view().tcp_speed_mm_s);
    prev = p;
  }
  ASSERT_TRUE(turned);
  EXPECT_EQ(c.cell.out().sub, Sub::AUTO_PAUSED) << "after " << k << " cycles";
  EXPECT_TRUE(c.cell.alarms().active(AlarmId::COLLISION));
  const float backed = dist(c.tcp(), stopped);
  EXPECT_NEAR(backed, 10.0F, 1.0F) << "SPEC §11: 10 mm along the path";
  EXPECT_LE(back_peak, 100.0F) << "SPEC §11: at <= 100 mm/s";
  EXPECT_GT(back_peak, 50.0F);
  // It holds there.
  const Vec3 held = c.tcp();
  for (int j = 0; j < 500; ++j) c.cell.step();
  EXPECT_LT(dist(c.tcp(), held), 0.01F);
  EXPECT_EQ(c.cell.out().sub, Sub::AUTO_PAUSED);
}

}  // namespace

// @req TR-C8 COL-BACKOFF COL-SIM-CONTACT
TEST(CollisionCell, AContactStopsTheArmWhichBacksOffTenMillimetresSlowlyAndHolds) {
  PflCell c;
  contact_backs_off_and_holds(c);
}

// @req TR-C8 COL-BACKOFF
TEST(CollisionCell, TheStopLastsUntilTheBackOffIsDoneEvenWhereTheArmReadsAsStill) {
  // With a standstill threshold above the back-off's joint speeds (0.5 rad/s), the arm is
  // "at standstill" through the whole retrace: the Cat 2 stop must still wait for the motion
  // layer's back-off to finish (SPEC §11 rule 8), not end at the turn and cut it short.
  Config cfg{};
  cfg.standstill_rad_s = 0.5F;
  PflCell c(cfg);
  contact_backs_off_and_holds(c);
}
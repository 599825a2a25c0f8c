// Forward kinematics and point speeds of the IRB 120 model (motion/). Expected positions
// are worked out by hand from the datasheet dimensions (docs/robot.md), not from the code.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "safestate/motion/kinematics.hpp"
#include "safestate/motion/robot.hpp"

using namespace safestate::motion;

namespace {

constexpr float kPosTol = 1e-3F;  // mm; float FK over ~1 m is good to ~1e-4 mm

Joints zero() { return Joints{0.0F, 0.0F, 0.0F, 0.0F, 0.0F, 0.0F}; }

Joints only(std::size_t axis, float value) {
  Joints q = zero();
  q[axis - 1] = value;
  return q;
}

void expect_vec(const Vec3& got, float x, float y, float z, const char* what) {
  EXPECT_NEAR(got[0], x, kPosTol) << what;
  EXPECT_NEAR(got[1], y, kPosTol) << what;
  EXPECT_NEAR(got[2], z, kPosTol) << what;
}

void expect_mat(const Mat3& got, const Mat3& want, float tol) {
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(got[r][c], want[r][c], tol) << r << "," << c;
  }
}

// kRobot with a tool 100 mm along the flange normal and 30 mm to the side, so the TCP
// differs from the flange and also moves when axis 6 turns.
RobotModel tooled() {
  RobotModel m = kRobot;
  m.tcp_offset_mm = {30.0F, 0.0F, 100.0F};
  return m;
}

struct Rng {
  std::mt19937 gen{20240611U};
  float uniform(float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(gen); }
  Joints pose(const RobotModel& m) {
    Joints q{};
    for (std::size_t j = 0; j < kJoints; ++j) q[j] = uniform(m.q_min_rad[j], m.q_max_rad[j]);
    return q;
  }
  Joints rates(const RobotModel& m) {
    Joints qd{};
    for (std::size_t j = 0; j < kJoints; ++j) qd[j] = uniform(-m.qd_max_rad_s[j], m.qd_max_rad_s[j]);
    return qd;
  }
};

Vec3 point_of(const Frames& f, std::size_t i) { return i == kTcpPoint ? f.tcp : f.origin[i]; }

float max_point_speed(const RobotModel& m, const Joints& q, const Joints& qd) {
  PointSpeeds ps{};
  point_speeds(m, q, qd, ps);
  return ps.max_speed;
}

Joints times(const Joints& qd, float s) {
  Joints r{};
  for (std::size_t j = 0; j < kJoints; ++j) r[j] = qd[j] * s;
  return r;
}

Joints step(const Joints& q, const Joints& qd, double dt) {
  Joints r{};
  for (std::size_t j = 0; j < kJoints; ++j) r[j] = static_cast<float>(q[j] + qd[j] * dt);
  return r;
}

// Z-Y-X composition written independently of the code under test.
Mat3 from_rpy(double roll, double pitch, double yaw) {
  const double cr = std::cos(roll), sr = std::sin(roll);
  const double cp = std::cos(pitch), sp = std::sin(pitch);
  const double cy = std::cos(yaw), sy = std::sin(yaw);
  const double m[3][3] = {{cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr},
                          {sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr},
                          {-sp, cp * sr, cp * cr}};
  Mat3 R{};
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) R[r][c] = static_cast<float>(m[r][c]);
  }
  return R;
}

}  // namespace

// --- the model ---------------------------------------------------------------------------

TEST(RobotModel, LimitsAreSane) {
  for (std::size_t j = 0; j < kJoints; ++j) {
    SCOPED_TRACE(j + 1);
    EXPECT_LT(kRobot.q_min_rad[j], 0.0F);  // home (all zero) lies inside every range
    EXPECT_GT(kRobot.q_max_rad[j], 0.0F);
    EXPECT_LT(kRobot.q_min_rad[j], kRobot.q_max_rad[j]);
    EXPECT_GT(kRobot.qd_max_rad_s[j], 0.0F);
    EXPECT_LT(kRobot.qd_max_rad_s[j], 10.0F);  // < 573 deg/s: plausible for a small arm
    EXPECT_GT(kRobot.qdd_max_rad_s2[j], 0.0F);
  }
  for (const char* name : kRobot.link_names) {
    ASSERT_NE(name, nullptr);
    EXPECT_GT(std::strlen(name), 0U);
  }
  EXPECT_STREQ(kRobot.link_names[0], "base_link");  // the URDF's (examples/robots/abb_irb120.urdf)
  EXPECT_STREQ(kRobot.link_names[kLinks - 1], "link_6");
}

TEST(RobotModel, DatasheetDegreesBecomeRadians) {
  EXPECT_NEAR(kRobot.q_max_rad[0], 2.879793F, 1e-5F);      // axis 1 +165 deg
  EXPECT_NEAR(kRobot.q_max_rad[2], 1.221730F, 1e-5F);      // axis 3 +70 deg
  EXPECT_NEAR(kRobot.q_min_rad[2], -1.919862F, 1e-5F);     // axis 3 -110 deg
  EXPECT_NEAR(kRobot.qd_max_rad_s[0], 4.363323F, 1e-5F);   // 250 deg/s
  EXPECT_NEAR(kRobot.qd_max_rad_s[5], 7.330383F, 1e-5F);   // 420 deg/s
}

TEST(RobotModel, CatalogueReachIsToTheWristCentre) {
  // Upper arm (joint 3's origin above joint 2's), then the elbow offset and the forearm.
  const float reach = kRobot.joints[2].origin.xyz_mm[2] +
                      std::hypot(kRobot.joints[3].origin.xyz_mm[2], kRobot.joints[4].origin.xyz_mm[0]);
  EXPECT_NEAR(reach, 580.0F, 1.0F);  // 270 + hypot(70, 302) = 580.0 [PS]
  EXPECT_FLOAT_EQ(kRobot.reach_mm, 270.0F + 70.0F + 302.0F + 72.0F);  // the bound: offsets added
}

// --- forward kinematics ------------------------------------------------------------------

TEST(Forward, ZeroPoseMatchesDatasheet) {
  Frames f{};
  forward(kRobot, zero(), f);
  expect_vec(f.origin[0], 0, 0, 0, "base");
  expect_vec(f.origin[1], 0, 0, 290, "axis 2, 290 mm above the base plate");
  expect_vec(f.origin[2], 0, 0, 560, "axis 3, upper arm 270 mm");
  expect_vec(f.origin[3], 0, 0, 630, "axis 4, elbow offset 70 mm");
  expect_vec(f.origin[4], 302, 0, 630, "wrist centre, forearm 302 mm");
  expect_vec(f.origin[5], 302, 0, 630, "wrist centre");
  expect_vec(f.origin[6], 374, 0, 630, "flange, 72 mm beyond the wrist centre");
  expect_vec(f.tcp, 374, 0, 630, "tool0");
  // ABB tool0 at the calibration pose: z out of the flange (+x), x down, y = +y.
  expect_mat(f.R, Mat3{{{0, 0, 1}, {0, 1, 0}, {-1, 0, 0}}}, 1e-6F);
  // Joint axes point the way ABB's positive directions do (see robot.hpp).
  expect_vec(f.z[0], 0, 0, 1, "axis 1");
  expect_vec(f.z[1], 0, 1, 0, "axis 2");
  expect_vec(f.z[2], 0, 1, 0, "axis 3");
  expect_vec(f.z[3], 1, 0, 0, "axis 4");
  expect_vec(f.z[4], 0, 1, 0, "axis 5");
  expect_vec(f.z[5], 1, 0, 0, "axis 6");
}

TEST(Forward, ToolOffsetIsInTheFlangeFrame) {
  Frames f{};
  forward(tooled(), zero(), f);
  expect_vec(f.origin[6], 374, 0, 630, "flange unchanged");
  expect_vec(f.tcp, 374 + 100, 0, 630 - 30, "100 mm along flange z (+x), 30 along flange x (-z)");
}

TEST(Forward, Axis1At90DegRotatesXIntoY) {
  Frames f{};
  forward(tooled(), only(1, kPi / 2), f);
  expect_vec(f.origin[4], 0, 302, 630, "wrist centre");
  expect_vec(f.origin[6], 0, 374, 630, "flange");
  expect_vec(f.tcp, 0, 474, 600, "tcp");
}

TEST(Forward, Axis2At90DegLaysTheUpperArmForward) {
  Frames f{};
  forward(tooled(), only(2, kPi / 2), f);
  expect_vec(f.origin[1], 0, 0, 290, "shoulder does not move");
  expect_vec(f.origin[2], 270, 0, 290, "elbow one upper-arm length forward");
  expect_vec(f.origin[3], 340, 0, 290, "elbow offset now points forward");
  expect_vec(f.origin[4], 340, 0, -12, "forearm hangs down 302 mm");
  expect_vec(f.origin[6], 340, 0, -84, "flange");
  expect_vec(f.tcp, 310, 0, -184, "tool points down, its side offset backwards");
}

TEST(Forward, Axis3NegativeRaisesTheForearm) {
  Frames f{};
  forward(kRobot, only(3, -kPi / 2), f);
  expect_vec(f.origin[2], 0, 0, 560, "elbow does not move");
  expect_vec(f.origin[3], -70, 0, 560, "elbow offset now points backwards");
  expect_vec(f.origin[4], -70, 0, 862, "wrist centre above");
  expect_vec(f.origin[6], -70, 0, 934, "flange");
}

TEST(Forward, Axis5PositiveBendsTheWristDown) {
  Frames f{};
  forward(kRobot, only(5, kPi / 2), f);
  expect_vec(f.origin[4], 302, 0, 630, "wrist centre does not move");
  expect_vec(f.origin[6], 302, 0, 558, "flange 72 mm below the wrist centre");
}

TEST(Forward, Axis6TurnsTheToolAboutTheFlangeNormal) {
  Frames f{};
  forward(tooled(), only(6, kPi / 2), f);
  expect_vec(f.origin[6], 374, 0, 630, "flange centre does not move");
  expect_vec(f.tcp, 474, 30, 630, "side offset turned from -z to +y");
}

TEST(Forward, StretchedUpwardWristCentreIsAtReach) {
  Frames f{};
  forward(kRobot, only(3, -std::atan2(302.0F, 70.0F)), f);
  // 290 + 270 + hypot(70, 302) = 870.0065 mm: the catalogue's 580 mm reach, rounded.
  expect_vec(f.origin[4], 0, 0, 560 + std::hypot(70.0F, 302.0F), "forearm in line");
}

TEST(Rpy, RecoversAGeneralOrientation) {
  const Rpy r = to_rpy(from_rpy(0.3, -0.4, 1.2));
  EXPECT_NEAR(r.roll, 0.3F, 1e-5F);
  EXPECT_NEAR(r.pitch, -0.4F, 1e-5F);
  EXPECT_NEAR(r.yaw, 1.2F, 1e-5F);
}

TEST(Rpy, HomeToolIsAtPitch90AndRebuildsTheSameMatrix) {
  Frames f{};
  forward(kRobot, zero(), f);
  const Rpy r = to_rpy(tcp_pose(f).R);
  EXPECT_NEAR(r.pitch, kPi / 2, 1e-5F);
  expect_mat(from_rpy(r.roll, r.pitch, r.yaw), f.R, 1e-5F);
}

TEST(Rpy, RebuildsTheTcpOrientationAtRandomPoses) {
  Rng rng;
  for (int n = 0; n < 20; ++n) {
    Frames f{};
    forward(kRobot, rng.pose(kRobot), f);
    const Rpy r = to_rpy(f.R);
    expect_mat(from_rpy(r.roll, r.pitch, r.yaw), f.R, 1e-4F);
  }
}

// --- point speeds ------------------------------------------------------------------------

// The motion layer's point speeds, its T1 limiting's basis (the core's T1 monitor
// differentiates positions of its own kinematics: test_monitors' T1SpeedMonitor).
// @req MO-T1-LIMIT
TEST(PointSpeeds, MatchFiniteDifferencesOfForward) {
  const RobotModel m = tooled();
  Rng rng;
  const double dt = 1e-3;  // s; central difference, error ~ (qd*dt)^2/6 << 1e-3
  for (int n = 0; n < 20; ++n) {
    const Joints q = rng.pose(m);
    const Joints qd = rng.rates(m);
    PointSpeeds ps{};
    point_speeds(m, q, qd, ps);
    Frames plus{}, minus{};
    forward(m, step(q, qd, dt), plus);
    forward(m, step(q, qd, -dt), minus);
    for (std::size_t i = 1; i < kPoints; ++i) {
      SCOPED_TRACE(testing::Message() << "pose " << n << " point " << i);
      const Vec3 a = point_of(plus, i);
      const Vec3 b = point_of(minus, i);
      const double fd[3] = {(a[0] - b[0]) / (2 * dt), (a[1] - b[1]) / (2 * dt),
                            (a[2] - b[2]) / (2 * dt)};
      const double fd_speed = std::sqrt(fd[0] * fd[0] + fd[1] * fd[1] + fd[2] * fd[2]);
      // Relative to the fastest point: a point near an axis is slow, and float rounding
      // of forward() is absolute, not relative to that small speed.
      const double tol = 1e-3 * ps.max_speed;
      EXPECT_NEAR(ps.speed[i], fd_speed, tol);
      for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(ps.velocity[i][c], fd[c], tol);
    }
  }
}

TEST(PointSpeeds, TcpSpeedMatchesFiniteDifferenceWithinRelative1e3) {
  const RobotModel m = tooled();
  Rng rng;
  const double dt = 1e-3;
  for (int n = 0; n < 20; ++n) {
    const Joints q = rng.pose(m);
    const Joints qd = rng.rates(m);
    PointSpeeds ps{};
    point_speeds(m, q, qd, ps);
    Frames plus{}, minus{};
    forward(m, step(q, qd, dt), plus);
    forward(m, step(q, qd, -dt), minus);
    const double dx = plus.tcp[0] - minus.tcp[0];
    const double dy = plus.tcp[1] - minus.tcp[1];
    const double dz = plus.tcp[2] - minus.tcp[2];
    const double fd_speed = std::sqrt(dx * dx + dy * dy + dz * dz) / (2 * dt);
    EXPECT_NEAR(ps.speed[kTcpPoint], fd_speed, 1e-3 * fd_speed) << "pose " << n;
  }
}

TEST(PointSpeeds, Axis1AloneMovesTheTcpAtItsHorizontalRadius) {
  const RobotModel m = tooled();
  Rng rng;
  for (int n = 0; n < 20; ++n) {
    const Joints q = rng.pose(m);
    Frames f{};
    forward(m, q, f);
    PointSpeeds ps{};
    point_speeds(m, q, only(1, 1.0F), ps);
    const float radius = std::hypot(f.tcp[0], f.tcp[1]);
    EXPECT_NEAR(ps.speed[kTcpPoint], radius, 1e-4F * std::max(radius, 1.0F)) << "pose " << n;
    EXPECT_NEAR(ps.velocity[kTcpPoint][2], 0.0F, 1e-3F);  // a turn about a vertical axis
  }
}

TEST(PointSpeeds, Axis2AloneAtHome) {
  PointSpeeds ps{};
  point_speeds(kRobot, zero(), only(2, 1.0F), ps);
  EXPECT_FLOAT_EQ(ps.speed[0], 0.0F);
  EXPECT_NEAR(ps.speed[1], 0.0F, 1e-4F);    // on axis 2 itself
  EXPECT_NEAR(ps.speed[2], 270.0F, 1e-3F);  // upper-arm length
  EXPECT_NEAR(ps.speed[4], std::hypot(302.0F, 340.0F), 1e-3F);
  EXPECT_NEAR(ps.speed[6], std::hypot(374.0F, 340.0F), 1e-3F);
  EXPECT_EQ(ps.fastest_point, kTcpPoint);  // TCP = flange, the tie names the TCP
  EXPECT_EQ(ps.fastest_axis, 6);
  EXPECT_FLOAT_EQ(ps.max_speed, ps.speed[kTcpPoint]);
}

TEST(PointSpeeds, ParallelAxesCounterTurningTranslateTheForearm) {
  // Axis 2 turning and axis 3 counter-turning at the same rate keep the forearm's
  // orientation: everything from the elbow on translates with the elbow, at 270 mm/s.
  PointSpeeds ps{};
  point_speeds(kRobot, zero(), Joints{0.0F, 1.0F, -1.0F, 0.0F, 0.0F, 0.0F}, ps);
  EXPECT_NEAR(ps.speed[1], 0.0F, 1e-4F);
  for (std::size_t i = 2; i < kPoints; ++i) EXPECT_NEAR(ps.speed[i], 270.0F, 1e-3F) << i;
  EXPECT_NEAR(ps.max_speed, 270.0F, 1e-3F);
}

TEST(PointSpeeds, NothingMovingNamesNoPoint) {
  PointSpeeds ps{};
  point_speeds(kRobot, zero(), zero(), ps);
  EXPECT_FLOAT_EQ(ps.max_speed, 0.0F);
  EXPECT_EQ(ps.fastest_point, 0);
  EXPECT_EQ(ps.fastest_axis, 0);
}

// @req MO-T1-LIMIT
TEST(PointSpeeds, FoldedWristMakesTheWristCentreFastest) {
  // Forearm up (q3 = -90 deg), wrist bent forward (q5 = +90 deg): the wrist centre is at
  // (-70, 0, 862) and the flange at (2, 0, 862), a little closer to axis 2.
  Joints q = only(3, -kPi / 2);
  q[4] = kPi / 2;
  Frames f{};
  forward(kRobot, q, f);
  expect_vec(f.origin[4], -70, 0, 862, "wrist centre");
  expect_vec(f.origin[6], 2, 0, 862, "flange");
  PointSpeeds ps{};
  point_speeds(kRobot, q, only(2, 1.0F), ps);  // speed = distance from axis 2 (y at z = 290)
  EXPECT_NEAR(ps.speed[3], std::hypot(70.0F, 270.0F), 1e-3F);
  EXPECT_NEAR(ps.speed[6], std::hypot(2.0F, 572.0F), 1e-3F);
  EXPECT_NEAR(ps.max_speed, std::hypot(70.0F, 572.0F), 1e-3F);
  // Origins 4 and 5 coincide exactly (a4 = a5 = d5 = 0); the tie names the distal one.
  EXPECT_EQ(ps.fastest_point, 5);
  EXPECT_EQ(ps.fastest_axis, 5);
}

TEST(PointSpeeds, NonFiniteInputReadsAsInfinitelyFast) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  PointSpeeds ps{};
  point_speeds(kRobot, zero(), only(6, nan), ps);
  EXPECT_TRUE(std::isinf(ps.max_speed));
  EXPECT_EQ(ps.fastest_point, kTcpPoint);
  point_speeds(kRobot, only(2, nan), only(1, 1.0F), ps);
  EXPECT_TRUE(std::isinf(ps.max_speed));
}

// --- T1 speed scaling --------------------------------------------------------------------

// @req MO-T1-LIMIT
TEST(T1Scale, ScaledMotionRunsExactlyAtTheLimit) {
  const RobotModel m = tooled();
  const float limit = 250.0F;  // mm/s, ISO 10218-1 reduced speed
  Rng rng;
  int active = 0;
  for (int n = 0; n < 50; ++n) {
    const Joints q = rng.pose(m);
    const Joints qd = rng.rates(m);
    const float s = t1_scale(m, q, qd, limit);
    ASSERT_GT(s, 0.0F);
    ASSERT_LE(s, 1.0F);
    const float after = max_point_speed(m, q, times(qd, s));
    EXPECT_LE(after, limit * (1.0F + 1e-5F)) << "pose " << n;
    if (s < 1.0F) {
      ++active;
      EXPECT_NEAR(after, limit, limit * 1e-5F) << "pose " << n;
    }
  }
  EXPECT_GT(active, 40);  // full-speed random motions of this arm far exceed 250 mm/s
}

TEST(T1Scale, SlowMotionIsLeftAlone) {
  // Axis 1 at 0.5 rad/s moves the home flange (radius 374 mm) at 187 mm/s.
  EXPECT_FLOAT_EQ(t1_scale(kRobot, zero(), only(1, 0.5F), 250.0F), 1.0F);
  EXPECT_FLOAT_EQ(t1_scale(kRobot, zero(), zero(), 250.0F), 1.0F);
}

// @req MO-T1-LIMIT
TEST(T1Scale, JustAboveTheLimitScalesToIt) {
  // 1 rad/s on axis 1: flange at 374 mm/s, so the factor is 250 / 374.
  EXPECT_NEAR(t1_scale(kRobot, zero(), only(1, 1.0F), 250.0F), 250.0F / 374.0F, 1e-6F);
}

TEST(T1Scale, InvalidInputStops) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(t1_scale(kRobot, zero(), only(1, 1.0F), 0.0F), 0.0F);
  EXPECT_EQ(t1_scale(kRobot, zero(), only(1, 1.0F), -1.0F), 0.0F);
  EXPECT_EQ(t1_scale(kRobot, zero(), only(1, 1.0F), nan), 0.0F);
  EXPECT_EQ(t1_scale(kRobot, zero(), only(4, nan), 250.0F), 0.0F);
  EXPECT_EQ(t1_scale(kRobot, zero(), only(2, inf), 250.0F), 0.0F);
  EXPECT_EQ(t1_scale(kRobot, only(3, nan), only(1, 0.1F), 250.0F), 0.0F);
}

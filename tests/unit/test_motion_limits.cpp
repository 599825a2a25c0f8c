// The motion layer inside the safe limits of SPEC §10 (issue 19, item 3): jogs hold short
// of every kind of limit at 10 % and 100 %, programs outside are flagged, speeds are scaled
// to 95 %, reduced mode ramps down within ramp_ms, recovery allows only improving jogs.
// The drives follow their set-points exactly; every check below recomputes positions and
// distances itself from the measured joint positions (its own box distance and angle),
// not from the planner's clearance functions.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "safestate/core/cia402.hpp"
#include "safestate/motion/back_off.hpp"
#include "safestate/motion/kinematics.hpp"
#include "safestate/motion/limits.hpp"
#include "safestate/motion/motion_controller.hpp"

namespace {

using namespace safestate;
using namespace safestate::motion;

constexpr float kDt = 0.001F;
constexpr std::array<float, 3> kTcp{0.0F, 0.0F, 100.0F};  // a 100 mm tool
constexpr float kRadius = 30.0F;

float rad2deg(float r) { return r * 180.0F / kPi; }

core::SafetyLimits base_limits() {
  core::SafetyLimits l{};
  for (std::size_t i = 0; i < kJoints; ++i) {
    l.joints[i] = {kRobot.q_min_rad[i], kRobot.q_max_rad[i], kRobot.qd_max_rad_s[i]};
  }
  l.tcp_mm = kTcp;
  l.tool_radius_mm = kRadius;
  l.tcp_max_speed_mm_s = 5000.0F;
  return l;
}

void add_zone(core::SafetyLimits& l, core::ZoneKind kind, std::array<float, 3> mn, std::array<float, 3> mx) {
  core::Zone& z = l.zones[l.zone_count++];
  z.name = {'z', static_cast<char>('0' + l.zone_count), '\0'};
  z.kind = kind;
  z.min_mm = mn;
  z.max_mm = mx;
}

RobotModel tool_model() {
  RobotModel m = kRobot;
  m.tcp_offset_mm = kTcp;
  return m;
}

// Test's own box distance (Euclidean outside, minus the nearest face inside).
float box_distance(const Vec3& p, const core::Zone& z) {
  float out = 0.0F;
  float in = -1e9F;
  for (std::size_t k = 0; k < 3; ++k) {
    const float e = std::max(z.min_mm[k] - p[k], p[k] - z.max_mm[k]);
    out += (e > 0.0F) ? e * e : 0.0F;
    in = std::max(in, e);
  }
  return std::sqrt(out) + std::min(in, 0.0F);
}

// The smallest distance by which the TCP sphere and link origins 2..6 keep clear of the
// limit of zone z (< 0: violated), computed from joint positions with the test's own math.
float zone_clearance(const Joints& q, const core::Zone& z) {
  Frames f{};
  forward(tool_model(), q, f);
  float c = 1e9F;
  for (std::size_t k = 2; k <= 6; ++k) {
    const float d = box_distance(f.origin[k], z);
    c = std::min(c, z.kind == core::ZoneKind::keep_in ? -d : d);
  }
  const float d = box_distance(f.tcp, z);
  return std::min(c, z.kind == core::ZoneKind::keep_in ? -d - kRadius : d - kRadius);
}

float tool_angle(const Joints& q, const Vec3& axis) {
  Frames f{};
  forward(tool_model(), q, f);
  const float c = f.R[0][2] * axis[0] + f.R[1][2] * axis[1] + f.R[2][2] * axis[2];
  return std::acos(std::clamp(c, -1.0F, 1.0F));
}

// A controller whose six drives follow every set-point exactly.
struct Rig {
  MotionController mc{kRobot, MotionConfig{}};
  std::array<core::DriveFeedback, kJoints> drives{};
  std::array<hal::DriveOut, kJoints> out{};
  core::Feedback fb{};
  Joints prev{};

  explicit Rig(const Joints& q0, const core::SafetyLimits* lim) {
    if (lim != nullptr) {
      mc.set_limits(*lim);
    }
    for (std::size_t i = 0; i < kJoints; ++i) {
      drives[i].statusword = core::cia402::statusword_of(core::cia402::DriveState::OperationEnabled);
      drives[i].position_rad = q0[i];
    }
    prev = q0;
    core::SupervisorOut so{};
    so.motion.mode = core::MotionMode::Track;
    cycle(so);
  }
  Joints q() const {
    Joints r{};
    for (std::size_t i = 0; i < kJoints; ++i) r[i] = drives[i].position_rad;
    return r;
  }
  void cycle(const core::SupervisorOut& so) {
    prev = q();
    mc.measure(drives, fb);
    mc.step(so, drives, out);
    for (std::size_t i = 0; i < kJoints; ++i) drives[i].position_rad = out[i].target_position_rad;
  }
  // Measured speeds of the last cycle.
  float joint_speed(std::size_t i) const { return std::fabs(q()[i] - prev[i]) / kDt; }
  float tcp_speed() const {
    Joints qd{};
    for (std::size_t i = 0; i < kJoints; ++i) qd[i] = (q()[i] - prev[i]) / kDt;
    PointSpeeds ps{};
    point_speeds(tool_model(), prev, qd, ps);
    return ps.speed[kTcpPoint];
  }
};

core::SupervisorOut jog(std::uint8_t axis, std::int8_t dir, std::uint8_t speed, bool recovery = false) {
  core::SupervisorOut so{};
  so.drives_enable = true;
  so.brakes_release = true;
  so.motion.mode = core::MotionMode::Jog;
  so.motion.jog = {axis, dir, speed};
  so.motion.recovery = recovery;
  return so;
}

core::SupervisorOut run_program(core::ProgramCmd cmd = core::ProgramCmd::None) {
  core::SupervisorOut so{};
  so.drives_enable = true;
  so.brakes_release = true;
  so.motion.mode = core::MotionMode::Program;
  so.motion.program = cmd;
  return so;
}

// ------------------------------------------------------------------ jog: holds short
struct JogResult {
  float worst = 1e9F;  // the smallest clearance met on the way
  float final = 0.0F;  // clearance where it holds
  bool still = false;  // the arm stopped
  bool jog_active = false;
};

template <typename Clear>
JogResult jog_into(const core::SafetyLimits& lim, const Joints& q0, std::uint8_t axis, std::int8_t dir,
                   std::uint8_t speed, Clear clearance) {
  Rig rig(q0, &lim);
  JogResult r;
  const int cycles = (speed >= 100) ? 2000 : 8000;  // long enough to reach the limit and stand
  for (int n = 0; n < cycles; ++n) {
    rig.cycle(jog(axis, dir, speed));
    r.worst = std::min(r.worst, clearance(rig.q()));
  }
  r.final = clearance(rig.q());
  r.still = rig.joint_speed(axis - 1U) == 0.0F;
  r.jog_active = rig.mc.axis_state(axis - 1U) == AxisState::ContinuousMotion;
  return r;
}

class JogHolds : public ::testing::TestWithParam<int> {};

// @req MO-LIMITS-JOG
TEST_P(JogHolds, ShortOfAJointLimitWithinTheMargin) {
  core::SafetyLimits lim = base_limits();
  lim.joints[0].max_rad = deg(30.0F);
  const auto speed = static_cast<std::uint8_t>(GetParam());
  const JogResult r = jog_into(lim, Joints{}, 1, +1, speed, [](const Joints& q) { return deg(30.0F) - q[0]; });
  EXPECT_GE(rad2deg(r.worst), 1.0F - 1e-3F) << "entered the 1 deg margin";
  EXPECT_LE(rad2deg(r.final), 1.2F) << "held too far from the limit";
  EXPECT_TRUE(r.still);
  EXPECT_TRUE(r.jog_active);
}

// @req MO-LIMITS-JOG
TEST_P(JogHolds, ShortOfAKeepOutZoneWithinTheMargin) {
  core::SafetyLimits lim = base_limits();
  add_zone(lim, core::ZoneKind::keep_out, {300, -300, 0}, {900, 300, 300});  // a table under the tool
  const core::Zone z = lim.zones[0];
  const auto speed = static_cast<std::uint8_t>(GetParam());
  const JogResult r = jog_into(lim, Joints{}, 2, +1, speed, [&](const Joints& q) { return zone_clearance(q, z); });
  EXPECT_GE(r.worst, kZoneMarginMm - kStepFloorMm) << "entered the 10 mm margin";
  EXPECT_LE(r.final, 25.0F) << "held too far from the zone";
  EXPECT_TRUE(r.still);
  EXPECT_TRUE(r.jog_active);
}

// @req MO-LIMITS-JOG
TEST_P(JogHolds, InsideAKeepInZoneWithinTheMargin) {
  core::SafetyLimits lim = base_limits();
  add_zone(lim, core::ZoneKind::keep_in, {-700, -300, 0}, {700, 300, 1000});  // the cell
  add_zone(lim, core::ZoneKind::reduced, {-700, -700, 0}, {700, 700, 1000});  // speed only
  const core::Zone z = lim.zones[0];
  const auto speed = static_cast<std::uint8_t>(GetParam());
  const JogResult r = jog_into(lim, Joints{}, 1, +1, speed, [&](const Joints& q) { return zone_clearance(q, z); });
  EXPECT_GE(r.worst, kZoneMarginMm - kStepFloorMm) << "entered the 10 mm margin";
  EXPECT_LE(r.final, 25.0F) << "held too far from the wall";
  EXPECT_TRUE(r.still);
  EXPECT_TRUE(r.jog_active);
}

// @req MO-LIMITS-JOG
TEST_P(JogHolds, ShortOfTheOrientationCone) {
  core::SafetyLimits lim = base_limits();
  lim.orientation_enabled = true;
  lim.orientation_axis = {2.0F, 0.0F, 0.0F};  // not unit: the planner normalises
  lim.orientation_max_deviation_rad = deg(30.0F);
  const auto speed = static_cast<std::uint8_t>(GetParam());
  const JogResult r = jog_into(lim, Joints{}, 5, +1, speed, [](const Joints& q) {
    return deg(30.0F) - tool_angle(q, {1.0F, 0.0F, 0.0F});
  });
  EXPECT_GE(rad2deg(r.worst), 1.0F - 0.1F) << "entered the 1 deg margin";
  EXPECT_LE(rad2deg(r.final), 3.0F) << "held too far from the cone";
  EXPECT_TRUE(r.still);
  EXPECT_TRUE(r.jog_active);
}

INSTANTIATE_TEST_SUITE_P(AtSpeed, JogHolds, ::testing::Values(10, 100),
                         [](const ::testing::TestParamInfo<int>& p) { return "percent" + std::to_string(p.param); });

// Without set_limits nothing changes: the robot's own range (less 0.02 rad) is the bound.
TEST(MotionLimits, WithoutLimitsTheJogRunsToTheRobotsOwnRange) {
  Rig rig(Joints{}, nullptr);
  for (int n = 0; n < 4000; ++n) rig.cycle(jog(1, +1, 100));
  EXPECT_NEAR(rig.q()[0], kRobot.q_max_rad[0] - MotionConfig{}.limit_margin_rad, 2e-3F);
  EXPECT_TRUE(rig.fb.program_within_limits);
}

// ------------------------------------------------------------------ programs
std::array<Waypoint, 3> swing() {  // base turns from -60 to +60 deg and back to 0 deg
  std::array<Waypoint, 3> w{};
  w[0].q[0] = -deg(60.0F);
  w[1].q[0] = deg(60.0F);
  w[2].q[0] = -deg(30.0F);
  return w;
}

bool flagged(const core::SafetyLimits& lim, const Waypoint* w, std::uint8_t n, const Joints& at) {
  Rig rig(at, &lim);
  rig.mc.load_program(w, n);
  rig.cycle(core::SupervisorOut{});  // measure() reports the flag
  return rig.fb.program_within_limits;
}

// @req MO-LIMITS-PROGRAM
TEST(ProgramLimits, InsideIsAccepted) {
  const auto w = swing();
  Joints at{};
  at[0] = -deg(60.0F);
  EXPECT_TRUE(flagged(base_limits(), w.data(), 3, at));
}

// @req MO-LIMITS-PROGRAM
TEST(ProgramLimits, AWaypointPastAJointLimitLessItsMarginIsRefused) {
  const auto w = swing();
  Joints at{};
  at[0] = -deg(60.0F);
  core::SafetyLimits lim = base_limits();
  lim.joints[0].max_rad = deg(60.5F);  // the waypoint at 60 deg is inside the limit, not the margin
  EXPECT_FALSE(flagged(lim, w.data(), 3, at));
  lim.joints[0].max_rad = deg(61.5F);
  EXPECT_TRUE(flagged(lim, w.data(), 3, at));
}

// @req MO-LIMITS-PROGRAM
TEST(ProgramLimits, AWaypointInsideAKeepOutZoneIsRefused) {
  const auto w = swing();
  Joints at{};
  at[0] = -deg(60.0F);
  core::SafetyLimits lim = base_limits();
  // Around the TCP at the last waypoint (-30 deg): (410, -237, 630).
  add_zone(lim, core::ZoneKind::keep_out, {380, -280, 600}, {440, -200, 660});
  EXPECT_FALSE(flagged(lim, w.data(), 3, at));
}

// @req MO-LIMITS-PROGRAM
TEST(ProgramLimits, APathThroughAKeepOutBoxBetweenTwoWaypointsOutsideItIsRefused) {
  const auto w = swing();
  Joints at{};
  at[0] = -deg(60.0F);
  core::SafetyLimits lim = base_limits();
  add_zone(lim, core::ZoneKind::keep_out, {400, -50, 500}, {700, 50, 800});  // where the TCP passes at 0 deg
  // Both ends well clear of it (the test's own distance), only the path crosses it.
  Joints a{};
  a[0] = -deg(60.0F);
  Joints b{};
  b[0] = deg(60.0F);
  ASSERT_GT(zone_clearance(a, lim.zones[0]), 100.0F);
  ASSERT_GT(zone_clearance(b, lim.zones[0]), 100.0F);
  EXPECT_FALSE(flagged(lim, w.data(), 3, at));
  // The same box a little higher than the tool passes, plus the margin: accepted.
  lim.zones[0].min_mm[2] = 630.0F + kRadius + kZoneMarginMm + 2.0F;
  EXPECT_TRUE(flagged(lim, w.data(), 3, at));
}

// @req MO-LIMITS-PROGRAM
TEST(ProgramLimits, ThePathFromTheArmToTheFirstWaypointCountsAndIsRecheckedWhenTheArmMoves) {
  const auto w = swing();
  core::SafetyLimits lim = base_limits();
  add_zone(lim, core::ZoneKind::keep_out, {400, -50, 500}, {700, 50, 800});
  const std::array<Waypoint, 1> first{w[1]};  // +60 deg only: no path between waypoints
  Joints left{};
  left[0] = -deg(60.0F);  // to +60 through the box
  EXPECT_FALSE(flagged(lim, first.data(), 1, left));
  Joints right{};
  right[0] = deg(90.0F);  // to +60 without passing it
  EXPECT_TRUE(flagged(lim, first.data(), 1, right));
  // Loaded once with the arm on the right; then the arm is found on the left (moved with
  // power off, tracked): the flag follows without a reload.
  Rig rig(right, &lim);
  rig.mc.load_program(first.data(), 1);
  rig.cycle(core::SupervisorOut{});
  EXPECT_TRUE(rig.fb.program_within_limits);
  for (std::size_t i = 0; i < kJoints; ++i) rig.drives[i].position_rad = left[i];
  rig.cycle(core::SupervisorOut{});
  EXPECT_FALSE(rig.fb.program_within_limits);
  EXPECT_TRUE(rig.mc.start_within_limits(right));
  EXPECT_FALSE(rig.mc.start_within_limits(left));
}

// @req MO-LIMITS-PROGRAM
TEST(ProgramLimits, SetLimitsAfterLoadingRechecksAndStartOutsideDoesNotMove) {
  const auto w = swing();
  Joints at{};
  at[0] = -deg(60.0F);
  core::SafetyLimits lim = base_limits();
  add_zone(lim, core::ZoneKind::keep_out, {400, -50, 500}, {700, 50, 800});
  MotionController mc{kRobot, MotionConfig{}};
  mc.load_program(w.data(), 3);
  EXPECT_TRUE(mc.program_within_limits());
  mc.set_limits(lim);
  EXPECT_FALSE(mc.program_within_limits());
  // A start that arrives anyway (a faulty supervisor) does not move the arm.
  Rig rig(at, &lim);
  rig.mc.load_program(w.data(), 3);
  rig.cycle(run_program(core::ProgramCmd::Start));
  for (int n = 0; n < 200; ++n) rig.cycle(run_program());
  EXPECT_EQ(rig.q()[0], at[0]);
}

// The motion layer's own barrier behind OUTSIDE_LIMITS (MC/DC): waypoints and the path
// between them inside, only the leg from where the arm stands through a keep-out box; a
// start that arrives anyway does not move. Without limits or without a program there is no
// leg to refuse.
// @req MO-LIMITS-PROGRAM
TEST(ProgramLimits, AStartWhoseOnlyFaultIsTheFirstLegDoesNotMove) {
  const auto w = swing();
  core::SafetyLimits lim = base_limits();
  add_zone(lim, core::ZoneKind::keep_out, {400, -50, 500}, {700, 50, 800});
  const std::array<Waypoint, 1> first{w[1]};  // +60 deg
  Joints left{};
  left[0] = -deg(60.0F);
  Rig rig(left, &lim);
  rig.mc.load_program(first.data(), 1);
  rig.cycle(core::SupervisorOut{});
  ASSERT_TRUE(rig.mc.program_within_limits()) << "the waypoint alone is inside";
  ASSERT_FALSE(rig.fb.program_within_limits) << "the leg from the arm crosses the box";
  rig.cycle(run_program(core::ProgramCmd::Start));
  for (int n = 0; n < 200; ++n) rig.cycle(run_program());
  EXPECT_EQ(rig.q()[0], left[0]);
  Joints right{};
  right[0] = deg(90.0F);
  Rig moves(right, &lim);
  moves.mc.load_program(first.data(), 1);
  moves.cycle(core::SupervisorOut{});
  moves.cycle(run_program(core::ProgramCmd::Start));
  for (int n = 0; n < 200; ++n) moves.cycle(run_program());
  EXPECT_LT(moves.q()[0], right[0]) << "the same program from the right starts";

  MotionController bare{kRobot, MotionConfig{}};
  EXPECT_TRUE(bare.start_within_limits(left)) << "no limits: nothing to refuse";
  bare.set_limits(lim);
  EXPECT_TRUE(bare.start_within_limits(left)) << "no program: no leg";
  bare.load_program(first.data(), 1);
  EXPECT_FALSE(bare.start_within_limits(left));
}

// A program at its end holds its last waypoint while the supervisor still asks for program
// motion (the cycle before it sees program_finished): no jump back to where it started.
// @req MO-LIMITS-PROGRAM
TEST(ProgramLimits, AFinishedProgramHoldsItsLastWaypoint) {
  const auto w = swing();
  Joints at{};
  at[0] = -deg(60.0F);
  const core::SafetyLimits lim = base_limits();
  Rig rig(at, &lim);
  rig.mc.load_program(w.data(), 3);
  rig.cycle(core::SupervisorOut{});
  rig.cycle(run_program(core::ProgramCmd::Start));
  int n = 0;
  for (; n < 20000 && !rig.fb.program_finished; ++n) rig.cycle(run_program());
  ASSERT_TRUE(rig.fb.program_finished) << "the swing ends";
  const Joints end = rig.q();
  EXPECT_NEAR(end[0], -deg(30.0F), 1e-4F);
  for (int k = 0; k < 200; ++k) rig.cycle(run_program());
  EXPECT_EQ(rig.q(), end);
}

// The axis under brake test is pushed off its set-point on purpose (SPEC §12): not a
// following error; another axis lagging at the same time still is.
// @req BT-SEQUENCE
TEST(FollowingError, TheAxisUnderBrakeTestIsNotAFollowingError) {
  Joints at{};
  Rig rig(at, nullptr);
  core::SupervisorOut so{};
  so.drives_enable = true;
  so.brakes_release = true;
  so.motion.mode = core::MotionMode::Hold;
  so.motion.brake_test.axis = 2;
  rig.cycle(so);
  rig.drives[1].position_rad = 0.2F;  // axis 2 slips off its set-point
  rig.mc.measure(rig.drives, rig.fb);
  EXPECT_EQ(rig.fb.following_error_axis, 0U);
  rig.drives[2].position_rad = 0.2F;  // and axis 3, which is not tested, too
  rig.mc.measure(rig.drives, rig.fb);
  EXPECT_EQ(rig.fb.following_error_axis, 3U);
}

// The retrace of a collision's back-off (COL-BACKOFF) on its own: before begin() and with
// nothing recorded there is nothing to do; with a straight path it goes back 10 mm of it.
// @req COL-BACKOFF
TEST(BackOff, NothingRecordedOrNotBegunIsNoMotion) {
  BackOff b;
  Joints q{};
  Joints v{};
  v.fill(1.0F);
  b.step(0.001F, q, v);
  EXPECT_EQ(v, Joints{}) << "not begun: still";
  EXPECT_FALSE(b.started());
  b.begin(q, Vec3{300.0F, 0.0F, 600.0F});
  EXPECT_TRUE(b.done()) << "nothing recorded: done at once";
  EXPECT_EQ(b.distance_mm(), 0.0F);
  v.fill(1.0F);
  b.step(0.001F, q, v);
  EXPECT_EQ(v, Joints{});
  EXPECT_EQ(q, Joints{});
}

// @req COL-BACKOFF
TEST(BackOff, RetracesTenMillimetresOfAStraightPath) {
  BackOff b;
  for (int k = 0; k <= 30; ++k) {  // 1 mm per sample along x, axis 1 at 1 mrad per mm
    Joints q{};
    q[0] = 0.001F * static_cast<float>(k);
    b.record(q, Vec3{300.0F + static_cast<float>(k), 0.0F, 600.0F});
  }
  Joints q{};
  q[0] = 0.030F;
  b.begin(q, Vec3{330.0F, 0.0F, 600.0F});
  EXPECT_NEAR(b.distance_mm(), 10.0F, 1e-3F);
  Joints v{};
  int n = 0;
  for (; n < 5000 && !b.done(); ++n) b.step(0.001F, q, v);
  ASSERT_TRUE(b.done());
  EXPECT_NEAR(q[0], 0.020F, 1e-5F) << "10 mm back along the recorded path";
  EXPECT_GE(n, 100) << "at most 100 mm/s: 10 mm take 100 ms or more";
}

// Which limits make the planner predict stopping paths (cartesian()): a keep-in or keep-out
// zone anywhere in the list, or an orientation cone with an axis; reduced zones and a cone
// without an axis do not (MC/DC of LimitPlanner::configure).
// @req MO-LIMITS-JOG
TEST(LimitPlanner, OnlyZonesThatLimitAndAConeWithAnAxisArePredicted) {
  core::SafetyLimits l = base_limits();
  LimitPlanner p;
  p.configure(l, tool_model(), 0.0F);
  EXPECT_FALSE(p.cartesian()) << "joints only";
  add_zone(l, core::ZoneKind::reduced, {0, 0, 0}, {100, 100, 100});
  p.configure(l, tool_model(), 0.0F);
  EXPECT_FALSE(p.cartesian()) << "a reduced zone slows, it does not limit the path";
  add_zone(l, core::ZoneKind::keep_out, {500, 500, 0}, {600, 600, 100});
  add_zone(l, core::ZoneKind::reduced, {0, 0, 0}, {50, 50, 50});
  p.configure(l, tool_model(), 0.0F);
  EXPECT_TRUE(p.cartesian()) << "a keep-out box between two reduced zones";
  l = base_limits();
  l.orientation_enabled = true;
  l.orientation_axis = {0.0F, 0.0F, 0.0F};
  p.configure(l, tool_model(), 0.0F);
  EXPECT_FALSE(p.cartesian()) << "a cone without an axis is no cone";
  l.orientation_axis = {0.0F, 0.0F, -2.0F};
  p.configure(l, tool_model(), 0.0F);
  EXPECT_TRUE(p.cartesian());
}

// A pose whose clearance is not a number (a joint position lost) has no slack.
// @req MO-LIMITS-JOG
TEST(LimitPlanner, NoSlackWhereTheClearanceIsUnknown) {
  core::SafetyLimits l = base_limits();
  add_zone(l, core::ZoneKind::keep_out, {500, 500, 0}, {600, 600, 100});
  LimitPlanner p;
  p.configure(l, tool_model(), 0.0F);
  Clearance thr{};
  p.margins(thr);
  EXPECT_TRUE(p.path_clear(Joints{}, Joints{}, thr, 4U));
  Joints lost{};
  lost[1] = std::nanf("");
  EXPECT_FALSE(p.path_clear(Joints{}, lost, thr, 4U)) << "a path to an unknown pose";
  EXPECT_FALSE(p.path_clear(lost, lost, thr, 4U));
}

// A back-off cut short: the stop ends (or escalates) while the arm retraces; the retrace is
// dropped at once and the arm holds where it is (MC/DC of the controller's cancel).
// @req COL-BACKOFF
TEST(BackOff, EndingTheStopMidwayDropsTheRetraceAndHolds) {
  Rig rig(Joints{}, nullptr);
  for (int n = 0; n < 300; ++n) rig.cycle(jog(1, +1, 100));
  core::SupervisorOut stop{};
  stop.drives_enable = true;
  stop.brakes_release = true;
  stop.motion.mode = core::MotionMode::Ramp2;
  stop.motion.back_off = true;
  // The Cat 2 ramp first (backing_off already says the stop is not over), then, at rest, the
  // retrace: axis 1 turning back.
  float before = rig.q()[0];
  bool retracing = false;
  for (int n = 0; n < 3000 && !retracing; ++n) {
    rig.cycle(stop);
    retracing = rig.q()[0] < before;
    before = rig.q()[0];
  }
  ASSERT_TRUE(retracing) << "at rest, the back-off begins";
  ASSERT_TRUE(rig.fb.backing_off);
  for (int k = 0; k < 20; ++k) rig.cycle(stop);
  ASSERT_LT(rig.q()[0], before) << "still retracing";
  const float mid = rig.q()[0];
  core::SupervisorOut hold = stop;
  hold.motion.mode = core::MotionMode::Hold;
  hold.motion.back_off = false;
  rig.cycle(hold);
  rig.cycle(hold);
  EXPECT_FALSE(rig.fb.backing_off) << "the retrace is dropped with the stop";
  const float held = rig.q()[0];
  EXPECT_LT(held, mid + 1e-6F) << "it went back, not forward";
  for (int k = 0; k < 100; ++k) rig.cycle(hold);
  EXPECT_EQ(rig.q()[0], held) << "and holds there";
  // The path is recorded again from here: a later collision backs off along the new motion
  // (axis 2), not along the old one.
  for (int k = 0; k < 300; ++k) rig.cycle(jog(2, +1, 100));
  const float axis1 = rig.q()[0];
  float top = rig.q()[1];
  bool back = false;
  for (int k = 0; k < 3000 && !back; ++k) {
    rig.cycle(stop);
    back = rig.q()[1] < top - 1e-4F;
    top = std::max(top, rig.q()[1]);
  }
  EXPECT_TRUE(back) << "the second back-off retraces axis 2's path";
  EXPECT_EQ(rig.q()[0], axis1);
}

// A first sample that comes stale (the bus's first exchange late) is still the first sample:
// the next one is differentiated against it, over one cycle.
// @req MO-SAMPLE-TIME
TEST(MeasuredSpeed, AStaleFirstSampleStillStartsTheDifferentiation) {
  MotionController mc{kRobot, MotionConfig{}};
  std::array<core::DriveFeedback, kJoints> drives{};
  core::Feedback fb{};
  mc.measure(drives, fb, true);
  EXPECT_EQ(fb.max_point_speed_mm_s, 0.0F);
  drives[0].position_rad = 0.001F;  // 1 rad/s on axis 1 over one 1 ms cycle
  mc.measure(drives, fb, false);
  EXPECT_NEAR(fb.tcp_speed_mm_s, 374.0F, 5.0F) << "the flange at ~374 mm from axis 1";
  drives[0].position_rad = 0.002F;
  mc.measure(drives, fb, true);  // stale now: the last speeds stand
  EXPECT_NEAR(fb.tcp_speed_mm_s, 374.0F, 5.0F);
  drives[0].position_rad = 0.003F;
  mc.measure(drives, fb, false);  // 2 mrad over the two cycles since the last fresh one
  EXPECT_NEAR(fb.tcp_speed_mm_s, 374.0F, 5.0F) << "over the real time between the samples";
}

// On EtherCAT with distributed clocks the drives sample at SYNC0: a frame late past its pulse
// carries the next pulse's sample (two cycles of motion since the last), the frame after it
// the same sample again. Differentiated over the frames, a steady 1 rad/s would read 2 then 0.
// @req MO-SAMPLE-TIME
TEST(MeasuredSpeed, SamplesAreDifferentiatedOverTheirSync0CyclesNotOverTheFrames) {
  MotionController mc{kRobot, MotionConfig{}};
  std::array<core::DriveFeedback, kJoints> drives{};
  core::Feedback fb{};
  mc.measure(drives, fb, false, 1);
  drives[0].position_rad = 0.001F;  // 1 rad/s on axis 1: ~374 mm/s at the flange
  mc.measure(drives, fb, false, 1);
  EXPECT_NEAR(fb.tcp_speed_mm_s, 374.0F, 5.0F);
  drives[0].position_rad = 0.003F;  // a late frame: the sample two pulses after the last
  mc.measure(drives, fb, false, 2);
  EXPECT_NEAR(fb.tcp_speed_mm_s, 374.0F, 5.0F) << "two cycles of motion over two cycles";
  mc.measure(drives, fb, false, 0);  // the next frame on time: the same sample again
  EXPECT_NEAR(fb.tcp_speed_mm_s, 374.0F, 5.0F) << "no new sample: the last speeds stand, not 0";
  drives[0].position_rad = 0.004F;
  mc.measure(drives, fb, false, 1);
  EXPECT_NEAR(fb.tcp_speed_mm_s, 374.0F, 5.0F) << "against the sample before, one pulse on";
  // Without the sampling instants (-1), the same frames would be judged by their count.
  MotionController blind{kRobot, MotionConfig{}};
  drives[0].position_rad = 0.001F;
  blind.measure(drives, fb, false);
  drives[0].position_rad = 0.003F;
  blind.measure(drives, fb, false);
  EXPECT_NEAR(fb.tcp_speed_mm_s, 2.0F * 374.0F, 10.0F) << "what the core saw before: a doubled speed";
}

// ------------------------------------------------------------------ speeds
// @req MO-LIMITS-SPEED
TEST(SpeedLimits, AJogKeepsTheJointAt95PercentOfItsLimit) {
  core::SafetyLimits lim = base_limits();
  lim.joints[0].max_speed_rad_s = deg(40.0F);  // the jog at 100 % asks for 125 deg/s
  Joints q0{};
  q0[0] = -deg(100.0F);
  Rig rig(q0, &lim);
  float top = 0.0F;
  for (int n = 0; n < 1000; ++n) {
    rig.cycle(jog(1, +1, 100));
    top = std::max(top, rig.joint_speed(0));
  }
  EXPECT_LE(top, 0.95F * deg(40.0F) * 1.0001F);
  EXPECT_GE(top, 0.95F * deg(40.0F) * 0.99F);  // and it does reach it
}

// @req MO-LIMITS-SPEED
TEST(SpeedLimits, AJogKeepsTheTcpAt95PercentOfItsLimit) {
  core::SafetyLimits lim = base_limits();
  lim.tcp_max_speed_mm_s = 300.0F;  // the jog at 100 % would move the TCP at ~1 m/s
  Joints q0{};
  q0[0] = -deg(100.0F);
  Rig rig(q0, &lim);
  float top = 0.0F;
  for (int n = 0; n < 1000; ++n) {
    rig.cycle(jog(1, +1, 100));
    top = std::max(top, rig.tcp_speed());
  }
  EXPECT_LE(top, 0.95F * 300.0F * 1.001F);
  EXPECT_GE(top, 0.95F * 300.0F * 0.99F);
}

// @req MO-LIMITS-SPEED
TEST(SpeedLimits, AProgramIsScaledNotRefused) {
  const auto w = swing();
  core::SafetyLimits lim = base_limits();
  lim.tcp_max_speed_mm_s = 400.0F;
  lim.joints[0].max_speed_rad_s = deg(100.0F);
  Joints at{};
  at[0] = -deg(60.0F);
  Rig rig(at, &lim);
  rig.mc.load_program(w.data(), 3);
  rig.cycle(core::SupervisorOut{});
  EXPECT_TRUE(rig.fb.program_within_limits);
  rig.cycle(run_program(core::ProgramCmd::Start));
  float tcp = 0.0F;
  float joint = 0.0F;
  for (int n = 0; n < 8000 && !rig.mc.program().finished(); ++n) {
    rig.cycle(run_program());
    tcp = std::max(tcp, rig.tcp_speed());
    joint = std::max(joint, rig.joint_speed(0));
  }
  EXPECT_TRUE(rig.mc.program().finished());
  EXPECT_LE(tcp, 0.95F * 400.0F * 1.001F);
  EXPECT_GE(tcp, 0.95F * 400.0F * 0.98F);
  EXPECT_LE(joint, 0.95F * deg(100.0F) * 1.001F);
}

// ------------------------------------------------------------------ reduced mode
// @req MO-LIMITS-REDUCED
TEST(ReducedMode, RampsTheTcpDownWithinRampMsWithoutAStepAndBackUp) {
  core::SafetyLimits lim = base_limits();
  lim.reduced_tcp_max_speed_mm_s = 250.0F;
  lim.reduced_ramp_ms = 500;
  Joints q0{};
  q0[0] = -deg(150.0F);
  Rig rig(q0, &lim);
  for (int n = 0; n < 300; ++n) rig.cycle(jog(1, +1, 100));  // up to speed: ~1 m/s at the TCP
  const float before = rig.tcp_speed();
  ASSERT_GT(before, 900.0F);
  auto so = jog(1, +1, 100);
  so.motion.reduced = true;
  float last = before;
  float worst_drop = 0.0F;
  for (int n = 1; n <= 1000; ++n) {
    rig.cycle(so);
    const float v = rig.tcp_speed();
    worst_drop = std::max(worst_drop, last - v);
    last = v;
    if (n >= 500) {
      ASSERT_LE(v, 0.95F * 250.0F * 1.001F) << "at " << n << " ms";
    }
  }
  // A linear ramp over 0.8 x 500 ms: at most (before - 237.5) / 400 mm/s per cycle (+5 %:
  // the ramp is of the allowed speed, the measured one also changes with the pose).
  EXPECT_LE(worst_drop, (before - 237.5F) / 400.0F * 1.05F);
  EXPECT_GE(last, 0.95F * 250.0F * 0.99F);
  // Cleared: back up, again gradually.
  so.motion.reduced = false;
  float worst_rise = 0.0F;
  for (int n = 0; n < 1000; ++n) {
    rig.cycle(so);
    const float v = rig.tcp_speed();
    worst_rise = std::max(worst_rise, v - last);
    last = v;
  }
  EXPECT_GT(last, 900.0F);
  EXPECT_LE(worst_rise, (0.95F * 5000.0F - 237.5F) / 500.0F * 1.01F);
}

// @req MO-LIMITS-REDUCED
TEST(ReducedMode, AProgramIsSlowedWithinRampMsToo) {
  const auto w = swing();
  core::SafetyLimits lim = base_limits();
  lim.reduced_ramp_ms = 300;
  Joints at{};
  at[0] = -deg(60.0F);
  Rig rig(at, &lim);
  rig.mc.load_program(w.data(), 3);
  rig.cycle(run_program(core::ProgramCmd::Start));
  for (int n = 0; n < 200; ++n) rig.cycle(run_program());
  ASSERT_GT(rig.tcp_speed(), 600.0F);
  auto so = run_program();
  so.motion.reduced = true;
  for (int n = 1; n <= 600; ++n) {
    rig.cycle(so);
    if (n >= 300) {
      ASSERT_LE(rig.tcp_speed(), 0.95F * 250.0F * 1.001F) << "at " << n << " ms";
    }
  }
}

// ------------------------------------------------------------------ recovery
// Each case: the arm starts with a limit violated; a jog one way would make it worse and
// must not move the arm at all; the other way improves it and moves.
struct Moves {
  float worse;
  float better;
};

Moves recovery_jogs(const core::SafetyLimits& lim, const Joints& q0, std::uint8_t axis) {
  Rig w(q0, &lim);
  for (int n = 0; n < 300; ++n) w.cycle(jog(axis, +1, 10, true));
  Rig b(q0, &lim);
  for (int n = 0; n < 300; ++n) b.cycle(jog(axis, -1, 10, true));
  return {std::fabs(w.q()[axis - 1U] - q0[axis - 1U]), std::fabs(b.q()[axis - 1U] - q0[axis - 1U])};
}

// @req MO-LIMITS-RECOVERY
TEST(Recovery, AJointPastItsLimitOnlyMovesBack) {
  core::SafetyLimits lim = base_limits();
  lim.joints[0].min_rad = -deg(30.0F);
  lim.joints[0].max_rad = -deg(10.0F);  // the arm at 0 deg is 10 deg past it
  const Moves m = recovery_jogs(lim, Joints{}, 1);
  EXPECT_EQ(m.worse, 0.0F);
  EXPECT_GT(m.better, deg(1.0F));
}

// @req MO-LIMITS-RECOVERY
TEST(Recovery, TheSphereInAKeepOutBoxOnlyMovesOut) {
  core::SafetyLimits lim = base_limits();
  // The TCP (474, 0, 630) is 34 mm inside the box's x = 440 face: +axis 2 takes it deeper.
  add_zone(lim, core::ZoneKind::keep_out, {440, -50, 500}, {700, 50, 800});
  ASSERT_LT(zone_clearance(Joints{}, lim.zones[0]), 0.0F);
  const Moves m = recovery_jogs(lim, Joints{}, 2);
  EXPECT_EQ(m.worse, 0.0F);
  EXPECT_GT(m.better, deg(1.0F));
}

// @req MO-LIMITS-RECOVERY
TEST(Recovery, TheSphereOutOfAKeepInBoxOnlyMovesIn) {
  core::SafetyLimits lim = base_limits();
  add_zone(lim, core::ZoneKind::keep_in, {-700, -700, 0}, {480, 700, 1000});  // TCP sphere pokes out at +x
  ASSERT_LT(zone_clearance(Joints{}, lim.zones[0]), 0.0F);
  const Moves m = recovery_jogs(lim, Joints{}, 2);  // +axis 2: forward, further out
  EXPECT_EQ(m.worse, 0.0F);
  EXPECT_GT(m.better, deg(1.0F));
}

// @req MO-LIMITS-RECOVERY
TEST(Recovery, TheToolAxisOutsideTheConeOnlyTurnsBack) {
  core::SafetyLimits lim = base_limits();
  lim.orientation_enabled = true;
  lim.orientation_axis = {1.0F, 0.0F, 0.0F};
  lim.orientation_max_deviation_rad = deg(10.0F);
  Joints q0{};
  q0[4] = deg(20.0F);
  const Moves m = recovery_jogs(lim, q0, 5);
  EXPECT_EQ(m.worse, 0.0F);
  EXPECT_GT(m.better, deg(1.0F));
}

// Inside a margin but not violated (a stop that overshot into it): the same rule, so the
// arm is never stuck there and never goes deeper.
// @req MO-LIMITS-RECOVERY
TEST(Recovery, InsideTheMarginTheJogMayLeaveButNotGoDeeper) {
  core::SafetyLimits lim = base_limits();
  add_zone(lim, core::ZoneKind::keep_out, {300, -300, 0}, {900, 300, 630.0F - kRadius - 5.0F});  // 5 mm below
  ASSERT_GT(zone_clearance(Joints{}, lim.zones[0]), 4.0F);
  ASSERT_LT(zone_clearance(Joints{}, lim.zones[0]), 6.0F);
  const Moves m = recovery_jogs(lim, Joints{}, 2);  // +axis 2 lowers the tool
  EXPECT_EQ(m.worse, 0.0F);
  EXPECT_GT(m.better, deg(1.0F));
}

}  // namespace

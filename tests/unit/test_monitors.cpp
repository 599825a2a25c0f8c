// The monitors of core/src/monitors/ that the state machine's own tests reach only through
// the cells they run in, driven one cycle at a time through their one entry (monitor.hpp),
// and the supervisor's diverse output check, which no correct table can fail, fed outputs
// that contradict their state on purpose (each operand alone).
#include <gtest/gtest.h>

#include <cmath>

#include "monitor_harness.hpp"
#include "safestate/core/supervisor.hpp"

using namespace safestate;
using core::AlarmId;
using core::Leaf;
using safestate::test::found;

namespace {

// One cycle of a monitor with the view's flags as given.
template <typename M>
core::AlarmMask findings(M& m, const core::Feedback& fb, bool integrity_fault, bool self_test_ok = true) {
  core::AlarmSet alarms;
  core::Reporter r;
  r.begin(alarms, 0U);
  const core::SafetyInputs in{};
  const core::Timing timing = core::to_timing(core::Config{});
  const core::StateVariant state{core::StIdle{}};
  const core::CycleView v{in,    fb,    timing, state,           r.facts(),      nullptr, Leaf::IDLE, false,
                          0U,    core::Mode::AUTO, 0U, false, integrity_fault, self_test_ok, true, core::Commanded{}};
  m.check(v, r);
  return r.found();
}

}  // namespace

TEST(IntegrityMonitor, EitherThePlatformsCheckOrTheSupervisorsOwnLocksOut) {
  core::IntegrityMonitor m;
  core::Feedback fb{};
  EXPECT_EQ(findings(m, fb, false), 0U) << "both checks pass";
  EXPECT_EQ(findings(m, fb, true), core::bit(AlarmId::INTEGRITY_FAULT)) << "the supervisor's own check failed";
  fb.integrity_ok = false;
  EXPECT_EQ(findings(m, fb, false), core::bit(AlarmId::INTEGRITY_FAULT)) << "the platform's check failed";
}

TEST(Reporter, RuleFiveWithoutAnAlarmIsAnEventOfItsRuleOnly) {
  core::AlarmSet alarms;
  core::Reporter r;
  r.begin(alarms, 0U);
  core::AlarmDetail d{};
  d.signal = core::Signal::enable;
  r.trip_event(core::Trigger::enable_left_centre, d);
  r.trip_event(core::Trigger::reset, d);  // not a rule: ignored
  const auto five = static_cast<std::size_t>(core::Trigger::enable_left_centre);
  for (std::size_t t = 0; t < core::kConditionCount; ++t) {
    EXPECT_EQ(r.event(t), t == five) << t;
  }
  EXPECT_EQ(r.event_detail(five).signal, core::Signal::enable);
  EXPECT_EQ(r.found(), 0U) << "an event raises no alarm";
  EXPECT_EQ(alarms.mask(), 0U);
}

TEST(Reporter, TheFirstDetailOfACycleIsKeptAndHoldRaisesAndClears) {
  core::AlarmSet alarms;
  core::Reporter r;
  r.begin(alarms, 5U);
  r.trip(AlarmId::FIELDBUS_LOST, core::detail_of(core::Signal::fieldbus, core::Channel::none, 0U, 3U));
  r.trip(AlarmId::FIELDBUS_LOST, core::detail_of(core::Signal::drive, core::Channel::none, 2U));
  EXPECT_EQ(r.detail(AlarmId::FIELDBUS_LOST).signal, core::Signal::fieldbus) << "the bus before the drive";
  EXPECT_EQ(alarms.mask(), 0U) << "a rule's alarm is raised by the state machine, not by trip()";
  r.hold(AlarmId::ESTOP_PRESSED, true, core::AlarmDetail{});
  EXPECT_TRUE(alarms.active(AlarmId::ESTOP_PRESSED));
  EXPECT_EQ(alarms.since(AlarmId::ESTOP_PRESSED), 5U);
  r.hold(AlarmId::ESTOP_PRESSED, false, core::AlarmDetail{});
  EXPECT_FALSE(alarms.active(AlarmId::ESTOP_PRESSED));
}

// @req ST-OUTPUTS
TEST(OutputCheck, EachContradictionAloneFailsIt) {
  const core::StateVariant idle{core::StIdle{}};
  const core::StateVariant op{core::StOperational{core::Sub::AUTO_RUNNING}};
  const core::StateVariant jog{core::StOperational{core::Sub::MANUAL_JOGGING}};
  core::SupervisorOut o{};
  EXPECT_TRUE(core::outputs_consistent(o, Leaf::IDLE, idle, false)) << "nothing powered in IDLE";
  // Power outside a powered state, by each output alone.
  for (int k = 0; k < 3; ++k) {
    core::SupervisorOut p{};
    p.contactor = (k == 0);
    p.drives_enable = (k == 1);
    p.brakes_release = (k == 2);
    EXPECT_FALSE(core::outputs_consistent(p, Leaf::IDLE, idle, false)) << "output " << k;
    EXPECT_TRUE(core::outputs_consistent(p, Leaf::AUTO_RUNNING, op, false))
        << "the same power in a powered state is no contradiction";
  }
  // Power while the E-stop is pressed, in a powered state.
  core::SupervisorOut p{};
  p.contactor = true;
  p.motion.mode = core::MotionMode::Program;
  EXPECT_TRUE(core::outputs_consistent(p, Leaf::AUTO_RUNNING, op, false));
  EXPECT_FALSE(core::outputs_consistent(p, Leaf::AUTO_RUNNING, op, true));
  p.contactor = false;
  EXPECT_TRUE(core::outputs_consistent(p, Leaf::AUTO_RUNNING, op, true)) << "pressed, nothing powered";
  // Jog motion outside MANUAL_JOGGING.
  core::SupervisorOut j{};
  j.motion.mode = core::MotionMode::Jog;
  EXPECT_TRUE(core::outputs_consistent(j, Leaf::MANUAL_JOGGING, jog, false));
  EXPECT_FALSE(core::outputs_consistent(j, Leaf::AUTO_RUNNING, op, false));
  // Program motion outside both running states.
  core::SupervisorOut g{};
  g.motion.mode = core::MotionMode::Program;
  EXPECT_TRUE(core::outputs_consistent(g, Leaf::MANUAL_RUNNING, core::StateVariant{core::StOperational{core::Sub::MANUAL_RUNNING}}, false));
  EXPECT_FALSE(core::outputs_consistent(g, Leaf::MANUAL_JOGGING, jog, false));
  EXPECT_FALSE(core::outputs_consistent(g, Leaf::IDLE, idle, false));
  // State data of another state than the leaf.
  EXPECT_FALSE(core::outputs_consistent(o, Leaf::IDLE, op, false));
}

// ---- T1 speed (SPEC §4 rule 3, issue 35): the core's own, from its positions ---------------

namespace {

// One cycle of the T1 speed monitor with motion armed in T1, the core's pose of this cycle
// being `pose` (nullptr: no arm) and the sample's timing as in `fb`.
struct T1Cycle {
  core::T1SpeedMonitor m;
  safestate::test::MonitorCycle c;
  T1Cycle() {
    c.in.mode = core::Mode::T1;
    c.armed_mode = core::Mode::T1;
    c.leaf = Leaf::MANUAL_JOGGING;
    c.state = core::StOperational{core::Sub::MANUAL_JOGGING};
  }
  // The TCP at x mm along the base's x axis, every link origin at the base.
  core::ArmPose at(float tcp_x_mm) {
    core::ArmPose p{};
    p.tcp = {tcp_x_mm, 0.0F, 0.0F};
    return p;
  }
  bool trips(const core::ArmPose* pose) {
    c.facts.pose = pose;
    const core::Reporter r = c.run(m);
    speed = r.facts().t1_speed_mm_s;
    const bool hit = found(r, AlarmId::T1_SPEED_EXCEEDED);
    detail = hit ? r.detail(AlarmId::T1_SPEED_EXCEEDED) : core::AlarmDetail{};
    present = safestate::test::present(r, AlarmId::T1_SPEED_EXCEEDED);
    return hit;
  }
  float speed = 0.0F;
  bool present = false;
  core::AlarmDetail detail{};
};

}  // namespace

// @req MO-T1-MONITOR
TEST(T1SpeedMonitor, DifferentiatesTheCoresPositionsAndExactlyTheLimitIsAllowed) {
  T1Cycle t;
  core::ArmPose p = t.at(100.0F);
  EXPECT_FALSE(t.trips(&p)) << "the first sample: nothing to differentiate";
  EXPECT_EQ(t.speed, 0.0F);
  p = t.at(100.25F);  // 0.25 mm in one 1 ms cycle: 250 mm/s exactly (binary fractions)
  EXPECT_FALSE(t.trips(&p)) << "exactly the limit is allowed";
  EXPECT_EQ(t.speed, 250.0F);
  p = t.at(100.25F + 0.2505F);
  EXPECT_TRUE(t.trips(&p));
  EXPECT_NEAR(t.speed, 250.5F, 0.01F);
  EXPECT_EQ(t.detail.signal, core::Signal::drive);
  EXPECT_EQ(t.detail.axis, 6U) << "the TCP belongs to link 6";
  EXPECT_EQ(t.detail.code, 250U) << "the speed, mm/s";
}

// @req MO-T1-MONITOR
TEST(T1SpeedMonitor, EveryLinkOriginCountsAndTheFastestNamesItsLink) {
  T1Cycle t;
  core::ArmPose p = t.at(300.0F);
  ASSERT_FALSE(t.trips(&p));
  p.origin[3] = {0.0F, 0.4F, 0.0F};  // link origin 3 (the elbow offset) 400 mm/s, the TCP still
  EXPECT_TRUE(t.trips(&p));
  EXPECT_NEAR(t.speed, 400.0F, 0.01F);
  EXPECT_EQ(t.detail.axis, 3U);
  p.origin[0] = {0.0F, 0.0F, 50.0F};  // joint 1's frame on the base: no link moves it
  p.origin[3] = {0.0F, 0.4F, 0.0F};
  EXPECT_FALSE(t.trips(&p));
  p.origin[4] = p.origin[5] = {0.0F, 0.0F, 1.0F};  // the wrist centre is origin 4 and 5: the outer named
  EXPECT_TRUE(t.trips(&p));
  EXPECT_EQ(t.detail.axis, 5U);
  p.origin[6] = {0.0F, 0.0F, -1.0F};  // the flange, as fast: link 6
  p.origin[4] = p.origin[5] = {0.0F, 0.0F, 0.0F};
  p.tcp = {300.0F, 0.0F, 0.0F};
  EXPECT_TRUE(t.trips(&p));
  EXPECT_EQ(t.detail.axis, 6U);
}

// A cycle without a fresh sample holds the positions: no zero-length span (no infinite
// speed, no division by zero), the last speed stands, and the next fresh sample is
// differentiated over every cycle since the last one.
// @req MO-T1-MONITOR MO-SAMPLE-TIME
TEST(T1SpeedMonitor, AStaleCycleIsNoZeroSpanAndTheNextSampleSpansBoth) {
  T1Cycle t;
  core::ArmPose p = t.at(0.0F);
  ASSERT_FALSE(t.trips(&p));
  p = t.at(0.2F);
  ASSERT_FALSE(t.trips(&p));
  ASSERT_NEAR(t.speed, 200.0F, 0.01F);
  t.c.fb.stale = true;  // the frame was lost: the positions held
  EXPECT_FALSE(t.trips(&p));
  EXPECT_NEAR(t.speed, 200.0F, 0.01F) << "the last sample's speed stands";
  EXPECT_FALSE(t.trips(&p));
  t.c.fb.stale = false;
  p = t.at(0.8F);  // three cycles of motion at 200 mm/s since the last sample
  EXPECT_FALSE(t.trips(&p)) << "over three cycles, not one (600 mm/s)";
  EXPECT_NEAR(t.speed, 200.0F, 0.01F);
  p = t.at(1.1F);
  EXPECT_TRUE(t.trips(&p)) << "back to one cycle a sample: 300 mm/s";
  EXPECT_NEAR(t.speed, 300.0F, 0.01F);
}

// With the drives' sample clock (EtherCAT DC), the span is the SYNC0 cycles between the
// samples as the bus says, not the cycles between the frames.
// @req MO-T1-MONITOR MO-SAMPLE-TIME
TEST(T1SpeedMonitor, TheDrivesSampleClockSetsTheSpan) {
  T1Cycle t;
  t.c.fb.sample_clock = true;
  t.c.fb.sample_span = 1;
  core::ArmPose p = t.at(0.0F);
  ASSERT_FALSE(t.trips(&p));
  p = t.at(0.2F);
  ASSERT_FALSE(t.trips(&p));
  t.c.fb.sample_span = 2;  // a frame late past its SYNC0: the next pulse's sample
  p = t.at(0.6F);
  EXPECT_FALSE(t.trips(&p)) << "two pulses of motion: 200 mm/s, not 400";
  EXPECT_NEAR(t.speed, 200.0F, 0.01F);
  t.c.fb.sample_span = 0;  // the same sample again
  EXPECT_FALSE(t.trips(&p));
  EXPECT_NEAR(t.speed, 200.0F, 0.01F);
  t.c.fb.sample_span = 1;
  p = t.at(0.8F);
  EXPECT_FALSE(t.trips(&p));
  EXPECT_NEAR(t.speed, 200.0F, 0.01F) << "over the one pulse the bus names";
}

// @req MO-T1-MONITOR ST-UNKNOWN-UNSAFE
TEST(T1SpeedMonitor, UnknownIsOverTheLimit) {
  T1Cycle t;
  EXPECT_TRUE(t.trips(nullptr)) << "no arm in the core: the speed is unknown";
  EXPECT_TRUE(t.present);
  core::ArmPose p = t.at(0.0F);
  EXPECT_FALSE(t.trips(&p)) << "the arm's first sample";
  p.tcp[1] = std::nanf("");
  EXPECT_TRUE(t.trips(&p)) << "a position no one can read";
  EXPECT_EQ(t.detail.axis, 6U);
  EXPECT_EQ(t.detail.code, 65535U);
  p = t.at(0.0F);
  EXPECT_TRUE(t.trips(&p)) << "differentiated against the unreadable one";
  EXPECT_FALSE(t.trips(&p)) << "two readable samples";
}

// @req MO-T1-MONITOR TR-C3
TEST(T1SpeedMonitor, TripsOnlyWithMotionArmedInT1AndTheCauseStaysPresentInEveryMode) {
  T1Cycle t;
  core::ArmPose p = t.at(0.0F);
  ASSERT_FALSE(t.trips(&p));
  t.c.armed_mode = core::Mode::AUTO;  // the key turned to T1 while the arm moves at AUTO's speed
  p = t.at(1.0F);
  EXPECT_FALSE(t.trips(&p)) << "rule 6's, not a T1 speed fault";
  EXPECT_TRUE(t.present) << "over the limit: a reset's cause is present";
  t.c.armed_mode = core::Mode::T1;
  t.c.in.mode = core::Mode::T2;
  p = t.at(2.0F);
  EXPECT_FALSE(t.trips(&p)) << "T2 has no reduced speed";
  EXPECT_TRUE(t.present);
}

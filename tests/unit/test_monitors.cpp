// The monitors of core/src/monitors/ that the state machine's own tests reach only through
// the cells they run in, driven one cycle at a time through their one entry (monitor.hpp),
// and the supervisor's diverse output check, which no correct table can fail, fed outputs
// that contradict their state on purpose (each operand alone).
#include <gtest/gtest.h>

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

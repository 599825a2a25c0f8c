// The guards of core/src/guards.cpp called directly, operand by operand (MC/DC,
// docs/verification.md). The reset guard asks one question of the monitors: which alarms'
// causes are still present (Reporter::present); servo_on asks whether a position limit is
// violated now.
#include <gtest/gtest.h>

#include "safestate/core/monitor.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/core/transitions.hpp"

using namespace safestate::core;

namespace {

// A cell where every guard below says OK unless the test changes one thing: AUTO, gate
// closed, enabling device held, configuration validated, no brake test required.
struct View {
  SafetyInputs in{};
  Feedback fb{};
  AlarmSet alarms{};
  Timing timing{};
  AlarmMask present = 0U;  // causes the monitors found still present
  bool outside = false;

  View() {
    in.estop_pressed = false;
    in.gate_open = false;
    in.mode = Mode::AUTO;
    in.enable_ok = true;
  }
  void raise(AlarmId id) { alarms.raise(id, AlarmDetail{}, 1U); }
  [[nodiscard]] GuardView guard() const {
    return GuardView{in, fb, alarms, timing, false, false, false, true, present, outside, true, 0U, 0U, false, false};
  }
  [[nodiscard]] Result reset() const { return guard_reset_causes_gone(guard()); }
  [[nodiscard]] Result servo_on() const { return guard_servo_on(guard()); }
};

}  // namespace

// @req LIM-SPEED
TEST(GuardReset, ASpeedStillOverItsLimitRefusesTheResetOnlyWithItsAlarm) {
  View v;
  v.present = bit(AlarmId::SPEED_LIMIT);
  EXPECT_EQ(v.reset(), Result::OK) << "no SPEED_LIMIT alarm: nothing to reset";
  v.raise(AlarmId::SPEED_LIMIT);
  EXPECT_EQ(v.reset(), Result::FAULT_PRESENT) << "the cause is still there";
  v.present = 0U;
  EXPECT_EQ(v.reset(), Result::OK) << "the speed is back under its limit";
  v.present = bit(AlarmId::SEPARATION_VIOLATED);
  EXPECT_EQ(v.reset(), Result::OK) << "another alarm's cause does not hold this one";
}

// @req COL-SSM-MONITOR
TEST(GuardReset, TheTcpStillTooFastForTheSeparationRefusesTheResetOnlyWithItsAlarm) {
  View v;
  v.present = bit(AlarmId::SEPARATION_VIOLATED);
  EXPECT_EQ(v.reset(), Result::OK) << "no SEPARATION_VIOLATED alarm: nothing to reset";
  v.raise(AlarmId::SEPARATION_VIOLATED);
  EXPECT_EQ(v.reset(), Result::FAULT_PRESENT);
  v.present = 0U;
  EXPECT_EQ(v.reset(), Result::OK) << "the TCP is slow enough again";
}

// @req LIM-VALIDATION
TEST(GuardServoOn, OutsideTheLimitsRefusesAutoAndT2ButNotT1) {
  View v;
  EXPECT_EQ(v.servo_on(), Result::OK);
  v.outside = true;
  EXPECT_EQ(v.servo_on(), Result::OUTSIDE_LIMITS);
  v.in.mode = Mode::T1;
  EXPECT_EQ(v.servo_on(), Result::OK) << "T1 is where the operator jogs back";
}

// The reporter's contract for a rule without an alarm (rule 5's event), as for an alarm's
// trip(): the first detail found in the cycle is the one the stop names, a second finding
// changes nothing; a trigger that is not one of SPEC §4's conditions is no event.
// @req TR-PRIORITY
TEST(Reporter, AnEventKeepsTheFirstDetailOfTheCycleAndOnlyConditionsAreEvents) {
  AlarmSet alarms{};
  Reporter r;
  r.begin(alarms, 1U);
  const auto t = static_cast<std::size_t>(Trigger::enable_left_centre);
  EXPECT_FALSE(r.event(t));
  r.trip_event(Trigger::enable_left_centre, detail_of(Signal::enable, Channel::a));
  r.trip_event(Trigger::enable_left_centre, detail_of(Signal::enable, Channel::panic));
  EXPECT_TRUE(r.event(t));
  EXPECT_EQ(r.event_detail(t).signal, Signal::enable);
  EXPECT_EQ(r.event_detail(t).channel, Channel::a);
  r.trip_event(Trigger::standstill, detail_of(Signal::internal));  // an internal event, not a condition
  for (std::size_t i = 0; i < kConditionCount; ++i) {
    EXPECT_EQ(r.event(i), i == t) << "condition " << i;
  }
  EXPECT_EQ(alarms.mask(), 0U) << "an event raises no alarm";
}

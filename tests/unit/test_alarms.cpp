// The alarm table of SPEC §7 and the AlarmSet semantics.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "safestate/core/alarms.hpp"

using namespace safestate::core;

// @req AL-TABLE
TEST(AlarmTable, RowsAreInIdOrderWithUniqueNumbersAndNames) {
  std::set<int> numbers;
  std::set<std::string> names;
  for (std::size_t i = 0; i < kAlarms.size(); ++i) {
    EXPECT_EQ(static_cast<std::size_t>(kAlarms[i].id), i);
    EXPECT_TRUE(numbers.insert(kAlarms[i].number).second) << kAlarms[i].name;
    EXPECT_TRUE(names.insert(kAlarms[i].name).second);
    EXPECT_GT(std::string(kAlarms[i].text).size(), 10U);
    EXPECT_GT(std::string(kAlarms[i].remedy).size(), 10U);
    EXPECT_STREQ(to_string(kAlarms[i].id), kAlarms[i].name);
  }
}

// @req AL-TABLE AL-LIFETIME
TEST(AlarmTable, SeverityAndLatchingAreThoseOfTheSpec) {
  struct Row {
    const char* name;
    Severity sev;
    Latch latch;
  };
  const Row spec[] = {
      {"ESTOP_DISCREPANCY", Severity::lockout, Latch::power_cycle},
      {"GATE_DISCREPANCY", Severity::lockout, Latch::power_cycle},
      {"ENABLE_DISCREPANCY", Severity::lockout, Latch::power_cycle},
      {"FIELDBUS_LOST", Severity::lockout, Latch::power_cycle},
      {"INTEGRITY_FAULT", Severity::lockout, Latch::power_cycle},
      {"BOOT_FAILED", Severity::lockout, Latch::power_cycle},
      {"PROTECTIVE_STOP", Severity::fault, Latch::reset},
      {"DRIVE_FAULT", Severity::fault, Latch::reset},
      {"ARMING_TIMEOUT", Severity::fault, Latch::reset},
      {"T1_SPEED_EXCEEDED", Severity::fault, Latch::reset},
      {"STOP_TIME_EXCEEDED", Severity::fault, Latch::reset},
      {"ESTOP_PRESSED", Severity::info, Latch::condition},
      {"MODE_SELECTOR_INVALID", Severity::warning, Latch::condition},
      {"RESET_BUTTON_STUCK", Severity::info, Latch::condition},
      {"MODE_CHANGED", Severity::info, Latch::until_ok},
      {"ENABLING_PANIC", Severity::info, Latch::until_ok},
      {"JOG_LINK_LOST", Severity::info, Latch::until_ok},
      {"CONTACTOR_WELDED", Severity::lockout, Latch::power_cycle},
      {"BRAKE_NOT_ENGAGED", Severity::fault, Latch::reset},
      {"JOINT_LIMIT", Severity::fault, Latch::reset},
      {"ZONE_VIOLATION", Severity::fault, Latch::reset},
      {"ORIENTATION_LIMIT", Severity::fault, Latch::reset},
      {"SPEED_LIMIT", Severity::fault, Latch::reset},
      {"CONFIG_NOT_VALIDATED", Severity::warning, Latch::condition},
      {"REDUCED_SPEED", Severity::info, Latch::condition},
      // SPEC §7/§11: FIELD_DISCREPANCY lockout; SEPARATION_VIOLATED latched fault; PERSON_IN_FIELD
      // info while the condition lasts.
      {"FIELD_DISCREPANCY", Severity::lockout, Latch::power_cycle},
      {"SEPARATION_VIOLATED", Severity::fault, Latch::reset},
      {"PERSON_IN_FIELD", Severity::info, Latch::condition},
      {"BRAKE_TEST_DUE", Severity::warning, Latch::condition},
      {"BRAKE_TEST_FAILED", Severity::fault, Latch::reset},
      // SPEC §7/§11: COLLISION latched fault (rule 8).
      {"COLLISION", Severity::fault, Latch::reset},
      // SPEC §14: lockouts until power cycle.
      {"CHANNEL_MISMATCH", Severity::lockout, Latch::power_cycle},
      {"CHANNEL_LOST", Severity::lockout, Latch::power_cycle},
      {"ENCODER_DISCREPANCY", Severity::lockout, Latch::power_cycle},
      {"SAFETY_LINK_FAULT", Severity::lockout, Latch::power_cycle},
  };
  ASSERT_EQ(std::size(spec), kAlarmCount);
  for (const Row& r : spec) {
    AlarmId id{};
    ASSERT_TRUE(parse_alarm(r.name, id)) << r.name;
    EXPECT_EQ(alarm_info(id).severity, r.sev) << r.name;
    EXPECT_EQ(alarm_info(id).latch, r.latch) << r.name;
  }
}

// @req AL-CAUSE
TEST(AlarmSet, RaiseKeepsTheFirstCauseAndSince) {
  AlarmSet s;
  AlarmDetail a{};
  a.signal = Signal::estop;
  a.channel = Channel::a;
  AlarmDetail b = a;
  b.channel = Channel::b;
  s.raise(AlarmId::ESTOP_PRESSED, a, 10);
  s.raise(AlarmId::ESTOP_PRESSED, b, 20);
  EXPECT_TRUE(s.active(AlarmId::ESTOP_PRESSED));
  EXPECT_EQ(s.since(AlarmId::ESTOP_PRESSED), 10U);
  EXPECT_EQ(s.detail(AlarmId::ESTOP_PRESSED).channel, Channel::a);
}

TEST(AlarmSet, TracksRaisedAndClearedPerCycle) {
  AlarmSet s;
  s.begin_cycle();
  s.raise(AlarmId::MODE_CHANGED, {}, 5);
  EXPECT_EQ(s.raised(), bit(AlarmId::MODE_CHANGED));
  s.begin_cycle();
  EXPECT_EQ(s.raised(), 0U);
  s.clear(AlarmId::MODE_CHANGED);
  EXPECT_EQ(s.cleared(), bit(AlarmId::MODE_CHANGED));
  EXPECT_FALSE(s.active(AlarmId::MODE_CHANGED));
}

// @req AL-LIFETIME
TEST(AlarmSet, ClearOlderSparesAlarmsRaisedThisCycle) {
  AlarmSet s;
  s.raise(AlarmId::MODE_CHANGED, {}, 5);
  s.raise(AlarmId::JOG_LINK_LOST, {}, 9);
  s.clear_older(kUntilOkAlarms, 9);
  EXPECT_FALSE(s.active(AlarmId::MODE_CHANGED));
  EXPECT_TRUE(s.active(AlarmId::JOG_LINK_LOST));
}

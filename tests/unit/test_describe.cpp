// Causes in words: what the banner and the demo show to an operator.
#include <gtest/gtest.h>

#include <string>

#include "safestate/core/describe.hpp"

using namespace safestate::core;

namespace {
std::string words(AlarmId id, Signal s, Channel ch = Channel::none, std::uint8_t axis = 0, std::uint16_t code = 0) {
  AlarmDetail d{};
  d.signal = s;
  d.channel = ch;
  d.axis = axis;
  d.code = code;
  char buf[128];
  return describe(id, d, buf, sizeof buf);
}
}  // namespace

// @req AL-CAUSE
TEST(Describe, EstopNamesTheChannel) {
  EXPECT_EQ(words(AlarmId::ESTOP_PRESSED, Signal::estop, Channel::a), "E-stop channel A opened");
  EXPECT_EQ(words(AlarmId::ESTOP_PRESSED, Signal::estop, Channel::both), "E-stop pressed");
}

TEST(Describe, GuardInAuto) {
  EXPECT_EQ(words(AlarmId::PROTECTIVE_STOP, Signal::gate, Channel::b), "Guard opened in AUTO channel B");
}

// @req AL-CAUSE
TEST(Describe, DriveFaultNamesAxisAndStatusword) {
  EXPECT_EQ(words(AlarmId::DRIVE_FAULT, Signal::drive, Channel::none, 3, 0x0008), "Drive 3 fault (statusword 0x0008)");
}

// @req AL-CAUSE
TEST(Describe, ArmingTimeoutNamesTheStep) {
  AlarmDetail d{};
  d.step = ArmingStep::BRAKES;
  d.has_step = true;
  char buf[64];
  EXPECT_STREQ(describe(AlarmId::ARMING_TIMEOUT, d, buf, sizeof buf), "Arming step BRAKES timed out");
}

TEST(Describe, EnableReleaseAndCommandCauses) {
  Cause c{};
  c.kind = CauseKind::event;
  c.rule = 5;
  c.mode = Mode::T1;
  char buf[64];
  EXPECT_STREQ(describe(c, buf, sizeof buf), "Enabling device released in T1");
  c.kind = CauseKind::command;
  c.command = CommandId::servo_off;
  c.source = Source::remote;
  EXPECT_STREQ(describe(c, buf, sizeof buf), "Command servo_off from remote");
  c.kind = CauseKind::none;
  EXPECT_STREQ(describe(c, buf, sizeof buf), "");
}

TEST(Describe, TruncatesToTheBuffer) {
  char buf[8];
  describe(AlarmId::FIELDBUS_LOST, AlarmDetail{}, buf, sizeof buf);
  EXPECT_EQ(std::string(buf).size(), 7U);
}

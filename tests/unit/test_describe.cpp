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

// SPEC §14: the contactor of two, the channel lost, the field that differed, the axis whose
// encoders disagree; the details as the scenario keys name them.
TEST(Describe, TwoChannelAlarmsNameTheirPart) {
  EXPECT_EQ(words(AlarmId::CONTACTOR_WELDED, Signal::contactor, Channel::a),
            "Contactor K1 feedback still closed after open was commanded");
  EXPECT_EQ(words(AlarmId::CONTACTOR_WELDED, Signal::contactor, Channel::b),
            "Contactor K2 feedback still closed after open was commanded");
  EXPECT_EQ(words(AlarmId::CONTACTOR_WELDED, Signal::contactor),
            "Main contactor feedback still closed after open was commanded");
  EXPECT_EQ(words(AlarmId::CHANNEL_LOST, Signal::channel, Channel::b), "Safety channel B lost");
  EXPECT_EQ(words(AlarmId::CHANNEL_LOST, Signal::channel, Channel::a), "Safety channel A lost");
  EXPECT_EQ(words(AlarmId::CHANNEL_MISMATCH, Signal::channel, Channel::none, 0,
                  static_cast<std::uint16_t>(CrossField::alarms)),
            "Safety channels disagree on alarms");
  EXPECT_EQ(words(AlarmId::ENCODER_DISCREPANCY, Signal::axis, Channel::none, 5), "Axis 5 encoders disagree");
  char buf[32];
  AlarmDetail d{};
  d.signal = Signal::contactor;
  EXPECT_STREQ(detail_name(d, buf, sizeof buf), "contactor");
  d.channel = Channel::a;
  EXPECT_STREQ(detail_name(d, buf, sizeof buf), "k1");
  d.channel = Channel::b;
  EXPECT_STREQ(detail_name(d, buf, sizeof buf), "k2");
  EXPECT_STREQ(signal_name(d, buf, sizeof buf), "contactor") << "cause.signal stays the contactor";
  d.channel = Channel::both;
  EXPECT_STREQ(detail_name(d, buf, sizeof buf), "contactor");
  d = AlarmDetail{};
  d.signal = Signal::channel;
  d.code = static_cast<std::uint16_t>(CrossField::state);
  EXPECT_STREQ(detail_name(d, buf, sizeof buf), "state");
  EXPECT_STREQ(signal_name(d, buf, sizeof buf), "channel");
  d.code = 0;
  d.channel = Channel::b;
  EXPECT_STREQ(detail_name(d, buf, sizeof buf), "B");
  d.channel = Channel::none;
  EXPECT_STREQ(detail_name(d, buf, sizeof buf), "channel");
  d.has_step = true;
  d.step = ArmingStep::CONTACTOR;
  EXPECT_STREQ(detail_name(d, buf, sizeof buf), "CONTACTOR");
  EXPECT_STREQ(detail_name(d, nullptr, 8), "");
  EXPECT_STREQ(detail_name(d, buf, 0), "");
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
  d.signal = Signal::brake;
  d.axis = 4;
  EXPECT_STREQ(describe(AlarmId::ARMING_TIMEOUT, d, buf, sizeof buf), "Arming step BRAKES timed out (brake 4)");
  d.step = ArmingStep::DRIVES;
  d.signal = Signal::drive;
  d.axis = 2;
  EXPECT_STREQ(describe(AlarmId::ARMING_TIMEOUT, d, buf, sizeof buf), "Arming step DRIVES timed out (drive 2)");
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

namespace {
std::string signal(Signal s, Channel ch = Channel::none, std::uint8_t axis = 0) {
  AlarmDetail d{};
  d.signal = s;
  d.channel = ch;
  d.axis = axis;
  char buf[32];
  return signal_name(d, buf, sizeof buf);
}
}  // namespace

// The names of spec/scenario-format.md `cause.signal=` and `alarm.NAME.detail=`.
// @req AL-CAUSE SCN-MORE-KEYS
TEST(Names, SignalNamesAreThoseOfTheScenarioFormat) {
  EXPECT_EQ(signal(Signal::estop, Channel::a), "estop.a");
  EXPECT_EQ(signal(Signal::estop, Channel::b), "estop.b");
  EXPECT_EQ(signal(Signal::estop, Channel::both), "estop.a");
  EXPECT_EQ(signal(Signal::gate, Channel::b), "gate.b");
  EXPECT_EQ(signal(Signal::enable, Channel::a), "enable.a");
  EXPECT_EQ(signal(Signal::enable, Channel::panic), "enable.panic");
  EXPECT_EQ(signal(Signal::mode), "mode");
  EXPECT_EQ(signal(Signal::fieldbus), "fieldbus");
  EXPECT_EQ(signal(Signal::drive, Channel::none, 4), "drive.4");
  EXPECT_EQ(signal(Signal::brake, Channel::none, 6), "brake.6");
  EXPECT_EQ(signal(Signal::contactor), "contactor");
  EXPECT_EQ(signal(Signal::internal), "internal");
  EXPECT_EQ(signal(Signal::command), "command");
  EXPECT_EQ(signal(Signal::none), "-");
  char tiny[4];
  AlarmDetail d{};
  d.signal = Signal::contactor;
  EXPECT_EQ(std::string(signal_name(d, tiny, sizeof tiny)), "con") << "truncated, always terminated";
}

// @req AL-CAUSE SCN-MORE-KEYS
TEST(Names, DetailNamesTheArmingStep) {
  AlarmDetail d{};
  d.signal = Signal::drive;
  d.axis = 2;
  d.step = ArmingStep::DRIVES;
  d.has_step = true;
  char buf[32];
  EXPECT_EQ(std::string(detail_name(d, buf, sizeof buf)), "DRIVES");
  d.has_step = false;
  EXPECT_EQ(std::string(detail_name(d, buf, sizeof buf)), "drive.2");
}

// @req AL-FIRST-OUT SCN-MORE-KEYS
TEST(Names, CauseNames) {
  Cause c{};
  EXPECT_STREQ(cause_name(c), "-");
  c.kind = CauseKind::alarm;
  c.alarm = AlarmId::BRAKE_NOT_ENGAGED;
  EXPECT_STREQ(cause_name(c), "BRAKE_NOT_ENGAGED");
  c.kind = CauseKind::command;
  c.command = CommandId::jog_stop;
  EXPECT_STREQ(cause_name(c), "jog_stop");
  c.kind = CauseKind::event;
  c.rule = 5;
  EXPECT_STREQ(cause_name(c), "enable_released");
  c.rule = 0;  // a program that finished in MANUAL_RUNNING: a stop without a named cause
  EXPECT_STREQ(cause_name(c), "-");
}

// @req AL-FEEDBACK
TEST(Describe, FeedbackAlarms) {
  EXPECT_EQ(words(AlarmId::BRAKE_NOT_ENGAGED, Signal::brake, Channel::none, 3),
            "Brake 3 still released after engage was commanded");
  EXPECT_EQ(words(AlarmId::CONTACTOR_WELDED, Signal::contactor),
            "Main contactor feedback still closed after open was commanded");
}

// ---------------------------------------------------------------- MC/DC of describe.cpp
// Each test below shows one condition of a decision deciding on its own (docs/verification.md,
// "Coverage (MC/DC)").

// A missing or empty buffer is refused by every writer: nothing is written, "" comes back.
TEST(Describe, NoBufferOrAnEmptyOneGivesTheEmptyString) {
  AlarmDetail d{};
  d.signal = Signal::contactor;
  char buf[16] = "untouched";
  EXPECT_STREQ(describe(AlarmId::CONTACTOR_WELDED, d, nullptr, sizeof buf), "");
  EXPECT_STREQ(describe(AlarmId::CONTACTOR_WELDED, d, buf, 0), "");
  EXPECT_STREQ(buf, "untouched");
  Cause c{};
  c.kind = CauseKind::command;
  c.command = CommandId::stop;
  EXPECT_STREQ(describe(c, nullptr, sizeof buf), "");
  EXPECT_STREQ(describe(c, buf, 0), "");
  EXPECT_STREQ(buf, "untouched");
  EXPECT_STREQ(signal_name(d, nullptr, sizeof buf), "");
  EXPECT_STREQ(signal_name(d, buf, 0), "");
  EXPECT_STREQ(buf, "untouched");
  // detail_name with an arming step: the step is not written, and signal_name refuses too.
  d.has_step = true;
  d.step = ArmingStep::DRIVES;
  EXPECT_STREQ(detail_name(d, nullptr, sizeof buf), "");
  EXPECT_STREQ(detail_name(d, buf, 0), "");
  EXPECT_STREQ(buf, "untouched");
}

// Numbers of more than one digit are written whole, most significant digit first.
TEST(Describe, MultiDigitNumbersAreWrittenInFull) {
  EXPECT_EQ(words(AlarmId::T1_SPEED_EXCEEDED, Signal::drive, Channel::none, 3, 65535),
            "T1 speed exceeded at link 3 (65535 mm/s)");
  EXPECT_EQ(words(AlarmId::FIELDBUS_LOST, Signal::fieldbus, Channel::none, 0, 12), "Fieldbus lost at subdevice 12");
}

// BOOT_FAILED: a fieldbus cause names the subdevice only when there is one; a cause with a
// code that is not the fieldbus's is the self-test.
TEST(Describe, BootFailedWordsFollowSignalAndSubdevice) {
  EXPECT_EQ(words(AlarmId::BOOT_FAILED, Signal::fieldbus, Channel::none, 0, 3),
            "Start-up failed: fieldbus not as configured at subdevice 3");
  EXPECT_EQ(words(AlarmId::BOOT_FAILED, Signal::fieldbus, Channel::none, 0, 0), "Start-up failed: fieldbus not up");
  EXPECT_EQ(words(AlarmId::BOOT_FAILED, Signal::internal, Channel::none, 0, 3), "Start-up self-test failed");
  EXPECT_EQ(words(AlarmId::BOOT_FAILED, Signal::drive, Channel::none, 5, 0), "Start-up failed: drive 5 did not answer");
}

TEST(Describe, EstopNamesChannelB) {
  EXPECT_EQ(words(AlarmId::ESTOP_PRESSED, Signal::estop, Channel::b), "E-stop channel B opened");
}

// A drive or brake signal without an axis is named without one (not "drive.0").
TEST(Names, DriveOrBrakeWithoutAnAxisIsTheBareSignal) {
  EXPECT_EQ(signal(Signal::drive), "drive");
  EXPECT_EQ(signal(Signal::brake), "brake");
}

// The four principles of SPEC §3, each checked on the real supervisor.
#include <cmath>

#include "bench.hpp"

using namespace safestate::test;

// ---------------------------------------------------------------- no surprise motion
// @req ST-NO-SURPRISE
TEST(NoSurpriseMotion, AfterArmingNothingMovesUntilACommandIsAccepted) {
  Bench b;
  b.to_operational();
  for (int k = 0; k < 200; ++k) {
    b.cycle();
    ASSERT_EQ(b.out.motion.mode, MotionMode::Hold);
    ASSERT_EQ(b.out.motion.program, ProgramCmd::None);
  }
}

// @req ST-NO-SURPRISE
TEST(NoSurpriseMotion, ArmingTracksMeasuredPositions) {
  Bench b;
  b.to_idle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  while (b.out.state == State::ARMING) {
    ASSERT_EQ(b.out.motion.mode, MotionMode::Track) << "set-points follow the measured positions";
    b.cycle();
  }
}

// @req ST-NO-SURPRISE
TEST(NoSurpriseMotion, EveryStopDiscardsQueuedMotion) {
  struct Stop {
    const char* name;
    void (*cause)(Bench&);
  };
  const Stop stops[] = {
      {"pause", [](Bench& b) { b.send(CommandId::pause); }},
      {"stop", [](Bench& b) { b.send(CommandId::stop); }},
      {"servo_off", [](Bench& b) { b.send(CommandId::servo_off); }},
      {"gate", [](Bench& b) { b.gate(true); }},
      {"estop", [](Bench& b) { b.estop(true); }},
      {"mode", [](Bench& b) { b.mode(Mode::T2); }},
  };
  for (const Stop& s : stops) {
    Bench b;
    b.to_auto_running();
    s.cause(b);
    b.cycle();
    EXPECT_TRUE(b.out.motion.discard) << s.name;
    EXPECT_NE(b.out.motion.mode, MotionMode::Program) << s.name;
  }
}

// @req ST-NO-SURPRISE TR-RESUME
TEST(NoSurpriseMotion, ResumeAfterPauseReplansAndReArmDoesNotRestart) {
  Bench b;
  b.to_auto_running();
  ASSERT_EQ(b.command(CommandId::pause), Result::OK);
  ASSERT_GT(b.finish_stop(), 0);
  ASSERT_EQ(b.command(CommandId::resume), Result::OK);
  EXPECT_EQ(b.out.motion.program, ProgramCmd::Resume);
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  ASSERT_GT(b.finish_stop(), 0);
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return o.state != State::ARMING; }, 1000), 0);
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE) << "the program does not continue by itself";
  EXPECT_EQ(b.out.motion.mode, MotionMode::Hold);
}

// ---------------------------------------------------------------- unknown is unsafe
// @req ST-UNKNOWN-UNSAFE CIA-UNKNOWN
TEST(UnknownIsUnsafe, UndecodableStatuswordIsADriveFault) {
  Bench b;
  b.to_auto_running();
  b.cycle();
  b.plant.ds[2] = static_cast<c402::DriveState>(99);  // statusword_of -> 0x004F
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(b.alarm(AlarmId::DRIVE_FAULT));
  EXPECT_EQ(b.out.cause.detail.axis, 3U);
}

// @req ST-UNKNOWN-UNSAFE
TEST(UnknownIsUnsafe, NaNSpeedInT1IsOverTheLimit) {
  Bench b;
  b.to_jogging(Mode::T1);
  b.plant.pos[0] = std::nanf("");  // a measured position no one can read: its speed is unknown
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(b.alarm(AlarmId::T1_SPEED_EXCEEDED));
}

// @req ST-UNKNOWN-UNSAFE ST-STANDSTILL
TEST(UnknownIsUnsafe, NaNVelocityIsNotStandstill) {
  Bench b;
  b.to_auto_running();
  b.plant.drive_nostop[0] = true;
  b.plant.vel[0] = std::nanf("");
  ASSERT_EQ(b.command(CommandId::stop), Result::OK);
  b.cycle(1001);
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(b.alarm(AlarmId::STOP_TIME_EXCEEDED));
}

// @req ST-UNKNOWN-UNSAFE
TEST(UnknownIsUnsafe, StopTimeResetIsRefusedWhileAnAxisStillMoves) {
  Bench b;
  b.to_auto_running();
  b.plant.drive_nostop[0] = true;  // keeps moving even without torque in this bench
  ASSERT_EQ(b.command(CommandId::stop), Result::OK);
  b.cycle(1001);
  ASSERT_TRUE(b.alarm(AlarmId::STOP_TIME_EXCEEDED));
  EXPECT_EQ(b.command(CommandId::reset), Result::FAULT_PRESENT);
  b.plant.drive_nostop[0] = false;
  b.plant.vel.fill(0.0F);
  b.cycle(10);
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
}

// @req ST-UNKNOWN-UNSAFE IN-MODE-INVALID
TEST(UnknownIsUnsafe, SelectorWithSeveralPositionsIsModeNone) {
  Bench b;
  b.to_idle();
  b.raw.mode_t1 = true;  // AUTO and T1 both closed
  b.cycle(51);
  EXPECT_EQ(b.out.mode, Mode::NONE);
  EXPECT_EQ(b.command(CommandId::servo_on), Result::MODE_INVALID);
}

// ---------------------------------------------------------------- Cat 1 completes
// @req ST-CAT1-COMPLETES
TEST(Cat1Completes, EvenIfItsCauseClears) {
  Bench b;
  b.to_auto_running();
  b.gate(true);
  b.cycle();
  ASSERT_EQ(b.out.stop, StopCat::CAT1);
  b.gate(false);  // guard closed again at once
  b.cycle();
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.target, Leaf::IDLE);
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.state, State::IDLE);
}

// @req ST-CAT1-COMPLETES
TEST(Cat1Completes, CommandsDoNotCancelIt) {
  Bench b;
  b.to_jogging(Mode::T1);
  b.enable_released();
  b.cycle();
  b.enable_centre();
  b.cycle();
  EXPECT_EQ(b.jog(1, 1), Result::BUSY);
  EXPECT_EQ(b.command(CommandId::servo_on), Result::BUSY);
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.state, State::IDLE);
}

// ---------------------------------------------------------------- every condition raises its alarm
// @req TR-EVERY-ALARM
TEST(EveryConditionRaisesItsAlarm, KeyToT1WithEnableReleasedRaisesModeChanged) {
  Bench b;
  b.to_auto_running();
  b.mode(Mode::T1);  // rule 5 (enable not held in T1) decides; rule 6 still raises
  b.cycle();
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
  EXPECT_EQ(b.out.cause.rule, 5U);
  EXPECT_TRUE(b.alarm(AlarmId::MODE_CHANGED));
}

// @req TR-EVERY-ALARM TR-PRIORITY
TEST(EveryConditionRaisesItsAlarm, EstopAndGateTogether) {
  Bench b;
  b.to_auto_running();
  b.estop(true);
  b.gate(true);
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE);
  EXPECT_TRUE(b.alarm(AlarmId::ESTOP_PRESSED));
  EXPECT_TRUE(b.alarm(AlarmId::PROTECTIVE_STOP));
  EXPECT_EQ(b.out.cause.alarm, AlarmId::ESTOP_PRESSED) << "first-out: the higher rule";
}

// @req TR-EVERY-ALARM
TEST(EveryConditionRaisesItsAlarm, DriveFaultInIdleIsRaisedToo) {
  Bench b;
  b.to_idle();
  b.plant.drive_fault[1] = true;
  b.cycle(3);
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(b.alarm(AlarmId::DRIVE_FAULT));
  EXPECT_EQ(b.command(CommandId::servo_on), Result::RESET_REQUIRED);
}

// @req AL-CAUSE AL-FIRST-OUT
TEST(EveryConditionRaisesItsAlarm, EveryStopNamesItsCause) {
  Bench b;
  b.to_auto_running();
  b.raw.gate_b = false;
  b.cycle();
  EXPECT_EQ(b.out.cause.kind, CauseKind::alarm);
  EXPECT_EQ(b.out.cause.alarm, AlarmId::PROTECTIVE_STOP);
  EXPECT_EQ(b.out.cause.detail.signal, Signal::gate);
  EXPECT_EQ(b.out.cause.detail.channel, Channel::b);
  EXPECT_EQ(b.out.cause.mode, Mode::AUTO);
}

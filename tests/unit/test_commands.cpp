// Every rule of SPEC §5: one result per command, the check order, each result code.
#include "bench.hpp"
#include "safestate/core/command_queue.hpp"

using namespace safestate::test;

namespace {
Command raw_cmd(Bench& b, CommandId id, Source src = Source::pendant) { return b.make(id, src); }

void lock_out(Bench& b) {
  b.to_idle();
  b.plant.fieldbus = false;
  b.cycle();
  ASSERT_EQ(b.out.state, State::ERROR_LOCKOUT);
}

// Everything the manager shows to the outside, to prove a refusal changed nothing.
struct Snapshot {
  State state;
  Sub sub;
  StopCat stop;
  AlarmMask alarms;
  bool contactor, drives, brakes, lamp, t2;
  MotionMode motion;
  bool operator==(const Snapshot&) const = default;
};
Snapshot snap(const SupervisorOut& o) {
  return {o.state, o.sub, o.stop, o.alarms, o.contactor, o.drives_enable, o.brakes_release, o.reset_lamp, o.t2_confirmed,
          o.motion.mode};
}
}  // namespace

// ---------------------------------------------------------------- check order
// @req RES-ORDER
TEST(CheckOrder, MalformedComesBeforeLockedOut) {
  Bench b;
  lock_out(b);
  Command c = raw_cmd(b, CommandId::reset);
  c.id = 200;
  EXPECT_EQ(b.command(c), Result::UNKNOWN_COMMAND);
  Command j = raw_cmd(b, CommandId::jog);
  j.axis = 9;
  j.dir = 1;
  j.speed = 10;
  EXPECT_EQ(b.command(j), Result::BAD_ARGUMENT);
}

// @req RES-ORDER
TEST(CheckOrder, LockedOutComesBeforeOwnership) {
  Bench b;
  lock_out(b);
  EXPECT_EQ(b.command(CommandId::start, Source::observer), Result::LOCKED_OUT);
  EXPECT_EQ(b.command(CommandId::reset, Source::remote), Result::LOCKED_OUT);
}

// @req RES-ORDER
TEST(CheckOrder, OwnershipComesBeforeStateRules) {
  Bench b;
  b.boot();
  ASSERT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
  EXPECT_EQ(b.command(CommandId::reset, Source::remote), Result::NOT_CONTROL_OWNER);
  EXPECT_EQ(b.command(CommandId::servo_on, Source::observer), Result::NOT_CONTROL_OWNER);
}

// ---------------------------------------------------------------- each code
// @req RES-ORDER
TEST(Results, UnknownCommand) {
  Bench b;
  b.to_idle();
  Command c = raw_cmd(b, CommandId::reset);
  c.id = static_cast<std::uint8_t>(kCommandCount);
  EXPECT_EQ(b.command(c), Result::UNKNOWN_COMMAND);
  EXPECT_EQ(b.replies.back().cmd, kCommandCount) << "the reply names what was received";
}

// @req TR-JOG-ARGS RES-ORDER
TEST(Results, BadArgument) {
  Bench b;
  b.to_operational(Mode::T1);
  const int bad[][3] = {{0, 1, 10}, {7, 1, 10}, {9, 1, 10}, {-1, 1, 10}, {1, 0, 10},
                        {1, 2, 10}, {1, 1, 0},  {1, 1, 101}, {1, -2, 50}};
  for (const auto& a : bad) {
    EXPECT_EQ(b.jog(a[0], a[1], a[2]), Result::BAD_ARGUMENT) << a[0] << " " << a[1] << " " << a[2];
    EXPECT_EQ(b.out.sub, Sub::MANUAL_IDLE);
  }
  Command m = raw_cmd(b, CommandId::set_mode);
  m.mode = 9;
  EXPECT_EQ(b.command(m), Result::BAD_ARGUMENT);
  Command s = raw_cmd(b, CommandId::reset);
  s.source = 17;
  EXPECT_EQ(b.command(s), Result::BAD_ARGUMENT);
}

// @req RES-OWNER
TEST(Results, NotControlOwner) {
  Bench b;
  b.to_operational(Mode::AUTO);
  EXPECT_EQ(b.command(CommandId::start, Source::observer), Result::NOT_CONTROL_OWNER);
  EXPECT_EQ(b.command(CommandId::reset, Source::remote), Result::NOT_CONTROL_OWNER) << "reset never remote";
  EXPECT_EQ(b.command(CommandId::start, Source::remote), Result::OK) << "remote may command in AUTO";
  EXPECT_EQ(b.command(CommandId::stop, Source::reset_button), Result::NOT_CONTROL_OWNER);

  Bench m;
  m.to_operational(Mode::T1);
  EXPECT_EQ(m.command(CommandId::start, Source::remote), Result::NOT_CONTROL_OWNER) << "T1: pendant only";
  EXPECT_EQ(m.jog(1, 1, 10, Source::remote), Result::NOT_CONTROL_OWNER);
  EXPECT_EQ(m.command(CommandId::servo_off, Source::remote), Result::NOT_CONTROL_OWNER);
}

// @req RES-LOCKED-OUT
TEST(Results, LockedOutForEveryCommand) {
  Bench b;
  lock_out(b);
  for (std::uint8_t id = 0; id < kCommandCount; ++id) {
    Command c = raw_cmd(b, static_cast<CommandId>(id));
    c.axis = 1;
    c.dir = 1;
    c.speed = 10;
    c.mode = static_cast<std::uint8_t>(Mode::T1);
    c.has_code = 1U;
    EXPECT_EQ(b.command(c), Result::LOCKED_OUT) << to_string(static_cast<CommandId>(id));
  }
}

// @req RES-ESTOP
TEST(Results, EstopActiveForResetAndMotionCommands) {
  Bench b;
  b.to_idle();
  b.estop(true);
  b.cycle();
  for (CommandId id : {CommandId::reset, CommandId::servo_on, CommandId::start, CommandId::resume}) {
    EXPECT_EQ(b.command(id), Result::ESTOP_ACTIVE) << to_string(id);
  }
  EXPECT_EQ(b.jog(1, 1), Result::ESTOP_ACTIVE);
  EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE);
}

// @req RES-RESET-NEEDED
TEST(Results, ResetRequiredForAnythingButResetInEstopResetNeeded) {
  Bench b;
  b.boot();
  for (CommandId id : {CommandId::servo_on, CommandId::servo_off, CommandId::start, CommandId::pause,
                       CommandId::resume, CommandId::stop, CommandId::jog_stop, CommandId::confirm_t2}) {
    EXPECT_EQ(b.command(id), Result::RESET_REQUIRED) << to_string(id);
  }
  EXPECT_EQ(b.jog(1, 1), Result::RESET_REQUIRED);
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
}

// @req TR-LATCH TR-SERVO-ON
TEST(Results, ResetRequiredForServoOnWithALatchedAlarm) {
  Bench b;
  b.to_auto_running();
  b.gate(true);
  b.cycle();
  ASSERT_GT(b.finish_stop(), 0);
  b.gate(false);
  b.cycle();
  EXPECT_EQ(b.command(CommandId::servo_on), Result::RESET_REQUIRED);
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
  EXPECT_EQ(b.command(CommandId::servo_on), Result::OK);
}

// @req TR-RESET-IDLE
TEST(Results, FaultPresentWhileTheCauseIsPresent) {
  Bench b;
  b.to_auto_running();
  b.gate(true);
  b.cycle();
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.command(CommandId::reset), Result::FAULT_PRESENT);
}

// @req TR-SERVO-ON
TEST(Results, ModeInvalid) {
  Bench b;
  b.to_idle();
  b.mode(Mode::NONE);
  b.cycle(51);
  ASSERT_EQ(b.out.mode, Mode::NONE);
  EXPECT_EQ(b.command(CommandId::servo_on), Result::MODE_INVALID);
  b.mode(Mode::T1);
  b.cycle();
  EXPECT_EQ(b.command(CommandId::confirm_t2), Result::MODE_INVALID) << "confirm_t2 only with T2 selected";
}

// @req IN-SET-MODE
TEST(Results, ModeBySelectorOnlyAlways) {
  Bench b;
  b.to_idle();
  Command c = raw_cmd(b, CommandId::set_mode);
  c.mode = static_cast<std::uint8_t>(Mode::T1);
  EXPECT_EQ(b.command(c), Result::MODE_BY_SELECTOR_ONLY);
  EXPECT_EQ(b.out.mode, Mode::AUTO);
  b.to_operational();
  Command d = raw_cmd(b, CommandId::set_mode);
  d.mode = static_cast<std::uint8_t>(Mode::AUTO);
  EXPECT_EQ(b.command(d), Result::MODE_BY_SELECTOR_ONLY);
}

// @req TR-SERVO-ON
TEST(Results, GateOpen) {
  Bench b;
  b.to_idle();
  b.gate(true);
  b.cycle();
  EXPECT_EQ(b.command(CommandId::servo_on), Result::GATE_OPEN);
  EXPECT_EQ(b.out.state, State::IDLE);
}

// @req TR-START-AUTO TR-RESUME
TEST(Results, GateOpenForResumeAndStart) {
  // Reach AUTO_PAUSED, then test resume with the guard open in the same cycle as it
  // opens (rule 4 acts first, so the resume meets STOPPING: BUSY), proving the order.
  Bench b;
  b.to_auto_running();
  ASSERT_EQ(b.command(CommandId::pause), Result::OK);
  ASSERT_GT(b.finish_stop(), 0);
  b.gate(true);
  EXPECT_EQ(b.command(CommandId::resume), Result::BUSY);
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
}

// @req TR-SERVO-ON TR-JOG TR-START-MANUAL
TEST(Results, EnablingNotHeld) {
  Bench b;
  b.mode(Mode::T1);
  b.to_idle();
  EXPECT_EQ(b.command(CommandId::servo_on), Result::ENABLING_NOT_HELD);
  b.enable_panic();
  b.cycle();
  b.raw.enable_panic = false;
  b.enable_centre();  // panic straight back to centre: does not count
  b.cycle();
  EXPECT_EQ(b.command(CommandId::servo_on), Result::ENABLING_NOT_HELD);
  b.enable_released();
  b.cycle();
  b.enable_centre();
  b.cycle();
  EXPECT_EQ(b.command(CommandId::servo_on), Result::OK);
}

// @req TR-SERVO-ON TR-CONFIRM-T2
TEST(Results, T2NotConfirmed) {
  Bench b;
  b.mode(Mode::T2);
  b.to_idle();
  b.enable_centre();
  b.cycle();
  EXPECT_EQ(b.command(CommandId::servo_on), Result::T2_NOT_CONFIRMED);
}

// @req RES-WRONG-STATE
TEST(Results, JogNotInAuto) {
  Bench b;
  b.to_idle();
  EXPECT_EQ(b.jog(1, 1), Result::JOG_NOT_IN_AUTO);
  b.to_operational();
  EXPECT_EQ(b.jog(1, 1), Result::JOG_NOT_IN_AUTO);
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE);
}

// @req TR-START-AUTO TR-START-MANUAL
TEST(Results, NoProgram) {
  Bench b;
  b.plant.program_loaded = false;
  b.to_operational();
  EXPECT_EQ(b.command(CommandId::start), Result::NO_PROGRAM);
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE);
}

// @req RES-WRONG-STATE
TEST(Results, BusyInArmingAndStopping) {
  Bench b;
  b.to_idle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  EXPECT_EQ(b.command(CommandId::start), Result::BUSY);
  EXPECT_EQ(b.command(CommandId::reset), Result::BUSY);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return o.state == State::OPERATIONAL; }, 1000), 0);
  ASSERT_EQ(b.command(CommandId::start), Result::OK);
  b.plant.vel.fill(0.5F);
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  EXPECT_EQ(b.command(CommandId::start), Result::BUSY);
  EXPECT_EQ(b.command(CommandId::servo_on), Result::BUSY);
}

// @req RES-WRONG-STATE
TEST(Results, WrongState) {
  Bench b;
  b.mode(Mode::T1);
  b.to_idle();
  EXPECT_EQ(b.command(CommandId::start), Result::WRONG_STATE);
  EXPECT_EQ(b.jog(1, 1), Result::WRONG_STATE);
  EXPECT_EQ(b.command(CommandId::servo_off), Result::WRONG_STATE);
  b.enable_centre();
  b.cycle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return o.state == State::OPERATIONAL; }, 1000), 0);
  EXPECT_EQ(b.command(CommandId::jog_stop), Result::WRONG_STATE);
  EXPECT_EQ(b.command(CommandId::resume), Result::WRONG_STATE);
  EXPECT_EQ(b.command(CommandId::pause), Result::WRONG_STATE);
}

// @req RES-QUEUE-FULL
TEST(Results, QueueFull) {
  CommandQueue<4> q;
  Command c{};
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(q.push(c), Result::OK);
  }
  EXPECT_EQ(q.push(c), Result::QUEUE_FULL);
  EXPECT_EQ(q.size(), 4U);
  std::array<Command, 8> out{};
  EXPECT_EQ(q.peek(out.data(), out.size()), 4U);
  q.pop(3);
  EXPECT_EQ(q.size(), 1U);
  EXPECT_EQ(q.push(c), Result::OK);
}

// @req RES-RESET-OK TR-RESET-OP
TEST(Results, ResetWithNothingToResetIsOk) {
  Bench b;
  b.to_idle();
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
  b.to_operational();
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE);
}

// ---------------------------------------------------------------- one result each
// @req RES-ONE RES-SAME-CYCLE
TEST(OneResult, EveryCommandGetsExactlyOneReply) {
  Bench b;
  b.to_idle();
  std::vector<std::uint32_t> seqs;
  for (int i = 0; i < 20; ++i) {
    Command c = raw_cmd(b, static_cast<CommandId>(i % kCommandCount));
    c.axis = 1;
    c.dir = 1;
    c.speed = 10;
    c.mode = 1;
    seqs.push_back(c.seq);
    b.send(c);
  }
  b.replies.clear();
  b.cycle(5);
  ASSERT_EQ(b.replies.size(), seqs.size());
  for (std::size_t i = 0; i < seqs.size(); ++i) {
    EXPECT_EQ(b.replies[i].seq, seqs[i]) << "answered in arrival order";
  }
}

// @req CYC-MAX-COMMANDS
TEST(OneResult, AtMostMaxCommandsPerCycleAreTaken) {
  Bench b;
  b.to_idle();
  for (int i = 0; i < 11; ++i) {
    b.send(CommandId::reset);
  }
  b.replies.clear();
  b.cycle();
  EXPECT_EQ(b.replies.size(), 8U);
  EXPECT_EQ(b.queue.size(), 3U);
  b.cycle();
  EXPECT_EQ(b.replies.size(), 11U);
}

// @req RES-NO-CHANGE
TEST(OneResult, ARefusedCommandChangesNothing) {
  Bench b;
  b.to_operational();
  const Snapshot before = snap(b.out);
  b.cycle();
  EXPECT_EQ(snap(b.out), before);
  for (CommandId id : {CommandId::resume, CommandId::jog_stop, CommandId::pause, CommandId::confirm_t2}) {
    ASSERT_NE(b.command(id), Result::OK) << to_string(id);
    EXPECT_EQ(snap(b.out), before) << to_string(id);
  }
  Command m = raw_cmd(b, CommandId::set_mode);
  m.mode = 2;
  ASSERT_EQ(b.command(m), Result::MODE_BY_SELECTOR_ONLY);
  EXPECT_EQ(snap(b.out), before);
}

// @req AL-LIFETIME
TEST(OneResult, InfoAlarmsLastUntilTheNextCommandAnsweredOk) {
  Bench b;
  b.to_operational();
  b.mode(Mode::T1);
  b.cycle();
  ASSERT_TRUE(b.alarm(AlarmId::MODE_CHANGED));
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_TRUE(b.alarm(AlarmId::MODE_CHANGED));
  EXPECT_EQ(b.command(CommandId::start), Result::WRONG_STATE);
  EXPECT_TRUE(b.alarm(AlarmId::MODE_CHANGED)) << "a refused command does not clear it";
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
  EXPECT_FALSE(b.alarm(AlarmId::MODE_CHANGED));
}

// ---------------------------------------------------------------- reset button
// @req IN-RESET-EDGE IN-RESET-FRESH
TEST(ResetButtonRule, FreshPressAndReleaseResets) {
  Bench b;
  b.boot();
  b.raw.reset_button = true;
  b.cycle(100);
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED) << "acts on release";
  b.raw.reset_button = false;
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  ASSERT_FALSE(b.replies.empty());
  EXPECT_EQ(b.replies.back().source, static_cast<std::uint8_t>(Source::reset_button));
}

// @req IN-RESET-FRESH
TEST(ResetButtonRule, PressBegunBeforeResetBecamePossibleIsNoReset) {
  Bench b;
  b.to_idle();
  b.estop(true);
  b.cycle();
  b.raw.reset_button = true;  // pressed while the E-stop is still pressed
  b.cycle(10);
  b.estop(false);
  b.cycle(10);
  ASSERT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
  b.raw.reset_button = false;
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
  b.raw.reset_button = true;
  b.cycle();
  b.raw.reset_button = false;
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
}

// @req IN-RESET-FRESH
TEST(ResetButtonRule, HeldLongerThanFiveSecondsIsNoResetAndRaisesStuck) {
  Bench b;
  b.boot();
  b.raw.reset_button = true;
  b.cycle(5000);
  EXPECT_FALSE(b.alarm(AlarmId::RESET_BUTTON_STUCK));
  b.cycle();
  EXPECT_TRUE(b.alarm(AlarmId::RESET_BUTTON_STUCK));
  b.raw.reset_button = false;
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
  EXPECT_FALSE(b.alarm(AlarmId::RESET_BUTTON_STUCK));
}

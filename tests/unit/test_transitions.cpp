// Every row of SPEC §4 as its own named test, through the whole supervisor.
#include <algorithm>

#include "bench.hpp"

using namespace safestate::test;

// ================================================================ the table itself
// @req TR-PRIORITY
TEST(TransitionTable, EveryRowIsReachableThroughTheIndex) {
  for (std::size_t r = 0; r < kTransitions.size(); ++r) {
    bool found = false;
    for (std::size_t l = 0; l < kLeafCount; ++l) {
      if ((kTransitions[r].from & (1U << l)) != 0U) {
        EXPECT_EQ(find_row(static_cast<Leaf>(l), kTransitions[r].trigger), &kTransitions[r]) << "row " << r;
        found = true;
      }
    }
    EXPECT_TRUE(found) << "row " << r << " has no from-state";
  }
}

// @req TR-PRIORITY
TEST(TransitionTable, ConditionRowsComeFirstInPriorityOrder) {
  std::size_t last = 0;
  bool in_conditions = true;
  for (const Transition& t : kTransitions) {
    if (is_condition(t.trigger)) {
      ASSERT_TRUE(in_conditions) << "condition row after an event/command row";
      ASSERT_GE(static_cast<std::size_t>(t.trigger), last);
      last = static_cast<std::size_t>(t.trigger);
    } else {
      in_conditions = false;
    }
  }
}

// @req TR-C1
TEST(TransitionTable, LockoutIsNeverLeftByAnyRow) {
  for (const Transition& t : kTransitions) {
    if ((t.from & mask_of(Leaf::ERROR_LOCKOUT)) != 0U) {
      EXPECT_EQ(t.to, Leaf::ERROR_LOCKOUT) << to_string(t.trigger);
    }
  }
}

// ================================================================ BOOT
// @req TR-BOOT
TEST(Boot, PassedGoesToEstopResetNeeded) {
  Bench b;
  b.cycle();
  EXPECT_EQ(b.out.state, State::BOOT);
  EXPECT_TRUE(all_outputs_safe(b.out));
  b.boot();
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
  EXPECT_TRUE(b.out.reset_lamp);
  EXPECT_LE(b.ssm().now(), 100U) << "the simulated BOOT ends within 100 cycles";
}

// @req TR-BOOT TR-C2
TEST(Boot, EstopPressedGoesToEstopActive) {
  Bench b;
  b.estop(true);
  b.cycle(150);
  EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE);
  EXPECT_FALSE(b.ssm().boot_pending());
  b.estop(false);
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
}

// @req TR-RESET-ESTOP
TEST(Boot, ResetBeforeTheSelfTestEndsIsBusy) {
  Bench b;
  b.plant.boot_cycles = 1000;  // drives slow to answer
  b.estop(true);
  b.cycle();
  b.estop(false);
  b.cycle();
  ASSERT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
  EXPECT_EQ(b.command(CommandId::reset), Result::BUSY);
}

// @req TR-BOOT-FAILED TR-C1
TEST(Boot, TimeoutLocksOutWithBootFailed) {
  Bench b;
  b.plant.fieldbus = false;
  b.cycle(3001);  // cycles 0..3000: not yet more than 3000 ms
  EXPECT_EQ(b.out.state, State::BOOT);
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::BOOT_FAILED));
  EXPECT_EQ(b.out.cause.alarm, AlarmId::BOOT_FAILED);
  EXPECT_EQ(b.out.cause.detail.signal, Signal::fieldbus);
}

// @req TR-BOOT-FAILED AL-CAUSE
TEST(Boot, ADriveThatNeverAnswersNamesItsAxis) {
  Bench b;
  b.fb.drive[3].online = false;  // the bench refills statuswords, never `online`  // bench refills statuswords, not `online`
  b.cycle(3001);  // cycles 0..3000
  EXPECT_EQ(b.out.state, State::BOOT);
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_EQ(b.out.cause.detail.axis, 4U);
}

// @req TR-BOOT-FAILED AL-CAUSE
TEST(Boot, ABusNotAsConfiguredFailsAtOnceNamingTheSubdevice) {
  // The fieldbus scan found a wrong identity at bus position 3: no timeout to wait for.
  Bench b;
  b.plant.fieldbus = false;
  b.fb.fieldbus_boot_failed = true;  // not refilled by the plant
  b.fb.fieldbus_subdevice = 3;
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_EQ(b.out.cause.alarm, AlarmId::BOOT_FAILED);
  EXPECT_EQ(b.out.cause.detail.signal, Signal::fieldbus);
  EXPECT_EQ(b.out.cause.detail.code, 3U);
  char buf[96];
  EXPECT_STREQ(describe(b.out.cause, buf, sizeof buf), "Start-up failed: fieldbus not as configured at subdevice 3");
}

// @req TR-BOOT-FAILED
TEST(Boot, ABusNotAsConfiguredIsNeverPassedEvenWithEveryDriveAnswering) {
  Bench b;
  b.fb.fieldbus_boot_failed = true;  // the drives answer, the bus still is not the one configured
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::BOOT_FAILED));
}

// @req TR-BOOT-FAILED
TEST(Boot, SelfTestRejectsAnImpossibleTimingAndLocksOut) {
  // An integrator that bypasses validate(): the supervisor's own start-up check fails.
  const auto bad = [](void (*mutate)(Config&)) {
    Config c{};
    mutate(c);
    return c;
  };
  const Config cases[] = {
      bad([](Config& c) { c.standstill_cycles = 0; }),
      bad([](Config& c) { c.max_commands_per_cycle = 0; }),
      bad([](Config& c) { c.max_commands_per_cycle = 17; }),
      bad([](Config& c) { c.standstill_rad_s = 0.0F; }),
  };
  for (const Config& c : cases) {
    Bench b(c);
    b.cycle();
    EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
    EXPECT_TRUE(b.alarm(AlarmId::BOOT_FAILED));
    EXPECT_EQ(b.ssm().alarms().detail(AlarmId::BOOT_FAILED).signal, Signal::internal);
  }
}

// @req TR-BOOT-FAILED ST-UNKNOWN-UNSAFE
TEST(Boot, AnUndecodableStatuswordIsNoAnswer) {
  Bench b;
  b.plant.boot_cycles = 1000000;  // the bench drives keep the states set here
  b.plant.ds.fill(c402::DriveState::SwitchOnDisabled);
  b.plant.ds[1] = static_cast<c402::DriveState>(99);  // statusword 0x004F: no CiA 402 state
  b.cycle(200);
  EXPECT_EQ(b.out.state, State::BOOT) << "a drive that does not answer properly holds BOOT";
  b.plant.ds[1] = c402::DriveState::SwitchOnDisabled;
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
}

// ================================================================ rule 1: lockout
// @req TR-C1 IN-DISCREPANCY
TEST(Rule1, EstopDiscrepancyLocksOutFromOperational) {
  Bench b;
  b.to_operational();
  b.raw.estop_b = false;  // channel B opens alone
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE) << "one channel is enough to stop";
  b.cycle(49);
  EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE);
  b.cycle();  // 51st cycle of disagreement
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::ESTOP_DISCREPANCY));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::ESTOP_DISCREPANCY).channel, Channel::b);
  EXPECT_TRUE(all_outputs_safe(b.out));
}

// @req TR-C1 IN-DISCREPANCY
TEST(Rule1, GateDiscrepancyLocksOutFromIdle) {
  Bench b;
  b.to_idle();
  b.raw.gate_a = false;
  b.cycle(51);
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::GATE_DISCREPANCY));
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
}

// @req TR-C1 IN-DISCREPANCY
TEST(Rule1, EnableDiscrepancyLocksOutFromManual) {
  Bench b;
  b.to_operational(Mode::T1);
  b.raw.enable_b = false;
  b.cycle();
  EXPECT_EQ(b.out.state, State::STOPPING) << "centre lost on one contact: Cat 1 at once";
  b.cycle(50);
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::ENABLE_DISCREPANCY));
  EXPECT_TRUE(all_outputs_safe(b.out));
}

// @req TR-C1 CYC-ZERO-DELAY
TEST(Rule1, FieldbusLostLocksOutInTheSameCycle) {
  Bench b;
  b.to_auto_running();
  b.plant.fieldbus = false;
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_TRUE(b.alarm(AlarmId::FIELDBUS_LOST));
  EXPECT_TRUE(all_outputs_safe(b.out));
}

// @req TR-C1
TEST(Rule1, ADriveDroppingOffTheBusLocksOut) {
  Bench b;
  b.to_idle();
  b.fb.drive[2].online = false;  // not refilled by the plant
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::FIELDBUS_LOST));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::FIELDBUS_LOST).axis, 3U);
}

// @req TR-C1 AL-CAUSE
TEST(Rule1, FieldbusLostNamesTheSubdeviceAtFault) {
  Bench b;
  b.to_idle();
  b.plant.fieldbus = false;
  b.fb.fieldbus_subdevice = 8;  // e.g. the last drive on the line left OP
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_EQ(b.out.cause.alarm, AlarmId::FIELDBUS_LOST);
  EXPECT_EQ(b.out.cause.detail.code, 8U);
  char buf[96];
  EXPECT_STREQ(describe(b.out.cause, buf, sizeof buf), "Fieldbus lost at subdevice 8");
}

// @req TR-C1 AL-CAUSE
TEST(Rule1, ASilentFieldbusNamesWhereTheSilenceBegins) {
  Bench b;
  b.to_idle();
  b.plant.fieldbus = false;
  b.fb.fieldbus_subdevice = 1;  // no frame comes back: nothing answers from the first on
  b.fb.fieldbus_silent = true;
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_EQ(b.out.cause.detail.code, 1U | kFieldbusSilentFrom);
  char buf[96];
  EXPECT_STREQ(describe(b.out.cause, buf, sizeof buf), "Fieldbus lost: no answer from subdevice 1 on");
}

TEST(Rule1, ASilentFieldbusWithoutASubdeviceIsPlainFieldbusLost) {
  // No frame back, but no position known: no "silent from" flag on subdevice 0.
  Bench b;
  b.to_idle();
  b.plant.fieldbus = false;
  b.fb.fieldbus_subdevice = 0;
  b.fb.fieldbus_silent = true;
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_EQ(b.out.cause.alarm, AlarmId::FIELDBUS_LOST);
  EXPECT_EQ(b.out.cause.detail.code, 0U);
  char buf[96];
  EXPECT_STREQ(describe(b.out.cause, buf, sizeof buf), "Fieldbus lost");
}

// @req TR-C1
TEST(Rule1, IntegrityFaultLocksOut) {
  Bench b;
  b.to_idle();
  b.fb.integrity_ok = false;  // not refilled by the plant: stays for the next cycle
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::INTEGRITY_FAULT));
  EXPECT_EQ(b.out.cause.alarm, AlarmId::INTEGRITY_FAULT);
}

// @req TR-C1 AL-LIFETIME
TEST(Rule1, LockoutIsNeverLeft) {
  Bench b;
  b.to_idle();
  b.plant.fieldbus = false;
  b.cycle();
  ASSERT_EQ(b.out.state, State::ERROR_LOCKOUT);
  b.plant.fieldbus = true;
  b.estop(true);
  b.cycle(10);
  b.estop(false);
  b.cycle(10);
  EXPECT_EQ(b.command(CommandId::reset), Result::LOCKED_OUT);
  b.raw.reset_button = true;
  b.cycle(5);
  b.raw.reset_button = false;
  b.cycle(5);
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::FIELDBUS_LOST)) << "lockout alarms last until power cycle";
}

// ================================================================ rule 2: E-stop
// @req TR-C2 ST-CAT0 CYC-ZERO-DELAY
TEST(Rule2, EstopFromEveryStateButLockoutIsCat0InTheSameCycle) {
  struct Path {
    const char* name;
    void (*go)(Bench&);
  };
  const Path paths[] = {
      {"ESTOP_RESET_NEEDED", [](Bench& b) { b.boot(); }},
      {"IDLE", [](Bench& b) { b.to_idle(); }},
      {"ARMING",
       [](Bench& b) {
         b.to_idle();
         ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
         b.cycle(30);
       }},
      {"AUTO_RUNNING", [](Bench& b) { b.to_auto_running(); }},
      {"MANUAL_JOGGING", [](Bench& b) { b.to_jogging(); }},
      {"STOPPING", [](Bench& b) {
         b.to_auto_running();
         ASSERT_EQ(b.command(CommandId::pause), Result::OK);
       }},
  };
  for (const Path& p : paths) {
    Bench b;
    p.go(b);
    b.raw.estop_a = false;
    b.cycle();
    EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE) << p.name;
    EXPECT_EQ(b.out.stop, StopCat::CAT0) << p.name;
    EXPECT_TRUE(all_outputs_safe(b.out)) << p.name;
    EXPECT_TRUE(b.alarm(AlarmId::ESTOP_PRESSED)) << p.name;
    EXPECT_EQ(b.out.cause.detail.channel, Channel::a) << p.name;
  }
}

// @req TR-C2 AL-LIFETIME
TEST(Rule2, EstopPressedAlarmLastsWhileTheConditionLasts) {
  Bench b;
  b.to_idle();
  b.estop(true);
  b.cycle(5);
  EXPECT_TRUE(b.alarm(AlarmId::ESTOP_PRESSED));
  b.estop(false);
  b.cycle();
  EXPECT_FALSE(b.alarm(AlarmId::ESTOP_PRESSED));
}

// ================================================================ rule 3
// @req TR-C3 ST-CAT0
TEST(Rule3, DriveFaultIsCat0ToIdleLatched) {
  Bench b;
  b.to_auto_running();
  b.plant.drive_fault[2] = true;
  b.cycle();  // the statusword reads Fault in this cycle
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_TRUE(all_outputs_safe(b.out));
  EXPECT_TRUE(b.alarm(AlarmId::DRIVE_FAULT));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::DRIVE_FAULT).axis, 3U);
  EXPECT_TRUE(b.out.reset_lamp);
}

// @req TR-C3
TEST(Rule3, DriveLeavingOperationEnabledOnItsOwnIsADriveFault) {
  Bench b;
  b.to_operational();
  b.plant.ds[4] = c402::DriveState::SwitchOnDisabled;
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::DRIVE_FAULT).axis, 5U);
}

// @req TR-C3
TEST(Rule3, ADriveThatDoesNotFollowItsSetPointIsADriveFault) {
  Bench b;
  b.to_operational();
  b.fb.following_error_axis = 4;  // reported by the motion layer; not refilled by the plant
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::DRIVE_FAULT).axis, 4U);
}

// @req TR-C3 AL-FIRST-OUT
TEST(Rule3, TwoDriveFaultsInOneCycleNameTheFirst) {
  Bench b;
  b.to_operational();
  b.plant.drive_fault[1] = true;   // drive 2 reports Fault ...
  b.fb.following_error_axis = 5;   // ... and drive 5 lags, in the same cycle
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::DRIVE_FAULT).axis, 2U);
}

// The plant's joints move, the core differentiates the positions of its own kinematics
// (exactly the limit: TEST(T1SpeedMonitor, ...) in test_monitors.cpp, on positions chosen so).
// @req TR-C3 MO-T1-MONITOR
TEST(Rule3, T1SpeedAboveTheLimitIsCat0) {
  Bench b;
  b.to_jogging(Mode::T1);
  b.plant.vel[0] = plant_axis1_for(249.0F, b.plant.pos);
  b.cycle(5);
  EXPECT_EQ(b.out.sub, Sub::MANUAL_JOGGING) << "below the limit";
  b.plant.vel[0] = plant_axis1_for(251.0F, b.plant.pos);
  b.cycle();  // the positions of this cycle are 251 mm/s apart from the last (the plant moved after it)
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_TRUE(b.alarm(AlarmId::T1_SPEED_EXCEEDED));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::T1_SPEED_EXCEEDED).axis, 6U) << "the flange, farthest from axis 1";
  EXPECT_NEAR(b.ssm().alarms().detail(AlarmId::T1_SPEED_EXCEEDED).code, 251, 1) << "mm/s";
}

// Issue 35: the T1 speed is the core's own, from the measured joint positions through its
// kinematics, never the figure the motion layer hands over.
// @req MO-T1-MONITOR
TEST(Rule3, T1SpeedIsTheCoresOwnNotTheMotionLayers) {
  {
    Bench b;  // the joints run away while the motion layer says nothing moves
    b.to_jogging(Mode::T1);
    b.plant.motion_speed = 0.0F;
    b.plant.vel[0] = plant_axis1_for(400.0F, b.plant.pos);
    b.cycle(3);
    EXPECT_EQ(b.out.state, State::IDLE);
    EXPECT_TRUE(b.alarm(AlarmId::T1_SPEED_EXCEEDED));
  }
  {
    Bench b;  // the motion layer's figure is wrong the other way: no stop for it
    b.to_jogging(Mode::T1);
    b.plant.motion_speed = 900.0F;
    b.plant.vel[0] = plant_axis1_for(100.0F, b.plant.pos);
    b.cycle(50);
    EXPECT_EQ(b.out.sub, Sub::MANUAL_JOGGING);
    EXPECT_FALSE(b.alarm(AlarmId::T1_SPEED_EXCEEDED));
  }
}

// @req TR-C3 TR-C6
TEST(Rule3, KeyToT1WhileMovingFastIsRule6NotAT1SpeedFault) {
  Bench b;
  b.to_auto_running();
  b.plant.vel[0] = plant_axis1_for(900.0F, b.plant.pos);
  b.cycle();
  b.mode(Mode::T1);
  b.cycle();
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
  EXPECT_FALSE(b.alarm(AlarmId::T1_SPEED_EXCEEDED));
  EXPECT_TRUE(b.alarm(AlarmId::MODE_CHANGED));
}

// @req MO-T1-MONITOR
TEST(Rule3, T1SpeedIsNotMonitoredInT2) {
  Bench b;
  b.to_jogging(Mode::T2);
  b.plant.vel[0] = plant_axis1_for(900.0F, b.plant.pos);
  b.cycle(5);
  EXPECT_EQ(b.out.sub, Sub::MANUAL_JOGGING);
}

// @req TR-C3 ST-STOP-TIME
TEST(Rule3, StopTimeExceededEscalatesToCat0AtTheFirstCycleBeyond) {
  Bench b;
  b.to_auto_running();
  b.plant.drive_nostop[1] = true;
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  ASSERT_EQ(b.out.state, State::STOPPING);
  b.cycle(1000);
  EXPECT_EQ(b.out.state, State::STOPPING) << "1000 ms is still within max_stop_ms";
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_TRUE(b.alarm(AlarmId::STOP_TIME_EXCEEDED));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::STOP_TIME_EXCEEDED).axis, 2U);
}

// ================================================================ rule 4 / 4b
// @req TR-C4 ST-CAT1
TEST(Rule4, GateOpenInAutoIsCat1ToIdleLatched) {
  Bench b;
  b.to_auto_running();
  b.gate(true);
  b.cycle();
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
  EXPECT_EQ(b.out.target, Leaf::IDLE);
  EXPECT_EQ(b.out.motion.mode, MotionMode::QuickStop);
  EXPECT_TRUE(b.out.drives_enable) << "Cat 1 keeps power to ramp down";
  EXPECT_TRUE(b.alarm(AlarmId::PROTECTIVE_STOP));
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(all_outputs_safe(b.out));
  EXPECT_TRUE(b.alarm(AlarmId::PROTECTIVE_STOP));
  EXPECT_TRUE(b.out.reset_lamp);
}

// @req TR-C4
TEST(Rule4, GateOpenDuringACat2StopBecomesCat1) {
  Bench b;
  b.to_auto_running();
  ASSERT_EQ(b.command(CommandId::pause), Result::OK);
  ASSERT_EQ(b.out.stop, StopCat::CAT2);
  b.gate(true);
  b.cycle();
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
  EXPECT_EQ(b.out.target, Leaf::IDLE);
}

// @req TR-C4b
TEST(Rule4b, GateOpenInArmingIsCat0ToIdle) {
  Bench b;
  b.to_idle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  b.cycle(20);
  ASSERT_EQ(b.out.state, State::ARMING);
  b.gate(true);
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_TRUE(b.alarm(AlarmId::PROTECTIVE_STOP));
  EXPECT_TRUE(all_outputs_safe(b.out));
}

// @req TR-C4
TEST(Rule4, GateOpenInT1IsNotAProtectiveStop) {
  Bench b;
  b.to_jogging(Mode::T1);
  b.gate(true);
  b.cycle(5);
  EXPECT_EQ(b.out.sub, Sub::MANUAL_JOGGING);
  EXPECT_FALSE(b.alarm(AlarmId::PROTECTIVE_STOP));
}

// ================================================================ rule 5 / 5b
// @req TR-C5
TEST(Rule5, EnableReleasedInT1IsCat1ToIdle) {
  Bench b;
  b.to_jogging(Mode::T1);
  b.enable_released();
  b.cycle();
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
  EXPECT_FALSE(b.alarm(AlarmId::ENABLING_PANIC));
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_FALSE(b.out.reset_lamp) << "a release latches nothing";
}

// @req TR-C5
TEST(Rule5, PanicIsACat1StopAndRaisesEnablingPanic) {
  Bench b;
  b.to_jogging(Mode::T1);
  b.enable_panic();
  b.cycle();
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
  EXPECT_TRUE(b.alarm(AlarmId::ENABLING_PANIC));
  EXPECT_EQ(alarm_info(AlarmId::ENABLING_PANIC).severity, Severity::info);
}

// @req TR-C5b
TEST(Rule5b, EnableReleasedInArmingIsCat0ToIdle) {
  Bench b;
  b.mode(Mode::T1);
  b.to_idle();
  b.enable_centre();
  b.cycle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  b.cycle(5);
  b.enable_released();
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
}

// ================================================================ rule 6
// @req TR-C6
TEST(Rule6, ModeChangeInOperationalIsCat1WithModeChanged) {
  Bench b;
  b.to_auto_running();
  b.mode(Mode::T1);
  b.cycle();
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
  EXPECT_TRUE(b.alarm(AlarmId::MODE_CHANGED));
}

// @req TR-C6b
TEST(Rule6, ModeChangeInArmingIsIdleAtOnce) {
  Bench b;
  b.to_idle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  b.cycle(3);
  b.mode(Mode::T2);
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(all_outputs_safe(b.out));
  EXPECT_TRUE(b.alarm(AlarmId::MODE_CHANGED));
}

// @req TR-C6 IN-MODE-INVALID
TEST(Rule6, SelectorWithNoPositionStopsOnlyAfterTheDiscrepancyTime) {
  Bench b;
  b.to_operational();
  b.mode(Mode::NONE);
  b.cycle(50);
  EXPECT_EQ(b.out.state, State::OPERATIONAL) << "a key switch breaks before it makes";
  EXPECT_EQ(b.out.mode, Mode::AUTO);
  EXPECT_EQ(b.out.mode_requested, Mode::NONE);
  b.cycle();
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.mode, Mode::NONE);
  EXPECT_TRUE(b.alarm(AlarmId::MODE_SELECTOR_INVALID));
  EXPECT_TRUE(b.alarm(AlarmId::MODE_CHANGED));
}

// ================================================================ rule 7
// @req TR-C7 ST-CAT2
TEST(Rule7, JogKeepAliveOlderThanTheTimeoutIsCat2ToManualIdle) {
  Bench b;
  b.to_jogging(Mode::T1);  // jog accepted at cycle J
  b.cycle(99);             // J+99: keep-alive 99 cycles old
  EXPECT_EQ(b.out.sub, Sub::MANUAL_JOGGING);
  b.cycle();  // J+100: exactly 100 ms is not older than 100 ms
  EXPECT_EQ(b.out.sub, Sub::MANUAL_JOGGING);
  b.cycle();  // J+101
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.stop, StopCat::CAT2);
  EXPECT_TRUE(b.alarm(AlarmId::JOG_LINK_LOST));
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.sub, Sub::MANUAL_IDLE);
  EXPECT_TRUE(b.out.drives_enable) << "Cat 2 keeps the drives holding";
}

// @req TR-JOG-KEEPALIVE
TEST(Rule7, KeepAliveKeepsTheJogGoing) {
  Bench b;
  b.to_jogging(Mode::T1);
  for (int k = 0; k < 20; ++k) {
    b.cycle(60);
    ASSERT_EQ(b.jog(1, +1, 50), Result::OK);
  }
  EXPECT_EQ(b.out.sub, Sub::MANUAL_JOGGING);
}

// ================================================================ E-stop rows
// @req TR-ESTOP-RELEASED
TEST(EstopActive, ReleasedOnBothChannelsGoesToResetNeeded) {
  Bench b;
  b.to_idle();
  b.estop(true);
  b.cycle(10);
  b.raw.estop_a = true;  // one channel back: still active
  b.cycle(5);
  EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE);
  b.raw.estop_b = true;
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED);
  EXPECT_TRUE(b.out.reset_lamp);
  b.cycle(500);
  EXPECT_EQ(b.out.state, State::ESTOP_RESET_NEEDED) << "release alone never restarts";
}

// @req TR-RESET-ESTOP
TEST(EstopResetNeeded, ResetGoesToIdle) {
  Bench b;
  b.boot();
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_FALSE(b.out.reset_lamp);
}

// ================================================================ IDLE rows
// @req TR-RESET-IDLE AL-LIFETIME
TEST(Idle, ResetClearsLatchedAlarmsWhenTheirCauseIsGone) {
  Bench b;
  b.to_auto_running();
  b.gate(true);
  b.cycle();
  ASSERT_GT(b.finish_stop(), 0);
  ASSERT_TRUE(b.alarm(AlarmId::PROTECTIVE_STOP));
  EXPECT_EQ(b.command(CommandId::reset), Result::FAULT_PRESENT) << "guard still open";
  EXPECT_TRUE(b.alarm(AlarmId::PROTECTIVE_STOP));
  b.gate(false);
  b.cycle();
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
  EXPECT_FALSE(b.alarm(AlarmId::PROTECTIVE_STOP));
  EXPECT_FALSE(b.out.reset_lamp);
}

// @req TR-RESET-IDLE RES-SAME-CYCLE
TEST(Idle, ResetAcknowledgesDriveFaultsAndAnswersWhenTheyReply) {
  Bench b;
  b.to_auto_running();
  b.plant.drive_fault[0] = true;
  b.cycle(3);
  ASSERT_EQ(b.out.state, State::IDLE);
  b.plant.drive_fault[0] = false;  // cause gone; the drive still shows Fault until reset
  b.cycle(3);
  ASSERT_TRUE(b.alarm(AlarmId::DRIVE_FAULT));
  const Command c = b.make(CommandId::reset);
  b.send(c);
  b.cycle();
  EXPECT_TRUE(b.out.motion.fault_reset) << "the drives get a fault reset";
  const auto answered = [&] {
    for (const Reply& r : b.replies) {
      if (r.seq == c.seq) return true;
    }
    return false;
  };
  EXPECT_FALSE(answered()) << "the answer waits for the drives";
  ASSERT_GT(b.until([&](const SupervisorOut&) { return answered(); }, 50), 0);
  EXPECT_EQ(b.replies.back().result, Result::OK);
  EXPECT_FALSE(b.alarm(AlarmId::DRIVE_FAULT));
}

// @req TR-RESET-IDLE RES-SAME-CYCLE
TEST(Idle, ResetWithADriveStillFaultedAnswersFaultPresentWithin50Cycles) {
  Bench b;
  b.to_auto_running();
  b.plant.drive_fault[5] = true;  // cause stays
  b.cycle(3);
  const Command c = b.make(CommandId::reset);
  b.send(c);
  b.cycle(50);  // cycles T..T+49: still waiting for the drives
  EXPECT_TRUE(b.replies.empty() || b.replies.back().seq != c.seq);
  b.cycle();  // cycle T+50: the answer, at the latest (SPEC §5)
  ASSERT_FALSE(b.replies.empty());
  EXPECT_EQ(b.replies.back().seq, c.seq);
  EXPECT_EQ(b.replies.back().result, Result::FAULT_PRESENT);
  EXPECT_TRUE(b.alarm(AlarmId::DRIVE_FAULT));
}

// @req TR-SERVO-ON
TEST(Idle, ServoOnStartsArming) {
  Bench b;
  b.to_idle();
  EXPECT_EQ(b.command(CommandId::servo_on), Result::OK);
  EXPECT_EQ(b.out.state, State::ARMING);
  EXPECT_EQ(b.out.arming_step, ArmingStep::CONTACTOR);
  EXPECT_TRUE(b.out.contactor);
  EXPECT_FALSE(b.out.drives_enable);
  EXPECT_FALSE(b.out.brakes_release);
}

// ================================================================ ARMING rows
// @req TR-ARMING-DONE ST-OUTPUTS
TEST(Arming, StepsInOrderToAutoIdle) {
  Bench b;
  b.to_idle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return o.arming_step == ArmingStep::DRIVES; }, 100), 0);
  EXPECT_TRUE(b.out.drives_enable);
  EXPECT_FALSE(b.out.brakes_release);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return o.arming_step == ArmingStep::BRAKES; }, 500), 0);
  EXPECT_TRUE(b.out.brakes_release);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return o.state != State::ARMING; }, 300), 0);
  EXPECT_EQ(b.out.state, State::OPERATIONAL);
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE);
  EXPECT_EQ(b.out.motion.mode, MotionMode::Hold);
}

// @req TR-ARMING-DONE
TEST(Arming, InT1EndsInManualIdle) {
  Bench b;
  b.to_operational(Mode::T1);
  EXPECT_EQ(b.out.sub, Sub::MANUAL_IDLE);
}

// @req TR-ARMING-TIMEOUT
TEST(Arming, ContactorTimeoutAtTheFirstCycleBeyond100ms) {
  Bench b;
  b.plant.contactor_stuck_open = true;
  b.to_idle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);  // entered at cycle S
  b.cycle(100);                                           // S+100: not yet
  EXPECT_EQ(b.out.state, State::ARMING);
  b.cycle();  // S+101
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_TRUE(b.alarm(AlarmId::ARMING_TIMEOUT));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::ARMING_TIMEOUT).step, ArmingStep::CONTACTOR);
  EXPECT_TRUE(b.ssm().alarms().detail(AlarmId::ARMING_TIMEOUT).has_step);
}

// @req TR-ARMING-TIMEOUT AL-CAUSE
TEST(Arming, DrivesTimeoutNamesTheStep) {
  Bench b;
  b.to_idle();
  b.plant.boot_cycles = 1000000;  // drives stop walking the state machine
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return o.state != State::ARMING; }, 1000), 0);
  EXPECT_TRUE(b.alarm(AlarmId::ARMING_TIMEOUT));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::ARMING_TIMEOUT).step, ArmingStep::DRIVES);
}

// @req TR-ARMING-TIMEOUT
TEST(Arming, BrakeStuckTimesOutInStepBrakes) {
  Bench b;
  b.plant.brake_stuck[3] = true;
  b.to_idle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return o.arming_step == ArmingStep::BRAKES; }, 500), 0);
  b.cycle(300);
  EXPECT_EQ(b.out.state, State::ARMING);
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::ARMING_TIMEOUT).step, ArmingStep::BRAKES);
}

// @req TR-SERVO-OFF-ARMING
TEST(Arming, ServoOffGoesToIdleAtOnce) {
  Bench b;
  b.to_idle();
  ASSERT_EQ(b.command(CommandId::servo_on), Result::OK);
  b.cycle(20);
  EXPECT_EQ(b.command(CommandId::servo_off), Result::OK);
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(all_outputs_safe(b.out));
}

// ================================================================ OPERATIONAL rows
// @req TR-SERVO-OFF ST-CAT1
TEST(Operational, ServoOffIsCat1ToIdle) {
  Bench b;
  b.to_auto_running();
  EXPECT_EQ(b.command(CommandId::servo_off), Result::OK);
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.stop, StopCat::CAT1);
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(all_outputs_safe(b.out));
  EXPECT_FALSE(b.out.reset_lamp);
}

// @req ST-CAT1
TEST(Operational, Cat1CutsPowerAfterTheBrakeTimeEvenIfTheFeedbackStaysReleased) {
  Bench b;
  b.to_auto_running();
  b.plant.vel.fill(0.0F);
  b.plant.brake_stuck_released = true;
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return !o.brakes_release; }, 100), 0);
  b.cycle(300);
  EXPECT_EQ(b.out.state, State::STOPPING) << "waits brakes_timeout for the brake feedback";
  EXPECT_TRUE(b.out.drives_enable) << "the drives hold the axis until the timeout";
  b.cycle();
  EXPECT_EQ(b.out.state, State::IDLE);
  // SPEC §7: BRAKE_NOT_ENGAGED (rule 3, latched) names the axis; power is cut at once.
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_TRUE(all_outputs_safe(b.out));
  ASSERT_TRUE(b.alarm(AlarmId::BRAKE_NOT_ENGAGED));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::BRAKE_NOT_ENGAGED).axis, 1U);
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::BRAKE_NOT_ENGAGED).signal, Signal::brake);
  EXPECT_EQ(b.command(CommandId::reset), Result::FAULT_PRESENT) << "the brake still does not hold";
}

TEST(Operational, Cat1CutsPowerAfterTheBrakeTimeWhileTheBrakeFeedbacksChatter) {
  // Two brake feedbacks alternate: never all engaged, neither released long enough for
  // BRAKE_NOT_ENGAGED. The brake phase still ends at brakes_timeout: power is removed.
  Bench b;
  b.to_auto_running();
  b.plant.vel.fill(0.0F);
  b.plant.brake_welded_released[0] = true;  // brake 1's feedback stays released when engaging begins
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return !o.brakes_release; }, 100), 0);
  int k = 0;
  for (; k < 400 && b.out.state == State::STOPPING; ++k) {
    b.plant.brake_welded_released[0] = (k % 2) != 0;
    b.plant.brake_welded_released[1] = (k % 2) == 0;
    b.cycle();
    if (b.out.state == State::STOPPING) {
      ASSERT_TRUE(b.out.drives_enable) << "the drives hold the axes until the brake time is over, cycle " << k;
    }
  }
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_GE(k, static_cast<int>(b.timing().brakes_timeout)) << "not before the brake time";
  EXPECT_LE(k, static_cast<int>(b.timing().brakes_timeout) + 2);
  EXPECT_TRUE(all_outputs_safe(b.out));
}

// SPEC §7: "A brake commanded engaged whose feedback still says released 300 ms later is
// BRAKE_NOT_ENGAGED". Found by the MC/DC work (issue 25): counting only consecutive released
// cycles, two chattering feedbacks (never all engaged) ended the stop silently and servo_on
// was accepted at once. A brake now counts as engaged only after kBrakeConfirmMs of engaged
// feedback without a break.
// @req AL-FEEDBACK TR-C3
TEST(FeedbackMonitoring, BrakesNeverAllEngagedByTheBrakeTimeRaiseBrakeNotEngaged) {
  Bench b;
  b.to_auto_running();
  b.plant.vel.fill(0.0F);
  b.plant.brake_welded_released[0] = true;
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return !o.brakes_release; }, 100), 0);
  for (int k = 0; k < 400 && b.out.state == State::STOPPING; ++k) {
    b.plant.brake_welded_released[0] = (k % 2) != 0;
    b.plant.brake_welded_released[1] = (k % 2) == 0;
    b.cycle();
  }
  ASSERT_EQ(b.out.state, State::IDLE);
  EXPECT_TRUE(b.alarm(AlarmId::BRAKE_NOT_ENGAGED)) << "a brake said released when the brake time ran out";
  EXPECT_EQ(b.command(CommandId::servo_on), Result::RESET_REQUIRED);
}

// A contact that bounces shorter than the confirmation time while engaging, then holds:
// the brake engaged in time, no alarm.
// @req AL-FEEDBACK TR-C3
TEST(FeedbackMonitoring, BrakeThatBouncesThenHoldsWithinTheBrakeTimeRaisesNothing) {
  Bench b;
  b.to_auto_running();
  b.plant.vel.fill(0.0F);
  b.plant.brake_welded_released[2] = true;
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return !o.brakes_release; }, 100), 0);
  const auto confirm = static_cast<int>(b.timing().brake_confirm);
  const int settle = static_cast<int>(b.timing().brakes_timeout) - confirm - 5;
  for (int k = 0; k < 400 && b.out.state == State::STOPPING; ++k) {
    // bounces (released every third cycle) until `settle`, then engaged for good
    b.plant.brake_welded_released[2] = (k < settle) && (k % 3 == 0);
    b.cycle();
  }
  ASSERT_EQ(b.out.state, State::IDLE);
  EXPECT_FALSE(b.alarm(AlarmId::BRAKE_NOT_ENGAGED));
}

// Released and engaged in runs just shorter than the confirmation time: never engaged.
// @req AL-FEEDBACK TR-C3
TEST(FeedbackMonitoring, BrakeEngagedInRunsShorterThanTheConfirmationIsNotEngaged) {
  Bench b;
  b.to_idle();
  const auto confirm = static_cast<int>(b.timing().brake_confirm);
  const auto timeout = static_cast<int>(b.timing().brakes_timeout);
  int raised_at = -1;
  for (int k = 0; k < timeout + 3 * confirm && raised_at < 0; ++k) {
    b.plant.brake_welded_released[4] = (k % confirm) == 0;  // engaged runs of confirm - 1
    b.cycle();
    if (b.alarm(AlarmId::BRAKE_NOT_ENGAGED)) {
      raised_at = k;
    }
  }
  ASSERT_GE(raised_at, timeout) << "not before the brake time";
  EXPECT_LE(raised_at, timeout + confirm);
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::BRAKE_NOT_ENGAGED).axis, 5U);
}

// @req AL-FEEDBACK TR-C1
TEST(FeedbackMonitoring, WeldedContactorLocksOutFromAnyState) {
  Bench b;
  b.to_idle();
  b.plant.contactor_welded = true;  // feedback closed from the next cycle on
  b.cycle(101);
  EXPECT_EQ(b.out.state, State::IDLE) << "100 ms of a contradicting feedback are tolerated";
  b.cycle();
  EXPECT_EQ(b.out.state, State::ERROR_LOCKOUT);
  EXPECT_TRUE(b.alarm(AlarmId::CONTACTOR_WELDED));
  EXPECT_EQ(b.out.stop, StopCat::CAT0);
  EXPECT_EQ(b.command(CommandId::reset), Result::LOCKED_OUT);
}

// @req AL-FEEDBACK TR-C3
TEST(FeedbackMonitoring, BrakeNotEngagedIsLatchedInIdleToo) {
  Bench b;
  b.to_idle();
  b.plant.brake_welded_released[3] = true;  // axis 4, feedback released from the next cycle on
  b.cycle(301);
  EXPECT_FALSE(b.alarm(AlarmId::BRAKE_NOT_ENGAGED));
  b.cycle();
  ASSERT_TRUE(b.alarm(AlarmId::BRAKE_NOT_ENGAGED));
  EXPECT_EQ(b.ssm().alarms().detail(AlarmId::BRAKE_NOT_ENGAGED).axis, 4U);
  EXPECT_TRUE(b.out.reset_lamp);
  EXPECT_EQ(b.command(CommandId::servo_on), Result::RESET_REQUIRED);
  EXPECT_EQ(b.command(CommandId::reset), Result::FAULT_PRESENT);
  b.plant.brake_welded_released[3] = false;
  b.cycle();
  EXPECT_EQ(b.command(CommandId::reset), Result::OK);
  EXPECT_FALSE(b.alarm(AlarmId::BRAKE_NOT_ENGAGED));
}

// @req CYC-MAX-COMMANDS RES-ONE
TEST(OneResult, EveryTransitionOfACycleIsReported) {
  Bench b;
  b.to_idle();
  for (int i = 0; i < 4; ++i) {
    b.send(CommandId::servo_on);
    b.send(CommandId::servo_off);
  }
  b.cycle();
  EXPECT_EQ(b.out.transition_count, 8U) << "IDLE->ARMING->IDLE four times in one cycle";
  EXPECT_EQ(b.out.state, State::IDLE);
}

// @req ST-CAT1 ST-OUTPUTS
TEST(Operational, Cat1EngagesBrakesAtStandstillBeforeCuttingPower) {
  Bench b;
  b.to_auto_running();
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return !o.brakes_release; }, 500), 0);
  EXPECT_EQ(b.out.state, State::STOPPING) << "brakes engage while the drives still hold";
  EXPECT_TRUE(b.out.drives_enable);
  EXPECT_TRUE(b.out.contactor);
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.state, State::IDLE);
}

// @req TR-START-AUTO
TEST(AutoIdle, StartRunsTheProgram) {
  Bench b;
  b.to_operational();
  EXPECT_EQ(b.command(CommandId::start), Result::OK);
  EXPECT_EQ(b.out.sub, Sub::AUTO_RUNNING);
  EXPECT_EQ(b.out.motion.mode, MotionMode::Program);
  EXPECT_EQ(b.out.motion.program, ProgramCmd::Start);
}

// @req TR-PAUSE-AUTO ST-CAT2
TEST(AutoRunning, PauseIsCat2ToAutoPaused) {
  Bench b;
  b.to_auto_running();
  EXPECT_EQ(b.command(CommandId::pause), Result::OK);
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.stop, StopCat::CAT2);
  EXPECT_NE(b.out.motion.program, ProgramCmd::Abort) << "a pause keeps the program";
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.sub, Sub::AUTO_PAUSED);
  EXPECT_TRUE(b.out.drives_enable);
  EXPECT_TRUE(b.out.brakes_release);
}

// @req TR-STOP-RUNNING
TEST(AutoRunning, StopIsCat2ToAutoIdle) {
  Bench b;
  b.to_auto_running();
  EXPECT_EQ(b.command(CommandId::stop), Result::OK);
  EXPECT_EQ(b.out.stop, StopCat::CAT2);
  EXPECT_EQ(b.out.motion.program, ProgramCmd::Abort);
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE);
}

// @req TR-STOP-PAUSED
TEST(AutoPaused, StopGoesToAutoIdleAtOnce) {
  Bench b;
  b.to_auto_running();
  ASSERT_EQ(b.command(CommandId::pause), Result::OK);
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.command(CommandId::stop), Result::OK);
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE);
  EXPECT_EQ(b.out.motion.program, ProgramCmd::Abort);
}

// @req TR-RESUME
TEST(AutoPaused, ResumeReturnsToAutoRunning) {
  Bench b;
  b.to_auto_running();
  ASSERT_EQ(b.command(CommandId::pause), Result::OK);
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.command(CommandId::resume), Result::OK);
  EXPECT_EQ(b.out.sub, Sub::AUTO_RUNNING);
  EXPECT_EQ(b.out.motion.program, ProgramCmd::Resume);
}

// @req TR-FINISHED-AUTO
TEST(AutoRunning, ProgramFinishedGoesToAutoIdle) {
  Bench b;
  b.to_auto_running();
  b.plant.program_finished = true;
  b.cycle();
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE);
}

// @req TR-JOG
TEST(ManualIdle, JogStartsJogging) {
  Bench b;
  b.to_operational(Mode::T1);
  EXPECT_EQ(b.jog(3, -1, 25), Result::OK);
  EXPECT_EQ(b.out.sub, Sub::MANUAL_JOGGING);
  EXPECT_EQ(b.out.motion.mode, MotionMode::Jog);
  EXPECT_EQ(b.out.motion.jog.axis, 3U);
  EXPECT_EQ(b.out.motion.jog.dir, -1);
  EXPECT_EQ(b.out.motion.jog.speed, 25U);
  EXPECT_TRUE(b.out.motion.t1_limit);
}

// @req TR-JOG-STOP
TEST(ManualJogging, JogStopIsCat2ToManualIdle) {
  Bench b;
  b.to_jogging(Mode::T1);
  EXPECT_EQ(b.command(CommandId::jog_stop), Result::OK);
  EXPECT_EQ(b.out.stop, StopCat::CAT2);
  ASSERT_GT(b.finish_stop(), 0);
  EXPECT_EQ(b.out.sub, Sub::MANUAL_IDLE);
}

// @req TR-START-MANUAL
TEST(ManualIdle, StartRunsTheProgramInManual) {
  Bench b;
  b.to_operational(Mode::T1);
  EXPECT_EQ(b.command(CommandId::start), Result::OK);
  EXPECT_EQ(b.out.sub, Sub::MANUAL_RUNNING);
  EXPECT_EQ(b.out.motion.program, ProgramCmd::Start);
}

// @req TR-PAUSE-MANUAL TR-STOP-MANUAL TR-FINISHED-MANUAL
TEST(ManualRunning, PauseStopAndFinishAreCat2ToManualIdle) {
  for (int how = 0; how < 3; ++how) {
    Bench b;
    b.to_operational(Mode::T1);
    ASSERT_EQ(b.command(CommandId::start), Result::OK);
    if (how == 0) {
      EXPECT_EQ(b.command(CommandId::pause), Result::OK);
    } else if (how == 1) {
      EXPECT_EQ(b.command(CommandId::stop), Result::OK);
    } else {
      b.plant.program_finished = true;
      b.cycle();
    }
    EXPECT_EQ(b.out.state, State::STOPPING) << how;
    EXPECT_EQ(b.out.stop, StopCat::CAT2) << how;
    ASSERT_GT(b.finish_stop(), 0);
    EXPECT_EQ(b.out.sub, Sub::MANUAL_IDLE) << how;
  }
}

// @req TR-STANDSTILL ST-STANDSTILL
TEST(Stopping, StandstillNeedsTenConsecutiveQuietCycles) {
  Bench b;
  b.to_auto_running();
  b.plant.vel.fill(0.02F);  // just above standstill_rad_s; the bench ramp zeroes it next cycle
  ASSERT_EQ(b.command(CommandId::stop), Result::OK);
  ASSERT_EQ(b.out.state, State::STOPPING);
  b.cycle(9);
  EXPECT_EQ(b.out.state, State::STOPPING) << "9 quiet cycles are not standstill";
  b.cycle();
  EXPECT_EQ(b.out.state, State::OPERATIONAL) << "the 10th quiet cycle is";
  EXPECT_EQ(b.out.sub, Sub::AUTO_IDLE);
}

// @req TR-STANDSTILL
TEST(Stopping, AxisAlreadyAtRestStopsAtOnce) {
  Bench b;
  b.to_auto_running();
  b.plant.vel.fill(0.0F);
  b.cycle(10);
  ASSERT_EQ(b.command(CommandId::stop), Result::OK);
  EXPECT_EQ(b.finish_stop(), 1) << "standstill counts from before the stop";
}

// @req TR-CONFIRM-T2
TEST(ConfirmT2, ConfirmsUntilTheModeChanges) {
  Bench b;
  b.mode(Mode::T2);
  b.to_idle();
  b.enable_released();
  b.cycle();
  b.enable_centre();
  b.cycle();
  EXPECT_EQ(b.command(CommandId::servo_on), Result::T2_NOT_CONFIRMED);
  EXPECT_EQ(b.command(CommandId::confirm_t2), Result::OK);
  EXPECT_TRUE(b.out.t2_confirmed);
  b.mode(Mode::T1);
  b.cycle();
  b.mode(Mode::T2);
  b.cycle();
  EXPECT_FALSE(b.out.t2_confirmed);
}

// @req ST-STATUS
TEST(Status, SubOnlyInOperationalAndCat0OnlyForTheCycleItHappened) {
  Bench b;
  b.to_idle();
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_EQ(b.out.sub, Sub::NONE);
  EXPECT_EQ(b.out.stop, StopCat::NONE);
  EXPECT_EQ(b.out.mode, Mode::AUTO);
  b.to_auto_running();
  EXPECT_EQ(b.out.state, State::OPERATIONAL);
  EXPECT_EQ(b.out.sub, Sub::AUTO_RUNNING);
  ASSERT_EQ(b.command(CommandId::pause), Result::OK);
  EXPECT_EQ(b.out.state, State::STOPPING);
  EXPECT_EQ(b.out.sub, Sub::NONE);
  EXPECT_EQ(b.out.stop, StopCat::CAT2) << "the category of the stop in progress";
  b.finish_stop();
  EXPECT_EQ(b.out.sub, Sub::AUTO_PAUSED);
  EXPECT_EQ(b.out.stop, StopCat::NONE);
  b.estop(true);
  b.cycle();
  EXPECT_EQ(b.out.stop, StopCat::CAT0) << "shown in the cycle it happened";
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE);
  EXPECT_EQ(b.out.stop, StopCat::NONE) << "not while its cause lasts";
}

// @req CYC-ORDER
TEST(CycleOrder, ConditionsOfACycleComeBeforeItsCommands) {
  // The E-stop read in a cycle decides before the commands taken in that cycle: a servo_on
  // queued in the same cycle meets ESTOP_ACTIVE, not IDLE.
  Bench b;
  b.to_idle();
  b.send(CommandId::servo_on);
  b.estop(true);
  b.cycle();
  EXPECT_EQ(b.out.state, State::ESTOP_ACTIVE);
  ASSERT_FALSE(b.replies.empty());
  EXPECT_EQ(b.replies.back().result, Result::ESTOP_ACTIVE);
  // And the commands of one cycle in arrival order: reset first makes servo_on possible.
  Bench c;
  c.boot();
  c.send(CommandId::reset);
  c.send(CommandId::servo_on);
  c.cycle();
  ASSERT_GE(c.replies.size(), 2U);
  EXPECT_EQ(c.replies[c.replies.size() - 2].result, Result::OK);
  EXPECT_EQ(c.replies.back().result, Result::OK);
  EXPECT_EQ(c.out.state, State::ARMING);
}

// The Cat 1 stop's brake phase has a bound of its own, the brake time: two brake feedbacks
// that chatter in antiphase, each engaged for longer than the confirmation time in turn,
// never read all engaged in one cycle and never let a brake read released for the brake
// time after its last confirmed engagement (no BRAKE_NOT_ENGAGED). The stop still ends when
// the brake time is over: power removed, IDLE (SPEC §3: "at standstill engages brakes,
// disables drives, opens the contactor and ends in IDLE"). (The only case where the stop's
// own bound, not the feedback monitor, ends the brake phase: MC/DC of stopping.cpp.)
// @req ST-CAT1 AL-FEEDBACK
TEST(FeedbackMonitoring, BrakesChatteringInTurnEndTheCat1StopOnTheBrakeTime) {
  Bench b;
  b.to_auto_running();
  b.plant.vel.fill(0.0F);
  b.plant.brake_welded_released[0] = true;  // brake 1's feedback released when engaging begins
  ASSERT_EQ(b.command(CommandId::servo_off), Result::OK);
  ASSERT_GT(b.until([](const SupervisorOut& o) { return !o.brakes_release; }, 100), 0);
  const int run = static_cast<int>(b.timing().brake_confirm) + 2;  // each brake engaged for longer
  int k = 0;
  bool all_engaged = false;
  for (; k < 600 && b.out.state == State::STOPPING; ++k) {
    const bool first = (k / run) % 2 == 0;
    b.plant.brake_welded_released[0] = first;
    b.plant.brake_welded_released[1] = !first;
    b.cycle();
    all_engaged = all_engaged || std::none_of(b.fb.brake_released.begin(), b.fb.brake_released.end(), [](bool r) { return r; });
    if (b.out.state == State::STOPPING) {
      ASSERT_TRUE(b.out.drives_enable) << "the drives hold until the brake time is over, cycle " << k;
    }
  }
  EXPECT_FALSE(all_engaged) << "the test means brakes that never read all engaged";
  EXPECT_EQ(b.out.state, State::IDLE);
  EXPECT_GE(k, static_cast<int>(b.timing().brakes_timeout)) << "not before the brake time";
  EXPECT_LE(k, static_cast<int>(b.timing().brakes_timeout) + 2);
  EXPECT_TRUE(all_outputs_safe(b.out));
  EXPECT_FALSE(b.alarm(AlarmId::BRAKE_NOT_ENGAGED)) << "each brake was confirmed engaged within the brake time";
}

// SPEC §4 rule 1, "internal integrity check failed": the supervisor reads the safety outputs
// it is about to write a second time, against the state (outputs_consistent). Each
// contradiction it is there for is refused, taken from real outputs of the states with one
// field corrupted: power of any one output outside the powered states, power with the E-stop
// pressed, a jog outside MANUAL_JOGGING, a program outside the running states, state data of
// another state; the real outputs pass.
// @req TR-C1 ST-OUTPUTS
TEST(Rule1, TheOutputCrossCheckRefusesEachContradiction) {
  Bench b;
  b.to_idle();
  const auto consistent = [&b](const SupervisorOut& o, bool estop = false) {
    return outputs_consistent(o, b.ssm().leaf(), b.ssm().variant(), estop);
  };
  // IDLE: nothing powered; any one output energised is a contradiction.
  ASSERT_TRUE(consistent(b.out));
  for (int k = 0; k < 3; ++k) {
    SupervisorOut o = b.out;
    (k == 0 ? o.contactor : (k == 1 ? o.drives_enable : o.brakes_release)) = true;
    EXPECT_FALSE(consistent(o)) << "output " << k << " energised in IDLE";
  }
  EXPECT_TRUE(consistent(b.out, true)) << "E-stop pressed with nothing powered";
  SupervisorOut jog = b.out;
  jog.motion.mode = MotionMode::Jog;
  EXPECT_FALSE(consistent(jog)) << "a jog in IDLE";
  // OPERATIONAL, AUTO_IDLE: powered, consistent; with the E-stop pressed, not.
  b.to_operational(Mode::AUTO);
  ASSERT_EQ(b.out.sub, Sub::AUTO_IDLE);
  EXPECT_TRUE(consistent(b.out));
  EXPECT_FALSE(consistent(b.out, true)) << "power with the E-stop pressed";
  SupervisorOut prog = b.out;
  prog.motion.mode = MotionMode::Program;
  EXPECT_FALSE(consistent(prog)) << "a program in AUTO_IDLE";
  EXPECT_FALSE(outputs_consistent(b.out, Leaf::AUTO_IDLE, StateVariant{StIdle{}}, false)) << "state data of IDLE";
  // AUTO_RUNNING: its program is consistent, a jog is not.
  ASSERT_EQ(b.command(CommandId::start), Result::OK);
  ASSERT_EQ(b.out.sub, Sub::AUTO_RUNNING);
  ASSERT_EQ(b.out.motion.mode, MotionMode::Program);
  EXPECT_TRUE(consistent(b.out));
  jog = b.out;
  jog.motion.mode = MotionMode::Jog;
  EXPECT_FALSE(consistent(jog)) << "a jog in AUTO_RUNNING";
  // T1: MANUAL_JOGGING's jog and MANUAL_RUNNING's program are consistent.
  Bench m;
  m.to_jogging(Mode::T1);
  ASSERT_EQ(m.out.motion.mode, MotionMode::Jog);
  EXPECT_TRUE(outputs_consistent(m.out, m.ssm().leaf(), m.ssm().variant(), false));
  Bench r;
  r.to_operational(Mode::T1);
  ASSERT_EQ(r.command(CommandId::start), Result::OK);
  ASSERT_EQ(r.out.sub, Sub::MANUAL_RUNNING);
  ASSERT_EQ(r.out.motion.mode, MotionMode::Program);
  EXPECT_TRUE(outputs_consistent(r.out, r.ssm().leaf(), r.ssm().variant(), false));
}

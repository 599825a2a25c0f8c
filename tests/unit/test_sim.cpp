// The simulated cell with the real controller: timings of SPEC §6, the demo program,
// T1 limiting by the motion layer, and each injected fault.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "safestate/core/cia402.hpp"
#include "safestate/motion/motion_controller.hpp"
#include "safestate/sim/cell.hpp"

using namespace safestate;
using core::CommandId;
using core::Result;
using core::State;
using core::Sub;

namespace {

struct CellRun {
  sim::Cell cell{core::Config{}};
  std::uint32_t seq = 0;

  void cycles(int n) {
    for (int i = 0; i < n; ++i) cell.step();
  }
  template <typename P>
  int until(P pred, int limit) {
    for (int k = 1; k <= limit; ++k) {
      cell.step();
      if (pred(cell)) return k;
    }
    return -1;
  }
  Result cmd(CommandId id, int axis = 0, int dir = 0, int speed = 0) {
    core::Command c{};
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    c.axis = static_cast<std::int8_t>(axis);
    c.dir = static_cast<std::int8_t>(dir);
    c.speed = static_cast<std::uint8_t>(speed);
    EXPECT_EQ(cell.submit(c), Result::OK);
    cell.step();
    const core::SupervisorOut& o = cell.out();
    for (std::size_t i = 0; i < o.reply_count; ++i) {
      if (o.replies[i].seq == c.seq) return o.replies[i].result;
    }
    return Result::QUEUE_FULL;
  }
  void arm(core::Mode m = core::Mode::AUTO) {
    auto& in = cell.inputs();
    in.mode_auto = m == core::Mode::AUTO;
    in.mode_t1 = m == core::Mode::T1;
    in.mode_t2 = m == core::Mode::T2;
    ASSERT_GT(until([](const sim::Cell& c) { return c.out().state == State::ESTOP_RESET_NEEDED; }, 100), 0);
    ASSERT_EQ(cmd(CommandId::reset), Result::OK);
    if (m != core::Mode::AUTO) {
      in.enable_a = in.enable_b = true;
      cycles(1);
    }
    ASSERT_EQ(cmd(CommandId::servo_on), Result::OK);
    ASSERT_GT(until([](const sim::Cell& c) { return c.out().state == State::OPERATIONAL; }, 700), 0);
  }
  State state() const { return cell.out().state; }
};

}  // namespace

// @req SIM-CELL
TEST(SimCell, BootEndsWithin100Cycles) {
  CellRun r;
  const int k = r.until([](const sim::Cell& c) { return c.out().state != State::BOOT; }, 100);
  EXPECT_GT(k, 0);
  EXPECT_EQ(r.state(), State::ESTOP_RESET_NEEDED);
}

// @req SIM-CELL
TEST(SimCell, ContactorFeedbackTenCyclesAfterTheCommand) {
  CellRun r;
  r.cycles(100);
  ASSERT_EQ(r.cmd(CommandId::reset), Result::OK);
  ASSERT_EQ(r.cmd(CommandId::servo_on), Result::OK);  // contactor commanded in this cycle
  int k = r.until([](const sim::Cell& c) { return c.view().contactor_closed; }, 50);
  EXPECT_EQ(k, 10);
}

// @req SIM-CELL
TEST(SimCell, ArmingWalksTheDrivesAndReleasesTheBrakes) {
  CellRun r;
  r.arm();
  EXPECT_EQ(r.cell.out().sub, Sub::AUTO_IDLE);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(core::cia402::decode(r.cell.view().statusword[i]), core::cia402::DriveState::OperationEnabled);
    EXPECT_TRUE(r.cell.view().brake_released[i]);
    EXPECT_STREQ(r.cell.view().axis_state[i], "Standstill");
  }
  EXPECT_LT(r.cell.view().tcp_speed_mm_s, 0.01F) << "no surprise motion after arming";
}

// @req SIM-PROGRAM
TEST(SimCell, DemoProgramLastsFiveToTenSecondsAndFinishes) {
  CellRun r;
  r.arm();
  ASSERT_EQ(r.cmd(CommandId::start), Result::OK);
  float top = 0.0F;
  const int k = r.until(
      [&](const sim::Cell& c) {
        top = std::max(top, c.view().tcp_speed_mm_s);
        return c.out().sub == Sub::AUTO_IDLE;
      },
      12000);
  EXPECT_GE(k, 5000);
  EXPECT_LE(k, 10000);
  EXPECT_GT(top, 300.0F) << "AUTO runs at full speed";
  EXPECT_EQ(r.state(), State::OPERATIONAL);
}

// @req MO-T1-LIMIT
TEST(SimCell, T1JogIsCappedBelow250mmPerSecond) {
  CellRun r;
  r.arm(core::Mode::T1);
  float top = 0.0F;
  for (int k = 0; k < 20; ++k) {
    ASSERT_EQ(r.cmd(CommandId::jog, 1, +1, 100), Result::OK);
    for (int i = 0; i < 40; ++i) {
      r.cell.step();
      top = std::max(top, r.cell.view().max_point_speed_mm_s);
    }
  }
  EXPECT_EQ(r.cell.out().sub, Sub::MANUAL_JOGGING);
  EXPECT_GT(top, 200.0F) << "the jog does move";
  EXPECT_LE(top, 250.0F);
  EXPECT_STREQ(r.cell.view().axis_state[0], "ContinuousMotion");
}

// @req MO-T1-LIMIT
TEST(SimCell, T1ProgramIsTimeScaledBelow250) {
  CellRun r;
  r.arm(core::Mode::T1);
  ASSERT_EQ(r.cmd(CommandId::start), Result::OK);
  float top = 0.0F;
  for (int i = 0; i < 3000; ++i) {
    r.cell.step();
    top = std::max(top, r.cell.view().max_point_speed_mm_s);
  }
  EXPECT_EQ(r.cell.out().sub, Sub::MANUAL_RUNNING);
  EXPECT_LE(top, 250.0F);
  EXPECT_GT(top, 150.0F);
}

// @req CIA-NO-REENABLE
TEST(SimCell, DriveFaultStopsAndResetAcknowledgesIt) {
  CellRun r;
  r.arm();
  ASSERT_EQ(r.cmd(CommandId::start), Result::OK);
  r.cycles(300);
  r.cell.inject({sim::FaultKind::drive_fault, 2});
  r.cycles(1);
  EXPECT_EQ(r.state(), State::IDLE);
  EXPECT_EQ(r.cmd(CommandId::reset), Result::QUEUE_FULL) << "answer deferred: no reply in this cycle";
  r.cycles(60);
  r.cell.inject({sim::FaultKind::drive_clear, 2});
  core::Command c{};
  c.seq = 999;
  c.id = static_cast<std::uint8_t>(CommandId::reset);
  ASSERT_EQ(r.cell.submit(c), Result::OK);
  Result got = Result::QUEUE_FULL;
  for (int i = 0; i < 60 && got == Result::QUEUE_FULL; ++i) {
    r.cell.step();
    for (std::size_t k = 0; k < r.cell.out().reply_count; ++k) {
      if (r.cell.out().replies[k].seq == 999) got = r.cell.out().replies[k].result;
    }
  }
  EXPECT_EQ(got, Result::OK);
  EXPECT_EQ(core::cia402::decode(r.cell.view().statusword[1]), core::cia402::DriveState::SwitchOnDisabled);
}

// @req TR-C3
TEST(SimCell, RunawayInAutoIsCaughtAsAFollowingError) {
  CellRun r;
  r.arm();
  r.cell.inject({sim::FaultKind::drive_runaway, 3});
  const int k = r.until([](const sim::Cell& c) { return c.out().state != State::OPERATIONAL; }, 500);
  ASSERT_GT(k, 0);
  EXPECT_LT(k, 150);
  EXPECT_EQ(r.state(), State::IDLE);
  EXPECT_TRUE((r.cell.out().alarms & core::bit(core::AlarmId::DRIVE_FAULT)) != 0U);
}

// @req ST-STOP-TIME
TEST(SimCell, NostopDriveMeetsTheStopTimeMonitor) {
  CellRun r;
  r.arm();
  ASSERT_EQ(r.cmd(CommandId::start), Result::OK);
  ASSERT_GT(r.until([](const sim::Cell& c) { return std::fabs(c.view().velocities_rad_s[0]) > 1.0F; }, 2000), 0);
  r.cell.inject({sim::FaultKind::drive_nostop, 1});
  ASSERT_EQ(r.cmd(CommandId::servo_off), Result::OK);
  const int k = r.until([](const sim::Cell& c) { return c.out().state != State::STOPPING; }, 2000);
  ASSERT_GT(k, 0);
  EXPECT_TRUE((r.cell.out().alarms & core::bit(core::AlarmId::STOP_TIME_EXCEEDED)) != 0U);
}

TEST(SimCell, ContactorStuckOpenTimesOutArming) {
  CellRun r;
  r.cell.inject({sim::FaultKind::contactor_stuck_open, 0});
  r.cycles(100);
  ASSERT_EQ(r.cmd(CommandId::reset), Result::OK);
  ASSERT_EQ(r.cmd(CommandId::servo_on), Result::OK);
  r.cycles(101);
  EXPECT_EQ(r.state(), State::IDLE);
  EXPECT_TRUE((r.cell.out().alarms & core::bit(core::AlarmId::ARMING_TIMEOUT)) != 0U);
}

TEST(SimCell, FieldbusLostLocksOut) {
  CellRun r;
  r.arm();
  r.cell.inject({sim::FaultKind::fieldbus_lost, 0});
  r.cycles(1);
  EXPECT_EQ(r.state(), State::ERROR_LOCKOUT);
}

// @req CYC-DETERMINISM
TEST(SimCell, SameInputsGiveTheSameRunBitForBit) {
  CellRun a;
  CellRun b;
  a.arm();
  b.arm();
  a.cmd(CommandId::start);
  b.cmd(CommandId::start);
  for (int i = 0; i < 2000; ++i) {
    a.cell.step();
    b.cell.step();
    ASSERT_EQ(std::memcmp(&a.cell.view().joints_rad, &b.cell.view().joints_rad, sizeof(float) * 6), 0);
  }
}

// @req ST-CAT1 CIA-NO-REENABLE
TEST(SimCell, LaggingDriveInCat1GetsItsOwnQuickStop) {
  CellRun r;
  r.arm();
  ASSERT_EQ(r.cmd(CommandId::start), Result::OK);
  ASSERT_GT(r.until([](const sim::Cell& c) { return std::fabs(c.view().velocities_rad_s[1]) > 0.5F; }, 2000), 0);
  ASSERT_EQ(r.cmd(CommandId::servo_off), Result::OK);
  r.cell.inject({sim::FaultKind::drive_runaway, 2});  // its set-point interface no longer works
  bool saw_quick_stop = false;
  const int k = r.until(
      [&](const sim::Cell& c) {
        saw_quick_stop = saw_quick_stop || (c.view().controlword[1] == core::cia402::cw::kQuickStop &&
                                            std::string(c.view().axis_state[1]) == "Stopping");
        return c.out().state != State::STOPPING;
      },
      2000);
  ASSERT_GT(k, 0);
  EXPECT_TRUE(saw_quick_stop) << "the lagging drive was sent CiA 402 quick stop";
  EXPECT_EQ(r.state(), State::IDLE);
  EXPECT_EQ(r.cell.out().alarms & core::bit(core::AlarmId::STOP_TIME_EXCEEDED), 0U) << "it stopped in time";
  EXPECT_EQ(r.cell.out().alarms & core::bit(core::AlarmId::DRIVE_FAULT), 0U);
}

// @req CIA-AXIS-STATES
TEST(SimCell, PlcopenAxisStatesFollowTheDrivesAndTheMotion) {
  CellRun r;
  r.cycles(100);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_STREQ(r.cell.view().axis_state[i], "Disabled");
  r.arm();
  for (std::size_t i = 0; i < 6; ++i) EXPECT_STREQ(r.cell.view().axis_state[i], "Standstill");
  ASSERT_EQ(r.cmd(CommandId::start), Result::OK);
  r.cycles(1);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_STREQ(r.cell.view().axis_state[i], "DiscreteMotion");
  r.cycles(300);
  ASSERT_EQ(r.cmd(CommandId::pause), Result::OK);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_STREQ(r.cell.view().axis_state[i], "Stopping");
  r.cell.inject({sim::FaultKind::drive_fault, 3});
  r.cycles(3);
  EXPECT_STREQ(r.cell.view().axis_state[2], "ErrorStop");
  EXPECT_STREQ(r.cell.view().axis_state[0], "Disabled") << "Cat 0: the others lose power";
}

// @req CIA-AXIS-STATES
TEST(SimCell, OnlyTheJoggedAxisIsInContinuousMotion) {
  CellRun r;
  r.arm(core::Mode::T1);
  ASSERT_EQ(r.cmd(CommandId::jog, 2, 1, 10), Result::OK);
  r.cycles(1);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_STREQ(r.cell.view().axis_state[i], i == 1 ? "ContinuousMotion" : "Standstill") << i;
  }
}

// The program executor's defensive paths, driven directly (the supervisor never resumes a
// program that is not loaded or has finished, nor asks a velocity of an idle executor).
TEST(ProgramExecutor, ResumeWithoutAProgramOrAfterItsEndDoesNothing) {
  motion::ProgramExecutor p;
  const motion::Joints home{};
  p.resume(home, motion::kRobot, 1.0F);
  EXPECT_FALSE(p.active());
  for (float v : p.velocity()) EXPECT_EQ(v, 0.0F) << "an idle executor commands no velocity";
  const motion::Waypoint prog[] = {{motion::Joints{0.1F, 0.0F, 0.0F, 0.0F, 0.0F, 0.0F}, 1.0F, 0}};
  p.load(prog, 1);
  p.start(home, motion::kRobot, 1.0F);
  ASSERT_TRUE(p.active());
  for (int i = 0; i < 20000 && !p.finished(); ++i) p.advance(0.001F, motion::kRobot, 1.0F);
  ASSERT_TRUE(p.finished());
  p.resume(home, motion::kRobot, 1.0F);
  EXPECT_FALSE(p.active()) << "a finished program is not resumed";
  EXPECT_TRUE(p.finished());
}

TEST(ProgramExecutor, AWaypointWhereTheArmAlreadyIsTakesNoTimeAndNoVelocity) {
  motion::ProgramExecutor p;
  const motion::Joints here{0.2F, -0.1F, 0.1F, 0.0F, 0.3F, 0.0F};
  const motion::Waypoint prog[] = {{here, 1.0F, 5}, {motion::Joints{}, 1.0F, 0}};
  p.load(prog, 2);
  p.start(here, motion::kRobot, 1.0F);  // zero-length segment to the first waypoint
  ASSERT_TRUE(p.active());
  for (float v : p.velocity()) EXPECT_EQ(v, 0.0F);
  const motion::Joints q = p.advance(0.001F, motion::kRobot, 1.0F);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_FLOAT_EQ(q[i], here[i]) << "it dwells where it is";
  for (float v : p.velocity()) EXPECT_EQ(v, 0.0F) << "no velocity while dwelling";
}

// A dwell holds the arm at its waypoint; when it ends, the next segment starts from that
// waypoint (no jump to the next one), and after the last dwell the program ends there.
TEST(ProgramExecutor, DwellHoldsTheWaypointThenTheNextSegmentStartsFromIt) {
  motion::ProgramExecutor p;
  const motion::Joints home{};
  const motion::Joints a{0.1F, 0.0F, 0.0F, 0.0F, 0.0F, 0.0F};
  const motion::Joints b{0.1F, 0.1F, 0.0F, 0.0F, 0.0F, 0.0F};
  const motion::Waypoint prog[] = {{a, 1.0F, 5}, {b, 1.0F, 3}};
  p.load(prog, 2);
  p.start(home, motion::kRobot, 1.0F);
  motion::Joints q{};
  int k = 0;
  for (; k < 20000 && p.index() == 0; ++k) q = p.advance(0.001F, motion::kRobot, 1.0F);
  ASSERT_EQ(p.index(), 1U) << "the first dwell ended";
  for (std::size_t i = 0; i < 6; ++i) EXPECT_FLOAT_EQ(q[i], a[i]) << "the new segment starts where the arm waits";
  ASSERT_TRUE(p.active());
  int dwelt = 0;
  while (!p.finished() && k++ < 40000) {
    q = p.advance(0.001F, motion::kRobot, 1.0F);
    if (p.active() && q == b) {
      ++dwelt;  // dwelling at b: held exactly there, no velocity
      for (float v : p.velocity()) EXPECT_EQ(v, 0.0F);
    }
  }
  ASSERT_TRUE(p.finished());
  EXPECT_FALSE(p.active());
  EXPECT_EQ(p.index(), 1U) << "the index stays on the last waypoint";
  EXPECT_GE(dwelt, 2) << "3 ms of dwell at 1 ms steps";
  for (std::size_t i = 0; i < 6; ++i) EXPECT_FLOAT_EQ(q[i], b[i]) << "the program ends at its last waypoint";
}

// The motion controller driven directly with chosen drive states (the simulated drives walk
// CiA 402 one state per cycle, which does not give every combination below).
namespace {
struct Direct {
  motion::MotionController ctl{motion::kRobot, motion::MotionConfig{}};
  std::array<core::DriveFeedback, 6> drives{};
  std::array<hal::DriveOut, 6> out{};
  core::SupervisorOut so{};
  Direct() {
    for (auto& d : drives) {
      d.online = true;
      d.statusword = core::cia402::statusword_of(core::cia402::DriveState::OperationEnabled);
    }
    so.drives_enable = true;
    so.brakes_release = true;
    so.contactor = true;
  }
  void state(std::size_t axis, core::cia402::DriveState s) { drives[axis - 1].statusword = core::cia402::statusword_of(s); }
  core::Feedback cycle(core::MotionMode m) {
    core::Feedback fb{};
    ctl.measure(drives, fb);
    so.motion.mode = m;
    ctl.step(so, drives, out);
    return fb;
  }
};
}  // namespace

TEST(MotionDirect, TwoAxesLaggingInOneCycleNameTheFirst) {
  Direct d;
  d.cycle(core::MotionMode::Hold);  // enabled, brakes released, holding: the watch is on
  d.cycle(core::MotionMode::Hold);
  d.drives[1].position_rad = 0.2F;  // axis 2 and axis 4 far behind their set-points
  d.drives[3].position_rad = -0.3F;
  const core::Feedback fb = d.cycle(core::MotionMode::Hold);
  EXPECT_EQ(fb.following_error_axis, 2U) << "the first lagging axis is named, not the last";
}

TEST(MotionDirect, Cat1QuickStopsOnlyALaggingDriveThatIsEnabledOrAlreadyQuickStopped) {
  namespace cw = core::cia402::cw;
  using DS = core::cia402::DriveState;
  Direct d;
  d.state(3, DS::SwitchOnDisabled);  // axis 3 never reached Operation enabled
  d.cycle(core::MotionMode::Hold);
  d.cycle(core::MotionMode::Hold);
  ASSERT_EQ(d.out[0].controlword, cw::kEnableOperation);
  ASSERT_EQ(d.out[2].controlword, cw::kShutdown) << "not yet enabled: walked on, not dropped";
  // Axis 1 (enabled) and axis 2 (fallen to Switched on) lag behind in a Cat 1 stop.
  d.drives[0].position_rad = 0.3F;
  d.drives[1].position_rad = 0.3F;
  d.state(2, DS::SwitchedOn);
  d.cycle(core::MotionMode::QuickStop);
  EXPECT_EQ(d.out[0].controlword, cw::kQuickStop) << "an enabled lagging drive gets its own quick stop";
  EXPECT_EQ(d.out[1].controlword, cw::kDisableVoltage) << "a drive that fell out of Operation enabled is dropped";
  EXPECT_EQ(d.out[3].controlword, cw::kEnableOperation) << "a following drive stays on the controller's ramp";
  // The quick-stopped drive now reports Quick stop active: kept in its quick stop, not dropped.
  d.state(1, DS::QuickStopActive);
  d.cycle(core::MotionMode::QuickStop);
  EXPECT_EQ(d.out[0].controlword, cw::kQuickStop);
  d.cycle(core::MotionMode::Hold);  // the stop reached standstill: brakes phase, still held
  EXPECT_EQ(d.out[0].controlword, cw::kQuickStop) << "held until power is removed";
  EXPECT_EQ(d.out[1].controlword, cw::kDisableVoltage) << "never re-enabled by us";
  d.state(2, DS::SwitchOnDisabled);
  d.cycle(core::MotionMode::Hold);
  EXPECT_EQ(d.out[1].controlword, cw::kDisableVoltage) << "a dropped drive is not walked up again";
}

// A jog target naming no axis (axis 0: the core sends none, it validates 1..6) moves nothing.
TEST(MotionDirect, AJogTargetWithoutAnAxisMovesNothing) {
  Direct d;
  d.so.motion.jog.axis = 0;
  d.so.motion.jog.dir = 1;
  d.so.motion.jog.speed = 100;
  for (int k = 0; k < 50; ++k) d.cycle(core::MotionMode::Jog);
  for (float v : d.ctl.setpoint_velocity()) EXPECT_EQ(v, 0.0F);
  d.so.motion.jog.axis = 2;  // the same target with an axis does move that axis
  for (int k = 0; k < 50; ++k) d.cycle(core::MotionMode::Jog);
  EXPECT_GT(d.ctl.setpoint_velocity()[1], 0.0F);
  EXPECT_EQ(d.ctl.setpoint_velocity()[0], 0.0F);
}

// --- the injections of "More keys, faults and settings" ------------------------------------------

// @req SIM-CELL
TEST(SimFaults, SlowEnableMakesEachEnablingStepTakeItsTime) {
  CellRun r;
  r.cycles(100);
  r.cell.inject({sim::FaultKind::drive_slow_enable, 2, 40});  // 40 ms per step at 1 ms
  ASSERT_EQ(r.cmd(CommandId::reset), Result::OK);
  ASSERT_EQ(r.cmd(CommandId::servo_on), Result::OK);
  const auto enabled = [](std::size_t i) {
    return [i](const sim::Cell& c) {
      return core::cia402::decode(c.view().statusword[i]) == core::cia402::DriveState::OperationEnabled;
    };
  };
  const int fast = r.until(enabled(0), 200);
  ASSERT_GT(fast, 0);
  const int slow = r.until(enabled(1), 400);
  ASSERT_GT(slow, 0);
  // Three enabling steps of 40 cycles instead of one each: about 117 cycles later.
  EXPECT_GE(slow, 3 * 40 - 3 - 2);
  EXPECT_LE(slow, 3 * 40 + 2);
}

// @req SIM-CELL
TEST(SimFaults, RawStatuswordUntilClear) {
  CellRun r;
  r.cycles(100);
  r.cell.inject({sim::FaultKind::drive_statusword, 5, 0x1234});
  r.cycles(1);
  EXPECT_EQ(r.cell.view().statusword[4], 0x1234);
  r.cell.inject({sim::FaultKind::drive_clear, 5, 0});
  r.cycles(1);
  EXPECT_EQ(r.cell.view().statusword[4], 0x0040) << "back to its own state: Switch on disabled";
}

// @req SIM-CELL
TEST(SimFaults, WeldedContactorAndReleasedBrakeFeedbacks) {
  CellRun r;
  r.cycles(10);
  r.cell.inject({sim::FaultKind::contactor_welded, 0, 0});
  r.cell.inject({sim::FaultKind::brake_stuck_released, 3, 0});
  r.cycles(1);
  EXPECT_TRUE(r.cell.view().contactor_closed) << "closed though commanded open";
  EXPECT_TRUE(r.cell.view().brake_released[2]) << "released though commanded engaged";
  EXPECT_FALSE(r.cell.view().brake_released[1]);
  r.cell.inject({sim::FaultKind::clear_all, 0, 0});
  r.cycles(2);  // the contacts open in this cycle's write, the next read sees it
  EXPECT_FALSE(r.cell.view().contactor_closed);
}

// @req SIM-CELL
TEST(SimFaults, ProgramUnloadAndJogLinkAreRestoredByClearAll) {
  CellRun r;
  r.cell.inject({sim::FaultKind::program_unload, 0, 0});
  r.cell.inject({sim::FaultKind::jog_link_drop, 0, 0});
  r.cycles(1);
  EXPECT_EQ(r.cell.view().program_length, 0U);
  EXPECT_FALSE(r.cell.jog_link_up());
  r.cell.inject({sim::FaultKind::clear_all, 0, 0});
  r.cycles(1);
  EXPECT_GT(r.cell.view().program_length, 0U);
  EXPECT_TRUE(r.cell.jog_link_up());
}

// Issue 22 item 2: a stale cycle (the frame late or lost, the positions held from the last
// answered one) keeps the last sample's speeds, and the next fresh sample is differentiated
// over the two cycles between them: the measured speed is never doubled (no false
// T1_SPEED_EXCEEDED under frame loss) nor dropped to zero.
TEST(MotionMeasure, AStaleCycleNeverDoublesAMeasuredSpeed) {
  motion::MotionController ctl{motion::kRobot, motion::MotionConfig{}};
  std::array<core::DriveFeedback, 6> drives{};
  const float dq = 0.0002F;  // axis 1 at 0.2 rad/s (1 ms cycles)
  core::Feedback fb{};
  for (int k = 0; k <= 2; ++k) {
    drives[0].position_rad = static_cast<float>(k) * dq;
    ctl.measure(drives, fb);
  }
  const float v = fb.max_point_speed_mm_s;
  ASSERT_GT(v, 10.0F);
  ctl.measure(drives, fb, true);  // stale: the same positions again
  EXPECT_FLOAT_EQ(fb.max_point_speed_mm_s, v);
  ctl.measure(drives, fb, true);  // and again
  EXPECT_FLOAT_EQ(fb.max_point_speed_mm_s, v);
  drives[0].position_rad = 5.0F * dq;  // fresh, three cycles after the last fresh one
  ctl.measure(drives, fb);
  EXPECT_NEAR(fb.max_point_speed_mm_s, v, 0.01F * v);
  drives[0].position_rad = 6.0F * dq;  // and the next one over one cycle again
  ctl.measure(drives, fb);
  EXPECT_NEAR(fb.max_point_speed_mm_s, v, 0.01F * v);
}

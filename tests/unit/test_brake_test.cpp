// SPEC §12 brake test: the core's sequencer and due logic alone (hand-made feedback), and
// the whole cell (the motion layer's torque limit and offset, the simulated brakes).
#include <gtest/gtest.h>

#include <cmath>

#include "safestate/core/brake_test.hpp"
#include "safestate/core/config.hpp"
#include "safestate/sim/cell.hpp"

using namespace safestate;
using core::BrakeTest;
using core::BrakeTestHistory;
using core::BrakeTestLimits;
using core::BrakeTestResult;
using core::BrakeTestVerdict;
using core::Feedback;

namespace {

constexpr float kDeg = 3.14159265358979F / 180.0F;
constexpr core::Cycle kHour = 3600U * 1000U;  // cycles at 1 ms

BrakeTest configured(float interval_h = 8.0F, float grace_h = 1.0F, bool required = true) {
  BrakeTestLimits l{};
  l.configured = required;
  l.interval_h = interval_h;
  l.grace_h = grace_h;
  BrakeTest t;
  t.configure(l, 1000U, 10U, 300U);
  return t;
}

BrakeTestHistory passed_ago_h(double h) {
  BrakeTestHistory hist{};
  hist.last = BrakeTestResult::passed;
  hist.passed_ever = true;
  hist.pass_age_ms = static_cast<std::uint64_t>(h * 3600.0 * 1000.0);
  return hist;
}

// Runs the sequencer against an arm whose axis `slip_axis` (1..6, 0 none) follows the
// offset set-point (a brake that does not hold) and whose brakes follow their command at
// once. Returns the cycles it took and the last verdict.
struct SeqRun {
  BrakeTest t = configured();
  Feedback fb{};
  BrakeTestVerdict v{};
  core::Cycle now = 0;
  // slip_dir 0: the brake slips both ways; -1 / +1: only under that push.
  int run(std::uint8_t slip_axis, int slip_dir = 0, int limit = 20000) {
    t.begin(now);
    for (int k = 1; k <= limit; ++k) {
      t.step(true, fb, now++, v);
      if (v.passed || v.failed) return k;
      for (std::size_t i = 0; i < core::kAxes; ++i) {
        fb.brake_released[i] = v.brake_engaged_axis != i + 1U;
        if (slip_axis == i + 1U && v.motion.axis == slip_axis && v.motion.dir != 0 &&
            (slip_dir == 0 || slip_dir == v.motion.dir)) {
          fb.drive[i].position_rad = static_cast<float>(v.motion.dir) * v.motion.offset_rad;
        }
      }
    }
    return -1;
  }
};

}  // namespace

// @req BT-DRIFT
TEST(BrakeTestCore, DriftAboveTheLimitIsASlipAtOrBelowIsNot) {
  EXPECT_FALSE(BrakeTest::slipped(0.5F, 0.5F));  // "may not move more than max_drift_deg"
  EXPECT_TRUE(BrakeTest::slipped(0.5001F, 0.5F));
  EXPECT_FALSE(BrakeTest::slipped(0.0F, 0.5F));
  EXPECT_TRUE(BrakeTest::slipped(std::nanf(""), 0.5F));  // unknown is unsafe
}

// @req BT-SEQUENCE
TEST(BrakeTestCore, SixHoldingBrakesPassInTableOrderWithTheTestTorque) {
  SeqRun r;
  std::array<bool, core::kAxes> pushed_pos{};
  std::array<bool, core::kAxes> pushed_neg{};
  r.t.begin(0);
  int k = 0;
  for (; k < 20000; ++k) {
    r.t.step(true, r.fb, r.now++, r.v);
    if (r.v.passed || r.v.failed) break;
    ASSERT_TRUE(r.v.running);
    for (std::size_t i = 0; i < core::kAxes; ++i) r.fb.brake_released[i] = r.v.brake_engaged_axis != i + 1U;
    if (r.v.motion.dir != 0) {
      EXPECT_EQ(r.v.brake_engaged_axis, r.v.axis) << "the test torque only against an engaged brake";
      EXPECT_EQ(r.v.motion.torque_permille, 1300U);  // 130 % of rated, CiA 402 0x6072 per mille
      EXPECT_NEAR(r.v.motion.offset_rad, 2.0F * 0.5F * kDeg, 1e-6F);  // larger than max_drift_deg
      (r.v.motion.dir > 0 ? pushed_pos : pushed_neg)[r.v.axis - 1U] = true;
    } else {
      EXPECT_EQ(r.v.motion.torque_permille, 0U);
    }
  }
  EXPECT_TRUE(r.v.passed);
  EXPECT_FALSE(r.v.failed);
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    EXPECT_TRUE(pushed_pos[i] && pushed_neg[i]) << "axis " << i + 1U;
  }
  // Per axis: 10 cycles to confirm the brake, 500 + 500 pushing, a cycle or two to see it
  // released (this feedback follows its command one cycle late).
  EXPECT_GE(k + 1, 6 * (10 + 500 + 500));
  EXPECT_LE(k + 1, 6 * (11 + 500 + 500 + 2));
  core::BrakeTestStatus st{};
  r.t.status(r.now, st);
  EXPECT_EQ(st.last, BrakeTestResult::passed);
  EXPECT_EQ(st.since_start, BrakeTestResult::passed);
  EXPECT_FALSE(st.running);
}

// @req BT-RULE10
TEST(BrakeTestCore, ASlippingBrakeFailsOnItsAxisWithItsDrift) {
  for (std::uint8_t axis = 1; axis <= core::kAxes; ++axis) {
    SeqRun r;
    ASSERT_GT(r.run(axis), 0);
    EXPECT_TRUE(r.v.failed) << "axis " << int(axis);
    EXPECT_EQ(r.v.fail_axis, axis);
    EXPECT_NEAR(r.v.fail_drift_deg, 1.0F, 1e-3F);  // the whole offset: it followed the set-point
    core::BrakeTestStatus st{};
    r.t.status(r.now, st);
    EXPECT_EQ(st.last, BrakeTestResult::failed);
    EXPECT_TRUE(st.required) << "a failed test blocks AUTO until one passes";
  }
}

// A brake that holds one way but not the other (a worn ratchet, a load on one side): the
// drift is measured both ways, so the second push finds it.
TEST(BrakeTestCore, ABrakeThatSlipsOnlyUnderTheNegativePushFails) {
  SeqRun r;
  ASSERT_GT(r.run(2, -1), 0);
  EXPECT_TRUE(r.v.failed);
  EXPECT_EQ(r.v.fail_axis, 2U);
  EXPECT_NEAR(r.v.fail_drift_deg, 1.0F, 1e-3F);
  SeqRun q;
  ASSERT_GT(q.run(5, +1), 0);
  EXPECT_TRUE(q.v.failed);
  EXPECT_EQ(q.v.fail_axis, 5U);
}

TEST(BrakeTestCore, AStopAbortsWithoutAResult) {
  SeqRun r;
  r.t.begin(0);
  for (int k = 0; k < 700; ++k) r.t.step(true, r.fb, r.now++, r.v);
  ASSERT_TRUE(r.v.running);
  r.t.step(false, r.fb, r.now++, r.v);
  EXPECT_FALSE(r.v.running);
  r.t.step(true, r.fb, r.now++, r.v);
  EXPECT_FALSE(r.v.running) << "an aborted test does not resume by itself";
  core::BrakeTestStatus st{};
  r.t.status(r.now, st);
  EXPECT_EQ(st.since_start, BrakeTestResult::none);
}

// @req BT-DUE BT-REQUIRED
TEST(BrakeTestCore, DueAfterTheIntervalRequiredAfterTheGrace) {
  BrakeTest t = configured(8.0F, 1.0F);
  t.set_history(passed_ago_h(7.5));
  EXPECT_FALSE(t.due(0));
  EXPECT_FALSE(t.due(kHour / 2U));      // exactly 8 h: not above
  EXPECT_TRUE(t.due(kHour / 2U + 1U));  // one cycle later
  EXPECT_FALSE(t.required(kHour / 2U + 1U));
  EXPECT_FALSE(t.required(kHour + kHour / 2U));      // 9 h: not above interval + grace
  EXPECT_TRUE(t.required(kHour + kHour / 2U + 1U));  // above
  core::BrakeTestStatus st{};
  t.status(0, st);
  EXPECT_TRUE(st.due_known);
  EXPECT_NEAR(st.due_in_h, 0.5F, 1e-4F);
  t.status(kHour, st);
  EXPECT_NEAR(st.due_in_h, -0.5F, 1e-4F);  // overdue shows negative
}

TEST(BrakeTestCore, NeverPassedIsDueAndRequiredOnlyWhenConfigured) {
  BrakeTest t = configured();
  t.set_history(BrakeTestHistory{});
  EXPECT_TRUE(t.due(0));
  EXPECT_TRUE(t.required(0));
  BrakeTest none = configured(8.0F, 1.0F, false);  // no `brake_test` key
  none.set_history(BrakeTestHistory{});
  EXPECT_FALSE(none.due(0));
  EXPECT_FALSE(none.required(0));
  BrakeTestHistory failed{};
  failed.last = BrakeTestResult::failed;
  none.set_history(failed);
  EXPECT_TRUE(none.required(0)) << "a failed test still blocks AUTO without the key";
}

TEST(BrakeTestCore, APassRestartsTheInterval) {
  SeqRun r;
  r.t.set_history(passed_ago_h(20.0));
  EXPECT_TRUE(r.t.required(0));
  ASSERT_GT(r.run(0), 0);
  ASSERT_TRUE(r.v.passed);
  EXPECT_FALSE(r.t.due(r.now));
  EXPECT_FALSE(r.t.required(r.now));
  EXPECT_TRUE(r.t.due(r.now + 8U * kHour + 1U));
}

// ---- the whole cell: motion layer, simulated brakes -------------------------------------

namespace {

struct Cell {
  sim::Cell cell{core::Config{}};
  std::uint32_t seq = 0;
  core::Result cmd(core::CommandId id) {
    core::Command c{};
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    EXPECT_EQ(cell.submit(c), core::Result::OK);
    cell.step();
    for (std::size_t i = 0; i < cell.out().reply_count; ++i) {
      if (cell.out().replies[i].seq == c.seq) return cell.out().replies[i].result;
    }
    return core::Result::QUEUE_FULL;
  }
  void arm_auto() {
    for (int k = 0; k < 100 && cell.out().state != core::State::ESTOP_RESET_NEEDED; ++k) cell.step();
    ASSERT_EQ(cmd(core::CommandId::reset), core::Result::OK);
    ASSERT_EQ(cmd(core::CommandId::servo_on), core::Result::OK);
    for (int k = 0; k < 1000 && cell.out().sub != core::Sub::AUTO_IDLE; ++k) cell.step();
    ASSERT_EQ(cell.out().sub, core::Sub::AUTO_IDLE);
    for (int k = 0; k < 20; ++k) cell.step();  // standstill
  }
};

}  // namespace

// @req BT-CSP-TORQUE BT-SIM
TEST(BrakeTestCell, PassesWithHealthyBrakesAndOnlyTheTestedBrakeEngages) {
  Cell c;
  c.arm_auto();
  ASSERT_EQ(c.cmd(core::CommandId::brake_test), core::Result::OK);
  EXPECT_EQ(c.cell.out().sub, core::Sub::BRAKE_TEST);
  bool saw_engaged_3 = false;
  int k = 0;
  for (; k < 10000 && c.cell.out().sub == core::Sub::BRAKE_TEST; ++k) {
    c.cell.step();
    const auto& o = c.cell.out();
    if (o.brake_test_axis == 3U) {
      saw_engaged_3 = true;
      EXPECT_TRUE(o.brakes_release) << "the others stay released";
    }
    for (std::size_t i = 0; i < core::kAxes; ++i) {
      EXPECT_LT(std::fabs(c.cell.view().velocities_rad_s[i]), 1e-6F) << "healthy brakes hold: nothing moves";
    }
  }
  EXPECT_TRUE(saw_engaged_3);
  EXPECT_EQ(c.cell.out().sub, core::Sub::AUTO_IDLE);
  EXPECT_EQ(c.cell.out().brake_test.since_start, BrakeTestResult::passed);
  for (float d : c.cell.out().brake_test.drift_deg) EXPECT_LT(d, 1e-3F);
}

TEST(BrakeTestCell, AWeakBrakeSlipsFailsRule10AndBlocksAuto) {
  Cell c;
  c.arm_auto();
  c.cell.inject({sim::FaultKind::brake_weak, 4, 0});
  ASSERT_EQ(c.cmd(core::CommandId::brake_test), core::Result::OK);
  int k = 0;
  for (; k < 10000 && c.cell.out().sub == core::Sub::BRAKE_TEST; ++k) c.cell.step();
  const auto& o = c.cell.out();
  EXPECT_EQ(o.state, core::State::STOPPING);
  EXPECT_EQ(o.stop, core::StopCat::CAT1);
  ASSERT_TRUE(c.cell.alarms().active(core::AlarmId::BRAKE_TEST_FAILED));
  EXPECT_EQ(c.cell.alarms().detail(core::AlarmId::BRAKE_TEST_FAILED).axis, 4U);
  const auto mdeg = c.cell.alarms().detail(core::AlarmId::BRAKE_TEST_FAILED).code;
  EXPECT_GT(mdeg, 500U) << "drift above max_drift_deg";
  EXPECT_LT(mdeg, 1100U) << "no more than the offset";
  EXPECT_EQ(o.brake_test.since_start, BrakeTestResult::failed);
  for (int j = 0; j < 2000 && c.cell.out().state != core::State::IDLE; ++j) c.cell.step();
  EXPECT_EQ(c.cell.out().state, core::State::IDLE);
  ASSERT_EQ(c.cmd(core::CommandId::reset), core::Result::OK);
  EXPECT_EQ(c.cmd(core::CommandId::servo_on), core::Result::BRAKE_TEST_REQUIRED);
}

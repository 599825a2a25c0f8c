// SPEC §12 brake test: the sequencer walks kBrakeTestTable for axis 1 to 6; the due logic
// counts the age of the last passed test in cycles from the age given at start-up.
#include "safestate/core/brake_test.hpp"

#include <cmath>

#include "safestate/core/config.hpp"
#include "safestate/core/monitor.hpp"

namespace safestate::core {

namespace {

constexpr float kPiF = 3.14159265358979F;
constexpr float kRadToDeg = 180.0F / kPiF;
constexpr double kUsPerHour = 3600.0 * 1.0e6;

std::int64_t hours_to_cycles(float h, std::uint32_t cycle_us) noexcept {
  // Start-up only (soft double on a Cortex-M4 is fine here, never in the cycle).
  const double c = (static_cast<double>(h) * kUsPerHour) / static_cast<double>(cycle_us);
  return static_cast<std::int64_t>(std::llround(c));  // safety/ bounds the hours: no overflow
}

float absf(float x) noexcept { return (x < 0.0F) ? -x : x; }

}  // namespace

const char* to_string(BrakeTestResult r) noexcept {
  switch (r) {
    case BrakeTestResult::passed: return "passed";
    case BrakeTestResult::failed: return "failed";
    case BrakeTestResult::none: break;
  }
  return "none";
}

bool BrakeTest::slipped(float drift_deg, float max_drift_deg) noexcept {
  return !(drift_deg <= max_drift_deg);  // NaN is a slip (unknown is unsafe)
}

void BrakeTest::configure(const BrakeTestLimits& limits, std::uint32_t cycle_us, Cycle brake_confirm,
                          Cycle brakes_timeout) noexcept {
  limits_ = limits;
  cycle_us_ = (cycle_us == 0U) ? 1000U : cycle_us;
  hold_ = ms_to_cycles(limits.hold_ms, cycle_us_);
  confirm_ = brake_confirm;
  release_timeout_ = brakes_timeout;
  interval_ = hours_to_cycles(limits.interval_h, cycle_us_);
  overdue_ = hours_to_cycles(limits.interval_h + limits.grace_h, cycle_us_);
  offset_rad_ = kBrakeTestOffsetFactor * limits.max_drift_deg / kRadToDeg;
  const float pm = limits.test_torque_pct * 10.0F;
  torque_permille_ = (pm >= 65535.0F) ? std::uint16_t{65535U} : static_cast<std::uint16_t>(std::lround(pm));
}

void BrakeTest::set_history(const BrakeTestHistory& h) noexcept {
  last_ = h.last;
  passed_ever_ = h.passed_ever;
  const auto age_cycles = static_cast<std::int64_t>((h.pass_age_ms * 1000U) / cycle_us_);
  pass_at_ = -age_cycles;
}

std::int64_t BrakeTest::age(Cycle now) const noexcept { return static_cast<std::int64_t>(now) - pass_at_; }

// @req BT-DUE
bool BrakeTest::due(Cycle now) const noexcept {
  // "Time since the last passed test above interval_h": never passed is above any interval.
  return limits_.configured && (!passed_ever_ || (age(now) > interval_));
}

// @req BT-REQUIRED
bool BrakeTest::required(Cycle now) const noexcept {
  if (last_ == BrakeTestResult::failed) {
    return true;  // a failed test blocks AUTO until one passes, configured or not
  }
  return limits_.configured && (!passed_ever_ || (age(now) > overdue_));
}

void BrakeTest::begin(Cycle now) noexcept {
  static_cast<void>(now);
  running_ = true;
  axis_ = 0;
  row_ = 0;
  elapsed_ = 0;
  engaged_run_ = 0;
  q0_ = 0.0F;
  drift_deg_.fill(0.0F);
}

void BrakeTest::finish(bool passed, Cycle now) noexcept {
  running_ = false;
  last_ = passed ? BrakeTestResult::passed : BrakeTestResult::failed;
  since_start_ = last_;
  finished_ = true;
  finished_at_ = now;
  if (passed) {
    passed_ever_ = true;
    pass_at_ = static_cast<std::int64_t>(now);
  }
}

// @req BT-SEQUENCE BT-DRIFT
void BrakeTest::step(bool active, const Feedback& fb, Cycle now, BrakeTestVerdict& out) noexcept {
  out = BrakeTestVerdict{};
  // @req BT-ABORT
  if (!active) {
    running_ = false;  // any stop aborts the test: no result
    return;
  }
  if (!running_) {
    return;
  }
  const BrakeTestRow& row = kBrakeTestTable[row_ % kBrakeTestSteps];
  const DriveFeedback& d = fb.drive[axis_ % kAxes];
  const bool released = fb.brake_released[axis_ % kAxes];
  ++elapsed_;
  bool done = false;
  switch (row.ends) {
    case StepEnd::brake_engaged:
      engaged_run_ = released ? 0U : engaged_run_ + 1U;
      done = engaged_run_ >= confirm_;
      if (done) {
        q0_ = d.position_rad;  // the drive holds here; drift is counted from it
      }
      break;
    case StepEnd::hold_elapsed:
      done = elapsed_ >= hold_;
      break;
    case StepEnd::brake_released:
      done = released;
      if (!done && (elapsed_ > release_timeout_)) {
        // A brake that does not release cannot be tested further: the test fails on it.
        out.failed = true;
      }
      break;
  }
  if (row.measure) {
    const float drift = absf(d.position_rad - q0_) * kRadToDeg;
    if (!(drift <= drift_deg_[axis_ % kAxes])) {
      drift_deg_[axis_ % kAxes] = drift;
    }
    out.failed = out.failed || slipped(drift, limits_.max_drift_deg);
  }
  if (out.failed) {
    out.fail_axis = static_cast<std::uint8_t>(axis_ + 1U);
    out.fail_drift_deg = drift_deg_[axis_ % kAxes];
    finish(false, now);
    return;
  }
  out.running = true;
  out.axis = static_cast<std::uint8_t>(axis_ + 1U);
  out.step = row.step;
  out.brake_engaged_axis = row.brake_engaged ? out.axis : 0U;
  out.motion.axis = out.axis;
  out.motion.dir = row.dir;
  out.motion.offset_rad = offset_rad_;
  out.motion.torque_permille = row.torque_limited ? torque_permille_ : 0U;
  if (!done) {
    return;
  }
  elapsed_ = 0;
  engaged_run_ = 0;
  if ((row_ + 1U) < kBrakeTestSteps) {
    ++row_;
    return;
  }
  row_ = 0;
  ++axis_;
  if (axis_ >= kAxes) {
    out.passed = true;
    finish(true, now);
  }
}

void BrakeTest::status(Cycle now, BrakeTestStatus& out) const noexcept {
  out.running = running_;
  out.axis = running_ ? static_cast<std::uint8_t>(axis_ + 1U) : 0U;
  out.progress = running_ ? static_cast<std::uint8_t>(((axis_ * kBrakeTestSteps + row_) * 100U) / (kAxes * kBrakeTestSteps))
                          : 0U;
  out.last = last_;
  out.since_start = since_start_;
  out.finished = (finished_ && (finished_at_ == now)) ? since_start_ : BrakeTestResult::none;
  out.due_known = limits_.configured && passed_ever_;
  out.due_in_h = out.due_known ? static_cast<float>(interval_ - age(now)) * (static_cast<float>(cycle_us_) / 3.6e9F)
                               : 0.0F;
  out.due = due(now);
  out.required = required(now);
  out.drift_deg = drift_deg_;
}

// @req BT-RULE10
void BrakeTest::check(const CycleView& v, Reporter& r) noexcept {
  BrakeTestVerdict& out = r.facts().brake_test;
  step(v.leaf == Leaf::BRAKE_TEST, v.fb, v.now, out);
  if (out.failed) {
    // Names the axis and its drift (code: millidegrees, saturated).
    const float mdeg = out.fail_drift_deg * 1000.0F;
    r.trip(AlarmId::BRAKE_TEST_FAILED, detail_of(Signal::axis, Channel::none, out.fail_axis, detail_code(mdeg)));
  }
  r.hold(AlarmId::BRAKE_TEST_DUE, due(v.now), detail_of(Signal::internal));
}

}  // namespace safestate::core

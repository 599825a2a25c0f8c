// The brake test of SPEC §12 (ISO 10218-1:2025 position holding): the sequencer that tests
// the six holding brakes one after the other, and the due logic (interval, grace, never
// tested, failed). Like every monitor of core/src/monitors it takes the cycle's measured
// state and fixed-size parameters and returns a verdict; only the supervisor changes
// state (rule 10 on a failure, the `brake_test_passed` event on a pass).
//
// Time is counted in cycles only. The age of the last passed test at start-up comes in as
// data (from the event log via the runtime, or a scenario's `config brake_test_age_h=`).
//
// How the test torque is applied to CSP drives (SPEC §6): the drive's torque is limited to
// test_torque_pct of rated (CiA 402 0x6072, per mille) and its set-point is moved by a small
// offset, first one way, then the other, so that its position loop saturates at that limit
// and pushes the engaged brake with exactly the test torque. A brake that holds keeps the
// axis where it was; one that slips lets it follow the offset, which is larger than
// max_drift_deg so that a slip is always seen.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/interfaces.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

struct CycleView;  // monitor.hpp
class Reporter;    // monitor.hpp

// SPEC §12 in the core's units (the file's numbers; cycles are derived in configure()).
struct BrakeTestLimits {
  bool configured = false;  // the file has a `brake_test` key: a passed test is required
  float interval_h = 8.0F;
  float grace_h = 1.0F;
  float test_torque_pct = 130.0F;
  std::uint32_t hold_ms = 500;
  float max_drift_deg = 0.5F;
};

// The latest result (status `last`, scenario `brake_test=`).
enum class BrakeTestResult : std::uint8_t { none, passed, failed };
const char* to_string(BrakeTestResult r) noexcept;

// What the event log says at start-up.
struct BrakeTestHistory {
  BrakeTestResult last = BrakeTestResult::none;  // the latest recorded test
  bool passed_ever = false;                      // a passed test is on record ...
  std::uint64_t pass_age_ms = 0;                 // ... this long ago
};

// The set-point offset that makes a CSP drive push with its torque limit: twice the
// allowed drift, so that a slipping brake always lets the axis drift past max_drift_deg.
inline constexpr float kBrakeTestOffsetFactor = 2.0F;

// One axis' sequence, as a table (rows in order; the test walks it for axis 1 to 6).
enum class BrakeTestStep : std::uint8_t { engage, push_pos, push_neg, release };
inline constexpr std::size_t kBrakeTestSteps = 4;
enum class StepEnd : std::uint8_t {
  brake_engaged,   // the brake's feedback has said engaged for brake_confirm cycles
  hold_elapsed,    // hold_ms have passed (drift measured every cycle)
  brake_released,  // the brake's feedback says released (else a failure after brakes_timeout)
};
struct BrakeTestRow {
  BrakeTestStep step;
  bool brake_engaged;   // this axis' brake commanded engaged
  std::int8_t dir;      // set-point offset direction, 0 = none
  bool torque_limited;  // the drive's torque limited to the test torque
  bool measure;         // drift counted in this step
  StepEnd ends;
  const char* text;     // for the documentation
};
inline constexpr std::array<BrakeTestRow, kBrakeTestSteps> kBrakeTestTable{{
    {BrakeTestStep::engage, true, 0, false, false, StepEnd::brake_engaged,
     "engage this axis' brake, the drives hold every axis; the position is taken once it has engaged"},
    {BrakeTestStep::push_pos, true, 1, true, true, StepEnd::hold_elapsed,
     "torque limited to test_torque_pct, set-point + offset, for hold_ms; drift measured"},
    {BrakeTestStep::push_neg, true, -1, true, true, StepEnd::hold_elapsed,
     "torque limited to test_torque_pct, set-point - offset, for hold_ms; drift measured"},
    {BrakeTestStep::release, false, 0, false, false, StepEnd::brake_released,
     "torque limit lifted, set-point back, brake released; then the next axis"},
}};

// What the sequencer asks of the cycle, and what it found.
struct BrakeTestVerdict {
  bool running = false;
  std::uint8_t axis = 0;  // 1..6 while running
  BrakeTestStep step = BrakeTestStep::engage;
  std::uint8_t brake_engaged_axis = 0;  // 1..6: that brake engaged by the test
  BrakeTestRequest motion{};            // offset and torque limit for the motion layer
  bool passed = false;                  // this cycle: all six held
  bool failed = false;                  // this cycle: rule 10
  std::uint8_t fail_axis = 0;
  float fail_drift_deg = 0.0F;
};

// Status of SPEC §12 (protocol `safety.brake_test`, scenario `brake_test=`).
struct BrakeTestStatus {
  bool running = false;
  std::uint8_t axis = 0;
  std::uint8_t progress = 0;                          // percent of the whole test
  BrakeTestResult last = BrakeTestResult::none;       // latest on record (log + this run)
  BrakeTestResult since_start = BrakeTestResult::none;
  BrakeTestResult finished = BrakeTestResult::none;  // a test ended in this cycle, so
  bool due_known = false;                             // false: never passed, or none required
  float due_in_h = 0.0F;                              // interval_h - age (negative: overdue)
  bool due = false;                                   // BRAKE_TEST_DUE
  bool required = false;                              // servo_on in AUTO is BRAKE_TEST_REQUIRED
  std::array<float, kAxes> drift_deg{};               // of the latest test run here (or running)
};

class BrakeTest {
 public:
  // Before the first cycle. `brake_confirm` and `brakes_timeout` are the supervisor's own
  // brake feedback times (SPEC §7).
  void configure(const BrakeTestLimits& limits, std::uint32_t cycle_us, Cycle brake_confirm,
                 Cycle brakes_timeout) noexcept;
  void set_history(const BrakeTestHistory& h) noexcept;

  // The command was accepted: start with axis 1.
  void begin(Cycle now) noexcept;
  // The monitor's entry: runs step() while the supervisor is in BRAKE_TEST (facts
  // brake_test); BRAKE_TEST_FAILED (rule 10) naming the axis and its drift in millidegrees;
  // BRAKE_TEST_DUE while the last pass is older than the interval.
  void check(const CycleView& v, Reporter& r) noexcept;
  // One cycle. `active`: the supervisor is in BRAKE_TEST (anything else aborts the test
  // without a result). Fills the verdict; on a pass or failure records it.
  void step(bool active, const Feedback& fb, Cycle now, BrakeTestVerdict& out) noexcept;

  [[nodiscard]] bool due(Cycle now) const noexcept;
  [[nodiscard]] bool required(Cycle now) const noexcept;
  void status(Cycle now, BrakeTestStatus& out) const noexcept;
  [[nodiscard]] const BrakeTestLimits& limits() const noexcept { return limits_; }
  [[nodiscard]] float offset_rad() const noexcept { return offset_rad_; }
  [[nodiscard]] Cycle hold_cycles() const noexcept { return hold_; }

  // A drift above max_drift_deg (strictly) is a slip (SPEC §12 "may not move more than").
  [[nodiscard]] static bool slipped(float drift_deg, float max_drift_deg) noexcept;

 private:
  void finish(bool passed, Cycle now) noexcept;
  [[nodiscard]] std::int64_t age(Cycle now) const noexcept;

  BrakeTestLimits limits_{};
  std::uint32_t cycle_us_ = 1000;
  Cycle hold_ = 500;
  Cycle confirm_ = 10;
  Cycle release_timeout_ = 300;
  std::int64_t interval_ = 0;  // cycles
  std::int64_t overdue_ = 0;   // interval + grace, cycles
  float offset_rad_ = 0.0F;
  std::uint16_t torque_permille_ = 1300;
  // Due logic: the cycle (on this run's clock, negative before start) of the last pass.
  bool passed_ever_ = false;
  std::int64_t pass_at_ = 0;
  BrakeTestResult last_ = BrakeTestResult::none;
  BrakeTestResult since_start_ = BrakeTestResult::none;
  bool finished_ = false;
  Cycle finished_at_ = 0;
  // Sequencer.
  bool running_ = false;
  std::uint8_t axis_ = 0;  // 0-based
  std::uint8_t row_ = 0;
  Cycle elapsed_ = 0;
  Cycle engaged_run_ = 0;
  float q0_ = 0.0F;
  std::array<float, kAxes> drift_deg_{};
};

}  // namespace safestate::core

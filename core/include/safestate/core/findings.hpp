// What the safe-limit and collaborative monitors measured in one cycle (CycleFacts in
// monitor.hpp): the values the state machine, the motion request and the status read.
// The alarms themselves go to the Reporter by name; these are the numbers behind them.
#pragma once

#include <cstdint>

#include "safestate/core/alarms.hpp"

namespace safestate::core {

struct LimitFinding {
  bool hit = false;
  AlarmDetail detail{};
};

// SPEC §10, the safe limits.
struct LimitReport {
  bool speed_over = false;   // a speed over its limit now, with power or not (reset guard)
  bool outside = false;      // a position limit is violated now
  bool recovering = false;   // ... and that is being recovered from (status `recovery`)
  bool in_reduced_zone = false;
  std::uint8_t reduced_zone = 0;  // 1 + index of the first reduced zone holding the TCP, 0: none
  bool reduced_enforced = false;  // reduced mode active and its ramp time over
  float reduced_limit_mm_s = 0.0F;  // the reduced TCP limit of the active sources (SPEC §10, §11)
  float tcp_speed_mm_s = 0.0F;
  float speed_limit_mm_s = 0.0F;  // the TCP limit in force this cycle

  // As a value-initialised report, member by member: `= LimitReport{}` is a byte-wise
  // memset in newlib-nano (a hundred and more instructions per cycle on the Cortex-M4).
  void clear() noexcept {
    speed_over = false;
    outside = false;
    recovering = false;
    in_reduced_zone = false;
    reduced_zone = 0U;
    reduced_enforced = false;
    reduced_limit_mm_s = 0.0F;
    tcp_speed_mm_s = 0.0F;
    speed_limit_mm_s = 0.0F;
  }
};

// What the protective fields mean this cycle (SPEC §11).
struct FieldReport {
  bool acting = false;         // collaborative on and mode AUTO: the fields act (SPEC §11)
  bool outer_reduces = false;  // reduced mode source kReducedByField
  bool inner_stops = false;    // rule 9's condition (the row says from which leaf)
  bool blocks_start = false;   // start / resume: FIELD_INTERRUPTED
  bool resume_due = false;     // both clear for resume_delay_ms and auto_resume on
};

// Speed and separation monitoring's verdict this cycle (SPEC §11).
struct SsmReport {
  bool acting = false;           // collaborative and ssm on, mode AUTO
  float separation_mm = 0.0F;    // the separation used (after the plausibility filter)
  float v_allowed_mm_s = 0.0F;   // v_allowed(separation) clamped to [0, the limit in force]
  float v_plan_mm_s = 0.0F;      // what the motion layer plans to (ssm_planning_speed_mm_s)
  bool over = false;             // TCP above v_allowed + 5 % now (the reset guard's "cause")
};

}  // namespace safestate::core

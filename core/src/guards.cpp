// Guards of the transition table: pure functions of what the cycle sees, each checking
// its conditions in the order SPEC §4 lists them and returning the first reject code.
#include "safestate/core/transitions.hpp"

namespace safestate::core {

namespace {
constexpr bool is_manual(Mode m) noexcept { return (m == Mode::T1) || (m == Mode::T2); }
}  // namespace

Result guard_boot_done(const GuardView& v) noexcept {
  return v.boot_pending ? Result::BUSY : Result::OK;
}

// @req RES-RESET-OK
Result guard_reset_causes_gone(const GuardView& v) noexcept {
  if (v.reset_pending) {
    return Result::BUSY;
  }
  // ISO 13849-1 5.2.2: a reset must not be possible while the cause is still present. Each
  // monitor says whose cause is (Reporter::present): the guard open in AUTO, a speed still
  // over T1's, its limit or SSM's v_allowed, a stop not at standstill, a brake that still
  // does not hold. A position limit still violated is no reason to refuse: SPEC §10
  // recovery needs the reset to jog back in T1.
  if ((v.alarms.mask() & v.causes_present) != 0U) {
    return Result::FAULT_PRESENT;
  }
  return Result::OK;  // drive faults are acknowledged by the reset itself (Effect::reset_alarms)
}

// @req TR-LATCH
Result guard_servo_on(const GuardView& v) noexcept {
  // A pending reset implies DRIVE_FAULT (latched): covered by the first check.
  if ((v.alarms.mask() & kLatchedAlarms) != 0U) {
    return Result::RESET_REQUIRED;
  }
  if (v.in.mode == Mode::NONE) {
    return Result::MODE_INVALID;
  }
  if ((v.in.mode == Mode::AUTO) && v.in.gate_open) {
    return Result::GATE_OPEN;
  }
  if (is_manual(v.in.mode) && !v.in.enable_ok) {
    return Result::ENABLING_NOT_HELD;
  }
  if ((v.in.mode == Mode::T2) && !v.t2_confirmed) {
    return Result::T2_NOT_CONFIRMED;
  }
  // @req LIM-VALIDATION LIM-RECOVERY
  // SPEC §10: T1 stays allowed, to commission at reduced speed and to recover.
  const bool auto_or_t2 = (v.in.mode == Mode::AUTO) || (v.in.mode == Mode::T2);
  if (auto_or_t2 && !v.config_validated) {
    return Result::CONFIG_NOT_VALIDATED;
  }
  if (auto_or_t2 && v.outside_limits) {
    return Result::OUTSIDE_LIMITS;
  }
  // @req BT-REQUIRED
  // SPEC §12: T1 and T2 stay allowed, to move to a service position and test again.
  if ((v.in.mode == Mode::AUTO) && v.brake_test_required) {
    return Result::BRAKE_TEST_REQUIRED;
  }
  return Result::OK;
}

namespace {
// @req LIM-PROGRAM
// SPEC §10: a program with a waypoint or path outside the safe limits is refused at start.
Result program_ready(const GuardView& v) noexcept {
  if (!v.fb.program_loaded) {
    return Result::NO_PROGRAM;
  }
  return v.fb.program_within_limits ? Result::OK : Result::OUTSIDE_LIMITS;
}
}  // namespace

// @req COL-FIELD-GUARD
Result guard_start_auto(const GuardView& v) noexcept {
  if (v.in.gate_open) {
    return Result::GATE_OPEN;
  }
  if (!v.fb.program_loaded) {
    return Result::NO_PROGRAM;
  }
  if (v.field_blocks) {
    return Result::FIELD_INTERRUPTED;  // SPEC §11: a person in the inner field
  }
  return program_ready(v);
}

// @req COL-FIELD-GUARD
Result guard_resume(const GuardView& v) noexcept {
  if (v.in.gate_open) {
    return Result::GATE_OPEN;
  }
  return v.field_blocks ? Result::FIELD_INTERRUPTED : Result::OK;
}

Result guard_enable_held(const GuardView& v) noexcept {
  return v.in.enable_ok ? Result::OK : Result::ENABLING_NOT_HELD;
}

Result guard_start_manual(const GuardView& v) noexcept {
  if (!v.in.enable_ok) {
    return Result::ENABLING_NOT_HELD;
  }
  return program_ready(v);
}

Result guard_t2_selected(const GuardView& v) noexcept {
  return (v.in.mode == Mode::T2) ? Result::OK : Result::MODE_INVALID;
}

// @req LIM-VALIDATION
Result guard_validate_config(const GuardView& v) noexcept {
  if (!is_manual(v.in.mode)) {
    return Result::MODE_INVALID;
  }
  return (v.code == v.checksum) ? Result::OK : Result::CHECKSUM_MISMATCH;
}

// @req BT-COMMAND
// SPEC §4: `brake_test` in AUTO_IDLE or MANUAL_IDLE at standstill with a valid mode.
Result guard_brake_test(const GuardView& v) noexcept {
  if (!v.at_standstill) {
    return Result::WRONG_STATE;
  }
  return (v.in.mode == Mode::NONE) ? Result::MODE_INVALID : Result::OK;
}

}  // namespace safestate::core

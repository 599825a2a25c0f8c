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
  // ISO 13849-1 5.2.2: a reset must not be possible while the cause is still present.
  if (v.alarms.active(AlarmId::PROTECTIVE_STOP) && v.in.gate_open && (v.in.mode == Mode::AUTO)) {
    return Result::FAULT_PRESENT;
  }
  if (v.alarms.active(AlarmId::T1_SPEED_EXCEEDED) && !(v.fb.max_point_speed_mm_s <= v.timing.t1_speed_limit_mm_s)) {
    return Result::FAULT_PRESENT;
  }
  if (v.alarms.active(AlarmId::STOP_TIME_EXCEEDED) && !v.at_standstill) {
    return Result::FAULT_PRESENT;
  }
  if (v.alarms.active(AlarmId::BRAKE_NOT_ENGAGED) && v.brake_not_engaged) {
    return Result::FAULT_PRESENT;  // the brake still does not hold
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
  return Result::OK;
}

Result guard_start_auto(const GuardView& v) noexcept {
  if (v.in.gate_open) {
    return Result::GATE_OPEN;
  }
  return v.fb.program_loaded ? Result::OK : Result::NO_PROGRAM;
}

Result guard_gate_closed(const GuardView& v) noexcept {
  return v.in.gate_open ? Result::GATE_OPEN : Result::OK;
}

Result guard_enable_held(const GuardView& v) noexcept {
  return v.in.enable_ok ? Result::OK : Result::ENABLING_NOT_HELD;
}

Result guard_start_manual(const GuardView& v) noexcept {
  if (!v.in.enable_ok) {
    return Result::ENABLING_NOT_HELD;
  }
  return v.fb.program_loaded ? Result::OK : Result::NO_PROGRAM;
}

Result guard_t2_selected(const GuardView& v) noexcept {
  return (v.in.mode == Mode::T2) ? Result::OK : Result::MODE_INVALID;
}

}  // namespace safestate::core

// @req SIM-CELL
#include "safestate/sim/plant.hpp"

#include <cmath>

namespace safestate::sim {

namespace c402 = core::cia402;

namespace {
float clampf(float x, float lo, float hi) noexcept { return (x < lo) ? lo : ((x > hi) ? hi : x); }
float toward_zero(float v, float dv) noexcept { return (v > dv) ? v - dv : ((v < -dv) ? v + dv : 0.0F); }
}  // namespace

SimPlant::SimPlant(const motion::RobotModel& model, float cycle_s, const PlantTiming& t,
                   const motion::Joints& home) noexcept
    : model_(model), dt_(cycle_s), timing_(t) {
  for (std::size_t i = 0; i < hal::kAxes; ++i) {
    axis_[i].q = home[i];
  }
}

void SimPlant::inject(const Fault& f) noexcept {
  const std::size_t i = (f.axis >= 1U && f.axis <= hal::kAxes) ? f.axis - 1U : 0U;
  switch (f.kind) {
    case FaultKind::drive_fault:
      axis_[i].fault_cause = true;
      axis_[i].ds = c402::DriveState::Fault;  // reports Fault from the next read
      break;
    case FaultKind::drive_clear:
      axis_[i].fault_cause = false;
      axis_[i].runaway = false;
      axis_[i].nostop = false;
      axis_[i].sw_override = false;
      axis_[i].slow_cycles = 0;
      break;
    case FaultKind::drive_runaway: axis_[i].runaway = true; break;
    case FaultKind::drive_nostop: axis_[i].nostop = true; break;
    case FaultKind::fieldbus_lost: fieldbus_ok_ = false; break;
    case FaultKind::contactor_stuck_open: contactor_stuck_open_ = true; break;
    case FaultKind::brake_stuck: axis_[i].brake_stuck = true; break;
    case FaultKind::brake_weak: axis_[i].brake_weak = true; break;
    case FaultKind::clear_all:
      for (Axis& a : axis_) {
        a.fault_cause = false;
        a.runaway = false;
        a.nostop = false;
        a.brake_stuck = false;
        a.brake_stuck_released = false;
        a.brake_weak = false;
        a.sw_override = false;
        a.slow_cycles = 0;
      }
      contactor_stuck_open_ = false;
      contactor_welded_ = false;
      fieldbus_ok_ = true;
      integrity_ok_ = true;
      self_test_ok_ = true;
      break;
    case FaultKind::integrity: integrity_ok_ = false; break;
    case FaultKind::selftest_fail: self_test_ok_ = false; break;
    case FaultKind::drive_statusword:
      axis_[i].sw_override = true;
      axis_[i].sw_value = f.value;
      break;
    case FaultKind::drive_slow_enable:
      axis_[i].slow_cycles = cycles_of_ms(f.value);
      axis_[i].slow_timer = 0;
      break;
    case FaultKind::contactor_welded:
      contactor_welded_ = true;
      contactor_closed_ = true;  // welded shut: closed from now on, whatever the command
      break;
    case FaultKind::brake_stuck_released:
      axis_[i].brake_stuck_released = true;
      axis_[i].brake_released = true;
      break;
    case FaultKind::program_unload:
    case FaultKind::jog_link_drop:
      break;  // not the plant's: the cell handles them
  }
}

std::uint32_t SimPlant::cycles_of_ms(std::uint16_t ms) const noexcept {
  const float c = std::ceil((static_cast<float>(ms) * 1.0e-3F / dt_) - 1.0e-3F);
  return (c < 1.0F) ? 1U : static_cast<std::uint32_t>(c);
}

void SimPlant::read(hal::ProcessImageIn& in) noexcept {
  in.safety = safety_;
  for (std::size_t i = 0; i < hal::kAxes; ++i) {
    const Axis& a = axis_[i];
    in.drive[i].statusword = a.sw_override ? a.sw_value : c402::statusword_of(a.ds);
    in.drive[i].position_rad = a.q;
    in.drive[i].velocity_rad_s = a.v;
    in.drive[i].online = true;
    in.drive[i].torque_permille = a.torque;
    in.brake_released[i] = a.brake_released;
  }
  in.contactor_closed = contactor_closed_;
  in.fieldbus_ok = fieldbus_ok_;
  in.integrity_ok = integrity_ok_;
  in.self_test_ok = self_test_ok_;
}

void SimPlant::drive_state(Axis& a, std::uint16_t cw, bool power) noexcept {
  if (!fieldbus_ok_ && a.ds != c402::DriveState::Fault) {
    a.ds = c402::DriveState::FaultReactionActive;  // the drive's own bus watchdog
  } else if (a.ds == c402::DriveState::NotReadyToSwitchOn) {
    if (age_ >= timing_.drive_boot_cycles) {
      a.ds = c402::DriveState::SwitchOnDisabled;
    }
  } else if (a.ds == c402::DriveState::Fault && a.fault_cause) {
    // stays in Fault while its cause is present, whatever the controlword
  } else {
    const c402::DriveState next = c402::next_state(a.ds, a.last_cw, cw, power);
    // slow_enable: each step towards Operation enabled takes slow_cycles (2, 3, 4 of
    // IEC 61800-7-201); every step away from it stays immediate.
    const bool enabling = (next == c402::DriveState::ReadyToSwitchOn && a.ds == c402::DriveState::SwitchOnDisabled) ||
                          (next == c402::DriveState::SwitchedOn && a.ds == c402::DriveState::ReadyToSwitchOn) ||
                          (next == c402::DriveState::OperationEnabled && a.ds == c402::DriveState::SwitchedOn);
    if (enabling && a.slow_cycles > 0U && ++a.slow_timer < a.slow_cycles) {
      // still working on this step
    } else {
      a.slow_timer = 0;
      a.ds = next;
    }
  }
  a.last_cw = cw;
}

// Torque actual (0x6077) of a drive, an assumption of this plant (no gravity, no friction:
// docs/robot.md): rated torque accelerates the axis at its limit, so the torque is the
// acceleration in per mille of qdd_max, within the drive's limit (0x6072); against the
// engaged brake a drive off its set-point pushes with its limit, held or slipping; a drive
// without torque (not enabled, no power) reports 0.
std::int16_t SimPlant::drive_torque(const Axis& a, const hal::DriveOut& d, float accel, float amax,
                                    float target) const noexcept {
  if (a.ds != c402::DriveState::OperationEnabled || !contactor_closed_) {
    return 0;
  }
  const float limit = std::fmin(static_cast<float>(d.max_torque_permille), 32767.0F);
  float t = 1000.0F * accel / amax;
  if (!a.brake_released && std::fabs(target - a.q) > 1.0e-6F) {
    t = (target > a.q) ? limit : -limit;
  }
  return static_cast<std::int16_t>(std::lround(clampf(t, -limit, limit)));
}

void SimPlant::physics(Axis& a, std::size_t i, const hal::DriveOut& d) noexcept {
  const float target = d.target_position_rad;
  const float v_before = a.v;
  const float vmax = model_.qd_max_rad_s[i];
  const float amax = model_.qdd_max_rad_s2[i] * payload_decel_scale(payload_);
  const bool torque = (a.ds == c402::DriveState::OperationEnabled) && contactor_closed_;
  if (torque && a.runaway) {
    const float dir = (a.v < 0.0F) ? -1.0F : 1.0F;  // accelerates at its limit, ignoring set-points
    a.v = clampf(a.v + (dir * amax * dt_), -vmax, vmax);
  } else if (a.ds == c402::DriveState::QuickStopActive && contactor_closed_ && !a.nostop) {
    a.v = toward_zero(a.v, amax * dt_);  // the drive's own quick-stop ramp (0x6085)
  } else if (a.ds == c402::DriveState::QuickStopActive && contactor_closed_) {
    // nostop: ignores its own quick-stop ramp too
  } else if (torque && a.brake_released) {
    const float v0 = a.v;
    const float v_cmd = clampf((target - a.q) / dt_, -vmax, vmax);
    const bool decelerating = std::fabs(v_cmd) < std::fabs(a.v) || (v_cmd * a.v) < 0.0F;
    if (!(a.nostop && decelerating)) {
      a.v = v_cmd;  // CSP: follows the set-point within its limits
    }
    // @req STOP-DATA
    if (payload_ > 0.0F) {
      a.v = clampf(a.v, v0 - (amax * dt_), v0 + (amax * dt_));  // the payload's inertia: no faster than amax
    }
  } else if (torque) {
    // @req BT-SIM
    // Against the engaged brake: a CSP drive off its set-point pushes with its torque limit
    // (0x6072); the brake holds unless that is more than its holding torque (SPEC §12).
    const std::uint16_t holds = a.brake_weak ? kWeakBrakeHoldingPermille : kBrakeHoldingPermille;
    const bool pushes = std::fabs(target - a.q) > 1.0e-6F;
    if (pushes && (d.max_torque_permille > holds)) {
      a.v = clampf((target - a.q) / dt_, -kBrakeSlipRadS, kBrakeSlipRadS);  // slips toward the set-point
    } else {
      a.v = 0.0F;  // held by the brake
    }
  } else {
    a.v = toward_zero(a.v, kBrakeStopDecelFactor * amax * dt_);  // no torque: the holding brake stops the axis
  }
  a.torque = drive_torque(a, d, (a.v - v_before) / dt_, model_.qdd_max_rad_s2[i], target);
  a.q += a.v * dt_;
  if (a.q > model_.q_max_rad[i] || a.q < model_.q_min_rad[i]) {
    a.q = clampf(a.q, model_.q_min_rad[i], model_.q_max_rad[i]);  // mechanical hard stop
    a.v = 0.0F;
  }
}

void SimPlant::write(const hal::ProcessImageOut& out) noexcept {
  ++age_;
  if (out.contactor != contactor_cmd_) {
    contactor_cmd_ = out.contactor;
    contactor_timer_ = 0;
  }
  ++contactor_timer_;
  if (contactor_timer_ >= timing_.contactor_cycles) {
    contactor_closed_ = contactor_cmd_ && !contactor_stuck_open_;
  }
  if (contactor_stuck_open_) {
    contactor_closed_ = false;
  }
  if (contactor_welded_) {
    contactor_closed_ = true;
  }
  for (std::size_t i = 0; i < hal::kAxes; ++i) {
    Axis& a = axis_[i];
    const bool release = out.brakes_release && (static_cast<std::size_t>(out.brake_test_axis) != (i + 1U));
    if (release != a.brake_cmd) {
      a.brake_cmd = release;
      a.brake_timer = 0;
    }
    ++a.brake_timer;
    if (a.brake_timer >= timing_.brake_cycles) {
      a.brake_released = a.brake_cmd && !a.brake_stuck;
    }
    if (a.brake_stuck) {
      a.brake_released = false;
    }
    if (a.brake_stuck_released) {
      a.brake_released = true;
    }
    drive_state(a, out.drive[i].controlword, contactor_closed_);
    physics(a, i, out.drive[i]);
  }
}

}  // namespace safestate::sim

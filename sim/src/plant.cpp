// @req SIM-CELL
#include "safestate/sim/plant.hpp"

#include <cmath>

#include "safestate/core/dynamics.hpp"

namespace safestate::sim {

namespace c402 = core::cia402;

namespace {
float clampf(float x, float lo, float hi) noexcept { return (x < lo) ? lo : ((x > hi) ? hi : x); }
float toward_zero(float v, float dv) noexcept { return (v > dv) ? v - dv : ((v < -dv) ? v + dv : 0.0F); }
}  // namespace

SimPlant::SimPlant(const motion::RobotModel& model, float cycle_s, const PlantTiming& t,
                   const motion::Joints& home) noexcept
    : model_(model), dt_(cycle_s), timing_(t), dyn_(std::make_shared<ArmDynamics>()) {
  for (std::size_t i = 0; i < hal::kAxes; ++i) {
    axis_[i].q = home[i];
  }
}

void SimPlant::set_tool(float payload_kg, const std::array<float, 3>& tcp_tool0_mm) noexcept {
  for (std::size_t k = 0; k < 3U; ++k) {
    tcp_m_[k] = static_cast<double>(tcp_tool0_mm[k]) * 1.0e-3;
  }
  auto d = std::make_shared<ArmDynamics>();  // copies made before keep the old tool
  d->set_payload(static_cast<double>(payload_kg), tcp_m_);
  dyn_ = std::move(d);
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
    case FaultKind::contactor_stuck_open: k_[(f.axis == 2U) ? 1U : 0U].stuck_open = true; break;
    case FaultKind::brake_stuck: axis_[i].brake_stuck = true; break;
    case FaultKind::brake_weak: axis_[i].brake_weak = true; break;
    // @req COL-SIM-CONTACT
    case FaultKind::contact:
      contact_n_ = static_cast<float>(f.value) * 0.1F;
      contact_on_ = false;  // placed where the TCP next moves
      break;
    case FaultKind::drive_torque_bias: axis_[i].bias = static_cast<std::int16_t>(f.value); break;
    case FaultKind::clear_all:
      contact_n_ = 0.0F;
      contact_on_ = false;
      for (Axis& a : axis_) {
        a.fault_cause = false;
        a.runaway = false;
        a.nostop = false;
        a.brake_stuck = false;
        a.brake_stuck_released = false;
        a.brake_weak = false;
        a.bias = 0;
        a.sw_override = false;
        a.slow_cycles = 0;
      }
      for (Contactor& k : k_) {
        k.stuck_open = false;
        k.welded = false;
      }
      for (Axis& a : axis_) {
        a.enc_stuck = false;
        a.enc_offset_rad = 0.0F;
        a.enc_drift_rad_s = 0.0F;
        a.enc_drift_acc_rad = 0.0F;
      }
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
    case FaultKind::contactor_welded: {
      Contactor& k = k_[(f.axis == 2U) ? 1U : 0U];
      k.welded = true;
      k.closed = true;  // welded shut: closed from now on, whatever the command
      break;
    }
    // SPEC §14 the load-side encoder of axis N.
    case FaultKind::encoder_stuck:
      axis_[i].enc_stuck_rad = load_position(i);
      axis_[i].enc_stuck = true;
      break;
    case FaultKind::encoder_offset:
      axis_[i].enc_offset_rad = static_cast<float>(static_cast<std::int16_t>(f.value)) * 0.01F * (3.14159265F / 180.0F);
      break;
    case FaultKind::encoder_drift:
      axis_[i].enc_drift_rad_s = static_cast<float>(static_cast<std::int16_t>(f.value)) * 0.01F * (3.14159265F / 180.0F);
      break;
    case FaultKind::brake_stuck_released:
      axis_[i].brake_stuck_released = true;
      axis_[i].brake_released = true;
      break;
    case FaultKind::program_unload:
    case FaultKind::jog_link_drop:
    case FaultKind::channel_stall:
    case FaultKind::channel_crash:
    case FaultKind::channel_input:
    case FaultKind::digest_corrupt:
    case FaultKind::digest_drop:
    case FaultKind::digest_repeat:
    case FaultKind::channel_flip:
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
    in.drive[i].load_position_rad = load_position(i);
  }
  in.load_encoders = true;
  in.contactor_closed = k_[0].closed;
  in.two_contactors = two_contactors_;
  in.k2_closed = two_contactors_ && k_[1].closed;
  in.fieldbus_ok = fieldbus_ok_;
  in.integrity_ok = integrity_ok_;
  in.self_test_ok = self_test_ok_;
}

// SPEC §14: the load-side encoder: the joint behind the gearbox's compliance under the
// drive's torque, with its injected faults.
float SimPlant::load_position(std::size_t i) const noexcept {
  const Axis& a = axis_[i];
  if (a.enc_stuck) {
    return a.enc_stuck_rad;
  }
  return a.q - (kGearComplianceRadPerPermille * static_cast<float>(a.torque)) + a.enc_offset_rad + a.enc_drift_acc_rad;
}

void SimPlant::switch_contactor(Contactor& k, bool cmd) const noexcept {
  if (cmd != k.cmd) {
    k.cmd = cmd;
    k.timer = 0;
  }
  ++k.timer;
  if (k.timer >= timing_.contactor_cycles) {
    k.closed = k.cmd && !k.stuck_open;
  }
  if (k.stuck_open) {
    k.closed = false;
  }
  if (k.welded) {
    k.closed = true;
  }
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

// Torque actual (0x6077) of a drive whose axis its brake holds, or without power: a drive
// without torque (not enabled, no power) reports 0; against the engaged brake a drive off its
// set-point pushes with its limit (0x6072), held or slipping; otherwise the axis' acceleration
// in per mille of qdd_max, within that limit (the brake, not the drive, carries the arm). An
// axis the drive holds with its brake released gets the arm's dynamics instead (dynamics()).
std::int16_t SimPlant::drive_torque(const Axis& a, const hal::DriveOut& d, float accel, float amax,
                                    float target) const noexcept {
  if (a.ds != c402::DriveState::OperationEnabled || !power()) {
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
  const bool torque = (a.ds == c402::DriveState::OperationEnabled) && power();
  if (torque && a.runaway) {
    const float dir = (a.v < 0.0F) ? -1.0F : 1.0F;  // accelerates at its limit, ignoring set-points
    a.v = clampf(a.v + (dir * amax * dt_), -vmax, vmax);
  } else if (a.ds == c402::DriveState::QuickStopActive && power() && !a.nostop) {
    a.v = toward_zero(a.v, amax * dt_);  // the drive's own quick-stop ramp (0x6085)
  } else if (a.ds == c402::DriveState::QuickStopActive && power()) {
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
  a.acc = (a.v - v_before) / dt_;
  a.held_by_drive = torque && (a.brake_released || (a.ds == c402::DriveState::QuickStopActive));
  a.torque = drive_torque(a, d, a.acc, model_.qdd_max_rad_s2[i], target);  // dynamics() replaces it when held
  a.q += a.v * dt_;
  if (a.q > model_.q_max_rad[i] || a.q < model_.q_min_rad[i]) {
    a.q = clampf(a.q, model_.q_min_rad[i], model_.q_max_rad[i]);  // mechanical hard stop
    a.v = 0.0F;
  }
}

void SimPlant::write(const hal::ProcessImageOut& out) noexcept {
  ++age_;
  switch_contactor(k_[0], out.contactor);
  switch_contactor(k_[1], two_contactors_ && out.contactor_k2);
  for (Axis& a : axis_) {
    a.enc_drift_acc_rad += a.enc_drift_rad_s * dt_;
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
    drive_state(a, out.drive[i].controlword, power());
    physics(a, i, out.drive[i]);
  }
  dynamics();
}

// @req COL-SIM-DYNAMICS
// Torque actual (0x6077) of the drives that hold the arm: what its rigid-body dynamics
// (KDL) need for this cycle's motion under gravity, against the contact's force, in per mille
// of rated torque (the description's efforts, ArmDynamics::rated_torque_nm) within the drive's
// peak, plus an injected bias.
void SimPlant::dynamics() noexcept {
  JointVec q{};
  JointVec qd{};
  JointVec qdd{};
  for (std::size_t i = 0; i < hal::kAxes; ++i) {
    q[i] = static_cast<double>(axis_[i].q);
    qd[i] = static_cast<double>(axis_[i].v);
    qdd[i] = static_cast<double>(axis_[i].acc);
  }
  contact(q);
  JointVec tau{};
  const bool ok = dyn_->torques(q, qd, qdd, contact_f_, tcp_m_, tau);
  const JointVec& rated = dyn_->rated_torque_nm();
  for (std::size_t i = 0; i < hal::kAxes; ++i) {
    Axis& a = axis_[i];
    if (!a.held_by_drive) {
      continue;
    }
    const double permille = ok ? (1000.0 * tau[i] / rated[i]) : 0.0;
    const double limit = static_cast<double>(hal::kDriveMaxTorquePermille);
    const double t = std::fmin(std::fmax(permille, -limit), limit) + static_cast<double>(a.bias);
    a.torque = static_cast<std::int16_t>(std::lround(std::fmin(std::fmax(t, -32768.0), 32767.0)));
  }
}

// The contact fault (SPEC §11 `contact F`): a surface where the TCP meets it, the first time
// it moves after the fault; from then on, while the TCP is at or past that surface (along
// the direction it was moving), the surface pushes it back with F newtons. Backing off
// behind the surface frees the TCP.
void SimPlant::contact(const JointVec& q) noexcept {
  Vec3 p{};
  dyn_->tcp(q, tcp_m_, p);
  const Vec3 v{(p[0] - tcp_prev_[0]) / static_cast<double>(dt_), (p[1] - tcp_prev_[1]) / static_cast<double>(dt_),
               (p[2] - tcp_prev_[2]) / static_cast<double>(dt_)};
  const double speed = std::sqrt((v[0] * v[0]) + (v[1] * v[1]) + (v[2] * v[2]));
  const bool moving = have_tcp_prev_ && (speed > 1.0e-3);  // 1 mm/s
  tcp_prev_ = p;
  have_tcp_prev_ = true;
  contact_f_ = Vec3{};
  if (contact_n_ <= 0.0F) {
    return;
  }
  if (!contact_on_ && moving) {
    contact_on_ = true;
    contact_p0_ = p;
    contact_u_ = {v[0] / speed, v[1] / speed, v[2] / speed};
  }
  if (!contact_on_) {
    return;
  }
  const double into = ((p[0] - contact_p0_[0]) * contact_u_[0]) + ((p[1] - contact_p0_[1]) * contact_u_[1]) +
                      ((p[2] - contact_p0_[2]) * contact_u_[2]);
  if (into >= -1.0e-6) {
    const double f = static_cast<double>(contact_n_);
    contact_f_ = {-f * contact_u_[0], -f * contact_u_[1], -f * contact_u_[2]};
  }
}

motion::Joints home_pose() noexcept { return {0.0F, 0.0F, 0.0F, 0.0F, 0.5F, 0.0F}; }

}  // namespace safestate::sim

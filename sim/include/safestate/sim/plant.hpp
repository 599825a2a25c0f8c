// The simulated plant, a HAL backend: six CiA 402 drives in CSP that walk their state
// machine one state per cycle, a main contactor (feedback 10 ms after the command), six
// holding brakes (60 ms), the safety inputs, fieldbus health, and the arm's joints.
// Fault injection as in spec/scenario-format.md. Deterministic: no clock, no randomness.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "safestate/core/cia402.hpp"
#include "safestate/controller/cell.hpp"
#include "safestate/hal/process_image.hpp"
#include "safestate/motion/motion_controller.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/sim/cell.hpp"
#include "safestate/sim/dynamics.hpp"

namespace safestate::sim {

// The holding brakes (docs/robot.md, an assumption: ABB publishes no brake torques). A
// healthy brake holds the drive's peak torque, 300 % of rated (hal::kDriveMaxTorquePermille),
// so its own drive can never turn the axis against it; `brake N weak` holds only 100 %, less
// than the brake test's default 130 %. An engaged brake slips when the drive pushes harder
// than it holds; the axis then follows the set-point at no more than kBrakeSlipRadS.
inline constexpr std::uint16_t kBrakeHoldingPermille = 3000;
inline constexpr std::uint16_t kWeakBrakeHoldingPermille = 1000;
inline constexpr float kBrakeSlipRadS = 0.2F;

// SPEC §6: the contactor's feedback follows its command after this long, the brakes'
// after this long; the drives initialise ("Not ready to switch on") for this long. The
// cell converts them into cycles (rounded up); `safestate rta` reads the same constants.
inline constexpr std::uint32_t kContactorFeedbackMs = 10;
inline constexpr std::uint32_t kBrakeFeedbackMs = 60;
inline constexpr std::uint32_t kDriveBootMs = 50;
// Without torque (Cat 0: STO, contactor open) the holding brakes stop an axis at this
// multiple of its acceleration limit (motion::RobotModel::qdd_max_rad_s2). An assumption
// of the simulated cell, as the limit itself (docs/robot.md).
inline constexpr float kBrakeStopDecelFactor = 2.0F;

// Payload (docs/stopping-data.md, an assumption of the simulated cell: ABB publishes no
// inertias). A payload adds inertia at the flange; at the rated payload (kRatedPayloadKg)
// at full extension the moved inertia of every axis is taken to be 1 + kPayloadInertiaRatio
// times the unloaded arm's, so every deceleration the drives or the brakes can give falls to
// 1 / (1 + kPayloadInertiaRatio x fraction). Fraction 0 (the default) is the unloaded arm and
// leaves the plant exactly as without this model.
inline constexpr float kPayloadInertiaRatio = 0.5F;

// SPEC §14 the load-side encoder (0x60E4) behind the gearbox: the gear's torsional
// compliance makes it lag the motor encoder by this much per rated torque (0.05 deg at
// 1000 per mille, 0.15 deg at the drives' peak: an assumption, well inside the default
// encoder_tolerance_deg of 0.5).
inline constexpr float kGearComplianceRadPerPermille = 0.05F * 3.14159265F / 180.0F / 1000.0F;
[[nodiscard]] constexpr float payload_decel_scale(float fraction) noexcept {
  return 1.0F / (1.0F + (kPayloadInertiaRatio * fraction));
}

struct PlantTiming {
  std::uint32_t contactor_cycles = kContactorFeedbackMs;  // at 1 ms
  std::uint32_t brake_cycles = kBrakeFeedbackMs;
  std::uint32_t drive_boot_cycles = kDriveBootMs;
};

// The plant's timing at a scan cycle of `cycle_us`: each time rounded up to whole cycles.
[[nodiscard]] constexpr PlantTiming plant_timing(std::uint32_t cycle_us) noexcept {
  const auto cycles = [cycle_us](std::uint32_t ms) {
    const std::uint32_t c = (ms * 1000U + cycle_us - 1U) / cycle_us;  // round up
    return (c == 0U) ? 1U : c;
  };
  return PlantTiming{cycles(kContactorFeedbackMs), cycles(kBrakeFeedbackMs), cycles(kDriveBootMs)};
}

class SimPlant final : public hal::Backend {
 public:
  SimPlant(const motion::RobotModel& model, float cycle_s, const PlantTiming& t, const motion::Joints& home) noexcept;

  core::RawInputs& inputs() noexcept { return safety_; }
  void inject(const Fault& f) noexcept;
  // The payload as a fraction of the rated one (0..1): with one, the drives follow their
  // set-points no faster than their reduced acceleration and every stop is slower.
  void set_payload_fraction(float fraction) noexcept {
    payload_ = (fraction > 0.0F) ? ((fraction < 1.0F) ? fraction : 1.0F) : 0.0F;
  }
  // The tool the arm really carries (SPEC §11: its dynamics): a point mass at the TCP
  // (tool0 frame, mm). Start-up only (rebuilds the dynamics model). The cell sets it from the
  // safety configuration: the simulated world carries what the configuration declares.
  void set_tool(float payload_kg, const std::array<float, 3>& tcp_tool0_mm) noexcept;
  // The force the contact fault pushes the TCP with this cycle (N, base frame; 0 without).
  [[nodiscard]] const Vec3& contact_force() const noexcept { return contact_f_; }

  void read(hal::ProcessImageIn& in) noexcept override;
  // The controller platform's own checks (integrity, start-up self-test): injected here
  // whatever carries the field I/O, so a cell on EtherCAT sees them as well.
  void read_platform(hal::ProcessImageIn& in) const noexcept {
    in.integrity_ok = in.integrity_ok && integrity_ok_;
    in.self_test_ok = in.self_test_ok && self_test_ok_;
  }
  // Applies the outputs and advances the physics by one cycle.
  void write(const hal::ProcessImageOut& out) noexcept override;
  // SPEC §14: K2 in series with K1 (ProcessImageOut::contactor_k2), each with its auxiliary
  // contact; power flows only while both are closed. Off: one contactor (K1). Start-up only.
  void set_two_contactors(bool on) noexcept { two_contactors_ = on; }
  [[nodiscard]] bool two_contactors() const noexcept { return two_contactors_; }
  [[nodiscard]] bool k2_closed() const noexcept { return k_[1].closed; }
  [[nodiscard]] bool k1_closed() const noexcept { return k_[0].closed; }
  // Power reaches the drives (K1 closed, and K2 with two contactors).
  [[nodiscard]] bool powered() const noexcept { return power(); }

  [[nodiscard]] std::uint16_t controlword(std::size_t i) const noexcept { return axis_[i].last_cw; }
  // Injected causes as bits: per axis i, bit 4i fault, 4i+1 runaway, 4i+2 nostop,
  // 4i+3 brake stuck; bit 24 fieldbus lost, 25 contactor (K1) stuck open, 26 K1 welded,
  // 27 integrity failed, 28 self-test failed, 29 K2 stuck open, 30 K2 welded; per axis i,
  // bit 32+4i brake stuck released, 33+4i raw statusword, 34+4i slow enable, 35+4i brake
  // weak, 56+i an encoder fault.
  [[nodiscard]] std::uint64_t injected() const noexcept {
    std::uint64_t m = 0;
    const auto b = [](bool v, std::size_t at) { return static_cast<std::uint64_t>(v ? 1U : 0U) << at; };
    for (std::size_t i = 0; i < hal::kAxes; ++i) {
      const Axis& a = axis_[i];
      m |= b(a.fault_cause, 4U * i) | b(a.runaway, 4U * i + 1U) | b(a.nostop, 4U * i + 2U) |
           b(a.brake_stuck, 4U * i + 3U);
      m |= b(a.brake_stuck_released, 32U + 4U * i) | b(a.sw_override, 33U + 4U * i) |
           b(a.slow_cycles != 0U, 34U + 4U * i) | b(a.brake_weak, 35U + 4U * i);
    }
    m |= b(!fieldbus_ok_, 24U) | b(k_[0].stuck_open, 25U) | b(k_[0].welded, 26U) | b(!integrity_ok_, 27U) |
         b(!self_test_ok_, 28U) | b(k_[1].stuck_open, 29U) | b(k_[1].welded, 30U);
    for (std::size_t i = 0; i < hal::kAxes; ++i) {  // SPEC §14: an encoder fault of axis i
      const Axis& a = axis_[i];
      m |= b(a.enc_stuck || a.enc_offset_rad != 0.0F || a.enc_drift_rad_s != 0.0F, 56U + i);
    }
    return m;
  }

 private:
  // The plant's side of the HAL integrity and self-test inputs.
  bool integrity_ok_ = true;
  bool self_test_ok_ = true;

  // A contactor with its auxiliary contact (feedback kContactorFeedbackMs after the command).
  struct Contactor {
    bool cmd = false;
    std::uint32_t timer = 0;
    bool closed = false;
    bool stuck_open = false;
    bool welded = false;
  };
  void switch_contactor(Contactor& k, bool cmd) const noexcept;
  [[nodiscard]] bool power() const noexcept { return k_[0].closed && (!two_contactors_ || k_[1].closed); }
  [[nodiscard]] float load_position(std::size_t i) const noexcept;

  struct Axis {
    core::cia402::DriveState ds = core::cia402::DriveState::NotReadyToSwitchOn;
    std::uint16_t last_cw = 0;
    bool fault_cause = false;  // injected: the drive is (or goes) to Fault and cannot be reset
    bool runaway = false;
    bool nostop = false;
    float q = 0.0F;
    float v = 0.0F;
    bool brake_cmd = false;
    std::uint32_t brake_timer = 0;
    bool brake_released = false;
    bool brake_stuck = false;
    bool brake_stuck_released = false;
    bool brake_weak = false;  // holds kWeakBrakeHoldingPermille instead of kBrakeHoldingPermille
    bool sw_override = false;     // reports sw_value instead of its state's statusword
    std::uint16_t sw_value = 0;
    std::uint32_t slow_cycles = 0;  // 0: one enabling step per cycle
    std::uint32_t slow_timer = 0;
    std::int16_t torque = 0;  // 0x6077, per mille of rated: see physics()
    std::int16_t bias = 0;    // drive_torque_bias: reported on top of the torque, per mille
    float acc = 0.0F;         // this cycle's acceleration, rad/s^2
    bool held_by_drive = false;  // powered with its brake released: torque from the dynamics
    // SPEC §14 the load-side encoder's faults: stuck at enc_stuck_rad, an offset, a drift
    // (enc_drift_acc_rad so far).
    bool enc_stuck = false;
    float enc_stuck_rad = 0.0F;
    float enc_offset_rad = 0.0F;
    float enc_drift_rad_s = 0.0F;
    float enc_drift_acc_rad = 0.0F;
  };
  void dynamics() noexcept;
  void contact(const JointVec& q) noexcept;
  [[nodiscard]] std::uint32_t cycles_of_ms(std::uint16_t ms) const noexcept;
  void drive_state(Axis& a, std::uint16_t cw, bool power) noexcept;
  void physics(Axis& a, std::size_t i, const hal::DriveOut& d) noexcept;
  [[nodiscard]] std::int16_t drive_torque(const Axis& a, const hal::DriveOut& d, float accel, float amax,
                                          float target) const noexcept;

  const motion::RobotModel& model_;
  float dt_;
  PlantTiming timing_;
  core::RawInputs safety_{};
  std::array<Axis, hal::kAxes> axis_{};
  std::array<Contactor, 2> k_{};  // K1, K2 (SPEC §14)
  bool two_contactors_ = false;
  bool fieldbus_ok_ = true;
  std::uint32_t age_ = 0;
  float payload_ = 0.0F;  // fraction of the rated payload
  // SPEC §11: the arm's rigid-body dynamics (KDL), shared by the copies of a plant (the
  // checker copies cells by the thousand; building KDL's chain per copy would dominate).
  // Its results do not depend on earlier calls, but it works in scratch arrays of its own:
  // copies of a plant must step in the thread of their original (they do: the checker is
  // single-threaded, every other user holds one plant).
  std::shared_ptr<ArmDynamics> dyn_;
  Vec3 tcp_m_{};             // the TCP in tool0, m
  float contact_n_ = 0.0F;   // the contact fault's force, 0: none
  bool contact_on_ = false;  // the surface is placed (the TCP moved once since the fault)
  Vec3 contact_p0_{};        // where the TCP met it, m
  Vec3 contact_u_{};         // the direction the TCP was moving then
  Vec3 tcp_prev_{};
  bool have_tcp_prev_ = false;
  Vec3 contact_f_{};
};

// The demo program of the simulated cell: a pick-and-place round of joint waypoints.
using controller::demo_program;  // controller/cell.hpp
// Where the simulated arm stands at power-up.
motion::Joints home_pose() noexcept;

}  // namespace safestate::sim

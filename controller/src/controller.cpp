#include "safestate/controller/controller.hpp"

namespace safestate::controller {

motion::MotionConfig Controller::motion_config(const core::Config& cfg) noexcept {
  motion::MotionConfig m{};
  m.cycle_s = static_cast<float>(cfg.cycle_us) * 1.0e-6F;
  m.t1_limit_mm_s = cfg.t1_speed_limit_mm_s;
  return m;
}

Controller::Controller(const core::Config& cfg, const motion::RobotModel& model) noexcept
    : cycle_us_(cfg.cycle_us), model_(model), supervisor_(core::to_timing(cfg)), motion_(model, motion_config(cfg)) {
  // The core's own kinematics of this arm from the start (T1 speed); configure_limits sets
  // it again with the limits' TCP, as it does the motion layer's.
  supervisor_.configure_arm(arm_geometry(model_), model_.tcp_offset_mm);
}

core::ArmGeometry Controller::arm_geometry(const motion::RobotModel& model) noexcept {
  core::ArmGeometry g{};
  const auto frame = [](const motion::FixedFrame& f) {
    core::ArmFrame a{};
    a.origin_mm = f.xyz_mm;
    for (std::size_t r = 0; r < 3U; ++r) {
      a.rotation[r] = f.R[r];
    }
    return a;
  };
  for (std::size_t k = 0; k < core::kAxes; ++k) {
    g.joint[k].frame = frame(model.joints[k].origin);
    g.joint[k].axis = model.joints[k].axis;
  }
  g.flange = frame(model.flange);
  return g;
}

void Controller::configure_limits(const core::SafetyLimits& limits, bool validated) noexcept {
  supervisor_.configure_limits(limits, arm_geometry(model_), cycle_us_, validated);
  motion_.set_limits(limits);
}

// @req CYC-ORDER CYC-DETERMINISM
std::size_t Controller::step(const hal::ProcessImageIn& in, const core::Command* cmds, std::size_t n,
                             hal::ProcessImageOut& out) noexcept {
  feedback_.drive = in.drive;
  feedback_.contactor_closed = in.contactor_closed;
  feedback_.two_contactors = in.two_contactors;
  feedback_.k2_closed = in.k2_closed;
  feedback_.load_encoders = in.load_encoders;
  feedback_.brake_released = in.brake_released;
  feedback_.fieldbus_ok = in.fieldbus_ok;
  feedback_.fieldbus_subdevice = in.fieldbus_subdevice;
  feedback_.fieldbus_silent = in.fieldbus_silent;
  feedback_.fieldbus_boot_failed = in.fieldbus_boot_failed;
  feedback_.integrity_ok = in.integrity_ok;
  feedback_.self_test_ok = in.self_test_ok;
  feedback_.stale = in.stale;
  feedback_.sample_clock = in.sample_clock;
  feedback_.sample_span = in.sample_span;
  motion_.measure(in.drive, feedback_, in.stale, in.sample_clock ? static_cast<std::int32_t>(in.sample_span) : -1);
  const std::size_t taken = supervisor_.step(in.safety, feedback_, cmds, n, status_);
  motion_.step(status_, in.drive, out.drive);
  out.contactor = status_.contactor;
  // SPEC §14: a channel alone on a cell with K2 drives both contactors (in a pair,
  // combine_outputs gives K2 to channel B).
  out.contactor_k2 = status_.contactor;
  out.brakes_release = status_.brakes_release;
  out.brake_test_axis = status_.brake_test_axis;
  out.reset_lamp = status_.reset_lamp;
  out.reduced_active = status_.safety.reduced;
  return taken;
}

}  // namespace safestate::controller

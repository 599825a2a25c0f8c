// One scan cycle of the robot controller (DESIGN.md "the cycle is the spine"):
//   process image in -> motion.measure -> supervisor.step -> motion.step -> image out.
// Composes core/ and motion/ over the HAL's process image; no heap, no OS, so the same
// cycle runs in the simulator, in the Linux real-time loop and on a microcontroller.
#pragma once

#include <cstddef>

#include "safestate/core/config.hpp"
#include "safestate/core/supervisor.hpp"
#include "safestate/hal/process_image.hpp"
#include "safestate/motion/motion_controller.hpp"

namespace safestate::controller {

class Controller {
 public:
  // `cfg` must have passed core::validate().
  Controller(const core::Config& cfg, const motion::RobotModel& model) noexcept;

  void load_program(const motion::Waypoint* points, std::uint8_t count) noexcept {
    motion_.load_program(points, count);
  }

  // SPEC §10, before the first cycle: the safe limits the supervisor monitors (on its own
  // kinematics of `model`) and the motion layer plans within, and whether the event log
  // holds a confirmation of their checksum.
  void configure_limits(const core::SafetyLimits& limits, bool validated) noexcept;
  // SPEC §12, before the first cycle: the event log's last brake test.
  void configure_brake_test(const core::BrakeTestHistory& history) noexcept {
    supervisor_.configure_brake_test(history);
  }

  // The robot's DH table in the core's own form.
  static core::ArmGeometry arm_geometry(const motion::RobotModel& model) noexcept;

  // Runs one cycle; takes at most max_commands_per_cycle of `cmds` and returns how many.
  std::size_t step(const hal::ProcessImageIn& in, const core::Command* cmds, std::size_t n,
                   hal::ProcessImageOut& out) noexcept;

  [[nodiscard]] const core::SupervisorOut& status() const noexcept { return status_; }
  [[nodiscard]] const core::Feedback& feedback() const noexcept { return feedback_; }
  // SPEC §14: the cross-check's verdict on the other channel, for the next step.
  void set_cross_check(const core::ChannelCheck& c) noexcept { feedback_.cross = c; }
  // Issue 37: this cycle's check of the black channel's connections (SafetyLinks), for this step.
  void set_link_check(const core::LinkCheck& c) noexcept { feedback_.link = c; }
  [[nodiscard]] const core::Supervisor& supervisor() const noexcept { return supervisor_; }
  [[nodiscard]] const motion::MotionController& motion() const noexcept { return motion_; }

 private:
  static motion::MotionConfig motion_config(const core::Config& cfg) noexcept;

  std::uint32_t cycle_us_;
  motion::RobotModel model_;
  core::Supervisor supervisor_;
  motion::MotionController motion_;
  core::Feedback feedback_{};
  core::SupervisorOut status_{};
};

}  // namespace safestate::controller

// A minimal plant double for the core's tests and fuzzers: contactor and brakes with
// their feedback delays, drives walking CiA 402, velocities the tests set and the positions
// they integrate to. Obviously right rather than realistic; the realistic simulated cell is
// sim/.
#pragma once

#include <array>
#include <cmath>

#include "safestate/core/arm.hpp"
#include "safestate/core/cia402.hpp"
#include "safestate/core/supervisor.hpp"

namespace safestate::test {

using namespace safestate::core;
namespace c402 = safestate::core::cia402;

// The arm the plant's joints belong to, for the core's own kinematics (T1 speed): the
// IRB 120 as the DH table it was before issue 38 (docs/robot.md "DH convention"), no tool.
// Written here in the core's terms so that the core's tests need no robot description.
inline ArmGeometry plant_arm() {
  constexpr float kPi = 3.14159265358979F;
  return arm_from_dh({{
      {0.0F, -kPi / 2.0F, 290.0F, 0.0F},
      {270.0F, 0.0F, 0.0F, -kPi / 2.0F},
      {70.0F, -kPi / 2.0F, 0.0F, 0.0F},
      {0.0F, kPi / 2.0F, 302.0F, 0.0F},
      {0.0F, -kPi / 2.0F, 0.0F, 0.0F},
      {0.0F, 0.0F, 72.0F, kPi},
  }});
}

// Joint 1's speed (rad/s) that moves the fastest of the T1 points (link origins, the TCP)
// at `mm_s` with the plant's arm at `q` (the core's kinematics, no tool): the point
// farthest from axis 1 (vertical through the base).
inline float plant_axis1_for(float mm_s, const JointArray& q = JointArray{}) {
  ArmPose p{};
  arm_forward(plant_arm(), q, Vec3{}, p);
  float r = std::hypot(p.tcp[0], p.tcp[1]);
  for (std::size_t k = 1; k < kArmFrames; ++k) {
    r = std::fmax(r, std::hypot(p.origin[k][0], p.origin[k][1]));
  }
  return mm_s / r;
}

struct Plant {
  int contactor_delay = 10;  // SPEC §6: feedback 10 ms after the command
  int brake_delay = 60;      // SPEC §6: 60 ms
  bool contactor_stuck_open = false;
  std::array<bool, kAxes> brake_stuck{};           // never releases
  bool brake_stuck_released = false;                // feedback never reports engaged
  std::array<bool, kAxes> brake_welded_released{};  // this brake's feedback: released, always
  bool contactor_welded = false;                    // feedback closed, always
  std::array<bool, kAxes> drive_fault{};       // cause present: drive reports Fault
  std::array<bool, kAxes> drive_nostop{};      // ignores stop ramps
  std::array<c402::DriveState, kAxes> ds{};
  std::array<float, kAxes> vel{};              // rad/s, set by tests while moving
  std::array<float, kAxes> pos{};              // rad, integrated from vel every cycle
  float cycle_s = 0.001F;                      // the cycle the positions are integrated over
  // false: the positions stay where the test puts them, whatever the velocities (a test of
  // the safe limits' speeds at one pose: they read the drives' velocities).
  bool integrate = true;
  float decel = 0.05F;                         // rad/s per cycle in a stop ramp
  int contactor_count = 0;
  bool contactor_fb = false;
  std::array<int, kAxes> brake_count{};
  std::array<bool, kAxes> brake_fb{};
  bool fieldbus = true;
  bool program_loaded = true;
  bool program_finished = false;
  // What the motion layer reports as the fastest TCP / link-origin speed (for motion and the
  // status). The core does not use it: its T1 speed comes from the positions.
  float motion_speed = 0.0F;
  int boot_cycles = 20;      // drives answer "Not ready" then "Switch on disabled"
  int age = 0;

  Plant() { ds.fill(c402::DriveState::NotReadyToSwitchOn); }

  void fill(Feedback& fb) const {
    for (std::size_t i = 0; i < kAxes; ++i) {
      fb.drive[i].statusword = c402::statusword_of(drive_fault[i] ? c402::DriveState::Fault : ds[i]);
      fb.drive[i].velocity_rad_s = vel[i];
      fb.drive[i].position_rad = pos[i];
      fb.brake_released[i] = brake_fb[i];
    }
    fb.contactor_closed = contactor_fb;
    fb.fieldbus_ok = fieldbus;
    fb.program_loaded = program_loaded;
    fb.program_finished = program_finished;
    fb.max_point_speed_mm_s = motion_speed;
    fb.tcp_speed_mm_s = motion_speed;
    fb.fastest_axis = 1;
  }

  void follow(const SupervisorOut& o) {
    ++age;
    contactor_count = (o.contactor && !contactor_stuck_open) ? contactor_count + 1 : 0;
    contactor_fb = (contactor_count >= contactor_delay) || contactor_welded;
    for (std::size_t i = 0; i < kAxes; ++i) {
      const bool release = o.brakes_release && (o.brake_test_axis != i + 1U);  // SPEC §12: one engaged by the test
      brake_count[i] = (release && !brake_stuck[i]) ? brake_count[i] + 1 : 0;
      brake_fb[i] = (brake_count[i] >= brake_delay) || (brake_stuck_released && brake_fb[i]) || brake_welded_released[i];
      auto& s = ds[i];
      if (age < boot_cycles) {
        continue;
      }
      if (drive_fault[i]) {
        s = c402::DriveState::Fault;
        continue;
      }
      if (s == c402::DriveState::Fault || s == c402::DriveState::NotReadyToSwitchOn) {
        s = (s == c402::DriveState::Fault && !o.motion.fault_reset) ? s : c402::DriveState::SwitchOnDisabled;
        continue;
      }
      if (!o.drives_enable) {
        s = c402::DriveState::SwitchOnDisabled;  // safe torque off
      } else if (s == c402::DriveState::SwitchOnDisabled) {
        s = c402::DriveState::ReadyToSwitchOn;
      } else if (s == c402::DriveState::ReadyToSwitchOn) {
        s = c402::DriveState::SwitchedOn;
      } else if (s == c402::DriveState::SwitchedOn) {
        s = c402::DriveState::OperationEnabled;
      }
      const bool ramping = o.motion.mode == MotionMode::QuickStop || o.motion.mode == MotionMode::Ramp2 ||
                           o.motion.mode == MotionMode::Hold;
      if (!o.drives_enable && !drive_nostop[i]) {
        vel[i] = 0.0F;  // brakes and no torque: the bench arm stops at once
      } else if (ramping && !drive_nostop[i]) {
        vel[i] = (vel[i] > decel) ? vel[i] - decel : ((vel[i] < -decel) ? vel[i] + decel : 0.0F);
      }
    }
    for (std::size_t i = 0; (i < kAxes) && integrate; ++i) {
      pos[i] += vel[i] * cycle_s;  // the next sample (velocities of a booting plant too)
    }
  }
};

}  // namespace safestate::test

// A minimal plant double for the core's tests and fuzzers: contactor and brakes with
// their feedback delays, drives walking CiA 402, velocities the tests set. Obviously
// right rather than realistic; the realistic simulated cell is sim/.
#pragma once

#include <array>

#include "safestate/core/cia402.hpp"
#include "safestate/core/supervisor.hpp"

namespace safestate::test {

using namespace safestate::core;
namespace c402 = safestate::core::cia402;

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
  float decel = 0.05F;                         // rad/s per cycle in a stop ramp
  int contactor_count = 0;
  bool contactor_fb = false;
  std::array<int, kAxes> brake_count{};
  std::array<bool, kAxes> brake_fb{};
  bool fieldbus = true;
  bool program_loaded = true;
  bool program_finished = false;
  float point_speed = 0.0F;  // max TCP / link-origin speed the motion layer reports
  int boot_cycles = 20;      // drives answer "Not ready" then "Switch on disabled"
  int age = 0;

  Plant() { ds.fill(c402::DriveState::NotReadyToSwitchOn); }

  void fill(Feedback& fb) const {
    for (std::size_t i = 0; i < kAxes; ++i) {
      fb.drive[i].statusword = c402::statusword_of(drive_fault[i] ? c402::DriveState::Fault : ds[i]);
      fb.drive[i].velocity_rad_s = vel[i];
      fb.brake_released[i] = brake_fb[i];
    }
    fb.contactor_closed = contactor_fb;
    fb.fieldbus_ok = fieldbus;
    fb.program_loaded = program_loaded;
    fb.program_finished = program_finished;
    fb.max_point_speed_mm_s = point_speed;
    fb.tcp_speed_mm_s = point_speed;
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
  }
};

}  // namespace safestate::test

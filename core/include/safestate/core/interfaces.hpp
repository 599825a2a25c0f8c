// The plain data the core exchanges with the layers around it, once per cycle:
//  - Feedback: what the HAL read this cycle (drives, contactor, brakes, fieldbus, when
//    the positions were sampled) plus what the motion layer measured (TCP and link-origin
//    speeds, for motion and the status: the core derives its own) and reports about its
//    program;
//  - MotionRequest: what motion is allowed this cycle and how to stop.
// The motion layer and any HAL backend implement against these structs only.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/types.hpp"

namespace safestate::core {

struct DriveFeedback {
  std::uint16_t statusword = 0;  // CiA 402 0x6041
  float position_rad = 0.0F;     // measured joint position
  float velocity_rad_s = 0.0F;   // measured joint velocity
  bool online = true;            // the drive answers on the fieldbus
  std::int16_t torque_permille = 0;  // CiA 402 0x6077 torque actual
  // SPEC §14: the load-side encoder (CiA 402 0x60E4, additional position actual value), as a
  // joint position; read only while Feedback::load_encoders.
  float load_position_rad = 0.0F;
};

// SPEC §14: this channel's cross-check against the other channel, as the controller's
// CrossCheck found it after the previous cycle. partner none: a one-channel cell.
struct ChannelCheck {
  Channel partner = Channel::none;
  bool mismatch = false;
  CrossField field = CrossField::none;  // the first that differed
  bool lost = false;
};

// Issue 37, the black channel: the state of this channel's safety connections (the controller's
// SafetyLinks). configured: the backend carries connections (else nothing here applies);
// up: every one of them has delivered valid data in its session; fault: one failed its check
// (the first found: its connection id and error). While a connection is not up or failed its
// data are the safe values (contacts open, E-stop pressed).
struct LinkCheck {
  bool configured = false;
  bool up = false;
  bool fault = false;
  Channel channel = Channel::none;  // the channel hosting the connection named
  std::uint16_t connection = 0;     // its id (0xA002, ...)
  LinkError error = LinkError::none;
};

struct Feedback {
  std::array<DriveFeedback, kAxes> drive{};
  bool contactor_closed = false;                 // main contactor (K1) auxiliary contact
  // SPEC §14: a second contactor K2 in series (channel B's), with its own auxiliary contact.
  // Either one open removes power; both must be closed for power. One-contactor cell: false.
  bool two_contactors = false;
  bool k2_closed = false;
  // SPEC §14: a second (load-side) encoder per axis, DriveFeedback::load_position_rad.
  bool load_encoders = false;
  ChannelCheck cross{};
  LinkCheck link{};  // issue 37: the black channel's connections of this channel
  std::array<bool, kAxes> brake_released{};      // brake feedback: true = released
  bool fieldbus_ok = true;                       // cyclic data valid this cycle
  // Bus position (1-based) of the first fieldbus subdevice at fault, 0 = the bus as a
  // whole (or not known): named in FIELDBUS_LOST and BOOT_FAILED (ISO 13849-1 diagnostics).
  std::uint8_t fieldbus_subdevice = 0;
  // No frame comes back at all: every subdevice from fieldbus_subdevice on is silent
  // (on a line, the break is at or before it).
  bool fieldbus_silent = false;
  // The fieldbus cannot come up as configured (a wrong, missing or unexpected subdevice,
  // no interface): BOOT fails at once rather than at its timeout, waiting would not help.
  bool fieldbus_boot_failed = false;
  bool integrity_ok = true;                      // external integrity checks (HAL, memory)
  bool self_test_ok = true;                      // the platform's start-up self-test (RAM, watchdog)
  // When the measured positions were sampled (hal::ProcessImageIn, copied as read): `stale`,
  // no fresh sample this cycle (the positions are the last ones held); with `sample_clock`
  // (the drives sample at SYNC0 and the frame says which pulse) `sample_span` is the cycles
  // since the previous sample as the drives took them, 0 when it is that same sample again.
  // The core's T1 speed monitor differentiates its own positions over this span.
  bool stale = false;
  bool sample_clock = false;
  std::uint16_t sample_span = 0;
  // From the motion layer, computed from measured joint positions (forward kinematics), for
  // motion itself and the status; the core's monitors do not use them (T1 speed: its own):
  float tcp_speed_mm_s = 0.0F;
  float max_point_speed_mm_s = 0.0F;  // max over the TCP and every link-frame origin
  std::uint8_t fastest_axis = 0;      // 1..6: link whose origin (or the TCP: 6) is fastest
  // Axis (1..6) whose measured position left its set-point by more than the following-
  // error window while the motion layer was commanding it (0 = none): a drive that does
  // not follow is a drive fault, however healthy its statusword looks.
  std::uint8_t following_error_axis = 0;
  bool program_loaded = true;
  bool program_finished = false;  // the running program reached its last waypoint
  // The loaded program's waypoints and the paths between them keep inside the safe limits
  // of SPEC §10 less the planning margins (checked by the motion layer when the program or
  // the limits change): `start` is OUTSIDE_LIMITS otherwise.
  bool program_within_limits = true;
  // SPEC §11 collision back-off: the motion layer was asked to back off (MotionRequest::
  // back_off) and has not finished: the stop is not at its end yet, however slow the arm.
  bool backing_off = false;
};

// What motion the core allows this cycle. The motion layer must not move otherwise.
enum class MotionMode : std::uint8_t {
  Track,      // power off or arming: set-points follow measured positions, no motion
  Hold,       // powered, holding the set-point (equal to the measured position on entry)
  Jog,        // per-axis jog (MANUAL_JOGGING)
  Program,    // run the program (AUTO_RUNNING / MANUAL_RUNNING)
  QuickStop,  // Cat 1: ramp every axis down on the quick-stop ramp
  Ramp2,      // Cat 2: ramp down, then hold with drives enabled
};

// One-cycle pulses for the program executor.
enum class ProgramCmd : std::uint8_t { None, Start, Resume, Abort };

struct JogTarget {
  std::uint8_t axis = 0;   // 1..6
  std::int8_t dir = 0;     // +1 / -1
  std::uint8_t speed = 0;  // percent
};

// SPEC §12 brake test, for the axis under test: its set-point is moved by dir x offset and
// its drive's torque limited (CiA 402 0x6072, per mille of rated), so that the CSP drive
// pushes the engaged brake with the test torque. axis 0: no test.
struct BrakeTestRequest {
  std::uint8_t axis = 0;   // 1..6
  std::int8_t dir = 0;     // +1 / -1 while pushing, 0 otherwise
  float offset_rad = 0.0F;
  std::uint16_t torque_permille = 0;  // 0: not limited by the test
};

struct MotionRequest {
  MotionMode mode = MotionMode::Track;
  ProgramCmd program = ProgramCmd::None;
  JogTarget jog{};
  bool t1_limit = false;     // limit TCP and link origins to the T1 speed
  bool discard = false;      // a stop began: drop every queued motion now
  bool fault_reset = false;  // give faulted drives a CiA 402 fault reset (bit 7 edge)
  // SPEC §10 reduced mode: bring the TCP to the reduced limit within reduced.ramp_ms and
  // keep it there while this is set.
  bool reduced = false;
  // The reduced TCP limit in force while `reduced` (mm/s): reduced.tcp_max_speed_mm_s, or
  // lower with SPEC §11's outer field (collaborative.reduced_speed_mm_s, v_pfl).
  float reduced_limit_mm_s = 0.0F;
  // SPEC §11 speed and separation monitoring: the TCP stays at or below this (mm/s): v_allowed
  // as planned (core::ssm_planning_speed_mm_s); at 0 the program holds. Negative: SSM does
  // not act.
  float v_allowed_mm_s = -1.0F;
  // SPEC §10 recovery (T1, a limit violated): move only in ways that do not make the
  // violation worse.
  bool recovery = false;
  // SPEC §12: the axis under test (its following error is not watched: it is meant to lag).
  BrakeTestRequest brake_test{};
  // SPEC §11 rule 8: in this Cat 2 stop, once stopped, back off 10 mm along the path the TCP
  // came at <= 100 mm/s, then hold (Feedback::backing_off until done).
  bool back_off = false;
};

}  // namespace safestate::core

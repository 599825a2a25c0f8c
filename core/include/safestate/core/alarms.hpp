// The alarm table of SPEC §7: one row per alarm, in code, from which docs/alarms.md is
// generated. An alarm names its cause (input and channel, axis, arming step) so that
// every stop, lockout and refusal explains itself.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/types.hpp"

namespace safestate::core {

enum class AlarmId : std::uint8_t {
  ESTOP_DISCREPANCY,
  GATE_DISCREPANCY,
  ENABLE_DISCREPANCY,
  FIELDBUS_LOST,
  INTEGRITY_FAULT,
  BOOT_FAILED,
  PROTECTIVE_STOP,
  DRIVE_FAULT,
  ARMING_TIMEOUT,
  T1_SPEED_EXCEEDED,
  STOP_TIME_EXCEEDED,
  ESTOP_PRESSED,
  MODE_SELECTOR_INVALID,
  RESET_BUTTON_STUCK,
  MODE_CHANGED,
  ENABLING_PANIC,
  JOG_LINK_LOST,
  // SPEC §7 feedback monitoring (ISO 13849-1 external device monitoring); appended so
  // that the bit of every older alarm keeps its place (bridge, event log, HMI).
  CONTACTOR_WELDED,
  BRAKE_NOT_ENGAGED,
  // SPEC §10 safe limits, appended likewise.
  JOINT_LIMIT,
  ZONE_VIOLATION,
  ORIENTATION_LIMIT,
  SPEED_LIMIT,
  CONFIG_NOT_VALIDATED,
  REDUCED_SPEED,
  // SPEC §11 collaborative operation, appended likewise.
  FIELD_DISCREPANCY,
  SEPARATION_VIOLATED,
  PERSON_IN_FIELD,
  // SPEC §12 brake test, appended likewise.
  BRAKE_TEST_DUE,
  BRAKE_TEST_FAILED,
  // SPEC §11 collision detection (rule 8), appended likewise.
  COLLISION,
  // SPEC §14 two channels, appended likewise (the mask is 64 bits wide from here).
  CHANNEL_MISMATCH,
  CHANNEL_LOST,
  ENCODER_DISCREPANCY,
  // Issue 37, the black channel (docs/black-channel.md), appended likewise.
  SAFETY_LINK_FAULT,
};
inline constexpr std::size_t kAlarmCount = 35;

enum class Severity : std::uint8_t { info, warning, fault, lockout };

// How long an alarm stays active (SPEC §7 "active" column).
enum class Latch : std::uint8_t {
  power_cycle,  // lockout: until power cycle
  reset,        // latched until a `reset` succeeds
  condition,    // while the condition lasts
  until_ok,     // from the event until the next command answered OK
};

struct AlarmInfo {
  AlarmId id;
  const char* name;
  std::uint16_t number;
  Severity severity;
  Latch latch;
  const char* text;
  const char* remedy;
};

// clang-format off
// @req AL-TABLE AL-LIFETIME
inline constexpr std::array<AlarmInfo, kAlarmCount> kAlarms{{
  {AlarmId::ESTOP_DISCREPANCY, "ESTOP_DISCREPANCY", 101, Severity::lockout, Latch::power_cycle,
   "The two E-stop channels disagreed for longer than the discrepancy time.",
   "Check the E-stop wiring and contacts of the named channel, then power-cycle the controller."},
  {AlarmId::GATE_DISCREPANCY, "GATE_DISCREPANCY", 102, Severity::lockout, Latch::power_cycle,
   "The two guard / light-curtain channels disagreed for longer than the discrepancy time.",
   "Check the guard switch or light curtain and its wiring on the named channel, then power-cycle."},
  {AlarmId::ENABLE_DISCREPANCY, "ENABLE_DISCREPANCY", 103, Severity::lockout, Latch::power_cycle,
   "The two centre contacts of the enabling device disagreed for longer than the discrepancy time.",
   "Replace or repair the enabling device and its cable, then power-cycle."},
  {AlarmId::FIELDBUS_LOST, "FIELDBUS_LOST", 104, Severity::lockout, Latch::power_cycle,
   "Cyclic process data from the drives stopped being valid.",
   "Check the fieldbus cable, drive power and the real-time host, then power-cycle."},
  {AlarmId::INTEGRITY_FAULT, "INTEGRITY_FAULT", 105, Severity::lockout, Latch::power_cycle,
   "An internal consistency check of the safety supervisor failed.",
   "Record the event history, power-cycle, and report it: the controller must be inspected."},
  {AlarmId::BOOT_FAILED, "BOOT_FAILED", 106, Severity::lockout, Latch::power_cycle,
   "Start-up self-test failed, or the fieldbus and drives did not answer in time.",
   "Check that every drive is powered and on the bus, then power-cycle."},
  {AlarmId::PROTECTIVE_STOP, "PROTECTIVE_STOP", 201, Severity::fault, Latch::reset,
   "The guard opened (or the light curtain was interrupted) while the mode was AUTO.",
   "Leave the cell, close the guard, then reset."},
  {AlarmId::DRIVE_FAULT, "DRIVE_FAULT", 202, Severity::fault, Latch::reset,
   "A drive reported a fault, an unknown status, or left Operation enabled on its own.",
   "Read the drive's own fault code, remove the cause, then reset (this acknowledges the drive)."},
  {AlarmId::ARMING_TIMEOUT, "ARMING_TIMEOUT", 203, Severity::fault, Latch::reset,
   "Power-up did not complete the named step in time (contactor, drives or brakes).",
   "Check the feedback of the named step (contactor, drive enable or brake release), then reset."},
  {AlarmId::T1_SPEED_EXCEEDED, "T1_SPEED_EXCEEDED", 204, Severity::fault, Latch::reset,
   "In T1, the measured speed of the TCP or a link origin exceeded the reduced-speed limit.",
   "Check the drive of the named axis and the motion limits, then reset."},
  {AlarmId::STOP_TIME_EXCEEDED, "STOP_TIME_EXCEEDED", 205, Severity::fault, Latch::reset,
   "A controlled stop did not reach standstill within the maximum stop time; power was cut.",
   "Check the named axis' drive, brake and load, then reset."},
  {AlarmId::ESTOP_PRESSED, "ESTOP_PRESSED", 301, Severity::info, Latch::condition,
   "An emergency stop is pressed.",
   "Remove the hazard, release the E-stop, then reset."},
  {AlarmId::MODE_SELECTOR_INVALID, "MODE_SELECTOR_INVALID", 302, Severity::warning, Latch::condition,
   "The mode selector has no position (or several) selected.",
   "Turn the key fully to AUTO, T1 or T2."},
  {AlarmId::RESET_BUTTON_STUCK, "RESET_BUTTON_STUCK", 303, Severity::info, Latch::condition,
   "The reset button has been held longer than 5 s; this press is not a reset.",
   "Release the reset button; press and release it once to reset."},
  {AlarmId::MODE_CHANGED, "MODE_CHANGED", 401, Severity::info, Latch::until_ok,
   "The operating mode changed while the servos were on; the robot was stopped.",
   "Confirm the selected mode, then switch the servos on again."},
  {AlarmId::ENABLING_PANIC, "ENABLING_PANIC", 402, Severity::info, Latch::until_ok,
   "The enabling device was squeezed to the panic position.",
   "Release the enabling device fully, then hold it at the centre position again."},
  {AlarmId::JOG_LINK_LOST, "JOG_LINK_LOST", 403, Severity::info, Latch::until_ok,
   "Jog keep-alive messages stopped arriving; the jog was stopped.",
   "Check the pendant connection, then jog again."},
  {AlarmId::CONTACTOR_WELDED, "CONTACTOR_WELDED", 107, Severity::lockout, Latch::power_cycle,
   "The main contactor was commanded open but its feedback contact still said closed 100 ms later: "
   "power cannot be removed by this path.",
   "Isolate the cell at the main switch, replace the main contactor (welded contacts), then power-cycle."},
  {AlarmId::BRAKE_NOT_ENGAGED, "BRAKE_NOT_ENGAGED", 206, Severity::fault, Latch::reset,
   "A holding brake was commanded engaged but its feedback still said released 300 ms later; power was cut.",
   "Secure the named axis against falling, check its brake and brake feedback, then reset."},
  {AlarmId::JOINT_LIMIT, "JOINT_LIMIT", 207, Severity::fault, Latch::reset,
   "The named joint left the range of the safety configuration; power was cut.",
   "Reset, then in T1 jog the named axis back into its range (only motion back toward it is allowed)."},
  {AlarmId::ZONE_VIOLATION, "ZONE_VIOLATION", 208, Severity::fault, Latch::reset,
   "The tool sphere or a link of the arm left a keep-in zone or entered a keep-out zone; power was cut.",
   "Reset, then in T1 jog the arm out of the named zone (only motion that does not go deeper is allowed)."},
  {AlarmId::ORIENTATION_LIMIT, "ORIENTATION_LIMIT", 209, Severity::fault, Latch::reset,
   "The tool axis left the permitted orientation cone of the safety configuration; power was cut.",
   "Reset, then in T1 turn the tool back toward the permitted orientation."},
  {AlarmId::SPEED_LIMIT, "SPEED_LIMIT", 210, Severity::fault, Latch::reset,
   "A joint or the TCP moved faster than the safety configuration allows (normal or reduced); power was cut.",
   "Check the named axis' drive and the program's speeds against the safety configuration, then reset."},
  {AlarmId::CONFIG_NOT_VALIDATED, "CONFIG_NOT_VALIDATED", 304, Severity::warning, Latch::condition,
   "The active safety configuration's checksum has not been confirmed by an operator: AUTO and T2 are refused.",
   "Check the configuration, then in T1 or T2 with the servos off confirm its checksum on the pendant."},
  {AlarmId::REDUCED_SPEED, "REDUCED_SPEED", 305, Severity::info, Latch::condition,
   "Reduced mode is active: the TCP is held to the reduced speed limit (reduced zone or reduced input).",
   "None needed; the robot returns to normal speed when the TCP leaves the zone and the input clears."},
  {AlarmId::FIELD_DISCREPANCY, "FIELD_DISCREPANCY", 108, Severity::lockout, Latch::power_cycle,
   "The two OSSD channels of a protective field (area scanner) disagreed for longer than the discrepancy time.",
   "Check the scanner's OSSD outputs and wiring of the named field and channel, then power-cycle."},
  {AlarmId::SEPARATION_VIOLATED, "SEPARATION_VIOLATED", 211, Severity::fault, Latch::reset,
   "The TCP stayed faster than the speed allowed for the person's separation (SSM, v_allowed + 5 %) for longer "
   "than the reaction time; power was cut.",
   "Check the distance sensor, the drives and the speed scaling of the motion layer, then reset."},
  {AlarmId::PERSON_IN_FIELD, "PERSON_IN_FIELD", 307, Severity::info, Latch::condition,
   "A person is in the inner protective field during collaborative operation in AUTO: the program pauses.",
   "Leave the inner field; with auto resume on the program goes on once both fields are clear for the resume delay, "
   "else press resume."},
  {AlarmId::BRAKE_TEST_DUE, "BRAKE_TEST_DUE", 320, Severity::warning, Latch::condition,
   "The last passed brake test is older than brake_test.interval_h: the brakes must be tested again.",
   "Run the brake test (pendant, servos on, at standstill) before the grace time runs out; after it AUTO is refused."},
  {AlarmId::BRAKE_TEST_FAILED, "BRAKE_TEST_FAILED", 220, Severity::fault, Latch::reset,
   "A holding brake let the named axis drift further than brake_test.max_drift_deg under the test torque; "
   "the robot was stopped and AUTO is refused until a brake test passes.",
   "Secure the named axis against falling, replace or adjust its brake, reset, then run the brake test again "
   "(T1 or T2 stay allowed)."},
  {AlarmId::COLLISION, "COLLISION", 212, Severity::fault, Latch::reset,
   "The force at the TCP estimated from the drives' torques exceeded the body region's quasi-static limit F_qs "
   "(power and force limiting): the robot stopped (Cat 2), backed off 10 mm along its path and holds.",
   "Free the person or the obstacle and check the path and the payload in the safety configuration; then resume "
   "(AUTO) or jog on (T1/T2). The alarm stays until a reset with the servos off."},
  {AlarmId::CHANNEL_MISMATCH, "CHANNEL_MISMATCH", 109, Severity::lockout, Latch::power_cycle,
   "The two safety channels computed different results (the named field of their cross-check digest) for longer "
   "than cross_check_cycles, or gave a command different answers: one of them is faulty. Each opened its contactor.",
   "Record the event history of both channels, power-cycle, and report it: the controller must be inspected."},
  {AlarmId::CHANNEL_LOST, "CHANNEL_LOST", 110, Severity::lockout, Latch::power_cycle,
   "The named safety channel's cross-check digest did not arrive intact and in sequence for cross_check_cycles "
   "(the channel stopped, crashed or its link failed). The other channel opened its contactor.",
   "Check the named channel's process or processor and the cross-channel link, then power-cycle."},
  {AlarmId::ENCODER_DISCREPANCY, "ENCODER_DISCREPANCY", 111, Severity::lockout, Latch::power_cycle,
   "The named axis' load-side encoder disagreed with its motor encoder by more than encoder_tolerance_deg for "
   "longer than encoder_discrepancy_ms, or stood still while the motor encoder moved: position-based limits "
   "cannot be trusted.",
   "Check both encoders of the named axis, its gearbox and its coupling, then power-cycle."},
  {AlarmId::SAFETY_LINK_FAULT, "SAFETY_LINK_FAULT", 112, Severity::lockout, Latch::power_cycle,
   "A safety container of the named connection (the black channel between a channel and a safe device) failed "
   "its check: crc (corrupted), sequence (repeated, lost or out of order), identity (another connection's or "
   "device's), timeout (none new within its watchdog), not_connected (nothing valid from the device) or length. "
   "The bus or its master altered it; the channel took the safe values and opened its contactor, the device "
   "went to its safe state by itself.",
   "Check the named device, the cabling to it and the EtherCAT master (event log), then power-cycle: a new "
   "session is opened at start-up."},
}};
// clang-format on

[[nodiscard]] constexpr const AlarmInfo& alarm_info(AlarmId id) noexcept {
  return kAlarms[static_cast<std::size_t>(id)];
}
[[nodiscard]] const char* to_string(AlarmId id) noexcept;
[[nodiscard]] const char* to_string(Severity s) noexcept;
bool parse_alarm(const char* name, AlarmId& out) noexcept;

using AlarmMask = std::uint64_t;
static_assert(kAlarmCount <= 64U, "AlarmMask holds a bit per alarm");
[[nodiscard]] constexpr AlarmMask bit(AlarmId id) noexcept {
  return AlarmMask{1U} << static_cast<unsigned>(id);
}

// FIELDBUS_LOST / BOOT_FAILED with signal fieldbus: `code` is the bus position (1-based) of
// the subdevice at fault; this bit added: no frame comes back from that subdevice on.
inline constexpr std::uint16_t kFieldbusSilentFrom = 0x100U;

// What an alarm (or a stop) is about: which input and channel, which axis, which step.
struct AlarmDetail {
  Signal signal = Signal::none;
  Channel channel = Channel::none;
  std::uint8_t axis = 0;  // 1..6, 0 = none
  ArmingStep step = ArmingStep::CONTACTOR;
  bool has_step = false;
  std::uint16_t code = 0;  // e.g. the drive statusword, or the command id
};

// A measured value as an alarm detail's code, saturated to 0..65535: NaN (unknown) and
// values above as 65535, negatives as 0. A plain cast of NaN or of an out-of-range float
// to an integer is undefined behaviour (found by clang's UBSan: a NaN T1 speed).
[[nodiscard]] constexpr std::uint16_t detail_code(float v) noexcept {
  if (!(v < 65535.0F)) {
    return 65535U;
  }
  return (v > 0.0F) ? static_cast<std::uint16_t>(v) : std::uint16_t{0U};
}

// The set of active alarms with since-when and cause detail. Fixed size, no heap.
class AlarmSet {
  // SPEC §14 `channel X flip FIELD`: the simulator's probe of named variables (sim/src/flip.cpp).
  friend struct FieldProbe;

 public:
  void begin_cycle() noexcept {
    raised_ = 0;
    cleared_ = 0;
  }
  // Raises `id` (no effect when already active: the first cause is kept).
  void raise(AlarmId id, const AlarmDetail& d, Cycle now) noexcept;
  void clear(AlarmId id) noexcept;
  // Clears every active alarm in `mask` whose since-cycle is before `now`.
  void clear_older(AlarmMask mask, Cycle now) noexcept;

  [[nodiscard]] bool active(AlarmId id) const noexcept { return (active_ & bit(id)) != 0U; }
  [[nodiscard]] AlarmMask mask() const noexcept { return active_; }
  [[nodiscard]] AlarmMask raised() const noexcept { return raised_; }
  [[nodiscard]] AlarmMask cleared() const noexcept { return cleared_; }
  [[nodiscard]] Cycle since(AlarmId id) const noexcept { return since_[static_cast<std::size_t>(id)]; }
  [[nodiscard]] const AlarmDetail& detail(AlarmId id) const noexcept {
    return detail_[static_cast<std::size_t>(id)];
  }

 private:
  AlarmMask active_ = 0;
  AlarmMask raised_ = 0;
  AlarmMask cleared_ = 0;
  std::array<Cycle, kAlarmCount> since_{};
  std::array<AlarmDetail, kAlarmCount> detail_{};
};

// Masks by latch kind, derived from the table at compile time.
[[nodiscard]] constexpr AlarmMask alarms_with(Latch l) noexcept {
  AlarmMask m = 0;
  for (const AlarmInfo& a : kAlarms) {
    if (a.latch == l) {
      m |= bit(a.id);
    }
  }
  return m;
}
inline constexpr AlarmMask kLockoutAlarms = alarms_with(Latch::power_cycle);
inline constexpr AlarmMask kLatchedAlarms = alarms_with(Latch::reset);
inline constexpr AlarmMask kUntilOkAlarms = alarms_with(Latch::until_ok);

}  // namespace safestate::core

// Every safety function the supervisor evaluates each cycle, one class per function, each
// in a file of its own under core/src/monitors/, each with the one entry of monitor.hpp:
//
//     void check(const CycleView& v, Reporter& r) noexcept;
//
// A monitor names its alarms, their details and whether their cause is still present; it
// changes no state of the supervisor. They run in the order of
// SystemStateManager::run_monitors (supervisor.cpp); a monitor reads only the facts of the
// monitors before it. Configuration (limits, cycle time) comes before the first cycle.
//
// Position limits (joint range, zones, orientation) have a recovery (SPEC §10): a limit
// found violated while power is off raises nothing and is remembered as `recovering`;
// with power on (T1 only: servo_on refuses AUTO/T2 with OUTSIDE_LIMITS) motion may go on
// while it does not make the violation worse. "Worse" is one number per limit, how far
// outside it is, compared with the best (smallest) value reached since power came on.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/alarms.hpp"
#include "safestate/core/arm.hpp"
#include "safestate/core/findings.hpp"
#include "safestate/core/interfaces.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

struct CycleView;  // monitor.hpp
class Reporter;    // monitor.hpp

// ---- The safety inputs (SPEC §2, §4 rules 1, 2, 4, 5, 6) ------------------------------------

// E-stop: ESTOP_DISCREPANCY (rule 1), ESTOP_PRESSED (rule 2, and active while pressed).
class EstopMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// Guard / light curtain: GATE_DISCREPANCY (rule 1), PROTECTIVE_STOP (rule 4: open in AUTO).
class GateMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// Enabling device: ENABLE_DISCREPANCY (rule 1); ENABLING_PANIC on the panic edge; rule 5
// (left the centre in T1/T2: the panic position with its alarm, a release without one).
class EnablingMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// Mode selector: MODE_SELECTOR_INVALID (while no single position), MODE_CHANGED (rule 6).
class ModeMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// Reset button held too long: RESET_BUTTON_STUCK (while held past the limit).
class ResetButtonMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// SPEC §10 validation: CONFIG_NOT_VALIDATED while the checksum is not confirmed.
class ConfigValidationMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// ---- The platform (SPEC §4 rule 1) ---------------------------------------------------------

// Start-up: self-test, fieldbus up, every drive answering, within boot_timeout (facts
// boot_passed; BOOT_FAILED, rule 1).
class BootMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// Cyclic data valid and every drive on the bus, after BOOT: FIELDBUS_LOST (rule 1).
class FieldbusMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// The integrity checks of the platform and of the supervisor itself: INTEGRITY_FAULT (rule 1).
class IntegrityMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// ---- The drives and the arm's motion (SPEC §3, §4 rules 3, 7) -------------------------------

// Standstill: every axis below standstill_rad_s for standstill_cycles in a row (facts).
class StandstillMonitor {
  // SPEC §14 `channel X flip FIELD`: the simulator's probe of named variables (sim/src/flip.cpp).
  friend struct FieldProbe;

 public:
  void check(const CycleView& v, Reporter& r) noexcept;

 private:
  Cycle count_ = 0;
};

// CiA 402 state of every drive (unknown is unsafe), Operation enabled where power is
// expected, and the following error: DRIVE_FAULT (rule 3; raised in every state but BOOT).
class DriveMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// T1: the fastest TCP or link-origin speed <= t1_speed_limit_mm_s while motion armed in T1
// runs: T1_SPEED_EXCEEDED (rule 3). The speeds are the core's own: the positions of the
// TCP and of every link origin through the core's kinematics (facts: pose), differentiated
// over the cycles between two measured samples (Feedback: stale, sample_span). Without
// the core's arm (SystemStateManager::configure_arm) the speed is unknown: over the limit.
inline constexpr std::size_t kT1Points = kAxes + 1U;  // link origins 1..5, the flange, the TCP
class T1SpeedMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;

 private:
  std::array<Vec3, kT1Points> last_{};  // the points at the last fresh sample
  bool have_last_ = false;
  std::uint32_t span_ = 1;   // cycles from the sample in last_ to the next fresh one (saturates)
  float speed_mm_s_ = 0.0F;  // the last fresh sample's fastest point (stands while none comes)
  std::uint8_t axis_ = 0;    // 1..6: the link that point belongs to (the flange, the TCP: 6)
};

// SS1-t: a controlled stop reaches standstill within max_stop: STOP_TIME_EXCEEDED (rule 3).
class StopTimeMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// Jog keep-alive: JOG_LINK_LOST (rule 7) when none came within jog_timeout.
class JogLinkMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// ---- External device monitoring (SPEC §7, ISO 13849-1) -------------------------------------

// The contactor's auxiliary contact follows the last command: CONTACTOR_WELDED (rule 1)
// when it stays closed contactor_timeout after an open command. With two contactors (SPEC
// §14) each channel watches both (K1, K2) against its own command, naming the one.
class ContactorMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;

 private:
  Cycle welded_ = 0;
  Cycle welded_k2_ = 0;
};

// Every brake's feedback follows the last command: BRAKE_NOT_ENGAGED (rule 3, raised in
// every state) when one still says released brakes_timeout after an engage command.
class BrakeFeedbackMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;

 private:
  // Per brake, while commanded engaged: cycles since it last stopped counting as engaged
  // (0 once engaged), and how long its feedback has said engaged without a break.
  std::array<Cycle, kAxes> cycles_{};
  std::array<Cycle, kAxes> engaged_run_{};
};

// ---- SPEC §14 two channels -----------------------------------------------------------------

// The cross-check with the other channel (Feedback::cross, from the controller):
// CHANNEL_MISMATCH naming the first field that differed, CHANNEL_LOST naming the partner
// (rule 1, lockout). Nothing in a one-channel cell.
class ChannelMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// Issue 37, the black channel (Feedback::link, from the controller's SafetyLinks):
// SAFETY_LINK_FAULT naming the connection and its error (rule 1, lockout). Nothing on a
// backend without safety connections.
class SafetyLinkMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// Two encoders per axis (Feedback::load_encoders): ENCODER_DISCREPANCY naming the axis
// (rule 1, lockout) when the motor and load-side positions differ by more than
// encoder_tolerance for longer than encoder_discrepancy, or the load-side one stood still
// while the motor one moved by more than the tolerance.
class EncoderMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;

 private:
  std::array<Cycle, kAxes> over_{};          // cycles in a row over the tolerance
  std::array<float, kAxes> load_last_{};     // the load-side position when it last changed
  std::array<float, kAxes> motor_at_last_{};  // the motor position at that moment
  bool have_last_ = false;
};

// ---- SPEC §10 safe limits -------------------------------------------------------------------

// Why reduced mode is active (status `reduced_by`), bit per source.
inline constexpr std::uint8_t kReducedByZone = 0x01U;
inline constexpr std::uint8_t kReducedByInput = 0x02U;
inline constexpr std::uint8_t kReducedByField = 0x04U;  // SPEC §11 outer protective field

// Noise allowed before a recovering position limit counts as worse: a tenth of a degree,
// a millimetre. Below the motion layer's margins (1 deg, 10 mm), above position noise.
inline constexpr float kWorseJointRad = 0.002F;
inline constexpr float kWorseZoneMm = 1.0F;
inline constexpr float kWorseOrientationCos = 0.002F;

struct RecoveryTrack {
  float best = 0.0F;
  bool recovering = false;
};

// One position limit's verdict from how far outside it is (<= 0: inside; NaN: outside).
// Returns true when it trips.
bool track_violation(RecoveryTrack& t, float outside, bool powered, float tolerance) noexcept;

// Each joint within its range: JOINT_LIMIT naming the axis.
class JointLimitMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;

 private:
  std::array<RecoveryTrack, kAxes> track_{};
};

// Keep-in / keep-out zones (ZONE_VIOLATION naming the zone) and reduced zones (facts).
class ZoneMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
  // The arm the zones are checked for (a new configuration: other zones, another tool):
  // forgets what the last cycles proved and allows zones to be skipped while provably far.
  // Until then every zone is tested every cycle.
  void reset(const PreparedArm& arm, const Vec3& tcp_flange_mm) noexcept;
  // How far the TCP sphere and the link points 2..6 are outside a keep_in box / into a
  // keep_out box, mm (<= 0: the zone is respected). Public for tests.
  [[nodiscard]] static float outside_mm(const Zone& z, const ArmPose& p, float radius_mm) noexcept;

  // Conservative advancement (zones.cpp): between two cycles no checked point (link origin,
  // TCP) moves further than step = sum_k reach_k |dq_k| (joint k turns every point after it
  // about its axis; reach_k bounds their distance from that axis over all poses), so the box
  // around them moves by at most that along any axis. `travel_` sums the steps. A zone found
  // clear of the box by a gap g at travel T stays clear while travel < T + g: no test needed
  // until then. It only saves work: a restart makes every zone be tested again.
  static constexpr float kMaxStepMm = 1000.0F;      // a larger step (or NaN/inf) restarts
  static constexpr float kRebaseMm = 8192.0F;       // travel is restarted beyond this
  static constexpr float kTravelFloorMm = 1.0e-3F;  // added per cycle: > float rounding below kRebaseMm
  static constexpr float kGapMarginMm = 0.01F;      // taken off each gap: > its rounding

 private:
  void restart() noexcept;

  std::array<RecoveryTrack, kMaxZones> track_{};
  std::array<float, kMaxZones> clear_until_{};  // travel below which zone i is respected
  JointArray reach_{};                          // mm: see above
  JointArray last_q_{};
  float travel_ = 0.0F;
  float next_due_ = -1.0F;         // the smallest clear_until_ of a keep_in/keep_out zone
  std::uint16_t reduced_mask_ = 0;  // the reduced zones (bit i), from the last full pass
  bool cull_ = false;               // reset() with an arm: skipping allowed
  bool have_last_ = false;
};

// The tool axis within its cone: ORIENTATION_LIMIT (detail tcp).
class OrientationMonitor {
 public:
  // cos(max deviation), computed once here rather than every cycle.
  void configure(const SafetyLimits& limits) noexcept;
  void check(const CycleView& v, Reporter& r) noexcept;

 private:
  RecoveryTrack track_{};
  float cos_max_ = 1.0F;
};

// Reduced mode (SPEC §10): active while a source asks (a reduced zone holds the TCP, the
// reduced input, SPEC §11's outer field); the reduced limit is enforced once `ramp`
// cycles have passed since it became active. REDUCED_SPEED while active.
class ReducedMode {
 public:
  void configure(Cycle ramp) noexcept { ramp_ = ramp; }
  void check(const CycleView& v, Reporter& r) noexcept;
  // `limit`: the reduced TCP limit of these sources; a lower limit than before (a source
  // that reduces further, SPEC §11's outer field) starts the ramp again.
  void update(std::uint8_t sources, Cycle ramp, float limit) noexcept;
  [[nodiscard]] bool active() const noexcept { return sources_ != 0U; }
  [[nodiscard]] bool enforced() const noexcept { return active() && (elapsed_ > ramp_); }
  [[nodiscard]] std::uint8_t sources() const noexcept { return sources_; }
  [[nodiscard]] float limit() const noexcept { return limit_; }

 private:
  std::uint8_t sources_ = 0;
  Cycle elapsed_ = 0;
  Cycle ramp_ = 0;
  float limit_ = 0.0F;
};

// Each joint speed and the TCP speed within their limits (the reduced one once enforced):
// SPEED_LIMIT naming the axis or tcp, with power on; its cause present with power or not.
class SpeedLimitMonitor {
 public:
  void check(const CycleView& v, Reporter& r) noexcept;
};

// The safe limits together: the arm's pose through the core's own kinematics from the
// measured joint positions (facts: q, qd, pose), then joints, zones, orientation, reduced
// mode and speeds, in the order their alarms are listed in SPEC §4 rule 3.
class SafeLimitMonitors {
 public:
  // Before the first cycle: the arm alone (its pose is then computed every cycle, for T1
  // speed, the limits not monitored), or the limits with their arm and TCP. Until the
  // limits are configured the monitors report nothing (unit tests of the state machine
  // alone); every cell configures them (the built-in configuration when no file is given).
  void configure_arm(const ArmGeometry& arm, const Vec3& tcp_flange_mm) noexcept;
  void configure(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us) noexcept;
  [[nodiscard]] bool configured() const noexcept { return configured_; }
  [[nodiscard]] bool arm_configured() const noexcept { return arm_configured_; }
  [[nodiscard]] const SafetyLimits& limits() const noexcept { return limits_; }
  [[nodiscard]] const PreparedArm& arm() const noexcept { return arm_; }
  [[nodiscard]] const ArmPose& pose() const noexcept { return pose_; }
  [[nodiscard]] const ReducedMode& reduced() const noexcept { return reduced_; }

  void check(const CycleView& v, Reporter& r) noexcept;

 private:
  SafetyLimits limits_{};
  PreparedArm arm_{};
  Vec3 tcp_{};  // the TCP in the flange frame (limits_.tcp_mm once the limits are configured)
  bool configured_ = false;
  bool arm_configured_ = false;
  ArmPose pose_{};
  JointLimitMonitor joints_;
  ZoneMonitor zones_;
  OrientationMonitor orientation_;
  ReducedMode reduced_;
  SpeedLimitMonitor speed_;
};

// Name of an alarm detail with the configuration's zone names (`alarm.NAME.detail=`):
// axis.N, tcp, the zone's name, else as detail_name().
const char* limit_detail_name(const AlarmDetail& d, const SafetyLimits& limits, char* buf, std::size_t n) noexcept;

// ---- SPEC §11 collaborative operation (fields.cpp, ssm.cpp; collision.hpp) -----------------

// The reduced TCP limit for a set of kReducedBy* sources: reduced.tcp_max_speed_mm_s, and
// with the outer field among them the lower of that, collaborative.reduced_speed_mm_s and
// (pfl on) the PFL cap v_pfl.
[[nodiscard]] float reduced_limit_mm_s(const SafetyLimits& limits, std::uint8_t sources) noexcept;

// Protective fields (SPEC §11): FIELD_DISCREPANCY (rule 1, whatever the configuration),
// outer -> reduced mode, inner -> PERSON_IN_FIELD (rule 9), automatic resume (facts).
class FieldMonitor {
 public:
  void configure(const CollaborativeLimits& c, std::uint32_t cycle_us) noexcept;
  void check(const CycleView& v, Reporter& r) noexcept;
  [[nodiscard]] Cycle clear_cycles() const noexcept { return clear_; }

 private:
  bool enabled_ = false;
  bool auto_resume_ = true;
  Cycle delay_ = 0;
  Cycle clear_ = 0;  // consecutive cycles with both fields clear (saturating above delay_)
};

// SSM (SPEC §11): SEPARATION_VIOLATED when the TCP stays over v_allowed + 5 % longer than
// T_r with power on. A separation that rises faster than a person walking away and the
// robot moving away together could (kHumanSpeedNearMmS + tcp_max_speed_mm_s) is not
// believed: the separation used rises at that rate at most. A fall is taken at once.
class SsmMonitor {
 public:
  void configure(const SafetyLimits& limits, std::uint32_t cycle_us) noexcept;
  // Reads the TCP speed and the limit in force from the safe limits' facts.
  void check(const CycleView& v, Reporter& r) noexcept;
  [[nodiscard]] Cycle reaction_cycles() const noexcept { return reaction_; }
  [[nodiscard]] float rise_per_cycle_mm() const noexcept { return rise_; }

 private:
  bool enabled_ = false;
  SsmParams params_{};
  Cycle reaction_ = 0;
  float rise_ = 0.0F;     // mm a cycle
  float used_ = 0.0F;     // the separation used last cycle
  Cycle over_ = 0;        // consecutive cycles over v_allowed + 5 %
};

// The SSM monitor's tolerance: SPEC §11 "above v_allowed + 5 %".
inline constexpr float kSsmTolerance = 1.05F;

}  // namespace safestate::core

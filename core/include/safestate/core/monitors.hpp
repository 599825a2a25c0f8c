// The safe-limit monitors of SPEC §10, one small class per safety function (DESIGN.md:
// PX4's HealthAndArmingChecks shape). Each looks at the cycle's measured state and the
// fixed-size limits and reports a named finding; none changes state: the supervisor does
// that, in the rule order of SPEC §4 (a finding here is rule 3, Cat 0, latched).
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
#include "safestate/core/interfaces.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

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

struct LimitFinding {
  bool hit = false;
  AlarmDetail detail{};
};

// What the monitors see in one cycle.
struct LimitContext {
  // NOLINTBEGIN(cppcoreguidelines-avoid-const-or-ref-data-members): a view for one cycle
  const SafetyLimits& limits;
  const ArmPose& pose;
  const JointArray& q;
  const JointArray& qd;
  // NOLINTEND(cppcoreguidelines-avoid-const-or-ref-data-members)
  bool powered;             // ARMING, OPERATIONAL, STOPPING
  bool reduced_enforced;    // reduced mode active and its ramp time over
  float reduced_limit_mm_s; // the reduced TCP limit of the active sources (SPEC §10, §11)
  float orientation_cos;    // cos(orientation max deviation), computed once at configure()
};

struct LimitReport {
  LimitFinding joint;        // JOINT_LIMIT, detail axis.N
  LimitFinding zone;         // ZONE_VIOLATION, detail the zone (index in `code`)
  LimitFinding orientation;  // ORIENTATION_LIMIT, detail tcp
  LimitFinding speed;        // SPEED_LIMIT, detail axis.N or tcp (with power on: trips)
  bool speed_over = false;   // a speed over its limit now, with power or not (reset guard)
  bool outside = false;      // a position limit is violated now
  bool recovering = false;   // ... and that is being recovered from (status `recovery`)
  bool in_reduced_zone = false;
  std::uint8_t reduced_zone = 0;  // 1 + index of the first reduced zone holding the TCP, 0: none
  float tcp_speed_mm_s = 0.0F;
  float speed_limit_mm_s = 0.0F;  // the TCP limit in force this cycle

  // As a value-initialised report, member by member: `= LimitReport{}` is a byte-wise
  // memset in newlib-nano (a hundred and more instructions per cycle on the Cortex-M4).
  void clear() noexcept {
    joint = LimitFinding{};
    zone = LimitFinding{};
    orientation = LimitFinding{};
    speed = LimitFinding{};
    speed_over = false;
    outside = false;
    recovering = false;
    in_reduced_zone = false;
    reduced_zone = 0U;
    tcp_speed_mm_s = 0.0F;
    speed_limit_mm_s = 0.0F;
  }
};

class JointLimitMonitor {
 public:
  void check(const LimitContext& c, LimitReport& r) noexcept;

 private:
  std::array<RecoveryTrack, kAxes> track_{};
};

class ZoneMonitor {
 public:
  void check(const LimitContext& c, LimitReport& r) noexcept;
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

class OrientationMonitor {
 public:
  void check(const LimitContext& c, LimitReport& r) noexcept;

 private:
  RecoveryTrack track_{};
};

class SpeedLimitMonitor {
 public:
  static void check(const LimitContext& c, LimitReport& r) noexcept;
};

// Reduced mode (SPEC §10): active while a source asks; the reduced limit is enforced by the
// monitor once `ramp` cycles have passed since it became active.
class ReducedMode {
 public:
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

// ---- SPEC §11 collaborative operation (core/src/monitors/fields.cpp, ssm.cpp) ----------

// The reduced TCP limit for a set of kReducedBy* sources: reduced.tcp_max_speed_mm_s, and
// with the outer field among them the lower of that, collaborative.reduced_speed_mm_s and
// (pfl on) the PFL cap v_pfl.
[[nodiscard]] float reduced_limit_mm_s(const SafetyLimits& limits, std::uint8_t sources) noexcept;

// What the protective fields mean this cycle.
struct FieldReport {
  bool acting = false;         // collaborative on and mode AUTO: the fields act (SPEC §11)
  bool outer_reduces = false;  // reduced mode source kReducedByField
  bool inner_stops = false;    // rule 9's condition (the row says from which leaf)
  bool blocks_start = false;   // start / resume: FIELD_INTERRUPTED
  bool resume_due = false;     // both clear for resume_delay_ms and auto_resume on
  // FIELD_DISCREPANCY (rule 1), whatever the configuration: a hardware fault.
  bool discrepancy = false;
  AlarmDetail discrepancy_detail{};
  AlarmDetail inner_detail{};  // PERSON_IN_FIELD's detail: field.inner and the channel
};

// Protective fields (SPEC §11): outer -> reduced mode, inner -> rule 9, automatic resume.
class FieldMonitor {
 public:
  void configure(const CollaborativeLimits& c, std::uint32_t cycle_us) noexcept;
  void check(const SafetyInputs& in, FieldReport& r) noexcept;
  [[nodiscard]] Cycle clear_cycles() const noexcept { return clear_; }

 private:
  bool enabled_ = false;
  bool auto_resume_ = true;
  Cycle delay_ = 0;
  Cycle clear_ = 0;  // consecutive cycles with both fields clear (saturating above delay_)
};

// Speed and separation monitoring's verdict this cycle.
struct SsmReport {
  bool acting = false;           // collaborative and ssm on, mode AUTO
  float separation_mm = 0.0F;    // the separation used (after the plausibility filter)
  float v_allowed_mm_s = 0.0F;   // v_allowed(separation) clamped to [0, the limit in force]
  float v_plan_mm_s = 0.0F;      // what the motion layer plans to (ssm_planning_speed_mm_s)
  bool over = false;             // TCP above v_allowed + 5 % now (the reset guard's "cause")
  LimitFinding violated;         // SEPARATION_VIOLATED: over for longer than T_r, power on
};

// SSM (SPEC §11). A separation that rises faster than a person walking away and the robot
// moving away together could (kHumanSpeedNearMmS + tcp_max_speed_mm_s) is not believed: the
// separation used rises at that rate at most. A fall is taken at once (the safe side).
class SsmMonitor {
 public:
  void configure(const SafetyLimits& limits, std::uint32_t cycle_us) noexcept;
  // `tcp_speed`, `limit`: the core's own TCP speed and the TCP limit in force (LimitReport).
  void check(const SafetyInputs& in, float tcp_speed, float limit, bool powered, SsmReport& r) noexcept;
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

// The monitors together, in the order their alarms are listed in SPEC §4 rule 3.
class SafeLimitMonitors {
 public:
  // Before the first cycle. Until configured the monitors report nothing (unit tests of
  // the state machine alone); every cell configures them (the built-in configuration
  // when no file is given).
  void configure(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us) noexcept;
  [[nodiscard]] bool configured() const noexcept { return configured_; }
  [[nodiscard]] const SafetyLimits& limits() const noexcept { return limits_; }
  [[nodiscard]] const ArmPose& pose() const noexcept { return pose_; }
  [[nodiscard]] const ReducedMode& reduced() const noexcept { return reduced_; }

  // `input_reduced`: the dual-channel reduced input asks for it (SPEC §10);
  // `other_sources`: further kReducedBy* bits (the outer protective field, SPEC §11).
  void evaluate(const Feedback& fb, bool powered, bool input_reduced, std::uint8_t other_sources,
                LimitReport& out) noexcept;

 private:
  SafetyLimits limits_{};
  PreparedArm arm_{};
  Cycle ramp_cycles_ = 0;
  bool configured_ = false;
  ArmPose pose_{};
  float orientation_cos_ = 1.0F;
  JointLimitMonitor joints_;
  ZoneMonitor zones_;
  OrientationMonitor orientation_;
  ReducedMode reduced_;
};

// Name of an alarm detail with the configuration's zone names (`alarm.NAME.detail=`):
// axis.N, tcp, the zone's name, else as detail_name().
const char* limit_detail_name(const AlarmDetail& d, const SafetyLimits& limits, char* buf, std::size_t n) noexcept;

}  // namespace safestate::core

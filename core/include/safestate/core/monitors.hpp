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
  // How far the TCP sphere and the link points 2..6 are outside a keep_in box / into a
  // keep_out box, mm (<= 0: the zone is respected). Public for tests.
  [[nodiscard]] static float outside_mm(const Zone& z, const ArmPose& p, float radius_mm) noexcept;

 private:
  std::array<RecoveryTrack, kMaxZones> track_{};
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
  void update(std::uint8_t sources, Cycle ramp) noexcept;
  [[nodiscard]] bool active() const noexcept { return sources_ != 0U; }
  [[nodiscard]] bool enforced() const noexcept { return active() && (elapsed_ > ramp_); }
  [[nodiscard]] std::uint8_t sources() const noexcept { return sources_; }

 private:
  std::uint8_t sources_ = 0;
  Cycle elapsed_ = 0;
  Cycle ramp_ = 0;
};

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

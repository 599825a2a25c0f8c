// The one shape of a safety function (DESIGN.md: PX4 commander's HealthAndArmingChecks):
//
//     void check(const CycleView& v, Reporter& r) noexcept;
//
// Every safety function evaluated each cycle is a monitor in a file of its own under
// core/src/monitors/ with this entry. It looks at the cycle (CycleView: inputs, feedback,
// where the state machine stands) and tells the Reporter what it found, by alarm name:
//  - trip(ALARM, detail): the alarm's condition holds. The alarm belongs to one rule of
//    SPEC §4 (kRuleAlarms below); the supervisor raises it when that rule applies in the
//    current state, and the first alarm found of the first rule that holds is the cause;
//  - raise(ALARM, detail): raised now, in every state (a fault whose lifetime is its own);
//  - hold(ALARM, holds, detail): active exactly while the condition holds (Latch::condition);
//  - present(ALARM): the alarm's cause is still there, so a reset must be refused
//    (ISO 13849-1 5.2.2); the reset guard asks the reporter this one question;
//  - facts(): measured values other monitors, the state machine and the status use
//    (standstill, the safe limits' report, the fields, SSM...). A monitor reads only the
//    facts of monitors that run before it (the order in SystemStateManager::run_monitors).
// A monitor changes no state of the supervisor: the supervisor stays the state machine
// (conditions in rule order, events, commands, outputs). Adding a safety function touches
// its file, the alarm table (alarms.hpp) and the rule its alarm belongs to (kRuleAlarms).
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/alarms.hpp"
#include "safestate/core/arm.hpp"
#include "safestate/core/brake_test.hpp"
#include "safestate/core/collision.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/interfaces.hpp"
#include "safestate/core/findings.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/states.hpp"
#include "safestate/core/transitions.hpp"

namespace safestate::core {

// ---- The rules the alarms belong to ---------------------------------------------------

inline constexpr std::size_t kMaxRuleAlarms = 12;
struct RuleAlarms {
  Trigger rule;
  std::uint8_t count;
  std::array<AlarmId, kMaxRuleAlarms> alarms;  // in the order a cause is chosen: the first found
};

// SPEC §4's condition rules and their alarms. An alarm absent here is not a rule's
// (ARMING_TIMEOUT: an event's; the Latch::condition alarms: raised by hold()).
// @req TR-PRIORITY TR-EVERY-ALARM
inline constexpr std::array<RuleAlarms, kConditionCount> kRuleAlarms{{
    {Trigger::lockout_condition, 12U,
     {AlarmId::ESTOP_DISCREPANCY, AlarmId::GATE_DISCREPANCY, AlarmId::ENABLE_DISCREPANCY, AlarmId::FIELD_DISCREPANCY,
      AlarmId::FIELDBUS_LOST, AlarmId::INTEGRITY_FAULT, AlarmId::BOOT_FAILED, AlarmId::CONTACTOR_WELDED,
      AlarmId::CHANNEL_MISMATCH, AlarmId::CHANNEL_LOST, AlarmId::ENCODER_DISCREPANCY, AlarmId::SAFETY_LINK_FAULT}},
    {Trigger::estop_pressed, 1U, {AlarmId::ESTOP_PRESSED}},
    // @req LIM-RULE3
    {Trigger::stop_fault, 9U,
     {AlarmId::DRIVE_FAULT, AlarmId::T1_SPEED_EXCEEDED, AlarmId::STOP_TIME_EXCEEDED, AlarmId::BRAKE_NOT_ENGAGED,
      AlarmId::JOINT_LIMIT, AlarmId::ZONE_VIOLATION, AlarmId::ORIENTATION_LIMIT, AlarmId::SPEED_LIMIT,
      AlarmId::SEPARATION_VIOLATED}},
    {Trigger::gate_open_in_auto, 1U, {AlarmId::PROTECTIVE_STOP}},
    {Trigger::enable_left_centre, 1U, {AlarmId::ENABLING_PANIC}},  // and the release: an event, no alarm
    {Trigger::mode_changed, 1U, {AlarmId::MODE_CHANGED}},
    {Trigger::jog_timeout, 1U, {AlarmId::JOG_LINK_LOST}},
    {Trigger::collision, 1U, {AlarmId::COLLISION}},
    {Trigger::person_in_field, 1U, {AlarmId::PERSON_IN_FIELD}},
    {Trigger::brake_test_failed, 1U, {AlarmId::BRAKE_TEST_FAILED}},
}};

[[nodiscard]] constexpr AlarmMask rule_mask(std::size_t t) noexcept {
  AlarmMask m = 0U;
  for (std::size_t i = 0; i < kRuleAlarms[t].count; ++i) {
    m |= bit(kRuleAlarms[t].alarms[i]);
  }
  return m;
}

namespace detail {
constexpr bool rules_well_formed() noexcept {
  AlarmMask seen = 0U;
  for (std::size_t t = 0; t < kConditionCount; ++t) {
    if (kRuleAlarms[t].rule != static_cast<Trigger>(t) || kRuleAlarms[t].count > kMaxRuleAlarms) {
      return false;
    }
    if ((seen & rule_mask(t)) != 0U) {
      return false;  // an alarm belongs to one rule
    }
    seen |= rule_mask(t);
  }
  return true;
}
}  // namespace detail
static_assert(detail::rules_well_formed(), "kRuleAlarms: one row per condition rule, in rule order; an alarm in one rule");

namespace detail {
// Every row of a condition in the transition table lists exactly its rule's alarms.
constexpr bool rows_match_rules() noexcept {
  for (const Transition& t : kTransitions) {
    const auto i = static_cast<std::size_t>(t.trigger);
    if ((i < kConditionCount) && (t.alarms != rule_mask(i))) {
      return false;
    }
  }
  return true;
}
}  // namespace detail
static_assert(detail::rows_match_rules(), "kTransitions: a condition row's alarms are its rule's (kRuleAlarms)");

// ---- What a monitor sees ----------------------------------------------------------------

// What the monitors measured this cycle, for the monitors after them, the state machine
// and the status.
struct CycleFacts {
  bool at_standstill = false;
  std::uint8_t fastest_moving_axis = 0;  // 1..6, the axis turning fastest (0: none)
  // The safe limits' view of the arm (SafeLimitMonitors; valid while limits are configured):
  // measured joint positions and velocities, and the pose through the core's own kinematics.
  JointArray q{};
  JointArray qd{};
  const ArmPose* pose = nullptr;
  bool any_drive_faulted = false;        // a statusword decodes to Fault / reaction / unknown
  bool boot_passed = false;              // BOOT's checks all passed this cycle
  float t1_speed_mm_s = 0.0F;            // the core's own fastest TCP / link-origin speed
  LimitReport limits{};                  // SPEC §10
  FieldReport fields{};                  // SPEC §11 protective fields
  SsmReport ssm{};                       // SPEC §11 speed and separation monitoring
  CollisionReport collision{};           // SPEC §11 collision detection
  BrakeTestVerdict brake_test{};         // SPEC §12 sequencer
};

// What this core commanded in the previous cycle (external device monitoring, SPEC §7).
struct Commanded {
  bool contactor = false;
  bool brakes_release = false;
  std::uint8_t brake_test_axis = 0;
};

// One cycle as every monitor sees it; built by the supervisor, alive during step().
struct CycleView {
  // NOLINTBEGIN(cppcoreguidelines-avoid-const-or-ref-data-members): a view for one cycle
  const SafetyInputs& in;
  const Feedback& fb;
  const Timing& timing;
  const StateVariant& state;  // the state's own data (arming step, stop time)
  const CycleFacts& facts;    // what the monitors before this one found
  // NOLINTEND(cppcoreguidelines-avoid-const-or-ref-data-members)
  const SafetyLimits* limits = nullptr;  // SPEC §10, as configured (normalised); nullptr: not monitored
  Leaf leaf = Leaf::BOOT;                 // the state at the start of the cycle
  bool powered = false;              // ARMING, OPERATIONAL, STOPPING
  Cycle now = 0;
  Mode armed_mode = Mode::NONE;           // the mode in which servo_on was accepted
  Cycle last_jog = 0;            // the cycle of the last jog keep-alive
  bool boot_pending = true;         // BOOT's checks have not passed before this cycle
  bool integrity_fault = false;      // the supervisor's own consistency checks failed
  bool self_test_ok = false;         // the supervisor's own start-up self-test passed
  bool config_validated = false;     // SPEC §10
  Commanded last{};           // outputs of the previous cycle
};

// ---- What a monitor says ----------------------------------------------------------------

// One per supervisor, begun again every cycle: nothing of it is value-initialised per cycle
// (a byte-wise memset of the facts in newlib-nano on the Cortex-M4); each monitor writes
// its own facts whole every cycle.
class Reporter {
 public:
  void begin(AlarmSet& alarms, Cycle now) noexcept {
    alarms_ = &alarms;
    now_ = now;
    found_ = 0U;
    present_ = 0U;
    events_ = 0U;
  }

  // The condition of `a`'s rule holds with `a` (the first detail of the cycle is kept).
  void trip(AlarmId a, const AlarmDetail& d) noexcept {
    if ((found_ & bit(a)) == 0U) {
      found_ |= bit(a);
      detail_[static_cast<std::size_t>(a)] = d;
    }
  }
  // Rule `t` holds without an alarm (rule 5: the enabling device released at the centre).
  void trip_event(Trigger t, const AlarmDetail& d) noexcept {
    const auto i = static_cast<std::size_t>(t);
    if (i >= kConditionCount) {
      return;  // not a rule
    }
    const auto b = static_cast<std::uint16_t>(1U << i);
    if ((events_ & b) == 0U) {  // the first detail of the cycle is kept, as by trip()
      events_ = static_cast<std::uint16_t>(events_ | b);
      event_detail_[i] = d;
    }
  }
  // Raised now, whatever the state.
  void raise(AlarmId a, const AlarmDetail& d) noexcept { alarms_->raise(a, d, now_); }
  // Active while `holds`.
  void hold(AlarmId a, bool holds, const AlarmDetail& d) noexcept {
    if (holds) {
      alarms_->raise(a, d, now_);
    } else {
      alarms_->clear(a);
    }
  }
  // `a`'s cause is still there: a reset is refused while `a` is active.
  void present(AlarmId a) noexcept { present_ |= bit(a); }
  CycleFacts& facts() noexcept { return facts_; }

  // The supervisor's side.
  [[nodiscard]] const CycleFacts& facts() const noexcept { return facts_; }
  [[nodiscard]] AlarmMask found() const noexcept { return found_; }
  [[nodiscard]] const AlarmDetail& detail(AlarmId a) const noexcept { return detail_[static_cast<std::size_t>(a)]; }
  [[nodiscard]] bool event(std::size_t t) const noexcept { return (events_ & (1U << t)) != 0U; }
  [[nodiscard]] const AlarmDetail& event_detail(std::size_t t) const noexcept { return event_detail_[t]; }
  [[nodiscard]] AlarmMask present_mask() const noexcept { return present_; }

 private:
  AlarmSet* alarms_ = nullptr;  // the supervisor's, set by begin()
  Cycle now_ = 0;
  AlarmMask found_ = 0U;
  AlarmMask present_ = 0U;
  std::uint16_t events_ = 0U;
  // Read only for the alarms in found_ / the rules in events_: not cleared per cycle.
  std::array<AlarmDetail, kAlarmCount> detail_{};
  std::array<AlarmDetail, kConditionCount> event_detail_{};
  CycleFacts facts_{};
};

// A detail naming a signal, channel, axis and code.
[[nodiscard]] constexpr AlarmDetail detail_of(Signal s, Channel ch = Channel::none, std::uint8_t axis = 0U,
                                              std::uint16_t code = 0U) noexcept {
  AlarmDetail d{};
  d.signal = s;
  d.channel = ch;
  d.axis = axis;
  d.code = code;
  return d;
}

}  // namespace safestate::core

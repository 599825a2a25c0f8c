// The transition table of SPEC §4: one constexpr array, one row per transition, the
// columns in the spec's order (from, trigger, guard, to, stop, alarm), plus the effect
// the row has on the state's data. docs/transitions.md and docs/states.mmd are
// generated from this array; a safety engineer audits this file, not the dispatcher.
//
// Reading a row: `from + trigger [guard] / stop, effect = to`, as in Boost.SML.
// A row with stop CAT1/CAT2 goes to STOPPING first and to `to` at standstill; a row with
// stop CAT0 cuts power in the same cycle and goes straight to `to`.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include "safestate/core/alarms.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/interfaces.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/states.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

enum class Trigger : std::uint8_t {
  // Conditions, checked every cycle in this priority (SPEC §4 rules 1..10).
  lockout_condition,   // 1: discrepancy, fieldbus lost, integrity or boot failure, contactor welded, channels, encoders
  estop_pressed,       // 2
  stop_fault,          // 3: drive fault, T1 speed, stop time, brake not engaged, a safe limit (§10), SSM (§11)
  gate_open_in_auto,   // 4, 4b
  enable_left_centre,  // 5, 5b
  mode_changed,        // 6
  jog_timeout,         // 7
  collision,           // 8: force at the TCP over the region's F_qs, pfl on (SPEC §11)
  person_in_field,     // 9: inner protective field interrupted, collaborative on (SPEC §11)
  brake_test_failed,   // 10: a brake slipped during the brake test (SPEC §12)
  // Internal events.
  boot_passed,
  estop_released,
  arming_complete,
  arming_timeout,
  program_finished,
  standstill,
  fields_clear,        // SPEC §11: both fields clear for resume_delay_ms, auto_resume on
  brake_test_passed,  // SPEC §12: every axis tested and held
  // Commands, in the order of CommandId.
  reset,
  servo_on,
  servo_off,
  start,
  pause,
  resume,
  stop,
  jog,
  jog_stop,
  confirm_t2,
  set_mode,
  validate_config,
  brake_test,
};
inline constexpr std::size_t kTriggerCount = 31;
inline constexpr std::size_t kConditionCount = 10;
// The SPEC §4 rule number of each condition trigger.
inline constexpr std::array<std::uint8_t, kConditionCount> kConditionRule{1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
inline constexpr std::size_t kFirstCommandTrigger = static_cast<std::size_t>(Trigger::reset);

[[nodiscard]] constexpr Trigger trigger_of(CommandId c) noexcept {
  return static_cast<Trigger>(kFirstCommandTrigger + static_cast<std::size_t>(c));
}
[[nodiscard]] constexpr bool is_condition(Trigger t) noexcept {
  return static_cast<std::size_t>(t) < kConditionCount;
}
const char* to_string(Trigger t) noexcept;

// What a guard may look at. Built once per cycle by the manager; guards are pure.
struct GuardView {
  // NOLINTBEGIN(cppcoreguidelines-avoid-const-or-ref-data-members): a view for one guard call
  const SafetyInputs& in;
  const Feedback& fb;
  const AlarmSet& alarms;
  const Timing& timing;
  // NOLINTEND(cppcoreguidelines-avoid-const-or-ref-data-members)
  bool t2_confirmed;
  bool boot_pending;
  bool reset_pending;
  bool at_standstill;
  // The alarms whose cause the monitors found still present this cycle (Reporter::present):
  // a reset is refused while one of them is active (ISO 13849-1 5.2.2).
  AlarmMask causes_present;
  // SPEC §10: a position limit is violated now; whether the configuration is validated,
  // its checksum and the code a validate_config command carries.
  bool outside_limits;
  bool config_validated;
  std::uint32_t checksum;
  std::uint32_t code;
  // SPEC §11: the inner protective field is interrupted while collaborative operation acts.
  bool field_blocks;
  // SPEC §12: a brake test is overdue, never passed (when one is required) or failed.
  bool brake_test_required;
};

using GuardFn = Result (*)(const GuardView&) noexcept;
struct Guard {
  GuardFn fn;        // nullptr: always OK
  const char* text;  // for the generated documentation
};

// Guards: each returns OK or the reject code of SPEC §4/§5, checks in the spec's order.
Result guard_boot_done(const GuardView& v) noexcept;
Result guard_reset_causes_gone(const GuardView& v) noexcept;
Result guard_servo_on(const GuardView& v) noexcept;
Result guard_start_auto(const GuardView& v) noexcept;
Result guard_resume(const GuardView& v) noexcept;
Result guard_enable_held(const GuardView& v) noexcept;
Result guard_start_manual(const GuardView& v) noexcept;
Result guard_t2_selected(const GuardView& v) noexcept;
Result guard_validate_config(const GuardView& v) noexcept;
Result guard_brake_test(const GuardView& v) noexcept;

inline constexpr Guard kNoGuard{nullptr, "-"};
inline constexpr Guard kBootDone{&guard_boot_done, "start-up self-test finished (BUSY)"};
inline constexpr Guard kCausesGone{&guard_reset_causes_gone,
                                   "every latched alarm's cause is gone (FAULT_PRESENT)"};
inline constexpr Guard kServoOn{&guard_servo_on,
                                "no latched alarm (RESET_REQUIRED); mode != NONE (MODE_INVALID); "
                                "AUTO: gate closed (GATE_OPEN); T1/T2: enable at centre "
                                "(ENABLING_NOT_HELD); T2: confirmed (T2_NOT_CONFIRMED); AUTO/T2: safety "
                                "configuration validated (CONFIG_NOT_VALIDATED); AUTO/T2: no safe limit "
                                "violated (OUTSIDE_LIMITS); AUTO: brake test not overdue or failed "
                                "(BRAKE_TEST_REQUIRED)"};
inline constexpr Guard kStartAuto{&guard_start_auto, "gate closed (GATE_OPEN); program loaded (NO_PROGRAM); "
                                                     "inner field clear (FIELD_INTERRUPTED); "
                                                     "program inside the safe limits (OUTSIDE_LIMITS)"};
inline constexpr Guard kResume{&guard_resume, "gate closed (GATE_OPEN); inner field clear (FIELD_INTERRUPTED)"};
inline constexpr Guard kEnableHeld{&guard_enable_held, "enable at centre (ENABLING_NOT_HELD)"};
inline constexpr Guard kStartManual{&guard_start_manual,
                                    "enable at centre (ENABLING_NOT_HELD); program loaded (NO_PROGRAM); "
                                    "program inside the safe limits (OUTSIDE_LIMITS)"};
inline constexpr Guard kT2Selected{&guard_t2_selected, "mode is T2 (MODE_INVALID)"};
inline constexpr Guard kValidate{&guard_validate_config,
                                 "mode T1 or T2 (MODE_INVALID); CODE is the active checksum (CHECKSUM_MISMATCH)"};
inline constexpr Guard kBrakeTest{&guard_brake_test, "standstill (WRONG_STATE); mode != NONE (MODE_INVALID)"};

// What a row does to the state's own data besides changing state.
enum class Effect : std::uint8_t {
  none,
  reset_alarms,    // clear latched alarms; acknowledge drive faults (answer may come later)
  begin_arming,    // ARMING from step CONTACTOR
  start_program,   // program from its first waypoint, planned from the measured position
  resume_program,  // program from where it paused, re-planned from the measured position
  abort_program,   // discard the program
  jog_keepalive,   // (re)start the jog keep-alive timer, take axis/direction/speed
  set_t2_confirmed,  // T2 confirmed until the mode next changes
  set_validated,     // SPEC §10: the safety configuration is validated
  field_pause,       // SPEC §11 rule 9: the pause that follows may resume by itself
  begin_brake_test,  // SPEC §12: the brake test from axis 1
  back_off,          // SPEC §11 rule 8: the Cat 2 stop ends with a back-off (program kept)
  back_off_abort,    // the same, and the program is discarded (manual modes)
};
const char* to_string(Effect e) noexcept;

using LeafMask = std::uint16_t;
[[nodiscard]] constexpr LeafMask mask_of(Leaf l) noexcept {
  return static_cast<LeafMask>(1U << static_cast<unsigned>(l));
}
[[nodiscard]] constexpr LeafMask only(Leaf l) noexcept { return mask_of(l); }
template <typename... L>
[[nodiscard]] constexpr LeafMask any_of(L... leaves) noexcept {
  return static_cast<LeafMask>((static_cast<unsigned>(mask_of(leaves)) | ...));
}

// Set algebra on masks, in unsigned arithmetic (no promotion to int).
template <typename... M>
[[nodiscard]] constexpr LeafMask join(M... masks) noexcept {
  return static_cast<LeafMask>((static_cast<unsigned>(masks) | ...));
}
[[nodiscard]] constexpr LeafMask without(LeafMask a, LeafMask b) noexcept {
  return static_cast<LeafMask>(static_cast<unsigned>(a) & ~static_cast<unsigned>(b));
}

inline constexpr LeafMask kAnyLeaf = static_cast<LeafMask>((1U << kLeafCount) - 1U);
inline constexpr LeafMask kOperational = any_of(Leaf::AUTO_IDLE, Leaf::AUTO_RUNNING, Leaf::AUTO_PAUSED,
                                                Leaf::MANUAL_IDLE, Leaf::MANUAL_JOGGING, Leaf::MANUAL_RUNNING,
                                                Leaf::BRAKE_TEST);
inline constexpr LeafMask kStopping = any_of(Leaf::STOPPING_CAT1, Leaf::STOPPING_CAT2);
inline constexpr LeafMask kPowered = join(mask_of(Leaf::ARMING), kOperational, kStopping);
// @req ST-CAT1-COMPLETES
inline constexpr LeafMask kOperationalOrCat2 = join(kOperational, mask_of(Leaf::STOPPING_CAT2));
inline constexpr LeafMask kAnyButLockout = without(kAnyLeaf, mask_of(Leaf::ERROR_LOCKOUT));
inline constexpr LeafMask kIdleOrPowered = join(mask_of(Leaf::IDLE), kPowered);
inline constexpr LeafMask kOpIdle = any_of(Leaf::AUTO_IDLE, Leaf::MANUAL_IDLE);  // SPEC §12: where a brake test starts
inline constexpr LeafMask kManualMoving = any_of(Leaf::MANUAL_RUNNING, Leaf::MANUAL_JOGGING);  // SPEC §11 rule 8

struct Transition {
  LeafMask from;
  Trigger trigger;
  Guard guard;
  Leaf to;
  StopCat stop;
  AlarmMask alarms;  // alarms this row's condition raises
  Effect effect;
  const char* rule;  // SPEC §4 reference, for the documentation
  const char* id;    // stable requirement id: docs/traceability.md, tests tag it with `@req`
};

// clang-format off
inline constexpr auto kTransitions = [] {
  using enum Leaf;
  using enum Trigger;
  using enum StopCat;
  using enum AlarmId;
  using enum Effect;
  constexpr AlarmMask kRule1 = bit(ESTOP_DISCREPANCY) | bit(GATE_DISCREPANCY) | bit(ENABLE_DISCREPANCY) |
                               bit(FIELDBUS_LOST) | bit(INTEGRITY_FAULT) | bit(BOOT_FAILED) | bit(CONTACTOR_WELDED) |
                               bit(FIELD_DISCREPANCY) | bit(CHANNEL_MISMATCH) | bit(CHANNEL_LOST) |
                               bit(ENCODER_DISCREPANCY) | bit(SAFETY_LINK_FAULT);
  constexpr AlarmMask kRule3 = bit(DRIVE_FAULT) | bit(T1_SPEED_EXCEEDED) | bit(STOP_TIME_EXCEEDED) |
                               bit(BRAKE_NOT_ENGAGED) | bit(JOINT_LIMIT) | bit(ZONE_VIOLATION) |
                               bit(ORIENTATION_LIMIT) | bit(SPEED_LIMIT) | bit(SEPARATION_VIOLATED);
  return std::array<Transition, 43>{{
  // from                       trigger             guard         to                  stop  alarm                  effect            rule          id
  // ---- conditions, in priority order (SPEC §4, first table) -----------------------------------------------------------------------------
  {kAnyLeaf,                    lockout_condition,  kNoGuard,     ERROR_LOCKOUT,      CAT0, kRule1,                abort_program,    "1",          "TR-C1"},
  {kAnyButLockout,              estop_pressed,      kNoGuard,     ESTOP_ACTIVE,       CAT0, bit(ESTOP_PRESSED),    abort_program,    "2",          "TR-C2"},
  {kPowered,                    stop_fault,         kNoGuard,     IDLE,               CAT0, kRule3,                abort_program,    "3",          "TR-C3"},
  {kOperationalOrCat2,          gate_open_in_auto,  kNoGuard,     IDLE,               CAT1, bit(PROTECTIVE_STOP),  abort_program,    "4",          "TR-C4"},
  {only(ARMING),                gate_open_in_auto,  kNoGuard,     IDLE,               CAT0, bit(PROTECTIVE_STOP),  abort_program,    "4b",         "TR-C4b"},
  {kOperationalOrCat2,          enable_left_centre, kNoGuard,     IDLE,               CAT1, bit(ENABLING_PANIC),   abort_program,    "5",          "TR-C5"},
  {only(ARMING),                enable_left_centre, kNoGuard,     IDLE,               CAT0, bit(ENABLING_PANIC),   abort_program,    "5b",         "TR-C5b"},
  {kOperationalOrCat2,          mode_changed,       kNoGuard,     IDLE,               CAT1, bit(MODE_CHANGED),     abort_program,    "6",          "TR-C6"},
  {only(ARMING),                mode_changed,       kNoGuard,     IDLE,               CAT0, bit(MODE_CHANGED),     abort_program,    "6",          "TR-C6b"},
  {only(MANUAL_JOGGING),        jog_timeout,        kNoGuard,     MANUAL_IDLE,        CAT2, bit(JOG_LINK_LOST),    none,             "7",          "TR-C7"},
  {only(AUTO_RUNNING),          collision,          kNoGuard,     AUTO_PAUSED,        CAT2, bit(COLLISION),        back_off,         "8",          "TR-C8"},
  {kManualMoving,               collision,          kNoGuard,     MANUAL_IDLE,        CAT2, bit(COLLISION),        back_off_abort,   "8",          "TR-C8b"},
  {only(AUTO_RUNNING),          person_in_field,    kNoGuard,     AUTO_PAUSED,        CAT2, bit(PERSON_IN_FIELD),  field_pause,      "9",          "TR-C9"},
  {only(BRAKE_TEST),            brake_test_failed,  kNoGuard,     IDLE,               CAT1, bit(BRAKE_TEST_FAILED), none,            "10",         "TR-C10"},
  // ---- events and commands (SPEC §4, second table) --------------------------------------------------------------------------------------
  {only(BOOT),                  boot_passed,        kNoGuard,     ESTOP_RESET_NEEDED, NONE, 0,                     none,             "boot",       "TR-BOOT"},
  {only(ESTOP_ACTIVE),          estop_released,     kNoGuard,     ESTOP_RESET_NEEDED, NONE, 0,                     none,             "estop",      "TR-ESTOP-RELEASED"},
  {only(ESTOP_RESET_NEEDED),    reset,              kBootDone,    IDLE,               NONE, 0,                     none,             "reset",      "TR-RESET-ESTOP"},
  {only(IDLE),                  reset,              kCausesGone,  SAME,               NONE, 0,                     reset_alarms,     "reset",      "TR-RESET-IDLE"},
  {kOperational,                reset,              kNoGuard,     SAME,               NONE, 0,                     none,             "reset",      "TR-RESET-OP"},
  {only(IDLE),                  servo_on,           kServoOn,     ARMING,             NONE, 0,                     begin_arming,     "servo_on",   "TR-SERVO-ON"},
  {only(ARMING),                arming_complete,    kNoGuard,     OP_IDLE,            NONE, 0,                     none,             "arming",     "TR-ARMING-DONE"},
  {only(ARMING),                arming_timeout,     kNoGuard,     IDLE,               CAT0, bit(ARMING_TIMEOUT),   none,             "arming",     "TR-ARMING-TIMEOUT"},
  {only(ARMING),                servo_off,          kNoGuard,     IDLE,               CAT0, 0,                     none,             "servo_off",  "TR-SERVO-OFF-ARMING"},
  {kOperationalOrCat2,          servo_off,          kNoGuard,     IDLE,               CAT1, 0,                     abort_program,    "servo_off",  "TR-SERVO-OFF"},
  {only(AUTO_IDLE),             start,              kStartAuto,   AUTO_RUNNING,       NONE, 0,                     start_program,    "start",      "TR-START-AUTO"},
  {only(AUTO_RUNNING),          pause,              kNoGuard,     AUTO_PAUSED,        CAT2, 0,                     none,             "pause",      "TR-PAUSE-AUTO"},
  {only(AUTO_RUNNING),          stop,               kNoGuard,     AUTO_IDLE,          CAT2, 0,                     abort_program,    "stop",       "TR-STOP-RUNNING"},
  {only(AUTO_PAUSED),           stop,               kNoGuard,     AUTO_IDLE,          NONE, 0,                     abort_program,    "stop",       "TR-STOP-PAUSED"},
  {only(AUTO_PAUSED),           resume,             kResume,      AUTO_RUNNING,       NONE, 0,                     resume_program,   "resume",     "TR-RESUME"},
  {only(AUTO_PAUSED),           fields_clear,       kNoGuard,     AUTO_RUNNING,       NONE, 0,                     resume_program,   "fields",     "TR-AUTO-RESUME"},
  {only(AUTO_RUNNING),          program_finished,   kNoGuard,     AUTO_IDLE,          NONE, 0,                     abort_program,    "program",    "TR-FINISHED-AUTO"},
  {only(MANUAL_IDLE),           jog,                kEnableHeld,  MANUAL_JOGGING,     NONE, 0,                     jog_keepalive,    "jog",        "TR-JOG"},
  {only(MANUAL_JOGGING),        jog,                kEnableHeld,  SAME,               NONE, 0,                     jog_keepalive,    "jog",        "TR-JOG-KEEPALIVE"},
  {only(MANUAL_JOGGING),        jog_stop,           kNoGuard,     MANUAL_IDLE,        CAT2, 0,                     none,             "jog_stop",   "TR-JOG-STOP"},
  {only(MANUAL_IDLE),           start,              kStartManual, MANUAL_RUNNING,     NONE, 0,                     start_program,    "start",      "TR-START-MANUAL"},
  {only(MANUAL_RUNNING),        pause,              kNoGuard,     MANUAL_IDLE,        CAT2, 0,                     abort_program,    "pause",      "TR-PAUSE-MANUAL"},
  {only(MANUAL_RUNNING),        stop,               kNoGuard,     MANUAL_IDLE,        CAT2, 0,                     abort_program,    "stop",       "TR-STOP-MANUAL"},
  {only(MANUAL_RUNNING),        program_finished,   kNoGuard,     MANUAL_IDLE,        CAT2, 0,                     abort_program,    "program",    "TR-FINISHED-MANUAL"},
  {kStopping,                   standstill,         kNoGuard,     STOP_TARGET,        NONE, 0,                     none,             "standstill", "TR-STANDSTILL"},
  {kIdleOrPowered,              confirm_t2,         kT2Selected,  SAME,               NONE, 0,                     set_t2_confirmed, "confirm_t2", "TR-CONFIRM-T2"},
  {only(IDLE),                  validate_config,    kValidate,    SAME,               NONE, 0,                     set_validated,    "validate_config", "TR-VALIDATE"},
  {kOpIdle,                     brake_test,         kBrakeTest,   BRAKE_TEST,         NONE, 0,                     begin_brake_test, "brake_test", "TR-BRAKE-TEST"},
  {only(BRAKE_TEST),            brake_test_passed,  kNoGuard,     OP_IDLE,            NONE, 0,                     none,             "brake_test", "TR-BRAKE-TEST-PASSED"},
  }};
}();
// clang-format on
inline constexpr std::size_t kTransitionCount = kTransitions.size();

// Index: for each (leaf, trigger) the one row that applies, or kNoRow. Built at compile
// time from the table, so a dispatch is one lookup.
inline constexpr std::uint8_t kNoRow = 0xFF;
using TransitionIndex = std::array<std::array<std::uint8_t, kTriggerCount>, kLeafCount>;

[[nodiscard]] constexpr TransitionIndex build_index() noexcept {
  TransitionIndex idx{};
  for (auto& row : idx) {
    row.fill(kNoRow);
  }
  for (std::size_t r = 0; r < kTransitions.size(); ++r) {
    for (std::size_t l = 0; l < kLeafCount; ++l) {
      if ((kTransitions[r].from & (1U << l)) != 0U) {
        auto& cell = idx[l][static_cast<std::size_t>(kTransitions[r].trigger)];
        if (cell == kNoRow) {
          cell = static_cast<std::uint8_t>(r);
        }
      }
    }
  }
  return idx;
}
inline constexpr TransitionIndex kIndex = build_index();

// Table well-formedness, checked at compile time: at most one row per (leaf, trigger),
// targets that exist, stop categories that make sense for their target.
[[nodiscard]] constexpr bool table_is_well_formed() noexcept {
  for (std::size_t a = 0; a < kTransitions.size(); ++a) {
    const Transition& t = kTransitions[a];
    if (t.from == 0U || without(t.from, kAnyLeaf) != 0U) {
      return false;
    }
    if (t.stop == StopCat::CAT0 && (t.to == Leaf::SAME || t.to == Leaf::STOP_TARGET)) {
      return false;
    }
    if ((t.stop == StopCat::CAT1 || t.stop == StopCat::CAT2) && (t.to == Leaf::SAME || t.to == Leaf::STOP_TARGET)) {
      return false;
    }
    for (std::size_t b = a + 1; b < kTransitions.size(); ++b) {
      if (kTransitions[b].trigger == t.trigger && (kTransitions[b].from & t.from) != 0U) {
        return false;
      }
    }
  }
  return kTransitions.size() < kNoRow;
}
static_assert(table_is_well_formed(), "transition table: overlapping rows or impossible targets");

// Requirement ids are unique, so a test tagged with one names exactly one row.
[[nodiscard]] constexpr bool row_ids_are_unique() noexcept {
  for (std::size_t a = 0; a < kTransitions.size(); ++a) {
    for (std::size_t b = a + 1; b < kTransitions.size(); ++b) {
      if (std::string_view(kTransitions[a].id) == std::string_view(kTransitions[b].id)) {
        return false;
      }
    }
  }
  return true;
}
static_assert(row_ids_are_unique(), "transition table: two rows share a requirement id");

// The first-out cause is set by every stopping row; E-stop and lockout must be Cat 0.
[[nodiscard]] constexpr bool estop_and_lockout_rows_are_cat0() noexcept {
  for (const Transition& t : kTransitions) {
    if ((t.to == Leaf::ESTOP_ACTIVE || t.to == Leaf::ERROR_LOCKOUT) && t.stop != StopCat::CAT0) {
      return false;
    }
  }
  return true;
}
static_assert(estop_and_lockout_rows_are_cat0(), "rows into ESTOP_ACTIVE / ERROR_LOCKOUT must be Cat 0");

[[nodiscard]] constexpr const Transition* find_row(Leaf from, Trigger trigger) noexcept {
  const std::uint8_t r = kIndex[static_cast<std::size_t>(from)][static_cast<std::size_t>(trigger)];
  return (r == kNoRow) ? nullptr : &kTransitions[r];
}

// Refusals that do not depend on a row (SPEC §5): per leaf, the answer to a command
// for which the leaf has no row. `refuse_all`: the leaf answers every command so.
// @req RES-ESTOP RES-RESET-NEEDED RES-LOCKED-OUT RES-WRONG-STATE
struct LeafPolicy {
  Result no_row;
  bool refuse_all;
};
inline constexpr std::array<LeafPolicy, kLeafCount> kLeafPolicy{{
    {Result::WRONG_STATE, false},     // BOOT
    {Result::LOCKED_OUT, true},       // ERROR_LOCKOUT
    {Result::ESTOP_ACTIVE, true},     // ESTOP_ACTIVE
    {Result::RESET_REQUIRED, false},  // ESTOP_RESET_NEEDED: anything but reset
    {Result::WRONG_STATE, false},     // IDLE
    {Result::BUSY, false},            // ARMING
    {Result::WRONG_STATE, false},     // AUTO_IDLE
    {Result::WRONG_STATE, false},     // AUTO_RUNNING
    {Result::WRONG_STATE, false},     // AUTO_PAUSED
    {Result::WRONG_STATE, false},     // MANUAL_IDLE
    {Result::WRONG_STATE, false},     // MANUAL_JOGGING
    {Result::WRONG_STATE, false},     // MANUAL_RUNNING
    {Result::BUSY, false},            // STOPPING_CAT1
    {Result::BUSY, false},            // STOPPING_CAT2
    {Result::WRONG_STATE, false},     // BRAKE_TEST
}};

}  // namespace safestate::core

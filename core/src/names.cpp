// Names of SPEC.md, one table per enum, used both ways (to_string and parse).
#include <array>
#include <cstring>

#include "safestate/core/alarms.hpp"
#include "safestate/core/cia402.hpp"
#include "safestate/core/states.hpp"
#include "safestate/core/transitions.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

namespace {

template <typename E, std::size_t N>
const char* name_in(const std::array<const char*, N>& names, E v, const char* unknown = "?") noexcept {
  const auto i = static_cast<std::size_t>(v);
  // cppcheck-suppress CastIntegerToAddressAtReturn ; false positive of cppcheck 2.10: names[i] is a const char*
  return (i < N) ? names[i] : unknown;
}

template <typename E, std::size_t N>
bool parse_in(const std::array<const char*, N>& names, const char* s, E& out) noexcept {
  if (s == nullptr) {
    return false;
  }
  for (std::size_t i = 0; i < N; ++i) {
    if (std::strcmp(names[i], s) == 0) {
      out = static_cast<E>(i);
      return true;
    }
  }
  return false;
}

constexpr std::array<const char*, kStateCount> kStateNames{
    "BOOT", "ERROR_LOCKOUT", "ESTOP_ACTIVE", "ESTOP_RESET_NEEDED", "IDLE", "ARMING", "OPERATIONAL", "STOPPING"};
constexpr std::array<const char*, 8> kSubNames{"-",           "AUTO_IDLE",      "AUTO_RUNNING",  "AUTO_PAUSED",
                                               "MANUAL_IDLE", "MANUAL_JOGGING", "MANUAL_RUNNING", "BRAKE_TEST"};
constexpr std::array<const char*, 4> kModeNames{"NONE", "AUTO", "T1", "T2"};
constexpr std::array<const char*, 4> kStopNames{"-", "CAT0", "CAT1", "CAT2"};
constexpr std::array<const char*, kResultCount> kResultNames{
    "OK",           "UNKNOWN_COMMAND",       "BAD_ARGUMENT", "NOT_CONTROL_OWNER", "LOCKED_OUT",
    "ESTOP_ACTIVE", "RESET_REQUIRED",        "FAULT_PRESENT", "MODE_INVALID",     "MODE_BY_SELECTOR_ONLY",
    "GATE_OPEN",    "ENABLING_NOT_HELD",     "T2_NOT_CONFIRMED", "JOG_NOT_IN_AUTO", "NO_PROGRAM",
    "BUSY",         "WRONG_STATE",           "QUEUE_FULL", "CONFIG_NOT_VALIDATED", "CHECKSUM_MISMATCH",
    "OUTSIDE_LIMITS", "FIELD_INTERRUPTED",   "BRAKE_TEST_REQUIRED"};
constexpr std::array<const char*, kCommandCount> kCommandNames{
    "reset", "servo_on", "servo_off", "start", "pause", "resume", "stop", "jog", "jog_stop", "confirm_t2", "set_mode",
    "validate_config", "brake_test"};
constexpr std::array<const char*, kSourceCount> kSourceNames{"pendant", "remote", "observer", "reset_button"};
constexpr std::array<const char*, 21> kSignalNames{"none",      "estop", "gate",  "enable",   "mode",    "reset_button",
                                                   "drive",     "contactor", "brake", "fieldbus", "command", "internal",
                                                   "axis",      "tcp",       "zone",  "reduced",
                                                   "field.outer", "field.inner", "separation", "channel",
                                                   "safety_link"};
constexpr std::array<const char*, 7> kLinkErrorNames{"none",    "crc",           "sequence", "identity",
                                                     "timeout", "not_connected", "length"};
constexpr std::array<const char*, 5> kChannelNames{"none", "a", "b", "both", "panic"};
constexpr std::array<const char*, 9> kCrossFieldNames{"none",    "cycle",   "state",           "sub",    "stop",
                                                      "alarms",  "outputs", "brake_test_axis", "replies"};
constexpr std::array<const char*, 3> kStepNames{"CONTACTOR", "DRIVES", "BRAKES"};
constexpr std::array<const char*, 18> kLeafNames{
    "BOOT",         "ERROR_LOCKOUT", "ESTOP_ACTIVE",   "ESTOP_RESET_NEEDED", "IDLE",          "ARMING",
    "AUTO_IDLE",    "AUTO_RUNNING",  "AUTO_PAUSED",    "MANUAL_IDLE",        "MANUAL_JOGGING", "MANUAL_RUNNING",
    "STOPPING_CAT1", "STOPPING_CAT2", "BRAKE_TEST",    "(same)",        "OPERATIONAL (AUTO_IDLE or MANUAL_IDLE by mode)",
    "(the stop's target)"};
constexpr std::array<const char*, kTriggerCount> kTriggerNames{
    "discrepancy > limit (also of the protective fields), fieldbus lost, integrity check failed, boot failed",
    "estop pressed",
    "drive fault, T1 speed of TCP or link origin > limit, stop time exceeded, brake not engaged, "
    "a safe limit violated (joint, zone, orientation, speed), separation violated (SSM)",
    "gate open while mode=AUTO",
    "enable leaves centre while mode is T1/T2",
    "mode changes (including to NONE)",
    "jog keep-alive older than jog_timeout_ms",
    "collision: the force at the TCP estimated from the drives' torques above the region's F_qs (pfl on)",
    "inner protective field interrupted while collaborative operation is on (AUTO)",
    "a brake test fails (an axis drifted more than max_drift_deg)",
    "self-test passed, fieldbus up, all drives answer",
    "estop released on both channels",
    "all arming steps done (CONTACTOR, DRIVES, BRAKES)",
    "an arming step timed out",
    "program finished",
    "standstill reached (Cat 1: and brakes engaged)",
    "paused by rule 9; both fields clear for resume_delay_ms, auto_resume on",
    "brake test: every axis tested and held",
    "reset", "servo_on", "servo_off", "start", "pause", "resume", "stop", "jog", "jog_stop", "confirm_t2", "set_mode",
    "validate_config", "brake_test"};
constexpr std::array<const char*, 13> kEffectNames{"-",           "clear latched alarms, acknowledge drive faults",
                                                  "arm from step CONTACTOR", "start program from first waypoint",
                                                  "resume program, re-planned from measured position",
                                                  "discard program", "restart jog keep-alive",
                                                  "T2 confirmed until the mode changes",
                                                  "configuration validated (written to the event log)",
                                                  "the pause may resume by itself (auto_resume)",
                                                  "brake test from axis 1 (SPEC §12)",
                                                  "back off 10 mm along the path, then hold (program kept)",
                                                  "back off 10 mm along the path, then hold; discard program"};
constexpr std::array<const char*, kAlarmCount> kAlarmNames = [] {
  std::array<const char*, kAlarmCount> n{};
  for (std::size_t i = 0; i < kAlarmCount; ++i) {
    n[i] = kAlarms[i].name;
  }
  return n;
}();
constexpr std::array<const char*, 4> kSeverityNames{"info", "warning", "fault", "lockout"};
constexpr std::array<const char*, 9> kDriveStateNames{
    "Not ready to switch on", "Switch on disabled", "Ready to switch on", "Switched on", "Operation enabled",
    "Quick stop active",      "Fault reaction active", "Fault",            "Unknown"};

}  // namespace

const char* to_string(State s) noexcept { return name_in(kStateNames, s); }
const char* to_string(Sub s) noexcept { return name_in(kSubNames, s); }
const char* to_string(Mode m) noexcept { return name_in(kModeNames, m); }
const char* to_string(StopCat c) noexcept { return name_in(kStopNames, c); }
const char* to_string(Result r) noexcept { return name_in(kResultNames, r); }
const char* to_string(CommandId c) noexcept { return name_in(kCommandNames, c); }
const char* to_string(Source s) noexcept { return name_in(kSourceNames, s); }
const char* to_string(Signal s) noexcept { return name_in(kSignalNames, s); }
const char* to_string(LinkError e) noexcept { return name_in(kLinkErrorNames, e); }
const char* to_string(Channel c) noexcept { return name_in(kChannelNames, c); }
const char* to_string(ArmingStep s) noexcept { return name_in(kStepNames, s); }
const char* to_string(CrossField f) noexcept { return name_in(kCrossFieldNames, f); }
const char* to_string(Leaf l) noexcept { return name_in(kLeafNames, l); }
const char* to_string(Trigger t) noexcept { return name_in(kTriggerNames, t); }
const char* to_string(Effect e) noexcept { return name_in(kEffectNames, e); }
const char* to_string(AlarmId id) noexcept { return name_in(kAlarmNames, id); }
const char* to_string(Severity s) noexcept { return name_in(kSeverityNames, s); }
namespace cia402 {
const char* to_string(DriveState s) noexcept { return name_in(kDriveStateNames, s); }
}  // namespace cia402

bool parse_command(const char* name, CommandId& out) noexcept { return parse_in(kCommandNames, name, out); }
bool parse_mode(const char* name, Mode& out) noexcept { return parse_in(kModeNames, name, out); }
bool parse_result(const char* name, Result& out) noexcept { return parse_in(kResultNames, name, out); }
bool parse_state(const char* name, State& out) noexcept { return parse_in(kStateNames, name, out); }
bool parse_sub(const char* name, Sub& out) noexcept { return parse_in(kSubNames, name, out); }
bool parse_alarm(const char* name, AlarmId& out) noexcept { return parse_in(kAlarmNames, name, out); }

Leaf leaf_of(const StateVariant& s) noexcept {
  if (const auto* op = std::get_if<StOperational>(&s)) {
    return leaf_of_sub(op->sub);
  }
  if (const auto* st = std::get_if<StStopping>(&s)) {
    return (st->category == StopCat::CAT1) ? Leaf::STOPPING_CAT1 : Leaf::STOPPING_CAT2;
  }
  // BOOT..ARMING: the variant index is the leaf.
  return static_cast<Leaf>(s.index());
}

}  // namespace safestate::core

// SafeState core vocabulary: every name of SPEC.md spelled the same way, so one grep
// finds the contract and the code. No heap, no exceptions, no OS: builds for a
// Cortex-M4 as well as Linux.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace safestate::core {

inline constexpr std::size_t kAxes = 6;

// All timing inside the core is counted in scan cycles (SPEC §1), never read from a clock.
using Cycle = std::uint64_t;

// SPEC §3 `state`. Order is the order of the alternatives of StateVariant.
enum class State : std::uint8_t {
  BOOT,
  ERROR_LOCKOUT,
  ESTOP_ACTIVE,
  ESTOP_RESET_NEEDED,
  IDLE,
  ARMING,
  OPERATIONAL,
  STOPPING,
};
inline constexpr std::size_t kStateCount = 8;

// SPEC §3 `sub` (NONE = null outside OPERATIONAL).
enum class Sub : std::uint8_t {
  NONE,
  AUTO_IDLE,
  AUTO_RUNNING,
  AUTO_PAUSED,
  MANUAL_IDLE,
  MANUAL_JOGGING,
  MANUAL_RUNNING,
  BRAKE_TEST,  // SPEC §12 (appended: the older values keep their place)
};

// SPEC §2 mode selector.
enum class Mode : std::uint8_t { NONE, AUTO, T1, T2 };

// IEC 60204-1 stop categories; NONE = null.
enum class StopCat : std::uint8_t { NONE, CAT0, CAT1, CAT2 };

// SPEC §5 command results, in the spec's order.
enum class Result : std::uint8_t {
  OK,
  UNKNOWN_COMMAND,
  BAD_ARGUMENT,
  NOT_CONTROL_OWNER,
  LOCKED_OUT,
  ESTOP_ACTIVE,
  RESET_REQUIRED,
  FAULT_PRESENT,
  MODE_INVALID,
  MODE_BY_SELECTOR_ONLY,
  GATE_OPEN,
  ENABLING_NOT_HELD,
  T2_NOT_CONFIRMED,
  JOG_NOT_IN_AUTO,
  NO_PROGRAM,
  BUSY,
  WRONG_STATE,
  QUEUE_FULL,
  // SPEC §10-§12 (appended: the numbers of the older results keep their place).
  CONFIG_NOT_VALIDATED,
  CHECKSUM_MISMATCH,
  OUTSIDE_LIMITS,
  FIELD_INTERRUPTED,
  BRAKE_TEST_REQUIRED,
};
inline constexpr std::size_t kResultCount = 23;

// SPEC §4 commands, spelled as on the wire and in .scn files.
enum class CommandId : std::uint8_t {
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
  validate_config,  // SPEC §10: the operator confirms the safety configuration's checksum
  brake_test,       // SPEC §12: test the six holding brakes in turn
};
inline constexpr std::size_t kCommandCount = 13;

// Who sent a command (single point of control, ISO 10218-1 5.3.5).
enum class Source : std::uint8_t { pendant, remote, observer, reset_button };
inline constexpr std::size_t kSourceCount = 4;

// The fixed-size binary command record: raw fields so that the core itself validates
// them (a malformed command is refused with UNKNOWN_COMMAND / BAD_ARGUMENT, SPEC §5).
struct Command {
  std::uint32_t seq = 0;
  std::uint8_t id = 0;      // CommandId value
  std::uint8_t source = 0;  // Source value
  std::int8_t axis = 0;     // jog: 1..6
  std::int8_t dir = 0;      // jog: +1 / -1
  std::uint8_t speed = 0;   // jog: percent 1..100
  std::uint8_t mode = 0;    // set_mode: Mode value
  std::uint8_t has_code = 0;  // validate_config: 1 when `code` holds the 8 hex digits typed
  std::uint32_t code = 0;     // validate_config: the checksum typed by the operator
};

// `jog AXIS DIR [SPEED]` (SPEC §5) as a command record, built in one place for every front
// end (protocol, scenario files, tools). The values are passed on as given, an invalid one
// as 0: the core itself answers BAD_ARGUMENT.
inline constexpr std::uint8_t kJogDefaultSpeedPct = 10;
// "+" -> +1, "-" -> -1, anything else 0.
[[nodiscard]] constexpr std::int8_t jog_direction(std::string_view s) noexcept {
  if (s == "+") {
    return 1;
  }
  return (s == "-") ? std::int8_t{-1} : std::int8_t{0};
}
constexpr void set_jog(Command& c, std::int8_t axis, std::int8_t dir, std::uint8_t speed) noexcept {
  c.axis = axis;
  c.dir = dir;
  c.speed = speed;
}

// One answer per command. `cmd`/`source` are the raw values received, so that an
// unknown command is reported as what it was, not as a valid one.
struct Reply {
  std::uint32_t seq = 0;
  std::uint8_t cmd = 0;     // CommandId value, or the unknown value received
  std::uint8_t source = 0;  // Source value, or the unknown value received
  Result result = Result::OK;
};

// Which physical contact a cause refers to.
// SPEC §10 adds the safe limits' subjects: a joint (`axis.N`), the TCP (`tcp`), a zone
// (`code` = its index in the configuration, named by its name) and the reduced input.
// SPEC §11 adds the protective fields (`field.outer`, `field.inner`, dual channel) and the
// distance sensor (`separation`).
enum class Signal : std::uint8_t {
  none, estop, gate, enable, mode, reset_button, drive, contactor, brake, fieldbus, command, internal,
  axis, tcp, zone, reduced,
  field_outer, field_inner, separation,
  channel,  // SPEC §14: a safety channel (CHANNEL_LOST: which; CHANNEL_MISMATCH: code = the CrossField)
  // Issue 37, the black channel: a safety connection (SAFETY_LINK_FAULT: channel = the one
  // hosting it, code = the connection id, axis = the LinkError).
  safety_link,
};
enum class Channel : std::uint8_t { none, a, b, both, panic };

// SPEC §14: the fields of the cross-channel digest a mismatch names, in the order compared.
enum class CrossField : std::uint8_t { none, cycle, state, sub, stop, alarms, outputs, brake_test_axis, replies };
const char* to_string(CrossField f) noexcept;

// Issue 37: what a safety connection's check found (docs/black-channel.md; safelink's verdicts,
// named the same): a corrupted container (crc), a repeated, lost or out-of-order one
// (sequence), another connection's or device's (identity), none new within the watchdog
// (timeout), nothing valid from the device at all (not_connected), a wrong size (length).
enum class LinkError : std::uint8_t { none, crc, sequence, identity, timeout, not_connected, length };
const char* to_string(LinkError e) noexcept;

// ARMING steps (SPEC §4): contactor, then drives, then brakes.
enum class ArmingStep : std::uint8_t { CONTACTOR, DRIVES, BRAKES };

// Names, exactly as in SPEC.md. Pure lookups, usable on a microcontroller.
const char* to_string(State s) noexcept;
const char* to_string(Sub s) noexcept;   // "-" for NONE
const char* to_string(Mode m) noexcept;
const char* to_string(StopCat c) noexcept;  // "-" for NONE
const char* to_string(Result r) noexcept;
const char* to_string(CommandId c) noexcept;
const char* to_string(Source s) noexcept;
const char* to_string(Signal s) noexcept;
const char* to_string(Channel c) noexcept;
const char* to_string(ArmingStep s) noexcept;

// Reverse lookups for parsers at the boundary (scenario files, gateway). Return false
// and leave `out` untouched when the name is unknown.
bool parse_command(const char* name, CommandId& out) noexcept;
bool parse_mode(const char* name, Mode& out) noexcept;
bool parse_result(const char* name, Result& out) noexcept;
bool parse_state(const char* name, State& out) noexcept;
bool parse_sub(const char* name, Sub& out) noexcept;

}  // namespace safestate::core

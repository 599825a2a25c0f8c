// Parser of .scn files (spec/scenario-format.md). One pass, line by line; the first
// problem stops the parse and is reported as FILE:LINE: what is wrong (exit 2).
//
// Decisions beyond the format spec (the spec says what is valid; these say how strictly):
//  - `#` starts a comment anywhere on a line; blank and comment-only lines are ignored;
//    tokens are separated by spaces, tabs or a CR (CRLF files work).
//  - `config NAME=VALUE ...` is allowed only before the first `@` line. NAME is one of
//    cycle_us, discrepancy_ms, jog_timeout_ms, max_stop_ms, boot_timeout_ms,
//    max_commands_per_cycle, reset_hold_ms, fault_reset_cycles, queue_size (unsigned
//    integers), standstill_rad_s and t1_speed_mm_s (numbers). A later line overrides an
//    earlier one.
//    When the config section ends (first `@` line or end of file) core::validate() runs;
//    its field and reason are reported on the line that last set that field (or on the
//    last config line if the file did not set it).
//  - `@T`: T is a non-negative decimal integer (no sign), at most kMaxTime. A `@T` line
//    whose T is smaller than that of an earlier `@T` line is malformed. `@T1..T2` is only
//    for `expect`, with T1 <= T2, and takes no part in that order: the format spec's rule
//    is about `@T` lines, and the shared scenario t1-jog.scn (SPEC's own example set)
//    writes `@810..1000 expect tcp_speed<=250` after `@970 cmd jog ...`, i.e. a range
//    after the actions it watches. A range acts on nothing and is checked over its
//    whole span whatever its place in the file, so its place cannot change a run. The
//    steps are then sorted by their (first) cycle, keeping file order within a cycle:
//    only ranges move.
//  - `in`: at least one KEY=VALUE; shorthands and raw contacts exactly as in the spec;
//    enable=panic sets panic=1 and a=b=0; mode=NONE opens all three contacts.
//  - `cmd`: the core, not the parser, judges commands. An unknown NAME is sent with the
//    out-of-range id core::kCommandCount (the core answers UNKNOWN_COMMAND; its arguments
//    are ignored). A missing, unparseable or out-of-range argument of `jog` or `set_mode`
//    (or one too many) is still sent, with an invalid value (axis 0, dir 0, speed 0,
//    mode 0), so that the core answers BAD_ARGUMENT; a field that fits keeps the value
//    written (axis 9 is sent as 9). A known command that takes no argument but is given
//    one is malformed: the binary record has no room for it, so it would be dropped
//    silently. `from=` must be the first token after `cmd` and be pendant or remote.
//    Each command's seq is its line number (unique; the reset button's replies use 0).
//  - `fault`: exactly the forms of the spec, N a decimal 1..6; `statusword` takes 0x and
//    one to four hex digits, `slow_enable` 1..60000 ms.
//  - `expect`: at least one key; `tcp_speed` takes <=, <, >=, > and a finite number;
//    every other key takes `=` and a value of the spec (sub and stop use `-` for null).
//    Unknown keys or values are malformed; `reply=` and `reply.CMD=` accept result names
//    and `pending`. The keys of "More keys, faults and settings" likewise: `axis.N.` with N
//    1..6, `controlword` as 0x and one to four hex digits, speeds with a comparison;
//    `cause.signal=-` is accepted for "no cause". `replies=N` must be alone on an
//    `expect` line (not `expect-once`). `expect-once` takes a window like `expect`.
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "safestate/core/alarms.hpp"
#include "safestate/core/cia402.hpp"
#include "safestate/motion/motion_controller.hpp"
#include "safestate/scenario/scenario.hpp"
#include "parse_util.hpp"
#include "brake_keys.hpp"
#include "channel_keys.hpp"
#include "person_keys.hpp"
#include "safety_keys.hpp"

namespace safestate::scenario {

std::string ParseError::text() const { return file + ":" + std::to_string(line) + ": " + message; }

namespace {

using util::lookup;
using util::Problem;
using util::quoted;
using util::split_pair;
using util::to_number;
using util::to_real;
using util::Tokens;

std::string_view strip_comment(std::string_view s) noexcept {
  const std::size_t hash = s.find('#');
  return (hash == std::string_view::npos) ? s : s.substr(0, hash);
}

// ---------------------------------------------------------------------------------------
// config

// The file's names (spec/scenario-format.md) and the core::Config field each sets; the
// core's name is what core::validate() reports.
struct ConfigField {
  const char* name;
  const char* core_name;
  std::uint32_t core::Config::*uint_field;  // nullptr for the real-valued ones
  float core::Config::*real_field;
};

constexpr std::array<ConfigField, 15> kConfigFields{{
    {"cycle_us", "cycle_us", &core::Config::cycle_us, nullptr},
    {"discrepancy_ms", "discrepancy_ms", &core::Config::discrepancy_ms, nullptr},
    {"jog_timeout_ms", "jog_timeout_ms", &core::Config::jog_timeout_ms, nullptr},
    {"max_stop_ms", "max_stop_ms", &core::Config::max_stop_ms, nullptr},
    {"boot_timeout_ms", "boot_timeout_ms", &core::Config::boot_timeout_ms, nullptr},
    {"standstill_rad_s", "standstill_rad_s", nullptr, &core::Config::standstill_rad_s},
    {"max_commands_per_cycle", "max_commands_per_cycle", &core::Config::max_commands_per_cycle, nullptr},
    {"reset_hold_ms", "reset_hold_max_ms", &core::Config::reset_hold_max_ms, nullptr},
    {"fault_reset_cycles", "fault_reset_reply_cycles", &core::Config::fault_reset_reply_cycles, nullptr},
    {"queue_size", "queue_size", &core::Config::queue_size, nullptr},
    {"t1_speed_mm_s", "t1_speed_limit_mm_s", nullptr, &core::Config::t1_speed_limit_mm_s},
    {"cross_check_cycles", "cross_check_cycles", &core::Config::cross_check_cycles, nullptr},
    {"encoder_tolerance_deg", "encoder_tolerance_deg", nullptr, &core::Config::encoder_tolerance_deg},
    {"encoder_discrepancy_ms", "encoder_discrepancy_ms", &core::Config::encoder_discrepancy_ms, nullptr},
    {"integrity_period_ms", "integrity_period_ms", &core::Config::integrity_period_ms, nullptr},
}};

constexpr std::size_t kMaxStopField = 3;  // max_stop_ms: the safety file's stop.max_time_ms unless set here
static_assert(std::string_view(kConfigFields[kMaxStopField].name) == "max_stop_ms");

Problem set_config(std::string_view key, std::string_view value, core::Config& cfg, std::size_t& index) {
  for (std::size_t i = 0; i < kConfigFields.size(); ++i) {
    const ConfigField& f = kConfigFields[i];
    if (key != f.name) {
      continue;
    }
    index = i;
    if (f.uint_field != nullptr) {
      return to_number(value, cfg.*(f.uint_field))
                 ? Problem{}
                 : "config " + std::string(key) + ": " + quoted(value) + " is not a non-negative integer";
    }
    double v = 0.0;
    if (!to_real(value, v)) {
      return "config " + std::string(key) + ": " + quoted(value) + " is not a number";
    }
    cfg.*(f.real_field) = static_cast<float>(v);
    return {};
  }
  std::string names;
  for (const ConfigField& f : kConfigFields) {
    names += (names.empty() ? "" : ", ") + std::string(f.name);
  }
  return "unknown config name " + quoted(key) + " (expected one of " + names + ")";
}

// ---------------------------------------------------------------------------------------
// in

Problem parse_in(const Tokens& args, InputStep& out) { return vocab::parse_inputs(args, out); }

// ---------------------------------------------------------------------------------------
// cmd

// A field that fits keeps the value written; anything else becomes `invalid`.
template <typename Field>
Field field_or(std::string_view s, Field invalid) noexcept {
  Field v{};
  return to_number(s, v) ? v : invalid;
}

void fill_jog(const Tokens& args, std::size_t first, core::Command& c) noexcept {
  const std::size_t n = args.size() - first;
  core::set_jog(c, (n >= 1) ? field_or<std::int8_t>(args[first], 0) : std::int8_t{0},
                (n >= 2) ? core::jog_direction(args[first + 1]) : std::int8_t{0},
                (n >= 3) ? field_or<std::uint8_t>(args[first + 2], 0) : core::kJogDefaultSpeedPct);
  if (n > 3) {
    c.axis = 0;  // too many arguments: still sent, refused by the core (BAD_ARGUMENT)
  }
}

void fill_set_mode(const Tokens& args, std::size_t first, core::Command& c) noexcept {
  core::Mode m = core::Mode::NONE;
  const bool one_arg = (args.size() - first) == 1;
  c.mode = (one_arg && lookup(args[first], &core::parse_mode, m)) ? static_cast<std::uint8_t>(m) : std::uint8_t{0};
}

Problem parse_from(std::string_view tok, core::Command& c) {
  const std::string_view value = tok.substr(5);
  if (value == "pendant") {
    c.source = static_cast<std::uint8_t>(core::Source::pendant);
  } else if (value == "remote") {
    c.source = static_cast<std::uint8_t>(core::Source::remote);
  } else {
    return "bad from= value " + quoted(value) + " (expected pendant|remote)";
  }
  return {};
}

Problem parse_cmd(const Tokens& args, std::size_t line, CommandStep& out) {
  core::Command& c = out.command;
  c.seq = static_cast<std::uint32_t>(line);
  c.source = static_cast<std::uint8_t>(core::Source::pendant);
  std::size_t i = 0;
  if (!args.empty() && args[0].substr(0, 5) == "from=") {
    if (Problem p = parse_from(args[0], c); !p.empty()) {
      return p;
    }
    i = 1;
  }
  if (i >= args.size()) {
    return "cmd needs a command name";
  }
  out.name = std::string(args[i]);
  core::CommandId id{};
  if (!lookup(args[i], &core::parse_command, id)) {
    c.id = static_cast<std::uint8_t>(core::kCommandCount);  // the core answers UNKNOWN_COMMAND
    return {};
  }
  c.id = static_cast<std::uint8_t>(id);
  if (id == core::CommandId::jog) {
    fill_jog(args, i + 1, c);
  } else if (id == core::CommandId::set_mode) {
    fill_set_mode(args, i + 1, c);
  } else if (id == core::CommandId::validate_config) {
    safety_keys::fill_validate_config(args, i + 1, c);
  } else if (i + 1 < args.size()) {
    return "cmd " + out.name + " takes no argument, found " + quoted(args[i + 1]);
  }
  return {};
}

// ---------------------------------------------------------------------------------------
// fault

using util::axis_1_to_6;
using vocab::hex_word;

Problem parse_fault(const Tokens& args, FaultStep& out) { return vocab::parse_fault(args, out.fault); }

// ---------------------------------------------------------------------------------------
// expect

struct Choice {
  const char* key;
  const char* yes;  // value 1
  const char* no;   // value 0
  ExpectKey id;
};

constexpr std::array<Choice, 4> kChoices{{
    {"contactor", "closed", "open", ExpectKey::contactor},
    {"drives", "enabled", "disabled", ExpectKey::drives},
    {"brakes", "released", "engaged", ExpectKey::brakes},
    {"reset_lamp", "on", "off", ExpectKey::reset_lamp},
}};

bool parse_stop(std::string_view s, core::StopCat& out) noexcept {
  for (std::uint8_t i = 0; i < 4; ++i) {
    const auto c = static_cast<core::StopCat>(i);
    if (s == core::to_string(c)) {
      out = c;
      return true;
    }
  }
  return false;
}

template <typename E>
bool named(std::string_view value, bool (*parse_fn)(const char*, E&) noexcept, Expectation& e) noexcept {
  E v{};
  if (!lookup(value, parse_fn, v)) {
    return false;
  }
  e.value = static_cast<std::uint8_t>(v);
  return true;
}

bool parse_stop_value(std::string_view value, Expectation& e) noexcept {
  core::StopCat c{};
  if (!parse_stop(value, c)) {
    return false;
  }
  e.value = static_cast<std::uint8_t>(c);
  return true;
}

// 1 when `key` is one of the named-value keys; `ok` tells whether the value is known.
bool parse_named_key(std::string_view key, std::string_view value, Expectation& e, bool& ok) noexcept {
  if (key == "state") {
    e.key = ExpectKey::state;
    ok = named(value, &core::parse_state, e);
  } else if (key == "sub") {
    e.key = ExpectKey::sub;
    ok = named(value, &core::parse_sub, e);
  } else if (key == "mode") {
    e.key = ExpectKey::mode;
    ok = named(value, &core::parse_mode, e);
  } else if (key == "stop") {
    e.key = ExpectKey::stop;
    ok = parse_stop_value(value, e);
  } else if (key == "alarm" || key == "noalarm") {
    e.key = (key == "alarm") ? ExpectKey::alarm : ExpectKey::noalarm;
    ok = named(value, &core::parse_alarm, e);
  } else if (key == "reply") {
    e.key = ExpectKey::reply;
    // SPEC §9: `reply=pending` means the latest command has not been answered yet.
    ok = (value == "pending") ? ((e.value = kPendingReply), true) : named(value, &core::parse_result, e);
  } else {
    return false;
  }
  return true;
}

bool parse_choice_key(std::string_view key, std::string_view value, Expectation& e, bool& ok) noexcept {
  for (const Choice& c : kChoices) {
    if (key == c.key) {
      e.key = c.id;
      ok = (value == c.yes) || (value == c.no);
      e.value = (value == c.yes) ? 1U : 0U;
      return true;
    }
  }
  return false;
}

// `NAME<=X`, `<`, `>=`, `>` with a finite number; `rest` is what follows NAME.
Problem parse_compare(std::string_view tok, std::string_view rest, std::string_view name, ExpectKey key,
                      Expectation& e) {
  std::string_view number;
  if (util::compare_op(rest, e.cmp, number)) {
    e.key = key;
    if (!to_real(number, e.limit)) {
      return "expect " + quoted(tok) + ": the speed limit is not a number";
    }
    return {};
  }
  return "expect " + quoted(tok) + ": " + std::string(name) + " takes <=, <, >= or > and a number";
}

// `axis.N.` prefix: N 1..6 into e.axis; the rest after the second dot.
bool axis_prefix(std::string_view key, Expectation& e, std::string_view& rest) noexcept {
  if (key.substr(0, 5) != "axis.") {
    return false;
  }
  const std::string_view tail = key.substr(5);
  const std::size_t dot = tail.find('.');
  if (dot == std::string_view::npos || !axis_1_to_6(tail.substr(0, dot), e.axis)) {
    return false;
  }
  rest = tail.substr(dot + 1);
  return true;
}

// Speeds: tcp_speed, point_speed (mm/s), axis.N.speed (rad/s). 1 when `tok` is one.
bool parse_speed(std::string_view tok, Expectation& e, Problem& problem) {
  constexpr std::array<std::pair<std::string_view, ExpectKey>, 2> points{{
      {"tcp_speed", ExpectKey::tcp_speed}, {"point_speed", ExpectKey::point_speed}}};
  for (const auto& [name, key] : points) {
    if (tok.substr(0, name.size()) == name) {
      problem = parse_compare(tok, tok.substr(name.size()), name, key, e);
      return true;
    }
  }
  const std::size_t op = tok.find_first_of("<>=");
  std::string_view rest;
  if (op != std::string_view::npos && axis_prefix(tok.substr(0, op), e, rest) && rest == "speed") {
    problem = parse_compare(tok, tok.substr(op), "axis.N.speed", ExpectKey::axis_speed, e);
    return true;
  }
  return false;
}

// The signal names of `cause.signal=` and `alarm.NAME.detail=`.
bool known_signal(std::string_view v) noexcept {
  constexpr std::array<std::string_view, 14> kFixed{"estop.a", "estop.b",      "gate.a", "gate.b",   "enable.a",
                                                    "enable.b", "enable.panic", "mode",   "fieldbus", "contactor",
                                                    "internal", "command",      "reset_button", "-"};
  if (std::find(kFixed.begin(), kFixed.end(), v) != kFixed.end()) {
    return true;
  }
  std::uint8_t axis = 0;
  const bool drive = v.substr(0, 6) == "drive." && axis_1_to_6(v.substr(6), axis);
  const bool brake = v.substr(0, 6) == "brake." && axis_1_to_6(v.substr(6), axis);
  return drive || brake;
}

bool known_cause(std::string_view v) noexcept {
  core::AlarmId a{};
  constexpr std::array<std::string_view, 6> kStops{"enable_released", "servo_off", "pause", "stop", "jog_stop", "-"};
  return (std::find(kStops.begin(), kStops.end(), v) != kStops.end()) || lookup(v, &core::parse_alarm, a);
}

template <typename E, std::size_t N>
bool from_names(std::string_view v, const std::array<std::string_view, N>& names, Expectation& e) noexcept {
  for (std::size_t i = 0; i < N; ++i) {
    if (v == names[i]) {
      e.value = static_cast<std::uint8_t>(i);
      return true;
    }
  }
  return false;
}

// PLCopen axis states (motion::AxisState order) and CiA 402 states (cia402::DriveState order).
constexpr std::array<std::string_view, 8> kAxisStates{"Disabled",         "Standstill",         "Homing",
                                                      "DiscreteMotion",   "ContinuousMotion",   "SynchronizedMotion",
                                                      "Stopping",         "ErrorStop"};
constexpr std::array<std::string_view, 8> kCia402States{
    "Not_ready_to_switch_on", "Switch_on_disabled",  "Ready_to_switch_on",    "Switched_on",
    "Operation_enabled",      "Quick_stop_active",   "Fault_reaction_active", "Fault"};

bool parse_axis_key(std::string_view key, std::string_view value, Expectation& e, bool& ok) {
  std::string_view rest;
  if (!axis_prefix(key, e, rest)) {
    return false;
  }
  std::uint16_t word = 0;
  if (rest == "state") {
    e.key = ExpectKey::axis_state;
    ok = from_names<motion::AxisState>(value, kAxisStates, e);
  } else if (rest == "cia402") {
    e.key = ExpectKey::axis_cia402;
    ok = from_names<core::cia402::DriveState>(value, kCia402States, e);
  } else if (rest == "controlword") {
    e.key = ExpectKey::axis_controlword;
    ok = hex_word(value, word);
    e.number = word;
  } else {
    return false;
  }
  return true;
}

// alarm.NAME.number=N, alarm.NAME.detail=D
bool parse_alarm_key(std::string_view key, std::string_view value, Expectation& e, bool& ok) {
  if (key.substr(0, 6) != "alarm.") {
    return false;
  }
  const std::string_view tail = key.substr(6);
  const std::size_t dot = tail.rfind('.');
  core::AlarmId a{};
  if (dot == std::string_view::npos || !lookup(tail.substr(0, dot), &core::parse_alarm, a)) {
    return false;
  }
  e.value = static_cast<std::uint8_t>(a);
  const std::string_view what = tail.substr(dot + 1);
  if (what == "number") {
    e.key = ExpectKey::alarm_number;
    ok = to_number(value, e.number);
  } else if (what == "detail") {
    e.key = ExpectKey::alarm_detail;
    ok = known_signal(value) || value == "CONTACTOR" || value == "DRIVES" || value == "BRAKES" ||
         safety_keys::known_detail(value) || channel_keys::known_detail(value);
    if (!ok && !value.empty()) {
      ok = true;  // a zone's name: checked once the safety configuration is loaded
      e.number = safety_keys::kZoneDetail;
    }
    e.name = std::string(value);
  } else {
    return false;
  }
  return true;
}

// reply.CMD=RESULT|pending, reply.reset_button=RESULT
bool parse_reply_key(std::string_view key, std::string_view value, Expectation& e, bool& ok) {
  if (key.substr(0, 6) != "reply.") {
    return false;
  }
  const std::string_view cmd = key.substr(6);
  core::CommandId id{};
  if (cmd == "reset_button") {
    e.axis = kResetButtonReply;
  } else if (lookup(cmd, &core::parse_command, id)) {
    e.axis = static_cast<std::uint8_t>(id);
  } else {
    return false;
  }
  e.key = ExpectKey::reply_cmd;
  ok = (value == "pending") ? ((e.value = kPendingReply), true) : named(value, &core::parse_result, e);
  return true;
}

struct YesNo {
  const char* key;
  const char* yes;
  const char* no;
  ExpectKey id;
};
constexpr std::array<YesNo, 3> kYesNo{{
    {"standstill", "yes", "no", ExpectKey::standstill},
    {"t2_confirmed", "yes", "no", ExpectKey::t2_confirmed},
    {"owner", "pendant", "none", ExpectKey::owner},
}};

// @req SCN-MORE-KEYS
// The keys of "More keys, faults and settings"; 1 when `key` is one of them.
bool parse_more_key(std::string_view key, std::string_view value, Expectation& e, bool& ok) {
  if (key == "cause" || key == "cause.signal") {
    e.key = (key == "cause") ? ExpectKey::cause : ExpectKey::cause_signal;
    ok = (key == "cause") ? known_cause(value) : known_signal(value);
    e.name = std::string(value);
    return true;
  }
  if (key == "mode_requested") {
    e.key = ExpectKey::mode_requested;
    ok = named(value, &core::parse_mode, e);
    return true;
  }
  for (const YesNo& y : kYesNo) {
    if (key == y.key) {
      e.key = y.id;
      ok = (value == y.yes) || (value == y.no);
      e.value = (value == y.yes) ? 1U : 0U;
      return true;
    }
  }
  return parse_axis_key(key, value, e, ok) || parse_alarm_key(key, value, e, ok) ||
         parse_reply_key(key, value, e, ok);
}

Problem parse_expectation(std::string_view tok, Expectation& e) {
  e.text = std::string(tok);
  Problem speed;
  if (safety_keys::parse_expect(tok, e, speed) || brake_keys::parse_expect(tok, e, speed) ||
      channel_keys::parse_expect(tok, e, speed) || parse_speed(tok, e, speed)) {
    return speed;
  }
  std::string_view key;
  std::string_view value;
  if (!split_pair(tok, key, value)) {
    return "expect: expected KEY=VALUE, found " + quoted(tok);
  }
  bool ok = false;
  if (key == "replies") {
    e.key = ExpectKey::replies;
    ok = to_number(value, e.number);
  } else if (!parse_named_key(key, value, e, ok) && !parse_choice_key(key, value, e, ok) &&
             !parse_more_key(key, value, e, ok)) {
    return "unknown expect key " + quoted(key);
  }
  return ok ? Problem{} : "expect: unknown value " + quoted(value) + " for " + std::string(key);
}

Problem parse_expect(const Tokens& args, ExpectStep& out, bool once) {
  if (args.empty()) {
    return "expect needs at least one KEY=VALUE";
  }
  out.checks.reserve(args.size());
  out.mode = once ? ExpectMode::once : ExpectMode::every;
  for (const std::string_view tok : args) {
    Expectation e;
    if (Problem p = parse_expectation(tok, e); !p.empty()) {
      return p;
    }
    out.checks.push_back(std::move(e));
  }
  const bool counts = std::any_of(out.checks.begin(), out.checks.end(),
                                  [](const Expectation& e) { return e.key == ExpectKey::replies; });
  if (counts && (out.checks.size() != 1U || once)) {
    return "a line with replies= holds no other key, and is an expect (not expect-once)";
  }
  out.mode = counts ? ExpectMode::replies : out.mode;
  return {};
}

// ---------------------------------------------------------------------------------------
// the file

Problem parse_time_value(std::string_view s, core::Cycle& t) {
  if (!to_number(s, t)) {
    return "bad time " + quoted(s) + " (expected a non-negative integer)";
  }
  if (t > kMaxTime) {
    return "time " + std::string(s) + " is too large (at most " + std::to_string(kMaxTime) + ")";
  }
  return {};
}

// `tok` without its '@'.
Problem parse_time(std::string_view tok, core::Cycle& t1, core::Cycle& t2, bool& range) {
  const std::size_t dots = tok.find("..");
  range = dots != std::string_view::npos;
  if (Problem p = parse_time_value(range ? tok.substr(0, dots) : tok, t1); !p.empty()) {
    return p;
  }
  t2 = t1;
  if (!range) {
    return {};
  }
  if (Problem p = parse_time_value(tok.substr(dots + 2), t2); !p.empty()) {
    return p;
  }
  return (t1 <= t2) ? Problem{} : "bad range @" + std::string(tok) + " (T1 must not be after T2)";
}

class Parser {
 public:
  explicit Parser(std::string file) { result_.scenario.file = std::move(file); }

  ParseResult parse(std::string_view text) {
    std::size_t number = 0;
    std::size_t pos = 0;
    while (pos <= text.size() && ok()) {
      const std::size_t nl = text.find('\n', pos);
      const std::size_t end = (nl == std::string_view::npos) ? text.size() : nl;
      ++number;
      line(number, text.substr(pos, end - pos));
      if (nl == std::string_view::npos) {
        break;
      }
      pos = nl + 1;
    }
    if (ok()) {
      end_config();
    }
    // Ranges may be written after later lines: order by first cycle, file order kept (one
    // step per line, so (t, line) is the stable order; std::stable_sort's temporary buffer
    // is deprecated in libstdc++ 12 and refused by clang's -Werror).
    std::sort(result_.scenario.steps.begin(), result_.scenario.steps.end(), [](const Step& a, const Step& b) {
      return (a.t < b.t) || ((a.t == b.t) && (a.line < b.line));
    });
    std::size_t at = 0;
    if (ok()) {
      if (Problem p = safety_keys::check_details(result_.scenario, at); !p.empty()) {
        fail(at, std::move(p));
      }
    }
    return std::move(result_);
  }

 private:
  [[nodiscard]] bool ok() const noexcept { return result_.ok(); }

  void fail(std::size_t number, Problem message) {
    result_.error = ParseError{result_.scenario.file, number, std::move(message)};
  }

  void line(std::size_t number, std::string_view raw) {
    const Tokens tokens = vocab::split_words(strip_comment(raw));
    if (tokens.empty()) {
      return;
    }
    if (tokens[0] == "config") {
      config_line(number, tokens);
    } else if (tokens[0].front() == '@') {
      end_config();
      if (ok()) {
        timed_line(number, tokens);
      }
    } else {
      fail(number, "unknown directive " + quoted(tokens[0]) + " (a line starts with @T or config)");
    }
  }

  void config_line(std::size_t number, const Tokens& tokens) {
    if (timed_seen_) {
      fail(number, "config after the first @ line (config lines come first)");
      return;
    }
    if (tokens.size() < 2) {
      fail(number, "config needs at least one NAME=VALUE");
      return;
    }
    for (std::size_t i = 1; i < tokens.size() && ok(); ++i) {
      std::string_view key;
      std::string_view value;
      std::size_t index = 0;
      Problem safety;
      if (!split_pair(tokens[i], key, value)) {
        fail(number, "config: expected NAME=VALUE, found " + quoted(tokens[i]));
      } else if (safety_keys::set_config(key, value, number, safety_lines_, safety) ||
                 brake_keys::set_config(key, value, result_.scenario, safety) ||
                 channel_keys::set_config(key, value, result_.scenario, safety) ||
                 person_keys::set_config(key, value, result_.scenario, safety)) {
        if (!safety.empty()) {
          fail(number, std::move(safety));
        }
      } else if (Problem p = set_config(key, value, result_.scenario.config, index); !p.empty()) {
        fail(number, std::move(p));
      } else {
        config_lines_[index] = number;
      }
    }
    last_config_line_ = number;
  }

  // The config section is over: the result must pass core::validate().
  void end_config() {
    if (config_checked_) {
      return;
    }
    config_checked_ = true;
    std::size_t safety_at = 0;
    if (Problem p = safety_keys::finish_config(safety_lines_, config_lines_[kMaxStopField] != 0, result_.scenario,
                                               safety_at);
        !p.empty()) {
      fail(safety_at, std::move(p));
      return;
    }
    const core::ConfigError e = core::validate(result_.scenario.config);
    if (e.ok()) {
      return;
    }
    std::size_t at = last_config_line_;
    std::string field = e.field;
    for (std::size_t i = 0; i < kConfigFields.size(); ++i) {
      if (std::strcmp(kConfigFields[i].core_name, e.field) == 0) {
        field = kConfigFields[i].name;  // named as the file names it
        at = (config_lines_[i] != 0) ? config_lines_[i] : at;
      }
    }
    fail(at, "invalid config " + field + ": " + e.reason);
  }

  void timed_line(std::size_t number, const Tokens& tokens) {
    timed_seen_ = true;
    Step step;
    step.line = number;
    bool range = false;
    if (Problem p = parse_time(tokens[0].substr(1), step.t, step.t_end, range); !p.empty()) {
      fail(number, std::move(p));
      return;
    }
    if (!range && step.t < last_t_) {
      fail(number, "time @" + std::to_string(step.t) + " goes backwards (line " + std::to_string(last_t_line_) +
                       " is at @" + std::to_string(last_t_) + ")");
      return;
    }
    if (tokens.size() < 2) {
      fail(number, "missing directive after " + std::string(tokens[0]));
      return;
    }
    if (range && tokens[1] != "expect" && tokens[1] != "expect-once") {
      fail(number, "a range @T1..T2 is only allowed for expect, not " + std::string(tokens[1]));
      return;
    }
    if (Problem p = directive(tokens, step); !p.empty()) {
      fail(number, std::move(p));
      return;
    }
    if (!range) {
      last_t_ = step.t;
      last_t_line_ = number;
    }
    add(std::move(step));
  }

  Problem directive(const Tokens& tokens, Step& step) {
    const std::string_view name = tokens[1];
    const Tokens args(tokens.begin() + 2, tokens.end());
    if (name == "in") {
      return parse_in(args, step.what.emplace<InputStep>());
    }
    if (name == "cmd") {
      return parse_cmd(args, step.line, step.what.emplace<CommandStep>());
    }
    if (name == "fault") {
      return parse_fault(args, step.what.emplace<FaultStep>());
    }
    if (name == "expect" || name == "expect-once") {
      return parse_expect(args, step.what.emplace<ExpectStep>(), name == "expect-once");
    }
    if (name == "person") {
      return person_keys::parse(args, step.what.emplace<PersonStep>(), person_present_);
    }
    if (name == "config") {
      return "config lines come before the first @ line and take no time";
    }
    return "unknown directive " + quoted(name) + " (expected in, cmd, fault, expect, expect-once or person)";
  }

  void add(Step&& step) {
    Scenario& s = result_.scenario;
    if (std::holds_alternative<ExpectStep>(step.what)) {
      ++s.expect_lines;
    }
    if (step.t_end + 1 > s.cycles) {
      s.cycles = step.t_end + 1;
    }
    s.steps.push_back(std::move(step));
  }

  ParseResult result_;
  bool timed_seen_ = false;
  bool config_checked_ = false;
  std::array<std::size_t, kConfigFields.size()> config_lines_{};  // line that last set each field
  std::size_t last_config_line_ = 0;
  safety_keys::ConfigLines safety_lines_;
  core::Cycle last_t_ = 0;
  std::size_t last_t_line_ = 0;
  bool person_present_ = false;  // after the lines so far (person_keys)
};

}  // namespace

ParseResult parse(std::string_view text, std::string file_name) {
  Parser p{std::move(file_name)};
  return p.parse(text);
}

}  // namespace safestate::scenario

// Parsing of client messages (protocol.md "Messages", "Bad input").
//
// Decisions where protocol.md is silent:
//  - `hello`: `role` is required; `client` and `token` are optional strings (null is
//    taken as absent). Any other field is ignored.
//  - `command`: `seq` must be a JSON integer; without it the frame gets error
//    BAD_MESSAGE. With it, everything else is judged by the core: a missing or unknown
//    `cmd` is sent as the out-of-range id core::kCommandCount (UNKNOWN_COMMAND); a jog
//    argument that is missing (except speed, default 10), mistyped or out of the field's
//    range is sent as 0 (BAD_ARGUMENT), a value that fits is sent as written (axis 9
//    stays 9, the core refuses it). Arguments a command does not take are ignored.
//    validate_config's `code` must be a string of exactly 8 hex digits (either case),
//    else it is sent without a code (BAD_ARGUMENT from the core).
//  - `sim`: `seq` must be an integer and exactly one of `set` (object), `fault`
//    (string) or `person` (object or string; docs/collaborative.md) must be present. Raw contacts take 0/1, true/false or "0"/"1";
//    `reset_button` likewise; the other shorthands take exactly the words of the
//    scenario format. Keys apply in the order written, so a later key wins.
#include "safestate/gateway/protocol.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

#include "safestate/vocab/faults.hpp"
#include "safestate/vocab/inputs.hpp"
#include "safestate/vocab/person.hpp"

namespace safestate::gateway {

namespace {


constexpr std::array<const char*, 3> kRoleNames{"pendant", "remote", "observer"};
constexpr std::array<const char*, 6> kErrorNames{"BAD_MESSAGE", "NOT_HELLO",  "ROLE_TAKEN",
                                                 "BAD_TOKEN",   "TOO_LARGE", "NOT_SIMULATED"};

ProtocolError bad(std::string detail) { return ProtocolError{ErrorCode::BAD_MESSAGE, std::move(detail)}; }

// Reads an optional string field: true when absent/null or a string, false when mistyped.
bool optional_string(const Json& j, const char* key, std::string& out, bool& present) {
  present = false;
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) {
    return true;
  }
  if (!it->is_string()) {
    return false;
  }
  out = it->get<std::string>();
  present = true;
  return true;
}

// An integral JSON number that fits [lo, hi], else `invalid`.
template <typename T>
T integer_or(const Json& v, T invalid) {
  std::int64_t x = 0;
  if (v.is_number_unsigned()) {
    const auto u = v.get<std::uint64_t>();
    if (u > static_cast<std::uint64_t>(std::numeric_limits<T>::max())) {
      return invalid;
    }
    return static_cast<T>(u);
  }
  if (v.is_number_integer()) {
    x = v.get<std::int64_t>();
  } else if (v.is_number_float()) {
    const double d = v.get<double>();
    if (!(d >= static_cast<double>(std::numeric_limits<T>::min()) &&
          d <= static_cast<double>(std::numeric_limits<T>::max())) ||
        static_cast<double>(static_cast<std::int64_t>(d)) != d) {
      return invalid;
    }
    x = static_cast<std::int64_t>(d);
  } else {
    return invalid;
  }
  if (x < static_cast<std::int64_t>(std::numeric_limits<T>::min()) ||
      x > static_cast<std::int64_t>(std::numeric_limits<T>::max())) {
    return invalid;
  }
  return static_cast<T>(x);
}

ClientMessage parse_hello(const Json& j) {
  HelloMsg h;
  const auto role = j.find("role");
  if (role == j.end() || !role->is_string()) {
    return bad("hello needs \"role\": \"pendant\", \"remote\" or \"observer\"");
  }
  const auto& r = role->get_ref<const std::string&>();
  bool found = false;
  for (std::size_t i = 0; i < kRoleNames.size(); ++i) {
    if (r == kRoleNames[i]) {
      h.role = static_cast<Role>(i);
      found = true;
    }
  }
  if (!found) {
    return bad("unknown role \"" + r + "\" (expected pendant, remote or observer)");
  }
  bool present = false;
  if (!optional_string(j, "client", h.client, present)) {
    return bad("\"client\" must be a string");
  }
  if (!optional_string(j, "token", h.token, h.has_token)) {
    return bad("\"token\" must be a string");
  }
  return h;
}

void fill_jog(const Json& j, core::Command& c) {
  const auto axis = j.find("axis");
  const auto dir = j.find("dir");
  const auto speed = j.find("speed");
  const std::string* d = (dir != j.end() && dir->is_string()) ? &dir->get_ref<const std::string&>() : nullptr;
  core::set_jog(c, (axis == j.end()) ? std::int8_t{0} : integer_or<std::int8_t>(*axis, 0),
                (d == nullptr) ? std::int8_t{0} : core::jog_direction(*d),
                (speed == j.end()) ? core::kJogDefaultSpeedPct : integer_or<std::uint8_t>(*speed, 0));
}

// validate_config: `code` must be a string of exactly 8 hex digits (the checksum as
// `safestate safety check` prints it; lower case is the same number). Anything else is
// sent without a code, and the core answers BAD_ARGUMENT.
void fill_validate_config(const Json& j, core::Command& c) {
  c.has_code = 0;
  c.code = 0;
  const auto code = j.find("code");
  if (code == j.end() || !code->is_string()) {
    return;
  }
  const auto& s = code->get_ref<const std::string&>();
  if (s.size() != 8U) {
    return;
  }
  std::uint32_t v = 0;
  for (const char ch : s) {
    unsigned d = 0;
    if (ch >= '0' && ch <= '9') {
      d = static_cast<unsigned>(ch - '0');
    } else if (ch >= 'A' && ch <= 'F') {
      d = static_cast<unsigned>(ch - 'A') + 10U;
    } else if (ch >= 'a' && ch <= 'f') {
      d = static_cast<unsigned>(ch - 'a') + 10U;
    } else {
      return;
    }
    v = (v << 4U) | d;
  }
  c.code = v;
  c.has_code = 1;
}

void fill_set_mode(const Json& j, core::Command& c) {
  core::Mode m = core::Mode::NONE;
  const auto mode = j.find("mode");
  const bool ok = mode != j.end() && mode->is_string() &&
                  core::parse_mode(mode->get_ref<const std::string&>().c_str(), m);
  c.mode = ok ? static_cast<std::uint8_t>(m) : std::uint8_t{0};
}

bool read_seq(const Json& j, Json& seq) {
  const auto it = j.find("seq");
  if (it == j.end() || !it->is_number_integer()) {
    return false;
  }
  seq = *it;
  return true;
}

ClientMessage parse_command(const Json& j) {
  CommandMsg m;
  if (!read_seq(j, m.seq)) {
    return bad("command needs an integer \"seq\"");
  }
  core::CommandId id{};
  const auto cmd = j.find("cmd");
  if (cmd != j.end() && cmd->is_string()) {
    m.name = cmd->get<std::string>();
  }
  if (!core::parse_command(m.name.c_str(), id)) {
    m.command.id = static_cast<std::uint8_t>(core::kCommandCount);  // the core answers UNKNOWN_COMMAND
    return m;
  }
  m.command.id = static_cast<std::uint8_t>(id);
  if (id == core::CommandId::jog) {
    fill_jog(j, m.command);
  } else if (id == core::CommandId::set_mode) {
    fill_set_mode(j, m.command);
  } else if (id == core::CommandId::validate_config) {
    fill_validate_config(j, m.command);
  }
  return m;
}

ClientMessage parse_sim(const Json& j) {
  SimMsg m;
  if (!read_seq(j, m.seq)) {
    return bad("sim needs an integer \"seq\"");
  }
  const auto set = j.find("set");
  const auto fault = j.find("fault");
  const auto person = j.find("person");
  if ((set != j.end() ? 1 : 0) + (fault != j.end() ? 1 : 0) + (person != j.end() ? 1 : 0) != 1) {
    return bad("sim needs exactly one of \"set\" (object), \"fault\" (string) or \"person\" (object or string)");
  }
  std::string problem;
  if (set != j.end()) {
    problem = set->is_object() ? encode_sim_set(*set, m.record) : "\"set\" must be an object";
  } else if (person != j.end()) {
    problem = encode_sim_person(*person, m.record);
  } else {
    problem = fault->is_string() ? encode_sim_fault(fault->get_ref<const std::string&>(), m.record)
                                 : "\"fault\" must be a string";
  }
  if (!problem.empty()) {
    return bad(problem);
  }
  return m;
}

// ------------------------------------------------------------------ sim vocabulary
// The `set` object's values in the vocabulary's words (vocab/inputs.hpp): a string as it is,
// a boolean or an integer as its digits (raw contacts take 0/1, true/false or "0"/"1").
bool value_word(const Json& v, std::string& out) {
  if (v.is_string()) {
    out = v.get<std::string>();
    return true;
  }
  if (v.is_boolean()) {
    out = v.get<bool>() ? "1" : "0";
    return true;
  }
  if (v.is_number_integer()) {
    out = std::to_string(v.get<std::int64_t>());
    return true;
  }
  return false;
}

std::string value_text(const Json& v) { return v.dump(); }

// ------------------------------------------------------------------ sim person
// SPEC §11, the simulated person, in the words and limits of the scenario's `person` keys
// (scenario/src/person_keys.cpp, sim/person.hpp). "" when fine, else what is wrong.

// A finite JSON number (not a boolean, not a string).
bool json_real(const Json& v, double& out) {
  if (!v.is_number() || !std::isfinite(v.get<double>())) {
    return false;
  }
  out = v.get<double>();
  return true;
}

std::string on_floor(const Json& v, const std::string& what, float& out) {
  double x = 0.0;
  if (!json_real(v, x)) {
    return what + " " + value_text(v) + " is not a number (mm)";
  }
  if (std::fabs(x) > static_cast<double>(vocab::kPersonMaxRangeMm)) {
    return what + " " + value_text(v) + " is off the floor (|x|, |y| <= 20000 mm)";
  }
  out = static_cast<float>(x);
  return {};
}

std::string person_at(const Json& person, bridge::PersonRecord& p) {
  const Json& at = person.at("at");
  if (!at.is_array() || at.size() != 2U) {
    return "person at must be [X, Y] (mm), found " + value_text(at);
  }
  if (std::string e = on_floor(at[0], "person at: X", p.x_mm); !e.empty()) {
    return e;
  }
  if (std::string e = on_floor(at[1], "person at: Y", p.y_mm); !e.empty()) {
    return e;
  }
  p.radius_mm = vocab::kPersonDefaultRadiusMm;
  if (const auto r = person.find("radius_mm"); r != person.end()) {
    double v = 0.0;
    if (!json_real(*r, v) || v <= 0.0 || v > static_cast<double>(vocab::kPersonMaxRadiusMm)) {
      return "person radius_mm " + value_text(*r) + " is not a number of mm in (0, 1000]";
    }
    p.radius_mm = static_cast<float>(v);
  }
  p.what = static_cast<std::uint8_t>(p.what | bridge::kPersonAt);
  return {};
}

std::string person_walk(const Json& walk, bridge::PersonRecord& p) {
  if (!walk.is_array() || walk.empty()) {
    return "person walk must be a list of 1..16 points [X, Y, SPEED] or [X, Y, SPEED, STAND_MS], found " +
           value_text(walk);
  }
  if (walk.size() > bridge::kPersonPoints) {
    return "person walk: " + std::to_string(walk.size()) + " points, more than 16";
  }
  for (std::size_t i = 0; i < walk.size(); ++i) {
    const Json& w = walk[i];
    const std::string point = "person walk: point " + std::to_string(i + 1U);
    if (!w.is_array() || (w.size() != 3U && w.size() != 4U)) {
      return point + " must be [X, Y, SPEED] or [X, Y, SPEED, STAND_MS], found " + value_text(w);
    }
    bridge::PersonPoint& q = p.path[i];
    if (std::string e = on_floor(w[0], point + ": X", q.x_mm); !e.empty()) {
      return e;
    }
    if (std::string e = on_floor(w[1], point + ": Y", q.y_mm); !e.empty()) {
      return e;
    }
    double v = 0.0;
    if (!json_real(w[2], v)) {
      return point + ": speed " + value_text(w[2]) + " is not a number (mm/s)";
    }
    if (v <= 0.0) {
      return point + ": speed " + value_text(w[2]) + " mm/s is not above 0 (\"stand\" stops)";
    }
    if (v > static_cast<double>(vocab::kPersonMaxSpeedMmS)) {
      return point + ": speed " + value_text(w[2]) + " mm/s is over 2000 (ISO 13855's fastest approach)";
    }
    q.speed_mm_s = static_cast<float>(v);
    if (w.size() == 4U) {
      // A JSON integer (a huge unsigned one reads negative here and is refused too).
      const std::int64_t ms = w[3].is_number_integer() ? w[3].get<std::int64_t>() : -1;
      if (ms < 0 || ms > static_cast<std::int64_t>(vocab::kPersonMaxStandMs)) {
        return point + ": stand " + value_text(w[3]) + " is not a whole number of ms up to 3600000";
      }
      q.stand_ms = static_cast<std::uint32_t>(ms);
    }
  }
  p.points = static_cast<std::uint8_t>(walk.size());
  p.what = static_cast<std::uint8_t>(p.what | bridge::kPersonWalk);
  return {};
}

std::string person_fields(const Json& f, bridge::PersonRecord& p) {
  vocab::PersonSensors s{};
  double outer = 0.0;
  double inner = 0.0;
  if (!f.is_array() || f.size() != 2U || !json_real(f[0], outer) || !json_real(f[1], inner)) {
    return "person fields must be [OUTER, INNER] (mm), found " + value_text(f);
  }
  s.outer_mm = static_cast<float>(outer);
  s.inner_mm = static_cast<float>(inner);
  if (!vocab::valid(s)) {
    return "person fields " + value_text(f) + " are not 0 < INNER < OUTER <= 20000 mm";
  }
  p.fields_outer_mm = s.outer_mm;
  p.fields_inner_mm = s.inner_mm;
  p.what = static_cast<std::uint8_t>(p.what | bridge::kPersonFields);
  return {};
}

constexpr const char* kPersonForms =
    "\"stand\", \"leave\", or an object with \"at\": [X, Y] (and \"radius_mm\"), \"walk\": [[X, Y, SPEED], ...], "
    "\"fields\": [OUTER, INNER]";

}  // namespace

const char* to_string(Role r) noexcept {
  const auto i = static_cast<std::size_t>(r);
  return i < kRoleNames.size() ? kRoleNames[i] : "?";
}

core::Source source_of(Role r) noexcept {
  switch (r) {
    case Role::pendant: return core::Source::pendant;
    case Role::remote: return core::Source::remote;
    case Role::observer: break;
  }
  return core::Source::observer;
}

const char* to_string(ErrorCode c) noexcept {
  const auto i = static_cast<std::size_t>(c);
  return i < kErrorNames.size() ? kErrorNames[i] : "?";
}

ClientMessage parse_client_message(std::string_view text) {
  const Json j = Json::parse(text.begin(), text.end(), nullptr, false);
  if (j.is_discarded()) {
    return bad("invalid JSON");
  }
  if (!j.is_object()) {
    return bad("a message must be a JSON object");
  }
  const auto type = j.find("type");
  if (type == j.end() || !type->is_string()) {
    return bad("a message needs a string \"type\"");
  }
  const auto& t = type->get_ref<const std::string&>();
  if (t == "hello") {
    return parse_hello(j);
  }
  if (t == "command") {
    return parse_command(j);
  }
  if (t == "sim") {
    return parse_sim(j);
  }
  return bad("unknown type \"" + t + "\" (expected hello, command or sim)");
}

std::string encode_sim_set(const Json& set, bridge::CommandRecord& out) {
  out = bridge::CommandRecord{};
  out.kind = bridge::RecordKind::sim_set;
  if (!set.is_object() || set.empty()) {
    return "\"set\" needs at least one input";
  }
  vocab::InputStep step;
  for (const auto& [key, value] : set.items()) {
    std::string word;
    if (!value_word(value, word)) {
      return "bad value " + value_text(value) + " for input " + key + " (a string, 0/1 or true/false)";
    }
    if (std::string problem = vocab::parse_input(key, word, step); !problem.empty()) {
      return problem;
    }
  }
  for (const vocab::ContactWrite& w : step.writes) {
    const std::uint32_t b = 1U << static_cast<unsigned>(w.contact);
    out.set_mask |= b;
    out.set_values = w.closed ? (out.set_values | b) : (out.set_values & ~b);
  }
  if (step.separation_mm) {
    out.separation_mm = *step.separation_mm;
    out.separation_set |= bridge::kSetSeparation;
  }
  if (step.separation_valid) {
    out.separation_set = static_cast<std::uint8_t>(out.separation_set | bridge::kSetValid |
                                                   (*step.separation_valid ? bridge::kSeparationValid : 0U));
  }
  return {};
}

std::string encode_sim_fault(std::string_view line, bridge::CommandRecord& out) {
  out = bridge::CommandRecord{};
  out.kind = bridge::RecordKind::sim_fault;
  vocab::Fault f{};
  if (std::string problem = vocab::parse_fault(vocab::split_words(line), f, vocab::FaultSource::network); !problem.empty()) {
    return problem;
  }
  out.fault_kind = static_cast<std::uint8_t>(f.kind);
  out.fault_axis = f.axis;
  out.fault_value = f.value;
  return {};
}

// @req COL-SIM-PERSON
std::string encode_sim_person(const Json& person, bridge::CommandRecord& out) {
  out = bridge::CommandRecord{};
  out.kind = bridge::RecordKind::sim_person;
  bridge::PersonRecord& p = out.person;
  std::string problem;
  if (person.is_string()) {
    const auto& w = person.get_ref<const std::string&>();
    if (w == "stand" || w == "leave") {
      p.what = (w == "stand") ? bridge::kPersonStand : bridge::kPersonLeave;
      return {};
    }
    problem = "unknown person action " + value_text(person) + " (expected " + kPersonForms + ")";
  } else if (!person.is_object() || person.empty()) {
    problem = std::string("\"person\" must be ") + kPersonForms;
  } else {
    for (const auto& [key, value] : person.items()) {
      if (key == "at") {
        problem = person_at(person, p);
      } else if (key == "walk") {
        problem = person_walk(value, p);
      } else if (key == "fields") {
        problem = person_fields(value, p);
      } else if (key == "radius_mm") {
        problem = person.contains("at") ? "" : "person radius_mm goes with \"at\"";
      } else {
        problem = "unknown person key \"" + key + "\" (expected at, radius_mm, walk, fields)";
      }
      if (!problem.empty()) {
        break;
      }
    }
  }
  if (!problem.empty()) {
    out = bridge::CommandRecord{};
    out.kind = bridge::RecordKind::sim_person;
  }
  return problem;
}

Json make_welcome(Role role, const std::string& version) {
  Json j;
  j["type"] = "welcome";
  j["role"] = to_string(role);
  j["server"] = "safestate " + (version.empty() ? std::string("unknown") : version);
  return j;
}

Json make_reply(const Json& seq, const char* result) {
  Json j;
  j["type"] = "reply";
  j["seq"] = seq;
  j["result"] = result;
  return j;
}

Json make_error(ErrorCode code, const std::string& detail) {
  Json j;
  j["type"] = "error";
  j["code"] = to_string(code);
  j["detail"] = detail;
  return j;
}

}  // namespace safestate::gateway

#include "safestate/vocab/inputs.hpp"

#include <array>
#include <string>

namespace safestate::vocab {

namespace {

struct InputWord {
  const char* word;
  std::array<ContactWrite, 3> writes;
  std::size_t count;
};

struct Shorthand {
  const char* key;
  const char* expected;  // for messages
  std::array<InputWord, 4> words;
  std::size_t count;
};

constexpr ContactWrite cw(Contact c, bool closed) { return ContactWrite{c, closed}; }

// clang-format off
const std::array<Shorthand, 8> kShorthands{{
  {"estop", "pressed|released", {{
    {"pressed", {cw(Contact::estop_a, false), cw(Contact::estop_b, false), {}}, 2},
    {"released", {cw(Contact::estop_a, true), cw(Contact::estop_b, true), {}}, 2}, {}, {}}}, 2},
  {"gate", "open|closed", {{
    {"open", {cw(Contact::gate_a, false), cw(Contact::gate_b, false), {}}, 2},
    {"closed", {cw(Contact::gate_a, true), cw(Contact::gate_b, true), {}}, 2}, {}, {}}}, 2},
  {"enable", "released|centre|panic", {{
    {"released", {cw(Contact::enable_a, false), cw(Contact::enable_b, false), cw(Contact::enable_panic, false)}, 3},
    {"centre", {cw(Contact::enable_a, true), cw(Contact::enable_b, true), cw(Contact::enable_panic, false)}, 3},
    {"panic", {cw(Contact::enable_a, false), cw(Contact::enable_b, false), cw(Contact::enable_panic, true)}, 3},
    {}}}, 3},
  {"mode", "AUTO|T1|T2|NONE", {{
    {"AUTO", {cw(Contact::mode_auto, true), cw(Contact::mode_t1, false), cw(Contact::mode_t2, false)}, 3},
    {"T1", {cw(Contact::mode_auto, false), cw(Contact::mode_t1, true), cw(Contact::mode_t2, false)}, 3},
    {"T2", {cw(Contact::mode_auto, false), cw(Contact::mode_t1, false), cw(Contact::mode_t2, true)}, 3},
    {"NONE", {cw(Contact::mode_auto, false), cw(Contact::mode_t1, false), cw(Contact::mode_t2, false)}, 3}}}, 4},
  {"reset_button", "0|1", {{
    {"0", {cw(Contact::reset_button, false), {}, {}}, 1},
    {"1", {cw(Contact::reset_button, true), {}, {}}, 1}, {}, {}}}, 2},
  // SPEC §10 reduced-speed request (NC: 1 = normal speed).
  {"reduced", "normal|reduced", {{
    {"normal", {cw(Contact::reduced_a, true), cw(Contact::reduced_b, true), {}}, 2},
    {"reduced", {cw(Contact::reduced_a, false), cw(Contact::reduced_b, false), {}}, 2}, {}, {}}}, 2},
  // SPEC §11 protective fields: both OSSD channels (NC: 1 = clear).
  {"field.outer", "clear|interrupted", {{
    {"clear", {cw(Contact::field_outer_a, true), cw(Contact::field_outer_b, true), {}}, 2},
    {"interrupted", {cw(Contact::field_outer_a, false), cw(Contact::field_outer_b, false), {}}, 2}, {}, {}}}, 2},
  {"field.inner", "clear|interrupted", {{
    {"clear", {cw(Contact::field_inner_a, true), cw(Contact::field_inner_b, true), {}}, 2},
    {"interrupted", {cw(Contact::field_inner_a, false), cw(Contact::field_inner_b, false), {}}, 2}, {}, {}}}, 2},
}};
// clang-format on

// The raw contacts by name, in Contact order (reset_button is only the shorthand's).
constexpr std::array<const char*, kContacts> kContactNames{
    "estop.a",   "estop.b",   "gate.a",        "gate.b",        "enable.a",      "enable.b",
    "enable.panic", "mode.auto", "mode.t1",     "mode.t2",       "reset_button",  "reduced.a",
    "reduced.b", "field.outer.a", "field.outer.b", "field.inner.a", "field.inner.b"};

// 1: key handled (problem may be set); 0: not a shorthand.
bool parse_shorthand(std::string_view key, std::string_view value, InputStep& out, Problem& problem) {
  for (const Shorthand& s : kShorthands) {
    if (key != s.key) {
      continue;
    }
    for (std::size_t i = 0; i < s.count; ++i) {
      const InputWord& w = s.words[i];
      if (value == w.word) {
        out.writes.insert(out.writes.end(), w.writes.begin(), w.writes.begin() + static_cast<std::ptrdiff_t>(w.count));
        return true;
      }
    }
    problem = "bad value " + quoted(value) + " for input " + std::string(key) + " (expected " + s.expected + ")";
    return true;
  }
  return false;
}

bool parse_raw_contact(std::string_view key, std::string_view value, InputStep& out, Problem& problem) {
  for (std::size_t i = 0; i < kContacts; ++i) {
    if (key != kContactNames[i] || static_cast<Contact>(i) == Contact::reset_button) {
      continue;
    }
    if (value != "0" && value != "1") {
      problem = "bad value " + quoted(value) + " for contact " + std::string(key) + " (expected 0|1)";
    } else {
      out.writes.push_back(ContactWrite{static_cast<Contact>(i), value == "1"});
    }
    return true;
  }
  return false;
}

// @req COL-SSM-INPUT
bool parse_separation(std::string_view key, std::string_view value, InputStep& out, Problem& problem) {
  if (key == "separation_mm") {
    std::int32_t mm = 0;
    if (!to_number(value, mm) || mm < 0) {
      problem = "bad value " + quoted(value) + " for input separation_mm (expected an integer number of mm >= 0)";
      return true;
    }
    out.separation_mm = mm;
    return true;
  }
  if (key == "separation_valid") {
    if (value != "0" && value != "1") {
      problem = "bad value " + quoted(value) + " for input separation_valid (expected 0|1)";
      return true;
    }
    out.separation_valid = value == "1";
    return true;
  }
  return false;
}

}  // namespace

// @req COL-FIELDS
Problem parse_input(std::string_view key, std::string_view value, InputStep& out) {
  Problem problem;
  if (!parse_shorthand(key, value, out, problem) && !parse_raw_contact(key, value, out, problem) &&
      !parse_separation(key, value, out, problem)) {
    return "unknown input " + quoted(key);
  }
  return problem;
}

Problem parse_inputs(const Tokens& tokens, InputStep& out) {
  if (tokens.empty()) {
    return "in needs at least one KEY=VALUE";
  }
  InputStep step = out;
  for (const std::string_view tok : tokens) {
    std::string_view key;
    std::string_view value;
    if (!split_pair(tok, key, value)) {
      return "in: expected KEY=VALUE, found " + quoted(tok);
    }
    if (Problem p = parse_input(key, value, step); !p.empty()) {
      return p;
    }
  }
  out = std::move(step);
  return {};
}

void apply(const ContactWrite& w, core::RawInputs& raw) noexcept {
  switch (w.contact) {
    case Contact::estop_a: raw.estop_a = w.closed; break;
    case Contact::estop_b: raw.estop_b = w.closed; break;
    case Contact::gate_a: raw.gate_a = w.closed; break;
    case Contact::gate_b: raw.gate_b = w.closed; break;
    case Contact::enable_a: raw.enable_a = w.closed; break;
    case Contact::enable_b: raw.enable_b = w.closed; break;
    case Contact::enable_panic: raw.enable_panic = w.closed; break;
    case Contact::mode_auto: raw.mode_auto = w.closed; break;
    case Contact::mode_t1: raw.mode_t1 = w.closed; break;
    case Contact::mode_t2: raw.mode_t2 = w.closed; break;
    case Contact::reset_button: raw.reset_button = w.closed; break;
    case Contact::reduced_a: raw.reduced_a = w.closed; break;
    case Contact::reduced_b: raw.reduced_b = w.closed; break;
    case Contact::field_outer_a: raw.field_outer_a = w.closed; break;
    case Contact::field_outer_b: raw.field_outer_b = w.closed; break;
    case Contact::field_inner_a: raw.field_inner_a = w.closed; break;
    case Contact::field_inner_b: raw.field_inner_b = w.closed; break;
  }
}

void apply(const InputStep& step, core::RawInputs& raw) noexcept {
  for (const ContactWrite& w : step.writes) {
    apply(w, raw);
  }
  if (step.separation_mm) {
    raw.separation_mm = *step.separation_mm;
    raw.separation_valid = true;  // a reading given is a valid one, unless the line says otherwise
  }
  if (step.separation_valid) {
    raw.separation_valid = *step.separation_valid;
  }
}

bool contact_of(const core::RawInputs& raw, Contact c) noexcept {
  switch (c) {
    case Contact::estop_a: return raw.estop_a;
    case Contact::estop_b: return raw.estop_b;
    case Contact::gate_a: return raw.gate_a;
    case Contact::gate_b: return raw.gate_b;
    case Contact::enable_a: return raw.enable_a;
    case Contact::enable_b: return raw.enable_b;
    case Contact::enable_panic: return raw.enable_panic;
    case Contact::mode_auto: return raw.mode_auto;
    case Contact::mode_t1: return raw.mode_t1;
    case Contact::mode_t2: return raw.mode_t2;
    case Contact::reset_button: return raw.reset_button;
    case Contact::reduced_a: return raw.reduced_a;
    case Contact::reduced_b: return raw.reduced_b;
    case Contact::field_outer_a: return raw.field_outer_a;
    case Contact::field_outer_b: return raw.field_outer_b;
    case Contact::field_inner_a: return raw.field_inner_a;
    case Contact::field_inner_b: return raw.field_inner_b;
  }
  return false;
}

const char* to_string(Contact c) noexcept {
  const auto i = static_cast<std::size_t>(c);
  return i < kContacts ? kContactNames[i] : "?";
}

}  // namespace safestate::vocab

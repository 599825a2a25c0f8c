// SPEC §10 keys of the scenario format (see safety_keys.hpp).
#include "safety_keys.hpp"

#include <array>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>

#include "safestate/robot/description.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/safety/safety_config.hpp"

namespace safestate::scenario {

// @req LIM-CONFIG
const core::SafetyLimits& safety_limits(const Scenario& s) {
  static const core::SafetyLimits kBuiltIn = safety::default_safety().limits;
  return s.safety ? *s.safety : kBuiltIn;
}

namespace safety_keys {

namespace {

using util::Problem;
using util::quoted;

bool hex8(std::string_view v, std::uint32_t& out) noexcept {
  if (v.size() != 8U) {
    return false;
  }
  std::uint32_t x = 0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), x, 16);
  if (ec != std::errc{} || end != v.data() + v.size()) {
    return false;
  }
  out = x;
  return true;
}

std::string hex8_text(std::uint32_t v) {
  std::array<char, 9> buf{};
  std::snprintf(buf.data(), buf.size(), "%08X", v);  // NOLINT(cppcoreguidelines-pro-type-vararg): fixed format
  return std::string(buf.data(), 8);
}

struct YesNoKey {
  std::string_view key;
  ExpectKey id;
};
constexpr std::array<YesNoKey, 3> kYesNo{{
    {"validated", ExpectKey::validated},
    {"reduced", ExpectKey::reduced},
    {"recovery", ExpectKey::recovery},
}};

bool yes_no_value(const Expectation& e, const core::SupervisorOut& out) noexcept {
  switch (e.key) {
    case ExpectKey::validated: return out.safety.validated;
    case ExpectKey::reduced: return out.safety.reduced;
    case ExpectKey::recovery: return out.safety.recovery;
    default: break;
  }
  return false;
}

double joint_deg(const Expectation& e, const sim::CellView& v) noexcept {
  constexpr double kDeg = 180.0 / 3.14159265358979323846;
  return static_cast<double>(v.joints_rad[static_cast<std::size_t>(e.axis - 1U) % core::kAxes]) * kDeg;
}

}  // namespace

bool set_config(std::string_view key, std::string_view value, std::size_t line, ConfigLines& out, Problem& problem) {
  if (key == "safety") {
    if (value.empty()) {
      problem = "config safety: needs a file name";
    }
    out.file = std::string(value);
    out.file_line = line;
    return true;
  }
  if (key == "validated") {
    std::uint32_t code = 0;
    if (!hex8(value, code)) {
      problem = "config validated: " + quoted(value) + " is not a checksum (8 hex digits)";
    }
    out.validated = code;
    out.validated_line = line;
    return true;
  }
  return false;
}

Problem finish_config(const ConfigLines& lines, bool max_stop_set, Scenario& s, std::size_t& line) {
  std::uint32_t checksum = safety_limits(s).checksum;
  if (!lines.file.empty()) {
    line = lines.file_line;
    namespace fs = std::filesystem;
    fs::path path(lines.file);
    if (path.is_relative()) {
      path = fs::path(s.file).parent_path() / path;
    }
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) {
      return "config safety: " + util::quoted(path.string()) + " is not a readable file";
    }
    const safety::Result r = safety::load_safety_file(path.string());
    if (!r.ok()) {
      std::string all;
      for (const safety::Error& e : r.errors) {
        all += (all.empty() ? "" : "; ") + e.text();
      }
      return "config safety: " + path.string() + ": " + all;
    }
    // Issue 38: a configuration for another arm than the one replayed (`--robot`) is refused.
    if (robot::canonical_parameters(*r.config->robot.robot) != robot::canonical_parameters(robot::active())) {
      return "config safety: " + path.string() + ": names robot " + r.config->robot.robot->d.name + " (" +
             r.config->robot.robot->d.source + "), the replay runs " + robot::active().d.name + " (--robot)";
    }
    s.safety = r.config->limits;
    checksum = r.config->limits.checksum;
    if (!max_stop_set) {
      s.config.max_stop_ms = r.config->limits.max_stop_ms;  // SPEC §10: the file's value wins
    }
    // SPEC §14: the file's `channels` settings, as `safestate run` takes them (the scenario's own
    // `config cross_check_cycles=` and encoder keys still apply to a file without the key).
    if (r.config->channels_configured) {
      s.config.cross_check_cycles = r.config->channels.cross_check_cycles;
      s.config.encoder_tolerance_deg = static_cast<float>(r.config->channels.encoder_tolerance_deg);
      s.config.encoder_discrepancy_ms = r.config->channels.encoder_discrepancy_ms;
    }
  }
  // Without a file: the built-in configuration, which counts as validated.
  s.safety_validated = lines.file.empty() || (lines.validated && (*lines.validated == checksum));
  return {};
}


void fill_validate_config(const util::Tokens& args, std::size_t first, core::Command& c) noexcept {
  std::uint32_t code = 0;
  const bool one = (args.size() - first) == 1U;
  c.has_code = (one && hex8(args[first], code)) ? 1U : 0U;
  c.code = code;
}

bool parse_expect(std::string_view tok, Expectation& e, Problem& problem) {
  std::string_view key;
  std::string_view value;
  if (tok.substr(0, 9) == "v_allowed" && tok.size() > 9U && (tok[9] == '<' || tok[9] == '>' || tok[9] == '=')) {
    e.key = ExpectKey::v_allowed;
    std::string_view number;
    if (!util::compare_op(tok.substr(9), e.cmp, number)) {
      problem = "expect " + quoted(tok) + ": v_allowed takes <=, <, >= or > and a speed in mm/s";
    } else if (!util::to_real(number, e.limit)) {
      problem = "expect " + quoted(tok) + ": the speed is not a number";
    }
    return true;
  }
  if (tok.substr(0, 6) == "joint.") {
    const std::size_t op = tok.find_first_of("<>=");
    if (op == std::string_view::npos || !util::axis_1_to_6(tok.substr(6, op - 6), e.axis)) {
      return false;
    }
    e.key = ExpectKey::joint;
    std::string_view number;
    if (util::compare_op(tok.substr(op), e.cmp, number)) {
      if (!util::to_real(number, e.limit)) {
        problem = "expect " + quoted(tok) + ": the angle is not a number";
      }
      return true;
    }
    problem = "expect " + quoted(tok) + ": joint.N takes <=, <, >= or > and a number of degrees";
    return true;
  }
  if (!util::split_pair(tok, key, value)) {
    return false;
  }
  if (key == "checksum") {
    e.key = ExpectKey::checksum;
    if (!hex8(value, e.number)) {
      problem = "expect: unknown value " + quoted(value) + " for checksum (8 hex digits)";
    }
    return true;
  }
  for (const YesNoKey& y : kYesNo) {
    if (key == y.key) {
      e.key = y.id;
      if (value != "yes" && value != "no") {
        problem = "expect: unknown value " + quoted(value) + " for " + std::string(key) + " (yes|no)";
      }
      e.value = (value == "yes") ? 1U : 0U;
      return true;
    }
  }
  return false;
}

bool known_detail(std::string_view v) noexcept {
  std::uint8_t axis = 0;
  // SPEC §11: the protective fields' channels (FIELD_DISCREPANCY, PERSON_IN_FIELD) and the
  // distance sensor (SEPARATION_VIOLATED).
  constexpr std::array<std::string_view, 5> kCollaborative{"field.outer.a", "field.outer.b", "field.inner.a",
                                                           "field.inner.b", "separation"};
  for (const std::string_view c : kCollaborative) {
    if (v == c) {
      return true;
    }
  }
  return (v == "tcp") || (v == "reduced") || (v.substr(0, 5) == "axis." && util::axis_1_to_6(v.substr(5), axis));
}

Problem check_details(const Scenario& s, std::size_t& line) {
  const core::SafetyLimits& limits = safety_limits(s);
  for (const Step& step : s.steps) {
    const auto* ex = std::get_if<ExpectStep>(&step.what);
    if (ex == nullptr) {
      continue;
    }
    for (const Expectation& e : ex->checks) {
      if (e.key != ExpectKey::alarm_detail || e.number != kZoneDetail) {
        continue;
      }
      bool found_zone = false;
      for (std::size_t i = 0; i < limits.zone_count && i < core::kMaxZones; ++i) {
        found_zone = found_zone || (e.name == limits.zones[i].name.data());
      }
      if (!found_zone) {
        line = step.line;
        return "expect: unknown value " + util::quoted(e.name) + " for alarm detail (a signal, axis.N, tcp, or the name of a "
               "zone of the safety configuration)";
      }
    }
  }
  return {};
}

bool is_safety_key(ExpectKey k) noexcept {
  return k == ExpectKey::checksum || k == ExpectKey::validated || k == ExpectKey::reduced ||
         k == ExpectKey::recovery || k == ExpectKey::joint || k == ExpectKey::v_allowed;
}

bool holds(const Expectation& e, const core::SupervisorOut& out, const sim::CellView& v) noexcept {
  switch (e.key) {
    case ExpectKey::checksum: return out.safety.checksum == e.number;
    case ExpectKey::joint: return compare(joint_deg(e, v), e.cmp, e.limit);
    // @req COL-SSM-MONITOR
    case ExpectKey::v_allowed:
      return out.safety.ssm && compare(static_cast<double>(out.safety.v_allowed_mm_s), e.cmp, e.limit);
    default: return yes_no_value(e, out) == (e.value != 0U);
  }
}

std::string found(const Expectation& e, const core::SupervisorOut& out, const sim::CellView& v) {
  switch (e.key) {
    case ExpectKey::checksum: return "checksum=" + hex8_text(out.safety.checksum);
    case ExpectKey::joint: {
      std::array<char, 32> buf{};
      const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), joint_deg(e, v));
      return "joint." + std::to_string(e.axis) + "=" + std::string(buf.data(), r.ptr);
    }
    case ExpectKey::v_allowed: {
      if (!out.safety.ssm) {
        return "v_allowed=null (SSM does not act: collaborative.ssm off, or the mode is not AUTO)";
      }
      std::array<char, 32> buf{};
      const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), out.safety.v_allowed_mm_s);
      return "v_allowed=" + std::string(buf.data(), r.ptr) + " (separation " +
             std::to_string(static_cast<long>(out.safety.separation_mm)) + " mm)";
    }
    default: break;
  }
  for (const YesNoKey& y : kYesNo) {
    if (y.id == e.key) {
      return std::string(y.key) + "=" + (yes_no_value(e, out) ? "yes" : "no");
    }
  }
  return "?";
}

}  // namespace safety_keys
}  // namespace safestate::scenario

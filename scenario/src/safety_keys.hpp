// The scenario keys of spec/scenario-format.md "Safety configuration, collaborative
// operation, brake test" that concern SPEC §10, kept apart from parser.cpp and runner.cpp
// (which call in at one place each) so that the older files do not grow by them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "parse_util.hpp"
#include "safestate/core/supervisor.hpp"
#include "safestate/scenario/scenario.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::scenario::safety_keys {

// `config safety=FILE validated=CHECKSUM`, remembered until the config section ends.
struct ConfigLines {
  std::string file;
  std::size_t file_line = 0;
  std::optional<std::uint32_t> validated;
  std::size_t validated_line = 0;
};

// True when `key` is one of these config keys (`problem` set for a bad value).
bool set_config(std::string_view key, std::string_view value, std::size_t line, ConfigLines& out,
                util::Problem& problem);

// At the end of the config section: loads the file (relative to the scenario file) into
// `s.safety`, sets `s.safety_validated` and, unless the file set max_stop_ms itself,
// `s.config.max_stop_ms` from stop.max_time_ms. On a problem, `line` is where to report it.
util::Problem finish_config(const ConfigLines& lines, bool max_stop_set, Scenario& s, std::size_t& line);

// `cmd validate_config CODE`: CODE of exactly 8 hex digits, else sent without a code (the
// core answers BAD_ARGUMENT), as the parser does for every malformed argument.
void fill_validate_config(const util::Tokens& args, std::size_t first, core::Command& c) noexcept;

// `checksum=`, `validated=`, `reduced=`, `recovery=`, `joint.N<=X`, `v_allowed<=X` (also <, >=, >).
// True when `tok` is one of them (`problem` set for a bad value).
bool parse_expect(std::string_view tok, Expectation& e, util::Problem& problem);

// `alarm.NAME.detail=` values of SPEC §10: axis.N, tcp, reduced. A zone's name is taken
// as written and checked against the configuration once it is loaded (check_details).
bool known_detail(std::string_view v) noexcept;
inline constexpr std::uint32_t kZoneDetail = 1U;  // Expectation::number of such a detail
util::Problem check_details(const Scenario& s, std::size_t& line);

// Running: whether a §10 key holds, and what was found, in the key's own words.
bool holds(const Expectation& e, const core::SupervisorOut& out, const sim::CellView& v) noexcept;
std::string found(const Expectation& e, const core::SupervisorOut& out, const sim::CellView& v);
bool is_safety_key(ExpectKey k) noexcept;

}  // namespace safestate::scenario::safety_keys

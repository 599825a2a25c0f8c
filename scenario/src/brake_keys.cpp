// SPEC §12 keys of the scenario format (see brake_keys.hpp).
#include "brake_keys.hpp"

#include <array>
#include <cmath>
#include <string>
#include <utility>

namespace safestate::scenario::brake_keys {

namespace {

using util::Problem;
using util::quoted;

constexpr std::array<std::pair<std::string_view, core::BrakeTestResult>, 3> kResults{{
    {"none", core::BrakeTestResult::none},
    {"passed", core::BrakeTestResult::passed},
    {"failed", core::BrakeTestResult::failed},
}};

// The longest age a file may give: a year of hours (the configuration's interval_h is at
// most 8760 h), far beyond any interval, and well inside the core's cycle counters.
constexpr double kMaxAgeH = 100000.0;

}  // namespace

// @req BT-SCENARIO
bool set_config(std::string_view key, std::string_view value, Scenario& s, Problem& problem) {
  if (key != "brake_test_age_h") {
    return false;
  }
  if (value == "never") {
    s.brake_test = core::BrakeTestHistory{};
    return true;
  }
  double h = 0.0;
  if (!util::to_real(value, h) || h < 0.0 || h > kMaxAgeH) {
    problem = "config brake_test_age_h: " + quoted(value) + " is not a number of hours (0..100000) or never";
    return true;
  }
  s.brake_test.last = core::BrakeTestResult::passed;
  s.brake_test.passed_ever = true;
  s.brake_test.pass_age_ms = static_cast<std::uint64_t>(std::llround(h * 3600.0 * 1000.0));
  return true;
}


bool parse_expect(std::string_view tok, Expectation& e, Problem& problem) {
  std::string_view key;
  std::string_view value;
  if (!util::split_pair(tok, key, value) || key != "brake_test") {
    return false;
  }
  e.key = ExpectKey::brake_test;
  for (const auto& [name, r] : kResults) {
    if (value == name) {
      e.value = static_cast<std::uint8_t>(r);
      return true;
    }
  }
  problem = "expect: unknown value " + quoted(value) + " for brake_test (none|passed|failed)";
  return true;
}

bool is_brake_key(ExpectKey k) noexcept { return k == ExpectKey::brake_test; }

bool holds(const Expectation& e, const core::SupervisorOut& out) noexcept {
  return static_cast<std::uint8_t>(out.brake_test.since_start) == e.value;
}

std::string found(const Expectation& e, const core::SupervisorOut& out) {
  static_cast<void>(e);
  return std::string("brake_test=") + core::to_string(out.brake_test.since_start);
}

}  // namespace safestate::scenario::brake_keys

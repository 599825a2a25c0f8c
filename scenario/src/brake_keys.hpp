// The scenario keys of spec/scenario-format.md "Safety configuration, collaborative
// operation, brake test" that concern the brake test of SPEC §12, kept in a file of their
// own (parser.cpp and runner.cpp call in at one place each): `config brake_test_age_h=X|never`,
// `fault brake N weak`, `expect brake_test=none|passed|failed`. `cmd brake_test` and
// `sub=BRAKE_TEST` need nothing here: they are core names, looked up like the others.
#pragma once

#include <string_view>

#include "parse_util.hpp"
#include "safestate/core/supervisor.hpp"
#include "safestate/scenario/scenario.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::scenario::brake_keys {

// True when `key` is `brake_test_age_h` (`problem` set for a bad value).
bool set_config(std::string_view key, std::string_view value, Scenario& s, util::Problem& problem);


// `brake_test=none|passed|failed`. True when `tok` is this key (`problem` set for a bad value).
bool parse_expect(std::string_view tok, Expectation& e, util::Problem& problem);

bool is_brake_key(ExpectKey k) noexcept;
bool holds(const Expectation& e, const core::SupervisorOut& out) noexcept;
std::string found(const Expectation& e, const core::SupervisorOut& out);

}  // namespace safestate::scenario::brake_keys

// The scenario keys of spec/scenario-format.md "Two channels" (SPEC §14), kept in a file of
// their own (parser.cpp and runner.cpp call in at one place each): `config channels=1|2`,
// `expect contactor.k1=open|closed`, `contactor.k2=`, `channel.a=STATE`, `channel.b=STATE`,
// and `contactor=` read as both contactors. The faults are the vocabulary's
// (vocab/faults.hpp); the settings cross_check_cycles, encoder_tolerance_deg,
// encoder_discrepancy_ms and integrity_period_ms are core::Config's (parser.cpp's table).
#pragma once

#include <string>
#include <string_view>

#include "parse_util.hpp"
#include "safestate/scenario/scenario.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::scenario::channel_keys {

// `config channels=1|2`; false when the key is not this file's.
bool set_config(std::string_view key, std::string_view value, Scenario& s, util::Problem& problem);
// contactor.k1, contactor.k2, channel.a, channel.b; false when the token is not one of them.
bool parse_expect(std::string_view tok, Expectation& e, util::Problem& problem);
bool is_channel_key(ExpectKey k) noexcept;
bool holds(const Expectation& e, const sim::Cell& cell) noexcept;
std::string found(const Expectation& e, const sim::Cell& cell);

// `contactor=closed`: both contactors commanded closed; `contactor=open`: both open (one
// channel: its one).
bool contactor_is(const sim::Cell& cell, bool closed) noexcept;
// The details of SPEC §14's alarms: k1, k2 (CONTACTOR_WELDED), A, B (CHANNEL_LOST), the
// digest's fields (CHANNEL_MISMATCH: cycle, state, sub, stop, alarms, outputs,
// brake_test_axis, replies).
bool known_detail(std::string_view v) noexcept;
std::string contactor_found(const sim::Cell& cell);

}  // namespace safestate::scenario::channel_keys

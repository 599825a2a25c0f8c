// The scenario keys of the simulated person (SPEC §11, issue 20 item 5), an extension beyond
// the shared spec/scenario-format.md (documented in docs/collaborative.md "The simulated
// person" and docs/scenarios.md), kept in a file of their own (parser.cpp and runner.cpp
// call in at one place each):
//
//   config person_fields=OUTER,INNER          the scanner's field radii, mm (0 < INNER < OUTER <= 20000)
//   @T person at X Y [radius=R]               enters (or is moved at once) to X, Y mm, standing
//   @T person walk X Y SPEED [stand MS] ...   walks through 1..16 points, SPEED 0 < v <= 2000 mm/s,
//                                             standing MS ms at a point that has `stand MS`
//   @T person stand                           stops where it is
//   @T person leave                           leaves the cell (fields and separation: as set by `in`)
#pragma once

#include <string_view>

#include "parse_util.hpp"
#include "safestate/scenario/scenario.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::scenario::person_keys {

// True when `key` is `person_fields` (`problem` set for a bad value).
bool set_config(std::string_view key, std::string_view value, Scenario& s, util::Problem& problem);

// The words after `person`. `present`: whether a person is in the cell after the lines
// before this one (file order is time order for these lines); updated. Empty: well formed.
util::Problem parse(const util::Tokens& words, PersonStep& out, bool& present);

// Applies a step to the cell (the parser has checked it; false only for a hand-built step
// the cell refuses).
bool apply(const PersonStep& step, sim::Cell& cell) noexcept;

}  // namespace safestate::scenario::person_keys

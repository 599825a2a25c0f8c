// The scenario keys of spec/scenario-format.md "Safety configuration, collaborative
// operation, brake test" that concern SPEC §11's collision detection, kept in a file of their
// own (parser.cpp calls in at one place): `fault contact F` (newtons, 0 removes it) and
// `fault drive N torque_bias X` (percent of rated torque, may be negative or fractional).
#pragma once

#include "parse_util.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::scenario::collision_keys {

inline constexpr double kMaxContactN = 5000.0;       // stored in tenths of a newton
inline constexpr double kMaxTorqueBiasPct = 300.0;   // the drives' peak

// True when the words are one of the two faults above, well formed.
bool parse_fault(const util::Tokens& words, sim::Fault& f) noexcept;

}  // namespace safestate::scenario::collision_keys

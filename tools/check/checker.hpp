// `safestate check`: breadth-first exploration of the reachable states of the real
// controller (signal layer, supervisor, motion layer) on the simulated cell.
//
// A configuration is a whole copied Cell. From each one the checker applies every
// action of the scenario vocabulary (each input and channel, each command from the
// pendant and a remote client, each fault) and two ways of letting time pass (one
// cycle; until the next change, which is where timers fire), steps the cell, and
// checks the invariants after every cycle, together with the independent reference
// supervisor as a differential oracle. Configurations are merged on an abstract key
// (state, inputs, alarms, flags, plant condition: everything but raw timer values and
// arm positions); timers are explored by the time actions from each representative.
// A violation is reported with the shortest action sequence that leads to it (BFS),
// written as a .scn file that `safestate replay` reproduces.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace safestate::check {

// The defaults explore every configuration within 4 actions of boot and of each seed (about
// 520,000 configurations, 2.5 minutes and 1.3 GB on a 2-core machine in 2026-11: `safestate
// check` with no options stays within a few minutes); `make bench-check` runs depth 5
// (docs/verification.md gives both).
inline constexpr std::size_t kDefaultCheckDepth = 4;
inline constexpr std::size_t kDefaultCheckConfigs = 200000;

struct CheckOptions {
  std::size_t max_depth = kDefaultCheckDepth;      // actions from boot (or from a seed)
  // Configurations kept to be explored one action deeper: beyond this many, new ones are
  // still checked and counted but not explored further (the run is then "bounded").
  std::size_t max_configs = kDefaultCheckConfigs;
  std::string out_dir = ".";          // where a counterexample .scn is written
  bool verbose = false;
  // For testing the checker itself: demand IDLE (instead of ESTOP_ACTIVE) after an
  // E-stop (with `pair`: the frozen channel's partner's contactor open within one cycle),
  // so that a violation, its counterexample and its replay can be shown.
  bool break_invariant = false;
  // SPEC §14 (`--pair`): explore the pair (channels A and B in lock-step, K1 from A, K2
  // from B) and, at every reachable configuration where a contactor is commanded closed,
  // freeze each channel in turn (`channel X stall`) and apply each demand (none, the E-stop,
  // the guard, the enabling device released, a runaway): the other channel must command its
  // contactor open within cross_check_cycles + 1 cycles and be in ERROR_LOCKOUT or
  // ESTOP_ACTIVE the cycle after (its supervisor names the lockout the cycle after the
  // cross-check opened the contactor). The reference stays the oracle of each channel (they
  // agree while healthy).
  bool pair = false;
};

struct CheckStats {
  std::size_t configurations = 0;  // distinct abstract configurations reached
  std::size_t transitions = 0;     // actions applied
  std::size_t cycles = 0;          // scan cycles run
  std::size_t checks = 0;          // invariant checks made
  std::size_t max_depth = 0;
  std::size_t dropped = 0;         // configurations not explored further for --max-configs
  bool complete = false;           // the reachable set was exhausted within the bounds
  std::size_t frozen = 0;          // --pair: (configuration, channel, demand) runs with one channel frozen
};

// Returns 0 when every invariant held, 1 on a violation (counterexample written), 2 on
// bad options.
int check_main(const CheckOptions& opt, CheckStats& stats);

// Replays a scenario (a counterexample this checker wrote: `in`, `cmd` and `fault` lines,
// `config safety=` naming one of its configurations; `expect` lines are not run here,
// `safestate replay` runs them) from boot on the simulated cell, with every invariant and
// the reference supervisor checked after every cycle, through its last line and `extra`
// cycles more. Returns an empty string when all held, else what broke, at which cycle;
// `error` is set (and the result empty) when the text cannot be replayed.
std::string replay_checked(const std::string& scn_text, const std::string& file_name, std::size_t extra,
                           std::string& error);

// `safestate check --replay FILE`: 0 all held, 1 a violation (printed), 2 unreadable.
int replay_main(const std::string& file, std::size_t extra);

}  // namespace safestate::check

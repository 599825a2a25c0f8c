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

struct CheckOptions {
  std::size_t max_depth = 8;          // actions from boot
  std::size_t max_configs = 200000;   // stop exploring beyond this many configurations
  std::string out_dir = ".";          // where a counterexample .scn is written
  bool verbose = false;
  // For testing the checker itself: demand IDLE (instead of ESTOP_ACTIVE) after an
  // E-stop, so that a violation, its counterexample and its replay can be shown.
  bool break_invariant = false;
};

struct CheckStats {
  std::size_t configurations = 0;  // distinct abstract configurations reached
  std::size_t transitions = 0;     // actions applied
  std::size_t cycles = 0;          // scan cycles run
  std::size_t checks = 0;          // invariant checks made
  std::size_t max_depth = 0;
  bool complete = false;           // the reachable set was exhausted within the bounds
};

// Returns 0 when every invariant held, 1 on a violation (counterexample written), 2 on
// bad options.
int check_main(const CheckOptions& opt, CheckStats& stats);

}  // namespace safestate::check

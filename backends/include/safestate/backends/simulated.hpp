// The simulated cell for measurement harnesses (rta/, the benches): the sim::Cell the
// factory's `sim` choice runs, with what a measurement of it needs (the plant's home pose and
// timing). What such a harness measures is the simulation: rta's figures say so
// (docs/response-time.md). The loop of `safestate run` gets its backend from factory.hpp.
#pragma once

#include "safestate/sim/cell.hpp"
#include "safestate/sim/plant.hpp"

// Response time analysis (SPEC §13): for every safety function, the worst-case time from
// the input's change to the actuator's safe state, term by term, computed from the core's
// own constants (core/config.hpp, the monitors), the simulated cell's (sim/plant.hpp), the
// robot model (motion/robot.hpp) and the active safety configuration. Nothing here is a
// figure of its own: every term names where it comes from. Not real-time (runs once).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "safestate/core/config.hpp"
#include "safestate/safety/safety_config.hpp"

namespace safestate::rta {

// How the I/O reaches the core: the simulated cell's plant (in the cycle) or an EtherCAT
// segment (one exchange per cycle, a frame timeout, the fieldbus watchdog).
struct BusTiming {
  bool ethercat = false;
  std::string source;               // "simulated cell" or the bus configuration's file name
  std::uint32_t frame_timeout_us = 0;
  std::uint32_t watchdog_ms = 0;    // `safestate run --watchdog-ms`
  // SPEC §11: the bus has a distance_sensor subdevice (always so in the simulated cell).
  // Without one the separation is invalid: SSM holds the program at v_allowed 0.
  bool distance_sensor = true;
  // Issue 37: the bus carries the black channel (safe terminals, the drives' containers): the
  // contacts and the contactors travel in containers, one exchange of the ping-pong each way
  // more, and a container that does not come opens the outputs after its watchdog.
  bool safety_links = false;
  std::uint32_t link_watchdog_ms = 0;  // the longest of the connections'
};

struct Term {
  std::string name;     // what takes the time
  std::uint64_t us = 0; // worst case, microseconds
  std::string basis;    // where the figure comes from
};

enum class StopKind : std::uint8_t { cat0, cat1, cat2, reduce };
const char* to_string(StopKind k) noexcept;

struct Function {
  std::string id;       // stable key: estop, guard, enable, t1_speed, joint_range, ...
  std::string name;
  std::string rule;     // SPEC §4 rule, e.g. "2"
  StopKind stop = StopKind::cat0;
  bool active = true;   // false: not configured (the figures then use the file's values anyway)
  std::string note;
  // Cycles from the input's change to the cycle whose outputs command the safe state
  // (stop begun, power removal written): input filter + scan + bus. The in-process
  // measurement must never exceed it (tests/unit/test_rta_measured.cpp).
  std::uint64_t reaction_cycles = 0;
  std::vector<Term> terms;
  [[nodiscard]] std::uint64_t total_us() const noexcept;
};

struct Analysis {
  std::uint32_t cycle_us = 0;
  std::string safety_name;
  std::string safety_checksum;
  BusTiming bus;
  std::vector<Function> functions;
  [[nodiscard]] const Function* find(const std::string& id) const noexcept;
};

// `cfg` must have passed core::validate(); its max_stop_ms is replaced by the
// configuration's stop.max_time_ms (SPEC §10: the file's value wins).
Analysis analyse(const core::Config& cfg, const safety::Loaded& safety, const BusTiming& bus);

std::string table(const Analysis& a);  // aligned text, one block per function
std::string json(const Analysis& a);   // one JSON object

// ---- Measured on the simulated cell, in-process (rta/src/measure.cpp) --------------------

// One safety function triggered on a running sim::Cell. Cycles count from the input's
// change (made between two cycles): `reaction_cycles` to the first cycle whose outputs
// command the safe state (contactor open / stop begun / reduced mode on), `safe_cycles` to
// the safe state itself (contactor's feedback open and standstill for Cat 0; contactor
// open at the end of a Cat 1; standstill held for Cat 2; TCP at or below the reduced limit).
// A state of the plant after cycle n is seen by the core in cycle n+1: it counts as n.
struct Measured {
  std::string id;
  bool measured = false;
  std::string how;     // the situation and what changed, or why it is not measured
  std::string alarm;   // the alarm that stopped the arm, when one did
  std::uint64_t reaction_cycles = 0;
  std::uint64_t safe_cycles = 0;
};

// Every function of analyse(), in its order. `s` as for analyse(); functions the
// configuration does not enable are measured with it enabled (fields: collaborative on).
// The limits (T1 speed, SPEC §10) and SSM are measured from the cycle the measured quantity
// crosses the limit, with a drive fault, and the limit under test moved beside the arm's
// pose (measure.cpp says why); SSM only where the configuration sets its parameters.
std::vector<Measured> measure(const core::Config& cfg, const safety::Loaded& s);
std::string measured_json(const std::vector<Measured>& m, std::uint32_t cycle_us);

}  // namespace safestate::rta

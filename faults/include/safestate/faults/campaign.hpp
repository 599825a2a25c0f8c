// SPEC §14 "Measured, not assumed": a fault-injection campaign on the simulated cell. Each
// injection is one single fault — a channel stalled or crashed, a channel reading one contact
// wrong, digests corrupted, dropped or repeated, a contactor welded, an encoder stuck, off or
// drifting, or a random bit flipped in one channel's supervisor (its state, timers, monitors'
// memory) — put into a warm cell at a random moment, followed after kDetectCycles by each
// demand of that cell's situation (each injection in one of four situations, in turn):
//  - AUTO, the demo program moving: E-stop, guard opened, drive 1 running away, reduced speed
//    requested (the speed over its new limit);
//  - T1, axis 1 jogged from the pendant: the enabling device released;
//  - AUTO, standing in a keep_in slot: drive 1 running away into its wall (a zone);
//  - AUTO, standing 2 degrees inside axis 1's limits: drive 1 running away past them.
// Each injection runs in a child process of its own (a flipped bit may crash it: a crashed
// process is what `channel X crash` models, named by the other channel), from the warm cells
// made once. Reproducible: injection i of seed s is always the same fault in the same
// situation at the same moment.
//
// Each injection is classified:
//  - dangerous (undetected): a demand did not reach its safe state within the fault-free
//    cell's reaction plus cross_check_cycles, or the safety outputs differed from the
//    fault-free twin's and no diagnostic alarm ever named it;
//  - detected: a diagnostic lockout (CHANNEL_MISMATCH, CHANNEL_LOST, ENCODER_DISCREPANCY,
//    CONTACTOR_WELDED, INTEGRITY_FAULT) named it, before the demands or at one, and every
//    demand reached its safe state in time;
//  - masked: no effect on the safety outputs, nothing named, every demand in time;
//  - fail-safe: the safety outputs went only towards safe (power off, brakes on) without a
//    diagnostic alarm naming it (a safe failure: not in the diagnostic coverage);
//  - crashed: the child process died (a bit flip made the channel's program fail).
// Diagnostic coverage = detected / (detected + dangerous), crashes counted as detected with
// two channels (the partner names a dead channel) and left out with one.
//
// Issue 37 (`--fieldbus ethercat`): the warm cells carry the black channel of the shipped
// segment (sim/black_channel.hpp: the containers and both ends are the real code, the bus a
// byte copy in this process, the frames not built) and a quarter of the injections, drawn
// from a stream of their own (the others are the sim campaign's draws, index by index), are
// faults on its wire: a flipped bit, a stale container replayed, two connections' containers
// swapped, a connection's containers held past the watchdog, another connection's container
// inserted; a random connection, direction, moment and bit. For each: whether
// SAFETY_LINK_FAULT named it, and the cycles from the injection to the safe output
// terminal's K1 or K2 open (the power path open) and to both open, against the 10-cycle
// watchdog.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace safestate::faults {

inline constexpr std::uint32_t kDetectCycles = 300;   // from the fault to the demands
inline constexpr std::uint32_t kDemandCycles = 3000;  // a demand not safe by then is lost

// Where the channels' safety data travel: the simulated cell's process image (sim), or the
// black channel of the EtherCAT segment, in the simulated world (ethercat).
enum class Fieldbus : std::uint8_t { sim, ethercat };
[[nodiscard]] const char* to_string(Fieldbus f) noexcept;
// "sim" or "ethercat"; false otherwise (`out` unchanged).
[[nodiscard]] bool parse_fieldbus(const std::string& s, Fieldbus& out) noexcept;

struct Options {
  std::uint32_t seed = 1;
  std::uint32_t injections = 10000;
  std::uint8_t channels = 2;
  std::uint32_t jobs = 2;       // child processes at once
  std::uint32_t first = 0;      // the first injection's index (one injection: --first I --injections 1)
  Fieldbus fieldbus = Fieldbus::sim;
};

enum class Outcome : std::uint8_t { detected, masked, dangerous, crashed, failsafe };
[[nodiscard]] const char* to_string(Outcome o) noexcept;

struct ClassStats {
  std::string name;
  std::uint64_t injected = 0;
  std::uint64_t detected = 0;
  std::uint64_t masked = 0;
  std::uint64_t dangerous = 0;
  std::uint64_t crashed = 0;
  std::uint64_t failsafe = 0;
  std::uint64_t named_before_demand = 0;
};

struct DemandStats {
  std::string name;
  std::string situation;    // where it is made (its warm cell)
  std::uint64_t pairs = 0;  // injections in its situation
  std::uint64_t safe = 0;
  std::uint32_t reaction_cycles = 0;  // the fault-free warm cell's
  std::string answered_by;            // the alarm the fault-free cell answered it with ("": its own stop)
};

// One injection's result (also the record a child writes to its parent).
struct Injection {
  std::uint32_t index = 0;
  std::string fault;  // in the scenario language, or "channel A flip byte N bit B"
  std::string cls;
  Outcome outcome = Outcome::masked;
  std::int32_t to_lockout = -1;  // cycles from the fault to the naming lockout (-1: none before the demands)
  std::string named;             // the diagnostic alarm that named it
  std::vector<bool> demand_safe;  // per demand of the campaign (true for another situation's)
  std::vector<bool> demand_run;   // whether the demand was made (its situation's)
  std::string situation;
  // A bus fault's (--fieldbus ethercat): SAFETY_LINK_FAULT's detail (link.0xA001.crc) and the
  // cycles from the injection to it, to the F-DO's K1 or K2 open, to both open (-1: not
  // within the window before the demands).
  std::string link_detail;
  std::int32_t to_link_fault = -1;
  std::int32_t to_power_open = -1;
  std::int32_t to_both_open = -1;
  // Cycles from the last new valid container the hosting channel accepted on the faulted
  // connection to K1 or K2 open (the watchdog bounds it; the injection may find one in flight).
  std::int32_t from_last_valid = -1;
};

// One class of bus faults (--fieldbus ethercat).
struct BusStats {
  std::string name;
  std::uint64_t injected = 0;
  std::uint64_t caught = 0;     // SAFETY_LINK_FAULT named it before the demands
  std::uint64_t dangerous = 0;  // as the campaign's classification
  std::vector<std::uint32_t> to_link_fault;  // cycles, each caught one
  std::vector<std::uint32_t> to_power_open;  // cycles to K1 or K2 open at the F-DO
  std::vector<std::uint32_t> to_both_open;   // cycles to K1 and K2 open at the F-DO
  std::vector<std::uint32_t> from_last_valid;  // cycles from the last valid container accepted to K1 or K2 open
  std::uint64_t not_opened = 0;              // the F-DO's K1 and K2 not both open in the window
  std::vector<std::pair<std::string, std::uint64_t>> errors;  // the error SAFETY_LINK_FAULT named, and how often
};

struct Report {
  Options options;
  std::vector<ClassStats> classes;
  std::vector<BusStats> bus;           // --fieldbus ethercat: the bus fault classes
  std::uint32_t watchdog_cycles = 0;   // the connections' watchdog, in cycles
  std::vector<DemandStats> demands;
  std::vector<std::uint32_t> to_lockout;  // cycles, every detection before the demands
  std::vector<Injection> dangerous;       // each one, to reproduce (--first I --injections 1)
  std::uint64_t injected = 0;
  std::uint64_t detected = 0;
  std::uint64_t masked = 0;
  std::uint64_t dangerous_count = 0;
  std::uint64_t crashed = 0;
  std::uint64_t failsafe = 0;
  std::uint64_t pairs = 0;
  std::uint64_t pairs_safe = 0;
  double dc = 0.0;
  std::string error;  // set when the campaign could not run (the warm cell did not reach AUTO)
};

[[nodiscard]] Report run(const Options& o);
[[nodiscard]] std::string table(const Report& r);
[[nodiscard]] std::string json(const Report& r);

}  // namespace safestate::faults

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
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace safestate::faults {

inline constexpr std::uint32_t kDetectCycles = 300;   // from the fault to the demands
inline constexpr std::uint32_t kDemandCycles = 3000;  // a demand not safe by then is lost

struct Options {
  std::uint32_t seed = 1;
  std::uint32_t injections = 10000;
  std::uint8_t channels = 2;
  std::uint32_t jobs = 2;       // child processes at once
  std::uint32_t first = 0;      // the first injection's index (one injection: --first I --injections 1)
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
};

struct Report {
  Options options;
  std::vector<ClassStats> classes;
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

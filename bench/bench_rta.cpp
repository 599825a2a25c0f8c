// SPEC §13 for bench/response_time.py: the analysis of `safestate rta` and the same
// functions measured in-process on the simulated cell, as one JSON object
// {"computed": ..., "measured": ...}. Usage: bench_rta [--safety FILE] [--cycle-us N]
#include <cstdio>
#include <cstdlib>
#include <string>

#include "safestate/rta/rta.hpp"

using namespace safestate;

int main(int argc, char** argv) {
  std::string file;
  core::Config cfg{};
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--safety") {
      file = argv[i + 1];
    } else if (a == "--cycle-us") {
      cfg.cycle_us = static_cast<std::uint32_t>(std::strtoul(argv[i + 1], nullptr, 10));
    } else {
      std::fprintf(stderr, "bench_rta: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (const core::ConfigError e = core::validate(cfg); !e.ok()) {
    std::fprintf(stderr, "bench_rta: %s: %s\n", e.field, e.reason);
    return 2;
  }
  const safety::Result r = file.empty() ? safety::parse_safety(safety::default_safety_text()) : safety::load_safety_file(file);
  if (!r.ok()) {
    for (const safety::Error& e : r.errors) std::fprintf(stderr, "bench_rta: %s: %s\n", file.c_str(), e.text().c_str());
    return 2;
  }
  rta::BusTiming bus;
  bus.source = "simulated cell";
  const std::string computed = rta::json(rta::analyse(cfg, *r.config, bus));
  const std::string measured = rta::measured_json(rta::measure(cfg, *r.config), cfg.cycle_us);
  std::printf("{\"computed\": %s, \"measured\": %s}\n", computed.c_str(), measured.c_str());
  return 0;
}

// `safestate rta [--safety FILE] [--bus-config FILE] [--json]`: SPEC §13's worst-case
// response time of every safety function, term by term (rta/). Registered from main.cpp
// by add_rta_command, run when parsed.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <string>

#include "safestate/core/config.hpp"
#include "safestate/hal/ethercat.hpp"
#include "safestate/rta/rta.hpp"
#include "safestate/runtime/runtime.hpp"
#include "safestate/safety/safety_config.hpp"

namespace safestate::app {

namespace {
struct RtaOptions {
  std::string safety_file;
  std::string bus_file;
  bool json = false;
  std::uint32_t cycle_us = core::Config{}.cycle_us;
  std::uint32_t watchdog_ms = runtime::RtOptions{}.watchdog_ms;
};
RtaOptions g_rta;

int rta_main(const RtaOptions& o) {
  core::Config cfg{};
  cfg.cycle_us = o.cycle_us;
  if (const core::ConfigError e = core::validate(cfg); !e.ok()) {
    std::fprintf(stderr, "safestate rta: --cycle-us: %s: %s\n", e.field, e.reason);
    return 2;
  }
  const safety::Result r =
      o.safety_file.empty() ? safety::parse_safety(safety::default_safety_text()) : safety::load_safety_file(o.safety_file);
  if (!r.ok()) {
    for (const safety::Error& e : r.errors) {
      std::fprintf(stderr, "safestate rta: %s: %s\n", o.safety_file.c_str(), e.text().c_str());
    }
    return 2;
  }
  rta::BusTiming bus;
  bus.source = "simulated cell";
  if (!o.bus_file.empty()) {
    hal::ethercat::BusConfig bc;
    std::string err;
    if (!hal::ethercat::load_bus_config(o.bus_file, bc, err)) {
      std::fprintf(stderr, "safestate rta: %s: %s\n", o.bus_file.c_str(), err.c_str());
      return 2;
    }
    if (static_cast<std::uint64_t>(o.watchdog_ms) * 1000U < 2U * static_cast<std::uint64_t>(o.cycle_us)) {
      std::fprintf(stderr, "safestate rta: --watchdog-ms: must span at least two cycles\n");
      return 2;
    }
    bus.ethercat = true;
    bus.source = o.bus_file;
    bus.frame_timeout_us = bc.frame_timeout_us;
    bus.watchdog_ms = o.watchdog_ms;
    bus.distance_sensor = std::any_of(bc.subdevices.begin(), bc.subdevices.end(), [](const hal::ethercat::Subdevice& d) {
      return d.role == hal::ethercat::Role::distance_sensor;
    });
    // Issue 37: the black channel's connections (their longest watchdog).
    bus.safety_links = bc.links.count != 0U;
    for (std::size_t i = 0; i < bc.links.count; ++i) {
      bus.link_watchdog_ms = std::max<std::uint32_t>(bus.link_watchdog_ms, bc.links.link[i].watchdog_ms);
    }
  }
  const rta::Analysis a = rta::analyse(cfg, *r.config, bus);
  const std::string text = o.json ? rta::json(a) : rta::table(a);
  std::fwrite(text.data(), 1, text.size(), stdout);
  return 0;
}
}  // namespace

CLI::App* add_rta_command(CLI::App& app) {
  auto* c = app.add_subcommand("rta", "worst-case response time of every safety function, term by term (SPEC 13)");
  c->add_option("--safety", g_rta.safety_file, "safety configuration (SPEC 10, JSON; default: the built-in one)");
  c->add_option("--bus-config", g_rta.bus_file,
                "EtherCAT topology file: bus exchange and watchdog terms (default: the simulated cell's I/O)");
  c->add_option("--cycle-us", g_rta.cycle_us, "scan cycle in microseconds (250..4000)");
  c->add_option("--watchdog-ms", g_rta.watchdog_ms, "fieldbus watchdog of `safestate run` (with --bus-config)")
      ->check(CLI::Range(1, 10000));
  c->add_flag("--json", g_rta.json, "print one JSON object");
  return c;
}

int run_rta_command() { return rta_main(g_rta); }

std::string rta_safety_file() { return g_rta.safety_file; }

}  // namespace safestate::app

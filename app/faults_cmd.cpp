// `safestate faults [--seed N] [--injections N] [--channels 1|2] [--fieldbus sim|ethercat]
// [--jobs N] [--first I] [--json]`: SPEC §14's fault-injection campaign on the simulated cell
// (faults/); with `--fieldbus ethercat` the cell carries the black channel (issue 37) and the
// campaign adds faults on its wire. Registered from main.cpp by add_faults_command, run when
// parsed.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <string>

#include "safestate/faults/campaign.hpp"

namespace safestate::app {

namespace {
struct FaultsOptions {
  faults::Options campaign{};
  unsigned channels = 2;
  std::string fieldbus = "sim";
  bool json = false;
};
FaultsOptions g_faults;
}  // namespace

CLI::App* add_faults_command(CLI::App& app) {
  auto* c = app.add_subcommand(
      "faults", "fault-injection campaign on the simulated cell (SPEC 14): diagnostic coverage, demands that stayed safe");
  c->add_option("--seed", g_faults.campaign.seed, "seed (the same seed, the same faults)")->capture_default_str();
  c->add_option("--injections", g_faults.campaign.injections, "single faults to inject")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  c->add_option("--channels", g_faults.channels, "1 or 2 (2: SPEC 14's pair; 1: for comparison)")
      ->check(CLI::IsMember({1, 2}))
      ->capture_default_str();
  c->add_option("--fieldbus", g_faults.fieldbus,
                "sim (the simulated cell's process image) or ethercat (the EtherCAT segment's black channel, in the "
                "simulated world: the containers and both ends real, the bus a byte copy; adds the bus faults)")
      ->check([](const std::string& v) {
        faults::Fieldbus f{};
        return faults::parse_fieldbus(v, f) ? std::string()
                                            : "\"" + v + "\" is neither sim nor ethercat";
      })
      ->capture_default_str();
  c->add_option("--jobs", g_faults.campaign.jobs, "injections run at once (child processes)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  c->add_option("--first", g_faults.campaign.first, "index of the first injection (to replay one: --first I --injections 1)");
  c->add_flag("--json", g_faults.json, "print one JSON object");
  return c;
}

int run_faults_command() {
  faults::Options o = g_faults.campaign;
  o.channels = static_cast<std::uint8_t>(g_faults.channels);
  if (!faults::parse_fieldbus(g_faults.fieldbus, o.fieldbus)) {  // CLI11 checked it; nothing runs otherwise
    std::fprintf(stderr, "safestate faults: --fieldbus must be sim or ethercat, not \"%s\"\n", g_faults.fieldbus.c_str());
    return 2;
  }
  const faults::Report r = faults::run(o);
  const std::string text = g_faults.json ? faults::json(r) : faults::table(r);
  std::fwrite(text.data(), 1, text.size(), stdout);
  return r.error.empty() ? 0 : 2;
}

}  // namespace safestate::app

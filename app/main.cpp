// The one `safestate` command. Subcommands are added as the layers land.
#include <CLI/CLI.hpp>

#include <cstdio>

#include <string>
#include <vector>

#include "safestate/core/alarms.hpp"
#include "safestate/core/transitions.hpp"
#include "safestate/scenario/scenario.hpp"

using namespace safestate::core;

namespace safestate::app {
int demo_main(const std::string& file);
}

namespace {
int print_table() {
  std::printf("%-4s %-40s %-22s %-5s\n", "rule", "trigger", "to", "stop");
  for (const Transition& t : kTransitions) {
    std::printf("%-4s %-40.40s %-22s %-5s\n", t.rule, to_string(t.trigger), to_string(t.to), to_string(t.stop));
  }
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"SafeState: safety supervisor of a 6-axis robot controller"};
  app.require_subcommand(1);
  auto* version = app.add_subcommand("version", "print the version");
  auto* table = app.add_subcommand("table", "print the transition table the core runs");
  std::vector<std::string> files;
  bool trace = false;
  auto* replay = app.add_subcommand("replay", "run .scn scenarios on the simulated cell (exit 0 pass, 1 fail, 2 malformed)");
  replay->add_option("FILE", files, "scenario files")->required();
  replay->add_flag("--trace", trace, "print a JSON Lines trace on stdout");
  std::string demo_file = "examples/demo.scn";
  auto* demo = app.add_subcommand("demo", "replay a scenario on the simulated cell and narrate it in words");
  demo->add_option("FILE", demo_file, "scenario file (default examples/demo.scn)");
  CLI11_PARSE(app, argc, argv);
  if (demo->parsed()) {
    return safestate::app::demo_main(demo_file);
  }
  if (replay->parsed()) {
    return safestate::scenario::replay_main(files, trace);
  }
  if (version->parsed()) {
    std::printf("safestate %s\n", SAFESTATE_VERSION);
    return 0;
  }
  if (table->parsed()) {
    return print_table();
  }
  return 0;
}

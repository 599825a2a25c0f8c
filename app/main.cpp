// The one `safestate` command. Subcommands are added as the layers land.
#include <CLI/CLI.hpp>

#include <cstdio>

#include <string>
#include <vector>

#include "safestate/core/alarms.hpp"
#include "safestate/core/transitions.hpp"
#include "safestate/ecat/ecat_sim.hpp"
#include "safestate/ecat/esi_segment.hpp"
#include "checker.hpp"
#include "safestate/gateway/admission.hpp"
#include "safestate/gateway/gateway.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/runtime/runtime.hpp"
#include "safestate/safety/safety_config.hpp"
#include "safestate/scenario/scenario.hpp"

using namespace safestate::core;

namespace safestate::app {
int demo_main(const std::string& file);
int replay_ethercat_main(const std::string& file, bool trace, const std::string& ifname, const std::string& control,
                         const std::string& bus_config);
int safety_check_main(const std::string& file, bool builtin);
int safety_canonical_main(const std::string& file, bool with_checksum);
CLI::App* add_rta_command(CLI::App& app);
CLI::App* add_faults_command(CLI::App& app);
int run_faults_command();
std::string rta_safety_file();
int robot_fk_main(const std::string& q_deg, const std::string& qd_deg_s, const std::string& tcp_mm);
int run_rta_command();
CLI::App* add_ecat_config_command(CLI::App& app);
int run_ecat_config_command();
}

namespace {
// `--robot FILE.urdf --base LINK --flange LINK` (issue 38): the arm, read before anything is
// built. Without them: the safety configuration's `robot` key (run, rta), else the built-in
// ABB IRB 120 (examples/robots/abb_irb120.urdf).
struct RobotOptions {
  std::string file;
  std::string base;
  std::string flange;
};

void add_robot_options(CLI::App* c, RobotOptions& o) {
  c->add_option("--robot", o.file, "the arm's URDF (default: the built-in ABB IRB 120, examples/robots/abb_irb120.urdf)");
  c->add_option("--base", o.base, "the URDF's base link (default: its root)");
  c->add_option("--flange", o.flange, "the URDF's flange link (default: tool0, else the tip of its only chain)");
}

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
  std::string replay_fieldbus = "sim";
  std::string replay_ifname;
  std::string replay_control;
  std::string replay_bus;
  replay->add_option("--fieldbus", replay_fieldbus, "sim (default) or ethercat: the controller on the EtherCAT backend "
                                                   "against `safestate ecat-sim` (one file)")
      ->check(CLI::IsMember({"sim", "ethercat"}));
  replay->add_option("--ifname", replay_ifname, "ethercat: interface of the segment");
  replay->add_option("--ecat-sim-control", replay_control, "ethercat: ecat-sim's control socket (in/fault lines go there)");
  replay->add_option("--bus-config", replay_bus, "ethercat: topology file (default: built-in)");
  std::string demo_file = "examples/demo.scn";
  auto* demo = app.add_subcommand("demo", "replay a scenario on the simulated cell and narrate it in words");
  demo->add_option("FILE", demo_file, "scenario file (default examples/demo.scn)");
  safestate::runtime::RunOptions run_opt;
  auto* run = app.add_subcommand("run", "run the core on the simulated cell in a real-time loop, with the gateway");
  run->set_config("--config", "", "settings file (INI/TOML: port=8080, bind=..., db=..., cycle-us=...)");
  run->add_option("--port", run_opt.port, "HTTP/WebSocket port")->check(CLI::Range(1, 65535));
  run->add_option("--bind", run_opt.bind, "address to listen on (beyond loopback both tokens are required)");
  run->add_option("--db", run_opt.db, "SQLite event database (survives restarts)");
  run->add_option("--safety", run_opt.safety_file,
                  "safety configuration (SPEC 10, JSON; default: the built-in one). Any error: exit 2, nothing starts");
  std::string run_pendant_file;
  std::string run_remote_file;
  std::vector<std::string> run_origins;
  std::vector<std::string> run_hosts;
  std::size_t run_max_clients = 64;
  std::size_t run_max_http = 32;
  run->add_option("--pendant-token-file", run_pendant_file,
                  "file holding the pendant token (else env SAFESTATE_PENDANT_TOKEN; never on the command line)");
  run->add_option("--remote-token-file", run_remote_file,
                  "file holding the remote token (else env SAFESTATE_REMOTE_TOKEN)");
  run->add_option("--allow-origin", run_origins, "a further web origin allowed to connect (e.g. https://hmi.plant)");
  run->add_option("--allow-host", run_hosts, "a further Host name the server answers to");
  run->add_option("--max-clients", run_max_clients, "WebSocket clients at most (one slot kept for the pendant)")
      ->check(CLI::Range(2, 100000));
  run->add_option("--max-http", run_max_http, "HTTP requests in service at once (answered or upgraded)")
      ->check(CLI::Range(1, 100000));
  run->add_option("--cycle-us", run_opt.rt.cycle_us, "scan cycle in microseconds (250..4000)");
  run->add_option("--watchdog-ms", run_opt.rt.watchdog_ms, "fieldbus watchdog: a longer stall locks out")
      ->check(CLI::Range(1, 10000));
  run->add_option("--priority", run_opt.rt.priority, "SCHED_FIFO priority of the loop, 0 for none")
      ->check(CLI::Range(0, 99));
  run->add_option("--cpu", run_opt.rt.cpu, "pin the loop to this CPU");
  run->add_option("--channels", run_opt.channels,
                  "SPEC §14: 2 = channels A (GCC) and B (Clang) in processes of their own (the default on the "
                  "simulated cell and on a segment with K2 and the load-side encoders), 1 = one channel in this process")
      ->check(CLI::Range(1, 2));
  run->add_option("--cross-check-cycles", run_opt.cross_check_cycles,
                  "SPEC §14: cycles a channel's digest may be missing or differ (default 2); a wider window rides out "
                  "a host that stalls one channel's CPU (docs/two-channels.md)")
      ->check(CLI::Range(1, 100));
  run->add_option("--channel-a", run_opt.channel_a_exe, "channel A's program (default: safestate-channel beside this one)");
  run->add_option("--channel-b", run_opt.channel_b_exe,
                  "channel B's program (default: safestate-channel-clang beside this one)");
  run->add_option("--channel-cpu-a", run_opt.channel_cpu_a, "pin channel A to this CPU (-1: not; default CPU 0)")
      ->check(CLI::Range(-1, 1023));
  run->add_option("--channel-cpu-b", run_opt.channel_cpu_b, "pin channel B to this CPU (-1: not; default CPU 1)")
      ->check(CLI::Range(-1, 1023));
  run->add_option("--static", run_opt.static_dir, "folder of the HMI files served at /");
  run->add_option("--shm", run_opt.shm, "shared-memory segment name (default /safestate-PORT)");
  run->add_flag("!--no-opcua", run_opt.opcua, "do not start the OPC UA (OPC 40010-1) adapter");
  run->add_option("--opcua-port", run_opt.opcua_port, "OPC UA port (default 4840)")->check(CLI::Range(1, 65535));
  run->add_option("--opcua-bind", run_opt.opcua_bind,
                  "OPC UA listen address (beyond loopback --opcua-users-file is required)");
  run->add_option("--opcua-users-file", run_opt.opcua_users_file,
                  "users who may call OPC UA methods (name:scrypt:SALT:HASH lines, see docs/opcua.md)");
  run->add_option("--opcua-pki", run_opt.opcua_pki, "OPC UA certificate store (default opcua-pki beside --db)");
  run->add_option("--opcua-main", run_opt.opcua_main, "the adapter's main.js (default: this build's adapters/opcua)");
  run->add_flag("--ros2", run_opt.ros2, "start the ROS 2 adapter (adapters/ros2, `make ros2`; docs/ros2.md)");
  run->add_option("--ros2-domain-id", run_opt.ros2_domain_id, "its DDS domain (default: ROS_DOMAIN_ID, else 0)")
      ->check(CLI::Range(0, 232));
  run->add_option("--ros2-namespace", run_opt.ros2_namespace, "its namespace (default: none)");
  run->add_option("--fieldbus", run_opt.fieldbus, "sim (the in-process simulated cell, default) or ethercat")
      ->check(CLI::IsMember({"sim", "ethercat"}));
  run->add_option("--ifname", run_opt.ifname, "ethercat: network interface of the segment (needs CAP_NET_RAW)");
#if defined(SAFESTATE_TEST_HOOKS)
  run->add_option("--corrupt", run_opt.corrupt,
                  "TESTS: the master corrupts the black channel's containers it copies: 'KIND ID [ID2] DIR [ARG] "
                  "at=CYCLES' (flip ID DIR [BIT], replay ID DIR, swap ID ID2 DIR, delay ID DIR MS, insert ID FROM "
                  "DIR); repeatable. Not in a production build (SAFESTATE_TEST_HOOKS=OFF)");
#endif
  run->add_option("--ecat-sim-control", run_opt.ecat_sim_control,
                  "ethercat on `safestate ecat-sim`: its --control socket, so the HMI's sim panel drives the emulator");
  run->add_option("--bus-config", run_opt.bus_config,
                  "ethercat: topology file (default: built-in, the segment of `safestate ecat-sim`)");
  safestate::runtime::RtBenchOptions rtb_opt;
  auto* rtbench = app.add_subcommand("rtbench", "measure the real-time loop's wake-up lateness (no gateway)");
  rtbench->add_option("--seconds", rtb_opt.seconds, "how long to run")->check(CLI::Range(1, 3600));
  rtbench->add_option("--cycle-us", rtb_opt.rt.cycle_us, "scan cycle in microseconds (250..4000)");
  rtbench->add_option("--priority", rtb_opt.rt.priority, "SCHED_FIFO priority of the loop, 0 for none")
      ->check(CLI::Range(0, 99));
  rtbench->add_option("--cpu", rtb_opt.rt.cpu, "pin the loop to this CPU");
  rtbench->add_flag("--json", rtb_opt.json, "print one JSON object");
  safestate::runtime::EcatBenchOptions eb_opt;
  auto* ecat_bench = app.add_subcommand("ecat-bench", "measure the EtherCAT exchange round trip (no core, no gateway)");
  ecat_bench->add_option("--ifname", eb_opt.ifname, "network interface of the segment")->required();
  ecat_bench->add_option("--bus-config", eb_opt.bus_config, "topology file (default: built-in)");
  ecat_bench->add_option("--cycles", eb_opt.cycles, "exchanges to time")->check(CLI::Range(1, 10000000));
  ecat_bench->add_option("--cycle-us", eb_opt.cycle_us, "period in microseconds")->check(CLI::Range(250, 4000));
  ecat_bench->add_flag("--json", eb_opt.json, "print one JSON object");
  safestate::gateway::GatewayOptions gw_opt;
  gw_opt.version = SAFESTATE_VERSION;
  auto* gateway = app.add_subcommand("gateway", "the non-real-time gateway (started by `safestate run`)");
  gateway->add_option("--shm", gw_opt.shm_name, "shared-memory segment of the core")->required();
  gateway->add_option("--bind", gw_opt.bind, "address to listen on");
  gateway->add_option("--port", gw_opt.port, "HTTP/WebSocket port")->check(CLI::Range(1, 65535));
  gateway->add_option("--db", gw_opt.db_path, "SQLite event database")->required();
  std::string gw_pendant_file;
  std::string gw_remote_file;
  gateway->add_option("--pendant-token-file", gw_pendant_file, "file holding the pendant token (else env SAFESTATE_PENDANT_TOKEN)");
  gateway->add_option("--remote-token-file", gw_remote_file, "file holding the remote token (else env SAFESTATE_REMOTE_TOKEN)");
  gateway->add_option("--allow-origin", gw_opt.allow_origins, "a further web origin allowed to connect");
  gateway->add_option("--allow-host", gw_opt.allow_hosts, "a further Host name the server answers to");
  gateway->add_option("--max-clients", gw_opt.max_clients, "WebSocket clients at most (one slot kept for the pendant)")
      ->check(CLI::Range(2, 100000));
  gateway->add_option("--max-http", gw_opt.max_http, "HTTP requests in service at once (answered or upgraded)")
      ->check(CLI::Range(1, 100000));
  gateway->add_option("--static", gw_opt.static_dir, "folder of the HMI files served at /");
  safestate::ecat::EcatSimOptions ecat_opt;
  auto* ecat_sim = app.add_subcommand(
      "ecat-sim",
      "emulate an EtherCAT segment on a network interface: EMULATED subdevices (a DI terminal, a DO terminal, six "
      "CiA 402 CSP drives, a distance sensor, a safe input and a safe output terminal speaking our black-channel "
      "protocol) in front of the simulated cell. It stands in for real hardware: it is no drive, no I/O, no safety "
      "device");
  ecat_sim->add_option("--ifname", ecat_opt.ifname, "network interface to answer EtherCAT frames on (needs CAP_NET_RAW)")
      ->required();
  ecat_sim->add_option("--control", ecat_opt.control,
                       "Unix socket for the emulated world: `in ...`, `fault ...` lines (scenario vocabulary, plus "
                       "`fault unplug N`, `fault replug`, `fault drop N`, `fault corrupt N`, `fault no-pd N`, `fault sdo-refuse POS INDEX:SUB ABORT`, `fault link flip|replay|swap|delay|insert ...`), `plant lockstep|paced|reset`, JSON sim messages, `status`");
  ecat_sim->add_option("--cycle-us", ecat_opt.cycle_us, "plant cycle when the master is silent (microseconds)")
      ->check(CLI::Range(250, 4000));
  ecat_sim->add_option("--priority", ecat_opt.priority, "SCHED_FIFO priority when permitted, 0 for none")
      ->check(CLI::Range(0, 99));
  ecat_sim->add_option("--cpu", ecat_opt.cpu, "pin the frame loop to this CPU (as `run --cpu`)")
      ->check(CLI::Range(0, 1023));
  ecat_sim->add_option("--product", ecat_opt.product_override, "POS=CODE: give subdevice POS another product code (tests)");
  ecat_sim->add_option("--revision", ecat_opt.revision_override, "POS=REV: give subdevice POS another revision (tests)");
  ecat_sim->add_flag("--drives-free-run", ecat_opt.drives_free_run,
                     "the drives also go to OP without DC SYNC0 (for masters that configure no distributed clocks)");
  ecat_sim->add_flag("--no-distance-sensor", ecat_opt.no_distance_sensor,
                     "a segment without the distance sensor (its bus configuration has no distance_sensor: the "
                     "separation stays invalid)");
  ecat_sim->add_flag("--no-safe-terminals", ecat_opt.no_safe_terminals,
                     "a segment without the safe input and output terminals and with the drives' PDOs without "
                     "safety containers, as before issue 37 (the DO terminal's bits drive the power path)");
  ecat_sim->add_option("--link-watchdog-ms", ecat_opt.link_watchdog_ms,
                       "the safe devices' watchdog per connection, ms (default 10; the bus configuration's "
                       "safety_links must give the same: it is in every container's CRC)")
      ->check(CLI::Range(1, 60000));
  ecat_sim->add_option("--link-seed", ecat_opt.link_seed,
                       "the safe devices' first sessions from this number instead of at random (tests)")
      ->check(CLI::Range(1U, 0xFFFFFFFFU));
  ecat_sim->add_flag("--lockstep", ecat_opt.lockstep,
                     "step the plant once per process-data exchange instead of on the drives' SYNC0 pulses (what "
                     "`safestate replay` asks for over the control socket)");
  ecat_sim->add_option("--drift-ppm", ecat_opt.drift_ppm,
                       "the emulated ESCs' clock drifts, ppm: one value for all or one per subdevice, comma-separated "
                       "(default 12,-25,31,-8,45,-37,19,-14)");
  ecat_sim->add_option("--sdo-refuse", ecat_opt.sdo_refuse,
                       "'POS INDEX:SUB ABORT': the drive at POS refuses SDO downloads to INDEX:SUB with ABORT (tests)");
  safestate::check::CheckOptions check_opt;
  auto* check = app.add_subcommand("check", "explore every reachable state of the real core and check the invariants");
  check->footer(
      "With no options: depth " + std::to_string(safestate::check::kDefaultCheckDepth) +
      ", every configuration within that many actions of boot and of each scripted seed (about 520,000; a few "
      "minutes, 1.3 GB), keeping at most " + std::to_string(safestate::check::kDefaultCheckConfigs) +
      " to explore deeper. `make test` runs depth 3, `make bench-check` depth 5 (docs/verification.md).");
  check->add_option("--depth", check_opt.max_depth, "actions from boot (and from each seed) to explore")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  check->add_option("--max-configs", check_opt.max_configs,
                    "configurations kept to explore one action deeper; beyond them new ones are checked, not explored")
      ->capture_default_str();
  check->add_option("--out", check_opt.out_dir, "folder for a counterexample .scn");
  check->add_flag("-v,--verbose", check_opt.verbose, "print progress per depth");
  check->add_flag("--pair", check_opt.pair,
                  "SPEC 14: explore two channels in lock-step and, at every configuration with a contactor closed, "
                  "freeze each channel in turn before each demand (the other must open its contactor within "
                  "cross_check_cycles + 1 cycles)");
  check->add_flag("--break-invariant", check_opt.break_invariant,
                  "test the checker: demand a wrong state after an E-stop (must find a counterexample)");
  std::string check_replay;
  std::size_t check_replay_cycles = 2000;
  check->add_option("--replay", check_replay,
                    "instead of exploring, replay FILE (a counterexample .scn) with every invariant and the reference "
                    "checked after every cycle");
  check->add_option("--replay-cycles", check_replay_cycles, "with --replay: cycles to run past the file's last line")
      ->capture_default_str();
  auto* safety = app.add_subcommand("safety", "the safety configuration (SPEC 10): check a file, print its RFC 8785 form");
  safety->require_subcommand(1);
  std::string safety_file;
  bool safety_default = false;
  auto* safety_check = safety->add_subcommand(
      "check", "print the name, checksum and limits of a safety configuration and every error (exit 0 valid, 2 not)");
  safety_check->add_option("FILE", safety_file, "safety configuration (JSON)");
  safety_check->add_flag("--default", safety_default, "check the built-in default configuration");
  bool canonical_checksum = false;
  auto* safety_canonical = safety->add_subcommand("canonical", "print the RFC 8785 (JCS) form of a JSON file");
  safety_canonical->add_option("FILE", safety_file, "JSON file")->required();
  safety_canonical->add_flag("--checksum", canonical_checksum, "also print its SHA-256 and checksum");
  auto* rta = safestate::app::add_rta_command(app);
  auto* faults = safestate::app::add_faults_command(app);
  auto* ecat_config = safestate::app::add_ecat_config_command(app);
  RobotOptions robot_opt;
  for (CLI::App* c : {replay, demo, run, gateway, ecat_sim, check, safety_check, rta, faults}) {
    add_robot_options(c, robot_opt);
  }
  CLI::App* robot_cmd = app.add_subcommand("robot", "the arm's description (URDF): forward kinematics");
  robot_cmd->require_subcommand(1);
  std::string fk_q;
  CLI::App* robot_fk = robot_cmd->add_subcommand(
      "fk", "print every link origin, the flange and the TCP (mm, JSON) at joint positions --q (degrees)");
  add_robot_options(robot_fk, robot_opt);
  robot_fk->add_option("--q", fk_q, "six joint positions in degrees, comma-separated; '-': lines of 6 (q) or 12 "
                                     "(q, qd) numbers on stdin, one JSON line each")
      ->required();
  std::string fk_qd;
  robot_fk->add_option("--qd", fk_qd, "six joint speeds in deg/s: also print the point speeds (core::point_speed)");
  std::string fk_tcp;
  robot_fk->add_option("--tcp", fk_tcp, "the TCP in the flange frame, mm: X,Y,Z (default 0,0,0)");
  CLI11_PARSE(app, argc, argv);
  {
    // The safety configuration's `robot` key names the arm when no --robot is given.
    std::string file = run->parsed() ? run_opt.safety_file : safestate::app::rta_safety_file();
    safestate::safety::RobotKey key;
    if (robot_opt.file.empty() && !file.empty() && safestate::safety::robot_key_of_file(file, key)) {
      robot_opt.file = key.urdf;
      if (robot_opt.base.empty()) robot_opt.base = key.base;
      if (robot_opt.flange.empty()) robot_opt.flange = key.flange;
    }
    std::string error;
    if (!safestate::robot::select(robot_opt.file, robot_opt.base, robot_opt.flange, error)) {
      std::fprintf(stderr, "safestate: robot description refused: %s\n", error.c_str());
      return 2;
    }
  }
  if (robot_fk->parsed()) {
    return safestate::app::robot_fk_main(fk_q, fk_qd, fk_tcp);
  }
  if (rta->parsed()) {
    return safestate::app::run_rta_command();
  }
  if (faults->parsed()) {
    return safestate::app::run_faults_command();
  }
  if (ecat_config->parsed()) {
    return safestate::app::run_ecat_config_command();
  }
  if (safety_check->parsed()) {
    return safestate::app::safety_check_main(safety_file, safety_default);
  }
  if (safety_canonical->parsed()) {
    return safestate::app::safety_canonical_main(safety_file, canonical_checksum);
  }
  if (check->parsed() && !check_replay.empty()) {
    return safestate::check::replay_main(check_replay, check_replay_cycles);
  }
  if (check->parsed()) {
    safestate::check::CheckStats stats;
    return safestate::check::check_main(check_opt, stats);
  }
  if (ecat_sim->parsed()) {
    // The emulated subdevices and their SII come from the shipped ESI (one description for
    // both ends of the wire: ecat-config reads the same file).
    std::string esi_error;
    if (!safestate::ecat::esi_segment(ecat_opt.devices, esi_error)) {
      std::fprintf(stderr, "ecat-sim: the built-in ESI: %s\n", esi_error.c_str());
      return 2;
    }
    return safestate::ecat::ecat_sim_main(ecat_opt);
  }
  if (gateway->parsed()) {
    std::string error;
    if (!safestate::gateway::load_token("SAFESTATE_PENDANT_TOKEN", gw_pendant_file, gw_opt.pendant_token, error) ||
        !safestate::gateway::load_token("SAFESTATE_REMOTE_TOKEN", gw_remote_file, gw_opt.remote_token, error)) {
      std::fprintf(stderr, "safestate gateway: %s\n", error.c_str());
      return 2;
    }
    return safestate::gateway::gateway_main(gw_opt);
  }
  if (ecat_bench->parsed()) {
    return safestate::runtime::ecat_bench_main(eb_opt);
  }
  if (rtbench->parsed()) {
    return safestate::runtime::rtbench_main(rtb_opt);
  }
  if (run->parsed()) {
    std::string error;
    if (!safestate::gateway::load_token("SAFESTATE_PENDANT_TOKEN", run_pendant_file, run_opt.pendant_token, error) ||
        !safestate::gateway::load_token("SAFESTATE_REMOTE_TOKEN", run_remote_file, run_opt.remote_token, error)) {
      std::fprintf(stderr, "safestate run: %s\n", error.c_str());
      return 2;
    }
    safestate::gateway::GatewayOptions g;
    g.bind = run_opt.bind;
    g.pendant_token = run_opt.pendant_token;
    g.remote_token = run_opt.remote_token;
    bool loopback = true;
    if (!safestate::gateway::bind_is_loopback(run_opt.bind, loopback, error)) {
      std::fprintf(stderr, "safestate run: %s\n", error.c_str());
      return 2;
    }
    if (const std::string why = safestate::gateway::startup_refusal(g, loopback); !why.empty()) {
      std::fprintf(stderr, "safestate run: %s\n", why.c_str());
      return 2;
    }
    for (const auto& o : run_origins) {
      run_opt.gateway_args.insert(run_opt.gateway_args.end(), {"--allow-origin", o});
    }
    for (const auto& h : run_hosts) {
      run_opt.gateway_args.insert(run_opt.gateway_args.end(), {"--allow-host", h});
    }
    if (!robot_opt.file.empty()) {  // the gateway serves the same arm at /api/robot
      run_opt.gateway_args.insert(run_opt.gateway_args.end(), {"--robot", robot_opt.file});
      if (!robot_opt.base.empty()) run_opt.gateway_args.insert(run_opt.gateway_args.end(), {"--base", robot_opt.base});
      if (!robot_opt.flange.empty()) {
        run_opt.gateway_args.insert(run_opt.gateway_args.end(), {"--flange", robot_opt.flange});
      }
    }
    run_opt.gateway_args.insert(run_opt.gateway_args.end(), {"--max-clients", std::to_string(run_max_clients),
                                                              "--max-http", std::to_string(run_max_http)});
    return safestate::runtime::run_main(run_opt);
  }
  if (demo->parsed()) {
    return safestate::app::demo_main(demo_file);
  }
  if (replay->parsed() && replay_fieldbus == "ethercat") {
    if (files.size() != 1U || replay_ifname.empty() || replay_control.empty()) {
      std::fprintf(stderr, "safestate replay --fieldbus ethercat: one FILE, --ifname and --ecat-sim-control\n");
      return 2;
    }
    return safestate::app::replay_ethercat_main(files[0], trace, replay_ifname, replay_control, replay_bus);
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

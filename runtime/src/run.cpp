#include <link.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "safestate/robot/description.hpp"
#include "safestate/gateway/event_log.hpp"
#include "safestate/hal/ethercat.hpp"
#include "safestate/backends/factory.hpp"
#include "safestate/pair/host.hpp"
#include "safestate/pair/os.hpp"
#include "safestate/runtime/runtime.hpp"
#include "safestate/safety/safety_config.hpp"

extern char** environ;

namespace safestate::runtime {

namespace {

std::string self_exe() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1U);
  return (n > 0) ? std::string(buf, static_cast<std::size_t>(n)) : std::string("safestate");
}

// Writes each forwarded `sim` record as a line to ecat-sim's control socket (a Unix
// socket: reachable from any network namespace) and logs a refusal. Not real-time.
void forward_sim(SimForward& fwd, const std::string& path, const std::atomic<bool>& run) {
  int fd = -1;
  while (run.load()) {
    bridge::CommandRecord rec{};
    if (!fwd.pop(rec)) {
      usleep(2000);
      continue;
    }
    if (fd < 0) {
      fd = socket(AF_UNIX, SOCK_STREAM, 0);
      sockaddr_un sa{};
      sa.sun_family = AF_UNIX;
      std::snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path.c_str());
      if (connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
        std::fprintf(stderr, "safestate run: ecat-sim control %s: %s\n", path.c_str(), std::strerror(errno));
        close(fd);
        fd = -1;
        continue;
      }
    }
    const std::string line = sim_line(rec) + "\n";
    char answer[512] = {0};
    if (send(fd, line.data(), line.size(), MSG_NOSIGNAL) < 0 || recv(fd, answer, sizeof answer - 1U, 0) <= 0) {
      close(fd);
      fd = -1;
      continue;
    }
    if (std::strncmp(answer, "OK", 2) != 0) {
      std::fprintf(stderr, "safestate run: ecat-sim refused '%s': %s", sim_line(rec).c_str(), answer);
    }
  }
  if (fd >= 0) {
    close(fd);
  }
}

// This process's environment with the tokens set (or removed when there are none), so
// that the gateway child gets them without a command line.
std::vector<std::string> child_environment(const RunOptions& opt) {
  std::vector<std::string> env;
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string v(*e);
    if (v.rfind("SAFESTATE_PENDANT_TOKEN=", 0) != 0 && v.rfind("SAFESTATE_REMOTE_TOKEN=", 0) != 0) {
      env.push_back(v);
    }
  }
  if (!opt.pendant_token.empty()) {
    env.push_back("SAFESTATE_PENDANT_TOKEN=" + opt.pendant_token);
  }
  if (!opt.remote_token.empty()) {
    env.push_back("SAFESTATE_REMOTE_TOKEN=" + opt.remote_token);
  }
  return env;
}

std::vector<char*> pointers(std::vector<std::string>& v) {
  std::vector<char*> p;
  for (std::string& a : v) {
    p.push_back(a.data());
  }
  p.push_back(nullptr);
  return p;
}

pid_t spawn_gateway(const RunOptions& opt, const std::string& shm) {
  const std::string exe = self_exe();
  std::vector<std::string> args = {exe,       "gateway", "--shm",    shm,         "--bind", opt.bind,
                                   "--port",  std::to_string(opt.port), "--db", opt.db, "--static", opt.static_dir};
  args.insert(args.end(), opt.gateway_args.begin(), opt.gateway_args.end());
  std::vector<char*> argv = pointers(args);
  std::vector<std::string> env_strings = child_environment(opt);
  std::vector<char*> envp = pointers(env_strings);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);  // the gateway handles its own SIGTERM
  // Its own process group: a Ctrl-C in the terminal reaches only `safestate run`, which
  // stops the robot first and then the gateway, so the final events are logged.
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETPGROUP);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, exe.c_str(), nullptr, &attr, argv.data(), envp.data());
  posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    std::fprintf(stderr, "safestate run: cannot start the gateway: %s\n", std::strerror(rc));
    return -1;
  }
  return pid;
}

void stop_gateway(pid_t pid) {
  if (pid <= 0) {
    return;
  }
  kill(pid, SIGTERM);
  for (int i = 0; i < 30; ++i) {
    if (waitpid(pid, nullptr, WNOHANG) == pid) {
      return;
    }
    usleep(100000);
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
}

double ms(std::uint64_t ns) { return static_cast<double>(ns) / 1.0e6; }

// ---------------------------------------------------------------- the OPC UA adapter
// A non-real-time child like the gateway, supervised the same way: a crash or a busy port
// costs the plant its OPC UA view, never the core or the gateway anything.
constexpr int kAdapterConfigError = 2;  // adapters/opcua/src/main.ts: EXIT_CONFIG

double mono_s() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<double>(now.tv_sec) + static_cast<double>(now.tv_nsec) / 1.0e9;
}

// A child that keeps dying is restarted after `first` s, then twice as long each time up
// to `most` s; one that lived `healthy` s starts the series again. The gateway: 0.5 s ..
// 30 s, healthy after a minute (protocol.md "One controller"); the OPC UA adapter: 1 s ..
// 30 s, healthy after 10 s.
class Restarts {
 public:
  Restarts(double first, double most, double healthy) : first_(first), most_(most), healthy_(healthy) {}
  void started(double now) { started_at_ = now; }
  double exited(double now) {
    delay_ = (now - started_at_ >= healthy_) ? first_ : std::min(most_, (delay_ <= 0.0) ? first_ : delay_ * 2.0);
    due_at_ = now + delay_;
    return delay_;
  }
  [[nodiscard]] bool due(double now) const { return now >= due_at_; }

 private:
  double first_;
  double most_;
  double healthy_;
  double started_at_ = 0.0;
  double delay_ = 0.0;
  double due_at_ = 0.0;
};

struct Adapter {
  const char* name = "OPC UA";  // in messages: "the OPC UA adapter", "the ROS 2 adapter"
  pid_t (*spawn)(const RunOptions&) = nullptr;
  pid_t pid = -1;
  bool enabled = false;
  Restarts restarts{1.0, 30.0, 10.0};
};

std::string opcua_main(const RunOptions& opt) {
#ifdef SAFESTATE_OPCUA_MAIN
  return opt.opcua_main.empty() ? std::string(SAFESTATE_OPCUA_MAIN) : opt.opcua_main;
#else
  return opt.opcua_main;
#endif
}

std::string opcua_pki(const RunOptions& opt) {
  if (!opt.opcua_pki.empty()) {
    return opt.opcua_pki;
  }
  const std::size_t slash = opt.db.rfind('/');
  return (slash == std::string::npos) ? std::string("opcua-pki") : opt.db.substr(0, slash + 1) + "opcua-pki";
}

// The adapter reaches the gateway over loopback when the gateway listens on every address.
std::string gateway_host(const RunOptions& opt) {
  return (opt.bind == "0.0.0.0" || opt.bind == "::") ? std::string("127.0.0.1") : opt.bind;
}

pid_t spawn_adapter(const RunOptions& opt) {
  // Secrets (the remote token) reach it through the environment, never argv.
  std::vector<std::string> args = {"node", opcua_main(opt), "--bind", opt.opcua_bind,
                                   "--port", std::to_string(opt.opcua_port),
                                   "--gateway", gateway_host(opt) + ":" + std::to_string(opt.port),
                                   "--pki", opcua_pki(opt), "--cycle-us", std::to_string(opt.rt.cycle_us)};
  if (!opt.opcua_users_file.empty()) {
    args.emplace_back("--users-file");
    args.push_back(opt.opcua_users_file);
  }
  std::vector<char*> argv;
  for (std::string& a : args) {
    argv.push_back(a.data());
  }
  argv.push_back(nullptr);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETPGROUP);
  pid_t pid = -1;
  std::vector<std::string> env = child_environment(opt);
  const int rc = posix_spawnp(&pid, "node", nullptr, &attr, argv.data(), pointers(env).data());
  posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    std::fprintf(stderr, "safestate run: cannot start the OPC UA adapter (node: %s); continuing without OPC UA\n",
                 std::strerror(rc));
    return -1;
  }
  return pid;
}

Adapter start_adapter(const RunOptions& opt) {
  Adapter a;
  a.spawn = spawn_adapter;
  if (!opt.opcua) {
    return a;
  }
  if (access(opcua_main(opt).c_str(), R_OK) != 0) {
    std::fprintf(stderr,
                 "safestate run: the OPC UA adapter is not built (%s missing; `make opcua` builds it); "
                 "continuing without OPC UA\n",
                 opcua_main(opt).c_str());
    return a;
  }
  a.pid = spawn_adapter(opt);
  a.enabled = a.pid > 0;
  a.restarts.started(mono_s());
  return a;
}

// ---------------------------------------------------------------- the ROS 2 adapter
// adapters/ros2 (rclpy from PyPI in .venv-ros2, `make ros2`), started and supervised like the
// OPC UA adapter: a `remote` client of the gateway, its token through the environment.
#ifndef SAFESTATE_ROS2_PYTHON
#define SAFESTATE_ROS2_PYTHON ".venv-ros2/bin/python"
#define SAFESTATE_ROS2_DIR "adapters/ros2"
#endif

pid_t spawn_ros2(const RunOptions& opt) {
  std::vector<std::string> args = {SAFESTATE_ROS2_PYTHON, "-m", "safestate_ros2", "--ros-args",
                                   "-p", "gateway:=" + gateway_host(opt) + ":" + std::to_string(opt.port),
                                   "-p", "cycle_us:=" + std::to_string(opt.rt.cycle_us)};
  if (opt.ros2_domain_id >= 0) {
    args.insert(args.end(), {"-p", "domain_id:=" + std::to_string(opt.ros2_domain_id)});
  }
  if (!opt.ros2_namespace.empty()) {
    args.insert(args.end(), {"-p", "namespace:=" + opt.ros2_namespace});
  }
  std::vector<char*> argv = pointers(args);
  std::vector<std::string> env = child_environment(opt);
  env.push_back(std::string("PYTHONPATH=") + SAFESTATE_ROS2_DIR);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETPGROUP);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, SAFESTATE_ROS2_PYTHON, nullptr, &attr, argv.data(), pointers(env).data());
  posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    std::fprintf(stderr, "safestate run: cannot start the ROS 2 adapter (%s); continuing without ROS 2\n",
                 std::strerror(rc));
    return -1;
  }
  return pid;
}

Adapter start_ros2(const RunOptions& opt) {
  Adapter a;
  a.name = "ROS 2";
  a.spawn = spawn_ros2;
  if (!opt.ros2) {
    return a;
  }
  if (access(SAFESTATE_ROS2_PYTHON, X_OK) != 0) {
    std::fprintf(stderr,
                 "safestate run: the ROS 2 adapter is not installed (%s missing; `make ros2` installs it); "
                 "continuing without ROS 2\n",
                 SAFESTATE_ROS2_PYTHON);
    return a;
  }
  a.pid = spawn_ros2(opt);
  a.enabled = a.pid > 0;
  a.restarts.started(mono_s());
  return a;
}

// Restart a dead adapter with growing back-off (1 s .. 30 s; reset after 10 s of life);
// a configuration error is not retried: it would fail the same way.
void supervise_adapter(const RunOptions& opt, Adapter& a) {
  if (!a.enabled) {
    return;
  }
  int status = 0;
  if (a.pid > 0 && waitpid(a.pid, &status, WNOHANG) == a.pid) {
    a.pid = -1;
    if (WIFEXITED(status) && WEXITSTATUS(status) == kAdapterConfigError) {
      std::fprintf(stderr, "safestate run: the %s adapter refused its configuration; %s stays off\n", a.name, a.name);
      a.enabled = false;
      return;
    }
    const double delay = a.restarts.exited(mono_s());
    std::fprintf(stderr, "safestate run: the %s adapter exited (%s %d); restarting it in %.1f s\n", a.name,
                 WIFSIGNALED(status) ? "signal" : "status", WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status),
                 delay);
  }
  if (a.pid < 0 && a.restarts.due(mono_s())) {
    a.pid = a.spawn(opt);
    a.enabled = a.pid > 0;
    a.restarts.started(mono_s());
  }
}

// The subdevices' names and the boot error, for the gateway's alarm texts (written before
// the gateway is spawned, never again: no reader sees them change).
void publish_bus(const hal::ethercat::Backend& bus, const hal::ethercat::BusConfig& bc, bridge::BusInfo& info) {
  const std::size_t n = std::min(bc.subdevices.size(), bridge::kBusNames);
  for (std::size_t i = 0; i < n; ++i) {
    bridge::copy_text(info.name[i], bc.subdevices[i].name.c_str());
  }
  bridge::copy_text(info.boot_error, bus.boot_error().c_str());
  info.count = static_cast<std::uint32_t>(n);
}

// This program's code for the platform's check of invariable memory (pair/os.hpp).
using pair::CodeRegion;
using pair::own_code;

// SPEC §14: a channel program beside this one (the build puts both there), unless given.
std::string beside_me(const std::string& given, const char* name) {
  if (!given.empty()) {
    return given;
  }
  char self[4096];
  const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1U);
  if (n <= 0) {
    return name;
  }
  self[n] = '\0';
  std::string dir(self);
  const std::size_t slash = dir.rfind('/');
  return (slash == std::string::npos ? std::string(".") : dir.substr(0, slash)) + "/" + name;
}

// The channels' CPUs: as given, or A on CPU 0 and B on CPU 1 when there are two or more.
int channel_cpu(int given, int which) {
  if (given != -2) {
    return given;
  }
  return (sysconf(_SC_NPROCESSORS_ONLN) >= 2) ? which : -1;
}

// SPEC §10 at start-up: the configuration (a file, or the built-in one), and whether the
// event log holds the operator's confirmation of its checksum. Nothing partial: any error
// in the file and nothing starts.
struct ActiveSafety {
  safety::Loaded config;
  std::string source;
  bool validated = false;
};

// @req LIM-RUN LIM-PERSIST
bool load_safety(const RunOptions& opt, ActiveSafety& out) {
  if (opt.safety_file.empty()) {
    out.config = safety::default_safety();
    out.source = "built-in";
    out.validated = true;  // the built-in configuration counts as validated (SPEC §10)
    std::fprintf(stderr, "safestate run: safety configuration: built-in \"%s\", checksum %s (validated)\n",
                 out.config.name.c_str(), out.config.checksum.c_str());
    return true;
  }
  const safety::Result r = safety::load_safety_file(opt.safety_file);
  if (!r.ok()) {
    std::fprintf(stderr, "safestate run: safety configuration %s: %zu error%s; not started\n", opt.safety_file.c_str(),
                 r.errors.size(), r.errors.size() == 1U ? "" : "s");
    for (const safety::Error& e : r.errors) {
      std::fprintf(stderr, "  %s\n", e.text().c_str());
    }
    return false;
  }
  out.config = *r.config;
  out.source = opt.safety_file;
  // Issue 38: the arm the configuration was checked against is the one the cell runs.
  if (out.config.robot.robot.get() != &robot::active() &&
      robot::canonical_parameters(*out.config.robot.robot) != robot::canonical_parameters(robot::active())) {
    std::fprintf(stderr, "safestate run: safety configuration %s names robot %s (%s), --robot gives %s (%s); not started\n",
                 opt.safety_file.c_str(), out.config.robot.robot->d.name.c_str(),
                 out.config.robot.robot->d.source.c_str(), robot::active().d.name.c_str(),
                 robot::active().d.source.c_str());
    return false;
  }
  if (out.config.canonical.size() >= bridge::kSafetyTextChars || out.source.size() >= bridge::kSafetySourceChars) {
    std::fprintf(stderr, "safestate run: safety configuration %s: too large to hand to the gateway; not started\n",
                 opt.safety_file.c_str());
    return false;
  }
  gateway::Confirmation c;
  bool found = false;
  std::string error;
  if (!gateway::latest_confirmation(opt.db, c, found, error)) {
    std::fprintf(stderr, "safestate run: event log %s: %s; the safety configuration counts as not validated\n",
                 opt.db.c_str(), error.c_str());
  }
  out.validated = found && c.checksum == out.config.checksum;
  std::fprintf(stderr, "safestate run: safety configuration %s: \"%s\", checksum %s, %s\n", opt.safety_file.c_str(),
               out.config.name.c_str(), out.config.checksum.c_str(),
               out.validated ? ("validated " + c.time + " by " + c.client).c_str()
                             : "NOT validated (validate_config on the pendant, T1/T2, IDLE)");
  return true;
}

// SPEC §12 at start-up: the latest brake test in the event log, and for a pass how long ago
// (the core counts on from there in cycles). An unreadable log, a malformed event or a time
// in the future count as no pass on record: the safe side (AUTO then needs a test when the
// configuration asks for one).
// @req BT-PERSIST
core::BrakeTestHistory brake_test_history(const RunOptions& opt) {
  core::BrakeTestHistory h{};
  gateway::BrakeTestRecord r;
  bool found = false;
  std::string error;
  if (!gateway::latest_brake_test(opt.db, r, found, error)) {
    std::fprintf(stderr, "safestate run: event log %s: %s; no brake test counts as passed\n", opt.db.c_str(),
                 error.c_str());
    return h;
  }
  if (!found) {
    std::fprintf(stderr, "safestate run: brake test: none on record\n");
    return h;
  }
  if (r.result == "failed") {
    h.last = core::BrakeTestResult::failed;
    std::fprintf(stderr, "safestate run: brake test: FAILED %s (AUTO refused until one passes)\n", r.time.c_str());
    return h;
  }
  std::uint64_t age_ms = 0;
  if (!gateway::age_ms_of(r.time, std::chrono::system_clock::now(), age_ms)) {
    std::fprintf(stderr, "safestate run: brake test: passed at %s, a time that cannot be aged (clock?); counts as none\n",
                 r.time.c_str());
    return h;
  }
  h.last = core::BrakeTestResult::passed;
  h.passed_ever = true;
  h.pass_age_ms = age_ms;
  std::fprintf(stderr, "safestate run: brake test: passed %s (%.2f h ago)\n", r.time.c_str(),
               static_cast<double>(age_ms) / 3.6e6);
  return h;
}

void publish_safety(const ActiveSafety& s, bridge::SafetyInfo& info) {
  bridge::copy_text(info.source, s.source.c_str());
  const std::size_t n = std::min(s.config.canonical.size(), info.canonical.size() - 1U);
  std::memcpy(info.canonical.data(), s.config.canonical.data(), n);
  info.canonical[n] = '\0';
  info.canonical_len = static_cast<std::uint32_t>(n);
  info.checksum = s.config.limits.checksum;
  info.set = 1U;
}

}  // namespace

namespace {

void keep_loop_cpu_free(int cpu) {
  if (cpu < 0) {
    return;
  }
  const auto c = static_cast<std::size_t>(cpu);
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0 || !CPU_ISSET(c, &set) || CPU_COUNT(&set) < 2) {
    return;  // nothing to keep free (one CPU), or the loop will not get that one anyway (said by the loop)
  }
  CPU_CLR(c, &set);
  if (sched_setaffinity(0, sizeof set, &set) != 0) {
    std::fprintf(stderr, "safestate run: warning: cannot keep CPU %d for the loop (%s)\n", cpu, std::strerror(errno));
  }
}

}  // namespace

int run_main(const RunOptions& opt) {
  core::Config cfg = opt.core;
  cfg.cycle_us = opt.rt.cycle_us;
  ActiveSafety safety;
  if (!load_safety(opt, safety)) {
    return 2;
  }
  cfg.max_stop_ms = safety.config.limits.max_stop_ms;  // SPEC §10: the file's stop.max_time_ms wins
  // @req CH-CONFIG
  // SPEC §14: the channels' window and the encoders' comparison from the safety configuration
  // (validated, under its checksum); a command line that says otherwise is refused.
  const safety::Channels& ch = safety.config.channels;
  if (safety.config.channels_configured && opt.cross_check_cycles != 0U &&
      opt.cross_check_cycles != ch.cross_check_cycles) {
    std::fprintf(stderr,
                 "safestate run: --cross-check-cycles %u: the safety configuration sets channels.cross_check_cycles = %u "
                 "(under its checksum); not started\n",
                 opt.cross_check_cycles, ch.cross_check_cycles);
    return 2;
  }
  cfg.cross_check_cycles = safety.config.channels_configured ? ch.cross_check_cycles
                           : (opt.cross_check_cycles != 0U ? opt.cross_check_cycles : ch.cross_check_cycles);
  cfg.encoder_tolerance_deg = static_cast<float>(ch.encoder_tolerance_deg);
  cfg.encoder_discrepancy_ms = ch.encoder_discrepancy_ms;
  if (const core::ConfigError e = core::validate(cfg); !e.ok()) {
    std::fprintf(stderr, "safestate run: invalid setting %s: %s\n", e.field, e.reason);
    return 2;
  }
  if (opt.rt.watchdog_ms * 1000U < 2U * opt.rt.cycle_us) {
    std::fprintf(stderr, "safestate run: invalid setting watchdog-ms: must span at least two cycles\n");
    return 2;
  }
  const std::string shm = opt.shm.empty() ? bridge::default_segment_name(opt.port) : opt.shm;
  std::string error;
  std::unique_ptr<bridge::Segment> seg = bridge::Segment::create(shm, error);
  if (!seg) {
    std::fprintf(stderr, "safestate run: %s\n", error.c_str());
    return 1;
  }
  // --cpu: the loop's CPU is kept for the loop (and, on EtherCAT, its exchange thread).
  // Everything else of ours (this thread, the gateway and adapter it spawns, the event log's
  // writes, the frame thread) runs on the other CPUs: on a kernel that does not preempt
  // kernel code (preempt=none), a system call of an ordinary thread on the loop's CPU (an
  // fsync of the event log took 127 ms under load) delays the loop's wake-up until it ends.
  keep_loop_cpu_free(opt.rt.cpu);
  // Signals are taken by this (main) thread only, with sigtimedwait.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  // The backend factory chooses what the controller runs on: the simulated cell here, or
  // --fieldbus ethercat: the controller directly on the EtherCAT backend (no simulator in
  // this process); BOOT is what decides whether the bus is right (a wrong or missing
  // subdevice is BOOT_FAILED).
  RtOptions rt = opt.rt;
  backends::Choice choice;
  choice.fieldbus = opt.fieldbus;
  choice.ifname = opt.ifname;
  choice.bus_config = opt.bus_config;
  choice.watchdog_ms = opt.rt.watchdog_ms;
  choice.channels = opt.channels;
  std::unique_ptr<backends::Host> host = backends::make_host(cfg, choice, error);
  if (!host) {
    std::fprintf(stderr, "safestate run: %s\n", error.c_str());
    return 2;
  }
  if (const std::string note = host->channels_note(); !note.empty()) {
    std::fprintf(stderr, "safestate run: %s\n", note.c_str());
  }
  hal::ethercat::Backend* const bus = host->ethercat();
  if (!opt.corrupt.empty()) {
    // Issue 37 item 4 (tests): the master at fault on the containers it copies.
    if (bus == nullptr || bus->safety_links().count == 0U) {
      std::fprintf(stderr, "safestate run: --corrupt needs --fieldbus ethercat with safety connections (safe terminals)\n");
      return 2;
    }
    hal::ethercat::LinkCorruptor c;
    for (const std::string& spec : opt.corrupt) {
      std::string err;
      if (!c.add(spec, bus->safety_links(), opt.rt.cycle_us, err)) {
        std::fprintf(stderr, "safestate run: %s\n", err.c_str());
        return 2;
      }
      std::fprintf(stderr, "safestate run: TEST: the master will corrupt the black channel: %s\n", spec.c_str());
    }
    bus->set_corruptor(std::move(c));
  }
  if (bus != nullptr) {
    const hal::ethercat::BusConfig& bc = *host->bus_config();
    std::fprintf(stderr, "safestate run: EtherCAT on %s, %zu subdevices expected\n", opt.ifname.c_str(), bc.subdevices.size());
    std::fprintf(stderr,
                 "safestate run: EtherCAT exchange timeout %u us, the bus is lost after %u stale cycles in a row; "
                 "process-data watchdog %u cycles (0x0400 = %u, 0x0420 = %u)\n",
                 bus->exchange_timeout_us(), bc.stale_cycles, bc.watchdog_cycles, bus->watchdog_divider(),
                 bus->watchdog_time());
    if (!bus->booted()) {
      std::fprintf(stderr, "safestate run: BOOT will fail: %s\n", bus->boot_error().c_str());
    } else if (bus->dc()) {
      std::fprintf(stderr,
                   "safestate run: distributed clocks: reference clock subdevice %d, SYNC0 every %u us, %u us after "
                   "the cycle's start; the loop follows DC time\n",
                   bus->dc_reference(), opt.rt.cycle_us, bc.sync0_shift_us);
      rt.cycle_adjust_ns = bus->cycle_adjust();
    }
    publish_bus(*bus, bc, seg->header().bus);
    if (const hal::LinkTable& links = bus->safety_links(); links.count != 0U) {
      // Issue 37: the safety data travel in containers the channels check (docs/black-channel.md).
      std::uint32_t watchdog = 0;
      for (std::size_t i = 0; i < links.count; ++i) {
        watchdog = std::max<std::uint32_t>(watchdog, links.link[i].watchdog_ms);
      }
      std::fprintf(stderr,
                   "safestate run: black channel: %u safety connections (safe input and output terminals, the "
                   "drives' load-side encoders), watchdog %u ms; the channels check every container, the master "
                   "copies them\n",
                   static_cast<unsigned>(links.count), watchdog);
    }
    rt.simulated = !opt.ecat_sim_control.empty();
  }
  // SPEC §14: the channels. Two (the default on the simulated cell): A and B in processes of
  // their own on the backend alone (pair/host.hpp); one: the controller in this process.
  const unsigned channels = host->channels();
  controller::Cell& cell = host->cell();
  controller::OneChannel one(cell);
  std::unique_ptr<pair::ChannelPair> two;
  controller::Channels* chans = &one;
  if (channels == 2U) {
    host->configure_limits(safety.config.limits, safety.validated);  // the world's tool
    two = std::make_unique<pair::ChannelPair>(cfg, *host->pair_backend());
    pair::PairOptions po;
    po.exe_a = beside_me(opt.channel_a_exe, "safestate-channel");
    po.exe_b = beside_me(opt.channel_b_exe, "safestate-channel-clang");
    po.shm_base = "/safestate-ch-" + std::to_string(getpid());
    po.cpu_a = channel_cpu(opt.channel_cpu_a, 0);
    po.cpu_b = channel_cpu(opt.channel_cpu_b, 1);
    po.priority = opt.rt.priority > 0 ? std::min(opt.rt.priority + 1, 99) : 0;  // above the loop that waits for them
    if (!two->start(po, robot::active().model, safety.config.limits, safety.validated, brake_test_history(opt),
                    error)) {
      std::fprintf(stderr, "safestate run: %s\n", error.c_str());
      return 1;
    }
#if defined(__clang__)
    constexpr const char* kCompilerA = "Clang";
    std::fprintf(stderr,
                 "safestate run: warning: this is a Clang build (a sanitizer or coverage tree): channel A is Clang's "
                 "too; the two compilers of SPEC §14 are the default build's\n");
#else
    constexpr const char* kCompilerA = "GCC";
#endif
    std::fprintf(stderr,
                 "safestate run: two channels (SPEC §14): A (%s, %s, pid %u, CPU %d) and B (Clang, %s, pid %u, CPU %d), "
                 "each its own process; the cross-check after every cycle, CHANNEL_LOST after %u cycles without the "
                 "other's digest; K1 from A, K2 from B\n",
                 kCompilerA, po.exe_a.c_str(), two->info(0).pid, po.cpu_a, po.exe_b.c_str(), two->info(1).pid, po.cpu_b,
                 cfg.cross_check_cycles);
    chans = two.get();
  }
  if (channels == 1U) {
    // The platform's checks (controller/platform.hpp) cover this program's code too: a CRC of
    // its text beside the core's tables, all within the integrity period (SPEC §14), after a
    // reference taken now.
    const CodeRegion code = own_code();
    if (code.p == nullptr || !cell.platform().add_rom(code.p, code.n)) {
      std::fprintf(stderr, "safestate run: warning: this program's code is not under the platform's CRC check\n");
    }
    std::fprintf(stderr,
                 "safestate run: platform checks every %.1f s: CRC-32 of %zu KiB (the core's tables, this program's "
                 "code; %zu bytes a cycle), pattern test of %zu words of the controller's state (%zu a cycle), start-up "
                 "self-test %s\n",
                 static_cast<double>(cell.platform().period()) * opt.rt.cycle_us * 1e-6, cell.platform().rom_bytes() / 1024U,
                 cell.platform().rom_slice(), cell.platform().ram_words(), cell.platform().ram_slice(),
                 cell.platform().self_test_ok() ? "passed" : "FAILED (BOOT_FAILED follows)");
  } else {
    std::fprintf(stderr, "safestate run: platform checks: each channel its own (its code, its constant tables, its state; "
                         "their lines above)\n");
  }
  // Before the first cycle, on the simulated cell and on EtherCAT alike.
  host->configure_limits(safety.config.limits, safety.validated);
  cell.configure_brake_test(brake_test_history(opt));
  publish_safety(safety, seg->header().safety);
  // The HMI's sim panel on an emulated segment: records to ecat-sim's control socket.
  SimForward forward;
  std::atomic<bool> forwarding{!opt.ecat_sim_control.empty() && bus != nullptr};
  std::thread forwarder;
  if (forwarding.load()) {
    rt.sim_forward = &forward;
    forwarder = std::thread([&] { forward_sim(forward, opt.ecat_sim_control, forwarding); });
  }
  RtLoop loop(*seg, *chans, host->world(), rt);
  std::atomic<bool> stop{false};
  std::atomic<bool> ready{false};
  std::thread rt_thread([&] {
    loop.setup();
    ready.store(true);
    loop.run(stop);
  });
  while (!ready.load()) {
    usleep(1000);
  }
  std::fputs(loop.setup_report().c_str(), stderr);

  pid_t gateway = spawn_gateway(opt, shm);
  std::printf("SafeState running: http://%s:%u  (%s, %u us cycle, events in %s)\n", opt.bind.c_str(), opt.port,
              bus ? "EtherCAT" : "simulated cell", rt.cycle_us, opt.db.c_str());
  Adapter adapter = start_adapter(opt);
  if (adapter.enabled) {
    std::printf("OPC UA (OPC 40010-1 Robotics): opc.tcp://%s:%u\n", opt.opcua_bind.c_str(), opt.opcua_port);
  }
  Adapter ros2 = start_ros2(opt);
  if (ros2.enabled) {
    std::printf("ROS 2: node %s/safestate (docs/ros2.md)\n", opt.ros2_namespace.c_str());
  }
  std::printf("Press Ctrl-C for a Cat 1 stop and a clean exit.\n");
  std::fflush(stdout);

  bool bus_loss_reported = false;
  bool channel_loss_reported = false;
  Restarts restarts{0.5, 30.0, 60.0};
  restarts.started(mono_s());
  for (;;) {
    timespec wait{0, 100000000};
    const int sig = sigtimedwait(&signals, nullptr, &wait);
    if (sig == SIGINT || sig == SIGTERM) {
      break;
    }
    supervise_adapter(opt, adapter);
    supervise_adapter(opt, ros2);
    // The core says FIELDBUS_LOST; this names whom it concerns (read off the RT path).
    if (bus && !bus_loss_reported && bus->lost().why != nullptr) {
      const auto loss = bus->lost();
      const auto pos = loss.position;
      const char* why = loss.why;
      const std::string whom = pos == 0U ? "the bus as a whole"
                               : "subdevice " + std::to_string(pos) + " (" + bus->subdevice_name(pos) + ")" +
                                     (loss.silent ? " and every one after it" : "");
      std::fprintf(stderr, "safestate run: FIELDBUS_LOST: %s: %s\n", whom.c_str(), why);
      if (bus->lost_after_cycles() > 0U) {
        std::fprintf(stderr, "safestate run: FIELDBUS_LOST after %u stale cycles, %.3f ms after the last answered frame\n",
                     bus->lost_after_cycles(), static_cast<double>(bus->lost_after_ns()) * 1e-6);
      }
      bus_loss_reported = true;
    }
    // SPEC §14: the channels say CHANNEL_LOST; this says whether the host kept the lost one
    // from running (its wake-up after a frame, measured by the channel itself), read off the
    // RT path from the status the loop published.
    if (two && !channel_loss_reported) {
      bridge::Status st{};
      if (seg->status().read(st) && (st.alarms & core::bit(core::AlarmId::CHANNEL_LOST)) != 0U) {
        channel_loss_reported = true;
        for (std::size_t i = 0; i < 2U; ++i) {
          const bridge::ChannelRecord& c = st.channels[i];
          const bool gone = c.running == 0U;
          std::fprintf(stderr,
                       "safestate run: CHANNEL_LOST: channel %c %s; the longest it was kept from starting on a frame: "
                       "%.1f ms (the window: %u cycles of %u us)\n",
                       i == 0U ? 'A' : 'B', gone ? "has ended" : (c.answered != 0U ? "answers" : "does not answer"),
                       static_cast<double>(c.wake_max_us) * 1e-3, cfg.cross_check_cycles, cfg.cycle_us);
        }
        const std::uint32_t worst = std::max(st.channels[0].wake_max_us, st.channels[1].wake_max_us);
        if (st.channels[0].running != 0U && st.channels[1].running != 0U &&
            worst >= cfg.cross_check_cycles * cfg.cycle_us) {
          std::fprintf(stderr,
                       "safestate run: a channel process was kept from running longer than the cross-check window by "
                       "this host's scheduler (no dedicated CPU, a kernel that does not preempt): correct for SPEC "
                       "§14, a lockout. On a development host: --cross-check-cycles N (make run CROSS_CHECK_CYCLES=N); "
                       "docs/two-channels.md \"On a shared host\"\n");
        }
      }
    }
    int status = 0;
    if (gateway > 0 && waitpid(gateway, &status, WNOHANG) == gateway) {
      gateway = -1;
      const double delay = restarts.exited(mono_s());
      std::fprintf(stderr,
                   "safestate run: the gateway exited (%s %d); the core keeps cycling; restarting it in %.1f s\n",
                   WIFSIGNALED(status) ? "signal" : "status", WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status),
                   delay);
    }
    if (gateway <= 0 && restarts.due(mono_s())) {
      gateway = spawn_gateway(opt, shm);
      restarts.started(mono_s());
      seg->header().gateway_restarts.fetch_add(1U, std::memory_order_relaxed);
    }
  }
  std::printf("\nsafestate run: stopping (Cat 1) ...\n");
  std::fflush(stdout);
  stop.store(true);
  rt_thread.join();
  stop_gateway(adapter.pid);
  stop_gateway(ros2.pid);
  forwarding.store(false);
  if (forwarder.joinable()) {
    forwarder.join();
  }
  stop_gateway(gateway);
  if (two) {
    two->stop();
  }
  const bridge::Metrics& m = seg->metrics();
  std::printf("safestate run: stopped in state %s after %llu cycles; overruns %llu, max lateness %.3f ms, max cycle %.3f ms\n",
              core::to_string(chans->out().state), static_cast<unsigned long long>(m.cycles.load()),
              static_cast<unsigned long long>(m.overruns.load()), ms(m.lateness_max_ns.load()), ms(m.exec_max_ns.load()));
  if (bus) {
    std::printf("safestate run: EtherCAT: %llu exchanges, %llu late or stray frames dropped\n",
                static_cast<unsigned long long>(bus->exchanges()),
                static_cast<unsigned long long>(hal::ethercat::Backend::stray_frames()));
  }
  return 0;
}

}  // namespace safestate::runtime

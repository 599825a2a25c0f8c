// The real-time side of `safestate run` (Linux only): a periodic loop on
// CLOCK_MONOTONIC with clock_nanosleep(TIMER_ABSTIME), memory locked, SCHED_FIFO when
// permitted, optional CPU pinning. Each cycle it takes binary records from the bridge,
// steps the cell, and publishes status, events, replies and the black box. It never
// blocks, waits or allocates on the bridge; it never parses network input.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "safestate/bridge/segment.hpp"
#include "safestate/controller/cell.hpp"
#include "safestate/controller/channels.hpp"
#include "safestate/core/config.hpp"
#include "safestate/vocab/world.hpp"

namespace safestate::runtime {

// The physical world of a cell on a real fieldbus is not in this process: `sim` records
// for an emulated segment (ecat-sim) are handed, without blocking, to a non-real-time
// thread that writes them to the emulator's control socket. Single producer (the RT
// loop), single consumer; full = the record is refused.
class SimForward {
 public:
  bool push(const bridge::CommandRecord& r) noexcept;
  bool pop(bridge::CommandRecord& r) noexcept;

 private:
  static constexpr std::uint32_t kSize = 64;
  std::array<bridge::CommandRecord, kSize> ring_{};
  std::atomic<std::uint32_t> head_{0};
  std::atomic<std::uint32_t> tail_{0};
};

// One `sim` record as a line of the emulator's control channel (`in ...` / `fault ...`).
std::string sim_line(const bridge::CommandRecord& r);

struct RtOptions {
  std::uint32_t cycle_us = 1000;
  std::uint32_t watchdog_ms = 100;  // EtherCAT process-data watchdog: a longer stall = fieldbus lost
  int priority = 80;                // SCHED_FIFO priority; 0 = do not ask for real-time scheduling
  int cpu = -1;                     // pin the loop to this CPU; -1 = no pinning
  std::uint32_t max_records_per_cycle = 16;
  bool simulated = true;            // sim messages are accepted (in-process cell, or forwarded)
  SimForward* sim_forward = nullptr;  // non-null: sim records go there instead of to the cell
  // Non-null (EtherCAT with distributed clocks): a correction of the next wake-up (ns) the
  // bus posts from DC time; the loop takes it (exchanging it for 0) once per cycle.
  std::atomic<std::int64_t>* cycle_adjust_ns = nullptr;
};

// Copies one cycle of the controller into the bridge. Fixed work, no allocation.
class Publisher {
 public:
  // `world`: the in-process simulated world, or null (a segment). The status shows the
  // simulated person when there is a world and the cell is `simulated`.
  Publisher(bridge::Segment& seg, const controller::Channels& cell, const vocab::World* world, bool simulated = true) noexcept
      : seg_(seg), cell_(cell), world_(world), simulated_(simulated), person_(simulated && world != nullptr) {}
  void publish() noexcept;                         // after cell.step()
  void reply(const bridge::ReplyRecord& r) noexcept;  // answers the runtime gives itself

 private:
  void event(const bridge::EventRecord& e) noexcept;
  bridge::Segment& seg_;
  const controller::Channels& cell_;
  const vocab::World* world_;
  bool simulated_;
  bool person_;
};

// Applies one record from the gateway: a command to the controller's queue; a sim record to
// the in-process world, or with `forward` (an emulated segment) to the emulator's control
// socket; answers sim records and refused commands at once (commands are otherwise answered
// by the core). A person record is applied all or nothing; with `forward` it is refused
// (person_not_on_bus); with neither world nor forward every sim record is NOT_SIMULATED.
void take_record(const bridge::CommandRecord& rec, controller::Channels& cell, vocab::World* world, Publisher& pub,
                 std::uint64_t t, SimForward* forward = nullptr) noexcept;

class RtLoop {
 public:
  // The controller on its backend and, for the in-process simulated cell, its world (null on
  // a segment): both from the backend factory (backends/factory.hpp).
  // `cell`: one channel in this process (controller::OneChannel) or a pair (pair/host.hpp).
  RtLoop(bridge::Segment& seg, controller::Channels& cell, vocab::World* world, const RtOptions& opt) noexcept;
  ~RtLoop();
  RtLoop(const RtLoop&) = delete;
  RtLoop& operator=(const RtLoop&) = delete;
  // Runs until `stop` is set, then performs a Cat 1 stop (servo_off) and returns once
  // the robot is no longer powered, or after `shutdown_cycles` more cycles.
  void run(const std::atomic<bool>& stop, std::uint64_t shutdown_cycles = 3000);
  // What the loop could set up (memory lock, SCHED_FIFO, affinity): for the log.
  [[nodiscard]] const std::string& setup_report() const noexcept { return report_; }
  void setup();  // call from the loop thread before run()
  // Optional: the wake-up lateness of every cycle, in ns, into a buffer the caller
  // allocated before run() (cycle k -> log[k]; cycles beyond its size are not logged).
  void log_lateness(std::span<std::uint32_t> log) noexcept { lateness_log_ = log; }

 private:
  void one_cycle() noexcept;
  bridge::Segment& seg_;
  controller::Channels& cell_;
  vocab::World* world_;
  RtOptions opt_;
  Publisher pub_;
  std::string report_;
  std::span<std::uint32_t> lateness_log_;
  int dma_latency_fd_ = -1;  // /dev/cpu_dma_latency held at 0 while the loop lives
};

}  // namespace safestate::runtime

namespace safestate::runtime {

struct RunOptions {
  unsigned port = 8080;
  std::string bind = "127.0.0.1";
  std::string db = "safestate-events.db";
  // Given to the gateway child through its environment (SAFESTATE_PENDANT_TOKEN,
  // SAFESTATE_REMOTE_TOKEN), never its argv: other local users can read a command line.
  std::string pendant_token;
  std::string remote_token;
  std::vector<std::string> gateway_args;  // further gateway options (no secrets)
  std::string static_dir = "hmi/dist";
  std::string shm;  // default: /safestate-<port>
  // The OPC 40010-1 adapter (adapters/opcua, Node.js), a supervised `remote` client.
  bool opcua = true;
  unsigned opcua_port = 4840;
  std::string opcua_bind = "127.0.0.1";
  std::string opcua_users_file;  // required by the adapter beyond loopback
  std::string opcua_pki;         // default: opcua-pki beside the event database
  std::string opcua_main;        // default: SAFESTATE_OPCUA_MAIN (the build's adapters/opcua/dist/main.js)
  // The ROS 2 adapter (adapters/ros2, rclpy in .venv-ros2), a supervised `remote` client; off
  // unless asked for (--ros2). Domain -1: the environment's ROS_DOMAIN_ID, else 0.
  bool ros2 = false;
  int ros2_domain_id = -1;
  std::string ros2_namespace;
  RtOptions rt{};
  core::Config core{};
  // SPEC §10: the safety configuration file; empty = the built-in configuration. A file
  // with any error refuses the start (exit 2, naming the key), never partial limits.
  std::string safety_file;
  std::string fieldbus = "sim";  // sim | ethercat
  std::string ifname;            // ethercat: the interface of the segment
  std::string bus_config;        // ethercat: topology file; empty = the shipped default (ecat-sim's segment)
  std::string ecat_sim_control;  // ethercat on ecat-sim: its control socket, for the HMI's sim panel
  // Issue 37 item 4, tests only (`--corrupt`, a SAFESTATE_TEST_HOOKS build): the master's own
  // faults on the black channel's containers (hal/link_corrupt.hpp).
  std::vector<std::string> corrupt;
  // SPEC §14: 2 = channels A (GCC) and B (Clang) in processes of their own (pair/host.hpp),
  // 1 = the one-channel controller in this process (for comparison); 0 = the backend's
  // default (2 on the simulated cell; 1 on EtherCAT until K2 is on the segment).
  unsigned channels = 0;
  // SPEC §14's window (`--cross-check-cycles`; 0: not given): the safety configuration's
  // `channels.cross_check_cycles` when it has one (then a different value here is refused),
  // else this, else SPEC's 2.
  std::uint32_t cross_check_cycles = 0;
  std::string channel_a_exe;  // default: safestate-channel beside this program
  std::string channel_b_exe;  // default: safestate-channel-clang beside this program
  int channel_cpu_a = -2;     // -2: CPU 0 with two CPUs or more, else not pinned; -1: not pinned
  int channel_cpu_b = -2;     // -2: CPU 1 with two CPUs or more
};

// `safestate run`: the core on the simulated cell in a real-time thread, plus the
// gateway as a supervised child process (restarted if it dies). SIGINT/SIGTERM: a Cat 1
// stop, then a clean exit. Returns the process exit code.
int run_main(const RunOptions& opt);

struct RtBenchOptions {
  unsigned seconds = 60;
  RtOptions rt{};
  bool json = false;
};

// `safestate rtbench`: the real-time loop alone (no gateway) on the simulated cell running
// the demo program in AUTO, for a given time; prints the wake-up lateness p50/p99/p99.9/max,
// the overruns and the execution time, in text or JSON. Used by bench/run.py beside cyclictest.
int rtbench_main(const RtBenchOptions& opt);

struct EcatBenchOptions {
  std::string ifname;
  std::string bus_config;  // empty = built-in (ecat-sim's segment)
  std::uint32_t cycles = 5000;
  std::uint32_t cycle_us = 1000;
  bool json = false;
};

// `safestate ecat-bench`: EtherCAT exchange round trip p50/p99/max on the bus alone.
int ecat_bench_main(const EcatBenchOptions& opt);

}  // namespace safestate::runtime

// The real-time side of `safestate run` (Linux only): a periodic loop on
// CLOCK_MONOTONIC with clock_nanosleep(TIMER_ABSTIME), memory locked, SCHED_FIFO when
// permitted, optional CPU pinning. Each cycle it takes binary records from the bridge,
// steps the cell, and publishes status, events, replies and the black box. It never
// blocks, waits or allocates on the bridge; it never parses network input.
#pragma once

#include <atomic>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "safestate/bridge/segment.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::runtime {

struct RtOptions {
  std::uint32_t cycle_us = 1000;
  std::uint32_t watchdog_ms = 100;  // EtherCAT process-data watchdog: a longer stall = fieldbus lost
  int priority = 80;                // SCHED_FIFO priority; 0 = do not ask for real-time scheduling
  int cpu = -1;                     // pin the loop to this CPU; -1 = no pinning
  std::uint32_t max_records_per_cycle = 16;
};

// Copies one cycle of the cell into the bridge. Fixed work, no allocation.
class Publisher {
 public:
  Publisher(bridge::Segment& seg, const sim::Cell& cell) noexcept : seg_(seg), cell_(cell) {}
  void publish() noexcept;                         // after cell.step()
  void reply(const bridge::ReplyRecord& r) noexcept;  // answers the runtime gives itself

 private:
  void event(const bridge::EventRecord& e) noexcept;
  bridge::Segment& seg_;
  const sim::Cell& cell_;
};

// Applies one record from the gateway to the cell; answers sim records and refused
// commands at once (commands are otherwise answered by the core).
void take_record(const bridge::CommandRecord& rec, sim::Cell& cell, Publisher& pub, std::uint64_t t) noexcept;

class RtLoop {
 public:
  RtLoop(bridge::Segment& seg, sim::Cell& cell, const RtOptions& opt) noexcept;
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
  sim::Cell& cell_;
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
  RtOptions rt{};
  core::Config core{};
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

}  // namespace safestate::runtime

// `safestate rtbench`: how late the real-time loop wakes up, measured on the loop itself.
// The same RtLoop as `safestate run` (clock_nanosleep TIMER_ABSTIME, mlockall, SCHED_FIFO,
// pinning), the same simulated cell, busy with the demo program in AUTO; a main thread in
// the role of the gateway answers the cell with reset / servo_on / start through the
// bridge, as an operator would. Every cycle's lateness goes into a buffer allocated before
// the loop starts; percentiles are computed after it stopped.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "safestate/backends/factory.hpp"
#include "safestate/runtime/runtime.hpp"
#include "safestate/util/percentile.hpp"

namespace safestate::runtime {

namespace {

struct Percentiles {
  std::uint64_t p50 = 0, p99 = 0, p999 = 0, max = 0, n = 0;
};

Percentiles percentiles(std::vector<std::uint32_t> v) {
  Percentiles p;
  std::sort(v.begin(), v.end());
  p.p50 = util::percentile_sorted(v, 0.50);
  p.p99 = util::percentile_sorted(v, 0.99);
  p.p999 = util::percentile_sorted(v, 0.999);
  p.max = util::percentile_sorted(v, 1.0);
  p.n = v.size();
  return p;
}

void command(bridge::Segment& seg, std::uint32_t& seq, core::CommandId id) {
  bridge::CommandRecord r{};
  r.seq = ++seq;
  r.kind = bridge::RecordKind::command;
  r.command.id = static_cast<std::uint8_t>(id);
  r.command.source = static_cast<std::uint8_t>(core::Source::pendant);
  static_cast<void>(seg.commands().push(r));
}

}  // namespace

int rtbench_main(const RtBenchOptions& opt) {
  core::Config cfg{};
  cfg.cycle_us = opt.rt.cycle_us;
  if (const core::ConfigError e = core::validate(cfg); !e.ok()) {
    std::fprintf(stderr, "safestate rtbench: invalid setting %s: %s\n", e.field, e.reason);
    return 2;
  }
  if (opt.seconds < 1U || opt.seconds > 3600U) {
    std::fprintf(stderr, "safestate rtbench: invalid setting seconds: must be 1..3600\n");
    return 2;
  }
  const std::string shm = "/safestate-rtbench-" + std::to_string(getpid());
  std::string error;
  std::unique_ptr<bridge::Segment> seg = bridge::Segment::create(shm, error);
  if (!seg) {
    std::fprintf(stderr, "safestate rtbench: %s\n", error.c_str());
    return 1;
  }
  backends::Choice choice;
  choice.channels = 1;  // the one-channel loop in this process (the pair's own costs: docs/two-channels.md)
  std::unique_ptr<backends::Host> host = backends::make_host(cfg, choice, error);  // the simulated cell
  if (!host) {
    std::fprintf(stderr, "safestate rtbench: %s\n", error.c_str());
    return 1;
  }
  controller::OneChannel one(host->cell());  // the one-channel loop (docs/performance.md)
  RtLoop loop(*seg, one, host->world(), opt.rt);
  const std::size_t cycles = static_cast<std::size_t>(opt.seconds) * 1000000U / opt.rt.cycle_us;
  std::vector<std::uint32_t> log(cycles + 10000U, 0U);  // allocated (and touched) before the loop starts
  loop.log_lateness(log);
  std::atomic<bool> stop{false};
  std::atomic<bool> ready{false};
  std::thread rt_thread([&] {
    loop.setup();
    ready.store(true);
    loop.run(stop, 0);
  });
  while (!ready.load()) {
    usleep(1000);
  }
  std::fputs(loop.setup_report().c_str(), stderr);

  // The operator: keep the program running.
  std::uint32_t seq = 0;
  const bridge::Metrics& m = seg->metrics();
  while (m.cycles.load(std::memory_order_relaxed) < cycles) {
    usleep(50000);
    bridge::Status s{};
    if (!seg->status().read(s)) {
      continue;
    }
    if (s.state == core::State::ESTOP_RESET_NEEDED) {
      command(*seg, seq, core::CommandId::reset);
    } else if (s.state == core::State::IDLE) {
      command(*seg, seq, core::CommandId::servo_on);
    } else if (s.state == core::State::OPERATIONAL && s.sub == core::Sub::AUTO_IDLE) {
      command(*seg, seq, core::CommandId::start);
    }
  }
  stop.store(true);
  rt_thread.join();

  const std::uint64_t done = m.cycles.load();
  log.resize(std::min<std::size_t>(cycles, static_cast<std::size_t>(done)));
  const Percentiles p = percentiles(log);
  const std::uint64_t overruns = m.overruns.load();
  const std::uint64_t exec_max = m.exec_max_ns.load();
  const unsigned prio = m.rt_priority.load();
  if (opt.json) {
    std::printf(
        "{\"cycles\":%llu,\"cycle_us\":%u,\"priority\":%u,\"lateness_ns\":{\"p50\":%llu,\"p99\":%llu,\"p999\":%llu,"
        "\"max\":%llu},\"overruns\":%llu,\"exec_max_ns\":%llu}\n",
        static_cast<unsigned long long>(p.n), opt.rt.cycle_us, prio, static_cast<unsigned long long>(p.p50),
        static_cast<unsigned long long>(p.p99), static_cast<unsigned long long>(p.p999),
        static_cast<unsigned long long>(p.max), static_cast<unsigned long long>(overruns),
        static_cast<unsigned long long>(exec_max));
  } else {
    std::printf("rtbench: %llu cycles of %u us (SCHED_FIFO priority %u)\n", static_cast<unsigned long long>(p.n),
                opt.rt.cycle_us, prio);
    std::printf("wake-up lateness: p50 %.1f us, p99 %.1f us, p99.9 %.1f us, max %.1f us; overruns %llu; "
                "longest cycle %.1f us\n",
                static_cast<double>(p.p50) / 1e3, static_cast<double>(p.p99) / 1e3, static_cast<double>(p.p999) / 1e3,
                static_cast<double>(p.max) / 1e3, static_cast<unsigned long long>(overruns),
                static_cast<double>(exec_max) / 1e3);
  }
  return 0;
}

}  // namespace safestate::runtime

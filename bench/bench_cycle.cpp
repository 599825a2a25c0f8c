// Scan-cycle cost, cycle by cycle: percentiles over 10^6 cycles (not means), for
//   supervisor  signals + state machine + validation + monitors (core::Supervisor)
//   reference   the same cycles on tools/reference (hand-written switch code)
//   full        the whole scan cycle of the simulated cell: signals, supervisor, motion for
//               six axes with forward kinematics of every link origin, CiA 402, plant
// each on a typical shift and on the worst path (see workload.hpp).
//
//   bench_cycle times [--cycles N]            JSON with p50/p99/p99.9/max in ns
//   bench_cycle callgrind WHAT [--cycles N]   run only WHAT (supervisor-typical,
//       reference-typical, supervisor-worst, reference-worst, full-typical, and with a
//       safety configuration supervisor-limits, full-limits) between
//       callgrind's start/stop instrumentation requests, for `valgrind --tool=callgrind
//       --instr-atstart=no`: instructions per cycle = Ir / N.
//   bench_cycle allocs [--cycles N]           heap allocations (operator new) during N full
//       cycles of the shift, after the cell is built
//   bench_cycle slowest [--cycles N]          the slowest 0.1 % of full cycles with their
//       position in the shift (to tell a code path from the machine's interruptions)
#include <valgrind/callgrind.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "../tools/reference/reference.hpp"
#include "safestate/controller/controller.hpp"
#include "safestate/util/percentile.hpp"
#include "workload.hpp"

using namespace safestate;
using bench::Sample;
using bench::Trace;

// Every operator new of the process is counted (the measured loops must not allocate).
static std::size_t g_allocs = 0;
void* operator new(std::size_t n) {
  ++g_allocs;
  void* p = std::malloc(n == 0U ? 1U : n);
  if (p == nullptr) {
    throw std::bad_alloc();
  }
  return p;
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace {

using Clock = std::chrono::steady_clock;

template <typename T>
inline void keep(const T& v) {
  asm volatile("" : : "g"(&v) : "memory");
}

core::Timing timing() { return core::to_timing(core::Config{}); }

// The two supervisors behind one interface (both take the raw inputs through the signal layer).
struct Core {
  core::Supervisor s{timing()};
  core::SupervisorOut out{};
  Core() { s.configure_arm(bench::workload_arm(), bench::kWorkloadTcp); }  // as the cell's
  void step(const Sample& x) {
    s.step(x.raw, x.fb, x.cmds.data(), x.n, out);
    keep(out);
  }
  [[nodiscard]] core::State state() const { return out.state; }
};
// The same supervisor with a safety configuration (bench::cost_limits(): joints, speeds, 16
// zones and a cone), the arm as the cell's controller gives it: every cell's case.
struct CoreLimits {
  core::Supervisor s{timing()};
  core::SupervisorOut out{};
  CoreLimits() {
    s.configure_limits(bench::cost_limits(), controller::Controller::arm_geometry(motion::kRobot), core::Config{}.cycle_us,
                       true);
  }
  void step(const Sample& x) {
    s.step(x.raw, x.fb, x.cmds.data(), x.n, out);
    keep(out);
  }
  [[nodiscard]] core::State state() const { return out.state; }
};
struct Ref {
  core::Timing t = timing();
  core::SignalLayer signals;
  reference::Supervisor s{t};
  reference::Out out{};
  core::Cycle now = 0;
  reference::Geometry geo{};  // the T1 points, recorded with the sample
  void step(const Sample& x) {
    signals.update(x.raw, now++, t);
    geo.arm = true;
    geo.t1_points = x.t1_points;
    s.step(signals.inputs(), x.fb, x.cmds.data(), x.n, out, geo);
    keep(out);
  }
  [[nodiscard]] core::State state() const { return out.state; }
};

struct Stats {
  double p50 = 0, p99 = 0, p999 = 0, max = 0;
  std::size_t n = 0;
};

Stats stats(std::vector<double>& v) {
  Stats s;
  std::sort(v.begin(), v.end());
  s.p50 = safestate::util::percentile_sorted(v, 0.5);
  s.p99 = safestate::util::percentile_sorted(v, 0.99);
  s.p999 = safestate::util::percentile_sorted(v, 0.999);
  s.max = safestate::util::percentile_sorted(v, 1.0);
  s.n = v.size();
  return s;
}

// One sample: the interval minus the clock's own read cost, never below zero.
double elapsed_ns(Clock::time_point a, Clock::time_point b, double overhead) {
  return std::max(0.0, std::chrono::duration<double, std::nano>(b - a).count() - overhead);
}

double timer_overhead() {
  std::vector<double> v(100000);
  for (double& d : v) {
    const auto a = Clock::now();
    const auto b = Clock::now();
    d = elapsed_ns(a, b, 0.0);
  }
  return stats(v).p50;
}

// Replays `trace` from a fresh supervisor `reps` times, timing every cycle.
template <typename S>
std::vector<double> time_trace(const Trace& trace, std::size_t cycles, double overhead) {
  std::vector<double> ns;
  ns.reserve(cycles);
  while (ns.size() < cycles) {
    S s;
    Sample local;
    for (const Sample& x : trace) {
      // The cycle's inputs are copied in first, untimed: in a controller the process image
      // was just written by the fieldbus and is in cache, not streamed from a long recording.
      local = x;
      keep(local);
      const auto a = Clock::now();
      s.step(local);
      const auto b = Clock::now();
      ns.push_back(elapsed_ns(a, b, overhead));
      if (ns.size() == cycles) {
        break;
      }
    }
  }
  return ns;
}

// The supervisor as it was before the last sample of `trace`.
template <typename S>
S before_last(const Trace& trace) {
  S before;
  for (std::size_t i = 0; i + 1 < trace.size(); ++i) {
    before.step(trace[i]);
  }
  return before;
}

// The last sample of `trace`, stepped `cycles` times from a copy of the supervisor as it was before it.
template <typename S>
std::vector<double> time_last(const Trace& trace, std::size_t cycles, double overhead) {
  const S before = before_last<S>(trace);
  const Sample& worst = trace.back();
  std::vector<double> ns(cycles);
  for (double& d : ns) {
    S s = before;
    const auto a = Clock::now();
    s.step(worst);
    const auto b = Clock::now();
    d = elapsed_ns(a, b, overhead);
  }
  return ns;
}

// Checks that a replay decides exactly as the cell's own supervisor did.
template <typename S>
bool replays_faithfully(const Trace& trace) {
  S s;
  for (const Sample& x : trace) {
    s.step(x);
    if (s.state() != core::state_of(x.leaf_after)) {
      return false;
    }
  }
  return true;
}

void print(const char* name, const Stats& s, bool last) {
  std::printf("  \"%s\": {\"n\": %zu, \"p50\": %.1f, \"p99\": %.1f, \"p999\": %.1f, \"max\": %.1f}%s\n", name, s.n, s.p50,
              s.p99, s.p999, s.max, last ? "" : ",");
}

// The full scan cycle on the cell itself: the same shift, every cycle timed.
std::vector<double> time_full_typical(std::size_t cycles, double overhead) {
  sim::Cell cell{core::Config{}};
  bench::Driver d(cell);
  std::vector<double> ns;
  ns.reserve(cycles);
  for (std::size_t k = 0; k < cycles; ++k) {
    bench::shift_pattern(cell, d, k);
    const auto a = Clock::now();
    cell.step();
    const auto b = Clock::now();
    ns.push_back(elapsed_ns(a, b, overhead));
  }
  return ns;
}

// Worst: the cell forked just before the worst cycle, that cycle timed (the fork is not).
std::vector<double> time_full_worst(std::size_t cycles, double overhead) {
  sim::Cell before{core::Config{}};
  bench::Driver d(before);
  for (std::size_t k = 0; k < bench::kWorstPrelude; ++k) {
    bench::worst_prelude(before, d, k);
    before.step();
  }
  std::vector<double> ns(cycles);
  for (double& t : ns) {
    sim::Cell c(before);
    bench::Driver dc(c);
    bench::worst_trigger(c, dc);
    const auto a = Clock::now();
    c.step();
    const auto b = Clock::now();
    t = elapsed_ns(a, b, overhead);
  }
  return ns;
}

int usage() {
  std::fprintf(stderr,
               "usage: bench_cycle times [--cycles N]\n"
               "       bench_cycle callgrind supervisor-typical|reference-typical|supervisor-worst|reference-worst|"
               "full-typical|supervisor-limits|full-limits [--cycles N]\n");
  return 2;
}

template <typename S>
void run_trace(const Trace& t, std::size_t cycles) {
  S s;
  std::size_t done = 0;
  CALLGRIND_START_INSTRUMENTATION;
  while (done < cycles) {
    for (const Sample& x : t) {
      s.step(x);
      if (++done == cycles) {
        break;
      }
    }
  }
  CALLGRIND_STOP_INSTRUMENTATION;
}

template <typename S>
void run_last(const Trace& t, std::size_t cycles) {
  std::vector<S> copies(cycles, before_last<S>(t));  // copied outside the measured region
  CALLGRIND_START_INSTRUMENTATION;
  for (S& s : copies) {
    s.step(t.back());
  }
  CALLGRIND_STOP_INSTRUMENTATION;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    return usage();
  }
  const std::string mode = argv[1];
  std::string what;
  std::size_t cycles = 1000000;
  for (int i = 2; i < argc; ++i) {
    if (std::strcmp(argv[i], "--cycles") == 0 && i + 1 < argc) {
      cycles = std::strtoull(argv[++i], nullptr, 10);
    } else if (what.empty() && argv[i][0] != '-') {
      what = argv[i];
    } else {
      return usage();
    }
  }
  if (cycles == 0U || cycles > 100000000U) {
    std::fprintf(stderr, "bench_cycle: --cycles must be 1..100000000\n");
    return 2;
  }
  // Modes that run the cell itself need no recorded workload.
  if (mode == "callgrind" && (what == "full-typical" || what == "full-limits")) {
    sim::Cell cell{core::Config{}};
    if (what == "full-limits") {
      cell.configure_limits(bench::cost_limits(), true);
    }
    bench::Driver d(cell);
    CALLGRIND_START_INSTRUMENTATION;
    for (std::size_t k = 0; k < cycles; ++k) {
      bench::shift_pattern(cell, d, k);  // a few instructions per cycle, counted too
      cell.step();
    }
    CALLGRIND_STOP_INSTRUMENTATION;
    // A series that ends in a lockout measures a stopped cell, not a shift: refuse it.
    if (cell.out().state == core::State::ERROR_LOCKOUT) {
      std::fprintf(stderr, "bench_cycle: %s ended in ERROR_LOCKOUT\n", what.c_str());
      return 1;
    }
    std::printf("%zu\n", cycles);
    return 0;
  }
  if (mode == "slowest") {  // where in the shift the slowest 0.1 % of full cycles fall
    const std::vector<double> ns = time_full_typical(cycles, 0.0);
    std::vector<std::size_t> order(ns.size());
    for (std::size_t k = 0; k < order.size(); ++k) {
      order[k] = k;
    }
    std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return ns[x] > ns[y]; });
    for (std::size_t i = 0; i < order.size() / 1000U; ++i) {
      std::printf("%.0f %zu %zu\n", ns[order[i]], order[i], order[i] % 300000U);
    }
    return 0;
  }
  if (mode == "allocs") {
    sim::Cell cell{core::Config{}};
    bench::Driver d(cell);
    const std::size_t before = g_allocs;
    for (std::size_t k = 0; k < cycles; ++k) {
      bench::shift_pattern(cell, d, k);
      cell.step();
    }
    std::printf("{\"cycles\": %zu, \"allocations\": %zu}\n", cycles, g_allocs - before);
    return 0;
  }
  // The recorded workloads, only those the mode uses, each checked to replay faithfully.
  const bool all = mode == "times";
  const bool limits = what == "supervisor-limits";
  const Trace shift = (all || what.ends_with("-typical")) ? bench::shift(300000) : Trace{};
  const core::SafetyLimits configured = bench::cost_limits();
  const Trace shift_limits = limits ? bench::shift(300000, &configured) : Trace{};
  const Trace worst = (all || what.ends_with("-worst")) ? bench::worst() : Trace{};
  if (!replays_faithfully<Core>(shift) || !replays_faithfully<Ref>(shift) || !replays_faithfully<Core>(worst) ||
      !replays_faithfully<Ref>(worst) || !replays_faithfully<CoreLimits>(shift_limits)) {
    std::fprintf(stderr, "bench_cycle: a replay does not decide as the cell did: the workload is not what it claims\n");
    return 1;
  }
  if (mode == "callgrind") {
    if (what == "supervisor-typical") {
      run_trace<Core>(shift, cycles);
    } else if (limits) {
      run_trace<CoreLimits>(shift_limits, cycles);
    } else if (what == "reference-typical") {
      run_trace<Ref>(shift, cycles);
    } else if (what == "supervisor-worst") {
      run_last<Core>(worst, cycles);
    } else if (what == "reference-worst") {
      run_last<Ref>(worst, cycles);
    } else {
      return usage();
    }
    std::printf("%zu\n", cycles);
    return 0;
  }
  if (mode != "times") {
    return usage();
  }
  const double overhead = timer_overhead();
  std::vector<double> v;
  std::printf("{\n  \"cycles\": %zu,\n  \"timer_overhead_ns\": %.1f,\n", cycles, overhead);
  v = time_trace<Core>(shift, cycles, overhead);
  print("supervisor_typical", stats(v), false);
  v = time_trace<Ref>(shift, cycles, overhead);
  print("reference_typical", stats(v), false);
  v = time_last<Core>(worst, cycles, overhead);
  print("supervisor_worst", stats(v), false);
  v = time_last<Ref>(worst, cycles, overhead);
  print("reference_worst", stats(v), false);
  v = time_full_typical(cycles, overhead);
  print("full_typical", stats(v), false);
  v = time_full_worst(cycles, overhead);
  print("full_worst", stats(v), true);
  std::printf("}\n");
  return 0;
}

// SPEC §14, issue 36 item 7: real-time faults of one channel's process, measured from outside
// the process as `safestate run` meets them: the two channel programs (safestate-channel, GCC;
// safestate-channel-clang, Clang) started by pair::ChannelPair on the simulated world, the host
// stepping them on a 1 ms clock (absolute sleeps, as the real-time loop), the robot powered
// (OPERATIONAL), then at a random phase of a cycle one of:
//   - SIGSTOP of channel A or B (a hung processor), SIGKILL of A or B (a crashed one);
//   - a cycle overrun of channel A: SIGSTOP, then SIGCONT after D microseconds (a channel whose
//     cycle took D longer than it should: an interrupt storm, a page fault, a cache miss run).
// Per trial: whether the other channel named CHANNEL_LOST, the host cycles from the fault to the
// other channel's contactor bit open (the power path open: K1 and K2 are in series), and the
// same in microseconds from the signal. Before them, the cost (issue 36 item 9): each channel's
// own step (its cross-check included) over a steady run of the AUTO program, p50 / p99.9 / max,
// the host's cycle (publish, wait for both, combine), and the cross-check alone (a digest made
// and compared against its twin, in a loop). One JSON object on stdout (bench/pair_faults.py
// turns it into docs/performance.md's section).
//
// Usage: bench_pair CHANNEL_A CHANNEL_B [TRIALS_PER_KIND] [SEED]
#include <sched.h>
#include <signal.h>
#include <time.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "safestate/controller/cross_check.hpp"
#include "safestate/pair/host.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/safety/safety_config.hpp"
#include "safestate/sim/cell.hpp"
#include "safestate/util/percentile.hpp"

namespace {

using namespace safestate;
using Clock = std::chrono::steady_clock;

struct Kind {
  const char* name;
  std::size_t victim;  // 0 A, 1 B
  int sig;             // SIGSTOP or SIGKILL
  std::uint32_t resume_us;  // SIGSTOP only: SIGCONT after this long (0: never, a hang)
};

struct Trial {
  bool started = false;
  bool lost = false;          // the other channel named CHANNEL_LOST
  bool opened = false;        // the other channel's contactor bit open within the trial
  std::uint64_t cycles = 0;   // host cycles from the fault to that
  double us = 0.0;            // microseconds from the signal to the host's step that saw it
};

// As `safestate run` runs them: the host's loop SCHED_FIFO, the channels one above it (where
// the process may; without it the figures are a loaded host's, and the bench says so).
constexpr int kHostPriority = 80;
constexpr int kChannelPriority = 81;

// A 1 ms host clock with absolute sleeps.
struct Pace {
  timespec next{};
  Pace() { clock_gettime(CLOCK_MONOTONIC, &next); }
  void wait() {
    next.tv_nsec += 1000000;
    if (next.tv_nsec >= 1000000000) {
      next.tv_nsec -= 1000000000;
      ++next.tv_sec;
    }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
  }
};

// The two channel programs on the simulated world, as `safestate run` starts them (A on CPU 0,
// B on CPU 1, SCHED_FIFO above the host), stepped on the 1 ms clock.
struct Rig {
  core::Config cfg{};
  sim::Cell world{cfg, nullptr, 2};
  pair::ChannelPair pair{cfg, world.world_port()};
  Pace pace;
  std::uint32_t seq = 0;

  bool start(const std::string& exe_a, const std::string& exe_b, const std::string& tag) {
    pair::PairOptions po;
    po.exe_a = exe_a;
    po.exe_b = exe_b;
    po.shm_base = "/safestate-bench-pair-" + std::to_string(getpid()) + "-" + tag;
    po.cpu_a = 0;
    po.cpu_b = (std::thread::hardware_concurrency() > 1U) ? 1 : 0;
    po.priority = kChannelPriority;
    std::string err;
    if (!pair.start(po, robot::active().model, safety::default_safety().limits, true, core::BrakeTestHistory{},
                    err)) {
      std::fprintf(stderr, "bench_pair: %s\n", err.c_str());
      return false;
    }
    pace = Pace{};
    cycles(300);  // BOOT
    return true;
  }
  void step() {
    pace.wait();
    pair.step();
  }
  void cycles(int n) {
    for (int i = 0; i < n; ++i) step();
  }
  void command(core::CommandId id) {
    core::Command c{};
    c.source = static_cast<std::uint8_t>(core::Source::pendant);
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    static_cast<void>(pair.submit(c));
  }
  // What the pair is in when a run did not get where it should.
  void say_where(const char* what) {
    std::fprintf(stderr, "bench_pair: %s (state %s, alarms %llx)\n", what, core::to_string(pair.out().state),
                 static_cast<unsigned long long>(pair.alarms().mask()));
  }
};

// The cross-check alone: this channel's digest made and sent, the partner's (its twin, over a
// loopback) received and compared, `n` times; nanoseconds per cycle.
class Loopback final : public controller::Link {
 public:
  void send(const controller::Digest& d) noexcept override {
    d_ = d;
    full_ = true;
  }
  bool receive(controller::Digest& d) noexcept override {
    if (!full_) return false;
    d = d_;
    full_ = false;
    return true;
  }

 private:
  controller::Digest d_{};
  bool full_ = false;
};

double crosscheck_ns(int n) {
  core::SupervisorOut o{};
  o.state = core::State::OPERATIONAL;
  o.contactor = true;
  Loopback link;
  controller::CrossCheck cc(2);
  std::uint32_t bad = 0;
  const Clock::time_point t0 = Clock::now();
  for (int i = 0; i < n; ++i) {
    const auto c = static_cast<std::uint32_t>(i);
    bad += cc.step(controller::make_digest(c, c, o), link).mismatch ? 1U : 0U;
  }
  const double ns = std::chrono::duration<double, std::nano>(Clock::now() - t0).count() / n;
  return bad == 0U ? ns : -1.0;  // a healthy twin never mismatches
}

struct Steady {
  std::vector<double> a_us, b_us, host_us;
};

// The pair running the demo program in AUTO for `cycles` cycles on the 1 ms clock.
bool steady(const std::string& exe_a, const std::string& exe_b, int cycles, Steady& s) {
  Rig r;
  if (!r.start(exe_a, exe_b, "steady")) return false;
  for (const core::CommandId id : {core::CommandId::reset, core::CommandId::servo_on, core::CommandId::start}) {
    r.command(id);
    r.cycles(1500);
  }
  const bool running = r.pair.out().sub == core::Sub::AUTO_RUNNING;
  for (int i = 0; running && i < cycles; ++i) {
    r.pace.wait();
    const Clock::time_point t0 = Clock::now();
    r.pair.step();
    s.host_us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
    s.a_us.push_back(static_cast<double>(r.pair.report(0).exec_ns) * 1e-3);
    s.b_us.push_back(static_cast<double>(r.pair.report(1).exec_ns) * 1e-3);
  }
  if (!running) r.say_where("the steady run did not reach AUTO_RUNNING");
  r.pair.stop();
  return running;
}

void print_dist(const char* name, const std::vector<double>& v) {
  std::printf("\"%s\":{\"p50\":%.1f,\"p99\":%.1f,\"p999\":%.1f,\"max\":%.1f}", name, util::percentile(v, 0.5),
              util::percentile(v, 0.99), util::percentile(v, 0.999), util::percentile(v, 1.0));
}

Trial run_trial(const Kind& k, const std::string& exe_a, const std::string& exe_b, std::mt19937& rng, int n) {
  Trial t;
  Rig r;
  if (!r.start(exe_a, exe_b, std::to_string(n))) return t;
  pair::ChannelPair& p = r.pair;
  r.command(core::CommandId::reset);
  r.cycles(20);
  r.command(core::CommandId::servo_on);
  for (int i = 0; i < 3000 && p.out().state != core::State::OPERATIONAL; ++i) r.step();
  const std::size_t other = 1U - k.victim;
  if (p.out().state != core::State::OPERATIONAL || !p.report(other).out.contactor) {
    r.say_where(("trial " + std::to_string(n) + " did not reach OPERATIONAL").c_str());
    p.stop();
    return t;
  }
  t.started = true;
  // A random phase within the next cycle.
  r.step();
  std::this_thread::sleep_for(std::chrono::microseconds(std::uniform_int_distribution<int>(0, 900)(rng)));
  const auto pid = static_cast<pid_t>(p.info(k.victim).pid);
  const std::uint64_t from = p.now();
  const Clock::time_point t0 = Clock::now();
  kill(pid, k.sig);
  std::thread resume;
  if (k.sig == SIGSTOP && k.resume_us > 0U) {
    resume = std::thread([pid, us = k.resume_us] {
      std::this_thread::sleep_for(std::chrono::microseconds(us));
      kill(pid, SIGCONT);
    });
  }
  for (int i = 0; i < 60; ++i) {
    r.step();
    if (!t.opened && !p.report(other).out.contactor) {
      t.opened = true;
      t.cycles = p.now() - from;
      t.us = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    }
  }
  t.lost = p.report(other).alarms.active(core::AlarmId::CHANNEL_LOST);
  if (resume.joinable()) {
    resume.join();
  } else if (k.sig == SIGSTOP) {
    kill(pid, SIGCONT);
  }
  p.stop();
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_pair CHANNEL_A CHANNEL_B [TRIALS_PER_KIND] [SEED]\n");
    return 2;
  }
  const int trials = (argc > 3) ? std::atoi(argv[3]) : 20;
  const unsigned seed = (argc > 4) ? static_cast<unsigned>(std::atoi(argv[4])) : 1U;
  if (trials < 1 || trials > 1000) {
    std::fprintf(stderr, "bench_pair: TRIALS_PER_KIND must be 1..1000\n");
    return 2;
  }
  std::mt19937 rng(seed);
  sched_param sp{};
  sp.sched_priority = kHostPriority;
  const bool rt = sched_setscheduler(0, SCHED_FIFO, &sp) == 0;
  if (!rt) std::fprintf(stderr, "bench_pair: no SCHED_FIFO for the host loop (not root?): figures of a loaded host\n");
  const Kind kinds[] = {
      {"A stopped (SIGSTOP)", 0, SIGSTOP, 0},       {"B stopped (SIGSTOP)", 1, SIGSTOP, 0},
      {"A killed (SIGKILL)", 0, SIGKILL, 0},        {"B killed (SIGKILL)", 1, SIGKILL, 0},
      {"A overrun 0.5 ms", 0, SIGSTOP, 500},        {"A overrun 1 ms", 0, SIGSTOP, 1000},
      {"A overrun 1.5 ms", 0, SIGSTOP, 1500},       {"A overrun 2 ms", 0, SIGSTOP, 2000},
      {"A overrun 3 ms", 0, SIGSTOP, 3000},         {"A overrun 5 ms", 0, SIGSTOP, 5000},
  };
  core::Config cfg{};
  std::printf("{\"cycle_us\":%u,\"cross_check_cycles\":%u,\"trials_per_kind\":%d,\"seed\":%u,\"realtime\":%s,",
              cfg.cycle_us, cfg.cross_check_cycles, trials, seed, rt ? "true" : "false");
  Steady s;
  const int steady_cycles = 20000;
  if (steady(argv[1], argv[2], steady_cycles, s)) {
    std::printf("\"steady\":{\"cycles\":%d,", steady_cycles);
    print_dist("a_us", s.a_us);
    std::printf(",");
    print_dist("b_us", s.b_us);
    std::printf(",");
    print_dist("host_us", s.host_us);
    std::printf("},");
  }
  std::printf("\"crosscheck_ns\":%.1f,\"kinds\":[", crosscheck_ns(1000000));
  int n = 0;
  bool first = true;
  for (const Kind& k : kinds) {
    std::vector<double> cycles;
    std::vector<double> us;
    int started = 0;
    int lost = 0;
    int opened = 0;
    for (int i = 0; i < trials; ++i) {
      const Trial t = run_trial(k, argv[1], argv[2], rng, n++);
      if (!t.started) continue;
      ++started;
      lost += t.lost ? 1 : 0;
      if (t.opened) {
        ++opened;
        cycles.push_back(static_cast<double>(t.cycles));
        us.push_back(t.us);
      }
    }
    std::printf("%s{\"kind\":\"%s\",\"victim\":\"%c\",\"signal\":\"%s\",\"resume_us\":%u,\"trials\":%d,"
                "\"lost\":%d,\"opened\":%d,\"cycles_p50\":%.0f,\"cycles_max\":%.0f,\"us_p50\":%.0f,\"us_max\":%.0f}",
                first ? "" : ",", k.name, k.victim == 0U ? 'A' : 'B', k.sig == SIGKILL ? "SIGKILL" : "SIGSTOP",
                k.resume_us, started, lost, opened, util::percentile(cycles, 0.5), util::percentile(cycles, 1.0),
                util::percentile(us, 0.5), util::percentile(us, 1.0));
    std::fflush(stdout);
    first = false;
  }
  std::printf("]}\n");
  return 0;
}

// `safestate ecat-bench`: the EtherCAT cycle alone (no core, no gateway): one exchange per
// period on an absolute deadline, outputs all zero (the safe state), and the round trip
// of each exchange. Used by bench/run.py on a veth pair against `safestate ecat-sim`.
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>

#include <cerrno>
#include <cstring>

#include <algorithm>
#include <cstdio>
#include <vector>

#include "safestate/hal/ethercat.hpp"
#include "safestate/runtime/runtime.hpp"
#include "safestate/util/percentile.hpp"

namespace safestate::runtime {

namespace {
std::uint64_t mono_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
}
double pct(const std::vector<std::uint64_t>& sorted, double p) {
  return static_cast<double>(util::percentile_sorted(sorted, p)) / 1000.0;
}
}  // namespace

int ecat_bench_main(const EcatBenchOptions& opt) {
  hal::ethercat::BusConfig bc;
  std::string err;
  const bool ok = opt.bus_config.empty() ? hal::ethercat::parse_bus_config(hal::ethercat::default_bus_config(), bc, err)
                                         : hal::ethercat::load_bus_config(opt.bus_config, bc, err);
  if (!ok) {
    std::fprintf(stderr, "ecat-bench: bus configuration: %s\n", err.c_str());
    return 2;
  }
  // As `safestate run`'s real-time loop (RtOptions' default priority 80): locked memory and
  // SCHED_FIFO when permitted, else said, since the figures then show ordinary scheduling.
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    std::fprintf(stderr, "ecat-bench: warning: mlockall failed (%s), memory may page\n", std::strerror(errno));
  }
  sched_param sp{};
  sp.sched_priority = RtOptions{}.priority;
  if (const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp); rc != 0) {
    std::fprintf(stderr, "ecat-bench: warning: SCHED_FIFO not permitted (%s), measuring with normal scheduling\n",
                 std::strerror(rc));
  }
  // The round trip is measured whole: each exchange waits up to the frame timeout.
  hal::ethercat::Backend bus(bc, opt.ifname, opt.cycle_us, 0);
  if (!bus.booted()) {
    std::fprintf(stderr, "ecat-bench: %s\n", bus.boot_error().c_str());
    return 1;
  }
  std::vector<std::uint64_t> rtt(opt.cycles);
  hal::ProcessImageIn in{};
  const hal::ProcessImageOut out{};
  std::uint64_t next = mono_ns();
  for (std::uint32_t k = 0; k < opt.cycles; ++k) {
    next += static_cast<std::uint64_t>(opt.cycle_us) * 1000U;
    const timespec ts{static_cast<time_t>(next / 1000000000ULL), static_cast<long>(next % 1000000000ULL)};
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    const std::uint64_t t0 = mono_ns();
    bus.read(in);
    rtt[k] = mono_ns() - t0;
    bus.write(out);
  }
  // The exchanges that `safestate run` would have left stale (longer than its budget), and
  // the longest run of them in a row (stale_cycles of them is FIELDBUS_LOST).
  const std::uint64_t budget_ns = std::uint64_t{hal::ethercat::exchange_budget_us(opt.cycle_us)} * 1000U;
  std::uint32_t over = 0;
  std::uint32_t row = 0;
  std::uint32_t longest = 0;
  for (const std::uint64_t r : rtt) {
    row = r > budget_ns ? row + 1U : 0U;
    over += r > budget_ns ? 1U : 0U;
    longest = std::max(longest, row);
  }
  std::sort(rtt.begin(), rtt.end());
  const char* fmt = opt.json ? "{\"cycles\":%u,\"cycle_us\":%u,\"p50_us\":%.1f,\"p99_us\":%.1f,\"p999_us\":%.1f,"
                               "\"max_us\":%.1f,\"budget_us\":%u,\"over_budget\":%u,\"over_budget_in_row\":%u,\"bus_lost\":%s}\n"
                             : "cycles %u at %u us: round trip p50 %.1f us, p99 %.1f us, p99.9 %.1f us, max %.1f us; "
                               "over the %u us budget: %u (at most %u in a row); bus lost: %s\n";
  std::printf(fmt, opt.cycles, opt.cycle_us, pct(rtt, 0.50), pct(rtt, 0.99), pct(rtt, 0.999), pct(rtt, 1.0),
              hal::ethercat::exchange_budget_us(opt.cycle_us), over, longest, bus.health().ok ? "false" : "true");
  if (!bus.health().ok) {
    std::fprintf(stderr, "ecat-bench: the bus was lost: subdevice %u: %s\n", static_cast<unsigned>(bus.health().subdevice),
                 bus.health().why);
  }
  return bus.health().ok ? 0 : 1;
}

}  // namespace safestate::runtime

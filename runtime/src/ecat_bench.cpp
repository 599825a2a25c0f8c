// `safestate ecat-bench`: the EtherCAT cycle alone (no core, no gateway): one exchange per
// period on an absolute deadline, outputs all zero (the safe state), and the round trip
// of each exchange. Used by bench/run.py on a veth pair against `safestate ecat-sim`.
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <vector>

#include "safestate/hal/ethercat.hpp"
#include "safestate/runtime/runtime.hpp"

namespace safestate::runtime {

namespace {
std::uint64_t mono_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
}
double pct(const std::vector<std::uint64_t>& sorted, double p) {
  if (sorted.empty()) {
    return 0.0;
  }
  const auto i = static_cast<std::size_t>(p * static_cast<double>(sorted.size() - 1U));
  return static_cast<double>(sorted[i]) / 1000.0;
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
  hal::ethercat::Backend bus(bc, opt.ifname, opt.cycles);
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
  std::sort(rtt.begin(), rtt.end());
  const char* fmt = opt.json ? "{\"cycles\":%u,\"cycle_us\":%u,\"p50_us\":%.1f,\"p99_us\":%.1f,\"max_us\":%.1f,\"bus_lost\":%s}\n"
                             : "cycles %u at %u us: round trip p50 %.1f us, p99 %.1f us, max %.1f us; bus lost: %s\n";
  std::printf(fmt, opt.cycles, opt.cycle_us, pct(rtt, 0.50), pct(rtt, 0.99), pct(rtt, 1.0),
              bus.health().ok ? "false" : "true");
  return bus.health().ok ? 0 : 1;
}

}  // namespace safestate::runtime

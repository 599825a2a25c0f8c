// SPEC §3: standstill is every axis below standstill_rad_s for standstill_cycles in a row
// (a NaN velocity is not standstill); also which axis turns fastest (the stop-time
// monitor names it).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req ST-STANDSTILL
void StandstillMonitor::check(const CycleView& v, Reporter& r) noexcept {
  CycleFacts& f = r.facts();
  bool still = true;
  float fastest = 0.0F;
  f.fastest_moving_axis = 0U;
  for (std::size_t i = 0; i < kAxes; ++i) {
    const float w = v.fb.drive[i].velocity_rad_s;
    const float aw = (w < 0.0F) ? -w : w;
    if (!(aw < v.timing.standstill_rad_s)) {  // NaN is not standstill
      still = false;
    }
    if (aw > fastest) {
      fastest = aw;
      f.fastest_moving_axis = static_cast<std::uint8_t>(i + 1U);
    }
  }
  const Cycle n = v.timing.standstill_cycles;
  count_ = still ? ((count_ < n) ? count_ + 1U : count_) : 0U;
  f.at_standstill = count_ >= n;
}

}  // namespace safestate::core

// SPEC §2: the reset button held longer than the hold limit is not a reset
// (RESET_BUTTON_STUCK while it is held; ISO 13849-1 5.2.2, a stuck button must not reset).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

void ResetButtonMonitor::check(const CycleView& v, Reporter& r) noexcept {
  r.hold(AlarmId::RESET_BUTTON_STUCK, v.in.reset_stuck, detail_of(Signal::reset_button));
}

}  // namespace safestate::core

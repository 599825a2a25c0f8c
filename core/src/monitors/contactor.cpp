// SPEC §7, ISO 13849-1 external device monitoring: the main contactor's auxiliary contact
// must follow what this core commanded in the previous cycle. Commanded open but still
// closed after contactor_timeout: power cannot be removed by this path (CONTACTOR_WELDED,
// lockout). Closing late is arming's timeout, not this monitor's.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req AL-FEEDBACK
void ContactorMonitor::check(const CycleView& v, Reporter& r) noexcept {
  const bool welded_now = !v.last.contactor && v.fb.contactor_closed;
  welded_ = welded_now ? welded_ + 1U : 0U;
  if (welded_ > v.timing.contactor_timeout) {
    r.trip(AlarmId::CONTACTOR_WELDED, detail_of(Signal::contactor));
  }
}

}  // namespace safestate::core

// SPEC §4 rule 1: an integrity check failed, the platform's (HAL: the running image's
// code and constant tables, RAM test patterns) or the supervisor's own (its outputs read a
// second time against its state, an impossible state entered): INTEGRITY_FAULT, lockout.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

void IntegrityMonitor::check(const CycleView& v, Reporter& r) noexcept {
  if (!v.fb.integrity_ok || v.integrity_fault) {
    r.trip(AlarmId::INTEGRITY_FAULT, detail_of(Signal::internal));
  }
}

}  // namespace safestate::core

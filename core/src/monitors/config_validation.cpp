// SPEC §10: the active safety configuration's checksum not confirmed by an operator
// (CONFIG_NOT_VALIDATED while so: AUTO and T2 are refused by servo_on's guard).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req LIM-VALIDATION
void ConfigValidationMonitor::check(const CycleView& v, Reporter& r) noexcept {
  r.hold(AlarmId::CONFIG_NOT_VALIDATED, !v.config_validated, detail_of(Signal::internal));
}

}  // namespace safestate::core

// SPEC §2, §4 rules 1 and 2: the E-stop's two channels disagreeing for longer than the
// discrepancy time lock out (ESTOP_DISCREPANCY, naming the channel at fault); pressed is
// rule 2 (ESTOP_PRESSED, active while pressed, naming the channel that opened first).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

void EstopMonitor::check(const CycleView& v, Reporter& r) noexcept {
  if (v.in.estop_discrepancy) {
    r.trip(AlarmId::ESTOP_DISCREPANCY, detail_of(Signal::estop, v.in.estop_fault_channel));
  }
  const AlarmDetail pressed = detail_of(Signal::estop, v.in.estop_cause);
  r.hold(AlarmId::ESTOP_PRESSED, v.in.estop_pressed, pressed);
  if (v.in.estop_pressed) {
    r.trip(AlarmId::ESTOP_PRESSED, pressed);
  }
}

}  // namespace safestate::core

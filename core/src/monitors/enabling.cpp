// SPEC §2, §4 rules 1 and 5: the enabling device's two centre contacts disagreeing lock
// out (ENABLE_DISCREPANCY). Squeezed to panic raises ENABLING_PANIC on the edge, in every
// state. In T1/T2 the device leaving the centre stops the robot (rule 5): at the panic
// position with ENABLING_PANIC, released without an alarm (the normal way to stop).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

void EnablingMonitor::check(const CycleView& v, Reporter& r) noexcept {
  if (v.in.enable_discrepancy) {
    r.trip(AlarmId::ENABLE_DISCREPANCY, detail_of(Signal::enable, v.in.enable_fault_channel));
  }
  const AlarmDetail panic = detail_of(Signal::enable, Channel::panic);
  if (v.in.enable_panic_edge) {
    r.raise(AlarmId::ENABLING_PANIC, panic);
  }
  const bool manual = (v.in.mode == Mode::T1) || (v.in.mode == Mode::T2);
  if (manual && !v.in.enable_ok) {
    if (v.in.enable == EnablePos::panic) {
      r.trip(AlarmId::ENABLING_PANIC, panic);
    } else {
      r.trip_event(Trigger::enable_left_centre, detail_of(Signal::enable, v.in.enable_cause));
    }
  }
}

}  // namespace safestate::core

// SPEC §2, §4 rules 1 and 4: the guard (or light curtain) channels disagreeing lock out
// (GATE_DISCREPANCY); the guard open while the mode is AUTO stops the robot
// (PROTECTIVE_STOP, Cat 1 with power, Cat 0 while arming), and its cause stays present,
// refusing a reset, as long as the guard is open in AUTO (ISO 13849-1 5.2.2).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

void GateMonitor::check(const CycleView& v, Reporter& r) noexcept {
  if (v.in.gate_discrepancy) {
    r.trip(AlarmId::GATE_DISCREPANCY, detail_of(Signal::gate, v.in.gate_fault_channel));
  }
  if (v.in.gate_open && (v.in.mode == Mode::AUTO)) {
    r.trip(AlarmId::PROTECTIVE_STOP, detail_of(Signal::gate, v.in.gate_cause));
    r.present(AlarmId::PROTECTIVE_STOP);
  }
}

}  // namespace safestate::core

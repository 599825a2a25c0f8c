// SPEC §4 rule 3, IEC 61800-5-2 SS1-t: a controlled stop (Cat 1 or 2) must reach
// standstill within max_stop; past it power is cut (STOP_TIME_EXCEEDED, naming the axis
// turning fastest). The cause stays present until the arm is at standstill.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req ST-STOP-TIME
void StopTimeMonitor::check(const CycleView& v, Reporter& r) noexcept {
  const auto* s = std::get_if<StStopping>(&v.state);
  if ((s != nullptr) && !s->braking && (s->elapsed > v.timing.max_stop)) {
    r.trip(AlarmId::STOP_TIME_EXCEEDED, detail_of(Signal::drive, Channel::none, v.facts.fastest_moving_axis));
  }
  if (!v.facts.at_standstill) {
    r.present(AlarmId::STOP_TIME_EXCEEDED);
  }
}

}  // namespace safestate::core

// SPEC §2, §4 rule 6: the mode selector with no single position (MODE_SELECTOR_INVALID,
// while it lasts) and a mode change (MODE_CHANGED: with power it stops the robot).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

void ModeMonitor::check(const CycleView& v, Reporter& r) noexcept {
  r.hold(AlarmId::MODE_SELECTOR_INVALID, v.in.mode_invalid, detail_of(Signal::mode));
  if (v.in.mode_changed) {
    r.trip(AlarmId::MODE_CHANGED, detail_of(Signal::mode, Channel::none, 0U, static_cast<std::uint16_t>(v.in.mode)));
  }
}

}  // namespace safestate::core

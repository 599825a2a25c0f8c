// SPEC §4 rule 7: while jogging, a keep-alive `jog` must come within jog_timeout, else the
// jog stops (Cat 2) with JOG_LINK_LOST: a pendant whose link drops cannot leave an axis
// moving.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

void JogLinkMonitor::check(const CycleView& v, Reporter& r) noexcept {
  if ((v.now - v.last_jog) > v.timing.jog_timeout) {
    r.trip(AlarmId::JOG_LINK_LOST, detail_of(Signal::command));
  }
}

}  // namespace safestate::core

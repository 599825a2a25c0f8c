// Issue 37, the black channel (docs/black-channel.md): the safety data of this channel's
// connections travel in containers the channel checks itself (controller/safety_links.hpp);
// a container that fails its check (CRC, sequence, identity, watchdog) leaves the connection
// failed, its data the safe values. SAFETY_LINK_FAULT names the connection and the error:
// rule 1, lockout (the channel has opened its own contactor in that cycle already).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req LINK-FAULT
void SafetyLinkMonitor::check(const CycleView& v, Reporter& r) noexcept {
  const LinkCheck& l = v.fb.link;
  if (!l.configured || !l.fault) {
    return;
  }
  r.trip(AlarmId::SAFETY_LINK_FAULT,
         detail_of(Signal::safety_link, l.channel, static_cast<std::uint8_t>(l.error), l.connection));
}

}  // namespace safestate::core

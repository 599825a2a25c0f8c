// SPEC §14 cross-comparison: this channel's verdict on the other (controller::CrossCheck,
// Feedback::cross). A difference that lasted longer than cross_check_cycles is
// CHANNEL_MISMATCH naming the first field of the digest that differed; a partner whose
// digest has not arrived intact and in sequence for cross_check_cycles is CHANNEL_LOST naming
// it. Both rule 1: lockout, this channel's own contactor open in the cycle it decides (the
// controller opens it at once; this monitor names the alarm the cycle after).
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req CH-MISMATCH CH-LOST
void ChannelMonitor::check(const CycleView& v, Reporter& r) noexcept {
  const ChannelCheck& c = v.fb.cross;
  if (c.partner == Channel::none) {
    return;  // one channel: nothing to compare with
  }
  if (c.mismatch) {
    r.trip(AlarmId::CHANNEL_MISMATCH,
           detail_of(Signal::channel, Channel::none, 0U, static_cast<std::uint16_t>(c.field)));
  }
  if (c.lost) {
    r.trip(AlarmId::CHANNEL_LOST, detail_of(Signal::channel, c.partner));
  }
}

}  // namespace safestate::core

// SPEC §7, ISO 13849-1 external device monitoring: the main contactor's auxiliary contact
// must follow what this core commanded in the previous cycle. Commanded open but still
// closed after contactor_timeout: power cannot be removed by this path (CONTACTOR_WELDED,
// lockout). Closing late is arming's timeout, not this monitor's.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req AL-FEEDBACK CH-CONTACTORS
void ContactorMonitor::check(const CycleView& v, Reporter& r) noexcept {
  const bool two = v.fb.two_contactors;
  const bool welded_now = !v.last.contactor && v.fb.contactor_closed;
  welded_ = welded_now ? welded_ + 1U : 0U;
  // SPEC §14: each channel reads both auxiliary contacts; both contactors follow the same
  // command (either channel's, compared every cycle), so each checks both against its own.
  const bool k2_welded_now = two && !v.last.contactor && v.fb.k2_closed;
  welded_k2_ = k2_welded_now ? welded_k2_ + 1U : 0U;
  // With two channels K1 is channel A's contactor, named so even where the field has only it
  // (a segment whose DO terminal carries no K2).
  const bool paired = two || (v.fb.cross.partner != Channel::none);
  if (welded_ > v.timing.contactor_timeout) {
    r.trip(AlarmId::CONTACTOR_WELDED, detail_of(Signal::contactor, paired ? Channel::a : Channel::none));
  }
  if (welded_k2_ > v.timing.contactor_timeout) {
    r.trip(AlarmId::CONTACTOR_WELDED, detail_of(Signal::contactor, Channel::b));
  }
}

}  // namespace safestate::core

#include "safestate/controller/channels.hpp"

namespace safestate::controller {

// @req CH-PAIR
bool together(const ChannelResult& a, const ChannelResult& b, core::SupervisorOut& out, core::AlarmSet& alarms,
              core::Leaf& leaf) noexcept {
  const bool a_locked = a.leaf == core::Leaf::ERROR_LOCKOUT;
  const bool b_locked = b.leaf == core::Leaf::ERROR_LOCKOUT;
  const bool lead_b = (b_locked && !a_locked) || (!b_locked && !a_locked && !b.out->contactor && a.out->contactor);
  const ChannelResult& lead = lead_b ? b : a;
  const ChannelResult& other = lead_b ? a : b;
  out = *lead.out;
  out.alarms = a.out->alarms | b.out->alarms;
  out.contactor = a.out->contactor && b.out->contactor;  // both closed (`contactor=` reads both)
  out.brakes_release = a.out->brakes_release && b.out->brakes_release;
  alarms = *lead.alarms;
  for (std::size_t i = 0; i < core::kAlarmCount; ++i) {
    const auto id = static_cast<core::AlarmId>(i);
    if (other.alarms->active(id) && !alarms.active(id)) {
      alarms.raise(id, other.alarms->detail(id), other.alarms->since(id));
    }
  }
  leaf = (a_locked || b_locked) ? core::Leaf::ERROR_LOCKOUT : lead.leaf;
  return lead_b;
}

hal::ProcessImageOut combine_outputs(const hal::ProcessImageOut& a, const hal::ProcessImageOut& b) noexcept {
  hal::ProcessImageOut o = a;
  o.contactor = a.contactor;
  o.contactor_k2 = b.contactor;
  o.brakes_release = a.brakes_release && b.brakes_release;
  o.reduced_active = a.reduced_active || b.reduced_active;
  // Issue 37: each black-channel connection's container from the channel hosting it (the
  // other writes none: len 0); a channel whose outputs dropped sends none.
  for (std::size_t i = 0; i < hal::kMaxLinks; ++i) {
    o.link_tx[i] = (a.link_tx[i].len != 0U) ? a.link_tx[i] : b.link_tx[i];
  }
  return o;
}

}  // namespace safestate::controller

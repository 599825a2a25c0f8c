// SPEC §10 reduced mode: active while the TCP is in a reduced zone, the reduced input asks
// for it (either channel: reduced is the safe side) or the outer protective field is
// interrupted (SPEC §11). The TCP must be at the reduced limit within reduced.ramp_ms of it
// becoming active; the monitor applies the reduced limit from then on.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req LIM-REDUCED
void ReducedMode::update(std::uint8_t sources, Cycle ramp, float limit) noexcept {
  const bool was = sources_ != 0U;
  const bool lower = was && (limit < limit_);
  sources_ = sources;
  ramp_ = ramp;
  limit_ = limit;
  if ((sources_ == 0U) || !was || lower) {
    // inactive, became active in this cycle, or a source that reduces further joined
    // (SPEC §11's outer field): the ramp to the new limit starts now
    elapsed_ = 0;
  } else if (elapsed_ <= ramp_) {
    ++elapsed_;
  }
}

// @req LIM-REDUCED COL-FIELD-REDUCED
void ReducedMode::check(const CycleView& v, Reporter& rep) noexcept {
  LimitReport& r = rep.facts().limits;
  const auto asking = static_cast<std::uint8_t>((r.in_reduced_zone ? kReducedByZone : 0U) |
                                                 (v.in.reduced_requested ? kReducedByInput : 0U) |
                                                 (v.facts.fields.outer_reduces ? kReducedByField : 0U));
  r.reduced_limit_mm_s = reduced_limit_mm_s(*v.limits, asking);
  update(asking, ramp_, r.reduced_limit_mm_s);
  r.reduced_enforced = enforced();
  rep.hold(AlarmId::REDUCED_SPEED, active(), detail_of(Signal::reduced, Channel::none, r.reduced_zone, sources_));
}

}  // namespace safestate::core

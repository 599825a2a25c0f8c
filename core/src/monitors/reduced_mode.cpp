// SPEC §10 reduced mode: active while the TCP is in a reduced zone, the reduced input asks
// for it (either channel: reduced is the safe side) or the outer protective field is
// interrupted (SPEC §11). The TCP must be at the reduced limit within reduced.ramp_ms of it
// becoming active; the monitor applies the reduced limit from then on.
#include "safestate/core/monitors.hpp"

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

}  // namespace safestate::core

#include "safestate/core/sequences.hpp"

namespace safestate::core {

// @req ST-CAT1
bool stop_step(StStopping& s, bool at_standstill, const Feedback& fb, const Timing& t) noexcept {
  if (!s.braking) {
    if (at_standstill && !(s.back_off && fb.backing_off)) {
      if (s.category == StopCat::CAT2) {
        return true;
      }
      s.braking = true;
      s.brake_elapsed = 0;
    }
    return false;
  }
  bool engaged = true;
  for (const bool released : fb.brake_released) {
    engaged = engaged && !released;
  }
  return engaged || (s.brake_elapsed > t.brakes_timeout);
}

}  // namespace safestate::core

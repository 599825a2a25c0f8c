// SPEC §10 "Recovery": a violated position limit does not leave the robot stuck.
#include "safestate/core/monitors.hpp"

namespace safestate::core {

// @req LIM-RECOVERY
bool track_violation(RecoveryTrack& t, float outside, bool powered, float tolerance) noexcept {
  const bool out = !(outside <= 0.0F);  // NaN is outside (unknown is unsafe)
  if (!powered) {
    // Found while no power is on: no alarm, nothing latched; remember it for recovery.
    t.recovering = out;
    t.best = outside;
    return false;
  }
  if (!out) {
    t.recovering = false;  // back inside: from now on the limit is a limit again
    return false;
  }
  if (!t.recovering || !(outside <= (t.best + tolerance))) {
    return true;  // a new violation, or a recovering one made worse
  }
  if (outside < t.best) {
    t.best = outside;
  }
  return false;
}

}  // namespace safestate::core

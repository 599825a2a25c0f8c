// SPEC §4 rule 3, ISO 10218-1 5.7.3: in T1 the TCP and every link origin stay at or below
// t1_speed_limit_mm_s (250 mm/s). Watches motion armed in T1: a key turned to T1 while the
// arm moves at another mode's speed is rule 6's (Cat 1), not a T1 speed fault. The speed
// stays over its limit (the reset's cause present) whatever the mode.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req MO-T1-MONITOR
void T1SpeedMonitor::check(const CycleView& v, Reporter& r) noexcept {
  const float speed = v.fb.max_point_speed_mm_s;
  r.facts().t1_speed_mm_s = speed;
  // `!(x <= limit)` so that a NaN speed counts as exceeded (unknown is unsafe).
  if (!(speed <= v.timing.t1_speed_limit_mm_s)) {
    r.present(AlarmId::T1_SPEED_EXCEEDED);
    if ((v.in.mode == Mode::T1) && (v.armed_mode == Mode::T1)) {
      r.trip(AlarmId::T1_SPEED_EXCEEDED,
             detail_of(Signal::drive, Channel::none, v.fb.fastest_axis, detail_code(speed)));
    }
  }
}

}  // namespace safestate::core

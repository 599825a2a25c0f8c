// SPEC §10: each joint speed <= max_speed_deg_s, the TCP speed <= tcp_max_speed_mm_s (or the
// reduced limit once reduced mode's ramp time is over) -> else SPEED_LIMIT naming the axis
// or `tcp`. Speeds from the drives' measured velocities through the core's own kinematics.
#include "safestate/core/monitors.hpp"

namespace safestate::core {

// @req LIM-SPEED
void SpeedLimitMonitor::check(const LimitContext& c, LimitReport& r) noexcept {
  r.tcp_speed_mm_s = point_speed(c.pose, c.pose.tcp, kAxes, c.qd);
  r.speed_limit_mm_s = c.reduced_enforced ? c.limits.reduced_tcp_max_speed_mm_s : c.limits.tcp_max_speed_mm_s;
  if (!c.powered) {
    return;  // rule 3 stops only what has power
  }
  for (std::size_t i = 0; (i < kAxes) && !r.speed.hit; ++i) {
    const float v = c.qd[i];
    const float speed = (v < 0.0F) ? -v : v;
    if (!(speed <= c.limits.joints[i].max_speed_rad_s)) {  // NaN is too fast
      r.speed.hit = true;
      r.speed.detail.signal = Signal::axis;
      r.speed.detail.axis = static_cast<std::uint8_t>(i + 1U);
    }
  }
  if (!r.speed.hit && !(r.tcp_speed_mm_s <= r.speed_limit_mm_s)) {
    r.speed.hit = true;
    r.speed.detail.signal = Signal::tcp;
    r.speed.detail.code = static_cast<std::uint16_t>((r.tcp_speed_mm_s < 65535.0F) ? r.tcp_speed_mm_s : 65535.0F);
  }
}

}  // namespace safestate::core

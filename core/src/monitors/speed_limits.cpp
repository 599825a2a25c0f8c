// SPEC §10: each joint speed <= max_speed_deg_s, the TCP speed <= tcp_max_speed_mm_s (or the
// reduced limit once reduced mode's ramp time is over) -> else SPEED_LIMIT naming the axis
// or `tcp`. Speeds from the drives' measured velocities through the core's own kinematics.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req LIM-SPEED
void SpeedLimitMonitor::check(const CycleView& v, Reporter& rep) noexcept {
  LimitReport& r = rep.facts().limits;
  const ArmPose& pose = *v.facts.pose;
  const JointArray& qd = v.facts.qd;
  r.tcp_speed_mm_s = point_speed(pose, pose.tcp, kAxes, qd);
  r.speed_limit_mm_s = r.reduced_enforced ? r.reduced_limit_mm_s : v.limits->tcp_max_speed_mm_s;
  // Judged with or without power: the reset guard asks whether the cause is gone (SPEC §5);
  // only with power on is it a finding of rule 3.
  LimitFinding f{};
  for (std::size_t i = 0; (i < kAxes) && !f.hit; ++i) {
    const float w = qd[i];
    const float speed = (w < 0.0F) ? -w : w;
    if (!(speed <= v.limits->joints[i].max_speed_rad_s)) {  // NaN is too fast
      f.hit = true;
      f.detail.signal = Signal::axis;
      f.detail.axis = static_cast<std::uint8_t>(i + 1U);
    }
  }
  if (!f.hit && !(r.tcp_speed_mm_s <= r.speed_limit_mm_s)) {
    f.hit = true;
    f.detail.signal = Signal::tcp;
    f.detail.code = detail_code(r.tcp_speed_mm_s);
  }
  r.speed_over = f.hit;
  if (f.hit) {
    rep.present(AlarmId::SPEED_LIMIT);
    if (v.powered) {
      rep.trip(AlarmId::SPEED_LIMIT, f.detail);  // rule 3 stops only what has power
    }
  }
}

}  // namespace safestate::core

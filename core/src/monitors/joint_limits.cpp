// SPEC §10: each joint within [min_deg, max_deg] of the safety configuration, from the
// measured position -> else JOINT_LIMIT naming the axis.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req LIM-JOINT
void JointLimitMonitor::check(const CycleView& v, Reporter& rep) noexcept {
  LimitReport& r = rep.facts().limits;
  for (std::size_t i = 0; i < kAxes; ++i) {
    const JointLimit& l = v.limits->joints[i];
    const float q = v.facts.q[i];
    const float below = l.min_rad - q;
    const float above = q - l.max_rad;
    const float outside = (below > above) ? below : above;  // NaN q: both NaN, stays NaN
    if ((outside <= 0.0F) && !track_[i].recovering) {
      continue;  // inside, as before: what track_violation() would conclude, without the call
    }
    const bool trips = track_violation(track_[i], (q == q) ? outside : q, v.powered, kWorseJointRad);
    r.outside = r.outside || !(outside <= 0.0F);
    r.recovering = r.recovering || track_[i].recovering;
    if (trips) {
      AlarmDetail d{};
      d.signal = Signal::axis;
      d.axis = static_cast<std::uint8_t>(i + 1U);
      rep.trip(AlarmId::JOINT_LIMIT, d);  // the first axis of the cycle is named
    }
  }
}

}  // namespace safestate::core

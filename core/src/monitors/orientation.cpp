// SPEC §10: the tool's z axis within max_deviation_deg of orientation.axis (base frame)
// -> else ORIENTATION_LIMIT (detail tcp). Compared as cosines: no acos in the cycle, and
// "how far outside" stays monotonic in the angle.
#include <cmath>

#include "safestate/core/monitor.hpp"

namespace safestate::core {

void OrientationMonitor::configure(const SafetyLimits& limits) noexcept {
  cos_max_ = std::cos(limits.orientation_max_deviation_rad);  // once, not every cycle
}

// @req LIM-ORIENTATION
void OrientationMonitor::check(const CycleView& v, Reporter& rep) noexcept {
  if (!v.limits->orientation_enabled) {
    return;
  }
  LimitReport& r = rep.facts().limits;
  const Vec3& a = v.limits->orientation_axis;  // unit (SafeLimitMonitors::configure() normalises it)
  const Vec3& z = v.facts.pose->tool_z;
  const float cos_angle = (a[0] * z[0]) + (a[1] * z[1]) + (a[2] * z[2]);
  const float outside = cos_max_ - cos_angle;
  const bool trips = track_violation(track_, outside, v.powered, kWorseOrientationCos);
  r.outside = r.outside || !(outside <= 0.0F);
  r.recovering = r.recovering || track_.recovering;
  if (trips) {
    rep.trip(AlarmId::ORIENTATION_LIMIT, detail_of(Signal::tcp));
  }
}

}  // namespace safestate::core

// SPEC §10: the tool's z axis within max_deviation_deg of orientation.axis (base frame)
// -> else ORIENTATION_LIMIT (detail tcp). Compared as cosines: no acos in the cycle, and
// "how far outside" stays monotonic in the angle.
#include "safestate/core/monitors.hpp"

namespace safestate::core {

// @req LIM-ORIENTATION
void OrientationMonitor::check(const LimitContext& c, LimitReport& r) noexcept {
  if (!c.limits.orientation_enabled) {
    return;
  }
  const Vec3& a = c.limits.orientation_axis;  // unit (configure() normalises it)
  const Vec3& z = c.pose.tool_z;
  const float cos_angle = (a[0] * z[0]) + (a[1] * z[1]) + (a[2] * z[2]);
  const float outside = c.orientation_cos - cos_angle;
  const bool trips = track_violation(track_, outside, c.powered, kWorseOrientationCos);
  r.outside = r.outside || !(outside <= 0.0F);
  r.recovering = r.recovering || track_.recovering;
  if (trips) {
    r.orientation.hit = true;
    r.orientation.detail.signal = Signal::tcp;
  }
}

}  // namespace safestate::core

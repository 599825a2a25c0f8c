// The safe-limit monitors together (SPEC §10), run once per cycle by the supervisor.
#include <cmath>

#include "safestate/core/config.hpp"
#include "safestate/core/describe.hpp"
#include "safestate/core/monitor.hpp"

namespace safestate::core {

void SafeLimitMonitors::configure_arm(const ArmGeometry& arm, const Vec3& tcp_flange_mm) noexcept {
  arm_ = prepare_arm(arm);
  tcp_ = tcp_flange_mm;
  arm_configured_ = true;
}

void SafeLimitMonitors::configure(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us) noexcept {
  limits_ = limits;
  configure_arm(arm, limits_.tcp_mm);
  zones_.reset(arm_, limits_.tcp_mm);  // other zones: nothing the last cycles proved holds for them
  Vec3& a = limits_.orientation_axis;
  const float len = std::sqrt((a[0] * a[0]) + (a[1] * a[1]) + (a[2] * a[2]));
  if (len > 0.0F) {
    a = {a[0] / len, a[1] / len, a[2] / len};
  } else {
    limits_.orientation_enabled = false;  // safety/ refuses a zero axis before we get here
  }
  orientation_.configure(limits_);
  reduced_.configure((cycle_us > 0U) ? ms_to_cycles(limits_.reduced_ramp_ms, cycle_us) : 0U);
  configured_ = true;
}

void SafeLimitMonitors::check(const CycleView& v, Reporter& r) noexcept {
  CycleFacts& f = r.facts();
  f.limits.clear();
  f.pose = nullptr;
  if (arm_configured_) {  // the pose for T1 speed too, limits or not
    for (std::size_t i = 0; i < kAxes; ++i) {
      f.q[i] = v.fb.drive[i].position_rad;
      f.qd[i] = v.fb.drive[i].velocity_rad_s;
    }
    arm_forward(arm_, f.q, tcp_, pose_);
    f.pose = &pose_;
  }
  if (v.limits == nullptr) {  // the supervisor passes the limits once configured
    r.hold(AlarmId::REDUCED_SPEED, false, AlarmDetail{});
    return;
  }
  // Reduced mode after the zones (its zone source is this cycle's TCP position) and before
  // the speeds (whether the reduced limit is enforced).
  joints_.check(v, r);
  zones_.check(v, r);
  orientation_.check(v, r);
  reduced_.check(v, r);
  speed_.check(v, r);
}

const char* limit_detail_name(const AlarmDetail& d, const SafetyLimits& limits, char* buf, std::size_t n) noexcept {
  if ((buf == nullptr) || (n == 0U)) {
    return "";
  }
  if ((d.signal == Signal::zone) && (d.code < limits.zone_count) && (d.code < kMaxZones)) {
    const auto& name = limits.zones[d.code].name;
    std::size_t i = 0;
    for (; (i + 1U < n) && (i < name.size()) && (name[i] != '\0'); ++i) {
      buf[i] = name[i];  // NOLINT(cppcoreguidelines-pro-bounds-pointer-arithmetic): caller's buffer of n
    }
    buf[i] = '\0';  // NOLINT(cppcoreguidelines-pro-bounds-pointer-arithmetic): i < n
    return buf;
  }
  return detail_name(d, buf, n);
}

}  // namespace safestate::core

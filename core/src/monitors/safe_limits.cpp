// The safe-limit monitors together (SPEC §10), run once per cycle by the supervisor.
#include <cmath>

#include "safestate/core/config.hpp"
#include "safestate/core/describe.hpp"
#include "safestate/core/monitors.hpp"

namespace safestate::core {

void SafeLimitMonitors::configure(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us) noexcept {
  limits_ = limits;
  arm_ = prepare_arm(arm);
  zones_.reset(arm_, limits_.tcp_mm);  // other zones: nothing the last cycles proved holds for them
  Vec3& a = limits_.orientation_axis;
  const float len = std::sqrt((a[0] * a[0]) + (a[1] * a[1]) + (a[2] * a[2]));
  if (len > 0.0F) {
    a = {a[0] / len, a[1] / len, a[2] / len};
  } else {
    limits_.orientation_enabled = false;  // safety/ refuses a zero axis before we get here
  }
  orientation_cos_ = std::cos(limits_.orientation_max_deviation_rad);  // once, not every cycle
  ramp_cycles_ = (cycle_us > 0U) ? ms_to_cycles(limits_.reduced_ramp_ms, cycle_us) : 0U;
  configured_ = true;
}

void SafeLimitMonitors::evaluate(const Feedback& fb, bool powered, bool input_reduced, std::uint8_t other_sources,
                                 LimitReport& out) noexcept {
  out.clear();
  if (!configured_) {
    return;
  }
  // Written whole by the loop: no value-initialisation first (two byte-wise newlib-nano
  // memsets per cycle on the Cortex-M4).
  JointArray q;   // NOLINT(cppcoreguidelines-pro-type-member-init,hicpp-member-init)
  JointArray qd;  // NOLINT(cppcoreguidelines-pro-type-member-init,hicpp-member-init)
  for (std::size_t i = 0; i < kAxes; ++i) {
    q[i] = fb.drive[i].position_rad;
    qd[i] = fb.drive[i].velocity_rad_s;
  }
  arm_forward(arm_, q, limits_.tcp_mm, pose_);
  // Reduced mode first: the speed monitor needs to know whether it is enforced. The zone
  // source is this cycle's TCP position, so the zone monitor runs before it.
  LimitContext ctx{limits_, pose_, q, qd, powered, false, limits_.reduced_tcp_max_speed_mm_s, orientation_cos_};
  joints_.check(ctx, out);
  zones_.check(ctx, out);
  orientation_.check(ctx, out);
  const auto sources = static_cast<std::uint8_t>((out.in_reduced_zone ? kReducedByZone : 0U) |
                                                 (input_reduced ? kReducedByInput : 0U) | other_sources);
  ctx.reduced_limit_mm_s = reduced_limit_mm_s(limits_, sources);
  reduced_.update(sources, ramp_cycles_, ctx.reduced_limit_mm_s);
  ctx.reduced_enforced = reduced_.enforced();
  SpeedLimitMonitor::check(ctx, out);
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

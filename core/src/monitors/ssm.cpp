// SPEC §11 speed and separation monitoring (ISO 10218-2:2025, formerly ISO/TS 15066 5.5.4).
// The allowed TCP speed v_allowed(d) comes from the protective separation distance solved
// for v (ssm_allowed_speed_mm_s, collaborative.cpp); the motion layer keeps the TCP at
// 0.95 x v_allowed; this monitor trips when the TCP, measured through the core's own
// kinematics, has been above v_allowed + 5 % for longer than the reaction time T_r.
//
// The separation (SPEC §11 "bad input"): invalid or negative counts as 0 (SignalLayer). A
// reading that rises faster than the person and the robot can move apart (a person at most
// kHumanSpeedNearMmS, ISO 13855, plus the TCP at its normal limit, the other way) is a
// "jump": not believed, the separation used rises at that rate only. A fall is always taken
// at once: it is the safe side, and a person may step into the sensor's view at any time.
#include <cmath>

#include "safestate/core/monitor.hpp"

namespace safestate::core {

void SsmMonitor::configure(const SafetyLimits& limits, std::uint32_t cycle_us) noexcept {
  const CollaborativeLimits& c = limits.collaborative;
  enabled_ = c.enabled && c.ssm_enabled;
  params_ = c.ssm;
  const double cycle_s = static_cast<double>(cycle_us) * 1.0e-6;
  // T_r in whole cycles, rounded down: "longer than T_r" is then the cycle after. T_r is
  // held in seconds as a float: back to whole microseconds first (0.02F s is 19999.9995 us,
  // which must count as the 20 ms the file says, not 19 cycles).
  const double reaction_us = std::floor((static_cast<double>(c.ssm.reaction_s) * 1.0e6) + 0.5);
  reaction_ = ((cycle_us > 0U) && (reaction_us > 0.0)) ? (static_cast<Cycle>(reaction_us) / cycle_us) : 0U;
  rise_ = static_cast<float>((static_cast<double>(kHumanSpeedNearMmS) +
                              static_cast<double>(limits.tcp_max_speed_mm_s)) * cycle_s);
  used_ = 0.0F;  // unknown until the sensor has been read
  over_ = 0;
}

// @req COL-SSM-INPUT COL-SSM-MONITOR
void SsmMonitor::check(const CycleView& v, Reporter& rep) noexcept {
  SsmReport& r = rep.facts().ssm;
  // The core's own TCP speed and the TCP limit in force (the safe limits' facts).
  const float tcp_speed = v.facts.limits.tcp_speed_mm_s;
  const float limit = v.facts.limits.speed_limit_mm_s;
  r = SsmReport{};
  const float ceiling = used_ + rise_;
  used_ = (v.in.separation_mm < ceiling) ? v.in.separation_mm : ceiling;  // NaN never reaches here (SignalLayer)
  r.separation_mm = used_;
  r.acting = enabled_ && (v.in.mode == Mode::AUTO);
  if (!r.acting) {
    over_ = 0;
    return;
  }
  r.v_allowed_mm_s = ssm_allowed_speed_mm_s(used_, params_, limit);
  r.v_plan_mm_s = ssm_planning_speed_mm_s(used_, params_, limit);
  r.over = !(tcp_speed <= (r.v_allowed_mm_s * kSsmTolerance));  // NaN is over
  over_ = r.over ? over_ + 1U : 0U;
  if (r.over) {
    rep.present(AlarmId::SEPARATION_VIOLATED);
  }
  if (v.powered && (over_ > reaction_)) {
    rep.trip(AlarmId::SEPARATION_VIOLATED, detail_of(Signal::separation, Channel::none, 0U, detail_code(tcp_speed)));
  }
}

}  // namespace safestate::core

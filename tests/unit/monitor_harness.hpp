// Runs monitors of core/src/monitors/ outside the supervisor, one cycle at a time, the way
// SystemStateManager::run_monitors does: a CycleView of hand-made inputs and feedback, a
// Reporter, then what it found (by alarm name) and measured (facts).
#pragma once

#include "safestate/core/config.hpp"
#include "safestate/core/monitor.hpp"
#include "safestate/core/monitors.hpp"

namespace safestate::test {

struct MonitorCycle {
  core::SafetyInputs in{};
  core::Feedback fb{};
  core::Timing timing = core::to_timing(core::Config{});
  core::StateVariant state{core::StOperational{}};
  core::Leaf leaf = core::Leaf::AUTO_RUNNING;
  bool powered = true;
  core::Cycle now = 0;
  core::Mode armed_mode = core::Mode::AUTO;
  core::CycleFacts facts{};  // what the monitors before this one found (inputs to it)
  const core::SafetyLimits* limits = nullptr;
  core::AlarmSet alarms;

  // One cycle of `m`; `r` is what it reported (found, present, facts).
  template <typename M>
  core::Reporter run(M& m) {
    core::Reporter r;
    r.begin(alarms, now);
    r.facts() = facts;
    const core::CycleView v{in,       fb,    timing,     state, r.facts(), limits, leaf, powered, now, armed_mode, 0U,
                            false,    false, true,       true,  core::Commanded{}};
    m.check(v, r);
    facts = r.facts();
    ++now;
    return r;
  }
};

[[nodiscard]] inline bool found(const core::Reporter& r, core::AlarmId a) { return (r.found() & core::bit(a)) != 0U; }
[[nodiscard]] inline bool present(const core::Reporter& r, core::AlarmId a) {
  return (r.present_mask() & core::bit(a)) != 0U;
}
[[nodiscard]] inline core::LimitFinding finding(const core::Reporter& r, core::AlarmId a) {
  core::LimitFinding f{};
  f.hit = found(r, a);
  if (f.hit) {
    f.detail = r.detail(a);
  }
  return f;
}

// One cycle of monitor `m` with hand-made inputs: `facts_in` are the facts of the monitors
// before it; `see` is called with the Reporter before it goes.
template <typename M, typename F>
void run_one(M& m, const core::SafetyInputs& in, const core::Feedback& fb, core::Leaf leaf, bool powered,
             const core::CycleFacts& facts_in, const core::SafetyLimits* limits, F&& see) {
  core::AlarmSet alarms;
  core::Reporter r;
  r.begin(alarms, 0U);
  r.facts() = facts_in;
  const core::Timing timing = core::to_timing(core::Config{});
  const core::StateVariant state{core::StOperational{}};
  const core::CycleView v{in,   fb,      timing, state,          r.facts(), limits, leaf, powered,
                          0U,   core::Mode::AUTO,  0U,   false, false, true, true,   core::Commanded{}};
  m.check(v, r);
  see(r);
}

// The safe limits' verdict of one cycle, with each finding by its old field name.
struct LimitResult : core::LimitReport {
  core::LimitFinding joint;
  core::LimitFinding zone;
  core::LimitFinding orientation;
  core::LimitFinding speed;
};

// SafeLimitMonitors for one cycle of feedback `fb`: `powered`, the reduced input, and the
// other reduced-mode sources (kReducedByField: the outer field).
inline void evaluate(core::SafeLimitMonitors& m, const core::Feedback& fb, bool powered, bool input_reduced,
                     std::uint8_t other_sources, LimitResult& out) {
  core::AlarmSet alarms;
  core::Reporter r;
  r.begin(alarms, 0U);
  core::SafetyInputs in{};
  in.reduced_requested = input_reduced;
  r.facts().fields.outer_reduces = (other_sources & core::kReducedByField) != 0U;
  const core::Timing timing = core::to_timing(core::Config{});
  const core::StateVariant state{core::StOperational{}};
  const core::CycleView v{in,    fb,      timing, state, r.facts(), m.configured() ? &m.limits() : nullptr,
                          core::Leaf::AUTO_RUNNING, powered, 0U,  core::Mode::AUTO, 0U, false, false, true, true,
                          core::Commanded{}};
  m.check(v, r);
  static_cast<core::LimitReport&>(out) = r.facts().limits;
  out.joint = finding(r, core::AlarmId::JOINT_LIMIT);
  out.zone = finding(r, core::AlarmId::ZONE_VIOLATION);
  out.orientation = finding(r, core::AlarmId::ORIENTATION_LIMIT);
  out.speed = finding(r, core::AlarmId::SPEED_LIMIT);
}

// CollisionMonitor for one cycle; `arm_free`: the drives hold the arm (AUTO_RUNNING), else
// power is off (IDLE).
struct CollisionResult : core::CollisionReport {
  core::LimitFinding hit;
};
inline void collide(core::CollisionMonitor& m, const core::Feedback& fb, bool arm_free, CollisionResult& out) {
  run_one(m, core::SafetyInputs{}, fb, arm_free ? core::Leaf::AUTO_RUNNING : core::Leaf::IDLE, arm_free,
          core::CycleFacts{}, nullptr, [&](const core::Reporter& r) {
            static_cast<core::CollisionReport&>(out) = r.facts().collision;
            out.hit = finding(r, core::AlarmId::COLLISION);
          });
}

// FieldMonitor for one cycle.
struct FieldResult : core::FieldReport {
  bool discrepancy = false;
  core::AlarmDetail discrepancy_detail{};
  core::AlarmDetail inner_detail{};  // PERSON_IN_FIELD's, while the inner field stops
};
inline void fields(core::FieldMonitor& m, const core::SafetyInputs& in, FieldResult& out) {
  run_one(m, in, core::Feedback{}, core::Leaf::AUTO_RUNNING, true, core::CycleFacts{}, nullptr,
          [&](const core::Reporter& r) {
            static_cast<core::FieldReport&>(out) = r.facts().fields;
            const core::LimitFinding d = finding(r, core::AlarmId::FIELD_DISCREPANCY);
            out.discrepancy = d.hit;
            out.discrepancy_detail = d.detail;
            out.inner_detail = finding(r, core::AlarmId::PERSON_IN_FIELD).detail;
          });
}

// SsmMonitor for one cycle: the core's TCP speed and the TCP limit in force as the safe
// limits would have found them.
struct SsmResult : core::SsmReport {
  core::LimitFinding violated;
  bool cause_present = false;
};
inline void ssm(core::SsmMonitor& m, const core::SafetyInputs& in, float tcp_speed, float limit, bool powered,
                SsmResult& out) {
  core::CycleFacts f{};
  f.limits.tcp_speed_mm_s = tcp_speed;
  f.limits.speed_limit_mm_s = limit;
  run_one(m, in, core::Feedback{}, core::Leaf::AUTO_RUNNING, powered, f, nullptr, [&](const core::Reporter& r) {
    static_cast<core::SsmReport&>(out) = r.facts().ssm;
    out.violated = finding(r, core::AlarmId::SEPARATION_VIOLATED);
    out.cause_present = present(r, core::AlarmId::SEPARATION_VIOLATED);
  });
}

}  // namespace safestate::test

// SPEC §11 protective fields (ISO 10218-2:2025, area scanner with an outer warning field and
// an inner protective field). With collaborative operation on and the mode AUTO: the outer
// field interrupted makes reduced mode active (kReducedByField), the inner field interrupted
// stops a running program (rule 9, Cat 2 to AUTO_PAUSED), and a pause of rule 9 resumes by
// itself once both fields have been clear for resume_delay_ms (auto_resume on). In T1/T2 the
// enabling device guards the person beside the robot: the fields do not act. A discrepancy
// of a field's two OSSD channels is a hardware fault and locks out in every case (rule 1).
#include "safestate/core/config.hpp"
#include "safestate/core/monitor.hpp"

namespace safestate::core {

namespace {
float lower(float a, float b) noexcept { return (b < a) ? b : a; }
}  // namespace

// @req COL-FIELD-REDUCED
float reduced_limit_mm_s(const SafetyLimits& limits, std::uint8_t sources) noexcept {
  float limit = limits.reduced_tcp_max_speed_mm_s;
  const CollaborativeLimits& c = limits.collaborative;
  if (((sources & kReducedByField) != 0U) && c.enabled) {
    limit = lower(limit, c.reduced_speed_mm_s);
    if (c.pfl_enabled) {
      limit = lower(limit, c.pfl_speed_mm_s);
    }
  }
  return limit;
}

void FieldMonitor::configure(const CollaborativeLimits& c, std::uint32_t cycle_us) noexcept {
  enabled_ = c.enabled;
  auto_resume_ = c.auto_resume;
  delay_ = (cycle_us > 0U) ? ms_to_cycles(c.resume_delay_ms, cycle_us) : 0U;
  clear_ = 0;
}

// @req COL-FIELDS COL-FIELD-GUARD
void FieldMonitor::check(const CycleView& v, Reporter& rep) noexcept {
  const SafetyInputs& in = v.in;
  FieldReport& r = rep.facts().fields;
  r = FieldReport{};
  // Which field (outer first, as wired) and channel disagreed: a hardware fault, rule 1.
  if (in.field_outer_discrepancy || in.field_inner_discrepancy) {
    rep.trip(AlarmId::FIELD_DISCREPANCY,
             detail_of(in.field_outer_discrepancy ? Signal::field_outer : Signal::field_inner,
                       in.field_outer_discrepancy ? in.field_outer_fault_channel : in.field_inner_fault_channel));
  }
  r.acting = enabled_ && (in.mode == Mode::AUTO);
  r.outer_reduces = r.acting && in.field_outer_interrupted;
  r.inner_stops = r.acting && in.field_inner_interrupted;
  r.blocks_start = r.inner_stops;
  // PERSON_IN_FIELD (rule 9), active while the inner field stops, naming its channel.
  const AlarmDetail inner = detail_of(Signal::field_inner, in.field_inner_cause);
  rep.hold(AlarmId::PERSON_IN_FIELD, r.inner_stops, inner);
  if (r.inner_stops) {
    rep.trip(AlarmId::PERSON_IN_FIELD, inner);
  }
  // "Both fields clear for resume_delay_ms": counted in cycles, the first clear cycle
  // counting 1, so that the resume comes resume_delay_ms after the cycle that read them clear.
  const bool both_clear = !in.field_outer_interrupted && !in.field_inner_interrupted;
  clear_ = both_clear ? ((clear_ <= delay_) ? clear_ + 1U : clear_) : 0U;
  r.resume_due = r.acting && auto_resume_ && (clear_ > delay_);
}

}  // namespace safestate::core

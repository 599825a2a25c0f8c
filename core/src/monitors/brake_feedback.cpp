// SPEC §7, ISO 13849-1 external device monitoring: every brake's feedback must follow what
// this core commanded in the previous cycle (the brake test engages one brake while the
// others stay released, SPEC §12). A brake counts as engaged only after its feedback said
// so for brake_confirm cycles without a break; until then its time runs from the first
// released reading, so a feedback that chatters is still released when the brake time is
// over. Still released brakes_timeout after the engage command: BRAKE_NOT_ENGAGED, raised
// in every state (an axis without its brake is a hazard whether or not rule 3 has a stop to
// make) and rule 3's; its cause present while the brake still does not hold.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req AL-FEEDBACK
void BrakeFeedbackMonitor::check(const CycleView& v, Reporter& r) noexcept {
  std::uint8_t axis = 0;
  for (std::size_t i = 0; i < kAxes; ++i) {
    const bool release_cmd = v.last.brakes_release && (v.last.brake_test_axis != (i + 1U));
    const bool stuck_now = !release_cmd && v.fb.brake_released[i];
    const bool engaged_now = !release_cmd && !v.fb.brake_released[i];
    engaged_run_[i] = engaged_now ? engaged_run_[i] + 1U : 0U;
    if (release_cmd || (engaged_run_[i] >= v.timing.brake_confirm)) {
      cycles_[i] = 0U;
    } else if (stuck_now || (cycles_[i] != 0U)) {
      ++cycles_[i];
    } else {
      // engaged reading, not confirmed yet, nothing released since the last confirmation
    }
    if (stuck_now && (cycles_[i] > v.timing.brakes_timeout) && (axis == 0U)) {
      axis = static_cast<std::uint8_t>(i + 1U);
    }
  }
  if (axis != 0U) {
    const AlarmDetail d = detail_of(Signal::brake, Channel::none, axis);
    r.raise(AlarmId::BRAKE_NOT_ENGAGED, d);
    r.trip(AlarmId::BRAKE_NOT_ENGAGED, d);
    r.present(AlarmId::BRAKE_NOT_ENGAGED);
  }
}

}  // namespace safestate::core

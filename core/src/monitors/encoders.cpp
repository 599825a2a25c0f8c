// SPEC §14 two encoders per axis: the motor encoder (0x6064, what every position-based
// monitor uses) and the load-side encoder (0x60E4, behind the gearbox) must agree. A
// difference above encoder_tolerance for longer than encoder_discrepancy (a slipping
// coupling, a failing encoder, a broken gear), or a load-side encoder that stands still
// while the motor encoder moves by more than the tolerance (a stuck or dead encoder, at
// once: it would otherwise hide for as long as the motion stays small), is
// ENCODER_DISCREPANCY naming the axis (rule 1, lockout). A NaN on either side is a
// difference. Timing in cycles; positions as read this cycle (held ones are compared again).
#include <cmath>

#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req CH-ENCODERS
void EncoderMonitor::check(const CycleView& v, Reporter& r) noexcept {
  if (!v.fb.load_encoders) {
    have_last_ = false;
    return;
  }
  const float tol = v.timing.encoder_tolerance_rad;
  for (std::size_t i = 0; i < kAxes; ++i) {
    const float motor = v.fb.drive[i].position_rad;
    const float load = v.fb.drive[i].load_position_rad;
    const bool over = !(std::fabs(motor - load) <= tol);
    over_[i] = over ? ((over_[i] < v.timing.encoder_discrepancy + 1U) ? over_[i] + 1U : over_[i]) : 0U;
    // Exact comparison on purpose: an encoder that counts changes its value; one that does
    // not stands still, whatever the resolution.
    // NOLINTNEXTLINE(clang-diagnostic-float-equal)
    if (!have_last_ || (load != load_last_[i])) {
      load_last_[i] = load;
      motor_at_last_[i] = motor;
    }
    const bool stuck = !(std::fabs(motor - motor_at_last_[i]) <= tol);
    if ((over_[i] > v.timing.encoder_discrepancy) || stuck) {
      r.trip(AlarmId::ENCODER_DISCREPANCY, detail_of(Signal::axis, Channel::none, static_cast<std::uint8_t>(i + 1U)));
    }
  }
  have_last_ = true;
}

}  // namespace safestate::core

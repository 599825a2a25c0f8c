#include "safestate/core/sequences.hpp"

#include "safestate/core/cia402.hpp"

namespace safestate::core {

ArmingOutcome arming_step(StArming& a, const Feedback& fb, const Timing& t, AlarmDetail& detail) noexcept {
  bool done = false;
  Cycle limit = t.contactor_timeout;
  std::uint8_t laggard = 0;  // the first axis not there yet: the timeout names it
  switch (a.step) {
    case ArmingStep::CONTACTOR:
      done = fb.contactor_closed && (!fb.two_contactors || fb.k2_closed);  // SPEC §14: K1 and K2 in series
      break;
    case ArmingStep::DRIVES:
      limit = t.drives_timeout;
      for (std::size_t i = 0; (i < kAxes) && (laggard == 0U); ++i) {
        const bool enabled = cia402::decode(fb.drive[i].statusword) == cia402::DriveState::OperationEnabled;
        laggard = enabled ? 0U : static_cast<std::uint8_t>(i + 1U);
      }
      done = laggard == 0U;
      break;
    case ArmingStep::BRAKES:
      limit = t.brakes_timeout;
      for (std::size_t i = 0; (i < kAxes) && (laggard == 0U); ++i) {
        laggard = fb.brake_released[i] ? 0U : static_cast<std::uint8_t>(i + 1U);
      }
      done = laggard == 0U;
      break;
  }
  if (done && (a.step == ArmingStep::BRAKES)) {
    a.progress = 100U;
    return ArmingOutcome::complete;
  }
  if (done) {
    a.step = static_cast<ArmingStep>(static_cast<std::uint8_t>(a.step) + 1U);
    a.step_elapsed = 0;
  } else if (a.step_elapsed > limit) {
    detail = AlarmDetail{};
    detail.signal = (a.step == ArmingStep::CONTACTOR) ? Signal::contactor
                                                      : ((a.step == ArmingStep::DRIVES) ? Signal::drive : Signal::brake);
    detail.step = a.step;
    detail.has_step = true;
    detail.axis = laggard;
    return ArmingOutcome::timeout;
  } else {
    // the step goes on
  }
  const Cycle span = (a.step == ArmingStep::CONTACTOR)
                         ? t.contactor_timeout
                         : ((a.step == ArmingStep::DRIVES) ? t.drives_timeout : t.brakes_timeout);
  const Cycle part = (span > 0U) ? ((a.step_elapsed * 33U) / (span + 1U)) : 0U;
  a.progress = static_cast<std::uint8_t>((static_cast<Cycle>(a.step) * 33U) + part);
  return ArmingOutcome::running;
}

}  // namespace safestate::core

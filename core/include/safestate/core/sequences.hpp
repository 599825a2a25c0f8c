// The supervisor's sequences, each with a home of its own: they advance a state's own data
// and tell the state machine what happened; the state machine takes the rows. (The brake
// test of SPEC §12, a sequence too, is in brake_test.hpp.)
//
// SPEC §4 ARMING: the power-up sequence after servo_on, one step at a time: the contactor
// closes (its auxiliary contact), every drive reaches Operation enabled, every brake
// releases, each within its timeout. A sequence with a home of its own: it advances the
// ARMING state's data and tells the state machine what happened; the state machine takes
// the `arming_complete` / `arming_timeout` rows.
#pragma once

#include "safestate/core/alarms.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/interfaces.hpp"
#include "safestate/core/states.hpp"

namespace safestate::core {

enum class ArmingOutcome : std::uint8_t {
  running,   // the step goes on (or the next one began)
  complete,  // every brake released: the arm is powered
  timeout,   // a step took longer than its timeout: ARMING_TIMEOUT with `detail`
};

// One cycle of the sequence: `a.step_elapsed` already counts this cycle. Updates the step,
// its time and the progress (percent); on a timeout fills `detail` (the step's signal, the
// step, the first axis not there yet).
ArmingOutcome arming_step(StArming& a, const Feedback& fb, const Timing& t, AlarmDetail& detail) noexcept;

// SPEC §3 STOPPING, one cycle: whether the stop has reached its end (the `standstill`
// row). Cat 2 ends at standstill (not while the motion layer still backs off, SPEC §11
// rule 8: the stop-time monitor bounds it). IEC 60204-1 Cat 1: at standstill the brakes
// engage while the drives still hold, and the stop ends (power removed) once every brake
// has engaged or brakes_timeout has passed (BrakeFeedbackMonitor names a brake that did not).
[[nodiscard]] bool stop_step(StStopping& s, bool at_standstill, const Feedback& fb, const Timing& t) noexcept;

}  // namespace safestate::core

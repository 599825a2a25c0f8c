// The supervisor's own integrity check of every cycle (SPEC §4 rule 1, INTEGRITY_FAULT):
// the safety outputs it is about to write read a second time, independently of the table
// that produced them (a diverse check against a fault in the state data or the tables).
#include "safestate/core/supervisor.hpp"

namespace safestate::core {

bool outputs_consistent(const SupervisorOut& o, Leaf leaf, const StateVariant& state, bool estop_pressed) noexcept {
  // A second, independent reading of the safety outputs (diverse check): power only in
  // the powered states, nothing powered while the E-stop is pressed, and the state data
  // agreeing with the state the table believes in.
  const bool powered_state = (static_cast<unsigned>(kPowered) & static_cast<unsigned>(mask_of(leaf))) != 0U;
  const bool any_power = o.contactor || o.drives_enable || o.brakes_release;
  if (any_power && !powered_state) {
    return false;
  }
  if (estop_pressed && any_power) {
    return false;
  }
  if ((o.motion.mode == MotionMode::Jog) && (leaf != Leaf::MANUAL_JOGGING)) {
    return false;
  }
  if ((o.motion.mode == MotionMode::Program) && (leaf != Leaf::AUTO_RUNNING) && (leaf != Leaf::MANUAL_RUNNING)) {
    return false;
  }
  return leaf_of(state) == leaf;
}

}  // namespace safestate::core

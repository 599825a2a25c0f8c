// SPEC §5, the first three steps of a command's check order, before the state rules:
// malformed (unknown command, bad arguments), lockout, ownership (single point of control,
// ISO 10218-1 5.3.5: observers never command, the remote station only in AUTO and never a
// reset, the reset button only resets).
#include "safestate/core/supervisor.hpp"

namespace safestate::core {

Result check_command(const Command& cmd, Leaf leaf, Mode mode) noexcept {
  // @req RES-ORDER TR-JOG-ARGS
  // 1. Malformed (SPEC §5 check order).
  if (cmd.id >= kCommandCount) {
    return Result::UNKNOWN_COMMAND;
  }
  const auto id = static_cast<CommandId>(cmd.id);
  if (cmd.source >= kSourceCount) {
    return Result::BAD_ARGUMENT;
  }
  if (id == CommandId::jog) {
    const bool axis_ok = (cmd.axis >= 1) && (cmd.axis <= static_cast<std::int8_t>(kAxes));
    const bool dir_ok = (cmd.dir == 1) || (cmd.dir == -1);
    const bool speed_ok = (cmd.speed >= 1U) && (cmd.speed <= 100U);
    if (!axis_ok || !dir_ok || !speed_ok) {
      return Result::BAD_ARGUMENT;
    }
  }
  if ((id == CommandId::set_mode) && ((cmd.mode == 0U) || (cmd.mode > static_cast<std::uint8_t>(Mode::T2)))) {
    return Result::BAD_ARGUMENT;
  }
  if ((id == CommandId::validate_config) && (cmd.has_code != 1U)) {
    return Result::BAD_ARGUMENT;  // no code, or not 8 hex digits
  }
  // @req RES-LOCKED-OUT
  // 2. Lockout.
  if (leaf == Leaf::ERROR_LOCKOUT) {
    return Result::LOCKED_OUT;
  }
  // @req RES-OWNER
  // 3. Ownership (single point of control, ISO 10218-1 5.3.5).
  const auto src = static_cast<Source>(cmd.source);
  if (src == Source::observer) {
    return Result::NOT_CONTROL_OWNER;
  }
  if ((src == Source::remote) && ((id == CommandId::reset) || (mode != Mode::AUTO))) {
    return Result::NOT_CONTROL_OWNER;
  }
  if ((src == Source::reset_button) && (id != CommandId::reset)) {
    return Result::NOT_CONTROL_OWNER;
  }
  return Result::OK;
}

}  // namespace safestate::core

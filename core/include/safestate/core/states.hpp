// States of SPEC §3 as small structs, each carrying its own data, held in a
// std::variant (no heap: the variant is a tagged union inside the manager).
#pragma once

#include <cstdint>
#include <variant>

#include "safestate/core/alarms.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

// Leaf states: a state together with the sub-state or stop category that the
// transition table distinguishes. The table's from/to columns are leaves.
enum class Leaf : std::uint8_t {
  BOOT,
  ERROR_LOCKOUT,
  ESTOP_ACTIVE,
  ESTOP_RESET_NEEDED,
  IDLE,
  ARMING,
  AUTO_IDLE,
  AUTO_RUNNING,
  AUTO_PAUSED,
  MANUAL_IDLE,
  MANUAL_JOGGING,
  MANUAL_RUNNING,
  STOPPING_CAT1,
  STOPPING_CAT2,
  BRAKE_TEST,  // OPERATIONAL, sub BRAKE_TEST (SPEC §12); appended so older leaves keep their place
  // Targets only (never a current state):
  SAME,         // stay: the row only acts (keep-alive, confirmation, acknowledgement)
  OP_IDLE,      // OPERATIONAL, AUTO_IDLE or MANUAL_IDLE by the mode
  STOP_TARGET,  // the target the current STOPPING was started with
};
inline constexpr std::size_t kLeafCount = 15;  // real leaves, BOOT..BRAKE_TEST

// Why the current stop (or lockout) happened: the first-out cause shown to operators.
enum class CauseKind : std::uint8_t { none, alarm, command, event };
struct Cause {
  CauseKind kind = CauseKind::none;
  std::uint8_t rule = 0;  // SPEC §4 condition rule 1..7, 0 for commands and events
  AlarmId alarm = AlarmId::ESTOP_PRESSED;
  CommandId command = CommandId::reset;
  Source source = Source::pendant;
  Mode mode = Mode::NONE;  // the mode when it happened ("Guard opened in AUTO")
  AlarmDetail detail{};
};

struct StBoot {
  Cycle elapsed = 0;
};
struct StErrorLockout {
  Cause cause{};
};
struct StEstopActive {};
struct StEstopResetNeeded {};
struct StIdle {};
struct StArming {
  ArmingStep step = ArmingStep::CONTACTOR;
  Cycle step_elapsed = 0;
  std::uint8_t progress = 0;  // percent
};
struct StOperational {
  Sub sub = Sub::AUTO_IDLE;
};
struct StStopping {
  StopCat category = StopCat::CAT1;
  Leaf target = Leaf::IDLE;
  Cycle elapsed = 0;        // since the stop began (stop time monitoring, SS1-t)
  bool braking = false;     // Cat 1 at standstill: brakes engaging, drives still holding
  Cycle brake_elapsed = 0;
  bool back_off = false;    // rule 8 (SPEC §11): back off along the path before holding
};

// Alternatives in the order of enum State.
using StateVariant = std::variant<StBoot, StErrorLockout, StEstopActive, StEstopResetNeeded, StIdle, StArming,
                                  StOperational, StStopping>;

[[nodiscard]] constexpr State state_of(Leaf l) noexcept {
  switch (l) {
    case Leaf::BOOT: return State::BOOT;
    case Leaf::ERROR_LOCKOUT: return State::ERROR_LOCKOUT;
    case Leaf::ESTOP_ACTIVE: return State::ESTOP_ACTIVE;
    case Leaf::ESTOP_RESET_NEEDED: return State::ESTOP_RESET_NEEDED;
    case Leaf::IDLE: return State::IDLE;
    case Leaf::ARMING: return State::ARMING;
    case Leaf::STOPPING_CAT1:
    case Leaf::STOPPING_CAT2: return State::STOPPING;
    default: return State::OPERATIONAL;
  }
}

[[nodiscard]] constexpr Sub sub_of(Leaf l) noexcept {
  switch (l) {
    case Leaf::AUTO_IDLE: return Sub::AUTO_IDLE;
    case Leaf::AUTO_RUNNING: return Sub::AUTO_RUNNING;
    case Leaf::AUTO_PAUSED: return Sub::AUTO_PAUSED;
    case Leaf::MANUAL_IDLE: return Sub::MANUAL_IDLE;
    case Leaf::MANUAL_JOGGING: return Sub::MANUAL_JOGGING;
    case Leaf::MANUAL_RUNNING: return Sub::MANUAL_RUNNING;
    case Leaf::BRAKE_TEST: return Sub::BRAKE_TEST;
    default: return Sub::NONE;
  }
}

[[nodiscard]] constexpr Leaf leaf_of_sub(Sub s) noexcept {
  switch (s) {
    case Sub::AUTO_RUNNING: return Leaf::AUTO_RUNNING;
    case Sub::AUTO_PAUSED: return Leaf::AUTO_PAUSED;
    case Sub::MANUAL_IDLE: return Leaf::MANUAL_IDLE;
    case Sub::MANUAL_JOGGING: return Leaf::MANUAL_JOGGING;
    case Sub::MANUAL_RUNNING: return Leaf::MANUAL_RUNNING;
    case Sub::BRAKE_TEST: return Leaf::BRAKE_TEST;
    default: return Leaf::AUTO_IDLE;
  }
}

// The leaf a variant value stands for (used by the integrity check, which compares it
// with the leaf the manager believes it is in).
[[nodiscard]] Leaf leaf_of(const StateVariant& s) noexcept;

const char* to_string(Leaf l) noexcept;

}  // namespace safestate::core

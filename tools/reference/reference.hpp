// An independent reference implementation of the supervisor, written as plain switch
// code from SPEC.md §3-§5 and docs/decisions.md. It shares only the vocabulary (enums,
// the input/feedback/command structs) with core/, not the transition table, the guards
// or the dispatcher, so that the checker and the fuzzer can compare the two cycle by
// cycle (a differential oracle). Not for production: clarity over speed.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/alarms.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/interfaces.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/types.hpp"

namespace safestate::reference {

struct Out {
  core::State state = core::State::BOOT;
  core::Sub sub = core::Sub::NONE;
  core::StopCat stop = core::StopCat::NONE;
  bool contactor = false;
  bool drives = false;
  bool brakes_release = false;
  bool reset_lamp = false;
  bool fault_reset = false;
  core::AlarmMask alarms = 0;
  std::array<core::Reply, 20> replies{};
  std::uint8_t reply_count = 0;
};

class Supervisor {
 public:
  explicit Supervisor(const core::Timing& t) noexcept : t_(t) {}
  std::size_t step(const core::SafetyInputs& in, const core::Feedback& fb, const core::Command* cmds, std::size_t n,
                   Out& out) noexcept;

 private:
  enum class St : std::uint8_t { BOOT, LOCKOUT, ESTOP, ESTOP_RESET, IDLE, ARMING, OP, STOPPING };

  void conditions(const core::SafetyInputs& in, const core::Feedback& fb, Out& out) noexcept;
  void events(const core::SafetyInputs& in, const core::Feedback& fb) noexcept;
  core::Result command(const core::SafetyInputs& in, const core::Feedback& fb, const core::Command& c,
                       bool& deferred) noexcept;
  void answer(Out& out, std::uint32_t seq, std::uint8_t id, std::uint8_t src, core::Result r) noexcept;
  void go(St s, core::Sub sub = core::Sub::NONE) noexcept;
  void stop_to(core::StopCat cat, St target, core::Sub target_sub) noexcept;
  void cat0_to(St s) noexcept;
  void raise(core::AlarmId a) noexcept;
  void drop(core::AlarmId a) noexcept;
  [[nodiscard]] bool has(core::AlarmId a) const noexcept { return (alarms_ & core::bit(a)) != 0U; }
  [[nodiscard]] bool drives_faulted(const core::Feedback& fb) const noexcept;
  // Judged on the state the cycle began in (every condition that holds raises its alarm).
  [[nodiscard]] bool drive_fault_condition(const core::Feedback& fb, St s0, core::StopCat cat0, int step0) const noexcept;
  [[nodiscard]] bool standstill() const noexcept { return quiet_ >= t_.standstill_cycles; }
  void write(Out& out) const noexcept;

  core::Timing t_;
  St st_ = St::BOOT;
  core::Sub sub_ = core::Sub::NONE;
  core::StopCat stop_cat_ = core::StopCat::NONE;  // while STOPPING
  St stop_target_ = St::IDLE;
  core::Sub stop_target_sub_ = core::Sub::NONE;
  core::Cycle stop_elapsed_ = 0;
  bool braking_ = false;
  core::Cycle brake_elapsed_ = 0;
  int arming_step_ = 0;  // 0 contactor, 1 drives, 2 brakes
  core::Cycle arming_elapsed_ = 0;
  bool cat0_now_ = false;
  bool changed_ = false;  // a condition changed the state this cycle
  core::AlarmMask alarms_ = 0;
  std::array<core::Cycle, core::kAlarmCount> since_{};
  core::Cycle now_ = 0;
  core::Cycle quiet_ = 0;
  core::Cycle last_jog_ = 0;
  bool boot_pending_ = true;
  bool t2_ok_ = false;
  core::Mode armed_mode_ = core::Mode::NONE;
  core::Cycle resettable_since_ = 0;
  bool pending_reset_ = false;
  core::Cycle pending_since_ = 0;
  std::uint32_t pending_seq_ = 0;
  std::uint8_t pending_src_ = 0;
  // SPEC §7 feedback monitoring: last cycle's commands and how long feedback contradicts them.
  bool last_contactor_ = false;
  bool last_brakes_release_ = false;
  core::Cycle welded_for_ = 0;
  std::array<core::Cycle, core::kAxes> brake_for_{};
  bool brake_not_engaged_ = false;
  bool contactor_welded_ = false;
};

}  // namespace safestate::reference

// SystemStateManager: one step per scan cycle (SPEC §1). Conditions first in the
// priority of §4, then internal events, then commands in arrival order; outputs from
// the resulting state, written in the same cycle. Deterministic, no heap, no clock.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/core/alarms.hpp"
#include "safestate/core/brake_test.hpp"
#include "safestate/core/collision.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/interfaces.hpp"
#include "safestate/core/monitor.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/core/safety_status.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/states.hpp"
#include "safestate/core/transitions.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

inline constexpr std::size_t kMaxCommandsPerCycle = 16;  // Config may ask for fewer
// Queued commands, plus a deferred reset answer and the reset button.
inline constexpr std::size_t kMaxRepliesPerCycle = kMaxCommandsPerCycle + 2;
// At most one transition from the conditions or an event, one from the reset button, and
// one per command taken: every one is reported.
inline constexpr std::size_t kMaxTransitionsPerCycle = kMaxCommandsPerCycle + 2;

struct TransitionEvent {
  Leaf from = Leaf::BOOT;
  Leaf to = Leaf::BOOT;
  StopCat stop = StopCat::NONE;
  Trigger trigger = Trigger::boot_passed;
  std::uint8_t row = kNoRow;
};


struct SupervisorOut {
  State state = State::BOOT;
  Sub sub = Sub::NONE;
  Mode mode = Mode::NONE;
  Mode mode_requested = Mode::NONE;  // what the selector contacts say, when it differs
  StopCat stop = StopCat::NONE;      // CAT1/CAT2 in STOPPING; CAT0 in the cycle it happened
  Leaf target = Leaf::SAME;          // in STOPPING: where the stop ends
  // Outputs of SPEC §3, true = energised / closed / released / lit.
  bool contactor = false;
  bool drives_enable = false;
  bool brakes_release = false;
  bool reset_lamp = false;
  MotionRequest motion{};
  ArmingStep arming_step = ArmingStep::CONTACTOR;
  std::uint8_t arming_progress = 0;
  bool t2_confirmed = false;
  bool at_standstill = false;
  // Single point of control (ISO 10218-1 5.3.5): in T1/T2 the pendant alone commands;
  // in AUTO or NONE no station holds control exclusively.
  bool pendant_owner = false;
  Cause cause{};  // first-out cause of the current stop or lockout
  AlarmMask alarms = 0;
  AlarmMask alarms_raised = 0;   // this cycle
  AlarmMask alarms_cleared = 0;  // this cycle
  std::array<Reply, kMaxRepliesPerCycle> replies{};
  std::uint8_t reply_count = 0;
  std::array<TransitionEvent, kMaxTransitionsPerCycle> transitions{};
  std::uint8_t transition_count = 0;
  SafetyStatus safety{};
  // SPEC §12: the axis whose brake the brake test holds engaged (1..6; 0 none) while
  // brakes_release keeps the others released, and the test's status.
  std::uint8_t brake_test_axis = 0;
  BrakeTestStatus brake_test{};
};

// SPEC §5 check order, steps 1-3 (commands.cpp): OK, or the first reject code.
[[nodiscard]] Result check_command(const Command& cmd, Leaf leaf, Mode mode) noexcept;
// The status' SPEC §10/§11 part from one cycle's monitor facts (status.cpp).
void safety_status(const CycleFacts& f, const SafeLimitMonitors& limits, bool validated, const SafetyInputs& in,
                   SafetyStatus& st) noexcept;

// A second, independent reading of the safety outputs (output_check.cpp): false when they
// contradict the state (power outside the powered states or with the E-stop pressed,
// motion the state does not allow, state data of another state).
[[nodiscard]] bool outputs_consistent(const SupervisorOut& o, Leaf leaf, const StateVariant& state,
                                      bool estop_pressed) noexcept;

class SystemStateManager {
  // SPEC §14 `channel X flip FIELD`: the simulator's probe of named variables (sim/src/flip.cpp).
  friend struct FieldProbe;

 public:
  explicit SystemStateManager(const Timing& timing) noexcept;

  // SPEC §10, before the first cycle: the safe limits to monitor, the arm they are
  // measured on, and whether the event log already holds a confirmation of this
  // checksum. Without it no safe limit is monitored (the state machine alone).
  void configure_limits(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us,
                        bool validated) noexcept;
  // Before the first cycle, without limits: the arm whose TCP (in the flange frame) and
  // link origins the T1 speed monitor watches, through the core's own kinematics
  // (configure_limits sets it with the limits' TCP). Without an arm the T1 speed is unknown:
  // motion armed in T1 stops at once (unknown is unsafe).
  void configure_arm(const ArmGeometry& arm, const Vec3& tcp_flange_mm) noexcept {
    limits_.configure_arm(arm, tcp_flange_mm);
  }
  [[nodiscard]] const SafeLimitMonitors& limit_monitors() const noexcept { return limits_; }
  [[nodiscard]] bool config_validated() const noexcept { return config_validated_; }
  // SPEC §12, before the first cycle (after configure_limits): what the event log says
  // about the last brake test. Without it: none on record.
  void configure_brake_test(const BrakeTestHistory& history) noexcept { brake_test_.set_history(history); }
  [[nodiscard]] const BrakeTest& brake_test() const noexcept { return brake_test_; }

  // One scan cycle. Takes at most `max_commands_per_cycle` of `cmds` (the caller keeps
  // the rest queued) and returns how many it took.
  std::size_t step(const SafetyInputs& in, const Feedback& fb, const Command* cmds, std::size_t n,
                   SupervisorOut& out) noexcept;

  [[nodiscard]] Leaf leaf() const noexcept { return leaf_; }
  [[nodiscard]] State state() const noexcept { return state_of(leaf_); }
  [[nodiscard]] const StateVariant& variant() const noexcept { return state_; }
  [[nodiscard]] const AlarmSet& alarms() const noexcept { return alarms_; }
  [[nodiscard]] Cycle now() const noexcept { return now_; }
  [[nodiscard]] bool t2_confirmed() const noexcept { return t2_confirmed_; }
  [[nodiscard]] bool boot_pending() const noexcept { return boot_pending_; }
  [[nodiscard]] const Timing& timing() const noexcept { return timing_; }

 private:
  struct CycleCtx;  // per-cycle scratch, defined in supervisor.cpp

  void advance_state_timers() noexcept;
  void run_monitors(CycleCtx& c) noexcept;
  bool evaluate_conditions(CycleCtx& c) noexcept;
  void evaluate_events(CycleCtx& c) noexcept;
  void finish_pending_reset(CycleCtx& c) noexcept;
  void handle_reset_button(CycleCtx& c) noexcept;
  Result dispatch_command(CycleCtx& c, const Command& cmd) noexcept;
  Result apply(CycleCtx& c, const Transition& row, const Cause& cause, const Command* cmd) noexcept;
  void enter(CycleCtx& c, Leaf to) noexcept;
  void clear_latched() noexcept;
  void set_cause(const Cause& cause) noexcept;
  void reply(CycleCtx& c, std::uint32_t seq, std::uint8_t id, std::uint8_t src, Result r) noexcept;
  void write_outputs(CycleCtx& c) noexcept;
  [[nodiscard]] GuardView view(const CycleCtx& c, std::uint32_t code = 0U) const noexcept;

  Timing timing_;
  StateVariant state_{StBoot{}};
  Leaf leaf_ = Leaf::BOOT;
  AlarmSet alarms_;
  Cause cause_{};
  Cycle now_ = 0;
  bool self_test_ok_ = false;
  bool boot_pending_ = true;
  bool integrity_fault_ = false;
  bool t2_confirmed_ = false;
  Mode armed_mode_ = Mode::NONE;  // the mode in which servo_on was accepted
  Cycle last_jog_ = 0;
  JogTarget jog_{};
  Cycle reset_possible_since_ = 0;
  // A `reset` waiting for the drives to answer their fault reset (SPEC §5).
  bool reset_pending_ = false;
  Cycle reset_pending_since_ = 0;
  std::uint32_t reset_seq_ = 0;
  std::uint8_t reset_source_ = 0;
  Commanded last_{};  // what this core commanded last cycle (external device monitoring)
  bool config_validated_ = true;
  // SPEC §11: whether the current pause (or the Cat 2 stop leading to it) came from rule 9,
  // so that it may resume by itself.
  bool field_paused_ = false;

  Reporter rep_;  // begun every cycle
  // The monitors (monitor.hpp), in the order run_monitors() runs them.
  StandstillMonitor standstill_;
  EstopMonitor estop_;
  GateMonitor gate_;
  EnablingMonitor enabling_;
  ModeMonitor mode_;
  ResetButtonMonitor reset_button_;
  ConfigValidationMonitor config_;
  FieldMonitor fields_;
  SafeLimitMonitors limits_;
  SsmMonitor ssm_;
  CollisionMonitor collision_;
  BrakeTest brake_test_;  // SPEC §12: a sequence, and the monitor of its result
  DriveMonitor drives_;
  ContactorMonitor contactor_;
  BrakeFeedbackMonitor brakes_;
  BootMonitor boot_;
  FieldbusMonitor fieldbus_;
  IntegrityMonitor integrity_;
  T1SpeedMonitor t1_speed_;
  StopTimeMonitor stop_time_;
  JogLinkMonitor jog_link_;
  ChannelMonitor channel_;
  EncoderMonitor encoders_;
  SafetyLinkMonitor links_;
};

// The whole supervisor of DESIGN.md: signal layer + state manager, one call per cycle.
class Supervisor {
  // SPEC §14 `channel X flip FIELD`: the simulator's probe of named variables (sim/src/flip.cpp).
  friend struct FieldProbe;

 public:
  explicit Supervisor(const Timing& t) noexcept : timing_(t), ssm_(t) {}
  std::size_t step(const RawInputs& raw, const Feedback& fb, const Command* cmds, std::size_t n,
                   SupervisorOut& out) noexcept {
    signals_.update(raw, ssm_.now(), timing_);
    return ssm_.step(signals_.inputs(), fb, cmds, n, out);
  }
  [[nodiscard]] const SafetyInputs& inputs() const noexcept { return signals_.inputs(); }
  [[nodiscard]] const SystemStateManager& manager() const noexcept { return ssm_; }
  void configure_limits(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us,
                        bool validated) noexcept {
    ssm_.configure_limits(limits, arm, cycle_us, validated);
  }
  void configure_arm(const ArmGeometry& arm, const Vec3& tcp_flange_mm) noexcept {
    ssm_.configure_arm(arm, tcp_flange_mm);
  }
  void configure_brake_test(const BrakeTestHistory& history) noexcept { ssm_.configure_brake_test(history); }

 private:
  Timing timing_;
  SignalLayer signals_;
  SystemStateManager ssm_;
};

}  // namespace safestate::core

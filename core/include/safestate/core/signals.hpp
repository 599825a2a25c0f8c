// Signal layer (SPEC §2): turns raw contacts into validated logical inputs.
// Each input is a small type with an update() per cycle and no knowledge of the state
// machine, so each can be tested alone, cycle by cycle.
#pragma once

#include <cstdint>

#include "safestate/core/config.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

// ISO 13849-1 Cat. 3 dual-channel input with PLCopen SF_Equivalent behaviour.
// `a`/`b` are the raw contacts, true = the non-safe value (E-stop circuit closed,
// guard closed, enabling centre contact made).
class DualChannel {
  // SPEC §14 `channel X flip FIELD`: the simulator's probe of named variables (sim/src/flip.cpp).
  friend struct FieldProbe;

 public:
  // `limit`: discrepancy time in cycles; a disagreement lasting more than `limit`
  // cycles is a discrepancy fault, which latches until power cycle.
  void update(bool a, bool b, Cycle limit) noexcept;

  // Logical value: true = non-safe (healthy). Safe in the very cycle either channel
  // demands it. Leaving the safe value needs both channels, and once a channel has
  // dropped, both must have been seen safe together before it counts again (PLCopen
  // SF_Equivalent): a channel that blinks never re-enables. Contacts that close one
  // after the other from the safe value (within the discrepancy time) are normal.
  [[nodiscard]] bool active() const noexcept { return active_; }
  [[nodiscard]] bool discrepancy() const noexcept { return fault_; }
  // The channel(s) that demanded the safe value when the input last went safe.
  [[nodiscard]] Channel cause() const noexcept { return cause_; }
  // Which channel disagreed when the discrepancy fault fired (the one in the safe value).
  [[nodiscard]] Channel fault_channel() const noexcept { return fault_channel_; }
  [[nodiscard]] Cycle disagree_cycles() const noexcept { return disagree_; }
  // True in the cycle the logical value went from non-safe to safe.
  [[nodiscard]] bool fell() const noexcept { return fell_; }

 private:
  bool active_ = false;
  bool armed_ = true;  // both channels seen safe together since the last drop
  bool fault_ = false;
  bool fell_ = false;
  bool seen_ = false;
  Channel cause_ = Channel::none;
  Channel fault_channel_ = Channel::none;
  Cycle disagree_ = 0;
};

// 3-position enabling device (IEC 60204-1 10.9, ISO 10218-1 5.8.3, PLCopen SF_EnableSwitch).
enum class EnablePos : std::uint8_t { released, centre, panic };

class EnablingDevice {
 public:
  // `manual_entered`: the effective mode became T1 or T2 in this cycle.
  void update(bool a, bool b, bool panic, bool manual_entered, Cycle limit) noexcept;

  [[nodiscard]] EnablePos position() const noexcept { return pos_; }
  // At centre *and* reached through released since the last panic or the last time the
  // mode became manual. Only this enables motion.
  [[nodiscard]] bool enabled() const noexcept { return enabled_; }
  [[nodiscard]] bool discrepancy() const noexcept { return centre_.discrepancy(); }
  [[nodiscard]] Channel fault_channel() const noexcept { return centre_.fault_channel(); }
  // The centre contact that dropped first (the cause of a release).
  [[nodiscard]] Channel cause() const noexcept { return centre_.cause(); }
  [[nodiscard]] bool panic_edge() const noexcept { return panic_edge_; }
  // True while a return to centre would not count until the device is released.
  [[nodiscard]] bool needs_release() const noexcept { return need_release_; }

 private:
  DualChannel centre_;
  EnablePos pos_ = EnablePos::released;
  bool enabled_ = false;
  bool need_release_ = true;  // a device held at power-up does not count
  bool panic_prev_ = false;
  bool panic_edge_ = false;
};

// Key-switch mode selector, one-hot contacts (ISO 10218-1 5.7).
class ModeSelector {
 public:
  void update(bool auto_contact, bool t1_contact, bool t2_contact, Cycle limit) noexcept;

  [[nodiscard]] Mode mode() const noexcept { return mode_; }
  // What the contacts say right now (NONE when not exactly one is closed).
  [[nodiscard]] Mode requested() const noexcept { return requested_; }
  [[nodiscard]] bool changed() const noexcept { return changed_; }
  [[nodiscard]] Mode previous() const noexcept { return previous_; }
  // None or several contacts closed for more than the limit: MODE_SELECTOR_INVALID.
  [[nodiscard]] bool invalid() const noexcept { return invalid_; }

 private:
  Mode mode_ = Mode::NONE;
  Mode requested_ = Mode::NONE;
  Mode previous_ = Mode::NONE;
  bool changed_ = false;
  bool invalid_ = false;
  Cycle bad_cycles_ = 0;
};

// Reset push-button (ISO 13849-1 5.2.2): acts on release, only for a fresh press.
class ResetButton {
 public:
  void update(bool pressed, Cycle now, Cycle hold_limit) noexcept;

  // True in the cycle the button was released after a press no longer than the limit.
  [[nodiscard]] bool released_edge() const noexcept { return released_edge_; }
  // Cycle at which the press that just ended (or is going on) began.
  [[nodiscard]] Cycle press_start() const noexcept { return press_start_; }
  // Held longer than the limit: RESET_BUTTON_STUCK while held.
  [[nodiscard]] bool stuck() const noexcept { return stuck_; }
  [[nodiscard]] bool pressed() const noexcept { return pressed_; }

 private:
  bool pressed_ = false;  // held at power-up: a press that began before reset was possible
  bool too_long_ = false;
  bool stuck_ = false;
  bool released_edge_ = false;
  Cycle press_start_ = 0;
  Cycle held_ = 0;
};

// Raw process image of the safety inputs (SPEC §2), one field per contact.
struct RawInputs {
  bool estop_a = true;
  bool estop_b = true;
  bool gate_a = true;
  bool gate_b = true;
  bool enable_a = false;
  bool enable_b = false;
  bool enable_panic = false;
  bool mode_auto = true;
  bool mode_t1 = false;
  bool mode_t2 = false;
  bool reset_button = false;
  // SPEC §10 reduced-speed request, NC (1 = normal speed).
  bool reduced_a = true;
  bool reduced_b = true;
  // SPEC §11 protective fields of the area scanner, OSSD pairs, NC (1 = clear).
  bool field_outer_a = true;
  bool field_outer_b = true;
  bool field_inner_a = true;
  bool field_inner_b = true;
  // SPEC §11 distance sensor: the separation person-robot (mm) and whether it is valid.
  // Without a sensor (the default) the separation is invalid: unknown is unsafe.
  std::int32_t separation_mm = 0;
  bool separation_valid = false;
};

// The validated logical inputs the state machine decides on.
struct SafetyInputs {
  bool estop_pressed = true;
  Channel estop_cause = Channel::none;
  bool estop_discrepancy = false;
  Channel estop_fault_channel = Channel::none;
  bool gate_open = true;
  Channel gate_cause = Channel::none;
  bool gate_discrepancy = false;
  Channel gate_fault_channel = Channel::none;
  EnablePos enable = EnablePos::released;
  bool enable_ok = false;  // centre, reached through released
  bool enable_panic_edge = false;
  bool enable_discrepancy = false;
  Channel enable_fault_channel = Channel::none;
  Channel enable_cause = Channel::none;  // the centre contact that dropped first
  Mode mode = Mode::NONE;
  Mode mode_requested = Mode::NONE;
  bool mode_changed = false;
  bool mode_invalid = false;
  bool reset_released = false;   // falling edge of a press no longer than the limit
  Cycle reset_press_start = 0;
  bool reset_stuck = false;
  // SPEC §10: reduced speed asked for (safe on either channel). A discrepancy keeps it
  // asked for and is no lockout: reduced is the safe side.
  bool reduced_requested = false;
  bool reduced_discrepancy = false;
  // SPEC §11: the protective fields, validated like `gate` (interrupted on either channel;
  // a discrepancy is FIELD_DISCREPANCY, lockout), and the separation: an invalid or
  // negative reading counts as 0 (unknown is unsafe).
  bool field_outer_interrupted = false;
  Channel field_outer_cause = Channel::none;
  bool field_outer_discrepancy = false;
  Channel field_outer_fault_channel = Channel::none;
  bool field_inner_interrupted = false;
  Channel field_inner_cause = Channel::none;
  bool field_inner_discrepancy = false;
  Channel field_inner_fault_channel = Channel::none;
  float separation_mm = 0.0F;
};

// All inputs of §2 together; owns the per-input validators.
class SignalLayer {
  // SPEC §14 `channel X flip FIELD`: the simulator's probe of named variables (sim/src/flip.cpp).
  friend struct FieldProbe;

 public:
  void update(const RawInputs& raw, Cycle now, const Timing& t) noexcept;
  [[nodiscard]] const SafetyInputs& inputs() const noexcept { return out_; }

 private:
  DualChannel estop_;
  DualChannel gate_;
  EnablingDevice enable_;
  ModeSelector mode_;
  ResetButton reset_;
  DualChannel reduced_;
  DualChannel field_outer_;
  DualChannel field_inner_;
  SafetyInputs out_;
};

}  // namespace safestate::core

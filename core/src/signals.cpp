#include "safestate/core/signals.hpp"

namespace safestate::core {

namespace {
Channel which_dropped(bool a, bool b) noexcept {
  if (!a && !b) {
    return Channel::both;
  }
  return a ? Channel::b : Channel::a;
}
}  // namespace

// @req IN-SAFE-EITHER IN-DISCREPANCY IN-EQUIVALENT
void DualChannel::update(bool a, bool b, Cycle limit) noexcept {
  const bool was_active = active_;
  if (a != b) {
    ++disagree_;
    if ((disagree_ > limit) && !fault_) {
      fault_ = true;
      fault_channel_ = which_dropped(a, b);
    }
  } else {
    disagree_ = 0;
  }
  if (was_active && !(a && b)) {
    armed_ = false;  // a channel dropped: both must be seen safe before it counts again
  }
  if (!a && !b) {
    armed_ = true;
  }
  active_ = a && b && armed_ && !fault_;
  fell_ = was_active && !active_;
  if (fell_ || (!seen_ && !active_)) {
    cause_ = which_dropped(a, b);
  }
  seen_ = true;
}

// @req IN-ENABLE-DECODE IN-ENABLE-PANIC IN-ENABLE-MODE
void EnablingDevice::update(bool a, bool b, bool panic, bool manual_entered, Cycle limit) noexcept {
  centre_.update(a, b, limit);
  panic_edge_ = panic && !panic_prev_;
  panic_prev_ = panic;
  const bool released = !a && !b && !panic;
  if (released) {
    need_release_ = false;
  }
  // IEC 60204-1 10.9: from panic back to centre does not enable; PLCopen
  // SF_EnableSwitch: a device already held when the mode becomes manual does not count.
  if (panic || (manual_entered && !released)) {
    need_release_ = true;
  }
  if (panic) {
    pos_ = EnablePos::panic;
  } else if (centre_.active()) {
    pos_ = EnablePos::centre;
  } else {
    pos_ = EnablePos::released;
  }
  enabled_ = (pos_ == EnablePos::centre) && !need_release_;
}

// @req IN-MODE-DECODE IN-MODE-INVALID
void ModeSelector::update(bool auto_contact, bool t1_contact, bool t2_contact, Cycle limit) noexcept {
  const int closed = static_cast<int>(auto_contact) + static_cast<int>(t1_contact) + static_cast<int>(t2_contact);
  requested_ = Mode::NONE;
  if (closed == 1) {
    requested_ = auto_contact ? Mode::AUTO : (t1_contact ? Mode::T1 : Mode::T2);
  }
  previous_ = mode_;
  if (requested_ != Mode::NONE) {
    mode_ = requested_;
    bad_cycles_ = 0;
    invalid_ = false;
  } else {
    ++bad_cycles_;
    // A key switch breaks before it makes: the last valid mode holds for the limit.
    if (bad_cycles_ > limit) {
      mode_ = Mode::NONE;
      invalid_ = true;
    }
  }
  changed_ = mode_ != previous_;
}

// @req IN-RESET-EDGE IN-RESET-FRESH
void ResetButton::update(bool pressed, Cycle now, Cycle hold_limit) noexcept {
  released_edge_ = false;
  if (pressed && !pressed_) {
    press_start_ = now;
    held_ = 0;
    too_long_ = false;
  }
  if (pressed) {
    ++held_;
    if (held_ > hold_limit) {
      too_long_ = true;
    }
  } else if (pressed_) {
    released_edge_ = !too_long_;
  }
  stuck_ = pressed && too_long_;
  pressed_ = pressed;
}

void SignalLayer::update(const RawInputs& raw, Cycle now, const Timing& t) noexcept {
  mode_.update(raw.mode_auto, raw.mode_t1, raw.mode_t2, t.discrepancy);
  const bool manual_entered = mode_.changed() && ((mode_.mode() == Mode::T1) || (mode_.mode() == Mode::T2));
  estop_.update(raw.estop_a, raw.estop_b, t.discrepancy);
  gate_.update(raw.gate_a, raw.gate_b, t.discrepancy);
  enable_.update(raw.enable_a, raw.enable_b, raw.enable_panic, manual_entered, t.discrepancy);
  reset_.update(raw.reset_button, now, t.reset_hold_max);
  reduced_.update(raw.reduced_a, raw.reduced_b, t.discrepancy);
  field_outer_.update(raw.field_outer_a, raw.field_outer_b, t.discrepancy);
  field_inner_.update(raw.field_inner_a, raw.field_inner_b, t.discrepancy);

  out_.estop_pressed = !estop_.active();
  out_.estop_cause = estop_.cause();
  out_.estop_discrepancy = estop_.discrepancy();
  out_.estop_fault_channel = estop_.fault_channel();
  out_.gate_open = !gate_.active();
  out_.gate_cause = gate_.cause();
  out_.gate_discrepancy = gate_.discrepancy();
  out_.gate_fault_channel = gate_.fault_channel();
  out_.enable = enable_.position();
  out_.enable_ok = enable_.enabled();
  out_.enable_panic_edge = enable_.panic_edge();
  out_.enable_discrepancy = enable_.discrepancy();
  out_.enable_fault_channel = enable_.fault_channel();
  out_.enable_cause = enable_.cause();
  out_.mode = mode_.mode();
  out_.mode_requested = mode_.requested();
  out_.mode_changed = mode_.changed();
  out_.mode_invalid = mode_.invalid();
  out_.reset_released = reset_.released_edge();
  out_.reset_press_start = reset_.press_start();
  out_.reset_stuck = reset_.stuck();
  out_.reduced_requested = !reduced_.active();
  out_.reduced_discrepancy = reduced_.discrepancy();
  // @req COL-FIELDS
  out_.field_outer_interrupted = !field_outer_.active();
  out_.field_outer_cause = field_outer_.cause();
  out_.field_outer_discrepancy = field_outer_.discrepancy();
  out_.field_outer_fault_channel = field_outer_.fault_channel();
  out_.field_inner_interrupted = !field_inner_.active();
  out_.field_inner_cause = field_inner_.cause();
  out_.field_inner_discrepancy = field_inner_.discrepancy();
  out_.field_inner_fault_channel = field_inner_.fault_channel();
  // @req COL-SSM-INPUT
  out_.separation_mm = (raw.separation_valid && (raw.separation_mm >= 0)) ? static_cast<float>(raw.separation_mm) : 0.0F;
}

}  // namespace safestate::core

// Reference supervisor: SPEC.md §3-§5 as one switch per concern, read top to bottom.
#include "reference.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "safestate/core/cia402.hpp"
#include "safestate/core/monitors.hpp"  // the recovery tolerances kWorse* (vocabulary), nothing else

namespace safestate::reference {

using core::AlarmId;
using core::CommandId;
using core::Mode;
using core::Result;
using core::StopCat;
using core::Sub;
namespace c402 = core::cia402;

namespace {
bool manual(Mode m) { return m == Mode::T1 || m == Mode::T2; }
}  // namespace

void Supervisor::raise(AlarmId a) noexcept {
  if (!has(a)) {
    alarms_ |= core::bit(a);
    since_[static_cast<std::size_t>(a)] = now_;
  }
}

void Supervisor::drop(AlarmId a) noexcept { alarms_ &= ~core::bit(a); }

bool Supervisor::drives_faulted(const core::Feedback& fb) const noexcept {
  for (const core::DriveFeedback& d : fb.drive) {
    if (d.online && c402::is_fault(c402::decode(d.statusword))) {
      return true;
    }
  }
  return false;
}

bool Supervisor::drive_fault_condition(const core::Feedback& fb, St s0, StopCat cat0, int step0) const noexcept {
  const bool expect_enabled = s0 == St::OP || s0 == St::STOPPING || (s0 == St::ARMING && step0 == 2);
  for (const core::DriveFeedback& d : fb.drive) {
    if (!d.online) {
      continue;
    }
    const c402::DriveState ds = c402::decode(d.statusword);
    if (c402::is_fault(ds)) {
      return true;
    }
    const bool commanded_quick_stop =
        s0 == St::STOPPING && cat0 == StopCat::CAT1 && ds == c402::DriveState::QuickStopActive;
    if (expect_enabled && ds != c402::DriveState::OperationEnabled && !commanded_quick_stop) {
      return true;
    }
  }
  return expect_enabled && fb.following_error_axis != 0U;
}

void Supervisor::go(St s, Sub sub) noexcept {
  const bool resettable_before = st_ == St::ESTOP_RESET || st_ == St::IDLE;
  const bool resettable_after = s == St::ESTOP_RESET || s == St::IDLE;
  if (resettable_after && !resettable_before) {
    resettable_since_ = now_;
  }
  if (pending_reset_ && s != St::IDLE) {
    pending_reset_ = false;
    // answered by the caller through `leave_answer_`: see step()
  }
  st_ = s;
  sub_ = (s == St::OP) ? sub : Sub::NONE;
  if (!(s == St::OP && sub == Sub::AUTO_PAUSED)) field_paused_ = false;  // only a rule 9 pause resumes itself
}

void Supervisor::cat0_to(St s) noexcept {
  if (s != st_) {
    cat0_now_ = true;
  }
  go(s);
}

void Supervisor::stop_to(StopCat cat, St target, Sub target_sub) noexcept {
  if (st_ != St::STOPPING) {
    stop_elapsed_ = 0;
  }
  back_off_ = false;  // rule 8 sets it after; any other stop (an escalation) has none
  braking_ = false;
  brake_elapsed_ = 0;
  stop_cat_ = cat;
  stop_target_ = target;
  stop_target_sub_ = target_sub;
  st_ = St::STOPPING;
  sub_ = Sub::NONE;
}

void Supervisor::answer(Out& out, std::uint32_t seq, std::uint8_t id, std::uint8_t src, Result r) noexcept {
  if (out.reply_count < out.replies.size()) {
    out.replies[out.reply_count++] = core::Reply{seq, id, src, r};
  }
  if (r == Result::OK) {  // until the next command answered OK
    for (AlarmId a : {AlarmId::MODE_CHANGED, AlarmId::ENABLING_PANIC, AlarmId::JOG_LINK_LOST}) {
      if (has(a) && since_[static_cast<std::size_t>(a)] < now_) {
        drop(a);
      }
    }
  }
}

bool Supervisor::trips(Track& t, float outside, bool powered, float tolerance) noexcept {
  const bool nan = outside != outside;
  const bool out = nan || outside > 0.0F;
  if (!powered) {  // found without power: nothing trips, remember it for recovery (SPEC §10)
    t.recovering = out;
    t.best = outside;
    return false;
  }
  if (!out) {
    t.recovering = false;
    return false;
  }
  if (!t.recovering) {
    return true;  // newly violated with power on
  }
  const bool worse = nan || (t.best != t.best) || outside > t.best + tolerance;
  if (worse) {
    return true;  // recovery lets only motion that does not make it worse
  }
  if (outside < t.best) {
    t.best = outside;
  }
  return false;
}

// SPEC §4 rule 3, ISO 10218-1 5.7.3: how fast the fastest of the TCP and the link origins
// went between the last two samples of the measured positions. A cycle whose frame brought
// no new sample (stale, or the drives' clock says it is the same sample again) keeps the
// last speed; a new one is compared with the last over the cycles between them (the drives'
// count when their clock gives one). No kinematics, or a point not finite: unknown, too fast.
void Supervisor::t1_speed(const core::Feedback& fb, const Geometry& g) noexcept {
  if (!g.arm) {
    t1_have_last_ = false;
    t1_speed_ = HUGE_VALF;
    return;
  }
  ++t1_cycles_;
  const bool repeat = fb.stale || (fb.sample_clock && fb.sample_span == 0U);
  if (t1_have_last_ && repeat) {
    return;
  }
  float fastest = 0.0F;
  if (t1_have_last_) {
    const core::Cycle over = (fb.sample_clock && fb.sample_span != 0U) ? core::Cycle{fb.sample_span} : t1_cycles_;
    for (std::size_t k = 0; k < kT1Points; ++k) {
      float sq = 0.0F;
      for (std::size_t a = 0; a < 3; ++a) {
        const float d = g.t1_points[k][a] - t1_last_[k][a];
        sq += d * d;
      }
      const float v = std::sqrt(sq) * t_.cycles_per_s / static_cast<float>(over);
      if (!std::isfinite(v) || v > fastest) {
        fastest = std::isfinite(v) ? v : HUGE_VALF;
      }
    }
  }
  t1_speed_ = fastest;
  t1_last_ = g.t1_points;
  t1_have_last_ = true;
  t1_cycles_ = 0;
}

void Supervisor::judge_limits(const core::SafetyInputs& in, const core::Feedback& fb, const Geometry& g) noexcept {
  joint_hit_ = zone_hit_ = orientation_hit_ = speed_hit_ = speed_over_ = outside_ = false;
  // SPEC §11 collision: the arm held by its drives, brakes released, no brake test pushing.
  const bool arm_free = (st_ == St::OP && sub_ != Sub::BRAKE_TEST) ||
                        (st_ == St::STOPPING && stop_cat_ == StopCat::CAT2);
  const bool over = lim_.configured && lim_.pfl && arm_free && !(g.contact_force_n <= lim_.f_qs_n);
  collision_over_ = over ? collision_over_ + 1 : 0;
  collision_now_ = collision_over_ >= 2;
  if (!lim_.configured) {
    return;
  }
  const bool powered = st_ == St::ARMING || st_ == St::OP || st_ == St::STOPPING;
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    const float q = fb.drive[i].position_rad;
    float o = lim_.min_rad[i] - q;
    if (q - lim_.max_rad[i] > o) o = q - lim_.max_rad[i];
    if (q != q) o = q;  // unknown is outside
    outside_ = outside_ || !(o <= 0.0F);
    joint_hit_ = trips(joint_track_[i], o, powered, core::kWorseJointRad) || joint_hit_;
  }
  for (std::size_t k = 0; k < g.zones && k < core::kMaxZones; ++k) {
    outside_ = outside_ || !(g.zone_outside[k] <= 0.0F);
    zone_hit_ = trips(zone_track_[k], g.zone_outside[k], powered, core::kWorseZoneMm) || zone_hit_;
  }
  if (g.orientation) {
    outside_ = outside_ || !(g.orientation_outside <= 0.0F);
    orientation_hit_ = trips(orientation_track_, g.orientation_outside, powered, core::kWorseOrientationCos);
  }
  // Reduced mode: active while the TCP is in a reduced zone, the input asks or (SPEC §11)
  // the outer field is interrupted; the reduced TCP limit applies once `ramp` cycles have
  // passed since it became active, or since a source that reduces further joined.
  const bool by_field = collab_acts(in) && in.field_outer_interrupted;
  const bool reduced_now = g.in_reduced_zone || in.reduced_requested || by_field;
  float red = lim_.reduced_tcp_max_mm_s;
  if (by_field && lim_.field_reduced_mm_s < red) red = lim_.field_reduced_mm_s;
  if (reduced_now && (!reduced_ || red < reduced_limit_)) reduced_since_ = now_;
  reduced_ = reduced_now;
  reduced_limit_ = red;
  const bool enforced = reduced_ && (now_ - reduced_since_ > lim_.ramp);
  const float tcp_limit = enforced ? red : lim_.tcp_max_mm_s;
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    const float v = fb.drive[i].velocity_rad_s;
    speed_over_ = speed_over_ || !((v < 0.0F ? -v : v) <= lim_.max_speed_rad_s[i]);
  }
  speed_over_ = speed_over_ || !(g.tcp_speed_mm_s <= tcp_limit);
  speed_hit_ = powered && speed_over_;
  // SPEC §11 SSM: the separation believed falls at once and rises at rise_mm a cycle at most;
  // over v_allowed + 5 % for more than T_r cycles with power on trips (rule 3).
  separation_ = (in.separation_mm < separation_ + lim_.rise_mm) ? in.separation_mm : separation_ + lim_.rise_mm;
  ssm_over_now_ = false;
  ssm_hit_ = false;
  if (lim_.ssm && collab_acts(in)) {
    const float v = core::ssm_allowed_speed_mm_s(separation_, lim_.ssm_params, tcp_limit);
    ssm_over_now_ = !(g.tcp_speed_mm_s <= v * 1.05F);
    ssm_over_ = ssm_over_now_ ? ssm_over_ + 1U : 0U;
    ssm_hit_ = powered && ssm_over_ > lim_.reaction;
  } else {
    ssm_over_ = 0;
  }
}

bool Supervisor::bt_due() const noexcept {
  return lim_.bt_required && (!bt_passed_ever_ || static_cast<std::int64_t>(now_) - bt_pass_at_ > lim_.bt_interval);
}

bool Supervisor::bt_needed() const noexcept {
  if (bt_failed_) return true;
  return lim_.bt_required && (!bt_passed_ever_ || static_cast<std::int64_t>(now_) - bt_pass_at_ > lim_.bt_overdue);
}

// SPEC §12, read as a list: for axis 1..6, engage its brake (wait for the feedback to say so
// for brake_confirm cycles, take the position), push hold cycles one way and hold cycles the
// other (drift above max_drift_deg fails), release (the feedback must say so within the
// brake time, else it fails too). All six: a pass.
void Supervisor::brake_test(const core::Feedback& fb) noexcept {
  bt_pass_now_ = bt_fail_now_ = false;
  bt_out_axis_ = 0;
  if (!(st_ == St::OP && sub_ == Sub::BRAKE_TEST)) {
    bt_on_ = false;
    return;
  }
  if (!bt_on_) return;
  const auto a = static_cast<std::size_t>(bt_axis_);
  const bool released = fb.brake_released[a];
  const float q = fb.drive[a].position_rad;
  ++bt_n_;
  bool next = false;
  if (bt_phase_ == 0) {
    bt_held_ = released ? 0U : bt_held_ + 1U;
    next = bt_held_ >= t_.brake_confirm;
    if (next) bt_q0_ = q;
  } else if (bt_phase_ == 1 || bt_phase_ == 2) {
    const float d = (q > bt_q0_ ? q - bt_q0_ : bt_q0_ - q) * (180.0F / 3.14159265358979F);
    if (!(d <= bt_drift_)) bt_drift_ = d;
    bt_fail_now_ = !(d <= lim_.bt_max_drift_deg);
    next = bt_n_ >= lim_.bt_hold;
  } else {
    next = released;
    bt_fail_now_ = !released && bt_n_ > t_.brakes_timeout;
  }
  if (bt_fail_now_) {
    bt_on_ = false;
    bt_failed_ = true;
    return;
  }
  bt_out_axis_ = (bt_phase_ != 3) ? static_cast<std::uint8_t>(bt_axis_ + 1) : std::uint8_t{0U};
  if (!next) return;
  bt_n_ = 0;
  bt_held_ = 0;
  if (++bt_phase_ < 4) return;
  bt_phase_ = 0;
  bt_drift_ = 0.0F;
  if (++bt_axis_ < static_cast<int>(core::kAxes)) return;
  bt_on_ = false;
  bt_pass_now_ = true;
  bt_failed_ = false;
  bt_passed_ever_ = true;
  bt_pass_at_ = static_cast<std::int64_t>(now_);
}

void Supervisor::conditions(const core::SafetyInputs& in, const core::Feedback& fb, Out& out) noexcept {
  static_cast<void>(out);
  const St s0 = st_;
  const Sub sub0 = sub_;
  const StopCat cat_at_start = stop_cat_;
  const int step_at_start = arming_step_;
  const bool ramping_at_start = !braking_;  // still ramping (not yet braking) when the cycle began
  const core::Cycle stop_elapsed_at_start = stop_elapsed_;
  const bool op_or_cat2 = s0 == St::OP || (s0 == St::STOPPING && stop_cat_ == StopCat::CAT2);
  bool done = false;

  // Rule 1: lockout, from any state.
  bool r1 = false;
  if (in.estop_discrepancy) { raise(AlarmId::ESTOP_DISCREPANCY); r1 = true; }
  if (in.gate_discrepancy) { raise(AlarmId::GATE_DISCREPANCY); r1 = true; }
  if (in.enable_discrepancy) { raise(AlarmId::ENABLE_DISCREPANCY); r1 = true; }
  if (in.field_outer_discrepancy || in.field_inner_discrepancy) { raise(AlarmId::FIELD_DISCREPANCY); r1 = true; }
  bool offline = false;
  for (const core::DriveFeedback& d : fb.drive) offline = offline || !d.online;
  if (!boot_pending_ && (!fb.fieldbus_ok || offline)) { raise(AlarmId::FIELDBUS_LOST); r1 = true; }
  if (!fb.integrity_ok) { raise(AlarmId::INTEGRITY_FAULT); r1 = true; }
  if (boot_pending_ && (now_ > t_.boot_timeout || !fb.self_test_ok || fb.fieldbus_boot_failed)) { raise(AlarmId::BOOT_FAILED); r1 = true; }
  if (contactor_welded_) { raise(AlarmId::CONTACTOR_WELDED); r1 = true; }
  if (channel_mismatch_) { raise(AlarmId::CHANNEL_MISMATCH); r1 = true; }
  if (channel_lost_) { raise(AlarmId::CHANNEL_LOST); r1 = true; }
  if (encoder_bad_) { raise(AlarmId::ENCODER_DISCREPANCY); r1 = true; }
  if (fb.link.configured && fb.link.fault) { raise(AlarmId::SAFETY_LINK_FAULT); r1 = true; }
  if (r1) {
    done = true;
    cat0_to(St::LOCKOUT);
  }

  // Rule 2: E-stop, from any state but lockout.
  if (s0 != St::LOCKOUT && in.estop_pressed) {
    raise(AlarmId::ESTOP_PRESSED);
    if (!done) {
      done = true;
      cat0_to(St::ESTOP);
    }
  }

  const bool powered = s0 == St::ARMING || s0 == St::OP || s0 == St::STOPPING;
  // Rule 3: drive fault, T1 speed, stop time.
  if (powered) {
    bool r3 = false;
    if (drive_fault_condition(fb, s0, cat_at_start, step_at_start)) { raise(AlarmId::DRIVE_FAULT); r3 = true; }
    if (in.mode == Mode::T1 && armed_mode_ == Mode::T1 && !(t1_speed_ <= t_.t1_speed_limit_mm_s)) {
      raise(AlarmId::T1_SPEED_EXCEEDED);
      r3 = true;
    }
    if (s0 == St::STOPPING && ramping_at_start && stop_elapsed_at_start > t_.max_stop) { raise(AlarmId::STOP_TIME_EXCEEDED); r3 = true; }
    if (brake_not_engaged_) r3 = true;  // raised in every state, above
    // SPEC §10: a safe limit violated with power on (judged in judge_limits()).
    if (joint_hit_) { raise(AlarmId::JOINT_LIMIT); r3 = true; }
    if (zone_hit_) { raise(AlarmId::ZONE_VIOLATION); r3 = true; }
    if (orientation_hit_) { raise(AlarmId::ORIENTATION_LIMIT); r3 = true; }
    if (speed_hit_) { raise(AlarmId::SPEED_LIMIT); r3 = true; }
    if (ssm_hit_) { raise(AlarmId::SEPARATION_VIOLATED); r3 = true; }
    if (r3 && !done) {
      done = true;
      cat0_to(St::IDLE);
    }
  }
  // Rule 4 / 4b: guard open in AUTO.
  if ((op_or_cat2 || s0 == St::ARMING) && in.gate_open && in.mode == Mode::AUTO) {
    raise(AlarmId::PROTECTIVE_STOP);
    if (!done) {
      done = true;
      if (s0 == St::ARMING) cat0_to(St::IDLE); else stop_to(StopCat::CAT1, St::IDLE, Sub::NONE);
    }
  }
  // Rule 5 / 5b: enabling device not at centre in T1/T2.
  if ((op_or_cat2 || s0 == St::ARMING) && manual(in.mode) && !in.enable_ok) {
    if (in.enable == core::EnablePos::panic) raise(AlarmId::ENABLING_PANIC);
    if (!done) {
      done = true;
      if (s0 == St::ARMING) cat0_to(St::IDLE); else stop_to(StopCat::CAT1, St::IDLE, Sub::NONE);
    }
  }
  // Rule 6: mode changed.
  if ((op_or_cat2 || s0 == St::ARMING) && in.mode_changed) {
    raise(AlarmId::MODE_CHANGED);
    if (!done) {
      done = true;
      if (s0 == St::ARMING) cat0_to(St::IDLE); else stop_to(StopCat::CAT1, St::IDLE, Sub::NONE);
    }
  }
  // Rule 7: jog keep-alive lost.
  if (s0 == St::OP && sub_ == Sub::MANUAL_JOGGING && (now_ - last_jog_) > t_.jog_timeout) {
    raise(AlarmId::JOG_LINK_LOST);
    if (!done) {
      done = true;
      stop_to(StopCat::CAT2, St::OP, Sub::MANUAL_IDLE);
    }
  }
  // Rule 8 (SPEC §11): a collision stops moving motion (Cat 2), which ends with a back-off.
  // Judged on the sub-state the cycle began in (an earlier rule may have changed it: the
  // alarm is raised all the same).
  const bool moving = s0 == St::OP && (sub0 == Sub::AUTO_RUNNING || sub0 == Sub::MANUAL_RUNNING ||
                                        sub0 == Sub::MANUAL_JOGGING);
  if (moving && collision_now_) {
    raise(AlarmId::COLLISION);
    if (!done) {
      done = true;
      stop_to(StopCat::CAT2, St::OP, sub0 == Sub::AUTO_RUNNING ? Sub::AUTO_PAUSED : Sub::MANUAL_IDLE);
      back_off_ = true;
    }
  }
  // Rule 9 (SPEC §11): a person in the inner field stops a running AUTO program (Cat 2),
  // and the pause may resume by itself.
  if (s0 == St::OP && sub_ == Sub::AUTO_RUNNING && person_in_inner(in)) {
    raise(AlarmId::PERSON_IN_FIELD);
    if (!done) {
      done = true;
      stop_to(StopCat::CAT2, St::OP, Sub::AUTO_PAUSED);
      field_paused_ = true;
    }
  }
  // Rule 10: a brake slipped in the brake test (SPEC §12).
  if (bt_fail_now_) {
    raise(AlarmId::BRAKE_TEST_FAILED);
    if (!done) {
      done = true;
      stop_to(StopCat::CAT1, St::IDLE, Sub::NONE);
    }
  }
  changed_ = done;
}

void Supervisor::events(const core::SafetyInputs& in, const core::Feedback& fb) noexcept {
  switch (st_) {
    case St::BOOT:
      if (!boot_pending_) go(St::ESTOP_RESET);
      break;
    case St::ESTOP:
      if (!in.estop_pressed) go(St::ESTOP_RESET);
      break;
    case St::ARMING: {
      bool done = true;
      core::Cycle limit = t_.contactor_timeout;
      if (arming_step_ == 0) {
        done = fb.contactor_closed && (!fb.two_contactors || fb.k2_closed);
      } else if (arming_step_ == 1) {
        limit = t_.drives_timeout;
        for (const core::DriveFeedback& d : fb.drive) done = done && c402::decode(d.statusword) == c402::DriveState::OperationEnabled;
      } else {
        limit = t_.brakes_timeout;
        for (bool b : fb.brake_released) done = done && b;
      }
      if (done && arming_step_ == 2) {
        go(St::OP, in.mode == Mode::AUTO ? Sub::AUTO_IDLE : Sub::MANUAL_IDLE);
      } else if (done) {
        ++arming_step_;
        arming_elapsed_ = 0;
      } else if (arming_elapsed_ > limit) {
        raise(AlarmId::ARMING_TIMEOUT);
        cat0_to(St::IDLE);
      }
      break;
    }
    case St::OP:
      if (sub_ == Sub::AUTO_PAUSED && field_paused_ && collab_acts(in) && lim_.auto_resume &&
          fields_clear_ > lim_.resume_delay) {
        go(St::OP, Sub::AUTO_RUNNING);  // both fields clear for resume_delay_ms (SPEC §11)
      } else if (bt_pass_now_) {
        go(St::OP, in.mode == Mode::AUTO ? Sub::AUTO_IDLE : Sub::MANUAL_IDLE);
      } else if (fb.program_finished && sub_ == Sub::AUTO_RUNNING) {
        go(St::OP, Sub::AUTO_IDLE);
      } else if (fb.program_finished && sub_ == Sub::MANUAL_RUNNING) {
        stop_to(StopCat::CAT2, St::OP, Sub::MANUAL_IDLE);
      }
      break;
    case St::STOPPING:
      if (!braking_) {
        if (standstill() && !(back_off_ && fb.backing_off)) {
          if (stop_cat_ == StopCat::CAT2) {
            go(stop_target_, stop_target_sub_);
          } else {
            braking_ = true;  // Cat 1: brakes first, then power off
            brake_elapsed_ = 0;
          }
        }
      } else {
        bool engaged = true;
        for (bool b : fb.brake_released) engaged = engaged && !b;
        if (engaged || brake_elapsed_ > t_.brakes_timeout) go(stop_target_, stop_target_sub_);
      }
      break;
    default:
      break;
  }
}

Result Supervisor::command(const core::SafetyInputs& in, const core::Feedback& fb, const core::Command& c,
                           bool& deferred) noexcept {
  deferred = false;
  if (c.id >= core::kCommandCount) return Result::UNKNOWN_COMMAND;
  if (c.source >= core::kSourceCount) return Result::BAD_ARGUMENT;
  const auto id = static_cast<CommandId>(c.id);
  const auto src = static_cast<core::Source>(c.source);
  if (id == CommandId::jog && (c.axis < 1 || c.axis > 6 || (c.dir != 1 && c.dir != -1) || c.speed < 1 || c.speed > 100)) {
    return Result::BAD_ARGUMENT;
  }
  if (id == CommandId::set_mode && (c.mode < 1 || c.mode > 3)) return Result::BAD_ARGUMENT;
  if (id == CommandId::validate_config && c.has_code != 1U) return Result::BAD_ARGUMENT;
  if (st_ == St::LOCKOUT) return Result::LOCKED_OUT;
  if (src == core::Source::observer) return Result::NOT_CONTROL_OWNER;
  if (src == core::Source::remote && (id == CommandId::reset || in.mode != Mode::AUTO)) return Result::NOT_CONTROL_OWNER;
  if (src == core::Source::reset_button && id != CommandId::reset) return Result::NOT_CONTROL_OWNER;
  if (id == CommandId::set_mode) return Result::MODE_BY_SELECTOR_ONLY;

  const bool jog_in_auto = id == CommandId::jog && in.mode == Mode::AUTO;
  const auto confirm = [&] {
    if (in.mode != Mode::T2) return Result::MODE_INVALID;
    t2_ok_ = true;
    return Result::OK;
  };
  switch (st_) {
    case St::ESTOP:
      return Result::ESTOP_ACTIVE;
    case St::BOOT:
      if (id == CommandId::confirm_t2 && in.mode != Mode::T2) return Result::MODE_INVALID;
      return jog_in_auto ? Result::JOG_NOT_IN_AUTO : Result::WRONG_STATE;
    case St::ESTOP_RESET:
      if (id != CommandId::reset) return Result::RESET_REQUIRED;
      if (boot_pending_) return Result::BUSY;
      go(St::IDLE);
      return Result::OK;
    case St::IDLE:
      switch (id) {
        case CommandId::reset: {
          if (pending_reset_) return Result::BUSY;
          if (has(AlarmId::PROTECTIVE_STOP) && in.gate_open && in.mode == Mode::AUTO) return Result::FAULT_PRESENT;
          if (has(AlarmId::T1_SPEED_EXCEEDED) && !(t1_speed_ <= t_.t1_speed_limit_mm_s)) return Result::FAULT_PRESENT;
          if (has(AlarmId::STOP_TIME_EXCEEDED) && !standstill()) return Result::FAULT_PRESENT;
          if (has(AlarmId::BRAKE_NOT_ENGAGED) && brake_not_engaged_) return Result::FAULT_PRESENT;
          // SPEC §10: a position limit still violated is no reason (recovery needs the reset);
          // a speed still over its limit is.
          if (has(AlarmId::SPEED_LIMIT) && speed_over_) return Result::FAULT_PRESENT;
          if (has(AlarmId::SEPARATION_VIOLATED) && ssm_over_now_) return Result::FAULT_PRESENT;
          if (drives_faulted(fb)) {
            pending_reset_ = true;
            pending_since_ = now_;
            pending_seq_ = c.seq;
            pending_src_ = c.source;
            deferred = true;
            return Result::OK;
          }
          alarms_ &= ~core::kLatchedAlarms;
          return Result::OK;
        }
        case CommandId::servo_on:
          if ((alarms_ & core::kLatchedAlarms) != 0U || pending_reset_) return Result::RESET_REQUIRED;
          if (in.mode == Mode::NONE) return Result::MODE_INVALID;
          if (in.mode == Mode::AUTO && in.gate_open) return Result::GATE_OPEN;
          if (manual(in.mode) && !in.enable_ok) return Result::ENABLING_NOT_HELD;
          if (in.mode == Mode::T2 && !t2_ok_) return Result::T2_NOT_CONFIRMED;
          // SPEC §10: AUTO and T2 need a validated configuration and no limit violated; T1
          // stays allowed (commissioning, recovery).
          if ((in.mode == Mode::AUTO || in.mode == Mode::T2) && !validated_) return Result::CONFIG_NOT_VALIDATED;
          if ((in.mode == Mode::AUTO || in.mode == Mode::T2) && outside_) return Result::OUTSIDE_LIMITS;
          if (in.mode == Mode::AUTO && bt_needed()) return Result::BRAKE_TEST_REQUIRED;  // SPEC §12
          armed_mode_ = in.mode;
          arming_step_ = 0;
          arming_elapsed_ = 0;
          go(St::ARMING);
          return Result::OK;
        case CommandId::confirm_t2:
          return confirm();
        case CommandId::validate_config:
          // SPEC §10: the operator confirms the active checksum (0 without a configuration).
          if (!manual(in.mode)) return Result::MODE_INVALID;
          if (c.code != (lim_.configured ? lim_.checksum : 0U)) return Result::CHECKSUM_MISMATCH;
          validated_ = true;
          return Result::OK;
        default:
          return jog_in_auto ? Result::JOG_NOT_IN_AUTO : Result::WRONG_STATE;
      }
    case St::ARMING:
      if (id == CommandId::servo_off) {
        cat0_to(St::IDLE);
        return Result::OK;
      }
      if (id == CommandId::confirm_t2) return confirm();
      return jog_in_auto ? Result::JOG_NOT_IN_AUTO : Result::BUSY;
    case St::STOPPING:
      if (id == CommandId::servo_off && stop_cat_ == StopCat::CAT2) {
        stop_to(StopCat::CAT1, St::IDLE, Sub::NONE);
        return Result::OK;
      }
      if (id == CommandId::confirm_t2) return confirm();
      return jog_in_auto ? Result::JOG_NOT_IN_AUTO : Result::BUSY;
    case St::OP:
      break;
    case St::LOCKOUT:
      return Result::LOCKED_OUT;
  }
  // OPERATIONAL, by command then by sub-state.
  switch (id) {
    case CommandId::reset:
      return Result::OK;
    case CommandId::servo_off:
      stop_to(StopCat::CAT1, St::IDLE, Sub::NONE);
      return Result::OK;
    case CommandId::confirm_t2:
      return confirm();
    case CommandId::start:
      if (sub_ == Sub::AUTO_IDLE) {
        if (in.gate_open) return Result::GATE_OPEN;
        if (!fb.program_loaded) return Result::NO_PROGRAM;
        if (person_in_inner(in)) return Result::FIELD_INTERRUPTED;
        if (!fb.program_within_limits) return Result::OUTSIDE_LIMITS;
        go(St::OP, Sub::AUTO_RUNNING);
        return Result::OK;
      }
      if (sub_ == Sub::MANUAL_IDLE) {
        if (!in.enable_ok) return Result::ENABLING_NOT_HELD;
        if (!fb.program_loaded) return Result::NO_PROGRAM;
        if (!fb.program_within_limits) return Result::OUTSIDE_LIMITS;
        go(St::OP, Sub::MANUAL_RUNNING);
        return Result::OK;
      }
      break;
    case CommandId::pause:
      if (sub_ == Sub::AUTO_RUNNING) { stop_to(StopCat::CAT2, St::OP, Sub::AUTO_PAUSED); return Result::OK; }
      if (sub_ == Sub::MANUAL_RUNNING) { stop_to(StopCat::CAT2, St::OP, Sub::MANUAL_IDLE); return Result::OK; }
      break;
    case CommandId::stop:
      if (sub_ == Sub::AUTO_RUNNING) { stop_to(StopCat::CAT2, St::OP, Sub::AUTO_IDLE); return Result::OK; }
      if (sub_ == Sub::AUTO_PAUSED) { go(St::OP, Sub::AUTO_IDLE); return Result::OK; }
      if (sub_ == Sub::MANUAL_RUNNING) { stop_to(StopCat::CAT2, St::OP, Sub::MANUAL_IDLE); return Result::OK; }
      break;
    case CommandId::resume:
      if (sub_ == Sub::AUTO_PAUSED) {
        if (in.gate_open) return Result::GATE_OPEN;
        if (person_in_inner(in)) return Result::FIELD_INTERRUPTED;
        go(St::OP, Sub::AUTO_RUNNING);
        return Result::OK;
      }
      break;
    case CommandId::jog:
      if (sub_ == Sub::MANUAL_IDLE || sub_ == Sub::MANUAL_JOGGING) {
        if (!in.enable_ok) return Result::ENABLING_NOT_HELD;
        last_jog_ = now_;
        go(St::OP, Sub::MANUAL_JOGGING);
        return Result::OK;
      }
      break;
    case CommandId::jog_stop:
      if (sub_ == Sub::MANUAL_JOGGING) { stop_to(StopCat::CAT2, St::OP, Sub::MANUAL_IDLE); return Result::OK; }
      break;
    case CommandId::brake_test:
      if (sub_ == Sub::AUTO_IDLE || sub_ == Sub::MANUAL_IDLE) {
        if (!standstill()) return Result::WRONG_STATE;
        if (in.mode == Mode::NONE) return Result::MODE_INVALID;
        go(St::OP, Sub::BRAKE_TEST);
        bt_on_ = true;
        bt_axis_ = bt_phase_ = 0;
        bt_n_ = bt_held_ = 0;
        bt_drift_ = 0.0F;
        return Result::OK;
      }
      break;
    default:
      break;
  }
  return jog_in_auto ? Result::JOG_NOT_IN_AUTO : Result::WRONG_STATE;
}

void Supervisor::write(Out& out) const noexcept {
  out.state = core::State::BOOT;
  switch (st_) {
    case St::BOOT: out.state = core::State::BOOT; break;
    case St::LOCKOUT: out.state = core::State::ERROR_LOCKOUT; break;
    case St::ESTOP: out.state = core::State::ESTOP_ACTIVE; break;
    case St::ESTOP_RESET: out.state = core::State::ESTOP_RESET_NEEDED; break;
    case St::IDLE: out.state = core::State::IDLE; break;
    case St::ARMING: out.state = core::State::ARMING; break;
    case St::OP: out.state = core::State::OPERATIONAL; break;
    case St::STOPPING: out.state = core::State::STOPPING; break;
  }
  out.sub = (st_ == St::OP) ? sub_ : Sub::NONE;
  out.stop = (st_ == St::STOPPING) ? stop_cat_ : (cat0_now_ ? StopCat::CAT0 : StopCat::NONE);
  out.contactor = st_ == St::ARMING || st_ == St::OP || st_ == St::STOPPING;
  out.drives = st_ == St::OP || st_ == St::STOPPING || (st_ == St::ARMING && arming_step_ >= 1);
  out.brakes_release = st_ == St::OP || (st_ == St::STOPPING && !braking_) || (st_ == St::ARMING && arming_step_ == 2);
  out.reset_lamp = st_ == St::ESTOP_RESET || (st_ == St::IDLE && ((alarms_ & core::kLatchedAlarms) != 0U || pending_reset_));
  out.fault_reset = pending_reset_;
  out.alarms = alarms_;
  out.brake_test_axis = (st_ == St::OP && sub_ == Sub::BRAKE_TEST) ? bt_out_axis_ : std::uint8_t{0U};
}

std::size_t Supervisor::step(const core::SafetyInputs& in, const core::Feedback& fb, const core::Command* cmds,
                             std::size_t n, Out& out, const Geometry& g) noexcept {
  out.reply_count = 0;
  cat0_now_ = false;

  bool still = true;
  for (const core::DriveFeedback& d : fb.drive) {
    const float v = d.velocity_rad_s < 0.0F ? -d.velocity_rad_s : d.velocity_rad_s;
    still = still && (v < t_.standstill_rad_s);
  }
  quiet_ = still ? (quiet_ < t_.standstill_cycles ? quiet_ + 1U : quiet_) : 0U;
  if (in.mode_changed) t2_ok_ = false;
  judge_limits(in, fb, g);
  t1_speed(fb, g);
  const bool clear = !in.field_outer_interrupted && !in.field_inner_interrupted;
  fields_clear_ = clear ? (fields_clear_ <= lim_.resume_delay ? fields_clear_ + 1U : fields_clear_) : 0U;
  brake_test(fb);
  const AlarmId conds[] = {AlarmId::ESTOP_PRESSED, AlarmId::MODE_SELECTOR_INVALID, AlarmId::RESET_BUTTON_STUCK,
                           AlarmId::CONFIG_NOT_VALIDATED, AlarmId::REDUCED_SPEED, AlarmId::PERSON_IN_FIELD,
                           AlarmId::BRAKE_TEST_DUE};
  const bool holds[] = {in.estop_pressed, in.mode_invalid, in.reset_stuck, !validated_, reduced_, person_in_inner(in),
                        bt_due()};
  static_assert(std::size(conds) == std::size(holds));
  for (std::size_t i = 0; i < std::size(conds); ++i) {
    if (holds[i]) raise(conds[i]); else drop(conds[i]);
  }
  if (in.enable_panic_edge) raise(AlarmId::ENABLING_PANIC);
  if (drives_faulted(fb) && st_ != St::BOOT) raise(AlarmId::DRIVE_FAULT);
  if (boot_pending_) {
    bool answered = fb.fieldbus_ok;
    for (const core::DriveFeedback& d : fb.drive) {
      const c402::DriveState ds = c402::decode(d.statusword);
      answered = answered && d.online && ds != c402::DriveState::Unknown && ds != c402::DriveState::NotReadyToSwitchOn;
    }
    answered = answered && (!fb.link.configured || fb.link.up);  // issue 37: every safety connection up
    if (answered && fb.self_test_ok && !fb.fieldbus_boot_failed) boot_pending_ = false;
  }
  // Contactor commanded open with its feedback closed, brakes commanded engaged with a
  // feedback released: more than 100 / 300 cycles in a row is a fault (SPEC §7).
  welded_for_ = (!last_contactor_ && fb.contactor_closed) ? welded_for_ + 1U : 0U;
  k2_welded_for_ = (fb.two_contactors && !last_contactor_ && fb.k2_closed) ? k2_welded_for_ + 1U : 0U;
  contactor_welded_ = welded_for_ > t_.contactor_timeout || k2_welded_for_ > t_.contactor_timeout;
  // SPEC §14: the partner channel as the cross-check judged it; each axis' two encoders: a
  // difference over the tolerance for more than encoder_discrepancy cycles, or the load-side
  // one unchanged since the motor one moved the tolerance away from where it was then.
  channel_mismatch_ = fb.cross.partner != core::Channel::none && fb.cross.mismatch;
  channel_lost_ = fb.cross.partner != core::Channel::none && fb.cross.lost;
  encoder_bad_ = false;
  for (std::size_t i = 0; i < core::kAxes && fb.load_encoders; ++i) {
    const float m = fb.drive[i].position_rad;
    const float l = fb.drive[i].load_position_rad;
    const float tol = t_.encoder_tolerance_rad;
    const bool apart = !(std::fabs(m - l) <= tol);
    enc_apart_[i] = apart ? std::min<core::Cycle>(enc_apart_[i] + 1U, t_.encoder_discrepancy + 1U) : 0U;
    if (!enc_seen_ || std::memcmp(&l, &enc_load_[i], sizeof l) != 0) {  // the load side moved (bitwise)
      enc_load_[i] = l;
      enc_motor_[i] = m;
    }
    encoder_bad_ = encoder_bad_ || enc_apart_[i] > t_.encoder_discrepancy || !(std::fabs(m - enc_motor_[i]) <= tol);
  }
  enc_seen_ = fb.load_encoders;
  // A brake: "commanded engaged whose feedback still says released 300 ms later" (SPEC §7),
  // the 300 ms counted from the command, i.e. from the first released reading after it. A
  // brake is engaged only once its feedback has said so for brake_confirm cycles in a row
  // (docs/decisions.md: a chattering contact is not an engaged brake), so a moment's engaged
  // reading does not restart the time: a brake that sticks released as it was about to engage
  // is late 300 ms after its command, not 300 ms after the stick.
  brake_not_engaged_ = false;
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    const bool engage_cmd = !last_brakes_release_ || bt_cmd_axis_ == i + 1U;
    const bool released = fb.brake_released[i];
    engaged_run_[i] = (engage_cmd && !released) ? engaged_run_[i] + 1U : 0U;
    if (!engage_cmd || engaged_run_[i] >= t_.brake_confirm) {
      released_[i] = false;  // released on command, or engaged for sure
    } else if (released && !released_[i]) {
      released_[i] = true;
      released_at_[i] = now_;
    }
    brake_not_engaged_ = brake_not_engaged_ || (released && released_[i] && now_ - released_at_[i] >= t_.brakes_timeout);
  }
  if (brake_not_engaged_) raise(AlarmId::BRAKE_NOT_ENGAGED);
  if (st_ == St::ARMING) ++arming_elapsed_;
  if (st_ == St::STOPPING) {
    ++stop_elapsed_;
    if (braking_) ++brake_elapsed_;
  }

  const bool had_pending = pending_reset_;
  conditions(in, fb, out);
  if (!changed_) events(in, fb);
  // A pending reset answered by leaving IDLE: the new state's refusal.
  const auto refusal = [this] {
    switch (st_) {
      case St::LOCKOUT: return Result::LOCKED_OUT;
      case St::ESTOP: return Result::ESTOP_ACTIVE;
      case St::ESTOP_RESET: return Result::RESET_REQUIRED;
      case St::ARMING:
      case St::STOPPING: return Result::BUSY;
      default: return Result::WRONG_STATE;
    }
  };
  if (had_pending && !pending_reset_) {
    answer(out, pending_seq_, static_cast<std::uint8_t>(CommandId::reset), pending_src_, refusal());
  }
  if (pending_reset_) {
    if (!drives_faulted(fb)) {
      alarms_ &= ~core::kLatchedAlarms;
      pending_reset_ = false;
      answer(out, pending_seq_, static_cast<std::uint8_t>(CommandId::reset), pending_src_, Result::OK);
    } else if (now_ - pending_since_ >= t_.fault_reset_reply) {  // answered by T+50
      pending_reset_ = false;
      answer(out, pending_seq_, static_cast<std::uint8_t>(CommandId::reset), pending_src_, Result::FAULT_PRESENT);
    }
  }
  const auto run = [&](const core::Command& c) {
    const bool pending_before = pending_reset_;
    bool deferred = false;
    const Result r = command(in, fb, c, deferred);
    if (pending_before && !pending_reset_ && !deferred) {
      answer(out, pending_seq_, static_cast<std::uint8_t>(CommandId::reset), pending_src_, refusal());
    }
    if (!deferred) answer(out, c.seq, c.id, c.source, r);
  };
  if (in.reset_released && in.reset_press_start > resettable_since_ && (st_ == St::ESTOP_RESET || st_ == St::IDLE)) {
    core::Command c{};
    c.id = static_cast<std::uint8_t>(CommandId::reset);
    c.source = static_cast<std::uint8_t>(core::Source::reset_button);
    run(c);
  }
  const std::size_t limit = t_.max_commands_per_cycle < 16U ? t_.max_commands_per_cycle : 16U;
  const std::size_t taken = (cmds == nullptr) ? 0U : (n < limit ? n : limit);
  for (std::size_t i = 0; i < taken; ++i) run(cmds[i]);
  write(out);
  last_contactor_ = out.contactor;
  last_brakes_release_ = out.brakes_release;
  bt_cmd_axis_ = out.brake_test_axis;
  ++now_;
  return taken;
}

}  // namespace safestate::reference

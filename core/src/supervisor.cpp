#include "safestate/core/supervisor.hpp"

#include <array>
#include <span>

#include "safestate/core/leaf_outputs.hpp"
#include "safestate/core/monitor.hpp"
#include "safestate/core/sequences.hpp"

namespace safestate::core {

namespace {

constexpr bool in_mask(LeafMask m, Leaf l) noexcept { return (m & mask_of(l)) != 0U; }

constexpr auto kResetId = static_cast<std::uint8_t>(CommandId::reset);

constexpr bool is_manual(Mode m) noexcept { return (m == Mode::T1) || (m == Mode::T2); }

// Priority of a cause for the first-out display: a cause is replaced only by a more
// severe one (lockout, then E-stop, then faults, then protective/enabling/mode stops).
constexpr std::uint8_t rank(const Cause& c) noexcept {
  if (c.kind == CauseKind::none) {
    return 255U;
  }
  if (c.rule != 0U) {
    return c.rule;
  }
  // Without a rule number: an arming timeout (the only alarm raised by an event), ranked
  // with the faults of rule 3; else a command or event.
  return (c.kind == CauseKind::alarm) ? 3U : 10U;
}

// Each rule's alarms as a mask: a rule none of whose alarms was found is passed over quickly.
constexpr std::array<AlarmMask, kConditionCount> kRuleMasks = [] {
  std::array<AlarmMask, kConditionCount> m{};
  for (std::size_t t = 0; t < kConditionCount; ++t) {
    m[t] = rule_mask(t);
  }
  return m;
}();

Cause alarm_cause(std::uint8_t rule, AlarmId a, const AlarmDetail& d, Mode m) noexcept {
  Cause c{};
  c.kind = CauseKind::alarm;
  c.rule = rule;
  c.alarm = a;
  c.detail = d;
  c.mode = m;
  return c;
}

}  // namespace

// One cycle's data, alive only during step(): it views inputs, writes outputs (references).
struct SystemStateManager::CycleCtx {
  // NOLINTBEGIN(cppcoreguidelines-avoid-const-or-ref-data-members): a view for one call
  const SafetyInputs& in;
  const Feedback& fb;
  SupervisorOut& out;
  Reporter& rep;  // what the monitors found this cycle (the manager's, begun for it)
  // NOLINTEND(cppcoreguidelines-avoid-const-or-ref-data-members)
  Leaf start_leaf = Leaf::BOOT;
  bool cat0 = false;
  bool discard = false;
  bool deferred = false;  // the current command's answer comes later
  ProgramCmd program = ProgramCmd::None;
};

SystemStateManager::SystemStateManager(const Timing& timing) noexcept : timing_(timing) {
  // Start-up self-test: the table is checked at compile time (static_assert); what can
  // still be wrong at run time is the configuration this instance was given, and the
  // alarm table's numbering.
  bool ok = (timing_.standstill_cycles > 0U) && (timing_.max_commands_per_cycle > 0U) &&
            (timing_.max_commands_per_cycle <= kMaxCommandsPerCycle) && (timing_.standstill_rad_s > 0.0F);
  for (std::size_t i = 0; i < kAlarmCount; ++i) {
    ok = ok && (static_cast<std::size_t>(kAlarms[i].id) == i);
  }
  self_test_ok_ = ok;
  brake_test_.configure(BrakeTestLimits{}, 1000U, timing_.brake_confirm, timing_.brakes_timeout);
}

void SystemStateManager::configure_limits(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us,
                                          bool validated) noexcept {
  limits_.configure(limits, arm, cycle_us);
  fields_.configure(limits.collaborative, cycle_us);
  ssm_.configure(limits, cycle_us);
  collision_.configure(limits, arm, cycle_us);
  config_validated_ = validated;
  brake_test_.configure(limits.brake_test, cycle_us, timing_.brake_confirm, timing_.brakes_timeout);
}

GuardView SystemStateManager::view(const CycleCtx& c, std::uint32_t code) const noexcept {
  const CycleFacts& f = c.rep.facts();
  return GuardView{c.in,           c.fb,           alarms_,           timing_,       t2_confirmed_,
                   boot_pending_,  reset_pending_, f.at_standstill,   c.rep.present_mask(), f.limits.outside,
                   config_validated_, limits_.limits().checksum, code, f.fields.blocks_start,
                   brake_test_.required(now_)};
}

// Timers carried by the states themselves, counting this cycle.
void SystemStateManager::advance_state_timers() noexcept {
  if (auto* a = std::get_if<StArming>(&state_)) {
    ++a->step_elapsed;
  } else if (auto* s = std::get_if<StStopping>(&state_)) {
    ++s->elapsed;
    // @req ST-CAT1
    if (s->braking) {
      ++s->brake_elapsed;
    }
  } else if (auto* b = std::get_if<StBoot>(&state_)) {
    ++b->elapsed;
  }
}

// Every safety function, each a monitor of its own (monitor.hpp), in an order where a
// monitor reads only the facts of those before it: standstill before the stop time, the
// protective fields before the safe limits (the outer field reduces), the safe limits
// before SSM (the TCP speed and the limit in force), BOOT before the fieldbus.
void SystemStateManager::run_monitors(CycleCtx& c) noexcept {
  const CycleView v{c.in,      c.fb,        timing_,        state_,        c.rep.facts(),
                    limits_.configured() ? &limits_.limits() : nullptr,     leaf_,         in_mask(kPowered, leaf_),
                    now_,      armed_mode_, last_jog_,      boot_pending_, integrity_fault_,
                    self_test_ok_, config_validated_, last_};
  Reporter& r = c.rep;
  standstill_.check(v, r);
  estop_.check(v, r);
  gate_.check(v, r);
  enabling_.check(v, r);
  mode_.check(v, r);
  reset_button_.check(v, r);
  config_.check(v, r);
  fields_.check(v, r);
  limits_.check(v, r);
  ssm_.check(v, r);
  collision_.check(v, r);
  brake_test_.check(v, r);
  drives_.check(v, r);
  contactor_.check(v, r);
  brakes_.check(v, r);
  boot_.check(v, r);
  fieldbus_.check(v, r);
  integrity_.check(v, r);
  t1_speed_.check(v, r);
  stop_time_.check(v, r);
  jog_link_.check(v, r);
  channel_.check(v, r);
  encoders_.check(v, r);
  links_.check(v, r);
}

// @req TR-PRIORITY TR-EVERY-ALARM
// The rules in priority order (SPEC §4): each rule that applies in this state raises every
// alarm the monitors found of it; the first rule that holds decides the transition, its
// first alarm found (kRuleAlarms' order) being the cause.
bool SystemStateManager::evaluate_conditions(CycleCtx& c) noexcept {
  const Reporter& rep = c.rep;
  bool decided = false;
  for (std::size_t t = 0; t < kConditionCount; ++t) {
    const Transition* row = find_row(c.start_leaf, static_cast<Trigger>(t));
    if (row == nullptr) {
      continue;  // this rule does not apply in this state
    }
    const std::uint8_t rule = kConditionRule[t];
    bool holds = false;
    Cause cause{};
    AlarmMask left = rep.found() & kRuleMasks[t];  // this rule's alarms found, not raised yet
    const RuleAlarms& ra = kRuleAlarms[t];
    for (std::size_t k = 0; (k < ra.count) && (left != 0U); ++k) {
      const AlarmId a = ra.alarms[k];
      if ((left & bit(a)) != 0U) {
        left &= ~bit(a);
        alarms_.raise(a, rep.detail(a), now_);
        if (!holds) {
          cause = alarm_cause(rule, a, rep.detail(a), c.in.mode);
          holds = true;
        }
      }
    }
    if (!holds && rep.event(t)) {
      holds = true;  // rule 5's release raises no alarm: it is the normal way to stop
      cause.kind = CauseKind::event;
      cause.rule = rule;
      cause.mode = c.in.mode;
      cause.detail = rep.event_detail(t);
    }
    if (holds && !decided) {
      decided = true;
      static_cast<void>(apply(c, *row, cause, nullptr));
    }
  }
  return decided;
}

void SystemStateManager::evaluate_events(CycleCtx& c) noexcept {
  Trigger trig = Trigger::boot_passed;
  bool fired = false;
  Cause cause{};
  cause.kind = CauseKind::event;
  cause.mode = c.in.mode;

  if (leaf_ == Leaf::BOOT) {
    fired = c.rep.facts().boot_passed;
  } else if (leaf_ == Leaf::ESTOP_ACTIVE) {
    trig = Trigger::estop_released;
    fired = !c.in.estop_pressed;
  } else if (auto* a = std::get_if<StArming>(&state_)) {
    AlarmDetail d{};
    const ArmingOutcome o = arming_step(*a, c.fb, timing_, d);
    if (o == ArmingOutcome::complete) {
      trig = Trigger::arming_complete;
      fired = true;
    } else if (o == ArmingOutcome::timeout) {
      trig = Trigger::arming_timeout;
      fired = true;
      alarms_.raise(AlarmId::ARMING_TIMEOUT, d, now_);
      cause = alarm_cause(0U, AlarmId::ARMING_TIMEOUT, d, c.in.mode);
    } else {
      // the sequence goes on
    }
  } else if ((leaf_ == Leaf::AUTO_RUNNING) || (leaf_ == Leaf::MANUAL_RUNNING)) {
    trig = Trigger::program_finished;
    fired = c.fb.program_finished;
  } else if (leaf_ == Leaf::AUTO_PAUSED) {
    trig = Trigger::fields_clear;  // SPEC §11: only a pause of rule 9 resumes by itself
    fired = field_paused_ && c.rep.facts().fields.resume_due;
  } else if (leaf_ == Leaf::BRAKE_TEST) {
    trig = Trigger::brake_test_passed;
    fired = c.rep.facts().brake_test.passed;
  } else if (auto* s = std::get_if<StStopping>(&state_)) {
    trig = Trigger::standstill;
    fired = stop_step(*s, c.rep.facts().at_standstill, c.fb, timing_);
  }
  if (fired) {
    const Transition* row = find_row(leaf_, trig);
    if (row != nullptr) {
      static_cast<void>(apply(c, *row, cause, nullptr));
    }
  }
}

void SystemStateManager::clear_latched() noexcept {
  for (std::size_t i = 0; i < kAlarmCount; ++i) {
    const auto a = static_cast<AlarmId>(i);
    if ((kLatchedAlarms & bit(a)) != 0U) {
      alarms_.clear(a);
    }
  }
}

// @req RES-SAME-CYCLE
void SystemStateManager::finish_pending_reset(CycleCtx& c) noexcept {
  if (!reset_pending_) {
    return;
  }
  if (!c.rep.facts().any_drive_faulted) {
    clear_latched();
    cause_ = Cause{};
    reset_pending_ = false;
    reply(c, reset_seq_, kResetId, reset_source_, Result::OK);
  } else if ((now_ - reset_pending_since_) >= timing_.fault_reset_reply) {
    // SPEC §5: a reset taken at cycle T is answered at T+50 at the latest (not T+51).
    reset_pending_ = false;
    reply(c, reset_seq_, kResetId, reset_source_, Result::FAULT_PRESENT);
  }
}

// @req IN-RESET-EDGE IN-RESET-FRESH
void SystemStateManager::handle_reset_button(CycleCtx& c) noexcept {
  // ISO 13849-1 5.2.2: only a press that began after the reset became possible, and
  // was released within the hold limit, is a reset.
  if (!c.in.reset_released || (c.in.reset_press_start <= reset_possible_since_) ||
      ((leaf_ != Leaf::ESTOP_RESET_NEEDED) && (leaf_ != Leaf::IDLE))) {
    return;
  }
  Command cmd{};
  cmd.id = static_cast<std::uint8_t>(CommandId::reset);
  cmd.source = static_cast<std::uint8_t>(Source::reset_button);
  c.deferred = false;
  const Result r = dispatch_command(c, cmd);
  if (!c.deferred) {
    reply(c, 0U, cmd.id, cmd.source, r);
  }
}

Result SystemStateManager::dispatch_command(CycleCtx& c, const Command& cmd) noexcept {
  // 1.-3. Malformed, lockout, ownership (SPEC §5 check order): commands.cpp.
  const Result early = check_command(cmd, leaf_, c.in.mode);
  if (early != Result::OK) {
    return early;
  }
  const auto id = static_cast<CommandId>(cmd.id);
  const auto src = static_cast<Source>(cmd.source);
  // 4. State rules.
  // @req IN-SET-MODE
  if (id == CommandId::set_mode) {
    return Result::MODE_BY_SELECTOR_ONLY;
  }
  // @req RES-ESTOP RES-RESET-NEEDED RES-WRONG-STATE
  const LeafPolicy& policy = kLeafPolicy[static_cast<std::size_t>(leaf_)];
  if (policy.refuse_all) {
    return policy.no_row;
  }
  const Transition* row = find_row(leaf_, trigger_of(id));
  if (row == nullptr) {
    const bool generic = (policy.no_row == Result::WRONG_STATE) || (policy.no_row == Result::BUSY);
    if ((id == CommandId::jog) && (c.in.mode == Mode::AUTO) && generic) {
      return Result::JOG_NOT_IN_AUTO;
    }
    // @req SET-READINGS
    // SPEC §9: `confirm_t2` while the mode is not T2 is MODE_INVALID (BOOT included).
    if ((id == CommandId::confirm_t2) && (c.in.mode != Mode::T2) && generic) {
      return Result::MODE_INVALID;
    }
    return policy.no_row;
  }
  if (row->guard.fn != nullptr) {
    const Result g = row->guard.fn(view(c, cmd.code));
    if (g != Result::OK) {
      // @req RES-NO-CHANGE
      return g;  // a refused command changes nothing
    }
  }
  Cause cause{};
  cause.kind = CauseKind::command;
  cause.command = id;
  cause.source = src;
  cause.mode = c.in.mode;
  cause.detail.signal = Signal::command;
  cause.detail.code = static_cast<std::uint16_t>(id);
  return apply(c, *row, cause, &cmd);
}

Result SystemStateManager::apply(CycleCtx& c, const Transition& row, const Cause& cause, const Command* cmd) noexcept {
  const Leaf from = leaf_;
  Leaf to = row.to;
  if (to == Leaf::SAME) {
    to = from;
  } else if (to == Leaf::OP_IDLE) {
    to = (c.in.mode == Mode::AUTO) ? Leaf::AUTO_IDLE : Leaf::MANUAL_IDLE;
  } else if (to == Leaf::STOP_TARGET) {
    const auto* s = std::get_if<StStopping>(&state_);
    to = (s != nullptr) ? s->target : Leaf::IDLE;
  }

  switch (row.effect) {
    case Effect::reset_alarms:
      if (c.rep.facts().any_drive_faulted) {
        // SPEC §5: the drives get a fault reset; the answer comes once they reply.
        reset_pending_ = true;
        reset_pending_since_ = now_;
        reset_seq_ = (cmd != nullptr) ? cmd->seq : 0U;
        reset_source_ = (cmd != nullptr) ? cmd->source : static_cast<std::uint8_t>(Source::pendant);
        c.deferred = true;
      } else {
        clear_latched();
      }
      break;
    case Effect::start_program: c.program = ProgramCmd::Start; break;
    case Effect::resume_program: c.program = ProgramCmd::Resume; break;
    case Effect::abort_program:
    case Effect::back_off_abort: c.program = ProgramCmd::Abort; break;
    case Effect::jog_keepalive:
      last_jog_ = now_;
      if (cmd != nullptr) {
        jog_ = JogTarget{static_cast<std::uint8_t>(cmd->axis), cmd->dir, cmd->speed};
      }
      break;
    case Effect::set_t2_confirmed: t2_confirmed_ = true; break;
    case Effect::set_validated: config_validated_ = true; break;
    case Effect::field_pause: field_paused_ = true; break;
    case Effect::begin_arming: armed_mode_ = c.in.mode; break;
    case Effect::begin_brake_test: brake_test_.begin(now_); break;
    case Effect::back_off:
    case Effect::none:
      break;
  }

  const bool stops = row.stop != StopCat::NONE;
  if (stops) {  // rows into ESTOP_ACTIVE and ERROR_LOCKOUT are all Cat 0 (static_assert)
    set_cause(cause);
  } else if ((cmd != nullptr) && (((row.to != Leaf::SAME) && (row.trigger != Trigger::reset)) ||
                                  (row.effect == Effect::reset_alarms))) {
    // An accepted command that starts something: no stop is current. The reset that
    // leaves ESTOP_RESET_NEEDED only leaves it (SPEC §9): the E-stop stays the last
    // stop's cause until the reset in IDLE or a new start.
    cause_ = Cause{};
  }

  if (stops) {
    // @req ST-NO-SURPRISE
    c.discard = true;  // every stop discards all queued motion (SPEC §3)
  }
  if ((row.stop == StopCat::CAT1) || (row.stop == StopCat::CAT2)) {
    StStopping s{};
    s.category = row.stop;
    s.target = to;
    s.back_off = (row.effect == Effect::back_off) || (row.effect == Effect::back_off_abort);
    if (const auto* prev = std::get_if<StStopping>(&state_)) {
      s.elapsed = prev->elapsed;  // an escalated stop keeps its original start (SS1-t)
    }
    state_ = s;
    leaf_ = (row.stop == StopCat::CAT1) ? Leaf::STOPPING_CAT1 : Leaf::STOPPING_CAT2;
  } else {
    if ((row.stop == StopCat::CAT0) && (to != from)) {
      c.cat0 = true;  // shown for the cycle it happened, not while its cause lasts
    }
    if (to != from) {
      enter(c, to);
    }
  }

  if ((leaf_ != from) && (c.out.transition_count < kMaxTransitionsPerCycle)) {
    TransitionEvent& e = c.out.transitions[c.out.transition_count];
    e.from = from;
    e.to = leaf_;
    e.stop = row.stop;
    e.trigger = row.trigger;
    e.row = static_cast<std::uint8_t>(&row - kTransitions.data());
    ++c.out.transition_count;
  }
  return Result::OK;
}

void SystemStateManager::enter(CycleCtx& c, Leaf to) noexcept {
  const Leaf from = leaf_;
  switch (to) {
    case Leaf::BOOT: state_ = StBoot{}; break;
    case Leaf::ERROR_LOCKOUT: state_ = StErrorLockout{cause_}; break;
    case Leaf::ESTOP_ACTIVE: state_ = StEstopActive{}; break;
    case Leaf::ESTOP_RESET_NEEDED: state_ = StEstopResetNeeded{}; break;
    case Leaf::IDLE: state_ = StIdle{}; break;
    case Leaf::ARMING: state_ = StArming{}; break;
    case Leaf::STOPPING_CAT1:
    case Leaf::STOPPING_CAT2:
    case Leaf::SAME:
    case Leaf::OP_IDLE:
    case Leaf::STOP_TARGET:
      // Not reachable through enter(): STOPPING is entered by apply() with its data.
      integrity_fault_ = true;
      state_ = StIdle{};
      to = Leaf::IDLE;
      break;
    default: state_ = StOperational{sub_of(to)}; break;
  }
  leaf_ = to;
  // A pause of rule 9 stays one through its Cat 2 stop (entered by apply()) into
  // AUTO_PAUSED, and ends with any other state.
  field_paused_ = field_paused_ && (to == Leaf::AUTO_PAUSED);
  const bool resettable_before = (from == Leaf::ESTOP_RESET_NEEDED) || (from == Leaf::IDLE);
  const bool resettable_now = (to == Leaf::ESTOP_RESET_NEEDED) || (to == Leaf::IDLE);
  if (resettable_now && !resettable_before) {
    reset_possible_since_ = now_;
  }
  if (reset_pending_ && (to != Leaf::IDLE)) {
    reset_pending_ = false;
    reply(c, reset_seq_, kResetId, reset_source_, kLeafPolicy[static_cast<std::size_t>(to)].no_row);
  }
}

// @req AL-FIRST-OUT
void SystemStateManager::set_cause(const Cause& cause) noexcept {
  if (rank(cause) < rank(cause_)) {
    cause_ = cause;
  }
}

// @req RES-ONE
void SystemStateManager::reply(CycleCtx& c, std::uint32_t seq, std::uint8_t id, std::uint8_t src, Result r) noexcept {
  if (c.out.reply_count < kMaxRepliesPerCycle) {
    Reply& rp = c.out.replies[c.out.reply_count];
    rp.seq = seq;
    rp.cmd = id;
    rp.source = src;
    rp.result = r;
    ++c.out.reply_count;
  }
  if (r == Result::OK) {
    alarms_.clear_older(kUntilOkAlarms, now_);  // "until the next command answered OK"
  }
}

void SystemStateManager::write_outputs(CycleCtx& c) noexcept {
  SupervisorOut& o = c.out;
  const LeafOutputs& lo = kLeafOutputs[static_cast<std::size_t>(leaf_)];
  o.state = state_of(leaf_);
  o.sub = sub_of(leaf_);
  o.mode = c.in.mode;
  // @req AL-FIRST-OUT
  o.mode_requested = c.in.mode_requested;
  o.contactor = lo.contactor;
  o.drives_enable = lo.drives;
  o.brakes_release = lo.brakes_release;
  o.reset_lamp = lo.reset_lamp;
  o.motion.mode = lo.motion;
  // @req ST-STATUS ST-CAT0
  o.stop = c.cat0 ? StopCat::CAT0 : StopCat::NONE;
  o.target = Leaf::SAME;
  o.arming_step = ArmingStep::CONTACTOR;
  o.arming_progress = 0;

  if (const auto* a = std::get_if<StArming>(&state_)) {
    // The table gives ARMING's outputs at step CONTACTOR; later steps add to them.
    o.drives_enable = lo.drives || (a->step != ArmingStep::CONTACTOR);
    o.brakes_release = lo.brakes_release || (a->step == ArmingStep::BRAKES);
    o.arming_step = a->step;
    o.arming_progress = a->progress;
  } else if (const auto* s = std::get_if<StStopping>(&state_)) {
    o.stop = s->category;
    o.target = s->target;
    o.motion.back_off = s->back_off && !s->braking;
    if (s->braking) {
      o.brakes_release = false;
      o.motion.mode = MotionMode::Hold;
    }
  } else if (leaf_ == Leaf::IDLE) {
    // A pending reset implies DRIVE_FAULT, a latched alarm, so the lamp stays on.
    o.reset_lamp = lo.reset_lamp || ((alarms_.mask() & kLatchedAlarms) != 0U);
  }

  o.motion.program = c.program;
  o.motion.discard = c.discard;
  o.motion.jog = jog_;
  o.motion.t1_limit = c.in.mode == Mode::T1;
  o.motion.fault_reset = reset_pending_;
  o.t2_confirmed = t2_confirmed_;
  const CycleFacts& f = c.rep.facts();
  o.at_standstill = f.at_standstill;
  o.pendant_owner = is_manual(c.in.mode);
  o.cause = cause_;
  o.alarms = alarms_.mask();
  o.alarms_raised = alarms_.raised();
  o.alarms_cleared = alarms_.cleared();
  o.motion.reduced = limits_.reduced().active();
  o.motion.reduced_limit_mm_s = limits_.reduced().limit();
  o.motion.v_allowed_mm_s = f.ssm.acting ? f.ssm.v_plan_mm_s : -1.0F;
  o.motion.recovery = f.limits.recovering;
  safety_status(f, limits_, config_validated_, c.in, o.safety);
  // SPEC §12: the tested brake and the test's offset and torque, only while testing.
  const bool testing = (leaf_ == Leaf::BRAKE_TEST) && f.brake_test.running;
  o.brake_test_axis = testing ? f.brake_test.brake_engaged_axis : 0U;
  o.motion.brake_test = testing ? f.brake_test.motion : BrakeTestRequest{};
  brake_test_.status(now_, o.brake_test);
}

std::size_t SystemStateManager::step(const SafetyInputs& in, const Feedback& fb, const Command* cmds, std::size_t n,
                                     SupervisorOut& out) noexcept {
  out.reply_count = 0;
  out.transition_count = 0;
  // @req CH-FLIP
  // A state outside its range (a memory fault: SPEC §14 self-test) is a contradiction like
  // the outputs' below: INTEGRITY_FAULT, lockout. Its index is made valid before any table
  // (kLeafPolicy, kLeafOutputs, the transitions) reads it.
  const bool leaf_corrupt = static_cast<std::size_t>(leaf_) >= kLeafCount;
  if (leaf_corrupt) {
    leaf_ = Leaf::ERROR_LOCKOUT;
  }
  rep_.begin(alarms_, now_);
  CycleCtx c{in, fb, out, rep_, leaf_};

  // @req CYC-ORDER CYC-ZERO-DELAY
  alarms_.begin_cycle();
  if (in.mode_changed) {
    t2_confirmed_ = false;  // "T2 confirmed until the mode next changes"
  }
  advance_state_timers();
  run_monitors(c);
  if (c.rep.facts().boot_passed) {
    boot_pending_ = false;
  }
  if (!evaluate_conditions(c)) {
    evaluate_events(c);
  }
  finish_pending_reset(c);
  handle_reset_button(c);

  // @req CYC-MAX-COMMANDS
  const std::size_t limit = (timing_.max_commands_per_cycle < kMaxCommandsPerCycle)
                                ? static_cast<std::size_t>(timing_.max_commands_per_cycle)
                                : kMaxCommandsPerCycle;
  const std::size_t taken = ((cmds == nullptr) ? 0U : ((n < limit) ? n : limit));
  // The C-style (pointer, count) interface keeps the core embeddable from C; from here on
  // the commands are a bounded view.
  const std::span<const Command> queue = (taken == 0U) ? std::span<const Command>{} : std::span<const Command>(cmds, taken);
  for (const Command& cmd : queue) {
    c.deferred = false;
    const Result r = dispatch_command(c, cmd);
    if (!c.deferred) {
      reply(c, cmd.seq, cmd.id, cmd.source, r);
    }
  }

  write_outputs(c);
  if (leaf_corrupt || !outputs_consistent(out, leaf_, state_, in.estop_pressed)) {
    integrity_fault_ = true;
    alarms_.raise(AlarmId::INTEGRITY_FAULT, detail_of(Signal::internal), now_);
    set_cause(alarm_cause(1U, AlarmId::INTEGRITY_FAULT, detail_of(Signal::internal), in.mode));
    c.cat0 = true;
    enter(c, Leaf::ERROR_LOCKOUT);
    c.program = ProgramCmd::Abort;
    c.discard = true;
    write_outputs(c);
  }
  last_.contactor = out.contactor;
  last_.brakes_release = out.brakes_release;
  last_.brake_test_axis = out.brake_test_axis;
  ++now_;
  return taken;
}

}  // namespace safestate::core

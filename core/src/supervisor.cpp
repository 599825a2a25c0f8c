#include "safestate/core/supervisor.hpp"

#include <array>
#include <span>
#include <utility>

#include "safestate/core/cia402.hpp"

namespace safestate::core {

namespace {

constexpr bool in_mask(LeafMask m, Leaf l) noexcept { return (m & mask_of(l)) != 0U; }

constexpr auto kResetId = static_cast<std::uint8_t>(CommandId::reset);

constexpr bool is_manual(Mode m) noexcept { return (m == Mode::T1) || (m == Mode::T2); }

// Outputs per leaf (SPEC §3). ARMING (by step), STOPPING (brake phase) and IDLE (lamp)
// refine these in write_outputs().
struct LeafOutputs {
  bool contactor;
  bool drives;
  bool brakes_release;
  bool reset_lamp;
  MotionMode motion;
};
// @req ST-OUTPUTS
constexpr std::array<LeafOutputs, kLeafCount> kLeafOutputs{{
    {false, false, false, false, MotionMode::Track},  // BOOT
    {false, false, false, false, MotionMode::Track},  // ERROR_LOCKOUT
    {false, false, false, false, MotionMode::Track},  // ESTOP_ACTIVE
    {false, false, false, true, MotionMode::Track},   // ESTOP_RESET_NEEDED
    {false, false, false, false, MotionMode::Track},  // IDLE (lamp: latched alarm waiting)
    {true, false, false, false, MotionMode::Track},   // ARMING (drives/brakes by step)
    {true, true, true, false, MotionMode::Hold},      // AUTO_IDLE
    {true, true, true, false, MotionMode::Program},   // AUTO_RUNNING
    {true, true, true, false, MotionMode::Hold},      // AUTO_PAUSED
    {true, true, true, false, MotionMode::Hold},      // MANUAL_IDLE
    {true, true, true, false, MotionMode::Jog},       // MANUAL_JOGGING
    {true, true, true, false, MotionMode::Program},   // MANUAL_RUNNING
    {true, true, true, false, MotionMode::QuickStop}, // STOPPING_CAT1
    {true, true, true, false, MotionMode::Ramp2},     // STOPPING_CAT2
    {true, true, true, false, MotionMode::Hold},      // BRAKE_TEST (the tested brake: brake_test_axis)
}};

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

Cause alarm_cause(std::uint8_t rule, AlarmId a, const AlarmDetail& d, Mode m) noexcept {
  Cause c{};
  c.kind = CauseKind::alarm;
  c.rule = rule;
  c.alarm = a;
  c.detail = d;
  c.mode = m;
  return c;
}

// FIELDBUS_LOST's detail code: the bus position of the subdevice at fault, plus
// kFieldbusSilentFrom when no frame comes back (silent from that subdevice on).
std::uint16_t fieldbus_code(const Feedback& fb) noexcept {
  const bool silent = fb.fieldbus_silent && (fb.fieldbus_subdevice != 0U);
  return static_cast<std::uint16_t>(fb.fieldbus_subdevice | (silent ? kFieldbusSilentFrom : 0U));
}

AlarmDetail detail_of(Signal s, Channel ch = Channel::none, std::uint8_t axis = 0U, std::uint16_t code = 0U) noexcept {
  AlarmDetail d{};
  d.signal = s;
  d.channel = ch;
  d.axis = axis;
  d.code = code;
  return d;
}

}  // namespace

// The data of one cycle, alive only during step(): it views the cycle's inputs and writes
// its outputs, so it holds references by design.
struct SystemStateManager::CycleCtx {
  // NOLINTBEGIN(cppcoreguidelines-avoid-const-or-ref-data-members): a view for one call
  const SafetyInputs& in;
  const Feedback& fb;
  SupervisorOut& out;
  // NOLINTEND(cppcoreguidelines-avoid-const-or-ref-data-members)
  Leaf start_leaf = Leaf::BOOT;
  bool cat0 = false;
  bool discard = false;
  bool deferred = false;  // the current command's answer comes later
  ProgramCmd program = ProgramCmd::None;
  bool at_standstill = false;
  bool boot_passed = false;
  bool boot_failed = false;
  AlarmDetail boot_detail{};
  bool any_drive_faulted = false;  // a statusword decodes to Fault / reaction / unknown
  bool drive_fault = false;        // rule 3: the above, or left Operation enabled on its own
  AlarmDetail drive_detail{};
  bool drive_offline = false;
  std::uint8_t offline_axis = 0;
  bool contactor_welded = false;   // rule 1: open commanded, feedback closed > 100 ms
  std::uint8_t brake_axis = 0;     // rule 3: first axis whose brake did not engage in 300 ms
  std::uint8_t fastest_moving_axis = 0;
  LimitReport limits{};  // SPEC §10 monitors' verdict this cycle
  FieldReport fields{};  // SPEC §11 protective fields
  SsmReport ssm{};       // SPEC §11 speed and separation monitoring
  CollisionReport collision{};  // SPEC §11 collision detection (rule 8)
  BrakeTestVerdict brake_test{};  // SPEC §12 sequencer's verdict this cycle
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
  collision_.configure(limits, cycle_us);
  config_validated_ = validated;
  brake_test_.configure(limits.brake_test, cycle_us, timing_.brake_confirm, timing_.brakes_timeout);
}

GuardView SystemStateManager::view(const CycleCtx& c, std::uint32_t code) const noexcept {
  return GuardView{c.in,           c.fb,           alarms_,           timing_,
                   t2_confirmed_,  boot_pending_,  reset_pending_,    c.at_standstill,
                   c.brake_axis != 0U, &c.limits,  config_validated_, limits_.limits().checksum,
                   code,           c.fields.blocks_start,             c.ssm.over,
                   brake_test_.required(now_)};
}

void SystemStateManager::update_monitors(CycleCtx& c) noexcept {
  const SafetyInputs& in = c.in;
  const Feedback& fb = c.fb;
  alarms_.begin_cycle();

  // @req ST-STANDSTILL
  // Standstill: every axis below the threshold for N consecutive cycles (SPEC §3).
  bool still = true;
  float fastest = 0.0F;
  for (std::size_t i = 0; i < kAxes; ++i) {
    const float v = fb.drive[i].velocity_rad_s;
    const float av = (v < 0.0F) ? -v : v;
    if (!(av < timing_.standstill_rad_s)) {  // NaN is not standstill
      still = false;
    }
    if (av > fastest) {
      fastest = av;
      c.fastest_moving_axis = static_cast<std::uint8_t>(i + 1U);
    }
  }
  standstill_count_ = still ? ((standstill_count_ < timing_.standstill_cycles) ? standstill_count_ + 1U : standstill_count_) : 0U;
  c.at_standstill = standstill_count_ >= timing_.standstill_cycles;

  if (in.mode_changed) {
    t2_confirmed_ = false;  // "T2 confirmed until the mode next changes"
  }
  // SPEC §11 first: the outer field is a source of reduced mode; SSM clamps v_allowed to
  // the TCP limit in force, which the safe limits decide.
  const bool powered = in_mask(kPowered, leaf_);
  fields_.check(in, c.fields);
  limits_.evaluate(fb, powered, in.reduced_requested, c.fields.outer_reduces ? kReducedByField : 0U, c.limits);
  ssm_.check(in, c.limits.tcp_speed_mm_s, c.limits.speed_limit_mm_s, powered, c.ssm);
  // The drives hold the arm, brakes released, nothing pushing a brake: their torques follow the model.
  const bool arm_free = in_mask(kOperationalOrCat2, leaf_) && (leaf_ != Leaf::BRAKE_TEST);
  collision_.check(fb, arm_free, c.collision);
  brake_test_.step(leaf_ == Leaf::BRAKE_TEST, fb, now_, c.brake_test);

  // @req AL-LIFETIME
  // Alarms that are active while their condition lasts.
  constexpr std::size_t kCond = 7U;
  const std::array<AlarmId, kCond> cond{AlarmId::ESTOP_PRESSED, AlarmId::MODE_SELECTOR_INVALID,
                                        AlarmId::RESET_BUTTON_STUCK, AlarmId::CONFIG_NOT_VALIDATED,
                                        AlarmId::REDUCED_SPEED, AlarmId::PERSON_IN_FIELD, AlarmId::BRAKE_TEST_DUE};
  const std::array<bool, kCond> holds{in.estop_pressed, in.mode_invalid, in.reset_stuck, !config_validated_,
                                      limits_.reduced().active(), c.fields.inner_stops, brake_test_.due(now_)};
  const std::array<AlarmDetail, kCond> what{detail_of(Signal::estop, in.estop_cause), detail_of(Signal::mode),
                                            detail_of(Signal::reset_button), detail_of(Signal::internal),
                                            detail_of(Signal::reduced, Channel::none, c.limits.reduced_zone,
                                                      limits_.reduced().sources()),
                                            c.fields.inner_detail, detail_of(Signal::internal)};
  for (std::size_t i = 0; i < kCond; ++i) {
    if (holds[i]) {
      alarms_.raise(cond[i], what[i], now_);
    } else {
      alarms_.clear(cond[i]);
    }
  }
  if (in.enable_panic_edge) {
    alarms_.raise(AlarmId::ENABLING_PANIC, detail_of(Signal::enable, Channel::panic), now_);
  }

  // @req CIA-UNKNOWN ST-UNKNOWN-UNSAFE
  // Drives: decoded state, unknown is a fault (SPEC §3 "unknown is unsafe").
  const auto* arming = std::get_if<StArming>(&state_);
  const bool expect_enabled = in_mask(static_cast<LeafMask>(kOperational | kStopping), leaf_) ||
                              ((arming != nullptr) && (arming->step == ArmingStep::BRAKES));
  for (std::size_t i = 0; i < kAxes; ++i) {
    const DriveFeedback& d = fb.drive[i];
    const auto axis = static_cast<std::uint8_t>(i + 1U);
    if (!d.online) {
      if (!c.drive_offline) {
        c.drive_offline = true;
        c.offline_axis = axis;
      }
      continue;
    }
    const cia402::DriveState ds = cia402::decode(d.statusword);
    const bool faulted = cia402::is_fault(ds);
    c.any_drive_faulted = c.any_drive_faulted || faulted;
    // In a Cat 1 stop the motion layer may put a lagging drive into its own quick stop.
    const bool quick_stop_ok = (leaf_ == Leaf::STOPPING_CAT1) && (ds == cia402::DriveState::QuickStopActive);
    const bool bad = faulted || (expect_enabled && (ds != cia402::DriveState::OperationEnabled) && !quick_stop_ok);
    if (bad && !c.drive_fault) {
      c.drive_fault = true;
      c.drive_detail = detail_of(Signal::drive, Channel::none, axis, d.statusword);
    }
  }
  if (expect_enabled && (fb.following_error_axis != 0U) && !c.drive_fault) {
    c.drive_fault = true;
    c.drive_detail = detail_of(Signal::drive, Channel::none, fb.following_error_axis,
                               fb.drive[static_cast<std::size_t>(fb.following_error_axis - 1U) % kAxes].statusword);
  }
  if (c.any_drive_faulted && (leaf_ != Leaf::BOOT)) {
    // Every condition raises its alarm, also in states where rule 3 stops nothing.
    alarms_.raise(AlarmId::DRIVE_FAULT, c.drive_detail, now_);
  }

  update_feedback_monitors(c);

  // @req TR-BOOT-FAILED
  // BOOT: self-test, fieldbus up, every drive answers, within boot_timeout.
  if (boot_pending_) {
    bool answered = fb.fieldbus_ok;
    for (std::size_t i = 0; i < kAxes; ++i) {
      const DriveFeedback& d = fb.drive[i];
      // A drive answers once it is on the bus and past its own initialisation
      // ("Not ready to switch on" is the drive still starting up).
      const cia402::DriveState ds = cia402::decode(d.statusword);
      if (!d.online || (ds == cia402::DriveState::Unknown) || (ds == cia402::DriveState::NotReadyToSwitchOn)) {
        if (answered) {
          c.boot_detail = detail_of(Signal::drive, Channel::none, static_cast<std::uint8_t>(i + 1U), d.statusword);
        }
        answered = false;
      }
    }
    if (!fb.fieldbus_ok || fb.fieldbus_boot_failed) {
      c.boot_detail = detail_of(Signal::fieldbus, Channel::none, 0U, fb.fieldbus_subdevice);
    }
    const bool self_test = self_test_ok_ && fb.self_test_ok;
    if (self_test && answered && !fb.fieldbus_boot_failed) {
      boot_pending_ = false;
      c.boot_passed = true;
    } else if (!self_test || fb.fieldbus_boot_failed || (now_ > timing_.boot_timeout)) {
      c.boot_failed = true;
      if (!self_test) {
        c.boot_detail = detail_of(Signal::internal);
      }
    }
  }

  // Timers carried by the states themselves.
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

// @req AL-FEEDBACK
// ISO 13849-1 external device monitoring (SPEC §7): the contactor's auxiliary contact and
// every brake feedback must follow what this core commanded in the previous cycle.
void SystemStateManager::update_feedback_monitors(CycleCtx& c) noexcept {
  const bool welded_now = !contactor_cmd_ && c.fb.contactor_closed;
  welded_cycles_ = welded_now ? welded_cycles_ + 1U : 0U;
  c.contactor_welded = welded_cycles_ > timing_.contactor_timeout;
  // A brake counts as engaged only after its feedback said so for brake_confirm cycles
  // without a break; until then its time runs from the first released reading, so a
  // feedback that chatters is still released when the brake time is over.
  for (std::size_t i = 0; i < kAxes; ++i) {
    // The brake test engages one brake while the others stay released (SPEC §12).
    const bool release_cmd = brakes_release_cmd_ && (brake_test_axis_cmd_ != (i + 1U));
    const bool stuck_now = !release_cmd && c.fb.brake_released[i];
    const bool engaged_now = !release_cmd && !c.fb.brake_released[i];
    brake_engaged_run_[i] = engaged_now ? brake_engaged_run_[i] + 1U : 0U;
    if (release_cmd || (brake_engaged_run_[i] >= timing_.brake_confirm)) {
      brake_cycles_[i] = 0U;
    } else if (stuck_now || (brake_cycles_[i] != 0U)) {
      ++brake_cycles_[i];
    } else {
      // engaged reading, not confirmed yet, nothing released since the last confirmation
    }
    if (stuck_now && (brake_cycles_[i] > timing_.brakes_timeout) && (c.brake_axis == 0U)) {
      c.brake_axis = static_cast<std::uint8_t>(i + 1U);
    }
  }
  if (c.brake_axis != 0U) {
    // Latched in every state, like DRIVE_FAULT: an axis without its brake is a hazard
    // whether or not rule 3 has a stop to make.
    alarms_.raise(AlarmId::BRAKE_NOT_ENGAGED, detail_of(Signal::brake, Channel::none, c.brake_axis), now_);
  }
}

// @req TR-PRIORITY TR-EVERY-ALARM
bool SystemStateManager::evaluate_conditions(CycleCtx& c) noexcept {
  const SafetyInputs& in = c.in;
  const Feedback& fb = c.fb;
  bool decided = false;
  for (std::size_t t = 0; t < kConditionCount; ++t) {
    const auto trig = static_cast<Trigger>(t);
    const Transition* row = find_row(c.start_leaf, trig);
    if (row == nullptr) {
      continue;  // this rule does not apply in this state
    }
    const std::uint8_t rule = kConditionRule[t];
    bool holds = false;
    Cause cause{};
    // Evaluate the condition; raise every alarm it implies; remember the first as cause.
    auto hit = [&](AlarmId a, const AlarmDetail& d) {
      alarms_.raise(a, d, now_);
      if (!holds) {
        cause = alarm_cause(rule, a, d, in.mode);
      }
      holds = true;
    };
    switch (trig) {
      case Trigger::lockout_condition: {
        // The dual-channel inputs' discrepancies, in the order of SPEC §2 and §11.
        const std::array<std::pair<bool, AlarmId>, 4> discrepancies{{
            {in.estop_discrepancy, AlarmId::ESTOP_DISCREPANCY},
            {in.gate_discrepancy, AlarmId::GATE_DISCREPANCY},
            {in.enable_discrepancy, AlarmId::ENABLE_DISCREPANCY},
            {c.fields.discrepancy, AlarmId::FIELD_DISCREPANCY}}};
        const std::array<AlarmDetail, 4> where{detail_of(Signal::estop, in.estop_fault_channel),
                                               detail_of(Signal::gate, in.gate_fault_channel),
                                               detail_of(Signal::enable, in.enable_fault_channel),
                                               c.fields.discrepancy_detail};
        for (std::size_t k = 0; k < discrepancies.size(); ++k) {
          if (discrepancies[k].first) {
            hit(discrepancies[k].second, where[k]);
          }
        }
        if (!boot_pending_ && !fb.fieldbus_ok) {
          hit(AlarmId::FIELDBUS_LOST, detail_of(Signal::fieldbus, Channel::none, 0U, fieldbus_code(fb)));
        }
        if (!boot_pending_ && c.drive_offline) {
          hit(AlarmId::FIELDBUS_LOST, detail_of(Signal::drive, Channel::none, c.offline_axis));
        }
        if (!fb.integrity_ok || integrity_fault_) {
          hit(AlarmId::INTEGRITY_FAULT, detail_of(Signal::internal));
        }
        if (c.boot_failed) {
          hit(AlarmId::BOOT_FAILED, c.boot_detail);
        }
        if (c.contactor_welded) {
          hit(AlarmId::CONTACTOR_WELDED, detail_of(Signal::contactor));
        }
        break;
      }
      case Trigger::estop_pressed:
        if (in.estop_pressed) {
          hit(AlarmId::ESTOP_PRESSED, detail_of(Signal::estop, in.estop_cause));
        }
        break;
      case Trigger::stop_fault: {
        if (c.drive_fault) {
          hit(AlarmId::DRIVE_FAULT, c.drive_detail);
        }
        // @req MO-T1-MONITOR
        // `!(x <= limit)` so that a NaN speed counts as exceeded (unknown is unsafe).
        // The T1 monitor watches motion armed in T1. A key turned to T1 while the arm
        // moves at another mode's speed is rule 6's (Cat 1), not a T1 speed fault.
        if ((in.mode == Mode::T1) && (armed_mode_ == Mode::T1) &&
            !(fb.max_point_speed_mm_s <= timing_.t1_speed_limit_mm_s)) {
          hit(AlarmId::T1_SPEED_EXCEEDED, detail_of(Signal::drive, Channel::none, fb.fastest_axis,
                                                    detail_code(fb.max_point_speed_mm_s)));
        }
        // @req ST-STOP-TIME
        const auto* s = std::get_if<StStopping>(&state_);
        if ((s != nullptr) && !s->braking && (s->elapsed > timing_.max_stop)) {
          hit(AlarmId::STOP_TIME_EXCEEDED, detail_of(Signal::drive, Channel::none, c.fastest_moving_axis));
        }
        if (c.brake_axis != 0U) {
          hit(AlarmId::BRAKE_NOT_ENGAGED, detail_of(Signal::brake, Channel::none, c.brake_axis));
        }
        // @req LIM-RULE3
        for (const auto& [id, f] : {std::pair{AlarmId::JOINT_LIMIT, &c.limits.joint},
                                    std::pair{AlarmId::ZONE_VIOLATION, &c.limits.zone},
                                    std::pair{AlarmId::ORIENTATION_LIMIT, &c.limits.orientation},
                                    std::pair{AlarmId::SPEED_LIMIT, &c.limits.speed},
                                    std::pair{AlarmId::SEPARATION_VIOLATED, &c.ssm.violated}}) {
          if (f->hit) {
            hit(id, f->detail);
          }
        }
        break;
      }
      case Trigger::gate_open_in_auto:
        if (in.gate_open && (in.mode == Mode::AUTO)) {
          hit(AlarmId::PROTECTIVE_STOP, detail_of(Signal::gate, in.gate_cause));
        }
        break;
      case Trigger::enable_left_centre:
        if (is_manual(in.mode) && !in.enable_ok) {
          if (in.enable == EnablePos::panic) {
            hit(AlarmId::ENABLING_PANIC, detail_of(Signal::enable, Channel::panic));
          } else {
            holds = true;  // a release raises no alarm: it is the normal way to stop
            cause.kind = CauseKind::event;
            cause.rule = rule;
            cause.mode = in.mode;
            cause.detail = detail_of(Signal::enable, in.enable_cause);
          }
        }
        break;
      case Trigger::mode_changed:
        if (in.mode_changed) {
          hit(AlarmId::MODE_CHANGED, detail_of(Signal::mode, Channel::none, 0U, static_cast<std::uint16_t>(in.mode)));
        }
        break;
      case Trigger::jog_timeout:
        if ((now_ - last_jog_) > timing_.jog_timeout) {
          hit(AlarmId::JOG_LINK_LOST, detail_of(Signal::command));
        }
        break;
      // @req COL-COLLISION
      case Trigger::collision:
        if (c.collision.hit.hit) {
          hit(AlarmId::COLLISION, c.collision.hit.detail);
        }
        break;
      // @req COL-FIELD-GUARD
      case Trigger::person_in_field:
        if (c.fields.inner_stops) {
          hit(AlarmId::PERSON_IN_FIELD, c.fields.inner_detail);
        }
        break;
      // @req BT-RULE10
      case Trigger::brake_test_failed:
        if (c.brake_test.failed) {
          // Names the axis and its drift (code: millidegrees, saturated).
          const float mdeg = c.brake_test.fail_drift_deg * 1000.0F;
          hit(AlarmId::BRAKE_TEST_FAILED, detail_of(Signal::axis, Channel::none, c.brake_test.fail_axis, detail_code(mdeg)));
        }
        break;
      default:
        break;
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
    fired = c.boot_passed;
  } else if (leaf_ == Leaf::ESTOP_ACTIVE) {
    trig = Trigger::estop_released;
    fired = !c.in.estop_pressed;
  } else if (auto* a = std::get_if<StArming>(&state_)) {
    bool done = false;
    Cycle limit = timing_.contactor_timeout;
    std::uint8_t laggard = 0;  // the first axis not there yet: the timeout names it
    switch (a->step) {
      case ArmingStep::CONTACTOR:
        done = c.fb.contactor_closed;
        break;
      case ArmingStep::DRIVES:
        limit = timing_.drives_timeout;
        for (std::size_t i = 0; (i < kAxes) && (laggard == 0U); ++i) {
          const bool enabled = cia402::decode(c.fb.drive[i].statusword) == cia402::DriveState::OperationEnabled;
          laggard = enabled ? 0U : static_cast<std::uint8_t>(i + 1U);
        }
        done = laggard == 0U;
        break;
      case ArmingStep::BRAKES:
        limit = timing_.brakes_timeout;
        for (std::size_t i = 0; (i < kAxes) && (laggard == 0U); ++i) {
          laggard = c.fb.brake_released[i] ? 0U : static_cast<std::uint8_t>(i + 1U);
        }
        done = laggard == 0U;
        break;
    }
    const auto step_index = static_cast<std::uint8_t>(a->step);
    if (done && (a->step == ArmingStep::BRAKES)) {
      trig = Trigger::arming_complete;
      fired = true;
      a->progress = 100U;
    } else if (done) {
      a->step = static_cast<ArmingStep>(step_index + 1U);
      a->step_elapsed = 0;
    } else if (a->step_elapsed > limit) {
      trig = Trigger::arming_timeout;
      fired = true;
      AlarmDetail d{};
      d.signal = (a->step == ArmingStep::CONTACTOR) ? Signal::contactor
                                                    : ((a->step == ArmingStep::DRIVES) ? Signal::drive : Signal::brake);
      d.step = a->step;
      d.has_step = true;
      d.axis = laggard;
      alarms_.raise(AlarmId::ARMING_TIMEOUT, d, now_);
      cause = alarm_cause(0U, AlarmId::ARMING_TIMEOUT, d, c.in.mode);
    }
    if (!fired) {
      const Cycle span = (a->step == ArmingStep::CONTACTOR)
                             ? timing_.contactor_timeout
                             : ((a->step == ArmingStep::DRIVES) ? timing_.drives_timeout : timing_.brakes_timeout);
      const Cycle part = (span > 0U) ? ((a->step_elapsed * 33U) / (span + 1U)) : 0U;
      a->progress = static_cast<std::uint8_t>((static_cast<Cycle>(a->step) * 33U) + part);
    }
  } else if ((leaf_ == Leaf::AUTO_RUNNING) || (leaf_ == Leaf::MANUAL_RUNNING)) {
    trig = Trigger::program_finished;
    fired = c.fb.program_finished;
  } else if (leaf_ == Leaf::AUTO_PAUSED) {
    trig = Trigger::fields_clear;  // SPEC §11: only a pause of rule 9 resumes by itself
    fired = field_paused_ && c.fields.resume_due;
  } else if (leaf_ == Leaf::BRAKE_TEST) {
    trig = Trigger::brake_test_passed;
    fired = c.brake_test.passed;
  } else if (auto* s = std::get_if<StStopping>(&state_)) {
    trig = Trigger::standstill;
    if (!s->braking) {
      // SPEC §11 rule 8: not at the end while the motion layer still backs off (the stop
      // time monitor bounds it).
      if (c.at_standstill && !(s->back_off && c.fb.backing_off)) {
        if (s->category == StopCat::CAT2) {
          fired = true;
        } else {
          // IEC 60204-1 Cat 1: at standstill engage the brakes while the drives still
          // hold, and remove power once the brakes have engaged.
          s->braking = true;
          s->brake_elapsed = 0;
        }
      }
    } else {
      bool engaged = true;
      for (const bool released : c.fb.brake_released) {
        engaged = engaged && !released;
      }
      fired = engaged || (s->brake_elapsed > timing_.brakes_timeout);
    }
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
  if (!c.any_drive_faulted) {
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
  if (leaf_ == Leaf::ERROR_LOCKOUT) {
    return Result::LOCKED_OUT;
  }
  // @req RES-OWNER
  // 3. Ownership (single point of control, ISO 10218-1 5.3.5).
  const auto src = static_cast<Source>(cmd.source);
  if (src == Source::observer) {
    return Result::NOT_CONTROL_OWNER;
  }
  if ((src == Source::remote) && ((id == CommandId::reset) || (c.in.mode != Mode::AUTO))) {
    return Result::NOT_CONTROL_OWNER;
  }
  if ((src == Source::reset_button) && (id != CommandId::reset)) {
    return Result::NOT_CONTROL_OWNER;
  }
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
      if (c.any_drive_faulted) {
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
    case Effect::start_program:
      c.program = ProgramCmd::Start;
      break;
    case Effect::resume_program:
      c.program = ProgramCmd::Resume;
      break;
    case Effect::abort_program:
      c.program = ProgramCmd::Abort;
      break;
    case Effect::jog_keepalive:
      last_jog_ = now_;
      if (cmd != nullptr) {
        jog_.axis = static_cast<std::uint8_t>(cmd->axis);
        jog_.dir = cmd->dir;
        jog_.speed = cmd->speed;
      }
      break;
    case Effect::set_t2_confirmed:
      t2_confirmed_ = true;
      break;
    case Effect::set_validated:
      config_validated_ = true;
      break;
    case Effect::field_pause:
      field_paused_ = true;
      break;
    case Effect::begin_arming:
      armed_mode_ = c.in.mode;
      break;
    case Effect::begin_brake_test:
      brake_test_.begin(now_);
      break;
    case Effect::back_off_abort:
      c.program = ProgramCmd::Abort;
      break;
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
  o.at_standstill = c.at_standstill;
  o.pendant_owner = is_manual(c.in.mode);
  o.cause = cause_;
  o.alarms = alarms_.mask();
  o.alarms_raised = alarms_.raised();
  o.alarms_cleared = alarms_.cleared();
  o.motion.reduced = limits_.reduced().active();
  o.motion.reduced_limit_mm_s = limits_.reduced().limit();
  o.motion.v_allowed_mm_s = c.ssm.acting ? c.ssm.v_plan_mm_s : -1.0F;
  o.motion.recovery = c.limits.recovering;
  SafetyStatus& st = o.safety;
  st.checksum = limits_.limits().checksum;
  st.validated = config_validated_;
  st.reduced = limits_.reduced().active();
  st.reduced_by = limits_.reduced().sources();
  st.recovery = c.limits.recovering;
  st.outside = c.limits.outside;
  st.speed_limit_mm_s = c.limits.speed_limit_mm_s;
  st.tcp_speed_mm_s = c.limits.tcp_speed_mm_s;
  st.field_outer_interrupted = c.in.field_outer_interrupted;
  st.field_inner_interrupted = c.in.field_inner_interrupted;
  st.ssm = c.ssm.acting;
  st.v_allowed_mm_s = c.ssm.v_allowed_mm_s;
  st.separation_mm = c.ssm.separation_mm;
  st.pfl = c.collision.acting;
  st.contact_force_n = c.collision.force_n;
  // SPEC §12: the tested brake and the test's offset and torque, only while testing.
  const bool testing = (leaf_ == Leaf::BRAKE_TEST) && c.brake_test.running;
  o.brake_test_axis = testing ? c.brake_test.brake_engaged_axis : 0U;
  o.motion.brake_test = testing ? c.brake_test.motion : BrakeTestRequest{};
  brake_test_.status(now_, o.brake_test);
}

bool SystemStateManager::outputs_consistent(const CycleCtx& c) const noexcept {
  // A second, independent reading of the safety outputs (diverse check): power only in
  // the powered states, nothing powered while the E-stop is pressed, and the state data
  // agreeing with the state the table believes in.
  const SupervisorOut& o = c.out;
  const bool powered_state = in_mask(kPowered, leaf_);
  const bool any_power = o.contactor || o.drives_enable || o.brakes_release;
  if (any_power && !powered_state) {
    return false;
  }
  if (c.in.estop_pressed && any_power) {
    return false;
  }
  if ((o.motion.mode == MotionMode::Jog) && (leaf_ != Leaf::MANUAL_JOGGING)) {
    return false;
  }
  if ((o.motion.mode == MotionMode::Program) && (leaf_ != Leaf::AUTO_RUNNING) && (leaf_ != Leaf::MANUAL_RUNNING)) {
    return false;
  }
  return leaf_of(state_) == leaf_;
}

std::size_t SystemStateManager::step(const SafetyInputs& in, const Feedback& fb, const Command* cmds, std::size_t n,
                                     SupervisorOut& out) noexcept {
  out.reply_count = 0;
  out.transition_count = 0;
  CycleCtx c{in, fb, out, leaf_};

  // @req CYC-ORDER CYC-ZERO-DELAY
  update_monitors(c);
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
  if (!outputs_consistent(c)) {
    integrity_fault_ = true;
    alarms_.raise(AlarmId::INTEGRITY_FAULT, detail_of(Signal::internal), now_);
    set_cause(alarm_cause(1U, AlarmId::INTEGRITY_FAULT, detail_of(Signal::internal), in.mode));
    c.cat0 = true;
    enter(c, Leaf::ERROR_LOCKOUT);
    c.program = ProgramCmd::Abort;
    c.discard = true;
    write_outputs(c);
  }
  contactor_cmd_ = out.contactor;
  brakes_release_cmd_ = out.brakes_release;
  brake_test_axis_cmd_ = out.brake_test_axis;
  ++now_;
  return taken;
}

}  // namespace safestate::core

#!/usr/bin/env python3
"""Mutation testing of core/: does the test suite notice when the supervisor is wrong?

Mutant families (issue 6):
  row       drop each transition row (it no longer applies where it did)
  guard     flip each condition of each guard
  timer     move each timer threshold by one cycle (> becomes >=, >= becomes >)
  stop      swap the stop category of each row (CAT0->CAT1, CAT1->CAT2, CAT2->CAT1)
  output    invert each output of each state in the output table, and of ARMING/STOPPING
  monitor   weaken each safe-limit monitor of core/src/monitors/ (SPEC §10): a bound or a
            check dropped, a threshold given slack, recovery's "not worse" loosened, the
            reduced limit or its ramp lost, the wrong axis or zone named; and each of the
            supervisor's rule-3 entries for them dropped
  brake     weaken the brake test of SPEC §12 (core/src/monitors/brake_test.cpp): the drift
            comparison given slack, made one-sided or dropped, the pushes shortened; the due
            logic's interval, grace, never-tested and failed cases loosened; the servo_on
            guard's BRAKE_TEST_REQUIRED dropped
  collision SPEC §11 rule 8: the collision monitor's threshold, its two-sample count, its
            gating (pfl, arm free), the model's gravity and the estimate's sign, the torque
            scaling, the supervisor's rule-8 entry and its wait for the back-off
  margin    remove each planning margin of the motion layer (motion/limits.hpp: 1 deg,
            10 mm, 5 %, 1 deg), so that a jog holds at the limit itself
  round3    issue 40: the joint-range loop's bounds, the reduced ramp's restart and sources,
            the speed monitor's limit and axes, the order of the safe-limit monitors, the
            ramp's unit, the constants of monitors.hpp (recovery tolerances, reduced-by bits,
            SSM tolerance)
  stopdata  safety/src/stopping_check.cpp: the stopping data a configuration is judged by
            (its payload's level), the comparisons of max_time_ms, decel and reaction
  collab    SPEC §11: the v_allowed formula (each term: v_h, a·T_r, C, Z, the 500 mm switch,
            the clamp), the PFL cap, the field logic (mode, which field, the resume delay
            and its reset, auto_resume, the lowest reduced limit, the discrepancy), the SSM
            monitor (tolerance, T_r, the separation's rise bound) and the supervisor's and
            guards' entries for them

Each mutant is applied to a copy of the source in build-mut/src, built, and run against
the unit tests, the scenario suite, the differential test and the exhaustive checker.
A mutant is killed when a test fails, stillborn when it does not compile. Writes
build-mut/mutation.json and build-mut/mutation.md (score and every survivor).

Each mutant is judged in phases to keep the run short: first only the differential test
(one small binary to rebuild, fails at the first cycle where core and reference differ),
then for the monitor, margin, collab and brake families the unit tests of that code (one
binary); a mutant that survives those is rebuilt in full and meets every selected suite.
Outcomes are appended to build-mut/progress.jsonl as they come; `--resume` skips the
mutants already judged there (the run takes over an hour on two cores).
"""
import argparse
import json
import os
import re
from shlex import quote as shlex_quote
import shutil
import subprocess
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
WORK = os.path.join(ROOT, "build-mut")
SRC = os.path.join(WORK, "src")
BUILD = os.path.join(WORK, "build")
TRANSITIONS = "core/include/safestate/core/transitions.hpp"
GUARDS = "core/src/guards.cpp"
SUPERVISOR = "core/src/supervisor.cpp"
SIGNALS = "core/src/signals.cpp"
MON = "core/src/monitors/"
MARGINS = "motion/include/safestate/motion/limits.hpp"
# The suites that judge core/: the unit tests of the state machine and signal layer, the
# differential test, the scenario suite and the exhaustive checker. Only their binaries
# are rebuilt for each mutant.
TARGETS = "test_transitions test_commands test_principles test_signals test_guards test_reference test_safe_limits test_motion_limits test_collaborative test_brake_test test_collision test_rta safestate"
SELECT = "^(StoppingCheck|StoppingData|JointLimits|Reporter|GuardReset|GuardServoOn|Ssm|Pfl|FieldMonitor|SsmMonitor|CollisionModel|CollisionEstimate|CollisionMonitor|CollisionCell|BrakeTestCore|BrakeTestCell|CoreArm|SpeedLimit|SpeedLimits|Orientation|Zones|Recovery|ReducedMode|MotionLimits|ProgramLimits|Boot|Rule|TransitionTable|EstopActive|EstopResetNeeded|Idle|Arming|Operational|AutoIdle|AutoRunning|AutoPaused|ManualIdle|ManualJogging|ManualRunning|Stopping|ConfirmT2|CheckOrder|Results|OneResult|ResetButtonRule|NoSurpriseMotion|UnknownIsUnsafe|Cat1Completes|EveryConditionRaisesItsAlarm|DualChannel|EnablingDevice|ModeSelector|ResetButton|SignalLayer|Differential|scenario/|check_invariants)"


def read(rel):
    with open(os.path.join(ROOT, rel)) as f:
        return f.read()


def mutants():
    out = []
    # --- rows: each row of kTransitions moved away from its from-states -------------
    t = read(TRANSITIONS)
    rows = [m for m in re.finditer(r"^  \{(k\w+|only\(\w+\)),\s+(\w+),.*\},?\s*$", t, re.M)]
    for i, m in enumerate(rows):
        line = m.group(0)
        target = "only(BOOT)" if m.group(2) == "lockout_condition" else "only(ERROR_LOCKOUT)"
        new = line.replace(m.group(1), target, 1)
        out.append(("row", f"row {i + 1} ({m.group(2)} from {m.group(1)}) dropped", TRANSITIONS, line, new))
    # --- stop categories of each row -------------------------------------------------
    swap = {"CAT0": "CAT1", "CAT1": "CAT2", "CAT2": "CAT1"}
    for i, m in enumerate(rows):
        line = m.group(0)
        cat = re.search(r",\s+(CAT0|CAT1|CAT2),", line)
        if cat:
            new = line[: cat.start(1)] + swap[cat.group(1)] + line[cat.end(1):]
            out.append(("stop", f"row {i + 1} ({m.group(2)}) {cat.group(1)} -> {swap[cat.group(1)]}", TRANSITIONS, line, new))
    # --- guards: negate each `if (...)` condition inside the guard functions ------------
    g = read(GUARDS)
    for m in re.finditer(r"^(\s+)if \((.*)\) \{$", g, re.M):
        line = m.group(0)
        new = f"{m.group(1)}if (!({m.group(2)})) {{"
        out.append(("guard", f"guards.cpp: if ({m.group(2)[:60]}) negated", GUARDS, line, new))
    for m in re.finditer(r"^(\s+return )(.+) \? (Result::\w+) : (Result::\w+);$", g, re.M):
        line = m.group(0)
        new = f"{m.group(1)}{m.group(2)} ? {m.group(4)} : {m.group(3)};"
        out.append(("guard", f"guards.cpp: {m.group(2)[:40]} ? swapped", GUARDS, line, new))
    # --- timers: each threshold comparison moved by one ---------------------------------
    for rel in (SUPERVISOR, SIGNALS):
        s = read(rel)
        for m in re.finditer(r"^.*(\S+) (>=|>) (timing_\.\w+|limit|hold_limit|timing_\.standstill_cycles)\b.*$", s, re.M):
            line = m.group(0)
            op = m.group(2)
            new_op = ">" if op == ">=" else ">="
            new = line.replace(f" {op} {m.group(3)}", f" {new_op} {m.group(3)}", 1)
            if new != line:
                out.append(("timer", f"{os.path.basename(rel)}: `{op} {m.group(3)}` -> `{new_op}`", rel, line, new))
    # --- outputs: each cell of kLeafOutputs, and the ARMING/STOPPING refinements -------
    s = read(SUPERVISOR)
    for m in re.finditer(r"^    \{(true|false), (true|false), (true|false), (true|false), MotionMode::\w+\},\s*// (\w+).*$", s, re.M):
        line = m.group(0)
        names = ["contactor", "drives", "brakes_release", "reset_lamp"]
        for k in range(4):
            vals = [m.group(1), m.group(2), m.group(3), m.group(4)]
            vals[k] = "false" if vals[k] == "true" else "true"
            new = re.sub(r"\{(true|false), (true|false), (true|false), (true|false),",
                         "{" + ", ".join(vals) + ",", line, count=1)
            out.append(("output", f"{m.group(5)}: {names[k]} inverted", SUPERVISOR, line, new))
    for pat, desc in [(r"o\.drives_enable = lo\.drives \|\| \(a->step != ArmingStep::CONTACTOR\);", "ARMING drives_enable inverted"),
                      (r"o\.brakes_release = lo\.brakes_release \|\| \(a->step == ArmingStep::BRAKES\);", "ARMING brakes_release inverted"),
                      (r"o\.brakes_release = false;", "STOPPING braking: brakes stay released")]:
        m = re.search(r"^.*" + pat + r".*$", s, re.M)
        if m:
            line = m.group(0)
            new = (line.replace("!=", "==") if "!=" in line else
                   line.replace("== ArmingStep::BRAKES", "!= ArmingStep::BRAKES") if "== ArmingStep" in line else
                   line.replace("= false;", "= true;"))
            out.append(("output", desc, SUPERVISOR, line, new))
    # --- monitors: each safe-limit monitor weakened (SPEC §10) ---------------------------
    J, R, Z, O, S, RM, SL = (MON + f for f in ("joint_limits.cpp", "recovery.cpp", "zones.cpp", "orientation.cpp",
                                                "speed_limits.cpp", "reduced_mode.cpp", "safe_limits.cpp"))
    weak = [
        (J, "const float below = l.min_rad - q;", "const float below = -1.0F;", "joint: lower bound dropped"),
        (J, "const float above = q - l.max_rad;", "const float above = -1.0F;", "joint: upper bound dropped"),
        (J, "(q == q) ? outside : q", "(q == q) ? (outside - 0.01F) : q", "joint: 0.01 rad of slack"),
        (J, "if (trips && !r.joint.hit) {", "if (trips && r.joint.hit) {", "joint: finding never reported"),
        (J, "r.joint.detail.axis = static_cast<std::uint8_t>(i + 1U);", "r.joint.detail.axis = static_cast<std::uint8_t>(i);", "joint: wrong axis named"),
        (R, "  if (!powered) {", "  if (false) {", "recovery: none (found without power trips at power-on)"),
        (R, "    t.recovering = out;", "    t.recovering = false;", "recovery: never entered"),
        (R, "    t.recovering = false;  // back inside", "    // back inside", "recovery: not left when back inside"),
        (R, "if (!t.recovering || !(outside <= (t.best + tolerance))) {", "if (!t.recovering) {", "recovery: worse allowed"),
        (R, "(t.best + tolerance)", "(t.best + (10.0F * tolerance))", "recovery: tolerance x10"),
        (R, "  if (outside < t.best) {", "  if (false) {", "recovery: best never improves (creep back allowed)"),
        (R, "const bool out = !(outside <= 0.0F);", "const bool out = outside > 0.0F;", "recovery: NaN no longer outside"),
        (Z, "(p[2] >= z.min_mm[2]) && (p[2] <= z.max_mm[2])", "true", "zones: inside() ignores z"),
        (Z, "(z.min_mm[k] + r) - p[k]", "z.min_mm[k] - p[k]", "zones: keep_in sphere radius dropped at min"),
        (Z, "p[k] - (z.max_mm[k] - r)", "p[k] - z.max_mm[k]", "zones: keep_in sphere radius dropped at max"),
        (Z, "return r - std::sqrt(d2);", "return -std::sqrt(d2);", "zones: keep_out sphere radius dropped"),
        (Z, "return r + to_face + ((r > 0.0F) ? 0.0F : 1.0e-3F);", "return -1.0F;", "zones: a point inside a keep_out box not seen"),
        (Z, "for (std::size_t k = kFirstLinkPoint; k < kArmFrames; ++k) {", "for (std::size_t k = kFirstLinkPoint; k < kFirstLinkPoint; ++k) {", "zones: link points dropped"),
        (Z, "const std::size_t n = (c.limits.zone_count < kMaxZones) ? c.limits.zone_count : kMaxZones;",
            "const std::size_t n = (c.limits.zone_count < kMaxZones) ? ((c.limits.zone_count > 0U) ? c.limits.zone_count - 1U : 0U) : kMaxZones;",
            "zones: the last zone dropped"),
        (Z, "    if (z.kind == ZoneKind::reduced) {\n      reduced = ", "    if (z.kind != ZoneKind::keep_out) {\n      reduced = ", "zones: keep_in boxes not checked"),
        (Z, "      if (!r.in_reduced_zone && inside(z, c.pose.tcp)) {", "      if (false) {", "zones: reduced zone dropped"),
        (Z, "      if (inside(c.limits.zones[i], c.pose.tcp)) {", "      if (false) {", "zones: reduced zone dropped while the others are skipped"),
        (Z, "      clear_until_[i] = travel + gap;", "      clear_until_[i] = travel + gap + 50.0F;", "zones: a clear zone skipped 50 mm too long"),
        (Z, "    if (travel < clear_until_[i]) {", "    if (travel <= clear_until_[i] + 1.0e9F) {", "zones: a zone once clear never tested again"),
        (Z, "track_violation(track_[i], outside, c.powered, kWorseZoneMm)", "track_violation(track_[i], outside - 5.0F, c.powered, kWorseZoneMm)", "zones: 5 mm of slack"),
        (Z, "r.zone.detail.code = static_cast<std::uint16_t>(i);", "r.zone.detail.code = 0U;", "zones: wrong zone named"),
        (Z, "      const float below = z.min_mm[k] - b.hi[k];", "      const float below = z.min_mm[k] - b.hi[k] + 50.0F;", "zones: bounding box lets 50 mm into a keep_out box"),
        (Z, "  float s = b.lo[0] - z.min_mm[0];", "  float s = b.lo[0] - z.min_mm[0] + 50.0F;", "zones: bounding box lets 50 mm out of a keep_in box"),
        (O, "  if (!c.limits.orientation_enabled) {", "  if (true) {", "orientation: monitor dropped"),
        (SL, "orientation_cos_ = std::cos(limits_.orientation_max_deviation_rad);",
             "orientation_cos_ = std::cos(limits_.orientation_max_deviation_rad * 1.05F);", "orientation: 5 % slack"),
        (O, " + (a[2] * z[2]);", ";", "orientation: z component dropped"),
        (S, "if (!(speed <= c.limits.joints[i].max_speed_rad_s)) {", "if (!(speed <= (1.05F * c.limits.joints[i].max_speed_rad_s))) {", "speed: joints 5 % slack"),
        (S, "const float speed = (v < 0.0F) ? -v : v;", "const float speed = v;", "speed: negative direction unchecked"),
        (S, "if (!f.hit && !(r.tcp_speed_mm_s <= r.speed_limit_mm_s)) {", "if (false) {", "speed: TCP check dropped"),
        (S, "if (!f.hit && !(r.tcp_speed_mm_s <= r.speed_limit_mm_s)) {", "if (!f.hit && !(r.tcp_speed_mm_s <= (1.05F * r.speed_limit_mm_s))) {", "speed: TCP 5 % slack"),
        (S, "c.reduced_enforced ? c.reduced_limit_mm_s : c.limits.tcp_max_speed_mm_s",
            "c.limits.tcp_max_speed_mm_s", "speed: reduced limit never applied"),
        (S, "point_speed(c.pose, c.pose.tcp, kAxes, c.qd)", "point_speed(c.pose, c.pose.tcp, 3U, c.qd)", "speed: TCP speed without the wrist"),
        (S, "  r.speed_over = f.hit;", "  r.speed_over = false;", "speed: reset guard blind to a speed still over"),
        (RM, "} else if (elapsed_ <= ramp_) {", "} else if (elapsed_ < ramp_) {", "reduced: ramp never ends (limit never enforced)"),
        (SL, "(input_reduced ? kReducedByInput : 0U)", "0U", "reduced: input ignored"),
        (SL, "ms_to_cycles(limits_.reduced_ramp_ms, cycle_us)", "(10U * ms_to_cycles(limits_.reduced_ramp_ms, cycle_us))", "reduced: ramp 10x longer"),
        (SL, "  joints_.check(ctx, out);\n", "", "joint monitor dropped"),
        (SL, "  zones_.check(ctx, out);\n", "", "zone monitor dropped"),
        (SL, "  orientation_.check(ctx, out);\n", "", "orientation monitor dropped"),
        (SL, "  SpeedLimitMonitor::check(ctx, out);\n", "", "speed monitor dropped"),
        (SL, "a = {a[0] / len, a[1] / len, a[2] / len};", "a = {a[0], a[1], a[2]};", "orientation axis not normalised"),
        (SUPERVISOR, "std::pair{AlarmId::JOINT_LIMIT, &c.limits.joint}", "std::pair{AlarmId::JOINT_LIMIT, &c.limits.zone}", "rule 3: JOINT_LIMIT entry dropped"),
        (SUPERVISOR, "std::pair{AlarmId::ZONE_VIOLATION, &c.limits.zone}", "std::pair{AlarmId::ZONE_VIOLATION, &c.limits.joint}", "rule 3: ZONE_VIOLATION entry dropped"),
        (SUPERVISOR, "std::pair{AlarmId::ORIENTATION_LIMIT, &c.limits.orientation}", "std::pair{AlarmId::ORIENTATION_LIMIT, &c.limits.joint}", "rule 3: ORIENTATION_LIMIT entry dropped"),
        (SUPERVISOR, "std::pair{AlarmId::SPEED_LIMIT, &c.limits.speed}", "std::pair{AlarmId::SPEED_LIMIT, &c.limits.joint}", "rule 3: SPEED_LIMIT entry dropped"),
    ]
    for rel, old, new, desc in weak:
        out.append(("monitor", desc, rel, old, new))  # "not applied" if the text has gone
    # --- collaborative operation (SPEC §11): the formula and the field logic ----------------
    CO, FI, SS = "core/src/collaborative.cpp", MON + "fields.cpp", MON + "ssm.cpp"
    collab = [
        (CO, "return (near && (p.human_speed_mm_s < kHumanSpeedNearMmS)) ? kHumanSpeedNearMmS : p.human_speed_mm_s;",
             "return p.human_speed_mm_s;", "formula: no 2000 mm/s within 500 mm"),
        (CO, "const bool near = !(separation_mm > kSsmNearMm);", "const bool near = separation_mm < kSsmNearMm;",
             "formula: the switch at 500 mm moved (500 itself far)"),
        (CO, "(v_h * v_h) + (a_tr * a_tr) + (2.0F * p.decel_mm_s2", "(v_h * v_h) + (2.0F * p.decel_mm_s2",
             "formula: (a T_r)^2 dropped"),
        (CO, "(separation_mm - p.intrusion_mm - p.uncertainty_mm)", "(separation_mm - p.intrusion_mm)",
             "formula: Z dropped"),
        (CO, "(separation_mm - p.intrusion_mm - p.uncertainty_mm)", "(separation_mm - p.uncertainty_mm)",
             "formula: C dropped"),
        (CO, "const float v = std::sqrt(radicand) - (v_h + a_tr);", "const float v = std::sqrt(radicand) - v_h;",
             "formula: a T_r not subtracted"),
        (CO, "(2.0F * p.decel_mm_s2 * (separation_mm", "(p.decel_mm_s2 * (separation_mm", "formula: 2a becomes a"),
        (CO, "return (v < limit) ? v : limit;", "return v;", "formula: not clamped to the limit in force"),
        (CO, "const float v_m_s = b.f_tr_n / std::sqrt(mu * k_n_per_m);", "const float v_m_s = b.f_tr_n / (mu * k_n_per_m);",
             "pfl: the square root dropped"),
        (CO, "const float m_r = (robot_mass_kg / 2.0F) + payload_kg;", "const float m_r = robot_mass_kg + payload_kg;",
             "pfl: the whole robot mass"),
        (FI, "r.acting = enabled_ && (in.mode == Mode::AUTO);", "r.acting = enabled_;", "fields: act in T1/T2 too"),
        (FI, "r.acting = enabled_ && (in.mode == Mode::AUTO);", "r.acting = in.mode == Mode::AUTO;",
             "fields: act without collaborative operation"),
        (FI, "r.inner_stops = r.acting && in.field_inner_interrupted;", "r.inner_stops = r.acting && in.field_outer_interrupted;",
             "fields: the outer field stops"),
        (FI, "r.outer_reduces = r.acting && in.field_outer_interrupted;", "r.outer_reduces = false;",
             "fields: the outer field does not reduce"),
        (FI, "r.blocks_start = r.inner_stops;", "r.blocks_start = false;", "fields: start/resume never refused"),
        (FI, "r.resume_due = r.acting && auto_resume_ && (clear_ > delay_);", "r.resume_due = r.acting && auto_resume_ && (clear_ >= delay_);",
             "fields: resume one cycle early"),
        (FI, "r.resume_due = r.acting && auto_resume_ && (clear_ > delay_);", "r.resume_due = r.acting && (clear_ > delay_);",
             "fields: auto_resume ignored"),
        (FI, "const bool both_clear = !in.field_outer_interrupted && !in.field_inner_interrupted;",
             "const bool both_clear = !in.field_inner_interrupted;", "fields: resume with the outer field interrupted"),
        (FI, "clear_ = both_clear ? ((clear_ <= delay_) ? clear_ + 1U : clear_) : 0U;",
             "clear_ = both_clear ? ((clear_ <= delay_) ? clear_ + 1U : clear_) : clear_;", "fields: the delay not restarted"),
        (FI, "if (in.field_outer_discrepancy || in.field_inner_discrepancy) {", "if (in.field_outer_discrepancy) {",
             "fields: inner discrepancy ignored"),
        (FI, "    limit = lower(limit, c.reduced_speed_mm_s);\n", "", "fields: collaborative.reduced_speed_mm_s ignored"),
        (FI, "    if (c.pfl_enabled) {", "    if (false) {", "fields: the PFL cap ignored"),
        (SS, "r.over = !(tcp_speed <= (r.v_allowed_mm_s * kSsmTolerance));", "r.over = !(tcp_speed <= (r.v_allowed_mm_s * 1.2F));",
             "ssm: 20 % instead of 5 %"),
        (SS, "if (powered && (over_ > reaction_)) {", "if (powered && (over_ > 2U * reaction_)) {", "ssm: 2 T_r"),
        (SS, "used_ = (in.separation_mm < ceiling) ? in.separation_mm : ceiling;", "used_ = in.separation_mm;",
             "ssm: a jump believed"),
        (SS, "r.acting = enabled_ && (in.mode == Mode::AUTO);", "r.acting = enabled_;", "ssm: acts in T1/T2 too"),
        (SUPERVISOR, "std::pair{AlarmId::SEPARATION_VIOLATED, &c.ssm.violated}", "std::pair{AlarmId::SEPARATION_VIOLATED, &c.limits.joint}",
             "rule 3: SEPARATION_VIOLATED entry dropped"),
        (SUPERVISOR, "            {c.fields.discrepancy, AlarmId::FIELD_DISCREPANCY}}};", "            {false, AlarmId::FIELD_DISCREPANCY}}};",
             "rule 1: FIELD_DISCREPANCY entry dropped"),
        (SUPERVISOR, "    fired = field_paused_ && c.fields.resume_due;", "    fired = c.fields.resume_due;",
             "resume: any pause resumes by itself"),
        (SUPERVISOR, "  field_paused_ = field_paused_ && (to == Leaf::AUTO_PAUSED);", "",
             "resume: a pause of rule 9 is never forgotten"),
        (SUPERVISOR, "  o.motion.v_allowed_mm_s = c.ssm.acting ? c.ssm.v_plan_mm_s : -1.0F;", "  o.motion.v_allowed_mm_s = -1.0F;",
             "motion: v_allowed not handed to the motion layer"),
        (SUPERVISOR, "  o.motion.reduced_limit_mm_s = limits_.reduced().limit();", "  o.motion.reduced_limit_mm_s = 0.0F;",
             "motion: the field's reduced limit not handed over"),
        (GUARDS, "  if (v.field_blocks) {\n    return Result::FIELD_INTERRUPTED;", "  if (false) {\n    return Result::FIELD_INTERRUPTED;",
             "guard: start with the inner field interrupted"),
        (GUARDS, "  return v.field_blocks ? Result::FIELD_INTERRUPTED : Result::OK;", "  return Result::OK;",
             "guard: resume with the inner field interrupted"),
    ]
    for rel, old, new, desc in collab:
        out.append(("collab", desc, rel, old, new))
    # --- brake test: the drift comparison and the due logic (SPEC §12) -------------------
    BT = MON + "brake_test.cpp"
    for old, new, desc in [
        ("return !(drift_deg <= max_drift_deg);", "return !(drift_deg <= (max_drift_deg + 0.5F));", "drift: 0.5 deg of slack"),
        ("return !(drift_deg <= max_drift_deg);", "return drift_deg > max_drift_deg;", "drift: NaN no longer a slip"),
        ("return !(drift_deg <= max_drift_deg);", "return false;", "drift: never a slip"),
        ("const float drift = absf(d.position_rad - q0_) * kRadToDeg;", "const float drift = (d.position_rad - q0_) * kRadToDeg;", "drift: one direction only"),
        ("done = elapsed_ >= hold_;", "done = elapsed_ >= (hold_ / 2U);", "pushes: half of hold_ms"),
        ("return limits_.configured && (!passed_ever_ || (age(now) > interval_));", "return limits_.configured && (!passed_ever_ || (age(now) > overdue_));", "due: only after the grace"),
        ("return limits_.configured && (!passed_ever_ || (age(now) > interval_));", "return limits_.configured && (age(now) > interval_);", "due: never-tested not due"),
        ("return limits_.configured && (!passed_ever_ || (age(now) > overdue_));", "return limits_.configured && (!passed_ever_ || (age(now) > (overdue_ + interval_)));", "required: grace doubled by the interval"),
        ("return limits_.configured && (!passed_ever_ || (age(now) > overdue_));", "return limits_.configured && (age(now) > overdue_);", "required: never-tested allowed"),
        ("  if (last_ == BrakeTestResult::failed) {\n    return true;", "  if (false) {\n    return true;", "required: a failed test no longer blocks AUTO"),
        ("    pass_at_ = static_cast<std::int64_t>(now);", "    pass_at_ = pass_at_;", "due: a pass does not restart the interval"),
    ]:
        out.append(("brake", desc, BT, old, new))
    out.append(("brake", "servo_on: BRAKE_TEST_REQUIRED dropped", GUARDS,
                "if ((v.in.mode == Mode::AUTO) && v.brake_test_required) {", "if (false && v.brake_test_required) {"))
    # --- collision detection (SPEC §11 rule 8) -------------------------------------------
    CM = MON + "collision.cpp"
    for rel, old, new, desc in [
        (CM, "const bool over = !(r.force_n <= limit_n_);", "const bool over = !(r.force_n <= (limit_n_ * 1.5F));", "threshold: 1.5 F_qs"),
        (CM, "const bool over = !(r.force_n <= limit_n_);", "const bool over = r.force_n > limit_n_;", "threshold: NaN no longer over"),
        (CM, "if (over_ >= kCollisionConfirmCycles) {", "if (over_ > kCollisionConfirmCycles) {", "count: three samples"),
        (CM, "enabled_ = c.enabled && c.pfl_enabled && (cycle_us > 0U);", "enabled_ = c.enabled && (cycle_us > 0U);", "gating: acts without pfl"),
        (CM, "  if (!enabled_ || !arm_free) {", "  if (!enabled_) {", "gating: judged while the arm is not free"),
        (CM, "Vec3 a{0.0F, 0.0F, kGravityM_S2};", "Vec3 a{0.0F, 0.0F, 0.0F};", "model: no gravity"),
        (CM, "  const float k = -1.0F / det;", "  const float k = 1.0F / (det * 4.0F);", "estimate: a quarter of the force"),
        (CM, "    qdd[k] = have_prev_ ? ((qd[k] - qd_prev_[k]) * inv_dt_) : 0.0F;", "    qdd[k] = 0.0F;", "model: no inertia"),
        (CM, "* 0.001F * rated_torque_nm[k];", "* 0.0005F * rated_torque_nm[k];", "torque: half the scale"),
        (SUPERVISOR, "        if (c.collision.hit.hit) {\n          hit(AlarmId::COLLISION", "        if (false) {\n          hit(AlarmId::COLLISION",
             "rule 8: the entry dropped"),
        (SUPERVISOR, "      if (c.at_standstill && !(s->back_off && c.fb.backing_off)) {", "      if (c.at_standstill) {",
             "rule 8: the stop ends before the back-off"),
        (SUPERVISOR, "    s.back_off = (row.effect == Effect::back_off) || (row.effect == Effect::back_off_abort);", "    s.back_off = false;",
             "rule 8: no back-off asked"),
    ]:
        out.append(("collision", desc, rel, old, new))
    # --- margins of the motion layer ----------------------------------------------------
    for old, new, desc in [("kJointMarginRad = deg(1.0F);", "kJointMarginRad = deg(0.0F);", "joint margin 1 deg removed"),
                           ("kZoneMarginMm = 10.0F;", "kZoneMarginMm = 0.0F;", "zone margin 10 mm removed"),
                           ("kSpeedFactor = 0.95F;", "kSpeedFactor = 1.0F;", "speed margin 5 % removed"),
                           ("kOrientationMarginRad = deg(1.0F);", "kOrientationMarginRad = deg(0.0F);", "orientation margin 1 deg removed")]:
        out.append(("margin", desc, MARGINS, old, new))
    # --- round three (issue 40): the §10-§13 code the six survivors were in, again -------
    J, RM, S, SL, MH = (MON + "joint_limits.cpp", MON + "reduced_mode.cpp", MON + "speed_limits.cpp",
                        MON + "safe_limits.cpp", "core/include/safestate/core/monitors.hpp")
    for rel, old, new, desc in [
        (J, "for (std::size_t i = 0; i < kAxes; ++i) {", "for (std::size_t i = 0; i + 1U < kAxes; ++i) {", "joint: axis 6 not checked"),
        (J, "for (std::size_t i = 0; i < kAxes; ++i) {", "for (std::size_t i = 1; i < kAxes; ++i) {", "joint: axis 1 not checked"),
        (J, "r.outside = r.outside || !(outside <= 0.0F);", "r.outside = r.outside || (outside > 0.0F);", "joint: NaN not outside (servo_on)"),
        (J, "r.recovering = r.recovering || track_[i].recovering;", "r.recovering = track_[i].recovering;", "joint: the last axis decides recovery"),
        (J, "if ((outside <= 0.0F) && !track_[i].recovering) {", "if (outside <= 0.0F) {", "joint: recovery never left"),
        (RM, "const bool lower = was && (limit < limit_);", "const bool lower = was && (limit > limit_);", "reduced: ramp restarts on a rising limit"),
        (RM, "const bool lower = was && (limit < limit_);", "const bool lower = false;", "reduced: a lower limit joining enforced at once"),
        (RM, "(v.in.reduced_requested ? kReducedByInput : 0U)", "0U", "reduced: the input ignored"),
        (RM, "(v.facts.fields.outer_reduces ? kReducedByField : 0U)", "0U", "reduced: the outer field ignored"),
        (RM, "rep.hold(AlarmId::REDUCED_SPEED, active(),", "rep.hold(AlarmId::REDUCED_SPEED, enforced(),", "reduced: REDUCED_SPEED only after the ramp"),
        (S, "r.reduced_enforced ? r.reduced_limit_mm_s : v.limits->tcp_max_speed_mm_s",
            "r.reduced_enforced ? v.limits->reduced_tcp_max_speed_mm_s : v.limits->tcp_max_speed_mm_s", "speed: the input's reduced limit whatever the sources"),
        (S, "for (std::size_t i = 0; (i < kAxes) && !f.hit; ++i) {", "for (std::size_t i = 0; (i + 1U < kAxes) && !f.hit; ++i) {", "speed: axis 6 not checked"),
        (S, "    rep.present(AlarmId::SPEED_LIMIT);\n", "", "speed: the reset guard blind to a speed still over"),
        (SL, "reduced_.configure((cycle_us > 0U) ? ms_to_cycles(limits_.reduced_ramp_ms, cycle_us) : 0U);",
             "reduced_.configure((cycle_us > 0U) ? limits_.reduced_ramp_ms : 0U);", "safe_limits: ramp_ms taken as cycles"),
        (SL, "  reduced_.check(v, r);\n  speed_.check(v, r);", "  speed_.check(v, r);\n  reduced_.check(v, r);", "safe_limits: speeds judged before reduced mode"),
        (SL, "  zones_.check(v, r);\n  orientation_.check(v, r);\n  reduced_.check(v, r);",
             "  reduced_.check(v, r);\n  zones_.check(v, r);\n  orientation_.check(v, r);", "safe_limits: reduced mode before the zones"),
        (MH, "kWorseJointRad = 0.002F;", "kWorseJointRad = 0.1F;", "constant: kWorseJointRad 0.1 rad"),
        (MH, "kWorseZoneMm = 1.0F;", "kWorseZoneMm = 50.0F;", "constant: kWorseZoneMm 50 mm"),
        (MH, "kWorseOrientationCos = 0.002F;", "kWorseOrientationCos = 0.1F;", "constant: kWorseOrientationCos 0.1"),
        (MH, "kReducedByField = 0x04U;", "kReducedByField = 0x02U;", "constant: the field's bit is the input's"),
        (MH, "kReducedByZone = 0x01U;", "kReducedByZone = 0x04U;", "constant: the zone's bit is the field's"),
        (MH, "kSsmTolerance = 1.05F;", "kSsmTolerance = 1.10F;", "constant: SSM tolerance 10 %"),
    ]:
        out.append(("round3", desc, rel, old, new))
    SC = "safety/src/stopping_check.cpp"
    for old, new, desc in [
        ("if (s.decel_mm_s2 > lv->tcp_decel_mm_s2) {", "if (s.decel_mm_s2 > stopping::kLevels.front().tcp_decel_mm_s2) {",
         "decel judged by the 33 % payload data"),
        ("if (static_cast<double>(c.limits.max_stop_ms) < lv->cat1_stop_ms) {",
         "if (static_cast<double>(c.limits.max_stop_ms) < stopping::kLevels.front().cat1_stop_ms) {", "stop time judged by the 33 % payload data"),
        (">= c.limits.payload_kg) {", "> c.limits.payload_kg) {", "a payload at a level judged by the next"),
        ("if (s.reaction_ms < stopping::kReactionMs) {", "if (s.reaction_ms < stopping::kReactionMs / 2.0) {", "reaction judged against half"),
        ("if (c.collaborative && c.collaborative->ssm && c.collaborative->ssm->enabled) {",
         "if (c.collaborative && c.collaborative->ssm) {", "SSM judged while disabled"),
        ("if (s.decel_mm_s2 > lv->tcp_decel_mm_s2) {", "if (s.decel_mm_s2 > 1.1 * lv->tcp_decel_mm_s2) {", "decel 10 % of slack"),
    ]:
        out.append(("stopdata", desc, SC, old, new))
    return out


LOCK = os.environ.get("MUTATE_LOCK", "")  # e.g. /tmp/safestate-cpu.lock: each build/test step takes it


def sh(cmd, cwd, timeout):
    if LOCK:
        cmd = f"flock {LOCK} sh -c {shlex_quote(cmd)}"
    try:
        r = subprocess.run(cmd, cwd=cwd, shell=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=timeout)
        return r.returncode, r.stdout.decode(errors="replace")
    except subprocess.TimeoutExpired:
        return 124, "timeout"


# Phase 1b: the one unit-test binary written for a family's code, small to rebuild (the
# full phase 2 relinks `safestate`, minutes per mutant on two cores).
FAMILY_UNIT = {"monitor": "test_safe_limits", "margin": "test_motion_limits", "collab": "test_collaborative",
               "brake": "test_brake_test", "collision": "test_collision", "round3": "test_safe_limits",
               "stopdata": "test_rta"}


def judge(family=""):
    """Phase 1: the differential test alone; 1b: the family's own unit tests; phase 2: every selected suite."""
    rc, _ = sh(f"cmake --build {BUILD} --target test_reference", ROOT, 900)
    if rc != 0:
        return "stillborn", "does not compile"
    rc, log = sh(f"ctest --test-dir {BUILD} -R '^Differential\\.' --no-tests=error", ROOT, 900)
    if rc != 0:
        failed = re.findall(r"\d+ - (\S+) \(", log)
        return "killed", ", ".join(failed[:3]) if failed else ("timeout" if rc == 124 else "")
    unit = FAMILY_UNIT.get(family)
    if unit:
        rc, _ = sh(f"cmake --build {BUILD} --target {unit}", ROOT, 900)
        if rc != 0:
            return "stillborn", "does not compile"
        rc, log = sh(f"{os.path.join(BUILD, 'bin', unit)} --gtest_brief=1", ROOT, 900)
        if rc != 0:
            failed = re.findall(r"\[  FAILED  \] (\S+) \(", log)
            return "killed", ", ".join(failed[:3]) if failed else ("timeout" if rc == 124 else unit)
    rc, _ = sh(f"cmake --build {BUILD} --target {TARGETS}", ROOT, 900)
    if rc != 0:
        return "stillborn", "does not compile"
    rc, log = sh(f"ctest --test-dir {BUILD} -j2 -R '{SELECT}' --no-tests=error --stop-on-failure", ROOT, 900)
    failed = re.findall(r"\d+ - (\S+) \(", log)
    outcome = "killed" if rc != 0 else "survived"
    return outcome, ", ".join(failed[:3]) if failed else ("timeout" if rc == 124 else "")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", help="only these families, comma-separated (row, guard, timer, stop, output, monitor, margin, collab, brake, collision, round3, stopdata)")
    ap.add_argument("--limit", type=int, default=0, help="at most this many mutants")
    ap.add_argument("--resume", action="store_true", help="skip mutants already judged in build-mut/progress.jsonl")
    a = ap.parse_args()
    ms = mutants()
    if a.only:
        ms = [m for m in ms if m[0] in a.only.split(",")]
    if a.limit:
        ms = ms[: a.limit]
    os.makedirs(WORK, exist_ok=True)
    # A fresh copy with fresh timestamps and a fresh build: objects of a mutant from an
    # interrupted run must never be mistaken for up to date.
    for d in (SRC, BUILD):
        if os.path.exists(d):
            shutil.rmtree(d)
    shutil.copytree(ROOT, SRC, copy_function=shutil.copy,
                    ignore=shutil.ignore_patterns("build*", ".git", ".venv", "node_modules", "hmi"))
    rc, log = sh(f"cmake -S {SRC} -B {BUILD} -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE=-O2 -DSAFESTATE_WERROR=OFF > /dev/null && "
                 f"cmake --build {BUILD} --target {TARGETS}", ROOT, 3600)
    if rc != 0:
        print(log[-3000:])
        sys.exit("the unmutated tree does not build")
    rc, log = sh(f"ctest --test-dir {BUILD} -j2 -R '{SELECT}' --no-tests=error", ROOT, 1800)
    ran = re.search(r"tests passed, \d+ tests failed out of (\d+)", log)
    if rc != 0 or not ran or int(ran.group(1)) < 100:
        print(log[-3000:])
        sys.exit("the unmutated tree does not pass its tests (or too few tests ran)")
    print(f"baseline: {ran.group(1)} tests pass on the unmutated tree", flush=True)
    results = []
    progress = os.path.join(WORK, "progress.jsonl")
    done = {}
    if a.resume and os.path.exists(progress):
        with open(progress) as f:
            for line in f:
                r = json.loads(line)
                done[r["mutant"]] = r
    elif os.path.exists(progress):
        os.remove(progress)
    t0 = time.time()
    for i, (family, desc, rel, old, new) in enumerate(ms, 1):
        if desc in done:
            results.append(done[desc])
            continue
        path = os.path.join(SRC, rel)
        with open(path) as f:
            orig = f.read()
        if old not in orig:
            results.append({"family": family, "mutant": desc, "outcome": "not applied"})
            continue
        with open(path, "w") as f:
            f.write(orig.replace(old, new, 1))
        outcome, by = judge(family)
        with open(path, "w") as f:
            f.write(orig)
        results.append({"family": family, "mutant": desc, "outcome": outcome, "by": by})
        with open(progress, "a") as f:
            f.write(json.dumps(results[-1]) + "\n")
        print(f"[{i}/{len(ms)}] {outcome:9s} {family:6s} {desc}  {by}", flush=True)
    sh(f"cmake --build {BUILD} --target {TARGETS}", ROOT, 900)  # leave the tree unmutated
    live = [r for r in results if r["outcome"] in ("killed", "survived")]
    killed = sum(1 for r in live if r["outcome"] == "killed")
    score = 100.0 * killed / len(live) if live else 0.0
    with open(os.path.join(WORK, "mutation.json"), "w") as f:
        json.dump({"score": score, "killed": killed, "total": len(live), "results": results}, f, indent=1)
    lines = [f"Mutation score: **{score:.1f} %** ({killed} of {len(live)} mutants killed; "
             f"{sum(1 for r in results if r['outcome'] == 'stillborn')} did not compile), {time.time() - t0:.0f} s.", ""]
    fams = sorted({r["family"] for r in results})
    lines += ["| family | mutants | killed | survived |", "|---|---|---|---|"]
    for fam in fams:
        rs = [r for r in live if r["family"] == fam]
        lines.append(f"| {fam} | {len(rs)} | {sum(r['outcome'] == 'killed' for r in rs)} | {sum(r['outcome'] == 'survived' for r in rs)} |")
    surv = [r for r in live if r["outcome"] == "survived"]
    lines += ["", "Survivors:" if surv else "No mutant survived."]
    lines += [f"- {r['family']}: {r['mutant']}" for r in surv]
    with open(os.path.join(WORK, "mutation.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

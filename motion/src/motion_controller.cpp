#include "safestate/motion/motion_controller.hpp"

#include <cmath>
#include <limits>

#include "safestate/core/cia402.hpp"

namespace safestate::motion {

namespace c402 = core::cia402;

namespace {
float clampf(float x, float lo, float hi) noexcept { return (x < lo) ? lo : ((x > hi) ? hi : x); }
float absf(float x) noexcept { return (x < 0.0F) ? -x : x; }
bool finite(float x) noexcept { return std::isfinite(x); }
bool at_rest(const Joints& v) noexcept {
  bool still = true;
  for (const float x : v) {
    still = still && (x == 0.0F);  // the stop ramp ends on an exact zero
  }
  return still;
}
float minf(float a, float b) noexcept { return (b < a) ? b : a; }
float maxf(float a, float b) noexcept { return (b > a) ? b : a; }

constexpr float kUnlimited = std::numeric_limits<float>::infinity();
// Reduced mode: the allowed TCP speed reaches 0.95 x the reduced limit after this share of
// reduced.ramp_ms, leaving the rest for the drives' following lag and the measurement.
constexpr float kReducedRampShare = 0.8F;
// Bounds on the path samples (each one forward kinematics + every zone): a jog's stopping
// path every cycle; the path to the first waypoint whenever the arm has moved; a program's
// paths once per load.
constexpr std::uint32_t kJogSamples = 256;
constexpr std::uint32_t kLegSamples = 1024;
constexpr std::uint32_t kProgramSamples = 4096;
constexpr float kLegRecheckRad = 1.0e-4F;  // measured motion that makes the first leg stale
}  // namespace

const char* to_string(AxisState s) noexcept {
  constexpr std::array<const char*, 8> kNames{"Disabled",         "Standstill",         "Homing",   "DiscreteMotion",
                                              "ContinuousMotion", "SynchronizedMotion", "Stopping", "ErrorStop"};
  const auto i = static_cast<std::size_t>(s);
  // cppcheck-suppress CastIntegerToAddressAtReturn ; false positive of cppcheck 2.10: kNames[i] is a const char*
  return (i < kNames.size()) ? kNames[i] : "?";
}

// ------------------------------------------------------------------ ProgramExecutor
void ProgramExecutor::load(const Waypoint* points, std::uint8_t count) noexcept {
  count_ = (points == nullptr) ? 0U : count;
  points_ = std::span<const Waypoint>(points, count_);
  abort();
}

void ProgramExecutor::abort() noexcept {
  active_ = false;
  finished_ = false;
  dwelling_ = false;
  index_ = 0;
  tau_ = 0.0F;
  T_ = 0.0F;
}

void ProgramExecutor::start(const Joints& from, const RobotModel& m, float override) noexcept {
  abort();
  if (count_ == 0U) {
    return;
  }
  active_ = true;
  plan(from, m, override);
}

void ProgramExecutor::resume(const Joints& from, const RobotModel& m, float override) noexcept {
  if (count_ == 0U || finished_) {
    return;
  }
  active_ = true;
  dwelling_ = false;
  plan(from, m, override);  // from where the arm actually is, to the waypoint it was heading to
}

void ProgramExecutor::plan(const Joints& from, const RobotModel& m, float override) noexcept {
  const Waypoint& w = points_[index_];
  const float k = clampf(w.speed * override, 0.01F, 1.0F);
  q0_ = from;
  T_ = 0.0F;
  ta_ = 0.0F;
  for (std::size_t i = 0; i < kJoints; ++i) {
    delta_[i] = w.q[i] - from[i];
    const float d = absf(delta_[i]);
    const float v = m.qd_max_rad_s[i] * k;
    const float a = m.qdd_max_rad_s2[i];
    float t = 0.0F;
    float ta = 0.0F;
    if (d > 0.0F) {
      if (d >= (v * v) / a) {  // reaches cruise speed: trapezoid
        ta = v / a;
        t = (d / v) + ta;
      } else {  // triangle
        ta = std::sqrt(d / a);
        t = 2.0F * ta;
      }
    }
    if (t > T_) {  // the slowest axis sets the shape every axis follows
      T_ = t;
      ta_ = ta;
    }
  }
  tau_ = 0.0F;
}

float ProgramExecutor::s_of(float tau) const noexcept {
  if (T_ <= 0.0F) {
    return 1.0F;
  }
  const float t = clampf(tau, 0.0F, T_);
  const float vp = 1.0F / (T_ - ta_);
  if (t < ta_) {
    return 0.5F * vp / ta_ * t * t;
  }
  if (t < T_ - ta_) {
    return (0.5F * vp * ta_) + (vp * (t - ta_));
  }
  const float r = T_ - t;
  return 1.0F - (0.5F * vp / ta_ * r * r);
}

float ProgramExecutor::ds_of(float tau) const noexcept {
  if (T_ <= 0.0F || tau >= T_ || tau < 0.0F) {
    return 0.0F;
  }
  const float vp = 1.0F / (T_ - ta_);
  if (tau < ta_) {
    return vp * tau / ta_;
  }
  if (tau < T_ - ta_) {
    return vp;
  }
  return vp * (T_ - tau) / ta_;
}

Joints ProgramExecutor::velocity() const noexcept {
  Joints v{};
  if (!active_ || dwelling_) {
    return v;
  }
  const float ds = ds_of(tau_);
  for (std::size_t i = 0; i < kJoints; ++i) {
    v[i] = delta_[i] * ds;
  }
  return v;
}

Joints ProgramExecutor::advance(float dt, const RobotModel& m, float override) noexcept {
  Joints q{};
  if (!active_) {
    return q0_;
  }
  if (dwelling_) {
    dwell_left_ -= dt;
    if (dwell_left_ <= 0.0F) {
      dwelling_ = false;
      ++index_;
      if (index_ >= count_) {
        active_ = false;
        finished_ = true;
        index_ = static_cast<std::uint8_t>(count_ - 1U);
      } else {
        plan(points_[index_ - 1U].q, m, override);
      }
    }
    return dwelling_ || !active_ ? points_[index_].q : q0_;
  }
  tau_ += dt;
  const float s = s_of(tau_);
  for (std::size_t i = 0; i < kJoints; ++i) {
    q[i] = q0_[i] + (delta_[i] * s);
  }
  if (tau_ >= T_) {
    dwelling_ = true;
    dwell_left_ = static_cast<float>(points_[index_].dwell_ms) * 0.001F;
    q = points_[index_].q;
  }
  return q;
}

// ------------------------------------------------------------------ MotionController
MotionController::MotionController(const RobotModel& model, const MotionConfig& cfg) noexcept
    : model_(model), cfg_(cfg), plan_(model), tcp_allow_(kUnlimited), tcp_cap_(kUnlimited) {
  axis_.fill(AxisState::Disabled);
  // Without set_limits: the robot's own ranges and speeds and SafetyLimits' defaults, used
  // for reduced mode only (limits_set_ gates everything else).
  core::SafetyLimits d{};
  for (std::size_t i = 0; i < kJoints; ++i) {
    d.joints[i] = {model.q_min_rad[i], model.q_max_rad[i], model.qd_max_rad_s[i]};
  }
  d.tcp_mm = model.tcp_offset_mm;
  lim_.configure(d, model_, cfg_.limit_margin_rad);
}

void MotionController::set_limits(const core::SafetyLimits& limits) noexcept {
  model_.tcp_offset_mm = limits.tcp_mm;  // the tool's TCP: zones, TCP speeds, measure()
  lim_.configure(limits, model_, cfg_.limit_margin_rad);
  limits_set_ = true;
  plan_ = model_;
  for (std::size_t i = 0; i < kJoints; ++i) {
    plan_.qd_max_rad_s[i] = lim_.joint_speed(i);
  }
  tcp_allow_ = reduced_prev_ ? lim_.reduced_tcp_speed() : lim_.tcp_speed();
  check_program();
}

// A program is checked once, here: every waypoint within the joint bounds and the
// Cartesian limits less their margins, and the straight joint-space path between
// consecutive waypoints (what ProgramExecutor drives) sampled by LimitPlanner::path_clear:
// the next sample is as far as the smallest clearance left allows (a point moves at most
// sum_j |dq_j| lever_j), never closer than 0.5 mm of point travel / 0.001 rad of tool-axis
// turn. Joints are linear along such a path: the waypoints bound them.
void MotionController::load_program(const Waypoint* points, std::uint8_t count) noexcept {
  prog_count_ = (points == nullptr) ? 0U : count;
  prog_ = (prog_count_ == 0U) ? std::span<const Waypoint>{} : std::span<const Waypoint>(points, prog_count_);
  program_.load(points, count);
  check_program();
}

void MotionController::check_program() noexcept {
  program_ok_ = true;
  first_leg_dirty_ = true;
  if (!limits_set_) {
    return;
  }
  Clearance margin{};
  lim_.margins(margin);
  for (std::size_t k = 0; k < prog_count_ && program_ok_; ++k) {
    program_ok_ = lim_.joints_inside(prog_[k].q) && lim_.path_clear(prog_[k].q, prog_[k].q, margin, 2U);
    if (program_ok_ && k + 1U < prog_count_) {
      program_ok_ = lim_.path_clear(prog_[k].q, prog_[k + 1U].q, margin, kProgramSamples);
    }
  }
}

bool MotionController::start_within_limits(const Joints& from) const noexcept {
  if (!limits_set_ || prog_count_ == 0U) {
    return true;
  }
  Clearance thr{};
  lim_.thresholds(from, thr);
  return lim_.path_clear(from, prog_[0].q, thr, kLegSamples);
}

void MotionController::measure(const std::array<core::DriveFeedback, kJoints>& drives, core::Feedback& fb,
                               bool stale, std::int32_t sample_span) noexcept {
  for (std::size_t i = 0; i < kJoints; ++i) {
    q_meas_[i] = drives[i].position_rad;
  }
  // @req MO-SAMPLE-TIME
  // A frame that carries the sample the last one carried is no new sample either.
  const bool fresh = !((stale || (sample_span == 0)) && have_prev_);
  forward(model_, q_meas_, frames_);
  if (fresh) {
    // ISO 10218-1 5.7.3: the reduced speed is checked on measured positions, differentiated
    // here rather than taken from the drives' own velocity estimate (a diverse channel),
    // over the real time between the two samples (more than one cycle after a stale one).
    Joints qdot{};
    if (have_prev_) {
      // The cycles between the two samples: as the drives took them when known (a frame
      // late past its SYNC0 carries the next pulse's sample, two cycles of motion after the
      // last one), else as the frames came (a stale cycle in between: two cycles).
      const std::uint32_t cycles = (sample_span > 0) ? static_cast<std::uint32_t>(sample_span) : span_;
      const float dt = static_cast<float>(cycles) * cfg_.cycle_s;
      for (std::size_t i = 0; i < kJoints; ++i) {
        qdot[i] = (q_meas_[i] - q_prev_[i]) / dt;
      }
    }
    q_prev_ = q_meas_;
    have_prev_ = true;
    span_ = 1;
    // For motion and the status (the core's T1 monitor derives its own, issue 35).
    point_speeds(frames_, qdot, speeds_);
  } else if (span_ < 0xFFFFU) {
    ++span_;  // the last sample's speeds stand
  }
  // @req COL-BACKOFF
  // The path the TCP came, for a collision's back-off (not the retrace itself).
  if (fresh && !back_off_.started()) {
    back_off_.record(q_meas_, frames_.tcp);
  }
  fb.backing_off = back_off_req_ && !back_off_.done();
  fb.tcp_speed_mm_s = speeds_.speed[kTcpPoint];
  fb.max_point_speed_mm_s = speeds_.max_speed;
  fb.fastest_axis = speeds_.fastest_axis;
  // Following error, outside stop ramps: in a stop the supervisor's stop-time monitor
  // (SS1-t) is the specified measure, and a drive ignoring the ramp must meet it.
  fb.following_error_axis = 0;
  for (std::size_t i = 0; i < kJoints; ++i) {
    if (fresh) {  // a held position lags the set-points by the stale cycles: judged on fresh samples
      lagging_[i] = !(absf(q_sent_[i] - q_meas_[i]) <= cfg_.following_error_rad);
    }
    // The axis under brake test is meant to be pushed off its set-point (SPEC §12): its
    // drift is the brake test's to judge.
    const bool tested = static_cast<std::size_t>(test_axis_) == (i + 1U);
    if (watch_following_ && lagging_[i] && !tested && (fb.following_error_axis == 0U)) {
      fb.following_error_axis = static_cast<std::uint8_t>(i + 1U);
    }
  }
  fb.program_loaded = program_.loaded();
  fb.program_finished = program_.finished();
  // @req MO-LIMITS-PROGRAM
  // The path to the first waypoint starts wherever the arm is: re-checked when it has
  // moved (not while the program runs: the check is for `start`).
  if (limits_set_ && (prog_count_ > 0U) && !program_.active()) {
    bool moved = first_leg_dirty_;
    for (std::size_t i = 0; i < kJoints; ++i) {
      moved = moved || !(absf(q_meas_[i] - first_leg_from_[i]) <= kLegRecheckRad);
    }
    if (moved) {
      first_leg_from_ = q_meas_;
      first_leg_ok_ = start_within_limits(q_meas_);
      first_leg_dirty_ = false;
    }
  }
  fb.program_within_limits = !limits_set_ || (program_ok_ && first_leg_ok_);
}

void MotionController::follow_program(const core::SupervisorOut& so) noexcept {
  // T1: time-scale the program so that the path stays the same and no point exceeds
  // the reduced speed (ISO 10218-1 5.7.3).
  if (!program_.active()) {
    // Not started (refused outside the limits) or finished: hold where the set-point is.
    // A finished program's executor answers with its last segment's start, so asking it
    // for one more step (the supervisor still in AUTO_RUNNING for a cycle) jumped back
    // there; never jump.
    v_sp_.fill(0.0F);
    return;
  }
  float scale = 1.0F;
  if (so.motion.t1_limit) {
    scale = t1_scale(model_, q_sp_, program_.velocity(), cfg_.t1_limit_mm_s * cfg_.t1_margin);
  }
  // SPEC §10: the TCP at 0.95 x its limit (normal, or the reduced ramp), by time-scaling
  // like T1; the joints' 0.95 x max_speed is in plan_, the model the executor plans with.
  if (tcp_cap_ < kUnlimited) {
    scale = minf(scale, tcp_scale(model_, q_sp_, program_.velocity(), tcp_cap_));
  }
  const Joints q = program_.advance(cfg_.cycle_s * scale, plan_, cfg_.speed_override);
  for (std::size_t i = 0; i < kJoints; ++i) {
    v_sp_[i] = (q[i] - q_sp_[i]) / cfg_.cycle_s;
  }
  if (so.motion.t1_limit) {
    limit_t1();  // a last, exact check on the step actually taken
  }
  limit_tcp();
}

// @req MO-LIMITS-JOG MO-LIMITS-RECOVERY
// A jog stays active (the supervisor still says MANUAL_JOGGING) but holds short of every
// safe limit: joints exactly (the speed from which the axis stops at its deceleration
// inside the bound), Cartesian limits by prediction: the path from the set-point to where
// every axis would stop braking at full deceleration from this cycle's speed must keep
// every clearance (limits.hpp); if it does not, the axes brake now. Because braking only
// ever shortens the stopping path (by a*dt^2/2 a cycle), a path found clear once stays
// clear, so a jog at 100 % does not overshoot into the margin. Where the set-point is
// already inside a margin (or past a limit: recovery), "clear" means "not worse than
// now", so the operator can always jog back out and nowhere deeper.
void MotionController::jog(const core::JogTarget& j, bool t1) noexcept {
  const Joints v_prev = v_sp_;
  for (std::size_t i = 0; i < kJoints; ++i) {
    const bool moving_axis = (j.axis >= 1U) && (static_cast<std::size_t>(j.axis - 1U) == i);
    float target = 0.0F;
    if (moving_axis) {
      target = static_cast<float>(j.dir) * (static_cast<float>(j.speed) / 100.0F) * cfg_.jog_speed *
               model_.qd_max_rad_s[i];
    }
    if (limits_set_) {
      target = clampf(target, -lim_.joint_speed(i), lim_.joint_speed(i));
    }
    // Never drive into a joint limit: the speed from which the axis can still stop
    // inside the limit at its acceleration.
    const float a = model_.qdd_max_rad_s2[i];
    const float hi = limits_set_ ? lim_.joint_hi(i) : (model_.q_max_rad[i] - cfg_.limit_margin_rad);
    const float lo = limits_set_ ? lim_.joint_lo(i) : (model_.q_min_rad[i] + cfg_.limit_margin_rad);
    const float room_hi = hi - q_sp_[i];
    const float room_lo = q_sp_[i] - lo;
    const float v_hi = (room_hi > 0.0F) ? std::sqrt(2.0F * a * room_hi) : 0.0F;
    const float v_lo = (room_lo > 0.0F) ? std::sqrt(2.0F * a * room_lo) : 0.0F;
    target = clampf(target, -v_lo, v_hi);
    const float dv = a * cfg_.cycle_s;
    v_sp_[i] = clampf(target, v_sp_[i] - dv, v_sp_[i] + dv);
  }
  limit_tcp();
  if (t1) {
    limit_t1();
  }
  if (limits_set_ && lim_.cartesian() && !stop_path_clear()) {
    for (std::size_t i = 0; i < kJoints; ++i) {  // brake: the stop the prediction assumed
      const float dv = model_.qdd_max_rad_s2[i] * cfg_.cycle_s;
      const float brake = (v_prev[i] > 0.0F) ? maxf(v_prev[i] - dv, 0.0F) : minf(v_prev[i] + dv, 0.0F);
      const bool slower = (v_sp_[i] * brake >= 0.0F) && (absf(v_sp_[i]) < absf(brake));
      v_sp_[i] = slower ? v_sp_[i] : brake;
    }
    limit_tcp();  // both only ever slow down further: the stopping path only shortens
    if (t1) {
      limit_t1();
    }
  }
}

bool MotionController::stop_path_clear() const noexcept {
  Joints stop{};
  for (std::size_t i = 0; i < kJoints; ++i) {
    const float v = v_sp_[i];
    stop[i] = q_sp_[i] + (v * cfg_.cycle_s) + ((v * absf(v)) / (2.0F * model_.qdd_max_rad_s2[i]));
  }
  Clearance thr{};
  lim_.thresholds(q_sp_, thr);
  return lim_.path_clear(q_sp_, stop, thr, kJogSamples);
}

// @req MO-LIMITS-SPEED
void MotionController::limit_tcp() noexcept {
  if (tcp_cap_ < kUnlimited) {
    const float s = tcp_scale(model_, q_sp_, v_sp_, tcp_cap_);
    for (float& v : v_sp_) {
      v *= s;
    }
  }
}

// @req MO-LIMITS-REDUCED
// Reduced mode (SPEC §10): from the onset, the allowed TCP speed falls linearly from the
// TCP speed of this cycle's set-point to 0.95 x the reduced limit, reaching it after
// kReducedRampShare x reduced.ramp_ms, and stays there; when reduced mode ends it rises
// back at the rate (normal - reduced) / ramp_ms (no step up either). Without set_limits
// there is no normal cap: the allowed speed rises until it is above anything this arm can
// reach, then the cap is lifted.
void MotionController::update_tcp_allow(const core::MotionRequest& r) noexcept {
  const bool reduced = r.reduced;
  // The reduced limit the core names (SPEC §11's outer field may lower it), else the file's.
  const float red = (r.reduced_limit_mm_s > 0.0F) ? minf(kSpeedFactor * r.reduced_limit_mm_s, lim_.reduced_tcp_speed())
                                                  : lim_.reduced_tcp_speed();
  const float normal = limits_set_ ? lim_.tcp_speed() : kUnlimited;
  const float ramp_s = lim_.reduced_ramp_s();
  const bool lowered = reduced && reduced_prev_ && (red < red_prev_);
  red_prev_ = red;
  if ((reduced && !reduced_prev_) || lowered) {
    PointSpeeds ps{};
    point_speeds(model_, q_sp_, v_sp_, ps);
    const float now = finite(ps.speed[kTcpPoint]) ? ps.speed[kTcpPoint] : red;
    tcp_allow_ = minf(tcp_allow_, maxf(now, red));
    const float t = kReducedRampShare * ramp_s;
    tcp_ramp_down_ = (t > 0.0F) ? ((tcp_allow_ - red) / t) : kUnlimited;
  }
  reduced_prev_ = reduced;
  if (reduced) {
    tcp_allow_ = (tcp_ramp_down_ < kUnlimited) ? maxf(red, tcp_allow_ - (tcp_ramp_down_ * cfg_.cycle_s)) : red;
    return;
  }
  if (tcp_allow_ < normal) {
    // back up at the rate the built-in (or configured) normal limit would take over ramp_ms
    const float top = limits_set_ ? normal : (kSpeedFactor * core::SafetyLimits{}.tcp_max_speed_mm_s);
    const float rate = (ramp_s > 0.0F) ? (maxf(top - red, 1.0F) / ramp_s) : kUnlimited;
    tcp_allow_ = (rate < kUnlimited) ? (tcp_allow_ + (rate * cfg_.cycle_s)) : normal;
    const float lift = limits_set_ ? normal : 10.0F * top;  // above any TCP speed of this arm
    if (!(tcp_allow_ < lift)) {
      tcp_allow_ = normal;
    }
  }
}

void MotionController::ramp(float decel_fraction) noexcept {
  // All axes reach zero together, along the current direction of motion.
  float t_stop = 0.0F;
  for (std::size_t i = 0; i < kJoints; ++i) {
    const float t = absf(v_sp_[i]) / (model_.qdd_max_rad_s2[i] * decel_fraction);
    t_stop = (t > t_stop) ? t : t_stop;
  }
  const float k = (t_stop <= cfg_.cycle_s) ? 0.0F : (1.0F - (cfg_.cycle_s / t_stop));
  for (float& v : v_sp_) {
    v *= k;
  }
}

// @req MO-T1-LIMIT
void MotionController::limit_t1() noexcept {
  const float s = t1_scale(model_, q_sp_, v_sp_, cfg_.t1_limit_mm_s * cfg_.t1_margin);
  for (float& v : v_sp_) {
    v *= s;
  }
}

void MotionController::integrate(bool bounded) noexcept {
  for (std::size_t i = 0; i < kJoints; ++i) {
    float q = q_sp_[i] + (v_sp_[i] * cfg_.cycle_s);
    if (bounded && limits_set_) {
      // Planned motion never passes a joint's bound; already past it (recovery), never
      // further out. (Stop ramps are not clamped: a set-point step is no stop.)
      q = minf(q, maxf(q_sp_[i], lim_.joint_hi(i)));
      q = maxf(q, minf(q_sp_[i], lim_.joint_lo(i)));
    }
    q = clampf(q, model_.q_min_rad[i], model_.q_max_rad[i]);
    if (!finite(q)) {
      q = q_meas_[i];
      v_sp_[i] = 0.0F;
    }
    q_sp_[i] = q;
  }
}

void MotionController::step(const core::SupervisorOut& so, const std::array<core::DriveFeedback, kJoints>& drives,
                            std::array<hal::DriveOut, kJoints>& out) noexcept {
  const core::MotionRequest& r = so.motion;
  update_tcp_allow(r);
  // @req COL-SSM-MOTION
  // SPEC §11 SSM: the TCP at 0.95 x v_allowed (the margin of SPEC §10 for speeds), on top of
  // the normal or reduced cap; at 0 the program holds where it is.
  tcp_cap_ = tcp_allow_;
  if (r.v_allowed_mm_s >= 0.0F) {
    tcp_cap_ = minf(tcp_cap_, kSpeedFactor * r.v_allowed_mm_s);
  }
  // SPEC §12: when an axis' brake test ends (next axis, pass, or any stop) its set-point is
  // taken from where it stands, so that a brake that slipped is not pulled back: no motion
  // that nobody commanded (SPEC §3).
  if ((test_axis_ != 0U) && (r.brake_test.axis != test_axis_)) {
    const std::size_t k = static_cast<std::size_t>(test_axis_ - 1U) % kJoints;
    q_sp_[k] = q_meas_[k];
    v_sp_[k] = 0.0F;
  }
  test_axis_ = r.brake_test.axis;
  switch (r.program) {
    case core::ProgramCmd::Start:
      // A second barrier behind the supervisor's OUTSIDE_LIMITS: never start outside.
      if (program_ok_ && first_leg_ok_) {
        program_.start(q_meas_, plan_, cfg_.speed_override);
      } else {
        program_.abort();
      }
      break;
    case core::ProgramCmd::Resume: program_.resume(q_meas_, plan_, cfg_.speed_override); break;
    case core::ProgramCmd::Abort: program_.abort(); break;
    case core::ProgramCmd::None: break;
  }
  switch (r.mode) {
    // @req ST-NO-SURPRISE
    case core::MotionMode::Track:
      q_sp_ = q_meas_;  // re-seeded from the measured position: no jump on the next arm
      v_sp_.fill(0.0F);
      break;
    case core::MotionMode::Hold:
      v_sp_.fill(0.0F);
      break;
    case core::MotionMode::Jog:
      jog(r.jog, r.t1_limit);
      integrate(true);
      break;
    case core::MotionMode::Program:
      follow_program(so);
      integrate(true);
      break;
    // @req ST-CAT1
    case core::MotionMode::QuickStop:
      ramp(cfg_.quick_stop_decel);
      integrate(false);
      break;
    // @req ST-CAT2
    case core::MotionMode::Ramp2:
      // @req COL-BACKOFF
      // SPEC §11 rule 8: stopped, the arm backs off along its path, then holds.
      if (r.back_off && (back_off_.started() || at_rest(v_sp_))) {
        if (!back_off_.started()) {
          back_off_.begin(q_sp_, frames_.tcp);
        }
        back_off_.step(cfg_.cycle_s, q_sp_, v_sp_);
      } else {
        ramp(cfg_.cat2_decel);
        integrate(false);
      }
      break;
  }
  if (!r.back_off && back_off_.started()) {
    back_off_.cancel();  // the stop ended (or escalated): the next path is recorded again
  }
  back_off_req_ = r.back_off;
  drive_control(so, drives, out);
  axis_states(so, drives);
  q_sent_ = q_sp_;
  watch_following_ = so.drives_enable && so.brakes_release &&
                     (r.mode == core::MotionMode::Hold || r.mode == core::MotionMode::Jog ||
                      r.mode == core::MotionMode::Program);
}

// @req CIA-NO-REENABLE
void MotionController::drive_control(const core::SupervisorOut& so,
                                     const std::array<core::DriveFeedback, kJoints>& drives,
                                     std::array<hal::DriveOut, kJoints>& out) noexcept {
  for (std::size_t i = 0; i < kJoints; ++i) {
    const c402::DriveState ds = c402::decode(drives[i].statusword);
    std::uint16_t cw = c402::cw::kDisableVoltage;
    if (!so.drives_enable) {
      reached_enabled_[i] = false;
      dropped_[i] = false;
      quick_stopped_[i] = false;
      if (so.motion.fault_reset && c402::is_fault(ds)) {
        // Fault reset acts on the rising edge of bit 7: alternate 0x00 / 0x80.
        cw = ((last_cw_[i] & c402::cw::kFaultReset) != 0U) ? c402::cw::kDisableVoltage : c402::cw::kFaultReset;
      }
    } else {
      // Cat 1: an axis that does not follow the controller's ramp also gets the drive's
      // own quick-stop ramp (CiA 402 quick stop), a second, independent means to stop.
      if ((so.motion.mode == core::MotionMode::QuickStop) && lagging_[i] &&
          ((ds == c402::DriveState::OperationEnabled) || quick_stopped_[i])) {
        quick_stopped_[i] = true;
      }
      if (so.motion.mode != core::MotionMode::QuickStop && so.motion.mode != core::MotionMode::Hold) {
        quick_stopped_[i] = false;
      }
      if (reached_enabled_[i] && (ds != c402::DriveState::OperationEnabled) && !quick_stopped_[i]) {
        dropped_[i] = true;  // a drive that fell out of Operation enabled is never re-enabled by us
      }
      if (quick_stopped_[i]) {
        cw = c402::cw::kQuickStop;  // held until power is removed; never enabled again by us
      } else if (!dropped_[i]) {
        switch (ds) {
          case c402::DriveState::SwitchOnDisabled: cw = c402::cw::kShutdown; break;
          case c402::DriveState::ReadyToSwitchOn: cw = c402::cw::kSwitchOn; break;
          case c402::DriveState::SwitchedOn: cw = c402::cw::kEnableOperation; break;
          case c402::DriveState::OperationEnabled:
            cw = c402::cw::kEnableOperation;
            reached_enabled_[i] = true;
            break;
          default: cw = c402::cw::kDisableVoltage; break;
        }
      }
    }
    last_cw_[i] = cw;
    out[i].controlword = cw;
    out[i].target_position_rad = q_sp_[i];
    out[i].max_torque_permille = hal::kDriveMaxTorquePermille;
    // @req BT-CSP-TORQUE
    // SPEC §12 on a CSP drive: the torque limited to the test torque (0x6072) and the
    // set-point moved by the offset, so the saturated position loop pushes the brake.
    const core::BrakeTestRequest& bt = so.motion.brake_test;
    if ((static_cast<std::size_t>(bt.axis) == (i + 1U)) && so.drives_enable) {
      out[i].target_position_rad = q_sp_[i] + (static_cast<float>(bt.dir) * bt.offset_rad);
      if (bt.torque_permille != 0U) {
        out[i].max_torque_permille = bt.torque_permille;
      }
    }
  }
}

// @req CIA-AXIS-STATES
void MotionController::axis_states(const core::SupervisorOut& so,
                                   const std::array<core::DriveFeedback, kJoints>& drives) noexcept {
  for (std::size_t i = 0; i < kJoints; ++i) {
    const c402::DriveState ds = c402::decode(drives[i].statusword);
    AxisState s = AxisState::Standstill;
    if (c402::is_fault(ds)) {
      s = AxisState::ErrorStop;
    } else if (ds == c402::DriveState::QuickStopActive) {
      s = AxisState::Stopping;
    } else if (ds != c402::DriveState::OperationEnabled) {
      s = AxisState::Disabled;
    } else {
      switch (so.motion.mode) {
        case core::MotionMode::QuickStop:
        case core::MotionMode::Ramp2: s = AxisState::Stopping; break;
        case core::MotionMode::Program: s = AxisState::DiscreteMotion; break;
        case core::MotionMode::Jog:
          s = (static_cast<std::size_t>(so.motion.jog.axis) == i + 1U) ? AxisState::ContinuousMotion
                                                                        : AxisState::Standstill;
          break;
        default: s = AxisState::Standstill; break;
      }
    }
    axis_[i] = s;
  }
}

}  // namespace safestate::motion

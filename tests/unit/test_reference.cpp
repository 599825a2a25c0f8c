// Differential test: the table-driven SystemStateManager against the independent
// reference implementation (tools/reference), cycle by cycle, over long random but
// realistic histories. Any difference in state, sub-state, stop category, outputs,
// alarms or command results fails with the cycle and the history that led to it.
#include <algorithm>
#include <random>
#include <sstream>

#include <cmath>

#include "../../tools/check/checker.hpp"
#include "../../tools/reference/reference.hpp"
#include "bench.hpp"
#include "monitor_harness.hpp"
#include "safestate/controller/controller.hpp"
#include "safestate/core/collision.hpp"
#include "safestate/core/dynamics.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/motion/robot.hpp"

using namespace safestate::test;
namespace ref = safestate::reference;

namespace {

// SPEC §10 for the differential test: a safety configuration, and the poses the arm is put
// in (measured positions jump there: a fault below the planner), each with what it violates.
constexpr std::uint32_t kChecksum = 0x5AFE0001U;
enum Pose : std::uint8_t { kHome, kJoint, kJointBetter, kJointWorse, kZone, kOrientation, kReduced, kPoses };
const std::array<JointArray, kPoses> kPose{{
    {0.0F, 0.3F, 0.3F, 0.0F, 0.3F, 0.0F},   // home: inside every limit
    {1.10F, 0.3F, 0.3F, 0.0F, 0.3F, 0.0F},  // joint 1 outside its range [-1, 1] by 0.1 rad
    {1.05F, 0.3F, 0.3F, 0.0F, 0.3F, 0.0F},  // ... by less (recovering)
    {1.30F, 0.3F, 0.3F, 0.0F, 0.3F, 0.0F},  // ... by more (worse)
    {0.0F, 0.9F, 0.3F, 0.0F, 0.3F, 0.0F},   // the TCP sphere in the keep_out zone
    {0.0F, 0.3F, 0.3F, 0.0F, 1.6F, 0.0F},   // the tool axis outside its cone
    {0.0F, -0.3F, 0.3F, 0.0F, 0.3F, 0.0F},  // the TCP in the reduced zone
}};

ArmGeometry geometry() { return safestate::controller::Controller::arm_geometry(safestate::motion::kRobot); }

ArmPose pose_of(const JointArray& q, const SafetyLimits& l) {
  ArmPose p{};
  arm_forward(geometry(), q, l.tcp_mm, p);
  return p;
}

Zone box_around(const char* name, ZoneKind kind, const Vec3& c, float half) {
  Zone z{};
  for (std::size_t i = 0; name[i] != '\0' && i + 1U < z.name.size(); ++i) z.name[i] = name[i];
  z.kind = kind;
  for (std::size_t k = 0; k < 3; ++k) {
    z.min_mm[k] = c[k] - half;
    z.max_mm[k] = c[k] + half;
  }
  return z;
}

SafetyLimits limits() {
  SafetyLimits l{};
  l.checksum = kChecksum;
  l.tcp_mm = {0.0F, 0.0F, 120.0F};
  l.tool_radius_mm = 40.0F;
  for (auto& j : l.joints) j = JointLimit{-2.8F, 2.8F, 3.0F};
  l.joints[0] = JointLimit{-1.0F, 1.0F, 3.0F};
  l.joints[5].max_speed_rad_s = 0.8F;  // the harness's random speeds exceed it now and then
  l.tcp_max_speed_mm_s = 3000.0F;
  l.reduced_tcp_max_speed_mm_s = 300.0F;
  l.reduced_ramp_ms = 100;
  l.orientation_enabled = true;
  l.orientation_axis = pose_of(kPose[kHome], l).tool_z;  // unit
  l.orientation_max_deviation_rad = 0.8F;
  l.zone_count = 3;
  l.zones[0] = box_around("table", ZoneKind::keep_out, pose_of(kPose[kZone], l).tcp, 60.0F);
  l.zones[1] = box_around("loading", ZoneKind::reduced, pose_of(kPose[kReduced], l).tcp, 60.0F);
  l.zones[2] = box_around("cell", ZoneKind::keep_in, Vec3{0.0F, 0.0F, 0.0F}, 5000.0F);
  return l;
}

// What the reference needs from the kinematics, computed here: the zone distances and the
// TCP speed with the core's arm model (shared geometry), the cone and the reduced box by hand.
ref::Geometry geometry_of(const SafetyLimits& l, const Feedback& fb) {
  JointArray q{};
  JointArray qd{};
  for (std::size_t i = 0; i < kAxes; ++i) {
    q[i] = fb.drive[i].position_rad;
    qd[i] = fb.drive[i].velocity_rad_s;
  }
  const ArmPose p = pose_of(q, l);
  ref::Geometry g{};
  for (std::size_t k = 0; k < l.zone_count; ++k) {
    const Zone& z = l.zones[k];
    if (z.kind == ZoneKind::reduced) {
      bool in = true;
      for (std::size_t a = 0; a < 3; ++a) in = in && p.tcp[a] >= z.min_mm[a] && p.tcp[a] <= z.max_mm[a];
      g.in_reduced_zone = g.in_reduced_zone || in;
    } else {
      g.zone_outside[g.zones++] = ZoneMonitor::outside_mm(z, p, l.tool_radius_mm);
    }
  }
  g.orientation = l.orientation_enabled;
  const Vec3& a = l.orientation_axis;
  g.orientation_outside = std::cos(l.orientation_max_deviation_rad) -
                          (a[0] * p.tool_z[0] + a[1] * p.tool_z[1] + a[2] * p.tool_z[2]);
  g.tcp_speed_mm_s = point_speed(p, p.tcp, kAxes, qd);
  return g;
}

// T1 speed: the points the reference differentiates itself (link origins 1..5, the flange,
// the TCP) where the core's kinematics puts them at the measured positions of `fb`, the TCP
// as the core is configured with (lim.tcp_mm, limits or not).
ref::Geometry& with_t1_points(ref::Geometry& g, const SafetyLimits& l, const Feedback& fb) {
  JointArray q{};
  for (std::size_t i = 0; i < kAxes; ++i) q[i] = fb.drive[i].position_rad;
  const ArmPose p = pose_of(q, l);
  g.arm = true;
  for (std::size_t k = 0; k + 1U < ref::kT1Points; ++k) {
    g.t1_points[k] = p.origin[k + 1U];
  }
  g.t1_points[ref::kT1Points - 1U] = p.tcp;
  return g;
}

ref::Limits ref_limits(const SafetyLimits& l, bool validated) {
  ref::Limits r{};
  r.configured = true;
  r.validated = validated;
  r.checksum = l.checksum;
  for (std::size_t i = 0; i < kAxes; ++i) {
    r.min_rad[i] = l.joints[i].min_rad;
    r.max_rad[i] = l.joints[i].max_rad;
    r.max_speed_rad_s[i] = l.joints[i].max_speed_rad_s;
  }
  r.tcp_max_mm_s = l.tcp_max_speed_mm_s;
  r.reduced_tcp_max_mm_s = l.reduced_tcp_max_speed_mm_s;
  r.ramp = ms_to_cycles(l.reduced_ramp_ms, 1000U);
  // SPEC §11, by hand from the configuration (not through the core's monitors).
  const CollaborativeLimits& c = l.collaborative;
  r.collaborative = c.enabled;
  r.field_reduced_mm_s = c.pfl_enabled && c.pfl_speed_mm_s < c.reduced_speed_mm_s ? c.pfl_speed_mm_s : c.reduced_speed_mm_s;
  r.auto_resume = c.auto_resume;
  r.resume_delay = c.resume_delay_ms;  // 1 ms cycles
  r.ssm = c.ssm_enabled;
  r.ssm_params = c.ssm;
  r.reaction = static_cast<Cycle>(c.ssm.reaction_s * 1000.0F + 0.5F);
  r.rise_mm = (2000.0F + l.tcp_max_speed_mm_s) * 0.001F;
  r.pfl = c.enabled && c.pfl_enabled;
  r.f_qs_n = c.f_qs_n;
  // SPEC §12 in cycles at 1 ms, computed here from the hours (not by core/'s brake test).
  r.bt_required = l.brake_test.configured;
  r.bt_interval = std::llround(static_cast<double>(l.brake_test.interval_h) * 3.6e6);
  r.bt_overdue = std::llround(static_cast<double>(l.brake_test.interval_h + l.brake_test.grace_h) * 3.6e6);
  r.bt_hold = l.brake_test.hold_ms;
  r.bt_max_drift_deg = l.brake_test.max_drift_deg;
  return r;
}

// SPEC §11 for the histories that run collaborative: fields, SSM with the SPEC's example
// figures, PFL for the hand (the cap, 1348 mm/s, is above the collaborative reduced speed
// here, so the lower one is collaborative.reduced_speed_mm_s; the test of the cap is
// test_collaborative's).
void make_collaborative(SafetyLimits& l, bool auto_resume) {
  CollaborativeLimits& c = l.collaborative;
  c.enabled = true;
  c.auto_resume = auto_resume;
  c.resume_delay_ms = 300;
  c.reduced_speed_mm_s = 200.0F;
  c.pfl_enabled = true;
  c.pfl_speed_mm_s = pfl_speed_cap_mm_s(BodyRegion::hand, 25.0F, 1.5F);
  c.f_qs_n = body_region(BodyRegion::hand).f_qs_n;  // collision detection: the random torques cross it
  c.ssm_enabled = true;
  c.ssm = SsmParams{1600.0F, 2000.0F, 0.02F, 200.0F, 100.0F};  // T_r 20 ms: the random runs are short
}

struct Harness {
  explicit Harness(std::uint32_t seed) : rng(seed), feedback_rng(seed * 7919U), limits_rng(seed * 104729U) {}
  std::mt19937 rng;
  // Feedback-monitoring faults (SPEC §7) draw from their own stream, and only in the
  // histories that ask for them, so the other histories keep their coverage.
  Cycle bus_boot_failed_at = 0;
  std::mt19937 feedback_rng;
  std::mt19937 limits_rng;  // SPEC §10 perturbations
  std::mt19937 torque_rng{20261127U};  // SPEC §11 drive torques (its own stream: the others unchanged)
  JointArray qd_prev{};     // the core's collision monitor differences velocities: so does the force here
  bool have_qd_prev = false;
  unsigned contact_left = 0;  // cycles of the current torque burst
  bool feedback_faults = false;
  bool rare_feedback(int per_100k) {
    return feedback_faults && static_cast<int>(feedback_rng() % 100000U) < per_100k;
  }
  Timing timing = to_timing(Config{});
  SignalLayer signals;
  SystemStateManager core{timing};
  ref::Supervisor reference{timing};
  Plant plant;
  RawInputs raw{};
  Feedback fb{};
  SupervisorOut out{};
  ref::Out rout{};
  std::uint32_t seq = 0;
  std::ostringstream log;  // what was done, for the failure message

  bool chance(int per_mille) { return static_cast<int>(rng() % 1000U) < per_mille; }

  void perturb(Cycle t) {
    // Inputs change rarely and mostly both channels together; sometimes one channel
    // alone (discrepancy, blink), so that every rule is met but the cell also runs.
    if (chance(1)) { raw.estop_a = raw.estop_b = !raw.estop_a; log << t << ":estop " << raw.estop_a << "\n"; }
    if (chance(!raw.estop_a ? 30 : 0)) { raw.estop_a = raw.estop_b = true; log << t << ":estop release\n"; }
    if (rare(3)) { raw.estop_b = !raw.estop_b; log << t << ":estop.b " << raw.estop_b << "\n"; }
    if (chance(1)) { raw.gate_a = raw.gate_b = !raw.gate_a; log << t << ":gate " << raw.gate_a << "\n"; }
    if (chance(!raw.gate_a ? 20 : 0)) { raw.gate_a = raw.gate_b = true; log << t << ":gate closed\n"; }
    if (rare(3)) { raw.gate_a = !raw.gate_a; log << t << ":gate.a " << raw.gate_a << "\n"; }
    const bool manual = raw.mode_t1 || raw.mode_t2;
    if (chance(manual ? 2 : 10)) { raw.enable_a = raw.enable_b = !raw.enable_a; raw.enable_panic = false; log << t << ":enable " << raw.enable_a << "\n"; }
    if (rare(5)) { raw.enable_panic = !raw.enable_panic; log << t << ":panic " << raw.enable_panic << "\n"; }
    if (rare(2)) { raw.enable_b = !raw.enable_b; log << t << ":enable.b " << raw.enable_b << "\n"; }
    if (chance(1)) {
      const auto m = rng() % 10U;  // mostly a valid position, sometimes none or two
      raw.mode_auto = m < 4U || m == 9U;
      raw.mode_t1 = (m >= 4U && m < 7U) || m == 9U;
      raw.mode_t2 = m == 7U;
      log << t << ":mode " << m << "\n";
    }
    if (t < button_held_until) {
      raw.reset_button = true;  // an episode: the button held (or stuck) for more than 5 s
    } else if (rare(20)) {
      button_held_until = t + 5200U;
      log << t << ":button held\n";
    } else if (chance(3)) {
      raw.reset_button = !raw.reset_button;
      log << t << ":button " << raw.reset_button << "\n";
    }
    // Plant faults and measurements.
    if (rare(10)) { const auto i = rng() % 6U; plant.drive_fault[i] = !plant.drive_fault[i]; log << t << ":drivefault " << i << "\n"; }
    if (rare(1)) { plant.fieldbus = !plant.fieldbus; log << t << ":fieldbus " << plant.fieldbus << "\n"; }
    if (fieldbus_down_until > 0U) { plant.fieldbus = t >= fieldbus_down_until; }
    if (bus_boot_failed_at > 0U && t == bus_boot_failed_at) {  // the bus scan found a wrong subdevice
      fb.fieldbus_boot_failed = true;
      fb.fieldbus_subdevice = 3;
      log << t << ":bus boot failed\n";
    }
    if (rare(5)) { plant.contactor_stuck_open = !plant.contactor_stuck_open; }
    if (rare_feedback(3)) { plant.contactor_welded = !plant.contactor_welded; log << t << ":welded " << plant.contactor_welded << "\n"; }
    if (rare_feedback(10)) { const auto i = feedback_rng() % 6U; plant.brake_welded_released[i] = !plant.brake_welded_released[i]; log << t << ":brake released " << i << "\n"; }
    if (rare_feedback(2)) { fb.self_test_ok = !fb.self_test_ok; log << t << ":self-test " << fb.self_test_ok << "\n"; }
    if (rare(5)) { const auto i = rng() % 6U; plant.brake_stuck[i] = !plant.brake_stuck[i]; }
    if (rare(10)) { const auto i = rng() % 6U; plant.drive_nostop[i] = !plant.drive_nostop[i]; }
    // SPEC §12: a brake becomes weak (slips under the test torque) or is replaced, from its
    // own stream so that the other perturbations keep their coverage.
    if (static_cast<int>(brake_rng() % 100000U) < 10) {
      const auto i = brake_rng() % 6U;
      weak[i] = !weak[i];
      log << t << ":brake weak " << i << " " << weak[i] << "\n";
    }
    const bool moving = out.motion.mode == MotionMode::Program || out.motion.mode == MotionMode::Jog;
    if (chance(moving ? 30 : 0)) { plant.vel[rng() % 6U] = static_cast<float>(rng() % 200U) / 100.0F - 1.0F; }
    fb.integrity_ok = !rare(3);
    // T1 speed: joint 1 creeps to and fro at a rate drawn now and then (about 0 to 300 mm/s
    // at the TCP), and now and then a frame brings no fresh sample (its own stream: the
    // others keep their histories).
    if (chance(5)) { creep_rate = static_cast<float>(rng() % 300U) / 500.0F; }
    stale_now = static_cast<int>(sample_rng() % 1000U) < 3;
    late_now = clock && !stale_now && static_cast<int>(sample_rng() % 1000U) < 2;
    if (chance(2)) { plant.program_finished = !plant.program_finished; }
    if (rare(20)) { plant.program_loaded = !plant.program_loaded; }
    // SPEC §10: the arm jumps into or out of a limit, the reduced input, the program's check.
    // From their own stream, so that the other histories keep their coverage.
    if (safety) {
      const auto lim_chance = [this](int per_100k) { return static_cast<int>(limits_rng() % 100000U) < per_100k; };
      if (pose != kHome && lim_chance(200)) { pose = kHome; log << t << ":pose home\n"; }
      if (lim_chance(out.contactor ? 80 : 10)) { pose = static_cast<Pose>(1U + limits_rng() % (kPoses - 1U)); log << t << ":pose " << static_cast<int>(pose) << "\n"; }
      if (raw.reduced_a ? lim_chance(5) : lim_chance(200)) { raw.reduced_a = raw.reduced_b = !raw.reduced_a; log << t << ":reduced " << raw.reduced_a << "\n"; }
      if (raw.reduced_b != raw.reduced_a ? lim_chance(500) : lim_chance(2)) { raw.reduced_b = !raw.reduced_b; log << t << ":reduced.b " << raw.reduced_b << "\n"; }
      if (within_limits ? lim_chance(3) : lim_chance(200)) { within_limits = !within_limits; log << t << ":program within limits " << within_limits << "\n"; }
    }
    // SPEC §11: a person walks through the fields, the distance sensor follows (or fails),
    // now and then one OSSD channel alone (FIELD_DISCREPANCY when it lasts).
    if (collab) {
      const auto c = [this](int per_100k) { return static_cast<int>(collab_rng() % 100000U) < per_100k; };
      if (c(raw.field_outer_a ? 60 : 150)) { raw.field_outer_a = raw.field_outer_b = !raw.field_outer_a; log << t << ":outer " << raw.field_outer_a << "\n"; }
      if (c(raw.field_inner_a ? 40 : 200)) { raw.field_inner_a = raw.field_inner_b = !raw.field_inner_a; log << t << ":inner " << raw.field_inner_a << "\n"; }
      if (c(raw.field_inner_b != raw.field_inner_a ? 3000 : 1)) { raw.field_inner_b = !raw.field_inner_b; log << t << ":inner.b " << raw.field_inner_b << "\n"; }
      if (c(raw.field_outer_b != raw.field_outer_a ? 3000 : 1)) { raw.field_outer_b = !raw.field_outer_b; log << t << ":outer.b " << raw.field_outer_b << "\n"; }
      // The program runs long (it finishes now and then only), so that AUTO_RUNNING meets SSM.
      plant.program_finished = plant.program_finished && c(2000);
      if (c(100)) {
        constexpr std::array<std::int32_t, 6> kSeparations{300, 600, 800, 1500, 5000, -20};
        raw.separation_mm = kSeparations[collab_rng() % kSeparations.size()];
        raw.separation_valid = !c(10000);
        log << t << ":separation " << raw.separation_mm << " valid " << raw.separation_valid << "\n";
      }
    }
  }
  // T1 speed (issue 35): joint 1's offset from the pose (rad, within +-kCreep: a recovering
  // limit gets no worse by it than its tolerance, kWorseJointRad, kWorseZoneMm within 0.7 m
  // of axis 1, kWorseOrientationCos), its rate and direction; the sample timing: this cycle's
  // frame holds the last sample (stale_now) or carries one a SYNC0 pulse late (late_now, with
  // the drives' clock), the positions of the last fresh sample and the cycles since it.
  static constexpr float kCreep = 0.0005F;
  static_assert(2.0F * kCreep < kWorseJointRad && 2.0F * kCreep * 700.0F < kWorseZoneMm &&
                2.0F * kCreep < kWorseOrientationCos);
  float creep = 0.0F;
  float creep_rate = 0.0F;
  float creep_dir = 1.0F;
  bool clock = false;  // this history's drives sample at SYNC0 (Feedback::sample_clock)
  bool stale_now = false;
  bool late_now = false;
  JointArray held{};
  bool have_held = false;
  std::uint16_t since_sample = 1;
  std::mt19937 sample_rng{777U};
  void advance_creep() {
    creep += creep_dir * creep_rate * 0.001F;
    if (creep > kCreep || creep < -kCreep) {
      creep = creep > 0.0F ? kCreep : -kCreep;
      creep_dir = -creep_dir;
    }
  }
  // The measured positions as the frame brings them, from the true ones.
  void sample(const JointArray& q) {
    const bool hold = stale_now && have_held;
    fb.sample_clock = clock;
    fb.stale = hold && !clock;
    if (hold) {
      since_sample = static_cast<std::uint16_t>(since_sample + 1U);
      fb.sample_span = 0;
    } else {
      held = q;
      have_held = true;
      fb.sample_span = clock ? since_sample : 0U;
      since_sample = 1;
    }
    for (std::size_t i = 0; i < kAxes; ++i) fb.drive[i].position_rad = held[i];
  }
  // SPEC §14: the cross-check's verdict on the partner channel and each axis' load-side
  // encoder, in the histories that ask for them, from a stream of their own: K2 welded now
  // and then, a mismatch or a lost partner (rare), an encoder off by a little (within the
  // tolerance) or a lot, or stuck.
  bool two_channels = false;
  std::mt19937 channel_rng{2718281U};
  std::mt19937 link_rng{1414213U};
  bool link_faults = false;  // half the two-channel histories: the others keep their coverage
  std::array<float, kAxes> enc_offset{};
  std::array<bool, kAxes> enc_stuck{};
  std::array<float, kAxes> enc_stuck_at{};
  bool k2_welded = false;
  void perturb_channels(Cycle t) {
    const auto c = [this](int per_100k) { return static_cast<int>(channel_rng() % 100000U) < per_100k; };
    fb.cross.partner = Channel::b;
    fb.load_encoders = true;
    fb.two_contactors = true;
    if (c(3)) { fb.cross.mismatch = true; fb.cross.field = static_cast<CrossField>(1U + channel_rng() % 8U); log << t << ":mismatch\n"; }
    if (c(3)) { fb.cross.lost = true; log << t << ":lost\n"; }
    if (c(20)) {
      const auto i = channel_rng() % 6U;
      const float offsets[] = {0.0F, 0.004F, -0.006F, 0.02F, -0.5F};
      enc_offset[i] = offsets[channel_rng() % 5U];
      log << t << ":encoder " << i << " offset " << enc_offset[i] << "\n";
    }
    if (c(5)) { const auto i = channel_rng() % 6U; enc_stuck[i] = !enc_stuck[i]; enc_stuck_at[i] = fb.drive[i].position_rad; log << t << ":encoder " << i << " stuck " << enc_stuck[i] << "\n"; }
    if (c(3)) { k2_welded = !k2_welded; log << t << ":k2 welded " << k2_welded << "\n"; }
    // Issue 37: the black channel's connections, up; now and then one fails its check.
    fb.link.configured = true;
    fb.link.up = true;
    // (a stream of its own: the channel stream's histories stay as they were)
    if (link_faults && static_cast<int>(link_rng() % 100000U) < 3) {
      fb.link.fault = true;
      fb.link.connection = static_cast<std::uint16_t>(0xA001U + link_rng() % 2U);
      fb.link.error = static_cast<LinkError>(1U + link_rng() % 6U);
      log << t << ":link fault\n";
    }
  }
  void load_encoders() {
    for (std::size_t i = 0; i < kAxes; ++i) {
      fb.drive[i].load_position_rad = enc_stuck[i] ? enc_stuck_at[i] : fb.drive[i].position_rad + enc_offset[i];
    }
    fb.k2_closed = k2_welded || fb.contactor_closed;  // follows K1's command (same timing), or welded
  }
  bool collab = false;  // SPEC §11 configured and perturbed
  std::mt19937 collab_rng{12345U};
  std::mt19937 brake_rng{4242U};
  bool brake_tests = true;  // SPEC §12: brake_test commands in the history
  std::array<bool, kAxes> weak{};
  std::array<float, kAxes> slip{};
  // SPEC §12: a configuration that requires the brake test every 0.002 h (7.2 s) with a
  // 0.001 h grace and 100 ms pushes, so that histories see it due, overdue, pass and fail.
  bool brake_cfg = false;
  bool safety = true;  // SPEC §10 monitored (configure_limits) and perturbed
  Pose pose = kHome;
  bool within_limits = true;
  SafetyLimits lim = limits();
  // The core's collision model of the arm the core is configured with (its chain, the limits' inertials).
  const ArmDynamicsModel dyn = prepare_dynamics(geometry(), lim.inertials);
  bool validated_at_start = true;

  void configure() {
    if (!safety) {
      core.configure_arm(geometry(), lim.tcp_mm);  // the T1 speed's arm, without limits
      return;
    }
    if (brake_cfg) {
      lim.brake_test.configured = true;
      lim.brake_test.interval_h = 0.002F;
      lim.brake_test.grace_h = 0.001F;
      lim.brake_test.hold_ms = 100;
    }
    core.configure_limits(lim, geometry(), 1000U, validated_at_start);
    BrakeTestHistory h{};
    h.last = BrakeTestResult::passed;
    h.passed_ever = true;
    h.pass_age_ms = 1000;  // a second ago, at every (re)start
    core.configure_brake_test(h);
    ref::Limits rl = ref_limits(lim, validated_at_start);
    rl.bt_passed_ever = true;
    rl.bt_pass_age = 1000;
    reference = ref::Supervisor{ref_timing, rl};
  }

  // Per 10^5: rarer than chance().
  bool rare(int per_100k) { return static_cast<int>(rng() % 100000U) < per_100k; }

  Command valid(CommandId id) {
    Command c{};
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    c.source = static_cast<std::uint8_t>(chance(900) ? Source::pendant : (chance(500) ? Source::remote : Source::observer));
    c.axis = static_cast<std::int8_t>(1U + rng() % 6U);
    c.dir = chance(500) ? 1 : -1;
    c.speed = static_cast<std::uint8_t>(1U + rng() % 100U);
    c.mode = static_cast<std::uint8_t>(1U + rng() % 3U);
    c.has_code = 1U;
    const std::uint32_t active = safety ? kChecksum : 0U;  // 0: the checksum without a configuration
    c.code = chance(500) ? active : static_cast<std::uint32_t>(rng());
    return c;
  }

  std::size_t commands(std::array<Command, 16>& cmds, Cycle t) {
    std::size_t n = 0;
    if (t >= link_lost_until && rare(200)) {
      link_lost_until = t + 150U;  // an episode: the pendant's link drops for 150 ms
    }
    if (out.sub == Sub::MANUAL_JOGGING && t % 40U == 0U && t >= link_lost_until) {
      cmds[n++] = valid(CommandId::jog);  // the pendant's keep-alive, usually on time
    }
    // SPEC §11 histories: the operator starts and resumes often, so that the program runs
    // while people come and go (from the collaborative stream: the others keep theirs).
    if (collab && (out.sub == Sub::AUTO_IDLE || out.sub == Sub::AUTO_PAUSED) && collab_rng() % 1000U < 5U) {
      Command c = valid(out.sub == Sub::AUTO_IDLE ? CommandId::start : CommandId::resume);
      c.source = static_cast<std::uint8_t>(Source::pendant);
      log << t << ":cmd " << static_cast<int>(c.id) << " (collaborative)\n";
      cmds[n++] = c;
    }
    const int k = chance(25) ? 1 + static_cast<int>(rng() % 2U) : 0;
    for (int i = 0; i < k; ++i) {
      // brake_test (the last command) comes from its own stream below: a test lasts seconds,
      // and drawn as often as the others it would crowd out the rest of the histories.
      Command c = valid(static_cast<CommandId>(rng() % (kCommandCount - 1U)));
      if (chance(30)) {  // malformed now and then
        c.id = static_cast<std::uint8_t>(rng() % (kCommandCount + 1U));
        c.source = static_cast<std::uint8_t>(rng() % (kSourceCount + 1U));
        c.axis = static_cast<std::int8_t>(rng() % 9U);
        c.dir = static_cast<std::int8_t>(static_cast<int>(rng() % 3U) - 1);
        c.speed = static_cast<std::uint8_t>(rng() % 102U);
        c.mode = static_cast<std::uint8_t>(rng() % 5U);
      }
      log << t << ":cmd " << static_cast<int>(c.id) << " src " << static_cast<int>(c.source) << "\n";
      cmds[n++] = c;
    }
    if (brake_tests && brake_rng() % 1000U < 3U && n < cmds.size()) {  // SPEC §12, from the pendant or a remote client
      Command c{};
      c.seq = ++seq;
      c.id = static_cast<std::uint8_t>(CommandId::brake_test);
      c.source = static_cast<std::uint8_t>((brake_rng() % 4U == 0U) ? Source::remote : Source::pendant);
      log << t << ":cmd brake_test src " << static_cast<int>(c.source) << "\n";
      cmds[n++] = c;
    }
    return n;
  }

  Cycle button_held_until = 0;
  Cycle link_lost_until = 0;
  Cycle fieldbus_down_until = 0;  // > 0: the bus is down until then (boot failure episode)
  Cycle locked_since = 0;

  // After a lockout only a power cycle helps: restart everything, keep the history going.
  void power_cycle(Cycle t) {
    validated_at_start = reference.validated();  // the event log keeps the confirmation
    signals = SignalLayer{};
    core = SystemStateManager{timing};
    reference = ref::Supervisor{ref_timing};
    plant = Plant{};
    raw = RawInputs{};
    fb = Feedback{};
    out = SupervisorOut{};
    enc_offset = {};
    enc_stuck = {};
    k2_welded = false;
    fieldbus_down_until = 0;
    button_held_until = 0;
    within_limits = true;
    have_qd_prev = false;
    have_held = false;
    since_sample = 1;
    configure();
    log << t << ":power cycle\n";
  }
  Timing ref_timing = timing;

  std::array<long, kStateCount> state_cycles{};
  std::array<long, 8> sub_cycles{};
  std::array<long, kAlarmCount> alarm_cycles{};
  std::array<long, kResultCount> results{};
  long ssm_cycles = 0;   // SSM acting (collaborative histories in AUTO)
  long ssm_running = 0;  // ... in AUTO_RUNNING
  long ssm_over = 0;     // ... with the TCP above v_allowed + 5 %

  // Returns an empty string when both agree for `cycles`, else what differed.
  std::string run(Cycle cycles) {
    std::array<Command, 16> cmds{};
    Cycle local = 0;  // cycles since the last power cycle: the supervisors count from 0
    for (Cycle t = 0; t < cycles; ++t, ++local) {
      if (out.state == State::ERROR_LOCKOUT) {
        if (locked_since == 0U) locked_since = t;
        if (t - locked_since > 300U) {
          power_cycle(t);
          locked_since = 0;
          local = 0;
        }
      }
      perturb(t);
      if (two_channels) {
        perturb_channels(t);
      }
      signals.update(raw, local, timing);
      plant.fill(fb);
      ref::Geometry geo{};
      // SPEC §11: now and then a burst of 1..8 cycles of random torques (a contact, a drive
      // misreading), so that rule 8 is met and missed; else the torques the model expects.
      if (contact_left == 0U && std::uniform_int_distribution<int>(0, 299)(torque_rng) == 0) {
        contact_left = static_cast<unsigned>(std::uniform_int_distribution<int>(1, 8)(torque_rng));
      }
      // SPEC §12: a weak brake lets the axis under test follow the offset set-point.
      const BrakeTestRequest& bt = out.motion.brake_test;
      if (bt.axis >= 1U && bt.axis <= kAxes && bt.dir != 0 && weak[bt.axis - 1U]) {
        slip[bt.axis - 1U] += static_cast<float>(bt.dir) * 0.0005F;
      }
      advance_creep();
      if (late_now) {
        advance_creep();  // the frame carries the next pulse's sample: two cycles of motion
        since_sample = static_cast<std::uint16_t>(since_sample + 1U);
      }
      JointArray q{};
      for (std::size_t i = 0; i < kAxes; ++i) q[i] = (safety ? kPose[pose][i] : 0.0F) + slip[i] + (i == 0U ? creep : 0.0F);
      sample(q);
      if (two_channels) {
        load_encoders();
      }
      if (safety) {
        fb.program_within_limits = within_limits;
        geo = geometry_of(lim, fb);
        // The force the torques show (the model's agreement with the arm is test_collision's).
        JointArray q{};
        JointArray qd{};
        JointArray qdd{};
        for (std::size_t i = 0; i < kAxes; ++i) {
          q[i] = fb.drive[i].position_rad;
          qd[i] = fb.drive[i].velocity_rad_s;
          qdd[i] = (qd[i] - qd_prev[i]) * 1000.0F;
        }
        ArmDynamicsState model{};
        arm_dynamics(dyn, q, qd, have_qd_prev ? qdd : JointArray{}, lim.payload_kg, lim.tcp_mm, model);
        for (std::size_t i = 0; i < kAxes; ++i) {
          const float expected = std::round(1000.0F * model.tau_nm[i] / dyn.rated_torque_nm[i]);
          const float burst = (contact_left > 0U)
                                  ? static_cast<float>(std::uniform_int_distribution<int>(-1500, 1500)(torque_rng))
                                  : 0.0F;
          fb.drive[i].torque_permille = static_cast<std::int16_t>(std::clamp(expected + burst, -3000.0F, 3000.0F));
        }
        contact_left = (contact_left > 0U) ? contact_left - 1U : 0U;
        Vec3 f{};
        geo.contact_force_n = tcp_force_from_drives(fb, dyn.rated_torque_nm, model, f);
      }
      with_t1_points(geo, lim, fb);
      for (std::size_t i = 0; i < kAxes; ++i) qd_prev[i] = fb.drive[i].velocity_rad_s;
      have_qd_prev = true;
      const std::size_t n = commands(cmds, t);
      const std::size_t a = core.step(signals.inputs(), fb, cmds.data(), n, out);
      const std::size_t b = reference.step(signals.inputs(), fb, cmds.data(), n, rout, geo);
      std::ostringstream d;
      if (a != b) d << " taken " << a << "/" << b;
      if (out.state != rout.state) d << " state " << to_string(out.state) << "/" << to_string(rout.state);
      if (out.sub != rout.sub) d << " sub " << to_string(out.sub) << "/" << to_string(rout.sub);
      if (out.stop != rout.stop) d << " stop " << to_string(out.stop) << "/" << to_string(rout.stop);
      if (out.contactor != rout.contactor) d << " contactor";
      if (out.drives_enable != rout.drives) d << " drives";
      if (out.brakes_release != rout.brakes_release) d << " brakes";
      if (out.reset_lamp != rout.reset_lamp) d << " lamp";
      if (out.brake_test_axis != rout.brake_test_axis) {
        d << " brake_test_axis " << int(out.brake_test_axis) << "/" << int(rout.brake_test_axis);
      }
      if (out.motion.fault_reset != rout.fault_reset) d << " fault_reset";
      if (out.alarms != rout.alarms) d << " alarms " << std::hex << out.alarms << "/" << rout.alarms << std::dec;
      if (out.reply_count != rout.reply_count) {
        d << " replies " << static_cast<int>(out.reply_count) << "/" << static_cast<int>(rout.reply_count);
      } else {
        for (std::size_t i = 0; i < out.reply_count; ++i) {
          const Reply& x = out.replies[i];
          const Reply& y = rout.replies[i];
          if (x.seq != y.seq || x.result != y.result || x.cmd != y.cmd || x.source != y.source) {
            d << " reply#" << i << " seq " << x.seq << "/" << y.seq << " " << to_string(x.result) << "/"
              << to_string(y.result) << " cmd " << static_cast<int>(x.cmd);
          }
        }
      }
      if (!d.str().empty()) {
        std::ostringstream msg;
        msg << "cycle " << t << " (core/reference):" << d.str();
        return msg.str();
      }
      ++state_cycles[static_cast<std::size_t>(out.state)];
      ++sub_cycles[static_cast<std::size_t>(out.sub)];
      for (std::size_t i = 0; i < kAlarmCount; ++i) alarm_cycles[i] += (out.alarms >> i) & 1U;
      for (std::size_t i = 0; i < out.reply_count; ++i) ++results[static_cast<std::size_t>(out.replies[i].result)];
      if (out.safety.ssm) {
        ++ssm_cycles;
        ssm_running += out.sub == Sub::AUTO_RUNNING ? 1 : 0;
        ssm_over += (out.sub == Sub::AUTO_RUNNING && !(out.safety.tcp_speed_mm_s <= out.safety.v_allowed_mm_s * 1.05F)) ? 1 : 0;
      }
      plant.follow(out);
    }
    return {};
  }
};

std::string tail(const std::string& s, std::size_t lines) {
  std::size_t pos = s.size();
  for (std::size_t i = 0; i <= lines && pos != std::string::npos && pos > 0; ++i) {
    pos = s.rfind('\n', pos - 1);
  }
  return (pos == std::string::npos) ? s : s.substr(pos + 1);
}

}  // namespace

// @req TR-PRIORITY CYC-ORDER
TEST(Differential, CoreAndReferenceAgreeOverRandomHistories) {
  constexpr int kSeeds = 40;
  constexpr Cycle kCycles = 30000;
  std::array<long, kStateCount> states{};
  std::array<long, 8> subs{};
  std::array<long, kAlarmCount> alarms{};
  std::array<long, kResultCount> results{};
  std::array<long, 3> ssm{};
  for (int seed = 1; seed <= kSeeds; ++seed) {
    Harness h(static_cast<std::uint32_t>(seed));
    // SPEC §10: three histories in four run with a safety configuration (a third of those
    // start with it not validated yet); every fourth runs without one, as the state machine's
    // own unit tests do, and keeps its history as it was (seed 40's stop-time episode: with
    // speed limits, a drive that does not stop trips SPEED_LIMIT before the stop time is over).
    h.safety = seed % 4 != 0;
    h.validated_at_start = seed % 3 != 1;
    // SPEC §11: one history in four runs a collaborative configuration (every other one of
    // them without automatic resume), with a person walking through the fields.
    h.collab = seed % 4 == 2;
    h.clock = seed % 3 == 0;  // the drives' sample clock (EtherCAT DC) in one history in three
    h.collab_rng.seed(static_cast<std::uint32_t>(seed) * 15485863U);
    if (h.collab) {
      make_collaborative(h.lim, seed % 8 == 2);
      h.raw.separation_mm = 5000;  // the sensor sees the person far away at first
      h.raw.separation_valid = true;
    }
    h.brake_cfg = seed % 2 == 1;
    h.configure();
    if (seed % 8 == 0) {
      h.fieldbus_down_until = 3500;  // the bus never comes up in time: BOOT_FAILED
    }
    if (seed % 8 == 4) {
      h.bus_boot_failed_at = static_cast<Cycle>(seed);  // the bus is not as configured: BOOT_FAILED at once
    }
    h.feedback_faults = seed % 5 == 3;
    h.two_channels = seed % 6 == 5;  // SPEC §14 (its own stream: the other histories unchanged)
    h.channel_rng.seed(static_cast<std::uint32_t>(seed) * 2654435761U);
    h.link_rng.seed(static_cast<std::uint32_t>(seed) * 40503U + 7U);
    h.link_faults = seed % 12 == 11;
    const std::string diff = h.run(kCycles);
    ASSERT_TRUE(diff.empty()) << "seed " << seed << ": " << diff << "\nlast events:\n" << tail(h.log.str(), 25);
    for (std::size_t i = 0; i < states.size(); ++i) states[i] += h.state_cycles[i];
    for (std::size_t i = 0; i < subs.size(); ++i) subs[i] += h.sub_cycles[i];
    for (std::size_t i = 0; i < alarms.size(); ++i) alarms[i] += h.alarm_cycles[i];
    for (std::size_t i = 0; i < results.size(); ++i) results[i] += h.results[i];
    ssm[0] += h.ssm_cycles;
    ssm[1] += h.ssm_running;
    ssm[2] += h.ssm_over;
  }
  std::printf("SSM acting %ld cycles, %ld in AUTO_RUNNING, %ld of them over v_allowed + 5 %%\n", ssm[0], ssm[1], ssm[2]);
  // The comparison means something only if the histories went everywhere.
  for (std::size_t i = 0; i < states.size(); ++i) {
    EXPECT_GT(states[i], 100) << "state never reached: " << to_string(static_cast<State>(i));
  }
  for (std::size_t i = 1; i < subs.size(); ++i) {
    EXPECT_GT(subs[i], 100) << "sub-state never reached: " << to_string(static_cast<Sub>(i));
  }
  // The reference models SPEC §10 (safe limits, validation, reduced mode, recovery), §11's
  // fields, rule 9, the automatic resume, FIELD_INTERRUPTED and SSM, and §12 (brake test,
  // abstractly: its sequence on the measured positions and brake feedback, due and required
  // in cycles): every alarm and result is covered.
  const auto not_modelled_alarm = [](std::size_t i) { return i >= kAlarmCount; };
  const auto not_modelled_result = [](Result) { return false; };
  for (std::size_t i = 0; i < alarms.size(); ++i) {
    if (not_modelled_alarm(i)) continue;
    EXPECT_GT(alarms[i], 0) << "alarm never raised: " << to_string(static_cast<AlarmId>(i));
  }
  for (std::size_t i = 0; i < results.size(); ++i) {
    if (static_cast<Result>(i) == Result::QUEUE_FULL || not_modelled_result(static_cast<Result>(i))) continue;
    EXPECT_GT(results[i], 0) << "result never given: " << to_string(static_cast<Result>(i));
  }
}

// The poses of the harness violate what they say (else the comparison of SPEC §10 would
// compare nothing), by the harness's own measure and by the core's monitors.
TEST(Differential, ThePosesViolateWhatTheySay) {
  const SafetyLimits l = limits();
  SafeLimitMonitors m;
  m.configure(l, geometry(), 1000U);
  for (std::size_t k = 0; k < kPoses; ++k) {
    Feedback fb{};
    for (std::size_t i = 0; i < kAxes; ++i) fb.drive[i].position_rad = kPose[k][i];
    const ref::Geometry g = geometry_of(l, fb);
    safestate::test::LimitResult r{};
    safestate::test::evaluate(m, fb, false, false, 0U, r);
    const bool joint = k == kJoint || k == kJointBetter || k == kJointWorse;
    EXPECT_EQ(g.zone_outside[0] > 0.0F, k == kZone) << "pose " << k << " keep_out " << g.zone_outside[0];
    EXPECT_LE(g.zone_outside[1], 0.0F) << "pose " << k << " keep_in";
    EXPECT_EQ(g.orientation_outside > 0.0F, k == kOrientation) << "pose " << k << " cone " << g.orientation_outside;
    EXPECT_EQ(g.in_reduced_zone, k == kReduced) << "pose " << k;
    EXPECT_EQ(r.outside, joint || k == kZone || k == kOrientation) << "pose " << k;
    EXPECT_EQ(r.in_reduced_zone, k == kReduced) << "pose " << k;
  }
}

TEST(Differential, TheComparisonCanFail) {
  // A reference with other timeouts must disagree: the harness compares what it claims.
  Harness h(7);
  h.safety = false;  // the history this test was written on (no SPEC §10 perturbation)
  h.brake_tests = false;  // ... nor SPEC §12's commands
  h.configure();          // the core's arm (T1 speed)
  h.ref_timing.jog_timeout = 30;
  h.ref_timing.max_stop = 50;
  h.reference = ref::Supervisor{h.ref_timing};
  EXPECT_FALSE(h.run(300000).empty());
}

// Counterexamples of `safestate check` replayed through the checker's own cycle (every
// invariant, and the core against the reference after every cycle), each for 2000 cycles
// past its last line, so that a disagreement the exhaustive run once found stays found at
// `make test`'s depth. The `expect` lines are what the checker wrote; `safestate replay` runs
// them, not this test.
// @req AL-FEEDBACK
TEST(Differential, TheCheckersCounterexamplesReplayInAgreement) {
  struct Case {
    const char* why;
    const char* scn;
  };
  const Case cases[] = {
      // Issue 40: the guard opened in AUTO_IDLE, a Cat 1 stop commands the brakes engaged in
      // cycle 402; brake 2 sticks released in cycle 463, as its 60 ms were ending (its feedback
      // had said engaged for one cycle, 462, which ended the stop). SPEC §7 counts the 300 ms
      // from the command: the core raises BRAKE_NOT_ENGAGED in cycle 703; the reference counted
      // from the last engaged reading and was 60 ms late.
      {"brake 2 stuck released as it engaged (depth 5, issue 40)",
       "@100 cmd reset\n"
       "@110 cmd servo_on\n"
       "@400 in reset_button=0\n"
       "@401 in gate=open\n"
       "@402 in reset_button=1\n"
       "@463 fault brake 2 stuck_released\n"
       "@703 expect state=IDLE sub=-   # core/reference: alarm BRAKE_NOT_ENGAGED 1/0\n"},
  };
  for (const Case& c : cases) {
    std::string error;
    const std::string broke = safestate::check::replay_checked(c.scn, c.why, 2000, error);
    EXPECT_TRUE(error.empty()) << c.why << ": " << error;
    EXPECT_TRUE(broke.empty()) << c.why << ": " << broke;
  }
}

// SPEC §13: each safety function triggered on the running simulated cell, in-process,
// counted in cycles (the cell has no clock). tests/unit/test_rta_measured.cpp checks the
// counts against analyse(); bench/response_time.py puts them beside it in
// docs/response-time.md.
// @req RTA-MEASURED
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>

#include "safestate/robot/description.hpp"
#include "safestate/rta/rta.hpp"
#include "safestate/controller/controller.hpp"
#include "safestate/core/arm.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/motion/limits.hpp"
#include "safestate/backends/simulated.hpp"

namespace safestate::rta {

namespace {

using core::CommandId;
using core::State;
using Pred = std::function<bool(const sim::Cell&)>;

constexpr int kLimit = 20000;  // cycles any one wait may take

struct Run {
  std::unique_ptr<sim::Cell> cell;
  std::uint32_t seq = 0;
  bool ok = true;

  Run(const core::Config& cfg, const core::SafetyLimits& limits) : cell(std::make_unique<sim::Cell>(cfg)) {
    cell->configure_limits(limits, true);
    // A configuration that requires the brake test (SPEC §12) finds one passed just now.
    core::BrakeTestHistory h{};
    h.last = core::BrakeTestResult::passed;
    h.passed_ever = true;
    cell->configure_brake_test(h);
  }
  int until(const Pred& p, int limit = kLimit) {
    for (int k = 1; k <= limit; ++k) {
      cell->step();
      if (p(*cell)) return k;
    }
    ok = false;
    return -1;
  }
  void cycles(int n) {
    for (int i = 0; i < n; ++i) cell->step();
  }
  bool cmd(CommandId id, int axis = 0, int dir = 0, int speed = 0) {
    core::Command c{};
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    core::set_jog(c, static_cast<std::int8_t>(axis), static_cast<std::int8_t>(dir), static_cast<std::uint8_t>(speed));
    if (cell->submit(c) != core::Result::OK) return ok = false;
    cell->step();
    const core::SupervisorOut& o = cell->out();
    for (std::size_t i = 0; i < o.reply_count; ++i) {
      if (o.replies[i].seq == c.seq && o.replies[i].result == core::Result::OK) return true;
    }
    return ok = false;
  }
  // Armed in `m` (AUTO: the demo program running; T1: the enabling device held).
  void arm(core::Mode m) {
    core::RawInputs& in = cell->inputs();
    // SPEC §11: with SSM on, a distance sensor that sees nobody (invalid would hold the arm).
    in.separation_mm = 100000;
    in.separation_valid = true;
    in.mode_auto = m == core::Mode::AUTO;
    in.mode_t1 = m == core::Mode::T1;
    in.mode_t2 = m == core::Mode::T2;
    until([](const sim::Cell& c) { return c.out().state == State::ESTOP_RESET_NEEDED; });
    cmd(CommandId::reset);
    if (m != core::Mode::AUTO) {
      in.enable_a = in.enable_b = true;
      cycles(1);
    }
    cmd(CommandId::servo_on);
    until([](const sim::Cell& c) { return c.out().state == State::OPERATIONAL; });
  }
  // The demo program in AUTO until axis 1 moves fast (a stop from speed, not from rest).
  void running() {
    arm(core::Mode::AUTO);
    cmd(CommandId::start);
    until([](const sim::Cell& c) { return std::fabs(c.view().velocities_rad_s[0]) > 1.0F; });
  }
  [[nodiscard]] bool still() const {
    for (const float v : cell->view().velocities_rad_s) {
      if (!(std::fabs(v) < cell->config().standstill_rad_s)) return false;
    }
    return true;
  }
  [[nodiscard]] std::string alarm() const {
    const core::AlarmMask m = cell->out().alarms_raised;
    for (std::size_t i = 0; i < core::kAlarmCount; ++i) {
      const auto id = static_cast<core::AlarmId>(i);
      if ((m & core::bit(id)) != 0U) return core::to_string(id);
    }
    return "";
  }
};

// After the change: cycles to the first commanded safe output (`out`), then to the safe
// state (`safe`: a plant state, seen one cycle late, so one less).
// `second`, when given, is the other channel: it follows kSecondChannelCycles later (within
// discrepancy_ms, so no discrepancy lockout), as a real two-channel contact does.
// `crossed`, when given, is a measured quantity past its limit (the limits of SPEC §10, T1
// speed, SSM): the count starts with the first cycle whose inputs show it, not with the
// fault that led there (the plant crossed in the cycle before, as an input changes between
// two cycles). A safe output before that cycle is a setup failure: something else stopped
// the arm first, and the function under test was not what reacted.
constexpr std::uint64_t kSecondChannelCycles = 5;
using Change = std::function<void(core::RawInputs&)>;

void count(Run& r, Measured& m, const Pred& out, const Pred& safe, const Change& second = nullptr,
           const Pred& crossed = nullptr) {
  std::uint64_t k = 0;
  bool out_seen = false;
  bool started = !crossed;
  for (int i = 1; i <= kLimit; ++i) {
    if (second && k == kSecondChannelCycles) second(r.cell->inputs());
    r.cell->step();
    if (!started) {
      started = crossed(*r.cell);
      if (!started && out(*r.cell)) {
        m.measured = false;
        m.how += " (stopped by " + r.alarm() + " before the limit was crossed)";
        return;
      }
      if (!started) continue;
    }
    ++k;
    if (!out_seen && out(*r.cell)) {
      out_seen = true;
      m.reaction_cycles = k;
      if (m.alarm.empty()) m.alarm = r.alarm();
    }
    if (out_seen && m.alarm.empty()) m.alarm = r.alarm();
    if (out_seen && safe(*r.cell)) {
      m.safe_cycles = k - 1U;
      m.measured = r.ok;
      return;
    }
  }
  m.measured = false;
  const char* what = !started ? "limit never crossed" : (out_seen ? "no safe state" : "no safe output");
  m.how += std::string(" (timed out: ") + what + " in " +
           core::to_string(r.cell->out().state) + "/" + core::to_string(r.cell->out().sub) + ", setup " +
           (r.ok ? "ok" : "failed") + ")";
}

bool power_removed(const sim::Cell& c) { return !c.out().contactor && !c.out().drives_enable; }
bool stopping(const sim::Cell& c) { return c.out().state == State::STOPPING || power_removed(c); }

core::SafetyLimits with_fields(const core::SafetyLimits& in) {
  core::SafetyLimits l = in;
  if (!l.collaborative.enabled) {
    l.collaborative.enabled = true;
    l.collaborative.reduced_speed_mm_s = l.reduced_tcp_max_speed_mm_s;
  }
  return l;
}

bool cat0_safe(const sim::Cell& c) {
  if (c.view().contactor_closed) return false;
  for (const float v : c.view().velocities_rad_s) {
    if (!(std::fabs(v) < c.config().standstill_rad_s)) return false;
  }
  return true;
}

// ---- The limits of SPEC §10, T1 speed and SSM --------------------------------------------
//
// In normal use the planner keeps the arm inside every limit less its margin (SPEC §10), so
// these functions act when something below the planner fails: here a drive, with the
// faults of the scenario format. Which monitor sees such a drive first is a matter of
// numbers: the following-error monitor (motion::MotionConfig::following_error_rad, 0.05
// rad, DRIVE_FAULT) sees a drive `runaway` from rest (accelerating at qdd_max, 1000 deg/s^2
// on axis 1) after 76 ms, by when axis 1 turns at 76 deg/s and has moved 2.9 deg; a limit
// closer than that trips first. So each function is measured with the arm at rest at its
// home pose, powered and held (its following error watched), and a bench configuration:
// the loaded one with the limit under test moved beside that pose, kBeside planning
// margins away (motion/limits.hpp: where the planner may still hold the arm), or the speed
// limit under test set below what the runaway reaches inside the following-error window.
// The motion layer and the monitors read that same configuration (sim::Cell::
// configure_limits): nothing is set for one and not the other. T1 speed needs no bench
// configuration (250 mm/s is reached within the window), SSM none either (a drive
// `nostop` that keeps turning while the person is close; see measure_ssm()).
// The count starts when the measured quantity crosses its limit (count()'s `crossed`),
// judged here as the monitor judges it, with the core's own kinematics.
constexpr float kBeside = 1.2F;                          // planning margins from the pose
constexpr float kBenchJointSpeedRadS = motion::deg(60.0F);  // axis 1, reached after 1.8 deg
constexpr float kBenchTcpSpeedMmS = 300.0F;              // axis 1 at <= 0.82 rad/s at home

core::JointArray positions(const sim::Cell& c) { return c.view().joints_rad; }

core::ArmPose pose_at(const core::JointArray& q, const core::SafetyLimits& l) {
  static const core::PreparedArm arm = core::prepare_arm(controller::Controller::arm_geometry(safestate::robot::active().model));
  core::ArmPose p{};
  core::arm_forward(arm, q, l.tcp_mm, p);
  return p;
}

core::JointArray home() {
  const motion::Joints h = sim::home_pose();
  core::JointArray q{};
  std::copy(h.begin(), h.end(), q.begin());
  return q;
}

float core_tcp_speed(const sim::Cell& c, const core::SafetyLimits& l) {
  const core::ArmPose p = pose_at(positions(c), l);
  return core::point_speed(p, p.tcp, core::kAxes, c.view().velocities_rad_s);
}

// Euclidean distance from p to the box (0 inside or on it).
float distance_to(const core::Zone& z, const core::Vec3& p) {
  float d2 = 0.0F;
  for (std::size_t k = 0; k < 3U; ++k) {
    const float gap = std::max({z.min_mm[k] - p[k], p[k] - z.max_mm[k], 0.0F});
    d2 += gap * gap;
  }
  return std::sqrt(d2);
}

// Axis 1 (or 5) of a drive that runs away from rest, measured as above.
struct Runaway {
  const char* id;
  std::string how;
  core::Mode mode;
  std::uint8_t axis;
  core::SafetyLimits limits;
  Pred crossed;
};

Measured runaway_from_rest(const core::Config& cfg, const Runaway& w) {
  Measured m{w.id, false, w.how, "", 0, 0};
  Run r(cfg, w.limits);
  r.arm(w.mode);
  r.cycles(50);  // settled: held at the home pose
  r.cell->inject({sim::FaultKind::drive_runaway, w.axis, 0});
  count(r, m, power_removed, cat0_safe, nullptr, w.crossed);
  return m;
}

// A figure of the bench configuration for `how`, e.g. "1.2".
std::string fig(float v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", static_cast<double>(v));
  return b;
}
constexpr float kDegPerRad = 180.0F / motion::kPi;

std::vector<Measured> limits_by_runaway(const core::Config& cfg, const core::SafetyLimits& in) {
  std::vector<Measured> res;
  const auto add = [&cfg, &res](const char* id, const std::string& how, core::Mode mode, std::uint8_t axis,
                                const core::SafetyLimits& l, const Pred& crossed) {
    res.push_back(runaway_from_rest(cfg, Runaway{id, how, mode, axis, l, crossed}));
  };
  const std::string held = "AUTO, held at home, ";
  const core::ArmPose at_home = pose_at(home(), in);
  {
    const float t1 = cfg.t1_speed_limit_mm_s;
    add("t1_speed",
        "T1, held at home: drive 1 runs away from rest; counted from the cycle a measured point is over " + fig(t1) +
            " mm/s",
        core::Mode::T1, 1, in, [t1](const sim::Cell& c) { return c.view().max_point_speed_mm_s > t1; });
  }
  {
    core::SafetyLimits l = in;
    l.joints[0].max_rad = std::min(l.joints[0].max_rad, home()[0] + (kBeside * motion::kJointMarginRad));
    const float max = l.joints[0].max_rad;
    add("joint_range",
        held + "axis 1's max " + fig((max - home()[0]) * kDegPerRad) +
            " deg beside it: drive 1 runs away from rest; counted from the cycle its measured position is past the max",
        core::Mode::AUTO, 1, l, [max](const sim::Cell& c) { return c.view().joints_rad[0] > max; });
  }
  {
    core::SafetyLimits l = in;
    l.joints[0].max_speed_rad_s = std::min(l.joints[0].max_speed_rad_s, kBenchJointSpeedRadS);
    const float max = l.joints[0].max_speed_rad_s;
    add("joint_speed",
        held + "axis 1's max speed " + fig(max * kDegPerRad) +
            " deg/s: drive 1 runs away from rest; counted from the cycle its measured speed is over it",
        core::Mode::AUTO, 1, l, [max](const sim::Cell& c) { return std::fabs(c.view().velocities_rad_s[0]) > max; });
  }
  {
    core::SafetyLimits l = in;
    l.tcp_max_speed_mm_s = std::min(l.tcp_max_speed_mm_s, kBenchTcpSpeedMmS);
    l.reduced_tcp_max_speed_mm_s = std::min(l.reduced_tcp_max_speed_mm_s, l.tcp_max_speed_mm_s);
    add("tcp_speed",
        held + "TCP max speed " + fig(l.tcp_max_speed_mm_s) +
            " mm/s: drive 1 runs away from rest; counted from the cycle the TCP speed (the core's kinematics, measured "
            "velocities) is over it",
        core::Mode::AUTO, 1, l, [l](const sim::Cell& c) { return core_tcp_speed(c, l) > l.tcp_max_speed_mm_s; });
  }
  {
    // A keep_out box on the side axis 1 turns the TCP towards (+y at home), its face
    // kBeside zone margins from the tool sphere.
    core::SafetyLimits l = in;
    core::Zone z{};
    const char name[] = "rta-bench";
    std::copy(std::begin(name), std::end(name), z.name.begin());
    z.kind = core::ZoneKind::keep_out;
    const core::Vec3& p = at_home.tcp;
    const float gap = kBeside * motion::kZoneMarginMm;
    const float face = p[1] + l.tool_radius_mm + gap;
    z.min_mm = {p[0] - 100.0F, face, p[2] - 100.0F};
    z.max_mm = {p[0] + 100.0F, face + 100.0F, p[2] + 100.0F};
    if (l.zone_count < core::kMaxZones) l.zones[l.zone_count++] = z;
    add("zones",
        held + "a keep_out box " + fig(gap) +
            " mm beside the tool sphere: drive 1 runs away from rest toward it; counted from the cycle the sphere "
            "touches it",
        core::Mode::AUTO, 1, l, [l, z](const sim::Cell& c) {
          const float d = distance_to(z, pose_at(positions(c), l).tcp);
          return d < l.tool_radius_mm || !(d > 0.0F);
        });
  }
  {
    // The cone about the tool's z axis at home, kBeside orientation margins wide: axis 5
    // tilts the tool axis by its own angle.
    core::SafetyLimits l = in;
    l.orientation_enabled = true;
    l.orientation_axis = at_home.tool_z;
    l.orientation_max_deviation_rad = kBeside * motion::kOrientationMarginRad;
    const float cos_max = std::cos(l.orientation_max_deviation_rad);
    add("orientation",
        held + "the tool axis allowed " + fig(l.orientation_max_deviation_rad * kDegPerRad) +
            " deg about its pose: drive 5 runs away from rest; counted from the cycle the tool axis is outside the "
            "cone",
        core::Mode::AUTO, 5, l, [l, cos_max](const sim::Cell& c) {
          const core::Vec3 t = pose_at(positions(c), l).tool_z;
          const core::Vec3& a = l.orientation_axis;
          return ((a[0] * t[0]) + (a[1] * t[1]) + (a[2] * t[2])) < cos_max;
        });
  }
  return res;
}

// SPEC §11 SSM. The motion layer keeps the TCP at v_allowed, and the simulated drives follow
// its set-points at once, so a person who steps close (the separation falling in one cycle)
// never makes a healthy arm violate SSM: its own reaction is what the person needs. The
// function is there for a drive that does not slow down when told to: `nostop` (it keeps
// its velocity when the set-points decelerate). Axis 1 turns slowly (a bench program from
// home, at a speed whose following error over T_r is half the window: 0.2 rad/s at most,
// 0.025 rad in 100 ms), the person steps in to C + Z, where v_allowed is 0 and the program
// holds; the drive keeps turning. Counted from the first cycle the TCP speed (the core's
// kinematics) is over v_allowed + 5 %: the monitor's T_r runs from there.
Measured measure_ssm(const core::Config& cfg, const core::SafetyLimits& in) {
  const core::SsmParams& p = in.collaborative.ssm;
  if (!(p.decel_mm_s2 > 0.0F && p.reaction_s > 0.0F)) {
    return Measured{"ssm", false,
                    "not measured: the configuration sets no SSM (collaborative.ssm: without a and T_r v_allowed is 0 "
                    "everywhere, there is no speed to keep); measured with a configuration that sets it "
                    "(examples/safety/collaborative.json)",
                    "", 0, 0};
  }
  core::SafetyLimits l = with_fields(in);
  l.collaborative.ssm_enabled = true;
  const float speed = std::min(0.2F, 0.5F * motion::MotionConfig{}.following_error_rad / p.reaction_s);
  motion::Joints to = sim::home_pose();
  to[0] += 0.5F;
  // Outlives `r`, which holds it (sim::Cell::load_program).
  const float fraction = speed / (motion::kSpeedFactor * l.joints[0].max_speed_rad_s);
  const std::array<motion::Waypoint, 1> program{{{to, fraction, 0}}};
  Measured m{"ssm", false,
             "AUTO, SSM on, axis 1 at " + fig(speed) +
                 " rad/s (bench program), drive 1 nostop: the separation falls to C + Z (v_allowed 0); counted from "
                 "the cycle the TCP speed is over v_allowed + 5 %",
             "", 0, 0};
  Run r(cfg, l);
  r.cell->load_program(program.data(), static_cast<std::uint8_t>(program.size()));
  r.arm(core::Mode::AUTO);
  r.cmd(CommandId::start);
  r.until([speed](const sim::Cell& c) { return std::fabs(c.view().velocities_rad_s[0]) > 0.9F * speed; });
  r.cycles(50);  // at its speed
  r.cell->inject({sim::FaultKind::drive_nostop, 1, 0});
  r.cell->inputs().separation_mm = static_cast<std::int32_t>(std::lround(p.intrusion_mm + p.uncertainty_mm));
  count(r, m, power_removed, cat0_safe, nullptr, [l](const sim::Cell& c) {
    const core::SafetyStatus& st = c.out().safety;
    return st.ssm && core_tcp_speed(c, l) > core::kSsmTolerance * st.v_allowed_mm_s;
  });
  return m;
}

}  // namespace

std::vector<Measured> measure(const core::Config& cfg_in, const safety::Loaded& s) {
  core::Config cfg = cfg_in;
  cfg.max_stop_ms = s.limits.max_stop_ms;
  std::vector<Measured> res;
  const auto cat1_safe = [](const sim::Cell& c) { return c.out().state == State::IDLE && !c.view().contactor_closed; };

  {
    Measured m{"estop", false, "AUTO, demo program at speed: estop.a opens, estop.b 5 cycles later", "", 0, 0};
    Run r(cfg, s.limits);
    r.running();
    r.cell->inputs().estop_a = false;
    count(r, m, power_removed, cat0_safe, [](core::RawInputs& in) { in.estop_b = false; });
    res.push_back(m);
  }
  {
    Measured m{"guard", false, "AUTO, demo program at speed: gate.a opens, gate.b 5 cycles later", "", 0, 0};
    Run r(cfg, s.limits);
    r.running();
    r.cell->inputs().gate_a = false;
    count(r, m, stopping, cat1_safe, [](core::RawInputs& in) { in.gate_b = false; });
    res.push_back(m);
  }
  {
    Measured m{"enable", false, "T1, axis 1 jogged at 100 %: enable.a released, enable.b 5 cycles later", "", 0, 0};
    Run r(cfg, s.limits);
    r.arm(core::Mode::T1);
    r.cmd(CommandId::jog, 1, 1, 100);
    r.cycles(60);  // within jog_timeout_ms: still jogging
    r.cell->inputs().enable_a = false;
    count(r, m, stopping, cat1_safe, [](core::RawInputs& in) { in.enable_b = false; });
    res.push_back(m);
  }
  // t1_speed, joint_range, joint_speed, tcp_speed, zones, orientation, in that order.
  const std::vector<Measured> limits = limits_by_runaway(cfg, s.limits);
  res.insert(res.end(), limits.begin(), limits.begin() + 4);
  // At or below the reduced limit of the sources asking (core::reduced_limit_mm_s).
  const auto reduced_safe = [](const core::SafetyLimits& l) {
    return [l](const sim::Cell& c) {
      const core::SafetyStatus& st = c.out().safety;
      return st.reduced && c.view().tcp_speed_mm_s <= core::reduced_limit_mm_s(l, st.reduced_by);
    };
  };
  {
    Measured m{"reduced_speed", false, "AUTO, demo program at speed: reduced.a opens, reduced.b 5 cycles later", "", 0, 0};
    Run r(cfg, s.limits);
    r.running();
    r.cell->inputs().reduced_a = false;
    count(r, m, [](const sim::Cell& c) { return c.out().safety.reduced; }, reduced_safe(s.limits),
          [](core::RawInputs& in) { in.reduced_b = false; });
    res.push_back(m);
  }
  res.insert(res.end(), limits.begin() + 4, limits.end());
  {
    Measured m{"field_outer", false, "AUTO, collaborative on, demo program at speed: field.outer.a interrupted, .b 5 cycles later", "",
               0, 0};
    const core::SafetyLimits l = with_fields(s.limits);
    Run r(cfg, l);
    r.running();
    r.cell->inputs().field_outer_a = false;
    count(r, m, [](const sim::Cell& c) { return c.out().safety.reduced; }, reduced_safe(l),
          [](core::RawInputs& in) { in.field_outer_b = false; });
    res.push_back(m);
  }
  {
    Measured m{"field_inner", false, "AUTO, collaborative on, demo program at speed: field.inner.a interrupted, .b 5 cycles later", "",
               0, 0};
    Run r(cfg, with_fields(s.limits));
    r.running();
    r.cell->inputs().field_inner_a = false;
    count(
        r, m, stopping,
        [](const sim::Cell& c) { return c.out().state == State::OPERATIONAL && c.out().sub == core::Sub::AUTO_PAUSED; },
        [](core::RawInputs& in) { in.field_inner_b = false; });
    res.push_back(m);
  }
  res.push_back(measure_ssm(cfg, s.limits));
  {
    // SPEC §11 rule 8: pfl on (the hand's F_qs unless the file names a region), a contact of
    // twice F_qs against the running program; safe once paused (the back-off comes after).
    Measured m{"collision", false, "AUTO, pfl on, demo program at speed: a contact of 2 x F_qs against the TCP", "", 0, 0};
    core::SafetyLimits l = with_fields(s.limits);
    if (!l.collaborative.pfl_enabled) {
      l.collaborative.pfl_enabled = true;
      l.collaborative.f_qs_n = core::body_region(core::BodyRegion::hand).f_qs_n;
    }
    Run r(cfg, l);
    r.running();
    const auto tenths = static_cast<std::uint16_t>(std::lround(l.collaborative.f_qs_n * 20.0F));
    r.cell->inject({sim::FaultKind::contact, 0, tenths});
    count(
        r, m, stopping,
        [](const sim::Cell& c) { return c.out().state == State::OPERATIONAL && c.out().sub == core::Sub::AUTO_PAUSED; });
    res.push_back(m);
  }
  {
    Measured m{"bus_loss", false, "AUTO, demo program at speed: fieldbus lost", "", 0, 0};
    Run r(cfg, s.limits);
    r.running();
    r.cell->inject({sim::FaultKind::fieldbus_lost, 0, 0});
    count(r, m, power_removed, cat0_safe);
    res.push_back(m);
  }
  return res;
}

std::string measured_json(const std::vector<Measured>& ms, std::uint32_t cycle_us) {
  nlohmann::ordered_json j;
  j["cycle_us"] = cycle_us;
  j["functions"] = nlohmann::ordered_json::array();
  for (const Measured& m : ms) {
    j["functions"].push_back({{"id", m.id},
                              {"measured", m.measured},
                              {"how", m.how},
                              {"alarm", m.alarm},
                              {"reaction_cycles", m.reaction_cycles},
                              {"safe_cycles", m.safe_cycles}});
  }
  return j.dump(1) + "\n";
}

}  // namespace safestate::rta

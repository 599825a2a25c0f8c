// @req STOP-DATA
// SPEC §13, ISO 10218-1 Annex B: stopping time and distance of axes 1, 2 and 3 for Cat 0
// (E-stop) and Cat 1 (guard in AUTO) at 33/66/100 % of the axis speed and 33/66/100 % of
// the rated payload, on the SIMULATED cell (sim::Cell: the real controller, the simulated
// plant). One JSON object on stdout for bench/stopping.py.
// Arguments (all optional): --robot FILE.urdf [--base LINK] [--flange LINK] runs another arm
// (issue 38; the built-in IRB 120 without); --rated-payload-kg KG names its rated payload (the
// runs' payloads are fractions of it: only the label); --short runs 100 % speed and payload
// only (6 runs, for a test).
//
// Each run: the arm at home, a one-waypoint program moving only the axis under test at the
// speed fraction; once the axis runs at that speed the payload's inertia is applied (the
// planner of the simulated cell does not know the payload, so the run-up is the unloaded
// arm's; the stop, which is what Annex B measures, sees the payload) and both channels of
// the stop input open together. Counted in cycles from that change until every axis is
// below standstill_rad_s: up to one cycle more than the plant took (conservative).
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <string>
#include <vector>

#include "safestate/robot/description.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/safety/safety_config.hpp"
#include "safestate/sim/cell.hpp"
#include "safestate/sim/plant.hpp"

using namespace safestate;

namespace {

constexpr int kLimit = 20000;
constexpr std::array<float, 3> kFractions = {0.33F, 0.66F, 1.0F};
// Where the axis under test is sent (deg): far enough to reach full speed (0.25 s of
// acceleration, docs/robot.md) and inside the working range less the planner's margin.
constexpr std::array<float, 3> kTargetDeg = {150.0F, 95.0F, -100.0F};

struct Result {
  int axis = 0;
  int cat = 0;
  float speed = 0.0F;
  float payload = 0.0F;
  bool ok = false;
  std::string why;
  float v0_deg_s = 0.0F;
  float tcp0_mm_s = 0.0F;
  std::uint64_t reaction_cycles = 0;  // until the axis' speed first falls
  std::uint64_t stop_cycles = 0;
  float distance_deg = 0.0F;
  float tcp_distance_mm = 0.0F;
  std::vector<float> trace_deg_s;  // the axis' speed every cycle from the change
};

int step_until(sim::Cell& c, bool (*p)(const sim::Cell&)) {
  for (int k = 1; k <= kLimit; ++k) {
    c.step();
    if (p(c)) return k;
  }
  return -1;
}

bool command(sim::Cell& c, core::CommandId id, std::uint32_t seq) {
  core::Command cmd{};
  cmd.seq = seq;
  cmd.id = static_cast<std::uint8_t>(id);
  if (c.submit(cmd) != core::Result::OK) return false;
  c.step();
  for (std::size_t i = 0; i < c.out().reply_count; ++i) {
    if (c.out().replies[i].seq == seq) return c.out().replies[i].result == core::Result::OK;
  }
  return false;
}

Result run(const safety::Loaded& s, int axis, int cat, float speed, float payload) {
  Result r;
  r.axis = axis;
  r.cat = cat;
  r.speed = speed;
  r.payload = payload;
  const auto i = static_cast<std::size_t>(axis - 1);
  core::Config cfg{};
  cfg.max_stop_ms = s.limits.max_stop_ms;
  sim::Cell cell(cfg);
  cell.configure_limits(s.limits, true);
  motion::Waypoint wp{};
  wp.q = sim::home_pose();
  // Inside another arm's range as well, 10 deg from its limits.
  const motion::RobotModel& m = safestate::robot::active().model;
  wp.q[i] = std::clamp(motion::deg(kTargetDeg[i]), m.q_min_rad[i] + motion::deg(10.0F), m.q_max_rad[i] - motion::deg(10.0F));
  wp.speed = speed;
  cell.load_program(&wp, 1);
  std::uint32_t seq = 0;
  if (step_until(cell, [](const sim::Cell& c) { return c.out().state == core::State::ESTOP_RESET_NEEDED; }) < 0 ||
      !command(cell, core::CommandId::reset, ++seq) || !command(cell, core::CommandId::servo_on, ++seq) ||
      step_until(cell, [](const sim::Cell& c) { return c.out().state == core::State::OPERATIONAL; }) < 0 ||
      !command(cell, core::CommandId::start, ++seq)) {
    r.why = "could not start the program";
    return r;
  }
  const float v_target = speed * safestate::robot::active().model.qd_max_rad_s[i];
  // At speed: the planner's plateau (it plans below the limits by their margin, SPEC §10),
  // the axis' speed steady for kSteadyCycles.
  constexpr int kSteadyCycles = 5;
  int k = 0;
  int steady = 0;
  float v_prev = 0.0F;
  for (; k < kLimit; ++k) {
    cell.step();
    const float v = std::fabs(cell.view().velocities_rad_s[i]);
    steady = (v > 0.5F * v_target && std::fabs(v - v_prev) < 1.0e-4F) ? steady + 1 : 0;
    v_prev = v;
    if (steady >= kSteadyCycles) break;
  }
  if (k == kLimit) {
    r.why = "the axis never reached its speed";
    return r;
  }
  cell.step();  // one more cycle at speed: the velocity of the cycle the stop begins from
  const float q0 = cell.view().joints_rad[i];
  r.v0_deg_s = std::fabs(cell.view().velocities_rad_s[i]) * 180.0F / motion::kPi;
  r.tcp0_mm_s = cell.view().tcp_speed_mm_s;
  std::array<float, 3> p_prev{cell.view().tcp[0], cell.view().tcp[1], cell.view().tcp[2]};
  cell.set_payload_fraction(payload);
  core::RawInputs& in = cell.inputs();
  if (cat == 0) {
    in.estop_a = in.estop_b = false;
  } else {
    in.gate_a = in.gate_b = false;
  }
  const float v_start = std::fabs(cell.view().velocities_rad_s[i]);
  for (std::uint64_t n = 1; n <= static_cast<std::uint64_t>(kLimit); ++n) {
    cell.step();
    const sim::CellView& v = cell.view();
    const float vi = std::fabs(v.velocities_rad_s[i]);
    r.trace_deg_s.push_back(vi * 180.0F / motion::kPi);
    if (r.reaction_cycles == 0U && vi < v_start - 1.0e-4F) r.reaction_cycles = n;
    r.tcp_distance_mm += std::hypot(v.tcp[0] - p_prev[0], v.tcp[1] - p_prev[1], v.tcp[2] - p_prev[2]);
    p_prev = {v.tcp[0], v.tcp[1], v.tcp[2]};
    bool still = true;
    for (const float w : v.velocities_rad_s) still = still && std::fabs(w) < cfg.standstill_rad_s;
    if (still) {
      r.stop_cycles = n;
      r.distance_deg = std::fabs(v.joints_rad[i] - q0) * 180.0F / motion::kPi;
      r.ok = true;
      return r;
    }
  }
  r.why = "no standstill";
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  std::string file;
  std::string base;
  std::string flange;
  double rated = static_cast<double>(motion::kRatedPayloadKg);
  bool rated_given = false;
  bool short_mode = false;
  for (int a = 1; a < argc; ++a) {
    const std::string k = argv[a];
    const bool has_value = a + 1 < argc;
    if (k == "--short") {
      short_mode = true;
    } else if (k == "--robot" && has_value) {
      file = argv[++a];
    } else if (k == "--base" && has_value) {
      base = argv[++a];
    } else if (k == "--flange" && has_value) {
      flange = argv[++a];
    } else if (k == "--rated-payload-kg" && has_value) {
      char* end = nullptr;
      rated = std::strtod(argv[++a], &end);
      rated_given = true;
      if (end == nullptr || *end != '\0' || !(rated > 0.0 && rated <= 2000.0)) {
        std::fprintf(stderr, "bench_stopping: --rated-payload-kg must be a number in (0, 2000]\n");
        return 2;
      }
    } else {
      std::fprintf(stderr, "bench_stopping: unknown or incomplete argument %s\n"
                           "usage: bench_stopping [--robot FILE.urdf [--base LINK] [--flange LINK]] "
                           "[--rated-payload-kg KG] [--short]\n", k.c_str());
      return 2;
    }
  }
  if (!file.empty() || !base.empty() || !flange.empty()) {
    std::string error;
    if (!safestate::robot::select(file, base, flange, error)) {
      std::fprintf(stderr, "bench_stopping: %s\n", error.c_str());
      return 2;
    }
  }
  const bool builtin = safestate::robot::is_builtin(safestate::robot::active());
  const safety::Loaded s = safety::default_safety();
  const std::uint32_t cycle_us = core::Config{}.cycle_us;
  std::string name = safestate::robot::active().d.name;  // for the JSON: no quote or control character
  for (char& ch : name) {
    if (ch == '"' || ch == '\\' || static_cast<unsigned char>(ch) < 0x20U) ch = '_';
  }
  const std::string rated_text = (builtin || rated_given) ? std::to_string(rated) : std::string("null");
  std::printf("{\"robot\": \"%s\", \"builtin\": %s, \"short\": %s, \"cycle_us\": %u, \"payload_rated_kg\": %s, "
              "\"payload_inertia_ratio\": %.3f, \"brake_decel_factor\": %.3f, \"max_stop_ms\": %u, \"runs\": [\n",
              name.c_str(), builtin ? "true" : "false", short_mode ? "true" : "false",
              cycle_us, rated_text.c_str(), static_cast<double>(sim::kPayloadInertiaRatio),
              static_cast<double>(sim::kBrakeStopDecelFactor), s.limits.max_stop_ms);
  const std::vector<float> fractions = short_mode ? std::vector<float>{1.0F} : std::vector<float>(kFractions.begin(), kFractions.end());
  bool first = true;
  for (int axis = 1; axis <= 3; ++axis) {
    for (int cat = 0; cat <= 1; ++cat) {
      for (const float sp : fractions) {
        for (const float pl : fractions) {
          const Result r = run(s, axis, cat, sp, pl);
          std::printf("%s {\"axis\": %d, \"cat\": %d, \"speed\": %.2f, \"payload\": %.2f, \"ok\": %s, \"why\": \"%s\", "
                      "\"v0_deg_s\": %.3f, \"tcp0_mm_s\": %.1f, \"reaction_cycles\": %llu, \"stop_cycles\": %llu, "
                      "\"distance_deg\": %.3f, \"tcp_distance_mm\": %.1f, \"trace_deg_s\": [",
                      first ? "" : ",", r.axis, r.cat, static_cast<double>(r.speed), static_cast<double>(r.payload),
                      r.ok ? "true" : "false", r.why.c_str(), static_cast<double>(r.v0_deg_s),
                      static_cast<double>(r.tcp0_mm_s), static_cast<unsigned long long>(r.reaction_cycles),
                      static_cast<unsigned long long>(r.stop_cycles), static_cast<double>(r.distance_deg),
                      static_cast<double>(r.tcp_distance_mm));
          for (std::size_t n = 0; n < r.trace_deg_s.size(); ++n) {
            std::printf("%s%.2f", n == 0U ? "" : ",", static_cast<double>(r.trace_deg_s[n]));
          }
          std::printf("]}\n");
          first = false;
        }
      }
    }
  }
  std::printf("]}\n");
  return 0;
}

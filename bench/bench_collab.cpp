// SPEC §11, issue 20 item 6: speed and separation monitoring against protective fields only,
// on the SIMULATED cell (sim::Cell: the real controller, the simulated plant, the simulated
// person with its scanner and distance sensor). One JSON object on stdout for
// bench/collaborative.py.
//
//   bench_collab SSM.json FIELDS.json [--smoke]
//
// SSM.json: a collaborative configuration with SSM on (the person's distance sensor feeds
// it; the simulated scanner is switched off, so only SSM guards the person). FIELDS.json:
// the same with SSM off (the scanner's outer field = reduced mode, inner field = rule 9,
// automatic resume). Each run: the arm at home, the AUTO demo program started and started
// again each time it ends (`start` in AUTO_IDLE), kRounds rounds; the person stands
// kFarMm from the base axis in one of 20 directions, walks in at 1600 or 2000 mm/s to
// kStandMm from the axis kWalkInMs after the first start, stands kStandMs, walks back out
// at the same speed and stays there. A baseline per configuration: the person stays out.
// Counted per cycle: (separation - S_p(v_tcp)) while the TCP moves, stops, collisions.
// --smoke: one direction, one speed, one round (the ctest smoke test).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "safestate/core/collaborative.hpp"
#include "safestate/safety/safety_config.hpp"
#include "safestate/sim/cell.hpp"

using namespace safestate;

namespace {

constexpr float kFarMm = 4000.0F;     // where the person comes from and goes back to
constexpr float kStandMm = 1000.0F;   // body centre from the base axis while standing
constexpr std::uint32_t kStandMs = 3000;
constexpr int kWalkInMs = 1000;       // after the first start
// The first start: after the core's separation has risen to the far person's (it rises at
// most 3.5 mm a cycle from 0, docs/collaborative.md), so that every round of the baseline
// runs unhindered.
constexpr int kFirstStart = 2000;
constexpr int kDirections = 20;
constexpr int kRounds = 3;
constexpr float kMovingMmS = 1.0F;    // the TCP "moves" above this (the standstill of the margin)
constexpr int kLimitCycles = 200000;  // a run that takes longer has failed
constexpr int kTraceEvery = 10;       // cycles between the plotted samples

struct Run {
  std::string mode;  // "ssm" or "fields"
  int direction_deg = -1;  // -1: baseline (the person stays out)
  float speed = 0.0F;
  bool ok = false;
  std::string why;
  int rounds = 0;
  double round_ms = 0.0;  // mean time per program round, first start to the last round's end
  double min_margin_mm = 1e9;  // min (separation - S_p(v_tcp)) while the TCP moves
  double margin_at_sep = 0.0;  // the separation and TCP speed where that minimum was
  double margin_at_v = 0.0;
  double min_sep_moving_mm = 1e9;  // the smallest separation while the TCP moves
  double min_sep_mm = 1e9;         // the smallest separation at all
  int negative_cycles = 0;         // cycles with a negative margin while the TCP moves
  int negative_near = 0;           // of them with the separation within kSsmNearMm (v_h 2000)
  double min_margin_far_mm = 1e9;  // the lowest margin with the separation above kSsmNearMm
  int stops = 0;                   // entries into STOPPING
  int rule9 = 0;                   // of them with PERSON_IN_FIELD (the inner field)
  int separation_violated = 0;
  int collisions = 0;
  double max_tcp_mm_s = 0.0;
  std::vector<float> trace;  // t_s, separation, v_allowed (-1: SSM not acting), tcp speed
};

bool command(sim::Cell& c, core::CommandId id, std::uint32_t& seq) {
  core::Command cmd{};
  cmd.seq = ++seq;
  cmd.id = static_cast<std::uint8_t>(id);
  return c.submit(cmd) == core::Result::OK;
}

bool alarm(const sim::Cell& c, core::AlarmId a) { return (c.out().alarms & core::bit(a)) != 0U; }

Run run(const safety::Loaded& s, const std::string& mode, int direction_deg, float speed, int rounds, bool trace) {
  Run r;
  r.mode = mode;
  r.direction_deg = direction_deg;
  r.speed = speed;
  core::Config cfg{};
  cfg.max_stop_ms = s.limits.max_stop_ms;
  sim::Cell cell(cfg);
  cell.configure_limits(s.limits, true);
  sim::PersonSensors sensors{};
  sensors.scanner = (mode == "fields");  // SSM runs: the distance sensor alone guards
  if (!cell.configure_person_sensors(sensors)) {
    r.why = "sensors refused";
    return r;
  }
  const double th = (direction_deg < 0 ? 0.0 : direction_deg) * M_PI / 180.0;
  const auto cx = static_cast<float>(std::cos(th));
  const auto cy = static_cast<float>(std::sin(th));
  if (!cell.add_person(kFarMm * cx, kFarMm * cy)) {
    r.why = "person refused";
    return r;
  }
  const core::SsmParams& p = s.limits.collaborative.ssm;
  const float dt_s = static_cast<float>(cfg.cycle_us) * 1.0e-6F;
  std::uint32_t seq = 0;
  int t = 0;
  int started_at = -1;
  int done = 0;
  int start_sent_at = -1;  // a start not yet seen running (sent again after 50 cycles)
  bool reset_sent = false;
  bool servo_sent = false;
  bool was_stopping = false;
  bool was_violated = false;
  bool was_collision = false;
  bool walked = false;
  bool was_running = false;
  for (; t < kLimitCycles && done < rounds; ++t) {
    const core::SupervisorOut& o = cell.out();
    if (!reset_sent && o.state == core::State::ESTOP_RESET_NEEDED) {
      reset_sent = command(cell, core::CommandId::reset, seq);
    } else if (!servo_sent && o.state == core::State::IDLE) {
      servo_sent = command(cell, core::CommandId::servo_on, seq);
    } else if (o.state == core::State::OPERATIONAL && o.sub == core::Sub::AUTO_IDLE && t >= kFirstStart &&
               (start_sent_at < 0 || t - start_sent_at > 50)) {
      start_sent_at = command(cell, core::CommandId::start, seq) ? t : -1;
    }
    if (started_at >= 0 && !walked && direction_deg >= 0 && t >= started_at + kWalkInMs) {
      const std::array<sim::PersonWaypoint, 2> path{{{kStandMm * cx, kStandMm * cy, speed, kStandMs},
                                                     {kFarMm * cx, kFarMm * cy, speed, 0}}};
      walked = cell.set_person_path(path.data(), path.size());
      if (!walked) {
        r.why = "path refused";
        return r;
      }
    }
    cell.step();
    const core::SupervisorOut& out = cell.out();
    if (out.sub == core::Sub::AUTO_RUNNING) {
      if (started_at < 0) started_at = t;
      if (start_sent_at >= 0) start_sent_at = -1;
    } else if (started_at >= 0 && out.sub == core::Sub::AUTO_IDLE && start_sent_at < 0 && was_running) {
      ++done;  // the program has ended a round (AUTO_IDLE after running)
    }
    was_running = out.sub == core::Sub::AUTO_RUNNING || out.sub == core::Sub::AUTO_PAUSED;
    if (out.state == core::State::IDLE && servo_sent && started_at >= 0) {
      r.why = "the robot lost power (a Cat 0 or Cat 1 stop)";
      break;
    }
    const bool stopping = out.state == core::State::STOPPING;
    if (stopping && !was_stopping) {
      ++r.stops;
      if (alarm(cell, core::AlarmId::PERSON_IN_FIELD)) ++r.rule9;
    }
    was_stopping = stopping;
    const bool v = alarm(cell, core::AlarmId::SEPARATION_VIOLATED);
    if (v && !was_violated) ++r.separation_violated;
    was_violated = v;
    const bool c = alarm(cell, core::AlarmId::COLLISION);
    if (c && !was_collision) ++r.collisions;
    was_collision = c;
    // The margin: the distance sensor's separation against S_p at the measured TCP speed.
    const sim::PersonView& pv = cell.view().person;
    const float vt = cell.view().tcp_speed_mm_s;
    const auto sep = static_cast<double>(pv.separation_mm);
    r.min_sep_mm = std::min(r.min_sep_mm, sep);
    r.max_tcp_mm_s = std::max(r.max_tcp_mm_s, static_cast<double>(vt));
    if (started_at >= 0 && vt > kMovingMmS) {
      const double m = sep - static_cast<double>(core::ssm_protective_distance_mm(vt, pv.separation_mm, p));
      if (m < r.min_margin_mm) {
        r.min_margin_mm = m;
        r.margin_at_sep = sep;
        r.margin_at_v = static_cast<double>(vt);
      }
      r.negative_cycles += (m < 0.0) ? 1 : 0;
      const bool near = pv.separation_mm <= core::kSsmNearMm;
      r.negative_near += (m < 0.0 && near) ? 1 : 0;
      if (!near) r.min_margin_far_mm = std::min(r.min_margin_far_mm, m);
      r.min_sep_moving_mm = std::min(r.min_sep_moving_mm, sep);
    }
    if (trace && started_at >= 0 && (t - started_at) % kTraceEvery == 0) {
      r.trace.push_back(static_cast<float>(t - started_at) * dt_s);
      r.trace.push_back(pv.separation_mm);
      r.trace.push_back(out.safety.ssm ? out.safety.v_allowed_mm_s : -1.0F);
      r.trace.push_back(vt);
    }
  }
  r.rounds = done;
  if (done < rounds) {
    if (r.why.empty()) r.why = "the program did not finish its rounds";
    return r;
  }
  r.round_ms = static_cast<double>(t - started_at) * static_cast<double>(dt_s) * 1000.0 / rounds;
  r.ok = r.why.empty();
  return r;
}

void print(const Run& r, bool first) {
  std::printf("%s {\"mode\": \"%s\", \"direction_deg\": %d, \"speed_mm_s\": %.0f, \"ok\": %s, \"why\": \"%s\", "
              "\"rounds\": %d, \"round_ms\": %.1f, \"min_margin_mm\": %.1f, \"margin_at_sep_mm\": %.1f, "
              "\"margin_at_v_mm_s\": %.1f, \"min_sep_moving_mm\": %.1f, \"min_sep_mm\": %.1f, "
              "\"negative_cycles\": %d, \"negative_near\": %d, \"min_margin_far_mm\": %.1f, "
              "\"stops\": %d, \"rule9\": %d, \"separation_violated\": %d, \"collisions\": %d, \"max_tcp_mm_s\": %.1f",
              first ? "" : ",", r.mode.c_str(), r.direction_deg, static_cast<double>(r.speed), r.ok ? "true" : "false",
              r.why.c_str(), r.rounds, r.round_ms, r.min_margin_mm, r.margin_at_sep, r.margin_at_v,
              r.min_sep_moving_mm, r.min_sep_mm, r.negative_cycles, r.negative_near, r.min_margin_far_mm, r.stops, r.rule9,
              r.separation_violated,
              r.collisions, r.max_tcp_mm_s);
  if (!r.trace.empty()) {
    std::printf(", \"trace\": [");
    for (std::size_t i = 0; i < r.trace.size(); ++i) {
      std::printf("%s%.3f", i == 0U ? "" : ",", static_cast<double>(r.trace[i]));
    }
    std::printf("]");
  }
  std::printf("}\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3 || argc > 4 || (argc == 4 && std::strcmp(argv[3], "--smoke") != 0)) {
    std::fprintf(stderr, "usage: bench_collab SSM.json FIELDS.json [--smoke]\n");
    return 2;
  }
  const bool smoke = argc == 4;
  const safety::Result ssm = safety::load_safety_file(argv[1]);
  const safety::Result fields = safety::load_safety_file(argv[2]);
  if (!ssm.ok() || !fields.ok() || !ssm.config->limits.collaborative.ssm_enabled ||
      fields.config->limits.collaborative.ssm_enabled || !fields.config->limits.collaborative.enabled) {
    std::fprintf(stderr, "bench_collab: %s must be collaborative with SSM on, %s collaborative with SSM off\n", argv[1],
                 argv[2]);
    return 2;
  }
  const core::SsmParams& p = ssm.config->limits.collaborative.ssm;
  std::printf("{\"cycle_us\": %u, \"far_mm\": %.0f, \"stand_mm\": %.0f, \"stand_ms\": %u, \"walk_in_ms\": %d, "
              "\"rounds\": %d, \"radius_mm\": %.0f, \"outer_mm\": %.0f, \"inner_mm\": %.0f, \"moving_mm_s\": %.1f, "
              "\"ssm\": {\"human_speed_mm_s\": %.0f, \"decel_mm_s2\": %.0f, \"reaction_s\": %.3f, \"intrusion_mm\": %.0f, "
              "\"uncertainty_mm\": %.0f}, \"ssm_config\": \"%s\", \"fields_config\": \"%s\", \"smoke\": %s, \"runs\": [\n",
              core::Config{}.cycle_us, static_cast<double>(kFarMm), static_cast<double>(kStandMm), kStandMs, kWalkInMs,
              smoke ? 1 : kRounds, static_cast<double>(sim::kPersonDefaultRadiusMm),
              static_cast<double>(sim::PersonSensors{}.outer_mm), static_cast<double>(sim::PersonSensors{}.inner_mm),
              static_cast<double>(kMovingMmS), static_cast<double>(p.human_speed_mm_s), static_cast<double>(p.decel_mm_s2),
              static_cast<double>(p.reaction_s), static_cast<double>(p.intrusion_mm), static_cast<double>(p.uncertainty_mm),
              ssm.config->checksum.c_str(), fields.config->checksum.c_str(), smoke ? "true" : "false");
  const int rounds = smoke ? 1 : kRounds;
  bool first = true;
  for (const char* mode : {"ssm", "fields"}) {
    const safety::Loaded& s = (std::strcmp(mode, "ssm") == 0) ? *ssm.config : *fields.config;
    print(run(s, mode, -1, 0.0F, rounds, false), first);
    first = false;
    for (const float v : {1600.0F, 2000.0F}) {
      for (int d = 0; d < (smoke ? 1 : kDirections); ++d) {
        const int deg = d * 360 / kDirections;
        const bool trace = !smoke && v == 1600.0F && deg == 0;
        print(run(s, mode, deg, v, rounds, trace), false);
      }
      if (smoke) break;
    }
  }
  std::printf("]}\n");
  return 0;
}

// SPEC §13: each safety function triggered on the running simulated cell, in-process,
// counted in cycles (the cell has no clock). tests/unit/test_rta_measured.cpp checks the
// counts against analyse(); bench/response_time.py puts them beside it in
// docs/response-time.md.
// @req RTA-MEASURED
#include <nlohmann/json.hpp>

#include <cmath>
#include <functional>
#include <memory>

#include "safestate/rta/rta.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/sim/cell.hpp"

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
    c.axis = static_cast<std::int8_t>(axis);
    c.dir = static_cast<std::int8_t>(dir);
    c.speed = static_cast<std::uint8_t>(speed);
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
constexpr std::uint64_t kSecondChannelCycles = 5;
using Change = std::function<void(core::RawInputs&)>;

void count(Run& r, Measured& m, const Pred& out, const Pred& safe, const Change& second = nullptr) {
  std::uint64_t k = 0;
  bool out_seen = false;
  for (int i = 1; i <= kLimit; ++i) {
    if (second && k == kSecondChannelCycles) second(r.cell->inputs());
    r.cell->step();
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
  m.how += std::string(" (timed out: ") + (out_seen ? "no safe state" : "no safe output") + " in " +
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

}  // namespace

std::vector<Measured> measure(const core::Config& cfg_in, const safety::Loaded& s) {
  core::Config cfg = cfg_in;
  cfg.max_stop_ms = s.limits.max_stop_ms;
  std::vector<Measured> res;
  const auto cat0_safe = [](const sim::Cell& c) {
    if (c.view().contactor_closed) return false;
    for (const float v : c.view().velocities_rad_s) {
      if (!(std::fabs(v) < c.config().standstill_rad_s)) return false;
    }
    return true;
  };
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
  const char* limit_why =
      "not measured in-process: the planner keeps the arm inside the limit, and a drive that pushes past it is caught "
      "first by the following-error monitor (DRIVE_FAULT, the same rule 3 Cat 0 chain)";
  for (const char* id : {"t1_speed", "joint_range", "joint_speed", "tcp_speed"}) {
    res.push_back(Measured{id, false, limit_why, "", 0, 0});
  }
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
  res.push_back(Measured{"zones", false, limit_why, "", 0, 0});
  res.push_back(Measured{"orientation", false, limit_why, "", 0, 0});
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
  res.push_back(Measured{"ssm", false,
                         "not measured in-process: the motion layer keeps the TCP at v_allowed, so SEPARATION_VIOLATED "
                         "needs a drive that ignores it, which the following-error monitor catches first",
                         "", 0, 0});
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

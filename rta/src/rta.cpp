// SPEC §13 response time analysis: the terms, from the code's own constants.
// @req RTA-TERMS
#include "safestate/robot/description.hpp"
#include "safestate/rta/rta.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "safestate/core/collision.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/backends/simulated.hpp"

namespace safestate::rta {

const char* to_string(StopKind k) noexcept {
  switch (k) {
    case StopKind::cat0: return "Cat 0";
    case StopKind::cat1: return "Cat 1";
    case StopKind::cat2: return "Cat 2";
    case StopKind::reduce: return "reduce";
  }
  return "?";
}

std::uint64_t Function::total_us() const noexcept {
  std::uint64_t t = 0;
  for (const Term& x : terms) t += x.us;
  return t;
}

const Function* Analysis::find(const std::string& id) const noexcept {
  for (const Function& f : functions) {
    if (f.id == id) return &f;
  }
  return nullptr;
}

namespace {

std::string num(std::uint64_t v) { return std::to_string(v); }

struct Builder {
  core::Config cfg;
  core::Timing t;
  const safety::Loaded& s;
  BusTiming bus;
  sim::PlantTiming plant;
  std::uint64_t c;  // cycle, us

  [[nodiscard]] std::uint64_t cycles(std::uint64_t n) const { return n * c; }
  [[nodiscard]] std::string per_cycle(std::uint64_t n, const std::string& what) const {
    return num(n) + " cycle" + (n == 1U ? "" : "s") + " x cycle_us " + num(c) + (what.empty() ? "" : " (" + what + ")");
  }

  // The arm the configuration was checked against (its `robot` key, else --robot, else the
  // built-in IRB 120): its speed and acceleration limits, its rated payload.
  [[nodiscard]] const safestate::robot::Robot& arm() const {
    return s.robot.robot ? *s.robot.robot : safestate::robot::active();
  }
  // tool.payload_kg as a fraction of the arm's rated payload (robot.rated_payload_kg, else the
  // IRB 120's 3 kg; an arm without one carries none), as the simulated plant scales braking.
  [[nodiscard]] float payload_fraction() const {
    const double rated = s.robot.rated_payload_kg;
    if (!(rated > 0.0)) return 0.0F;
    return static_cast<float>(std::min(1.0, static_cast<double>(s.limits.payload_kg) / rated));
  }

  // For an arm other than the built-in IRB 120: whose figures these are.
  [[nodiscard]] std::string other_arm() const {
    if (safestate::robot::is_builtin(arm())) return "";
    return " of rated " + std::to_string(s.robot.rated_payload_kg).substr(0, 4) + ", robot " + arm().d.name;
  }

  // Braking without torque from the drive's own speed limit (the arm cannot go faster):
  // whole cycles, as the plant ramps the velocity down once per cycle.
  [[nodiscard]] std::uint64_t cat0_stop_cycles(std::size_t& axis) const {
    std::uint64_t worst = 0;
    const float payload_scale = sim::payload_decel_scale(payload_fraction());
    const float dt = static_cast<float>(c) * 1.0e-6F;
    const motion::RobotModel& m = arm().model;
    for (std::size_t i = 0; i < motion::kJoints; ++i) {
      const float per_cycle = sim::kBrakeStopDecelFactor * m.qdd_max_rad_s2[i] * payload_scale * dt;
      const auto n = static_cast<std::uint64_t>(std::ceil((m.qd_max_rad_s[i] / per_cycle) - 1.0e-4F));
      if (n > worst) {
        worst = n;
        axis = i + 1U;
      }
    }
    return worst;
  }

  void dual_filter(Function& f, const char* input) const {
    f.terms.push_back({std::string("input filter: ") + input + " (dual channel)", 0,
                       "safe on the first channel (SPEC §2): discrepancy_ms " + num(cfg.discrepancy_ms) +
                           " does not delay"});
  }
  void no_filter(Function& f, const char* what) const {
    f.terms.push_back({std::string("input filter: none (") + what + ")", 0, "measured every cycle, unfiltered"});
  }
  void scan(Function& f) const {
    f.terms.push_back({"scan: read by the next cycle, which reacts", cycles(1),
                       per_cycle(1, "SPEC §1: 0 cycles of added delay")});
    f.reaction_cycles += 1U;
  }
  void io(Function& f) const {
    if (!bus.ethercat) {
      f.terms.push_back({"I/O: " + bus.source + " (read and written in the cycle)", 0, "hal::Backend of sim::Cell"});
      return;
    }
    f.terms.push_back({"bus exchange: the outputs leave with the next frame", cycles(1),
                       per_cycle(1, "one exchange per cycle")});
    f.terms.push_back({"bus watchdog: frames lost in a row", bus_watchdog_us(),
                       "watchdog_ms " + num(bus.watchdog_ms) + " + frame_timeout_us " + num(bus.frame_timeout_us) +
                           " of " + bus.source});
    f.reaction_cycles += 1U;
    if (bus.safety_links) {
      // docs/black-channel.md "Timing": the ping-pong. The device answers each new container of
      // the channel with its data of that moment; the channel sends its next only once the
      // answer came back: the contacts can be one exchange older than the frame that brings
      // them, and the channel's decision waits up to one exchange for the output terminal's
      // acknowledge before its container can carry it.
      f.terms.push_back({"black channel: the safe input terminal's container, one exchange older", cycles(1),
                         per_cycle(1, "ping-pong: the data of the device's last answer")});
      f.terms.push_back({"black channel: the output terminal's container waits for its acknowledge", cycles(1),
                         per_cycle(1, "ping-pong: one container in flight per connection")});
      f.reaction_cycles += 2U;
    }
  }
  [[nodiscard]] std::uint64_t bus_watchdog_us() const {
    return static_cast<std::uint64_t>(bus.watchdog_ms) * 1000U + bus.frame_timeout_us;
  }
  void cat0(Function& f, const char* prefix = "") const {
    const std::string p = prefix;
    f.terms.push_back({p + "output: contactor, STO, brakes written", 0, "SPEC §1, §3"});
    f.terms.push_back({p + "STO: the drive leaves Operation enabled", cycles(1),
                       per_cycle(1, "CiA 402: one state per cycle on the controlword")});
    f.terms.push_back({p + "contactor drop-out", cycles(plant.contactor_cycles),
                       per_cycle(plant.contactor_cycles, "sim kContactorFeedbackMs " + num(sim::kContactorFeedbackMs) +
                                                             " rounded up")});
    std::size_t axis = 0;
    const std::uint64_t n = cat0_stop_cycles(axis);
    f.terms.push_back({p + "Cat 0 stop: braked from the axis speed limit", cycles(n),
                       per_cycle(n, "axis " + num(axis) + ": qd_max / (kBrakeStopDecelFactor x qdd_max x payload scale), tool.payload_kg " +
                                       std::to_string(s.limits.payload_kg).substr(0, 4) + other_arm())});
  }
  void ramp_stop(Function& f, core::StopCat cat) const {
    const std::uint64_t ms = t.max_stop + 1U;
    f.terms.push_back({std::string(cat == core::StopCat::CAT1 ? "Cat 1" : "Cat 2") +
                           " ramp to standstill (SS1-t bound)",
                       cycles(ms), per_cycle(ms, "stop.max_time_ms " + num(cfg.max_stop_ms) + " + 1, standstill over " +
                                                     num(t.standstill_cycles) + " cycles inside it; beyond it Cat 0")});
  }
  [[nodiscard]] std::uint64_t coast_us() const {
    std::size_t axis = 0;
    return cycles(cat0_stop_cycles(axis));
  }
  void cat1_end(Function& f) const {
    const std::uint64_t brakes = cycles(t.brakes_timeout + 1U);
    const std::uint64_t coast = coast_us();
    if (brakes >= coast) {
      f.terms.push_back({"brakes engage at standstill", brakes,
                         per_cycle(t.brakes_timeout + 1U, "brakes_timeout_ms " + num(cfg.brakes_timeout_ms) +
                                                              " + 1; longer than a Cat 0 stop after SS1-t")});
    } else {
      f.terms.push_back({"Cat 0 stop after SS1-t", coast,
                         "qd_max / (kBrakeStopDecelFactor x qdd_max)"});
    }
    f.terms.push_back({"STO: the drive leaves Operation enabled", cycles(1),
                       per_cycle(1, "CiA 402: one state per cycle on the controlword")});
    f.terms.push_back({"contactor drop-out", cycles(plant.contactor_cycles),
                       per_cycle(plant.contactor_cycles, "sim kContactorFeedbackMs " +
                                                             num(sim::kContactorFeedbackMs) + " rounded up")});
  }
  void cat2_end(Function& f) const {
    f.terms.push_back({"if SS1-t trips: Cat 0 stop", coast_us(),
                       "qd_max / (kBrakeStopDecelFactor x qdd_max)"});
  }

  Function make(const char* id, const char* name, const char* rule, StopKind k) const {
    Function f;
    f.id = id;
    f.name = name;
    f.rule = rule;
    f.stop = k;
    return f;
  }

  // A limit of §10 (or T1 speed): measured from the drives' positions, rule 3, Cat 0.
  Function limit(const char* id, const char* name, const char* what, const std::string& note) const {
    Function f = make(id, name, "3", StopKind::cat0);
    f.note = note;
    no_filter(f, what);
    scan(f);
    io(f);
    cat0(f);
    return f;
  }

  Function reduced(const char* id, const char* name, const char* input, bool dual, const std::string& note) const {
    Function f = make(id, name, "§10 reduced", StopKind::reduce);
    f.note = note;
    if (dual) {
      dual_filter(f, input);
    } else {
      no_filter(f, input);
    }
    scan(f);
    io(f);
    const std::uint64_t ramp = core::ms_to_cycles(s.limits.reduced_ramp_ms, cfg.cycle_us) + 1U;
    f.terms.push_back({"reduced ramp: at or below the limit", cycles(ramp),
                       per_cycle(ramp, "reduced.ramp_ms " + num(s.limits.reduced_ramp_ms) + " + 1, monitored after it")});
    cat0(f, "if above (rule 3): ");
    return f;
  }
};

}  // namespace

Analysis analyse(const core::Config& cfg_in, const safety::Loaded& s, const BusTiming& bus) {
  core::Config cfg = cfg_in;
  cfg.max_stop_ms = s.limits.max_stop_ms;
  Builder b{cfg, core::to_timing(cfg), s, bus, sim::plant_timing(cfg.cycle_us), cfg.cycle_us};
  Analysis a;
  a.cycle_us = cfg.cycle_us;
  a.safety_name = s.name;
  a.safety_checksum = s.checksum;
  a.bus = bus;

  Function f = b.make("estop", "E-stop", "2", StopKind::cat0);
  b.dual_filter(f, "estop.a/b");
  b.scan(f);
  b.io(f);
  b.cat0(f);
  a.functions.push_back(f);

  f = b.make("guard", "guard (gate, AUTO)", "4", StopKind::cat1);
  b.dual_filter(f, "gate.a/b");
  b.scan(f);
  b.io(f);
  b.ramp_stop(f, core::StopCat::CAT1);
  b.cat1_end(f);
  a.functions.push_back(f);

  f = b.make("enable", "enabling device (T1/T2)", "5", StopKind::cat1);
  b.dual_filter(f, "enable.a/b, panic");
  b.scan(f);
  b.io(f);
  b.ramp_stop(f, core::StopCat::CAT1);
  b.cat1_end(f);
  a.functions.push_back(f);

  a.functions.push_back(b.limit("t1_speed", "T1 speed (250 mm/s)", "TCP and link origins from measured positions",
                                "t1_speed_limit_mm_s " + std::to_string(static_cast<int>(cfg.t1_speed_limit_mm_s))));
  a.functions.push_back(b.limit("joint_range", "safe limit: joint range", "measured joint positions", ""));
  a.functions.push_back(b.limit("joint_speed", "safe limit: joint speed", "measured joint velocities", ""));
  a.functions.push_back(b.limit("tcp_speed", "safe limit: TCP speed", "forward kinematics of measured positions",
                                "tcp_max_speed_mm_s " +
                                    std::to_string(static_cast<int>(s.limits.tcp_max_speed_mm_s))));
  a.functions.push_back(b.reduced("reduced_speed", "safe limit: reduced speed", "reduced.a/b", true,
                                  "reduced.tcp_max_speed_mm_s " +
                                      std::to_string(static_cast<int>(s.limits.reduced_tcp_max_speed_mm_s))));
  Function z = b.limit("zones", "safe limit: zones", "forward kinematics of measured positions",
                       std::to_string(s.limits.zone_count) + " zone(s) configured");
  z.active = s.limits.zone_count > 0U;
  a.functions.push_back(z);
  Function o = b.limit("orientation", "safe limit: orientation", "forward kinematics of measured positions", "");
  o.active = s.limits.orientation_enabled;
  if (!o.active) o.note = "not configured";
  a.functions.push_back(o);

  const bool collab = s.limits.collaborative.enabled;
  Function outer = b.reduced("field_outer", "protective field: outer", "field.outer.a/b", true,
                             "reduced mode; acts in AUTO with collaborative on");
  outer.active = collab;
  a.functions.push_back(outer);

  f = b.make("field_inner", "protective field: inner", "9", StopKind::cat2);
  f.active = collab;
  f.note = "Cat 2 to AUTO_PAUSED; acts in AUTO_RUNNING with collaborative on";
  b.dual_filter(f, "field.inner.a/b");
  b.scan(f);
  b.io(f);
  b.ramp_stop(f, core::StopCat::CAT2);
  b.cat2_end(f);
  a.functions.push_back(f);

  f = b.make("ssm", "speed and separation monitoring", "3", StopKind::cat0);
  f.active = collab && s.limits.collaborative.ssm_enabled;
  b.no_filter(f, "separation_mm");
  b.scan(f);
  b.io(f);
  core::SsmMonitor ssm;
  ssm.configure(s.limits, cfg.cycle_us);
  const std::uint64_t persist = ssm.reaction_cycles() + 1U;
  const auto tr_ms = static_cast<std::uint64_t>(std::lround(s.limits.collaborative.ssm.reaction_s * 1000.0F));
  f.terms.push_back({"SSM: over v_allowed + 5 % beyond T_r", b.cycles(persist),
                     b.per_cycle(persist, "reaction_ms " + num(tr_ms) + " + 1 (core::SsmMonitor)")});
  f.reaction_cycles += persist;
  b.cat0(f);
  f.note = f.active ? "" : "not configured";
  if (f.active && !bus.distance_sensor) {
    f.note = "the bus configuration has no distance_sensor: the separation is invalid (0), SSM holds the program";
  }
  a.functions.push_back(f);

  // SPEC §11 rule 8: the drives' torque reaches the core with the positions (one
  // exchange), the force must be over F_qs in kCollisionConfirmCycles samples in a row, then
  // the Cat 2 stop (its back-off comes after the arm stopped: not part of the reaction).
  f = b.make("collision", "collision detection", "8", StopKind::cat2);
  f.active = collab && s.limits.collaborative.pfl_enabled;
  b.no_filter(f, "torque actual (0x6077)");
  // The drive measures the torque of the cycle the contact begins in while it moves the
  // arm: the core reads it with the next exchange.
  f.terms.push_back({"drive: torque sampled, read with the next exchange", b.cycles(1),
                     b.per_cycle(1, "CiA 402 0x6077 of the last cycle's motion")});
  f.reaction_cycles += 1U;
  b.scan(f);
  b.io(f);
  {
    const std::uint64_t confirm = core::kCollisionConfirmCycles;
    f.terms.push_back({"collision: force over F_qs in consecutive samples", b.cycles(confirm - 1U),
                       b.per_cycle(confirm - 1U, "kCollisionConfirmCycles " + num(confirm) +
                                                     " - 1 (the first sample is the scan's; core::CollisionMonitor)")});
    f.reaction_cycles += confirm - 1U;
  }
  b.ramp_stop(f, core::StopCat::CAT2);
  b.cat2_end(f);
  f.note = f.active ? "then a 10 mm back-off at <= 100 mm/s, after the stop" : "not configured (pfl off)";
  a.functions.push_back(f);

  f = b.make("bus_loss", "fieldbus loss", "1", StopKind::cat0);
  if (bus.ethercat) {
    f.terms.push_back({"bus watchdog: no valid frame", b.bus_watchdog_us(),
                       "watchdog_ms " + num(bus.watchdog_ms) + " + frame_timeout_us " + num(bus.frame_timeout_us) +
                           " of " + bus.source});
    b.scan(f);
    f.note = "the outputs cannot cross a lost bus: the subdevices' own process-data watchdogs (set in the devices, "
             "not in the bus configuration) must drop them; add their time";
    b.cat0(f);
  } else {
    b.no_filter(f, "fieldbus health");
    b.scan(f);
    b.io(f);
    b.cat0(f);
  }
  a.functions.push_back(f);

  if (bus.ethercat && bus.safety_links) {
    // Issue 37: a container that does not come, or comes invalid: the safe output terminal
    // opens its outputs by itself after its watchdog, whatever the channel and the master do
    // (the channel, finding the same, names SAFETY_LINK_FAULT).
    f = b.make("link_loss", "safety container lost, late or invalid (black channel)", "1", StopKind::cat0);
    f.terms.push_back({"safe output terminal's watchdog: no new valid container of its channel",
                       static_cast<std::uint64_t>(bus.link_watchdog_ms) * 1000U,
                       "watchdog_ms " + num(bus.link_watchdog_ms) + " of the connections (" + bus.source +
                           "); an invalid container opens them at once"});
    f.terms.push_back({"output: the terminal opens K1 / K2 and the brake relay itself", 0,
                       "docs/black-channel.md: the device's fail-safe rule"});
    f.terms.push_back({"contactor drop-out", b.cycles(b.plant.contactor_cycles),
                       b.per_cycle(b.plant.contactor_cycles, "sim kContactorFeedbackMs " + num(sim::kContactorFeedbackMs) +
                                                                 " rounded up")});
    std::size_t axis = 0;
    const std::uint64_t n = b.cat0_stop_cycles(axis);
    f.terms.push_back({"Cat 0 stop: braked from the axis speed limit", b.cycles(n),
                       b.per_cycle(n, "axis " + num(axis) + ", as the other Cat 0 stops")});
    f.note = "measured on the wire by ecat-sim (`fault link ...`, status -> safety -> fault_to_open_us)";
    a.functions.push_back(f);
  }
  return a;
}

namespace {
std::string ms_text(std::uint64_t us) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", static_cast<double>(us) / 1000.0);
  return buf;
}
}  // namespace

std::string table(const Analysis& a) {
  std::string out = "Response time, worst case (SPEC §13): cycle " + std::to_string(a.cycle_us) + " us, safety \"" +
                    a.safety_name + "\" " + a.safety_checksum + ", I/O: " + a.bus.source + "\n";
  std::size_t w = 0;
  for (const Function& f : a.functions) {
    for (const Term& t : f.terms) w = std::max(w, t.name.size());
  }
  for (const Function& f : a.functions) {
    out += "\n" + f.name + " [" + f.id + "]: rule " + f.rule + ", " + to_string(f.stop) +
           (f.active ? "" : ", not active in this configuration") + (f.note.empty() ? "" : " (" + f.note + ")") + "\n";
    for (const Term& t : f.terms) {
      std::string line = "  " + t.name;
      line.append(w + 2U - t.name.size(), ' ');
      const std::string v = ms_text(t.us);
      line.append(v.size() < 10U ? 10U - v.size() : 0U, ' ');
      out += line + v + " ms  " + t.basis + "\n";
    }
    std::string tot = "  total";
    tot.append(w + 2U - 5U, ' ');
    const std::string v = ms_text(f.total_us());
    tot.append(v.size() < 10U ? 10U - v.size() : 0U, ' ');
    out += tot + v + " ms  (reaction to the safe output: " + std::to_string(f.reaction_cycles) + " cycle" +
           (f.reaction_cycles == 1U ? "" : "s") + ")\n";
  }
  return out;
}

std::string json(const Analysis& a) {
  nlohmann::ordered_json j;
  j["cycle_us"] = a.cycle_us;
  j["safety"] = {{"name", a.safety_name}, {"checksum", a.safety_checksum}};
  j["io"] = {{"ethercat", a.bus.ethercat}, {"source", a.bus.source}};
  if (a.bus.ethercat) {
    j["io"]["frame_timeout_us"] = a.bus.frame_timeout_us;
    j["io"]["watchdog_ms"] = a.bus.watchdog_ms;
  }
  j["functions"] = nlohmann::ordered_json::array();
  for (const Function& f : a.functions) {
    nlohmann::ordered_json jf;
    jf["id"] = f.id;
    jf["name"] = f.name;
    jf["rule"] = f.rule;
    jf["stop"] = to_string(f.stop);
    jf["active"] = f.active;
    jf["note"] = f.note;
    jf["reaction_cycles"] = f.reaction_cycles;
    jf["terms"] = nlohmann::ordered_json::array();
    for (const Term& t : f.terms) jf["terms"].push_back({{"name", t.name}, {"us", t.us}, {"basis", t.basis}});
    jf["total_us"] = f.total_us();
    j["functions"].push_back(jf);
  }
  return j.dump(1) + "\n";
}

}  // namespace safestate::rta

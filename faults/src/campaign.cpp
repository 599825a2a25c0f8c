// SPEC §14's fault-injection campaign (faults/campaign.hpp). Each injection runs in a child
// process forked from the parent's warm cell: a flipped bit may make a channel's program fail
// (a crash), which must not end the campaign.
#include "safestate/faults/campaign.hpp"

#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <sstream>

#include "safestate/backends/simulated.hpp"
#include "safestate/core/describe.hpp"
#include "safestate/safety/safety_config.hpp"
#include "safestate/vocab/inputs.hpp"

namespace safestate::faults {

namespace {

using core::AlarmId;
using core::State;
using vocab::FaultKind;

constexpr core::AlarmMask kDiagnostic = core::bit(AlarmId::CHANNEL_MISMATCH) | core::bit(AlarmId::CHANNEL_LOST) |
                                        core::bit(AlarmId::ENCODER_DISCREPANCY) |
                                        core::bit(AlarmId::CONTACTOR_WELDED) | core::bit(AlarmId::INTEGRITY_FAULT) |
                                        core::bit(AlarmId::SAFETY_LINK_FAULT);
constexpr std::uint32_t kMaxJitter = 500;   // cycles past the warm point before the fault
constexpr std::uint32_t kAfterSafe = 200;   // cycles a demand's run goes on to see a naming (EDM: 100 ms)
constexpr int kWarmLimit = 20000;

constexpr std::array<const char*, 12> kClasses{"channel stall", "channel crash", "channel input", "digest",
                                               "contactor welded", "encoder", "supervisor bit flip",
                                               // --fieldbus ethercat: faults on the black channel's wire
                                               "bus flip", "bus replay", "bus swap", "bus delay", "bus insert"};
constexpr std::size_t kFirstBusClass = 7;
constexpr std::uint32_t kBusPercent = 25;  // of the injections with --fieldbus ethercat
// Where an injection happens (SPEC §14: every demand after any one fault). Each situation is
// one warm cell, made once, with the demands that belong to it.
enum class Situation : std::uint8_t {
  auto_running,  // AUTO, the demo program moving, the built-in safety configuration
  t1_jogging,    // T1, the enabling device held, axis 1 jogged from the pendant
  in_slot,       // AUTO, standing in a keep_in slot 5 mm wider than the tool on each side
  at_joint,      // AUTO, standing with axis 1 limited to its position +-2 degrees
};
constexpr std::size_t kSituations = 4;
constexpr std::array<const char*, kSituations> kSituationNames{
    "AUTO, the program running", "T1, jogging axis 1", "AUTO, standing in a keep_in slot",
    "AUTO, standing 2 degrees from axis 1's limits"};

enum class Demand : std::uint8_t { estop, guard, runaway, reduced, enabling, zone, joint };
struct DemandInfo {
  Demand d;
  Situation where;
  const char* name;
};
constexpr std::array<DemandInfo, 7> kDemands{{
    {Demand::estop, Situation::auto_running, "E-stop"},
    {Demand::guard, Situation::auto_running, "guard opened in AUTO"},
    {Demand::runaway, Situation::auto_running, "drive 1 runaway"},
    {Demand::reduced, Situation::auto_running, "reduced speed requested (speed over its new limit)"},
    {Demand::enabling, Situation::t1_jogging, "enabling device released in T1"},
    {Demand::zone, Situation::in_slot, "drive 1 runaway into the slot's wall (zone)"},
    {Demand::joint, Situation::at_joint, "drive 1 runaway past axis 1's limit"},
}};

struct Fault {
  bool flip = false;
  bool bus = false;  // a fault on the black channel's wire (w)
  sim::WireFault w{};
  vocab::Fault f{};
  std::uint8_t channel = 0;  // flip: 0 A, 1 B
  std::uint32_t byte = 0;
  std::uint8_t bit = 0;
  std::size_t cls = 0;
};

// One fault of SPEC §14's list (30 %: each kind alike) or a bit of one channel's supervisor
// (70 %). With one channel, B's faults are A's and K2 is K1.
Fault draw(std::mt19937& rng, std::uint8_t channels) {
  Fault x{};
  const auto u = static_cast<std::uint32_t>(rng() % 100U);
  const auto ch = static_cast<std::uint8_t>((channels == 2U) ? 1U + rng() % 2U : 1U);  // 1 A, 2 B
  if (u >= 30U) {
    x.flip = true;
    x.channel = static_cast<std::uint8_t>(ch - 1U);
    x.byte = static_cast<std::uint32_t>(rng() % sim::Cell::supervisor_bytes());
    x.bit = static_cast<std::uint8_t>(rng() % 8U);
    x.cls = 6;
    return x;
  }
  x.cls = u % 6U;
  switch (x.cls) {
    case 0: x.f = vocab::Fault{FaultKind::channel_stall, ch, 0}; break;
    case 1: x.f = vocab::Fault{FaultKind::channel_crash, ch, 0}; break;
    case 2: {
      const auto c = static_cast<std::uint16_t>(rng() % vocab::kContacts);
      const auto level = static_cast<unsigned>(rng() % 2U);
      x.f = vocab::Fault{FaultKind::channel_input, ch, static_cast<std::uint16_t>((static_cast<unsigned>(c) << 1U) | level)};
      break;
    }
    case 3: {
      constexpr std::array<FaultKind, 3> kinds{FaultKind::digest_corrupt, FaultKind::digest_drop,
                                               FaultKind::digest_repeat};
      x.f = vocab::Fault{kinds[rng() % kinds.size()], ch, 0};
      break;
    }
    case 4: x.f = vocab::Fault{FaultKind::contactor_welded, ch, 0}; break;
    default: {
      const auto axis = static_cast<std::uint8_t>(1U + rng() % 6U);
      const auto k = static_cast<std::uint32_t>(rng() % 3U);
      const double sign = (rng() % 2U == 0U) ? 1.0 : -1.0;
      constexpr std::array<double, 4> kOffsetsDeg{0.2, 0.6, 2.0, 10.0};
      constexpr std::array<double, 3> kDriftsDegS{0.5, 5.0, 50.0};
      if (k == 0U) {
        x.f = vocab::Fault{FaultKind::encoder_stuck, axis, 0};
      } else if (k == 1U) {
        const double deg = sign * kOffsetsDeg[rng() % kOffsetsDeg.size()];
        x.f = vocab::Fault{FaultKind::encoder_offset, axis,
                           static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(deg * 100.0)))};
      } else {
        const double deg = sign * kDriftsDegS[rng() % kDriftsDegS.size()];
        x.f = vocab::Fault{FaultKind::encoder_drift, axis,
                           static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(deg * 100.0)))};
      }
      break;
    }
  }
  return x;
}

// A fault on the black channel's wire (--fieldbus ethercat): its kind, a connection and a
// direction, the bit of the container (a flip), how old (a replay: 2..9 cycles), the other
// connection (a swap, an insertion), how long held (a delay: 11..20 cycles, past the
// 10-cycle watchdog).
Fault draw_bus(std::mt19937& rng) {
  Fault x{};
  x.bus = true;
  const hal::LinkTable t = sim::shipped_links();
  const auto kind = static_cast<std::uint32_t>(rng() % 5U);
  x.cls = kFirstBusClass + kind;
  x.w.kind = static_cast<sim::WireFaultKind>(kind);
  x.w.dir = (rng() % 2U == 0U) ? sim::WireDirection::to_device : sim::WireDirection::to_channel;
  x.w.link = static_cast<std::uint8_t>(rng() % t.count);
  x.w.other = static_cast<std::uint8_t>((x.w.link + 1U + rng() % (t.count - 1U)) % t.count);
  const hal::LinkSpec& s = t.link[x.w.link];
  const std::size_t len =
      safelink::container_bytes(x.w.dir == sim::WireDirection::to_device ? s.host_data_bytes : s.device_data_bytes);
  x.w.bit = static_cast<std::uint16_t>(rng() % (8U * len));
  x.w.age = static_cast<std::uint8_t>(2U + rng() % 8U);
  x.w.hold = static_cast<std::uint8_t>(11U + rng() % 10U);
  return x;
}

std::string link_name(std::uint8_t i) {
  char b[8];
  std::snprintf(b, sizeof b, "0x%04X", static_cast<unsigned>(sim::shipped_links().link[i].id));
  return b;
}

std::string words(const Fault& x) {
  if (x.bus) {
    std::string w = std::string("bus ") + sim::to_string(x.w.kind) + " " + sim::to_string(x.w.dir) + " " +
                    link_name(x.w.link);
    switch (x.w.kind) {
      case sim::WireFaultKind::flip: w += " bit " + std::to_string(x.w.bit); break;
      case sim::WireFaultKind::replay: w += " " + std::to_string(x.w.age) + " cycles old"; break;
      case sim::WireFaultKind::swap: w += " with " + link_name(x.w.other); break;
      case sim::WireFaultKind::delay: w += " held " + std::to_string(x.w.hold) + " cycles"; break;
      case sim::WireFaultKind::insert: w += " replaced by " + link_name(x.w.other) + "'s"; break;
    }
    return w;
  }
  if (x.flip) {
    return std::string("channel ") + (x.channel == 1U ? "B" : "A") + " flip byte " + std::to_string(x.byte) + " bit " +
           std::to_string(static_cast<unsigned>(x.bit));
  }
  return vocab::format_fault(x.f);
}

void apply(sim::Cell& c, const Fault& x) {
  if (x.bus) {
    static_cast<void>(c.inject_wire(x.w));
  } else if (x.flip) {
    static_cast<void>(c.flip_supervisor_bit(x.channel, x.byte, x.bit));
  } else {
    c.inject(x.f);
  }
}

void demand(sim::Cell& c, Demand d) {
  core::RawInputs& in = c.inputs();
  switch (d) {
    case Demand::estop: in.estop_a = in.estop_b = false; break;
    case Demand::guard: in.gate_a = in.gate_b = false; break;
    case Demand::reduced: in.reduced_a = in.reduced_b = false; break;
    case Demand::enabling: in.enable_a = in.enable_b = false; break;
    case Demand::runaway:
    case Demand::zone:
    case Demand::joint: c.inject(vocab::Fault{FaultKind::drive_runaway, 1, 0}); break;
  }
}

// The operator's part of a situation, before each cycle: in T1 the pendant's jog command,
// repeated as the pendant does (the jog link's deadman), axis 1 back and forth.
void operate(sim::Cell& c, Situation where) {
  if (where != Situation::t1_jogging) {
    return;
  }
  const core::Cycle k = c.now();
  if ((k % 40U) != 0U) {
    return;
  }
  core::Command cmd{};
  cmd.seq = static_cast<std::uint32_t>(k);
  cmd.id = static_cast<std::uint8_t>(core::CommandId::jog);
  cmd.source = static_cast<std::uint8_t>(core::Source::pendant);
  cmd.axis = 1;
  cmd.dir = static_cast<std::int8_t>(((k / 2000U) % 2U == 0U) ? 1 : -1);
  cmd.speed = 20;
  static_cast<void>(c.submit(cmd));
}

void step(sim::Cell& c, Situation where) {
  operate(c, where);
  c.step();
}

bool stopping(State s) {
  return s == State::STOPPING || s == State::ESTOP_ACTIVE || s == State::ESTOP_RESET_NEEDED || s == State::IDLE ||
         s == State::ERROR_LOCKOUT;
}

// A demand's safe state, as the robot is: the power path open (K1's contacts, or K2's with
// two channels: a welded contactor is no open path, whatever was commanded); for the guard in
// AUTO (a Cat 1 stop, power on while it ramps) also the channel that moves the arm (A) running
// and stopping it.
bool safe(const sim::Cell& c, Demand d, float reduced_mm_s) {
  if (!c.power_on()) {
    return true;
  }
  switch (d) {
    case Demand::guard:
    case Demand::enabling:  // a Cat 1 stop likewise
      return c.channel_running(0) && stopping(c.channel(0).out().state);
    case Demand::reduced:  // the arm at or under the reduced limit, moved by a running channel A
      return c.channel_running(0) && c.view().tcp_speed_mm_s <= reduced_mm_s;
    default:
      return false;
  }
}

// The safety outputs as the world gets them (a change that makes the cell less safe than
// its fault-free twin is what an unnamed fault may not do).
// With the black channel (--fieldbus ethercat) those are the safe output terminal's: the
// channels' plain contactor and brake bits are wired to nothing there.
bool fdo_less_safe(const sim::BlackChannel& f, const sim::BlackChannel& twin, std::uint8_t channels) {
  const bool power_f = f.k(0) && (channels == 1U || f.k(1));
  const bool power_t = twin.k(0) && (channels == 1U || twin.k(1));
  const bool brakes_f = f.brake_relay(0) && f.brake_relay(1);
  const bool brakes_t = twin.brake_relay(0) && twin.brake_relay(1);
  return (power_f && !power_t) || (brakes_f && !brakes_t);
}
bool less_safe(const sim::Cell& f, const sim::Cell& twin) {
  if (f.black_channel() != nullptr && twin.black_channel() != nullptr) {
    return fdo_less_safe(*f.black_channel(), *twin.black_channel(), f.channels());
  }
  const bool power_f = f.contactor_command(0) && (f.channels() == 1U || f.contactor_command(1));
  const bool power_t = twin.contactor_command(0) && (twin.channels() == 1U || twin.contactor_command(1));
  const bool brakes_f = f.channel(0).image_out().brakes_release &&
                        (f.channels() == 1U || f.channel(1).image_out().brakes_release);
  const bool brakes_t = twin.channel(0).image_out().brakes_release &&
                        (twin.channels() == 1U || twin.channel(1).image_out().brakes_release);
  return (power_f && !power_t) || (brakes_f && !brakes_t);
}
bool differs(const sim::Cell& f, const sim::Cell& twin) {
  if (f.black_channel() != nullptr && twin.black_channel() != nullptr) {
    const sim::BlackChannel& a = *f.black_channel();
    const sim::BlackChannel& b = *twin.black_channel();
    return a.k(0) != b.k(0) || a.k(1) != b.k(1) || a.brake_relay(0) != b.brake_relay(0) ||
           a.brake_relay(1) != b.brake_relay(1);
  }
  return f.contactor_command(0) != twin.contactor_command(0) || f.contactor_command(1) != twin.contactor_command(1) ||
         f.channel(0).image_out().brakes_release != twin.channel(0).image_out().brakes_release ||
         f.channel(1).image_out().brakes_release != twin.channel(1).image_out().brakes_release;
}

std::string diagnostic_named(const sim::Cell& c) {
  const core::AlarmMask m = c.out().alarms & kDiagnostic;
  for (std::size_t i = 0; i < core::kAlarmCount; ++i) {
    if ((m & core::bit(static_cast<AlarmId>(i))) != 0U) {
      return core::to_string(static_cast<AlarmId>(i));
    }
  }
  return "";
}

// Cycles until the safe state (0: already), -1: not within kDemandCycles.
int cycles_to_safe(sim::Cell& c, const DemandInfo& d, float reduced_mm_s) {
  if (safe(c, d.d, reduced_mm_s)) {
    return 0;
  }
  for (std::uint32_t k = 1; k <= kDemandCycles; ++k) {
    step(c, d.where);
    if (safe(c, d.d, reduced_mm_s)) {
      return static_cast<int>(k);
    }
  }
  return -1;
}

// The first alarm the cell raised that it did not have before (the safety function that
// answered a demand), or "" (the demand's own stop raises none: an E-stop, a guard).
std::string answered_by(const sim::Cell& c, core::AlarmMask before) {
  const core::AlarmMask m = c.out().alarms & ~before;
  for (std::size_t i = 0; i < core::kAlarmCount; ++i) {
    if ((m & core::bit(static_cast<AlarmId>(i))) != 0U) {
      return core::to_string(static_cast<AlarmId>(i));
    }
  }
  return "";
}

// A situation's warm cell and what its demands are judged by.
struct Warm {
  std::unique_ptr<sim::Cell> cell;
  float reduced_mm_s = 0.0F;  // the configuration's reduced TCP speed (Demand::reduced)
};

// The built-in safety configuration, and for the standing situations narrowed around the
// arm's standing pose (TCP in mm, axis 1 in rad), through the configuration's own parser so
// that it is validated and checksummed as any configuration is.
bool situation_config(Situation where, const controller::CellView& at, safety::Loaded& out, std::string& error) {
  nlohmann::json j = nlohmann::json::parse(safety::default_safety_text());
  const safety::Result base = safety::parse_safety(safety::default_safety_text());
  if (!base.ok()) {
    error = "the built-in safety configuration does not load";
    return false;
  }
  constexpr double kPi = 3.14159265358979323846;
  if (where == Situation::in_slot) {
    // A slot along the arm's reach: the tool sphere 5 mm from each wall; axis 1 turning moves
    // the TCP across it (the arm stands along x at its home pose).
    const double half = static_cast<double>(base.config->limits.tool_radius_mm) + 5.0;
    j["zones"] = nlohmann::json::array({{{"name", "slot"},
                                          {"kind", "keep_in"},
                                          {"min_mm", {-3000.0, static_cast<double>(at.tcp[1]) - half, -3000.0}},
                                          {"max_mm", {3000.0, static_cast<double>(at.tcp[1]) + half, 3000.0}}}});
  } else if (where == Situation::at_joint) {
    // Degrees to 0.001 (as `safestate safety check` prints them): a float's own rounding
    // must not put a limit past the robot's.
    const auto deg = [&](float rad) { return std::round(static_cast<double>(rad) * 180.0 / kPi * 1000.0) / 1000.0; };
    nlohmann::json joints = nlohmann::json::array();
    for (std::size_t i = 0; i < core::kAxes; ++i) {
      const core::JointLimit& l = base.config->limits.joints[i];
      const double q = deg(at.joints_rad[i]);
      joints.push_back({{"min_deg", i == 0U ? q - 2.0 : deg(l.min_rad)},
                        {"max_deg", i == 0U ? q + 2.0 : deg(l.max_rad)},
                        {"max_speed_deg_s", deg(l.max_speed_rad_s)}});
    }
    j["joints"] = joints;
  }
  safety::Result r = safety::parse_safety(j.dump());
  if (!r.ok()) {
    error = std::string("the configuration of \"") + kSituationNames[static_cast<std::size_t>(where)] +
            "\" does not load: " + (r.errors.empty() ? std::string("?") : r.errors.front().text());
    return false;
  }
  out = std::move(*r.config);
  return true;
}

// A cell of the situation, brought to it: reset, servo_on, and in AUTO_RUNNING the program
// started, in T1 the enabling device held and the jog going; a distance sensor that sees
// nobody, the brake test passed.
std::unique_ptr<sim::Cell> bring_up(Situation where, const safety::Loaded& cfg, std::uint8_t channels, Fieldbus bus,
                                    std::string& error) {
  auto cell = std::make_unique<sim::Cell>(core::Config{}, nullptr, channels);
  const char* why = nullptr;
  if (bus == Fieldbus::ethercat && !cell->use_black_channel(why)) {
    error = std::string("the black channel does not come up: ") + (why != nullptr ? why : "?");
    return nullptr;
  }
  cell->configure_limits(cfg.limits, true);
  core::BrakeTestHistory h{};
  h.last = core::BrakeTestResult::passed;
  h.passed_ever = true;
  cell->configure_brake_test(h);
  core::RawInputs& in = cell->inputs();
  in.separation_mm = 100000;
  in.separation_valid = true;
  const bool t1 = where == Situation::t1_jogging;
  in.mode_auto = !t1;
  in.mode_t1 = t1;
  std::uint32_t seq = 0x40000000U;  // apart from operate()'s jog numbers
  const auto until = [&](const auto& p) {
    for (int k = 0; k < kWarmLimit; ++k) {
      step(*cell, t1 ? Situation::auto_running : where);  // no jog before it is OPERATIONAL
      if (p(*cell)) return true;
    }
    return false;
  };
  const auto cmd = [&](core::CommandId id) {
    core::Command c{};
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    c.source = static_cast<std::uint8_t>(core::Source::pendant);
    return cell->submit(c) == core::Result::OK;
  };
  // With the black channel the safe values before its connections are up (E-stop pressed)
  // take the cell out of BOOT at once; its boot checks end later, and a reset before then is
  // answered BUSY: wait for them too.
  const bool black = bus == Fieldbus::ethercat;
  bool ok = until([black](const sim::Cell& c) {
              return c.out().state == State::ESTOP_RESET_NEEDED &&
                     (!black || (!c.channel(0).controller().supervisor().manager().boot_pending() &&
                                 !c.channel(1).controller().supervisor().manager().boot_pending()));
            }) &&
            cmd(core::CommandId::reset) && until([](const sim::Cell& c) { return c.out().state == State::IDLE; });
  if (ok && t1) {
    in.enable_a = in.enable_b = true;
    for (int k = 0; black && k < 4; ++k) {
      step(*cell, Situation::auto_running);  // the contacts reach the channels in the F-DI's next containers
    }
  }
  ok = ok && cmd(core::CommandId::servo_on) &&
       until([](const sim::Cell& c) { return c.out().state == State::OPERATIONAL; });
  if (ok && where == Situation::auto_running) {
    ok = cmd(core::CommandId::start) &&
         until([](const sim::Cell& c) { return std::fabs(c.view().velocities_rad_s[0]) > 0.5F; }) &&
         cell->out().sub == core::Sub::AUTO_RUNNING;
  }
  if (ok && t1) {
    for (int k = 0; k < 300 && ok; ++k) {
      step(*cell, where);
    }
    ok = cell->out().state == State::OPERATIONAL && std::fabs(cell->view().velocities_rad_s[0]) > 0.01F;
  }
  if (!ok) {
    error = std::string("the warm cell of \"") + kSituationNames[static_cast<std::size_t>(where)] +
            "\" did not get there (" + core::to_string(cell->out().state) + ")";
    return nullptr;
  }
  return cell;
}

Warm warm_cell(Situation where, std::uint8_t channels, Fieldbus bus, std::string& error) {
  Warm w{};
  safety::Loaded cfg{};
  if (where == Situation::in_slot || where == Situation::at_joint) {
    // Where the arm stands once armed: a cell brought up on the built-in configuration.
    safety::Loaded plain{};
    if (!situation_config(Situation::auto_running, controller::CellView{}, plain, error)) {
      return w;
    }
    const std::unique_ptr<sim::Cell> probe = bring_up(Situation::at_joint, plain, channels, bus, error);
    if (!probe || !situation_config(where, probe->view(), cfg, error)) {
      return w;
    }
  } else if (!situation_config(where, controller::CellView{}, cfg, error)) {
    return w;
  }
  w.reduced_mm_s = cfg.limits.reduced_tcp_max_speed_mm_s;
  w.cell = bring_up(where, cfg, channels, bus, error);
  return w;
}

// Injection `index` of the seed: its situation (every kSituations-th alike), its jitter
// (cycles past the warm point) and its fault. The one place that draws them, so that a
// crashed child's fault can be named by drawing it again.
struct Drawn {
  Situation where = Situation::auto_running;
  std::uint32_t jitter = 0;
  Fault fault{};
};
Drawn drawn(const Options& o, std::uint32_t index) {
  std::seed_seq seq{o.seed, index, 14U};
  std::mt19937 rng(seq);
  Drawn d{};
  d.where = static_cast<Situation>(index % kSituations);
  d.jitter = static_cast<std::uint32_t>(rng() % kMaxJitter);
  d.fault = draw(rng, o.channels);
  if (o.fieldbus == Fieldbus::ethercat) {
    // The bus faults from a stream of their own: every other injection is the sim
    // campaign's, the same fault at the same moment.
    std::seed_seq bus_seq{o.seed, index, 37U};
    std::mt19937 bus_rng(bus_seq);
    if (bus_rng() % 100U < kBusPercent) {
      d.fault = draw_bus(bus_rng);
    }
  }
  return d;
}

// One injection, from a copy of its situation's warm cell: its jitter, its twin, the fault,
// the window before the demands, then each of the situation's demands on a copy of the faulty
// cell and of the twin.
Injection one(const std::array<Warm, kSituations>& warm, const Options& o, std::uint32_t index) {
  Injection r{};
  r.index = index;
  const Drawn dr = drawn(o, index);
  const Warm& w = warm[static_cast<std::size_t>(dr.where)];
  sim::Cell faulty(*w.cell);
  for (std::uint32_t k = 0; k < dr.jitter; ++k) {
    step(faulty, dr.where);
  }
  sim::Cell twin(faulty);
  const Fault& x = dr.fault;
  r.fault = words(x);
  r.cls = kClasses[x.cls];
  r.situation = kSituationNames[static_cast<std::size_t>(dr.where)];
  apply(faulty, x);
  // A bus fault: the hosting channel's end of the faulted connection, whose counter moves
  // with every new valid container it accepts (the last one before the power path opened).
  const std::size_t host = (x.bus && faulty.channels() == 2U && sim::shipped_links().link[x.w.link].channel == 'B') ? 1U : 0U;
  std::uint32_t last_seq = x.bus ? faulty.channel(host).links().end(x.w.link).seq() : 0U;
  std::int32_t last_valid = 0;
  bool worse = false;
  bool changed = false;
  for (std::uint32_t k = 1; k <= kDetectCycles; ++k) {
    step(faulty, dr.where);
    step(twin, dr.where);
    if (r.to_lockout < 0) {
      r.named = diagnostic_named(faulty);
      r.to_lockout = r.named.empty() ? -1 : static_cast<std::int32_t>(k);
    }
    worse = worse || less_safe(faulty, twin);
    changed = changed || differs(faulty, twin);
    if (x.bus) {
      // Issue 37: SAFETY_LINK_FAULT, and the safe output terminal's K1 and K2 (its outputs
      // as its connections drive them: what reaches the contactors).
      const sim::BlackChannel& bc = *faulty.black_channel();
      if (r.to_link_fault < 0 && faulty.alarms().active(AlarmId::SAFETY_LINK_FAULT)) {
        r.to_link_fault = static_cast<std::int32_t>(k);
        std::array<char, 64> b{};
        r.link_detail = core::detail_name(faulty.alarms().detail(AlarmId::SAFETY_LINK_FAULT), b.data(), b.size());
      }
      const std::uint32_t seq = faulty.channel(host).links().end(x.w.link).seq();
      if (seq != last_seq && r.to_power_open < 0) {
        last_seq = seq;
        last_valid = static_cast<std::int32_t>(k);
      }
      if (r.to_power_open < 0 && (!bc.k(0) || !bc.k(1))) {
        r.to_power_open = static_cast<std::int32_t>(k);
        r.from_last_valid = r.to_power_open - last_valid;
      }
      if (r.to_both_open < 0 && !bc.k(0) && !bc.k(1)) {
        r.to_both_open = static_cast<std::int32_t>(k);
      }
    }
  }
  const std::uint32_t limit = faulty.config().cross_check_cycles;
  bool all_safe = true;
  std::string named_at_demand;
  for (std::size_t i = 0; i < kDemands.size(); ++i) {
    const DemandInfo& d = kDemands[i];
    if (d.where != dr.where) {
      r.demand_safe.push_back(true);  // not this situation's: not a pair (demand_run says so)
      r.demand_run.push_back(false);
      continue;
    }
    sim::Cell a(faulty);
    sim::Cell t(twin);
    demand(a, d.d);
    demand(t, d.d);
    const int r0 = cycles_to_safe(t, d, w.reduced_mm_s);
    const int rf = cycles_to_safe(a, d, w.reduced_mm_s);
    const bool ok = rf >= 0 && (r0 < 0 || rf <= r0 + static_cast<int>(limit));
    r.demand_safe.push_back(ok);
    r.demand_run.push_back(true);
    all_safe = all_safe && ok;
    for (std::uint32_t k = 0; k < kAfterSafe && named_at_demand.empty() && r.named.empty(); ++k) {
      step(a, d.where);
      named_at_demand = diagnostic_named(a);
    }
  }
  if (r.named.empty()) {
    r.named = named_at_demand;
  }
  if (!all_safe) {
    r.outcome = Outcome::dangerous;
  } else if (!r.named.empty()) {
    r.outcome = Outcome::detected;
  } else if (worse) {
    r.outcome = Outcome::dangerous;  // less safe than the twin, and never named
  } else {
    r.outcome = changed ? Outcome::failsafe : Outcome::masked;
  }
  return r;
}

// The record a child writes to its parent: one line, fields split by '|'.
std::string record(const Injection& r) {
  std::string d;  // per demand: 1 safe in time, 0 not, - not this situation's
  for (std::size_t i = 0; i < r.demand_safe.size(); ++i) {
    d += (i < r.demand_run.size() && !r.demand_run[i]) ? '-' : (r.demand_safe[i] ? '1' : '0');
  }
  return std::to_string(static_cast<int>(r.outcome)) + "|" + std::to_string(r.to_lockout) + "|" + r.named + "|" +
         r.cls + "|" + r.fault + "|" + d + "|" + r.link_detail + "|" + std::to_string(r.to_link_fault) + "|" +
         std::to_string(r.to_power_open) + "|" + std::to_string(r.to_both_open) + "|" + std::to_string(r.from_last_valid) +
         "\n";
}

bool parse_record(const std::string& line, Injection& r) {
  std::vector<std::string> f;
  std::string cur;
  for (const char c : line) {
    if (c == '|') {
      f.push_back(cur);
      cur.clear();
    } else if (c != '\n') {
      cur += c;
    }
  }
  f.push_back(cur);
  if (f.size() != 11U) {
    return false;
  }
  const int o = std::atoi(f[0].c_str());
  if (o < 0 || o > static_cast<int>(Outcome::failsafe)) {
    return false;
  }
  r.outcome = static_cast<Outcome>(o);
  r.to_lockout = std::atoi(f[1].c_str());
  r.named = f[2];
  r.cls = f[3];
  r.fault = f[4];
  r.link_detail = f[6];
  r.to_link_fault = std::atoi(f[7].c_str());
  r.to_power_open = std::atoi(f[8].c_str());
  r.to_both_open = std::atoi(f[9].c_str());
  r.from_last_valid = std::atoi(f[10].c_str());
  r.demand_safe.clear();
  r.demand_run.clear();
  for (const char c : f[5]) {
    r.demand_safe.push_back(c != '0');
    r.demand_run.push_back(c != '-');
  }
  return r.demand_safe.size() == kDemands.size();
}

struct Child {
  pid_t pid = -1;
  int fd = -1;
  std::uint32_t index = 0;
};

// A bus fault's figures (--fieldbus ethercat).
void tally_bus(Report& rep, const Injection& r) {
  BusStats* b = nullptr;
  for (BusStats& x : rep.bus) {
    if (x.name == r.cls) {
      b = &x;
    }
  }
  if (b == nullptr) {
    return;  // not a bus fault
  }
  ++b->injected;
  if (r.outcome == Outcome::dangerous) {
    ++b->dangerous;
  }
  if (r.to_link_fault >= 0) {
    ++b->caught;
    b->to_link_fault.push_back(static_cast<std::uint32_t>(r.to_link_fault));
    const std::string e = r.link_detail.substr(r.link_detail.rfind('.') + 1U);
    auto it = std::find_if(b->errors.begin(), b->errors.end(), [&e](const auto& p) { return p.first == e; });
    if (it == b->errors.end()) {
      b->errors.emplace_back(e, 1U);
    } else {
      ++it->second;
    }
  }
  if (r.to_power_open >= 0) {
    b->to_power_open.push_back(static_cast<std::uint32_t>(r.to_power_open));
    b->from_last_valid.push_back(static_cast<std::uint32_t>(std::max(0, r.from_last_valid)));
  }
  if (r.to_both_open >= 0) {
    b->to_both_open.push_back(static_cast<std::uint32_t>(r.to_both_open));
  } else {
    ++b->not_opened;
  }
}

void tally(Report& rep, const Injection& r) {
  ++rep.injected;
  tally_bus(rep, r);
  ClassStats* cs = nullptr;
  for (ClassStats& c : rep.classes) {
    if (c.name == r.cls) {
      cs = &c;
    }
  }
  if (cs == nullptr) {
    rep.classes.push_back(ClassStats{r.cls});
    cs = &rep.classes.back();
  }
  ++cs->injected;
  switch (r.outcome) {
    case Outcome::detected: ++cs->detected; ++rep.detected; break;
    case Outcome::masked: ++cs->masked; ++rep.masked; break;
    case Outcome::failsafe: ++cs->failsafe; ++rep.failsafe; break;
    case Outcome::dangerous:
      ++cs->dangerous;
      ++rep.dangerous_count;
      if (rep.dangerous.size() < 50U) {
        rep.dangerous.push_back(r);
      }
      break;
    case Outcome::crashed: ++cs->crashed; ++rep.crashed; break;
  }
  if (r.to_lockout >= 0 && r.outcome == Outcome::detected) {
    ++cs->named_before_demand;
    rep.to_lockout.push_back(static_cast<std::uint32_t>(r.to_lockout));
  }
  for (std::size_t d = 0; d < r.demand_safe.size() && d < rep.demands.size(); ++d) {
    if (d < r.demand_run.size() && !r.demand_run[d]) {
      continue;  // another situation's demand
    }
    ++rep.demands[d].pairs;
    ++rep.pairs;
    if (r.demand_safe[d]) {
      ++rep.demands[d].safe;
      ++rep.pairs_safe;
    }
  }
}

std::uint32_t percentile(std::vector<std::uint32_t> v, double p) {
  if (v.empty()) {
    return 0;
  }
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size()))) - 1U;
  return v[std::min(i, v.size() - 1U)];
}

}  // namespace

const char* to_string(Fieldbus f) noexcept { return (f == Fieldbus::ethercat) ? "ethercat" : "sim"; }

bool parse_fieldbus(const std::string& s, Fieldbus& out) noexcept {
  if (s == "sim") {
    out = Fieldbus::sim;
    return true;
  }
  if (s == "ethercat") {
    out = Fieldbus::ethercat;
    return true;
  }
  return false;
}

const char* to_string(Outcome o) noexcept {
  switch (o) {
    case Outcome::detected: return "detected";
    case Outcome::masked: return "masked";
    case Outcome::failsafe: return "fail-safe";
    case Outcome::dangerous: return "dangerous";
    case Outcome::crashed: return "crashed";
  }
  return "?";
}

Report run(const Options& o) {
  Report rep{};
  rep.options = o;
  std::string error;
  std::array<Warm, kSituations> warm{};
  if (o.fieldbus == Fieldbus::ethercat) {
    for (std::size_t c = kFirstBusClass; c < kClasses.size(); ++c) {
      BusStats b{};
      b.name = kClasses[c];
      rep.bus.push_back(b);
    }
    const core::Config cfg{};
    rep.watchdog_cycles = static_cast<std::uint32_t>((sim::kLinkWatchdogMs * 1000U + cfg.cycle_us - 1U) / cfg.cycle_us);
  }
  for (std::size_t i = 0; i < kSituations; ++i) {
    warm[i] = warm_cell(static_cast<Situation>(i), o.channels, o.fieldbus, error);
    if (!warm[i].cell) {
      rep.error = error;
      return rep;
    }
  }
  // The fault-free reactions from each warm cell (what each demand is allowed, plus
  // cross_check_cycles, is its own twin's in each injection) and the safety function that
  // answered it: the first alarm it raised.
  for (const DemandInfo& d : kDemands) {
    const Warm& w = warm[static_cast<std::size_t>(d.where)];
    sim::Cell t(*w.cell);
    const core::AlarmMask before = t.out().alarms;
    demand(t, d.d);
    const int r0 = cycles_to_safe(t, d, w.reduced_mm_s);
    for (std::uint32_t k = 0; k < kAfterSafe && answered_by(t, before).empty(); ++k) {
      step(t, d.where);
    }
    DemandStats ds{};
    ds.name = d.name;
    ds.situation = kSituationNames[static_cast<std::size_t>(d.where)];
    ds.reaction_cycles = r0 < 0 ? 0U : static_cast<std::uint32_t>(r0);
    ds.answered_by = answered_by(t, before);
    rep.demands.push_back(ds);
  }
  std::fflush(stdout);
  std::fflush(stderr);
  std::vector<Child> running;
  std::uint32_t next = o.first;
  const std::uint32_t end = o.first + o.injections;
  const std::uint32_t jobs = std::max<std::uint32_t>(1U, o.jobs);
  while (next < end || !running.empty()) {
    while (next < end && running.size() < jobs) {
      int fds[2];
      if (pipe(fds) != 0) {
        rep.error = "pipe failed";
        return rep;
      }
      const pid_t pid = fork();
      if (pid < 0) {
        rep.error = "fork failed";
        return rep;
      }
      if (pid == 0) {
        close(fds[0]);
        const std::string line = record(one(warm, o, next));
        const ssize_t w = write(fds[1], line.data(), line.size());
        _exit((w == static_cast<ssize_t>(line.size())) ? 0 : 3);
      }
      close(fds[1]);
      running.push_back(Child{pid, fds[0], next});
      ++next;
    }
    int status = 0;
    const pid_t done = waitpid(-1, &status, 0);
    if (done < 0) {
      if (errno == EINTR) {
        continue;
      }
      rep.error = "waitpid failed";
      return rep;
    }
    const auto it = std::find_if(running.begin(), running.end(), [done](const Child& c) { return c.pid == done; });
    if (it == running.end()) {
      continue;
    }
    std::string line;
    char buf[512];
    ssize_t n = 0;
    while ((n = read(it->fd, buf, sizeof buf)) > 0) {
      line.append(buf, static_cast<std::size_t>(n));
    }
    close(it->fd);
    Injection r{};
    r.index = it->index;
    if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0 && parse_record(line, r))) {
      // The child died: a flipped bit made the channel's program fail. The fault it had is
      // drawn again here (the same seed and index) to name it.
      const Fault x = drawn(o, it->index).fault;
      r.fault = words(x);
      r.cls = kClasses[x.cls];
      r.outcome = Outcome::crashed;
      // The partner removes power (ch-crash-a.scn): the demands of its situation safe with two.
      const Situation where = drawn(o, it->index).where;
      for (const DemandInfo& d : kDemands) {
        r.demand_run.push_back(d.where == where);
        r.demand_safe.push_back(d.where != where || o.channels == 2U);
      }
    }
    running.erase(it);
    tally(rep, r);
  }
  // SPEC §14 / ISO 13849-1: DC = dangerous faults detected / all dangerous faults. Masked
  // and fail-safe outcomes are not dangerous; a crash is detected by the other channel with
  // two (CHANNEL_LOST, as `channel X crash`), and fail-safe with one (its outputs drop).
  const double det = static_cast<double>(rep.detected + (o.channels == 2U ? rep.crashed : 0U));
  const double all = det + static_cast<double>(rep.dangerous_count);
  rep.dc = (all > 0.0) ? det / all : 1.0;
  std::sort(rep.classes.begin(), rep.classes.end(),
            [](const ClassStats& a, const ClassStats& b) { return a.name < b.name; });
  return rep;
}

std::string table(const Report& r) {
  std::ostringstream t;
  if (!r.error.empty()) {
    t << "faults: " << r.error << "\n";
    return t.str();
  }
  t << "fault-injection campaign (SPEC 14): seed " << r.options.seed << ", " << r.injected << " injections, "
    << static_cast<int>(r.options.channels) << " channel" << (r.options.channels == 2U ? "s" : "");
  if (r.options.fieldbus == Fieldbus::ethercat) {
    t << ", fieldbus ethercat (the black channel in the simulated world: the containers and both ends real, the "
         "bus a byte copy, no frames)";
  }
  t << "\n";
  char line[256];
  std::snprintf(line, sizeof line, "%-22s %9s %9s %9s %9s %9s %9s %9s\n", "fault class", "injected", "detected",
                "before", "masked", "failsafe", "crashed", "DANGER");
  t << line;
  for (const ClassStats& c : r.classes) {
    std::snprintf(line, sizeof line, "%-22s %9llu %9llu %9llu %9llu %9llu %9llu %9llu\n", c.name.c_str(),
                  static_cast<unsigned long long>(c.injected), static_cast<unsigned long long>(c.detected),
                  static_cast<unsigned long long>(c.named_before_demand), static_cast<unsigned long long>(c.masked),
                  static_cast<unsigned long long>(c.failsafe), static_cast<unsigned long long>(c.crashed),
                  static_cast<unsigned long long>(c.dangerous));
    t << line;
  }
  std::snprintf(line, sizeof line, "diagnostic coverage: %.2f %% (detected%s / (that + dangerous undetected))\n",
                100.0 * r.dc, r.options.channels == 2U ? " + crashed" : "");
  t << line;
  t << "(fault, demand) pairs that reached their safe state in time: " << r.pairs_safe << " of " << r.pairs << "\n";
  for (const DemandStats& d : r.demands) {
    t << "  " << d.name << " (" << d.situation << "): " << d.safe << " of " << d.pairs << " (fault-free: safe after "
      << d.reaction_cycles << " cycles, answered by " << (d.answered_by.empty() ? "its own stop" : d.answered_by)
      << "; allowed its twin's time + cross_check_cycles)\n";
  }
  t << "fault to naming lockout (before the demands): p50 " << percentile(r.to_lockout, 0.5) << " cycles, max "
    << percentile(r.to_lockout, 1.0) << " cycles (" << r.to_lockout.size() << " detections)\n";
  for (std::size_t n = 0; n < r.dangerous.size() && n < 10U; ++n) {
    const Injection& i = r.dangerous[n];
    t << "  dangerous: injection " << i.index << ": " << i.fault << " (" << i.cls << ")";
    for (std::size_t d = 0; d < i.demand_safe.size() && d < kDemands.size(); ++d) {
      if (!i.demand_safe[d]) {
        t << "; " << kDemands[d].name << " not safe in time";
      }
    }
    t << (i.named.empty() ? "; never named" : "; named " + i.named) << "\n";
  }
  if (r.dangerous_count > 10U) {
    t << "  ... " << (r.dangerous_count - 10U) << " more dangerous (--json lists the first 50)\n";
  }
  if (!r.bus.empty()) {
    t << "bus faults (issue 37): caught = SAFETY_LINK_FAULT named; cycles from the injection to it, to the safe output "
         "terminal's K1 or K2 open (the power path open) and to both open; watchdog "
      << r.watchdog_cycles << " cycles\n";
    std::snprintf(line, sizeof line, "%-12s %8s %8s %7s %9s %13s %9s %13s %7s  %s\n", "bus fault", "injected",
                  "caught", "DANGER", "fault max", "K1|K2 p50/max", "from valid", "K1&K2 p50/max", "within",
                  "errors named");
    t << line;
    for (const BusStats& b : r.bus) {
      std::string errors;
      for (const auto& e : b.errors) {
        errors += (errors.empty() ? "" : ", ") + e.first + " " + std::to_string(e.second);
      }
      const std::uint32_t both_max = percentile(b.to_both_open, 1.0);
      char any[32];
      char both[32];
      std::snprintf(any, sizeof any, "%u/%u", percentile(b.to_power_open, 0.5), percentile(b.to_power_open, 1.0));
      std::snprintf(both, sizeof both, "%u/%u", percentile(b.to_both_open, 0.5), both_max);
      const bool within = b.not_opened == 0U && percentile(b.from_last_valid, 1.0) <= r.watchdog_cycles;
      std::snprintf(line, sizeof line, "%-12s %8llu %8llu %7llu %9u %13s %9u %13s %7s  %s\n", b.name.c_str(),
                    static_cast<unsigned long long>(b.injected), static_cast<unsigned long long>(b.caught),
                    static_cast<unsigned long long>(b.dangerous), percentile(b.to_link_fault, 1.0), any,
                    percentile(b.from_last_valid, 1.0), both, b.injected == 0U ? "-" : (within ? "yes" : "NO"),
                    errors.c_str());
      t << line;
    }
    t << "(from valid: max cycles from the last new valid container the channel accepted on the faulted connection to "
         "K1 or K2 open, which the watchdog bounds; within: that max <= the watchdog and K1 and K2 both opened every "
         "time; K1&K2 adds the other channel's cross-check)\n";
  }
  return t.str();
}

std::string json(const Report& r) {
  nlohmann::json j;
  if (!r.error.empty()) {
    j["error"] = r.error;
    return j.dump() + "\n";
  }
  j["seed"] = r.options.seed;
  j["channels"] = r.options.channels;
  j["injections"] = r.injected;
  j["detected"] = r.detected;
  j["masked"] = r.masked;
  j["failsafe"] = r.failsafe;
  j["crashed"] = r.crashed;
  j["dangerous"] = r.dangerous_count;
  j["dc"] = r.dc;
  j["pairs"] = r.pairs;
  j["pairs_safe"] = r.pairs_safe;
  j["to_lockout_cycles"] = {{"p50", percentile(r.to_lockout, 0.5)},
                            {"max", percentile(r.to_lockout, 1.0)},
                            {"count", r.to_lockout.size()}};
  for (const ClassStats& c : r.classes) {
    j["classes"].push_back({{"name", c.name},
                            {"injected", c.injected},
                            {"detected", c.detected},
                            {"named_before_demand", c.named_before_demand},
                            {"masked", c.masked},
                            {"failsafe", c.failsafe},
                            {"crashed", c.crashed},
                            {"dangerous", c.dangerous}});
  }
  for (const DemandStats& d : r.demands) {
    j["demands"].push_back({{"name", d.name},
                            {"situation", d.situation},
                            {"pairs", d.pairs},
                            {"safe", d.safe},
                            {"reaction_cycles", d.reaction_cycles},
                            {"answered_by", d.answered_by}});
  }
  if (r.options.fieldbus == Fieldbus::ethercat) {  // the sim campaign's JSON stays as it was
    j["fieldbus"] = to_string(r.options.fieldbus);
    j["watchdog_cycles"] = r.watchdog_cycles;
    j["bus_faults"] = nlohmann::json::array();
    for (const BusStats& b : r.bus) {
      nlohmann::json errors = nlohmann::json::object();
      for (const auto& e : b.errors) {
        errors[e.first] = e.second;
      }
      j["bus_faults"].push_back({{"name", b.name},
                                 {"injected", b.injected},
                                 {"caught", b.caught},
                                 {"dangerous", b.dangerous},
                                 {"to_link_fault_cycles", {{"p50", percentile(b.to_link_fault, 0.5)},
                                                           {"max", percentile(b.to_link_fault, 1.0)}}},
                                 {"to_power_open_cycles", {{"p50", percentile(b.to_power_open, 0.5)},
                                                           {"max", percentile(b.to_power_open, 1.0)}}},
                                 {"to_both_open_cycles", {{"p50", percentile(b.to_both_open, 0.5)},
                                                          {"max", percentile(b.to_both_open, 1.0)}}},
                                 {"from_last_valid_to_power_open_cycles", {{"p50", percentile(b.from_last_valid, 0.5)},
                                                                           {"max", percentile(b.from_last_valid, 1.0)}}},
                                 {"not_opened", b.not_opened},
                                 {"errors", errors}});
    }
  }
  j["dangerous_injections"] = nlohmann::json::array();
  for (const Injection& i : r.dangerous) {
    j["dangerous_injections"].push_back({{"index", i.index}, {"fault", i.fault}, {"class", i.cls}, {"named", i.named},
                                         {"demand_safe", i.demand_safe}});
  }
  return j.dump() + "\n";
}

}  // namespace safestate::faults

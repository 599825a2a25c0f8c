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
#include "safestate/safety/safety_config.hpp"
#include "safestate/vocab/inputs.hpp"

namespace safestate::faults {

namespace {

using core::AlarmId;
using core::State;
using vocab::FaultKind;

constexpr core::AlarmMask kDiagnostic = core::bit(AlarmId::CHANNEL_MISMATCH) | core::bit(AlarmId::CHANNEL_LOST) |
                                        core::bit(AlarmId::ENCODER_DISCREPANCY) |
                                        core::bit(AlarmId::CONTACTOR_WELDED) | core::bit(AlarmId::INTEGRITY_FAULT);
constexpr std::uint32_t kMaxJitter = 500;   // cycles past the warm point before the fault
constexpr std::uint32_t kAfterSafe = 200;   // cycles a demand's run goes on to see a naming (EDM: 100 ms)
constexpr int kWarmLimit = 20000;

constexpr std::array<const char*, 7> kClasses{"channel stall", "channel crash", "channel input", "digest",
                                              "contactor welded", "encoder", "supervisor bit flip"};
enum class Demand : std::uint8_t { estop, guard, runaway };
constexpr std::array<Demand, 3> kDemands{Demand::estop, Demand::guard, Demand::runaway};
constexpr std::array<const char*, 3> kDemandNames{"E-stop", "guard opened in AUTO", "drive 1 runaway"};

struct Fault {
  bool flip = false;
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

std::string words(const Fault& x) {
  if (x.flip) {
    return std::string("channel ") + (x.channel == 1U ? "B" : "A") + " flip byte " + std::to_string(x.byte) + " bit " +
           std::to_string(static_cast<unsigned>(x.bit));
  }
  return vocab::format_fault(x.f);
}

void apply(sim::Cell& c, const Fault& x) {
  if (x.flip) {
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
    case Demand::runaway: c.inject(vocab::Fault{FaultKind::drive_runaway, 1, 0}); break;
  }
}

bool stopping(State s) {
  return s == State::STOPPING || s == State::ESTOP_ACTIVE || s == State::ESTOP_RESET_NEEDED || s == State::IDLE ||
         s == State::ERROR_LOCKOUT;
}

// A demand's safe state, as the robot is: the power path open (K1's contacts, or K2's with
// two channels: a welded contactor is no open path, whatever was commanded); for the guard in
// AUTO (a Cat 1 stop, power on while it ramps) also the channel that moves the arm (A) running
// and stopping it.
bool safe(const sim::Cell& c, Demand d) {
  if (!c.power_on()) {
    return true;
  }
  return d == Demand::guard && c.channel_running(0) && stopping(c.channel(0).out().state);
}

// The safety outputs as the world gets them (a change that makes the cell less safe than
// its fault-free twin is what an unnamed fault may not do).
bool less_safe(const sim::Cell& f, const sim::Cell& twin) {
  const bool power_f = f.contactor_command(0) && (f.channels() == 1U || f.contactor_command(1));
  const bool power_t = twin.contactor_command(0) && (twin.channels() == 1U || twin.contactor_command(1));
  const bool brakes_f = f.channel(0).image_out().brakes_release &&
                        (f.channels() == 1U || f.channel(1).image_out().brakes_release);
  const bool brakes_t = twin.channel(0).image_out().brakes_release &&
                        (twin.channels() == 1U || twin.channel(1).image_out().brakes_release);
  return (power_f && !power_t) || (brakes_f && !brakes_t);
}
bool differs(const sim::Cell& f, const sim::Cell& twin) {
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
int cycles_to_safe(sim::Cell& c, Demand d) {
  if (safe(c, d)) {
    return 0;
  }
  for (std::uint32_t k = 1; k <= kDemandCycles; ++k) {
    c.step();
    if (safe(c, d)) {
      return static_cast<int>(k);
    }
  }
  return -1;
}

// The warm cell: AUTO, the demo program running (the arm moving), the built-in safety
// configuration validated, a distance sensor that sees nobody.
std::unique_ptr<sim::Cell> warm_cell(std::uint8_t channels, std::string& error) {
  core::Config cfg{};
  auto cell = std::make_unique<sim::Cell>(cfg, nullptr, channels);
  const safety::Result r = safety::parse_safety(safety::default_safety_text());
  if (!r.ok()) {
    error = "the built-in safety configuration does not load";
    return nullptr;
  }
  cell->configure_limits(r.config->limits, true);
  core::BrakeTestHistory h{};
  h.last = core::BrakeTestResult::passed;
  h.passed_ever = true;
  cell->configure_brake_test(h);
  core::RawInputs& in = cell->inputs();
  in.separation_mm = 100000;
  in.separation_valid = true;
  in.mode_auto = true;
  std::uint32_t seq = 0;
  const auto until = [&](const auto& p) {
    for (int k = 0; k < kWarmLimit; ++k) {
      cell->step();
      if (p(*cell)) return true;
    }
    return false;
  };
  const auto cmd = [&](core::CommandId id) {
    core::Command c{};
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    return cell->submit(c) == core::Result::OK;
  };
  const bool ok = until([](const sim::Cell& c) { return c.out().state == State::ESTOP_RESET_NEEDED; }) &&
                  cmd(core::CommandId::reset) &&
                  until([](const sim::Cell& c) { return c.out().state == State::IDLE; }) &&
                  cmd(core::CommandId::servo_on) &&
                  until([](const sim::Cell& c) { return c.out().state == State::OPERATIONAL; }) &&
                  cmd(core::CommandId::start) &&
                  until([](const sim::Cell& c) { return std::fabs(c.view().velocities_rad_s[0]) > 0.5F; });
  if (!ok || cell->out().sub != core::Sub::AUTO_RUNNING) {
    error = std::string("the warm cell did not reach AUTO_RUNNING (") + core::to_string(cell->out().state) + ")";
    return nullptr;
  }
  return cell;
}

// Injection `index` of the seed: its jitter (cycles past the warm point) and its fault. The one
// place that draws them, so that a crashed child's fault can be named by drawing it again.
struct Drawn {
  std::uint32_t jitter = 0;
  Fault fault{};
};
Drawn drawn(const Options& o, std::uint32_t index) {
  std::seed_seq seq{o.seed, index, 14U};
  std::mt19937 rng(seq);
  Drawn d{};
  d.jitter = static_cast<std::uint32_t>(rng() % kMaxJitter);
  d.fault = draw(rng, o.channels);
  return d;
}

// One injection, from a copy of the warm cell: its jitter, its twin, the fault, the window
// before the demands, then each demand on a copy of the faulty cell and of the twin.
Injection one(const sim::Cell& warm, const Options& o, std::uint32_t index) {
  Injection r{};
  r.index = index;
  const Drawn dr = drawn(o, index);
  sim::Cell faulty(warm);
  for (std::uint32_t k = 0; k < dr.jitter; ++k) {
    faulty.step();
  }
  sim::Cell twin(faulty);
  const Fault& x = dr.fault;
  r.fault = words(x);
  r.cls = kClasses[x.cls];
  apply(faulty, x);
  bool worse = false;
  bool changed = false;
  for (std::uint32_t k = 1; k <= kDetectCycles; ++k) {
    faulty.step();
    twin.step();
    if (r.to_lockout < 0) {
      r.named = diagnostic_named(faulty);
      r.to_lockout = r.named.empty() ? -1 : static_cast<std::int32_t>(k);
    }
    worse = worse || less_safe(faulty, twin);
    changed = changed || differs(faulty, twin);
  }
  const std::uint32_t limit = faulty.config().cross_check_cycles;
  bool all_safe = true;
  std::string named_at_demand;
  for (const Demand d : kDemands) {
    sim::Cell a(faulty);
    sim::Cell t(twin);
    demand(a, d);
    demand(t, d);
    const int r0 = cycles_to_safe(t, d);
    const int rf = cycles_to_safe(a, d);
    const bool ok = rf >= 0 && (r0 < 0 || rf <= r0 + static_cast<int>(limit));
    r.demand_safe.push_back(ok);
    all_safe = all_safe && ok;
    for (std::uint32_t k = 0; k < kAfterSafe && named_at_demand.empty() && r.named.empty(); ++k) {
      a.step();
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
  std::string d;
  for (const bool b : r.demand_safe) {
    d += b ? '1' : '0';
  }
  return std::to_string(static_cast<int>(r.outcome)) + "|" + std::to_string(r.to_lockout) + "|" + r.named + "|" +
         r.cls + "|" + r.fault + "|" + d + "\n";
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
  if (f.size() != 6U) {
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
  r.demand_safe.clear();
  for (const char c : f[5]) {
    r.demand_safe.push_back(c == '1');
  }
  return r.demand_safe.size() == kDemands.size();
}

struct Child {
  pid_t pid = -1;
  int fd = -1;
  std::uint32_t index = 0;
};

void tally(Report& rep, const Injection& r) {
  ++rep.injected;
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
  for (const char* n : kDemandNames) {
    rep.demands.push_back(DemandStats{n});
  }
  std::string error;
  const std::unique_ptr<sim::Cell> warm = warm_cell(o.channels, error);
  if (!warm) {
    rep.error = error;
    return rep;
  }
  // The fault-free reactions (what each demand is allowed, plus cross_check_cycles).
  for (std::size_t d = 0; d < kDemands.size(); ++d) {
    sim::Cell t(*warm);
    demand(t, kDemands[d]);
    const int r0 = cycles_to_safe(t, kDemands[d]);
    rep.demands[d].reaction_cycles = r0 < 0 ? 0U : static_cast<std::uint32_t>(r0);
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
        const std::string line = record(one(*warm, o, next));
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
      r.demand_safe.assign(kDemands.size(), o.channels == 2U);  // the partner removes power (ch-crash-a.scn)
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
    << static_cast<int>(r.options.channels) << " channel" << (r.options.channels == 2U ? "s" : "") << "\n";
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
    t << "  " << d.name << ": " << d.safe << " of " << d.pairs << " (fault-free: safe after " << d.reaction_cycles
      << " cycles; allowed that + cross_check_cycles)\n";
  }
  t << "fault to naming lockout (before the demands): p50 " << percentile(r.to_lockout, 0.5) << " cycles, max "
    << percentile(r.to_lockout, 1.0) << " cycles (" << r.to_lockout.size() << " detections)\n";
  for (std::size_t n = 0; n < r.dangerous.size() && n < 10U; ++n) {
    const Injection& i = r.dangerous[n];
    t << "  dangerous: injection " << i.index << ": " << i.fault << " (" << i.cls << ")";
    for (std::size_t d = 0; d < i.demand_safe.size(); ++d) {
      if (!i.demand_safe[d]) {
        t << "; " << kDemandNames[d % kDemandNames.size()] << " not safe in time";
      }
    }
    t << (i.named.empty() ? "; never named" : "; named " + i.named) << "\n";
  }
  if (r.dangerous_count > 10U) {
    t << "  ... " << (r.dangerous_count - 10U) << " more dangerous (--json lists the first 50)\n";
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
    j["demands"].push_back({{"name", d.name}, {"pairs", d.pairs}, {"safe", d.safe}, {"reaction_cycles", d.reaction_cycles}});
  }
  j["dangerous_injections"] = nlohmann::json::array();
  for (const Injection& i : r.dangerous) {
    j["dangerous_injections"].push_back({{"index", i.index}, {"fault", i.fault}, {"class", i.cls}, {"named", i.named},
                                         {"demand_safe", i.demand_safe}});
  }
  return j.dump() + "\n";
}

}  // namespace safestate::faults

#include "checker.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <unordered_set>
#include <vector>

#include "reference.hpp"
#include "safestate/core/cia402.hpp"
#include "safestate/scenario/scenario.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::check {

namespace {

using core::State;
using core::Sub;

// The actions: every input and channel, command and fault of the scenario vocabulary.
const std::vector<std::string>& action_texts() {
  static const std::vector<std::string> k = {
      "in estop=pressed", "in estop=released", "in estop.a=0", "in estop.a=1",
      "in gate=open", "in gate=closed", "in gate.b=0", "in gate.b=1",
      "in enable=released", "in enable=centre", "in enable=panic", "in enable.a=1",
      "in mode=AUTO", "in mode=T1", "in mode=T2", "in mode=NONE", "in mode.t1=1",
      "in reset_button=1", "in reset_button=0",
      "cmd reset", "cmd servo_on", "cmd servo_off", "cmd start", "cmd pause", "cmd resume", "cmd stop",
      "cmd jog 1 + 50", "cmd jog_stop", "cmd confirm_t2", "cmd set_mode T1", "cmd jog 9 +",
      "cmd from=remote start", "cmd from=remote reset", "cmd from=remote servo_on",
      "fault drive 1 fault", "fault drive 1 clear", "fault drive 2 runaway", "fault drive 3 nostop",
      "fault fieldbus lost", "fault contactor stuck_open", "fault brake 1 stuck", "fault clear all",
      "fault contactor welded", "fault brake 2 stuck_released",
  };
  return k;
}
constexpr std::size_t kWaitOne = 1000;     // action id: let one cycle pass
constexpr std::size_t kWaitChange = 1001;  // let time pass until something changes
constexpr std::size_t kWaitLong = 1002;    // 5100 cycles: reset button held / boot timeout
constexpr core::Cycle kChangeBound = 1200;

struct Applied {
  scenario::Directive what;
};

std::vector<Applied> parse_actions() {
  std::vector<Applied> out;
  for (const std::string& t : action_texts()) {
    const scenario::ParseResult r = scenario::parse("@0 " + t + "\n", "check");
    out.push_back(Applied{r.scenario.steps.at(0).what});
  }
  return out;
}

// How long each feedback has contradicted the command of the cycle before (SPEC §7),
// counted here from the outside, independently of the core's own monitors.
struct FeedbackWatch {
  core::Cycle welded = 0;
  std::array<core::Cycle, core::kAxes> brake{};
};

struct Node {
  std::unique_ptr<sim::Cell> cell;
  reference::Supervisor ref;
  std::vector<std::pair<std::uint32_t, core::Cycle>> pending;  // command seq, cycle sent
  std::size_t trail = 0;  // index into the trail (path) table
  FeedbackWatch watch{};
};

struct Trail {
  std::size_t parent;
  std::string line;  // the .scn directive applied ("" for letting time pass)
  core::Cycle t;     // cycle at which it was applied
};

// Seeds: configurations reached by a scripted prefix, from which every combination of
// actions is explored as from boot. Deep states (running, jogging, paused, stopping)
// are then within a few actions.
struct Seed {
  const char* name;
  const char* script;  // .scn lines
};
const std::vector<Seed>& seeds() {
  static const std::vector<Seed> k = {
      {"boot", ""},
      {"IDLE (AUTO)", "@100 cmd reset\n@101 in reset_button=0\n"},
      {"AUTO_IDLE", "@100 cmd reset\n@110 cmd servo_on\n@400 in reset_button=0\n"},
      {"AUTO_RUNNING", "@100 cmd reset\n@110 cmd servo_on\n@400 cmd start\n@600 in reset_button=0\n"},
      {"AUTO_PAUSED", "@100 cmd reset\n@110 cmd servo_on\n@400 cmd start\n@600 cmd pause\n@1500 in reset_button=0\n"},
      {"STOPPING(CAT1)", "@100 cmd reset\n@110 cmd servo_on\n@400 cmd start\n@600 cmd servo_off\n@601 in reset_button=0\n"},
      {"MANUAL_IDLE (T1)", "@0 in mode=T1\n@100 cmd reset\n@105 in enable=centre\n@110 cmd servo_on\n@400 in reset_button=0\n"},
      {"MANUAL_JOGGING (T1)",
       "@0 in mode=T1\n@100 cmd reset\n@105 in enable=centre\n@110 cmd servo_on\n@400 cmd jog 1 + 50\n@430 cmd jog 1 + 50\n"},
      {"MANUAL_RUNNING (T1)",
       "@0 in mode=T1\n@100 cmd reset\n@105 in enable=centre\n@110 cmd servo_on\n@400 cmd start\n@600 in reset_button=0\n"},
      {"MANUAL_IDLE (T2)",
       "@0 in mode=T2\n@100 cmd reset\n@101 cmd confirm_t2\n@105 in enable=centre\n@110 cmd servo_on\n@400 in reset_button=0\n"},
      {"ESTOP_ACTIVE", "@100 cmd reset\n@110 cmd servo_on\n@400 in estop=pressed\n@401 in reset_button=0\n"},
  };
  return k;
}

struct Violation {
  std::string invariant;
  std::string detail;
  std::string expect;  // .scn expect line body that fails when replayed
  core::Cycle t = 0;
};

std::string key_of(const sim::Cell& c) {
  const core::SupervisorOut& o = c.out();
  const sim::CellView& v = c.view();
  const core::SafetyInputs& in = c.safety_inputs();
  const core::RawInputs& r = c.raw_inputs_of_last_cycle();
  std::ostringstream k;
  k << static_cast<int>(c.leaf()) << '|' << o.alarms << '|' << static_cast<int>(o.mode) << o.t2_confirmed
    << static_cast<int>(o.arming_step) << o.motion.fault_reset << o.brakes_release << '|' << r.estop_a << r.estop_b
    << r.gate_a << r.gate_b << r.enable_a << r.enable_b << r.enable_panic << r.mode_auto << r.mode_t1 << r.mode_t2
    << r.reset_button << '|' << in.estop_pressed << in.gate_open << in.enable_ok << static_cast<int>(in.enable)
    << in.mode_invalid << in.estop_discrepancy << in.gate_discrepancy << in.enable_discrepancy << '|' << v.injected
    << '|' << v.contactor_closed << v.fieldbus_ok << '|';
  bool moving = false;
  for (std::size_t i = 0; i < 6; ++i) {
    k << static_cast<int>(core::cia402::decode(v.statusword[i])) << v.brake_released[i];
    moving = moving || !(std::fabs(v.velocities_rad_s[i]) < 0.01F);
  }
  k << '|' << moving;
  return k.str();
}

class Checker {
 public:
  Checker(const CheckOptions& o, CheckStats& s) : opt_(o), stats_(s), actions_(parse_actions()) {}
  int run();

 private:
  bool step(Node& n, const Node* baseline_of, std::uint32_t cmd_seq, Violation& v);
  bool apply(Node& n, std::size_t action, Violation& v);
  bool apply_directive(Node& n, const scenario::Directive& d, Violation& v);
  bool run_seed(const Seed& seed, Node& n, Violation& v);
  void report(std::size_t trail, const std::string& line, core::Cycle t, const Violation& v);

  CheckOptions opt_;
  CheckStats& stats_;
  std::vector<Applied> actions_;
  std::vector<Trail> trails_;
  std::uint32_t seq_ = 1;
};

// One scan cycle of `n` with every invariant checked. `cmd_seq` is the command sent
// before this cycle (0: none); for it, `baseline` is the same node stepped without the
// command, to show that a refused command changed nothing.
bool Checker::step(Node& n, const Node* baseline, std::uint32_t cmd_seq, Violation& v) {
  const core::SupervisorOut before = n.cell->out();
  n.cell->step();
  ++stats_.cycles;
  const core::SupervisorOut& o = n.cell->out();
  const core::SafetyInputs& in = n.cell->safety_inputs();
  const core::Cycle t = n.cell->now() - 1U;
  v.t = t;
  std::size_t taken = 0;
  const core::Command* cmds = n.cell->commands_taken(taken);
  reference::Out r{};
  n.ref.step(in, n.cell->feedback(), cmds, taken, r);
  stats_.checks += 9;

  const bool powered_state = o.state == State::ARMING || o.state == State::OPERATIONAL || o.state == State::STOPPING;
  const bool any_power = o.contactor || o.drives_enable || o.brakes_release;
  if (any_power && !powered_state) {
    v = {"power only in ARMING, OPERATIONAL or STOPPING", to_string(o.state), "contactor=open drives=disabled brakes=engaged", t};
    return false;
  }
  if (opt_.break_invariant && in.estop_pressed && o.state != State::IDLE) {
    v = {"(deliberately wrong, --break-invariant) E-stop pressed => IDLE", to_string(o.state), "state=IDLE", t};
    return false;
  }
  if (in.estop_pressed && (!(o.state == State::ESTOP_ACTIVE || o.state == State::ERROR_LOCKOUT) || any_power)) {
    v = {"E-stop pressed => ESTOP_ACTIVE or ERROR_LOCKOUT with safe outputs in the same cycle", to_string(o.state),
         "state=ESTOP_ACTIVE contactor=open drives=disabled brakes=engaged", t};
    return false;
  }
  // SPEC §7 feedback monitoring: a contactor feedback closed for more than 100 ms after
  // open was commanded locks out; a brake feedback released for more than 300 ms after
  // engage was commanded raises BRAKE_NOT_ENGAGED with power removed.
  const core::Feedback& fb = n.cell->feedback();
  const core::Timing tm = core::to_timing(n.cell->config());
  n.watch.welded = (!before.contactor && fb.contactor_closed) ? n.watch.welded + 1U : 0U;
  if (n.watch.welded > tm.contactor_timeout && o.state != State::ERROR_LOCKOUT) {
    v = {"contactor feedback closed > 100 ms after open was commanded => ERROR_LOCKOUT (CONTACTOR_WELDED)",
         to_string(o.state), "state=ERROR_LOCKOUT alarm=CONTACTOR_WELDED", t};
    return false;
  }
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    n.watch.brake[i] = (!before.brakes_release && fb.brake_released[i]) ? n.watch.brake[i] + 1U : 0U;
    const bool alarmed = (o.alarms & core::bit(core::AlarmId::BRAKE_NOT_ENGAGED)) != 0U;
    if (n.watch.brake[i] > tm.brakes_timeout && (!alarmed || powered_state)) {
      v = {"brake feedback released > 300 ms after engage was commanded => BRAKE_NOT_ENGAGED, power removed",
           to_string(o.state), "alarm=BRAKE_NOT_ENGAGED contactor=open", t};
      return false;
    }
  }
  if (before.state == State::ERROR_LOCKOUT && o.state != State::ERROR_LOCKOUT) {
    v = {"ERROR_LOCKOUT is never left", to_string(o.state), "state=ERROR_LOCKOUT", t};
    return false;
  }
  bool reset_ok = false;
  bool motion_ok = false;
  for (std::size_t i = 0; i < o.reply_count; ++i) {
    const core::Reply& rp = o.replies[i];
    const auto id = static_cast<core::CommandId>(rp.cmd);
    reset_ok = reset_ok || (rp.cmd == static_cast<std::uint8_t>(core::CommandId::reset) && rp.result == core::Result::OK);
    motion_ok = motion_ok || ((id == core::CommandId::start || id == core::CommandId::resume || id == core::CommandId::jog) &&
                              rp.result == core::Result::OK);
  }
  if ((before.state == State::ESTOP_ACTIVE || before.state == State::ESTOP_RESET_NEEDED) && o.state == State::IDLE &&
      !reset_ok) {
    v = {"IDLE is reached from ESTOP_* only through a reset", "no reset answered OK", "state=" + std::string(to_string(before.state)), t};
    return false;
  }
  if (in.mode == core::Mode::AUTO && in.gate_open && o.sub == Sub::AUTO_RUNNING) {
    v = {"AUTO with the guard open => never AUTO_RUNNING", "AUTO_RUNNING", "sub=AUTO_IDLE", t};
    return false;
  }
  const bool manual_motion = o.sub == Sub::MANUAL_JOGGING || o.sub == Sub::MANUAL_RUNNING;
  if (manual_motion && !((in.mode == core::Mode::T1 || in.mode == core::Mode::T2) && in.enable_ok)) {
    v = {"manual motion => mode T1/T2 and the enabling device at centre (through released)", to_string(o.sub),
         "state=STOPPING", t};
    return false;
  }
  if (in.mode_changed && (before.state == State::ARMING || before.state == State::OPERATIONAL) &&
      o.stop == core::StopCat::NONE) {
    v = {"a mode change in ARMING or OPERATIONAL => a stop in that cycle", to_string(o.state), "stop=CAT1", t};
    return false;
  }
  const bool motion_sub = o.sub == Sub::AUTO_RUNNING || o.sub == Sub::MANUAL_JOGGING || o.sub == Sub::MANUAL_RUNNING;
  if (motion_sub && o.sub != before.sub && !motion_ok) {
    v = {"no motion sub-state without a motion command accepted in that cycle", to_string(o.sub),
         "sub=" + std::string(to_string(before.sub)), t};
    return false;
  }
  // Exactly one result per command.
  for (std::size_t i = 0; i < o.reply_count; ++i) {
    const std::uint32_t s = o.replies[i].seq;
    if (o.replies[i].source == static_cast<std::uint8_t>(core::Source::reset_button)) continue;
    bool found = false;
    for (auto it = n.pending.begin(); it != n.pending.end(); ++it) {
      if (it->first == s) {
        n.pending.erase(it);
        found = true;
        break;
      }
    }
    if (!found) {
      v = {"every command gets exactly one result", "a second or unexpected reply for seq " + std::to_string(s), "", t};
      return false;
    }
  }
  for (const auto& p : n.pending) {
    if (t - p.second > 60U) {
      v = {"every command gets exactly one result", "no reply for seq " + std::to_string(p.first) + " after 60 cycles", "", t};
      return false;
    }
  }
  // A refused command changes nothing.
  if (cmd_seq != 0U && baseline != nullptr) {
    for (std::size_t i = 0; i < o.reply_count; ++i) {
      if (o.replies[i].seq != cmd_seq || o.replies[i].result == core::Result::OK) continue;
      const core::SupervisorOut& b = baseline->cell->out();
      const bool same = b.state == o.state && b.sub == o.sub && b.stop == o.stop && b.contactor == o.contactor &&
                        b.drives_enable == o.drives_enable && b.brakes_release == o.brakes_release &&
                        b.reset_lamp == o.reset_lamp && b.alarms == o.alarms && b.t2_confirmed == o.t2_confirmed &&
                        b.motion.mode == o.motion.mode && b.motion.program == o.motion.program;
      if (!same) {
        v = {"a refused command changes nothing", std::string(to_string(o.replies[i].result)) + " but the cycle differs", "", t};
        return false;
      }
    }
  }
  // Differential oracle: the independent reference supervisor.
  bool agree = r.state == o.state && r.sub == o.sub && r.stop == o.stop && r.contactor == o.contactor &&
               r.drives == o.drives_enable && r.brakes_release == o.brakes_release && r.reset_lamp == o.reset_lamp &&
               r.alarms == o.alarms && r.reply_count == o.reply_count;
  for (std::size_t i = 0; agree && i < o.reply_count; ++i) {
    agree = r.replies[i].seq == o.replies[i].seq && r.replies[i].result == o.replies[i].result;
  }
  if (!agree) {
    std::ostringstream d;
    d << "core/reference:";
    if (r.state != o.state || r.sub != o.sub) d << " state " << to_string(o.state) << "/" << to_string(r.state) << " sub " << to_string(o.sub) << "/" << to_string(r.sub);
    if (r.stop != o.stop) d << " stop " << to_string(o.stop) << "/" << to_string(r.stop);
    if (r.contactor != o.contactor || r.drives != o.drives_enable || r.brakes_release != o.brakes_release) d << " outputs";
    if (r.reset_lamp != o.reset_lamp) d << " reset_lamp " << o.reset_lamp << "/" << r.reset_lamp;
    for (std::size_t a = 0; a < core::kAlarmCount; ++a) {
      const core::AlarmMask b = core::bit(static_cast<core::AlarmId>(a));
      if ((r.alarms & b) != (o.alarms & b)) d << " alarm " << to_string(static_cast<core::AlarmId>(a)) << " " << ((o.alarms & b) != 0U) << "/" << ((r.alarms & b) != 0U);
    }
    if (r.reply_count != o.reply_count) d << " replies " << static_cast<int>(o.reply_count) << "/" << static_cast<int>(r.reply_count);
    v = {"the core agrees with the reference implementation", d.str(),
         "state=" + std::string(to_string(r.state)) + " sub=" + std::string(to_string(r.sub)), t};
    return false;
  }
  return true;
}

bool Checker::apply(Node& n, std::size_t action, Violation& v) {
  ++stats_.transitions;
  if (action == kWaitOne) {
    return step(n, nullptr, 0, v);
  }
  if (action == kWaitChange || action == kWaitLong) {
    const std::string k0 = key_of(*n.cell);
    const core::Cycle bound = (action == kWaitLong) ? 5100U : kChangeBound;
    for (core::Cycle i = 0; i < bound; ++i) {
      if (!step(n, nullptr, 0, v)) return false;
      if (action == kWaitChange && key_of(*n.cell) != k0) break;
    }
    return true;
  }
  return apply_directive(n, actions_[action].what, v);
}

bool Checker::apply_directive(Node& n, const scenario::Directive& d, Violation& v) {
  if (const auto* in = std::get_if<scenario::InputStep>(&d)) {
    scenario::apply(*in, n.cell->inputs());
    return step(n, nullptr, 0, v);
  }
  if (const auto* f = std::get_if<scenario::FaultStep>(&d)) {
    n.cell->inject(f->fault);
    return step(n, nullptr, 0, v);
  }
  const auto& c = std::get<scenario::CommandStep>(d);
  Node base{std::make_unique<sim::Cell>(*n.cell), n.ref, n.pending, n.trail, n.watch};
  Violation ignored;
  step(base, nullptr, 0, ignored);
  core::Command cmd = c.command;
  cmd.seq = seq_++;
  if (n.cell->submit(cmd) != core::Result::OK) return true;  // QUEUE_FULL is its answer
  n.pending.emplace_back(cmd.seq, n.cell->now());
  return step(n, &base, cmd.seq, v);
}

// Plays a seed's script (one directive per cycle at its time, time passing between),
// with every invariant checked on the way; the lines become trail entries.
bool Checker::run_seed(const Seed& seed, Node& n, Violation& v) {
  const scenario::ParseResult p = scenario::parse(seed.script, seed.name);
  std::istringstream lines(seed.script);
  std::vector<std::string> text;
  for (std::string l; std::getline(lines, l);) text.push_back(l.substr(l.find(' ') + 1U));
  std::size_t i = 0;
  for (const scenario::Step& st : p.scenario.steps) {
    while (n.cell->now() < st.t) {
      if (!step(n, nullptr, 0, v)) return false;
    }
    trails_.push_back(Trail{n.trail, text[i++], n.cell->now()});
    n.trail = trails_.size() - 1U;
    if (!apply_directive(n, st.what, v)) return false;
  }
  return true;
}

void Checker::report(std::size_t trail, const std::string& line, core::Cycle t, const Violation& v) {
  std::vector<const Trail*> path;
  const Trail last{trail, line, t};
  path.push_back(&last);
  for (std::size_t i = trail; i != 0; i = trails_[i].parent) {
    path.push_back(&trails_[i]);
  }
  std::ostringstream scn;
  scn << "# Counterexample found by `safestate check`: " << v.invariant << "\n# found: " << v.detail << "\n";
  for (auto it = path.rbegin(); it != path.rend(); ++it) {
    if (!(*it)->line.empty()) {
      scn << "@" << (*it)->t << " " << (*it)->line << "\n";
    }
  }
  if (!v.expect.empty()) {
    scn << "@" << v.t << " expect " << v.expect << "   # the invariant: " << v.invariant << "\n";
  }
  const std::string file = opt_.out_dir + "/counterexample.scn";
  std::ofstream(file) << scn.str();
  std::printf("VIOLATION: %s (%s) at cycle %llu\ncounterexample written to %s:\n%s", v.invariant.c_str(),
              v.detail.c_str(), static_cast<unsigned long long>(v.t), file.c_str(), scn.str().c_str());
}

int Checker::run() {
  trails_.push_back(Trail{0, "", 0});  // the root
  std::unordered_set<std::string> seen;
  std::vector<Node> frontier;
  for (const Seed& sd : seeds()) {
    Node n{std::make_unique<sim::Cell>(core::Config{}), reference::Supervisor{core::to_timing(core::Config{})}, {}, 0};
    Violation v;
    if (!run_seed(sd, n, v)) {
      report(n.trail, "", n.cell->now(), v);
      return 1;
    }
    if (seen.insert(key_of(*n.cell)).second) {
      frontier.push_back(std::move(n));
    }
  }
  stats_.configurations = frontier.size();
  std::vector<std::size_t> all;
  for (std::size_t i = 0; i < action_texts().size(); ++i) all.push_back(i);
  all.push_back(kWaitOne);
  all.push_back(kWaitChange);

  for (std::size_t depth = 0; depth < opt_.max_depth && !frontier.empty(); ++depth) {
    std::vector<Node> next;
    for (Node& n : frontier) {
      std::vector<std::size_t> acts = all;
      if (n.cell->out().state == State::BOOT || n.cell->raw_inputs_of_last_cycle().reset_button) {
        acts.push_back(kWaitLong);
      }
      for (std::size_t a : acts) {
        Node child{std::make_unique<sim::Cell>(*n.cell), n.ref, n.pending, n.trail, n.watch};
        const core::Cycle t = child.cell->now();
        const std::string line = (a < action_texts().size()) ? action_texts()[a] : std::string();
        Violation v;
        if (!apply(child, a, v)) {
          report(n.trail, line, t, v);
          stats_.max_depth = depth + 1;
          return 1;
        }
        if (seen.insert(key_of(*child.cell)).second) {
          trails_.push_back(Trail{n.trail, line, t});
          child.trail = trails_.size() - 1U;
          ++stats_.configurations;
          if (stats_.configurations < opt_.max_configs) {
            next.push_back(std::move(child));
          }
        }
      }
    }
    stats_.max_depth = depth + 1;
    if (opt_.verbose) {
      std::printf("depth %zu: %zu configurations, frontier %zu\n", depth + 1, stats_.configurations, next.size());
      std::fflush(stdout);
    }
    frontier = std::move(next);
  }
  stats_.complete = frontier.empty();
  return 0;
}

}  // namespace

int check_main(const CheckOptions& opt, CheckStats& stats) {
  if (opt.max_depth == 0 || opt.max_configs == 0) {
    std::fprintf(stderr, "safestate check: --depth and --max-configs must be positive\n");
    return 2;
  }
  Checker c(opt, stats);
  const int rc = c.run();
  std::printf("%s: %zu configurations, %zu transitions, %zu cycles, %zu invariant checks, depth %zu%s\n",
              rc == 0 ? "all invariants hold" : "stopped at the first violation", stats.configurations,
              stats.transitions, stats.cycles, stats.checks, stats.max_depth,
              stats.complete ? " (reachable set exhausted)" : " (bounded)");
  return rc;
}

}  // namespace safestate::check

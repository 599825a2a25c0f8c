#include "checker.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <unordered_set>
#include <variant>
#include <vector>

#include "reference.hpp"
#include "safestate/controller/controller.hpp"
#include "safestate/core/arm.hpp"
#include "safestate/core/cia402.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/safety/safety_config.hpp"
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
      // SPEC §12: the brake test, and a brake that slips under its torque.
      "cmd brake_test", "fault brake 3 weak",
      // SPEC §10, abstractly: reduced mode asked for (both channels, one channel), the
      // configuration validated (the right code, a wrong one), a jog toward and away from
      // the limited axes' ranges (limit violated or not, recovery), a runaway into them.
      // (kFirstLimitAction on: only from the seeds with a configuration of their own, where
      // they matter; the first of them from every configuration.)
      "in reduced=reduced", "in reduced=normal", "in reduced.a=0",
      "cmd validate_config 00000000", "cmd jog 1 - 50", "fault drive 1 runaway",
      // SPEC §11, abstractly, from the collaborative seeds only: a person in and out of each
      // field, one OSSD channel alone (discrepancy), the distance sensor near, at the 500 mm
      // switch, far, and failing; a contact over the hand's F_qs against the TCP, and gone.
      "in field.inner=interrupted", "in field.inner=clear", "in field.outer=interrupted", "in field.outer=clear",
      "in field.inner.a=0", "in separation_mm=300", "in separation_mm=800", "in separation_mm=5000",
      "in separation_valid=0", "fault contact 300", "fault contact 0",
  };
  return k;
}
constexpr std::size_t kFirstLimitAction = 46;  // "in reduced=reduced"
constexpr std::size_t kLimitActionsEverywhere = 1;
constexpr std::size_t kFirstCollabAction = 52;  // "in field.inner=interrupted"
constexpr std::size_t kValidateRight = 999;  // action id: validate_config with the active checksum
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

// SPEC §10 as the checker watches it, from the outside: which configuration the node runs,
// whether the checker saw it validated, and per limited joint the best (smallest) amount
// outside its range since power came on (recovery may only reduce it).
struct LimitWatch {
  std::size_t config = 0;  // index into configurations()
  bool validated = true;
  std::array<float, core::kAxes> best{};
  std::uint32_t validate_seq = 0;  // a validate_config sent, and its code
  std::uint32_t validate_code = 0;
  // SPEC §11, counted from the outside: cycles both fields have read clear, cycles the TCP
  // has been over v_allowed + 5 %.
  core::Cycle fields_clear = 0;
  core::Cycle ssm_over = 0;
};

struct Node {
  std::unique_ptr<sim::Cell> cell;
  reference::Supervisor ref;
  std::vector<std::pair<std::uint32_t, core::Cycle>> pending;  // command seq, cycle sent
  std::size_t trail = 0;  // index into the trail (path) table
  FeedbackWatch watch{};
  LimitWatch lim{};
};

// The safety configurations the seeds run with (SPEC §10 files, parsed by the same parser
// as `safestate run --safety`): the built-in one, axis 1 within 2 deg (a jog reaches it, a
// runaway crosses it; started not validated) and axis 1 within [-90, -2] deg (the home
// pose, 0 deg, is outside it: recovery from boot, where + is worse and a runaway makes it so).
struct Configuration {
  const char* file;  // written beside a counterexample; "" for the built-in one
  std::string text;
  bool validated;    // at start (the event log holds a confirmation)
  safety::Loaded loaded;
};
std::string joints_json(const char* axis1) {
  return std::string(R"({"format":"safestate-safety/1","name":"checker","tool":{"tcp_mm":[0,0,120],"radius_mm":40,"payload_kg":1.5},"joints":[)") +
         axis1 + R"(,{"min_deg":-90,"max_deg":100,"max_speed_deg_s":200},{"min_deg":-110,"max_deg":70,"max_speed_deg_s":200},{"min_deg":-160,"max_deg":160,"max_speed_deg_s":300},{"min_deg":-120,"max_deg":120,"max_speed_deg_s":300},{"min_deg":-360,"max_deg":360,"max_speed_deg_s":400}],"tcp_max_speed_mm_s":1500,"reduced":{"tcp_max_speed_mm_s":250,"ramp_ms":500},"stop":{"max_time_ms":1000}})";
}
const std::vector<Configuration>& configurations() {
  static const std::vector<Configuration> k = [] {
    std::vector<Configuration> v;
    v.push_back({"", std::string(safety::default_safety_text()), true, safety::default_safety()});
    v.push_back({"checker-axis1-2deg.json", joints_json(R"({"min_deg":-2,"max_deg":2,"max_speed_deg_s":200})"),
                 false, {}});
    v.push_back({"checker-axis1-below-2deg.json",
                 joints_json(R"({"min_deg":-90,"max_deg":-2,"max_speed_deg_s":200})"), true, {}});
    // SPEC §11: fields, SSM with the SPEC's example figures, PFL for the hand; a short
    // resume delay so that the time actions reach it.
    std::string collab = joints_json(R"({"min_deg":-165,"max_deg":165,"max_speed_deg_s":200})");
    collab.pop_back();
    collab += R"(,"collaborative":{"enabled":true,"resume_delay_ms":200,"auto_resume":true,"reduced_speed_mm_s":200,)"
              R"("ssm":{"enabled":true,"human_speed_mm_s":1600,"decel_mm_s2":2000,"reaction_ms":100,"intrusion_mm":200,)"
              R"("uncertainty_mm":100},"pfl":{"enabled":true,"body_region":"hand","robot_mass_kg":25}}})";
    v.push_back({"checker-collaborative.json", collab, true, {}});
    for (Configuration& c : v) {
      if (c.file[0] != '\0') {
        safety::Result r = safety::parse_safety(c.text);
        if (!r.ok()) {
          std::fprintf(stderr, "safestate check: a built-in checker configuration does not parse\n");
          std::abort();
        }
        c.loaded = *r.config;
      }
    }
    return v;
  }();
  return k;
}

reference::Limits ref_limits(const Configuration& c, std::uint32_t cycle_us) {
  const core::SafetyLimits& l = c.loaded.limits;
  reference::Limits r{};
  r.configured = true;
  r.validated = c.validated;
  r.checksum = l.checksum;
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    r.min_rad[i] = l.joints[i].min_rad;
    r.max_rad[i] = l.joints[i].max_rad;
    r.max_speed_rad_s[i] = l.joints[i].max_speed_rad_s;
  }
  r.tcp_max_mm_s = l.tcp_max_speed_mm_s;
  r.reduced_tcp_max_mm_s = l.reduced_tcp_max_speed_mm_s;
  r.ramp = core::ms_to_cycles(l.reduced_ramp_ms, cycle_us);
  const core::CollaborativeLimits& co = l.collaborative;
  r.collaborative = co.enabled;
  r.field_reduced_mm_s = (co.pfl_enabled && co.pfl_speed_mm_s < co.reduced_speed_mm_s) ? co.pfl_speed_mm_s : co.reduced_speed_mm_s;
  r.auto_resume = co.auto_resume;
  r.resume_delay = core::ms_to_cycles(co.resume_delay_ms, cycle_us);
  r.ssm = co.ssm_enabled;
  r.ssm_params = co.ssm;
  r.reaction = static_cast<core::Cycle>(std::llround(static_cast<double>(co.ssm.reaction_s) * 1.0e6)) / cycle_us;
  r.rise_mm = static_cast<float>((2000.0 + static_cast<double>(l.tcp_max_speed_mm_s)) * cycle_us * 1.0e-6);
  r.pfl = co.enabled && co.pfl_enabled;
  r.f_qs_n = co.f_qs_n;
  return r;
}

// T1 speed: the points the reference differentiates itself (link origins 1..5, the flange,
// the TCP) where the core's kinematics of the cell's arm (the IRB 120) puts them at the
// measured positions, with the configuration's TCP.
void t1_points(const core::Feedback& fb, const core::Vec3& tcp_mm, reference::Geometry& g) {
  static const core::PreparedArm arm = core::prepare_arm(controller::Controller::arm_geometry(motion::kRobot));
  core::JointArray q{};
  for (std::size_t i = 0; i < core::kAxes; ++i) q[i] = fb.drive[i].position_rad;
  core::ArmPose p{};
  core::arm_forward(arm, q, tcp_mm, p);
  g.arm = true;
  for (std::size_t k = 0; k + 1U < reference::kT1Points; ++k) g.t1_points[k] = p.origin[k + 1U];
  g.t1_points[reference::kT1Points - 1U] = p.tcp;
}

// How far joint i is outside its range (rad, <= 0 inside), measured from the outside.
float joint_outside(const core::SafetyLimits& l, std::size_t i, float q) {
  const float below = l.joints[i].min_rad - q;
  const float above = q - l.joints[i].max_rad;
  return (q != q) ? 1.0e30F : ((below > above) ? below : above);
}

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
  std::size_t config = 0;  // index into configurations()
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
      // SPEC §12: in the brake test, brake 2 weak: axis 1 holds, axis 2 slips about 1.2 s on.
      {"BRAKE_TEST (AUTO), brake 2 weak",
       "@100 cmd reset\n@110 cmd servo_on\n@300 fault brake 2 weak\n@400 cmd brake_test\n@401 in reset_button=0\n"},
      {"BRAKE_TEST (T1), healthy brakes",
       "@0 in mode=T1\n@100 cmd reset\n@105 in enable=centre\n@110 cmd servo_on\n@400 cmd brake_test\n@401 in reset_button=0\n"},
      // SPEC §10: a configuration not validated yet, axis 1 within 2 deg.
      {"IDLE (T1), not validated", "@0 in mode=T1\n@100 cmd reset\n@101 in reset_button=0\n", 1},
      {"MANUAL_JOGGING (T1) toward axis 1's limit, not validated",
       "@0 in mode=T1\n@100 cmd reset\n@105 in enable=centre\n@110 cmd servo_on\n@400 cmd jog 1 + 50\n@430 cmd jog 1 + 50\n", 1},
      // SPEC §10 recovery: axis 1 outside its range from boot.
      {"MANUAL_IDLE (T1), recovering axis 1",
       "@0 in mode=T1\n@100 cmd reset\n@105 in enable=centre\n@110 cmd servo_on\n@400 in reset_button=0\n", 2},
      // SPEC §11: collaborative operation, the person far away (SSM lets the program run).
      {"AUTO_RUNNING, collaborative",
       "@0 in separation_mm=5000\n@100 cmd reset\n@110 cmd servo_on\n@400 cmd start\n@600 in reset_button=0\n", 3},
      {"AUTO_PAUSED by rule 9, collaborative",
       "@0 in separation_mm=5000\n@100 cmd reset\n@110 cmd servo_on\n@400 cmd start\n@600 in field.inner=interrupted\n"
       "@1500 in reset_button=0\n", 3},
  };
  return k;
}

struct Violation {
  std::string invariant;
  std::string detail;
  std::string expect;  // .scn expect line body that fails when replayed
  core::Cycle t = 0;
};

// The abstract key, built as bytes (it is made once per cycle while time passes: an
// ostringstream here was a tenth of the checker's time).
std::string key_of(const sim::Cell& c) {
  const core::SupervisorOut& o = c.out();
  const sim::CellView& v = c.view();
  const core::SafetyInputs& in = c.safety_inputs();
  const core::RawInputs& r = c.raw_inputs_of_last_cycle();
  std::string k;
  k.reserve(96);
  const auto put = [&k](auto x) {  // the value's bytes
    const auto* b = reinterpret_cast<const char*>(&x);
    k.append(b, sizeof x);
  };
  put(c.leaf());
  put(o.alarms);
  put(o.mode);
  put(o.arming_step);
  put(v.injected);
  put(o.safety.checksum);
  put(o.brake_test.axis);  // SPEC §12: which axis is tested, the latest result, due/required
  put(o.brake_test.since_start);
  put(o.brake_test.last);
  k.push_back(o.brake_test.required ? '1' : '0');
  k.push_back(o.brake_test.due ? '1' : '0');
  for (bool b : {o.t2_confirmed, o.motion.fault_reset, o.brakes_release, r.estop_a, r.estop_b, r.gate_a, r.gate_b,
                 r.enable_a, r.enable_b, r.enable_panic, r.mode_auto, r.mode_t1, r.mode_t2, r.reset_button,
                 in.estop_pressed, in.gate_open, in.enable_ok, in.mode_invalid, in.estop_discrepancy,
                 in.gate_discrepancy, in.enable_discrepancy, v.contactor_closed, v.fieldbus_ok, o.safety.validated,
                 o.safety.recovery, o.safety.outside, o.safety.reduced, r.reduced_a, r.reduced_b,
                 in.reduced_requested, r.field_outer_a, r.field_outer_b, r.field_inner_a, r.field_inner_b,
                 in.field_outer_interrupted, in.field_inner_interrupted, r.separation_valid,
                 o.safety.ssm && o.safety.v_allowed_mm_s > 0.0F}) {
    k.push_back(b ? '1' : '0');
  }
  put(in.enable);
  put(r.separation_mm);
  bool moving = false;
  for (std::size_t i = 0; i < 6; ++i) {
    put(core::cia402::decode(v.statusword[i]));
    k.push_back(v.brake_released[i] ? '1' : '0');
    moving = moving || !(std::fabs(v.velocities_rad_s[i]) < 0.01F);
  }
  k.push_back(moving ? '1' : '0');
  return k;
}

class Checker {
 public:
  Checker(const CheckOptions& o, CheckStats& s) : opt_(o), stats_(s), actions_(parse_actions()) {}
  int run();
  std::string replay(const scenario::Scenario& s, std::size_t extra, std::string& error);

 private:
  bool step(Node& n, const Node* baseline_of, std::uint32_t cmd_seq, Violation& v);
  bool apply(Node& n, std::size_t action, Violation& v);
  bool apply_directive(Node& n, const scenario::Directive& d, Violation& v);
  bool run_seed(const Seed& seed, Node& n, Violation& v);
  void report(std::size_t trail, const std::string& line, core::Cycle t, const Violation& v, std::size_t config);
  bool limits(Node& n, const core::SupervisorOut& before, bool reset_ok, Violation& v);
  bool collaborative(Node& n, const core::SupervisorOut& before, bool reset_ok, Violation& v);
  bool frozen_pair(const Node& n, std::string& lines, Violation& v);
  [[nodiscard]] std::uint8_t channels() const noexcept { return opt_.pair ? 2U : 1U; }

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
  reference::Geometry geo{};  // the checker's configurations have no zones and no orientation limit
  geo.tcp_speed_mm_s = o.safety.tcp_speed_mm_s;  // the measured TCP speed, judged by the reference itself
  // SPEC §11: the force the core's model reads from the drives' torques (its agreement with
  // the arm's dynamics is test_collision's); what it means, rule 8, the reference judges.
  geo.contact_force_n = o.safety.contact_force_n;
  t1_points(n.cell->feedback(), configurations()[n.lim.config].loaded.limits.tcp_mm, geo);
  n.ref.step(in, n.cell->feedback(), cmds, taken, r, geo);
  stats_.checks += 12;

  const bool powered_state = o.state == State::ARMING || o.state == State::OPERATIONAL || o.state == State::STOPPING;
  const bool any_power = o.contactor || o.drives_enable || o.brakes_release;
  if (any_power && !powered_state) {
    v = {"power only in ARMING, OPERATIONAL or STOPPING", to_string(o.state), "contactor=open drives=disabled brakes=engaged", t};
    return false;
  }
  if (opt_.break_invariant && !opt_.pair && in.estop_pressed && o.state != State::IDLE) {
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
    const bool engage_cmd = !before.brakes_release || before.brake_test_axis == i + 1U;  // SPEC §12: one by the test
    n.watch.brake[i] = (engage_cmd && fb.brake_released[i]) ? n.watch.brake[i] + 1U : 0U;
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
  // SPEC §11's automatic resume is the one motion without a command: invariant 14 judges it.
  const core::CollaborativeLimits& co = configurations()[n.lim.config].loaded.limits.collaborative;
  const bool auto_resume = co.enabled && co.auto_resume && before.sub == Sub::AUTO_PAUSED && o.sub == Sub::AUTO_RUNNING;
  if (motion_sub && o.sub != before.sub && !motion_ok && !auto_resume) {
    v = {"no motion sub-state without a motion command accepted in that cycle", to_string(o.sub),
         "sub=" + std::string(to_string(before.sub)), t};
    return false;
  }
  if (!limits(n, before, reset_ok, v)) {
    return false;
  }
  if (!collaborative(n, before, reset_ok, v)) {
    return false;
  }
  // SPEC §12: 16. a brake test that fails (BRAKE_TEST_FAILED raised in a cycle begun in
  // BRAKE_TEST) ends OPERATIONAL in that cycle (rule 10's Cat 1, or a higher rule's stop);
  // 17. never armed in AUTO while the brake test is required (overdue, never passed, failed);
  // 18. the brake test starts only at standstill.
  const bool bt_failed_now = (o.alarms_raised & core::bit(core::AlarmId::BRAKE_TEST_FAILED)) != 0U;
  if (bt_failed_now && (before.sub != Sub::BRAKE_TEST || o.state == State::OPERATIONAL)) {
    v = {"BRAKE_TEST_FAILED only from BRAKE_TEST, and a stop in that cycle (rule 10)", to_string(o.state),
         "state=STOPPING stop=CAT1", t};
    return false;
  }
  if (before.state == State::IDLE && o.state == State::ARMING && in.mode == core::Mode::AUTO && before.brake_test.required) {
    v = {"never armed in AUTO while the brake test is required", "ARMING", "reply=BRAKE_TEST_REQUIRED state=IDLE", t};
    return false;
  }
  if (o.sub == Sub::BRAKE_TEST && before.sub != Sub::BRAKE_TEST && !o.at_standstill) {
    v = {"the brake test starts only at standstill", "BRAKE_TEST", "sub=" + std::string(to_string(before.sub)), t};
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
               r.alarms == o.alarms && r.reply_count == o.reply_count && r.brake_test_axis == o.brake_test_axis;
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
    if (r.brake_test_axis != o.brake_test_axis) d << " brake_test_axis " << int(o.brake_test_axis) << "/" << int(r.brake_test_axis);
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

// SPEC §10, from the outside (the checker's own measure of the joints, its own record of
// validation), after every cycle:
// 10. never ARMING or OPERATIONAL in AUTO or T2 with a configuration not validated;
// 11. a safe limit violated with power on (a joint newly outside its range, or further
//     outside than its best since power came on, or a joint faster than its limit) is a
//     Cat 0 in that cycle: power off, IDLE (or a higher rule's state), the alarm raised;
// 12. power stays on only while no joint is worse than its best since power came on
//     (recovery lets only motion that reduces a violation), and a SPEC §10 alarm, once
//     latched, leaves only with a reset answered OK.
bool Checker::limits(Node& n, const core::SupervisorOut& before, bool reset_ok, Violation& v) {
  const core::SupervisorOut& o = n.cell->out();
  const core::SafetyInputs& in = n.cell->safety_inputs();
  const core::Feedback& fb = n.cell->feedback();
  const Configuration& cfg = configurations()[n.lim.config];
  const core::SafetyLimits& l = cfg.loaded.limits;
  const core::Cycle t = v.t;
  for (std::size_t i = 0; i < o.reply_count; ++i) {
    const core::Reply& rp = o.replies[i];
    if (rp.seq == n.lim.validate_seq && n.lim.validate_seq != 0U) {
      if (rp.result == core::Result::OK && n.lim.validate_code != l.checksum) {
        v = {"validate_config with a wrong code changes nothing", "answered OK", "reply=CHECKSUM_MISMATCH", t};
        return false;
      }
      n.lim.validated = n.lim.validated || rp.result == core::Result::OK;
      n.lim.validate_seq = 0;
    }
  }
  const bool powered_before = before.state == State::ARMING || before.state == State::OPERATIONAL ||
                              before.state == State::STOPPING;
  const bool any_power = o.contactor || o.drives_enable || o.brakes_release;
  const bool armed = o.state == State::ARMING || o.state == State::OPERATIONAL;
  if (armed && (in.mode == core::Mode::AUTO || in.mode == core::Mode::T2) && !n.lim.validated) {
    v = {"never ARMING or OPERATIONAL in AUTO or T2 with a configuration not validated", to_string(o.state),
         "state=IDLE", t};
    return false;
  }
  const auto cat0 = [&](core::AlarmId a, const std::string& what) {
    const bool right_state = o.state == State::IDLE || o.state == State::ESTOP_ACTIVE || o.state == State::ERROR_LOCKOUT;
    if (!right_state || any_power || o.stop != core::StopCat::CAT0 || (o.alarms & core::bit(a)) == 0U) {
      v = {"a safe limit violated with power on => Cat 0 to IDLE in that cycle, alarm latched", what,
           "state=IDLE stop=CAT0 contactor=open alarm=" + std::string(to_string(a)), t};
      return false;
    }
    return true;
  };
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    const float out = joint_outside(l, i, fb.drive[i].position_rad);
    if (!powered_before) {
      n.lim.best[i] = out;  // found without power: the reference point of a recovery
      continue;
    }
    const bool newly = out > 0.0F && n.lim.best[i] <= 0.0F;
    const bool worse = out > 0.0F && out > n.lim.best[i] + core::kWorseJointRad;
    if (newly || worse) {
      if (any_power) {
        v = {"power stays on only while no limit gets worse (recovery only lets motion that reduces it)",
             "axis " + std::to_string(i + 1U) + (newly ? " left its range" : " moved further outside"), "contactor=open", t};
        return false;
      }
      if (!cat0(core::AlarmId::JOINT_LIMIT, "axis " + std::to_string(i + 1U) + " outside its range")) return false;
    }
    n.lim.best[i] = (out < n.lim.best[i]) ? out : n.lim.best[i];
    const float w = fb.drive[i].velocity_rad_s;
    if (!((w < 0.0F ? -w : w) <= l.joints[i].max_speed_rad_s) &&
        !cat0(core::AlarmId::SPEED_LIMIT, "axis " + std::to_string(i + 1U) + " faster than its limit")) {
      return false;
    }
  }
  for (core::AlarmId a : {core::AlarmId::JOINT_LIMIT, core::AlarmId::ZONE_VIOLATION, core::AlarmId::ORIENTATION_LIMIT,
                          core::AlarmId::SPEED_LIMIT}) {
    if ((before.alarms & core::bit(a)) != 0U && (o.alarms & core::bit(a)) == 0U && !reset_ok) {
      v = {"a SPEC §10 alarm stays latched until a reset answered OK", to_string(a) + std::string(" cleared"),
           "alarm=" + std::string(to_string(a)), t};
      return false;
    }
  }
  return true;
}

// SPEC §11, from the outside, after every cycle (with collaborative operation on, in AUTO):
// 13. never AUTO_RUNNING with the inner field interrupted (rule 9 acts in the cycle that
//     reads it), and start / resume are never accepted then;
// 14. AUTO_PAUSED becomes AUTO_RUNNING without a resume only once both fields have been
//     clear for resume_delay_ms (auto_resume on);
// 15. power stays on only while the TCP has not been above v_allowed + 5 % for longer than
//     T_r, and then SEPARATION_VIOLATED is raised; once latched it leaves only with a reset.
bool Checker::collaborative(Node& n, const core::SupervisorOut& before, bool reset_ok, Violation& v) {
  const core::SupervisorOut& o = n.cell->out();
  const core::SafetyInputs& in = n.cell->safety_inputs();
  const core::SafetyLimits& l = configurations()[n.lim.config].loaded.limits;
  const core::CollaborativeLimits& c = l.collaborative;
  const core::Cycle t = v.t;
  const std::uint32_t cycle_us = n.cell->config().cycle_us;
  const bool clear = !in.field_outer_interrupted && !in.field_inner_interrupted;
  n.lim.fields_clear = clear ? n.lim.fields_clear + 1U : 0U;
  if (!c.enabled || in.mode != core::Mode::AUTO) {
    n.lim.ssm_over = 0;
    return true;
  }
  if (in.field_inner_interrupted && o.sub == Sub::AUTO_RUNNING) {
    v = {"collaborative, AUTO: never AUTO_RUNNING with the inner field interrupted (rule 9 in the detecting cycle)",
         "AUTO_RUNNING", "sub=AUTO_PAUSED", t};
    return false;
  }
  bool resumed_by_command = false;
  for (std::size_t i = 0; i < o.reply_count; ++i) {
    const auto id = static_cast<core::CommandId>(o.replies[i].cmd);
    resumed_by_command = resumed_by_command || (id == core::CommandId::resume && o.replies[i].result == core::Result::OK);
  }
  if (before.sub == Sub::AUTO_PAUSED && o.sub == Sub::AUTO_RUNNING && !resumed_by_command &&
      (!c.auto_resume || n.lim.fields_clear <= core::ms_to_cycles(c.resume_delay_ms, cycle_us))) {
    v = {"AUTO_PAUSED -> AUTO_RUNNING without resume only after both fields clear for resume_delay_ms, auto_resume on",
         "resumed after " + std::to_string(n.lim.fields_clear) + " clear cycles", "sub=AUTO_PAUSED", t};
    return false;
  }
  if (c.ssm_enabled) {
    const bool over = !(o.safety.tcp_speed_mm_s <= o.safety.v_allowed_mm_s * 1.05F);
    n.lim.ssm_over = over ? n.lim.ssm_over + 1U : 0U;
    const auto reaction = static_cast<core::Cycle>(std::llround(static_cast<double>(c.ssm.reaction_s) * 1.0e6)) / cycle_us;
    const bool powered = o.contactor || o.drives_enable || o.brakes_release;
    const bool was_powered = before.state == State::ARMING || before.state == State::OPERATIONAL ||
                             before.state == State::STOPPING;
    if (was_powered && n.lim.ssm_over > reaction + 1U &&
        (powered || (o.alarms & core::bit(core::AlarmId::SEPARATION_VIOLATED)) == 0U)) {
      v = {"TCP above v_allowed + 5 % for longer than T_r => SEPARATION_VIOLATED, power off",
           "over for " + std::to_string(n.lim.ssm_over) + " cycles", "alarm=SEPARATION_VIOLATED contactor=open", t};
      return false;
    }
  }
  const core::AlarmMask sv = core::bit(core::AlarmId::SEPARATION_VIOLATED);
  if ((before.alarms & sv) != 0U && (o.alarms & sv) == 0U && !reset_ok) {
    v = {"SEPARATION_VIOLATED stays latched until a reset answered OK", "cleared", "alarm=SEPARATION_VIOLATED", t};
    return false;
  }
  return true;
}

bool Checker::apply(Node& n, std::size_t action, Violation& v) {
  ++stats_.transitions;
  if (action == kValidateRight) {  // the operator confirms the active checksum
    char line[64];
    std::snprintf(line, sizeof line, "@0 cmd validate_config %08X\n",
                  static_cast<unsigned>(configurations()[n.lim.config].loaded.limits.checksum));
    const scenario::ParseResult p = scenario::parse(line, "check");
    return apply_directive(n, p.scenario.steps.at(0).what, v);
  }
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
  Node base{std::make_unique<sim::Cell>(*n.cell), n.ref, n.pending, n.trail, n.watch, n.lim};
  Violation ignored;
  step(base, nullptr, 0, ignored);
  core::Command cmd = c.command;
  cmd.seq = seq_++;
  if (n.cell->submit(cmd) != core::Result::OK) return true;  // QUEUE_FULL is its answer
  n.pending.emplace_back(cmd.seq, n.cell->now());
  if (cmd.id == static_cast<std::uint8_t>(core::CommandId::validate_config)) {
    n.lim.validate_seq = cmd.seq;
    n.lim.validate_code = cmd.code;
  }
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

void Checker::report(std::size_t trail, const std::string& line, core::Cycle t, const Violation& v, std::size_t config) {
  std::vector<const Trail*> path;
  const Trail last{trail, line, t};
  path.push_back(&last);
  for (std::size_t i = trail; i != 0; i = trails_[i].parent) {
    path.push_back(&trails_[i]);
  }
  std::ostringstream scn;
  scn << "# Counterexample found by `safestate check`: " << v.invariant << "\n# found: " << v.detail << "\n";
  const Configuration& cfg = configurations()[config];
  if (cfg.file[0] != '\0') {  // the configuration beside it, as `config safety=` reads it
    std::ofstream(opt_.out_dir + "/" + cfg.file) << cfg.text << "\n";
    scn << "config safety=" << cfg.file;
    if (cfg.validated) scn << " validated=" << cfg.loaded.checksum;
    scn << "\n";
  }
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

// A scenario's lines played as the exploration plays a seed's (one directive per cycle at
// its time), then `extra` cycles of time passing, every invariant and the reference checked.
std::string Checker::replay(const scenario::Scenario& s, std::size_t extra, std::string& error) {
  std::size_t config = 0;
  if (s.safety.has_value()) {
    config = configurations().size();
    for (std::size_t i = 0; i < configurations().size(); ++i) {
      if (configurations()[i].loaded.limits.checksum == s.safety->checksum) config = i;
    }
    if (config == configurations().size()) {
      error = "its safety configuration is none of the checker's (see `safestate check`'s configurations)";
      return {};
    }
  }
  const Configuration& cfg = configurations()[config];
  reference::Limits rl = ref_limits(cfg, s.config.cycle_us);
  rl.validated = s.safety_validated;
  Node n{std::make_unique<sim::Cell>(s.config, nullptr, s.channels), reference::Supervisor{core::to_timing(s.config), rl},
         {}, 0};
  n.cell->configure_limits(cfg.loaded.limits, s.safety_validated);
  n.lim.config = config;
  n.lim.validated = s.safety_validated;
  Violation v;
  const auto broke = [&v] {
    return v.invariant + " (" + v.detail + ") at cycle " + std::to_string(v.t);
  };
  for (const scenario::Step& st : s.steps) {
    if (std::holds_alternative<scenario::ExpectStep>(st.what)) continue;  // safestate replay's
    if (std::holds_alternative<scenario::PersonStep>(st.what)) {
      error = "line " + std::to_string(st.line) + ": the checker has no person";
      return {};
    }
    while (n.cell->now() < st.t) {
      if (!step(n, nullptr, 0, v)) return broke();
    }
    if (!apply_directive(n, st.what, v)) return broke();
  }
  const core::Cycle end = s.cycles + static_cast<core::Cycle>(extra);
  while (n.cell->now() < end) {
    if (!step(n, nullptr, 0, v)) return broke();
  }
  return {};
}

// SPEC §14 (issue 36 item 8): one channel frozen at this configuration, each demand after it.
// A stalled channel's outputs stay as it last wrote them (its contactor too); the other must
// find it lost and open its own contactor (K1: A, K2: B) within cross_check_cycles + 1
// cycles, whatever the demand, and be in a safe state. `lines`: the fault and the demand as
// .scn lines for a counterexample (after the configuration's trail).
bool Checker::frozen_pair(const Node& n, std::string& lines, Violation& v) {
  if (!opt_.pair || !(n.cell->contactor_command(0) || n.cell->contactor_command(1))) {
    return true;  // one channel, or nothing to open
  }
  static const std::vector<std::pair<std::string, scenario::Directive>> demands = [] {
    std::vector<std::pair<std::string, scenario::Directive>> d;
    for (const char* t : {"", "in estop=pressed", "in gate=open", "in enable=released", "fault drive 2 runaway"}) {
      const std::string text(t);
      d.emplace_back(text, text.empty() ? scenario::Directive{scenario::InputStep{}}
                                        : scenario::parse("@0 " + text + "\n", "check").scenario.steps.at(0).what);
    }
    return d;
  }();
  const core::Cycle t = n.cell->now();
  // --break-invariant (testing the checker): one cycle, too few for any cross-check.
  const core::Cycle bound =
      opt_.break_invariant ? 1U : static_cast<core::Cycle>(n.cell->config().cross_check_cycles) + 1U;
  for (std::size_t x = 0; x < 2U; ++x) {
    const std::size_t other = 1U - x;
    const char* name = (x == 0U) ? "A" : "B";
    for (const auto& [text, what] : demands) {
      sim::Cell c(*n.cell);
      c.inject(vocab::Fault{vocab::FaultKind::channel_stall, static_cast<std::uint8_t>(x + 1U), 0});
      if (const auto* in = std::get_if<scenario::InputStep>(&what)) {
        scenario::apply(*in, c.inputs());
      } else if (const auto* f = std::get_if<scenario::FaultStep>(&what)) {
        c.inject(f->fault);
      }
      for (core::Cycle i = 0; i < bound; ++i) {
        c.step();
        ++stats_.cycles;
      }
      ++stats_.frozen;
      ++stats_.checks;
      // The deciding channel opens its contactor in the cycle it decides; its supervisor names
      // the lockout in the next (SPEC §14; controller::Cell::step).
      const bool open = !c.contactor_command(other);
      core::Leaf leaf = c.channel(other).leaf();
      if (open) {
        c.step();
        ++stats_.cycles;
        leaf = c.channel(other).leaf();
      }
      const bool safe_state = leaf == core::Leaf::ERROR_LOCKOUT || leaf == core::Leaf::ESTOP_ACTIVE;
      if (!open || !safe_state) {
        const char* ch = (other == 0U) ? "a" : "b";
        lines = std::string("fault channel ") + name + " stall" + (text.empty() ? "" : "\n@" + std::to_string(t) + " " + text);
        v = {std::string("one channel frozen (channel ") + name + " stall), every demand: the other's contactor open "
                 "within cross_check_cycles + 1 cycles and the other in ERROR_LOCKOUT or ESTOP_ACTIVE the cycle after",
             std::string("channel ") + (other == 0U ? "A" : "B") + " in " + core::to_string(leaf) +
                 (open ? "" : ", its contactor still commanded closed"),
             open ? std::string("channel.") + ch + "=ERROR_LOCKOUT"
                  : std::string("contactor.") + (other == 0U ? "k1" : "k2") + "=open",
             open ? t + bound : t + bound - 1U};  // the fault at t, then cycles t, t + 1, ...
        return false;
      }
    }
  }
  return true;
}

int Checker::run() {
  trails_.push_back(Trail{0, "", 0});  // the root
  std::unordered_set<std::string> seen;
  std::vector<Node> frontier;
  for (const Seed& sd : seeds()) {
    const Configuration& cfg = configurations()[sd.config];
    const core::Config cc{};
    Node n{std::make_unique<sim::Cell>(cc, nullptr, channels()),
           reference::Supervisor{core::to_timing(cc), ref_limits(cfg, cc.cycle_us)}, {}, 0};
    n.cell->configure_limits(cfg.loaded.limits, cfg.validated);
    n.lim.config = sd.config;
    n.lim.validated = cfg.validated;
    Violation v;
    if (!run_seed(sd, n, v)) {
      report(n.trail, "", n.cell->now(), v, n.lim.config);
      return 1;
    }
    std::string lines;
    if (!frozen_pair(n, lines, v)) {
      report(n.trail, lines, n.cell->now(), v, n.lim.config);
      return 1;
    }
    if (seen.insert(key_of(*n.cell)).second) {
      frontier.push_back(std::move(n));
    }
  }
  stats_.configurations = frontier.size();
  // Every configuration explores the vocabulary and the reduced input; the seeds with a
  // configuration of their own (a limit within reach, recovery, not validated) also the
  // rest of SPEC §10's actions. That keeps the checker's time within a few seconds of
  // what it was without SPEC §10 (docs/verification.md).
  if (action_texts()[kFirstLimitAction] != "in reduced=reduced") {
    std::fprintf(stderr, "safestate check: kFirstLimitAction is stale\n");
    return 2;
  }
  std::vector<std::size_t> base;
  for (std::size_t i = 0; i < kFirstLimitAction + kLimitActionsEverywhere; ++i) base.push_back(i);
  base.push_back(kWaitOne);
  base.push_back(kWaitChange);
  std::vector<std::size_t> all = base;
  for (std::size_t i = kFirstLimitAction + kLimitActionsEverywhere; i < kFirstCollabAction; ++i) all.push_back(i);
  all.push_back(kValidateRight);
  std::vector<std::size_t> collab = base;  // SPEC §11's seeds: the vocabulary and the fields
  for (std::size_t i = kFirstCollabAction; i < action_texts().size(); ++i) collab.push_back(i);
  if (action_texts()[kFirstCollabAction] != "in field.inner=interrupted") {
    std::fprintf(stderr, "safestate check: kFirstCollabAction is stale\n");
    return 2;
  }

  bool cut = false;
  for (std::size_t depth = 0; depth < opt_.max_depth && !frontier.empty(); ++depth) {
    const bool last = depth + 1U == opt_.max_depth;
    std::vector<Node> next;
    for (Node& n : frontier) {
      std::vector<std::size_t> acts = (n.lim.config == 0U) ? base : ((n.lim.config == 3U) ? collab : all);
      if (n.cell->out().state == State::BOOT || n.cell->raw_inputs_of_last_cycle().reset_button) {
        acts.push_back(kWaitLong);
      }
      for (std::size_t a : acts) {
        Node child{std::make_unique<sim::Cell>(*n.cell), n.ref, n.pending, n.trail, n.watch, n.lim};
        const core::Cycle t = child.cell->now();
        std::string line = (a < action_texts().size()) ? action_texts()[a] : std::string();
        if (a == kValidateRight) {
          char code[16];
          std::snprintf(code, sizeof code, "%08X",
                        static_cast<unsigned>(configurations()[n.lim.config].loaded.limits.checksum));
          line = std::string("cmd validate_config ") + code;
        }
        Violation v;
        if (!apply(child, a, v)) {
          report(n.trail, line, t, v, n.lim.config);
          stats_.max_depth = depth + 1;
          return 1;
        }
        if (seen.insert(key_of(*child.cell)).second) {
          trails_.push_back(Trail{n.trail, line, t});
          child.trail = trails_.size() - 1U;
          ++stats_.configurations;
          std::string frozen_lines;
          if (!frozen_pair(child, frozen_lines, v)) {
            report(child.trail, frozen_lines, child.cell->now(), v, n.lim.config);
            stats_.max_depth = depth + 1;
            return 1;
          }
          // Kept only to be explored further: at the last depth a configuration is counted
          // (and its key merges the others), but its cell is not stored (a third of the
          // memory of a run was the last frontier, never used).
          if (!last && stats_.configurations < opt_.max_configs) {
            next.push_back(std::move(child));
          } else if (!last) {
            ++stats_.dropped;
          } else {
            cut = true;  // found at the depth bound: there may be more beyond it
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
  stats_.complete = frontier.empty() && !cut && stats_.dropped == 0U;
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
  if (stats.dropped > 0U) {
    std::printf("%zu configurations found beyond --max-configs %zu were not explored further\n", stats.dropped,
                opt.max_configs);
  }
  if (opt.pair) {
    std::printf("the pair (SPEC 14): %zu runs with one channel frozen before a demand (2 channels x 5 demands at every "
                "configuration with a contactor closed)%s\n",
                stats.frozen, rc == 0 ? ": the other opened its contactor in each" : "");
  }
  return rc;
}

std::string replay_checked(const std::string& scn_text, const std::string& file_name, std::size_t extra,
                           std::string& error) {
  const scenario::ParseResult p = scenario::parse(scn_text, file_name);
  if (!p.ok()) {
    error = p.error->text();
    return {};
  }
  const CheckOptions opt{};
  CheckStats stats;
  Checker c(opt, stats);
  return c.replay(p.scenario, extra, error);
}

int replay_main(const std::string& file, std::size_t extra) {
  std::ifstream in(file);
  if (!in) {
    std::fprintf(stderr, "safestate check: cannot read %s\n", file.c_str());
    return 2;
  }
  std::stringstream text;
  text << in.rdbuf();
  std::string error;
  const std::string broke = replay_checked(text.str(), file, extra, error);
  if (!error.empty()) {
    std::fprintf(stderr, "safestate check: %s: %s\n", file.c_str(), error.c_str());
    return 2;
  }
  if (!broke.empty()) {
    std::printf("VIOLATION replaying %s: %s\n", file.c_str(), broke.c_str());
    return 1;
  }
  std::printf("%s: every invariant held and the core agreed with the reference in every cycle\n", file.c_str());
  return 0;
}

}  // namespace safestate::check

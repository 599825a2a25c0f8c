// Replays a parsed scenario against a fresh simulated cell, cycle by cycle.
//
// Per cycle T: apply every in/cmd/fault at T in file order, run the cycle, collect the
// replies, then check every expect at T and every range covering T. Everything the
// loop needs was computed by the parser or is allocated before the first cycle (the
// cell, one flag per step, the list of open ranges), so with tracing off a cycle never
// allocates; a message string is built only when an expect fails.
#include <algorithm>
#include <array>
#include <charconv>
#include <optional>
#include <ostream>
#include <string>
#include <variant>
#include <vector>

#include "safestate/core/alarms.hpp"
#include "safestate/core/cia402.hpp"
#include "safestate/core/describe.hpp"
#include "safestate/motion/motion_controller.hpp"
#include "safestate/scenario/scenario.hpp"
#include "brake_keys.hpp"
#include "channel_keys.hpp"
#include "person_keys.hpp"
#include "safety_keys.hpp"
#include "trace.hpp"

namespace safestate::scenario {

namespace {

// The latest command sent from a `cmd` line (not the reset button), for `reply=`.
struct LatestCommand {
  bool sent = false;
  bool answered = false;
  std::uint32_t seq = 0;
  core::Result result = core::Result::OK;
};

// The latest reply per command name (`reply.CMD=`), and the reset button's.
using LatestByCommand = std::array<LatestCommand, core::kCommandCount>;

struct Observed {
  const core::SupervisorOut& out;
  const core::SafetyLimits& limits;
  float tcp_speed;
  const LatestCommand& latest;
  const sim::Cell& cell;
  const LatestByCommand& by_cmd;
  const LatestCommand& button;
};

// Names written into a fixed buffer: no allocation while an expect holds.
using NameBuf = std::array<char, 32>;

std::string_view cause_signal(const core::SupervisorOut& out, NameBuf& buf) noexcept {
  if (out.cause.kind == core::CauseKind::none) {
    return "-";
  }
  return core::signal_name(out.cause.detail, buf.data(), buf.size());
}

const LatestCommand& reply_of(const Expectation& e, const Observed& o) noexcept {
  return (e.axis == kResetButtonReply) ? o.button : o.by_cmd[e.axis % core::kCommandCount];
}

bool reply_is(const LatestCommand& l, std::uint8_t expected) noexcept {
  if (expected == kPendingReply) {
    return l.sent && !l.answered;
  }
  return l.sent && l.answered && (static_cast<std::uint8_t>(l.result) == expected);
}

std::size_t axis_index(const Expectation& e) noexcept { return static_cast<std::size_t>(e.axis - 1U) % core::kAxes; }

float abs_speed(float v) noexcept { return (v < 0.0F) ? -v : v; }

template <typename E>
bool is(E actual, std::uint8_t expected) noexcept {
  return static_cast<std::uint8_t>(actual) == expected;
}

bool alarm_active(const core::SupervisorOut& out, std::uint8_t id) noexcept {
  return (out.alarms & core::bit(static_cast<core::AlarmId>(id))) != 0U;
}

// The keys of "More keys, faults and settings".
bool holds_more(const Expectation& e, const Observed& o) noexcept {
  const core::SupervisorOut& out = o.out;
  const sim::CellView& v = o.cell.view();
  NameBuf buf{};
  switch (e.key) {
    case ExpectKey::cause: return e.name == core::cause_name(out.cause);
    case ExpectKey::cause_signal: return e.name == cause_signal(out, buf);
    case ExpectKey::alarm_number: return core::kAlarms[e.value % core::kAlarmCount].number == e.number;
    case ExpectKey::alarm_detail: {
      const auto id = static_cast<core::AlarmId>(e.value);
      return alarm_active(out, e.value) &&
             e.name == core::limit_detail_name(o.cell.alarms().detail(id), o.limits, buf.data(), buf.size());
    }
    case ExpectKey::mode_requested: return is(out.mode_requested, e.value);
    case ExpectKey::axis_state: return v.axis_code[axis_index(e)] == e.value;
    case ExpectKey::axis_cia402: return is(core::cia402::decode(v.statusword[axis_index(e)]), e.value);
    case ExpectKey::axis_controlword: return v.controlword[axis_index(e)] == e.number;
    case ExpectKey::axis_speed:
      return compare(static_cast<double>(abs_speed(v.velocities_rad_s[axis_index(e)])), e.cmp, e.limit);
    case ExpectKey::point_speed: return compare(static_cast<double>(v.max_point_speed_mm_s), e.cmp, e.limit);
    case ExpectKey::reply_cmd: return reply_is(reply_of(e, o), e.value);
    case ExpectKey::standstill: return out.at_standstill == (e.value != 0U);
    case ExpectKey::t2_confirmed: return out.t2_confirmed == (e.value != 0U);
    case ExpectKey::owner: return out.pendant_owner == (e.value != 0U);
    default:
      if (safety_keys::is_safety_key(e.key)) {
        return safety_keys::holds(e, out, v);
      }
      if (brake_keys::is_brake_key(e.key)) {
        return brake_keys::holds(e, out);
      }
      if (channel_keys::is_channel_key(e.key)) {
        return channel_keys::holds(e, o.cell);
      }
      break;  // replies: counted by the runner over the window
  }
  return false;
}

bool holds(const Expectation& e, const Observed& o) noexcept {
  const core::SupervisorOut& out = o.out;
  switch (e.key) {
    case ExpectKey::state: return is(out.state, e.value);
    case ExpectKey::sub: return is(out.sub, e.value);
    case ExpectKey::mode: return is(out.mode, e.value);
    case ExpectKey::stop: return is(out.stop, e.value);
    case ExpectKey::contactor: return channel_keys::contactor_is(o.cell, e.value != 0U);  // both (SPEC §14)
    case ExpectKey::drives: return out.drives_enable == (e.value != 0U);
    case ExpectKey::brakes: return out.brakes_release == (e.value != 0U);
    case ExpectKey::reset_lamp: return out.reset_lamp == (e.value != 0U);
    case ExpectKey::alarm: return alarm_active(out, e.value);
    case ExpectKey::noalarm: return !alarm_active(out, e.value);
    case ExpectKey::reply:
      if (e.value == kPendingReply) {
        return o.latest.sent && !o.latest.answered;
      }
      return o.latest.sent && o.latest.answered && is(o.latest.result, e.value);
    case ExpectKey::tcp_speed: return compare(static_cast<double>(o.tcp_speed), e.cmp, e.limit);
    default: return holds_more(e, o);
  }
  return false;
}

std::string alarm_list(core::AlarmMask mask) {
  std::string s = "alarms=[";
  bool first = true;
  for (const core::AlarmInfo& a : core::kAlarms) {
    if ((mask & core::bit(a.id)) != 0U) {
      s += (first ? "" : ",");
      s += a.name;
      first = false;
    }
  }
  return s + "]";
}

std::string reply_found(const LatestCommand& latest) {
  if (!latest.sent) {
    return "reply=none";
  }
  return latest.answered ? std::string("reply=") + core::to_string(latest.result) : std::string("reply=pending");
}

std::string speed_found(float v) {
  std::array<char, 32> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return "tcp_speed=" + std::string(buf.data(), r.ptr);
}

std::string choice(const char* key, bool v, const char* yes, const char* no) {
  return std::string(key) + "=" + (v ? yes : no);
}

std::string number_found(const char* key, double v) {
  std::array<char, 32> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(key) + "=" + std::string(buf.data(), r.ptr);
}

std::string hex_found(const std::string& key, unsigned v) {
  std::array<char, 8> buf{};
  constexpr std::array<char, 16> kHex{'0', '1', '2', '3', '4', '5', '6', '7', '8', '9', 'A', 'B', 'C', 'D', 'E', 'F'};
  for (std::size_t i = 0; i < 4; ++i) {
    buf[i] = kHex[(v >> (12U - 4U * i)) & 0xFU];
  }
  return key + "=0x" + std::string(buf.data(), 4);
}

std::string cia402_name(std::uint16_t sw) {
  std::string n = core::cia402::to_string(core::cia402::decode(sw));
  std::replace(n.begin(), n.end(), ' ', '_');
  return n;
}

std::string found_more(const Expectation& e, const Observed& o) {
  const core::SupervisorOut& out = o.out;
  const sim::CellView& v = o.cell.view();
  NameBuf buf{};
  const std::string axis = "axis." + std::to_string(e.axis);
  const std::string alarm = "alarm." + std::string(core::kAlarms[e.value % core::kAlarmCount].name);
  switch (e.key) {
    case ExpectKey::cause: return std::string("cause=") + core::cause_name(out.cause);
    case ExpectKey::cause_signal: return "cause.signal=" + std::string(cause_signal(out, buf));
    case ExpectKey::alarm_number: return alarm + ".number=" + std::to_string(core::kAlarms[e.value % core::kAlarmCount].number);
    case ExpectKey::alarm_detail:
      if (!alarm_active(out, e.value)) {
        return alarm + " not active, " + alarm_list(out.alarms);
      }
      return alarm + ".detail=" + core::limit_detail_name(o.cell.alarms().detail(static_cast<core::AlarmId>(e.value)),
                                                          o.limits, buf.data(), buf.size());
    case ExpectKey::mode_requested: return std::string("mode_requested=") + core::to_string(out.mode_requested);
    case ExpectKey::axis_state:
      return axis + ".state=" + motion::to_string(static_cast<motion::AxisState>(v.axis_code[axis_index(e)]));
    case ExpectKey::axis_cia402:
      return axis + ".cia402=" + cia402_name(v.statusword[axis_index(e)]) + " (statusword " +
             hex_found("", v.statusword[axis_index(e)]).substr(1) + ")";
    case ExpectKey::axis_controlword: return hex_found(axis + ".controlword", v.controlword[axis_index(e)]);
    case ExpectKey::axis_speed:
      return number_found((axis + ".speed").c_str(), static_cast<double>(abs_speed(v.velocities_rad_s[axis_index(e)])));
    case ExpectKey::point_speed: return number_found("point_speed", static_cast<double>(v.max_point_speed_mm_s));
    case ExpectKey::reply_cmd: {
      const std::string key = (e.axis == kResetButtonReply) ? "reply.reset_button" : "reply." + std::string(core::to_string(static_cast<core::CommandId>(e.axis)));
      const LatestCommand& l = reply_of(e, o);
      return key + "=" + (!l.sent ? "none" : (l.answered ? core::to_string(l.result) : "pending"));
    }
    case ExpectKey::standstill: return choice("standstill", out.at_standstill, "yes", "no");
    case ExpectKey::t2_confirmed: return choice("t2_confirmed", out.t2_confirmed, "yes", "no");
    case ExpectKey::owner: return choice("owner", out.pendant_owner, "pendant", "none");
    default:
      if (safety_keys::is_safety_key(e.key)) {
        return safety_keys::found(e, out, v);
      }
      if (brake_keys::is_brake_key(e.key)) {
        return brake_keys::found(e, out);
      }
      if (channel_keys::is_channel_key(e.key)) {
        return channel_keys::found(e, o.cell);
      }
      break;
  }
  return "?";
}

// What was found, in the same words as the expectation.
std::string found(const Expectation& e, const Observed& o) {
  const core::SupervisorOut& out = o.out;
  switch (e.key) {
    case ExpectKey::state: return std::string("state=") + core::to_string(out.state);
    case ExpectKey::sub: return std::string("sub=") + core::to_string(out.sub);
    case ExpectKey::mode: return std::string("mode=") + core::to_string(out.mode);
    case ExpectKey::stop: return std::string("stop=") + core::to_string(out.stop);
    case ExpectKey::contactor: return channel_keys::contactor_found(o.cell);
    case ExpectKey::drives: return choice("drives", out.drives_enable, "enabled", "disabled");
    case ExpectKey::brakes: return choice("brakes", out.brakes_release, "released", "engaged");
    case ExpectKey::reset_lamp: return choice("reset_lamp", out.reset_lamp, "on", "off");
    case ExpectKey::alarm:
    case ExpectKey::noalarm: return alarm_list(out.alarms);
    case ExpectKey::reply: return reply_found(o.latest);
    case ExpectKey::tcp_speed: return speed_found(o.tcp_speed);
    default: return found_more(e, o);
  }
  return "?";
}

// Steps in time order, each inside the run: what the parser guarantees, checked for
// scenarios built by hand.
bool consistent(const Scenario& s) noexcept {
  for (std::size_t i = 0; i < s.steps.size(); ++i) {
    const Step& st = s.steps[i];
    if (st.t_end < st.t || st.t_end >= s.cycles || (i > 0 && st.t < s.steps[i - 1].t)) {
      return false;
    }
  }
  return true;
}

std::size_t count_ranges(const Scenario& s) noexcept {
  return static_cast<std::size_t>(std::count_if(s.steps.begin(), s.steps.end(), [](const Step& st) {
    return std::holds_alternative<ExpectStep>(st.what) && st.t_end > st.t;
  }));
}

class Runner {
 public:
  [[nodiscard]] std::string links_error() const { return cell_.links_error(); }
  bool connect_links() noexcept { return cell_.connect_links(100); }
  Runner(const Scenario& s, const RunOptions& o)
      : s_(s), opts_(o), cell_(s.config, o.bus, s.channels), failed_(s.steps.size(), 0U), count_(s.steps.size(), 0U) {
    cell_.configure_limits(safety_limits(s), s.safety_validated);
    cell_.configure_brake_test(s.brake_test);
    person_ok_ = cell_.configure_person_sensors(s.person_sensors);
    open_.reserve(count_ranges(s));
    if (o.trace && o.trace_out != nullptr) {
      tracer_.emplace(s, *o.trace_out);
    }
  }

  Summary run() {
    Summary sum;
    sum.expects = s_.expect_lines;
    std::size_t next = 0;
    for (core::Cycle t = 0; t < s_.cycles; ++t) {
      std::size_t end = next;
      while (end < s_.steps.size() && s_.steps[end].t == t) {
        act(s_.steps[end]);
        ++end;
      }
      cell_.step();
      collect_replies();
      replies_now_ += cell_.out().reply_count;
      if (tracer_) {
        tracer_->cycle(t, cell_.out(), cell_.view());
      }
      check_open(t);
      check_new(t, next, end);
      replies_now_ = 0;
      next = end;
      sum.cycles = t + 1;
    }
    sum.failed = failures_ + world_failures_;
    return sum;
  }

 private:
  void act(const Step& step) {
    const bool world = std::holds_alternative<InputStep>(step.what) || std::holds_alternative<FaultStep>(step.what);
    if (world && opts_.world) {
      const auto* f = std::get_if<FaultStep>(&step.what);
      // The controller's own faults (integrity, self-test, program, jog link) stay in the
      // cell; the field's go to the world behind the bus; `clear all` to both.
      if (f != nullptr && controller_side(f->fault.kind)) {
        cell_.inject(f->fault);
        return;
      }
      if (f != nullptr && f->fault.kind == sim::FaultKind::clear_all) {
        cell_.inject(f->fault);
      }
      world_failures_ += opts_.world(step) ? 0U : 1U;
      return;
    }
    if (const auto* in = std::get_if<InputStep>(&step.what)) {
      apply(*in, cell_.inputs());
    } else if (const auto* c = std::get_if<CommandStep>(&step.what)) {
      send(*c);
    } else if (const auto* f = std::get_if<FaultStep>(&step.what)) {
      cell_.inject(f->fault);
    } else if (const auto* p = std::get_if<PersonStep>(&step.what)) {
      // The simulated person feeds the simulated plant, or the world behind the bus where
      // that world has one (the emulated segment: opts_.world); behind a bus without it it
      // cannot act, which fails the run rather than pass it unseen.
      if (opts_.bus != nullptr && opts_.world) {
        world_failures_ += opts_.world(step) ? 0U : 1U;
        return;
      }
      const bool took = person_ok_ && opts_.bus == nullptr && person_keys::apply(*p, cell_);
      world_failures_ += took ? 0U : 1U;
      if (!took && opts_.report != nullptr) {
        *opts_.report << s_.file << ":" << step.line << ": the simulated person cannot act here"
                      << (opts_.bus != nullptr ? " (a real fieldbus: it feeds only the simulated plant)\n" : "\n");
      }
    }
  }

  // SPEC §14: a channel's faults (stall, crash, its own input, its digests, a flipped bit) are the
  // controllers', wherever the field is.
  static bool controller_side(sim::FaultKind k) noexcept {
    return k == sim::FaultKind::integrity || k == sim::FaultKind::selftest_fail ||
           k == sim::FaultKind::program_unload || k == sim::FaultKind::jog_link_drop ||
           k == sim::FaultKind::channel_stall || k == sim::FaultKind::channel_crash ||
           k == sim::FaultKind::channel_input || k == sim::FaultKind::digest_corrupt ||
           k == sim::FaultKind::digest_drop || k == sim::FaultKind::digest_repeat ||
           k == sim::FaultKind::channel_flip;
  }

  void send(const CommandStep& c) {
    const bool jog = c.command.id == static_cast<std::uint8_t>(core::CommandId::jog);
    const bool pendant = c.command.source == static_cast<std::uint8_t>(core::Source::pendant);
    if (jog && pendant && !cell_.jog_link_up()) {
      // `jog_link drop`: sent, but lost on the way: neither delivered nor answered.
      remember(c, LatestCommand{true, false, c.command.seq, core::Result::OK});
      return;
    }
    const core::Result r = cell_.submit(c.command);
    remember(c, LatestCommand{true, r == core::Result::QUEUE_FULL, c.command.seq, r});
    if (r == core::Result::QUEUE_FULL) {
      ++replies_now_;  // the queue's answer, given in this cycle
      if (tracer_) {
        tracer_->queue_full(c);
      }
    }
  }

  void remember(const CommandStep& c, const LatestCommand& l) noexcept {
    latest_ = l;
    if (c.command.id < core::kCommandCount) {
      by_cmd_[c.command.id] = l;
    }
  }

  static void answer(LatestCommand& l, const core::Reply& r) noexcept {
    if (l.sent && !l.answered && r.seq == l.seq) {
      l.answered = true;
      l.result = r.result;
    }
  }

  void collect_replies() noexcept {
    const core::SupervisorOut& out = cell_.out();
    for (std::size_t i = 0; i < out.reply_count && i < out.replies.size(); ++i) {
      const core::Reply& r = out.replies[i];
      if (r.source == static_cast<std::uint8_t>(core::Source::reset_button)) {
        button_ = LatestCommand{true, true, r.seq, r.result};
        continue;
      }
      answer(latest_, r);
      if (r.cmd < core::kCommandCount) {
        answer(by_cmd_[r.cmd], r);
      }
    }
  }

  // Ranges opened at an earlier cycle, then the expects of this cycle (opening ranges).
  void check_open(core::Cycle t) {
    for (const std::size_t i : open_) {
      check(i, t);
    }
    std::erase_if(open_, [this, t](std::size_t i) { return s_.steps[i].t_end <= t || failed_[i] != 0U; });
  }

  void check_new(core::Cycle t, std::size_t first, std::size_t end) {
    for (std::size_t i = first; i < end; ++i) {
      if (!std::holds_alternative<ExpectStep>(s_.steps[i].what)) {
        continue;
      }
      check(i, t);
      if (s_.steps[i].t_end > t && failed_[i] == 0U) {
        open_.push_back(i);  // capacity reserved: no allocation
      }
    }
  }

  // failed_[i]: 0 open, 1 failed, 2 settled (an expect-once that held).
  void check(std::size_t i, core::Cycle t) {
    if (failed_[i] != 0U) {
      return;  // a range reports its first failing cycle only
    }
    const Step& step = s_.steps[i];
    const auto& expect = std::get<ExpectStep>(step.what);
    const Observed o{cell_.out(), safety_limits(s_), cell_.view().tcp_speed_mm_s, latest_, cell_, by_cmd_, button_};
    if (expect.mode == ExpectMode::replies) {
      count_[i] += replies_now_;
      if (t == step.t_end && count_[i] != expect.checks.front().number) {
        fail(i, t, expect.checks.front().text, "replies=" + std::to_string(count_[i]));
      }
      return;
    }
    const bool all = std::all_of(expect.checks.begin(), expect.checks.end(),
                                 [&o](const Expectation& e) { return holds(e, o); });
    if (all && expect.mode == ExpectMode::once) {
      failed_[i] = 2U;  // held once: settled
      return;
    }
    if (all || (expect.mode == ExpectMode::once && t < step.t_end)) {
      return;
    }
    std::string expected;
    std::string actual;
    for (const Expectation& e : expect.checks) {
      if (!holds(e, o)) {
        expected += (expected.empty() ? "" : " ") + e.text;
        actual += (actual.empty() ? "" : " ") + found(e, o);
      }
    }
    if (expect.mode == ExpectMode::once) {
      expected = "once in @" + std::to_string(step.t) + ".." + std::to_string(step.t_end) + ": " + expected;
      actual = "never all at once; at the last cycle " + actual;
    }
    fail(i, t, expected, actual);
  }

  void fail(std::size_t i, core::Cycle t, const std::string& expected, const std::string& actual) {
    failed_[i] = 1U;
    ++failures_;
    if (opts_.report != nullptr) {
      // FILE:LINE: cycle T: expected state=IDLE, found state=STOPPING (failing keys only).
      *opts_.report << s_.file << ':' << s_.steps[i].line << ": cycle " << t << ": expected " << expected
                    << ", found " << actual << '\n';
    }
  }

  const Scenario& s_;
  const RunOptions& opts_;
  sim::Cell cell_;
  LatestCommand latest_{};
  LatestByCommand by_cmd_{};
  LatestCommand button_{};
  std::size_t replies_now_ = 0;       // replies given for this cycle (queue's and core's)
  std::vector<std::uint8_t> failed_;  // per step: this expect line has failed
  std::vector<std::size_t> count_;    // per step: replies counted in its window so far
  std::vector<std::size_t> open_;     // ranges being checked
  std::size_t failures_ = 0;
  std::size_t world_failures_ = 0;  // in/fault steps the world behind the bus refused
  bool person_ok_ = true;  // the scenario's person_fields were taken
  std::optional<Tracer> tracer_;
};

}  // namespace

bool compare(double v, Compare cmp, double limit) noexcept {
  switch (cmp) {
    case Compare::lt: return v < limit;
    case Compare::le: return v <= limit;
    case Compare::gt: return v > limit;
    case Compare::ge: return v >= limit;
  }
  return false;
}

int run(const Scenario& s, const RunOptions& opts, Summary& summary) {
  const core::ConfigError e = core::validate(s.config);
  if (!e.ok()) {
    if (opts.report != nullptr) {
      *opts.report << s.file << ": invalid config " << e.field << ": " << e.reason << '\n';
    }
    return 2;
  }
  if (!consistent(s)) {
    if (opts.report != nullptr) {
      *opts.report << s.file << ": steps out of time order or beyond the end of the run\n";
    }
    return 2;
  }
  Runner r{s, opts};
  if (const std::string why = r.links_error(); !why.empty()) {
    if (opts.report != nullptr) {
      *opts.report << s.file << ": the bus's safety connections are refused: " << why << '\n';
    }
    return 2;
  }
  // Over a bus with the black channel its sessions are opened before cycle 0, as the bus is
  // brought up before it: the scenario's cycles are the cell's from its first step. A bus that
  // did not come up (a scenario about BOOT_FAILED) leaves them connecting: the cell's boot
  // then names what is missing, as it would without this.
  static_cast<void>(r.connect_links());
  summary = r.run();
  return (summary.failed == 0U) ? 0 : 1;
}

}  // namespace safestate::scenario

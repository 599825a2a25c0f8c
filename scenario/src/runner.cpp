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
#include "safestate/scenario/scenario.hpp"
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

struct Observed {
  const core::SupervisorOut& out;
  float tcp_speed;
  const LatestCommand& latest;
};

bool compare(double v, Compare cmp, double limit) noexcept {
  switch (cmp) {
    case Compare::lt: return v < limit;
    case Compare::le: return v <= limit;
    case Compare::gt: return v > limit;
    case Compare::ge: return v >= limit;
  }
  return false;
}

template <typename E>
bool is(E actual, std::uint8_t expected) noexcept {
  return static_cast<std::uint8_t>(actual) == expected;
}

bool alarm_active(const core::SupervisorOut& out, std::uint8_t id) noexcept {
  return (out.alarms & core::bit(static_cast<core::AlarmId>(id))) != 0U;
}

bool holds(const Expectation& e, const Observed& o) noexcept {
  const core::SupervisorOut& out = o.out;
  switch (e.key) {
    case ExpectKey::state: return is(out.state, e.value);
    case ExpectKey::sub: return is(out.sub, e.value);
    case ExpectKey::mode: return is(out.mode, e.value);
    case ExpectKey::stop: return is(out.stop, e.value);
    case ExpectKey::contactor: return out.contactor == (e.value != 0U);
    case ExpectKey::drives: return out.drives_enable == (e.value != 0U);
    case ExpectKey::brakes: return out.brakes_release == (e.value != 0U);
    case ExpectKey::reset_lamp: return out.reset_lamp == (e.value != 0U);
    case ExpectKey::alarm: return alarm_active(out, e.value);
    case ExpectKey::noalarm: return !alarm_active(out, e.value);
    case ExpectKey::reply: return o.latest.sent && o.latest.answered && is(o.latest.result, e.value);
    case ExpectKey::tcp_speed: return compare(static_cast<double>(o.tcp_speed), e.cmp, e.limit);
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

// What was found, in the same words as the expectation.
std::string found(const Expectation& e, const Observed& o) {
  const core::SupervisorOut& out = o.out;
  switch (e.key) {
    case ExpectKey::state: return std::string("state=") + core::to_string(out.state);
    case ExpectKey::sub: return std::string("sub=") + core::to_string(out.sub);
    case ExpectKey::mode: return std::string("mode=") + core::to_string(out.mode);
    case ExpectKey::stop: return std::string("stop=") + core::to_string(out.stop);
    case ExpectKey::contactor: return choice("contactor", out.contactor, "closed", "open");
    case ExpectKey::drives: return choice("drives", out.drives_enable, "enabled", "disabled");
    case ExpectKey::brakes: return choice("brakes", out.brakes_release, "released", "engaged");
    case ExpectKey::reset_lamp: return choice("reset_lamp", out.reset_lamp, "on", "off");
    case ExpectKey::alarm:
    case ExpectKey::noalarm: return alarm_list(out.alarms);
    case ExpectKey::reply: return reply_found(o.latest);
    case ExpectKey::tcp_speed: return speed_found(o.tcp_speed);
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
  Runner(const Scenario& s, const RunOptions& o)
      : s_(s), opts_(o), cell_(s.config, o.bus), failed_(s.steps.size(), 0U) {
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
      if (tracer_) {
        tracer_->cycle(t, cell_.out(), cell_.view());
      }
      check_open(t);
      check_new(t, next, end);
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
      world_failures_ += opts_.world(step) ? 0U : 1U;
      return;
    }
    if (const auto* in = std::get_if<InputStep>(&step.what)) {
      apply(*in, cell_.inputs());
    } else if (const auto* c = std::get_if<CommandStep>(&step.what)) {
      send(*c);
    } else if (const auto* f = std::get_if<FaultStep>(&step.what)) {
      cell_.inject(f->fault);
    }
  }

  void send(const CommandStep& c) {
    const core::Result r = cell_.submit(c.command);
    latest_ = LatestCommand{true, r == core::Result::QUEUE_FULL, c.command.seq, r};
    if (r == core::Result::QUEUE_FULL && tracer_) {
      tracer_->queue_full(c);
    }
  }

  void collect_replies() noexcept {
    const core::SupervisorOut& out = cell_.out();
    for (std::size_t i = 0; i < out.reply_count && i < out.replies.size(); ++i) {
      const core::Reply& r = out.replies[i];
      const bool from_button = r.source == static_cast<std::uint8_t>(core::Source::reset_button);
      if (latest_.sent && !latest_.answered && !from_button && r.seq == latest_.seq) {
        latest_.answered = true;
        latest_.result = r.result;
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

  void check(std::size_t i, core::Cycle t) {
    if (failed_[i] != 0U) {
      return;  // a range reports its first failing cycle only
    }
    const auto& expect = std::get<ExpectStep>(s_.steps[i].what);
    const Observed o{cell_.out(), cell_.view().tcp_speed_mm_s, latest_};
    const bool all = std::all_of(expect.checks.begin(), expect.checks.end(),
                                 [&o](const Expectation& e) { return holds(e, o); });
    if (all) {
      return;
    }
    failed_[i] = 1U;
    ++failures_;
    if (opts_.report != nullptr) {
      report(s_.steps[i], expect, o, t);
    }
  }

  // FILE:LINE: cycle T: expected state=IDLE, found state=STOPPING (failing keys only).
  void report(const Step& step, const ExpectStep& expect, const Observed& o, core::Cycle t) const {
    std::string expected;
    std::string actual;
    for (const Expectation& e : expect.checks) {
      if (!holds(e, o)) {
        expected += (expected.empty() ? "" : " ") + e.text;
        actual += (actual.empty() ? "" : " ") + found(e, o);
      }
    }
    *opts_.report << s_.file << ':' << step.line << ": cycle " << t << ": expected " << expected << ", found "
                  << actual << '\n';
  }

  const Scenario& s_;
  const RunOptions& opts_;
  sim::Cell cell_;
  LatestCommand latest_{};
  std::vector<std::uint8_t> failed_;  // per step: this expect line has failed
  std::vector<std::size_t> open_;     // ranges being checked
  std::size_t failures_ = 0;
  std::size_t world_failures_ = 0;  // in/fault steps the world behind the bus refused
  std::optional<Tracer> tracer_;
};

}  // namespace

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
  summary = r.run();
  return (summary.failed == 0U) ? 0 : 1;
}

}  // namespace safestate::scenario

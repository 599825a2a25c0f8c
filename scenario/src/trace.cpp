// JSON Lines trace of a replay. nlohmann::ordered_json keeps the keys in the order they
// are inserted (the spec's order) and escapes strings, so every line is valid JSON and
// the same run gives the same bytes.
#include "trace.hpp"

#include <cmath>
#include <ostream>
#include <variant>

#include <nlohmann/json.hpp>

#include "safestate/vocab/names.hpp"

namespace safestate::scenario {

namespace {

using Json = nlohmann::ordered_json;

// Compact, and never throws: bytes that are not UTF-8 (a path or a command name written
// in another encoding) become U+FFFD instead of aborting the trace.
std::string dump(const Json& j) { return j.dump(-1, ' ', false, Json::error_handler_t::replace); }

Json name_or_null(const char* name, bool is_null) { return is_null ? Json(nullptr) : Json(name); }

std::int64_t tenths(float v) noexcept {
  const double x = static_cast<double>(v);
  return std::isfinite(x) ? std::llround(x * 10.0) : std::int64_t{-1};
}

Json speed(std::int64_t t) { return (t < 0) ? Json(nullptr) : Json(static_cast<double>(t) / 10.0); }


}  // namespace

TraceSnapshot snapshot(const core::SupervisorOut& out, float tcp_speed_mm_s) noexcept {
  TraceSnapshot s;
  s.state = out.state;
  s.sub = out.sub;
  s.mode = out.mode;
  s.stop = out.stop;
  s.contactor = out.contactor;
  s.drives = out.drives_enable;
  s.brakes = out.brakes_release;
  s.reset_lamp = out.reset_lamp;
  s.tcp_tenths = tenths(tcp_speed_mm_s);
  s.alarms = out.alarms;
  return s;
}

std::string state_line(core::Cycle t, const TraceSnapshot& s) {
  Json j;
  j["t"] = t;
  j["state"] = core::to_string(s.state);
  j["sub"] = name_or_null(core::to_string(s.sub), s.sub == core::Sub::NONE);
  j["mode"] = core::to_string(s.mode);
  j["stop"] = name_or_null(core::to_string(s.stop), s.stop == core::StopCat::NONE);
  j["contactor"] = s.contactor ? "closed" : "open";
  j["drives"] = s.drives ? "enabled" : "disabled";
  j["brakes"] = s.brakes ? "released" : "engaged";
  j["reset_lamp"] = s.reset_lamp ? "on" : "off";
  j["tcp_speed"] = speed(s.tcp_tenths);
  j["alarms"] = vocab::alarm_names(s.alarms);
  return dump(j);
}

std::string reply_line(core::Cycle t, const std::string& cmd, core::Source from, core::Result result) {
  Json r;
  r["cmd"] = cmd;
  r["from"] = core::to_string(from);
  r["result"] = core::to_string(result);
  Json j;
  j["t"] = t;
  j["reply"] = std::move(r);
  return dump(j);
}

std::string file_line(const std::string& path) {
  Json j;
  j["file"] = path;
  return dump(j);
}

std::string Tracer::command_name(const core::Reply& r) const {
  if (r.cmd < core::kCommandCount) {
    return core::to_string(static_cast<core::CommandId>(r.cmd));
  }
  // An unknown command: the name as written in the file (its seq is its line).
  for (const Step& step : scenario_.steps) {
    const auto* c = std::get_if<CommandStep>(&step.what);
    if (c != nullptr && c->command.seq == r.seq && r.seq != 0U) {
      return c->name;
    }
  }
  return "?";
}

// @req SCN-TRACE
void Tracer::cycle(core::Cycle t, const core::SupervisorOut& out, const sim::CellView& view) {
  const TraceSnapshot now = snapshot(out, view.tcp_speed_mm_s);
  if (first_ || !(now == last_)) {
    out_ << state_line(t, now) << '\n';
    last_ = now;
    first_ = false;
  }
  for (const CommandStep* c : queue_full_) {
    out_ << reply_line(t, c->name, static_cast<core::Source>(c->command.source), core::Result::QUEUE_FULL) << '\n';
  }
  queue_full_.clear();
  for (std::size_t i = 0; i < out.reply_count && i < out.replies.size(); ++i) {
    const core::Reply& r = out.replies[i];
    out_ << reply_line(t, command_name(r), static_cast<core::Source>(r.source), r.result) << '\n';
  }
}

}  // namespace safestate::scenario

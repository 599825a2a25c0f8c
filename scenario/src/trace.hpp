// Trace of a replay (`--trace`): JSON Lines, exactly as in spec/scenario-format.md.
// Internal to the scenario module; it allocates freely (it only exists when tracing).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "safestate/core/alarms.hpp"
#include "safestate/core/supervisor.hpp"
#include "safestate/core/types.hpp"
#include "safestate/scenario/scenario.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::scenario {

// What a state line shows; a line is written when any of it changed.
struct TraceSnapshot {
  core::State state = core::State::BOOT;
  core::Sub sub = core::Sub::NONE;
  core::Mode mode = core::Mode::NONE;
  core::StopCat stop = core::StopCat::NONE;
  bool contactor = false;
  bool drives = false;
  bool brakes = false;
  bool reset_lamp = false;
  std::int64_t tcp_tenths = 0;  // tcp_speed in 0.1 mm/s; -1 when not finite
  core::AlarmMask alarms = 0;

  friend bool operator==(const TraceSnapshot&, const TraceSnapshot&) = default;
};

[[nodiscard]] TraceSnapshot snapshot(const core::SupervisorOut& out, float tcp_speed_mm_s) noexcept;

// {"t":..,"state":..,...}: keys in the spec's order, alarms in table order.
[[nodiscard]] std::string state_line(core::Cycle t, const TraceSnapshot& s);
// {"t":..,"reply":{"cmd":..,"from":..,"result":..}}
[[nodiscard]] std::string reply_line(core::Cycle t, const std::string& cmd, core::Source from, core::Result result);
// {"file":PATH}
[[nodiscard]] std::string file_line(const std::string& path);

class Tracer {
 public:
  Tracer(const Scenario& s, std::ostream& out) : scenario_(s), out_(out) {}

  // A command refused by the queue before cycle `t`: QUEUE_FULL is its only reply.
  void queue_full(const CommandStep& c) { queue_full_.push_back(&c); }
  // After cycle `t`: the state line if anything changed, then every reply of the cycle.
  void cycle(core::Cycle t, const core::SupervisorOut& out, const sim::CellView& view);

 private:
  [[nodiscard]] std::string command_name(const core::Reply& r) const;

  const Scenario& scenario_;
  std::ostream& out_;
  TraceSnapshot last_{};
  bool first_ = true;
  std::vector<const CommandStep*> queue_full_;
};

}  // namespace safestate::scenario

// Scenario files (.scn, spec/scenario-format.md): the parser, the runner that replays a
// file against the simulated cell, and `safestate replay`.
//
// Everything a run needs is computed when the file is parsed; the run itself keeps only
// fixed buffers, so that with tracing off it allocates nothing per cycle (a replay of
// 100 cycles and one of 10^6 cycles allocate the same number of times). Strings are
// built only for a failing expect or for the trace.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "safestate/core/config.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/types.hpp"
#include "safestate/sim/cell.hpp"
#include "safestate/vocab/faults.hpp"
#include "safestate/vocab/inputs.hpp"
#include "safestate/vocab/person.hpp"

namespace safestate::scenario {

// ---------------------------------------------------------------------------------------
// What a file says

// The world's vocabulary (vocab/): the contacts, `in` lines, faults and the person.
using vocab::Contact;
using vocab::ContactWrite;
using vocab::InputStep;
using vocab::PersonStep;
using vocab::apply;  // an InputStep onto RawInputs

// `cmd [from=pendant|remote] NAME ARGS...`: the binary record handed to the core, and
// the name as written (for the trace of an unknown command).
struct CommandStep {
  core::Command command{};
  std::string name;
};

// `fault ...`
struct FaultStep {
  vocab::Fault fault{};
};

enum class ExpectKey : std::uint8_t {
  state,
  sub,
  mode,
  stop,
  contactor,
  drives,
  brakes,
  reset_lamp,
  alarm,
  noalarm,
  reply,
  tcp_speed,
  // "More keys, faults and settings" of the format.
  cause,             // name: alarm name, enable_released, servo_off, pause, stop, jog_stop, -
  cause_signal,      // name: estop.a ... brake.N
  alarm_number,      // value: AlarmId, number: expected number
  alarm_detail,      // value: AlarmId, name: expected detail
  mode_requested,    // value: Mode
  axis_state,        // axis, value: motion::AxisState
  axis_cia402,       // axis, value: cia402::DriveState
  axis_controlword,  // axis, number: expected controlword
  axis_speed,        // axis, cmp, limit (rad/s, |measured velocity|)
  point_speed,       // cmp, limit (mm/s, fastest of TCP and link origins)
  reply_cmd,         // axis: CommandId, or kResetButtonReply; value: Result or kPendingReply
  replies,           // number: replies given in the window's cycles (alone on its line)
  standstill,        // value 1 = yes
  t2_confirmed,      // value 1 = yes
  owner,             // value 1 = pendant, 0 = none
  // "Safety configuration, collaborative operation, brake test" (SPEC §10).
  checksum,          // number: the expected checksum (8 hex digits)
  validated,         // value 1 = yes
  reduced,           // value 1 = yes
  recovery,          // value 1 = yes
  joint,             // axis, cmp, limit (degrees, measured position)
  v_allowed,         // cmp, limit (mm/s, SPEC §11 SSM; fails while SSM does not act)
  brake_test,        // value: core::BrakeTestResult, the latest result since start (SPEC §12)
  // "Two channels" (SPEC §14).
  contactor_k1,      // value 1 = closed (channel A's command)
  contactor_k2,      // value 1 = closed (channel B's command)
  channel_state,     // axis: 0 A, 1 B; value: State
};

enum class Compare : std::uint8_t { lt, le, gt, ge };

// `v CMP limit` for the comparing expect keys (speeds, joint.N).
[[nodiscard]] bool compare(double v, Compare cmp, double limit) noexcept;

// `reply=pending` (and `reply.CMD=pending`): no Result has this value.
inline constexpr std::uint8_t kPendingReply = 0xFF;
// `reply.reset_button=`: the reset button's replies instead of one command's.
inline constexpr std::uint8_t kResetButtonReply = 0xFE;

// One key of an `expect` line.
struct Expectation {
  ExpectKey key = ExpectKey::state;
  // state/sub/mode/stop/alarm/noalarm/reply: the value of State, Sub, Mode, StopCat,
  // AlarmId or Result. contactor/drives/brakes/reset_lamp: 1 = closed / enabled /
  // released / on, 0 = open / disabled / engaged / off.
  std::uint8_t value = 0;
  Compare cmp = Compare::le;  // tcp_speed, point_speed, axis.N.speed
  double limit = 0.0;         // the same: mm/s or rad/s
  std::uint8_t axis = 0;      // axis.N.*: N (1..6); reply.CMD: the command
  std::uint32_t number = 0;   // alarm.NAME.number, axis.N.controlword, replies
  std::string name;           // cause, cause.signal, alarm.NAME.detail: the expected name
  std::string text;           // the token as written, e.g. "state=IDLE" (for messages)
};

// How an expect line is judged over its window (@T or @T1..T2).
enum class ExpectMode : std::uint8_t {
  every,    // `expect`: after every cycle of the window
  once,     // `expect-once`: after at least one cycle, all keys in the same cycle
  replies,  // `expect replies=N`: the replies of all the window's cycles, counted once at its end
};

// `expect KEY...`: every key must hold.
struct ExpectStep {
  std::vector<Expectation> checks;
  ExpectMode mode = ExpectMode::every;
};

// `person ...` (docs/collaborative.md "The simulated person", an extension beyond the shared
// format): the simulated person enters at a point, walks a path, stands, leaves.
using Directive = std::variant<InputStep, CommandStep, FaultStep, ExpectStep, PersonStep>;

struct Step {
  std::size_t line = 0;  // 1-based line of the file
  core::Cycle t = 0;     // @T, or T1 of @T1..T2
  core::Cycle t_end = 0; // == t except for an expect range
  Directive what;
};

// Times above this are refused, so that a run always ends and never overflows.
inline constexpr core::Cycle kMaxTime = 1'000'000'000;

struct Scenario {
  std::string file;          // as given to parse(), used in messages
  core::Config config{};     // defaults + the file's `config` lines; validate() passed
  std::vector<Step> steps;   // by t (T1 for a range); file order within the same t
  std::size_t expect_lines = 0;
  core::Cycle cycles = 0;    // cycles to run: largest T (or T2) + 1; 0 without any @ line
  // SPEC §10: the safety configuration of `config safety=FILE` (nullopt: the built-in one)
  // and whether the event log at start holds a confirmation of its checksum
  // (`config validated=CHECKSUM`; the built-in configuration counts as validated).
  std::optional<core::SafetyLimits> safety;
  bool safety_validated = true;
  // SPEC §12: what the event log says about the last brake test at start
  // (`config brake_test_age_h=X|never`; default never).
  core::BrakeTestHistory brake_test{};
  // SPEC §11, the simulated person's scanner fields (`config person_fields=OUTER,INNER`).
  sim::PersonSensors person_sensors{};
  // SPEC §14: 2 channels (the default) or 1 (`config channels=1`, for comparison).
  std::uint8_t channels = 2;
};

struct ParseError {
  std::string file;
  std::size_t line = 0;
  std::string message;
  // "FILE:LINE: message"
  [[nodiscard]] std::string text() const;
};

struct ParseResult {
  Scenario scenario;                // meaningful only when ok()
  std::optional<ParseError> error;  // set for a malformed file
  [[nodiscard]] bool ok() const noexcept { return !error.has_value(); }
};

// Parses a whole .scn text. `file_name` is only used in messages.
[[nodiscard]] ParseResult parse(std::string_view text, std::string file_name);

// The limits a run monitors: the scenario's safety configuration or the built-in one.
[[nodiscard]] const core::SafetyLimits& safety_limits(const Scenario& s);


// ---------------------------------------------------------------------------------------
// Running a file

struct RunOptions {
  bool trace = false;
  std::ostream* trace_out = nullptr;  // JSON Lines, when `trace`
  std::ostream* report = nullptr;     // human messages (failing expects); none when null
  // Run the controller on this HAL backend (a real fieldbus) instead of the simulated
  // plant; `world` then applies the file's `in` and `fault` steps to whatever stands
  // behind the bus (e.g. ecat-sim's control channel) and says whether it took them.
  hal::Backend* bus = nullptr;
  std::function<bool(const Step&)> world;
};

struct Summary {
  std::size_t expects = 0;  // expect lines
  std::size_t failed = 0;   // expect lines that failed (at least once)
  core::Cycle cycles = 0;   // cycles run
};

// Replays `s` from a fresh cell for cycles 0..last T inclusive. Returns 0 when every
// expect held, 1 when one failed (one message per failing line on `report`), 2 when the
// scenario's config does not pass core::validate() (only for hand-built scenarios).
int run(const Scenario& s, const RunOptions& opts, Summary& summary);

// `safestate replay FILE... [--trace]`: the worst exit code over all files (2 malformed
// or unreadable > 1 failed > 0). The trace goes to stdout; human messages go to stderr
// when tracing, to stdout otherwise.
int replay_main(const std::vector<std::string>& files, bool trace);

// The same, with the streams given (for tests).
int replay(const std::vector<std::string>& files, bool trace, std::ostream& trace_out, std::ostream& report);

}  // namespace safestate::scenario

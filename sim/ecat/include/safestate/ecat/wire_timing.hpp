// Response time of a safety function measured on the wire by the emulated segment (issue 21
// item 4): armed over the control socket (`time STOP from=WHAT`), it watches every process-data
// exchange, with the emulator's own exchange counter and clock, and records
//   - the start: the exchange that carries the trigger to the master (a changed input contact,
//     the first plant cycle of an injected fault, or the first inputs past a limit);
//   - the reaction: the first later exchange whose outputs command the safe reaction;
//   - the safe state as the wire shows it.
// What counts as reaction and safe state per stop (docs/ethercat.md, "Response time on the wire"):
//   cat0    reaction: contactor output bit cleared; safe: contactor feedback open and every
//           velocity actual (0x606C) under 0.01 rad/s in the inputs carried back;
//   cat1    reaction: the commanded speed (the targets 0x607A, exchange to exchange) falls, or
//           the contactor bit is cleared; safe: the contactor bit cleared at the end of the stop;
//   cat2    reaction: as cat1; safe: the targets at standstill (unchanged in counts), held over
//           10 exchanges (the figure is the first of them);
//   reduce  reaction: the DO terminal's reduced_active bit set (reduced mode on, SPEC §10), or as
//           cat1, or the commanded TCP speed already at or below the limit; safe:
//           the commanded TCP speed (forward kinematics of the targets) at or below the limit;
//   reduced reaction and safe: the DO terminal's reduced_active bit set (SPEC §10 reduced mode
//           in force: from then on the core monitors the reduced limit).
// A "fall" is more than kFallCounts below the highest commanded speed since the start (the
// start's own, or higher while a program still accelerates): the targets travel in encoder
// counts, whose rounding alone moves the speed by up to about 2.5 counts per cycle, so a
// gentle ramp is seen only once it has fallen that far.
#pragma once

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

#include "safestate/hal/process_image.hpp"

namespace safestate::ecat {

// The fastest of the TCP and the link origins (mm/s) for the positions and velocities `in`
// carries, as the wire carries them (whole counts), with the core's kinematics and the tool's
// TCP (tool0, mm): the quantity the T1 monitor judges (SPEC §4 rule 3).
float max_point_speed(const hal::ProcessImageIn& in, const std::array<float, 3>& tcp) noexcept;

class WireTiming {
 public:
  enum class Stop : std::uint8_t { cat0, cat1, cat2, reduce, reduced };
  // What starts the count. input/fault: the trigger itself; the others: the first exchange
  // whose carried inputs are past `threshold` (joint: position of axis `index` in rad;
  // speed: |velocity| of axis `index` in rad/s; tcp_speed / point_speed: mm/s of the TCP /
  // the fastest of TCP and link origins, from the positions and velocities carried, with the
  // core's kinematics and the tool's TCP; tcp_pos: coordinate `index` (0 x, 1 y, 2 z) of the
  // TCP in mm; tilt: angle in rad of the tool's z axis from where it pointed when armed;
  // separation: the distance sensor's reading below `threshold` mm, or invalid, SPEC §11).
  enum class From : std::uint8_t { input, fault, joint, speed, tcp_speed, point_speed, tcp_pos, tilt, separation };
  struct Spec {
    Stop stop = Stop::cat0;
    float reduce_mm_s = 0.0F;
    From from = From::input;
    std::uint8_t index = 0;
    float threshold = 0.0F;
  };
  struct Mark {
    bool seen = false;
    std::uint64_t exchange = 0;
    std::uint64_t ns = 0;
  };
  static constexpr double kFallCounts = 2.5;        // counts per cycle (see above)
  static constexpr float kStandstillRadS = 0.01F;   // core::Config::standstill_rad_s
  static constexpr std::uint64_t kHeldExchanges = 10;

  // Parses the words after `time` ("cat1 from=input", "reduce=250 from=fault",
  // "cat0 from=joint.1>0.5", "cat0 from=tcp.y>312.5", "cat2 from=separation<1200",
  // "reduced from=input", ...). Empty on success, else what is wrong.
  static std::string parse(std::string_view words, Spec& out);

  void arm(const Spec& s) noexcept;
  void disarm() noexcept { armed_ = false; }
  void input_changed() noexcept { input_pending_ = armed_ && !start_.seen; }
  void fault_injected() noexcept { fault_pending_ = armed_ && !start_.seen; }
  void set_tcp(const std::array<float, 3>& tcp_flange_mm) noexcept { tcp_ = tcp_flange_mm; }
  // Exchange n: `out` the outputs it brought (already unpacked), `in` the inputs its reply
  // carries back (latched after the plant cycle it ran: the segment's inputs are one
  // exchange fresher, segment.cpp logical()).
  void exchange(std::uint64_t n, std::uint64_t now_ns, const hal::ProcessImageOut& out,
                const hal::ProcessImageIn& in, std::uint32_t cycle_us) noexcept;

  [[nodiscard]] bool armed() const noexcept { return armed_; }
  [[nodiscard]] const Spec& spec() const noexcept { return spec_; }
  [[nodiscard]] const Mark& start() const noexcept { return start_; }
  [[nodiscard]] const Mark& reaction() const noexcept { return reaction_; }
  [[nodiscard]] const Mark& safe() const noexcept { return safe_; }
  // The safe reaction came before the start (something else stopped the arm first).
  [[nodiscard]] const Mark& early() const noexcept { return early_; }
  // `status` → `wire_timing`: the spec, the figures (cycles and us from the start), the TCP
  // and tool axis of the last carried inputs (for a bench that places a limit beside them).
  [[nodiscard]] nlohmann::json to_json(const hal::ProcessImageIn& last_in) const;

 private:
  [[nodiscard]] bool crossed(const hal::ProcessImageIn& in) noexcept;
  [[nodiscard]] bool reacted(const hal::ProcessImageOut& out, double speed_counts, float tcp_mm_s) const noexcept;

  Spec spec_{};
  bool armed_ = false;
  bool input_pending_ = false;
  bool fault_pending_ = false;
  bool have_prev_ = false;
  bool have_ref_axis_ = false;
  bool prev_powered_ = false;  // K1 and K2 commanded closed in the last exchange
  std::array<float, 3> tcp_{};
  std::array<float, 3> ref_axis_{};
  std::array<float, hal::kAxes> prev_target_{};
  double peak_speed_counts_ = 0.0;  // the highest commanded speed from the start on
  Mark start_{};
  Mark reaction_{};
  Mark safe_{};
  Mark early_{};
  Mark still_{};  // the first exchange of the current run of unchanged targets
  // The commanded speed (counts per cycle) of the start exchange and the ones after it: the
  // evidence behind a reaction read from a fall (`status` → `wire_timing.speed_counts`).
  static constexpr std::size_t kTrace = 12;
  std::array<float, kTrace> trace_{};
  std::size_t traced_ = 0;
};

}  // namespace safestate::ecat

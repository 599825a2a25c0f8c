// SPEC §14 with each channel in a process of its own (docs/two-channels.md "Two processes"):
// the host's side. The host owns the backend (the simulated world, or a bus); each cycle it
// reads the input image, publishes it with the cycle's commands as a frame (pair/shm.hpp),
// wakes both channels, waits for both reports until its answer budget is spent, and writes
// what the power path makes of them: the drives and K1 from A, K2 from B, the brakes released
// only while both release them (two relays in series), reduced speed on while either asks.
//
// A channel that did not answer in time keeps its outputs as last written (a stalled
// processor's outputs hold); one whose process has ended has its outputs dropped (de-energised).
// The host never decides for a channel: the other channel's cross-check finds the silent one
// (CHANNEL_LOST within cross_check_cycles) and opens its own contactor. What the host does
// with the outputs stands in for wiring: two contactors in series, two brake relays in series.
//
// The host's loop never waits past the budget: futex waits with a deadline, no other blocking.
// The channels' processes are started (posix_spawn) and ended by start()/stop(), outside the
// loop.
#pragma once

#include <sys/types.h>

#include <array>
#include <cstdint>
#include <string>

#include "safestate/controller/channels.hpp"
#include "safestate/core/config.hpp"
#include "safestate/hal/process_image.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/pair/shm.hpp"

namespace safestate::pair {

struct PairOptions {
  std::string exe_a;  // the GCC build of the channel (safestate-channel)
  std::string exe_b;  // the Clang build (safestate-channel-clang)
  std::string shm_base;  // "/safestate-ch-PID" unless given
  int cpu_a = -1;  // -1: not pinned
  int cpu_b = -1;
  int priority = 0;  // the channels' SCHED_FIFO priority (0: none)
  std::uint32_t budget_us = 0;  // how long a cycle waits for both reports (0: 3/4 of the cycle, as an EtherCAT exchange)
};

// What the host knows of one channel, for the status.
struct ChannelInfo {
  bool running = false;    // its process is there
  bool answered = false;   // its report of this cycle came in time
  std::uint32_t pid = 0;
  std::uint32_t compiler = 0;  // kGcc / kClang
  std::uint64_t cycle = 0;     // the last frame it answered
  std::uint64_t late = 0;      // cycles it did not answer in time, so far
  int exit_status = -1;        // once ended: its wait status
  std::uint64_t extrapolated = 0;  // A: cycles whose set-points the host extrapolated (step())
};

class ChannelPair final : public controller::Channels {
 public:
  // `io` (the world or the bus) must outlive the pair.
  ChannelPair(const core::Config& cfg, hal::Backend& io) noexcept;
  ~ChannelPair() override;
  ChannelPair(const ChannelPair&) = delete;
  ChannelPair& operator=(const ChannelPair&) = delete;

  // Creates the segments, writes the setup, starts both channel processes and waits (at most
  // 10 s) until both are ready. False with `err` naming what failed; nothing left running.
  bool start(const PairOptions& opt, const motion::RobotModel& model, const core::SafetyLimits& limits,
             bool validated, const core::BrakeTestHistory& brake_history, std::string& err);
  // Tells both to leave, waits for them (1 s), kills what is left, removes the segments.
  void stop() noexcept;

  core::Result submit(const core::Command& c) noexcept override;
  void step() noexcept override;
  [[nodiscard]] const core::SupervisorOut& out() const noexcept override { return out_; }
  [[nodiscard]] const controller::CellView& view() const noexcept override { return view_; }
  [[nodiscard]] const core::AlarmSet& alarms() const noexcept override { return alarms_; }
  [[nodiscard]] const core::RawInputs& raw_inputs_of_last_cycle() const noexcept override { return raw_; }
  [[nodiscard]] core::Leaf leaf() const noexcept override { return leaf_; }
  [[nodiscard]] core::Cycle now() const noexcept override { return cycle_; }
  [[nodiscard]] std::uint8_t count() const noexcept override { return 2U; }
  [[nodiscard]] bool channel_status(std::size_t i, controller::ChannelStatus& out) const noexcept override;

  // Channel 0 (A) or 1 (B): its last report and what the host knows of it.
  [[nodiscard]] const Report& report(std::size_t i) const noexcept { return reports_[i & 1U]; }
  [[nodiscard]] const ChannelInfo& info(std::size_t i) const noexcept { return info_[i & 1U]; }
  [[nodiscard]] const hal::ProcessImageOut& combined() const noexcept { return combined_; }
  [[nodiscard]] bool b_leads() const noexcept { return b_leads_; }

 private:
  void reap() noexcept;  // notices a channel process that ended (waitpid, WNOHANG)

  core::Config cfg_;
  hal::Backend* io_;
  Names names_{};
  InSegment* in_ = nullptr;
  std::array<const ChannelSegment*, 2> ch_{};
  std::array<pid_t, 2> pid_{-1, -1};
  std::uint64_t budget_ns_ = 0;
  bool started_ = false;

  // The command queue (SPEC §9): commands wait here for the next cycle's frame.
  std::array<core::Command, core::kMaxQueueSize> queue_{};
  std::size_t queue_head_ = 0;
  std::size_t queue_count_ = 0;

  Frame frame_{};
  std::array<Report, 2> reports_{};
  std::array<std::uint64_t, 2> seen_{};  // the last report read of each channel
  std::array<hal::ProcessImageOut, 2> outputs_{};  // each channel's outputs as they stand
  std::array<ChannelInfo, 2> info_{};
  hal::ProcessImageOut combined_{};
  // A's set-points when they are late (step()): the last, its step, cycles gone on.
  std::array<float, hal::kAxes> last_target_rad_{};
  std::array<float, hal::kAxes> step_rad_{};
  std::uint32_t extrapolated_ = 0;
  std::uint64_t last_target_cycle_ = 0;  // the cycle of A's last set-points
  core::Cycle cycle_ = 0;
  core::SupervisorOut out_{};
  core::AlarmSet alarms_{};
  core::Leaf leaf_ = core::Leaf::BOOT;
  controller::CellView view_{};
  core::RawInputs raw_{};
  bool b_leads_ = false;
};

// The events of a report kept in the next one read in the same look (its replies and
// transitions first, the alarm changes of both, a finished brake test).
void merge_events(const core::SupervisorOut& earlier, core::SupervisorOut& later) noexcept;

}  // namespace safestate::pair

// What a host drives each cycle (SPEC §14): the safety controller as one channel in this
// process (OneChannel, a controller::Cell), or as a pair of channels wherever they run
// (runtime/pair.hpp: two processes). The host's loop, its status and its event log see only
// this interface; the channels together are what SPEC §14 and the scenario format call
// "together": led by the channel that leads towards safety (together()).
// No heap, no exceptions, no OS calls, no clock: the same rules as core/.
#pragma once

#include <cstdint>

#include "safestate/controller/cell.hpp"
#include "safestate/core/alarms.hpp"
#include "safestate/core/supervisor.hpp"

namespace safestate::controller {

// One channel as a status shows it (SPEC §14: state, cycle, last digest, agree or not).
struct ChannelStatus {
  bool present = false;   // this host has the channel
  bool running = false;   // its process is there (always, in this process)
  bool answered = false;  // its result of the last cycle came in time
  std::uint32_t pid = 0;
  std::uint8_t compiler = 0;  // 1 GCC, 2 Clang, 0 unknown
  std::uint64_t cycle = 0;    // the last cycle it ran
  std::uint64_t late = 0;     // cycles it did not answer in time, so far
  std::uint64_t skipped = 0;  // cycles it never saw (not run meanwhile)
  core::State state = core::State::BOOT;
  core::Leaf leaf = core::Leaf::BOOT;
  std::uint32_t digest_crc = 0;  // its last digest's CRC
  bool agree = true;             // its cross-check: no mismatch, partner not lost
  core::CrossField field = core::CrossField::none;  // the first field that differed
  std::uint32_t missing = 0;     // its cycles since the partner's last valid digest
  std::uint32_t wake_max_us = 0;  // the longest it was kept from starting on a frame (in processes)
  std::uint32_t exec_max_us = 0;  // its longest cycle (in processes: its own clock)
};

class Channels {
 public:
  Channels() = default;
  Channels(const Channels&) = delete;
  Channels& operator=(const Channels&) = delete;
  virtual ~Channels() = default;

  // Queues a command for the next cycle: OK, or QUEUE_FULL. With two channels both take it
  // in the same cycle.
  virtual core::Result submit(const core::Command& c) noexcept = 0;
  // One scan cycle: the backend read, every channel's step, the backend written.
  virtual void step() noexcept = 0;

  // Of the last cycle, the channels together.
  [[nodiscard]] virtual const core::SupervisorOut& out() const noexcept = 0;
  [[nodiscard]] virtual const CellView& view() const noexcept = 0;
  [[nodiscard]] virtual const core::AlarmSet& alarms() const noexcept = 0;
  [[nodiscard]] virtual const core::RawInputs& raw_inputs_of_last_cycle() const noexcept = 0;
  [[nodiscard]] virtual core::Leaf leaf() const noexcept = 0;
  [[nodiscard]] virtual core::Cycle now() const noexcept = 0;  // cycles run so far
  [[nodiscard]] virtual std::uint8_t count() const noexcept = 0;  // 1 or 2
  // Channel i (0: A, 1: B) for the status; false when there is no such channel.
  [[nodiscard]] virtual bool channel_status(std::size_t i, ChannelStatus& out) const noexcept = 0;
};

// One channel: a controller::Cell in this process (`--channels 1`, and every host that has
// no second channel: rtbench, rta). Inline, with no key function: its vtable (and the
// deleting destructor that would pull operator delete) is emitted only where a host uses it,
// never in the embedded image (make embedded links controller/ without a heap).
class OneChannel final : public Channels {
 public:
  explicit OneChannel(Cell& cell) noexcept : cell_(&cell) {}
  core::Result submit(const core::Command& c) noexcept override { return cell_->submit(c); }
  void step() noexcept override { cell_->step(); }
  [[nodiscard]] const core::SupervisorOut& out() const noexcept override { return cell_->out(); }
  [[nodiscard]] const CellView& view() const noexcept override { return cell_->view(); }
  [[nodiscard]] const core::AlarmSet& alarms() const noexcept override { return cell_->alarms(); }
  [[nodiscard]] const core::RawInputs& raw_inputs_of_last_cycle() const noexcept override {
    return cell_->raw_inputs_of_last_cycle();
  }
  [[nodiscard]] core::Leaf leaf() const noexcept override { return cell_->leaf(); }
  [[nodiscard]] core::Cycle now() const noexcept override { return cell_->now(); }
  [[nodiscard]] std::uint8_t count() const noexcept override { return 1U; }
  [[nodiscard]] bool channel_status(std::size_t i, ChannelStatus& out) const noexcept override {
    if (i != 0U) {
      return false;
    }
    out = ChannelStatus{};
    out.present = true;
    out.running = true;
    out.answered = true;
    out.cycle = cell_->now();
    out.state = cell_->out().state;
    out.leaf = cell_->leaf();
    out.digest_crc = cell_->last_digest().crc;
    return true;
  }
  [[nodiscard]] Cell& cell() noexcept { return *cell_; }

 private:
  Cell* cell_;
};

// One channel's result of a cycle, as together() reads it.
struct ChannelResult {
  const core::SupervisorOut* out = nullptr;
  const core::AlarmSet* alarms = nullptr;
  core::Leaf leaf = core::Leaf::BOOT;
};

// The channels together (spec/scenario-format.md "Two channels"): the state, sub-state, stop
// and first-out cause of the channel that leads towards safety — the one locked out, else the
// one whose contactor is open, else A; the alarms of either (the leading channel's detail
// first); the contactor closed only while both command it closed, the brakes released only
// while both release them; the leaf: ERROR_LOCKOUT if either is locked out, else the lead's.
// Returns whether B leads.
bool together(const ChannelResult& a, const ChannelResult& b, core::SupervisorOut& out, core::AlarmSet& alarms,
              core::Leaf& leaf) noexcept;

// The outputs the power path makes of two channels' (SPEC §14), standing in for its wiring:
// the drives (set-points, controlwords) and K1 from A, K2 from B, the brakes released only
// while both release them (two brake relays in series), reduced speed on while either asks.
[[nodiscard]] hal::ProcessImageOut combine_outputs(const hal::ProcessImageOut& a, const hal::ProcessImageOut& b) noexcept;

}  // namespace safestate::controller

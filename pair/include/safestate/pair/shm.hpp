// SPEC §14, two channels in processes of their own (docs/two-channels.md "Two processes"):
// what the host and the two channel processes share, in three POSIX shared-memory objects.
//
//   NAME-in   written by the host only (the channels map it read-only): the setup, written
//             once before the channels start (configuration, safety limits, robot model,
//             brake-test history, sealed by a CRC), and each cycle's frame (the last kFrames
//             kept): the cycle number, the input image the backend read, the commands both
//             channels take in that cycle.
//   NAME-a    written by channel A only (the host and B map it read-only): A's report of each
//   NAME-b    cycle (its output image, its supervisor's output, its alarms, its view) and its
//             lane of digests to the other channel (the cross-channel link of SPEC §14).
//
// No object is writable by two processes: a channel's state, its outputs and its digests are
// its own; the input image is the only thing both read. A lane is a broadcast ring whose
// reader keeps its own place (LaneReader, in the reader's memory), so the link needs no
// writable memory in common either; a UART or SPI link would carry the same Digest bytes.
//
// Every record is published under a sequence lock (odd while written); a reader copies it
// and accepts the copy only if the sequence was even and unchanged around the copy.
// Everything here is plain data: no pointer crosses a process (RobotModel's names travel as
// text and are pointed at again in the channel).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "safestate/controller/cell.hpp"
#include "safestate/controller/cross_check.hpp"
#include "safestate/core/alarms.hpp"
#include "safestate/core/brake_test.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/core/supervisor.hpp"
#include "safestate/hal/process_image.hpp"
#include "safestate/motion/robot.hpp"

namespace safestate::pair {

inline constexpr std::uint32_t kMagic = 0x53535043U;  // "SSPC"
inline constexpr std::uint32_t kVersion = 3U;
inline constexpr std::size_t kLaneSlots = 16;  // digests kept for a reader that fell behind
// Frames kept for a channel that fell behind: it runs every one of them, in order (a channel
// that skipped a frame would run its timers a cycle behind the other's). One that falls
// further behind than this has long been found lost by the other (cross_check_cycles).
inline constexpr std::size_t kFrames = 16;
inline constexpr std::size_t kNameLen = 48;

// Written once, before the channels start.
struct Setup {
  std::uint32_t magic = 0;
  std::uint32_t version = 0;
  std::uint32_t size = 0;  // sizeof(Setup): a channel of another build refuses
  std::uint32_t validated = 0;  // the safety configuration was validated (SPEC §10)
  core::Config cfg{};
  core::SafetyLimits limits{};
  core::BrakeTestHistory brake_history{};
  motion::RobotModel model{};  // its pointers null here: the names are below
  char model_name[kNameLen]{};
  char link_names[motion::kLinks][kNameLen]{};
  // Issue 37: the black channel's connections of the backend (each channel hosts its own)
  // and the first host session (random at each start of the host).
  hal::LinkTable links{};
  std::uint32_t link_session_seed = 0;
  std::uint32_t crc = 0;  // CRC-32 of every byte above
};

// Cycle `cycle`'s inputs, written by the host each cycle.
struct Frame {
  std::uint64_t cycle = 0;  // 1, 2, ... (0: none yet)
  std::uint64_t published_ns = 0;  // when the host published it (CLOCK_MONOTONIC, one clock for all)
  hal::ProcessImageIn in{};
  std::uint32_t command_count = 0;
  std::array<core::Command, core::kMaxCommandsPerCycle> commands{};
};

// A channel's report of one cycle.
struct Report {
  std::uint64_t cycle = 0;       // the frame it answers
  std::uint64_t own_cycles = 0;  // cycles this channel ran (a channel that stalled ran fewer)
  std::uint64_t skipped = 0;     // frames it never saw (it was not run meanwhile)
  std::uint32_t pid = 0;
  std::uint32_t compiler = 0;  // kGcc or kClang: what built this channel
  hal::ProcessImageOut out{};
  core::SupervisorOut sup{};
  controller::CellView view{};  // axis_state null: names are the host's (axis_code)
  core::AlarmSet alarms{};
  core::RawInputs raw{};
  std::uint8_t leaf = 0;  // core::Leaf
  controller::Digest digest{};
  controller::CrossVerdict verdict{};
  std::uint32_t integrity_fault = 0;  // the channel's self-test failed (INTEGRITY_FAULT)
  std::uint64_t exec_ns_max = 0;      // the longest step so far (the channel's own clock)
  std::uint64_t exec_ns = 0;          // this step's (its cross-check included): the cost benches
  // The longest time from a frame's publication to this channel starting on it, and the
  // frame: how long the host's scheduler kept this channel from running (a channel found
  // lost with a figure of cross_check_cycles or more here was not run, docs/two-channels.md).
  std::uint64_t wake_ns_max = 0;
  std::uint64_t wake_max_cycle = 0;
};
inline constexpr std::uint32_t kGcc = 1U;
inline constexpr std::uint32_t kClang = 2U;

// A record under a sequence lock.
template <typename T>
struct Sealed {
  static_assert(std::is_trivially_copyable_v<T>, "shared records are plain data");
  std::atomic<std::uint64_t> seq{0};
  T value{};

  void write(const T& v) noexcept {
    const std::uint64_t s = seq.load(std::memory_order_relaxed);
    seq.store(s + 1U, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    std::memcpy(static_cast<void*>(&value), &v, sizeof(T));
    std::atomic_thread_fence(std::memory_order_release);
    seq.store(s + 2U, std::memory_order_release);
  }
  // A consistent copy, or false (being written: try again).
  bool read(T& out) const noexcept {
    const std::uint64_t s0 = seq.load(std::memory_order_acquire);
    if ((s0 & 1U) != 0U) {
      return false;
    }
    std::memcpy(static_cast<void*>(&out), &value, sizeof(T));
    std::atomic_thread_fence(std::memory_order_acquire);
    return seq.load(std::memory_order_relaxed) == s0;
  }
};

// A channel's digests to the other: slot n % kLaneSlots holds the n-th (n from 1).
struct Lane {
  std::atomic<std::uint64_t> written{0};
  std::array<Sealed<controller::Digest>, kLaneSlots> slots{};
};

struct InSegment {
  std::uint32_t magic = 0;
  std::uint32_t version = 0;
  Setup setup{};
  // Frame k in slot k % kFrames; `published`: the last frame written whole.
  std::array<Sealed<Frame>, kFrames> frames{};
  std::atomic<std::uint64_t> published{0};
  // The futex word the channels wait on: the low 32 bits of `published`.
  std::atomic<std::uint32_t> frame_word{0};
  std::atomic<std::uint32_t> stop{0};  // nonzero: the host is ending, the channels leave
};

struct ChannelSegment {
  std::uint32_t magic = 0;
  std::uint32_t version = 0;
  // The report of frame k in slot k % kFrames; `reported`: the last one written whole (a
  // host that did not look for a few cycles reads every one it missed: their replies and
  // transitions are events).
  std::array<Sealed<Report>, kFrames> reports{};
  std::atomic<std::uint64_t> reported{0};
  // The futex word the host waits on: the low 32 bits of `reported`.
  std::atomic<std::uint32_t> report_word{0};
  std::atomic<std::uint32_t> ready{0};  // set up and waiting for frames
  Lane lane{};
};

static_assert(std::is_trivially_copyable_v<Setup>);
static_assert(std::is_trivially_copyable_v<Frame>);
static_assert(std::is_trivially_copyable_v<Report>);

// The CRC that seals the setup (CRC-32 of its bytes before `crc`).
[[nodiscard]] std::uint32_t setup_crc(const Setup& s) noexcept;
// Whether a setup is one this build can run: magic, version, size, CRC; `why` names what is wrong.
[[nodiscard]] bool setup_valid(const Setup& s, const char*& why) noexcept;
// Fills a setup (magic, version, size, the model's names as text, the CRC).
void seal_setup(Setup& s, const motion::RobotModel& model) noexcept;

// The reader's side of a lane: its own place, in its own memory.
class LaneReader {
 public:
  explicit LaneReader(const Lane* lane = nullptr) noexcept : lane_(lane) {}
  // The next digest written since the last call, if any. A reader that fell more than
  // kLaneSlots behind skips to the oldest still kept (the cross-check sees the gap in the
  // sequence numbers: SPEC §14, "skipped counts as not arrived").
  bool next(controller::Digest& d) noexcept;

 private:
  const Lane* lane_;
  std::uint64_t read_ = 0;
};

// The cross-channel link over the shared memory (controller::Link): send() writes this
// channel's lane, receive() reads the partner's.
class ShmLink final : public controller::Link {
 public:
  ShmLink(Lane& mine, const Lane& theirs) noexcept : mine_(&mine), theirs_(&theirs) {}
  void send(const controller::Digest& d) noexcept override;
  bool receive(controller::Digest& d) noexcept override { return theirs_.next(d); }

 private:
  Lane* mine_;
  LaneReader theirs_;
};

// The shared-memory objects' names for a base NAME ("/safestate-ch-1234").
struct Names {
  char in[64]{};
  char a[64]{};
  char b[64]{};
};
[[nodiscard]] bool make_names(const char* base, Names& out) noexcept;

}  // namespace safestate::pair

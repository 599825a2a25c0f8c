// An emulated EtherCAT segment: subdevices in a line, each an emulated ESC, processing
// the datagrams of every frame in order as the frame passes them (ETG.1000.4 5.4: auto-
// increment, configured-address, broadcast and logical addressing, working counters),
// and the wire faults a test needs: a cable cut in front of a subdevice, damaged frames,
// lost frames.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "safestate/ecat/esc.hpp"

namespace safestate::ecat {

inline constexpr std::uint16_t kEtherTypeEcat = 0x88A4;
// The time a frame takes from one emulated subdevice to the next (forwarding through an ESC
// and its cable), the same both ways: what the master's propagation-delay measurement finds.
inline constexpr std::uint64_t kHopNs = 800;
// The emulated clocks' default drifts (ppm, by position): a few tens, both signs, as quartz
// oscillators of +-50 ppm are; `ecat-sim --drift-ppm` sets others.
inline constexpr double kDefaultDriftPpm[] = {12.0, -25.0, 31.0, -8.0, 45.0, -37.0, 19.0, -14.0};

enum class Cmd : std::uint8_t {
  NOP = 0, APRD, APWR, APRW, FPRD, FPWR, FPRW, BRD, BWR, BRW, LRD, LWR, LRW, ARMW, FRMW
};

class Segment {
 public:
  explicit Segment(const std::vector<SubdeviceDesc>& devices);

  // Called once per frame whose logical datagrams wrote process data, between the
  // writes and the reads (the applications take their outputs and latch new inputs).
  void on_process_data(std::function<void()> f) { on_pd_ = std::move(f); }

  // Processes one Ethernet frame in place. Returns false when no frame comes back
  // (not EtherCAT, malformed, dropped, or nothing connected).
  bool process(std::span<std::uint8_t> frame, std::uint64_t now_ns) noexcept;

  void poll(std::uint64_t now_ns) noexcept;  // process-data watchdogs, DC (pending OP)
  // The position (0-based) of the DC reference clock: the first connected subdevice with a
  // DC unit (every emulated ESC has one, so the first), or size() when none is connected.
  [[nodiscard]] std::size_t dc_reference() const noexcept { return connected() > 0U ? 0U : escs_.size(); }
  // The sync error of subdevice `i` at host time `now_ns`: its system time minus the
  // reference clock's at the same instant (ns).
  [[nodiscard]] std::int64_t sync_error_ns(std::size_t i, std::uint64_t now_ns) noexcept;

  // Wire faults.
  void cut_before(std::size_t position) noexcept;  // 1-based; 0 = every cable plugged
  void drop_frames(std::uint32_t n) noexcept { drop_ += n; }
  void corrupt_frames(std::uint32_t n) noexcept { corrupt_ += n; }
  // One frame in every `n` (0 = none) is lost on its way back: the subdevices process it
  // (outputs taken, the plant steps) but the master never sees the answer, as with a frame
  // damaged after the last subdevice or one that comes back after the master gave it up.
  void lose_every(std::uint32_t n) noexcept {
    lose_every_ = n;
    lose_count_ = 0;
  }
  [[nodiscard]] std::uint64_t lost_replies() const noexcept { return lost_replies_; }
  // The whole bus silent (a cable cut at the master) until clear_wire_faults().
  void go_silent() noexcept { silent_ = true; }
  // Subdevice `position` (1-based; 0 = none) stays in OP and answers every other datagram
  // but no longer processes process data: it neither takes its outputs nor puts its inputs
  // in the logical datagrams, so their working counter comes back short (its own process-
  // data watchdog then expires, as on a real ESC whose application hangs).
  void ignore_process_data(std::size_t position) noexcept { no_pd_ = position; }
  // A host stall as the segment sees it (a test of the master): from `from_ns`, for `ns`, no
  // frame reaches it; the frames sent meanwhile reach it when the stall ends, in order, as a
  // stalled master's would go out then (the emulator's loop takes none before frozen_until():
  // ecat_sim.cpp). Its clocks, SYNC0 pulses and process-data watchdogs run on meanwhile.
  void freeze(std::uint64_t from_ns, std::uint64_t ns) noexcept {
    frozen_until_ = from_ns + ns;
    ++freezes_;
  }
  // The same, from the first frame that exchanges process data with a subdevice in OP: the
  // master's first cyclic exchange after its OP request (its boot wait, or its keep-alive).
  // That frame is processed but not answered (the stall took the master as it went out: the
  // master never sees the answer, so no answer from before the stall can show the bus up).
  void freeze_at_op(std::uint64_t ns) noexcept { freeze_at_op_ns_ = ns; }
  [[nodiscard]] std::uint64_t frozen_until() const noexcept { return frozen_until_; }
  [[nodiscard]] std::uint32_t freezes() const noexcept { return freezes_; }
  void clear_wire_faults() noexcept {
    silent_ = false;
    no_pd_ = 0;
    drop_ = 0;
    corrupt_ = 0;
    lose_every_ = 0;
    frozen_until_ = 0;
    freeze_at_op_ns_ = 0;
  }
  [[nodiscard]] std::size_t connected() const noexcept;

  [[nodiscard]] std::size_t size() const noexcept { return escs_.size(); }
  Esc& esc(std::size_t i) noexcept { return escs_[i]; }
  [[nodiscard]] const Esc& esc(std::size_t i) const noexcept { return escs_[i]; }
  [[nodiscard]] std::uint64_t frames() const noexcept { return frames_; }

  // How late the emulating process answered (ecat_sim.cpp): the time from a frame reaching
  // the interface to its answer going out. A real ESC answers as the frame passes; a figure of
  // a millisecond or more says the host did not run this process (a host stall, not a fault of
  // the segment or the master), and a test tells the two apart by it. Frames held back by a
  // `freeze` are not counted: that delay is the fault asked for.
  struct Answers {
    std::uint64_t count = 0;
    std::uint64_t max_delay_ns = 0;
    std::uint64_t max_at_ns = 0;  // host time of the slowest answer
    std::uint64_t late_1ms = 0;   // answers that took 1 ms or longer
  };
  void note_answer(std::uint64_t delay_ns, std::uint64_t now_ns) noexcept {
    ++answers_.count;
    if (delay_ns >= 1000000U) {
      ++answers_.late_1ms;
    }
    if (delay_ns > answers_.max_delay_ns) {
      answers_.max_delay_ns = delay_ns;
      answers_.max_at_ns = now_ns;
    }
  }
  [[nodiscard]] const Answers& answers() const noexcept { return answers_; }

 private:
  bool datagram(std::span<std::uint8_t> dg, std::uint64_t now_ns, bool& pd_written) noexcept;
  void physical(Cmd c, std::uint16_t adp, std::uint16_t ado, std::span<std::uint8_t> data, std::uint16_t& wkc,
                std::uint64_t now_ns) noexcept;
  void logical(Cmd c, std::uint32_t addr, std::span<std::uint8_t> data, std::uint16_t& wkc, std::uint64_t now_ns,
               bool& pd_written) noexcept;
  void update_dl_status() noexcept;
  void sample_sync_errors(std::uint64_t now_ns) noexcept;

  std::vector<Esc> escs_;
  std::size_t cut_ = 0;
  std::uint32_t drop_ = 0;
  std::uint32_t corrupt_ = 0;
  std::uint32_t lose_every_ = 0;
  std::uint32_t lose_count_ = 0;
  std::uint64_t lost_replies_ = 0;
  bool silent_ = false;
  std::size_t no_pd_ = 0;
  std::uint64_t frozen_until_ = 0;
  std::uint64_t freeze_at_op_ns_ = 0;
  std::uint32_t freezes_ = 0;
  std::uint64_t frames_ = 0;
  Answers answers_;
  std::vector<std::uint8_t> scratch_;
  std::function<void()> on_pd_;
};

}  // namespace safestate::ecat

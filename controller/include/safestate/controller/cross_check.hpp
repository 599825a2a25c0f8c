// SPEC §14 cross-comparison between two channels: the digest each channel sends the other
// every cycle, the link that carries it (an interface a UART, SPI or shared-memory ring can
// implement), and the check that turns what arrived into CHANNEL_MISMATCH / CHANNEL_LOST.
// No heap, no OS, no clock: timing in the channel's own cycles. controller::Cell runs it
// after every step when it has a partner (Cell::pair).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/core/supervisor.hpp"

namespace safestate::controller {

// One cycle's result as SPEC §14 lists it: cycle number, state, sub-state, stop category,
// active alarms, every output bit, each command's result; a sequence number and a CRC-32
// over all of it. Plain bytes: what goes on the wire is this struct as it is.
struct Digest {
  std::uint32_t seq = 0;
  std::uint32_t pad0 = 0;
  std::uint64_t cycle = 0;
  std::uint64_t alarms = 0;  // core::AlarmMask, widened: room for more alarms
  std::uint8_t state = 0;
  std::uint8_t sub = 0;
  std::uint8_t stop = 0;
  std::uint8_t outputs = 0;  // controller::output_bits
  std::uint8_t brake_test_axis = 0;
  std::uint8_t reply_count = 0;
  std::uint8_t pad1[2]{};
  std::uint32_t replies = 0;  // CRC-32 of the (seq, command, source, result) of each reply
  std::uint32_t crc = 0;      // over every byte above
};

// The fields a mismatch can name, in the order they are compared (the first that differs):
// the core's, since CHANNEL_MISMATCH names it (core::to_string(CrossField)).
using DigestField = core::CrossField;

// This cycle's digest of `out` (the cycle just run), sealed with its CRC.
[[nodiscard]] Digest make_digest(std::uint32_t seq, std::uint64_t cycle, const core::SupervisorOut& out) noexcept;
[[nodiscard]] bool sealed(const Digest& d) noexcept;  // the CRC matches
// The first field in which two digests of the same cycle differ (none: they agree).
[[nodiscard]] DigestField first_difference(const Digest& a, const Digest& b) noexcept;

// What carries digests between the channels. send() never blocks; receive() gives the next
// digest that arrived since the last call, if any (several may have: the channels' cycles are
// not locked to each other).
class Link {
 public:
  Link() = default;
  Link(const Link&) = default;
  Link& operator=(const Link&) = default;
  virtual ~Link() = default;
  virtual void send(const Digest& d) noexcept = 0;
  virtual bool receive(Digest& d) noexcept = 0;
};

struct CrossVerdict {
  bool mismatch = false;  // CHANNEL_MISMATCH (latched by the caller: a lockout)
  DigestField field = DigestField::none;
  bool lost = false;      // CHANNEL_LOST
  std::uint32_t missing = 0;    // own cycles since the last valid digest of the partner
  std::uint32_t differing = 0;  // compared cycles in a row that differed
};

// SPEC §14: a difference that lasts longer than `cross_check_cycles` compared cycles is a
// mismatch; a partner whose valid digest has not arrived for `cross_check_cycles` of this
// channel's cycles is lost (a cycle whose digest, or a later one, came earlier is not
// missing: two processes are not in lock-step); a digest with a wrong CRC, or a sequence number that is not the
// next one (repeated, skipped), counts as not arrived. A partner's digest is compared with
// this channel's digest of the same cycle (kept for kHistory cycles); one of a cycle this
// channel has not run yet waits until it has.
class CrossCheck {
 public:
  static constexpr std::size_t kHistory = 8;
  explicit CrossCheck(std::uint32_t cross_check_cycles = 2) noexcept : limit_(cross_check_cycles) {}

  // Each cycle, after the channel's own step: its digest, then every digest the link has.
  CrossVerdict step(const Digest& mine, Link& link) noexcept;
  [[nodiscard]] const CrossVerdict& verdict() const noexcept { return verdict_; }
  [[nodiscard]] std::uint64_t last_agreed_cycle() const noexcept { return last_agreed_; }

 private:
  void take(const Digest& theirs) noexcept;
  void compare_pending() noexcept;

  std::uint32_t limit_;
  std::array<Digest, kHistory> mine_{};  // by cycle % kHistory
  std::uint64_t my_cycle_ = 0;
  std::array<Digest, kHistory> pending_{};  // the partner's, not yet compared
  std::size_t pending_count_ = 0;
  std::uint32_t next_seq_ = 0;
  bool have_seq_ = false;
  bool arrived_ = false;
  std::uint64_t newest_ = 0;  // the cycle of the partner's newest valid digest
  std::uint64_t last_agreed_ = 0;
  CrossVerdict verdict_{};
};

}  // namespace safestate::controller

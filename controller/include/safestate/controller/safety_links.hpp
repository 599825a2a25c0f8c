// Issue 37, the black channel (docs/black-channel.md): a channel's ends of its safety
// connections. The backend only copies container bytes (hal::ProcessImageIn::link_rx,
// hal::ProcessImageOut::link_tx); here the channel checks each container it receives and
// creates each one it sends, so that no fault of the bus or its master can hand the channel an
// old E-stop bit or keep a contactor closed that the channel opened.
//
// Each cycle, in the scan's order:
//   receive(): after the backend's read, every hosted connection's container is checked
//     (safelink::HostEnd::receive); the safety data of the image are replaced by the
//     containers' (the safe input terminal's contacts, K1's and K2's contacts and the brakes'
//     feedback; each drive's load-side position), or by the safe values (zeros: E-stop
//     pressed, contacts open) where a connection is not up or has failed; the LinkCheck
//     for the supervisor says which connection failed first and why (SAFETY_LINK_FAULT).
//   transmit(): after the step, the containers to send, with this cycle's decision in the
//     safe output terminal's (K of this channel, its brake relay).
// A channel of a pair hosts its own channel's connections; a channel alone hosts all of them
// (its decision goes to K1 and K2 both, as its plain outputs do).
//
// Start-up: a connection whose device has not answered its connect within the watchdog (the
// bus still coming up) is connected again with a new session, until every connection has been
// up once; the boot waits for that (BootMonitor, BOOT_FAILED at boot_timeout naming the first
// connection not up). From then on any error is latched: SAFETY_LINK_FAULT.
//
// Same rules as core/: no heap, no exceptions, no OS calls, no clock; time in cycles.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/core/interfaces.hpp"
#include "safestate/core/types.hpp"
#include "safestate/hal/process_image.hpp"
#include "safestate/safelink/link.hpp"

namespace safestate::controller {

// The safe input terminal's data: the DI terminal's contact word, bit by bit (docs/ethercat.md).
namespace fdi {
inline constexpr unsigned kEstopA = 0, kEstopB = 1, kGateA = 2, kGateB = 3, kEnableA = 4, kEnableB = 5,
                          kEnablePanic = 6, kModeAuto = 7, kModeT1 = 8, kModeT2 = 9, kResetButton = 10,
                          kContactorK1 = 11, kBrake1 = 12, kReducedA = 18, kReducedB = 19, kFieldOuterA = 20,
                          kFieldOuterB = 21, kFieldInnerA = 22, kFieldInnerB = 23, kContactorK2 = 24;
}  // namespace fdi
// The safe output terminal's data byte from the channel: bit 0 its contactor, bit 1 its brake relay.
inline constexpr std::uint8_t kFdoContactor = 0x01U;
inline constexpr std::uint8_t kFdoBrakeRelay = 0x02U;

class SafetyLinks {
 public:
  // Configures the connections of `table` this channel hosts (`self` a or b: that channel's;
  // none: a channel alone, all of them) and opens a session on each. `session_seed`: the
  // first host session (the caller's random source, different at every start). false with
  // `why` naming the first connection refused (nothing configured then).
  bool configure(const hal::LinkTable& table, core::Channel self, std::uint32_t cycle_us,
                 std::uint16_t session_seed, const char*& why) noexcept;
  [[nodiscard]] bool configured() const noexcept { return hosted_ != 0U; }

  // After the backend's read, before the step (see above).
  void receive(hal::ProcessImageIn& in) noexcept;
  // After the step: `out.link_tx` of every hosted connection, with `out`'s decision.
  void transmit(hal::ProcessImageOut& out) noexcept;

  [[nodiscard]] const core::LinkCheck& check() const noexcept { return check_; }
  [[nodiscard]] std::uint8_t count() const noexcept { return count_; }
  [[nodiscard]] bool hosts(std::size_t i) const noexcept { return i < count_ && conn_[i].hosted; }
  [[nodiscard]] const hal::LinkSpec& spec(std::size_t i) const noexcept { return conn_[i].spec; }
  [[nodiscard]] const safelink::HostEnd& end(std::size_t i) const noexcept { return conn_[i].end; }

 private:
  struct Conn {
    hal::LinkSpec spec{};
    safelink::HostEnd end{};
    bool hosted = false;
    bool ever_up = false;  // its session has been up once
  };
  // Which connection's data this channel uses for a role (its own channel's; a channel
  // alone: channel A's, the B ones are checked all the same).
  [[nodiscard]] bool uses(const Conn& c) const noexcept;

  std::array<Conn, hal::kMaxLinks> conn_{};
  std::uint8_t count_ = 0;
  std::uint8_t hosted_ = 0;
  core::Channel self_ = core::Channel::none;
  std::uint16_t next_session_ = 1;
  core::LinkCheck check_{};
};

// A connection's parameters as both of its ends put them into every CRC (the host here, a
// device end in an emulation or a test).
[[nodiscard]] safelink::ConnectionParams link_params(const hal::LinkSpec& s) noexcept;

// safelink's verdict as the core names it.
[[nodiscard]] core::LinkError link_error(safelink::Verdict v) noexcept;

}  // namespace safestate::controller

#pragma once
// The two ends of one black-channel connection (issue 37, docs/black-channel.md): the host
// (a supervisor channel) and the device (a safe terminal or a drive's encoder data). Each is
// called once per cycle of its own with the container the bus delivered and writes the
// container the bus is to carry; the bus and its master only copy bytes.
//
// Ping-pong: the host holds its container until the device's answer acknowledges it, then
// sends the next; the device answers each new host container with a new one of its own.
// A container identical to the last one accepted is a repetition (the bus delivering it
// again): not new, so it does not feed the watchdog. Any other fault is latched: the end
// goes fail-safe (the device's outputs off, the host's data the safe values, both send
// zeros) until the host opens a new session with connect().
//
// No heap, no exceptions, no RTTI, no OS calls, no clock: time is counted in calls.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "safestate/safelink/container.hpp"

namespace safestate::safelink {

enum class Verdict : std::uint8_t {
  Ok,            // a new valid container (or, while connecting, the session opened)
  Repetition,    // the last container again: nothing new (not a fault by itself)
  Crc,           // CRC mismatch: corruption
  Sequence,      // valid, but not the next one: gap, replay of an older one, wrong ack
  Identity,      // another connection's or the other direction's container (masquerade)
  Timeout,       // no new valid container within the watchdog
  NotConnected,  // no session (nothing sent yet, or the partner is fail-safe: zeros)
  Length         // a container or data buffer of the wrong size
};

const char* to_string(Verdict v) noexcept;

enum class LinkState : std::uint8_t { Unconfigured, Idle, Connecting, Connected, Failed };

const char* to_string(LinkState s) noexcept;

namespace detail {
// What both ends share: parameters, sessions, counters, the held and last accepted containers.
struct EndCommon {
  ConnectionParams params{};
  std::uint32_t watchdog_cycles = 0;
  LinkState state = LinkState::Unconfigured;
  Verdict fault = Verdict::NotConnected;  // the latched fault while Failed
  std::uint16_t host_session = 0;
  std::uint16_t device_session = 0;
  std::uint64_t prefix = 0;       // CRC register after P(host_session, device_session)
  std::uint32_t own_seq = 0;      // this end's counter (32 bits; 16 sent)
  std::uint32_t partner_seq = 0;  // the partner's counter last accepted
  std::uint32_t since_ok = 0;     // calls since the last new valid container
  bool have_data = false;         // a data container was accepted in this session
  std::size_t rx_len = 0;         // container sizes of this end: received, sent
  std::size_t tx_len = 0;
  std::array<std::uint8_t, kMaxContainer> last_rx{};  // the last container accepted
  std::array<std::uint8_t, kMaxContainer> tx{};       // the container this end holds
  std::array<std::uint8_t, kMaxData> data{};          // the partner's last valid data

  ConfigError configure(const ConnectionParams& p, std::uint32_t cycle_us, std::size_t rx_data,
                        std::size_t tx_data) noexcept;
  bool same_as_last(std::span<const std::uint8_t> rx) const noexcept;
  void accept(std::span<const std::uint8_t> rx) noexcept;
  Verdict crc_error(std::span<const std::uint8_t> rx, bool host_end) const noexcept;
  void fail(Verdict v) noexcept;
  void write_tx(std::span<std::uint8_t> out) const noexcept;
};
}  // namespace detail

// The host's end (a supervisor channel).
class HostEnd {
 public:
  // cycle_us: this end's call period. Checked; on an error nothing changes.
  ConfigError configure(const ConnectionParams& p, std::uint32_t cycle_us) noexcept;
  // Opens a new session (session != 0, different at every call: the caller's random source
  // or a counter kept across restarts). false (nothing changes) when unconfigured or 0.
  bool connect(std::uint16_t session) noexcept;
  // One cycle: checks `rx` (the device's container as the bus delivered it), then writes the
  // container to send into `tx`. `out` is the host's safety data for the next new container
  // (host_data_bytes). Sizes are checked (Length).
  Verdict cycle(std::span<const std::uint8_t> rx, std::span<const std::uint8_t> out,
                std::span<std::uint8_t> tx) noexcept;
  // The same cycle in two halves, for a channel whose outputs are decided between them
  // (controller/safety_links.hpp): receive() checks `rx` (data() then holds what it
  // delivered); transmit() writes the container to send, a new one with `out` when the
  // device's last answer was accepted in this cycle's receive(), else the one held.
  Verdict receive(std::span<const std::uint8_t> rx) noexcept;
  Verdict transmit(std::span<const std::uint8_t> out, std::span<std::uint8_t> tx) noexcept;

  // The device's data of the last valid container, or zeros (the safe values) unless the
  // session is up, has delivered data and no fault is latched.
  std::span<const std::uint8_t> data() const noexcept;
  bool data_valid() const noexcept { return c_.state == LinkState::Connected && c_.have_data; }
  LinkState state() const noexcept { return c_.state; }
  Verdict fault() const noexcept { return c_.fault; }
  std::size_t rx_bytes() const noexcept { return c_.rx_len; }
  std::size_t tx_bytes() const noexcept { return c_.tx_len; }
  std::uint32_t seq() const noexcept { return c_.own_seq; }

 private:
  Verdict check_connected(std::span<const std::uint8_t> rx) noexcept;
  Verdict check_connecting(std::span<const std::uint8_t> rx) noexcept;
  void build(std::span<const std::uint8_t> out) noexcept;
  detail::EndCommon c_{};
  std::array<std::uint8_t, kMaxData> zeros_{};
  bool pending_ = false;  // receive() accepted a new container: transmit() builds the next
};

// The device's end (a safe terminal, or a drive for its load-side encoder data).
class DeviceEnd {
 public:
  // session_seed: the first device session (then +1 per connect, never 0); must differ
  // across the device's restarts (a random number at power-up).
  ConfigError configure(const ConnectionParams& p, std::uint32_t cycle_us, std::uint16_t session_seed) noexcept;
  // One cycle: checks `rx` (the host's container), then writes the answer into `tx`.
  // `in` is the device's safety data for the next new container (device_data_bytes).
  Verdict cycle(std::span<const std::uint8_t> rx, std::span<const std::uint8_t> in,
                std::span<std::uint8_t> tx) noexcept;

  // The fail-safe rule: the safe outputs are on only while a session is up, a data
  // container was accepted in it, no fault is latched, and the last new valid container is
  // younger than the watchdog.
  bool outputs_enabled() const noexcept { return c_.state == LinkState::Connected && c_.have_data; }
  // The host's data while outputs_enabled(), otherwise zeros (every output off).
  std::span<const std::uint8_t> outputs() const noexcept;
  LinkState state() const noexcept { return c_.state; }
  Verdict fault() const noexcept { return c_.fault; }
  std::size_t rx_bytes() const noexcept { return c_.rx_len; }
  std::size_t tx_bytes() const noexcept { return c_.tx_len; }
  std::uint16_t session() const noexcept { return c_.device_session; }

 private:
  Verdict check(std::span<const std::uint8_t> rx, std::span<const std::uint8_t> in) noexcept;
  Verdict open_session(std::span<const std::uint8_t> rx) noexcept;
  detail::EndCommon c_{};
  std::uint16_t next_session_ = 1;
  std::array<std::uint8_t, kMaxData> zeros_{};
};

}  // namespace safestate::safelink

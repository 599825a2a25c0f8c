#pragma once
// The safety container of the black channel (issue 37, docs/black-channel.md): its layout,
// a connection's parameters, and encode/check of one container. The state machines of the
// two ends (link.hpp) build on these.
//
// Layout (both directions; little-endian like EtherCAT):
//   0      1  kind: version 1 in the high nibble, 0 host data, 1 device data, 2 connect,
//                   3 connect answer in the low nibble
//   1      2  connection id
//   3      2  sequence number (low 16 bits of the sender's 32-bit counter)
//   5      2  acknowledge (low 16 bits of the partner's counter last accepted)
//   7      n  safety data (n fixed per connection and direction, 0..kMaxData)
//   7+n    8  CRC-64/XZ over the connection's prefix (parameters, sessions: not sent), the
//             high 16 bits of both counters (not sent) and bytes 0..6+n.
//
// core's rules: no heap, no exceptions, no RTTI, no OS calls, no clock; every input checked.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace safestate::safelink {

inline constexpr std::size_t kHeaderBytes = 7;
inline constexpr std::size_t kCrcBytes = 8;
inline constexpr std::size_t kMaxData = 16;
inline constexpr std::size_t kMaxContainer = kHeaderBytes + kMaxData + kCrcBytes;

constexpr std::size_t container_bytes(std::size_t data_bytes) noexcept {
  return kHeaderBytes + data_bytes + kCrcBytes;
}

enum class Kind : std::uint8_t {
  HostData = 0x10,    // host -> device, in a session
  DeviceData = 0x11,  // device -> host, in a session
  Connect = 0x12,     // host -> device: opens a session (acknowledge field: host session)
  ConnectAck = 0x13,  // device -> host: sequence field: device session; acknowledge: host session
};

// Which end a container comes from.
constexpr bool is_host_kind(std::uint8_t k) noexcept {
  return k == static_cast<std::uint8_t>(Kind::HostData) || k == static_cast<std::uint8_t>(Kind::Connect);
}
constexpr bool is_device_kind(std::uint8_t k) noexcept {
  return k == static_cast<std::uint8_t>(Kind::DeviceData) || k == static_cast<std::uint8_t>(Kind::ConnectAck);
}

// The device's identity as the bus configuration names it (ESI vendor id, product code, and
// its configured station position): part of the CRC, never sent.
struct DeviceIdentity {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint16_t position = 0;
};

// One connection, configured identically on both ends (docs/black-channel.md "Connections").
struct ConnectionParams {
  std::uint16_t id = 0;                 // unique on the segment, never 0
  std::uint8_t host_data_bytes = 0;     // host -> device safety data, 0..kMaxData
  std::uint8_t device_data_bytes = 0;   // device -> host safety data, 0..kMaxData
  std::uint16_t watchdog_ms = 0;        // 1..60000
  DeviceIdentity device{};
};

enum class ConfigError : std::uint8_t {
  None,
  ZeroId,           // connection id 0
  DataTooLong,      // host_data_bytes or device_data_bytes > kMaxData
  BadWatchdog,      // watchdog_ms outside 1..60000
  BadCycle,         // cycle_us outside 50..100000
  WatchdogTooShort  // the watchdog is shorter than 2 cycles of this end (one exchange)
};

const char* to_string(ConfigError e) noexcept;

ConfigError check_params(const ConnectionParams& p) noexcept;

// The CRC register after the prefix: the connection's parameters and the two sessions
// (0 before they are known). Computed once per session.
std::uint64_t prefix_register(const ConnectionParams& p, std::uint16_t host_session,
                              std::uint16_t device_session) noexcept;

struct Header {
  Kind kind = Kind::HostData;
  std::uint16_t connection = 0;
  std::uint16_t seq = 0;
  std::uint16_t ack = 0;
};

// Writes a whole container into `out` (size container_bytes(data.size())). The high halves of
// the sender's counter (seq_hi) and of the acknowledged counter (ack_hi) enter the CRC only.
// false (and `out` unchanged) when a size is wrong.
bool encode(std::uint64_t prefix, const Header& h, std::uint16_t seq_hi, std::uint16_t ack_hi,
            std::span<const std::uint8_t> data, std::span<std::uint8_t> out) noexcept;

// The CRC a container must carry (its last eight bytes, kCrcBytes, excluded); the container must be at
// least kHeaderBytes + kCrcBytes long (false otherwise).
bool crc_matches(std::uint64_t prefix, std::uint16_t seq_hi, std::uint16_t ack_hi,
                 std::span<const std::uint8_t> container) noexcept;

// The header fields as sent (unchecked: read only after crc_matches, or to name an error).
Header read_header(std::span<const std::uint8_t> container) noexcept;
std::uint8_t read_kind(std::span<const std::uint8_t> container) noexcept;

bool all_zero(std::span<const std::uint8_t> bytes) noexcept;

}  // namespace safestate::safelink

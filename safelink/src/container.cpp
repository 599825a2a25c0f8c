#include "safestate/safelink/container.hpp"

#include "safestate/safelink/crc64.hpp"

namespace safestate::safelink {
namespace {

void put16(std::span<std::uint8_t> out, std::size_t at, std::uint16_t v) noexcept {
  out[at] = static_cast<std::uint8_t>(v & 0xFFU);
  out[at + 1U] = static_cast<std::uint8_t>(v >> 8U);
}
void put32(std::span<std::uint8_t> out, std::size_t at, std::uint32_t v) noexcept {
  for (std::size_t i = 0; i < 4U; ++i) {
    out[at + i] = static_cast<std::uint8_t>((v >> (8U * i)) & 0xFFU);
  }
}
std::uint16_t get16(std::span<const std::uint8_t> in, std::size_t at) noexcept {
  return static_cast<std::uint16_t>(static_cast<unsigned>(in[at]) | (static_cast<unsigned>(in[at + 1U]) << 8U));
}
void put64(std::span<std::uint8_t> out, std::size_t at, std::uint64_t v) noexcept {
  for (std::size_t i = 0; i < 8U; ++i) {
    out[at + i] = static_cast<std::uint8_t>((v >> (8U * i)) & 0xFFU);
  }
}
std::uint64_t get64(std::span<const std::uint8_t> in, std::size_t at) noexcept {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < 8U; ++i) {
    v |= static_cast<std::uint64_t>(in[at + i]) << (8U * i);
  }
  return v;
}

// The register after the counters' high halves and the header and data of a container.
std::uint64_t body_register(std::uint64_t prefix, std::uint16_t seq_hi, std::uint16_t ack_hi,
                            std::span<const std::uint8_t> body) noexcept {
  std::array<std::uint8_t, 4> hi{};
  put16(hi, 0, seq_hi);
  put16(hi, 2, ack_hi);
  return crc64_update(crc64_update(prefix, hi), body);
}

}  // namespace

const char* to_string(ConfigError e) noexcept {
  switch (e) {
    case ConfigError::None: return "none";
    case ConfigError::ZeroId: return "connection id is 0";
    case ConfigError::DataTooLong: return "safety data longer than 16 bytes";
    case ConfigError::BadWatchdog: return "watchdog_ms outside 1..60000";
    case ConfigError::BadCycle: return "cycle_us outside 50..100000";
    case ConfigError::WatchdogTooShort: return "watchdog shorter than 2 cycles";
  }
  return "?";
}

ConfigError check_params(const ConnectionParams& p) noexcept {
  if (p.id == 0U) {
    return ConfigError::ZeroId;
  }
  if (p.host_data_bytes > kMaxData || p.device_data_bytes > kMaxData) {
    return ConfigError::DataTooLong;
  }
  if (p.watchdog_ms == 0U || p.watchdog_ms > 60000U) {
    return ConfigError::BadWatchdog;
  }
  return ConfigError::None;
}

std::uint64_t prefix_register(const ConnectionParams& p, std::uint16_t host_session,
                              std::uint16_t device_session) noexcept {
  // "SSB1" id(2) host_data(1) device_data(1) watchdog_ms(2) vendor(4) product(4) position(2)
  // host_session(2) device_session(2): 24 bytes.
  std::array<std::uint8_t, 24> b{'S', 'S', 'B', '1'};
  put16(b, 4, p.id);
  b[6] = p.host_data_bytes;
  b[7] = p.device_data_bytes;
  put16(b, 8, p.watchdog_ms);
  put32(b, 10, p.device.vendor_id);
  put32(b, 14, p.device.product_code);
  put16(b, 18, p.device.position);
  put16(b, 20, host_session);
  put16(b, 22, device_session);
  return crc64_update(kCrc64Init, b);
}

bool encode(std::uint64_t prefix, const Header& h, std::uint16_t seq_hi, std::uint16_t ack_hi,
            std::span<const std::uint8_t> data, std::span<std::uint8_t> out) noexcept {
  if (data.size() > kMaxData || out.size() != container_bytes(data.size())) {
    return false;
  }
  out[0] = static_cast<std::uint8_t>(h.kind);
  put16(out, 1, h.connection);
  put16(out, 3, h.seq);
  put16(out, 5, h.ack);
  for (std::size_t i = 0; i < data.size(); ++i) {
    out[kHeaderBytes + i] = data[i];
  }
  const std::size_t body = kHeaderBytes + data.size();
  put64(out, body, crc64_final(body_register(prefix, seq_hi, ack_hi, out.first(body))));
  return true;
}

bool crc_matches(std::uint64_t prefix, std::uint16_t seq_hi, std::uint16_t ack_hi,
                 std::span<const std::uint8_t> container) noexcept {
  if (container.size() < kHeaderBytes + kCrcBytes) {
    return false;
  }
  const std::size_t body = container.size() - kCrcBytes;
  return crc64_final(body_register(prefix, seq_hi, ack_hi, container.first(body))) == get64(container, body);
}

Header read_header(std::span<const std::uint8_t> c) noexcept {
  Header h{};
  if (c.size() < kHeaderBytes) {
    return h;
  }
  h.kind = static_cast<Kind>(c[0]);
  h.connection = get16(c, 1);
  h.seq = get16(c, 3);
  h.ack = get16(c, 5);
  return h;
}

std::uint8_t read_kind(std::span<const std::uint8_t> c) noexcept { return c.empty() ? 0U : c[0]; }

bool all_zero(std::span<const std::uint8_t> bytes) noexcept {
  for (const std::uint8_t b : bytes) {
    if (b != 0U) {
      return false;
    }
  }
  return true;
}

}  // namespace safestate::safelink

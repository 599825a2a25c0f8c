#include "safestate/safelink/link.hpp"

namespace safestate::safelink {
namespace {

constexpr std::uint16_t lo16(std::uint32_t v) noexcept { return static_cast<std::uint16_t>(v & 0xFFFFU); }
constexpr std::uint16_t hi16(std::uint32_t v) noexcept { return static_cast<std::uint16_t>(v >> 16U); }

bool is_fault(Verdict v) noexcept { return v != Verdict::Ok && v != Verdict::Repetition; }

}  // namespace

const char* to_string(Verdict v) noexcept {
  switch (v) {
    case Verdict::Ok: return "ok";
    case Verdict::Repetition: return "repetition";
    case Verdict::Crc: return "crc";
    case Verdict::Sequence: return "sequence";
    case Verdict::Identity: return "identity";
    case Verdict::Timeout: return "timeout";
    case Verdict::NotConnected: return "not_connected";
    case Verdict::Length: return "length";
  }
  return "?";
}

const char* to_string(LinkState s) noexcept {
  switch (s) {
    case LinkState::Unconfigured: return "unconfigured";
    case LinkState::Idle: return "idle";
    case LinkState::Connecting: return "connecting";
    case LinkState::Connected: return "connected";
    case LinkState::Failed: return "failed";
  }
  return "?";
}

namespace detail {

ConfigError EndCommon::configure(const ConnectionParams& p, std::uint32_t cycle_us, std::size_t rx_data,
                                 std::size_t tx_data) noexcept {
  const ConfigError e = check_params(p);
  if (e != ConfigError::None) {
    return e;
  }
  if (cycle_us < 50U || cycle_us > 100000U) {
    return ConfigError::BadCycle;
  }
  const std::uint32_t wd_us = static_cast<std::uint32_t>(p.watchdog_ms) * 1000U;
  const std::uint32_t wd = (wd_us + cycle_us - 1U) / cycle_us;
  if (wd < 2U) {
    return ConfigError::WatchdogTooShort;
  }
  *this = EndCommon{};
  params = p;
  watchdog_cycles = wd;
  state = LinkState::Idle;
  rx_len = container_bytes(rx_data);
  tx_len = container_bytes(tx_data);
  return ConfigError::None;
}

bool EndCommon::same_as_last(std::span<const std::uint8_t> rx) const noexcept {
  for (std::size_t i = 0; i < rx_len; ++i) {
    if (rx[i] != last_rx[i]) {
      return false;
    }
  }
  return true;
}

void EndCommon::accept(std::span<const std::uint8_t> rx) noexcept {
  for (std::size_t i = 0; i < rx_len; ++i) {
    last_rx[i] = rx[i];
  }
  since_ok = 0;
}

// A container whose CRC does not match: another connection's, or one from this end's own
// direction (masquerade), when its header says so; otherwise corruption.
Verdict EndCommon::crc_error(std::span<const std::uint8_t> rx, bool host_end) const noexcept {
  const std::uint8_t k = read_kind(rx);
  if (read_header(rx).connection != params.id) {
    return Verdict::Identity;
  }
  if (host_end ? is_host_kind(k) : is_device_kind(k)) {
    return Verdict::Identity;
  }
  return Verdict::Crc;
}

void EndCommon::fail(Verdict v) noexcept {
  state = LinkState::Failed;
  fault = v;
  have_data = false;
  data = {};
  tx = {};
}

void EndCommon::write_tx(std::span<std::uint8_t> out) const noexcept {
  const bool holding = state == LinkState::Connecting || state == LinkState::Connected;
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = (holding && i < tx_len) ? tx[i] : std::uint8_t{0};
  }
}

}  // namespace detail

// ---- host --------------------------------------------------------------------------------

ConfigError HostEnd::configure(const ConnectionParams& p, std::uint32_t cycle_us) noexcept {
  return c_.configure(p, cycle_us, p.device_data_bytes, p.host_data_bytes);
}

bool HostEnd::connect(std::uint16_t session) noexcept {
  if (c_.state == LinkState::Unconfigured || session == 0U) {
    return false;
  }
  c_.state = LinkState::Connecting;
  c_.fault = Verdict::NotConnected;
  c_.host_session = session;
  c_.device_session = 0;
  c_.own_seq = 0;
  c_.partner_seq = 0;
  c_.since_ok = 0;
  c_.have_data = false;
  c_.data = {};
  c_.last_rx = {};
  const Header h{Kind::Connect, c_.params.id, 0, session};
  (void)encode(prefix_register(c_.params, 0, 0), h, 0, 0, std::span{zeros_}.first(c_.params.host_data_bytes),
               std::span{c_.tx}.first(c_.tx_len));
  return true;
}

void HostEnd::build(std::span<const std::uint8_t> out) noexcept {
  const Header h{Kind::HostData, c_.params.id, lo16(c_.own_seq), lo16(c_.partner_seq)};
  (void)encode(c_.prefix, h, hi16(c_.own_seq), hi16(c_.partner_seq), out, std::span{c_.tx}.first(c_.tx_len));
}

Verdict HostEnd::check_connecting(std::span<const std::uint8_t> rx) noexcept {
  // Until the device's answer to this session's connect arrives, anything else (zeros, its
  // containers of an older session) is "not yet": no data is used, the watchdog runs.
  const Header h = read_header(rx);
  if (read_kind(rx) != static_cast<std::uint8_t>(Kind::ConnectAck) || h.connection != c_.params.id ||
      h.ack != c_.host_session || h.seq == 0U ||
      !crc_matches(prefix_register(c_.params, c_.host_session, 0), 0, 0, rx)) {
    return Verdict::NotConnected;
  }
  c_.device_session = h.seq;
  c_.prefix = prefix_register(c_.params, c_.host_session, c_.device_session);
  c_.accept(rx);
  c_.state = LinkState::Connected;
  c_.own_seq = 1;
  c_.partner_seq = 0;
  return Verdict::Ok;
}

Verdict HostEnd::check_connected(std::span<const std::uint8_t> rx) noexcept {
  if (all_zero(rx)) {
    return Verdict::NotConnected;  // the device is fail-safe or gone
  }
  if (c_.same_as_last(rx)) {
    return Verdict::Repetition;
  }
  const std::uint8_t k = read_kind(rx);
  const Header h = read_header(rx);
  if (k == static_cast<std::uint8_t>(Kind::ConnectAck) && h.connection == c_.params.id) {
    return Verdict::Sequence;  // the device opened another session
  }
  if (k != static_cast<std::uint8_t>(Kind::DeviceData)) {
    return c_.crc_error(rx, true);
  }
  const std::uint32_t next = c_.partner_seq + 1U;
  if (!crc_matches(c_.prefix, hi16(next), hi16(c_.own_seq), rx)) {
    return c_.crc_error(rx, true);
  }
  if (h.connection != c_.params.id) {
    return Verdict::Identity;
  }
  if (h.seq != lo16(next) || h.ack != lo16(c_.own_seq)) {
    return Verdict::Sequence;
  }
  c_.partner_seq = next;
  for (std::size_t i = 0; i < c_.params.device_data_bytes; ++i) {
    c_.data[i] = rx[kHeaderBytes + i];
  }
  c_.have_data = true;
  c_.accept(rx);
  c_.own_seq += 1U;
  return Verdict::Ok;
}

Verdict HostEnd::receive(std::span<const std::uint8_t> rx) noexcept {
  pending_ = false;
  if (c_.state == LinkState::Unconfigured) {
    return Verdict::NotConnected;
  }
  const bool up = c_.state == LinkState::Connecting || c_.state == LinkState::Connected;
  if (rx.size() != c_.rx_len) {
    if (up) {
      c_.fail(Verdict::Length);
    }
    return Verdict::Length;
  }
  if (!up) {
    return Verdict::NotConnected;
  }
  if (c_.since_ok < 0xFFFFFFFFU) {
    ++c_.since_ok;
  }
  const bool connecting = c_.state == LinkState::Connecting;
  Verdict v = connecting ? check_connecting(rx) : check_connected(rx);
  if (v == Verdict::Ok) {
    pending_ = true;  // the next container goes out with the data of transmit()
  } else if (v == Verdict::Repetition || (connecting && v == Verdict::NotConnected)) {
    if (c_.since_ok >= c_.watchdog_cycles) {
      v = Verdict::Timeout;
      c_.fail(v);
    }
  } else {
    c_.fail(v);
  }
  return v;
}

Verdict HostEnd::transmit(std::span<const std::uint8_t> out, std::span<std::uint8_t> tx) noexcept {
  const bool build_now = pending_;
  pending_ = false;
  if (c_.state == LinkState::Unconfigured) {
    for (auto& b : tx) {
      b = 0;
    }
    return Verdict::NotConnected;
  }
  if (tx.size() != c_.tx_len || out.size() != c_.params.host_data_bytes) {
    if (c_.state == LinkState::Connecting || c_.state == LinkState::Connected) {
      c_.fail(Verdict::Length);
    }
    if (tx.size() == c_.tx_len) {
      c_.write_tx(tx);
    }
    return Verdict::Length;
  }
  if (build_now && c_.state == LinkState::Connected) {
    build(out);
  }
  c_.write_tx(tx);
  return Verdict::Ok;
}

Verdict HostEnd::cycle(std::span<const std::uint8_t> rx, std::span<const std::uint8_t> out,
                       std::span<std::uint8_t> tx) noexcept {
  const Verdict v = receive(rx);
  const Verdict t = transmit(out, tx);
  return (t == Verdict::Length) ? t : v;
}

std::span<const std::uint8_t> HostEnd::data() const noexcept {
  const std::size_t n = c_.params.device_data_bytes;
  return data_valid() ? std::span<const std::uint8_t>{c_.data}.first(n) : std::span<const std::uint8_t>{zeros_}.first(n);
}

// ---- device ------------------------------------------------------------------------------

ConfigError DeviceEnd::configure(const ConnectionParams& p, std::uint32_t cycle_us,
                                 std::uint16_t session_seed) noexcept {
  const ConfigError e = c_.configure(p, cycle_us, p.host_data_bytes, p.device_data_bytes);
  if (e == ConfigError::None) {
    next_session_ = (session_seed == 0U) ? std::uint16_t{1} : session_seed;
  }
  return e;
}

Verdict DeviceEnd::open_session(std::span<const std::uint8_t> rx) noexcept {
  const std::uint16_t host_session = read_header(rx).ack;
  const std::uint16_t dev_session = next_session_;
  next_session_ = (next_session_ == 0xFFFFU) ? std::uint16_t{1} : static_cast<std::uint16_t>(next_session_ + 1U);
  c_.state = LinkState::Connected;
  c_.fault = Verdict::NotConnected;
  c_.host_session = host_session;
  c_.device_session = dev_session;
  c_.own_seq = 0;
  c_.partner_seq = 0;
  c_.have_data = false;
  c_.data = {};
  c_.accept(rx);
  const Header h{Kind::ConnectAck, c_.params.id, dev_session, host_session};
  (void)encode(prefix_register(c_.params, host_session, 0), h, 0, 0,
               std::span{zeros_}.first(c_.params.device_data_bytes), std::span{c_.tx}.first(c_.tx_len));
  c_.prefix = prefix_register(c_.params, host_session, dev_session);
  return Verdict::Ok;
}

Verdict DeviceEnd::check(std::span<const std::uint8_t> rx, std::span<const std::uint8_t> in) noexcept {
  const bool connected = c_.state == LinkState::Connected;
  if (all_zero(rx)) {
    return Verdict::NotConnected;  // the host sends nothing (yet, or any more)
  }
  if (connected && c_.same_as_last(rx)) {
    return Verdict::Repetition;
  }
  const std::uint8_t k = read_kind(rx);
  const Header h = read_header(rx);
  if (k == static_cast<std::uint8_t>(Kind::Connect)) {
    if (!crc_matches(prefix_register(c_.params, 0, 0), 0, 0, rx)) {
      return c_.crc_error(rx, false);
    }
    if (h.connection != c_.params.id) {
      return Verdict::Identity;
    }
    if (h.ack == 0U || h.seq != 0U) {
      return Verdict::Sequence;  // no host sends session 0
    }
    return open_session(rx);
  }
  if (!connected) {
    return (k == static_cast<std::uint8_t>(Kind::HostData) && h.connection == c_.params.id)
               ? Verdict::NotConnected
               : c_.crc_error(rx, false);
  }
  if (k != static_cast<std::uint8_t>(Kind::HostData)) {
    return c_.crc_error(rx, false);
  }
  const std::uint32_t next = c_.partner_seq + 1U;
  if (!crc_matches(c_.prefix, hi16(next), hi16(c_.own_seq), rx)) {
    return c_.crc_error(rx, false);
  }
  if (h.connection != c_.params.id) {
    return Verdict::Identity;
  }
  if (h.seq != lo16(next) || h.ack != lo16(c_.own_seq)) {
    return Verdict::Sequence;
  }
  c_.partner_seq = next;
  for (std::size_t i = 0; i < c_.params.host_data_bytes; ++i) {
    c_.data[i] = rx[kHeaderBytes + i];
  }
  c_.have_data = true;
  c_.accept(rx);
  c_.own_seq += 1U;
  const Header out{Kind::DeviceData, c_.params.id, lo16(c_.own_seq), lo16(c_.partner_seq)};
  (void)encode(c_.prefix, out, hi16(c_.own_seq), hi16(c_.partner_seq), in, std::span{c_.tx}.first(c_.tx_len));
  return Verdict::Ok;
}

Verdict DeviceEnd::cycle(std::span<const std::uint8_t> rx, std::span<const std::uint8_t> in,
                         std::span<std::uint8_t> tx) noexcept {
  if (c_.state == LinkState::Unconfigured) {
    for (auto& b : tx) {
      b = 0;
    }
    return Verdict::NotConnected;
  }
  if (rx.size() != c_.rx_len || tx.size() != c_.tx_len || in.size() != c_.params.device_data_bytes) {
    if (c_.state == LinkState::Connected) {
      c_.fail(Verdict::Length);
    }
    if (tx.size() == c_.tx_len) {
      c_.write_tx(tx);
    }
    return Verdict::Length;
  }
  const bool was_connected = c_.state == LinkState::Connected;
  if (was_connected && c_.since_ok < 0xFFFFFFFFU) {
    ++c_.since_ok;
  }
  Verdict v = check(rx, in);
  if (c_.state == LinkState::Connected && v != Verdict::Ok) {
    if (is_fault(v)) {
      c_.fail(v);
    } else if (c_.since_ok >= c_.watchdog_cycles) {
      v = Verdict::Timeout;
      c_.fail(v);
    }
  }
  c_.write_tx(tx);
  return v;
}

std::span<const std::uint8_t> DeviceEnd::outputs() const noexcept {
  const std::size_t n = c_.params.host_data_bytes;
  return outputs_enabled() ? std::span<const std::uint8_t>{c_.data}.first(n)
                           : std::span<const std::uint8_t>{zeros_}.first(n);
}

}  // namespace safestate::safelink

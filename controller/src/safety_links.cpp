#include "safestate/controller/safety_links.hpp"

#include <span>

namespace safestate::controller {

static_assert(safelink::kMaxContainer <= hal::kLinkBytes, "a container fits a LinkFrame");

namespace {

core::Channel channel_of(const hal::LinkSpec& s) noexcept {
  return (s.channel == 'B') ? core::Channel::b : core::Channel::a;
}

bool bit_of(std::uint32_t word, unsigned b) noexcept { return ((word >> b) & 1U) != 0U; }

std::uint32_t le32(std::span<const std::uint8_t> d) noexcept {
  if (d.size() < 4U) {
    return 0U;
  }
  return static_cast<std::uint32_t>(d[0]) | (static_cast<std::uint32_t>(d[1]) << 8U) |
         (static_cast<std::uint32_t>(d[2]) << 16U) | (static_cast<std::uint32_t>(d[3]) << 24U);
}

// The data lengths a role has (docs/black-channel.md "Connections").
bool role_lengths(const hal::LinkSpec& s) noexcept {
  switch (s.role) {
    case hal::LinkRole::safe_inputs: return s.host_data_bytes == 0U && s.device_data_bytes == 4U;
    case hal::LinkRole::safe_outputs: return s.host_data_bytes == 1U && s.device_data_bytes == 1U;
    case hal::LinkRole::load_encoder:
      return s.host_data_bytes == 0U && s.device_data_bytes == 4U && s.axis >= 1U && s.axis <= core::kAxes &&
             s.counts_per_revolution != 0U;
    case hal::LinkRole::none: break;
  }
  return false;
}

}  // namespace

safelink::ConnectionParams link_params(const hal::LinkSpec& s) noexcept {
  safelink::ConnectionParams p{};
  p.id = s.id;
  p.host_data_bytes = s.host_data_bytes;
  p.device_data_bytes = s.device_data_bytes;
  p.watchdog_ms = s.watchdog_ms;
  p.device = safelink::DeviceIdentity{s.vendor_id, s.product_code, s.position};
  return p;
}

core::LinkError link_error(safelink::Verdict v) noexcept {
  switch (v) {
    case safelink::Verdict::Crc: return core::LinkError::crc;
    case safelink::Verdict::Sequence: return core::LinkError::sequence;
    case safelink::Verdict::Identity: return core::LinkError::identity;
    case safelink::Verdict::Timeout: return core::LinkError::timeout;
    case safelink::Verdict::NotConnected: return core::LinkError::not_connected;
    case safelink::Verdict::Length: return core::LinkError::length;
    case safelink::Verdict::Ok:
    case safelink::Verdict::Repetition: break;
  }
  return core::LinkError::none;
}

bool SafetyLinks::configure(const hal::LinkTable& table, core::Channel self, std::uint32_t cycle_us,
                            std::uint16_t session_seed, const char*& why) noexcept {
  why = nullptr;
  if (table.count > hal::kMaxLinks) {
    why = "more safety connections than a channel holds";
    return false;
  }
  std::array<Conn, hal::kMaxLinks> conn{};
  std::uint8_t hosted = 0;
  for (std::size_t i = 0; i < table.count; ++i) {
    const hal::LinkSpec& s = table.link[i];
    for (std::size_t j = 0; j < i; ++j) {
      if (table.link[j].id == s.id) {
        why = "two safety connections with the same id";
        return false;
      }
    }
    if ((s.channel != 'A' && s.channel != 'B') || !role_lengths(s)) {
      why = "a safety connection's channel, role or data lengths are not the protocol's";
      return false;
    }
    conn[i].spec = s;
    conn[i].hosted = (self == core::Channel::none) || (self == channel_of(s));
    if (conn[i].hosted) {
      const safelink::ConfigError e = conn[i].end.configure(link_params(s), cycle_us);
      if (e != safelink::ConfigError::None) {
        why = safelink::to_string(e);
        return false;
      }
      ++hosted;
    }
  }
  // Sessions: the seed, then one more per connection (never 0).
  std::uint16_t session = session_seed;
  for (std::size_t i = 0; i < table.count; ++i) {
    if (conn[i].hosted) {
      if (session == 0U) {
        session = 1U;
      }
      static_cast<void>(conn[i].end.connect(session));
      session = static_cast<std::uint16_t>(session + 1U);
    }
  }
  conn_ = conn;
  next_session_ = (session == 0U) ? std::uint16_t{1} : session;
  count_ = table.count;
  hosted_ = hosted;
  self_ = self;
  check_ = core::LinkCheck{};
  check_.configured = hosted != 0U;
  return true;
}

bool SafetyLinks::uses(const Conn& c) const noexcept {
  return c.hosted && ((self_ != core::Channel::none) || (c.spec.channel == 'A'));
}

// @req LINK-FAULT LINK-SAFE-VALUES
void SafetyLinks::receive(hal::ProcessImageIn& in) noexcept {
  if (hosted_ == 0U) {
    return;
  }
  bool all_up = true;
  if (!check_.fault && !check_.up) {
    check_.connection = 0U;  // named below: the first one not up yet
  }
  for (std::size_t i = 0; i < count_; ++i) {
    Conn& c = conn_[i];
    if (!c.hosted) {
      continue;
    }
    const hal::LinkFrame& f = in.link_rx[i];
    const std::size_t len = (f.len <= f.bytes.size()) ? f.len : f.bytes.size();
    static_cast<void>(c.end.receive(std::span<const std::uint8_t>{f.bytes}.first(len)));
    if (c.end.state() == safelink::LinkState::Connected) {
      c.ever_up = true;
    } else if (!c.ever_up && !check_.up && c.end.state() == safelink::LinkState::Failed &&
               c.end.fault() == safelink::Verdict::Timeout) {
      // Start-up: the device did not answer the connect in time (the bus still coming up):
      // connect again, with a new session.
      static_cast<void>(c.end.connect(next_session_));
      next_session_ = (next_session_ == 0xFFFFU) ? std::uint16_t{1} : static_cast<std::uint16_t>(next_session_ + 1U);
    }
    const bool valid = c.end.data_valid();
    if (!check_.fault && c.end.state() == safelink::LinkState::Failed) {
      check_.fault = true;  // the first found stays named (a lockout until power cycle)
      check_.connection = c.spec.id;
      check_.channel = channel_of(c.spec);
      check_.error = link_error(c.end.fault());
    }
    if (!valid) {
      all_up = false;
      if (!check_.fault && check_.connection == 0U) {
        // Not up yet (start-up): BOOT_FAILED names it if it never comes.
        check_.connection = c.spec.id;
        check_.channel = channel_of(c.spec);
        check_.error = core::LinkError::not_connected;
      }
    }
    if (!uses(c)) {
      continue;
    }
    const std::span<const std::uint8_t> d = c.end.data();  // zeros unless valid: the safe values
    if (c.spec.role == hal::LinkRole::safe_inputs) {
      const std::uint32_t w = le32(d);
      using namespace fdi;
      core::RawInputs r{};
      r.estop_a = bit_of(w, kEstopA);
      r.estop_b = bit_of(w, kEstopB);
      r.gate_a = bit_of(w, kGateA);
      r.gate_b = bit_of(w, kGateB);
      r.enable_a = bit_of(w, kEnableA);
      r.enable_b = bit_of(w, kEnableB);
      r.enable_panic = bit_of(w, kEnablePanic);
      r.mode_auto = bit_of(w, kModeAuto);
      r.mode_t1 = bit_of(w, kModeT1);
      r.mode_t2 = bit_of(w, kModeT2);
      r.reset_button = bit_of(w, kResetButton);
      r.reduced_a = bit_of(w, kReducedA);
      r.reduced_b = bit_of(w, kReducedB);
      r.field_outer_a = bit_of(w, kFieldOuterA);
      r.field_outer_b = bit_of(w, kFieldOuterB);
      r.field_inner_a = bit_of(w, kFieldInnerA);
      r.field_inner_b = bit_of(w, kFieldInnerB);
      // The distance sensor is not on the safe terminal: its reading stays the backend's.
      r.separation_mm = in.safety.separation_mm;
      r.separation_valid = in.safety.separation_valid;
      in.safety = r;
      in.contactor_closed = bit_of(w, kContactorK1);
      in.k2_closed = bit_of(w, kContactorK2);
      for (std::size_t a = 0; a < core::kAxes; ++a) {
        in.brake_released[a] = bit_of(w, kBrake1 + static_cast<unsigned>(a));
      }
    } else if (c.spec.role == hal::LinkRole::load_encoder) {
      const auto counts = static_cast<std::int32_t>(le32(d));
      const double counts_per_rad = static_cast<double>(c.spec.counts_per_revolution) / 6.283185307179586;
      in.drive[c.spec.axis - 1U].load_position_rad = static_cast<float>(static_cast<double>(counts) / counts_per_rad);
    }
  }
  if (all_up && !check_.fault) {
    check_.up = true;
    check_.connection = 0U;
    check_.error = core::LinkError::none;
  }
  // Until every connection has delivered once (start-up), no load-side reading is there to
  // compare: the encoder monitor waits, as the boot does (BootMonitor waits for `up`).
  if (!check_.up) {
    in.load_encoders = false;
  }
}

void SafetyLinks::transmit(hal::ProcessImageOut& out) noexcept {
  for (std::size_t i = 0; i < count_; ++i) {
    Conn& c = conn_[i];
    hal::LinkFrame& f = out.link_tx[i];
    if (!c.hosted) {
      f.len = 0;
      continue;
    }
    const std::size_t n = c.end.tx_bytes();
    f.len = static_cast<std::uint8_t>(n);
    const std::span<std::uint8_t> tx = std::span<std::uint8_t>{f.bytes}.first(n);
    if (c.spec.role == hal::LinkRole::safe_outputs) {
      const bool k = (c.spec.channel == 'B') ? out.contactor_k2 : out.contactor;
      const std::array<std::uint8_t, 1> data{
          static_cast<std::uint8_t>((k ? kFdoContactor : 0U) | (out.brakes_release ? kFdoBrakeRelay : 0U))};
      static_cast<void>(c.end.transmit(data, tx));
    } else {
      static_cast<void>(c.end.transmit({}, tx));
    }
  }
}

}  // namespace safestate::controller

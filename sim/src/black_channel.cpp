// The simulated world's black channel (sim/black_channel.hpp): the shipped segment's
// connections with the devices' ends, a wire that copies bytes, and its faults.
#include "safestate/sim/black_channel.hpp"

#include <cmath>
#include <cstring>
#include <span>

#include "safestate/controller/safety_links.hpp"

namespace safestate::sim {

namespace {

hal::LinkSpec spec(std::uint16_t id, char ch, hal::LinkRole role, std::uint8_t axis, std::uint32_t product,
                   std::uint16_t position) noexcept {
  hal::LinkSpec s{};
  s.id = id;
  s.channel = ch;
  s.role = role;
  s.axis = axis;
  s.host_data_bytes = (role == hal::LinkRole::safe_outputs) ? 1U : 0U;
  s.device_data_bytes = (role == hal::LinkRole::safe_outputs) ? 1U : 4U;
  s.watchdog_ms = kLinkWatchdogMs;
  s.vendor_id = kSafeVendor;
  s.product_code = product;
  s.position = position;
  s.counts_per_revolution = (role == hal::LinkRole::load_encoder) ? kLoadCountsPerRev : 0U;
  return s;
}

void put_le32(std::uint32_t v, std::span<std::uint8_t> d) noexcept {
  for (std::size_t i = 0; i < 4U; ++i) {
    d[i] = static_cast<std::uint8_t>(v >> (8U * i));
  }
}

std::size_t container_len(const hal::LinkSpec& s, WireDirection d) noexcept {
  return safelink::container_bytes(d == WireDirection::to_device ? s.host_data_bytes : s.device_data_bytes);
}

}  // namespace

hal::LinkTable shipped_links() noexcept {
  hal::LinkTable t{};
  const auto add = [&t](const hal::LinkSpec& s) { t.link[t.count++] = s; };
  for (std::uint8_t a = 1; a <= 6U; ++a) {
    add(spec(static_cast<std::uint16_t>(0xA010U + a), 'A', hal::LinkRole::load_encoder, a, kDriveProduct,
             static_cast<std::uint16_t>(a + 2U)));
    add(spec(static_cast<std::uint16_t>(0xB010U + a), 'B', hal::LinkRole::load_encoder, a, kDriveProduct,
             static_cast<std::uint16_t>(a + 2U)));
  }
  add(spec(0xA001, 'A', hal::LinkRole::safe_inputs, 0, kFdiProduct, 10));
  add(spec(0xB001, 'B', hal::LinkRole::safe_inputs, 0, kFdiProduct, 10));
  add(spec(0xA002, 'A', hal::LinkRole::safe_outputs, 0, kFdoProduct, 11));
  add(spec(0xB002, 'B', hal::LinkRole::safe_outputs, 0, kFdoProduct, 11));
  return t;
}

const char* to_string(WireFaultKind k) noexcept {
  switch (k) {
    case WireFaultKind::flip: return "flip";
    case WireFaultKind::replay: return "replay";
    case WireFaultKind::swap: return "swap";
    case WireFaultKind::delay: return "delay";
    case WireFaultKind::insert: return "insert";
  }
  return "?";
}

const char* to_string(WireDirection d) noexcept {
  return (d == WireDirection::to_device) ? "to the device" : "to the channel";
}

std::uint32_t contact_word(const core::RawInputs& s, const hal::ProcessImageIn& in) noexcept {
  using namespace controller::fdi;
  const auto b = [](bool v, unsigned n) { return v ? (1U << n) : 0U; };
  std::uint32_t w = b(s.estop_a, kEstopA) | b(s.estop_b, kEstopB) | b(s.gate_a, kGateA) | b(s.gate_b, kGateB) |
                    b(s.enable_a, kEnableA) | b(s.enable_b, kEnableB) | b(s.enable_panic, kEnablePanic) |
                    b(s.mode_auto, kModeAuto) | b(s.mode_t1, kModeT1) | b(s.mode_t2, kModeT2) |
                    b(s.reset_button, kResetButton) | b(s.reduced_a, kReducedA) | b(s.reduced_b, kReducedB) |
                    b(s.field_outer_a, kFieldOuterA) | b(s.field_outer_b, kFieldOuterB) |
                    b(s.field_inner_a, kFieldInnerA) | b(s.field_inner_b, kFieldInnerB) |
                    b(in.contactor_closed, kContactorK1) | b(in.k2_closed, kContactorK2);
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    w |= b(in.brake_released[a], kBrake1 + static_cast<unsigned>(a));
  }
  return w;
}

std::int32_t load_counts(float rad) noexcept {
  const double counts = std::round(static_cast<double>(rad) * static_cast<double>(kLoadCountsPerRev) /
                                   6.283185307179586);
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(static_cast<std::int64_t>(counts)));
}

BlackChannel::BlackChannel(std::uint32_t cycle_us) noexcept : table_(shipped_links()) {
  for (std::size_t i = 0; i < table_.count; ++i) {
    const hal::LinkSpec& s = table_.link[i];
    // Each device's first session: a seed of its own (a random number at power-up on a
    // device; fixed here, the simulated world being deterministic).
    static_cast<void>(dev_[i].configure(controller::link_params(s), cycle_us, static_cast<std::uint16_t>(0x3000U + (i * 0x101U))));
    from_dev_[i].len = static_cast<std::uint8_t>(safelink::container_bytes(s.device_data_bytes));
  }
  fdo_a_ = index_of(0xA002);
  fdo_b_ = index_of(0xB002);
}

std::size_t BlackChannel::index_of(std::uint16_t id) const noexcept {
  for (std::size_t i = 0; i < table_.count; ++i) {
    if (table_.link[i].id == id) {
      return i;
    }
  }
  return hal::kMaxLinks;
}

// The wire: each connection's slot copied as it is; the faults act on the copy.
void BlackChannel::Wire::carry(Frames& f) noexcept {
  head = (head + 1U) % kWireHistory;
  history[head] = f;
  for (std::size_t n = 0; n < pending.size(); ++n) {
    if (!active[n]) {
      continue;
    }
    WireFault& x = pending[n];
    hal::LinkFrame& slot = f[x.link];
    switch (x.kind) {
      case WireFaultKind::flip:
        slot.bytes[x.bit / 8U] = static_cast<std::uint8_t>(slot.bytes[x.bit / 8U] ^ (1U << (x.bit % 8U)));
        active[n] = false;
        break;
      case WireFaultKind::replay:  // an older container of the same connection, once
        slot.bytes = history[(head + kWireHistory - x.age) % kWireHistory][x.link].bytes;
        active[n] = false;
        break;
      case WireFaultKind::swap: {  // two connections' bytes in each other's slots, once
        const std::array<std::uint8_t, hal::kLinkBytes> t = slot.bytes;
        slot.bytes = f[x.other].bytes;
        f[x.other].bytes = t;
        active[n] = false;
        break;
      }
      case WireFaultKind::insert:  // another connection's container in this one's slot, once
        slot.bytes = f[x.other].bytes;
        active[n] = false;
        break;
      case WireFaultKind::delay:  // the container delivered last, again, for `hold` cycles
        if (x.age == 0U) {
          held[n] = delivered[x.link];
          x.age = 1U;  // holding
        }
        slot.bytes = held[n].bytes;
        if (--x.hold == 0U) {
          active[n] = false;
        }
        break;
    }
  }
  delivered = f;
}

void BlackChannel::to_channels(hal::ProcessImageIn& in) noexcept {
  Frames f = from_dev_;
  up_.carry(f);
  in.link_rx = f;
}

void BlackChannel::to_devices(const hal::ProcessImageOut& out, const DeviceWorld& world,
                              hal::ProcessImageOut& plant) noexcept {
  Frames f{};
  for (std::size_t i = 0; i < table_.count; ++i) {
    f[i].len = static_cast<std::uint8_t>(container_len(table_.link[i], WireDirection::to_device));
    if (out.link_tx[i].len != 0U) {  // none sent (a channel gone): the slot carries zeros
      f[i].bytes = out.link_tx[i].bytes;
    }
  }
  down_.carry(f);
  for (std::size_t i = 0; i < table_.count; ++i) {
    const hal::LinkSpec& s = table_.link[i];
    std::array<std::uint8_t, 4> data{};
    std::size_t n = 4;
    if (s.role == hal::LinkRole::safe_inputs) {
      put_le32(world.contacts[s.channel == 'B' ? 1U : 0U], data);
    } else if (s.role == hal::LinkRole::load_encoder) {
      put_le32(static_cast<std::uint32_t>(world.load_counts[s.axis - 1U]), data);
    } else {  // the F-DO: its output's auxiliary contact (bit 0) and its outputs on (bit 1)
      const bool closed = (s.channel == 'B') ? world.k2_closed : world.k1_closed;
      data[0] = static_cast<std::uint8_t>((closed ? 1U : 0U) | (dev_[i].outputs_enabled() ? 2U : 0U));
      n = 1;
    }
    const std::size_t rx = safelink::container_bytes(s.host_data_bytes);
    const std::size_t tx = safelink::container_bytes(s.device_data_bytes);
    static_cast<void>(dev_[i].cycle(std::span<const std::uint8_t>{f[i].bytes}.first(rx),
                                    std::span<const std::uint8_t>{data}.first(n),
                                    std::span<std::uint8_t>{from_dev_[i].bytes}.first(tx)));
  }
  plant = out;
  plant.contactor = k(0);
  plant.contactor_k2 = k(1);
  plant.brakes_release = brake_relay(0) && brake_relay(1);
}

bool BlackChannel::inject(const WireFault& f) noexcept {
  if (f.link >= table_.count) {
    return false;
  }
  const bool needs_other = f.kind == WireFaultKind::swap || f.kind == WireFaultKind::insert;
  if (needs_other && (f.other >= table_.count || f.other == f.link)) {
    return false;
  }
  if (f.kind == WireFaultKind::flip && f.bit >= 8U * container_len(table_.link[f.link], f.dir)) {
    return false;
  }
  if (f.kind == WireFaultKind::replay && (f.age < 2U || f.age >= kWireHistory)) {
    return false;
  }
  if (f.kind == WireFaultKind::delay && f.hold == 0U) {
    return false;
  }
  Wire& w = (f.dir == WireDirection::to_device) ? down_ : up_;
  for (std::size_t n = 0; n < w.pending.size(); ++n) {
    if (!w.active[n]) {
      w.pending[n] = f;
      if (f.kind == WireFaultKind::delay) {
        w.pending[n].age = 0U;  // not holding yet
      }
      w.active[n] = true;
      return true;
    }
  }
  return false;  // as many faults on this direction as it takes at once
}

void BlackChannel::clear() noexcept {
  down_.active = {};
  up_.active = {};
}

bool BlackChannel::k(std::size_t channel) const noexcept {
  const safelink::DeviceEnd& d = dev_[channel == 1U ? fdo_b_ : fdo_a_];
  return d.outputs_enabled() && (d.outputs()[0] & controller::kFdoContactor) != 0U;
}

bool BlackChannel::brake_relay(std::size_t channel) const noexcept {
  const safelink::DeviceEnd& d = dev_[channel == 1U ? fdo_b_ : fdo_a_];
  return d.outputs_enabled() && (d.outputs()[0] & controller::kFdoBrakeRelay) != 0U;
}

}  // namespace safestate::sim

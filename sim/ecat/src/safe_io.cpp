#include "safestate/ecat/safe_io.hpp"

#include <sys/random.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <random>
#include <sstream>

#include "safestate/ecat/segment.hpp"

namespace safestate::ecat {

namespace {

constexpr std::uint8_t kUsint = 0x05;
constexpr std::uint8_t kUint = 0x06;
constexpr std::uint8_t kUdint = 0x07;
static_assert(safelink::kCrcBytes % 4U == 0U, "the CRC is mapped in 32-bit parts");

std::string object_label(std::uint16_t object) {
  const bool to_device = object == kObjToDeviceA || object == kObjToDeviceB;
  const char ch = (object == kObjToDeviceA || object == kObjToHostA) ? 'A' : 'B';
  return std::string("link ") + ch + (to_device ? " out " : " in ");
}

bool parse_u32(std::string_view s, std::uint32_t hi, std::uint32_t& v) {
  const bool hex = s.size() > 2U && s[0] == '0' && (s[1] == 'x' || s[1] == 'X');
  const std::string_view digits = hex ? s.substr(2) : s;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), v, hex ? 16 : 10);
  return !digits.empty() && r.ec == std::errc{} && r.ptr == digits.data() + digits.size() && v <= hi;
}

std::uint16_t random16() {
  std::uint16_t v = 0;
  while (v == 0U) {
    if (getrandom(&v, sizeof v, 0) != static_cast<ssize_t>(sizeof v)) {
      v = static_cast<std::uint16_t>(std::random_device{}());  // never expected; still not 0 below
    }
  }
  return v;
}

}  // namespace

void add_container(Pdo& pdo, std::uint16_t object, std::size_t data_bytes, std::uint8_t data_type) {
  const std::string l = object_label(object);
  pdo.entries.push_back({object, 1, 8, kUsint, l + "kind"});
  pdo.entries.push_back({object, 2, 16, kUint, l + "connection"});
  pdo.entries.push_back({object, 3, 16, kUint, l + "sequence"});
  pdo.entries.push_back({object, 4, 16, kUint, l + "acknowledge"});
  std::uint8_t sub = 5;
  if (data_bytes > 0U) {
    pdo.entries.push_back({object, sub, static_cast<std::uint8_t>(data_bytes * 8U), data_type, l + "data"});
  }
  ++sub;
  for (std::size_t k = 0; k < safelink::kCrcBytes / 4U; ++k) {
    pdo.entries.push_back({object, sub++, 32, kUdint, l + "CRC " + std::to_string(4U * k) + ".." + std::to_string(4U * k + 3U)});
  }
}

void strip_containers(SubdeviceDesc& d) {
  for (Pdo* p : {&d.rx, &d.tx}) {
    std::erase_if(p->entries, [](const PdoEntry& e) { return is_container_object(e.index); });
  }
}

int container_offset(const Pdo& pdo, std::uint16_t object) noexcept {
  std::size_t bits = 0;
  for (const PdoEntry& e : pdo.entries) {
    if (e.index == object && e.subindex == 1U) {
      return (bits % 8U) == 0U ? static_cast<int>(bits / 8U) : -1;
    }
    bits += e.bits;
  }
  return -1;
}

int SafeLinks::find(std::uint16_t id) const noexcept {
  for (std::size_t i = 0; i < conns_.size(); ++i) {
    if (conns_[i].id == id) {
      return static_cast<int>(i);
    }
  }
  return -1;
}

void SafeLinks::configure(Conn& c, bool new_power_up) {
  if (new_power_up) {
    ++power_ups_;
  }
  safelink::ConnectionParams p;
  p.id = c.id;
  p.host_data_bytes = static_cast<std::uint8_t>(c.host_data);
  p.device_data_bytes = static_cast<std::uint8_t>(c.device_data);
  p.watchdog_ms = watchdog_ms_;
  p.device = {c.vendor, c.product, static_cast<std::uint16_t>(c.pos + 1U)};
  // A fixed seed (tests) still gives each connection and each power-up a session of its own.
  const std::uint16_t session =
      seed_ == 0U ? random16()
                  : static_cast<std::uint16_t>(((seed_ + c.id * 7U + power_ups_ * 0x100U) & 0xFFFFU) | 1U);
  c.end = safelink::DeviceEnd{};
  (void)c.end.configure(p, cycle_us_, session);  // the parameters are ours and valid (test_ecat_sim)
  c.last = safelink::Verdict::NotConnected;
  c.n_dev = 0;
  c.n_host = 0;
}

void SafeLinks::setup(const Segment& seg, std::uint32_t cycle_us, std::uint32_t seed, std::uint16_t watchdog_ms) {
  watchdog_ms_ = watchdog_ms;
  conns_.clear();
  faults_.clear();
  cycle_us_ = cycle_us;
  period_ns_ = std::uint64_t{cycle_us} * 1000U;
  seed_ = seed;
  fdo_a_ = -1;
  fdo_b_ = -1;
  for (std::size_t pos = 0; pos < seg.size(); ++pos) {
    const SubdeviceDesc& d = seg.esc(pos).desc();
    std::size_t host = 0;
    std::size_t dev = 0;
    std::size_t axis = 0;
    std::uint16_t id_a = 0;
    std::uint16_t id_b = 0;
    if (d.product_code == kProductSafeIn) {
      host = kSafeInHostData;
      dev = kSafeInDeviceData;
      id_a = kLinkSafeInA;
      id_b = kLinkSafeInB;
    } else if (d.product_code == kProductSafeOut) {
      host = kSafeOutHostData;
      dev = kSafeOutDeviceData;
      id_a = kLinkSafeOutA;
      id_b = kLinkSafeOutB;
    } else if (d.mailbox && d.device_type == 0x00020192U && pos >= 2U && pos < 2U + 6U) {
      axis = pos - 1U;  // drives at positions 3..8: axis = position - 2
      host = kEncoderHostData;
      dev = kEncoderDeviceData;
      id_a = link_drive('A', axis);
      id_b = link_drive('B', axis);
    } else {
      continue;
    }
    const std::array<std::pair<char, std::uint16_t>, 2> chans{{{'A', id_a}, {'B', id_b}}};
    for (const auto& [ch, id] : chans) {
      const int out_off = container_offset(d.rx, ch == 'A' ? kObjToDeviceA : kObjToDeviceB);
      const int in_off = container_offset(d.tx, ch == 'A' ? kObjToHostA : kObjToHostB);
      if (out_off < 0 || in_off < 0) {
        continue;  // a drive without containers (--no-safe-terminals)
      }
      Conn c;
      c.id = id;
      c.channel = ch;
      c.pos = pos;
      c.axis = axis;
      c.vendor = d.vendor_id;
      c.product = d.product_code;
      c.host_data = host;
      c.device_data = dev;
      c.out_off = static_cast<std::size_t>(out_off);
      c.in_off = static_cast<std::size_t>(in_off);
      c.rx_len = safelink::container_bytes(host);
      c.tx_len = safelink::container_bytes(dev);
      configure(c, false);
      conns_.push_back(std::move(c));
      if (d.product_code == kProductSafeOut) {
        (ch == 'A' ? fdo_a_ : fdo_b_) = static_cast<int>(conns_.size() - 1U);
      }
    }
  }
  rx_.assign(conns_.size(), {});
  tx_.assign(conns_.size(), {});
}

bool SafeLinks::out_bit(int c, std::uint8_t bit) const noexcept {
  if (c < 0) {
    return false;
  }
  const Conn& k = conns_[static_cast<std::size_t>(c)];
  return k.powered && k.end.outputs_enabled() && (k.end.outputs()[0] & bit) != 0U;
}

void SafeLinks::remember(std::array<std::array<std::uint8_t, safelink::kMaxContainer>, 8>& h, std::size_t& n,
                         const std::uint8_t* c, std::size_t len) noexcept {
  if (safelink::all_zero({c, len}) || (n > 0U && std::memcmp(h[0].data(), c, len) == 0)) {
    return;
  }
  for (std::size_t i = h.size() - 1U; i > 0U; --i) {
    h[i] = h[i - 1U];
  }
  std::memcpy(h[0].data(), c, len);
  n = std::min(n + 1U, h.size());
}

void SafeLinks::hit(std::uint64_t now_ns) noexcept {
  fault_hit_ = true;
  fault_seen_ = true;
  fault_ns_ = now_ns;
  opened_ = false;
}

// The faults of one direction on this cycle's containers (`bufs`, one per connection).
void SafeLinks::apply(LinkDir dir, std::vector<std::array<std::uint8_t, safelink::kMaxContainer>>& bufs,
                      std::uint64_t now_ns) {
  for (std::size_t f = 0; f < faults_.size();) {
    Fault& x = faults_[f];
    if (x.dir != dir) {
      ++f;
      continue;
    }
    Conn& c = conns_[static_cast<std::size_t>(x.conn)];
    const std::size_t len = dir == LinkDir::to_device ? c.rx_len : c.tx_len;
    auto& buf = bufs[static_cast<std::size_t>(x.conn)];
    bool done = true;
    switch (x.kind) {
      case Fault::Kind::flip: {
        const std::size_t bit = x.bit >= 0 ? static_cast<std::size_t>(x.bit) : safelink::kHeaderBytes * 8U;
        if (safelink::all_zero({buf.data(), len}) && x.bit < 0) {
          done = false;  // nothing sent yet: wait for a container to damage
          break;
        }
        buf[bit / 8U] = static_cast<std::uint8_t>(buf[bit / 8U] ^ (1U << (bit % 8U)));
        hit(now_ns);
        break;
      }
      case Fault::Kind::replay: {
        const auto& h = dir == LinkDir::to_device ? c.hist_dev : c.hist_host;
        const std::size_t n = dir == LinkDir::to_device ? c.n_dev : c.n_host;
        // The oldest of the last four distinct containers that differs from the current one.
        std::size_t pick = std::min<std::size_t>(n, 4U);
        while (pick > 0U && std::memcmp(h[pick - 1U].data(), buf.data(), len) == 0) {
          --pick;
        }
        if (pick == 0U) {
          done = false;  // no earlier container yet
          break;
        }
        std::memcpy(buf.data(), h[pick - 1U].data(), len);
        hit(now_ns);
        break;
      }
      case Fault::Kind::swap: {
        auto& other = bufs[static_cast<std::size_t>(x.other)];
        std::swap_ranges(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(len), other.begin());
        hit(now_ns);
        break;
      }
      case Fault::Kind::insert: {
        std::memcpy(buf.data(), bufs[static_cast<std::size_t>(x.other)].data(), len);
        hit(now_ns);
        break;
      }
      case Fault::Kind::delay: {
        if (!x.started) {
          x.started = true;
          x.until_ns = now_ns + x.ms * 1000000U;
          x.held = buf;  // the last one before: repeated while it lasts
          hit(now_ns);
        }
        if (now_ns < x.until_ns) {
          std::memcpy(buf.data(), x.held.data(), len);
          done = false;
        }
        break;
      }
    }
    if (done) {
      faults_.erase(faults_.begin() + static_cast<std::ptrdiff_t>(f));
    } else {
      ++f;
    }
  }
}

void SafeLinks::cycle(Segment& seg, std::uint32_t contacts, const std::array<std::int32_t, 6>& load_counts,
                      bool k1_closed, bool k2_closed, std::uint64_t now_ns, bool exchange) {
  outputs(seg, k1_closed, k2_closed, now_ns, exchange);
  inputs(seg, contacts, load_counts, now_ns);
}

void SafeLinks::outputs(Segment& seg, bool k1_closed, bool k2_closed, std::uint64_t now_ns, bool exchange) {
  if (conns_.empty()) {
    return;
  }
  last_cycle_ns_ = exchange ? now_ns : std::max(last_cycle_ns_ + period_ns_, now_ns - period_ns_);
  // The master's containers as the last frame left them (zeros outside OP: ETG.1000.6 6.4.1).
  for (std::size_t i = 0; i < conns_.size(); ++i) {
    Conn& c = conns_[i];
    const bool on_line = c.pos < seg.connected();
    if (!on_line) {
      c.powered = false;  // cut off: unpowered, every output off
      continue;
    }
    if (!c.powered) {
      c.powered = true;  // plugged back: a new power-up, a new session seed
      configure(c, true);
    }
    const std::span<const std::uint8_t> o = seg.esc(c.pos).outputs();
    rx_[i].fill(0);
    if (c.out_off + c.rx_len <= o.size()) {
      std::memcpy(rx_[i].data(), o.data() + c.out_off, c.rx_len);
    }
  }
  // The history holds what the master sent, before any fault (a replay repeats a real one).
  std::vector<std::array<std::uint8_t, safelink::kMaxContainer>> sent = rx_;
  apply(LinkDir::to_device, rx_, now_ns);
  for (std::size_t i = 0; i < conns_.size(); ++i) {
    Conn& c = conns_[i];
    if (!c.powered) {
      continue;
    }
    remember(c.hist_dev, c.n_dev, sent[i].data(), c.rx_len);
    if (c.product != kProductSafeOut) {
      continue;  // inputs(): with the plant cycle's sample
    }
    // Its contactor's auxiliary contact, and whether this connection's outputs are on as the
    // container arrives (the state it answers from: docs/ethercat.md).
    const bool k = c.channel == 'A' ? k1_closed : k2_closed;
    std::array<std::uint8_t, 1> data{
        static_cast<std::uint8_t>((k ? 0x01U : 0U) | (c.end.outputs_enabled() ? kSafeOutOn : 0U))};
    c.last = c.end.cycle({rx_[i].data(), c.rx_len}, {data.data(), 1}, {tx_[i].data(), c.tx_len});
  }
}

void SafeLinks::inputs(Segment& seg, std::uint32_t contacts, const std::array<std::int32_t, 6>& load_counts,
                       std::uint64_t now_ns) {
  if (conns_.empty()) {
    return;
  }
  for (std::size_t i = 0; i < conns_.size(); ++i) {
    Conn& c = conns_[i];
    if (!c.powered || c.product == kProductSafeOut) {
      continue;
    }
    std::array<std::uint8_t, 4> data{};
    const std::uint32_t v =
        (c.product == kProductSafeIn) ? contacts : static_cast<std::uint32_t>(load_counts[c.axis - 1U]);
    for (std::size_t k = 0; k < 4U; ++k) {
      data[k] = static_cast<std::uint8_t>(v >> (8U * k));
    }
    c.last = c.end.cycle({rx_[i].data(), c.rx_len}, {data.data(), c.device_data}, {tx_[i].data(), c.tx_len});
  }
  std::vector<std::array<std::uint8_t, safelink::kMaxContainer>> sent = tx_;
  apply(LinkDir::to_host, tx_, now_ns);
  for (std::size_t i = 0; i < conns_.size(); ++i) {
    Conn& c = conns_[i];
    if (!c.powered) {
      continue;
    }
    remember(c.hist_host, c.n_host, sent[i].data(), c.tx_len);
    seg.esc(c.pos).set_inputs_at(c.in_off, {tx_[i].data(), c.tx_len});
  }
  // The F-DO's outputs opening after a link fault hit a frame (`status` -> `safety`).
  const bool powered = k1() && k2();
  if (was_powered_ && !powered && fault_seen_ && !opened_) {
    opened_ = true;
    opened_us_ = (now_ns - fault_ns_) / 1000U;
  }
  was_powered_ = powered;
}

std::string SafeLinks::fault(const std::string& words) {
  std::istringstream in(words);
  std::vector<std::string> w;
  for (std::string t; in >> t;) {
    w.push_back(t);
  }
  const auto conn = [&](const std::string& s, int& out) {
    std::uint32_t v = 0;
    out = parse_u32(s, 0xFFFF, v) ? find(static_cast<std::uint16_t>(v)) : -1;
    return out >= 0;
  };
  const auto dir = [](const std::string& s, LinkDir& d) {
    if (s == "to-device" || s == "to-host") {
      d = s == "to-device" ? LinkDir::to_device : LinkDir::to_host;
      return true;
    }
    return false;
  };
  std::string ids;
  for (const Conn& c : conns_) {
    char b[8];
    std::snprintf(b, sizeof b, "0x%04X", static_cast<unsigned>(c.id));
    ids += (ids.empty() ? "" : ", ") + std::string(b);
  }
  if (conns_.empty()) {
    return "ERROR this segment has no safety connections (ecat-sim --no-safe-terminals)";
  }
  const std::string usage =
      "ERROR fault link needs flip ID DIR [BIT], replay ID DIR, swap ID1 ID2 DIR, delay ID DIR MS or insert ID FROM "
      "DIR (DIR to-device or to-host; ID one of " + ids + ")";
  if (w.empty()) {
    return usage;
  }
  Fault f;
  const std::string& verb = w[0];
  const auto len_of = [&](int c, LinkDir d) {
    const Conn& k = conns_[static_cast<std::size_t>(c)];
    return d == LinkDir::to_device ? k.rx_len : k.tx_len;
  };
  if (verb == "flip" && (w.size() == 3U || w.size() == 4U) && conn(w[1], f.conn) && dir(w[2], f.dir)) {
    f.kind = Fault::Kind::flip;
    if (w.size() == 4U) {
      std::uint32_t b = 0;
      const std::size_t bits = len_of(f.conn, f.dir) * 8U;
      if (!parse_u32(w[3], static_cast<std::uint32_t>(bits - 1U), b)) {
        return "ERROR fault link flip: BIT must be 0.." + std::to_string(bits - 1U) + " (the container's bits)";
      }
      f.bit = static_cast<int>(b);
    }
  } else if (verb == "replay" && w.size() == 3U && conn(w[1], f.conn) && dir(w[2], f.dir)) {
    f.kind = Fault::Kind::replay;
  } else if ((verb == "swap" || verb == "insert") && w.size() == 4U && conn(w[1], f.conn) && conn(w[2], f.other) &&
             dir(w[3], f.dir)) {
    f.kind = verb == "swap" ? Fault::Kind::swap : Fault::Kind::insert;
    if (f.conn == f.other) {
      return "ERROR fault link " + verb + ": two different connections";
    }
    if (len_of(f.conn, f.dir) != len_of(f.other, f.dir)) {
      return "ERROR fault link " + verb + ": " + w[1] + " and " + w[2] + " carry containers of different sizes (" +
             std::to_string(len_of(f.conn, f.dir)) + " and " + std::to_string(len_of(f.other, f.dir)) +
             " bytes) in that direction";
    }
  } else if (verb == "delay" && w.size() == 4U && conn(w[1], f.conn) && dir(w[2], f.dir)) {
    std::uint32_t ms = 0;
    if (!parse_u32(w[3], 60000, ms) || ms == 0U) {
      return "ERROR fault link delay: MS must be 1..60000";
    }
    f.kind = Fault::Kind::delay;
    f.ms = ms;
  } else {
    return usage;
  }
  faults_.push_back(f);
  return "OK";
}

void SafeLinks::clear_faults() noexcept { faults_.clear(); }

nlohmann::json SafeLinks::status() const {
  nlohmann::json links = nlohmann::json::object();
  for (const Conn& c : conns_) {
    char id[8];
    std::snprintf(id, sizeof id, "0x%04X", static_cast<unsigned>(c.id));
    const bool failed = c.end.state() == safelink::LinkState::Failed;
    links[id] = {{"position", c.pos + 1U},
                 {"powered", c.powered},
                 {"state", safelink::to_string(c.end.state())},
                 {"verdict", failed ? nlohmann::json(safelink::to_string(c.end.fault())) : nlohmann::json(nullptr)},
                 {"last", safelink::to_string(c.last)},
                 {"session", c.end.session()},
                 {"outputs_enabled", c.end.outputs_enabled()}};
  }
  nlohmann::json j = {{"links", links}, {"faults_pending", faults_.size()}};
  if (drives_power()) {
    j["fdo"] = {{"k1", k1()}, {"k2", k2()}, {"relay_a", relay_a()}, {"relay_b", relay_b()}};
  } else {
    j["fdo"] = nullptr;
  }
  j["fault_to_open_us"] = opened_ ? nlohmann::json(opened_us_) : nlohmann::json(nullptr);
  return j;
}

}  // namespace safestate::ecat

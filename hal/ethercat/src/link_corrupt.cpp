#include "safestate/hal/link_corrupt.hpp"

#include <sstream>

namespace safestate::hal::ethercat {

namespace {

bool parse_id(const std::string& w, const LinkTable& t, std::size_t& index) {
  try {
    std::size_t used = 0;
    const unsigned long v = std::stoul(w, &used, 0);
    if (used != w.size()) return false;
    for (std::size_t i = 0; i < t.count; ++i) {
      if (t.link[i].id == v) {
        index = i;
        return true;
      }
    }
  } catch (...) {
  }
  return false;
}

bool parse_uint(const std::string& w, std::uint64_t max, std::uint64_t& out) {
  try {
    std::size_t used = 0;
    const unsigned long long v = std::stoull(w, &used, 0);
    if (used != w.size() || v > max) return false;
    out = v;
    return true;
  } catch (...) {
    return false;
  }
}

}  // namespace

bool LinkCorruptor::add(const std::string& spec, const LinkTable& links, std::uint32_t cycle_us, std::string& err) {
  std::istringstream in(spec);
  std::vector<std::string> w;
  for (std::string t; in >> t;) w.push_back(t);
  const std::string usage =
      "expected KIND ID [ID2] DIR [ARG] at=CYCLES (flip ID DIR [BIT], replay ID DIR, swap ID ID2 DIR, "
      "delay ID DIR MS, insert ID FROM DIR; DIR to-device or to-host)";
  if (w.size() < 4U || w.back().rfind("at=", 0) != 0) {
    err = "--corrupt \"" + spec + "\": " + usage;
    return false;
  }
  Fault f{};
  f.text = spec;
  if (!parse_uint(w.back().substr(3), 100000000ULL, f.at) || f.at == 0U) {
    err = "--corrupt \"" + spec + "\": at= must be a cycle count from 1";
    return false;
  }
  w.pop_back();
  const std::string& kind = w[0];
  if (!parse_id(w[1], links, f.a)) {
    err = "--corrupt \"" + spec + "\": " + w[1] + " is no safety connection of this bus";
    return false;
  }
  std::size_t dir_at = 2;
  if (kind == "swap" || kind == "insert") {
    if (w.size() < 4U || !parse_id(w[2], links, f.b)) {
      err = "--corrupt \"" + spec + "\": " + (w.size() > 2U ? w[2] : std::string("?")) +
            " is no safety connection of this bus";
      return false;
    }
    if (f.b == f.a) {
      err = "--corrupt \"" + spec + "\": the two connections must differ";
      return false;
    }
    dir_at = 3;
  }
  if (w.size() <= dir_at || (w[dir_at] != "to-device" && w[dir_at] != "to-host")) {
    err = "--corrupt \"" + spec + "\": DIR must be to-device or to-host";
    return false;
  }
  f.to_device = w[dir_at] == "to-device";
  const std::size_t rest = w.size() - dir_at - 1U;
  if (kind == "flip") {
    f.kind = Kind::flip;
    if (rest > 1U) {
      err = "--corrupt \"" + spec + "\": " + usage;
      return false;
    }
    if (rest == 1U) {
      std::uint64_t bit = 0;
      if (!parse_uint(w[dir_at + 1U], 8U * kLinkBytes - 1U, bit)) {
        err = "--corrupt \"" + spec + "\": BIT must be a bit of the container";
        return false;
      }
      f.bit = static_cast<int>(bit);
    }
  } else if (kind == "replay" || kind == "swap" || kind == "insert") {
    f.kind = (kind == "replay") ? Kind::replay : (kind == "swap" ? Kind::swap : Kind::insert);
    if (rest != 0U) {
      err = "--corrupt \"" + spec + "\": " + usage;
      return false;
    }
  } else if (kind == "delay") {
    f.kind = Kind::delay;
    std::uint64_t ms = 0;
    if (rest != 1U || !parse_uint(w[dir_at + 1U], 60000U, ms) || ms == 0U) {
      err = "--corrupt \"" + spec + "\": delay needs MS, 1..60000";
      return false;
    }
    f.cycles = (ms * 1000U + cycle_us - 1U) / cycle_us;
  } else {
    err = "--corrupt \"" + spec + "\": unknown KIND " + kind + "; " + usage;
    return false;
  }
  faults_.push_back(f);
  return true;
}

void LinkCorruptor::apply(bool to_device, std::uint64_t n, std::array<LinkFrame, kMaxLinks>& fr) noexcept {
  auto& hist = to_device ? hist_to_device_ : hist_to_host_;
  const std::array<LinkFrame, kMaxLinks> clean = fr;
  for (Fault& f : faults_) {
    if (f.to_device != to_device || n < f.at) continue;
    const bool first = !f.acted;
    switch (f.kind) {
      case Kind::flip:
        if (first) {
          LinkFrame& c = fr[f.a];
          const int bit = (f.bit >= 0) ? f.bit : 7 * 8;  // byte 7: the data's first, or the CRC's
          if (c.len != 0U && static_cast<std::size_t>(bit / 8) < c.len) {
            c.bytes[static_cast<std::size_t>(bit / 8)] ^= static_cast<std::uint8_t>(1U << (bit % 8));
          }
        }
        break;
      case Kind::replay:
        if (first) fr[f.a] = hist[f.a][kHistory - 1U];
        break;
      case Kind::swap:
        if (first) {
          fr[f.a] = clean[f.b];
          fr[f.b] = clean[f.a];
        }
        break;
      case Kind::insert:
        if (first) fr[f.a] = clean[f.b];
        break;
      case Kind::delay:
        if (first) f.held = hist[f.a][0];
        if (n < f.at + f.cycles) fr[f.a] = f.held;
        break;
    }
    f.acted = true;
  }
  // What was on its way (before any fault), the newest first.
  for (std::size_t i = 0; i < kMaxLinks; ++i) {
    for (std::size_t k = kHistory - 1U; k > 0U; --k) hist[i][k] = hist[i][k - 1U];
    hist[i][0] = clean[i];
  }
}

void LinkCorruptor::to_host(std::uint64_t n, std::array<LinkFrame, kMaxLinks>& rx) noexcept { apply(false, n, rx); }
void LinkCorruptor::to_device(std::uint64_t n, std::array<LinkFrame, kMaxLinks>& tx) noexcept { apply(true, n, tx); }

std::vector<std::string> LinkCorruptor::done() const {
  std::vector<std::string> out;
  for (const Fault& f : faults_) {
    if (f.acted) out.push_back(f.text);
  }
  return out;
}

}  // namespace safestate::hal::ethercat

#include "safestate/ecat/segment.hpp"

#include <algorithm>
#include <cstring>

namespace safestate::ecat {

namespace {
std::uint16_t get16(const std::uint8_t* p) noexcept { return static_cast<std::uint16_t>(p[0] | (p[1] << 8U)); }
void put16(std::uint8_t* p, std::uint16_t v) noexcept {
  p[0] = static_cast<std::uint8_t>(v & 0xFFU);
  p[1] = static_cast<std::uint8_t>(v >> 8U);
}
constexpr std::size_t kEthHeader = 14;
constexpr std::size_t kDgHeader = 10;
}  // namespace

Segment::Segment(const std::vector<SubdeviceDesc>& devices) {
  escs_.reserve(devices.size());
  for (const SubdeviceDesc& d : devices) {
    escs_.emplace_back(d);
    const std::size_t p = escs_.size() - 1U;
    escs_.back().set_drift_ppm(kDefaultDriftPpm[p % std::size(kDefaultDriftPpm)]);
    // powered up one after the other, so that their local times differ (as on a real line)
    escs_.back().set_power_on_lag_ns(5000000U + 1300000U * (devices.size() - p));
  }
  scratch_.resize(2048);
  update_dl_status();
}

std::size_t Segment::connected() const noexcept { return (cut_ == 0U) ? escs_.size() : cut_ - 1U; }

void Segment::cut_before(std::size_t position) noexcept {
  cut_ = (position > escs_.size()) ? 0U : position;
  // A subdevice that loses its upstream link loses its power in this emulation: it
  // comes back in INIT, as a real one re-plugged would.
  for (std::size_t i = connected(); i < escs_.size(); ++i) {
    escs_[i].reset();
  }
  update_dl_status();
}

// DL status (0x0110): link and communication on port 0 always, on port 1 only where a
// subdevice follows; otherwise the port's loop is closed (ETG.1000.4 6.1.4).
void Segment::update_dl_status() noexcept {
  const std::size_t n = connected();
  for (std::size_t i = 0; i < escs_.size(); ++i) {
    const bool next = (i + 1U) < n;
    std::uint16_t s = 0x0001 | 0x0010 | 0x0200;  // PDI operational, port 0 link, port 0 communication
    s |= next ? (0x0020 | 0x0800) : 0x0400;     // port 1: link + communication, or loop closed
    s |= 0x1000 | 0x4000;                        // ports 2 and 3: loop closed
    escs_[i].set_downstream_loop_ns(next ? 2U * kHopNs * (n - 1U - i) : 0U);
    std::uint8_t b[2];
    put16(b, s);
    // DL status is read-only from the wire: set it through the application side.
    escs_[i].pdi_write(reg::dl_status, b);
  }
}

bool Segment::process(std::span<std::uint8_t> frame, std::uint64_t now_ns) noexcept {
  if (frame.size() < kEthHeader + 2U || get16(&frame[12]) != ((kEtherTypeEcat >> 8U) | ((kEtherTypeEcat & 0xFFU) << 8U))) {
    return false;
  }
  const std::uint16_t h = get16(&frame[kEthHeader]);
  const std::size_t len = h & 0x7FFU;
  if ((h >> 12U) != 1U || kEthHeader + 2U + len > frame.size() || connected() == 0U) {
    return false;
  }
  if (silent_) {
    return false;
  }
  if (drop_ > 0U) {
    --drop_;
    return false;
  }
  ++frames_;
  frame[6] |= 0x02U;  // the first ESC marks the source address as locally administered
  if (corrupt_ > 0U) {
    --corrupt_;  // the ESCs see a frame check error: no datagram is processed
    return true;
  }
  std::span<std::uint8_t> rest = frame.subspan(kEthHeader + 2U, len);
  bool pd_written = false;
  while (rest.size() >= kDgHeader + 2U) {
    const std::size_t dlen = get16(&rest[6]) & 0x7FFU;
    if (kDgHeader + dlen + 2U > rest.size()) {
      return false;
    }
    const bool more = (get16(&rest[6]) & 0x8000U) != 0U;
    if (!datagram(rest.subspan(0, kDgHeader + dlen + 2U), now_ns, pd_written)) {
      return false;
    }
    rest = rest.subspan(kDgHeader + dlen + 2U);
    if (!more) {
      break;
    }
  }
  if (freeze_at_op_ns_ > 0U && pd_written &&
      std::any_of(escs_.begin(), escs_.end(), [](const Esc& e) { return e.state() == AlState::op; })) {
    freeze(now_ns, freeze_at_op_ns_);
    freeze_at_op_ns_ = 0;
    return false;  // processed, but the stall took the master as it went out: it never sees the answer
  }
  if (lose_every_ > 0U && ++lose_count_ >= lose_every_) {
    lose_count_ = 0;
    ++lost_replies_;
    return false;  // processed, but the answer never reaches the master
  }
  return true;
}

bool Segment::datagram(std::span<std::uint8_t> dg, std::uint64_t now_ns, bool& pd_written) noexcept {
  const auto c = static_cast<Cmd>(dg[0]);
  const std::size_t dlen = get16(&dg[6]) & 0x7FFU;
  std::span<std::uint8_t> data = dg.subspan(kDgHeader, dlen);
  std::uint16_t wkc = get16(&dg[kDgHeader + dlen]);
  const std::uint16_t adp = get16(&dg[2]);
  const std::uint16_t ado = get16(&dg[4]);
  if (dg[0] > static_cast<std::uint8_t>(Cmd::FRMW)) {
    return true;  // unknown command: passed on untouched
  }
  if (c == Cmd::LRD || c == Cmd::LWR || c == Cmd::LRW) {
    const std::uint32_t addr = static_cast<std::uint32_t>(adp) | (static_cast<std::uint32_t>(ado) << 16U);
    logical(c, addr, data, wkc, now_ns, pd_written);
  } else if (c != Cmd::NOP) {
    physical(c, adp, ado, data, wkc, now_ns);
    const bool increments = c == Cmd::APRD || c == Cmd::APWR || c == Cmd::APRW || c == Cmd::ARMW ||
                            c == Cmd::BRD || c == Cmd::BWR || c == Cmd::BRW;
    if (increments) {
      put16(&dg[2], static_cast<std::uint16_t>(adp + connected()));
    }
  }
  put16(&dg[kDgHeader + dlen], wkc);
  return true;
}

void Segment::physical(Cmd c, std::uint16_t adp, std::uint16_t ado, std::span<std::uint8_t> data, std::uint16_t& wkc,
                       std::uint64_t now_ns) noexcept {
  const std::size_t n = connected();
  std::span<std::uint8_t> tmp(scratch_.data(), data.size());
  for (std::size_t p = 0; p < n; ++p) {
    Esc& e = escs_[p];
    const std::uint64_t t = now_ns + kHopNs * p;  // when the frame reaches it
    e.dc_at(t);
    const bool auto_inc = c == Cmd::APRD || c == Cmd::APWR || c == Cmd::APRW || c == Cmd::ARMW;
    const bool fixed = c == Cmd::FPRD || c == Cmd::FPWR || c == Cmd::FPRW || c == Cmd::FRMW;
    const bool addressed = (auto_inc && static_cast<std::uint16_t>(adp + p) == 0U) ||
                           (fixed && e.station_address() == adp);
    switch (c) {
      case Cmd::APRD:
      case Cmd::FPRD:
        if (addressed && e.read(ado, data)) {
          ++wkc;
        }
        break;
      case Cmd::APWR:
      case Cmd::FPWR:
        if (addressed && e.write(ado, data, t)) {
          ++wkc;
        }
        break;
      case Cmd::APRW:
      case Cmd::FPRW:
        if (addressed) {
          const bool r = e.read(ado, tmp);
          const bool w = e.write(ado, data, t);
          if (r) {
            std::copy(tmp.begin(), tmp.end(), data.begin());
          }
          wkc = static_cast<std::uint16_t>(wkc + (r ? 1U : 0U) + (w ? 2U : 0U));
        }
        break;
      case Cmd::BRD:
        if (e.read(ado, tmp)) {
          for (std::size_t i = 0; i < data.size(); ++i) {
            data[i] = static_cast<std::uint8_t>(data[i] | tmp[i]);
          }
          ++wkc;
        }
        break;
      case Cmd::BWR:
        if (e.write(ado, data, t)) {
          ++wkc;
        }
        break;
      case Cmd::BRW: {
        const bool r = e.read(ado, tmp);
        const bool w = e.write(ado, data, t);
        for (std::size_t i = 0; i < data.size() && r; ++i) {
          data[i] = static_cast<std::uint8_t>(data[i] | tmp[i]);
        }
        wkc = static_cast<std::uint16_t>(wkc + (r ? 1U : 0U) + (w ? 2U : 0U));
        break;
      }
      case Cmd::ARMW:
      case Cmd::FRMW:
        // the addressed one reads, every other one writes what passes
        if (addressed ? e.read(ado, data) : e.write(ado, data, t)) {
          ++wkc;
        }
        break;
      default: break;
    }
  }
}

// Two passes: every subdevice takes its outputs, the applications run (on_pd_), then
// every subdevice puts its inputs; with disjoint logical areas this is what one pass
// through the line gives, with the inputs one exchange fresher.
void Segment::logical(Cmd c, std::uint32_t addr, std::span<std::uint8_t> data, std::uint16_t& wkc,
                      std::uint64_t now_ns, bool& pd_written) noexcept {
  const std::size_t n = connected();
  bool wrote = false;
  if (c == Cmd::LWR || c == Cmd::LRW) {
    for (std::size_t p = 0; p < n; ++p) {
      if (p + 1U != no_pd_ && escs_[p].logical_write(addr, data, now_ns + kHopNs * p)) {
        wkc = static_cast<std::uint16_t>(wkc + ((c == Cmd::LRW) ? 2U : 1U));
        wrote = true;
      }
    }
  }
  if (wrote && !pd_written) {
    pd_written = true;
    sample_sync_errors(now_ns);
    if (on_pd_) {
      on_pd_();
    }
  }
  if (c == Cmd::LRD || c == Cmd::LRW) {
    for (std::size_t p = 0; p < n; ++p) {
      if (p + 1U != no_pd_ && escs_[p].logical_read(addr, data)) {
        ++wkc;
      }
    }
  }
}

void Segment::poll(std::uint64_t now_ns) noexcept {
  for (std::size_t p = 0; p < connected(); ++p) {
    escs_[p].dc_at(now_ns);
    escs_[p].poll_watchdog(now_ns);
  }
}

std::int64_t Segment::sync_error_ns(std::size_t i, std::uint64_t now_ns) noexcept {
  const std::size_t ref = dc_reference();
  if (ref >= escs_.size() || i >= escs_.size()) {
    return 0;
  }
  return static_cast<std::int64_t>(escs_[i].system_time(now_ns) - escs_[ref].system_time(now_ns));
}

// Every process-data frame: each subdevice whose SYNC0 runs records its sync error.
void Segment::sample_sync_errors(std::uint64_t now_ns) noexcept {
  for (std::size_t p = 0; p < connected(); ++p) {
    if (escs_[p].desc().dc_sync0_required && escs_[p].sync0_running(now_ns)) {
      escs_[p].dc_stats().record(sync_error_ns(p, now_ns), now_ns, escs_[p].dc_input_gap_ns(now_ns));
    }
  }
}

}  // namespace safestate::ecat

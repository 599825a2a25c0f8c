// The emulated ESC: register space, AL state machine (ETG.1000.6 6.4), SII access
// (ETG.1000.4 6.4), FMMUs (ETG.1000.4 6.6), sync-manager checks and the process-data
// watchdog.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "safestate/ecat/esc.hpp"

namespace safestate::ecat {

namespace {

// Bit `i % 8` of a byte of a bit-addressed (FMMU) range.
constexpr bool bit_at(std::uint8_t byte, std::uint64_t i) noexcept {
  return ((static_cast<unsigned>(byte) >> (i % 8U)) & 1U) != 0U;
}

void put_bit(std::uint8_t& byte, std::uint64_t i, bool v) noexcept {
  const auto m = static_cast<std::uint8_t>(1U << (i % 8U));
  byte = static_cast<std::uint8_t>(v ? (byte | m) : (byte & ~m));
}

constexpr std::uint8_t kFmmuRead = 1U;   // FMMU type register (+11): bit 0 read, bit 1 write
constexpr std::uint8_t kFmmuWrite = 2U;

// ETG.1000.4 6.6: every active FMMU of the direction maps a bit range of the logical
// address space onto a bit range of the ESC's memory. f(memory bit, datagram bit) for
// each bit of the datagram [logical, logical + bytes) that one of them maps; true when
// there was at least one.
template <class F>
bool for_each_mapped_bit(const std::uint8_t* mem, std::uint32_t logical, std::size_t bytes, std::uint8_t dir,
                         F&& f) noexcept {
  bool hit = false;
  const std::uint64_t dg_first = static_cast<std::uint64_t>(logical) * 8U;
  const std::uint64_t dg_last = dg_first + bytes * 8U - 1U;
  for (std::size_t i = 0; i < kFmmus && bytes != 0U; ++i) {
    const std::uint8_t* fm = &mem[reg::fmmu + i * 16U];
    const std::uint32_t lstart = static_cast<std::uint32_t>(fm[0] | (fm[1] << 8U) | (fm[2] << 16U)) |
                                 (static_cast<std::uint32_t>(fm[3]) << 24U);
    const auto len = static_cast<std::uint16_t>(fm[4] | (fm[5] << 8U));
    const auto phys = static_cast<std::uint16_t>(fm[8] | (fm[9] << 8U));
    if ((fm[12] & 1U) == 0U || (fm[11] & dir) == 0U || len == 0U) {
      continue;
    }
    const std::uint64_t first = static_cast<std::uint64_t>(lstart) * 8U + (fm[6] & 7U);
    const std::uint64_t last = (static_cast<std::uint64_t>(lstart) + len - 1U) * 8U + (fm[7] & 7U);
    const std::uint64_t lo = std::max(first, dg_first);
    const std::uint64_t hi = std::min(last, dg_last);
    for (std::uint64_t b = lo; b <= hi && lo <= hi; ++b) {
      const std::uint64_t pbit = static_cast<std::uint64_t>(phys) * 8U + (fm[10] & 7U) + (b - first);
      if (pbit / 8U >= kEscMemory) {
        break;
      }
      f(pbit, b - dg_first);
      hit = true;
    }
  }
  return hit;
}

struct Range {
  std::uint16_t first;
  std::uint16_t last;
};

// The bytes a master may write (the ESC datasheets' "ECAT write" column); everything
// else below the process RAM is read-only from the wire.
constexpr Range kWritable[] = {
    {0x0010, 0x0011},  // configured station address
    {0x0100, 0x0103},  // DL control
    {0x0108, 0x0109},  // physical read/write offset
    {0x0120, 0x0121},  // AL control
    {0x0200, 0x0203},  // ECAT event mask
    {0x0300, 0x0313},  // error counters (a write clears them)
    {0x0400, 0x0401},  // watchdog divider
    {0x0410, 0x0411},  // watchdog time PDI
    {0x0420, 0x0421},  // watchdog time process data
    {0x0442, 0x0443},  // watchdog counters
    {0x0500, 0x0500},  // EEPROM configuration
    {0x0502, 0x050F},  // EEPROM control, address, data
    {0x0600, 0x06FF},  // FMMUs
    {0x0800, 0x087F},  // sync managers (status and PDI control bytes excepted below)
    // distributed clocks: 0x0900..0x0917 are written for their side effects only (a write
    // to 0x0900 latches the receive times, one to 0x0910 is the drift-control input)
    {0x0920, 0x092B},  // system time offset, system time delay
    {0x0930, 0x0931},  // speed counter start
    {0x0934, 0x0935},  // filter depths
    {0x0980, 0x0983},  // cyclic unit control, activation, pulse length
    {0x0990, 0x0997},  // start time of cyclic operation
    {0x09A0, 0x09A9},  // SYNC0 / SYNC1 cycle times, latch control
};

// The drift-control loop of the emulated ESC (the datasheets leave the loop to the chip; it
// is bounded here): a PI controller on the difference between the system time received from
// the reference clock (plus the delay 0x0928) and its own. The proportional part slews half
// the difference out at 200 ppm (the clock is never stepped); the integral part is a rate
// correction (at most +-200 ppm) that grows by kLoopI x difference x time, so that it takes up
// the clock's drift against the reference whatever the rate of the inputs (conditional
// integration against wind-up).
constexpr double kLoopP = 0.5;
constexpr double kLoopI = 2e-14;  // per ns of difference per ns of time
constexpr double kMaxRate = 200e-6;
constexpr double kMaxRateStep = 5e-6;  // one input moves the rate correction by at most this
constexpr double kSlewRate = 200e-6;
constexpr std::uint64_t kTickNs = 10;  // a 100 MHz local clock

bool writable(std::uint32_t a) noexcept {
  if (a >= reg::process_ram) {
    return a < kEscMemory;
  }
  if (a >= reg::sm && a < reg::sm + 0x80U && ((a & 7U) == 5U || (a & 7U) == 7U)) {
    return false;
  }
  return std::any_of(std::begin(kWritable), std::end(kWritable),
                     [a](const Range& r) { return a >= r.first && a <= r.last; });
}

bool touches(std::uint16_t address, std::size_t n, std::uint16_t first, std::uint16_t last) noexcept {
  const std::uint32_t end = static_cast<std::uint32_t>(address) + static_cast<std::uint32_t>(n);
  return n > 0U && address <= last && end > first;
}

bool valid_state(std::uint8_t s) noexcept { return s == 1U || s == 2U || s == 3U || s == 4U || s == 8U; }

}  // namespace

Esc::Esc(SubdeviceDesc desc) : desc_(std::move(desc)), sii_(build_sii(desc_)) {
  if (desc_.mailbox) {
    od_ = coe::Dictionary(desc_);
  }
  reset();
}

std::uint16_t Esc::u16(std::uint16_t a) const noexcept {
  return static_cast<std::uint16_t>(mem_[a] | (mem_[a + 1U] << 8U));
}

void Esc::put16(std::uint16_t a, std::uint16_t v) noexcept {
  mem_[a] = static_cast<std::uint8_t>(v & 0xFFU);
  mem_[a + 1U] = static_cast<std::uint8_t>(v >> 8U);
}

void Esc::reset() {
  mem_.fill(0);
  mem_[reg::type] = 0xE0;  // not a real ESC type: an emulation
  mem_[reg::fmmu_count] = kFmmus;
  mem_[reg::sm_count] = kSyncManagers;
  mem_[reg::ram_size] = 8;       // KiB of process RAM
  mem_[reg::port_desc] = 0x0F;   // ports 0 and 1: MII
  // bit-wise FMMU mapping; DC supported (bit 2) with 64-bit system time (bit 3) and
  // enhanced DC SYNC activation, 0x0981..0x0984 (bit 8)
  put16(reg::features, 0x010C);
  put16(reg::dc_speed_start, 0x1000);
  powered_ = false;
  corr_ns_ = 0.0;
  corr_host_ns_ = 0;
  slew_left_ns_ = 0.0;
  rate_i_ = 0.0;
  last_ctl_ns_ = 0;
  pending_op_ = false;
  sync0_armed_ = false;
  sync0_started_ = false;
  last_sync0_k_ = 0;
  dc_stats_ = DcStats{};
  put16(reg::wdg_divider, 2498); // 100 us watchdog ticks
  put16(0x0410, 1000);
  put16(reg::wdg_time_pd, 1000);  // 100 ms
  put16(reg::pdi_control, 0x0004);
  set_al(static_cast<std::uint8_t>(AlState::init), false, al_code::none);
  last_output_ns_ = 0;
  od_.reset();
  mailbox_counter_ = 0;
}

bool Esc::mailbox_sm(bool master_writes, MailboxSm& out) const noexcept {
  for (std::size_t i = 0; i < kSyncManagers; ++i) {
    const auto base = static_cast<std::uint16_t>(reg::sm + i * 8U);
    const std::uint8_t control = mem_[base + 4U];
    const bool enabled = (mem_[base + 6U] & 1U) != 0U;
    // control bits 0..1: 2 = mailbox; bits 2..3: 1 = the master writes, 0 = it reads
    if (enabled && (control & 0x03U) == 0x02U && ((control >> 2U) & 0x03U) == (master_writes ? 1U : 0U)) {
      out = MailboxSm{base, u16(base), u16(static_cast<std::uint16_t>(base + 2U))};
      return out.bytes > 0U && static_cast<std::size_t>(out.start) + out.bytes <= kEscMemory;
    }
  }
  return false;
}

void Esc::set_mailbox_full(const MailboxSm& m, bool full) noexcept {
  mem_[m.base + 5U] = static_cast<std::uint8_t>(full ? (mem_[m.base + 5U] | 0x08U) : (mem_[m.base + 5U] & ~0x08U));
}

// The application side of the mailbox: a full receive mailbox is taken and answered as soon
// as the send mailbox is free (outside INIT, where there is no mailbox communication).
void Esc::serve_mailbox() noexcept {
  MailboxSm rx;
  MailboxSm tx;
  if (state() == AlState::init || !mailbox_sm(true, rx) || !mailbox_sm(false, tx) || !mailbox_full(rx) ||
      mailbox_full(tx)) {
    return;
  }
  const std::vector<std::uint8_t> reply =
      coe::serve(od_, {&mem_[rx.start], rx.bytes}, {&mem_[desc_.out_address], desc_.rx.bytes()},
                 {&mem_[desc_.in_address], desc_.tx.bytes()}, state(), tx.bytes, mailbox_counter_);
  set_mailbox_full(rx, false);
  if (reply.empty()) {
    return;
  }
  std::fill(mem_.begin() + tx.start, mem_.begin() + tx.start + tx.bytes, 0);
  std::copy_n(reply.begin(), std::min<std::size_t>(reply.size(), tx.bytes), mem_.begin() + tx.start);
  set_mailbox_full(tx, true);
}

bool Esc::read(std::uint16_t address, std::span<std::uint8_t> out) noexcept {
  MailboxSm tx;
  const bool mbx = mailbox_sm(false, tx) && touches(address, out.size(), tx.start, static_cast<std::uint16_t>(tx.start + tx.bytes - 1U));
  if (mbx && !mailbox_full(tx)) {
    return false;  // nothing to read: the datagram is not counted
  }
  for (std::size_t i = 0; i < out.size(); ++i) {
    const std::size_t a = static_cast<std::size_t>(address) + i;
    out[i] = (a < kEscMemory) ? mem_[a] : 0U;
  }
  if (mbx && touches(address, out.size(), static_cast<std::uint16_t>(tx.start + tx.bytes - 1U),
                     static_cast<std::uint16_t>(tx.start + tx.bytes - 1U))) {
    set_mailbox_full(tx, false);  // the last byte read: the mailbox is free again
    serve_mailbox();
  }
  return true;
}

bool Esc::write(std::uint16_t address, std::span<const std::uint8_t> in, std::uint64_t now_ns) noexcept {
  MailboxSm rx;
  const bool mbx = mailbox_sm(true, rx) && touches(address, in.size(), rx.start, static_cast<std::uint16_t>(rx.start + rx.bytes - 1U));
  if (mbx && mailbox_full(rx)) {
    return false;  // the previous request is not taken yet: not counted, nothing written
  }
  for (std::size_t i = 0; i < in.size(); ++i) {
    const std::uint32_t a = static_cast<std::uint32_t>(address) + static_cast<std::uint32_t>(i);
    if (writable(a)) {
      mem_[a] = in[i];
    }
  }
  dc_at(now_ns);
  if (touches(address, in.size(), reg::dc_recv_port0, reg::dc_recv_port0 + 3U)) {
    dc_latch_receive_times(now_ns);
  }
  if (touches(address, in.size(), reg::dc_system_time, reg::dc_system_time + 7U)) {
    dc_control(in, static_cast<std::size_t>(reg::dc_system_time > address ? reg::dc_system_time - address : 0U), now_ns);
    dc_at(now_ns);  // the register shows the own time again, not what was written
  }
  if (touches(address, in.size(), reg::dc_speed_start, reg::dc_speed_start + 1U)) {
    dc_reset_loop(now_ns);
  }
  if (touches(address, in.size(), reg::dc_activation, reg::dc_activation)) {
    // Activated with the start time still ahead, SYNC0 starts there; one already past is
    // never reached (a real ESC waits for its 32-bit time to wrap, ~4.3 s, at best).
    sync0_armed_ = sync0_activated() && u64(reg::dc_start_time) > system_time(now_ns);
    sync0_started_ = false;
    last_sync0_k_ = 0;
    pending_op_ = pending_op_ && sync0_armed_;
    dc_at(now_ns);
  }
  if (touches(address, in.size(), 0x0300, 0x0313)) {
    std::fill(mem_.begin() + 0x0300, mem_.begin() + 0x0314, 0);  // a write clears the counters
  }
  if (touches(address, in.size(), reg::eep_control, reg::eep_control + 1U)) {
    on_eeprom_control();
  }
  if (touches(address, in.size(), reg::al_control, reg::al_control + 1U)) {
    pending_op_ = false;  // a new request replaces one that waited for SYNC0
    on_al_control(now_ns);
    last_output_ns_ = now_ns;  // the watchdog counts from entering the state
  }
  if (!desc_.rx.entries.empty() &&
      touches(address, in.size(), desc_.out_address, static_cast<std::uint16_t>(desc_.out_address + desc_.rx.bytes() - 1U))) {
    last_output_ns_ = now_ns;
  }
  if (touches(address, in.size(), reg::sm, reg::sm + 0x7FU)) {
    // A sync manager disabled (or reconfigured) loses what its mailbox held.
    for (std::size_t i = 0; i < kSyncManagers; ++i) {
      const auto base = static_cast<std::uint16_t>(reg::sm + i * 8U);
      if ((mem_[base + 6U] & 1U) == 0U) {
        mem_[base + 5U] = 0;
      }
    }
  }
  if (mbx && touches(address, in.size(), static_cast<std::uint16_t>(rx.start + rx.bytes - 1U),
                     static_cast<std::uint16_t>(rx.start + rx.bytes - 1U))) {
    set_mailbox_full(rx, true);  // the last byte written: the request is complete
    serve_mailbox();
  }
  return true;
}

void Esc::set_al(std::uint8_t state, bool error, std::uint16_t code) noexcept {
  put16(reg::al_status, static_cast<std::uint16_t>(state | (error ? 0x10U : 0U)));
  put16(reg::al_status_code, code);
  mem_[reg::wdg_status_pd] = (state == static_cast<std::uint8_t>(AlState::op)) ? 1U : 0U;
}

std::uint16_t Esc::transition_error(AlState from, std::uint8_t to) const noexcept {
  if (!valid_state(to)) {
    return al_code::unknown_state;
  }
  if (to == static_cast<std::uint8_t>(AlState::boot)) {
    return al_code::bootstrap_not_supported;
  }
  const auto f = static_cast<std::uint8_t>(from);
  const bool up_one = (f == 1U && to == 2U) || (f == 2U && to == 4U) || (f == 4U && to == 8U);
  const bool down = to < f || (f == 8U && to == 4U);
  return (up_one || down) ? al_code::none : al_code::invalid_state_change;
}

bool Esc::sm_matches(std::uint16_t start, std::size_t bytes) const noexcept {
  for (std::size_t i = 0; i < kSyncManagers; ++i) {
    const auto base = static_cast<std::uint16_t>(reg::sm + i * 8U);
    const bool enabled = (mem_[base + 6U] & 1U) != 0U;
    if (enabled && u16(base) == start && u16(static_cast<std::uint16_t>(base + 2U)) == bytes) {
      return true;
    }
  }
  return false;
}

// ETG.1000.6 6.4.1: an error indication is cleared only by a request with the
// acknowledge bit; a request without it is ignored while the error is shown.
void Esc::on_al_control(std::uint64_t now_ns) noexcept {
  const std::uint16_t ctl = u16(reg::al_control);
  const auto req = static_cast<std::uint8_t>(ctl & 0x0FU);
  const bool ack = (ctl & 0x10U) != 0U;
  const std::uint16_t status = u16(reg::al_status);
  const auto cur = static_cast<AlState>(status & 0x0FU);
  const bool error = (status & 0x10U) != 0U;
  if (error && !ack) {
    return;
  }
  if (req == static_cast<std::uint8_t>(cur)) {
    set_al(req, false, al_code::none);
    return;
  }
  const std::uint16_t code = transition_error(cur, req);
  if (code != al_code::none) {
    set_al(static_cast<std::uint8_t>(cur), true, code);
    return;
  }
  if (cur == AlState::init && req != static_cast<std::uint8_t>(AlState::init) && desc_.mailbox && !mailbox_configured()) {
    set_al(static_cast<std::uint8_t>(cur), true, al_code::invalid_mailbox_config);
    return;
  }
  if (cur == AlState::safeop && req == static_cast<std::uint8_t>(AlState::op) && desc_.dc_sync0_required) {
    if (const std::uint16_t c = dc_op_error(now_ns); c != al_code::none) {
      set_al(static_cast<std::uint8_t>(cur), true, c);
      return;
    }
    if (!sync0_running(now_ns)) {
      set_al(static_cast<std::uint8_t>(cur), false, al_code::none);  // acknowledged
      pending_op_ = true;  // SAFE-OP until its first SYNC0 (dc_at), without an error
      return;
    }
  }
  if (cur == AlState::preop && req == static_cast<std::uint8_t>(AlState::safeop)) {
    if (const std::uint16_t c = preop_to_safeop_error(); c != al_code::none) {
      set_al(static_cast<std::uint8_t>(cur), true, c);
      return;
    }
    if (!desc_.rx.entries.empty() && !sm_matches(desc_.out_address, desc_.rx.bytes())) {
      set_al(static_cast<std::uint8_t>(cur), true, al_code::invalid_output_config);
      return;
    }
    if (!desc_.tx.entries.empty() && !sm_matches(desc_.in_address, desc_.tx.bytes())) {
      set_al(static_cast<std::uint8_t>(cur), true, al_code::invalid_input_config);
      return;
    }
  }
  set_al(req, false, al_code::none);
  if (req == static_cast<std::uint8_t>(AlState::init)) {
    for (std::size_t i = 0; i < kSyncManagers; ++i) {
      mem_[reg::sm + i * 8U + 5U] = 0;  // no mailbox communication in INIT: emptied
    }
  } else {
    serve_mailbox();  // a request written in INIT is answered now
  }
}

// The mailbox sync managers as the SII describes them (SM0 receive, SM1 send).
bool Esc::mailbox_configured() const noexcept {
  MailboxSm rx;
  MailboxSm tx;
  return mailbox_sm(true, rx) && mailbox_sm(false, tx) && rx.base == reg::sm && rx.start == kMailboxOut &&
         rx.bytes == kMailboxBytes && tx.base == reg::sm + 8U && tx.start == kMailboxIn && tx.bytes == kMailboxBytes;
}

// What a CiA 402 drive checks of its start-up parameters before SAFE-OP: the PDOs assigned,
// the mode of operation CSP (the only one it has), and its interpolation period its cycle.
std::uint16_t Esc::preop_to_safeop_error() const noexcept {
  if (od_.empty()) {
    return al_code::none;
  }
  if (od_.value(0x1C12, 0) == 0) {
    return al_code::invalid_output_config;
  }
  if (od_.value(0x1C13, 0) == 0) {
    return al_code::invalid_input_config;
  }
  if (od_.value(0x6060, 0) != 8) {
    return al_code::inconsistent_settings;
  }
  std::int64_t ns = od_.value(0x60C2, 1);
  for (std::int64_t e = od_.value(0x60C2, 2) + 9; e > 0; --e) {
    ns *= 10;
  }
  return ns == static_cast<std::int64_t>(desc_.cycle_us) * 1000 ? al_code::none : al_code::invalid_sync_cycle;
}

// ETG.1000.4 6.4: command in bits 8..10 of 0x0502 (1 read, 2 write, 4 reload), word
// address in 0x0504, 4 data bytes in 0x0508 (8-byte reads are not offered: bit 6 = 0).
void Esc::on_eeprom_control() noexcept {
  const std::uint16_t ctl = u16(reg::eep_control);
  const auto cmd = static_cast<std::uint16_t>((ctl >> 8U) & 0x7U);
  std::uint16_t result = 0;
  if (cmd == 1U) {
    const std::uint32_t a = static_cast<std::uint32_t>(u16(reg::eep_address)) |
                            (static_cast<std::uint32_t>(u16(reg::eep_address + 2U)) << 16U);
    for (std::uint32_t k = 0; k < 2U; ++k) {
      const std::uint32_t w = a + k;
      put16(static_cast<std::uint16_t>(reg::eep_data + 2U * k), (w < sii_.size()) ? sii_[w] : 0xFFFFU);
    }
  } else if (cmd == 2U) {
    result = 0x2000;  // command error: the image is read-only
  }
  put16(reg::eep_control, result);  // done at once: never busy
}

bool Esc::logical_write(std::uint32_t logical, std::span<const std::uint8_t> data, std::uint64_t now_ns) noexcept {
  const bool hit = for_each_mapped_bit(mem_.data(), logical, data.size(), kFmmuWrite,
                                       [&](std::uint64_t pbit, std::uint64_t d) {
                                         put_bit(mem_[pbit / 8U], pbit, bit_at(data[d / 8U], d));
                                       });
  if (hit) {
    last_output_ns_ = now_ns;
    if (desc_.dc_sync0_required) {
      dc_setpoint_taken(now_ns);
    }
  }
  return hit;
}

bool Esc::logical_read(std::uint32_t logical, std::span<std::uint8_t> data) const noexcept {
  return for_each_mapped_bit(mem_.data(), logical, data.size(), kFmmuRead, [&](std::uint64_t pbit, std::uint64_t d) {
    put_bit(data[d / 8U], d, bit_at(mem_[pbit / 8U], pbit));
  });
}

std::span<const std::uint8_t> Esc::outputs() const noexcept {
  const std::size_t n = std::min(desc_.rx.bytes(), zeros_.size());
  if (state() != AlState::op) {
    return {zeros_.data(), n};  // outputs in their safe state outside OP (ETG.1000.6 6.4.1)
  }
  return {&mem_[desc_.out_address], n};
}

void Esc::set_inputs(std::span<const std::uint8_t> in) noexcept {
  const std::size_t n = std::min(in.size(), kEscMemory - desc_.in_address);
  std::memcpy(&mem_[desc_.in_address], in.data(), n);
}

void Esc::set_inputs_at(std::size_t offset, std::span<const std::uint8_t> in) noexcept {
  const std::size_t at = std::min<std::size_t>(desc_.in_address + offset, kEscMemory);
  std::memcpy(&mem_[at], in.data(), std::min(in.size(), kEscMemory - at));
}

void Esc::pdi_write(std::uint16_t address, std::span<const std::uint8_t> in) noexcept {
  const std::size_t n = std::min(in.size(), kEscMemory - std::min<std::size_t>(address, kEscMemory));
  std::memcpy(&mem_[address], in.data(), n);
}

std::uint64_t Esc::watchdog_ns() const noexcept {
  return (static_cast<std::uint64_t>(u16(reg::wdg_divider)) + 2U) * 40U * u16(reg::wdg_time_pd);
}

void Esc::poll_watchdog(std::uint64_t now_ns) noexcept {
  const std::uint64_t limit = watchdog_ns();
  // (last_output_ns_ can lie a few forwarding delays after now_ns: the frame reached this
  // subdevice that much later than the first)
  if (state() != AlState::op || desc_.rx.entries.empty() || limit == 0U || now_ns <= last_output_ns_ ||
      now_ns - last_output_ns_ <= limit) {
    return;
  }
  set_al(static_cast<std::uint8_t>(AlState::safeop), true, al_code::sm_watchdog);
  ++mem_[reg::wdg_counter_pd];
}

std::uint64_t Esc::u64(std::uint16_t a) const noexcept {
  std::uint64_t v = 0;
  for (unsigned i = 0; i < 8U; ++i) {
    v |= static_cast<std::uint64_t>(mem_[a + i]) << (8U * i);
  }
  return v;
}

void Esc::put64(std::uint16_t a, std::uint64_t v) noexcept {
  for (unsigned i = 0; i < 8U; ++i) {
    mem_[a + i] = static_cast<std::uint8_t>(v >> (8U * i));
  }
}

void DcStats::record(std::int64_t err_ns, std::uint64_t at_ns, std::uint64_t input_gap_ns) noexcept {
  const std::uint64_t a = static_cast<std::uint64_t>(err_ns < 0 ? -err_ns : err_ns);
  ++samples;
  last_ns = err_ns;
  if (a > max_abs_ns || samples == 1U) {
    max_abs_ns = a;
    max_at_ns = at_ns;
    max_input_gap_ns = input_gap_ns;
  }
  ++hist[std::min<std::uint64_t>(a / 10U, kBuckets - 1U)];
}

std::uint64_t DcStats::percentile_ns(double p) const noexcept {
  if (samples == 0U) {
    return 0;
  }
  const auto want = static_cast<std::uint64_t>(std::ceil(p * static_cast<double>(samples)));
  std::uint64_t seen = 0;
  for (std::size_t b = 0; b < kBuckets; ++b) {
    seen += hist[b];
    if (seen >= want) {
      return (b + 1U == kBuckets) ? max_abs_ns : std::min<std::uint64_t>((b + 1U) * 10U - 1U, max_abs_ns);
    }
  }
  return max_abs_ns;
}

std::uint64_t Esc::local_time(std::uint64_t now_ns) noexcept {
  if (!powered_) {
    powered_ = true;
    power_ns_ = now_ns > power_lag_ns_ ? now_ns - power_lag_ns_ : 0U;
  }
  const double dt = static_cast<double>(now_ns > power_ns_ ? now_ns - power_ns_ : 0U) * (1.0 + drift_ppm_ * 1e-6);
  return static_cast<std::uint64_t>(dt / static_cast<double>(kTickNs)) * kTickNs;
}

double Esc::slewed(double since) const noexcept {
  const double most = since * kSlewRate;
  return slew_left_ns_ >= 0.0 ? std::min(slew_left_ns_, most) : std::max(slew_left_ns_, -most);
}

void Esc::anchor(std::uint64_t now_ns) noexcept {
  if (now_ns <= corr_host_ns_) {
    return;
  }
  const double since = static_cast<double>(now_ns - corr_host_ns_);
  const double a = slewed(since);
  corr_ns_ += since * rate_i_ + a;
  slew_left_ns_ -= a;
  corr_host_ns_ = now_ns;
}

std::uint64_t Esc::system_time(std::uint64_t now_ns) noexcept {
  const double since = now_ns > corr_host_ns_ ? static_cast<double>(now_ns - corr_host_ns_) : 0.0;
  const double corr = corr_ns_ + since * rate_i_ + slewed(since);
  return local_time(now_ns) + u64(reg::dc_offset) + static_cast<std::uint64_t>(std::llround(corr));
}

bool Esc::sync0_activated() const noexcept {
  return (mem_[reg::dc_activation] & 0x03U) == 0x03U && u32(reg::dc_sync0_cycle) != 0U &&
         (mem_[reg::dc_cyclic_unit] & 0x01U) == 0U;  // the SYNC unit assigned to ECAT, not to the PDI
}

std::uint32_t Esc::sync0_cycle_ns() const noexcept { return u32(reg::dc_sync0_cycle); }

// Pulse k (1-based) fires at system time start + (k - 1) x cycle: the pulses fired by system
// time s (the next one, k + 1, at start + k x cycle).
std::uint64_t Esc::sync0_fired(std::uint64_t s) const noexcept {
  const std::uint64_t start = u64(reg::dc_start_time);
  return (s < start) ? 0U : (s - start) / sync0_cycle_ns() + 1U;
}

std::uint64_t Esc::sync0_pulses(std::uint64_t now_ns) noexcept {
  return sync0_running(now_ns) ? sync0_fired(system_time(now_ns)) : 0U;
}

std::uint64_t Esc::ns_to_next_sync0(std::uint64_t now_ns) noexcept {
  if (!sync0_activated() || !sync0_armed_) {
    return 0;
  }
  const std::uint64_t s = system_time(now_ns);
  return u64(reg::dc_start_time) + sync0_fired(s) * sync0_cycle_ns() - s;
}

bool Esc::sync0_running(std::uint64_t now_ns) noexcept {
  if (!sync0_armed_ || !sync0_activated()) {
    return false;
  }
  sync0_started_ = sync0_started_ || system_time(now_ns) >= u64(reg::dc_start_time);
  return sync0_started_;
}

void Esc::dc_at(std::uint64_t now_ns) noexcept {
  put64(reg::dc_system_time, system_time(now_ns));
  const bool running = sync0_running(now_ns);
  mem_[reg::dc_activation_status] = sync0_activated() && sync0_armed_ ? 0x01U : 0x00U;
  mem_[reg::dc_sync0_status] = running ? 0x01U : 0x00U;
  if (pending_op_ && running) {
    pending_op_ = false;
    set_al(static_cast<std::uint8_t>(AlState::op), false, al_code::none);
    last_output_ns_ = now_ns;  // the watchdog counts from entering the state
  }
  // A drive that needs SYNC0 and loses it in OP stops (ETG.1000.6 table 11: fatal sync error).
  if (desc_.dc_sync0_required && state() == AlState::op && !running) {
    set_al(static_cast<std::uint8_t>(AlState::safeop), true, 0x002C);
  }
}

// A write to 0x0900 latches, on every port, the local time at which that frame passed it
// (port 0 on the way out, port 1 on its way back from the subdevices behind), and the
// processing unit's receive time (0x0918): what the master computes propagation delays from.
void Esc::dc_latch_receive_times(std::uint64_t now_ns) noexcept {
  const std::uint64_t t0 = local_time(now_ns);
  const std::uint64_t t1 = downstream_ns_ > 0U ? local_time(now_ns + downstream_ns_) : 0U;
  const auto put32 = [this](std::uint16_t a, std::uint32_t v) {
    put16(a, static_cast<std::uint16_t>(v & 0xFFFFU));
    put16(static_cast<std::uint16_t>(a + 2U), static_cast<std::uint16_t>(v >> 16U));
  };
  put32(reg::dc_recv_port0, static_cast<std::uint32_t>(t0));
  put32(reg::dc_recv_port0 + 4U, static_cast<std::uint32_t>(t1));
  put32(reg::dc_recv_port0 + 8U, 0);
  put32(reg::dc_recv_port0 + 12U, 0);
  put64(reg::dc_recv_pu, t0);
}

void Esc::dc_reset_loop(std::uint64_t now_ns) noexcept {
  anchor(now_ns);  // the time so far stays
  rate_i_ = 0.0;
  slew_left_ns_ = 0.0;
  last_ctl_ns_ = 0;
}

// ETG.1000.4 6.8: a system time written to 0x0910 (by the ARMW/FRMW that carries the
// reference clock's time, or any write) is compared with the own system time at the frame's
// arrival, the delay 0x0928 added; the difference (0x092C) drives the clock's speed.
void Esc::dc_control(std::span<const std::uint8_t> written, std::size_t first, std::uint64_t now_ns) noexcept {
  if (first >= written.size()) {
    return;
  }
  const std::size_t n = std::min<std::size_t>(written.size() - first, 8U);
  if (n < 4U) {
    return;  // less than the 32-bit time: no input
  }
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < n; ++i) {
    v |= static_cast<std::uint64_t>(written[first + i]) << (8U * i);
  }
  const std::uint64_t own = system_time(now_ns);
  const std::uint64_t received = v + u32(reg::dc_delay);
  const std::int64_t delta = (n >= 8U) ? static_cast<std::int64_t>(received - own)
                                       : static_cast<std::int32_t>(static_cast<std::uint32_t>(received) -
                                                                   static_cast<std::uint32_t>(own));
  anchor(now_ns);
  const std::uint64_t h = (last_ctl_ns_ == 0U || now_ns <= last_ctl_ns_) ? 0U : now_ns - last_ctl_ns_;
  last_ctl_ns_ = now_ns;
  const double dt = static_cast<double>(std::min<std::uint64_t>(h, 10000000U));  // a pause is not a long input
  // Anti-windup (conditional integration): the integral learns while the slew can take out its
  // part before the next input (a large difference is an offset being removed, not a drift to
  // learn), and always while it unwinds (a rate correction of the other sign than the difference
  // asks for). One input moves it by at most kMaxRateStep. Without the second rule one input
  // after a pause could pin the rate at the wrong limit (-200 ppm for a clock that needs +12),
  // the slew (200 ppm) then just short of undoing it: a clock falling behind at its own drift
  // for ever, its differences too large to learn from (issue 40: ecat_dc's drive at -122 us).
  const double d = static_cast<double>(delta);
  const bool within_slew = std::abs(kLoopP * d) <= dt * kSlewRate;
  const bool unwinds = (d > 0.0 && rate_i_ < 0.0) || (d < 0.0 && rate_i_ > 0.0);
  if (within_slew || unwinds) {
    const double step = std::clamp(kLoopI * d * dt, -kMaxRateStep, kMaxRateStep);
    rate_i_ = std::clamp(rate_i_ + step, -kMaxRate, kMaxRate);
  }
  slew_left_ns_ = kLoopP * static_cast<double>(delta);
  const std::uint64_t mag = std::min<std::uint64_t>(static_cast<std::uint64_t>(delta < 0 ? -delta : delta), 0x7FFFFFFFU);
  const std::uint32_t diff = static_cast<std::uint32_t>(mag) | (delta > 0 ? 0x80000000U : 0U);
  put16(reg::dc_diff, static_cast<std::uint16_t>(diff & 0xFFFFU));
  put16(reg::dc_diff + 2U, static_cast<std::uint16_t>(diff >> 16U));
}

// What a drive that needs SYNC0 checks before OP (the register side: the master configured
// the SYNC unit): activated with a cycle and a start ahead, at its own cycle.
std::uint16_t Esc::dc_op_error(std::uint64_t now_ns) noexcept {
  static_cast<void>(now_ns);
  if (!sync0_activated() || !sync0_armed_) {
    return al_code::invalid_dc_sync_config;
  }
  if (sync0_cycle_ns() != static_cast<std::uint64_t>(desc_.cycle_us) * 1000U) {
    return al_code::dc_sync0_cycle_time;
  }
  return al_code::none;
}

// A set-point written by process data is applied by the drive at the next SYNC0 (its output
// latched there): which SYNC0 takes it, how long before it arrived, and whether the one
// before was replaced before any SYNC0 took it or SYNC0 events passed without a new one.
void Esc::dc_setpoint_taken(std::uint64_t now_ns) noexcept {
  if (!sync0_running(now_ns)) {
    return;
  }
  const std::uint64_t s = system_time(now_ns);
  // the next SYNC0, numbered from 1 (0 stands for none)
  const std::uint64_t k = sync0_fired(s) + 1U;
  const auto lead = static_cast<std::int64_t>(u64(reg::dc_start_time) + (k - 1U) * sync0_cycle_ns() - s);
  DcStats& st = dc_stats_;
  if (last_sync0_k_ == k) {
    ++st.overwritten;
  } else {
    if (last_sync0_k_ != 0U && k > last_sync0_k_ + 1U) {
      st.missed += k - last_sync0_k_ - 1U;
    }
    ++st.latched;
    st.min_lead_ns = (st.latched == 1U) ? lead : std::min(st.min_lead_ns, lead);
  }
  st.last_lead_ns = lead;
  last_sync0_k_ = k;
}

AlState Esc::state() const noexcept { return static_cast<AlState>(mem_[reg::al_status] & 0x0FU); }
std::uint16_t Esc::al_status_code() const noexcept { return u16(reg::al_status_code); }
std::uint16_t Esc::station_address() const noexcept { return u16(reg::station_addr); }

}  // namespace safestate::ecat

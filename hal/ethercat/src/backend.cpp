// The `ethercat` backend. The cycle does one exchange (one LRW with the AL status checks in
// the same frame) in read(): the outputs written in the previous cycle go out, the inputs
// come back; nothing else blocks, nothing allocates.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <thread>
#include <vector>

#include <pthread.h>
#include <sched.h>

#include "safestate/hal/ecat_master.hpp"
#include "safestate/hal/ethercat.hpp"
#include "safestate/hal/pdo_bytes.hpp"
#include "safestate/safelink/container.hpp"

namespace safestate::hal::ethercat {

struct Backend::Master {
  SsEcatMaster* m = nullptr;
  SsEcatCycle cycle{};
  SsEcatCycle answer{};  // the exchange thread's last answer (under xfer_)
};

namespace {

std::string hex(std::uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%08X", v);
  return b;
}

std::string object(const StartupSdo& s) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%04X:%02X", static_cast<unsigned>(s.index), static_cast<unsigned>(s.sub));
  return b;
}

// 0x60C2 (interpolation time period, CiA 402) of a start-up list in ns: value x 10^index s;
// 0 when the list does not write both parts.
std::int64_t interpolation_ns(const std::vector<StartupSdo>& list) {
  std::int64_t value = -1;
  std::int64_t exponent = 100;
  for (const StartupSdo& s : list) {
    if (s.index == 0x60C2 && s.sub == 1) {
      value = s.value & 0xFFU;
    } else if (s.index == 0x60C2 && s.sub == 2) {
      exponent = static_cast<std::int8_t>(s.value & 0xFFU);
    }
  }
  if (value < 0 || exponent < -9 || exponent > 0) {
    return 0;
  }
  for (std::int64_t e = exponent + 9; e > 0; --e) {
    value *= 10;
  }
  return value;
}

using pdo::get16;
using pdo::get32;
using pdo::get_bit;
using pdo::put16;
using pdo::put32;
using pdo::set_bit;

constexpr int kScanPauseMs = 200;


std::uint64_t mono_ns() noexcept {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count());
}

}  // namespace

Backend::Backend(const BusConfig& cfg, const std::string& ifname, std::uint32_t cycle_us,
                 std::uint32_t exchange_timeout_us, std::uint64_t watchdog_ns)
    : cfg_(cfg),
      cycle_us_(cycle_us),
      exchange_timeout_us_((exchange_timeout_us == 0U || exchange_timeout_us > cfg.frame_timeout_us) ? cfg.frame_timeout_us
                                                                                                  : exchange_timeout_us),
      watchdog_ns_(watchdog_ns),
      async_(exchange_timeout_us != 0U) {
  std::size_t in = 0;
  std::size_t out = 0;
  for (const Subdevice& s : cfg_.subdevices) {
    in_off_.push_back(in);
    out_off_.push_back(out);
    in += s.in_bytes;
    out += s.out_bytes;
  }
  in_buf_.assign(in, 0);
  out_buf_.assign(out, 0);
  req_out_.assign(out, 0);
  ans_in_.assign(in, 0);
  asked_ns_.assign(cfg_.subdevices.size(), 0);
  asked_.assign(cfg_.subdevices.size(), 0);
  // Issue 37: where each connection's containers lie in the whole images (LinkTable order).
  for (std::size_t i = 0; i < cfg_.links.count; ++i) {
    const LinkSpec& l = cfg_.links.link[i];
    const std::size_t sub = l.position - 1U;
    for (const SafetyLink& s : cfg_.subdevices[sub].links) {
      if (s.id == l.id) {
        link_in_[i] = in_off_[sub] + s.in_offset;
        link_out_[i] = out_off_[sub] + s.out_offset;
      }
    }
    link_in_len_[i] = static_cast<std::uint8_t>(safelink::container_bytes(l.device_data_bytes));
    link_out_len_[i] = static_cast<std::uint8_t>(safelink::container_bytes(l.host_data_bytes));
  }
  std::string why;
  if (links_fit_cycle(cfg_, cycle_us, why)) {
    boot(ifname);
  } else {
    boot_error_ = why;
  }
  if (!boot_error_.empty()) {
    health_ = Health{false, health_.subdevice, false, "boot failed"};
  }
}

Backend::~Backend() {
  stop_exchanges();
  delete master_;
}

void Backend::keep_alive() noexcept {
  // As punctual as the real-time loop it stands in for (when permitted): a late exchange
  // here lets the 10-cycle watchdogs expire before the loop starts. hand_over() then moves
  // it just below the loop's priority, on the loop's CPU.
  sched_param sp{};
  sp.sched_priority = 80;
  static_cast<void>(pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp));
  SsEcatCycle c{};
  std::vector<std::uint8_t> out(out_buf_.size(), 0);
  std::vector<std::uint8_t> in(in_buf_.size(), 0);
  std::uint64_t served = 0;
  while (!handover_.load(std::memory_order_acquire)) {
    // Until the loop's first request: an exchange every cycle of the (safe, all-zero)
    // outputs. After it (async_): one exchange per request, none without one, so that a
    // loop that hangs stops the process data and the subdevices' watchdogs drop their
    // outputs, as when the whole master dies.
    const bool requested = wake_.try_acquire_for(std::chrono::microseconds(cycle_us_));
    while (wake_.try_acquire()) {
    }
    std::uint64_t seq = 0;
    {
      const std::lock_guard<std::mutex> g(xfer_);
      seq = req_seq_;
      std::copy(req_out_.begin(), req_out_.end(), out.begin());
    }
    if (seq == 0U ? requested : seq == served) {
      continue;  // woken for nothing new (a stop, or a request already served)
    }
    served = seq;
    const int rc = ss_ecat_exchange(master_->m, out.data(), out.size(), in.data(), in.size(), &c, exchange_timeout_us_, 1U);
    if (rc == 0) {
      const std::uint64_t now = mono_ns();
      {
        const std::lock_guard<std::mutex> g(xfer_);
        std::copy(in.begin(), in.end(), ans_in_.begin());
        master_->answer = c;
        ans_seq_ = seq;
        ans_ns_ = now;
        ++ans_id_;
      }
      // Until the bus is up (read()), every subdevice was in OP at the end of the boot: one
      // that is not any more fell back (a host stall past its watchdog) and is asked back.
      if (!up_.load(std::memory_order_acquire)) {
        for (std::size_t i = 0; i < cfg_.subdevices.size(); ++i) {
          if (i < c.count && c.al_state[i] != 8U) {
            ask_back_to_op(i, now);
          }
        }
      }
    }
  }
}

// A subdevice that fell back from OP before the bus is up (SAFE-OP with its error indication
// set: its process-data watchdog expired while the host could not send for 10 cycles, ...)
// is asked back as masters commonly do (SOEM's and IgH's state checks): the error is
// acknowledged (AL control = its state | 0x10), and once its AL status shows SAFE-OP without
// the error, OP is requested again. At most every 10 ms per subdevice; the boot timeout
// bounds how long (await_dc_op's 3 s, then the core's boot_timeout_ms). Not in the real-time
// loop: each call waits for its frames (the boot thread, or the exchange thread before the
// bus is up). Once the bus is up a subdevice leaving OP is FIELDBUS_LOST (SPEC §4 rule 1).
void Backend::ask_back_to_op(std::size_t i, std::uint64_t now_ns) noexcept {
  constexpr std::uint64_t kEveryNs = 10000000;
  if (asked_ns_[i] != 0U && now_ns - asked_ns_[i] < kEveryNs) {
    return;
  }
  asked_ns_[i] = now_ns;
  SsEcatMaster* m = master_->m;
  const auto pos = static_cast<std::uint16_t>(i);
  std::uint16_t status = 0;
  std::uint16_t code = 0;
  if (ss_ecat_al_status(m, pos, &status, &code) != 0 || (status & 0x0FU) == 8U) {
    return;  // not read (tried again later), or in OP again
  }
  if ((status & 0x10U) != 0U) {
    std::fprintf(stderr,
                 "safestate: EtherCAT boot: subdevice %zu (%s) fell back to AL state %u with AL status code 0x%04X; "
                 "error acknowledged, OP requested again\n",
                 i + 1U, cfg_.subdevices[i].name.c_str(), static_cast<unsigned>(status & 0x0FU), static_cast<unsigned>(code));
    if (ss_ecat_al_control(m, pos, static_cast<std::uint16_t>((status & 0x0FU) | 0x10U)) != 0 ||
        ss_ecat_al_status(m, pos, &status, &code) != 0 || (status & 0x10U) != 0U) {
      return;  // not acknowledged yet: asked again at the next try
    }
  }
  if ((status & 0x0FU) == 4U && ss_ecat_al_control(m, pos, 8U) == 0) {
    ++asked_[i];
  }
}

// The real-time loop takes over (once, in its first cycle, in BOOT). Synchronous (a replay,
// the bench: exchange_timeout 0): the keep-alive stops (at most one exchange and one cycle's
// wait to wait for) and the loop exchanges itself. Asynchronous (`safestate run`): the
// keep-alive thread becomes the exchange thread, on the loop's CPU just below its priority.
void Backend::hand_over() noexcept {
  if (handed_over_) {
    return;
  }
  handed_over_ = true;
  if (!async_) {
    if (keepalive_.joinable()) {
      handover_.store(true, std::memory_order_release);
      wake_.release();
      keepalive_.join();
    }
    return;
  }
  if (keepalive_.joinable()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof set, &set) == 0) {
      static_cast<void>(pthread_setaffinity_np(keepalive_.native_handle(), sizeof set, &set));
    }
    int policy = SCHED_OTHER;
    sched_param mine{};
    if (pthread_getschedparam(pthread_self(), &policy, &mine) == 0 && policy == SCHED_FIFO && mine.sched_priority > 1) {
      sched_param below{};
      below.sched_priority = mine.sched_priority - 1;
      static_cast<void>(pthread_setschedparam(keepalive_.native_handle(), SCHED_FIFO, &below));
    }
  }
}

void Backend::stop_exchanges() noexcept {
  if (keepalive_.joinable()) {
    handover_.store(true, std::memory_order_release);
    wake_.release();
    keepalive_.join();
  }
}

// BOOT (SPEC §4 rule 1): every expected subdevice found, in order, with its identity and
// PDO sizes, and in OP; otherwise the first that is wrong or missing is named.
void Backend::boot(const std::string& ifname) {
  char err[256] = {0};
  SsEcatMaster* m = ss_ecat_open(ifname.c_str(), cfg_.frame_timeout_us, 5000, 85, err, sizeof err);
  if (m == nullptr) {
    boot_error_ = std::string("EtherCAT: ") + err;
    return;
  }
  master_ = new Master{m, {}};
  std::array<SsEcatSub, 16> found{};
  // A scan that times out or finds fewer subdevices than configured is tried again for a
  // while: a lost frame, or drives still powering up after the controller. A wrong
  // identity is not: that bus will not become right by waiting.
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(cfg_.scan_timeout_ms);
  int n = -1;
  for (int attempt = 1;; ++attempt) {
    n = ss_ecat_scan(m, found.data(), found.size());
    if (n >= static_cast<int>(cfg_.subdevices.size()) || std::chrono::steady_clock::now() >= until) {
      break;
    }
    std::fprintf(stderr, "safestate: EtherCAT scan %d: %s; scanning again\n", attempt,
                 n < 0 ? ss_ecat_error(m) : (std::to_string(n) + " subdevices found").c_str());
    std::this_thread::sleep_for(std::chrono::milliseconds(kScanPauseMs));
  }
  if (n < 0) {
    boot_error_ = std::string("EtherCAT scan: ") + ss_ecat_error(m);
    return;
  }
  // Identities first (in PRE-OP): no start-up SDO goes to a subdevice that is not the one
  // configured.
  const auto fail = [&](std::size_t i, const std::string& what) {
    health_.subdevice = static_cast<std::uint8_t>(i + 1U);
    boot_error_ = "subdevice " + std::to_string(i + 1U) + " (" + cfg_.subdevices[i].name + ") " + what;
  };
  for (std::size_t i = 0; i < cfg_.subdevices.size(); ++i) {
    const Subdevice& want = cfg_.subdevices[i];
    if (i >= static_cast<std::size_t>(n)) {
      return fail(i, "missing: " + std::to_string(n) + " found on the bus");
    }
    const SsEcatSub& got = found[i];
    if (got.vendor_id != want.vendor_id || got.product_code != want.product_code ||
        (want.check_revision && got.revision != want.revision)) {
      return fail(i, "has the wrong identity: vendor " + hex(got.vendor_id) + " product " + hex(got.product_code) +
                         " revision " + hex(got.revision) + ", expected vendor " + hex(want.vendor_id) + " product " +
                         hex(want.product_code) + (want.check_revision ? " revision " + hex(want.revision) : ""));
    }
  }
  if (static_cast<std::size_t>(n) > cfg_.subdevices.size()) {
    health_.subdevice = static_cast<std::uint8_t>(cfg_.subdevices.size() + 1U);
    boot_error_ = "unexpected subdevice " + std::to_string(cfg_.subdevices.size() + 1U) + " (" + found[cfg_.subdevices.size()].name +
                  "): the configuration lists " + std::to_string(cfg_.subdevices.size());
    return;
  }
  // The start-up lists, in PRE-OP, in order: a refused SDO is BOOT_FAILED naming the
  // subdevice, the object and the abort code.
  for (std::size_t i = 0; i < cfg_.subdevices.size(); ++i) {
    const std::int64_t period_ns = interpolation_ns(cfg_.subdevices[i].startup);
    if (period_ns != 0 && period_ns != static_cast<std::int64_t>(cycle_us_) * 1000) {
      return fail(i, "start-up list: 0x60C2 sets an interpolation period of " + std::to_string(period_ns / 1000) +
                         " us, the scan cycle is " + std::to_string(cycle_us_) + " us");
    }
    for (const StartupSdo& sdo : cfg_.subdevices[i].startup) {
      std::uint32_t code = 0;
      if (ss_ecat_sdo_write(m, static_cast<std::uint16_t>(i), sdo.index, sdo.sub, sdo.value, sdo.size, &code) != 0) {
        return fail(i, code != 0U ? "refused start-up SDO " + object(sdo) + " = " + std::to_string(sdo.value) + ": abort " +
                                        hex(code) + " (" + ss_ecat_error(m) + ")"
                                   : "start-up SDO " + object(sdo) + ": " + ss_ecat_error(m));
      }
    }
  }
  // Distributed clocks: SYNC0 on the subdevices whose configuration asks for it (the ESI's
  // AssignActivate), at the scan cycle; it fires sync0_shift_us after the cycle's start.
  std::vector<std::uint16_t> assign;
  for (const Subdevice& sd : cfg_.subdevices) {
    assign.push_back(sd.dc_assign_activate);
    dc_ = dc_ || sd.dc_assign_activate != 0U;
  }
  if (dc_ && cfg_.sync0_shift_us >= cycle_us_) {
    boot_error_ = "sync0_shift_us: " + std::to_string(cfg_.sync0_shift_us) + " us is not within the scan cycle of " +
                  std::to_string(cycle_us_) + " us";
    return;
  }
  n = ss_ecat_to_safe_op(m, found.data(), found.size(), assign.data(), assign.size(), cycle_us_ * 1000U,
                         cfg_.sync0_shift_us * 1000U);
  if (n < 0) {
    boot_error_ = std::string("EtherCAT: ") + ss_ecat_error(m);
    return;
  }
  for (std::size_t i = 0; i < cfg_.subdevices.size(); ++i) {
    const Subdevice& want = cfg_.subdevices[i];
    const SsEcatSub& got = found[i];
    if (got.in_bytes != want.in_bytes || got.out_bytes != want.out_bytes) {
      return fail(i, "maps " + std::to_string(got.in_bytes) + "/" + std::to_string(got.out_bytes) +
                         " input/output bytes, expected " + std::to_string(want.in_bytes) + "/" +
                         std::to_string(want.out_bytes));
    }
  }
  // Every subdevice's outputs go safe by themselves when this master stops writing them
  // (killed, hung): its process-data watchdog, written before OP, where it starts counting.
  if (!watchdog_registers(cfg_.watchdog_cycles, cycle_us_, wd_divider_, wd_time_)) {
    boot_error_ = "watchdog_cycles: " + std::to_string(cfg_.watchdog_cycles) + " cycles of " + std::to_string(cycle_us_) +
                  " us do not fit the process-data watchdog (at most 65535 ms)";
    return;
  }
  if (ss_ecat_set_watchdog(m, wd_divider_, wd_time_) != 0) {
    boot_error_ = std::string("EtherCAT: ") + ss_ecat_error(m);
    return;
  }
  // From the OP request until the keep-alive thread's first exchange the watchdogs run
  // without process data: this stretch at real-time priority (when permitted; the thread
  // inherits it), so that a busy host does not let them expire before the cycle starts.
  int policy = SCHED_OTHER;
  sched_param before{};
  const bool restore = pthread_getschedparam(pthread_self(), &policy, &before) == 0;
  sched_param rt{};
  rt.sched_priority = 80;
  static_cast<void>(pthread_setschedparam(pthread_self(), SCHED_FIFO, &rt));
  if (ss_ecat_to_op(m) != 0) {
    boot_error_ = std::string("EtherCAT: ") + ss_ecat_error(m);
  } else if (dc_ && !await_dc_op()) {
    // boot_error_ names the subdevice
  } else {
    dc_reference_ = dc_ ? ss_ecat_dc_reference(m) : 0;
    keepalive_ = std::thread([this] { keep_alive(); });
  }
  if (restore) {
    static_cast<void>(pthread_setschedparam(pthread_self(), policy, &before));
  }
}

// With distributed clocks the synchronised subdevices enter OP at their first SYNC0 pulse
// (the master set it ~100 ms ahead): meanwhile the (safe, all-zero) outputs are exchanged
// every cycle, with the reference clock's time, so that the free-running subdevices already
// in OP keep their watchdogs fed and the clocks stay in step. Up to 3 s; else BOOT fails
// naming the first subdevice not in OP.
bool Backend::await_dc_op() {
  SsEcatCycle c{};
  std::vector<std::uint8_t> out(out_buf_.size(), 0);
  std::vector<std::uint8_t> in(in_buf_.size(), 0);
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  auto next = std::chrono::steady_clock::now();
  const std::size_t n = cfg_.subdevices.size();
  std::size_t not_op = 0;
  // Seen in OP during this wait, or free-running (in OP at the request): one of these not in
  // OP fell back and is asked back (ask_back_to_op). A synchronised drive not yet in OP waits
  // for its first SYNC0 (the master set it 100 ms after SAFE-OP) and is left alone until
  // kSync0DueMs have passed: then one not in OP may have fallen back as well (it entered OP at
  // its pulse and its watchdog expired before an exchange saw it there).
  constexpr auto kSync0DueMs = std::chrono::milliseconds(250);
  const auto sync0_due = std::chrono::steady_clock::now() + kSync0DueMs;
  std::vector<bool> was_op(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    was_op[i] = cfg_.subdevices[i].dc_assign_activate == 0U;
  }
  while (std::chrono::steady_clock::now() < until) {
    if (ss_ecat_exchange(master_->m, out.data(), out.size(), in.data(), in.size(), &c, exchange_timeout_us_, 1U) == 0) {
      not_op = n;
      for (std::size_t i = 0; i < n; ++i) {
        if (i < c.count && c.al_state[i] == 8U) {
          was_op[i] = true;
        } else if (not_op == n) {
          not_op = i;
        }
      }
      if (not_op == n) {
        return true;
      }
      const bool due = std::chrono::steady_clock::now() >= sync0_due;
      for (std::size_t i = 0; i < n && i < c.count; ++i) {
        if (c.al_state[i] != 8U && (was_op[i] || due)) {
          ask_back_to_op(i, mono_ns());
        }
      }
    }
    next += std::chrono::microseconds(cycle_us_);
    std::this_thread::sleep_until(next);
  }
  health_.subdevice = static_cast<std::uint8_t>(not_op + 1U);
  std::string al;
  std::uint16_t status = 0;
  std::uint16_t code = 0;
  if (not_op < n && ss_ecat_al_status(master_->m, static_cast<std::uint16_t>(not_op), &status, &code) == 0) {
    char b[96];
    std::snprintf(b, sizeof b, ": AL status 0x%02X, AL status code 0x%04X", static_cast<unsigned>(status),
                  static_cast<unsigned>(code));
    al = b;
    if (asked_[not_op] > 0U) {
      al += ", asked back to OP " + std::to_string(asked_[not_op]) + " times";
    }
  }
  boot_error_ = "subdevice " + std::to_string(not_op + 1U) + " (" +
                (not_op < n ? cfg_.subdevices[not_op].name : std::string("?")) +
                ") did not reach OP with distributed clocks (its SYNC0 did not start, or it refused it)" + al;
  return false;
}

std::uint64_t Backend::stray_frames() noexcept { return ss_ecat_stray_frames(); }

void Backend::lose(std::uint8_t position, const char* why, bool silent) noexcept {
  if (health_.ok) {
    health_ = Health{false, position, silent, why};
    lost_position_.store(position, std::memory_order_relaxed);
    lost_silent_.store(silent, std::memory_order_relaxed);
    lost_why_.store(why, std::memory_order_release);
  }
}

void Backend::read(ProcessImageIn& in) noexcept {
  if (!booted()) {
    // The bus was scanned once at start and is not as configured: BOOT fails now, naming
    // the subdevice (waiting for the boot timeout would not change the bus).
    in.fieldbus_ok = false;
    in.fieldbus_boot_failed = true;
    in.fieldbus_subdevice = health_.subdevice;
    for (auto& d : in.drive) {
      d.online = false;
    }
    return;
  }
  hand_over();
  SsEcatCycle& c = master_->cycle;
  bool fresh = false;
  std::uint64_t answered_ns = 0;
  if (async_) {
    // The cycle never waits for the bus (issue 22): the exchange thread sent the outputs of
    // the last write() and put the answer aside; this cycle takes it if it is there, the
    // answer to that very request. Not there (late, lost, or the thread busy with its copy
    // at this moment: try_lock) is a stale cycle.
    if (xfer_.try_lock()) {
      if (ans_id_ != taken_id_ && ans_seq_ == req_seq_) {
        std::copy(ans_in_.begin(), ans_in_.end(), in_buf_.begin());
        c = master_->answer;
        taken_id_ = ans_id_;
        answered_ns = ans_ns_;
        fresh = true;
      }
      xfer_.unlock();
    }
  } else {
    // Synchronous (a replay, the bench): the cycle sends its frame and sleeps on the socket
    // for the answer itself, up to the frame timeout.
    fresh = ss_ecat_exchange(master_->m, out_buf_.data(), out_buf_.size(), in_buf_.data(), in_buf_.size(), &c,
                             exchange_timeout_us_, 1U) == 0;
    answered_ns = mono_ns();
  }
  ++exchanges_;
  const std::uint64_t now = mono_ns();  // vDSO clock read, no system call
  in.stale = !fresh;
  if (!fresh) {
    // A stale cycle: the frame is late or lost, the inputs stay those of the last answered
    // frame. Tolerated for fewer than stale_cycles cycles in a row (and the time watchdog).
    // Counted from the first answer to one of the loop's own requests on: the loop's first
    // request can meet the keep-alive's last exchange still in flight.
    stale_total_.fetch_add(1, std::memory_order_relaxed);
    if (counting_) {
      ++stale_in_row_;
    }
    const bool too_long = watchdog_ns_ > 0U && last_good_ns_ > 0U && now - last_good_ns_ > watchdog_ns_;
    if (health_.ok && up_.load(std::memory_order_relaxed) && (stale_in_row_ >= cfg_.stale_cycles || too_long)) {
      lost_after_cycles_.store(stale_in_row_, std::memory_order_relaxed);
      lost_after_ns_.store(last_good_ns_ > 0U ? now - last_good_ns_ : 0U, std::memory_order_relaxed);
      // On a line nothing answers from the first subdevice on (a cut cable, a dead segment).
      lose(1, too_long ? "no frame came back for longer than the fieldbus watchdog"
                       : "no frame came back for stale_cycles cycles in a row",
           true);
    }
  } else {
    stale_in_row_ = 0;
    counting_ = counting_ || !async_ || req_seq_ > 0U;
    last_good_ns_ = answered_ns;
    std::size_t not_op = cfg_.subdevices.size();
    for (std::size_t i = 0; i < cfg_.subdevices.size(); ++i) {
      if (i >= c.count || c.al_state[i] != 8U) {
        not_op = i;
        break;
      }
    }
    const bool wkc_ok = c.wkc == c.expected_wkc;
    if (up_.load(std::memory_order_relaxed)) {
      if (not_op < cfg_.subdevices.size()) {
        lose(static_cast<std::uint8_t>(not_op + 1U), "subdevice left OP");
      }
      if (!wkc_ok) {
        lose(0, "working counter differs from the expected one");
      }
    } else if (not_op == cfg_.subdevices.size() && wkc_ok) {
      up_.store(true, std::memory_order_release);  // the bus is up: SPEC §4 rule 1 from here
      waiting_for_ = 0;
    } else {
      // Not up yet (a subdevice asked back to OP by the exchange thread, or still on its way):
      // BOOT waits for it, up to boot_timeout_ms, and names it if it never comes.
      waiting_for_ = static_cast<std::uint8_t>(not_op < cfg_.subdevices.size() ? not_op + 1U : 0U);
    }
    if (dc_ && c.dc_time != 0U) {
      follow_dc(c.dc_time);
    }
  }
  sample_time(in, fresh, c.dc_time);
  decode(in);
  // Issue 37: each connection's container from the device as the bus delivered it, copied,
  // not looked into (the channels check them). A stale cycle repeats the last answered
  // frame's bytes: the channel's watchdog counts it.
  for (std::size_t i = 0; i < cfg_.links.count; ++i) {
    LinkFrame& f = in.link_rx[i];
    f.len = link_in_len_[i];
    std::copy_n(in_buf_.begin() + static_cast<std::ptrdiff_t>(link_in_[i]), f.len, f.bytes.begin());
  }
  ++link_cycles_;
  if (!corrupt_.empty()) {
    corrupt_.to_host(link_cycles_, in.link_rx);  // tests: the master at fault (--corrupt)
  }
}

// @req MO-SAMPLE-TIME
// The drives sample their inputs at SYNC0 (ethercrab starts it at a whole number of cycles of
// DC time, and the emulated drives do sample there): the pulse before the frame passed the
// reference clock took what it carries. A frame late past its pulse carries the next pulse's
// sample, and the frame after it, on time again, that same sample: counting frames would see
// two cycles of motion in one and none in the next (a doubled measured speed). Only in real
// time (the loop's own cycle): a replay exchanges when it likes, and the emulator then steps
// its plant per exchange (lock-step), not at SYNC0.
void Backend::sample_time(ProcessImageIn& in, bool fresh, std::uint64_t dc_time) noexcept {
  in.sample_clock = dc_ && async_ && sample_pulse_ != 0U;
  in.sample_span = 0;  // no new sample (a stale cycle is none anyway)
  if (!dc_ || !async_ || !fresh || dc_time == 0U) {
    return;
  }
  const std::uint64_t pulse = dc_time / (static_cast<std::uint64_t>(cycle_us_) * 1000U);
  if (in.sample_clock) {
    const std::uint64_t span = (pulse > sample_pulse_) ? pulse - sample_pulse_ : 0U;
    in.sample_span = static_cast<std::uint16_t>(std::min<std::uint64_t>(span, 0xFFFFU));
  }
  sample_pulse_ = std::max(sample_pulse_, pulse);
}

// The real-time loop takes its cycle from DC time: the frame should pass the reference clock
// sync0_shift_us before SYNC0 (SYNC0 events at whole cycles of DC time, as the master set
// their start). The phase error of this answer's frame moves the loop's next wake-up by a
// quarter of it, at most 1/20 of a cycle per cycle (the loop never jumps, its cycle never
// stretches by more than that): a phase-locked loop on the reference clock.
void Backend::follow_dc(std::uint64_t dc_time) noexcept {
  const auto period = static_cast<std::int64_t>(cycle_us_) * 1000;
  std::int64_t phase = static_cast<std::int64_t>((dc_time + std::uint64_t{cfg_.sync0_shift_us} * 1000U) %
                                                 static_cast<std::uint64_t>(period));
  if (phase >= period / 2) {
    phase -= period;  // early: negative
  }
  dc_phase_ns_.store(phase, std::memory_order_relaxed);
  const std::int64_t bound = period / 20;
  cycle_adjust_ns_.store(std::clamp<std::int64_t>(-phase / 4, -bound, bound), std::memory_order_relaxed);
}

void Backend::decode(ProcessImageIn& in) const noexcept {
  const bool up = up_.load(std::memory_order_relaxed);
  in.fieldbus_ok = health_.ok && up;
  in.fieldbus_subdevice = up ? health_.subdevice : waiting_for_;
  in.fieldbus_silent = health_.silent;
  // A subdevice still answering: a silent bus takes every subdevice from its position on.
  const auto online = [this](std::size_t pos) {
    return health_.ok || (health_.subdevice != 0U && (health_.silent ? pos < health_.subdevice : pos != health_.subdevice));
  };
  // SPEC §11: without a distance sensor on the bus (or with one that is lost) the separation
  // is invalid: unknown is unsafe.
  std::int32_t separation = 0;
  bool separation_valid = false;
  for (std::size_t i = 0; i < cfg_.subdevices.size(); ++i) {
    const Subdevice& s = cfg_.subdevices[i];
    const std::uint8_t* p = in_buf_.data() + in_off_[i];
    if (s.role == Role::distance_sensor) {
      separation = static_cast<std::int32_t>(get32(p + s.separation_mm));
      separation_valid = get_bit(p, s.separation_valid_bit) && online(i + 1U);
    }
  }
  for (std::size_t i = 0; i < cfg_.subdevices.size(); ++i) {
    const Subdevice& s = cfg_.subdevices[i];
    const std::uint8_t* p = in_buf_.data() + in_off_[i];
    if (s.role == Role::safety_inputs) {
      bool v[kInputBits];
      for (std::size_t b = 0; b < kInputBits; ++b) {
        v[b] = (s.in_bit[b] != kNoBit) && get_bit(p, s.in_bit[b]);
      }
      in.safety = core::RawInputs{v[0], v[1], v[2],  v[3],  v[4],  v[5],  v[6],  v[7],  v[8],
                                  v[9], v[10], v[18], v[19], v[20], v[21], v[22], v[23]};
      in.safety.separation_mm = separation;
      in.safety.separation_valid = separation_valid;
      in.contactor_closed = v[11];
      // SPEC §14: K2 and its auxiliary contact where the segment has them (bus_config checks
      // that the output and its contact come together).
      in.two_contactors = s.in_bit[kInputBits - 1U] != kNoBit;
      in.k2_closed = v[kInputBits - 1U];
      for (std::size_t a = 0; a < kAxes; ++a) {
        in.brake_released[a] = v[12U + a];
      }
    } else if (s.role == Role::drive) {
      core::DriveFeedback& d = in.drive[s.axis - 1U];
      d.statusword = get16(p + s.statusword);
      d.position_rad = static_cast<float>(get32(p + s.position_actual) / s.counts_per_rad);
      d.velocity_rad_s = static_cast<float>(get32(p + s.velocity_actual) / s.counts_per_rad);
      d.torque_permille = static_cast<std::int16_t>(get16(p + s.torque_actual));
      d.online = online(i + 1U);
      // SPEC §14: the load-side encoder, on every drive or on none (bus_config).
      in.load_encoders = s.load_position != kNoOffset;
      d.load_position_rad =
          in.load_encoders ? static_cast<float>(get32(p + s.load_position) / s.counts_per_rad) : d.position_rad;
    }
  }
}

void Backend::write(const ProcessImageOut& out) noexcept {
  for (std::size_t i = 0; i < cfg_.subdevices.size(); ++i) {
    const Subdevice& s = cfg_.subdevices[i];
    std::uint8_t* p = out_buf_.data() + out_off_[i];
    if (s.role == Role::safety_outputs) {
      set_bit(p, s.out_bit[0], out.contactor);
      set_bit(p, s.out_bit[1], out.brakes_release);
      set_bit(p, s.out_bit[2], out.reset_lamp);
      for (std::size_t a = 0; a < kAxes; ++a) {
        set_bit(p, s.out_bit[3U + a], out.brake_test_axis == a + 1U);
      }
      if (s.out_bit[9] != kNoBit) {
        set_bit(p, s.out_bit[9], out.reduced_active);
      }
      if (s.out_bit[10] != kNoBit) {
        set_bit(p, s.out_bit[10], out.contactor_k2);  // SPEC §14: K2
      }
    } else if (s.role == Role::drive) {
      const DriveOut& d = out.drive[s.axis - 1U];
      put16(p + s.controlword, d.controlword);
      put32(p + s.target_position, static_cast<std::int32_t>(std::lround(static_cast<double>(d.target_position_rad) * s.counts_per_rad)));
      put16(p + s.max_torque, d.max_torque_permille);
    }
  }
  // Issue 37: each connection's container to its device, copied as the channel made it
  // (zeros where it made none: the device then sees "not connected").
  const std::array<LinkFrame, kMaxLinks>* tx = &out.link_tx;
  std::array<LinkFrame, kMaxLinks> corrupted;
  if (!corrupt_.empty()) {
    corrupted = out.link_tx;
    corrupt_.to_device(link_cycles_, corrupted);  // tests: the master at fault (--corrupt)
    tx = &corrupted;
  }
  for (std::size_t i = 0; i < cfg_.links.count; ++i) {
    const LinkFrame& f = (*tx)[i];
    std::uint8_t* p = out_buf_.data() + link_out_[i];
    const std::size_t n = std::min<std::size_t>(f.len, link_out_len_[i]);
    std::copy_n(f.bytes.begin(), n, p);
    std::fill(p + n, p + link_out_len_[i], std::uint8_t{0});
  }
  if (async_ && handed_over_ && booted()) {
    {
      // Held by the exchange thread only to copy a few dozen bytes.
      const std::lock_guard<std::mutex> g(xfer_);
      std::copy(out_buf_.begin(), out_buf_.end(), req_out_.begin());
      ++req_seq_;
    }
    wake_.release();  // a futex wake: the exchange thread sends at once
  }
}

}  // namespace safestate::hal::ethercat

// The `ethercat` HAL backend: the process image mapped onto the PDOs of a real EtherCAT
// segment through our master (ethercrab, hal/ethercat/master-rs). The topology it
// expects comes from a validated configuration file (docs/ethercat.md), not from code.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <semaphore>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "safestate/hal/process_image.hpp"
#include "safestate/hal/link_corrupt.hpp"
#include "safestate/hal/safety_links.hpp"

namespace safestate::hal::ethercat {

// distance_sensor: SPEC §11's safety-rated distance sensor (optional, at most one): a TxPDO
// with the separation person-robot in mm (INT32) and a valid bit. Without one the separation
// is invalid, as unknown is unsafe (SSM then holds at v_allowed 0).
// safe_inputs / safe_outputs (issue 37): the safe input and output terminals of the black
// channel (docs/black-channel.md): no bits of their own, only safety containers
// ("safety_links"), which the backend copies and the channels check.
enum class Role : std::uint8_t { safety_inputs, safety_outputs, drive, distance_sensor, safe_inputs, safe_outputs };

// One connection of the black channel as a subdevice's entry lists it ("safety_links": [{"id":
// "0xA001", "channel": "A", "out_offset": 0, "in_offset": 0, "watchdog_ms": 10}, ...]): where
// its container lies in the subdevice's RxPDO image (the channel's, out_offset) and TxPDO image
// (the device's answer, in_offset). The container sizes follow from the role's data lengths.
struct SafetyLink {
  std::uint16_t id = 0;
  char channel = 'A';
  std::uint16_t out_offset = 0;
  std::uint16_t in_offset = 0;
  std::uint16_t watchdog_ms = 0;
};

// Named bits of the safety I/O terminals, in the order of the names below.
// SPEC §2 contacts, contactor/brake feedbacks, the SPEC §10 reduced-speed input, the SPEC §11
// protective fields' OSSD pairs (the first kRequiredInputBits, all required), then K2's
// auxiliary contact (SPEC §14, optional: a segment with K2 maps it and `contactor_k2`).
inline constexpr std::size_t kInputBits = 25;
inline constexpr std::size_t kRequiredInputBits = 24;
// Outputs: contactor, brakes_release, reset_lamp, then brake_hold.1..6 (that axis' brake
// stays engaged although brakes_release is set: the SPEC §12 brake test), then
// reduced_active (SPEC §10 reduced mode in force, the core's SafetyStatus::reduced: a safe
// output for the cell, and what times the reduced-mode reaction on the wire), then
// contactor_k2 (SPEC §14: K2 in series with K1, channel B's; with one channel the one
// channel drives both). The first kRequiredOutputBits must be mapped; the others are
// optional (kNoBit when not mapped).
inline constexpr std::size_t kOutputBits = 11;
inline constexpr std::size_t kRequiredOutputBits = 9;
inline constexpr std::uint16_t kNoBit = 0xFFFF;
inline constexpr std::uint16_t kNoOffset = 0xFFFF;
extern const char* const kInputBitNames[kInputBits];
extern const char* const kOutputBitNames[kOutputBits];

// One SDO download of a subdevice's start-up list, sent by the master in PRE-OP (before
// SAFE-OP) in the order of the list and read back where the object is readable.
struct StartupSdo {
  std::uint16_t index = 0;  // 0x1000..0xFFFF
  std::uint8_t sub = 0;
  std::uint8_t size = 0;    // bytes: 1, 2 or 4
  std::uint32_t value = 0;  // little-endian image, `size` bytes wide (a negative value in two's complement)
};
inline constexpr std::size_t kMaxStartupSdos = 32;  // per subdevice

struct Subdevice {
  std::string name;
  Role role = Role::drive;
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  bool check_revision = false;
  std::uint16_t in_bytes = 0;
  std::uint16_t out_bytes = 0;
  std::array<std::uint16_t, kInputBits> in_bit{};    // safety_inputs: bit of each named input
  std::array<std::uint16_t, kOutputBits> out_bit{};  // safety_outputs
  std::uint8_t axis = 0;                             // drive: 1..6
  // distance_sensor: the byte offset of the separation (INT32, mm) in its TxPDO image and
  // the bit of its valid flag ("pdo": {"separation_mm": N}, "bits": {"separation_valid": N}).
  std::uint16_t separation_mm = 0;
  std::uint16_t separation_valid_bit = 0;
  double counts_per_rad = 0.0;                       // drive: encoder increments per radian
  std::uint16_t controlword = 0, target_position = 0, max_torque = 0;   // RxPDO byte offsets (0x6040, 0x607A, 0x6072)
  std::uint16_t statusword = 0, position_actual = 0, velocity_actual = 0,
                torque_actual = 0;  // TxPDO byte offsets (0x6041, 0x6064, 0x606C, 0x6077)
  // SPEC §14: the TxPDO byte offset of 0x60E4:01 (additional position actual value: the
  // load-side encoder, INT32, in the same counts per joint revolution), optional: kNoOffset
  // when the drive has none (every drive has one or none does).
  std::uint16_t load_position = kNoOffset;
  std::vector<StartupSdo> startup;  // "startup": written by SDO in PRE-OP (needs a CoE mailbox)
  // "dc": {"assign_activate": "0x0300"}: the subdevice is synchronised by distributed
  // clocks; the ESI's AssignActivate word (0x0980/0x0981: 0x0300 = cyclic unit on, SYNC0).
  // 0 = free run (no "dc" key).
  std::uint16_t dc_assign_activate = 0;
  // Issue 37: the black channel's connections to this subdevice (safe_inputs, safe_outputs:
  // required; a drive: optional, its load-side encoder, together with load_position).
  std::vector<SafetyLink> links;
  std::uint32_t counts_per_revolution = 0;  // drive: as configured (LinkSpec)
};

// The range of `watchdog_cycles` in a bus configuration.
inline constexpr std::uint32_t kMinWatchdogCycles = 2;
inline constexpr std::uint32_t kMaxWatchdogCycles = 10000;

struct BusConfig {
  std::vector<Subdevice> subdevices;  // in bus order
  std::uint32_t frame_timeout_us = 900;
  // How long the start-up scan is repeated while it times out or finds fewer subdevices
  // than configured (drives still powering up); 0 = one scan.
  std::uint32_t scan_timeout_ms = 5000;
  // A cycle whose frame is late or lost is stale (inputs held from the last answered
  // frame); this many stale cycles in a row is FIELDBUS_LOST.
  std::uint32_t stale_cycles = 3;
  // Each subdevice's process-data watchdog (0x0400/0x0420), in scan cycles: outputs not
  // written for that long go to their safe state by themselves (the master died).
  std::uint32_t watchdog_cycles = 10;
  // SYNC0 of the DC-synchronised subdevices fires this long after the cycle's start in DC
  // time (after the frame has passed them); checked against the cycle at start-up. Default
  // 500: half the default 1 ms cycle, so that a frame sent up to that late still reaches the
  // drives before the SYNC0 that applies it (docs/ethercat.md, "Distributed clocks").
  std::uint32_t sync0_shift_us = 500;
  // Issue 37: every connection of the subdevices, in bus order and within a subdevice in its
  // listed order: the order of ProcessImageIn::link_rx / ProcessImageOut::link_tx.
  LinkTable links{};
};

// Each connection's watchdog must be at least 2 cycles of `cycle_us` (one exchange of the
// ping-pong): false with the connection named in `err` otherwise.
bool links_fit_cycle(const BusConfig& cfg, std::uint32_t cycle_us, std::string& err);

// The process-data watchdog registers for `cycles` scan cycles of `cycle_us`: the divider
// (0x0400, ticks of (divider + 2) x 40 ns) and the time in ticks (0x0420). 100 us ticks
// while the time fits 16 bits, else 1 ms ticks; false if it fits neither.
bool watchdog_registers(std::uint32_t cycles, std::uint32_t cycle_us, std::uint16_t& divider, std::uint16_t& time) noexcept;

// How long one exchange of `safestate run` may wait for its frame in a cycle of `cycle_us`:
// until 150 us before the cycle ends (3/4 of cycles shorter than 600 us). Past it the cycle
// is stale (docs/ethercat.md).
constexpr std::uint32_t exchange_budget_us(std::uint32_t cycle_us) noexcept {
  return (cycle_us >= 600U) ? cycle_us - 150U : cycle_us * 3U / 4U;
}

// Parses and validates a configuration (JSON text). On error returns false and names
// the field that is wrong in `err`; `out` is then unspecified.
bool parse_bus_config(const std::string& text, BusConfig& out, std::string& err);
bool load_bus_config(const std::string& path, BusConfig& out, std::string& err);
// hal/ethercat/default-bus.json, built in: the segment of `safestate ecat-sim`.
const char* default_bus_config() noexcept;

struct Health {
  bool ok = true;
  std::uint8_t subdevice = 0;  // 1-based position of the first subdevice at fault, 0 = none
  bool silent = false;         // no frame comes back: silent from `subdevice` on
  const char* why = "";  // a literal: set in the real-time path
};

class Backend final : public hal::Backend {
 public:
  // Opens the interface, scans, checks every identity against `cfg`, writes every
  // subdevice's process-data watchdog (`cfg.watchdog_cycles` of `cycle_us`), maps, goes to
  // OP. Never throws; on failure the backend reports the fieldbus down (BOOT then fails)
  // and boot_error() names the subdevice.
  // One exchange waits at most `exchange_timeout_us` (0: the frame timeout, as a replay
  // that must not lose a frame to a busy host does); a frame not back by then makes the
  // cycle stale: inputs held, counted. `cfg.stale_cycles` stale cycles in a row, or (when
  // `watchdog_ns` > 0) that long on the monotonic clock since the last answered frame, is
  // FIELDBUS_LOST.
  Backend(const BusConfig& cfg, const std::string& ifname, std::uint32_t cycle_us, std::uint32_t exchange_timeout_us,
          std::uint64_t watchdog_ns = 0);
  ~Backend() override;
  Backend(const Backend&) = delete;
  Backend& operator=(const Backend&) = delete;

  // One cyclic exchange: the outputs of the last write() go out, inputs come back.
  void read(ProcessImageIn& in) noexcept override;
  void write(const ProcessImageOut& out) noexcept override;

  [[nodiscard]] bool booted() const noexcept { return master_ != nullptr && boot_error_.empty(); }
  [[nodiscard]] const std::string& boot_error() const noexcept { return boot_error_; }
  // Latched: the first loss of the bus and whom it concerns.
  [[nodiscard]] const Health& health() const noexcept { return health_; }
  [[nodiscard]] std::uint64_t exchanges() const noexcept { return exchanges_; }
  // Cycles whose frame did not come back within the exchange timeout (inputs held).
  [[nodiscard]] std::uint64_t stale_cycles() const noexcept { return stale_total_.load(std::memory_order_relaxed); }
  // When the bus was lost for want of answers: the stale cycles in a row and the time since
  // the last answered frame at that moment (0 when it was lost otherwise or not at all).
  [[nodiscard]] std::uint32_t lost_after_cycles() const noexcept { return lost_after_cycles_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t lost_after_ns() const noexcept { return lost_after_ns_.load(std::memory_order_relaxed); }
  // The exchange timeout in use (us) and the watchdog written to the subdevices.
  [[nodiscard]] std::uint32_t exchange_timeout_us() const noexcept { return exchange_timeout_us_; }
  [[nodiscard]] std::uint16_t watchdog_divider() const noexcept { return wd_divider_; }
  [[nodiscard]] std::uint16_t watchdog_time() const noexcept { return wd_time_; }
  // Frames that came back matching no frame in flight (late after the frame timeout, or
  // corrupted): dropped by the master's frame thread, which carries on.
  [[nodiscard]] static std::uint64_t stray_frames() noexcept;
  // The same, for another thread (the supervisor's log): once the bus is lost, the
  // position (1-based, 0 = the bus as a whole), whether it is silent from there on, and
  // the reason; else why == nullptr.
  struct Loss {
    std::uint8_t position = 0;
    bool silent = false;
    const char* why = nullptr;
  };
  [[nodiscard]] Loss lost() const noexcept {
    const char* why = lost_why_.load(std::memory_order_acquire);  // published after the rest
    return {lost_position_.load(std::memory_order_relaxed), lost_silent_.load(std::memory_order_relaxed), why};
  }
  // Distributed clocks: whether any subdevice is synchronised, the reference clock's
  // position (1-based; 0 = none), the last frame's phase against SYNC0 minus the shift (ns,
  // negative = early), and the correction the real-time loop takes for its next wake-up
  // (RtOptions::cycle_adjust_ns: it exchanges it for 0).
  [[nodiscard]] bool dc() const noexcept { return dc_; }
  [[nodiscard]] int dc_reference() const noexcept { return dc_reference_; }
  [[nodiscard]] std::int64_t dc_phase_ns() const noexcept { return dc_phase_ns_.load(std::memory_order_relaxed); }
  std::atomic<std::int64_t>* cycle_adjust() noexcept { return dc_ ? &cycle_adjust_ns_ : nullptr; }
  // Issue 37: the black channel's connections of the bus configuration (LinkTable order).
  [[nodiscard]] const LinkTable& safety_links() const noexcept override { return cfg_.links; }
  // Issue 37 item 4, tests only (`safestate run --corrupt`, a SAFESTATE_TEST_HOOKS build):
  // faults of the master on the containers it copies. Before the first cycle.
  void set_corruptor(LinkCorruptor c) { corrupt_ = std::move(c); }
  [[nodiscard]] const LinkCorruptor& corruptor() const noexcept { return corrupt_; }
  [[nodiscard]] const std::string& subdevice_name(std::size_t position) const noexcept {
    static const std::string none = "the bus";
    return (position >= 1U && position <= cfg_.subdevices.size()) ? cfg_.subdevices[position - 1U].name : none;
  }

 private:
  void boot(const std::string& ifname);
  void decode(ProcessImageIn& in) const noexcept;
  void lose(std::uint8_t position, const char* why, bool silent = false) noexcept;
  void keep_alive() noexcept;
  void sample_time(ProcessImageIn& in, bool fresh, std::uint64_t dc_time) noexcept;
  void follow_dc(std::uint64_t dc_time) noexcept;
  bool await_dc_op();
  void ask_back_to_op(std::size_t i, std::uint64_t now_ns) noexcept;
  void hand_over() noexcept;
  void stop_exchanges() noexcept;

  BusConfig cfg_;
  struct Master;
  Master* master_ = nullptr;
  std::string boot_error_;
  Health health_;
  std::vector<std::uint8_t> in_buf_;
  std::vector<std::uint8_t> out_buf_;
  std::vector<std::size_t> in_off_;
  std::vector<std::size_t> out_off_;
  // Issue 37: each connection's container: its byte offset in in_buf_ / out_buf_ and size.
  std::array<std::size_t, kMaxLinks> link_in_{};
  std::array<std::size_t, kMaxLinks> link_out_{};
  std::array<std::uint8_t, kMaxLinks> link_in_len_{};
  LinkCorruptor corrupt_{};
  std::uint64_t link_cycles_ = 0;  // cycles since the bus came up (the corruptor's clock)
  std::array<std::uint8_t, kMaxLinks> link_out_len_{};
  std::atomic<std::uint8_t> lost_position_{0};
  std::atomic<bool> lost_silent_{false};
  std::atomic<const char*> lost_why_{nullptr};
  std::uint32_t cycle_us_;
  std::uint32_t exchange_timeout_us_;
  std::uint32_t stale_in_row_ = 0;
  std::atomic<std::uint64_t> stale_total_{0};
  std::atomic<std::uint32_t> lost_after_cycles_{0};
  std::atomic<std::uint64_t> lost_after_ns_{0};
  std::uint16_t wd_divider_ = 0;
  std::uint16_t wd_time_ = 0;
  std::uint64_t watchdog_ns_;
  std::uint64_t last_good_ns_ = 0;
  std::uint64_t exchanges_ = 0;
  // From OP until the real-time loop's first read(): the process-data watchdogs count from
  // OP, so a thread exchanges the (safe, all-zero) outputs every cycle meanwhile.
  // With an exchange timeout (`safestate run`) it stays as the exchange thread: write()
  // posts the outputs (req_out_, req_seq_) and wakes it, it sends them at once and puts the
  // answer aside (ans_*); the next read() takes it if it answers that request, else the
  // cycle is stale. The loop never waits for the bus.
  std::thread keepalive_;
  std::atomic<bool> handover_{false};
  bool async_;
  bool handed_over_ = false;
  bool counting_ = false;  // stale cycles count towards the loss once a request of the loop was answered
  // The bus is up: read() has seen an answer with every subdevice in OP and the expected
  // working counter. Until then (the master's boot, and BOOT of the core, which waits for the
  // fieldbus up to boot_timeout_ms) nothing is lost: the fieldbus is reported not up, and a
  // subdevice that fell back from OP is asked back (ask_back_to_op). From then on SPEC §4
  // rule 1: a subdevice leaving OP, a short working counter, stale cycles are FIELDBUS_LOST.
  std::atomic<bool> up_{false};
  std::uint8_t waiting_for_ = 0;  // while not up: the first subdevice not in OP (1-based), 0 = the bus
  // Per subdevice: when it was last asked back to OP (monotonic ns) and how often in all.
  std::vector<std::uint64_t> asked_ns_;
  std::vector<std::uint32_t> asked_;
  std::counting_semaphore<1 << 30> wake_{0};
  std::mutex xfer_;
  std::vector<std::uint8_t> req_out_;
  std::uint64_t req_seq_ = 0;
  std::vector<std::uint8_t> ans_in_;
  std::uint64_t ans_seq_ = 0;
  std::uint64_t ans_id_ = 0;
  std::uint64_t ans_ns_ = 0;
  std::uint64_t taken_id_ = 0;
  bool dc_ = false;
  // The SYNC0 pulse (DC time / cycle) before the last answered frame passed: the drives'
  // inputs in it were sampled there (ProcessImageIn::sample_span). 0 = none yet.
  std::uint64_t sample_pulse_ = 0;
  int dc_reference_ = 0;
  std::atomic<std::int64_t> dc_phase_ns_{0};
  std::atomic<std::int64_t> cycle_adjust_ns_{0};
};

}  // namespace safestate::hal::ethercat

// One emulated EtherCAT slave controller (ESC): the register and process-RAM space a
// master reads and writes with datagrams, the AL state machine, the SII EEPROM
// interface, the FMMUs and sync managers, the process-data watchdog. It stands in for
// the ESC chip of a real subdevice (ETG.1000.4 data link layer, ETG.1000.6 application
// layer, ETG.2010 SII); nothing here is certified or timing-accurate.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "safestate/ecat/coe.hpp"

namespace safestate::ecat {

// Register addresses of ETG.1000.4 / the ESC datasheets that the emulation gives meaning to.
namespace reg {
inline constexpr std::uint16_t type = 0x0000;
inline constexpr std::uint16_t fmmu_count = 0x0004;
inline constexpr std::uint16_t sm_count = 0x0005;
inline constexpr std::uint16_t ram_size = 0x0006;
inline constexpr std::uint16_t port_desc = 0x0007;
inline constexpr std::uint16_t features = 0x0008;
inline constexpr std::uint16_t station_addr = 0x0010;
inline constexpr std::uint16_t station_alias = 0x0012;
inline constexpr std::uint16_t dl_status = 0x0110;
inline constexpr std::uint16_t al_control = 0x0120;
inline constexpr std::uint16_t al_status = 0x0130;
inline constexpr std::uint16_t al_status_code = 0x0134;
inline constexpr std::uint16_t pdi_control = 0x0140;
inline constexpr std::uint16_t wdg_divider = 0x0400;
inline constexpr std::uint16_t wdg_time_pd = 0x0420;
inline constexpr std::uint16_t wdg_status_pd = 0x0440;
inline constexpr std::uint16_t wdg_counter_pd = 0x0442;
inline constexpr std::uint16_t eep_config = 0x0500;
inline constexpr std::uint16_t eep_control = 0x0502;
inline constexpr std::uint16_t eep_address = 0x0504;
inline constexpr std::uint16_t eep_data = 0x0508;
inline constexpr std::uint16_t fmmu = 0x0600;
inline constexpr std::uint16_t sm = 0x0800;
// Distributed clocks (ETG.1000.4 6.8, the ESC datasheets' DC chapter).
inline constexpr std::uint16_t dc_recv_port0 = 0x0900;   // 4 x 32-bit receive times, latched by a write here
inline constexpr std::uint16_t dc_system_time = 0x0910;  // 64-bit; a write is the drift-control input
inline constexpr std::uint16_t dc_recv_pu = 0x0918;      // 64-bit receive time of the processing unit
inline constexpr std::uint16_t dc_offset = 0x0920;       // 64-bit system time offset
inline constexpr std::uint16_t dc_delay = 0x0928;        // 32-bit system time delay (from the reference)
inline constexpr std::uint16_t dc_diff = 0x092C;         // 32-bit system time difference (bit 31: local smaller)
inline constexpr std::uint16_t dc_speed_start = 0x0930;  // speed counter start: a write resets the control loop
inline constexpr std::uint16_t dc_speed_diff = 0x0932;
inline constexpr std::uint16_t dc_cyclic_unit = 0x0980;  // AssignActivate low byte
inline constexpr std::uint16_t dc_activation = 0x0981;   // bit 0 cyclic operation, bit 1 SYNC0, bit 2 SYNC1
inline constexpr std::uint16_t dc_activation_status = 0x0984;
inline constexpr std::uint16_t dc_sync0_status = 0x098E;
inline constexpr std::uint16_t dc_start_time = 0x0990;   // 64-bit start time of cyclic operation (system time)
inline constexpr std::uint16_t dc_next_sync1 = 0x0998;
inline constexpr std::uint16_t dc_sync0_cycle = 0x09A0;  // 32-bit, ns
inline constexpr std::uint16_t dc_sync1_cycle = 0x09A4;
inline constexpr std::uint16_t process_ram = 0x1000;
}  // namespace reg

inline constexpr std::size_t kEscMemory = 0x3000;  // 4 KiB registers + 8 KiB process RAM
inline constexpr std::size_t kFmmus = 8;
inline constexpr std::size_t kSyncManagers = 8;

enum class AlState : std::uint8_t { init = 1, preop = 2, boot = 3, safeop = 4, op = 8 };

// AL status codes of ETG.1000.6 table 11 that the emulation raises.
namespace al_code {
inline constexpr std::uint16_t none = 0x0000;
inline constexpr std::uint16_t invalid_state_change = 0x0011;
inline constexpr std::uint16_t invalid_mailbox_config = 0x0016;
inline constexpr std::uint16_t unknown_state = 0x0012;
inline constexpr std::uint16_t bootstrap_not_supported = 0x0013;
inline constexpr std::uint16_t sm_watchdog = 0x001B;
inline constexpr std::uint16_t invalid_output_config = 0x001D;
inline constexpr std::uint16_t invalid_input_config = 0x001E;
inline constexpr std::uint16_t inconsistent_settings = 0x0026;  // 0x6060 is not CSP
inline constexpr std::uint16_t invalid_sync_cycle = 0x0035;     // 0x60C2 is not the drive's cycle
// ETG.1000.6 table 11 (ETG.1020, synchronisation): a subdevice that needs DC SYNC0 in its
// operation mode and finds it not activated (0x0981), without a cycle (0x09A0 = 0) or with a
// start time already past is refused SAFE-OP -> OP with "invalid DC SYNC configuration";
// a SYNC0 cycle other than the drive's cycle with "DC Sync0 cycle time".
inline constexpr std::uint16_t invalid_dc_sync_config = 0x0030;
inline constexpr std::uint16_t dc_sync0_cycle_time = 0x0036;
}  // namespace al_code

// One object entry of a PDO (SII PDO category entry, ETG.2010 table 15). index 0 = padding.
struct PdoEntry {
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  std::uint8_t bits = 0;
  std::uint8_t data_type = 0;  // CoE data type: 0x0001 BOOL, 0x0006 UINT16, 0x0004 INT32 ...
  std::string name;
};

struct Pdo {
  std::uint16_t index = 0;  // 0x16xx RxPDO (outputs), 0x1Axx TxPDO (inputs)
  std::vector<PdoEntry> entries;
  [[nodiscard]] std::size_t bytes() const noexcept;
};

// What a subdevice is: its identity (SII words 0x0008..0x000F) and its fixed PDO layout.
struct SubdeviceDesc {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial = 0;
  std::string name;       // SII string, shown by masters
  Pdo rx;                 // outputs (master -> subdevice); no entries = none
  Pdo tx;                 // inputs (subdevice -> master)
  std::uint16_t out_address = 0x1000;  // process RAM of the output sync manager
  std::uint16_t in_address = 0x1800;   // process RAM of the input sync manager
  // A CoE mailbox (SM0 receive at kMailboxOut, SM1 send at kMailboxIn, kMailboxBytes each;
  // the process data then on SM2/SM3) and a CiA 402 object dictionary (coe.hpp). Without
  // one (the digital I/O terminals, as simple real ones) the PDOs are on SM0/SM1.
  bool mailbox = false;
  std::uint32_t device_type = 0;  // 0x1000
  std::uint32_t cycle_us = 1000;  // the drive's cycle: 0x60C2 must equal it before SAFE-OP
  // Its operation mode needs DC SYNC0 (the ESI's OpMode "DC", AssignActivate 0x0300): no OP
  // without SYNC0 active at its cycle (AL status code 0x0030 / 0x0036). The I/O terminals
  // run free (SM-synchronous); every emulated ESC has a DC unit (can be the reference clock).
  bool dc_sync0_required = false;
};

// One subdevice's distributed-clock figures as the emulation sees them from outside (the
// "truth" no real ESC can report): its sync error against the reference clock's system
// time at the same instant, sampled at every process-data frame while its SYNC0 runs, and
// the SYNC0 events that took (or missed) a set-point.
struct DcStats {
  static constexpr std::size_t kBuckets = 2001;  // |error| in 10-ns buckets up to 20 us, the last = more
  std::uint64_t samples = 0;
  std::int64_t last_ns = 0;
  std::uint64_t max_abs_ns = 0;
  std::array<std::uint32_t, kBuckets> hist{};
  std::uint64_t latched = 0;      // set-points taken by a SYNC0 (one per frame that reached it in time)
  std::uint64_t overwritten = 0;  // a set-point replaced by the next frame before any SYNC0 took it
  std::uint64_t missed = 0;       // SYNC0 events that found no new set-point (a late or lost frame)
  std::int64_t last_lead_ns = 0;  // how long before the SYNC0 that takes it the last set-point arrived
  std::int64_t min_lead_ns = 0;
  // Where the worst sample came from (a diagnosis, not a figure): the host time it was taken
  // at, and how long before it the clock's last drift-control input came.
  std::uint64_t max_at_ns = 0;
  std::uint64_t max_input_gap_ns = 0;
  void record(std::int64_t err_ns, std::uint64_t at_ns = 0, std::uint64_t input_gap_ns = 0) noexcept;
  [[nodiscard]] std::uint64_t percentile_ns(double p) const noexcept;  // its 10-ns bucket's top (at most the max)
};

inline constexpr std::uint16_t kMailboxOut = 0x1000;  // master -> subdevice (SM0)
inline constexpr std::uint16_t kMailboxIn = 0x1080;   // subdevice -> master (SM1)
inline constexpr std::uint16_t kMailboxBytes = 128;

// The SII EEPROM image (ETG.2010): identity, general, strings, FMMU, sync-manager and PDO
// categories; the standard mailbox words and the CoE protocol bit when it has a mailbox.
std::vector<std::uint16_t> build_sii(const SubdeviceDesc& d);

class Esc {
 public:
  explicit Esc(SubdeviceDesc desc);

  // Power-on: registers to their reset values, AL state INIT.
  void reset();

  // ECAT-side access (what datagrams do). A write touches only the ECAT-writable bytes
  // and then runs the register side effects (AL control, EEPROM command).
  // Each returns false when the access was not carried out (no working counter): a read of
  // a send mailbox that holds nothing, a write to a receive mailbox that is still full.
  // Reading the last byte of a full send mailbox empties it; writing the last byte of the
  // receive mailbox fills it, and the CoE server answers at once (coe.hpp).
  bool read(std::uint16_t address, std::span<std::uint8_t> out) noexcept;
  bool write(std::uint16_t address, std::span<const std::uint8_t> in, std::uint64_t now_ns) noexcept;

  // Logical addressing through the FMMUs. Each returns true when an active FMMU of the
  // direction mapped at least one bit of [logical, logical + data.size()).
  bool logical_write(std::uint32_t logical, std::span<const std::uint8_t> data, std::uint64_t now_ns) noexcept;
  bool logical_read(std::uint32_t logical, std::span<std::uint8_t> data) const noexcept;

  // The application side (PDI): outputs the master wrote (zeros outside OP or after the
  // watchdog expired: the safe state of the outputs), inputs it will read.
  [[nodiscard]] std::span<const std::uint8_t> outputs() const noexcept;
  void set_inputs(std::span<const std::uint8_t> in) noexcept;
  // Part of the inputs: `in` at byte `offset` of the input image (a safety container).
  void set_inputs_at(std::size_t offset, std::span<const std::uint8_t> in) noexcept;
  // A register the application (PDI) sets, read-only from the wire (e.g. DL status).
  void pdi_write(std::uint16_t address, std::span<const std::uint8_t> in) noexcept;
  // Process-data watchdog (ETG.1000.4 6.3): no write to the output sync manager for
  // longer than its time = outputs safe, and the application falls back to SAFEOP
  // with AL status code 0x001B.
  void poll_watchdog(std::uint64_t now_ns) noexcept;
  // Its time as the registers hold it: (0x0400 divider + 2) x 40 ns x 0x0420.
  [[nodiscard]] std::uint64_t watchdog_ns() const noexcept;
  // How often it expired (0x0442, the process-data watchdog counter; wraps at 256).
  [[nodiscard]] std::uint8_t watchdog_expiries() const noexcept { return mem_[reg::wdg_counter_pd]; }

  // Distributed clocks. The local clock runs from power-on at (1 + drift) times the host's
  // monotonic clock in 10-ns ticks (a 100 MHz ESC clock); system time = local time + offset
  // (0x0920) + the drift-control correction. `now_ns` is the host time at which the frame
  // reaches this ESC (the segment adds the forwarding delay of the subdevices before it).
  void set_drift_ppm(double ppm) noexcept { drift_ppm_ = ppm; }
  [[nodiscard]] double drift_ppm() const noexcept { return drift_ppm_; }
  // Power-on this long before the first frame that reaches it (distinct local times per ESC).
  void set_power_on_lag_ns(std::uint64_t ns) noexcept { power_lag_ns_ = ns; }
  // The loop time through the subdevices behind it (its port 1), 0 when port 1 is closed.
  void set_downstream_loop_ns(std::uint64_t ns) noexcept { downstream_ns_ = ns; }
  void dc_at(std::uint64_t now_ns) noexcept;  // brings the DC registers to this instant
  [[nodiscard]] std::uint64_t local_time(std::uint64_t now_ns) noexcept;
  [[nodiscard]] std::uint64_t system_time(std::uint64_t now_ns) noexcept;
  // SYNC0 generated: cyclic operation and SYNC0 activated with a cycle, its start reached.
  [[nodiscard]] bool sync0_running(std::uint64_t now_ns) noexcept;
  [[nodiscard]] bool sync0_activated() const noexcept;
  [[nodiscard]] std::uint32_t sync0_cycle_ns() const noexcept;
  // SYNC0 pulses generated up to this instant (0 while SYNC0 does not run), and the time in
  // ns (of its system time, within its drift of the host's) until the next one.
  [[nodiscard]] std::uint64_t sync0_pulses(std::uint64_t now_ns) noexcept;
  [[nodiscard]] std::uint64_t ns_to_next_sync0(std::uint64_t now_ns) noexcept;
  // The drift-control loop's rate correction (its integral part), ppm.
  [[nodiscard]] double rate_correction_ppm() const noexcept { return rate_i_ * 1e6; }
  // The drift-control loop as it stands (a diagnosis): the delay (0x0928) and the last
  // difference (0x092C, signed: own system time minus the received one) the master's inputs
  // left, the slew still to take out, ns.
  [[nodiscard]] std::uint32_t dc_delay_ns() const noexcept { return u32(reg::dc_delay); }
  [[nodiscard]] std::int64_t dc_last_diff_ns() const noexcept {
    const std::uint32_t d = u32(reg::dc_diff);
    const auto mag = static_cast<std::int64_t>(d & 0x7FFFFFFFU);
    return (d & 0x80000000U) != 0U ? -mag : mag;
  }
  [[nodiscard]] double dc_slew_left_ns() const noexcept { return slew_left_ns_; }
  DcStats& dc_stats() noexcept { return dc_stats_; }
  // host time since the last drift-control input (0: none yet)
  [[nodiscard]] std::uint64_t dc_input_gap_ns(std::uint64_t now_ns) const noexcept {
    return (last_ctl_ns_ == 0U || now_ns <= last_ctl_ns_) ? 0U : now_ns - last_ctl_ns_;
  }
  [[nodiscard]] const DcStats& dc_stats() const noexcept { return dc_stats_; }

  [[nodiscard]] AlState state() const noexcept;
  [[nodiscard]] std::uint16_t al_status_code() const noexcept;
  [[nodiscard]] std::uint16_t station_address() const noexcept;
  [[nodiscard]] const SubdeviceDesc& desc() const noexcept { return desc_; }
  // The CoE object dictionary (empty without a mailbox).
  [[nodiscard]] const coe::Dictionary& dictionary() const noexcept { return od_; }
  coe::Dictionary& dictionary() noexcept { return od_; }

 private:
  struct MailboxSm {
    std::uint16_t base = 0;  // its registers
    std::uint16_t start = 0;
    std::uint16_t bytes = 0;
  };
  // The enabled mailbox sync manager of the direction (write: the master writes), if any.
  [[nodiscard]] bool mailbox_sm(bool master_writes, MailboxSm& out) const noexcept;
  [[nodiscard]] bool mailbox_full(const MailboxSm& m) const noexcept { return (mem_[m.base + 5U] & 0x08U) != 0U; }
  void set_mailbox_full(const MailboxSm& m, bool full) noexcept;
  void serve_mailbox() noexcept;
  [[nodiscard]] bool mailbox_configured() const noexcept;
  [[nodiscard]] std::uint16_t preop_to_safeop_error() const noexcept;
  void set_al(std::uint8_t state, bool error, std::uint16_t code) noexcept;
  [[nodiscard]] std::uint16_t dc_op_error(std::uint64_t now_ns) noexcept;
  void dc_latch_receive_times(std::uint64_t now_ns) noexcept;
  void dc_control(std::span<const std::uint8_t> written, std::size_t first, std::uint64_t now_ns) noexcept;
  void dc_reset_loop(std::uint64_t now_ns) noexcept;
  [[nodiscard]] double slewed(double since) const noexcept;
  void anchor(std::uint64_t now_ns) noexcept;
  void dc_setpoint_taken(std::uint64_t now_ns) noexcept;
  [[nodiscard]] std::uint64_t sync0_fired(std::uint64_t system_ns) const noexcept;
  [[nodiscard]] std::uint64_t u64(std::uint16_t a) const noexcept;
  void put64(std::uint16_t a, std::uint64_t v) noexcept;
  void on_al_control(std::uint64_t now_ns) noexcept;
  void on_eeprom_control() noexcept;
  [[nodiscard]] std::uint16_t transition_error(AlState from, std::uint8_t to) const noexcept;
  [[nodiscard]] bool sm_matches(std::uint16_t start, std::size_t bytes) const noexcept;
  [[nodiscard]] std::uint16_t u16(std::uint16_t a) const noexcept;
  [[nodiscard]] std::uint32_t u32(std::uint16_t a) const noexcept {
    return static_cast<std::uint32_t>(u16(a)) | (static_cast<std::uint32_t>(u16(static_cast<std::uint16_t>(a + 2U))) << 16U);
  }
  void put16(std::uint16_t a, std::uint16_t v) noexcept;

  SubdeviceDesc desc_;
  std::vector<std::uint16_t> sii_;
  std::array<std::uint8_t, kEscMemory> mem_{};
  std::array<std::uint8_t, 512> zeros_{};
  std::uint64_t last_output_ns_ = 0;
  coe::Dictionary od_;
  std::uint8_t mailbox_counter_ = 0;
  // Distributed clocks.
  double drift_ppm_ = 0.0;
  std::uint64_t power_lag_ns_ = 0;
  std::uint64_t downstream_ns_ = 0;
  bool powered_ = false;           // the host time of power-on is taken at the first frame
  std::uint64_t power_ns_ = 0;
  double corr_ns_ = 0.0;           // the drift-control correction at corr_host_ns_
  std::uint64_t corr_host_ns_ = 0;
  double slew_left_ns_ = 0.0;      // the proportional correction still to slew out
  double rate_i_ = 0.0;            // the integral part: a rate correction (parts)
  std::uint64_t last_ctl_ns_ = 0;  // host time of the last drift-control input
  bool pending_op_ = false;        // OP requested, waiting for the first SYNC0
  bool sync0_armed_ = false;       // activated with a start time still ahead (else it never starts)
  bool sync0_started_ = false;     // its first pulse has fired (until deactivated or reset)
  std::uint64_t last_sync0_k_ = 0; // the SYNC0 event that took the last set-point (+1; 0 = none)
  DcStats dc_stats_{};
};

}  // namespace safestate::ecat

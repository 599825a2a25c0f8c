// The black channel's devices on the emulated segment (issue 37, docs/black-channel.md,
// docs/ethercat.md "The safe terminals"): the device ends (safelink::DeviceEnd) of the safe
// input terminal (F-DI), the safe output terminal (F-DO) and the drives' protected load-side
// encoder data, their containers in the PDOs, and the faults a test puts on the wire between
// them and the master (`fault link ...` on the control socket).
//
// EMULATED: the safe terminals stand in for certified safety I/O (FSoE terminals); the
// protocol is ours (docs/black-channel.md), not FSoE. Nothing here is certified.
//
// The container objects are ours, in the manufacturer-specific range of CoE (0x2000..0x5FFF,
// ETG.1000.6): 0x2E00 / 0x2E01 the containers of channel A / B to the device (RxPDO), 0x2E10
// / 0x2E11 the device's answers to A / B (TxPDO); each container field by field: sub 1 kind
// (USINT), 2 connection id (UINT), 3 sequence (UINT), 4 acknowledge (UINT), 5 the safety data
// (when there is any), then the CRC in 32-bit parts (UDINT, the low bytes first). FSoE's own
// objects and layout are different and not used.
#pragma once

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "safestate/ecat/esc.hpp"
#include "safestate/safelink/link.hpp"

namespace safestate::ecat {

class Segment;

inline constexpr std::uint32_t kProductSafeIn = 0x00D1F001;   // F-DI
inline constexpr std::uint32_t kProductSafeOut = 0x00D0F001;  // F-DO

inline constexpr std::uint16_t kObjToDeviceA = 0x2E00;
inline constexpr std::uint16_t kObjToDeviceB = 0x2E01;
inline constexpr std::uint16_t kObjToHostA = 0x2E10;
inline constexpr std::uint16_t kObjToHostB = 0x2E11;
inline constexpr bool is_container_object(std::uint16_t index) noexcept {
  return index == kObjToDeviceA || index == kObjToDeviceB || index == kObjToHostA || index == kObjToHostB;
}

// The connections (docs/black-channel.md "Connections").
inline constexpr std::uint16_t kLinkSafeInA = 0xA001;
inline constexpr std::uint16_t kLinkSafeInB = 0xB001;
inline constexpr std::uint16_t kLinkSafeOutA = 0xA002;
inline constexpr std::uint16_t kLinkSafeOutB = 0xB002;
inline constexpr std::uint16_t link_drive(char channel, std::size_t axis) noexcept {
  return static_cast<std::uint16_t>((channel == 'A' ? 0xA010U : 0xB010U) + axis);
}
inline constexpr std::uint16_t kLinkWatchdogMs = 10;

// Data lengths of the roles (host -> device, device -> host).
inline constexpr std::size_t kSafeInHostData = 0, kSafeInDeviceData = 4;
inline constexpr std::size_t kSafeOutHostData = 1, kSafeOutDeviceData = 1;
inline constexpr std::size_t kEncoderHostData = 0, kEncoderDeviceData = 4;
// F-DO bits: host -> device bit 0 the contactor (A: K1, B: K2), bit 1 the brake relay;
// device -> host bit 0 that contactor's auxiliary contact, bit 1 that connection's outputs on.
inline constexpr std::uint8_t kSafeOutK = 0x01;
inline constexpr std::uint8_t kSafeOutRelay = 0x02;
inline constexpr std::uint8_t kSafeOutOn = 0x02;

// Appends one container to a PDO, field by field (object `object`, the header comment).
// `data_type` is the CoE type of the data entry (USINT, UDINT, DINT), unused without data.
void add_container(Pdo& pdo, std::uint16_t object, std::size_t data_bytes, std::uint8_t data_type);
// A subdevice without its containers (`ecat-sim --no-safe-terminals`: the drives as before).
void strip_containers(SubdeviceDesc& d);
// The byte offset of a container (its kind entry) in a PDO's image; -1 when it has none.
int container_offset(const Pdo& pdo, std::uint16_t object) noexcept;

enum class LinkDir : std::uint8_t { to_device, to_host };

// Every connection of the segment's devices, the device ends, the F-DO's outputs, and the
// wire faults. The cell calls cycle() at each process-data exchange (after the outputs were
// taken, before the inputs go out) and poll() in between: a device cycle runs at each
// exchange, and once per cycle period while none comes (so that a silent master still runs
// the devices' watchdogs down).
class SafeLinks {
 public:
  struct Conn {
    std::uint16_t id = 0;
    char channel = 'A';
    std::size_t pos = 0;  // 0-based position on the segment
    std::size_t axis = 0;  // drives: 1..6; 0 for the terminals
    std::uint32_t vendor = 0;
    std::uint32_t product = 0;
    std::size_t host_data = 0;
    std::size_t device_data = 0;
    std::size_t out_off = 0;  // in the subdevice's RxPDO image (the master's container)
    std::size_t in_off = 0;   // in its TxPDO image (the device's answer)
    std::size_t rx_len = 0;
    std::size_t tx_len = 0;
    safelink::DeviceEnd end;
    safelink::Verdict last = safelink::Verdict::NotConnected;
    bool powered = true;
    // The last distinct containers each way, the newest first (replay).
    std::array<std::array<std::uint8_t, safelink::kMaxContainer>, 8> hist_dev{};
    std::array<std::array<std::uint8_t, safelink::kMaxContainer>, 8> hist_host{};
    std::size_t n_dev = 0;
    std::size_t n_host = 0;
  };

  // Finds the connections of `seg`'s subdevices: the F-DI and F-DO by product code, the
  // drives (positions 3..8) where their PDOs carry containers. `seed` 0: each device's first
  // session random (getrandom) at power-up; otherwise derived from it (tests).
  // `watchdog_ms`: every connection's (the devices' parameterisation, part of each container's
  // CRC: the master's bus configuration must say the same).
  void setup(const Segment& seg, std::uint32_t cycle_us, std::uint32_t seed,
             std::uint16_t watchdog_ms = kLinkWatchdogMs);
  [[nodiscard]] bool any() const noexcept { return !conns_.empty(); }
  // An F-DO is on the line: it, not the DO terminal, drives K1, K2 and the brakes.
  [[nodiscard]] bool drives_power() const noexcept { return fdo_a_ >= 0; }
  // One device cycle of every connection. `contacts`: the DI bit word (the F-DI's data);
  // `load_counts`: each axis' 0x60E4:01 (the drives' data); `exchange`: called in a
  // process-data exchange (else: a cycle period passed without one).
  void cycle(Segment& seg, std::uint32_t contacts, const std::array<std::int32_t, 6>& load_counts,
             bool k1_closed, bool k2_closed, std::uint64_t now_ns, bool exchange);
  // The same cycle in two halves, for an exchange that runs a plant cycle in between (lock-
  // step): outputs() takes the master's containers (the faults to the device applied) and
  // runs the output terminal, whose outputs the plant cycle then uses; inputs() runs the input
  // terminal and the drives with what that plant cycle sampled (as the DI terminal and the
  // drives' plain PDOs answer in the same frame) and puts every answer on the wire.
  void outputs(Segment& seg, bool k1_closed, bool k2_closed, std::uint64_t now_ns, bool exchange);
  void inputs(Segment& seg, std::uint32_t contacts, const std::array<std::int32_t, 6>& load_counts,
              std::uint64_t now_ns);
  // Device cycles due at `now_ns` without an exchange; true when one ran.
  [[nodiscard]] bool due(std::uint64_t now_ns) const noexcept {
    return any() && now_ns >= last_cycle_ns_ + period_ns_;
  }

  // The F-DO's outputs as driven (its fail-safe rule applied).
  [[nodiscard]] bool k1() const noexcept { return out_bit(fdo_a_, kSafeOutK); }
  [[nodiscard]] bool k2() const noexcept { return out_bit(fdo_b_, kSafeOutK); }
  [[nodiscard]] bool relay_a() const noexcept { return out_bit(fdo_a_, kSafeOutRelay); }
  [[nodiscard]] bool relay_b() const noexcept { return out_bit(fdo_b_, kSafeOutRelay); }

  // `fault link ...` (the words after "fault link"): "OK" or "ERROR ...".
  std::string fault(const std::string& words);
  void clear_faults() noexcept;
  // A link fault changed a container since the last call (wire timing starts there).
  [[nodiscard]] bool take_fault_hit() noexcept {
    const bool h = fault_hit_;
    fault_hit_ = false;
    return h;
  }
  // `status` -> `safety`.
  [[nodiscard]] nlohmann::json status() const;
  [[nodiscard]] const std::vector<Conn>& connections() const noexcept { return conns_; }
  [[nodiscard]] int find(std::uint16_t id) const noexcept;

 private:
  struct Fault {
    enum class Kind : std::uint8_t { flip, replay, swap, delay, insert } kind = Kind::flip;
    int conn = -1;
    int other = -1;  // swap: the second connection; insert: the source
    LinkDir dir = LinkDir::to_device;
    int bit = -1;     // flip: -1 = the first bit of the data (or of the CRC without data)
    std::uint64_t ms = 0;
    bool started = false;
    std::uint64_t until_ns = 0;
    std::array<std::uint8_t, safelink::kMaxContainer> held{};
  };
  [[nodiscard]] bool out_bit(int c, std::uint8_t bit) const noexcept;
  void configure(Conn& c, bool new_power_up);
  void apply(LinkDir dir, std::vector<std::array<std::uint8_t, safelink::kMaxContainer>>& bufs, std::uint64_t now_ns);
  static void remember(std::array<std::array<std::uint8_t, safelink::kMaxContainer>, 8>& h, std::size_t& n,
                       const std::uint8_t* c, std::size_t len) noexcept;
  void hit(std::uint64_t now_ns) noexcept;

  std::vector<Conn> conns_;
  std::vector<Fault> faults_;
  std::uint32_t cycle_us_ = 1000;
  std::uint64_t period_ns_ = 1000000;
  std::uint64_t last_cycle_ns_ = 0;
  std::uint32_t seed_ = 0;
  std::uint16_t watchdog_ms_ = kLinkWatchdogMs;
  std::uint32_t power_ups_ = 0;
  int fdo_a_ = -1;
  int fdo_b_ = -1;
  bool fault_hit_ = false;
  bool fault_seen_ = false;       // a link fault affected a frame (the last one at fault_ns_)
  std::uint64_t fault_ns_ = 0;
  bool opened_ = false;           // the F-DO's outputs opened after it
  std::uint64_t opened_us_ = 0;
  bool was_powered_ = false;
  std::vector<std::array<std::uint8_t, safelink::kMaxContainer>> rx_;
  std::vector<std::array<std::uint8_t, safelink::kMaxContainer>> tx_;
};

}  // namespace safestate::ecat

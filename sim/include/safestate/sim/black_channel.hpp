// Issue 37 in the simulated world: the black channel of the shipped EtherCAT segment, with
// the frames not built (docs/black-channel.md "Bus faults in the campaign").
//
// What it stands in for, plainly: on the real segment the channels' containers travel in
// EtherCAT frames through the master (hal/ethercat) to the safe devices, which the emulated
// segment (ecat-sim, sim/ecat) implements. Here the containers and both of their ends are the
// real code — each channel's controller::SafetyLinks on one side, a safelink::DeviceEnd per
// connection on the other, with the same parameters as the shipped bus configuration — but
// the bus between them is a byte copy in this process: no frame, no master, no wire timing.
// The wire is tested with ecat-sim; this world exists so that the fault campaign
// (`safestate faults --fieldbus ethercat`) and unit tests can put a bus fault between a
// channel and a device at an exact cycle, reproducibly, thousands of times.
//
// The devices read the simulated world as the emulated ones do:
//  - the safe input terminal (F-DI, connections 0xA001 / 0xB001) sends each channel the DI
//    terminal's contact word (controller::fdi bit layout: the contacts, K1's and K2's
//    auxiliary contacts, the brakes' feedback);
//  - each drive (0xA01N / 0xB01N) sends its load-side encoder 0x60E4:01 in counts
//    (2^20 per revolution);
//  - the safe output terminal (F-DO) drives the plant's power path: K1 only from a valid
//    container of 0xA002 with its bit 0 set, K2 only from one of 0xB002, the brakes released
//    only while both connections' brake relay bits (bit 1) are on. The channels' plain K1,
//    K2 and brake outputs are wired to nothing.
// Between the channels and the devices a wire that copies each connection's bytes (a fixed
// slot per connection, as a PDO is) and on which single faults can be put, in either
// direction: a flipped bit, a stale container replayed, two connections' containers swapped,
// a connection's container held past the watchdog (delay), another connection's container
// inserted.
//
// No heap, no clock, no randomness: plain data, copied with the cell.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/hal/process_image.hpp"
#include "safestate/safelink/link.hpp"

namespace safestate::sim {

// The shipped segment's identities (config/bus: the ESI's vendor and product codes).
inline constexpr std::uint32_t kSafeVendor = 0x00005AFEU;
inline constexpr std::uint32_t kFdiProduct = 0x00D1F001U;
inline constexpr std::uint32_t kFdoProduct = 0x00D0F001U;
inline constexpr std::uint32_t kDriveProduct = 0x00402001U;
inline constexpr std::uint32_t kLoadCountsPerRev = 1U << 20U;
inline constexpr std::uint16_t kLinkWatchdogMs = 10;

// The shipped segment's sixteen connections, in its bus configuration's order: the drives'
// load-side encoders at positions 3..8 (0xA011..0xA016, 0xB011..0xB016, interleaved A, B),
// the F-DI at 10 (0xA001, 0xB001), the F-DO at 11 (0xA002, 0xB002).
[[nodiscard]] hal::LinkTable shipped_links() noexcept;

enum class WireFaultKind : std::uint8_t { flip, replay, swap, delay, insert };
enum class WireDirection : std::uint8_t { to_device, to_channel };
[[nodiscard]] const char* to_string(WireFaultKind k) noexcept;
[[nodiscard]] const char* to_string(WireDirection d) noexcept;

// One fault on the wire, taking effect with the next container the wire carries in `dir`.
struct WireFault {
  WireFaultKind kind = WireFaultKind::flip;
  WireDirection dir = WireDirection::to_device;
  std::uint8_t link = 0;   // the connection (its index in shipped_links())
  std::uint8_t other = 0;  // swap: the other connection; insert: the one whose container is put in
  std::uint16_t bit = 0;   // flip: the bit of the container (byte bit / 8, bit bit % 8)
  std::uint8_t age = 0;    // replay: how many cycles old the container is (2..kWireHistory-1)
  std::uint8_t hold = 0;   // delay: the cycles the wire keeps delivering the container it held
};
inline constexpr std::size_t kWireHistory = 10;

// What the devices read of the world in a cycle.
struct DeviceWorld {
  std::array<std::uint32_t, 2> contacts{};  // the F-DI's word as sent on A's and on B's connection
  std::array<std::int32_t, hal::kAxes> load_counts{};
  bool k1_closed = false;  // the F-DO's own feedback (its outputs' auxiliary contacts)
  bool k2_closed = false;
};

// The F-DI's contact word from a process image's safety inputs and feedback (controller::fdi).
[[nodiscard]] std::uint32_t contact_word(const core::RawInputs& s, const hal::ProcessImageIn& in) noexcept;
// A load-side position in the drive's counts (kLoadCountsPerRev per revolution, wrapping as an i32).
[[nodiscard]] std::int32_t load_counts(float rad) noexcept;

class BlackChannel {
 public:
  // The shipped table, each device end configured with it (cycle_us: the devices' cycle).
  explicit BlackChannel(std::uint32_t cycle_us) noexcept;

  [[nodiscard]] const hal::LinkTable& table() const noexcept { return table_; }
  // Before the channels read: each device's last container, as the wire delivers it.
  void to_channels(hal::ProcessImageIn& in) noexcept;
  // After the channels wrote: their containers (`out.link_tx`, the combined image's) as the
  // wire delivers them, each device's cycle on what it reads of `world`, and `plant` = `out`
  // with the power path as the F-DO drives it (contactor, contactor_k2, brakes_release).
  void to_devices(const hal::ProcessImageOut& out, const DeviceWorld& world, hal::ProcessImageOut& plant) noexcept;
  // A fault on the wire; false (nothing changed) when a connection, bit or age is outside
  // the table, or `other` is `link` where one is needed.
  bool inject(const WireFault& f) noexcept;
  // Wire faults go (as `clear all`); the devices stay as they are (a latched one stays failed).
  void clear() noexcept;

  // The F-DO's outputs as its connections drive them: K1 (channel 0, 0xA002) and K2
  // (channel 1, 0xB002); its brake relays likewise.
  [[nodiscard]] bool k(std::size_t channel) const noexcept;
  [[nodiscard]] bool brake_relay(std::size_t channel) const noexcept;
  [[nodiscard]] const safelink::DeviceEnd& device(std::size_t i) const noexcept { return dev_[i]; }
  [[nodiscard]] std::size_t index_of(std::uint16_t id) const noexcept;

 private:
  using Frames = std::array<hal::LinkFrame, hal::kMaxLinks>;
  // One direction of the wire: the containers it carried (for a replay), what it delivered
  // last (for a delay), the faults still to act.
  struct Wire {
    std::array<Frames, kWireHistory> history{};
    std::size_t head = 0;  // history[head]: the newest
    Frames delivered{};
    std::array<WireFault, 4> pending{};
    std::array<bool, 4> active{};
    std::array<hal::LinkFrame, 4> held{};
    void carry(Frames& f) noexcept;
  };
  hal::LinkTable table_{};
  std::array<safelink::DeviceEnd, hal::kMaxLinks> dev_{};
  Frames from_dev_{};  // each device's last container as it sent it
  Wire down_{};        // to the devices
  Wire up_{};          // to the channels
  std::size_t fdo_a_ = 0;
  std::size_t fdo_b_ = 0;
};

}  // namespace safestate::sim

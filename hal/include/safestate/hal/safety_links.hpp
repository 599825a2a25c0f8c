// The black channel's connections as a backend knows them (issue 37, docs/black-channel.md):
// which safety containers the bus carries, between which channel and which device, and the
// parameters both ends put into every container's CRC. The backend only copies each
// connection's container bytes between the bus and the process image (ProcessImageIn::link_rx,
// ProcessImageOut::link_tx, in this table's order); the channels create and check them
// (controller/safety_links.hpp), so nothing between a channel and a safe device can forge one.
//
// Plain data, no heap: a table filled once at start-up from the bus configuration.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace safestate::hal {

inline constexpr std::size_t kMaxLinks = 16;   // 2 channels x (F-DI, F-DO, 6 drives)
inline constexpr std::size_t kLinkBytes = 32;  // room for one container (safelink::kMaxContainer)

// What a connection carries (its data lengths follow from it, docs/black-channel.md).
enum class LinkRole : std::uint8_t {
  none,
  safe_inputs,   // the safe input terminal's contacts, device -> host 4 bytes (the DI bit layout)
  safe_outputs,  // the safe output terminal: host -> device 1 byte (bit 0 K, bit 1 brake relay),
                 // device -> host 1 byte (bit 0 the K's auxiliary contact, bit 1 outputs on)
  load_encoder,  // a drive's load-side position 0x60E4:01, device -> host 4 bytes (i32 counts)
};

// One connection: channel 'A' or 'B' hosts it, the device is the subdevice at `position`.
struct LinkSpec {
  std::uint16_t id = 0;  // unique on the segment, never 0 (0xA001, 0xB001, ...)
  char channel = 0;      // 'A' or 'B'
  LinkRole role = LinkRole::none;
  std::uint8_t axis = 0;  // load_encoder: 1..6
  std::uint8_t host_data_bytes = 0;
  std::uint8_t device_data_bytes = 0;
  std::uint16_t watchdog_ms = 0;
  std::uint32_t vendor_id = 0;  // the device's identity, as the bus configuration names it
  std::uint32_t product_code = 0;
  std::uint16_t position = 0;                // 1-based station position on the segment
  std::uint32_t counts_per_revolution = 0;   // load_encoder: the scale of its data
};

struct LinkTable {
  std::uint8_t count = 0;
  std::array<LinkSpec, kMaxLinks> link{};
};

// One connection's container as the bus delivered it (in) or is to carry it (out).
struct LinkFrame {
  std::uint8_t len = 0;  // the container's size; 0: nothing (no such connection)
  std::array<std::uint8_t, kLinkBytes> bytes{};
};

}  // namespace safestate::hal

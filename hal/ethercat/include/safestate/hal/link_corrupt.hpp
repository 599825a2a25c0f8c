// Issue 37 item 4: faults of the master itself on the black channel's containers, for tests
// (`safestate run --corrupt SPEC`, only in a build with SAFESTATE_TEST_HOOKS: a production
// build has no such entry point). The master is the part every channel's data passes through;
// these are the errors a faulty master process, its memory or its network stack could make,
// put where it copies the containers (hal::ethercat::Backend): the channels and the safe
// devices must catch each of them, exactly as they catch the same faults on the wire
// (ecat-sim's `fault link ...`).
//
// SPEC (one fault): KIND ID [ID2] DIR [ARG] at=CYCLES
//   flip ID DIR [BIT]        one container: bit BIT (default: the first bit of its data, or of
//                            its CRC without data) flipped
//   replay ID DIR            one container replaced by the one of that connection 4 cycles before
//   swap ID ID2 DIR          the two connections' containers exchanged in one cycle
//   delay ID DIR MS          that connection's containers held (the last one repeated) for MS ms
//   insert ID FROM DIR       connection FROM's container put in ID's place, once
// DIR: to-device (what the channel made, on its way to the device) or to-host (the device's
// answer, on its way to the channel). at=CYCLES: the master's cycles after the bus came up.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "safestate/hal/safety_links.hpp"

namespace safestate::hal::ethercat {

class LinkCorruptor {
 public:
  // Parses one SPEC against the bus's connections; false with `err` naming what is wrong
  // (nothing added).
  bool add(const std::string& spec, const LinkTable& links, std::uint32_t cycle_us, std::string& err);
  [[nodiscard]] bool empty() const noexcept { return faults_.empty(); }
  // The master's cycle `n` (from 1 once the bus is up): the device's answers on their way to
  // the channels, and the channels' containers on their way to the devices.
  void to_host(std::uint64_t n, std::array<LinkFrame, kMaxLinks>& rx) noexcept;
  void to_device(std::uint64_t n, std::array<LinkFrame, kMaxLinks>& tx) noexcept;
  // Faults that have acted, for the log: "flip 0xA002 to-device at cycle 3000", ...
  [[nodiscard]] std::vector<std::string> done() const;

 private:
  enum class Kind : std::uint8_t { flip, replay, swap, delay, insert };
  struct Fault {
    Kind kind = Kind::flip;
    std::size_t a = 0;  // the connection (LinkTable index)
    std::size_t b = 0;  // swap: the other; insert: the source
    bool to_device = true;
    int bit = -1;
    std::uint64_t at = 0;
    std::uint64_t cycles = 1;  // delay: how many cycles
    bool acted = false;
    LinkFrame held{};
    std::string text;
  };
  void apply(bool to_device, std::uint64_t n, std::array<LinkFrame, kMaxLinks>& f) noexcept;

  std::vector<Fault> faults_;
  // The last few containers of each connection and direction (replay).
  static constexpr std::size_t kHistory = 4;
  std::array<std::array<LinkFrame, kHistory>, kMaxLinks> hist_to_device_{};
  std::array<std::array<LinkFrame, kHistory>, kMaxLinks> hist_to_host_{};
};

}  // namespace safestate::hal::ethercat

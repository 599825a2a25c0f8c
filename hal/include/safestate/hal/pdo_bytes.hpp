// Reading and writing process data as it travels on EtherCAT: little-endian words, bit i
// of a byte string at byte i/8, bit i%8 (ETG.1000.4). Shared by the master's backend and
// the segment emulator, so both sides read the wire the same way.
#pragma once

#include <cstddef>
#include <cstdint>

namespace safestate::hal::pdo {

[[nodiscard]] inline bool get_bit(const std::uint8_t* p, std::size_t i) noexcept {
  return ((static_cast<unsigned>(p[i / 8U]) >> (i % 8U)) & 1U) != 0U;
}
inline void set_bit(std::uint8_t* p, std::size_t i, bool v) noexcept {
  const auto m = static_cast<std::uint8_t>(1U << (i % 8U));
  p[i / 8U] = static_cast<std::uint8_t>(v ? (p[i / 8U] | m) : (p[i / 8U] & ~m));
}
[[nodiscard]] inline std::uint16_t get16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>(static_cast<unsigned>(p[0]) | (static_cast<unsigned>(p[1]) << 8U));
}
inline void put16(std::uint8_t* p, std::uint16_t v) noexcept {
  p[0] = static_cast<std::uint8_t>(v & 0xFFU);
  p[1] = static_cast<std::uint8_t>(v >> 8U);
}
[[nodiscard]] inline std::int32_t get32(const std::uint8_t* p) noexcept {
  std::uint32_t u = 0;
  for (std::size_t k = 0; k < 4U; ++k) {
    u |= static_cast<std::uint32_t>(p[k]) << (8U * k);
  }
  return static_cast<std::int32_t>(u);
}
inline void put32(std::uint8_t* p, std::int32_t v) noexcept {
  const auto u = static_cast<std::uint32_t>(v);
  for (std::size_t k = 0; k < 4U; ++k) {
    p[k] = static_cast<std::uint8_t>((u >> (8U * k)) & 0xFFU);
  }
}

}  // namespace safestate::hal::pdo

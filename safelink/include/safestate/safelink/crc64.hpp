#pragma once
// CRC-64/XZ, the CRC of the safety container (docs/black-channel.md): the ECMA-182 polynomial
// 0x42F0E1EBA9EA3693 (reflected 0xC96C5795D7870F42), initial register 0xFFFFFFFFFFFFFFFF,
// reflected in and out, final XOR 0xFFFFFFFFFFFFFFFF; check value of "123456789":
// 0x995DC9BBDF1939FA. The CRC of the .xz file format (also called CRC-64/GO-ECMA).
// Table-driven, the table computed at compile time.
//
// The register can be carried between calls (crc64_update) so that the connection's
// parameters, which are not sent, are fed first and the container after them.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace safestate::safelink {

inline constexpr std::uint64_t kCrc64ReflectedPoly = 0xC96C5795D7870F42ULL;
inline constexpr std::uint64_t kCrc64Poly = 0x42F0E1EBA9EA3693ULL;  // the same, MSB-first notation
inline constexpr std::uint64_t kCrc64Init = 0xFFFFFFFFFFFFFFFFULL;

namespace detail {
constexpr std::array<std::uint64_t, 256> make_crc64_table() noexcept {
  std::array<std::uint64_t, 256> t{};
  for (std::size_t i = 0; i < 256U; ++i) {
    std::uint64_t c = i;
    for (int k = 0; k < 8; ++k) c = ((c & 1U) != 0U) ? ((c >> 1U) ^ kCrc64ReflectedPoly) : (c >> 1U);
    t[i] = c;
  }
  return t;
}

// The reflected notation is the MSB-first one with its 64 bits in reverse order.
constexpr std::uint64_t reflect64(std::uint64_t v) noexcept {
  std::uint64_t r = 0;
  for (int i = 0; i < 64; ++i) r |= ((v >> i) & 1U) << (63 - i);
  return r;
}
static_assert(reflect64(kCrc64Poly) == kCrc64ReflectedPoly, "CRC-64/XZ: the two notations of one polynomial");
}  // namespace detail

inline constexpr std::array<std::uint64_t, 256> kCrc64Table = detail::make_crc64_table();

// Feeds bytes into a register (start with kCrc64Init; the CRC is the register's complement).
constexpr std::uint64_t crc64_update(std::uint64_t reg, std::span<const std::uint8_t> bytes) noexcept {
  for (const std::uint8_t b : bytes) reg = kCrc64Table[(reg ^ b) & 0xFFU] ^ (reg >> 8U);
  return reg;
}

constexpr std::uint64_t crc64_final(std::uint64_t reg) noexcept { return ~reg; }

constexpr std::uint64_t crc64(std::span<const std::uint8_t> bytes) noexcept {
  return crc64_final(crc64_update(kCrc64Init, bytes));
}

namespace detail {
constexpr bool crc64_check_value() noexcept {
  constexpr std::array<std::uint8_t, 9> s{'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  return crc64(s) == 0x995DC9BBDF1939FAULL;
}
}  // namespace detail
static_assert(detail::crc64_check_value(), "CRC-64/XZ check value (the catalogue's check of \"123456789\")");

}  // namespace safestate::safelink

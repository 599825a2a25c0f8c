#pragma once
// CRC-32C (Castagnoli, polynomial 0x1EDC6F41; reflected 0x82F63B78), the CRC of the safety
// container (docs/black-channel.md). Table-driven, the table computed at compile time.
// Standard parameters: initial register 0xFFFFFFFF, reflected in and out, final XOR
// 0xFFFFFFFF; check value of "123456789": 0xE3069283.
//
// The register can be carried between calls (crc32c_update) so that the connection's
// parameters, which are not sent, are fed first and the container after them.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace safestate::safelink {

inline constexpr std::uint32_t kCrc32cReflectedPoly = 0x82F63B78U;
inline constexpr std::uint32_t kCrc32cPoly = 0x1EDC6F41U;  // the same, MSB-first notation
inline constexpr std::uint32_t kCrc32cInit = 0xFFFFFFFFU;

namespace detail {
constexpr std::array<std::uint32_t, 256> make_crc32c_table() noexcept {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t i = 0; i < 256U; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = ((c & 1U) != 0U) ? ((c >> 1U) ^ kCrc32cReflectedPoly) : (c >> 1U);
    t[i] = c;
  }
  return t;
}
}  // namespace detail

inline constexpr std::array<std::uint32_t, 256> kCrc32cTable = detail::make_crc32c_table();

// Feeds bytes into a register (start with kCrc32cInit; the CRC is the register's complement).
constexpr std::uint32_t crc32c_update(std::uint32_t reg, std::span<const std::uint8_t> bytes) noexcept {
  for (const std::uint8_t b : bytes) reg = kCrc32cTable[(reg ^ b) & 0xFFU] ^ (reg >> 8U);
  return reg;
}

constexpr std::uint32_t crc32c_final(std::uint32_t reg) noexcept { return ~reg; }

constexpr std::uint32_t crc32c(std::span<const std::uint8_t> bytes) noexcept {
  return crc32c_final(crc32c_update(kCrc32cInit, bytes));
}

namespace detail {
constexpr bool crc32c_check_value() noexcept {
  constexpr std::array<std::uint8_t, 9> s{'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  return crc32c(s) == 0xE3069283U;
}
}  // namespace detail
static_assert(detail::crc32c_check_value(), "CRC-32C check value (RFC 3720 B.4 / Castagnoli)");

}  // namespace safestate::safelink

// The container's CRC-64/XZ (safelink/crc64.hpp) against a bitwise reference, and the weight
// distribution behind docs/black-channel.md's residual error figures (tools/crc/weights.hpp,
// tools/crc_residual.cpp): against a brute force over every codeword of small codes (8- to
// 64-bit CRCs), and against the Hamming distances published for CRC-32C and IEEE 802.3's
// CRC-32 (P. Koopman, CRC Polynomial Zoo: 0x8f6e37a0 and 0x82608edb in his notation), which
// check the counting itself (the container no longer uses a 32-bit CRC).
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "crc/weights.hpp"
#include "safestate/safelink/crc64.hpp"

namespace crc = safestate::tools::crc;
namespace sl = safestate::safelink;

namespace {

constexpr std::uint64_t kCrc32cPoly = 0x1EDC6F41U;  // CRC-32C (Castagnoli), MSB-first

// CRC-64/XZ bit by bit in the catalogue's terms, without the reflected table: each input
// byte reflected, shifted MSB-first through the ECMA-182 polynomial, the register reflected
// and complemented at the end.
std::uint64_t reflect(std::uint64_t v, unsigned bits) {
  std::uint64_t r = 0;
  for (unsigned i = 0; i < bits; ++i) r |= ((v >> i) & 1U) << (bits - 1U - i);
  return r;
}
std::uint64_t crc64_bitwise(const std::vector<std::uint8_t>& bytes) {
  std::uint64_t reg = ~std::uint64_t{0};
  for (const std::uint8_t b : bytes) {
    reg ^= reflect(b, 8) << 56U;
    for (int k = 0; k < 8; ++k) reg = ((reg >> 63U) != 0U) ? ((reg << 1U) ^ 0x42F0E1EBA9EA3693ULL) : (reg << 1U);
  }
  return reflect(reg, 64) ^ ~std::uint64_t{0};
}

// Every codeword of an MSB-first CRC (initial register 0) over `bytes` bytes: its weight.
std::vector<std::uint64_t> brute_force(std::uint64_t poly, unsigned width, unsigned bytes) {
  const unsigned k = bytes * 8U;
  const unsigned n = k + width;
  std::vector<std::uint64_t> a(n + 1U, 0);
  const std::uint64_t top = std::uint64_t{1} << (width - 1U);
  const std::uint64_t mask = (width == 64U) ? ~std::uint64_t{0} : ((std::uint64_t{1} << width) - 1U);
  for (std::uint64_t m = 1; m < (std::uint64_t{1} << k); ++m) {
    std::uint64_t reg = 0;
    for (unsigned i = k; i-- > 0;) {
      const bool in = ((m >> i) & 1U) != 0U;
      const bool fb = ((reg & top) != 0U) != in;
      reg = (reg << 1U) & mask;
      if (fb) reg ^= poly;
    }
    a[static_cast<unsigned>(__builtin_popcountll(m) + __builtin_popcountll(reg))] += 1;
  }
  return a;
}

void expect_same_as_brute_force(std::uint64_t poly, unsigned width, unsigned bytes) {
  const std::vector<std::uint64_t> want = brute_force(poly, width, bytes);
  const crc::Weights got = crc::weights(poly, width, bytes, 8);
  ASSERT_TRUE(got.error.empty()) << got.error;
  ASSERT_EQ(got.n, bytes * 8U + width);
  for (unsigned d = 1; d <= 8 && d < want.size(); ++d) {
    EXPECT_EQ(crc::to_string(got.a[d]), std::to_string(want[d]))
        << "poly 0x" << std::hex << poly << std::dec << " width " << width << " bytes " << bytes << " d " << d;
  }
}

bool zero_below(const crc::Weights& w, unsigned d) {
  for (unsigned i = 1; i < d; ++i) {
    if (w.a[i] != 0U) return false;
  }
  return true;
}

}  // namespace

TEST(SafelinkCrc64, CheckValueAndABitwiseReference) {
  const std::vector<std::uint8_t> check{'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(crc64_bitwise(check), 0x995DC9BBDF1939FAULL);  // the reference itself
  EXPECT_EQ(sl::crc64(check), 0x995DC9BBDF1939FAULL);
  std::mt19937_64 rng(37);
  for (int i = 0; i < 2000; ++i) {
    std::vector<std::uint8_t> b(static_cast<std::size_t>(rng() % 64U));
    for (auto& x : b) x = static_cast<std::uint8_t>(rng());
    ASSERT_EQ(sl::crc64(b), crc64_bitwise(b)) << "length " << b.size();
    // Fed in two parts through the carried register: the same.
    const std::size_t cut = b.empty() ? 0 : static_cast<std::size_t>(rng() % b.size());
    const std::span<const std::uint8_t> all{b};
    ASSERT_EQ(sl::crc64_final(sl::crc64_update(sl::crc64_update(sl::kCrc64Init, all.first(cut)), all.subspan(cut))),
              crc64_bitwise(b));
  }
}

TEST(SafelinkCrcWeights, SmallCodesAgreeWithEveryCodeword) {
  // Codes with low distances (A_2, A_3, A_4 > 0): the overlapping pairs must be subtracted.
  expect_same_as_brute_force(0x07, 8, 1);     // CRC-8 (x^8+x^2+x+1)
  expect_same_as_brute_force(0x07, 8, 2);
  expect_same_as_brute_force(0x05, 5, 2);     // CRC-5-USB
  expect_same_as_brute_force(0x03, 3, 2);     // a 3-bit CRC: many low-weight codewords
  expect_same_as_brute_force(0x1021, 16, 2);  // CRC-16-CCITT
  expect_same_as_brute_force(0x8005, 16, 2);  // CRC-16 (IBM)
  // The container's 64-bit CRC (no codeword of weight <= 8 here: the zeros are counted too).
  expect_same_as_brute_force(sl::kCrc64Poly, 64, 1);
  expect_same_as_brute_force(sl::kCrc64Poly, 64, 2);
  // CRC-64/GO-ISO (x^64 + x^4 + x^3 + x + 1): codewords of weight 5 and up, so the 64-bit
  // path is checked on counts that are not 0 as well.
  expect_same_as_brute_force(0x000000000000001BULL, 64, 2);
}

TEST(SafelinkCrcWeights, Crc32cHammingDistancesAsPublished) {
  // CRC-32C: HD 10 up to 47 data bits, HD 8 up to 177, HD 6 up to 5243 (Koopman).
  const auto w5 = crc::weights(kCrc32cPoly, 32, 5, 8);  // 40 bits
  EXPECT_TRUE(zero_below(w5, 9));
  const auto w6 = crc::weights(kCrc32cPoly, 32, 6, 8);  // 48 bits
  EXPECT_TRUE(zero_below(w6, 8));
  EXPECT_GT(w6.a[8], 0U);
  const auto w22 = crc::weights(kCrc32cPoly, 32, 22, 6);  // 176 bits
  EXPECT_TRUE(zero_below(w22, 7));
  const auto w23 = crc::weights(kCrc32cPoly, 32, 23, 6);  // 184 bits
  EXPECT_TRUE(zero_below(w23, 6));
  EXPECT_GT(w23.a[6], 0U);
}

TEST(SafelinkCrcWeights, Ieee8023HammingDistancesAsPublished) {
  // IEEE 802.3 CRC-32: HD 8 up to 91 data bits, HD 7 up to 171, HD 6 up to 268.
  const auto a = crc::weights(0x04C11DB7, 32, 11, 8);  // 88 bits
  EXPECT_TRUE(zero_below(a, 8));
  EXPECT_GT(a.a[8], 0U);
  const auto b = crc::weights(0x04C11DB7, 32, 12, 7);  // 96 bits
  EXPECT_TRUE(zero_below(b, 7));
  EXPECT_GT(b.a[7], 0U);
  const auto c = crc::weights(0x04C11DB7, 32, 33, 6);  // 264 bits
  EXPECT_TRUE(zero_below(c, 6));
  const auto d = crc::weights(0x04C11DB7, 32, 34, 5);  // 272 bits
  EXPECT_TRUE(zero_below(d, 5));
  EXPECT_GT(d.a[5], 0U);
}

TEST(SafelinkCrcWeights, BadInputsAreRefused) {
  EXPECT_FALSE(crc::weights(0x07, 8, 0, 8).error.empty());
  EXPECT_FALSE(crc::weights(0x07, 8, 65, 8).error.empty());
  EXPECT_FALSE(crc::weights(0x06, 8, 2, 8).error.empty());   // no x^0 term
  EXPECT_FALSE(crc::weights(0x107, 8, 2, 8).error.empty());  // above the width
  EXPECT_FALSE(crc::weights(0x07, 8, 2, 9).error.empty());
  EXPECT_FALSE(crc::weights(0x07, 2, 2, 8).error.empty());
}

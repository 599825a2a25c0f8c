#pragma once
// The low part of the weight distribution of a CRC code of one length (issue 37,
// docs/black-channel.md): A_d, the number of error patterns of weight d that the CRC does
// not detect, exactly for d <= 8. Used by tools/crc_residual.cpp and test_safelink_crc.
//
// An error pattern over the n transmitted bits (the covered bytes and the CRC) goes
// undetected exactly when its syndrome is 0; the syndrome is linear, so each bit has one and
// a pattern is undetected when its bits' syndromes XOR to 0. The initial register, the final
// XOR and an unsent prefix (the connection's parameters) cancel: both ends feed the same.
// Bit order (reflected or not) only renames positions: the distribution is the same.
//
// Meet in the middle: for d = lo + hi (lo = d/2), count the ordered pairs (X, Y) of bit sets
// with |X| = lo, |Y| = hi and equal syndromes. A pair with |X n Y| = t is a codeword of
// weight d - 2t (X xor Y) with t of the other positions added to both, so
//   pairs_d = sum_t A_{d-2t} C(d-2t, lo-t) C(n-d+2t, t)   (A_0 = 1)
// and A_d follows from the lower weights: exact for every code, no assumption on its
// distance. Memory: C(n, 4) syndromes of 8 bytes for d = 7, 8.
#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

namespace safestate::tools::crc {

__extension__ typedef unsigned __int128 u128;

inline u128 choose(unsigned n, unsigned k) {
  if (k > n) return 0;
  u128 r = 1;
  for (unsigned i = 0; i < k; ++i) r = r * (n - i) / (i + 1U);
  return r;
}

// The syndromes of the n = 8*bytes + width transmitted bits: first the covered bits in the
// order sent (MSB-first polynomial convention), then the CRC's own bits.
inline std::vector<std::uint64_t> syndromes(std::uint64_t poly, unsigned width, unsigned bytes) {
  const std::uint64_t top = std::uint64_t{1} << (width - 1U);
  const std::uint64_t mask = (width == 64U) ? ~std::uint64_t{0} : ((std::uint64_t{1} << width) - 1U);
  const unsigned k = bytes * 8U;
  std::vector<std::uint64_t> s(k + width);
  // The last covered bit's syndrome is x^width mod G (= poly); each earlier one is x times the next.
  std::uint64_t reg = poly & mask;
  for (unsigned i = k; i-- > 0;) {
    s[i] = reg;
    const bool carry = (reg & top) != 0U;
    reg = (reg << 1U) & mask;
    if (carry) reg ^= poly & mask;
  }
  for (unsigned j = 0; j < width; ++j) s[k + j] = std::uint64_t{1} << j;
  return s;
}

namespace detail {
inline void subsets(const std::vector<std::uint64_t>& s, unsigned k, std::vector<std::uint64_t>& out) {
  const std::size_t n = s.size();
  out.clear();
  if (k == 0) {
    out.push_back(0);
  } else if (k == 1) {
    out = s;
  } else if (k == 2) {
    out.reserve(n * (n - 1) / 2);
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j) out.push_back(s[i] ^ s[j]);
  } else if (k == 3) {
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j)
        for (std::size_t l = j + 1; l < n; ++l) out.push_back(s[i] ^ s[j] ^ s[l]);
  } else {
    out.reserve(static_cast<std::size_t>(choose(static_cast<unsigned>(n), 4)));
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j) {
        const std::uint64_t ij = s[i] ^ s[j];
        for (std::size_t l = j + 1; l < n; ++l)
          for (std::size_t m = l + 1; m < n; ++m) out.push_back(ij ^ s[l] ^ s[m]);
      }
  }
  std::sort(out.begin(), out.end());
}

inline u128 matching_pairs(const std::vector<std::uint64_t>& x, const std::vector<std::uint64_t>& y) {
  u128 pairs = 0;
  std::size_t i = 0;
  std::size_t j = 0;
  while (i < x.size() && j < y.size()) {
    if (x[i] < y[j]) {
      ++i;
    } else if (y[j] < x[i]) {
      ++j;
    } else {
      const std::uint64_t v = x[i];
      u128 ci = 0;
      u128 cj = 0;
      while (i < x.size() && x[i] == v) ++i, ++ci;
      while (j < y.size() && y[j] == v) ++j, ++cj;
      pairs += ci * cj;
    }
  }
  return pairs;
}
}  // namespace detail

struct Weights {
  unsigned n = 0;            // transmitted bits
  std::vector<u128> a;       // a[d], d = 0..max_weight (a[0] = 1)
  std::string error;         // non-empty: the inputs were refused or the count failed
};

// A_d for d = 0..max_weight (<= 8) of the CRC `poly` (MSB-first, without the x^width term)
// of `width` bits over `bytes` covered bytes.
inline Weights weights(std::uint64_t poly, unsigned width, unsigned bytes, unsigned max_weight) {
  Weights w;
  if (width < 3 || width > 64) return w.error = "width must be 3..64", w;
  if ((poly & 1U) == 0U) return w.error = "the polynomial's x^0 term must be 1", w;
  if (width < 64 && (poly >> width) != 0U) return w.error = "the polynomial has bits above its width", w;
  if (bytes < 1 || bytes > 64) return w.error = "covered bytes must be 1..64", w;
  if (max_weight < 1 || max_weight > 8) return w.error = "max weight must be 1..8", w;
  const std::vector<std::uint64_t> s = syndromes(poly, width, bytes);
  w.n = static_cast<unsigned>(s.size());
  w.a.assign(max_weight + 1U, 0);
  w.a[0] = 1;
  std::vector<std::vector<std::uint64_t>> table(5);
  std::vector<bool> built(5, false);
  for (unsigned d = 1; d <= max_weight; ++d) {
    const unsigned lo = d / 2U;
    const unsigned hi = d - lo;
    for (unsigned k : {lo, hi}) {
      if (!built[k]) {
        detail::subsets(s, k, table[k]);
        built[k] = true;
      }
    }
    u128 pairs = detail::matching_pairs(table[lo], table[hi]);
    for (unsigned t = 1; t <= lo; ++t) {
      const unsigned wt = d - 2U * t;
      const u128 sub = w.a[wt] * choose(wt, lo - t) * choose(w.n - wt, t);
      if (sub > pairs) return w.error = "inconsistent count at weight " + std::to_string(d), w;
      pairs -= sub;
    }
    const u128 per = choose(d, lo);
    if (pairs % per != 0U) return w.error = "count at weight " + std::to_string(d) + " not divisible", w;
    w.a[d] = pairs / per;
  }
  return w;
}

inline std::string to_string(u128 v) {
  if (v == 0) return "0";
  std::string r;
  while (v > 0) {
    r.insert(r.begin(), static_cast<char>('0' + static_cast<int>(v % 10U)));
    v /= 10U;
  }
  return r;
}

}  // namespace safestate::tools::crc

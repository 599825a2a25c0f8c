// Token helpers of the simulated world's vocabulary (inputs, faults, the person), shared by
// every parser of it: the .scn parser, the emulator's control socket and the gateway.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "safestate/core/types.hpp"

namespace safestate::vocab {

// An empty string: no problem. Otherwise what is wrong, naming it.
using Problem = std::string;
using Tokens = std::vector<std::string_view>;

inline std::string quoted(std::string_view s) { return "'" + std::string(s) + "'"; }

// Whitespace-separated words of `s` (views into it).
Tokens split_words(std::string_view s);

// Whole-token decimal numbers: no sign for unsigned types, nothing left over.
template <typename T>
bool to_number(std::string_view s, T& out) noexcept {
  if (s.empty()) {
    return false;
  }
  T v{};
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc{} || end != s.data() + s.size()) {
    return false;
  }
  out = v;
  return true;
}

// A whole-token finite decimal number (no '+'; '-' only).
inline bool to_real(std::string_view s, double& out) noexcept {
  double v = 0.0;
  if (!to_number(s, v) || !std::isfinite(v)) {
    return false;
  }
  out = v;
  return true;
}

inline bool split_pair(std::string_view tok, std::string_view& key, std::string_view& value) noexcept {
  const std::size_t eq = tok.find('=');
  if (eq == std::string_view::npos || eq == 0) {
    return false;
  }
  key = tok.substr(0, eq);
  value = tok.substr(eq + 1);
  return true;
}

// `0x` and one to four hex digits.
inline bool hex_word(std::string_view s, std::uint16_t& out) noexcept {
  if (s.size() < 3 || s.size() > 6 || (s.substr(0, 2) != "0x" && s.substr(0, 2) != "0X")) {
    return false;
  }
  std::uint16_t v = 0;
  const auto [end, ec] = std::from_chars(s.data() + 2, s.data() + s.size(), v, 16);
  if (ec != std::errc{} || end != s.data() + s.size()) {
    return false;
  }
  out = v;
  return true;
}

inline bool axis_1_to_6(std::string_view s, std::uint8_t& axis) noexcept {
  std::uint8_t v = 0;
  if (!to_number(s, v) || v < 1 || v > core::kAxes) {
    return false;
  }
  axis = v;
  return true;
}

}  // namespace safestate::vocab

// Small token helpers shared by the .scn parser's files (parser.cpp, safety_keys.cpp).
#pragma once

#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "safestate/core/types.hpp"
#include "safestate/scenario/scenario.hpp"

namespace safestate::scenario::util {

// An empty string: no problem. Otherwise what is wrong with the line.
using Problem = std::string;

using Tokens = std::vector<std::string_view>;

inline std::string quoted(std::string_view s) { return "'" + std::string(s) + "'"; }

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

inline bool to_real(std::string_view s, double& out) noexcept {
  double v = 0.0;
  if (!to_number(s, v) || !std::isfinite(v)) {
    return false;
  }
  out = v;
  return true;
}

// `<=X`, `>=X`, `<X`, `>X` (`rest` starts at the operator): the comparison into `cmp` and
// `number` the text after it. False when `rest` starts with none of them.
inline bool compare_op(std::string_view rest, Compare& cmp, std::string_view& number) noexcept {
  constexpr std::array<std::pair<std::string_view, Compare>, 4> ops{{
      {"<=", Compare::le}, {">=", Compare::ge}, {"<", Compare::lt}, {">", Compare::gt}}};
  for (const auto& [op, c] : ops) {
    if (rest.substr(0, op.size()) == op) {
      cmp = c;
      number = rest.substr(op.size());
      return true;
    }
  }
  return false;
}

// The core's name lookups take C strings: copy the token into a bounded buffer.
template <typename E>
bool lookup(std::string_view s, bool (*parse_fn)(const char*, E&) noexcept, E& out) noexcept {
  std::array<char, 64> buf{};
  if (s.size() >= buf.size()) {
    return false;
  }
  std::memcpy(buf.data(), s.data(), s.size());
  return parse_fn(buf.data(), out);
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

inline bool axis_1_to_6(std::string_view s, std::uint8_t& axis) noexcept {
  std::uint8_t v = 0;
  if (!to_number(s, v) || v < 1 || v > core::kAxes) {
    return false;
  }
  axis = v;
  return true;
}

}  // namespace safestate::scenario::util

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
#include "safestate/vocab/tokens.hpp"

namespace safestate::scenario::util {

// The token helpers are the vocabulary's (vocab/tokens.hpp): one definition.
using vocab::Problem;
using vocab::quoted;
using vocab::to_number;
using vocab::to_real;
using vocab::Tokens;

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

using vocab::axis_1_to_6;
using vocab::split_pair;

}  // namespace safestate::scenario::util

// RFC 8785 (JCS) written over nlohmann::json. See jcs.hpp.
#include "safestate/safety/jcs.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string_view>
#include <system_error>
#include <vector>

namespace safestate::safety::jcs {

std::optional<std::string> number_to_string(double x) {
  if (!std::isfinite(x)) return std::nullopt;
  if (x == 0.0) return std::string("0");  // +0 and -0 (ECMA-262: -0 prints "0")
  std::string out;
  if (x < 0.0) {
    out.push_back('-');
    x = -x;
  }
  // The shortest digits that round-trip (ECMA-262 Number::toString step 5: the k and s
  // with the smallest k), from std::to_chars in scientific form: "d[.ddd]e[+-]XX".
  char buf[64];
  const std::to_chars_result r = std::to_chars(buf, buf + sizeof buf, x, std::chars_format::scientific);
  if (r.ec != std::errc{}) return std::nullopt;
  const std::string_view sci(buf, static_cast<std::size_t>(r.ptr - buf));
  const std::size_t e_pos = sci.find('e');
  std::string digits;
  for (const char c : sci.substr(0, e_pos)) {
    if (c != '.') digits.push_back(c);
  }
  const int exp10 = std::atoi(std::string(sci.substr(e_pos + 1)).c_str());
  // value = 0.digits * 10^n, i.e. digits * 10^(n - k)
  const int k = static_cast<int>(digits.size());
  const int n = exp10 + 1;
  if (k <= n && n <= 21) {
    out += digits;
    out.append(static_cast<std::size_t>(n - k), '0');
  } else if (0 < n && n <= 21) {
    out += digits.substr(0, static_cast<std::size_t>(n));
    out.push_back('.');
    out += digits.substr(static_cast<std::size_t>(n));
  } else if (-6 < n && n <= 0) {
    out += "0.";
    out.append(static_cast<std::size_t>(-n), '0');
    out += digits;
  } else {
    const int e = n - 1;
    out.push_back(digits[0]);
    if (k > 1) {
      out.push_back('.');
      out += digits.substr(1);
    }
    out.push_back('e');
    out.push_back(e < 0 ? '-' : '+');
    out += std::to_string(e < 0 ? -e : e);
  }
  return out;
}

namespace {

// UTF-8 (already validated by the parser) to UTF-16 code units.
std::vector<std::uint16_t> utf16(const std::string& s) {
  std::vector<std::uint16_t> out;
  out.reserve(s.size());
  std::size_t i = 0;
  while (i < s.size()) {
    const auto b0 = static_cast<unsigned char>(s[i]);
    std::uint32_t cp = 0;
    std::size_t len = 1;
    if (b0 < 0x80U) {
      cp = b0;
    } else if ((b0 & 0xE0U) == 0xC0U) {
      cp = b0 & 0x1FU;
      len = 2;
    } else if ((b0 & 0xF0U) == 0xE0U) {
      cp = b0 & 0x0FU;
      len = 3;
    } else {
      cp = b0 & 0x07U;
      len = 4;
    }
    for (std::size_t j = 1; j < len && i + j < s.size(); ++j) {
      cp = (cp << 6U) | (static_cast<unsigned char>(s[i + j]) & 0x3FU);
    }
    i += len;
    if (cp >= 0x10000U) {
      cp -= 0x10000U;
      out.push_back(static_cast<std::uint16_t>(0xD800U + (cp >> 10U)));
      out.push_back(static_cast<std::uint16_t>(0xDC00U + (cp & 0x3FFU)));
    } else {
      out.push_back(static_cast<std::uint16_t>(cp));
    }
  }
  return out;
}

void write_string(const std::string& s, std::string& out) {
  static constexpr char kHex[] = "0123456789abcdef";
  out.push_back('"');
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\b': out += "\\b"; break;
      case '\t': out += "\\t"; break;
      case '\n': out += "\\n"; break;
      case '\f': out += "\\f"; break;
      case '\r': out += "\\r"; break;
      default:
        if (u < 0x20U) {
          out += "\\u00";
          out.push_back(kHex[u >> 4U]);
          out.push_back(kHex[u & 0x0FU]);
        } else {
          out.push_back(c);  // everything else as is, non-ASCII as its UTF-8 bytes
        }
    }
  }
  out.push_back('"');
}

bool write(const nlohmann::json& v, std::string& out, std::size_t depth, std::size_t max_depth) {
  if (depth > max_depth) return false;
  switch (v.type()) {
    case nlohmann::json::value_t::null: out += "null"; return true;
    case nlohmann::json::value_t::boolean: out += v.get<bool>() ? "true" : "false"; return true;
    case nlohmann::json::value_t::number_integer:
    case nlohmann::json::value_t::number_unsigned:
    case nlohmann::json::value_t::number_float: {
      // Integers too are IEEE doubles in JCS: beyond 2^53 they round like JSON.parse.
      const double d = v.is_number_unsigned()  ? static_cast<double>(v.get<std::uint64_t>())
                       : v.is_number_integer() ? static_cast<double>(v.get<std::int64_t>())
                                               : v.get<double>();
      const std::optional<std::string> s = number_to_string(d);
      if (!s) return false;
      out += *s;
      return true;
    }
    case nlohmann::json::value_t::string: write_string(v.get_ref<const std::string&>(), out); return true;
    case nlohmann::json::value_t::array: {
      out.push_back('[');
      bool first = true;
      for (const auto& e : v) {
        if (!first) out.push_back(',');
        first = false;
        if (!write(e, out, depth + 1, max_depth)) return false;
      }
      out.push_back(']');
      return true;
    }
    case nlohmann::json::value_t::object: {
      std::vector<const std::string*> keys;
      keys.reserve(v.size());
      for (auto it = v.begin(); it != v.end(); ++it) keys.push_back(&it.key());
      std::sort(keys.begin(), keys.end(), [](const std::string* a, const std::string* b) { return utf16_less(*a, *b); });
      out.push_back('{');
      bool first = true;
      for (const std::string* k : keys) {
        if (!first) out.push_back(',');
        first = false;
        write_string(*k, out);
        out.push_back(':');
        if (!write(v.at(*k), out, depth + 1, max_depth)) return false;
      }
      out.push_back('}');
      return true;
    }
    case nlohmann::json::value_t::binary:
    case nlohmann::json::value_t::discarded:
      return false;
  }
  return false;
}

}  // namespace

bool utf16_less(const std::string& a, const std::string& b) {
  const std::vector<std::uint16_t> ua = utf16(a);
  const std::vector<std::uint16_t> ub = utf16(b);
  return std::lexicographical_compare(ua.begin(), ua.end(), ub.begin(), ub.end());
}

std::optional<std::string> canonicalize(const nlohmann::json& value, std::size_t max_depth) {
  std::string out;
  if (!write(value, out, 0, max_depth)) return std::nullopt;
  return out;
}

}  // namespace safestate::safety::jcs

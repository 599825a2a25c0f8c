// RFC 8785 JSON Canonicalization Scheme (JCS) over nlohmann::json's parsed tree.
// nlohmann's dump() is not JCS (its numbers and escapes differ); this writes it by hand:
// object keys sorted by UTF-16 code units, strings escaped per RFC 8785 §3.2.2.2, every
// number as ECMAScript's Number.prototype.toString of its IEEE-754 double.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace safestate::safety::jcs {

// ECMAScript Number.prototype.toString(x) (ECMA-262 Number::toString, radix 10) for a finite
// double; nullopt for NaN and infinities, which JSON cannot carry.
std::optional<std::string> number_to_string(double x);

// The canonical form of `value`, or nullopt when it holds a non-finite number (only
// possible for a tree not built by the parser) or a nesting deeper than max_depth.
std::optional<std::string> canonicalize(const nlohmann::json& value, std::size_t max_depth = 64);

// Keys of an object compared as RFC 8785 §3.2.3 requires: by their UTF-16 code units.
bool utf16_less(const std::string& a, const std::string& b);

}  // namespace safestate::safety::jcs

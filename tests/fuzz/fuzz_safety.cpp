// libFuzzer target: the safety configuration parser (SPEC §10) on arbitrary bytes. It must
// never crash; a refusal must carry at least one error with a message and no config; an
// accepted file must be complete (a checksum of 8 hex digits, at most 16 zones, every joint
// range non-empty) and must re-parse from its own canonical form to the same checksum.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

#include "safestate/safety/safety_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const safestate::safety::Result r = safestate::safety::parse_safety(text);
  if (!r.ok()) {
    if (r.errors.empty() || r.config.has_value()) __builtin_trap();
    for (const auto& e : r.errors) {
      if (e.message.empty()) __builtin_trap();
    }
    return 0;
  }
  const safestate::safety::Loaded& c = *r.config;
  if (c.checksum.size() != 8U || c.limits.zone_count > safestate::core::kMaxZones) __builtin_trap();
  for (const auto& j : c.limits.joints) {
    if (!(j.min_rad < j.max_rad) || !(j.max_speed_rad_s > 0.0F)) __builtin_trap();
  }
  const safestate::safety::Result again = safestate::safety::parse_safety(c.canonical);
  if (!again.ok() || again.config->checksum != c.checksum || again.config->canonical != c.canonical) {
    std::fprintf(stderr, "canonical form does not re-parse to itself\n");
    __builtin_trap();
  }
  return 0;
}

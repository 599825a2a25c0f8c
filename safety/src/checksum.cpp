// SHA-256 from OpenSSL's libcrypto (a maintained implementation; we write no hash).
#include <openssl/evp.h>

#include <cstdio>

#include "safestate/safety/safety_config.hpp"

namespace safestate::safety {

std::string sha256_hex(std::string_view bytes) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  if (EVP_Digest(bytes.data(), bytes.size(), md, &len, EVP_sha256(), nullptr) != 1 || len != 32U) return {};
  std::string out;
  char hex[3];
  for (unsigned int i = 0; i < len; ++i) {
    std::snprintf(hex, sizeof hex, "%02X", static_cast<unsigned>(md[i]));
    out += hex;
  }
  return out;
}

std::string checksum_text(std::string_view canonical) { return sha256_hex(canonical).substr(0, 8); }

std::uint32_t checksum_value(std::string_view canonical) {
  const std::string hex = checksum_text(canonical);
  std::uint32_t v = 0;
  for (const char c : hex) {
    v = (v << 4U) | static_cast<std::uint32_t>(c <= '9' ? c - '0' : c - 'A' + 10);
  }
  return v;
}

}  // namespace safestate::safety

// Admission and authentication (protocol.md "Access and admission"; IEC 62443-3-3 SR 1.1
// / SR 1.2 identification and authentication, SR 2.1 least privilege, SR 7.1 denial of
// service protection). Who may connect, with which credentials, as which role. No
// sockets here: the transport asks, this file decides, so that it can be tested alone.
#pragma once

#include <string>
#include <string_view>

#include "safestate/gateway/gateway.hpp"
#include "safestate/gateway/protocol.hpp"

namespace safestate::gateway {

// Equal, in a time that depends only on the length of `given` (what the client sent),
// never on the secret's content or length nor on how much of it matched. An empty
// secret matches nothing.
[[nodiscard]] bool same_token(std::string_view given, std::string_view secret) noexcept;

// The token of a role: from `file` when given (its content, trailing newline stripped),
// else from the environment variable `env` (may be unset: empty). False and `error`
// when the file cannot be read or is empty.
bool load_token(const char* env, const std::string& file, std::string& out, std::string& error);

// Whether `bind` (an address or a name) is a loopback address. False and `error` when
// it cannot be resolved.
bool bind_is_loopback(const std::string& bind, bool& loopback, std::string& error);

// Beyond loopback both tokens are required (protocol.md): "" when `o` may start, else why not.
std::string startup_refusal(const GatewayOptions& o, bool loopback_bind);

class Access {
 public:
  Access(const GatewayOptions& o, bool loopback_bind);

  // A `Host` header we answer to: the bound address, localhost, a name of
  // --allow-host, or (bound to a wildcard address) any IP literal. DNS rebinding always
  // comes with a foreign name. An absent header is refused too (HTTP/1.1 requires it).
  [[nodiscard]] bool host_ok(std::string_view host_header, bool present) const;
  // An `Origin` header we accept: absent (not a browser), the server's own
  // (http://<an accepted host>:<port>), or one listed with --allow-origin.
  [[nodiscard]] bool origin_ok(std::string_view origin, bool present) const;
  // /api/* and /metrics beyond loopback: `Authorization: Bearer <either token>`.
  [[nodiscard]] bool needs_bearer(std::string_view path) const;
  [[nodiscard]] bool bearer_ok(std::string_view authorization) const;
  // The hello's credentials for `role`; "" when accepted, else why not (BAD_TOKEN).
  [[nodiscard]] std::string hello_refusal(Role role, bool has_token, std::string_view token) const;
  [[nodiscard]] bool loopback_bind() const noexcept { return loopback_bind_; }

 private:
  [[nodiscard]] bool host_name_ok(std::string_view host) const;
  [[nodiscard]] bool either_token(std::string_view given) const;

  std::string bind_;
  unsigned port_;
  std::string pendant_token_;
  std::string remote_token_;
  std::vector<std::string> allow_origins_;
  std::vector<std::string> allow_hosts_;
  bool loopback_bind_;
  bool wildcard_bind_;
};

}  // namespace safestate::gateway

// Admission and authentication (protocol.md "Access and admission"; IEC 62443-3-3 SR 1.1
// / SR 1.2 identification and authentication, SR 2.1 least privilege, SR 7.1 denial of
// service protection). Who may connect, with which credentials, as which role. No
// sockets here: the transport asks, this file decides, so that it can be tested alone.
#pragma once

#include <chrono>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

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

// ------------------------------------------------------------------ connections (issue 40)
// Slow and idle clients: a connection that has not sent a complete request head yet holds
// a descriptor and nothing else the gateway needs. Such connections are bounded per peer
// address and overall, time out early, and the oldest silent one gives its place to a
// newcomer, so that whatever opens sockets and waits, the pendant and a fresh request
// are served (gateway/README.md "Admission").

// A new connection's first request head must be complete within this (else 408 and
// closed): a slowloris client, or one that connects and never sends a byte, goes early.
// A client on the plant's network sends its head in one segment, milliseconds after
// connecting.
inline constexpr std::chrono::seconds kFirstHeadLimit{3};
// After an answer, a connection kept alive has this long for its next request head.
inline constexpr std::chrono::seconds kKeepAliveLimit{10};
// HTTP connections waiting for a request head, from one peer address and from all. On
// loopback every client shares one address: the newest are kept (the oldest silent one
// gives way), so a pendant connecting among hundreds of squatters still gets in.
inline constexpr std::size_t kWaitingPerPeer = 512;
inline constexpr std::size_t kWaitingMax = 2048;
// Descriptors the gateway keeps for itself: the event log (two connections, WAL, shm),
// the segment, epoll, timers, a static file being read, stdio.
inline constexpr std::size_t kOwnDescriptors = 64;
// 503 answers in flight at once (each drains what its client sent, at most 1 s).
inline constexpr std::size_t kMaxRefusing = 64;
// Fewer waiting connections than this and the caps do not fit the descriptors.
inline constexpr std::size_t kMinWaiting = 16;

struct ConnectionLimits {
  std::size_t fd_limit = 0;          // RLIMIT_NOFILE (soft) as the gateway runs with it
  std::size_t open_max = 0;          // client connections at once, of every kind
  std::size_t waiting_max = 0;       // HTTP connections waiting for a request head, all peers
  std::size_t waiting_per_peer = 0;  // ... from one peer address
};

// The bounds for a descriptor limit: open_max leaves kOwnDescriptors to the gateway;
// waiting_max is what open_max leaves once every WebSocket slot (2 x max_clients: the
// lobby and those that said hello), every service slot (max_http) and the 503s in flight
// have theirs, at most kWaitingMax; waiting_per_peer at most waiting_max. False and
// `error` (naming the limit) when fewer than kMinWaiting remain.
bool connection_limits(std::size_t fd_limit, std::size_t max_clients, std::size_t max_http, ConnectionLimits& out,
                       std::string& error);

// A connection waiting for a request head, as the shedding rule sees it.
struct WaitingConnection {
  std::string peer;                             // its peer address (bytes; equal: the same peer)
  std::chrono::steady_clock::time_point since;  // waiting since (its accept, or its last answer)
  bool answered = false;                        // it has had an answer before (kept alive)
  bool silent = false;  // no complete head and nothing unread in its socket: not about to be served
};

// Who gives way when a bound is reached (index into `c`, or c.size() for nobody): among
// the silent ones (of `peer`, unless it is empty), the oldest that has never had an
// answer; else the oldest kept-alive one silent for at least `kept_grace`. A connection
// whose request is arriving (not silent) never gives way.
std::size_t pick_shed(const std::vector<WaitingConnection>& c, std::string_view peer,
                      std::chrono::steady_clock::time_point now, std::chrono::steady_clock::duration kept_grace);

}  // namespace safestate::gateway

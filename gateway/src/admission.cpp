// Decisions where protocol.md is silent:
//  - Tokens: a file given on the command line wins over the environment variable; an
//    unreadable or empty file stops the start (a typo must not leave the pendant open).
//  - Host: IP literals are accepted when bound to a wildcard address (0.0.0.0, ::):
//    a DNS-rebinding page always reaches us under its own name, never an IP literal.
//    Bound to loopback, 127.0.0.1, ::1 and localhost are the bound address's names.
//  - Origin: the server's own origin is http://<accepted host>:<port>; "null" (a
//    sandboxed or file: page) is foreign.
//  - Observers: bound beyond loopback an observer needs either token too (the same
//    rule as /api/*: status and history are not for anyone on the network).
//  - Connections (issue 40): see admission.hpp "connections"; the rule of who gives way
//    is pick_shed, the bounds connection_limits, both without sockets (test_admission).
#include "safestate/gateway/admission.hpp"

#include <netdb.h>
#include <sys/socket.h>

#include <algorithm>
#include <boost/asio/ip/address.hpp>
#include <cctype>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace safestate::gateway {

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

// "host", "host:port", "[v6]", "[v6]:port" -> host (without brackets) and port text.
void split_host_port(std::string_view hp, std::string& host, std::string& port) {
  if (!hp.empty() && hp.front() == '[') {
    const std::size_t close = hp.find(']');
    host = lower(hp.substr(1, close == std::string_view::npos ? std::string_view::npos : close - 1));
    const std::size_t colon = (close == std::string_view::npos) ? std::string_view::npos : hp.find(':', close);
    port = (colon == std::string_view::npos) ? std::string{} : std::string(hp.substr(colon + 1));
    return;
  }
  const std::size_t colon = hp.find(':');
  if (colon != std::string_view::npos && hp.find(':', colon + 1) != std::string_view::npos) {
    host = lower(hp);  // a bare IPv6 literal (not valid in Host, but not ours to guess)
    port.clear();
    return;
  }
  host = lower(hp.substr(0, colon));
  port = (colon == std::string_view::npos) ? std::string{} : std::string(hp.substr(colon + 1));
}

bool ip_literal(const std::string& host, boost::asio::ip::address& out) {
  boost::system::error_code ec;
  out = boost::asio::ip::make_address(host, ec);
  return !ec;
}

std::string trim_origin(std::string_view o) {
  std::string s = lower(o);
  while (!s.empty() && (s.back() == '/' || s.back() == ' ')) {
    s.pop_back();
  }
  return s;
}

}  // namespace

bool same_token(std::string_view given, std::string_view secret) noexcept {
  const std::size_t n = secret.size();
  // The loop runs over what the client sent: its time says nothing about the secret.
  unsigned diff = (given.size() != n) ? 1U : 0U;
  diff |= (n == 0U) ? 1U : 0U;
  const std::size_t m = (n == 0U) ? 1U : n;
  const char* s = (n == 0U) ? "" : secret.data();
  for (std::size_t i = 0; i < given.size(); ++i) {
    const std::size_t j = i % m;
    const unsigned char sc = (n == 0U) ? 0U : static_cast<unsigned char>(s[j]);
    diff |= static_cast<unsigned>(static_cast<unsigned char>(given[i]) ^ sc);
  }
  return diff == 0U;
}

bool load_token(const char* env, const std::string& file, std::string& out, std::string& error) {
  out.clear();
  if (file.empty()) {
    const char* v = std::getenv(env);
    out = (v != nullptr) ? std::string(v) : std::string{};
    return true;
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    error = "cannot read token file " + file;
    return false;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  out = ss.str();
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) {
    out.pop_back();
  }
  if (out.empty()) {
    error = "token file " + file + " is empty";
    return false;
  }
  return true;
}

bool bind_is_loopback(const std::string& bind, bool& loopback, std::string& error) {
  boost::asio::ip::address a;
  if (ip_literal(bind, a)) {
    if (a.is_v6() && a.to_v6().is_v4_mapped()) {
      a = boost::asio::ip::make_address_v4(boost::asio::ip::v4_mapped, a.to_v6());
    }
    loopback = a.is_loopback();
    return true;
  }
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* res = nullptr;
  const int rc = getaddrinfo(bind.c_str(), nullptr, &hints, &res);
  if (rc != 0 || res == nullptr) {
    error = "cannot resolve bind address " + bind + ": " + gai_strerror(rc);
    return false;
  }
  char text[NI_MAXHOST];
  loopback = getnameinfo(res->ai_addr, res->ai_addrlen, text, sizeof text, nullptr, 0, NI_NUMERICHOST) == 0 &&
             ip_literal(text, a) && a.is_loopback();
  freeaddrinfo(res);
  return true;
}

std::string startup_refusal(const GatewayOptions& o, bool loopback_bind) {
  if (loopback_bind || (!o.pendant_token.empty() && !o.remote_token.empty())) {
    return {};
  }
  return "refusing to listen on " + o.bind +
         " (beyond loopback) without both tokens: set SAFESTATE_PENDANT_TOKEN and SAFESTATE_REMOTE_TOKEN, or give "
         "--pendant-token-file and --remote-token-file";
}

Access::Access(const GatewayOptions& o, bool loopback_bind)
    : bind_(lower(o.bind)),
      port_(o.port),
      pendant_token_(o.pendant_token),
      remote_token_(o.remote_token),
      loopback_bind_(loopback_bind) {
  for (const auto& x : o.allow_origins) {
    allow_origins_.push_back(trim_origin(x));
  }
  for (const auto& x : o.allow_hosts) {
    allow_hosts_.push_back(lower(x));
  }
  boost::asio::ip::address a;
  wildcard_bind_ = ip_literal(bind_, a) && a.is_unspecified();
}

bool Access::host_name_ok(std::string_view host_sv) const {
  const std::string host(host_sv);
  if (host.empty()) {
    return false;
  }
  if (host == bind_ || host == "localhost" || std::find(allow_hosts_.begin(), allow_hosts_.end(), host) != allow_hosts_.end()) {
    return true;
  }
  boost::asio::ip::address a;
  if (!ip_literal(host, a)) {
    return false;  // a foreign name: DNS rebinding (protocol.md: 421)
  }
  return wildcard_bind_ || (loopback_bind_ && a.is_loopback());
}

bool Access::host_ok(std::string_view host_header, bool present) const {
  if (!present) {
    return false;
  }
  std::string host;
  std::string port;
  split_host_port(host_header, host, port);
  return host_name_ok(host);
}

bool Access::origin_ok(std::string_view origin, bool present) const {
  if (!present) {
    return true;  // not a browser: the Host check and the tokens still apply
  }
  const std::string o = trim_origin(origin);
  if (std::find(allow_origins_.begin(), allow_origins_.end(), o) != allow_origins_.end()) {
    return true;
  }
  constexpr std::string_view kScheme = "http://";
  if (o.rfind(kScheme, 0) != 0) {
    return false;
  }
  std::string host;
  std::string port;
  split_host_port(std::string_view(o).substr(kScheme.size()), host, port);
  const std::string own_port = std::to_string(port_);
  return host_name_ok(host) && (port == own_port || (port.empty() && port_ == 80U));
}

bool Access::needs_bearer(std::string_view path) const {
  return !loopback_bind_ && (path == "/metrics" || path == "/api" || path.rfind("/api/", 0) == 0);
}

bool Access::either_token(std::string_view given) const {
  // Both comparisons always run: which token matched takes no different time.
  const bool p = same_token(given, pendant_token_);
  const bool r = same_token(given, remote_token_);
  return p || r;
}

bool Access::bearer_ok(std::string_view authorization) const {
  constexpr std::string_view kBearer = "Bearer ";
  if (authorization.size() < kBearer.size() || lower(authorization.substr(0, kBearer.size())) != "bearer ") {
    return false;
  }
  return either_token(authorization.substr(kBearer.size()));
}

std::string Access::hello_refusal(Role role, bool has_token, std::string_view token) const {
  const std::string_view given = has_token ? token : std::string_view{};
  switch (role) {
    case Role::pendant:
      if (!pendant_token_.empty() && !same_token(given, pendant_token_)) {
        return "a pendant needs the pendant token";
      }
      return {};
    case Role::remote:
      if (!remote_token_.empty() && !same_token(given, remote_token_)) {
        return "a remote needs the remote token";
      }
      return {};
    case Role::observer:
      if (!loopback_bind_ && !either_token(given)) {
        return "beyond loopback an observer needs a token";
      }
      return {};
  }
  return "unknown role";
}

bool connection_limits(std::size_t fd_limit, std::size_t max_clients, std::size_t max_http, ConnectionLimits& out,
                       std::string& error) {
  out = ConnectionLimits{};
  out.fd_limit = fd_limit;
  const std::size_t others = 2U * max_clients + max_http + kMaxRefusing;
  if (fd_limit < kOwnDescriptors + others + kMinWaiting) {
    error = "RLIMIT_NOFILE " + std::to_string(fd_limit) + " leaves fewer than " + std::to_string(kMinWaiting) +
            " connections waiting for a request once the gateway's own " + std::to_string(kOwnDescriptors) +
            " descriptors, 2 x --max-clients, --max-http and " + std::to_string(kMaxRefusing) +
            " refusals are counted: raise it (ulimit -n, LimitNOFILE=) or lower the caps";
    return false;
  }
  out.waiting_max = std::min(kWaitingMax, fd_limit - kOwnDescriptors - others);
  out.open_max = out.waiting_max + others;
  out.waiting_per_peer = std::min(kWaitingPerPeer, out.waiting_max);
  return true;
}

std::size_t pick_shed(const std::vector<WaitingConnection>& c, std::string_view peer,
                      std::chrono::steady_clock::time_point now, std::chrono::steady_clock::duration kept_grace) {
  std::size_t never = c.size();
  std::size_t kept = c.size();
  for (std::size_t i = 0; i < c.size(); ++i) {
    const WaitingConnection& w = c[i];
    if (!w.silent || (!peer.empty() && w.peer != peer)) {
      continue;
    }
    if (!w.answered) {
      if (never == c.size() || w.since < c[never].since) {
        never = i;
      }
    } else if (now - w.since >= kept_grace && (kept == c.size() || w.since < c[kept].since)) {
      kept = i;
    }
  }
  return (never != c.size()) ? never : kept;
}

}  // namespace safestate::gateway

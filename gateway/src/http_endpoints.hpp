// HTTP endpoints: one connection each until it upgrades to a WebSocket, and the cap on
// how many there are at once. Private to gateway/src; one io_context thread.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "safestate/gateway/admission.hpp"
#include "sessions.hpp"

namespace safestate::gateway {

inline constexpr std::size_t kHeadLimit = 8U * 1024U;  // 431 beyond (protocol.md)
inline constexpr std::size_t kUrlLimit = 2U * 1024U;   // 414 beyond (protocol.md)
// An upgrade that finds the lobby full waits for a slot this long at most (then 503),
// looking again every kLobbyPoll.
inline constexpr std::chrono::seconds kLobbyWait{2};
inline constexpr std::chrono::milliseconds kLobbyPoll{10};

class HttpSession;

// At most max_http connections; when full, the oldest one that has waited kSilentLimit
// for a complete request head with nothing unread in its socket gives its slot to the
// newcomer (it is answered 503 + Retry-After), so that idle connections never keep a
// pendant's upgrade out, and a connection whose request is already in its socket buffer
// (a burst) is never evicted. gateway.cpp's listener makes a newcomer wait (unaccepted,
// in the kernel's backlog) while no slot is free, and answers 503 once one has waited
// kSilentLimit without a slot.
using HttpSessions = Registry<HttpSession>;

// Answers 503 with Retry-After on a connection that gets no session (the HTTP cap), then
// closes it once the peer has read it (its request, if any, is read and thrown away
// first, at most kSilentLimit, so that the close is not a reset that loses the answer).
// `count`, if given, is incremented while the answer is in flight.
void refuse_busy(tcp::socket socket, std::shared_ptr<std::size_t> count);

struct Endpoints {
  Hub& hub;
  Sessions& ws;
  const Access& access;
  std::string server;  // "safestate <version>"
};

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket&& socket, Endpoints& ep)
      : stream_(std::move(socket)), ep_(ep), since_(Clock::now()), wait_(stream_.get_executor()) {}

  void run() { do_read(); }
  // Gives its slot away (HttpSessions::admit): answered 503 + Retry-After.
  void evict();
  [[nodiscard]] bool live() const noexcept { return !done_; }
  [[nodiscard]] bool occupies() const noexcept { return !done_; }
  [[nodiscard]] bool evictable(Clock::time_point now) const;
  [[nodiscard]] Clock::time_point since() const noexcept { return since_; }

 private:
  void do_read();
  void on_read(beast::error_code ec, std::size_t bytes);
  void on_too_big(beast::error_code ec);
  void dispatch();
  void try_upgrade();
  void answer(HttpAnswer a, bool close = false);
  void on_write(bool close, beast::error_code ec, std::size_t bytes);
  void finish();

  beast::tcp_stream stream_;
  Endpoints& ep_;
  Clock::time_point since_;
  asio::steady_timer wait_;  // an upgrade waiting for a slot in the lobby
  Clock::time_point upgrade_since_{};
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<http::response<http::string_body>> res_;
  bool reading_ = false;
  bool evicted_ = false;
  bool done_ = false;
};

}  // namespace safestate::gateway

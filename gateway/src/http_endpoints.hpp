// HTTP endpoints: one connection each until it upgrades to a WebSocket, the bounds on
// how many wait for a request and how many are in service. Private to gateway/src; one
// io_context thread.
#pragma once

#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
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
// A complete request waits this long at most for a service slot (then 503).
inline constexpr std::chrono::seconds kServiceWait{1};

class HttpSession;
struct Endpoints;

// The HTTP connections (issue 40): every accepted connection is an HttpSession at once,
// so that the kernel's backlog never holds a fresh request behind a crowd of slow or
// silent ones. Two kinds of bound:
//  - waiting for a request head (a new connection, or one kept alive after an answer):
//    at most limits.waiting_per_peer from one peer address and limits.waiting_max from
//    all; a newcomer beyond either takes the place of the oldest silent one (admission.hpp
//    pick_shed: answered 503 + Retry-After and closed at once), and when nobody is
//    silent, the newcomer itself is answered 503. Deadlines: the first head within
//    kFirstHeadLimit, a kept-alive connection's next one within kKeepAliveLimit (408).
//  - in service (a complete request being answered or upgraded): at most max_http;
//    beyond, a request waits in order of arrival, at most kServiceWait (then 503).
// Every client connection (HTTP, WebSocket, 503 in flight) holds a Seat: the listener
// accepts while fewer than limits.open_max are held, else after the oldest silent
// waiting one has given way, else it waits (the kernel's backlog holds the newcomers).
class HttpConnections {
 public:
  HttpConnections(std::size_t max_service, const ConnectionLimits& limits);

  // Room for one more connection: true when fewer than open_max are held or the oldest
  // silent waiting one gave way for it.
  [[nodiscard]] bool make_room();
  // Out of descriptors (accept failed): the oldest silent waiting one gives way. False
  // when nobody may.
  bool shed_one();
  // A newly accepted connection: its session starts, within the waiting bounds (see above).
  void admit(tcp::socket socket, Endpoints& ep);
  void count_accept_paused() noexcept { ++accept_paused_; }

  // Service slots, called by the sessions.
  [[nodiscard]] bool take_service();
  void queue_for_service(const std::shared_ptr<HttpSession>& s);
  // A slot is free: the oldest queued request gets it (posted on `ex`).
  void release_service(const asio::any_io_executor& ex);
  // The same from a session's destructor: nothing may be posted any more.
  void release_service_quietly() noexcept;
  void count_head_timeout() noexcept { ++head_timeouts_; }
  void count_refused() noexcept { ++refused_; }

  [[nodiscard]] ConnectionFigures figures() const;
  [[nodiscard]] const ConnectionLimits& limits() const noexcept { return limits_; }

 private:
  void prune();
  // Who gives way (pick_shed) among the waiting sessions, of `peer` unless empty.
  bool shed(std::string_view peer, const HttpSession* spare);
  void serve_next();

  std::size_t max_service_;
  ConnectionLimits limits_;
  std::shared_ptr<std::size_t> open_ = std::make_shared<std::size_t>(0);
  std::shared_ptr<std::size_t> refusing_ = std::make_shared<std::size_t>(0);
  std::vector<std::weak_ptr<HttpSession>> list_;
  std::deque<std::weak_ptr<HttpSession>> queue_;
  std::size_t in_service_ = 0;
  bool serve_posted_ = false;
  std::uint64_t shed_ = 0;
  std::uint64_t head_timeouts_ = 0;
  std::uint64_t refused_ = 0;
  std::uint64_t accept_paused_ = 0;
};

// Answers 503 with Retry-After on a connection that gets no session, then closes it once
// the peer has read it (its request, if any, is read and thrown away first, at most
// kSilentLimit, so that the close is not a reset that loses the answer). `count`, if
// given, is incremented while the answer is in flight.
void refuse_busy(tcp::socket socket, Seat seat, std::shared_ptr<std::size_t> count);

struct Endpoints {
  Hub& hub;
  Sessions& ws;
  HttpConnections& http;
  const Access& access;
  std::string server;  // "safestate <version>"
};

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket&& socket, Endpoints& ep, Seat seat, std::string peer);
  HttpSession(const HttpSession&) = delete;
  HttpSession& operator=(const HttpSession&) = delete;
  ~HttpSession();

  void run() { do_read(kFirstHeadLimit); }
  [[nodiscard]] bool live() const noexcept { return !done_; }
  // Waiting for a request head (not in service, not queued for it).
  [[nodiscard]] bool waiting() const noexcept { return reading_ && !done_; }
  // As the shedding rule sees it (waiting() only), but for its socket: has_unread().
  [[nodiscard]] WaitingConnection view() const;
  [[nodiscard]] bool has_unread() const;
  [[nodiscard]] const std::string& peer() const noexcept { return peer_; }
  // Gives its place away for a newcomer: 503 + Retry-After at once, closed.
  void shed();
  // Queued for a service slot and given one (HttpConnections::serve_next).
  [[nodiscard]] bool queued() const noexcept { return queued_ && !done_; }
  void serve();

 private:
  void do_read(Clock::duration limit);
  void on_read(beast::error_code ec, std::size_t bytes);
  void on_too_big(beast::error_code ec);
  void request_complete();
  void dispatch();
  void try_upgrade();
  void answer(HttpAnswer a, bool close = false);
  void on_write(bool close, beast::error_code ec, std::size_t bytes);
  void leave_service();
  // A canned answer (none when empty) written at once (it fits an empty socket buffer),
  // then closed: the descriptor is free before this returns.
  void say_and_close(const std::string& raw);
  void finish();

  beast::tcp_stream stream_;
  Endpoints& ep_;
  Seat seat_;
  std::string peer_;
  Clock::time_point since_;  // waiting for a request head since
  asio::steady_timer deadline_;  // the request head's deadline, then the wait for a service slot
  asio::steady_timer wait_;      // an upgrade waiting for a slot in the lobby
  Clock::time_point upgrade_since_{};
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<http::response<http::string_body>> res_;
  std::uint64_t gen_ = 0;  // a timer's wait is for this read or service wait only
  bool reading_ = false;
  bool answered_ = false;  // a request of this connection has been answered (kept alive)
  bool in_service_ = false;
  bool queued_ = false;
  bool done_ = false;
};

}  // namespace safestate::gateway

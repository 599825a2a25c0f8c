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

class HttpSession;

// At most max_http connections; when full, the oldest one still waiting for (or
// reading) a request gives its slot to the newcomer, so that idle connections never
// keep a pendant's upgrade out.
using HttpSessions = Registry<HttpSession>;

struct Endpoints {
  Hub& hub;
  Sessions& ws;
  const Access& access;
  std::string server;  // "safestate <version>"
};

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket&& socket, Endpoints& ep) : stream_(std::move(socket)), ep_(ep), since_(Clock::now()) {}

  void run() { do_read(); }
  void evict();
  [[nodiscard]] bool live() const noexcept { return !done_; }
  [[nodiscard]] bool evictable() const noexcept { return reading_; }  // HttpSessions::admit
  [[nodiscard]] Clock::time_point since() const noexcept { return since_; }

 private:
  void do_read();
  void on_read(beast::error_code ec, std::size_t bytes);
  void on_too_big(beast::error_code ec);
  void dispatch();
  void answer(HttpAnswer a, bool close = false);
  void on_write(bool close, beast::error_code ec, std::size_t bytes);
  void finish();

  beast::tcp_stream stream_;
  Endpoints& ep_;
  Clock::time_point since_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<http::response<http::string_body>> res_;
  bool reading_ = false;
  bool done_ = false;
};

}  // namespace safestate::gateway

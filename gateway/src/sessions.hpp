// Sessions and fan-out: one WebSocket connection each, its outgoing queue, and the
// registry that admits new connections (protocol.md "Access and admission").
// Private to gateway/src; every call comes from the one io_context thread.
#pragma once

#include <utility>

#include <boost/asio.hpp>
#include <boost/beast.hpp>

#include <deque>
#include <memory>
#include <vector>

#include "safestate/gateway/hub.hpp"

namespace safestate::gateway {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;

// A client that said nothing useful is closed after this (protocol.md).
inline constexpr std::chrono::seconds kHelloDeadline{5};
// A client whose write has made no progress for this long does not read: disconnected.
inline constexpr std::chrono::seconds kStallLimit{5};
// Safety net on memory for a client that reads, but slower than it is sent to.
inline constexpr std::size_t kMaxQueuedBytes = 32U * 1024U * 1024U;
// An oversize frame is read and thrown away up to this size, then the connection closes.
inline constexpr std::size_t kDiscardLimit = 1024U * 1024U;

bool is_loopback(asio::ip::address a);

class WsSession;

// The WebSocket connections that live, and who gets a slot. At most max_clients; when
// full, the oldest connection that has not said hello gives its slot to the newcomer
// (it may still be a pendant about to say hello). The hub keeps one of the slots for
// the pendant: at most max_clients - 1 clients may say hello as anything else, so the
// pendant always finds a slot.
class Sessions {
 public:
  explicit Sessions(std::size_t max_clients) : max_(max_clients) {}
  [[nodiscard]] bool admit();
  void add(const std::shared_ptr<WsSession>& s);
  void shutdown();

 private:
  void prune();
  std::size_t max_;
  std::vector<std::weak_ptr<WsSession>> list_;
};

class WsSession : public Client, public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket&& socket, Hub& hub);
  ~WsSession() override;

  void run(http::request<http::string_body> req);
  void send(const Frame& frame, bool droppable) override;
  void close_after_flush() override;
  [[nodiscard]] bool loopback_peer() const override { return loopback_; }

  void shutdown() { close_when_flushed(websocket::close_code::going_away); }
  // Gives its slot away (Sessions::admit): it had not said hello.
  void evict();
  [[nodiscard]] bool live() const noexcept { return !aborted_; }
  [[nodiscard]] Clock::time_point since() const noexcept { return since_; }

 private:
  void on_accept(beast::error_code ec);
  void on_hello_deadline(beast::error_code ec);
  void do_read();
  void on_read(beast::error_code ec, std::size_t bytes);
  void message_done();
  void do_write();
  void on_write(beast::error_code ec, std::size_t bytes);
  void close_when_flushed(websocket::close_code code);
  void do_close(websocket::close_code code);
  void abort();
  void leave();

  websocket::stream<beast::tcp_stream> ws_;
  Hub& hub_;
  http::request<http::string_body> req_;
  beast::flat_buffer buffer_;
  asio::steady_timer timer_;  // hello deadline, then read throttling
  std::deque<Frame> queue_;   // replies, events, errors: every one is delivered
  Frame status_;              // the newest unsent status (protocol.md: replaces an older one)
  Frame current_;             // the frame being written
  std::size_t queued_bytes_ = 0;
  std::size_t message_bytes_ = 0;  // of the frame being read
  Clock::time_point since_;
  Clock::time_point write_since_;
  bool loopback_ = false;
  bool open_ = false;
  bool attached_ = false;
  bool writing_ = false;
  bool closing_ = false;
  bool close_pending_ = false;
  bool aborted_ = false;
  bool oversize_ = false;
  websocket::close_code close_code_ = websocket::close_code::normal;
};

}  // namespace safestate::gateway

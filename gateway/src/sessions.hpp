// Sessions and fan-out: one WebSocket connection each, its outgoing queue, and the
// registry that admits new connections (protocol.md "Access and admission").
// Private to gateway/src; every call comes from the one io_context thread.
#pragma once

#include <utility>

#include <boost/asio.hpp>
#include <boost/beast.hpp>

#include <array>
#include <deque>
#include <string>
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

// One client connection held (its descriptor), counted in a shared count as long as it
// lives: the listener's bound on connections of every kind (admission.hpp
// connection_limits). Moves with the socket: HTTP session, WebSocket session, 503.
class Seat {
 public:
  Seat() = default;
  explicit Seat(std::shared_ptr<std::size_t> count) : count_(std::move(count)) {
    if (count_) {
      ++*count_;
    }
  }
  Seat(const Seat&) = delete;
  Seat& operator=(const Seat&) = delete;
  Seat(Seat&& o) noexcept : count_(std::move(o.count_)) {}
  Seat& operator=(Seat&& o) noexcept {
    if (this != &o) {
      release();
      count_ = std::move(o.count_);
    }
    return *this;
  }
  ~Seat() { release(); }
  // The descriptor is closed: no longer counted.
  void release() noexcept {
    if (count_) {
      --*count_;
      count_.reset();
    }
  }

 private:
  std::shared_ptr<std::size_t> count_;
};

class WsSession;

// A connection that has been admitted may give its slot to a newcomer only when it has
// been silent this long: a WebSocket this long after its upgrade without a hello, an HTTP
// connection kept alive this long after its last answer without a new request. In a
// burst, a connection whose request or hello is already on its way is never evicted for a
// newcomer. (A connection that has never sent a complete request gives way at a bound
// whatever its age: admission.hpp pick_shed; gateway/README.md "Admission".)
inline constexpr std::chrono::seconds kSilentLimit{1};
// What a refused newcomer is told to wait before it tries again (HTTP Retry-After).
inline constexpr int kRetryAfterSeconds = 1;

// The connections of one kind that live, and who gets a slot: at most `max` that
// S::occupies(); when full, the oldest one whose S::evictable() says it has been silent
// for kSilentLimit gives its slot away (evict(): told so in words, never a silent
// close), and when none may, the newcomer is refused. S has live(), occupies(), since(),
// evictable(now) and evict().
template <typename S>
class Registry {
 public:
  explicit Registry(std::size_t max) : max_(max) {}
  [[nodiscard]] bool admit() {
    prune();
    std::size_t occupied = 0;
    for (const auto& w : list_) {
      const auto s = w.lock();
      occupied += (s && s->occupies()) ? 1U : 0U;
    }
    if (occupied < max_) {
      return true;
    }
    const auto now = Clock::now();
    std::shared_ptr<S> oldest;
    for (const auto& w : list_) {
      const auto s = w.lock();
      if (s && s->occupies() && s->evictable(now) && (!oldest || s->since() < oldest->since())) {
        oldest = s;
      }
    }
    if (!oldest) {
      return false;
    }
    oldest->evict();
    prune();
    return true;
  }
  void add(const std::shared_ptr<S>& s) { list_.push_back(s); }

 protected:
  std::vector<std::weak_ptr<S>> list_;

 private:
  void prune() {
    std::erase_if(list_, [](const std::weak_ptr<S>& w) {
      const auto s = w.lock();
      return !s || !s->live();
    });
  }
  std::size_t max_;
};

// The WebSocket connections that have not said hello yet (the lobby): at most
// max_clients; when full, the oldest one silent for kSilentLimit since its upgrade is
// closed with 1013 for the newcomer, else the newcomer's upgrade waits for that
// (HttpSession::try_upgrade, at most kLobbyWait, then 503). Those that
// said hello are counted by the hub: at most max_clients - 1 as anything but the
// pendant (one more is closed with 1013), so a pendant always finds a slot.
class Sessions : public Registry<WsSession> {
 public:
  using Registry::Registry;
  void shutdown();
};

// One WebSocket connection. Beast performs the opening handshake; after it the session
// frames RFC 6455 itself on the TCP socket: every complete message already received is
// handled in one go (a pipelining client is not read one message per turn of the event
// loop, behind every other client's writes), and queued frames go out in one gathered
// write (one system call for many frames: protocol.md "Fairness", batched writes).
class WsSession : public Client, public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket&& socket, Hub& hub, Seat seat);
  ~WsSession() override;

  void run(http::request<http::string_body> req);
  void send(const Frame& frame, Delivery delivery) override;
  void close_after_flush() override;
  void close_try_again_later() override;
  [[nodiscard]] bool loopback_peer() const override { return loopback_; }

  void shutdown();
  // Gives its slot away (Sessions::admit): close 1013, it had not said hello.
  void evict();
  [[nodiscard]] bool live() const noexcept { return !aborted_; }
  // In the lobby: upgraded, no hello yet, not closing.
  [[nodiscard]] bool occupies() const noexcept { return !aborted_ && !hello && !closing_; }
  [[nodiscard]] Clock::time_point since() const noexcept { return since_; }
  [[nodiscard]] bool evictable(Clock::time_point now) const noexcept { return now - since_ >= kSilentLimit; }

 private:
  // Incoming frame parser state (RFC 6455 section 5.2).
  struct Incoming {
    bool in_frame = false;       // header parsed, payload being consumed
    std::uint8_t opcode = 0;     // of the current frame
    bool fin = false;
    std::array<std::uint8_t, 4> mask{};
    std::uint64_t remaining = 0;  // payload bytes of the current frame still to come
    std::uint64_t offset = 0;     // payload bytes of the current frame consumed (mask index)
    std::uint8_t message_opcode = 0;  // 1 text, 2 binary; 0 = no message in progress
    std::size_t message_bytes = 0;
    bool oversize = false;
    std::string message;  // at most kMaxFrameBytes
    std::string control;  // a control frame's payload (<= 125)
  };

  void on_accept(beast::error_code ec);
  void arm_tick();
  void on_tick(beast::error_code ec);
  void do_read();
  void on_read(beast::error_code ec, std::size_t bytes);
  // Consumes what is in rbuf_; false when the connection must end (protocol error).
  bool parse();
  int parse_header(std::size_t& pos);
  void frame_done();
  void message_done();
  void queue_control(std::uint8_t opcode, std::string payload);
  void schedule_write();
  void do_write();
  void on_write(beast::error_code ec, std::size_t bytes);
  void close_with(std::uint16_t code);
  void abort();
  void leave();

  websocket::stream<beast::tcp_stream> ws_;  // the handshake only
  Hub& hub_;
  Seat seat_;
  http::request<http::string_body> req_;
  asio::steady_timer tick_;   // every second: hello deadline, keep-alive, stalled writes
  asio::steady_timer hold_;   // rate limit: reading resumes at hold_reads_until
  std::array<std::uint8_t, 16384> rbuf_{};
  std::size_t rlen_ = 0;
  Incoming in_;
  std::deque<Frame> queue_;    // replies, events, errors: every one is delivered
  std::deque<Frame> control_;  // pong / close frames (already framed)
  Frame status_;               // the newest unsent status (protocol.md: replaces an older one)
  Frame close_frame_;          // written once the queue is empty
  std::vector<Frame> batch_;   // the frames being written
  std::vector<std::array<std::uint8_t, 10>> heads_;  // their headers
  std::vector<asio::const_buffer> buffers_;
  std::size_t queued_bytes_ = 0;
  Clock::time_point since_;
  Clock::time_point last_read_;
  Clock::time_point write_since_;
  bool loopback_ = false;
  bool open_ = false;
  bool attached_ = false;
  bool reading_ = false;
  bool writing_ = false;
  bool write_posted_ = false;
  bool closing_ = false;    // a close frame is queued or sent: nothing more is queued
  bool close_sent_ = false;
  bool ping_sent_ = false;
  bool aborted_ = false;
};

}  // namespace safestate::gateway

// The gateway process: Boost.Beast HTTP + WebSocket on one io_context thread, in front
// of the Hub (hub.cpp), which holds all of the protocol's logic.
//
// Transport decisions (protocol.md is silent):
//  - WebSocket frames are read up to 64 KiB; a frame over 4 KiB gets error TOO_LARGE
//    and the connection stays open. Beyond 64 KiB Beast closes the connection with
//    1009 (message too big): no error frame for a client that sends that much.
//  - Each client has an outgoing queue. Status frames are skipped for a client with 8
//    or more frames queued; a client with 1024 queued (it does not read) is
//    disconnected. Nothing a client does can block the poll loop or the others.
//  - At most 64 WebSocket clients (a 65th upgrade gets 503). HTTP requests: GET only
//    (405 otherwise), headers and body up to 8 KiB, 30 s to send a request.
//  - WebSocket keep-alive: a ping after 15 s of silence, closed after 30 s without an
//    answer, so a pendant whose network vanished frees the pendant role.
#include "safestate/gateway/gateway.hpp"

#include "safestate/gateway/hub.hpp"

#include <signal.h>
#include <unistd.h>

#include <boost/asio.hpp>
#include <boost/beast.hpp>

#include <csignal>
#include <cstdio>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

namespace safestate::gateway {

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using namespace std::chrono_literals;

constexpr std::size_t kReadLimit = 64 * 1024;
constexpr std::size_t kStatusSkipQueued = 8;
constexpr std::size_t kMaxQueued = 1024;
constexpr std::size_t kMaxClients = 64;
constexpr std::size_t kHttpLimit = 8 * 1024;
constexpr auto kPollPeriod = 2ms;
constexpr auto kStatusPeriod = 20ms;
constexpr auto kLivenessPeriod = 250ms;
constexpr auto kAttachTimeout = 5s;

void say(const std::string& s) { std::fprintf(stderr, "safestate gateway: %s\n", s.c_str()); }

// SIGTERM/SIGINT before the io_context's signal_set is in place (while attaching).
volatile std::sig_atomic_t g_early_stop = 0;
extern "C" void on_early_signal(int /*sig*/) { g_early_stop = 1; }

bool is_loopback(asio::ip::address a) {
  if (a.is_v6() && a.to_v6().is_v4_mapped()) {
    a = asio::ip::make_address_v4(asio::ip::v4_mapped, a.to_v6());
  }
  return a.is_loopback();
}

// ------------------------------------------------------------------ WebSocket
class WsSession : public Client, public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket&& socket, Hub& hub) : ws_(std::move(socket)), hub_(hub) {
    beast::error_code ec;
    const auto ep = beast::get_lowest_layer(ws_).socket().remote_endpoint(ec);
    loopback_ = !ec && is_loopback(ep.address());
  }
  ~WsSession() override { leave(); }

  void run(http::request<http::string_body> req) {
    req_ = std::move(req);
    beast::get_lowest_layer(ws_).expires_never();
    websocket::stream_base::timeout t{};
    t.handshake_timeout = 10s;
    t.idle_timeout = 30s;
    t.keep_alive_pings = true;
    ws_.set_option(t);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "safestate"); }));
    ws_.read_message_max(kReadLimit);
    ws_.text(true);
    ws_.async_accept(req_, beast::bind_front_handler(&WsSession::on_accept, shared_from_this()));
  }

  void send(const Frame& frame, bool droppable) override {
    if (!open_ || closing_) {
      return;
    }
    if (droppable && queue_.size() >= kStatusSkipQueued) {
      return;  // a slow client misses status frames, never replies or events
    }
    if (queue_.size() >= kMaxQueued) {
      say("a WebSocket client does not read its messages: disconnected");
      abort();
      return;
    }
    queue_.push_back(frame);
    if (!writing_) {
      do_write();
    }
  }

  void close_after_flush() override { close_when_flushed(websocket::close_code::policy_error); }

  [[nodiscard]] bool loopback_peer() const override { return loopback_; }

  void shutdown() { close_when_flushed(websocket::close_code::going_away); }

 private:
  void on_accept(beast::error_code ec) {
    if (ec) {
      return;
    }
    open_ = true;
    hub_.attach(*this);
    attached_ = true;
    do_read();
  }

  void do_read() { ws_.async_read(buffer_, beast::bind_front_handler(&WsSession::on_read, shared_from_this())); }

  void on_read(beast::error_code ec, std::size_t bytes) {
    if (ec) {
      leave();  // closed by the peer, timed out, or over kReadLimit (Beast has closed it)
      return;
    }
    if (!ws_.got_text()) {
      hub_.on_binary(*this);
    } else if (bytes > kMaxFrameBytes) {
      hub_.on_too_large(*this, bytes);
    } else {
      const auto data = buffer_.data();
      hub_.on_text(*this, std::string_view(static_cast<const char*>(data.data()), data.size()));
    }
    buffer_.consume(buffer_.size());
    do_read();
  }

  void do_write() {
    writing_ = true;
    ws_.async_write(asio::buffer(*queue_.front()),
                    beast::bind_front_handler(&WsSession::on_write, shared_from_this()));
  }

  void on_write(beast::error_code ec, std::size_t /*bytes*/) {
    writing_ = false;
    if (ec || aborted_) {
      abort();
      return;
    }
    queue_.pop_front();
    if (!queue_.empty() && !closing_) {
      do_write();
    } else if (close_pending_) {
      do_close(close_code_);
    }
  }

  void close_when_flushed(websocket::close_code code) {
    close_pending_ = true;
    close_code_ = code;
    if (!writing_) {
      do_close(code);
    }
  }

  void do_close(websocket::close_code code) {
    if (closing_ || !open_) {
      return;
    }
    closing_ = true;
    ws_.async_close(code, [self = shared_from_this()](beast::error_code) {});
  }

  // The pending read completes with an error and leaves the hub then: never from
  // inside a call of the hub, which may be iterating over its clients.
  void abort() {
    closing_ = true;
    if (!writing_) {
      queue_.clear();  // else the write in flight still uses the front frame: on_write clears
    }
    if (!aborted_) {
      aborted_ = true;
      beast::error_code ec;
      beast::get_lowest_layer(ws_).socket().close(ec);
    }
  }

  void leave() {
    open_ = false;
    if (attached_) {
      attached_ = false;
      hub_.detach(*this);
    }
  }

  websocket::stream<beast::tcp_stream> ws_;
  Hub& hub_;
  http::request<http::string_body> req_;
  beast::flat_buffer buffer_;
  std::deque<Frame> queue_;
  bool loopback_ = false;
  bool open_ = false;
  bool attached_ = false;
  bool writing_ = false;
  bool closing_ = false;
  bool close_pending_ = false;
  bool aborted_ = false;
  websocket::close_code close_code_ = websocket::close_code::normal;
};

// Live WebSocket sessions, to close them politely on shutdown.
class Sessions {
 public:
  void add(const std::shared_ptr<WsSession>& s) {
    std::erase_if(list_, [](const std::weak_ptr<WsSession>& w) { return w.expired(); });
    list_.push_back(s);
  }
  [[nodiscard]] std::size_t live() {
    std::erase_if(list_, [](const std::weak_ptr<WsSession>& w) { return w.expired(); });
    return list_.size();
  }
  void shutdown() {
    for (const auto& w : list_) {
      if (auto s = w.lock()) {
        s->shutdown();
      }
    }
  }

 private:
  std::vector<std::weak_ptr<WsSession>> list_;
};

// ------------------------------------------------------------------ HTTP
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket&& socket, Hub& hub, Sessions& sessions, const std::string& version)
      : stream_(std::move(socket)), hub_(hub), sessions_(sessions), server_("safestate " + version) {}

  void run() { do_read(); }

 private:
  void do_read() {
    parser_.emplace();
    parser_->header_limit(kHttpLimit);
    parser_->body_limit(kHttpLimit);
    stream_.expires_after(30s);
    http::async_read(stream_, buffer_, *parser_, beast::bind_front_handler(&HttpSession::on_read, shared_from_this()));
  }

  void on_read(beast::error_code ec, std::size_t /*bytes*/) {
    if (ec == http::error::end_of_stream) {
      stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
      return;
    }
    if (ec) {
      return;
    }
    const auto& req = parser_->get();
    const std::string_view target(req.target().data(), req.target().size());
    const std::string_view path = target.substr(0, target.find('?'));
    if (websocket::is_upgrade(req)) {
      if (path == "/ws" && sessions_.live() < kMaxClients) {
        auto ws = std::make_shared<WsSession>(stream_.release_socket(), hub_);
        sessions_.add(ws);
        ws->run(parser_->release());
        return;
      }
      answer(path == "/ws" ? HttpAnswer{503, "text/plain; charset=utf-8", "too many clients\n"}
                           : HttpAnswer{404, "text/plain; charset=utf-8", "not found\n"});
      return;
    }
    if (req.method() != http::verb::get) {
      answer(HttpAnswer{405, "text/plain; charset=utf-8", "only GET\n"});
      return;
    }
    answer(hub_.http_get(target));
  }

  void answer(HttpAnswer a) {
    const auto& req = parser_->get();
    res_ = std::make_shared<http::response<http::string_body>>(static_cast<http::status>(a.status), req.version());
    res_->set(http::field::server, server_);
    res_->set(http::field::content_type, a.content_type);
    res_->set(http::field::cache_control, "no-store");
    if (a.status == 405) {
      res_->set(http::field::allow, "GET");
    }
    res_->keep_alive(req.keep_alive());
    res_->body() = std::move(a.body);
    res_->prepare_payload();
    http::async_write(stream_, *res_,
                      beast::bind_front_handler(&HttpSession::on_write, shared_from_this(), res_->need_eof()));
  }

  void on_write(bool close, beast::error_code ec, std::size_t /*bytes*/) {
    if (ec) {
      return;
    }
    if (close) {
      stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
      return;
    }
    res_.reset();
    do_read();
  }

  beast::tcp_stream stream_;
  Hub& hub_;
  Sessions& sessions_;
  std::string server_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<http::response<http::string_body>> res_;
};

class Listener : public std::enable_shared_from_this<Listener> {
 public:
  Listener(asio::io_context& ioc, Hub& hub, Sessions& sessions, std::string version)
      : acceptor_(ioc), retry_(ioc), hub_(hub), sessions_(sessions), version_(std::move(version)) {}

  bool open(const tcp::endpoint& ep, std::string& error) {
    beast::error_code ec;
    acceptor_.open(ep.protocol(), ec);
    if (!ec) {
      acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
    }
    if (!ec) {
      acceptor_.bind(ep, ec);
    }
    if (!ec) {
      acceptor_.listen(asio::socket_base::max_listen_connections, ec);
    }
    if (ec) {
      error = ec.message();
      return false;
    }
    return true;
  }

  void run() { do_accept(); }

  void stop() {
    beast::error_code ec;
    acceptor_.close(ec);
    retry_.cancel();
  }

 private:
  void do_accept() { acceptor_.async_accept(beast::bind_front_handler(&Listener::on_accept, shared_from_this())); }

  void on_accept(beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor_.is_open()) {
      return;
    }
    if (ec) {
      // e.g. out of file descriptors: do not spin
      retry_.expires_after(50ms);
      retry_.async_wait([self = shared_from_this()](beast::error_code e) {
        if (!e) {
          self->do_accept();
        }
      });
      return;
    }
    beast::error_code nd;
    socket.set_option(tcp::no_delay(true), nd);
    std::make_shared<HttpSession>(std::move(socket), hub_, sessions_, version_)->run();
    do_accept();
  }

  tcp::acceptor acceptor_;
  asio::steady_timer retry_;
  Hub& hub_;
  Sessions& sessions_;
  std::string version_;
};

// A periodic timer without drift; after a stall it resumes from now.
class Ticker {
 public:
  Ticker(asio::io_context& ioc, Clock::duration period, std::function<void()> fn)
      : timer_(ioc), period_(period), fn_(std::move(fn)) {}
  void start() {
    next_ = Clock::now() + period_;
    arm();
  }
  void stop() {
    stopped_ = true;
    timer_.cancel();
  }

 private:
  void arm() {
    timer_.expires_at(next_);
    timer_.async_wait([this](beast::error_code ec) {
      if (ec || stopped_) {
        return;
      }
      fn_();
      next_ += period_;
      const auto now = Clock::now();
      if (next_ < now) {
        next_ = now + period_;
      }
      arm();
    });
  }

  asio::steady_timer timer_;
  Clock::duration period_;
  std::function<void()> fn_;
  Clock::time_point next_;
  bool stopped_ = false;
};

std::unique_ptr<bridge::Segment> attach(const std::string& name) {
  const auto deadline = Clock::now() + kAttachTimeout;
  std::string error;
  for (;;) {
    auto seg = bridge::Segment::attach(name, error);
    if (seg || g_early_stop != 0) {
      return seg;
    }
    if (Clock::now() >= deadline) {
      say("cannot attach to the core's shared memory: " + error + " (is `safestate run` running?)");
      return nullptr;
    }
    std::this_thread::sleep_for(50ms);
  }
}

bool resolve(const GatewayOptions& o, tcp::endpoint& ep) {
  beast::error_code ec;
  const auto addr = asio::ip::make_address(o.bind, ec);
  const auto port = static_cast<unsigned short>(o.port);
  if (!ec) {
    ep = tcp::endpoint(addr, port);
    return true;
  }
  asio::io_context ioc{1};
  tcp::resolver resolver(ioc);
  const auto results = resolver.resolve(o.bind, std::to_string(o.port), ec);
  if (ec || results.empty()) {
    say("cannot resolve bind address " + o.bind + ": " + (ec ? ec.message() : std::string("no address")));
    return false;
  }
  ep = results.begin()->endpoint();
  return true;
}

}  // namespace

int gateway_main(const GatewayOptions& options) {
  ::signal(SIGPIPE, SIG_IGN);
  if (options.port == 0U || options.port > 65535U) {
    say("bad port " + std::to_string(options.port));
    return 1;
  }
  if (options.db_path.empty()) {
    say("no event log path (--db PATH)");
    return 1;
  }
  ::signal(SIGTERM, on_early_signal);
  ::signal(SIGINT, on_early_signal);
  std::unique_ptr<bridge::Segment> segment = attach(options.shm_name);
  if (g_early_stop != 0) {
    return 0;
  }
  if (!segment) {
    return 1;
  }
  std::string error;
  std::unique_ptr<EventLog> log = EventLog::open(options.db_path, error);
  if (!log) {
    say(error);
    return 1;
  }

  tcp::endpoint endpoint;
  if (!resolve(options, endpoint)) {
    return 1;
  }
  const bool loopback = is_loopback(endpoint.address());
  if (!loopback && options.token.empty()) {
    say("listening beyond loopback without a token: every hello will be refused (BAD_TOKEN)");
  }
  // Declared before the io_context: sessions destroyed with it still detach from the hub.
  Hub hub(options, *segment, *log, loopback);
  Sessions sessions;
  asio::io_context ioc{1};
  auto listener = std::make_shared<Listener>(ioc, hub, sessions, options.version);
  if (!listener->open(endpoint, error)) {
    say("cannot listen on " + options.bind + ":" + std::to_string(options.port) + ": " + error);
    return 1;
  }
  auto& header = segment->header();
  const auto pid = static_cast<std::uint32_t>(::getpid());
  header.gateway_pid.store(pid, std::memory_order_relaxed);

  int exit_code = 0;
  bool stopping = false;
  asio::steady_timer grace(ioc);
  Ticker poll(ioc, kPollPeriod, [&hub] { hub.poll(); });
  Ticker status(ioc, kStatusPeriod, [&hub] { hub.broadcast_status(); });
  std::function<void(int)> stop = [&](int code) {
    if (stopping) {
      return;
    }
    stopping = true;
    exit_code = code;
    listener->stop();
    poll.stop();
    status.stop();
    hub.flush();  // what the core said last goes to the log
    sessions.shutdown();
    grace.expires_after(200ms);
    grace.async_wait([&ioc](beast::error_code) { ioc.stop(); });
  };
  Ticker liveness(ioc, kLivenessPeriod, [&] {
    if (hub.core_gone()) {
      say("the core process is gone");
      stop(1);
    }
  });
  asio::signal_set signals(ioc, SIGINT, SIGTERM);
  signals.async_wait([&](beast::error_code ec, int /*sig*/) {
    if (!ec) {
      stop(0);
    }
  });

  if (g_early_stop != 0) {
    stop(0);
  }
  listener->run();
  poll.start();
  status.start();
  liveness.start();
  say("listening on http://" + options.bind + ":" + std::to_string(options.port) + " (segment " +
      options.shm_name + ", event log " + options.db_path + ")");
  ioc.run();
  liveness.stop();

  std::uint32_t expected = pid;
  header.gateway_pid.compare_exchange_strong(expected, 0U, std::memory_order_relaxed);
  return exit_code;
}

}  // namespace safestate::gateway

// The gateway process: the listener, the timers and signals on one io_context thread,
// in front of the Hub. Admission and authentication: admission.cpp; sessions and
// fan-out: sessions.cpp; HTTP endpoints and the bounds on connections (slow and idle
// clients, descriptors: issue 40): http_endpoints.cpp; protocol messages:
// messages.cpp; the core side and the event feed: hub.cpp; the event log: event_log.cpp.
//
// Waking: while commands wait for the core's reply, the poll runs just after the core's
// next cycle boundary (published in the segment by the real-time loop, a plain store),
// looking again at short intervals until the core has published that cycle, instead of
// every 2 ms, so a reply goes out within about one cycle; idle, every 2 ms. The event log's
// commit waits until the replies are out (kEventsAfterReplies).
#include "safestate/gateway/gateway.hpp"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <functional>
#include <memory>
#include <thread>

#include "http_endpoints.hpp"
#include "safestate/gateway/admission.hpp"
#include "safestate/gateway/hub.hpp"
#include "sessions.hpp"

namespace safestate::gateway {

namespace {

using namespace std::chrono_literals;

constexpr auto kPollPeriod = 2ms;
constexpr auto kLivenessPeriod = 250ms;
constexpr auto kAttachTimeout = 5s;
// While replies are due, the first look after the core's cycle boundary. The core wakes
// late and runs its cycle, then publishes it: on the bench machine 12-21 us after the
// boundary at p50 and 35-49 us at p99 (`ws_rtt cycle-done`, docs/performance.md); this
// process's own timer wakes 20-50 us late on top of the time asked for, so a first look
// at 25 us finds the cycle published nearly always, about 100 us sooner than the 120 us
// this replaced.
constexpr auto kFirstLook = 25us;
// The cycle has not been published yet (the core is late or still running): look again
// this often, for at most kRetryWindow after the boundary. Beyond it the core is stalled
// or not cycling and costs no more than the idle poll.
constexpr auto kRetry = 25us;
constexpr auto kRetryWindow = 500us;
// The event log's commit (SQLite, synchronous=FULL: an fsync) right after the replies'
// writes delayed the clients' reading of those replies by about 200 us at p50 on the bench
// machine (the flush competes with them for the two vCPUs), although the replies had been
// written first; started this long after them, the commit falls in the middle of the
// cycle, away from the next replies, and the round trip lost those 200 us (docs/performance.md).
constexpr auto kEventsAfterReplies = 400us;

void say(const std::string& s) { std::fprintf(stderr, "safestate gateway: %s\n", s.c_str()); }

// SIGTERM/SIGINT before the io_context's signal_set is in place (while attaching).
volatile std::sig_atomic_t g_early_stop = 0;
extern "C" void on_early_signal(int /*sig*/) { g_early_stop = 1; }

// Accepts every connection as soon as it comes (HttpConnections::admit decides what
// becomes of it), so that a fresh request never waits in the kernel's backlog behind a
// crowd of slow or silent connections; only when limits.open_max connections are held and
// none of them may give way does it wait (kRoomRetry) and the backlog hold the newcomers.
class Listener : public std::enable_shared_from_this<Listener> {
 public:
  Listener(asio::io_context& ioc, Endpoints& ep) : acceptor_(ioc), retry_(ioc), ep_(ep) {}

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

  void run() { next(); }

  void stop() {
    beast::error_code ec;
    acceptor_.close(ec);
    retry_.cancel();
  }

 private:
  void next() {
    if (!acceptor_.is_open()) {
      return;
    }
    if (ep_.http.make_room()) {
      acceptor_.async_accept(beast::bind_front_handler(&Listener::on_accept, shared_from_this()));
      return;
    }
    pause(kRoomRetry);
  }

  void pause(Clock::duration d) {
    ep_.http.count_accept_paused();
    retry_.expires_after(d);
    retry_.async_wait([self = shared_from_this()](beast::error_code e) {
      if (!e) {
        self->next();
      }
    });
  }

  void on_accept(beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor_.is_open()) {
      return;
    }
    if (ec) {
      // Out of descriptors although the count had room (something else holds more than
      // kOwnDescriptors): the oldest silent waiting connection gives way, and accepting
      // goes on at once; else not before kErrorRetry (no spin).
      const bool no_fds = ec == asio::error::no_descriptors || ec == boost::system::errc::too_many_files_open_in_system;
      if (no_fds && ep_.http.shed_one()) {
        next();
        return;
      }
      pause(kErrorRetry);
      return;
    }
    beast::error_code nd;
    socket.set_option(tcp::no_delay(true), nd);
    ep_.http.admit(std::move(socket), ep_);
    next();
  }

  static constexpr auto kRoomRetry = 5ms;
  static constexpr auto kErrorRetry = 50ms;
  tcp::acceptor acceptor_;
  asio::steady_timer retry_;
  Endpoints& ep_;
};

// A periodic timer without drift: a tick that comes late does not cost the next one (the
// promised 50 Hz status); after a stall of more than a period it resumes from now.
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
      if (next_ + period_ < now) {
        next_ = now;  // more than a period behind (a stall): one tick now, then on period again, no burst
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


// The hub's poll: every 2 ms when idle; while replies are due, just after each of the
// core's cycle boundaries, when the core has published that cycle. kick() re-arms it early
// when a command has been sent.
class Poller {
 public:
  Poller(asio::io_context& ioc, Hub& hub, const bridge::Header& header)
      : timer_(ioc), events_(ioc), hub_(hub), header_(header) {}
  void start() { arm(Clock::now() + kPollPeriod); }
  void stop() {
    stopped_ = true;
    timer_.cancel();
    events_.cancel();
  }
  void kick() {
    if (!stopped_ && hub_.awaiting_core()) {
      const auto at = after_boundary(Clock::now());
      if (at < armed_) {
        arm(at);
      }
    }
  }

 private:
  // The next look while replies are due: at most 1 + kRetryWindow / kRetry wakes per cycle,
  // and only while a reply is due (idle: every kPollPeriod).
  [[nodiscard]] Clock::time_point after_boundary(Clock::time_point now) const {
    // steady_clock is CLOCK_MONOTONIC on Linux, the clock of the core's deadlines. The core
    // stores its next boundary after it has published a cycle: while it still holds a
    // boundary that has passed, that cycle is yet to be published.
    const auto boundary =
        Clock::time_point(std::chrono::nanoseconds(header_.next_cycle_ns.load(std::memory_order_acquire)));
    const auto first = boundary + kFirstLook;
    if (first > now) {
      return std::min(first, now + kPollPeriod);
    }
    return (now - boundary < kRetryWindow) ? now + kRetry : now + kPollPeriod;
  }
  void arm(Clock::time_point at) {
    armed_ = at;
    timer_.expires_at(at);
    timer_.async_wait([this](beast::error_code ec) {
      if (ec || stopped_) {
        return;
      }
      hub_.poll();
      drain_events_later();
      const auto now = Clock::now();
      arm(hub_.awaiting_core() ? after_boundary(now) : now + kPollPeriod);
    });
  }

  // The event log's commit (an fsync) comes kEventsAfterReplies after the replies of the
  // poll, once coalesced: a reply never waits for the disk, nor does its client.
  void drain_events_later() {
    if (events_armed_) {
      return;
    }
    events_armed_ = true;
    events_.expires_after(kEventsAfterReplies);
    events_.async_wait([this](beast::error_code ec) {
      events_armed_ = false;
      if (!ec && !stopped_) {
        hub_.poll_events();
      }
    });
  }

  asio::steady_timer timer_;
  asio::steady_timer events_;
  bool events_armed_ = false;
  Hub& hub_;
  const bridge::Header& header_;
  Clock::time_point armed_{};
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

// The soft RLIMIT_NOFILE raised to the hard limit (a soft 1024 is a common default that
// a descriptor-hungry load reaches first): what the gateway may hold from now on.
std::size_t raise_fd_limit() {
  rlimit r{};
  if (::getrlimit(RLIMIT_NOFILE, &r) != 0) {
    return 1024;
  }
  if (r.rlim_cur < r.rlim_max) {
    rlimit want = r;
    want.rlim_cur = r.rlim_max;
    if (::setrlimit(RLIMIT_NOFILE, &want) == 0) {
      r = want;
    }
  }
  constexpr rlim_t kCeiling = 1U << 20U;  // the kernel's usual nr_open
  return static_cast<std::size_t>(std::min<rlim_t>(r.rlim_cur, kCeiling));
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
  ::prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);  // wake at the cycle boundary, not 50 us later
  {
    bool loopback = true;
    std::string why;
    if (!bind_is_loopback(options.bind, loopback, why)) {
      say(why);
      return 1;
    }
    why = startup_refusal(options, loopback);
    if (!why.empty()) {
      say(why);  // before any socket exists: nothing listens unprotected, not even briefly
      return 1;
    }
  }
  if (options.max_clients < 2U || options.max_http < 1U) {
    say("--max-clients must be at least 2 (one slot is kept for the pendant) and --max-http at least 1");
    return 1;
  }
  if (options.port == 0U || options.port > 65535U) {
    say("bad port " + std::to_string(options.port));
    return 1;
  }
  if (options.db_path.empty()) {
    say("no event log path (--db PATH)");
    return 1;
  }
  ConnectionLimits limits;
  if (std::string why; !connection_limits(raise_fd_limit(), options.max_clients, options.max_http, limits, why)) {
    say(why);
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
  // Two connections to the log: the writer's thread commits (an fsync each), the I/O thread
  // reads (history, black boxes, the latest confirmation) without waiting for it (WAL).
  std::unique_ptr<EventLog> log = EventLog::open(options.db_path, error);
  std::unique_ptr<EventLog> write_log = log ? EventLog::open(options.db_path, error) : nullptr;
  if (!log || !write_log) {
    say(error);
    return 1;
  }
  EventWriter writer(std::move(write_log));

  tcp::endpoint endpoint;
  if (!resolve(options, endpoint)) {
    return 1;
  }
  const bool loopback = is_loopback(endpoint.address());
  // Declared before the io_context: sessions destroyed with it still detach from the hub.
  Hub hub(options, *segment, *log, writer, loopback);
  Sessions sessions(options.max_clients);
  HttpConnections http(options.max_http, limits);
  hub.connection_figures([&http] { return http.figures(); });
  Endpoints endpoints{hub, sessions, http, hub.access(), "safestate " + options.version};
  asio::io_context ioc{1};
  writer.on_done([&ioc, &hub] { asio::post(ioc, [&hub] { hub.collect_log(); }); });
  auto listener = std::make_shared<Listener>(ioc, endpoints);
  if (!listener->open(endpoint, error)) {
    say("cannot listen on " + options.bind + ":" + std::to_string(options.port) + ": " + error);
    return 1;
  }
  auto& header = segment->header();
  set_fieldbus(header.bus);
  if (std::string why; !set_safety(header.safety, why)) {
    say(why + " (GET /api/safety answers 503; zones are named by number)");
  }
  const auto pid = static_cast<std::uint32_t>(::getpid());
  header.gateway_pid.store(pid, std::memory_order_relaxed);

  int exit_code = 0;
  bool stopping = false;
  asio::steady_timer grace(ioc);
  Poller poll(ioc, hub, header);
  hub.on_submit([&poll] { poll.kick(); });
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
      options.shm_name + ", event log " + options.db_path + "; at most " + std::to_string(limits.open_max) +
      " connections of " + std::to_string(limits.fd_limit) + " descriptors, " + std::to_string(limits.waiting_max) +
      " waiting for a request, " + std::to_string(limits.waiting_per_peer) + " of them from one address)");
  ioc.run();
  liveness.stop();
  writer.stop();  // what is queued is written; nothing is posted to the io_context after this

  std::uint32_t expected = pid;
  header.gateway_pid.compare_exchange_strong(expected, 0U, std::memory_order_relaxed);
  return exit_code;
}

}  // namespace safestate::gateway

// Command round trip through `safestate run` as a C++ client sees it (issue 12's goal:
// p50 <= 1.0 ms, p99 <= 2.0 ms at a 1 ms cycle on loopback), measured with a client whose
// own cost is small next to the figure, so that the figure is SafeState's: the Python
// client of bench/ws_latency.py adds about 0.4 ms per round trip on the bench machine.
//
//   ws_rtt rtt --port P [--shm NAME] [--commands N] [--warmup N] [--json FILE]
//     Two series over two WebSocket connections (Boost.Beast, synchronous):
//      - pendant: `set_mode` commands, which the core always answers MODE_BY_SELECTOR_ONLY
//        and which change nothing; every reply is checked to be that one (the core's);
//      - observer: the same command from an observer, answered NOT_CONTROL_OWNER by the
//        gateway itself (protocol.md "Roles"): the two WebSocket hops, the JSON and the
//        client without the core: the baseline that splits the round trip.
//     Commands are paced at random 4-6 ms apart: under the gateway's per-client rate
//     (250 records/s) and at a random phase against the 1 ms cycle, so that the wait for
//     the next cycle is what a client sees on average, not one lucky phase. With --shm the
//     client also reads the core's next boundary from the segment when it sends (read
//     only), which splits each pendant round trip into the wait for that boundary and
//     what follows it, and shows whether the phases were indeed random.
//   ws_rtt cycle-done --shm NAME [--cycles N] [--json FILE]
//     When, after its cycle boundary, the core has run the cycle and published it (the
//     segment's next_cycle_ns moves on, stored after the replies): spins reading the
//     segment for N cycles (default 2,000: two seconds of one CPU). The data the gateway's
//     wake-up after the boundary is chosen from (gateway/src/gateway.cpp, kFirstLook).
//
// Environment WS_RTT_RAW=FILE (rtt with --shm): each pendant command's wait for the
// boundary and time after it (us), one pair a line, for a closer look.
//
// A measurement, not a test: nothing is asserted except that the replies are the ones the
// series is about (a wrong reply ends the run with an error: the figure would be wrong).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>
#include <sys/prctl.h>

#include "safestate/bridge/segment.hpp"
#include "safestate/util/percentile.hpp"

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using Clock = std::chrono::steady_clock;
using Json = nlohmann::json;

struct Args {
  std::string mode;
  unsigned port = 0;
  std::string shm;
  int commands = 2000;
  int warmup = 20;
  int cycles = 2000;
  std::string json;
};

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr,
               "ws_rtt: %s\nusage: ws_rtt rtt --port P [--shm NAME] [--commands N] [--warmup N] [--json FILE]\n"
               "       ws_rtt cycle-done --shm NAME [--cycles N] [--json FILE]\n",
               why.c_str());
  std::exit(2);
}

int to_int(const std::string& s, const char* what) {
  char* end = nullptr;
  const long v = std::strtol(s.c_str(), &end, 10);
  if (end == s.c_str() || *end != '\0' || v < 0 || v > 10000000) {
    usage(std::string("bad ") + what + ": " + s);
  }
  return static_cast<int>(v);
}

Args parse(int argc, char** argv) {
  Args a;
  if (argc < 2) {
    usage("no mode");
  }
  a.mode = argv[1];
  for (int i = 2; i < argc; ++i) {
    const std::string k = argv[i];
    if (i + 1 >= argc) {
      usage("no value for " + k);
    }
    const std::string v = argv[++i];
    if (k == "--port") {
      a.port = static_cast<unsigned>(to_int(v, "port"));
    } else if (k == "--shm") {
      a.shm = v;
    } else if (k == "--commands") {
      a.commands = to_int(v, "command count");
    } else if (k == "--warmup") {
      a.warmup = to_int(v, "warm-up count");
    } else if (k == "--cycles") {
      a.cycles = to_int(v, "cycle count");
    } else if (k == "--json") {
      a.json = v;
    } else {
      usage("unknown option " + k);
    }
  }
  if (a.mode == "rtt" && (a.port == 0U || a.port > 65535U || a.commands < 1)) {
    usage("rtt needs --port and at least one command");
  }
  if (a.mode == "cycle-done" && (a.shm.empty() || a.cycles < 1)) {
    usage("cycle-done needs --shm and at least one cycle");
  }
  if (a.mode != "rtt" && a.mode != "cycle-done") {
    usage("unknown mode " + a.mode);
  }
  return a;
}

// Percentiles as bench/ws_latency.py computes them (nearest rank on the sorted series).
double pct(std::vector<double> xs, double p) { return safestate::util::percentile(std::move(xs), p / 100.0); }

Json figures(const std::vector<double>& xs) {
  double sum = 0.0;
  for (const double x : xs) {
    sum += x;
  }
  return Json{{"n", xs.size()},
              {"p50", pct(xs, 50)},
              {"p90", pct(xs, 90)},
              {"p99", pct(xs, 99)},
              {"max", *std::max_element(xs.begin(), xs.end())},
              {"mean", sum / static_cast<double>(xs.size())}};
}

class Client {
 public:
  Client(asio::io_context& ioc, unsigned port, const std::string& role) : ws_(ioc) {
    tcp::resolver resolver(ioc);
    asio::connect(ws_.next_layer(), resolver.resolve("127.0.0.1", std::to_string(port)));
    ws_.next_layer().set_option(tcp::no_delay(true));
    ws_.handshake("127.0.0.1:" + std::to_string(port), "/ws");  // no Origin: not a browser
    ws_.text(true);
    Json hello{{"type", "hello"}, {"role", role}, {"client", "ws_rtt"}};
    const char* token = std::getenv("SAFESTATE_PENDANT_TOKEN");
    if (role == "pendant" && token != nullptr && *token != '\0') {
      hello["token"] = token;
    }
    write(hello.dump());
    for (;;) {
      const Json m = read();
      if (m.value("type", "") == "welcome") {
        return;
      }
      if (m.value("type", "") == "error") {
        throw std::runtime_error("hello as " + role + " refused: " + m.dump());
      }
    }
  }

  // One command and its reply; returns the round trip in ms and the reply's result.
  double command(std::uint64_t seq, std::string& result) {
    const std::string text = Json{{"type", "command"}, {"seq", seq}, {"cmd", "set_mode"}, {"mode", "T1"}}.dump();
    const auto t0 = Clock::now();
    write(text);
    for (;;) {
      const Json m = read();
      if (m.value("type", "") == "reply" && m.value("seq", std::uint64_t{0}) == seq) {
        const auto t1 = Clock::now();
        result = m.value("result", "");
        return std::chrono::duration<double, std::milli>(t1 - t0).count();
      }
    }
  }

  void close() {
    beast::error_code ec;
    ws_.close(websocket::close_code::normal, ec);
  }

 private:
  void write(const std::string& s) { ws_.write(asio::buffer(s)); }
  Json read() {
    buf_.clear();
    ws_.read(buf_);
    return Json::parse(beast::buffers_to_string(buf_.data()));
  }

  websocket::stream<tcp::socket> ws_;
  beast::flat_buffer buf_;
};

std::uint64_t now_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
}

// With the segment (--shm): each command's phase against the cycle, i.e. how long before
// the core's next cycle boundary it was sent, and how long after that boundary its reply
// was in the client's hands; what splits the round trip into the wait for the cycle and
// the rest.
struct Phases {
  const safestate::bridge::Segment* seg = nullptr;
  std::uint64_t period_ns = 1000000;
  std::vector<double> to_boundary_us;
  std::vector<double> after_boundary_us;
};

std::vector<double> series(Client& c, int warmup, int n, const char* expected, std::uint64_t first_seq,
                           Phases* ph) {
  std::mt19937_64 rng(std::random_device{}());
  std::uniform_int_distribution<int> pace_us(4000, 6000);
  std::vector<double> out;
  out.reserve(static_cast<std::size_t>(n));
  std::string result;
  for (int i = 0; i < warmup + n; ++i) {
    std::this_thread::sleep_for(std::chrono::microseconds(pace_us(rng)));
    std::uint64_t phase = 0;
    if (ph != nullptr && ph->seg != nullptr) {
      const std::uint64_t t = now_ns();
      const std::uint64_t next = ph->seg->header().next_cycle_ns.load(std::memory_order_acquire);
      // A boundary that has passed but is not yet published (the cycle runs): the next one.
      phase = (next > t) ? (next - t) % ph->period_ns : ph->period_ns - (t - next) % ph->period_ns;
    }
    const double ms = c.command(first_seq + static_cast<std::uint64_t>(i), result);
    if (result != expected) {
      throw std::runtime_error("reply " + result + " where " + expected +
                               " was expected: the measurement would be of something else");
    }
    if (i < warmup) {
      continue;
    }
    out.push_back(ms);
    if (ph != nullptr && ph->seg != nullptr) {
      const double to_us = static_cast<double>(phase) / 1000.0;
      ph->to_boundary_us.push_back(to_us);
      ph->after_boundary_us.push_back(ms * 1000.0 - to_us);
    }
  }
  return out;
}

Json rtt(const Args& a) {
  asio::io_context ioc;
  Phases ph;
  std::unique_ptr<safestate::bridge::Segment> seg;
  if (!a.shm.empty()) {
    std::string error;
    seg = safestate::bridge::Segment::attach(a.shm, error);
    if (!seg) {
      throw std::runtime_error("cannot attach to " + a.shm + ": " + error);
    }
    ph.seg = seg.get();
    ph.period_ns = std::uint64_t{1000} * std::max<std::uint32_t>(1U, seg->metrics().cycle_us.load());
  }
  Client pendant(ioc, a.port, "pendant");
  Client observer(ioc, a.port, "observer");
  const auto p = series(pendant, a.warmup, a.commands, "MODE_BY_SELECTOR_ONLY", 1, &ph);
  const auto o = series(observer, a.warmup, a.commands, "NOT_CONTROL_OWNER", 1000000, nullptr);
  pendant.close();
  observer.close();
  Json out{{"pendant_ms", figures(p)}, {"observer_ms", figures(o)}, {"warmup", a.warmup}};
  if (!ph.to_boundary_us.empty()) {
    // A reply later than one period after the boundary that followed its command: the
    // command reached the core after that cycle had taken its commands.
    const auto missed = std::count_if(ph.after_boundary_us.begin(), ph.after_boundary_us.end(),
                                      [&](double us) { return us * 1000.0 > static_cast<double>(ph.period_ns); });
    out["pendant_to_boundary_us"] = figures(ph.to_boundary_us);
    out["pendant_after_boundary_us"] = figures(ph.after_boundary_us);
    out["pendant_missed_boundary"] = missed;
    out["cycle_us"] = ph.period_ns / 1000U;
    if (const char* raw = std::getenv("WS_RTT_RAW"); raw != nullptr) {  // pairs, for a closer look
      std::ofstream f(raw);
      for (std::size_t i = 0; i < ph.to_boundary_us.size(); ++i) {
        f << ph.to_boundary_us[i] << ' ' << ph.after_boundary_us[i] << '\n';
      }
    }
  }
  return out;
}

Json cycle_done(const Args& a) {
  std::string error;
  const auto seg = safestate::bridge::Segment::attach(a.shm, error);
  if (!seg) {
    throw std::runtime_error("cannot attach to " + a.shm + ": " + error);
  }
  const auto& next = seg->header().next_cycle_ns;
  std::vector<double> after_us;
  after_us.reserve(static_cast<std::size_t>(a.cycles));
  std::uint64_t boundary = next.load(std::memory_order_acquire);
  const std::uint64_t give_up = now_ns() + static_cast<std::uint64_t>(a.cycles) * std::uint64_t{20000000};
  while (static_cast<int>(after_us.size()) < a.cycles && now_ns() < give_up) {
    const std::uint64_t n = next.load(std::memory_order_acquire);
    if (n == boundary) {
      continue;
    }
    const std::uint64_t t = now_ns();
    if (boundary != 0U && t > boundary) {
      after_us.push_back(static_cast<double>(t - boundary) / 1000.0);
    }
    boundary = n;
  }
  if (after_us.empty()) {
    throw std::runtime_error("the core published no cycle: is it running?");
  }
  return Json{{"published_after_boundary_us", figures(after_us)}};
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
  // The pacing sleeps must end at random instants: with the default 50 us timer slack the
  // kernel may fire them together with the core's 1 ms timer, just after a cycle boundary,
  // and every command would wait a whole cycle: a phase no real client has.
  ::prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  try {
    const Json out = (a.mode == "rtt") ? rtt(a) : cycle_done(a);
    std::printf("%s\n", out.dump(1).c_str());
    if (!a.json.empty()) {
      std::ofstream(a.json) << out.dump(1) << '\n';
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ws_rtt: %s\n", e.what());
    return 1;
  }
  return 0;
}

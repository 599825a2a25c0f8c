// HTTP endpoints (protocol.md "Endpoints", "Access and admission").
//
// Decisions where protocol.md is silent:
//  - Checked in this order: URL length (414), Host (421), Origin (403), then for /api/*
//    and /metrics beyond loopback the bearer token (401 with WWW-Authenticate), then
//    the method (GET only, 405). A 414/431 closes the connection.
//  - An upgrade anywhere but /ws is 404; /ws with every slot of the lobby (upgraded,
//    no hello yet) taken waits until one is free or silent for kSilentLimit (then
//    evicted with close 1013), at most kLobbyWait, then 503 with Retry-After.
//  - /api/events: after >= 0 (default 0), limit >= 1 (default 100, above 500 clamped to
//    500); a malformed value is 400 {"error", "parameter", "detail"}. The body is the
//    page (a JSON array, oldest first); when the page is full, a `Link: <...>;
//    rel="next"` header says where to continue (RFC 8288), and `X-Next-After` carries
//    the id to pass as `after`. Each row's `blackbox` is null or the URL of its black
//    box, /api/events/ID/blackbox.
//  - Static paths with a `..` segment (also percent-encoded) or leaving the static
//    folder are 400; unknown files 404; `/` without a built HMI is a small built-in
//    page. `/ws` without Upgrade is 426. Request head: 8 KiB.
//  - Connections (issue 40, gateway/README.md "Admission"): every one accepted at once;
//    one that waits for a request head is bounded per peer and overall (the oldest silent
//    one gives way: 503 + Retry-After, closed at once) and has 3 s for its first head
//    (10 s for the next one, kept alive), else 408 and closed (a kept-alive connection
//    that has not begun its next request is closed without a word, as keep-alive ends). --max-http counts requests
//    in service (answered or upgraded); beyond, a request waits its turn, at most 1 s.
//    503 and 408 to a connection that has had no answer yet are written without waiting
//    (its send buffer is empty) and the descriptor closed at once: under a flood of silent
//    connections nothing lingers.
#include "http_endpoints.hpp"

#include <array>
#include <charconv>
#include <fstream>
#include <map>
#include <sstream>

#include "safestate/gateway/static_files.hpp"

namespace safestate::gateway {

namespace {

using namespace std::chrono_literals;
constexpr std::int64_t kMaxPage = 500;

HttpAnswer text_answer(unsigned status, const char* body) { return HttpAnswer{status, "text/plain; charset=utf-8", body, {}}; }
HttpAnswer json_answer(unsigned status, const Json& j) { return HttpAnswer{status, "application/json", dump(j), {}}; }

HttpAnswer bad_parameter(const char* name, const std::string& detail) {
  Json j;
  j["error"] = "bad parameter";
  j["parameter"] = name;
  j["detail"] = detail;
  return json_answer(400, j);
}

bool parse_int64(std::string_view s, std::int64_t& out) {
  const char* end = s.data() + s.size();
  const auto [p, ec] = std::from_chars(s.data(), end, out);
  return !s.empty() && ec == std::errc{} && p == end;
}

}  // namespace

// ------------------------------------------------------------------ refused: 503, 408
namespace {
std::string canned(const char* status, const std::string& body, bool retry_after) {
  std::string a = std::string("HTTP/1.1 ") + status +
                  "\r\nServer: safestate\r\nContent-Type: text/plain; charset=utf-8\r\nCache-Control: no-store\r\n";
  if (retry_after) {
    a += "Retry-After: " + std::to_string(kRetryAfterSeconds) + "\r\n";
  }
  return a + "Connection: close\r\nContent-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body;
}

const std::string& busy_answer() {
  static const std::string a = canned(
      "503 Service Unavailable",
      "too many connections at once: try again in " + std::to_string(kRetryAfterSeconds) + " s\n", true);
  return a;
}

const std::string& timeout_answer() {
  static const std::string a =
      canned("408 Request Timeout", "the request head did not arrive in time: send it whole, then wait\n", false);
  return a;
}

// Written at once on a socket whose send buffer is empty (a connection that has had no
// answer yet, or whose answers are written), never blocking; then closed.
void write_and_close(tcp::socket& s, const std::string& raw) {
  beast::error_code ec;
  s.non_blocking(true, ec);
  if (!raw.empty()) {
    s.write_some(asio::buffer(raw), ec);
  }
  s.shutdown(tcp::socket::shutdown_both, ec);
  s.close(ec);
}

// The peer's address as bytes (an IPv4-mapped IPv6 address as its IPv4 one).
std::string peer_key(const tcp::socket& s) {
  beast::error_code ec;
  const auto ep = s.remote_endpoint(ec);
  if (ec) {
    return "?";
  }
  auto a = ep.address();
  if (a.is_v6() && a.to_v6().is_v4_mapped()) {
    a = asio::ip::make_address_v4(asio::ip::v4_mapped, a.to_v6());
  }
  if (a.is_v4()) {
    const auto b = a.to_v4().to_bytes();
    return {b.begin(), b.end()};
  }
  const auto b = a.to_v6().to_bytes();
  return {b.begin(), b.end()};
}

class Refusal : public std::enable_shared_from_this<Refusal> {
 public:
  Refusal(tcp::socket&& s, Seat seat, std::shared_ptr<std::size_t> count)
      : socket_(std::move(s)), seat_(std::move(seat)), timer_(socket_.get_executor()), count_(std::move(count)) {
    if (count_) {
      ++*count_;
    }
  }
  Refusal(const Refusal&) = delete;
  Refusal& operator=(const Refusal&) = delete;
  ~Refusal() {
    if (count_) {
      --*count_;
    }
  }
  void run() {
    timer_.expires_after(kSilentLimit);
    timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (!ec) {
        beast::error_code e;
        self->socket_.close(e);  // the peer neither read nor closed: enough
      }
    });
    asio::async_write(socket_, asio::buffer(busy_answer()), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        self->timer_.cancel();
        return;
      }
      beast::error_code e;
      self->socket_.shutdown(tcp::socket::shutdown_send, e);
      self->drain();
    });
  }

 private:
  // Reads (and throws away) until the peer closes: closing with unread bytes would send
  // a reset, which may destroy the answer before the peer has read it.
  void drain() {
    socket_.async_read_some(asio::buffer(sink_), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        self->timer_.cancel();
        return;
      }
      self->drain();
    });
  }
  tcp::socket socket_;
  Seat seat_;
  asio::steady_timer timer_;
  std::shared_ptr<std::size_t> count_;
  std::array<char, 4096> sink_{};
};
}  // namespace

void refuse_busy(tcp::socket socket, Seat seat, std::shared_ptr<std::size_t> count) {
  std::make_shared<Refusal>(std::move(socket), std::move(seat), std::move(count))->run();
}

// ------------------------------------------------------------------ the connections
HttpConnections::HttpConnections(std::size_t max_service, const ConnectionLimits& limits)
    : max_service_(max_service), limits_(limits) {}

void HttpConnections::prune() {
  std::erase_if(list_, [](const std::weak_ptr<HttpSession>& w) {
    const auto s = w.lock();
    return !s || !s->live();
  });
}

bool HttpConnections::shed(std::string_view peer, const HttpSession* spare) {
  std::vector<WaitingConnection> views;
  std::vector<std::shared_ptr<HttpSession>> who;
  for (const auto& w : list_) {
    auto s = w.lock();
    if (s && s->waiting() && s.get() != spare) {
      views.push_back(s->view());
      who.push_back(std::move(s));
    }
  }
  // view() leaves out the socket: looked at for the chosen one only (one system call,
  // not one per connection). Its request arriving, the next one is chosen, a few times at
  // most: beyond, it is a burst whose requests are all arriving, and nobody gives way.
  const auto now = Clock::now();
  for (int tries = 0; tries < 8; ++tries) {
    const std::size_t i = pick_shed(views, peer, now, kSilentLimit);
    if (i == views.size()) {
      return false;
    }
    if (who[i]->has_unread()) {
      views[i].silent = false;
      continue;
    }
    who[i]->shed();
    ++shed_;
    return true;
  }
  return false;
}

bool HttpConnections::make_room() {
  if (*open_ < limits_.open_max) {
    return true;
  }
  return shed_one();
}

bool HttpConnections::shed_one() {
  prune();
  return shed({}, nullptr);
}

void HttpConnections::admit(tcp::socket socket, Endpoints& ep) {
  prune();
  std::string peer = peer_key(socket);
  std::size_t waiting = 0;
  std::size_t of_peer = 0;
  for (const auto& w : list_) {
    const auto s = w.lock();
    if (s && s->waiting()) {
      ++waiting;
      of_peer += (s->peer() == peer) ? 1U : 0U;
    }
  }
  Seat seat(open_);
  bool room = true;
  if (of_peer >= limits_.waiting_per_peer) {
    room = shed(peer, nullptr);
    waiting -= room ? 1U : 0U;
  }
  if (room && waiting >= limits_.waiting_max) {
    room = shed({}, nullptr);
  }
  if (!room) {
    // Every connection waiting within the bound has its request arriving: the newcomer is
    // told to come back (drained first when few are; at once beyond).
    ++refused_;
    if (*refusing_ < kMaxRefusing) {
      refuse_busy(std::move(socket), std::move(seat), refusing_);
    } else {
      write_and_close(socket, busy_answer());
    }
    return;
  }
  auto s = std::make_shared<HttpSession>(std::move(socket), ep, std::move(seat), std::move(peer));
  list_.push_back(s);
  s->run();
}

bool HttpConnections::take_service() {
  while (!queue_.empty()) {
    const auto s = queue_.front().lock();
    if (s && s->queued()) {
      return false;  // first come, first served
    }
    queue_.pop_front();
  }
  if (in_service_ >= max_service_) {
    return false;
  }
  ++in_service_;
  return true;
}

void HttpConnections::queue_for_service(const std::shared_ptr<HttpSession>& s) { queue_.push_back(s); }

void HttpConnections::release_service(const asio::any_io_executor& ex) {
  release_service_quietly();
  if (!serve_posted_ && !queue_.empty()) {
    serve_posted_ = true;
    asio::post(ex, [this] {
      serve_posted_ = false;
      serve_next();
    });
  }
}

void HttpConnections::release_service_quietly() noexcept {
  if (in_service_ > 0U) {
    --in_service_;
  }
}

void HttpConnections::serve_next() {
  while (in_service_ < max_service_ && !queue_.empty()) {
    const auto s = queue_.front().lock();
    queue_.pop_front();
    if (s && s->queued()) {
      ++in_service_;
      s->serve();
    }
  }
}

ConnectionFigures HttpConnections::figures() const {
  ConnectionFigures f;
  f.known = true;
  f.fd_limit = limits_.fd_limit;
  f.open = *open_;
  f.open_max = limits_.open_max;
  f.waiting_max = limits_.waiting_max;
  f.waiting_per_peer_max = limits_.waiting_per_peer;
  f.in_service = in_service_;
  f.in_service_max = max_service_;
  f.first_head_limit_s = std::chrono::duration<double>(kFirstHeadLimit).count();
  f.keep_alive_limit_s = std::chrono::duration<double>(kKeepAliveLimit).count();
  f.shed_total = shed_;
  f.head_timeouts_total = head_timeouts_;
  f.refused_total = refused_;
  f.accept_paused_total = accept_paused_;
  std::map<std::string, std::size_t> per_peer;
  for (const auto& w : list_) {
    const auto s = w.lock();
    if (s && s->waiting()) {
      ++f.waiting;
      f.waiting_peer_peak = std::max(f.waiting_peer_peak, ++per_peer[s->peer()]);
    }
  }
  for (const auto& w : queue_) {
    const auto s = w.lock();
    f.service_queue += (s && s->queued()) ? 1U : 0U;
  }
  return f;
}

// ------------------------------------------------------------------ session
HttpSession::HttpSession(tcp::socket&& socket, Endpoints& ep, Seat seat, std::string peer)
    : stream_(std::move(socket)),
      ep_(ep),
      seat_(std::move(seat)),
      peer_(std::move(peer)),
      since_(Clock::now()),
      deadline_(stream_.get_executor()),
      wait_(stream_.get_executor()) {}

HttpSession::~HttpSession() {
  if (in_service_) {
    ep_.http.release_service_quietly();  // only when the io_context goes: every other way out has left service
  }
}

WaitingConnection HttpSession::view() const {
  WaitingConnection w;
  w.peer = peer_;
  w.since = since_;
  w.answered = answered_;
  w.silent = !(parser_ && parser_->is_header_done());  // the socket: has_unread(), asked of the chosen one
  return w;
}

bool HttpSession::has_unread() const {
  beast::error_code ec;
  // Bytes waiting unread: its request has come, the gateway has not read it yet.
  return stream_.socket().available(ec) > 0U && !ec;
}

void HttpSession::shed() { say_and_close(busy_answer()); }

void HttpSession::say_and_close(const std::string& raw) {
  done_ = true;
  reading_ = false;
  queued_ = false;
  ++gen_;
  deadline_.cancel();
  wait_.cancel();
  write_and_close(stream_.socket(), raw);  // the pending read ends (aborted) with nothing to do
  seat_.release();
  leave_service();
}

void HttpSession::finish() {
  done_ = true;
  beast::error_code ec;
  stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
}

void HttpSession::do_read(Clock::duration limit) {
  parser_.emplace();
  parser_->header_limit(kHeadLimit);
  parser_->body_limit(kHeadLimit);
  reading_ = true;
  since_ = Clock::now();
  stream_.expires_never();
  const auto gen = ++gen_;
  deadline_.expires_after(limit);
  deadline_.async_wait([self = shared_from_this(), gen](beast::error_code ec) {
    if (!ec && gen == self->gen_ && self->reading_ && !self->done_) {
      if (self->answered_ && !self->parser_->got_some() && self->buffer_.size() == 0U) {
        // A kept-alive connection that never began a next request: closed without a word,
        // as keep-alive ends (a 408 here could be read as the answer to a request its
        // client sends at this very moment).
        self->say_and_close({});
        return;
      }
      self->ep_.http.count_head_timeout();
      self->say_and_close(timeout_answer());
    }
  });
  http::async_read(stream_, buffer_, *parser_, beast::bind_front_handler(&HttpSession::on_read, shared_from_this()));
}

void HttpSession::on_read(beast::error_code ec, std::size_t /*bytes*/) {
  reading_ = false;
  ++gen_;
  deadline_.cancel();
  if (done_) {
    return;  // given away or timed out: answered and closed already
  }
  if (ec == http::error::header_limit || ec == http::error::body_limit) {
    on_too_big(ec);
    return;
  }
  if (ec == http::error::end_of_stream) {
    finish();
    return;
  }
  if (ec) {
    done_ = true;
    return;
  }
  request_complete();
}

// A complete request: a service slot now, or in order of arrival (at most kServiceWait).
void HttpSession::request_complete() {
  answered_ = true;
  if (ep_.http.take_service()) {
    in_service_ = true;
    dispatch();
    return;
  }
  queued_ = true;
  ep_.http.queue_for_service(shared_from_this());
  const auto gen = ++gen_;
  deadline_.expires_after(kServiceWait);
  deadline_.async_wait([self = shared_from_this(), gen](beast::error_code e) {
    if (!e && gen == self->gen_ && self->queued_ && !self->done_) {
      self->queued_ = false;
      self->ep_.http.count_refused();
      HttpAnswer a = text_answer(503, "too many requests at once: try again later\n");
      a.headers.emplace_back("Retry-After", std::to_string(kRetryAfterSeconds));
      self->answer(std::move(a), true);
    }
  });
}

void HttpSession::serve() {
  queued_ = false;
  ++gen_;
  deadline_.cancel();
  in_service_ = true;
  dispatch();
}

void HttpSession::leave_service() {
  if (in_service_) {
    in_service_ = false;
    ep_.http.release_service(stream_.get_executor());
  }
}

void HttpSession::on_too_big(beast::error_code ec) {
  if (ec == http::error::body_limit) {
    answer(text_answer(413, "request body too large\n"), true);
  } else if (parser_->get().target().empty() || parser_->get().target().size() > kUrlLimit) {
    // No target yet: the request line alone did not fit, so it is the URL that is long.
    answer(text_answer(414, "URL too long: at most 2 KiB\n"), true);
  } else {
    answer(text_answer(431, "request head too large: at most 8 KiB\n"), true);
  }
}

void HttpSession::dispatch() {
  const auto& req = parser_->get();
  const std::string_view target(req.target().data(), req.target().size());
  if (target.size() > kUrlLimit) {
    answer(text_answer(414, "URL too long: at most 2 KiB\n"), true);
    return;
  }
  const auto host = req.find(http::field::host);
  const bool has_host = host != req.end();
  if (!ep_.access.host_ok(has_host ? std::string_view(host->value().data(), host->value().size()) : "", has_host)) {
    answer(text_answer(421, "this server does not answer to that Host name (add it with --allow-host)\n"), true);
    return;
  }
  const auto origin = req.find(http::field::origin);
  const bool has_origin = origin != req.end();
  if (!ep_.access.origin_ok(has_origin ? std::string_view(origin->value().data(), origin->value().size()) : "",
                            has_origin)) {
    answer(text_answer(403, "cross-origin request refused (add the origin with --allow-origin)\n"), true);
    return;
  }
  const std::string_view path = target.substr(0, target.find('?'));
  if (ep_.access.needs_bearer(path)) {
    const auto auth = req.find(http::field::authorization);
    if (auth == req.end() || !ep_.access.bearer_ok(std::string_view(auth->value().data(), auth->value().size()))) {
      HttpAnswer a = text_answer(401, "this server listens beyond loopback: send Authorization: Bearer <token>\n");
      a.headers.emplace_back("WWW-Authenticate", "Bearer realm=\"safestate\"");
      answer(std::move(a));
      return;
    }
  }
  if (websocket::is_upgrade(req)) {
    if (path != "/ws") {
      answer(text_answer(404, "not found\n"), true);
      return;
    }
    upgrade_since_ = Clock::now();
    try_upgrade();
    return;
  }
  if (req.method() != http::verb::get) {
    HttpAnswer a = text_answer(405, "only GET\n");
    a.headers.emplace_back("Allow", "GET");
    answer(std::move(a));
    return;
  }
  answer(ep_.hub.http_get(target));
}

// A full lobby makes the upgrade wait: its oldest member gives its slot away once it has
// been silent for kSilentLimit (or leaves it sooner by saying hello), so a newcomer, the
// pendant among a hundred silent squatters too, waits at most about that long. Past
// kLobbyWait (a flood that keeps refilling the lobby with newcomers) the answer is 503.
void HttpSession::try_upgrade() {
  if (ep_.ws.admit()) {
    done_ = true;
    stream_.expires_never();
    auto ws = std::make_shared<WsSession>(stream_.release_socket(), ep_.hub, std::move(seat_));
    ep_.ws.add(ws);
    ws->run(parser_->release());
    leave_service();
    return;
  }
  if (Clock::now() - upgrade_since_ >= kLobbyWait) {
    HttpAnswer a = text_answer(503, "too many WebSocket clients connecting at once: try again later\n");
    a.headers.emplace_back("Retry-After", std::to_string(kRetryAfterSeconds));
    answer(std::move(a), true);
    return;
  }
  wait_.expires_after(kLobbyPoll);
  wait_.async_wait([self = shared_from_this()](beast::error_code ec) {
    if (!ec) {
      self->try_upgrade();
    }
  });
}

void HttpSession::answer(HttpAnswer a, bool close) {
  const unsigned version = parser_->is_header_done() ? parser_->get().version() : 11U;
  res_ = std::make_shared<http::response<http::string_body>>(static_cast<http::status>(a.status), version);
  res_->set(http::field::server, ep_.server);
  res_->set(http::field::content_type, a.content_type);
  res_->set(http::field::cache_control, "no-store");
  for (const auto& [name, value] : a.headers) {
    res_->set(name, value);
  }
  res_->keep_alive(!close && parser_->is_header_done() && parser_->get().keep_alive());
  res_->body() = std::move(a.body);
  res_->prepare_payload();
  stream_.expires_after(30s);
  http::async_write(stream_, *res_, beast::bind_front_handler(&HttpSession::on_write, shared_from_this(), res_->need_eof()));
}

void HttpSession::on_write(bool close, beast::error_code ec, std::size_t /*bytes*/) {
  leave_service();
  if (ec) {
    done_ = true;
    return;
  }
  if (close) {
    finish();
    return;
  }
  res_.reset();
  do_read(kKeepAliveLimit);
}

// ------------------------------------------------------------------ the answers
HttpAnswer Hub::http_get(std::string_view target) {
  const std::size_t q = target.find('?');
  const std::string_view path = target.substr(0, q);
  const std::string_view query = (q == std::string_view::npos) ? std::string_view{} : target.substr(q + 1);
  if (path == "/api/status") {
    read_status();
    return json_answer(200, status_json(status_, extras(), false));
  }
  if (path == "/api/alarms") {
    return json_answer(200, alarms_json(read_status()));
  }
  if (path == "/api/events") {
    return events_answer(query);
  }
  if (path.rfind("/api/events/", 0) == 0) {
    return blackbox_answer(path.substr(12));
  }
  if (path == "/api/robot") {
    return HttpAnswer{200, "application/json", robot_, {}};
  }
  if (path.rfind("/api/robot/meshes/", 0) == 0) {  // only the listed ones, from memory
    for (std::size_t i = 0; i < meshes_.size(); ++i) {
      if (path == mesh_url(i, meshes_[i].ext)) {
        const std::string& e = meshes_[i].ext;
        const char* type = e == "stl" ? "model/stl" : e == "obj" ? "model/obj" : "model/vnd.collada+xml";
        return HttpAnswer{200, type, meshes_[i].bytes, {}};
      }
    }
  }
  if (path == "/api/safety") {
    return safety_answer();
  }
  if (path == "/metrics") {
    return metrics_answer();
  }
  if (path == "/ws") {
    Json j;
    j["error"] = "/ws is a WebSocket endpoint: send an Upgrade request";
    return json_answer(426, j);
  }
  if (path.substr(0, 5) == "/api/" || path == "/api") {
    Json j;
    j["error"] = "not found";
    return json_answer(404, j);
  }
  return static_answer(path);
}

// GET /api/safety: the configuration the core was given (from the segment), whether the
// core holds it validated (status), and the latest confirmation in the log (any checksum).
HttpAnswer Hub::safety_answer() {
  Json j = safety_json();
  if (j.is_null()) {
    Json e;
    e["error"] = "the core's safety configuration is not available to the gateway";
    return json_answer(503, e);
  }
  j["validated"] = read_status().safety.validated;
  Confirmation c;
  bool found = false;
  std::string error;
  if (!latest_confirmation(log_, c, found, error)) {
    Json e;
    e["error"] = "event log: " + error;
    return json_answer(500, e);
  }
  if (found) {
    Json conf;
    conf["checksum"] = c.checksum;
    conf["client"] = c.client;
    conf["time"] = c.time;
    j["confirmation"] = std::move(conf);
  }
  return json_answer(200, j);
}

HttpAnswer Hub::events_answer(std::string_view query) {
  std::int64_t after = 0;
  std::int64_t limit = 100;
  while (!query.empty()) {
    const std::size_t amp = query.find('&');
    const std::string_view pair = query.substr(0, amp);
    query = (amp == std::string_view::npos) ? std::string_view{} : query.substr(amp + 1);
    const std::size_t eq = pair.find('=');
    const std::string_view key = pair.substr(0, eq);
    std::string value;
    const bool decoded =
        percent_decode((eq == std::string_view::npos) ? std::string_view{} : pair.substr(eq + 1), value, true);
    if (key == "after" && (!decoded || !parse_int64(value, after) || after < 0)) {
      return bad_parameter("after", "after must be an event id, an integer >= 0");
    }
    if (key == "limit" && (!decoded || !parse_int64(value, limit) || limit < 1)) {
      return bad_parameter("limit", "limit must be an integer >= 1 (at most 500 are returned)");
    }
  }
  limit = std::min(limit, kMaxPage);
  HttpAnswer a;
  std::string error;
  std::int64_t last = 0;
  std::int64_t rows = 0;
  if (!log_.query_json(after, limit, a.body, last, rows, error)) {
    Json j;
    j["error"] = "event log: " + error;
    return json_answer(500, j);
  }
  if (rows == limit) {
    a.headers.emplace_back("Link", "</api/events?after=" + std::to_string(last) + "&limit=" + std::to_string(limit) +
                                       ">; rel=\"next\"");
    a.headers.emplace_back("X-Next-After", std::to_string(last));
  }
  return a;
}

HttpAnswer Hub::blackbox_answer(std::string_view rest) {
  constexpr std::string_view kSuffix = "/blackbox";
  std::int64_t id = 0;
  if (rest.size() <= kSuffix.size() || rest.substr(rest.size() - kSuffix.size()) != kSuffix ||
      !parse_int64(rest.substr(0, rest.size() - kSuffix.size()), id) || id < 1) {
    Json j;
    j["error"] = "not found: the black box of event ID is /api/events/ID/blackbox";
    return json_answer(404, j);
  }
  HttpAnswer a;
  std::string error;
  bool found = false;
  if (!log_.query_blackbox(id, a.body, found, error)) {
    Json j;
    j["error"] = "event log: " + error;
    return json_answer(500, j);
  }
  if (!found) {
    Json j;
    j["error"] = "event " + std::to_string(id) + " has no black box";
    return json_answer(404, j);
  }
  return a;
}

HttpAnswer Hub::metrics_answer() {
  MetricsExtras x;
  x.ws_clients = clients_.size();
  x.core_heartbeat = segment_.header().core_heartbeat.load(std::memory_order_relaxed);
  x.events_stored = events_stored_;
  x.commands_by_result = commands_by_result_;
  if (connection_figures_) {
    x.connections = connection_figures_();
  }
  return HttpAnswer{200, "text/plain; version=0.0.4; charset=utf-8", metrics_text(segment_.metrics(), x), {}};
}

HttpAnswer Hub::static_answer(std::string_view path) {
  if (path == "/" && !hmi_built(options_.static_dir)) {
    return HttpAnswer{200, "text/html; charset=utf-8", builtin_index_html(options_.version), {}};
  }
  std::string file;
  switch (resolve_static(options_.static_dir, path, file)) {
    case StaticLookup::found: break;
    case StaticLookup::bad_path: return text_answer(400, "bad path\n");
    case StaticLookup::not_found: return text_answer(404, "not found\n");
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    return text_answer(404, "not found\n");
  }
  std::ostringstream body;
  body << in.rdbuf();
  return HttpAnswer{200, mime_type(file), body.str(), {}};
}

}  // namespace safestate::gateway

// Decisions where protocol.md is silent (see also protocol.cpp and views.cpp):
//  - hello: the token is checked first, then the role. A pendant needs the token when
//    the server has one; when the server listens beyond loopback every hello needs it
//    (and without a configured token nobody can say hello: BAD_TOKEN). A refused hello
//    (BAD_TOKEN, ROLE_TAKEN) leaves the connection open and as it was (a connection
//    that had not said hello still has not), so the client may retry, e.g. as an
//    observer. A second hello on the same
//    connection changes its role (a pendant that becomes an observer frees the pendant
//    role). After `welcome` the client gets one status message at once.
//  - A command before hello gets NOT_HELLO. A `sim` message needs no hello: it changes
//    the simulated world, not the robot's control, and is limited to loopback peers.
//    From a non-loopback peer, or when the cell is not simulated, it gets
//    NOT_SIMULATED. With more than kMaxPendingPerClient commands in flight a client
//    gets reply QUEUE_FULL from the gateway (also for sim).
//  - Refused frames (error messages) are counted per client; kMaxBadFrames in a row
//    close the connection after the last error is sent. Any accepted message resets the
//    count.
//  - A pendant that disconnects is not sent a jog_stop: the core's jog keep-alive
//    timeout (SPEC rule 7, jog_timeout_ms) stops the jog and raises JOG_LINK_LOST,
//    which also covers a gateway that dies.
//  - Events are pushed only to clients that said hello; `id` is the SQLite rowid (null
//    if the insert failed). The black box is stored, not pushed: /api/events has it.
//  - /api/events: after >= 0 (default 0), limit 1..1000 (default 100); anything else,
//    or a malformed value, is 400 {"error", "parameter", "detail"}. Other parameters
//    are ignored.
#include "safestate/gateway/hub.hpp"

#include <signal.h>
#include <sys/types.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <vector>

#include "safestate/gateway/static_files.hpp"

namespace safestate::gateway {

namespace {

constexpr std::chrono::seconds kPendingTimeout{30};
constexpr std::size_t kRecentMax = 4096;
constexpr std::size_t kBacklogMax = 2 * bridge::kEventSlots;

bool same_token(const std::string& a, const std::string& b) noexcept {
  if (a.size() != b.size()) {
    return false;
  }
  unsigned diff = 0;  // no early exit: the time does not tell how much matched
  for (std::size_t i = 0; i < a.size(); ++i) {
    diff |= static_cast<unsigned>(static_cast<unsigned char>(a[i]) ^ static_cast<unsigned char>(b[i]));
  }
  return diff == 0U;
}

HttpAnswer json_answer(unsigned status, const Json& j) { return HttpAnswer{status, "application/json", dump(j)}; }

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

Hub::Hub(const GatewayOptions& options, bridge::Segment& segment, EventLog& log, bool loopback_bind)
    : options_(options), segment_(segment), log_(log), loopback_bind_(loopback_bind) {
  // A restarted gateway must not take a reply meant for its predecessor as its own.
  std::random_device rd;
  next_seq_ = static_cast<std::uint32_t>(rd());
  const auto now = Clock::now();
  core_heartbeat_changed_ = now;
  last_sweep_ = now;
  last_error_log_ = now - std::chrono::hours(1);
  robot_ = dump(robot_json());
  parent_at_start_ = ::getppid();
}

// ------------------------------------------------------------------ clients
void Hub::attach(Client& c) {
  c.id = ++next_client_id_;
  clients_[c.id] = &c;
}

void Hub::detach(Client& c) {
  clients_.erase(c.id);
  if (pendant_ == c.id) {
    pendant_ = 0;
  }
}

void Hub::send(Client& c, const Json& message) { c.send(std::make_shared<const std::string>(dump(message)), false); }

void Hub::refuse(Client& c, ErrorCode code, const std::string& detail) {
  send(c, make_error(code, detail));
  if (++c.bad_frames >= kMaxBadFrames) {
    c.close_after_flush();
  }
}

void Hub::on_text(Client& c, std::string_view text) {
  ClientMessage msg = parse_client_message(text);
  if (auto* e = std::get_if<ProtocolError>(&msg)) {
    refuse(c, e->code, e->detail);
  } else if (auto* h = std::get_if<HelloMsg>(&msg)) {
    on_hello(c, *h);
  } else if (auto* m = std::get_if<CommandMsg>(&msg)) {
    on_command(c, *m);
  } else if (auto* s = std::get_if<SimMsg>(&msg)) {
    on_sim(c, *s);
  }
}

void Hub::on_binary(Client& c) { refuse(c, ErrorCode::BAD_MESSAGE, "binary frames are not accepted: send JSON text"); }

void Hub::on_too_large(Client& c, std::size_t bytes) {
  refuse(c, ErrorCode::TOO_LARGE,
         "frame of " + std::to_string(bytes) + " bytes; the limit is " + std::to_string(kMaxFrameBytes));
}

void Hub::on_hello(Client& c, const HelloMsg& h) {
  const bool need_token = !loopback_bind_ || (h.role == Role::pendant && !options_.token.empty());
  if (need_token && (options_.token.empty() || !h.has_token || !same_token(h.token, options_.token))) {
    refuse(c, ErrorCode::BAD_TOKEN,
           options_.token.empty() ? "this server listens beyond loopback and has no token: nobody may connect"
                                  : std::string("a ") + to_string(h.role) + " needs the server's token");
    return;
  }
  if (h.role == Role::pendant && pendant_ != 0 && pendant_ != c.id) {
    refuse(c, ErrorCode::ROLE_TAKEN, "another pendant is connected (single point of control)");
    return;
  }
  if (pendant_ == c.id && h.role != Role::pendant) {
    pendant_ = 0;
  }
  c.hello = true;
  c.role = h.role;
  c.name = h.client;
  c.bad_frames = 0;
  if (h.role == Role::pendant) {
    pendant_ = c.id;
  }
  send(c, make_welcome(h.role, options_.version));
  read_status();
  send(c, status_json(status_, extras(), true));
}

void Hub::on_command(Client& c, const CommandMsg& m) {
  if (!c.hello) {
    refuse(c, ErrorCode::NOT_HELLO, "send hello before commands");
    return;
  }
  c.bad_frames = 0;
  bridge::CommandRecord rec{};
  rec.kind = bridge::RecordKind::command;
  rec.command = m.command;
  rec.command.source = static_cast<std::uint8_t>(source_of(c.role));
  submit(c, rec, m.seq, false, m.name);
}

void Hub::on_sim(Client& c, const SimMsg& m) {
  if (!c.loopback_peer()) {
    refuse(c, ErrorCode::NOT_SIMULATED, "sim messages are accepted only from a loopback client");
    return;
  }
  if (segment_.header().simulated.load(std::memory_order_relaxed) == 0U) {
    refuse(c, ErrorCode::NOT_SIMULATED, "the cell is not simulated");
    return;
  }
  c.bad_frames = 0;
  submit(c, m.record, m.seq, true, {});
}

std::uint32_t Hub::next_seq() {
  do {
    ++next_seq_;
  } while (next_seq_ == 0U || pending_.count(next_seq_) != 0U);  // 0 is the reset button's
  return next_seq_;
}

void Hub::local_reply(Client& c, const Json& client_seq, core::Result r) {
  ++commands_by_result_[static_cast<std::size_t>(r)];
  send(c, make_reply(client_seq, core::to_string(r)));
}

void Hub::submit(Client& c, bridge::CommandRecord record, const Json& client_seq, bool sim, const std::string& name) {
  if (c.pending >= kMaxPendingPerClient) {
    local_reply(c, client_seq, core::Result::QUEUE_FULL);
    return;
  }
  record.seq = next_seq();
  record.command.seq = record.seq;
  if (!segment_.commands().push(record)) {
    local_reply(c, client_seq, core::Result::QUEUE_FULL);
    return;
  }
  ++c.pending;
  pending_[record.seq] = Pending{c.id, client_seq, sim, Clock::now()};
  if (!sim) {
    recent_[record.seq] = Recent{client_seq, name};
    recent_order_.push_back(record.seq);
    while (recent_order_.size() > kRecentMax) {
      recent_.erase(recent_order_.front());
      recent_order_.pop_front();
    }
  }
}

// ------------------------------------------------------------------ from the core
void Hub::poll() {
  auto& h = segment_.header();
  h.gateway_heartbeat.fetch_add(1, std::memory_order_relaxed);
  const auto now = Clock::now();
  const std::uint64_t hb = h.core_heartbeat.load(std::memory_order_relaxed);
  if (hb != core_heartbeat_) {
    core_heartbeat_ = hb;
    core_heartbeat_changed_ = now;
  }
  drain_replies();
  drain_events();
  if (now - last_sweep_ > std::chrono::seconds(1)) {
    sweep_pending(now);
    last_sweep_ = now;
  }
}

void Hub::flush() {
  flushing_ = true;
  drain_replies();
  drain_events();
  flushing_ = false;
}

void Hub::drain_replies() {
  bridge::ReplyRecord r{};
  while (segment_.replies().pop(r)) {
    if (r.kind == bridge::RecordKind::command && static_cast<std::size_t>(r.result) < core::kResultCount) {
      ++commands_by_result_[static_cast<std::size_t>(r.result)];
    }
    const auto it = pending_.find(r.seq);
    if (it == pending_.end()) {
      continue;  // a predecessor's, or timed out
    }
    const Pending p = it->second;
    pending_.erase(it);
    const auto c = clients_.find(p.client);
    if (c == clients_.end()) {
      continue;  // the client has gone
    }
    Client& client = *c->second;
    if (client.pending > 0) {
      --client.pending;
    }
    if (r.kind == bridge::RecordKind::command) {
      send(client, make_reply(p.seq, core::to_string(r.result)));
    } else if (r.sim == bridge::SimResult::ok) {
      send(client, make_reply(p.seq, "OK"));
    } else {
      send(client, make_error(ErrorCode::NOT_SIMULATED, "the cell is not simulated"));
    }
  }
}

bool Hub::blackbox_ready(const bridge::EventRecord& e) {
  if (flushing_) {
    return true;  // the core has stopped cycling: take what the black box has
  }
  // The core writes cycle t's black-box slot at the end of cycle t, possibly after the
  // event: wait until a later cycle has run (or give up after kBlackBoxWait and mark
  // what is missing).
  const std::uint64_t hb = segment_.header().core_heartbeat.load(std::memory_order_acquire);
  if (hb >= e.t + 2) {
    return true;
  }
  const auto now = Clock::now();
  if (!blackbox_wait_since_) {
    blackbox_wait_since_ = now;
  }
  return now - *blackbox_wait_since_ >= kBlackBoxWait;
}

void Hub::drain_events() {
  bridge::EventRecord e{};
  while (backlog_.size() < kBacklogMax && segment_.events().pop(e)) {
    backlog_.push_back(e);
  }
  if (backlog_.empty()) {
    return;
  }
  const std::string time = iso8601_utc(std::chrono::system_clock::now());
  bool began = false;
  while (!backlog_.empty()) {
    const bridge::EventRecord& front = backlog_.front();
    std::string blackbox;
    if (needs_blackbox(front)) {
      if (!blackbox_ready(front)) {
        break;
      }
      blackbox = dump(blackbox_json(segment_.blackbox(), front.t));
    }
    blackbox_wait_since_.reset();
    if (!began) {
      began = log_.begin();
      if (!began) {
        log_error("event log: cannot begin a transaction: " + log_.last_error());
      }
    }
    store_and_push(front, time, blackbox);
    backlog_.pop_front();
  }
  if (began && !log_.commit()) {
    log_error("event log: commit failed: " + log_.last_error());
  }
}

void Hub::store_and_push(const bridge::EventRecord& e, const std::string& time, const std::string& blackbox) {
  Json seq = nullptr;
  std::string name;
  if (e.kind == bridge::EventKind::command && e.reply.seq != 0U) {
    if (const auto it = recent_.find(e.reply.seq); it != recent_.end()) {
      seq = it->second.seq;
      name = it->second.name;
      recent_.erase(it);
    }
  }
  const char* kind = kind_name(e.kind);
  const Json data = event_data(e, name, seq);
  const std::int64_t id = log_.insert(e.t, time, kind, dump(data), blackbox);
  if (id < 0) {
    log_error("event log: insert failed: " + log_.last_error());
  } else {
    ++events_stored_;
  }
  broadcast(std::make_shared<const std::string>(dump(event_message(id, e.t, time, kind, data))), false);
}

void Hub::broadcast(const Frame& frame, bool droppable) {
  std::vector<Client*> targets;  // a send may close a client: not while iterating clients_
  targets.reserve(clients_.size());
  for (const auto& [id, c] : clients_) {
    if (c->hello) {
      targets.push_back(c);
    }
  }
  for (Client* c : targets) {
    c->send(frame, droppable);
  }
}

void Hub::sweep_pending(Clock::time_point now) {
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (now - it->second.since < kPendingTimeout) {
      ++it;
      continue;
    }
    if (const auto c = clients_.find(it->second.client); c != clients_.end() && c->second->pending > 0) {
      --c->second->pending;
    }
    it = pending_.erase(it);
  }
}

void Hub::log_error(const std::string& what) {
  const auto now = Clock::now();
  if (now - last_error_log_ >= std::chrono::seconds(5)) {
    std::fprintf(stderr, "safestate gateway: %s\n", what.c_str());
    last_error_log_ = now;
  }
}

// ------------------------------------------------------------------ status
const bridge::Status& Hub::read_status() {
  bridge::Status s{};
  if (segment_.status().read(s)) {
    status_ = s;
  }
  return status_;
}

StatusExtras Hub::extras() const {
  bool remote = false;
  for (const auto& [id, c] : clients_) {
    remote = remote || (c->hello && c->role == Role::remote);
  }
  const auto& h = segment_.header();
  StatusExtras x;
  x.owner = owner_of(status_.mode, remote, pendant_ != 0);
  x.simulated = h.simulated.load(std::memory_order_relaxed) != 0U;
  x.core_heartbeat = core_heartbeat_;
  x.gateway_heartbeat = h.gateway_heartbeat.load(std::memory_order_relaxed);
  x.core_heartbeat_age_ms =
      std::chrono::duration<double, std::milli>(Clock::now() - core_heartbeat_changed_).count();
  x.core_pid = h.core_pid.load(std::memory_order_relaxed);
  x.shutting_down = h.shutting_down.load(std::memory_order_relaxed) != 0U;
  x.gateway_pid = h.gateway_pid.load(std::memory_order_relaxed);
  return x;
}

void Hub::broadcast_status() {
  read_status();
  broadcast(std::make_shared<const std::string>(dump(status_json(status_, extras(), true))), true);
}

// The core process is gone when it no longer exists or is a zombie (its parent has not
// reaped it yet), or, for a gateway the core started, when the gateway has been
// re-parented: a core killed with SIGKILL leaves no other trace. A core that is shutting
// down is still running: its last events (the Cat 1 stop of `safestate run`) are still
// to be logged, and it stops the gateway with SIGTERM when it is done.
bool Hub::core_gone() const {
  const auto pid = static_cast<pid_t>(segment_.header().core_pid.load(std::memory_order_relaxed));
  if (pid <= 0) {
    return false;
  }
  if (parent_at_start_ == pid && ::getppid() != pid) {
    return true;
  }
  if (::kill(pid, 0) != 0 && errno == ESRCH) {
    return true;
  }
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (std::getline(stat, line)) {
    const std::size_t paren = line.rfind(')');
    return paren != std::string::npos && paren + 2 < line.size() && line[paren + 2] == 'Z';
  }
  return false;
}

// ------------------------------------------------------------------ HTTP
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
  if (path == "/api/robot") {
    return HttpAnswer{200, "application/json", robot_};
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
    if (key == "limit" && (!decoded || !parse_int64(value, limit) || limit < 1 || limit > 1000)) {
      return bad_parameter("limit", "limit must be an integer from 1 to 1000");
    }
  }
  HttpAnswer a;
  std::string error;
  if (!log_.query_json(after, limit, a.body, error)) {
    Json j;
    j["error"] = "event log: " + error;
    return json_answer(500, j);
  }
  return a;
}

HttpAnswer Hub::metrics_answer() {
  MetricsExtras x;
  x.ws_clients = clients_.size();
  x.core_heartbeat = segment_.header().core_heartbeat.load(std::memory_order_relaxed);
  x.events_stored = events_stored_;
  x.commands_by_result = commands_by_result_;
  return HttpAnswer{200, "text/plain; version=0.0.4; charset=utf-8", metrics_text(segment_.metrics(), x)};
}

HttpAnswer Hub::static_answer(std::string_view path) {
  if (path == "/" && !hmi_built(options_.static_dir)) {
    return HttpAnswer{200, "text/html; charset=utf-8", builtin_index_html(options_.version)};
  }
  std::string file;
  switch (resolve_static(options_.static_dir, path, file)) {
    case StaticLookup::found: break;
    case StaticLookup::bad_path: return HttpAnswer{400, "text/plain; charset=utf-8", "bad path\n"};
    case StaticLookup::not_found: return HttpAnswer{404, "text/plain; charset=utf-8", "not found\n"};
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    return HttpAnswer{404, "text/plain; charset=utf-8", "not found\n"};
  }
  std::ostringstream body;
  body << in.rdbuf();
  return HttpAnswer{200, mime_type(file), body.str()};
}

}  // namespace safestate::gateway

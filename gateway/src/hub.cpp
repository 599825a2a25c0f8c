// The hub's side towards the core: the gateway heartbeat, replies back to the clients
// that sent the commands, events into the event log and then to every client, the
// status broadcast, and whether the core still lives. Client messages: messages.cpp;
// HTTP answers: http_endpoints.cpp.
//
// Decisions where protocol.md is silent:
//  - Events are taken from the core's ring without removing them (peek), written to the
//    log in one transaction together with how far the ring has been logged, and only
//    after the commit is the ring's tail advanced and the event pushed to the clients
//    (protocol.md "Nothing lost"). A gateway that restarts skips what its predecessor
//    committed (the ring_progress row of this segment instance): nothing lost, nothing
//    twice.
//  - Events are pushed only to clients that said hello; `id` is the SQLite rowid (null
//    if the insert failed). The black box is stored, not pushed: /api/events/ID/blackbox.
//  - A pendant that disconnects is not sent a jog_stop: the core's jog keep-alive
//    timeout (SPEC rule 7, jog_timeout_ms) stops the jog and raises JOG_LINK_LOST,
//    which also covers a gateway that dies.
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
// Events logged per poll at most: one transaction stays short.
constexpr std::uint64_t kEventsPerPoll = 1024;

}  // namespace

Hub::Hub(const GatewayOptions& options, bridge::Segment& segment, EventLog& log, EventWriter& writer,
         bool loopback_bind)
    : options_(options),
      segment_(segment),
      log_(log),
      writer_(writer),
      loopback_bind_(loopback_bind),
      access_(options, loopback_bind) {
  // A restarted gateway must not take a reply meant for its predecessor as its own.
  std::random_device rd;
  next_seq_ = static_cast<std::uint32_t>(rd());
  const auto now = Clock::now();
  core_heartbeat_changed_ = now;
  last_sweep_ = now;
  last_error_log_ = now - std::chrono::hours(1);
  {
    // The meshes the URDF names, from its own package folder only: listed in /api/robot
    // (url by index), the refused ones with the reason (the HMI then draws simple shapes).
    robot::Meshes m = robot::read_visual_meshes(robot::active());
    Json rj = robot_json();
    Json served = Json::array();
    for (std::size_t i = 0; i < m.files.size(); ++i) {
      Json e;
      e["uri"] = m.files[i].uri;
      e["url"] = mesh_url(i, m.files[i].ext);
      served.push_back(std::move(e));
    }
    Json refused = Json::array();
    for (const robot::MeshRefusal& r : m.refused) {
      Json e;
      e["uri"] = r.uri;
      e["why"] = r.why;
      refused.push_back(std::move(e));
      std::string line = r.uri + ": " + r.why;  // from the URDF: no control characters into the log
      for (char& c : line) {
        if (static_cast<unsigned char>(c) < 0x20U || c == 0x7F) c = '?';
      }
      std::fprintf(stderr, "safestate gateway: robot mesh not served (the HMI draws simple shapes): %s\n", line.c_str());
    }
    rj["meshes"] = std::move(served);
    rj["meshes_refused"] = std::move(refused);
    robot_ = dump(rj);
    meshes_ = std::move(m.files);
  }
  parent_at_start_ = ::getppid();
  // What a predecessor already committed stays committed: start after it.
  auto& h = segment_.header();
  segment_.events().advance_to(log_.ring_progress(h.instance));
  // The latest brake test on record, for the status; an unreadable log shows none.
  std::string time;
  std::string data;
  bool found = false;
  std::string error;
  if (!log_.latest("brake_test", time, data, found, error)) {
    log_error("event log: the latest brake test cannot be read: " + error);
  } else if (found) {
    brake_test_record_ = brake_test_record(time, Json::parse(data, nullptr, false));
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
  if (now - last_sweep_ > std::chrono::seconds(1)) {
    sweep_pending(now);
    last_sweep_ = now;
  }
}

void Hub::poll_events() { drain_events(); }

void Hub::flush() {
  flushing_ = true;
  drain_replies();
  auto& ring = segment_.events();
  for (;;) {
    const std::size_t left = ring.size();
    drain_events();
    writer_.wait_idle();
    collect_log();
    if (ring.size() == 0U || ring.size() >= left) {
      break;  // all logged, or the log refuses: nothing more to gain
    }
  }
  flushing_ = false;
}

namespace {

// @req COL-SIM-PERSON
// A `sim` record the runtime refused, as the `error` the client gets (nothing changed).
Json sim_refusal(bridge::SimResult r) {
  switch (r) {
    case bridge::SimResult::person_absent:
      return make_error(ErrorCode::BAD_MESSAGE,
                        "person: no person in the cell to walk, stand or leave (send {\"at\": [X, Y]} first)");
    case bridge::SimResult::person_invalid:
      return make_error(ErrorCode::BAD_MESSAGE, "person: the simulated cell refused the values (nothing changed)");
    case bridge::SimResult::person_not_on_bus:
      return make_error(ErrorCode::NOT_SIMULATED,
                        "the simulated person is not on the fieldbus: over EtherCAT, ecat-sim's person moves by "
                        "its control socket's `person` lines (as a replay sends them), not by the sim message");
    case bridge::SimResult::ok:
    case bridge::SimResult::not_simulated: break;
  }
  return make_error(ErrorCode::NOT_SIMULATED, "the cell is not simulated");
}

}  // namespace

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
    if (c != clients_.end() && c->second->pending > 0) {
      --c->second->pending;
    }
    if (p.validate && r.kind == bridge::RecordKind::command && r.result == core::Result::OK) {
      log_confirmation(p, r.t);  // the reply follows the commit: whoever sees OK finds it in the log
      continue;
    }
    if (c == clients_.end()) {
      continue;  // the client has gone
    }
    Client& client = *c->second;
    if (r.kind == bridge::RecordKind::command) {
      send(client, make_reply(p.seq, core::to_string(r.result)));
    } else if (r.sim == bridge::SimResult::ok) {
      send(client, make_reply(p.seq, "OK"));
    } else {
      send(client, sim_refusal(r.sim));
    }
  }
}

// SPEC §10: the core has taken the operator's validate_config. The confirmation is kept in
// the event log with the client and the time, and found again by the next `safestate run`
// (latest_confirmation): written in its own transaction (synchronous=FULL), and only once it
// is on disk are the reply OK sent and the event pushed (collect_log). A gateway that dies
// before the commit loses the confirmation and never said OK: the next start is then not
// validated, the safe side.
// @req LIM-PERSIST
void Hub::log_confirmation(const Pending& p, std::uint64_t t) {
  std::array<char, 16> hex{};
  std::snprintf(hex.data(), hex.size(), "%08X", p.code);
  Json data;
  data["checksum"] = hex.data();
  data["client"] = p.client_name;
  data["role"] = to_string(p.role);
  const std::string time = iso8601_utc(std::chrono::system_clock::now());
  LogBatch batch;
  batch.rows.push_back(LogRow{t, time, "config_validated", dump(data), {}});
  Submitted sub;
  sub.data.push_back(std::move(data));
  sub.reply = true;
  sub.reply_client = p.client;
  sub.reply_seq = p.seq;
  submitted_.push_back(std::move(sub));
  writer_.submit(std::move(batch));
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

// Events are peeked behind what has already been handed to the writer; the ring's tail
// moves only when their batch comes back committed (collect_log).
void Hub::drain_events() {
  auto& ring = segment_.events();
  LogBatch batch;
  Submitted sub;
  std::uint64_t taken = 0;
  bridge::EventRecord e{};
  std::string time;
  while (taken < kEventsPerPoll && ring.peek(ring_submitted_ + taken, e)) {
    std::string blackbox;
    if (needs_blackbox(e)) {
      if (!blackbox_ready(e)) {
        break;
      }
      blackbox = dump(blackbox_json(segment_.blackbox(), e.t));
    }
    blackbox_wait_since_.reset();
    if (time.empty()) {
      time = iso8601_utc(std::chrono::system_clock::now());
    }
    record(e, time, std::move(blackbox), batch, sub);
    ++taken;
  }
  if (taken == 0U) {
    return;
  }
  ring_submitted_ += taken;
  batch.ring = true;
  batch.instance = segment_.header().instance;
  batch.tail = ring.tail.load(std::memory_order_relaxed) + ring_submitted_;
  sub.ring_events = taken;
  submitted_.push_back(std::move(sub));
  writer_.submit(std::move(batch));
}

void Hub::record(const bridge::EventRecord& e, const std::string& time, std::string blackbox, LogBatch& batch,
                 Submitted& sub) {
  Json seq = nullptr;
  std::string name;
  if (e.kind == bridge::EventKind::command && e.reply.seq != 0U) {
    if (const auto it = recent_.find(e.reply.seq); it != recent_.end()) {
      seq = it->second.seq;
      name = it->second.name;
      recent_.erase(it);
    }
  }
  Json data = event_data(e, name, seq);
  batch.rows.push_back(LogRow{e.t, time, kind_name(e.kind), dump(data), std::move(blackbox)});
  sub.data.push_back(std::move(data));
}

void Hub::collect_log() {
  for (LogBatch& b : writer_.take_done()) {
    if (submitted_.empty()) {
      break;  // cannot happen: every batch is recorded before it is submitted
    }
    Submitted s = std::move(submitted_.front());
    submitted_.pop_front();
    if (!b.error.empty()) {
      log_error("event log: " + b.error);
    }
    if (b.commit_ms > 50.0) {
      // On the writer's thread: no client waited for it, but the events reached them late.
      log_error("event log: a commit took " + std::to_string(static_cast<int>(b.commit_ms)) + " ms");
    }
    if (s.ring_events > 0U) {
      segment_.events().advance(s.ring_events);  // only now may the core reuse these slots
      ring_submitted_ -= s.ring_events;
    }
    for (std::size_t i = 0; i < b.rows.size(); ++i) {  // the writer gave every row its id (-1: not stored)
      const LogRow& row = b.rows[i];
      const std::int64_t id = b.ids[i];
      if (id >= 0) {
        ++events_stored_;
      }
      if (row.kind == kind_name(bridge::EventKind::brake_test)) {
        brake_test_record_ = brake_test_record(row.time, s.data[i]);
      }
      broadcast_event(std::make_shared<const std::string>(dump(event_message(id, row.t, row.time, row.kind.c_str(), s.data[i]))));
    }
    if (s.reply) {
      if (const auto c = clients_.find(s.reply_client); c != clients_.end()) {
        send(*c->second, make_reply(s.reply_seq, core::to_string(core::Result::OK)));
      }
    }
  }
}

void Hub::broadcast(const Frame& frame, const std::function<std::optional<Delivery>(Client&)>& how) {
  std::vector<std::pair<Client*, Delivery>> targets;  // a send may close a client: not while iterating clients_
  targets.reserve(clients_.size());
  for (const auto& [id, c] : clients_) {
    if (!c->hello) {
      continue;
    }
    if (const std::optional<Delivery> d = how(*c)) {
      targets.emplace_back(c, *d);
    }
  }
  for (const auto& [c, d] : targets) {
    c->send(frame, d);
  }
}

void Hub::broadcast_event(const Frame& frame) {
  broadcast(frame, [](Client& c) -> std::optional<Delivery> {
    return c.role == Role::observer ? Delivery::with_status : Delivery::at_once;
  });
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
  x.gateway_restarts = h.gateway_restarts.load(std::memory_order_relaxed);
  x.brake_test_record = &brake_test_record_;
  return x;
}

void Hub::broadcast_status() {
  read_status();
  const auto frame = std::make_shared<const std::string>(dump(status_json(status_, extras(), true)));
  const auto now = Clock::now();
  broadcast(frame, [&](Client& c) -> std::optional<Delivery> {
    // The same snapshot again within a period (the hello's status just before this tick)
    // tells the client nothing; a stalled core's snapshot is still repeated every period,
    // with the gateway's own fields (core_heartbeat_age_ms) moving on.
    if (c.status_t == status_.t && now - c.status_at < kStatusPeriod) {
      return std::nullopt;
    }
    c.status_t = status_.t;
    c.status_at = now;
    return Delivery::status;
  });
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

}  // namespace safestate::gateway

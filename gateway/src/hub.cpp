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

Hub::Hub(const GatewayOptions& options, bridge::Segment& segment, EventLog& log, bool loopback_bind)
    : options_(options), segment_(segment), log_(log), loopback_bind_(loopback_bind), access_(options, loopback_bind) {
  // A restarted gateway must not take a reply meant for its predecessor as its own.
  std::random_device rd;
  next_seq_ = static_cast<std::uint32_t>(rd());
  const auto now = Clock::now();
  core_heartbeat_changed_ = now;
  last_sweep_ = now;
  last_error_log_ = now - std::chrono::hours(1);
  robot_ = dump(robot_json());
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
  std::size_t left = segment_.events().size();
  while (left > 0U) {
    drain_events();
    const std::size_t now_left = segment_.events().size();
    if (now_left >= left) {
      break;  // the log refuses: nothing more to gain
    }
    left = now_left;
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
                        "the simulated person is not on the fieldbus: an emulated EtherCAT segment has no person "
                        "(only the in-process simulated cell, --fieldbus sim, has one)");
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
    if (p.validate && r.kind == bridge::RecordKind::command && r.result == core::Result::OK) {
      log_confirmation(p, r.t);  // before the reply: whoever sees OK finds it in the log
    }
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
      send(client, sim_refusal(r.sim));
    }
  }
}

// SPEC §10: the core has taken the operator's validate_config. The confirmation is kept in
// the event log with the client and the time, and found again by the next `safestate run`
// (latest_confirmation). Written at once, in its own transaction (synchronous=FULL: on disk
// when insert returns), then pushed like every event. A gateway that dies before this line
// loses the confirmation: the next start is then not validated, the safe side.
// @req LIM-PERSIST
void Hub::log_confirmation(const Pending& p, std::uint64_t t) {
  std::array<char, 16> hex{};
  std::snprintf(hex.data(), hex.size(), "%08X", p.code);
  Json data;
  data["checksum"] = hex.data();
  data["client"] = p.client_name;
  data["role"] = to_string(p.role);
  const std::string time = iso8601_utc(std::chrono::system_clock::now());
  const std::int64_t id = log_.insert(t, time, "config_validated", dump(data), {});
  if (id < 0) {
    log_error("event log: the config_validated event could not be written: " + log_.last_error());
  } else {
    ++events_stored_;
  }
  broadcast(std::make_shared<const std::string>(dump(event_message(id, t, time, "config_validated", data))), false);
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
  auto& ring = segment_.events();
  std::vector<Frame> frames;
  std::uint64_t taken = 0;
  bridge::EventRecord e{};
  std::string time;
  bool began = false;
  while (taken < kEventsPerPoll && ring.peek(taken, e)) {
    std::string blackbox;
    if (needs_blackbox(e)) {
      if (!blackbox_ready(e)) {
        break;
      }
      blackbox = dump(blackbox_json(segment_.blackbox(), e.t));
    }
    blackbox_wait_since_.reset();
    if (!began) {
      time = iso8601_utc(std::chrono::system_clock::now());
      began = log_.begin();
      if (!began) {
        log_error("event log: cannot begin a transaction: " + log_.last_error());
      }
    }
    frames.push_back(store(e, time, blackbox));
    ++taken;
  }
  if (taken == 0U) {
    return;
  }
  const std::uint64_t tail = ring.tail.load(std::memory_order_relaxed) + taken;
  const auto commit_start = Clock::now();
  if (began && (!log_.set_ring_progress(segment_.header().instance, tail) || !log_.commit())) {
    log_error("event log: commit failed: " + log_.last_error());
  }
  const auto commit_ms = std::chrono::duration<double, std::milli>(Clock::now() - commit_start).count();
  if (commit_ms > 50.0) {
    // The commit (fsync) runs on the one I/O thread: a slow disk delays every client.
    log_error("event log: a commit took " + std::to_string(static_cast<int>(commit_ms)) + " ms");
  }
  ring.advance(taken);  // only now may the core reuse these slots
  for (const Frame& f : frames) {
    broadcast(f, false);
  }
}

Frame Hub::store(const bridge::EventRecord& e, const std::string& time, const std::string& blackbox) {
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
  if (e.kind == bridge::EventKind::brake_test) {
    brake_test_record_ = brake_test_record(time, data);
  }
  return std::make_shared<const std::string>(dump(event_message(id, e.t, time, kind, data)));
}

void Hub::broadcast(const Frame& frame, bool droppable, const std::function<bool(Client&)>& take) {
  std::vector<Client*> targets;  // a send may close a client: not while iterating clients_
  targets.reserve(clients_.size());
  for (const auto& [id, c] : clients_) {
    if (c->hello && (!take || take(*c))) {
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
  x.gateway_restarts = h.gateway_restarts.load(std::memory_order_relaxed);
  x.brake_test_record = &brake_test_record_;
  return x;
}

void Hub::broadcast_status() {
  read_status();
  const auto frame = std::make_shared<const std::string>(dump(status_json(status_, extras(), true)));
  const auto now = Clock::now();
  broadcast(frame, true, [&](Client& c) {
    // The same snapshot again within a period (the hello's status just before this tick)
    // tells the client nothing; a stalled core's snapshot is still repeated every period,
    // with the gateway's own fields (core_heartbeat_age_ms) moving on.
    if (c.status_t == status_.t && now - c.status_at < kStatusPeriod) {
      return false;
    }
    c.status_t = status_.t;
    c.status_at = now;
    return true;
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

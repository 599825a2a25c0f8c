// The gateway's logic, between the transport (Beast sessions) and the core (the
// shared-memory bridge): roles, commands and their replies, sim messages, the event
// log and its pushes, the status broadcast and the HTTP answers. Single-threaded: every
// call comes from the one io_context thread. No network code here, so that the
// behaviour of protocol.md can be read (and tested) without sockets.
#pragma once

#include "safestate/gateway/bridge.hpp"

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "safestate/gateway/admission.hpp"
#include "safestate/gateway/event_log.hpp"
#include "safestate/gateway/event_writer.hpp"
#include "safestate/gateway/gateway.hpp"
#include "safestate/gateway/protocol.hpp"
#include "safestate/gateway/views.hpp"
#include "safestate/robot/meshes.hpp"

namespace safestate::gateway {

using Clock = std::chrono::steady_clock;
using Frame = std::shared_ptr<const std::string>;

// A client may have this many commands in flight; more get QUEUE_FULL from the gateway
// (one client cannot fill the core's ring for everybody else).
inline constexpr std::size_t kMaxPendingPerClient = 64;
// ... and put at most this many records per second on the ring, sustained (a token
// bucket of kMaxPendingPerClient): more get QUEUE_FULL from the gateway. Far above what
// a pendant (jog keep-alive at 25 Hz) or a PLC needs; it keeps one client from flooding
// the core's command stream and every other client with command events (protocol.md
// "Fairness").
inline constexpr double kMaxRecordsPerSecond = 250.0;
// Consecutive refused frames after which a client is disconnected.
inline constexpr unsigned kMaxBadFrames = 32;
// Commands remembered for their command events (client seq and name).
inline constexpr std::size_t kRecentMax = 4096;
// A stopping transition waits at most this long for its black-box cycles to be written.
inline constexpr std::chrono::milliseconds kBlackBoxWait{200};
// Status is broadcast every kStatusPeriod; a client that got the same core snapshot less
// than that ago (its hello's status, just before the tick) is not sent it twice.
inline constexpr std::chrono::milliseconds kStatusPeriod{20};

// How soon a frame goes out (every frame but a replaced status is delivered).
enum class Delivery : std::uint8_t {
  // Written once the current handler is done, together with whatever else it queued:
  // replies, errors, the welcome, events to the client that controls the robot.
  at_once,
  // Queued, written with the client's next write: its next status at the latest, so at
  // most one kStatusPeriod later. Events to observers: a burst of command events then costs
  // one system call per observer and status period, not one per poll (protocol.md
  // "Fairness": status is never starved by events, and on two cores the writes are the
  // gateway's cost).
  with_status,
  // The status: replaces an older one not yet written (a client that is behind skips
  // one), written at once.
  status,
};

// One WebSocket connection as the hub sees it; the transport does the I/O.
class Client {
 public:
  Client() = default;
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;
  virtual ~Client() = default;
  // Queues a text frame (see Delivery); a client too far behind on the frames that are
  // all delivered is disconnected.
  virtual void send(const Frame& frame, Delivery delivery) = 0;
  // Closes once the queued frames are written. Neither call may detach the client
  // synchronously: the hub may be iterating over its clients.
  virtual void close_after_flush() = 0;
  // The same with close code 1013 "try again later": refused for lack of a slot.
  virtual void close_try_again_later() = 0;
  [[nodiscard]] virtual bool loopback_peer() const = 0;

  // Session state, kept by the hub.
  std::uint64_t id = 0;
  bool hello = false;
  Role role = Role::observer;
  std::string name;
  std::size_t pending = 0;
  unsigned bad_frames = 0;
  // Refused commands (what the role may not send) in the current one-second window;
  // beyond kMaxRefusedPerSecond the transport stops reading the client until then.
  Clock::time_point refused_window{};
  unsigned refused = 0;
  Clock::time_point hold_reads_until{};
  double bucket = static_cast<double>(kMaxPendingPerClient);  // records it may still submit now
  Clock::time_point bucket_at{};
  // The core cycle of the last status sent and when (see kStatusPeriod).
  std::uint64_t status_t = 0;
  Clock::time_point status_at{};
};

// Commands the gateway refuses itself (an observer's), per client and second, before
// its socket is left unread for the rest of the second (protocol.md "Fairness").
inline constexpr unsigned kMaxRefusedPerSecond = 200;

struct HttpAnswer {
  unsigned status = 200;
  std::string content_type = "application/json";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;
};

class Hub {
 public:
  // `log` is the I/O thread's own (read) connection; `writer` writes the events.
  Hub(const GatewayOptions& options, bridge::Segment& segment, EventLog& log, EventWriter& writer, bool loopback_bind);

  void attach(Client& c);
  void detach(Client& c);
  void on_text(Client& c, std::string_view text);
  void on_binary(Client& c);
  void on_too_large(Client& c, std::size_t bytes);
  void on_hello_timeout(Client& c);

  // Every poll: gateway heartbeat, replies to their clients; then (poll_events, run
  // after the replies' writes have started) events to the log and to every client.
  void poll();
  void poll_events();
  // The event log's writer has written batches: advance the core's ring past their
  // events, push them to the clients, answer a validate_config.
  void collect_log();
  // Commands sent to the core and not yet answered (the poll loop then wakes at the
  // core's next cycle boundary instead of its idle period).
  [[nodiscard]] bool awaiting_core() const noexcept { return !pending_.empty(); }
  [[nodiscard]] const Access& access() const noexcept { return access_; }
  // Called after a record has been put on the core's ring (the poller wakes early).
  void on_submit(std::function<void()> fn) { on_submit_ = std::move(fn); }
  // The status message to every client that said hello (50 Hz).
  void broadcast_status();
  // At exit: every reply and event still in the rings, without waiting for black-box
  // cycles (missing ones are marked).
  void flush();
  // GET `target` (path and query).
  HttpAnswer http_get(std::string_view target);
  // Where /metrics finds the connections and their bounds (the transport's).
  void connection_figures(std::function<ConnectionFigures()> fn) { connection_figures_ = std::move(fn); }

  // The core's process has died (SIGKILL, crash): the gateway has nothing to serve.
  [[nodiscard]] bool core_gone() const;
  [[nodiscard]] std::size_t clients() const noexcept { return clients_.size(); }

 private:
  struct Pending {
    std::uint64_t client = 0;
    Json seq;
    bool sim = false;
    Clock::time_point since;
    // validate_config: what the core is asked to confirm and by whom, for the
    // config_validated event written on its OK (the client may be gone by then).
    bool validate = false;
    std::uint32_t code = 0;
    std::string client_name;
    Role role = Role::observer;
  };
  struct Recent {
    Json seq;
    std::string name;
  };
  // A batch handed to the event log's writer, as the I/O thread needs it back beside the
  // batch itself (its rows: t, time, kind): how many of the ring's events it holds, each
  // row's data as JSON (for the pushed message, not parsed again), and the reply that waits
  // for its commit (validate_config: whoever sees OK finds the confirmation in the log).
  struct Submitted {
    std::uint64_t ring_events = 0;
    std::vector<Json> data;
    bool reply = false;
    std::uint64_t reply_client = 0;
    Json reply_seq;
  };

  void refuse(Client& c, ErrorCode code, const std::string& detail);
  void send(Client& c, const Json& message);
  // To every client past its hello, as `how` says for that client (nullopt: not to it).
  void broadcast(const Frame& frame, const std::function<std::optional<Delivery>(Client&)>& how);
  // An event to every client past its hello: at once to the pendant and a remote client,
  // with their next status to observers.
  void broadcast_event(const Frame& frame);
  void on_hello(Client& c, const HelloMsg& h);
  void on_command(Client& c, const CommandMsg& m);
  void on_sim(Client& c, const SimMsg& m);
  void submit(Client& c, bridge::CommandRecord record, const Json& client_seq, bool sim, const std::string& name);
  void local_reply(Client& c, const Json& client_seq, core::Result r);
  void refuse_command(Client& c, const Json& client_seq);
  bool take_token(Client& c);
  [[nodiscard]] std::size_t hello_others() const;
  std::uint32_t next_seq();
  void drain_replies();
  void drain_events();
  bool blackbox_ready(const bridge::EventRecord& e);
  void record(const bridge::EventRecord& e, const std::string& time, std::string blackbox, LogBatch& batch,
              Submitted& sub);
  void sweep_pending(Clock::time_point now);
  const bridge::Status& read_status();
  StatusExtras extras() const;
  void log_confirmation(const Pending& p, std::uint64_t t);
  HttpAnswer safety_answer();
  HttpAnswer events_answer(std::string_view query);
  HttpAnswer blackbox_answer(std::string_view rest);
  HttpAnswer metrics_answer();
  HttpAnswer static_answer(std::string_view path);
  void log_error(const std::string& what);

  GatewayOptions options_;
  std::function<ConnectionFigures()> connection_figures_;
  bridge::Segment& segment_;
  EventLog& log_;
  EventWriter& writer_;
  std::deque<Submitted> submitted_;    // in the writer's order
  std::uint64_t ring_submitted_ = 0;  // ring events handed to the writer, the ring not yet advanced
  bool loopback_bind_;
  Access access_;

  std::unordered_map<std::uint64_t, Client*> clients_;
  std::uint64_t next_client_id_ = 0;
  std::uint64_t pendant_ = 0;  // client id holding the pendant role, 0 = none

  std::uint32_t next_seq_ = 0;
  std::unordered_map<std::uint32_t, Pending> pending_;
  std::unordered_map<std::uint32_t, Recent> recent_;  // for the command events
  std::deque<std::uint32_t> recent_order_;

  std::optional<Clock::time_point> blackbox_wait_since_;

  bridge::Status status_{};
  std::uint64_t core_heartbeat_ = 0;
  Clock::time_point core_heartbeat_changed_;
  Clock::time_point last_sweep_;
  Clock::time_point last_error_log_;

  std::array<std::uint64_t, core::kResultCount> commands_by_result_{};
  std::uint64_t events_stored_ = 0;
  // SPEC §12: the latest brake test on record (brake_test_record(); null: none), read from
  // the log at start and kept as brake_test events are stored; shown in the status.
  Json brake_test_record_;
  std::string robot_;  // GET /api/robot never changes
  // GET /api/robot/meshes/N.EXT: the description's visual meshes, read once at start from its
  // own package folder (robot/include/safestate/robot/meshes.hpp); never written.
  std::vector<robot::MeshFile> meshes_;
  int parent_at_start_ = 0;
  bool flushing_ = false;
  std::function<void()> on_submit_;
};

}  // namespace safestate::gateway

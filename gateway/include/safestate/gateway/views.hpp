// What the gateway shows: the JSON of status, alarms, events, black box and robot, and
// the Prometheus text of /metrics, built from the bridge's binary records. Pure
// functions of their inputs (no network, no database), so each can be tested alone.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <string>

#include "safestate/gateway/bridge.hpp"
#include "safestate/gateway/protocol.hpp"

namespace safestate::gateway {

// What the status message shows beyond the core's snapshot.
struct StatusExtras {
  const char* owner = nullptr;  // null when nobody may command
  bool simulated = false;       // header().simulated
  std::uint64_t core_heartbeat = 0;
  std::uint64_t gateway_heartbeat = 0;
  double core_heartbeat_age_ms = 0.0;  // wall time since the core heartbeat last advanced
  std::uint32_t core_pid = 0;
  std::uint32_t gateway_pid = 0;
  bool shutting_down = false;  // header().shutting_down: the core is stopping for good
  std::uint32_t gateway_restarts = 0;  // header().gateway_restarts, counted by `safestate run`
  // SPEC §12: the latest brake test on record in the event log, as brake_test_record()
  // made it (null or absent: none).
  const Json* brake_test_record = nullptr;
};

// The fieldbus subdevice names and boot error `safestate run` put in the segment: alarm
// texts of FIELDBUS_LOST and BOOT_FAILED name the subdevice. Called once, at attach.
void set_fieldbus(const bridge::BusInfo& bus) noexcept;

// The active safety configuration `safestate run` put in the segment (SPEC §10): its
// zone names name ZONE_VIOLATION's detail. Called once, at attach; false and `error` when
// the segment holds none or one that does not parse (then zones are named by number).
bool set_safety(const bridge::SafetyInfo& info, std::string& error);
// GET /api/safety without `validated` and `confirmation` (the status and the log say those):
// name, checksum, source, config; null when set_safety() has not succeeded.
Json safety_json();
// The status `safety` object (protocol.md). `brake_test_record`: see brake_test_record().
Json status_safety_json(const bridge::Status& s, const Json* brake_test_record = nullptr);
// SPEC §12: a `brake_test` event of the log (its time and data) as the status shows it:
// {time, result, axis, drift_deg}; null when the data is not a brake_test event's (a
// result passed or failed, axis null or 1..6, six finite drifts).
Json brake_test_record(const std::string& time, const Json& data);
// An alarm detail in the vocabulary of the scenario format's `alarm.NAME.detail=`: axis.N,
// tcp, the zone's name, estop.a, ... (the `subject` of an alarm object).
std::string alarm_subject(const core::AlarmDetail& d);

// The status `sim` object (SPEC §11, the simulated person and the scanner's field radii);
// null unless the status comes from the in-process simulated cell.
Json status_sim_json(const bridge::Status& s);
// SPEC §14: the channels (one, or A and B) as the status shows them.
Json status_channels_json(const bridge::Status& s);
// The `status` message (with_type) or GET /api/status (without).
Json status_json(const bridge::Status& s, const StatusExtras& x, bool with_type);
// Who may command (protocol.md "Roles"): the pendant in T1/T2; in AUTO a connected
// remote, else a connected pendant; nullptr when nobody.
const char* owner_of(core::Mode mode, bool remote_connected, bool pendant_connected) noexcept;

// GET /api/alarms: the active alarms, in the order of the alarm table.
Json alarms_json(const bridge::Status& s);

// The `kind` and `data` of an event record. For a command, `name` is the command name
// the client sent (for an unknown one), `client_seq` its seq (null when unknown, e.g.
// the reset button).
const char* kind_name(bridge::EventKind k) noexcept;
Json event_data(const bridge::EventRecord& e, const std::string& name, const Json& client_seq);
// A transition that stops (Cat 0/1/2, or into ESTOP_ACTIVE / ERROR_LOCKOUT) carries a
// black box.
bool needs_blackbox(const bridge::EventRecord& e) noexcept;
inline constexpr std::size_t kBlackBoxPerEvent = 50;
// The last `cycles` cycles up to and including `t`; a slot that does not hold the
// expected cycle (overwritten, or never written) is listed as missing.
Json blackbox_json(const bridge::BlackBox& box, std::uint64_t t, std::size_t cycles = kBlackBoxPerEvent);
// The `event` message.
Json event_message(std::int64_t id, std::uint64_t t, const std::string& time, const char* kind, const Json& data);

// GET /api/robot.
Json robot_json();
// Where the gateway serves the description's i-th visual mesh (GET, read-only).
inline std::string mesh_url(std::size_t i, const std::string& ext) {
  return "/api/robot/meshes/" + std::to_string(i) + "." + ext;
}

// GET /metrics (Prometheus text exposition format 0.0.4).
// The gateway's connections and their bounds (issue 40; gateway/README.md "Admission").
struct ConnectionFigures {
  bool known = false;  // false: none to show (no listener)
  std::size_t fd_limit = 0;
  std::size_t open = 0;  // client connections of every kind
  std::size_t open_max = 0;
  std::size_t waiting = 0;  // HTTP connections waiting for a request head
  std::size_t waiting_max = 0;
  std::size_t waiting_peer_peak = 0;  // from the peer address with the most of them now
  std::size_t waiting_per_peer_max = 0;
  std::size_t in_service = 0;  // requests being answered or upgraded
  std::size_t in_service_max = 0;
  std::size_t service_queue = 0;  // complete requests waiting for a service slot
  double first_head_limit_s = 0.0;
  double keep_alive_limit_s = 0.0;
  std::uint64_t shed_total = 0;           // silent waiting connections that gave way (503)
  std::uint64_t head_timeouts_total = 0;  // closed for a head not complete in time (408)
  std::uint64_t refused_total = 0;        // newcomers and requests answered 503 for lack of room
  std::uint64_t accept_paused_total = 0;  // times the listener waited for room (or a descriptor)
};

struct MetricsExtras {
  std::size_t ws_clients = 0;
  std::uint64_t core_heartbeat = 0;
  std::uint64_t events_stored = 0;
  std::array<std::uint64_t, core::kResultCount> commands_by_result{};
  ConnectionFigures connections;
};
std::string metrics_text(const bridge::Metrics& m, const MetricsExtras& x);

// ISO-8601 UTC with milliseconds: 2026-11-22T10:00:00.123Z.
std::string iso8601_utc(std::chrono::system_clock::time_point tp);

// JSON text of a message; invalid UTF-8 (never expected) is replaced, not thrown.
std::string dump(const Json& j);

}  // namespace safestate::gateway

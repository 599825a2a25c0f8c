// The persisted event history (SQLite): every transition, alarm, alarm clear and
// command result, with a black box for each stopping transition. Opened with
// journal_mode=WAL and synchronous=FULL, so a committed event survives a crash or a
// power cut; ids are SQLite rowids and continue across restarts.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

struct sqlite3;
struct sqlite3_stmt;

namespace safestate::gateway {

class EventLog {
 public:
  // Opens (creating the file and the table when missing). nullptr and `error` on failure.
  static std::unique_ptr<EventLog> open(const std::string& path, std::string& error);
  ~EventLog();
  EventLog(const EventLog&) = delete;
  EventLog& operator=(const EventLog&) = delete;

  // One transaction per batch of events (one fsync per batch, not per event).
  bool begin();
  bool commit();
  // Returns the new id, or -1 (see last_error()). `data` and `blackbox` are JSON text;
  // an empty `blackbox` is stored as NULL.
  std::int64_t insert(std::uint64_t t, const std::string& time, const std::string& kind, const std::string& data,
                      const std::string& blackbox);
  // Events with id > after, oldest first, at most `limit`, as a JSON array text of
  // {id, t, time, kind, data, blackbox}, `blackbox` being null or the URL of the
  // event's black box; `last` is the last id and `rows` how many. False and `error` on
  // a database error.
  bool query_json(std::int64_t after, std::int64_t limit, std::string& out, std::int64_t& last, std::int64_t& rows,
                  std::string& error);
  // The black box of event `id` (JSON text); found false when it has none.
  bool query_blackbox(std::int64_t id, std::string& out, bool& found, std::string& error);
  // How far the event ring of segment `instance` has been logged (its tail), 0 when
  // unknown; set inside the transaction that logs the events, so that both are durable
  // together: a gateway killed at any moment neither loses nor repeats an event.
  std::uint64_t ring_progress(std::uint64_t instance);
  bool set_ring_progress(std::uint64_t instance, std::uint64_t tail);
  // The newest event of `kind` (its time and data as JSON text); found false when none.
  bool latest(const std::string& kind, std::string& time, std::string& data, bool& found, std::string& error);
  [[nodiscard]] std::string last_error() const;

 private:
  explicit EventLog(sqlite3* db) noexcept : db_(db) {}
  bool exec(const char* sql);

  sqlite3* db_ = nullptr;
  sqlite3_stmt* insert_ = nullptr;
  sqlite3_stmt* select_ = nullptr;
  sqlite3_stmt* blackbox_ = nullptr;
  sqlite3_stmt* progress_get_ = nullptr;
  sqlite3_stmt* progress_set_ = nullptr;
  sqlite3_stmt* latest_ = nullptr;
  bool in_transaction_ = false;
};

// SPEC §10: the operator's latest confirmation of a safety configuration, as the gateway
// logged it (event `config_validated`).
struct Confirmation {
  std::string checksum;  // 8 upper-case hex digits
  std::string client;
  std::string role;
  std::string time;  // ISO-8601 UTC
};
// The latest `config_validated` event of the log at `path`, read before the core starts
// (`safestate run`). No file or no such event: found false, true returned. False and
// `error` when the log exists but cannot be read or the event is malformed: the caller
// then treats the configuration as not validated.
bool latest_confirmation(const std::string& path, Confirmation& out, bool& found, std::string& error);
// The same from an open log (GET /api/safety).
bool latest_confirmation(EventLog& log, Confirmation& out, bool& found, std::string& error);

// SPEC §12: the latest `brake_test` event (written from the core's ring when a brake test
// ends), read before the core starts, by the same mechanism as latest_confirmation.
struct BrakeTestRecord {
  std::string result;  // "passed" or "failed"
  std::string time;    // ISO-8601 UTC
};
bool latest_brake_test(const std::string& path, BrakeTestRecord& out, bool& found, std::string& error);
// Milliseconds from the ISO-8601 UTC time the log writes to `now`; false when the text is
// not such a time or lies in the future (a clock set back: the age is then unknown).
bool age_ms_of(const std::string& iso_time, std::chrono::system_clock::time_point now, std::uint64_t& age_ms);

}  // namespace safestate::gateway

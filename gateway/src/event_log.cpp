#include "safestate/gateway/event_log.hpp"

#include <sqlite3.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <ctime>

#include <nlohmann/json.hpp>

namespace safestate::gateway {

namespace {

constexpr const char* kSchema =
    "CREATE TABLE IF NOT EXISTS events("
    "id INTEGER PRIMARY KEY, "
    "t INTEGER NOT NULL, "
    "time TEXT NOT NULL, "
    "kind TEXT NOT NULL, "
    "data TEXT NOT NULL, "
    "blackbox TEXT);"
    "CREATE TABLE IF NOT EXISTS ring_progress(instance INTEGER PRIMARY KEY, tail INTEGER NOT NULL);"
    // The newest event of a kind (config_validated: GET /api/safety, every start) without a
    // scan of the whole history on the gateway's one I/O thread.
    "CREATE INDEX IF NOT EXISTS events_kind ON events(kind, id)";

// A string as a JSON string literal (our own ASCII time and kind names).
std::string quoted(const unsigned char* s) {
  const nlohmann::json j = (s == nullptr) ? std::string{} : std::string(reinterpret_cast<const char*>(s));
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string raw_or_null(const unsigned char* s) {
  return (s == nullptr) ? std::string("null") : std::string(reinterpret_cast<const char*>(s));
}

}  // namespace

std::unique_ptr<EventLog> EventLog::open(const std::string& path, std::string& error) {
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
                                 nullptr);
  if (rc != SQLITE_OK) {
    error = "cannot open event log " + path + ": " + (db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc));
    sqlite3_close(db);
    return nullptr;
  }
  std::unique_ptr<EventLog> log(new EventLog(db));
  sqlite3_busy_timeout(db, 2000);
  if (!log->exec("PRAGMA journal_mode=WAL") || !log->exec("PRAGMA synchronous=FULL") || !log->exec(kSchema)) {
    error = "cannot initialise event log " + path + ": " + log->last_error();
    return nullptr;
  }
  if (sqlite3_prepare_v2(db, "INSERT INTO events(t, time, kind, data, blackbox) VALUES(?, ?, ?, ?, ?)", -1,
                         &log->insert_, nullptr) != SQLITE_OK ||
      sqlite3_prepare_v2(db,
                         "SELECT id, t, time, kind, data, blackbox IS NOT NULL FROM events WHERE id > ? ORDER BY id "
                         "LIMIT ?",
                         -1, &log->select_, nullptr) != SQLITE_OK ||
      sqlite3_prepare_v2(db, "SELECT blackbox FROM events WHERE id = ?", -1, &log->blackbox_, nullptr) != SQLITE_OK ||
      sqlite3_prepare_v2(db, "SELECT tail FROM ring_progress WHERE instance = ?", -1, &log->progress_get_, nullptr) !=
          SQLITE_OK ||
      sqlite3_prepare_v2(db, "INSERT OR REPLACE INTO ring_progress(instance, tail) VALUES(?, ?)", -1,
                         &log->progress_set_, nullptr) != SQLITE_OK ||
      sqlite3_prepare_v2(db, "SELECT time, data FROM events WHERE kind = ? ORDER BY id DESC LIMIT 1", -1,
                         &log->latest_, nullptr) != SQLITE_OK) {
    error = "cannot prepare event log statements: " + log->last_error();
    return nullptr;
  }
  return log;
}

EventLog::~EventLog() {
  if (in_transaction_) {
    exec("COMMIT");
  }
  sqlite3_finalize(insert_);
  sqlite3_finalize(select_);
  sqlite3_finalize(blackbox_);
  sqlite3_finalize(progress_get_);
  sqlite3_finalize(progress_set_);
  sqlite3_finalize(latest_);
  sqlite3_close(db_);
}

bool EventLog::exec(const char* sql) { return sqlite3_exec(db_, sql, nullptr, nullptr, nullptr) == SQLITE_OK; }

std::string EventLog::last_error() const { return sqlite3_errmsg(db_); }

bool EventLog::begin() {
  in_transaction_ = exec("BEGIN IMMEDIATE");
  return in_transaction_;
}

bool EventLog::commit() {
  if (!in_transaction_) {
    return true;
  }
  in_transaction_ = false;
  if (exec("COMMIT")) {
    return true;
  }
  exec("ROLLBACK");
  return false;
}

std::int64_t EventLog::insert(std::uint64_t t, const std::string& time, const std::string& kind,
                              const std::string& data, const std::string& blackbox) {
  sqlite3_reset(insert_);
  sqlite3_clear_bindings(insert_);
  sqlite3_bind_int64(insert_, 1, static_cast<sqlite3_int64>(t));
  sqlite3_bind_text(insert_, 2, time.c_str(), static_cast<int>(time.size()), SQLITE_TRANSIENT);
  sqlite3_bind_text(insert_, 3, kind.c_str(), static_cast<int>(kind.size()), SQLITE_TRANSIENT);
  sqlite3_bind_text(insert_, 4, data.c_str(), static_cast<int>(data.size()), SQLITE_TRANSIENT);
  if (blackbox.empty()) {
    sqlite3_bind_null(insert_, 5);
  } else {
    sqlite3_bind_text(insert_, 5, blackbox.c_str(), static_cast<int>(blackbox.size()), SQLITE_TRANSIENT);
  }
  const int rc = sqlite3_step(insert_);
  sqlite3_reset(insert_);
  if (rc != SQLITE_DONE) {
    return -1;
  }
  return sqlite3_last_insert_rowid(db_);
}

bool EventLog::query_json(std::int64_t after, std::int64_t limit, std::string& out, std::int64_t& last,
                          std::int64_t& rows, std::string& error) {
  last = after;
  rows = 0;
  sqlite3_reset(select_);
  sqlite3_bind_int64(select_, 1, after);
  sqlite3_bind_int64(select_, 2, limit);
  out = "[";
  bool first = true;
  int rc = SQLITE_ROW;
  while ((rc = sqlite3_step(select_)) == SQLITE_ROW) {
    if (!first) {
      out += ',';
    }
    first = false;
    last = sqlite3_column_int64(select_, 0);
    ++rows;
    out += "{\"id\":" + std::to_string(last);
    out += ",\"t\":" + std::to_string(sqlite3_column_int64(select_, 1));
    out += ",\"time\":" + quoted(sqlite3_column_text(select_, 2));
    out += ",\"kind\":" + quoted(sqlite3_column_text(select_, 3));
    out += ",\"data\":" + raw_or_null(sqlite3_column_text(select_, 4));
    out += ",\"blackbox\":";
    out += (sqlite3_column_int(select_, 5) != 0) ? "\"/api/events/" + std::to_string(last) + "/blackbox\"" : "null";
    out += '}';
  }
  sqlite3_reset(select_);
  if (rc != SQLITE_DONE) {
    error = last_error();
    return false;
  }
  out += ']';
  return true;
}

bool EventLog::query_blackbox(std::int64_t id, std::string& out, bool& found, std::string& error) {
  sqlite3_reset(blackbox_);
  sqlite3_bind_int64(blackbox_, 1, id);
  const int rc = sqlite3_step(blackbox_);
  found = rc == SQLITE_ROW && sqlite3_column_type(blackbox_, 0) != SQLITE_NULL;
  if (found) {
    out = raw_or_null(sqlite3_column_text(blackbox_, 0));
  }
  sqlite3_reset(blackbox_);
  if (rc != SQLITE_ROW && rc != SQLITE_DONE) {
    error = last_error();
    return false;
  }
  return true;
}

std::uint64_t EventLog::ring_progress(std::uint64_t instance) {
  sqlite3_reset(progress_get_);
  sqlite3_bind_int64(progress_get_, 1, static_cast<sqlite3_int64>(instance));
  std::uint64_t tail = 0;
  if (sqlite3_step(progress_get_) == SQLITE_ROW) {
    tail = static_cast<std::uint64_t>(sqlite3_column_int64(progress_get_, 0));
  }
  sqlite3_reset(progress_get_);
  return tail;
}

bool EventLog::set_ring_progress(std::uint64_t instance, std::uint64_t tail) {
  sqlite3_reset(progress_set_);
  sqlite3_bind_int64(progress_set_, 1, static_cast<sqlite3_int64>(instance));
  sqlite3_bind_int64(progress_set_, 2, static_cast<sqlite3_int64>(tail));
  const int rc = sqlite3_step(progress_set_);
  sqlite3_reset(progress_set_);
  return rc == SQLITE_DONE;
}

bool EventLog::latest(const std::string& kind, std::string& time, std::string& data, bool& found, std::string& error) {
  sqlite3_reset(latest_);
  sqlite3_bind_text(latest_, 1, kind.c_str(), static_cast<int>(kind.size()), SQLITE_TRANSIENT);
  const int rc = sqlite3_step(latest_);
  found = rc == SQLITE_ROW;
  if (found) {
    const unsigned char* t = sqlite3_column_text(latest_, 0);
    const unsigned char* d = sqlite3_column_text(latest_, 1);
    time = (t == nullptr) ? std::string() : std::string(reinterpret_cast<const char*>(t));
    data = (d == nullptr) ? std::string() : std::string(reinterpret_cast<const char*>(d));
  }
  sqlite3_reset(latest_);
  if (rc != SQLITE_ROW && rc != SQLITE_DONE) {
    error = last_error();
    return false;
  }
  return true;
}

namespace {

bool is_checksum(const std::string& s) {
  return s.size() == 8U && std::all_of(s.begin(), s.end(), [](char c) { return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'F'); });
}

// A config_validated event's data as the gateway writes it (hub.cpp).
bool confirmation_of(const std::string& time, const std::string& data, Confirmation& out, std::string& error) {
  const nlohmann::json j = nlohmann::json::parse(data, nullptr, false);
  const auto text = [&j](const char* key) -> std::string {
    const auto it = j.find(key);
    return (it != j.end() && it->is_string()) ? it->get<std::string>() : std::string();
  };
  if (!j.is_object() || !is_checksum(text("checksum"))) {
    error = "the latest config_validated event has no checksum of 8 upper-case hex digits";
    return false;
  }
  out.checksum = text("checksum");
  out.client = text("client");
  out.role = text("role");
  out.time = time;
  return true;
}

}  // namespace

bool latest_confirmation(EventLog& log, Confirmation& out, bool& found, std::string& error) {
  std::string time;
  std::string data;
  if (!log.latest("config_validated", time, data, found, error)) {
    return false;
  }
  return !found || confirmation_of(time, data, out, error);
}

namespace {
// The log at `path` opened as the gateway opens it (the schema is created when missing, so an
// empty log answers "none"), by this process alone: the gateway starts after `safestate run`
// has read what it needs. No file: nothing to read (`none` set).
std::unique_ptr<EventLog> open_for_start(const std::string& path, bool& none, std::string& error) {
  none = false;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 && errno == ENOENT) {
    none = true;
    return nullptr;
  }
  return EventLog::open(path, error);
}
}  // namespace

bool latest_confirmation(const std::string& path, Confirmation& out, bool& found, std::string& error) {
  found = false;
  bool none = false;
  std::unique_ptr<EventLog> log = open_for_start(path, none, error);
  if (!log) {
    return none;  // no log yet: nothing was ever confirmed
  }
  return latest_confirmation(*log, out, found, error);
}

// @req BT-PERSIST
bool latest_brake_test(const std::string& path, BrakeTestRecord& out, bool& found, std::string& error) {
  found = false;
  bool none = false;
  std::unique_ptr<EventLog> log = open_for_start(path, none, error);
  if (!log) {
    return none;  // no log yet: no brake test on record
  }
  std::string data;
  if (!log->latest("brake_test", out.time, data, found, error) || !found) {
    return !found && error.empty();
  }
  const nlohmann::json j = nlohmann::json::parse(data, nullptr, false);
  const auto it = j.is_object() ? j.find("result") : j.end();
  if (it == j.end() || !it->is_string() || (*it != "passed" && *it != "failed")) {
    error = "the latest brake_test event has no result passed or failed";
    return false;
  }
  out.result = it->get<std::string>();
  return true;
}

bool age_ms_of(const std::string& iso_time, std::chrono::system_clock::time_point now, std::uint64_t& age_ms) {
  std::tm tm{};
  int ms = 0;
  char z = 0;
  // NOLINTNEXTLINE(cppcoreguidelines-pro-type-vararg): fixed format, as iso8601_utc writes it
  if (std::sscanf(iso_time.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d.%3d%c", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour,
                  &tm.tm_min, &tm.tm_sec, &ms, &z) != 8 || z != 'Z') {
    return false;
  }
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  const std::time_t secs = timegm(&tm);
  if (secs == static_cast<std::time_t>(-1)) {
    return false;
  }
  const auto then = std::chrono::system_clock::from_time_t(secs) + std::chrono::milliseconds(ms);
  if (then > now) {
    return false;
  }
  age_ms = static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(now - then).count());
  return true;
}

}  // namespace safestate::gateway

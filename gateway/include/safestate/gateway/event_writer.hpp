// The event log's writer: a thread of its own that owns the log's write connection and
// runs each batch of events as one transaction (synchronous=FULL: the commit is an fsync).
// The gateway's one I/O thread only hands batches over and takes them back done, so a slow
// disk delays the durability of events, never a client's status, reply or read (a commit
// of 156 ms on the CI machine's disk had left 500 observers without status that long).
//
// Batches are written in the order submitted and returned in that order. The I/O thread
// must not act on an event (advance the core's ring past it, push it to a client) before
// its batch comes back committed: protocol.md "Nothing lost".
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "safestate/gateway/event_log.hpp"

namespace safestate::gateway {

struct LogRow {
  std::uint64_t t = 0;
  std::string time;
  std::string kind;
  std::string data;      // JSON text
  std::string blackbox;  // JSON text, empty: none
};

struct LogBatch {
  std::vector<LogRow> rows;
  // How far the core's event ring has been logged, in the same transaction (0 instance:
  // not a batch from the ring).
  bool ring = false;
  std::uint64_t instance = 0;
  std::uint64_t tail = 0;
  // Filled by the writer: each row's id (-1: not stored), whether the transaction
  // committed, what went wrong, and how long the commit took.
  std::vector<std::int64_t> ids;
  bool committed = false;
  std::string error;
  double commit_ms = 0.0;
};

class EventWriter {
 public:
  // Takes the write connection.
  explicit EventWriter(std::unique_ptr<EventLog> log);
  ~EventWriter();
  EventWriter(const EventWriter&) = delete;
  EventWriter& operator=(const EventWriter&) = delete;

  // `fn` is called on the writer thread whenever a batch has been written (the owner then
  // calls take_done() on its own thread); set before the first submit.
  void on_done(std::function<void()> fn);
  void submit(LogBatch batch);
  // The batches written since the last call, in the order submitted.
  std::vector<LogBatch> take_done();
  // Blocks until every submitted batch has been written (at exit).
  void wait_idle();
  // Writes what is queued, then ends the thread; no `done` call after it returns.
  void stop();
  // Batches submitted and not yet taken back.
  [[nodiscard]] std::size_t outstanding() const;

 private:
  void run();
  void write(LogBatch& b);

  std::unique_ptr<EventLog> log_;
  std::function<void()> done_fn_;
  mutable std::mutex m_;
  std::condition_variable work_;
  std::condition_variable idle_;
  std::deque<LogBatch> todo_;
  std::vector<LogBatch> done_;
  bool busy_ = false;
  bool stop_ = false;
  bool finished_ = false;
  std::thread thread_;
};

}  // namespace safestate::gateway

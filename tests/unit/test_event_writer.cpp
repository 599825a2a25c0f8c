// The event log's writer thread (gateway/include/safestate/gateway/event_writer.hpp): batches
// committed in the order submitted, each with its rows' ids and the ring's progress in the
// same transaction, handed back only once committed; a reader connection sees them then.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "safestate/gateway/event_writer.hpp"

using namespace safestate::gateway;

namespace {

std::string temp_db() {
  static int n = 0;
  const std::string path = "/tmp/safestate-test-writer-" + std::to_string(::getpid()) + "-" + std::to_string(n++) + ".db";
  std::remove(path.c_str());
  return path;
}

void remove_db(const std::string& path) {
  for (const char* suffix : {"", "-wal", "-shm"}) {
    std::remove((path + suffix).c_str());
  }
}

std::unique_ptr<EventLog> open_log(const std::string& path) {
  std::string error;
  auto log = EventLog::open(path, error);
  EXPECT_TRUE(log) << error;
  return log;
}

// What a reader finds in the log: `rows` events (-1 when the read failed), the last id and
// the events as JSON.
struct Read {
  std::int64_t rows = -1;
  std::int64_t last = 0;
  nlohmann::json events;
};
Read read_log(EventLog& log, std::int64_t limit) {
  Read r;
  std::string out;
  std::string error;
  std::int64_t rows = 0;
  const bool ok = log.query_json(0, limit, out, r.last, rows, error);
  EXPECT_TRUE(ok) << error;
  if (ok) {
    r.rows = rows;
    r.events = nlohmann::json::parse(out);
  }
  return r;
}

LogBatch ring_batch(std::uint64_t first_t, int rows, std::uint64_t tail) {
  LogBatch b;
  for (int i = 0; i < rows; ++i) {
    b.rows.push_back(LogRow{first_t + static_cast<std::uint64_t>(i), "2026-11-27T00:00:00.000Z", "transition",
                            R"({"n":)" + std::to_string(first_t + static_cast<std::uint64_t>(i)) + "}", ""});
  }
  b.ring = true;
  b.instance = 7;
  b.tail = tail;
  return b;
}

}  // namespace

TEST(EventWriter, BatchesComeBackInOrderCommittedWithTheirIdsAndTheRingProgress) {
  const std::string path = temp_db();
  auto reader = open_log(path);
  {
    EventWriter writer(open_log(path));
    std::atomic<int> signalled{0};
    writer.on_done([&] { ++signalled; });
    writer.submit(ring_batch(100, 3, 3));
    writer.submit(ring_batch(200, 2, 5));
    LogBatch confirmation;  // not from the ring: no progress written
    confirmation.rows.push_back(LogRow{300, "2026-11-27T00:00:01.000Z", "config_validated", R"({"checksum":"0A1B2C3D"})", ""});
    writer.submit(std::move(confirmation));
    writer.wait_idle();
    EXPECT_EQ(writer.outstanding(), 3U);  // written, not yet taken back
    const auto done = writer.take_done();
    ASSERT_EQ(done.size(), 3U);
    EXPECT_GE(signalled.load(), 1);
    std::int64_t expect = 1;
    for (const LogBatch& b : done) {
      EXPECT_TRUE(b.committed) << b.error;
      EXPECT_TRUE(b.error.empty()) << b.error;
      ASSERT_EQ(b.ids.size(), b.rows.size());
      for (const std::int64_t id : b.ids) {
        EXPECT_EQ(id, expect++);  // rowids in submission order
      }
    }
    EXPECT_EQ(done[0].rows[0].t, 100U);
    EXPECT_EQ(done[1].rows[0].t, 200U);
    EXPECT_EQ(done[2].rows[0].kind, "config_validated");
    EXPECT_EQ(writer.outstanding(), 0U);
    EXPECT_TRUE(writer.take_done().empty());
  }
  // The reader (the I/O thread's connection) sees every row and the last ring progress.
  const Read got = read_log(*reader, 100);
  ASSERT_EQ(got.rows, 6);
  EXPECT_EQ(got.last, 6);
  const nlohmann::json& j = got.events;
  EXPECT_EQ(j[0]["t"], 100);
  EXPECT_EQ(j[4]["t"], 201);
  EXPECT_EQ(j[5]["kind"], "config_validated");
  EXPECT_EQ(reader->ring_progress(7), 5U);
  reader.reset();
  remove_db(path);
}

TEST(EventWriter, StopWritesWhatIsQueuedAndCallsNoOneAfterwards) {
  const std::string path = temp_db();
  std::atomic<int> after_stop{0};
  std::atomic<bool> stopped{false};
  {
    EventWriter writer(open_log(path));
    writer.on_done([&] {
      if (stopped) {
        ++after_stop;
      }
    });
    for (int i = 0; i < 20; ++i) {
      writer.submit(ring_batch(static_cast<std::uint64_t>(1000 + 10 * i), 5, static_cast<std::uint64_t>(5 * (i + 1))));
    }
    writer.stop();
    stopped = true;
    EXPECT_EQ(writer.take_done().size(), 20U);  // all written
    writer.wait_idle();                         // returns at once once stopped
  }
  EXPECT_EQ(after_stop.load(), 0);
  auto reader = open_log(path);
  EXPECT_EQ(read_log(*reader, 500).rows, 100);
  EXPECT_EQ(reader->ring_progress(7), 100U);
  reader.reset();
  remove_db(path);
}

// While the writer holds its transaction open (here: a commit that waits for a lock), the
// reader is not held up: the I/O thread's history and black-box answers never wait for an
// fsync (WAL).
TEST(EventWriter, TheReaderDoesNotWaitForTheWriter) {
  const std::string path = temp_db();
  auto reader = open_log(path);
  auto blocker = open_log(path);
  ASSERT_TRUE(blocker->begin());  // holds the write lock: the writer's BEGIN IMMEDIATE waits
  ASSERT_GE(blocker->insert(1, "2026-11-27T00:00:00.000Z", "transition", "{}", ""), 1);
  EventWriter writer(open_log(path));
  writer.submit(ring_batch(10, 1, 1));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(writer.take_done().size(), 0U);  // still waiting for the lock
  // Without WAL this read would wait out the busy timeout and fail with SQLITE_BUSY.
  EXPECT_EQ(read_log(*reader, 10).rows, 0);  // nothing committed yet
  ASSERT_TRUE(blocker->commit());
  writer.wait_idle();
  const auto done = writer.take_done();
  ASSERT_EQ(done.size(), 1U);
  EXPECT_TRUE(done[0].committed) << done[0].error;
  EXPECT_EQ(read_log(*reader, 10).rows, 2);
  writer.stop();
  reader.reset();
  blocker.reset();
  remove_db(path);
}

#include "safestate/gateway/event_writer.hpp"

#include <chrono>
#include <utility>

namespace safestate::gateway {

EventWriter::EventWriter(std::unique_ptr<EventLog> log) : log_(std::move(log)) {
  thread_ = std::thread([this] { run(); });
}

void EventWriter::on_done(std::function<void()> fn) {
  const std::lock_guard<std::mutex> lock(m_);
  done_fn_ = std::move(fn);
}

EventWriter::~EventWriter() { stop(); }

void EventWriter::submit(LogBatch batch) {
  {
    const std::lock_guard<std::mutex> lock(m_);
    todo_.push_back(std::move(batch));
  }
  work_.notify_one();
}

std::vector<LogBatch> EventWriter::take_done() {
  const std::lock_guard<std::mutex> lock(m_);
  return std::exchange(done_, {});
}

void EventWriter::wait_idle() {
  std::unique_lock<std::mutex> lock(m_);
  idle_.wait(lock, [this] { return (todo_.empty() && !busy_) || finished_; });
}

std::size_t EventWriter::outstanding() const {
  const std::lock_guard<std::mutex> lock(m_);
  return todo_.size() + done_.size() + (busy_ ? 1U : 0U);
}

void EventWriter::stop() {
  {
    const std::lock_guard<std::mutex> lock(m_);
    stop_ = true;
  }
  work_.notify_one();
  if (thread_.joinable()) {
    thread_.join();
  }
}

void EventWriter::run() {
  std::unique_lock<std::mutex> lock(m_);
  for (;;) {
    work_.wait(lock, [this] { return stop_ || !todo_.empty(); });
    if (todo_.empty()) {
      finished_ = true;  // stopping, everything written
      lock.unlock();
      idle_.notify_all();
      return;
    }
    LogBatch b = std::move(todo_.front());
    todo_.pop_front();
    busy_ = true;
    lock.unlock();
    write(b);
    lock.lock();
    busy_ = false;
    done_.push_back(std::move(b));
    const bool idle = todo_.empty();
    const std::function<void()> done = stop_ ? std::function<void()>{} : done_fn_;
    lock.unlock();
    if (done) {
      done();
    }
    if (idle) {
      idle_.notify_all();
    }
    lock.lock();
  }
}

void EventWriter::write(LogBatch& b) {
  b.ids.assign(b.rows.size(), -1);
  const bool began = log_->begin();
  if (!began) {
    b.error = "cannot begin a transaction: " + log_->last_error();
  }
  for (std::size_t i = 0; i < b.rows.size(); ++i) {
    const LogRow& r = b.rows[i];
    b.ids[i] = log_->insert(r.t, r.time, r.kind, r.data, r.blackbox);
    if (b.ids[i] < 0 && b.error.empty()) {
      b.error = "insert failed: " + log_->last_error();
    }
  }
  const auto start = std::chrono::steady_clock::now();
  const bool progress = !b.ring || log_->set_ring_progress(b.instance, b.tail);
  b.committed = began && progress && log_->commit();
  b.commit_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (began && !b.committed) {
    b.error = "commit failed: " + log_->last_error();
    b.ids.assign(b.rows.size(), -1);  // rolled back: none of them is stored
  }
}

}  // namespace safestate::gateway

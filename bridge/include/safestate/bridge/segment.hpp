// Maps the bridge's shared-memory segment. The core process creates it; the gateway
// attaches and checks magic, layout version, size and offsets before touching anything.
#pragma once

#include <memory>
#include <string>

#include "safestate/bridge/layout.hpp"

namespace safestate::bridge {

class Segment {
 public:
  // Core side: creates (replacing a stale one of the same name) and initialises, and
  // holds an exclusive lock on it for its whole life. A segment of the same name still
  // locked by a live process is never replaced: `error` names that process instead
  // (one controller per segment, protocol.md "Access and admission").
  static std::unique_ptr<Segment> create(const std::string& name, std::string& error);
  // Gateway side: attaches to an existing, initialised segment.
  static std::unique_ptr<Segment> attach(const std::string& name, std::string& error);
  ~Segment();
  Segment(const Segment&) = delete;
  Segment& operator=(const Segment&) = delete;

  [[nodiscard]] Header& header() const noexcept { return *reinterpret_cast<Header*>(base_); }
  [[nodiscard]] CommandRing& commands() const noexcept { return at<CommandRing>(layout().commands); }
  [[nodiscard]] ReplyRing& replies() const noexcept { return at<ReplyRing>(layout().replies); }
  [[nodiscard]] EventRing& events() const noexcept { return at<EventRing>(layout().events); }
  [[nodiscard]] StatusLock& status() const noexcept { return at<StatusLock>(layout().status); }
  [[nodiscard]] BlackBox& blackbox() const noexcept { return at<BlackBox>(layout().blackbox); }
  [[nodiscard]] Metrics& metrics() const noexcept { return at<Metrics>(layout().metrics); }
  [[nodiscard]] const std::string& name() const noexcept { return name_; }

 private:
  Segment(std::string name, unsigned char* base, std::size_t size, bool owner, int lock_fd) noexcept
      : name_(std::move(name)), base_(base), size_(size), owner_(owner), lock_fd_(lock_fd) {}
  template <typename T>
  T& at(std::uint64_t offset) const noexcept {
    return *reinterpret_cast<T*>(base_ + offset);
  }

  std::string name_;
  unsigned char* base_;
  std::size_t size_;
  bool owner_;
  int lock_fd_;  // the creator's open descriptor holding flock(LOCK_EX); -1 when attached
};

// Default segment name for a gateway port, so that several instances can coexist.
std::string default_segment_name(unsigned port);

}  // namespace safestate::bridge

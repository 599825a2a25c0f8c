// Bounded FIFO of commands waiting for the next cycle. Fixed capacity, no heap; a push
// onto a full queue is refused with QUEUE_FULL, which is that command's one result.
#pragma once

#include <array>
#include <cstddef>

#include "safestate/core/types.hpp"

namespace safestate::core {

template <std::size_t N>
class CommandQueue {
  static_assert(N > 0U, "capacity must be positive");

 public:
  // OK when queued; QUEUE_FULL (and nothing queued) when full.
  Result push(const Command& c) noexcept {
    if (size_ == N) {
      // @req RES-QUEUE-FULL
      return Result::QUEUE_FULL;
    }
    buf_[(head_ + size_) % N] = c;
    ++size_;
    return Result::OK;
  }
  // Copies up to `max` oldest commands into `out` without removing them.
  std::size_t peek(Command* out, std::size_t max) const noexcept {
    const std::size_t n = (size_ < max) ? size_ : max;
    for (std::size_t i = 0; i < n; ++i) {
      out[i] = buf_[(head_ + i) % N];
    }
    return n;
  }
  // Removes the `n` oldest commands (those the supervisor took this cycle).
  void pop(std::size_t n) noexcept {
    const std::size_t k = (n < size_) ? n : size_;
    head_ = (head_ + k) % N;
    size_ -= k;
  }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  [[nodiscard]] static constexpr std::size_t capacity() noexcept { return N; }

 private:
  std::array<Command, N> buf_{};
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

}  // namespace safestate::core

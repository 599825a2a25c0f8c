// The operating-system side of two channels in processes (pair/shm.hpp): shared memory, the
// futex a channel waits on for its frame and the host on its reports, the real-time set-up of
// a loop, and this program's code for the platform's CRC. Used at start-up (map, set-up) and
// by the loops (futex_wait/futex_wake: bounded waits, never on the network).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>

namespace safestate::pair {

// A shared-memory object mapped: created (O_EXCL, owner only, `size` bytes, zeroed) or opened
// (its size must be at least `size`), read-write or read-only. Null with `err` naming what
// failed.
void* map_shm(const char* name, std::size_t size, bool create, bool writable, std::string& err);
void unmap_shm(void* p, std::size_t size) noexcept;
void remove_shm(const char* name) noexcept;

// Waits while `word` holds `expected`, at most `timeout_ns` (a shared futex: the word may be in
// a read-only mapping of the waiter). False on timeout.
bool futex_wait(const std::atomic<std::uint32_t>& word, std::uint32_t expected, std::uint64_t timeout_ns) noexcept;
void futex_wake(std::atomic<std::uint32_t>& word) noexcept;

std::uint64_t now_ns() noexcept;  // CLOCK_MONOTONIC

// Issue 37: a host session for the black channel's connections, different at every start
// (getrandom; the monotonic clock's low bits if that fails), never 0.
std::uint16_t random_session() noexcept;

// SCHED_FIFO at `priority` (0: none), pinned to `cpu` (-1: not), memory locked; what could
// not be done, one line each (empty: all of it).
std::string realtime(int priority, int cpu);

// This program's executable segment (read-only, executable), found with dl_iterate_phdr.
struct CodeRegion {
  const void* p = nullptr;
  std::size_t n = 0;
};
CodeRegion own_code() noexcept;

}  // namespace safestate::pair

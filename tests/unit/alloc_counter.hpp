// A counting allocator for the no-allocation tests (DESIGN.md: no heap in the control loop):
// replaces operator new/delete and malloc & co. for the whole binary and counts every call
// made while `armed`. Include it in exactly one translation unit of a test binary that is
// not built with a sanitizer (a sanitizer owns malloc).
#pragma once

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <new>

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}

namespace {
// NOLINTBEGIN(cppcoreguidelines-avoid-non-const-global-variables): the counter is the point
std::atomic<bool> armed{false};
std::atomic<long> allocations{0};
// NOLINTEND(cppcoreguidelines-avoid-non-const-global-variables)
void count() {
  if (armed.load(std::memory_order_relaxed)) {
    allocations.fetch_add(1, std::memory_order_relaxed);
  }
}
}  // namespace

extern "C" {
void* malloc(std::size_t n) {
  count();
  return __libc_malloc(n);
}
void* calloc(std::size_t a, std::size_t b) {
  count();
  return __libc_calloc(a, b);
}
void* realloc(void* p, std::size_t n) {
  count();
  return __libc_realloc(p, n);
}
void* aligned_alloc(std::size_t al, std::size_t n) {
  count();
  return __libc_memalign(al, n);
}
int posix_memalign(void** p, std::size_t al, std::size_t n) {
  count();
  *p = __libc_memalign(al, n);
  return (*p == nullptr) ? ENOMEM : 0;
}
void free(void* p) { __libc_free(p); }
}

void* operator new(std::size_t n) {
  count();
  void* p = __libc_malloc(n == 0 ? 1 : n);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  count();
  return __libc_malloc(n == 0 ? 1 : n);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept { return operator new(n, t); }
void operator delete(void* p) noexcept { __libc_free(p); }
void operator delete[](void* p) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t) noexcept { __libc_free(p); }

#include "safestate/pair/os.hpp"

#include <fcntl.h>
#include <link.h>
#include <linux/futex.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace safestate::pair {

void* map_shm(const char* name, std::size_t size, bool create, bool writable, std::string& err) {
  const int flags = (create ? (O_CREAT | O_EXCL | O_RDWR) : (writable ? O_RDWR : O_RDONLY)) | O_CLOEXEC;
  const int fd = shm_open(name, flags, 0600);
  if (fd < 0) {
    err = std::string("shared memory ") + name + ": " + std::strerror(errno);
    return nullptr;
  }
  if (create && ftruncate(fd, static_cast<off_t>(size)) != 0) {
    err = std::string("shared memory ") + name + ": cannot size it: " + std::strerror(errno);
    close(fd);
    shm_unlink(name);
    return nullptr;
  }
  struct stat st{};
  if (fstat(fd, &st) != 0 || static_cast<std::size_t>(st.st_size) < size) {
    err = std::string("shared memory ") + name + ": smaller than this build's layout (another build's host?)";
    close(fd);
    return nullptr;
  }
  void* p = mmap(nullptr, size, (create || writable) ? (PROT_READ | PROT_WRITE) : PROT_READ, MAP_SHARED, fd, 0);
  close(fd);
  if (p == MAP_FAILED) {
    err = std::string("shared memory ") + name + ": mmap: " + std::strerror(errno);
    return nullptr;
  }
  return p;
}

void unmap_shm(void* p, std::size_t size) noexcept {
  if (p != nullptr) {
    munmap(p, size);
  }
}

void remove_shm(const char* name) noexcept { shm_unlink(name); }

bool futex_wait(const std::atomic<std::uint32_t>& word, std::uint32_t expected, std::uint64_t timeout_ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(timeout_ns / 1000000000ULL);
  ts.tv_nsec = static_cast<long>(timeout_ns % 1000000000ULL);
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t));
  const long rc = syscall(SYS_futex, reinterpret_cast<const std::uint32_t*>(&word), FUTEX_WAIT, expected, &ts,
                          nullptr, 0);
  return !(rc != 0 && errno == ETIMEDOUT);
}

void futex_wake(std::atomic<std::uint32_t>& word) noexcept {
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE, 0x7FFFFFFF, nullptr, nullptr, 0);
}

std::uint64_t now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL) + static_cast<std::uint64_t>(ts.tv_nsec);
}

std::string realtime(int priority, int cpu) {
  std::string report;
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    report += std::string("warning: mlockall failed (") + std::strerror(errno) + "), memory may page\n";
  }
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(cpu), &set);
    const int rc = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
    if (rc != 0) {
      report += "warning: cannot pin to CPU " + std::to_string(cpu) + " (" + std::strerror(rc) + ")\n";
    }
  }
  if (priority > 0) {
    sched_param sp{};
    sp.sched_priority = priority;
    const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (rc != 0) {
      report += std::string("warning: SCHED_FIFO not permitted (") + std::strerror(rc) + "), normal scheduling\n";
    }
  }
  return report;
}

CodeRegion own_code() noexcept {
  CodeRegion r;
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void* data) -> int {
        auto* out = static_cast<CodeRegion*>(data);
        for (int i = 0; i < info->dlpi_phnum; ++i) {
          const ElfW(Phdr)& ph = info->dlpi_phdr[i];
          if (ph.p_type == PT_LOAD && (ph.p_flags & PF_X) != 0U && (ph.p_flags & PF_W) == 0U && ph.p_memsz > out->n) {
            out->p = reinterpret_cast<const void*>(info->dlpi_addr + ph.p_vaddr);
            out->n = ph.p_memsz;
          }
        }
        return 1;  // the first object is the program itself
      },
      &r);
  return r;
}

std::uint16_t random_session() noexcept {
  std::uint16_t v = 0;
  if (getrandom(&v, sizeof v, 0) != static_cast<ssize_t>(sizeof v)) {
    v = static_cast<std::uint16_t>(now_ns() ^ (now_ns() >> 16U));
  }
  return (v == 0U) ? std::uint16_t{1} : v;
}

}  // namespace safestate::pair

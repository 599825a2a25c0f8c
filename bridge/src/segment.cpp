#include "safestate/bridge/segment.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <new>
#include <random>

namespace safestate::bridge {

namespace {
std::string errno_text(const char* what, const std::string& name) {
  return std::string(what) + " " + name + ": " + std::strerror(errno);
}
}  // namespace

std::string default_segment_name(unsigned port) { return "/safestate-" + std::to_string(port); }

namespace {
// An existing segment of this name whose creator still holds its lock belongs to a live
// controller: say whose it is. False when there is none, or only a stale one (its
// creator died: the kernel dropped the lock with the process).
bool held_by_live_run(const std::string& name, std::string& error) {
  const int fd = shm_open(name.c_str(), O_RDWR, 0);
  if (fd < 0) {
    return false;
  }
  if (flock(fd, LOCK_EX | LOCK_NB) == 0) {
    close(fd);  // releases the lock: the segment is stale
    return false;
  }
  std::uint32_t pid = 0;
  struct stat st {};
  if (fstat(fd, &st) == 0 && static_cast<std::size_t>(st.st_size) >= sizeof(Header)) {
    void* p = mmap(nullptr, sizeof(Header), PROT_READ, MAP_SHARED, fd, 0);
    if (p != MAP_FAILED) {
      pid = static_cast<const Header*>(p)->core_pid.load(std::memory_order_relaxed);
      munmap(p, sizeof(Header));
    }
  }
  close(fd);
  error = "shared-memory segment " + name + " is in use by a running controller (process " +
          (pid != 0U ? std::to_string(pid) : std::string("unknown")) +
          "): one controller per segment; stop it first or use another --port / --shm";
  return true;
}
}  // namespace

std::unique_ptr<Segment> Segment::create(const std::string& name, std::string& error) {
  const Layout l = layout();
  if (held_by_live_run(name, error)) {
    return nullptr;
  }
  shm_unlink(name.c_str());  // a stale segment of a crashed run
  const int fd = shm_open(name.c_str(), O_CREAT | O_EXCL | O_RDWR, 0600);
  if (fd < 0) {
    error = (errno == EEXIST) ? "shared-memory segment " + name + " was just created by another controller"
                              : errno_text("shm_open", name);
    return nullptr;
  }
  if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
    error = errno_text("flock", name);
    close(fd);
    return nullptr;
  }
  if (ftruncate(fd, static_cast<off_t>(l.size)) != 0) {
    error = errno_text("ftruncate", name);
    close(fd);
    shm_unlink(name.c_str());
    return nullptr;
  }
  void* p = mmap(nullptr, l.size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) {
    error = errno_text("mmap", name);
    close(fd);
    shm_unlink(name.c_str());
    return nullptr;
  }
  auto* base = static_cast<unsigned char*>(p);
  std::memset(base, 0, l.size);
  new (base + l.commands) CommandRing();
  new (base + l.replies) ReplyRing();
  new (base + l.events) EventRing();
  new (base + l.status) StatusLock();
  new (base + l.blackbox) BlackBox();
  new (base + l.metrics) Metrics();
  auto* h = new (base) Header();
  h->size = l.size;
  h->commands_offset = l.commands;
  h->replies_offset = l.replies;
  h->events_offset = l.events;
  h->status_offset = l.status;
  h->blackbox_offset = l.blackbox;
  h->metrics_offset = l.metrics;
  h->core_pid.store(static_cast<std::uint32_t>(getpid()), std::memory_order_relaxed);
  std::random_device rd;
  h->instance = (static_cast<std::uint64_t>(rd()) << 32U) | rd();
  h->magic = kMagic;  // written last; the gateway is only started after this returns
  return std::unique_ptr<Segment>(new Segment(name, base, l.size, true, fd));
}

std::unique_ptr<Segment> Segment::attach(const std::string& name, std::string& error) {
  const Layout l = layout();
  const int fd = shm_open(name.c_str(), O_RDWR, 0);
  if (fd < 0) {
    error = errno_text("shm_open", name);
    return nullptr;
  }
  struct stat st {};
  if (fstat(fd, &st) != 0 || static_cast<std::uint64_t>(st.st_size) != l.size) {
    error = "segment " + name + " has size " + std::to_string(st.st_size) + ", this build expects " +
            std::to_string(l.size) + " (different layout)";
    close(fd);
    return nullptr;
  }
  void* p = mmap(nullptr, l.size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  close(fd);
  if (p == MAP_FAILED) {
    error = errno_text("mmap", name);
    return nullptr;
  }
  auto* base = static_cast<unsigned char*>(p);
  const auto* h = reinterpret_cast<const Header*>(base);
  const bool offsets_ok = h->size == l.size && h->commands_offset == l.commands && h->replies_offset == l.replies &&
                          h->events_offset == l.events && h->status_offset == l.status &&
                          h->blackbox_offset == l.blackbox && h->metrics_offset == l.metrics;
  if (h->magic != kMagic || h->version != kLayoutVersion || !offsets_ok) {
    error = "segment " + name + " is not a SafeState bridge of layout version " + std::to_string(kLayoutVersion);
    munmap(p, l.size);
    return nullptr;
  }
  return std::unique_ptr<Segment>(new Segment(name, base, l.size, false, -1));
}

Segment::~Segment() {
  munmap(base_, size_);
  if (owner_) {
    shm_unlink(name_.c_str());
  }
  if (lock_fd_ >= 0) {
    close(lock_fd_);
  }
}

}  // namespace safestate::bridge

// The emulated segment on a network interface. One thread: poll() on the raw socket and
// the control channel, a 1 ms tick for the watchdogs and the free-running physics.
#include "safestate/ecat/ecat_sim.hpp"

#include <arpa/inet.h>
#include <linux/if_packet.h>
#include <net/if.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

namespace safestate::ecat {

namespace {

std::atomic<bool> g_stop{false};
constexpr std::uint64_t kPulseGraceNs = 50000;
void on_signal(int) { g_stop.store(true); }

std::uint64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
}

int open_raw(const std::string& ifname, std::string& err) {
  const unsigned idx = if_nametoindex(ifname.c_str());
  if (idx == 0U) {
    err = "no network interface named '" + ifname + "'";
    return -1;
  }
  const int fd = socket(AF_PACKET, SOCK_RAW | SOCK_NONBLOCK, htons(kEtherTypeEcat));
  if (fd < 0) {
    err = std::string("raw socket: ") + std::strerror(errno) + " (needs CAP_NET_RAW)";
    return -1;
  }
  sockaddr_ll sll{};
  sll.sll_family = AF_PACKET;
  sll.sll_protocol = htons(kEtherTypeEcat);
  sll.sll_ifindex = static_cast<int>(idx);
  if (bind(fd, reinterpret_cast<sockaddr*>(&sll), sizeof sll) != 0) {
    err = std::string("bind to ") + ifname + ": " + std::strerror(errno);
    close(fd);
    return -1;
  }
  const int on = 1;  // receive timestamps: when each frame arrived (serve_frames)
  setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
  packet_mreq mr{};
  mr.mr_ifindex = static_cast<int>(idx);
  mr.mr_type = PACKET_MR_PROMISC;
  setsockopt(fd, SOL_PACKET, PACKET_ADD_MEMBERSHIP, &mr, sizeof mr);
  return fd;
}

int open_control(const std::string& path, std::string& err) {
  sockaddr_un sa{};
  if (path.size() >= sizeof sa.sun_path) {
    err = "control socket path too long";
    return -1;
  }
  const int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK, 0);
  sa.sun_family = AF_UNIX;
  std::memcpy(sa.sun_path, path.c_str(), path.size() + 1U);
  unlink(path.c_str());
  const mode_t old = umask(0077);  // owner only: the control channel moves the emulated world
  const int rc = bind(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa);
  umask(old);
  if (rc != 0 || listen(fd, 4) != 0) {
    err = "control socket " + path + ": " + std::strerror(errno);
    close(fd);
    return -1;
  }
  return fd;
}

struct Client {
  int fd = -1;
  std::string buf;
};

void serve_client(EmulatedCell& cell, Client& c) {
  char b[1024];
  const ssize_t n = recv(c.fd, b, sizeof b, MSG_DONTWAIT);
  if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) {
    close(c.fd);
    c.fd = -1;
    return;
  }
  if (n < 0) {
    return;
  }
  c.buf.append(b, static_cast<std::size_t>(n));
  for (std::size_t nl = c.buf.find('\n'); nl != std::string::npos; nl = c.buf.find('\n')) {
    cell.set_time(now_ns());  // the reaction on the wire is timed from the contact's change
    const std::string reply = control_line(cell, c.buf.substr(0, nl)) + "\n";
    c.buf.erase(0, nl + 1U);
    if (send(c.fd, reply.data(), reply.size(), MSG_NOSIGNAL) < 0) {
      close(c.fd);
      c.fd = -1;
      return;
    }
  }
  if (c.buf.size() > 8192U) {
    close(c.fd);  // a line that never ends
    c.fd = -1;
  }
}

// When the frame reached the interface: the kernel's receive timestamp (CLOCK_REALTIME,
// taken as the veth queues it) on the monotonic clock, never later than `now`. A real ESC
// takes a frame as it passes; this process may get it later (woken late, or the frame handed
// over late by the kernel), and the SYNC0 pulses between must not overtake it.
std::uint64_t arrival_ns(msghdr& msg, std::uint64_t now) {
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
      timespec ts{};
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      timespec real{};
      clock_gettime(CLOCK_REALTIME, &real);
      const auto ns = [](const timespec& t) {
        return static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + static_cast<std::int64_t>(t.tv_nsec);
      };
      const std::int64_t ago = ns(real) - ns(ts);
      // (a timestamp from the future, or older than 100 ms: the clock was set; use now)
      return (ago > 0 && ago < 100000000LL) ? now - static_cast<std::uint64_t>(ago) : now;
    }
  }
  return now;
}

void serve_frames(EmulatedCell& cell, int raw) {
  if (now_ns() < cell.segment().frozen_until()) {
    return;  // a host stall (`freeze`): the frames wait in the socket until it ends
  }
  std::uint8_t frame[2048];
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec)) + 64];
  for (int k = 0; k < 64; ++k) {
    sockaddr_ll from{};
    iovec iov{frame, sizeof frame};
    msghdr msg{};
    msg.msg_name = &from;
    msg.msg_namelen = sizeof from;
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    const ssize_t n = recvmsg(raw, &msg, 0);
    if (n <= 0) {
      return;
    }
    if (from.sll_pkttype == PACKET_OUTGOING) {
      continue;  // our own replies
    }
    // In order, never back; a frame sent during a `freeze` reaches the segment when it ends.
    const std::uint64_t arrived = arrival_ns(msg, now_ns());
    const std::uint64_t held_until = cell.segment().frozen_until();
    const std::uint64_t t = std::max({arrived, cell.now(), held_until});
    cell.sync0_until(t);  // the pulses before it first: they took the set-points the last frame left
    cell.set_time(t);
    if (cell.segment().process(std::span<std::uint8_t>(frame, static_cast<std::size_t>(n)), t)) {
      send(raw, frame, static_cast<std::size_t>(n), 0);
      const std::uint64_t sent = now_ns();
      if (arrived >= held_until && sent > arrived) {
        cell.segment().note_answer(sent - arrived, sent);
      }
    }
    if (cell.segment().frozen_until() > t) {
      return;  // this frame started a freeze (`freeze MS at-op`): the next ones wait for its end
    }
  }
}

// "POS=VALUE" (VALUE decimal or 0x hex, 32 bits): subdevice POS gets `field` = VALUE.
bool apply_override(std::vector<SubdeviceDesc>& devs, const std::string& spec, const char* option,
                    std::uint32_t SubdeviceDesc::*field, std::string& err) {
  const std::size_t eq = spec.find('=');
  unsigned long pos = 0;
  unsigned long value = 0;
  bool ok = eq != std::string::npos;
  if (ok) {
    try {
      std::size_t used_pos = 0;
      std::size_t used_value = 0;
      const std::string p = spec.substr(0, eq);
      const std::string v = spec.substr(eq + 1U);
      pos = std::stoul(p, &used_pos);
      value = std::stoul(v, &used_value, 0);
      ok = used_pos == p.size() && used_value == v.size();
    } catch (...) {
      ok = false;
    }
  }
  if (!ok || pos < 1U || pos > devs.size() || value > 0xFFFFFFFFUL) {
    err = std::string(option) + " expects POS=VALUE with POS 1.." + std::to_string(devs.size()) +
          " and a 32-bit VALUE, got '" + spec + "'";
    return false;
  }
  devs[pos - 1U].*field = static_cast<std::uint32_t>(value);
  return true;
}

// A real ESC answers within nanoseconds; masters give a frame a few milliseconds at most.
// On a shared machine the emulator must not wait behind other work: SCHED_FIFO when
// permitted, as the real-time loop of `safestate run` does.
void realtime(int priority, int cpu) {
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(cpu), &set);
    const int rc = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
    if (rc != 0) {
      std::fprintf(stderr, "ecat-sim: warning: cannot pin to CPU %d (%s)\n", cpu, std::strerror(rc));
    }
  }
  if (priority <= 0) {
    return;
  }
  // No mlockall: the process stands in for hardware that costs the master's CPU nothing when
  // it goes, yet a killed emulator at this priority unlocks and frees every locked page (the
  // whole binary, ~17 MB) before the loop on its CPU may run: 1-1.8 ms measured, one cycle
  // overrun and the bus loss seen a cycle late (bench/ecat_loss.py, docs/ethercat.md). What
  // it touches per frame is resident after the first frames; unlocked, its exit takes ~0.5 ms.
  sched_param sp{};
  sp.sched_priority = priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  if (rc != 0) {
    std::fprintf(stderr, "ecat-sim: warning: SCHED_FIFO not permitted (%s)\n", std::strerror(rc));
  }
}

}  // namespace

bool parse_drift_ppm(const std::string& spec, std::size_t subdevices, std::vector<double>& out, std::string& err) {
  std::vector<double> v;
  std::size_t from = 0;
  bool ok = !spec.empty();
  while (ok) {
    const std::size_t comma = spec.find(',', from);
    const std::string item = spec.substr(from, comma == std::string::npos ? std::string::npos : comma - from);
    try {
      std::size_t used = 0;
      const double d = std::stod(item, &used);
      ok = used == item.size() && !item.empty() && d >= -500.0 && d <= 500.0;  // NaN fails the range check
      v.push_back(d);
    } catch (...) {
      ok = false;
    }
    if (comma == std::string::npos) {
      break;
    }
    from = comma + 1U;
  }
  if (!ok || (v.size() != 1U && v.size() != subdevices)) {
    err = "--drift-ppm expects one value or " + std::to_string(subdevices) +
          " comma-separated values, each -500..500 (ppm), got '" + spec + "'";
    return false;
  }
  out.assign(subdevices, v.front());
  if (v.size() == subdevices) {
    out = v;
  }
  return true;
}

int ecat_sim_main(const EcatSimOptions& opt) {
  std::vector<SubdeviceDesc> devs = opt.devices.empty() ? default_segment() : opt.devices;
  std::string err;
  if ((!opt.product_override.empty() &&
       !apply_override(devs, opt.product_override, "--product", &SubdeviceDesc::product_code, err)) ||
      (!opt.revision_override.empty() &&
       !apply_override(devs, opt.revision_override, "--revision", &SubdeviceDesc::revision, err))) {
    std::fprintf(stderr, "ecat-sim: %s\n", err.c_str());
    return 2;
  }
  if (opt.no_distance_sensor) {
    std::erase_if(devs, [](const SubdeviceDesc& d) { return d.product_code == kProductDistance; });
  }
  if (opt.no_safe_terminals) {
    std::erase_if(devs, [](const SubdeviceDesc& d) {
      return d.product_code == kProductSafeIn || d.product_code == kProductSafeOut;
    });
    for (SubdeviceDesc& d : devs) {
      strip_containers(d);
    }
  }
  if (opt.drives_free_run) {
    for (SubdeviceDesc& d : devs) {
      d.dc_sync0_required = false;
    }
  }
  const int raw = open_raw(opt.ifname, err);
  if (raw < 0) {
    std::fprintf(stderr, "ecat-sim: %s\n", err.c_str());
    return 1;
  }
  const int ctl = opt.control.empty() ? -1 : open_control(opt.control, err);
  if (!opt.control.empty() && ctl < 0) {
    std::fprintf(stderr, "ecat-sim: %s\n", err.c_str());
    close(raw);
    return 1;
  }
  realtime(opt.priority, opt.cpu);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::vector<double> drifts;
  if (!opt.drift_ppm.empty() && !parse_drift_ppm(opt.drift_ppm, devs.size(), drifts, err)) {
    std::fprintf(stderr, "ecat-sim: %s\n", err.c_str());
    close(raw);
    if (ctl >= 0) {
      close(ctl);
      unlink(opt.control.c_str());
    }
    return 2;
  }
  EmulatedCell cell(opt.cycle_us, devs, opt.link_seed, opt.link_watchdog_ms);
  cell.set_pacing(opt.lockstep ? EmulatedCell::Pacing::lockstep : EmulatedCell::Pacing::paced);
  for (std::size_t i = 0; i < drifts.size(); ++i) {
    cell.segment().esc(i).set_drift_ppm(drifts[i]);
  }
  if (!opt.sdo_refuse.empty()) {
    const std::string r = control_line(cell, "fault sdo-refuse " + opt.sdo_refuse);
    if (r != "OK") {
      std::fprintf(stderr, "ecat-sim: --sdo-refuse: %s\n", r.c_str());
      close(raw);
      if (ctl >= 0) {
        close(ctl);
        unlink(opt.control.c_str());
      }
      return 2;
    }
  }
  std::fprintf(stderr, "ecat-sim: %zu emulated subdevices on %s%s%s\n", cell.segment().size(), opt.ifname.c_str(),
               opt.control.empty() ? "" : ", control ", opt.control.c_str());
  std::vector<Client> clients;
  while (!g_stop.load()) {
    // During a `freeze` the raw socket is not looked at (its frames wait), the rest runs on.
    const std::uint64_t frozen = cell.segment().frozen_until();
    std::vector<pollfd> fds{{now_ns() < frozen ? -1 : raw, POLLIN, 0}};
    if (ctl >= 0) {
      fds.push_back({ctl, POLLIN, 0});
    }
    for (const Client& c : clients) {
      fds.push_back({c.fd, POLLIN, 0});
    }
    // Awake for the watchdogs every millisecond at least, and at each SYNC0 pulse when it
    // paces the plant (the inputs sampled there are what the next frame carries), a little
    // after it: a frame that reached the interface before the pulse and that the kernel has
    // not handed over yet is then taken first (serve_frames, by its arrival time).
    const std::uint64_t t0 = now_ns();
    std::uint64_t sleep = cell.sleep_ns(t0, 1000000U - kPulseGraceNs) + kPulseGraceNs;
    if (t0 < frozen) {
      sleep = std::min(sleep, frozen - t0);
    }
    const timespec ts{0, static_cast<long>(sleep)};
    ppoll(fds.data(), fds.size(), &ts, nullptr);
    // Frames first, then the watchdogs: a frame that reached the socket while this process
    // waited to be scheduled was on time for a real ESC (which takes it in hardware on
    // arrival); judging the watchdog before taking it would expire it falsely.
    serve_frames(cell, raw);
    cell.poll(now_ns());
    for (std::size_t i = 0; i < clients.size(); ++i) {
      if ((fds[(ctl >= 0 ? 2U : 1U) + i].revents & (POLLIN | POLLHUP)) != 0) {
        serve_client(cell, clients[i]);
      }
    }
    if (ctl >= 0 && (fds[1].revents & POLLIN) != 0) {
      const int c = accept4(ctl, nullptr, nullptr, SOCK_NONBLOCK);
      if (c >= 0 && clients.size() < 8U) {
        clients.push_back({c, {}});
      } else if (c >= 0) {
        close(c);
      }
    }
    std::erase_if(clients, [](const Client& c) { return c.fd < 0; });
  }
  for (const Client& c : clients) {
    close(c.fd);
  }
  if (ctl >= 0) {
    close(ctl);
    unlink(opt.control.c_str());
  }
  close(raw);
  return 0;
}

}  // namespace safestate::ecat

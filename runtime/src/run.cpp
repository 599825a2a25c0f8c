#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "safestate/runtime/runtime.hpp"

extern char** environ;

namespace safestate::runtime {

namespace {

std::string self_exe() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1U);
  return (n > 0) ? std::string(buf, static_cast<std::size_t>(n)) : std::string("safestate");
}

// This process's environment with the tokens set (or removed when there are none), so
// that the gateway child gets them without a command line.
std::vector<std::string> child_environment(const RunOptions& opt) {
  std::vector<std::string> env;
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string v(*e);
    if (v.rfind("SAFESTATE_PENDANT_TOKEN=", 0) != 0 && v.rfind("SAFESTATE_REMOTE_TOKEN=", 0) != 0) {
      env.push_back(v);
    }
  }
  if (!opt.pendant_token.empty()) {
    env.push_back("SAFESTATE_PENDANT_TOKEN=" + opt.pendant_token);
  }
  if (!opt.remote_token.empty()) {
    env.push_back("SAFESTATE_REMOTE_TOKEN=" + opt.remote_token);
  }
  return env;
}

std::vector<char*> pointers(std::vector<std::string>& v) {
  std::vector<char*> p;
  for (std::string& a : v) {
    p.push_back(a.data());
  }
  p.push_back(nullptr);
  return p;
}

pid_t spawn_gateway(const RunOptions& opt, const std::string& shm) {
  const std::string exe = self_exe();
  std::vector<std::string> args = {exe,       "gateway", "--shm",    shm,         "--bind", opt.bind,
                                   "--port",  std::to_string(opt.port), "--db", opt.db, "--static", opt.static_dir};
  args.insert(args.end(), opt.gateway_args.begin(), opt.gateway_args.end());
  std::vector<char*> argv = pointers(args);
  std::vector<std::string> env_strings = child_environment(opt);
  std::vector<char*> envp = pointers(env_strings);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);  // the gateway handles its own SIGTERM
  // Its own process group: a Ctrl-C in the terminal reaches only `safestate run`, which
  // stops the robot first and then the gateway, so the final events are logged.
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETPGROUP);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, exe.c_str(), nullptr, &attr, argv.data(), envp.data());
  posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    std::fprintf(stderr, "safestate run: cannot start the gateway: %s\n", std::strerror(rc));
    return -1;
  }
  return pid;
}

void stop_gateway(pid_t pid) {
  if (pid <= 0) {
    return;
  }
  kill(pid, SIGTERM);
  for (int i = 0; i < 30; ++i) {
    if (waitpid(pid, nullptr, WNOHANG) == pid) {
      return;
    }
    usleep(100000);
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
}

double ms(std::uint64_t ns) { return static_cast<double>(ns) / 1.0e6; }

double mono_s() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<double>(now.tv_sec) + static_cast<double>(now.tv_nsec) / 1.0e9;
}

// A gateway that keeps dying is restarted after 0.5 s, then 1, 2, 4 ... at most 30 s;
// one that ran for a minute starts the series again (protocol.md "One controller").
class Restarts {
 public:
  void started(double now) { started_at_ = now; }
  double exited(double now) {
    delay_ = (now - started_at_ >= 60.0) ? 0.5 : std::min(30.0, (delay_ <= 0.0) ? 0.5 : delay_ * 2.0);
    due_at_ = now + delay_;
    return delay_;
  }
  [[nodiscard]] bool due(double now) const { return now >= due_at_; }

 private:
  double started_at_ = 0.0;
  double delay_ = 0.0;
  double due_at_ = 0.0;
};

}  // namespace

int run_main(const RunOptions& opt) {
  core::Config cfg = opt.core;
  cfg.cycle_us = opt.rt.cycle_us;
  if (const core::ConfigError e = core::validate(cfg); !e.ok()) {
    std::fprintf(stderr, "safestate run: invalid setting %s: %s\n", e.field, e.reason);
    return 2;
  }
  if (opt.rt.watchdog_ms * 1000U < 2U * opt.rt.cycle_us) {
    std::fprintf(stderr, "safestate run: invalid setting watchdog-ms: must span at least two cycles\n");
    return 2;
  }
  const std::string shm = opt.shm.empty() ? bridge::default_segment_name(opt.port) : opt.shm;
  std::string error;
  std::unique_ptr<bridge::Segment> seg = bridge::Segment::create(shm, error);
  if (!seg) {
    std::fprintf(stderr, "safestate run: %s\n", error.c_str());
    return 1;
  }
  // Signals are taken by this (main) thread only, with sigtimedwait.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  sim::Cell cell(cfg);
  RtOptions rt = opt.rt;
  RtLoop loop(*seg, cell, rt);
  std::atomic<bool> stop{false};
  std::atomic<bool> ready{false};
  std::thread rt_thread([&] {
    loop.setup();
    ready.store(true);
    loop.run(stop);
  });
  while (!ready.load()) {
    usleep(1000);
  }
  std::fputs(loop.setup_report().c_str(), stderr);

  pid_t gateway = spawn_gateway(opt, shm);
  std::printf("SafeState running: http://%s:%u  (simulated cell, %u us cycle, events in %s)\n", opt.bind.c_str(),
              opt.port, rt.cycle_us, opt.db.c_str());
  std::printf("Press Ctrl-C for a Cat 1 stop and a clean exit.\n");
  std::fflush(stdout);

  Restarts restarts;
  restarts.started(mono_s());
  for (;;) {
    timespec wait{0, 100000000};
    const int sig = sigtimedwait(&signals, nullptr, &wait);
    if (sig == SIGINT || sig == SIGTERM) {
      break;
    }
    int status = 0;
    if (gateway > 0 && waitpid(gateway, &status, WNOHANG) == gateway) {
      gateway = -1;
      const double delay = restarts.exited(mono_s());
      std::fprintf(stderr,
                   "safestate run: the gateway exited (%s %d); the core keeps cycling; restarting it in %.1f s\n",
                   WIFSIGNALED(status) ? "signal" : "status", WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status),
                   delay);
    }
    if (gateway <= 0 && restarts.due(mono_s())) {
      gateway = spawn_gateway(opt, shm);
      restarts.started(mono_s());
      seg->header().gateway_restarts.fetch_add(1U, std::memory_order_relaxed);
    }
  }
  std::printf("\nsafestate run: stopping (Cat 1) ...\n");
  std::fflush(stdout);
  stop.store(true);
  rt_thread.join();
  stop_gateway(gateway);
  const bridge::Metrics& m = seg->metrics();
  std::printf("safestate run: stopped in state %s after %llu cycles; overruns %llu, max lateness %.3f ms, max cycle %.3f ms\n",
              core::to_string(cell.out().state), static_cast<unsigned long long>(m.cycles.load()),
              static_cast<unsigned long long>(m.overruns.load()), ms(m.lateness_max_ns.load()), ms(m.exec_max_ns.load()));
  return 0;
}

}  // namespace safestate::runtime

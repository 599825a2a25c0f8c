// One channel of SPEC §14 in a process of its own: `safestate-channel` (built by GCC with the
// rest of the tree: channel A) and `safestate-channel-clang` (the same source built by Clang in
// a tree of its own: channel B). Started by `safestate run` (pair/host.hpp), never by hand:
//
//   safestate-channel --shm BASE --channel a|b [--cpu N] [--priority P]
//
// It maps the host's segment read-only (the setup and each cycle's frame), its own segment
// read-write (its reports and its lane of digests) and the other channel's read-only (its
// lane), builds a complete controller (controller::Cell: every monitor, its own platform
// checks over its own code and state) on the frame as its backend, pairs it with the other
// channel over the lanes, and then, in its own real-time loop, runs one cycle per frame: the
// frame's commands, the step, the cross-check, the report. It leaves when the host says stop,
// or when no frame has come for a second (the host is gone: its outputs are then the host's
// concern no more; a real channel would drop its output).
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <string>

#include "safestate/controller/cell.hpp"
#include "safestate/pair/os.hpp"
#include "safestate/pair/shm.hpp"

namespace {

using namespace safestate;

// The frame of this cycle as the controller's backend: read() gives its input image, write()
// keeps the output image for the report.
class FrameBackend final : public hal::Backend {
 public:
  void read(hal::ProcessImageIn& in) noexcept override { in = frame.in; }
  void write(const hal::ProcessImageOut& out) noexcept override { written = out; }
  pair::Frame frame{};
  hal::ProcessImageOut written{};
};

struct Options {
  std::string shm;
  char channel = 0;
  int cpu = -1;
  int priority = 0;
};

int usage(const char* why) {
  std::fprintf(stderr,
               "safestate-channel: %s\nusage: safestate-channel --shm /BASE --channel a|b [--cpu N] [--priority P]\n"
               "(started by `safestate run`; docs/two-channels.md)\n",
               why);
  return 2;
}

bool parse_int(const char* s, int lo, int hi, int& out) {
  char* end = nullptr;
  const long v = std::strtol(s, &end, 10);
  if (end == s || *end != '\0' || v < lo || v > hi) {
    return false;
  }
  out = static_cast<int>(v);
  return true;
}

// The robot model's names, pointed at again in this process.
char g_model_name[pair::kNameLen];
char g_link_names[motion::kLinks][pair::kNameLen];

constexpr std::uint32_t kCompiler =
#if defined(__clang__)
    pair::kClang;
#else
    pair::kGcc;
#endif

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  for (int i = 1; i < argc; i += 2) {  // every option takes one value
    const std::string a = argv[i];
    const char* v = (i + 1 < argc) ? argv[i + 1] : nullptr;
    if (a == "--shm" && v != nullptr) {
      opt.shm = v;
    } else if (a == "--channel" && v != nullptr && (std::strcmp(v, "a") == 0 || std::strcmp(v, "b") == 0)) {
      opt.channel = v[0];
    } else if (a == "--cpu" && v != nullptr) {
      if (!parse_int(v, -1, 1023, opt.cpu)) {
        return usage("--cpu expects a CPU number (or -1)");
      }
    } else if (a == "--priority" && v != nullptr) {
      if (!parse_int(v, 0, 99, opt.priority)) {
        return usage("--priority expects 0..99");
      }
    } else {
      return usage(("unknown or incomplete option: " + a).c_str());
    }
  }
  pair::Names names;
  if (opt.channel == 0 || !pair::make_names(opt.shm.c_str(), names)) {
    return usage("--shm /BASE and --channel a|b are required");
  }
  const bool is_a = opt.channel == 'a';
  const char tag = is_a ? 'A' : 'B';
  std::string err;
  const auto* in = static_cast<const pair::InSegment*>(pair::map_shm(names.in, sizeof(pair::InSegment), false, false, err));
  auto* mine = static_cast<pair::ChannelSegment*>(
      pair::map_shm(is_a ? names.a : names.b, sizeof(pair::ChannelSegment), false, true, err));
  const auto* theirs = static_cast<const pair::ChannelSegment*>(
      pair::map_shm(is_a ? names.b : names.a, sizeof(pair::ChannelSegment), false, false, err));
  if (in == nullptr || mine == nullptr || theirs == nullptr) {
    std::fprintf(stderr, "safestate-channel %c: %s\n", tag, err.c_str());
    return 2;
  }
  // The setup, copied into this process and checked before anything is built from it.
  static pair::Setup setup;
  std::memcpy(static_cast<void*>(&setup), &in->setup, sizeof setup);
  const char* why = nullptr;
  if (in->magic != pair::kMagic || !pair::setup_valid(setup, why)) {
    std::fprintf(stderr, "safestate-channel %c: refused the setup: %s\n", tag,
                 why != nullptr ? why : "not a SafeState host segment");
    return 2;
  }
  std::memcpy(g_model_name, setup.model_name, sizeof g_model_name);
  g_model_name[pair::kNameLen - 1U] = '\0';
  motion::RobotModel model = setup.model;
  model.name = g_model_name;
  for (std::size_t k = 0; k < motion::kLinks; ++k) {
    std::memcpy(g_link_names[k], setup.link_names[k], pair::kNameLen);
    g_link_names[k][pair::kNameLen - 1U] = '\0';
    model.link_names[k] = g_link_names[k];
  }

  // Everything this channel uses, allocated now, before its loop.
  static FrameBackend io;
  static pair::ShmLink link(mine->lane, theirs->lane);
  static controller::Cell* cell = new (std::nothrow) controller::Cell(setup.cfg, model, io);
  if (cell == nullptr) {
    std::fprintf(stderr, "safestate-channel %c: out of memory\n", tag);
    return 2;
  }
  const pair::CodeRegion code = pair::own_code();
  if (code.p == nullptr || !cell->platform().add_rom(code.p, code.n)) {
    std::fprintf(stderr, "safestate-channel %c: warning: its code is not under the platform's CRC check\n", tag);
  }
  std::uint8_t count = 0;
  const motion::Waypoint* program = controller::demo_program(count);
  cell->load_program(program, count);
  cell->configure_limits(setup.limits, setup.validated != 0U);
  cell->configure_brake_test(setup.brake_history);
  cell->pair(is_a ? core::Channel::a : core::Channel::b, link);
  const char* link_why = nullptr;
  if (!cell->configure_links(setup.links, static_cast<std::uint16_t>(setup.link_session_seed), link_why)) {
    std::fprintf(stderr, "safestate-channel %c: the safety connections are refused: %s\n", tag,
                 link_why != nullptr ? link_why : "?");
    return 2;
  }
  static pair::Report report{};
  report.pid = static_cast<std::uint32_t>(getpid());
  report.compiler = kCompiler;

  const std::string rt = pair::realtime(opt.priority, opt.cpu);
  if (!rt.empty()) {
    std::fprintf(stderr, "safestate-channel %c: %s", tag, rt.c_str());
  }
  std::fprintf(stderr, "safestate-channel %c: %s build, pid %d, CPU %d, self-test %s\n", tag,
               kCompiler == pair::kClang ? "Clang" : "GCC", static_cast<int>(getpid()), opt.cpu,
               cell->platform().self_test_ok() ? "passed" : "FAILED");
  mine->ready.store(1U, std::memory_order_release);

  // The loop: one cycle per frame, every frame in order (a channel that was not run for a
  // while catches up; one more than kFrames behind skips, counts it, and is long found lost).
  std::uint64_t last = 0;
  std::uint64_t quiet_since = pair::now_ns();
  static pair::Frame f{};
  while (in->stop.load(std::memory_order_acquire) == 0U) {
    const std::uint32_t word = in->frame_word.load(std::memory_order_acquire);
    const std::uint64_t newest = in->published.load(std::memory_order_acquire);
    if (newest <= last) {
      if (pair::now_ns() - quiet_since > 1000000000ULL) {
        std::fprintf(stderr, "safestate-channel %c: no frame for 1 s: the host is gone, leaving\n", tag);
        return 1;
      }
      static_cast<void>(pair::futex_wait(in->frame_word, word, 100000000ULL));
      continue;
    }
    std::uint64_t next = last + 1U;
    if (newest - next >= pair::kFrames) {
      report.skipped += newest - pair::kFrames + 1U - next;
      next = newest - pair::kFrames + 1U;
    }
    if (!in->frames[next % pair::kFrames].read(f) || f.cycle != next) {
      continue;  // being written over (this channel fell a ring behind): look again
    }
    quiet_since = pair::now_ns();
    const std::uint64_t t0 = quiet_since;
    const std::uint64_t wake = t0 > f.published_ns ? t0 - f.published_ns : 0U;
    if (wake > report.wake_ns_max) {
      report.wake_ns_max = wake;
      report.wake_max_cycle = f.cycle;
    }
    last = next;
    io.frame = f;
    const std::uint32_t n = f.command_count <= f.commands.size() ? f.command_count : 0U;
    for (std::uint32_t i = 0; i < n; ++i) {
      static_cast<void>(cell->submit(f.commands[i]));
    }
    cell->step();
    report.cycle = f.cycle;
    report.own_cycles = cell->now();
    report.out = io.written;
    report.sup = cell->out();
    report.view = cell->view();
    report.view.axis_state = {};
    report.alarms = cell->alarms();
    report.raw = cell->raw_inputs_of_last_cycle();
    report.leaf = static_cast<std::uint8_t>(cell->leaf());
    report.digest = cell->last_digest();
    report.verdict = cell->cross_check().verdict();
    report.integrity_fault = cell->platform().self_test_ok() ? 0U : 1U;
    const std::uint64_t exec = pair::now_ns() - t0;
    report.exec_ns = exec;
    report.exec_ns_max = exec > report.exec_ns_max ? exec : report.exec_ns_max;
    mine->reports[f.cycle % pair::kFrames].write(report);
    mine->reported.store(f.cycle, std::memory_order_release);
    mine->report_word.store(static_cast<std::uint32_t>(f.cycle), std::memory_order_release);
    pair::futex_wake(mine->report_word);
  }
  std::fprintf(stderr, "safestate-channel %c: stopped by the host after %llu cycles\n", tag,
               static_cast<unsigned long long>(cell->now()));
  return 0;
}

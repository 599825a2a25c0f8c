#include "safestate/pair/host.hpp"

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <new>
#include <vector>

#include "safestate/pair/os.hpp"

extern char** environ;

namespace safestate::pair {

ChannelPair::ChannelPair(const core::Config& cfg, hal::Backend& io) noexcept : cfg_(cfg), io_(&io) {
  info_[0].compiler = kGcc;
  info_[1].compiler = kClang;
}

ChannelPair::~ChannelPair() { stop(); }

namespace {

pid_t spawn(const std::string& exe, const std::string& base, char which, int cpu, int priority, std::string& err) {
  std::vector<std::string> args{exe, "--shm", base, "--channel", std::string(1, which), "--cpu", std::to_string(cpu),
                                "--priority", std::to_string(priority)};
  std::vector<char*> argv;
  for (std::string& a : args) {
    argv.push_back(a.data());
  }
  argv.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, exe.c_str(), nullptr, nullptr, argv.data(), environ);
  if (rc != 0) {
    err = "cannot start channel " + std::string(1, which == 'a' ? 'A' : 'B') + " (" + exe + "): " + std::strerror(rc);
    return -1;
  }
  return pid;
}

}  // namespace

// The events of `earlier` (a report the host read in the same look as `later`) kept in
// `later`: its replies and transitions before later's, the alarm changes of both, a finished
// brake test.
void merge_events(const core::SupervisorOut& earlier, core::SupervisorOut& later) noexcept {
  core::SupervisorOut m = later;
  std::size_t n = 0;
  for (std::size_t i = 0; i < earlier.reply_count && n < m.replies.size(); ++i) {
    m.replies[n++] = earlier.replies[i];
  }
  for (std::size_t i = 0; i < later.reply_count && n < m.replies.size(); ++i) {
    m.replies[n++] = later.replies[i];
  }
  m.reply_count = static_cast<std::uint8_t>(n);
  n = 0;
  for (std::size_t i = 0; i < earlier.transition_count && n < m.transitions.size(); ++i) {
    m.transitions[n++] = earlier.transitions[i];
  }
  for (std::size_t i = 0; i < later.transition_count && n < m.transitions.size(); ++i) {
    m.transitions[n++] = later.transitions[i];
  }
  m.transition_count = static_cast<std::uint8_t>(n);
  m.alarms_raised = earlier.alarms_raised | later.alarms_raised;
  m.alarms_cleared = earlier.alarms_cleared | later.alarms_cleared;
  if (m.brake_test.finished == core::BrakeTestResult::none) {
    m.brake_test.finished = earlier.brake_test.finished;
  }
  later = m;
}

bool ChannelPair::start(const PairOptions& opt, const motion::RobotModel& model, const core::SafetyLimits& limits,
                        bool validated, const core::BrakeTestHistory& brake_history, std::string& err) {
  const std::string base = opt.shm_base.empty() ? "/safestate-ch-" + std::to_string(getpid()) : opt.shm_base;
  if (!make_names(base.c_str(), names_)) {
    err = "the channels' shared-memory name must start with '/' and be short: " + base;
    return false;
  }
  for (const char* n : {names_.in, names_.a, names_.b}) {
    remove_shm(n);  // a crashed run's leftovers (our own names: this PID)
  }
  in_ = static_cast<InSegment*>(map_shm(names_.in, sizeof(InSegment), true, true, err));
  void* a = (in_ != nullptr) ? map_shm(names_.a, sizeof(ChannelSegment), true, true, err) : nullptr;
  void* b = (a != nullptr) ? map_shm(names_.b, sizeof(ChannelSegment), true, true, err) : nullptr;
  if (b == nullptr) {
    stop();
    return false;
  }
  new (in_) InSegment();
  new (a) ChannelSegment();
  new (b) ChannelSegment();
  static_cast<ChannelSegment*>(a)->magic = kMagic;
  static_cast<ChannelSegment*>(b)->magic = kMagic;
  ch_[0] = static_cast<const ChannelSegment*>(a);
  ch_[1] = static_cast<const ChannelSegment*>(b);
  // The host keeps write access to the channels' segments only to set them up: from here on
  // it only reads them (the channels write); a mapping read-only would need the segment
  // created by the channel itself, which would leave the host's set-up racing the channel.
  Setup& s = in_->setup;
  s.cfg = cfg_;
  s.limits = limits;
  s.validated = validated ? 1U : 0U;
  s.brake_history = brake_history;
  s.links = io_->safety_links();
  s.link_session_seed = random_session();
  seal_setup(s, model);
  in_->version = kVersion;
  in_->magic = kMagic;
  budget_ns_ = (opt.budget_us != 0U ? opt.budget_us : cfg_.cycle_us * 3U / 4U) * 1000ULL;

  pid_[0] = spawn(opt.exe_a, base, 'a', opt.cpu_a, opt.priority, err);
  pid_[1] = (pid_[0] > 0) ? spawn(opt.exe_b, base, 'b', opt.cpu_b, opt.priority, err) : -1;
  if (pid_[1] <= 0) {
    stop();
    return false;
  }
  const std::uint64_t deadline = now_ns() + 10000000000ULL;
  while (ch_[0]->ready.load(std::memory_order_acquire) == 0U || ch_[1]->ready.load(std::memory_order_acquire) == 0U) {
    reap();
    if (!info_[0].running || !info_[1].running || now_ns() > deadline) {
      err = std::string("channel ") + (!info_[0].running ? "A" : !info_[1].running ? "B" : "A or B") +
            (now_ns() > deadline ? " was not ready within 10 s" : " ended during its start (its message above)");
      stop();
      return false;
    }
    usleep(2000);
  }
  for (std::size_t i = 0; i < 2U; ++i) {
    info_[i].pid = static_cast<std::uint32_t>(pid_[i]);
  }
  started_ = true;
  return true;
}

void ChannelPair::reap() noexcept {
  for (std::size_t i = 0; i < 2U; ++i) {
    if (pid_[i] <= 0) {
      info_[i].running = false;
      continue;
    }
    int status = 0;
    const pid_t r = waitpid(pid_[i], &status, WNOHANG);
    if (r == pid_[i]) {
      info_[i].running = false;
      info_[i].exit_status = status;
      pid_[i] = -1;
    } else {
      info_[i].running = true;
    }
  }
}

void ChannelPair::stop() noexcept {
  if (in_ != nullptr) {
    in_->stop.store(1U, std::memory_order_release);
    in_->frame_word.fetch_add(1U, std::memory_order_release);
    futex_wake(in_->frame_word);
  }
  const std::uint64_t deadline = now_ns() + 1000000000ULL;
  for (std::size_t i = 0; i < 2U; ++i) {
    while (pid_[i] > 0) {
      int status = 0;
      const pid_t r = waitpid(pid_[i], &status, WNOHANG);
      if (r == pid_[i] || r < 0) {
        info_[i].exit_status = status;
        pid_[i] = -1;
        break;
      }
      if (now_ns() > deadline) {
        kill(pid_[i], SIGKILL);
        static_cast<void>(waitpid(pid_[i], &status, 0));
        pid_[i] = -1;
        break;
      }
      usleep(2000);
    }
    info_[i].running = false;
  }
  if (in_ != nullptr) {
    unmap_shm(in_, sizeof(InSegment));
    in_ = nullptr;
  }
  for (std::size_t i = 0; i < 2U; ++i) {
    if (ch_[i] != nullptr) {
      unmap_shm(const_cast<ChannelSegment*>(ch_[i]), sizeof(ChannelSegment));
      ch_[i] = nullptr;
    }
  }
  if (names_.in[0] != '\0') {
    remove_shm(names_.in);
    remove_shm(names_.a);
    remove_shm(names_.b);
    names_ = Names{};
  }
  started_ = false;
}

core::Result ChannelPair::submit(const core::Command& c) noexcept {
  const std::size_t limit = cfg_.queue_size < queue_.size() ? cfg_.queue_size : queue_.size();
  if (queue_count_ >= limit) {
    return core::Result::QUEUE_FULL;
  }
  queue_[(queue_head_ + queue_count_) % queue_.size()] = c;
  ++queue_count_;
  return core::Result::OK;
}

// @req CH-PAIR CH-PROCESSES
void ChannelPair::step() noexcept {
  ++cycle_;
  io_->read(frame_.in);
  frame_.cycle = cycle_;
  const std::size_t per_cycle =
      cfg_.max_commands_per_cycle < frame_.commands.size() ? cfg_.max_commands_per_cycle : frame_.commands.size();
  std::size_t n = 0;
  while (queue_count_ > 0U && n < per_cycle) {
    frame_.commands[n++] = queue_[queue_head_];
    queue_head_ = (queue_head_ + 1U) % queue_.size();
    --queue_count_;
  }
  frame_.command_count = static_cast<std::uint32_t>(n);
  if (!started_) {
    return;
  }
  frame_.published_ns = now_ns();
  in_->frames[cycle_ % kFrames].write(frame_);
  in_->published.store(cycle_, std::memory_order_release);
  in_->frame_word.store(static_cast<std::uint32_t>(cycle_), std::memory_order_release);
  futex_wake(in_->frame_word);

  // Both reports of this cycle, until the budget is spent. A channel catching up may have
  // written several since the last look: every one is read, its events kept (merge_events).
  const std::uint64_t deadline = now_ns() + budget_ns_;
  std::array<bool, 2> have{};
  std::array<bool, 2> fresh{};
  for (;;) {
    for (std::size_t i = 0; i < 2U; ++i) {
      const std::uint64_t newest = ch_[i]->reported.load(std::memory_order_acquire);
      std::uint64_t next = seen_[i] + 1U;
      if (newest >= next && newest - next >= kFrames) {
        next = newest - kFrames + 1U;  // older ones are written over (and the channel long lost)
      }
      Report r;
      while (next <= newest && ch_[i]->reports[next % kFrames].read(r) && r.cycle == next) {
        if (fresh[i]) {
          merge_events(reports_[i].sup, r.sup);
        }
        reports_[i] = r;
        outputs_[i] = r.out;
        fresh[i] = true;
        seen_[i] = next;
        ++next;
      }
      have[i] = seen_[i] >= cycle_;
    }
    const std::uint64_t now = now_ns();
    if ((have[0] && have[1]) || now >= deadline) {
      break;
    }
    const std::size_t wait_on = have[0] ? 1U : 0U;
    const std::uint32_t word = ch_[wait_on]->report_word.load(std::memory_order_acquire);
    if (word != static_cast<std::uint32_t>(cycle_)) {
      static_cast<void>(futex_wait(ch_[wait_on]->report_word, word, deadline - now));
    }
  }
  reap();
  for (std::size_t i = 0; i < 2U; ++i) {
    info_[i].answered = have[i];
    info_[i].cycle = seen_[i];
    if (!have[i]) {
      ++info_[i].late;
    }
    if (!fresh[i]) {
      // An old report says nothing happened in this cycle: its replies, transitions, alarm
      // changes and brake-test result were published in their own cycle.
      core::SupervisorOut& o = reports_[i].sup;
      o.reply_count = 0;
      o.transition_count = 0;
      o.alarms_raised = 0;
      o.alarms_cleared = 0;
      o.brake_test.finished = core::BrakeTestResult::none;
    }
    if (!info_[i].running) {
      outputs_[i] = hal::ProcessImageOut{};  // its process ended: its outputs drop
    }
  }
  // The drives' set-points come from A. When A's of this cycle did not come in time (its
  // process was woken late: a fraction of a cycle on this kind of host), the host does what a
  // CSP drive's interpolation does with a set-point that did not arrive: it goes on along the
  // last step for as long as the pair tolerates A's silence (cross_check_cycles + 1 cycles:
  // later, B has found A lost and opened K2), then holds (ecat-sim's drives extrapolate too,
  // docs/ethercat.md). Holding at once would make the arm stop dead for a cycle and jump the
  // next: a jerk the collision monitor rightly reads as a contact (docs/two-channels.md).
  // Motion set-points only: the safety outputs (contactors, brakes, enable) are the
  // channels' as they last wrote them.
  hal::ProcessImageOut a = outputs_[0];
  if (fresh[0]) {
    // The step per cycle since the last set-points A gave (several cycles, after a late one).
    const std::uint64_t span = reports_[0].cycle - last_target_cycle_;
    for (std::size_t k = 0; k < hal::kAxes; ++k) {
      step_rad_[k] = (last_target_cycle_ != 0U && span > 0U)
                         ? (a.drive[k].target_position_rad - last_target_rad_[k]) / static_cast<float>(span)
                         : 0.0F;
      last_target_rad_[k] = a.drive[k].target_position_rad;
    }
    last_target_cycle_ = reports_[0].cycle;
    extrapolated_ = 0;
  } else if (info_[0].running) {
    if (extrapolated_ < cfg_.cross_check_cycles + 1U) {
      ++extrapolated_;
      ++info_[0].extrapolated;
    }  // beyond: held where the extrapolation ended
    for (std::size_t k = 0; k < hal::kAxes; ++k) {
      a.drive[k].target_position_rad = last_target_rad_[k] + (step_rad_[k] * static_cast<float>(extrapolated_));
    }
  }
  combined_ = controller::combine_outputs(a, outputs_[1]);
  io_->write(combined_);

  b_leads_ = controller::together(
      {&reports_[0].sup, &reports_[0].alarms, static_cast<core::Leaf>(reports_[0].leaf)},
      {&reports_[1].sup, &reports_[1].alarms, static_cast<core::Leaf>(reports_[1].leaf)}, out_, alarms_, leaf_);
  // The arm as channel A measured it (B measures the same image); the power path as wired.
  view_ = reports_[0].view;
  view_.k2_closed = frame_.in.k2_closed;
  view_.two_contactors = frame_.in.two_contactors;
  raw_ = reports_[b_leads_ ? 1U : 0U].raw;
}

bool ChannelPair::channel_status(std::size_t i, controller::ChannelStatus& out) const noexcept {
  if (i > 1U) {
    return false;
  }
  const Report& r = reports_[i];
  const ChannelInfo& c = info_[i];
  out = controller::ChannelStatus{};
  out.present = true;
  out.running = c.running;
  out.answered = c.answered;
  out.pid = c.pid;
  out.compiler = static_cast<std::uint8_t>(r.compiler != 0U ? r.compiler : c.compiler);
  out.cycle = c.cycle;
  out.late = c.late;
  out.skipped = r.skipped;
  out.state = r.sup.state;
  out.leaf = static_cast<core::Leaf>(r.leaf);
  out.digest_crc = r.digest.crc;
  out.agree = !r.verdict.mismatch && !r.verdict.lost;
  out.field = r.verdict.field;
  out.missing = r.verdict.missing;
  out.wake_max_us = static_cast<std::uint32_t>(r.wake_ns_max / 1000U);
  out.exec_max_us = static_cast<std::uint32_t>(r.exec_ns_max / 1000U);
  return true;
}

}  // namespace safestate::pair

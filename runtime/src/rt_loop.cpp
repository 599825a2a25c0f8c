#include <fcntl.h>
#include <pthread.h>
#include <unistd.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>

#include <cerrno>
#include <cstring>

#include "safestate/runtime/runtime.hpp"
#include "safestate/vocab/faults.hpp"
#include "safestate/vocab/inputs.hpp"

namespace safestate::runtime {

namespace {

std::uint64_t now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL) + static_cast<std::uint64_t>(ts.tv_nsec);
}

timespec to_timespec(std::uint64_t ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1000000000ULL);
  ts.tv_nsec = static_cast<long>(ns % 1000000000ULL);
  return ts;
}

void store_max(std::atomic<std::uint64_t>& m, std::uint64_t v) noexcept {
  std::uint64_t cur = m.load(std::memory_order_relaxed);
  while (v > cur && !m.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

std::uint32_t contacts_of(const core::RawInputs& r) noexcept {
  std::uint32_t m = 0;
  for (std::size_t i = 0; i < bridge::kContactCount; ++i) {
    m |= vocab::contact_of(r, static_cast<vocab::Contact>(i)) ? (1U << i) : 0U;
  }
  return m;
}

void apply_contacts(const bridge::CommandRecord& rec, core::RawInputs& r) noexcept {
  for (std::size_t i = 0; i < bridge::kContactCount; ++i) {
    if ((rec.set_mask & (1U << i)) != 0U) {
      vocab::apply(vocab::ContactWrite{static_cast<vocab::Contact>(i), (rec.set_values & (1U << i)) != 0U}, r);
    }
  }
  // SPEC §11's distance sensor, as the scenario format's `in separation_mm=N`: a reading
  // given is valid unless the record says otherwise.
  if ((rec.separation_set & bridge::kSetSeparation) != 0U) {
    r.separation_mm = rec.separation_mm;
    r.separation_valid = true;
  }
  if ((rec.separation_set & bridge::kSetValid) != 0U) {
    r.separation_valid = (rec.separation_set & bridge::kSeparationValid) != 0U;
  }
}

// @req COL-SIM-PERSON
// A `sim` person record (bridge::PersonRecord) as the world's all-or-nothing change. The
// gateway has checked the values already; the world does not trust it.
bridge::SimResult apply_person(const bridge::PersonRecord& p, vocab::World& world) noexcept {
  static_assert(bridge::kPersonPoints == vocab::kPersonMaxWaypoints);
  constexpr unsigned kAll = bridge::kPersonFields | bridge::kPersonAt | bridge::kPersonWalk | bridge::kPersonStand |
                           bridge::kPersonLeave;
  if ((static_cast<unsigned>(p.what) & ~kAll) != 0U) {
    return bridge::SimResult::person_invalid;  // an unknown bit (the world judges the combinations)
  }
  vocab::PersonCommand c{};
  c.fields = (p.what & bridge::kPersonFields) != 0U;
  c.outer_mm = p.fields_outer_mm;
  c.inner_mm = p.fields_inner_mm;
  c.at = (p.what & bridge::kPersonAt) != 0U;
  c.x_mm = p.x_mm;
  c.y_mm = p.y_mm;
  c.radius_mm = p.radius_mm;
  c.walk = (p.what & bridge::kPersonWalk) != 0U;
  c.points = p.points;
  for (std::size_t i = 0; i < c.path.size(); ++i) {
    c.path[i] = vocab::PersonWaypoint{p.path[i].x_mm, p.path[i].y_mm, p.path[i].speed_mm_s, p.path[i].stand_ms};
  }
  c.stand = (p.what & bridge::kPersonStand) != 0U;
  c.leave = (p.what & bridge::kPersonLeave) != 0U;
  switch (world.person(c)) {
    case vocab::PersonResult::ok: return bridge::SimResult::ok;
    case vocab::PersonResult::absent: return bridge::SimResult::person_absent;
    case vocab::PersonResult::invalid: break;
  }
  return bridge::SimResult::person_invalid;
}

}  // namespace

// ------------------------------------------------------------------ Publisher
void Publisher::event(const bridge::EventRecord& e) noexcept {
  if (!seg_.events().push(e)) {
    seg_.metrics().events_dropped.fetch_add(1, std::memory_order_relaxed);
  }
}

void Publisher::reply(const bridge::ReplyRecord& r) noexcept {
  if (!seg_.replies().push(r)) {
    seg_.metrics().replies_dropped.fetch_add(1, std::memory_order_relaxed);
  }
}

void Publisher::publish() noexcept {
  const core::SupervisorOut& o = cell_.out();
  const controller::CellView& v = cell_.view();
  const core::AlarmSet& alarms = cell_.alarms();
  const std::uint64_t t = cell_.now() - 1U;  // the cycle just run

  for (std::size_t i = 0; i < o.reply_count; ++i) {
    const core::Reply& r = o.replies[i];
    bridge::ReplyRecord rr{};
    rr.seq = r.seq;
    rr.kind = bridge::RecordKind::command;
    rr.cmd = r.cmd;
    rr.source = r.source;
    rr.result = r.result;
    rr.t = t;
    if (r.source != static_cast<std::uint8_t>(core::Source::reset_button)) {
      reply(rr);
    }
    bridge::EventRecord e{};
    e.t = t;
    e.kind = bridge::EventKind::command;
    e.reply = r;
    e.cause = o.cause;
    event(e);
  }
  for (std::size_t i = 0; i < o.transition_count; ++i) {
    const core::TransitionEvent& tr = o.transitions[i];
    bridge::EventRecord e{};
    e.t = t;
    e.kind = bridge::EventKind::transition;
    e.from = tr.from;
    e.to = tr.to;
    e.stop = tr.stop;
    e.trigger = static_cast<std::uint8_t>(tr.trigger);
    e.row = tr.row;
    e.cause = o.cause;
    event(e);
  }
  // @req BT-PERSIST
  // SPEC §12: a finished brake test becomes a `brake_test` event of the log (found again
  // at the next start by run.cpp).
  if (o.brake_test.finished != core::BrakeTestResult::none) {
    bridge::EventRecord e{};
    e.t = t;
    e.kind = bridge::EventKind::brake_test;
    e.brake_result = static_cast<std::uint8_t>(o.brake_test.finished);
    e.brake_axis = (o.brake_test.finished == core::BrakeTestResult::failed)
                       ? alarms.detail(core::AlarmId::BRAKE_TEST_FAILED).axis
                       : std::uint8_t{0U};
    e.brake_drift_deg = o.brake_test.drift_deg;
    e.cause = o.cause;
    event(e);
  }
  for (std::size_t a = 0; a < core::kAlarmCount; ++a) {
    const auto id = static_cast<core::AlarmId>(a);
    const bool raised = (o.alarms_raised & core::bit(id)) != 0U;
    const bool cleared = (o.alarms_cleared & core::bit(id)) != 0U;
    if (raised || cleared) {
      bridge::EventRecord e{};
      e.t = t;
      e.kind = raised ? bridge::EventKind::alarm : bridge::EventKind::alarm_cleared;
      e.alarm = id;
      e.detail = alarms.detail(id);
      e.cause = o.cause;
      event(e);
    }
  }

  bridge::Status s{};
  s.t = t;
  s.state = o.state;
  s.sub = o.sub;
  s.mode = o.mode;
  s.mode_requested = o.mode_requested;
  s.stop = o.stop;
  s.target = o.target;
  s.contactor = o.contactor;
  s.drives = o.drives_enable;
  s.brakes_released = o.brakes_release;
  s.reset_lamp = o.reset_lamp;
  s.t2_confirmed = o.t2_confirmed;
  s.simulated = simulated_;
  s.arming_step = o.arming_step;
  s.arming_progress = o.arming_progress;
  s.program_index = v.program_index;
  s.program_length = v.program_length;
  s.alarms = o.alarms;
  s.cause = o.cause;
  s.tcp_speed_mm_s = v.tcp_speed_mm_s;
  s.max_point_speed_mm_s = v.max_point_speed_mm_s;
  s.joints = v.joints_rad;
  s.tcp = v.tcp;
  for (std::size_t i = 0; i < 6; ++i) {
    s.axis_state[i] = v.axis_code[i];
    s.statusword[i] = v.statusword[i];
  }
  for (std::size_t a = 0; a < core::kAlarmCount; ++a) {
    s.alarm_since[a] = alarms.since(static_cast<core::AlarmId>(a));
    s.alarm_detail[a] = alarms.detail(static_cast<core::AlarmId>(a));
  }
  s.safety = o.safety;
  // @req COL-SIM-PERSON
  s.person_shown = person_;
  if (person_ && world_ != nullptr) {
    const vocab::PersonView& pv = world_->person_view();
    s.person_present = pv.present;
    s.person_walking = pv.walking;
    s.person_in_outer = pv.outer_interrupted;
    s.person_in_inner = pv.inner_interrupted;
    s.person_scanner = pv.sensors.scanner;
    s.person_distance_sensor = pv.sensors.distance_sensor;
    s.person_nearest_point = pv.nearest_point;
    s.person_x_mm = pv.x_mm;
    s.person_y_mm = pv.y_mm;
    s.person_radius_mm = pv.radius_mm;
    s.person_speed_mm_s = pv.speed_mm_s;
    s.person_separation_mm = pv.separation_mm;
    s.person_outer_mm = pv.sensors.outer_mm;
    s.person_inner_mm = pv.sensors.inner_mm;
  }
  s.brake_test = o.brake_test;
  // @req CH-PAIR CH-PROCESSES
  s.channel_count = cell_.count();
  for (std::size_t i = 0; i < s.channels.size(); ++i) {
    controller::ChannelStatus c{};
    if (!cell_.channel_status(i, c)) {
      continue;
    }
    bridge::ChannelRecord& r = s.channels[i];
    r.present = 1U;
    r.running = c.running ? 1U : 0U;
    r.answered = c.answered ? 1U : 0U;
    r.agree = c.agree ? 1U : 0U;
    r.compiler = c.compiler;
    r.state = c.state;
    r.leaf = c.leaf;
    r.field = c.field;
    r.pid = c.pid;
    r.digest_crc = c.digest_crc;
    r.missing = c.missing;
    r.wake_max_us = c.wake_max_us;
    r.exec_max_us = c.exec_max_us;
    r.cycle = c.cycle;
    r.late = c.late;
    r.skipped = c.skipped;
  }
  // K2 where the backend has it: with two channels, or one channel on a segment with K2
  // (which that one channel drives with K1).
  s.two_contactors = cell_.count() == 2U || v.two_contactors;
  s.k1_closed = v.contactor_closed;
  s.k2_closed = v.k2_closed;
  seg_.status().write(s);

  bridge::BlackBoxRecord b{};
  b.t = t;
  b.contacts = contacts_of(cell_.raw_inputs_of_last_cycle());
  b.contactor_fb = v.contactor_closed ? 1U : 0U;
  for (std::size_t i = 0; i < 6; ++i) {
    b.brakes_fb = static_cast<std::uint8_t>(b.brakes_fb | (v.brake_released[i] ? (1U << i) : 0U));
    b.statusword[i] = v.statusword[i];
    b.controlword[i] = v.controlword[i];
    b.position[i] = v.joints_rad[i];
    b.target[i] = v.target_rad[i];
  }
  b.fieldbus_ok = v.fieldbus_ok ? 1U : 0U;
  b.leaf = static_cast<std::uint8_t>(cell_.leaf());
  b.outputs = controller::output_bits(o);
  seg_.blackbox()[t % bridge::kBlackBoxCycles].write(b);
  seg_.header().core_heartbeat.store(t + 1U, std::memory_order_release);
}

void take_record(const bridge::CommandRecord& rec, controller::Channels& cell, vocab::World* world, Publisher& pub,
                 std::uint64_t t, SimForward* forward) noexcept {
  bridge::ReplyRecord r{};
  r.seq = rec.seq;
  r.kind = rec.kind;
  r.t = t;
  if (rec.kind == bridge::RecordKind::command) {
    core::Command c = rec.command;
    c.seq = rec.seq;
    if (cell.submit(c) == core::Result::QUEUE_FULL) {
      r.cmd = c.id;
      r.source = c.source;
      r.result = core::Result::QUEUE_FULL;
      pub.reply(r);
    }
    return;  // otherwise the core answers in the cycle that takes it
  }
  if (forward != nullptr) {
    // The person of an emulated segment is ecat-sim's, moved by its control socket's
    // `person` lines; a `sim` person record is not forwarded there (the forwarding is
    // asynchronous: a walk the emulator refused could not be answered): refused, never dropped.
    if (rec.kind == bridge::RecordKind::sim_person) {
      r.sim = bridge::SimResult::person_not_on_bus;
    } else {
      r.sim = forward->push(rec) ? bridge::SimResult::ok : bridge::SimResult::not_simulated;
    }
    pub.reply(r);
    return;
  }
  if (world == nullptr) {
    r.sim = bridge::SimResult::not_simulated;
    pub.reply(r);
    return;
  }
  r.sim = bridge::SimResult::ok;
  switch (rec.kind) {
    case bridge::RecordKind::command: return;
    case bridge::RecordKind::sim_set: apply_contacts(rec, world->inputs()); break;
    case bridge::RecordKind::sim_fault: {
      // The gateway has checked the fault; the runtime does not trust it (vocab::injectable).
      const vocab::Fault f{static_cast<vocab::FaultKind>(rec.fault_kind), rec.fault_axis, rec.fault_value};
      if (vocab::injectable(f.kind, vocab::FaultSource::network)) {
        world->inject(f);
      }
      break;
    }
    case bridge::RecordKind::sim_person: r.sim = apply_person(rec.person, *world); break;
  }
  pub.reply(r);
}

// ------------------------------------------------------------------ RtLoop
RtLoop::RtLoop(bridge::Segment& seg, controller::Channels& cell, vocab::World* world, const RtOptions& opt) noexcept
    : seg_(seg), cell_(cell), world_(world), opt_(opt), pub_(seg, cell, world, opt.simulated) {}

RtLoop::~RtLoop() {
  if (dma_latency_fd_ >= 0) {
    close(dma_latency_fd_);
  }
}

void RtLoop::setup() {
  report_.clear();
  // Keep the CPUs out of deep idle states while the loop runs (as cyclictest does): a
  // wake-up from C6 can take longer than the whole scan cycle. Held until the loop ends.
  if (dma_latency_fd_ < 0) {
    dma_latency_fd_ = open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
    const std::int32_t zero = 0;
    if (dma_latency_fd_ < 0 || write(dma_latency_fd_, &zero, sizeof zero) != static_cast<ssize_t>(sizeof zero)) {
      report_ += std::string("note: /dev/cpu_dma_latency not available (") + std::strerror(errno) +
                 "), CPU idle states may add wake-up latency\n";
    }
  }
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    report_ += std::string("warning: mlockall failed (") + std::strerror(errno) + "), memory may page\n";
  }
  if (opt_.priority > 0) {
    sched_param sp{};
    sp.sched_priority = opt_.priority;
    const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (rc != 0) {
      report_ += std::string("warning: SCHED_FIFO not permitted (") + std::strerror(rc) +
                 "), running with normal scheduling\n";
    } else {
      seg_.metrics().rt_priority.store(static_cast<std::uint32_t>(opt_.priority), std::memory_order_relaxed);
    }
  }
  if (opt_.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(opt_.cpu), &set);
    const int rc = pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
    if (rc != 0) {
      report_ += std::string("warning: cannot pin to CPU ") + std::to_string(opt_.cpu) + " (" + std::strerror(rc) + ")\n";
    }
  }
  seg_.metrics().cycle_us.store(opt_.cycle_us, std::memory_order_relaxed);
  seg_.header().simulated.store(opt_.simulated ? 1U : 0U, std::memory_order_relaxed);
}

void RtLoop::one_cycle() noexcept {
  bridge::CommandRecord rec{};
  for (std::uint32_t k = 0; k < opt_.max_records_per_cycle && seg_.commands().pop(rec); ++k) {
    take_record(rec, cell_, world_, pub_, cell_.now(), opt_.sim_forward);
  }
  seg_.metrics().command_queue_depth.store(static_cast<std::uint32_t>(seg_.commands().size()),
                                           std::memory_order_relaxed);
  cell_.step();
  if (cell_.view().inputs_stale) {
    seg_.metrics().fieldbus_stale_cycles.fetch_add(1, std::memory_order_relaxed);
  }
  pub_.publish();
}

void RtLoop::run(const std::atomic<bool>& stop, std::uint64_t shutdown_cycles) {
  bridge::Metrics& m = seg_.metrics();
  const std::uint64_t period = static_cast<std::uint64_t>(opt_.cycle_us) * 1000ULL;
  const std::uint64_t watchdog = static_cast<std::uint64_t>(opt_.watchdog_ms) * 1000000ULL;
  std::uint64_t next = now_ns() + period;
  std::uint64_t last_start = 0;
  bool stopping = false;
  std::uint64_t stop_cycles = 0;
  for (;;) {
    const timespec ts = to_timespec(next);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const std::uint64_t start = now_ns();
    const std::uint64_t late = (start > next) ? start - next : 0U;
    m.lateness_ns[bridge::histogram_bucket(late)].fetch_add(1, std::memory_order_relaxed);
    store_max(m.lateness_max_ns, late);
    const std::uint64_t k = m.cycles.load(std::memory_order_relaxed);
    if (k < lateness_log_.size()) {
      lateness_log_[k] = static_cast<std::uint32_t>((late < 0xFFFFFFFFULL) ? late : 0xFFFFFFFFULL);
    }
    // A stall longer than the fieldbus watchdog: real EtherCAT drives would have seen
    // their process data stop; so do the simulated ones, and the core locks out.
    if (last_start != 0U && (start - last_start) > watchdog) {
      if (world_ != nullptr) {
        world_->host_stalled();
      }
      m.watchdog_trips.fetch_add(1, std::memory_order_relaxed);
    }
    last_start = start;

    if (stop.load(std::memory_order_relaxed) && !stopping) {
      stopping = true;  // Ctrl-C: a Cat 1 stop (servo_off) before leaving, if powered
      seg_.header().shutting_down.store(1U, std::memory_order_relaxed);
      const core::State s = cell_.out().state;
      if (s == core::State::ARMING || s == core::State::OPERATIONAL || s == core::State::STOPPING) {
        core::Command c{};
        c.seq = 0xFFFFFFFFU;
        c.id = static_cast<std::uint8_t>(core::CommandId::servo_off);
        c.source = static_cast<std::uint8_t>(core::Source::pendant);  // the local operator's Ctrl-C
        static_cast<void>(cell_.submit(c));
      }
    }
    one_cycle();

    const std::uint64_t end = now_ns();
    const std::uint64_t exec = end - start;
    m.exec_ns[bridge::histogram_bucket(exec)].fetch_add(1, std::memory_order_relaxed);
    store_max(m.exec_max_ns, exec);
    m.cycles.fetch_add(1, std::memory_order_relaxed);

    if (stopping) {
      const core::State s = cell_.out().state;
      const bool powered = s == core::State::ARMING || s == core::State::OPERATIONAL || s == core::State::STOPPING;
      if ((!powered && stop_cycles > 0U) || ++stop_cycles > shutdown_cycles) {
        return;
      }
    }
    next += period;
    if (opt_.cycle_adjust_ns != nullptr) {  // the cycle follows DC time (bounded by the bus: 1/20 cycle)
      next = static_cast<std::uint64_t>(static_cast<std::int64_t>(next) +
                                        opt_.cycle_adjust_ns->exchange(0, std::memory_order_relaxed));
    }
    if (end > next) {  // the next deadline has already passed: count it, do not burst
      m.overruns.fetch_add(1, std::memory_order_relaxed);
      next = end + period - ((end - next) % period);
    }
    seg_.header().next_cycle_ns.store(next, std::memory_order_release);
  }
}

}  // namespace safestate::runtime

// The shared-memory bridge between the real-time core process and the non-real-time
// gateway (protocol.md: "the real-time core never parses network input").
//
// One POSIX shared-memory segment: a header (magic, layout version, size, offsets),
// then fixed regions located by offsets, never pointers:
//   - command ring  (gateway -> core): fixed-size binary records with sequence numbers
//   - reply ring    (core -> gateway): one reply per command record, echoing its seq
//   - event ring    (core -> gateway): transitions, alarms, alarm clears, command results
//   - status        (core -> gateway): a seqlock snapshot, rewritten every cycle
//   - black box     (core -> gateway): the last kBlackBoxCycles cycles of inputs/outputs
//   - metrics       (core -> gateway): cycle time / lateness histograms, overruns
//   - heartbeats both ways.
// Every ring is single-producer single-consumer; the core side never blocks, waits or
// allocates: a full ring drops the record and counts it.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "safestate/core/alarms.hpp"
#include "safestate/vocab/inputs.hpp"
#include "safestate/core/safety_status.hpp"
#include "safestate/core/states.hpp"
#include "safestate/core/types.hpp"

namespace safestate::bridge {

inline constexpr std::uint32_t kMagic = 0x53534252U;  // "SSBR"
inline constexpr std::uint32_t kLayoutVersion = 9U;  // 2: instance, gateway_restarts; 3: bus; 4: safety, reduced; 5: fields, SSM, brake test; 6: stale cycles; 7: fault value, pfl and contact force; 8: the simulated person (record and status); 9: the channels (SPEC §14)

// ------------------------------------------------------------------ records
enum class RecordKind : std::uint8_t { command, sim_set, sim_fault, sim_person };

// Contacts a `sim` message may set: the vocabulary's (vocab/inputs.hpp), bit i = Contact i.
using vocab::Contact;
inline constexpr std::size_t kContactCount = vocab::kContacts;
static_assert(kContactCount <= 32U, "set_mask and contacts are 32-bit");

// A `sim` record's distance sensor (SPEC §11): which of separation_mm / separation_valid it writes.
inline constexpr std::uint8_t kSetSeparation = 0x01U;    // separation_mm written (and valid, unless kSetValid)
inline constexpr std::uint8_t kSetValid = 0x02U;         // separation_valid written ...
inline constexpr std::uint8_t kSeparationValid = 0x04U;  // ... with this value

// A `sim` record's person (SPEC §11, sim::Person; the scenario's `person` keys): what it
// does, as kPerson* bits. The runtime applies them in this order, all or nothing: the
// field radii, `at` (place, standing), `walk` (the path from where it then is); `stand`
// and `leave` come alone.
inline constexpr std::uint8_t kPersonFields = 0x01U;  // fields_outer_mm / fields_inner_mm
inline constexpr std::uint8_t kPersonAt = 0x02U;      // x_mm, y_mm, radius_mm
inline constexpr std::uint8_t kPersonWalk = 0x04U;    // path[0 .. points)
inline constexpr std::uint8_t kPersonStand = 0x08U;
inline constexpr std::uint8_t kPersonLeave = 0x10U;
inline constexpr std::size_t kPersonPoints = 16;  // sim::kPersonMaxWaypoints
struct PersonPoint {  // sim::PersonWaypoint
  float x_mm = 0.0F;
  float y_mm = 0.0F;
  float speed_mm_s = 0.0F;
  std::uint32_t stand_ms = 0;
};
struct PersonRecord {
  std::uint8_t what = 0;    // kPerson* bits
  std::uint8_t points = 0;  // kPersonWalk: how many of `path`
  std::uint8_t pad[2]{};
  float x_mm = 0.0F;        // kPersonAt
  float y_mm = 0.0F;
  float radius_mm = 0.0F;
  float fields_outer_mm = 0.0F;  // kPersonFields
  float fields_inner_mm = 0.0F;
  std::array<PersonPoint, kPersonPoints> path{};
};

struct CommandRecord {
  std::uint32_t seq = 0;  // assigned by the gateway, echoed in the reply
  RecordKind kind = RecordKind::command;
  std::uint8_t pad[3]{};
  core::Command command{};        // kind == command (command.seq == seq)
  std::uint32_t set_mask = 0;     // kind == sim_set: bit i = Contact i is written ...
  std::uint32_t set_values = 0;   // ... with this value (1 = closed)
  std::int32_t separation_mm = 0;  // kind == sim_set: the distance sensor (separation_set says what)
  std::uint8_t separation_set = 0;
  std::uint8_t fault_kind = 0;    // kind == sim_fault: sim::FaultKind
  std::uint8_t fault_axis = 0;
  std::uint8_t pad2[1]{};
  std::uint16_t fault_value = 0;  // kind == sim_fault: sim::Fault::value (contact: 0.1 N; torque bias: int16 per mille)
  std::uint8_t pad3[2]{};
  PersonRecord person{};          // kind == sim_person
};

// Answer to a record: a command's result, or for sim records OK / NOT_SIMULATED. A person
// record may also be refused, nothing changed: `walk`, `stand` or `leave` with nobody in the
// cell (person_absent), a value the cell refuses (person_invalid; the gateway checks them
// first), or any person record where the world is an emulated segment (person_not_on_bus).
enum class SimResult : std::uint8_t { ok, not_simulated, person_absent, person_invalid, person_not_on_bus };
struct ReplyRecord {
  std::uint32_t seq = 0;
  RecordKind kind = RecordKind::command;
  std::uint8_t cmd = 0;     // raw command id
  std::uint8_t source = 0;  // raw source
  core::Result result = core::Result::OK;
  SimResult sim = SimResult::ok;
  std::uint8_t pad[3]{};
  std::uint64_t t = 0;  // cycle of the answer
};

enum class EventKind : std::uint8_t { transition, alarm, alarm_cleared, command, brake_test };
struct EventRecord {
  std::uint64_t t = 0;  // cycle
  EventKind kind = EventKind::transition;
  // transition
  core::Leaf from = core::Leaf::BOOT;
  core::Leaf to = core::Leaf::BOOT;
  core::StopCat stop = core::StopCat::NONE;
  std::uint8_t trigger = 0;  // core::Trigger
  std::uint8_t row = 0;      // index in kTransitions
  // alarm / alarm_cleared
  core::AlarmId alarm = core::AlarmId::ESTOP_PRESSED;
  std::uint8_t pad = 0;
  core::AlarmDetail detail{};
  // command
  core::Reply reply{};
  // the first-out cause in force after the event
  core::Cause cause{};
  // brake_test (SPEC §12): the result (core::BrakeTestResult), the axis that slipped (0 on
  // a pass) and every axis' drift, degrees
  std::uint8_t brake_result = 0;
  std::uint8_t brake_axis = 0;
  std::array<float, 6> brake_drift_deg{};
};

// SPEC §14: one channel as the status shows it (controller::ChannelStatus).
struct ChannelRecord {
  std::uint8_t present = 0;
  std::uint8_t running = 0;   // its process is there
  std::uint8_t answered = 0;  // its result of the last cycle came in time
  std::uint8_t agree = 1;     // its cross-check: no mismatch, partner not lost
  std::uint8_t compiler = 0;  // 1 GCC, 2 Clang
  core::State state = core::State::BOOT;
  core::Leaf leaf = core::Leaf::BOOT;
  core::CrossField field = core::CrossField::none;
  std::uint32_t pid = 0;
  std::uint32_t digest_crc = 0;
  std::uint32_t missing = 0;
  std::uint32_t wake_max_us = 0;
  std::uint32_t exec_max_us = 0;
  std::uint32_t pad = 0;
  std::uint64_t cycle = 0;
  std::uint64_t late = 0;
  std::uint64_t skipped = 0;
};

// Everything the gateway shows, rewritten every cycle.
struct Status {
  std::uint64_t t = 0;
  core::State state = core::State::BOOT;
  core::Sub sub = core::Sub::NONE;
  core::Mode mode = core::Mode::NONE;
  core::Mode mode_requested = core::Mode::NONE;
  core::StopCat stop = core::StopCat::NONE;
  core::Leaf target = core::Leaf::SAME;
  bool contactor = false;
  bool drives = false;
  bool brakes_released = false;
  bool reset_lamp = false;
  bool t2_confirmed = false;
  bool simulated = false;
  core::ArmingStep arming_step = core::ArmingStep::CONTACTOR;
  std::uint8_t arming_progress = 0;
  std::uint8_t program_index = 0;
  std::uint8_t program_length = 0;
  core::AlarmMask alarms = 0;
  core::Cause cause{};
  float tcp_speed_mm_s = 0.0F;
  float max_point_speed_mm_s = 0.0F;
  std::array<float, 6> joints{};
  std::array<float, 6> tcp{};  // x, y, z mm; rx, ry, rz rad
  std::array<std::uint8_t, 6> axis_state{};  // motion::AxisState
  std::array<std::uint16_t, 6> statusword{};
  std::array<std::uint64_t, core::kAlarmCount> alarm_since{};
  std::array<core::AlarmDetail, core::kAlarmCount> alarm_detail{};
  // SPEC §10, §11 as the core reports them, the same struct (one status shape).
  core::SafetyStatus safety{};
  // SPEC §11, the simulated person (sim::PersonView of the last cycle), for the HMI's floor.
  // person_shown: the in-process simulated cell, where a person can be placed (false on a
  // fieldbus, emulated or not); the rest is meaningful only with it.
  bool person_shown = false;
  bool person_present = false;
  bool person_walking = false;
  bool person_in_outer = false;  // what the scanner sees of the person
  bool person_in_inner = false;
  bool person_scanner = false;   // sim::PersonSensors: which devices the person feeds
  bool person_distance_sensor = false;
  std::uint8_t person_nearest_point = 0;  // 0..6 DH frame origin, 7 TCP
  float person_x_mm = 0.0F;
  float person_y_mm = 0.0F;
  float person_radius_mm = 0.0F;
  float person_speed_mm_s = 0.0F;
  float person_separation_mm = 0.0F;  // what the distance sensor sees of the person
  float person_outer_mm = 0.0F;       // the scanner's field radii
  float person_inner_mm = 0.0F;
  // SPEC §12, as the core reports it, the same struct.
  core::BrakeTestStatus brake_test{};
  // SPEC §14: the channels (1, or A and B) and the power path as its auxiliary contacts read.
  std::uint8_t channel_count = 1;
  std::array<ChannelRecord, 2> channels{};
  bool two_contactors = false;
  bool k1_closed = false;
  bool k2_closed = false;
};

// One cycle of the black box: what the cycle read and what it wrote.
struct BlackBoxRecord {
  std::uint64_t t = 0;
  std::uint32_t contacts = 0;  // bit i = Contact i closed
  std::uint8_t contactor_fb = 0;
  std::uint8_t brakes_fb = 0;  // bit i = brake i released
  std::uint8_t fieldbus_ok = 0;
  std::uint8_t leaf = 0;       // core::Leaf after the cycle
  std::uint8_t outputs = 0;    // bit0 contactor, bit1 drives, bit2 brakes release, bit3 reset lamp
  std::uint8_t pad = 0;
  std::array<std::uint16_t, 6> statusword{};
  std::array<std::uint16_t, 6> controlword{};
  std::array<float, 6> position{};
  std::array<float, 6> target{};
};
inline constexpr std::size_t kBlackBoxCycles = 1024;  // the gateway keeps 50 per stop event

inline constexpr std::size_t kHistogramBuckets = 32;  // bucket i: [2^i, 2^(i+1)) ns, bucket 0 includes 0
struct Metrics {
  std::array<std::atomic<std::uint64_t>, kHistogramBuckets> exec_ns{};
  std::array<std::atomic<std::uint64_t>, kHistogramBuckets> lateness_ns{};
  std::atomic<std::uint64_t> cycles{0};
  std::atomic<std::uint64_t> overruns{0};
  std::atomic<std::uint64_t> exec_max_ns{0};
  std::atomic<std::uint64_t> lateness_max_ns{0};
  std::atomic<std::uint64_t> watchdog_trips{0};
  std::atomic<std::uint64_t> events_dropped{0};
  std::atomic<std::uint64_t> replies_dropped{0};
  std::atomic<std::uint32_t> command_queue_depth{0};
  std::atomic<std::uint32_t> cycle_us{0};
  std::atomic<std::uint32_t> rt_priority{0};  // 0: not SCHED_FIFO
  std::atomic<std::uint64_t> fieldbus_stale_cycles{0};  // cycles whose frame was late or lost (inputs held)
};

[[nodiscard]] inline std::size_t histogram_bucket(std::uint64_t ns) noexcept {
  std::size_t b = 0;
  while ((ns > 1U) && (b + 1U < kHistogramBuckets)) {
    ns >>= 1U;
    ++b;
  }
  return b;
}

// ------------------------------------------------------------------ SPSC ring
// Lives inside the segment. head: next slot the producer writes; tail: next slot the
// consumer reads. Release/acquire on the indices publishes the slot contents.
template <typename T, std::size_t N>
struct Ring {
  static_assert(std::is_trivially_copyable_v<T>);
  static_assert((N & (N - 1U)) == 0U, "capacity must be a power of two");
  alignas(64) std::atomic<std::uint64_t> head{0};
  alignas(64) std::atomic<std::uint64_t> tail{0};
  std::array<T, N> slot{};

  bool push(const T& v) noexcept {
    const std::uint64_t h = head.load(std::memory_order_relaxed);
    if (h - tail.load(std::memory_order_acquire) >= N) {
      return false;  // full: the producer never waits
    }
    slot[h & (N - 1U)] = v;
    head.store(h + 1U, std::memory_order_release);
    return true;
  }
  bool pop(T& out) noexcept {
    if (!peek(0U, out)) {
      return false;
    }
    advance(1U);
    return true;
  }
  // Consumer: the record `i` places behind the tail, without taking it. The producer
  // cannot overwrite it until advance() has moved the tail past it, so a consumer can
  // make a record durable first and only then release its slot (nothing lost when the
  // consumer dies in between).
  bool peek(std::uint64_t i, T& out) const noexcept {
    const std::uint64_t t = tail.load(std::memory_order_relaxed);
    if (head.load(std::memory_order_acquire) - t <= i) {
      return false;
    }
    out = slot[(t + i) & (N - 1U)];
    return true;
  }
  void advance(std::uint64_t n) noexcept { tail.store(tail.load(std::memory_order_relaxed) + n, std::memory_order_release); }
  // Consumer, at start-up: skip what a predecessor already made durable.
  void advance_to(std::uint64_t t) noexcept {
    const std::uint64_t cur = tail.load(std::memory_order_relaxed);
    const std::uint64_t h = head.load(std::memory_order_acquire);
    if (t > cur && t <= h) {
      tail.store(t, std::memory_order_release);
    }
  }
  [[nodiscard]] std::size_t size() const noexcept {
    return static_cast<std::size_t>(head.load(std::memory_order_acquire) - tail.load(std::memory_order_acquire));
  }
};

// ------------------------------------------------------------------ seqlock
// A snapshot copied word by word through atomics, so that a torn read is only
// ever detected and retried, never a data race (ThreadSanitizer-clean).
template <typename T>
struct SeqLock {
  static_assert(std::is_trivially_copyable_v<T>);
  static constexpr std::size_t kWords = (sizeof(T) + 7U) / 8U;
  std::atomic<std::uint32_t> seq{0};
  std::array<std::atomic<std::uint64_t>, kWords> words{};

  void write(const T& v) noexcept {
    std::array<std::uint64_t, kWords> buf{};
    std::memcpy(buf.data(), &v, sizeof(T));
    const std::uint32_t s = seq.load(std::memory_order_relaxed);
    seq.store(s + 1U, std::memory_order_relaxed);  // odd: writing
    // Release stores: a reader that sees any new word also sees the odd sequence
    // number (H.-J. Boehm, "Can seqlocks get along with programming language memory
    // models?", 2012) - no standalone fence, so ThreadSanitizer can follow it.
    for (std::size_t i = 0; i < kWords; ++i) {
      words[i].store(buf[i], std::memory_order_release);
    }
    seq.store(s + 2U, std::memory_order_release);
  }
  // Returns false when a consistent copy could not be taken in `tries` attempts.
  bool read(T& out, int tries = 64) const noexcept {
    std::array<std::uint64_t, kWords> buf{};
    for (int k = 0; k < tries; ++k) {
      const std::uint32_t s1 = seq.load(std::memory_order_acquire);
      if ((s1 & 1U) != 0U) {
        continue;
      }
      for (std::size_t i = 0; i < kWords; ++i) {
        buf[i] = words[i].load(std::memory_order_acquire);
      }
      if (seq.load(std::memory_order_relaxed) == s1) {
        std::memcpy(static_cast<void*>(&out), buf.data(), sizeof(T));
        return true;
      }
    }
    return false;
  }
};

// ------------------------------------------------------------------ the segment
inline constexpr std::size_t kCommandSlots = 256;
inline constexpr std::size_t kReplySlots = 1024;
inline constexpr std::size_t kEventSlots = 4096;

// The fieldbus subdevices, named by bus position; written once by `safestate run` before
// the gateway starts, read by the gateway to name the subdevice of FIELDBUS_LOST and
// BOOT_FAILED, whose core detail carries only the position.
inline constexpr std::size_t kBusNames = 16;
inline constexpr std::size_t kBusNameChars = 48;
inline constexpr std::size_t kBusErrorChars = 256;
struct BusInfo {
  std::uint32_t count = 0;  // 0: no fieldbus (the simulated cell)
  std::uint32_t pad = 0;
  std::array<std::array<char, kBusNameChars>, kBusNames> name{};
  std::array<char, kBusErrorChars> boot_error{};  // why the bus did not come up, or empty
};
// Copies `s` into `dst`, truncated, always NUL-terminated.
template <std::size_t N>
void copy_text(std::array<char, N>& dst, const char* s) noexcept {
  std::size_t i = 0;
  for (; s != nullptr && s[i] != '\0' && i + 1U < N; ++i) {
    dst[i] = s[i];
  }
  dst[i] = '\0';
}

// The active safety configuration (SPEC §10), written once by `safestate run` before the
// gateway starts and never again: the gateway shows what the core was given (GET
// /api/safety, zone names in alarm texts), not what a file holds by the time it reads it.
// `canonical` is the file's RFC 8785 form; the schema bounds it far below its size (a
// complete file with 16 zones and every optional block is about 4 kB).
inline constexpr std::size_t kSafetyTextChars = 32768;
inline constexpr std::size_t kSafetySourceChars = 1024;
struct SafetyInfo {
  std::uint32_t set = 0;       // 1 once written
  std::uint32_t checksum = 0;  // as core::SafetyLimits::checksum
  std::uint32_t canonical_len = 0;
  std::uint32_t pad = 0;
  std::array<char, kSafetySourceChars> source{};  // the --safety path, or "built-in"
  std::array<char, kSafetyTextChars> canonical{};
};

struct Header {
  std::uint32_t magic = kMagic;
  std::uint32_t version = kLayoutVersion;
  std::uint64_t size = 0;  // bytes of the whole segment
  std::uint64_t commands_offset = 0;
  std::uint64_t replies_offset = 0;
  std::uint64_t events_offset = 0;
  std::uint64_t status_offset = 0;
  std::uint64_t blackbox_offset = 0;
  std::uint64_t metrics_offset = 0;
  std::atomic<std::uint64_t> core_heartbeat{0};     // the cycle counter
  std::atomic<std::uint64_t> gateway_heartbeat{0};  // incremented by every gateway poll
  std::atomic<std::uint32_t> core_pid{0};
  std::atomic<std::uint32_t> gateway_pid{0};
  std::atomic<std::uint32_t> simulated{0};
  std::atomic<std::uint32_t> shutting_down{0};
  // Random at creation: tells one run's segment from the next one's (the gateway keeps
  // how far it has logged the event ring per instance, so a restart neither loses nor
  // repeats an event).
  std::uint64_t instance = 0;
  std::atomic<std::uint32_t> gateway_restarts{0};  // written by `safestate run`
  std::uint32_t pad = 0;
  // CLOCK_MONOTONIC ns of the core's next cycle start, stored by the loop each cycle (a
  // plain store: no system call). The gateway sleeps until just after it while replies
  // are due, instead of polling (protocol.md latency; docs/performance.md).
  std::atomic<std::uint64_t> next_cycle_ns{0};
  BusInfo bus{};
  SafetyInfo safety{};
};

using CommandRing = Ring<CommandRecord, kCommandSlots>;
using ReplyRing = Ring<ReplyRecord, kReplySlots>;
using EventRing = Ring<EventRecord, kEventSlots>;
using StatusLock = SeqLock<Status>;
using BlackBoxSlot = SeqLock<BlackBoxRecord>;
using BlackBox = std::array<BlackBoxSlot, kBlackBoxCycles>;

// Offsets of the regions, computed the same way by both sides.
struct Layout {
  std::uint64_t commands;
  std::uint64_t replies;
  std::uint64_t events;
  std::uint64_t status;
  std::uint64_t blackbox;
  std::uint64_t metrics;
  std::uint64_t size;
};
[[nodiscard]] constexpr std::uint64_t align_up(std::uint64_t x) noexcept { return (x + 63U) & ~std::uint64_t{63U}; }
[[nodiscard]] constexpr Layout layout() noexcept {
  Layout l{};
  l.commands = align_up(sizeof(Header));
  l.replies = align_up(l.commands + sizeof(CommandRing));
  l.events = align_up(l.replies + sizeof(ReplyRing));
  l.status = align_up(l.events + sizeof(EventRing));
  l.blackbox = align_up(l.status + sizeof(StatusLock));
  l.metrics = align_up(l.blackbox + sizeof(BlackBox));
  l.size = align_up(l.metrics + sizeof(Metrics));
  return l;
}

static_assert(std::atomic<std::uint64_t>::is_always_lock_free, "shared-memory atomics must be lock-free");
static_assert(std::atomic<std::uint32_t>::is_always_lock_free, "shared-memory atomics must be lock-free");

}  // namespace safestate::bridge

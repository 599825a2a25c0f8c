// Zero heap allocations after start-up (DESIGN.md: no heap in the control loop).
// This binary replaces operator new/delete and malloc & co. and counts every call
// made while `armed`; 10^6 cycles of a busy input/command sequence must make none.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "bench.hpp"  // for Plant only: Bench itself allocates (std::deque)

#include "alloc_counter.hpp"

using namespace safestate::core;
using safestate::test::Plant;

namespace {
// A deterministic, busy script: every phase toggles inputs and sends commands.
struct Driver {
  std::uint32_t lcg = 12345U;
  std::uint32_t next() {
    lcg = lcg * 1664525U + 1013904223U;
    return lcg >> 8;
  }
  void inputs(RawInputs& r, Cycle t) {
    const std::uint32_t phase = static_cast<std::uint32_t>(t % 20000U);
    r.estop_a = r.estop_b = !(phase >= 15000U && phase < 15100U);
    r.gate_a = r.gate_b = !(phase >= 9000U && phase < 9050U);
    const bool t1 = (t / 20000U) % 2U == 1U;
    r.mode_auto = !t1;
    r.mode_t1 = t1;
    r.mode_t2 = false;
    const bool hold = t1 && phase > 300U && phase < 14000U;
    r.enable_a = r.enable_b = hold;
    r.reset_button = (phase % 4000U) > 3990U;
  }
  std::size_t commands(Command* out, Cycle t) {
    std::size_t n = 0;
    const std::uint32_t phase = static_cast<std::uint32_t>(t % 20000U);
    const auto add = [&](CommandId id) {
      Command c{};
      c.seq = next();
      c.id = static_cast<std::uint8_t>(id);
      c.source = static_cast<std::uint8_t>(next() % 8U == 0U ? Source::remote : Source::pendant);
      c.axis = static_cast<std::int8_t>(1U + next() % 7U);
      c.dir = (next() % 2U) != 0U ? 1 : -1;
      c.speed = static_cast<std::uint8_t>(1U + next() % 100U);
      out[n++] = c;
    };
    if (phase % 1000U == 100U) add(CommandId::reset);
    if (phase % 1000U == 150U) add(CommandId::servo_on);
    if (phase % 1000U == 800U) add(CommandId::start);
    if (phase % 50U == 0U) add(CommandId::jog);
    if (phase % 3000U == 2000U) add(CommandId::pause);
    if (phase % 3000U == 2600U) add(CommandId::resume);
    if (phase % 5000U == 4500U) add(CommandId::servo_off);
    if (phase % 777U == 1U) add(static_cast<CommandId>(next() % kCommandCount));
    return n;
  }
};
}  // namespace

TEST(NoAlloc, ZeroAllocationsOverAMillionBusyCycles) {
  const Timing timing = to_timing(Config{});
  // Start-up: everything is constructed before arming the counter.
  static Supervisor sup(timing);
  sup.configure_arm(safestate::test::plant_arm(), Vec3{});  // T1 speed: the plant's arm
  static Plant plant;
  RawInputs raw{};
  Feedback fb{};
  SupervisorOut out{};
  Driver drv;
  std::array<Command, kMaxCommandsPerCycle> cmds{};
  std::size_t states_seen = 0;
  std::array<bool, kStateCount> seen{};
  long replies = 0;

  allocations = 0;
  armed = true;
  for (Cycle t = 0; t < 1000000U; ++t) {
    drv.inputs(raw, t);
    plant.fill(fb);
    const std::size_t n = drv.commands(cmds.data(), t);
    sup.step(raw, fb, cmds.data(), n, out);
    plant.follow(out);
    replies += out.reply_count;
    const auto s = static_cast<std::size_t>(out.state);
    if (!seen[s]) {
      seen[s] = true;
      ++states_seen;
    }
    plant.vel.fill(out.motion.mode == MotionMode::Program ? 0.3F : plant.vel[0]);
  }
  armed = false;

  EXPECT_EQ(allocations.load(), 0) << "the cycle allocated";
  // The sequence must really have been busy, or the test proves nothing.
  EXPECT_GE(states_seen, 6U);
  EXPECT_GT(replies, 10000);
}

TEST(NoAlloc, TheCounterWorks) {
  armed = true;
  void* p = std::malloc(16);
  auto* q = new int(3);
  armed = false;
  std::free(p);
  delete q;
  EXPECT_GE(allocations.load(), 2);
  allocations = 0;
}

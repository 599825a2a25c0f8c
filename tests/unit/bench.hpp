// Test bench for the core: the whole Supervisor (signal layer + state manager) driven
// by raw contacts, with a minimal plant double so that arming and stopping complete.
// The plant is deliberately simple and obviously right; the realistic simulated cell
// (sim/) is tested through scenarios.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <deque>
#include <ostream>
#include <string>
#include <vector>

#include "plant.hpp"
#include "safestate/core/cia402.hpp"
#include "safestate/core/describe.hpp"
#include "safestate/core/supervisor.hpp"

// Readable gtest failure messages: names, not bytes.
namespace safestate::core {
inline void PrintTo(State v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(Sub v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(Mode v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(StopCat v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(Result v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(Leaf v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(ArmingStep v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(AlarmId v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(Channel v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(Signal v, std::ostream* os) { *os << to_string(v); }
inline void PrintTo(MotionMode v, std::ostream* os) { *os << static_cast<int>(v); }
inline void PrintTo(ProgramCmd v, std::ostream* os) { *os << static_cast<int>(v); }
namespace cia402 {
inline void PrintTo(DriveState v, std::ostream* os) { *os << to_string(v); }
}  // namespace cia402
}  // namespace safestate::core

namespace safestate::test {

using namespace safestate::core;
namespace c402 = safestate::core::cia402;

class Bench {
 public:
  // The core watches the plant's arm (T1 speed from its own kinematics), as a controller's
  // does from the start; configure_limits() gives it the limits' arm and TCP instead.
  explicit Bench(const Config& cfg = Config{}) : timing_(to_timing(cfg)), sup_(timing_) {
    sup_.configure_arm(plant_arm(), Vec3{});
    plant.cycle_s = static_cast<float>(cfg.cycle_us) * 1.0e-6F;
  }

  RawInputs raw{};
  Plant plant{};
  Feedback fb{};
  SupervisorOut out{};
  std::deque<Command> queue;
  std::vector<Reply> replies;  // every reply ever given, in order

  // Runs `n` cycles. Returns the output of the last one.
  const SupervisorOut& cycle(int n = 1) {
    for (int k = 0; k < n; ++k) {
      plant.fill(fb);
      std::array<Command, kMaxCommandsPerCycle> cmds{};
      std::size_t count = 0;
      for (const Command& c : queue) {
        if (count == cmds.size()) {
          break;
        }
        cmds[count++] = c;
      }
      const std::size_t taken = sup_.step(raw, fb, cmds.data(), count, out);
      queue.erase(queue.begin(), queue.begin() + static_cast<std::ptrdiff_t>(taken));
      for (std::size_t i = 0; i < out.reply_count; ++i) {
        replies.push_back(out.replies[i]);
      }
      plant.follow(out);
    }
    return out;
  }

  // Cycles until `pred` holds or `limit` cycles have run; returns cycles used (or -1).
  template <typename P>
  int until(P pred, int limit = 5000) {
    for (int k = 1; k <= limit; ++k) {
      cycle();
      if (pred(out)) {
        return k;
      }
    }
    return -1;
  }

  Command make(CommandId id, Source src = Source::pendant) {
    Command c{};
    c.seq = ++seq_;
    c.id = static_cast<std::uint8_t>(id);
    c.source = static_cast<std::uint8_t>(src);
    return c;
  }
  void send(const Command& c) { queue.push_back(c); }
  void send(CommandId id, Source src = Source::pendant) { send(make(id, src)); }

  // Sends one command, runs one cycle, returns its result.
  Result command(const Command& c) {
    send(c);
    const std::size_t before = replies.size();
    cycle();
    for (std::size_t i = before; i < replies.size(); ++i) {
      if (replies[i].seq == c.seq) {
        return replies[i].result;
      }
    }
    ADD_FAILURE() << "no reply in the cycle for command seq " << c.seq;
    return Result::QUEUE_FULL;
  }
  Result command(CommandId id, Source src = Source::pendant) { return command(make(id, src)); }
  Result jog(int axis, int dir, int speed = 10, Source src = Source::pendant) {
    Command c = make(CommandId::jog, src);
    c.axis = static_cast<std::int8_t>(axis);
    c.dir = static_cast<std::int8_t>(dir);
    c.speed = static_cast<std::uint8_t>(speed);
    return command(c);
  }

  // Raw-input helpers named like the .scn shorthands.
  void estop(bool pressed) { raw.estop_a = raw.estop_b = !pressed; }
  void gate(bool open) { raw.gate_a = raw.gate_b = !open; }
  void enable_centre() { raw.enable_a = raw.enable_b = true; raw.enable_panic = false; }
  void enable_released() { raw.enable_a = raw.enable_b = false; raw.enable_panic = false; }
  void enable_panic() { raw.enable_panic = true; }
  void mode(Mode m) {
    raw.mode_auto = m == Mode::AUTO;
    raw.mode_t1 = m == Mode::T1;
    raw.mode_t2 = m == Mode::T2;
  }

  // Scripted paths through the machine.
  void boot() {
    const int k = until([](const SupervisorOut& o) { return o.state != State::BOOT; }, 200);
    ASSERT_GT(k, 0) << "BOOT did not end";
  }
  void to_idle() {
    if (out.state == State::BOOT) {
      boot();
    }
    if (out.state == State::ESTOP_RESET_NEEDED) {
      ASSERT_EQ(command(CommandId::reset), Result::OK);
    }
    ASSERT_EQ(out.state, State::IDLE);
  }
  void to_operational(Mode m = Mode::AUTO) {
    mode(m);
    cycle();
    to_idle();
    if (m != Mode::AUTO) {
      enable_released();
      cycle();
      enable_centre();
      cycle();
    }
    if (m == Mode::T2) {
      ASSERT_EQ(command(CommandId::confirm_t2), Result::OK);
    }
    ASSERT_EQ(command(CommandId::servo_on), Result::OK);
    ASSERT_EQ(out.state, State::ARMING);
    const int k = until([](const SupervisorOut& o) { return o.state != State::ARMING; }, 1000);
    ASSERT_GT(k, 0);
    ASSERT_EQ(out.state, State::OPERATIONAL);
  }
  void to_auto_running() {
    to_operational(Mode::AUTO);
    ASSERT_EQ(command(CommandId::start), Result::OK);
    ASSERT_EQ(out.sub, Sub::AUTO_RUNNING);
    plant.vel.fill(0.5F);
  }
  void to_jogging(Mode m = Mode::T1) {
    to_operational(m);
    ASSERT_EQ(jog(1, +1, 50), Result::OK);
    ASSERT_EQ(out.sub, Sub::MANUAL_JOGGING);
    plant.vel[0] = 0.2F;
  }
  // Runs until the state leaves STOPPING; returns the cycles it took.
  int finish_stop(int limit = 3000) {
    return until([](const SupervisorOut& o) { return o.state != State::STOPPING; }, limit);
  }

  bool alarm(AlarmId a) const { return (out.alarms & bit(a)) != 0U; }
  const SystemStateManager& ssm() const { return sup_.manager(); }
  // SPEC §10: the safe limits to monitor (before the first cycle), with the arm they are about.
  // `cycle_us` is the scan cycle the limits' times (ms) are counted in: the Config's.
  void configure_limits(const SafetyLimits& l, const ArmGeometry& arm, bool validated, std::uint32_t cycle_us = 1000U) {
    sup_.configure_limits(l, arm, cycle_us, validated);
  }
  const Timing& timing() const { return timing_; }

 private:
  Timing timing_;
  Supervisor sup_;
  std::uint32_t seq_ = 0;
};

inline bool all_outputs_safe(const SupervisorOut& o) {
  return !o.contactor && !o.drives_enable && !o.brakes_release;
}

}  // namespace safestate::test

// SPEC §14 with each channel in a process of its own (pair/): the shared-memory link, the
// setup's seal, the power path's combination, and the pair itself: the GCC and the Clang
// channel programs started by ChannelPair on the simulated world, agreeing cycle after cycle,
// and one of them stopped (SIGSTOP) or killed (SIGKILL) from outside: the other names
// CHANNEL_LOST and opens its own contactor within cross_check_cycles + 1 cycles.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "safestate/controller/channels.hpp"
#include "safestate/core/alarms.hpp"
#include "safestate/pair/host.hpp"
#include "safestate/pair/shm.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/safety/safety_config.hpp"
#include "safestate/sim/cell.hpp"

namespace {

using namespace safestate;

controller::Digest digest(std::uint32_t seq) {
  core::SupervisorOut o{};
  return controller::make_digest(seq, seq, o);
}

// @req CH-PAIR
TEST(PairLane, DeliversEveryDigestInOrder) {
  pair::Lane ab;
  pair::Lane ba;
  pair::ShmLink a(ab, ba);
  pair::ShmLink b(ba, ab);
  for (std::uint32_t i = 1; i <= 40; ++i) {
    a.send(digest(i));
    controller::Digest d;
    ASSERT_TRUE(b.receive(d));
    EXPECT_EQ(d.seq, i);
    EXPECT_TRUE(controller::sealed(d));
    EXPECT_FALSE(b.receive(d));  // nothing more
  }
}

TEST(PairLane, AReaderThatFellBehindSkipsToTheOldestKeptAndTheGapShows) {
  pair::Lane ab;
  pair::Lane ba;
  pair::ShmLink a(ab, ba);
  pair::ShmLink b(ba, ab);
  const std::uint32_t sent = pair::kLaneSlots + 5U;
  for (std::uint32_t i = 1; i <= sent; ++i) {
    a.send(digest(i));
  }
  controller::Digest d;
  ASSERT_TRUE(b.receive(d));
  EXPECT_EQ(d.seq, sent - pair::kLaneSlots + 1U);  // the first 5 are gone: a skipped sequence
  std::uint32_t last = d.seq;
  while (b.receive(d)) {
    EXPECT_EQ(d.seq, last + 1U);
    last = d.seq;
  }
  EXPECT_EQ(last, sent);
}

TEST(PairSetup, SealedSetupIsValidAndEveryChangedByteIsNot) {
  pair::Setup s{};
  s.cfg = core::Config{};
  seal_setup(s, robot::active().model);
  const char* why = nullptr;
  ASSERT_TRUE(pair::setup_valid(s, why)) << why;
  EXPECT_STREQ(s.model_name, robot::active().model.name);
  EXPECT_EQ(s.model.name, nullptr);  // no pointer crosses a process
  pair::Setup t = s;
  t.cfg.cross_check_cycles += 1U;
  EXPECT_FALSE(pair::setup_valid(t, why));
  EXPECT_NE(std::string(why).find("CRC"), std::string::npos) << why;
  t = s;
  t.version = pair::kVersion + 1U;
  EXPECT_FALSE(pair::setup_valid(t, why));
  EXPECT_NE(std::string(why).find("another build"), std::string::npos) << why;
  t = s;
  t.magic = 0;
  EXPECT_FALSE(pair::setup_valid(t, why));
}

TEST(PairOutputs, K1FromAK2FromBBrakesOnlyWhileBothRelease) {
  hal::ProcessImageOut a{};
  hal::ProcessImageOut b{};
  a.contactor = true;
  a.brakes_release = true;
  a.drive[0].controlword = 0x0F;
  b.contactor = false;
  b.brakes_release = true;
  b.drive[0].controlword = 0x06;
  hal::ProcessImageOut o = controller::combine_outputs(a, b);
  EXPECT_TRUE(o.contactor);
  EXPECT_FALSE(o.contactor_k2);
  EXPECT_TRUE(o.brakes_release);
  EXPECT_EQ(o.drive[0].controlword, 0x0F);  // the drives from A
  b.brakes_release = false;
  EXPECT_FALSE(controller::combine_outputs(a, b).brakes_release);
  b.reduced_active = true;
  EXPECT_TRUE(controller::combine_outputs(a, b).reduced_active);
}

TEST(PairTogether, LedByTheLockedOutChannelAlarmsOfEither) {
  core::SupervisorOut a{};
  core::SupervisorOut b{};
  a.state = core::State::OPERATIONAL;
  a.contactor = true;
  b.state = core::State::ERROR_LOCKOUT;
  b.contactor = false;
  b.alarms = core::bit(core::AlarmId::CHANNEL_LOST);
  core::AlarmSet aa{};
  core::AlarmSet ab{};
  ab.raise(core::AlarmId::CHANNEL_LOST, core::AlarmDetail{}, 7);
  core::SupervisorOut out{};
  core::AlarmSet alarms{};
  core::Leaf leaf = core::Leaf::BOOT;
  const bool b_leads = controller::together({&a, &aa, core::Leaf::AUTO_RUNNING}, {&b, &ab, core::Leaf::ERROR_LOCKOUT},
                                            out, alarms, leaf);
  EXPECT_TRUE(b_leads);
  EXPECT_EQ(out.state, core::State::ERROR_LOCKOUT);
  EXPECT_EQ(leaf, core::Leaf::ERROR_LOCKOUT);
  EXPECT_FALSE(out.contactor);
  EXPECT_TRUE(alarms.active(core::AlarmId::CHANNEL_LOST));
}

// ----------------------------------------------------------------- the pair in processes

char proc_state(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
  std::string s;
  std::getline(f, s);
  const std::size_t close = s.rfind(')');
  return (close != std::string::npos && close + 2U < s.size()) ? s[close + 2U] : '?';
}

struct Pair {
  core::Config cfg{};
  sim::Cell world{cfg, nullptr, 2};
  pair::ChannelPair pair{cfg, world.world_port()};
  std::string err;

  bool start() {
    pair::PairOptions po;
    po.exe_a = SAFESTATE_CHANNEL_A;
    po.exe_b = SAFESTATE_CHANNEL_B;
    po.shm_base = "/safestate-test-pair-" + std::to_string(getpid());
    po.budget_us = 20000;  // a test host: no real-time loop, room for a loaded machine
    // The built-in safety configuration, validated (as `safestate run` without --safety).
    return pair.start(po, robot::active().model, safety::default_safety().limits, true, core::BrakeTestHistory{}, err);
  }
  void cycles(int n) {
    for (int i = 0; i < n; ++i) {
      pair.step();
    }
  }
};


// Power on from ESTOP_RESET_NEEDED: reset, servo on (SPEC §4), until OPERATIONAL (3000 cycles
// at most; the caller asserts the state).
void power_on(Pair& p) {
  core::Command c{};
  c.seq = 1;
  c.id = static_cast<std::uint8_t>(core::CommandId::reset);
  c.source = static_cast<std::uint8_t>(core::Source::pendant);
  ASSERT_EQ(p.pair.submit(c), core::Result::OK);
  p.cycles(20);
  c.seq = 2;
  c.id = static_cast<std::uint8_t>(core::CommandId::servo_on);
  ASSERT_EQ(p.pair.submit(c), core::Result::OK);
  for (int i = 0; i < 3000 && p.pair.out().state != core::State::OPERATIONAL; ++i) {
    p.pair.step();
  }
}

// @req CH-PROCESSES
TEST(PairProcesses, TheGccAndTheClangChannelRunInStepAndAgree) {
  Pair p;
  ASSERT_TRUE(p.start()) << p.err;
  p.cycles(300);
  for (std::size_t i = 0; i < 2; ++i) {
    controller::ChannelStatus c{};
    ASSERT_TRUE(p.pair.channel_status(i, c));
    EXPECT_TRUE(c.running) << i;
    EXPECT_TRUE(c.agree) << i;
    EXPECT_EQ(c.cycle, 300U) << i;
    EXPECT_EQ(c.state, core::State::ESTOP_RESET_NEEDED) << i;  // BOOT done, E-stop to be reset
  }
  // Channel A is this tree's compiler (GCC in the default build; the sanitizer trees are
  // Clang's, and so is their A), channel B always Clang's.
#if defined(__clang__)
  EXPECT_EQ(p.pair.report(0).compiler, pair::kClang);
#else
  EXPECT_EQ(p.pair.report(0).compiler, pair::kGcc);
#endif
  EXPECT_EQ(p.pair.report(1).compiler, pair::kClang);
  EXPECT_EQ(p.pair.report(0).digest.crc, p.pair.report(1).digest.crc);  // the same result, two compilers
  EXPECT_NE(p.pair.report(0).pid, p.pair.report(1).pid);
  EXPECT_EQ(p.pair.out().state, core::State::ESTOP_RESET_NEEDED);
  EXPECT_EQ(p.pair.alarms().raised(), 0U);
}

// Commands reach both channels in the same cycle, and both answer alike.
TEST(PairProcesses, ACommandIsTakenByBothInTheSameCycle) {
  Pair p;
  ASSERT_TRUE(p.start()) << p.err;
  p.cycles(300);
  core::Command c{};
  c.seq = 41;
  c.id = static_cast<std::uint8_t>(core::CommandId::reset);
  c.source = static_cast<std::uint8_t>(core::Source::pendant);
  ASSERT_EQ(p.pair.submit(c), core::Result::OK);
  p.pair.step();
  ASSERT_EQ(p.pair.report(0).sup.reply_count, 1U);
  ASSERT_EQ(p.pair.report(1).sup.reply_count, 1U);
  EXPECT_EQ(p.pair.report(0).sup.replies[0].seq, 41U);
  EXPECT_EQ(p.pair.report(0).sup.replies[0].result, p.pair.report(1).sup.replies[0].result);
  EXPECT_EQ(p.pair.report(0).digest.replies, p.pair.report(1).digest.replies);
  p.cycles(10);
  controller::ChannelStatus a{};
  ASSERT_TRUE(p.pair.channel_status(0, a));
  EXPECT_TRUE(a.agree);
}

// The fault from outside the process, as SPEC §14 and issue 36 ask: the other channel finds
// it lost and opens its own contactor within cross_check_cycles + 1 of its cycles.
void stops_the_other(int sig, std::size_t victim) {
  Pair p;
  ASSERT_TRUE(p.start()) << p.err;
  p.cycles(300);
  ASSERT_EQ(p.pair.out().state, core::State::ESTOP_RESET_NEEDED);
  power_on(p);
  ASSERT_EQ(p.pair.out().state, core::State::OPERATIONAL)
      << "alarms " << p.pair.alarms().mask() << ", cause kind " << static_cast<int>(p.pair.out().cause.kind)
      << " alarm " << static_cast<int>(p.pair.out().cause.alarm);
  ASSERT_TRUE(p.pair.combined().contactor);
  ASSERT_TRUE(p.pair.combined().contactor_k2);

  const auto pid = static_cast<pid_t>(p.pair.info(victim).pid);
  ASSERT_EQ(kill(pid, sig), 0);
  for (int i = 0; i < 2000 && proc_state(pid) != (sig == SIGSTOP ? 'T' : 'Z'); ++i) {
    usleep(500);
  }
  const std::size_t other = 1U - victim;
  const std::uint64_t from = p.pair.now();
  std::uint64_t opened = 0;
  for (int i = 0; i < 50 && opened == 0U; ++i) {
    p.pair.step();
    const hal::ProcessImageOut& o = p.pair.report(other).out;
    if (!o.contactor) {
      opened = p.pair.now();
    }
  }
  ASSERT_NE(opened, 0U) << "the other channel never opened its contactor";
  const std::uint64_t cycles = opened - from;
  const std::uint64_t limit = p.cfg.cross_check_cycles + 1U;
  std::printf("channel %c stopped by signal %d: channel %c opened its contactor after %llu cycles (limit %llu)\n",
              victim == 0U ? 'A' : 'B', sig, other == 0U ? 'A' : 'B', static_cast<unsigned long long>(cycles),
              static_cast<unsigned long long>(limit));
  EXPECT_LE(cycles, limit);
  EXPECT_FALSE(p.pair.combined().contactor && p.pair.combined().contactor_k2);  // the power path is open
  p.pair.step();  // the supervisor names it in the next cycle (a lockout: SPEC §14)
  EXPECT_TRUE(p.pair.report(other).alarms.active(core::AlarmId::CHANNEL_LOST));
  EXPECT_EQ(p.pair.report(other).sup.state, core::State::ERROR_LOCKOUT);
  EXPECT_EQ(p.pair.out().state, core::State::ERROR_LOCKOUT);
  EXPECT_TRUE(p.pair.alarms().active(core::AlarmId::CHANNEL_LOST));
  if (sig == SIGSTOP) {
    kill(pid, SIGCONT);
  }
}

TEST(PairProcesses, ChannelBStoppedChannelAOpensK1WithinTheCrossCheck) { stops_the_other(SIGSTOP, 1); }
TEST(PairProcesses, ChannelAStoppedChannelBOpensK2WithinTheCrossCheck) { stops_the_other(SIGSTOP, 0); }
TEST(PairProcesses, ChannelBKilledChannelAOpensK1WithinTheCrossCheck) { stops_the_other(SIGKILL, 1); }

TEST(PairProcesses, AChannelProgramRefusesASetupOfAnotherBuild) {
  // The Clang program against a segment whose setup's CRC does not match: it leaves with a
  // message naming it, and start() reports the channel ended.
  core::Config cfg{};
  sim::Cell world(cfg, nullptr, 2);
  pair::ChannelPair p(cfg, world.world_port());
  pair::PairOptions po;
  po.exe_a = SAFESTATE_CHANNEL_A;
  po.exe_b = "/nonexistent/safestate-channel-clang";
  po.shm_base = "/safestate-test-pair-bad-" + std::to_string(getpid());
  std::string err;
  EXPECT_FALSE(p.start(po, robot::active().model, core::SafetyLimits{}, false, core::BrakeTestHistory{}, err));
  EXPECT_NE(err.find("channel B"), std::string::npos) << err;
}

}  // namespace

namespace {

// A's set-points late (its process not run): the world's drives go on along the last step for
// cross_check_cycles + 1 cycles (3), then hold, as a CSP drive's interpolation does; holding at once made
// the arm stop dead and jump (a COLLISION under PFL, docs/two-channels.md).
TEST(PairProcesses, LateSetPointsGoOnAlongTheLastStepThenHold) {
  Pair p;
  ASSERT_TRUE(p.start()) << p.err;
  p.cycles(300);
  power_on(p);
  core::Command c{};
  c.source = static_cast<std::uint8_t>(core::Source::pendant);
  c.seq = 3;
  c.id = static_cast<std::uint8_t>(core::CommandId::start);
  ASSERT_EQ(p.pair.submit(c), core::Result::OK);
  p.cycles(600);  // AUTO_RUNNING, the arm moving
  ASSERT_EQ(p.pair.out().sub, core::Sub::AUTO_RUNNING);
  const hal::ProcessImageOut before = p.pair.combined();
  p.pair.step();
  const hal::ProcessImageOut last = p.pair.combined();
  std::size_t axis = 0;  // the axis that moves most
  for (std::size_t k = 1; k < hal::kAxes; ++k) {
    if (std::abs(last.drive[k].target_position_rad - before.drive[k].target_position_rad) >
        std::abs(last.drive[axis].target_position_rad - before.drive[axis].target_position_rad)) {
      axis = k;
    }
  }
  const float step = last.drive[axis].target_position_rad - before.drive[axis].target_position_rad;
  ASSERT_GT(std::abs(step), 1e-5F) << "the arm moves";
  const auto pid = static_cast<pid_t>(p.pair.info(0).pid);
  ASSERT_EQ(kill(pid, SIGSTOP), 0);
  for (int i = 0; i < 2000 && proc_state(pid) != 'T'; ++i) {
    usleep(500);
  }
  for (int n = 1; n <= 6; ++n) {
    p.pair.step();
    const float expect = last.drive[axis].target_position_rad + (step * static_cast<float>(n <= 3 ? n : 3));
    EXPECT_NEAR(p.pair.combined().drive[axis].target_position_rad, expect, 1e-5F)
        << "cycle " << n << " of A's silence, axis " << axis + 1U;
  }
  EXPECT_EQ(p.pair.info(0).extrapolated, 3U);
  kill(pid, SIGCONT);
}

}  // namespace

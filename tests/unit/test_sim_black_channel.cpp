// Issue 37 in the simulated world (sim/black_channel.hpp): the shipped segment's sixteen
// connections between the channels and simulated devices, the bus a byte copy with faults.
// With valid traffic the cell boots and runs the demo as it does without; the safety inputs
// come from the F-DI's and the drives' containers and the power path follows the F-DO alone;
// each fault on the wire, either way, is named SAFETY_LINK_FAULT with its connection and the
// F-DO's K1 and K2 open within the watchdog (and the cross-check's window for the other one).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>

#include "safestate/core/describe.hpp"
#include "safestate/hal/ethercat.hpp"
#include "safestate/sim/black_channel.hpp"
#include "safestate/sim/cell.hpp"

using namespace safestate;
using core::CommandId;
using core::State;

namespace {

struct BcRun {
  sim::Cell cell;
  std::uint32_t seq = 0;
  explicit BcRun(std::uint8_t channels, bool black) : cell(core::Config{}, nullptr, channels) {
    // As the campaign's warm cells: AUTO, the brake test passed, a distance sensor seeing nobody.
    core::BrakeTestHistory h{};
    h.last = core::BrakeTestResult::passed;
    h.passed_ever = true;
    cell.configure_brake_test(h);
    cell.inputs().mode_auto = true;
    cell.inputs().separation_mm = 100000;
    cell.inputs().separation_valid = true;
    if (black) {
      const char* why = nullptr;
      EXPECT_TRUE(cell.use_black_channel(why)) << (why ? why : "");
    }
  }
  template <typename P>
  int until(P pred, int limit) {
    for (int k = 1; k <= limit; ++k) {
      cell.step();
      if (pred(cell)) return k;
    }
    return -1;
  }
  void cycles(int n) {
    for (int i = 0; i < n; ++i) cell.step();
  }
  bool cmd(CommandId id) {
    core::Command c{};
    c.seq = ++seq;
    c.id = static_cast<std::uint8_t>(id);
    c.source = static_cast<std::uint8_t>(core::Source::pendant);
    if (cell.submit(c) != core::Result::OK) return false;
    cell.step();
    const core::SupervisorOut& o = cell.out();
    for (std::size_t i = 0; i < o.reply_count; ++i) {
      if (o.replies[i].seq == c.seq) {
        EXPECT_EQ(o.replies[i].result, core::Result::OK) << static_cast<int>(o.replies[i].result);
        return o.replies[i].result == core::Result::OK;
      }
    }
    return true;  // answered later (a reset waits for the drives)
  }
  // Boot, reset, servo on, the demo program started and moving.
  void running() {
    // With the black channel the safe values before the connections are up (E-stop pressed)
    // take the cell out of BOOT at once; the boot's own checks finish later, and a reset
    // before then is answered BUSY: wait for both.
    ASSERT_GT(until(
                  [](const sim::Cell& c) {
                    return c.out().state == State::ESTOP_RESET_NEEDED &&
                           !c.channel(0).controller().supervisor().manager().boot_pending() &&
                           !c.channel(1).controller().supervisor().manager().boot_pending();
                  },
                  200),
              0);
    ASSERT_TRUE(cmd(CommandId::reset));
    ASSERT_GT(until([](const sim::Cell& c) { return c.out().state == State::IDLE; }, 1000), 0)
        << core::to_string(cell.out().state);
    ASSERT_TRUE(cmd(CommandId::servo_on));
    ASSERT_GT(until([](const sim::Cell& c) { return c.out().state == State::OPERATIONAL; }, 1000), 0);
    ASSERT_TRUE(cmd(CommandId::start));
    ASSERT_GT(until([](const sim::Cell& c) { return std::fabs(c.view().velocities_rad_s[0]) > 0.5F; }, 3000), 0);
  }
  bool link_fault() const { return cell.alarms().active(core::AlarmId::SAFETY_LINK_FAULT); }
  std::string detail() const {
    std::array<char, 64> b{};
    return core::detail_name(cell.alarms().detail(core::AlarmId::SAFETY_LINK_FAULT), b.data(), b.size());
  }
  bool k1() const { return cell.black_channel()->k(0); }
  bool k2() const { return cell.black_channel()->k(1); }
};

std::string hex(std::uint16_t id) {
  char b[8];
  std::snprintf(b, sizeof b, "0x%04X", id);
  return b;
}

}  // namespace

// The simulated world stands in for the shipped segment's black channel: its connections are
// the default bus configuration's, field by field (the one table the unit tests of the
// channel's link layer use too).
TEST(SimBlackChannel, ItsConnectionsAreTheDefaultBusConfigurations) {
  hal::ethercat::BusConfig bc;
  std::string err;
  ASSERT_TRUE(hal::ethercat::parse_bus_config(hal::ethercat::default_bus_config(), bc, err)) << err;
  const hal::LinkTable t = sim::shipped_links();
  ASSERT_EQ(t.count, bc.links.count);
  for (std::size_t i = 0; i < t.count; ++i) {
    const hal::LinkSpec& a = t.link[i];
    const hal::LinkSpec& b = bc.links.link[i];
    EXPECT_EQ(a.id, b.id) << i;
    EXPECT_EQ(a.channel, b.channel) << a.id;
    EXPECT_EQ(a.role, b.role) << a.id;
    EXPECT_EQ(a.axis, b.axis) << a.id;
    EXPECT_EQ(a.host_data_bytes, b.host_data_bytes) << a.id;
    EXPECT_EQ(a.device_data_bytes, b.device_data_bytes) << a.id;
    EXPECT_EQ(a.watchdog_ms, b.watchdog_ms) << a.id;
    EXPECT_EQ(a.vendor_id, b.vendor_id) << a.id;
    EXPECT_EQ(a.product_code, b.product_code) << a.id;
    EXPECT_EQ(a.position, b.position) << a.id;
    EXPECT_EQ(a.counts_per_revolution, b.counts_per_revolution) << a.id;
  }
}

// @req LINK-FAULT LINK-SAFE-VALUES
TEST(SimBlackChannel, TheCellBootsAndRunsTheDemoAsItDoesWithout) {
  for (const std::uint8_t ch : {std::uint8_t{2}, std::uint8_t{1}}) {
    SCOPED_TRACE(static_cast<int>(ch));
    BcRun plain(ch, false);
    BcRun black(ch, true);
    ASSERT_EQ(plain.cell.black_channel(), nullptr);
    ASSERT_NE(black.cell.black_channel(), nullptr);
    plain.running();
    black.running();
    // A whole round of the demo program: every station reached, nothing named, the power
    // path closed by the F-DO.
    std::array<bool, 8> seen{};
    for (int k = 0; k < 12000; ++k) {
      black.cell.step();
      seen[black.cell.view().program_index % seen.size()] = true;
      ASSERT_EQ(black.cell.out().state, State::OPERATIONAL) << k;
    }
    plain.cycles(12000);
    EXPECT_EQ(plain.cell.out().state, State::OPERATIONAL);
    EXPECT_EQ(black.cell.out().alarms, plain.cell.out().alarms);
    EXPECT_FALSE(black.link_fault());
    EXPECT_TRUE(seen[0] && seen[1] && seen[2]) << "the program's stations";
    EXPECT_TRUE(black.k1());
    EXPECT_TRUE(black.k2());
    EXPECT_TRUE(black.cell.power_on());
    const sim::BlackChannel& bc = *black.cell.black_channel();
    for (std::size_t i = 0; i < bc.table().count; ++i) {
      EXPECT_EQ(bc.device(i).state(), safelink::LinkState::Connected) << hex(bc.table().link[i].id);
      const std::size_t host = (ch == 2U && bc.table().link[i].channel == 'B') ? 1U : 0U;
      EXPECT_TRUE(black.cell.channel(host).links().hosts(i)) << hex(bc.table().link[i].id);
      EXPECT_EQ(black.cell.channel(host).links().end(i).state(), safelink::LinkState::Connected);
    }
    // The load-side positions the channels use are the drives' containers' (2^20 counts per
    // revolution: within a count and a cycle's motion of the plant's).
    for (std::size_t a = 0; a < 6U; ++a) {
      EXPECT_NEAR(black.cell.channel(0).image_in().drive[a].load_position_rad,
                  black.cell.channel(0).image_in().drive[a].position_rad, 0.05F)
          << a;
    }
    // The E-stop travels through the F-DI's containers: the same stop, a cycle or two later
    // than on the plain cell; the F-DO opens K1 and K2.
    plain.cell.inputs().estop_a = plain.cell.inputs().estop_b = false;
    black.cell.inputs().estop_a = black.cell.inputs().estop_b = false;
    const int kp = plain.until([](const sim::Cell& c) { return !c.power_on(); }, 100);
    const int kb = black.until([](const sim::Cell& c) { return !c.power_on(); }, 100);
    ASSERT_GT(kp, 0);
    ASSERT_GT(kb, 0);
    EXPECT_LE(kb, kp + 3) << "two exchanges at most on top";
    EXPECT_TRUE(black.cell.alarms().active(core::AlarmId::ESTOP_PRESSED));
    EXPECT_FALSE(black.k1());
    EXPECT_FALSE(black.k2());
  }
}

// The plant's power path follows the F-DO, not the channels' plain outputs: a container to
// the F-DO refused opens K1 at the terminal in that very cycle, before any channel decides.
TEST(SimBlackChannel, ThePowerPathFollowsTheSafeOutputTerminalAlone) {
  BcRun r(2, true);
  r.running();
  const sim::BlackChannel& bc = *r.cell.black_channel();
  sim::WireFault f{};
  f.kind = sim::WireFaultKind::flip;
  f.dir = sim::WireDirection::to_device;
  f.link = static_cast<std::uint8_t>(bc.index_of(0xA002));
  f.bit = 7U * 8U;  // the data byte's bit 0: K1 itself
  ASSERT_TRUE(r.cell.inject_wire(f));
  r.cell.step();
  EXPECT_FALSE(r.k1()) << "the terminal fails safe on the container it refused";
  EXPECT_TRUE(r.cell.contactor_command(0)) << "channel A has not decided yet: its plain K1 bit is still on";
  EXPECT_GT(r.until([](const sim::Cell& c) { return !c.power_on(); }, 30), 0) << "K1 drops out of the plant";

  // One channel, stalled: its plain outputs stay as last written (K1 on) and nothing else
  // would open the power path; its containers stop changing, the F-DO's watchdog opens K1.
  BcRun one(1, true);
  one.running();
  one.cell.inject(sim::Fault{sim::FaultKind::channel_stall, 1, 0});
  const int k = one.until([](const sim::Cell& c) { return !c.power_on(); }, 100);
  ASSERT_GT(k, 0) << "the F-DO's watchdog opens the power path";
  EXPECT_LE(k, 11 + 10) << "the watchdog plus the contactor's drop-out";
  EXPECT_TRUE(one.cell.contactor_command(0)) << "the stalled channel's own K1 bit is still on";
  EXPECT_FALSE(one.k1());
}

namespace {
struct Case {
  sim::WireFaultKind kind;
  sim::WireDirection dir;
  std::uint16_t link;
  std::uint16_t other;
  const char* error;  // the error named, "" any
};
}  // namespace

// @req LINK-FAULT
TEST(SimBlackChannel, EachFaultOnTheWireIsCaughtAndTheOutputsOpen) {
  using K = sim::WireFaultKind;
  constexpr auto down = sim::WireDirection::to_device;
  constexpr auto up = sim::WireDirection::to_channel;
  const std::array<Case, 14> cases{{
      {K::flip, up, 0xA001, 0, "crc"},            // a bit of the contacts
      {K::flip, down, 0xB002, 0, "not_connected"},  // the F-DO fails safe, sends zeros
      {K::flip, up, 0xB014, 0, "crc"},
      {K::replay, up, 0xA001, 0, "sequence"},
      {K::replay, down, 0xA002, 0, "not_connected"},
      {K::replay, up, 0xB016, 0, "sequence"},
      {K::swap, up, 0xA001, 0xA013, "identity"},
      {K::swap, down, 0xA002, 0xB002, "not_connected"},
      {K::delay, up, 0xA014, 0, "timeout"},
      {K::delay, down, 0xB002, 0, ""},   // both ends time out (the device first: then zeros)
      {K::delay, down, 0xA011, 0, ""},
      {K::insert, up, 0xA001, 0xB001, "identity"},
      {K::insert, down, 0xB001, 0xA001, "not_connected"},
      {K::insert, up, 0xB012, 0xA002, ""},  // another size: whatever it is taken for, caught
  }};
  BcRun warm(2, true);
  warm.running();
  warm.cycles(321);
  const sim::BlackChannel& bc = *warm.cell.black_channel();
  for (const Case& c : cases) {
    const std::string what = std::string(sim::to_string(c.kind)) + " " + sim::to_string(c.dir) + " " + hex(c.link);
    SCOPED_TRACE(what);
    BcRun r(warm);
    sim::WireFault f{};
    f.kind = c.kind;
    f.dir = c.dir;
    f.link = static_cast<std::uint8_t>(bc.index_of(c.link));
    f.other = static_cast<std::uint8_t>(c.other != 0U ? bc.index_of(c.other) : 0U);
    f.bit = 8U * 8U + 2U;  // a bit of the data (byte 8)
    f.age = 5;
    f.hold = 15;  // past the 10 ms watchdog
    ASSERT_TRUE(r.cell.inject_wire(f));
    int named = -1;
    int open = -1;
    for (int k = 1; k <= 40 && (named < 0 || open < 0); ++k) {
      r.cell.step();
      if (named < 0 && r.link_fault()) named = k;
      if (open < 0 && !r.k1() && !r.k2()) open = k;
    }
    ASSERT_GT(named, 0) << "not named";
    const std::string d = r.detail();
    const bool which = d.rfind("link." + hex(c.link) + ".", 0) == 0 ||
                       (c.other != 0U && d.rfind("link." + hex(c.other) + ".", 0) == 0);
    EXPECT_TRUE(which) << d;
    if (*c.error != '\0') {
      EXPECT_EQ(d.substr(d.rfind('.') + 1U), c.error) << d;
    }
    EXPECT_LE(named, 11) << "within the 10 ms watchdog";
    ASSERT_GT(open, 0) << "K1 and K2 at the F-DO";
    // The connection's own channel opens its contactor at once; the other follows through
    // the cross-check (cross_check_cycles): the watchdog plus that at most.
    EXPECT_LE(open, 11 + static_cast<int>(r.cell.config().cross_check_cycles) + 1) << d;
    EXPECT_EQ(r.cell.leaf(), core::Leaf::ERROR_LOCKOUT);
    r.cycles(20);
    EXPECT_FALSE(r.cell.power_on());
  }
}

TEST(SimBlackChannel, OnlyOnRequestBeforeTheFirstStepAndFaultsOutsideAreRefused) {
  BcRun plain(2, false);
  sim::WireFault f{};
  EXPECT_FALSE(plain.cell.inject_wire(f)) << "no black channel, no wire";
  plain.cell.step();
  const char* why = nullptr;
  EXPECT_FALSE(plain.cell.use_black_channel(why));
  EXPECT_STREQ(why, "the black channel is set up before the first step");
  EXPECT_EQ(plain.cell.black_channel(), nullptr);

  BcRun r(2, true);
  EXPECT_FALSE(r.cell.use_black_channel(why)) << "once";
  f.link = 16;
  EXPECT_FALSE(r.cell.inject_wire(f)) << "no 17th connection";
  f.link = 0;
  f.bit = 15U * 8U;  // a 15-byte container to the drive: bits 0..119
  EXPECT_FALSE(r.cell.inject_wire(f));
  f.kind = sim::WireFaultKind::swap;
  f.other = 0;
  EXPECT_FALSE(r.cell.inject_wire(f)) << "a connection swapped with itself";
  f.kind = sim::WireFaultKind::replay;
  f.age = 1;
  EXPECT_FALSE(r.cell.inject_wire(f)) << "last cycle's is no stale container";
  f.kind = sim::WireFaultKind::delay;
  f.hold = 0;
  EXPECT_FALSE(r.cell.inject_wire(f));
}

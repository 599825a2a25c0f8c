// SPEC §14 on the core's side and the controller's: the channel monitor names what the
// cross-check found, the encoder monitor compares each axis' two encoders, the contactor
// monitor watches both auxiliary contacts; a pair of controller::Cells in lock-step agrees,
// and a silent partner is named and the deciding channel opens its contactor that same
// cycle. Every condition of the new monitors alone flips its finding.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <limits>

#include "safestate/controller/cell.hpp"
#include "safestate/core/describe.hpp"
#include "safestate/core/monitor.hpp"
#include "safestate/core/sequences.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/sim/cell.hpp"

using namespace safestate;
using core::AlarmId;
using core::Leaf;

namespace {

struct Cycle1 {
  core::AlarmSet alarms;
  core::Reporter r;
  core::Timing timing = core::to_timing(core::Config{});
  core::Commanded last{};
  template <typename M>
  core::AlarmMask run(M& m, const core::Feedback& fb) {
    r.begin(alarms, 0U);
    const core::SafetyInputs in{};
    const core::StateVariant state{core::StIdle{}};
    const core::CycleView v{in,    fb,    timing, state,           r.facts(),      nullptr, Leaf::IDLE, false,
                            0U,    core::Mode::AUTO, 0U, false, false, true, true, last};
    m.check(v, r);
    return r.found();
  }
};

}  // namespace

TEST(ChannelMonitor, NamesTheFieldAndThePartnerAndNothingWithOneChannel) {
  core::ChannelMonitor m;
  Cycle1 c;
  core::Feedback fb{};
  fb.cross.mismatch = true;
  fb.cross.lost = true;
  EXPECT_EQ(c.run(m, fb), 0U) << "one channel: no partner, nothing to name";
  fb.cross.partner = core::Channel::b;
  fb.cross.lost = false;
  fb.cross.field = core::CrossField::outputs;
  EXPECT_EQ(c.run(m, fb), core::bit(AlarmId::CHANNEL_MISMATCH));
  char buf[32];
  EXPECT_STREQ(core::detail_name(c.r.detail(AlarmId::CHANNEL_MISMATCH), buf, sizeof buf), "outputs");
  fb.cross.mismatch = false;
  fb.cross.lost = true;
  EXPECT_EQ(c.run(m, fb), core::bit(AlarmId::CHANNEL_LOST));
  EXPECT_STREQ(core::detail_name(c.r.detail(AlarmId::CHANNEL_LOST), buf, sizeof buf), "B");
  fb.cross.lost = false;
  EXPECT_EQ(c.run(m, fb), 0U) << "both agree";
}

TEST(EncoderMonitor, ADifferenceOverTheToleranceForLongerThanTheTimeNamesTheAxis) {
  core::EncoderMonitor m;
  Cycle1 c;
  core::Feedback fb{};
  fb.load_encoders = true;
  const float tol = c.timing.encoder_tolerance_rad;
  fb.drive[2].position_rad = 1.0F;
  fb.drive[2].load_position_rad = 1.0F + 0.9F * tol;  // within the tolerance: never
  for (int k = 0; k < 50; ++k) {
    ASSERT_EQ(c.run(m, fb), 0U) << k;
  }
  fb.drive[2].load_position_rad = 1.0F + 1.1F * tol;
  for (core::Cycle k = 0; k < c.timing.encoder_discrepancy; ++k) {
    ASSERT_EQ(c.run(m, fb), 0U) << "cycle " << k << " of the tolerated time";
  }
  EXPECT_EQ(c.run(m, fb), core::bit(AlarmId::ENCODER_DISCREPANCY)) << "the one after the time";
  char buf[32];
  EXPECT_STREQ(core::detail_name(c.r.detail(AlarmId::ENCODER_DISCREPANCY), buf, sizeof buf), "axis.3");
  fb.drive[2].load_position_rad = 1.0F;  // agree again: the count starts over
  EXPECT_EQ(c.run(m, fb), 0U);
  fb.drive[2].load_position_rad = std::numeric_limits<float>::quiet_NaN();  // NaN is a difference
  for (core::Cycle k = 0; k < c.timing.encoder_discrepancy; ++k) {
    ASSERT_EQ(c.run(m, fb), 0U);
  }
  EXPECT_EQ(c.run(m, fb), core::bit(AlarmId::ENCODER_DISCREPANCY));
}

TEST(EncoderMonitor, ALoadEncoderStandingStillWhileTheMotorMovesPastTheToleranceTripsAtOnce) {
  core::EncoderMonitor m;
  Cycle1 c;
  core::Feedback fb{};
  fb.load_encoders = true;
  const float tol = c.timing.encoder_tolerance_rad;
  fb.drive[0].load_position_rad = 0.0F;
  // The motor moves in steps of a tenth of the tolerance; the load side follows until it
  // sticks: the finding comes once the motor is more than the tolerance past the stick,
  // although the difference has lasted only a few cycles (less than the time).
  float q = 0.0F;
  for (int k = 0; k < 5; ++k) {
    q += 0.1F * tol;
    fb.drive[0].position_rad = q;
    fb.drive[0].load_position_rad = q;
    ASSERT_EQ(c.run(m, fb), 0U);
  }
  const float stuck = q;
  int cycles = 0;
  core::AlarmMask found = 0U;
  while (found == 0U && cycles < 100) {
    q += 0.3F * tol;
    fb.drive[0].position_rad = q;
    fb.drive[0].load_position_rad = stuck;
    found = c.run(m, fb);
    ++cycles;
  }
  EXPECT_EQ(found, core::bit(AlarmId::ENCODER_DISCREPANCY));
  EXPECT_EQ(cycles, 4) << "0.9 x tol after 3 cycles, 1.2 x tol after the 4th: at once, before the time";
  EXPECT_LT(static_cast<core::Cycle>(cycles), c.timing.encoder_discrepancy);
  // Without load encoders nothing is compared.
  core::EncoderMonitor quiet;
  fb.load_encoders = false;
  EXPECT_EQ(c.run(quiet, fb), 0U);
}

TEST(ContactorMonitor, EachAuxiliaryContactIsWatchedAndNamed) {
  core::ContactorMonitor m;
  Cycle1 c;
  core::Feedback fb{};
  fb.two_contactors = true;
  fb.k2_closed = true;  // K2 welded: commanded open (last.contactor false), still closed
  for (core::Cycle k = 0; k < c.timing.contactor_timeout; ++k) {
    ASSERT_EQ(c.run(m, fb), 0U);
  }
  EXPECT_EQ(c.run(m, fb), core::bit(AlarmId::CONTACTOR_WELDED));
  char buf[32];
  EXPECT_STREQ(core::detail_name(c.r.detail(AlarmId::CONTACTOR_WELDED), buf, sizeof buf), "k2");
  core::ContactorMonitor k1;
  fb.k2_closed = false;
  fb.contactor_closed = true;
  for (core::Cycle k = 0; k < c.timing.contactor_timeout; ++k) {
    ASSERT_EQ(c.run(k1, fb), 0U);
  }
  EXPECT_EQ(c.run(k1, fb), core::bit(AlarmId::CONTACTOR_WELDED));
  EXPECT_STREQ(core::detail_name(c.r.detail(AlarmId::CONTACTOR_WELDED), buf, sizeof buf), "k1");
  core::ContactorMonitor one;  // one contactor: K2's contact is not read, K1 named as before
  fb.two_contactors = false;
  fb.k2_closed = true;
  for (core::Cycle k = 0; k <= c.timing.contactor_timeout; ++k) {
    static_cast<void>(c.run(one, fb));
  }
  EXPECT_STREQ(core::detail_name(c.r.detail(AlarmId::CONTACTOR_WELDED), buf, sizeof buf), "contactor");
  core::ContactorMonitor field_k1_only;  // two channels on a field with K1 only: still K1
  fb.cross.partner = core::Channel::b;
  for (core::Cycle k = 0; k <= c.timing.contactor_timeout; ++k) {
    static_cast<void>(c.run(field_k1_only, fb));
  }
  EXPECT_STREQ(core::detail_name(c.r.detail(AlarmId::CONTACTOR_WELDED), buf, sizeof buf), "k1");
  fb.cross.partner = core::Channel::none;
  c.last.contactor = true;  // commanded closed: closed contacts are right
  fb.two_contactors = true;
  core::ContactorMonitor closed;
  for (int k = 0; k < 300; ++k) {
    ASSERT_EQ(c.run(closed, fb), 0U);
  }
}

TEST(ChannelPair, InLockStepTheChannelsAgreeEveryCycle) {
  core::Config cfg{};
  sim::Cell cell(cfg, nullptr, 2);
  ASSERT_EQ(cell.channels(), 2U);
  core::Command reset{};
  reset.id = static_cast<std::uint8_t>(core::CommandId::reset);
  reset.seq = 1;
  for (int t = 0; t < 3000; ++t) {
    if (t == 150) {
      ASSERT_EQ(cell.submit(reset), core::Result::OK);
    }
    if (t == 160) {
      core::Command on = reset;
      on.id = static_cast<std::uint8_t>(core::CommandId::servo_on);
      on.seq = 2;
      ASSERT_EQ(cell.submit(on), core::Result::OK);
    }
    cell.step();
    const controller::Cell& a = cell.channel(0);
    const controller::Cell& b = cell.channel(1);
    ASSERT_EQ(a.last_digest().crc, b.last_digest().crc) << "cycle " << t;
    ASSERT_FALSE(a.cross_check().verdict().mismatch || a.cross_check().verdict().lost) << t;
    ASSERT_FALSE(b.cross_check().verdict().mismatch || b.cross_check().verdict().lost) << t;
  }
  EXPECT_EQ(cell.out().state, core::State::OPERATIONAL);
  EXPECT_TRUE(cell.contactor_command(0) && cell.contactor_command(1));
  EXPECT_TRUE(cell.k2_closed());
  EXPECT_GT(cell.channel(0).cross_check().last_agreed_cycle(), 2990U);
}

TEST(ChannelPair, ACopyOfAPairedCellRunsOnItsOwnLink) {
  core::Config cfg{};
  sim::Cell cell(cfg, nullptr, 2);
  for (int t = 0; t < 200; ++t) cell.step();
  sim::Cell copy(cell);  // the checker forks cells
  for (int t = 0; t < 200; ++t) {
    cell.step();
    copy.step();
  }
  for (const sim::Cell* c : {&cell, &copy}) {
    EXPECT_FALSE(c->channel(0).cross_check().verdict().lost);
    EXPECT_FALSE(c->channel(1).cross_check().verdict().lost);
    EXPECT_EQ(c->channel(0).last_digest().crc, c->channel(1).last_digest().crc);
  }
  EXPECT_EQ(cell.channel(0).last_digest().crc, copy.channel(0).last_digest().crc) << "the same history";
}

TEST(Arming, WithTwoContactorsBothAuxiliaryContactsMustSayClosed) {
  const core::Timing t = core::to_timing(core::Config{});
  core::AlarmDetail d{};
  core::Feedback fb{};
  fb.contactor_closed = true;  // K1
  fb.two_contactors = true;
  core::StArming a{};
  static_cast<void>(core::arming_step(a, fb, t, d));
  EXPECT_EQ(a.step, core::ArmingStep::CONTACTOR) << "K2 still open";
  fb.k2_closed = true;
  static_cast<void>(core::arming_step(a, fb, t, d));
  EXPECT_EQ(a.step, core::ArmingStep::DRIVES);
  core::StArming one{};
  fb.two_contactors = false;
  fb.k2_closed = false;  // one contactor: K2's contact is not read
  static_cast<void>(core::arming_step(one, fb, t, d));
  EXPECT_EQ(one.step, core::ArmingStep::DRIVES);
  core::StArming none{};
  fb.contactor_closed = false;
  fb.two_contactors = true;
  fb.k2_closed = true;  // K2 alone is not power
  static_cast<void>(core::arming_step(none, fb, t, d));
  EXPECT_EQ(none.step, core::ArmingStep::CONTACTOR);
}

namespace {

// A two-channel cell powered: reset, servo on, OPERATIONAL by cycle 1000.
void powered_pair(sim::Cell& cell) {
  core::Command c{};
  c.id = static_cast<std::uint8_t>(core::CommandId::reset);
  c.seq = 1;
  for (int t = 0; t < 1000; ++t) {
    if (t == 150) {
      ASSERT_EQ(cell.submit(c), core::Result::OK);
    }
    if (t == 160) {
      c.id = static_cast<std::uint8_t>(core::CommandId::servo_on);
      c.seq = 2;
      ASSERT_EQ(cell.submit(c), core::Result::OK);
    }
    cell.step();
  }
  ASSERT_EQ(cell.out().state, core::State::OPERATIONAL);
}

}  // namespace

// SPEC §14 `channel X flip FIELD`: every named field of vocab::kFlipFields is reachable in
// either channel (a bit inside its width flips, one past it is refused), and a state flipped
// outside the state machine is caught by that channel in the very cycle it runs with it:
// INTEGRITY_FAULT, ERROR_LOCKOUT, its contactor open (before any table is indexed with it).
// @req CH-FLIP
TEST(ChannelFlip, EveryFieldIsReachableAndAStateOutOfRangeLocksOutAtOnce) {
  core::Config cfg{};
  sim::Cell cell(cfg, nullptr, 2);
  powered_pair(cell);
  for (std::size_t f = 0; f < vocab::kFlipFields.size(); ++f) {
    const unsigned bits = vocab::kFlipFields[f].bits;
    sim::Cell copy(cell);
    for (std::size_t ch = 0; ch < 2; ++ch) {
      EXPECT_TRUE(copy.flip_field(ch, static_cast<std::uint16_t>((f << 8U) | (bits - 1U)))) << vocab::kFlipFields[f].name;
      EXPECT_TRUE(copy.flip_field(ch, static_cast<std::uint16_t>((f << 8U) | (bits - 1U)))) << "and back";
      EXPECT_FALSE(copy.flip_field(ch, static_cast<std::uint16_t>((f << 8U) | bits))) << vocab::kFlipFields[f].name;
    }
  }
  EXPECT_FALSE(cell.flip_field(0, static_cast<std::uint16_t>(vocab::kFlipFields.size() << 8U))) << "no such field";

  // Bit 4 of A's state: OPERATIONAL's leaf (MANUAL_IDLE or AUTO_IDLE) + 16 is past the last.
  const std::size_t state = static_cast<std::size_t>(vocab::FlipField::state);
  ASSERT_TRUE(cell.flip_field(0, static_cast<std::uint16_t>((state << 8U) | 4U)));
  cell.step();
  EXPECT_EQ(cell.channel(0).leaf(), Leaf::ERROR_LOCKOUT);
  EXPECT_TRUE(cell.channel(0).alarms().active(AlarmId::INTEGRITY_FAULT));
  EXPECT_FALSE(cell.contactor_command(0)) << "K1 open in that cycle";
  EXPECT_TRUE(cell.contactor_command(1)) << "B has not decided yet";
  for (int t = 0; t < 5; ++t) cell.step();
  EXPECT_EQ(cell.channel(1).leaf(), Leaf::ERROR_LOCKOUT);
  EXPECT_TRUE(cell.channel(1).alarms().active(AlarmId::CHANNEL_MISMATCH)) << "B sees A's digest differ";
  EXPECT_FALSE(cell.contactor_command(1));
}

// Bit 0 of B's state: a valid neighbour whose state data contradicts it (AUTO_IDLE <-> the
// variant of AUTO_RUNNING, or MANUAL_IDLE/AUTO_PAUSED): the output check of every cycle.
TEST(ChannelFlip, AStateThatContradictsItsDataIsAnIntegrityFault) {
  core::Config cfg{};
  sim::Cell cell(cfg, nullptr, 2);
  powered_pair(cell);
  const std::size_t state = static_cast<std::size_t>(vocab::FlipField::state);
  ASSERT_TRUE(cell.flip_field(1, static_cast<std::uint16_t>(state << 8U)));
  cell.step();
  EXPECT_EQ(cell.channel(1).leaf(), Leaf::ERROR_LOCKOUT);
  EXPECT_TRUE(cell.channel(1).alarms().active(AlarmId::INTEGRITY_FAULT));
  EXPECT_FALSE(cell.contactor_command(1));
}

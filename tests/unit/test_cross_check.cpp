// SPEC §14 cross-comparison, on its own: digests agree and are CRC-sealed; a difference that
// lasts longer than cross_check_cycles is CHANNEL_MISMATCH naming the first field; a partner
// silent for cross_check_cycles is CHANNEL_LOST; a corrupt, repeated or skipped digest counts
// as not arrived; a partner a cycle ahead or behind is compared cycle with cycle.
#include <gtest/gtest.h>

#include <deque>

#include "safestate/controller/cross_check.hpp"

using namespace safestate;
using controller::CrossCheck;
using controller::Digest;
using controller::DigestField;

namespace {

// A link whose partner's digests the test puts in by hand; what this side sends is kept.
struct Wire final : controller::Link {
  std::deque<Digest> in;
  std::deque<Digest> out;
  void send(const Digest& d) noexcept override { out.push_back(d); }
  bool receive(Digest& d) noexcept override {
    if (in.empty()) return false;
    d = in.front();
    in.pop_front();
    return true;
  }
};

core::SupervisorOut idle() {
  core::SupervisorOut o{};
  o.state = core::State::IDLE;
  o.reset_lamp = true;
  return o;
}

}  // namespace

TEST(CrossCheck, DigestsAreSealedAndNameTheFirstDifference) {
  const Digest a = controller::make_digest(7, 100, idle());
  EXPECT_TRUE(controller::sealed(a));
  Digest bent = a;
  bent.alarms ^= 1U;
  EXPECT_FALSE(controller::sealed(bent)) << "one bit changed: the CRC no longer matches";
  core::SupervisorOut o = idle();
  o.contactor = true;
  EXPECT_EQ(controller::first_difference(a, controller::make_digest(7, 100, o)), DigestField::outputs);
  o = idle();
  o.replies[0] = core::Reply{12, 1, 1, core::Result::OK};
  o.reply_count = 1;
  EXPECT_EQ(controller::first_difference(a, controller::make_digest(7, 100, o)), DigestField::replies);
  EXPECT_EQ(controller::first_difference(a, controller::make_digest(9, 100, idle())), DigestField::none)
      << "the sequence number is the link's, not a result";
}

TEST(CrossCheck, AgreeingChannelsStayQuietEvenAFractionOfACycleApart) {
  CrossCheck check(2);
  Wire link;
  std::uint32_t seq = 0;
  for (std::uint64_t t = 1; t <= 100; ++t) {
    // The partner is one cycle behind half of the time.
    if (t % 2 == 0) {
      link.in.push_back(controller::make_digest(seq, t - 1, idle()));
      ++seq;
      link.in.push_back(controller::make_digest(seq, t, idle()));
      ++seq;
    }
    const auto v = check.step(controller::make_digest(static_cast<std::uint32_t>(t), t, idle()), link);
    ASSERT_FALSE(v.mismatch) << t;
    ASSERT_FALSE(v.lost) << t;
  }
  EXPECT_EQ(check.last_agreed_cycle(), 100U);
  EXPECT_EQ(link.out.size(), 100U) << "one digest sent every cycle";
}

TEST(CrossCheck, ADifferenceLongerThanCrossCheckCyclesIsAMismatchNamingTheField) {
  CrossCheck check(2);
  Wire link;
  core::SupervisorOut other = idle();
  other.state = core::State::ERROR_LOCKOUT;
  for (std::uint64_t t = 1; t <= 3; ++t) {
    link.in.push_back(controller::make_digest(static_cast<std::uint32_t>(t), t, t == 1 ? idle() : other));
    const auto v = check.step(controller::make_digest(0, t, idle()), link);
    EXPECT_FALSE(v.mismatch) << "cycle " << t << ": 2 differing cycles are within cross_check_cycles";
  }
  link.in.push_back(controller::make_digest(4, 4, other));
  const auto v = check.step(controller::make_digest(0, 4, idle()), link);
  EXPECT_TRUE(v.mismatch) << "the third differing cycle in a row";
  EXPECT_EQ(v.field, DigestField::state);
  // A difference that goes away in time is none.
  CrossCheck again(2);
  Wire l2;
  for (std::uint64_t t = 1; t <= 20; ++t) {
    l2.in.push_back(controller::make_digest(static_cast<std::uint32_t>(t), t, (t % 3 == 0) ? other : idle()));
    ASSERT_FALSE(again.step(controller::make_digest(0, t, idle()), l2).mismatch) << t;
  }
}

TEST(CrossCheck, ASilentPartnerIsLostAfterCrossCheckCycles) {
  CrossCheck check(2);
  Wire link;
  link.in.push_back(controller::make_digest(0, 1, idle()));
  EXPECT_FALSE(check.step(controller::make_digest(0, 1, idle()), link).lost);
  EXPECT_FALSE(check.step(controller::make_digest(0, 2, idle()), link).lost) << "one cycle without: not yet";
  const auto v = check.step(controller::make_digest(0, 3, idle()), link);
  EXPECT_TRUE(v.lost);
  EXPECT_EQ(v.missing, 2U);
}

TEST(CrossCheck, CorruptRepeatedOrSkippedDigestsCountAsNotArrived) {
  for (int kind = 0; kind < 3; ++kind) {
    CrossCheck check(2);
    Wire link;
    link.in.push_back(controller::make_digest(10, 1, idle()));
    ASSERT_FALSE(check.step(controller::make_digest(0, 1, idle()), link).lost);
    for (std::uint64_t t = 2; t <= 3; ++t) {
      Digest d = controller::make_digest(static_cast<std::uint32_t>(9 + t), t, idle());
      if (kind == 0) d.state ^= 1U;                                   // corrupt: the CRC fails
      if (kind == 1) d = controller::make_digest(10, t, idle());      // repeated sequence number
      if (kind == 2) d = controller::make_digest(static_cast<std::uint32_t>(20 + t), t, idle());  // skipped
      link.in.push_back(d);
      const auto v = check.step(controller::make_digest(0, t, idle()), link);
      EXPECT_EQ(v.lost, t == 3) << "kind " << kind << " cycle " << t;
      EXPECT_FALSE(v.mismatch) << "not arrived is not compared";
    }
  }
}

// Two processes are not in lock-step: a channel whose process was not run for a few cycles
// catches up, reading the partner's digests of those cycles (and of the next ones) at once.
// The cycles it then runs are covered by digests that came before: not missing, not lost.
// (With "none arrived in this cycle" alone, `safestate run` locked out with CHANNEL_LOST
// under a loaded browser test: two catch-up cycles in a row found nothing new.)
TEST(CrossCheck, AChannelCatchingUpIsNotLostByDigestsThatCameAhead) {
  CrossCheck check(2);
  Wire link;
  std::uint32_t seq = 0;
  std::uint32_t mine = 0;
  for (std::uint64_t c = 1; c <= 5; ++c) {  // in step
    link.in.push_back(controller::make_digest(seq++, c, idle()));
    ASSERT_FALSE(check.step(controller::make_digest(mine++, c, idle()), link).lost);
  }
  // This channel was not run for cycles 6..9; the partner ran them and two more (10, 11).
  for (std::uint64_t c = 6; c <= 11; ++c) {
    link.in.push_back(controller::make_digest(seq++, c, idle()));
  }
  for (std::uint64_t c = 6; c <= 11; ++c) {  // catching up: everything came in its first cycle
    const controller::CrossVerdict v = check.step(controller::make_digest(mine++, c, idle()), link);
    EXPECT_FALSE(v.lost) << "cycle " << c;
    EXPECT_EQ(v.missing, 0U) << "cycle " << c;
    EXPECT_FALSE(v.mismatch) << "cycle " << c;
  }
  EXPECT_EQ(check.last_agreed_cycle(), 11U);
  // And a partner that then stops: lost after cross_check_cycles cycles past its last digest.
  EXPECT_FALSE(check.step(controller::make_digest(mine++, 12, idle()), link).lost);  // missing 1
  EXPECT_TRUE(check.step(controller::make_digest(mine++, 13, idle()), link).lost);   // missing 2
}

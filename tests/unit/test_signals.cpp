// Signal layer (SPEC §2): each validator alone, cycle by cycle.
#include <gtest/gtest.h>

#include "safestate/core/signals.hpp"

using namespace safestate::core;

namespace {
constexpr Cycle kLimit = 50;  // discrepancy_ms at 1 ms
}

// ---------------------------------------------------------------- DualChannel
// @req IN-SAFE-EITHER
TEST(DualChannel, HealthyBothChannelsIsActive) {
  DualChannel d;
  d.update(true, true, kLimit);
  EXPECT_TRUE(d.active());
  EXPECT_FALSE(d.discrepancy());
}

// @req IN-SAFE-EITHER CYC-ZERO-DELAY
TEST(DualChannel, EitherChannelAloneGivesSafeValueInTheSameCycle) {
  for (int which = 0; which < 2; ++which) {
    DualChannel d;
    d.update(true, true, kLimit);
    d.update(which != 0, which == 0, kLimit);
    EXPECT_FALSE(d.active()) << "channel " << which;
    EXPECT_TRUE(d.fell());
    EXPECT_EQ(d.cause(), which == 0 ? Channel::a : Channel::b);
  }
}

// @req IN-SAFE-EITHER AL-CAUSE
TEST(DualChannel, BothChannelsDroppingTogetherNamesBoth) {
  DualChannel d;
  d.update(true, true, kLimit);
  d.update(false, false, kLimit);
  EXPECT_FALSE(d.active());
  EXPECT_EQ(d.cause(), Channel::both);
}

// @req IN-DISCREPANCY
TEST(DualChannel, DiscrepancyFiresAtTheFirstCycleBeyondTheLimit) {
  DualChannel d;
  d.update(true, true, kLimit);
  for (Cycle k = 1; k <= kLimit; ++k) {
    d.update(false, true, kLimit);
    ASSERT_FALSE(d.discrepancy()) << "fired early at disagreement cycle " << k;
  }
  d.update(false, true, kLimit);  // disagreement cycle 51: more than 50 ms
  EXPECT_TRUE(d.discrepancy());
  EXPECT_EQ(d.fault_channel(), Channel::a);
}

// @req IN-DISCREPANCY AL-LIFETIME
TEST(DualChannel, DiscrepancyLatchesUntilPowerCycle) {
  DualChannel d;
  d.update(true, true, kLimit);
  for (Cycle k = 0; k <= kLimit; ++k) {
    d.update(true, false, kLimit);
  }
  ASSERT_TRUE(d.discrepancy());
  EXPECT_EQ(d.fault_channel(), Channel::b);
  d.update(false, false, kLimit);
  d.update(true, true, kLimit);
  EXPECT_TRUE(d.discrepancy());
  EXPECT_FALSE(d.active());
}

// @req IN-DISCREPANCY
TEST(DualChannel, DisagreementWithinTheLimitIsTolerated) {
  DualChannel d;
  d.update(true, true, kLimit);
  for (Cycle k = 0; k < kLimit; ++k) {
    d.update(false, true, kLimit);
  }
  d.update(false, false, kLimit);
  EXPECT_FALSE(d.discrepancy());
  EXPECT_EQ(d.disagree_cycles(), 0U);
}

// @req IN-EQUIVALENT
TEST(DualChannel, BlinkingChannelNeverReEnables) {
  DualChannel d;
  d.update(true, true, kLimit);
  d.update(false, true, kLimit);  // channel A opens for one cycle
  d.update(true, true, kLimit);   // and comes back: both agree again
  for (int k = 0; k < 200; ++k) {
    d.update(true, true, kLimit);
    ASSERT_FALSE(d.active()) << "re-enabled after a blink, cycle " << k;
  }
  EXPECT_FALSE(d.discrepancy());
  d.update(false, false, kLimit);  // both seen safe together once more
  d.update(true, true, kLimit);
  EXPECT_TRUE(d.active());
}

// @req IN-EQUIVALENT
TEST(DualChannel, StaggeredCloseFromSafeIsNormal) {
  DualChannel d;
  d.update(false, false, kLimit);
  d.update(true, false, kLimit);  // contact A makes first ...
  EXPECT_FALSE(d.active());
  d.update(true, true, kLimit);  // ... then B: enabled
  EXPECT_TRUE(d.active());
}

// @req IN-DISCREPANCY
TEST(DualChannel, StaggeredCloseBeyondTheLimitIsADiscrepancy) {
  DualChannel d;
  d.update(false, false, kLimit);
  for (Cycle k = 0; k <= kLimit; ++k) {
    d.update(true, false, kLimit);
  }
  EXPECT_TRUE(d.discrepancy());
  d.update(true, true, kLimit);
  EXPECT_FALSE(d.active());
}

// ---------------------------------------------------------------- EnablingDevice
namespace {
void to_centre_through_released(EnablingDevice& e) {
  e.update(false, false, false, false, kLimit);
  e.update(true, true, false, false, kLimit);
}
}  // namespace

// @req IN-ENABLE-DECODE
TEST(EnablingDevice, HeldAtPowerUpDoesNotEnable) {
  EnablingDevice e;
  e.update(true, true, false, false, kLimit);
  EXPECT_EQ(e.position(), EnablePos::centre);
  EXPECT_FALSE(e.enabled());
  e.update(false, false, false, false, kLimit);
  e.update(true, true, false, false, kLimit);
  EXPECT_TRUE(e.enabled());
}

// @req IN-ENABLE-DECODE
TEST(EnablingDevice, CentreThroughReleasedEnables) {
  EnablingDevice e;
  to_centre_through_released(e);
  EXPECT_TRUE(e.enabled());
  EXPECT_EQ(e.position(), EnablePos::centre);
}

// @req IN-ENABLE-DECODE
TEST(EnablingDevice, PanicDisablesWhateverTheCentreContactsSay) {
  EnablingDevice e;
  to_centre_through_released(e);
  e.update(true, true, true, false, kLimit);
  EXPECT_EQ(e.position(), EnablePos::panic);
  EXPECT_FALSE(e.enabled());
  EXPECT_TRUE(e.panic_edge());
  e.update(true, true, true, false, kLimit);
  EXPECT_FALSE(e.panic_edge()) << "edge only in the first cycle";
}

// @req IN-ENABLE-PANIC
TEST(EnablingDevice, PanicBackToCentreDoesNotEnable) {
  EnablingDevice e;
  to_centre_through_released(e);
  e.update(false, false, true, false, kLimit);  // squeezed: centre contacts open, panic closed
  e.update(true, true, false, false, kLimit);   // relaxed back to centre
  EXPECT_EQ(e.position(), EnablePos::centre);
  EXPECT_FALSE(e.enabled());
  EXPECT_TRUE(e.needs_release());
  to_centre_through_released(e);
  EXPECT_TRUE(e.enabled());
}

// @req IN-ENABLE-MODE
TEST(EnablingDevice, HeldWhenTheModeBecomesManualDoesNotCount) {
  EnablingDevice e;
  to_centre_through_released(e);
  e.update(true, true, false, /*manual_entered=*/true, kLimit);
  EXPECT_FALSE(e.enabled());
  e.update(true, true, false, false, kLimit);
  EXPECT_FALSE(e.enabled());
  to_centre_through_released(e);
  EXPECT_TRUE(e.enabled());
}

// @req IN-ENABLE-MODE
TEST(EnablingDevice, ReleasedWhenTheModeBecomesManualCountsAtOnce) {
  EnablingDevice e;
  e.update(false, false, false, true, kLimit);
  e.update(true, true, false, false, kLimit);
  EXPECT_TRUE(e.enabled());
}

// @req IN-ENABLE-DECODE IN-SAFE-EITHER
TEST(EnablingDevice, OneCentreContactIsNotCentre) {
  EnablingDevice e;
  e.update(false, false, false, false, kLimit);
  e.update(true, false, false, false, kLimit);
  EXPECT_EQ(e.position(), EnablePos::released);
  EXPECT_FALSE(e.enabled());
}

// @req IN-DISCREPANCY
TEST(EnablingDevice, CentreContactDiscrepancy) {
  EnablingDevice e;
  e.update(false, false, false, false, kLimit);
  for (Cycle k = 0; k <= kLimit; ++k) {
    e.update(true, false, false, false, kLimit);
  }
  EXPECT_TRUE(e.discrepancy());
  EXPECT_EQ(e.fault_channel(), Channel::b);
}

// ---------------------------------------------------------------- ModeSelector
// @req IN-MODE-DECODE
TEST(ModeSelector, ExactlyOneContactSelectsTheMode) {
  ModeSelector m;
  m.update(true, false, false, kLimit);
  EXPECT_EQ(m.mode(), Mode::AUTO);
  m.update(false, true, false, kLimit);
  EXPECT_EQ(m.mode(), Mode::T1);
  EXPECT_TRUE(m.changed());
  EXPECT_EQ(m.previous(), Mode::AUTO);
  m.update(false, false, true, kLimit);
  EXPECT_EQ(m.mode(), Mode::T2);
}

// @req IN-MODE-INVALID
TEST(ModeSelector, BreakBeforeMakeHoldsTheLastModeForTheLimit) {
  ModeSelector m;
  m.update(true, false, false, kLimit);
  for (Cycle k = 1; k <= kLimit; ++k) {
    m.update(false, false, false, kLimit);
    ASSERT_EQ(m.mode(), Mode::AUTO) << "cycle " << k;
    ASSERT_FALSE(m.changed());
    ASSERT_FALSE(m.invalid());
    EXPECT_EQ(m.requested(), Mode::NONE);
  }
  m.update(false, true, false, kLimit);
  EXPECT_EQ(m.mode(), Mode::T1);
  EXPECT_FALSE(m.invalid());
}

// @req IN-MODE-INVALID
TEST(ModeSelector, NoContactBeyondTheLimitGivesNone) {
  ModeSelector m;
  m.update(true, false, false, kLimit);
  for (Cycle k = 1; k <= kLimit; ++k) {
    m.update(false, false, false, kLimit);
  }
  m.update(false, false, false, kLimit);
  EXPECT_EQ(m.mode(), Mode::NONE);
  EXPECT_TRUE(m.invalid());
  EXPECT_TRUE(m.changed());
}

// @req IN-MODE-INVALID
TEST(ModeSelector, SeveralContactsBeyondTheLimitGivesNone) {
  ModeSelector m;
  m.update(false, true, false, kLimit);
  for (Cycle k = 0; k <= kLimit; ++k) {
    m.update(false, true, true, kLimit);
  }
  EXPECT_EQ(m.mode(), Mode::NONE);
  EXPECT_TRUE(m.invalid());
}

// ---------------------------------------------------------------- ResetButton
// @req IN-RESET-EDGE
TEST(ResetButton, ActsOnTheFallingEdge) {
  ResetButton r;
  r.update(false, 0, 5000);
  r.update(true, 1, 5000);
  EXPECT_FALSE(r.released_edge());
  EXPECT_EQ(r.press_start(), 1U);
  r.update(false, 2, 5000);
  EXPECT_TRUE(r.released_edge());
  r.update(false, 3, 5000);
  EXPECT_FALSE(r.released_edge());
}

// @req IN-RESET-FRESH
TEST(ResetButton, HeldExactlyTheLimitIsStillAReset) {
  ResetButton r;
  Cycle t = 0;
  for (Cycle k = 0; k < 5000; ++k) {
    r.update(true, t++, 5000);
    ASSERT_FALSE(r.stuck());
  }
  r.update(false, t++, 5000);
  EXPECT_TRUE(r.released_edge());
}

// @req IN-RESET-FRESH
TEST(ResetButton, HeldLongerThanTheLimitIsStuckAndNotAReset) {
  ResetButton r;
  Cycle t = 0;
  for (Cycle k = 0; k < 5000; ++k) {
    r.update(true, t++, 5000);
  }
  EXPECT_FALSE(r.stuck());
  r.update(true, t++, 5000);  // the 5001st cycle held
  EXPECT_TRUE(r.stuck());
  r.update(false, t++, 5000);
  EXPECT_FALSE(r.released_edge());
  EXPECT_FALSE(r.stuck()) << "RESET_BUTTON_STUCK lasts while held";
}

// @req IN-RESET-FRESH
TEST(ResetButton, HeldAtPowerUpIsAPressStartingAtCycleZero) {
  ResetButton r;
  r.update(true, 0, 5000);
  EXPECT_EQ(r.press_start(), 0U);
}

// ---------------------------------------------------------------- SignalLayer
// @req IN-ENABLE-MODE
TEST(SignalLayer, ModeBecomingManualWhileEnableHeldNeedsARelease) {
  SignalLayer s;
  const Timing t{};
  RawInputs raw{};
  s.update(raw, 0, t);
  raw.enable_a = raw.enable_b = true;
  s.update(raw, 1, t);  // held in AUTO
  raw.mode_auto = false;
  raw.mode_t1 = true;
  s.update(raw, 2, t);
  EXPECT_EQ(s.inputs().mode, Mode::T1);
  EXPECT_TRUE(s.inputs().mode_changed);
  EXPECT_FALSE(s.inputs().enable_ok);
}

// @req SIM-CELL
TEST(SignalLayer, DefaultRawInputsAreHealthyAutoReleased) {
  SignalLayer s;
  s.update(RawInputs{}, 0, Timing{});
  const SafetyInputs& in = s.inputs();
  EXPECT_FALSE(in.estop_pressed);
  EXPECT_FALSE(in.gate_open);
  EXPECT_EQ(in.enable, EnablePos::released);
  EXPECT_EQ(in.mode, Mode::AUTO);
}

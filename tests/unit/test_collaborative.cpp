// SPEC §11 formulas against hand computations (worked on paper, digits below), and the
// body region table against the SPEC's list.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "safestate/core/collaborative.hpp"
#include "safestate/core/monitors.hpp"
#include "monitor_harness.hpp"

using namespace safestate::core;

namespace {

// The SPEC's example: v_h 1600, a 2000, T_r 100 ms, C 200, Z 100.
SsmParams spec_example() {
  SsmParams p;
  p.human_speed_mm_s = 1600.0F;
  p.decel_mm_s2 = 2000.0F;
  p.reaction_s = 0.1F;
  p.intrusion_mm = 200.0F;
  p.uncertainty_mm = 100.0F;
  return p;
}

constexpr float kNoCap = 1.0e6F;

}  // namespace

// @req COL-SSM
TEST(Ssm, SpecExampleAt800mm) {
  // sqrt(1600^2 + 200^2 + 2*2000*(800-300)) - 1800 = sqrt(4,600,000) - 1800 = 2144.761 - 1800 = 344.761 (SPEC: 344.8)
  EXPECT_NEAR(ssm_allowed_speed_mm_s(800.0F, spec_example(), kNoCap), 344.761F, 0.01F);
}

// @req COL-SSM
TEST(Ssm, HandComputedDistances) {
  const SsmParams p = spec_example();
  // 1000 mm: sqrt(2,560,000 + 40,000 + 2,800,000) = sqrt(5,400,000) = 2323.790 - 1800
  EXPECT_NEAR(ssm_allowed_speed_mm_s(1000.0F, p, kNoCap), 523.790F, 0.01F);
  // 2000 mm: sqrt(2,600,000 + 6,800,000) = sqrt(9,400,000) = 3065.942 - 1800
  EXPECT_NEAR(ssm_allowed_speed_mm_s(2000.0F, p, kNoCap), 1265.942F, 0.02F);
  // 501 mm (v_h still 1600): sqrt(2,600,000 + 4000*201) = sqrt(3,404,000) = 1844.993 - 1800
  EXPECT_NEAR(ssm_allowed_speed_mm_s(501.0F, p, kNoCap), 44.993F, 0.01F);
  // 500 mm: v_h becomes 2000 (ISO 13855): sqrt(4,000,000 + 40,000 + 800,000) = 2200 - 2200 = 0
  EXPECT_NEAR(ssm_allowed_speed_mm_s(500.0F, p, kNoCap), 0.0F, 0.01F);
  // 400 mm: sqrt(4,040,000 + 400,000) = 2107.13 < 2200: 0
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(400.0F, p, kNoCap), 0.0F);
  // 0 mm: sqrt(4,040,000 - 1,200,000) = 1685.23 < 2200: 0
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(0.0F, p, kNoCap), 0.0F);
}

// @req COL-SSM
TEST(Ssm, TheSwitchOfHumanSpeedAt500mmWithAShortReach) {
  // C = Z = 0, a 2000, T_r 0.1: at 500 mm with v_h 2000: sqrt(4,040,000 + 2,000,000) =
  // 2457.641 - 2200 = 257.641; just above, v_h 1600: sqrt(2,600,000 + 4000*500.5) =
  // sqrt(4,602,000) = 2145.227 - 1800 = 345.227.
  SsmParams p = spec_example();
  p.intrusion_mm = 0.0F;
  p.uncertainty_mm = 0.0F;
  EXPECT_NEAR(ssm_allowed_speed_mm_s(500.0F, p, kNoCap), 257.641F, 0.01F);
  EXPECT_NEAR(ssm_allowed_speed_mm_s(500.5F, p, kNoCap), 345.227F, 0.01F);
  // A configured v_h above 2000 is kept near too.
  p.human_speed_mm_s = 2500.0F;
  // sqrt(6,250,000 + 40,000 + 2,000,000) = 2879.236 - 2700 = 179.236
  EXPECT_NEAR(ssm_allowed_speed_mm_s(500.0F, p, kNoCap), 179.236F, 0.01F);
}

// @req COL-SSM
TEST(Ssm, ClampedToTheLimitInForce) {
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(2000.0F, spec_example(), 250.0F), 250.0F);
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(2000.0F, spec_example(), 0.0F), 0.0F);
  // A limit that is not a number is no limit to trust: 0, whatever the separation.
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(2000.0F, spec_example(), std::numeric_limits<float>::quiet_NaN()), 0.0F);
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(2000.0F, spec_example(), std::numeric_limits<float>::infinity()), 0.0F);
}

// @req COL-SSM
TEST(Ssm, UnknownOrImpossibleSeparationIsZero) {
  const SsmParams p = spec_example();
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(-1.0F, p, kNoCap), 0.0F);
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(std::numeric_limits<float>::quiet_NaN(), p, kNoCap), 0.0F);
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(std::numeric_limits<float>::infinity(), p, kNoCap), 0.0F);
  SsmParams bad = p;
  bad.decel_mm_s2 = 0.0F;
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(2000.0F, bad, kNoCap), 0.0F);
  bad = p;
  bad.reaction_s = 0.0F;
  EXPECT_FLOAT_EQ(ssm_allowed_speed_mm_s(2000.0F, bad, kNoCap), 0.0F);
}

// @req COL-SSM
TEST(Ssm, AllowedSpeedIsExactlyWhereTheProtectiveDistanceEqualsTheSeparation) {
  const SsmParams p = spec_example();
  for (float d = 520.0F; d < 5000.0F; d += 137.0F) {
    const float v = ssm_allowed_speed_mm_s(d, p, kNoCap);
    ASSERT_GT(v, 0.0F) << d;
    EXPECT_NEAR(ssm_protective_distance_mm(v, d, p), d, 0.05F) << d;
    EXPECT_GT(ssm_protective_distance_mm(v * 1.01F, d, p), d) << "faster would not stop in time at " << d;
  }
  // The SPEC's terms at v = 344.761, d = 800: 1600*(0.1 + 0.172381) + 34.476 + 29.715 + 300
  EXPECT_NEAR(ssm_protective_distance_mm(344.761F, 800.0F, p), 800.0F, 0.05F);
}

// @req COL-PFL
TEST(Pfl, SpecExampleHand) {
  // hand: F_tr 280 N, k 75 N/mm, m_H 0.6 kg; m_R = 25/2 + 1.5 = 14 kg;
  // mu = 1 / (1/0.6 + 1/14) = 0.575342; sqrt(0.575342 * 75,000) = 207.726; 280 / 207.726
  EXPECT_NEAR(pfl_speed_cap_mm_s(BodyRegion::hand, 25.0F, 1.5F), 1347.93F, 0.5F);
}

// @req COL-PFL
TEST(Pfl, OtherRegionsByHand) {
  // chest: F_tr 280, k 25 N/mm, m_H 40; m_R 14: mu = 1/(0.025 + 0.0714286) = 10.3704;
  // sqrt(10.3704 * 25,000) = 509.175; 280 / 509.175 = 0.549902 m/s
  EXPECT_NEAR(pfl_speed_cap_mm_s(BodyRegion::chest, 25.0F, 1.5F), 549.90F, 0.5F);
  // neck, 10 kg robot, no payload: m_R 5; mu = 1/(1/1.2 + 0.2) = 0.967742;
  // sqrt(0.967742 * 50,000) = 219.971; 300 / 219.971 = 1.363817 m/s
  EXPECT_NEAR(pfl_speed_cap_mm_s(BodyRegion::neck, 10.0F, 0.0F), 1363.82F, 0.5F);
}

// @req COL-PFL
TEST(Pfl, SkullAndFaceAllowNoTransientContact) {
  EXPECT_FALSE(transient_contact_allowed(BodyRegion::skull));
  EXPECT_FALSE(transient_contact_allowed(BodyRegion::face));
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::skull, 25.0F, 1.5F), 0.0F);
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::face, 25.0F, 1.5F), 0.0F);
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::hand, 0.0F, 1.5F), 0.0F) << "no robot mass: no cap to trust";
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::hand, 25.0F, -1.0F), 0.0F);
}

// Each operand of the cap's input check on its own (MC/DC): a mass or payload that is not a
// number, and an effective mass m_R that overflows to infinity from two finite halves.
// @req COL-PFL
TEST(Pfl, NoCapFromMassesThatAreNotNumbers) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::hand, kNaN, 1.5F), 0.0F);
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::hand, kInf, 1.5F), 0.0F);
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::hand, 25.0F, kNaN), 0.0F);
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::hand, 25.0F, kInf), 0.0F);
  EXPECT_FLOAT_EQ(pfl_speed_cap_mm_s(BodyRegion::hand, 3.0e38F, 3.0e38F), 0.0F) << "m_R = inf";
  EXPECT_GT(pfl_speed_cap_mm_s(BodyRegion::hand, 3.0e38F, 0.0F), 0.0F) << "a huge but finite m_R still caps";
}

// @req COL-PFL
TEST(Pfl, TheTableIsTheSpecsList) {
  // SPEC §11, F_qs/F_tr/k/m_H in the SPEC's order; F_tr = 2 x F_qs where transient is allowed.
  struct Row {
    const char* name;
    float f_qs, f_tr, k, m_h;
  };
  const Row spec[] = {{"skull", 130, 0, 150, 4.4F},    {"face", 65, 0, 75, 4.4F},
                      {"neck", 150, 300, 50, 1.2F},    {"back", 210, 420, 35, 40},
                      {"chest", 140, 280, 25, 40},     {"abdomen", 110, 220, 10, 40},
                      {"pelvis", 180, 360, 25, 40},    {"upper_arm", 150, 300, 30, 3},
                      {"lower_arm", 160, 320, 40, 2},  {"hand", 140, 280, 75, 0.6F},
                      {"thigh", 220, 440, 50, 75},     {"lower_leg", 130, 260, 60, 75}};
  ASSERT_EQ(std::size(spec), kBodyRegionCount);
  for (std::size_t i = 0; i < kBodyRegionCount; ++i) {
    const BodyRegionLimits& r = kBodyRegions[i];
    EXPECT_EQ(static_cast<std::size_t>(r.id), i);
    EXPECT_STREQ(r.name, spec[i].name);
    EXPECT_FLOAT_EQ(r.f_qs_n, spec[i].f_qs);
    EXPECT_FLOAT_EQ(r.f_tr_n, spec[i].f_tr);
    EXPECT_FLOAT_EQ(r.k_n_per_mm, spec[i].k);
    EXPECT_FLOAT_EQ(r.m_h_kg, spec[i].m_h);
    if (r.f_tr_n > 0.0F) {
      EXPECT_FLOAT_EQ(r.f_tr_n, 2.0F * r.f_qs_n) << r.name;
    }
    BodyRegion parsed{};
    ASSERT_TRUE(parse_body_region(r.name, parsed));
    EXPECT_EQ(parsed, r.id);
  }
  BodyRegion untouched = BodyRegion::chest;
  EXPECT_FALSE(parse_body_region("elbow", untouched));
  EXPECT_FALSE(parse_body_region(nullptr, untouched));
  EXPECT_EQ(untouched, BodyRegion::chest);
}

// ---- the monitors of core/src/monitors/fields.cpp and ssm.cpp, cycle by cycle ----------

namespace {

CollaborativeLimits collaborative_on(bool auto_resume) {
  CollaborativeLimits c{};
  c.enabled = true;
  c.auto_resume = auto_resume;
  c.resume_delay_ms = 10;  // 10 cycles at 1 ms
  c.reduced_speed_mm_s = 200.0F;
  return c;
}

SafetyInputs auto_inputs() {
  SafetyInputs in{};
  in.mode = Mode::AUTO;
  in.estop_pressed = false;
  in.gate_open = false;
  return in;
}

}  // namespace

// @req COL-FIELDS COL-FIELD-GUARD
TEST(FieldMonitor, InnerStopsAndOuterReducesOnlyInAutoWithCollaborativeOn) {
  FieldMonitor m;
  m.configure(collaborative_on(true), 1000U);
  SafetyInputs in = auto_inputs();
  safestate::test::FieldResult r{};
  in.field_inner_interrupted = true;
  in.field_inner_cause = Channel::b;
  safestate::test::fields(m, in, r);
  EXPECT_TRUE(r.acting);
  EXPECT_TRUE(r.inner_stops);
  EXPECT_TRUE(r.blocks_start);
  EXPECT_FALSE(r.outer_reduces);
  EXPECT_EQ(r.inner_detail.signal, Signal::field_inner);
  EXPECT_EQ(r.inner_detail.channel, Channel::b);
  in.field_inner_interrupted = false;
  in.field_outer_interrupted = true;
  safestate::test::fields(m, in, r);
  EXPECT_FALSE(r.inner_stops);
  EXPECT_TRUE(r.outer_reduces);
  for (const Mode mode : {Mode::T1, Mode::T2, Mode::NONE}) {  // the enabling device guards in T1/T2
    in.mode = mode;
    in.field_inner_interrupted = true;
    safestate::test::fields(m, in, r);
    EXPECT_FALSE(r.acting || r.inner_stops || r.outer_reduces || r.blocks_start) << to_string(mode);
  }
  FieldMonitor off;  // collaborative operation off (the default): the fields do not act
  off.configure(CollaborativeLimits{}, 1000U);
  in.mode = Mode::AUTO;
  safestate::test::fields(off, in, r);
  EXPECT_FALSE(r.acting || r.inner_stops || r.outer_reduces || r.blocks_start);
}

// @req COL-FIELDS
TEST(FieldMonitor, ADiscrepancyIsReportedWhateverTheConfigurationAndMode) {
  FieldMonitor off;
  off.configure(CollaborativeLimits{}, 1000U);
  SafetyInputs in = auto_inputs();
  in.mode = Mode::T1;
  in.field_inner_discrepancy = true;
  in.field_inner_fault_channel = Channel::a;
  safestate::test::FieldResult r{};
  safestate::test::fields(off, in, r);
  EXPECT_TRUE(r.discrepancy);
  EXPECT_EQ(r.discrepancy_detail.signal, Signal::field_inner);
  EXPECT_EQ(r.discrepancy_detail.channel, Channel::a);
  in.field_outer_discrepancy = true;  // both: the outer one is named (first as wired)
  in.field_outer_fault_channel = Channel::b;
  safestate::test::fields(off, in, r);
  EXPECT_EQ(r.discrepancy_detail.signal, Signal::field_outer);
  EXPECT_EQ(r.discrepancy_detail.channel, Channel::b);
}

// @req COL-FIELD-GUARD
TEST(FieldMonitor, ResumeIsDueResumeDelayAfterBothFieldsReadClear) {
  FieldMonitor m;
  m.configure(collaborative_on(true), 1000U);
  SafetyInputs in = auto_inputs();
  safestate::test::FieldResult r{};
  in.field_inner_interrupted = true;
  safestate::test::fields(m, in, r);
  in.field_inner_interrupted = false;
  in.field_outer_interrupted = true;  // the person still in the outer field: not yet
  for (int i = 0; i < 50; ++i) {
    safestate::test::fields(m, in, r);
    EXPECT_FALSE(r.resume_due);
  }
  in.field_outer_interrupted = false;  // both clear from cycle T = 0 on
  for (int t = 0; t < 10; ++t) {
    safestate::test::fields(m, in, r);
    EXPECT_FALSE(r.resume_due) << "cycle T+" << t;
  }
  safestate::test::fields(m, in, r);
  EXPECT_TRUE(r.resume_due) << "cycle T+10 = T + resume_delay";
  in.field_inner_interrupted = true;  // back in: the count starts again
  safestate::test::fields(m, in, r);
  EXPECT_FALSE(r.resume_due);
  FieldMonitor manual;
  manual.configure(collaborative_on(false), 1000U);
  in.field_inner_interrupted = false;
  for (int t = 0; t < 100; ++t) {
    safestate::test::fields(manual, in, r);
    EXPECT_FALSE(r.resume_due);  // auto_resume off: never by itself
  }
}

// @req COL-FIELD-REDUCED COL-PFL
TEST(FieldMonitor, TheOuterFieldsReducedLimitIsTheLowestOfTheThree) {
  SafetyLimits l{};
  l.reduced_tcp_max_speed_mm_s = 250.0F;
  l.collaborative = collaborative_on(true);
  EXPECT_FLOAT_EQ(reduced_limit_mm_s(l, kReducedByField), 200.0F);  // collaborative.reduced_speed_mm_s
  EXPECT_FLOAT_EQ(reduced_limit_mm_s(l, kReducedByInput), 250.0F);  // the other sources: reduced only
  l.collaborative.pfl_enabled = true;
  l.collaborative.pfl_speed_mm_s = 120.0F;
  EXPECT_FLOAT_EQ(reduced_limit_mm_s(l, kReducedByField | kReducedByZone), 120.0F);  // v_pfl
  l.collaborative.reduced_speed_mm_s = 1500.0F;
  l.collaborative.pfl_speed_mm_s = 1348.0F;
  EXPECT_FLOAT_EQ(reduced_limit_mm_s(l, kReducedByField), 250.0F);  // reduced.tcp_max_speed_mm_s
  l.collaborative.enabled = false;
  l.collaborative.pfl_speed_mm_s = 100.0F;
  EXPECT_FLOAT_EQ(reduced_limit_mm_s(l, kReducedByField), 250.0F);
}

namespace {
SafetyLimits ssm_limits() {
  SafetyLimits l{};
  l.tcp_max_speed_mm_s = 1500.0F;
  l.collaborative = collaborative_on(true);
  l.collaborative.ssm_enabled = true;
  l.collaborative.ssm = spec_example();
  return l;
}
}  // namespace

// @req COL-SSM-INPUT
TEST(SsmMonitor, TheSeparationFallsAtOnceAndRisesAtMostAsFastAsAPersonAndTheRobotPart) {
  SsmMonitor m;
  m.configure(ssm_limits(), 1000U);
  EXPECT_FLOAT_EQ(m.rise_per_cycle_mm(), 3.5F);  // (2000 + 1500) mm/s x 1 ms
  SafetyInputs in = auto_inputs();
  safestate::test::SsmResult r{};
  in.separation_mm = 5000.0F;
  safestate::test::ssm(m, in, 0.0F, 1500.0F, true, r);
  EXPECT_FLOAT_EQ(r.separation_mm, 3.5F);  // unknown before: from 0
  for (int i = 0; i < 2000; ++i) safestate::test::ssm(m, in, 0.0F, 1500.0F, true, r);
  EXPECT_FLOAT_EQ(r.separation_mm, 5000.0F);
  in.separation_mm = 800.0F;  // a fall: at once
  safestate::test::ssm(m, in, 0.0F, 1500.0F, true, r);
  EXPECT_FLOAT_EQ(r.separation_mm, 800.0F);
  EXPECT_NEAR(r.v_allowed_mm_s, 344.761F, 0.01F);
  in.separation_mm = 3000.0F;  // a jump up: 3.5 mm a cycle
  safestate::test::ssm(m, in, 0.0F, 1500.0F, true, r);
  EXPECT_FLOAT_EQ(r.separation_mm, 803.5F);
  in.separation_mm = 0.0F;  // invalid (the signal layer's 0)
  safestate::test::ssm(m, in, 0.0F, 1500.0F, true, r);
  EXPECT_FLOAT_EQ(r.v_allowed_mm_s, 0.0F);
}

// @req COL-SSM-MONITOR
TEST(SsmMonitor, OverVAllowedPlusFivePercentForLongerThanTrTrips) {
  SsmMonitor m;
  m.configure(ssm_limits(), 1000U);
  EXPECT_EQ(m.reaction_cycles(), 100U);
  SafetyInputs in = auto_inputs();
  in.separation_mm = 800.0F;
  safestate::test::SsmResult r{};
  for (int i = 0; i < 400; ++i) safestate::test::ssm(m, in, 0.0F, 1500.0F, true, r);  // the separation believed reaches 800
  const float v = r.v_allowed_mm_s;
  ASSERT_NEAR(v, 344.761F, 0.01F);
  safestate::test::ssm(m, in, v * 1.0499F, 1500.0F, true, r);  // within 5 %: not over
  EXPECT_FALSE(r.over);
  for (int k = 1; k <= 100; ++k) {  // over for 100 cycles = T_r: not longer
    safestate::test::ssm(m, in, v * 1.051F, 1500.0F, true, r);
    EXPECT_TRUE(r.over);
    EXPECT_FALSE(r.violated.hit) << k;
  }
  safestate::test::ssm(m, in, v * 1.051F, 1500.0F, true, r);  // the 101st
  EXPECT_TRUE(r.violated.hit);
  EXPECT_EQ(r.violated.detail.signal, Signal::separation);
  safestate::test::ssm(m, in, v, 1500.0F, true, r);  // back under: the count starts again
  EXPECT_FALSE(r.over || r.violated.hit);
  safestate::test::ssm(m, in, std::numeric_limits<float>::quiet_NaN(), 1500.0F, false, r);  // unknown speed is over ...
  EXPECT_TRUE(r.over);
  EXPECT_FALSE(r.violated.hit);  // ... but without power nothing trips
  in.mode = Mode::T1;  // SSM acts only in AUTO
  for (int i = 0; i < 200; ++i) safestate::test::ssm(m, in, 1000.0F, 1500.0F, true, r);
  EXPECT_FALSE(r.acting || r.over || r.violated.hit);
}

// @req COL-SSM-MONITOR
TEST(SsmMonitor, TrInCyclesFromTheFilesMilliseconds) {
  SafetyLimits l = ssm_limits();
  l.collaborative.ssm.reaction_s = 0.02F;  // 19999.9995 us as a float: still 20 ms
  SsmMonitor m;
  m.configure(l, 1000U);
  EXPECT_EQ(m.reaction_cycles(), 20U);
  m.configure(l, 250U);
  EXPECT_EQ(m.reaction_cycles(), 80U);
  m.configure(l, 3000U);
  EXPECT_EQ(m.reaction_cycles(), 6U);  // 20 ms / 3 ms, rounded down
  m.configure(l, 0U);
  EXPECT_EQ(m.reaction_cycles(), 0U) << "no cycle time: no division, T_r of 0 cycles";
  l.collaborative.ssm.reaction_s = 0.0F;
  m.configure(l, 1000U);
  EXPECT_EQ(m.reaction_cycles(), 0U);
}

// The SSM benchmark found the robot one reaction closer than S_p for a cycle where the
// person crosses 500 mm (v_h 1600 -> 2000 while the TCP still moved at v_allowed(501)).
// The motion layer plans with v_h 2000 from 500 mm + 2000 mm/s x T_r on: by hand, SPEC's
// example (T_r 0.1 s: lookahead 200 mm).
// @req COL-SSM-MOTION
TEST(Ssm, PlanningUsesTheNearHumanSpeedBeforeTheSwitch) {
  const SsmParams p = spec_example();
  // 800 mm is beyond 700: the same as v_allowed.
  EXPECT_FLOAT_EQ(ssm_planning_speed_mm_s(800.0F, p, kNoCap), ssm_allowed_speed_mm_s(800.0F, p, kNoCap));
  // 600 mm: v_h 2000: sqrt(4,000,000 + 40,000 + 4000*300) = sqrt(5,240,000) = 2289.105 - 2200
  EXPECT_NEAR(ssm_planning_speed_mm_s(600.0F, p, kNoCap), 89.105F, 0.01F);
  // ... where v_allowed (v_h 1600) is sqrt(2,600,000 + 1,200,000) = 1949.359 - 1800
  EXPECT_NEAR(ssm_allowed_speed_mm_s(600.0F, p, kNoCap), 149.359F, 0.02F);
  // 501 mm: 0.9 mm/s planned (v_allowed 44.993): continuous towards 0 at 500.
  EXPECT_LT(ssm_planning_speed_mm_s(501.0F, p, kNoCap), 1.0F);
  EXPECT_FLOAT_EQ(ssm_planning_speed_mm_s(500.0F, p, kNoCap), 0.0F);
  // Never above v_allowed; while it moves, S_p(v_plan) <= d; and a cycle later, with the
  // person 2 mm closer (2000 mm/s, 1 ms), S_p grows by no more than those 2 mm, also where
  // d crosses 500 mm (with v_allowed itself it grew by 50 mm there).
  for (float d = 0.0F; d < 3000.0F; d += 0.5F) {
    const float v = ssm_planning_speed_mm_s(d, p, kNoCap);
    ASSERT_LE(v, ssm_allowed_speed_mm_s(d, p, kNoCap)) << d;
    if (v > 0.0F) {
      ASSERT_LE(ssm_protective_distance_mm(v, d, p), d + 0.01F) << d;
      ASSERT_LE(ssm_protective_distance_mm(v, d - 2.0F, p), d + 0.01F) << d;
    }
  }
  const float v501 = ssm_allowed_speed_mm_s(501.0F, p, kNoCap);
  EXPECT_GT(ssm_protective_distance_mm(v501, 499.0F, p), 540.0F) << "the jump this avoids";
}

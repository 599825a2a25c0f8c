// SPEC §11 formulas against hand computations (worked on paper, digits below), and the
// body region table against the SPEC's list.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "safestate/core/collaborative.hpp"

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

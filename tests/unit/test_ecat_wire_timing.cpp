// The emulated segment's response-time measurement on the wire (issue 21 item 4,
// sim/ecat/src/wire_timing.cpp), exchange by exchange without a network: what starts the
// count, what the reaction and the safe state are for each stop, the wire's quantisation,
// and the control line that arms it (validated: a bad line changes nothing).
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "safestate/ecat/cell.hpp"
#include "safestate/ecat/ecat_sim.hpp"
#include "safestate/ecat/wire_timing.hpp"

using namespace safestate;
using namespace safestate::ecat;

namespace {

constexpr std::uint32_t kCycleUs = 1000;
constexpr double kCount = 1.0 / kCountsPerRad;  // one encoder count in rad

// One side of the wire per exchange: the outputs brought, the inputs carried back.
struct Wire {
  WireTiming t;
  hal::ProcessImageOut out{};
  hal::ProcessImageIn in{};
  std::uint64_t n = 0;
  Wire() {
    out.contactor = true;  // K1 and K2 (SPEC §14) closed, as the emulated segment has both
    out.contactor_k2 = true;
    in.contactor_closed = true;
    in.two_contactors = true;
    in.k2_closed = true;
  }
  void arm(const std::string& words) {
    WireTiming::Spec s{};
    ASSERT_EQ(WireTiming::parse(words, s), "");
    t.arm(s);
  }
  // Axis 1's target moves by `step` rad in this exchange.
  void go(double step = 0.0) {
    out.drive[0].target_position_rad = static_cast<float>(out.drive[0].target_position_rad + step);
    t.exchange(n, n * kCycleUs * 1000U, out, in, kCycleUs);
    ++n;
  }
};

}  // namespace

// SPEC §14: K1 and K2 in series: K2's bit cleared alone (channel B deciding first) is the power
// removed, and its contact open alone is the power path open.
TEST(EcatWireTiming, K2AloneOpeningIsThePowerRemoved) {
  Wire w;
  w.arm("cat0 from=input");
  w.go();
  w.t.input_changed();
  w.go();  // 1 carries the change
  ASSERT_TRUE(w.t.start().seen);
  w.in.drive[0].velocity_rad_s = 1.0F;
  w.out.contactor_k2 = false;  // K1 still commanded closed
  w.go();  // 2
  ASSERT_TRUE(w.t.reaction().seen);
  EXPECT_EQ(w.t.reaction().exchange, 2U);
  w.in.drive[0].velocity_rad_s = 0.0F;
  w.go();  // 3: standstill, but both contacts still read closed
  EXPECT_FALSE(w.t.safe().seen);
  w.in.k2_closed = false;  // K2's contact open, K1's still closed
  w.go();  // 4
  ASSERT_TRUE(w.t.safe().seen);
  EXPECT_EQ(w.t.safe().exchange, 4U);
}

TEST(EcatWireTiming, Cat0FromTheInputToTheClearedBitAndStandstillOnTheInputs) {
  Wire w;
  w.arm("cat0 from=input");
  w.go();
  w.go();
  EXPECT_FALSE(w.t.start().seen);  // nothing changed yet
  w.t.input_changed();
  w.go();  // exchange 2 carries the change
  ASSERT_TRUE(w.t.start().seen);
  EXPECT_EQ(w.t.start().exchange, 2U);
  w.in.drive[0].velocity_rad_s = 1.0F;
  w.go();  // 3: still closed (a master one cycle late)
  EXPECT_FALSE(w.t.reaction().seen);
  w.out.contactor = false;
  w.go();  // 4: the cleared bit
  ASSERT_TRUE(w.t.reaction().seen);
  EXPECT_EQ(w.t.reaction().exchange - w.t.start().exchange, 2U);
  w.in.contactor_closed = false;
  w.go();  // 5: feedback open, still turning
  w.in.drive[0].velocity_rad_s = 0.02F;
  w.go();  // 6: above 0.01 rad/s: not yet
  EXPECT_FALSE(w.t.safe().seen);
  w.in.drive[0].velocity_rad_s = 0.005F;
  w.go();  // 7: standstill on every axis, contactor open
  ASSERT_TRUE(w.t.safe().seen);
  EXPECT_EQ(w.t.safe().exchange, 7U);
  const nlohmann::json j = w.t.to_json(w.in);
  EXPECT_EQ(j["reaction"]["cycles"], 2);
  EXPECT_EQ(j["reaction"]["us"], 2000);
  EXPECT_EQ(j["safe"]["cycles"], 5);
  EXPECT_EQ(j["stop"], "cat0");
  EXPECT_EQ(j["from"], "input");
}

TEST(EcatWireTiming, Cat1ReactionIsTheCommandedSpeedFallingBeyondTheWiresQuantisation) {
  Wire w;
  w.arm("cat1 from=input");
  const double cruise = 167.3 * kCount;  // about 1 rad/s
  for (int i = 0; i < 5; ++i) w.go(cruise);
  w.t.input_changed();
  w.go(cruise);  // 5: start, at cruise
  w.go(cruise - 1.0 * kCount);  // 6: one count less: rounding can do that, no reaction
  EXPECT_FALSE(w.t.reaction().seen);
  w.go(cruise + 1.0 * kCount);  // 7
  w.go(cruise - 3.0 * kCount);  // 8: three counts below the start's: the ramp has begun
  ASSERT_TRUE(w.t.reaction().seen);
  EXPECT_EQ(w.t.reaction().exchange, 8U);
  // The commanded speed from the start on, as `status` shows it (the fall's evidence).
  const nlohmann::json tr = w.t.to_json(w.in)["speed_counts"];
  ASSERT_EQ(tr.size(), 4U);
  EXPECT_EQ(tr[0], 167.0);
  EXPECT_EQ(tr[3], 164.0);
  for (double s = cruise - 6.0 * kCount; s > 0.0; s -= 3.0 * kCount) w.go(s);
  EXPECT_FALSE(w.t.safe().seen);  // standstill is not the end of a Cat 1: the contactor is
  w.go();
  w.out.contactor = false;
  w.go();
  ASSERT_TRUE(w.t.safe().seen);
  EXPECT_EQ(w.t.safe().exchange, w.n - 1U);
}

TEST(EcatWireTiming, Cat1ReactionAlsoWhenThePowerIsRemovedAtOnce) {
  Wire w;
  w.arm("cat1 from=input");
  w.go(0.001);
  w.t.input_changed();
  w.go(0.001);
  w.out.contactor = false;
  w.go(0.001);  // no fall of the targets, but power removed (an escalation to Cat 0)
  ASSERT_TRUE(w.t.reaction().seen);
  EXPECT_EQ(w.t.reaction().exchange - w.t.start().exchange, 1U);
  EXPECT_TRUE(w.t.safe().seen);
}

TEST(EcatWireTiming, Cat2SafeIsTheFirstOfTenExchangesWithTheTargetsStill) {
  Wire w;
  w.arm("cat2 from=fault");
  w.go(0.001);
  w.t.fault_injected();
  w.go(0.001);  // 1: the first exchange after the fault starts the count
  EXPECT_EQ(w.t.start().exchange, 1U);
  w.go(0.0005);  // 2: falls
  EXPECT_EQ(w.t.reaction().exchange, 2U);
  for (int i = 0; i < 5; ++i) w.go();  // 3..7 still
  w.go(kCount);  // 8: moves one count again: the run of standstill starts afresh
  for (int i = 0; i < 9; ++i) w.go();  // 9..17
  EXPECT_FALSE(w.t.safe().seen);
  w.go();  // 18: the tenth exchange without motion since 9
  ASSERT_TRUE(w.t.safe().seen);
  EXPECT_EQ(w.t.safe().exchange, 9U);
}

TEST(EcatWireTiming, ReduceSafeIsTheCommandedTcpSpeedAtOrBelowTheLimit) {
  Wire w;
  w.t.set_tcp({0.0F, 0.0F, 120.0F});
  w.arm("reduce=250 from=input");
  // Axis 1 at 1 rad/s: the TCP, far from the base, is well above 250 mm/s.
  for (int i = 0; i < 3; ++i) w.go(0.001);
  w.t.input_changed();
  w.go(0.001);  // 3: start
  w.go(0.001);  // 4: unchanged
  EXPECT_FALSE(w.t.reaction().seen);
  double step = 0.001;
  while (!w.t.safe().seen && w.n < 2000U) {
    step *= 0.97;
    w.go(step);
  }
  ASSERT_TRUE(w.t.reaction().seen);
  EXPECT_EQ(w.t.reaction().exchange, 5U);  // 3 % of 167 counts: 5 counts below the start
  ASSERT_TRUE(w.t.safe().seen);
  // The exchange of the safe state is the first whose TCP step is at or below 0.25 mm.
  const std::uint64_t k = w.t.safe().exchange;
  EXPECT_GT(k, 5U);
  const double lever_mm = 250.0 / 1000.0 / (0.001 * std::pow(0.97, static_cast<double>(k - 4U)));
  EXPECT_GT(lever_mm, 100.0);  // plausibly the TCP's distance from axis 1 (a real arm, not 0)
  EXPECT_LT(lever_mm, 1000.0);
}

TEST(EcatWireTiming, ALimitStartsTheCountWhenTheCarriedInputsCrossIt) {
  Wire w;
  w.arm("cat0 from=joint.1>0.5");
  w.in.drive[0].position_rad = 0.49F;
  w.go();
  EXPECT_FALSE(w.t.start().seen);
  w.in.drive[0].position_rad = 0.51F;
  w.go();  // 1 carries the crossing
  EXPECT_EQ(w.t.start().exchange, 1U);
  w.out.contactor = false;
  w.go();
  EXPECT_EQ(w.t.reaction().exchange - w.t.start().exchange, 1U);
  EXPECT_FALSE(w.t.early().seen);

  Wire v;  // something else stopped the arm before the limit was crossed: said so
  v.arm("cat0 from=speed.2>1.0");
  v.go();
  v.out.contactor = false;
  v.go();
  EXPECT_TRUE(v.t.early().seen);
  EXPECT_FALSE(v.t.start().seen);
  EXPECT_TRUE(v.t.to_json(v.in)["reaction"].is_null());
  EXPECT_EQ(v.t.to_json(v.in)["early_exchange"], 1);
}

TEST(EcatWireTiming, TiltAndTcpAreJudgedWithTheArmsKinematics) {
  Wire w;
  w.arm("cat0 from=tilt>0.02");
  w.in.drive[4].position_rad = 0.3F;
  w.go();  // the reference: where the tool axis pointed when armed
  w.in.drive[4].position_rad = 0.315F;
  w.go();
  EXPECT_FALSE(w.t.start().seen);  // 0.015 rad
  w.in.drive[4].position_rad = 0.325F;
  w.go();
  EXPECT_TRUE(w.t.start().seen);  // 0.025 rad: axis 5 tilts the tool axis by its own angle

  Wire p;
  const nlohmann::json pose = p.t.to_json(p.in);
  const float y = pose["tcp_mm"][1].get<float>();
  p.arm("cat0 from=tcp.y>" + std::to_string(y + 5.0F));
  p.go();
  p.in.drive[0].position_rad = 0.001F;  // axis 1 turns the TCP towards +y
  p.go();
  EXPECT_FALSE(p.t.start().seen);
  p.in.drive[0].position_rad = 0.05F;
  p.go();
  EXPECT_TRUE(p.t.start().seen);
}

TEST(EcatWireTiming, TheControlLineIsValidatedAndABadOneChangesNothing) {
  EmulatedCell cell(kCycleUs, safestate::ecat::default_segment(false));
  const auto armed = [&cell] { return nlohmann::json::parse(control_line(cell, "status"))["wire_timing"]["armed"]; };
  EXPECT_EQ(armed(), false);
  for (const char* bad : {"time", "time cat3 from=input", "time cat1", "time cat1 from=gate", "time cat1 from=input x",
                          "time reduce=0 from=input", "time reduce=abc from=input", "time cat0 from=joint.7>1",
                          "time cat0 from=joint.1>x", "time cat0 from=speed.1>0", "time cat0 from=tcp.w>1",
                          "time cat0 from=joint.1<1", "time cat0 from=tilt>nan"}) {
    const std::string r = control_line(cell, bad);
    EXPECT_EQ(r.rfind("ERROR", 0), 0U) << bad << " -> " << r;
    EXPECT_EQ(armed(), false) << bad;
  }
  EXPECT_NE(control_line(cell, "time cat9 from=input").find("unknown stop 'cat9'"), std::string::npos);
  EXPECT_NE(control_line(cell, "time cat0 from=knee>1").find("unknown quantity 'knee'"), std::string::npos);
  EXPECT_EQ(control_line(cell, "time reduce=250 from=point_speed>300"), "OK");
  EXPECT_EQ(armed(), true);
  const nlohmann::json j = nlohmann::json::parse(control_line(cell, "status"))["wire_timing"];
  EXPECT_EQ(j["stop"], "reduce");
  EXPECT_EQ(j["from"], "point_speed");
  EXPECT_TRUE(j["start_exchange"].is_null());
  EXPECT_EQ(control_line(cell, "time off"), "OK");
  EXPECT_EQ(armed(), false);
}

// The bench arms and opens the contact between two exchanges: the start is then the first
// exchange after arming, and the fall is judged against the speed the targets had then.
TEST(EcatWireTiming, TheTargetsHistoryOutlivesArmingSoTheFirstExchangeMayStart) {
  Wire w;
  const double cruise = 167.3 * kCount;
  for (int i = 0; i < 5; ++i) w.go(cruise);  // not armed yet: the history is kept all the same
  w.arm("cat1 from=input");
  w.t.input_changed();
  w.go(cruise);  // 5: the start, at cruise
  EXPECT_EQ(w.t.start().exchange, 5U);
  w.go(cruise);
  EXPECT_FALSE(w.t.reaction().seen);
  w.go(cruise - 4.0 * kCount);
  ASSERT_TRUE(w.t.reaction().seen);
  EXPECT_EQ(w.t.reaction().exchange - w.t.start().exchange, 2U);
}

// A program still accelerating when the trigger came: the fall is judged against the highest
// commanded speed since the start, not the start's own (which would see the ramp late).
TEST(EcatWireTiming, TheFallIsJudgedAgainstTheHighestSpeedSinceTheStart) {
  Wire w;
  w.arm("cat2 from=fault");
  w.go(170.0 * kCount);
  w.t.fault_injected();
  w.go(170.0 * kCount);  // 1: the start
  w.go(175.0 * kCount);  // 2: still accelerating
  w.go(172.0 * kCount);  // 3: 3 counts below the peak, only 2 above the start's
  ASSERT_TRUE(w.t.reaction().seen);
  EXPECT_EQ(w.t.reaction().exchange, 3U);
}

// SPEC §10 on the wire: the DO terminal's reduced_active bit is the reaction of reduced mode,
// for `reduced` alone and for `reduce=` (before the commanded speed has fallen at all).
TEST(EcatWireTiming, ReducedModeReactionIsTheReducedActiveBit) {
  Wire w;
  w.arm("reduced from=input");
  w.go(0.001);
  w.t.input_changed();
  w.go(0.001);  // 1: start
  w.go(0.001);  // 2: not yet
  EXPECT_FALSE(w.t.reaction().seen);
  w.out.contactor = false;  // power removal is not reduced mode
  w.go(0.001);  // 3
  EXPECT_FALSE(w.t.reaction().seen);
  w.out.contactor = true;
  w.out.reduced_active = true;
  w.go(0.001);  // 4: the bit
  ASSERT_TRUE(w.t.reaction().seen);
  EXPECT_EQ(w.t.reaction().exchange - w.t.start().exchange, 3U);
  ASSERT_TRUE(w.t.safe().seen);
  EXPECT_EQ(w.t.safe().exchange, w.t.reaction().exchange);
  EXPECT_EQ(w.t.to_json(w.in)["stop"], "reduced");

  Wire r;
  r.t.set_tcp({0.0F, 0.0F, 120.0F});
  r.arm("reduce=250 from=input");
  for (int i = 0; i < 3; ++i) r.go(0.001);
  r.t.input_changed();
  r.go(0.001);  // 3: start
  r.out.reduced_active = true;
  r.go(0.001);  // 4: the bit, the speed unchanged
  ASSERT_TRUE(r.t.reaction().seen);
  EXPECT_EQ(r.t.reaction().exchange, 4U);
  EXPECT_FALSE(r.t.safe().seen);  // the TCP is still far above 250 mm/s

  // Already on before the trigger: the arm was reduced before, nothing to time.
  Wire e;
  e.arm("reduced from=input");
  e.out.reduced_active = true;
  e.go();
  e.go();
  EXPECT_TRUE(e.t.early().seen);
}

// SPEC §11 on the wire: the distance sensor's reading below the protective distance (or
// invalid: unknown is unsafe) carried to the master starts the count.
TEST(EcatWireTiming, TheSeparationBelowAThresholdStartsTheCount) {
  Wire w;
  w.arm("cat2 from=separation<2372");
  w.in.safety.separation_mm = 5000;
  w.in.safety.separation_valid = true;
  w.go(0.001);
  w.go(0.001);
  EXPECT_FALSE(w.t.start().seen);
  w.in.safety.separation_mm = 2372;  // at it: not below
  w.go(0.001);
  EXPECT_FALSE(w.t.start().seen);
  w.in.safety.separation_mm = 300;
  w.go(0.001);  // 3
  ASSERT_TRUE(w.t.start().seen);
  EXPECT_EQ(w.t.start().exchange, 3U);
  EXPECT_EQ(w.t.to_json(w.in)["from"], "separation");

  Wire v;
  v.arm("cat2 from=separation<1000");
  v.in.safety.separation_mm = 5000;
  v.in.safety.separation_valid = false;  // far, but not valid
  v.go();
  EXPECT_TRUE(v.t.start().seen);

  EmulatedCell cell(kCycleUs, safestate::ecat::default_segment(false));
  for (const char* bad : {"time cat2 from=separation<0", "time cat2 from=separation<x", "time cat2 from=separation>5",
                          "time reduced from=separation<", "time reducedx from=input"}) {
    EXPECT_EQ(control_line(cell, bad).rfind("ERROR", 0), 0U) << bad;
  }
  EXPECT_EQ(control_line(cell, "time cat2 from=separation<1200"), "OK");
  EXPECT_EQ(control_line(cell, "time reduced from=input"), "OK");
}

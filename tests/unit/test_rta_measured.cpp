// SPEC §13: each safety function triggered on the running simulated cell (in-process),
// and the measured reaction never later than `safestate rta` computes, in cycles to the
// safe output and in time to the safe state. So the analysis cannot drift from the code.
#include <gtest/gtest.h>

#include "safestate/rta/rta.hpp"

using namespace safestate;

namespace {
void check(const core::Config& cfg, const safety::Loaded& s) {
  rta::BusTiming bus;
  bus.source = "simulated cell";
  const rta::Analysis a = rta::analyse(cfg, s, bus);
  const std::vector<rta::Measured> ms = rta::measure(cfg, s);
  int measured = 0;
  for (const rta::Measured& m : ms) {
    const rta::Function* f = a.find(m.id);
    ASSERT_NE(f, nullptr) << m.id;
    if (!m.measured) {
      EXPECT_NE(m.how.find("not measured"), std::string::npos) << m.id << ": " << m.how;
      continue;
    }
    ++measured;
    EXPECT_GE(m.reaction_cycles, 1U) << m.id;
    EXPECT_LE(m.reaction_cycles, f->reaction_cycles) << m.id << ": " << m.how;
    EXPECT_LE(m.safe_cycles * cfg.cycle_us, f->total_us()) << m.id << ": " << m.how;
    EXPECT_GE(m.safe_cycles, m.reaction_cycles - 1U) << m.id;
  }
  EXPECT_GE(measured, 8);  // estop, guard, enable, reduced, outer, inner, collision, bus loss
}
}  // namespace

// @req RTA-MEASURED
TEST(RtaMeasured, BuiltinConfigurationNeverAboveTheAnalysis) { check(core::Config{}, safety::default_safety()); }

// @req RTA-MEASURED
TEST(RtaMeasured, TwoMillisecondCycleNeverAboveTheAnalysis) {
  core::Config cfg{};
  cfg.cycle_us = 2000;
  check(cfg, safety::default_safety());
}

// The collaborative example (fields, SSM, PFL, a brake test required): every function is
// measured on it too (the fields, SSM holding, the brake test due: the run sets a distant
// person and a recent pass), never above the analysis.
// @req RTA-MEASURED
TEST(RtaMeasured, CollaborativeExampleNeverAboveTheAnalysis) {
  const safety::Result r = safety::load_safety_file(std::string(SAFESTATE_SOURCE_DIR) + "/examples/safety/collaborative.json");
  ASSERT_TRUE(r.ok());
  check(core::Config{}, *r.config);
  for (const rta::Measured& m : rta::measure(core::Config{}, *r.config)) {
    EXPECT_EQ(m.how.find("setup failed"), std::string::npos) << m.id << ": " << m.how;
  }
}

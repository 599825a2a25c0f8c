// SPEC §14 measured: the short campaign of `make test` (the bench runs 10,000 injections,
// docs/performance.md). With two channels every (fault, demand) pair stays safe and every
// dangerous fault is named; with one, the stalled channel and the welded contactor are
// dangerous (what the second channel buys). The campaign is reproducible.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "safestate/faults/campaign.hpp"

using namespace safestate;

namespace {
const faults::Report& two() {
  static const faults::Report r = faults::run(faults::Options{1, 400, 2, 2, 0});
  return r;
}
}  // namespace

// @req CH-PAIR CH-LOST CH-MISMATCH
TEST(FaultCampaign, WithTwoChannelsEveryDemandStaysSafeAndEveryDangerousFaultIsNamed) {
  const faults::Report& r = two();
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.injected, 400U);
  // Four situations in turn: AUTO running (4 demands), T1 jogging, in a slot, at a joint limit.
  EXPECT_EQ(r.pairs, 100U * 4U + 100U + 100U + 100U);
  EXPECT_EQ(r.pairs_safe, r.pairs) << faults::table(r);
  EXPECT_EQ(r.dangerous_count, 0U) << faults::table(r);
  EXPECT_GE(r.dc, 0.99);
  std::set<std::string> classes;
  for (const faults::ClassStats& c : r.classes) {
    classes.insert(c.name);
    EXPECT_EQ(c.injected, c.detected + c.masked + c.failsafe + c.dangerous + c.crashed) << c.name;
  }
  for (const char* c : {"channel stall", "channel crash", "channel input", "digest", "contactor welded", "encoder",
                        "supervisor bit flip"}) {
    EXPECT_TRUE(classes.count(c) == 1U) << "no " << c << " among 400 injections";
  }
  for (const faults::ClassStats& c : r.classes) {
    if (c.name == "channel stall" || c.name == "channel crash" || c.name == "digest") {
      EXPECT_EQ(c.detected, c.injected) << c.name << ": the other channel names every one";
      EXPECT_EQ(c.named_before_demand, c.injected) << c.name << ": before the demand";
    }
  }
  ASSERT_FALSE(r.to_lockout.empty());
}

// SPEC §14 / issue 36 item 7: every demand of the list is made, in its own situation, and
// the fault-free cell answers each with the safety function it is about (a demand answered
// by another function would not test the one it names).
TEST(FaultCampaign, EachDemandIsAnsweredByTheSafetyFunctionItNames) {
  const faults::Report& r = two();
  ASSERT_TRUE(r.error.empty()) << r.error;
  const std::map<std::string, std::string> want{
      {"E-stop", "ESTOP_PRESSED"},
      {"guard opened in AUTO", "PROTECTIVE_STOP"},
      {"drive 1 runaway", "DRIVE_FAULT"},
      {"reduced speed requested (speed over its new limit)", "REDUCED_SPEED"},
      {"enabling device released in T1", ""},  // its own stop (SPEC §4: no alarm)
      {"drive 1 runaway into the slot's wall (zone)", "ZONE_VIOLATION"},
      {"drive 1 runaway past axis 1's limit", "JOINT_LIMIT"},
  };
  ASSERT_EQ(r.demands.size(), want.size()) << faults::table(r);
  for (const faults::DemandStats& d : r.demands) {
    ASSERT_TRUE(want.count(d.name) == 1U) << d.name;
    EXPECT_EQ(d.answered_by, want.at(d.name)) << d.name << "\n" << faults::table(r);
    EXPECT_EQ(d.pairs, 100U) << d.name;
    EXPECT_EQ(d.safe, d.pairs) << d.name;
    EXPECT_GT(d.reaction_cycles, 0U) << d.name << ": already safe before the demand proves nothing";
  }
}

TEST(FaultCampaign, WithOneChannelAStalledChannelIsDangerous) {
  const faults::Report r = faults::run(faults::Options{1, 400, 1, 2, 0});
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_GT(r.dangerous_count, 0U);
  EXPECT_LT(r.pairs_safe, r.pairs);
  EXPECT_LT(r.dc, two().dc);
  bool stall = false;
  for (const faults::Injection& i : r.dangerous) {
    stall = stall || i.cls == "channel stall";
  }
  EXPECT_TRUE(stall) << faults::table(r);
}

TEST(FaultCampaign, AnInjectionIsTheSameFaultEveryTime) {
  const faults::Report a = faults::run(faults::Options{7, 3, 2, 1, 20});
  const faults::Report b = faults::run(faults::Options{7, 3, 2, 1, 20});
  ASSERT_TRUE(a.error.empty() && b.error.empty());
  EXPECT_EQ(faults::json(a), faults::json(b));
  const auto classes = [](const faults::Report& r) {
    std::string s;
    for (const faults::ClassStats& c : r.classes) s += c.name + ":" + std::to_string(c.injected) + " ";
    return s;
  };
  int differ = 0;
  for (std::uint32_t seed = 8; seed < 12; ++seed) {
    differ += classes(faults::run(faults::Options{seed, 3, 2, 1, 20})) != classes(a) ? 1 : 0;
  }
  EXPECT_GT(differ, 0) << "other seeds, other faults";
}

// Issue 37 item 6: `--fieldbus ethercat` — the warm cells carry the black channel (in the
// simulated world: the containers and both ends real, the bus a byte copy) and the campaign
// adds faults on its wire. Every bus fault is named SAFETY_LINK_FAULT, the safe output
// terminal opens K1 or K2 within the 10-cycle watchdog of the last valid container and both
// in the end, and every demand still reaches its safe state.
// @req LINK-FAULT
TEST(FaultCampaign, EveryBusFaultIsNamedAndTheSafeOutputsOpenWithinTheWatchdog) {
  for (const std::uint8_t ch : {std::uint8_t{2}, std::uint8_t{1}}) {
    SCOPED_TRACE(static_cast<int>(ch));
    faults::Options o{3, 240, ch, 2, 0};
    o.fieldbus = faults::Fieldbus::ethercat;
    const faults::Report r = faults::run(o);
    ASSERT_TRUE(r.error.empty()) << r.error;
    EXPECT_EQ(r.watchdog_cycles, 10U);
    ASSERT_EQ(r.bus.size(), 5U);
    for (const faults::BusStats& b : r.bus) {
      SCOPED_TRACE(b.name);
      EXPECT_GT(b.injected, 0U) << "each class at least once\n" << faults::table(r);
      EXPECT_EQ(b.caught, b.injected) << faults::table(r);
      EXPECT_EQ(b.dangerous, 0U);
      EXPECT_EQ(b.not_opened, 0U) << "K1 and K2 both open at the F-DO every time";
      ASSERT_EQ(b.from_last_valid.size(), b.injected);
      for (const std::uint32_t k : b.from_last_valid) {
        EXPECT_LE(k, r.watchdog_cycles) << faults::table(r);
      }
      for (const std::uint32_t k : b.to_power_open) {
        EXPECT_LE(k, r.watchdog_cycles + 1U) << "the watchdog, and a container that was on its way";
      }
      std::uint64_t named = 0;
      for (const auto& e : b.errors) {
        named += e.second;
      }
      EXPECT_EQ(named, b.caught);
    }
    // The errors each kind is meant to produce are among those named (the device's end, failing
    // first, turns the others into not_connected at the channel).
    const auto has = [&r](const std::string& cls, const std::string& err) {
      for (const faults::BusStats& b : r.bus) {
        for (const auto& e : b.errors) {
          if (b.name == cls && e.first == err) return true;
        }
      }
      return false;
    };
    EXPECT_TRUE(has("bus flip", "crc"));
    EXPECT_TRUE(has("bus replay", "sequence"));
    EXPECT_TRUE(has("bus delay", "timeout"));
    EXPECT_TRUE(has("bus insert", "identity"));
    if (ch == 2U) {
      EXPECT_EQ(r.dangerous_count, 0U) << faults::table(r);
      EXPECT_EQ(r.pairs_safe, r.pairs) << faults::table(r);
    }
    const std::string text = faults::table(r);
    EXPECT_NE(text.find("bus faults (issue 37)"), std::string::npos);
    const nlohmann::json j = nlohmann::json::parse(faults::json(r));
    EXPECT_EQ(j.at("fieldbus"), "ethercat");
    EXPECT_EQ(j.at("bus_faults").size(), 5U);
  }
}

// The sim campaign (no --fieldbus, or sim) gives exactly what it gave before the bus faults
// came: the figures of seed 1, 120 injections, both channel counts, as the tree before them
// printed (tests/golden/faults_seed1_120.json).
TEST(FaultCampaign, TheSimCampaignIsUnchangedByTheBusFaults) {
  std::ifstream f(std::string(SAFESTATE_SOURCE_DIR) + "/tests/golden/faults_seed1_120.json");
  ASSERT_TRUE(f.good());
  const nlohmann::json golden = nlohmann::json::parse(f);
  for (const std::uint8_t ch : {std::uint8_t{2}, std::uint8_t{1}}) {
    const faults::Report r = faults::run(faults::Options{1, 120, ch, 1, 0});
    EXPECT_EQ(nlohmann::json::parse(faults::json(r)), golden.at(std::to_string(ch))) << static_cast<int>(ch);
  }
}

TEST(FaultCampaign, TheFieldbusIsSimOrEthercat) {
  faults::Fieldbus f = faults::Fieldbus::ethercat;
  EXPECT_TRUE(faults::parse_fieldbus("sim", f));
  EXPECT_EQ(f, faults::Fieldbus::sim);
  EXPECT_TRUE(faults::parse_fieldbus("ethercat", f));
  EXPECT_EQ(f, faults::Fieldbus::ethercat);
  EXPECT_FALSE(faults::parse_fieldbus("EtherCAT ", f));
  EXPECT_FALSE(faults::parse_fieldbus("", f));
  EXPECT_EQ(f, faults::Fieldbus::ethercat) << "unchanged";
  EXPECT_STREQ(faults::to_string(faults::Fieldbus::sim), "sim");
}

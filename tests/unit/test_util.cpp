// The helpers shared by benches, printers and parsers (issue 35 item 5: one definition each).
#include <gtest/gtest.h>

#include <vector>

#include "safestate/core/types.hpp"
#include "safestate/util/percentile.hpp"
#include "safestate/vocab/names.hpp"

using namespace safestate;

TEST(Percentile, NearestRankOfOneToAHundred) {
  std::vector<int> v;
  for (int i = 100; i >= 1; --i) {
    v.push_back(i);  // unsorted on purpose: percentile() sorts
  }
  EXPECT_EQ(util::percentile(v, 0.50), 50);
  EXPECT_EQ(util::percentile(v, 0.99), 99);
  EXPECT_EQ(util::percentile(v, 0.999), 100) << "rank ceil(99.9) = 100";
  EXPECT_EQ(util::percentile(v, 1.0), 100) << "p100 is the maximum";
  EXPECT_EQ(util::percentile(v, 0.0), 1) << "p0 is the minimum";
  EXPECT_EQ(util::percentile(v, 0.011), 2) << "rank ceil(1.1) = 2, never interpolated";
}

TEST(Percentile, OneSampleAndNone) {
  EXPECT_EQ(util::percentile(std::vector<double>{7.5}, 0.99), 7.5);
  EXPECT_EQ(util::percentile(std::vector<double>{}, 0.5), 0.0);
  EXPECT_EQ(util::percentile(std::vector<int>{3, 1, 2}, 2.0), 3) << "q is clamped to [0, 1]";
}

TEST(AlarmNames, InTheAlarmTablesOrderWhateverTheMask) {
  const core::AlarmMask m = core::bit(core::AlarmId::COLLISION) | core::bit(core::AlarmId::ESTOP_DISCREPANCY) |
                            core::bit(core::AlarmId::JOINT_LIMIT);
  EXPECT_EQ(vocab::alarm_names(m).dump(), R"(["ESTOP_DISCREPANCY","JOINT_LIMIT","COLLISION"])");
  EXPECT_EQ(vocab::alarm_names(0U).dump(), "[]");
}

TEST(JogCommand, DirectionSignsAndTheDefaultSpeed) {
  EXPECT_EQ(core::jog_direction("+"), 1);
  EXPECT_EQ(core::jog_direction("-"), -1);
  EXPECT_EQ(core::jog_direction("+1"), 0) << "anything else: the core answers BAD_ARGUMENT";
  EXPECT_EQ(core::jog_direction(""), 0);
  core::Command c{};
  core::set_jog(c, 3, -1, core::kJogDefaultSpeedPct);
  EXPECT_EQ(c.axis, 3);
  EXPECT_EQ(c.dir, -1);
  EXPECT_EQ(c.speed, 10);
}

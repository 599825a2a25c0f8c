// Configuration from outside is validated: a bad value is named, never used.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "safestate/core/config.hpp"

using namespace safestate::core;

TEST(Config, DefaultsAreValidAndGiveTheSpecTimings) {
  const Config c{};
  ASSERT_TRUE(validate(c).ok());
  const Timing t = to_timing(c);
  EXPECT_EQ(t.discrepancy, 50U);
  EXPECT_EQ(t.jog_timeout, 100U);
  EXPECT_EQ(t.max_stop, 1000U);
  EXPECT_EQ(t.boot_timeout, 3000U);
  EXPECT_EQ(t.standstill_cycles, 10U);
  EXPECT_EQ(t.contactor_timeout, 100U);
  EXPECT_EQ(t.drives_timeout, 500U);
  EXPECT_EQ(t.brakes_timeout, 300U);
  EXPECT_EQ(t.reset_hold_max, 5000U);
  EXPECT_EQ(t.fault_reset_reply, 50U);
  EXPECT_EQ(t.max_commands_per_cycle, 8U);
}

TEST(Config, MillisecondsBecomeWholeCyclesRoundedDown) {
  EXPECT_EQ(ms_to_cycles(50, 1000), 50U);
  EXPECT_EQ(ms_to_cycles(50, 250), 200U);
  EXPECT_EQ(ms_to_cycles(50, 4000), 12U);  // 13 cycles = 52 ms is "more than 50 ms"
  EXPECT_EQ(ms_to_cycles(100, 3000), 33U);
}

TEST(Config, EachBadFieldIsNamed) {
  struct Case {
    const char* field;
    void (*mutate)(Config&);
  };
  const Case cases[] = {
      {"cycle_us", [](Config& c) { c.cycle_us = 100; }},
      {"cycle_us", [](Config& c) { c.cycle_us = 5000; }},
      {"discrepancy_ms", [](Config& c) { c.discrepancy_ms = 0; }},
      {"jog_timeout_ms", [](Config& c) { c.jog_timeout_ms = 0; }},
      {"max_stop_ms", [](Config& c) { c.max_stop_ms = 0; }},
      {"boot_timeout_ms", [](Config& c) { c.boot_timeout_ms = 0; }},
      {"standstill_rad_s", [](Config& c) { c.standstill_rad_s = 0.0F; }},
      {"standstill_rad_s", [](Config& c) { c.standstill_rad_s = std::nanf(""); }},
      {"max_commands_per_cycle", [](Config& c) { c.max_commands_per_cycle = 0; }},
      {"max_commands_per_cycle", [](Config& c) { c.max_commands_per_cycle = 17; }},
      {"t1_speed_limit_mm_s", [](Config& c) { c.t1_speed_limit_mm_s = 251.0F; }},
      {"t1_speed_limit_mm_s", [](Config& c) { c.t1_speed_limit_mm_s = 0.0F; }},
      {"standstill_rad_s", [](Config& c) { c.standstill_rad_s = 10.0F; }},
      // SPEC §14.
      {"cross_check_cycles", [](Config& c) { c.cross_check_cycles = 0; }},
      {"cross_check_cycles", [](Config& c) { c.cross_check_cycles = 101; }},
      {"encoder_tolerance_deg", [](Config& c) { c.encoder_tolerance_deg = 0.0F; }},
      {"encoder_tolerance_deg", [](Config& c) { c.encoder_tolerance_deg = 10.5F; }},
      {"encoder_tolerance_deg", [](Config& c) { c.encoder_tolerance_deg = std::nanf(""); }},
      {"encoder_discrepancy_ms", [](Config& c) { c.encoder_discrepancy_ms = 0; }},
      {"integrity_period_ms", [](Config& c) { c.integrity_period_ms = 5; }},
      {"cycle_us", [](Config& c) {
         c.cycle_us = 4000;
         c.encoder_discrepancy_ms = 3;
       }},
      {"cycle_us", [](Config& c) {
         c.cycle_us = 4000;
         c.discrepancy_ms = 3;
       }},
  };
  for (const Case& k : cases) {
    Config c{};
    k.mutate(c);
    const ConfigError e = validate(c);
    ASSERT_FALSE(e.ok()) << k.field;
    EXPECT_STREQ(e.field, k.field);
    EXPECT_NE(std::string(e.reason).size(), 0U);
  }
}

#include "safestate/core/config.hpp"

#include <array>

#include "safestate/core/supervisor.hpp"

namespace safestate::core {

namespace {
struct Range {
  const char* field;
  std::uint32_t value;
  std::uint32_t min;
  std::uint32_t max;
  const char* reason;
};
}  // namespace

ConfigError validate(const Config& c) noexcept {
  const std::array<Range, 16> ranges{{
      {"cycle_us", c.cycle_us, 250U, 4000U, "must be 250..4000 (SPEC 1: 0.25-4 ms)"},
      {"discrepancy_ms", c.discrepancy_ms, 1U, 1000U, "must be 1..1000"},
      {"jog_timeout_ms", c.jog_timeout_ms, 1U, 10000U, "must be 1..10000"},
      {"max_stop_ms", c.max_stop_ms, 1U, 60000U, "must be 1..60000"},
      {"boot_timeout_ms", c.boot_timeout_ms, 1U, 600000U, "must be 1..600000"},
      {"standstill_cycles", c.standstill_cycles, 1U, 10000U, "must be 1..10000"},
      {"max_commands_per_cycle", c.max_commands_per_cycle, 1U, static_cast<std::uint32_t>(kMaxCommandsPerCycle),
       "must be 1..16"},
      {"contactor_timeout_ms", c.contactor_timeout_ms, 1U, 60000U, "must be 1..60000"},
      {"drives_timeout_ms", c.drives_timeout_ms, 1U, 60000U, "must be 1..60000"},
      {"brakes_timeout_ms", c.brakes_timeout_ms, 1U, 60000U, "must be 1..60000"},
      {"reset_hold_max_ms", c.reset_hold_max_ms, 1U, 60000U, "must be 1..60000"},
      {"fault_reset_reply_cycles", c.fault_reset_reply_cycles, 1U, 10000U, "must be 1..10000"},
      {"queue_size", c.queue_size, 1U, kMaxQueueSize, "must be 1..256"},
      {"cross_check_cycles", c.cross_check_cycles, 1U, 100U, "must be 1..100"},
      {"encoder_discrepancy_ms", c.encoder_discrepancy_ms, 1U, 1000U, "must be 1..1000"},
      {"integrity_period_ms", c.integrity_period_ms, 10U, 600000U, "must be 10..600000"},
  }};
  for (const Range& r : ranges) {
    if ((r.value < r.min) || (r.value > r.max)) {
      return ConfigError{r.field, r.reason};
    }
  }
  // `!(x > 0)` also rejects NaN.
  if (!(c.standstill_rad_s > 0.0F) || !(c.standstill_rad_s < 10.0F)) {
    return ConfigError{"standstill_rad_s", "must be > 0 and < 10"};
  }
  if (!(c.encoder_tolerance_deg > 0.0F) || !(c.encoder_tolerance_deg <= 10.0F)) {
    return ConfigError{"encoder_tolerance_deg", "must be > 0 and <= 10"};
  }
  if (!(c.t1_speed_limit_mm_s > 0.0F) || !(c.t1_speed_limit_mm_s <= 250.0F)) {
    return ConfigError{"t1_speed_limit_mm_s", "must be > 0 and <= 250 (ISO 10218-1 reduced speed)"};
  }
  // Every timer must span at least one cycle, or it would fire in the cycle it starts.
  const std::array<std::uint32_t, 8> timed{c.discrepancy_ms,       c.jog_timeout_ms,    c.max_stop_ms,
                                           c.contactor_timeout_ms, c.drives_timeout_ms, c.brakes_timeout_ms,
                                           c.encoder_discrepancy_ms, c.integrity_period_ms};
  for (const std::uint32_t ms : timed) {
    if (ms_to_cycles(ms, c.cycle_us) < 1U) {
      return ConfigError{"cycle_us", "is longer than one of the timeouts: every timeout must span at least one cycle"};
    }
  }
  return ConfigError{};
}

Timing to_timing(const Config& c) noexcept {
  Timing t{};
  t.discrepancy = ms_to_cycles(c.discrepancy_ms, c.cycle_us);
  t.jog_timeout = ms_to_cycles(c.jog_timeout_ms, c.cycle_us);
  t.max_stop = ms_to_cycles(c.max_stop_ms, c.cycle_us);
  t.boot_timeout = ms_to_cycles(c.boot_timeout_ms, c.cycle_us);
  t.standstill_cycles = c.standstill_cycles;
  t.standstill_rad_s = c.standstill_rad_s;
  t.max_commands_per_cycle = c.max_commands_per_cycle;
  t.t1_speed_limit_mm_s = c.t1_speed_limit_mm_s;
  t.cycles_per_s = 1.0e6F / static_cast<float>(c.cycle_us);
  t.contactor_timeout = ms_to_cycles(c.contactor_timeout_ms, c.cycle_us);
  t.drives_timeout = ms_to_cycles(c.drives_timeout_ms, c.cycle_us);
  t.brakes_timeout = ms_to_cycles(c.brakes_timeout_ms, c.cycle_us);
  t.reset_hold_max = ms_to_cycles(c.reset_hold_max_ms, c.cycle_us);
  t.fault_reset_reply = c.fault_reset_reply_cycles;
  const Cycle confirm = ms_to_cycles(kBrakeConfirmMs, c.cycle_us);
  t.brake_confirm = (confirm < 1U) ? Cycle{1} : confirm;
  t.cross_check = c.cross_check_cycles;
  t.encoder_tolerance_rad = c.encoder_tolerance_deg * (3.14159265F / 180.0F);
  t.encoder_discrepancy = ms_to_cycles(c.encoder_discrepancy_ms, c.cycle_us);
  t.integrity_period = ms_to_cycles(c.integrity_period_ms, c.cycle_us);
  return t;
}

}  // namespace safestate::core

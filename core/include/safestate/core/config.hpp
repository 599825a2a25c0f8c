// Timing constants of SPEC.md, given in milliseconds by integrators and converted once,
// at start-up, into cycles. Nothing in the cycle ever looks at milliseconds again.
#pragma once

#include <cstdint>

#include "safestate/core/types.hpp"

namespace safestate::core {

struct Config {
  std::uint32_t cycle_us = 1000;         // 250..4000 (SPEC §1)
  std::uint32_t discrepancy_ms = 50;     // dual-channel and selector tolerance (SPEC §2)
  std::uint32_t jog_timeout_ms = 100;    // rule 7
  std::uint32_t max_stop_ms = 1000;      // SS1-t stop time monitoring (SPEC §3)
  std::uint32_t boot_timeout_ms = 3000;  // BOOT row of §4
  float standstill_rad_s = 0.01F;        // |velocity| below this on every axis ...
  std::uint32_t standstill_cycles = 10;  // ... for this many consecutive cycles
  std::uint32_t max_commands_per_cycle = 8;
  float t1_speed_limit_mm_s = 250.0F;    // ISO 10218-1 5.7.3, rule 3
  std::uint32_t contactor_timeout_ms = 100;  // ARMING step CONTACTOR
  std::uint32_t drives_timeout_ms = 500;     // ARMING step DRIVES
  std::uint32_t brakes_timeout_ms = 300;     // ARMING step BRAKES, and brake engage at Cat 1 end
  std::uint32_t reset_hold_max_ms = 5000;    // reset button held longer is not a reset
  std::uint32_t fault_reset_reply_cycles = 50;  // SPEC §5: drives answer a fault reset within
  std::uint32_t queue_size = 64;                // SPEC §9: commands waiting for a cycle
  // SPEC §14 two channels.
  std::uint32_t cross_check_cycles = 2;      // a digest difference or absence tolerated this long
  float encoder_tolerance_deg = 0.5F;        // motor vs load-side encoder, per axis
  std::uint32_t encoder_discrepancy_ms = 10;  // ... for longer than this
  std::uint32_t integrity_period_ms = 1000;  // the whole image's CRC within this
};

// The same constants in cycles. A timer "fires" when its count of elapsed cycles is
// strictly greater than the limit, so "more than 50 ms" at 1 ms is the 51st cycle.
struct Timing {
  Cycle discrepancy = 50;
  Cycle jog_timeout = 100;
  Cycle max_stop = 1000;
  Cycle boot_timeout = 3000;
  Cycle standstill_cycles = 10;
  float standstill_rad_s = 0.01F;
  std::uint32_t max_commands_per_cycle = 8;
  float t1_speed_limit_mm_s = 250.0F;
  // Cycles per second (10^6 / cycle_us): a distance covered over N cycles is
  // distance x cycles_per_s / N per second (the T1 speed, from positions).
  float cycles_per_s = 1000.0F;
  Cycle contactor_timeout = 100;
  Cycle drives_timeout = 500;
  Cycle brakes_timeout = 300;
  Cycle reset_hold_max = 5000;
  Cycle fault_reset_reply = 50;
  // A brake counts as engaged once its feedback has said so this long without a break
  // (kBrakeConfirmMs): a chattering contact is never an engaged brake (SPEC §7).
  Cycle brake_confirm = 10;
  // SPEC §14.
  Cycle cross_check = 2;
  float encoder_tolerance_rad = 0.0087266F;
  Cycle encoder_discrepancy = 10;
  Cycle integrity_period = 1000;
};

// Feedback monitoring (SPEC §7): how long a brake's feedback must say engaged without a
// break before the brake counts as engaged; shorter than any brake timeout worth setting.
inline constexpr std::uint32_t kBrakeConfirmMs = 10;

// What is wrong with a Config: the field's name and a sentence; field == nullptr when
// the config is valid.
struct ConfigError {
  const char* field = nullptr;
  const char* reason = nullptr;
  [[nodiscard]] bool ok() const noexcept { return field == nullptr; }
};

[[nodiscard]] ConfigError validate(const Config& c) noexcept;

// Only meaningful for a Config that validate() accepted.
[[nodiscard]] Timing to_timing(const Config& c) noexcept;

// The largest command queue a cell may be configured with (fixed storage, no heap).
inline constexpr std::uint32_t kMaxQueueSize = 256;

// Whole cycles in `ms` at `cycle_us`, rounded down: a limit of N cycles fires after
// strictly more than `ms` have elapsed.
[[nodiscard]] constexpr Cycle ms_to_cycles(std::uint32_t ms, std::uint32_t cycle_us) noexcept {
  return (static_cast<Cycle>(ms) * 1000U) / static_cast<Cycle>(cycle_us);
}

}  // namespace safestate::core

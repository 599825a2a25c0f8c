// The safe limits of SPEC §10 as the core holds them: fixed-size, in the core's own
// units (radians, mm, cycles are derived later), filled once at start-up from the
// validated safety configuration (safety/ parses the JSON file and converts it here).
// Nothing in this struct is read from a file or the network inside the cycle.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/core/brake_test.hpp"
#include "safestate/core/collaborative.hpp"
#include "safestate/core/dynamics.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

inline constexpr std::size_t kMaxZones = 16;      // SPEC §10: at most 16 zones
inline constexpr std::size_t kZoneNameSize = 32;  // bytes including the terminating NUL

// SPEC §10 zone kinds, spelled as in the file.
enum class ZoneKind : std::uint8_t { keep_in, keep_out, reduced };

// An axis-aligned box in the robot's base frame (mm).
struct Zone {
  std::array<char, kZoneNameSize> name{};  // NUL-terminated, unique within a configuration
  ZoneKind kind = ZoneKind::keep_out;
  std::array<float, 3> min_mm{};
  std::array<float, 3> max_mm{};
};

struct JointLimit {
  float min_rad = 0.0F;
  float max_rad = 0.0F;
  float max_speed_rad_s = 0.0F;
};

// SPEC §11 in the core's units; `enabled` false (the default, and a file without the key):
// none of it acts.
struct CollaborativeLimits {
  bool enabled = false;
  std::uint32_t resume_delay_ms = 1000;
  bool auto_resume = true;
  float reduced_speed_mm_s = 0.0F;  // collaborative.reduced_speed_mm_s (outer field)
  bool ssm_enabled = false;
  SsmParams ssm{};
  bool pfl_enabled = false;
  BodyRegion body_region = BodyRegion::hand;
  float pfl_speed_mm_s = 0.0F;  // v_pfl for the region, robot mass and payload (start-up)
  float f_qs_n = 0.0F;          // the region's quasi-static force limit: collision threshold
};

struct SafetyLimits {
  // First 32 bits of the SHA-256 of the file's RFC 8785 form: the 8 hex digits the
  // operator confirms (SPEC §10 "Checksum").
  std::uint32_t checksum = 0;
  // The tool: TCP in the flange frame (tool0), the sphere around it, the payload.
  std::array<float, 3> tcp_mm{};
  float tool_radius_mm = 0.0F;
  float payload_kg = 0.0F;
  std::array<JointLimit, kAxes> joints{};
  float tcp_max_speed_mm_s = 2000.0F;
  float reduced_tcp_max_speed_mm_s = 250.0F;
  std::uint32_t reduced_ramp_ms = 500;
  // Tool orientation: the tool's z axis within max_deviation of `axis` (unit, base frame).
  bool orientation_enabled = false;
  std::array<float, 3> orientation_axis{0.0F, 0.0F, -1.0F};
  float orientation_max_deviation_rad = 0.0F;
  std::uint8_t zone_count = 0;
  std::array<Zone, kMaxZones> zones{};
  std::uint32_t max_stop_ms = 1000;  // stop.max_time_ms: SPEC §3 max_stop_ms
  CollaborativeLimits collaborative{};
  // The arm's links' inertials and the drives' rated torques (SPEC §11 collision detection),
  // from the robot's description (safety/ fills them; the built-in IRB 120's by default).
  ArmInertials inertials = kIrb120Inertials;
  BrakeTestLimits brake_test{};  // SPEC §12 (defaults when the file has no `brake_test` key)
};

}  // namespace safestate::core

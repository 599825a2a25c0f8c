// The safety configuration of SPEC §10-§12 outside the core: the JSON file, its strict
// parse and consistency checks, its RFC 8785 checksum, and its conversion into the core's
// fixed-size core::SafetyLimits. Nothing here runs in the scan cycle; the result is handed
// to the core once, at start-up. docs/safety-configuration.md describes the file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "safestate/core/collaborative.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/robot/description.hpp"

namespace safestate::safety {

inline constexpr std::string_view kFormat = "safestate-safety/1";
// A file larger than this is refused before it is parsed (SPEC §10; a configuration
// of 6 joints and 16 zones is a few kB).
inline constexpr std::size_t kMaxFileBytes = 1024U * 1024U;
// Deeper nesting than this is refused while parsing (the file's own depth is 4).
inline constexpr std::size_t kMaxDepth = 16;

// One problem with the file: the key path (`joints[2].max_deg`, `zones[1].name`, `` for the
// whole document) and what is wrong with it.
struct Error {
  std::string path;
  std::string message;
  [[nodiscard]] std::string text() const { return path.empty() ? message : path + ": " + message; }
};

// SPEC §11 ISO/TS 15066 Annex A body regions: the core's one table (collaborative.hpp).
// A configuration may name only those that allow transient contact (not skull, not face).
using core::BodyRegion;
const char* to_string(BodyRegion r) noexcept;

struct Ssm {
  bool enabled = false;
  double human_speed_mm_s = 1600.0;  // v_h, default ISO 13855
  double decel_mm_s2 = 0.0;          // a
  double reaction_ms = 0.0;          // T_r
  double intrusion_mm = 0.0;         // C
  double uncertainty_mm = 0.0;       // Z
};

struct Pfl {
  bool enabled = false;
  BodyRegion body_region = BodyRegion::hand;
  double robot_mass_kg = 0.0;
};

// SPEC §11, as written in the file (the core's fixed-size form comes with the monitors).
struct Collaborative {
  bool enabled = false;
  std::uint32_t resume_delay_ms = 1000;
  bool auto_resume = true;
  double reduced_speed_mm_s = 0.0;
  std::optional<Ssm> ssm;
  std::optional<Pfl> pfl;
};

// SPEC §12 with its defaults (used also when the file has no `brake_test` key).
struct BrakeTest {
  double interval_h = 8.0;
  double grace_h = 1.0;
  double test_torque_pct = 130.0;
  std::uint32_t hold_ms = 500;
  double max_drift_deg = 0.5;
};

// SPEC §14 with its defaults (used also when the file has no `channels` key): the two
// channels' cross-check window and the comparison of each axis' two encoders.
struct Channels {
  std::uint32_t cross_check_cycles = 2;
  double encoder_tolerance_deg = 0.5;
  std::uint32_t encoder_discrepancy_ms = 10;
};

// The robot a configuration was checked against (issue 38): the one its `robot` key names
// (its `urdf`, relative to the configuration's folder, with `base` and `flange`), else the
// program's active robot (`--robot`, else the built-in IRB 120).
struct RobotPart {
  std::shared_ptr<const robot::Robot> robot;
  bool from_key = false;       // the configuration has a `robot` key
  std::string parameters;      // robot::canonical_parameters(): what the models use
  std::string checksum;        // first 8 hex digits of SHA-256(RFC 8785 form of `parameters`)
  bool in_checksum = false;    // not the built-in IRB 120's parameters: part of the checksum
  // The arm's rated payload (kg): robot.rated_payload_kg, else the built-in IRB 120's 3 kg;
  // 0 for another arm without the key (its URDF gives none, so it carries no payload).
  double rated_payload_kg = 0.0;
};

struct Loaded {
  std::string name;
  RobotPart robot;
  // RFC 8785 form of the file, UTF-8; for a robot other than the built-in IRB 120, of the file
  // with the robot's parameters as robot.parameters (a changed URDF is a changed configuration).
  std::string canonical;
  std::string checksum;   // first 8 hex digits of SHA-256(canonical), upper case
  core::SafetyLimits limits{};  // limits.checksum holds the same 32 bits
  std::optional<Collaborative> collaborative;  // absent when the file has no such key
  bool brake_test_configured = false;          // false: the file has no `brake_test` key
  BrakeTest brake_test{};                      // the file's values, or the SPEC §12 defaults
  bool channels_configured = false;            // false: the file has no `channels` key
  Channels channels{};                         // the file's values, or the SPEC §14 defaults
};

struct Result {
  std::optional<Loaded> config;  // set exactly when errors is empty
  std::vector<Error> errors;     // every problem found, in file order
  [[nodiscard]] bool ok() const { return config.has_value() && errors.empty(); }
};

// Parses and checks a safety configuration given as text. `errors` lists every problem
// (unknown, missing, mistyped or out-of-range keys and the consistency checks of §10);
// when it is empty the configuration is complete and `config` is set. Never throws.
// A `robot` key's relative `urdf` is taken relative to `dir` (load_safety_file: the file's
// folder; parse_safety(text): the working directory).
Result parse_safety(std::string_view text);
Result parse_safety(std::string_view text, const std::string& dir);

// The `robot` key of a configuration file, to select the robot before anything is built
// (`safestate run --safety FILE`): false when the file cannot be read, is not JSON or has
// no such key (then parse_safety reports what is wrong).
struct RobotKey {
  std::string urdf;  // resolved against the file's folder
  std::string base;
  std::string flange;
};
bool robot_key_of_file(const std::string& path, RobotKey& out);

// Reads FILE (refused above kMaxFileBytes, before parsing) and parses it. This is the
// function `safestate run --safety FILE` and the scenario runner call. Never throws.
Result load_safety_file(const std::string& path);

// The built-in configuration of SPEC §10 (the robot's own ranges and speeds, TCP 2000 mm/s,
// reduced 250 mm/s with a 500 ms ramp, no zones, no orientation limit, stop 1000 ms) as the
// JSON text it is made from, and parsed by the same parser.
std::string_view default_safety_text() noexcept;
Loaded default_safety();

// A human-readable summary of a loaded configuration (`safestate safety check`).
std::string summary(const Loaded& config);

// The RFC 8785 form of any JSON text (no schema: duplicate keys, nesting deeper than
// kMaxDepth and syntax errors are refused into `errors`).
std::optional<std::string> canonical_json(std::string_view text, std::vector<Error>& errors);

// The checksum of RFC 8785 text: the first 32 bits of its SHA-256 (OpenSSL libcrypto),
// as 8 upper-case hex digits and as a number.
std::string sha256_hex(std::string_view bytes);
std::string checksum_text(std::string_view canonical);
std::uint32_t checksum_value(std::string_view canonical);

// Every key path the parser accepts, with `[]` for an array index (e.g. `joints[].min_deg`):
// the unknown-key check uses the same lists, and a test checks the docs name each one.
std::vector<std::string> known_keys();

}  // namespace safestate::safety

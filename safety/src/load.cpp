// Reading the file, the built-in default, and the summary `safestate safety check` prints.
#include <cerrno>
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>

#include <nlohmann/json.hpp>

#include "safestate/safety/jcs.hpp"
#include "safestate/safety/safety_config.hpp"

namespace safestate::safety {

namespace {

// SPEC §10 last paragraph: the robot's own ranges and speeds (docs/robot.md; a unit test
// compares them with motion/robot.hpp), TCP 2000 mm/s, reduced 250 mm/s with a 500 ms ramp,
// no zones, no orientation limit, stop 1000 ms; tool0 with no tool mounted.
constexpr std::string_view kDefault = R"json({
  "format": "safestate-safety/1",
  "name": "built-in default (robot's own ranges, no zones)",
  "tool": { "tcp_mm": [0, 0, 0], "radius_mm": 0, "payload_kg": 0 },
  "joints": [
    { "min_deg": -165, "max_deg": 165, "max_speed_deg_s": 250 },
    { "min_deg": -110, "max_deg": 110, "max_speed_deg_s": 250 },
    { "min_deg": -110, "max_deg": 70, "max_speed_deg_s": 250 },
    { "min_deg": -160, "max_deg": 160, "max_speed_deg_s": 320 },
    { "min_deg": -120, "max_deg": 120, "max_speed_deg_s": 320 },
    { "min_deg": -400, "max_deg": 400, "max_speed_deg_s": 420 }
  ],
  "tcp_max_speed_mm_s": 2000,
  "reduced": { "tcp_max_speed_mm_s": 250, "ramp_ms": 500 },
  "stop": { "max_time_ms": 1000 }
}
)json";

// The same for any other arm (issue 38): no `joints` key, so the joint table is the robot's
// own, from its URDF.
constexpr std::string_view kDefaultOtherRobot = R"json({
  "format": "safestate-safety/1",
  "name": "built-in default (robot's own ranges, no zones)",
  "tool": { "tcp_mm": [0, 0, 0], "radius_mm": 0, "payload_kg": 0 },
  "tcp_max_speed_mm_s": 2000,
  "reduced": { "tcp_max_speed_mm_s": 250, "ramp_ms": 500 },
  "stop": { "max_time_ms": 1000 }
}
)json";

constexpr double kPi = 3.14159265358979323846;

std::string n(double x) { return jcs::number_to_string(x).value_or("?"); }
// Degrees back from the core's float radians, to 1/1000 degree.
std::string deg(float rad) { return n(std::round(static_cast<double>(rad) * 180.0 / kPi * 1000.0) / 1000.0); }
std::string f(float x) { return n(std::round(static_cast<double>(x) * 1000.0) / 1000.0); }

const char* kind_name(core::ZoneKind k) {
  switch (k) {
    case core::ZoneKind::keep_in: return "keep_in";
    case core::ZoneKind::keep_out: return "keep_out";
    case core::ZoneKind::reduced: return "reduced";
  }
  return "?";
}

}  // namespace

std::string_view default_safety_text() noexcept {
  return robot::is_builtin(robot::active()) ? kDefault : kDefaultOtherRobot;
}

Loaded default_safety() {
  Result r = parse_safety(default_safety_text());
  // The text is a constant of this file and a unit test parses it; an error here is a
  // programming error, reported loudly rather than hidden behind partial limits.
  if (!r.ok()) {
    for (const Error& e : r.errors) std::fprintf(stderr, "built-in safety configuration: %s\n", e.text().c_str());
    std::abort();
  }
  return std::move(*r.config);
}

Result load_safety_file(const std::string& path) {
  Result r;
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(st)) {
    r.errors.push_back({"", "cannot read " + path + ": no such file"});
    return r;
  }
  if (!std::filesystem::is_regular_file(st)) {
    r.errors.push_back({"", "cannot read " + path + ": not a regular file"});
    return r;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    r.errors.push_back({"", "cannot read " + path + ": " + std::strerror(errno)});
    return r;
  }
  // Read at most one byte more than allowed: a larger file is refused before parsing.
  std::string text(kMaxFileBytes + 1U, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  if (text.size() > kMaxFileBytes) {
    r.errors.push_back({"", "file is larger than " + std::to_string(kMaxFileBytes) + " bytes (1 MiB): refused"});
    return r;
  }
  if (in.bad()) {
    r.errors.push_back({"", "cannot read " + path});
    return r;
  }
  return parse_safety(text, std::filesystem::path(path).parent_path().string());
}

bool robot_key_of_file(const std::string& path, RobotKey& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return false;
  }
  std::string text(kMaxFileBytes + 1U, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  const nlohmann::json doc = nlohmann::json::parse(text, nullptr, false);
  if (doc.is_discarded() || !doc.is_object() || !doc.contains("robot") || !doc.at("robot").is_object()) {
    return false;
  }
  const nlohmann::json& r = doc.at("robot");
  const auto str = [&](const char* k) {
    return (r.contains(k) && r.at(k).is_string()) ? r.at(k).get<std::string>() : std::string();
  };
  out.urdf = str("urdf");
  if (out.urdf.empty()) {
    return false;
  }
  const std::filesystem::path p(out.urdf);
  if (!p.is_absolute()) {
    out.urdf = (std::filesystem::path(path).parent_path() / p).string();
  }
  out.base = str("base");
  out.flange = str("flange");
  return true;
}

std::string summary(const Loaded& c) {
  const core::SafetyLimits& l = c.limits;
  std::ostringstream o;
  o << "name:      " << c.name << "\n";
  o << "checksum:  " << c.checksum << "\n";
  if (c.robot.robot) {
    const robot::Robot& rb = *c.robot.robot;
    o << "robot:     " << rb.d.name << " (" << rb.d.source << ", " << rb.d.base << " -> " << rb.d.flange
      << "), parameters " << c.robot.checksum
      << (c.robot.in_checksum ? " (in the checksum)" : " (the built-in IRB 120's)") << "\n";
    o << "           joint                 range deg            max deg/s\n";
    for (std::size_t i = 0; i < robot::kJoints; ++i) {
      char line[160];
      std::snprintf(line, sizeof line, "           %-20.20s  %-9s .. %-9s  %s\n", rb.d.joints[i].name.c_str(),
                    deg(rb.model.q_min_rad[i]).c_str(), deg(rb.model.q_max_rad[i]).c_str(),
                    deg(rb.model.qd_max_rad_s[i]).c_str());
      o << line;
    }
  }
  o << "tool:      tcp [" << f(l.tcp_mm[0]) << ", " << f(l.tcp_mm[1]) << ", " << f(l.tcp_mm[2]) << "] mm, radius "
    << f(l.tool_radius_mm) << " mm, payload " << f(l.payload_kg) << " kg\n";
  o << "joints:    axis  min deg   max deg   max deg/s\n";
  for (std::size_t i = 0; i < l.joints.size(); ++i) {
    char line[96];
    std::snprintf(line, sizeof line, "           %-4zu  %-8s  %-8s  %s\n", i + 1, deg(l.joints[i].min_rad).c_str(),
                  deg(l.joints[i].max_rad).c_str(), deg(l.joints[i].max_speed_rad_s).c_str());
    o << line;
  }
  o << "tcp speed: " << f(l.tcp_max_speed_mm_s) << " mm/s\n";
  o << "reduced:   " << f(l.reduced_tcp_max_speed_mm_s) << " mm/s within " << l.reduced_ramp_ms << " ms\n";
  if (l.orientation_enabled) {
    o << "tool axis: within " << deg(l.orientation_max_deviation_rad) << " deg of [" << f(l.orientation_axis[0])
      << ", " << f(l.orientation_axis[1]) << ", " << f(l.orientation_axis[2]) << "]\n";
  } else {
    o << "tool axis: not limited\n";
  }
  o << "zones:     " << static_cast<unsigned>(l.zone_count) << (l.zone_count == 0U ? " (none)\n" : "\n");
  for (std::size_t i = 0; i < l.zone_count; ++i) {
    const core::Zone& z = l.zones[i];
    o << "           " << z.name.data() << " " << kind_name(z.kind) << " [" << f(z.min_mm[0]) << ", " << f(z.min_mm[1])
      << ", " << f(z.min_mm[2]) << "] .. [" << f(z.max_mm[0]) << ", " << f(z.max_mm[1]) << ", " << f(z.max_mm[2])
      << "] mm\n";
  }
  o << "stop:      within " << l.max_stop_ms << " ms\n";
  if (c.collaborative) {
    const Collaborative& co = *c.collaborative;
    o << "collaborative: " << (co.enabled ? "enabled" : "disabled") << ", reduced " << n(co.reduced_speed_mm_s)
      << " mm/s, resume after " << co.resume_delay_ms << " ms" << (co.auto_resume ? " (automatic)" : " (by command)")
      << "\n";
    if (co.ssm) {
      o << "  ssm:     " << (co.ssm->enabled ? "enabled" : "disabled") << ", v_h " << n(co.ssm->human_speed_mm_s)
        << " mm/s, a " << n(co.ssm->decel_mm_s2) << " mm/s2, T_r " << n(co.ssm->reaction_ms) << " ms, C "
        << n(co.ssm->intrusion_mm) << " mm, Z " << n(co.ssm->uncertainty_mm) << " mm\n";
    }
    if (co.pfl) {
      o << "  pfl:     " << (co.pfl->enabled ? "enabled" : "disabled") << ", body region "
        << to_string(co.pfl->body_region) << ", robot mass " << n(co.pfl->robot_mass_kg) << " kg\n";
    }
  } else {
    o << "collaborative: none\n";
  }
  const BrakeTest& b = c.brake_test;
  o << "brake test: " << (c.brake_test_configured ? "" : "(defaults) ") << "every " << n(b.interval_h) << " h + "
    << n(b.grace_h) << " h grace, " << n(b.test_torque_pct) << " % torque for " << b.hold_ms << " ms, drift <= "
    << n(b.max_drift_deg) << " deg\n";
  const Channels& ch = c.channels;
  o << "channels: " << (c.channels_configured ? "" : "(defaults) ") << "cross-check " << ch.cross_check_cycles
    << " cycles, encoders within " << n(ch.encoder_tolerance_deg) << " deg for at most " << ch.encoder_discrepancy_ms
    << " ms\n";
  return o.str();
}

}  // namespace safestate::safety

// The safety configuration file (SPEC §10-§12): the strict parser, the consistency checks,
// the conversion into core::SafetyLimits, the built-in default and the shipped examples.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "safestate/motion/kinematics.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/safety/safety_config.hpp"

using namespace safestate;
using namespace safestate::safety;
using nlohmann::json;

namespace {

const std::string kSource = SAFESTATE_SOURCE_DIR;

std::string read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

json default_json() { return json::parse(default_safety_text()); }

std::vector<std::string> texts(const Result& r) {
  std::vector<std::string> out;
  for (const Error& e : r.errors) out.push_back(e.text());
  return out;
}

// The errors of a document, as "path: message" lines (empty when valid).
std::vector<std::string> errors_of(const json& doc) { return texts(parse_safety(doc.dump())); }

// Exactly one error, at `path`, whose message contains `words`.
void expect_one_error(const json& doc, const std::string& path, const std::string& words) {
  const Result r = parse_safety(doc.dump());
  ASSERT_EQ(r.errors.size(), 1U) << ::testing::PrintToString(texts(r));
  EXPECT_EQ(r.errors[0].path, path) << r.errors[0].text();
  EXPECT_NE(r.errors[0].message.find(words), std::string::npos) << r.errors[0].text();
  EXPECT_FALSE(r.config.has_value());
}

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

}  // namespace

TEST(SafetyDefault, IsTheRobotsOwnRangesAndSpecValues) {
  const Result r = parse_safety(default_safety_text());
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(texts(r));
  const core::SafetyLimits& l = r.config->limits;
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    EXPECT_NEAR(l.joints[i].min_rad, motion::kRobot.q_min_rad[i], 1e-5) << "axis " << i + 1;
    EXPECT_NEAR(l.joints[i].max_rad, motion::kRobot.q_max_rad[i], 1e-5) << "axis " << i + 1;
    EXPECT_NEAR(l.joints[i].max_speed_rad_s, motion::kRobot.qd_max_rad_s[i], 1e-5) << "axis " << i + 1;
    // never a float step beyond the robot's own range
    EXPECT_GE(l.joints[i].min_rad, motion::kRobot.q_min_rad[i]);
    EXPECT_LE(l.joints[i].max_rad, motion::kRobot.q_max_rad[i]);
    EXPECT_LE(l.joints[i].max_speed_rad_s, motion::kRobot.qd_max_rad_s[i]);
  }
  EXPECT_EQ(l.tcp_max_speed_mm_s, 2000.0F);
  EXPECT_EQ(l.reduced_tcp_max_speed_mm_s, 250.0F);
  EXPECT_EQ(l.reduced_ramp_ms, 500U);
  EXPECT_EQ(l.zone_count, 0U);
  EXPECT_FALSE(l.orientation_enabled);
  EXPECT_EQ(l.max_stop_ms, 1000U);
  EXPECT_FALSE(r.config->collaborative.has_value());
  EXPECT_FALSE(r.config->brake_test_configured);
  EXPECT_EQ(r.config->brake_test.interval_h, 8.0);  // SPEC §12 defaults
  EXPECT_EQ(r.config->brake_test.grace_h, 1.0);
  EXPECT_EQ(r.config->brake_test.test_torque_pct, 130.0);
  EXPECT_EQ(r.config->brake_test.hold_ms, 500U);
  EXPECT_EQ(r.config->brake_test.max_drift_deg, 0.5);
  ASSERT_EQ(r.config->checksum.size(), 8U);
  EXPECT_EQ(r.config->checksum, checksum_text(r.config->canonical));
  char hex[9];
  std::snprintf(hex, sizeof hex, "%08X", l.checksum);
  EXPECT_EQ(r.config->checksum, hex);
  EXPECT_EQ(default_safety().checksum, r.config->checksum);
}

TEST(SafetyExamples, CellAndCollaborativeLoad) {
  const Result cell = load_safety_file(kSource + "/examples/safety/cell.json");
  ASSERT_TRUE(cell.ok()) << ::testing::PrintToString(texts(cell));
  const core::SafetyLimits& l = cell.config->limits;
  EXPECT_EQ(l.zone_count, 3U);
  EXPECT_TRUE(l.orientation_enabled);
  const Result co = load_safety_file(kSource + "/examples/safety/collaborative.json");
  ASSERT_TRUE(co.ok()) << ::testing::PrintToString(texts(co));
  ASSERT_TRUE(co.config->collaborative.has_value());
  const Collaborative& c = *co.config->collaborative;
  EXPECT_TRUE(c.enabled);
  ASSERT_TRUE(c.ssm && c.pfl);
  EXPECT_EQ(c.ssm->decel_mm_s2, 2000.0);
  EXPECT_EQ(c.pfl->body_region, BodyRegion::hand);
  EXPECT_TRUE(co.config->brake_test_configured);
  EXPECT_NE(co.config->checksum, cell.config->checksum);
  // ... and in the core's units (SPEC §11 worked examples: hand, 25 kg, 1.5 kg payload).
  const core::CollaborativeLimits& k = co.config->limits.collaborative;
  EXPECT_TRUE(k.enabled && k.ssm_enabled && k.pfl_enabled && k.auto_resume);
  EXPECT_EQ(k.resume_delay_ms, 1000U);
  EXPECT_FLOAT_EQ(k.reduced_speed_mm_s, 250.0F);
  EXPECT_FLOAT_EQ(k.ssm.reaction_s, 0.1F);
  EXPECT_FLOAT_EQ(k.ssm.intrusion_mm + k.ssm.uncertainty_mm, 300.0F);
  EXPECT_NEAR(k.pfl_speed_mm_s, 1347.93F, 0.5F);
  EXPECT_FLOAT_EQ(k.f_qs_n, 140.0F);
  EXPECT_NEAR(core::ssm_allowed_speed_mm_s(800.0F, k.ssm, 1500.0F), 344.761F, 0.01F);
  EXPECT_FALSE(cell.config->limits.collaborative.enabled) << "no collaborative key: none of §11 acts";
}

// The shipped cell makes sense for the IRB 120: at the home pose q = 0 the tool sphere and
// the link-frame origins 2..6 lie inside every keep_in box and touch no keep_out box, the
// TCP is outside the reduced zone, and the tool's z axis is inside the orientation cone.
TEST(SafetyExamples, CellHomePoseIsInsideTheLimits) {
  const Result r = load_safety_file(kSource + "/examples/safety/cell.json");
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(texts(r));
  const core::SafetyLimits& l = r.config->limits;
  motion::RobotModel robot = motion::kRobot;
  robot.tcp_offset_mm = l.tcp_mm;
  motion::Frames frames{};
  motion::forward(robot, motion::Joints{}, frames);
  const float rad = l.tool_radius_mm;
  ASSERT_GT(rad, 0.0F);
  // spheres: the TCP with the tool radius, the link origins 2..6 as points
  std::vector<std::pair<motion::Vec3, float>> bodies = {{frames.tcp, rad}};
  for (std::size_t k = 2; k <= 6; ++k) bodies.emplace_back(frames.origin[k], 0.0F);
  int keep_in = 0;
  int keep_out = 0;
  for (std::size_t z = 0; z < l.zone_count; ++z) {
    const core::Zone& zone = l.zones[z];
    for (const auto& [p, radius] : bodies) {
      bool inside_whole = true;
      bool touches = true;
      for (std::size_t a = 0; a < 3; ++a) {
        inside_whole = inside_whole && p[a] - radius >= zone.min_mm[a] && p[a] + radius <= zone.max_mm[a];
        touches = touches && p[a] + radius >= zone.min_mm[a] && p[a] - radius <= zone.max_mm[a];
      }
      if (zone.kind == core::ZoneKind::keep_in) {
        EXPECT_TRUE(inside_whole) << zone.name.data();
      }
      if (zone.kind == core::ZoneKind::keep_out) {
        EXPECT_FALSE(touches) << zone.name.data();
      }
    }
    if (zone.kind == core::ZoneKind::reduced) {
      bool tcp_in = true;
      for (std::size_t a = 0; a < 3; ++a) {
        tcp_in = tcp_in && frames.tcp[a] >= zone.min_mm[a] && frames.tcp[a] <= zone.max_mm[a];
      }
      EXPECT_FALSE(tcp_in) << "home is in reduced zone " << zone.name.data();
    }
    keep_in += zone.kind == core::ZoneKind::keep_in ? 1 : 0;
    keep_out += zone.kind == core::ZoneKind::keep_out ? 1 : 0;
  }
  EXPECT_GE(keep_in, 1);
  EXPECT_GE(keep_out, 1);
  // the tool's z axis (third column of R) against the cone
  const float cosang = frames.R[0][2] * l.orientation_axis[0] + frames.R[1][2] * l.orientation_axis[1] +
                       frames.R[2][2] * l.orientation_axis[2];
  EXPECT_GT(cosang, std::cos(l.orientation_max_deviation_rad));
  // and the TCP is where docs/robot.md says tool0 is, plus the tool along +x
  EXPECT_NEAR(frames.tcp[0], 374.0F + l.tcp_mm[2], 0.01F);
  EXPECT_NEAR(frames.tcp[2], 630.0F, 0.01F);
}

TEST(SafetyParse, ConvertsUnits) {
  json d = default_json();
  d["joints"][0] = {{"min_deg", -90}, {"max_deg", 45.5}, {"max_speed_deg_s", 180}};
  d["orientation"] = {{"axis", {0, 0, -2}}, {"max_deviation_deg", 30}};
  d["zones"] = json::array({{{"name", "table"}, {"kind", "keep_out"}, {"min_mm", {300, -200, 0}}, {"max_mm", {600, 200, 150}}},
                            {{"name", "load.1"}, {"kind", "reduced"}, {"min_mm", {-1, -2, -3}}, {"max_mm", {1, 2, 3}}}});
  d["stop"]["max_time_ms"] = 750;
  d["tool"] = {{"tcp_mm", {1, 2, 120}}, {"radius_mm", 40}, {"payload_kg", 1.5}};
  const Result r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(texts(r));
  const core::SafetyLimits& l = r.config->limits;
  EXPECT_NEAR(l.joints[0].min_rad, -1.5707963F, 1e-6);
  EXPECT_NEAR(l.joints[0].max_rad, 0.7941248F, 1e-6);
  EXPECT_NEAR(l.joints[0].max_speed_rad_s, 3.1415927F, 1e-6);
  EXPECT_TRUE(l.orientation_enabled);
  EXPECT_EQ(l.orientation_axis, (std::array<float, 3>{0.0F, 0.0F, -1.0F}));  // normalised
  EXPECT_NEAR(l.orientation_max_deviation_rad, 0.5235988F, 1e-6);
  ASSERT_EQ(l.zone_count, 2U);
  EXPECT_STREQ(l.zones[0].name.data(), "table");
  EXPECT_EQ(l.zones[0].kind, core::ZoneKind::keep_out);
  EXPECT_EQ(l.zones[0].min_mm, (std::array<float, 3>{300.0F, -200.0F, 0.0F}));
  EXPECT_EQ(l.zones[0].max_mm, (std::array<float, 3>{600.0F, 200.0F, 150.0F}));
  EXPECT_STREQ(l.zones[1].name.data(), "load.1");
  EXPECT_EQ(l.zones[1].kind, core::ZoneKind::reduced);
  EXPECT_EQ(l.max_stop_ms, 750U);
  EXPECT_EQ(l.tcp_mm, (std::array<float, 3>{1.0F, 2.0F, 120.0F}));
  EXPECT_EQ(l.tool_radius_mm, 40.0F);
  EXPECT_EQ(l.payload_kg, 1.5F);
}

TEST(SafetyParse, CollectsEveryErrorNamingItsKey) {
  const std::string text = R"({
  "format": "safestate-safety/2",
  "name": "x",
  "name": "y",
  "tool": { "tcp_mm": [0, 0], "radius_mm": -1, "payload_kg": 1, "colour": "red" },
  "joints": [
    { "min_deg": -165, "max_deg": 165, "max_speed_deg_s": 250 },
    { "min_deg": -110, "max_deg": 110, "max_speed_deg_s": 250 },
    { "min_deg": -110, "max_deg": true, "max_speed_deg_s": 250 },
    { "min_deg": 10, "max_deg": 10, "max_speed_deg_s": 321 },
    { "min_deg": -121, "max_deg": 120, "max_speed_deg_s": 320 },
    { "min_deg": -400, "max_deg": 400 }
  ],
  "tcp_max_speed_mm_s": 1000,
  "reduced": { "tcp_max_speed_mm_s": 1500, "ramp_ms": 12.5 },
  "orientation": { "axis": [0, 0, 0], "max_deviation_deg": 60 },
  "zones": [ { "name": "table", "kind": "keep_away", "min_mm": [0, 0, 0], "max_mm": [1, 1, 0] },
             { "name": "table", "kind": "keep_in", "min_mm": [0, 0, 0], "max_mm": [1, 1, 1] } ]
})";
  const std::vector<std::string> e = texts(parse_safety(text));
  const std::vector<std::string> expected = {
      "name: duplicate key (a key may appear once in an object)",
      "format: must be \"safestate-safety/1\" (found \"safestate-safety/2\")",
      "tool.colour: unknown key (expected one of: tcp_mm, radius_mm, payload_kg)",
      "tool.tcp_mm: must be an array of 3 numbers (found an array of 2)",
      "tool.radius_mm: must be >= 0 and <= 500 (found -1)",
      "joints[2].max_deg: must be a number (found a boolean)",
      "joints[3].max_deg: must be > min_deg (10) (found 10)",
      "joints[3].max_speed_deg_s: must be > 0 and <= 320 (axis 4's own maximum speed) (found 321)",
      "joints[4].min_deg: must be >= -120 and <= 120 (axis 5's own range) (found -121)",
      "joints[5].max_speed_deg_s: missing (required)",
      "reduced.tcp_max_speed_mm_s: must be <= tcp_max_speed_mm_s (1000): reduced may not be faster than normal "
      "(found 1500)",
      "reduced.ramp_ms: must be a whole number (found 12.5)",
      "orientation.axis: must not be zero (it is a direction)",
      "zones[0].kind: must be keep_in, keep_out or reduced (found \"keep_away\")",
      "zones[0].max_mm[2]: must be > min_mm[2] (0) (found 0)",
      "zones[1].name: duplicate zone name \"table\" (also zones[0].name)",
      "stop: missing (required)",
  };
  for (const std::string& x : expected) EXPECT_TRUE(contains(e, x)) << "missing: " << x << "\nin: " << ::testing::PrintToString(e);
  EXPECT_EQ(e.size(), expected.size()) << ::testing::PrintToString(e);
}

TEST(SafetyParse, EachConsistencyCheckNamesItsKey) {
  json d;
  d = default_json();
  d["joints"][1]["min_deg"] = 20;
  d["joints"][1]["max_deg"] = 10;
  expect_one_error(d, "joints[1].max_deg", "must be > min_deg (20)");
  d = default_json();
  d["joints"][0]["max_deg"] = 165.5;
  expect_one_error(d, "joints[0].max_deg", "axis 1's own range");
  d = default_json();
  d["joints"][2]["max_deg"] = 71;  // axis 3 is +70 / -110
  expect_one_error(d, "joints[2].max_deg", "<= 70");
  d = default_json();
  d["joints"][5]["max_speed_deg_s"] = 0;
  expect_one_error(d, "joints[5].max_speed_deg_s", "must be > 0 and <= 420");
  d = default_json();
  d["joints"].erase(5);
  expect_one_error(d, "joints", "array of 6 joints (found an array of 5)");
  d = default_json();
  d["reduced"]["tcp_max_speed_mm_s"] = 2000.5;
  expect_one_error(d, "reduced.tcp_max_speed_mm_s", "<= tcp_max_speed_mm_s (2000)");
  d = default_json();
  d["tcp_max_speed_mm_s"] = 1e300;
  expect_one_error(d, "tcp_max_speed_mm_s", "<= 10000");
  d = default_json();
  d["orientation"] = {{"axis", {0, 0, 0}}, {"max_deviation_deg", 10}};
  expect_one_error(d, "orientation.axis", "must not be zero");
  d = default_json();
  d["orientation"] = {{"axis", {0, 0, 1}}, {"max_deviation_deg", 180}};
  expect_one_error(d, "orientation.max_deviation_deg", "must be < 180");
  d = default_json();
  d["stop"]["max_time_ms"] = 0;
  expect_one_error(d, "stop.max_time_ms", "must be >= 10 and <= 5000");
  d = default_json();
  d["stop"]["max_time_ms"] = 5001;
  expect_one_error(d, "stop.max_time_ms", "must be >= 10 and <= 5000");
  d = default_json();
  d["tool"]["payload_kg"] = 3.5;
  expect_one_error(d, "tool.payload_kg", "rated payload");
  const json zone = {{"name", "z"}, {"kind", "keep_out"}, {"min_mm", {0, 0, 0}}, {"max_mm", {1, 1, 1}}};
  d = default_json();
  d["zones"] = json::array();
  for (int i = 0; i < 17; ++i) {
    json z = zone;
    z["name"] = "z" + std::to_string(i);
    d["zones"].push_back(z);
  }
  expect_one_error(d, "zones", "at most 16 zones (found 17)");
  d["zones"].erase(16);
  EXPECT_TRUE(errors_of(d).empty());  // 16 is allowed
  d = default_json();
  d["zones"] = {zone, zone};
  expect_one_error(d, "zones[1].name", "duplicate zone name");
  json bad = zone;
  bad["name"] = "";
  d["zones"] = json::array({bad});
  expect_one_error(d, "zones[0].name", "must be 1..31 bytes (found 0)");
  bad["name"] = std::string(32, 'a');
  d["zones"] = json::array({bad});
  expect_one_error(d, "zones[0].name", "must be 1..31 bytes (found 32)");
  bad["name"] = std::string(31, 'a');
  d["zones"] = json::array({bad});
  EXPECT_TRUE(errors_of(d).empty());
  bad["name"] = "two words";
  d["zones"] = json::array({bad});
  expect_one_error(d, "zones[0].name", "only letters, digits");
  bad["name"] = "tcp";
  d["zones"] = json::array({bad});
  expect_one_error(d, "zones[0].name", "reserved");
  bad = zone;
  bad["min_mm"] = {0, 5, 0};
  bad["max_mm"] = {1, 4, 1};
  d["zones"] = json::array({bad});
  expect_one_error(d, "zones[0].max_mm[1]", "must be > min_mm[1] (5)");
  bad = zone;
  bad["max_mm"] = {1, 1, 1e9};
  d["zones"] = json::array({bad});
  expect_one_error(d, "zones[0].max_mm[2]", "<= 10000");
}

TEST(SafetyParse, StrictTypesAndKeys) {
  json d = default_json();
  d["extra"] = 1;
  expect_one_error(d, "extra", "unknown key");
  d = default_json();
  d.erase("reduced");
  expect_one_error(d, "reduced", "missing (required)");
  d = default_json();
  d["name"] = 7;
  expect_one_error(d, "name", "must be a string (found a number)");
  d = default_json();
  d["name"] = "cell 7 \xE2\x80\x94 welding";  // an em dash is fine (SPEC's own example)
  EXPECT_TRUE(errors_of(d).empty());
  d["name"] = "bell \x07";
  expect_one_error(d, "name", "without control characters");
  d["name"] = "csi \xC2\x9B";  // U+009B, a C1 control character
  expect_one_error(d, "name", "without control characters");
  d["name"] = "";
  expect_one_error(d, "name", "must be 1..64 bytes");
  d = default_json();
  d["tcp_max_speed_mm_s"] = "1500";
  expect_one_error(d, "tcp_max_speed_mm_s", "must be a number (found a string)");
  d = default_json();
  d["reduced"] = json::array();
  expect_one_error(d, "reduced", "must be an object (found an array)");
  d = default_json();
  d["tool"]["tcp_mm"][1] = nullptr;
  expect_one_error(d, "tool.tcp_mm[1]", "must be a number (found null)");
  EXPECT_EQ(texts(parse_safety("[1, 2]")), std::vector<std::string>{"must be an object (found an array)"});
}

TEST(SafetyParse, BadJsonHugeNumbersNanAndNesting) {
  const auto one = [](const std::string& text) {
    const Result r = parse_safety(text);
    EXPECT_FALSE(r.config.has_value());
    return r.errors.size() == 1U ? r.errors[0].text() : ::testing::PrintToString(texts(r));
  };
  EXPECT_NE(one("").find("not valid JSON at line 1, column 1"), std::string::npos) << one("");
  EXPECT_NE(one("{\n  \"a\": 1,\n  \"b\": }").find("not valid JSON at line 3"), std::string::npos);
  EXPECT_NE(one(R"({"tcp_max_speed_mm_s": NaN})").find("not valid JSON"), std::string::npos);
  EXPECT_NE(one(R"({"tcp_max_speed_mm_s": 1e999})").find("not valid JSON"), std::string::npos);
  EXPECT_NE(one(R"({"tcp_max_speed_mm_s": Infinity})").find("not valid JSON"), std::string::npos);
  EXPECT_NE(one(std::string(50000, '[')).find("nested deeper than 16 levels"), std::string::npos);
  EXPECT_NE(one("{\"name\": \"\xff\"}").find("not valid JSON"), std::string::npos);
  json d = default_json();
  d["tcp_max_speed_mm_s"] = 18446744073709551615ULL;
  expect_one_error(d, "tcp_max_speed_mm_s", "<= 10000");
}

TEST(SafetyParse, CollaborativeAndBrakeTest) {
  json d = default_json();
  d["collaborative"] = {{"enabled", true}};
  Result r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(texts(r));
  EXPECT_EQ(r.config->collaborative->resume_delay_ms, 1000U);  // defaults
  EXPECT_TRUE(r.config->collaborative->auto_resume);
  EXPECT_EQ(r.config->collaborative->reduced_speed_mm_s, 2000.0);
  const json ssm = {{"enabled", true}, {"decel_mm_s2", 2000}, {"reaction_ms", 100}, {"intrusion_mm", 200},
                    {"uncertainty_mm", 100}};
  d["collaborative"]["ssm"] = ssm;
  r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(texts(r));
  EXPECT_EQ(r.config->collaborative->ssm->human_speed_mm_s, 1600.0);
  d["collaborative"]["ssm"]["decel_mm_s2"] = 0;
  expect_one_error(d, "collaborative.ssm.decel_mm_s2", "a <= 0");
  d["collaborative"]["ssm"] = ssm;
  d["collaborative"]["ssm"]["reaction_ms"] = -5;
  expect_one_error(d, "collaborative.ssm.reaction_ms", "T_r <= 0");
  d["collaborative"]["ssm"] = ssm;
  d["collaborative"]["pfl"] = {{"enabled", true}, {"body_region", "skull"}, {"robot_mass_kg", 25}};
  expect_one_error(d, "collaborative.pfl.body_region", "skull allows no transient contact");
  d["collaborative"]["pfl"]["body_region"] = "face";
  expect_one_error(d, "collaborative.pfl.body_region", "face allows no transient contact");
  d["collaborative"]["pfl"]["body_region"] = "elbow";
  expect_one_error(d, "collaborative.pfl.body_region", "unknown body region \"elbow\"");
  d["collaborative"]["pfl"]["body_region"] = "lower_leg";
  r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(texts(r));
  EXPECT_EQ(r.config->collaborative->pfl->body_region, BodyRegion::lower_leg);
  d["collaborative"]["reduced_speed_mm_s"] = 2001;
  expect_one_error(d, "collaborative.reduced_speed_mm_s", "at most tcp_max_speed_mm_s");
  d["collaborative"].erase("reduced_speed_mm_s");
  d["collaborative"]["enabled"] = "yes";
  expect_one_error(d, "collaborative.enabled", "must be true or false");

  d = default_json();
  d["brake_test"] = json::object();
  r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.config->brake_test_configured);
  EXPECT_EQ(r.config->brake_test.interval_h, 8.0);
  d["brake_test"] = {{"interval_h", 0.5}, {"grace_h", 0.25}, {"test_torque_pct", 110}, {"hold_ms", 300},
                     {"max_drift_deg", 0.2}};
  r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.config->brake_test.interval_h, 0.5);
  EXPECT_EQ(r.config->brake_test.hold_ms, 300U);
  d["brake_test"]["interval_h"] = 0;
  expect_one_error(d, "brake_test.interval_h", "must be > 0");
}

// @req CH-CONFIG
// SPEC §14's settings in the safety configuration: the defaults without the key, the file's
// values with it, each range-checked and named, and each under the checksum.
TEST(SafetyConfig, ChannelsKeySetsTheCrossCheckAndTheEncoderComparison) {
  json d = default_json();
  Result r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r.config->channels_configured);
  EXPECT_EQ(r.config->channels.cross_check_cycles, 2U);
  EXPECT_EQ(r.config->channels.encoder_tolerance_deg, 0.5);
  EXPECT_EQ(r.config->channels.encoder_discrepancy_ms, 10U);
  const std::string plain = r.config->checksum;
  d["channels"] = {{"cross_check_cycles", 3}, {"encoder_tolerance_deg", 0.8}, {"encoder_discrepancy_ms", 20}};
  r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.config->channels_configured);
  EXPECT_EQ(r.config->channels.cross_check_cycles, 3U);
  EXPECT_EQ(r.config->channels.encoder_tolerance_deg, 0.8);
  EXPECT_EQ(r.config->channels.encoder_discrepancy_ms, 20U);
  EXPECT_NE(r.config->checksum, plain) << "under the checksum";
  const std::string three = r.config->checksum;
  d["channels"]["encoder_tolerance_deg"] = 0.9;
  r = parse_safety(d.dump());
  ASSERT_TRUE(r.ok());
  EXPECT_NE(r.config->checksum, three) << "every value is";
  EXPECT_NE(summary(*r.config).find("channels: cross-check 3 cycles, encoders within 0.9 deg for at most 20 ms"),
            std::string::npos)
      << summary(*r.config);
  d["channels"]["cross_check_cycles"] = 0;
  expect_one_error(d, "channels.cross_check_cycles", "");
  d["channels"]["cross_check_cycles"] = 2.5;
  expect_one_error(d, "channels.cross_check_cycles", "");
  d["channels"]["cross_check_cycles"] = 2;
  d["channels"]["encoder_tolerance_deg"] = 11;
  expect_one_error(d, "channels.encoder_tolerance_deg", "");
  d["channels"]["encoder_tolerance_deg"] = 0.5;
  d["channels"]["encoder_discrepancy_ms"] = 0;
  expect_one_error(d, "channels.encoder_discrepancy_ms", "");
  d["channels"]["encoder_discrepancy_ms"] = 10;
  d["channels"]["cross_checks"] = 2;
  expect_one_error(d, "channels.cross_checks", "");
}

TEST(SafetyChecksum, WhitespaceOrderAndSpellingDoNotChangeItAnyValueDoes) {
  const std::string text = read(kSource + "/examples/safety/cell.json");
  const Result a = parse_safety(text);
  ASSERT_TRUE(a.ok());
  // the same document, re-serialised (other whitespace, nlohmann's key order, 120 -> 120.0)
  std::string other = json::parse(text).dump(7);
  const std::size_t p = other.find("120");
  ASSERT_NE(p, std::string::npos);
  other.replace(p, 3, "1.2e2");
  const Result b = parse_safety(other);
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(a.config->checksum, b.config->checksum);
  EXPECT_EQ(a.config->canonical, b.config->canonical);
  json changed = json::parse(text);
  changed["tool"]["radius_mm"] = changed["tool"]["radius_mm"].get<double>() + 1.0;
  const Result c = parse_safety(changed.dump());
  ASSERT_TRUE(c.ok());
  EXPECT_NE(a.config->checksum, c.config->checksum);
  EXPECT_NE(a.config->limits.checksum, c.config->limits.checksum);
}

TEST(SafetyFile, RefusesMissingDirectoriesAndFilesOver1MiB) {
  const std::string dir = ::testing::TempDir();
  Result r = load_safety_file(dir + "/no-such-safety.json");
  ASSERT_EQ(r.errors.size(), 1U);
  EXPECT_NE(r.errors[0].message.find("no such file"), std::string::npos);
  r = load_safety_file(dir);
  ASSERT_EQ(r.errors.size(), 1U);
  EXPECT_NE(r.errors[0].message.find("not a regular file"), std::string::npos);
  // a valid configuration padded with whitespace: fine at 1 MiB, refused one byte above
  const std::string path = dir + "/big-safety.json";
  std::string text(default_safety_text());
  text.append(kMaxFileBytes - text.size(), ' ');
  std::ofstream(path, std::ios::binary) << text;
  r = load_safety_file(path);
  EXPECT_TRUE(r.ok()) << ::testing::PrintToString(texts(r));
  std::ofstream(path, std::ios::binary) << text << ' ';
  r = load_safety_file(path);
  ASSERT_EQ(r.errors.size(), 1U);
  EXPECT_NE(r.errors[0].message.find("larger than 1048576 bytes"), std::string::npos) << r.errors[0].text();
  std::filesystem::remove(path);
}

// Every key the parser accepts is documented (docs/safety-configuration.md names it in
// backticks, with its parent path: `joints[].min_deg`).
TEST(SafetyDocs, EveryKeyIsDocumented) {
  const std::string doc = read(kSource + "/docs/safety-configuration.md");
  ASSERT_FALSE(doc.empty());
  for (const std::string& k : known_keys()) {
    EXPECT_NE(doc.find("`" + k + "`"), std::string::npos) << "docs/safety-configuration.md does not name `" << k << "`";
  }
}

TEST(SafetySummary, NamesTheLimits) {
  const Result r = load_safety_file(kSource + "/examples/safety/collaborative.json");
  ASSERT_TRUE(r.ok());
  const std::string s = summary(*r.config);
  for (const char* word : {"checksum:", "table keep_out", "cell keep_in", "loading reduced", "tool axis: within",
                           "stop:      within", "ssm:", "pfl:", "brake test:"}) {
    EXPECT_NE(s.find(word), std::string::npos) << word << "\n" << s;
  }
  EXPECT_NE(s.find(r.config->checksum), std::string::npos);
}

// --- the robot's part (issue 38) ------------------------------------------------------------

namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string with_robot(const std::string& robot_json) {
  json d = json::parse(default_safety_text());
  d.erase("joints");
  d["robot"] = json::parse(robot_json);
  return d.dump();
}

}  // namespace

TEST(SafetyRobot, BuiltInArmWithoutKeyKeepsTheFilesChecksum) {
  const Loaded d = default_safety();
  EXPECT_FALSE(d.robot.from_key);
  EXPECT_FALSE(d.robot.in_checksum);
  std::vector<Error> errors;
  EXPECT_EQ(d.checksum, checksum_text(*canonical_json(default_safety_text(), errors)));
  EXPECT_EQ(d.robot.robot->d.name, "abb_irb120_3_58");
  ASSERT_EQ(d.robot.checksum.size(), 8U);
}

TEST(SafetyRobot, TheKeysUrdfIsCheckedAndItsParametersAreInTheChecksum) {
  const std::string dir = kSource + "/examples/robots";
  const Result a = parse_safety(with_robot(R"({"urdf": "abb_irb120.urdf"})"), dir);
  ASSERT_TRUE(a.ok()) << (a.errors.empty() ? "" : a.errors.front().text());
  EXPECT_TRUE(a.config->robot.from_key);
  EXPECT_TRUE(a.config->robot.in_checksum);
  // The checksummed form carries the parameters the models use.
  const json c = json::parse(a.config->canonical);
  ASSERT_TRUE(c.at("robot").contains("parameters"));
  EXPECT_EQ(c.at("robot").at("parameters").at("joints").at(1).at("origin_mm"), json::parse("[0,0,290]"));
  // Without joints the table is the robot's own.
  EXPECT_FLOAT_EQ(a.config->limits.joints[2].max_rad, motion::kRobot.q_max_rad[2]);
  EXPECT_FLOAT_EQ(a.config->limits.joints[5].max_speed_rad_s, motion::kRobot.qd_max_rad_s[5]);

  // The same arm 1 mm longer in the upper arm: another configuration.
  const auto tmp = std::filesystem::temp_directory_path() / "safestate-test-irb120-longer.urdf";
  std::string text = slurp(dir + "/abb_irb120.urdf");
  const std::string from = "<origin xyz=\"0 0 0.27\" rpy=\"0 0 0\"/>";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "<origin xyz=\"0 0 0.271\" rpy=\"0 0 0\"/>");
  std::ofstream(tmp) << text;
  const Result b = parse_safety(with_robot(R"({"urdf": ")" + tmp.string() + R"("})"), dir);
  ASSERT_TRUE(b.ok());
  EXPECT_NE(a.config->checksum, b.config->checksum);
  EXPECT_NE(a.config->robot.checksum, b.config->robot.checksum);
  std::filesystem::remove(tmp);

  // Read back as the gateway does (the canonical form, robot.parameters present): accepted
  // when they are the running arm's (the built-in IRB 120 here), refused for another.
  const Result back = parse_safety(a.config->canonical);
  ASSERT_TRUE(back.ok()) << (back.errors.empty() ? "" : back.errors.front().text());
  EXPECT_EQ(back.config->checksum, a.config->checksum);
  const Result other = parse_safety(b.config->canonical);
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.errors.front().path, "robot.parameters");
}

// The core's collision model (PFL) is the description's: PFL is accepted on another arm and the
// core gets that arm's inertials and rated torques; a joint without an effort (the rated
// torque the drives report in) is refused, naming it.
TEST(SafetyRobot, PflTakesTheArmsInertialsAndNeedsEveryEffort) {
  const std::string dir = kSource + "/examples/robots";
  const auto write = [&](const std::string& name, const std::string& from, const std::string& to) {
    const auto tmp = std::filesystem::temp_directory_path() / name;
    std::string text = slurp(dir + "/abb_irb120.urdf");
    EXPECT_NE(text.find(from), std::string::npos) << from;
    text.replace(text.find(from), from.size(), to);
    std::ofstream(tmp) << text;
    return tmp;
  };
  const auto other = write("safestate-test-irb120-other.urdf", "<mass value=\"3.909\"/>", "<mass value=\"5.5\"/>");
  const auto no_effort = write("safestate-test-irb120-noeffort.urdf", "velocity=\"5.58505344\" effort=\"8\"/>",
                               "velocity=\"5.58505344\" effort=\"0\"/>");
  const auto with_collab = [&](const std::string& urdf, bool pfl) {
    json d = json::parse(with_robot(R"({"urdf": ")" + urdf + R"("})"));
    d["collaborative"] = json::parse(std::string(R"({"enabled": true, "reduced_speed_mm_s": 200, "pfl": {"enabled": )") +
                                     (pfl ? "true" : "false") + R"(, "body_region": "hand", "robot_mass_kg": 25}})");
    return parse_safety(d.dump(), dir);
  };
  const Result heavier = with_collab(other.string(), true);
  ASSERT_TRUE(heavier.ok()) << (heavier.errors.empty() ? "" : heavier.errors.front().text());
  EXPECT_EQ(heavier.config->limits.inertials.link[1].mass_kg, 5.5F) << "the core gets the description's masses";
  EXPECT_EQ(heavier.config->limits.inertials.link[0].mass_kg, 3.067F);
  EXPECT_EQ(heavier.config->limits.inertials.rated_torque_nm[2], 30.0F);
  const Result refused = with_collab(no_effort.string(), true);
  ASSERT_FALSE(refused.ok());
  ASSERT_EQ(refused.errors.size(), 1U);
  EXPECT_EQ(refused.errors.front().path, "collaborative.pfl.enabled");
  EXPECT_NE(refused.errors.front().message.find("joint 'joint_4'"), std::string::npos) << refused.errors.front().message;
  EXPECT_NE(refused.errors.front().message.find("effort"), std::string::npos);
  EXPECT_TRUE(with_collab(no_effort.string(), false).ok()) << "PFL off: no rated torque needed";
  const Result irb = with_collab("abb_irb120.urdf", true);
  ASSERT_TRUE(irb.ok()) << (irb.errors.empty() ? "" : irb.errors.front().text());
  EXPECT_EQ(irb.config->limits.inertials.link[5].com_m[0], core::kIrb120Inertials.link[5].com_m[0]);
  std::filesystem::remove(other);
  std::filesystem::remove(no_effort);
}

// tool.payload_kg is bounded by the robot's rated payload: the IRB 120's 3 kg built in, another
// arm's from robot.rated_payload_kg (a URDF holds none); refused with the key named.
TEST(SafetyRobot, ThePayloadIsBoundedByTheRobotsRatedPayload) {
  const std::string dir = kSource + "/examples/robots";
  const auto tmp = std::filesystem::temp_directory_path() / "safestate-test-irb120-payload.urdf";
  {
    std::string text = slurp(dir + "/abb_irb120.urdf");
    const std::string from = "<mass value=\"3.909\"/>";
    ASSERT_NE(text.find(from), std::string::npos);
    text.replace(text.find(from), from.size(), "<mass value=\"5.5\"/>");
    std::ofstream(tmp) << text;
  }
  const auto with = [&](const std::string& robot, double payload) {
    json d = json::parse(with_robot(robot));
    d["tool"]["payload_kg"] = payload;
    return parse_safety(d.dump(), dir);
  };
  const std::string other = R"({"urdf": ")" + tmp.string() + R"("})";
  const std::string other5 = R"({"urdf": ")" + tmp.string() + R"(", "rated_payload_kg": 5})";
  // Another arm: no payload without its rated payload; up to it with the key.
  EXPECT_TRUE(with(other, 0.0).ok());
  const Result none = with(other, 1.5);
  ASSERT_FALSE(none.ok());
  ASSERT_EQ(none.errors.size(), 1U);
  EXPECT_EQ(none.errors.front().path, "tool.payload_kg");
  EXPECT_NE(none.errors.front().message.find("robot.rated_payload_kg"), std::string::npos) << none.errors.front().message;
  EXPECT_TRUE(with(other5, 5.0).ok());
  const Result over = with(other5, 5.5);
  ASSERT_FALSE(over.ok());
  EXPECT_EQ(over.errors.front().path, "tool.payload_kg");
  EXPECT_NE(over.errors.front().message.find("<= 5 (robot.rated_payload_kg"), std::string::npos) << over.errors.front().message;
  // The built-in IRB 120: 3 kg, the key may only lower it.
  EXPECT_TRUE(with(R"({"urdf": "abb_irb120.urdf"})", 3.0).ok());
  const Result irb_over = with(R"({"urdf": "abb_irb120.urdf"})", 3.5);
  ASSERT_FALSE(irb_over.ok());
  EXPECT_NE(irb_over.errors.front().message.find("the IRB 120's rated payload"), std::string::npos);
  const Result key_over = with(R"({"urdf": "abb_irb120.urdf", "rated_payload_kg": 4})", 1.0);
  ASSERT_FALSE(key_over.ok());
  EXPECT_EQ(key_over.errors.front().path, "robot.rated_payload_kg");
  // Only the key: the rated payload of the arm the program runs (here the built-in IRB 120).
  EXPECT_TRUE(with(R"({"rated_payload_kg": 2})", 2.0).ok());
  const Result low = with(R"({"rated_payload_kg": 2})", 2.5);
  ASSERT_FALSE(low.ok());
  EXPECT_EQ(low.errors.front().path, "tool.payload_kg");
  const Result bad = with(R"({"rated_payload_kg": 0})", 0.0);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.errors.front().path, "robot.rated_payload_kg");
  const Result base_only = with(R"({"rated_payload_kg": 2, "base": "base_link"})", 0.0);
  ASSERT_FALSE(base_only.ok());
  EXPECT_EQ(base_only.errors.front().path, "robot.urdf");
  std::filesystem::remove(tmp);
}

TEST(SafetyRobot, ABrokenUrdfIsAnErrorOfTheRobotKey) {
  const auto tmp = std::filesystem::temp_directory_path() / "safestate-test-prismatic.urdf";
  std::string text = slurp(kSource + "/examples/robots/abb_irb120.urdf");
  const std::string from = "<joint name=\"joint_3\" type=\"revolute\">";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "<joint name=\"joint_3\" type=\"prismatic\">");
  std::ofstream(tmp) << text;
  const Result r = parse_safety(with_robot(R"({"urdf": ")" + tmp.string() + R"("})"), ".");
  std::filesystem::remove(tmp);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors.front().path, "robot");
  EXPECT_NE(r.errors.front().message.find("joint 'joint_3' is prismatic"), std::string::npos) << r.errors.front().message;
  const Result missing = parse_safety(with_robot(R"({"urdf": "no-such.urdf"})"), "/nonexistent");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.errors.front().message.find("cannot read robot description"), std::string::npos);
}

TEST(SafetyRobot, SummaryNamesTheRobotAndItsJointTable) {
  const std::string s = summary(default_safety());
  for (const char* word : {"robot:     abb_irb120_3_58", "parameters ", "joint_1", "joint_6", "-165", "400"}) {
    EXPECT_NE(s.find(word), std::string::npos) << word << "\n" << s;
  }
}

// On another arm than the built-in one, a file without a `robot` key is checksummed with
// robot.parameters added (and no urdf): the gateway reads that form back (run on a UR5 with
// the built-in configuration found this).
TEST(SafetyRobot, TheChecksummedFormOfAFileWithoutRobotKeyReadsBack) {
  const std::shared_ptr<const robot::Robot> before = robot::active_shared();
  std::string text = slurp(kSource + "/examples/robots/abb_irb120.urdf");
  const std::string from = "<origin xyz=\"0 0 0.27\" rpy=\"0 0 0\"/>";
  text.replace(text.find(from), from.size(), "<origin xyz=\"0 0 0.28\" rpy=\"0 0 0\"/>");
  std::string error;
  std::shared_ptr<const robot::Robot> other = robot::load_text(text, "test", "", "", error);
  ASSERT_NE(other, nullptr) << error;
  robot::set_active(other);
  const Result r = parse_safety(default_safety_text());
  const bool ok = r.ok();
  const Result back = ok ? parse_safety(r.config->canonical) : Result{};
  robot::set_active(before);
  ASSERT_TRUE(ok);
  EXPECT_TRUE(r.config->robot.in_checksum);
  EXPECT_FALSE(r.config->robot.from_key);
  EXPECT_NE(r.config->canonical.find("\"parameters\""), std::string::npos);
  ASSERT_TRUE(back.ok()) << (back.errors.empty() ? "" : back.errors.front().text());
  EXPECT_EQ(back.config->checksum, r.config->checksum);
}

// The strict parser and the consistency checks of the safety configuration (SPEC §10-§12).
// Every problem is collected (not only the first) and names its key path.
#include <algorithm>
#include <array>
#include <optional>
#include <vector>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "safestate/robot/description.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/safety/jcs.hpp"
#include "safestate/safety/safety_config.hpp"

namespace safestate::safety {

using nlohmann::json;

namespace {

// [docs/robot.md] the IRB 120-3/0.58 carries 3 kg (motion::kRatedPayloadKg). A URDF holds no
// rated payload: another arm's comes from robot.rated_payload_kg (the vendor's data sheet).
constexpr double kRatedPayloadKg = static_cast<double>(motion::kRatedPayloadKg);
// A plausibility bound for robot.rated_payload_kg and tool.payload_kg (the largest industrial
// arms carry some 2.3 t): it refuses typos, not arms.
constexpr double kMaxPayloadKg = 2500.0;
// Plausibility bounds where the robot has no published number; they refuse typos (a TCP
// speed of 150000 mm/s, a box 100 m wide), not settings that make sense for this arm.
constexpr double kMaxTcpSpeedMmS = 10000.0;
constexpr double kMaxCoordinateMm = 10000.0;
constexpr double kMaxToolOffsetMm = 1000.0;
constexpr double kMaxToolRadiusMm = 500.0;
constexpr std::size_t kMaxNameBytes = 64;
// stop.max_time_ms: at least a few cycles (the core needs >= 1 cycle at its slowest
// 4 ms cycle) and at most 5 s: a 3 kg arm that needs longer to stop is broken, not slow.
constexpr double kMinStopMs = 10.0;
constexpr double kMaxStopMs = 5000.0;

constexpr double kPi = 3.14159265358979323846;

struct KeySpec {
  const char* name;
  bool required;
};

struct ObjectSpec {
  const char* path;  // pattern as known_keys() lists it
  std::vector<KeySpec> keys;
};

const std::vector<KeySpec> kTop = {{"format", true},        {"name", true},   {"tool", true},
                                   {"robot", false},        {"joints", false},       {"tcp_max_speed_mm_s", true},
                                   {"reduced", true},       {"orientation", false},
                                   {"zones", false},        {"stop", true},   {"collaborative", false},
                                   {"brake_test", false},   {"channels", false}};
// `urdf` or `parameters` (the checksummed form the gateway reads back may hold only the latter).
const std::vector<KeySpec> kRobotKey = {{"urdf", false},       {"base", false},
                                        {"flange", false},     {"parameters", false},
                                        {"rated_payload_kg", false}};
const std::vector<KeySpec> kTool = {{"tcp_mm", true}, {"radius_mm", true}, {"payload_kg", true}};
const std::vector<KeySpec> kJoint = {{"min_deg", true}, {"max_deg", true}, {"max_speed_deg_s", true}};
const std::vector<KeySpec> kReduced = {{"tcp_max_speed_mm_s", true}, {"ramp_ms", true}};
const std::vector<KeySpec> kOrientation = {{"axis", true}, {"max_deviation_deg", true}};
const std::vector<KeySpec> kZone = {{"name", true}, {"kind", true}, {"min_mm", true}, {"max_mm", true}};
const std::vector<KeySpec> kStop = {{"max_time_ms", true}};
const std::vector<KeySpec> kCollaborative = {{"enabled", true},           {"resume_delay_ms", false},
                                             {"auto_resume", false},      {"reduced_speed_mm_s", false},
                                             {"ssm", false},              {"pfl", false}};
const std::vector<KeySpec> kSsm = {{"enabled", true},      {"human_speed_mm_s", false}, {"decel_mm_s2", true},
                                   {"reaction_ms", true},  {"intrusion_mm", true},      {"uncertainty_mm", true}};
const std::vector<KeySpec> kPfl = {{"enabled", true}, {"body_region", true}, {"robot_mass_kg", true}};
const std::vector<KeySpec> kChannels = {{"cross_check_cycles", false}, {"encoder_tolerance_deg", false},
                                        {"encoder_discrepancy_ms", false}};
const std::vector<KeySpec> kBrakeTest = {{"interval_h", false},    {"grace_h", false}, {"test_torque_pct", false},
                                         {"hold_ms", false},       {"max_drift_deg", false}};

const std::vector<ObjectSpec>& object_specs() {
  static const std::vector<ObjectSpec> specs = {
      {"", kTop},
      {"tool", kTool},
      {"robot", kRobotKey},
      {"joints[]", kJoint},
      {"reduced", kReduced},
      {"orientation", kOrientation},
      {"zones[]", kZone},
      {"stop", kStop},
      {"collaborative", kCollaborative},
      {"collaborative.ssm", kSsm},
      {"collaborative.pfl", kPfl},
      {"brake_test", kBrakeTest},
      {"channels", kChannels},
  };
  return specs;
}

std::string join(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string index(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

// A number as the messages print it (the shortest form that reads back the same).
std::string num(double x) { return jcs::number_to_string(x).value_or("?"); }

// A string from the file, quoted and cut short for an error message.
std::string shown(const std::string& s) {
  std::string out = "\"";
  std::size_t cut = std::min<std::size_t>(s.size(), 40);
  // never cut a UTF-8 sequence in two
  while (cut > 0 && cut < s.size() && (static_cast<unsigned char>(s[cut]) & 0xC0U) == 0x80U) --cut;
  for (std::size_t i = 0; i < cut; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    out.push_back(c < 0x20U || c == 0x7FU ? '?' : s[i]);
  }
  if (cut < s.size()) out += "...";
  out.push_back('"');
  return out;
}

std::string type_name(const json& v) {
  switch (v.type()) {
    case json::value_t::null: return "null";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::string: return "a string";
    case json::value_t::array: return "an array";
    case json::value_t::object: return "an object";
    default: return "a number";
  }
}

// The SAX pre-pass: nlohmann's DOM keeps one of two duplicate keys silently, and its
// parser would follow any nesting depth; this pass names every duplicate key by its path
// and stops at kMaxDepth.
class Precheck {
 public:
  using number_integer_t = json::number_integer_t;
  using number_unsigned_t = json::number_unsigned_t;
  using number_float_t = json::number_float_t;
  using string_t = json::string_t;
  using binary_t = json::binary_t;

  explicit Precheck(std::string_view text) : text_(text) {}

  std::vector<Error> duplicates;
  std::optional<Error> fatal;

  bool null() { return value(); }
  bool boolean(bool /*v*/) { return value(); }
  bool number_integer(number_integer_t /*v*/) { return value(); }
  bool number_unsigned(number_unsigned_t /*v*/) { return value(); }
  bool number_float(number_float_t /*v*/, const string_t& /*s*/) { return value(); }
  bool string(string_t& /*v*/) { return value(); }
  bool binary(binary_t& /*v*/) { return value(); }
  bool start_object(std::size_t /*n*/) { return open(true); }
  bool end_object() { return close(); }
  bool start_array(std::size_t /*n*/) { return open(false); }
  bool end_array() { return close(); }
  bool key(string_t& k) {
    Frame& f = stack_.back();
    if (std::find(f.keys.begin(), f.keys.end(), k) != f.keys.end()) {
      duplicates.push_back({join(f.path, k), "duplicate key (a key may appear once in an object)"});
    } else {
      f.keys.push_back(k);
    }
    f.current = k;
    return true;
  }
  bool parse_error(std::size_t position, const std::string& /*token*/, const json::exception& ex) {
    std::size_t line = 1;
    std::size_t column = 1;
    for (std::size_t i = 0; i + 1 < position && i < text_.size(); ++i) {
      if (text_[i] == '\n') {
        ++line;
        column = 1;
      } else {
        ++column;
      }
    }
    std::string what = ex.what();
    // "[json.exception.parse_error.101] parse error at line 1, column 2: syntax error ..."
    if (const std::size_t p = what.find(": "); p != std::string::npos && what.find("parse error") != std::string::npos) {
      what = what.substr(p + 2);
    } else if (const std::size_t q = what.find("] "); q != std::string::npos) {
      what = what.substr(q + 2);
    }
    fatal = Error{"", "not valid JSON at line " + std::to_string(line) + ", column " + std::to_string(column) + ": " +
                          what};
    return false;
  }

 private:
  struct Frame {
    bool object;
    std::string path;
    std::vector<std::string> keys;
    std::string current;
    std::size_t next_index = 0;
  };

  // The path of the value that starts now, in the innermost container.
  std::string child_path() {
    if (stack_.empty()) return "";
    Frame& f = stack_.back();
    if (f.object) return join(f.path, f.current);
    return index(f.path, f.next_index++);
  }
  bool value() {
    (void)child_path();
    return true;
  }
  bool open(bool object) {
    if (stack_.size() >= kMaxDepth) {
      fatal = Error{child_path(), "nested deeper than " + std::to_string(kMaxDepth) + " levels"};
      return false;
    }
    std::string p = child_path();
    stack_.push_back(Frame{object, std::move(p), {}, {}, 0});
    return true;
  }
  bool close() {
    stack_.pop_back();
    return true;
  }

  std::string_view text_;
  std::vector<Frame> stack_;
};

// Checks of the parsed tree; `errors` collects them all.
class Checker {
 public:
  std::vector<Error> errors;

  void add(const std::string& path, const std::string& message) { errors.push_back({path, message}); }

  // An object with exactly the keys of `spec`: reports unknown and missing keys.
  bool object(const json& v, const std::string& path, const std::vector<KeySpec>& spec) {
    if (!v.is_object()) {
      add(path, "must be an object (found " + type_name(v) + ")");
      return false;
    }
    for (auto it = v.begin(); it != v.end(); ++it) {
      const bool known = std::any_of(spec.begin(), spec.end(), [&](const KeySpec& k) { return it.key() == k.name; });
      if (!known) {
        std::string expected;
        for (const KeySpec& k : spec) expected += (expected.empty() ? "" : ", ") + std::string(k.name);
        add(join(path, it.key()), "unknown key (expected one of: " + expected + ")");
      }
    }
    for (const KeySpec& k : spec) {
      if (k.required && !v.contains(k.name)) add(join(path, k.name), "missing (required)");
    }
    return true;
  }

  // A number in [lo, hi] (or (lo, hi] when lo_open). Absent: nullopt, no error (the key
  // check reports required keys).
  std::optional<double> number(const json& obj, const std::string& path, const char* key, double lo, bool lo_open,
                               double hi, const std::string& why = "") {
    if (!obj.is_object() || !obj.contains(key)) return std::nullopt;
    return number_value(obj.at(key), join(path, key), lo, lo_open, hi, why);
  }

  std::optional<double> number_value(const json& v, const std::string& p, double lo, bool lo_open, double hi,
                                     const std::string& why = "") {
    if (!v.is_number()) {
      add(p, "must be a number (found " + type_name(v) + ")");
      return std::nullopt;
    }
    const double x = v.get<double>();
    if (!std::isfinite(x) || (lo_open ? !(x > lo) : !(x >= lo)) || !(x <= hi)) {
      add(p, "must be " + std::string(lo_open ? "> " : ">= ") + num(lo) + " and <= " + num(hi) +
                 (why.empty() ? "" : " (" + why + ")") + " (found " + num(x) + ")");
      return std::nullopt;
    }
    return x;
  }

  // A whole number of milliseconds in [lo, hi].
  std::optional<std::uint32_t> whole(const json& obj, const std::string& path, const char* key, double lo, double hi,
                                     const std::string& why = "") {
    if (!obj.is_object() || !obj.contains(key)) return std::nullopt;
    const json& v = obj.at(key);
    const std::string p = join(path, key);
    if (!v.is_number()) {
      add(p, "must be a number (found " + type_name(v) + ")");
      return std::nullopt;
    }
    const double x = v.get<double>();
    if (std::floor(x) != x) {
      add(p, "must be a whole number (found " + num(x) + ")");
      return std::nullopt;
    }
    const std::optional<double> r = number_value(v, p, lo, false, hi, why);
    if (!r) return std::nullopt;
    return static_cast<std::uint32_t>(*r);
  }

  std::optional<bool> boolean(const json& obj, const std::string& path, const char* key) {
    if (!obj.is_object() || !obj.contains(key)) return std::nullopt;
    const json& v = obj.at(key);
    if (!v.is_boolean()) {
      add(join(path, key), "must be true or false (found " + type_name(v) + ")");
      return std::nullopt;
    }
    return v.get<bool>();
  }

  std::optional<std::string> string(const json& obj, const std::string& path, const char* key) {
    if (!obj.is_object() || !obj.contains(key)) return std::nullopt;
    const json& v = obj.at(key);
    if (!v.is_string()) {
      add(join(path, key), "must be a string (found " + type_name(v) + ")");
      return std::nullopt;
    }
    return v.get<std::string>();
  }

  // An array of exactly three numbers, each within [-bound, bound].
  std::optional<std::array<double, 3>> vec3(const json& obj, const std::string& path, const char* key, double bound) {
    if (!obj.is_object() || !obj.contains(key)) return std::nullopt;
    const json& v = obj.at(key);
    const std::string p = join(path, key);
    if (!v.is_array() || v.size() != 3U) {
      add(p, "must be an array of 3 numbers (found " +
                 (v.is_array() ? "an array of " + std::to_string(v.size()) : type_name(v)) + ")");
      return std::nullopt;
    }
    std::array<double, 3> out{};
    bool ok = true;
    for (std::size_t i = 0; i < 3; ++i) {
      const std::optional<double> x = number_value(v[i], index(p, i), -bound, false, bound);
      if (x) {
        out[i] = *x;
      } else {
        ok = false;
      }
    }
    if (!ok) return std::nullopt;
    return out;
  }
};

// No C0 or C1 control characters (DEL, and U+0080..U+009F, UTF-8 C2 80..C2 9F, included):
// the name is printed on terminals and in logs.
bool printable_name(const std::string& s) {
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto u = static_cast<unsigned char>(s[i]);
    if (u < 0x20U || u == 0x7FU) return false;
    if (u == 0xC2U && i + 1 < s.size() && static_cast<unsigned char>(s[i + 1]) <= 0x9FU) return false;
  }
  return true;
}

bool zone_name_chars(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' ||
           c == '.';
  });
}

double rad_to_deg(double r) { return r * 180.0 / kPi; }

std::string resolve_path(const std::string& dir, const std::string& p) {
  const std::filesystem::path path(p);
  return (path.is_absolute() || dir.empty()) ? p : (std::filesystem::path(dir) / path).string();
}
// The robot's range in degrees, to 1/1000 degree (robot.hpp holds float radians).
double robot_deg(float rad) { return std::round(rad_to_deg(static_cast<double>(rad)) * 1000.0) / 1000.0; }

float to_rad(double deg, float lo, float hi) {
  // Clamped to the robot's own range: a file at exactly the robot's limit must not end up
  // a float rounding step beyond it.
  return std::clamp(static_cast<float>(deg * kPi / 180.0), lo, hi);
}

void check_collaborative(const json& c, double tcp_max, Checker& ck, Collaborative& out) {
  const std::string p = "collaborative";
  if (!ck.object(c, p, kCollaborative)) return;
  if (auto v = ck.boolean(c, p, "enabled")) out.enabled = *v;
  if (auto v = ck.whole(c, p, "resume_delay_ms", 0.0, 60000.0)) out.resume_delay_ms = *v;
  if (auto v = ck.boolean(c, p, "auto_resume")) out.auto_resume = *v;
  out.reduced_speed_mm_s = tcp_max;
  if (auto v = ck.number(c, p, "reduced_speed_mm_s", 0.0, true, tcp_max, "at most tcp_max_speed_mm_s")) {
    out.reduced_speed_mm_s = *v;
  }
  if (c.contains("ssm")) {
    const json& s = c.at("ssm");
    const std::string sp = "collaborative.ssm";
    Ssm ssm;
    if (ck.object(s, sp, kSsm)) {
      if (auto v = ck.boolean(s, sp, "enabled")) ssm.enabled = *v;
      if (auto v = ck.number(s, sp, "human_speed_mm_s", 0.0, true, 5000.0)) ssm.human_speed_mm_s = *v;
      if (auto v = ck.number(s, sp, "decel_mm_s2", 0.0, true, 1.0e6, "a <= 0 would never stop")) ssm.decel_mm_s2 = *v;
      if (auto v = ck.number(s, sp, "reaction_ms", 0.0, true, 10000.0, "T_r <= 0 is not a real chain")) {
        ssm.reaction_ms = *v;
      }
      if (auto v = ck.number(s, sp, "intrusion_mm", 0.0, false, 5000.0)) ssm.intrusion_mm = *v;
      if (auto v = ck.number(s, sp, "uncertainty_mm", 0.0, false, 5000.0)) ssm.uncertainty_mm = *v;
    }
    out.ssm = ssm;
  }
  if (c.contains("pfl")) {
    const json& f = c.at("pfl");
    const std::string fp = "collaborative.pfl";
    Pfl pfl;
    if (ck.object(f, fp, kPfl)) {
      if (auto v = ck.boolean(f, fp, "enabled")) pfl.enabled = *v;
      if (auto v = ck.string(f, fp, "body_region")) {
        BodyRegion region{};
        if (!core::parse_body_region(v->c_str(), region)) {
          std::string list;
          for (const core::BodyRegionLimits& r : core::kBodyRegions) {
            if (core::transient_contact_allowed(r.id)) list += (list.empty() ? "" : ", ") + std::string(r.name);
          }
          ck.add(fp + ".body_region", "unknown body region " + shown(*v) + " (expected one of: " + list + ")");
        } else if (!core::transient_contact_allowed(region)) {
          ck.add(fp + ".body_region", *v + " allows no transient contact (ISO/TS 15066 Annex A): refused");
        } else {
          pfl.body_region = region;
        }
      }
      if (auto v = ck.number(f, fp, "robot_mass_kg", 0.0, true, 10000.0)) pfl.robot_mass_kg = *v;
    }
    out.pfl = pfl;
  }
}

// tool.payload_kg within the robot's rated payload: robot.rated_payload_kg, else the built-in
// IRB 120's 3 kg; another arm without the key carries none (its URDF gives no rated payload).
void check_payload(const safestate::robot::Robot& rb, const std::optional<double>& payload,
                   const std::optional<double>& rated_key, Checker& ck) {
  const bool builtin = safestate::robot::is_builtin(rb);
  if (builtin && rated_key && *rated_key > kRatedPayloadKg) {
    ck.add("robot.rated_payload_kg", "must be <= " + num(kRatedPayloadKg) +
                                         " (the IRB 120-3/0.58's rated payload) (found " + num(*rated_key) + ")");
    return;
  }
  if (!payload) {
    return;
  }
  if (!rated_key && !builtin) {
    if (*payload > 0.0) {
      ck.add("tool.payload_kg", "must be 0 without robot.rated_payload_kg: the description of robot " + rb.d.name +
                                    " (URDF) gives no rated payload; set robot.rated_payload_kg from the arm's data "
                                    "sheet (found " + num(*payload) + ")");
    }
    return;
  }
  const double rated = rated_key ? *rated_key : kRatedPayloadKg;
  if (!(*payload <= rated)) {
    ck.add("tool.payload_kg", "must be >= 0 and <= " + num(rated) + " (" +
                                  (rated_key ? "robot.rated_payload_kg, robot " + rb.d.name + "'s rated payload"
                                             : std::string("the IRB 120's rated payload")) +
                                  ") (found " + num(*payload) + ")");
  }
}

// The file's §11 section in the core's units (only for a configuration without errors).
void to_core(const Collaborative& c, float payload_kg, core::CollaborativeLimits& out) {
  out.enabled = c.enabled;
  out.resume_delay_ms = c.resume_delay_ms;
  out.auto_resume = c.auto_resume;
  out.reduced_speed_mm_s = static_cast<float>(c.reduced_speed_mm_s);
  if (c.ssm) {
    out.ssm_enabled = c.ssm->enabled;
    out.ssm.human_speed_mm_s = static_cast<float>(c.ssm->human_speed_mm_s);
    out.ssm.decel_mm_s2 = static_cast<float>(c.ssm->decel_mm_s2);
    out.ssm.reaction_s = static_cast<float>(c.ssm->reaction_ms / 1000.0);
    out.ssm.intrusion_mm = static_cast<float>(c.ssm->intrusion_mm);
    out.ssm.uncertainty_mm = static_cast<float>(c.ssm->uncertainty_mm);
  }
  if (c.pfl) {
    out.pfl_enabled = c.pfl->enabled;
    out.body_region = c.pfl->body_region;
    out.pfl_speed_mm_s = core::pfl_speed_cap_mm_s(c.pfl->body_region, static_cast<float>(c.pfl->robot_mass_kg), payload_kg);
    out.f_qs_n = core::body_region(c.pfl->body_region).f_qs_n;
  }
}

void check_brake_test(const json& b, Checker& ck, BrakeTest& out) {
  const std::string p = "brake_test";
  if (!ck.object(b, p, kBrakeTest)) return;
  if (auto v = ck.number(b, p, "interval_h", 0.0, true, 8760.0, "at most a year")) out.interval_h = *v;
  if (auto v = ck.number(b, p, "grace_h", 0.0, false, 8760.0)) out.grace_h = *v;
  if (auto v = ck.number(b, p, "test_torque_pct", 0.0, true, 300.0)) out.test_torque_pct = *v;
  if (auto v = ck.whole(b, p, "hold_ms", 1.0, 10000.0)) out.hold_ms = *v;
  if (auto v = ck.number(b, p, "max_drift_deg", 0.0, true, 10.0)) out.max_drift_deg = *v;
}

// @req CH-CONFIG
// SPEC §14's settings (core::validate's ranges): the cross-check window in cycles, the encoder
// tolerance in degrees and its time in milliseconds.
void check_channels(const json& c, Checker& ck, Channels& out) {
  const std::string p = "channels";
  if (!ck.object(c, p, kChannels)) return;
  if (auto v = ck.whole(c, p, "cross_check_cycles", 1.0, 100.0)) out.cross_check_cycles = *v;
  if (auto v = ck.number(c, p, "encoder_tolerance_deg", 0.0, true, 10.0)) out.encoder_tolerance_deg = *v;
  if (auto v = ck.whole(c, p, "encoder_discrepancy_ms", 1.0, 1000.0)) out.encoder_discrepancy_ms = *v;
}

}  // namespace

const char* to_string(BodyRegion r) noexcept { return core::body_region(r).name; }

std::vector<std::string> known_keys() {
  std::vector<std::string> out;
  for (const ObjectSpec& o : object_specs()) {
    for (const KeySpec& k : o.keys) out.push_back(join(o.path, k.name));
  }
  return out;
}

namespace {
// JSON text to a tree, refusing syntax errors and too deep nesting (fatal: nullopt) and
// listing every duplicate key in `duplicates`.
std::optional<json> parse_tree(std::string_view text, std::vector<Error>& errors) {
  Precheck pre(text);
  try {
    (void)json::sax_parse(text.begin(), text.end(), &pre);
  } catch (const std::exception& ex) {  // nlohmann reports through the SAX; belt and braces
    errors.push_back({"", std::string("not valid JSON: ") + ex.what()});
    return std::nullopt;
  }
  if (pre.fatal) {
    errors.push_back(*pre.fatal);
    return std::nullopt;
  }
  json doc = json::parse(text.begin(), text.end(), nullptr, false);
  if (doc.is_discarded()) {
    errors.push_back({"", "not valid JSON"});
    return std::nullopt;
  }
  errors.insert(errors.end(), pre.duplicates.begin(), pre.duplicates.end());
  return doc;
}
}  // namespace

std::optional<std::string> canonical_json(std::string_view text, std::vector<Error>& errors) {
  const std::optional<json> doc = parse_tree(text, errors);
  if (!doc || !errors.empty()) return std::nullopt;
  std::optional<std::string> c = jcs::canonicalize(*doc);
  if (!c) errors.push_back({"", "cannot be put in RFC 8785 form"});
  return c;
}

Result parse_safety(std::string_view text) { return parse_safety(text, "."); }

Result parse_safety(std::string_view text, const std::string& dir) {
  Result result;
  Checker ck;
  const std::optional<json> parsed = parse_tree(text, ck.errors);
  if (!parsed) {
    result.errors = std::move(ck.errors);
    return result;
  }
  const json& doc = *parsed;
  Loaded cfg;
  core::SafetyLimits& lim = cfg.limits;
  if (!ck.object(doc, "", kTop)) {
    result.errors = std::move(ck.errors);
    return result;
  }

  if (auto f = ck.string(doc, "", "format"); f && *f != kFormat) {
    ck.add("format", "must be \"" + std::string(kFormat) + "\" (found " + shown(*f) + ")");
  }
  if (auto n = ck.string(doc, "", "name")) {
    if (n->empty() || n->size() > kMaxNameBytes || !printable_name(*n)) {
      ck.add("name", "must be 1.." + std::to_string(kMaxNameBytes) + " bytes without control characters");
    } else {
      cfg.name = *n;
    }
  }

  std::optional<double> payload;        // tool.payload_kg
  std::optional<double> rated_payload;  // robot.rated_payload_kg
  if (doc.contains("tool") && ck.object(doc.at("tool"), "tool", kTool)) {
    const json& t = doc.at("tool");
    if (auto v = ck.vec3(t, "tool", "tcp_mm", kMaxToolOffsetMm)) {
      for (std::size_t i = 0; i < 3; ++i) lim.tcp_mm[i] = static_cast<float>((*v)[i]);
    }
    if (auto v = ck.number(t, "tool", "radius_mm", 0.0, false, kMaxToolRadiusMm)) {
      lim.tool_radius_mm = static_cast<float>(*v);
    }
    // Bounded by the robot's rated payload below, once the robot is known.
    if (auto v = ck.number(t, "tool", "payload_kg", 0.0, false, kMaxPayloadKg, "a plausibility bound")) {
      lim.payload_kg = static_cast<float>(*v);
      payload = *v;
    }
  }

  // The robot first: the joint table's defaults and bounds are its own (issue 38).
  cfg.robot.robot = safestate::robot::active_shared();
  if (doc.contains("robot") && ck.object(doc.at("robot"), "robot", kRobotKey)) {
    const json& r = doc.at("robot");
    // Only rated_payload_kg: the rated payload of the arm the program runs (--robot, else the
    // built-in IRB 120); anything else names the arm's URDF.
    const bool payload_only = r.contains("rated_payload_kg") && !r.contains("base") && !r.contains("flange");
    if (!r.contains("urdf") && !r.contains("parameters") && !payload_only) {
      ck.add("robot.urdf", "missing (required): the arm's URDF file");
    }
    rated_payload = ck.number(r, "robot", "rated_payload_kg", 0.0, true, kMaxPayloadKg, "a plausibility bound");
    const auto urdf = r.contains("urdf") ? ck.string(r, "robot", "urdf") : std::optional<std::string>(std::string());
    const auto base = r.contains("base") ? ck.string(r, "robot", "base") : std::optional<std::string>(std::string());
    const auto flange =
        r.contains("flange") ? ck.string(r, "robot", "flange") : std::optional<std::string>(std::string());
    if (urdf && base && flange && r.contains("parameters")) {
      // The form the checksum covers (robot.parameters added), as the gateway reads it back
      // from the core: the parameters must be exactly those of the robot the program runs.
      const std::optional<std::string> want =
          jcs::canonicalize(json::parse(safestate::robot::canonical_parameters(*cfg.robot.robot)));
      const std::optional<std::string> got = jcs::canonicalize(r.at("parameters"));
      if (!r.at("parameters").is_object() || !got || got != want) {
        ck.add("robot.parameters", "are not the parameters of the robot this program runs (" +
                                       cfg.robot.robot->d.name + ", " + cfg.robot.robot->d.source + ")");
      }
      cfg.robot.from_key = true;
    } else if (urdf && base && flange && !urdf->empty()) {
      std::string error;
      std::shared_ptr<const safestate::robot::Robot> loaded =
          safestate::robot::load_file(resolve_path(dir, *urdf), *base, *flange, error);
      if (loaded) {
        cfg.robot.robot = std::move(loaded);
        cfg.robot.from_key = true;
      } else {
        ck.add("robot", error);
      }
    }
  }
  const safestate::robot::Robot& rb = *cfg.robot.robot;
  check_payload(rb, payload, rated_payload, ck);
  cfg.robot.rated_payload_kg = rated_payload ? *rated_payload : (safestate::robot::is_builtin(rb) ? kRatedPayloadKg : 0.0);
  lim.inertials = rb.inertials;
  for (std::size_t i = 0; i < core::kAxes; ++i) {  // no `joints` key: the robot's own limits
    lim.joints[i] = core::JointLimit{rb.model.q_min_rad[i], rb.model.q_max_rad[i], rb.model.qd_max_rad_s[i]};
  }

  if (doc.contains("joints")) {
    const json& j = doc.at("joints");
    if (!j.is_array() || j.size() != core::kAxes) {
      ck.add("joints", "must be an array of " + std::to_string(core::kAxes) + " joints (found " +
                           (j.is_array() ? "an array of " + std::to_string(j.size()) : type_name(j)) + ")");
    } else {
      const motion::RobotModel& robot = rb.model;
      for (std::size_t i = 0; i < core::kAxes; ++i) {
        const std::string p = index("joints", i);
        if (!ck.object(j[i], p, kJoint)) continue;
        const double lo = robot_deg(robot.q_min_rad[i]);
        const double hi = robot_deg(robot.q_max_rad[i]);
        const double vmax = robot_deg(robot.qd_max_rad_s[i]);
        const std::string axis = "axis " + std::to_string(i + 1);
        const auto mn = ck.number(j[i], p, "min_deg", lo, false, hi, axis + "'s own range");
        const auto mx = ck.number(j[i], p, "max_deg", lo, false, hi, axis + "'s own range");
        if (mn && mx && !(*mn < *mx)) {
          ck.add(p + ".max_deg", "must be > min_deg (" + num(*mn) + ") (found " + num(*mx) + ")");
        }
        const auto sp = ck.number(j[i], p, "max_speed_deg_s", 0.0, true, vmax, axis + "'s own maximum speed");
        core::JointLimit& jl = lim.joints[i];
        if (mn) jl.min_rad = to_rad(*mn, robot.q_min_rad[i], robot.q_max_rad[i]);
        if (mx) jl.max_rad = to_rad(*mx, robot.q_min_rad[i], robot.q_max_rad[i]);
        if (sp) jl.max_speed_rad_s = to_rad(*sp, 0.0F, robot.qd_max_rad_s[i]);
      }
    }
  }

  const std::optional<double> tcp_max =
      ck.number(doc, "", "tcp_max_speed_mm_s", 0.0, true, kMaxTcpSpeedMmS, "a plausibility bound");
  if (tcp_max) lim.tcp_max_speed_mm_s = static_cast<float>(*tcp_max);

  if (doc.contains("reduced") && ck.object(doc.at("reduced"), "reduced", kReduced)) {
    const json& r = doc.at("reduced");
    if (auto v = ck.number(r, "reduced", "tcp_max_speed_mm_s", 0.0, true, kMaxTcpSpeedMmS, "a plausibility bound")) {
      if (tcp_max && *v > *tcp_max) {
        ck.add("reduced.tcp_max_speed_mm_s",
               "must be <= tcp_max_speed_mm_s (" + num(*tcp_max) + "): reduced may not be faster than normal (found " +
                   num(*v) + ")");
      }
      lim.reduced_tcp_max_speed_mm_s = static_cast<float>(*v);
    }
    if (auto v = ck.whole(r, "reduced", "ramp_ms", 1.0, 10000.0)) lim.reduced_ramp_ms = *v;
  }

  if (doc.contains("orientation") && ck.object(doc.at("orientation"), "orientation", kOrientation)) {
    const json& o = doc.at("orientation");
    const auto axis = ck.vec3(o, "orientation", "axis", 1.0e6);
    const auto dev = ck.number(o, "orientation", "max_deviation_deg", 0.0, true, 180.0, "a cone's half angle");
    if (axis) {
      const double norm = std::sqrt((*axis)[0] * (*axis)[0] + (*axis)[1] * (*axis)[1] + (*axis)[2] * (*axis)[2]);
      if (!(norm > 1.0e-6)) {
        ck.add("orientation.axis", "must not be zero (it is a direction)");
      } else {
        for (std::size_t i = 0; i < 3; ++i) lim.orientation_axis[i] = static_cast<float>((*axis)[i] / norm);
      }
    }
    if (dev) {
      if (*dev >= 180.0) {
        ck.add("orientation.max_deviation_deg", "must be < 180 (180 would allow every orientation) (found 180)");
      }
      lim.orientation_max_deviation_rad = static_cast<float>(*dev * kPi / 180.0);
    }
    lim.orientation_enabled = true;
  }

  if (doc.contains("zones")) {
    const json& z = doc.at("zones");
    if (!z.is_array()) {
      ck.add("zones", "must be an array of zones (found " + type_name(z) + ")");
    } else if (z.size() > core::kMaxZones) {
      ck.add("zones", "at most " + std::to_string(core::kMaxZones) + " zones (found " + std::to_string(z.size()) + ")");
    } else {
      lim.zone_count = static_cast<std::uint8_t>(z.size());
      std::vector<std::string> names;
      for (std::size_t i = 0; i < z.size(); ++i) {
        const std::string p = index("zones", i);
        names.emplace_back();
        if (!ck.object(z[i], p, kZone)) continue;
        core::Zone& zone = lim.zones[i];
        if (auto n = ck.string(z[i], p, "name")) {
          if (n->empty() || n->size() >= core::kZoneNameSize) {
            ck.add(p + ".name", "must be 1.." + std::to_string(core::kZoneNameSize - 1) + " bytes (found " +
                                    std::to_string(n->size()) + ")");
          } else if (!zone_name_chars(*n)) {
            ck.add(p + ".name", "may hold only letters, digits, '_', '-' and '.' (it is an alarm's detail) (found " +
                                    shown(*n) + ")");
          } else if (*n == "tcp" || n->rfind("axis.", 0) == 0) {
            ck.add(p + ".name", shown(*n) + " is reserved for the alarm details of the other limits");
          } else {
            const auto dup = std::find(names.begin(), names.end(), *n);
            if (dup != names.end()) {
              ck.add(p + ".name", "duplicate zone name " + shown(*n) + " (also zones[" +
                                      std::to_string(dup - names.begin()) + "].name)");
            }
            names.back() = *n;
            std::memcpy(zone.name.data(), n->data(), n->size());
            zone.name[n->size()] = '\0';
          }
        }
        if (auto k = ck.string(z[i], p, "kind")) {
          if (*k == "keep_in") {
            zone.kind = core::ZoneKind::keep_in;
          } else if (*k == "keep_out") {
            zone.kind = core::ZoneKind::keep_out;
          } else if (*k == "reduced") {
            zone.kind = core::ZoneKind::reduced;
          } else {
            ck.add(p + ".kind", "must be keep_in, keep_out or reduced (found " + shown(*k) + ")");
          }
        }
        const auto mn = ck.vec3(z[i], p, "min_mm", kMaxCoordinateMm);
        const auto mx = ck.vec3(z[i], p, "max_mm", kMaxCoordinateMm);
        if (mn && mx) {
          for (std::size_t a = 0; a < 3; ++a) {
            if (!((*mn)[a] < (*mx)[a])) {
              ck.add(index(p + ".max_mm", a), "must be > min_mm[" + std::to_string(a) + "] (" + num((*mn)[a]) +
                                                  ") (found " + num((*mx)[a]) + ")");
            }
            zone.min_mm[a] = static_cast<float>((*mn)[a]);
            zone.max_mm[a] = static_cast<float>((*mx)[a]);
          }
        }
      }
    }
  }

  if (doc.contains("stop") && ck.object(doc.at("stop"), "stop", kStop)) {
    if (auto v = ck.whole(doc.at("stop"), "stop", "max_time_ms", kMinStopMs, kMaxStopMs)) lim.max_stop_ms = *v;
  }

  if (doc.contains("collaborative")) {
    Collaborative c;
    check_collaborative(doc.at("collaborative"), tcp_max.value_or(kMaxTcpSpeedMmS), ck, c);
    // PFL's collision detection compares the drives' torques (per mille of their rated torque)
    // with the core's model of the arm's dynamics, both from the description: the rated torque
    // is the URDF's effort, so every joint needs one.
    if (c.pfl && c.pfl->enabled) {
      for (const safestate::robot::Joint& j : cfg.robot.robot->d.joints) {
        if (!(j.effort_nm > 0.0)) {
          ck.add("collaborative.pfl.enabled",
                 "power and force limiting reads the drives' torques in per mille of their rated torque, the URDF's "
                 "effort limit: joint '" + j.name + "' of robot " + cfg.robot.robot->d.name +
                     " has none (effort 0); give it its rated torque or leave PFL off");
          break;
        }
      }
    }
    cfg.collaborative = c;
  }
  if (doc.contains("brake_test")) {
    cfg.brake_test_configured = true;
    check_brake_test(doc.at("brake_test"), ck, cfg.brake_test);
  }
  if (doc.contains("channels")) {
    cfg.channels_configured = true;
    check_channels(doc.at("channels"), ck, cfg.channels);
  }

  if (!ck.errors.empty()) {
    result.errors = std::move(ck.errors);
    return result;
  }
  // The robot's part: the parameters its models use. A robot other than the built-in IRB 120
  // puts them into what the checksum covers, as robot.parameters (docs/robot.md "Checksum").
  cfg.robot.parameters = safestate::robot::canonical_parameters(rb);
  const json params = json::parse(cfg.robot.parameters);
  const std::optional<std::string> params_canonical = jcs::canonicalize(params);
  cfg.robot.in_checksum = cfg.robot.from_key || !safestate::robot::is_builtin(rb);
  json covered = doc;
  if (cfg.robot.in_checksum) {
    if (!covered.contains("robot")) {
      covered["robot"] = json::object();
    }
    covered["robot"]["parameters"] = params;
  }
  const std::optional<std::string> canonical = jcs::canonicalize(covered);
  if (!canonical || !params_canonical) {
    result.errors.push_back({"", "cannot be put in RFC 8785 form"});
    return result;
  }
  cfg.robot.checksum = checksum_text(*params_canonical);
  if (cfg.collaborative) {
    to_core(*cfg.collaborative, lim.payload_kg, lim.collaborative);
  }
  // SPEC §12 into the core (the defaults when the file has no `brake_test` key).
  lim.brake_test.configured = cfg.brake_test_configured;
  lim.brake_test.interval_h = static_cast<float>(cfg.brake_test.interval_h);
  lim.brake_test.grace_h = static_cast<float>(cfg.brake_test.grace_h);
  lim.brake_test.test_torque_pct = static_cast<float>(cfg.brake_test.test_torque_pct);
  lim.brake_test.hold_ms = cfg.brake_test.hold_ms;
  lim.brake_test.max_drift_deg = static_cast<float>(cfg.brake_test.max_drift_deg);
  cfg.canonical = *canonical;
  cfg.checksum = checksum_text(cfg.canonical);
  lim.checksum = checksum_value(cfg.canonical);
  result.config = std::move(cfg);
  return result;
}

}  // namespace safestate::safety

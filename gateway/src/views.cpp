// JSON and Prometheus views of the bridge's records (protocol.md "Endpoints", "Messages").
//
// Decisions where protocol.md is silent:
//  - Numbers are rounded to what they mean: tcp_speed to 0.1 mm/s, positions to 1 um,
//    angles to 1 urad, so that a float does not print as 0.30000001192092896.
//  - The status message carries, after the fields of protocol.md: mode_requested,
//    target (leaf or null), cause (words or null), arming_step (null outside ARMING),
//    arming_progress, axis_state (PLCopen names), program_index, program_length,
//    simulated, max_point_speed, statusword, core/gateway heartbeats and pids,
//    core_heartbeat_age_ms (wall time since the core's cycle counter last advanced, as
//    seen by the gateway: a stuck core shows here) and shutting_down.
//  - The status' `safety` object carries, after its fields of protocol.md: pfl (collision
//    detection acts), contact_force (N at the TCP, 0.1, null when pfl is off) and, from the
//    active configuration, contact_force_limit (the body region's F_qs, N) and
//    pfl_speed_limit (v_pfl, mm/s), both null without pfl.
//  - The status carries `sim` (SPEC §11, the simulated person; docs/collaborative.md): null
//    unless the in-process simulated cell, else {person: null | {x_mm, y_mm, radius_mm,
//    speed_mm_s, walking, in_outer, in_inner, separation_mm, nearest_point}, person_fields:
//    {outer_mm, inner_mm, scanner, distance_sensor}} (mm, 0.1; what the simulated devices
//    see of the person, not what the core validated: that is `safety`).
//  - The black box of a stopping transition is {first, last, missing, cycles:[...]};
//    a cycle whose slot no longer holds it is {"t": T, "missing": true}.
#include "safestate/robot/description.hpp"
#include "safestate/gateway/views.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>

#include "safestate/core/describe.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/core/transitions.hpp"
#include "safestate/motion/motion_controller.hpp"
#include "safestate/vocab/names.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/safety/jcs.hpp"
#include "safestate/safety/safety_config.hpp"

namespace safestate::gateway {

namespace {

constexpr std::array<const char*, bridge::kContactCount> kContactNames{
    "estop.a",  "estop.b",   "gate.a",  "gate.b",  "enable.a",    "enable.b",
    "enable.panic", "mode.auto", "mode.t1", "mode.t2", "reset_button", "reduced.a", "reduced.b",
    "field.outer.a", "field.outer.b", "field.inner.a", "field.inner.b"};

double rounded(double v, double scale) { return std::round(v * scale) / scale + 0.0; }  // + 0.0: no -0

Json name_or_null(const char* dash_for_none) {
  if (dash_for_none == nullptr || std::string_view(dash_for_none) == "-") {
    return nullptr;
  }
  return dash_for_none;
}

// The fieldbus as `safestate run` published it (set once at attach, before any view).
bridge::BusInfo g_bus{};

// The safety configuration `safestate run` gave the core (set once at attach).
struct SafetyView {
  bool ok = false;
  std::string name;
  std::string checksum;
  std::string source;
  Json config;
  core::SafetyLimits limits{};
};
SafetyView g_safety;

std::string hex8(std::uint32_t v) {
  std::array<char, 16> b{};
  std::snprintf(b.data(), b.size(), "%08X", v);
  return b.data();
}

const char* zone_kind_words(core::ZoneKind k) noexcept {
  switch (k) {
    case core::ZoneKind::keep_in: return "keep-in";
    case core::ZoneKind::keep_out: return "keep-out";
    case core::ZoneKind::reduced: break;
  }
  return "reduced";
}

// SPEC §10 words the core cannot know: the zone's name (the core's detail carries its
// index), the sources of reduced mode.
std::string limit_words(core::AlarmId id, const core::AlarmDetail& d, std::string s) {
  if (id == core::AlarmId::ZONE_VIOLATION && d.signal == core::Signal::zone && g_safety.ok &&
      d.code < g_safety.limits.zone_count && d.code < core::kMaxZones) {
    const core::Zone& z = g_safety.limits.zones[d.code];
    const std::string key = "Zone " + std::to_string(d.code + 1U);
    const std::size_t at = s.find(key);
    if (at != std::string::npos) {
      s.replace(at, key.size(), "Zone " + std::string(z.name.data()) + " (" + zone_kind_words(z.kind) + ")");
    }
  }
  if (id == core::AlarmId::REDUCED_SPEED && d.signal == core::Signal::reduced && d.code != 0U) {
    std::string why;
    const std::array<std::pair<std::uint16_t, const char*>, 3> sources{
        {{core::kReducedByZone, "in reduced zone"}, {core::kReducedByInput, "reduced input"},
         {core::kReducedByField, "outer protective field"}}};
    for (const auto& [bit, words] : sources) {
      if ((d.code & bit) != 0U) {
        why += (why.empty() ? "" : ", ") + std::string(words);
        // The core's detail carries 1 + the zone's index in `axis` (core/src/monitors/zones.cpp).
        if (bit == core::kReducedByZone && d.axis != 0U && g_safety.ok && d.axis <= g_safety.limits.zone_count &&
            d.axis <= core::kMaxZones) {
          why += " " + std::string(g_safety.limits.zones[d.axis - 1U].name.data());
        }
      }
    }
    s += " (" + why + ")";
  }
  return s;
}

// The core names a fieldbus subdevice by its bus position; the configuration's name is
// added here, and for BOOT_FAILED the reason the bus did not come up.
std::string alarm_words(core::AlarmId id, const core::AlarmDetail& d) {
  std::array<char, 160> buf{};
  std::string s = limit_words(id, d, core::describe(id, d, buf.data(), buf.size()));
  const bool bus_alarm = id == core::AlarmId::FIELDBUS_LOST || id == core::AlarmId::BOOT_FAILED;
  if (!bus_alarm || d.signal != core::Signal::fieldbus) {
    return s;
  }
  if (id == core::AlarmId::BOOT_FAILED && g_bus.boot_error[0] != '\0') {
    return "Start-up failed: " + std::string(g_bus.boot_error.data());  // names position and name itself
  }
  // "subdevice N" in the core's words becomes "subdevice N (its configured name)".
  const unsigned pos = d.code & 0xFFU;
  const std::string key = "subdevice " + std::to_string(pos);
  const std::size_t at = s.find(key);
  if (pos >= 1U && pos <= g_bus.count && at != std::string::npos) {
    s.insert(at + key.size(), " (" + std::string(g_bus.name[pos - 1U].data()) + ")");
  }
  return s;
}

Json words_or_null(const core::Cause& c) {
  if (c.kind == core::CauseKind::alarm) {
    return alarm_words(c.alarm, c.detail);
  }
  std::array<char, 160> buf{};
  const char* s = core::describe(c, buf.data(), buf.size());
  return (s[0] == '\0') ? Json(nullptr) : Json(s);
}


template <std::size_t N>
Json rounded_array(const std::array<float, N>& v, std::size_t first, std::size_t count, double scale) {
  Json a = Json::array();
  for (std::size_t i = first; i < first + count; ++i) {
    a.push_back(rounded(static_cast<double>(v[i]), scale));
  }
  return a;
}

template <typename T, std::size_t N>
Json int_array(const std::array<T, N>& v) {
  Json a = Json::array();
  for (const T x : v) {
    a.push_back(x);
  }
  return a;
}

Json leaf_target(core::Leaf l) {
  return (l == core::Leaf::SAME) ? Json(nullptr) : Json(core::to_string(l));
}

Json alarm_object(core::AlarmId id, const core::AlarmDetail& d) {
  const core::AlarmInfo& info = core::alarm_info(id);
  Json j;
  j["name"] = info.name;
  j["number"] = info.number;
  j["severity"] = core::to_string(info.severity);
  j["text"] = info.text;
  j["remedy"] = info.remedy;
  j["detail"] = alarm_words(id, d);
  j["subject"] = alarm_subject(d);
  return j;
}

Json blackbox_cycle(const bridge::BlackBoxRecord& r) {
  Json j;
  j["t"] = r.t;
  j["state"] = core::to_string(static_cast<core::Leaf>(r.leaf));
  Json contacts;
  for (std::size_t i = 0; i < kContactNames.size(); ++i) {
    contacts[kContactNames[i]] = (r.contacts >> i) & 1U;
  }
  j["contacts"] = std::move(contacts);
  j["contactor_fb"] = r.contactor_fb;
  Json brakes = Json::array();
  for (unsigned i = 0; i < core::kAxes; ++i) {
    brakes.push_back((r.brakes_fb >> i) & 1U);
  }
  j["brakes_released"] = std::move(brakes);
  j["fieldbus_ok"] = r.fieldbus_ok;
  Json out;
  out["contactor"] = r.outputs & 1U;
  out["drives"] = (r.outputs >> 1U) & 1U;
  out["brakes_release"] = (r.outputs >> 2U) & 1U;
  out["reset_lamp"] = (r.outputs >> 3U) & 1U;
  j["outputs"] = std::move(out);
  j["statusword"] = int_array(r.statusword);
  j["controlword"] = int_array(r.controlword);
  j["position"] = rounded_array(r.position, 0, 6, 1e6);
  j["target"] = rounded_array(r.target, 0, 6, 1e6);
  return j;
}

// Prometheus float formatting.
std::string num(double v) {
  std::array<char, 32> b{};
  std::snprintf(b.data(), b.size(), "%.9g", v);
  return b.data();
}

void header(std::string& s, const char* name, const char* type, const char* help) {
  s += "# HELP ";
  s += name;
  s += ' ';
  s += help;
  s += "\n# TYPE ";
  s += name;
  s += ' ';
  s += type;
  s += '\n';
}

void scalar(std::string& s, const char* name, const char* type, const char* help, const std::string& value) {
  header(s, name, type, help);
  s += name;
  s += ' ';
  s += value;
  s += '\n';
}

// Bucket i of the bridge holds [2^i, 2^(i+1)) ns (bucket 0 also 0; the last bucket is
// open-ended): the cumulative bucket `le` 2^(i+1) ns counts buckets 0..i.
void histogram(std::string& s, const char* name, const char* help,
               const std::array<std::atomic<std::uint64_t>, bridge::kHistogramBuckets>& buckets) {
  header(s, name, "histogram", help);
  std::array<std::uint64_t, bridge::kHistogramBuckets> n{};
  for (std::size_t i = 0; i < n.size(); ++i) {
    n[i] = buckets[i].load(std::memory_order_relaxed);
  }
  std::uint64_t cumulative = 0;
  double sum_ns = 0.0;
  for (std::size_t i = 0; i < n.size(); ++i) {
    cumulative += n[i];
    const double lo = (i == 0) ? 0.0 : std::ldexp(1.0, static_cast<int>(i));
    const double hi = std::ldexp(1.0, static_cast<int>(i) + 1);
    sum_ns += static_cast<double>(n[i]) * ((i + 1 == n.size()) ? lo : (lo + hi) / 2.0);
    if (i + 1 < n.size()) {
      s += name;
      s += "_bucket{le=\"" + num(hi * 1e-9) + "\"} " + std::to_string(cumulative) + '\n';
    }
  }
  s += name;
  s += "_bucket{le=\"+Inf\"} " + std::to_string(cumulative) + '\n';
  s += name;
  s += "_sum " + num(sum_ns * 1e-9) + '\n';
  s += name;
  s += "_count " + std::to_string(cumulative) + '\n';
}

std::string u64(const std::atomic<std::uint64_t>& a) { return std::to_string(a.load(std::memory_order_relaxed)); }

}  // namespace

const char* owner_of(core::Mode mode, bool remote_connected, bool pendant_connected) noexcept {
  if (mode == core::Mode::T1 || mode == core::Mode::T2) {
    return "pendant";
  }
  if (mode == core::Mode::AUTO && remote_connected) {
    return "remote";
  }
  return pendant_connected ? "pendant" : nullptr;
}

void set_fieldbus(const bridge::BusInfo& bus) noexcept {
  g_bus = bus;
  g_bus.count = std::min<std::uint32_t>(g_bus.count, static_cast<std::uint32_t>(bridge::kBusNames));
  for (auto& n : g_bus.name) {
    n.back() = '\0';  // written by another process: never trusted to be terminated
  }
  g_bus.boot_error.back() = '\0';
}

bool set_safety(const bridge::SafetyInfo& info, std::string& error) {
  g_safety = SafetyView{};
  if (info.set != 1U) {
    error = "the core's segment holds no safety configuration";
    return false;
  }
  // Written by another process: never trusted to be terminated or in range.
  const std::size_t n = std::min<std::size_t>(info.canonical_len, info.canonical.size());
  const std::string text(info.canonical.data(), n);
  const safety::Result r = safety::parse_safety(text);
  if (!r.ok()) {
    error = "the safety configuration in the core's segment does not parse: " +
            (r.errors.empty() ? std::string("?") : r.errors.front().text());
    return false;
  }
  if (r.config->limits.checksum != info.checksum) {
    error = "the safety configuration in the core's segment has checksum " + r.config->checksum + ", the core runs " +
            hex8(info.checksum);
    return false;
  }
  SafetyView v;
  v.config = Json::parse(text, nullptr, false);
  if (v.config.is_discarded()) {
    error = "the safety configuration in the core's segment is not JSON";
    return false;
  }
  std::array<char, bridge::kSafetySourceChars> src = info.source;
  src.back() = '\0';
  v.source = src.data();
  v.name = r.config->name;
  v.checksum = r.config->checksum;
  v.limits = r.config->limits;
  v.ok = true;
  g_safety = std::move(v);
  return true;
}

Json safety_json() {
  if (!g_safety.ok) {
    return nullptr;
  }
  Json j;
  j["name"] = g_safety.name;
  j["checksum"] = g_safety.checksum;
  j["source"] = g_safety.source;
  j["validated"] = false;  // the caller fills it from the status
  j["confirmation"] = nullptr;
  j["config"] = g_safety.config;
  return j;
}

Json status_safety_json(const bridge::Status& s, const Json* brake_test_record) {
  Json j;
  j["checksum"] = hex8(s.safety.checksum);
  j["validated"] = s.safety.validated;
  j["reduced"] = s.safety.reduced;
  Json by = Json::array();
  if ((s.safety.reduced_by & core::kReducedByZone) != 0U) {
    by.push_back("zone");
  }
  if ((s.safety.reduced_by & core::kReducedByInput) != 0U) {
    by.push_back("input");
  }
  if ((s.safety.reduced_by & core::kReducedByField) != 0U) {
    by.push_back("field");
  }
  j["reduced_by"] = std::move(by);
  j["recovery"] = s.safety.recovery;
  j["speed_limit"] = rounded(static_cast<double>(s.safety.speed_limit_mm_s), 10.0);
  // SPEC §11: v_allowed and the separation used while SSM acts (collaborative and ssm on,
  // mode AUTO), else null; the fields as validated, whether or not they act.
  j["v_allowed"] = s.safety.ssm ? Json(rounded(static_cast<double>(s.safety.v_allowed_mm_s), 10.0)) : Json(nullptr);
  Json fields;
  fields["outer"] = s.safety.field_outer_interrupted ? "interrupted" : "clear";
  fields["inner"] = s.safety.field_inner_interrupted ? "interrupted" : "clear";
  j["fields"] = std::move(fields);
  j["separation_mm"] = s.safety.ssm ? Json(rounded(static_cast<double>(s.safety.separation_mm), 1.0)) : Json(nullptr);
  // @req BT-STATUS
  // SPEC §12: hours until the brake test is due (negative: overdue; null when no pass is on
  // record or none is required) and the latest result on record.
  Json brake;
  brake["due_in_h"] = s.brake_test.due_known ? Json(rounded(static_cast<double>(s.brake_test.due_in_h), 1000.0))
                                             : Json(nullptr);
  brake["last"] = core::to_string(s.brake_test.last);
  // After protocol.md's fields (additive): the test in progress (axis 1..6 and percent of
  // the whole test, 4 steps per axis, null while none runs), the BRAKE_TEST_DUE and
  // BRAKE_TEST_REQUIRED conditions, and the latest result on record in the event log (so
  // that it survives a restart): when, the axis that slipped, every axis' drift.
  brake["running"] = s.brake_test.running;
  brake["axis"] = (s.brake_test.running && s.brake_test.axis >= 1U && std::size_t{s.brake_test.axis} <= core::kAxes)
                      ? Json(s.brake_test.axis)
                      : Json(nullptr);
  brake["progress"] = s.brake_test.running ? Json(std::min<unsigned>(s.brake_test.progress, 100U)) : Json(nullptr);
  brake["due"] = s.brake_test.due;
  brake["required"] = s.brake_test.required;
  const bool record = (brake_test_record != nullptr) && brake_test_record->is_object();
  brake["last_time"] = record ? brake_test_record->at("time") : Json(nullptr);
  brake["last_axis"] = record ? brake_test_record->at("axis") : Json(nullptr);
  brake["drift_deg"] = record ? brake_test_record->at("drift_deg") : Json(nullptr);
  j["brake_test"] = std::move(brake);
  // SPEC §11 collision detection, after the fields of protocol.md: whether it acts
  // (collaborative and pfl on), the force estimated at the TCP (N, 0.1; null while it does
  // not act), and from the configuration the gateway holds the region's F_qs (the force
  // that is COLLISION) and the PFL speed cap v_pfl (null without pfl).
  j["pfl"] = s.safety.pfl;
  j["contact_force"] = s.safety.pfl ? Json(rounded(static_cast<double>(s.safety.contact_force_n), 10.0)) : Json(nullptr);
  const bool pfl_config = g_safety.ok && g_safety.limits.collaborative.enabled && g_safety.limits.collaborative.pfl_enabled;
  j["contact_force_limit"] =
      pfl_config ? Json(rounded(static_cast<double>(g_safety.limits.collaborative.f_qs_n), 10.0)) : Json(nullptr);
  j["pfl_speed_limit"] =
      pfl_config ? Json(rounded(static_cast<double>(g_safety.limits.collaborative.pfl_speed_mm_s), 10.0)) : Json(nullptr);
  return j;
}

Json brake_test_record(const std::string& time, const Json& data) {
  if (!data.is_object()) {
    return nullptr;
  }
  const auto result = data.find("result");
  const auto axis = data.find("axis");
  const auto drift = data.find("drift_deg");
  if (result == data.end() || !result->is_string() || (*result != "passed" && *result != "failed") ||
      axis == data.end() ||
      !(axis->is_null() || (axis->is_number_integer() && axis->get<std::int64_t>() >= 1 &&
                            axis->get<std::int64_t>() <= static_cast<std::int64_t>(core::kAxes))) ||
      drift == data.end() || !drift->is_array() || drift->size() != core::kAxes) {
    return nullptr;
  }
  for (const Json& d : *drift) {
    if (!d.is_number() || !std::isfinite(d.get<double>())) {
      return nullptr;
    }
  }
  Json j;
  j["time"] = time;
  j["result"] = *result;
  j["axis"] = *axis;
  j["drift_deg"] = *drift;
  return j;
}

std::string alarm_subject(const core::AlarmDetail& d) {
  std::array<char, 64> buf{};
  return core::limit_detail_name(d, g_safety.limits, buf.data(), buf.size());
}

Json status_json(const bridge::Status& s, const StatusExtras& x, bool with_type) {
  Json j;
  if (with_type) {
    j["type"] = "status";
  }
  j["t"] = s.t;
  j["state"] = core::to_string(s.state);
  j["sub"] = name_or_null(core::to_string(s.sub));
  j["mode"] = core::to_string(s.mode);
  j["stop"] = name_or_null(core::to_string(s.stop));
  j["contactor"] = s.contactor ? "closed" : "open";
  j["drives"] = s.drives ? "enabled" : "disabled";
  j["brakes"] = s.brakes_released ? "released" : "engaged";
  j["reset_lamp"] = s.reset_lamp ? "on" : "off";
  j["tcp_speed"] = rounded(static_cast<double>(s.tcp_speed_mm_s), 10.0);
  j["alarms"] = vocab::alarm_names(s.alarms);
  j["joints"] = rounded_array(s.joints, 0, 6, 1e6);
  Json tcp = rounded_array(s.tcp, 0, 3, 1e3);
  for (std::size_t i = 3; i < 6; ++i) {
    tcp.push_back(rounded(static_cast<double>(s.tcp[i]), 1e6));
  }
  j["tcp"] = std::move(tcp);
  j["t2_confirmed"] = s.t2_confirmed;
  j["owner"] = (x.owner == nullptr) ? Json(nullptr) : Json(x.owner);
  j["safety"] = status_safety_json(s, x.brake_test_record);
  // Beyond protocol.md (SPEC §7: requested beside effective, the first-out cause).
  j["mode_requested"] = core::to_string(s.mode_requested);
  j["target"] = leaf_target(s.target);
  j["cause"] = words_or_null(s.cause);
  j["arming_step"] = (s.state == core::State::ARMING) ? Json(core::to_string(s.arming_step)) : Json(nullptr);
  j["arming_progress"] = s.arming_progress;
  Json axes = Json::array();
  for (const std::uint8_t a : s.axis_state) {
    axes.push_back(motion::to_string(static_cast<motion::AxisState>(a)));
  }
  j["axis_state"] = std::move(axes);
  j["program_index"] = s.program_index;
  j["program_length"] = s.program_length;
  j["simulated"] = s.simulated || x.simulated;
  j["max_point_speed"] = rounded(static_cast<double>(s.max_point_speed_mm_s), 10.0);
  j["statusword"] = int_array(s.statusword);
  j["core_heartbeat"] = x.core_heartbeat;
  j["core_heartbeat_age_ms"] = rounded(x.core_heartbeat_age_ms, 10.0);
  j["gateway_heartbeat"] = x.gateway_heartbeat;
  j["core_pid"] = x.core_pid;
  j["gateway_pid"] = x.gateway_pid;
  j["shutting_down"] = x.shutting_down;
  j["gateway_restarts"] = x.gateway_restarts;
  j["sim"] = status_sim_json(s);
  j["channels"] = status_channels_json(s);
  Json k;
  k["k1"] = s.k1_closed ? "closed" : "open";
  k["k2"] = s.two_contactors ? Json(s.k2_closed ? "closed" : "open") : Json(nullptr);
  j["contactors"] = std::move(k);
  return j;
}

// @req CH-PAIR CH-PROCESSES
// SPEC §14: each channel's state, cycle, last digest and whether it agrees with the other
// (docs/two-channels.md "Two processes"). One entry with one channel.
Json status_channels_json(const bridge::Status& s) {
  Json a = Json::array();
  for (std::size_t i = 0; i < s.channels.size(); ++i) {
    const bridge::ChannelRecord& c = s.channels[i];
    if (c.present == 0U) {
      continue;
    }
    Json j;
    j["name"] = i == 0U ? "A" : "B";
    j["compiler"] = c.compiler == 1U ? Json("gcc") : c.compiler == 2U ? Json("clang") : Json(nullptr);
    j["pid"] = c.pid != 0U ? Json(c.pid) : Json(nullptr);
    j["running"] = c.running != 0U;
    j["answered"] = c.answered != 0U;
    j["state"] = core::to_string(c.state);
    j["cycle"] = c.cycle;
    j["digest"] = hex8(c.digest_crc);
    j["agree"] = c.agree != 0U;
    j["differs_in"] = c.field == core::CrossField::none ? Json(nullptr) : Json(core::to_string(c.field));
    j["missing"] = c.missing;
    j["late"] = c.late;
    j["skipped"] = c.skipped;
    j["wake_max_us"] = c.wake_max_us;
    j["exec_max_us"] = c.exec_max_us;
    a.push_back(std::move(j));
  }
  return a;
}

// @req COL-SIM-PERSON
Json status_sim_json(const bridge::Status& s) {
  if (!s.person_shown) {
    return nullptr;
  }
  Json fields;
  fields["outer_mm"] = rounded(static_cast<double>(s.person_outer_mm), 10.0);
  fields["inner_mm"] = rounded(static_cast<double>(s.person_inner_mm), 10.0);
  fields["scanner"] = s.person_scanner;
  fields["distance_sensor"] = s.person_distance_sensor;
  Json j;
  if (s.person_present) {
    Json p;
    p["x_mm"] = rounded(static_cast<double>(s.person_x_mm), 10.0);
    p["y_mm"] = rounded(static_cast<double>(s.person_y_mm), 10.0);
    p["radius_mm"] = rounded(static_cast<double>(s.person_radius_mm), 10.0);
    p["speed_mm_s"] = rounded(static_cast<double>(s.person_speed_mm_s), 10.0);
    p["walking"] = s.person_walking;
    p["in_outer"] = s.person_in_outer;
    p["in_inner"] = s.person_in_inner;
    p["separation_mm"] = rounded(static_cast<double>(s.person_separation_mm), 10.0);
    p["nearest_point"] = s.person_nearest_point;
    j["person"] = std::move(p);
  } else {
    j["person"] = nullptr;
  }
  j["person_fields"] = std::move(fields);
  return j;
}

Json alarms_json(const bridge::Status& s) {
  Json a = Json::array();
  for (const core::AlarmInfo& info : core::kAlarms) {
    if ((s.alarms & core::bit(info.id)) == 0U) {
      continue;
    }
    const auto i = static_cast<std::size_t>(info.id);
    Json j = alarm_object(info.id, s.alarm_detail[i]);
    j["since"] = s.alarm_since[i];
    a.push_back(std::move(j));
  }
  return a;
}

const char* kind_name(bridge::EventKind k) noexcept {
  switch (k) {
    case bridge::EventKind::transition: return "transition";
    case bridge::EventKind::alarm: return "alarm";
    case bridge::EventKind::alarm_cleared: return "alarm_cleared";
    case bridge::EventKind::brake_test: return "brake_test";
    case bridge::EventKind::command: break;
  }
  return "command";
}

Json event_data(const bridge::EventRecord& e, const std::string& name, const Json& client_seq) {
  Json j;
  switch (e.kind) {
    case bridge::EventKind::transition: {
      j["from"] = core::to_string(e.from);
      j["to"] = core::to_string(e.to);
      j["state"] = core::to_string(core::state_of(e.to));
      j["sub"] = name_or_null(core::to_string(core::sub_of(e.to)));
      j["stop"] = name_or_null(core::to_string(e.stop));
      j["trigger"] = core::to_string(static_cast<core::Trigger>(e.trigger));
      j["rule"] = (e.row < core::kTransitions.size()) ? Json(core::kTransitions[e.row].rule) : Json(nullptr);
      j["cause"] = words_or_null(e.cause);
      break;
    }
    case bridge::EventKind::alarm: j = alarm_object(e.alarm, e.detail); break;
    case bridge::EventKind::alarm_cleared: j["name"] = core::to_string(e.alarm); break;
    case bridge::EventKind::brake_test: {
      // SPEC §12: the result with each axis' drift (read again at start by run.cpp).
      j["result"] = core::to_string(static_cast<core::BrakeTestResult>(e.brake_result));
      j["axis"] = (e.brake_axis != 0U) ? Json(e.brake_axis) : Json(nullptr);
      Json drift = Json::array();
      for (const float d : e.brake_drift_deg) {
        drift.push_back(rounded(static_cast<double>(d), 1000.0));
      }
      j["drift_deg"] = std::move(drift);
      break;
    }
    case bridge::EventKind::command: {
      const bool known = e.reply.cmd < core::kCommandCount;
      j["cmd"] = known ? std::string(core::to_string(static_cast<core::CommandId>(e.reply.cmd)))
                       : (name.empty() ? "unknown" : name);
      j["from"] = (e.reply.source < core::kSourceCount) ? core::to_string(static_cast<core::Source>(e.reply.source))
                                                        : "?";
      j["result"] = core::to_string(e.reply.result);
      if (!client_seq.is_null()) {
        j["seq"] = client_seq;
      }
      break;
    }
  }
  return j;
}

bool needs_blackbox(const bridge::EventRecord& e) noexcept {
  return e.kind == bridge::EventKind::transition &&
         (e.stop != core::StopCat::NONE || e.to == core::Leaf::ESTOP_ACTIVE || e.to == core::Leaf::ERROR_LOCKOUT);
}

Json blackbox_json(const bridge::BlackBox& box, std::uint64_t t, std::size_t cycles) {
  const std::uint64_t first = (t + 1 >= cycles) ? t + 1 - cycles : 0;
  Json list = Json::array();
  std::uint64_t missing = 0;
  for (std::uint64_t c = first; c <= t; ++c) {
    bridge::BlackBoxRecord r{};
    if (box[c % bridge::kBlackBoxCycles].read(r) && r.t == c) {
      list.push_back(blackbox_cycle(r));
    } else {
      Json m;
      m["t"] = c;
      m["missing"] = true;
      list.push_back(std::move(m));
      ++missing;
    }
  }
  Json j;
  j["first"] = first;
  j["last"] = t;
  j["missing"] = missing;
  j["cycles"] = std::move(list);
  return j;
}

Json event_message(std::int64_t id, std::uint64_t t, const std::string& time, const char* kind, const Json& data) {
  Json j;
  j["type"] = "event";
  j["id"] = (id > 0) ? Json(id) : Json(nullptr);
  j["t"] = t;
  j["time"] = time;
  j["kind"] = kind;
  j["data"] = data;
  return j;
}

Json robot_json() {
  const motion::RobotModel& r = safestate::robot::active().model;
  Json j;
  j["name"] = r.name;
  j["reach"] = static_cast<double>(r.reach_mm);
  const auto vec = [](const std::array<float, 3>& v) { return rounded_array(v, 0, 3, 1e6); };
  const auto mat = [&](const motion::Mat3f& m) {
    Json rows = Json::array();
    for (const auto& row : m) {
      rows.push_back(vec(row));
    }
    return rows;
  };
  const safestate::robot::Robot& rb = safestate::robot::active();
  Json joints = Json::array();
  for (std::size_t k = 0; k < motion::kJoints; ++k) {
    Json o;
    o["name"] = rb.d.joints[k].name;
    o["link"] = rb.d.joints[k].child;
    o["origin"] = vec(r.joints[k].origin.xyz_mm);
    o["rotation"] = mat(r.joints[k].origin.R);
    o["axis"] = vec(r.joints[k].axis);
    joints.push_back(std::move(o));
  }
  j["convention"] =
      "URDF chain: joint k's frame at origin (mm) turned by rotation (rows) in joint k-1's frame, turning about axis "
      "(its own frame); flange in joint 6's frame";
  j["base"] = rb.d.base;
  j["flange_link"] = rb.d.flange;
  j["source"] = rb.d.source;
  j["urdf"] = rb.d.urdf;  // the description itself, for a viewer that draws the URDF
  j["parameters_checksum"] =
      safety::checksum_text(safety::jcs::canonicalize(Json::parse(safestate::robot::canonical_parameters(rb))).value_or(""));
  j["joints"] = std::move(joints);
  Json flange;
  flange["origin"] = vec(r.flange.xyz_mm);
  flange["rotation"] = mat(r.flange.R);
  j["flange"] = std::move(flange);
  Json limits = Json::array();
  for (std::size_t i = 0; i < motion::kJoints; ++i) {
    Json l;
    l["min"] = rounded(static_cast<double>(r.q_min_rad[i]), 1e6);
    l["max"] = rounded(static_cast<double>(r.q_max_rad[i]), 1e6);
    limits.push_back(std::move(l));
  }
  j["joint_limits"] = std::move(limits);
  j["velocity_limits"] = rounded_array(r.qd_max_rad_s, 0, motion::kJoints, 1e6);
  j["acceleration_limits"] = rounded_array(r.qdd_max_rad_s2, 0, motion::kJoints, 1e6);
  Json links = Json::array();
  for (const char* n : r.link_names) {
    links.push_back(n);
  }
  j["link_names"] = std::move(links);
  j["tcp_offset"] = rounded_array(r.tcp_offset_mm, 0, 3, 1e6);
  Json units;
  units["length"] = "mm";
  units["angle"] = "rad";
  units["velocity"] = "rad/s";
  units["acceleration"] = "rad/s^2";
  j["units"] = std::move(units);
  return j;
}

std::string metrics_text(const bridge::Metrics& m, const MetricsExtras& x) {
  std::string s;
  s.reserve(8192);
  histogram(s, "safestate_cycle_exec_seconds", "Execution time of one scan cycle.", m.exec_ns);
  histogram(s, "safestate_cycle_lateness_seconds", "Wake-up lateness of the scan cycle.", m.lateness_ns);
  scalar(s, "safestate_cycle_exec_max_seconds", "gauge", "Longest scan cycle execution seen.",
         num(static_cast<double>(m.exec_max_ns.load(std::memory_order_relaxed)) * 1e-9));
  scalar(s, "safestate_cycle_lateness_max_seconds", "gauge", "Largest wake-up lateness seen.",
         num(static_cast<double>(m.lateness_max_ns.load(std::memory_order_relaxed)) * 1e-9));
  scalar(s, "safestate_cycles_total", "counter", "Scan cycles run.", u64(m.cycles));
  scalar(s, "safestate_overruns_total", "counter", "Scan cycles that overran their period.", u64(m.overruns));
  scalar(s, "safestate_watchdog_trips_total", "counter", "Watchdog trips.", u64(m.watchdog_trips));
  scalar(s, "safestate_fieldbus_stale_cycles_total", "counter",
         "Scan cycles whose fieldbus frame was late or lost (inputs held from the last answered frame).",
         u64(m.fieldbus_stale_cycles));
  scalar(s, "safestate_events_dropped_total", "counter", "Events dropped because the event ring was full.",
         u64(m.events_dropped));
  scalar(s, "safestate_replies_dropped_total", "counter", "Replies dropped because the reply ring was full.",
         u64(m.replies_dropped));
  scalar(s, "safestate_command_queue_depth", "gauge", "Commands waiting in the core's queue.",
         std::to_string(m.command_queue_depth.load(std::memory_order_relaxed)));
  scalar(s, "safestate_cycle_period_seconds", "gauge", "Configured scan cycle period.",
         num(static_cast<double>(m.cycle_us.load(std::memory_order_relaxed)) * 1e-6));
  scalar(s, "safestate_rt_priority", "gauge", "SCHED_FIFO priority of the cycle thread (0: not real-time).",
         std::to_string(m.rt_priority.load(std::memory_order_relaxed)));
  scalar(s, "safestate_ws_clients", "gauge", "Connected WebSocket clients.", std::to_string(x.ws_clients));
  scalar(s, "safestate_core_heartbeat", "gauge", "The core's cycle counter as seen by the gateway.",
         std::to_string(x.core_heartbeat));
  scalar(s, "safestate_events_stored_total", "counter", "Events stored in the event log by this gateway.",
         std::to_string(x.events_stored));
  header(s, "safestate_commands_total", "counter", "Command replies sent by this gateway, by result.");
  for (std::size_t i = 0; i < core::kResultCount; ++i) {
    s += "safestate_commands_total{result=\"";
    s += core::to_string(static_cast<core::Result>(i));
    s += "\"} " + std::to_string(x.commands_by_result[i]) + '\n';
  }
  const ConnectionFigures& c = x.connections;
  if (!c.known) {
    return s;
  }
  const auto z = [](std::size_t v) { return std::to_string(v); };
  scalar(s, "safestate_gateway_fd_limit", "gauge", "The gateway's RLIMIT_NOFILE (soft, raised to the hard limit at start).",
         z(c.fd_limit));
  scalar(s, "safestate_gateway_connections", "gauge", "Client connections held, of every kind.", z(c.open));
  scalar(s, "safestate_gateway_connections_max", "gauge",
         "Bound on client connections (the descriptor limit less the gateway's own).", z(c.open_max));
  scalar(s, "safestate_gateway_http_waiting", "gauge", "HTTP connections waiting for a request head.", z(c.waiting));
  scalar(s, "safestate_gateway_http_waiting_max", "gauge",
         "Bound on HTTP connections waiting for a request head, all peers (the oldest silent one gives way).",
         z(c.waiting_max));
  scalar(s, "safestate_gateway_http_waiting_peer_peak", "gauge",
         "HTTP connections waiting for a request head from the peer address with the most of them.",
         z(c.waiting_peer_peak));
  scalar(s, "safestate_gateway_http_waiting_per_peer_max", "gauge",
         "Bound on HTTP connections waiting for a request head from one peer address.", z(c.waiting_per_peer_max));
  scalar(s, "safestate_gateway_http_in_service", "gauge", "HTTP requests being answered or upgraded.",
         z(c.in_service));
  scalar(s, "safestate_gateway_http_in_service_max", "gauge", "Bound on HTTP requests in service (--max-http).",
         z(c.in_service_max));
  scalar(s, "safestate_gateway_http_service_queue", "gauge", "Complete HTTP requests waiting for a service slot.",
         z(c.service_queue));
  scalar(s, "safestate_gateway_first_head_limit_seconds", "gauge",
         "A new connection's first request head must be complete within this (else 408).", num(c.first_head_limit_s));
  scalar(s, "safestate_gateway_keep_alive_limit_seconds", "gauge",
         "A kept-alive connection's next request head must be complete within this.", num(c.keep_alive_limit_s));
  scalar(s, "safestate_gateway_shed_total", "counter",
         "Silent connections waiting for a request head that gave way to a newcomer (answered 503).",
         std::to_string(c.shed_total));
  scalar(s, "safestate_gateway_head_timeouts_total", "counter",
         "Connections closed because their request head was not complete in time (answered 408).",
         std::to_string(c.head_timeouts_total));
  scalar(s, "safestate_gateway_refused_total", "counter",
         "Newcomers and requests answered 503 for lack of room (nobody silent to give way, no service slot).",
         std::to_string(c.refused_total));
  scalar(s, "safestate_gateway_accept_paused_total", "counter",
         "Times the listener waited for room or a descriptor before accepting again.",
         std::to_string(c.accept_paused_total));
  return s;
}

std::string iso8601_utc(std::chrono::system_clock::time_point tp) {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(tp.time_since_epoch()).count();
  const auto secs = static_cast<std::time_t>(ms / 1000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  std::array<char, 96> b{};
  std::snprintf(b.data(), b.size(), "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1,
                tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms % 1000));
  return b.data();
}

std::string dump(const Json& j) { return j.dump(-1, ' ', false, Json::error_handler_t::replace); }

}  // namespace safestate::gateway

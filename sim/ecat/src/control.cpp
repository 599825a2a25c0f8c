// The control channel of the emulated segment. Everything from outside is validated:
// a bad line is answered with an error naming what is wrong, and changes nothing.
#include <nlohmann/json.hpp>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <array>
#include <string>
#include <string_view>

#include "safestate/ecat/ecat_sim.hpp"
#include "safestate/vocab/faults.hpp"
#include "safestate/vocab/inputs.hpp"
#include "safestate/vocab/person.hpp"

namespace safestate::ecat {

namespace {

bool parse_count(std::string_view s, std::uint32_t lo, std::uint32_t hi, std::uint32_t& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc{} && r.ptr == s.data() + s.size() && v >= lo && v <= hi;
}

// Wire faults, beyond the in-process cell's vocabulary.
std::string wire_fault(EmulatedCell& cell, std::string_view what, std::string_view arg, bool& handled) {
  handled = true;
  std::uint32_t n = 0;
  if (what == "replug" && arg.empty()) {
    cell.segment().cut_before(0);
    return "OK";
  }
  if (what == "unplug") {
    if (!parse_count(arg, 1, static_cast<std::uint32_t>(cell.segment().size()), n)) {
      return "ERROR unplug needs a subdevice position 1.." + std::to_string(cell.segment().size());
    }
    cell.segment().cut_before(n);
    return "OK";
  }
  if (what == "no-pd") {
    if (!parse_count(arg, 1, static_cast<std::uint32_t>(cell.segment().size()), n)) {
      return "ERROR no-pd needs a subdevice position 1.." + std::to_string(cell.segment().size());
    }
    cell.segment().ignore_process_data(n);
    return "OK";
  }
  if (what == "lose-every") {
    if (!parse_count(arg, 0, 1000000, n)) {
      return "ERROR lose-every needs a frame count 0..1000000 (0 = off)";
    }
    cell.segment().lose_every(n);
    return "OK";
  }
  if (what == "drop" || what == "corrupt") {
    if (!parse_count(arg, 1, 1000000, n)) {
      return "ERROR " + std::string(what) + " needs a frame count 1..1000000";
    }
    (what == "drop") ? cell.segment().drop_frames(n) : cell.segment().corrupt_frames(n);
    return "OK";
  }
  handled = false;
  return {};
}

// A 16/32-bit number, decimal or 0x hex, the whole word.
bool parse_hex(std::string_view s, std::uint32_t hi, std::uint32_t& v) {
  const bool hex = s.size() > 2U && s[0] == '0' && (s[1] == 'x' || s[1] == 'X');
  const std::string_view digits = hex ? s.substr(2) : s;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), v, hex ? 16 : 10);
  return !digits.empty() && r.ec == std::errc{} && r.ptr == digits.data() + digits.size() && v <= hi;
}

// `fault sdo-refuse POS INDEX:SUB ABORT`: the drive at POS (1-based) refuses every SDO
// download to INDEX:SUB with the abort code ABORT (a test of the master's start-up list);
// `fault sdo-refuse POS off` takes it back, as does `fault clear_all`.
std::string sdo_refuse_line(EmulatedCell& cell, const std::string& line) {
  std::istringstream words(line);
  std::string verb, what, pos, object, code, extra;
  words >> verb >> what >> pos >> object >> code >> extra;
  std::uint32_t p = 0;
  const auto n = static_cast<std::uint32_t>(cell.segment().size());
  if (!parse_count(pos, 1, n, p)) {
    return "ERROR sdo-refuse needs a subdevice position 1.." + std::to_string(n);
  }
  coe::Dictionary& od = cell.segment().esc(p - 1U).dictionary();
  if (od.empty()) {
    return "ERROR subdevice " + pos + " has no CoE mailbox (only the drives have one)";
  }
  if (object == "off" && code.empty()) {
    od.refuse(0, 0, 0);
    return "OK";
  }
  const std::size_t colon = object.find(':');
  std::uint32_t index = 0;
  std::uint32_t sub = 0;
  std::uint32_t code_value = 0;
  if (colon == std::string::npos || !parse_hex(std::string_view(object).substr(0, colon), 0xFFFF, index) ||
      !parse_hex(std::string_view(object).substr(colon + 1U), 0xFF, sub)) {
    return "ERROR sdo-refuse needs an object INDEX:SUB (e.g. 0x6072:0), got '" + object + "'";
  }
  if (!parse_hex(code, 0xFFFFFFFFU, code_value) || code_value == 0U || !extra.empty()) {
    return "ERROR sdo-refuse needs a non-zero abort code (e.g. 0x06090030) and nothing after it";
  }
  od.refuse(static_cast<std::uint16_t>(index), static_cast<std::uint8_t>(sub), code_value);
  return "OK";
}

// `tool KG X Y Z`: the payload (0..100 kg) at the TCP (tool0 frame, |mm| <= 2000) the emulated
// arm carries, so that its drives' torque (0x6077) is that of the arm the safety
// configuration declares (`safestate replay --fieldbus ethercat` sends it at start).
std::string tool_line(EmulatedCell& cell, const std::string& line) {
  std::istringstream words(line.substr(5));
  double kg = 0.0;
  std::array<double, 3> mm{};
  std::string extra;
  if (!(words >> kg >> mm[0] >> mm[1] >> mm[2]) || (words >> extra)) {
    return "ERROR tool needs four numbers: KG X Y Z (payload kg, TCP in tool0 mm)";
  }
  if (!(kg >= 0.0 && kg <= 100.0)) {
    return "ERROR tool payload must be 0..100 kg";
  }
  std::array<float, 3> tcp{};
  for (std::size_t i = 0; i < 3U; ++i) {
    if (!(mm[i] >= -2000.0 && mm[i] <= 2000.0)) {
      return "ERROR tool TCP coordinates must be -2000..2000 mm";
    }
    tcp[i] = static_cast<float>(mm[i]);
  }
  cell.set_tool(static_cast<float>(kg), tcp);
  return "OK";
}

// `time STOP from=WHAT` arms a response-time measurement on the wire; `time off` disarms it.
std::string time_line(EmulatedCell& cell, const std::string& words) {
  if (words == "off") {
    cell.wire_timing().disarm();
    return "OK";
  }
  WireTiming::Spec s{};
  const std::string err = WireTiming::parse(words, s);
  if (!err.empty()) {
    return "ERROR " + err;
  }
  cell.wire_timing().arm(s);
  return "OK";
}

// @req COL-SIM-PERSON
// `person at X Y [radius=R]`, `person walk X Y SPEED [stand MS] ...`, `person stand`, `person
// leave` (the scenario format's keys, docs/collaborative.md) and `config person_fields=OUTER,INNER`:
// the simulated person behind the segment, in the vocabulary's words (vocab/person.hpp); the
// words are checked there, whether a person is there to walk by the person itself.
std::string person_line(EmulatedCell& cell, const std::string& line) {
  const vocab::Tokens words = vocab::split_words(line);
  if (!words.empty() && words[0] == "config") {
    std::string_view key;
    std::string_view value;
    if (words.size() != 2U || !vocab::split_pair(words[1], key, value) || key != "person_fields") {
      return "ERROR only config person_fields=OUTER,INNER changes the emulated cell";
    }
    sim::PersonSensors sensors = cell.person_sensors();
    if (const std::string p = vocab::parse_person_fields(value, sensors); !p.empty()) {
      return "ERROR " + p;
    }
    if (!cell.set_person_sensors(sensors)) {
      return "ERROR the emulated cell refused the fields";
    }
    cell.latch_inputs();
    return "OK";
  }
  vocab::PersonStep step;
  bool present = true;  // the words alone; the person itself says whether it is there
  if (const std::string p = vocab::parse_person(vocab::Tokens(words.begin() + 1, words.end()), step, present); !p.empty()) {
    return "ERROR " + p;
  }
  sim::Person& person = cell.person();
  bool took = true;
  switch (step.action) {
    case vocab::PersonStep::Action::at: took = person.place(step.x_mm, step.y_mm, step.radius_mm); break;
    case vocab::PersonStep::Action::walk: took = person.walk(step.path.data(), step.path.size()); break;
    case vocab::PersonStep::Action::stand: took = person.present(); person.stand(); break;
    case vocab::PersonStep::Action::leave: took = person.present(); person.leave(); break;
  }
  if (!took) {
    return "ERROR the person cannot do that (none in the cell, or refused)";
  }
  cell.latch_inputs();
  return "OK";
}

// `freeze MS`: from now, for MS ms (1..1000), no frame reaches the segment; the frames sent
// meanwhile reach it when the freeze ends, in order (a host stall of the master as the wire
// sees it). Its clocks, SYNC0 pulses, watchdogs and the plant run on. `freeze MS at-op`: the
// same from the first frame that exchanges process data with a subdevice in OP (the master's
// boot wait after its OP request), which goes unanswered. For tests; `fault clear all` takes
// it back.
std::string freeze_line(EmulatedCell& cell, const std::string& line) {
  std::istringstream words(line);
  std::string verb, ms, when, extra;
  words >> verb >> ms >> when >> extra;
  std::uint32_t n = 0;
  if (verb != "freeze" || !parse_count(ms, 1, 1000, n) || !(when.empty() || when == "at-op") || !extra.empty()) {
    return "ERROR freeze needs MS (1..1000) and optionally at-op, got '" + line + "'";
  }
  const std::uint64_t ns = std::uint64_t{n} * 1000000U;
  if (when.empty()) {
    cell.segment().freeze(cell.now(), ns);
  } else {
    cell.segment().freeze_at_op(ns);
  }
  return "OK";
}

// `in KEY=VALUE ...` and `fault ...` lines in the vocabulary's words (vocab/inputs.hpp,
// vocab/faults.hpp: the scenario format's, every fault of it; the socket is local).
std::string world_line(EmulatedCell& cell, const std::string& line) {
  const vocab::Tokens words = vocab::split_words(line);
  const vocab::Tokens args(words.begin() + (words.empty() ? 0 : 1), words.end());
  if (!words.empty() && words[0] == "in") {
    vocab::InputStep in;
    if (const std::string p = vocab::parse_inputs(args, in); !p.empty()) {
      return "ERROR " + p;
    }
    // SPEC §11's distance sensor is a subdevice of its own (kPosDistance): a segment built
    // without it refuses a separation rather than take it and never put it on the wire.
    if ((in.separation_mm || in.separation_valid) && cell.distance_position() >= cell.segment().size()) {
      return "ERROR this emulated segment has no distance sensor (separation_mm, separation_valid)";
    }
    vocab::apply(in, cell.inputs());
    cell.latch_inputs();
    cell.mark_input_change();
    return "OK";
  }
  if (!words.empty() && words[0] == "fault") {
    vocab::Fault f{};
    if (const std::string p = vocab::parse_fault(args, f); !p.empty()) {
      return "ERROR " + p;
    }
    // SPEC §14: a channel's own faults are in the controller's processes, not on the segment
    // (on `safestate run` they come from outside, as signals: docs/two-channels.md).
    using K = vocab::FaultKind;
    if (f.kind == K::channel_stall || f.kind == K::channel_crash || f.kind == K::channel_input ||
        f.kind == K::digest_corrupt || f.kind == K::digest_drop || f.kind == K::digest_repeat ||
        f.kind == K::channel_flip) {
      return "ERROR fault \"" + vocab::format_fault(f) +
             "\" is a channel's, not the emulated segment's (stop or kill a channel's process from outside: "
             "docs/two-channels.md)";
    }
    // On a real bus "fieldbus lost" is the wire going silent, not a flag: the master must
    // find out by itself (the drives' own bus watchdogs react as in the plant).
    if (f.kind == vocab::FaultKind::fieldbus_lost) {
      cell.segment().go_silent();
    } else if (f.kind == vocab::FaultKind::clear_all) {
      cell.segment().clear_wire_faults();
      cell.links().clear_faults();
      for (std::size_t i = 0; i < cell.segment().size(); ++i) {
        cell.segment().esc(i).dictionary().refuse(0, 0, 0);
      }
    }
    cell.inject(f);
    cell.latch_inputs();
    return "OK";
  }
  return "ERROR only in and fault lines change the emulated cell";
}

// {"type":"sim","set":{...}} / {"fault":"..."} as the gateway's protocol writes them.
std::string json_line(EmulatedCell& cell, const std::string& line) {
  const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    return "ERROR not a JSON object";
  }
  if (const auto f = j.find("fault"); f != j.end()) {
    return f->is_string() ? control_line(cell, "fault " + f->get<std::string>()) : "ERROR \"fault\" must be a string";
  }
  const auto set = j.find("set");
  if (set == j.end() || !set->is_object() || set->empty()) {
    return "ERROR expected \"set\" (a non-empty object) or \"fault\"";
  }
  std::string in = "in";
  for (const auto& [k, v] : set->items()) {
    if (v.is_number_integer()) {
      in += " " + k + "=" + std::to_string(v.get<long long>());
    } else if (v.is_string()) {
      in += " " + k + "=" + v.get<std::string>();
    } else {
      return "ERROR value of \"" + k + "\" must be a number or a string";
    }
  }
  return world_line(cell, in);
}

// Distributed clocks, per subdevice (docs/ethercat.md, "Distributed clocks"): the SYNC0
// registers as the master left them, and for each subdevice whose SYNC0 runs its sync error
// (its system time minus the reference clock's at this instant, ns) and the figures since
// SYNC0 started or the last `dc reset`.
nlohmann::json dc_status(EmulatedCell& cell) {
  Segment& seg = cell.segment();
  const std::uint64_t now = cell.now();
  nlohmann::json dc;
  dc["reference"] = seg.dc_reference() < seg.size() ? nlohmann::json(seg.dc_reference() + 1U) : nlohmann::json(nullptr);
  nlohmann::json drift = nlohmann::json::array();
  nlohmann::json active = nlohmann::json::array();
  nlohmann::json cycle = nlohmann::json::array();
  nlohmann::json err = nlohmann::json::array();
  nlohmann::json stats = nlohmann::json::array();
  for (std::size_t i = 0; i < seg.size(); ++i) {
    Esc& e = seg.esc(i);
    const bool connected = i < seg.connected();
    const bool running = connected && e.sync0_running(now);
    drift.push_back(e.drift_ppm());
    active.push_back(running);
    cycle.push_back(e.sync0_cycle_ns());
    err.push_back(running ? nlohmann::json(seg.sync_error_ns(i, now)) : nlohmann::json(nullptr));
    const DcStats& s = e.dc_stats();
    if (s.samples == 0U && s.latched == 0U) {
      stats.push_back(nullptr);
      continue;
    }
    stats.push_back({{"samples", s.samples},
                     {"p99_ns", s.percentile_ns(0.99)},
                     {"max_ns", s.max_abs_ns},
                     {"max_age_ms", now > s.max_at_ns ? static_cast<double>(now - s.max_at_ns) * 1e-6 : 0.0},
                     {"max_input_gap_us", static_cast<double>(s.max_input_gap_ns) * 1e-3},
                     {"loop", {{"delay_ns", e.dc_delay_ns()},
                               {"diff_ns", e.dc_last_diff_ns()},
                               {"rate_ppm", std::round(e.rate_correction_ppm() * 1000.0) / 1000.0},
                               {"slew_left_ns", std::round(e.dc_slew_left_ns())},
                               {"input_gap_us", static_cast<double>(e.dc_input_gap_ns(now)) * 1e-3}}},
                     {"latched", s.latched},
                     {"overwritten", s.overwritten},
                     {"missed", s.missed},
                     {"lead_ns", s.last_lead_ns},
                     {"min_lead_ns", s.min_lead_ns}});
  }
  dc["drift_ppm"] = drift;
  dc["sync0_active"] = active;
  dc["sync0_cycle_ns"] = cycle;
  dc["sync_error_ns"] = err;
  dc["stats"] = stats;
  return dc;
}

double tenth(float v) { return std::round(static_cast<double>(v) * 10.0) / 10.0; }

std::string status(EmulatedCell& cell) {
  nlohmann::json j;
  const hal::ProcessImageOut& o = cell.last_outputs();
  const hal::ProcessImageIn& in = cell.last_inputs();
  j["cycles"] = cell.cycles();
  j["exchanges"] = cell.exchanges();
  // How the plant is stepped (cell.hpp): the pacing asked for, whether SYNC0 paces it now, and
  // what started its cycles so far.
  const EmulatedCell::Steps& st = cell.steps();
  j["plant"] = {{"pacing", cell.pacing() == EmulatedCell::Pacing::paced ? "paced" : "lockstep"},
                {"sync0_paced", cell.paced_by_sync0()},
                {"steps", {{"exchange", st.exchange}, {"sync0", st.sync0}, {"free", st.free}}},
                {"extrapolated", st.extrapolated},
                {"held", st.held},
                {"multi_step", st.multi_step},
                {"max_point_speed_mm_s", tenth(cell.max_point_speed_mm_s())},
                {"max_point_speed_multi_step_mm_s", tenth(cell.max_point_speed_multi_step_mm_s())},
                {"max_point_speed_one_step_mm_s", tenth(cell.max_point_speed_one_step_mm_s())}};
  j["frames"] = cell.segment().frames();
  j["lost_replies"] = cell.segment().lost_replies();
  // How late this process answered (Segment::Answers): a host stall shows here, not a fault.
  const Segment::Answers& an = cell.segment().answers();
  j["answers"] = {{"count", an.count},
                  {"max_delay_us", static_cast<double>(an.max_delay_ns / 100U) * 0.1},
                  {"max_age_ms", an.max_at_ns != 0U && cell.now() > an.max_at_ns
                                     ? static_cast<double>((cell.now() - an.max_at_ns) / 100000U) * 0.1
                                     : 0.0},
                  {"late_1ms", an.late_1ms}};
  j["connected"] = cell.segment().connected();
  nlohmann::json al = nlohmann::json::array();
  for (std::size_t i = 0; i < cell.segment().size(); ++i) {
    al.push_back(static_cast<int>(cell.segment().esc(i).state()));
  }
  j["al_state"] = al;
  // Each subdevice's process-data watchdog as its registers hold it (0x0400 divider x
  // 0x0420 time): what the master wrote at start-up (100000 us, the ESC default, if nothing).
  nlohmann::json wd = nlohmann::json::array();
  for (std::size_t i = 0; i < cell.segment().size(); ++i) {
    wd.push_back(cell.segment().esc(i).watchdog_ns() / 1000U);
  }
  j["watchdog_us"] = wd;
  // How often each one's process-data watchdog expired (0x0442), and the freezes so far.
  nlohmann::json expired = nlohmann::json::array();
  for (std::size_t i = 0; i < cell.segment().size(); ++i) {
    expired.push_back(cell.segment().esc(i).watchdog_expiries());
  }
  j["watchdog_expired"] = expired;
  j["freezes"] = cell.segment().freezes();
  // The writable CoE objects of each subdevice with a mailbox ("6060:00": 8, ...; null for
  // the I/O terminals): what the master's start-up list left there.
  nlohmann::json sdo = nlohmann::json::array();
  for (std::size_t i = 0; i < cell.segment().size(); ++i) {
    const coe::Dictionary& od = cell.segment().esc(i).dictionary();
    if (od.empty()) {
      sdo.push_back(nullptr);
      continue;
    }
    nlohmann::json objects = nlohmann::json::object();
    for (const coe::Entry& e : od.entries()) {
      if (e.access != coe::Access::ro) {  // the value SDO left (a PDO-mapped one follows the PDO in OP)
        char key[16];
        std::snprintf(key, sizeof key, "%04X:%02X", static_cast<unsigned>(e.index), static_cast<unsigned>(e.sub));
        objects[key] = e.as_int();
      }
    }
    sdo.push_back(objects);
  }
  j["sdo"] = sdo;
  j["dc"] = dc_status(cell);
  const EmulatedCell::OutputDrop& d = cell.output_drop();
  j["output_drop"] = {{"contactor_us", d.contactor ? nlohmann::json(d.contactor_ns / 1000U) : nlohmann::json(nullptr)},
                      {"enable_us", d.enable ? nlohmann::json(d.enable_ns / 1000U) : nlohmann::json(nullptr)}};
  j["contactor"] = o.contactor;
  j["contactor_k2"] = o.contactor_k2;
  j["brakes_release"] = o.brakes_release;
  j["reset_lamp"] = o.reset_lamp;
  j["reduced_active"] = o.reduced_active;
  // What the distance sensor reports (its TxPDO): mm and whether valid.
  j["separation_mm"] = in.safety.separation_mm;
  j["separation_valid"] = in.safety.separation_valid;
  const sim::PersonView& pv = cell.person_view();
  j["person"] = pv.present ? nlohmann::json{{"x_mm", pv.x_mm}, {"y_mm", pv.y_mm}, {"walking", pv.walking},
                                            {"separation_mm", pv.separation_mm}}
                           : nlohmann::json(nullptr);
  nlohmann::json cw = nlohmann::json::array();
  nlohmann::json sw = nlohmann::json::array();
  nlohmann::json q = nlohmann::json::array();
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    cw.push_back(o.drive[a].controlword);
    sw.push_back(in.drive[a].statusword);
    q.push_back(in.drive[a].position_rad);
  }
  j["controlword"] = cw;
  j["statusword"] = sw;
  j["joints"] = q;
  j["contactor_closed"] = in.contactor_closed;
  j["k2_closed"] = in.k2_closed;  // SPEC §14: K2's auxiliary contact
  const EmulatedCell::Reaction& r = cell.reaction();
  if (r.cleared) {
    // us: from the exchange that carried the changed contact to the master to the one that
    // brought the contactor bit back cleared; from_change_us adds the wait for that first
    // exchange (up to one cycle after the contact changed).
    j["reaction"] = {{"cycles", r.cleared_cycle - r.input_cycle},
                     {"us", (r.cleared_ns - r.input_ns) / 1000U},
                     {"from_change_us", (r.cleared_ns - r.change_ns) / 1000U},
                     {"input_exchange", r.input_cycle},
                     {"cleared_exchange", r.cleared_cycle}};
  } else {
    j["reaction"] = nullptr;
  }
  j["wire_timing"] = cell.wire_timing().to_json(in);
  // Issue 37: each safety connection's device end, the F-DO's outputs as driven, and the time
  // from the last link fault's first affected frame to the F-DO's outputs opening.
  j["safety"] = cell.links().status();
  return j.dump();
}

}  // namespace

std::string control_line(EmulatedCell& cell, const std::string& raw) {
  std::string line = raw;
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) {
    line.pop_back();
  }
  if (line.size() > 4096U) {
    return "ERROR line too long";
  }
  if (line == "status") {
    return status(cell);
  }
  if (line == "dc reset") {  // the DC figures start again (the bench measures from here)
    for (std::size_t i = 0; i < cell.segment().size(); ++i) {
      DcStats& s = cell.segment().esc(i).dc_stats();
      s = DcStats{};
    }
    return "OK";
  }
  if (!line.empty() && line.front() == '{') {
    return json_line(cell, line);
  }
  if (line.rfind("fault link ", 0) == 0 || line == "fault link") {  // issue 37: a container on the wire
    return cell.link_fault(line.size() > 11U ? line.substr(11) : std::string());
  }
  if (line.rfind("fault sdo-refuse", 0) == 0) {
    return sdo_refuse_line(cell, line);
  }
  if (line.rfind("tool ", 0) == 0) {
    return tool_line(cell, line);
  }
  if (line.rfind("person ", 0) == 0 || line.rfind("config person_fields=", 0) == 0) {
    return person_line(cell, line);
  }
  if (line == "plant lockstep" || line == "plant paced") {  // EmulatedCell::Pacing
    cell.set_pacing(line == "plant paced" ? EmulatedCell::Pacing::paced : EmulatedCell::Pacing::lockstep);
    return "OK";
  }
  if (line == "plant reset") {  // the step counts and the peak speed start again
    cell.reset_steps();
    return "OK";
  }
  if (line.rfind("plant", 0) == 0) {
    return "ERROR plant needs lockstep, paced or reset, got '" + line + "'";
  }
  if (line.rfind("freeze", 0) == 0) {  // a host stall as the segment sees it (segment.hpp)
    return freeze_line(cell, line);
  }
  if (line.rfind("time ", 0) == 0) {  // arm a response-time measurement (wire_timing.hpp)
    return time_line(cell, line.substr(5));
  }
  std::istringstream words(line);
  std::string verb, what, arg, extra;
  words >> verb >> what >> arg >> extra;
  if (verb == "fault" && extra.empty()) {
    bool handled = false;
    std::string r = wire_fault(cell, what, arg, handled);
    if (handled) {
      return r;
    }
  }
  if (verb == "in" || verb == "fault") {
    return world_line(cell, line);
  }
  return "ERROR unknown line (expected in ..., fault ..., person ..., config person_fields=, tool KG X Y Z, plant "
         "lockstep|paced|reset, time ..., freeze MS [at-op], status, dc reset, or a JSON sim message)";
}

}  // namespace safestate::ecat

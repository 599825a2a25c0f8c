// The bus configuration file: which subdevices, in which order, with which identity and
// PDO layout. Everything is checked before the bus is touched, and an error names the
// field (IEC 62443: input from outside is validated).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

#include "safestate/hal/ethercat.hpp"
#include "safestate/safelink/container.hpp"

namespace safestate::hal::ethercat {

const char* const kInputBitNames[kInputBits] = {
    "estop.a",      "estop.b",      "gate.a",     "gate.b",     "enable.a",   "enable.b",
    "enable.panic", "mode.auto",    "mode.t1",    "mode.t2",    "reset_button", "contactor_fb",
    "brake_fb.1",   "brake_fb.2",   "brake_fb.3", "brake_fb.4", "brake_fb.5", "brake_fb.6",
    "reduced.a",    "reduced.b",    "field.outer.a", "field.outer.b", "field.inner.a", "field.inner.b",
    "contactor_fb.k2"};
const char* const kOutputBitNames[kOutputBits] = {"contactor",    "brakes_release", "reset_lamp",
                                                  "brake_hold.1", "brake_hold.2",   "brake_hold.3",
                                                  "brake_hold.4", "brake_hold.5",   "brake_hold.6",
                                                  "reduced_active", "contactor_k2"};

namespace {

using Json = nlohmann::json;

struct Checker {
  std::string err;
  bool fail(const std::string& where, const std::string& what) {
    if (err.empty()) {
      err = where + ": " + what;
    }
    return false;
  }
};

// A 32-bit id: a number or a "0x..." string.
bool id32(const Json& j, const std::string& where, std::uint32_t& out, Checker& c) {
  if (j.is_number_unsigned() && j.get<std::uint64_t>() <= 0xFFFFFFFFULL) {
    out = static_cast<std::uint32_t>(j.get<std::uint64_t>());
    return true;
  }
  if (j.is_string()) {
    const std::string s = j.get<std::string>();
    std::size_t used = 0;
    try {
      const unsigned long long v = std::stoull(s, &used, 0);
      if (used == s.size() && v <= 0xFFFFFFFFULL) {
        out = static_cast<std::uint32_t>(v);
        return true;
      }
    } catch (...) {  // reported below
    }
  }
  return c.fail(where, "expected a 32-bit number (e.g. \"0x00005AFE\")");
}

bool uint_in(const Json& obj, const char* key, const std::string& where, std::uint64_t lo, std::uint64_t hi,
             std::uint64_t& out, Checker& c) {
  const auto it = obj.find(key);
  if (it == obj.end() || !it->is_number_unsigned() || it->get<std::uint64_t>() < lo || it->get<std::uint64_t>() > hi) {
    return c.fail(where + "." + key, "expected an integer " + std::to_string(lo) + ".." + std::to_string(hi));
  }
  out = it->get<std::uint64_t>();
  return true;
}

// The first `required` names must be given; the rest may be left out (kNoBit: not mapped).
template <std::size_t N>
bool bit_map(const Json& obj, const std::string& where, const char* const (&names)[N], std::size_t required,
             std::uint16_t bytes, std::array<std::uint16_t, N>& out, Checker& c) {
  const auto it = obj.find("bits");
  if (it == obj.end() || !it->is_object()) {
    return c.fail(where + ".bits", "expected an object naming the bit of each signal");
  }
  std::set<std::uint64_t> used;
  for (std::size_t i = 0; i < N; ++i) {
    std::uint64_t b = 0;
    if (i >= required && !it->contains(names[i])) {
      out[i] = kNoBit;
      continue;
    }
    if (!uint_in(*it, names[i], where + ".bits", 0, bytes * 8U - 1U, b, c)) {
      return false;
    }
    if (!used.insert(b).second) {
      return c.fail(where + ".bits." + names[i], "bit " + std::to_string(b) + " is used twice");
    }
    out[i] = static_cast<std::uint16_t>(b);
  }
  for (const auto& [k, v] : it->items()) {
    if (std::find_if(std::begin(names), std::end(names), [&](const char* n) { return k == n; }) == std::end(names)) {
      return c.fail(where + ".bits." + k, "unknown signal");
    }
  }
  return true;
}

// SPEC §11's distance sensor: "pdo": {"separation_mm": BYTE} (INT32 in the TxPDO image) and
// "bits": {"separation_valid": BIT}, nothing else, inside the input image and not overlapping.
bool distance_sensor(const Json& s, const std::string& where, Subdevice& d, Checker& c) {
  if (d.in_bytes < 5U) {
    return c.fail(where + ".in_bytes", "a distance sensor needs at least 5 input bytes (INT32 separation_mm and a valid bit)");
  }
  const auto pdo = s.find("pdo");
  if (pdo == s.end() || !pdo->is_object()) {
    return c.fail(where + ".pdo", "expected {\"separation_mm\": BYTE}, the byte offset of the INT32 separation in mm");
  }
  for (const auto& [k, v] : pdo->items()) {
    if (k != "separation_mm") {
      return c.fail(where + ".pdo." + k, "unknown object (a distance sensor has separation_mm)");
    }
  }
  std::uint64_t v = 0;
  if (!uint_in(*pdo, "separation_mm", where + ".pdo", 0, d.in_bytes - 4U, v, c)) {
    return false;
  }
  d.separation_mm = static_cast<std::uint16_t>(v);
  const auto bits = s.find("bits");
  if (bits == s.end() || !bits->is_object()) {
    return c.fail(where + ".bits", "expected {\"separation_valid\": BIT}, the bit of the reading's valid flag");
  }
  for (const auto& [k, b] : bits->items()) {
    if (k != "separation_valid") {
      return c.fail(where + ".bits." + k, "unknown signal (a distance sensor has separation_valid)");
    }
  }
  if (!uint_in(*bits, "separation_valid", where + ".bits", 0, d.in_bytes * 8U - 1U, v, c)) {
    return false;
  }
  if (v >= d.separation_mm * 8U && v < (d.separation_mm + 4U) * 8U) {
    return c.fail(where + ".bits.separation_valid", "bit " + std::to_string(v) + " lies inside separation_mm (bytes " +
                                                        std::to_string(d.separation_mm) + ".." +
                                                        std::to_string(d.separation_mm + 3U) + ")");
  }
  d.separation_valid_bit = static_cast<std::uint16_t>(v);
  return true;
}

// Issue 37: the data lengths (host -> device, device -> host) a role's connections carry
// (docs/black-channel.md "Connections").
struct LinkData {
  LinkRole role = LinkRole::none;
  std::uint8_t host = 0;
  std::uint8_t device = 0;
};
LinkData link_data(Role r) {
  switch (r) {
    case Role::safe_inputs: return {LinkRole::safe_inputs, 0, 4};
    case Role::safe_outputs: return {LinkRole::safe_outputs, 1, 1};
    case Role::drive: return {LinkRole::load_encoder, 0, 4};
    default: return {};
  }
}

// "safety_links": [{"id": "0xA001", "channel": "A", "out_offset": 0, "in_offset": 0,
// "watchdog_ms": 10}, ...]: each container inside the PDO images, not overlapping another one,
// each channel at most once per subdevice. Required on safe_inputs / safe_outputs, optional on
// a drive (its load-side encoder: only with load_position).
bool safety_links(const Json& s, const std::string& where, Subdevice& d, Checker& c) {
  const auto it = s.find("safety_links");
  const bool safe = d.role == Role::safe_inputs || d.role == Role::safe_outputs;
  const std::string at = where + " (" + d.name + ").safety_links";
  if (it == s.end()) {
    return !safe || c.fail(at, "missing: a safe terminal's connections to the channels (docs/black-channel.md)");
  }
  if (!safe && d.role != Role::drive) {
    return c.fail(at, "only the safe_inputs, safe_outputs and drive subdevices carry safety containers");
  }
  if (!it->is_array() || it->empty() || it->size() > 2U) {
    return c.fail(at, "expected a list of one or two connections (channel A's, channel B's)");
  }
  if (d.role == Role::drive && d.load_position == kNoOffset) {
    return c.fail(at, "a drive's containers carry its load-side encoder: give pdo.load_position too");
  }
  const LinkData data = link_data(d.role);
  const std::size_t out_len = safelink::container_bytes(data.host);
  const std::size_t in_len = safelink::container_bytes(data.device);
  for (std::size_t k = 0; k < it->size(); ++k) {
    const Json& e = (*it)[k];
    const std::string w = at + "[" + std::to_string(k) + "]";
    if (!e.is_object()) {
      return c.fail(w, "expected an object with id, channel, out_offset, in_offset and watchdog_ms");
    }
    for (const auto& [key, v] : e.items()) {
      if (key != "id" && key != "channel" && key != "out_offset" && key != "in_offset" && key != "watchdog_ms") {
        return c.fail(w + "." + key, "unknown key (expected id, channel, out_offset, in_offset, watchdog_ms)");
      }
    }
    SafetyLink l;
    std::uint32_t id = 0;
    if (!e.contains("id")) {
      return c.fail(w + ".id", "missing (the connection id, e.g. \"0xA001\")");
    }
    if (!id32(e["id"], w + ".id", id, c)) {
      return false;
    }
    if (id == 0U || id > 0xFFFFU) {
      return c.fail(w + ".id", "expected a non-zero 16-bit connection id");
    }
    l.id = static_cast<std::uint16_t>(id);
    const auto ch = e.find("channel");
    if (ch == e.end() || !ch->is_string() || (ch->get<std::string>() != "A" && ch->get<std::string>() != "B")) {
      return c.fail(w + ".channel", "expected \"A\" or \"B\" (the supervisor channel that hosts it)");
    }
    l.channel = ch->get<std::string>()[0];
    for (const SafetyLink& o : d.links) {
      if (o.channel == l.channel) {
        return c.fail(w + ".channel", std::string("channel ") + l.channel + " has a connection to this subdevice already");
      }
    }
    std::uint64_t v = 0;
    Checker range;  // its own message names the container's size and the image's
    if (d.out_bytes < out_len || !uint_in(e, "out_offset", w, 0, d.out_bytes - out_len, v, range)) {
      return c.fail(w + ".out_offset", "the channel's container (" + std::to_string(out_len) +
                                            " bytes) must lie inside the " + std::to_string(d.out_bytes) +
                                            " output bytes");
    }
    l.out_offset = static_cast<std::uint16_t>(v);
    if (d.in_bytes < in_len || !uint_in(e, "in_offset", w, 0, d.in_bytes - in_len, v, range)) {
      return c.fail(w + ".in_offset", "the device's container (" + std::to_string(in_len) +
                                           " bytes) must lie inside the " + std::to_string(d.in_bytes) +
                                           " input bytes");
    }
    l.in_offset = static_cast<std::uint16_t>(v);
    if (d.role == Role::drive) {  // nor any of the drive's own objects
      const struct {
        const char* key;
        std::uint16_t at;
        std::uint16_t bytes;
        bool out;
      } objs[] = {{"controlword", d.controlword, 2, true},         {"target_position", d.target_position, 4, true},
                  {"max_torque", d.max_torque, 2, true},           {"statusword", d.statusword, 2, false},
                  {"position_actual", d.position_actual, 4, false}, {"velocity_actual", d.velocity_actual, 4, false},
                  {"torque_actual", d.torque_actual, 2, false},     {"load_position", d.load_position, 4, false}};
      for (const auto& o : objs) {
        const std::size_t start = o.out ? l.out_offset : l.in_offset;
        const std::size_t len = o.out ? out_len : in_len;
        if (start < std::size_t{o.at} + o.bytes && o.at < start + len) {
          return c.fail(w, std::string("its container overlaps pdo.") + o.key);
        }
      }
    }
    for (const SafetyLink& o : d.links) {
      if ((l.out_offset < o.out_offset + out_len && o.out_offset < l.out_offset + out_len) ||
          (l.in_offset < o.in_offset + in_len && o.in_offset < l.in_offset + in_len)) {
        return c.fail(w, "its container overlaps the one of connection " + std::to_string(o.id));
      }
    }
    if (!uint_in(e, "watchdog_ms", w, 1, 60000, v, c)) {
      return false;
    }
    l.watchdog_ms = static_cast<std::uint16_t>(v);
    d.links.push_back(l);
  }
  return true;
}

bool drive(const Json& s, const std::string& where, Subdevice& d, Checker& c) {
  std::uint64_t v = 0;
  if (!uint_in(s, "axis", where, 1, kAxes, v, c)) {
    return false;
  }
  d.axis = static_cast<std::uint8_t>(v);
  if (!uint_in(s, "counts_per_revolution", where, 1, 1ULL << 31U, v, c)) {
    return false;
  }
  d.counts_per_rad = static_cast<double>(v) / 6.283185307179586;
  d.counts_per_revolution = static_cast<std::uint32_t>(v);
  const auto pdo = s.find("pdo");
  if (pdo == s.end() || !pdo->is_object()) {
    return c.fail(where + ".pdo", "expected the byte offsets of the CiA 402 objects");
  }
  const std::string p = where + ".pdo";
  const struct {
    const char* key;
    std::uint16_t* field;
    std::uint16_t bytes;   // object size
    std::uint16_t limit;   // image size
  } objs[] = {{"controlword", &d.controlword, 2, d.out_bytes},
              {"target_position", &d.target_position, 4, d.out_bytes},
              {"max_torque", &d.max_torque, 2, d.out_bytes},
              {"statusword", &d.statusword, 2, d.in_bytes},
              {"position_actual", &d.position_actual, 4, d.in_bytes},
              {"velocity_actual", &d.velocity_actual, 4, d.in_bytes},
              {"torque_actual", &d.torque_actual, 2, d.in_bytes}};
  for (const auto& o : objs) {
    if (o.limit < o.bytes || !uint_in(*pdo, o.key, p, 0, o.limit - o.bytes, v, c)) {
      return c.fail(p + "." + o.key, "offset outside the PDO image");
    }
    *o.field = static_cast<std::uint16_t>(v);
  }
  // SPEC §14: the load-side encoder (0x60E4:01, INT32), optional.
  if (pdo->contains("load_position")) {
    if (d.in_bytes < 4U || !uint_in(*pdo, "load_position", p, 0, d.in_bytes - 4U, v, c)) {
      return c.fail(p + ".load_position", "offset outside the PDO image (0x60E4:01, 4 bytes)");
    }
    d.load_position = static_cast<std::uint16_t>(v);
  }
  for (const auto& [k, x] : pdo->items()) {
    const bool known = k == "load_position" ||
                       std::any_of(std::begin(objs), std::end(objs), [&](const auto& o) { return k == o.key; });
    if (!known) {
      return c.fail(p + "." + k,
                    "unknown object (expected controlword, target_position, max_torque, statusword, position_actual, "
                    "velocity_actual, torque_actual, load_position)");
    }
  }
  return true;
}

// "startup": [{"index": "0x6060", "sub": 0, "size": 1, "value": 8}, ...]. Every key is
// required and no other is allowed; the value must fit `size` bytes, signed or unsigned.
bool startup_list(const Json& s, const std::string& where, Subdevice& d, Checker& c) {
  const auto it = s.find("startup");
  if (it == s.end()) {
    return true;
  }
  const std::string list = where + " (" + d.name + ").startup";
  if (!it->is_array() || it->size() > kMaxStartupSdos) {
    return c.fail(list, "expected a list of at most " + std::to_string(kMaxStartupSdos) + " SDO writes");
  }
  for (std::size_t k = 0; k < it->size(); ++k) {
    const Json& e = (*it)[k];
    const std::string at = list + "[" + std::to_string(k) + "]";
    if (!e.is_object()) {
      return c.fail(at, "expected an object with index, sub, size and value");
    }
    for (const auto& [key, v] : e.items()) {
      if (key != "index" && key != "sub" && key != "size" && key != "value") {
        return c.fail(at + "." + key, "unknown key (expected index, sub, size, value)");
      }
    }
    StartupSdo sdo;
    std::uint32_t index = 0;
    if (!e.contains("index")) {
      return c.fail(at + ".index", "missing (an object index, e.g. \"0x6060\")");
    }
    if (!id32(e["index"], at + ".index", index, c)) {
      return false;
    }
    if (index < 0x1000U || index > 0xFFFFU) {
      return c.fail(at + ".index", "object index must be 0x1000..0xFFFF");
    }
    sdo.index = static_cast<std::uint16_t>(index);
    std::uint64_t v = 0;
    if (!uint_in(e, "sub", at, 0, 255, v, c)) {
      return false;
    }
    sdo.sub = static_cast<std::uint8_t>(v);
    const auto size = e.find("size");
    if (size == e.end() || !size->is_number_unsigned() ||
        (size->get<std::uint64_t>() != 1U && size->get<std::uint64_t>() != 2U && size->get<std::uint64_t>() != 4U)) {
      return c.fail(at + ".size", "expected 1, 2 or 4 (bytes)");
    }
    sdo.size = static_cast<std::uint8_t>(size->get<std::uint64_t>());
    const unsigned bits = sdo.size * 8U;
    const std::int64_t lo = -(std::int64_t{1} << (bits - 1U));
    const std::int64_t hi = (std::int64_t{1} << bits) - 1;
    const auto value = e.find("value");
    const bool integer = value != e.end() && (value->is_number_integer());
    const bool fits = integer && (value->is_number_unsigned() ? value->get<std::uint64_t>() <= static_cast<std::uint64_t>(hi)
                                                              : value->get<std::int64_t>() >= lo);
    if (!fits) {
      return c.fail(at + ".value", "expected an integer that fits " + std::to_string(sdo.size) + " byte" +
                                       (sdo.size == 1U ? "" : "s") + " (" + std::to_string(lo) + ".." + std::to_string(hi) + ")");
    }
    const std::uint64_t mask = (std::uint64_t{1} << bits) - 1U;
    sdo.value = static_cast<std::uint32_t>(static_cast<std::uint64_t>(value->get<std::int64_t>()) & mask);
    d.startup.push_back(sdo);
  }
  return true;
}

// "dc": {"assign_activate": "0x0300"}: optional; no other key; a non-zero 16-bit word.
bool dc_sync(const Json& s, const std::string& where, Subdevice& d, Checker& c) {
  const auto it = s.find("dc");
  if (it == s.end()) {
    return true;
  }
  const std::string at = where + " (" + d.name + ").dc";
  if (!it->is_object()) {
    return c.fail(at, "expected an object {\"assign_activate\": \"0x0300\"}");
  }
  for (const auto& [k, v] : it->items()) {
    if (k != "assign_activate") {
      return c.fail(at + "." + k, "unknown key (expected assign_activate)");
    }
  }
  std::uint32_t aa = 0;
  if (!it->contains("assign_activate")) {
    return c.fail(at + ".assign_activate", "missing");
  }
  if (!id32((*it)["assign_activate"], at + ".assign_activate", aa, c)) {
    return false;
  }
  if (aa == 0U || aa > 0xFFFFU) {
    return c.fail(at + ".assign_activate", "expected a non-zero 16-bit word (e.g. \"0x0300\")");
  }
  d.dc_assign_activate = static_cast<std::uint16_t>(aa);
  return true;
}

bool subdevice(const Json& s, const std::string& where, Subdevice& d, Checker& c) {
  if (!s.is_object()) {
    return c.fail(where, "expected an object");
  }
  const auto name = s.find("name");
  d.name = (name != s.end() && name->is_string()) ? name->get<std::string>() : where;
  const auto role = s.find("role");
  const std::string r = (role != s.end() && role->is_string()) ? role->get<std::string>() : "";
  if (r == "safety_inputs") {
    d.role = Role::safety_inputs;
  } else if (r == "safety_outputs") {
    d.role = Role::safety_outputs;
  } else if (r == "drive") {
    d.role = Role::drive;
  } else if (r == "distance_sensor") {
    d.role = Role::distance_sensor;
  } else if (r == "safe_inputs") {
    d.role = Role::safe_inputs;
  } else if (r == "safe_outputs") {
    d.role = Role::safe_outputs;
  } else {
    return c.fail(where + ".role",
                  "expected safety_inputs, safety_outputs, drive, distance_sensor, safe_inputs or safe_outputs");
  }
  for (const char* k : {"vendor_id", "product_code"}) {
    if (s.find(k) == s.end()) {
      return c.fail(where + "." + k, "missing");
    }
  }
  if (!id32(s["vendor_id"], where + ".vendor_id", d.vendor_id, c) ||
      !id32(s["product_code"], where + ".product_code", d.product_code, c)) {
    return false;
  }
  d.check_revision = s.contains("revision");
  if (d.check_revision && !id32(s["revision"], where + ".revision", d.revision, c)) {
    return false;
  }
  std::uint64_t v = 0;
  if (!uint_in(s, "in_bytes", where, 0, 512, v, c)) {
    return false;
  }
  d.in_bytes = static_cast<std::uint16_t>(v);
  if (!uint_in(s, "out_bytes", where, 0, 512, v, c)) {
    return false;
  }
  d.out_bytes = static_cast<std::uint16_t>(v);
  if (!startup_list(s, where, d, c) || !dc_sync(s, where, d, c)) {
    return false;
  }
  switch (d.role) {
    case Role::safety_inputs:
      return (d.in_bytes > 0 ? bit_map(s, where, kInputBitNames, kRequiredInputBits, d.in_bytes, d.in_bit, c)
                             : c.fail(where + ".in_bytes", "safety inputs need input bytes")) &&
             safety_links(s, where, d, c);
    case Role::safety_outputs:
      return (d.out_bytes > 0 ? bit_map(s, where, kOutputBitNames, kRequiredOutputBits, d.out_bytes, d.out_bit, c)
                              : c.fail(where + ".out_bytes", "safety outputs need output bytes")) &&
             safety_links(s, where, d, c);
    case Role::drive: return drive(s, where, d, c) && safety_links(s, where, d, c);
    case Role::distance_sensor: return distance_sensor(s, where, d, c) && safety_links(s, where, d, c);
    case Role::safe_inputs:
    case Role::safe_outputs:
      for (const char* k : {"bits", "pdo"}) {
        if (s.contains(k)) {
          return c.fail(where + "." + k, "a safe terminal has no bits or objects of its own, only safety_links");
        }
      }
      return safety_links(s, where, d, c);
  }
  return false;
}

}  // namespace

namespace {

// SPEC §14, across subdevices: K2's output and its auxiliary contact come together (external
// device monitoring needs the contact of the contactor it drives), and the load-side encoder
// is on every drive or on none (a channel compares all six axes or none).
bool two_channel_io(const BusConfig& bus, std::string& err) {
  const Subdevice* in = nullptr;
  const Subdevice* out = nullptr;
  std::size_t with_load = 0;
  std::size_t drives = 0;
  const Subdevice* without_load = nullptr;
  for (const Subdevice& d : bus.subdevices) {
    in = (d.role == Role::safety_inputs) ? &d : in;
    out = (d.role == Role::safety_outputs) ? &d : out;
    if (d.role == Role::drive) {
      ++drives;
      with_load += (d.load_position != kNoOffset) ? 1U : 0U;
      without_load = (d.load_position == kNoOffset && without_load == nullptr) ? &d : without_load;
    }
  }
  const bool k2_out = out != nullptr && out->out_bit[kOutputBits - 1U] != kNoBit;
  const bool k2_in = in != nullptr && in->in_bit[kInputBits - 1U] != kNoBit;
  if (k2_out != k2_in) {
    err = k2_out ? "subdevices: \"contactor_k2\" is mapped on the safety outputs but K2's auxiliary contact "
                   "\"contactor_fb.k2\" is not on the safety inputs (SPEC §14: external device monitoring of K2)"
                 : "subdevices: \"contactor_fb.k2\" is mapped on the safety inputs but \"contactor_k2\" is not on "
                   "the safety outputs (a K2 auxiliary contact without its output)";
    return false;
  }
  if (with_load != 0U && with_load != drives) {
    err = "subdevices: drive axis " + std::to_string(without_load->axis) + " (" + without_load->name +
          ") has no pdo.load_position while " + std::to_string(with_load) +
          " drive(s) have one (SPEC §14: the load-side encoder on every axis or on none)";
    return false;
  }
  std::size_t with_links = 0;
  for (const Subdevice& d : bus.subdevices) {
    with_links += (d.role == Role::drive && !d.links.empty()) ? 1U : 0U;
  }
  if (with_links != 0U && with_links != drives) {
    for (const Subdevice& d : bus.subdevices) {
      if (d.role == Role::drive && d.links.empty()) {
        err = "subdevices: drive axis " + std::to_string(d.axis) + " (" + d.name + ") has no safety_links while " +
              std::to_string(with_links) +
              " drive(s) have some (issue 37: the load-side encoder protected on every axis or on none)";
        return false;
      }
    }
  }
  return true;
}

}  // namespace

namespace {

// Issue 37: at most one safe input and one safe output terminal, every connection id once,
// and the LinkTable in bus order (the order of the process image's containers).
bool link_table(BusConfig& bus, std::string& err) {
  int safe_in = 0;
  int safe_out = 0;
  std::set<std::uint16_t> ids;
  LinkTable t{};
  for (std::size_t i = 0; i < bus.subdevices.size(); ++i) {
    const Subdevice& d = bus.subdevices[i];
    const std::string where = "subdevices[" + std::to_string(i) + "] (" + d.name + ")";
    if ((d.role == Role::safe_inputs && ++safe_in > 1) || (d.role == Role::safe_outputs && ++safe_out > 1)) {
      err = where + ".role: a second " + (d.role == Role::safe_inputs ? "safe_inputs" : "safe_outputs") +
            " subdevice (at most one)";
      return false;
    }
    const LinkData data = link_data(d.role);
    for (std::size_t k = 0; k < d.links.size(); ++k) {
      const SafetyLink& l = d.links[k];
      if (!ids.insert(l.id).second) {
        char id[8];
        std::snprintf(id, sizeof id, "0x%04X", static_cast<unsigned>(l.id));
        err = where + ".safety_links[" + std::to_string(k) + "].id: connection " + id + " is used twice";
        return false;
      }
      if (t.count >= kMaxLinks) {
        err = where + ".safety_links: more than " + std::to_string(kMaxLinks) + " connections on the bus";
        return false;
      }
      LinkSpec& s = t.link[t.count++];
      s.id = l.id;
      s.channel = l.channel;
      s.role = data.role;
      s.axis = d.role == Role::drive ? d.axis : 0U;
      s.host_data_bytes = data.host;
      s.device_data_bytes = data.device;
      s.watchdog_ms = l.watchdog_ms;
      s.vendor_id = d.vendor_id;
      s.product_code = d.product_code;
      s.position = static_cast<std::uint16_t>(i + 1U);
      s.counts_per_revolution = d.role == Role::drive ? d.counts_per_revolution : 0U;
    }
  }
  bus.links = t;
  return true;
}

}  // namespace

bool parse_bus_config(const std::string& text, BusConfig& out, std::string& err) {
  Checker c;
  const Json j = Json::parse(text, nullptr, false, true);
  if (j.is_discarded() || !j.is_object()) {
    err = "not a JSON object";
    return false;
  }
  out = BusConfig{};
  // Optional bus-wide settings: absent keeps the default.
  const auto setting = [&](const char* key, std::uint64_t lo, std::uint64_t hi, std::uint32_t& field) {
    std::uint64_t v = field;
    if (j.contains(key) && !uint_in(j, key, "bus", lo, hi, v, c)) {
      return false;
    }
    field = static_cast<std::uint32_t>(v);
    return true;
  };
  if (!setting("frame_timeout_us", 100, 100000, out.frame_timeout_us) ||
      !setting("scan_timeout_ms", 0, 120000, out.scan_timeout_ms) ||
      !setting("stale_cycles", 1, 1000, out.stale_cycles) ||
      !setting("watchdog_cycles", kMinWatchdogCycles, kMaxWatchdogCycles, out.watchdog_cycles) ||
      !setting("sync0_shift_us", 0, 100000, out.sync0_shift_us)) {
    err = c.err;
    return false;
  }
  const auto subs = j.find("subdevices");
  if (subs == j.end() || !subs->is_array() || subs->empty() || subs->size() > 16U) {
    err = "subdevices: expected a list of 1..16 subdevices in bus order";
    return false;
  }
  std::array<int, kAxes> axes{};
  int inputs = 0;
  int outputs = 0;
  int sensors = 0;
  for (std::size_t i = 0; i < subs->size(); ++i) {
    Subdevice d;
    const std::string where = "subdevices[" + std::to_string(i) + "]";
    if (!subdevice((*subs)[i], where, d, c)) {
      err = c.err;
      return false;
    }
    if (d.role == Role::drive && ++axes[d.axis - 1U] > 1) {
      err = where + ".axis: axis " + std::to_string(d.axis) + " appears twice";
      return false;
    }
    inputs += d.role == Role::safety_inputs ? 1 : 0;
    outputs += d.role == Role::safety_outputs ? 1 : 0;
    if (d.role == Role::distance_sensor && ++sensors > 1) {
      err = where + ".role: a second distance_sensor (the separation comes from one sensor; at most one)";
      return false;
    }
    out.subdevices.push_back(std::move(d));
  }
  for (std::size_t a = 0; a < kAxes; ++a) {
    if (axes[a] == 0) {
      err = "subdevices: no drive for axis " + std::to_string(a + 1U);
      return false;
    }
  }
  if (inputs != 1 || outputs != 1) {
    err = "subdevices: expected exactly one safety_inputs and one safety_outputs subdevice";
    return false;
  }
  if (!two_channel_io(out, err)) {
    return false;
  }
  return link_table(out, err);
}

bool links_fit_cycle(const BusConfig& cfg, std::uint32_t cycle_us, std::string& err) {
  for (std::size_t i = 0; i < cfg.links.count; ++i) {
    const LinkSpec& l = cfg.links.link[i];
    if (cycle_us == 0U || std::uint64_t{l.watchdog_ms} * 1000U < 2U * std::uint64_t{cycle_us}) {
      char id[8];
      std::snprintf(id, sizeof id, "0x%04X", static_cast<unsigned>(l.id));
      err = std::string("safety link ") + id + ": watchdog_ms " + std::to_string(l.watchdog_ms) +
            " is shorter than 2 cycles of " + std::to_string(cycle_us) + " us (one exchange of the ping-pong)";
      return false;
    }
  }
  return true;
}

bool watchdog_registers(std::uint32_t cycles, std::uint32_t cycle_us, std::uint16_t& divider, std::uint16_t& time) noexcept {
  const std::uint64_t us = static_cast<std::uint64_t>(cycles) * cycle_us;
  // (divider + 2) x 40 ns: 2498 = 100 us (the ESC's default), 24998 = 1 ms.
  for (const auto& [div, tick_us] : {std::pair<std::uint16_t, std::uint64_t>{2498, 100}, {24998, 1000}}) {
    const std::uint64_t ticks = (us + tick_us - 1U) / tick_us;  // never shorter than asked
    if (ticks >= 1U && ticks <= 0xFFFFU) {
      divider = div;
      time = static_cast<std::uint16_t>(ticks);
      return true;
    }
  }
  return false;
}

bool load_bus_config(const std::string& path, BusConfig& out, std::string& err) {
  std::ifstream f(path);
  if (!f) {
    err = "cannot read " + path;
    return false;
  }
  std::stringstream ss;
  ss << f.rdbuf();
  if (!parse_bus_config(ss.str(), out, err)) {
    err = path + ": " + err;
    return false;
  }
  return true;
}

}  // namespace safestate::hal::ethercat

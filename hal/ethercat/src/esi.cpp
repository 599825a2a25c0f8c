// ETG.2000 ESI files -> devices -> the bus configuration (esi.hpp, docs/ethercat.md "ESI").
#include "safestate/hal/esi.hpp"

#include <nlohmann/json.hpp>
#include <pugixml.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

namespace safestate::hal::esi {

namespace {

std::string hex(std::uint32_t v, int digits = 8) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%0*X", digits, v);
  return b;
}

// The CoE data types a PDO entry may have here (ETG.1000.6 table 64 / ETG.2000), with
// their size. Strings, arrays and structures are not process data we could place.
struct DataType {
  const char* name;
  std::uint16_t code;
  std::uint8_t bits;
};
constexpr DataType kTypes[] = {
    {"BOOL", 0x0001, 1},   {"BIT", 0x0001, 1},    {"SINT", 0x0002, 8},   {"INT", 0x0003, 16},
    {"DINT", 0x0004, 32},  {"USINT", 0x0005, 8},  {"UINT", 0x0006, 16},  {"UDINT", 0x0007, 32},
    {"REAL", 0x0008, 32},  {"LREAL", 0x0011, 64}, {"INT24", 0x0010, 24}, {"UINT24", 0x0016, 24},
    {"LINT", 0x0015, 64},  {"ULINT", 0x001B, 64}, {"BYTE", 0x001E, 8},   {"WORD", 0x001F, 16},
    {"DWORD", 0x0020, 32}, {"BIT1", 0x0030, 1},   {"BIT2", 0x0031, 2},   {"BIT3", 0x0032, 3},
    {"BIT4", 0x0033, 4},   {"BIT5", 0x0034, 5},   {"BIT6", 0x0035, 6},   {"BIT7", 0x0036, 7},
    {"BIT8", 0x0037, 8},
};

std::string trim(const char* s) {
  std::string t = s;
  const auto b = t.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) {
    return "";
  }
  const auto e = t.find_last_not_of(" \t\r\n");
  return t.substr(b, e - b + 1U);
}

// Reads one document and reports with the file and line of the element.
class Reader {
 public:
  Reader(const std::string& text, std::string file) : text_(text), file_(std::move(file)) {}

  int line(const pugi::xml_node& n) const { return line_at(n.offset_debug()); }
  int line_at(std::ptrdiff_t off) const {
    if (off < 0 || static_cast<std::size_t>(off) > text_.size()) {
      return 0;
    }
    return 1 + static_cast<int>(std::count(text_.begin(), text_.begin() + off, '\n'));
  }
  bool fail(const pugi::xml_node& at, const std::string& what) {
    if (err.empty()) {
      err = file_ + ":" + std::to_string(line(at)) + ": " + what;
    }
    return false;
  }
  // A HexDecValue: "#x1A00" or decimal "6656", 0..max.
  bool number(const pugi::xml_node& n, const std::string& what, std::uint64_t max, std::uint64_t& out) {
    return text_number(n, trim(n.child_value()), what, max, out);
  }
  bool attr_number(const pugi::xml_node& n, const char* attr, const std::string& what, std::uint64_t max,
                   std::uint64_t& out) {
    return text_number(n, trim(n.attribute(attr).value()), what, max, out);
  }
  bool text_number(const pugi::xml_node& n, const std::string& s, const std::string& what, std::uint64_t max,
                   std::uint64_t& out) {
    if (!number_text(s, max, out)) {
      return fail(n, what + ": \"" + s + "\" is not a number 0.." + std::to_string(max) + " (decimal or #x hex)");
    }
    return true;
  }
  static bool number_text(const std::string& s, std::uint64_t max, std::uint64_t& out) {
    std::uint64_t v = 0;
    std::size_t i = 0;
    int base = 10;
    if (s.empty()) {
      return false;
    }
    if (s.size() > 2U && s[0] == '#' && (s[1] == 'x' || s[1] == 'X')) {
      base = 16;
      i = 2;
    }
    for (; i < s.size(); ++i) {
      const char c = s[i];
      int d = -1;
      if (c >= '0' && c <= '9') {
        d = c - '0';
      } else if (base == 16 && c >= 'a' && c <= 'f') {
        d = c - 'a' + 10;
      } else if (base == 16 && c >= 'A' && c <= 'F') {
        d = c - 'A' + 10;
      }
      if (d < 0 || static_cast<std::uint64_t>(d) > max ||
          v > (max - static_cast<std::uint64_t>(d)) / static_cast<std::uint64_t>(base)) {
        return false;
      }
      v = v * static_cast<std::uint64_t>(base) + static_cast<std::uint64_t>(d);
    }
    out = v;
    return true;
  }

  std::string err;
  std::vector<std::string> warnings;
  void warn(const pugi::xml_node& at, const std::string& what) {
    warnings.push_back(file_ + ":" + std::to_string(line(at)) + ": " + what);
  }
  const std::string& file() const { return file_; }

 private:
  const std::string& text_;
  std::string file_;
};

bool read_pdo(Reader& r, const pugi::xml_node& p, const std::string& where, Pdo& out) {
  out.line = r.line(p);
  std::uint64_t v = 0;
  const pugi::xml_node idx = p.child("Index");
  if (!idx) {
    return r.fail(p, where + ": missing <Index>");
  }
  if (!r.number(idx, where + " <Index>", 0xFFFF, v)) {
    return false;
  }
  out.index = static_cast<std::uint16_t>(v);
  const std::string pdo = where + " " + hex(out.index, 4);
  out.name = trim(p.child_value("Name"));
  if (p.attribute("Sm")) {
    if (!r.attr_number(p, "Sm", pdo + " attribute Sm", 15, v)) {
      return false;
    }
    out.sm = static_cast<int>(v);
  }
  int k = 0;
  for (const pugi::xml_node& e : p.children("Entry")) {
    ++k;
    Entry en;
    en.line = r.line(e);
    const std::string at = pdo + " <Entry> " + std::to_string(k);
    const pugi::xml_node ei = e.child("Index");
    if (!ei) {
      return r.fail(e, at + ": missing <Index>");
    }
    if (!r.number(ei, at + " <Index>", 0xFFFF, v)) {
      return false;
    }
    en.index = static_cast<std::uint16_t>(v);
    const pugi::xml_node bl = e.child("BitLen");
    if (!bl) {
      return r.fail(e, at + ": missing <BitLen>");
    }
    if (!r.number(bl, at + " <BitLen>", 255, v) || v == 0U) {
      return r.fail(bl, at + " <BitLen>: expected 1..255 bits");
    }
    en.bits = static_cast<std::uint8_t>(v);
    if (en.index != 0U) {
      // <SubIndex> is optional in ETG.2000 (absent = 0).
      const pugi::xml_node si = e.child("SubIndex");
      v = 0;
      if (si && !r.number(si, at + " <SubIndex>", 255, v)) {
        return false;
      }
      en.sub = static_cast<std::uint8_t>(v);
      en.name = trim(e.child_value("Name"));
      const pugi::xml_node dt = e.child("DataType");
      en.type_name = trim(dt.child_value());
      const std::string obj = at + " (" + hex(en.index, 4) + ":" + std::to_string(en.sub) + " \"" + en.name + "\")";
      if (!dt) {
        return r.fail(e, obj + ": missing <DataType>");
      }
      const auto* t = std::find_if(std::begin(kTypes), std::end(kTypes),
                                   [&](const DataType& d) { return en.type_name == d.name; });
      if (t == std::end(kTypes)) {
        return r.fail(dt, obj + ": unknown or unsupported <DataType> \"" + en.type_name +
                              "\" (expected BOOL, BIT1..BIT8, SINT, USINT, INT, UINT, DINT, UDINT, ...)");
      }
      if (t->bits != en.bits) {
        return r.fail(bl, obj + ": <BitLen> " + std::to_string(en.bits) + " does not match <DataType> " +
                              en.type_name + " (" + std::to_string(t->bits) + " bit" + (t->bits == 1U ? "" : "s") + ")");
      }
      en.data_type = t->code;
    }
    out.entries.push_back(std::move(en));
  }
  return true;
}

// One <InitCmd>: IP (INIT -> PRE-OP) and PS (PRE-OP -> SAFE-OP) commands become the start-up
// list, which our master writes in PRE-OP; the others (SO, OS, ...: writes in SAFE-OP or
// on the way down) are skipped with a warning. <Data> "08", "e803", "fd": the value's bytes,
// little-endian.
bool init_cmd(Reader& r, const pugi::xml_node& c, const std::string& where, Device& d, std::size_t& ip_count) {
  std::vector<std::string> transitions;
  for (const pugi::xml_node& t : c.children("Transition")) {
    transitions.push_back(trim(t.child_value()));
  }
  std::uint64_t v = 0;
  const pugi::xml_node idx = c.child("Index");
  if (!idx) {
    return r.fail(c, where + ": missing <Index>");
  }
  if (!r.number(idx, where + " <Index>", 0xFFFF, v)) {
    return false;
  }
  const auto index = static_cast<std::uint16_t>(v);
  std::uint64_t sub = 0;
  const pugi::xml_node si = c.child("SubIndex");
  if (si && !r.number(si, where + " <SubIndex>", 255, sub)) {
    return false;
  }
  const std::string obj = where + " (" + hex(index, 4) + ":" + std::to_string(sub) + ")";
  const bool ip = std::find(transitions.begin(), transitions.end(), "IP") != transitions.end();
  const bool ps = std::find(transitions.begin(), transitions.end(), "PS") != transitions.end();
  if (!ip && !ps) {
    std::string ts;
    for (const std::string& t : transitions) {
      ts += (ts.empty() ? "" : ",") + t;
    }
    r.warn(c, obj + ": transition " + (ts.empty() ? "(none)" : ts) +
                  " skipped: the master writes the start-up list in PRE-OP, so only IP and PS commands are taken");
    return true;
  }
  if (c.attribute("CompleteAccess").as_bool(false)) {
    return r.fail(c, obj + ": complete access is not supported (the master writes one subindex at a time)");
  }
  if (index < 0x1000U) {
    return r.fail(idx, obj + ": object index must be 0x1000..0xFFFF");
  }
  const pugi::xml_node data = c.child("Data");
  if (!data) {
    return r.fail(c, obj + ": missing <Data>");
  }
  const std::string hexs = trim(data.child_value());
  const bool is_hex = !hexs.empty() && hexs.size() % 2U == 0U &&
                      std::all_of(hexs.begin(), hexs.end(), [](char ch) { return std::isxdigit(static_cast<unsigned char>(ch)) != 0; });
  if (!is_hex) {
    return r.fail(data, obj + " <Data>: \"" + hexs + "\" is not a hex byte string (e.g. \"e803\" = 1000)");
  }
  const std::size_t n = hexs.size() / 2U;
  if (n != 1U && n != 2U && n != 4U) {
    return r.fail(data, obj + " <Data>: " + std::to_string(n) +
                            " bytes; the master writes 1, 2 or 4 bytes (expedited SDO downloads)");
  }
  if (d.startup.size() >= ethercat::kMaxStartupSdos) {
    return r.fail(c, obj + ": more than " + std::to_string(ethercat::kMaxStartupSdos) + " start-up commands");
  }
  ethercat::StartupSdo s;
  s.index = index;
  s.sub = static_cast<std::uint8_t>(sub);
  s.size = static_cast<std::uint8_t>(n);
  for (std::size_t i = 0; i < n; ++i) {
    s.value |= static_cast<std::uint32_t>(std::stoul(hexs.substr(i * 2U, 2), nullptr, 16)) << (8U * i);
  }
  // IP commands go before the PS ones, as a master sends them (INIT->PRE-OP first); each in file order.
  if (ip) {
    d.startup.insert(d.startup.begin() + static_cast<std::ptrdiff_t>(ip_count), s);
    ++ip_count;
  } else {
    d.startup.push_back(s);
  }
  return true;
}

bool read_device(Reader& r, const pugi::xml_node& dev, std::uint32_t vendor, Device& d) {
  d.file = r.file();
  d.line = r.line(dev);
  d.vendor_id = vendor;
  const pugi::xml_node type = dev.child("Type");
  if (!type) {
    return r.fail(dev, "<Device>: missing <Type>");
  }
  d.type = trim(type.child_value());
  const std::string where = "<Device> \"" + d.type + "\"";
  std::uint64_t v = 0;
  if (!type.attribute("ProductCode")) {
    return r.fail(type, where + ": missing <Type ProductCode>");
  }
  if (!r.attr_number(type, "ProductCode", where + " ProductCode", 0xFFFFFFFFULL, v)) {
    return false;
  }
  d.product_code = static_cast<std::uint32_t>(v);
  if (!type.attribute("RevisionNo")) {
    return r.fail(type, where + ": missing <Type RevisionNo>");
  }
  if (!r.attr_number(type, "RevisionNo", where + " RevisionNo", 0xFFFFFFFFULL, v)) {
    return false;
  }
  d.revision = static_cast<std::uint32_t>(v);
  for (const pugi::xml_node& n : dev.children("Name")) {
    if (d.name.empty() || std::string(n.attribute("LcId").value()) == "1033") {
      d.name = trim(n.child_value());
    }
  }
  return true;
}

// The rest of a device: a mistake here makes that device unusable (Device::error), not the
// whole file, so that one odd device in a vendor's file of hundreds does not block the others.
bool read_body(Reader& r, const pugi::xml_node& dev, Device& d) {
  const std::string where = "<Device> \"" + d.type + "\"";
  std::uint64_t v = 0;
  // <Profile><ProfileNo>, also inside <ChannelInfo> (one per channel of a multi-axis device).
  int drives = 0;
  for (const pugi::xml_node& prof : dev.children("Profile")) {
    for (const pugi::xpath_node& pn : prof.select_nodes(".//ProfileNo")) {
      std::uint64_t no = 0;
      if (!r.number(pn.node(), where + " <Profile><ProfileNo>", 0xFFFF, no)) {
        return false;
      }
      if (no == 402U) {
        ++drives;
        const pugi::xml_node ai = pn.node().parent().child("AddInfo");
        std::uint64_t add = 0;
        if (ai && !r.number(ai, where + " <Profile><AddInfo>", 0xFFFF, add)) {
          return false;
        }
        d.profile_no = 402;
        d.add_info = static_cast<std::uint32_t>(add);
      }
    }
  }
  if (drives > 1) {
    return r.fail(dev, where + ": a CiA 402 device of " + std::to_string(drives) +
                           " axes; one axis per subdevice is supported");
  }
  for (const pugi::xml_node& sm : dev.children("Sm")) {
    SyncManager s;
    s.kind = trim(sm.child_value());
    const std::string at = where + " <Sm> \"" + s.kind + "\"";
    if (sm.attribute("StartAddress")) {
      if (!r.attr_number(sm, "StartAddress", at + " StartAddress", 0xFFFF, v)) {
        return false;
      }
      s.start = static_cast<std::uint16_t>(v);
    }
    if (sm.attribute("DefaultSize")) {
      if (!r.attr_number(sm, "DefaultSize", at + " DefaultSize", 0xFFFF, v)) {
        return false;
      }
      s.default_size = static_cast<std::uint16_t>(v);
    }
    if (sm.attribute("ControlByte")) {
      if (!r.attr_number(sm, "ControlByte", at + " ControlByte", 0xFF, v)) {
        return false;
      }
      s.control = static_cast<std::uint8_t>(v);
    }
    s.enable = sm.attribute("Enable").as_int(0) != 0;
    d.sms.push_back(s);
  }
  for (const char* kind : {"RxPdo", "TxPdo"}) {
    for (const pugi::xml_node& p : dev.children(kind)) {
      Pdo pdo;
      if (!read_pdo(r, p, where + " <" + kind + ">", pdo)) {
        return false;
      }
      if (pdo.sm >= 0 && static_cast<std::size_t>(pdo.sm) >= d.sms.size()) {
        return r.fail(p, where + " <" + kind + "> " + hex(pdo.index, 4) + ": Sm=\"" + std::to_string(pdo.sm) +
                             "\" names no <Sm> of the device (it has " + std::to_string(d.sms.size()) + ")");
      }
      (kind[0] == 'R' ? d.rx : d.tx).push_back(std::move(pdo));
    }
  }
  if (dev.child("Slots")) {
    r.warn(dev.child("Slots"), where + ": <Slots> (modular device) not read: only the PDOs of the device itself are");
  }
  const pugi::xml_node coe = dev.child("Mailbox").child("CoE");
  d.coe = static_cast<bool>(coe);
  int k = 0;
  std::size_t ip_count = 0;
  // <InitCmd> directly in <CoE>, or (as many vendors' files have them) inside <InitCmds>.
  for (const pugi::xpath_node& x : coe.select_nodes("InitCmd | InitCmds/InitCmd")) {
    if (!init_cmd(r, x.node(), where + " <Mailbox><CoE><InitCmd> " + std::to_string(++k), d, ip_count)) {
      return false;
    }
  }
  for (const pugi::xml_node& m : dev.child("Dc").children("OpMode")) {
    const pugi::xml_node aa = m.child("AssignActivate");
    const std::string at = where + " <Dc><OpMode> \"" + trim(m.child_value("Name")) + "\"";
    if (!aa) {
      continue;
    }
    if (!r.number(aa, at + " <AssignActivate>", 0xFFFF, v)) {
      return false;
    }
    if (v == 0U || d.assign_activate != 0U) {
      continue;  // free run, or a later synchronous mode: the first one is the device's default
    }
    d.assign_activate = static_cast<std::uint16_t>(v);
    // ShiftTimeSync0 (ns) may be negative in vendors' files (SYNC0 before the cycle's start):
    // the bus-wide sync0_shift_us cannot be, so a negative one is taken as 0, with a warning.
    const pugi::xml_node shift = m.child("ShiftTimeSync0");
    const std::string text = trim(shift.child_value());
    if (shift && !text.empty() && text[0] == '-') {
      if (!r.text_number(shift, text.substr(1), at + " <ShiftTimeSync0>", 0xFFFFFFFFULL, v)) {
        return false;
      }
      r.warn(shift, at + " <ShiftTimeSync0> " + text + " ns: a negative shift is not supported, 0 is used");
      v = 0;
    } else if (shift && !r.number(shift, at + " <ShiftTimeSync0>", 0xFFFFFFFFULL, v)) {
      return false;
    }
    d.shift_sync0_ns = shift ? static_cast<std::uint32_t>(v) : 0U;
  }
  return true;
}

}  // namespace

std::string Device::label() const {
  return "\"" + type + "\" (product " + hex(product_code) + " rev " + hex(revision) + ", " + file + ":" +
         std::to_string(line) + ")";
}

namespace {

// Vendors' ESI files are often ISO 8859-1 ("ISO8859-1", a spelling pugixml does not detect by
// itself): such a file is converted to UTF-8 first, so that names stay readable (and valid in
// the JSON made from them) and line numbers are counted in the text that was parsed.
std::string as_utf8(const std::string& text) {
  const auto end = text.find("?>");
  if (text.rfind("<?xml", 0) != 0 || end == std::string::npos) {
    return text;
  }
  std::string decl = text.substr(0, end);
  std::transform(decl.begin(), decl.end(), decl.begin(), [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); });
  const auto at = decl.find("encoding");
  if (at == std::string::npos) {
    return text;
  }
  const std::string enc = decl.substr(at);
  const bool latin1 = enc.find("8859-1") != std::string::npos || enc.find("latin1") != std::string::npos ||
                      enc.find("latin-1") != std::string::npos || enc.find("1252") != std::string::npos;
  if (!latin1) {
    return text;
  }
  std::string out;
  out.reserve(text.size() + text.size() / 8U);
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x80U) {
      out.push_back(ch);
    } else {
      out.push_back(static_cast<char>(0xC0U | (c >> 6U)));
      out.push_back(static_cast<char>(0x80U | (c & 0x3FU)));
    }
  }
  return out;
}

}  // namespace

bool parse_esi(const std::string& raw, const std::string& file, std::vector<Device>& out, std::string& err,
               std::vector<std::string>& warnings) {
  const std::string text = as_utf8(raw);
  const bool converted = text.size() != raw.size();
  Reader r(text, file);
  pugi::xml_document doc;
  // Converted text is UTF-8 now; its declaration still names the old encoding, so say it.
  const pugi::xml_parse_result res = doc.load_buffer(text.data(), text.size(), pugi::parse_default & ~pugi::parse_eol,
                                                     converted ? pugi::encoding_utf8 : pugi::encoding_auto);
  if (!res) {
    err = file + ":" + std::to_string(r.line_at(res.offset)) + ": not well-formed XML: " + res.description();
    return false;
  }
  const pugi::xml_node root = doc.child("EtherCATInfo");
  if (!root) {
    err = file + ": not an ESI file: the root element is <" + std::string(doc.document_element().name()) +
          ">, expected <EtherCATInfo> (ETG.2000)";
    return false;
  }
  const pugi::xml_node vid = root.child("Vendor").child("Id");
  if (!vid) {
    r.fail(root.child("Vendor") ? root.child("Vendor") : root, "missing <Vendor><Id>");
    err = r.err;
    return false;
  }
  std::uint64_t vendor = 0;
  if (!r.number(vid, "<Vendor><Id>", 0xFFFFFFFFULL, vendor)) {
    err = r.err;
    return false;
  }
  const pugi::xml_node devices = root.child("Descriptions").child("Devices");
  std::vector<Device> got;
  for (const pugi::xml_node& dev : devices.children("Device")) {
    Device d;
    if (!read_device(r, dev, static_cast<std::uint32_t>(vendor), d)) {
      err = r.err;
      return false;
    }
    r.warnings.clear();
    if (!read_body(r, dev, d)) {
      d.error = r.err;
      r.err.clear();
    }
    d.warnings = r.warnings;
    got.push_back(std::move(d));
  }
  if (got.empty()) {
    err = file + ":" + std::to_string(r.line(devices ? devices : root)) +
          ": no <Descriptions><Devices><Device> in the file";
    return false;
  }
  out.insert(out.end(), got.begin(), got.end());
  (void)warnings;  // the devices' own warnings are reported when a device is used (make_bus_config)
  return true;
}

bool load_esi(const std::string& path, std::vector<Device>& out, std::string& err, std::vector<std::string>& warnings) {
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    err = path + ": cannot read the file";
    return false;
  }
  std::stringstream ss;
  ss << f.rdbuf();
  return parse_esi(ss.str(), path, out, err, warnings);
}

bool check_library(const std::vector<Device>& library, std::string& err) {
  for (std::size_t i = 0; i < library.size(); ++i) {
    for (std::size_t k = 0; k < i; ++k) {
      const Device& a = library[k];
      const Device& b = library[i];
      if (a.vendor_id == b.vendor_id && a.product_code == b.product_code && a.revision == b.revision) {
        err = b.file + ":" + std::to_string(b.line) + ": <Device> \"" + b.type + "\" (vendor " + hex(b.vendor_id) +
              " product " + hex(b.product_code) + " rev " + hex(b.revision) + ") is already described at " + a.file +
              ":" + std::to_string(a.line) + ": give each device once";
        return false;
      }
    }
  }
  return true;
}

Image image(const Device& d) {
  Image im;
  // Per direction: the sync managers in order, each one's assigned PDOs in file order.
  const auto place = [&](const std::vector<Pdo>& pdos, std::vector<Placed>& out) {
    std::uint32_t bit = 0;
    for (std::size_t sm = 0; sm < d.sms.size(); ++sm) {
      const std::uint32_t start = bit;
      for (const Pdo& p : pdos) {
        if (p.sm != static_cast<int>(sm)) {
          continue;
        }
        for (const Entry& e : p.entries) {
          if (e.index != 0U) {
            out.push_back({&e, bit});
          }
          bit += e.bits;
        }
      }
      if (bit != start) {
        bit = (bit + 7U) / 8U * 8U;  // each sync manager's data starts on a byte
      }
    }
    return static_cast<std::uint16_t>(bit / 8U);
  };
  im.out_bytes = place(d.rx, im.out);
  im.in_bytes = place(d.tx, im.in);
  return im;
}

namespace {

bool parse_spec(const std::string& spec, std::string& what, std::uint32_t& rev, bool& has_rev, std::uint32_t& count) {
  std::string s = spec;
  count = 1;
  has_rev = false;
  if (const auto star = s.rfind('*'); star != std::string::npos) {
    std::uint64_t c = 0;
    if (!Reader::number_text(s.substr(star + 1U), 16, c) || c == 0U) {
      return false;
    }
    count = static_cast<std::uint32_t>(c);
    s = s.substr(0, star);
  }
  if (const auto slash = s.find('/'); slash != std::string::npos) {
    std::string r = s.substr(slash + 1U);
    if (r.rfind("0x", 0) == 0 || r.rfind("0X", 0) == 0) {
      r = "#x" + r.substr(2);
    }
    std::uint64_t v = 0;
    if (!Reader::number_text(r, 0xFFFFFFFFULL, v)) {
      return false;
    }
    rev = static_cast<std::uint32_t>(v);
    has_rev = true;
    s = s.substr(0, slash);
  }
  what = s;
  return !what.empty();
}

}  // namespace

bool resolve_bus(const std::vector<Device>& library, const std::vector<std::string>& specs,
                 std::vector<const Device*>& bus, std::string& err) {
  std::vector<const Device*> out;
  for (const std::string& spec : specs) {
    std::string what;
    std::uint32_t rev = 0;
    std::uint32_t count = 0;
    bool has_rev = false;
    if (!parse_spec(spec, what, rev, has_rev, count)) {
      err = "--device " + spec + ": expected PRODUCT or TYPE, optionally /REVISION and *COUNT (1..16), e.g. 0x00402001*6";
      return false;
    }
    std::string code = what;
    if (code.rfind("0x", 0) == 0 || code.rfind("0X", 0) == 0) {
      code = "#x" + code.substr(2);
    }
    std::uint64_t product = 0;
    const bool by_code = code.rfind("#x", 0) == 0 && Reader::number_text(code, 0xFFFFFFFFULL, product);
    std::vector<const Device*> match;
    for (const Device& d : library) {
      const bool hit = by_code ? d.product_code == product : d.type == what;
      if (hit && (!has_rev || d.revision == rev)) {
        match.push_back(&d);
      }
    }
    if (match.empty()) {
      err = "--device " + spec + ": no device of the ESI files has " + (by_code ? "product code " : "type ") + what +
            (has_rev ? " and revision " + hex(rev) : "");
      return false;
    }
    if (match.size() > 1U) {
      err = "--device " + spec + ": matches " + std::to_string(match.size()) + " devices (";
      for (std::size_t i = 0; i < match.size(); ++i) {
        err += (i == 0U ? "" : ", ") + match[i]->label();
      }
      err += "): name the revision (PRODUCT/REVISION)";
      return false;
    }
    if (!match.front()->error.empty()) {
      err = "--device " + spec + ": " + match.front()->error;
      return false;
    }
    out.insert(out.end(), count, match.front());
  }
  if (out.size() > 16U) {
    err = "--device: " + std::to_string(out.size()) + " subdevices; a bus configuration has at most 16";
    return false;
  }
  bus = out;
  return true;
}

bool resolve_scanned(const std::vector<Device>& library, const std::vector<Identity>& found,
                     std::vector<const Device*>& bus, std::string& err) {
  std::vector<const Device*> out;
  for (std::size_t i = 0; i < found.size(); ++i) {
    const Identity& id = found[i];
    const auto it = std::find_if(library.begin(), library.end(), [&](const Device& d) {
      return d.vendor_id == id.vendor_id && d.product_code == id.product_code && d.revision == id.revision;
    });
    if (it == library.end()) {
      err = "subdevice " + std::to_string(i + 1U) + " on the segment (vendor " + hex(id.vendor_id) + " product " +
            hex(id.product_code) + " revision " + hex(id.revision) + ") is described by none of the ESI files";
      return false;
    }
    if (!it->error.empty()) {
      err = "subdevice " + std::to_string(i + 1U) + " on the segment: " + it->error;
      return false;
    }
    out.push_back(&*it);
  }
  bus = out;
  return true;
}

namespace {

using OJson = nlohmann::ordered_json;

// The byte offset of a CiA 402 object in the image, checked for size and alignment.
bool offset_of(const Device& d, const std::vector<Placed>& placed, std::uint16_t index, std::uint8_t bits,
               const char* what, const std::string& where, std::uint16_t& out, std::string& err) {
  for (const Placed& p : placed) {
    if (p.entry->index != index || p.entry->sub != 0U) {
      continue;
    }
    if (p.entry->bits != bits || (p.bit % 8U) != 0U) {
      err = where + ": " + d.file + ":" + std::to_string(p.entry->line) + ": " + hex(index, 4) + " " + what + " is " +
            std::to_string(p.entry->bits) + " bits at bit " + std::to_string(p.bit) + "; expected " +
            std::to_string(bits) + " bits on a byte boundary";
      return false;
    }
    out = static_cast<std::uint16_t>(p.bit / 8U);
    return true;
  }
  err = where + ": the CiA 402 drive " + d.label() + " has no " + hex(index, 4) + " (" + what +
        ") in its default PDO assignment; the backend needs 0x6040, 0x607A, 0x6072 in the RxPDOs and 0x6041, "
        "0x6064, 0x606C, 0x6077 in the TxPDOs";
  return false;
}

// The bits of `names` found among the entries; the first `required` missing are listed in
// `missing` (the others are optional signals: left out of the configuration).
template <std::size_t N>
int named_bits(const std::vector<Placed>& placed, const char* const (&names)[N], std::size_t required, OJson& bits,
               std::string& missing) {
  int found = 0;
  for (std::size_t k = 0; k < N; ++k) {
    const char* n = names[k];
    const auto it = std::find_if(placed.begin(), placed.end(), [&](const Placed& p) { return p.entry->name == n; });
    if (it == placed.end()) {
      if (k < required) {
        missing += (missing.empty() ? "" : ", ") + std::string(n);
      }
      continue;
    }
    bits[n] = it->bit;
    ++found;
  }
  return found;
}

// Issue 37: the safety containers of our black-channel protocol in a device's default PDOs
// (docs/black-channel.md; ours, not FSoE): the objects 0x2E00 / 0x2E01 carry channel A's /
// B's container to the device, 0x2E10 / 0x2E11 the device's answers, field by field from
// subindex 1 (kind) on, subindex 5 the data when there is any. The connection ids and the
// watchdog are not in an ESI: ours by convention (0xA001/0xB001 the safe inputs, 0xA002/0xB002
// the safe outputs, 0xA010 + axis / 0xB010 + axis a drive; 10 ms).
struct FoundLink {
  char channel = 'A';
  std::uint32_t out_offset = 0;
  std::uint32_t in_offset = 0;
  std::uint32_t host_data = 0;
  std::uint32_t device_data = 0;
};

bool find_links(const Device& d, const Image& im, const std::string& where, std::vector<FoundLink>& out,
                std::string& err) {
  const auto at = [](const std::vector<Placed>& v, std::uint16_t index, std::uint8_t sub) -> const Placed* {
    const auto it = std::find_if(v.begin(), v.end(), [&](const Placed& p) { return p.entry->index == index && p.entry->sub == sub; });
    return it == v.end() ? nullptr : &*it;
  };
  for (const auto& [ch, to_dev, to_host] : {std::tuple{'A', std::uint16_t{0x2E00}, std::uint16_t{0x2E10}},
                                            std::tuple{'B', std::uint16_t{0x2E01}, std::uint16_t{0x2E11}}}) {
    const Placed* o = at(im.out, to_dev, 1);
    const Placed* i = at(im.in, to_host, 1);
    if (o == nullptr && i == nullptr) {
      continue;
    }
    if (o == nullptr || i == nullptr || (o->bit % 8U) != 0U || (i->bit % 8U) != 0U) {
      err = where + ": " + d.file + ": channel " + ch + "'s safety container needs " + hex(to_dev, 4) +
            ":01 in the RxPDOs and " + hex(to_host, 4) + ":01 in the TxPDOs, each on a byte boundary";
      return false;
    }
    FoundLink f;
    f.channel = ch;
    f.out_offset = o->bit / 8U;
    f.in_offset = i->bit / 8U;
    const Placed* od = at(im.out, to_dev, 5);
    const Placed* id = at(im.in, to_host, 5);
    f.host_data = od != nullptr ? od->entry->bits / 8U : 0U;
    f.device_data = id != nullptr ? id->entry->bits / 8U : 0U;
    out.push_back(f);
  }
  return true;
}

OJson links_json(const std::vector<FoundLink>& links, std::uint16_t base_a, std::uint16_t base_b) {
  OJson list = OJson::array();
  for (const FoundLink& l : links) {
    list.push_back({{"id", hex(l.channel == 'A' ? base_a : base_b, 4)},
                    {"channel", std::string(1, l.channel)},
                    {"out_offset", l.out_offset},
                    {"in_offset", l.in_offset},
                    {"watchdog_ms", 10}});
  }
  return list;
}

}  // namespace

bool make_bus_config(const std::vector<const Device*>& bus, const GenOptions& opt, std::string& json, std::string& err,
                     std::vector<std::string>& warnings) {
  if (bus.empty()) {
    err = "no subdevices: give the bus order (--device) or --scan";
    return false;
  }
  OJson root;
  root["comment"] = "Generated by `safestate ecat-config` from " + opt.source +
                    ". Roles: CiA 402 devices are drives (axes in bus order), the I/O terminals are found by their "
                    "PDO entry names (docs/ethercat.md, ESI).";
  root["frame_timeout_us"] = opt.frame_timeout_us;
  OJson subs = OJson::array();
  std::uint32_t axis = 0;
  std::uint32_t shift_ns = 0;
  bool shift_set = false;
  std::set<const Device*> reported;
  for (std::size_t i = 0; i < bus.size(); ++i) {
    const Device& d = *bus[i];
    const std::string where = "subdevice " + std::to_string(i + 1U) + " " + d.label();
    if (!d.error.empty()) {
      err = where + ": " + d.error;
      return false;
    }
    if (reported.insert(&d).second) {
      warnings.insert(warnings.end(), d.warnings.begin(), d.warnings.end());
    }
    const Image im = image(d);
    std::vector<FoundLink> links;  // issue 37 (looked for after the CiA 402 objects of a drive)
    OJson s;
    s["name"] = d.name.empty() ? d.type : d.name;
    s["role"] = "";
    s["vendor_id"] = hex(d.vendor_id);
    s["product_code"] = hex(d.product_code);
    s["revision"] = hex(d.revision);
    s["in_bytes"] = im.in_bytes;
    s["out_bytes"] = im.out_bytes;
    for (const SyncManager& sm : d.sms) {
      const bool pd = sm.kind == "Inputs" || sm.kind == "Outputs";
      const std::uint16_t want = sm.kind == "Inputs" ? im.in_bytes : im.out_bytes;
      if (pd && sm.default_size != 0U && sm.default_size != want) {
        warnings.push_back(where + ": <Sm> " + sm.kind + " DefaultSize " + std::to_string(sm.default_size) +
                           " differs from its assigned PDOs' " + std::to_string(want) + " bytes (the PDOs are used)");
      }
    }
    if (d.drive()) {
      ++axis;
      s["role"] = "drive";
      s["axis"] = axis;
      s["name"] = "drive axis " + std::to_string(axis);
      const auto own = opt.counts_by_axis.find(axis);
      const std::uint32_t counts = own != opt.counts_by_axis.end() ? own->second : opt.counts_per_revolution;
      if (counts == 0U) {
        err = where + ": drive axis " + std::to_string(axis) +
              " needs its encoder resolution: give --counts-per-rev N or AXIS=N (increments per revolution; an ESI "
              "does not carry it)";
        return false;
      }
      s["counts_per_revolution"] = counts;
      struct Obj {
        const char* key;
        std::uint16_t index;
        std::uint8_t bits;
        bool rx;
      };
      constexpr Obj objs[] = {{"controlword", 0x6040, 16, true},     {"target_position", 0x607A, 32, true},
                              {"max_torque", 0x6072, 16, true},      {"statusword", 0x6041, 16, false},
                              {"position_actual", 0x6064, 32, false}, {"velocity_actual", 0x606C, 32, false},
                              {"torque_actual", 0x6077, 16, false}};
      OJson pdo;
      for (const Obj& o : objs) {
        std::uint16_t off = 0;
        if (!offset_of(d, o.rx ? im.out : im.in, o.index, o.bits, o.key, where, off, err)) {
          return false;
        }
        pdo[o.key] = off;
      }
      // SPEC §14: the load-side encoder, 0x60E4:01 (additional position actual value), where
      // the drive's default TxPDO carries it.
      for (const Placed& p : im.in) {
        if (p.entry->index == 0x60E4U && p.entry->sub == 1U) {
          if (p.entry->bits != 32U || (p.bit % 8U) != 0U) {
            err = where + ": " + d.file + ":" + std::to_string(p.entry->line) + ": 0x60E4:01 load_position is " +
                  std::to_string(p.entry->bits) + " bits at bit " + std::to_string(p.bit) +
                  "; expected 32 bits on a byte boundary";
            return false;
          }
          pdo["load_position"] = p.bit / 8U;
        }
      }
      s["pdo"] = pdo;
      if (!find_links(d, im, where, links, err)) {
        return false;
      }
      if (!links.empty()) {  // issue 37: its load-side encoder to each channel again, protected
        s["safety_links"] = links_json(links, static_cast<std::uint16_t>(0xA010U + axis),
                                       static_cast<std::uint16_t>(0xB010U + axis));
      }
    } else {
      if (!find_links(d, im, where, links, err)) {
        return false;
      }
      OJson in_bits;
      OJson out_bits;
      std::string in_missing;
      std::string out_missing;
      const int ins = named_bits(im.in, ethercat::kInputBitNames, ethercat::kRequiredInputBits, in_bits, in_missing);
      const int outs =
          named_bits(im.out, ethercat::kOutputBitNames, ethercat::kRequiredOutputBits, out_bits, out_missing);
      const auto sep = std::find_if(im.in.begin(), im.in.end(), [](const Placed& p) { return p.entry->name == "separation_mm"; });
      const auto valid =
          std::find_if(im.in.begin(), im.in.end(), [](const Placed& p) { return p.entry->name == "separation_valid"; });
      const bool sensor = sep != im.in.end() || valid != im.in.end();
      if (!links.empty() && (sensor || ins > 0 || outs > 0)) {
        err = where + ": its PDOs carry both safety containers and named signals; one subdevice has one role";
        return false;
      }
      if (sensor && (ins > 0 || outs > 0)) {
        err = where + ": its PDO entries name both the distance sensor's separation and safety inputs or outputs; one "
                      "subdevice has one role";
        return false;
      }
      if (sensor) {
        // SPEC §11's distance sensor: separation_mm a 32-bit integer on a byte, separation_valid one bit.
        if (sep == im.in.end() || valid == im.in.end()) {
          err = where + ": a distance sensor's TxPDO needs both separation_mm and separation_valid; it lacks " +
                (sep == im.in.end() ? "separation_mm" : "separation_valid");
          return false;
        }
        if (sep->entry->bits != 32U || (sep->bit % 8U) != 0U ||
            (sep->entry->data_type != 0x0004U && sep->entry->data_type != 0x0007U)) {
          err = where + ": " + d.file + ":" + std::to_string(sep->entry->line) + ": separation_mm is " +
                std::to_string(sep->entry->bits) + " bits at bit " + std::to_string(sep->bit) + " (" +
                sep->entry->type_name + "); expected a 32-bit DINT on a byte boundary";
          return false;
        }
        if (valid->entry->bits != 1U) {
          err = where + ": " + d.file + ":" + std::to_string(valid->entry->line) + ": separation_valid is " +
                std::to_string(valid->entry->bits) + " bits; expected one (BOOL)";
          return false;
        }
        s["role"] = "distance_sensor";
        s["pdo"] = {{"separation_mm", sep->bit / 8U}};
        s["bits"] = {{"separation_valid", valid->bit}};
      } else if (ins > 0 && outs > 0) {
        err = where + ": its PDO entries name both safety inputs and safety outputs; one subdevice has one role";
        return false;
      } else if (ins > 0) {
        if (!in_missing.empty()) {
          err = where + ": the safety inputs' TxPDO entries lack " + in_missing;
          return false;
        }
        s["role"] = "safety_inputs";
        s["bits"] = in_bits;
      } else if (outs > 0) {
        if (!out_missing.empty()) {
          err = where + ": the safety outputs' RxPDO entries lack " + out_missing;
          return false;
        }
        s["role"] = "safety_outputs";
        s["bits"] = out_bits;
      } else if (!links.empty()) {
        // Issue 37: a safe terminal, known by its containers' data lengths.
        const bool inputs = std::all_of(links.begin(), links.end(),
                                        [](const FoundLink& l) { return l.host_data == 0U && l.device_data == 4U; });
        const bool outputs = std::all_of(links.begin(), links.end(),
                                         [](const FoundLink& l) { return l.host_data == 1U && l.device_data == 1U; });
        if (!inputs && !outputs) {
          err = where + ": its safety containers carry neither the safe inputs' data (0 bytes to it, 4 from it) nor "
                        "the safe outputs' (1 byte each way)";
          return false;
        }
        s["role"] = inputs ? "safe_inputs" : "safe_outputs";
        s["safety_links"] = inputs ? links_json(links, 0xA001, 0xB001) : links_json(links, 0xA002, 0xB002);
      } else {
        err = where + ": no role: neither a CiA 402 drive (<Profile><ProfileNo>402) nor a terminal whose PDO entries "
                      "carry our signal names (estop.a, ..., contactor, ..., separation_mm)";
        return false;
      }
    }
    if (!d.startup.empty()) {
      OJson list = OJson::array();
      for (const ethercat::StartupSdo& e : d.startup) {
        list.push_back({{"index", hex(e.index, 4)}, {"sub", e.sub}, {"size", e.size}, {"value", e.value}});
      }
      s["startup"] = list;
    }
    if (d.assign_activate != 0U) {
      s["dc"] = {{"assign_activate", hex(d.assign_activate, 4)}};
      if (shift_set && d.shift_sync0_ns != shift_ns) {
        warnings.push_back(where + ": ShiftTimeSync0 " + std::to_string(d.shift_sync0_ns) +
                           " ns differs from another device's; the bus uses the largest");
      }
      shift_ns = std::max(shift_ns, d.shift_sync0_ns);
      shift_set = true;
    }
    subs.push_back(s);
  }
  for (const auto& [a, n] : opt.counts_by_axis) {
    if (a == 0U || a > axis) {
      err = "--counts-per-rev " + std::to_string(a) + "=" + std::to_string(n) + ": there is no drive axis " +
            std::to_string(a) + " on this bus (" + std::to_string(axis) + " drives)";
      return false;
    }
  }
  if (shift_ns > 0U) {
    root["sync0_shift_us"] = (shift_ns + 999U) / 1000U;
  }
  root["subdevices"] = subs;
  // A name with bytes that are not UTF-8 (a file that says UTF-8 but is not) is written with
  // U+FFFD in their place rather than refused: names are labels.
  std::string text = root.dump(2, ' ', false, OJson::error_handler_t::replace);
  ethercat::BusConfig check;
  std::string why;
  if (!ethercat::parse_bus_config(text, check, why)) {
    err = "the configuration made from these devices is refused: " + why;
    return false;
  }
  json = text + "\n";
  return true;
}

}  // namespace safestate::hal::esi

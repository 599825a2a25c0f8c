// ETG.2000 ESI files are input from outside: every mistake is refused naming the file, the
// line and the element; the emulated devices' own ESI is the one description of both ends
// (the emulator's subdevices and SII, and the built-in bus configuration).
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "safestate/ecat/cell.hpp"
#include "safestate/ecat/esi_segment.hpp"
#include "safestate/hal/esi.hpp"
#include "safestate/hal/ethercat.hpp"

using namespace safestate::hal;
using safestate::ecat::SubdeviceDesc;

namespace {

const std::vector<std::string> kBusOrder = {"0x00D10018", "0x00D00003", "0x00402001*6", "0x00D15001", "0x00D1F001",
                                            "0x00D0F001"};
constexpr std::uint32_t kCounts = 1048576;  // the emulated drives' 2^20 increments per revolution

std::string builtin() { return esi::builtin_esi(); }

// `text` with the first `from` replaced by `to` (the test fails if `from` is not there).
std::string with(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) {
    text.replace(at, from.size(), to);
  }
  return text;
}

// The 1-based line of the first `needle` in `text`.
int line_of(const std::string& text, const std::string& needle) {
  const auto at = text.find(needle);
  EXPECT_NE(at, std::string::npos) << needle;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
}

// The error of reading `text` as "bad.xml" and making the emulated segment's bus of it. A
// mistake of the document or of an identity refuses the file (and leaves the library as it
// was); one further inside a device is that device's error, refused when the bus uses it.
std::string esi_error(const std::string& text) {
  std::vector<esi::Device> lib(1);
  std::vector<std::string> warnings;
  std::string err;
  if (!esi::parse_esi(text, "bad.xml", lib, err, warnings)) {
    EXPECT_EQ(lib.size(), 1U) << "a refused file added devices";
    return err;
  }
  EXPECT_TRUE(err.empty());
  lib.erase(lib.begin());
  const bool some_refused = std::any_of(lib.begin(), lib.end(), [](const esi::Device& d) { return !d.error.empty(); });
  EXPECT_TRUE(some_refused) << "no device of the file was refused";
  std::vector<const esi::Device*> bus;
  EXPECT_FALSE(esi::resolve_bus(lib, kBusOrder, bus, err));
  return err;
}

// The bus configuration made from `text` with the emulated segment's order, or its error.
bool generate(const std::string& text, std::string& json, std::string& err, std::vector<std::string>& warnings,
              std::uint32_t counts = kCounts) {
  std::vector<esi::Device> lib;
  if (!esi::parse_esi(text, "esi.xml", lib, err, warnings)) {
    return false;
  }
  std::vector<const esi::Device*> bus;
  if (!esi::resolve_bus(lib, kBusOrder, bus, err)) {
    return false;
  }
  esi::GenOptions opt;
  opt.counts_per_revolution = counts;
  opt.source = "esi.xml";
  return esi::make_bus_config(bus, opt, json, err, warnings);
}

std::string generate_error(const std::string& text, std::uint32_t counts = kCounts) {
  std::string json;
  std::string err;
  std::vector<std::string> warnings;
  EXPECT_FALSE(generate(text, json, err, warnings, counts));
  EXPECT_TRUE(json.empty());
  return err;
}

void expect_has(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "'" << part << "' not in: " << text;
}

}  // namespace

// The emulator's subdevices are exactly what the ESI describes: identity, name, PDO entries
// (index, subindex, size, data type, name), sync manager addresses, mailbox, device type,
// and so the SII image the emulator serves is the same word for word.
TEST(EsiEmulated, DescribesTheEmulatedSegment) {
  std::vector<SubdeviceDesc> from_esi;
  std::string err;
  ASSERT_TRUE(safestate::ecat::esi_segment(from_esi, err)) << err;
  const std::vector<SubdeviceDesc> segment = safestate::ecat::default_segment();
  ASSERT_EQ(from_esi.size(), segment.size());
  for (std::size_t i = 0; i < segment.size(); ++i) {
    const SubdeviceDesc& a = from_esi[i];
    const SubdeviceDesc& b = segment[i];
    EXPECT_EQ(a.vendor_id, b.vendor_id) << i;
    EXPECT_EQ(a.product_code, b.product_code) << i;
    EXPECT_EQ(a.revision, b.revision) << i;
    EXPECT_EQ(a.serial, b.serial) << i;
    EXPECT_EQ(a.name, b.name) << i;
    EXPECT_EQ(a.out_address, b.out_address) << i;
    EXPECT_EQ(a.in_address, b.in_address) << i;
    EXPECT_EQ(a.mailbox, b.mailbox) << i;
    EXPECT_EQ(a.device_type, b.device_type) << i;
    EXPECT_EQ(a.dc_sync0_required, b.dc_sync0_required) << i;
    for (const auto& [pa, pb] : {std::pair{&a.rx, &b.rx}, std::pair{&a.tx, &b.tx}}) {
      EXPECT_EQ(pa->index, pb->index) << i;
      ASSERT_EQ(pa->entries.size(), pb->entries.size()) << i;
      for (std::size_t k = 0; k < pb->entries.size(); ++k) {
        EXPECT_EQ(pa->entries[k].index, pb->entries[k].index) << i << "/" << k;
        EXPECT_EQ(pa->entries[k].subindex, pb->entries[k].subindex) << i << "/" << k;
        EXPECT_EQ(pa->entries[k].bits, pb->entries[k].bits) << i << "/" << k;
        EXPECT_EQ(pa->entries[k].data_type, pb->entries[k].data_type) << i << "/" << k;
        EXPECT_EQ(pa->entries[k].name, pb->entries[k].name) << i << "/" << k;
      }
    }
    EXPECT_EQ(safestate::ecat::build_sii(a), safestate::ecat::build_sii(b)) << i;
  }
}

// `safestate ecat-config` on the shipped ESI makes the built-in configuration: the same
// identities, image sizes, bits, offsets, scaling and start-up list, compared field by field
// as the backend reads them (parse_bus_config), not as text.
TEST(EsiEmulated, MakesTheBuiltInBusConfig) {
  std::string json;
  std::string err;
  std::vector<std::string> warnings;
  ASSERT_TRUE(generate(builtin(), json, err, warnings)) << err;
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  ethercat::BusConfig got;
  ethercat::BusConfig want;
  ASSERT_TRUE(ethercat::parse_bus_config(json, got, err)) << err;
  ASSERT_TRUE(ethercat::parse_bus_config(ethercat::default_bus_config(), want, err)) << err;
  EXPECT_EQ(got.frame_timeout_us, want.frame_timeout_us);
  EXPECT_EQ(got.scan_timeout_ms, want.scan_timeout_ms);
  EXPECT_EQ(got.stale_cycles, want.stale_cycles);
  EXPECT_EQ(got.watchdog_cycles, want.watchdog_cycles);
  EXPECT_EQ(got.sync0_shift_us, want.sync0_shift_us);
  ASSERT_EQ(got.subdevices.size(), want.subdevices.size());
  for (std::size_t i = 0; i < want.subdevices.size(); ++i) {
    const ethercat::Subdevice& g = got.subdevices[i];
    const ethercat::Subdevice& w = want.subdevices[i];
    EXPECT_EQ(g.role, w.role) << i;
    EXPECT_EQ(g.vendor_id, w.vendor_id) << i;
    EXPECT_EQ(g.product_code, w.product_code) << i;
    // The ESI always gives the revision, so the generated file always checks it; the
    // built-in file checks it on the I/O terminals only. Where both check, they agree, and
    // the generated one is the emulated revision.
    EXPECT_TRUE(g.check_revision) << i;
    EXPECT_EQ(g.revision, safestate::ecat::kRevision) << i;
    if (w.check_revision) {
      EXPECT_EQ(g.revision, w.revision) << i;
    }
    EXPECT_EQ(g.in_bytes, w.in_bytes) << i;
    EXPECT_EQ(g.out_bytes, w.out_bytes) << i;
    EXPECT_EQ(g.in_bit, w.in_bit) << i;
    EXPECT_EQ(g.out_bit, w.out_bit) << i;
    EXPECT_EQ(g.axis, w.axis) << i;
    EXPECT_DOUBLE_EQ(g.counts_per_rad, w.counts_per_rad) << i;
    EXPECT_EQ(g.controlword, w.controlword) << i;
    EXPECT_EQ(g.target_position, w.target_position) << i;
    EXPECT_EQ(g.max_torque, w.max_torque) << i;
    EXPECT_EQ(g.statusword, w.statusword) << i;
    EXPECT_EQ(g.position_actual, w.position_actual) << i;
    EXPECT_EQ(g.velocity_actual, w.velocity_actual) << i;
    EXPECT_EQ(g.torque_actual, w.torque_actual) << i;
    EXPECT_EQ(g.separation_mm, w.separation_mm) << i;
    EXPECT_EQ(g.separation_valid_bit, w.separation_valid_bit) << i;
    ASSERT_EQ(g.startup.size(), w.startup.size()) << i;
    for (std::size_t k = 0; k < w.startup.size(); ++k) {
      EXPECT_EQ(g.startup[k].index, w.startup[k].index) << i << "/" << k;
      EXPECT_EQ(g.startup[k].sub, w.startup[k].sub) << i << "/" << k;
      EXPECT_EQ(g.startup[k].size, w.startup[k].size) << i << "/" << k;
      EXPECT_EQ(g.startup[k].value, w.startup[k].value) << i << "/" << k;  // -3 and 0xFD: the same byte
    }
    // DC: the drives' ESI has AssignActivate 0x0300, the I/O terminals none; the built-in
    // default-bus.json says the same.
    EXPECT_EQ(g.dc_assign_activate, g.role == ethercat::Role::drive ? 0x0300U : 0U) << i;
    EXPECT_EQ(g.dc_assign_activate, w.dc_assign_activate) << i;
    if (g.role == ethercat::Role::drive) {
      EXPECT_EQ(g.name, w.name) << i;  // "drive axis N": the axes in bus order
    }
  }
  // Issue 37: the black channel's connections, found in the ESI by their container objects
  // (0x2E00.. ours), with the conventional ids and watchdog: the same table as the built-in.
  ASSERT_EQ(got.links.count, want.links.count);
  EXPECT_EQ(want.links.count, 16U);
  for (std::size_t i = 0; i < want.links.count; ++i) {
    const safestate::hal::LinkSpec& g = got.links.link[i];
    const safestate::hal::LinkSpec& w = want.links.link[i];
    EXPECT_EQ(g.id, w.id) << i;
    EXPECT_EQ(g.channel, w.channel) << i;
    EXPECT_EQ(g.role, w.role) << i;
    EXPECT_EQ(g.axis, w.axis) << i;
    EXPECT_EQ(g.host_data_bytes, w.host_data_bytes) << i;
    EXPECT_EQ(g.device_data_bytes, w.device_data_bytes) << i;
    EXPECT_EQ(g.watchdog_ms, w.watchdog_ms) << i;
    EXPECT_EQ(g.vendor_id, w.vendor_id) << i;
    EXPECT_EQ(g.product_code, w.product_code) << i;
    EXPECT_EQ(g.position, w.position) << i;
    EXPECT_EQ(g.counts_per_revolution, w.counts_per_revolution) << i;
  }
  for (std::size_t i = 0; i < want.subdevices.size(); ++i) {
    ASSERT_EQ(got.subdevices[i].links.size(), want.subdevices[i].links.size()) << i;
    for (std::size_t k = 0; k < want.subdevices[i].links.size(); ++k) {
      EXPECT_EQ(got.subdevices[i].links[k].out_offset, want.subdevices[i].links[k].out_offset) << i << "/" << k;
      EXPECT_EQ(got.subdevices[i].links[k].in_offset, want.subdevices[i].links[k].in_offset) << i << "/" << k;
    }
  }
}

// A safety container half in an ESI (channel A's to the device without its answer), or with
// data lengths of no safe role, is refused naming the device.
TEST(EsiBad, SafetyContainers) {
  std::string text = builtin();
  // the F-DI's answer to A renamed to an object that is not ours: A's container to it alone
  std::string bad = text;
  const auto at = bad.find("<Index>#x2E10</Index>", bad.find("SS-EMU-FDI"));
  ASSERT_NE(at, std::string::npos);
  bad.replace(at, 21, "<Index>#x2E20</Index>");
  expect_has(generate_error(bad), "channel A's safety container needs 0x2E00:01 in the RxPDOs and 0x2E10:01 in the TxPDOs");
  // the F-DO's data widened to 2 bytes each way: neither the safe inputs' nor the outputs'
  bad = text;
  std::size_t from = bad.find("SS-EMU-FDO");
  for (int k = 0; k < 4; ++k) {
    const std::string one = "<SubIndex>5</SubIndex><BitLen>8</BitLen><Name>";
    from = bad.find(one, from);
    ASSERT_NE(from, std::string::npos);
    const auto type = bad.find("<DataType>USINT</DataType>", from);
    ASSERT_NE(type, std::string::npos);
    bad.replace(type, 26, "<DataType>UINT</DataType>");
    bad.replace(from, one.size(), "<SubIndex>5</SubIndex><BitLen>16</BitLen><Name>");
  }
  expect_has(generate_error(bad), "its safety containers carry neither the safe inputs' data");
}

TEST(EsiEmulated, ReadsIdentityProfileMailboxAndDc) {
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(builtin(), "emu.xml", lib, err, warnings)) << err;
  ASSERT_EQ(lib.size(), 6U);
  const esi::Device& drive = lib[2];
  EXPECT_EQ(drive.vendor_id, 0x00005AFEU);
  EXPECT_EQ(drive.product_code, 0x00402001U);
  EXPECT_EQ(drive.type, "SS-EMU-CSP");
  EXPECT_TRUE(drive.drive());
  EXPECT_TRUE(drive.coe);
  EXPECT_EQ(drive.assign_activate, 0x0300U);
  EXPECT_EQ(drive.line, line_of(builtin(), "<Device Physics=\"YY\">\n        <Type ProductCode=\"#x00402001\""));
  ASSERT_EQ(drive.startup.size(), 4U);
  EXPECT_EQ(drive.startup[3].index, 0x6072U);
  EXPECT_EQ(drive.startup[3].size, 2U);
  EXPECT_EQ(drive.startup[3].value, 1000U);  // "e803", little-endian
  EXPECT_EQ(drive.startup[2].value, 0xFDU);  // -3 in one byte
  EXPECT_FALSE(lib[0].drive());
  EXPECT_FALSE(lib[0].coe);
  EXPECT_EQ(lib[0].assign_activate, 0U);
  const esi::Image im = esi::image(lib[0]);
  EXPECT_EQ(im.in_bytes, 4U);  // 25 contacts (K2's contact the last, SPEC §14) + 7 bits of padding
  EXPECT_EQ(im.out_bytes, 0U);
  EXPECT_EQ(im.in.size(), 25U);  // padding is not an entry to place
}

TEST(EsiBad, NotXml) {
  const std::string e = esi_error("<EtherCATInfo>\n  <Vendor><Id>#x1</Id>\n</EtherCATInfo>\n");
  expect_has(e, "bad.xml:3: not well-formed XML");
  expect_has(esi_error(""), "bad.xml:1: not well-formed XML");
  expect_has(esi_error("<?xml version=\"1.0\"?>\n<Foo/>\n"), "bad.xml: not an ESI file: the root element is <Foo>");
}

TEST(EsiBad, MissingVendorId) {
  const std::string text = with(builtin(), "<Id>#x00005AFE</Id>", "");
  expect_has(esi_error(text), "bad.xml:" + std::to_string(line_of(text, "<Vendor>")) + ": missing <Vendor><Id>");
  const std::string bad = with(builtin(), "<Id>#x00005AFE</Id>", "<Id>#xZZ</Id>");
  expect_has(esi_error(bad), "bad.xml:" + std::to_string(line_of(bad, "<Id>#xZZ")) + ": <Vendor><Id>: \"#xZZ\" is not a number");
}

TEST(EsiBad, MissingProductCodeOrRevision) {
  std::string text = with(builtin(), "ProductCode=\"#x00D00003\" ", "");
  expect_has(esi_error(text), "bad.xml:" + std::to_string(line_of(text, "RevisionNo=\"#x00010000\">SS-EMU-DO3")) +
                                  ": <Device> \"SS-EMU-DO3\": missing <Type ProductCode>");
  text = with(builtin(), "RevisionNo=\"#x00010000\">SS-EMU-CSP", ">SS-EMU-CSP");
  expect_has(esi_error(text), "<Device> \"SS-EMU-CSP\": missing <Type RevisionNo>");
  text = with(builtin(), "ProductCode=\"#x00402001\"", "ProductCode=\"#x1FFFFFFFF\"");
  expect_has(esi_error(text), "<Device> \"SS-EMU-CSP\" ProductCode: \"#x1FFFFFFFF\" is not a number 0..4294967295");
  text = with(builtin(), "<Devices>", "<Nothing>");
  text = with(text, "</Devices>", "</Nothing>");
  expect_has(esi_error(text), "no <Descriptions><Devices><Device>");
}

TEST(EsiBad, UnknownDataTypeOrWrongBitLen) {
  std::string text = with(builtin(), "<Name>Target position</Name><DataType>DINT</DataType>",
                          "<Name>Target position</Name><DataType>FIXED32</DataType>");
  std::string e = esi_error(text);
  expect_has(e, "bad.xml:" + std::to_string(line_of(text, "FIXED32")) + ": <Device> \"SS-EMU-CSP\" <RxPdo> 0x1600 <Entry> 2");
  expect_has(e, "(0x607A:0 \"Target position\"): unknown or unsupported <DataType> \"FIXED32\"");

  text = with(builtin(), "<BitLen>32</BitLen><Name>Velocity actual value</Name>",
              "<BitLen>16</BitLen><Name>Velocity actual value</Name>");
  e = esi_error(text);
  expect_has(e, "bad.xml:" + std::to_string(line_of(text, "Velocity actual value")) +
                    ": <Device> \"SS-EMU-CSP\" <TxPdo> 0x1A00 <Entry> 3 (0x606C:0 \"Velocity actual value\"): "
                    "<BitLen> 16 does not match <DataType> DINT (32 bits)");

  text = with(builtin(), "<Name>estop.b</Name><DataType>BOOL</DataType>", "<Name>estop.b</Name>");
  expect_has(esi_error(text), "(0x6000:2 \"estop.b\"): missing <DataType>");
  text = with(builtin(), "<SubIndex>1</SubIndex><BitLen>1</BitLen><Name>estop.a</Name>",
              "<SubIndex>1</SubIndex><BitLen>0</BitLen><Name>estop.a</Name>");
  expect_has(esi_error(text), "<TxPdo> 0x1A00 <Entry> 1 <BitLen>: expected 1..255 bits");
  text = with(builtin(), "<TxPdo Fixed=\"1\" Mandatory=\"1\" Sm=\"3\">", "<TxPdo Fixed=\"1\" Mandatory=\"1\" Sm=\"4\">");
  expect_has(esi_error(text), "<TxPdo> 0x1A00: Sm=\"4\" names no <Sm> of the device (it has 4)");
}

TEST(EsiBad, DriveWithoutTheCia402ObjectsItNeeds) {
  // 0x6077 torque actual gone from the TxPDO (padding in its place keeps the size).
  std::string text = with(builtin(),
                          "<Entry><Index>#x6077</Index><SubIndex>0</SubIndex><BitLen>16</BitLen><Name>Torque actual "
                          "value</Name><DataType>INT</DataType></Entry>",
                          "<Entry><Index>#x0</Index><BitLen>16</BitLen></Entry>");
  std::string e = generate_error(text);
  expect_has(e, "subdevice 3 \"SS-EMU-CSP\" (product 0x00402001 rev 0x00010000, esi.xml:");
  expect_has(e, "has no 0x6077 (torque_actual) in its default PDO assignment");
  // The controlword one bit off a byte boundary.
  text = with(builtin(), "<Entry><Index>#x6040</Index>",
              "<Entry><Index>#x0</Index><BitLen>1</BitLen></Entry><Entry><Index>#x6040</Index>");
  e = generate_error(text);
  expect_has(e, ": 0x6040 controlword is 16 bits at bit 1; expected 16 bits on a byte boundary");
  // A PDO not assigned by default (no Sm attribute) is an alternative: not in the image.
  text = with(builtin(), "<RxPdo Fixed=\"1\" Mandatory=\"1\" Sm=\"2\">", "<RxPdo Fixed=\"1\">");
  expect_has(generate_error(text), "has no 0x6040 (controlword) in its default PDO assignment");
  // The encoder resolution is not in an ESI: it must be given.
  expect_has(generate_error(builtin(), 0), "drive axis 1 needs its encoder resolution: give --counts-per-rev N or AXIS=N");
}

TEST(EsiBad, InitCmds) {
  const std::string cmd = "<Data>e803</Data>";
  std::string text = with(builtin(), cmd, "<Data>e803000000</Data>");
  std::string e = esi_error(text);
  expect_has(e, "bad.xml:" + std::to_string(line_of(text, "<Data>e803000000")) +
                    ": <Device> \"SS-EMU-CSP\" <Mailbox><CoE><InitCmd> 4 (0x6072:0) <Data>: 5 bytes; the master "
                    "writes 1, 2 or 4 bytes");
  expect_has(esi_error(with(builtin(), cmd, "<Data>e80300</Data>")), "<Data>: 3 bytes");
  expect_has(esi_error(with(builtin(), cmd, "<Data>e8g3</Data>")), "<Data>: \"e8g3\" is not a hex byte string");
  expect_has(esi_error(with(builtin(), cmd, "<Data></Data>")), "<Data>: \"\" is not a hex byte string");
  expect_has(esi_error(with(builtin(), "<InitCmd>\n              <Transition>PS</Transition>\n              <Index>#x6072</Index>",
                            "<InitCmd CompleteAccess=\"1\">\n              <Transition>PS</Transition>\n              <Index>#x6072</Index>")),
             "(0x6072:0): complete access is not supported");
  expect_has(esi_error(with(builtin(), "<Index>#x6072</Index>\n              <SubIndex>0</SubIndex>\n              <Data>e803</Data>",
                            "<Index>#x0072</Index>\n              <SubIndex>0</SubIndex>\n              <Data>e803</Data>")),
             "(0x0072:0): object index must be 0x1000..0xFFFF");
}

// IP commands are written too, before the PS ones (the order a master sends them in).
TEST(EsiEmulated, InitCmdsOfIpComeBeforePs) {
  const std::string text = with(builtin(), "<Transition>PS</Transition>\n              <Index>#x6072</Index>",
                                "<Transition>IP</Transition>\n              <Index>#x6072</Index>");
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(text, "ip.xml", lib, err, warnings)) << err;
  EXPECT_TRUE(warnings.empty());
  ASSERT_EQ(lib.size(), 6U);
  ASSERT_EQ(lib[2].startup.size(), 4U);
  EXPECT_EQ(lib[2].startup[0].index, 0x6072U);
  EXPECT_EQ(lib[2].startup[1].index, 0x6060U);
  EXPECT_EQ(lib[2].startup[2].index, 0x60C2U);
  EXPECT_EQ(lib[2].startup[3].index, 0x60C2U);
}

// An InitCmd of another transition (SO, OS, ...) is not written in PRE-OP: skipped, and the
// warning says so (with the line).
TEST(EsiWarn, InitCmdOfAnotherTransitionIsSkipped) {
  const std::string text = with(builtin(), "<Transition>PS</Transition>\n              <Index>#x6072</Index>",
                                "<Transition>SO</Transition>\n              <Index>#x6072</Index>");
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(text, "w.xml", lib, err, warnings)) << err;
  ASSERT_EQ(lib.size(), 6U);
  EXPECT_EQ(lib[2].startup.size(), 3U);
  EXPECT_TRUE(lib[0].warnings.empty());
  ASSERT_EQ(lib[2].warnings.size(), 1U);
  const int init_cmd_line = line_of(text, "<Transition>SO") - 1;  // the <InitCmd> element above it
  expect_has(lib[2].warnings[0], "w.xml:" + std::to_string(init_cmd_line) +
                              ": <Device> \"SS-EMU-CSP\" <Mailbox><CoE><InitCmd> 4 (0x6072:0): transition SO skipped");
}

// A device's warnings are reported once when the bus uses it (six drives, one warning).
TEST(EsiWarn, ReportedOncePerDeviceUsed) {
  const std::string text = with(builtin(), "<Transition>PS</Transition>\n              <Index>#x6072</Index>",
                                "<Transition>SO</Transition>\n              <Index>#x6072</Index>");
  std::string json;
  std::string err;
  std::vector<std::string> warnings;
  ASSERT_TRUE(generate(text, json, err, warnings)) << err;
  ASSERT_EQ(warnings.size(), 1U);
  expect_has(warnings[0], "transition SO skipped");
}

// One odd device does not make the rest of its file unusable: it is refused when used.
TEST(EsiBad, OneBadDeviceOnlyRefusedWhenUsed) {
  const std::string text = with(builtin(), "<Name>contactor</Name><DataType>BOOL</DataType>",
                                "<Name>contactor</Name><DataType>STRING(1)</DataType>");
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(text, "lib.xml", lib, err, warnings)) << err;
  ASSERT_EQ(lib.size(), 6U);
  EXPECT_TRUE(lib[0].error.empty());
  EXPECT_TRUE(lib[2].error.empty());
  expect_has(lib[1].error, "lib.xml:" + std::to_string(line_of(text, "STRING(1)")) +
                               ": <Device> \"SS-EMU-DO3\" <RxPdo> 0x1600 <Entry> 1 (0x7000:1 \"contactor\"): unknown or "
                               "unsupported <DataType> \"STRING(1)\"");
  std::vector<const esi::Device*> bus;
  EXPECT_TRUE(esi::resolve_bus(lib, {"0x00D10018", "0x00402001*6"}, bus, err)) << err;
  EXPECT_EQ(bus.size(), 7U);
  EXPECT_FALSE(esi::resolve_bus(lib, {"0x00D00003"}, bus, err));
  expect_has(err, "--device 0x00D00003: lib.xml:");
  EXPECT_EQ(bus.size(), 7U);  // refused: unchanged
  EXPECT_FALSE(esi::resolve_scanned(lib, {{0x5AFE, 0x00D10018, 0x00010000}, {0x5AFE, 0x00D00003, 0x00010000}}, bus, err));
  expect_has(err, "subdevice 2 on the segment: lib.xml:");
  safestate::ecat::SubdeviceDesc desc;
  EXPECT_FALSE(safestate::ecat::desc_from_esi(lib[1], 2, desc, err));
  expect_has(err, "unknown or unsupported <DataType> \"STRING(1)\"");
}

TEST(EsiBad, RolesFromNames) {
  // A DI terminal that lacks one of our signal names.
  std::string text = with(builtin(), "<Name>gate.b</Name>", "<Name>Input 4</Name>");
  expect_has(generate_error(text), "subdevice 1 \"SS-EMU-DI24\" (product 0x00D10018 rev 0x00010000, esi.xml:");
  expect_has(generate_error(text), "the safety inputs' TxPDO entries lack gate.b");
  // A terminal whose entries name none of our signals has no role.
  text = with(builtin(), "<Name>contactor</Name>", "<Name>Output 1</Name>");
  text = with(text, "<Name>brakes_release</Name>", "<Name>Output 2</Name>");
  text = with(text, "<Name>reset_lamp</Name>", "<Name>Output 3</Name>");
  for (int a = 1; a <= 6; ++a) {
    text = with(text, "<Name>brake_hold." + std::to_string(a) + "</Name>", "<Name>Output " + std::to_string(a + 3) + "</Name>");
  }
  text = with(text, "<Name>reduced_active</Name>", "<Name>Output 10</Name>");
  text = with(text, "<Name>contactor_k2</Name>", "<Name>Output 11</Name>");
  expect_has(generate_error(text), "subdevice 2 \"SS-EMU-DO3\"");
  expect_has(generate_error(text), "no role: neither a CiA 402 drive");
}

// SPEC §11's distance sensor is found by its entry names (separation_mm, separation_valid),
// checked for size; the DO terminal's reduced_active bit (SPEC §10) is optional.
TEST(EsiBad, DistanceSensorAndReducedActiveFromNames) {
  std::string json;
  std::string err;
  std::vector<std::string> warnings;
  ASSERT_TRUE(generate(builtin(), json, err, warnings)) << err;
  expect_has(json, "\"role\": \"distance_sensor\"");

  std::string text = with(builtin(), "<Name>separation_valid</Name>", "<Name>Status</Name>");
  expect_has(generate_error(text), "subdevice 9 \"SS-EMU-DIST\"");
  expect_has(generate_error(text), "needs both separation_mm and separation_valid; it lacks separation_valid");

  text = with(builtin(), "<BitLen>32</BitLen><Name>separation_mm</Name><DataType>DINT</DataType>",
              "<BitLen>16</BitLen><Name>separation_mm</Name><DataType>INT</DataType>");
  expect_has(generate_error(text), "separation_mm is 16 bits at bit 0 (INT); expected a 32-bit DINT");

  text = with(builtin(), "<Name>separation_mm</Name>", "<Name>estop.a</Name>");
  expect_has(generate_error(text), "one subdevice has one role");

  // A DO terminal without reduced_active still is the safety outputs, without that bit.
  text = with(builtin(), "<Name>reduced_active</Name>", "<Name>Output 10</Name>");
  ASSERT_TRUE(generate(text, json, err, warnings)) << err;
  ethercat::BusConfig cfg;
  ASSERT_TRUE(ethercat::parse_bus_config(json, cfg, err)) << err;
  EXPECT_EQ(cfg.subdevices[1].out_bit[9], ethercat::kNoBit);
  EXPECT_EQ(cfg.subdevices[1].out_bit[0], 0U);
}

TEST(EsiBus, DeviceSpecs) {
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(builtin(), "emu.xml", lib, err, warnings)) << err;
  std::vector<const esi::Device*> bus;
  ASSERT_TRUE(esi::resolve_bus(lib, {"SS-EMU-DI24", "0x00D00003/0x00010000", "#x00402001*2"}, bus, err)) << err;
  ASSERT_EQ(bus.size(), 4U);
  EXPECT_EQ(bus[0], &lib[0]);
  EXPECT_EQ(bus[1], &lib[1]);
  EXPECT_EQ(bus[2], &lib[2]);
  EXPECT_EQ(bus[3], &lib[2]);

  const std::vector<const esi::Device*> before = bus;
  EXPECT_FALSE(esi::resolve_bus(lib, {"0x00D10018", "0x12345678"}, bus, err));
  expect_has(err, "--device 0x12345678: no device of the ESI files has product code 0x12345678");
  EXPECT_EQ(bus, before);  // refused: unchanged
  EXPECT_FALSE(esi::resolve_bus(lib, {"0x00402001/0x00020000"}, bus, err));
  expect_has(err, "and revision 0x00020000");
  EXPECT_FALSE(esi::resolve_bus(lib, {"EL1008"}, bus, err));
  expect_has(err, "no device of the ESI files has type EL1008");
  EXPECT_FALSE(esi::resolve_bus(lib, {"0x00402001*0"}, bus, err));
  expect_has(err, "--device 0x00402001*0: expected PRODUCT or TYPE");
  EXPECT_FALSE(esi::resolve_bus(lib, {"0x00402001*9", "0x00402001*8"}, bus, err));
  expect_has(err, "17 subdevices; a bus configuration has at most 16");

  // Two revisions of one product: the spec must name the revision.
  const std::string rev2 = with(builtin(), "RevisionNo=\"#x00010000\">SS-EMU-CSP", "RevisionNo=\"#x00020000\">SS-EMU-CSP");
  ASSERT_TRUE(esi::parse_esi(rev2, "emu2.xml", lib, err, warnings)) << err;
  EXPECT_FALSE(esi::resolve_bus(lib, {"0x00402001"}, bus, err));
  expect_has(err, "--device 0x00402001: matches 2 devices");
  expect_has(err, "emu2.xml:");
  expect_has(err, "name the revision (PRODUCT/REVISION)");
  ASSERT_TRUE(esi::resolve_bus(lib, {"0x00402001/0x00020000"}, bus, err)) << err;
  EXPECT_EQ(bus[0]->revision, 0x00020000U);

  // A scanned segment: each identity must be described exactly.
  ASSERT_TRUE(esi::resolve_scanned(lib, {{0x5AFE, 0x00D10018, 0x00010000}, {0x5AFE, 0x00402001, 0x00020000}}, bus, err))
      << err;
  EXPECT_EQ(bus[1]->file, "emu2.xml");
  EXPECT_FALSE(esi::resolve_scanned(lib, {{0x5AFE, 0x00D10018, 0x00010001}}, bus, err));
  expect_has(err, "subdevice 1 on the segment (vendor 0x00005AFE product 0x00D10018 revision 0x00010001) is "
                  "described by none of the ESI files");
}

TEST(EsiBad, OneDeviceDescribedTwice) {
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(builtin(), "a.xml", lib, err, warnings)) << err;
  EXPECT_TRUE(esi::check_library(lib, err)) << err;
  ASSERT_TRUE(esi::parse_esi(builtin(), "b.xml", lib, err, warnings)) << err;
  EXPECT_FALSE(esi::check_library(lib, err));
  const std::string line = std::to_string(line_of(builtin(), "<Device Physics=\"YY\">\n        <Type ProductCode=\"#x00D10018\""));
  EXPECT_EQ(err, "b.xml:" + line + ": <Device> \"SS-EMU-DI24\" (vendor 0x00005AFE product 0x00D10018 rev 0x00010000) is "
                 "already described at a.xml:" + line + ": give each device once");
}

// Vendors' files are often ISO 8859-1 (spelt "ISO8859-1"): names come out as UTF-8. A file
// that says UTF-8 but is not still gives a valid configuration (U+FFFD in the name).
TEST(EsiEmulated, Latin1FilesAndStrayBytes) {
  std::string text = with(builtin(), "<?xml version=\"1.0\" encoding=\"UTF-8\"?>",
                          "<?xml version=\"1.0\" encoding=\"ISO8859-1\"?>");
  text = with(text, "SafeState emu DI24 safety contacts", "DI24 24 V \xB1 10 %");
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(text, "latin1.xml", lib, err, warnings)) << err;
  ASSERT_EQ(lib.size(), 6U);
  EXPECT_EQ(lib[0].name, "DI24 24 V \xC2\xB1 10 %");
  EXPECT_EQ(lib[2].line, line_of(text, "<Device Physics=\"YY\">\n        <Type ProductCode=\"#x00402001\""));

  const std::string stray = with(builtin(), "SafeState emu DI24 safety contacts", "DI24 \xB1");
  std::string json;
  ASSERT_TRUE(generate(stray, json, err, warnings)) << err;
  ethercat::BusConfig c;
  ASSERT_TRUE(ethercat::parse_bus_config(json, c, err)) << err;
  EXPECT_EQ(c.subdevices[0].name, "DI24 \xEF\xBF\xBD");
}

// Forms found in vendors' files: InitCmds inside <InitCmds>, an entry without <SubIndex>
// (0), a negative ShiftTimeSync0 (taken as 0, with a warning), a positive one (the bus shift).
TEST(EsiEmulated, VendorForms) {
  std::string text = with(builtin(), "<CoE SdoInfo=\"0\" PdoAssign=\"0\" PdoConfig=\"0\" CompleteAccess=\"0\">",
                          "<CoE SdoInfo=\"0\" PdoAssign=\"0\" PdoConfig=\"0\" CompleteAccess=\"0\"><InitCmds>");
  text = with(text, "</CoE>", "</InitCmds></CoE>");
  text = with(text, "<Index>#x6041</Index><SubIndex>0</SubIndex>", "<Index>#x6041</Index>");
  const std::string negative = with(text, "<ShiftTimeSync0>0</ShiftTimeSync0>", "<ShiftTimeSync0>-1000</ShiftTimeSync0>");
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(negative, "v.xml", lib, err, warnings)) << err;
  ASSERT_EQ(lib.size(), 6U);
  EXPECT_TRUE(lib[2].error.empty()) << lib[2].error;
  EXPECT_EQ(lib[2].startup.size(), 4U);
  EXPECT_EQ(lib[2].shift_sync0_ns, 0U);
  ASSERT_EQ(lib[2].warnings.size(), 1U);
  expect_has(lib[2].warnings[0], "v.xml:" + std::to_string(line_of(negative, "<ShiftTimeSync0>-1000")) +
                                     ": <Device> \"SS-EMU-CSP\" <Dc><OpMode> \"DC\" <ShiftTimeSync0> -1000 ns: a negative "
                                     "shift is not supported, 0 is used");
  std::string json;
  ASSERT_TRUE(generate(negative, json, err, warnings)) << err;
  ethercat::BusConfig c;
  ASSERT_TRUE(ethercat::parse_bus_config(json, c, err)) << err;
  EXPECT_EQ(c.subdevices[2].statusword, 0U);  // 0x6041 found with subindex 0
  // No shift from the ESI (the negative one taken as 0): the key is not written and the bus
  // gets the master's default (half the 1 ms cycle, docs/ethercat.md "Distributed clocks").
  EXPECT_EQ(json.find("sync0_shift_us"), std::string::npos);
  EXPECT_EQ(c.sync0_shift_us, ethercat::BusConfig{}.sync0_shift_us);
  ASSERT_EQ(c.subdevices[2].startup.size(), 4U);

  const std::string positive = with(text, "<ShiftTimeSync0>0</ShiftTimeSync0>", "<ShiftTimeSync0>250500</ShiftTimeSync0>");
  warnings.clear();
  ASSERT_TRUE(generate(positive, json, err, warnings)) << err;
  EXPECT_TRUE(warnings.empty());
  ASSERT_TRUE(ethercat::parse_bus_config(json, c, err)) << err;
  EXPECT_EQ(c.sync0_shift_us, 251U);  // rounded up: never earlier than the device asks
}

// The encoder resolution: one for every drive, and per axis where a drive differs.
TEST(EsiBus, CountsPerRevolutionPerAxis) {
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  ASSERT_TRUE(esi::parse_esi(builtin(), "emu.xml", lib, err, warnings)) << err;
  std::vector<const esi::Device*> bus;
  ASSERT_TRUE(esi::resolve_bus(lib, kBusOrder, bus, err)) << err;
  esi::GenOptions opt;
  opt.counts_per_revolution = kCounts;
  opt.counts_by_axis = {{3, 4096}};
  std::string json;
  ASSERT_TRUE(esi::make_bus_config(bus, opt, json, err, warnings)) << err;
  ethercat::BusConfig c;
  ASSERT_TRUE(ethercat::parse_bus_config(json, c, err)) << err;
  EXPECT_DOUBLE_EQ(c.subdevices[4].counts_per_rad * 6.283185307179586, 4096.0);  // axis 3
  EXPECT_DOUBLE_EQ(c.subdevices[5].counts_per_rad * 6.283185307179586, static_cast<double>(kCounts));

  opt.counts_per_revolution = 0;  // only axis 3 given: axis 1 has none
  json.clear();
  EXPECT_FALSE(esi::make_bus_config(bus, opt, json, err, warnings));
  expect_has(err, "subdevice 3 ");
  expect_has(err, "drive axis 1 needs its encoder resolution: give --counts-per-rev N or AXIS=N");
  EXPECT_TRUE(json.empty());
  opt.counts_per_revolution = kCounts;
  opt.counts_by_axis = {{7, 4096}};
  EXPECT_FALSE(esi::make_bus_config(bus, opt, json, err, warnings));
  EXPECT_EQ(err, "--counts-per-rev 7=4096: there is no drive axis 7 on this bus (6 drives)");
}

TEST(EsiBad, UnreadableFile) {
  std::vector<esi::Device> lib;
  std::vector<std::string> warnings;
  std::string err;
  EXPECT_FALSE(esi::load_esi("/nonexistent/x.xml", lib, err, warnings));
  EXPECT_EQ(err, "/nonexistent/x.xml: cannot read the file");
  EXPECT_TRUE(lib.empty());
}

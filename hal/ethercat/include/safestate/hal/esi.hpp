// ETG.2000 EtherCAT Slave Information (ESI) files: the vendors' XML description of their
// devices, read with pugixml, and turned into the bus configuration of the `ethercat`
// backend (`safestate ecat-config`, docs/ethercat.md "ESI"). An ESI file is input from
// outside: every value that is used is checked, and an error names the file, the line and
// the element. Nothing here runs in the real-time loop.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "safestate/hal/ethercat.hpp"

namespace safestate::hal::esi {

// One PDO entry (<Entry>): Index 0 is padding (no name, no data type).
struct Entry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint8_t bits = 0;
  std::uint16_t data_type = 0;  // CoE data type code (0x0001 BOOL, 0x0006 UINT, ...); 0 for padding
  std::string type_name;        // as written in the file (BOOL, UINT, DINT, ...)
  std::string name;
  int line = 0;
};

// One <RxPdo>/<TxPdo>. `sm` is the sync manager it is assigned to by default (the Sm
// attribute); -1 = not assigned by default (an alternative the master may assign).
struct Pdo {
  std::uint16_t index = 0;
  std::string name;
  int sm = -1;
  std::vector<Entry> entries;
  int line = 0;
};

// One <Sm>: its kind is the element's text (MBoxOut, MBoxIn, Outputs, Inputs).
struct SyncManager {
  std::string kind;
  std::uint16_t start = 0;
  std::uint16_t default_size = 0;
  std::uint8_t control = 0;
  bool enable = false;
};

// One device description (<Descriptions><Devices><Device>).
struct Device {
  std::string file;
  int line = 0;
  std::string type;  // <Type> text, e.g. "EL1008"
  std::string name;  // <Name> (the first one, English when LcId 1033 is given)
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  // <Profile>: CiA 402 drive (ProfileNo 402), its AddInfo (0x1000 = AddInfo << 16 | ProfileNo).
  std::uint32_t profile_no = 0;
  std::uint32_t add_info = 0;
  std::vector<SyncManager> sms;
  std::vector<Pdo> rx;  // outputs (master -> subdevice)
  std::vector<Pdo> tx;  // inputs
  bool coe = false;     // <Mailbox><CoE>
  // <Mailbox><CoE><InitCmd> with Transition IP or PS: the start-up list (the IP ones first,
  // each in file order).
  std::vector<ethercat::StartupSdo> startup;
  // <Dc><OpMode>: the first mode with a non-zero AssignActivate (0 = no DC mode) and its
  // ShiftTimeSync0 in ns (0 when absent).
  std::uint16_t assign_activate = 0;
  std::uint32_t shift_sync0_ns = 0;
  // A mistake in the device's description past its identity (a PDO entry, an InitCmd, ...):
  // "FILE:LINE: what" as parse_esi's errors. Such a device is refused when the bus uses it;
  // the other devices of its file stay usable.
  std::string error;
  std::vector<std::string> warnings;  // what of it is read but not used, reported when it is used
  [[nodiscard]] bool drive() const noexcept { return profile_no == 402U; }
  [[nodiscard]] std::string label() const;  // "SS-EMU-CSP (product 0x00402001 rev 0x00010000, FILE:LINE)"
};

// Where to find a PDO entry in a subdevice's process image (bits from the image's start).
struct Placed {
  const Entry* entry = nullptr;
  std::uint32_t bit = 0;
};
// The process image of a device with its default PDO assignment: the assigned PDOs of each
// sync manager in file order, each sync manager's data starting on a byte.
struct Image {
  std::uint16_t in_bytes = 0;
  std::uint16_t out_bytes = 0;
  std::vector<Placed> in;   // TxPDO entries (not padding)
  std::vector<Placed> out;  // RxPDO entries
};
Image image(const Device& d);

// Reads one ESI document (`file` names it in errors). Appends its devices to `out`. On an
// error of the document (not XML, not ESI, no vendor id, no devices) or of a device's
// identity (Type, ProductCode, RevisionNo) returns false with `err` = "FILE:LINE: what is
// wrong (element)" and leaves `out` unchanged; a mistake further inside one device is kept
// in that Device::error (refused when the bus uses it). `warnings` is kept for the API's
// sake: the devices carry their own (Device::warnings).
bool parse_esi(const std::string& text, const std::string& file, std::vector<Device>& out, std::string& err,
               std::vector<std::string>& warnings);
bool load_esi(const std::string& path, std::vector<Device>& out, std::string& err, std::vector<std::string>& warnings);

// Refuses a library in which two devices have the same identity (vendor, product, revision):
// the same file given twice, or two files describing one device; the error names both.
bool check_library(const std::vector<Device>& library, std::string& err);

// The ESI of the emulated segment (hal/ethercat/esi/SafeState-Emulated.xml), built in.
const char* builtin_esi() noexcept;
inline constexpr const char* kBuiltinEsiName = "hal/ethercat/esi/SafeState-Emulated.xml";

// The bus in order: which device stands at each position. `spec` is how the user named it:
// a product code ("0x00402001", "#x00402001") or the ESI <Type> ("EL1008"), optionally
// "/REVISION", optionally "*COUNT" for COUNT identical subdevices in a row
// ("0x00402001*6"). A spec that matches no device, or more than one (two revisions or two
// vendors) is refused.
bool resolve_bus(const std::vector<Device>& library, const std::vector<std::string>& specs,
                 std::vector<const Device*>& bus, std::string& err);
// The same from identities found on a segment (vendor, product, revision in bus order):
// each must match one device exactly.
struct Identity {
  std::uint32_t vendor_id = 0, product_code = 0, revision = 0;
};
bool resolve_scanned(const std::vector<Device>& library, const std::vector<Identity>& found,
                     std::vector<const Device*>& bus, std::string& err);

struct GenOptions {
  std::uint32_t counts_per_revolution = 0;  // the drives' encoder resolution; 0 = not given
  std::map<std::uint32_t, std::uint32_t> counts_by_axis;  // axis -> its own resolution (overrides the above)
  std::uint32_t frame_timeout_us = 20000;   // the built-in configuration's (docs/ethercat.md)
  std::string source;                       // what the comment says it was made from
};

// The bus configuration (JSON text, the schema of parse_bus_config) for `bus`. Roles:
// a CiA 402 device (ProfileNo 402) is a drive, axes numbered 1.. in bus order; a device
// whose TxPDO entries carry the names of our safety inputs (kInputBitNames) is the
// safety_inputs subdevice, one whose RxPDO entries carry the output names the
// safety_outputs one. The result is checked with parse_bus_config before it is returned.
bool make_bus_config(const std::vector<const Device*>& bus, const GenOptions& opt, std::string& json, std::string& err,
                     std::vector<std::string>& warnings);

}  // namespace safestate::hal::esi

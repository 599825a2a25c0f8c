// The CoE SDO server and object dictionary of the emulated drives (ETG.1000.6 5.6.2,
// CiA 402). Frames as ETG.1000.6 lays them out: mailbox header (6 bytes: length, address,
// channel/priority, type/counter), CoE header (2 bytes: service in bits 12..15), SDO header
// (command specifier, index, subindex) and up to 4 data bytes or a size and the data.
#include "safestate/ecat/coe.hpp"

#include <algorithm>
#include <array>
#include <utility>

#include "safestate/ecat/esc.hpp"
#include "safestate/hal/pdo_bytes.hpp"

namespace safestate::ecat::coe {

namespace {

constexpr std::uint8_t kMbxTypeError = 0x00;
constexpr std::uint8_t kMbxTypeCoe = 0x03;
constexpr std::uint16_t kCoeSdoRequest = 2;   // also the service of an abort (ETG.1000.6 5.6.2.7)
constexpr std::uint16_t kCoeSdoResponse = 3;
// Mailbox error reply details (ETG.1000.4 table 29).
constexpr std::uint16_t kMbxErrUnsupportedProtocol = 0x0002;
constexpr std::uint16_t kMbxErrServiceNotSupported = 0x0004;
constexpr std::uint16_t kMbxErrSizeTooShort = 0x0006;
constexpr std::uint16_t kMbxErrInvalidSize = 0x0008;
constexpr std::size_t kMbxHeader = 6;
constexpr std::size_t kSdoFrame = 16;  // mailbox + CoE + SDO headers + 4 data bytes

using hal::pdo::get16;
std::uint32_t get32(const std::uint8_t* p) noexcept { return static_cast<std::uint32_t>(hal::pdo::get32(p)); }
void put16(std::vector<std::uint8_t>& v, std::uint16_t x) {
  v.push_back(static_cast<std::uint8_t>(x & 0xFFU));
  v.push_back(static_cast<std::uint8_t>(x >> 8U));
}
void put32(std::vector<std::uint8_t>& v, std::uint32_t x) {
  put16(v, static_cast<std::uint16_t>(x & 0xFFFFU));
  put16(v, static_cast<std::uint16_t>(x >> 16U));
}

// The signed or unsigned range of a CoE data type of `bytes` bytes.
std::int64_t type_min(std::uint8_t bytes, bool is_signed) noexcept {
  return is_signed ? -(std::int64_t{1} << (bytes * 8U - 1U)) : 0;
}
std::int64_t type_max(std::uint8_t bytes, bool is_signed) noexcept {
  return is_signed ? (std::int64_t{1} << (bytes * 8U - 1U)) - 1 : (std::int64_t{1} << (bytes * 8U)) - 1;
}

std::int64_t decode(std::uint32_t raw, std::uint8_t bytes, bool is_signed) noexcept {
  const std::uint32_t mask = (bytes >= 4U) ? 0xFFFFFFFFU : ((1U << (bytes * 8U)) - 1U);
  const std::uint32_t v = raw & mask;
  if (!is_signed || bytes >= 4U) {
    return is_signed ? static_cast<std::int64_t>(static_cast<std::int32_t>(v)) : static_cast<std::int64_t>(v);
  }
  const std::uint32_t sign = 1U << (bytes * 8U - 1U);
  return ((v & sign) != 0U) ? static_cast<std::int64_t>(v) - (std::int64_t{1} << (bytes * 8U)) : static_cast<std::int64_t>(v);
}

Entry variable(std::uint16_t index, std::uint8_t sub, std::uint8_t bytes, bool is_signed, Access access,
               std::int64_t min, std::int64_t max, std::int64_t value, const char* name) {
  const std::uint32_t raw = static_cast<std::uint32_t>(value) & ((bytes >= 4U) ? 0xFFFFFFFFU : ((1U << (bytes * 8U)) - 1U));
  return Entry{.index = index, .sub = sub, .bytes = bytes, .is_signed = is_signed, .access = access, .min = min,
               .max = max, .value = raw, .reset = raw, .name = name, .text = {}, .pdo_offset = -1, .pdo_output = false};
}

// A read-only entry: its value is its whole range.
Entry fixed(std::uint16_t index, std::uint8_t sub, std::uint8_t bytes, std::uint32_t value, const char* name) {
  const std::int64_t v = decode(value, bytes, false);
  return variable(index, sub, bytes, false, Access::ro, v, v, v, name);
}

// The PDO mapping of an entry: index << 16 | subindex << 8 | bit length (ETG.1000.6 table 74).
std::uint32_t mapping(const PdoEntry& p) noexcept {
  return (static_cast<std::uint32_t>(p.index) << 16U) | (static_cast<std::uint32_t>(p.subindex) << 8U) | p.bits;
}

// 0x60C2 interpolation time period (CiA 402): value x 10^index s. The power-on value is the
// emulated drive's own cycle, with the largest exponent that keeps the value within 1..255.
void interpolation_period(std::uint32_t cycle_us, std::int64_t& value, std::int64_t& exponent) noexcept {
  std::uint64_t ns = static_cast<std::uint64_t>(cycle_us) * 1000U;
  value = static_cast<std::int64_t>(cycle_us);
  exponent = -6;
  for (std::int64_t e = -3; e >= -6; --e) {
    std::uint64_t unit = 1;
    for (std::int64_t k = e + 9; k > 0; --k) {
      unit *= 10U;
    }
    if (ns % unit == 0U && ns / unit >= 1U && ns / unit <= 255U) {
      value = static_cast<std::int64_t>(ns / unit);
      exponent = e;
      return;
    }
  }
}

std::vector<std::uint8_t> frame(std::uint8_t type, std::uint8_t& counter, const std::vector<std::uint8_t>& payload) {
  std::vector<std::uint8_t> f;
  put16(f, static_cast<std::uint16_t>(payload.size()));
  put16(f, 0);  // station address of the originator: 0 = the master
  f.push_back(0);  // channel 0, priority 0
  counter = static_cast<std::uint8_t>((counter >= 7U) ? 1U : counter + 1U);
  f.push_back(static_cast<std::uint8_t>(type | (counter << 4U)));
  f.insert(f.end(), payload.begin(), payload.end());
  return f;
}

std::vector<std::uint8_t> mailbox_error(std::uint8_t& counter, std::uint16_t detail) {
  std::vector<std::uint8_t> p;
  put16(p, 0x0001);  // type: mailbox command error
  put16(p, detail);
  return frame(kMbxTypeError, counter, p);
}

std::vector<std::uint8_t> sdo(std::uint8_t& counter, std::uint16_t service, std::uint8_t cmd, std::uint16_t index,
                              std::uint8_t sub, std::uint32_t data, const std::vector<std::uint8_t>& more = {}) {
  std::vector<std::uint8_t> p;
  put16(p, static_cast<std::uint16_t>(service << 12U));
  p.push_back(cmd);
  put16(p, index);
  p.push_back(sub);
  put32(p, data);
  p.insert(p.end(), more.begin(), more.end());
  return frame(kMbxTypeCoe, counter, p);
}

}  // namespace

const char* abort_text(std::uint32_t code) noexcept {
  switch (code) {
    case 0x05030000: return "Toggle bit not changed";
    case 0x05040000: return "SDO protocol timeout";
    case 0x05040001: return "Client/Server command specifier not valid or unknown";
    case 0x05040005: return "Out of memory";
    case 0x06010000: return "Unsupported access to an object";
    case 0x06010001: return "Attempt to read a write-only object";
    case 0x06010002: return "Attempt to write a read-only object";
    case 0x06010006: return "Object mapped to RxPDO, SDO download blocked";
    case 0x06020000: return "The object does not exist in the object dictionary";
    case 0x06040041: return "The object cannot be mapped into the PDO";
    case 0x06040043: return "General parameter incompatibility";
    case 0x06060000: return "Access failed due to a hardware error";
    case 0x06070010: return "Data type does not match, length of service parameter does not match";
    case 0x06070012: return "Data type does not match, length of service parameter too high";
    case 0x06070013: return "Data type does not match, length of service parameter too low";
    case 0x06090011: return "Subindex does not exist";
    case 0x06090030: return "Value range of parameter exceeded";
    case 0x06090031: return "Value of parameter written too high";
    case 0x06090032: return "Value of parameter written too low";
    case 0x08000000: return "General error";
    case 0x08000020: return "Data cannot be transferred or stored to the application";
    case 0x08000021: return "Data cannot be transferred or stored to the application because of local control";
    case 0x08000022: return "Data cannot be transferred or stored to the application because of the present device state";
    case 0x08000023: return "Object dictionary dynamic generation fails or no object dictionary is present";
    default: return "unknown abort code";
  }
}

std::int64_t Entry::as_int() const noexcept { return decode(value, bytes, is_signed); }

Dictionary::Dictionary(const SubdeviceDesc& d) {
  std::vector<Entry>& v = entries_;
  v.push_back(fixed(0x1000, 0, 4, d.device_type, "Device type"));
  Entry name = fixed(0x1008, 0, 0, 0, "Manufacturer device name");
  name.text = d.name;  // VISIBLE_STRING: longer than 4 bytes, a normal (not expedited) upload
  v.push_back(name);
  v.push_back(fixed(0x1018, 0, 1, 4, "Identity: number of entries"));
  v.push_back(fixed(0x1018, 1, 4, d.vendor_id, "Vendor ID"));
  v.push_back(fixed(0x1018, 2, 4, d.product_code, "Product code"));
  v.push_back(fixed(0x1018, 3, 4, d.revision, "Revision number"));
  v.push_back(fixed(0x1018, 4, 4, d.serial, "Serial number"));
  // Sync manager communication types (ETG.1000.6 table 67): mailbox out, mailbox in,
  // process data outputs, process data inputs.
  v.push_back(fixed(0x1C00, 0, 1, 4, "Sync manager types: number of entries"));
  for (std::uint8_t sm = 1; sm <= 4; ++sm) {
    v.push_back(fixed(0x1C00, sm, 1, sm, "Sync manager type"));
  }
  // PDO assignment (SM2 outputs, SM3 inputs) and the fixed mapping of each PDO.
  const std::array<std::pair<std::uint16_t, const Pdo*>, 2> assignments{{{0x1C12, &d.rx}, {0x1C13, &d.tx}}};
  for (const auto& [assign, pdo] : assignments) {
    if (pdo->entries.empty()) {
      continue;
    }
    v.push_back(variable(assign, 0, 1, false, Access::rw_preop, 0, 1, 1, "PDO assignment: number of PDOs"));
    v.push_back(variable(assign, 1, 2, false, Access::rw_preop, pdo->index, pdo->index, pdo->index, "Assigned PDO"));
    v.push_back(fixed(pdo->index, 0, 1, static_cast<std::uint32_t>(pdo->entries.size()), "PDO mapping: number of entries"));
    std::uint8_t sub = 1;
    for (const PdoEntry& e : pdo->entries) {
      v.push_back(fixed(pdo->index, sub++, 4, mapping(e), "Mapped object"));
    }
  }
  v.push_back(fixed(0x6502, 0, 4, 0x00000080, "Supported drive modes: CSP"));
  // 0 (no mode) at power-on; the drive offers CSP (8) only: any other mode is out of range.
  v.push_back(variable(0x6060, 0, 1, true, Access::rw_preop, 8, 8, 0, "Modes of operation"));
  v.push_back(variable(0x6061, 0, 1, true, Access::ro, -128, 127, 0, "Modes of operation display"));
  // Quick stop option code: the emulated drive knows option 2 only (slow down on the quick
  // stop ramp, then Switch on disabled).
  v.push_back(variable(0x605A, 0, 2, true, Access::rw, 2, 2, 2, "Quick stop option code"));
  std::int64_t period = 0;
  std::int64_t exponent = 0;
  interpolation_period(d.cycle_us, period, exponent);
  v.push_back(fixed(0x60C2, 0, 1, 2, "Interpolation time period: number of entries"));
  v.push_back(variable(0x60C2, 1, 1, false, Access::rw_preop, 1, 255, period, "Interpolation time period value"));
  v.push_back(variable(0x60C2, 2, 1, true, Access::rw_preop, -6, -3, exponent, "Interpolation time index"));
  v.push_back(variable(0x6072, 0, 2, false, Access::rw, 0, 3000, 1000, "Max torque (per mille of rated)"));
  // The objects of the PDOs: a mapped object reads from the process RAM.
  const std::array<std::pair<const Pdo*, bool>, 2> pdos{{{&d.rx, true}, {&d.tx, false}}};
  for (const auto& [pdo, output] : pdos) {
    int offset = 0;
    for (const PdoEntry& p : pdo->entries) {
      const auto bytes = static_cast<std::uint8_t>(p.bits / 8U);
      if (p.index != 0 && (p.bits % 8U) == 0U && bytes >= 1U && bytes <= 4U) {
        Entry* e = find_mut(p.index, p.subindex);
        if (e == nullptr) {
          const bool is_signed = p.data_type == 0x02 || p.data_type == 0x03 || p.data_type == 0x04;
          entries_.push_back(variable(p.index, p.subindex, bytes, is_signed, output ? Access::rw : Access::ro,
                                      type_min(bytes, is_signed), type_max(bytes, is_signed), 0, "Process data object"));
          e = &entries_.back();
        }
        e->pdo_offset = offset;
        e->pdo_output = output;
      }
      offset += p.bits / 8;
    }
  }
}

void Dictionary::reset() noexcept {
  for (Entry& e : entries_) {
    e.value = e.reset;
  }
}

Entry* Dictionary::find_mut(std::uint16_t index, std::uint8_t sub) noexcept {
  const auto it = std::find_if(entries_.begin(), entries_.end(),
                               [&](const Entry& e) { return e.index == index && e.sub == sub; });
  return it == entries_.end() ? nullptr : &*it;
}

const Entry* Dictionary::find(std::uint16_t index, std::uint8_t sub) const noexcept {
  return const_cast<Dictionary*>(this)->find_mut(index, sub);
}

bool Dictionary::has_index(std::uint16_t index) const noexcept {
  return std::any_of(entries_.begin(), entries_.end(), [&](const Entry& e) { return e.index == index; });
}

std::int64_t Dictionary::value(std::uint16_t index, std::uint8_t sub) const noexcept {
  const Entry* e = find(index, sub);
  return e == nullptr ? 0 : e->as_int();
}

std::uint32_t Dictionary::upload(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> outputs,
                                 std::span<const std::uint8_t> inputs, AlState state,
                                 std::vector<std::uint8_t>& out) const {
  const Entry* e = find(index, sub);
  if (e == nullptr) {
    return has_index(index) ? abort_code::no_subindex : abort_code::no_object;
  }
  std::uint32_t raw = e->value;
  if (e->pdo_offset >= 0 && (!e->pdo_output || state == AlState::op)) {
    const std::span<const std::uint8_t> ram = e->pdo_output ? outputs : inputs;
    const auto o = static_cast<std::size_t>(e->pdo_offset);
    raw = 0;
    for (std::size_t k = 0; k < e->bytes && o + k < ram.size(); ++k) {
      raw |= static_cast<std::uint32_t>(ram[o + k]) << (8U * k);
    }
  }
  out.clear();
  if (!e->text.empty()) {
    out.assign(e->text.begin(), e->text.end());
    return 0;
  }
  for (std::size_t k = 0; k < e->bytes; ++k) {
    out.push_back(static_cast<std::uint8_t>(raw >> (8U * k)));
  }
  return 0;
}

std::uint32_t Dictionary::download(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                                   AlState state) {
  Entry* e = find_mut(index, sub);
  if (e == nullptr) {
    return has_index(index) ? abort_code::no_subindex : abort_code::no_object;
  }
  if (refuse_code_ != 0U && index == refuse_index_ && sub == refuse_sub_) {
    return refuse_code_;
  }
  if (e->access == Access::ro) {
    return abort_code::read_only;
  }
  if (e->access == Access::rw_preop && state != AlState::preop) {
    return abort_code::state;
  }
  if (e->pdo_offset >= 0 && e->pdo_output && state == AlState::op) {
    return abort_code::rxpdo_mapped;  // the process data owns it in OP
  }
  if (data.size() != e->bytes) {
    return abort_code::length;
  }
  std::uint32_t raw = 0;
  for (std::size_t k = 0; k < data.size(); ++k) {
    raw |= static_cast<std::uint32_t>(data[k]) << (8U * k);
  }
  const std::int64_t v = decode(raw, e->bytes, e->is_signed);
  if (v < e->min || v > e->max) {
    return abort_code::value_range;
  }
  e->value = raw;
  if (index == 0x6060) {
    find_mut(0x6061, 0)->value = raw;  // the drive follows the requested mode at once
  }
  return 0;
}

std::vector<std::uint8_t> serve(Dictionary& od, std::span<const std::uint8_t> req, std::span<const std::uint8_t> outputs,
                                std::span<const std::uint8_t> inputs, AlState state, std::size_t mailbox_bytes,
                                std::uint8_t& counter) {
  if (req.size() < kMbxHeader) {
    return {};
  }
  const std::size_t length = get16(req.data());
  if (kMbxHeader + length > req.size()) {
    return mailbox_error(counter, kMbxErrInvalidSize);
  }
  if ((req[5] & 0x0FU) != kMbxTypeCoe || od.empty()) {
    return mailbox_error(counter, kMbxErrUnsupportedProtocol);
  }
  if (length < 2U || (get16(&req[6]) >> 12U) != kCoeSdoRequest) {
    return mailbox_error(counter, length < 2U ? kMbxErrSizeTooShort : kMbxErrServiceNotSupported);
  }
  if (length < 10U) {
    return mailbox_error(counter, kMbxErrSizeTooShort);
  }
  const std::uint8_t cmd = req[8];
  const std::uint16_t index = get16(&req[9]);
  const std::uint8_t sub = req[11];
  const std::uint8_t ccs = cmd >> 5U;
  const auto refused = [&](std::uint32_t code) { return sdo(counter, kCoeSdoRequest, 0x80, index, sub, code); };
  if (ccs == 4U) {
    return {};  // the master aborts: nothing to answer
  }
  if (ccs != 1U && ccs != 2U) {
    // Segments (ccs 0, 3) and anything else: only whole values are transferred.
    return refused(abort_code::command);
  }
  if ((cmd & 0x10U) != 0U) {
    return refused(abort_code::unsupported_access);  // complete access is not offered
  }
  if (ccs == 2U) {  // initiate upload
    std::vector<std::uint8_t> data;
    if (const std::uint32_t code = od.upload(index, sub, outputs, inputs, state, data); code != 0U) {
      return refused(code);
    }
    if (data.size() <= 4U) {  // expedited: the size in bits 2..3 as 4 - n
      std::uint32_t v = 0;
      for (std::size_t k = 0; k < data.size(); ++k) {
        v |= static_cast<std::uint32_t>(data[k]) << (8U * k);
      }
      return sdo(counter, kCoeSdoResponse, static_cast<std::uint8_t>(0x43U | ((4U - data.size()) << 2U)), index, sub, v);
    }
    if (kSdoFrame + data.size() > mailbox_bytes) {
      return refused(abort_code::command);  // would need a segmented upload
    }
    return sdo(counter, kCoeSdoResponse, 0x41, index, sub, static_cast<std::uint32_t>(data.size()), data);
  }
  // initiate download: expedited (bit 1) with the size in bits 2..3 when bit 0 says so, or
  // normal with the size in the data field and the value after it.
  std::span<const std::uint8_t> value;
  if ((cmd & 0x02U) != 0U) {
    const Entry* e = od.find(index, sub);
    const std::size_t n = ((cmd & 0x01U) != 0U) ? 4U - ((cmd >> 2U) & 0x03U) : (e != nullptr ? e->bytes : 4U);
    value = req.subspan(12, n);
  } else {
    if ((cmd & 0x01U) == 0U) {
      return refused(abort_code::length);  // a normal download must state its size
    }
    const std::uint32_t size = get32(&req[12]);
    if (size > length - 10U) {
      return refused(size > mailbox_bytes ? abort_code::command : abort_code::length);  // segmented: not offered
    }
    value = req.subspan(kSdoFrame, size);
  }
  if (const std::uint32_t code = od.download(index, sub, value, state); code != 0U) {
    return refused(code);
  }
  return sdo(counter, kCoeSdoResponse, 0x60, index, sub, 0);
}

}  // namespace safestate::ecat::coe

// The SII EEPROM image of an emulated subdevice, laid out as ETG.2010 specifies: the
// fixed header words (configuration area, identity, mailbox, size), then categories.
// A subdevice without a mailbox (the I/O terminals) has its fixed PDO layout in the
// TxPDO/RxPDO categories only, which is how masters map simple subdevices without CoE; one
// with a mailbox (the drives) says so in the standard mailbox words and the CoE protocol
// bit, lists its mailbox sync managers first, and masters read its PDO assignment by SDO.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "safestate/ecat/esc.hpp"

namespace safestate::ecat {

std::size_t Pdo::bytes() const noexcept {
  std::size_t bits = 0;
  for (const PdoEntry& e : entries) {
    bits += e.bits;
  }
  return (bits + 7U) / 8U;
}

namespace {

// ETG.2010 category types.
constexpr std::uint16_t kCatStrings = 10;
constexpr std::uint16_t kCatGeneral = 30;
constexpr std::uint16_t kCatFmmu = 40;
constexpr std::uint16_t kCatSyncM = 41;
constexpr std::uint16_t kCatTxPdo = 50;
constexpr std::uint16_t kCatRxPdo = 51;
constexpr std::uint16_t kCatEnd = 0xFFFF;

// A byte-wise builder that packs into little-endian 16-bit words at the end.
class Bytes {
 public:
  void u8(std::uint8_t v) { b_.push_back(v); }
  void u16(std::uint16_t v) {
    u8(static_cast<std::uint8_t>(v & 0xFFU));
    u8(static_cast<std::uint8_t>(v >> 8U));
  }
  void u32(std::uint32_t v) {
    u16(static_cast<std::uint16_t>(v & 0xFFFFU));
    u16(static_cast<std::uint16_t>(v >> 16U));
  }
  void pad_even() {
    if ((b_.size() % 2U) != 0U) {
      u8(0);
    }
  }
  [[nodiscard]] std::size_t size() const { return b_.size(); }
  [[nodiscard]] const std::vector<std::uint8_t>& data() const { return b_; }

 private:
  std::vector<std::uint8_t> b_;
};

// Strings are referred to by 1-based index; index 0 = no string.
class Strings {
 public:
  std::uint8_t add(const std::string& s) {
    if (s.empty() || list_.size() >= 255U) {
      return 0;
    }
    list_.push_back(s.substr(0, 255));
    return static_cast<std::uint8_t>(list_.size());
  }
  [[nodiscard]] const std::vector<std::string>& list() const { return list_; }

 private:
  std::vector<std::string> list_;
};

void category(Bytes& out, std::uint16_t type, const Bytes& body) {
  out.u16(type);
  out.u16(static_cast<std::uint16_t>((body.size() + 1U) / 2U));  // length in words
  for (std::uint8_t v : body.data()) {
    out.u8(v);
  }
  out.pad_even();
}

void pdo_category(Bytes& out, std::uint16_t type, const Pdo& pdo, std::uint8_t sm, Strings& s) {
  if (pdo.entries.empty()) {
    return;
  }
  Bytes b;
  b.u16(pdo.index);
  b.u8(static_cast<std::uint8_t>(pdo.entries.size()));
  b.u8(sm);
  b.u8(0);  // no DC synchronisation
  b.u8(0);  // no name
  b.u16(0); // flags: fixed content (ETG.2010 table 14)
  for (const PdoEntry& e : pdo.entries) {
    b.u16(e.index);
    b.u8(e.subindex);
    b.u8(e.index == 0 ? 0 : s.add(e.name));
    b.u8(e.data_type);
    b.u8(e.bits);
    b.u16(0);
  }
  category(out, type, b);
}

void sync_manager(Bytes& b, std::uint16_t start, std::size_t bytes, std::uint8_t control, std::uint8_t type) {
  b.u16(start);
  b.u16(static_cast<std::uint16_t>(bytes));
  b.u8(control);
  b.u8(0);     // status
  b.u8(0x01);  // enable
  b.u8(type);  // 1 mailbox out, 2 mailbox in, 3 process data outputs, 4 process data inputs
}

// CRC-8 (x^8 + x^2 + x + 1, initial 0xFF) over the first 14 bytes (ETG.2010 2.2).
std::uint8_t config_crc(const std::vector<std::uint16_t>& w) {
  std::uint8_t crc = 0xFF;
  for (std::size_t i = 0; i < 14U; ++i) {
    crc ^= static_cast<std::uint8_t>((i % 2U == 0U) ? (w[i / 2U] & 0xFFU) : (w[i / 2U] >> 8U));
    for (int k = 0; k < 8; ++k) {
      const unsigned c = crc;
      crc = static_cast<std::uint8_t>(((c & 0x80U) != 0U) ? ((c << 1U) ^ 0x07U) : (c << 1U));
    }
  }
  return crc;
}

}  // namespace

std::vector<std::uint16_t> build_sii(const SubdeviceDesc& d) {
  std::vector<std::uint16_t> w(0x40, 0);
  w[0x08] = static_cast<std::uint16_t>(d.vendor_id & 0xFFFFU);
  w[0x09] = static_cast<std::uint16_t>(d.vendor_id >> 16U);
  w[0x0A] = static_cast<std::uint16_t>(d.product_code & 0xFFFFU);
  w[0x0B] = static_cast<std::uint16_t>(d.product_code >> 16U);
  w[0x0C] = static_cast<std::uint16_t>(d.revision & 0xFFFFU);
  w[0x0D] = static_cast<std::uint16_t>(d.revision >> 16U);
  w[0x0E] = static_cast<std::uint16_t>(d.serial & 0xFFFFU);
  w[0x0F] = static_cast<std::uint16_t>(d.serial >> 16U);
  if (d.mailbox) {
    w[0x18] = kMailboxOut;  // standard receive mailbox (master -> subdevice): offset, size
    w[0x19] = kMailboxBytes;
    w[0x1A] = kMailboxIn;   // standard send mailbox (subdevice -> master)
    w[0x1B] = kMailboxBytes;
    w[0x1C] = 0x0004;       // mailbox protocols: CoE
  }
  w[0x3E] = 0x000F;  // EEPROM size: 16 Kbit
  w[0x3F] = 0x0001;  // SII version
  w[0x07] = config_crc(w);

  Strings s;
  const std::uint8_t name = s.add(d.name);
  const bool has_out = !d.rx.entries.empty();
  const bool has_in = !d.tx.entries.empty();
  const std::uint8_t sm_first_pd = d.mailbox ? 2 : 0;  // SM0/SM1 are the mailbox
  const auto sm_out = sm_first_pd;
  const auto sm_in = static_cast<std::uint8_t>(sm_first_pd + (has_out ? 1 : 0));

  Bytes cats;
  Bytes general;
  general.u8(0);     // group
  general.u8(0);     // image
  general.u8(name);  // order
  general.u8(name);  // name
  general.u8(0);
  general.u8(d.mailbox ? 0x01 : 0);  // CoE details: SDO (no SDO information, no complete access)
  general.u8(0);     // FoE
  general.u8(0);     // EoE
  general.u8(0);     // SoE channels
  general.u8(0);     // DS402 channels
  general.u8(0);     // sysman class
  general.u8(0);     // flags
  general.u16(0);    // current on E-bus
  general.u8(0);     // group index
  general.u8(0);
  general.u16(0x0011);  // physical ports 0 and 1: MII
  general.u16(0);
  for (int i = 0; i < 12; ++i) {
    general.u8(0);
  }
  Bytes fmmu;
  Bytes syncm;
  if (d.mailbox) {
    sync_manager(syncm, kMailboxOut, kMailboxBytes, 0x26, 1);  // mailbox, master writes
    sync_manager(syncm, kMailboxIn, kMailboxBytes, 0x22, 2);   // mailbox, master reads
  }
  if (has_out) {
    fmmu.u8(1);  // outputs
    sync_manager(syncm, d.out_address, d.rx.bytes(), 0x64, 3);
  }
  if (has_in) {
    fmmu.u8(2);  // inputs
    sync_manager(syncm, d.in_address, d.tx.bytes(), 0x20, 4);
  }
  Bytes pdos;
  pdo_category(pdos, kCatTxPdo, d.tx, sm_in, s);
  pdo_category(pdos, kCatRxPdo, d.rx, sm_out, s);

  Bytes strings;
  strings.u8(static_cast<std::uint8_t>(s.list().size()));
  for (const std::string& str : s.list()) {
    strings.u8(static_cast<std::uint8_t>(str.size()));
    for (char c : str) {
      strings.u8(static_cast<std::uint8_t>(c));
    }
  }
  category(cats, kCatStrings, strings);
  category(cats, kCatGeneral, general);
  category(cats, kCatFmmu, fmmu);
  category(cats, kCatSyncM, syncm);
  for (std::uint8_t v : pdos.data()) {
    cats.u8(v);
  }
  cats.u16(kCatEnd);
  const std::vector<std::uint8_t>& b = cats.data();
  for (std::size_t i = 0; i + 1U < b.size(); i += 2U) {
    w.push_back(static_cast<std::uint16_t>(b[i] | (b[i + 1U] << 8U)));
  }
  return w;
}

}  // namespace safestate::ecat

#include "safestate/ecat/esi_segment.hpp"

#include <algorithm>

#include "safestate/ecat/cell.hpp"

namespace safestate::ecat {

namespace {

const hal::esi::SyncManager* find_sm(const hal::esi::Device& d, const char* kind, int& index) {
  for (std::size_t i = 0; i < d.sms.size(); ++i) {
    if (d.sms[i].kind == kind) {
      index = static_cast<int>(i);
      return &d.sms[i];
    }
  }
  index = -1;
  return nullptr;
}

// The one PDO of a direction assigned to `sm` (none when the device has no such SM).
bool one_pdo(const hal::esi::Device& d, const std::vector<hal::esi::Pdo>& pdos, int sm, const char* what, Pdo& out,
             std::string& err) {
  const hal::esi::Pdo* found = nullptr;
  for (const hal::esi::Pdo& p : pdos) {
    if (p.sm < 0) {
      continue;
    }
    if (p.sm != sm || found != nullptr) {
      err = d.label() + ": the emulator has one " + what + " on its process-data sync manager";
      return false;
    }
    found = &p;
  }
  if (found == nullptr) {
    return true;
  }
  out.index = found->index;
  for (const hal::esi::Entry& e : found->entries) {
    out.entries.push_back({e.index, e.sub, e.bits, static_cast<std::uint8_t>(e.data_type), e.name});
  }
  return true;
}

}  // namespace

bool desc_from_esi(const hal::esi::Device& d, std::uint32_t serial, SubdeviceDesc& out, std::string& err) {
  if (!d.error.empty()) {
    err = d.error;
    return false;
  }
  SubdeviceDesc s;
  s.vendor_id = d.vendor_id;
  s.product_code = d.product_code;
  s.revision = d.revision;
  s.serial = serial;
  s.name = d.name;
  s.mailbox = d.coe;
  // The emulated drive offers one operation mode, DC-synchronous (its ESI's <Dc><OpMode>
  // AssignActivate): without SYNC0 it refuses OP (AL 0x0030), as such drives do.
  s.dc_sync0_required = d.assign_activate != 0U;
  if (d.coe) {
    int mo = -1;
    int mi = -1;
    const auto* out_mb = find_sm(d, "MBoxOut", mo);
    const auto* in_mb = find_sm(d, "MBoxIn", mi);
    if (out_mb == nullptr || in_mb == nullptr || mo != 0 || mi != 1 || out_mb->start != kMailboxOut ||
        in_mb->start != kMailboxIn || out_mb->default_size != kMailboxBytes || in_mb->default_size != kMailboxBytes ||
        out_mb->control != 0x26U || in_mb->control != 0x22U) {
      err = d.label() + ": the emulator's mailbox is SM0 MBoxOut at 0x1000 and SM1 MBoxIn at 0x1080, 128 bytes, "
                        "control 0x26/0x22";
      return false;
    }
  }
  int so = -1;
  int si = -1;
  const auto* sm_out = find_sm(d, "Outputs", so);
  const auto* sm_in = find_sm(d, "Inputs", si);
  if (!one_pdo(d, d.rx, so, "RxPDO", s.rx, err) || !one_pdo(d, d.tx, si, "TxPDO", s.tx, err)) {
    return false;
  }
  // The emulator's SII sets these control bytes (sii.cpp): outputs 0x64 (watchdog on), inputs 0x20.
  if ((sm_out != nullptr && sm_out->control != 0x64U) || (sm_in != nullptr && sm_in->control != 0x20U)) {
    err = d.label() + ": the emulator's process-data sync managers have control 0x64 (outputs) and 0x20 (inputs)";
    return false;
  }
  if (sm_out != nullptr) {
    s.out_address = sm_out->start;
  }
  if (sm_in != nullptr) {
    s.in_address = sm_in->start;
  }
  if (d.profile_no != 0U) {
    s.device_type = (d.add_info << 16U) | d.profile_no;
  }
  out = s;
  return true;
}

bool esi_segment(std::vector<SubdeviceDesc>& out, std::string& err) {
  std::vector<hal::esi::Device> lib;
  std::vector<std::string> warnings;
  if (!hal::esi::parse_esi(hal::esi::builtin_esi(), hal::esi::kBuiltinEsiName, lib, err, warnings)) {
    return false;
  }
  // The line of default_segment(): the DI terminal, the DO terminal, one drive per axis, the
  // distance sensor, then the safe input and output terminals (issue 37).
  std::vector<std::uint32_t> products{kProductDigitalIn, kProductDigitalOut};
  products.insert(products.end(), hal::kAxes, kProductDrive);
  products.push_back(kProductDistance);
  products.push_back(kProductSafeIn);
  products.push_back(kProductSafeOut);
  std::vector<const hal::esi::Device*> bus;
  for (const std::uint32_t product : products) {
    const auto it = std::find_if(lib.begin(), lib.end(), [&](const hal::esi::Device& d) {
      return d.vendor_id == kVendorId && d.product_code == product && d.revision == kRevision;
    });
    if (it == lib.end()) {
      err = std::string(hal::esi::kBuiltinEsiName) + ": no device of product " + std::to_string(product);
      return false;
    }
    bus.push_back(&*it);
  }
  std::vector<SubdeviceDesc> v;
  for (std::size_t i = 0; i < bus.size(); ++i) {
    const bool is_drive = i >= kPosFirstDrive && i < kPosFirstDrive + hal::kAxes;
    const std::uint32_t serial = i == kPosDistance ? 3U
                                 : i == kPosSafeIn  ? 4U
                                 : i == kPosSafeOut ? 5U
                                 : !is_drive       ? static_cast<std::uint32_t>(i + 1U)
                                                   : static_cast<std::uint32_t>(10U + (i - kPosFirstDrive) + 1U);
    SubdeviceDesc d;
    if (!desc_from_esi(*bus[i], serial, d, err)) {
      return false;
    }
    if (is_drive) {
      d.name += " " + std::to_string(i - kPosFirstDrive + 1U);  // per unit, as the serial: "... drive 3"
    }
    v.push_back(std::move(d));
  }
  out = std::move(v);
  return true;
}

}  // namespace safestate::ecat

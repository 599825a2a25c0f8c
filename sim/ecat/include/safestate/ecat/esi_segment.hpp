// The emulated subdevices as their ESI file describes them (hal/ethercat/esi/
// SafeState-Emulated.xml, built in): one description for both ends of the wire. test_esi
// checks that default_segment() (and so the SII the emulator serves, build_sii) is exactly
// this, and that `safestate ecat-config` makes the built-in bus configuration from it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "safestate/ecat/esc.hpp"
#include "safestate/hal/esi.hpp"

namespace safestate::ecat {

// What the emulator needs of one ESI device: identity, name, the one RxPDO and TxPDO of its
// default assignment, the process-data sync managers' addresses, the CoE mailbox (the
// emulator's mailbox SMs are fixed: the ESI's must be them) and the CiA 402 device type.
// `serial` is per unit (not in an ESI). False with `err` when the emulator cannot be that
// device (more than one PDO per direction, other mailbox sync managers, ...).
bool desc_from_esi(const hal::esi::Device& d, std::uint32_t serial, SubdeviceDesc& out, std::string& err);

// The default segment built from the built-in ESI: the DI terminal, the DO terminal, six
// drives and the distance sensor, with default_segment()'s serial numbers (1, 2, 11..16, 3).
// False with `err` if the ESI does not describe them.
bool esi_segment(std::vector<SubdeviceDesc>& out, std::string& err);

}  // namespace safestate::ecat

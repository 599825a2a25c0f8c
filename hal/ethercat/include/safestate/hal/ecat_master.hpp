// The C ABI of our EtherCAT master (ethercrab behind `extern "C"`, hal/ethercat/master-rs/src/lib.rs,
// linked as safestate_ecat_master): one declaration for every C++ caller (the backend, `safestate
// ecat-config --scan`), so that a struct's layout or a signature cannot differ between them.
#pragma once

#include <cstddef>
#include <cstdint>

extern "C" {
struct SsEcatMaster;
struct SsEcatSub {
  std::uint32_t vendor_id, product_code, revision, serial;
  std::uint16_t configured_address, in_bytes, out_bytes;
  char name[64];
};
struct SsEcatCycle {
  std::uint16_t wkc, expected_wkc, count;
  std::uint8_t al_state[16];
  std::uint64_t dc_time;  // DC system time at which the frame's FRMW passed the reference clock (0: no DC)
};
SsEcatMaster* ss_ecat_open(const char* ifname, std::uint32_t pdu_timeout_us, std::uint32_t state_timeout_ms,
                           int tx_rx_priority, char* err, std::size_t errlen);
const char* ss_ecat_error(const SsEcatMaster* m);
int ss_ecat_scan(SsEcatMaster* m, SsEcatSub* subs, std::size_t max);
int ss_ecat_sdo_write(SsEcatMaster* m, std::uint16_t position, std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                      std::uint8_t size, std::uint32_t* abort_code);
int ss_ecat_to_safe_op(SsEcatMaster* m, SsEcatSub* subs, std::size_t max, const std::uint16_t* assign_activate,
                       std::size_t n_assign, std::uint32_t sync0_ns, std::uint32_t shift_ns);
int ss_ecat_dc_reference(const SsEcatMaster* m);
int ss_ecat_set_watchdog(SsEcatMaster* m, std::uint16_t divider, std::uint16_t time);
int ss_ecat_to_op(SsEcatMaster* m);
// AL status 0x0130 (state bits 0-3, error indication bit 4) and AL status code 0x0134 of the
// subdevice at `position` (0-based); AL control 0x0120 (state bits 0-3, acknowledge bit 4).
// Not for the real-time cycle: each waits for its frames.
int ss_ecat_al_status(SsEcatMaster* m, std::uint16_t position, std::uint16_t* status, std::uint16_t* code);
int ss_ecat_al_control(SsEcatMaster* m, std::uint16_t position, std::uint16_t control);
int ss_ecat_exchange(SsEcatMaster* m, const std::uint8_t* outputs, std::size_t out_len, std::uint8_t* inputs,
                     std::size_t in_len, SsEcatCycle* cycle, std::uint32_t timeout_us, std::uint32_t drive);
std::uint64_t ss_ecat_stray_frames();
}

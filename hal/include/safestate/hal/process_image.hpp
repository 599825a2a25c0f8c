// The process image: everything a HAL backend reads and writes once per cycle, as
// plain data (PLC thinking: the cycle works on a copy, never on live I/O).
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/interfaces.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/hal/safety_links.hpp"

namespace safestate::hal {

inline constexpr std::size_t kAxes = core::kAxes;

struct ProcessImageIn {
  core::RawInputs safety{};                          // both channels of every safety input
  std::array<core::DriveFeedback, kAxes> drive{};    // statusword, position, velocity, online
  bool contactor_closed = false;                     // main contactor (K1) auxiliary contact
  // SPEC §14: K2 in series with K1 (channel B's), its auxiliary contact; load-side encoders
  // (DriveFeedback::load_position_rad). A backend without them leaves these false.
  bool two_contactors = false;
  bool k2_closed = false;
  bool load_encoders = false;
  std::array<bool, kAxes> brake_released{};          // brake feedback contacts
  bool fieldbus_ok = true;                           // cyclic data valid this cycle
  bool stale = false;                                // no fresh sample this cycle: the inputs are the last ones held
  // The inputs carry when they were sampled (EtherCAT with distributed clocks: the drives
  // sample at SYNC0, and the frame's DC time says which pulse): sample_span is then the
  // SYNC0 cycles since the previous answered frame's sample, 0 when this frame carries that
  // same sample again (it came before the next pulse: its frame before was late).
  bool sample_clock = false;
  std::uint16_t sample_span = 0;
  std::uint8_t fieldbus_subdevice = 0;               // 1-based position of the first at fault, 0 = bus
  bool fieldbus_silent = false;                      // no frame back: silent from that subdevice on
  bool fieldbus_boot_failed = false;                 // the bus cannot come up as configured
  bool integrity_ok = true;                          // the backend's own integrity checks
  bool self_test_ok = true;                          // the platform's start-up self-test
  // Issue 37, the black channel: each connection's container as the bus delivered it, in the
  // order of the backend's LinkTable (safety_links()); the channels check them. Unused (len
  // 0) without safe devices.
  std::array<LinkFrame, kMaxLinks> link_rx{};
};

// CiA 402 0x6072 max torque, per mille of rated torque, outside the brake test: the drives'
// own peak (300 %). The brake test of SPEC §12 lowers it to test_torque_pct on the axis under
// test so that the CSP position loop pushes the engaged brake with exactly that torque.
inline constexpr std::uint16_t kDriveMaxTorquePermille = 3000;

struct DriveOut {
  std::uint16_t controlword = 0;     // CiA 402 0x6040
  float target_position_rad = 0.0F; // CSP 0x607A
  std::uint16_t max_torque_permille = kDriveMaxTorquePermille;  // CiA 402 0x6072
};

struct ProcessImageOut {
  bool contactor = false;        // close the main contactor (K1: channel A's)
  // SPEC §14: close K2 (channel B's, in series with K1). A world with two channels combines
  // the channels' outputs into one image: K1 from A, K2 from B, the brakes released only
  // while both release them. One channel: unused.
  bool contactor_k2 = false;
  bool brakes_release = false;   // release the holding brakes
  // SPEC §12 brake test: 1..6, that axis' brake stays engaged although brakes_release is
  // set (the drives hold the others); 0 = none.
  std::uint8_t brake_test_axis = 0;
  bool reset_lamp = false;
  // SPEC §10 reduced mode in force (the core's SafetyStatus::reduced): a safe output of the
  // DO terminal where the bus configuration maps one (`reduced_active`).
  bool reduced_active = false;
  std::array<DriveOut, kAxes> drive{};
  // Issue 37: the container each connection is to carry to its device (LinkTable order),
  // written by the channel that hosts it; the backend copies the bytes, nothing more.
  std::array<LinkFrame, kMaxLinks> link_tx{};
};

// A HAL backend: the simulated cell, or a fieldbus master driving real hardware.
class Backend {
 public:
  virtual ~Backend() = default;
  virtual void read(ProcessImageIn& in) noexcept = 0;
  virtual void write(const ProcessImageOut& out) noexcept = 0;
  // Issue 37: the black channel's connections this backend carries (none: the inputs and
  // outputs above are the safety data, as on the simulated cell).
  [[nodiscard]] virtual const LinkTable& safety_links() const noexcept { return kNoLinks; }

 private:
  static constexpr LinkTable kNoLinks{};
};

}  // namespace safestate::hal

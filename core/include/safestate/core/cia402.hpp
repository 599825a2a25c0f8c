// CiA 402 (IEC 61800-7-201) statusword decode and controlword encode, exactly as the
// table of SPEC §6. Shared by the core (which decides) and the motion layer and
// drives (which act), so all three read the bits the same way.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace safestate::core::cia402 {

enum class DriveState : std::uint8_t {
  NotReadyToSwitchOn,
  SwitchOnDisabled,
  ReadyToSwitchOn,
  SwitchedOn,
  OperationEnabled,
  QuickStopActive,
  FaultReactionActive,
  Fault,
  Unknown,  // matches no row: treated as a drive fault (unknown is unsafe)
};

struct StatusPattern {
  DriveState state;
  std::uint16_t mask;
  std::uint16_t value;
  const char* name;
};

// Order matters only for readability: the patterns are mutually exclusive.
inline constexpr std::array<StatusPattern, 8> kStatusPatterns{{
    {DriveState::NotReadyToSwitchOn, 0x4F, 0x00, "Not ready to switch on"},
    {DriveState::SwitchOnDisabled, 0x4F, 0x40, "Switch on disabled"},
    {DriveState::ReadyToSwitchOn, 0x6F, 0x21, "Ready to switch on"},
    {DriveState::SwitchedOn, 0x6F, 0x23, "Switched on"},
    {DriveState::OperationEnabled, 0x6F, 0x27, "Operation enabled"},
    {DriveState::QuickStopActive, 0x6F, 0x07, "Quick stop active"},
    {DriveState::FaultReactionActive, 0x4F, 0x0F, "Fault reaction active"},
    {DriveState::Fault, 0x4F, 0x08, "Fault"},
}};

// The patterns, searched one by one: the definition (and what the table below is built from).
[[nodiscard]] constexpr DriveState decode_by_search(std::uint16_t statusword) noexcept {
  for (const StatusPattern& p : kStatusPatterns) {
    if ((statusword & p.mask) == p.value) {
      return p.state;
    }
  }
  return DriveState::Unknown;
}

// Only bits 0-3, 5 and 6 (mask 0x6F) take part in any pattern; squeezed into 7 bits they
// index a 128-entry table built at compile time from kStatusPatterns, so the core decodes
// six drives per cycle with one lookup each instead of up to eight compares (bench/run.py
// measured the search as the largest single cost of a worst-case cycle).
inline constexpr std::uint16_t kDecodeMask = 0x6F;
[[nodiscard]] constexpr std::size_t decode_index(std::uint16_t statusword) noexcept {
  return static_cast<std::size_t>((statusword & 0x0FU) | ((statusword & 0x60U) >> 1U));
}
inline constexpr std::array<DriveState, 128> kDecodeTable = [] {
  std::array<DriveState, 128> t{};
  for (std::uint16_t sw = 0; sw <= kDecodeMask; ++sw) {
    if ((static_cast<unsigned>(sw) & ~static_cast<unsigned>(kDecodeMask)) == 0U) {
      t[decode_index(sw)] = decode_by_search(sw);
    }
  }
  return t;
}();
[[nodiscard]] constexpr bool patterns_fit_the_table() noexcept {
  for (const StatusPattern& p : kStatusPatterns) {
    if ((static_cast<unsigned>(p.mask) & ~static_cast<unsigned>(kDecodeMask)) != 0U) {
      return false;
    }
  }
  return true;
}
static_assert(patterns_fit_the_table(), "a CiA 402 pattern looks at bits the decode table ignores");

// @req CIA-DECODE CIA-UNKNOWN
[[nodiscard]] constexpr DriveState decode(std::uint16_t statusword) noexcept {
  return kDecodeTable[decode_index(statusword)];
}

[[nodiscard]] constexpr bool is_fault(DriveState s) noexcept {
  return (s == DriveState::Fault) || (s == DriveState::FaultReactionActive) || (s == DriveState::Unknown);
}

// Controlword commands (0x6040).
namespace cw {
inline constexpr std::uint16_t kShutdown = 0x0006;
inline constexpr std::uint16_t kSwitchOn = 0x0007;
inline constexpr std::uint16_t kEnableOperation = 0x000F;
inline constexpr std::uint16_t kDisableVoltage = 0x0000;
inline constexpr std::uint16_t kQuickStop = 0x0002;
inline constexpr std::uint16_t kDisableOperation = 0x0007;
inline constexpr std::uint16_t kFaultReset = 0x0080;  // acts on the rising edge of bit 7
}  // namespace cw

// Canonical statusword of each state (what a simulated drive reports).
[[nodiscard]] constexpr std::uint16_t statusword_of(DriveState s) noexcept {
  switch (s) {
    case DriveState::NotReadyToSwitchOn: return 0x0000;
    case DriveState::SwitchOnDisabled: return 0x0040;
    case DriveState::ReadyToSwitchOn: return 0x0021;
    case DriveState::SwitchedOn: return 0x0023;
    case DriveState::OperationEnabled: return 0x0027;
    case DriveState::QuickStopActive: return 0x0007;
    case DriveState::FaultReactionActive: return 0x000F;
    case DriveState::Fault: return 0x0008;
    case DriveState::Unknown: break;
  }
  return 0x004F;  // matches no pattern
}

// Device control commands carried by controlword bits 0..3 and 7 (IEC 61800-7-201).
[[nodiscard]] constexpr bool is_shutdown(std::uint16_t c) noexcept { return (c & 0x0087U) == 0x0006U; }
[[nodiscard]] constexpr bool is_switch_on(std::uint16_t c) noexcept { return (c & 0x008FU) == 0x0007U; }
[[nodiscard]] constexpr bool is_enable_operation(std::uint16_t c) noexcept { return (c & 0x008FU) == 0x000FU; }
[[nodiscard]] constexpr bool is_disable_voltage(std::uint16_t c) noexcept { return (c & 0x0082U) == 0x0000U; }
[[nodiscard]] constexpr bool is_quick_stop(std::uint16_t c) noexcept { return (c & 0x0086U) == 0x0002U; }
[[nodiscard]] constexpr bool fault_reset_edge(std::uint16_t prev, std::uint16_t c) noexcept {
  return ((prev & 0x0080U) == 0U) && ((c & 0x0080U) != 0U);
}

// The drive's side of the CiA 402 state machine: the next state for a controlword,
// one transition per cycle. `power`: the DC link is charged (main contactor closed).
// Fault handling (entering Fault) is the drive's own business; leaving it needs a
// fault-reset edge.
[[nodiscard]] constexpr DriveState next_state(DriveState s, std::uint16_t prev_cw, std::uint16_t cw,
                                              bool power) noexcept {
  switch (s) {
    case DriveState::NotReadyToSwitchOn:
      return DriveState::SwitchOnDisabled;  // 1: self-initialisation done
    case DriveState::SwitchOnDisabled:
      return is_shutdown(cw) ? DriveState::ReadyToSwitchOn : s;  // 2
    case DriveState::ReadyToSwitchOn:
      if (is_disable_voltage(cw) || is_quick_stop(cw)) {  // 7
        return DriveState::SwitchOnDisabled;
      }
      return (is_switch_on(cw) && power) ? DriveState::SwitchedOn : s;  // 3
    case DriveState::SwitchedOn:
      if (!power || is_disable_voltage(cw) || is_quick_stop(cw)) {  // 10
        return DriveState::SwitchOnDisabled;
      }
      if (is_shutdown(cw)) {  // 6
        return DriveState::ReadyToSwitchOn;
      }
      return is_enable_operation(cw) ? DriveState::OperationEnabled : s;  // 4
    case DriveState::OperationEnabled:
      if (!power || is_disable_voltage(cw)) {  // 9
        return DriveState::SwitchOnDisabled;
      }
      if (is_quick_stop(cw)) {  // 11
        return DriveState::QuickStopActive;
      }
      if (is_shutdown(cw)) {  // 8
        return DriveState::ReadyToSwitchOn;
      }
      return is_switch_on(cw) ? DriveState::SwitchedOn : s;  // 5 (disable operation)
    case DriveState::QuickStopActive:
      if (is_disable_voltage(cw) || !power) {  // 12
        return DriveState::SwitchOnDisabled;
      }
      return is_enable_operation(cw) ? DriveState::OperationEnabled : s;  // 16
    case DriveState::FaultReactionActive:
      return DriveState::Fault;  // 14
    case DriveState::Fault:
      return fault_reset_edge(prev_cw, cw) ? DriveState::SwitchOnDisabled : s;  // 15
    case DriveState::Unknown:
      break;
  }
  return DriveState::Fault;
}

const char* to_string(DriveState s) noexcept;

}  // namespace safestate::core::cia402

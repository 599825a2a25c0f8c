// The faults the simulated world can be given (spec/scenario-format.md `fault` lines, the
// gateway's `sim` message, the emulator's control socket): one enumeration, one parser.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

#include "safestate/vocab/tokens.hpp"

namespace safestate::vocab {

// Fault injection, exactly the vocabulary of spec/scenario-format.md.
enum class FaultKind : std::uint8_t {
  drive_fault,      // drive N reports Fault
  drive_clear,      // drive N's cause is gone (it still needs a fault reset)
  drive_runaway,    // drive N accelerates at its limit, ignoring set-points
  drive_nostop,     // drive N keeps its velocity, ignoring stop ramps
  fieldbus_lost,    // cyclic data stops being valid
  contactor_stuck_open,
  brake_stuck,      // brake N never releases
  clear_all,        // every injected cause is gone (drives still need a fault reset)
  // "More keys, faults and settings" of the format (appended: older codes keep their value).
  integrity,             // the core's integrity check fails (HAL integrity input)
  selftest_fail,         // the platform's start-up self-test fails
  drive_statusword,      // drive N reports the raw word `value` until `drive N clear`
  drive_slow_enable,     // each enabling CiA 402 step of drive N takes `value` ms
  contactor_welded,      // the contactor's feedback (and power) stay closed
  brake_stuck_released,  // brake N's feedback stays released (and it does not hold)
  program_unload,        // the program is unloaded (the cell's own, not the plant's)
  jog_link_drop,         // the pendant's jog commands are lost on the way (cell)
  // SPEC §12 (appended likewise).
  brake_weak,            // brake N holds less than the brake test's torque (it slips under it)
  // SPEC §11 collision detection (appended likewise).
  contact,               // a force of `value` / 10 N pushes against the TCP's motion (0: none)
  drive_torque_bias,     // drive N reports `value` (int16, per mille of rated) more torque than it applies
  // SPEC §14 two channels (appended likewise). `axis` is the channel (1: A, 2: B) for the
  // channel_* and digest_* kinds, the axis for the encoder_* kinds. contactor_welded and
  // contactor_stuck_open take `axis` 0 or 1 for K1 (`contactor welded` is K1's), 2 for K2.
  channel_stall,   // the channel stops cycling (its outputs stay as last written)
  channel_crash,   // the channel's process is gone (its outputs drop, de-energised)
  channel_input,   // the channel alone reads contact `value >> 1` (vocab::Contact) stuck at `value & 1`
  digest_corrupt,  // from now on the channel's digests arrive with a wrong CRC
  digest_drop,     // ... do not arrive
  digest_repeat,   // ... arrive as the last one again
  encoder_stuck,   // axis N's load-side encoder stands still from now on
  encoder_offset,  // ... reads `value` (int16, hundredths of a degree) more
  encoder_drift,   // ... drifts by `value` (int16, hundredths of a degree) per second
  channel_flip,    // one bit of the channel's own state or timer: `value` = FlipField << 8 | bit
};
inline constexpr std::uint8_t kFaultKinds = static_cast<std::uint8_t>(FaultKind::channel_flip) + 1U;

// SPEC §14 `channel A|B flip FIELD [bit N]`: the named variables of one channel's supervisor
// a scenario may flip one bit of (the fault campaign flips any byte of it, by offset). Each
// is kept from cycle to cycle by the channel alone; `bits`: the variable's width (bit N of
// its value, 0 = least significant; a flag has one).
enum class FlipField : std::uint8_t {
  state,             // the state machine's leaf (state and sub-state)
  cycle,             // the channel's cycle counter
  alarms,            // the active alarms (bit N: alarm code N, SPEC §8's order)
  mode,              // the mode in which servo_on was accepted
  reset_pending,     // a reset taken, waiting for its conditions
  boot_pending,      // the boot checks not yet passed
  estop,             // the E-stop signal after its dual-channel filter (the signal layer)
  gate,              // the guard's, likewise
  timer_reset,       // the cycle the pending reset was taken
  timer_jog,         // the cycle of the last jog command (the jog link's deadman)
  timer_standstill,  // cycles at standstill
  timer_estop,       // cycles the E-stop's two contacts have disagreed (discrepancy filter)
  timer_gate,        // the guard's, likewise
};
struct FlipFieldInfo {
  std::string_view name;
  std::uint8_t bits;
};
inline constexpr std::array<FlipFieldInfo, 13> kFlipFields{{
    {"state", 8},         {"cycle", 64},      {"alarms", 64},          {"mode", 8},
    {"reset_pending", 1}, {"boot_pending", 1}, {"estop", 1},           {"gate", 1},
    {"timer.reset", 64},  {"timer.jog", 64},  {"timer.standstill", 64}, {"timer.estop", 64},
    {"timer.gate", 64},
}};
static_assert(static_cast<std::size_t>(FlipField::timer_gate) + 1U == kFlipFields.size(), "one name per field");
inline constexpr double kMaxEncoderFaultDeg = 300.0;  // `encoder N offset|drift`, stored in hundredths

struct Fault {
  FaultKind kind = FaultKind::clear_all;
  std::uint8_t axis = 0;    // 1..6 for the drive_* and brake_* kinds
  std::uint16_t value = 0;  // drive_statusword: the word; drive_slow_enable: ms per step;
                            // contact: tenths of a newton; drive_torque_bias: int16 per mille
};

inline constexpr double kMaxContactN = 5000.0;      // `contact F`, stored in tenths of a newton
inline constexpr double kMaxTorqueBiasPct = 300.0;  // `drive N torque_bias X`, the drives' peak

// Where a fault comes from. `network`: the gateway's `sim` message (the HMI's panel) may only
// inject what a person could do to the plant (drives, brakes, contactor, fieldbus, a contact
// force); platform faults (integrity, self-test), the program and the jog link are the
// scenario files' and the emulator's local control socket's.
enum class FaultSource : std::uint8_t { local, network };
[[nodiscard]] bool injectable(FaultKind k, FaultSource from) noexcept;

// The words of a fault line ("drive 3 runaway") into `out`. Empty: well formed. Otherwise the
// problem, naming the bad word (and `out` is left as it was).
Problem parse_fault(const Tokens& words, Fault& out, FaultSource from = FaultSource::local);

// The fault's words, as parse_fault reads them back ("drive 3 torque_bias -12.5").
std::string format_fault(const Fault& f);

}  // namespace safestate::vocab

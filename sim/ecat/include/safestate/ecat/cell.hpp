// The default emulated segment of `safestate ecat-sim` and what stands behind it: the
// simulated plant of sim/ (six CiA 402 drives, contactor, brakes, safety contacts, arm
// physics) reached through the PDOs of a digital input terminal, a digital output
// terminal and six CSP drives. It stands in for real hardware on a real segment.
#pragma once

#include <cstdint>
#include <vector>

#include "safestate/robot/description.hpp"
#include "safestate/ecat/safe_io.hpp"
#include "safestate/ecat/segment.hpp"
#include "safestate/ecat/wire_timing.hpp"
#include "safestate/hal/process_image.hpp"
#include "safestate/sim/cell.hpp"
#include "safestate/sim/person.hpp"
#include "safestate/sim/plant.hpp"

namespace safestate::ecat {

// Identities of the emulated subdevices. The vendor id is not one ETG assigned to
// anybody: these subdevices exist only here (docs/ethercat.md).
inline constexpr std::uint32_t kVendorId = 0x00005AFE;
inline constexpr std::uint32_t kProductDrive = 0x00402001;
inline constexpr std::uint32_t kProductDigitalIn = 0x00D10018;
inline constexpr std::uint32_t kProductDigitalOut = 0x00D00003;
inline constexpr std::uint32_t kProductDistance = 0x00D15001;
inline constexpr std::uint32_t kRevision = 0x00010000;

// Positions on the line (0-based): the I/O terminals in the cabinet first, then drives,
// then the distance sensor out in the cell (SPEC §11), then the safe input and output
// terminals of the black channel (issue 37: kProductSafeIn/Out, safe_io.hpp). Without the
// distance sensor (`--no-distance-sensor`) the safe terminals move up by one; without the
// safe terminals (`--no-safe-terminals`) the segment is the nine subdevices of before.
inline constexpr std::size_t kPosDigitalIn = 0;
inline constexpr std::size_t kPosDigitalOut = 1;
inline constexpr std::size_t kPosFirstDrive = 2;
inline constexpr std::size_t kPosDistance = 8;
inline constexpr std::size_t kPosSafeIn = 9;
inline constexpr std::size_t kPosSafeOut = 10;
inline constexpr std::size_t kSubdevices = 11;
inline constexpr std::size_t kPlainSubdevices = 9;  // without the safe terminals

// Bits of the digital input terminal's TxPDO (0x6000:01.. = bit 0..), in this order.
// Bits 20..23 are the protective-field scanner's four OSSD channels (field.outer.a/b,
// field.inner.a/b, SPEC §11, NC: 1 = clear); 24 is K2's auxiliary contact (SPEC §14, NO:
// 1 = closed; `contactor_fb` at 11 is K1's); 25..31 are spare. docs/ethercat.md.
enum class DiBit : std::uint8_t {
  estop_a, estop_b, gate_a, gate_b, enable_a, enable_b, enable_panic,
  mode_auto, mode_t1, mode_t2, reset_button, contactor_fb,
  brake_fb1, brake_fb2, brake_fb3, brake_fb4, brake_fb5, brake_fb6,
  reduced_a, reduced_b,  // SPEC §10 reduced-speed request, NC (1 = normal)
  field_outer_a, field_outer_b, field_inner_a, field_inner_b,  // SPEC §11, NC (1 = clear)
  contactor_fb_k2,  // SPEC §14: K2's auxiliary contact
};
inline constexpr std::size_t kDiBytes = 4;  // 25 contacts, padded to 32 bits
// Bits of the digital output terminal's RxPDO (0x7000:01..). brake_hold_1..6: that axis'
// brake stays engaged although brakes_release is set (the SPEC §12 brake test's axis).
// reduced_active: SPEC §10 reduced mode in force (the core's flag, a safe output).
// contactor_k2: SPEC §14 K2, in series with K1 (`contactor`): power needs both closed.
enum class DoBit : std::uint8_t {
  contactor, brakes_release, reset_lamp,
  brake_hold1, brake_hold2, brake_hold3, brake_hold4, brake_hold5, brake_hold6,
  reduced_active, contactor_k2,
};
inline constexpr std::size_t kDoBytes = 2;
// Drive PDOs (CSP): RxPDO 0x1600 = 0x6040 controlword (u16), 0x607A target position
// (i32), 0x6072 max torque (u16, per mille of rated); TxPDO 0x1A00 = 0x6041 statusword
// (u16), 0x6064 position actual (i32), 0x606C velocity actual (i32), 0x6077 torque actual
// (i16, per mille of rated), 0x60E4:01 additional position actual value (i32: the load-side
// encoder of SPEC §14, in the same counts per joint radian). Little-endian, as on the wire.
// These are the CiA 402 part; with the black channel (issue 37) each PDO carries two
// containers behind it (channel A's, then B's: kDriveRxSafeBytes, kDriveTxSafeBytes in all).
inline constexpr std::size_t kDriveRxBytes = 8;
inline constexpr std::size_t kDriveTxBytes = 16;
inline constexpr std::size_t kDriveRxSafeBytes = kDriveRxBytes + 2U * safelink::container_bytes(kEncoderHostData);
inline constexpr std::size_t kDriveTxSafeBytes = kDriveTxBytes + 2U * safelink::container_bytes(kEncoderDeviceData);
// The safe terminals' PDOs: channel A's container at 0, B's behind it.
inline constexpr std::size_t kSafeInRxBytes = 2U * safelink::container_bytes(kSafeInHostData);
inline constexpr std::size_t kSafeInTxBytes = 2U * safelink::container_bytes(kSafeInDeviceData);
inline constexpr std::size_t kSafeOutRxBytes = 2U * safelink::container_bytes(kSafeOutHostData);
inline constexpr std::size_t kSafeOutTxBytes = 2U * safelink::container_bytes(kSafeOutDeviceData);
// The distance sensor's TxPDO 0x1A00: 0x6000:01 separation in mm (INT32, little-endian),
// 0x6000:02 valid (BOOL, bit 32), 7 bits padding.
inline constexpr std::size_t kDistanceBytes = 5;
inline constexpr std::size_t kDistanceValidBit = 32;
// Encoder resolution of the emulated drives: 2^20 increments per revolution.
inline constexpr double kCountsPerRad = 1048576.0 / 6.283185307179586;

// `safe_terminals` false: the segment as before issue 37 (no F-DI/F-DO, the drives' PDOs
// without containers: `ecat-sim --no-safe-terminals`).
std::vector<SubdeviceDesc> default_segment(bool safe_terminals = true);
// The position (0-based) of the first subdevice with this product code, or SIZE_MAX.
std::size_t position_of(const Segment& seg, std::uint32_t product) noexcept;

// Process image <-> PDO bytes of the default layout (used by both sides of the wire in tests).
void pack_inputs(const hal::ProcessImageIn& in, std::uint8_t* di, std::uint8_t (*drive_tx)[kDriveTxBytes]) noexcept;
void pack_distance(const core::RawInputs& in, std::uint8_t* tx) noexcept;
void pack_outputs(const hal::ProcessImageOut& out, std::uint8_t* dout, std::uint8_t (*drive_rx)[kDriveRxBytes]) noexcept;
void unpack_outputs(const std::uint8_t* dout, const std::uint8_t (*drive_rx)[kDriveRxBytes], hal::ProcessImageOut& out) noexcept;

// The plant behind the segment, in one of two pacings:
//   lockstep  one process-data exchange = one plant cycle, so a master cycling once per scan
//             cycle sees exactly what the in-process cell sees (a replay: not paced in real
//             time); the reply of an exchange carries the inputs after the plant cycle it ran;
//   paced     as a real segment: the plant is stepped by the drives' SYNC0 pulses, in real
//             time, whether frames come or not. At each pulse the drives take the set-points
//             the last frame left them (a pulse that found none: the drive extrapolates the
//             last step once, then holds), the plant runs one cycle and every input is
//             sampled; the next frame carries those inputs back: one exchange more from a
//             set-point to the position it gives than in lock-step. The drives track their
//             set-points ideally, as in-process: frames late past their SYNC0 twice and then
//             two in one cycle make the axis stand for a pulse and then take two steps in
//             one, really (steps().held, steps().multi_step, max_point_speed_multi_step()).
//             While no SYNC0 runs
//             (boot, drives free-running without DC) the drives are synchronous to the frames
//             and the plant steps per exchange, as in lock-step.
// In both, when no process data arrives (and no SYNC0 paces it) the plant runs on by itself
// with its outputs in the safe state.
class EmulatedCell {
 public:
  enum class Pacing : std::uint8_t { lockstep, paced };
  // What a plant cycle was started by (`status` -> `plant`).
  struct Steps {
    std::uint64_t exchange = 0;      // a process-data exchange (lock-step, or no SYNC0)
    std::uint64_t sync0 = 0;         // a SYNC0 pulse (paced)
    std::uint64_t free = 0;          // nothing: no master, no SYNC0
    std::uint64_t extrapolated = 0;  // SYNC0 pulses that found no new set-point: the last step repeated
    std::uint64_t held = 0;          // ... and found none again: the set-points held
    // SYNC0 pulses that applied more than one cycle's set-point at once: after a held pulse
    // (the axis stood while the master's set-points went on), or with more frames since the
    // last pulse than the pulses they were meant for (one extrapolated pulse makes up for
    // one of them). The axis really took two steps or more in one cycle there.
    std::uint64_t multi_step = 0;
  };
  // `link_seed`: the safe devices' first sessions; 0 = random at power-up (getrandom), as
  // `ecat-sim` runs; another value makes them reproducible (tests, `--link-seed`).
  // `link_watchdog_ms`: the safe devices' watchdog (ecat-sim --link-watchdog-ms).
  explicit EmulatedCell(std::uint32_t cycle_us, const std::vector<SubdeviceDesc>& devices = default_segment(),
                        std::uint32_t link_seed = 0, std::uint16_t link_watchdog_ms = kLinkWatchdogMs);
  void set_pacing(Pacing p) noexcept { pacing_ = p; }
  [[nodiscard]] Pacing pacing() const noexcept { return pacing_; }
  // The plant is stepped by SYNC0 now (paced, and the first drive's SYNC0 runs).
  [[nodiscard]] bool paced_by_sync0() noexcept;
  [[nodiscard]] const Steps& steps() const noexcept { return steps_; }
  // The fastest any point of the arm (TCP, link origins) really moved in a plant cycle since
  // the last reset_steps(), mm/s (max_point_speed() of the inputs each cycle latched): what
  // tells a speed alarm of the core the arm earned from one it did not.
  [[nodiscard]] float max_point_speed_mm_s() const noexcept { return peak_mm_s_; }
  // The same, split: at the pulses that applied more than one set-point (Steps::multi_step)
  // and at every other plant cycle. A speed alarm the arm earned because the host delivered
  // frames late shows in the first; a jog that kept to its limit keeps the second under it.
  [[nodiscard]] float max_point_speed_multi_step_mm_s() const noexcept { return peak_multi_mm_s_; }
  [[nodiscard]] float max_point_speed_one_step_mm_s() const noexcept { return peak_one_mm_s_; }
  void reset_steps() noexcept {
    steps_ = Steps{};
    peak_mm_s_ = 0.0F;
    peak_multi_mm_s_ = 0.0F;
    peak_one_mm_s_ = 0.0F;
  }
  // How long the emulator may sleep before the plant needs it (the next SYNC0 pulse when
  // paced by it), at most `most_ns`.
  [[nodiscard]] std::uint64_t sleep_ns(std::uint64_t now_ns, std::uint64_t most_ns) noexcept;
  Segment& segment() noexcept { return segment_; }
  core::RawInputs& inputs() noexcept { return plant_.inputs(); }
  void inject(const sim::Fault& f) noexcept {
    plant_.inject(f);
    timing_.fault_injected();
  }
  // The tool the emulated arm carries (SPEC §11 dynamics: the drives' torque), as the
  // safety configuration declares it: a point mass at the TCP (tool0 frame, mm).
  void set_tool(float payload_kg, const std::array<float, 3>& tcp_tool0_mm) noexcept {
    plant_.set_tool(payload_kg, tcp_tool0_mm);
    timing_.set_tcp(tcp_tool0_mm);
    tcp_mm_ = tcp_tool0_mm;
  }
  // SPEC §11, the simulated person (sim/person.hpp) behind the segment: it walks one step per
  // plant cycle, and while it is in the cell the scanner's OSSD pairs (DI bits 20..23) and the
  // distance sensor's reading show it (against the arm as the drives' positions place it, with
  // the tool's TCP), over what `in` lines set, which apply again once it has left: as in-process.
  sim::Person& person() noexcept { return person_; }
  [[nodiscard]] const sim::PersonSensors& person_sensors() const noexcept { return person_sensors_; }
  bool set_person_sensors(const sim::PersonSensors& s) noexcept {
    if (!sim::valid(s)) {
      return false;
    }
    person_sensors_ = s;
    return true;
  }
  [[nodiscard]] const sim::PersonView& person_view() const noexcept { return person_view_; }
  // Idle work: SYNC0 pulses due (paced), watchdogs, and free-running physics when the master
  // is silent.
  void poll(std::uint64_t now_ns) noexcept;
  // The SYNC0 pulses due by this instant only (paced; no watchdog): before a frame is taken.
  void sync0_until(std::uint64_t now_ns) noexcept;
  void set_time(std::uint64_t now_ns) noexcept { now_ns_ = now_ns; }
  [[nodiscard]] std::uint64_t now() const noexcept { return now_ns_; }
  void step() noexcept;  // one plant cycle on the outputs the subdevices hold
  // The input terminals show a changed contact at once, as real ones do between cycles.
  void latch_inputs() noexcept;
  // The subdevices' outputs as they stand: what the last exchange brought, in their safe
  // state once a subdevice left OP (the plant applies the drives' set-points at SYNC0 when paced).
  [[nodiscard]] const hal::ProcessImageOut& last_outputs() const noexcept { return held_; }
  [[nodiscard]] const hal::ProcessImageIn& last_inputs() const noexcept { return in_; }
  [[nodiscard]] std::uint64_t cycles() const noexcept { return cycles_; }
  [[nodiscard]] std::uint64_t exchanges() const noexcept { return exchanges_; }
  // Safety reaction on the wire (issue 13 item 7): an input contact that changes while the
  // contactor output is closed starts a measurement; the exchange that carries the changed
  // inputs to the master and the first exchange whose outputs clear the contactor end it.
  // A change while the contactor is open starts nothing (so the second channel of an
  // E-stop, pressed after the first opened it, keeps the first channel's figure), and
  // closing the contactor again forgets the last figure. Exchanges are numbered from 0.
  struct Reaction {
    bool armed = false;               // an input changed while the contactor was closed
    bool carried = false;             // the exchange carrying it has passed
    bool cleared = false;             // the contactor bit came back cleared
    std::uint64_t change_ns = 0;      // when the contact changed (the control channel)
    std::uint64_t input_cycle = 0;    // exchange that carries the changed inputs out
    std::uint64_t input_ns = 0;
    std::uint64_t cleared_cycle = 0;  // first exchange with the contactor bit cleared
    std::uint64_t cleared_ns = 0;
  };
  void mark_input_change() noexcept;
  [[nodiscard]] const Reaction& reaction() const noexcept { return reaction_; }
  // Outputs dropped by the subdevices themselves (issue 22 item 3): while no process data
  // arrives (the master died), the time from the last exchange to the plant seeing the
  // power path's output open (K1 or K2, SPEC §14) and the last drive's enable (controlword
  // bit 3) gone, as the
  // subdevices' process-data watchdogs put their outputs in the safe state. Cleared when
  // an exchange closes the contactor again.
  struct OutputDrop {
    bool contactor = false;
    bool enable = false;
    std::uint64_t contactor_ns = 0;  // after the last exchange
    std::uint64_t enable_ns = 0;
  };
  [[nodiscard]] const OutputDrop& output_drop() const noexcept { return drop_; }
  // Any safety function's response time on the wire (issue 21 item 4, wire_timing.hpp).
  [[nodiscard]] WireTiming& wire_timing() noexcept { return timing_; }
  [[nodiscard]] std::uint32_t cycle_us() const noexcept { return cycle_us_; }
  // The black channel's device ends (issue 37): the F-DI, the F-DO and the drives' encoder
  // connections, and the wire faults between them and the master.
  SafeLinks& links() noexcept { return links_; }
  [[nodiscard]] const SafeLinks& links() const noexcept { return links_; }
  // `fault link ...` (the words after "fault link").
  std::string link_fault(const std::string& words);
  // Where the distance sensor is (SIZE_MAX: none on this segment).
  [[nodiscard]] std::size_t distance_position() const noexcept { return pos_distance_; }

 private:
  void unpack_held(hal::ProcessImageOut& out) noexcept;
  enum class LinkPhase : std::uint8_t { both, outputs, inputs };
  void link_cycle(bool exchange, LinkPhase phase = LinkPhase::both) noexcept;
  enum class Cause : std::uint8_t { exchange, sync0, free };
  void on_exchange() noexcept;
  void time_reaction(bool was_closed) noexcept;
  void watch_held_outputs() noexcept;
  [[nodiscard]] bool outputs_went_safe() const noexcept;
  void sync0_setpoints() noexcept;
  void plant_cycle(Cause cause) noexcept;
  [[nodiscard]] std::size_t find_pacer() noexcept;

  std::uint32_t cycle_us_;
  sim::SimPlant plant_;
  Segment segment_;
  hal::ProcessImageIn in_{};
  hal::ProcessImageOut out_{};   // what the plant applies
  hal::ProcessImageOut held_{};  // what the subdevices hold (last_outputs())
  Pacing pacing_ = Pacing::lockstep;
  Steps steps_{};
  float peak_mm_s_ = 0.0F;
  float peak_multi_mm_s_ = 0.0F;
  float peak_one_mm_s_ = 0.0F;
  std::uint64_t cycles_ = 0;
  std::uint64_t exchanges_ = 0;
  std::uint64_t pulses_ = 0;           // SYNC0 pulses of the pacing drive the plant has stepped on
  static constexpr std::size_t kNoPacer = static_cast<std::size_t>(-1);
  std::size_t pacer_ = kNoPacer;       // the drive whose SYNC0 stepped the plant at the last look
  std::uint32_t fresh_ = 0;            // exchanges (set-points) since the last SYNC0 step
  std::uint8_t missed_ = 0;            // SYNC0 steps in a row without one
  bool extrapolation_moved_ = false;   // the last extrapolated pulse moved an axis
  bool multi_step_ = false;            // the SYNC0 step running applied more than one set-point
  std::array<float, hal::kAxes> step_rad_{};  // each drive's last set-point step (extrapolation)
  std::uint64_t last_step_ns_ = 0;
  std::uint64_t now_ns_ = 0;
  bool free_running_ = false;
  Reaction reaction_{};
  OutputDrop drop_{};
  WireTiming timing_{};
  std::uint64_t next_free_ns_ = 0;
  std::uint64_t last_exchange_ns_ = 0;
  std::array<float, 3> tcp_mm_ = safestate::robot::active().model.tcp_offset_mm;
  sim::Person person_{};
  sim::PersonSensors person_sensors_{};
  sim::PersonView person_view_{};
  SafeLinks links_{};
  std::size_t pos_distance_ = static_cast<std::size_t>(-1);
};

}  // namespace safestate::ecat

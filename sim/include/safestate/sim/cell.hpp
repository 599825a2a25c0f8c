// The simulated cell: the controller on a backend (controller/cell.hpp: signal layer,
// supervisor, motion layer, the platform's checks) driving a simulated plant (six CiA 402
// drives, contactor, brakes, I/O, arm physics) and a simulated person, one scan cycle at a
// time: the plant and the person are the backend, the controller does not know it.
// Deterministic: no clock, no randomness. This facade is what `safestate replay`, the tests
// and the runtime use.
//
// Two channels (SPEC §14, `channels` 2): two controllers, A and B, on the same world in
// lock-step: each reads the world's input image (a copy each: a channel's own input fault
// changes its copy only) and its own commands, exchanges its digest with the other over an
// in-memory link, and writes its own output image; the world takes the drives from A, K1 from
// A, K2 from B, and releases the brakes only while both do. Both come from one compiler here
// (docs/two-channels.md: the diversity of compilers is `safestate run`'s, two processes).
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "safestate/controller/cell.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/supervisor.hpp"
#include "safestate/core/types.hpp"
#include "safestate/hal/process_image.hpp"
#include "safestate/motion/motion_controller.hpp"
#include "safestate/sim/black_channel.hpp"
#include "safestate/sim/person.hpp"
#include "safestate/vocab/faults.hpp"
#include "safestate/vocab/world.hpp"

namespace safestate::sim {

// Fault injection: the vocabulary's (vocab/faults.hpp).
using vocab::Fault;
using vocab::FaultKind;

// What the simulated cell shows after a cycle, besides the supervisor's output: the
// controller's view (controller/cell.hpp) and the simulated world's.
struct CellView : controller::CellView {
  std::uint64_t injected = 0;  // injected fault causes (bit set; see SimPlant::injected)
  // The simulated person (SPEC §11, docs/collaborative.md "The simulated person"): where it
  // is, how fast it walks, what the scanner and the distance sensor see of it.
  PersonView person{};
};

class Cell final : public vocab::World {
 public:
  // `cfg` must have passed core::validate(). With `bus`, the controller runs on that HAL
  // backend (a real fieldbus) instead of the simulated plant; inputs() and inject() then
  // act on the unused plant only. `bus` must outlive the cell.
  // `channels`: 1 (one controller, one contactor) or 2 (SPEC §14: A and B, K1 and K2).
  explicit Cell(const core::Config& cfg, hal::Backend* bus = nullptr, std::uint8_t channels = 1);
  ~Cell() override;
  // A deep copy: the exhaustive checker forks the whole cell to explore alternatives.
  Cell(const Cell& other);
  Cell& operator=(const Cell&) = delete;
  // Issue 37: with a `bus` that carries the black channel, why its safety connections were
  // refused ("" when they were not): the controllers then check none, so a caller must stop.
  [[nodiscard]] const char* links_error() const noexcept;
  // Issue 37: with such a bus, opens the channels' sessions before the first cycle (at most
  // `max_exchanges` exchanges of the containers alone; the cycle count stays 0), as the bus
  // itself is brought up before it. true when every connection delivered data (also without
  // a bus or a black channel: nothing to open).
  bool connect_links(int max_exchanges) noexcept;

  // SPEC §10, before the first step: the safe limits and whether they are validated.
  void configure_limits(const core::SafetyLimits& limits, bool validated) noexcept;
  // SPEC §12, before the first step and after configure_limits: the event log's last test.
  void configure_brake_test(const core::BrakeTestHistory& history) noexcept;

  // SPEC §13 stopping data (bench/stopping.cpp): the payload as a fraction of the rated one
  // (sim::payload_decel_scale), and a program of the caller's instead of the demo (the
  // points must outlive the cell's use of them).
  void set_payload_fraction(float fraction) noexcept;
  void load_program(const motion::Waypoint* points, std::uint8_t count) noexcept;

  // The physical contacts of SPEC §2; change them between cycles.
  core::RawInputs& inputs() noexcept override;

  // SPEC §11, the simulated person (sim/person.hpp). While a person is in the cell, the
  // simulated scanner and distance sensor set the fields (all four channels) and the
  // separation the controller reads every cycle, over whatever inputs() holds for them;
  // inputs() keeps the values set from outside, which apply again once the person has
  // left (or for a device `sensors` turns off). Only on the simulated plant: with a `bus`
  // the person is shown but feeds nothing. Between cycles; false: refused, nothing changed.
  bool add_person(float x_mm, float y_mm, float radius_mm = kPersonDefaultRadiusMm) noexcept;
  bool set_person_path(const PersonWaypoint* points, std::size_t count) noexcept;
  void person_stand() noexcept;
  void remove_person() noexcept;
  // The scanner's field radii and which devices the person feeds (default: both, 2000 /
  // 1000 mm); false for radii that are not 0 < inner < outer <= 20 m.
  bool configure_person_sensors(const PersonSensors& s) noexcept;
  [[nodiscard]] const PersonSensors& person_sensors() const noexcept;
  [[nodiscard]] const Person& person() const noexcept;
  void inject(const Fault& f) noexcept override;
  // vocab::World: a person change all or nothing (tried on a copy of the person first), a
  // host stall (the drives' fieldbus lost), what the world shows.
  vocab::PersonResult person(const vocab::PersonCommand& c) noexcept override;
  void host_stalled() noexcept override { inject(Fault{FaultKind::fieldbus_lost, 0, 0}); }
  [[nodiscard]] const PersonView& person_view() const noexcept override { return view().person; }
  [[nodiscard]] std::uint64_t injected() const noexcept override;
  // Queues a command for the next cycle: OK, or QUEUE_FULL (that is its only answer).
  core::Result submit(const core::Command& c) noexcept;
  // False after `jog_link drop` until `clear all`: the pendant's `jog` commands are lost
  // on the way (neither delivered nor answered). The sender asks before submitting.
  [[nodiscard]] bool jog_link_up() const noexcept;
  // One scan cycle: read inputs and feedback, supervise, move, write, advance physics.
  void step() noexcept;

  // Of the last cycle. With two channels, the channels together (spec/scenario-format.md
  // "Two channels"): the state, sub-state and stop of the channel that leads towards safety
  // (the one locked out, else the one whose contactor is open, else A), the alarms of either.
  [[nodiscard]] const core::SupervisorOut& out() const noexcept;
  [[nodiscard]] const CellView& view() const noexcept;            // of the last cycle (A's controller)
  [[nodiscard]] const core::AlarmSet& alarms() const noexcept;    // with since-when and detail (together)
  // SPEC §14: 1 or 2; channel 0 is A, 1 is B (with one channel, both are A).
  [[nodiscard]] std::uint8_t channels() const noexcept;
  [[nodiscard]] const controller::Cell& channel(std::size_t i) const noexcept;
  // Whether channel i runs (not stalled, not crashed by a fault).
  [[nodiscard]] bool channel_running(std::size_t i) const noexcept;
  [[nodiscard]] bool k2_closed() const noexcept;  // K2's auxiliary contact (two channels)
  // The simulated power path as it is (not as commanded): K1 closed, and K2 with two channels.
  [[nodiscard]] bool power_on() const noexcept;
  // The contactor command the world got from channel i in the last cycle (K1: A, K2: B): the
  // channel's output image as written (a cross-check that decided opens it there the same
  // cycle, before its supervisor's state follows), nothing from a crashed channel.
  [[nodiscard]] bool contactor_command(std::size_t i) const noexcept;
  // SPEC §14's campaign (faults/): the size of a channel's supervisor (signal layer, state
  // machine, timers, every monitor's memory), and one bit of channel i's flipped, as a
  // particle hit or a stray write would. The simulated world's only: nothing of the kind
  // reaches a controller on a real backend. False (nothing changed) for a byte or bit outside.
  [[nodiscard]] static std::size_t supervisor_bytes() noexcept;
  bool flip_supervisor_bit(std::size_t channel, std::size_t byte, unsigned bit) noexcept;
  // SPEC §14 `channel A|B flip FIELD [bit N]` (sim/src/flip.cpp): bit N of a named variable
  // of channel i's supervisor (`value` as vocab::Fault's: FlipField << 8 | bit). False (nothing
  // changed) for a field or bit outside vocab::kFlipFields.
  bool flip_field(std::size_t channel, std::uint16_t value) noexcept;
  // Issue 37, opt-in (sim/black_channel.hpp): the shipped segment's black channel between
  // the channels and the simulated devices — the containers and both ends are the real code,
  // the bus a byte copy in this process (the frames are not built: the real wire is tested
  // with ecat-sim). Each channel configures its own connections (a one-channel cell all of
  // them) and takes its safety inputs from the F-DI's and the drives' containers; the plant's
  // K1, K2 and brakes follow the F-DO alone. Before the first step, on the simulated plant
  // only; false with `why` otherwise (nothing changed). Without it (replay, scenarios,
  // golden traces) nothing of this exists.
  bool use_black_channel(const char*& why) noexcept;
  // The black channel, or null when the cell has none.
  [[nodiscard]] const BlackChannel* black_channel() const noexcept;
  // A fault on its wire (false: no black channel, or refused as BlackChannel::inject).
  bool inject_wire(const WireFault& f) noexcept;
  [[nodiscard]] const core::RawInputs& raw_inputs_of_last_cycle() const noexcept;
  [[nodiscard]] core::Leaf leaf() const noexcept;
  // What the supervisor saw in the last cycle (for a differential oracle).
  [[nodiscard]] const core::SafetyInputs& safety_inputs() const noexcept;
  [[nodiscard]] const core::Feedback& feedback() const noexcept;
  [[nodiscard]] const core::Command* commands_taken(std::size_t& n) const noexcept;
  [[nodiscard]] core::Cycle now() const noexcept;                 // cycles run so far
  [[nodiscard]] const core::Config& config() const noexcept;
  // SPEC §14 with the channels in processes of their own (pair/host.hpp): the world alone as
  // their backend. read() is one world cycle (the plant, and the person seen against the arm
  // as the plant's joints place it); write() takes the outputs the power path combined. The
  // controllers of this cell are then not stepped (step() is not called).
  [[nodiscard]] hal::Backend& world_port() noexcept;
  // The controller on this world (for a host that runs it: the runtime's loop, its platform).
  [[nodiscard]] controller::Cell& controller() noexcept;
  [[nodiscard]] const controller::Cell& controller() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;  // allocated once, at construction
};

}  // namespace safestate::sim

// The simulated world behind a controller, as a host sees it: what the HMI's sim panel (the
// gateway's `sim` message, loopback only) may change in it between two cycles, and what it
// shows of itself. Implemented by the in-process simulated cell (sim::Cell); a host gets one
// from the backend factory (backends/factory.hpp), or none: on a real segment, or on an
// emulated one whose world is another process (ecat-sim, reached by its control socket),
// there is no world in this process and nothing here is called.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/signals.hpp"
#include "safestate/vocab/faults.hpp"
#include "safestate/vocab/person.hpp"

namespace safestate::vocab {

// One change of the simulated person, all or nothing (the gateway's `sim` `person`).
struct PersonCommand {
  bool fields = false;  // the scanner's field radii
  float outer_mm = 0.0F;
  float inner_mm = 0.0F;
  bool at = false;  // in (or moved at once) to x, y, standing
  float x_mm = 0.0F;
  float y_mm = 0.0F;
  float radius_mm = kPersonDefaultRadiusMm;
  bool walk = false;  // then walks `points` of `path`
  std::array<PersonWaypoint, kPersonMaxWaypoints> path{};
  std::uint8_t points = 0;
  bool stand = false;  // alone: stops where it is
  bool leave = false;  // alone: leaves the cell
};
enum class PersonResult : std::uint8_t { ok, absent, invalid };

class World {
 public:
  World() = default;
  World(const World&) = default;
  World& operator=(const World&) = default;
  virtual ~World() = default;

  // The physical contacts of SPEC §2; change them between cycles.
  virtual core::RawInputs& inputs() noexcept = 0;
  virtual void inject(const Fault& f) noexcept = 0;
  // Tried on a copy first: nothing changes unless every part of `c` is taken.
  virtual PersonResult person(const PersonCommand& c) noexcept = 0;
  // The host's loop stalled past the fieldbus watchdog: the world's drives would have seen
  // their process data stop (a simulated plant: `fault fieldbus lost`).
  virtual void host_stalled() noexcept = 0;

  [[nodiscard]] virtual const PersonView& person_view() const noexcept = 0;
  [[nodiscard]] virtual std::uint64_t injected() const noexcept = 0;  // fault causes, a bit set
};

}  // namespace safestate::vocab

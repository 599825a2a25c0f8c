// A person in the simulated cell (SPEC §11, issue 20 item 5): a walking human on the floor
// plane, and the two devices that see it, an area scanner (the protective fields
// `field.outer`, `field.inner`) and a distance sensor (`separation_mm`, `separation_valid`).
//
// Plain, deterministic C++: no clock (the cell advances it by its cycle time), no
// randomness, no heap (a path is a fixed array). Positions are in the robot's base frame on
// the floor (x, y in mm; z is ignored: the floor plane).
//
// Both devices are STAND-INS for safety-rated ones (docs/collaborative.md "The simulated
// person"): they see the person exactly and at once. A real scanner has a response time
// (add it to T_r) and a resolution (it sets C); a real distance sensor has an uncertainty
// (Z) and may miss a person (it would then report invalid, which the core treats as 0).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/core/signals.hpp"
#include "safestate/motion/kinematics.hpp"
#include "safestate/vocab/person.hpp"

namespace safestate::sim {

// The person's vocabulary (limits, waypoints, sensors, view) is vocab/person.hpp's.
using vocab::kPersonDefaultRadiusMm;
using vocab::kPersonMaxRadiusMm;
using vocab::kPersonMaxRangeMm;
using vocab::kPersonMaxSpeedMmS;
using vocab::kPersonMaxStandMs;
using vocab::kPersonMaxWaypoints;
using vocab::PersonSensors;
using vocab::PersonView;
using vocab::PersonWaypoint;
using vocab::valid;

// The scanner's view: the body (a circle of `radius_mm` about x, y) reaches into a field of
// radius `field_mm` about the base axis when hypot(x, y) - radius <= field_mm (touching
// the edge counts as in: the safe side).
[[nodiscard]] bool in_field(float x_mm, float y_mm, float radius_mm, float field_mm) noexcept;

// The distance sensor's view: the horizontal distance from the body's edge to the nearest
// of the robot's points (the base and every DH frame origin, the TCP), never below 0.
// `nearest` gets that point's number (0..6 frame origin, 7 TCP).
[[nodiscard]] float separation_to(float x_mm, float y_mm, float radius_mm, const motion::Frames& f,
                                  std::uint8_t& nearest) noexcept;

class Person {
 public:
  // Into the cell at (x, y), standing (a path is dropped). False (nothing changed) for a
  // position off the floor or not finite, or a radius not in (0, 1000] mm.
  bool place(float x_mm, float y_mm, float radius_mm = kPersonDefaultRadiusMm) noexcept;
  // Walks the points in order from where it is; standing at the last one at the end.
  // False (nothing changed) without a person, for 0 or more than 16 points, a point off
  // the floor, a speed not in (0, 2000] mm/s or a stand time over an hour.
  bool walk(const PersonWaypoint* points, std::size_t count) noexcept;
  // Stops where it is (the path is dropped).
  void stand() noexcept;
  // Out of the cell.
  void leave() noexcept;
  // `dt_s` seconds on: towards the waypoint at its speed (arriving exactly on it), then its
  // stand time, then the next one.
  void advance(float dt_s) noexcept;

  [[nodiscard]] bool present() const noexcept { return present_; }
  // Heading for a waypoint, or it moved this cycle (the cycle it arrives: so that a view that
  // says "not walking" always says speed 0; gateway_protocol once read walking false at
  // 1599.9 mm/s).
  [[nodiscard]] bool walking() const noexcept {
    return present_ && ((next_ < count_ && stand_left_s_ <= 0.0) || speed_ > 0.0F);
  }
  [[nodiscard]] float x_mm() const noexcept { return static_cast<float>(x_); }
  [[nodiscard]] float y_mm() const noexcept { return static_cast<float>(y_); }
  [[nodiscard]] float radius_mm() const noexcept { return radius_; }
  [[nodiscard]] float speed_mm_s() const noexcept { return speed_; }
  [[nodiscard]] std::uint8_t waypoint() const noexcept { return static_cast<std::uint8_t>(next_); }
  [[nodiscard]] std::uint8_t waypoints() const noexcept { return static_cast<std::uint8_t>(count_); }

  // The two devices: the person's fields and separation written into `raw` (only what
  // `s` enables), and what they saw into `view` (always).
  void sense(const PersonSensors& s, const motion::Frames& robot, core::RawInputs& raw, PersonView& view) const noexcept;

 private:
  bool present_ = false;
  double x_ = 0.0;  // double: a long walk in 1 ms steps does not drift
  double y_ = 0.0;
  float radius_ = kPersonDefaultRadiusMm;
  float speed_ = 0.0F;
  std::array<PersonWaypoint, kPersonMaxWaypoints> path_{};
  std::size_t count_ = 0;
  std::size_t next_ = 0;
  double stand_left_s_ = 0.0;
};

}  // namespace safestate::sim

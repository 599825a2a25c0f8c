// The simulated person's vocabulary (SPEC §11, docs/collaborative.md "The simulated person"):
// its limits, a walk's points, the sensors' settings, what a view of it shows, and the
// scenario format's `person` lines. The person itself (how it walks, what the devices see)
// is the simulator's (sim/person.hpp); the gateway's JSON form checks against these limits.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include "safestate/vocab/tokens.hpp"

namespace safestate::vocab {

// ISO 13855's fastest approach of a person: a walk faster than this is refused.
inline constexpr float kPersonMaxSpeedMmS = 2000.0F;
// The body as a circle on the floor: 250 mm covers the shoulders of most adults (an
// assumption; ISO 13855 has no body radius, its C covers a reaching arm).
inline constexpr float kPersonDefaultRadiusMm = 250.0F;
inline constexpr float kPersonMaxRadiusMm = 1000.0F;
// The floor the person may walk on: |x|, |y| up to 20 m.
inline constexpr float kPersonMaxRangeMm = 20000.0F;
inline constexpr std::size_t kPersonMaxWaypoints = 16;
inline constexpr std::uint32_t kPersonMaxStandMs = 3'600'000;  // an hour

// One point of a walk: go there at `speed_mm_s` (0 < speed <= 2000), then stand `stand_ms`.
struct PersonWaypoint {
  float x_mm = 0.0F;
  float y_mm = 0.0F;
  float speed_mm_s = 0.0F;
  std::uint32_t stand_ms = 0;
};

// The simulated scanner and distance sensor (assumed values, docs/collaborative.md).
struct PersonSensors {
  bool scanner = true;          // sets the four OSSD channels of field.outer / field.inner
  bool distance_sensor = true;  // sets separation_mm / separation_valid
  float outer_mm = 2000.0F;     // the fields: circles about the robot's base axis (z)
  float inner_mm = 1000.0F;
};
// 0 < inner < outer <= kPersonMaxRangeMm, finite.
[[nodiscard]] bool valid(const PersonSensors& s) noexcept;

// What the cell shows of the person (CellView::person), of the last cycle.
struct PersonView {
  bool present = false;
  float x_mm = 0.0F;
  float y_mm = 0.0F;
  float radius_mm = 0.0F;
  float speed_mm_s = 0.0F;        // 0 while standing
  bool walking = false;
  std::uint8_t waypoint = 0;      // index of the waypoint it heads to (or stands at)
  std::uint8_t waypoints = 0;     // of the current path
  float axis_distance_mm = 0.0F;  // body centre to the robot's base axis
  bool outer_interrupted = false; // what the scanner sees (also without `scanner`)
  bool inner_interrupted = false;
  float separation_mm = 0.0F;     // what the distance sensor sees (also without it)
  std::uint8_t nearest_point = 0; // 0..6 origin of DH frame k, 7 = TCP (motion::Frames)
  PersonSensors sensors{};        // the field radii, for a view of the floor
};

// `person at X Y [radius=R]` | `person walk X Y SPEED [stand MS] ...` | `person stand` |
// `person leave` (spec: docs/scenarios.md, an extension of spec/scenario-format.md).
struct PersonStep {
  enum class Action : std::uint8_t { at, walk, stand, leave };
  Action action = Action::stand;
  float x_mm = 0.0F;  // at
  float y_mm = 0.0F;
  float radius_mm = kPersonDefaultRadiusMm;
  std::vector<PersonWaypoint> path;  // walk (1..16 points)
};

// `person_fields=OUTER,INNER` (a config key): the scanner's field radii into `out` (nothing
// else changes). Empty: taken.
Problem parse_person_fields(std::string_view value, PersonSensors& out);

// The words after `person`. `present`: whether a person is in the cell before this line;
// updated. Empty: well formed, else the problem naming the bad word.
Problem parse_person(const Tokens& words, PersonStep& out, bool& present);

}  // namespace safestate::vocab

// @req COL-SIM-PERSON
#include "safestate/sim/person.hpp"

#include <cmath>
#include <limits>
#include <span>

namespace safestate::sim {

namespace {

bool on_floor(float x, float y) noexcept {
  return std::isfinite(x) && std::isfinite(y) && std::fabs(x) <= kPersonMaxRangeMm && std::fabs(y) <= kPersonMaxRangeMm;
}

// An arrival closer than this (mm) counts as there: float steps of a long walk.
constexpr double kArriveMm = 1.0e-6;

}  // namespace


bool in_field(float x_mm, float y_mm, float radius_mm, float field_mm) noexcept {
  return std::hypot(x_mm, y_mm) - radius_mm <= field_mm;
}

float separation_to(float x_mm, float y_mm, float radius_mm, const motion::Frames& f, std::uint8_t& nearest) noexcept {
  float best = std::numeric_limits<float>::infinity();
  nearest = 0;
  for (std::size_t k = 0; k <= f.origin.size(); ++k) {
    const motion::Vec3& p = (k < f.origin.size()) ? f.origin[k] : f.tcp;
    const float d = std::hypot(x_mm - p[0], y_mm - p[1]);
    if (d < best) {
      best = d;
      nearest = static_cast<std::uint8_t>(k);
    }
  }
  const float s = best - radius_mm;
  return (s > 0.0F) ? s : 0.0F;
}

bool Person::place(float x_mm, float y_mm, float radius_mm) noexcept {
  if (!on_floor(x_mm, y_mm) || !std::isfinite(radius_mm) || radius_mm <= 0.0F || radius_mm > kPersonMaxRadiusMm) {
    return false;
  }
  present_ = true;
  x_ = static_cast<double>(x_mm);
  y_ = static_cast<double>(y_mm);
  radius_ = radius_mm;
  stand();
  return true;
}

bool Person::walk(const PersonWaypoint* points, std::size_t count) noexcept {
  if (!present_ || points == nullptr || count == 0U || count > kPersonMaxWaypoints) {
    return false;
  }
  const std::span<const PersonWaypoint> pts(points, count);
  for (const PersonWaypoint& p : pts) {
    if (!on_floor(p.x_mm, p.y_mm) || !std::isfinite(p.speed_mm_s) || p.speed_mm_s <= 0.0F ||
        p.speed_mm_s > kPersonMaxSpeedMmS || p.stand_ms > kPersonMaxStandMs) {
      return false;
    }
  }
  for (std::size_t i = 0; i < count; ++i) {
    path_[i] = pts[i];
  }
  count_ = count;
  next_ = 0;
  stand_left_s_ = 0.0;
  speed_ = 0.0F;
  return true;
}

void Person::stand() noexcept {
  count_ = 0;
  next_ = 0;
  stand_left_s_ = 0.0;
  speed_ = 0.0F;
}

void Person::leave() noexcept {
  stand();
  present_ = false;
}

void Person::advance(float dt_s) noexcept {
  speed_ = 0.0F;
  if (!present_ || next_ >= count_ || !(dt_s > 0.0F)) {
    return;
  }
  const auto dt = static_cast<double>(dt_s);
  if (stand_left_s_ > 0.0) {
    stand_left_s_ -= dt;
    if (stand_left_s_ > 1.0e-9) {
      return;  // still standing at path_[next_ - 1]
    }
    stand_left_s_ = 0.0;
    if (next_ >= count_) {
      return;
    }
  }
  const PersonWaypoint& w = path_[next_];
  const double dx = static_cast<double>(w.x_mm) - x_;
  const double dy = static_cast<double>(w.y_mm) - y_;
  const double left = std::hypot(dx, dy);
  const double step = static_cast<double>(w.speed_mm_s) * dt;
  if (step + kArriveMm >= left) {
    x_ = static_cast<double>(w.x_mm);  // exactly on the waypoint; the rest of the cycle is not walked on
    y_ = static_cast<double>(w.y_mm);
    speed_ = static_cast<float>(left / dt);
    stand_left_s_ = static_cast<double>(w.stand_ms) * 1.0e-3;
    ++next_;  // past the last one: the walk is over, it stands there
    return;
  }
  x_ += dx / left * step;
  y_ += dy / left * step;
  speed_ = w.speed_mm_s;
}

void Person::sense(const PersonSensors& s, const motion::Frames& robot, core::RawInputs& raw,
                   PersonView& view) const noexcept {
  view.present = present_;
  view.sensors = s;
  if (!present_) {
    view.walking = false;
    view.speed_mm_s = 0.0F;
    view.outer_interrupted = view.inner_interrupted = false;
    return;
  }
  const float x = x_mm();
  const float y = y_mm();
  view.x_mm = x;
  view.y_mm = y;
  view.radius_mm = radius_;
  view.speed_mm_s = speed_;
  view.walking = walking();
  view.waypoint = waypoint();
  view.waypoints = waypoints();
  view.axis_distance_mm = std::hypot(x, y);
  view.outer_interrupted = in_field(x, y, radius_, s.outer_mm);
  view.inner_interrupted = in_field(x, y, radius_, s.inner_mm);
  view.separation_mm = separation_to(x, y, radius_, robot, view.nearest_point);
  if (s.scanner) {
    raw.field_outer_a = raw.field_outer_b = !view.outer_interrupted;  // NC: 1 = clear
    raw.field_inner_a = raw.field_inner_b = !view.inner_interrupted;
  }
  if (s.distance_sensor) {
    // Whole millimetres, rounded down (the safe side); the floor is 20 m wide at most.
    raw.separation_mm = static_cast<std::int32_t>(std::floor(view.separation_mm));
    raw.separation_valid = true;
  }
}

}  // namespace safestate::sim

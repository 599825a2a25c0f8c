#include "safestate/vocab/person.hpp"

#include <cmath>
#include <string>

namespace safestate::vocab {

namespace {


constexpr const char* kForms =
    "person at X Y [radius=R], person walk X Y SPEED [stand MS] [X Y SPEED [stand MS] ...], person stand, "
    "person leave";

std::string number_text(double v) {
  std::string s = std::to_string(v);
  while (!s.empty() && s.back() == '0') {
    s.pop_back();
  }
  if (!s.empty() && s.back() == '.') {
    s.pop_back();
  }
  return s;
}

// A coordinate on the floor, mm.
Problem coordinate(std::string_view tok, const char* what, float& out) {
  double v = 0.0;
  if (!to_real(tok, v)) {
    return std::string(what) + " " + quoted(tok) + " is not a number (mm)";
  }
  if (v < -static_cast<double>(kPersonMaxRangeMm) || v > static_cast<double>(kPersonMaxRangeMm)) {
    return std::string(what) + " " + quoted(tok) + " is off the floor (|x|, |y| <= 20000 mm)";
  }
  out = static_cast<float>(v);
  return {};
}

Problem parse_at(const Tokens& a, PersonStep& out) {
  if (a.size() != 3 && a.size() != 4) {
    return "person at needs X Y (mm) and at most radius=R, found " + std::to_string(a.size() - 1) + " word(s)";
  }
  if (Problem p = coordinate(a[1], "person at: X", out.x_mm); !p.empty()) {
    return p;
  }
  if (Problem p = coordinate(a[2], "person at: Y", out.y_mm); !p.empty()) {
    return p;
  }
  out.radius_mm = kPersonDefaultRadiusMm;
  if (a.size() == 4) {
    std::string_view key;
    std::string_view value;
    double r = 0.0;
    if (!split_pair(a[3], key, value) || key != "radius") {
      return "person at: expected radius=R after X Y, found " + quoted(a[3]);
    }
    if (!to_real(value, r) || r <= 0.0 || r > static_cast<double>(kPersonMaxRadiusMm)) {
      return "person at: radius " + quoted(value) + " is not a number of mm in (0, 1000]";
    }
    out.radius_mm = static_cast<float>(r);
  }
  return {};
}

Problem parse_walk(const Tokens& a, PersonStep& out) {
  std::size_t i = 1;
  while (i < a.size()) {
    const std::size_t n = out.path.size() + 1;
    const std::string point = "person walk: point " + std::to_string(n);
    if (n > kPersonMaxWaypoints) {
      return "person walk: more than 16 points";
    }
    std::size_t numbers = 0;
    while (numbers < 3 && i + numbers < a.size() && a[i + numbers] != "stand") {
      ++numbers;
    }
    if (numbers < 3) {
      return point + " needs X Y SPEED, found " + std::to_string(numbers) + " number(s)";
    }
    PersonWaypoint w{};
    if (Problem p = coordinate(a[i], (point + ": X").c_str(), w.x_mm); !p.empty()) {
      return p;
    }
    if (Problem p = coordinate(a[i + 1], (point + ": Y").c_str(), w.y_mm); !p.empty()) {
      return p;
    }
    double v = 0.0;
    if (!to_real(a[i + 2], v)) {
      return point + ": speed " + quoted(a[i + 2]) + " is not a number (mm/s)";
    }
    if (v <= 0.0) {
      return point + ": speed " + number_text(v) + " mm/s is not above 0 (`person stand` stops)";
    }
    if (v > static_cast<double>(kPersonMaxSpeedMmS)) {
      return point + ": speed " + number_text(v) + " mm/s is over 2000 (ISO 13855's fastest approach)";
    }
    w.speed_mm_s = static_cast<float>(v);
    i += 3;
    if (i < a.size() && a[i] == "stand") {
      std::uint32_t ms = 0;
      if (i + 1 >= a.size() || !to_number(a[i + 1], ms) || ms > kPersonMaxStandMs) {
        return point + ": stand needs MS, a whole number of milliseconds up to 3600000";
      }
      w.stand_ms = ms;
      i += 2;
    }
    out.path.push_back(w);
  }
  if (out.path.empty()) {
    return "person walk needs at least one point X Y SPEED";
  }
  return {};
}

}  // namespace

bool valid(const PersonSensors& s) noexcept {
  return std::isfinite(s.inner_mm) && std::isfinite(s.outer_mm) && s.inner_mm > 0.0F && s.inner_mm < s.outer_mm &&
         s.outer_mm <= kPersonMaxRangeMm;
}

Problem parse_person_fields(std::string_view value, PersonSensors& out) {
  const std::size_t comma = value.find(',');
  double outer = 0.0;
  double inner = 0.0;
  PersonSensors ps = out;
  if (comma == std::string_view::npos || !to_real(value.substr(0, comma), outer) ||
      !to_real(value.substr(comma + 1), inner)) {
    return "config person_fields: expected OUTER,INNER (mm), found " + quoted(value);
  }
  ps.outer_mm = static_cast<float>(outer);
  ps.inner_mm = static_cast<float>(inner);
  if (!valid(ps)) {
    return "config person_fields: " + quoted(value) + " is not 0 < INNER < OUTER <= 20000 mm";
  }
  out = ps;
  return {};
}

// @req COL-SIM-PERSON
Problem parse_person(const Tokens& a, PersonStep& out, bool& present) {
  if (a.empty()) {
    return std::string("person needs what it does: ") + kForms;
  }
  const std::string_view what = a[0];
  const bool needs_person = (what == "walk" || what == "stand" || what == "leave");
  if (needs_person && !present) {
    return "person " + std::string(what) + ": no person in the cell (person at X Y first)";
  }
  if (what == "at") {
    out.action = PersonStep::Action::at;
    Problem p = parse_at(a, out);
    present = present || p.empty();
    return p;
  }
  if (what == "walk") {
    out.action = PersonStep::Action::walk;
    return parse_walk(a, out);
  }
  if (what == "stand" || what == "leave") {
    if (a.size() != 1) {
      return "person " + std::string(what) + " takes nothing after it, found " + quoted(a[1]);
    }
    out.action = (what == "stand") ? PersonStep::Action::stand : PersonStep::Action::leave;
    present = (what == "stand");
    return {};
  }
  return "unknown person action " + quoted(what) + " (expected " + kForms + ")";
}

}  // namespace safestate::vocab

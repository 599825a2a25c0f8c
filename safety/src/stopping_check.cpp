// @req STOP-CHECK
#include "safestate/safety/stopping_check.hpp"

#include <cstdio>

#include "safestate/motion/robot.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/safety/stopping_data.hpp"

namespace safestate::safety {

namespace {
std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.0f", v);
  return b;
}
}  // namespace

std::vector<std::string> stopping_warnings(const Loaded& c) {
  std::vector<std::string> w;
  // The figures were measured on the built-in IRB 120 (bench/stopping.py without --robot);
  // another arm's stop is its own: say that it is not checked rather than judge it by them.
  if (c.robot.robot && !robot::is_builtin(*c.robot.robot)) {
    w.push_back("stop.max_time_ms, collaborative.ssm: not checked against measured stopping data: " + std::string(stopping::kSource) +
                " holds the built-in IRB 120's; measure robot " + c.robot.robot->d.name +
                "'s (python3 bench/stopping.py --robot FILE) and compare");
    return w;
  }
  // The lightest measured level whose payload is at least the tool's, both in kg as the
  // configuration holds them (float), the levels being fractions of the arm's rated payload
  // (robot.rated_payload_kg, else the IRB 120's 3 kg): a payload of exactly a level's (0.99 kg,
  // 33 % of 3 kg) is judged by that level's figures, not by the next one's (0.99 as a float is
  // a little above 0.33 x 3).
  const double rated = c.robot.rated_payload_kg > 0.0 ? c.robot.rated_payload_kg : static_cast<double>(motion::kRatedPayloadKg);
  const stopping::Level* lv = &stopping::kLevels.back();
  for (const stopping::Level& l : stopping::kLevels) {
    if (static_cast<float>(l.payload_fraction * rated) >= c.limits.payload_kg) {
      lv = &l;
      break;
    }
  }
  const std::string at = " (stopping data, payload " + fmt(lv->payload_fraction * 100.0) + " %: " + stopping::kSource + ")";
  if (static_cast<double>(c.limits.max_stop_ms) < lv->cat1_stop_ms) {
    w.push_back("stop.max_time_ms: " + std::to_string(c.limits.max_stop_ms) + " ms is shorter than the measured Cat 1 stop of " +
                fmt(lv->cat1_stop_ms) + " ms (axis " + std::to_string(lv->cat1_axis) +
                "): every Cat 1 stop from full speed would escalate to Cat 0" + at);
  }
  if (c.collaborative && c.collaborative->ssm && c.collaborative->ssm->enabled) {
    const Ssm& s = *c.collaborative->ssm;
    if (s.decel_mm_s2 > lv->tcp_decel_mm_s2) {
      w.push_back("collaborative.ssm.decel_mm_s2: " + fmt(s.decel_mm_s2) +
                  " mm/s² is more than the measured TCP deceleration of " + fmt(lv->tcp_decel_mm_s2) +
                  " mm/s²: the separation would be too short" + at);
    }
    if (s.reaction_ms < stopping::kReactionMs) {
      w.push_back("collaborative.ssm.reaction_ms: " + fmt(s.reaction_ms) + " ms is less than the measured reaction of " +
                  fmt(stopping::kReactionMs) + " ms (change -> the arm slows): T_r must cover the whole chain" + at);
    }
  }
  return w;
}

}  // namespace safestate::safety

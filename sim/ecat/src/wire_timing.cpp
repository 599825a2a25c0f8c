// Response time of a safety function on the wire, timed by the emulated segment per exchange
// (issue 21 item 4). See wire_timing.hpp for what counts as the reaction and the safe state.
#include "safestate/robot/description.hpp"
#include "safestate/ecat/wire_timing.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>

#include "safestate/controller/controller.hpp"
#include "safestate/core/arm.hpp"
#include "safestate/ecat/cell.hpp"
#include "safestate/motion/robot.hpp"

namespace safestate::ecat {

namespace {

const core::PreparedArm& arm_model() {
  static const core::PreparedArm arm = core::prepare_arm(controller::Controller::arm_geometry(safestate::robot::active().model));
  return arm;
}

core::ArmPose pose_of(const core::JointArray& q, const std::array<float, 3>& tcp) {
  core::ArmPose p{};
  core::arm_forward(arm_model(), q, tcp, p);
  return p;
}

// A position or velocity as the wire carries it (0x6064, 0x606C: whole counts) and the
// master reads it back: the limits are judged on what the core sees, not on the plant's float.
float on_wire(float rad) {
  return static_cast<float>(static_cast<double>(std::lround(static_cast<double>(rad) * kCountsPerRad)) / kCountsPerRad);
}

core::JointArray positions(const hal::ProcessImageIn& in) {
  core::JointArray q{};
  for (std::size_t a = 0; a < hal::kAxes; ++a) q[a] = on_wire(in.drive[a].position_rad);
  return q;
}

core::JointArray velocities(const hal::ProcessImageIn& in) {
  core::JointArray v{};
  for (std::size_t a = 0; a < hal::kAxes; ++a) v[a] = on_wire(in.drive[a].velocity_rad_s);
  return v;
}

bool parse_float(std::string_view s, float& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return !s.empty() && r.ec == std::errc{} && r.ptr == s.data() + s.size() && std::isfinite(v);
}

const char* name(WireTiming::Stop s) {
  switch (s) {
    case WireTiming::Stop::cat0: return "cat0";
    case WireTiming::Stop::cat1: return "cat1";
    case WireTiming::Stop::cat2: return "cat2";
    case WireTiming::Stop::reduce: return "reduce";
    case WireTiming::Stop::reduced: return "reduced";
  }
  return "?";
}

const char* name(WireTiming::From f) {
  switch (f) {
    case WireTiming::From::input: return "input";
    case WireTiming::From::fault: return "fault";
    case WireTiming::From::joint: return "joint";
    case WireTiming::From::speed: return "speed";
    case WireTiming::From::tcp_speed: return "tcp_speed";
    case WireTiming::From::point_speed: return "point_speed";
    case WireTiming::From::tcp_pos: return "tcp";
    case WireTiming::From::tilt: return "tilt";
    case WireTiming::From::separation: return "separation";
  }
  return "?";
}

constexpr const char* kUsage =
    "time needs STOP from=WHAT: STOP cat0, cat1, cat2, reduce=MM_S or reduced; WHAT input, fault, joint.N>RAD, "
    "speed.N>RAD_S, tcp_speed>MM_S, point_speed>MM_S, tcp.x|y|z>MM, tilt>RAD (N 1..6) or separation<MM";

}  // namespace

float max_point_speed(const hal::ProcessImageIn& in, const std::array<float, 3>& tcp) noexcept {
  const core::ArmPose p = pose_of(positions(in), tcp);
  const core::JointArray v = velocities(in);
  float m = core::point_speed(p, p.tcp, core::kAxes, v);
  for (std::size_t k = 1; k < core::kArmFrames; ++k) {
    m = std::max(m, core::point_speed(p, p.origin[k], k, v));
  }
  return m;
}

std::string WireTiming::parse(std::string_view words, Spec& out) {
  std::istringstream in{std::string(words)};
  std::string stop, from, extra;
  in >> stop >> from >> extra;
  if (stop.empty() || from.empty() || !extra.empty()) return kUsage;
  Spec s{};
  if (stop == "cat0") {
    s.stop = Stop::cat0;
  } else if (stop == "cat1") {
    s.stop = Stop::cat1;
  } else if (stop == "cat2") {
    s.stop = Stop::cat2;
  } else if (stop == "reduced") {
    s.stop = Stop::reduced;
  } else if (stop.rfind("reduce=", 0) == 0) {
    s.stop = Stop::reduce;
    if (!parse_float(std::string_view(stop).substr(7), s.reduce_mm_s) || !(s.reduce_mm_s > 0.0F && s.reduce_mm_s <= 10000.0F)) {
      return "time: reduce needs a limit 0 < MM_S <= 10000, got '" + stop + "'";
    }
  } else {
    return "time: unknown stop '" + stop + "' (cat0, cat1, cat2, reduce=MM_S or reduced)";
  }
  if (from.rfind("from=", 0) != 0) return kUsage;
  const std::string_view w = std::string_view(from).substr(5);
  if (w == "input" || w == "fault") {
    s.from = (w == "input") ? From::input : From::fault;
    out = s;
    return {};
  }
  if (w.rfind("separation<", 0) == 0) {
    float mm = 0.0F;
    if (!parse_float(w.substr(11), mm) || !(mm > 0.0F && mm <= 100000.0F)) {
      return "time: separation needs a distance 0 < MM <= 100000, got '" + std::string(w) + "'";
    }
    s.from = From::separation;
    s.threshold = mm;
    out = s;
    return {};
  }
  const std::size_t gt = w.find('>');
  if (gt == std::string_view::npos) {
    return "time: '" + std::string(w) + "' is not input, fault, QUANTITY>VALUE or separation<MM";
  }
  const std::string_view q = w.substr(0, gt);
  float v = 0.0F;
  if (!parse_float(w.substr(gt + 1U), v)) return "time: the threshold in '" + std::string(w) + "' is not a number";
  s.threshold = v;
  const auto axis = [&](std::string_view prefix) -> bool {
    if (q.size() != prefix.size() + 1U || q.substr(0, prefix.size()) != prefix) return false;
    const char c = q.back();
    if (c < '1' || c > '6') return false;
    s.index = static_cast<std::uint8_t>(c - '1');
    return true;
  };
  if (axis("joint.")) {
    s.from = From::joint;
  } else if (axis("speed.")) {
    s.from = From::speed;
  } else if (q == "tcp_speed" || q == "point_speed") {
    s.from = (q == "tcp_speed") ? From::tcp_speed : From::point_speed;
  } else if (q == "tcp.x" || q == "tcp.y" || q == "tcp.z") {
    s.from = From::tcp_pos;
    s.index = static_cast<std::uint8_t>(q.back() - 'x');
  } else if (q == "tilt") {
    s.from = From::tilt;
  } else {
    return "time: unknown quantity '" + std::string(q) + "' (joint.N, speed.N, tcp_speed, point_speed, tcp.x|y|z, tilt)";
  }
  if ((s.from == From::speed || s.from == From::tcp_speed || s.from == From::point_speed || s.from == From::tilt) &&
      !(v > 0.0F)) {
    return "time: the threshold of '" + std::string(q) + "' must be above 0";
  }
  out = s;
  return {};
}

void WireTiming::arm(const Spec& s) noexcept {
  // The targets' history is kept: the exchange right after arming may already be the start,
  // and its commanded speed is the reference of the fall.
  WireTiming fresh{};
  fresh.tcp_ = tcp_;
  fresh.have_prev_ = have_prev_;
  fresh.prev_target_ = prev_target_;
  fresh.prev_powered_ = prev_powered_;
  *this = fresh;
  spec_ = s;
  armed_ = true;
}

bool WireTiming::crossed(const hal::ProcessImageIn& in) noexcept {
  const std::size_t i = spec_.index;
  const float t = spec_.threshold;
  switch (spec_.from) {
    case From::input: {
      const bool c = input_pending_;
      input_pending_ = false;
      return c;
    }
    case From::fault: {
      const bool c = fault_pending_;
      fault_pending_ = false;
      return c;
    }
    case From::joint: return positions(in)[i] > t;
    case From::speed: return std::fabs(velocities(in)[i]) > t;
    case From::tcp_speed: {
      const core::ArmPose p = pose_of(positions(in), tcp_);
      return core::point_speed(p, p.tcp, core::kAxes, velocities(in)) > t;
    }
    case From::point_speed: return max_point_speed(in, tcp_) > t;
    case From::tcp_pos: return pose_of(positions(in), tcp_).tcp[i] > t;
    case From::separation:  // invalid counts as 0 (SPEC §11: unknown is unsafe)
      return !in.safety.separation_valid || static_cast<float>(in.safety.separation_mm) < t;
    case From::tilt: {
      const core::Vec3 z = pose_of(positions(in), tcp_).tool_z;
      if (!have_ref_axis_) {
        have_ref_axis_ = true;
        ref_axis_ = z;
        return false;
      }
      const float c = (z[0] * ref_axis_[0]) + (z[1] * ref_axis_[1]) + (z[2] * ref_axis_[2]);
      return std::acos(std::clamp(c, -1.0F, 1.0F)) > t;
    }
  }
  return false;
}

bool WireTiming::reacted(const hal::ProcessImageOut& out, double speed_counts, float tcp_mm_s) const noexcept {
  if (spec_.stop == Stop::reduced) return out.reduced_active;  // the safe output, nothing else
  if (!(out.contactor && out.contactor_k2)) return true;  // power removed (K1 or K2, SPEC §14): a Cat 0, or a stop escalated to it
  if (spec_.stop == Stop::cat0) return false;
  if (spec_.stop == Stop::reduce && out.reduced_active) return true;  // the DO's reduced_active bit: reduced mode on
  if (speed_counts < peak_speed_counts_ - kFallCounts) return true;
  return spec_.stop == Stop::reduce && tcp_mm_s <= spec_.reduce_mm_s;
}

void WireTiming::exchange(std::uint64_t n, std::uint64_t now_ns, const hal::ProcessImageOut& out,
                          const hal::ProcessImageIn& in, std::uint32_t cycle_us) noexcept {
  // The commanded motion of this exchange: the targets' step since the last one.
  std::array<float, hal::kAxes> target{};
  double step2 = 0.0;
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    target[a] = out.drive[a].target_position_rad;
    const double d = have_prev_ ? std::round(static_cast<double>(target[a] - prev_target_[a]) * kCountsPerRad) : 0.0;
    step2 += d * d;
  }
  const double speed_counts = std::sqrt(step2);
  float tcp_mm_s = 0.0F;
  if (spec_.stop == Stop::reduce && have_prev_) {
    core::JointArray q0{};
    core::JointArray q1{};
    std::copy(prev_target_.begin(), prev_target_.end(), q0.begin());
    std::copy(target.begin(), target.end(), q1.begin());
    const core::Vec3 p0 = pose_of(q0, tcp_).tcp;
    const core::Vec3 p1 = pose_of(q1, tcp_).tcp;
    const float d = std::hypot(p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]);
    tcp_mm_s = d * 1.0e6F / static_cast<float>(cycle_us);
  }
  const bool moved = have_prev_ && speed_counts > 0.0;
  prev_target_ = target;
  const bool had_prev = have_prev_;
  have_prev_ = true;
  const bool was_powered = prev_powered_;
  prev_powered_ = out.contactor && out.contactor_k2;
  if (!armed_) return;

  if (!start_.seen) {
    const bool trigger = crossed(in);
    // A fault on the wire (a damaged container to the safe output terminal, issue 37) can open
    // the outputs in the very exchange that carries it: a reaction of 0 exchanges, not "early".
    const bool at_once = trigger && spec_.from == From::fault && was_powered && reacted(out, speed_counts, tcp_mm_s);
    if (!at_once && had_prev && !(out.contactor && out.contactor_k2) && !early_.seen) early_ = Mark{true, n, now_ns};  // stopped before the trigger
    if (spec_.stop == Stop::reduced && out.reduced_active && !early_.seen) early_ = Mark{true, n, now_ns};
    if (trigger) {
      start_ = Mark{true, n, now_ns};
      if (at_once) reaction_ = start_;
      peak_speed_counts_ = speed_counts;
      trace_[0] = static_cast<float>(speed_counts);
      traced_ = 1;
    }
    return;
  }
  if (traced_ < kTrace) trace_[traced_++] = static_cast<float>(speed_counts);
  if (!reaction_.seen && reacted(out, speed_counts, tcp_mm_s)) reaction_ = Mark{true, n, now_ns};
  peak_speed_counts_ = std::max(peak_speed_counts_, speed_counts);  // a program still accelerating at the start
  if (!reaction_.seen || safe_.seen) return;
  switch (spec_.stop) {
    case Stop::cat0: {
      bool still = !(in.contactor_closed && (!in.two_contactors || in.k2_closed));  // the power path open
      for (const core::DriveFeedback& d : in.drive) still = still && std::fabs(d.velocity_rad_s) < kStandstillRadS;
      if (still) safe_ = Mark{true, n, now_ns};
      break;
    }
    case Stop::cat1:
      if (!(out.contactor && out.contactor_k2)) safe_ = Mark{true, n, now_ns};
      break;
    case Stop::cat2:
      if (moved) {
        still_ = Mark{};
      } else if (!still_.seen) {
        still_ = Mark{true, n, now_ns};
      }
      if (still_.seen && n + 1U - still_.exchange >= kHeldExchanges) safe_ = still_;
      break;
    case Stop::reduce:
      if (tcp_mm_s <= spec_.reduce_mm_s) safe_ = Mark{true, n, now_ns};
      break;
    case Stop::reduced:
      safe_ = reaction_;
      break;
  }
}

nlohmann::json WireTiming::to_json(const hal::ProcessImageIn& last_in) const {
  nlohmann::json j;
  const core::ArmPose p = pose_of(positions(last_in), tcp_);
  j["tcp_mm"] = p.tcp;
  j["tool_z"] = p.tool_z;
  j["tool_tcp_mm"] = tcp_;
  j["armed"] = armed_;
  if (!armed_) return j;
  j["stop"] = name(spec_.stop);
  j["from"] = name(spec_.from);
  const auto mark = [this](const Mark& m) -> nlohmann::json {
    if (!m.seen || !start_.seen) return nullptr;
    return {{"exchange", m.exchange}, {"cycles", m.exchange - start_.exchange}, {"us", (m.ns - start_.ns) / 1000U}};
  };
  j["start_exchange"] = start_.seen ? nlohmann::json(start_.exchange) : nlohmann::json(nullptr);
  j["reaction"] = mark(reaction_);
  j["safe"] = mark(safe_);
  j["early_exchange"] = early_.seen ? nlohmann::json(early_.exchange) : nlohmann::json(nullptr);
  nlohmann::json tr = nlohmann::json::array();
  for (std::size_t k = 0; k < traced_; ++k) tr.push_back(std::round(static_cast<double>(trace_[k]) * 10.0) / 10.0);
  j["speed_counts"] = tr;
  return j;
}

}  // namespace safestate::ecat

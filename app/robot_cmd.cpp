// `safestate robot fk --robot FILE [--base LINK] [--flange LINK] --q DEG,DEG,DEG,DEG,DEG,DEG
// [--qd DEG/S,...] [--tcp X,Y,Z]` (issue 38): where SafeState's model puts the arm, for checks
// from outside (tests/integration/test_robot_vs_pinocchio.py compares it with Pinocchio).
// `--q -` reads many poses from stdin, one JSON line out per line in.
//
// Prints one JSON object (mm): `links` maps every link at or below the base to its origin in
// the base frame. The chain's links (the base, each joint's child link) and the flange are the
// core's own model (core::arm_forward, float, what the monitors use); the links fixed to them
// off the chain (a URDF's ee_link, base, camera frames) come from the description in double.
// `joints` lists each joint's origin and axis (the core's), `flange_mm`, `tcp_mm`; with --qd
// `speed_mm_s`: core::point_speed of every joint origin, the flange and the TCP.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "safestate/core/arm.hpp"
#include "safestate/robot/description.hpp"

namespace safestate::app {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool numbers(const std::string& text, std::size_t n, std::vector<double>& out) {
  out.clear();
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::size_t used = 0;
    double v = 0.0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      return false;
    }
    if (item.find_first_not_of(" \t", used) != std::string::npos || !std::isfinite(v)) {
      return false;
    }
    out.push_back(v);
  }
  return out.size() == n;
}

nlohmann::json mm(const core::Vec3& v) {
  return nlohmann::json::array({static_cast<double>(v[0]), static_cast<double>(v[1]), static_cast<double>(v[2])});
}

}  // namespace

int robot_fk_main(const std::string& q_deg, const std::string& qd_deg_s, const std::string& tcp_mm) {
  std::vector<double> tcp{0.0, 0.0, 0.0};
  if (!tcp_mm.empty() && !numbers(tcp_mm, 3, tcp)) {
    std::fprintf(stderr, "safestate robot fk: --tcp needs three finite numbers in mm, comma-separated (got '%s')\n",
                 tcp_mm.c_str());
    return 2;
  }
  const robot::Robot& r = robot::active();
  const core::PreparedArm arm = core::prepare_arm(r.geometry);
  const robot::LinkTree tree(r);
  const core::Vec3 t{static_cast<float>(tcp[0]), static_cast<float>(tcp[1]), static_cast<float>(tcp[2])};
  std::vector<robot::LinkPose> poses;

  // One pose: q (deg) and, if not empty, qd (deg/s).
  const auto one = [&](const std::vector<double>& q, const std::vector<double>& qd) {
    core::JointArray qr{};
    core::JointArray qdr{};
    std::array<double, robot::kJoints> qrad{};
    for (std::size_t k = 0; k < robot::kJoints; ++k) {
      qrad[k] = q[k] * kPi / 180.0;
      qr[k] = static_cast<float>(qrad[k]);
      qdr[k] = qd.empty() ? 0.0F : static_cast<float>(qd[k] * kPi / 180.0);
    }
    core::ArmPose pose{};
    core::arm_forward(arm, qr, t, pose);
    nlohmann::json links = nlohmann::json::object();
    tree.poses(qrad, poses);
    for (const robot::LinkPose& l : poses) {
      links[l.name] =
          nlohmann::json::array({l.pose.xyz_m[0] * 1000.0, l.pose.xyz_m[1] * 1000.0, l.pose.xyz_m[2] * 1000.0});
    }
    // The core's: each joint's child link sits at the joint's origin; the flange.
    nlohmann::json joints = nlohmann::json::array();
    for (std::size_t k = 0; k < robot::kJoints; ++k) {
      links[r.d.joints[k].child] = mm(pose.origin[k]);
      joints.push_back({{"name", r.d.joints[k].name},
                        {"link", r.d.joints[k].child},
                        {"origin_mm", mm(pose.origin[k])},
                        {"axis", mm(pose.z[k])}});
    }
    links[r.d.flange] = mm(pose.origin[core::kAxes]);
    nlohmann::json out;
    out["q_deg"] = q;
    out["links"] = std::move(links);
    out["joints"] = std::move(joints);
    out["flange_mm"] = mm(pose.origin[core::kAxes]);
    out["flange_z"] = mm(pose.tool_z);
    out["tcp_mm"] = mm(pose.tcp);
    if (!qd.empty()) {
      // core::point_speed, as the T1 monitor: joint k+1's origin moved by joints 1..k, the
      // flange and the TCP by all six.
      nlohmann::json pts = nlohmann::json::array();
      for (std::size_t k = 0; k <= core::kAxes; ++k) {
        pts.push_back(static_cast<double>(core::point_speed(pose, pose.origin[k], (k < core::kAxes) ? k : core::kAxes, qdr)));
      }
      out["qd_deg_s"] = qd;
      out["speed_mm_s"] = {{"origins", std::move(pts)},
                           {"tcp", static_cast<double>(core::point_speed(pose, pose.tcp, core::kAxes, qdr))}};
    }
    return out;
  };

  if (q_deg == "-") {
    // Many poses: stdin lines of 6 numbers (q, deg) or 12 (q deg, qd deg/s), spaces or commas;
    // one JSON object per line.
    std::string line;
    long n = 0;
    while (std::getline(std::cin, line)) {
      ++n;
      for (char& c : line) {
        c = (c == ' ' || c == '\t') ? ',' : c;
      }
      std::string clean;
      for (std::size_t i = 0; i < line.size(); ++i) {  // runs of separators as one
        if (line[i] == ',' && (clean.empty() || clean.back() == ',')) continue;
        if (line[i] != '\r') clean.push_back(line[i]);
      }
      while (!clean.empty() && clean.back() == ',') clean.pop_back();
      if (clean.empty()) continue;
      std::vector<double> v;
      std::vector<double> q;
      std::vector<double> qd;
      if (numbers(clean, 6, v)) {
        q = v;
      } else if (numbers(clean, 12, v)) {
        q.assign(v.begin(), v.begin() + 6);
        qd.assign(v.begin() + 6, v.end());
      } else {
        std::fprintf(stderr, "safestate robot fk: line %ld: 6 numbers (q, deg) or 12 (q deg, qd deg/s) needed\n", n);
        return 2;
      }
      std::cout << one(q, qd).dump() << '\n';
    }
    return 0;
  }
  std::vector<double> q;
  if (!numbers(q_deg, robot::kJoints, q)) {
    std::fprintf(stderr, "safestate robot fk: --q needs six finite numbers in degrees, comma-separated (got '%s')\n",
                 q_deg.c_str());
    return 2;
  }
  std::vector<double> qd;
  if (!qd_deg_s.empty() && !numbers(qd_deg_s, robot::kJoints, qd)) {
    std::fprintf(stderr, "safestate robot fk: --qd needs six finite numbers in deg/s, comma-separated (got '%s')\n",
                 qd_deg_s.c_str());
    return 2;
  }
  nlohmann::json out = one(q, qd);
  out["robot"] = r.d.name;
  out["source"] = r.d.source;
  out["base"] = r.d.base;
  out["flange"] = r.d.flange;
  out["units"] = {{"length", "mm"}, {"angle", "deg"}, {"speed", "mm/s"}};
  std::cout << out.dump() << '\n';
  return 0;
}

}  // namespace safestate::app

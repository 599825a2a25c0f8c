// `safestate robot fk --robot FILE [--base LINK] [--flange LINK] --q DEG,DEG,DEG,DEG,DEG,DEG
// [--tcp X,Y,Z]` (issue 38): where SafeState's model puts the arm, for checks from outside
// (tests/integration/test_robot_vs_pinocchio.py compares it with Pinocchio).
//
// Prints one JSON object (mm): `links` maps every link at or below the base to its origin in
// the base frame. The chain's links (the base, each joint's child link) and the flange are the
// core's own model (core::arm_forward, float, what the monitors use); the links fixed to them
// off the chain (a URDF's ee_link, base, camera frames) come from the description in double.
// `joints` lists each joint's origin and axis (the core's), `flange_mm`, `tcp_mm`.
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

int robot_fk_main(const std::string& q_deg, const std::string& tcp_mm) {
  std::vector<double> q;
  if (!numbers(q_deg, robot::kJoints, q)) {
    std::fprintf(stderr, "safestate robot fk: --q needs six finite numbers in degrees, comma-separated (got '%s')\n",
                 q_deg.c_str());
    return 2;
  }
  std::vector<double> tcp{0.0, 0.0, 0.0};
  if (!tcp_mm.empty() && !numbers(tcp_mm, 3, tcp)) {
    std::fprintf(stderr, "safestate robot fk: --tcp needs three finite numbers in mm, comma-separated (got '%s')\n",
                 tcp_mm.c_str());
    return 2;
  }
  const robot::Robot& r = robot::active();
  core::JointArray qr{};
  std::array<double, robot::kJoints> qd{};
  for (std::size_t k = 0; k < robot::kJoints; ++k) {
    qd[k] = q[k] * kPi / 180.0;
    qr[k] = static_cast<float>(qd[k]);
  }
  const core::Vec3 t{static_cast<float>(tcp[0]), static_cast<float>(tcp[1]), static_cast<float>(tcp[2])};
  core::ArmPose pose{};
  core::arm_forward(core::prepare_arm(r.geometry), qr, t, pose);

  nlohmann::json links = nlohmann::json::object();
  for (const robot::LinkPose& l : robot::link_poses(r, qd)) {
    links[l.name] = nlohmann::json::array({l.pose.xyz_m[0] * 1000.0, l.pose.xyz_m[1] * 1000.0, l.pose.xyz_m[2] * 1000.0});
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
  out["robot"] = r.d.name;
  out["source"] = r.d.source;
  out["base"] = r.d.base;
  out["flange"] = r.d.flange;
  out["q_deg"] = q;
  out["links"] = std::move(links);
  out["joints"] = std::move(joints);
  out["flange_mm"] = mm(pose.origin[core::kAxes]);
  out["flange_z"] = mm(pose.tool_z);
  out["tcp_mm"] = mm(pose.tcp);
  out["units"] = {{"length", "mm"}, {"angle", "deg"}};
  std::cout << out.dump() << '\n';
  return 0;
}

}  // namespace safestate::app

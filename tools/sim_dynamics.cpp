// sim_dynamics: the simulated arm's rigid-body model and torques, for an outside oracle
// (tests/integration/test_dynamics_vs_pinocchio.py).
//
//   sim_dynamics [--robot FILE.urdf [--base LINK] [--flange LINK]] ...: the arm (default: the
//                          built-in IRB 120, examples/robots/abb_irb120.urdf)
//   sim_dynamics --model   prints the description's name, base and flange links, joint names,
//                          ranges and gravity as JSON (SI units)
//   sim_dynamics           reads lines of 21 numbers from stdin, q[6] qd[6] qdd[6] f_world[3]
//                          (rad, rad/s, rad/s^2, N in the base frame, on the TCP = the flange,
//                          no payload) and prints the 6 joint torques (N m) of
//                          sim::ArmDynamics::torques() per line, full precision.
//   sim_dynamics --core    the core's collision model instead (core::arm_dynamics on the
//                          description's chain and inertials, float, as the running program
//                          prepares it): reads lines of 24 numbers, q[6] qd[6] qdd[6] tau[6]
//                          (tau: the drives' torques, N m), prints the model's 6 joint torques
//                          and the force at the TCP (the flange, N, base frame) that the
//                          estimator reads from tau - model (core::estimate_tcp_force).
//
// Exit 0; 1 when a line's torques could not be computed (NaN printed); 2 on a malformed
// line or option.
#include <array>
#include <cstddef>
#include <exception>
#include <iomanip>
#include <iostream>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "safestate/core/collision.hpp"
#include "safestate/core/dynamics.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/sim/dynamics.hpp"

namespace {

using safestate::sim::JointVec;
using safestate::sim::Vec3;
namespace core = safestate::core;

double d(float v) { return static_cast<double>(v); }

template <std::size_t N>
std::vector<double> to_vec(const std::array<float, N>& a) {
  std::vector<double> v;
  v.reserve(N);
  for (const float x : a) {
    v.push_back(d(x));
  }
  return v;
}

int print_model() {
  const safestate::robot::Robot& r = safestate::robot::active();
  const nlohmann::json model = {
      {"name", r.d.name},
      {"source", r.d.source},
      {"base", r.d.base},
      {"flange", r.d.flange},
      {"joints", [&] {
         nlohmann::json j = nlohmann::json::array();
         for (const auto& jt : r.d.joints) {
           j.push_back(jt.name);
         }
         return j;
       }()},
      {"gravity_m_s2", {0.0, 0.0, -d(core::kGravityM_S2)}},
      {"q_min_rad", to_vec(r.model.q_min_rad)},
      {"q_max_rad", to_vec(r.model.q_max_rad)},
  };
  std::cout << model.dump(2) << '\n';
  return 0;
}

// Each non-blank line of stdin as N numbers, handed to `each`; a line of another count stops
// with exit 2 naming it and `what` the line should hold. Returns 2, or 1 when `each` said a
// line failed, else 0.
template <std::size_t N, typename Each>
int lines_from_stdin(const char* what, Each each) {
  int rc = 0;
  std::string line;
  long n = 0;
  while (std::getline(std::cin, line)) {
    ++n;
    if (line.find_first_not_of(" \t\r") == std::string::npos) {
      continue;
    }
    std::istringstream in(line);
    std::array<double, N> v{};
    std::size_t got = 0;
    double x = 0.0;
    while (in >> x) {
      if (got < v.size()) {
        v.at(got) = x;
      }
      ++got;
    }
    if (!in.eof() || got != v.size()) {
      std::cerr << "sim_dynamics: line " << n << ": expected " << N << " numbers (" << what << ")\n";
      return 2;
    }
    if (!each(v)) {
      rc = 1;
    }
  }
  return rc;
}

int torques_from_stdin() {
  safestate::sim::ArmDynamics dyn;
  std::cout << std::setprecision(17);  // round-trip precision
  const Vec3 tcp{0.0, 0.0, 0.0};
  return lines_from_stdin<21>("q qd qdd f_world", [&](const std::array<double, 21>& v) {
    JointVec q{};
    JointVec qd{};
    JointVec qdd{};
    Vec3 f{};
    for (std::size_t i = 0; i < 6; ++i) {
      q.at(i) = v.at(i);
      qd.at(i) = v.at(6 + i);
      qdd.at(i) = v.at(12 + i);
    }
    for (std::size_t i = 0; i < 3; ++i) {
      f.at(i) = v.at(18 + i);
    }
    JointVec tau{};
    const bool ok = dyn.torques(q, qd, qdd, f, tcp, tau);
    for (std::size_t i = 0; i < tau.size(); ++i) {
      std::cout << (i == 0 ? "" : " ") << tau.at(i);
    }
    std::cout << '\n';
    return ok;
  });
}

// The core's model: lines of q qd qdd tau (24 numbers) -> model torques (6) and force (3).
int core_from_stdin() {
  const safestate::robot::Robot& r = safestate::robot::active();
  const core::ArmDynamicsModel m = core::prepare_dynamics(r.geometry, r.inertials);
  std::cout << std::setprecision(9);  // float round-trip
  return lines_from_stdin<24>("q qd qdd tau", [&](const std::array<double, 24>& v) {
    core::JointArray q{};
    core::JointArray qd{};
    core::JointArray qdd{};
    core::JointArray residual{};
    for (std::size_t i = 0; i < 6; ++i) {
      q.at(i) = static_cast<float>(v.at(i));
      qd.at(i) = static_cast<float>(v.at(6 + i));
      qdd.at(i) = static_cast<float>(v.at(12 + i));
    }
    core::ArmDynamicsState s{};
    core::arm_dynamics(m, q, qd, qdd, 0.0F, {0.0F, 0.0F, 0.0F}, s);
    for (std::size_t i = 0; i < 6; ++i) {
      residual.at(i) = static_cast<float>(v.at(18 + i)) - s.tau_nm.at(i);
    }
    core::Vec3 f{};
    (void)core::estimate_tcp_force(s, residual, f);
    for (std::size_t i = 0; i < 6; ++i) {
      std::cout << (i == 0 ? "" : " ") << s.tau_nm.at(i);
    }
    std::cout << ' ' << f[0] << ' ' << f[1] << ' ' << f[2] << '\n';
    return true;
  });
}

int run(std::span<char*> argv) {
  std::vector<std::string> args;
  for (const char* a : argv.subspan(1)) {
    args.emplace_back(a);
  }
  // --robot FILE [--base LINK] [--flange LINK] first: the arm (default: the built-in IRB 120).
  std::string file;
  std::string base;
  std::string flange;
  while (args.size() >= 2U && (args[0] == "--robot" || args[0] == "--base" || args[0] == "--flange")) {
    (args[0] == "--robot" ? file : args[0] == "--base" ? base : flange) = args[1];
    args.erase(args.begin(), args.begin() + 2);
  }
  std::string error;
  if (!safestate::robot::select(file, base, flange, error)) {
    std::cerr << "sim_dynamics: " << error << '\n';
    return 2;
  }
  if (args.empty()) {
    return torques_from_stdin();
  }
  if (args.size() == 1 && args[0] == "--model") {
    return print_model();
  }
  if (args.size() == 1 && args[0] == "--core") {
    return core_from_stdin();
  }
  if (args.size() == 1 && (args[0] == "--help" || args[0] == "-h")) {
    std::cout << "usage: sim_dynamics [--robot FILE.urdf [--base LINK] [--flange LINK]] [--model | --core]\n"
                 "  --model  the arm's description: name, links, joints, ranges, gravity (JSON)\n"
                 "  --core   stdin lines 'q[6] qd[6] qdd[6] tau[6]' -> the core's collision model: 6 joint\n"
                 "           torques (N m) and the TCP force it reads from tau (N, base frame)\n"
                 "  (none)   stdin lines 'q[6] qd[6] qdd[6] f_world[3]' -> 6 joint torques (N m) per line\n";
    return 0;
  }
  std::cerr << "sim_dynamics: unknown option (usage: sim_dynamics [--model | --core])\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(std::span<char*>(argv, static_cast<std::size_t>(argc)));
  } catch (const std::exception& e) {
    std::cerr << "sim_dynamics: " << e.what() << '\n';
    return 2;
  }
}

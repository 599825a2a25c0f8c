// The ABB IRB 120-3/0.58's rigid-body data (SPEC §11 collision detection), one table for the
// two models that use it: the core's own fixed-size estimator (core/src/monitors/collision.cpp,
// float, no heap, builds for the Cortex-M4) and the simulated arm's dynamics (sim/, Orocos KDL's
// recursive Newton-Euler solver, double). The test tests/integration/test_dynamics_vs_pinocchio.py
// compares the simulator's torques with Pinocchio's on random states.
//
// Source [ROS]: ROS-Industrial abb_irb120_support, urdf/irb120_3_58_macro.xacro (BSD-3-Clause;
// only these numbers are used, no file is copied), the same file docs/robot.md cites for the
// kinematics. Frames are the URDF's: at q = 0 every link frame is parallel to the base frame
// (z up, x forward); joint k sits at `joint_origin_m` in link k-1's frame and turns about the
// unit `axis` of that frame; its link's centre of mass `com_m` and its inertia about the
// centre of mass (`inertia`, kg m^2: ixx ixy ixz iyy iyz izz) are in link k's frame. The
// joint angles and their signs are the DH model's (docs/robot.md: the axes agree at q = 0).
// The flange (ABB's tool0) is link 6's origin turned +90 deg about y: tool0 z = link 6 x.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/types.hpp"

namespace safestate::core {

enum class JointAxis : std::uint8_t { x = 0, y = 1, z = 2 };

struct LinkInertial {
  std::array<float, 3> joint_origin_m;  // joint k in link k-1's frame
  JointAxis axis;                       // joint k's axis in link k-1's (= link k's) frame
  float mass_kg;
  std::array<float, 3> com_m;           // centre of mass in link k's frame
  std::array<float, 6> inertia;         // about the centre of mass: ixx ixy ixz iyy iyz izz
};

// [ROS] links 1..6 (the base link does not move).
inline constexpr std::array<LinkInertial, kAxes> kIrb120Links{{
    {{0.0F, 0.0F, 0.0F}, JointAxis::z, 3.067F, {9.77e-05F, -0.00012F, 0.23841F},
     {0.0142175F, -1.28579e-05F, -2.31364e-05F, 0.0144041F, 1.93404e-05F, 0.0104533F}},
    {{0.0F, 0.0F, 0.29F}, JointAxis::y, 3.909F, {0.00078F, -0.00212F, 0.10124F},
     {0.0603111F, 9.83431e-06F, 5.72407e-05F, 0.041569F, -0.00050497F, 0.0259548F}},
    {{0.0F, 0.0F, 0.27F}, JointAxis::y, 2.944F, {0.02281F, 0.00106F, 0.05791F},
     {0.00835606F, -8.01545e-05F, 0.00142884F, 0.016713F, -0.000182227F, 0.0126984F}},
    {{0.0F, 0.0F, 0.07F}, JointAxis::x, 1.328F, {0.2247F, 0.00015F, 0.00041F},
     {0.00284661F, -2.12765e-05F, -1.6435e-05F, 0.00401346F, 1.31336e-05F, 0.0052535F}},
    {{0.302F, 0.0F, 0.0F}, JointAxis::y, 0.546F, {-0.00109F, 3.68e-05F, 6.22e-05F},
     {0.000404891F, 1.61943e-06F, 8.46805e-07F, 0.000892825F, -1.51792e-08F, 0.000815468F}},
    {{0.072F, 0.0F, 0.0F}, JointAxis::x, 0.137F, {-0.00706F, -0.00017F, -1.32e-06F},
     {0.001F, 0.0F, 0.0F, 0.001F, 0.0F, 0.001F}},
}};

// Standard gravity, m/s^2, along -z of the base frame (the robot stands on the floor).
inline constexpr float kGravityM_S2 = 9.81F;

// Rated torque of each axis at the joint (after the gear), N m: the unit of CiA 402 0x6077
// (per mille of rated torque). [ASM]: ABB publishes no motor or gear torques for the IRB 120;
// these are chosen so that gravity with the rated 3 kg payload at full reach stays below
// rated torque on every axis (axis 2 needs some 45 N m at most, axis 3 some 20 N m) and the
// drives' peak (300 %, hal::kDriveMaxTorquePermille) is a plausible servo peak.
inline constexpr std::array<float, kAxes> kRatedTorqueNm{60.0F, 60.0F, 30.0F, 8.0F, 8.0F, 5.0F};

}  // namespace safestate::core

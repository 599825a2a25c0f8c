// The arm's rigid-body data as the core's collision estimator holds it (SPEC §11 collision
// detection; core/src/monitors/collision.cpp, float, no heap, builds for the Cortex-M4): each
// moving link's mass, centre of mass and inertia, and each drive's rated torque (the unit of
// CiA 402 0x6077, per mille of rated torque). Read from the robot's description at start-up,
// outside the core (robot/: each moving link's URDF <inertial> with the links fixed to it
// folded in, the joint <limit effort> as the rated torque), and handed over with the safety
// limits (SafetyLimits::inertials). The kinematics (where each joint sits, its axis) is the
// core's ArmGeometry (arm.hpp), the same the other monitors use.
//
// kIrb120Inertials is the built-in ABB IRB 120-3/0.58 (examples/robots/abb_irb120.urdf) as
// constants, for the Cortex-M4 build and the unit tests; tests/unit/test_robot_description.cpp
// checks that the file gives exactly these numbers. Source [ROS]: ROS-Industrial
// abb_irb120_support, urdf/irb120_3_58_macro.xacro (BSD-3-Clause; only these numbers are used,
// no file is copied); rated torques [ASM]. docs/robot.md "Dynamics".
#pragma once

#include <array>

#include "safestate/core/arm.hpp"
#include "safestate/core/types.hpp"

namespace safestate::core {

// Moving link k (the link joint k turns, with every link fixed to it), in joint k's frame.
struct LinkInertial {
  float mass_kg = 0.0F;
  Vec3 com_m{};                    // centre of mass, m
  std::array<float, 6> inertia{};  // about the centre of mass, kg m^2: ixx ixy ixz iyy iyz izz
};

struct ArmInertials {
  std::array<LinkInertial, kAxes> link{};
  // Rated torque of each drive at the joint (after the gear), N m: what the drives' torque
  // actual is per mille of. The URDF's <limit effort>.
  JointArray rated_torque_nm{};
};

// The IRB 120 in its URDF's frames: at q = 0 every joint frame is parallel to the base frame;
// joint 6's frame sits at the wrist centre, so link 6's centre of mass is 72 mm - 7.06 mm
// along x (its flange, tool0, is 72 mm further along x, turned +90 deg about y).
inline constexpr ArmInertials kIrb120Inertials{
    {{
        {3.067F, {9.77e-05F, -0.00012F, 0.23841F},
         {0.0142175F, -1.28579e-05F, -2.31364e-05F, 0.0144041F, 1.93404e-05F, 0.0104533F}},
        {3.909F, {0.00078F, -0.00212F, 0.10124F},
         {0.0603111F, 9.83431e-06F, 5.72407e-05F, 0.041569F, -0.00050497F, 0.0259548F}},
        {2.944F, {0.02281F, 0.00106F, 0.05791F},
         {0.00835606F, -8.01545e-05F, 0.00142884F, 0.016713F, -0.000182227F, 0.0126984F}},
        {1.328F, {0.2247F, 0.00015F, 0.00041F},
         {0.00284661F, -2.12765e-05F, -1.6435e-05F, 0.00401346F, 1.31336e-05F, 0.0052535F}},
        {0.546F, {-0.00109F, 3.68e-05F, 6.22e-05F},
         {0.000404891F, 1.61943e-06F, 8.46805e-07F, 0.000892825F, -1.51792e-08F, 0.000815468F}},
        {0.137F, {0.06494F, -0.00017F, -1.32e-06F}, {0.001F, 0.0F, 0.0F, 0.001F, 0.0F, 0.001F}},
    }},
    // [ASM]: ABB publishes no motor or gear torques for the IRB 120; chosen so that gravity
    // with the rated 3 kg payload at full reach stays below rated torque on every axis (axis 2
    // needs some 45 N m at most, axis 3 some 20 N m) and the drives' peak (300 %,
    // hal::kDriveMaxTorquePermille) is a plausible servo peak.
    {60.0F, 60.0F, 30.0F, 8.0F, 8.0F, 5.0F},
};

// Standard gravity, m/s^2, along -z of the base frame (the robot stands on the floor).
inline constexpr float kGravityM_S2 = 9.81F;

}  // namespace safestate::core

// The arm SafeState supervises: ABB IRB 120-3/0.58 (3 kg payload, 580 mm reach to the
// wrist centre). Every number of the arm lives here and nowhere else, so a change of
// robot is a change of this one file; docs/robot.md explains the table.
//
// Sources (see docs/robot.md for the full story):
//  [PS]  ABB, "Product specification IRB 120", doc. 3HAC035960-001: link dimensions
//        (290 / 270 / 70 / 302 / 72 mm), axis working ranges, axis maximum speeds.
//        Its load-diagram page confirms the 72 mm from the axis-5 centre to the flange
//        (J5 = m((Z + 0.072)^2 + L^2) ...).
//  [ROS] ROS-Industrial abb/abb_irb120_support/urdf/irb120_3_58_macro.xacro, which
//        encodes the same dimensions and limits (in m and rad); used as a cross-check
//        of the joint directions and of the numbers recalled from [PS].
//  [ASM] Assumed by us; the manufacturer does not publish it.
#pragma once

#include <array>
#include <cstdint>

namespace safestate::motion {

inline constexpr std::size_t kJoints = 6;
// Links 0 (base, fixed) to 6 (flange); DH frame k is attached to link k.
inline constexpr std::size_t kLinks = kJoints + 1;

inline constexpr float kPi = 3.14159265358979F;

// Datasheets give degrees; the model keeps radians so no caller ever converts.
constexpr float deg(float degrees) noexcept { return degrees * (kPi / 180.0F); }

// One row of the standard (distal, Denavit-Hartenberg 1955 / Spong) convention:
// A_k = Rot_z(q_k + theta_offset) * Trans_z(d) * Trans_x(a) * Rot_x(alpha).
struct DhRow {
  float a_mm;
  float alpha_rad;
  float d_mm;
  float theta_offset_rad;
};

struct RobotModel {
  const char* name;
  float reach_mm;  // catalogue reach to the wrist centre, for plausibility checks
  std::array<DhRow, kJoints> dh;
  std::array<float, kJoints> q_min_rad;
  std::array<float, kJoints> q_max_rad;
  std::array<float, kJoints> qd_max_rad_s;
  std::array<float, kJoints> qdd_max_rad_s2;
  // TCP in the flange frame (frame 6: z out of the flange, x towards -z_base at home;
  // identical to ABB's tool0). A mounted tool must replace this with its own offset.
  std::array<float, 3> tcp_offset_mm;
  std::array<const char*, kLinks> link_names;
};

// [PS] The rated payload (the 3 of "IRB 120-3/0.58").
inline constexpr float kRatedPayloadKg = 3.0F;

// [ASM] ABB publishes no axis accelerations. We assume every axis can reach its maximum
// speed from standstill in this time; the supervisor uses the result only as a
// plausibility bound, so a too-small ramp time is the conservative error.
inline constexpr float kAssumedRampTime_s = 0.25F;

inline constexpr std::array<float, kJoints> kQdMax = {
    deg(250.0F),  // axis 1 [PS] 250 deg/s
    deg(250.0F),  // axis 2 [PS] 250 deg/s
    deg(250.0F),  // axis 3 [PS] 250 deg/s
    deg(320.0F),  // axis 4 [PS] 320 deg/s
    deg(320.0F),  // axis 5 [PS] 320 deg/s
    deg(420.0F),  // axis 6 [PS] 420 deg/s
};

inline constexpr RobotModel kRobot = {
    "ABB IRB 120-3/0.58",
    580.0F,  // [PS] reach 0.58 m = a2 + hypot(a3, d4) = 270 + 310 mm
    {{
        // a      alpha         d       theta offset
        {0.0F, -kPi / 2.0F, 290.0F, 0.0F},          // 1: base plate to axis 2 height [PS]
        {270.0F, 0.0F, 0.0F, -kPi / 2.0F},          // 2: upper arm, axis 2 to axis 3 [PS]
        {70.0F, -kPi / 2.0F, 0.0F, 0.0F},           // 3: elbow offset, axis 3 to axis 4 [PS]
        {0.0F, kPi / 2.0F, 302.0F, 0.0F},           // 4: forearm along axis 4 to wrist centre [PS]
        {0.0F, -kPi / 2.0F, 0.0F, 0.0F},            // 5: wrist centre (axes 4, 5, 6 meet)
        {0.0F, 0.0F, 72.0F, kPi},                   // 6: wrist centre to flange [PS]; pi makes
                                                    //    frame 6 = ABB tool0
    }},
    // Working ranges [PS], same in [ROS]. The DH axes were chosen to point the way ABB's
    // positive directions do (z0 up, z1 = z2 = z4 = +y, z3 = z5 = +x at home), so the
    // asymmetric axis-3 range maps without a sign flip.
    {-deg(165.0F), -deg(110.0F), -deg(110.0F), -deg(160.0F), -deg(120.0F), -deg(400.0F)},
    {deg(165.0F), deg(110.0F), deg(70.0F), deg(160.0F), deg(120.0F), deg(400.0F)},
    kQdMax,
    {
        kQdMax[0] / kAssumedRampTime_s,  // [ASM]
        kQdMax[1] / kAssumedRampTime_s,  // [ASM]
        kQdMax[2] / kAssumedRampTime_s,  // [ASM]
        kQdMax[3] / kAssumedRampTime_s,  // [ASM]
        kQdMax[4] / kAssumedRampTime_s,  // [ASM]
        kQdMax[5] / kAssumedRampTime_s,  // [ASM]
    },
    // tool0: no tool mounted. Zero keeps the model honest (a default tool length would be
    // invented); the cell configuration must set the real tool before T1 speed checks.
    {0.0F, 0.0F, 0.0F},
    {"base", "shoulder", "upper_arm", "elbow", "forearm", "wrist", "flange"},
};

}  // namespace safestate::motion

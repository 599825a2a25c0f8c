// The arm SafeState supervises, as the motion layer holds it: a chain of six revolute
// joints read from the robot's URDF at start-up (robot/: `--robot FILE.urdf`, the safety
// configuration's `robot` key). kRobot is the default, the ABB IRB 120-3/0.58 of
// examples/robots/abb_irb120.urdf written out as constants (for the Cortex-M4 build and the
// unit tests; tests/unit/test_robot_description.cpp checks that the file gives exactly these
// numbers). docs/robot.md explains the numbers and where they come from.
//
// Sources (see docs/robot.md for the full story):
//  [PS]  ABB, "Product specification IRB 120", doc. 3HAC035960-001: link dimensions
//        (290 / 270 / 70 / 302 / 72 mm), axis working ranges, axis maximum speeds.
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

using Vec3f = std::array<float, 3>;
using Mat3f = std::array<Vec3f, 3>;  // row-major; columns are the child frame's axes
inline constexpr Mat3f kEye{{{1.0F, 0.0F, 0.0F}, {0.0F, 1.0F, 0.0F}, {0.0F, 0.0F, 1.0F}}};

// A frame fixed in its parent (URDF <origin>: xyz in mm, rpy as its rotation matrix), fixed
// joints folded in.
struct FixedFrame {
  Vec3f xyz_mm;
  Mat3f R;
};

// Joint k: its frame in joint k-1's frame at joint k-1's zero (the base link's for k = 1),
// and the unit axis it turns about in its own frame.
struct ChainJoint {
  FixedFrame origin;
  Vec3f axis;
};

struct RobotModel {
  const char* name;
  // Above the farthest the flange gets from joint 2's origin: the lengths of the chain's fixed
  // offsets from joint 3 to the flange, added (for views and plausibility checks).
  float reach_mm;
  std::array<ChainJoint, kJoints> joints;
  FixedFrame flange;  // in joint 6's frame
  std::array<float, kJoints> q_min_rad;
  std::array<float, kJoints> q_max_rad;
  std::array<float, kJoints> qd_max_rad_s;
  std::array<float, kJoints> qdd_max_rad_s2;
  // TCP in the flange frame (the flange link's frame, e.g. tool0: z out of the flange).
  // A mounted tool must replace this with its own offset.
  std::array<float, 3> tcp_offset_mm;
  // 0: the base link, k = 1..6: joint k's child link (the link it turns).
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

// Working ranges [PS], same in [ROS], in the signs of ABB's positive directions.
inline constexpr std::array<float, kJoints> kQMin{-deg(165.0F), -deg(110.0F), -deg(110.0F),
                                                  -deg(160.0F), -deg(120.0F), -deg(400.0F)};
inline constexpr std::array<float, kJoints> kQMax{deg(165.0F), deg(110.0F), deg(70.0F),
                                                  deg(160.0F), deg(120.0F), deg(400.0F)};

// At q = 0 every joint frame is parallel to the base frame (z up, x forward through the
// arm); the flange is ABB's tool0, joint 6's frame turned +90 deg about y (z out of the
// flange along the base's x, x pointing down).
inline constexpr RobotModel kRobot = {
    "ABB IRB 120-3/0.58",
    714.0F,  // 270 + 70 + 302 + 72 mm (the catalogue's 580 mm reach is to the wrist centre)
    {{
        {{{0.0F, 0.0F, 0.0F}, kEye}, {0.0F, 0.0F, 1.0F}},    // 1: base plate, turns about z
        {{{0.0F, 0.0F, 290.0F}, kEye}, {0.0F, 1.0F, 0.0F}},  // 2: 290 mm up [PS], about y
        {{{0.0F, 0.0F, 270.0F}, kEye}, {0.0F, 1.0F, 0.0F}},  // 3: upper arm 270 mm [PS], about y
        {{{0.0F, 0.0F, 70.0F}, kEye}, {1.0F, 0.0F, 0.0F}},   // 4: elbow offset 70 mm [PS], about x
        {{{302.0F, 0.0F, 0.0F}, kEye}, {0.0F, 1.0F, 0.0F}},  // 5: forearm 302 mm to the wrist centre [PS]
        {{{0.0F, 0.0F, 0.0F}, kEye}, {1.0F, 0.0F, 0.0F}},    // 6: at the wrist centre (axes 4, 5, 6 meet)
    }},
    // tool0: 72 mm from the wrist centre [PS], turned +90 deg about y.
    {{72.0F, 0.0F, 0.0F}, {{{0.0F, 0.0F, 1.0F}, {0.0F, 1.0F, 0.0F}, {-1.0F, 0.0F, 0.0F}}}},
    kQMin,
    kQMax,
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
    {"base_link", "link_1", "link_2", "link_3", "link_4", "link_5", "link_6"},
};

}  // namespace safestate::motion

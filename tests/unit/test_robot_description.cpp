// The robot description (robot/, issue 38): the shipped IRB 120 URDF gives exactly the
// compiled-in model; the core's general chain equals the former DH model on random poses; the
// core (frame vectors) and the motion layer (matrix products) agree on a general arm with
// turned frames, fixed joints and a skew axis; every kind of broken description is refused
// naming the joint or link.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "safestate/controller/controller.hpp"
#include "safestate/core/arm.hpp"
#include "safestate/motion/kinematics.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/robot/description.hpp"

namespace core = safestate::core;
namespace motion = safestate::motion;
namespace robot = safestate::robot;

namespace {

std::unique_ptr<robot::Robot> load(const std::string& urdf, std::string& error, const std::string& base = "",
                                   const std::string& flange = "") {
  error.clear();
  return robot::load_text(urdf, "test", base, flange, error);
}

// A URDF from parts: links named in `links`, joints as written.
std::string urdf(const std::string& body) { return "<?xml version=\"1.0\"?><robot name=\"t\">" + body + "</robot>"; }

std::string lnk(const std::string& name, const std::string& inner = "") {
  return "<link name=\"" + name + "\">" + inner + "</link>";
}

std::string joint(const std::string& name, const std::string& type, const std::string& parent,
                  const std::string& child, const std::string& xyz = "0 0 0.1", const std::string& rpy = "0 0 0",
                  const std::string& axis = "0 0 1", const std::string& extra = "",
                  const std::string& limit = "<limit lower=\"-3\" upper=\"3\" velocity=\"2\" effort=\"10\"/>") {
  std::string j = "<joint name=\"" + name + "\" type=\"" + type + "\"><parent link=\"" + parent +
                  "\"/><child link=\"" + child + "\"/><origin xyz=\"" + xyz + "\" rpy=\"" + rpy + "\"/>";
  if (type != "fixed") {
    j += "<axis xyz=\"" + axis + "\"/>" + limit;
  }
  return j + extra + "</joint>";
}

// Six revolute joints base -> l1 .. l6 -> tool0 (fixed); joint k's type, axis, extra and
// limit may be replaced.
struct Arm {
  std::array<std::string, 6> type{"revolute", "revolute", "revolute", "revolute", "revolute", "revolute"};
  std::array<std::string, 6> axis{"0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"};
  std::array<std::string, 6> xyz{"0 0 0.2", "0.05 0 0.1", "0 0 0.3", "0.1 0 0.05", "0.25 0 0", "0.05 0 0"};
  std::array<std::string, 6> rpy{"0 0 0", "0 0 0", "0 0 0", "0 0 0", "0 0 0", "0 0 0"};
  std::array<std::string, 6> extra{};
  std::array<std::string, 6> limit{};
  std::string tail = joint("flange", "fixed", "l6", "tool0", "0 0 0.08");
  std::string more;

  [[nodiscard]] std::string text() const {
    std::string b = lnk("base") + lnk("tool0");
    std::string parent = "base";
    for (std::size_t k = 0; k < 6; ++k) {
      const std::string child = "l" + std::to_string(k + 1);
      b += lnk(child, "<inertial><origin xyz=\"0.01 0 0.02\"/><mass value=\"1.5\"/><inertia ixx=\"0.01\" ixy=\"0\" "
                       "ixz=\"0\" iyy=\"0.02\" iyz=\"0\" izz=\"0.03\"/></inertial>");
      b += limit[k].empty()
               ? joint("j" + std::to_string(k + 1), type[k], parent, child, xyz[k], rpy[k], axis[k], extra[k])
               : joint("j" + std::to_string(k + 1), type[k], parent, child, xyz[k], rpy[k], axis[k], extra[k],
                       limit[k]);
      parent = child;
    }
    return urdf(b + tail + more);
  }
};

void expect_refused(const std::string& text, const std::string& must_name, const std::string& base = "",
                    const std::string& flange = "") {
  std::string error;
  EXPECT_EQ(load(text, error, base, flange), nullptr) << must_name;
  EXPECT_NE(error.find(must_name), std::string::npos) << "error: " << error << "\nmust name: " << must_name;
}

// The IRB 120 as the DH table it was before issue 38 (docs/robot.md "DH convention").
constexpr float kPi = 3.14159265358979F;
const std::array<core::DhParam, 6> kIrb120Dh{{
    {0.0F, -kPi / 2.0F, 290.0F, 0.0F},
    {270.0F, 0.0F, 0.0F, -kPi / 2.0F},
    {70.0F, -kPi / 2.0F, 0.0F, 0.0F},
    {0.0F, kPi / 2.0F, 302.0F, 0.0F},
    {0.0F, -kPi / 2.0F, 0.0F, 0.0F},
    {0.0F, 0.0F, 72.0F, kPi},
}};

core::JointArray random_q(std::mt19937& rng, const motion::RobotModel& m) {
  core::JointArray q{};
  for (std::size_t i = 0; i < 6; ++i) {
    q[i] = std::uniform_real_distribution<float>(m.q_min_rad[i], m.q_max_rad[i])(rng);
  }
  return q;
}

void expect_near(const core::Vec3& a, const core::Vec3& b, float tol, const std::string& what) {
  for (std::size_t c = 0; c < 3; ++c) {
    EXPECT_NEAR(a[c], b[c], tol) << what << " coordinate " << c;
  }
}

}  // namespace

TEST(RobotDescription, ShippedIrb120IsExactlyTheCompiledInModel) {
  const robot::Robot& r = robot::active();  // the built-in examples/robots/abb_irb120.urdf
  const motion::RobotModel& m = r.model;
  const motion::RobotModel& k = motion::kRobot;
  EXPECT_EQ(r.d.name, "abb_irb120_3_58");
  EXPECT_EQ(r.d.base, "base_link");
  EXPECT_EQ(r.d.flange, "tool0");
  for (std::size_t j = 0; j < 6; ++j) {
    SCOPED_TRACE(j + 1);
    EXPECT_EQ(m.joints[j].origin.xyz_mm, k.joints[j].origin.xyz_mm);
    EXPECT_EQ(m.joints[j].origin.R, k.joints[j].origin.R);
    EXPECT_EQ(m.joints[j].axis, k.joints[j].axis);
    EXPECT_EQ(m.q_min_rad[j], k.q_min_rad[j]);
    EXPECT_EQ(m.q_max_rad[j], k.q_max_rad[j]);
    EXPECT_EQ(m.qd_max_rad_s[j], k.qd_max_rad_s[j]);
    EXPECT_EQ(m.qdd_max_rad_s2[j], k.qdd_max_rad_s2[j]);
  }
  for (std::size_t l = 0; l < motion::kLinks; ++l) {
    EXPECT_STREQ(m.link_names[l], k.link_names[l]);
  }
  EXPECT_EQ(m.flange.xyz_mm, k.flange.xyz_mm);
  EXPECT_EQ(m.flange.R, k.flange.R);
  EXPECT_EQ(m.tcp_offset_mm, k.tcp_offset_mm);
  EXPECT_EQ(m.reach_mm, k.reach_mm);
}

TEST(RobotDescription, ShippedIrb120MassesAreTheTables) {
  const robot::Robot& r = robot::active();
  double total = 0.0;
  for (const auto& j : r.d.joints) {
    total += j.inertial.mass_kg;
  }
  EXPECT_NEAR(total, 11.931, 1e-9);  // docs/robot.md: the masses add up to 11.93 kg
  EXPECT_NEAR(r.d.joints[5].inertial.com_m[0], 0.072 - 0.00706, 1e-12);  // link 6's, from the wrist centre
}

// The core's collision model reads the description's inertials and efforts: for the shipped
// IRB 120 exactly the compiled-in table (so PFL on the built-in arm is what it was).
TEST(RobotDescription, ShippedIrb120InertialsAreTheCoresTable) {
  const robot::Robot& r = robot::active();
  const core::ArmInertials& k = core::kIrb120Inertials;
  for (std::size_t j = 0; j < 6; ++j) {
    const core::LinkInertial& a = r.inertials.link[j];
    EXPECT_EQ(a.mass_kg, k.link[j].mass_kg) << "link " << (j + 1);
    for (std::size_t c = 0; c < 3; ++c) {
      EXPECT_EQ(a.com_m[c], k.link[j].com_m[c]) << "link " << (j + 1) << " com " << c;
    }
    for (std::size_t c = 0; c < 6; ++c) {
      EXPECT_EQ(a.inertia[c], k.link[j].inertia[c]) << "link " << (j + 1) << " inertia " << c;
    }
    EXPECT_EQ(r.inertials.rated_torque_nm[j], k.rated_torque_nm[j]) << "joint " << (j + 1);
  }
}

// A negative effort is refused naming the joint (it is the drive's rated torque).
TEST(RobotDescription, RefusesANegativeEffort) {
  Arm arm;
  arm.limit[3] = "<limit lower=\"-3\" upper=\"3\" velocity=\"2\" effort=\"-5\"/>";
  expect_refused(arm.text(), "joint 'j4': its effort limit must be >= 0");
}

// The general chain of the URDF reproduces the former DH model: same link origins (the DH
// frames' origins), the same joint axes, the same tool0 and TCP, on random poses.
TEST(RobotDescription, CoreChainEqualsTheFormerDhModel) {
  const core::PreparedArm chain = core::prepare_arm(safestate::controller::Controller::arm_geometry(motion::kRobot));
  const core::PreparedArm dh = core::prepare_arm(core::arm_from_dh(kIrb120Dh));
  std::mt19937 rng(38);
  const core::Vec3 tcp{30.0F, -20.0F, 100.0F};
  for (int i = 0; i < 2000; ++i) {
    const core::JointArray q = random_q(rng, motion::kRobot);
    core::ArmPose a{};
    core::ArmPose b{};
    core::arm_forward(chain, q, tcp, a);
    core::arm_forward(dh, q, tcp, b);
    for (std::size_t k = 0; k < core::kArmFrames; ++k) {
      expect_near(a.origin[k], b.origin[k], 1e-3F, "origin " + std::to_string(k));
      expect_near(a.z[k], b.z[k], 1e-5F, "axis " + std::to_string(k));
    }
    expect_near(a.tcp, b.tcp, 1e-3F, "tcp");
    expect_near(a.tool_z, b.tool_z, 1e-5F, "tool z");
  }
}

// The core and the motion layer, written apart, agree on an arm that exercises every path:
// turned joint frames (rpy), fixed joints between moving ones, a minus axis and a skew axis.
TEST(RobotDescription, CoreAndMotionAgreeOnAGeneralArm) {
  Arm arm;
  arm.rpy[1] = "1.5707963267948966 0 0";
  arm.rpy[2] = "0.3 -0.2 0.1";
  arm.axis[2] = "0 0 -1";
  arm.axis[4] = "0.6 0 0.8";
  arm.rpy[5] = "0 1.5707963267948966 0";
  arm.xyz[3] = "0.1 -0.03 0.05";
  std::string error;
  // A fixed joint between l3 and l4: l3 -> mid (fixed, turned) -> l4 (j4's parent becomes mid).
  std::string text = arm.text();
  const std::string from = "<parent link=\"l3\"/><child link=\"l4\"/>";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "<parent link=\"mid\"/><child link=\"l4\"/>");
  text.insert(text.find("</robot>"), lnk("mid") + joint("l3_mid", "fixed", "l3", "mid", "0.02 0.01 0.03", "0.1 0.2 0.3"));
  const auto r = load(text, error);
  ASSERT_NE(r, nullptr) << error;
  const core::PreparedArm prepared = core::prepare_arm(r->geometry);
  EXPECT_EQ(prepared.axis_kind[2], core::AxisKind::minus_z);
  EXPECT_EQ(prepared.axis_kind[4], core::AxisKind::general);
  EXPECT_TRUE(prepared.frame[3].turned);  // the folded fixed joint's rotation
  std::mt19937 rng(7);
  motion::RobotModel m = r->model;
  m.tcp_offset_mm = {10.0F, 20.0F, 50.0F};
  for (int i = 0; i < 2000; ++i) {
    const core::JointArray q = random_q(rng, m);
    core::ArmPose a{};
    core::arm_forward(prepared, q, m.tcp_offset_mm, a);
    motion::Frames f{};
    motion::forward(m, q, f);
    for (std::size_t k = 0; k < core::kArmFrames; ++k) {
      expect_near(a.origin[k], f.origin[k], 1e-3F, "origin " + std::to_string(k));
      expect_near(a.z[k], f.z[k], 1e-5F, "axis " + std::to_string(k));
    }
    expect_near(a.tcp, f.tcp, 1e-3F, "tcp");
  }
}

// Folding: the fixed joint between l3 and l4 above is the same arm as one joint whose origin
// is the composition (checked at q = 0 by the positions of every joint origin).
TEST(RobotDescription, FixedJointsFoldIntoTheNextMovingJoint) {
  Arm plain;
  Arm split;
  // j4 at "0.1 0 0.05" from l3 == fixed "0.1 0 0" to mid, then j4 at "0 0 0.05" from mid.
  std::string text = split.text();
  const std::string j4 = "<parent link=\"l3\"/><child link=\"l4\"/><origin xyz=\"0.1 0 0.05\"";
  ASSERT_NE(text.find(j4), std::string::npos);
  text.replace(text.find(j4), j4.size(), "<parent link=\"mid\"/><child link=\"l4\"/><origin xyz=\"0 0 0.05\"");
  text.insert(text.find("</robot>"), lnk("mid") + joint("l3_mid", "fixed", "l3", "mid", "0.1 0 0"));
  std::string error;
  const auto a = load(plain.text(), error);
  ASSERT_NE(a, nullptr) << error;
  const auto b = load(text, error);
  ASSERT_NE(b, nullptr) << error;
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(a->model.joints[k].origin.xyz_mm, b->model.joints[k].origin.xyz_mm) << k;
  }
}

TEST(RobotDescription, FixedLinksAddTheirMassToTheMovingLink) {
  Arm arm;
  arm.more = lnk("camera", "<inertial><origin xyz=\"0 0 0\"/><mass value=\"0.5\"/><inertia ixx=\"0\" ixy=\"0\" "
                            "ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/></inertial>") +
             joint("cam", "fixed", "l2", "camera", "0.2 0 0");
  std::string error;
  const auto r = load(arm.text(), error);
  ASSERT_NE(r, nullptr) << error;
  const robot::Inertial& in = r->d.joints[1].inertial;
  EXPECT_DOUBLE_EQ(in.mass_kg, 2.0);
  EXPECT_NEAR(in.com_m[0], (1.5 * 0.01 + 0.5 * 0.2) / 2.0, 1e-12);
  EXPECT_NEAR(in.com_m[2], (1.5 * 0.02) / 2.0, 1e-12);
  // Parallel axis: iyy = 0.02 + 1.5 (dx^2 + dz^2) + 0.5 (dx'^2 + dz'^2) about the joint COM.
  const double cx = in.com_m[0];
  const double cz = in.com_m[2];
  const double iyy = 0.02 + 1.5 * ((0.01 - cx) * (0.01 - cx) + (0.02 - cz) * (0.02 - cz)) +
                     0.5 * ((0.2 - cx) * (0.2 - cx) + cz * cz);
  EXPECT_NEAR(in.inertia[1][1], iyy, 1e-12);
}

TEST(RobotDescription, AGrippersFingerOffTheChainCountsAtItsZero) {
  Arm a;
  a.more = lnk("finger", "<inertial><origin xyz=\"0 0 0\"/><mass value=\"0.25\"/><inertia ixx=\"0\" ixy=\"0\" "
                         "ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/></inertial>") +
           joint("finger_joint", "revolute", "l6", "finger", "0.1 0 0");
  std::string error;
  const auto r = load(a.text(), error);
  ASSERT_NE(r, nullptr) << error;
  EXPECT_DOUBLE_EQ(r->d.joints[5].inertial.mass_kg, 1.75);
  EXPECT_NEAR(r->d.joints[5].inertial.com_m[0], (1.5 * 0.01 + 0.25 * 0.1) / 1.75, 1e-12);
}

TEST(RobotDescription, DefaultsAndChoices) {
  Arm arm;
  std::string error;
  auto r = load(arm.text(), error);
  ASSERT_NE(r, nullptr) << error;
  EXPECT_EQ(r->d.base, "base");    // the root
  EXPECT_EQ(r->d.flange, "tool0");  // there is one
  EXPECT_NEAR(r->model.flange.xyz_mm[2], 80.0F, 1e-4F);
  // --flange l6: the flange is joint 6's own link.
  r = load(arm.text(), error, "", "l6");
  ASSERT_NE(r, nullptr) << error;
  EXPECT_EQ(r->model.flange.xyz_mm, (motion::Vec3f{0.0F, 0.0F, 0.0F}));
  // No tool0, one chain: its tip.
  Arm notool;
  notool.tail = lnk("ee") + joint("ee_fixed", "fixed", "l6", "ee", "0.1 0 0");
  std::string t = notool.text();
  t.replace(t.find(lnk("tool0")), lnk("tool0").size(), "");
  r = load(t, error);
  ASSERT_NE(r, nullptr) << error;
  EXPECT_EQ(r->d.flange, "ee");
  // A base below the root: the chain starts there (the root's world link is not part of it).
  Arm world;
  world.more = lnk("world") + joint("world_fixed", "fixed", "world", "base", "0 0 1");
  r = load(world.text(), error);
  ASSERT_NE(r, nullptr) << error;
  EXPECT_EQ(r->d.base, "world");
  EXPECT_NEAR(r->model.joints[0].origin.xyz_mm[2], 1200.0F, 1e-3F);  // folded: 1 m + 0.2 m
  r = load(world.text(), error, "base");
  ASSERT_NE(r, nullptr) << error;
  EXPECT_NEAR(r->model.joints[0].origin.xyz_mm[2], 200.0F, 1e-3F);
  // A continuous joint: one turn each way until the configuration narrows it.
  Arm cont;
  cont.type[5] = "continuous";
  cont.limit[5] = "<limit velocity=\"3\" effort=\"5\"/>";
  r = load(cont.text(), error);
  ASSERT_NE(r, nullptr) << error;
  EXPECT_TRUE(r->d.joints[5].continuous);
  EXPECT_NEAR(r->model.q_max_rad[5], 6.2831853F, 1e-6F);
  EXPECT_NEAR(r->model.q_min_rad[5], -6.2831853F, 1e-6F);
  EXPECT_FLOAT_EQ(r->model.qd_max_rad_s[5], 3.0F);
}

TEST(RobotDescription, RefusesEachKindOfBrokenDescriptionNamingIt) {
  {
    Arm a;
    a.type[2] = "prismatic";
    expect_refused(a.text(), "joint 'j3' is prismatic");
  }
  {
    Arm a;
    a.extra[4] = "<mimic joint=\"j4\"/>";
    expect_refused(a.text(), "joint 'j5' mimics joint 'j4'");
  }
  {
    Arm a;  // five moving joints: j6 fixed
    a.type[5] = "fixed";
    expect_refused(a.text(), "has 5 revolute or continuous joints");
  }
  {
    Arm a;  // seven: one more revolute joint between l6 and tool0
    a.tail = lnk("l7") + joint("j7", "revolute", "l6", "l7") + joint("flange", "fixed", "l7", "tool0");
    expect_refused(a.text(), "has 7 revolute or continuous joints");
  }
  {
    Arm a;  // revolute without <limit>: urdfdom refuses it and names the joint
    a.limit[1] = " ";
    expect_refused(a.text(), "j2");
  }
  {
    Arm a;  // continuous without a velocity limit
    a.type[1] = "continuous";
    a.limit[1] = " ";
    expect_refused(a.text(), "joint 'j2' (continuous) has no <limit>");
  }
  {
    Arm a;
    a.xyz[3] = "0 nan 0.1";
    expect_refused(a.text(), "j4");
  }
  {
    Arm a;
    a.axis[3] = "1 1 0";
    expect_refused(a.text(), "joint 'j4': its axis (1 1 0) is not a unit vector");
  }
  {
    Arm a;
    a.axis[0] = "0 0 0";
    expect_refused(a.text(), "joint 'j1': its axis");
  }
  {
    Arm a;
    a.limit[2] = "<limit lower=\"1\" upper=\"-1\" velocity=\"2\" effort=\"1\"/>";
    expect_refused(a.text(), "joint 'j3': its range is empty");
  }
  {
    Arm a;
    a.limit[2] = "<limit lower=\"-1\" upper=\"1\" velocity=\"0\" effort=\"1\"/>";
    expect_refused(a.text(), "joint 'j3': its velocity limit must be > 0");
  }
  {
    Arm a;  // no tool0 and two tips: the flange must be named
    a.tail = lnk("ee") + joint("ee1", "fixed", "l6", "ee") + lnk("cam") + joint("ee2", "fixed", "l6", "cam");
    std::string t = a.text();
    t.replace(t.find(lnk("tool0")), lnk("tool0").size(), "");
    expect_refused(t, "link 'l6' branches ('ee', 'cam')");
  }
  {
    Arm a;
    expect_refused(a.text(), "no link 'nowhere' (the flange)", "", "nowhere");
    expect_refused(a.text(), "no link 'nowhere' (the base)", "nowhere");
    expect_refused(a.text(), "link 'l2' (the flange) is not below link 'l4' (the base)", "l4", "l2");
  }
  {
    Arm a;  // NaN in a mass
    a.more = lnk("blob", "<inertial><mass value=\"nan\"/><inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" "
                          "izz=\"0\"/></inertial>") +
             joint("blob_fixed", "fixed", "l3", "blob");
    expect_refused(a.text(), "Could not parse inertial element for Link [blob]");
  }
  expect_refused("<robot name=\"x\"><link name=\"a\"/>", "not a valid URDF");
  std::string error;
  EXPECT_EQ(robot::load_file("/nonexistent/arm.urdf", "", "", error), nullptr);
  EXPECT_NE(error.find("cannot read robot description '/nonexistent/arm.urdf'"), std::string::npos) << error;
  EXPECT_EQ(robot::load_file("/dev/zero", "", "", error), nullptr);  // never read: not a regular file
  EXPECT_NE(error.find("not a readable regular file"), std::string::npos) << error;
}

TEST(RobotDescription, CanonicalParametersChangeWithTheDescription) {
  Arm a;
  Arm b;
  b.xyz[2] = "0 0 0.3001";  // 0.1 mm longer
  std::string error;
  const auto ra = load(a.text(), error);
  const auto rb = load(b.text(), error);
  ASSERT_NE(ra, nullptr);
  ASSERT_NE(rb, nullptr);
  EXPECT_NE(robot::canonical_parameters(*ra), robot::canonical_parameters(*rb));
  const auto ra2 = load(a.text() + "\n<!-- a comment changes nothing used -->", error);
  ASSERT_NE(ra2, nullptr);
  EXPECT_EQ(robot::canonical_parameters(*ra), robot::canonical_parameters(*ra2));
}

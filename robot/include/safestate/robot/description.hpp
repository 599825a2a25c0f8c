// The robot description (issue 38): the arm SafeState supervises, read from its URDF at
// start-up, outside the core. Parsed with urdfdom (Debian's liburdfdom-dev, BSD-3-Clause),
// then checked and reduced to what the core, the motion layer and the simulated arm use:
// the chain of exactly six revolute (or continuous) joints from a base link to a flange
// link, the fixed joints between them folded into the moving joints' frames, joint limits
// and velocity limits, and each moving link's mass and inertia (its fixed children folded
// in). Anything else is refused with an error naming the joint or link; nothing starts.
//
// Frames: joint k's frame is the URDF joint's frame (its child link's frame), given in
// joint k-1's frame (the base link's for k = 1) at joint k-1's zero. The flange link's frame
// is given in joint 6's frame. Units: m and rad here (double, as in the file); the models
// handed to the core and the motion layer are in mm and rad (float).
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "safestate/core/arm.hpp"
#include "safestate/core/dynamics.hpp"
#include "safestate/motion/robot.hpp"

namespace safestate::robot {

inline constexpr std::size_t kJoints = 6;

using Vec3d = std::array<double, 3>;
using Mat3d = std::array<Vec3d, 3>;  // row-major; columns are the child frame's axes

struct FrameD {
  Vec3d xyz_m{};
  Mat3d R{{{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}}};
};

// A moving link with the links fixed to it: mass, centre of mass and the inertia about the
// centre of mass, in joint k's frame.
struct Inertial {
  double mass_kg = 0.0;
  Vec3d com_m{};
  Mat3d inertia{};  // kg m^2
};

struct Joint {
  std::string name;
  std::string child;        // the link this joint turns
  FrameD origin;            // in the previous joint's frame, fixed joints folded
  Vec3d axis{0.0, 0.0, 1.0};  // unit, in this joint's frame
  bool continuous = false;
  double lower_rad = 0.0;   // continuous: -2 pi (one turn each way; the configuration narrows it)
  double upper_rad = 0.0;
  double velocity_rad_s = 0.0;
  double effort_nm = 0.0;   // 0 when the URDF gives none; the drive's rated torque (0x6077's unit)
  Inertial inertial;        // the moving link and everything fixed to it
};

struct Description {
  std::string name;    // the URDF's robot name
  std::string source;  // the file, or "built-in"
  std::string base;    // base link
  std::string flange;  // flange link
  std::array<Joint, kJoints> joints;
  FrameD flange_frame;  // the flange in joint 6's frame
  std::string urdf;     // the file's text (served to the HMI at /api/robot)
};

// What the rest of the program uses: the description and the models made from it. Not
// copyable or movable: model.name and model.link_names point into `d`.
struct Robot {
  Description d;
  motion::RobotModel model{};
  core::ArmGeometry geometry{};
  core::ArmInertials inertials{};  // the core's collision model: links' inertials, rated torques
  std::array<std::string, motion::kLinks> link_names;

  Robot() = default;
  Robot(const Robot&) = delete;
  Robot& operator=(const Robot&) = delete;
  Robot(Robot&&) = delete;
  Robot& operator=(Robot&&) = delete;
};

// Loads and checks a description. Empty `base` is the URDF's root link; empty `flange` is
// `tool0` when the description has one below the base, else the tip of the only chain. On
// any error: nullptr and `error` says what is wrong (naming the joint or link).
std::unique_ptr<Robot> load_file(const std::string& path, const std::string& base, const std::string& flange,
                                 std::string& error);
std::unique_ptr<Robot> load_text(const std::string& urdf, const std::string& source, const std::string& base,
                                 const std::string& flange, std::string& error);

// The built-in default: examples/robots/abb_irb120.urdf, compiled in.
const char* builtin_urdf() noexcept;

// The robot the process runs: the built-in IRB 120 until set_active() is called, once, at
// start-up, before anything that reads it is built (the cell, the gateway's views).
const Robot& active();
std::shared_ptr<const Robot> active_shared();
void set_active(std::shared_ptr<const Robot> r);

// True when `r` uses exactly the built-in IRB 120's parameters (canonical_parameters equal).
bool is_builtin(const Robot& r);

// The parameters actually used (the models' numbers, in their units: mm, rad, rad/s, kg,
// m, kg m^2), as a JSON text in a canonical order: the robot's part of the safety
// configuration's checksum (docs/robot.md "Checksum").
std::string canonical_parameters(const Robot& r);

// Every link at or below the base at joint positions q (rad, the six chain joints; a moving
// joint off the chain at zero), in the base frame (m), in double: `safestate robot fk` prints
// the links the core does not model (fixed ones) from this. Built once (parses the URDF).
struct LinkPose {
  std::string name;
  FrameD pose;
};
class LinkTree {
 public:
  explicit LinkTree(const Robot& r);
  void poses(const std::array<double, kJoints>& q, std::vector<LinkPose>& out) const;

 private:
  struct Node {
    std::string name;
    int parent;     // index, -1 for the base
    FrameD origin;  // in the parent's frame
    int joint;      // the chain joint (0..5) between parent and this link, or -1
    Vec3d axis;
  };
  std::vector<Node> nodes_;
};

// Start-up from the command line: `--robot FILE --base LINK --flange LINK` (all empty: keep
// the active robot). False and `error` on a refused description.
bool select(const std::string& path, const std::string& base, const std::string& flange, std::string& error);

}  // namespace safestate::robot

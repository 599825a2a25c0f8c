#include "safestate/robot/description.hpp"
#include "safestate/robot/meshes.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <utility>

#include <console_bridge/console.h>
#include <nlohmann/json.hpp>
#include <urdf_parser/urdf_parser.h>

#include "safestate/controller/controller.hpp"

namespace safestate::robot {
namespace {

constexpr double kTwoPi = 6.283185307179586;
constexpr std::uintmax_t kMaxUrdfBytes = 16U * 1024U * 1024U;
constexpr double kUnitTolerance = 1.0e-6;  // |axis| within this of 1
constexpr float kRampTime_s = motion::kAssumedRampTime_s;

// urdfdom reports its reasons through console_bridge: gather them for the error message.
class Collect final : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char* /*filename*/, int /*line*/) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR) {
      if (!text_.empty()) {
        text_ += "; ";
      }
      text_ += text;
    }
  }
  [[nodiscard]] const std::string& text() const { return text_; }

 private:
  std::string text_;
};

Mat3d mul(const Mat3d& a, const Mat3d& b) {
  Mat3d c{};
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t k = 0; k < 3; ++k) {
      c[r][k] = a[r][0] * b[0][k] + a[r][1] * b[1][k] + a[r][2] * b[2][k];
    }
  }
  return c;
}

Vec3d mul(const Mat3d& a, const Vec3d& v) {
  return {a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2], a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
          a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2]};
}

Mat3d transpose(const Mat3d& a) {
  Mat3d t{};
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) {
      t[r][c] = a[c][r];
    }
  }
  return t;
}

// a * b: b given in a's frame.
FrameD compose(const FrameD& a, const FrameD& b) {
  FrameD f;
  const Vec3d p = mul(a.R, b.xyz_m);
  f.xyz_m = {a.xyz_m[0] + p[0], a.xyz_m[1] + p[1], a.xyz_m[2] + p[2]};
  f.R = mul(a.R, b.R);
  return f;
}

bool finite(double v) { return std::isfinite(v); }
bool finite(const urdf::Vector3& v) { return finite(v.x) && finite(v.y) && finite(v.z); }

// A URDF pose (xyz, rpy as urdfdom's quaternion) as a frame; false if a number is not finite.
bool frame_of(const urdf::Pose& p, FrameD& f) {
  const urdf::Rotation& q = p.rotation;
  if (!finite(p.position) || !finite(q.x) || !finite(q.y) || !finite(q.z) || !finite(q.w)) {
    return false;
  }
  f.xyz_m = {p.position.x, p.position.y, p.position.z};
  const double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  if (!(n > 0.0)) {
    return false;
  }
  const double x = q.x / n;
  const double y = q.y / n;
  const double z = q.z / n;
  const double w = q.w / n;
  f.R = {{{1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)},
          {2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)},
          {2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)}}};
  return true;
}

const char* type_name(int type) {
  switch (type) {
    case urdf::Joint::REVOLUTE:
      return "revolute";
    case urdf::Joint::CONTINUOUS:
      return "continuous";
    case urdf::Joint::PRISMATIC:
      return "prismatic";
    case urdf::Joint::FLOATING:
      return "floating";
    case urdf::Joint::PLANAR:
      return "planar";
    case urdf::Joint::FIXED:
      return "fixed";
    default:
      return "unknown";
  }
}

bool moving(int type) { return type == urdf::Joint::REVOLUTE || type == urdf::Joint::CONTINUOUS; }

// Adds link `l`'s inertial, the link placed at `at` in joint k's frame, to `acc`
// (mass-weighted centre of mass, inertia by the parallel-axis theorem in finish()).
struct Part {
  double m;
  Vec3d c;
  Mat3d I;  // about its own centre of mass, in joint k's axes
};

bool add_inertial(const urdf::Link& l, const FrameD& at, std::vector<Part>& parts, std::string& error) {
  if (!l.inertial) {
    return true;
  }
  const urdf::Inertial& in = *l.inertial;
  FrameD o;
  const std::array<double, 7> nums{in.mass, in.ixx, in.ixy, in.ixz, in.iyy, in.iyz, in.izz};
  for (const double v : nums) {
    if (!finite(v)) {
      error = "link '" + l.name + "': its inertial holds a number that is not finite";
      return false;
    }
  }
  if (!frame_of(in.origin, o)) {
    error = "link '" + l.name + "': its inertial origin holds a number that is not finite";
    return false;
  }
  if (in.mass < 0.0) {
    error = "link '" + l.name + "': negative mass (" + std::to_string(in.mass) + " kg)";
    return false;
  }
  const FrameD f = compose(at, o);
  const Mat3d I{{{in.ixx, in.ixy, in.ixz}, {in.ixy, in.iyy, in.iyz}, {in.ixz, in.iyz, in.izz}}};
  parts.push_back(Part{in.mass, f.xyz_m, mul(mul(f.R, I), transpose(f.R))});
  return true;
}

Inertial finish(const std::vector<Part>& parts) {
  Inertial r;
  for (const Part& p : parts) {
    r.mass_kg += p.m;
  }
  if (!(r.mass_kg > 0.0)) {
    return r;
  }
  for (const Part& p : parts) {
    for (std::size_t i = 0; i < 3; ++i) {
      r.com_m[i] += p.m * p.c[i] / r.mass_kg;
    }
  }
  for (const Part& p : parts) {
    const Vec3d d{p.c[0] - r.com_m[0], p.c[1] - r.com_m[1], p.c[2] - r.com_m[2]};
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    for (std::size_t i = 0; i < 3; ++i) {
      for (std::size_t j = 0; j < 3; ++j) {
        r.inertia[i][j] += p.I[i][j] + p.m * (((i == j) ? dd : 0.0) - d[i] * d[j]);
      }
    }
  }
  return r;
}

// Every link hanging off `l` (not through the chain's next joint), placed in the frame `at`
// is given in: their inertials into `parts`.
bool gather(const urdf::ModelInterface& m, const urdf::Link& l, const FrameD& at, const std::string& next_on_chain,
            std::vector<Part>& parts, std::string& error) {
  if (!add_inertial(l, at, parts, error)) {
    return false;
  }
  for (const auto& j : l.child_joints) {
    if (j->name == next_on_chain) {
      continue;
    }
    // A moving joint off the chain (a gripper's finger) is taken at its zero: its links' mass
    // counts where they are then (docs/robot.md "What is checked").
    FrameD o;
    if (!frame_of(j->parent_to_joint_origin_transform, o)) {
      error = "joint '" + j->name + "': its origin holds a number that is not finite";
      return false;
    }
    const urdf::LinkConstSharedPtr child = m.getLink(j->child_link_name);
    if (!child) {
      continue;
    }
    if (!gather(m, *child, compose(at, o), "", parts, error)) {
      return false;
    }
  }
  return true;
}

std::string default_flange(const urdf::Link& base, std::string& error) {
  const urdf::Link* l = &base;
  while (!l->child_links.empty()) {
    if (l->child_links.size() > 1U) {
      std::string names;
      for (const auto& c : l->child_links) {
        names += (names.empty() ? "'" : ", '") + c->name + "'";
      }
      error = "link '" + l->name + "' branches (" + names +
              "): the description has no tool0, so name the flange link (--flange LINK, or the robot key's flange)";
      return {};
    }
    l = l->child_links.front().get();
  }
  return l->name;
}

bool below(const urdf::Link& link, const std::string& base) {
  for (urdf::LinkConstSharedPtr p = link.getParent(); p; p = p->getParent()) {
    if (p->name == base) {
      return true;
    }
  }
  return false;
}

float f(double v) { return static_cast<float>(v); }

// A rotation entry within 1e-12 of 0 or +-1 is that number: the rounding of double's sin and
// cos at multiples of 90 deg (cos(pi/2) = 6e-17), far below float's resolution, would
// otherwise keep a quarter turn off the core's exact paths.
float entry(double v) {
  constexpr double kSnap = 1.0e-12;
  if (std::fabs(v) < kSnap) {
    return 0.0F;
  }
  if (std::fabs(std::fabs(v) - 1.0) < kSnap) {
    return (v > 0.0) ? 1.0F : -1.0F;
  }
  return f(v);
}

motion::FixedFrame to_model(const FrameD& d) {
  motion::FixedFrame m{};
  m.xyz_mm = {f(d.xyz_m[0] * 1000.0), f(d.xyz_m[1] * 1000.0), f(d.xyz_m[2] * 1000.0)};
  for (std::size_t r = 0; r < 3; ++r) {
    m.R[r] = {entry(d.R[r][0]), entry(d.R[r][1]), entry(d.R[r][2])};
  }
  return m;
}

float length(const motion::Vec3f& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

void make_models(Robot& r) {
  motion::RobotModel& m = r.model;
  m.name = r.d.name.c_str();
  r.link_names[0] = r.d.base;
  for (std::size_t k = 0; k < kJoints; ++k) {
    const Joint& j = r.d.joints[k];
    r.link_names[k + 1U] = j.child;
    m.joints[k].origin = to_model(j.origin);
    m.joints[k].axis = {entry(j.axis[0]), entry(j.axis[1]), entry(j.axis[2])};
    m.q_min_rad[k] = f(j.lower_rad);
    m.q_max_rad[k] = f(j.upper_rad);
    m.qd_max_rad_s[k] = f(j.velocity_rad_s);
    m.qdd_max_rad_s2[k] = m.qd_max_rad_s[k] / kRampTime_s;  // [ASM], docs/robot.md
  }
  for (std::size_t k = 0; k < motion::kLinks; ++k) {
    m.link_names[k] = r.link_names[k].c_str();
  }
  m.flange = to_model(r.d.flange_frame);
  m.tcp_offset_mm = {0.0F, 0.0F, 0.0F};
  float reach = length(m.flange.xyz_mm);
  for (std::size_t k = 2; k < kJoints; ++k) {
    reach += length(m.joints[k].origin.xyz_mm);
  }
  m.reach_mm = reach;
  r.geometry = controller::Controller::arm_geometry(m);
  // The core's collision model: each moving link's inertial in its joint's frame, the
  // effort as the drive's rated torque (docs/robot.md "Dynamics").
  for (std::size_t k = 0; k < kJoints; ++k) {
    const Inertial& in = r.d.joints[k].inertial;
    core::LinkInertial& l = r.inertials.link[k];
    l.mass_kg = f(in.mass_kg);
    l.com_m = {f(in.com_m[0]), f(in.com_m[1]), f(in.com_m[2])};
    l.inertia = {f(in.inertia[0][0]), f(in.inertia[0][1]), f(in.inertia[0][2]),
                 f(in.inertia[1][1]), f(in.inertia[1][2]), f(in.inertia[2][2])};
    r.inertials.rated_torque_nm[k] = f(r.d.joints[k].effort_nm);
  }
}

std::mutex g_parse_mutex;  // console_bridge's handler is process-wide
std::shared_ptr<const Robot> g_active;
std::mutex g_active_mutex;

}  // namespace

std::unique_ptr<Robot> load_file(const std::string& path, const std::string& base, const std::string& flange,
                                 std::string& error) {
  // A regular file of sane size only (not a FIFO, a device, a folder; a real arm's URDF
  // without meshes is tens of kilobytes).
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::is_regular_file(st)) {
    error = "cannot read robot description '" + path + "': not a readable regular file";
    return nullptr;
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec || size > kMaxUrdfBytes) {
    error = "robot description '" + path + "' is larger than " + std::to_string(kMaxUrdfBytes) + " bytes: refused";
    return nullptr;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot read robot description '" + path + "'";
    return nullptr;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  auto r = load_text(ss.str(), path, base, flange, error);
  if (!r) {
    error = path + ": " + error;
  }
  return r;
}

std::unique_ptr<Robot> load_text(const std::string& urdf, const std::string& source, const std::string& base,
                                 const std::string& flange, std::string& error) {
  urdf::ModelInterfaceSharedPtr m;
  {
    const std::lock_guard<std::mutex> lock(g_parse_mutex);
    Collect collect;
    console_bridge::useOutputHandler(&collect);
    try {
      m = urdf::parseURDF(urdf);
    } catch (const std::exception& e) {
      m.reset();
      error = std::string("not a valid URDF: ") + e.what();
    }
    console_bridge::restorePreviousOutputHandler();
    // urdfdom reports some faults and carries on (an <inertial> it cannot read is dropped,
    // the link left massless): any error it reports refuses the description.
    if (m && !collect.text().empty()) {
      m.reset();
    }
    if (!m) {
      if (error.empty()) {
        error = "not a valid URDF" + (collect.text().empty() ? std::string() : ": " + collect.text());
      }
      return nullptr;
    }
  }
  if (!m->getRoot()) {
    error = "the description has no root link";
    return nullptr;
  }
  auto r = std::make_unique<Robot>();
  Description& d = r->d;
  d.name = m->getName();
  d.source = source;
  d.urdf = urdf;
  d.base = base.empty() ? m->getRoot()->name : base;
  const urdf::LinkConstSharedPtr base_link = m->getLink(d.base);
  if (!base_link) {
    error = "no link '" + d.base + "' (the base)";
    return nullptr;
  }
  if (flange.empty()) {
    const urdf::LinkConstSharedPtr tool0 = m->getLink("tool0");
    if (tool0 && below(*tool0, d.base)) {
      d.flange = "tool0";
    } else {
      d.flange = default_flange(*base_link, error);
      if (d.flange.empty()) {
        return nullptr;
      }
    }
  } else {
    d.flange = flange;
  }
  const urdf::LinkConstSharedPtr flange_link = m->getLink(d.flange);
  if (!flange_link) {
    error = "no link '" + d.flange + "' (the flange)";
    return nullptr;
  }
  if (d.flange == d.base || !below(*flange_link, d.base)) {
    error = "link '" + d.flange + "' (the flange) is not below link '" + d.base + "' (the base)";
    return nullptr;
  }
  // The chain: the joints from the base down to the flange.
  std::vector<urdf::JointConstSharedPtr> path;
  for (urdf::LinkConstSharedPtr l = flange_link; l && l->name != d.base; l = l->getParent()) {
    path.insert(path.begin(), l->parent_joint);
  }
  std::vector<std::string> movers;
  for (const auto& j : path) {
    if (moving(j->type)) {
      movers.push_back(j->name);
    } else if (j->type != urdf::Joint::FIXED) {
      error = "joint '" + j->name + "' is " + type_name(j->type) +
              ": the chain from '" + d.base + "' to '" + d.flange + "' may hold only revolute, continuous and fixed joints";
      return nullptr;
    }
  }
  if (movers.size() != kJoints) {
    std::string names;
    for (const auto& n : movers) {
      names += (names.empty() ? "" : ", ") + n;
    }
    error = "the chain from '" + d.base + "' to '" + d.flange + "' has " + std::to_string(movers.size()) +
            " revolute or continuous joints (" + (names.empty() ? std::string("none") : names) + "): exactly 6 needed";
    return nullptr;
  }
  // Fold the fixed joints into the moving joints' origins (and the flange's frame).
  FrameD acc;  // the current link's frame in the last moving joint's frame (the base's first)
  std::size_t k = 0;
  for (const auto& j : path) {
    FrameD o;
    if (!frame_of(j->parent_to_joint_origin_transform, o)) {
      error = "joint '" + j->name + "': its origin holds a number that is not finite";
      return nullptr;
    }
    if (j->type == urdf::Joint::FIXED) {
      acc = compose(acc, o);
      continue;
    }
    Joint& out = d.joints[k];
    out.name = j->name;
    out.child = j->child_link_name;
    out.origin = compose(acc, o);
    acc = FrameD{};
    if (j->mimic) {
      error = "joint '" + j->name + "' mimics joint '" + j->mimic->joint_name +
              "': a coupled joint cannot be supervised as one of the six";
      return nullptr;
    }
    if (!finite(j->axis)) {
      error = "joint '" + j->name + "': its axis holds a number that is not finite";
      return nullptr;
    }
    const double n = std::sqrt(j->axis.x * j->axis.x + j->axis.y * j->axis.y + j->axis.z * j->axis.z);
    if (!(std::fabs(n - 1.0) <= kUnitTolerance)) {
      std::ostringstream s;
      s.precision(9);
      s << "joint '" << j->name << "': its axis (" << j->axis.x << " " << j->axis.y << " " << j->axis.z
        << ") is not a unit vector (length " << n << ")";
      error = s.str();
      return nullptr;
    }
    out.axis = {j->axis.x / n, j->axis.y / n, j->axis.z / n};
    out.continuous = j->type == urdf::Joint::CONTINUOUS;
    const urdf::JointLimitsSharedPtr& lim = j->limits;
    if (!lim) {
      error = "joint '" + j->name + "' (" + type_name(j->type) + ") has no <limit>: its velocity limit" +
              (out.continuous ? "" : " and range") + " are needed";
      return nullptr;
    }
    if (!finite(lim->lower) || !finite(lim->upper) || !finite(lim->velocity) || !finite(lim->effort)) {
      error = "joint '" + j->name + "': its <limit> holds a number that is not finite";
      return nullptr;
    }
    if (out.continuous) {
      out.lower_rad = -kTwoPi;
      out.upper_rad = kTwoPi;
    } else {
      out.lower_rad = lim->lower;
      out.upper_rad = lim->upper;
      if (!(out.lower_rad < out.upper_rad)) {
        error = "joint '" + j->name + "': its range is empty (lower " + std::to_string(lim->lower) + " >= upper " +
                std::to_string(lim->upper) + " rad)";
        return nullptr;
      }
    }
    if (!(lim->velocity > 0.0)) {
      error = "joint '" + j->name + "': its velocity limit must be > 0 (found " + std::to_string(lim->velocity) + ")";
      return nullptr;
    }
    out.velocity_rad_s = lim->velocity;
    if (lim->effort < 0.0) {
      error = "joint '" + j->name + "': its effort limit must be >= 0 (found " + std::to_string(lim->effort) + ")";
      return nullptr;
    }
    out.effort_nm = lim->effort;
    ++k;
  }
  d.flange_frame = acc;
  // Each moving link's inertial, with everything fixed to it (the flange and a tool too).
  // The base and what is fixed to it do not move: not needed. A moving joint off the chain
  // anywhere below the base is refused.
  {
    std::vector<Part> ignored;
    // Walk the base's fixed part only to refuse moving branches; its inertia is not used.
    if (!gather(*m, *base_link, FrameD{}, path.front()->name, ignored, error)) {
      return nullptr;
    }
    // The fixed links on the path between the base and joint 1 may carry branches too.
    std::size_t i = 0;
    for (; i < path.size() && !moving(path[i]->type); ++i) {
      const urdf::LinkConstSharedPtr l = m->getLink(path[i]->child_link_name);
      const std::string nx = (i + 1U < path.size()) ? path[i + 1U]->name : "";
      if (!gather(*m, *l, FrameD{}, nx, ignored, error)) {
        return nullptr;
      }
    }
    std::size_t jk = 0;
    std::vector<Part> parts;
    FrameD at;  // the current link in joint jk's frame
    for (; i < path.size(); ++i) {
      const auto& j = path[i];
      if (moving(j->type)) {
        if (jk > 0U) {
          d.joints[jk - 1U].inertial = finish(parts);
        }
        parts.clear();
        at = FrameD{};
        ++jk;
      } else {
        FrameD o;
        (void)frame_of(j->parent_to_joint_origin_transform, o);  // checked above
        at = compose(at, o);
      }
      const urdf::LinkConstSharedPtr l = m->getLink(j->child_link_name);
      const std::string nx = (i + 1U < path.size()) ? path[i + 1U]->name : "";
      if (!gather(*m, *l, at, nx, parts, error)) {
        return nullptr;
      }
    }
    d.joints[kJoints - 1U].inertial = finish(parts);
  }
  make_models(*r);
  return r;
}

std::shared_ptr<const Robot> active_shared() {
  const std::lock_guard<std::mutex> lock(g_active_mutex);
  if (!g_active) {
    std::string error;
    g_active = load_text(builtin_urdf(), "built-in", "", "", error);
    if (!g_active) {
      // The shipped description is checked by its unit test; reaching this is a build fault.
      std::fprintf(stderr, "safestate: the built-in robot description is refused: %s\n", error.c_str());
      std::abort();
    }
  }
  return g_active;
}

// The active robot lives until the process ends (set_active() at start-up only), so the
// reference stays valid.
const Robot& active() { return *active_shared(); }

bool is_builtin(const Robot& r) {
  static const std::string builtin = [] {
    std::string error;
    const auto b = load_text(builtin_urdf(), "built-in", "", "", error);
    return b ? canonical_parameters(*b) : std::string();
  }();
  return canonical_parameters(r) == builtin;
}

void set_active(std::shared_ptr<const Robot> r) {
  const std::lock_guard<std::mutex> lock(g_active_mutex);
  // Whatever was built on the previous robot keeps its references valid until the end.
  static std::vector<std::shared_ptr<const Robot>> retired;
  if (g_active) {
    retired.push_back(g_active);
  }
  g_active = std::move(r);
}

bool select(const std::string& path, const std::string& base, const std::string& flange, std::string& error) {
  if (path.empty() && base.empty() && flange.empty()) {
    return true;
  }
  std::unique_ptr<Robot> r = path.empty() ? load_text(builtin_urdf(), "built-in", base, flange, error)
                                          : load_file(path, base, flange, error);
  if (!r) {
    return false;
  }
  set_active(std::move(r));
  return true;
}

LinkTree::LinkTree(const Robot& r) {
  urdf::ModelInterfaceSharedPtr m;
  {
    const std::lock_guard<std::mutex> lock(g_parse_mutex);
    Collect collect;
    console_bridge::useOutputHandler(&collect);
    m = urdf::parseURDF(r.d.urdf);
    console_bridge::restorePreviousOutputHandler();
  }
  const urdf::LinkConstSharedPtr base = m ? m->getLink(r.d.base) : nullptr;
  if (!base) {
    return;
  }
  // Depth first from the base: a parent is always listed before its children.
  struct Item {
    urdf::LinkConstSharedPtr link;
    int parent;
    FrameD origin;
    int joint;
  };
  std::vector<Item> stack{{base, -1, FrameD{}, -1}};
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    const int self = static_cast<int>(nodes_.size());
    nodes_.push_back(Node{it.link->name, it.parent, it.origin, it.joint, {}});
    for (const auto& j : it.link->child_joints) {
      FrameD o;
      if (!frame_of(j->parent_to_joint_origin_transform, o)) {
        continue;
      }
      int joint = -1;
      for (std::size_t k = 0; k < kJoints; ++k) {
        if (r.d.joints[k].name == j->name) {
          joint = static_cast<int>(k);
        }
      }
      const urdf::LinkConstSharedPtr child = m->getLink(j->child_link_name);
      if (child) {
        stack.push_back(Item{child, self, o, joint});
      }
    }
  }
  // The axis belongs to the child's joint: stored with the child (fixed up here).
  for (Node& n : nodes_) {
    if (n.joint >= 0) {
      n.axis = r.d.joints[static_cast<std::size_t>(n.joint)].axis;
    }
  }
}

void LinkTree::poses(const std::array<double, kJoints>& q, std::vector<LinkPose>& out) const {
  out.resize(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const Node& n = nodes_[i];
    out[i].name = n.name;
    if (n.parent < 0) {
      out[i].pose = FrameD{};
      continue;
    }
    FrameD f = compose(out[static_cast<std::size_t>(n.parent)].pose, n.origin);
    if (n.joint >= 0) {
      const Vec3d& u = n.axis;
      const double a = q[static_cast<std::size_t>(n.joint)];
      const double c = std::cos(a);
      const double s = std::sin(a);
      const double v = 1.0 - c;
      FrameD turn;
      turn.R = {{{c + u[0] * u[0] * v, u[0] * u[1] * v - u[2] * s, u[0] * u[2] * v + u[1] * s},
                 {u[1] * u[0] * v + u[2] * s, c + u[1] * u[1] * v, u[1] * u[2] * v - u[0] * s},
                 {u[2] * u[0] * v - u[1] * s, u[2] * u[1] * v + u[0] * s, c + u[2] * u[2] * v}}};
      f = compose(f, turn);
    }
    out[i].pose = f;
  }
}

std::string canonical_parameters(const Robot& r) {
  using nlohmann::json;
  const auto v3 = [](const std::array<float, 3>& v) {
    return json::array({static_cast<double>(v[0]), static_cast<double>(v[1]), static_cast<double>(v[2])});
  };
  const auto m3 = [&](const motion::Mat3f& m) { return json::array({v3(m[0]), v3(m[1]), v3(m[2])}); };
  const auto d3 = [](const Vec3d& v) { return json::array({v[0], v[1], v[2]}); };
  const motion::RobotModel& m = r.model;
  json j;
  j["name"] = r.d.name;
  j["base"] = r.d.base;
  j["flange"] = r.d.flange;
  json joints = json::array();
  for (std::size_t k = 0; k < kJoints; ++k) {
    const Joint& dj = r.d.joints[k];
    const Inertial& in = dj.inertial;
    json o;
    o["name"] = dj.name;
    o["link"] = dj.child;
    o["origin_mm"] = v3(m.joints[k].origin.xyz_mm);
    o["rotation"] = m3(m.joints[k].origin.R);
    o["axis"] = v3(m.joints[k].axis);
    o["min_rad"] = static_cast<double>(m.q_min_rad[k]);
    o["max_rad"] = static_cast<double>(m.q_max_rad[k]);
    o["max_speed_rad_s"] = static_cast<double>(m.qd_max_rad_s[k]);
    o["max_accel_rad_s2"] = static_cast<double>(m.qdd_max_rad_s2[k]);
    o["effort_nm"] = dj.effort_nm;
    o["mass_kg"] = in.mass_kg;
    o["com_m"] = d3(in.com_m);
    o["inertia_kg_m2"] = json::array({in.inertia[0][0], in.inertia[0][1], in.inertia[0][2], in.inertia[1][1],
                                      in.inertia[1][2], in.inertia[2][2]});
    joints.push_back(std::move(o));
  }
  j["joints"] = std::move(joints);
  j["flange_origin_mm"] = v3(m.flange.xyz_mm);
  j["flange_rotation"] = m3(m.flange.R);
  return j.dump();
}

}  // namespace safestate::robot

namespace safestate::robot {

std::vector<std::string> visual_mesh_uris(const Robot& r) {
  std::vector<std::string> out;
  urdf::ModelInterfaceSharedPtr m;
  {
    const std::lock_guard<std::mutex> lock(g_parse_mutex);
    Collect collect;  // the description parsed once already; quiet here
    console_bridge::useOutputHandler(&collect);
    try {
      m = urdf::parseURDF(r.d.urdf);
    } catch (const std::exception&) {
      m.reset();
    }
    console_bridge::restorePreviousOutputHandler();
  }
  if (!m) return out;
  std::vector<urdf::LinkSharedPtr> links;
  m->getLinks(links);
  // urdfdom keeps links in a map (by name): the order is the names', which is stable.
  for (const urdf::LinkSharedPtr& l : links) {
    for (const urdf::VisualSharedPtr& v : l->visual_array) {
      if (!v || !v->geometry || v->geometry->type != urdf::Geometry::MESH) continue;
      const std::string& f = static_cast<const urdf::Mesh&>(*v->geometry).filename;
      if (std::find(out.begin(), out.end(), f) == out.end()) out.push_back(f);
    }
  }
  return out;
}

}  // namespace safestate::robot

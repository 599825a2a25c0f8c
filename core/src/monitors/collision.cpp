// SPEC §11 collision detection: the core's own model of the arm (core/collision.hpp). A
// recursive Newton-Euler pass in the base frame: outward the links' angular velocities and
// accelerations and the joints' linear accelerations (gravity as an upward acceleration of
// the base), inward the forces and moments each joint must carry; the joint torque is the
// moment about the joint's axis. Six links, one optional point mass (the payload at the TCP).
// The arm is the one its description gives (prepare_dynamics, at start-up).
#include <cmath>

#include "safestate/core/collision.hpp"
#include "safestate/core/dynamics.hpp"
#include "safestate/core/monitor.hpp"

namespace safestate::core {

namespace {

using Mat3 = std::array<Vec3, 3>;  // columns: the link frame's x, y, z in the base frame

Vec3 add(const Vec3& a, const Vec3& b) noexcept { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 sub(const Vec3& a, const Vec3& b) noexcept { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 scale(const Vec3& a, float k) noexcept { return {a[0] * k, a[1] * k, a[2] * k}; }
float dot(const Vec3& a, const Vec3& b) noexcept { return (a[0] * b[0]) + (a[1] * b[1]) + (a[2] * b[2]); }
Vec3 cross(const Vec3& a, const Vec3& b) noexcept {
  return {(a[1] * b[2]) - (a[2] * b[1]), (a[2] * b[0]) - (a[0] * b[2]), (a[0] * b[1]) - (a[1] * b[0])};
}
// R v: a vector given in the link frame, in the base frame.
Vec3 to_base(const Mat3& r, const Vec3& v) noexcept {
  return add(add(scale(r[0], v[0]), scale(r[1], v[1])), scale(r[2], v[2]));
}
// R^T v: a base-frame vector in the link frame.
Vec3 to_link(const Mat3& r, const Vec3& v) noexcept { return {dot(r[0], v), dot(r[1], v), dot(r[2], v)}; }
// I v for the symmetric inertia ixx ixy ixz iyy iyz izz.
Vec3 inertia_times(const std::array<float, 6>& i, const Vec3& v) noexcept {
  return {(i[0] * v[0]) + (i[1] * v[1]) + (i[2] * v[2]), (i[1] * v[0]) + (i[3] * v[1]) + (i[4] * v[2]),
          (i[2] * v[0]) + (i[4] * v[1]) + (i[5] * v[2])};
}
// R Rot(axis, q) for an axis along +-x, +-y or +-z of the frame: the two columns other than
// the axis turn (cyclic order x -> y -> z); a minus axis turns by -q (the caller passes -s).
void turn(Mat3& r, std::size_t a, float s, float c) noexcept {
  const std::size_t u = (a + 1U) % 3U;
  const std::size_t v = (a + 2U) % 3U;
  const Vec3 cu = r[u];
  const Vec3 cv = r[v];
  r[u] = add(scale(cu, c), scale(cv, s));
  r[v] = sub(scale(cv, c), scale(cu, s));
}
// R Rot(u, q) for any unit axis u (its own frame; z = R u in the base frame), Rodrigues:
// column i becomes c r_i + s (z x r_i) + (1 - c) u_i z.
void turn_general(Mat3& r, const Vec3& u, const Vec3& z, float s, float c) noexcept {
  for (std::size_t i = 0; i < 3U; ++i) {
    r[i] = add(add(scale(r[i], c), scale(cross(z, r[i]), s)), scale(z, (1.0F - c) * u[i]));
  }
}
// R F: the frame turned by a fixed rotation (row-major; column c is the new axis c).
Mat3 turned(const Mat3& r, const Rotation3& f) noexcept {
  Mat3 out{};
  for (std::size_t c = 0; c < 3U; ++c) {
    out[c] = to_base(r, {f[0][c], f[1][c], f[2][c]});
  }
  return out;
}
// Frame R turned by q about joint j's axis; returns the axis in the base frame.
Vec3 turn_joint(Mat3& r, const DynamicsJoint& j, float q) noexcept {
  float s = 0.0F;
  float c = 1.0F;
  sin_cos(q, s, c);
  switch (j.axis_kind) {
    case AxisKind::x:
    case AxisKind::y:
    case AxisKind::z: {
      const auto a = static_cast<std::size_t>(j.axis_kind);
      turn(r, a, s, c);
      return r[a];
    }
    case AxisKind::minus_x:
    case AxisKind::minus_y:
    case AxisKind::minus_z: {
      const auto a = static_cast<std::size_t>(j.axis_kind) - 3U;
      turn(r, a, -s, c);
      return scale(r[a], -1.0F);
    }
    default: {
      const Vec3 z = to_base(r, j.axis);
      turn_general(r, j.axis, z, s, c);
      return z;
    }
  }
}
// The acceleration of a point at offset d from a point with acceleration a on a body
// turning with w, wd.
Vec3 carried(const Vec3& a, const Vec3& w, const Vec3& wd, const Vec3& d) noexcept {
  return add(add(a, cross(wd, d)), cross(w, cross(w, d)));
}
Vec3 in_m(const Vec3& mm) noexcept { return {mm[0] / 1000.0F, mm[1] / 1000.0F, mm[2] / 1000.0F}; }

}  // namespace

ArmDynamicsModel prepare_dynamics(const ArmGeometry& arm, const ArmInertials& inertials) noexcept {
  const PreparedArm p = prepare_arm(arm);
  ArmDynamicsModel m{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    DynamicsJoint& j = m.joint[k];
    j.origin_m = in_m(arm.joint[k].frame.origin_mm);
    j.rotation = arm.joint[k].frame.rotation;
    j.turned = p.frame[k].turned;
    j.axis = arm.joint[k].axis;
    j.axis_kind = p.axis_kind[k];
    j.inertial = inertials.link[k];
  }
  m.flange_origin_m = in_m(arm.flange.origin_mm);
  m.flange_rotation = arm.flange.rotation;
  m.rated_torque_nm = inertials.rated_torque_nm;
  return m;
}

// @req COL-COLLISION
void arm_dynamics(const ArmDynamicsModel& m, const JointArray& q, const JointArray& qd, const JointArray& qdd,
                  float payload_kg, const Vec3& tcp_flange_mm, ArmDynamicsState& out) noexcept {
  Mat3 r{{{1.0F, 0.0F, 0.0F}, {0.0F, 1.0F, 0.0F}, {0.0F, 0.0F, 1.0F}}};
  Vec3 p{};
  Vec3 w{};
  Vec3 wd{};
  Vec3 a{0.0F, 0.0F, kGravityM_S2};  // gravity: the base accelerating upwards
  std::array<Vec3, kAxes> origin{};
  std::array<Vec3, kAxes> axis{};
  std::array<Vec3, kAxes> force{};   // m a_c of each link
  std::array<Vec3, kAxes> moment{};  // I wd + w x I w about its centre of mass
  std::array<Vec3, kAxes> com{};     // centre of mass - joint origin
  for (std::size_t k = 0; k < kAxes; ++k) {
    const DynamicsJoint& j = m.joint[k];
    const LinkInertial& l = j.inertial;
    const Vec3 pk = add(p, to_base(r, j.origin_m));
    a = carried(a, w, wd, sub(pk, p));
    p = pk;
    if (j.turned) {
      r = turned(r, j.rotation);
    }
    const Vec3 z = turn_joint(r, j, q[k]);
    const Vec3 wn = add(w, scale(z, qd[k]));
    wd = add(add(wd, scale(z, qdd[k])), cross(w, scale(z, qd[k])));
    w = wn;
    origin[k] = p;
    axis[k] = z;
    com[k] = to_base(r, l.com_m);
    force[k] = scale(carried(a, w, wd, com[k]), l.mass_kg);
    const Vec3 wl = to_link(r, w);
    const Vec3 nl = add(inertia_times(l.inertia, to_link(r, wd)), cross(wl, inertia_times(l.inertia, wl)));
    moment[k] = to_base(r, nl);
  }
  // The TCP: the flange's origin plus the tool's offset turned into joint 6's frame.
  const float mm = 0.001F;
  const Vec3 t{tcp_flange_mm[0] * mm, tcp_flange_mm[1] * mm, tcp_flange_mm[2] * mm};
  const Rotation3& fr = m.flange_rotation;
  const Vec3 in6 = add(m.flange_origin_m, {(fr[0][0] * t[0]) + (fr[0][1] * t[1]) + (fr[0][2] * t[2]),
                                           (fr[1][0] * t[0]) + (fr[1][1] * t[1]) + (fr[1][2] * t[2]),
                                           (fr[2][0] * t[0]) + (fr[2][1] * t[1]) + (fr[2][2] * t[2])});
  const Vec3 tcp_off = to_base(r, in6);
  out.tcp_m = add(origin[kAxes - 1U], tcp_off);
  const float mp = (payload_kg > 0.0F) ? payload_kg : 0.0F;
  Vec3 f = scale(carried(a, w, wd, tcp_off), mp);  // carried by joint 6 from the payload
  Vec3 n = cross(tcp_off, f);                      // about joint 6's origin
  for (std::size_t i = kAxes; i > 0U; --i) {
    const std::size_t k = i - 1U;
    // n arrives about the next joint's origin (or joint 6's for the payload): move it here.
    const Vec3 to_next = (k + 1U < kAxes) ? sub(origin[k + 1U], origin[k]) : Vec3{};
    n = add(add(add(n, cross(to_next, f)), moment[k]), cross(com[k], force[k]));
    f = add(f, force[k]);
    out.tau_nm[k] = dot(axis[k], n);
    out.jacobian[k] = cross(axis[k], sub(out.tcp_m, origin[k]));
  }
}

float estimate_tcp_force(const ArmDynamicsState& s, const JointArray& residual_nm, Vec3& force_n) noexcept {
  // A = J J^T + lambda^2 I (symmetric, positive definite), b = J r.
  const float l2 = kDampingM * kDampingM;
  std::array<float, 6> m{l2, 0.0F, 0.0F, l2, 0.0F, l2};  // a00 a01 a02 a11 a12 a22
  Vec3 b{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    const Vec3& j = s.jacobian[k];
    m[0] += j[0] * j[0];
    m[1] += j[0] * j[1];
    m[2] += j[0] * j[2];
    m[3] += j[1] * j[1];
    m[4] += j[1] * j[2];
    m[5] += j[2] * j[2];
    b = add(b, scale(j, residual_nm[k]));
  }
  // F = -A^-1 b by the adjugate (det >= lambda^6 > 0).
  const float c00 = (m[3] * m[5]) - (m[4] * m[4]);
  const float c01 = (m[2] * m[4]) - (m[1] * m[5]);
  const float c02 = (m[1] * m[4]) - (m[2] * m[3]);
  const float c11 = (m[0] * m[5]) - (m[2] * m[2]);
  const float c12 = (m[1] * m[2]) - (m[0] * m[4]);
  const float c22 = (m[0] * m[3]) - (m[1] * m[1]);
  const float det = (m[0] * c00) + (m[1] * c01) + (m[2] * c02);
  const float k = -1.0F / det;
  force_n = {k * ((c00 * b[0]) + (c01 * b[1]) + (c02 * b[2])), k * ((c01 * b[0]) + (c11 * b[1]) + (c12 * b[2])),
             k * ((c02 * b[0]) + (c12 * b[1]) + (c22 * b[2]))};
  return std::sqrt(dot(force_n, force_n));
}

float tcp_force_from_drives(const Feedback& fb, const JointArray& rated_torque_nm, const ArmDynamicsState& s,
                            Vec3& force_n) noexcept {
  JointArray residual{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    const float measured = static_cast<float>(fb.drive[k].torque_permille) * 0.001F * rated_torque_nm[k];
    residual[k] = measured - s.tau_nm[k];
  }
  return estimate_tcp_force(s, residual, force_n);
}

void CollisionMonitor::configure(const SafetyLimits& limits, const ArmGeometry& arm, std::uint32_t cycle_us) noexcept {
  const CollaborativeLimits& c = limits.collaborative;
  model_ = prepare_dynamics(arm, limits.inertials);
  enabled_ = c.enabled && c.pfl_enabled && (cycle_us > 0U);
  limit_n_ = c.f_qs_n;
  payload_kg_ = limits.payload_kg;
  tcp_mm_ = limits.tcp_mm;
  inv_dt_ = (cycle_us > 0U) ? (1.0e6F / static_cast<float>(cycle_us)) : 0.0F;
  have_prev_ = false;
  over_ = 0;
}

// @req COL-COLLISION
void CollisionMonitor::check(const CycleView& v, Reporter& rep) noexcept {
  const Feedback& fb = v.fb;
  // The drives hold the arm, brakes released, nothing pushing a brake: their torques
  // follow the model (OPERATIONAL but BRAKE_TEST, or a Cat 2 stop).
  const bool arm_free = ((static_cast<unsigned>(mask_of(v.leaf)) & static_cast<unsigned>(kOperationalOrCat2)) != 0U) &&
                        (v.leaf != Leaf::BRAKE_TEST);
  CollisionReport& r = rep.facts().collision;
  r = CollisionReport{};
  r.acting = enabled_;
  r.limit_n = limit_n_;
  JointArray q{};
  JointArray qd{};
  JointArray qdd{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    q[k] = fb.drive[k].position_rad;
    qd[k] = fb.drive[k].velocity_rad_s;
    qdd[k] = have_prev_ ? ((qd[k] - qd_prev_[k]) * inv_dt_) : 0.0F;
  }
  qd_prev_ = qd;
  have_prev_ = true;
  if (!enabled_ || !arm_free) {
    over_ = 0;
    return;
  }
  ArmDynamicsState model{};
  arm_dynamics(model_, q, qd, qdd, payload_kg_, tcp_mm_, model);
  Vec3 f{};
  r.evaluated = true;
  r.force_n = tcp_force_from_drives(fb, model_.rated_torque_nm, model, f);
  const bool over = !(r.force_n <= limit_n_);  // NaN is over
  over_ = over ? ((over_ < kCollisionConfirmCycles) ? static_cast<std::uint8_t>(over_ + 1U) : over_) : 0U;
  if (over_ >= kCollisionConfirmCycles) {
    rep.trip(AlarmId::COLLISION, detail_of(Signal::tcp, Channel::none, 0U, detail_code(r.force_n)));
  }
}

}  // namespace safestate::core

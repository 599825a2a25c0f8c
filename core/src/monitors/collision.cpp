// SPEC §11 collision detection: the core's own model of the arm (core/collision.hpp). A
// recursive Newton-Euler pass in the base frame: outward the links' angular velocities and
// accelerations and the joints' linear accelerations (gravity as an upward acceleration of
// the base), inward the forces and moments each joint must carry; the joint torque is the
// moment about the joint's axis. Six links, one optional point mass (the payload at the TCP).
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
// R Rot(axis, q): the two columns other than the axis turn (cyclic order x -> y -> z).
void turn(Mat3& r, JointAxis axis, float q) noexcept {
  float s = 0.0F;
  float c = 1.0F;
  sin_cos(q, s, c);
  const auto a = static_cast<std::size_t>(axis) % 3U;
  const std::size_t u = (a + 1U) % 3U;
  const std::size_t v = (a + 2U) % 3U;
  const Vec3 cu = r[u];
  const Vec3 cv = r[v];
  r[u] = add(scale(cu, c), scale(cv, s));
  r[v] = sub(scale(cv, c), scale(cu, s));
}
// The acceleration of a point at offset d from a point with acceleration a on a body
// turning with w, wd.
Vec3 carried(const Vec3& a, const Vec3& w, const Vec3& wd, const Vec3& d) noexcept {
  return add(add(a, cross(wd, d)), cross(w, cross(w, d)));
}

}  // namespace

// @req COL-COLLISION
void arm_dynamics(const JointArray& q, const JointArray& qd, const JointArray& qdd, float payload_kg,
                  const Vec3& tcp_tool0_mm, ArmDynamicsState& out) noexcept {
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
  Vec3 a6{};
  Vec3 w6{};
  Vec3 wd6{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    const LinkInertial& l = kIrb120Links[k];
    const Vec3 pk = add(p, to_base(r, l.joint_origin_m));
    a = carried(a, w, wd, sub(pk, p));
    p = pk;
    turn(r, l.axis, q[k]);
    const Vec3 z = r[static_cast<std::size_t>(l.axis) % 3U];
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
    a6 = a;
    w6 = w;
    wd6 = wd;
  }
  // tool0 is link 6 turned +90 deg about y: (x, y, z) in tool0 is (z, y, -x) in link 6.
  const float mm = 0.001F;
  const Vec3 t{tcp_tool0_mm[2] * mm, tcp_tool0_mm[1] * mm, -tcp_tool0_mm[0] * mm};
  const Vec3 tcp_off = to_base(r, t);
  out.tcp_m = add(origin[kAxes - 1U], tcp_off);
  const float mp = (payload_kg > 0.0F) ? payload_kg : 0.0F;
  Vec3 f = scale(carried(a6, w6, wd6, tcp_off), mp);  // carried by joint 6 from the payload
  Vec3 n = cross(tcp_off, f);                         // about joint 6's origin
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

float tcp_force_from_drives(const Feedback& fb, const ArmDynamicsState& s, Vec3& force_n) noexcept {
  JointArray residual{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    const float measured = static_cast<float>(fb.drive[k].torque_permille) * 0.001F * kRatedTorqueNm[k];
    residual[k] = measured - s.tau_nm[k];
  }
  return estimate_tcp_force(s, residual, force_n);
}

void CollisionMonitor::configure(const SafetyLimits& limits, std::uint32_t cycle_us) noexcept {
  const CollaborativeLimits& c = limits.collaborative;
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
  arm_dynamics(q, qd, qdd, payload_kg_, tcp_mm_, model);
  Vec3 f{};
  r.evaluated = true;
  r.force_n = tcp_force_from_drives(fb, model, f);
  const bool over = !(r.force_n <= limit_n_);  // NaN is over
  over_ = over ? ((over_ < kCollisionConfirmCycles) ? static_cast<std::uint8_t>(over_ + 1U) : over_) : 0U;
  if (over_ >= kCollisionConfirmCycles) {
    rep.trip(AlarmId::COLLISION, detail_of(Signal::tcp, Channel::none, 0U, detail_code(r.force_n)));
  }
}

}  // namespace safestate::core

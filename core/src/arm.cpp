#include "safestate/core/arm.hpp"

#include <cmath>

namespace safestate::core {

namespace {

Vec3 add(const Vec3& a, const Vec3& b) noexcept { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 sub(const Vec3& a, const Vec3& b) noexcept { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 scale(const Vec3& a, float k) noexcept { return {a[0] * k, a[1] * k, a[2] * k}; }
Vec3 cross(const Vec3& a, const Vec3& b) noexcept {
  return {(a[1] * b[2]) - (a[2] * b[1]), (a[2] * b[0]) - (a[0] * b[2]), (a[0] * b[1]) - (a[1] * b[0])};
}
// c*u + s*v, the rotation of one axis of a frame toward another.
Vec3 mix(float c, const Vec3& u, float s, const Vec3& v) noexcept { return add(scale(u, c), scale(v, s)); }

}  // namespace

void arm_forward(const ArmGeometry& g, const JointArray& q, const Vec3& tcp_flange_mm, ArmPose& out) noexcept {
  Vec3 o{0.0F, 0.0F, 0.0F};
  Vec3 x{1.0F, 0.0F, 0.0F};
  Vec3 y{0.0F, 1.0F, 0.0F};
  Vec3 z{0.0F, 0.0F, 1.0F};
  out.origin[0] = o;
  out.x[0] = x;
  out.z[0] = z;
  for (std::size_t k = 0; k < kAxes; ++k) {
    const DhParam& p = g.dh[k];
    const float th = q[k] + p.theta_offset_rad;
    const float ct = std::cos(th);
    const float st = std::sin(th);
    // Rot_z(theta): x and y turn about z.
    const Vec3 x1 = mix(ct, x, st, y);
    const Vec3 y1 = mix(-st, x, ct, y);
    // Trans_z(d) then Trans_x(a) along the turned x.
    o = add(add(o, scale(z, p.d_mm)), scale(x1, p.a_mm));
    // Rot_x(alpha): y and z turn about the new x.
    const float ca = std::cos(p.alpha_rad);
    const float sa = std::sin(p.alpha_rad);
    const Vec3 y2 = mix(ca, y1, sa, z);
    const Vec3 z2 = mix(-sa, y1, ca, z);
    x = x1;
    y = y2;
    z = z2;
    out.origin[k + 1U] = o;
    out.x[k + 1U] = x;
    out.z[k + 1U] = z;
  }
  out.tcp = add(add(add(o, scale(x, tcp_flange_mm[0])), scale(y, tcp_flange_mm[1])), scale(z, tcp_flange_mm[2]));
  out.tool_z = z;
}

float point_speed(const ArmPose& pose, const Vec3& point, std::size_t joints, const JointArray& qd) noexcept {
  Vec3 v{0.0F, 0.0F, 0.0F};
  const std::size_t n = (joints < kAxes) ? joints : kAxes;
  // cppcheck-suppress knownConditionTrueFalse ; false positive of cppcheck 2.10: n is 1..6 for the callers' values
  for (std::size_t k = 0; k < n; ++k) {
    // Joint k+1 turns about z of frame k through origin k.
    v = add(v, scale(cross(pose.z[k], sub(point, pose.origin[k])), qd[k]));
  }
  return std::sqrt((v[0] * v[0]) + (v[1] * v[1]) + (v[2] * v[2]));
}

}  // namespace safestate::core

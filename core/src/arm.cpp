#include "safestate/core/arm.hpp"

#include <cmath>
#include <cstdint>

namespace safestate::core {

namespace {

// pi/2 in two parts: the first has its low bits zero, so k * kHalfPiHi is exact for the k
// of kSinCosFastRange, and the reduced angle keeps float precision.
constexpr float kTwoOverPi = 0.636619772367581343F;
constexpr float kHalfPiHi = 1.5703125F;                // 0x3FC90000
constexpr float kHalfPiLo = 4.83826794897e-4F;         // pi/2 - kHalfPiHi

// The body of sin_cos(), inlined into arm_forward() (the call was a sixth of its cost).
[[gnu::always_inline]] inline void sin_cos_body(float x, float& s, float& c) noexcept {
  if (!((x <= kSinCosFastRange) && (x >= -kSinCosFastRange))) {  // NaN, infinite, huge
    s = std::sin(x);
    c = std::cos(x);
    return;
  }
  const float t = x * kTwoOverPi;
  const auto k = static_cast<std::int32_t>((t >= 0.0F) ? (t + 0.5F) : (t - 0.5F));  // nearest
  const auto kf = static_cast<float>(k);
  const float r = (x - (kf * kHalfPiHi)) - (kf * kHalfPiLo);  // |r| <= pi/4 (+ rounding)
  const float r2 = r * r;
  // Taylor to r^9 / r^10: the first omitted terms are below 2e-9 at |r| = pi/4.
  const float sr = r + (r * r2 * (-1.0F / 6.0F + r2 * (1.0F / 120.0F + r2 * (-1.0F / 5040.0F + r2 * (1.0F / 362880.0F)))));
  const float cr =
      1.0F + (r2 * (-0.5F + r2 * (1.0F / 24.0F + r2 * (-1.0F / 720.0F + r2 * (1.0F / 40320.0F + r2 * (-1.0F / 3628800.0F))))));
  switch (static_cast<std::uint32_t>(k) & 3U) {
    case 0U:
      s = sr;
      c = cr;
      break;
    case 1U:
      s = cr;
      c = -sr;
      break;
    case 2U:
      s = -sr;
      c = -cr;
      break;
    default:
      s = -cr;
      c = sr;
      break;
  }
}

}  // namespace

void sin_cos(float x, float& s, float& c) noexcept { sin_cos_body(x, s, c); }

PreparedArm prepare_arm(const ArmGeometry& g) noexcept {
  PreparedArm p{};
  p.geometry = g;
  constexpr float kHalfPi = 1.57079632679F;
  constexpr float kExact = 1.0e-6F;  // float's own pi/2 is 4e-8 from pi/2
  for (std::size_t k = 0; k < kAxes; ++k) {
    const float a = g.dh[k].alpha_rad;
    p.cos_alpha[k] = std::cos(a);
    p.sin_alpha[k] = std::sin(a);
    p.alpha_kind[k] = (std::fabs(a) < kExact)             ? AlphaKind::zero
                      : (std::fabs(a - kHalfPi) < kExact) ? AlphaKind::plus_half_pi
                      : (std::fabs(a + kHalfPi) < kExact) ? AlphaKind::minus_half_pi
                                                          : AlphaKind::general;
  }
  return p;
}

void arm_forward(const ArmGeometry& g, const JointArray& q, const Vec3& tcp_flange_mm, ArmPose& out) noexcept {
  arm_forward(prepare_arm(g), q, tcp_flange_mm, out);
}

// Each joint as rotations of the frame's axis vectors (diverse from motion/kinematics' matrix
// products), written out component by component in named scalars: on a Cortex-M4F at -Os
// the frame stays in FPU registers (docs/performance.md, M4 instructions per cycle).
void arm_forward(const PreparedArm& g, const JointArray& q, const Vec3& tcp_flange_mm, ArmPose& out) noexcept {
  float ox = 0.0F, oy = 0.0F, oz = 0.0F;  // NOLINT(readability-isolate-declaration): one frame, one line each
  float xx = 1.0F, xy = 0.0F, xz = 0.0F;  // NOLINT(readability-isolate-declaration)
  float yx = 0.0F, yy = 1.0F, yz = 0.0F;  // NOLINT(readability-isolate-declaration)
  float zx = 0.0F, zy = 0.0F, zz = 1.0F;  // NOLINT(readability-isolate-declaration)
  out.origin[0] = {ox, oy, oz};
  out.z[0] = {zx, zy, zz};
  for (std::size_t k = 0; k < kAxes; ++k) {
    const DhParam& p = g.geometry.dh[k];
    float st = 0.0F;
    float ct = 0.0F;
    sin_cos_body(q[k] + p.theta_offset_rad, st, ct);
    // Rot_z(theta): x and y turn about z.
    const float x1x = (ct * xx) + (st * yx);
    const float x1y = (ct * xy) + (st * yy);
    const float x1z = (ct * xz) + (st * yz);
    const float y1x = (ct * yx) - (st * xx);
    const float y1y = (ct * yy) - (st * xy);
    const float y1z = (ct * yz) - (st * xz);
    // Trans_z(d), then Trans_x(a) along the turned x.
    ox += (p.d_mm * zx) + (p.a_mm * x1x);
    oy += (p.d_mm * zy) + (p.a_mm * x1y);
    oz += (p.d_mm * zz) + (p.a_mm * x1z);
    xx = x1x;
    xy = x1y;
    xz = x1z;
    // Rot_x(alpha): y and z turn about the new x. Industrial arms' DH alphas are 0 and
    // +-90 degrees: exchanges, recognised once by prepare_arm().
    switch (g.alpha_kind[k]) {
      case AlphaKind::zero:
        yx = y1x;
        yy = y1y;
        yz = y1z;
        break;
      case AlphaKind::plus_half_pi:
        yx = zx;
        yy = zy;
        yz = zz;
        zx = -y1x;
        zy = -y1y;
        zz = -y1z;
        break;
      case AlphaKind::minus_half_pi:
        yx = -zx;
        yy = -zy;
        yz = -zz;
        zx = y1x;
        zy = y1y;
        zz = y1z;
        break;
      default: {
        const float ca = g.cos_alpha[k];
        const float sa = g.sin_alpha[k];
        yx = (ca * y1x) + (sa * zx);
        yy = (ca * y1y) + (sa * zy);
        yz = (ca * y1z) + (sa * zz);
        zx = (ca * zx) - (sa * y1x);
        zy = (ca * zy) - (sa * y1y);
        zz = (ca * zz) - (sa * y1z);
        break;
      }
    }
    out.origin[k + 1U] = {ox, oy, oz};
    out.z[k + 1U] = {zx, zy, zz};
  }
  const float tx = tcp_flange_mm[0];
  const float ty = tcp_flange_mm[1];
  const float tz = tcp_flange_mm[2];
  out.tcp = {ox + (xx * tx) + (yx * ty) + (zx * tz), oy + (xy * tx) + (yy * ty) + (zy * tz),
             oz + (xz * tx) + (yz * ty) + (zz * tz)};
  out.tool_z = {zx, zy, zz};
}

float point_speed(const ArmPose& pose, const Vec3& point, std::size_t joints, const JointArray& qd) noexcept {
  Vec3 v{0.0F, 0.0F, 0.0F};
  const std::size_t n = (joints < kAxes) ? joints : kAxes;
  // cppcheck-suppress knownConditionTrueFalse ; false positive of cppcheck 2.10: n is 1..6 for the callers' values
  for (std::size_t k = 0; k < n; ++k) {
    // Joint k+1 turns about z of frame k through origin k: v += (z_k x (point - o_k)) qd_k.
    const Vec3& z = pose.z[k];
    const Vec3& o = pose.origin[k];
    const float rx = point[0] - o[0];
    const float ry = point[1] - o[1];
    const float rz = point[2] - o[2];
    v[0] += ((z[1] * rz) - (z[2] * ry)) * qd[k];
    v[1] += ((z[2] * rx) - (z[0] * rz)) * qd[k];
    v[2] += ((z[0] * ry) - (z[1] * rx)) * qd[k];
  }
  return std::sqrt((v[0] * v[0]) + (v[1] * v[1]) + (v[2] * v[2]));
}

}  // namespace safestate::core

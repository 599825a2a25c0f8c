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

namespace {

constexpr float kExact = 1.0e-6F;  // below this a fixed number is taken as exactly 0 or 1

bool near(float a, float b) noexcept { return std::fabs(a - b) < kExact; }

PreparedFrame prepare_frame(const ArmFrame& f) noexcept {
  PreparedFrame p{};
  const Vec3& o = f.origin_mm;
  const bool zx = o[0] == 0.0F;
  const bool zy = o[1] == 0.0F;
  const bool zz = o[2] == 0.0F;
  if (zx && zy && zz) {
    p.shift = ShiftKind::none;
  } else if (zy && zz) {
    p.shift = ShiftKind::x;
    p.shift_mm = o[0];
  } else if (zx && zz) {
    p.shift = ShiftKind::y;
    p.shift_mm = o[1];
  } else if (zx && zy) {
    p.shift = ShiftKind::z;
    p.shift_mm = o[2];
  } else {
    p.shift = ShiftKind::general;
  }
  bool identity = true;
  for (std::size_t r = 0; r < 3U; ++r) {
    for (std::size_t c = 0; c < 3U; ++c) {
      // Exactly: a rotation within kExact of the identity but not equal to it keeps its
      // small angle (general path).
      identity = identity && (f.rotation[r][c] == ((r == c) ? 1.0F : 0.0F));
    }
  }
  p.turned = !identity;
  return p;
}

AxisKind axis_kind(const Vec3& a) noexcept {
  const bool x0 = near(a[0], 0.0F);
  const bool y0 = near(a[1], 0.0F);
  const bool z0 = near(a[2], 0.0F);
  if (y0 && z0 && near(std::fabs(a[0]), 1.0F)) {
    return (a[0] > 0.0F) ? AxisKind::x : AxisKind::minus_x;
  }
  if (x0 && z0 && near(std::fabs(a[1]), 1.0F)) {
    return (a[1] > 0.0F) ? AxisKind::y : AxisKind::minus_y;
  }
  if (x0 && y0 && near(std::fabs(a[2]), 1.0F)) {
    return (a[2] > 0.0F) ? AxisKind::z : AxisKind::minus_z;
  }
  return AxisKind::general;
}

// The frame (origin o, axes x, y, z in the base frame), written out in named scalars: on a
// Cortex-M4F at -Os it stays in FPU registers (docs/performance.md, M4 instructions per cycle).
struct Frame {
  float ox, oy, oz;  // NOLINT(readability-isolate-declaration)
  float xx, xy, xz;  // NOLINT(readability-isolate-declaration)
  float yx, yy, yz;  // NOLINT(readability-isolate-declaration)
  float zx, zy, zz;  // NOLINT(readability-isolate-declaration)
};

// Moves the frame to a child fixed in it: origin shifted along the frame's own axes, axes
// turned by the fixed rotation (each new axis a combination of the old ones).
[[gnu::always_inline]] inline void apply_fixed(Frame& f, const ArmFrame& g, const PreparedFrame& p) noexcept {
  switch (p.shift) {
    case ShiftKind::none:
      break;
    case ShiftKind::x:
      f.ox += p.shift_mm * f.xx;
      f.oy += p.shift_mm * f.xy;
      f.oz += p.shift_mm * f.xz;
      break;
    case ShiftKind::y:
      f.ox += p.shift_mm * f.yx;
      f.oy += p.shift_mm * f.yy;
      f.oz += p.shift_mm * f.yz;
      break;
    case ShiftKind::z:
      f.ox += p.shift_mm * f.zx;
      f.oy += p.shift_mm * f.zy;
      f.oz += p.shift_mm * f.zz;
      break;
    default: {
      const Vec3& o = g.origin_mm;
      f.ox += (o[0] * f.xx) + (o[1] * f.yx) + (o[2] * f.zx);
      f.oy += (o[0] * f.xy) + (o[1] * f.yy) + (o[2] * f.zy);
      f.oz += (o[0] * f.xz) + (o[1] * f.yz) + (o[2] * f.zz);
      break;
    }
  }
  if (p.turned) {
    const Rotation3& r = g.rotation;  // column c: new axis c in the old frame
    const float nxx = (r[0][0] * f.xx) + (r[1][0] * f.yx) + (r[2][0] * f.zx);
    const float nxy = (r[0][0] * f.xy) + (r[1][0] * f.yy) + (r[2][0] * f.zy);
    const float nxz = (r[0][0] * f.xz) + (r[1][0] * f.yz) + (r[2][0] * f.zz);
    const float nyx = (r[0][1] * f.xx) + (r[1][1] * f.yx) + (r[2][1] * f.zx);
    const float nyy = (r[0][1] * f.xy) + (r[1][1] * f.yy) + (r[2][1] * f.zy);
    const float nyz = (r[0][1] * f.xz) + (r[1][1] * f.yz) + (r[2][1] * f.zz);
    const float nzx = (r[0][2] * f.xx) + (r[1][2] * f.yx) + (r[2][2] * f.zx);
    const float nzy = (r[0][2] * f.xy) + (r[1][2] * f.yy) + (r[2][2] * f.zy);
    const float nzz = (r[0][2] * f.xz) + (r[1][2] * f.yz) + (r[2][2] * f.zz);
    f.xx = nxx;
    f.xy = nxy;
    f.xz = nxz;
    f.yx = nyx;
    f.yy = nyy;
    f.yz = nyz;
    f.zx = nzx;
    f.zy = nzy;
    f.zz = nzz;
  }
}

// Turns axes b and c of a frame by t about the third (a, with a b c right-handed):
// b' = cos t b + sin t c, c' = cos t c - sin t b.
[[gnu::always_inline]] inline void turn_pair(float& bx, float& by, float& bz, float& cx, float& cy, float& cz, float ct,
                                             float st) noexcept {
  const float nbx = (ct * bx) + (st * cx);
  const float nby = (ct * by) + (st * cy);
  const float nbz = (ct * bz) + (st * cz);
  cx = (ct * cx) - (st * bx);
  cy = (ct * cy) - (st * by);
  cz = (ct * cz) - (st * bz);
  bx = nbx;
  by = nby;
  bz = nbz;
}

// Turns the frame's axes by the angle (ct, st) about its unit axis `u` (in the frame's own
// coordinates): Rodrigues' formula, R = c I + s [u]x + (1 - c) u u^T, applied as the
// combination of the old axes with R's columns.
void turn_general(Frame& f, const Vec3& u, float ct, float st) noexcept {
  const float v = 1.0F - ct;
  ArmFrame r{};
  r.rotation = {{{ct + (u[0] * u[0] * v), (u[0] * u[1] * v) - (u[2] * st), (u[0] * u[2] * v) + (u[1] * st)},
                 {(u[1] * u[0] * v) + (u[2] * st), ct + (u[1] * u[1] * v), (u[1] * u[2] * v) - (u[0] * st)},
                 {(u[2] * u[0] * v) - (u[1] * st), (u[2] * u[1] * v) + (u[0] * st), ct + (u[2] * u[2] * v)}}};
  PreparedFrame p{};
  p.turned = true;
  apply_fixed(f, r, p);
}

}  // namespace

ArmGeometry arm_from_dh(const std::array<DhParam, kAxes>& dh) noexcept {
  // A_k = Rot_z(theta) Trans_z(d) Trans_x(a) Rot_x(alpha): joint k turns about z of DH frame
  // k-1 (joint k's frame); DH frame k, joint k+1's frame, sits at (a cos theta, a sin theta, d)
  // turned by Rot_z(theta) Rot_x(alpha) at q_k = 0.
  ArmGeometry g{};
  for (std::size_t k = 0; k < kAxes; ++k) {
    const DhParam& p = dh[k];
    const float ct = std::cos(p.theta_offset_rad);
    const float st = std::sin(p.theta_offset_rad);
    const float ca = std::cos(p.alpha_rad);
    const float sa = std::sin(p.alpha_rad);
    ArmFrame f{};
    f.origin_mm = {p.a_mm * ct, p.a_mm * st, p.d_mm};
    f.rotation = {{{ct, -st * ca, st * sa}, {st, ct * ca, -ct * sa}, {0.0F, sa, ca}}};
    if (k + 1U < kAxes) {
      g.joint[k + 1U].frame = f;
    } else {
      g.flange = f;
    }
  }
  return g;  // joint 1's frame is the base frame, every axis z
}

PreparedArm prepare_arm(const ArmGeometry& g) noexcept {
  PreparedArm p{};
  p.geometry = g;
  for (std::size_t k = 0; k < kAxes; ++k) {
    p.frame[k] = prepare_frame(g.joint[k].frame);
    p.axis_kind[k] = axis_kind(g.joint[k].axis);
  }
  p.flange = prepare_frame(g.flange);
  return p;
}

void arm_forward(const ArmGeometry& g, const JointArray& q, const Vec3& tcp_flange_mm, ArmPose& out) noexcept {
  arm_forward(prepare_arm(g), q, tcp_flange_mm, out);
}

// Each joint as rotations of the frame's axis vectors (diverse from motion/kinematics' matrix
// products): the fixed place of the joint's frame, then the turn about its axis.
void arm_forward(const PreparedArm& g, const JointArray& q, const Vec3& tcp_flange_mm, ArmPose& out) noexcept {
  Frame f{0.0F, 0.0F, 0.0F, 1.0F, 0.0F, 0.0F, 0.0F, 1.0F, 0.0F, 0.0F, 0.0F, 1.0F};
  for (std::size_t k = 0; k < kAxes; ++k) {
    const ArmJoint& j = g.geometry.joint[k];
    apply_fixed(f, j.frame, g.frame[k]);
    out.origin[k] = {f.ox, f.oy, f.oz};
    float st = 0.0F;
    float ct = 0.0F;
    sin_cos_body(q[k], st, ct);
    switch (g.axis_kind[k]) {
      case AxisKind::x:
        out.z[k] = {f.xx, f.xy, f.xz};
        turn_pair(f.yx, f.yy, f.yz, f.zx, f.zy, f.zz, ct, st);
        break;
      case AxisKind::minus_x:
        out.z[k] = {-f.xx, -f.xy, -f.xz};
        turn_pair(f.yx, f.yy, f.yz, f.zx, f.zy, f.zz, ct, -st);
        break;
      case AxisKind::y:
        out.z[k] = {f.yx, f.yy, f.yz};
        turn_pair(f.zx, f.zy, f.zz, f.xx, f.xy, f.xz, ct, st);
        break;
      case AxisKind::minus_y:
        out.z[k] = {-f.yx, -f.yy, -f.yz};
        turn_pair(f.zx, f.zy, f.zz, f.xx, f.xy, f.xz, ct, -st);
        break;
      case AxisKind::z:
        out.z[k] = {f.zx, f.zy, f.zz};
        turn_pair(f.xx, f.xy, f.xz, f.yx, f.yy, f.yz, ct, st);
        break;
      case AxisKind::minus_z:
        out.z[k] = {-f.zx, -f.zy, -f.zz};
        turn_pair(f.xx, f.xy, f.xz, f.yx, f.yy, f.yz, ct, -st);
        break;
      default: {
        const Vec3& u = j.axis;
        out.z[k] = {(u[0] * f.xx) + (u[1] * f.yx) + (u[2] * f.zx), (u[0] * f.xy) + (u[1] * f.yy) + (u[2] * f.zy),
                    (u[0] * f.xz) + (u[1] * f.yz) + (u[2] * f.zz)};
        turn_general(f, u, ct, st);
        break;
      }
    }
  }
  apply_fixed(f, g.geometry.flange, g.flange);
  out.origin[kAxes] = {f.ox, f.oy, f.oz};
  out.z[kAxes] = {f.zx, f.zy, f.zz};
  const float tx = tcp_flange_mm[0];
  const float ty = tcp_flange_mm[1];
  const float tz = tcp_flange_mm[2];
  out.tcp = {f.ox + (f.xx * tx) + (f.yx * ty) + (f.zx * tz), f.oy + (f.xy * tx) + (f.yy * ty) + (f.zy * tz),
             f.oz + (f.xz * tx) + (f.yz * ty) + (f.zz * tz)};
  out.tool_z = {f.zx, f.zy, f.zz};
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

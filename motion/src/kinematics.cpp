#include "safestate/motion/kinematics.hpp"

#include <cmath>

namespace safestate::motion {
namespace {

Vec3 add(const Vec3& a, const Vec3& b) noexcept { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }

Vec3 sub(const Vec3& a, const Vec3& b) noexcept { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

Vec3 scale(const Vec3& a, float s) noexcept { return {a[0] * s, a[1] * s, a[2] * s}; }

Vec3 cross(const Vec3& a, const Vec3& b) noexcept {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

float norm(const Vec3& a) noexcept { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

Vec3 mul(const Mat3& R, const Vec3& v) noexcept {
  return {R[0][0] * v[0] + R[0][1] * v[1] + R[0][2] * v[2],
          R[1][0] * v[0] + R[1][1] * v[1] + R[1][2] * v[2],
          R[2][0] * v[0] + R[2][1] * v[1] + R[2][2] * v[2]};
}

Mat3 mul(const Mat3& A, const Mat3& B) noexcept {
  Mat3 C{};
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) {
      C[r][c] = A[r][0] * B[0][c] + A[r][1] * B[1][c] + A[r][2] * B[2][c];
    }
  }
  return C;
}

Vec3 column(const Mat3& R, std::size_t c) noexcept { return {R[0][c], R[1][c], R[2][c]}; }

bool is_eye(const Mat3& R) noexcept {
  return R[0][0] == 1.0F && R[1][1] == 1.0F && R[2][2] == 1.0F && R[0][1] == 0.0F && R[0][2] == 0.0F &&
         R[1][0] == 0.0F && R[1][2] == 0.0F && R[2][0] == 0.0F && R[2][1] == 0.0F;
}

// R * Rot(e_a, q) for a unit axis along column a: columns b and c (a, b, c cyclic) turn,
// b' = cos q b + sin q c, c' = cos q c - sin q b (sign: s < 0 for the minus axis).
void turn_columns(Mat3& R, std::size_t b, std::size_t c, float co, float si) noexcept {
  for (std::size_t r = 0; r < 3; ++r) {
    const float vb = R[r][b];
    const float vc = R[r][c];
    R[r][b] = (co * vb) + (si * vc);
    R[r][c] = (co * vc) - (si * vb);
  }
}

// T.R * Rot(u, q): the turn of a joint about its unit axis u (the core's arm.cpp turns frame
// vectors instead). An axis along +-x, +-y, +-z turns two columns; any other axis is
// Rodrigues' matrix R = cos q I + (1 - cos q) u u^T + sin q [u]x, then one product.
void turn(Mat3& R, const Vec3& u, float q) noexcept {
  const float si = std::sin(q);
  const float co = std::cos(q);
  for (std::size_t a = 0; a < 3; ++a) {
    const std::size_t b = (a + 1U) % 3U;
    const std::size_t c = (a + 2U) % 3U;
    if (u[b] == 0.0F && u[c] == 0.0F && (u[a] == 1.0F || u[a] == -1.0F)) {
      turn_columns(R, b, c, co, u[a] * si);
      return;
    }
  }
  const float v = 1.0F - co;
  const Mat3 Q{{{co + u[0] * u[0] * v, u[0] * u[1] * v - u[2] * si, u[0] * u[2] * v + u[1] * si},
                {u[1] * u[0] * v + u[2] * si, co + u[1] * u[1] * v, u[1] * u[2] * v - u[0] * si},
                {u[2] * u[0] * v - u[1] * si, u[2] * u[1] * v + u[0] * si, co + u[2] * u[2] * v}}};
  R = mul(R, Q);
}

void place(Pose& T, const FixedFrame& f) noexcept {
  T.p = add(T.p, mul(T.R, f.xyz_mm));
  if (!is_eye(f.R)) {
    T.R = mul(T.R, f.R);
  }
}

// Geometric Jacobian column sum: joint j+1 turns about z[j] through origin[j], so it moves
// point p with z[j] x (p - origin[j]) per rad/s. Only joints before the point count.
Vec3 velocity_of(const Frames& f, const Joints& qdot, const Vec3& p, std::size_t joints) noexcept {
  Vec3 v{0.0F, 0.0F, 0.0F};
  for (std::size_t j = 0; j < joints; ++j) {
    v = add(v, scale(cross(f.z[j], sub(p, f.origin[j])), qdot[j]));
  }
  return v;
}

// A NaN would lose every comparison and hide as "slow"; as +inf it forces a stop.
float sane_speed(float s) noexcept { return std::isfinite(s) ? s : HUGE_VALF; }

void find_fastest(PointSpeeds& out) noexcept {
  out.max_speed = 0.0F;
  out.fastest_point = 0;
  out.fastest_axis = 0;
  // Distal first with a strict '>': on a tie (wrist centre 4 = 5, TCP = flange with no
  // tool) the outer point is named, the one an operator looks at.
  for (std::size_t i = kPoints - 1; i >= 1; --i) {
    if (out.speed[i] > out.max_speed) {
      out.max_speed = out.speed[i];
      out.fastest_point = static_cast<std::uint8_t>(i);
      out.fastest_axis = static_cast<std::uint8_t>(i < kJoints ? i : kJoints);
    }
  }
}

}  // namespace

void forward(const RobotModel& model, const Joints& q, Frames& out) noexcept {
  Pose T{{0.0F, 0.0F, 0.0F}, kEye};
  for (std::size_t k = 0; k < kJoints; ++k) {
    const ChainJoint& j = model.joints[k];
    place(T, j.origin);
    out.origin[k] = T.p;
    out.z[k] = mul(T.R, j.axis);
    turn(T.R, j.axis, q[k]);
  }
  place(T, model.flange);
  out.origin[kJoints] = T.p;
  out.z[kJoints] = column(T.R, 2);
  out.tcp = add(T.p, mul(T.R, model.tcp_offset_mm));
  out.R = T.R;
}

Pose tcp_pose(const Frames& frames) noexcept { return Pose{frames.tcp, frames.R}; }

Rpy to_rpy(const Mat3& R) noexcept {
  const float cos_pitch = std::sqrt(R[0][0] * R[0][0] + R[1][0] * R[1][0]);
  const float pitch = std::atan2(-R[2][0], cos_pitch);
  // Below this cos(pitch) the yaw/roll split is numerically meaningless in float.
  if (cos_pitch < 1.0e-5F) {
    const float roll = R[2][0] < 0.0F ? std::atan2(R[0][1], R[1][1]) : std::atan2(-R[0][1], R[1][1]);
    return Rpy{roll, pitch, 0.0F};
  }
  return Rpy{std::atan2(R[2][1], R[2][2]), pitch, std::atan2(R[1][0], R[0][0])};
}

void point_speeds(const Frames& frames, const Joints& qdot, PointSpeeds& out) noexcept {
  out.velocity[0] = Vec3{0.0F, 0.0F, 0.0F};
  out.speed[0] = 0.0F;
  for (std::size_t i = 1; i < kLinks; ++i) {
    out.velocity[i] = velocity_of(frames, qdot, frames.origin[i], i);
    out.speed[i] = sane_speed(norm(out.velocity[i]));
  }
  out.velocity[kTcpPoint] = velocity_of(frames, qdot, frames.tcp, kJoints);
  out.speed[kTcpPoint] = sane_speed(norm(out.velocity[kTcpPoint]));
  find_fastest(out);
}

void point_speeds(const RobotModel& model, const Joints& q, const Joints& qdot,
                  PointSpeeds& out) noexcept {
  Frames frames{};
  forward(model, q, frames);
  point_speeds(frames, qdot, out);
}

float t1_scale(const RobotModel& model, const Joints& q, const Joints& qdot,
               float limit_mm_s) noexcept {
  if (!(limit_mm_s > 0.0F)) {
    return 0.0F;  // also catches a NaN limit
  }
  PointSpeeds ps{};
  point_speeds(model, q, qdot, ps);
  if (!std::isfinite(ps.max_speed)) {
    return 0.0F;
  }
  if (ps.max_speed <= limit_mm_s) {
    return 1.0F;
  }
  return limit_mm_s / ps.max_speed;
}

}  // namespace safestate::motion

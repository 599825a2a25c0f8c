#include "safestate/motion/back_off.hpp"

#include <cmath>

namespace safestate::motion {

namespace {
constexpr float kHalfTurn = 3.14159265358979F;  // pi
constexpr float kMinTimeS = 0.02F;

float distance(const Vec3& a, const Vec3& b) noexcept {
  const float dx = a[0] - b[0];
  const float dy = a[1] - b[1];
  const float dz = a[2] - b[2];
  return std::sqrt((dx * dx) + (dy * dy) + (dz * dz));
}
}  // namespace

// @req COL-BACKOFF
void BackOff::record(const Joints& q, const Vec3& tcp_mm) noexcept {
  if (count_ > 0U) {
    const std::size_t last = (head_ + kPathPoints - 1U) % kPathPoints;
    if (!(distance(p_[last], tcp_mm) >= kRecordStepMm)) {  // NaN: not recorded
      return;
    }
  }
  q_[head_] = q;
  p_[head_] = tcp_mm;
  head_ = (head_ + 1U) % kPathPoints;
  count_ = (count_ < kPathPoints) ? count_ + 1U : kPathPoints;
}

void BackOff::begin(const Joints& q, const Vec3& tcp_mm) noexcept {
  started_ = true;
  t_ = 0.0F;
  from_ = q;
  to_ = q;
  Joints at_q = q;
  Vec3 at_p = tcp_mm;
  float left = kBackOffMm;
  while ((count_ > 0U) && (left > 0.0F)) {
    const std::size_t last = (head_ + kPathPoints - 1U) % kPathPoints;
    const float d = distance(p_[last], at_p);
    if (!(d < left)) {  // the target lies between here and this point: interpolate
      const float k = (d > 0.0F) ? (left / d) : 0.0F;
      for (std::size_t i = 0; i < kJoints; ++i) {
        at_q[i] += (q_[last][i] - at_q[i]) * k;
      }
      for (std::size_t i = 0; i < 3U; ++i) {
        at_p[i] += (p_[last][i] - at_p[i]) * k;
      }
      left = 0.0F;
    } else {  // past this point: it is retraced
      left -= d;
      at_q = q_[last];
      at_p = p_[last];
      head_ = last;
      --count_;
    }
  }
  to_ = at_q;
  dist_ = distance(at_p, tcp_mm);
  // Cosine profile: the peak speed is pi/2 times the mean.
  const float t = (kHalfTurn * 0.5F) * dist_ / kBackOffSpeedMmS;
  T_ = (dist_ > 0.0F) ? ((t > kMinTimeS) ? t : kMinTimeS) : 0.0F;
}

void BackOff::step(float dt, Joints& q_sp, Joints& v_sp) noexcept {
  if (!started_ || (t_ >= T_)) {
    v_sp.fill(0.0F);
    return;
  }
  t_ = (t_ + dt < T_) ? (t_ + dt) : T_;
  const float phase = kHalfTurn * t_ / T_;
  const float s = 0.5F * (1.0F - std::cos(phase));
  const float ds = 0.5F * kHalfTurn / T_ * std::sin(phase);
  for (std::size_t i = 0; i < kJoints; ++i) {
    const float delta = to_[i] - from_[i];
    q_sp[i] = from_[i] + (delta * s);
    v_sp[i] = (t_ >= T_) ? 0.0F : (delta * ds);
  }
}

void BackOff::cancel() noexcept {
  started_ = false;
  t_ = 0.0F;
  T_ = 0.0F;
  dist_ = 0.0F;
}

}  // namespace safestate::motion

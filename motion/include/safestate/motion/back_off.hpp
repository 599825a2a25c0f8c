// SPEC §11 rule 8: after a collision's Cat 2 stop the arm backs off 10 mm along the path the
// TCP came, at no more than 100 mm/s, so that nothing stays clamped, then holds.
//
// The path is recorded from measured positions: a joint vector each time the TCP has moved
// kRecordStepMm from the last one, in a ring of kPathPoints (no heap). The back-off walks the
// ring back from where the arm stopped until kBackOffMm of TCP path are covered (fewer when
// less was recorded), and moves there on a straight joint-space line (the recorded points
// are a millimetre apart: the line follows the path) with a cosine velocity profile whose
// peak TCP speed is kBackOffSpeedMmS. The points it retraced are dropped from the ring: a
// second collision backs off further along the same path.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/motion/kinematics.hpp"

namespace safestate::motion {

inline constexpr float kBackOffMm = 10.0F;          // SPEC §11
inline constexpr float kBackOffSpeedMmS = 90.0F;    // SPEC §11: <= 100 mm/s, less a margin
inline constexpr float kRecordStepMm = 1.0F;
inline constexpr std::size_t kPathPoints = 32;      // > kBackOffMm / kRecordStepMm + 1

class BackOff {
 public:
  // A measured sample (joints, TCP in mm) of the arm moving on its own path.
  void record(const Joints& q, const Vec3& tcp_mm) noexcept;
  // From the set-point `q` (the arm at rest) with its TCP at `tcp_mm`: plans the retrace.
  // Nothing recorded: nothing to do (done() at once).
  void begin(const Joints& q, const Vec3& tcp_mm) noexcept;
  // One cycle of `dt` s: the set-point and its velocity while backing off.
  void step(float dt, Joints& q_sp, Joints& v_sp) noexcept;
  void cancel() noexcept;  // the stop ended or escalated: forget the retrace, keep the path
  [[nodiscard]] bool started() const noexcept { return started_; }
  [[nodiscard]] bool done() const noexcept { return started_ && (t_ >= T_); }
  [[nodiscard]] float distance_mm() const noexcept { return dist_; }  // of the retrace planned
  [[nodiscard]] std::size_t recorded() const noexcept { return count_; }

 private:
  std::array<Joints, kPathPoints> q_{};
  std::array<Vec3, kPathPoints> p_{};
  std::size_t head_ = 0;   // next slot
  std::size_t count_ = 0;
  bool started_ = false;
  Joints from_{};
  Joints to_{};
  float T_ = 0.0F;
  float t_ = 0.0F;
  float dist_ = 0.0F;
};

}  // namespace safestate::motion

// SPEC §4 rule 3, ISO 10218-1 5.7.3: in T1 the TCP and every link origin stay at or below
// t1_speed_limit_mm_s (250 mm/s). Watches motion armed in T1: a key turned to T1 while the
// arm moves at another mode's speed is rule 6's (Cat 1), not a T1 speed fault. The speed
// stays over its limit (the reset's cause present) whatever the mode.
//
// The speeds are the core's own, never the motion layer's figure (a fault in the planner
// must not blind the monitor, as for the safe limits of SPEC §10): the positions of the
// link origins and the TCP through the core's kinematics (the safe limits' pose of this
// cycle, from the measured joint positions), differentiated over the cycles between this
// sample and the last one as the drives took them. A cycle without a fresh sample (a lost or
// late frame: the positions are the last ones held) is no zero-length span: the last
// sample's speeds stand, and the next fresh one is differentiated over all the cycles since.
#include <cmath>
#include <limits>

#include "safestate/core/monitor.hpp"

namespace safestate::core {

namespace {

constexpr float kUnknown = std::numeric_limits<float>::infinity();

// Link (1..6) of point k of T1SpeedMonitor: link origin k + 1 for k < 5, the flange and
// the TCP for 5 and 6 (moved by every joint).
constexpr std::uint8_t link_of(std::size_t k) noexcept {
  return static_cast<std::uint8_t>((k + 1U < kAxes) ? (k + 1U) : kAxes);
}

}  // namespace

// @req MO-T1-MONITOR
void T1SpeedMonitor::check(const CycleView& v, Reporter& r) noexcept {
  const ArmPose* pose = v.facts.pose;
  if (pose == nullptr) {
    // No arm in the core: the speed is unknown, and unknown is unsafe.
    have_last_ = false;
    speed_mm_s_ = kUnknown;
    axis_ = 0U;
  } else {
    // @req MO-SAMPLE-TIME
    // A frame that carries the sample the last one carried is no new sample either.
    const bool same_sample = v.fb.stale || (v.fb.sample_clock && (v.fb.sample_span == 0U));
    if (!have_last_ || !same_sample) {
      // The farthest a point went since the last sample, compared squared (one square root),
      // each point kept for the next sample as it is read (no copy of the whole array: a
      // byte-wise memcpy in newlib-nano). Distal first with a strict `>`, so that a tie
      // names the outer point (the wrist centre is origin 4 and 5; the TCP is the flange
      // without a tool). Not finite: unknown, over any limit.
      float far2 = 0.0F;
      std::uint8_t axis = 0U;
      for (std::size_t k = kT1Points; k > 0U; --k) {
        // Point k - 1: link origin k (origin[0], joint 1's on the base, never moves), the TCP last.
        const Vec3& a = (k < kT1Points) ? pose->origin[k] : pose->tcp;
        Vec3& b = last_[k - 1U];
        const float dx = a[0] - b[0];
        const float dy = a[1] - b[1];
        const float dz = a[2] - b[2];
        b[0] = a[0];
        b[1] = a[1];
        b[2] = a[2];
        float d2 = (dx * dx) + (dy * dy) + (dz * dz);
        d2 = (d2 <= std::numeric_limits<float>::max()) ? d2 : kUnknown;  // NaN, inf
        if (d2 > far2) {
          far2 = d2;
          axis = link_of(k - 1U);
        }
      }
      if (have_last_) {
        // The cycles between the two samples: as the drives took them when the bus says (a
        // frame late past its SYNC0 carries the next pulse's sample; one that repeats the
        // last sample, span 0, is no fresh sample), else as the frames came.
        const std::uint32_t cycles = v.fb.sample_clock ? static_cast<std::uint32_t>(v.fb.sample_span) : span_;
        speed_mm_s_ = std::sqrt(far2) * v.timing.cycles_per_s / static_cast<float>(cycles);
        axis_ = axis;
      } else {
        speed_mm_s_ = 0.0F;  // the first sample: nothing to differentiate yet
        axis_ = 0U;
      }
      have_last_ = true;
      span_ = 1U;
    } else if (span_ < 0xFFFFU) {
      ++span_;  // the last sample's speeds stand
    }
  }
  const float speed = speed_mm_s_;
  r.facts().t1_speed_mm_s = speed;
  // `!(x <= limit)` so that a NaN speed counts as exceeded (unknown is unsafe).
  if (!(speed <= v.timing.t1_speed_limit_mm_s)) {
    r.present(AlarmId::T1_SPEED_EXCEEDED);
    if ((v.in.mode == Mode::T1) && (v.armed_mode == Mode::T1)) {
      r.trip(AlarmId::T1_SPEED_EXCEEDED, detail_of(Signal::drive, Channel::none, axis_, detail_code(speed)));
    }
  }
}

}  // namespace safestate::core

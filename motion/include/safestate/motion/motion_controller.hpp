// The motion layer: turns the supervisor's MotionRequest into CSP set-points and CiA 402
// controlwords for six drives, and measures the TCP and link-origin speeds (for its own
// T1 limiting and the status; the supervisor monitors speeds of its own kinematics). Same
// rules as core/: no heap, no exceptions, no clock; time is the cycle period given at
// construction.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "safestate/core/interfaces.hpp"
#include "safestate/core/supervisor.hpp"
#include "safestate/hal/process_image.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/motion/back_off.hpp"
#include "safestate/motion/kinematics.hpp"
#include "safestate/motion/limits.hpp"
#include "safestate/motion/robot.hpp"

namespace safestate::motion {

// PLCopen Motion axis states (names as in SPEC §6).
enum class AxisState : std::uint8_t {
  Disabled,
  Standstill,
  Homing,
  DiscreteMotion,
  ContinuousMotion,
  SynchronizedMotion,
  Stopping,
  ErrorStop,
};
const char* to_string(AxisState s) noexcept;

// A program is a list of joint waypoints, each reached by a synchronized point-to-point
// move at a programmed fraction of the axis speed limits, then an optional dwell.
struct Waypoint {
  Joints q{};
  float speed = 1.0F;         // fraction of every axis' velocity limit, 0 < speed <= 1
  std::uint16_t dwell_ms = 0; // wait at the waypoint (gripper, process)
};

struct MotionConfig {
  float cycle_s = 0.001F;
  float t1_limit_mm_s = 250.0F;  // ISO 10218-1 reduced speed
  float t1_margin = 0.96F;       // plan to 240 mm/s so the monitor's 250 is never reached
  float jog_speed = 0.5F;        // fraction of the axis velocity limit at jog speed 100 %
  float quick_stop_decel = 1.0F; // Cat 1 ramp, fraction of the axis acceleration limit
  float cat2_decel = 0.5F;       // Cat 2 ramp (pause, jog stop)
  float speed_override = 1.0F;   // program speed override, 0 < x <= 1
  float limit_margin_rad = 0.02F;  // stop this far inside the joint limits
  float following_error_rad = 0.05F;  // drive more than this behind its set-point: not following
};

// Synchronized point-to-point executor: every axis follows the same normalized
// trapezoidal profile, so the path in joint space is a straight line and velocity is
// continuous. Re-planned from the measured position on start and on resume.
class ProgramExecutor {
 public:
  void load(const Waypoint* points, std::uint8_t count) noexcept;
  void start(const Joints& from, const RobotModel& m, float override) noexcept;   // first waypoint
  void resume(const Joints& from, const RobotModel& m, float override) noexcept;  // current waypoint
  void abort() noexcept;
  // Advances by `dt` seconds of program time; returns the set-point position.
  Joints advance(float dt, const RobotModel& m, float override) noexcept;
  // Joint velocity the profile commands at the current instant (for T1 scaling).
  [[nodiscard]] Joints velocity() const noexcept;

  [[nodiscard]] bool loaded() const noexcept { return count_ > 0U; }
  [[nodiscard]] bool active() const noexcept { return active_; }
  [[nodiscard]] bool finished() const noexcept { return finished_; }
  [[nodiscard]] std::uint8_t index() const noexcept { return index_; }
  [[nodiscard]] std::uint8_t count() const noexcept { return count_; }

 private:
  void plan(const Joints& from, const RobotModel& m, float override) noexcept;
  [[nodiscard]] float s_of(float tau) const noexcept;
  [[nodiscard]] float ds_of(float tau) const noexcept;

  std::span<const Waypoint> points_;  // the program, owned by the caller
  std::uint8_t count_ = 0;
  std::uint8_t index_ = 0;
  bool active_ = false;
  bool finished_ = false;
  bool dwelling_ = false;
  Joints q0_{};
  Joints delta_{};
  float tau_ = 0.0F;   // time into the current segment (s)
  float T_ = 0.0F;     // segment duration
  float ta_ = 0.0F;    // acceleration time of the normalized profile
  float dwell_left_ = 0.0F;
};

class MotionController {
 public:
  MotionController(const RobotModel& model, const MotionConfig& cfg) noexcept;
  // The program (owned by the caller, kept alive while loaded); checked against the safe
  // limits here, once, not every cycle (Feedback::program_within_limits).
  void load_program(const Waypoint* points, std::uint8_t count) noexcept;

  // SPEC §10: the safe limits (validated, complete: every joint filled), once at start-up,
  // before the first cycle. Until then (or never) the controller plans as before: within
  // the robot's own ranges and speeds only, no TCP cap, no zones; MotionRequest::reduced is
  // obeyed with the built-in default (250 mm/s, 500 ms). From then on it plans inside the
  // limits less the margins of limits.hpp, uses limits.tcp_mm as the TCP (zones and TCP
  // speeds, and the speeds measure() reports), and re-checks the loaded program.
  void set_limits(const core::SafetyLimits& limits) noexcept;
  [[nodiscard]] const LimitPlanner& limits() const noexcept { return lim_; }

  // The checks behind Feedback::program_within_limits, for a caller that wants them
  // directly: the loaded program's waypoints and paths (computed at load / set_limits),
  // and the straight path from `from` to its first waypoint (computed now; inside the
  // margin at `from` it must not get worse). Both true without limits or without program.
  [[nodiscard]] bool program_within_limits() const noexcept { return program_ok_; }
  [[nodiscard]] bool start_within_limits(const Joints& from) const noexcept;

  // The TCP speed (mm/s) the planner allows this cycle: 0.95 x the normal limit, or the
  // reduced-mode ramp towards 0.95 x the reduced limit; +inf when nothing caps it.
  [[nodiscard]] float tcp_allowed_mm_s() const noexcept { return tcp_allow_; }
  // The same with SPEC §11's v_allowed applied (0.95 x v_allowed while SSM acts).
  [[nodiscard]] float tcp_cap_mm_s() const noexcept { return tcp_cap_; }

  // Before the supervisor runs: the measured speeds of the TCP and every link origin,
  // from measured joint positions (this sample's and the last one's, over the cycles
  // between them), and the program status. `stale`: no fresh sample this cycle (a lost or
  // late frame, the positions are the last ones held): the speeds of the last sample
  // stand, and the next fresh one is differentiated over both cycles, so a stale cycle
  // never doubles a measured speed. `sample_span` (when not negative): the cycles between
  // this sample and the last one as the drives took them (their SYNC0, hal::ProcessImageIn),
  // which a late frame makes differ from the cycles between the frames: 0 is no new sample.
  void measure(const std::array<core::DriveFeedback, kJoints>& drives, core::Feedback& fb, bool stale = false,
               std::int32_t sample_span = -1) noexcept;

  // After the supervisor ran: set-points and controlwords for this cycle.
  void step(const core::SupervisorOut& so, const std::array<core::DriveFeedback, kJoints>& drives,
            std::array<hal::DriveOut, kJoints>& out) noexcept;

  [[nodiscard]] AxisState axis_state(std::size_t i) const noexcept { return axis_[i]; }
  [[nodiscard]] const Joints& setpoint() const noexcept { return q_sp_; }
  [[nodiscard]] const Joints& setpoint_velocity() const noexcept { return v_sp_; }
  [[nodiscard]] const Joints& measured() const noexcept { return q_meas_; }
  [[nodiscard]] const Frames& frames() const noexcept { return frames_; }
  [[nodiscard]] const PointSpeeds& speeds() const noexcept { return speeds_; }
  [[nodiscard]] const ProgramExecutor& program() const noexcept { return program_; }
  [[nodiscard]] const BackOff& back_off() const noexcept { return back_off_; }

 private:
  void follow_program(const core::SupervisorOut& so) noexcept;
  void jog(const core::JogTarget& j, bool t1) noexcept;
  void ramp(float decel_fraction) noexcept;
  void limit_t1() noexcept;
  void limit_tcp() noexcept;
  void check_program() noexcept;
  void update_tcp_allow(const core::MotionRequest& r) noexcept;
  [[nodiscard]] bool stop_path_clear() const noexcept;
  void integrate(bool bounded) noexcept;
  void drive_control(const core::SupervisorOut& so, const std::array<core::DriveFeedback, kJoints>& drives,
                     std::array<hal::DriveOut, kJoints>& out) noexcept;
  void axis_states(const core::SupervisorOut& so, const std::array<core::DriveFeedback, kJoints>& drives) noexcept;

  RobotModel model_;  // a copy: the controller does not depend on the caller keeping it alive
  MotionConfig cfg_;
  ProgramExecutor program_;
  Joints q_sp_{};
  Joints v_sp_{};
  Joints q_meas_{};
  Joints q_prev_{};
  bool have_prev_ = false;
  std::uint32_t span_ = 1;  // cycles from the sample in q_prev_ to the next fresh one
  Frames frames_{};
  PointSpeeds speeds_{};
  std::array<AxisState, kJoints> axis_{};
  std::array<std::uint16_t, kJoints> last_cw_{};
  std::array<bool, kJoints> reached_enabled_{};  // reached Operation enabled in this enable
  std::array<bool, kJoints> dropped_{};          // then left it: never re-enabled by us
  Joints q_sent_{};                               // set-points written last cycle
  std::array<bool, kJoints> lagging_{};           // measured position outside the window
  std::array<bool, kJoints> quick_stopped_{};     // we commanded the drive's own quick stop
  bool watch_following_ = false;                  // last cycle commanded hold, jog or program
  std::uint8_t test_axis_ = 0;                    // SPEC §12: the axis under brake test (1..6)
  BackOff back_off_{};                            // SPEC §11 rule 8: the path, and the retrace
  bool back_off_req_ = false;                     // the last step's MotionRequest::back_off
  // SPEC §10
  LimitPlanner lim_{};
  bool limits_set_ = false;
  RobotModel plan_;                 // model_ with the joint speeds capped at 0.95 x the limits
  float tcp_allow_;                 // TCP speed allowed this cycle, mm/s (+inf: no cap)
  float tcp_ramp_down_ = 0.0F;      // mm/s per s, set at the onset of reduced mode
  bool reduced_prev_ = false;
  float red_prev_ = 0.0F;           // the reduced cap of the last cycle (a lower one ramps again)
  float tcp_cap_;                   // tcp_allow_, and SPEC §11's v_allowed: what limits this cycle
  std::span<const Waypoint> prog_{};  // the loaded program (owned by the caller)
  std::uint8_t prog_count_ = 0;
  bool program_ok_ = true;          // waypoints and paths between them
  bool first_leg_ok_ = true;        // measured position -> first waypoint
  bool first_leg_dirty_ = true;
  Joints first_leg_from_{};
};

}  // namespace safestate::motion

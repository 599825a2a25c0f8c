// An independent reference implementation of the supervisor, written as plain switch
// code from SPEC.md §3-§5 and docs/decisions.md. It shares only the vocabulary (enums,
// the input/feedback/command structs) with core/, not the transition table, the guards
// or the dispatcher, so that the checker and the fuzzer can compare the two cycle by
// cycle (a differential oracle). Not for production: clarity over speed.
#pragma once

#include <array>
#include <cstdint>

#include "safestate/core/alarms.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/interfaces.hpp"
#include "safestate/core/safety_limits.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/core/types.hpp"

namespace safestate::reference {

struct Out {
  core::State state = core::State::BOOT;
  core::Sub sub = core::Sub::NONE;
  core::StopCat stop = core::StopCat::NONE;
  bool contactor = false;
  bool drives = false;
  bool brakes_release = false;
  bool reset_lamp = false;
  bool fault_reset = false;
  core::AlarmMask alarms = 0;
  std::array<core::Reply, 20> replies{};
  std::uint8_t reply_count = 0;
  std::uint8_t brake_test_axis = 0;  // SPEC §12: the brake the test holds engaged
};

// SPEC §10 as the supervisor sees it, abstractly: the limits that the reference judges
// itself from the measured joints (range, speed), and what needs the arm's kinematics
// (zones, orientation, TCP speed), handed over as numbers each cycle (`Geometry`). From
// these the reference decides, independently of core/src/monitors/ and the core's guards,
// when a limit trips (rule 3, with SPEC §10 recovery), which alarm it raises, the reduced
// ramp, validation and the guards CONFIG_NOT_VALIDATED / OUTSIDE_LIMITS.
struct Limits {
  bool configured = false;  // without: nothing is monitored (the core without configure_limits)
  bool validated = true;    // at start (the event log's confirmation); validate_config sets it
  std::uint32_t checksum = 0;
  std::array<float, core::kAxes> min_rad{};
  std::array<float, core::kAxes> max_rad{};
  std::array<float, core::kAxes> max_speed_rad_s{};
  float tcp_max_mm_s = 0.0F;
  float reduced_tcp_max_mm_s = 0.0F;
  core::Cycle ramp = 0;  // reduced.ramp_ms in cycles
  // SPEC §11, in the reference's own terms: whether collaborative operation is on, the
  // reduced limit the outer field brings (the lower of collaborative.reduced_speed_mm_s and
  // v_pfl), the automatic resume, and SSM: the formula's parameters (the formula itself is
  // the shared pure function, pinned by its own tests), T_r in cycles and how far the
  // separation may rise in a cycle.
  bool collaborative = false;
  float field_reduced_mm_s = 0.0F;
  bool auto_resume = true;
  core::Cycle resume_delay = 0;
  bool ssm = false;
  core::SsmParams ssm_params{};
  core::Cycle reaction = 0;
  float rise_mm = 0.0F;
  // Collision detection (pfl on, every mode): the region's F_qs. The force itself needs the
  // arm's dynamics: handed over each cycle (Geometry::contact_force_n).
  bool pfl = false;
  float f_qs_n = 0.0F;
  // SPEC §12 brake test (the defaults when no configuration: none required, 500 ms, 0.5 deg)
  // and what the event log says at start.
  bool bt_required = false;          // the configuration has a `brake_test` key
  std::int64_t bt_interval = 0;      // cycles
  std::int64_t bt_overdue = 0;       // interval + grace, cycles
  core::Cycle bt_hold = 500;         // cycles per direction
  float bt_max_drift_deg = 0.5F;
  bool bt_passed_ever = false;
  std::int64_t bt_pass_age = 0;      // cycles before start
  bool bt_last_failed = false;
};

// T1 speed (SPEC §4 rule 3): the points the T1 limit is about, in the base frame (mm), as a
// forward kinematics of the measured joint positions puts them: link origins 1..5, the
// flange, the TCP. The reference differentiates them itself over the cycles between two
// samples (core::Feedback::stale, sample_clock, sample_span). `arm` false: no kinematics (the
// core without an arm): the speed is unknown.
inline constexpr std::size_t kT1Points = 7;
using Point = std::array<float, 3>;

struct Geometry {
  bool arm = false;
  std::array<Point, kT1Points> t1_points{};
  // How far the TCP sphere / link points are outside each keep_in or into each keep_out
  // zone (mm, <= 0: respected; NaN: unknown). Reduced zones are not listed here.
  std::array<float, core::kMaxZones> zone_outside{};
  std::uint8_t zones = 0;
  bool orientation = false;           // an orientation limit is configured
  float orientation_outside = -1.0F;  // cos(max deviation) - cos(angle): <= 0 inside the cone
  bool in_reduced_zone = false;       // the TCP is in a `reduced` zone
  float tcp_speed_mm_s = 0.0F;        // measured TCP speed (SPEC §10)
  float contact_force_n = 0.0F;       // SPEC §11: the external force at the TCP the torques show
};

class Supervisor {
 public:
  explicit Supervisor(const core::Timing& t, const Limits& l = Limits{}) noexcept
      : t_(t), lim_(l), validated_(!l.configured || l.validated), bt_passed_ever_(l.bt_passed_ever),
        bt_pass_at_(-l.bt_pass_age), bt_failed_(l.bt_last_failed) {}
  std::size_t step(const core::SafetyInputs& in, const core::Feedback& fb, const core::Command* cmds, std::size_t n,
                   Out& out, const Geometry& g = Geometry{}) noexcept;
  [[nodiscard]] bool validated() const noexcept { return validated_; }

 private:
  enum class St : std::uint8_t { BOOT, LOCKOUT, ESTOP, ESTOP_RESET, IDLE, ARMING, OP, STOPPING };

  void conditions(const core::SafetyInputs& in, const core::Feedback& fb, Out& out) noexcept;
  void events(const core::SafetyInputs& in, const core::Feedback& fb) noexcept;
  core::Result command(const core::SafetyInputs& in, const core::Feedback& fb, const core::Command& c,
                       bool& deferred) noexcept;
  void answer(Out& out, std::uint32_t seq, std::uint8_t id, std::uint8_t src, core::Result r) noexcept;
  void go(St s, core::Sub sub = core::Sub::NONE) noexcept;
  void stop_to(core::StopCat cat, St target, core::Sub target_sub) noexcept;
  void cat0_to(St s) noexcept;
  void raise(core::AlarmId a) noexcept;
  void drop(core::AlarmId a) noexcept;
  [[nodiscard]] bool has(core::AlarmId a) const noexcept { return (alarms_ & core::bit(a)) != 0U; }
  [[nodiscard]] bool drives_faulted(const core::Feedback& fb) const noexcept;
  // Judged on the state the cycle began in (every condition that holds raises its alarm).
  [[nodiscard]] bool drive_fault_condition(const core::Feedback& fb, St s0, core::StopCat cat0, int step0) const noexcept;
  [[nodiscard]] bool standstill() const noexcept { return quiet_ >= t_.standstill_cycles; }
  void write(Out& out) const noexcept;
  // SPEC §10, judged once per cycle before the rules (on the state the cycle began in).
  void judge_limits(const core::SafetyInputs& in, const core::Feedback& fb, const Geometry& g) noexcept;
  // SPEC §11: whether the fields and SSM act (collaborative on, mode AUTO).
  [[nodiscard]] bool collab_acts(const core::SafetyInputs& in) const noexcept {
    return lim_.configured && lim_.collaborative && in.mode == core::Mode::AUTO;
  }
  [[nodiscard]] bool person_in_inner(const core::SafetyInputs& in) const noexcept {
    return collab_acts(in) && in.field_inner_interrupted;
  }
  // SPEC §4 rule 3: this cycle's fastest T1 point (t1_speed_), from the positions handed over.
  void t1_speed(const core::Feedback& fb, const Geometry& g) noexcept;
  // SPEC §12: one cycle of the brake test (on the state the cycle began in).
  void brake_test(const core::Feedback& fb) noexcept;
  [[nodiscard]] bool bt_due() const noexcept;
  [[nodiscard]] bool bt_needed() const noexcept;

  // One position limit (a joint's range, a zone, the orientation cone): SPEC §10 recovery.
  struct Track {
    bool recovering = false;
    float best = 0.0F;
  };
  static bool trips(Track& t, float outside, bool powered, float tolerance) noexcept;

  core::Timing t_;
  Limits lim_;
  bool validated_ = true;
  std::array<Track, core::kAxes> joint_track_{};
  std::array<Track, core::kMaxZones> zone_track_{};
  Track orientation_track_{};
  // T1 speed: the points of the last sample, whether there is one, the cycles since it
  // (this one counted), and the speed judged (the last sample's until a new one comes).
  std::array<Point, kT1Points> t1_last_{};
  bool t1_have_last_ = false;
  core::Cycle t1_cycles_ = 0;
  float t1_speed_ = 0.0F;
  bool reduced_ = false;          // reduced mode active this cycle
  core::Cycle reduced_since_ = 0;
  // This cycle's verdicts.
  bool joint_hit_ = false;
  bool zone_hit_ = false;
  bool orientation_hit_ = false;
  bool speed_hit_ = false;   // with power: a speed over its limit trips
  bool speed_over_ = false;  // a speed over its limit, with power or not (the reset guard)
  bool outside_ = false;     // a position limit violated now
  float reduced_limit_ = 0.0F;  // the reduced limit of the sources active last cycle
  // SPEC §11
  bool field_paused_ = false;     // the current pause (or the Cat 2 stop to it) is rule 9's
  core::Cycle fields_clear_ = 0;  // cycles both fields have read clear
  float separation_ = 0.0F;       // the separation believed (rises at rise_mm a cycle at most)
  core::Cycle ssm_over_ = 0;      // cycles the TCP has been over v_allowed + 5 %
  bool ssm_over_now_ = false;
  bool ssm_hit_ = false;
  int collision_over_ = 0;        // cycles in a row the force was over F_qs with the arm free
  bool collision_now_ = false;    // ... two of them: rule 8's condition this cycle
  bool back_off_ = false;         // the current stop is rule 8's: it ends after the back-off
  // SPEC §12 brake test: which axis (0..5), which phase (0 engage, 1 push +, 2 push -,
  // 3 release), cycles in the phase, engaged run, position held, this cycle's outcome.
  bool bt_on_ = false;
  int bt_axis_ = 0;
  int bt_phase_ = 0;
  core::Cycle bt_n_ = 0;
  core::Cycle bt_held_ = 0;
  float bt_q0_ = 0.0F;
  float bt_drift_ = 0.0F;
  bool bt_pass_now_ = false;
  bool bt_fail_now_ = false;
  std::uint8_t bt_out_axis_ = 0;  // the brake engaged by the test this cycle
  std::uint8_t bt_cmd_axis_ = 0;  // ... as written last cycle
  bool bt_passed_ever_ = false;
  std::int64_t bt_pass_at_ = 0;
  bool bt_failed_ = false;

  St st_ = St::BOOT;
  core::Sub sub_ = core::Sub::NONE;
  core::StopCat stop_cat_ = core::StopCat::NONE;  // while STOPPING
  St stop_target_ = St::IDLE;
  core::Sub stop_target_sub_ = core::Sub::NONE;
  core::Cycle stop_elapsed_ = 0;
  bool braking_ = false;
  core::Cycle brake_elapsed_ = 0;
  int arming_step_ = 0;  // 0 contactor, 1 drives, 2 brakes
  core::Cycle arming_elapsed_ = 0;
  bool cat0_now_ = false;
  bool changed_ = false;  // a condition changed the state this cycle
  core::AlarmMask alarms_ = 0;
  std::array<core::Cycle, core::kAlarmCount> since_{};
  core::Cycle now_ = 0;
  core::Cycle quiet_ = 0;
  core::Cycle last_jog_ = 0;
  bool boot_pending_ = true;
  bool t2_ok_ = false;
  core::Mode armed_mode_ = core::Mode::NONE;
  core::Cycle resettable_since_ = 0;
  bool pending_reset_ = false;
  core::Cycle pending_since_ = 0;
  std::uint32_t pending_seq_ = 0;
  std::uint8_t pending_src_ = 0;
  // SPEC §7 feedback monitoring: last cycle's commands and how long feedback contradicts them.
  bool last_contactor_ = false;
  bool last_brakes_release_ = false;
  core::Cycle welded_for_ = 0;
  // Per brake: since when its feedback has contradicted an engage command (the first released
  // reading since it was last released on command or confirmed engaged; `released_at_` valid
  // while `released_` is set), and how many engaged readings in a row it has given since.
  std::array<bool, core::kAxes> released_{};
  std::array<core::Cycle, core::kAxes> released_at_{};
  std::array<core::Cycle, core::kAxes> engaged_run_{};
  bool brake_not_engaged_ = false;
  bool contactor_welded_ = false;
  // SPEC §14.
  core::Cycle k2_welded_for_ = 0;
  bool channel_mismatch_ = false;
  bool channel_lost_ = false;
  bool encoder_bad_ = false;
  std::array<core::Cycle, core::kAxes> enc_apart_{};
  std::array<float, core::kAxes> enc_load_{};
  std::array<float, core::kAxes> enc_motor_{};
  bool enc_seen_ = false;
};

}  // namespace safestate::reference

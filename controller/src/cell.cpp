#include "safestate/controller/cell.hpp"

#include "safestate/core/alarms.hpp"
#include "safestate/core/transitions.hpp"
#include "safestate/motion/kinematics.hpp"

namespace safestate::controller {

namespace {
constexpr std::uint32_t kIntegrityPeriodMs = 1000;
}  // namespace

Cell::Cell(const core::Config& cfg, const motion::RobotModel& model, hal::Backend& io) noexcept
    : cfg_(cfg), io_(&io), controller_(cfg, model) {
  register_platform();
  platform_.start();
  // SPEC §14 `integrity_period_ms` (1000 ms until the safety configuration carries it).
  platform_.set_period(kIntegrityPeriodMs * 1000U / cfg.cycle_us);
}

Cell::Cell(const Cell& other, hal::Backend& io) noexcept
    : cfg_(other.cfg_),
      io_(&io),
      controller_(other.controller_),
      platform_(other.platform_),
      queue_(other.queue_),
      in_(other.in_),
      out_(other.out_),
      batch_(other.batch_),
      taken_(other.taken_),
      now_(other.now_),
      view_(other.view_) {
  // The copy's own controller is its RAM under test (the references and progress are kept:
  // a fork of the checker does not repeat the start-up self-test).
  platform_.relocate(&other.controller_, &controller_, sizeof controller_);
}

void Cell::register_platform() noexcept {
  // The core's constant tables: transitions and alarms (their names' pointers included).
  static_cast<void>(platform_.add_rom(core::kTransitions.data(), sizeof core::kTransitions));
  static_cast<void>(platform_.add_rom(core::kAlarms.data(), sizeof core::kAlarms));
  // The controller (supervisor, motion layer, feedback, status) is the state under test.
  static_cast<void>(platform_.add_ram(&controller_, sizeof controller_));
}

core::Result Cell::submit(const core::Command& c) noexcept {
  if (queue_.size() >= cfg_.queue_size) {
    return core::Result::QUEUE_FULL;  // the configured capacity, inside the fixed storage
  }
  return queue_.push(c);
}

void Cell::step() noexcept {
  io_->read(in_);
  platform_.cycle();
  in_.integrity_ok = in_.integrity_ok && platform_.integrity_ok();
  in_.self_test_ok = in_.self_test_ok && platform_.self_test_ok();
  const std::size_t n = queue_.peek(batch_.data(), batch_.size());
  taken_ = controller_.step(in_, batch_.data(), n, out_);
  queue_.pop(taken_);
  io_->write(out_);
  update_view();
  ++now_;
}

std::uint8_t output_bits(const core::SupervisorOut& o) noexcept {
  return static_cast<std::uint8_t>((o.contactor ? 1U : 0U) | (o.drives_enable ? 2U : 0U) | (o.brakes_release ? 4U : 0U) |
                                   (o.reset_lamp ? 8U : 0U));
}

void Cell::update_view() noexcept {
  const motion::MotionController& m = controller_.motion();
  const core::Feedback& fb = controller_.feedback();
  const motion::Frames& f = m.frames();
  const motion::Rpy r = motion::to_rpy(f.R);
  view_.tcp = {f.tcp[0], f.tcp[1], f.tcp[2], r.roll, r.pitch, r.yaw};
  view_.tcp_speed_mm_s = fb.tcp_speed_mm_s;
  view_.max_point_speed_mm_s = fb.max_point_speed_mm_s;
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    view_.joints_rad[i] = in_.drive[i].position_rad;
    view_.velocities_rad_s[i] = in_.drive[i].velocity_rad_s;
    view_.axis_state[i] = motion::to_string(m.axis_state(i));
    view_.axis_code[i] = static_cast<std::uint8_t>(m.axis_state(i));
    view_.statusword[i] = in_.drive[i].statusword;
    view_.controlword[i] = out_.drive[i].controlword;
    view_.target_rad[i] = out_.drive[i].target_position_rad;
    view_.brake_released[i] = in_.brake_released[i];
  }
  view_.contactor_closed = in_.contactor_closed;
  view_.fieldbus_ok = in_.fieldbus_ok;
  view_.inputs_stale = in_.stale;
  view_.program_index = m.program().index();
  view_.program_length = m.program().count();
}

}  // namespace safestate::controller

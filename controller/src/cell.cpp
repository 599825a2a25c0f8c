#include "safestate/controller/cell.hpp"

#include "safestate/core/alarms.hpp"
#include "safestate/core/transitions.hpp"
#include "safestate/motion/kinematics.hpp"

namespace safestate::controller {

Cell::Cell(const core::Config& cfg, const motion::RobotModel& model, hal::Backend& io) noexcept
    : cfg_(cfg), io_(&io), controller_(cfg, model) {
  register_platform();
  platform_.start();
  // SPEC §14 `integrity_period_ms`: the whole image's CRC within it.
  platform_.set_period(static_cast<std::uint32_t>(core::to_timing(cfg).integrity_period));
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
      view_(other.view_),
      link_(nullptr),  // a fork is not paired: its partner would not be forked with it
      self_(other.self_),
      cross_(other.cross_),
      seq_(other.seq_),
      digest_(other.digest_),
      check_(other.check_),
      links_(other.links_) {
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

// @req CH-MISMATCH CH-LOST
void Cell::pair(core::Channel self, Link& link) noexcept {
  link_ = &link;
  self_ = self;
  cross_ = CrossCheck(cfg_.cross_check_cycles);
  check_ = core::ChannelCheck{};
  check_.partner = (self == core::Channel::a) ? core::Channel::b : core::Channel::a;
  controller_.set_cross_check(check_);
}

void Cell::step() noexcept {
  io_->read(in_);
  if (links_.configured()) {
    // Issue 37: the containers checked, the safety data taken from them (or the safe values).
    links_.receive(in_);
    controller_.set_link_check(links_.check());
    if (input_stage_ != nullptr) {
      input_stage_->apply(in_.safety);
    }
  }
  platform_.cycle();
  in_.integrity_ok = in_.integrity_ok && platform_.integrity_ok();
  in_.self_test_ok = in_.self_test_ok && platform_.self_test_ok();
  const std::size_t n = queue_.peek(batch_.data(), batch_.size());
  controller_.set_cross_check(check_);  // the verdict after the last cycle
  taken_ = controller_.step(in_, batch_.data(), n, out_);
  queue_.pop(taken_);
  if (link_ != nullptr) {
    // SPEC §14: this cycle's digest to the other channel, theirs compared with ours; the
    // channel that decides opens its own contactor (and the brakes) in this very cycle.
    digest_ = make_digest(seq_, now_, controller_.status());
    ++seq_;
    const CrossVerdict& v = cross_.step(digest_, *link_);
    check_.mismatch = v.mismatch;
    check_.field = v.field;
    check_.lost = v.lost;
    if (v.mismatch || v.lost) {
      out_.contactor = false;
      out_.contactor_k2 = false;
      out_.brakes_release = false;
    }
  }
  if (links_.configured()) {
    links_.transmit(out_);  // this cycle's decision, K opened above included
  }
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
  view_.k2_closed = in_.k2_closed;
  view_.two_contactors = in_.two_contactors;
  view_.fieldbus_ok = in_.fieldbus_ok;
  view_.inputs_stale = in_.stale;
  view_.program_index = m.program().index();
  view_.program_length = m.program().count();
}

}  // namespace safestate::controller

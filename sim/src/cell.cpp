#include "safestate/sim/cell.hpp"

#include "safestate/controller/controller.hpp"
#include "safestate/core/command_queue.hpp"
#include "safestate/motion/kinematics.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/sim/plant.hpp"

namespace safestate::sim {

struct Cell::Impl {
  Impl(const core::Config& c, hal::Backend* b)
      : cfg(c),
        bus(b),
        controller(c, robot::active().model),
        plant(robot::active().model, static_cast<float>(c.cycle_us) * 1.0e-6F, plant_timing(c.cycle_us), home_pose()) {
    load_demo();
  }
  void load_demo() noexcept {
    std::uint8_t n = 0;
    const motion::Waypoint* p = demo_program(n);
    controller.load_program(p, n);
  }
  core::Config cfg;
  hal::Backend* bus;  // null: the simulated plant
  controller::Controller controller;
  SimPlant plant;
  core::CommandQueue<core::kMaxQueueSize> queue;  // holds cfg.queue_size (SPEC §9: 64)
  bool jog_link_up = true;
  hal::ProcessImageIn in{};
  hal::ProcessImageOut out{};
  std::array<core::Command, core::kMaxCommandsPerCycle> batch{};
  CellView view{};
  core::Cycle now = 0;
  std::size_t taken = 0;
  Person person;
  PersonSensors person_sensors{};
  core::RawInputs person_discard{};  // with a bus: the person's devices write here, unread

  void update_view() noexcept {
    const motion::MotionController& m = controller.motion();
    const core::Feedback& fb = controller.feedback();
    const motion::Frames& f = m.frames();
    const motion::Rpy r = motion::to_rpy(f.R);
    view.tcp = {f.tcp[0], f.tcp[1], f.tcp[2], r.roll, r.pitch, r.yaw};
    view.tcp_speed_mm_s = fb.tcp_speed_mm_s;
    view.max_point_speed_mm_s = fb.max_point_speed_mm_s;
    for (std::size_t i = 0; i < core::kAxes; ++i) {
      view.joints_rad[i] = in.drive[i].position_rad;
      view.velocities_rad_s[i] = in.drive[i].velocity_rad_s;
      view.axis_state[i] = motion::to_string(m.axis_state(i));
      view.axis_code[i] = static_cast<std::uint8_t>(m.axis_state(i));
      view.statusword[i] = in.drive[i].statusword;
      view.controlword[i] = out.drive[i].controlword;
      view.target_rad[i] = out.drive[i].target_position_rad;
      view.brake_released[i] = in.brake_released[i];
    }
    view.contactor_closed = in.contactor_closed;
    view.fieldbus_ok = in.fieldbus_ok;
    view.inputs_stale = in.stale;
    view.injected = plant.injected();
    view.program_index = m.program().index();
    view.program_length = m.program().count();
  }
};

Cell::Cell(const core::Config& cfg, hal::Backend* bus) : impl_(std::make_unique<Impl>(cfg, bus)) {}
Cell::~Cell() = default;
Cell::Cell(const Cell& other) : impl_(std::make_unique<Impl>(*other.impl_)) {}

core::RawInputs& Cell::inputs() noexcept { return impl_->plant.inputs(); }
void Cell::inject(const Fault& f) noexcept {
  Impl& s = *impl_;
  s.plant.inject(f);
  if (f.kind == FaultKind::program_unload) {
    s.controller.load_program(nullptr, 0);
  } else if (f.kind == FaultKind::jog_link_drop) {
    s.jog_link_up = false;
  } else if (f.kind == FaultKind::clear_all) {
    s.jog_link_up = true;
    if (!s.controller.motion().program().loaded()) {
      s.load_demo();
    }
  }
}

core::Result Cell::submit(const core::Command& c) noexcept {
  Impl& s = *impl_;
  if (s.queue.size() >= s.cfg.queue_size) {
    return core::Result::QUEUE_FULL;  // the configured capacity, inside the fixed storage
  }
  return s.queue.push(c);
}

bool Cell::jog_link_up() const noexcept { return impl_->jog_link_up; }

void Cell::step() noexcept {
  Impl& s = *impl_;
  hal::Backend& io = (s.bus != nullptr) ? *s.bus : static_cast<hal::Backend&>(s.plant);
  io.read(s.in);
  if (s.bus != nullptr) {
    s.plant.read_platform(s.in);
  }
  // @req COL-SIM-PERSON
  // The person walks one cycle; the scanner and the distance sensor see it against the
  // arm as the motion layer computed it last cycle (from measured joints, tool included).
  s.person.advance(static_cast<float>(s.cfg.cycle_us) * 1.0e-6F);
  s.person.sense(s.person_sensors, s.controller.motion().frames(), (s.bus == nullptr) ? s.in.safety : s.person_discard,
                 s.view.person);
  const std::size_t n = s.queue.peek(s.batch.data(), s.batch.size());
  s.taken = s.controller.step(s.in, s.batch.data(), n, s.out);
  s.queue.pop(s.taken);
  io.write(s.out);
  s.update_view();
  ++s.now;
}

void Cell::configure_limits(const core::SafetyLimits& limits, bool validated) noexcept {
  impl_->controller.configure_limits(limits, validated);
  impl_->plant.set_tool(limits.payload_kg, limits.tcp_mm);  // the simulated arm carries the declared tool
}

void Cell::set_payload_fraction(float fraction) noexcept { impl_->plant.set_payload_fraction(fraction); }

void Cell::load_program(const motion::Waypoint* points, std::uint8_t count) noexcept {
  impl_->controller.load_program(points, count);
}

bool Cell::add_person(float x_mm, float y_mm, float radius_mm) noexcept {
  return impl_->person.place(x_mm, y_mm, radius_mm);
}
bool Cell::set_person_path(const PersonWaypoint* points, std::size_t count) noexcept {
  return impl_->person.walk(points, count);
}
void Cell::person_stand() noexcept { impl_->person.stand(); }
void Cell::remove_person() noexcept { impl_->person.leave(); }
bool Cell::configure_person_sensors(const PersonSensors& s) noexcept {
  if (!valid(s)) {
    return false;
  }
  impl_->person_sensors = s;
  return true;
}
const PersonSensors& Cell::person_sensors() const noexcept { return impl_->person_sensors; }
const Person& Cell::person() const noexcept { return impl_->person; }

void Cell::configure_brake_test(const core::BrakeTestHistory& history) noexcept {
  impl_->controller.configure_brake_test(history);
}

const core::SupervisorOut& Cell::out() const noexcept { return impl_->controller.status(); }
const CellView& Cell::view() const noexcept { return impl_->view; }
const core::RawInputs& Cell::raw_inputs_of_last_cycle() const noexcept { return impl_->in.safety; }
const core::SafetyInputs& Cell::safety_inputs() const noexcept { return impl_->controller.supervisor().inputs(); }
const core::Feedback& Cell::feedback() const noexcept { return impl_->controller.feedback(); }
const core::Command* Cell::commands_taken(std::size_t& n) const noexcept {
  n = impl_->taken;
  return impl_->batch.data();
}
core::Leaf Cell::leaf() const noexcept { return impl_->controller.supervisor().manager().leaf(); }
const core::AlarmSet& Cell::alarms() const noexcept { return impl_->controller.supervisor().manager().alarms(); }
core::Cycle Cell::now() const noexcept { return impl_->now; }
const core::Config& Cell::config() const noexcept { return impl_->cfg; }

}  // namespace safestate::sim

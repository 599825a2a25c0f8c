#include "safestate/sim/cell.hpp"

#include "safestate/robot/description.hpp"
#include "safestate/sim/plant.hpp"

namespace safestate::sim {

// The simulated world as the controller's backend: the plant (or, with `bus`, a real
// fieldbus, the plant then only injecting the platform faults) and the person, who walks
// one cycle and is seen against the arm as the motion layer computed it last cycle (from
// measured joints, tool included).
struct Cell::Impl final : hal::Backend {
  Impl(const core::Config& c, hal::Backend* b)
      : cfg(c),
        bus(b),
        plant(robot::active().model, static_cast<float>(c.cycle_us) * 1.0e-6F, plant_timing(c.cycle_us), home_pose()),
        core(c, robot::active().model, *this) {
    load_demo();
  }
  Impl(const Impl& o)
      : hal::Backend(),
        cfg(o.cfg),
        bus(o.bus),
        plant(o.plant),
        jog_link_up(o.jog_link_up),
        view(o.view),
        person(o.person),
        person_sensors(o.person_sensors),
        person_discard(o.person_discard),
        core(o.core, *this) {}
  Impl& operator=(const Impl&) = delete;
  ~Impl() override = default;

  void load_demo() noexcept {
    std::uint8_t n = 0;
    const motion::Waypoint* p = demo_program(n);
    core.load_program(p, n);
  }

  // @req COL-SIM-PERSON
  void read(hal::ProcessImageIn& in) noexcept override {
    if (bus != nullptr) {
      bus->read(in);
      plant.read_platform(in);
    } else {
      plant.read(in);
    }
    person.advance(static_cast<float>(cfg.cycle_us) * 1.0e-6F);
    person.sense(person_sensors, core.controller().motion().frames(), (bus == nullptr) ? in.safety : person_discard,
                 view.person);
  }
  void write(const hal::ProcessImageOut& out) noexcept override {
    if (bus != nullptr) {
      bus->write(out);
    } else {
      plant.write(out);
    }
  }

  core::Config cfg;
  hal::Backend* bus;  // null: the simulated plant
  SimPlant plant;
  bool jog_link_up = true;
  CellView view{};
  Person person;
  PersonSensors person_sensors{};
  core::RawInputs person_discard{};  // with a bus: the person's devices write here, unread
  controller::Cell core;             // last: it reads the world above through *this
};

Cell::Cell(const core::Config& cfg, hal::Backend* bus) : impl_(std::make_unique<Impl>(cfg, bus)) {}
Cell::~Cell() = default;
Cell::Cell(const Cell& other) : vocab::World(other), impl_(std::make_unique<Impl>(*other.impl_)) {}

core::RawInputs& Cell::inputs() noexcept { return impl_->plant.inputs(); }
void Cell::inject(const Fault& f) noexcept {
  Impl& s = *impl_;
  s.plant.inject(f);
  if (f.kind == FaultKind::program_unload) {
    s.core.load_program(nullptr, 0);
  } else if (f.kind == FaultKind::jog_link_drop) {
    s.jog_link_up = false;
  } else if (f.kind == FaultKind::clear_all) {
    s.jog_link_up = true;
    if (!s.core.controller().motion().program().loaded()) {
      s.load_demo();
    }
  }
}

core::Result Cell::submit(const core::Command& c) noexcept { return impl_->core.submit(c); }

bool Cell::jog_link_up() const noexcept { return impl_->jog_link_up; }
std::uint64_t Cell::injected() const noexcept { return impl_->plant.injected(); }

void Cell::step() noexcept {
  Impl& s = *impl_;
  s.core.step();
  static_cast<controller::CellView&>(s.view) = s.core.view();
  s.view.injected = s.plant.injected();
}

void Cell::configure_limits(const core::SafetyLimits& limits, bool validated) noexcept {
  impl_->core.configure_limits(limits, validated);
  impl_->plant.set_tool(limits.payload_kg, limits.tcp_mm);  // the simulated arm carries the declared tool
}

void Cell::set_payload_fraction(float fraction) noexcept { impl_->plant.set_payload_fraction(fraction); }

void Cell::load_program(const motion::Waypoint* points, std::uint8_t count) noexcept {
  impl_->core.load_program(points, count);
}

// @req COL-SIM-PERSON
vocab::PersonResult Cell::person(const vocab::PersonCommand& c) noexcept {
  const int alone = (c.stand ? 1 : 0) + (c.leave ? 1 : 0);
  if ((!c.fields && !c.at && !c.walk && alone == 0) || (alone > 0 && (c.fields || c.at || c.walk || alone > 1)) ||
      c.points > kPersonMaxWaypoints) {
    return vocab::PersonResult::invalid;  // nothing, or stand/leave with more
  }
  Impl& s = *impl_;
  if ((c.walk || c.stand || c.leave) && !c.at && !s.person.present()) {
    return vocab::PersonResult::absent;  // nobody to do it (as the scenario's `person` keys)
  }
  PersonSensors sensors = s.person_sensors;
  if (c.fields) {
    sensors.outer_mm = c.outer_mm;
    sensors.inner_mm = c.inner_mm;
    if (!valid(sensors)) {
      return vocab::PersonResult::invalid;
    }
  }
  Person trial = s.person;
  if ((c.at && !trial.place(c.x_mm, c.y_mm, c.radius_mm)) || (c.walk && !trial.walk(c.path.data(), c.points))) {
    return vocab::PersonResult::invalid;
  }
  // Every part passed on the copy: the same on the cell, in the command's order.
  s.person_sensors = sensors;
  if (c.stand) {
    s.person.stand();
  } else if (c.leave) {
    s.person.leave();
  } else {
    s.person = trial;
  }
  return vocab::PersonResult::ok;
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
  impl_->core.configure_brake_test(history);
}

const core::SupervisorOut& Cell::out() const noexcept { return impl_->core.out(); }
const CellView& Cell::view() const noexcept { return impl_->view; }
const core::RawInputs& Cell::raw_inputs_of_last_cycle() const noexcept { return impl_->core.raw_inputs_of_last_cycle(); }
const core::SafetyInputs& Cell::safety_inputs() const noexcept { return impl_->core.safety_inputs(); }
const core::Feedback& Cell::feedback() const noexcept { return impl_->core.feedback(); }
const core::Command* Cell::commands_taken(std::size_t& n) const noexcept { return impl_->core.commands_taken(n); }
core::Leaf Cell::leaf() const noexcept { return impl_->core.leaf(); }
const core::AlarmSet& Cell::alarms() const noexcept { return impl_->core.alarms(); }
core::Cycle Cell::now() const noexcept { return impl_->core.now(); }
const core::Config& Cell::config() const noexcept { return impl_->cfg; }
controller::Cell& Cell::controller() noexcept { return impl_->core; }
const controller::Cell& Cell::controller() const noexcept { return impl_->core; }

}  // namespace safestate::sim

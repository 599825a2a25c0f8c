#include "safestate/sim/cell.hpp"

#include "safestate/controller/channels.hpp"

#include <optional>
#include <random>

#include "safestate/motion/kinematics.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/sim/plant.hpp"
#include "safestate/vocab/inputs.hpp"

namespace safestate::sim {

// SPEC §14: the in-memory link between the channels of one world: a ring per direction,
// and the digest faults of the sending channel (`channel X digest corrupt|drop|repeat`).
enum class DigestFault : std::uint8_t { none, corrupt, drop, repeat };

struct DigestRing {
  static constexpr std::size_t kSize = 16;  // a stalled receiver: the oldest are lost
  std::array<controller::Digest, kSize> d{};
  std::size_t head = 0;
  std::size_t count = 0;
  void push(const controller::Digest& x) noexcept {
    if (count == kSize) {
      head = (head + 1U) % kSize;
      --count;
    }
    d[(head + count) % kSize] = x;
    ++count;
  }
  bool pop(controller::Digest& x) noexcept {
    if (count == 0U) {
      return false;
    }
    x = d[head];
    head = (head + 1U) % kSize;
    --count;
    return true;
  }
};

struct ChannelLink final : controller::Link {
  ChannelLink(DigestRing& o, DigestRing& i, const DigestFault& f) noexcept : out(&o), in(&i), fault(&f) {}
  void send(const controller::Digest& d) noexcept override {
    switch (*fault) {
      case DigestFault::none: out->push(d); break;
      case DigestFault::drop: break;
      case DigestFault::corrupt: {
        controller::Digest bad = d;
        bad.state = static_cast<std::uint8_t>(bad.state ^ 0x01U);  // the CRC no longer matches
        out->push(bad);
        break;
      }
      case DigestFault::repeat: out->push(have_last ? last : d); break;
    }
    if (!have_last || *fault != DigestFault::repeat) {
      last = d;
      have_last = true;
    }
  }
  bool receive(controller::Digest& d) noexcept override { return in->pop(d); }
  DigestRing* out;
  DigestRing* in;
  const DigestFault* fault;
  controller::Digest last{};
  bool have_last = false;
};

// A channel's own view of the world (SPEC §14 `channel X input NAME=V`): contacts it alone
// reads stuck.
struct StuckInputs final : controller::InputStage {
  std::array<bool, vocab::kContacts> stuck{};
  std::array<bool, vocab::kContacts> value{};
  void apply(core::RawInputs& raw) const noexcept override {
    for (std::size_t c = 0; c < vocab::kContacts; ++c) {
      if (stuck[c]) {
        vocab::apply(vocab::ContactWrite{static_cast<vocab::Contact>(c), value[c]}, raw);
      }
    }
  }
};

// The simulated world as the controller's backend: the plant (or, with `bus`, a real
// fieldbus, the plant then only injecting the platform faults) and the person, who walks
// one cycle and is seen against the arm as the motion layer computed it last cycle (from
// measured joints, tool included). Channel A reads the world (one world cycle per read);
// channel B (PortB) reads the image A's read took. With one channel A's write advances the
// world; with two the cell combines both channels' writes first (Cell::step).
struct Cell::Impl final : hal::Backend {
  // The world alone, its channels elsewhere (Cell::world_port).
  struct WorldPort final : hal::Backend {
    explicit WorldPort(Impl& i) noexcept : s(&i) {}
    void read(hal::ProcessImageIn& in) noexcept override {
      motion::Joints q{};
      for (std::size_t a = 0; a < hal::kAxes; ++a) {
        q[a] = s->image.drive[a].position_rad;  // last cycle's, as the controller's frames are
      }
      motion::forward(s->arm_model, q, s->arm_frames);
      s->read_world(s->image, s->arm_frames);
      in = s->image;
    }
    void write(const hal::ProcessImageOut& out) noexcept override {
      s->out_a = out;
      s->write_world(out);
      ++s->cycles;
      s->view.k2_closed = s->plant.k2_closed();
      s->view.injected = s->plant.injected();
    }
    Impl* s;
  };
  struct PortB final : hal::Backend {
    explicit PortB(Impl& i) noexcept : s(&i) {}
    void read(hal::ProcessImageIn& in) noexcept override {
      in = s->image;
      if (!s->links_active) {
        s->stuck[1].apply(in.safety);
      }
    }
    void write(const hal::ProcessImageOut& out) noexcept override { s->out_b = out; }
    Impl* s;
  };

  Impl(const core::Config& c, hal::Backend* b, std::uint8_t ch)
      : cfg(c),
        bus(b),
        channels((ch == 2U) ? 2U : 1U),
        plant(robot::active().model, static_cast<float>(c.cycle_us) * 1.0e-6F, plant_timing(c.cycle_us), home_pose()),
        core(c, robot::active().model, *this),
        port_b(*this) {
    plant.set_two_contactors(channels == 2U);
    if (channels == 2U) {
      core_b.emplace(c, robot::active().model, port_b);
      core.pair(core::Channel::a, link_a);
      core_b->pair(core::Channel::b, link_b);
    }
    if (bus != nullptr) {
      // Issue 37: on a bus with the black channel each controller checks and creates its own
      // channel's containers (a channel alone all of them); new sessions at every start.
      const std::uint16_t seed = static_cast<std::uint16_t>(std::random_device{}());
      const char* why = nullptr;
      if (core.configure_links(bus->safety_links(), seed, why) && core_b) {
        static_cast<void>(core_b->configure_links(bus->safety_links(), static_cast<std::uint16_t>(seed + 0x100U), why));
      }
      links_error = (why != nullptr) ? why : "";
      links_active = core.links().configured();
      stage_inputs();
    }
    load_demo();
  }
  Impl(const Impl& o)
      : hal::Backend(),
        cfg(o.cfg),
        bus(o.bus),
        channels(o.channels),
        plant(o.plant),
        jog_link_up(o.jog_link_up),
        view(o.view),
        person(o.person),
        person_sensors(o.person_sensors),
        person_discard(o.person_discard),
        image(o.image),
        out_a(o.out_a),
        out_b(o.out_b),
        stuck(o.stuck),
        stalled(o.stalled),
        crashed(o.crashed),
        digest_fault(o.digest_fault),
        ring_ab(o.ring_ab),
        ring_ba(o.ring_ba),
        together(o.together),
        together_alarms(o.together_alarms),
        together_leaf(o.together_leaf),
        cycles(o.cycles),
        core(o.core, *this),
        port_b(*this),
        arm_model(o.arm_model),
        arm_frames(o.arm_frames),
        black(o.black) {
    link_a.last = o.link_a.last;
    link_a.have_last = o.link_a.have_last;
    link_b.last = o.link_b.last;
    link_b.have_last = o.link_b.have_last;
    if (o.core_b) {
      core_b.emplace(*o.core_b, port_b);
      core.relink(link_a);  // the copy's own rings, its cross-checks as they were
      core_b->relink(link_b);
    }
    links_active = o.links_active;
    links_error = o.links_error;
    stage_inputs();
  }
  // With the black channel the contacts reach the channels in containers: a channel's own
  // wrong reading (`channel X input`) applies after it decoded them, in the channel.
  void stage_inputs() noexcept {
    if (links_active) {
      core.set_input_stage(&stuck[0]);
      if (core_b) {
        core_b->set_input_stage(&stuck[1]);
      }
    }
  }
  Impl& operator=(const Impl&) = delete;
  ~Impl() override = default;

  void load_demo() noexcept {
    std::uint8_t n = 0;
    const motion::Waypoint* p = demo_program(n);
    core.load_program(p, n);
    if (core_b) {
      core_b->load_program(p, n);
    }
  }

  // One cycle of the world's inputs: the field I/O and the person (seen against the arm at
  // `arm`: as channel A's motion layer computed it last cycle, or from the plant's joints).
  // @req COL-SIM-PERSON
  void read_world(hal::ProcessImageIn& in, const motion::Frames& arm) noexcept {
    if (bus != nullptr) {
      bus->read(in);
      plant.read_platform(in);
    } else {
      plant.read(in);
    }
    person.advance(static_cast<float>(cfg.cycle_us) * 1.0e-6F);
    person.sense(person_sensors, arm, (bus == nullptr) ? in.safety : person_discard, view.person);
    if (black) {
      black->to_channels(in);  // the devices' containers as the wire delivers them
    }
  }
  void read_world(hal::ProcessImageIn& in) noexcept { read_world(in, core.controller().motion().frames()); }
  void write_world(const hal::ProcessImageOut& out) noexcept {
    if (bus != nullptr) {
      bus->write(out);
    } else if (black) {
      // Issue 37: the channels' containers to the devices; the power path as the F-DO drives it.
      hal::ProcessImageOut powered{};
      black->to_devices(out, device_world(), powered);
      plant.write(powered);
    } else {
      plant.write(out);
    }
  }
  // What the simulated devices read this cycle: the world's image of this cycle (before
  // a channel's own faults), each F-DI connection's contacts with its channel's stuck
  // contacts (SPEC §14 `channel X input`: with the black channel a channel's path from the
  // terminal reads them wrong), the load-side encoders, the contactors' auxiliary contacts.
  [[nodiscard]] DeviceWorld device_world() const noexcept {
    DeviceWorld w{};
    for (std::size_t ch = 0; ch < 2U; ++ch) {
      core::RawInputs s = image.safety;
      stuck[ch].apply(s);
      w.contacts[ch] = contact_word(s, image);
    }
    for (std::size_t a = 0; a < hal::kAxes; ++a) {
      w.load_counts[a] = load_counts(image.drive[a].load_position_rad);
    }
    w.k1_closed = image.contactor_closed;
    w.k2_closed = image.k2_closed;
    return w;
  }
  // Channel A's backend.
  void read(hal::ProcessImageIn& in) noexcept override {
    read_world(image);
    in = image;
    if (!links_active) {
      stuck[0].apply(in.safety);
    }
  }
  void write(const hal::ProcessImageOut& out) noexcept override {
    out_a = out;
    if (channels == 1U) {
      write_world(out);
    }
  }

  // SPEC §14: what the world gets from two channels: the drives (set-points, controlwords)
  // from A, K1 from A, K2 from B, the brakes released only while both release them.
  [[nodiscard]] hal::ProcessImageOut combined() const noexcept { return controller::combine_outputs(out_a, out_b); }
  void update_together() noexcept;

  core::Config cfg;
  hal::Backend* bus;  // null: the simulated plant
  const char* links_error = "";  // issue 37: why the bus's safety connections were refused
  bool links_active = false;     // the controllers check the bus's containers
  std::uint8_t channels;
  SimPlant plant;
  bool jog_link_up = true;
  CellView view{};
  Person person;
  PersonSensors person_sensors{};
  core::RawInputs person_discard{};  // with a bus: the person's devices write here, unread
  hal::ProcessImageIn image{};       // the world's inputs of this cycle (before a channel's own faults)
  hal::ProcessImageOut out_a{};      // two channels: each channel's last written outputs
  hal::ProcessImageOut out_b{};
  std::array<StuckInputs, 2> stuck{};
  std::array<bool, 2> stalled{};
  std::array<bool, 2> crashed{};
  std::array<DigestFault, 2> digest_fault{};
  DigestRing ring_ab{};
  DigestRing ring_ba{};
  ChannelLink link_a{ring_ab, ring_ba, digest_fault[0]};
  ChannelLink link_b{ring_ba, ring_ab, digest_fault[1]};
  core::SupervisorOut together{};
  core::AlarmSet together_alarms{};
  core::Leaf together_leaf = core::Leaf::BOOT;
  core::Cycle cycles = 0;
  controller::Cell core;  // channel A; after the world above: it reads it through *this
  PortB port_b;
  WorldPort world_port{*this};
  motion::RobotModel arm_model = robot::active().model;  // with the declared tool (configure_limits)
  motion::Frames arm_frames{};
  std::optional<controller::Cell> core_b;  // channel B, with two channels
  std::optional<BlackChannel> black;       // issue 37, opt-in (use_black_channel)
};

// The channels together (controller::together: spec/scenario-format.md "Two channels").
void Cell::Impl::update_together() noexcept {
  static_cast<void>(controller::together({&core.out(), &core.alarms(), core.leaf()},
                                         {&core_b->out(), &core_b->alarms(), core_b->leaf()}, together,
                                         together_alarms, together_leaf));
}

Cell::Cell(const core::Config& cfg, hal::Backend* bus, std::uint8_t channels)
    : impl_(std::make_unique<Impl>(cfg, bus, channels)) {}
Cell::~Cell() = default;
Cell::Cell(const Cell& other) : vocab::World(other), impl_(std::make_unique<Impl>(*other.impl_)) {}

const char* Cell::links_error() const noexcept { return impl_->links_error; }

bool Cell::connect_links(int max_exchanges) noexcept {
  Impl& s = *impl_;
  if (s.bus == nullptr || !s.links_active) {
    return true;
  }
  for (int k = 0; k < max_exchanges; ++k) {
    hal::ProcessImageIn in{};
    s.bus->read(in);
    hal::ProcessImageIn in_b = in;
    hal::ProcessImageOut out_a{};  // every output off: nothing has run yet
    hal::ProcessImageOut out_b{};
    bool up = s.core.exchange_links(in, out_a);
    if (s.core_b) {
      up = s.core_b->exchange_links(in_b, out_b) && up;
    }
    s.bus->write(s.core_b ? controller::combine_outputs(out_a, out_b) : out_a);
    if (up) {
      return true;
    }
  }
  return false;
}

core::RawInputs& Cell::inputs() noexcept { return impl_->plant.inputs(); }
void Cell::inject(const Fault& f) noexcept {
  Impl& s = *impl_;
  s.plant.inject(f);
  const std::size_t ch = (f.axis == 2U) ? 1U : 0U;
  switch (f.kind) {  // SPEC §14: a channel's own faults (with one channel, those of A)
    case FaultKind::channel_stall: s.stalled[ch] = true; break;
    case FaultKind::channel_crash: s.crashed[ch] = true; break;
    case FaultKind::channel_input: {
      const std::size_t c = static_cast<std::size_t>(f.value >> 1U) % vocab::kContacts;
      s.stuck[ch].stuck[c] = true;
      s.stuck[ch].value[c] = (f.value & 1U) != 0U;
      break;
    }
    case FaultKind::digest_corrupt: s.digest_fault[ch] = DigestFault::corrupt; break;
    case FaultKind::digest_drop: s.digest_fault[ch] = DigestFault::drop; break;
    case FaultKind::digest_repeat: s.digest_fault[ch] = DigestFault::repeat; break;
    case FaultKind::channel_flip: static_cast<void>(flip_field(ch, f.value)); break;
    case FaultKind::clear_all:  // the channels' input faults and the link's go; a stalled or
      s.stuck = {};             // crashed channel stays so (a process does not come back)
      s.digest_fault = {};
      if (s.black) {
        s.black->clear();  // and the black channel's wire faults (a failed device stays failed)
      }
      break;
    default: break;
  }
  if (f.kind == FaultKind::program_unload) {
    s.core.load_program(nullptr, 0);
    if (s.core_b) {
      s.core_b->load_program(nullptr, 0);
    }
  } else if (f.kind == FaultKind::jog_link_drop) {
    s.jog_link_up = false;
  } else if (f.kind == FaultKind::clear_all) {
    s.jog_link_up = true;
    if (!s.core.controller().motion().program().loaded()) {
      s.load_demo();
    }
  }
}

// SPEC §14: every command to both channels (each takes it in the same cycle: lock-step); the
// answer the sender sees is A's (a result that differs is CHANNEL_MISMATCH). A crashed or
// stalled channel takes none.
// @req CH-PAIR
core::Result Cell::submit(const core::Command& c) noexcept {
  Impl& s = *impl_;
  if (s.core_b && !s.stalled[1] && !s.crashed[1]) {
    static_cast<void>(s.core_b->submit(c));
  }
  return s.core.submit(c);
}

bool Cell::jog_link_up() const noexcept { return impl_->jog_link_up; }
std::uint64_t Cell::injected() const noexcept { return impl_->plant.injected(); }

void Cell::step() noexcept {
  Impl& s = *impl_;
  ++s.cycles;
  if (s.channels == 1U) {
    if (!s.stalled[0] && !s.crashed[0]) {
      s.core.step();
    } else {
      s.read_world(s.image);  // the world goes on without its controller
      if (s.crashed[0]) {
        s.out_a = hal::ProcessImageOut{};  // a process gone: its outputs drop
      }
      s.write_world(s.out_a);  // stalled: they stay as last written
    }
  } else {
    // SPEC §14 lock-step: A reads the world and runs, B reads the same image and runs, the
    // world takes both channels' outputs. A stalled channel's outputs stay as last written,
    // a crashed one's drop (de-energised); the world's cycle goes on without them.
    if (!s.stalled[0] && !s.crashed[0]) {
      s.core.step();
    } else {
      s.read_world(s.image);
    }
    if (!s.stalled[1] && !s.crashed[1]) {
      s.core_b->step();
    }
    for (std::size_t i = 0; i < 2U; ++i) {
      if (s.crashed[i]) {
        (i == 0U ? s.out_a : s.out_b) = hal::ProcessImageOut{};
      }
    }
    s.write_world(s.combined());
    s.update_together();
  }
  static_cast<controller::CellView&>(s.view) = s.core.view();
  s.view.k2_closed = s.plant.k2_closed();
  s.view.injected = s.plant.injected();
}

void Cell::configure_limits(const core::SafetyLimits& limits, bool validated) noexcept {
  impl_->core.configure_limits(limits, validated);
  if (impl_->core_b) {
    impl_->core_b->configure_limits(limits, validated);
  }
  impl_->plant.set_tool(limits.payload_kg, limits.tcp_mm);  // the simulated arm carries the declared tool
  impl_->arm_model.tcp_offset_mm = limits.tcp_mm;
}

void Cell::set_payload_fraction(float fraction) noexcept { impl_->plant.set_payload_fraction(fraction); }

void Cell::load_program(const motion::Waypoint* points, std::uint8_t count) noexcept {
  impl_->core.load_program(points, count);
  if (impl_->core_b) {
    impl_->core_b->load_program(points, count);
  }
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
  if (impl_->core_b) {
    impl_->core_b->configure_brake_test(history);
  }
}

const core::SupervisorOut& Cell::out() const noexcept {
  return (impl_->channels == 2U) ? impl_->together : impl_->core.out();
}
const CellView& Cell::view() const noexcept { return impl_->view; }
const core::RawInputs& Cell::raw_inputs_of_last_cycle() const noexcept { return impl_->core.raw_inputs_of_last_cycle(); }
const core::SafetyInputs& Cell::safety_inputs() const noexcept { return impl_->core.safety_inputs(); }
const core::Feedback& Cell::feedback() const noexcept { return impl_->core.feedback(); }
const core::Command* Cell::commands_taken(std::size_t& n) const noexcept { return impl_->core.commands_taken(n); }
core::Leaf Cell::leaf() const noexcept {
  return (impl_->channels == 2U) ? impl_->together_leaf : impl_->core.leaf();
}
const core::AlarmSet& Cell::alarms() const noexcept {
  return (impl_->channels == 2U) ? impl_->together_alarms : impl_->core.alarms();
}
core::Cycle Cell::now() const noexcept { return impl_->cycles; }
std::uint8_t Cell::channels() const noexcept { return impl_->channels; }
const controller::Cell& Cell::channel(std::size_t i) const noexcept {
  return (i == 1U && impl_->core_b) ? *impl_->core_b : impl_->core;
}
bool Cell::channel_running(std::size_t i) const noexcept {
  const std::size_t c = (i == 1U) ? 1U : 0U;
  return !impl_->stalled[c] && !impl_->crashed[c];
}
bool Cell::k2_closed() const noexcept { return impl_->plant.k2_closed(); }
bool Cell::power_on() const noexcept { return impl_->plant.powered(); }
std::size_t Cell::supervisor_bytes() noexcept { return sizeof(core::Supervisor); }

bool Cell::flip_supervisor_bit(std::size_t channel, std::size_t byte, unsigned bit) noexcept {
  if (byte >= sizeof(core::Supervisor) || bit > 7U) {
    return false;
  }
  // The supervisor is the (non-const) controller's member in this cell's own Impl: the const
  // accessor is the only way in, on purpose.
  const core::Supervisor& s = this->channel(channel).controller().supervisor();
  auto* p = const_cast<unsigned char*>(reinterpret_cast<const unsigned char*>(&s));
  p[byte] = static_cast<unsigned char>(p[byte] ^ (1U << bit));
  return true;
}

bool Cell::use_black_channel(const char*& why) noexcept {
  Impl& s = *impl_;
  why = nullptr;
  if (s.bus != nullptr) {
    why = "the black channel is the simulated world's: this cell runs on a fieldbus";
  } else if (s.cycles != 0U) {
    why = "the black channel is set up before the first step";
  } else if (s.black) {
    why = "the black channel is already set up";
  }
  if (why != nullptr) {
    return false;
  }
  BlackChannel bc(s.cfg.cycle_us);
  // Each channel's first host session (a random number on a real start; fixed in this
  // deterministic world). Both channels take the same checked table: A's passing, B's does.
  if (!s.core.configure_links(bc.table(), 0x5A01U, why) ||
      (s.core_b && !s.core_b->configure_links(bc.table(), 0x5B01U, why))) {
    return false;
  }
  s.black.emplace(bc);
  return true;
}
const BlackChannel* Cell::black_channel() const noexcept { return impl_->black ? &*impl_->black : nullptr; }
bool Cell::inject_wire(const WireFault& f) noexcept { return impl_->black && impl_->black->inject(f); }

bool Cell::contactor_command(std::size_t i) const noexcept {
  return (i == 1U && impl_->channels == 2U) ? impl_->out_b.contactor : impl_->out_a.contactor;
}
const core::Config& Cell::config() const noexcept { return impl_->cfg; }
controller::Cell& Cell::controller() noexcept { return impl_->core; }
hal::Backend& Cell::world_port() noexcept { return impl_->world_port; }
const controller::Cell& Cell::controller() const noexcept { return impl_->core; }

}  // namespace safestate::sim

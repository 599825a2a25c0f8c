#include "safestate/robot/description.hpp"
#include "safestate/ecat/cell.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "safestate/hal/pdo_bytes.hpp"
#include "safestate/motion/kinematics.hpp"
#include "safestate/motion/robot.hpp"

namespace safestate::ecat {

namespace {

constexpr std::uint8_t kBool = 0x01;
constexpr std::uint8_t kInt16 = 0x03;
constexpr std::uint8_t kInt32 = 0x04;
constexpr std::uint8_t kUsint = 0x05;
constexpr std::uint8_t kUint16 = 0x06;
constexpr std::uint8_t kUdint = 0x07;

const char* const kDiNames[] = {"estop.a",      "estop.b",    "gate.a",      "gate.b",      "enable.a",
                                "enable.b",     "enable.panic", "mode.auto", "mode.t1",     "mode.t2",
                                "reset_button", "contactor_fb", "brake_fb.1", "brake_fb.2", "brake_fb.3",
                                "brake_fb.4",   "brake_fb.5", "brake_fb.6", "reduced.a",  "reduced.b",
                                "field.outer.a", "field.outer.b", "field.inner.a", "field.inner.b", "contactor_fb.k2"};
static_assert(std::size(kDiNames) == static_cast<std::size_t>(DiBit::contactor_fb_k2) + 1U, "one name per DI bit");
const char* const kDoNames[] = {"contactor",    "brakes_release", "reset_lamp",   "brake_hold.1", "brake_hold.2",
                                "brake_hold.3", "brake_hold.4",   "brake_hold.5", "brake_hold.6", "reduced_active",
                                "contactor_k2"};
static_assert(std::size(kDoNames) == static_cast<std::size_t>(DoBit::contactor_k2) + 1U, "one name per DO bit");

SubdeviceDesc digital_in() {
  SubdeviceDesc d{kVendorId, kProductDigitalIn, kRevision, 1, "SafeState emu DI24 safety contacts", {}, {}};
  d.tx.index = 0x1A00;
  std::uint8_t sub = 1;
  for (const char* n : kDiNames) {
    d.tx.entries.push_back({0x6000, sub++, 1, kBool, n});
  }
  d.tx.entries.push_back({0, 0, static_cast<std::uint8_t>(kDiBytes * 8U - (sub - 1U)), 0, ""});  // padding
  d.in_address = 0x1000;
  return d;
}

SubdeviceDesc digital_out() {
  SubdeviceDesc d{kVendorId, kProductDigitalOut, kRevision, 2, "SafeState emu DO3 contactor brakes lamp", {}, {}};
  d.rx.index = 0x1600;
  std::uint8_t sub = 1;
  for (const char* n : kDoNames) {
    d.rx.entries.push_back({0x7000, sub++, 1, kBool, n});
  }
  d.rx.entries.push_back({0, 0, static_cast<std::uint8_t>(kDoBytes * 8U - (sub - 1U)), 0, ""});
  d.out_address = 0x1000;
  return d;
}

// SPEC §11's distance sensor: the separation person-robot (mm, INT32) and its valid bit.
SubdeviceDesc distance_sensor() {
  SubdeviceDesc d{kVendorId, kProductDistance, kRevision, 3, "SafeState emu distance sensor", {}, {}};
  d.tx.index = 0x1A00;
  d.tx.entries = {{0x6000, 1, 32, kInt32, "separation_mm"},
                  {0x6000, 2, 1, kBool, "separation_valid"},
                  {0, 0, 7, 0, ""}};  // padding to the byte
  d.in_address = 0x1000;
  return d;
}

// Issue 37: the safe input terminal (F-DI): its contacts, the DI terminal's 32-bit word, to
// channel A and to channel B in containers of their own (0 bytes of host data each way in).
SubdeviceDesc safe_in() {
  SubdeviceDesc d{kVendorId, kProductSafeIn, kRevision, 4, "SafeState emu F-DI safety contacts", {}, {}};
  d.rx.index = 0x1600;
  add_container(d.rx, kObjToDeviceA, kSafeInHostData, 0);
  add_container(d.rx, kObjToDeviceB, kSafeInHostData, 0);
  d.tx.index = 0x1A00;
  add_container(d.tx, kObjToHostA, kSafeInDeviceData, kUdint);
  add_container(d.tx, kObjToHostB, kSafeInDeviceData, kUdint);
  d.out_address = 0x1000;
  d.in_address = 0x1100;
  return d;
}

// Issue 37: the safe output terminal (F-DO): K1 from channel A's container, K2 from channel
// B's, the brakes from both; answers with each contactor's auxiliary contact.
SubdeviceDesc safe_out() {
  SubdeviceDesc d{kVendorId, kProductSafeOut, kRevision, 5, "SafeState emu F-DO contactors brake relays", {}, {}};
  d.rx.index = 0x1600;
  add_container(d.rx, kObjToDeviceA, kSafeOutHostData, kUsint);
  add_container(d.rx, kObjToDeviceB, kSafeOutHostData, kUsint);
  d.tx.index = 0x1A00;
  add_container(d.tx, kObjToHostA, kSafeOutDeviceData, kUsint);
  add_container(d.tx, kObjToHostB, kSafeOutDeviceData, kUsint);
  d.out_address = 0x1000;
  d.in_address = 0x1100;
  return d;
}

SubdeviceDesc drive(std::size_t axis) {
  SubdeviceDesc d{kVendorId, kProductDrive, kRevision, static_cast<std::uint32_t>(10U + axis),
                  "SafeState emu CiA402 CSP drive " + std::to_string(axis), {}, {}};
  d.rx.index = 0x1600;
  d.rx.entries = {{0x6040, 0, 16, kUint16, "Controlword"},
                  {0x607A, 0, 32, kInt32, "Target position"},
                  {0x6072, 0, 16, kUint16, "Max torque"}};
  d.tx.index = 0x1A00;
  d.tx.entries = {{0x6041, 0, 16, kUint16, "Statusword"},
                  {0x6064, 0, 32, kInt32, "Position actual value"},
                  {0x606C, 0, 32, kInt32, "Velocity actual value"},
                  {0x6077, 0, 16, kInt16, "Torque actual value"},
                  {0x60E4, 1, 32, kInt32, "Additional position actual value"}};  // SPEC §14 load side
  // Issue 37: 0x60E4:01 again, to each channel in a container of its own.
  add_container(d.rx, kObjToDeviceA, kEncoderHostData, 0);
  add_container(d.rx, kObjToDeviceB, kEncoderHostData, 0);
  add_container(d.tx, kObjToHostA, kEncoderDeviceData, kInt32);
  add_container(d.tx, kObjToHostB, kEncoderDeviceData, kInt32);
  // SM0/SM1 hold the CoE mailbox at 0x1000/0x1080: the process data on SM2 and SM3.
  d.out_address = 0x1100;
  d.in_address = 0x1800;
  d.mailbox = true;
  d.device_type = 0x00020192;  // CiA 402 (0x0192), servo drive
  d.dc_sync0_required = true;  // CSP with DC: its ESI's OpMode "DC", AssignActivate 0x0300
  return d;
}

using hal::pdo::get16;
using hal::pdo::get32;
using hal::pdo::get_bit;
using hal::pdo::put16;
using hal::pdo::put32;
using hal::pdo::set_bit;
std::int32_t to_counts(float rad) noexcept {
  return static_cast<std::int32_t>(std::lround(static_cast<double>(rad) * kCountsPerRad));
}
constexpr std::size_t bit(DiBit b) { return static_cast<std::size_t>(b); }
constexpr std::size_t bit(DoBit b) { return static_cast<std::size_t>(b); }

// The drives' cycle is the plant's: 0x60C2 must equal it before they go to SAFE-OP.
std::vector<SubdeviceDesc> with_cycle(std::vector<SubdeviceDesc> devices, std::uint32_t cycle_us) {
  for (SubdeviceDesc& d : devices) {
    d.cycle_us = cycle_us;
  }
  return devices;
}

sim::PlantTiming timing(std::uint32_t cycle_us) {
  const auto cycles = [&](std::uint32_t ms) {
    const std::uint32_t c = (ms * 1000U + cycle_us - 1U) / cycle_us;
    return (c == 0U) ? 1U : c;
  };
  return sim::PlantTiming{cycles(10), cycles(60), cycles(50)};
}

}  // namespace

std::vector<SubdeviceDesc> default_segment(bool safe_terminals) {
  std::vector<SubdeviceDesc> v{digital_in(), digital_out()};
  for (std::size_t a = 1; a <= hal::kAxes; ++a) {
    v.push_back(drive(a));
  }
  v.push_back(distance_sensor());
  if (safe_terminals) {
    v.push_back(safe_in());
    v.push_back(safe_out());
  } else {
    for (SubdeviceDesc& d : v) {
      strip_containers(d);
    }
  }
  return v;
}

std::size_t position_of(const Segment& seg, std::uint32_t product) noexcept {
  for (std::size_t i = 0; i < seg.size(); ++i) {
    if (seg.esc(i).desc().product_code == product) {
      return i;
    }
  }
  return static_cast<std::size_t>(-1);
}

void pack_distance(const core::RawInputs& in, std::uint8_t* tx) noexcept {
  std::memset(tx, 0, kDistanceBytes);
  put32(tx, in.separation_mm);
  set_bit(tx, kDistanceValidBit, in.separation_valid);
}

void pack_inputs(const hal::ProcessImageIn& in, std::uint8_t* di, std::uint8_t (*drive_tx)[kDriveTxBytes]) noexcept {
  std::memset(di, 0, kDiBytes);
  const core::RawInputs& s = in.safety;
  const bool contacts[] = {s.estop_a, s.estop_b, s.gate_a, s.gate_b, s.enable_a, s.enable_b,
                           s.enable_panic, s.mode_auto, s.mode_t1, s.mode_t2, s.reset_button, in.contactor_closed};
  for (std::size_t i = 0; i < std::size(contacts); ++i) {
    set_bit(di, i, contacts[i]);
  }
  set_bit(di, bit(DiBit::reduced_a), s.reduced_a);
  set_bit(di, bit(DiBit::reduced_b), s.reduced_b);
  set_bit(di, bit(DiBit::field_outer_a), s.field_outer_a);
  set_bit(di, bit(DiBit::field_outer_b), s.field_outer_b);
  set_bit(di, bit(DiBit::field_inner_a), s.field_inner_a);
  set_bit(di, bit(DiBit::field_inner_b), s.field_inner_b);
  set_bit(di, bit(DiBit::contactor_fb_k2), in.k2_closed);
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    set_bit(di, bit(DiBit::brake_fb1) + a, in.brake_released[a]);
    put16(&drive_tx[a][0], in.drive[a].statusword);
    put32(&drive_tx[a][2], to_counts(in.drive[a].position_rad));
    put32(&drive_tx[a][6], to_counts(in.drive[a].velocity_rad_s));
    put16(&drive_tx[a][10], static_cast<std::uint16_t>(in.drive[a].torque_permille));
    put32(&drive_tx[a][12], to_counts(in.drive[a].load_position_rad));
  }
}

void pack_outputs(const hal::ProcessImageOut& out, std::uint8_t* dout, std::uint8_t (*drive_rx)[kDriveRxBytes]) noexcept {
  std::memset(dout, 0, kDoBytes);
  set_bit(dout, bit(DoBit::contactor), out.contactor);
  set_bit(dout, bit(DoBit::brakes_release), out.brakes_release);
  set_bit(dout, bit(DoBit::reset_lamp), out.reset_lamp);
  set_bit(dout, bit(DoBit::reduced_active), out.reduced_active);
  set_bit(dout, bit(DoBit::contactor_k2), out.contactor_k2);
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    set_bit(dout, bit(DoBit::brake_hold1) + a, out.brake_test_axis == a + 1U);
    put16(&drive_rx[a][0], out.drive[a].controlword);
    put32(&drive_rx[a][2], to_counts(out.drive[a].target_position_rad));
    put16(&drive_rx[a][6], out.drive[a].max_torque_permille);
  }
}

void unpack_outputs(const std::uint8_t* dout, const std::uint8_t (*drive_rx)[kDriveRxBytes],
                    hal::ProcessImageOut& out) noexcept {
  out.contactor = get_bit(dout, bit(DoBit::contactor));
  out.brakes_release = get_bit(dout, bit(DoBit::brakes_release));
  out.reset_lamp = get_bit(dout, bit(DoBit::reset_lamp));
  out.reduced_active = get_bit(dout, bit(DoBit::reduced_active));
  out.contactor_k2 = get_bit(dout, bit(DoBit::contactor_k2));
  out.brake_test_axis = 0;
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    if (out.brake_test_axis == 0U && get_bit(dout, bit(DoBit::brake_hold1) + a)) {
      out.brake_test_axis = static_cast<std::uint8_t>(a + 1U);  // the first held; the master sets one at most
    }
    out.drive[a].controlword = get16(&drive_rx[a][0]);
    out.drive[a].target_position_rad = static_cast<float>(get32(&drive_rx[a][2]) / kCountsPerRad);
    out.drive[a].max_torque_permille = get16(&drive_rx[a][6]);
  }
}

EmulatedCell::EmulatedCell(std::uint32_t cycle_us, const std::vector<SubdeviceDesc>& devices, std::uint32_t link_seed,
                           std::uint16_t link_watchdog_ms)
    : cycle_us_(cycle_us),
      plant_(safestate::robot::active().model, static_cast<float>(cycle_us) * 1.0e-6F, timing(cycle_us), sim::home_pose()),
      segment_(with_cycle(devices, cycle_us)) {
  // SPEC §14: the segment's power path is K1 and K2 in series (the DO terminal's `contactor`
  // and `contactor_k2`), each with its auxiliary contact on the DI terminal.
  plant_.set_two_contactors(true);
  segment_.on_process_data([this] { on_exchange(); });
  pos_distance_ = position_of(segment_, kProductDistance);
  links_.setup(segment_, cycle_us, link_seed, link_watchdog_ms);
  latch_inputs();
}

std::string EmulatedCell::link_fault(const std::string& words) { return links_.fault(words); }

// One cycle of the safe devices (safe_io.hpp): the master's containers as the last frame left
// them, the contacts and load-side positions as the plant holds them now.
void EmulatedCell::link_cycle(bool exchange, LinkPhase phase) noexcept {
  if (!links_.any()) {
    return;
  }
  if (phase == LinkPhase::outputs) {
    links_.outputs(segment_, in_.contactor_closed, in_.k2_closed, now_ns_, exchange);
    if (links_.take_fault_hit()) {
      timing_.fault_injected();  // `time ... from=fault`: a wire fault of a container starts it
    }
    return;
  }
  std::uint8_t di[kDiBytes];
  std::uint8_t tx[hal::kAxes][kDriveTxBytes];
  pack_inputs(in_, di, tx);
  const std::uint32_t contacts = static_cast<std::uint32_t>(di[0]) | (static_cast<std::uint32_t>(di[1]) << 8U) |
                                 (static_cast<std::uint32_t>(di[2]) << 16U) | (static_cast<std::uint32_t>(di[3]) << 24U);
  std::array<std::int32_t, hal::kAxes> load{};
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    load[a] = static_cast<std::int32_t>(get32(&tx[a][12]));
  }
  if (phase == LinkPhase::inputs) {
    links_.inputs(segment_, contacts, load, now_ns_);
  } else {
    links_.cycle(segment_, contacts, load, in_.contactor_closed, in_.k2_closed, now_ns_, exchange);
  }
  if (links_.take_fault_hit()) {
    timing_.fault_injected();  // `time ... from=fault`: a wire fault of a container starts it
  }
}

void EmulatedCell::latch_inputs() noexcept {
  plant_.read(in_);
  // @req COL-SIM-PERSON
  // The person's devices see it against the arm where the drives' positions put it.
  motion::RobotModel model = safestate::robot::active().model;
  model.tcp_offset_mm = tcp_mm_;
  motion::Joints q{};
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    q[a] = in_.drive[a].position_rad;
  }
  motion::Frames frames{};
  motion::forward(model, q, frames);
  person_.sense(person_sensors_, frames, in_.safety, person_view_);
  std::uint8_t di[kDiBytes];
  std::uint8_t tx[hal::kAxes][kDriveTxBytes];
  pack_inputs(in_, di, tx);
  segment_.esc(kPosDigitalIn).set_inputs(di);
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    segment_.esc(kPosFirstDrive + a).set_inputs(tx[a]);
  }
  if (pos_distance_ < segment_.size()) {  // a segment built without the sensor has none to feed
    std::uint8_t dist[kDistanceBytes];
    pack_distance(in_.safety, dist);
    segment_.esc(pos_distance_).set_inputs(dist);
  }
}

void EmulatedCell::step() noexcept {
  if (pacing_ == Pacing::lockstep) {
    link_cycle(false);  // lock-step: the safe devices' time is the plant's (poll())
  }
  plant_cycle(Cause::free);
}

namespace {

// SPEC §14: the power path as commanded: K1 and K2 in series, both closed.
bool powered(const hal::ProcessImageOut& out) noexcept { return out.contactor && out.contactor_k2; }

bool any_enabled(const hal::ProcessImageOut& out) noexcept {
  for (const hal::DriveOut& d : out.drive) {
    if ((d.controlword & 0x0008U) != 0U) {  // CiA 402 enable operation
      return true;
    }
  }
  return false;
}

}  // namespace

// The outputs the plant's actuators see. With the F-DO on the line (issue 37) the power path
// is its: K1 from channel A's connection, K2 from channel B's, the brakes released only with
// both brake relays; the DO terminal's contactor, contactor_k2 and brakes_release bits are
// wired to nothing, its brake_hold.N still holds axis N (docs/ethercat.md).
void EmulatedCell::unpack_held(hal::ProcessImageOut& out) noexcept {
  std::uint8_t rx[hal::kAxes][kDriveRxBytes];
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    const std::span<const std::uint8_t> o = segment_.esc(kPosFirstDrive + a).outputs();
    std::memcpy(rx[a], o.data(), kDriveRxBytes);
  }
  unpack_outputs(segment_.esc(kPosDigitalOut).outputs().data(), rx, out);
  if (links_.drives_power()) {
    out.contactor = links_.k1();
    out.contactor_k2 = links_.k2();
    out.brakes_release = links_.relay_a() && links_.relay_b();
  }
}

// A subdevice whose outputs the plant still holds active has put them in the safe state
// (its process-data watchdog expired: it left OP).
bool EmulatedCell::outputs_went_safe() const noexcept {
  if (powered(out_) && segment_.esc(kPosDigitalOut).state() != AlState::op && !links_.drives_power()) {
    return true;
  }
  if (powered(out_) && links_.drives_power() && !(links_.k1() && links_.k2())) {
    return true;  // the F-DO opened K1 or K2 by itself (a connection failed or timed out)
  }
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    if (out_.drive[a].controlword != 0U && segment_.esc(kPosFirstDrive + a).state() != AlState::op) {
      return true;
    }
  }
  return false;
}

// The subdevices' outputs as they stand, looked at between exchanges: when no process data
// comes, the time from the last exchange to the contactor output opening and the last
// drive's enable going, as their process-data watchdogs put them in the safe state.
void EmulatedCell::watch_held_outputs() noexcept {
  const bool was_closed = powered(held_);
  const bool was_enabled = any_enabled(held_);
  unpack_held(held_);
  const std::uint64_t since = (now_ns_ > last_exchange_ns_) ? now_ns_ - last_exchange_ns_ : 0U;
  if (was_closed && !powered(held_) && !drop_.contactor) {
    drop_.contactor = true;
    drop_.contactor_ns = since;
  }
  if (was_enabled && !any_enabled(held_) && !drop_.enable) {
    drop_.enable = true;
    drop_.enable_ns = since;
  }
}

void EmulatedCell::on_exchange() noexcept {
  free_running_ = false;
  const bool was_closed = powered(held_);
  // The safe output terminal takes its containers before the plant cycle (its outputs are the
  // power path's); the input terminal and the drives answer with what it sampled (below).
  link_cycle(true, LinkPhase::outputs);
  unpack_held(held_);
  time_reaction(was_closed);
  last_exchange_ns_ = now_ns_;
  if (powered(held_)) {
    drop_ = OutputDrop{};  // powered again by the master: a new measurement may start
  }
  fresh_ = (fresh_ < 0xFFFFU) ? fresh_ + 1U : fresh_;
  if (!paced_by_sync0()) {
    plant_cycle(Cause::exchange);  // lock-step, or drives synchronous to the frames
  }
  // The outputs it brought, the inputs its reply carries back (segment.cpp logical()):
  // lock-step, those of the plant cycle it ran; paced, those the last SYNC0 sampled.
  link_cycle(true, LinkPhase::inputs);  // the same sample as the DI terminal's in this frame
  timing_.exchange(exchanges_, now_ns_, held_, in_, cycle_us_);
  ++exchanges_;
}

// The set-points as the drives take them at a SYNC0 pulse: the last frame's; a pulse that
// found no new one repeats the last step once (linear extrapolation, as CSP drives with
// linear interpolation commonly do: a frame missing now and then does not make the axis stop
// and jump), then holds them. Outside OP a drive holds nothing (its outputs are safe).
void EmulatedCell::sync0_setpoints() noexcept {
  const hal::ProcessImageOut before = out_;
  unpack_held(out_);
  // More than one set-point applied at once: after a held pulse (the set-points went on while
  // the axis stood: frames late or lost), or more frames since the last pulse than the pulses
  // they were meant for, the one extrapolated pulse before making up for one of them.
  // An extrapolated pulse made up for one set-point only when it moved the axis: one that
  // repeated a zero step (after a late frame taken alone) made up for none (issue 40).
  // And a pulse that extrapolates (no new frame after one that had one) the step of a pulse
  // that took more than one: the drive repeats that step, the axis goes on as fast.
  const std::uint32_t credit = (missed_ == 1U && extrapolation_moved_) ? 1U : 0U;
  const bool repeats_multi = fresh_ == 0U && missed_ == 0U && multi_step_;
  multi_step_ = (fresh_ > 0U && (missed_ > 1U || fresh_ - credit > 1U)) || repeats_multi;
  steps_.multi_step += multi_step_ ? 1U : 0U;
  if (fresh_ > 0U) {
    missed_ = 0;
  } else if (missed_ < 0xFFU) {
    ++missed_;
  }
  bool moved = false;
  for (std::size_t a = 0; a < hal::kAxes; ++a) {
    if (segment_.esc(kPosFirstDrive + a).state() != AlState::op) {
      step_rad_[a] = 0.0F;
      continue;
    }
    if (missed_ == 1U) {
      out_.drive[a].target_position_rad = before.drive[a].target_position_rad + step_rad_[a];
      moved = moved || (step_rad_[a] != 0.0F);
    } else if (missed_ > 1U) {
      out_.drive[a].target_position_rad = before.drive[a].target_position_rad;
      step_rad_[a] = 0.0F;
    } else {
      step_rad_[a] = out_.drive[a].target_position_rad - before.drive[a].target_position_rad;
    }
  }
  extrapolation_moved_ = moved;
  steps_.extrapolated += (missed_ == 1U) ? 1U : 0U;
  steps_.held += (missed_ > 1U) ? 1U : 0U;
  fresh_ = 0;
}

void EmulatedCell::plant_cycle(Cause cause) noexcept {
  if (cause == Cause::sync0) {
    sync0_setpoints();
    ++steps_.sync0;
  } else {
    multi_step_ = false;
    unpack_held(out_);
    ++(cause == Cause::exchange ? steps_.exchange : steps_.free);
  }
  plant_.write(out_);
  person_.advance(static_cast<float>(cycle_us_) * 1.0e-6F);  // one step per plant cycle, as in-process
  ++cycles_;
  last_step_ns_ = now_ns_;
  latch_inputs();
  const float v = max_point_speed(in_, tcp_mm_);
  peak_mm_s_ = std::max(peak_mm_s_, v);
  float& peak = multi_step_ ? peak_multi_mm_s_ : peak_one_mm_s_;
  peak = std::max(peak, v);
}

void EmulatedCell::mark_input_change() noexcept {
  timing_.input_changed();
  if (powered(held_)) {
    reaction_ = Reaction{true, false, false, now_ns_, exchanges_, 0, 0, 0};
  }
}

// Called in an exchange, with the outputs it brought already unpacked and before the
// inputs it takes back are latched.
void EmulatedCell::time_reaction(bool was_closed) noexcept {
  if (!was_closed && powered(held_)) {
    reaction_ = Reaction{};  // armed again: a new measurement may start
    return;
  }
  if (reaction_.armed && !reaction_.carried && exchanges_ == reaction_.input_cycle) {
    reaction_.carried = true;
    reaction_.input_ns = now_ns_;
  }
  if (reaction_.armed && was_closed && !powered(held_) && !reaction_.cleared) {
    reaction_.cleared = true;
    reaction_.cleared_cycle = exchanges_;
    reaction_.cleared_ns = now_ns_;
  }
}

// The drive whose SYNC0 paces the plant: the first whose SYNC0 runs (all of them run on
// one system time, within their sync error).
std::size_t EmulatedCell::find_pacer() noexcept {
  for (std::size_t p = 0; p < segment_.connected(); ++p) {
    Esc& e = segment_.esc(p);
    if (e.desc().dc_sync0_required && e.sync0_running(now_ns_)) {
      return p;
    }
  }
  return kNoPacer;
}

bool EmulatedCell::paced_by_sync0() noexcept {
  const std::size_t p = (pacing_ == Pacing::paced) ? find_pacer() : kNoPacer;
  if (p != kNoPacer && pacer_ == kNoPacer) {
    const std::uint64_t k = segment_.esc(p).sync0_pulses(now_ns_);
    pulses_ = (k > 0U) ? k - 1U : 0U;  // the pulse that started it is the first step
    fresh_ = 1;
    missed_ = 0;
  }
  pacer_ = p;
  return p != kNoPacer;
}

void EmulatedCell::sync0_until(std::uint64_t now_ns) noexcept {
  now_ns_ = now_ns;
  if (!paced_by_sync0()) {
    return;
  }
  const std::uint64_t k = segment_.esc(pacer_).sync0_pulses(now_ns);
  // A host stall of a second or more is not made up pulse by pulse: the plant runs on.
  for (std::uint32_t n = 0; pulses_ < k && n < 1000U; ++n) {
    ++pulses_;
    plant_cycle(Cause::sync0);
  }
  pulses_ = std::max(pulses_, k);
}

std::uint64_t EmulatedCell::sleep_ns(std::uint64_t now_ns, std::uint64_t most_ns) noexcept {
  now_ns_ = now_ns;
  if (!paced_by_sync0()) {
    return most_ns;
  }
  return std::min(most_ns, segment_.esc(pacer_).ns_to_next_sync0(now_ns));
}

void EmulatedCell::poll(std::uint64_t now_ns) noexcept {
  now_ns_ = now_ns;
  segment_.poll(now_ns);
  // The safe devices run their own cycle while no exchange comes (their watchdogs run down),
  // in real time when paced; in lock-step (a replay, not paced in real time: it may pause
  // between two exchanges) their time is the plant's: a cycle per exchange, and per plant
  // cycle the plant runs by itself once the master fell silent (step()).
  for (std::uint32_t k = 0; pacing_ == Pacing::paced && links_.due(now_ns) && k < 1000U; ++k) {
    link_cycle(false);
  }
  watch_held_outputs();
  sync0_until(now_ns);
  if (pacer_ != kNoPacer) {
    free_running_ = false;
    return;  // the drives' SYNC0 paces the plant, frames or not
  }
  // Physics does not wait for the master: after 20 silent cycles it runs on by itself,
  // one cycle per period, with whatever outputs the subdevices hold (safe ones once
  // their watchdogs have expired); at once when a subdevice's watchdog has put outputs the
  // plant still holds active in their safe state (the contactor drops when the terminal
  // lets go of it, not 20 cycles later).
  const std::uint64_t period = static_cast<std::uint64_t>(cycle_us_) * 1000U;
  if (!free_running_ && (now_ns - last_step_ns_ > 20U * period || outputs_went_safe())) {
    free_running_ = true;
    next_free_ns_ = now_ns;
  }
  for (std::uint32_t k = 0; free_running_ && next_free_ns_ <= now_ns && k < 1000U; ++k) {
    step();
    next_free_ns_ += period;
  }
}

}  // namespace safestate::ecat

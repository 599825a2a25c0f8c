// libFuzzer target: the supervisor stepped by byte-driven histories of inputs (per
// channel), plant faults and commands (valid and malformed, from every source), with
// the safety invariants and the independent reference implementation as assertions.
// A violated invariant or a disagreement traps, and libFuzzer keeps the input.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>

#include "plant.hpp"
#include "reference.hpp"

using namespace safestate::test;
namespace ref = safestate::reference;

namespace {

struct Reader {
  const std::uint8_t* p;
  std::size_t n;
  std::uint8_t byte() {
    if (n == 0U) return 0U;
    --n;
    return *p++;
  }
};

[[noreturn]] void fail(const char* what, Cycle t) {
  std::fprintf(stderr, "fuzz_core: %s at cycle %llu\n", what, static_cast<unsigned long long>(t));
  __builtin_trap();
}

void toggle_contact(RawInputs& r, unsigned i) {
  bool* c[] = {&r.estop_a, &r.estop_b, &r.gate_a, &r.gate_b, &r.enable_a, &r.enable_b,
               &r.enable_panic, &r.mode_auto, &r.mode_t1, &r.mode_t2, &r.reset_button};
  *c[i % 11U] = !*c[i % 11U];
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Reader in{data, size};
  const Timing timing = to_timing(Config{});
  SignalLayer signals;
  SystemStateManager core(timing);
  core.configure_arm(plant_arm(), Vec3{});  // T1 speed from the core's own kinematics
  static const PreparedArm arm = prepare_arm(plant_arm());
  ref::Supervisor reference(timing);
  Plant plant;
  RawInputs raw{};
  Feedback fb{};
  SupervisorOut out{};
  ref::Out rout{};
  std::uint32_t seq = 0;
  Cycle t = 0;
  while (in.n > 0U && t < 30000U) {
    const std::uint8_t op = in.byte();
    Command cmds[4]{};
    std::size_t n = 0;
    switch (op & 31U) {
      case 0: case 1: case 2: case 3: case 4: case 5: case 6: case 7: case 8: case 9: case 10:
        toggle_contact(raw, op & 31U);
        break;
      case 11: raw.estop_a = raw.estop_b = !raw.estop_a; break;
      case 12: raw.gate_a = raw.gate_b = !raw.gate_a; break;
      case 13: raw.enable_a = raw.enable_b = !raw.enable_a; raw.enable_panic = false; break;
      case 14: {
        const unsigned m = in.byte() % 3U;
        raw.mode_auto = m == 0U;
        raw.mode_t1 = m == 1U;
        raw.mode_t2 = m == 2U;
        break;
      }
      case 15: { const unsigned i = in.byte() % 6U; plant.drive_fault[i] = !plant.drive_fault[i]; break; }
      case 16: plant.fieldbus = !plant.fieldbus; break;
      case 17: { const unsigned i = in.byte() % 6U; plant.drive_nostop[i] = !plant.drive_nostop[i]; break; }
      case 18: plant.vel[in.byte() % 6U] = static_cast<float>(static_cast<std::int8_t>(in.byte())) / 64.0F; break;
      case 19: {  // when the positions were sampled (T1 speed): held, or the drives' span
        const unsigned b = in.byte();
        fb.stale = (b & 1U) != 0U;
        fb.sample_clock = (b & 2U) != 0U;
        fb.sample_span = static_cast<std::uint16_t>(b >> 2U);
        break;
      }
      case 20: plant.program_finished = !plant.program_finished; break;
      case 21: plant.contactor_stuck_open = !plant.contactor_stuck_open; break;
      case 22: { const unsigned i = in.byte() % 6U; plant.brake_stuck[i] = !plant.brake_stuck[i]; break; }
      case 23: fb.integrity_ok = !fb.integrity_ok; break;
      default: {  // a command: id, source, arguments from the next bytes
        Command c{};
        c.seq = ++seq;
        c.id = static_cast<std::uint8_t>(in.byte() % (kCommandCount + 2U));
        const std::uint8_t s = in.byte();
        c.source = static_cast<std::uint8_t>((s & 0x80U) != 0U ? s % 6U : 0U);
        c.axis = static_cast<std::int8_t>(in.byte() % 9U);
        c.dir = static_cast<std::int8_t>(static_cast<int>(in.byte() % 3U) - 1);
        c.speed = static_cast<std::uint8_t>(in.byte() % 102U);
        c.mode = static_cast<std::uint8_t>(in.byte() % 5U);
        cmds[n++] = c;
        break;
      }
    }
    const unsigned quiet = 1U << (op >> 5U);  // 1..128 cycles until the next event
    for (unsigned k = 0; k < quiet; ++k, ++t) {
      signals.update(raw, t, timing);
      plant.fill(fb);
      const SafetyInputs& si = signals.inputs();
      const State before = out.state;
      const std::size_t a = core.step(si, fb, k == 0U ? cmds : nullptr, k == 0U ? n : 0U, out);
      ref::Geometry geo{};  // the T1 points where the plant's arm puts them, for the reference to differentiate
      JointArray q{};
      for (std::size_t i = 0; i < kAxes; ++i) q[i] = fb.drive[i].position_rad;
      ArmPose pose{};
      arm_forward(arm, q, Vec3{}, pose);
      geo.arm = true;
      for (std::size_t i = 0; i + 1U < ref::kT1Points; ++i) geo.t1_points[i] = pose.origin[i + 1U];
      geo.t1_points[ref::kT1Points - 1U] = pose.tcp;
      const std::size_t b = reference.step(si, fb, k == 0U ? cmds : nullptr, k == 0U ? n : 0U, rout, geo);
      const bool powered = out.state == State::ARMING || out.state == State::OPERATIONAL || out.state == State::STOPPING;
      const bool power = out.contactor || out.drives_enable || out.brakes_release;
      if (power && !powered) fail("power outside ARMING/OPERATIONAL/STOPPING", t);
      if (si.estop_pressed && (power || !(out.state == State::ESTOP_ACTIVE || out.state == State::ERROR_LOCKOUT))) fail("E-stop not obeyed in its cycle", t);
      if (before == State::ERROR_LOCKOUT && out.state != State::ERROR_LOCKOUT) fail("left ERROR_LOCKOUT", t);
      if (si.mode == Mode::AUTO && si.gate_open && out.sub == Sub::AUTO_RUNNING) fail("AUTO_RUNNING with the guard open", t);
      if ((out.sub == Sub::MANUAL_JOGGING || out.sub == Sub::MANUAL_RUNNING) &&
          !((si.mode == Mode::T1 || si.mode == Mode::T2) && si.enable_ok)) fail("manual motion without the enabling device", t);
      if (a != b || out.state != rout.state || out.sub != rout.sub || out.stop != rout.stop || out.alarms != rout.alarms ||
          out.contactor != rout.contactor || out.drives_enable != rout.drives || out.brakes_release != rout.brakes_release ||
          out.reset_lamp != rout.reset_lamp || out.reply_count != rout.reply_count) {
        fail("core and reference disagree", t);
      }
      for (std::size_t i = 0; i < out.reply_count; ++i) {
        if (out.replies[i].seq != rout.replies[i].seq || out.replies[i].result != rout.replies[i].result) fail("replies differ", t);
      }
      plant.follow(out);
    }
  }
  return 0;
}

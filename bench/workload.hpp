// Workloads for the benchmarks: what the supervisor sees, recorded from the real simulated
// cell, so that SafeState and the reference (tools/reference) can be timed on exactly the
// same cycles, and cycles can be replayed from any point.
//   - shift():  a typical production shift: the demo program in AUTO, started again when it
//               ends, with pauses, an E-stop now and then, and a T1 jogging session;
//   - worst():  the heaviest cycle we know: an E-stop during a Cat 1 stop, with a drive fault
//               on every axis, the reset button held and a full command queue;
//   - random(): random inputs, commands and faults (for reaching every transition row).
// Recording allocates; the measured loops do not.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "safestate/controller/controller.hpp"
#include "safestate/core/arm.hpp"
#include "safestate/core/supervisor.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::bench {

// The workloads' cells run the IRB 120 without a safety configuration: the core watches the
// arm with its own TCP (tool0). A supervisor replaying them needs the same arm (T1 speed).
inline core::ArmGeometry workload_arm() { return controller::Controller::arm_geometry(motion::kRobot); }
inline constexpr core::Vec3 kWorkloadTcp{0.0F, 0.0F, 0.0F};

// One cycle as the supervisor saw it.
struct Sample {
  core::RawInputs raw{};
  core::Feedback fb{};
  std::array<core::Command, core::kMaxCommandsPerCycle> cmds{};
  std::uint8_t n = 0;
  core::Leaf leaf_after = core::Leaf::BOOT;  // what the cell's supervisor decided (replay check)
  // Link origins 1..5, the flange, the TCP at the measured positions (the core's kinematics
  // of workload_arm()), worked out when recorded: what the reference is handed (T1 speed).
  std::array<core::Vec3, core::kAxes + 1U> t1_points{};
};
using Trace = std::vector<Sample>;

inline Sample record(const sim::Cell& cell) {
  Sample s;
  s.raw = cell.raw_inputs_of_last_cycle();
  s.fb = cell.feedback();
  core::JointArray q{};
  for (std::size_t i = 0; i < core::kAxes; ++i) {
    q[i] = s.fb.drive[i].position_rad;
  }
  core::ArmPose p{};
  core::arm_forward(workload_arm(), q, kWorkloadTcp, p);
  for (std::size_t k = 0; k < core::kAxes; ++k) {
    s.t1_points[k] = p.origin[k + 1U];
  }
  s.t1_points[core::kAxes] = p.tcp;
  std::size_t n = 0;
  const core::Command* c = cell.commands_taken(n);
  for (std::size_t i = 0; i < n && i < s.cmds.size(); ++i) {
    s.cmds[i] = c[i];
  }
  s.n = static_cast<std::uint8_t>(n);
  s.leaf_after = cell.leaf();
  return s;
}

class Driver {
 public:
  explicit Driver(sim::Cell& cell) : cell_(cell) {}
  void cmd(core::CommandId id, int axis = 0, int dir = 0, int speed = 10) {
    core::Command c{};
    c.seq = ++seq_;
    c.id = static_cast<std::uint8_t>(id);
    c.source = static_cast<std::uint8_t>(core::Source::pendant);
    c.axis = static_cast<std::int8_t>(axis);
    c.dir = static_cast<std::int8_t>(dir);
    c.speed = static_cast<std::uint8_t>(speed);
    static_cast<void>(cell_.submit(c));
  }
  Sample step() {
    cell_.step();
    return record(cell_);
  }
  // The operator keeps the cell producing: reset, servo_on, start whenever needed.
  void keep_running() {
    const core::SupervisorOut& o = cell_.out();
    if (o.state == core::State::ESTOP_RESET_NEEDED || (o.state == core::State::IDLE && o.reset_lamp)) {
      cmd(core::CommandId::reset);
    } else if (o.state == core::State::IDLE) {
      cmd(core::CommandId::servo_on);
    } else if (o.state == core::State::OPERATIONAL && o.sub == core::Sub::AUTO_IDLE) {
      cmd(core::CommandId::start);
    }
  }

 private:
  sim::Cell& cell_;
  std::uint32_t seq_ = 0;
};

// The safety configuration of the cost series "with limits" (bench_cycle full-limits): the
// Cortex-M4 bench's (tools/embedded/bench_m4.cpp) with 16 zones and a cone, every point outside
// every keep-out box, the TCP inside the keep-in box and outside the reduced one, as a cell is
// configured in practice. Written so that it compiles against older trees as well (the
// before/after comparison builds this file in both).
inline core::Zone cost_box(char tag, core::ZoneKind kind, float x, float y, float z, float half) {
  core::Zone b{};
  b.name[0] = 'z';
  b.name[1] = tag;
  b.kind = kind;
  b.min_mm = {x - half, y - half, z - half};
  b.max_mm = {x + half, y + half, z + half};
  return b;
}

inline core::SafetyLimits cost_limits() {
  core::SafetyLimits l{};
  l.checksum = 0x0B0E0C4AU;
  l.tcp_mm = {0.0F, 0.0F, 120.0F};
  l.tool_radius_mm = 40.0F;
  for (auto& j : l.joints) {
    j = core::JointLimit{-2.8F, 2.8F, 4.0F};
  }
  l.tcp_max_speed_mm_s = 2000.0F;
  l.reduced_tcp_max_speed_mm_s = 250.0F;
  l.reduced_ramp_ms = 500;
  l.orientation_enabled = true;
  l.orientation_axis = {0.0F, 0.0F, -1.0F};
  l.orientation_max_deviation_rad = 3.0F;
  for (int k = 0; k < 14; ++k) {
    const float s = (k % 2 == 0) ? 1.0F : -1.0F;
    l.zones[static_cast<std::size_t>(k)] =
        cost_box(static_cast<char>('a' + k), core::ZoneKind::keep_out, s * (900.0F + 40.0F * static_cast<float>(k)),
                 s * 300.0F, 100.0F + 20.0F * static_cast<float>(k), 100.0F);
  }
  l.zones[14] = cost_box('o', core::ZoneKind::keep_in, 0.0F, 0.0F, 500.0F, 1500.0F);
  l.zones[15] = cost_box('p', core::ZoneKind::reduced, -700.0F, 700.0F, 300.0F, 150.0F);
  l.zone_count = 16;
  return l;
}

// A production shift, five minutes that repeat: the operator's action before cycle `k`.
inline void shift_pattern(sim::Cell& cell, Driver& d, std::size_t k) {
  core::RawInputs& in = cell.inputs();
  const std::size_t s = k % 300000U;
  if (s == 60000U || s == 180000U) {
    d.cmd(core::CommandId::pause);
  } else if (s == 62000U || s == 182000U) {
    d.cmd(core::CommandId::resume);
  } else if (s == 120000U) {
    in.estop_a = in.estop_b = false;  // E-stop pressed for 1 s
  } else if (s == 121000U) {
    in.estop_a = in.estop_b = true;
  } else if (s == 240000U) {
    in.mode_auto = false;  // key to T1, a jogging session of 20 s
    in.mode_t1 = true;
  } else if (s == 241000U) {
    in.enable_a = in.enable_b = true;
  } else if (s > 241500U && s < 261000U && (s % 40U) == 0U) {
    d.cmd(core::CommandId::jog, 1 + static_cast<int>((s / 5000U) % 6U), ((s / 2500U) % 2U) != 0U ? 1 : -1, 50);
  } else if (s == 261000U) {
    d.cmd(core::CommandId::jog_stop);
  } else if (s == 262000U) {
    in.enable_a = in.enable_b = false;
  } else if (s == 263000U) {
    in.mode_t1 = false;  // back to AUTO
    in.mode_auto = true;
  } else if ((s < 240000U || s > 264000U || (s > 241000U && s < 241500U)) && (s % 50U) == 0U) {
    d.keep_running();
  }
}

// `limits`: the cell configured with them (the motion layer keeps within them, so the
// recorded positions are those of a configured cell; cost_limits() for the limits series).
inline Trace shift(std::size_t cycles, const core::SafetyLimits* limits = nullptr) {
  sim::Cell cell{core::Config{}};
  if (limits != nullptr) {
    cell.configure_limits(*limits, true);
  }
  Driver d(cell);
  Trace t;
  t.reserve(cycles);
  for (std::size_t k = 0; k < cycles; ++k) {
    shift_pattern(cell, d, k);
    t.push_back(d.step());
  }
  return t;
}

// The worst path: boot, arm, run the program, open the guard in AUTO (a Cat 1 stop with
// PROTECTIVE_STOP) with the reset button held; `kWorstPrelude` cycles later comes the worst
// cycle: E-stop pressed, every drive faulted, a full queue of commands (one malformed).
inline constexpr std::size_t kWorstPrelude = 3020;
inline void worst_prelude(sim::Cell& cell, Driver& d, std::size_t k) {
  if (k < 3000U && (k % 50U) == 0U) {
    d.keep_running();
  } else if (k == 3000U) {
    cell.inputs().gate_a = cell.inputs().gate_b = false;
    cell.inputs().reset_button = true;
  }
}
inline void worst_trigger(sim::Cell& cell, Driver& d) {
  cell.inputs().estop_a = cell.inputs().estop_b = false;
  for (std::uint8_t a = 1; a <= 6; ++a) {
    cell.inject({sim::FaultKind::drive_fault, a});
  }
  const core::CommandId ids[] = {core::CommandId::reset, core::CommandId::servo_on, core::CommandId::start,
                                 core::CommandId::jog,   core::CommandId::pause,    core::CommandId::resume,
                                 core::CommandId::stop,  core::CommandId::servo_off};
  for (core::CommandId id : ids) {
    d.cmd(id, 9, 1, 10);  // axis 9: the jog is malformed
  }
}
inline Trace worst() {
  sim::Cell cell{core::Config{}};
  Driver d(cell);
  Trace t;
  for (std::size_t k = 0; k < kWorstPrelude; ++k) {
    worst_prelude(cell, d, k);
    t.push_back(d.step());
  }
  worst_trigger(cell, d);
  t.push_back(d.step());
  return t;
}

// Program test in T1: the demo program run to its end in MANUAL_RUNNING.
inline Trace manual_program() {
  sim::Cell cell{core::Config{}};
  Driver d(cell);
  cell.inputs().mode_auto = false;
  cell.inputs().mode_t1 = true;
  Trace t;
  bool started = false;
  for (std::size_t k = 0; k < 200000U; ++k) {
    if (k == 200U) {
      cell.inputs().enable_a = cell.inputs().enable_b = true;
    }
    const core::SupervisorOut& o = cell.out();
    if ((k % 50U) == 0U) {
      if (o.state == core::State::ESTOP_RESET_NEEDED || o.state == core::State::IDLE) {
        d.keep_running();
      } else if (o.sub == core::Sub::MANUAL_IDLE && !started) {
        d.cmd(core::CommandId::start);
        started = true;
      } else if (o.sub == core::Sub::MANUAL_IDLE && started && o.state == core::State::OPERATIONAL) {
        t.push_back(d.step());
        break;  // finished
      }
    }
    t.push_back(d.step());
  }
  return t;
}

// Jogging in T1: a jog whose keep-alive stops (Cat 2, JOG_LINK_LOST), then one kept alive
// and released with jog_stop.
inline Trace manual_jog() {
  sim::Cell cell{core::Config{}};
  Driver d(cell);
  cell.inputs().mode_auto = false;
  cell.inputs().mode_t1 = true;
  Trace t;
  for (std::size_t k = 0; k < 3000U; ++k) {
    if (k == 200U) {
      cell.inputs().enable_a = cell.inputs().enable_b = true;
    } else if (k < 1000U && (k % 50U) == 0U) {
      d.keep_running();
    } else if (k == 1000U) {
      d.cmd(core::CommandId::jog, 2, 1, 20);  // no keep-alive follows: rule 7
    } else if (k >= 1500U && k < 2500U && (k % 40U) == 0U) {
      d.cmd(core::CommandId::jog, 3, -1, 20);  // kept alive
    } else if (k == 2500U) {
      d.cmd(core::CommandId::jog_stop);
    }
    t.push_back(d.step());
  }
  return t;
}

// Random inputs, commands and faults, in lives that end at a lockout (a power cycle
// starts a new cell). Each life is a separate trace.
inline std::vector<Trace> random(std::size_t cycles, std::uint32_t seed) {
  std::mt19937 rng(seed);
  const auto chance = [&](unsigned per_mille) { return (rng() % 1000U) < per_mille; };
  std::vector<Trace> lives;
  std::size_t done = 0;
  while (done < cycles) {
    sim::Cell cell{core::Config{}};
    Driver d(cell);
    Trace t;
    core::RawInputs& in = cell.inputs();
    std::size_t link_lost_until = 0;
    for (std::size_t k = 0; k < 20000U && done < cycles; ++k, ++done) {
      if (chance(2)) { in.estop_a = in.estop_b = !in.estop_a; }
      if (chance(2)) { in.gate_a = in.gate_b = !in.gate_a; }
      if (chance(4)) { in.enable_a = in.enable_b = !in.enable_a; in.enable_panic = false; }
      if (chance(1)) { in.enable_panic = !in.enable_panic; }
      if (chance(2)) {
        const auto m = static_cast<unsigned>(rng() % 3U);
        in.mode_auto = m == 0U;
        in.mode_t1 = m == 1U;
        in.mode_t2 = m == 2U;
      }
      if (chance(3)) { in.reset_button = !in.reset_button; }
      if (rng() % 100000U < 3U) { in.gate_a = !in.gate_a; }  // a lone channel: discrepancy
      if (chance(1)) { cell.inject({sim::FaultKind::drive_fault, static_cast<std::uint8_t>(1U + rng() % 6U)}); }
      if (chance(1)) { cell.inject({sim::FaultKind::clear_all, 0}); }
      if (rng() % 100000U < 5U) { cell.inject({sim::FaultKind::contactor_stuck_open, 0}); }
      if (rng() % 100000U < 5U) { cell.inject({sim::FaultKind::drive_nostop, static_cast<std::uint8_t>(1U + rng() % 6U)}); }
      if (chance(20)) { d.keep_running(); }
      if (chance(15)) {
        const auto id = static_cast<core::CommandId>(rng() % core::kCommandCount);
        d.cmd(id, 1 + static_cast<int>(rng() % 6U), chance(500) ? 1 : -1, 1 + static_cast<int>(rng() % 100U));
      }
      if (k >= link_lost_until && chance(1)) {
        link_lost_until = k + 200U;  // the pendant's link drops for 200 ms
      }
      if (cell.out().sub == core::Sub::MANUAL_JOGGING && (k % 40U) == 0U && k >= link_lost_until) {
        d.cmd(core::CommandId::jog, 1, 1, 20);  // the keep-alive
      }
      t.push_back(d.step());
      if (cell.out().state == core::State::ERROR_LOCKOUT && chance(20)) {
        break;  // power cycle
      }
    }
    lives.push_back(std::move(t));
  }
  return lives;
}

}  // namespace safestate::bench

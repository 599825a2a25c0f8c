// SPEC §14 `channel A|B flip FIELD [bit N]`: one bit of a named variable of one channel's
// supervisor, flipped as a particle hit or a stray write would. The core's classes name this
// probe a friend and nothing else of theirs changes; it is defined here, in the simulated
// world, and reached only through a scenario's fault line (never the network, never a
// controller on a real backend). The fault campaign flips any byte by offset instead
// (Cell::flip_supervisor_bit).
#include "safestate/core/supervisor.hpp"
#include "safestate/sim/cell.hpp"
#include "safestate/vocab/faults.hpp"

#include <cstring>

namespace safestate::core {

struct FieldProbe {
  struct Bytes {
    unsigned char* p;
    std::size_t n;
  };
  template <typename T>
  static Bytes of(T& x) noexcept {
    return {reinterpret_cast<unsigned char*>(&x), sizeof(T)};
  }
  static Bytes bytes(Supervisor& s, vocab::FlipField f) noexcept {
    SystemStateManager& m = s.ssm_;
    switch (f) {
      case vocab::FlipField::state: return of(m.leaf_);
      case vocab::FlipField::cycle: return of(m.now_);
      case vocab::FlipField::alarms: return of(m.alarms_.active_);
      case vocab::FlipField::mode: return of(m.armed_mode_);
      case vocab::FlipField::reset_pending: return of(m.reset_pending_);
      case vocab::FlipField::boot_pending: return of(m.boot_pending_);
      case vocab::FlipField::estop: return of(s.signals_.estop_.active_);
      case vocab::FlipField::gate: return of(s.signals_.gate_.active_);
      case vocab::FlipField::timer_reset: return of(m.reset_pending_since_);
      case vocab::FlipField::timer_jog: return of(m.last_jog_);
      case vocab::FlipField::timer_standstill: return of(m.standstill_.count_);
      case vocab::FlipField::timer_estop: return of(s.signals_.estop_.disagree_);
      case vocab::FlipField::timer_gate: return of(s.signals_.gate_.disagree_);
    }
    return {nullptr, 0U};
  }
};

}  // namespace safestate::core

namespace safestate::sim {

// @req CH-FLIP
bool Cell::flip_field(std::size_t channel, std::uint16_t value) noexcept {
  const std::size_t field = static_cast<std::size_t>(value >> 8U);
  const unsigned bit = value & 0xFFU;
  if (field >= vocab::kFlipFields.size() || bit >= vocab::kFlipFields[field].bits) {
    return false;
  }
  // The supervisor is the controller's member in this cell's own Impl: the const accessor is
  // the only way in, on purpose (as flip_supervisor_bit).
  auto& s = const_cast<core::Supervisor&>(this->channel(channel).controller().supervisor());
  const core::FieldProbe::Bytes b = core::FieldProbe::bytes(s, static_cast<vocab::FlipField>(field));
  if (b.p == nullptr || bit / 8U >= b.n) {
    return false;
  }
  // Bit N of the value: the host is little-endian (x86-64, AArch64, Cortex-M); a flag's one
  // bit is its bit 0, so a bool stays 0 or 1.
  static_assert(sizeof(bool) == 1U, "a flag is one byte");
  b.p[bit / 8U] = static_cast<unsigned char>(b.p[bit / 8U] ^ (1U << (bit % 8U)));
  return true;
}

}  // namespace safestate::sim

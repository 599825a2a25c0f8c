// `sim` records for an emulated segment: from the RT loop (never blocking) to the
// emulator's control socket (written by a non-real-time thread of `safestate run`).
#include <cstdint>
#include <string>

#include "safestate/runtime/runtime.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::runtime {

bool SimForward::push(const bridge::CommandRecord& r) noexcept {
  const std::uint32_t h = head_.load(std::memory_order_relaxed);
  if (h - tail_.load(std::memory_order_acquire) >= kSize) {
    return false;
  }
  ring_[h % kSize] = r;
  head_.store(h + 1U, std::memory_order_release);
  return true;
}

bool SimForward::pop(bridge::CommandRecord& r) noexcept {
  const std::uint32_t t = tail_.load(std::memory_order_relaxed);
  if (t == head_.load(std::memory_order_acquire)) {
    return false;
  }
  r = ring_[t % kSize];
  tail_.store(t + 1U, std::memory_order_release);
  return true;
}

namespace {

// A value in tenths as decimal text: 1234 -> "123.4", -5 -> "-0.5", 20 -> "2".
std::string tenths(std::int32_t v) {
  const bool neg = v < 0;
  const std::uint32_t a = neg ? static_cast<std::uint32_t>(-static_cast<std::int64_t>(v)) : static_cast<std::uint32_t>(v);
  std::string t = (neg ? "-" : "") + std::to_string(a / 10U);
  if (a % 10U != 0U) {
    t += "." + std::to_string(a % 10U);
  }
  return t;
}

}  // namespace

std::string sim_line(const bridge::CommandRecord& r) {
  // Contacts in the order of scenario::Contact (the bit order of set_mask).
  static const char* const kContacts[] = {"estop.a", "estop.b", "gate.a",    "gate.b",  "enable.a",    "enable.b",
                                          "enable.panic", "mode.auto", "mode.t1", "mode.t2", "reset_button",
                                          "reduced.a", "reduced.b", "field.outer.a", "field.outer.b",
                                          "field.inner.a", "field.inner.b"};
  static_assert(std::size(kContacts) == bridge::kContactCount);
  if (r.kind == bridge::RecordKind::sim_set) {
    std::string line = "in";
    for (std::size_t i = 0; i < std::size(kContacts); ++i) {
      if (((r.set_mask >> i) & 1U) != 0U) {
        line += std::string(" ") + kContacts[i] + "=" + (((r.set_values >> i) & 1U) != 0U ? "1" : "0");
      }
    }
    // The distance sensor: the emulated segment has no channel for it and refuses it (docs/ethercat.md).
    if ((r.separation_set & bridge::kSetSeparation) != 0U) {
      line += " separation_mm=" + std::to_string(r.separation_mm);
    }
    if ((r.separation_set & bridge::kSetValid) != 0U) {
      line += std::string(" separation_valid=") + (((r.separation_set & bridge::kSeparationValid) != 0U) ? "1" : "0");
    }
    return line;
  }
  if (r.kind != bridge::RecordKind::sim_fault) {
    return "";  // a command or a person: never forwarded (take_record refuses a person there)
  }
  const std::string n = std::to_string(r.fault_axis);
  switch (static_cast<sim::FaultKind>(r.fault_kind)) {
    case sim::FaultKind::drive_fault: return "fault drive " + n + " fault";
    case sim::FaultKind::drive_clear: return "fault drive " + n + " clear";
    case sim::FaultKind::drive_runaway: return "fault drive " + n + " runaway";
    case sim::FaultKind::drive_nostop: return "fault drive " + n + " nostop";
    case sim::FaultKind::fieldbus_lost: return "fault fieldbus lost";
    case sim::FaultKind::contactor_stuck_open: return "fault contactor stuck_open";
    case sim::FaultKind::brake_stuck: return "fault brake " + n + " stuck";
    case sim::FaultKind::clear_all: return "fault clear all";
    case sim::FaultKind::contactor_welded: return "fault contactor welded";
    case sim::FaultKind::brake_stuck_released: return "fault brake " + n + " stuck_released";
    case sim::FaultKind::brake_weak: return "fault brake " + n + " weak";
    // The emulator parses these with the scenario parser and its plant takes them (the same
    // sim::Plant as the in-process cell): the value back in the scenario's units.
    case sim::FaultKind::contact: return "fault contact " + tenths(static_cast<std::int32_t>(r.fault_value));
    case sim::FaultKind::drive_torque_bias:
      return "fault drive " + n + " torque_bias " +
             tenths(static_cast<std::int32_t>(static_cast<std::int16_t>(r.fault_value)));  // per mille -> %
    // The gateway does not send these (no value form in the `sim` message, or they act on the
    // core's side of the cell, not on the segment; rt_loop refuses them).
    case sim::FaultKind::integrity:
    case sim::FaultKind::selftest_fail:
    case sim::FaultKind::drive_statusword:
    case sim::FaultKind::drive_slow_enable:
    case sim::FaultKind::program_unload:
    case sim::FaultKind::jog_link_drop: break;
  }
  return "fault ?";
}

}  // namespace safestate::runtime

// `sim` records for an emulated segment: from the RT loop (never blocking) to the
// emulator's control socket (written by a non-real-time thread of `safestate run`).
#include <cstdint>
#include <string>

#include "safestate/runtime/runtime.hpp"
#include "safestate/vocab/faults.hpp"
#include "safestate/vocab/inputs.hpp"

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

std::string sim_line(const bridge::CommandRecord& r) {
  if (r.kind == bridge::RecordKind::sim_set) {
    std::string line = "in";
    for (std::size_t i = 0; i < bridge::kContactCount; ++i) {
      if (((r.set_mask >> i) & 1U) != 0U) {
        line += std::string(" ") + vocab::to_string(static_cast<vocab::Contact>(i)) + "=" +
                (((r.set_values >> i) & 1U) != 0U ? "1" : "0");
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
  // What the gateway may send (vocab::injectable, network): the emulator's plant takes it (the
  // same sim::SimPlant as the in-process cell), in the vocabulary's words and units.
  const vocab::Fault f{static_cast<vocab::FaultKind>(r.fault_kind), r.fault_axis, r.fault_value};
  if (!vocab::injectable(f.kind, vocab::FaultSource::network)) {
    return "fault ?";
  }
  return "fault " + vocab::format_fault(f);
}

}  // namespace safestate::runtime

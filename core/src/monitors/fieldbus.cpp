// SPEC §4 rule 1: after BOOT, cyclic data that stops being valid, or a drive that leaves
// the bus, locks out (FIELDBUS_LOST). The detail names the subdevice at fault (bus
// position, kFieldbusSilentFrom when no frame comes back at all), or the drive's axis.
#include "safestate/core/monitor.hpp"

namespace safestate::core {

namespace {
// FIELDBUS_LOST's detail code: the bus position of the subdevice at fault, plus
// kFieldbusSilentFrom when no frame comes back (silent from that subdevice on).
std::uint16_t fieldbus_code(const Feedback& fb) noexcept {
  const bool silent = fb.fieldbus_silent && (fb.fieldbus_subdevice != 0U);
  return static_cast<std::uint16_t>(fb.fieldbus_subdevice | (silent ? kFieldbusSilentFrom : 0U));
}
}  // namespace

void FieldbusMonitor::check(const CycleView& v, Reporter& r) noexcept {
  if (v.boot_pending && !v.facts.boot_passed) {
    return;  // BOOT's own checks (BootMonitor) judge the bus until it has passed
  }
  if (!v.fb.fieldbus_ok) {
    r.trip(AlarmId::FIELDBUS_LOST, detail_of(Signal::fieldbus, Channel::none, 0U, fieldbus_code(v.fb)));
  }
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (!v.fb.drive[i].online) {
      r.trip(AlarmId::FIELDBUS_LOST, detail_of(Signal::drive, Channel::none, static_cast<std::uint8_t>(i + 1U)));
      break;
    }
  }
}

}  // namespace safestate::core

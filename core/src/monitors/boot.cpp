// SPEC §4 rule 1, BOOT: the start-up self-test (the supervisor's own and the platform's),
// the fieldbus up, every drive answering (on the bus and past "Not ready to switch on") and
// every safety connection of the black channel up (issue 37), within boot_timeout. Passed: the `boot_passed` event (facts). Failed: BOOT_FAILED,
// at once when the self-test fails or the fieldbus cannot come up as configured, else at
// the timeout, naming the first drive that did not answer or the subdevice at fault.
#include "safestate/core/cia402.hpp"
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req TR-BOOT-FAILED
void BootMonitor::check(const CycleView& v, Reporter& r) noexcept {
  r.facts().boot_passed = false;
  if (!v.boot_pending) {
    return;
  }
  const Feedback& fb = v.fb;
  AlarmDetail why{};
  bool answered = fb.fieldbus_ok;
  for (std::size_t i = 0; i < kAxes; ++i) {
    const DriveFeedback& d = fb.drive[i];
    // A drive answers once it is on the bus and past its own initialisation
    // ("Not ready to switch on" is the drive still starting up).
    const cia402::DriveState ds = cia402::decode(d.statusword);
    if (!d.online || (ds == cia402::DriveState::Unknown) || (ds == cia402::DriveState::NotReadyToSwitchOn)) {
      if (answered) {
        why = detail_of(Signal::drive, Channel::none, static_cast<std::uint8_t>(i + 1U), d.statusword);
      }
      answered = false;
    }
  }
  // Issue 37: every safety connection of this channel up (its inputs are the safe values
  // until then); one that never came up is named at the timeout.
  if (fb.link.configured && !fb.link.up && answered) {
    why = detail_of(Signal::safety_link, fb.link.channel, static_cast<std::uint8_t>(fb.link.error), fb.link.connection);
    answered = false;
  }
  if (!fb.fieldbus_ok || fb.fieldbus_boot_failed) {
    why = detail_of(Signal::fieldbus, Channel::none, 0U, fb.fieldbus_subdevice);
  }
  const bool self_test = v.self_test_ok && fb.self_test_ok;
  if (self_test && answered && !fb.fieldbus_boot_failed) {
    r.facts().boot_passed = true;
  } else if (!self_test || fb.fieldbus_boot_failed || (v.now > v.timing.boot_timeout)) {
    r.trip(AlarmId::BOOT_FAILED, self_test ? why : detail_of(Signal::internal));
  }
}

}  // namespace safestate::core

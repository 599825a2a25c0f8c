// SPEC §3, §4 rule 3, §6: every drive's CiA 402 state decoded, unknown is a fault ("unknown
// is unsafe"); where power is expected (operational, stopping, arming's brake step) a drive
// that is not Operation enabled on its own is a fault too (a Cat 1 stop may put a lagging
// drive into its quick stop), and so is one that does not follow its set-points (the motion
// layer's following-error window). DRIVE_FAULT names the first axis; a faulted drive
// raises it in every state but BOOT, where rule 3 stops nothing.
#include "safestate/core/cia402.hpp"
#include "safestate/core/monitor.hpp"

namespace safestate::core {

// @req CIA-UNKNOWN ST-UNKNOWN-UNSAFE
void DriveMonitor::check(const CycleView& v, Reporter& r) noexcept {
  const auto* arming = std::get_if<StArming>(&v.state);
  const auto leaf_bit = static_cast<unsigned>(mask_of(v.leaf));
  const bool expect_enabled = ((leaf_bit & static_cast<unsigned>(join(kOperational, kStopping))) != 0U) ||
                              ((arming != nullptr) && (arming->step == ArmingStep::BRAKES));
  bool any_faulted = false;
  bool fault = false;
  AlarmDetail what{};
  for (std::size_t i = 0; i < kAxes; ++i) {
    const DriveFeedback& d = v.fb.drive[i];
    if (!d.online) {
      continue;  // FieldbusMonitor's
    }
    const cia402::DriveState ds = cia402::decode(d.statusword);
    const bool faulted = cia402::is_fault(ds);
    any_faulted = any_faulted || faulted;
    // In a Cat 1 stop the motion layer may put a lagging drive into its own quick stop.
    const bool quick_stop_ok = (v.leaf == Leaf::STOPPING_CAT1) && (ds == cia402::DriveState::QuickStopActive);
    const bool bad = faulted || (expect_enabled && (ds != cia402::DriveState::OperationEnabled) && !quick_stop_ok);
    if (bad && !fault) {
      fault = true;
      what = detail_of(Signal::drive, Channel::none, static_cast<std::uint8_t>(i + 1U), d.statusword);
    }
  }
  const std::uint8_t lag = v.fb.following_error_axis;
  if (expect_enabled && (lag != 0U) && !fault) {
    fault = true;
    what = detail_of(Signal::drive, Channel::none, lag, v.fb.drive[static_cast<std::size_t>(lag - 1U) % kAxes].statusword);
  }
  r.facts().any_drive_faulted = any_faulted;
  if (any_faulted && (v.leaf != Leaf::BOOT)) {
    r.raise(AlarmId::DRIVE_FAULT, what);  // every condition raises its alarm, also where rule 3 stops nothing
  }
  if (fault) {
    r.trip(AlarmId::DRIVE_FAULT, what);
  }
}

}  // namespace safestate::core

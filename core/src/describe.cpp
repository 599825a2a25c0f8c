// @req AL-CAUSE
#include "safestate/core/describe.hpp"

#include <cstdio>

namespace safestate::core {

namespace {
const char* channel_words(Channel c) noexcept {
  switch (c) {
    case Channel::a: return " channel A";
    case Channel::b: return " channel B";
    case Channel::both: return " (both channels)";
    case Channel::panic: return " (panic position)";
    case Channel::none: break;
  }
  return "";
}
}  // namespace

const char* describe(AlarmId id, const AlarmDetail& d, char* buf, std::size_t n) noexcept {
  if (buf == nullptr || n == 0U) {
    return "";
  }
  const char* ch = channel_words(d.channel);
  const unsigned axis = d.axis;
  switch (id) {
    case AlarmId::ESTOP_DISCREPANCY: std::snprintf(buf, n, "E-stop channels disagree%s", ch); break;
    case AlarmId::GATE_DISCREPANCY: std::snprintf(buf, n, "Guard channels disagree%s", ch); break;
    case AlarmId::ENABLE_DISCREPANCY: std::snprintf(buf, n, "Enabling device contacts disagree%s", ch); break;
    case AlarmId::FIELDBUS_LOST:
      if (axis != 0U) {
        std::snprintf(buf, n, "Fieldbus lost: drive %u does not answer", axis);
      } else {
        std::snprintf(buf, n, "Fieldbus lost");
      }
      break;
    case AlarmId::INTEGRITY_FAULT: std::snprintf(buf, n, "Internal integrity check failed"); break;
    case AlarmId::BOOT_FAILED:
      if (axis != 0U) {
        std::snprintf(buf, n, "Start-up failed: drive %u did not answer", axis);
      } else if (d.signal == Signal::fieldbus) {
        std::snprintf(buf, n, "Start-up failed: fieldbus not up");
      } else {
        std::snprintf(buf, n, "Start-up self-test failed");
      }
      break;
    case AlarmId::PROTECTIVE_STOP: std::snprintf(buf, n, "Guard opened in AUTO%s", ch); break;
    case AlarmId::DRIVE_FAULT:
      std::snprintf(buf, n, "Drive %u fault (statusword 0x%04X)", axis, static_cast<unsigned>(d.code));
      break;
    case AlarmId::ARMING_TIMEOUT:
      std::snprintf(buf, n, "Arming step %s timed out", d.has_step ? to_string(d.step) : "?");
      break;
    case AlarmId::T1_SPEED_EXCEEDED:
      std::snprintf(buf, n, "T1 speed exceeded at link %u (%u mm/s)", axis, static_cast<unsigned>(d.code));
      break;
    case AlarmId::STOP_TIME_EXCEEDED: std::snprintf(buf, n, "Axis %u did not stop in time", axis); break;
    case AlarmId::ESTOP_PRESSED:
      if (d.channel == Channel::a || d.channel == Channel::b) {
        std::snprintf(buf, n, "E-stop%s opened", ch);
      } else {
        std::snprintf(buf, n, "E-stop pressed");
      }
      break;
    case AlarmId::MODE_SELECTOR_INVALID: std::snprintf(buf, n, "Mode selector has no valid position"); break;
    case AlarmId::RESET_BUTTON_STUCK: std::snprintf(buf, n, "Reset button held longer than 5 s"); break;
    case AlarmId::MODE_CHANGED:
      std::snprintf(buf, n, "Mode changed to %s", to_string(static_cast<Mode>(d.code & 0x3U)));
      break;
    case AlarmId::ENABLING_PANIC: std::snprintf(buf, n, "Enabling device squeezed to panic"); break;
    case AlarmId::JOG_LINK_LOST: std::snprintf(buf, n, "Jog keep-alive lost"); break;
  }
  return buf;
}

const char* describe(const Cause& c, char* buf, std::size_t n) noexcept {
  if (buf == nullptr || n == 0U) {
    return "";
  }
  buf[0] = '\0';
  switch (c.kind) {
    case CauseKind::alarm: return describe(c.alarm, c.detail, buf, n);
    case CauseKind::command:
      std::snprintf(buf, n, "Command %s from %s", to_string(c.command), to_string(c.source));
      break;
    case CauseKind::event:
      if (c.rule == 5U) {
        std::snprintf(buf, n, "Enabling device released in %s", to_string(c.mode));
      } else {
        std::snprintf(buf, n, "Rule %u", static_cast<unsigned>(c.rule));
      }
      break;
    case CauseKind::none: break;
  }
  return buf;
}

}  // namespace safestate::core

// @req AL-CAUSE
#include "safestate/core/describe.hpp"

#include <array>
#include <span>

namespace safestate::core {

namespace {
// A bounded text writer over the caller's buffer: like snprintf (truncates, always
// terminates) without a variadic call or the C library's formatter on the controller.
class Text {
 public:
  Text(char* buf, std::size_t n) noexcept : out_(buf, n) { out_[0] = '\0'; }
  Text& s(const char* text) noexcept {
    for (std::size_t i = 0; (text != nullptr) && (text[i] != '\0'); ++i) {  // NOLINT(cppcoreguidelines-pro-bounds-pointer-arithmetic): C string
      put(text[i]);  // NOLINT(cppcoreguidelines-pro-bounds-pointer-arithmetic): C string
    }
    return *this;
  }
  Text& u(unsigned v) noexcept {
    std::array<char, 10> digits{};
    std::size_t k = 0;
    do {
      digits[k++] = static_cast<char>('0' + (v % 10U));
      v /= 10U;
    } while ((v != 0U) && (k < digits.size()));
    while (k > 0U) {
      put(digits[--k]);
    }
    return *this;
  }
  Text& hex4(unsigned v) noexcept {
    constexpr std::array<char, 16> kHex{'0', '1', '2', '3', '4', '5', '6', '7', '8', '9', 'A', 'B', 'C', 'D', 'E', 'F'};
    for (unsigned shift = 12U;; shift -= 4U) {
      put(kHex[(v >> shift) & 0xFU]);
      if (shift == 0U) {
        break;
      }
    }
    return *this;
  }
  [[nodiscard]] const char* c_str() const noexcept { return out_.data(); }

 private:
  void put(char ch) noexcept {
    if (len_ + 1U < out_.size()) {
      out_[len_] = ch;
      ++len_;
      out_[len_] = '\0';
    }
  }
  std::span<char> out_;
  std::size_t len_ = 0;
};

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
  Text t(buf, n);
  const char* ch = channel_words(d.channel);
  const unsigned axis = d.axis;
  switch (id) {
    case AlarmId::ESTOP_DISCREPANCY: t.s("E-stop channels disagree").s(ch); break;
    case AlarmId::GATE_DISCREPANCY: t.s("Guard channels disagree").s(ch); break;
    case AlarmId::ENABLE_DISCREPANCY: t.s("Enabling device contacts disagree").s(ch); break;
    case AlarmId::FIELDBUS_LOST:
      if (axis != 0U) {
        t.s("Fieldbus lost: drive ").u(axis).s(" does not answer");
      } else if ((d.code & kFieldbusSilentFrom) != 0U) {
        t.s("Fieldbus lost: no answer from subdevice ").u(d.code & 0xFFU).s(" on");  // the gateway adds names
      } else if (d.code != 0U) {
        t.s("Fieldbus lost at subdevice ").u(d.code);  // bus position; the gateway adds its name
      } else {
        t.s("Fieldbus lost");
      }
      break;
    case AlarmId::INTEGRITY_FAULT: t.s("Internal integrity check failed"); break;
    case AlarmId::BOOT_FAILED:
      if (axis != 0U) {
        t.s("Start-up failed: drive ").u(axis).s(" did not answer");
      } else if ((d.signal == Signal::fieldbus) && (d.code != 0U)) {
        t.s("Start-up failed: fieldbus not as configured at subdevice ").u(d.code);  // the gateway adds its name
      } else if (d.signal == Signal::fieldbus) {
        t.s("Start-up failed: fieldbus not up");
      } else {
        t.s("Start-up self-test failed");
      }
      break;
    case AlarmId::PROTECTIVE_STOP: t.s("Guard opened in AUTO").s(ch); break;
    case AlarmId::DRIVE_FAULT: t.s("Drive ").u(axis).s(" fault (statusword 0x").hex4(d.code).s(")"); break;
    case AlarmId::ARMING_TIMEOUT:
      t.s("Arming step ").s(d.has_step ? to_string(d.step) : "?").s(" timed out");
      if (axis != 0U) {
        t.s((d.signal == Signal::brake) ? " (brake " : " (drive ").u(axis).s(")");  // the one not there
      }
      break;
    case AlarmId::T1_SPEED_EXCEEDED:
      t.s("T1 speed exceeded at link ").u(axis).s(" (").u(d.code).s(" mm/s)");
      break;
    case AlarmId::STOP_TIME_EXCEEDED: t.s("Axis ").u(axis).s(" did not stop in time"); break;
    case AlarmId::ESTOP_PRESSED:
      if (d.channel == Channel::a || d.channel == Channel::b) {
        t.s("E-stop").s(ch).s(" opened");
      } else {
        t.s("E-stop pressed");
      }
      break;
    case AlarmId::MODE_SELECTOR_INVALID: t.s("Mode selector has no valid position"); break;
    case AlarmId::RESET_BUTTON_STUCK: t.s("Reset button held longer than 5 s"); break;
    case AlarmId::MODE_CHANGED: t.s("Mode changed to ").s(to_string(static_cast<Mode>(d.code & 0x3U))); break;
    case AlarmId::ENABLING_PANIC: t.s("Enabling device squeezed to panic"); break;
    case AlarmId::JOG_LINK_LOST: t.s("Jog keep-alive lost"); break;
    case AlarmId::CONTACTOR_WELDED:
      // SPEC §14: K1 (channel a) or K2 (channel b) of two; the one main contactor otherwise.
      t.s((d.channel == Channel::a) ? "Contactor K1" : ((d.channel == Channel::b) ? "Contactor K2" : "Main contactor"));
      t.s(" feedback still closed after open was commanded");
      break;
    case AlarmId::BRAKE_NOT_ENGAGED: t.s("Brake ").u(axis).s(" still released after engage was commanded"); break;
    case AlarmId::JOINT_LIMIT: t.s("Axis ").u(axis).s(" outside its safe range"); break;
    case AlarmId::ZONE_VIOLATION: t.s("Zone ").u(d.code + 1U).s(" violated"); break;  // the gateway adds its name
    case AlarmId::ORIENTATION_LIMIT: t.s("Tool orientation outside its permitted cone"); break;
    case AlarmId::SPEED_LIMIT:
      if (d.signal == Signal::tcp) {
        t.s("TCP speed above the safe limit (").u(d.code).s(" mm/s)");
      } else {
        t.s("Axis ").u(axis).s(" speed above its safe limit");
      }
      break;
    case AlarmId::CONFIG_NOT_VALIDATED: t.s("Safety configuration not validated"); break;
    case AlarmId::REDUCED_SPEED: t.s("Reduced speed active"); break;
    case AlarmId::FIELD_DISCREPANCY:
      t.s((d.signal == Signal::field_inner) ? "Inner" : "Outer").s(" protective field channels disagree").s(ch);
      break;
    case AlarmId::SEPARATION_VIOLATED:
      t.s("TCP faster than allowed for the separation (").u(d.code).s(" mm/s)");
      break;
    case AlarmId::PERSON_IN_FIELD: t.s("Person in the inner protective field"); break;
    case AlarmId::COLLISION: t.s("Force at the TCP ").u(d.code).s(" N, over the body region's F_qs"); break;
    case AlarmId::BRAKE_TEST_DUE: t.s("Brake test due"); break;
    case AlarmId::CHANNEL_MISMATCH:
      t.s("Safety channels disagree on ").s(to_string(static_cast<CrossField>(d.code)));
      break;
    case AlarmId::CHANNEL_LOST: t.s("Safety channel ").s((d.channel == Channel::b) ? "B" : "A").s(" lost"); break;
    case AlarmId::ENCODER_DISCREPANCY: t.s("Axis ").u(axis).s(" encoders disagree"); break;
    case AlarmId::SAFETY_LINK_FAULT:
      // Issue 37: the connection (code), its channel and what its check found (axis).
      t.s("Safety link 0x").hex4(d.code).s(" (channel ").s((d.channel == Channel::b) ? "B" : "A").s("): ");
      t.s(to_string(static_cast<LinkError>(d.axis))).s(" error");
      break;
    case AlarmId::BRAKE_TEST_FAILED: {
      // code: the drift in millidegrees (SPEC §12 names the axis and its drift).
      const unsigned frac = d.code % 1000U;
      t.s("Brake ").u(axis).s(" slipped in the brake test: drift ").u(d.code / 1000U).s(".");
      t.s((frac < 100U) ? "0" : "").s((frac < 10U) ? "0" : "").u(frac).s(" deg");
      break;
    }
  }
  return t.c_str();
}

const char* describe(const Cause& c, char* buf, std::size_t n) noexcept {
  if (buf == nullptr || n == 0U) {
    return "";
  }
  Text t(buf, n);
  switch (c.kind) {
    case CauseKind::alarm: return describe(c.alarm, c.detail, buf, n);
    case CauseKind::command: t.s("Command ").s(to_string(c.command)).s(" from ").s(to_string(c.source)); break;
    case CauseKind::event:
      if (c.rule == 5U) {
        t.s("Enabling device released in ").s(to_string(c.mode));
      } else {
        t.s("Rule ").u(c.rule);
      }
      break;
    case CauseKind::none: break;
  }
  return t.c_str();
}

// A stop without alarm is named by what asked for it (spec/scenario-format.md `cause=`).
const char* cause_name(const Cause& c) noexcept {
  switch (c.kind) {
    case CauseKind::alarm: return to_string(c.alarm);
    case CauseKind::command: return to_string(c.command);
    case CauseKind::event: return (c.rule == 5U) ? "enable_released" : "-";
    case CauseKind::none: break;
  }
  return "-";
}

// @req AL-CAUSE
const char* signal_name(const AlarmDetail& d, char* buf, std::size_t n) noexcept {
  if (buf == nullptr || n == 0U) {
    return "";
  }
  Text t(buf, n);
  const bool dual = (d.signal == Signal::estop) || (d.signal == Signal::gate) || (d.signal == Signal::enable) ||
                    (d.signal == Signal::field_outer) || (d.signal == Signal::field_inner);
  if (d.signal == Signal::none) {
    t.s("-");
  } else if (dual && (d.channel == Channel::panic)) {
    t.s("enable.panic");
  } else if (dual) {
    // Both channels at once: channel a is named, the first of the pair to be checked.
    t.s(to_string(d.signal)).s((d.channel == Channel::b) ? ".b" : ".a");
  } else if (((d.signal == Signal::drive) || (d.signal == Signal::brake) || (d.signal == Signal::axis)) &&
             (d.axis != 0U)) {
    t.s(to_string(d.signal)).s(".").u(d.axis);
  } else if (d.signal == Signal::zone) {
    t.s("zone.").u(d.code + 1U);  // limit_detail_name() gives the zone's own name
  } else if (d.signal == Signal::safety_link) {
    t.s("link.0x").hex4(d.code);  // issue 37: the connection id
  } else if (d.signal == Signal::channel) {
    // SPEC §14: the channels are named A and B (CHANNEL_LOST); none: the pair (a mismatch)
    t.s((d.channel == Channel::none) ? "channel" : ((d.channel == Channel::b) ? "B" : "A"));
  } else {
    t.s(to_string(d.signal));
  }
  return t.c_str();
}

const char* detail_name(const AlarmDetail& d, char* buf, std::size_t n) noexcept {
  if ((buf == nullptr) || (n == 0U)) {
    return "";
  }
  Text t(buf, n);
  // SPEC §14: CONTACTOR_WELDED names the contactor (k1: channel A's, k2: channel B's) when
  // there are two; CHANNEL_MISMATCH the first field of the digest that differed (its code).
  const bool one_of_two = (d.channel == Channel::a) || (d.channel == Channel::b);
  if (d.has_step) {
    t.s(to_string(d.step));
  } else if ((d.signal == Signal::contactor) && one_of_two) {
    t.s((d.channel == Channel::a) ? "k1" : "k2");
  } else if ((d.signal == Signal::channel) && (d.code != 0U)) {
    t.s(to_string(static_cast<CrossField>(d.code)));
  } else if (d.signal == Signal::safety_link) {
    // Issue 37: the connection and what its check found.
    t.s("link.0x").hex4(d.code).s(".").s(to_string(static_cast<LinkError>(d.axis)));
  } else {
    return signal_name(d, buf, n);
  }
  return t.c_str();
}

}  // namespace safestate::core

#include "safestate/vocab/faults.hpp"

#include "safestate/vocab/inputs.hpp"

#include <array>
#include <cmath>
#include <utility>

namespace safestate::vocab {

bool injectable(FaultKind k, FaultSource from) noexcept {
  if (static_cast<std::uint8_t>(k) >= kFaultKinds) {
    return false;
  }
  if (from == FaultSource::local) {
    return true;
  }
  // What a person could do to the plant: no channel, digest or platform faults from the network.
  return static_cast<std::uint8_t>(k) <= static_cast<std::uint8_t>(FaultKind::clear_all) || k == FaultKind::brake_weak ||
         k == FaultKind::contact || k == FaultKind::drive_torque_bias || k == FaultKind::encoder_stuck ||
         k == FaultKind::encoder_offset || k == FaultKind::encoder_drift;
}

namespace {

bool parse_drive_fault(const Tokens& a, Fault& f) noexcept {
  if (a.size() != 3 || a[0] != "drive" || !axis_1_to_6(a[1], f.axis)) {
    return false;
  }
  constexpr std::array<std::pair<std::string_view, FaultKind>, 4> kinds{{
      {"fault", FaultKind::drive_fault},
      {"clear", FaultKind::drive_clear},
      {"runaway", FaultKind::drive_runaway},
      {"nostop", FaultKind::drive_nostop},
  }};
  for (const auto& [word, kind] : kinds) {
    if (a[2] == word) {
      f.kind = kind;
      return true;
    }
  }
  return false;
}

// drive N statusword 0xHHHH | drive N slow_enable MS
bool parse_drive_word_fault(const Tokens& a, Fault& f) noexcept {
  if (a.size() != 4 || a[0] != "drive" || !axis_1_to_6(a[1], f.axis)) {
    return false;
  }
  if (a[2] == "statusword" && hex_word(a[3], f.value)) {
    f.kind = FaultKind::drive_statusword;
    return true;
  }
  std::uint16_t ms = 0;
  if (a[2] == "slow_enable" && to_number(a[3], ms) && ms >= 1U && ms <= 60000U) {
    f.kind = FaultKind::drive_slow_enable;
    f.value = ms;
    return true;
  }
  return false;
}

std::string line_of(const Tokens& a) {
  std::string written;
  for (const std::string_view w : a) {
    written += (written.empty() ? "" : " ") + std::string(w);
  }
  return written;
}

// SPEC §11: `contact F` (N, 0..5000, 0 removes the surface), `drive N torque_bias X` (% of
// rated torque, -300..300). "?" when the line is neither; a bad number names itself.
Problem parse_collision_fault(const Tokens& a, Fault& f) {
  double x = 0.0;
  if (a.size() == 2 && a[0] == "contact") {
    if (!to_real(a[1], x) || x < 0.0 || x > kMaxContactN) {
      return "bad contact force \"" + std::string(a[1]) + "\" in fault \"" + line_of(a) +
             "\" (expected a number of newtons 0..5000)";
    }
    f = Fault{FaultKind::contact, 0, static_cast<std::uint16_t>(std::lround(x * 10.0))};
    return {};
  }
  if (a.size() == 4 && a[0] == "drive" && a[2] == "torque_bias") {
    std::uint8_t axis = 0;
    if (!axis_1_to_6(a[1], axis)) {
      return "bad drive \"" + std::string(a[1]) + "\" in fault \"" + line_of(a) + "\" (expected 1..6)";
    }
    if (!to_real(a[3], x) || x < -kMaxTorqueBiasPct || x > kMaxTorqueBiasPct) {
      return "bad torque bias \"" + std::string(a[3]) + "\" in fault \"" + line_of(a) +
             "\" (expected a percentage of rated torque -300..300)";
    }
    const auto permille = static_cast<std::int16_t>(std::lround(x * 10.0));
    f = Fault{FaultKind::drive_torque_bias, axis, static_cast<std::uint16_t>(permille)};  // two's complement
    return {};
  }
  return "?";
}

// SPEC §14: `channel A|B stall|crash`, `channel A|B input NAME=V`, `channel A|B digest
// corrupt|drop|repeat`, `contactor k1|k2 welded|stuck_open`, `encoder N stuck`, `encoder N
// offset DEG`, `encoder N drift DEG_S`. "?" when the line is none of them.
Problem parse_two_channel_fault(const Tokens& a, Fault& f) {
  if (a.size() >= 3 && a[0] == "channel") {
    std::uint8_t ch = 0;
    if (a[1] == "A") {
      ch = 1;
    } else if (a[1] == "B") {
      ch = 2;
    } else {
      return "bad channel \"" + std::string(a[1]) + "\" in fault \"" + line_of(a) + "\" (expected A or B)";
    }
    if (a.size() == 3 && (a[2] == "stall" || a[2] == "crash")) {
      f = Fault{(a[2] == "stall") ? FaultKind::channel_stall : FaultKind::channel_crash, ch, 0};
      return {};
    }
    if (a.size() == 4 && a[2] == "digest") {
      constexpr std::array<std::pair<std::string_view, FaultKind>, 3> kinds{{
          {"corrupt", FaultKind::digest_corrupt}, {"drop", FaultKind::digest_drop}, {"repeat", FaultKind::digest_repeat}}};
      for (const auto& [word, kind] : kinds) {
        if (a[3] == word) {
          f = Fault{kind, ch, 0};
          return {};
        }
      }
      return "bad digest fault \"" + std::string(a[3]) + "\" in fault \"" + line_of(a) + "\" (expected corrupt, drop or repeat)";
    }
    if (a.size() == 4 && a[2] == "input") {
      const std::string_view kv = a[3];
      const std::size_t eq = kv.find('=');
      InputStep step;
      if (eq == std::string_view::npos || !parse_input(kv.substr(0, eq), kv.substr(eq + 1U), step).empty() ||
          step.writes.size() != 1U || step.separation_mm || step.separation_valid) {
        return "bad input \"" + std::string(kv) + "\" in fault \"" + line_of(a) +
               "\" (expected one raw contact NAME=0|1: estop.a ... field.inner.b, reset_button, mode.auto ...)";
      }
      const ContactWrite w = step.writes.front();
      f = Fault{FaultKind::channel_input, ch,
                static_cast<std::uint16_t>((static_cast<unsigned>(w.contact) << 1U) | (w.closed ? 1U : 0U))};
      return {};
    }
    if ((a.size() == 4 || a.size() == 6) && a[2] == "flip") {
      std::size_t field = kFlipFields.size();
      for (std::size_t i = 0; i < kFlipFields.size(); ++i) {
        if (a[3] == kFlipFields[i].name) {
          field = i;
        }
      }
      if (field == kFlipFields.size()) {
        std::string names;
        for (const FlipFieldInfo& x : kFlipFields) {
          names += (names.empty() ? "" : ", ") + std::string(x.name);
        }
        return "bad field \"" + std::string(a[3]) + "\" in fault \"" + line_of(a) + "\" (expected " + names + ")";
      }
      std::uint16_t bit = 0;
      if (a.size() == 6 && (a[4] != "bit" || !to_number(a[5], bit) || bit >= kFlipFields[field].bits)) {
        return "bad bit \"" + std::string(a[4]) + " " + std::string(a[5]) + "\" in fault \"" + line_of(a) +
               "\" (expected bit 0.." + std::to_string(kFlipFields[field].bits - 1U) + " of " +
               std::string(kFlipFields[field].name) + ")";
      }
      f = Fault{FaultKind::channel_flip, ch, static_cast<std::uint16_t>((field << 8U) | bit)};
      return {};
    }
    return "bad fault \"" + line_of(a) + "\" (expected channel A|B stall|crash, channel A|B input NAME=V, channel A|B "
           "digest corrupt|drop|repeat, channel A|B flip FIELD [bit N])";
  }
  if (a.size() == 3 && a[0] == "contactor" && (a[1] == "k1" || a[1] == "k2") &&
      (a[2] == "welded" || a[2] == "stuck_open")) {
    f = Fault{(a[2] == "welded") ? FaultKind::contactor_welded : FaultKind::contactor_stuck_open,
              static_cast<std::uint8_t>((a[1] == "k1") ? 1U : 2U), 0};
    return {};
  }
  if (a.size() >= 3 && a[0] == "encoder") {
    std::uint8_t axis = 0;
    if (!axis_1_to_6(a[1], axis)) {
      return "bad encoder \"" + std::string(a[1]) + "\" in fault \"" + line_of(a) + "\" (expected 1..6)";
    }
    if (a.size() == 3 && a[2] == "stuck") {
      f = Fault{FaultKind::encoder_stuck, axis, 0};
      return {};
    }
    double x = 0.0;
    if (a.size() == 4 && (a[2] == "offset" || a[2] == "drift")) {
      if (!to_real(a[3], x) || x < -kMaxEncoderFaultDeg || x > kMaxEncoderFaultDeg) {
        return "bad " + std::string(a[2]) + " \"" + std::string(a[3]) + "\" in fault \"" + line_of(a) +
               "\" (expected degrees" + (a[2] == "drift" ? " per second" : "") + " -300..300)";
      }
      const auto hundredths = static_cast<std::int16_t>(std::lround(x * 100.0));
      f = Fault{(a[2] == "offset") ? FaultKind::encoder_offset : FaultKind::encoder_drift, axis,
                static_cast<std::uint16_t>(hundredths)};
      return {};
    }
    return "bad fault \"" + line_of(a) + "\" (expected encoder N stuck, encoder N offset DEG, encoder N drift DEG_S)";
  }
  return "?";
}

bool parse_fault_words(const Tokens& a, Fault& f) noexcept {
  if (parse_drive_fault(a, f) || parse_drive_word_fault(a, f)) {
    return true;
  }
  if (a.size() == 3 && a[0] == "brake" && axis_1_to_6(a[1], f.axis)) {
    constexpr std::array<std::pair<std::string_view, FaultKind>, 3> kinds{{
        {"stuck", FaultKind::brake_stuck},
        {"stuck_released", FaultKind::brake_stuck_released},
        {"weak", FaultKind::brake_weak},  // SPEC §12: holds less than the test torque
    }};
    for (const auto& [word, kind] : kinds) {
      if (a[2] == word) {
        f.kind = kind;
        return true;
      }
    }
    return false;
  }
  f.axis = 0;
  if (a.size() == 1 && a[0] == "integrity") {
    f.kind = FaultKind::integrity;
    return true;
  }
  if (a.size() != 2) {
    return false;
  }
  constexpr std::array<std::pair<std::pair<std::string_view, std::string_view>, FaultKind>, 7> pairs{{
      {{"fieldbus", "lost"}, FaultKind::fieldbus_lost},
      {{"contactor", "stuck_open"}, FaultKind::contactor_stuck_open},
      {{"clear", "all"}, FaultKind::clear_all},
      {{"selftest", "fail"}, FaultKind::selftest_fail},
      {{"contactor", "welded"}, FaultKind::contactor_welded},
      {{"program", "unload"}, FaultKind::program_unload},
      {{"jog_link", "drop"}, FaultKind::jog_link_drop},
  }};
  for (const auto& [words, kind] : pairs) {
    if (a[0] == words.first && a[1] == words.second) {
      f.kind = kind;
      return true;
    }
  }
  return false;
}

}  // namespace

Problem parse_fault(const Tokens& words, Fault& out, FaultSource from) {
  Fault f{};
  Problem p = parse_collision_fault(words, f);
  if (p == "?") {
    p = parse_two_channel_fault(words, f);
  }
  if (p == "?") {
    p = parse_fault_words(words, f) ? Problem{} : Problem{"?"};
  }
  if (p.empty() && !injectable(f.kind, from)) {
    return "fault \"" + line_of(words) +
           "\" cannot be injected over the network (a platform, program or jog-link fault: scenario files and "
           "the emulator's control socket only)";
  }
  if (p == "?") {
    const bool net = from == FaultSource::network;
    return "bad fault \"" + line_of(words) + "\" (expected drive N fault|clear|runaway|nostop, " +
           (net ? "" : "drive N statusword 0xHHHH, drive N slow_enable MS, ") + "drive N torque_bias X, fieldbus lost, " +
           (net ? "contactor stuck_open, brake N stuck|weak, " : "contactor stuck_open|welded, brake N stuck|stuck_released|weak, integrity, selftest fail, program unload, jog_link drop, ") +
           "contact F, encoder N stuck|offset DEG|drift DEG_S, " +
           (net ? "" : "channel A|B stall|crash|input NAME=V|digest corrupt|drop|repeat|flip FIELD [bit N], contactor k1|k2 welded|stuck_open, ") +
           "clear all; N 1..6" + (net ? "" : ", MS 1..60000") +
           ", F 0..5000 newtons, X -300..300 percent of rated torque)";
  }
  if (p.empty()) {
    out = f;
  }
  return p;
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

// A value in hundredths as decimal text: 1234 -> "12.34", -5 -> "-0.05", 50 -> "0.5".
std::string hundredths(std::int32_t v) {
  const bool neg = v < 0;
  const std::uint32_t a = neg ? static_cast<std::uint32_t>(-static_cast<std::int64_t>(v)) : static_cast<std::uint32_t>(v);
  std::string t = (neg ? "-" : "") + std::to_string(a / 100U);
  const std::uint32_t frac = a % 100U;
  if (frac != 0U) {
    t += "." + std::to_string(frac / 10U);
    if (frac % 10U != 0U) {
      t += std::to_string(frac % 10U);
    }
  }
  return t;
}

std::string hex4(std::uint16_t v) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  std::string t = "0x";
  for (int shift = 12; shift >= 0; shift -= 4) {
    t += kDigits[(v >> shift) & 0xFU];
  }
  return t;
}
}  // namespace

std::string format_fault(const Fault& f) {
  const std::string n = std::to_string(f.axis);
  switch (f.kind) {
    case FaultKind::drive_fault: return "drive " + n + " fault";
    case FaultKind::drive_clear: return "drive " + n + " clear";
    case FaultKind::drive_runaway: return "drive " + n + " runaway";
    case FaultKind::drive_nostop: return "drive " + n + " nostop";
    case FaultKind::fieldbus_lost: return "fieldbus lost";
    case FaultKind::contactor_stuck_open:
      return (f.axis == 0U) ? "contactor stuck_open" : std::string("contactor ") + (f.axis == 2U ? "k2" : "k1") + " stuck_open";
    case FaultKind::brake_stuck: return "brake " + n + " stuck";
    case FaultKind::clear_all: return "clear all";
    case FaultKind::integrity: return "integrity";
    case FaultKind::selftest_fail: return "selftest fail";
    case FaultKind::drive_statusword: return "drive " + n + " statusword " + hex4(f.value);
    case FaultKind::drive_slow_enable: return "drive " + n + " slow_enable " + std::to_string(f.value);
    case FaultKind::contactor_welded:
      return (f.axis == 0U) ? "contactor welded" : std::string("contactor ") + (f.axis == 2U ? "k2" : "k1") + " welded";
    case FaultKind::brake_stuck_released: return "brake " + n + " stuck_released";
    case FaultKind::program_unload: return "program unload";
    case FaultKind::jog_link_drop: return "jog_link drop";
    case FaultKind::brake_weak: return "brake " + n + " weak";
    case FaultKind::contact: return "contact " + tenths(static_cast<std::int32_t>(f.value));
    case FaultKind::drive_torque_bias:  // per mille -> %
      return "drive " + n + " torque_bias " + tenths(static_cast<std::int32_t>(static_cast<std::int16_t>(f.value)));
    case FaultKind::channel_stall: return std::string("channel ") + (f.axis == 2U ? "B" : "A") + " stall";
    case FaultKind::channel_crash: return std::string("channel ") + (f.axis == 2U ? "B" : "A") + " crash";
    case FaultKind::channel_input:
      return std::string("channel ") + (f.axis == 2U ? "B" : "A") + " input " +
             to_string(static_cast<Contact>(f.value >> 1U)) + "=" + ((f.value & 1U) != 0U ? "1" : "0");
    case FaultKind::digest_corrupt: return std::string("channel ") + (f.axis == 2U ? "B" : "A") + " digest corrupt";
    case FaultKind::digest_drop: return std::string("channel ") + (f.axis == 2U ? "B" : "A") + " digest drop";
    case FaultKind::digest_repeat: return std::string("channel ") + (f.axis == 2U ? "B" : "A") + " digest repeat";
    case FaultKind::encoder_stuck: return "encoder " + n + " stuck";
    case FaultKind::encoder_offset:
      return "encoder " + n + " offset " + hundredths(static_cast<std::int16_t>(f.value));
    case FaultKind::encoder_drift:
      return "encoder " + n + " drift " + hundredths(static_cast<std::int16_t>(f.value));
    case FaultKind::channel_flip: {
      const std::size_t field = static_cast<std::size_t>(f.value >> 8U) % kFlipFields.size();
      const unsigned bit = f.value & 0xFFU;
      return std::string("channel ") + (f.axis == 2U ? "B" : "A") + " flip " + std::string(kFlipFields[field].name) +
             (bit == 0U ? "" : " bit " + std::to_string(bit));
    }
  }
  return "?";
}

Tokens split_words(std::string_view s) {
  Tokens out;
  std::size_t i = 0;
  auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; };
  while (i < s.size()) {
    while (i < s.size() && space(s[i])) {
      ++i;
    }
    const std::size_t start = i;
    while (i < s.size() && !space(s[i])) {
      ++i;
    }
    if (i > start) {
      out.push_back(s.substr(start, i - start));
    }
  }
  return out;
}

}  // namespace safestate::vocab

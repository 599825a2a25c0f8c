#include "safestate/vocab/faults.hpp"

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
  return static_cast<std::uint8_t>(k) <= static_cast<std::uint8_t>(FaultKind::clear_all) || k == FaultKind::brake_weak ||
         k == FaultKind::contact || k == FaultKind::drive_torque_bias;
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
           "contact F, clear all; N 1..6" + (net ? "" : ", MS 1..60000") +
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
    case FaultKind::contactor_stuck_open: return "contactor stuck_open";
    case FaultKind::brake_stuck: return "brake " + n + " stuck";
    case FaultKind::clear_all: return "clear all";
    case FaultKind::integrity: return "integrity";
    case FaultKind::selftest_fail: return "selftest fail";
    case FaultKind::drive_statusword: return "drive " + n + " statusword " + hex4(f.value);
    case FaultKind::drive_slow_enable: return "drive " + n + " slow_enable " + std::to_string(f.value);
    case FaultKind::contactor_welded: return "contactor welded";
    case FaultKind::brake_stuck_released: return "brake " + n + " stuck_released";
    case FaultKind::program_unload: return "program unload";
    case FaultKind::jog_link_drop: return "jog_link drop";
    case FaultKind::brake_weak: return "brake " + n + " weak";
    case FaultKind::contact: return "contact " + tenths(static_cast<std::int32_t>(f.value));
    case FaultKind::drive_torque_bias:  // per mille -> %
      return "drive " + n + " torque_bias " + tenths(static_cast<std::int32_t>(static_cast<std::int16_t>(f.value)));
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

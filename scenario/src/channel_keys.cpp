#include "channel_keys.hpp"

#include "safestate/core/types.hpp"

namespace safestate::scenario::channel_keys {

using util::Problem;
using util::quoted;

bool set_config(std::string_view key, std::string_view value, Scenario& s, Problem& problem) {
  if (key != "channels") {
    return false;
  }
  if (value == "1" || value == "2") {
    s.channels = static_cast<std::uint8_t>(value == "1" ? 1U : 2U);
  } else {
    problem = "config channels: " + quoted(value) + " is not 1 or 2";
  }
  return true;
}

bool parse_expect(std::string_view tok, Expectation& e, Problem& problem) {
  std::string_view key;
  std::string_view value;
  if (!util::split_pair(tok, key, value)) {
    return false;
  }
  if (key == "contactor.k1" || key == "contactor.k2") {
    e.key = (key == "contactor.k1") ? ExpectKey::contactor_k1 : ExpectKey::contactor_k2;
    if (value != "open" && value != "closed") {
      problem = "bad " + std::string(key) + " value " + quoted(value) + " (expected open|closed)";
      return true;
    }
    e.value = (value == "closed") ? 1U : 0U;
    return true;
  }
  if (key == "channel.a" || key == "channel.b") {
    e.key = ExpectKey::channel_state;
    e.axis = (key == "channel.a") ? 0U : 1U;
    core::State st{};
    if (!core::parse_state(std::string(value).c_str(), st)) {
      problem = "bad " + std::string(key) + " state " + quoted(value) + " (expected a state of SPEC 4)";
      return true;
    }
    e.value = static_cast<std::uint8_t>(st);
    return true;
  }
  return false;
}

bool is_channel_key(ExpectKey k) noexcept {
  return k == ExpectKey::contactor_k1 || k == ExpectKey::contactor_k2 || k == ExpectKey::channel_state;
}

bool holds(const Expectation& e, const sim::Cell& cell) noexcept {
  switch (e.key) {
    case ExpectKey::contactor_k1: return cell.contactor_command(0) == (e.value != 0U);
    case ExpectKey::contactor_k2: return cell.contactor_command(1) == (e.value != 0U);
    case ExpectKey::channel_state:
      return static_cast<std::uint8_t>(cell.channel(e.axis).out().state) == e.value;
    default: break;
  }
  return false;
}

std::string found(const Expectation& e, const sim::Cell& cell) {
  switch (e.key) {
    case ExpectKey::contactor_k1: return std::string("contactor.k1=") + (cell.contactor_command(0) ? "closed" : "open");
    case ExpectKey::contactor_k2: return std::string("contactor.k2=") + (cell.contactor_command(1) ? "closed" : "open");
    case ExpectKey::channel_state:
      return std::string(e.axis == 0U ? "channel.a=" : "channel.b=") + core::to_string(cell.channel(e.axis).out().state);
    default: break;
  }
  return "?";
}

bool known_detail(std::string_view v) noexcept {
  if (v == "k1" || v == "k2" || v == "A" || v == "B") {
    return true;
  }
  for (std::uint8_t f = 1; f <= static_cast<std::uint8_t>(core::CrossField::replies); ++f) {
    if (v == core::to_string(static_cast<core::CrossField>(f))) {
      return true;
    }
  }
  return false;
}

bool contactor_is(const sim::Cell& cell, bool closed) noexcept {
  const bool a = cell.contactor_command(0);
  const bool b = cell.contactor_command(1);
  return closed ? (a && b) : (!a && !b);
}

std::string contactor_found(const sim::Cell& cell) {
  const bool a = cell.contactor_command(0);
  const bool b = cell.contactor_command(1);
  if (a == b) {
    return std::string("contactor=") + (a ? "closed" : "open");
  }
  return std::string("contactor.k1=") + (a ? "closed" : "open") + " contactor.k2=" + (b ? "closed" : "open");
}

}  // namespace safestate::scenario::channel_keys

// The physical contacts of the simulated world by name (spec/scenario-format.md `in` lines,
// the gateway's `sim` `set`, the emulator's control socket `in` lines): one table, one parser.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "safestate/core/signals.hpp"
#include "safestate/vocab/tokens.hpp"

namespace safestate::vocab {

// One physical contact of RawInputs (SPEC §2). For the NC inputs `closed` = healthy.
// The order is the bridge's contact bit order (bridge::kContactCount): append only.
enum class Contact : std::uint8_t {
  estop_a,
  estop_b,
  gate_a,
  gate_b,
  enable_a,
  enable_b,
  enable_panic,
  mode_auto,
  mode_t1,
  mode_t2,
  reset_button,
  reduced_a,  // SPEC §10 reduced-speed request, NC
  reduced_b,
  field_outer_a,  // SPEC §11 protective fields, OSSD, NC (1 = clear)
  field_outer_b,
  field_inner_a,
  field_inner_b,
};
inline constexpr std::size_t kContacts = static_cast<std::size_t>(Contact::field_inner_b) + 1U;

struct ContactWrite {
  Contact contact = Contact::estop_a;
  bool closed = false;
};

// `in KEY=VALUE ...`: the contacts to write, in the given order (a shorthand expands to the
// contacts it sets), and SPEC §11's distance sensor: `separation_mm=N` (also makes the
// reading valid unless the same line sets `separation_valid`), `separation_valid=0|1`.
struct InputStep {
  std::vector<ContactWrite> writes;
  std::optional<std::int32_t> separation_mm;
  std::optional<bool> separation_valid;
};

// One KEY=VALUE into `out`: a shorthand (estop, gate, enable, mode, reset_button, reduced,
// field.outer, field.inner), a raw contact (estop.a ... field.inner.b, 0|1) or the distance
// sensor. Empty: taken. Otherwise the problem, naming the key or the value.
Problem parse_input(std::string_view key, std::string_view value, InputStep& out);
// Every KEY=VALUE token of an `in` line; all or nothing.
Problem parse_inputs(const Tokens& tokens, InputStep& out);

// Writes the step into the raw inputs.
void apply(const InputStep& step, core::RawInputs& raw) noexcept;
void apply(const ContactWrite& w, core::RawInputs& raw) noexcept;

// The contact's state in `raw` (for printing and the bridge's contact bits).
[[nodiscard]] bool contact_of(const core::RawInputs& raw, Contact c) noexcept;
// Its name (estop.a ... field.inner.b, reset_button, reduced.a ...).
[[nodiscard]] const char* to_string(Contact c) noexcept;

}  // namespace safestate::vocab

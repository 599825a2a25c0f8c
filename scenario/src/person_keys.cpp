// The simulated person's scenario keys (see person_keys.hpp).
#include "person_keys.hpp"

#include <string>

namespace safestate::scenario::person_keys {

using util::Problem;
using util::quoted;

// @req COL-SIM-PERSON
bool set_config(std::string_view key, std::string_view value, Scenario& s, Problem& problem) {
  if (key != "person_fields") {
    return false;
  }
  problem = vocab::parse_person_fields(value, s.person_sensors);
  return true;
}

Problem parse(const util::Tokens& a, PersonStep& out, bool& present) { return vocab::parse_person(a, out, present); }

bool apply(const PersonStep& step, sim::Cell& cell) noexcept {
  switch (step.action) {
    case PersonStep::Action::at: return cell.add_person(step.x_mm, step.y_mm, step.radius_mm);
    case PersonStep::Action::walk: return cell.set_person_path(step.path.data(), step.path.size());
    case PersonStep::Action::stand: cell.person_stand(); return true;
    case PersonStep::Action::leave: cell.remove_person(); return true;
  }
  return false;
}

}  // namespace safestate::scenario::person_keys

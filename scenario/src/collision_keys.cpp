#include "collision_keys.hpp"

#include <cmath>
#include <cstdint>

namespace safestate::scenario::collision_keys {

bool parse_fault(const util::Tokens& a, sim::Fault& f) noexcept {
  double x = 0.0;
  if (a.size() == 2 && a[0] == "contact" && util::to_real(a[1], x) && x >= 0.0 && x <= kMaxContactN) {
    f.kind = sim::FaultKind::contact;
    f.axis = 0;
    f.value = static_cast<std::uint16_t>(std::lround(x * 10.0));
    return true;
  }
  std::uint8_t axis = 0;
  if (a.size() == 4 && a[0] == "drive" && a[2] == "torque_bias" && util::axis_1_to_6(a[1], axis) &&
      util::to_real(a[3], x) && x >= -kMaxTorqueBiasPct && x <= kMaxTorqueBiasPct) {
    f.kind = sim::FaultKind::drive_torque_bias;
    f.axis = axis;
    const auto permille = static_cast<std::int16_t>(std::lround(x * 10.0));
    f.value = static_cast<std::uint16_t>(permille);  // two's complement, read back as int16
    return true;
  }
  return false;
}

}  // namespace safestate::scenario::collision_keys

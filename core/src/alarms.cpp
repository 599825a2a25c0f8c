#include "safestate/core/alarms.hpp"

namespace safestate::core {

void AlarmSet::raise(AlarmId id, const AlarmDetail& d, Cycle now) noexcept {
  const AlarmMask b = bit(id);
  if ((active_ & b) != 0U) {
    return;  // first cause kept (first-out)
  }
  active_ |= b;
  raised_ |= b;
  cleared_ &= ~b;
  since_[static_cast<std::size_t>(id)] = now;
  detail_[static_cast<std::size_t>(id)] = d;
}

void AlarmSet::clear(AlarmId id) noexcept {
  const AlarmMask b = bit(id);
  if ((active_ & b) == 0U) {
    return;
  }
  active_ &= ~b;
  cleared_ |= b;
  raised_ &= ~b;
}

void AlarmSet::clear_older(AlarmMask mask, Cycle now) noexcept {
  for (std::size_t i = 0; i < kAlarmCount; ++i) {
    const auto id = static_cast<AlarmId>(i);
    if (((mask & bit(id)) != 0U) && active(id) && (since_[i] < now)) {
      clear(id);
    }
  }
}

}  // namespace safestate::core

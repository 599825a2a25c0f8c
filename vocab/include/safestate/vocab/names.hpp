// The names SafeState prints, in one place for every printer (status, traces, logs).
#pragma once

#include <nlohmann/json.hpp>

#include "safestate/core/alarms.hpp"

namespace safestate::vocab {

// The names of the alarms in `mask`, in the alarm table's order, as a JSON array.
[[nodiscard]] nlohmann::ordered_json alarm_names(core::AlarmMask mask);

}  // namespace safestate::vocab

#include "safestate/vocab/names.hpp"

namespace safestate::vocab {

nlohmann::ordered_json alarm_names(core::AlarmMask mask) {
  nlohmann::ordered_json a = nlohmann::ordered_json::array();
  for (const core::AlarmInfo& info : core::kAlarms) {
    if ((mask & core::bit(info.id)) != 0U) {
      a.push_back(info.name);
    }
  }
  return a;
}

}  // namespace safestate::vocab

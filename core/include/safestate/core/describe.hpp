// Causes and alarms in words, for operators ("E-stop channel A opened", "Guard opened
// in AUTO"). Writes into a caller's buffer: no heap, usable on the controller itself.
#pragma once

#include <cstddef>

#include "safestate/core/alarms.hpp"
#include "safestate/core/states.hpp"

namespace safestate::core {

// The first-out cause of a stop; returns `buf` (empty string for no cause).
const char* describe(const Cause& c, char* buf, std::size_t n) noexcept;
// One alarm with its cause detail ("Drive 3 reports a fault (statusword 0x0008)").
const char* describe(AlarmId id, const AlarmDetail& d, char* buf, std::size_t n) noexcept;

}  // namespace safestate::core

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

// The names of spec/scenario-format.md ("More keys"), for status and scenario files.
// The first-out cause: an alarm name, `enable_released`, or the command of a stop
// without alarm (`servo_off`, `pause`, `stop`, `jog_stop`); "-" for none.
const char* cause_name(const Cause& c) noexcept;
// The signal a detail names: `estop.a` ... `enable.panic`, `mode`, `fieldbus`, `drive.N`,
// `contactor`, `brake.N`, `internal`, `command`; "-" for none. Returns `buf`.
const char* signal_name(const AlarmDetail& d, char* buf, std::size_t n) noexcept;
// An alarm's detail: the arming step (`CONTACTOR`, `DRIVES`, `BRAKES`) when it names
// one, else its signal_name(). Returns `buf`.
const char* detail_name(const AlarmDetail& d, char* buf, std::size_t n) noexcept;

}  // namespace safestate::core

// SPEC §3: the safety outputs of every state. The supervisor writes them each cycle
// (write_outputs); ARMING (by step), STOPPING (brake phase) and IDLE (lamp) refine them.
#pragma once

#include <array>

#include "safestate/core/interfaces.hpp"
#include "safestate/core/states.hpp"

namespace safestate::core {

// Outputs per leaf (SPEC §3). ARMING (by step), STOPPING (brake phase) and IDLE (lamp)
// refine these in write_outputs().
struct LeafOutputs {
  bool contactor;
  bool drives;
  bool brakes_release;
  bool reset_lamp;
  MotionMode motion;
};
// @req ST-OUTPUTS
inline constexpr std::array<LeafOutputs, kLeafCount> kLeafOutputs{{
    {false, false, false, false, MotionMode::Track},  // BOOT
    {false, false, false, false, MotionMode::Track},  // ERROR_LOCKOUT
    {false, false, false, false, MotionMode::Track},  // ESTOP_ACTIVE
    {false, false, false, true, MotionMode::Track},   // ESTOP_RESET_NEEDED
    {false, false, false, false, MotionMode::Track},  // IDLE (lamp: latched alarm waiting)
    {true, false, false, false, MotionMode::Track},   // ARMING (drives/brakes by step)
    {true, true, true, false, MotionMode::Hold},      // AUTO_IDLE
    {true, true, true, false, MotionMode::Program},   // AUTO_RUNNING
    {true, true, true, false, MotionMode::Hold},      // AUTO_PAUSED
    {true, true, true, false, MotionMode::Hold},      // MANUAL_IDLE
    {true, true, true, false, MotionMode::Jog},       // MANUAL_JOGGING
    {true, true, true, false, MotionMode::Program},   // MANUAL_RUNNING
    {true, true, true, false, MotionMode::QuickStop}, // STOPPING_CAT1
    {true, true, true, false, MotionMode::Ramp2},     // STOPPING_CAT2
    {true, true, true, false, MotionMode::Hold},      // BRAKE_TEST (the tested brake: brake_test_axis)
}};

}  // namespace safestate::core

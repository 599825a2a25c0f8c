// What the supervisor reports each cycle besides states and outputs, in the one shape the
// status carries from the core to the bridge and the gateway (no field-by-field copies).
#pragma once

#include <cstdint>

#include "safestate/core/brake_test.hpp"

namespace safestate::core {

// SPEC §10 as status shows it (protocol `safety`).
struct SafetyStatus {
  std::uint32_t checksum = 0;
  bool validated = true;
  bool reduced = false;
  std::uint8_t reduced_by = 0;  // kReducedBy* bits
  bool recovery = false;        // a position limit is violated and being recovered from
  bool outside = false;         // a position limit is violated now
  float speed_limit_mm_s = 0.0F;
  float tcp_speed_mm_s = 0.0F;  // the core's own measure
  // SPEC §11: the protective fields as validated (whether or not they act), and SSM.
  bool field_outer_interrupted = false;
  bool field_inner_interrupted = false;
  bool ssm = false;              // SSM acts (collaborative and ssm on, mode AUTO)
  float v_allowed_mm_s = 0.0F;   // meaningful while `ssm`
  float separation_mm = 0.0F;    // the separation used, while `ssm`
  // SPEC §11 collision detection: acts (collaborative and pfl on), and the force at the TCP
  // estimated this cycle (0 while the arm is not free: power off, brakes, brake test).
  bool pfl = false;
  float contact_force_n = 0.0F;
};

}  // namespace safestate::core

// `safestate ecat-sim`: the emulated segment on a network interface (a raw AF_PACKET
// socket, EtherType 0x88A4), with a control channel on a Unix socket through which the
// physical world and the faults are changed (the `in` and `fault` vocabulary of the
// scenario format, or the gateway's `sim` JSON messages).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "safestate/ecat/cell.hpp"

namespace safestate::ecat {

struct EcatSimOptions {
  std::string ifname;
  std::string control;      // Unix socket path; empty = no control channel
  std::uint32_t cycle_us = 1000;
  // SCHED_FIFO when permitted (0 = ordinary scheduling). Above the master's threads (loop 80,
  // frame thread 85): it stands in for ESCs, which answer in hardware whatever the master's
  // CPU does; on the loop's CPU (`--cpu`) a lower priority let a loop spinning out its
  // deadline keep a late answer from being sent at all.
  int priority = 90;
  // Pin the frame loop to this CPU (-1: no pinning). The tests put it on the CPU of
  // `safestate run --cpu`: see docs/ethercat.md, "Timing on a shared host".
  int cpu = -1;
  std::string product_override;  // "POS=PRODUCT": a subdevice with another product code (tests)
  std::string revision_override;  // "POS=REVISION": a subdevice with another revision (tests)
  std::string sdo_refuse;  // "POS INDEX:SUB ABORT": that drive refuses SDO downloads there from power-on (tests)
  std::string drift_ppm;   // "P" (every clock) or "P1,...,P8": the local clocks' drifts (ppm, -500..500)
  // The drives also accept OP without DC SYNC0 (SM-synchronous), as drives whose ESI offers a
  // free-run OpMode besides DC: for masters that configure no DC (kickcat's Python binding).
  bool drives_free_run = false;
  // A segment without the distance sensor (SPEC §11): a cell whose bus configuration has no
  // distance_sensor, where the separation stays invalid (tests).
  bool no_distance_sensor = false;
  // Issue 37: a segment without the safe input and output terminals and the drives' PDOs
  // without containers, exactly as before them (the DO terminal's bits drive the power path).
  bool no_safe_terminals = false;
  // The safe devices' first sessions: 0 = random at power-up (getrandom); a fixed value for
  // tests (each connection and each power-up still gets a session of its own).
  std::uint32_t link_seed = 0;
  // Every safety connection's watchdog in the safe devices (ms; the bus configuration's
  // safety_links must say the same: it is in every container's CRC).
  std::uint16_t link_watchdog_ms = 10;
  // The plant one cycle per process-data exchange (EmulatedCell::Pacing::lockstep) instead
  // of paced by the drives' SYNC0; `safestate replay` sets it over the control channel.
  bool lockstep = false;
  // The subdevices served (their SII built from these): `safestate ecat-sim` passes the ones
  // made from the shipped ESI (hal/ethercat/esi, esi_segment()); empty = default_segment().
  std::vector<SubdeviceDesc> devices;
};

// `--drift-ppm`: one value for every subdevice or one per subdevice, each -500..500 ppm.
// False (and `err` says why) on anything else; `out` then unchanged.
bool parse_drift_ppm(const std::string& spec, std::size_t subdevices, std::vector<double>& out, std::string& err);

// One control line -> "OK" or "ERROR <why>"; `status` -> one JSON object. Exposed for tests.
std::string control_line(EmulatedCell& cell, const std::string& line);

int ecat_sim_main(const EcatSimOptions& opt);

}  // namespace safestate::ecat

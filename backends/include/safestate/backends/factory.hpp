// The backend factory: the one place that chooses what is behind a controller's process
// image. A host (`safestate run`, `rtbench`, `rta`) asks it for a controller on a backend and
// gets back the controller (controller::Cell) and, when the world is the in-process simulated
// cell, that world's port (vocab::World) for the HMI's sim panel. Nothing else in runtime/,
// gateway/ or rta/ includes sim/ (the test `no_sim_in_the_loop` checks the objects).
//   sim       the simulated plant and person in this process (sim/), the default;
//   ethercat  a segment on `ifname` through the EtherCAT master (hal/ethercat/): a real one,
//             or ecat-sim's emulated one, whose world is another process (no port here).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "safestate/controller/cell.hpp"
#include "safestate/core/config.hpp"
#include "safestate/hal/ethercat.hpp"
#include "safestate/vocab/world.hpp"

namespace safestate::backends {

struct Choice {
  std::string fieldbus = "sim";  // sim | ethercat
  std::string ifname;            // ethercat: the segment's interface
  std::string bus_config;        // ethercat: topology file; empty = the shipped default (ecat-sim's segment)
  std::uint32_t watchdog_ms = 100;  // ethercat: a longer stall of the host = the bus lost
  // SPEC §14: 1 = the controller in this process on the backend; 2 = the backend alone for two
  // channels in processes of their own (pair_backend()); 0 = the backend's default: two on the
  // simulated cell, two on a segment whose bus configuration has K2 and the load-side encoders
  // (the shipped default has them), else one with channels_note() saying why. `--channels 2`
  // on a segment without them is refused.
  unsigned channels = 0;
};

class Host {
 public:
  Host() = default;
  Host(const Host&) = delete;
  Host& operator=(const Host&) = delete;
  virtual ~Host() = default;
  // The controller on its backend (the command queue, one cycle per step()).
  virtual controller::Cell& cell() noexcept = 0;
  // The in-process simulated world, or null (a real or emulated segment).
  virtual vocab::World* world() noexcept = 0;
  // SPEC §10, before the first cycle: the controller's safe limits and, on the simulated
  // cell, the world's arm carrying the declared tool (payload, TCP).
  virtual void configure_limits(const core::SafetyLimits& limits, bool validated) noexcept {
    cell().configure_limits(limits, validated);
  }
  // SPEC §14: the channels this host was made for (Choice::channels, resolved), and with two
  // the backend they run on in processes of their own (pair/host.hpp), without this host's
  // in-process controller (the simulated world alone); null with one.
  [[nodiscard]] virtual unsigned channels() const noexcept { return 1U; }
  virtual hal::Backend* pair_backend() noexcept { return nullptr; }
  // Why the default gave fewer channels than SPEC §14's two (empty: it did not).
  [[nodiscard]] virtual std::string channels_note() const { return {}; }
  // The EtherCAT backend and its configuration, or null: for the host's reports (names of the
  // subdevices, boot error, loss, DC).
  virtual hal::ethercat::Backend* ethercat() noexcept { return nullptr; }
  virtual const hal::ethercat::BusConfig* bus_config() const noexcept { return nullptr; }
};

// The controller on the chosen backend, the demo program loaded. `cfg` must have passed
// core::validate(). Null, with `error` naming the problem (an unknown fieldbus, a bad bus
// configuration file), when nothing can be built; nothing is started then.
std::unique_ptr<Host> make_host(const core::Config& cfg, const Choice& choice, std::string& error);

}  // namespace safestate::backends

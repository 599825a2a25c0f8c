#include "safestate/backends/factory.hpp"

#include "safestate/robot/description.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::backends {

namespace {

// The simulated cell: the controller on the plant and the person of this process.
class SimHost final : public Host {
 public:
  // `channels` 2: the world with K1 and K2 and a load-side encoder per axis, for two channels
  // in processes of their own (pair_backend); 1: the world with its controller in this process.
  SimHost(const core::Config& cfg, unsigned channels)
      : cell_(cfg, nullptr, static_cast<std::uint8_t>(channels)), channels_(channels) {}
  controller::Cell& cell() noexcept override { return cell_.controller(); }
  vocab::World* world() noexcept override { return &cell_; }
  unsigned channels() const noexcept override { return channels_; }
  hal::Backend* pair_backend() noexcept override { return channels_ == 2U ? &cell_.world_port() : nullptr; }
  void configure_limits(const core::SafetyLimits& limits, bool validated) noexcept override {
    cell_.configure_limits(limits, validated);  // the controller's, and the plant's tool
  }

 private:
  sim::Cell cell_;
  unsigned channels_;
};

// A segment: the controller directly on the EtherCAT backend; no simulator in this process.
class EthercatHost final : public Host {
 public:
  EthercatHost(const core::Config& cfg, hal::ethercat::BusConfig bc, std::unique_ptr<hal::ethercat::Backend> bus)
      : bc_(std::move(bc)), bus_(std::move(bus)), cell_(cfg, robot::active().model, *bus_) {
    std::uint8_t n = 0;
    const motion::Waypoint* p = controller::demo_program(n);
    cell_.load_program(p, n);
  }
  controller::Cell& cell() noexcept override { return cell_; }
  vocab::World* world() noexcept override { return nullptr; }
  hal::ethercat::Backend* ethercat() noexcept override { return bus_.get(); }
  const hal::ethercat::BusConfig* bus_config() const noexcept override { return &bc_; }

 private:
  hal::ethercat::BusConfig bc_;
  std::unique_ptr<hal::ethercat::Backend> bus_;
  controller::Cell cell_;  // after bus_: it runs on it
};

}  // namespace

std::unique_ptr<Host> make_host(const core::Config& cfg, const Choice& choice, std::string& error) {
  if (choice.channels > 2U) {
    error = "--channels must be 1 or 2";
    return nullptr;
  }
  if (choice.fieldbus == "sim") {
    return std::make_unique<SimHost>(cfg, choice.channels == 0U ? 2U : choice.channels);
  }
  if (choice.fieldbus != "ethercat") {
    error = "--fieldbus must be sim or ethercat, not \"" + choice.fieldbus + "\"";
    return nullptr;
  }
  if (choice.channels == 2U) {
    error = "--channels 2 is not offered on EtherCAT yet: K2 and the load-side encoders are not on the segment "
            "(docs/two-channels.md); use --channels 1";
    return nullptr;
  }
  hal::ethercat::BusConfig bc;
  const bool ok = choice.bus_config.empty()
                      ? hal::ethercat::parse_bus_config(hal::ethercat::default_bus_config(), bc, error)
                      : hal::ethercat::load_bus_config(choice.bus_config, bc, error);
  if (!ok) {
    error = "bus configuration: " + error;
    return nullptr;
  }
  // One exchange never holds the loop past its cycle: a frame not back 150 us before the
  // cycle ends (3/4 of short cycles) leaves it stale (docs/ethercat.md).
  const std::uint32_t budget_us = hal::ethercat::exchange_budget_us(cfg.cycle_us);
  auto bus = std::make_unique<hal::ethercat::Backend>(bc, choice.ifname, cfg.cycle_us, budget_us,
                                                      std::uint64_t{choice.watchdog_ms} * 1000000ULL);
  return std::make_unique<EthercatHost>(cfg, std::move(bc), std::move(bus));
}

}  // namespace safestate::backends

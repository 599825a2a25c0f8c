#include "safestate/backends/factory.hpp"

#include "safestate/pair/os.hpp"
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
// `channels` 2: the backend alone for the two channels' processes (pair_backend).
class EthercatHost final : public Host {
 public:
  EthercatHost(const core::Config& cfg, hal::ethercat::BusConfig bc, std::unique_ptr<hal::ethercat::Backend> bus,
               unsigned channels, std::string note)
      : bc_(std::move(bc)),
        bus_(std::move(bus)),
        cell_(cfg, robot::active().model, *bus_),
        channels_(channels),
        note_(std::move(note)) {
    std::uint8_t n = 0;
    const motion::Waypoint* p = controller::demo_program(n);
    cell_.load_program(p, n);
    // Issue 37: a channel alone hosts every black-channel connection of the segment (a pair's
    // channels host their own: pair/host.cpp hands them the table).
    if (channels_ == 1U) {
      const char* why = nullptr;
      if (!cell_.configure_links(bus_->safety_links(), pair::random_session(), why)) {
        links_error_ = why != nullptr ? why : "?";
      }
    }
  }
  controller::Cell& cell() noexcept override { return cell_; }
  vocab::World* world() noexcept override { return nullptr; }
  hal::ethercat::Backend* ethercat() noexcept override { return bus_.get(); }
  const hal::ethercat::BusConfig* bus_config() const noexcept override { return &bc_; }
  unsigned channels() const noexcept override { return channels_; }
  hal::Backend* pair_backend() noexcept override { return channels_ == 2U ? bus_.get() : nullptr; }
  std::string channels_note() const override { return note_; }
  // Issue 37: why the channel alone refused the bus's safety connections (empty: it did not).
  const std::string& links_error() const noexcept { return links_error_; }

 private:
  hal::ethercat::BusConfig bc_;
  std::unique_ptr<hal::ethercat::Backend> bus_;
  controller::Cell cell_;  // after bus_: it runs on it
  unsigned channels_;
  std::string note_;
  std::string links_error_;
};

// SPEC §14 on a segment: what two channels need of the bus configuration (empty: all there).
std::string pair_missing(const hal::ethercat::BusConfig& bc) {
  using hal::ethercat::kNoBit;
  using hal::ethercat::kNoOffset;
  using hal::ethercat::Role;
  std::string missing;
  for (const hal::ethercat::Subdevice& d : bc.subdevices) {
    if (d.role == Role::safety_outputs && d.out_bit[hal::ethercat::kOutputBits - 1U] == kNoBit) {
      missing += "K2 (\"contactor_k2\" on the safety outputs, \"contactor_fb.k2\" on the inputs)";
    }
    if (d.role == Role::drive && d.axis == 1U && d.load_position == kNoOffset) {
      missing += std::string(missing.empty() ? "" : " and ") + "the load-side encoders (each drive's pdo.load_position, 0x60E4:01)";
    }
  }
  return missing;
}

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
  hal::ethercat::BusConfig bc;
  const bool ok = choice.bus_config.empty()
                      ? hal::ethercat::parse_bus_config(hal::ethercat::default_bus_config(), bc, error)
                      : hal::ethercat::load_bus_config(choice.bus_config, bc, error);
  if (!ok) {
    error = "bus configuration: " + error;
    return nullptr;
  }
  // SPEC §14: two channels need K2 (channel B's power path) and the load-side encoders. The
  // default is two wherever the segment carries them (the shipped bus does); a segment without
  // them runs one channel, which drives K1 (and K2 if present), and says why.
  const std::string missing = pair_missing(bc);
  if (choice.channels == 2U && !missing.empty()) {
    error = "--channels 2: the bus configuration has no " + missing + " (SPEC §14; docs/two-channels.md)";
    return nullptr;
  }
  unsigned channels = choice.channels;
  std::string note;
  if (channels == 0U) {
    channels = missing.empty() ? 2U : 1U;
    if (!missing.empty()) {
      note = "one channel, not SPEC §14's two: the bus configuration has no " + missing +
             " (give --channels 1 to choose one channel and silence this; docs/two-channels.md)";
    }
  }
  // One exchange never holds the loop past its cycle: a frame not back 150 us before the
  // cycle ends (3/4 of short cycles) leaves it stale (docs/ethercat.md).
  const std::uint32_t budget_us = hal::ethercat::exchange_budget_us(cfg.cycle_us);
  auto bus = std::make_unique<hal::ethercat::Backend>(bc, choice.ifname, cfg.cycle_us, budget_us,
                                                      std::uint64_t{choice.watchdog_ms} * 1000000ULL);
  auto host = std::make_unique<EthercatHost>(cfg, std::move(bc), std::move(bus), channels, std::move(note));
  if (!host->links_error().empty()) {
    error = "bus configuration: safety connections: " + host->links_error();
    return nullptr;
  }
  return host;
}

}  // namespace safestate::backends

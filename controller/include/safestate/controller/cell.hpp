// A controller on a backend: what runs a robot, whatever is behind the process image.
//   backend.read -> the platform's checks -> Controller::step (motion.measure, supervisor,
//   motion) -> backend.write
// The backend is the simulated plant (sim/), an EtherCAT segment (hal/ethercat/) or any other
// hal::Backend, chosen by the factory (runtime/backends); nothing here knows which. The
// command queue of SPEC §9 and the view of the last cycle (for the status) live here, so
// that a second channel is a second instance of this class. No heap after construction, no
// exceptions, no OS calls, no clock: the same rules as core/.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "safestate/controller/controller.hpp"
#include "safestate/controller/cross_check.hpp"
#include "safestate/controller/platform.hpp"
#include "safestate/controller/safety_links.hpp"
#include "safestate/core/command_queue.hpp"
#include "safestate/hal/process_image.hpp"

namespace safestate::controller {

// What the controller shows after a cycle, besides the supervisor's output: the process
// image as it read and wrote it, and the motion layer's view of the arm.
struct CellView {
  std::array<float, 6> joints_rad{};        // measured
  std::array<float, 6> velocities_rad_s{};  // measured
  std::array<float, 6> tcp{};               // x, y, z mm; rx, ry, rz rad
  float tcp_speed_mm_s = 0.0F;              // measured, from measured joint positions
  float max_point_speed_mm_s = 0.0F;        // TCP and every link origin
  std::array<const char*, 6> axis_state{};  // PLCopen axis state names
  std::array<std::uint8_t, 6> axis_code{};  // the same, as motion::AxisState values
  std::array<std::uint16_t, 6> statusword{};
  std::array<std::uint16_t, 6> controlword{};
  std::array<float, 6> target_rad{};        // CSP set-points written this cycle
  bool contactor_closed = false;            // feedback (K1's auxiliary contact)
  bool k2_closed = false;                   // SPEC §14: K2's, with two contactors
  bool two_contactors = false;              // SPEC §14: the backend has K2 (and its contact)
  std::array<bool, 6> brake_released{};     // feedback
  bool fieldbus_ok = true;
  bool inputs_stale = false;  // this cycle's frame was late or lost: inputs held
  std::uint8_t program_index = 0;           // waypoint the program is heading to
  std::uint8_t program_length = 0;
};

// A channel's own reading of its safety inputs, applied after the black channel's containers
// were decoded (issue 37): the simulator's `channel X input NAME=V` (SPEC §14: a channel reading
// one contact wrong) where the contacts reach the channel in containers. Only the simulated
// world installs one (sim::Cell); a controller on a plant has none.
class InputStage {
 public:
  virtual void apply(core::RawInputs& raw) const noexcept = 0;

 protected:
  InputStage() = default;
  InputStage(const InputStage&) = default;
  InputStage& operator=(const InputStage&) = default;
  ~InputStage() = default;
};

class Cell {
 public:
  // `cfg` must have passed core::validate(); `io` must outlive the cell. Registers the core's
  // constant tables (ROM) and this cell's controller (RAM) with its platform and runs the
  // platform's start-up self-test; a host may add regions (its code) before the first step.
  Cell(const core::Config& cfg, const motion::RobotModel& model, hal::Backend& io) noexcept;
  // A copy of `other` on another backend (the exhaustive checker forks whole cells).
  Cell(const Cell& other, hal::Backend& io) noexcept;
  Cell(const Cell&) = delete;
  Cell& operator=(const Cell&) = delete;
  ~Cell() = default;

  void configure_limits(const core::SafetyLimits& limits, bool validated) noexcept {
    controller_.configure_limits(limits, validated);
  }
  void configure_brake_test(const core::BrakeTestHistory& history) noexcept {
    controller_.configure_brake_test(history);
  }
  void load_program(const motion::Waypoint* points, std::uint8_t count) noexcept {
    controller_.load_program(points, count);
  }
  // SPEC §14: this cell is channel `self` (a or b) of a pair; `link` (which must outlive the
  // cell) carries its digest to the other channel every cycle and theirs back. Before the
  // first step. After each step the cell compares (CrossCheck, cross_check_cycles of its
  // configuration); on a mismatch or a lost partner it opens its own contactor and the
  // brakes in that same cycle, and its supervisor names the alarm the next cycle (lockout).
  void pair(core::Channel self, Link& link) noexcept;
  // A copy of a paired cell (the copy constructor leaves it unpaired) onto its own link,
  // its cross-check as it was.
  void relink(Link& link) noexcept { link_ = &link; }
  [[nodiscard]] bool paired() const noexcept { return link_ != nullptr; }
  // Issue 37, before the first step and after pair(): the black channel's connections of
  // `table` this cell hosts (a paired cell its own channel's, a cell alone all of them),
  // each with a session from `session_seed` (the caller's random source). From then on the
  // cell checks and creates their containers itself (SafetyLinks) and takes the safety data
  // from them. false with `why` when the table is refused (nothing changes).
  bool configure_links(const hal::LinkTable& table, std::uint16_t session_seed, const char*& why) noexcept {
    return links_.configure(table, self_, cfg_.cycle_us, session_seed, why);
  }
  [[nodiscard]] const SafetyLinks& links() const noexcept { return links_; }
  // Issue 37, before the first step: one exchange of the black channel's containers alone (the
  // connect and its answer) on `in` as read and into `out` (the safety layer only: the cell
  // does not step, its outputs stay as `out` holds them). A tool that brings its bus up before
  // its first cycle (safestate replay over EtherCAT) opens the sessions the same way. true
  // once every connection the cell hosts has delivered data.
  bool exchange_links(hal::ProcessImageIn& in, hal::ProcessImageOut& out) noexcept {
    links_.receive(in);
    links_.transmit(out);
    return links_.check().up;
  }
  // The simulator's stage after the containers (InputStage above); null: none. A copy of the
  // cell starts without one.
  void set_input_stage(const InputStage* s) noexcept { input_stage_ = s; }
  [[nodiscard]] core::Channel channel() const noexcept { return self_; }
  [[nodiscard]] const CrossCheck& cross_check() const noexcept { return cross_; }
  [[nodiscard]] const Digest& last_digest() const noexcept { return digest_; }
  // Queues a command for the next cycle: OK, or QUEUE_FULL (that is its only answer).
  core::Result submit(const core::Command& c) noexcept;
  // One scan cycle.
  void step() noexcept;

  [[nodiscard]] Platform& platform() noexcept { return platform_; }
  [[nodiscard]] const Platform& platform() const noexcept { return platform_; }
  [[nodiscard]] const core::SupervisorOut& out() const noexcept { return controller_.status(); }
  [[nodiscard]] const CellView& view() const noexcept { return view_; }
  [[nodiscard]] const core::AlarmSet& alarms() const noexcept { return controller_.supervisor().manager().alarms(); }
  [[nodiscard]] const core::RawInputs& raw_inputs_of_last_cycle() const noexcept { return in_.safety; }
  [[nodiscard]] core::Leaf leaf() const noexcept { return controller_.supervisor().manager().leaf(); }
  [[nodiscard]] const core::SafetyInputs& safety_inputs() const noexcept { return controller_.supervisor().inputs(); }
  [[nodiscard]] const core::Feedback& feedback() const noexcept { return controller_.feedback(); }
  [[nodiscard]] const core::Command* commands_taken(std::size_t& n) const noexcept {
    n = taken_;
    return batch_.data();
  }
  [[nodiscard]] core::Cycle now() const noexcept { return now_; }
  [[nodiscard]] const core::Config& config() const noexcept { return cfg_; }
  [[nodiscard]] const Controller& controller() const noexcept { return controller_; }
  [[nodiscard]] const hal::ProcessImageIn& image_in() const noexcept { return in_; }
  [[nodiscard]] const hal::ProcessImageOut& image_out() const noexcept { return out_; }

 private:
  void register_platform() noexcept;
  void update_view() noexcept;

  core::Config cfg_;
  hal::Backend* io_;
  Controller controller_;
  Platform platform_;
  core::CommandQueue<core::kMaxQueueSize> queue_;  // holds cfg.queue_size (SPEC §9: 64)
  hal::ProcessImageIn in_{};
  hal::ProcessImageOut out_{};
  std::array<core::Command, core::kMaxCommandsPerCycle> batch_{};
  std::size_t taken_ = 0;
  core::Cycle now_ = 0;
  CellView view_{};
  // SPEC §14 (pair()).
  Link* link_ = nullptr;
  core::Channel self_ = core::Channel::none;
  CrossCheck cross_{};
  std::uint32_t seq_ = 0;
  Digest digest_{};
  core::ChannelCheck check_{};
  SafetyLinks links_{};  // issue 37
  const InputStage* input_stage_ = nullptr;
};

// SPEC §3's output bits of one cycle, as the black box records them and the cross-channel
// digest compares them: bit 0 contactor, 1 drives enable, 2 brakes release, 3 reset lamp.
[[nodiscard]] std::uint8_t output_bits(const core::SupervisorOut& o) noexcept;

// The demo program: one pick-and-place round over three stations (ABB IRB 120 joints).
const motion::Waypoint* demo_program(std::uint8_t& count) noexcept;

}  // namespace safestate::controller

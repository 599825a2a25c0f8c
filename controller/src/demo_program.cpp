// The demo program the cell runs (the simulated one and ecat-sim's alike; an integrator's
// own program is loaded with Cell::load_program): one pick-and-place round over three stations
// of the ABB IRB 120, about 7 s at 100 % override. Joint positions in rad.
// @req SIM-PROGRAM
#include "safestate/controller/cell.hpp"

namespace safestate::controller {

namespace {
// clang-format off
constexpr std::array<motion::Waypoint, 10> kDemo{{
  //  q1      q2     q3     q4     q5     q6      speed dwell
  {{ 0.60F, 0.30F, 0.10F, 0.00F, 1.05F, 0.00F}, 0.50F, 0},    // above station A
  {{ 0.60F, 0.62F, 0.22F, 0.00F, 0.72F, 0.00F}, 0.15F, 400},  // down, grip
  {{ 0.60F, 0.30F, 0.10F, 0.00F, 1.05F, 0.00F}, 0.15F, 0},    // lift
  {{-0.85F, 0.25F, 0.05F, 0.00F, 1.10F, 1.20F}, 0.45F, 0},    // above station B
  {{-0.85F, 0.58F, 0.20F, 0.00F, 0.78F, 1.20F}, 0.15F, 400},  // down, release
  {{-0.85F, 0.25F, 0.05F, 0.00F, 1.10F, 1.20F}, 0.15F, 0},    // lift
  {{ 1.40F, 0.15F,-0.05F, 0.50F, 1.20F,-0.60F}, 0.40F, 0},    // above station C (inspection)
  {{ 1.40F, 0.45F, 0.10F, 0.50F, 0.95F,-0.60F}, 0.15F, 600},  // hold under the camera
  {{ 1.40F, 0.15F,-0.05F, 0.50F, 1.20F,-0.60F}, 0.15F, 0},    // lift
  {{ 0.00F, 0.00F, 0.00F, 0.00F, 0.50F, 0.00F}, 0.40F, 0},    // home
}};
// clang-format on
}  // namespace

const motion::Waypoint* demo_program(std::uint8_t& count) noexcept {
  count = static_cast<std::uint8_t>(kDemo.size());
  return kDemo.data();
}

}  // namespace safestate::controller

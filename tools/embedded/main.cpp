// Bare-metal Cortex-M4 image that runs the whole scan cycle the way a controller vendor
// would: everything constructed statically at start-up, one Controller::step per timer
// tick (signal layer, supervisor, motion layer, CiA 402 drive control), no heap.
// tools/scripts/embedded.sh builds it and checks that no allocator or exception
// machinery was linked in.
#include "safestate/controller/controller.hpp"
#include "safestate/core/command_queue.hpp"

using namespace safestate;

namespace {
controller::Controller g_controller{core::Config{}, motion::kRobot};
core::CommandQueue<32> g_queue;
hal::ProcessImageIn g_in{};
hal::ProcessImageOut g_out{};
volatile bool g_tick = false;
}  // namespace

// The HAL would fill g_in from the I/O and the fieldbus and send g_out in the timer ISR.
extern "C" void SysTick_Handler() { g_tick = true; }

int main() {
  for (;;) {
    while (!g_tick) {
    }
    g_tick = false;
    core::Command cmds[core::kMaxCommandsPerCycle];
    const std::size_t n = g_queue.peek(cmds, core::kMaxCommandsPerCycle);
    g_queue.pop(g_controller.step(g_in, cmds, n, g_out));
  }
}

// Bare-metal Cortex-M4 image that links the core the way a controller vendor would:
// objects constructed statically at start-up, one step per timer tick, no heap.
// tools/scripts/embedded.sh builds it and checks that no allocator or exception
// machinery was linked in.
#include "safestate/core/command_queue.hpp"
#include "safestate/core/supervisor.hpp"

using namespace safestate::core;

namespace {
Supervisor g_supervisor{to_timing(Config{})};
CommandQueue<32> g_queue;
RawInputs g_raw{};
Feedback g_feedback{};
SupervisorOut g_out{};
volatile bool g_tick = false;
}  // namespace

// The HAL would fill g_raw / g_feedback from the I/O and fieldbus in the timer ISR.
extern "C" void SysTick_Handler() { g_tick = true; }

int main() {
  for (;;) {
    while (!g_tick) {
    }
    g_tick = false;
    Command cmds[kMaxCommandsPerCycle];
    const std::size_t n = g_queue.peek(cmds, kMaxCommandsPerCycle);
    g_queue.pop(g_supervisor.step(g_raw, g_feedback, cmds, n, g_out));
  }
}

// Cortex-M4 instructions per scan cycle (tools/scripts/embedded_bench.sh runs it in QEMU's
// mps2-an386, a Cortex-M4F board, and counts the instructions executed): the same
// Controller::step as tools/embedded/main.cpp, BENCH_CYCLES times, on a process image of a
// healthy cell with the arm moving slowly, and with the SPEC §10 monitors per BENCH_LIMITS:
//   0  not configured: the cycle without the monitors (the landed baseline)
//   1  configured like the built-in configuration: no zone, no orientation limit
//   2  sixteen zones (14 keep_out, 1 keep_in, 1 reduced) and an orientation cone
//   3  as 2, but joint 1 jumps by 1 rad every cycle: more than the zone monitor's
//      kMaxStepMm, so no zone is ever skipped as provably far (every zone tested every
//      cycle: the worst case of the zones that the arm does not reach)
//   4  as 1, and the SPEC §14 cross-check after every cycle: the channel's digest made and
//      sent, the partner's received and compared (here its own digest back over a loopback
//      link: a healthy pair, every field compared); 4 minus 1 is the cross-check's own cost
// Two runs of different lengths give the cost per cycle without start-up. Exits through
// ARM semihosting (SYS_EXIT). Bench only: never linked into a product image.
#include <cstdint>

#include "safestate/controller/controller.hpp"
#include "safestate/controller/cross_check.hpp"

using namespace safestate;

#ifndef BENCH_CYCLES
#define BENCH_CYCLES 100
#endif
#ifndef BENCH_LIMITS
#define BENCH_LIMITS 2
#endif

namespace {

controller::Controller g_controller{core::Config{}, motion::kRobot};
hal::ProcessImageIn g_in{};
hal::ProcessImageOut g_out{};

}  // namespace

// No heap on the target (the image is linked without one): a class with a virtual destructor
// (controller::Link) has a deleting destructor that names operator delete; nothing here ever
// deletes one, so these stop the board if they were ever reached.
void operator delete(void*) noexcept {
  for (;;) {
  }
}
void operator delete(void*, std::size_t) noexcept {
  for (;;) {
  }
}

namespace {

// Mode 4's link: what is sent comes back (the partner's digest equals this channel's). A UART or
// SPI link to a second MCU implements the same interface (controller/cross_check.hpp).
class Loopback final : public controller::Link {
 public:
  void send(const controller::Digest& d) noexcept override {
    d_ = d;
    full_ = true;
  }
  bool receive(controller::Digest& d) noexcept override {
    if (!full_) {
      return false;
    }
    d = d_;
    full_ = false;
    return true;
  }

 private:
  controller::Digest d_{};
  bool full_ = false;
};
Loopback g_link;
controller::CrossCheck g_cross{core::Config{}.cross_check_cycles};

core::Zone box(char tag, core::ZoneKind kind, float x, float y, float z, float half) {
  core::Zone b{};
  b.name[0] = 'z';
  b.name[1] = tag;
  b.kind = kind;
  b.min_mm = {x - half, y - half, z - half};
  b.max_mm = {x + half, y + half, z + half};
  return b;
}

core::SafetyLimits limits(int zones) {
  core::SafetyLimits l{};
  l.checksum = 0x0B0E0C4AU;
  l.tcp_mm = {0.0F, 0.0F, 120.0F};
  l.tool_radius_mm = 40.0F;
  for (auto& j : l.joints) {
    j = core::JointLimit{-2.8F, 2.8F, 4.0F};
  }
  l.tcp_max_speed_mm_s = 2000.0F;
  l.reduced_tcp_max_speed_mm_s = 250.0F;
  l.reduced_ramp_ms = 500;
  if (zones > 0) {
    l.orientation_enabled = true;
    l.orientation_axis = {1.0F, 0.0F, -1.0F};
    l.orientation_max_deviation_rad = 1.3F;
    // Keep-out boxes all around the arm, none touched (the common case: every point is
    // outside every box, the full distance computed); a keep_in box around the cell; a
    // reduced box the TCP is not in.
    for (int k = 0; k < 14; ++k) {
      const float s = (k % 2 == 0) ? 1.0F : -1.0F;
      l.zones[static_cast<std::size_t>(k)] =
          box(static_cast<char>('a' + k), core::ZoneKind::keep_out, s * (900.0F + 40.0F * static_cast<float>(k)),
              s * 300.0F, 100.0F + 20.0F * static_cast<float>(k), 100.0F);
    }
    l.zones[14] = box('o', core::ZoneKind::keep_in, 0.0F, 0.0F, 500.0F, 1500.0F);
    l.zones[15] = box('p', core::ZoneKind::reduced, -600.0F, 600.0F, 300.0F, 150.0F);
    l.zone_count = 16;
  }
  return l;
}

void bench() {
  if (BENCH_LIMITS > 0) {
    g_controller.configure_limits(limits((BENCH_LIMITS == 2 || BENCH_LIMITS == 3) ? 16 : 0), true);
  }
  for (auto& d : g_in.drive) {
    d.statusword = 0x0040U;  // Switch on disabled
    d.online = true;
  }
  const std::array<float, 6> home{0.0F, 0.0F, 0.0F, 0.0F, 0.5F, 0.0F};
  for (std::uint32_t c = 0; c < BENCH_CYCLES; ++c) {
    // The arm moves slowly (every monitor computes its full distances; nothing trips).
    for (std::size_t i = 0; i < 6; ++i) {
      g_in.drive[i].velocity_rad_s = 0.05F;
      g_in.drive[i].position_rad = home[i] + (0.00005F * static_cast<float>(c));
    }
    if ((BENCH_LIMITS == 3) && ((c % 2U) == 1U)) {
      g_in.drive[0].position_rad += 1.0F;
    }
    g_controller.step(g_in, nullptr, 0, g_out);
    if (BENCH_LIMITS == 4) {
      static_cast<void>(g_cross.step(controller::make_digest(c, c, g_controller.status()), g_link));
    }
  }
}

[[noreturn]] void semihost_exit() {
  register std::uint32_t r0 asm("r0") = 0x18U;     // SYS_EXIT
  register std::uint32_t r1 asm("r1") = 0x20026U;  // ADP_Stopped_ApplicationExit
  asm volatile("bkpt 0xab" : : "r"(r0), "r"(r1) : "memory");
  for (;;) {
  }
}

}  // namespace

extern "C" {
using InitFn = void (*)();
extern InitFn __init_array_start[];  // NOLINT: linker symbols
extern InitFn __init_array_end[];
extern std::uint32_t __bss_start[];
extern std::uint32_t __bss_end[];
extern std::uint32_t __stack_top[];
void* __dso_handle = nullptr;
int __aeabi_atexit(void*, void (*)(void*), void*) { return 0; }  // nothing is ever destroyed

[[noreturn]] void Reset_Handler() {
  for (std::uint32_t* p = __bss_start; p < __bss_end; ++p) {
    *p = 0U;
  }
  // Enable the FPU (CPACR: CP10, CP11 full access) before any float.
  *reinterpret_cast<volatile std::uint32_t*>(0xE000ED88U) |= (0xFU << 20U);
  asm volatile("dsb\n isb" ::: "memory");
  for (InitFn* f = __init_array_start; f < __init_array_end; ++f) {
    (*f)();
  }
  bench();
  semihost_exit();
}

__attribute__((section(".isr_vector"), used)) const void* const g_vectors[2] = {
    __stack_top, reinterpret_cast<const void*>(&Reset_Handler)};
}

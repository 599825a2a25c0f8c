// The platform's own checks (controller/platform.hpp): the CRC's known answer, a ROM region
// that changes after start-up is found within one pass, a RAM word that does not hold a
// pattern is found, a healthy memory passes for ever and every word keeps its value; and the
// controller on a backend (controller/cell.hpp) ANDs them into what the supervisor reads.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstring>

#include "safestate/controller/cell.hpp"
#include "safestate/core/config.hpp"
#include "safestate/robot/description.hpp"

using namespace safestate;
using controller::Platform;

TEST(Platform, CrcKnownAnswer) {
  const unsigned char check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(controller::crc32(0U, check, sizeof check), 0xCBF43926U);
  // In slices, as the background test computes it.
  EXPECT_EQ(controller::crc32(controller::crc32(0U, check, 4), check + 4, 5), 0xCBF43926U);
}

TEST(Platform, AHealthyMemoryPassesAndKeepsEveryValue) {
  std::array<unsigned char, 3000> rom{};
  for (std::size_t i = 0; i < rom.size(); ++i) {
    rom[i] = static_cast<unsigned char>(i * 7U);
  }
  std::array<std::uint32_t, 100> ram{};
  for (std::size_t i = 0; i < ram.size(); ++i) {
    ram[i] = static_cast<std::uint32_t>(i * 2654435761U);
  }
  const auto before = ram;
  Platform p;
  ASSERT_TRUE(p.add_rom(rom.data(), rom.size()));
  ASSERT_TRUE(p.add_ram(ram.data(), sizeof ram));
  EXPECT_FALSE(p.self_test_ok()) << "not before the start-up self-test";
  p.start();
  EXPECT_TRUE(p.self_test_ok());
  p.set_period(50);  // every region once within 50 cycles
  EXPECT_EQ(p.rom_slice(), 60U);
  EXPECT_EQ(p.ram_slice(), 2U);
  for (std::size_t k = 0; k < 3 * 50; ++k) {
    p.cycle();
  }
  EXPECT_TRUE(p.integrity_ok());
  EXPECT_GE(p.rom_passes(), 3U);
  EXPECT_GE(p.ram_passes(), 3U);
  EXPECT_EQ(ram, before) << "the pattern test restores every word";
  EXPECT_FALSE(p.add_rom(rom.data(), 1)) << "no region once the background tests run";
}

TEST(Platform, AChangedConstantIsFoundWithinOnePass) {
  std::array<unsigned char, 2000> rom{};
  Platform p;
  ASSERT_TRUE(p.add_rom(rom.data(), rom.size()));
  p.start();
  p.cycle();
  rom[1999] ^= 0x10U;  // a bit flips after the reference was taken
  const std::size_t cycles_per_pass = (rom.size() + p.rom_slice() - 1) / p.rom_slice();
  EXPECT_LE(cycles_per_pass, p.period()) << "within the integrity period";
  for (std::size_t k = 0; k < 2 * cycles_per_pass; ++k) {
    p.cycle();
  }
  EXPECT_FALSE(p.integrity_ok());
  rom[1999] ^= 0x10U;
  for (std::size_t k = 0; k < 2 * cycles_per_pass; ++k) {
    p.cycle();
  }
  EXPECT_FALSE(p.integrity_ok()) << "latched: memory that changed once is not trusted again";
}

TEST(Platform, ARegionAddedAfterTheStartTakesItsReferenceInTheFirstPass) {
  // safestate run adds its own code after the start-up self-test: no 3 MiB CRC between the
  // bus entering OP and the first cycle; the first pass is the reference, the next ones check.
  std::array<unsigned char, 400> code{};
  code[7] = 0x5A;
  Platform p;
  p.start();
  ASSERT_TRUE(p.add_rom(code.data(), code.size()));
  p.set_period(10);  // 40 bytes a cycle: a pass every 10 cycles
  for (int k = 0; k < 10; ++k) {
    p.cycle();
  }
  EXPECT_TRUE(p.integrity_ok()) << "the first pass took the reference";
  code[200] ^= 0x01U;
  for (int k = 0; k < 10; ++k) {
    p.cycle();
  }
  EXPECT_FALSE(p.integrity_ok()) << "the second pass found the change";
}

namespace {
// Bit 3 of the word at `g_stuck` reads 0 whatever is written: a RAM fault as the pattern test
// sees it (software cannot make one; this stands in for it).
volatile std::uint32_t* g_stuck = nullptr;
bool stuck_bit_3(volatile std::uint32_t* w) noexcept {
  if (w != g_stuck) {
    return controller::ram_word_ok(w);
  }
  const std::uint32_t saved = *w;
  const bool a = (0x55555555U & ~8U) == 0x55555555U;
  const bool b = (0xAAAAAAAAU & ~8U) == 0xAAAAAAAAU;
  *w = saved;
  return a && b;
}
}  // namespace

TEST(Platform, AWordThatDoesNotHoldAPatternIsFoundWithinOnePass) {
  std::uint32_t healthy = 0x12345678U;
  EXPECT_TRUE(controller::ram_word_ok(&healthy));
  EXPECT_EQ(healthy, 0x12345678U);

  std::array<std::uint32_t, 64> ram{};
  g_stuck = &ram[41];
  Platform p(&stuck_bit_3);
  ASSERT_TRUE(p.add_ram(ram.data(), sizeof ram));
  p.start();
  EXPECT_TRUE(p.self_test_ok()) << "the self-test's own scratch area is healthy";
  p.set_period(8);  // 64 words in 8 cycles: 8 a cycle
  ASSERT_EQ(p.ram_slice(), 8U);
  for (std::size_t k = 0; k < 41 / p.ram_slice(); ++k) {
    p.cycle();
  }
  EXPECT_TRUE(p.integrity_ok()) << "not yet at word 41";
  p.cycle();
  EXPECT_FALSE(p.integrity_ok());

  std::uint32_t misaligned[2] = {};
  EXPECT_FALSE(p.add_ram(reinterpret_cast<unsigned char*>(misaligned) + 1, 4)) << "words only";
  Platform q;
  EXPECT_FALSE(q.add_ram(nullptr, 4));
  EXPECT_FALSE(q.add_rom(nullptr, 4));
  g_stuck = nullptr;
}

namespace {
// A backend that holds the inputs of a healthy cell at rest and records the outputs.
struct Bench final : hal::Backend {
  hal::ProcessImageIn in{};
  hal::ProcessImageOut out{};
  void read(hal::ProcessImageIn& i) noexcept override { i = in; }
  void write(const hal::ProcessImageOut& o) noexcept override { out = o; }
};
}  // namespace

TEST(ControllerCell, RunsOnAnyBackendAndTheSupervisorReadsThePlatform) {
  Bench io;
  io.in.safety.estop_a = io.in.safety.estop_b = true;
  io.in.safety.gate_a = io.in.safety.gate_b = true;
  io.in.safety.mode_auto = true;
  const core::Config cfg{};
  controller::Cell cell(cfg, robot::active().model, io);
  EXPECT_TRUE(cell.platform().self_test_ok());
  EXPECT_GT(cell.platform().rom_bytes(), 1000U) << "the core's tables are under test";
  EXPECT_GT(cell.platform().ram_words(), 100U) << "the controller's state is under test";
  for (int k = 0; k < 50; ++k) {
    cell.step();
  }
  EXPECT_EQ(cell.now(), 50U);
  EXPECT_TRUE(cell.feedback().integrity_ok);
  EXPECT_TRUE(cell.feedback().self_test_ok);
  EXPECT_EQ(cell.out().alarms & core::bit(core::AlarmId::INTEGRITY_FAULT), 0U);

  // A copy runs on its own backend and tests its own state, not the original's.
  Bench io2 = io;
  controller::Cell copy(cell, io2);
  for (int k = 0; k < 50; ++k) {
    copy.step();
  }
  EXPECT_EQ(copy.now(), 100U);
  EXPECT_EQ(cell.now(), 50U);
  EXPECT_TRUE(copy.feedback().integrity_ok);

  // The backend's own integrity input still counts (ANDed, never overridden).
  io.in.integrity_ok = false;
  cell.step();
  EXPECT_FALSE(cell.feedback().integrity_ok);
}

// The platform's own checks of the running controller: where the integrity and start-up
// self-test results the supervisor reads (SPEC §2 feedback, INTEGRITY_FAULT / BOOT_FAILED)
// come from, whatever the backend. Measures of IEC 61508-2 Annex A / ISO 13849-1 Annex E's
// kind, in software:
//   - invariable memory (A.4): a CRC-32 of every registered constant region (the core's
//     tables; on a target also its code), taken once at start-up as the reference and then
//     recomputed in slices, all of it within the period (SPEC §14 `integrity_period_ms`,
//     1000 ms by default); a pass that differs is an
//     integrity fault, latched (the memory does not heal).
//   - variable memory (A.5): a non-destructive pattern test of every registered state area
//     (the supervisor's own object): all within the same period, each word saved, written with
//     0x55.../0xAA..., read back, restored; a word that does not read back is an integrity
//     fault, latched.
//   - start-up self-test: the CRC's known answer ("123456789" -> CBF43926), the pattern
//     test of a scratch area of its own, and the reference taken twice, equal.
// What it cannot see (a fault between two passes, a fault that reads back what was written)
// is the second channel's to catch (SPEC §14). No heap, no OS, no clock: slices per cycle.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace safestate::controller {

// CRC-32 (IEEE 802.3, reflected, init and final xor 0xFFFFFFFF) of `n` bytes, continuing `crc`
// (start with 0). Reads through a volatile pointer: the bytes in memory, not a folded constant.
[[nodiscard]] std::uint32_t crc32(std::uint32_t crc, const volatile unsigned char* p, std::size_t n) noexcept;

// The pattern test of one word: saved, 0x55.., 0xAA.. written and read back, restored.
// True when both read back. Not interruptible by anything that reads the word meanwhile.
[[nodiscard]] bool ram_word_ok(volatile std::uint32_t* w) noexcept;

class Platform {
 public:
  // The word test: ram_word_ok on a target's memory. A test gives one that sees a stuck bit
  // (a RAM fault cannot be made in software); nothing at run time can change it.
  using WordTest = bool (*)(volatile std::uint32_t*) noexcept;
  explicit Platform(WordTest word_test = &ram_word_ok) noexcept : word_test_(word_test) {}

  static constexpr std::size_t kMaxRegions = 8;

  // At start-up, before the first cycle(): false when the table is full, the region empty or
  // misaligned (RAM: 4-byte words). A ROM region added after start() gets its reference in
  // the first background pass over it (checked from the second pass on).
  bool add_rom(const void* p, std::size_t n) noexcept;
  bool add_ram(void* p, std::size_t n) noexcept;
  // After a copy of the object holding the RAM regions: regions inside [from, from + n) move
  // to the same offsets from `to` (the references and the progress are kept).
  void relocate(const void* from, void* to, std::size_t n) noexcept;
  // The start-up self-test and the ROM references.
  void start() noexcept;
  // SPEC §14 `integrity_period_ms`: every region is tested once within `cycles` cycles (the
  // slices follow from the regions' sizes; set again by each add). Before the first cycle().
  void set_period(std::uint32_t cycles) noexcept;
  [[nodiscard]] std::uint32_t period() const noexcept { return period_; }
  [[nodiscard]] std::size_t rom_slice() const noexcept { return rom_slice_; }  // bytes a cycle
  [[nodiscard]] std::size_t ram_slice() const noexcept { return ram_slice_; }  // words a cycle
  // One slice of the background tests (each cycle, between two cycles of the controller).
  void cycle() noexcept;

  [[nodiscard]] bool integrity_ok() const noexcept { return integrity_ok_; }
  [[nodiscard]] bool self_test_ok() const noexcept { return self_test_ok_; }
  // Completed passes over all ROM regions / all RAM words since start (for the status).
  [[nodiscard]] std::uint32_t rom_passes() const noexcept { return rom_passes_; }
  [[nodiscard]] std::uint32_t ram_passes() const noexcept { return ram_passes_; }
  [[nodiscard]] std::size_t rom_bytes() const noexcept;
  [[nodiscard]] std::size_t ram_words() const noexcept;

 private:
  struct Rom {
    const volatile unsigned char* p = nullptr;
    std::size_t n = 0;
    std::uint32_t reference = 0;
    bool reference_pending = false;  // added after start(): the first pass takes the reference
  };
  struct Ram {
    volatile std::uint32_t* p = nullptr;
    std::size_t words = 0;
  };
  std::uint32_t rom_reference(std::size_t i) const noexcept;

  WordTest word_test_;
  std::array<Rom, kMaxRegions> rom_{};
  std::array<Ram, kMaxRegions> ram_{};
  std::size_t roms_ = 0;
  std::size_t rams_ = 0;
  // Where the background tests are.
  std::size_t rom_region_ = 0;
  std::size_t rom_offset_ = 0;
  std::uint32_t rom_crc_ = 0;
  std::size_t ram_region_ = 0;
  std::size_t ram_word_ = 0;
  std::uint32_t rom_passes_ = 0;
  std::uint32_t ram_passes_ = 0;
  std::uint32_t period_ = 1000;
  std::size_t rom_slice_ = 4;
  std::size_t ram_slice_ = 1;
  bool started_ = false;
  bool cycled_ = false;
  bool integrity_ok_ = true;
  bool self_test_ok_ = false;  // until start() says otherwise
};

}  // namespace safestate::controller

#include "safestate/controller/platform.hpp"

#include <bit>

namespace safestate::controller {

namespace {

// Slicing-by-4 tables of the reflected CRC-32 (IEEE 802.3): a word per step.
using Tables = std::array<std::array<std::uint32_t, 256>, 4>;
constexpr Tables make_tables() noexcept {
  Tables t{};
  for (std::uint32_t i = 0; i < 256U; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) {
      c = ((c & 1U) != 0U) ? (0xEDB88320U ^ (c >> 1U)) : (c >> 1U);
    }
    t[0][i] = c;
  }
  for (std::size_t k = 1; k < 4U; ++k) {
    for (std::size_t i = 0; i < 256U; ++i) {
      t[k][i] = (t[k - 1U][i] >> 8U) ^ t[0][t[k - 1U][i] & 0xFFU];
    }
  }
  return t;
}
constexpr Tables kCrc = make_tables();

// The self-test's own scratch area (a march over it cannot disturb anything else).
std::array<std::uint32_t, 16> g_scratch{};

}  // namespace

std::uint32_t crc32(std::uint32_t crc, const volatile unsigned char* p, std::size_t n) noexcept {
  static_assert(std::endian::native == std::endian::little, "the word step assumes little-endian memory");
  std::uint32_t c = ~crc;
  while (n > 0U && (reinterpret_cast<std::uintptr_t>(p) % 4U) != 0U) {
    c = kCrc[0][(c ^ *p) & 0xFFU] ^ (c >> 8U);
    ++p;
    --n;
  }
  // Whole aligned words, read as words (a memory test reads the memory, whatever object it
  // holds: volatile, so that no read is folded or elided).
  const volatile std::uint32_t* w = reinterpret_cast<const volatile std::uint32_t*>(p);
  for (; n >= 4U; n -= 4U) {
    c ^= *w;
    ++w;
    c = kCrc[3][c & 0xFFU] ^ kCrc[2][(c >> 8U) & 0xFFU] ^ kCrc[1][(c >> 16U) & 0xFFU] ^ kCrc[0][c >> 24U];
  }
  p = reinterpret_cast<const volatile unsigned char*>(w);
  for (; n > 0U; --n) {
    c = kCrc[0][(c ^ *p) & 0xFFU] ^ (c >> 8U);
    ++p;
  }
  return ~c;
}

bool ram_word_ok(volatile std::uint32_t* w) noexcept {
  const std::uint32_t saved = *w;
  *w = 0x55555555U;
  const bool a = *w == 0x55555555U;
  *w = 0xAAAAAAAAU;
  const bool b = *w == 0xAAAAAAAAU;
  *w = saved;  // not compared: a word of padding holds no defined value (valgrind, MSan)
  return a && b;
}

bool Platform::add_rom(const void* p, std::size_t n) noexcept {
  if (cycled_ || roms_ >= kMaxRegions || p == nullptr || n == 0U) {
    return false;
  }
  // A host's region added after the start-up self-test (safestate run's own code, 3 MiB) takes
  // its reference in the first background pass, not now: the time between a fieldbus entering
  // OP and the first cycle stays short (its process-data watchdogs run from OP on).
  rom_[roms_] = Rom{static_cast<const volatile unsigned char*>(p), n, 0U, started_};
  ++roms_;
  set_period(period_);  // the slices cover the new region within the same period
  return true;
}

bool Platform::add_ram(void* p, std::size_t n) noexcept {
  if (cycled_ || rams_ >= kMaxRegions || p == nullptr || n < sizeof(std::uint32_t) ||
      (reinterpret_cast<std::uintptr_t>(p) % alignof(std::uint32_t)) != 0U) {
    return false;
  }
  ram_[rams_++] = Ram{static_cast<volatile std::uint32_t*>(p), n / sizeof(std::uint32_t)};
  set_period(period_);
  return true;
}

void Platform::relocate(const void* from, void* to, std::size_t n) noexcept {
  const auto lo = reinterpret_cast<std::uintptr_t>(from);
  for (std::size_t i = 0; i < rams_; ++i) {
    const auto at = reinterpret_cast<std::uintptr_t>(ram_[i].p);
    if (at >= lo && at - lo < n) {
      ram_[i].p = reinterpret_cast<volatile std::uint32_t*>(static_cast<unsigned char*>(to) + (at - lo));
    }
  }
}

std::uint32_t Platform::rom_reference(std::size_t i) const noexcept { return crc32(0U, rom_[i].p, rom_[i].n); }

void Platform::start() noexcept {
  static constexpr unsigned char kCheck[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  bool ok = crc32(0U, kCheck, sizeof kCheck) == 0xCBF43926U;
  for (std::uint32_t& w : g_scratch) {
    ok = ram_word_ok(&w) && ok;
  }
  for (std::size_t i = 0; i < roms_; ++i) {
    rom_[i].reference = rom_reference(i);
    ok = (rom_reference(i) == rom_[i].reference) && ok;
  }
  self_test_ok_ = ok;
  started_ = true;
}

void Platform::set_period(std::uint32_t cycles) noexcept {
  if (cycled_ || cycles == 0U) {
    return;
  }
  period_ = cycles;
  const std::size_t rom = (rom_bytes() + cycles - 1U) / cycles;
  rom_slice_ = (rom < 4U) ? 4U : ((rom + 3U) / 4U) * 4U;
  const std::size_t ram = (ram_words() + cycles - 1U) / cycles;
  ram_slice_ = (ram < 1U) ? 1U : ram;
}

void Platform::cycle() noexcept {
  if (!started_) {
    return;
  }
  cycled_ = true;
  if (roms_ > 0U) {
    const Rom& r = rom_[rom_region_];
    const std::size_t n = (r.n - rom_offset_ < rom_slice_) ? (r.n - rom_offset_) : rom_slice_;
    rom_crc_ = crc32(rom_crc_, r.p + rom_offset_, n);
    rom_offset_ += n;
    if (rom_offset_ >= r.n) {
      Rom& done = rom_[rom_region_];
      if (done.reference_pending) {
        done.reference = rom_crc_;
        done.reference_pending = false;
      } else {
        integrity_ok_ = integrity_ok_ && (rom_crc_ == done.reference);
      }
      rom_crc_ = 0U;
      rom_offset_ = 0U;
      if (++rom_region_ >= roms_) {
        rom_region_ = 0U;
        ++rom_passes_;
      }
    }
  }
  for (std::size_t k = 0; k < ram_slice_ && rams_ > 0U; ++k) {
    const Ram& m = ram_[ram_region_];
    integrity_ok_ = word_test_(m.p + ram_word_) && integrity_ok_;
    if (++ram_word_ >= m.words) {
      ram_word_ = 0U;
      if (++ram_region_ >= rams_) {
        ram_region_ = 0U;
        ++ram_passes_;
      }
    }
  }
}

std::size_t Platform::rom_bytes() const noexcept {
  std::size_t n = 0;
  for (std::size_t i = 0; i < roms_; ++i) {
    n += rom_[i].n;
  }
  return n;
}

std::size_t Platform::ram_words() const noexcept {
  std::size_t n = 0;
  for (std::size_t i = 0; i < rams_; ++i) {
    n += ram_[i].words;
  }
  return n;
}

}  // namespace safestate::controller

// The black channel's safety layer allocates nothing (core's rule, safelink/): configure,
// connect, 100,000 exchanges and every fault path run with the counting allocator armed.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>

#include "alloc_counter.hpp"
#include "safestate/safelink/link.hpp"

namespace sl = safestate::safelink;

TEST(SafelinkNoAlloc, ExchangesAndFaultsAllocateNothing) {
  sl::ConnectionParams p;
  p.id = 0xA001;
  p.host_data_bytes = 1;
  p.device_data_bytes = 4;
  p.watchdog_ms = 10;
  p.device = {0x5AFEU, 0x00D50001U, 2};
  std::array<std::uint8_t, sl::container_bytes(1)> h2d{};
  std::array<std::uint8_t, sl::container_bytes(4)> d2h{};
  std::array<std::uint8_t, 1> out{1};
  std::array<std::uint8_t, 4> in{1, 2, 3, 4};
  sl::HostEnd host;
  sl::DeviceEnd dev;
  long ok = 0;
  armed.store(true);
  ASSERT_EQ(host.configure(p, 1000), sl::ConfigError::None);
  ASSERT_EQ(dev.configure(p, 1000, 77), sl::ConfigError::None);
  for (std::uint16_t session = 1; session <= 10; ++session) {
    (void)host.connect(session);
    for (int i = 0; i < 10000; ++i) {
      in[0] = static_cast<std::uint8_t>(i);
      ok += host.cycle(d2h, out, h2d) == sl::Verdict::Ok ? 1 : 0;
      if (i == 5000) h2d[9] ^= 0x10U;  // a corrupted container: the device fails safe
      (void)dev.cycle(h2d, in, d2h);
    }
  }
  armed.store(false);
  EXPECT_EQ(allocations.load(), 0);
  EXPECT_GT(ok, 40000);
}

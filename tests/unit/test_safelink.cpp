// The black channel's safety layer (issue 37, docs/black-channel.md): CRC-64/XZ, the container,
// and the two ends against every communication error IEC 61784-3 lists (corruption,
// unintended repetition, incorrect sequence, loss, unacceptable delay, insertion,
// masquerade, addressing), each caught with its own verdict and the device's outputs off.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "safestate/safelink/container.hpp"
#include "safestate/safelink/crc64.hpp"
#include "safestate/safelink/link.hpp"
#include "safestate/hal/safety_links.hpp"

namespace sl = safestate::safelink;
using sl::Verdict;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr std::uint32_t kCycleUs = 1000;

// Channel A <-> the safe output terminal (K1): one byte each way, 10 ms watchdog.
sl::ConnectionParams k1_params() {
  sl::ConnectionParams p;
  p.id = 0xA002;
  p.host_data_bytes = 1;
  p.device_data_bytes = 1;
  p.watchdog_ms = 10;
  p.device = {0x00000E5AU, 0x00010002U, 1002};
  return p;
}

// Channel A <-> the safe input terminal: no data to the device, 4 bytes of contacts back.
sl::ConnectionParams di_params() {
  sl::ConnectionParams p;
  p.id = 0xA001;
  p.host_data_bytes = 0;
  p.device_data_bytes = 4;
  p.watchdog_ms = 10;
  p.device = {0x00000E5AU, 0x00010001U, 1001};
  return p;
}

// A host and a device joined by a bus that copies bytes: one step is a host cycle (it reads
// the device's container) and a device cycle (it reads the host's).
struct Pair {
  sl::HostEnd host;
  sl::DeviceEnd dev;
  Bytes h2d;  // what the host sent last
  Bytes d2h;  // what the device sent last
  Bytes out;  // the host's safety data
  Bytes in;   // the device's safety data
  Verdict hv = Verdict::NotConnected;
  Verdict dv = Verdict::NotConnected;

  explicit Pair(const sl::ConnectionParams& p, std::uint16_t host_session = 0x1234, std::uint16_t dev_seed = 0x0777) {
    EXPECT_EQ(host.configure(p, kCycleUs), sl::ConfigError::None);
    EXPECT_EQ(dev.configure(p, kCycleUs, dev_seed), sl::ConfigError::None);
    h2d.assign(host.tx_bytes(), 0);
    d2h.assign(dev.tx_bytes(), 0);
    out.assign(p.host_data_bytes, 0);
    in.assign(p.device_data_bytes, 0);
    EXPECT_TRUE(host.connect(host_session));
  }
  void host_step() { hv = host.cycle(d2h, out, h2d); }
  void dev_step() { dv = dev.cycle(h2d, in, d2h); }
  void step() {
    host_step();
    dev_step();
  }
  // Connected with data both ways (the first data exchange done).
  void up() {
    for (int i = 0; i < 3; ++i) step();
    ASSERT_EQ(hv, Verdict::Ok);
    ASSERT_EQ(dv, Verdict::Ok);
    ASSERT_TRUE(dev.outputs_enabled());
    ASSERT_TRUE(host.data_valid());
  }
};

}  // namespace

// ---- CRC-64/XZ -----------------------------------------------------------------------------

// Every container fits the process image's slot for it (hal::LinkSlot, which a backend copies
// without knowing safelink): checked here so that safelink does not depend on hal.
static_assert(sl::kMaxContainer <= safestate::hal::kLinkBytes, "a container must fit hal::kLinkBytes");
static_assert(sl::container_bytes(0) == 15 && sl::container_bytes(1) == 16 && sl::container_bytes(4) == 19);

TEST(SafelinkCrc, KnownValues) {
  // Values of liblzma's CRC-64 (the .xz format's check, read out of files Python's lzma wrote
  // with CHECK_CRC64), not of this code.
  std::array<std::uint8_t, 32> zeros{};
  std::array<std::uint8_t, 32> ones{};
  ones.fill(0xFF);
  std::array<std::uint8_t, 32> inc{};
  for (std::size_t i = 0; i < inc.size(); ++i) inc[i] = static_cast<std::uint8_t>(i);
  EXPECT_EQ(sl::crc64(zeros), 0xC95AF8617CD5330CULL);
  EXPECT_EQ(sl::crc64(ones), 0xE95DCE9EFAA09ACFULL);
  EXPECT_EQ(sl::crc64(inc), 0x7FE571A587084D10ULL);
  // Carrying the register across calls is the same as one call.
  const std::uint64_t reg = sl::crc64_update(sl::kCrc64Init, std::span{inc}.first(10));
  EXPECT_EQ(sl::crc64_final(sl::crc64_update(reg, std::span{inc}.subspan(10))), 0x7FE571A587084D10ULL);
}

TEST(SafelinkContainer, LayoutAndCrc) {
  const auto p = k1_params();
  const std::uint64_t prefix = sl::prefix_register(p, 0x1234, 0x0777);
  std::array<std::uint8_t, 1> data{0x5A};
  std::array<std::uint8_t, 16> c{};
  const sl::Header h{sl::Kind::HostData, 0xA002, 0xBEEF, 0x0102};
  ASSERT_TRUE(sl::encode(prefix, h, 3, 4, data, c));
  EXPECT_EQ(c[0], 0x10);
  EXPECT_EQ(c[1], 0x02);
  EXPECT_EQ(c[2], 0xA0);
  EXPECT_EQ(c[3], 0xEF);
  EXPECT_EQ(c[4], 0xBE);
  EXPECT_EQ(c[5], 0x02);
  EXPECT_EQ(c[6], 0x01);
  EXPECT_EQ(c[7], 0x5A);
  // The CRC at 7+n, 8 bytes little-endian: CRC-64/XZ over the prefix P, the counters' high
  // halves and bytes 0..7, computed here from the documented layout of P.
  const std::array<std::uint8_t, 24> pb{'S', 'S', 'B', '1', 0x02, 0xA0, 1, 1, 10, 0, 0x5A, 0x0E, 0, 0,
                                        0x02, 0x00, 0x01, 0x00, 0xEA, 0x03, 0x34, 0x12, 0x77, 0x07};
  const std::array<std::uint8_t, 4> hi{3, 0, 4, 0};
  const std::uint64_t want =
      sl::crc64_final(sl::crc64_update(sl::crc64_update(sl::crc64_update(sl::kCrc64Init, pb), hi), std::span{c}.first(8)));
  std::uint64_t stored = 0;
  for (std::size_t i = 0; i < 8U; ++i) stored |= static_cast<std::uint64_t>(c[8U + i]) << (8U * i);
  EXPECT_EQ(stored, want);
  EXPECT_EQ(sl::prefix_register(p, 0x1234, 0x0777), sl::crc64_update(sl::kCrc64Init, pb));
  EXPECT_TRUE(sl::crc_matches(prefix, 3, 4, c));
  // The unsent parts are in the CRC: the counters' high halves, sessions, every parameter.
  EXPECT_FALSE(sl::crc_matches(prefix, 4, 4, c));
  EXPECT_FALSE(sl::crc_matches(prefix, 3, 5, c));
  EXPECT_FALSE(sl::crc_matches(sl::prefix_register(p, 0x1235, 0x0777), 3, 4, c));
  EXPECT_FALSE(sl::crc_matches(sl::prefix_register(p, 0x1234, 0x0778), 3, 4, c));
  auto q = p;
  q.watchdog_ms = 11;
  EXPECT_FALSE(sl::crc_matches(sl::prefix_register(q, 0x1234, 0x0777), 3, 4, c));
  q = p;
  q.device.position = 1003;
  EXPECT_FALSE(sl::crc_matches(sl::prefix_register(q, 0x1234, 0x0777), 3, 4, c));
  q = p;
  q.device.vendor_id ^= 1U;
  EXPECT_FALSE(sl::crc_matches(sl::prefix_register(q, 0x1234, 0x0777), 3, 4, c));
  // Wrong sizes are refused and write nothing.
  std::array<std::uint8_t, 17> wrong{};
  EXPECT_FALSE(sl::encode(prefix, h, 3, 4, data, wrong));
  EXPECT_TRUE(sl::all_zero(wrong));
  std::array<std::uint8_t, 14> tiny{};
  EXPECT_FALSE(sl::crc_matches(prefix, 0, 0, tiny));
}

TEST(SafelinkConfig, EveryBadParameterRefusedAndNothingChanges) {
  sl::HostEnd host;
  sl::DeviceEnd dev;
  auto p = k1_params();
  p.id = 0;
  EXPECT_EQ(host.configure(p, kCycleUs), sl::ConfigError::ZeroId);
  p = k1_params();
  p.device_data_bytes = 17;
  EXPECT_EQ(dev.configure(p, kCycleUs, 1), sl::ConfigError::DataTooLong);
  p = k1_params();
  p.watchdog_ms = 0;
  EXPECT_EQ(host.configure(p, kCycleUs), sl::ConfigError::BadWatchdog);
  p.watchdog_ms = 60001;
  EXPECT_EQ(host.configure(p, kCycleUs), sl::ConfigError::BadWatchdog);
  p = k1_params();
  EXPECT_EQ(host.configure(p, 49), sl::ConfigError::BadCycle);
  EXPECT_EQ(host.configure(p, 100001), sl::ConfigError::BadCycle);
  p.watchdog_ms = 1;
  EXPECT_EQ(host.configure(p, 1000), sl::ConfigError::WatchdogTooShort);
  EXPECT_EQ(host.state(), sl::LinkState::Unconfigured);
  EXPECT_FALSE(host.connect(1));
  EXPECT_EQ(dev.state(), sl::LinkState::Unconfigured);
  // Unconfigured ends send zeros and accept nothing.
  Bytes tx(16, 0xFF);
  EXPECT_EQ(dev.cycle(Bytes(16, 1), Bytes(1, 1), tx), Verdict::NotConnected);
  EXPECT_TRUE(sl::all_zero(tx));
  EXPECT_FALSE(dev.outputs_enabled());
  // Session 0 is refused.
  ASSERT_EQ(host.configure(k1_params(), kCycleUs), sl::ConfigError::None);
  EXPECT_FALSE(host.connect(0));
  EXPECT_EQ(host.state(), sl::LinkState::Idle);
  EXPECT_STREQ(sl::to_string(sl::ConfigError::WatchdogTooShort), "watchdog shorter than 2 cycles");
}

// ---- valid traffic ---------------------------------------------------------------------------

TEST(SafelinkTraffic, ConnectsAndOutputsStayOffUntilTheFirstData) {
  Pair b(k1_params());
  b.out[0] = 1;
  b.step();  // host: connect out; device: session opened
  EXPECT_EQ(b.hv, Verdict::NotConnected);
  EXPECT_EQ(b.dv, Verdict::Ok);
  EXPECT_EQ(b.dev.state(), sl::LinkState::Connected);
  EXPECT_FALSE(b.dev.outputs_enabled());
  EXPECT_EQ(b.dev.outputs()[0], 0);
  b.step();  // host: session up, first data out; device: first data in
  EXPECT_EQ(b.hv, Verdict::Ok);
  EXPECT_EQ(b.dv, Verdict::Ok);
  EXPECT_TRUE(b.dev.outputs_enabled());
  EXPECT_EQ(b.dev.outputs()[0], 1);
  EXPECT_FALSE(b.host.data_valid());
  b.step();
  EXPECT_TRUE(b.host.data_valid());
}

TEST(SafelinkTraffic, LongRunPastTheSequenceWrapAround) {
  Pair b(di_params());
  b.up();
  // 140,000 exchanges: the 16 sent bits of both counters wrap twice, the high halves
  // (in the CRC only) count on; every container is new, valid and carries its own data.
  for (std::uint32_t i = 0; i < 140000U; ++i) {
    const std::uint32_t v = i * 2654435761U;
    for (std::size_t k = 0; k < 4; ++k) b.in[k] = static_cast<std::uint8_t>(v >> (8U * k));
    b.step();
    ASSERT_EQ(b.hv, Verdict::Ok) << i;
    ASSERT_EQ(b.dv, Verdict::Ok) << i;
    if (i > 0) {
      const std::uint32_t prev = (i - 1U) * 2654435761U;  // the device's data lags one exchange
      for (std::size_t k = 0; k < 4; ++k) ASSERT_EQ(b.host.data()[k], static_cast<std::uint8_t>(prev >> (8U * k)));
    }
  }
  EXPECT_GT(b.host.seq(), 0x20000U);
}

TEST(SafelinkTraffic, SlowBusRepeatsWithinTheWatchdogAreNotFaults) {
  Pair b(k1_params());
  b.up();
  // The bus delivers each container three times before the answer comes: repetitions.
  for (int i = 0; i < 100; ++i) {
    b.host_step();
    ASSERT_EQ(b.hv, i == 0 ? Verdict::Ok : Verdict::Repetition);
    b.dev_step();
    ASSERT_EQ(b.dv, Verdict::Ok);
    b.dev_step();
    ASSERT_EQ(b.dv, Verdict::Repetition);
    b.host_step();
    ASSERT_EQ(b.hv, Verdict::Ok);
    b.host_step();
    ASSERT_EQ(b.hv, Verdict::Repetition);
    ASSERT_TRUE(b.dev.outputs_enabled());
  }
}

// ---- corruption ------------------------------------------------------------------------------

namespace {
// The verdict a flipped bit in `byte` must give: the kind byte may turn into another kind
// (identity, sequence) or an unknown one (crc); the connection id names another connection.
void expect_flip_verdict(Verdict v, std::size_t byte, const std::string& where) {
  if (byte == 0) {
    EXPECT_TRUE(v == Verdict::Crc || v == Verdict::Identity || v == Verdict::Sequence) << where << sl::to_string(v);
  } else if (byte == 1 || byte == 2) {
    EXPECT_EQ(v, Verdict::Identity) << where;
  } else {
    EXPECT_EQ(v, Verdict::Crc) << where;
  }
}
}  // namespace

TEST(SafelinkCorruption, EveryFlippedBitOfAHostContainerIsCaught) {
  for (const auto& p : {k1_params(), di_params()}) {
    Pair b(p);
    b.up();
    b.out.assign(p.host_data_bytes, 0x01);
    b.host_step();  // a new host container, not yet delivered
    const Bytes good = b.h2d;
    for (std::size_t bit = 0; bit < good.size() * 8U; ++bit) {
      sl::DeviceEnd dev = b.dev;  // the device as it was, for each flip
      Bytes bad = good;
      bad[bit / 8U] ^= static_cast<std::uint8_t>(1U << (bit % 8U));
      Bytes tx(dev.tx_bytes(), 0);
      const Verdict v = dev.cycle(bad, b.in, tx);
      expect_flip_verdict(v, bit / 8U, "bit " + std::to_string(bit) + " ");
      EXPECT_FALSE(dev.outputs_enabled()) << bit;
      EXPECT_EQ(dev.state(), sl::LinkState::Failed) << bit;
      EXPECT_TRUE(sl::all_zero(tx)) << bit;  // nothing valid goes back
    }
    // The good one passes (the copies above did not share state).
    b.dev_step();
    EXPECT_EQ(b.dv, Verdict::Ok);
  }
}

TEST(SafelinkCorruption, EveryFlippedBitOfADeviceContainerIsCaught) {
  for (const auto& p : {k1_params(), di_params()}) {
    Pair b(p);
    b.up();
    b.in.assign(p.device_data_bytes, 0xFF);
    b.host_step();
    b.dev_step();  // a new device container, not yet delivered
    const Bytes good = b.d2h;
    for (std::size_t bit = 0; bit < good.size() * 8U; ++bit) {
      sl::HostEnd host = b.host;
      Bytes bad = good;
      bad[bit / 8U] ^= static_cast<std::uint8_t>(1U << (bit % 8U));
      Bytes tx(host.tx_bytes(), 0);
      const Verdict v = host.cycle(bad, b.out, tx);
      expect_flip_verdict(v, bit / 8U, "bit " + std::to_string(bit) + " ");
      EXPECT_FALSE(host.data_valid()) << bit;
      EXPECT_TRUE(sl::all_zero(host.data())) << bit;  // the safe values
      EXPECT_EQ(host.fault(), v) << bit;
    }
    b.host_step();
    EXPECT_EQ(b.hv, Verdict::Ok);
  }
}

// ---- repetition, sequence, loss, delay -------------------------------------------------------

TEST(SafelinkRepetition, ARepeatedContainerIsNotNewAndPastTheWatchdogOpensTheOutputs) {
  Pair b(k1_params());
  b.out[0] = 1;
  b.up();
  b.host_step();
  b.dev_step();
  ASSERT_EQ(b.dv, Verdict::Ok);
  // The bus (or a faulty master) keeps delivering the same container: 10 ms watchdog, 1 ms.
  for (int i = 1; i < 10; ++i) {
    b.dev_step();
    ASSERT_EQ(b.dv, Verdict::Repetition) << i;
    ASSERT_TRUE(b.dev.outputs_enabled()) << i;
  }
  b.dev_step();
  EXPECT_EQ(b.dv, Verdict::Timeout);
  EXPECT_FALSE(b.dev.outputs_enabled());
  EXPECT_EQ(b.dev.outputs()[0], 0);
  EXPECT_EQ(b.dev.fault(), Verdict::Timeout);
}

TEST(SafelinkRepetition, SameSequenceWithOtherContentIsASequenceError) {
  Pair c(k1_params());
  c.up();
  sl::HostEnd twin = c.host;  // the host as it is, made to send other data at the same number
  Bytes other(twin.tx_bytes(), 0);
  (void)twin.cycle(c.d2h, Bytes{1}, other);
  c.out[0] = 0;
  c.host_step();
  c.dev_step();
  ASSERT_EQ(c.dv, Verdict::Ok);
  ASSERT_NE(other, c.h2d);
  EXPECT_EQ(c.dev.cycle(other, c.in, c.d2h), Verdict::Sequence);
  EXPECT_FALSE(c.dev.outputs_enabled());
}

TEST(SafelinkSequence, AnOldContainerReplayedLaterIsCaught) {
  Pair b(k1_params());
  b.out[0] = 1;
  b.up();
  b.host_step();
  const Bytes old_h2d = b.h2d;
  b.dev_step();
  const Bytes old_d2h = b.d2h;
  for (int i = 0; i < 10; ++i) b.step();
  ASSERT_EQ(b.dv, Verdict::Ok);
  sl::HostEnd host = b.host;
  Bytes tx(host.tx_bytes(), 0);
  EXPECT_EQ(host.cycle(old_d2h, b.out, tx), Verdict::Sequence);
  EXPECT_FALSE(host.data_valid());
  EXPECT_EQ(b.dev.cycle(old_h2d, b.in, b.d2h), Verdict::Sequence);
  EXPECT_FALSE(b.dev.outputs_enabled());
}

TEST(SafelinkSequence, AContainerReplayedAWholeWrapLaterIsCaught) {
  // 65,536 exchanges later the 16 bits sent (sequence and acknowledge) are the same again:
  // only the counters' high halves, in the CRC and never sent, tell the old one apart.
  Pair b(k1_params());
  b.out[0] = 1;
  b.up();
  b.host_step();
  const Bytes old_h2d = b.h2d;
  b.dev_step();
  for (std::uint32_t i = 0; i < 65535U; ++i) b.step();
  ASSERT_EQ(b.dv, Verdict::Ok);
  b.host_step();  // the host's next container, whose 16-bit numbers equal the old one's
  ASSERT_EQ(0, std::memcmp(b.h2d.data() + 3, old_h2d.data() + 3, 4));
  EXPECT_EQ(b.dev.cycle(old_h2d, b.in, b.d2h), Verdict::Crc);
  EXPECT_FALSE(b.dev.outputs_enabled());
}

TEST(SafelinkSequence, AGapIsCaught) {
  Pair b(k1_params());
  b.up();
  const sl::DeviceEnd before = b.dev;  // expects the host's next number n
  b.step();                            // n
  b.step();                            // n + 1
  b.host_step();                       // n + 2, not delivered
  sl::DeviceEnd dev = before;
  Bytes tx(dev.tx_bytes(), 0);
  EXPECT_EQ(dev.cycle(b.h2d, b.in, tx), Verdict::Sequence);
  EXPECT_FALSE(dev.outputs_enabled());
  // and the other way: the host that missed one of the device's containers.
  Pair c(k1_params());
  c.up();
  const sl::HostEnd host_before = c.host;
  c.step();
  c.step();
  sl::HostEnd host = host_before;
  Bytes htx(host.tx_bytes(), 0);
  EXPECT_EQ(host.cycle(c.d2h, c.out, htx), Verdict::Sequence);
  EXPECT_FALSE(host.data_valid());
}

TEST(SafelinkSequence, AContainerOfAnEarlierSessionIsCaught) {
  Pair b(k1_params());
  b.up();
  b.host_step();
  const Bytes session1 = b.h2d;
  // The host reconnects (new session); the device takes it; the old container comes back.
  ASSERT_TRUE(b.host.connect(0x4321));
  b.up();
  // Rewind the device's counter is impossible from the wire; the old container's number may
  // even match: the sessions in the CRC reject it.
  EXPECT_EQ(b.dev.cycle(session1, b.in, b.d2h), Verdict::Crc);
  EXPECT_FALSE(b.dev.outputs_enabled());
}

TEST(SafelinkDelay, NoNewContainerWithinTheWatchdogIsATimeoutAtBothEnds) {
  Pair b(k1_params());
  b.out[0] = 1;
  b.up();
  // The master stops forwarding: each end sees the other's last container again and again.
  const Bytes frozen_d2h = b.d2h;
  int dev_cycles = 0;
  for (; dev_cycles < 100 && b.dev.outputs_enabled(); ++dev_cycles) b.dev_step();
  // Accepted at the up() step; then 9 repetitions within 10 ms; the 10th call times out.
  EXPECT_EQ(dev_cycles, 10);
  EXPECT_EQ(b.dv, Verdict::Timeout);
  // The device's last answer reaches the host once (new), then only again and again.
  ASSERT_EQ(b.host.cycle(frozen_d2h, b.out, b.h2d), Verdict::Ok);
  int host_cycles = 0;
  for (; host_cycles < 100 && b.host.data_valid(); ++host_cycles) b.hv = b.host.cycle(frozen_d2h, b.out, b.h2d);
  EXPECT_EQ(host_cycles, 10);
  EXPECT_EQ(b.hv, Verdict::Timeout);
  EXPECT_EQ(b.host.fault(), Verdict::Timeout);
  // A late container does not bring them back: the session is over.
  b.step();
  EXPECT_EQ(b.dv, Verdict::NotConnected);
  EXPECT_FALSE(b.dev.outputs_enabled());
  EXPECT_FALSE(b.host.data_valid());
}

TEST(SafelinkDelay, AContainerHeldBackPastTheWatchdogIsRefused) {
  for (const int held : {9, 10}) {
    Pair b(k1_params());
    b.out[0] = 1;
    b.up();
    const Bytes previous = b.h2d;
    b.host_step();
    const Bytes delayed = b.h2d;  // held back by the master for `held` cycles
    for (int i = 0; i < held; ++i) b.dev.cycle(previous, b.in, b.d2h);
    const Verdict v = b.dev.cycle(delayed, b.in, b.d2h);
    if (held < 10) {
      // Within the watchdog (10 ms, the 10th cycle without a new container times out).
      EXPECT_EQ(v, Verdict::Ok) << held;
      EXPECT_TRUE(b.dev.outputs_enabled()) << held;
    } else {
      EXPECT_EQ(b.dev.fault(), Verdict::Timeout) << held;
      EXPECT_EQ(v, Verdict::NotConnected) << held;
      EXPECT_FALSE(b.dev.outputs_enabled()) << held;
    }
  }
}

TEST(SafelinkLoss, ADeviceReceivingNothingIsFailSafe) {
  // Never connected: zeros on the bus, outputs off.
  Pair idle(k1_params());
  for (int i = 0; i < 50; ++i) idle.dev_step();
  EXPECT_EQ(idle.dv, Verdict::NotConnected);
  EXPECT_FALSE(idle.dev.outputs_enabled());
  EXPECT_EQ(idle.dev.state(), sl::LinkState::Idle);
  EXPECT_TRUE(sl::all_zero(idle.d2h));
  // Connected, then the master delivers zeros (the host's container lost): outputs off at once.
  Pair b(k1_params());
  b.out[0] = 1;
  b.up();
  Bytes zeros(b.dev.rx_bytes(), 0);
  EXPECT_EQ(b.dev.cycle(zeros, b.in, b.d2h), Verdict::NotConnected);
  EXPECT_FALSE(b.dev.outputs_enabled());
  EXPECT_EQ(b.dev.outputs()[0], 0);
  EXPECT_EQ(b.dev.fault(), Verdict::NotConnected);
  // The host then sees the device fail-safe (zeros): not connected, latched.
  b.host_step();
  EXPECT_EQ(b.hv, Verdict::NotConnected);
  EXPECT_EQ(b.host.state(), sl::LinkState::Failed);
  // A new session brings the connection back.
  ASSERT_TRUE(b.host.connect(0x5555));
  b.up();
  EXPECT_EQ(b.dev.outputs()[0], 1);
}

TEST(SafelinkLoss, HostWithoutAnAnswerTimesOutWhileConnecting) {
  sl::HostEnd host;
  ASSERT_EQ(host.configure(k1_params(), kCycleUs), sl::ConfigError::None);
  ASSERT_TRUE(host.connect(7));
  Bytes rx(host.rx_bytes(), 0);
  Bytes tx(host.tx_bytes(), 0);
  Bytes out(1, 0);
  for (int i = 1; i < 10; ++i) ASSERT_EQ(host.cycle(rx, out, tx), Verdict::NotConnected) << i;
  EXPECT_EQ(host.cycle(rx, out, tx), Verdict::Timeout);
  EXPECT_EQ(host.state(), sl::LinkState::Failed);
  EXPECT_TRUE(sl::all_zero(tx));
}

// ---- insertion, masquerade, addressing -------------------------------------------------------

TEST(SafelinkIdentity, ContainersOfTwoConnectionsSwappedAreCaught) {
  auto pa = k1_params();  // channel A <-> K1
  auto pb = k1_params();  // channel B <-> K2, on the same terminal
  pb.id = 0xB002;
  Pair a(pa, 0x1111, 0x0101);
  Pair b(pb, 0x1111, 0x0101);  // even with the same sessions
  a.up();
  b.up();
  a.host_step();
  b.host_step();
  sl::DeviceEnd da = a.dev;
  sl::DeviceEnd db = b.dev;
  Bytes tx(da.tx_bytes(), 0);
  EXPECT_EQ(da.cycle(b.h2d, a.in, tx), Verdict::Identity);
  EXPECT_EQ(db.cycle(a.h2d, b.in, tx), Verdict::Identity);
  EXPECT_FALSE(da.outputs_enabled());
  EXPECT_FALSE(db.outputs_enabled());
  a.dev_step();
  b.dev_step();
  sl::HostEnd ha = a.host;
  Bytes htx(ha.tx_bytes(), 0);
  EXPECT_EQ(ha.cycle(b.d2h, a.out, htx), Verdict::Identity);
}

TEST(SafelinkIdentity, AHostContainerPresentedAsADevicesIsCaught) {
  Pair b(k1_params());
  b.up();
  b.host_step();
  b.dev_step();
  // The host's own container handed back to it as the device's (a master looping the frame).
  sl::HostEnd host = b.host;
  Bytes tx(host.tx_bytes(), 0);
  EXPECT_EQ(host.cycle(b.h2d, b.out, tx), Verdict::Identity);
  EXPECT_FALSE(host.data_valid());
  // And the device's container handed to the device.
  sl::DeviceEnd dev = b.dev;
  Bytes dtx(dev.tx_bytes(), 0);
  EXPECT_EQ(dev.cycle(b.d2h, b.in, dtx), Verdict::Identity);
  EXPECT_FALSE(dev.outputs_enabled());
}

TEST(SafelinkIdentity, TheRightIdOnTheWrongDeviceIsCaught) {
  // Addressing: the same connection id configured for a device at another position (or of
  // another product): its containers never validate, not even the connect.
  auto p = k1_params();
  auto q = p;
  q.device.position = 1003;
  sl::HostEnd host;
  sl::DeviceEnd dev;
  ASSERT_EQ(host.configure(p, kCycleUs), sl::ConfigError::None);
  ASSERT_EQ(dev.configure(q, kCycleUs, 9), sl::ConfigError::None);
  ASSERT_TRUE(host.connect(0x2222));
  Bytes h2d(host.tx_bytes(), 0);
  Bytes d2h(dev.tx_bytes(), 0);
  Bytes one(1, 1);
  (void)host.cycle(d2h, one, h2d);
  EXPECT_EQ(dev.cycle(h2d, one, d2h), Verdict::Crc);
  EXPECT_FALSE(dev.outputs_enabled());
  EXPECT_EQ(dev.state(), sl::LinkState::Idle);
}

TEST(SafelinkIdentity, AnInsertedConnectMidSessionTurnsTheOutputsOff) {
  // A connect container from an earlier session inserted by the master: the device takes a
  // new session (outputs off until data), and the host sees a session it did not open.
  Pair b(k1_params());
  b.out[0] = 1;
  b.step();
  const Bytes old_connect = b.h2d;
  b.up();
  ASSERT_TRUE(b.dev.outputs_enabled());
  b.host_step();
  EXPECT_EQ(b.dev.cycle(old_connect, b.in, b.d2h), Verdict::Ok);
  EXPECT_FALSE(b.dev.outputs_enabled());
  b.host_step();
  EXPECT_EQ(b.hv, Verdict::Sequence);
  EXPECT_FALSE(b.host.data_valid());
}

TEST(SafelinkLength, WrongSizesAreRefused) {
  Pair b(k1_params());
  b.up();
  Bytes longer(b.dev.rx_bytes() + 1, 0x10);
  EXPECT_EQ(b.dev.cycle(longer, b.in, b.d2h), Verdict::Length);
  EXPECT_FALSE(b.dev.outputs_enabled());
  Pair c(k1_params());
  c.up();
  Bytes out2(2, 0);
  EXPECT_EQ(c.host.cycle(c.d2h, out2, c.h2d), Verdict::Length);
  EXPECT_FALSE(c.host.data_valid());
}

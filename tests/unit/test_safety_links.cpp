// Issue 37, the black channel in a channel (controller/safety_links.hpp): a controller::Cell
// alone on a backend that carries the sixteen connections of the shipped segment (safe input
// terminal, safe output terminal, six drives' load-side encoders; A's and B's), with the
// devices' ends (safelink::DeviceEnd) on the other side of a wire that a test can rewrite:
// the master in the middle copies bytes, and whatever it does to them, the channel either
// gets the devices' data or the safe values and SAFETY_LINK_FAULT naming the connection.
#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <functional>
#include <span>
#include <string>

#include "safestate/controller/cell.hpp"
#include "safestate/core/config.hpp"
#include "safestate/core/describe.hpp"
#include "safestate/robot/description.hpp"
#include "safestate/safelink/link.hpp"
#include "safestate/sim/black_channel.hpp"

using namespace safestate;

namespace {

constexpr std::uint32_t kCountsPerRev = sim::kLoadCountsPerRev;

// The shipped segment's connections, in its bus configuration's order (the simulated world's
// table: test_sim_black_channel holds it to default-bus.json's).
using sim::shipped_links;

std::size_t index_of(const hal::LinkTable& t, std::uint16_t id) {
  for (std::size_t i = 0; i < t.count; ++i) {
    if (t.link[i].id == id) return i;
  }
  return hal::kMaxLinks;
}

// The bits of the safe input terminal's contact word (the DI terminal's layout).
std::uint32_t healthy_contacts() {
  using namespace controller::fdi;
  return (1U << kEstopA) | (1U << kEstopB) | (1U << kGateA) | (1U << kGateB) | (1U << kModeAuto) |
         (1U << kReducedA) | (1U << kReducedB) | (1U << kFieldOuterA) | (1U << kFieldOuterB) |
         (1U << kFieldInnerA) | (1U << kFieldInnerB);
}

// The segment: a plain process image (what the master decodes of the non-safe PDOs) and the
// devices' ends; `to_host` / `to_device` rewrite the containers on their way (the master or
// the wire at fault).
struct Segment final : hal::Backend {
  hal::LinkTable table = shipped_links();
  std::array<safelink::DeviceEnd, hal::kMaxLinks> dev{};
  hal::ProcessImageIn plain{};  // the non-safe PDOs as the master decoded them
  std::array<hal::LinkFrame, hal::kMaxLinks> from_dev{};  // each device's last container
  std::uint32_t contacts = healthy_contacts();
  std::array<std::int32_t, 6> load_counts{};
  bool silent = false;  // the devices stop answering (their containers held)
  std::function<void(std::array<hal::LinkFrame, hal::kMaxLinks>&)> to_host;
  std::function<void(std::array<hal::LinkFrame, hal::kMaxLinks>&)> to_device;
  std::array<std::uint8_t, hal::kMaxLinks> fdo_data{};  // what the F-DO ends hold as outputs
  std::array<bool, hal::kMaxLinks> fdo_on{};

  Segment() {
    for (std::size_t i = 0; i < table.count; ++i) {
      const hal::LinkSpec& s = table.link[i];
      EXPECT_EQ(dev[i].configure(controller::link_params(s), 1000, static_cast<std::uint16_t>(0x300 + i)), safelink::ConfigError::None);
      from_dev[i].len = static_cast<std::uint8_t>(safelink::container_bytes(s.device_data_bytes));
    }
    plain.safety.estop_a = plain.safety.estop_b = true;
    plain.safety.gate_a = plain.safety.gate_b = true;
    plain.safety.mode_auto = true;
    plain.two_contactors = true;
    plain.load_encoders = true;
    for (auto& d : plain.drive) d.statusword = 0x0040;  // switch on disabled: answering
  }
  const safelink::DeviceEnd& device(std::uint16_t id) const { return dev[index_of(table, id)]; }

  void read(hal::ProcessImageIn& in) noexcept override {
    in = plain;
    std::array<hal::LinkFrame, hal::kMaxLinks> f = from_dev;
    if (to_host) to_host(f);
    in.link_rx = f;
  }
  void write(const hal::ProcessImageOut& out) noexcept override {
    std::array<hal::LinkFrame, hal::kMaxLinks> f = out.link_tx;
    if (to_device) to_device(f);
    if (silent) return;
    for (std::size_t i = 0; i < table.count; ++i) {
      const hal::LinkSpec& s = table.link[i];
      std::array<std::uint8_t, 4> data{};
      std::span<const std::uint8_t> in{};
      if (s.role == hal::LinkRole::safe_inputs) {
        std::memcpy(data.data(), &contacts, 4);
        in = std::span<const std::uint8_t>{data};
      } else if (s.role == hal::LinkRole::load_encoder) {
        std::memcpy(data.data(), &load_counts[s.axis - 1U], 4);
        in = std::span<const std::uint8_t>{data};
      } else {
        in = std::span<const std::uint8_t>{data}.first(1);
      }
      const std::size_t rx = safelink::container_bytes(s.host_data_bytes);
      const std::size_t tx = safelink::container_bytes(s.device_data_bytes);
      static_cast<void>(dev[i].cycle(std::span<const std::uint8_t>{f[i].bytes}.first(rx), in,
                                     std::span<std::uint8_t>{from_dev[i].bytes}.first(tx)));
      if (s.role == hal::LinkRole::safe_outputs) {
        fdo_on[i] = dev[i].outputs_enabled();
        fdo_data[i] = dev[i].outputs()[0];
      }
    }
  }
};

struct Rig {
  Segment seg;
  core::Config cfg{};
  controller::Cell cell{cfg, robot::active().model, seg};
  Rig() {
    const char* why = nullptr;
    EXPECT_TRUE(cell.configure_links(seg.table, 0x1234, why)) << (why ? why : "");
  }
  void run(int n) {
    for (int k = 0; k < n; ++k) cell.step();
  }
  bool fault() const { return cell.alarms().active(core::AlarmId::SAFETY_LINK_FAULT); }
  std::string detail() const {
    std::array<char, 64> b{};
    return core::detail_name(cell.alarms().detail(core::AlarmId::SAFETY_LINK_FAULT), b.data(), b.size());
  }
  std::string message() const {
    std::array<char, 128> b{};
    return core::describe(core::AlarmId::SAFETY_LINK_FAULT, cell.alarms().detail(core::AlarmId::SAFETY_LINK_FAULT),
                          b.data(), b.size());
  }
  // The F-DO's outputs as its two connections drive them (K1, K2).
  bool k1() const {
    const std::size_t i = index_of(seg.table, 0xA002);
    return seg.fdo_on[i] && (seg.fdo_data[i] & controller::kFdoContactor) != 0U;
  }
  bool k2() const {
    const std::size_t i = index_of(seg.table, 0xB002);
    return seg.fdo_on[i] && (seg.fdo_data[i] & controller::kFdoContactor) != 0U;
  }
};

}  // namespace

// @req LINK-FAULT LINK-SAFE-VALUES
TEST(SafetyLinks, EveryConnectionComesUpAndTheBootWaitsForIt) {
  Rig r;
  r.cell.step();
  EXPECT_FALSE(r.cell.feedback().link.up) << "no container has come back yet";
  EXPECT_FALSE(r.cell.raw_inputs_of_last_cycle().estop_a) << "until then the safe values: E-stop pressed";
  EXPECT_FALSE(r.cell.raw_inputs_of_last_cycle().gate_a);
  EXPECT_FALSE(r.cell.image_in().load_encoders) << "no load-side reading to compare yet";
  r.run(10);
  EXPECT_TRUE(r.cell.feedback().link.up);
  EXPECT_FALSE(r.fault());
  EXPECT_NE(r.cell.leaf(), core::Leaf::BOOT);
  EXPECT_NE(r.cell.leaf(), core::Leaf::ERROR_LOCKOUT);
  EXPECT_TRUE(r.cell.raw_inputs_of_last_cycle().estop_a);
  EXPECT_TRUE(r.cell.image_in().load_encoders);
  for (std::size_t i = 0; i < r.seg.table.count; ++i) {
    EXPECT_EQ(r.seg.dev[i].state(), safelink::LinkState::Connected) << r.seg.table.link[i].id;
    EXPECT_EQ(r.cell.links().end(i).state(), safelink::LinkState::Connected) << r.seg.table.link[i].id;
  }
}

TEST(SafetyLinks, ADeviceThatNeverAnswersFailsTheBootNamingItsConnection) {
  Rig r;
  const std::size_t i = index_of(r.seg.table, 0xB011);
  r.seg.to_host = [i](auto& f) { f[i].bytes = {}; };
  r.run(static_cast<int>(r.cfg.boot_timeout_ms) + 5);
  ASSERT_TRUE(r.cell.alarms().active(core::AlarmId::BOOT_FAILED));
  std::array<char, 64> b{};
  EXPECT_EQ(std::string(core::detail_name(r.cell.alarms().detail(core::AlarmId::BOOT_FAILED), b.data(), b.size())),
            "link.0xB011.not_connected");
}

// @req LINK-SAFE-VALUES
TEST(SafetyLinks, TheContactsComeFromTheSafeTerminalNotFromWhatTheMasterDecoded) {
  Rig r;
  r.run(10);
  ASSERT_TRUE(r.cell.feedback().link.up);
  // The master hands the channel "E-stop released" in the plain image while the safe
  // terminal reads it pressed: the channel sees it pressed.
  r.seg.contacts &= ~(1U << controller::fdi::kEstopA);
  r.seg.contacts &= ~(1U << controller::fdi::kEstopB);
  r.run(4);
  EXPECT_FALSE(r.cell.raw_inputs_of_last_cycle().estop_a);
  EXPECT_FALSE(r.cell.raw_inputs_of_last_cycle().estop_b);
  EXPECT_TRUE(r.cell.alarms().active(core::AlarmId::ESTOP_PRESSED));
  // And the other way round: a master that says "pressed" cannot release it either.
  r.seg.contacts = healthy_contacts();
  r.seg.plain.safety.estop_a = r.seg.plain.safety.estop_b = false;
  r.run(4);
  EXPECT_TRUE(r.cell.raw_inputs_of_last_cycle().estop_a);
  // The load-side encoders come from the drives' containers.
  r.seg.load_counts[2] = static_cast<std::int32_t>(kCountsPerRev / 4U);  // a quarter turn
  r.seg.plain.drive[2].load_position_rad = 0.0F;
  r.run(4);
  EXPECT_NEAR(r.cell.image_in().drive[2].load_position_rad, 1.5707963F, 1e-5F);
}

TEST(SafetyLinks, TheChannelsDecisionReachesTheSafeOutputTerminal) {
  Rig r;
  r.run(10);
  const std::size_t a = index_of(r.seg.table, 0xA002);
  const std::size_t b = index_of(r.seg.table, 0xB002);
  EXPECT_TRUE(r.seg.fdo_on[a]);
  EXPECT_TRUE(r.seg.fdo_on[b]);
  // Each cycle the terminal holds what the channel decided (a cycle of the ping-pong later).
  for (int k = 0; k < 20; ++k) {
    r.cell.step();
    const std::uint8_t want = static_cast<std::uint8_t>((r.cell.image_out().contactor ? 1U : 0U) |
                                                        (r.cell.image_out().brakes_release ? 2U : 0U));
    EXPECT_EQ(r.seg.fdo_data[a] & 3U, want);
    EXPECT_EQ(r.seg.fdo_data[b] & 3U, want);
  }
}

namespace {
// One fault on the wire: the channel names it (connection and error), locks out, and the
// safe output terminal's K1 and K2 are off within the 10 ms watchdog.
void expect_caught(Rig& r, const std::string& detail, int within = 11) {
  int k = 0;
  for (; k < within && !r.fault(); ++k) r.cell.step();
  ASSERT_TRUE(r.fault()) << "not caught within " << within << " cycles: " << detail;
  EXPECT_EQ(r.detail(), detail);
  EXPECT_EQ(r.cell.leaf(), core::Leaf::ERROR_LOCKOUT);
  EXPECT_FALSE(r.cell.image_out().contactor);
  r.run(11);
  EXPECT_FALSE(r.k1()) << detail;
  EXPECT_FALSE(r.k2()) << detail;
}
}  // namespace

// @req LINK-FAULT
TEST(SafetyLinks, AFlippedBitIsACrcError) {
  Rig r;
  r.run(10);
  const std::size_t i = index_of(r.seg.table, 0xA001);
  int once = 1;
  r.seg.to_host = [i, &once](auto& f) {
    if (once-- == 1) f[i].bytes[8] ^= 0x04U;  // a bit of the contacts
  };
  expect_caught(r, "link.0xA001.crc", 2);
  EXPECT_EQ(r.message(), "Safety link 0xA001 (channel A): crc error");
}

// @req LINK-FAULT
TEST(SafetyLinks, AStaleContainerReplayedIsASequenceError) {
  Rig r;
  r.run(10);
  const std::size_t i = index_of(r.seg.table, 0xA001);
  hal::LinkFrame old = r.seg.from_dev[i];
  r.run(5);
  int once = 1;
  r.seg.to_host = [i, old, &once](auto& f) {
    if (once-- == 1) f[i] = old;
  };
  expect_caught(r, "link.0xA001.sequence", 2);
}

TEST(SafetyLinks, TwoConnectionsSwappedAreAnIdentityError) {
  Rig r;
  r.run(10);
  const std::size_t a = index_of(r.seg.table, 0xA001);
  const std::size_t e = index_of(r.seg.table, 0xA013);  // the same size: 4 bytes of data
  r.seg.to_host = [a, e](auto& f) { std::swap(f[a], f[e]); };
  int k = 0;
  for (; k < 3 && !r.fault(); ++k) r.cell.step();
  ASSERT_TRUE(r.fault());
  const std::string d = r.detail();
  EXPECT_TRUE(d == "link.0xA013.identity" || d == "link.0xA001.identity") << d;
}

// @req LINK-FAULT
TEST(SafetyLinks, AContainerOfAnotherConnectionInsertedIsAnIdentityError) {
  Rig r;
  r.run(10);
  const std::size_t a = index_of(r.seg.table, 0xA001);
  const std::size_t b = index_of(r.seg.table, 0xB001);
  int once = 1;
  r.seg.to_host = [a, b, &once](auto& f) {
    if (once-- == 1) f[a] = f[b];  // channel B's container of the same terminal
  };
  expect_caught(r, "link.0xA001.identity", 2);
}

// @req LINK-FAULT
TEST(SafetyLinks, ContainersHeldPastTheWatchdogAreATimeout) {
  Rig r;
  r.run(10);
  const std::size_t i = index_of(r.seg.table, 0xA014);
  hal::LinkFrame held = r.seg.from_dev[i];
  r.seg.to_host = [i, held](auto& f) { f[i] = held; };  // the bus delivers the same one again
  r.cell.step();
  EXPECT_FALSE(r.fault()) << "a repetition alone is no fault";
  expect_caught(r, "link.0xA014.timeout", 11);
}

// @req LINK-FAULT
TEST(SafetyLinks, AFlippedBitOnTheWayToTheOutputTerminalOpensItsOutputsAtOnce) {
  Rig r;
  r.run(10);
  const std::size_t i = index_of(r.seg.table, 0xB002);
  int once = 1;
  r.seg.to_device = [i, &once](auto& f) {
    if (once-- == 1) f[i].bytes[7] ^= 0x01U;  // K2's bit itself
  };
  r.cell.step();
  EXPECT_FALSE(r.seg.fdo_on[i]) << "the terminal fails safe on the container it refused";
  EXPECT_EQ(r.seg.device(0xB002).fault(), safelink::Verdict::Crc);
  // It sends zeros from then on: the channel finds its partner gone.
  expect_caught(r, "link.0xB002.not_connected", 3);
}

TEST(SafetyLinks, ADeviceFallingSilentIsATimeoutWithinTheWatchdog) {
  Rig r;
  r.run(10);
  r.seg.silent = true;
  expect_caught(r, "link.0xA011.timeout", 11);
}

TEST(SafetyLinks, ATableThatIsNotTheProtocolsIsRefusedAndChangesNothing) {
  Segment seg;
  const core::Config cfg{};
  controller::Cell cell(cfg, robot::active().model, seg);
  hal::LinkTable t = shipped_links();
  t.link[3].id = t.link[2].id;
  const char* why = nullptr;
  EXPECT_FALSE(cell.configure_links(t, 1, why));
  EXPECT_STREQ(why, "two safety connections with the same id");
  EXPECT_FALSE(cell.links().configured());
  t = shipped_links();
  t.link[0].device_data_bytes = 2;
  EXPECT_FALSE(cell.configure_links(t, 1, why));
  EXPECT_FALSE(cell.links().configured());
  t = shipped_links();
  t.link[0].watchdog_ms = 1;  // one cycle: shorter than an exchange
  EXPECT_FALSE(cell.configure_links(t, 1, why));
  EXPECT_FALSE(cell.links().configured());
}

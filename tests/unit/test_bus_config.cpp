// The EtherCAT bus configuration is input from outside: every mistake is refused with
// the field named, and the built-in default matches the emulated segment.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <functional>

#include "safestate/ecat/cell.hpp"
#include "safestate/hal/ethercat.hpp"

using namespace safestate::hal::ethercat;
using Json = nlohmann::json;

namespace {
std::string refused(const Json& j) {
  BusConfig c;
  std::string err;
  EXPECT_FALSE(parse_bus_config(j.dump(), c, err)) << j.dump();
  return err;
}
Json default_json() { return Json::parse(default_bus_config()); }
}  // namespace

TEST(BusConfig, DefaultMatchesTheEmulatedSegment) {
  BusConfig c;
  std::string err;
  ASSERT_TRUE(parse_bus_config(default_bus_config(), c, err)) << err;
  const auto segment = safestate::ecat::default_segment();
  ASSERT_EQ(c.subdevices.size(), segment.size());
  for (std::size_t i = 0; i < segment.size(); ++i) {
    EXPECT_EQ(c.subdevices[i].vendor_id, segment[i].vendor_id) << i;
    EXPECT_EQ(c.subdevices[i].product_code, segment[i].product_code) << i;
    EXPECT_EQ(c.subdevices[i].in_bytes, segment[i].tx.bytes()) << i;
    EXPECT_EQ(c.subdevices[i].out_bytes, segment[i].rx.bytes()) << i;
    // DC SYNC0 (AssignActivate 0x0300) exactly on the subdevices whose operation mode needs it
    EXPECT_EQ(c.subdevices[i].dc_assign_activate, segment[i].dc_sync0_required ? 0x0300 : 0) << i;
  }
  EXPECT_EQ(c.sync0_shift_us, 500U);  // half the 1 ms cycle: docs/ethercat.md, "Distributed clocks"
  EXPECT_EQ(c.subdevices[0].in_bit[0], 0);   // estop.a
  EXPECT_EQ(c.subdevices[0].in_bit[11], 11); // contactor feedback
  // Every named input bit of the configuration is where the emulated DI terminal's TxPDO
  // entry of the same name is (one layout on both ends of the wire, reduced.a/b included).
  std::size_t named = 0;
  std::size_t bit = 0;
  for (const auto& e : segment[0].tx.entries) {
    for (std::size_t k = 0; k < kInputBits && !e.name.empty(); ++k) {
      if (e.name == kInputBitNames[k]) {
        EXPECT_EQ(c.subdevices[0].in_bit[k], bit) << e.name;
        ++named;
      }
    }
    bit += e.bits;
  }
  EXPECT_EQ(named, kInputBits);
  EXPECT_EQ(c.subdevices[0].in_bit[18], 18);  // reduced.a
  EXPECT_EQ(c.subdevices[0].in_bit[19], 19);  // reduced.b
  EXPECT_EQ(c.subdevices[0].in_bit[20], 20);  // field.outer.a (SPEC §11)
  EXPECT_EQ(c.subdevices[0].in_bit[23], 23);  // field.inner.b
  EXPECT_NEAR(c.subdevices[2].counts_per_rad, safestate::ecat::kCountsPerRad, 1e-9);
  EXPECT_EQ(c.scan_timeout_ms, 5000U);  // not in the file: the default

  Json j = default_json();
  j["scan_timeout_ms"] = 0;  // one scan only
  ASSERT_TRUE(parse_bus_config(j.dump(), c, err)) << err;
  EXPECT_EQ(c.scan_timeout_ms, 0U);
}

TEST(BusConfig, EveryMistakeIsNamed) {
  Json j = default_json();
  j["subdevices"][2]["vendor_id"] = "0xZZ";
  EXPECT_NE(refused(j).find("subdevices[2].vendor_id"), std::string::npos);

  j = default_json();
  j["subdevices"][0]["bits"]["estop.b"] = 0;  // same bit as estop.a
  EXPECT_NE(refused(j).find("used twice"), std::string::npos);

  j = default_json();
  j["subdevices"][0]["bits"]["estop.c"] = 20;
  EXPECT_NE(refused(j).find("subdevices[0].bits.estop.c: unknown signal"), std::string::npos);

  j = default_json();
  j["subdevices"][0]["bits"].erase("gate.b");
  EXPECT_NE(refused(j).find("subdevices[0].bits.gate.b"), std::string::npos);

  j = default_json();
  j["subdevices"][0]["bits"].erase("reduced.b");  // the reduced input is wired like every contact
  EXPECT_NE(refused(j).find("subdevices[0].bits.reduced.b"), std::string::npos);

  j = default_json();
  j["subdevices"][0]["bits"].erase("field.inner.a");  // the scanner's OSSD pairs are wired like every contact
  EXPECT_NE(refused(j).find("subdevices[0].bits.field.inner.a"), std::string::npos);

  j = default_json();
  j["subdevices"][0]["bits"]["reduced.a"] = 32;  // past the terminal's 4 bytes
  EXPECT_NE(refused(j).find("subdevices[0].bits.reduced.a"), std::string::npos);

  j = default_json();
  j["subdevices"][3]["axis"] = 1;  // axis 1 twice, axis 2 missing
  EXPECT_NE(refused(j).find("appears twice"), std::string::npos);

  j = default_json();
  j["subdevices"][4]["pdo"]["velocity_actual"] = 52;  // 4 bytes at 52 of a 54-byte image
  EXPECT_NE(refused(j).find("subdevices[4].pdo.velocity_actual"), std::string::npos);

  // The brake test's objects (SPEC §12) are part of every drive's layout: 0x6072 max torque
  // out, 0x6077 torque actual in, and the DO terminal's brake output of each axis.
  j = default_json();
  j["subdevices"][4]["pdo"].erase("max_torque");
  EXPECT_NE(refused(j).find("subdevices[4].pdo.max_torque"), std::string::npos);
  j = default_json();
  j["subdevices"][4]["pdo"]["torque_actual"] = 53;  // 2 bytes at 53 of a 54-byte image
  EXPECT_NE(refused(j).find("subdevices[4].pdo.torque_actual"), std::string::npos);
  j = default_json();
  j["subdevices"][1]["bits"].erase("brake_hold.4");
  EXPECT_NE(refused(j).find("subdevices[1].bits.brake_hold.4"), std::string::npos);
  j = default_json();
  j["subdevices"][1]["bits"]["brake_hold.6"] = 16;  // past the terminal's 2 bytes
  EXPECT_NE(refused(j).find("subdevices[1].bits.brake_hold.6"), std::string::npos);

  j = default_json();
  j["subdevices"][1]["role"] = "relay";
  EXPECT_NE(refused(j).find("subdevices[1].role"), std::string::npos);

  j = default_json();
  j["subdevices"].erase(7);
  EXPECT_NE(refused(j).find("no drive for axis 6"), std::string::npos);

  j = default_json();
  j["frame_timeout_us"] = 5;
  EXPECT_NE(refused(j).find("frame_timeout_us"), std::string::npos);
  j.erase("frame_timeout_us");
  j["scan_timeout_ms"] = 120001;
  EXPECT_NE(refused(j).find("scan_timeout_ms"), std::string::npos);
  j["scan_timeout_ms"] = "5 s";
  EXPECT_NE(refused(j).find("scan_timeout_ms"), std::string::npos);

  j = default_json();
  for (const auto& [key, bad] : {std::pair<const char*, Json>{"stale_cycles", 0}, {"stale_cycles", 1001},
                                 {"stale_cycles", -3}, {"stale_cycles", "3"}, {"watchdog_cycles", 1},
                                 {"watchdog_cycles", 10001}, {"watchdog_cycles", 2.5}}) {
    j[key] = bad;
    EXPECT_NE(refused(j).find(std::string("bus.") + key + ": expected an integer"), std::string::npos) << key << bad;
    j = default_json();
  }

  EXPECT_EQ(refused(Json::array()), "not a JSON object");
}

// Issue 22: FIELDBUS_LOST after stale_cycles stale cycles (default 3) and every subdevice's
// process-data watchdog at watchdog_cycles (default 10), both from the file.
TEST(BusConfig, StaleCyclesAndWatchdogCycles) {
  BusConfig c;
  std::string err;
  ASSERT_TRUE(parse_bus_config(default_bus_config(), c, err)) << err;
  EXPECT_EQ(c.stale_cycles, 3U);
  EXPECT_EQ(c.watchdog_cycles, 10U);
  Json j = default_json();
  j["stale_cycles"] = 5;
  j["watchdog_cycles"] = 20;
  ASSERT_TRUE(parse_bus_config(j.dump(), c, err)) << err;
  EXPECT_EQ(c.stale_cycles, 5U);
  EXPECT_EQ(c.watchdog_cycles, 20U);
}

TEST(BusConfig, WatchdogRegistersNeverShorterThanAsked) {
  std::uint16_t div = 0;
  std::uint16_t time = 0;
  ASSERT_TRUE(watchdog_registers(10, 1000, div, time));  // 10 ms: 100 ticks of 100 us
  EXPECT_EQ(div, 2498);
  EXPECT_EQ(time, 100);
  ASSERT_TRUE(watchdog_registers(3, 250, div, time));  // 750 us: 8 ticks (800 us), not 7
  EXPECT_EQ(time, 8);
  ASSERT_TRUE(watchdog_registers(10000, 1000, div, time));  // 10 s: past 16 bits of 100 us, 1 ms ticks
  EXPECT_EQ(div, 24998);
  EXPECT_EQ(time, 10000);
  EXPECT_FALSE(watchdog_registers(10000, 10000, div, time));  // 100 s fits neither
}

// Issue 22 item 4: the drives' start-up list as shipped is what the emulated drives accept
// in PRE-OP (CSP, the interpolation period of their 1 ms cycle, a torque limit), and it
// leaves them ready for SAFE-OP.
TEST(BusConfig, DefaultStartupListIsAcceptedByTheEmulatedDrives) {
  BusConfig c;
  std::string err;
  ASSERT_TRUE(parse_bus_config(default_bus_config(), c, err)) << err;
  const auto segment = safestate::ecat::default_segment();
  for (std::size_t i = 0; i < segment.size(); ++i) {
    const Subdevice& s = c.subdevices[i];
    if (!segment[i].mailbox) {
      EXPECT_TRUE(s.startup.empty()) << i << ": no mailbox, no start-up SDOs";
      continue;
    }
    ASSERT_EQ(s.startup.size(), 4U) << i;
    EXPECT_EQ(s.startup[0].index, 0x6060);
    EXPECT_EQ(s.startup[0].value, 8U);
    EXPECT_EQ(s.startup[2].index, 0x60C2);
    EXPECT_EQ(s.startup[2].sub, 2);
    EXPECT_EQ(s.startup[2].value, 0xFDU);  // -3 in one byte
    safestate::ecat::coe::Dictionary od(segment[i]);
    for (const StartupSdo& sdo : s.startup) {
      std::vector<std::uint8_t> bytes;
      for (std::size_t k = 0; k < sdo.size; ++k) {
        bytes.push_back(static_cast<std::uint8_t>(sdo.value >> (8U * k)));
      }
      EXPECT_EQ(od.download(sdo.index, sdo.sub, bytes, safestate::ecat::AlState::preop), 0U)
          << i << ": " << std::hex << sdo.index << ":" << int(sdo.sub);
    }
    EXPECT_EQ(od.value(0x6060, 0), 8);
    EXPECT_EQ(od.value(0x60C2, 1), 1);
    EXPECT_EQ(od.value(0x60C2, 2), -3);
  }
}

TEST(BusConfig, StartupEntriesAreCheckedOneByOne) {
  Json j = default_json();
  Json& list = j["subdevices"][2]["startup"];
  list = Json::array({{{"index", "0x6072"}, {"sub", 0}, {"size", 2}, {"value", 65535}},
                      {{"index", 0x2000}, {"sub", 255}, {"size", 4}, {"value", -2147483648LL}},
                      {{"index", "0xFFFF"}, {"sub", 1}, {"size", 1}, {"value", -128}}});
  BusConfig c;
  std::string err;
  ASSERT_TRUE(parse_bus_config(j.dump(), c, err)) << err;
  ASSERT_EQ(c.subdevices[2].startup.size(), 3U);
  EXPECT_EQ(c.subdevices[2].startup[0].value, 0xFFFFU);
  EXPECT_EQ(c.subdevices[2].startup[1].index, 0x2000);
  EXPECT_EQ(c.subdevices[2].startup[1].value, 0x80000000U);
  EXPECT_EQ(c.subdevices[2].startup[2].value, 0x80U);
  const std::string at = "subdevices[2] (drive axis 1).startup";
  const Json good = {{"index", "0x6060"}, {"sub", 0}, {"size", 1}, {"value", 8}};
  const auto with = [&](const char* key, const Json& v) {
    Json e = good;
    if (v.is_null()) {
      e.erase(key);
    } else {
      e[key] = v;
    }
    return e;
  };
  const struct {
    Json entry;
    std::string field;
  } bad[] = {
      {Json(8), at + "[1]"},
      {with("extra", 1), at + "[1].extra"},
      {with("index", nullptr), at + "[1].index"},
      {with("index", "six"), at + "[1].index"},
      {with("index", "0x0FFF"), at + "[1].index"},
      {with("index", 0x10000), at + "[1].index"},
      {with("sub", nullptr), at + "[1].sub"},
      {with("sub", 256), at + "[1].sub"},
      {with("sub", -1), at + "[1].sub"},
      {with("size", nullptr), at + "[1].size"},
      {with("size", 3), at + "[1].size"},
      {with("size", "1"), at + "[1].size"},
      {with("value", nullptr), at + "[1].value"},
      {with("value", 256), at + "[1].value"},
      {with("value", -129), at + "[1].value"},
      {with("value", 1.5), at + "[1].value"},
      {with("value", "8"), at + "[1].value"},
  };
  for (const auto& b : bad) {
    Json k = default_json();
    k["subdevices"][2]["startup"] = Json::array({good, b.entry});
    const std::string e = refused(k);
    EXPECT_EQ(e.rfind(b.field + ":", 0), 0U) << b.entry.dump() << " -> " << e;
  }
  Json k = default_json();
  k["subdevices"][2]["startup"] = Json::object();
  EXPECT_EQ(refused(k).rfind(at + ":", 0), 0U);
  k["subdevices"][2]["startup"] = Json::array();
  for (std::size_t n = 0; n <= kMaxStartupSdos; ++n) {
    k["subdevices"][2]["startup"].push_back(good);
  }
  EXPECT_EQ(refused(k).rfind(at + ":", 0), 0U) << "more than kMaxStartupSdos";
  k["subdevices"][2]["startup"].erase(0);
  EXPECT_TRUE(parse_bus_config(k.dump(), c, err)) << err;  // exactly kMaxStartupSdos
  // With 2-byte and 4-byte sizes the range follows the size.
  k["subdevices"][2]["startup"] = Json::array({with("size", 2)});
  k["subdevices"][2]["startup"][0]["value"] = 65536;
  EXPECT_NE(refused(k).find("(-32768..65535)"), std::string::npos);
  k["subdevices"][2]["startup"][0]["size"] = 4;
  k["subdevices"][2]["startup"][0]["value"] = 4294967296LL;
  EXPECT_NE(refused(k).find("(-2147483648..4294967295)"), std::string::npos);
}

TEST(BusConfig, DistributedClocksPerSubdeviceAndTheSync0Shift) {
  Json j = default_json();
  j["subdevices"][2]["dc"] = {{"assign_activate", "0x0300"}};
  j["subdevices"][3].erase("dc");  // the default has it on every drive
  BusConfig c;
  std::string err;
  j.erase("sync0_shift_us");
  ASSERT_TRUE(parse_bus_config(j.dump(), c, err)) << err;
  EXPECT_EQ(c.sync0_shift_us, 500U) << "not in the file: the default, half the default cycle";
  j["sync0_shift_us"] = 250;
  ASSERT_TRUE(parse_bus_config(j.dump(), c, err)) << err;
  EXPECT_EQ(c.subdevices[2].dc_assign_activate, 0x0300);
  EXPECT_EQ(c.subdevices[3].dc_assign_activate, 0) << "no dc key: free run";
  EXPECT_EQ(c.sync0_shift_us, 250U);

  Json bad = j;
  bad["subdevices"][2]["dc"] = {{"assign_activate", "0x0300"}, {"sync1", 1}};
  EXPECT_NE(refused(bad).find("subdevices[2] (drive axis 1).dc.sync1: unknown key"), std::string::npos) << refused(bad);
  bad["subdevices"][2]["dc"] = Json::object();
  EXPECT_NE(refused(bad).find(".dc.assign_activate: missing"), std::string::npos) << refused(bad);
  bad["subdevices"][2]["dc"] = {{"assign_activate", "0x0"}};
  EXPECT_NE(refused(bad).find(".dc.assign_activate: expected a non-zero 16-bit word"), std::string::npos);
  bad["subdevices"][2]["dc"] = {{"assign_activate", "0x10300"}};
  EXPECT_NE(refused(bad).find(".dc.assign_activate"), std::string::npos);
  bad["subdevices"][2]["dc"] = "0x0300";
  EXPECT_NE(refused(bad).find(".dc: expected an object"), std::string::npos);
  bad = j;
  bad["sync0_shift_us"] = 100001;
  EXPECT_NE(refused(bad).find("sync0_shift_us"), std::string::npos);
}

// SPEC §11's distance sensor: a subdevice of its own (role distance_sensor), optional and at
// most one, its separation (INT32) and valid bit inside its input image; and the DO
// terminal's reduced_active bit (SPEC §10), optional too.
TEST(BusConfig, DistanceSensorAndReducedActive) {
  BusConfig c;
  std::string err;
  ASSERT_TRUE(parse_bus_config(default_bus_config(), c, err)) << err;
  const Subdevice& s = c.subdevices.at(safestate::ecat::kPosDistance);
  EXPECT_EQ(s.role, Role::distance_sensor);
  EXPECT_EQ(s.in_bytes, safestate::ecat::kDistanceBytes);
  EXPECT_EQ(s.separation_mm, 0U);
  EXPECT_EQ(s.separation_valid_bit, safestate::ecat::kDistanceValidBit);
  EXPECT_EQ(c.subdevices[1].out_bit[9], static_cast<std::uint16_t>(safestate::ecat::DoBit::reduced_active));

  // Optional: a segment without the sensor, or a DO terminal without the bit, is a bus.
  Json j = default_json();
  j["subdevices"].erase(safestate::ecat::kPosDistance);
  j["subdevices"][1]["bits"].erase("reduced_active");
  ASSERT_TRUE(parse_bus_config(j.dump(), c, err)) << err;
  EXPECT_EQ(c.subdevices.size(), safestate::ecat::kSubdevices - 1U);
  EXPECT_EQ(c.subdevices[1].out_bit[9], kNoBit);
  for (const Subdevice& d : c.subdevices) {
    EXPECT_NE(d.role, Role::distance_sensor);
  }

  const Json sensor = default_json()["subdevices"][safestate::ecat::kPosDistance];
  const std::string at = "subdevices[" + std::to_string(safestate::ecat::kPosDistance) + "]";
  const auto with = [&](const std::function<void(Json&)>& change) {
    Json k = default_json();
    change(k["subdevices"][safestate::ecat::kPosDistance]);
    return k;
  };
  j = default_json();
  j["subdevices"].push_back(sensor);  // two sensors: which separation counts?
  EXPECT_NE(refused(j).find("a second distance_sensor"), std::string::npos);
  EXPECT_NE(refused(with([](Json& d) { d["pdo"]["separation_mm"] = 2; })).find(at + ".pdo.separation_mm"),
            std::string::npos);  // 4 bytes at 2 of a 5-byte image
  EXPECT_NE(refused(with([](Json& d) { d["pdo"].erase("separation_mm"); })).find(at + ".pdo.separation_mm"),
            std::string::npos);
  EXPECT_NE(refused(with([](Json& d) { d.erase("pdo"); })).find(at + ".pdo"), std::string::npos);
  EXPECT_NE(refused(with([](Json& d) { d["pdo"]["distance"] = 0; })).find(at + ".pdo.distance: unknown object"),
            std::string::npos);
  EXPECT_NE(refused(with([](Json& d) { d["bits"].erase("separation_valid"); })).find(at + ".bits.separation_valid"),
            std::string::npos);
  EXPECT_NE(refused(with([](Json& d) { d["bits"]["separation_valid"] = 40; })).find(at + ".bits.separation_valid"),
            std::string::npos);  // past the 5 bytes
  EXPECT_NE(refused(with([](Json& d) { d["bits"]["separation_valid"] = 7; })).find("lies inside separation_mm"),
            std::string::npos);
  EXPECT_NE(refused(with([](Json& d) { d["bits"]["fault"] = 33; })).find(at + ".bits.fault: unknown signal"),
            std::string::npos);
  EXPECT_NE(refused(with([](Json& d) { d["in_bytes"] = 4; })).find(at + ".in_bytes"), std::string::npos);

  j = default_json();
  j["subdevices"][1]["bits"]["reduced_active"] = 16;  // past the terminal's 2 bytes
  EXPECT_NE(refused(j).find("subdevices[1].bits.reduced_active"), std::string::npos);
  j["subdevices"][1]["bits"]["reduced_active"] = 0;  // the contactor's bit
  EXPECT_NE(refused(j).find("used twice"), std::string::npos);
}

// SPEC §14 on a segment: K2 (DO `contactor_k2`) with its auxiliary contact (DI
// `contactor_fb.k2`), and each drive's load-side encoder (0x60E4:01, `pdo.load_position`), in
// the shipped default where the emulated segment has them; optional, but K2 never without its
// contact (nor the contact without K2), and the encoders on every drive or on none.
// @req CH-CONTACTORS CH-ENCODERS
TEST(BusConfig, K2AndTheLoadSideEncoders) {
  BusConfig c;
  std::string err;
  ASSERT_TRUE(parse_bus_config(default_bus_config(), c, err)) << err;
  EXPECT_EQ(c.subdevices[0].in_bit[kInputBits - 1U], static_cast<std::uint16_t>(safestate::ecat::DiBit::contactor_fb_k2));
  EXPECT_EQ(c.subdevices[1].out_bit[kOutputBits - 1U], static_cast<std::uint16_t>(safestate::ecat::DoBit::contactor_k2));
  for (std::size_t a = 0; a < 6; ++a) {
    EXPECT_EQ(c.subdevices[safestate::ecat::kPosFirstDrive + a].load_position, 12U) << "axis " << a + 1;
  }
  // A one-contactor segment with motor encoders only: still a bus (one channel's).
  Json j = default_json();
  j["subdevices"][0]["bits"].erase("contactor_fb.k2");
  j["subdevices"][1]["bits"].erase("contactor_k2");
  for (std::size_t a = 0; a < 6; ++a) {
    j["subdevices"][safestate::ecat::kPosFirstDrive + a]["pdo"].erase("load_position");
    j["subdevices"][safestate::ecat::kPosFirstDrive + a].erase("safety_links");  // they carry it (issue 37)
  }
  ASSERT_TRUE(parse_bus_config(j.dump(), c, err)) << err;
  EXPECT_EQ(c.subdevices[0].in_bit[kInputBits - 1U], kNoBit);
  EXPECT_EQ(c.subdevices[1].out_bit[kOutputBits - 1U], kNoBit);
  EXPECT_EQ(c.subdevices[2].load_position, kNoOffset);

  j = default_json();
  j["subdevices"][0]["bits"].erase("contactor_fb.k2");
  EXPECT_NE(refused(j).find("\"contactor_k2\" is mapped on the safety outputs but K2's auxiliary contact"),
            std::string::npos);
  j = default_json();
  j["subdevices"][1]["bits"].erase("contactor_k2");
  EXPECT_NE(refused(j).find("\"contactor_fb.k2\" is mapped on the safety inputs but \"contactor_k2\" is not"),
            std::string::npos);
  j = default_json();
  j["subdevices"][safestate::ecat::kPosFirstDrive + 3]["pdo"].erase("load_position");
  j["subdevices"][safestate::ecat::kPosFirstDrive + 3].erase("safety_links");
  EXPECT_NE(refused(j).find("drive axis 4 (drive axis 4) has no pdo.load_position while 5 drive(s) have one"),
            std::string::npos);
  j = default_json();
  j["subdevices"][safestate::ecat::kPosFirstDrive]["pdo"]["load_position"] = 51;  // 4 bytes past the 54
  EXPECT_NE(refused(j).find("subdevices[2].pdo.load_position"), std::string::npos);
  j = default_json();
  j["subdevices"][safestate::ecat::kPosFirstDrive]["pdo"]["load_positon"] = 12;  // a typo is not ignored
  EXPECT_NE(refused(j).find("subdevices[2].pdo.load_positon: unknown object"), std::string::npos);
  j = default_json();
  j["subdevices"][1]["bits"]["contactor_k2"] = 0;  // K1's bit
  EXPECT_NE(refused(j).find("used twice"), std::string::npos);
}

// Issue 37: the black channel's connections of the built-in bus, as the backend hands them to
// the channels (LinkTable: bus order, within a subdevice the listed order), and every mistake
// of a "safety_links" entry refused with the subdevice and the field named.
TEST(BusConfig, SafetyLinksOfTheDefaultBus) {
  namespace hal = safestate::hal;
  namespace sl = safestate::safelink;
  BusConfig c;
  std::string err;
  ASSERT_TRUE(parse_bus_config(default_bus_config(), c, err)) << err;
  ASSERT_EQ(c.links.count, 16U);
  for (std::size_t a = 0; a < 6; ++a) {  // the drives first (positions 3..8), A then B
    for (std::size_t k = 0; k < 2; ++k) {
      const hal::LinkSpec& l = c.links.link[2 * a + k];
      EXPECT_EQ(l.id, (k == 0 ? 0xA011U : 0xB011U) + a) << a;
      EXPECT_EQ(l.channel, k == 0 ? 'A' : 'B');
      EXPECT_EQ(l.role, hal::LinkRole::load_encoder);
      EXPECT_EQ(l.axis, a + 1U);
      EXPECT_EQ(l.host_data_bytes, 0U);
      EXPECT_EQ(l.device_data_bytes, 4U);
      EXPECT_EQ(l.watchdog_ms, 10U);
      EXPECT_EQ(l.vendor_id, safestate::ecat::kVendorId);
      EXPECT_EQ(l.product_code, safestate::ecat::kProductDrive);
      EXPECT_EQ(l.position, a + 3U);
      EXPECT_EQ(l.counts_per_revolution, 1048576U);
    }
    // the containers behind the CiA 402 objects, as the emulated drive's PDOs place them
    const Subdevice& d = c.subdevices[safestate::ecat::kPosFirstDrive + a];
    const auto seg = safestate::ecat::default_segment();
    const auto& e = seg[safestate::ecat::kPosFirstDrive + a];
    EXPECT_EQ(d.links[0].out_offset, safestate::ecat::container_offset(e.rx, safestate::ecat::kObjToDeviceA));
    EXPECT_EQ(d.links[1].out_offset, safestate::ecat::container_offset(e.rx, safestate::ecat::kObjToDeviceB));
    EXPECT_EQ(d.links[0].in_offset, safestate::ecat::container_offset(e.tx, safestate::ecat::kObjToHostA));
    EXPECT_EQ(d.links[1].in_offset, safestate::ecat::container_offset(e.tx, safestate::ecat::kObjToHostB));
  }
  const struct {
    std::uint16_t id;
    hal::LinkRole role;
    std::uint8_t host, device;
    std::uint32_t product;
    std::uint16_t position;
  } safe[] = {{0xA001, hal::LinkRole::safe_inputs, 0, 4, 0x00D1F001, 10},
              {0xB001, hal::LinkRole::safe_inputs, 0, 4, 0x00D1F001, 10},
              {0xA002, hal::LinkRole::safe_outputs, 1, 1, 0x00D0F001, 11},
              {0xB002, hal::LinkRole::safe_outputs, 1, 1, 0x00D0F001, 11}};
  for (std::size_t i = 0; i < 4; ++i) {
    const hal::LinkSpec& l = c.links.link[12 + i];
    EXPECT_EQ(l.id, safe[i].id) << i;
    EXPECT_EQ(l.role, safe[i].role) << i;
    EXPECT_EQ(l.host_data_bytes, safe[i].host) << i;
    EXPECT_EQ(l.device_data_bytes, safe[i].device) << i;
    EXPECT_EQ(l.product_code, safe[i].product) << i;
    EXPECT_EQ(l.position, safe[i].position) << i;
    EXPECT_EQ(l.axis, 0U) << i;
  }
  // The wire contract's sizes (CRC-64): 15, 16 and 19 bytes, channel B's behind channel A's.
  EXPECT_EQ(sl::container_bytes(0), 15U);
  EXPECT_EQ(sl::container_bytes(1), 16U);
  EXPECT_EQ(sl::container_bytes(4), 19U);
  EXPECT_EQ(c.subdevices[9].in_bytes, 2U * sl::container_bytes(4));
  EXPECT_EQ(c.subdevices[9].out_bytes, 2U * sl::container_bytes(0));
  EXPECT_EQ(c.subdevices[10].in_bytes, 2U * sl::container_bytes(1));
  EXPECT_EQ(c.subdevices[10].out_bytes, 2U * sl::container_bytes(1));
  // Watchdog against the cycle: 10 ms is 2 cycles or more up to a 5 ms cycle.
  EXPECT_TRUE(links_fit_cycle(c, 1000, err)) << err;
  EXPECT_TRUE(links_fit_cycle(c, 5000, err)) << err;
  EXPECT_FALSE(links_fit_cycle(c, 5001, err));
  EXPECT_NE(err.find("safety link 0xA011: watchdog_ms 10 is shorter than 2 cycles of 5001 us"), std::string::npos) << err;

  // Without any: the bus of before (--no-safe-terminals), no connections.
  Json j = default_json();
  j["subdevices"].erase(10);
  j["subdevices"].erase(9);
  for (std::size_t a = 0; a < 6; ++a) {
    j["subdevices"][safestate::ecat::kPosFirstDrive + a].erase("safety_links");
    j["subdevices"][safestate::ecat::kPosFirstDrive + a]["in_bytes"] = 16;
    j["subdevices"][safestate::ecat::kPosFirstDrive + a]["out_bytes"] = 8;
  }
  ASSERT_TRUE(parse_bus_config(j.dump(), c, err)) << err;
  EXPECT_EQ(c.links.count, 0U);
}

TEST(BusConfig, SafetyLinkMistakesAreNamed) {
  const auto with = [](std::size_t sub, const std::function<void(Json&)>& change) {
    Json k = default_json();
    change(k["subdevices"][sub]);
    return k;
  };
  const auto has = [](const Json& j, const std::string& part) {
    const std::string e = refused(j);
    EXPECT_NE(e.find(part), std::string::npos) << "'" << part << "' not in: " << e;
  };
  const std::string fdi = "subdevices[9] (F-DI safety contacts).safety_links";
  const std::string fdo = "subdevices[10] (F-DO contactors brake relays).safety_links";
  has(with(9, [](Json& d) { d["safety_links"][0]["id"] = "0x0"; }), fdi + "[0].id: expected a non-zero 16-bit");
  has(with(9, [](Json& d) { d["safety_links"][0]["id"] = "0x1A001"; }), fdi + "[0].id: expected a non-zero 16-bit");
  has(with(9, [](Json& d) { d["safety_links"][0]["id"] = "A001"; }), fdi + "[0].id: expected a 32-bit number");
  has(with(9, [](Json& d) { d["safety_links"][0].erase("id"); }), fdi + "[0].id: missing");
  has(with(10, [](Json& d) { d["safety_links"][0]["id"] = "0xA001"; }),
      "subdevices[10] (F-DO contactors brake relays).safety_links[0].id: connection 0xA001 is used twice");
  has(with(9, [](Json& d) { d["safety_links"][0]["channel"] = "C"; }), fdi + "[0].channel: expected \"A\" or \"B\"");
  has(with(9, [](Json& d) { d["safety_links"][1]["channel"] = "A"; }),
      fdi + "[1].channel: channel A has a connection to this subdevice already");
  has(with(9, [](Json& d) { d["safety_links"][1]["out_offset"] = 16; }),
      fdi + "[1].out_offset: the channel's container (15 bytes) must lie inside the 30 output bytes");
  has(with(9, [](Json& d) { d["safety_links"][1]["in_offset"] = 20; }),
      fdi + "[1].in_offset: the device's container (19 bytes) must lie inside the 38 input bytes");
  has(with(10, [](Json& d) { d["safety_links"][1]["out_offset"] = 8; }), fdo + "[1]: its container overlaps");
  has(with(10, [](Json& d) { d["safety_links"][1]["in_offset"] = 15; }), fdo + "[1]: its container overlaps");
  has(with(10, [](Json& d) { d["safety_links"][0]["watchdog_ms"] = 0; }), fdo + "[0].watchdog_ms: expected an integer 1..60000");
  has(with(10, [](Json& d) { d["safety_links"][0]["watchdog_ms"] = 60001; }),
      fdo + "[0].watchdog_ms: expected an integer 1..60000");
  has(with(10, [](Json& d) { d["safety_links"][0]["watchdog"] = 10; }), fdo + "[0].watchdog: unknown key");
  has(with(10, [](Json& d) { d.erase("safety_links"); }), fdo + ": missing");
  has(with(10, [](Json& d) { d["safety_links"] = Json::array(); }), fdo + ": expected a list of one or two");
  has(with(10, [](Json& d) { d["bits"] = {{"contactor", 0}}; }), "subdevices[10].bits: a safe terminal has no bits");
  has(with(9, [](Json& d) { d["role"] = "safe_input"; }), "subdevices[9].role: expected safety_inputs");
  // The F-DI's containers sized as the F-DO's role says: 16 bytes do not fit at 15 of 30.
  has(with(9, [](Json& d) { d["role"] = "safe_outputs"; }), "subdevices[9] (F-DI safety contacts).safety_links[1]");
  has(with(0, [](Json& d) { d["safety_links"] = {{{"id", "0xA0FF"}, {"channel", "A"}, {"out_offset", 0}, {"in_offset", 0}, {"watchdog_ms", 10}}}; }),
      "subdevices[0] (DI safety contacts).safety_links: only the safe_inputs, safe_outputs and drive subdevices");
  // a second safe terminal of a kind
  Json j = default_json();
  Json second = j["subdevices"][9];
  second["safety_links"][0]["id"] = "0xA0F1";
  second["safety_links"][1]["id"] = "0xB0F1";
  j["subdevices"].push_back(second);
  has(j, "subdevices[11] (F-DI safety contacts).role: a second safe_inputs subdevice (at most one)");
  // the drives' containers: all or none, and only with the load-side encoder
  has(with(4, [](Json& d) { d.erase("safety_links"); }),
      "drive axis 3 (drive axis 3) has no safety_links while 5 drive(s) have some");
  has(with(4, [](Json& d) { d["pdo"].erase("load_position"); }),
      "subdevices[4] (drive axis 3).safety_links: a drive's containers carry its load-side encoder");
  has(with(4, [](Json& d) { d["safety_links"][0]["in_offset"] = 10; }),
      "subdevices[4] (drive axis 3).safety_links[0]: its container overlaps pdo.torque_actual");
  has(with(4, [](Json& d) { d["safety_links"][1]["out_offset"] = 0; }),
      "subdevices[4] (drive axis 3).safety_links[1]: its container overlaps pdo.controlword");
}

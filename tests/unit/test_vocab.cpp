// The simulated world's vocabulary (vocab/): one parser and one printer of inputs, faults and
// the person for the scenario files, the gateway's `sim` message and the emulator's control
// socket. Every fault prints to words that parse back to it; the network may inject only
// what a person could do to the plant; every contact has one name that reads and writes it.
#include <gtest/gtest.h>

#include <string>

#include "safestate/vocab/faults.hpp"
#include "safestate/vocab/inputs.hpp"
#include "safestate/vocab/person.hpp"

using namespace safestate;
using namespace safestate::vocab;

namespace {

Problem parse_line(const std::string& line, Fault& f, FaultSource from = FaultSource::local) {
  return parse_fault(split_words(line), f, from);
}

// One example of every kind, with the values its words can carry.
std::vector<Fault> every_fault() {
  std::vector<Fault> all;
  for (std::uint8_t k = 0; k < kFaultKinds; ++k) {
    Fault f{static_cast<FaultKind>(k), 0, 0};
    switch (f.kind) {
      case FaultKind::drive_fault:
      case FaultKind::drive_clear:
      case FaultKind::drive_runaway:
      case FaultKind::drive_nostop:
      case FaultKind::brake_stuck:
      case FaultKind::brake_stuck_released:
      case FaultKind::brake_weak: f.axis = static_cast<std::uint8_t>(1 + k % 6); break;
      case FaultKind::drive_statusword: f.axis = 4; f.value = 0x021F; break;
      case FaultKind::drive_slow_enable: f.axis = 2; f.value = 250; break;
      case FaultKind::contact: f.value = 1255; break;  // 125.5 N
      case FaultKind::drive_torque_bias: f.axis = 6; f.value = static_cast<std::uint16_t>(std::int16_t{-125}); break;
      // SPEC §14: the channel (1 A, 2 B), the axis of an encoder, hundredths of a degree.
      case FaultKind::channel_stall:
      case FaultKind::digest_corrupt: f.axis = 1; break;
      case FaultKind::channel_crash:
      case FaultKind::digest_drop:
      case FaultKind::digest_repeat: f.axis = 2; break;
      case FaultKind::channel_input: f.axis = 2; f.value = static_cast<std::uint16_t>((5U << 1U) | 1U); break;
      case FaultKind::encoder_stuck: f.axis = 3; break;
      case FaultKind::encoder_offset: f.axis = 5; f.value = 75; break;  // 0.75 deg
      case FaultKind::encoder_drift: f.axis = 1; f.value = static_cast<std::uint16_t>(std::int16_t{-1250}); break;
      case FaultKind::channel_flip: f.axis = 2; f.value = static_cast<std::uint16_t>((2U << 8U) | 17U); break;  // alarms bit 17
      default: break;
    }
    all.push_back(f);
  }
  return all;
}

}  // namespace

TEST(Vocab, EveryFaultPrintsToWordsThatParseBackToIt) {
  for (const Fault& f : every_fault()) {
    const std::string words = format_fault(f);
    Fault back{FaultKind::clear_all, 9, 9};
    ASSERT_EQ(parse_line(words, back), "") << words;
    EXPECT_EQ(back.kind, f.kind) << words;
    EXPECT_EQ(back.axis, f.axis) << words;
    EXPECT_EQ(back.value, f.value) << words;
  }
  EXPECT_EQ(format_fault(every_fault()[static_cast<std::size_t>(FaultKind::drive_torque_bias)]), "drive 6 torque_bias -12.5");
  EXPECT_EQ(format_fault(every_fault()[static_cast<std::size_t>(FaultKind::drive_statusword)]), "drive 4 statusword 0x021F");
  EXPECT_EQ(format_fault(every_fault()[static_cast<std::size_t>(FaultKind::channel_input)]), "channel B input enable.b=1");
  EXPECT_EQ(format_fault(every_fault()[static_cast<std::size_t>(FaultKind::encoder_drift)]), "encoder 1 drift -12.5");
  EXPECT_EQ(format_fault(every_fault()[static_cast<std::size_t>(FaultKind::encoder_offset)]), "encoder 5 offset 0.75");
  EXPECT_EQ(format_fault(every_fault()[static_cast<std::size_t>(FaultKind::channel_flip)]), "channel B flip alarms bit 17");
}

// SPEC §14 `channel A|B flip FIELD [bit N]`: every named field, its bits from 0 to its width,
// bit 0 by default; nothing else.
TEST(Vocab, FlipNamesAFieldAndABitWithinIt) {
  for (std::size_t i = 0; i < kFlipFields.size(); ++i) {
    const std::string name(kFlipFields[i].name);
    Fault f{};
    ASSERT_EQ(parse_line("channel A flip " + name, f), "") << name;
    EXPECT_EQ(f.kind, FaultKind::channel_flip);
    EXPECT_EQ(f.axis, 1U);
    EXPECT_EQ(f.value, i << 8U) << name;
    const unsigned top = kFlipFields[i].bits - 1U;
    ASSERT_EQ(parse_line("channel B flip " + name + " bit " + std::to_string(top), f), "") << name;
    EXPECT_EQ(f.axis, 2U);
    EXPECT_EQ(f.value, (i << 8U) | top) << name;
    const Fault before = f;
    const Problem p = parse_line("channel B flip " + name + " bit " + std::to_string(top + 1U), f);
    EXPECT_NE(p.find("bad bit \"bit " + std::to_string(top + 1U) + "\""), std::string::npos) << p;
    EXPECT_NE(p.find("expected bit 0.." + std::to_string(top) + " of " + name), std::string::npos) << p;
    EXPECT_EQ(f.value, before.value) << "a refused line changes nothing";
  }
  Fault f{};
  const Problem p = parse_line("channel A flip leaf", f);
  EXPECT_NE(p.find("bad field \"leaf\""), std::string::npos) << p;
  EXPECT_NE(p.find("expected state, cycle, alarms"), std::string::npos) << p;
  EXPECT_NE(parse_line("channel A flip state bits 1", f), "");
  EXPECT_NE(parse_line("channel A flip state bit", f), "");
  EXPECT_NE(parse_line("channel A flip", f), "");
  EXPECT_NE(parse_line("channel A flip state bit -1", f), "");
  EXPECT_FALSE(injectable(FaultKind::channel_flip, FaultSource::network)) << "a channel's memory is not the network's";
}

TEST(Vocab, TwoChannelFaultsNameWhatIsWrong) {
  const std::pair<const char*, const char*> bad[] = {
      {"channel C stall", "bad channel \"C\""},
      {"channel A wobble", "expected channel A|B stall|crash"},
      {"channel B digest mangle", "bad digest fault \"mangle\""},
      {"channel A input estop=pressed", "bad input \"estop=pressed\""},  // a shorthand: not one contact
      {"channel A input estop.a=2", "bad input"},
      {"encoder 7 stuck", "bad encoder \"7\""},
      {"encoder 2 offset 400", "bad offset \"400\""},
      {"encoder 2 drift x", "bad drift \"x\""},
      {"contactor k3 welded", "bad fault"},
  };
  for (const auto& [line, want] : bad) {
    Fault f{FaultKind::clear_all, 7, 7};
    const Problem p = parse_line(line, f);
    EXPECT_NE(p.find(want), std::string::npos) << line << ": " << p;
    EXPECT_EQ(f.axis, 7) << "a refused line changes nothing: " << line;
  }
  Fault f{};
  ASSERT_EQ(parse_line("contactor k2 welded", f), "");
  EXPECT_EQ(f.kind, FaultKind::contactor_welded);
  EXPECT_EQ(f.axis, 2);
  ASSERT_EQ(parse_line("contactor welded", f), "");
  EXPECT_EQ(f.axis, 0);  // K1's, as before two contactors
  // Channel and digest faults are not a person's to inject over the network.
  EXPECT_NE(parse_line("channel A stall", f, FaultSource::network).find("cannot be injected over the network"),
            std::string::npos);
}

TEST(Vocab, TheNetworkInjectsOnlyWhatAPersonCouldDoToThePlant) {
  // Platform, program and jog-link faults are the scenario files' and the local socket's.
  for (const char* line : {"integrity", "selftest fail", "program unload", "jog_link drop", "contactor welded",
                           "drive 2 statusword 0x0008", "drive 2 slow_enable 100", "brake 3 stuck_released"}) {
    Fault f{FaultKind::clear_all, 7, 7};
    const Problem p = parse_line(line, f, FaultSource::network);
    EXPECT_NE(p.find("cannot be injected over the network"), std::string::npos) << line << ": " << p;
    EXPECT_EQ(f.axis, 7) << "a refused line changes nothing: " << line;
    EXPECT_EQ(parse_line(line, f, FaultSource::local), "") << line;
  }
  for (const char* line : {"drive 3 runaway", "brake 2 weak", "contact 40", "drive 1 torque_bias 12.5", "clear all",
                           "fieldbus lost", "contactor stuck_open", "brake 1 stuck"}) {
    Fault f{};
    EXPECT_EQ(parse_line(line, f, FaultSource::network), "") << line;
    EXPECT_TRUE(injectable(f.kind, FaultSource::network)) << line;
  }
  EXPECT_FALSE(injectable(static_cast<FaultKind>(kFaultKinds), FaultSource::local)) << "an unknown code is never injected";
}

TEST(Vocab, ABadFaultNamesWhatIsWrongAndChangesNothing) {
  Fault f{FaultKind::brake_weak, 3, 0};
  EXPECT_NE(parse_line("contact -1", f).find("bad contact force \"-1\""), std::string::npos);
  EXPECT_NE(parse_line("contact 5000.1", f).find("0..5000"), std::string::npos);
  EXPECT_NE(parse_line("drive 7 torque_bias 10", f).find("bad drive \"7\""), std::string::npos);
  EXPECT_NE(parse_line("drive 2 torque_bias -301", f).find("-300..300"), std::string::npos);
  EXPECT_NE(parse_line("drive 7 fault", f).find("bad fault \"drive 7 fault\""), std::string::npos);
  EXPECT_NE(parse_line("drive 1 statusword 021F", f).find("bad fault"), std::string::npos);
  EXPECT_NE(parse_line("drive 1 slow_enable 60001", f).find("bad fault"), std::string::npos);
  EXPECT_EQ(f.kind, FaultKind::brake_weak);
  EXPECT_EQ(f.axis, 3);
}

TEST(Vocab, EveryContactHasOneNameThatWritesAndReadsIt) {
  for (std::size_t i = 0; i < kContacts; ++i) {
    const auto c = static_cast<Contact>(i);
    for (const bool closed : {true, false}) {
      core::RawInputs raw{};
      const core::RawInputs other = raw;
      InputStep step;
      ASSERT_EQ(parse_input(to_string(c), closed ? "1" : "0", step), "") << to_string(c);
      ASSERT_EQ(step.writes.size(), 1U);
      EXPECT_EQ(step.writes[0].contact, c);
      apply(step, raw);
      EXPECT_EQ(contact_of(raw, c), closed) << to_string(c);
      for (std::size_t j = 0; j < kContacts; ++j) {  // and only it
        if (j != i) {
          EXPECT_EQ(contact_of(raw, static_cast<Contact>(j)), contact_of(other, static_cast<Contact>(j)))
              << to_string(c) << " wrote " << to_string(static_cast<Contact>(j));
        }
      }
    }
  }
}

TEST(Vocab, ShorthandsAndTheDistanceSensor) {
  InputStep step;
  ASSERT_EQ(parse_inputs(split_words("estop=pressed mode=T1 field.inner=interrupted separation_mm=420"), step), "");
  core::RawInputs raw{};
  raw.estop_a = raw.estop_b = raw.field_inner_a = raw.field_inner_b = raw.mode_auto = true;
  apply(step, raw);
  EXPECT_FALSE(raw.estop_a || raw.estop_b || raw.mode_auto || raw.field_inner_a || raw.field_inner_b);
  EXPECT_TRUE(raw.mode_t1);
  EXPECT_EQ(raw.separation_mm, 420);
  EXPECT_TRUE(raw.separation_valid) << "a reading given is valid unless the line says otherwise";

  InputStep keep;
  ASSERT_EQ(parse_inputs(split_words("gate=open"), keep), "");
  const std::size_t before = keep.writes.size();
  EXPECT_EQ(parse_inputs(split_words("gate=closed estop=maybe"), keep), "bad value 'maybe' for input estop (expected pressed|released)");
  EXPECT_EQ(keep.writes.size(), before) << "all or nothing";
  EXPECT_EQ(parse_inputs(split_words("estop.c=1"), keep), "unknown input 'estop.c'");
  EXPECT_EQ(parse_inputs(split_words("estop.a=2"), keep), "bad value '2' for contact estop.a (expected 0|1)");
  EXPECT_EQ(parse_inputs(split_words("separation_mm=-1"), keep).substr(0, 18), "bad value '-1' for");
}

TEST(Vocab, PersonLinesAndFields) {
  PersonStep step;
  bool present = false;
  EXPECT_NE(parse_person(split_words("walk 0 0 100"), step, present).find("no person in the cell"), std::string::npos);
  ASSERT_EQ(parse_person(split_words("at 1000 -500 radius=300"), step, present), "");
  EXPECT_TRUE(present);
  EXPECT_EQ(step.radius_mm, 300.0F);
  ASSERT_EQ(parse_person(split_words("walk 0 0 1600 stand 200 800 0 100"), step, present), "");
  ASSERT_EQ(step.path.size(), 2U);
  EXPECT_EQ(step.path[0].stand_ms, 200U);
  EXPECT_NE(parse_person(split_words("walk 0 0 2500"), step, present).find("over 2000"), std::string::npos);
  PersonSensors s{};
  EXPECT_EQ(parse_person_fields("1500,700", s), "");
  EXPECT_EQ(s.outer_mm, 1500.0F);
  EXPECT_NE(parse_person_fields("700,1500", s), "");
  EXPECT_EQ(s.outer_mm, 1500.0F) << "refused: nothing changed";
}

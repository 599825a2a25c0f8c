// The .scn parser (spec/scenario-format.md): every directive lands in the right fields,
// every malformed file is refused naming its line, and commands are judged by the core,
// not by the parser. No cell is needed.
#include <gtest/gtest.h>

#include <string>
#include <string_view>
#include <variant>

#include "safestate/core/alarms.hpp"
#include "safestate/core/signals.hpp"
#include "safestate/scenario/scenario.hpp"

using namespace safestate;
using namespace safestate::scenario;

namespace {

ParseResult parse_text(std::string_view text) { return parse(text, "t.scn"); }

// Parses a file that must be valid and have exactly one step.
Step only_step(std::string_view text) {
  const ParseResult r = parse_text(text);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error->text());
  EXPECT_EQ(r.scenario.steps.size(), 1U);
  return r.ok() && !r.scenario.steps.empty() ? r.scenario.steps.front() : Step{};
}

template <typename T>
T only(std::string_view text) {
  const Step s = only_step(text);
  EXPECT_TRUE(std::holds_alternative<T>(s.what));
  return std::holds_alternative<T>(s.what) ? std::get<T>(s.what) : T{};
}

core::RawInputs after(std::string_view text, core::RawInputs raw = {}) {
  apply(only<InputStep>(text), raw);
  return raw;
}

core::Command command(std::string_view text) { return only<CommandStep>(text).command; }

Expectation first_check(std::string_view text) {
  const ExpectStep e = only<ExpectStep>(text);
  EXPECT_FALSE(e.checks.empty());
  return e.checks.empty() ? Expectation{} : e.checks.front();
}

// The file must be refused on `line`, with a message containing `needle`.
void expect_malformed(std::string_view text, std::size_t line, std::string_view needle = "") {
  const ParseResult r = parse_text(text);
  ASSERT_FALSE(r.ok()) << "accepted:\n" << text;
  EXPECT_EQ(r.error->line, line) << r.error->text();
  EXPECT_EQ(r.error->file, "t.scn");
  EXPECT_NE(r.error->text().find("t.scn:" + std::to_string(line) + ": "), std::string::npos) << r.error->text();
  EXPECT_NE(r.error->message.find(needle), std::string::npos) << r.error->text();
}

}  // namespace

// --- the file -------------------------------------------------------------------------

TEST(ScenarioParser, CommentsAndBlankLinesAreIgnoredAndLinesAreNumbered) {
  const ParseResult r = parse_text(
      "# a scenario\n"
      "\n"
      "   \t\n"
      "@200  expect state=ESTOP_RESET_NEEDED reset_lamp=on   # trailing comment\n"
      "@201  cmd reset\r\n"
      "@201  expect state=IDLE\n");
  ASSERT_TRUE(r.ok()) << r.error->text();
  ASSERT_EQ(r.scenario.steps.size(), 3U);
  EXPECT_EQ(r.scenario.steps[0].line, 4U);
  EXPECT_EQ(r.scenario.steps[0].t, 200U);
  EXPECT_EQ(std::get<ExpectStep>(r.scenario.steps[0].what).checks.size(), 2U);
  EXPECT_EQ(r.scenario.steps[1].line, 5U);
  EXPECT_EQ(r.scenario.steps[2].line, 6U);
  EXPECT_EQ(r.scenario.expect_lines, 2U);
  EXPECT_EQ(r.scenario.cycles, 202U);  // cycles 0..201
  EXPECT_EQ(r.scenario.file, "t.scn");
}

TEST(ScenarioParser, AnEmptyFileRunsNoCycle) {
  const ParseResult r = parse_text("# nothing\n");
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.scenario.steps.empty());
  EXPECT_EQ(r.scenario.cycles, 0U);
}

TEST(ScenarioParser, TheSpecExampleParses) {
  const ParseResult r = parse_text(
      "# E-stop needs a deliberate reset after release (ISO 13849-1 5.2.2)\n"
      "@200  expect state=ESTOP_RESET_NEEDED reset_lamp=on\n"
      "@201  cmd reset\n"
      "@201  expect state=IDLE\n"
      "@300  in estop.a=0                 # one channel is enough to stop\n"
      "@300  expect state=ESTOP_ACTIVE stop=CAT0 contactor=open brakes=engaged\n"
      "@310  in estop.b=0\n"
      "@400  in estop=released\n"
      "@401..600 expect state=ESTOP_RESET_NEEDED   # release alone never restarts\n"
      "@601  cmd reset\n"
      "@601  expect state=IDLE reply=OK\n");
  ASSERT_TRUE(r.ok()) << r.error->text();
  EXPECT_EQ(r.scenario.steps.size(), 10U);
  EXPECT_EQ(r.scenario.expect_lines, 5U);
  EXPECT_EQ(r.scenario.cycles, 602U);
  const Step& range = r.scenario.steps[7];
  EXPECT_EQ(range.line, 9U);
  EXPECT_EQ(range.t, 401U);
  EXPECT_EQ(range.t_end, 600U);
}

TEST(ScenarioParser, ARangeEndsTheRunAtItsLastCycle) {
  const ParseResult r = parse_text("@5..900 expect state=BOOT\n@10 cmd reset\n");
  ASSERT_TRUE(r.ok()) << r.error->text();
  EXPECT_EQ(r.scenario.cycles, 901U);
  EXPECT_EQ(r.scenario.steps[0].t_end, 900U);
  EXPECT_EQ(r.scenario.steps[1].t_end, 10U);
}

TEST(ScenarioParser, LinesAtTheSameTimeKeepFileOrder) {
  const ParseResult r = parse_text("@7 in estop=pressed\n@7 expect state=ESTOP_ACTIVE\n@7 in estop=released\n");
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r.scenario.steps.size(), 3U);
  EXPECT_TRUE(std::holds_alternative<InputStep>(r.scenario.steps[0].what));
  EXPECT_TRUE(std::holds_alternative<ExpectStep>(r.scenario.steps[1].what));
  EXPECT_TRUE(std::holds_alternative<InputStep>(r.scenario.steps[2].what));
}

// --- config -----------------------------------------------------------------------------

TEST(ScenarioParser, ConfigOverridesTheDefaults) {
  const ParseResult r = parse_text(
      "config cycle_us=500 discrepancy_ms=20\n"
      "config jog_timeout_ms=200 max_stop_ms=1500 boot_timeout_ms=2000 standstill_rad_s=0.02\n"
      "@0 expect state=BOOT\n");
  ASSERT_TRUE(r.ok()) << r.error->text();
  const core::Config& c = r.scenario.config;
  EXPECT_EQ(c.cycle_us, 500U);
  EXPECT_EQ(c.discrepancy_ms, 20U);
  EXPECT_EQ(c.jog_timeout_ms, 200U);
  EXPECT_EQ(c.max_stop_ms, 1500U);
  EXPECT_EQ(c.boot_timeout_ms, 2000U);
  EXPECT_FLOAT_EQ(c.standstill_rad_s, 0.02F);
  EXPECT_EQ(c.max_commands_per_cycle, core::Config{}.max_commands_per_cycle);  // untouched
}

TEST(ScenarioParser, WithoutConfigTheDefaultsHold) {
  const ParseResult r = parse_text("@0 expect state=BOOT\n");
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.scenario.config.cycle_us, core::Config{}.cycle_us);
  EXPECT_EQ(r.scenario.config.discrepancy_ms, core::Config{}.discrepancy_ms);
}

TEST(ScenarioParser, ConfigAfterATimedLineIsMalformed) {
  expect_malformed("@0 expect state=BOOT\nconfig cycle_us=500\n", 2, "config");
}

TEST(ScenarioParser, TimedConfigIsMalformed) { expect_malformed("@0 config cycle_us=500\n", 1, "config"); }

TEST(ScenarioParser, InvalidConfigValueNamesTheField) {
  expect_malformed("# header\nconfig cycle_us=100\n@0 expect state=BOOT\n", 2, "cycle_us");
  expect_malformed("config discrepancy_ms=0\n", 1, "discrepancy_ms");
  expect_malformed("config standstill_rad_s=0\n@1 expect state=BOOT\n", 1, "standstill_rad_s");
  // The field reported by validate() is put on the line that set it.
  expect_malformed("config max_stop_ms=0\nconfig cycle_us=500\n@1 expect state=BOOT\n", 1, "max_stop_ms");
}

TEST(ScenarioParser, UnparseableOrUnknownConfigIsMalformed) {
  expect_malformed("config cycle_us=fast\n", 1, "cycle_us");
  expect_malformed("config cycle_us=-5\n", 1, "cycle_us");
  expect_malformed("config standstill_rad_s=nan\n", 1, "standstill_rad_s");
  expect_malformed("config\n", 1, "config");
  expect_malformed("config cycle_us\n", 1, "NAME=VALUE");
  expect_malformed("config t1_speed_limit_mm_s=100\n", 1, "t1_speed_limit_mm_s");
}

// --- time -------------------------------------------------------------------------------

TEST(ScenarioParser, BadTimeIsMalformed) {
  expect_malformed("@abc expect state=BOOT\n", 1, "time");
  expect_malformed("@-5 expect state=BOOT\n", 1, "time");
  expect_malformed("@+5 expect state=BOOT\n", 1, "time");
  expect_malformed("@ expect state=BOOT\n", 1, "time");
  expect_malformed("@1.5 expect state=BOOT\n", 1, "time");
  expect_malformed("@99999999999999999999999 expect state=BOOT\n", 1, "time");
  expect_malformed("@2000000000 expect state=BOOT\n", 1, "too large");
  expect_malformed("@5..x expect state=BOOT\n", 1, "time");
  expect_malformed("@5..3 expect state=BOOT\n", 1, "range");
  expect_malformed("@5\n", 1, "directive");
}

TEST(ScenarioParser, TimeGoingBackwardsIsMalformed) {
  expect_malformed("@10 expect state=BOOT\n@20 expect state=BOOT\n# gap\n@15 cmd reset\n", 4, "backwards");
  expect_malformed("@10 cmd reset\n@9 expect state=BOOT\n", 2, "backwards");
  // A range between them does not hide it.
  expect_malformed("@100 cmd reset\n@0..5 expect state=BOOT\n@50 cmd reset\n", 3, "backwards");
  // Equal times and a range ending after a later line are fine.
  EXPECT_TRUE(parse_text("@10 cmd reset\n@10 cmd reset\n@10..500 expect state=IDLE\n@20 cmd reset\n").ok());
}

// As in the shared scenario t1-jog.scn: a range written after the actions it watches.
TEST(ScenarioParser, ARangeMayBeWrittenAfterTheLinesItCovers) {
  const ParseResult r = parse_text(
      "@810  cmd jog 1 + 100\n"
      "@810  expect sub=MANUAL_JOGGING\n"
      "@970  cmd jog 1 + 100\n"
      "@810..1000 expect tcp_speed<=250\n"
      "@1000 in enable=released\n");
  ASSERT_TRUE(r.ok()) << r.error->text();
  ASSERT_EQ(r.scenario.steps.size(), 5U);
  // Sorted by first cycle, file order kept within a cycle: only the range moved.
  const std::size_t lines[] = {1, 2, 4, 3, 5};
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(r.scenario.steps[i].line, lines[i]) << i;
  }
  EXPECT_EQ(r.scenario.steps[2].t, 810U);
  EXPECT_EQ(r.scenario.steps[2].t_end, 1000U);
  EXPECT_EQ(r.scenario.cycles, 1001U);
  // A range does not move the time on either: a later @T is compared with the @T lines.
  EXPECT_TRUE(parse_text("@10 cmd reset\n@100..200 expect state=IDLE\n@50 cmd reset\n").ok());
}

TEST(ScenarioParser, RangeOnANonExpectIsMalformed) {
  expect_malformed("@1..5 in estop=pressed\n", 1, "range");
  expect_malformed("@0 expect state=BOOT\n@1..5 cmd reset\n", 2, "range");
  expect_malformed("@1..5 fault fieldbus lost\n", 1, "range");
}

TEST(ScenarioParser, UnknownDirectiveIsMalformed) {
  expect_malformed("@0 expect state=BOOT\n@1 wait 5\n", 2, "wait");
  expect_malformed("\n\nexpect state=BOOT\n", 3, "expect");
  expect_malformed("@1 IN estop=pressed\n", 1, "IN");
}

// --- in ---------------------------------------------------------------------------------

TEST(ScenarioParser, InputShorthandsSetBothChannels) {
  core::RawInputs r = after("@0 in estop=pressed gate=open\n");
  EXPECT_FALSE(r.estop_a);
  EXPECT_FALSE(r.estop_b);
  EXPECT_FALSE(r.gate_a);
  EXPECT_FALSE(r.gate_b);
  r = after("@0 in estop=released gate=closed\n", r);
  EXPECT_TRUE(r.estop_a && r.estop_b && r.gate_a && r.gate_b);
}

TEST(ScenarioParser, EnableShorthands) {
  core::RawInputs r = after("@0 in enable=centre\n");
  EXPECT_TRUE(r.enable_a && r.enable_b);
  EXPECT_FALSE(r.enable_panic);
  r = after("@0 in enable=panic\n", r);
  EXPECT_FALSE(r.enable_a || r.enable_b);
  EXPECT_TRUE(r.enable_panic);
  r = after("@0 in enable=released\n", r);
  EXPECT_FALSE(r.enable_a || r.enable_b || r.enable_panic);
}

TEST(ScenarioParser, ModeShorthandsAreOneHot) {
  core::RawInputs r = after("@0 in mode=T1\n");
  EXPECT_FALSE(r.mode_auto);
  EXPECT_TRUE(r.mode_t1);
  EXPECT_FALSE(r.mode_t2);
  r = after("@0 in mode=T2\n", r);
  EXPECT_TRUE(!r.mode_auto && !r.mode_t1 && r.mode_t2);
  r = after("@0 in mode=AUTO\n", r);
  EXPECT_TRUE(r.mode_auto && !r.mode_t1 && !r.mode_t2);
  r = after("@0 in mode=NONE\n", r);
  EXPECT_TRUE(!r.mode_auto && !r.mode_t1 && !r.mode_t2);
}

TEST(ScenarioParser, ResetButtonAndRawContacts) {
  core::RawInputs r = after("@0 in reset_button=1\n");
  EXPECT_TRUE(r.reset_button);
  r = after("@0 in reset_button=0 estop.a=0 gate.b=0 enable.a=1 enable.panic=1 mode.t2=1 mode.auto=0\n", r);
  EXPECT_FALSE(r.reset_button);
  EXPECT_FALSE(r.estop_a);
  EXPECT_TRUE(r.estop_b);
  EXPECT_TRUE(r.gate_a);
  EXPECT_FALSE(r.gate_b);
  EXPECT_TRUE(r.enable_a);
  EXPECT_FALSE(r.enable_b);
  EXPECT_TRUE(r.enable_panic);
  EXPECT_TRUE(r.mode_t2);
  EXPECT_FALSE(r.mode_auto);
  r = after("@0 in estop.b=0 gate.a=0 enable.b=1 mode.t1=1\n", r);
  EXPECT_FALSE(r.estop_b);
  EXPECT_FALSE(r.gate_a);
  EXPECT_TRUE(r.enable_b);
  EXPECT_TRUE(r.mode_t1);
}

TEST(ScenarioParser, LaterKeysOnALineWin) {
  const core::RawInputs r = after("@0 in estop=pressed estop.a=1\n");
  EXPECT_TRUE(r.estop_a);
  EXPECT_FALSE(r.estop_b);
}

TEST(ScenarioParser, BadInputsAreMalformed) {
  expect_malformed("@0 in\n", 1, "in");
  expect_malformed("@0 in door=open\n", 1, "door");
  expect_malformed("@0 in estop=open\n", 1, "estop");
  expect_malformed("@0 in enable=center\n", 1, "center");
  expect_malformed("@0 in mode=t1\n", 1, "mode");
  expect_malformed("@0 in reset_button=2\n", 1, "reset_button");
  expect_malformed("@0 in estop.a=2\n", 1, "estop.a");
  expect_malformed("@0 in estop.c=1\n", 1, "estop.c");
  expect_malformed("@0 in estop\n", 1, "KEY=VALUE");
  expect_malformed("@0 in =1\n", 1, "KEY=VALUE");
}

// --- cmd --------------------------------------------------------------------------------

TEST(ScenarioParser, SimpleCommandsFromThePendant) {
  const struct {
    const char* text;
    core::CommandId id;
  } cases[] = {
      {"@3 cmd reset\n", core::CommandId::reset},         {"@3 cmd servo_on\n", core::CommandId::servo_on},
      {"@3 cmd servo_off\n", core::CommandId::servo_off}, {"@3 cmd start\n", core::CommandId::start},
      {"@3 cmd pause\n", core::CommandId::pause},         {"@3 cmd resume\n", core::CommandId::resume},
      {"@3 cmd stop\n", core::CommandId::stop},           {"@3 cmd jog_stop\n", core::CommandId::jog_stop},
      {"@3 cmd confirm_t2\n", core::CommandId::confirm_t2},
  };
  for (const auto& k : cases) {
    const CommandStep c = only<CommandStep>(k.text);
    EXPECT_EQ(c.command.id, static_cast<std::uint8_t>(k.id)) << k.text;
    EXPECT_EQ(c.command.source, static_cast<std::uint8_t>(core::Source::pendant)) << k.text;
    EXPECT_EQ(c.command.seq, 1U) << k.text;
    EXPECT_EQ(c.name, core::to_string(k.id));
  }
}

TEST(ScenarioParser, FromSelectsTheSource) {
  EXPECT_EQ(command("@0 cmd from=remote start\n").source, static_cast<std::uint8_t>(core::Source::remote));
  EXPECT_EQ(command("@0 cmd from=pendant start\n").source, static_cast<std::uint8_t>(core::Source::pendant));
  EXPECT_EQ(command("@0 cmd from=remote start\n").id, static_cast<std::uint8_t>(core::CommandId::start));
}

TEST(ScenarioParser, BadFromIsMalformed) {
  expect_malformed("@0 cmd from=observer start\n", 1, "from");
  expect_malformed("@0 cmd from=reset_button reset\n", 1, "from");
  expect_malformed("@0 cmd from= start\n", 1, "from");
  expect_malformed("@0 cmd from=remote\n", 1, "name");
  expect_malformed("@0 cmd\n", 1, "name");
}

TEST(ScenarioParser, EveryCommandGetsAUniqueSeq) {
  const ParseResult r = parse_text("@0 cmd reset\n@0 cmd reset\n\n@5 cmd servo_on\n");
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(std::get<CommandStep>(r.scenario.steps[0].what).command.seq, 1U);
  EXPECT_EQ(std::get<CommandStep>(r.scenario.steps[1].what).command.seq, 2U);
  EXPECT_EQ(std::get<CommandStep>(r.scenario.steps[2].what).command.seq, 4U);
}

TEST(ScenarioParser, JogArguments) {
  core::Command c = command("@0 cmd jog 3 +\n");
  EXPECT_EQ(c.id, static_cast<std::uint8_t>(core::CommandId::jog));
  EXPECT_EQ(c.axis, 3);
  EXPECT_EQ(c.dir, 1);
  EXPECT_EQ(c.speed, 10U);  // default
  c = command("@0 cmd jog 6 - 25\n");
  EXPECT_EQ(c.axis, 6);
  EXPECT_EQ(c.dir, -1);
  EXPECT_EQ(c.speed, 25U);
}

TEST(ScenarioParser, BadJogArgumentsAreSentForTheCoreToRefuse) {
  // Not parse errors: each is sent with an invalid field, so the core answers BAD_ARGUMENT.
  EXPECT_EQ(command("@0 cmd jog 9 +\n").axis, 9);
  EXPECT_EQ(command("@0 cmd jog x +\n").axis, 0);
  EXPECT_EQ(command("@0 cmd jog 1000 +\n").axis, 0);
  EXPECT_EQ(command("@0 cmd jog\n").axis, 0);
  EXPECT_EQ(command("@0 cmd jog 2\n").dir, 0);
  EXPECT_EQ(command("@0 cmd jog 2 up\n").dir, 0);
  EXPECT_EQ(command("@0 cmd jog 2 + fast\n").speed, 0U);
  EXPECT_EQ(command("@0 cmd jog 2 + 0\n").speed, 0U);
  EXPECT_EQ(command("@0 cmd jog 2 + 500\n").speed, 0U);
  EXPECT_EQ(command("@0 cmd jog 2 + 150\n").speed, 150U);
  EXPECT_EQ(command("@0 cmd jog 2 + 10 extra\n").axis, 0);
}

TEST(ScenarioParser, SetModeArgument) {
  EXPECT_EQ(command("@0 cmd set_mode T1\n").mode, static_cast<std::uint8_t>(core::Mode::T1));
  EXPECT_EQ(command("@0 cmd set_mode AUTO\n").mode, static_cast<std::uint8_t>(core::Mode::AUTO));
  EXPECT_EQ(command("@0 cmd set_mode T3\n").mode, 0U);
  EXPECT_EQ(command("@0 cmd set_mode\n").mode, 0U);
  EXPECT_EQ(command("@0 cmd set_mode T1 T2\n").mode, 0U);
  EXPECT_EQ(command("@0 cmd set_mode T2\n").id, static_cast<std::uint8_t>(core::CommandId::set_mode));
}

TEST(ScenarioParser, UnknownCommandIsSentNotRefused) {
  const CommandStep c = only<CommandStep>("@0 cmd from=remote fly_to_the_moon 1 2 3\n");
  EXPECT_EQ(c.command.id, static_cast<std::uint8_t>(core::kCommandCount));
  EXPECT_EQ(c.command.source, static_cast<std::uint8_t>(core::Source::remote));
  EXPECT_EQ(c.name, "fly_to_the_moon");
  EXPECT_EQ(only<CommandStep>("@0 cmd RESET\n").command.id, static_cast<std::uint8_t>(core::kCommandCount));
}

TEST(ScenarioParser, ArgumentToACommandWithoutArgumentsIsMalformed) {
  expect_malformed("@0 cmd start now\n", 1, "start");
  expect_malformed("@0 cmd start from=remote\n", 1, "from=remote");
}

// --- fault ------------------------------------------------------------------------------

TEST(ScenarioParser, Faults) {
  const struct {
    const char* text;
    sim::FaultKind kind;
    std::uint8_t axis;
  } cases[] = {
      {"@0 fault drive 1 fault\n", sim::FaultKind::drive_fault, 1},
      {"@0 fault drive 6 clear\n", sim::FaultKind::drive_clear, 6},
      {"@0 fault drive 3 runaway\n", sim::FaultKind::drive_runaway, 3},
      {"@0 fault drive 4 nostop\n", sim::FaultKind::drive_nostop, 4},
      {"@0 fault fieldbus lost\n", sim::FaultKind::fieldbus_lost, 0},
      {"@0 fault contactor stuck_open\n", sim::FaultKind::contactor_stuck_open, 0},
      {"@0 fault brake 2 stuck\n", sim::FaultKind::brake_stuck, 2},
      {"@0 fault clear all\n", sim::FaultKind::clear_all, 0},
  };
  for (const auto& k : cases) {
    const FaultStep f = only<FaultStep>(k.text);
    EXPECT_EQ(f.fault.kind, k.kind) << k.text;
    EXPECT_EQ(f.fault.axis, k.axis) << k.text;
  }
}

TEST(ScenarioParser, BadFaultSyntaxIsMalformed) {
  const char* bad[] = {
      "@0 fault\n",
      "@0 fault drive 0 fault\n",
      "@0 fault drive 7 fault\n",
      "@0 fault drive x fault\n",
      "@0 fault drive 1\n",
      "@0 fault drive 1 explode\n",
      "@0 fault drive 1 fault now\n",
      "@0 fault fieldbus\n",
      "@0 fault fieldbus down\n",
      "@0 fault contactor stuck_closed\n",
      "@0 fault brake 2\n",
      "@0 fault brake 9 stuck\n",
      "@0 fault clear\n",
      "@0 fault clear everything\n",
      "@0 fault power lost\n",
  };
  for (const char* text : bad) {
    SCOPED_TRACE(text);
    expect_malformed(text, 1, "fault");
  }
}

// --- expect -----------------------------------------------------------------------------

TEST(ScenarioParser, ExpectNamedValues) {
  Expectation e = first_check("@0 expect state=ESTOP_RESET_NEEDED\n");
  EXPECT_EQ(e.key, ExpectKey::state);
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::State::ESTOP_RESET_NEEDED));
  EXPECT_EQ(e.text, "state=ESTOP_RESET_NEEDED");
  e = first_check("@0 expect sub=MANUAL_JOGGING\n");
  EXPECT_EQ(e.key, ExpectKey::sub);
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::Sub::MANUAL_JOGGING));
  e = first_check("@0 expect sub=-\n");
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::Sub::NONE));
  e = first_check("@0 expect mode=T2\n");
  EXPECT_EQ(e.key, ExpectKey::mode);
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::Mode::T2));
  e = first_check("@0 expect mode=NONE\n");
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::Mode::NONE));
  e = first_check("@0 expect stop=CAT1\n");
  EXPECT_EQ(e.key, ExpectKey::stop);
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::StopCat::CAT1));
  e = first_check("@0 expect stop=-\n");
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::StopCat::NONE));
  e = first_check("@0 expect alarm=PROTECTIVE_STOP\n");
  EXPECT_EQ(e.key, ExpectKey::alarm);
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::AlarmId::PROTECTIVE_STOP));
  e = first_check("@0 expect noalarm=JOG_LINK_LOST\n");
  EXPECT_EQ(e.key, ExpectKey::noalarm);
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::AlarmId::JOG_LINK_LOST));
  e = first_check("@0 expect reply=MODE_BY_SELECTOR_ONLY\n");
  EXPECT_EQ(e.key, ExpectKey::reply);
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::Result::MODE_BY_SELECTOR_ONLY));
}

TEST(ScenarioParser, ExpectOutputs) {
  const ExpectStep s = only<ExpectStep>(
      "@0 expect contactor=closed drives=enabled brakes=released reset_lamp=on "
      "contactor=open drives=disabled brakes=engaged reset_lamp=off\n");
  ASSERT_EQ(s.checks.size(), 8U);
  const ExpectKey keys[] = {ExpectKey::contactor, ExpectKey::drives, ExpectKey::brakes, ExpectKey::reset_lamp};
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(s.checks[i].key, keys[i]);
    EXPECT_EQ(s.checks[i].value, 1U);
    EXPECT_EQ(s.checks[i + 4].key, keys[i]);
    EXPECT_EQ(s.checks[i + 4].value, 0U);
  }
}

TEST(ScenarioParser, ExpectTcpSpeed) {
  const ExpectStep s =
      only<ExpectStep>("@0 expect tcp_speed<=250 tcp_speed<0.5 tcp_speed>=1e2 tcp_speed>-3 state=IDLE\n");
  ASSERT_EQ(s.checks.size(), 5U);
  EXPECT_EQ(s.checks[0].key, ExpectKey::tcp_speed);
  EXPECT_EQ(s.checks[0].cmp, Compare::le);
  EXPECT_DOUBLE_EQ(s.checks[0].limit, 250.0);
  EXPECT_EQ(s.checks[1].cmp, Compare::lt);
  EXPECT_DOUBLE_EQ(s.checks[1].limit, 0.5);
  EXPECT_EQ(s.checks[2].cmp, Compare::ge);
  EXPECT_DOUBLE_EQ(s.checks[2].limit, 100.0);
  EXPECT_EQ(s.checks[3].cmp, Compare::gt);
  EXPECT_DOUBLE_EQ(s.checks[3].limit, -3.0);
  EXPECT_EQ(s.checks[0].text, "tcp_speed<=250");
  EXPECT_EQ(s.checks[4].key, ExpectKey::state);
}

TEST(ScenarioParser, BadExpectsAreMalformed) {
  expect_malformed("@0 expect\n", 1, "expect");
  expect_malformed("@0 expect colour=red\n", 1, "colour");
  expect_malformed("@0 expect state=RUNNING\n", 1, "RUNNING");
  expect_malformed("@0 expect state=idle\n", 1, "idle");
  expect_malformed("@0 expect sub=NONE\n", 1, "NONE");
  expect_malformed("@0 expect mode=T3\n", 1, "T3");
  expect_malformed("@0 expect stop=CAT3\n", 1, "CAT3");
  expect_malformed("@0 expect contactor=shut\n", 1, "shut");
  expect_malformed("@0 expect drives=on\n", 1, "drives");
  expect_malformed("@0 expect brakes=on\n", 1, "brakes");
  expect_malformed("@0 expect reset_lamp=1\n", 1, "reset_lamp");
  expect_malformed("@0 expect alarm=FIRE\n", 1, "FIRE");
  expect_malformed("@0 expect noalarm=\n", 1, "noalarm");
  expect_malformed("@0 expect reply=waiting\n", 1, "waiting");  // `pending` is a value (SPEC §9)
  expect_malformed("@0 expect tcp_speed=5\n", 1, "tcp_speed");
  expect_malformed("@0 expect tcp_speed<=fast\n", 1, "tcp_speed");
  expect_malformed("@0 expect tcp_speed<=inf\n", 1, "tcp_speed");
  expect_malformed("@0 expect tcp_speed<\n", 1, "tcp_speed");
  expect_malformed("@0 expect state\n", 1, "KEY=VALUE");
  // The first bad key of a line is named, on the right line.
  expect_malformed("@0 expect state=IDLE\n@1 expect state=IDLE alarm=NOPE\n", 2, "NOPE");
}

TEST(ScenarioParser, TheFirstProblemIsReported) {
  expect_malformed("@0 expect state=IDLE\n@1 in door=open\n@0 cmd reset\n", 2, "door");
}

// @req BT-SCENARIO
TEST(ScenarioParser, BrakeTestKeys) {
  // config brake_test_age_h: hours (fractions too) or never; the default is never.
  EXPECT_FALSE(parse_text("@0 expect state=BOOT\n").scenario.brake_test.passed_ever);
  const ParseResult r = parse_text("config brake_test_age_h=7.5\n@0 expect state=BOOT\n");
  ASSERT_TRUE(r.ok()) << r.error->text();
  EXPECT_TRUE(r.scenario.brake_test.passed_ever);
  EXPECT_EQ(r.scenario.brake_test.pass_age_ms, 27000000U);
  EXPECT_EQ(r.scenario.brake_test.last, core::BrakeTestResult::passed);
  EXPECT_FALSE(parse_text("config brake_test_age_h=never\n@0 expect state=BOOT\n").scenario.brake_test.passed_ever);
  expect_malformed("config brake_test_age_h=-1\n", 1, "brake_test_age_h");
  expect_malformed("config brake_test_age_h=soon\n", 1, "brake_test_age_h");
  expect_malformed("config brake_test_age_h=\n", 1, "brake_test_age_h");
  // cmd brake_test, sub=BRAKE_TEST, fault brake N weak, expect brake_test=.
  EXPECT_EQ(command("@0 cmd brake_test\n").id, static_cast<std::uint8_t>(core::CommandId::brake_test));
  EXPECT_EQ(first_check("@0 expect sub=BRAKE_TEST\n").value, static_cast<std::uint8_t>(core::Sub::BRAKE_TEST));
  const sim::Fault f = only<FaultStep>("@0 fault brake 4 weak\n").fault;
  EXPECT_EQ(f.kind, sim::FaultKind::brake_weak);
  EXPECT_EQ(f.axis, 4U);
  expect_malformed("@0 fault brake 7 weak\n", 1, "fault");
  expect_malformed("@0 fault brake 1 feeble\n", 1, "fault");
  const Expectation e = first_check("@0 expect brake_test=failed\n");
  EXPECT_EQ(e.key, ExpectKey::brake_test);
  EXPECT_EQ(e.value, static_cast<std::uint8_t>(core::BrakeTestResult::failed));
  expect_malformed("@0 expect brake_test=ok\n", 1, "brake_test");
}

// @req COL-SIM-CONTACT
TEST(ScenarioParser, CollisionFaults) {
  // fault contact F: newtons (fractions too), stored in tenths; 0 removes it.
  sim::Fault f = only<FaultStep>("@0 fault contact 150\n").fault;
  EXPECT_EQ(f.kind, sim::FaultKind::contact);
  EXPECT_EQ(f.value, 1500U);
  EXPECT_EQ(only<FaultStep>("@0 fault contact 0\n").fault.value, 0U);
  EXPECT_EQ(only<FaultStep>("@0 fault contact 12.34\n").fault.value, 123U);
  EXPECT_EQ(only<FaultStep>("@0 fault contact 5000\n").fault.value, 50000U);
  for (const char* bad : {"@0 fault contact -1\n", "@0 fault contact 5000.1\n", "@0 fault contact\n",
                          "@0 fault contact many\n", "@0 fault contact 10 N\n", "@0 fault contact nan\n"}) {
    expect_malformed(bad, 1, "fault");
  }
  // fault drive N torque_bias X: percent of rated torque, signed, stored as int16 per mille.
  f = only<FaultStep>("@0 fault drive 2 torque_bias 5\n").fault;
  EXPECT_EQ(f.kind, sim::FaultKind::drive_torque_bias);
  EXPECT_EQ(f.axis, 2U);
  EXPECT_EQ(static_cast<std::int16_t>(f.value), 50);
  EXPECT_EQ(static_cast<std::int16_t>(only<FaultStep>("@0 fault drive 6 torque_bias -12.5\n").fault.value), -125);
  EXPECT_EQ(static_cast<std::int16_t>(only<FaultStep>("@0 fault drive 1 torque_bias -300\n").fault.value), -3000);
  for (const char* bad : {"@0 fault drive 7 torque_bias 5\n", "@0 fault drive 0 torque_bias 5\n",
                          "@0 fault drive 2 torque_bias 301\n", "@0 fault drive 2 torque_bias -300.5\n",
                          "@0 fault drive 2 torque_bias\n", "@0 fault drive 2 torque_bias x\n",
                          "@0 fault drive 2 torque 5\n"}) {
    expect_malformed(bad, 1, "fault");
  }
}

// @req COL-SIM-PERSON
TEST(ScenarioParser, PersonKeys) {
  // config person_fields=OUTER,INNER; the defaults are 2000 / 1000.
  EXPECT_FLOAT_EQ(parse_text("@0 expect state=BOOT\n").scenario.person_sensors.outer_mm, 2000.0F);
  const ParseResult r = parse_text("config person_fields=1500,600.5\n@0 expect state=BOOT\n");
  ASSERT_TRUE(r.ok()) << r.error->text();
  EXPECT_FLOAT_EQ(r.scenario.person_sensors.outer_mm, 1500.0F);
  EXPECT_FLOAT_EQ(r.scenario.person_sensors.inner_mm, 600.5F);
  expect_malformed("config person_fields=1000,1000\n", 1, "person_fields");
  expect_malformed("config person_fields=1000\n", 1, "OUTER,INNER");
  expect_malformed("config person_fields=500,1000\n", 1, "INNER < OUTER");
  expect_malformed("config person_fields=30000,1000\n", 1, "20000");
  // person at / walk / stand / leave.
  const PersonStep at = only<PersonStep>("@0 person at -1500 20.5\n");
  EXPECT_EQ(at.action, PersonStep::Action::at);
  EXPECT_FLOAT_EQ(at.x_mm, -1500.0F);
  EXPECT_FLOAT_EQ(at.y_mm, 20.5F);
  EXPECT_FLOAT_EQ(at.radius_mm, 250.0F);
  const ParseResult w = parse_text(
      "@0 person at 4000 0 radius=300\n@1 person walk 1000 0 1600 stand 2000 0 -3000 2000\n@2 person stand\n"
      "@3 person leave\n@4 person at 0 3000\n");
  ASSERT_TRUE(w.ok()) << w.error->text();
  ASSERT_EQ(w.scenario.steps.size(), 5U);
  EXPECT_FLOAT_EQ(std::get<PersonStep>(w.scenario.steps[0].what).radius_mm, 300.0F);
  const PersonStep& walk = std::get<PersonStep>(w.scenario.steps[1].what);
  EXPECT_EQ(walk.action, PersonStep::Action::walk);
  ASSERT_EQ(walk.path.size(), 2U);
  EXPECT_FLOAT_EQ(walk.path[0].x_mm, 1000.0F);
  EXPECT_FLOAT_EQ(walk.path[0].speed_mm_s, 1600.0F);
  EXPECT_EQ(walk.path[0].stand_ms, 2000U);
  EXPECT_FLOAT_EQ(walk.path[1].y_mm, -3000.0F);
  EXPECT_FLOAT_EQ(walk.path[1].speed_mm_s, 2000.0F);
  EXPECT_EQ(walk.path[1].stand_ms, 0U);
  EXPECT_EQ(std::get<PersonStep>(w.scenario.steps[2].what).action, PersonStep::Action::stand);
  EXPECT_EQ(std::get<PersonStep>(w.scenario.steps[3].what).action, PersonStep::Action::leave);
  // Each refusal names the line and what is wrong.
  expect_malformed("@0 person at 0 0\n@5 person walk 1000 0 2000.5\n", 2, "over 2000");
  expect_malformed("@0 person at 0 0\n@5 person walk 1000 0 0\n", 2, "not above 0");
  expect_malformed("@0 person at 0 0\n@5 person walk 1000 0 1600 500 0\n", 2, "point 2 needs X Y SPEED, found 2");
  expect_malformed("@0 person at 0 0\n@5 person walk 1000 0 stand 100\n", 2, "point 1 needs X Y SPEED, found 2");
  expect_malformed("@0 person at 0 0\n@5 person walk 1000 0 1600 stand\n", 2, "stand needs MS");
  expect_malformed("@0 person at 0 0\n@5 person walk 1000 0 1600 stand -4\n", 2, "stand needs MS");
  expect_malformed("@0 person at 0 0\n@5 person walk\n", 2, "at least one point");
  expect_malformed("@0 person at 0 0\n@5 person walk x 0 1600\n", 2, "not a number");
  expect_malformed("@0 person at 0 0\n@5 person walk 0 25000 1600\n", 2, "off the floor");
  expect_malformed("@0 person walk 1000 0 1600\n", 1, "no person in the cell");
  expect_malformed("@0 person at 0 0\n@1 person leave\n@2 person stand\n", 3, "no person in the cell");
  expect_malformed("@0 person leave\n", 1, "no person in the cell");
  expect_malformed("@0 person at 0\n", 1, "needs X Y");
  expect_malformed("@0 person at 0 0 radius=0\n", 1, "radius");
  expect_malformed("@0 person at 0 0 size=3\n", 1, "radius=R");
  expect_malformed("@0 person at 0 0\n@1 person stand 500\n", 2, "takes nothing");
  expect_malformed("@0 person run 0 0\n", 1, "unknown person action 'run'");
  expect_malformed("@0 person\n", 1, "person needs");
  std::string seventeen = "@0 person at 0 0\n@1 person walk";
  for (int i = 0; i < 17; ++i) seventeen += " 100 100 1000";
  expect_malformed(seventeen + "\n", 2, "more than 16 points");
}

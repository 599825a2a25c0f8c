// The shared-memory bridge: rings, seqlock, the segment's header checks, and the
// runtime's side of it (records in, events/replies/status/black box out).
#include <gtest/gtest.h>

#include <sys/mman.h>
#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <string>
#include <thread>

#include "safestate/bridge/segment.hpp"
#include "safestate/core/monitors.hpp"
#include "safestate/sim/cell.hpp"  // the simulated world the runtime is tested on
#include "safestate/controller/channels.hpp"
#include "safestate/runtime/runtime.hpp"

using namespace safestate;
using namespace safestate::bridge;

namespace {
std::string unique_name(const char* what) { return "/safestate-test-" + std::string(what) + "-" + std::to_string(getpid()); }

// A configuration the status can be told apart by: checksum 3AD9012B, TCP 1500 mm/s.
core::SafetyLimits safety_limits_for_test() {
  core::SafetyLimits l{};
  l.checksum = 0x3AD9012BU;
  for (auto& j : l.joints) {
    j.min_rad = -2.0F;
    j.max_rad = 2.0F;
    j.max_speed_rad_s = 3.0F;
  }
  l.tcp_max_speed_mm_s = 1500.0F;
  return l;
}

// The same with collaborative operation and SSM on: v_h 1600, a 2000, T_r 100 ms, C 200, Z 100.
core::SafetyLimits ssm_limits_for_test() {
  core::SafetyLimits l = safety_limits_for_test();
  l.collaborative.enabled = true;
  l.collaborative.ssm_enabled = true;
  l.collaborative.ssm = core::SsmParams{1600.0F, 2000.0F, 0.1F, 200.0F, 100.0F};
  return l;
}
}  // namespace

TEST(Ring, FifoAndFullWithoutWaiting) {
  static Ring<int, 4> r;
  for (int i = 0; i < 4; ++i) {
    EXPECT_TRUE(r.push(i));
  }
  EXPECT_FALSE(r.push(99)) << "a full ring refuses, it never waits";
  int v = -1;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(r.pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(r.pop(v));
}

TEST(Ring, PeekKeepsTheSlotUntilAdvance) {
  // The gateway makes an event durable before it frees its slot (protocol.md "Nothing lost").
  static Ring<int, 4> r;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(r.push(i));
  }
  int v = -1;
  ASSERT_TRUE(r.peek(0, v));
  EXPECT_EQ(v, 0);
  ASSERT_TRUE(r.peek(3, v));
  EXPECT_EQ(v, 3);
  EXPECT_FALSE(r.peek(4, v));
  EXPECT_FALSE(r.push(4)) << "peeked records still hold their slots";
  r.advance(2);
  EXPECT_EQ(r.size(), 2U);
  ASSERT_TRUE(r.push(4));
  r.advance_to(1);  // behind the tail: ignored
  r.advance_to(99);  // beyond the head: ignored
  ASSERT_TRUE(r.peek(0, v));
  EXPECT_EQ(v, 2);
  r.advance_to(4);  // a predecessor had committed up to 4
  ASSERT_TRUE(r.pop(v));
  EXPECT_EQ(v, 4);
  EXPECT_FALSE(r.pop(v));
}

TEST(Ring, TwoThreadsTransferEveryRecordInOrder) {
  static Ring<std::uint64_t, 64> r;
  constexpr std::uint64_t kN = 200000;
  std::thread producer([] {
    for (std::uint64_t i = 1; i <= kN;) {
      if (r.push(i)) ++i;
    }
  });
  std::uint64_t expect = 1;
  while (expect <= kN) {
    std::uint64_t v = 0;
    if (r.pop(v)) {
      ASSERT_EQ(v, expect);
      ++expect;
    }
  }
  producer.join();
}

TEST(SeqLock, ReaderNeverSeesATornSnapshot) {
  struct Big {
    std::array<std::uint64_t, 40> v;
  };
  static SeqLock<Big> lock;
  std::atomic<bool> done{false};
  std::atomic<std::uint64_t> read_count{0};
  // The writer keeps writing until the reader has read concurrently a number of times (on a
  // loaded machine 100,000 writes could end before the reader thread ever ran), bounded.
  std::thread writer([&] {
    Big b{};
    for (std::uint64_t k = 1; (k < 100000) || ((read_count.load() < 100U) && (k < 20000000)); ++k) {
      b.v.fill(k);
      lock.write(b);
    }
    done = true;
  });
  std::uint64_t reads = 0;
  while (!done.load()) {
    Big b{};
    if (lock.read(b)) {
      for (std::uint64_t x : b.v) {
        ASSERT_EQ(x, b.v[0]) << "torn read";
      }
      ++reads;
      read_count.store(reads);
    }
  }
  writer.join();
  EXPECT_GT(reads, 0U);
}

TEST(Segment, CreateAttachAndShareState) {
  const std::string name = unique_name("share");
  std::string err;
  auto core_side = Segment::create(name, err);
  ASSERT_TRUE(core_side) << err;
  auto gw_side = Segment::attach(name, err);
  ASSERT_TRUE(gw_side) << err;
  CommandRecord c{};
  c.seq = 42;
  ASSERT_TRUE(gw_side->commands().push(c));
  CommandRecord got{};
  ASSERT_TRUE(core_side->commands().pop(got));
  EXPECT_EQ(got.seq, 42U);
  core_side->header().core_heartbeat.store(7);
  EXPECT_EQ(gw_side->header().core_heartbeat.load(), 7U);
}

TEST(Segment, AttachRefusesAMissingOrForeignSegment) {
  std::string err;
  EXPECT_FALSE(Segment::attach("/safestate-test-none", err));
  EXPECT_NE(err.find("/safestate-test-none"), std::string::npos);

  const std::string name = unique_name("foreign");
  {
    const int fd = shm_open(name.c_str(), O_CREAT | O_RDWR, 0600);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(ftruncate(fd, static_cast<off_t>(layout().size)), 0);
    close(fd);  // right size, but zeros: no magic
  }
  err.clear();
  EXPECT_FALSE(Segment::attach(name, err));
  EXPECT_NE(err.find("layout version"), std::string::npos) << err;
  shm_unlink(name.c_str());

  {
    const int fd = shm_open(name.c_str(), O_CREAT | O_RDWR, 0600);
    ASSERT_EQ(ftruncate(fd, 4096), 0);
    close(fd);
  }
  err.clear();
  EXPECT_FALSE(Segment::attach(name, err));
  EXPECT_NE(err.find("size"), std::string::npos) << err;
  shm_unlink(name.c_str());
}

TEST(Segment, ASecondCreatorIsRefusedAndToldWhoHoldsIt) {
  const std::string name = unique_name("guard");
  std::string err;
  auto first = Segment::create(name, err);
  ASSERT_TRUE(first) << err;
  first->commands().push(CommandRecord{});
  auto second = Segment::create(name, err);
  EXPECT_FALSE(second);
  EXPECT_NE(err.find("process " + std::to_string(getpid())), std::string::npos) << err;
  EXPECT_EQ(first->commands().size(), 1U) << "the live segment was left alone";
  auto gw = Segment::attach(name, err);
  ASSERT_TRUE(gw) << err;
  EXPECT_EQ(gw->header().instance, first->header().instance);
  EXPECT_NE(first->header().instance, 0U);
}

TEST(Segment, AStaleSegmentIsReplaced) {
  const std::string name = unique_name("stale");
  {
    const int fd = shm_open(name.c_str(), O_CREAT | O_RDWR, 0600);  // left by a crash: nobody locks it
    ASSERT_GE(fd, 0);
    ASSERT_EQ(ftruncate(fd, static_cast<off_t>(layout().size)), 0);
    close(fd);
  }
  std::string err;
  auto s = Segment::create(name, err);
  EXPECT_TRUE(s) << err;
}

TEST(Segment, OwnerUnlinksOnDestruction) {
  const std::string name = unique_name("unlink");
  std::string err;
  { auto s = Segment::create(name, err); }
  EXPECT_FALSE(Segment::attach(name, err));
}

TEST(RuntimeBridge, CommandsFlowToTheCoreAndRepliesEchoTheSeq) {
  const std::string name = unique_name("flow");
  std::string err;
  auto seg = Segment::create(name, err);
  ASSERT_TRUE(seg);
  sim::Cell cell{core::Config{}};
  controller::OneChannel one(cell.controller());
  runtime::Publisher pub(*seg, one, &cell);
  for (int i = 0; i < 100; ++i) {
    cell.step();
    pub.publish();
  }
  CommandRecord rec{};
  rec.seq = 1234;
  rec.kind = RecordKind::command;
  rec.command.id = static_cast<std::uint8_t>(core::CommandId::reset);
  runtime::take_record(rec, one, &cell, pub, cell.now());
  cell.step();
  pub.publish();
  ReplyRecord r{};
  ASSERT_TRUE(seg->replies().pop(r));
  EXPECT_EQ(r.seq, 1234U);
  EXPECT_EQ(r.result, core::Result::OK);
  Status s{};
  ASSERT_TRUE(seg->status().read(s));
  EXPECT_EQ(s.state, core::State::IDLE);
  EXPECT_EQ(s.t, 100U);
  // Events: BOOT -> ESTOP_RESET_NEEDED, the command, ESTOP_RESET_NEEDED -> IDLE.
  int transitions = 0;
  int commands = 0;
  EventRecord e{};
  while (seg->events().pop(e)) {
    transitions += e.kind == EventKind::transition ? 1 : 0;
    commands += e.kind == EventKind::command ? 1 : 0;
  }
  EXPECT_EQ(transitions, 2);
  EXPECT_EQ(commands, 1);
  BlackBoxRecord b{};
  ASSERT_TRUE(seg->blackbox()[100 % kBlackBoxCycles].read(b));
  EXPECT_EQ(b.t, 100U);
  EXPECT_EQ(b.leaf, static_cast<std::uint8_t>(core::Leaf::IDLE));
}

TEST(RuntimeBridge, SimRecordsSetContactsAndInjectFaults) {
  const std::string name = unique_name("sim");
  std::string err;
  auto seg = Segment::create(name, err);
  ASSERT_TRUE(seg);
  sim::Cell cell{core::Config{}};
  controller::OneChannel one(cell.controller());
  runtime::Publisher pub(*seg, one, &cell);
  CommandRecord rec{};
  rec.seq = 5;
  rec.kind = RecordKind::sim_set;
  rec.set_mask = (1U << static_cast<unsigned>(Contact::estop_a)) | (1U << static_cast<unsigned>(Contact::mode_t1));
  rec.set_values = (1U << static_cast<unsigned>(Contact::mode_t1));  // estop.a=0, mode.t1=1
  runtime::take_record(rec, one, &cell, pub, 0);
  EXPECT_FALSE(cell.inputs().estop_a);
  EXPECT_TRUE(cell.inputs().mode_t1);
  EXPECT_TRUE(cell.inputs().estop_b) << "contacts outside the mask are untouched";
  ReplyRecord r{};
  ASSERT_TRUE(seg->replies().pop(r));
  EXPECT_EQ(r.seq, 5U);
  EXPECT_EQ(r.kind, RecordKind::sim_set);
  EXPECT_EQ(r.sim, SimResult::ok);

  rec.seq = 6;
  rec.kind = RecordKind::sim_fault;
  rec.fault_kind = static_cast<std::uint8_t>(sim::FaultKind::fieldbus_lost);
  runtime::take_record(rec, one, &cell, pub, 0);
  cell.step();
  EXPECT_FALSE(cell.view().fieldbus_ok);
}

// SPEC §10: the reduced input's two channels through a sim record (the HMI's sim panel),
// into the simulated cell, and as the line forwarded to an emulated EtherCAT segment.
TEST(RuntimeBridge, SimRecordsReachTheReducedInput) {
  const std::string name = unique_name("reduced");
  std::string err;
  auto seg = Segment::create(name, err);
  ASSERT_TRUE(seg);
  sim::Cell cell{core::Config{}};
  controller::OneChannel one(cell.controller());
  runtime::Publisher pub(*seg, one, &cell);
  ASSERT_TRUE(cell.inputs().reduced_a && cell.inputs().reduced_b) << "NC: 1 = normal speed at start";
  CommandRecord rec{};
  rec.seq = 7;
  rec.kind = RecordKind::sim_set;
  rec.set_mask = (1U << static_cast<unsigned>(Contact::reduced_a)) | (1U << static_cast<unsigned>(Contact::reduced_b));
  rec.set_values = (1U << static_cast<unsigned>(Contact::reduced_b));  // reduced.a=0, reduced.b=1
  runtime::take_record(rec, one, &cell, pub, 0);
  EXPECT_FALSE(cell.inputs().reduced_a);
  EXPECT_TRUE(cell.inputs().reduced_b);
  EXPECT_TRUE(cell.inputs().estop_a) << "contacts outside the mask are untouched";
  EXPECT_EQ(runtime::sim_line(rec), "in reduced.a=0 reduced.b=1");
  // Published: the black box records both channels, and the status the core's safety fields.
  cell.configure_limits(safety_limits_for_test(), true);
  for (int i = 0; i < 5; ++i) {
    cell.step();
    pub.publish();
  }
  BlackBoxRecord b{};
  ASSERT_TRUE(seg->blackbox()[4 % kBlackBoxCycles].read(b));
  EXPECT_EQ((b.contacts >> static_cast<unsigned>(Contact::reduced_a)) & 1U, 0U);
  EXPECT_EQ((b.contacts >> static_cast<unsigned>(Contact::reduced_b)) & 1U, 1U);
  Status st{};
  ASSERT_TRUE(seg->status().read(st));
  EXPECT_EQ(st.safety.checksum, 0x3AD9012BU);
  EXPECT_TRUE(st.safety.validated);
  EXPECT_TRUE(st.safety.reduced) << "either channel asks for reduced speed";
  EXPECT_EQ(st.safety.reduced_by, core::kReducedByInput);
  EXPECT_FLOAT_EQ(st.safety.speed_limit_mm_s, 1500.0F) << "the normal limit until the ramp is over";
}

// @req COL-FIELDS COL-SSM-INPUT
TEST(RuntimeBridge, SimRecordsReachTheFieldsAndTheSeparationAndStatusShowsSsm) {
  const std::string name = unique_name("collab");
  std::string err;
  auto seg = Segment::create(name, err);
  ASSERT_TRUE(seg);
  sim::Cell cell{core::Config{}};
  controller::OneChannel one(cell.controller());
  runtime::Publisher pub(*seg, one, &cell);
  cell.configure_limits(ssm_limits_for_test(), true);
  ASSERT_TRUE(cell.inputs().field_outer_a && cell.inputs().field_inner_b) << "NC: 1 = clear at start";
  ASSERT_FALSE(cell.inputs().separation_valid) << "no sensor reading yet: invalid";
  CommandRecord rec{};
  rec.seq = 8;
  rec.kind = RecordKind::sim_set;
  rec.set_mask = (1U << static_cast<unsigned>(Contact::field_inner_a)) | (1U << static_cast<unsigned>(Contact::field_inner_b));
  rec.separation_mm = 800;
  rec.separation_set = kSetSeparation;
  runtime::take_record(rec, one, &cell, pub, 0);
  EXPECT_FALSE(cell.inputs().field_inner_a);
  EXPECT_FALSE(cell.inputs().field_inner_b);
  EXPECT_TRUE(cell.inputs().field_outer_a) << "contacts outside the mask are untouched";
  EXPECT_EQ(cell.inputs().separation_mm, 800);
  EXPECT_TRUE(cell.inputs().separation_valid) << "a reading given is valid";
  EXPECT_EQ(runtime::sim_line(rec), "in field.inner.a=0 field.inner.b=0 separation_mm=800");
  for (int i = 0; i < 400; ++i) {  // the separation believed rises to 800 (3.5 mm a cycle)
    cell.step();
    pub.publish();
  }
  BlackBoxRecord b{};
  ASSERT_TRUE(seg->blackbox()[399 % kBlackBoxCycles].read(b));
  EXPECT_EQ((b.contacts >> static_cast<unsigned>(Contact::field_inner_b)) & 1U, 0U);
  EXPECT_EQ((b.contacts >> static_cast<unsigned>(Contact::field_outer_b)) & 1U, 1U);
  Status st{};
  ASSERT_TRUE(seg->status().read(st));
  EXPECT_TRUE(st.safety.field_inner_interrupted);
  EXPECT_FALSE(st.safety.field_outer_interrupted);
  EXPECT_TRUE(st.safety.ssm) << "collaborative and ssm on, mode AUTO";
  EXPECT_NEAR(st.safety.v_allowed_mm_s, 344.76F, 0.05F);
  EXPECT_FLOAT_EQ(st.safety.separation_mm, 800.0F);
  rec.set_mask = 0;
  rec.separation_set = kSetValid;  // separation_valid=0
  runtime::take_record(rec, one, &cell, pub, 400);
  EXPECT_FALSE(cell.inputs().separation_valid);
  EXPECT_EQ(runtime::sim_line(rec), "in separation_valid=0");
  cell.step();
  pub.publish();
  ASSERT_TRUE(seg->status().read(st));
  EXPECT_FLOAT_EQ(st.safety.v_allowed_mm_s, 0.0F) << "invalid is 0";
}

// @req COL-SIM-CONTACT
// The `sim` message's value faults (SPEC §11) travel in the record's fault_value and reach
// the emulator as the scenario's own words, in its units (N, % of rated torque).
TEST(RuntimeBridge, ValueFaultsKeepTheirValueOnTheWayToTheEmulator) {
  CommandRecord rec{};
  rec.kind = RecordKind::sim_fault;
  rec.fault_kind = static_cast<std::uint8_t>(sim::FaultKind::contact);
  rec.fault_value = 1505;  // tenths of a newton
  EXPECT_EQ(runtime::sim_line(rec), "fault contact 150.5");
  rec.fault_value = 0;
  EXPECT_EQ(runtime::sim_line(rec), "fault contact 0");
  rec.fault_kind = static_cast<std::uint8_t>(sim::FaultKind::drive_torque_bias);
  rec.fault_axis = 2;
  rec.fault_value = static_cast<std::uint16_t>(std::int16_t{-255});  // per mille
  EXPECT_EQ(runtime::sim_line(rec), "fault drive 2 torque_bias -25.5");
  rec.fault_value = 3000;
  EXPECT_EQ(runtime::sim_line(rec), "fault drive 2 torque_bias 300");
  rec.fault_value = static_cast<std::uint16_t>(std::int16_t{-5});
  EXPECT_EQ(runtime::sim_line(rec), "fault drive 2 torque_bias -0.5");
}

namespace {

CommandRecord person_record(std::uint32_t seq, std::uint8_t what) {
  CommandRecord rec{};
  rec.seq = seq;
  rec.kind = RecordKind::sim_person;
  rec.person.what = what;
  return rec;
}

SimResult answer(Segment& seg) {
  ReplyRecord r{};
  EXPECT_TRUE(seg.replies().pop(r)) << "every person record is answered at once";
  EXPECT_EQ(r.kind, RecordKind::sim_person);
  return r.sim;
}

}  // namespace

// @req COL-SIM-PERSON
// The `sim` message's person (issue 20 item 5) as a bridge record: all or nothing, a walk
// needs a person, the person walks in the cell, the simulated scanner and distance sensor
// follow it into what the core reads, the status shows it, and leaving gives the inputs
// set from outside back.
TEST(RuntimeBridge, PersonRecordsWalkThePersonAndTheFieldsAndTheSeparationFollow) {
  const std::string name = unique_name("person");
  std::string err;
  auto seg = Segment::create(name, err);
  ASSERT_TRUE(seg);
  sim::Cell cell{core::Config{}};
  controller::OneChannel one(cell.controller());
  runtime::Publisher pub(*seg, one, &cell);
  cell.configure_limits(ssm_limits_for_test(), true);
  // The HMI's manual distance sensor: with nobody placed, the person's devices write nothing.
  CommandRecord set{};
  set.kind = RecordKind::sim_set;
  set.separation_mm = 4321;
  set.separation_set = kSetSeparation;
  runtime::take_record(set, one, &cell, pub, 0);
  ReplyRecord r{};
  ASSERT_TRUE(seg->replies().pop(r));
  cell.step();
  pub.publish();
  EXPECT_EQ(cell.raw_inputs_of_last_cycle().separation_mm, 4321) << "no person: the manual reading stands";
  Status st{};
  ASSERT_TRUE(seg->status().read(st));
  EXPECT_TRUE(st.person_shown);
  EXPECT_FALSE(st.person_present);
  EXPECT_FLOAT_EQ(st.person_outer_mm, 2000.0F) << "the default fields";
  EXPECT_FLOAT_EQ(st.person_inner_mm, 1000.0F);

  // Walk, stand and leave need a person (as the scenario's keys); nothing changes.
  CommandRecord walk = person_record(20, kPersonWalk);
  walk.person.points = 1;
  walk.person.path[0] = PersonPoint{800.0F, 0.0F, 1600.0F, 0};
  for (const std::uint8_t what : {kPersonWalk, kPersonStand, kPersonLeave}) {
    walk.person.what = what;
    runtime::take_record(walk, one, &cell, pub, 1);
    EXPECT_EQ(answer(*seg), SimResult::person_absent) << int{what};
  }
  EXPECT_FALSE(cell.person().present());
  // A bad part refuses the whole record: the fields stay as they were, nobody is placed.
  CommandRecord in = person_record(21, kPersonFields | kPersonAt | kPersonWalk);
  in.person.fields_outer_mm = 1500.0F;
  in.person.fields_inner_mm = 700.0F;
  in.person.x_mm = 3000.0F;
  in.person.radius_mm = 250.0F;
  in.person.points = 1;
  in.person.path[0] = PersonPoint{800.0F, 0.0F, 2500.0F, 0};  // over 2000 mm/s
  runtime::take_record(in, one, &cell, pub, 1);
  EXPECT_EQ(answer(*seg), SimResult::person_invalid);
  EXPECT_FALSE(cell.person().present());
  EXPECT_FLOAT_EQ(cell.person_sensors().outer_mm, 2000.0F);
  for (const std::uint8_t what : {std::uint8_t{0}, std::uint8_t{kPersonStand | kPersonLeave},
                                  std::uint8_t{kPersonAt | kPersonStand}, std::uint8_t{0x80U}}) {
    CommandRecord odd = in;
    odd.person.what = what;
    odd.person.path[0].speed_mm_s = 1600.0F;
    runtime::take_record(odd, one, &cell, pub, 1);
    EXPECT_EQ(answer(*seg), SimResult::person_invalid) << int{what};
  }
  EXPECT_FALSE(cell.person().present());
  in.person.fields_inner_mm = 1600.0F;  // not inner < outer
  in.person.path[0].speed_mm_s = 1600.0F;
  runtime::take_record(in, one, &cell, pub, 1);
  EXPECT_EQ(answer(*seg), SimResult::person_invalid);
  EXPECT_FALSE(cell.person().present());

  // Fields 1500 / 700, in at 3 m on the x axis, walking to 0.8 m at 1.6 m/s.
  in.person.fields_inner_mm = 700.0F;
  runtime::take_record(in, one, &cell, pub, 1);
  EXPECT_EQ(answer(*seg), SimResult::ok);
  ASSERT_TRUE(cell.person().present());
  EXPECT_FLOAT_EQ(cell.person_sensors().outer_mm, 1500.0F);
  EXPECT_FLOAT_EQ(cell.person_sensors().inner_mm, 700.0F);
  auto run = [&](int cycles) {
    for (int i = 0; i < cycles; ++i) {
      cell.step();
      pub.publish();
    }
    EXPECT_TRUE(seg->status().read(st));
  };
  // 700 cycles: the centre at 3000 - 1120 = 1880 mm, its edge 1630 beyond the outer field.
  run(700);
  EXPECT_TRUE(st.person_present);
  EXPECT_TRUE(st.person_walking);
  EXPECT_FLOAT_EQ(st.person_speed_mm_s, 1600.0F);
  EXPECT_NEAR(st.person_x_mm, 1880.0F, 1.0F);
  EXPECT_FLOAT_EQ(st.person_outer_mm, 1500.0F);
  EXPECT_FALSE(st.person_in_outer);
  EXPECT_FALSE(st.safety.field_outer_interrupted);
  EXPECT_TRUE(cell.raw_inputs_of_last_cycle().field_outer_a);
  EXPECT_NE(cell.raw_inputs_of_last_cycle().separation_mm, 4321) << "the person's distance sensor now";
  EXPECT_EQ(cell.raw_inputs_of_last_cycle().separation_mm, static_cast<std::int32_t>(std::floor(st.person_separation_mm)));
  // 200 more: the centre at 1560, its edge 1310 inside the outer field, not the inner one.
  run(200);
  EXPECT_TRUE(st.person_in_outer);
  EXPECT_FALSE(st.person_in_inner);
  EXPECT_TRUE(st.safety.field_outer_interrupted) << "the core reads the scanner's channels";
  EXPECT_FALSE(st.safety.field_inner_interrupted);
  EXPECT_FALSE(cell.raw_inputs_of_last_cycle().field_outer_a);
  EXPECT_FALSE(cell.raw_inputs_of_last_cycle().field_outer_b);
  // At 0.8 m after 1.375 s: standing, in both fields.
  run(600);
  EXPECT_FALSE(st.person_walking);
  EXPECT_FLOAT_EQ(st.person_speed_mm_s, 0.0F);
  EXPECT_FLOAT_EQ(st.person_x_mm, 800.0F);
  EXPECT_TRUE(st.person_in_inner);
  EXPECT_TRUE(st.safety.field_inner_interrupted);
  EXPECT_LT(st.person_separation_mm, 550.0F) << "the arm is nearer than the base axis";
  // Stand while standing is fine; leave: the manual inputs again (fields clear, 4321 mm).
  runtime::take_record(person_record(22, kPersonStand), one, &cell, pub, 2);
  EXPECT_EQ(answer(*seg), SimResult::ok);
  runtime::take_record(person_record(23, kPersonLeave), one, &cell, pub, 2);
  EXPECT_EQ(answer(*seg), SimResult::ok);
  run(1);
  EXPECT_FALSE(st.person_present);
  EXPECT_EQ(cell.raw_inputs_of_last_cycle().separation_mm, 4321);
  EXPECT_TRUE(cell.raw_inputs_of_last_cycle().field_inner_a && cell.raw_inputs_of_last_cycle().field_inner_b);
}

// @req COL-SIM-PERSON
// On an emulated segment a person record is refused, not forwarded (ecat-sim's person moves by
// its control socket's `person` lines; the asynchronous forwarding could not answer a refusal).
TEST(RuntimeBridge, APersonRecordIsRefusedWhereTheWorldIsAnEmulatedSegment) {
  const std::string name = unique_name("person-bus");
  std::string err;
  auto seg = Segment::create(name, err);
  ASSERT_TRUE(seg);
  sim::Cell cell{core::Config{}};
  controller::OneChannel one(cell.controller());
  runtime::Publisher pub(*seg, one, nullptr, true);  // an emulated segment: no world here
  runtime::SimForward forward;
  CommandRecord rec = person_record(30, kPersonAt);
  rec.person.x_mm = 2000.0F;
  rec.person.radius_mm = 250.0F;
  runtime::take_record(rec, one, nullptr, pub, 0, &forward);
  EXPECT_EQ(answer(*seg), SimResult::person_not_on_bus);
  CommandRecord none{};
  EXPECT_FALSE(forward.pop(none)) << "not forwarded to the emulator";
  EXPECT_FALSE(cell.person().present());
  EXPECT_EQ(runtime::sim_line(rec), "");
  cell.step();
  pub.publish();
  Status st{};
  ASSERT_TRUE(seg->status().read(st));
  EXPECT_FALSE(st.person_shown) << "no person view where none can be placed";
}

TEST(Histogram, PowerOfTwoBuckets) {
  EXPECT_EQ(histogram_bucket(0), 0U);
  EXPECT_EQ(histogram_bucket(1), 0U);
  EXPECT_EQ(histogram_bucket(2), 1U);
  EXPECT_EQ(histogram_bucket(1023), 9U);
  EXPECT_EQ(histogram_bucket(1024), 10U);
  EXPECT_EQ(histogram_bucket(~0ULL), kHistogramBuckets - 1U);
}

// The simulated person (sim/person.hpp): path following, the speed limit, the scanner's
// fields and the distance sensor's separation against hand computations, the body radius,
// and how the cell feeds them to the controller (precedence over the inputs set from
// outside, the view).
#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "safestate/motion/kinematics.hpp"
#include "safestate/motion/robot.hpp"
#include "safestate/sim/cell.hpp"
#include "safestate/sim/person.hpp"
#include "safestate/sim/plant.hpp"

using namespace safestate;

namespace {

constexpr float kDt = 0.001F;

void steps(sim::Person& p, int n) {
  for (int i = 0; i < n; ++i) p.advance(kDt);
}

// A robot whose points are where the test says: every frame origin on the base axis at
// heights 0..600 mm, the TCP at `tcp`.
motion::Frames frames_with_tcp(float x, float y, float z) {
  motion::Frames f{};
  for (std::size_t k = 0; k < f.origin.size(); ++k) f.origin[k] = {0.0F, 0.0F, 100.0F * static_cast<float>(k)};
  f.tcp = {x, y, z};
  return f;
}

}  // namespace

// @req COL-SIM-PERSON
TEST(Person, FieldsAreCirclesAboutTheBaseAxisReachedByTheBodysEdge) {
  // (1200, 0), r 250: the edge is at 950 mm, inside the inner field (1000).
  EXPECT_TRUE(sim::in_field(1200.0F, 0.0F, 250.0F, 1000.0F));
  // (1250, 0): the edge touches the inner field's border: in (the safe side).
  EXPECT_TRUE(sim::in_field(1250.0F, 0.0F, 250.0F, 1000.0F));
  EXPECT_FALSE(sim::in_field(1251.0F, 0.0F, 250.0F, 1000.0F));
  // (1800, 1500): hypot = 2343.07, edge 2093.07: outside the outer field (2000) ...
  EXPECT_FALSE(sim::in_field(1800.0F, 1500.0F, 250.0F, 2000.0F));
  // ... with a 400 mm body the edge is at 1943.07: in.
  EXPECT_TRUE(sim::in_field(1800.0F, 1500.0F, 400.0F, 2000.0F));
  // The direction does not matter, only the distance to the axis.
  EXPECT_TRUE(sim::in_field(-1060.0F, -1060.0F, 250.0F, 1250.0F));   // 1499.07 - 250 = 1249.07
  EXPECT_FALSE(sim::in_field(-1061.0F, -1061.0F, 250.0F, 1250.0F));  // 1500.48 - 250 = 1250.48
}

// @req COL-SIM-PERSON
TEST(Person, SeparationIsTheHorizontalDistanceFromTheBodysEdgeToTheNearestPoint) {
  std::uint8_t nearest = 99;
  // TCP at (400, 300): the person at (1000, 300) is 600 mm from it, 1044.03 from the base
  // axis; less the radius 250: 350 mm, the TCP (point 7). The height does not count.
  const motion::Frames f = frames_with_tcp(400.0F, 300.0F, 900.0F);
  EXPECT_NEAR(sim::separation_to(1000.0F, 300.0F, 250.0F, f, nearest), 350.0F, 1e-3F);
  EXPECT_EQ(nearest, motion::kTcpPoint);
  // Behind the robot (-800, 0): the base axis (800) is nearer than the TCP (1244.99):
  // 550 mm, point 0 (the first of the equal origins on the axis).
  EXPECT_NEAR(sim::separation_to(-800.0F, 0.0F, 250.0F, f, nearest), 550.0F, 1e-3F);
  EXPECT_EQ(nearest, 0);
  // A frame origin off the axis is a point too: origin 4 at (300, -400).
  motion::Frames g = f;
  g.origin[4] = {300.0F, -400.0F, 500.0F};
  EXPECT_NEAR(sim::separation_to(300.0F, -1000.0F, 250.0F, g, nearest), 350.0F, 1e-3F);
  EXPECT_EQ(nearest, 4);
  // Overlapping bodies: 0, never negative.
  EXPECT_EQ(sim::separation_to(450.0F, 300.0F, 250.0F, f, nearest), 0.0F);
  // The radius is taken off exactly: a point-like person sees the full distance.
  EXPECT_NEAR(sim::separation_to(1000.0F, 300.0F, 1.0F, f, nearest), 599.0F, 1e-3F);
}

// @req COL-SIM-PERSON
TEST(Person, SenseWritesBothChannelsAndAWholeSeparationRoundedDown) {
  sim::Person p;
  ASSERT_TRUE(p.place(1000.7F, 300.0F));
  const motion::Frames f = frames_with_tcp(400.0F, 300.0F, 900.0F);
  core::RawInputs raw{};
  sim::PersonView v{};
  p.sense(sim::PersonSensors{}, f, raw, v);
  // 1044.72 from the axis, edge 794.72: in the outer field (2000) and in the inner (1000).
  EXPECT_FALSE(raw.field_outer_a);
  EXPECT_FALSE(raw.field_outer_b);
  EXPECT_FALSE(raw.field_inner_a);
  EXPECT_FALSE(raw.field_inner_b);
  EXPECT_TRUE(raw.separation_valid);
  EXPECT_EQ(raw.separation_mm, 350);  // 350.7 rounded down
  EXPECT_NEAR(v.separation_mm, 350.7F, 1e-2F);
  EXPECT_TRUE(v.present);
  EXPECT_NEAR(v.axis_distance_mm, std::hypot(1000.7F, 300.0F), 1e-2F);
  // Fields smaller than the person's distance: clear; devices switched off write nothing.
  core::RawInputs raw2{};
  raw2.separation_mm = 77;
  sim::PersonSensors small{};
  small.outer_mm = 700.0F;
  small.inner_mm = 500.0F;
  small.distance_sensor = false;
  p.sense(small, f, raw2, v);
  EXPECT_TRUE(raw2.field_outer_a && raw2.field_outer_b && raw2.field_inner_a && raw2.field_inner_b);
  EXPECT_EQ(raw2.separation_mm, 77);
  EXPECT_FALSE(raw2.separation_valid);
  EXPECT_NEAR(v.separation_mm, 350.7F, 1e-2F);  // what the sensor would see, shown anyway
  small.scanner = false;
  small.outer_mm = 5000.0F;
  core::RawInputs raw3{};
  p.sense(small, f, raw3, v);
  EXPECT_TRUE(raw3.field_outer_a && raw3.field_inner_a);
  EXPECT_TRUE(v.outer_interrupted);
}

// @req COL-SIM-PERSON
TEST(Person, FollowsItsPathAtEachPointsSpeedAndStands) {
  sim::Person p;
  ASSERT_TRUE(p.place(0.0F, 2000.0F));
  const std::array<sim::PersonWaypoint, 2> path{{{0.0F, 1000.0F, 1000.0F, 500}, {1000.0F, 1000.0F, 2000.0F, 0}}};
  ASSERT_TRUE(p.walk(path.data(), path.size()));
  steps(p, 500);  // 0.5 s at 1000 mm/s: 500 mm
  EXPECT_NEAR(p.x_mm(), 0.0F, 1e-3F);
  EXPECT_NEAR(p.y_mm(), 1500.0F, 1e-3F);
  EXPECT_FLOAT_EQ(p.speed_mm_s(), 1000.0F);
  EXPECT_TRUE(p.walking());
  steps(p, 500);  // on the first point after 1 s exactly
  EXPECT_NEAR(p.y_mm(), 1000.0F, 1e-3F);
  EXPECT_EQ(p.waypoint(), 1);
  steps(p, 499);  // standing 500 ms
  EXPECT_FLOAT_EQ(p.speed_mm_s(), 0.0F);
  EXPECT_FALSE(p.walking());
  EXPECT_NEAR(p.x_mm(), 0.0F, 1e-3F);
  steps(p, 1);  // the stand ends and it walks on in the same cycle: 2 mm
  EXPECT_NEAR(p.x_mm(), 2.0F, 1e-3F);
  EXPECT_FLOAT_EQ(p.speed_mm_s(), 2000.0F);
  steps(p, 499);  // 1000 mm at 2000 mm/s: there after 500 cycles
  EXPECT_NEAR(p.x_mm(), 1000.0F, 1e-3F);
  EXPECT_NEAR(p.y_mm(), 1000.0F, 1e-3F);
  EXPECT_EQ(p.waypoint(), 2);
  EXPECT_TRUE(p.walking()) << "it moved in the cycle it arrived: still walking, at that cycle's speed";
  EXPECT_GT(p.speed_mm_s(), 0.0F);
  steps(p, 1);
  EXPECT_FALSE(p.walking());
  EXPECT_FLOAT_EQ(p.speed_mm_s(), 0.0F) << "not walking is standing still";
  steps(p, 1000);  // the walk is over: it stays
  EXPECT_FLOAT_EQ(p.x_mm(), 1000.0F);
  EXPECT_FLOAT_EQ(p.speed_mm_s(), 0.0F);
  EXPECT_FALSE(p.walking());
  // A diagonal: the speed is along the path, not per axis (3-4-5: 500 mm in 0.25 s).
  ASSERT_TRUE(p.place(0.0F, 0.0F));
  const sim::PersonWaypoint d{300.0F, 400.0F, 2000.0F, 0};
  ASSERT_TRUE(p.walk(&d, 1));
  steps(p, 125);
  EXPECT_NEAR(p.x_mm(), 150.0F, 1e-3F);
  EXPECT_NEAR(p.y_mm(), 200.0F, 1e-3F);
  steps(p, 125);
  EXPECT_NEAR(p.x_mm(), 300.0F, 1e-3F);
  EXPECT_EQ(p.waypoint(), 1);
  // `stand` stops it where it is; `place` moves it at once and drops the path.
  ASSERT_TRUE(p.walk(path.data(), path.size()));
  steps(p, 10);
  p.stand();
  const float x = p.x_mm();
  steps(p, 100);
  EXPECT_FLOAT_EQ(p.x_mm(), x);
  EXPECT_EQ(p.waypoints(), 0);
}

// @req COL-SIM-PERSON
TEST(Person, RefusesWhatNoPersonDoes) {
  sim::Person p;
  const sim::PersonWaypoint ok{1000.0F, 0.0F, 2000.0F, 0};
  EXPECT_FALSE(p.walk(&ok, 1)) << "no person in the cell";
  EXPECT_FALSE(p.place(20001.0F, 0.0F));
  EXPECT_FALSE(p.place(0.0F, NAN));
  EXPECT_FALSE(p.place(0.0F, 0.0F, 0.0F)) << "radius 0";
  EXPECT_FALSE(p.place(0.0F, 0.0F, 1001.0F));
  EXPECT_FALSE(p.present());
  ASSERT_TRUE(p.place(3000.0F, 0.0F));
  EXPECT_TRUE(p.walk(&ok, 1)) << "2000 mm/s is the limit, allowed";
  for (const float v : {2000.5F, 2500.0F, 0.0F, -100.0F, NAN, INFINITY}) {
    const sim::PersonWaypoint bad{1000.0F, 0.0F, v, 0};
    ASSERT_TRUE(p.place(3000.0F, 0.0F));
    EXPECT_FALSE(p.walk(&bad, 1)) << v;
    p.advance(kDt);
    EXPECT_FLOAT_EQ(p.x_mm(), 3000.0F) << "a refused walk changes nothing";
  }
  // A bad point anywhere refuses the whole path.
  const std::array<sim::PersonWaypoint, 2> second_bad{{ok, {0.0F, 0.0F, 2001.0F, 0}}};
  EXPECT_FALSE(p.walk(second_bad.data(), 2));
  const sim::PersonWaypoint far{0.0F, -25000.0F, 1000.0F, 0};
  EXPECT_FALSE(p.walk(&far, 1));
  const sim::PersonWaypoint long_stand{0.0F, 0.0F, 1000.0F, sim::kPersonMaxStandMs + 1U};
  EXPECT_FALSE(p.walk(&long_stand, 1));
  std::array<sim::PersonWaypoint, sim::kPersonMaxWaypoints + 1> many{};
  many.fill(ok);
  EXPECT_FALSE(p.walk(many.data(), many.size()));
  EXPECT_TRUE(p.walk(many.data(), sim::kPersonMaxWaypoints));
  EXPECT_FALSE(p.walk(many.data(), 0));
  // Its measured speed never exceeds the limit, arrivals included.
  ASSERT_TRUE(p.place(0.0F, 0.0F));
  const std::array<sim::PersonWaypoint, 3> zig{{{1.5F, 0.0F, 2000.0F, 0}, {1000.0F, 7.0F, 2000.0F, 3}, {0.0F, 0.0F, 2000.0F, 0}}};
  ASSERT_TRUE(p.walk(zig.data(), zig.size()));
  float px = p.x_mm();
  float py = p.y_mm();
  for (int i = 0; i < 2000; ++i) {
    p.advance(kDt);
    const float moved = std::hypot(p.x_mm() - px, p.y_mm() - py) / kDt;
    EXPECT_LE(moved, 2000.0F * 1.0001F) << i;
    EXPECT_LE(p.speed_mm_s(), 2000.0F);
    px = p.x_mm();
    py = p.y_mm();
  }
  p.leave();
  EXPECT_FALSE(p.present());
  EXPECT_FALSE(p.walk(&ok, 1));
  sim::PersonSensors s{};
  EXPECT_TRUE(sim::valid(s));
  s.inner_mm = s.outer_mm;
  EXPECT_FALSE(sim::valid(s));
  s.inner_mm = 0.0F;
  EXPECT_FALSE(sim::valid(s));
  s = sim::PersonSensors{};
  s.outer_mm = 20001.0F;
  EXPECT_FALSE(sim::valid(s));
}

// @req COL-SIM-PERSON
TEST(Person, TheCellFeedsThePersonOverTheInputsSetFromOutsideAndShowsIt) {
  sim::Cell cell{core::Config{}};
  cell.inputs().separation_mm = 4321;
  cell.inputs().separation_valid = true;
  cell.step();
  EXPECT_FALSE(cell.view().person.present);
  EXPECT_EQ(cell.raw_inputs_of_last_cycle().separation_mm, 4321);
  // In the inner field at (0, -900): the scanner opens all four channels, the sensor
  // measures from the arm at its home pose (the motion layer's frames, measured joints).
  ASSERT_TRUE(cell.add_person(0.0F, -900.0F));
  cell.step();
  const core::RawInputs& r = cell.raw_inputs_of_last_cycle();
  EXPECT_FALSE(r.field_outer_a || r.field_outer_b || r.field_inner_a || r.field_inner_b);
  EXPECT_TRUE(r.separation_valid);
  motion::Frames f{};
  motion::forward(motion::kRobot, sim::home_pose(), f);
  std::uint8_t nearest = 0;
  const float expected = sim::separation_to(0.0F, -900.0F, sim::kPersonDefaultRadiusMm, f, nearest);
  EXPECT_EQ(r.separation_mm, static_cast<std::int32_t>(std::floor(expected)));
  // At home every point is above the floor's origin's x axis (y = 0): 900 - 250 = 650 mm.
  EXPECT_NEAR(expected, 650.0F, 1.0F);
  const sim::PersonView& v = cell.view().person;
  EXPECT_TRUE(v.present && v.outer_interrupted && v.inner_interrupted);
  EXPECT_FLOAT_EQ(v.y_mm, -900.0F);
  EXPECT_FLOAT_EQ(v.sensors.outer_mm, 2000.0F);
  // The values set from outside are kept and apply again once the person has left.
  EXPECT_EQ(cell.inputs().separation_mm, 4321);
  EXPECT_TRUE(cell.inputs().field_inner_a);
  // Walking out: after 1 s at 1600 mm/s it is 2500 mm from the axis, outside both fields.
  const sim::PersonWaypoint out{0.0F, -2500.0F, 1600.0F, 0};
  ASSERT_TRUE(cell.set_person_path(&out, 1));
  for (int i = 0; i < 1000; ++i) cell.step();
  EXPECT_NEAR(cell.view().person.y_mm, -2500.0F, 1e-2F);
  EXPECT_FALSE(cell.view().person.inner_interrupted);
  EXPECT_TRUE(cell.raw_inputs_of_last_cycle().field_inner_a && cell.raw_inputs_of_last_cycle().field_outer_b);
  cell.remove_person();
  cell.step();
  EXPECT_FALSE(cell.view().person.present);
  EXPECT_EQ(cell.raw_inputs_of_last_cycle().separation_mm, 4321);
  // Radii the cell refuses leave the old ones.
  sim::PersonSensors bad{};
  bad.inner_mm = 3000.0F;
  EXPECT_FALSE(cell.configure_person_sensors(bad));
  sim::PersonSensors good{};
  good.outer_mm = 1500.0F;
  good.inner_mm = 600.0F;
  EXPECT_TRUE(cell.configure_person_sensors(good));
  ASSERT_TRUE(cell.add_person(0.0F, -1000.0F));
  cell.step();
  EXPECT_TRUE(cell.view().person.outer_interrupted);
  EXPECT_FALSE(cell.view().person.inner_interrupted);
  EXPECT_FLOAT_EQ(cell.view().person.sensors.inner_mm, 600.0F);
}

// sim::ArmDynamics in the real-time loop (the plant calls it every 1 ms cycle): after the
// constructor, set_payload() and the first call, torques() and tcp() make no heap allocation.
// Its own binary, as test_no_alloc: it replaces operator new/delete and malloc & co. and
// counts every call made while `armed` (not built on a sanitizer build, which owns malloc).
#include <gtest/gtest.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <new>
#include <vector>

#include "safestate/sim/dynamics.hpp"

#include "alloc_counter.hpp"

using safestate::sim::ArmDynamics;
using safestate::sim::JointVec;
using safestate::sim::Vec3;

TEST(SimDynamicsNoAlloc, TorquesAndTcpAllocateNothingAfterTheFirstCall) {
  // Start-up: construction, the payload, one call of each.
  ArmDynamics dyn;
  dyn.set_payload(2.0, Vec3{0.01, 0.0, 0.08});
  JointVec q{0.1, -0.2, 0.3, -0.4, 0.5, -0.6};
  JointVec qd{0.5, 0.4, 0.3, 0.2, 0.1, 0.0};
  JointVec qdd{1.0, -2.0, 3.0, -4.0, 5.0, -6.0};
  Vec3 f{10.0, -20.0, 30.0};
  const Vec3 tcp{0.0, 0.02, 0.1};
  JointVec tau{};
  Vec3 p{};
  ASSERT_TRUE(dyn.torques(q, qd, qdd, f, tcp, tau));
  dyn.tcp(q, tcp, p);

  long ok = 0;
  double sum = 0.0;
  allocations = 0;
  armed = true;
  for (int k = 0; k < 20000; ++k) {  // 20 s of 1 ms cycles, every input changing
    const double s = 1e-4 * static_cast<double>(k);
    for (std::size_t i = 0; i < q.size(); ++i) {
      q[i] += s;
      qd[i] = -qd[i];
      qdd[i] += 0.5;
    }
    f[0] = -f[0];
    ok += dyn.torques(q, qd, qdd, f, tcp, tau) ? 1 : 0;
    dyn.tcp(q, tcp, p);
    sum += tau[1] + p[2];
  }
  armed = false;
  EXPECT_EQ(allocations.load(), 0) << "torques()/tcp() allocated";
  EXPECT_EQ(ok, 20000);
  EXPECT_TRUE(std::isfinite(sum));
}

TEST(SimDynamicsNoAlloc, TheCounterWorks) {
  allocations = 0;
  armed = true;
  std::vector<double> v(16);  // what a JntArray or Wrenches sized per call would do
  void* m = std::malloc(16);
  armed = false;
  std::free(m);
  EXPECT_GE(allocations.load(), 2);
  EXPECT_EQ(v.size(), 16U);
  allocations = 0;
}

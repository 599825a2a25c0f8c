// Admission and authentication decisions of the gateway (protocol.md "Access and
// admission"), without sockets: tokens, Host, Origin, bearer, start-up refusal, and the
// bounds on slow and idle connections (issue 40): who gives way, how many fit.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "safestate/gateway/admission.hpp"

using namespace safestate::gateway;

namespace {
GatewayOptions options(const std::string& bind, const std::string& pendant = "", const std::string& remote = "") {
  GatewayOptions o;
  o.bind = bind;
  o.port = 8080;
  o.pendant_token = pendant;
  o.remote_token = remote;
  return o;
}
}  // namespace

TEST(Admission, SameTokenOnlyForTheExactSecret) {
  EXPECT_TRUE(same_token("s3cret", "s3cret"));
  EXPECT_FALSE(same_token("s3cre", "s3cret"));
  EXPECT_FALSE(same_token("s3crett", "s3cret"));
  EXPECT_FALSE(same_token("s3cret\n", "s3cret"));
  EXPECT_FALSE(same_token("S3cret", "s3cret"));
  EXPECT_FALSE(same_token("", "s3cret"));
  EXPECT_FALSE(same_token("s3crets3cret", "s3cret"));  // a repetition of the secret
  EXPECT_FALSE(same_token("", ""));                    // no secret: nothing matches
  EXPECT_FALSE(same_token("x", ""));
}

TEST(Admission, HelloCredentialsPerRole) {
  const Access loop(options("127.0.0.1", "p", "r"), true);
  EXPECT_EQ(loop.hello_refusal(Role::pendant, true, "p"), "");
  EXPECT_NE(loop.hello_refusal(Role::pendant, true, "r"), "");
  EXPECT_NE(loop.hello_refusal(Role::pendant, false, ""), "");
  EXPECT_EQ(loop.hello_refusal(Role::remote, true, "r"), "");
  EXPECT_NE(loop.hello_refusal(Role::remote, true, "p"), "");
  EXPECT_EQ(loop.hello_refusal(Role::observer, false, ""), "");

  const Access open(options("127.0.0.1"), true);  // no tokens, loopback: as before
  EXPECT_EQ(open.hello_refusal(Role::pendant, false, ""), "");
  EXPECT_EQ(open.hello_refusal(Role::remote, false, ""), "");

  const Access wide(options("0.0.0.0", "p", "r"), false);
  EXPECT_NE(wide.hello_refusal(Role::observer, false, ""), "");
  EXPECT_EQ(wide.hello_refusal(Role::observer, true, "r"), "");
  EXPECT_EQ(wide.hello_refusal(Role::observer, true, "p"), "");
}

TEST(Admission, BeyondLoopbackNeedsBothTokens) {
  EXPECT_EQ(startup_refusal(options("127.0.0.1"), true), "");
  EXPECT_NE(startup_refusal(options("0.0.0.0"), false), "");
  EXPECT_NE(startup_refusal(options("0.0.0.0", "p"), false), "");
  EXPECT_NE(startup_refusal(options("0.0.0.0", "", "r"), false), "");
  EXPECT_EQ(startup_refusal(options("0.0.0.0", "p", "r"), false), "");
  bool loopback = false;
  std::string error;
  ASSERT_TRUE(bind_is_loopback("127.0.0.1", loopback, error));
  EXPECT_TRUE(loopback);
  ASSERT_TRUE(bind_is_loopback("::1", loopback, error));
  EXPECT_TRUE(loopback);
  ASSERT_TRUE(bind_is_loopback("0.0.0.0", loopback, error));
  EXPECT_FALSE(loopback);
  ASSERT_TRUE(bind_is_loopback("::ffff:127.0.0.1", loopback, error));
  EXPECT_TRUE(loopback);
}

TEST(Admission, HostMustBeOurs) {
  GatewayOptions o = options("127.0.0.1");
  o.allow_hosts = {"Cell7.plant.example"};
  const Access a(o, true);
  EXPECT_TRUE(a.host_ok("127.0.0.1:8080", true));
  EXPECT_TRUE(a.host_ok("localhost:8080", true));
  EXPECT_TRUE(a.host_ok("LOCALHOST", true));
  EXPECT_TRUE(a.host_ok("[::1]:8080", true));
  EXPECT_TRUE(a.host_ok("cell7.plant.example:8080", true));
  EXPECT_FALSE(a.host_ok("rebind.attacker.example:8080", true));
  EXPECT_FALSE(a.host_ok("10.0.0.5:8080", true));
  EXPECT_FALSE(a.host_ok("", true));
  EXPECT_FALSE(a.host_ok("127.0.0.1", false));
  const Access wide(options("0.0.0.0", "p", "r"), false);
  EXPECT_TRUE(wide.host_ok("10.0.0.5:8080", true));  // an IP literal: no rebinding
  EXPECT_FALSE(wide.host_ok("rebind.attacker.example", true));
}

TEST(Admission, OriginMustBeOursOrListed) {
  GatewayOptions o = options("127.0.0.1");
  o.allow_origins = {"https://hmi.plant.example/"};
  const Access a(o, true);
  EXPECT_TRUE(a.origin_ok("", false));
  EXPECT_TRUE(a.origin_ok("http://127.0.0.1:8080", true));
  EXPECT_TRUE(a.origin_ok("http://localhost:8080", true));
  EXPECT_TRUE(a.origin_ok("https://hmi.plant.example", true));
  EXPECT_FALSE(a.origin_ok("http://127.0.0.1:8081", true));
  EXPECT_FALSE(a.origin_ok("http://127.0.0.1", true));
  EXPECT_FALSE(a.origin_ok("https://127.0.0.1:8080", true));
  EXPECT_FALSE(a.origin_ok("http://evil.example:8080", true));
  EXPECT_FALSE(a.origin_ok("null", true));
}

TEST(Admission, BearerOnlyBeyondLoopbackAndOnlyForData) {
  const Access loop(options("127.0.0.1", "p", "r"), true);
  EXPECT_FALSE(loop.needs_bearer("/api/status"));
  const Access wide(options("0.0.0.0", "p", "r"), false);
  EXPECT_TRUE(wide.needs_bearer("/api/status"));
  EXPECT_TRUE(wide.needs_bearer("/api/events/3/blackbox"));
  EXPECT_TRUE(wide.needs_bearer("/metrics"));
  EXPECT_FALSE(wide.needs_bearer("/"));
  EXPECT_FALSE(wide.needs_bearer("/apiary.css"));
  EXPECT_TRUE(wide.bearer_ok("Bearer p"));
  EXPECT_TRUE(wide.bearer_ok("bearer r"));
  EXPECT_FALSE(wide.bearer_ok("Bearer x"));
  EXPECT_FALSE(wide.bearer_ok("Basic p"));
  EXPECT_FALSE(wide.bearer_ok("Bearer "));
  EXPECT_FALSE(wide.bearer_ok(""));
}

TEST(Admission, TokenFromFileWinsAndIsStripped) {
  const std::string path = ::testing::TempDir() + "safestate_token_test";
  {
    std::ofstream f(path);
    f << "from-file\r\n";
  }
  ::setenv("SAFESTATE_TEST_TOKEN", "from-env", 1);
  std::string out;
  std::string error;
  ASSERT_TRUE(load_token("SAFESTATE_TEST_TOKEN", path, out, error));
  EXPECT_EQ(out, "from-file");
  ASSERT_TRUE(load_token("SAFESTATE_TEST_TOKEN", "", out, error));
  EXPECT_EQ(out, "from-env");
  EXPECT_FALSE(load_token("SAFESTATE_TEST_TOKEN", path + ".missing", out, error));
  EXPECT_NE(error.find("cannot read"), std::string::npos);
  {
    std::ofstream f(path);
    f << "\n";
  }
  EXPECT_FALSE(load_token("SAFESTATE_TEST_TOKEN", path, out, error));
  ::unsetenv("SAFESTATE_TEST_TOKEN");
  std::remove(path.c_str());
}

// ------------------------------------------------------------------ connections (issue 40)
TEST(Connections, BoundsFollowTheDescriptorLimit) {
  ConnectionLimits l;
  std::string error;
  // A soft and hard limit of 1024 with the default caps (64 WebSocket clients, 32 HTTP):
  // 64 for the gateway itself, 2 x 64 + 32 + 64 for the WebSocket slots, the service
  // slots and the 503s in flight, the rest waits for a request head.
  ASSERT_TRUE(connection_limits(1024, 64, 32, l, error)) << error;
  EXPECT_EQ(l.fd_limit, 1024U);
  EXPECT_EQ(l.waiting_max, 1024U - 64U - 224U);
  EXPECT_EQ(l.open_max, 1024U - 64U);
  EXPECT_EQ(l.waiting_per_peer, kWaitingPerPeer);
  EXPECT_LT(l.waiting_per_peer, l.waiting_max);
  // Plenty of descriptors: waiting connections stay bounded all the same.
  ASSERT_TRUE(connection_limits(1U << 20U, 64, 32, l, error)) << error;
  EXPECT_EQ(l.waiting_max, kWaitingMax);
  EXPECT_EQ(l.open_max, kWaitingMax + 224U);
  EXPECT_EQ(l.waiting_per_peer, kWaitingPerPeer);
  // Just enough, and one short: a clear refusal naming the limit, the bounds untouched.
  ASSERT_TRUE(connection_limits(64 + 224 + kMinWaiting, 64, 32, l, error)) << error;
  EXPECT_EQ(l.waiting_max, kMinWaiting);
  EXPECT_EQ(l.waiting_per_peer, kMinWaiting);
  EXPECT_FALSE(connection_limits(64 + 224 + kMinWaiting - 1, 64, 32, l, error));
  EXPECT_NE(error.find("RLIMIT_NOFILE 303"), std::string::npos) << error;
  EXPECT_EQ(l.open_max, 0U);
}

namespace {
using Tp = std::chrono::steady_clock::time_point;
WaitingConnection waiting(const std::string& peer, int since_ms, bool answered, bool silent) {
  return WaitingConnection{peer, Tp(std::chrono::milliseconds(since_ms)), answered, silent};
}
}  // namespace

TEST(Connections, TheOldestSilentNewcomerGivesWayNeverOneWhoseRequestArrives) {
  const Tp now(std::chrono::milliseconds(10'000));
  const auto grace = std::chrono::seconds(1);
  std::vector<WaitingConnection> c{
      waiting("A", 100, false, false),  // the oldest, but its request is arriving
      waiting("A", 300, false, true),
      waiting("A", 200, false, true),   // the oldest silent one
      waiting("B", 50, true, true),     // kept alive, silent for 9.95 s: after every newcomer
  };
  EXPECT_EQ(pick_shed(c, "", now, grace), 2U);
  EXPECT_EQ(pick_shed(c, "A", now, grace), 2U);
  EXPECT_EQ(pick_shed(c, "B", now, grace), 3U);  // of B: its kept-alive one
  EXPECT_EQ(pick_shed(c, "C", now, grace), c.size());
  c[1].silent = false;
  c[2].silent = false;
  EXPECT_EQ(pick_shed(c, "", now, grace), 3U);
  EXPECT_EQ(pick_shed(c, "A", now, grace), c.size());  // a burst: nobody gives way
}

TEST(Connections, AKeptAliveConnectionGivesWayOnlyAfterItsGrace) {
  const Tp now(std::chrono::milliseconds(10'000));
  const auto grace = std::chrono::seconds(1);
  std::vector<WaitingConnection> c{
      waiting("A", 9'500, true, true),  // answered half a second ago
      waiting("A", 8'000, true, true),  // two seconds ago: may give way
      waiting("A", 7'000, true, false),
  };
  EXPECT_EQ(pick_shed(c, "", now, grace), 1U);
  c[1].since = Tp(std::chrono::milliseconds(9'001));
  EXPECT_EQ(pick_shed(c, "", now, grace), c.size());
  c.push_back(waiting("A", 9'999, false, true));  // a newcomer that never spoke: before them all
  EXPECT_EQ(pick_shed(c, "", now, grace), 3U);
  EXPECT_EQ(pick_shed({}, "", now, grace), 0U);
}

// The gateway: the non-real-time process between clients (HMI, PLC, MES) and the core
// (../shared/spec/protocol.md). It attaches to the core's shared-memory bridge, speaks
// HTTP + WebSocket JSON to clients, keeps the event log in SQLite and serves metrics.
// The core never parses network input and never waits for the gateway: if the gateway
// hangs or dies the core keeps cycling and stays safe, and the runtime restarts it.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace safestate::gateway {

struct GatewayOptions {
  std::string shm_name;            // the bridge segment, e.g. "/safestate-8080"
  std::string bind = "127.0.0.1";  // listen address; beyond loopback both tokens are required
  unsigned port = 8080;
  std::string db_path;        // SQLite event log (created when missing)
  std::string pendant_token;  // from SAFESTATE_PENDANT_TOKEN or a file, never argv
  std::string remote_token;   // from SAFESTATE_REMOTE_TOKEN or a file, never argv
  std::vector<std::string> allow_origins;  // besides the server's own, e.g. "https://hmi.plant"
  std::vector<std::string> allow_hosts;    // Host names besides the bound address and localhost
  std::size_t max_clients = 64;            // WebSocket clients, one slot kept for the pendant
  std::size_t max_http = 32;               // HTTP connections at once
  std::string static_dir;  // the built HMI; a small built-in page when it has no index.html
  std::string version;     // shown as "safestate <version>" in `welcome`
};

// Runs until SIGTERM/SIGINT (exit 0, after logging what the core said last), or until
// the core's process has died (exit 1). A core that is shutting down is still served:
// `safestate run` sends SIGTERM once its final Cat 1 stop is over. Exits 1 at once,
// with a message on stderr, when the segment cannot be attached within a few seconds,
// the event log cannot be opened or the port cannot be bound.
int gateway_main(const GatewayOptions& options);

}  // namespace safestate::gateway

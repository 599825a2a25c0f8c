// SafeState's OPC 40010-1 (Robotics) server: a separate non-real-time process and a plain
// `remote` client of the gateway (shared/spec/protocol.md). It has no other path to the
// core; if it hangs or dies the core and the gateway do not notice.
import * as fs from "fs";
import * as path from "path";
import { AccessLevelFlag, BaseNode, MessageSecurityMode, NodeClass, UAObject, UAVariable, OPCUACertificateManager, OPCUAServer, SecurityPolicy, StatusCodes, WellKnownRoles, makeRoles, nodesets } from "node-opcua";
import { refuseWrites, withoutX509Users } from "./access";
import { Alarms } from "./alarms";
import { Config, ConfigError, isLoopback, parseArgs } from "./config";
import { GatewayClient } from "./gateway_client";
import { answerDeliveredClauses } from "./events";
import { addMethods, requireAuthenticatedCalls } from "./methods";
import { Model } from "./model";
import { nodeMap } from "./nodemap";
import { Users, hashLine } from "./users";

const EXIT_CONFIG = 2;
const EXIT_PORT_BUSY = 3;
const EXIT_FAILED = 1;

function log(msg: string): void {
  process.stderr.write(`safestate-opcua: ${msg}\n`);
}

function packageVersion(): string {
  try {
    const pkg = JSON.parse(fs.readFileSync(path.join(__dirname, "..", "package.json"), "utf8")) as { version: string };
    return pkg.version;
  } catch {
    return "0";
  }
}

async function hashPassword(): Promise<void> {
  const chunks: Buffer[] = [];
  for await (const c of process.stdin) {
    chunks.push(c as Buffer);
  }
  const [name, ...rest] = Buffer.concat(chunks).toString("utf8").replace(/\r?\n$/, "").split(":");
  if (name === "" || rest.length === 0) {
    throw new ConfigError("--hash-password: give NAME:PASSWORD on stdin");
  }
  process.stdout.write(hashLine(name, rest.join(":")) + "\n");
}

function makeServer(cfg: Config, users: Users | null): OPCUAServer {
  const loopback = isLoopback(cfg.bind);
  const certificateManager = new OPCUACertificateManager({
    rootFolder: cfg.pkiDir,
    // Beyond loopback a client's certificate must be trusted by an administrator first
    // (moved from pki/rejected to pki/trusted); on loopback it is the same machine.
    automaticallyAcceptUnknownCertificate: loopback,
  });
  return new OPCUAServer({
    host: cfg.bind,
    port: cfg.port,
    hostname: cfg.bind === "0.0.0.0" ? undefined : cfg.bind,
    nodeset_filename: [nodesets.standard, nodesets.di, nodesets.ia, nodesets.robotics],
    serverCertificateManager: certificateManager,
    // X509 user tokens are not offered (access.ts); should one arrive all the same, no user
    // certificate is trusted: this store has no trusted certificates and accepts none.
    userCertificateManager: new OPCUACertificateManager({
      rootFolder: path.join(cfg.pkiDir, "users"),
      automaticallyAcceptUnknownCertificate: false,
    }),
    // OPC 10000-2 §6: Basic256Sha256 with Sign&Encrypt; None only on loopback, for reading.
    securityPolicies: loopback ? [SecurityPolicy.None, SecurityPolicy.Basic256Sha256] : [SecurityPolicy.Basic256Sha256],
    securityModes: loopback ? [MessageSecurityMode.None, MessageSecurityMode.SignAndEncrypt] : [MessageSecurityMode.SignAndEncrypt],
    allowAnonymous: loopback,
    userManager: {
      isValidUser: (name: string, password: string) => users !== null && users.check(name, password),
      getUserRoles: () => makeRoles([WellKnownRoles.AuthenticatedUser, WellKnownRoles.Operator]),
    },
    buildInfo: { productName: "SafeState OPC UA", manufacturerName: "SafeState", softwareVersion: cfg.version },
    serverInfo: { applicationUri: "urn:safestate:opcua", productUri: "urn:safestate" },
    maxConnectionsPerEndpoint: 20,
  });
}

// Writes to any of our values are refused (BadNotWritable): the adapter only reports. The
// whole MotionDeviceSystem tree is swept, its SafeState variables and alarm conditions too.
function readOnly(node: BaseNode, seen = new Set<string>()): void {
  const key = node.nodeId.toString();
  if (seen.has(key)) {
    return;
  }
  seen.add(key);
  if (node.nodeClass === NodeClass.Variable) {
    const v = node as UAVariable;
    v.accessLevel = AccessLevelFlag.CurrentRead;
    v.userAccessLevel = AccessLevelFlag.CurrentRead;
  }
  for (const child of (node as UAObject).getAggregates?.() ?? []) {
    readOnly(child, seen);
  }
}

// The generated node list (docs/opcua-nodes.md): the address space is built, nothing listens.
async function writeNodeMap(file: string): Promise<void> {
  const server = new OPCUAServer({ nodeset_filename: [nodesets.standard, nodesets.di, nodesets.ia, nodesets.robotics] });
  await server.initialize();
  const as = server.engine.addressSpace!;
  as.installAlarmsAndConditionsService();
  const model = new Model(as, 1000, "VERSION");
  new Alarms(model);
  addMethods(model, new GatewayClient("ws://127.0.0.1:1/ws", "http://127.0.0.1:1", "", "0"));
  // A file, not stdout: node-opcua prints its own notices on stdout.
  fs.writeFileSync(file, nodeMap(as, model.mds));
  process.exit(0);
}

async function serve(cfg: Config): Promise<void> {
  const users = cfg.usersFile !== null ? Users.load(cfg.usersFile) : null;
  const server = makeServer(cfg, users);
  await server.initialize();
  const as = server.engine.addressSpace!;
  // Binds the A&C type methods (Acknowledge, ConditionRefresh, ...) of OPC 10000-9.
  as.installAlarmsAndConditionsService();
  const model = new Model(as, cfg.cycleUs, cfg.version);
  const alarms = new Alarms(model);
  const gateway = new GatewayClient(cfg.gateway, cfg.gatewayHttp, cfg.remoteToken, cfg.version);
  addMethods(model, gateway);
  requireAuthenticatedCalls(as);
  readOnly(model.mds);
  refuseWrites(server);
  withoutX509Users(server);
  answerDeliveredClauses(as);

  let alarmKey = "";
  const syncAlarms = async () => {
    const list = await gateway.alarms();
    if (list !== null && gateway.connected) {
      try {
        alarms.sync(list);
        readOnly(model.mds); // conditions are created on an alarm's first occurrence
      } catch (e) {
        log(`alarm update failed: ${e instanceof Error ? e.message : String(e)}`);
      }
    } else {
      alarmKey = ""; // try again with the next status
    }
  };
  gateway.on("welcome", (server: string) => model.setCoreVersion(server));
  gateway.on("status", (s) => {
    model.update(s);
    const key = [...s.alarms].sort().join(",");
    if (key !== alarmKey) {
      alarmKey = key;
      void syncAlarms();
    }
  });
  gateway.on("down", () => {
    alarmKey = "";
    model.markBad(StatusCodes.BadCommunicationError);
    alarms.markBad();
  });
  gateway.on("up", () => log(`connected to the gateway at ${cfg.gateway} as remote`));

  try {
    await server.start();
  } catch (e) {
    const busy = String(e).includes("EADDRINUSE");
    log(busy ? `port ${cfg.port} on ${cfg.bind} is in use` : `cannot start: ${String(e)}`);
    process.exit(busy ? EXIT_PORT_BUSY : EXIT_FAILED);
  }
  gateway.start();
  const endpoint = `opc.tcp://${cfg.bind}:${cfg.port}`;
  log(
    `serving OPC 40010-1 at ${endpoint} (${isLoopback(cfg.bind) ? "loopback: anonymous read" : "Basic256Sha256 Sign&Encrypt only"}` +
      `, ${users === null ? "no users file: methods disabled" : `${users.size} user(s) may call methods`})`,
  );
  const shutdown = async () => {
    gateway.stop();
    await server.shutdown(0);
    process.exit(0);
  };
  process.on("SIGTERM", () => void shutdown());
  process.on("SIGINT", () => void shutdown());
}

async function main(): Promise<void> {
  const version = packageVersion();
  let cfg: Config | "hash-password";
  try {
    if (process.argv[2] === "--write-node-map" && process.argv.length === 4) {
      await writeNodeMap(process.argv[3]);
      return;
    }
    cfg = parseArgs(process.argv.slice(2), version);
    if (cfg === "hash-password") {
      await hashPassword();
      return;
    }
  } catch (e) {
    log(e instanceof Error ? e.message : String(e));
    process.exit(EXIT_CONFIG);
  }
  await serve(cfg);
}

main().catch((e) => {
  log(`failed: ${e instanceof Error ? (e.stack ?? e.message) : String(e)}`);
  process.exit(EXIT_FAILED);
});

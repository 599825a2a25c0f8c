// Command-line options of the adapter, validated before anything listens.
//
// Secrets never come from argv (other local users can read /proc/PID/cmdline): the remote
// token comes from env SAFESTATE_REMOTE_TOKEN or --remote-token-file, the OPC UA users from
// a file of scrypt hashes (users.ts).
import * as fs from "fs";
import * as net from "net";
import * as path from "path";

export interface Config {
  bind: string;
  port: number;
  gateway: string; // ws://host:port/ws
  gatewayHttp: string; // http://host:port
  usersFile: string | null;
  pkiDir: string;
  cycleUs: number;
  remoteToken: string;
  version: string;
}

export class ConfigError extends Error {}

const USAGE = `usage: node dist/main.js [options]
  --bind ADDR            address to listen on (default 127.0.0.1)
  --port N               OPC UA port (default 4840)
  --gateway HOST:PORT    the SafeState gateway (default 127.0.0.1:8080)
  --users-file F         users allowed to call methods (lines "name:scrypt:SALT_HEX:HASH_HEX");
                         required beyond loopback
  --pki DIR              certificate store (own certificate, trusted/rejected clients)
  --cycle-us N           scan cycle of the core, to turn cycle counts into time (default 1000)
  --remote-token-file F  the gateway's remote token (else env SAFESTATE_REMOTE_TOKEN)
  --hash-password        read a password on stdin, print its users-file hash, exit`;

export function isLoopback(addr: string): boolean {
  if (addr === "localhost" || addr === "::1") {
    return true;
  }
  return net.isIPv4(addr) && addr.startsWith("127.");
}

function intOption(name: string, v: string, lo: number, hi: number): number {
  if (!/^[0-9]+$/.test(v)) {
    throw new ConfigError(`${name}: not a number: ${JSON.stringify(v)}`);
  }
  const n = Number(v);
  if (n < lo || n > hi) {
    throw new ConfigError(`${name}: ${n} out of range ${lo}..${hi}`);
  }
  return n;
}

function readToken(file: string | null): string {
  if (file !== null) {
    return fs.readFileSync(file, "utf8").replace(/\r?\n$/, "");
  }
  return process.env.SAFESTATE_REMOTE_TOKEN ?? "";
}

function gatewayAddress(v: string): [string, number] {
  const m = /^([^:]+):([0-9]+)$/.exec(v);
  if (m === null) {
    throw new ConfigError(`--gateway: expected HOST:PORT, got ${JSON.stringify(v)}`);
  }
  return [m[1], intOption("--gateway port", m[2], 1, 65535)];
}

export function parseArgs(argv: string[], version: string): Config | "hash-password" {
  const opt = new Map<string, string>();
  const valued = new Set(["--bind", "--port", "--gateway", "--users-file", "--pki", "--cycle-us", "--remote-token-file"]);
  for (let i = 0; i < argv.length; ++i) {
    const a = argv[i];
    if (a === "--hash-password") {
      return "hash-password";
    }
    if (a === "--help" || a === "-h") {
      throw new ConfigError(USAGE);
    }
    if (!valued.has(a) || i + 1 >= argv.length) {
      throw new ConfigError(`unknown option or missing value: ${a}\n${USAGE}`);
    }
    opt.set(a, argv[++i]);
  }
  const bind = opt.get("--bind") ?? "127.0.0.1";
  if (!net.isIP(bind) && bind !== "localhost") {
    throw new ConfigError(`--bind: not an IP address: ${JSON.stringify(bind)}`);
  }
  const [gwHost, gwPort] = gatewayAddress(opt.get("--gateway") ?? "127.0.0.1:8080");
  const usersFile = opt.get("--users-file") ?? null;
  if (usersFile !== null && !fs.existsSync(usersFile)) {
    throw new ConfigError(`--users-file: no such file: ${usersFile}`);
  }
  // OPC 10000-2 / IEC 62443-3-3 SR 1.1: beyond loopback every client is identified.
  if (!isLoopback(bind) && usersFile === null) {
    throw new ConfigError(
      `refusing to listen on ${bind} without --users-file: beyond loopback OPC UA needs ` +
        `authenticated users (Basic256Sha256, Sign&Encrypt); see docs/opcua.md`,
    );
  }
  return {
    bind,
    port: intOption("--port", opt.get("--port") ?? "4840", 1, 65535),
    gateway: `ws://${gwHost}:${gwPort}/ws`,
    gatewayHttp: `http://${gwHost}:${gwPort}`,
    usersFile,
    pkiDir: path.resolve(opt.get("--pki") ?? "opcua-pki"),
    cycleUs: intOption("--cycle-us", opt.get("--cycle-us") ?? "1000", 50, 100000),
    remoteToken: readToken(opt.get("--remote-token-file") ?? null),
    version,
  };
}

// The adapter's only path to the core: a `remote` client of the gateway's WebSocket
// protocol (shared/spec/protocol.md). It is no more privileged than a PLC on the same
// socket, so single point of control (ISO 10218-1 5.3.5) holds unchanged for OPC UA.
import { EventEmitter } from "events";
import WebSocket from "ws";
import { retryDelayMs } from "./backoff";

export interface Status {
  t: number;
  state: string;
  sub: string | null;
  mode: string;
  stop: string | null;
  contactor: string;
  drives: string;
  brakes: string;
  tcp_speed: number;
  alarms: string[];
  joints: number[];
  owner: string | null;
  cause: string | null;
  axis_state?: string[];
  program_index?: number;
  program_length?: number;
  safety?: SafetyStatus;
  // SPEC §14 (absent from a gateway that predates it): the channels and the two contactors.
  channels?: ChannelStatus[];
  contactors?: { k1: string; k2: string | null };
}

// One channel of SPEC §14 as the status shows it (gateway/src/views.cpp).
export interface ChannelStatus {
  name: string;
  compiler: string | null;
  pid: number | null;
  running: boolean;
  answered: boolean;
  state: string;
  cycle: number;
  digest: string;
  agree: boolean;
  differs_in: string | null;
}

// The status message's `safety` object (protocol.md; SPEC §10).
export interface SafetyStatus {
  checksum: string;
  validated: boolean;
  reduced: boolean;
  reduced_by: string[];
  recovery: boolean;
  speed_limit: number;
  // SPEC §11 (absent from a gateway that predates it): null while the function does not act.
  v_allowed?: number | null;
  fields?: { outer: string; inner: string };
  separation_mm?: number | null;
  pfl?: boolean;
  contact_force?: number | null;
  contact_force_limit?: number | null;
  // SPEC §12 (protocol.md's due_in_h and last; running after them, from the gateway).
  brake_test?: { due_in_h: number | null; last: string; running?: boolean };
}

export interface AlarmInfo {
  name: string;
  number: number;
  severity: string;
  text: string;
  remedy: string;
  detail?: string;
  since?: number;
}

const STATUS_SILENCE_MS = 1000; // status comes at 50 Hz: a second of silence is a lost gateway
const REPLY_TIMEOUT_MS = 3000;

interface Pending {
  resolve: (result: string) => void;
  timer: NodeJS.Timeout;
}

export class GatewayClient extends EventEmitter {
  private ws: WebSocket | null = null;
  private seq = 0;
  private readonly pending = new Map<number, Pending>();
  private live = false;
  private closed = false;
  private silence: NodeJS.Timeout | null = null;
  private failures = 0; // connections in a row that ended before a welcome (back-off)
  latest: Status | null = null;

  constructor(
    private readonly url: string,
    private readonly httpBase: string,
    private readonly token: string,
    private readonly version: string,
  ) {
    super();
  }

  start(): void {
    this.connect();
  }

  stop(): void {
    this.closed = true;
    this.ws?.terminate();
  }

  get connected(): boolean {
    return this.live;
  }

  // Resolves with the SafeState result code; never rejects (a lost gateway is a result too).
  command(cmd: string): Promise<string> {
    if (this.ws === null || !this.live) {
      return Promise.resolve("GATEWAY_UNAVAILABLE");
    }
    const seq = ++this.seq;
    return new Promise((resolve) => {
      const timer = setTimeout(() => {
        this.pending.delete(seq);
        resolve("TIMEOUT");
      }, REPLY_TIMEOUT_MS);
      this.pending.set(seq, { resolve, timer });
      this.ws!.send(JSON.stringify({ type: "command", seq, cmd }));
    });
  }

  // Resolves true when a status satisfies pred, false after ms or when the gateway is lost.
  waitFor(pred: (s: Status) => boolean, ms: number): Promise<boolean> {
    if (this.latest !== null && pred(this.latest)) {
      return Promise.resolve(true);
    }
    return new Promise((resolve) => {
      const done = (ok: boolean) => {
        clearTimeout(timer);
        this.off("status", onStatus);
        this.off("down", onDown);
        resolve(ok);
      };
      const onStatus = (s: Status) => pred(s) && done(true);
      const onDown = () => done(false);
      const timer = setTimeout(() => done(false), ms);
      this.on("status", onStatus);
      this.on("down", onDown);
    });
  }

  async alarms(): Promise<AlarmInfo[] | null> {
    try {
      const headers: Record<string, string> = {};
      if (this.token !== "") {
        headers.Authorization = `Bearer ${this.token}`;
      }
      const r = await fetch(`${this.httpBase}/api/alarms`, { headers, signal: AbortSignal.timeout(2000) });
      return r.ok ? ((await r.json()) as AlarmInfo[]) : null;
    } catch {
      return null;
    }
  }

  private connect(): void {
    if (this.closed) {
      return;
    }
    // A non-browser client sends no Origin header (protocol.md "Who may connect").
    const ws = new WebSocket(this.url, { handshakeTimeout: 2000 });
    this.ws = ws;
    ws.on("open", () => {
      const hello: Record<string, string> = { type: "hello", role: "remote", client: `safestate-opcua ${this.version}` };
      if (this.token !== "") {
        hello.token = this.token;
      }
      ws.send(JSON.stringify(hello));
    });
    ws.on("message", (data) => this.onMessage(data.toString()));
    ws.on("error", () => undefined); // "close" follows and handles it
    ws.on("close", () => this.onClose(ws));
  }

  private onMessage(text: string): void {
    let m: Record<string, unknown>;
    try {
      m = JSON.parse(text) as Record<string, unknown>;
    } catch {
      return;
    }
    switch (m.type) {
      case "status":
        this.onStatus(m as unknown as Status);
        break;
      case "reply":
        this.onReply(m.seq as number, String(m.result));
        break;
      case "event":
        this.emit("event", m);
        break;
      case "welcome":
        this.failures = 0;
        this.emit("welcome", String(m.server ?? ""));
        break;
      case "error":
        process.stderr.write(`safestate-opcua: gateway error ${String(m.code)}: ${String(m.detail ?? "")}\n`);
        if (m.code === "BAD_TOKEN" || m.code === "ROLE_TAKEN") {
          this.ws?.close();
        }
        break;
      default:
        break;
    }
  }

  private onStatus(s: Status): void {
    if (this.silence !== null) {
      clearTimeout(this.silence);
    }
    this.silence = setTimeout(() => this.lost("no status for 1 s"), STATUS_SILENCE_MS);
    this.latest = s;
    if (!this.live) {
      this.live = true;
      this.emit("up");
    }
    this.emit("status", s);
  }

  private onReply(seq: number, result: string): void {
    const p = this.pending.get(seq);
    if (p !== undefined) {
      clearTimeout(p.timer);
      this.pending.delete(seq);
      p.resolve(result);
    }
  }

  private lost(why: string): void {
    if (this.silence !== null) {
      clearTimeout(this.silence);
      this.silence = null;
    }
    for (const [seq, p] of this.pending) {
      clearTimeout(p.timer);
      p.resolve("GATEWAY_UNAVAILABLE");
      this.pending.delete(seq);
    }
    this.latest = null;
    if (this.live) {
      this.live = false;
      if (!this.closed) {
        process.stderr.write(
          `safestate-opcua: lost the gateway (${why}); every value is BadCommunicationError\n`,
        );
      }
      this.emit("down");
    }
    this.ws?.terminate();
  }

  private onClose(ws: WebSocket): void {
    if (ws !== this.ws) {
      return;
    }
    this.lost("connection closed");
    this.ws = null;
    if (!this.closed) {
      // Jittered exponential back-off (backoff.ts): refused (503, close 1013) or after a
      // gateway restart, the adapter does not return in the same millisecond as every
      // other client; it starts again from 0.5 s after a welcome.
      this.failures += 1;
      setTimeout(() => this.connect(), retryDelayMs(this.failures));
    }
  }
}

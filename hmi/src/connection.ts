// The WebSocket link to the gateway (protocol.md): hello as pendant (observer when another
// pendant has control), commands with their own seq and exactly one reply each, `sim`
// messages, status and event pushes, and reconnection. A command that cannot be sent, or
// that gets no reply, is reported like a refusal: nothing is dropped silently.
import type { HmiEvent, ServerMessage, Status } from './api';
import type { PersonMessage } from './person';
// One reconnect schedule for every gateway client of this repository (the OPC UA adapter's
// file: its tsc build takes sources from its own src/ only; Vite takes this path as it is).
import { retryDelayMs } from '../../adapters/opcua/src/backoff';

export type LinkState = 'connecting' | 'open' | 'closed';
export type Role = 'pendant' | 'observer' | null;

export interface Outcome {
  seq: number | null;
  kind: 'command' | 'sim';
  cmd: string; // command name, or a description of the sim message
  result: string; // SPEC §5 result, protocol error code, or NOT_SENT / NO_REPLY
  detail?: string;
  show: Show;
}

/** What the result area shows of an outcome (the event history shows every command). */
export type Show = 'all' | 'refusals' | 'none';

interface Pending {
  kind: 'command' | 'sim';
  cmd: string;
  sentAt: number;
  show: Show;
  onResult?: (o: Outcome) => void;
}

export interface LinkHandlers {
  status(s: Status): void;
  event(e: HmiEvent): void;
  outcome(o: Outcome): void;
  link(state: LinkState, role: Role, note: string): void;
  protocolError(code: string, detail: string): void;
}

const REPLY_TIMEOUT_MS = 3000;
export const TOKEN_KEY = 'safestate.token';

/** Why a WebSocket closed, in words (RFC 6455 close codes; a refused upgrade is 1006). */
export function closeWords(code: number, opened: boolean): string {
  if (!opened) return 'The controller refused the connection or cannot be reached (wrong address, not allowed from this page, or full)';
  switch (code) {
    case 1000:
      return 'The connection was closed';
    case 1001:
      return 'The controller is shutting down or restarting its gateway';
    case 1008:
      return 'The controller closed the connection (no hello in time, or too many refused messages)';
    case 1009:
      return 'The controller closed the connection: a message was too large';
    case 1013:
      return 'The controller is full or busy (too many clients connecting at once)';
    default:
      return 'The connection to the controller dropped (network or gateway lost)';
  }
}

export class Link {
  private ws: WebSocket | null = null;
  private seq = 1;
  private pending = new Map<number, Pending>();
  private failures = 0; // attempts in a row that ended before a welcome
  private retryTimer = 0;
  state: LinkState = 'closed';
  role: Role = null;
  server = '';
  private wantRole: 'pendant' | 'observer' = 'pendant';
  private token: string | null;

  constructor(private readonly h: LinkHandlers) {
    // The token lives in this tab's sessionStorage and goes only into the hello (and the
    // Authorization header of /api requests): never into a URL, where it would stay in
    // the history, the server logs and the Referer of every link.
    this.token = sessionStorage.getItem(TOKEN_KEY);
    window.setInterval(() => this.expire(), 500);
  }

  connect(): void {
    window.clearTimeout(this.retryTimer);
    const proto = location.protocol === 'https:' ? 'wss:' : 'ws:';
    const ws = new WebSocket(`${proto}//${location.host}/ws`);
    this.ws = ws;
    this.setState('connecting', 'Connecting to the controller…');
    let opened = false;
    ws.onopen = () => {
      opened = true;
      this.hello();
    };
    ws.onmessage = (ev) => this.onMessage(ev.data as string);
    ws.onclose = (ev) => {
      if (this.ws !== ws) return;
      this.ws = null;
      this.role = null;
      this.failAll('NO_REPLY', 'the connection closed before the controller answered');
      // Jittered exponential back-off (backoff.ts); it starts again only after a welcome,
      // so a gateway that upgrades and then refuses (close 1013) is not hammered.
      this.failures += 1;
      const delay = retryDelayMs(this.failures);
      this.setState('closed', `${closeWords(ev.code, opened)}: retrying in ${(delay / 1000).toFixed(1)} s`);
      this.retryTimer = window.setTimeout(() => this.connect(), delay);
    };
  }

  /** Ask again for control (after the other pendant left). */
  takeControl(): void {
    this.wantRole = 'pendant';
    this.hello();
  }

  setToken(token: string): void {
    this.token = token;
    sessionStorage.setItem(TOKEN_KEY, token);
    this.wantRole = 'pendant';
    this.hello();
  }

  private hello(): void {
    const msg: Record<string, unknown> = { type: 'hello', role: this.wantRole, client: 'SafeState HMI' };
    if (this.token) msg.token = this.token;
    this.send(msg);
  }

  private setState(s: LinkState, note: string): void {
    this.state = s;
    this.h.link(s, this.role, note);
  }

  private send(msg: unknown): boolean {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    this.ws.send(JSON.stringify(msg));
    return true;
  }

  get connected(): boolean {
    return this.state === 'open';
  }

  command(cmd: string, args: Record<string, unknown> = {}, show: Show = 'all', onResult?: (o: Outcome) => void): number | null {
    const seq = this.seq++;
    if (!this.send({ type: 'command', seq, cmd, ...args })) {
      const o: Outcome = { seq: null, kind: 'command', cmd, result: 'NOT_SENT', detail: 'not connected to the controller', show };
      this.h.outcome(o);
      onResult?.(o);
      return null;
    }
    this.pending.set(seq, { kind: 'command', cmd, sentAt: performance.now(), show, onResult });
    return seq;
  }

  sim(
    body: { set: Record<string, string | number> } | { fault: string } | { person: PersonMessage },
    what: string,
  ): number | null {
    const seq = this.seq++;
    if (!this.send({ type: 'sim', seq, ...body })) {
      this.h.outcome({ seq: null, kind: 'sim', cmd: what, result: 'NOT_SENT', detail: 'not connected to the controller', show: 'all' });
      return null;
    }
    this.pending.set(seq, { kind: 'sim', cmd: what, sentAt: performance.now(), show: 'all' });
    return seq;
  }

  private settle(seq: number, result: string, detail?: string): void {
    const p = this.pending.get(seq);
    if (!p) return;
    this.pending.delete(seq);
    const o: Outcome = { seq, kind: p.kind, cmd: p.cmd, result, detail, show: p.show };
    this.h.outcome(o);
    p.onResult?.(o);
  }

  private failAll(result: string, detail: string): void {
    for (const seq of [...this.pending.keys()]) this.settle(seq, result, detail);
  }

  private expire(): void {
    const now = performance.now();
    for (const [seq, p] of this.pending) {
      if (now - p.sentAt > REPLY_TIMEOUT_MS) this.settle(seq, 'NO_REPLY', `no answer within ${REPLY_TIMEOUT_MS / 1000} s`);
    }
  }

  private onMessage(text: string): void {
    let m: ServerMessage;
    try {
      m = JSON.parse(text) as ServerMessage;
    } catch {
      return;
    }
    switch (m.type) {
      case 'status':
        this.h.status(m);
        break;
      case 'event':
        this.h.event(m);
        break;
      case 'reply':
        this.settle(m.seq, m.result);
        break;
      case 'welcome':
        this.failures = 0;
        this.role = m.role === 'pendant' ? 'pendant' : 'observer';
        this.server = m.server;
        this.setState(
          'open',
          this.role === 'pendant' ? 'Connected: this pendant has control' : 'Connected read-only: another pendant has control',
        );
        break;
      case 'error':
        this.onError(m.code, m.detail ?? '');
        break;
    }
  }

  private onError(code: string, detail: string): void {
    if (code === 'ROLE_TAKEN') {
      this.wantRole = 'observer';
      this.hello();
    } else if (code === 'BAD_TOKEN' && this.wantRole === 'pendant') {
      // Read-only meanwhile (where the server lets observers in without a token); the
      // login screen asks for the pendant token (main.ts).
      this.wantRole = 'observer';
      this.hello();
    } else if (code === 'NOT_SIMULATED' || code === 'BAD_MESSAGE' || code === 'TOO_LARGE') {
      // A `sim` error has no seq (protocol.md): it answers the oldest sim in flight.
      for (const [seq, p] of this.pending) {
        if (p.kind === 'sim') {
          this.settle(seq, code, detail);
          return;
        }
      }
    }
    this.h.protocolError(code, detail);
  }
}

// The messages and HTTP answers of ../shared/spec/protocol.md, as the gateway sends them
// (gateway/src/views.cpp adds the fields after `owner`).

export type State =
  | 'BOOT'
  | 'ERROR_LOCKOUT'
  | 'ESTOP_ACTIVE'
  | 'ESTOP_RESET_NEEDED'
  | 'IDLE'
  | 'ARMING'
  | 'OPERATIONAL'
  | 'STOPPING';
export type Sub = 'AUTO_IDLE' | 'AUTO_RUNNING' | 'AUTO_PAUSED' | 'MANUAL_IDLE' | 'MANUAL_JOGGING' | 'MANUAL_RUNNING';
export type Mode = 'AUTO' | 'T1' | 'T2' | 'NONE';
export type StopCat = 'CAT0' | 'CAT1' | 'CAT2';

export interface Status {
  type?: 'status';
  t: number;
  state: State;
  sub: Sub | null;
  mode: Mode;
  stop: StopCat | null;
  contactor: 'open' | 'closed';
  drives: 'enabled' | 'disabled';
  brakes: 'engaged' | 'released';
  reset_lamp: 'on' | 'off';
  tcp_speed: number;
  alarms: string[];
  joints: number[];
  tcp: number[];
  t2_confirmed: boolean;
  owner: string | null;
  // Beyond protocol.md (SPEC §7), see gateway/src/views.cpp.
  mode_requested?: Mode;
  target?: string | null;
  cause?: string | null;
  arming_step?: string | null;
  arming_progress?: number;
  axis_state?: string[];
  program_index?: number;
  program_length?: number;
  simulated?: boolean;
  max_point_speed?: number;
  core_heartbeat_age_ms?: number;
  core_pid?: number;
  shutting_down?: boolean;
}

export interface Alarm {
  name: string;
  number: number;
  severity: 'info' | 'warning' | 'fault' | 'lockout';
  text: string;
  remedy: string;
  detail: string;
  since: number; // core cycle number
}

export type EventKind = 'transition' | 'alarm' | 'alarm_cleared' | 'command';

export interface HmiEvent {
  id: number | null;
  t: number;
  time: string;
  kind: EventKind;
  data: Record<string, unknown>;
  blackbox?: string | null; // the URL of its black box (/api/events/ID/blackbox), or null
}

export interface DhRow {
  a: number;
  alpha: number;
  d: number;
  theta_offset: number;
}

export interface Robot {
  name: string;
  reach: number;
  dh: DhRow[];
  joint_limits: { min: number; max: number }[];
  velocity_limits: number[];
  link_names: string[];
  tcp_offset: number[];
}

export type ServerMessage =
  | ({ type: 'status' } & Status)
  | { type: 'welcome'; role: string; server: string }
  | { type: 'reply'; seq: number; result: string }
  | ({ type: 'event' } & HmiEvent)
  | { type: 'error'; code: string; detail?: string; seq?: number };

/** Beyond loopback /api/* and /metrics need `Authorization: Bearer <token>` (protocol.md). */
export function authHeaders(): Record<string, string> {
  const token = sessionStorage.getItem('safestate.token');
  return token ? { Authorization: `Bearer ${token}` } : {};
}

async function getJson<T>(path: string): Promise<T> {
  const r = await fetch(path, { cache: 'no-store', headers: authHeaders() });
  if (!r.ok) {
    throw new Error(`GET ${path}: HTTP ${r.status}`);
  }
  return (await r.json()) as T;
}

export const fetchAlarms = (): Promise<Alarm[]> => getJson<Alarm[]>('/api/alarms');
export const fetchRobot = (): Promise<Robot> => getJson<Robot>('/api/robot');
export const fetchStatus = (): Promise<Status> => getJson<Status>('/api/status');
export const fetchEvents = (after: number, limit: number): Promise<HmiEvent[]> =>
  getJson<HmiEvent[]>(`/api/events?after=${after}&limit=${limit}`);

export async function fetchMetricsText(): Promise<string> {
  const r = await fetch('/metrics', { cache: 'no-store', headers: authHeaders() });
  if (!r.ok) {
    throw new Error(`GET /metrics: HTTP ${r.status}`);
  }
  return r.text();
}

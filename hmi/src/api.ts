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
export type Sub =
  | 'AUTO_IDLE'
  | 'AUTO_RUNNING'
  | 'AUTO_PAUSED'
  | 'MANUAL_IDLE'
  | 'MANUAL_JOGGING'
  | 'MANUAL_RUNNING'
  | 'BRAKE_TEST';
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
  // SPEC §10 (protocol.md): absent from a gateway that predates it.
  safety?: SafetyStatus;
  // SPEC §11, the simulated person (gateway/src/views.cpp): null off the in-process simulated cell.
  sim?: SimStatus | null;
  // SPEC §14 (gateway/src/views.cpp): the channels, and the two contactors' auxiliary contacts.
  channels?: ChannelStatus[];
  contactors?: { k1: 'open' | 'closed'; k2: 'open' | 'closed' | null };
}

/** One channel of SPEC §14 as the status shows it (docs/two-channels.md). */
export interface ChannelStatus {
  name: 'A' | 'B';
  compiler: 'gcc' | 'clang' | null;
  pid: number | null;
  running: boolean;
  answered: boolean;
  state: State;
  cycle: number;
  digest: string;
  agree: boolean;
  differs_in: string | null;
  missing: number;
  late: number;
  skipped: number;
  wake_max_us: number;
  exec_max_us: number;
}

/** The simulated person as the simulated scanner and distance sensor see it. */
export interface SimPerson {
  x_mm: number;
  y_mm: number;
  radius_mm: number;
  speed_mm_s: number;
  walking: boolean;
  in_outer: boolean;
  in_inner: boolean;
  separation_mm: number; // body edge to the nearest robot point, horizontal
  nearest_point: number; // 0..5 a joint origin, 6 the flange, 7 the TCP
}

/** The status's `sim` object (docs/collaborative.md "The simulated person"). */
export interface SimStatus {
  person: SimPerson | null;
  person_fields: { outer_mm: number; inner_mm: number; scanner: boolean; distance_sensor: boolean };
}

/** The status's `safety` object (protocol.md, SPEC §10-§12). */
export interface SafetyStatus {
  checksum: string;
  validated: boolean;
  reduced: boolean;
  reduced_by: string[]; // subset of zone, input, field
  recovery: boolean;
  speed_limit: number; // mm/s, the TCP limit in force now
  v_allowed: number | null;
  fields?: { outer: string; inner: string };
  separation_mm?: number | null;
  brake_test?: BrakeTestStatus;
  // SPEC §11 collision detection (after protocol.md's fields, gateway/src/views.cpp).
  pfl?: boolean;
  contact_force?: number | null; // N at the TCP, null when pfl is off
  contact_force_limit?: number | null; // the body region's F_qs (N), from the configuration
  pfl_speed_limit?: number | null; // v_pfl (mm/s), from the configuration
}

/** The status's `safety.brake_test` (SPEC §12): protocol.md's due_in_h and last, then the
 * gateway's additive fields (gateway/README.md; absent from a gateway that predates them). */
export interface BrakeTestStatus {
  due_in_h: number | null; // negative: overdue; null when no pass is on record or none is required
  last: string; // none | passed | failed
  running?: boolean;
  axis?: number | null; // 1..6 while running
  progress?: number | null; // percent of the whole test while running
  due?: boolean; // BRAKE_TEST_DUE
  required?: boolean; // servo_on in AUTO is BRAKE_TEST_REQUIRED
  last_time?: string | null; // ISO-8601 UTC of the newest brake_test event of the log
  last_axis?: number | null; // the axis that slipped (null on a pass)
  drift_deg?: number[] | null; // every axis' drift of that result, degrees
}

export type ZoneKind = 'keep_in' | 'keep_out' | 'reduced';

export interface SafetyZone {
  name: string;
  kind: ZoneKind;
  min_mm: number[];
  max_mm: number[];
}

export interface SafetyJoint {
  min_deg: number;
  max_deg: number;
  max_speed_deg_s: number;
}

/** The safety configuration file as the gateway holds it (SPEC §10 keys). */
export interface SafetyConfig {
  format: string;
  name: string;
  tool: { tcp_mm: number[]; radius_mm: number; payload_kg: number };
  joints: SafetyJoint[];
  tcp_max_speed_mm_s: number;
  reduced: { tcp_max_speed_mm_s: number; ramp_ms: number };
  orientation?: { axis: number[]; max_deviation_deg: number } | null;
  zones: SafetyZone[];
  stop: { max_time_ms: number };
  collaborative?: unknown;
  brake_test?: unknown;
}

/** GET /api/safety. */
export interface SafetyInfo {
  name: string;
  checksum: string;
  source: string;
  validated: boolean;
  confirmation: { checksum: string; client: string; time: string } | null;
  config: SafetyConfig;
}

export interface Alarm {
  name: string;
  number: number;
  severity: 'info' | 'warning' | 'fault' | 'lockout';
  text: string;
  remedy: string;
  detail: string;
  since: number; // core cycle number
  subject?: string; // scenario vocabulary: axis.N, tcp, a zone's name, estop.a, ...
}

export type EventKind = 'transition' | 'alarm' | 'alarm_cleared' | 'command' | 'config_validated' | 'brake_test';

export interface HmiEvent {
  id: number | null;
  t: number;
  time: string;
  kind: EventKind;
  data: Record<string, unknown>;
  blackbox?: string | null; // the URL of its black box (/api/events/ID/blackbox), or null
}

type V3 = [number, number, number];

/** A frame fixed in its parent (mm; rotation as rows: columns are the child's axes). */
export interface FixedFrame {
  origin: V3;
  rotation: [V3, V3, V3];
}

/** Joint k of the URDF chain (docs/robot.md): its frame in joint k-1's, and its axis. */
export interface ChainJoint extends FixedFrame {
  name: string;
  link: string;
  axis: V3;
}

export interface Robot {
  name: string;
  source: string; // the URDF file, or "built-in"
  parameters_checksum: string; // the description's part of the safety checksum
  urdf: string; // the description as read
  reach: number;
  base: string;
  flange_link: string;
  joints: ChainJoint[];
  flange: FixedFrame;
  joint_limits: { min: number; max: number }[];
  velocity_limits: number[];
  link_names: string[];
  tcp_offset: number[];
  /** The URDF's visual meshes the gateway serves (from the description's own package folder). */
  meshes?: { uri: string; url: string }[];
  /** Those it does not serve, and why (the HMI then draws simple shapes). */
  meshes_refused?: { uri: string; why: string }[];
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
export const fetchSafety = (): Promise<SafetyInfo> => getJson<SafetyInfo>('/api/safety');
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

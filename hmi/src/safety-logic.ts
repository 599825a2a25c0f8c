// The pure rules behind the Safety page (SPEC §10): when the validate dialog may send, what
// a typed code is, which limit an alarm names (for the highlight), where a joint stands in
// its configured range, and the zone colours shared by the 3D view and its legend.
// No DOM and no value imports: hmi/tests/safety-logic.test.mjs loads this very file
// (types stripped) under `node --test`.
import type { Alarm, Mode, SafetyJoint, State, ZoneKind } from './api';

// ------------------------------------------------------------------ validate dialog
export interface Gate {
  enabled: boolean;
  /** Every condition that is not met, in words (empty when enabled). */
  reasons: string[];
}

export interface GateInput {
  connected: boolean;
  role: 'pendant' | 'observer' | null;
  state: State | null;
  mode: Mode | null;
  /** The status carries a `safety` object (a gateway that predates SPEC §10 does not). */
  hasSafety: boolean;
}

/** SPEC §10: `validate_config` from the pendant, in IDLE with mode T1 or T2. */
export function validateGate(g: GateInput): Gate {
  const reasons: string[] = [];
  if (!g.connected || g.state === null) {
    reasons.push('Not connected to the controller.');
    return { enabled: false, reasons };
  }
  if (g.role !== 'pendant') {
    reasons.push('This screen is read-only (observer): only the pendant that has control may validate.');
  }
  if (g.mode !== 'T1' && g.mode !== 'T2') {
    reasons.push(`Turn the key switch to T1 or T2 (now ${g.mode ?? 'unknown'}).`);
  }
  if (g.state !== 'IDLE') {
    reasons.push(`Only in IDLE, with the drives off (now ${g.state}).`);
  }
  if (!g.hasSafety) {
    reasons.push('The controller does not report a safety configuration.');
  }
  return { enabled: reasons.length === 0, reasons };
}

export interface TypedCode {
  /** The code to send (8 upper-case hex digits), or null when `problem` says why not. */
  code: string | null;
  problem: string;
}

/** What the operator typed: spaces are ignored and lower case is the same digit. */
export function typedCode(text: string): TypedCode {
  const t = text.replace(/\s+/g, '').toUpperCase();
  if (t.length === 0) return { code: null, problem: 'Type the 8 hex digits of the checksum.' };
  const bad = [...t].find((ch) => !/[0-9A-F]/.test(ch));
  if (bad !== undefined) return { code: null, problem: `"${bad}" is not a hex digit (0–9, A–F).` };
  if (t.length !== 8) return { code: null, problem: `${t.length} of 8 digits.` };
  return { code: t, problem: '' };
}

/** The reply to validate_config in words (SPEC §5 results). */
export function validateReplyWords(result: string, code: string): { tone: 'ok' | 'refused' | 'failed'; text: string } {
  switch (result) {
    case 'OK':
      return { tone: 'ok', text: `Validated: the controller confirmed checksum ${code} and wrote it to the event log.` };
    case 'CHECKSUM_MISMATCH':
      return {
        tone: 'refused',
        text: `${code} is not the checksum of the active configuration: nothing changed. Check that the loaded configuration is the approved one.`,
      };
    case 'WRONG_STATE':
      return { tone: 'refused', text: 'Refused: validation is only possible in IDLE with the drives off.' };
    case 'MODE_INVALID':
      return { tone: 'refused', text: 'Refused: validation needs the key switch at T1 or T2.' };
    case 'NOT_CONTROL_OWNER':
      return { tone: 'refused', text: 'Refused: only the pendant that has control may validate.' };
    case 'BAD_ARGUMENT':
      return { tone: 'refused', text: 'Refused: the code must be 8 hex digits.' };
    case 'NOT_SENT':
      return { tone: 'failed', text: 'Not sent: there is no connection to the controller.' };
    case 'NO_REPLY':
      return { tone: 'failed', text: 'No answer from the controller: check the Safety page before trying again.' };
    default:
      return { tone: 'refused', text: `Refused: ${result}.` };
  }
}

// ------------------------------------------------------------------ violated limits
export const LIMIT_ALARMS = ['JOINT_LIMIT', 'ZONE_VIOLATION', 'ORIENTATION_LIMIT', 'SPEED_LIMIT'] as const;

export interface Violation {
  alarm: string;
  axis: number | null; // 1..6
  zone: number | null; // index in config.zones
  tcp: boolean;
  /** "axis 3", "zone table", "TCP", "tool orientation", or "" while the detail is not known. */
  what: string;
}

export interface Highlight {
  violations: Violation[];
  joints: number[]; // axes (1..6) whose range or speed is violated
  zones: number[]; // zone indices violated
  tcp: boolean; // the TCP speed limit
  orientation: boolean;
  /** Reduced zones that make reduced mode active now (REDUCED_SPEED from a zone). */
  activeZones: number[];
}

type AlarmLike = Pick<Alarm, 'name' | 'detail'> & { subject?: string };

/** Which axis, zone or TCP an alarm names: from its `subject` (the scenario vocabulary:
 * axis.N, tcp, the zone's name), else from its words ("Axis 3 …", "Zone table …",
 * "Zone 2 …", "TCP …"). */
export function subjectOf(a: AlarmLike, zoneNames: readonly string[]): { axis: number | null; zone: number | null; tcp: boolean } {
  const none = { axis: null, zone: null, tcp: false };
  const sub = (a.subject ?? '').trim();
  if (sub) {
    const m = /^axis\.([1-6])$/.exec(sub);
    if (m) return { ...none, axis: Number(m[1]) };
    if (sub === 'tcp') return { ...none, tcp: true };
    const z = zoneNames.indexOf(sub);
    if (z >= 0) return { ...none, zone: z };
  }
  const d = a.detail ?? '';
  const axis = /\bAxis ([1-6])\b/.exec(d);
  if (axis) return { ...none, axis: Number(axis[1]) };
  if (/\bTCP\b/.test(d)) return { ...none, tcp: true };
  // "Zone table (keep-out) violated": the longest zone name that follows "Zone ".
  let best = -1;
  zoneNames.forEach((n, i) => {
    if (d.includes(`Zone ${n}`) && (best < 0 || n.length > zoneNames[best].length)) best = i;
  });
  if (best >= 0) return { ...none, zone: best };
  const num = /\bZone (\d+)\b/.exec(d); // the core's own words: 1-based
  if (num && Number(num[1]) >= 1 && Number(num[1]) <= zoneNames.length) return { ...none, zone: Number(num[1]) - 1 };
  return none;
}

/** The violated limits among the active alarms. `names` are status.alarms (always current);
 * `alarms` the objects of /api/alarms (with the detail; may lag a moment behind). */
export function highlights(names: readonly string[], alarms: readonly AlarmLike[], zoneNames: readonly string[]): Highlight {
  const h: Highlight = { violations: [], joints: [], zones: [], tcp: false, orientation: false, activeZones: [] };
  const add = <T>(list: T[], v: T) => {
    if (!list.includes(v)) list.push(v);
  };
  for (const name of names) {
    if (name === 'REDUCED_SPEED') {
      for (const a of alarms.filter((x) => x.name === name)) {
        const s = subjectOf(a, zoneNames);
        if (s.zone !== null) add(h.activeZones, s.zone);
      }
      continue;
    }
    if (!(LIMIT_ALARMS as readonly string[]).includes(name)) continue;
    const objs = alarms.filter((x) => x.name === name);
    if (objs.length === 0) objs.push({ name, detail: '' });
    for (const a of objs) {
      const s = subjectOf(a, zoneNames);
      const v: Violation = { alarm: name, ...s, what: '' };
      if (name === 'ORIENTATION_LIMIT') {
        v.what = 'tool orientation';
        h.orientation = true;
      } else if (s.axis !== null) {
        v.what = `axis ${s.axis}`;
        add(h.joints, s.axis);
      } else if (s.zone !== null) {
        v.what = `zone ${zoneNames[s.zone]}`;
        add(h.zones, s.zone);
      } else if (s.tcp) {
        v.what = 'TCP';
        h.tcp = true;
      }
      h.violations.push(v);
    }
  }
  return h;
}

/** One line naming a violation: "ZONE_VIOLATION · zone table". */
export function violationLabel(v: Violation): string {
  return v.what ? `${v.alarm} · ${v.what}` : v.alarm;
}

// ------------------------------------------------------------------ joint bars
export interface BarGeometry {
  /** The configured range within the robot's own, as fractions 0..1 of the bar. */
  lo: number;
  hi: number;
  /** The joint's position as a fraction of the bar (clamped). */
  at: number;
  where: 'inside' | 'near' | 'outside';
}

const clamp01 = (x: number) => Math.min(1, Math.max(0, x));
const DEG = 180 / Math.PI;

/** Where joint position `q` (rad) stands: the bar spans the robot's range [rMin, rMax]
 * (rad); `cfg` is the configured safe range (degrees), or null (then the robot's). Near:
 * within 3 % of the configured span or 2° of either end. */
export function barGeometry(q: number, rMin: number, rMax: number, cfg: SafetyJoint | null): BarGeometry {
  const span = rMax - rMin || 1;
  const cMin = cfg ? cfg.min_deg / DEG : rMin;
  const cMax = cfg ? cfg.max_deg / DEG : rMax;
  const lo = clamp01((cMin - rMin) / span);
  const hi = clamp01((cMax - rMin) / span);
  const at = clamp01((q - rMin) / span);
  const near = Math.max(0.03 * (cMax - cMin), 2 / DEG);
  let where: BarGeometry['where'] = 'inside';
  if (q < cMin || q > cMax) where = 'outside';
  else if (q - cMin < near || cMax - q < near) where = 'near';
  return { lo, hi, at, where };
}

// ------------------------------------------------------------------ zones and reduced mode
export const ZONE_STYLE: Record<ZoneKind, { color: string; label: string; words: string }> = {
  keep_in: { color: '#43a047', label: 'keep-in', words: 'the arm must stay inside' },
  keep_out: { color: '#e53935', label: 'keep-out', words: 'the arm must stay outside' },
  reduced: { color: '#ffb300', label: 'reduced', words: 'reduced speed inside' },
};

export const REDUCED_BY_WORDS: Record<string, string> = {
  zone: 'the TCP is in a reduced zone',
  input: 'the reduced-speed input asks for it',
  field: 'the outer protective field is interrupted',
};

/** Why reduced mode is on, in words ("" when it is off). */
export function reducedWords(reduced: boolean, by: readonly string[]): string {
  if (!reduced) return '';
  const why = by.map((b) => REDUCED_BY_WORDS[b] ?? b);
  return why.length ? `because ${why.join(' and ')}` : 'reason not reported';
}

// ------------------------------------------------------------------ collaborative operation (SPEC §11)
/** What the Collaborative section needs of the status' `safety` object (all optional: a
 * gateway that predates SPEC §11 or its collision detection leaves them out). */
export interface CollabInput {
  reduced: boolean;
  reduced_by: readonly string[];
  speed_limit: number;
  v_allowed: number | null;
  fields?: { outer: string; inner: string };
  separation_mm?: number | null;
  pfl?: boolean;
  contact_force?: number | null;
  contact_force_limit?: number | null;
  pfl_speed_limit?: number | null;
}

export interface SlowWhy {
  /** The TCP limit in force now (mm/s): the lower of speed_limit and v_allowed. */
  limit: number;
  /** What sets that limit: 'normal', 'reduced', 'ssm', 'ssm-hold' (v_allowed 0), 'pfl'. */
  by: 'normal' | 'reduced' | 'ssm' | 'ssm-hold' | 'pfl';
  /** Every reason the robot is slower than normal, or stopped by a field, in words. */
  reasons: string[];
}

const mm = (v: number) => `${Math.round(v)}`;

/** Why the robot is slow (or held), in words, from the status' `safety` object. Pure. */
export function slowWhy(sf: CollabInput): SlowWhy {
  const reasons: string[] = [];
  // PFL caps the reduced limit while the outer field is interrupted (v_pfl the lowest of
  // the reduced limits); the status rounds both to 0.1 mm/s.
  const pflCap =
    sf.reduced &&
    sf.reduced_by.includes('field') &&
    sf.pfl_speed_limit != null &&
    Math.abs(sf.speed_limit - sf.pfl_speed_limit) < 0.5;
  if (sf.reduced) {
    if (sf.reduced_by.includes('zone')) reasons.push('Reduced speed: the TCP is in a reduced zone.');
    if (sf.reduced_by.includes('input')) reasons.push('Reduced speed: the reduced-speed input asks for it.');
    if (sf.reduced_by.includes('field')) {
      reasons.push(
        pflCap
          ? `Reduced speed: the outer protective field is interrupted, and power and force limiting caps the TCP at v_pfl = ${mm(sf.pfl_speed_limit as number)} mm/s (transient contact).`
          : 'Reduced speed: the outer protective field is interrupted (a person is near).',
      );
    }
    if (sf.reduced_by.length === 0) reasons.push('Reduced speed (reason not reported).');
  }
  if (sf.fields?.inner === 'interrupted') reasons.push('The inner protective field is interrupted: the program may not run (rule 9).');
  let limit = sf.speed_limit;
  let by: SlowWhy['by'] = pflCap ? 'pfl' : sf.reduced ? 'reduced' : 'normal';
  if (sf.v_allowed !== null && sf.v_allowed !== undefined) {
    const sep = sf.separation_mm != null ? `${mm(sf.separation_mm)} mm` : 'unknown';
    if (sf.v_allowed <= 0) {
      reasons.push(`Speed and separation monitoring holds the robot: at a separation of ${sep}, v_allowed is 0 mm/s.`);
      limit = 0;
      by = 'ssm-hold';
    } else if (sf.v_allowed < sf.speed_limit) {
      reasons.push(`Speed and separation monitoring: at a separation of ${sep} the TCP may move at ${mm(sf.v_allowed)} mm/s.`);
      limit = sf.v_allowed;
      by = 'ssm';
    }
  }
  return { limit, by, reasons };
}

/** The contact force in words: "12.3 N of 140 N (F_qs)", or "off" when PFL does not act. */
export function contactWords(sf: CollabInput): string {
  if (!sf.pfl || sf.contact_force == null) return 'Collision detection off';
  const f = `${sf.contact_force.toFixed(1)} N`;
  return sf.contact_force_limit != null ? `${f} of ${mm(sf.contact_force_limit)} N (F_qs, COLLISION above)` : f;
}

// ------------------------------------------------------------------ brake test (SPEC §12)
/** The status' `safety.brake_test` (protocol.md's due_in_h and last, then the gateway's
 * additive fields; a gateway that predates them leaves them out). */
export interface BrakeTestInput {
  due_in_h: number | null;
  last: string; // none | passed | failed
  running?: boolean;
  axis?: number | null;
  progress?: number | null;
  due?: boolean;
  required?: boolean;
  last_time?: string | null;
  last_axis?: number | null;
  drift_deg?: number[] | null;
}

/** SPEC §12 defaults: the limit a test is held to when the configuration has no `brake_test` key. */
export const BRAKE_TEST_DEFAULT_MAX_DRIFT_DEG = 0.5;

/** max_drift_deg of the configuration's `brake_test` (SPEC §12), its default when absent or not a positive number. */
export function maxDriftDeg(brakeTestConfig: unknown): number {
  const v = (brakeTestConfig as { max_drift_deg?: unknown } | null | undefined)?.max_drift_deg;
  return typeof v === 'number' && Number.isFinite(v) && v > 0 ? v : BRAKE_TEST_DEFAULT_MAX_DRIFT_DEG;
}

/** Hours in words: "5.2 h", under one hour "45 min". */
export function hoursWords(hours: number): string {
  const a = Math.abs(hours);
  return a >= 1 ? `${a.toFixed(1)} h` : `${Math.round(a * 60)} min`;
}

export interface BrakeTestDue {
  /** 'ok' due in the future; 'overdue' past its interval; 'failed' the latest failed;
   * 'never' none passed and one is required; 'not-required' no periodic test configured. */
  tone: 'ok' | 'overdue' | 'failed' | 'never' | 'not-required';
  /** Shown large: "Due in 5.2 h", "Overdue by 1.5 h", "Failed: axis 3", "Never tested". */
  text: string;
  /** What it means for the operator. */
  detail: string;
}

/** When the next brake test is due, in words, from the status. Pure. */
export function brakeTestDue(bt: BrakeTestInput): BrakeTestDue {
  const auto = bt.required ? ' AUTO is refused (Servo on) until a test passes; T1 and T2 stay allowed.' : '';
  if (bt.last === 'failed') {
    const axis = bt.last_axis != null ? `axis ${bt.last_axis}` : 'axis not reported';
    return { tone: 'failed', text: `Failed: ${axis}`, detail: `The latest brake test failed.${auto || ' AUTO is refused until a test passes.'}` };
  }
  if (bt.due_in_h === null || bt.due_in_h === undefined) {
    if (bt.last === 'passed') {
      return { tone: 'not-required', text: 'Passed', detail: 'This configuration asks for no periodic brake test (no brake_test key).' };
    }
    if (bt.required || bt.due) {
      return { tone: 'never', text: 'Never tested', detail: `No brake test has passed yet.${auto}` };
    }
    return { tone: 'not-required', text: 'Never tested', detail: 'This configuration asks for no periodic brake test (no brake_test key).' };
  }
  if (bt.due_in_h > 0) {
    return { tone: 'ok', text: `Due in ${hoursWords(bt.due_in_h)}`, detail: 'The last test passed; run the next one before it is due.' };
  }
  return {
    tone: 'overdue',
    text: `Overdue by ${hoursWords(bt.due_in_h)}`,
    detail: bt.required ? `The grace time has run out.${auto}` : 'Run the brake test before the grace time runs out; after it AUTO is refused.',
  };
}

export interface BrakeTestGateInput {
  connected: boolean;
  role: 'pendant' | 'observer' | null;
  state: State | null;
  sub: string | null;
  mode: Mode | null;
  /** status.owner: who may command now (null: nobody). */
  owner: string | null;
  running: boolean;
}

/** SPEC §4/§12: `brake_test` in AUTO_IDLE or MANUAL_IDLE with a valid mode (at standstill:
 * the controller checks that, its reply says so); this screen sends it as the pendant, which
 * must hold control (status.owner). */
export function brakeTestGate(g: BrakeTestGateInput): Gate {
  const reasons: string[] = [];
  if (!g.connected || g.state === null) {
    return { enabled: false, reasons: ['Not connected to the controller.'] };
  }
  if (g.running) {
    return { enabled: false, reasons: ['The brake test is running.'] };
  }
  if (g.role !== 'pendant') {
    reasons.push('This screen is read-only (observer): only the pendant that has control may run the brake test.');
  } else if (g.owner !== 'pendant') {
    reasons.push(`The pendant does not have control now (${g.owner ? `${g.owner} has` : 'nobody has'}).`);
  }
  if (g.mode === 'NONE' || g.mode === null) {
    reasons.push('The mode selector gives no valid mode.');
  }
  if (g.state !== 'OPERATIONAL' || (g.sub !== 'AUTO_IDLE' && g.sub !== 'MANUAL_IDLE')) {
    reasons.push(`Only with the servos on and the robot idle (AUTO_IDLE or MANUAL_IDLE; now ${g.sub ?? g.state}).`);
  }
  return { enabled: reasons.length === 0, reasons };
}

export interface BrakeAxisRow {
  axis: number; // 1..6
  /** While running: done / testing / pending. Else, of the latest result: held / slipped /
   * untested (after a slip, or none on record). */
  phase: 'done' | 'testing' | 'pending' | 'held' | 'slipped' | 'untested';
  /** The drift of the latest result (degrees), null while running or when none. */
  drift: number | null;
  /** drift / max_drift_deg, clamped to 0..1 (for a bar), 0 when none. */
  frac: number;
}

/** The six axes of the brake test: progress while it runs, else the latest result's drift. Pure. */
export function brakeTestAxes(bt: BrakeTestInput, maxDrift: number): BrakeAxisRow[] {
  const rows: BrakeAxisRow[] = [];
  const drift = Array.isArray(bt.drift_deg) && bt.drift_deg.length === 6 ? bt.drift_deg : null;
  // After a failure the axes before the slipped one held and those after it were not tested
  // (an axis not reported: none counts as held).
  const failed = bt.last === 'failed' ? (bt.last_axis ?? 0) : null;
  for (let axis = 1; axis <= 6; axis++) {
    if (bt.running) {
      const at = bt.axis ?? 0;
      rows.push({ axis, phase: axis < at ? 'done' : axis === at ? 'testing' : 'pending', drift: null, frac: 0 });
      continue;
    }
    let phase: BrakeAxisRow['phase'] = 'untested';
    if (drift && failed === null) phase = 'held';
    else if (drift && failed !== null) phase = axis < failed ? 'held' : axis === failed ? 'slipped' : 'untested';
    const d = drift && phase !== 'untested' ? drift[axis - 1] : null;
    rows.push({ axis, phase, drift: d, frac: d !== null && maxDrift > 0 ? Math.min(1, Math.max(0, d / maxDrift)) : 0 });
  }
  return rows;
}

/** Hours since the last passed test: interval_h − due_in_h (the status counts due_in_h from
 * the last pass also after a failure); null when either is unknown. */
export function lastPassAgeH(bt: BrakeTestInput, intervalH: unknown): number | null {
  if (bt.due_in_h === null || bt.due_in_h === undefined || typeof intervalH !== 'number' || !Number.isFinite(intervalH)) return null;
  return Math.max(0, intervalH - bt.due_in_h);
}

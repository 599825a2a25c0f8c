// The simulated person (SPEC §11, issue 20 item 5; docs/collaborative.md "The simulated
// person"): the `sim` message's person forms the panel sends, checked here before anything
// is sent, the floor drawing taken from the status, and the words the pages show. Pure (no
// DOM), unit-tested in tests/person.test.mjs.
import type { SimPerson, Status } from './api';

/** The `person` of a `sim` message (an extension of protocol.md's `sim`, gateway/src/protocol.cpp). */
export type PersonMessage =
  | 'stand'
  | 'leave'
  | { at?: [number, number]; radius_mm?: number; walk?: number[][]; fields?: [number, number] };

/** The limits of the gateway and the scenario's `person` keys (sim/person.hpp). */
export const PERSON_MAX_SPEED = 2000; // mm/s, ISO 13855's fastest approach
export const PERSON_MAX_RANGE = 20000; // mm, |x| and |y|
/** Walk in from FROM to TO (mm from the robot's base axis). */
export const WALK_FROM_MM = 3000;
export const WALK_TO_MM = 800;

/** A point `r` mm from the base axis at `deg` (0 = +x, 90 = +y), whole millimetres. */
export function along(deg: number, r: number): [number, number] {
  const a = (deg * Math.PI) / 180;
  return [Math.round(r * Math.cos(a)) + 0, Math.round(r * Math.sin(a)) + 0] as [number, number]; // + 0: no -0
}

/** A walking speed typed by the operator (mm/s): the number, or why it is refused. */
export function parseSpeed(text: string): number | string {
  const v = Number(text);
  if (text.trim() === '' || !Number.isFinite(v)) return `"${text}" is not a speed: a number of mm/s.`;
  if (v <= 0) return `${v} mm/s is not above 0 (Stand stops the person).`;
  if (v > PERSON_MAX_SPEED) return `${v} mm/s is over ${PERSON_MAX_SPEED} (ISO 13855's fastest approach).`;
  return v;
}

/** Field radii typed by the operator (mm): [outer, inner], or why they are refused. */
export function parseFields(outerText: string, innerText: string): [number, number] | string {
  const o = Number(outerText);
  const i = Number(innerText);
  if (outerText.trim() === '' || innerText.trim() === '' || !Number.isFinite(o) || !Number.isFinite(i)) {
    return 'The field radii are numbers of mm.';
  }
  if (!(i > 0 && i < o && o <= PERSON_MAX_RANGE)) return `Outer ${o} / inner ${i} mm: needs 0 < inner < outer ≤ ${PERSON_MAX_RANGE} mm.`;
  return [o, i];
}

/** Walk in along `deg` to WALK_TO_MM at `speed`: entering at WALK_FROM_MM when nobody is in the cell. */
export function walkIn(deg: number, speed: number, present: boolean): PersonMessage {
  const walk = [[...along(deg, WALK_TO_MM), speed]];
  return present ? { walk } : { at: along(deg, WALK_FROM_MM), walk };
}

/** The person's bearing from the base axis (degrees, 0 = +x); `fallback` when it stands on the axis. */
export function bearing(p: SimPerson | null | undefined, fallback: number): number {
  if (!p || Math.hypot(p.x_mm, p.y_mm) < 1) return fallback;
  return (Math.atan2(p.y_mm, p.x_mm) * 180) / Math.PI;
}

/** Walk out from where the person is, straight away from the base axis, to WALK_FROM_MM. */
export function walkOut(p: SimPerson | null | undefined, fallbackDeg: number, speed: number): PersonMessage {
  return { walk: [[...along(bearing(p, fallbackDeg), WALK_FROM_MM), speed]] };
}

/** What the 3D view draws on the floor. */
export interface PersonDrawing {
  person: SimPerson | null;
  outer_mm: number;
  inner_mm: number;
  /** As the core validated them (status.safety.fields), else as the scanner sees the person. */
  outerInterrupted: boolean;
  innerInterrupted: boolean;
}

export function personDrawing(s: Status | null): PersonDrawing | null {
  const sim = s?.sim;
  if (!sim) return null;
  const f = s?.safety?.fields;
  return {
    person: sim.person,
    outer_mm: sim.person_fields.outer_mm,
    inner_mm: sim.person_fields.inner_mm,
    outerInterrupted: f ? f.outer === 'interrupted' : !!sim.person?.in_outer,
    innerInterrupted: f ? f.inner === 'interrupted' : !!sim.person?.in_inner,
  };
}

const m = (mm: number) => `${(mm / 1000).toFixed(2)} m`;

/** The person in one line: where, how fast, what the devices see. */
export function personWords(s: Status | null): string {
  const sim = s?.sim;
  if (!sim) return '';
  const p = sim.person;
  if (!p) return 'Simulated person: not in the cell (the panel\'s field and separation inputs apply).';
  const moving = p.walking ? `walking at ${(p.speed_mm_s / 1000).toFixed(1)} m/s` : 'standing';
  const where = `${m(Math.hypot(p.x_mm, p.y_mm))} from the base axis`;
  const fields = p.in_inner ? 'in the inner field' : p.in_outer ? 'in the outer field' : 'outside both fields';
  return `Simulated person: ${moving}, ${where}, ${fields}; separation ${m(p.separation_mm)}.`;
}

// The URDF's <visual> elements (issue 38 item 6), for drawing the arm as its description
// shows it: each visual placed in the frame of the chain link it rides on (the base link or
// the link joint k moves), through the fixed joints between (a moving joint off the chain,
// e.g. a gripper's finger, at zero, as `safestate robot fk` places it). Parsed here from the
// URDF text /api/robot serves (DOMParser); the core's own model is not read from this.
import type { Mat3, Vec3 } from './kinematics';

export type VisualGeometry =
  | { type: 'mesh'; uri: string; scale: Vec3 }
  | { type: 'box'; size: Vec3 } // m
  | { type: 'cylinder'; radius: number; length: number } // m, along z
  | { type: 'sphere'; radius: number };

export interface Visual {
  link: string;
  /** 0: the base link's frame; k = 1..6: joint k's (the link it moves). */
  frame: number;
  /** The visual's pose in that frame: position in mm, rotation as rows. */
  p: Vec3;
  R: Mat3;
  geometry: VisualGeometry;
  /** The URDF's colour (rgba 0..1), when the visual names one with a colour. */
  rgba: [number, number, number, number] | null;
}

interface Frame {
  p: Vec3; // mm
  R: Mat3;
}

const nums = (s: string | null, n: number, dflt: number): number[] | null => {
  if (s === null || s.trim() === '') return new Array(n).fill(dflt);
  const v = s.trim().split(/\s+/).map(Number);
  return v.length === n && v.every(Number.isFinite) ? v : null;
};

/** URDF rpy (fixed axes x, y, z): R = Rz(y) Ry(p) Rx(r). */
function rpyMatrix(r: number, p: number, y: number): Mat3 {
  const [cr, sr, cp, sp, cy, sy] = [Math.cos(r), Math.sin(r), Math.cos(p), Math.sin(p), Math.cos(y), Math.sin(y)];
  return [
    [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
    [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
    [-sp, cp * sr, cp * cr],
  ];
}

function originOf(el: Element | null): Frame | null {
  const o = el?.querySelector(':scope > origin') ?? null;
  const xyz = nums(o?.getAttribute('xyz') ?? null, 3, 0);
  const rpy = nums(o?.getAttribute('rpy') ?? null, 3, 0);
  if (!xyz || !rpy) return null;
  return { p: [xyz[0] * 1000, xyz[1] * 1000, xyz[2] * 1000], R: rpyMatrix(rpy[0], rpy[1], rpy[2]) };
}

const mulMV = (R: Mat3, v: Vec3): Vec3 => [
  R[0][0] * v[0] + R[0][1] * v[1] + R[0][2] * v[2],
  R[1][0] * v[0] + R[1][1] * v[1] + R[1][2] * v[2],
  R[2][0] * v[0] + R[2][1] * v[1] + R[2][2] * v[2],
];
const mulMM = (A: Mat3, B: Mat3): Mat3 =>
  [0, 1, 2].map((r) => [0, 1, 2].map((c) => A[r][0] * B[0][c] + A[r][1] * B[1][c] + A[r][2] * B[2][c])) as Mat3;
/** a ∘ b: b given in a's frame. */
const compose = (a: Frame, b: Frame): Frame => {
  const q = mulMV(a.R, b.p);
  return { p: [a.p[0] + q[0], a.p[1] + q[1], a.p[2] + q[2]], R: mulMM(a.R, b.R) };
};

function geometryOf(v: Element): VisualGeometry | null {
  const g = v.querySelector(':scope > geometry');
  if (!g) return null;
  const mesh = g.querySelector(':scope > mesh');
  if (mesh) {
    const uri = mesh.getAttribute('filename');
    const scale = nums(mesh.getAttribute('scale'), 3, 1);
    return uri && scale ? { type: 'mesh', uri, scale: scale as Vec3 } : null;
  }
  const box = g.querySelector(':scope > box');
  if (box) {
    const size = nums(box.getAttribute('size'), 3, NaN);
    return size && size.every((x) => x > 0) ? { type: 'box', size: size as Vec3 } : null;
  }
  const cyl = g.querySelector(':scope > cylinder');
  if (cyl) {
    const radius = Number(cyl.getAttribute('radius'));
    const length = Number(cyl.getAttribute('length'));
    return radius > 0 && length > 0 ? { type: 'cylinder', radius, length } : null;
  }
  const sph = g.querySelector(':scope > sphere');
  if (sph) {
    const radius = Number(sph.getAttribute('radius'));
    return radius > 0 ? { type: 'sphere', radius } : null;
  }
  return null;
}

function colourOf(v: Element, named: Map<string, [number, number, number, number]>): Visual['rgba'] {
  const m = v.querySelector(':scope > material');
  if (!m) return null;
  const c = nums(m.querySelector(':scope > color')?.getAttribute('rgba') ?? null, 4, NaN);
  if (c && c.every((x) => x >= 0 && x <= 1)) return c as [number, number, number, number];
  return named.get(m.getAttribute('name') ?? '') ?? null;
}

/**
 * The visuals of the links at or below the base, each in its chain frame; null when the
 * text is not a URDF with a <robot> root. `chainLinks[k]` is the link joint k+1 moves.
 */
export function urdfVisuals(urdf: string, base: string, chainLinks: string[]): Visual[] | null {
  const doc = new DOMParser().parseFromString(urdf, 'application/xml');
  const robot = doc.documentElement;
  if (!robot || robot.nodeName !== 'robot' || doc.querySelector('parsererror')) return null;
  const named = new Map<string, [number, number, number, number]>();
  for (const m of Array.from(robot.querySelectorAll(':scope > material'))) {
    const c = nums(m.querySelector(':scope > color')?.getAttribute('rgba') ?? null, 4, NaN);
    if (c) named.set(m.getAttribute('name') ?? '', c as [number, number, number, number]);
  }
  // child link -> (parent link, the joint's origin)
  const parentOf = new Map<string, { parent: string; origin: Frame }>();
  for (const j of Array.from(robot.querySelectorAll(':scope > joint'))) {
    const child = j.querySelector(':scope > child')?.getAttribute('link');
    const parent = j.querySelector(':scope > parent')?.getAttribute('link');
    const origin = originOf(j);
    if (child && parent && origin) parentOf.set(child, { parent, origin });
  }
  const frameOf = new Map<string, number>([[base, 0]]);
  chainLinks.forEach((l, k) => frameOf.set(l, k + 1));
  const out: Visual[] = [];
  for (const link of Array.from(robot.querySelectorAll(':scope > link'))) {
    const name = link.getAttribute('name') ?? '';
    // Up through the joints to a chain link or the base (at most as many steps as joints).
    let T: Frame = { p: [0, 0, 0], R: [[1, 0, 0], [0, 1, 0], [0, 0, 1]] };
    let at = name;
    let steps = 0;
    while (!frameOf.has(at) && steps++ <= parentOf.size) {
      const up = parentOf.get(at);
      if (!up) break;
      T = compose(up.origin, T);
      at = up.parent;
    }
    const frame = frameOf.get(at);
    if (frame === undefined) continue; // above the base or not connected to it: not drawn
    for (const v of Array.from(link.querySelectorAll(':scope > visual'))) {
      const geometry = geometryOf(v);
      const o = originOf(v);
      if (!geometry || !o) continue;
      const pose = compose(T, o);
      out.push({ link: name, frame, p: pose.p, R: pose.R, geometry, rgba: colourOf(v, named) });
    }
  }
  return out;
}

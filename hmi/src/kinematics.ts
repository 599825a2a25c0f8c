// Forward kinematics of the arm from /api/robot, built as the motion layer builds it
// (motion/src/kinematics.cpp `forward()`, docs/robot.md): a chain of six joints from the
// robot's URDF, joint k's frame placed at `origin` turned by `rotation` in joint k-1's frame,
// then turned by q_k about its `axis`; the flange fixed in joint 6's frame;
// TCP = p_flange + R_flange · tcp_offset. So the drawn TCP is the one in status.tcp.
import type { ChainJoint, FixedFrame } from './api';

export type Vec3 = [number, number, number];
export type Mat3 = [Vec3, Vec3, Vec3]; // rows

export interface Frames {
  origin: Vec3[]; // origin[k] = joint k+1's origin (k = 0..5), origin[6] = the flange
  z: Vec3[]; // z[k]: the axis joint k+1 turns about; z[6]: the flange's z
  x: Vec3[]; // x[k]: x axis of joint k+1's frame (at its zero); x[6]: the flange's x
  R: Mat3; // rotation of the flange
  tcp: Vec3;
}

const IDENTITY: Mat3 = [
  [1, 0, 0],
  [0, 1, 0],
  [0, 0, 1],
];

function mulMV(R: Mat3, v: Vec3): Vec3 {
  return [
    R[0][0] * v[0] + R[0][1] * v[1] + R[0][2] * v[2],
    R[1][0] * v[0] + R[1][1] * v[1] + R[1][2] * v[2],
    R[2][0] * v[0] + R[2][1] * v[1] + R[2][2] * v[2],
  ];
}

function mulMM(A: Mat3, B: Mat3): Mat3 {
  const C: Mat3 = [
    [0, 0, 0],
    [0, 0, 0],
    [0, 0, 0],
  ];
  for (let r = 0; r < 3; r++) {
    for (let c = 0; c < 3; c++) {
      C[r][c] = A[r][0] * B[0][c] + A[r][1] * B[1][c] + A[r][2] * B[2][c];
    }
  }
  return C;
}

const column = (R: Mat3, c: number): Vec3 => [R[0][c], R[1][c], R[2][c]];
const add = (a: Vec3, b: Vec3): Vec3 => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];

/** The turn of a joint about its unit axis u: R = I + sin q K + (1 - cos q) K². */
export function axisTurn(u: Vec3, q: number): Mat3 {
  const s = Math.sin(q);
  const v = 1 - Math.cos(q);
  const K: Mat3 = [
    [0, -u[2], u[1]],
    [u[2], 0, -u[0]],
    [-u[1], u[0], 0],
  ];
  const K2 = mulMM(K, K);
  const R: Mat3 = [
    [0, 0, 0],
    [0, 0, 0],
    [0, 0, 0],
  ];
  for (let r = 0; r < 3; r++) {
    for (let c = 0; c < 3; c++) {
      R[r][c] = (r === c ? 1 : 0) + s * K[r][c] + v * K2[r][c];
    }
  }
  return R;
}

/**
 * Frames of the chain at q: origin[k] (k = 0..5) is joint k+1's origin (on its axis), z[k]
 * its axis; origin[6] the flange, z[6] and x[6] its axes.
 */
export function forward(
  joints: ChainJoint[],
  flange: FixedFrame,
  q: number[],
  tcpOffset: Vec3 = [0, 0, 0],
): Frames {
  let p: Vec3 = [0, 0, 0];
  let R: Mat3 = IDENTITY;
  const origin: Vec3[] = [];
  const z: Vec3[] = [];
  const x: Vec3[] = [];
  for (let k = 0; k < joints.length; k++) {
    const j = joints[k];
    p = add(p, mulMV(R, j.origin));
    R = mulMM(R, j.rotation);
    origin.push(p);
    z.push(mulMV(R, j.axis));
    x.push(column(R, 0));
    R = mulMM(R, axisTurn(j.axis, q[k] ?? 0));
  }
  p = add(p, mulMV(R, flange.origin));
  R = mulMM(R, flange.rotation);
  origin.push(p);
  z.push(column(R, 2));
  x.push(column(R, 0));
  return { origin, z, x, R, tcp: add(p, mulMV(R, tcpOffset)) };
}

/** A frame of the arm: position (mm) and rotation (rows) in the base frame. */
export interface Pose {
  p: Vec3;
  R: Mat3;
}

/**
 * The link frames at q: [0] the base link's (identity), [k] (k = 1..6) joint k's frame turned
 * by q_k, i.e. the frame of the link joint k moves (URDF: the child link's frame). The URDF's
 * visuals of each link are placed in these (urdf-visuals.ts).
 */
export function linkPoses(joints: ChainJoint[], q: number[]): Pose[] {
  let p: Vec3 = [0, 0, 0];
  let R: Mat3 = IDENTITY;
  const out: Pose[] = [{ p, R }];
  for (let k = 0; k < joints.length; k++) {
    const j = joints[k];
    p = add(p, mulMV(R, j.origin));
    R = mulMM(mulMM(R, j.rotation), axisTurn(j.axis, q[k] ?? 0));
    out.push({ p, R });
  }
  return out;
}

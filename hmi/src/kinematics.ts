// Forward kinematics of the arm from /api/robot, built exactly as the core builds it
// (motion/src/kinematics.cpp `forward()`, docs/robot.md): standard DH,
// A_k = Rot_z(q_k + θ_offset,k) · Trans_z(d_k) · Trans_x(a_k) · Rot_x(α_k), T_0k = A_1 ⋯ A_k,
// TCP = p_6 + R_6 · tcp_offset. So the drawn TCP is the one in status.tcp.
import type { DhRow } from './api';

export type Vec3 = [number, number, number];
export type Mat3 = [Vec3, Vec3, Vec3]; // rows

export interface Frames {
  origin: Vec3[]; // origin[0] = base, origin[k] = origin of DH frame k (k = 1..6)
  z: Vec3[]; // z[k]: z axis of frame k (joint k+1 turns about it)
  x: Vec3[]; // x[k]: x axis of frame k
  R: Mat3; // rotation of frame 6
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

/** One standard-DH link transform A_k (kinematics.cpp `dh_link`). */
export function dhLink(row: DhRow, q: number): { p: Vec3; R: Mat3 } {
  const th = q + row.theta_offset;
  const ct = Math.cos(th);
  const st = Math.sin(th);
  const ca = Math.cos(row.alpha);
  const sa = Math.sin(row.alpha);
  return {
    p: [row.a * ct, row.a * st, row.d],
    R: [
      [ct, -st * ca, st * sa],
      [st, ct * ca, -ct * sa],
      [0, sa, ca],
    ],
  };
}

export function forward(dh: DhRow[], q: number[], tcpOffset: Vec3 = [0, 0, 0]): Frames {
  let p: Vec3 = [0, 0, 0];
  let R: Mat3 = IDENTITY;
  const origin: Vec3[] = [p];
  const z: Vec3[] = [column(R, 2)];
  const x: Vec3[] = [column(R, 0)];
  for (let k = 0; k < dh.length; k++) {
    const A = dhLink(dh[k], q[k] ?? 0);
    p = add(p, mulMV(R, A.p));
    R = mulMM(R, A.R);
    origin.push(p);
    z.push(column(R, 2));
    x.push(column(R, 0));
  }
  return { origin, z, x, R, tcp: add(p, mulMV(R, tcpOffset)) };
}

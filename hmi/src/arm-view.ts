// The arm in 3D (three.js), drawn from /api/robot and the live joint positions with the
// same forward kinematics as the core (kinematics.ts), so the drawn TCP is status.tcp.
// Without WebGL a flat 2D drawing of the same frames stands in.
// The drawn joint angles and TCP are exposed for tests and diagnostics on the container
// (data-joints, data-tcp) and as window.safestateHmi.view.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import type { Robot } from './api';
import { forward, type Frames, type Vec3 } from './kinematics';

export interface ArmDrawing {
  update(joints: number[]): void;
  highlight(axis: number | null): void;
  clearTrail(): void;
  readonly kind: 'webgl' | '2d';
}

const TRAIL_POINTS = 800;

function exposeDrawn(container: HTMLElement, joints: number[], f: Frames): void {
  const j = joints.map((q) => Math.round(q * 1e6) / 1e6);
  const tcp = f.tcp.map((v) => Math.round(v * 1000) / 1000);
  container.dataset.joints = JSON.stringify(j);
  container.dataset.tcp = JSON.stringify(tcp);
  const w = window as unknown as { safestateHmi?: Record<string, unknown> };
  w.safestateHmi ??= {};
  w.safestateHmi.view = { joints: j, tcp, origins: f.origin };
}

class Trail {
  readonly pts: Vec3[] = [];
  push(p: Vec3): boolean {
    const last = this.pts[this.pts.length - 1];
    if (last && Math.hypot(p[0] - last[0], p[1] - last[1], p[2] - last[2]) < 0.5) return false;
    this.pts.push(p);
    if (this.pts.length > TRAIL_POINTS) this.pts.shift();
    return true;
  }
  clear(): void {
    this.pts.length = 0;
  }
}

// ------------------------------------------------------------------------- WebGL
const UP = new THREE.Vector3(0, 1, 0);
const v3 = (p: Vec3) => new THREE.Vector3(p[0], p[1], p[2]);

class WebGlArm implements ArmDrawing {
  readonly kind = 'webgl' as const;
  private renderer: THREE.WebGLRenderer;
  private scene = new THREE.Scene();
  private camera = new THREE.PerspectiveCamera(38, 1, 10, 20000);
  private controls: OrbitControls;
  private links: THREE.Mesh[] = [];
  private housings: THREE.Mesh[] = [];
  private housingMat: THREE.MeshStandardMaterial;
  private hotMat: THREE.MeshStandardMaterial;
  private flange: THREE.Mesh;
  private tcpMark: THREE.Group;
  private trailGeom = new THREE.BufferGeometry();
  private trail = new Trail();
  private frame = 0;
  private lastRender = 0;
  private hot: number | null = null;
  /** Software GL (SwiftShader, llvmpipe) costs CPU that the jog keep-alive needs: fewer frames. */
  readonly software: boolean;
  private minFrameMs: number;

  constructor(
    private readonly container: HTMLElement,
    private readonly robot: Robot,
  ) {
    this.renderer = new THREE.WebGLRenderer({ antialias: false, powerPreference: 'low-power' });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    container.append(this.renderer.domElement);
    const gl = this.renderer.getContext();
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    const name = String(info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER));
    this.software = /swiftshader|llvmpipe|software|softpipe/i.test(name);
    this.minFrameMs = this.software ? 80 : 0;
    container.dataset.gl = name;
    this.scene.background = new THREE.Color(0x10151b);

    this.scene.add(new THREE.HemisphereLight(0xdde6f0, 0x1a1f26, 1.4));
    const sun = new THREE.DirectionalLight(0xffffff, 2.0);
    sun.position.set(800, 1600, 1000);
    this.scene.add(sun);

    const grid = new THREE.GridHelper(1600, 16, 0x3d4a5a, 0x25303c);
    this.scene.add(grid);

    // Robot coordinates (mm, z up) inside a group turned so that z is three.js's y.
    const root = new THREE.Group();
    root.rotation.x = -Math.PI / 2;
    this.scene.add(root);

    const reach = new THREE.Mesh(
      new THREE.RingGeometry(robot.reach - 3, robot.reach + 3, 96),
      new THREE.MeshBasicMaterial({ color: 0x2f6f8f, transparent: true, opacity: 0.5, side: THREE.DoubleSide }),
    );
    reach.position.z = 1;
    root.add(reach);

    const linkMat = new THREE.MeshStandardMaterial({ color: 0xe4e8ee, roughness: 0.55, metalness: 0.05 });
    this.housingMat = new THREE.MeshStandardMaterial({ color: 0x56616f, roughness: 0.5, metalness: 0.2 });
    this.hotMat = new THREE.MeshStandardMaterial({ color: 0x29b6f6, roughness: 0.4, emissive: 0x0b3c55 });
    const baseMat = new THREE.MeshStandardMaterial({ color: 0x39424e, roughness: 0.7 });

    const base = new THREE.Mesh(new THREE.CylinderGeometry(110, 125, 110, 48), baseMat);
    base.rotation.x = Math.PI / 2;
    base.position.z = 55;
    root.add(base);

    const unitCyl = (r: number, mat: THREE.Material) => {
      const m = new THREE.Mesh(new THREE.CylinderGeometry(r, r, 1, 32), mat);
      root.add(m);
      return m;
    };
    // Segments between consecutive frame origins (base→1, 1→2, 2→3, 3→4, 4→5, 5→6).
    for (const r of [62, 44, 42, 36, 30, 28]) this.links.push(unitCyl(r, linkMat));
    // Joint housings: joint k+1 turns about z_k through origin k.
    const housing: [number, number][] = [
      [84, 60],
      [62, 150],
      [52, 124],
      [42, 64],
      [36, 86],
      [30, 40],
    ];
    for (const [r, len] of housing) {
      const m = new THREE.Mesh(new THREE.CylinderGeometry(r, r, len, 36), this.housingMat);
      root.add(m);
      this.housings.push(m);
    }
    this.flange = new THREE.Mesh(new THREE.CylinderGeometry(36, 36, 10, 32), this.housingMat);
    root.add(this.flange);

    this.tcpMark = new THREE.Group();
    this.tcpMark.add(new THREE.Mesh(new THREE.SphereGeometry(11, 20, 14), new THREE.MeshBasicMaterial({ color: 0x4dd0e1 })));
    this.tcpMark.add(new THREE.AxesHelper(90));
    root.add(this.tcpMark);

    this.trailGeom.setAttribute('position', new THREE.BufferAttribute(new Float32Array(TRAIL_POINTS * 3), 3));
    this.trailGeom.setAttribute('color', new THREE.BufferAttribute(new Float32Array(TRAIL_POINTS * 3), 3));
    this.trailGeom.setDrawRange(0, 0);
    root.add(new THREE.Line(this.trailGeom, new THREE.LineBasicMaterial({ vertexColors: true })));

    root.add(new THREE.AxesHelper(220));

    // Camera in front of the arm, a little to its right (robot frame: x forward, z up).
    this.camera.position.set(1300, 820, 900);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.target.set(140, 300, 0);
    this.controls.enableDamping = false;
    this.controls.addEventListener('change', () => this.requestRender());
    this.controls.update();

    // Compile every shader now: a compile on the first motion (the trail's first segment,
    // the highlighted housing) would block the page just when a jog's keep-alive must go.
    this.housings[1].material = this.hotMat;
    this.renderer.compile(this.scene, this.camera);
    this.housings[1].material = this.housingMat;

    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  private resize(): void {
    const w = Math.max(1, this.container.clientWidth);
    const h = Math.max(1, this.container.clientHeight);
    this.renderer.setSize(w, h, false);
    this.renderer.domElement.style.width = '100%';
    this.renderer.domElement.style.height = '100%';
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  private requestRender(): void {
    if (this.frame) return;
    const wait = this.lastRender + this.minFrameMs - performance.now();
    const draw = () => {
      this.frame = requestAnimationFrame(() => {
        this.frame = 0;
        this.lastRender = performance.now();
        this.renderer.render(this.scene, this.camera);
      });
    };
    if (wait > 0) {
      this.frame = window.setTimeout(() => {
        this.frame = 0;
        draw();
      }, wait);
    } else {
      draw();
    }
  }

  private static segment(m: THREE.Mesh, a: Vec3, b: Vec3): void {
    const va = v3(a);
    const dir = v3(b).sub(va);
    const len = dir.length();
    m.visible = len > 1;
    if (!m.visible) return;
    m.position.copy(va.addScaledVector(dir, 0.5));
    m.quaternion.setFromUnitVectors(UP, dir.normalize());
    m.scale.set(1, len, 1);
  }

  update(joints: number[]): void {
    const f = forward(this.robot.dh, joints, this.robot.tcp_offset as Vec3);
    for (let k = 0; k < 6; k++) WebGlArm.segment(this.links[k], f.origin[k], f.origin[k + 1]);
    for (let k = 0; k < 6; k++) {
      const m = this.housings[k];
      m.position.copy(v3(f.origin[k]));
      m.quaternion.setFromUnitVectors(UP, v3(f.z[k]));
    }
    // The base housing sits on the base plate, turning with axis 1.
    this.housings[0].position.set(0, 0, 140);
    this.flange.position.copy(v3(f.origin[6]));
    this.flange.quaternion.setFromUnitVectors(UP, v3(f.z[6]));

    const R = f.R;
    const m4 = new THREE.Matrix4().set(
      R[0][0], R[0][1], R[0][2], f.tcp[0],
      R[1][0], R[1][1], R[1][2], f.tcp[1],
      R[2][0], R[2][1], R[2][2], f.tcp[2],
      0, 0, 0, 1,
    );
    this.tcpMark.matrixAutoUpdate = false;
    this.tcpMark.matrix.copy(m4);

    if (this.trail.push(f.tcp)) this.writeTrail();
    exposeDrawn(this.container, joints, f);
    this.requestRender();
  }

  private writeTrail(): void {
    const pos = this.trailGeom.getAttribute('position') as THREE.BufferAttribute;
    const col = this.trailGeom.getAttribute('color') as THREE.BufferAttribute;
    const n = this.trail.pts.length;
    this.trail.pts.forEach((p, i) => {
      pos.setXYZ(i, p[0], p[1], p[2]);
      const a = 0.15 + 0.85 * (i / Math.max(1, n - 1)); // older points fade
      col.setXYZ(i, 0.3 * a, 0.82 * a, 0.88 * a);
    });
    pos.needsUpdate = true;
    col.needsUpdate = true;
    this.trailGeom.setDrawRange(0, n);
  }

  highlight(axis: number | null): void {
    if (axis === this.hot) return;
    this.hot = axis;
    this.housings.forEach((m, k) => (m.material = k + 1 === axis ? this.hotMat : this.housingMat));
    this.requestRender();
  }

  clearTrail(): void {
    this.trail.clear();
    this.writeTrail();
    this.requestRender();
  }
}

// ------------------------------------------------------------------------- 2D fallback
class FlatArm implements ArmDrawing {
  readonly kind = '2d' as const;
  private canvas = document.createElement('canvas');
  private trail = new Trail();
  private last: Frames | null = null;
  private hot: number | null = null;

  constructor(
    private readonly container: HTMLElement,
    private readonly robot: Robot,
  ) {
    container.append(this.canvas);
    this.canvas.style.width = '100%';
    this.canvas.style.height = '100%';
    new ResizeObserver(() => this.draw()).observe(container);
  }

  update(joints: number[]): void {
    this.last = forward(this.robot.dh, joints, this.robot.tcp_offset as Vec3);
    this.trail.push(this.last.tcp);
    exposeDrawn(this.container, joints, this.last);
    this.draw();
  }

  highlight(axis: number | null): void {
    this.hot = axis;
    this.draw();
  }

  clearTrail(): void {
    this.trail.clear();
    this.draw();
  }

  private draw(): void {
    const c = this.canvas;
    const w = (c.width = this.container.clientWidth);
    const h = (c.height = this.container.clientHeight);
    const g = c.getContext('2d');
    if (!g || !this.last) return;
    const s = Math.min(w, h) / 1500;
    // Isometric projection of robot coordinates (x forward, y left, z up).
    const P = (p: Vec3): [number, number] => [
      w * 0.4 + (p[0] * 0.87 - p[1] * 0.87) * s,
      h * 0.8 - (p[2] + (p[0] + p[1]) * 0.5 * 0.5) * s,
    ];
    g.fillStyle = '#10151b';
    g.fillRect(0, 0, w, h);
    g.strokeStyle = '#4dd0e1';
    g.lineWidth = 2;
    g.beginPath();
    this.trail.pts.forEach((p, i) => (i ? g.lineTo(...P(p)) : g.moveTo(...P(p))));
    g.stroke();
    g.lineCap = 'round';
    const o = this.last.origin;
    for (let k = 0; k < 6; k++) {
      g.strokeStyle = '#e4e8ee';
      g.lineWidth = Math.max(4, 60 * s);
      g.beginPath();
      g.moveTo(...P(o[k]));
      g.lineTo(...P(o[k + 1]));
      g.stroke();
      g.fillStyle = k + 1 === this.hot ? '#29b6f6' : '#56616f';
      g.beginPath();
      g.arc(...P(o[k]), Math.max(5, 45 * s), 0, 2 * Math.PI);
      g.fill();
    }
    g.fillStyle = '#4dd0e1';
    g.beginPath();
    g.arc(...P(this.last.tcp), 6, 0, 2 * Math.PI);
    g.fill();
    g.fillStyle = '#9aa7b5';
    g.font = '12px sans-serif';
    g.fillText('2D view (WebGL unavailable)', 10, h - 10);
  }
}

export function createArmView(container: HTMLElement, robot: Robot): ArmDrawing {
  if (new URLSearchParams(location.search).get('view') === '2d') return new FlatArm(container, robot);
  try {
    return new WebGlArm(container, robot);
  } catch (e) {
    console.warn('WebGL unavailable, drawing the arm in 2D:', e);
    container.replaceChildren();
    return new FlatArm(container, robot);
  }
}

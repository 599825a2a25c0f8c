// The arm in 3D (three.js), drawn from /api/robot and the live joint positions with the
// same forward kinematics as the core (kinematics.ts), so the drawn TCP is status.tcp.
// Without WebGL a flat 2D drawing of the same frames stands in.
// The drawn joint angles and TCP are exposed for tests and diagnostics on the container
// (data-joints, data-tcp) and as window.safestateHmi.view.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { ColladaLoader } from 'three/addons/loaders/ColladaLoader.js';
import { OBJLoader } from 'three/addons/loaders/OBJLoader.js';
import { STLLoader } from 'three/addons/loaders/STLLoader.js';
import { authHeaders, type Robot, type SafetyZone } from './api';
import { forward, linkPoses, type Frames, type Vec3 } from './kinematics';
import { urdfVisuals, type Visual } from './urdf-visuals';
import type { PersonDrawing } from './person';
import { ZONE_STYLE } from './safety-logic';

/** The zones and the tool of the safety configuration (SPEC §10), as drawn. */
export interface SafetyDrawing {
  zones: SafetyZone[];
  /** The tool's TCP in the flange frame (mm): the TCP the core supervises. */
  tcp_mm: Vec3;
  radius_mm: number;
}

/** What is violated or active now (indices into zones). */
export interface ZoneMarks {
  violated: number[];
  active: number[];
}

export interface ArmDrawing {
  update(joints: number[]): void;
  highlight(axis: number | null): void;
  clearTrail(): void;
  setSafety(s: SafetyDrawing | null): void;
  markZones(m: ZoneMarks): void;
  /** SPEC §11: the simulated person and the scanner's two fields on the floor (null: none). */
  setPerson(d: PersonDrawing | null): void;
  readonly kind: 'webgl' | '2d';
}

interface DrawnZone {
  name: string;
  kind: string;
  violated: boolean;
  active: boolean;
}

/** The zones as drawn, for tests and diagnostics (window.safestateHmi.zones and #arm's
 * data-zones / data-zones-violated): the WebGL view reads them back from its meshes. */
function exposeZones(container: HTMLElement, list: DrawnZone[]): void {
  container.dataset.zones = String(list.length);
  container.dataset.zonesViolated = list.filter((z) => z.violated).map((z) => z.name).join(',');
  const w = window as unknown as { safestateHmi?: Record<string, unknown> };
  w.safestateHmi ??= {};
  w.safestateHmi.zones = list;
}

const VIOLATED_HEX = 0xff1744;

const flatZones = (zones: SafetyZone[], marks: ZoneMarks): DrawnZone[] =>
  zones.map((z, i) => ({ name: z.name, kind: z.kind, violated: marks.violated.includes(i), active: marks.active.includes(i) }));

const sameMarks = (a: ZoneMarks, b: ZoneMarks) =>
  a.violated.join() === b.violated.join() && a.active.join() === b.active.join();

const TRAIL_POINTS = 800;

// ------------------------------------------------------------------------- the person
// SPEC §11: the simulated person (a body of 1.7 m on its floor circle) and the scanner's
// fields as discs on the floor about the base axis; interrupted: a stronger colour.
const FIELD_STYLE = {
  outer: { color: 0xffb300, css: '#ffb300' }, // amber: slows
  inner: { color: 0xff1744, css: '#ff1744' }, // red: stops
};
const PERSON_CSS = '#b388ff';
const BODY_MM = 1450; // the body cylinder; the head's top at 1700 mm
const HEAD_MM = 110;

/** The person as drawn, for tests and diagnostics (window.safestateHmi.person and #arm's
 * data-person, data-person-xy, data-fields, data-person-objects): read back from what is drawn. */
interface DrawnPerson {
  present: boolean;
  x_mm: number;
  y_mm: number;
  outer: 'clear' | 'interrupted';
  inner: 'clear' | 'interrupted';
  objects: number; // visible parts of the drawing: fields, body, head, footprint, separation line and label
  separation: string; // the label's text
}

function exposePerson(container: HTMLElement, d: DrawnPerson | null): void {
  container.dataset.person = d === null ? 'none' : d.present ? 'present' : 'absent';
  container.dataset.personXy = d?.present ? `${Math.round(d.x_mm)},${Math.round(d.y_mm)}` : '';
  container.dataset.fields = d ? `outer:${d.outer},inner:${d.inner}` : '';
  container.dataset.personObjects = String(d?.objects ?? 0);
  const w = window as unknown as { safestateHmi?: Record<string, unknown> };
  w.safestateHmi ??= {};
  w.safestateHmi.person = d;
}

/** The robot point the separation is measured to (0..6 frame origin, 7 TCP), as kinematics.ts has it. */
const nearestPoint = (f: Frames, k: number): Vec3 => (k >= 0 && k < f.origin.length ? f.origin[k] : f.tcp);

/** The separation line on the floor: from the robot point to the body's edge. */
function separationEnds(f: Frames, p: NonNullable<PersonDrawing['person']>): [Vec3, Vec3] {
  const a = nearestPoint(f, p.nearest_point);
  const dx = p.x_mm - a[0];
  const dy = p.y_mm - a[1];
  const d = Math.hypot(dx, dy);
  const k = d > 1 ? Math.max(0, d - p.radius_mm) / d : 0;
  return [
    [a[0], a[1], 12],
    [a[0] + dx * k, a[1] + dy * k, 12],
  ];
}

const sepText = (p: NonNullable<PersonDrawing['person']>) => `${Math.round(p.separation_mm)} mm`;

/** A circle on the floor (z = 0) as a path of `n` segments, through the 2D view's projection. */
function floorCircle(g: CanvasRenderingContext2D, P: (p: Vec3) => [number, number], cx: number, cy: number, r: number, n: number): void {
  g.beginPath();
  for (let k = 0; k <= n; k++) {
    const a = (k / n) * 2 * Math.PI;
    const q = P([cx + r * Math.cos(a), cy + r * Math.sin(a), 0]);
    if (k) g.lineTo(...q);
    else g.moveTo(...q);
  }
}

function exposeDrawn(container: HTMLElement, joints: number[], f: Frames): void {
  const j = joints.map((q) => Math.round(q * 1e6) / 1e6);
  const tcp = f.tcp.map((v) => Math.round(v * 1000) / 1000);
  container.dataset.joints = JSON.stringify(j);
  container.dataset.tcp = JSON.stringify(tcp);
  const w = window as unknown as { safestateHmi?: Record<string, unknown> };
  w.safestateHmi ??= {};
  w.safestateHmi.view = { joints: j, tcp, origins: f.origin };
}

/** How the arm is drawn (issue 38 item 6), for tests and diagnostics (#arm's
 * data-arm-drawing and data-mesh-objects, window.safestateHmi.armDrawing): 'meshes' once every
 * mesh the URDF's visuals name was served by the gateway and loaded, 'shapes' otherwise (why
 * says what was missing), 'loading' in between (the shapes shown meanwhile). */
function exposeArmDrawing(container: HTMLElement, kind: 'shapes' | 'loading' | 'meshes', meshObjects: number, why: string): void {
  container.dataset.armDrawing = kind;
  container.dataset.meshObjects = String(meshObjects);
  const w = window as unknown as { safestateHmi?: Record<string, unknown> };
  w.safestateHmi ??= {};
  w.safestateHmi.armDrawing = { kind, meshObjects, why };
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
  private tcpOffset: Vec3;
  private lastJoints: number[] = [0, 0, 0, 0, 0, 0];
  private toolSphere: THREE.Mesh;
  private zoneGroup = new THREE.Group();
  private zoneParts: { fill: THREE.Mesh; edges: THREE.LineSegments; label: THREE.Sprite; zone: SafetyZone }[] = [];
  private zones: SafetyZone[] = [];
  private marks: ZoneMarks = { violated: [], active: [] };
  /** Software GL (SwiftShader, llvmpipe) costs CPU that the jog keep-alive needs: fewer frames. */
  readonly software: boolean;
  private minFrameMs: number;
  private personGroup = new THREE.Group();
  private fieldParts: Record<'outer' | 'inner', { fill: THREE.Mesh; edge: THREE.Mesh; r: number }>;
  private body: THREE.Group;
  private footprint: THREE.Mesh;
  private sepLine: THREE.Line;
  private sepLabel: THREE.Sprite;
  private sepLabelText = '';
  private floor: THREE.GridHelper;
  private personD: PersonDrawing | null = null;
  private widened = false;
  /** The built-in simple shapes (base, segments, housings, flange): hidden when meshes show. */
  private shapes: THREE.Object3D[] = [];
  /** The URDF's visuals, one group per link frame (0 base, k joint k), placed each update. */
  private visualFrames: THREE.Group[] = [];
  private meshesShown = false;

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
    this.tcpOffset = robot.tcp_offset as Vec3;
    root.add(this.zoneGroup);

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
    // The tool sphere the zone monitor checks (tool.radius_mm at the TCP).
    this.toolSphere = new THREE.Mesh(
      new THREE.SphereGeometry(1, 28, 18),
      new THREE.MeshBasicMaterial({ color: 0x4dd0e1, transparent: true, opacity: 0.22, depthWrite: false }),
    );
    this.toolSphere.visible = false;
    this.tcpMark.add(this.toolSphere);
    root.add(this.tcpMark);

    this.trailGeom.setAttribute('position', new THREE.BufferAttribute(new Float32Array(TRAIL_POINTS * 3), 3));
    this.trailGeom.setAttribute('color', new THREE.BufferAttribute(new Float32Array(TRAIL_POINTS * 3), 3));
    this.trailGeom.setDrawRange(0, 0);
    root.add(new THREE.Line(this.trailGeom, new THREE.LineBasicMaterial({ vertexColors: true })));

    root.add(new THREE.AxesHelper(220));

    // The person and the fields (hidden until the status has a `sim` object).
    const fieldPart = (which: 'outer' | 'inner', z: number) => {
      const st = FIELD_STYLE[which];
      const fill = new THREE.Mesh(
        new THREE.CircleGeometry(1, 96),
        new THREE.MeshBasicMaterial({ color: st.color, transparent: true, depthWrite: false, side: THREE.DoubleSide }),
      );
      const edge = new THREE.Mesh(
        new THREE.RingGeometry(0.98, 1, 128),
        new THREE.MeshBasicMaterial({ color: st.color, transparent: true, depthWrite: false, side: THREE.DoubleSide }),
      );
      fill.position.z = z;
      edge.position.z = z + 1;
      fill.name = `field:${which}`;
      this.personGroup.add(fill, edge);
      return { fill, edge, r: 0 };
    };
    this.fieldParts = { outer: fieldPart('outer', 2), inner: fieldPart('inner', 4) };
    const personMat = new THREE.MeshStandardMaterial({ color: PERSON_CSS, roughness: 0.6 });
    this.body = new THREE.Group();
    const torso = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, BODY_MM, 28), personMat);
    torso.rotation.x = Math.PI / 2; // three's cylinder stands on y; the robot's floor has z up
    torso.position.z = BODY_MM / 2;
    torso.name = 'person:body';
    const head = new THREE.Mesh(new THREE.SphereGeometry(HEAD_MM, 24, 16), new THREE.MeshStandardMaterial({ color: 0xffccbc, roughness: 0.7 }));
    head.position.z = 1700 - HEAD_MM;
    head.name = 'person:head';
    this.body.add(torso, head);
    this.footprint = new THREE.Mesh(
      new THREE.CircleGeometry(1, 48),
      new THREE.MeshBasicMaterial({ color: PERSON_CSS, transparent: true, opacity: 0.45, depthWrite: false, side: THREE.DoubleSide }),
    );
    this.footprint.position.z = 6;
    this.sepLine = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xffffff }));
    this.sepLine.geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(6), 3));
    this.sepLabel = new THREE.Sprite(new THREE.SpriteMaterial({ depthTest: false, transparent: true }));
    this.sepLabel.renderOrder = 3;
    this.personGroup.add(this.body, this.footprint, this.sepLine, this.sepLabel);
    this.personGroup.visible = false;
    root.add(this.personGroup);
    // A floor of 8 m (0.5 m squares) under the fields, beside the arm's own 1.6 m grid.
    this.floor = new THREE.GridHelper(8000, 16, 0x2a3440, 0x1c242d);
    this.floor.position.y = -1;
    this.floor.visible = false;
    this.scene.add(this.floor);

    // Camera in front of the arm, a little to its right (robot frame: x forward, z up).
    this.camera.position.set(1300, 820, 900);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.target.set(140, 300, 0);
    this.controls.enableDamping = false;
    this.controls.addEventListener('change', () => this.requestRender());
    this.controls.update();

    this.shapes = [base, ...this.links, ...this.housings, this.flange];
    for (let k = 0; k <= 6; k++) {
      const g = new THREE.Group();
      g.matrixAutoUpdate = false;
      g.visible = false;
      root.add(g);
      this.visualFrames.push(g);
    }
    exposeArmDrawing(container, 'shapes', 0, 'not loaded yet');
    void this.loadVisuals(linkMat);

    // Compile every shader now: a compile on the first motion (the trail's first segment,
    // the highlighted housing) would block the page just when a jog's keep-alive must go.
    this.housings[1].material = this.hotMat;
    this.renderer.compile(this.scene, this.camera);
    this.housings[1].material = this.housingMat;

    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  /** Draws the URDF's visuals when every mesh they name is served and loads; else keeps the shapes. */
  private async loadVisuals(linkMat: THREE.MeshStandardMaterial): Promise<void> {
    const list = urdfVisuals(this.robot.urdf ?? '', this.robot.base, this.robot.joints.map((j) => j.link));
    const meshes = (list ?? []).filter((v) => v.geometry.type === 'mesh');
    if (!list || meshes.length === 0) {
      exposeArmDrawing(this.container, 'shapes', 0, list ? 'the description names no meshes' : 'the description did not parse');
      return;
    }
    const urls = new Map((this.robot.meshes ?? []).map((m) => [m.uri, m.url]));
    const missing = meshes.find((v) => v.geometry.type === 'mesh' && !urls.has(v.geometry.uri));
    if (missing && missing.geometry.type === 'mesh') {
      const why = this.robot.meshes_refused?.find((r) => missing.geometry.type === 'mesh' && r.uri === missing.geometry.uri)?.why;
      exposeArmDrawing(this.container, 'shapes', 0, `mesh not served: ${missing.geometry.uri}${why ? ` (${why})` : ''}`);
      return;
    }
    exposeArmDrawing(this.container, 'loading', 0, '');
    let objects: THREE.Object3D[];
    try {
      objects = await Promise.all(list.map((v) => this.visualObject(v, urls, linkMat)));
    } catch (e) {
      exposeArmDrawing(this.container, 'shapes', 0, `mesh not loaded: ${String(e)}`);
      return;
    }
    list.forEach((v, i) => this.visualFrames[v.frame].add(objects[i]));
    for (const o of this.shapes) o.visible = false;
    for (const g of this.visualFrames) g.visible = true;
    this.meshesShown = true;
    this.renderer.compile(this.scene, this.camera); // the meshes' shaders now, not on the first jog
    const hot = this.hot;
    this.hot = -1; // re-apply the highlight to the meshes
    this.highlight(hot);
    this.update(this.lastJoints);
    let n = 0;
    for (const g of this.visualFrames) g.traverse((o) => void (o instanceof THREE.Mesh && o.visible && n++));
    exposeArmDrawing(this.container, 'meshes', n, '');
  }

  /** One visual in its link frame (mm): a served mesh (STL, COLLADA, OBJ) or a URDF primitive. */
  private async visualObject(v: Visual, urls: Map<string, string>, linkMat: THREE.MeshStandardMaterial): Promise<THREE.Object3D> {
    const mat = v.rgba
      ? new THREE.MeshStandardMaterial({ color: new THREE.Color(v.rgba[0], v.rgba[1], v.rgba[2]), roughness: 0.55, metalness: 0.05 })
      : linkMat.clone();
    const inner = new THREE.Group();
    const g = v.geometry;
    if (g.type === 'mesh') {
      const url = urls.get(g.uri)!;
      const ext = url.slice(url.lastIndexOf('.') + 1);
      let obj: THREE.Object3D;
      if (ext === 'stl') {
        const loader = new STLLoader();
        loader.setRequestHeader(authHeaders());
        obj = new THREE.Mesh(await loader.loadAsync(url), mat);
      } else if (ext === 'dae') {
        const loader = new ColladaLoader();
        loader.setRequestHeader(authHeaders());
        const dae = await loader.loadAsync(url);
        if (!dae?.scene) throw new Error(`${g.uri}: not COLLADA`);
        obj = dae.scene;
        // The vertices are in the link's frame as written (RViz draws them so): keep the
        // unit's scale, not the loader's turn from Z_UP to three.js's Y_UP.
        obj.rotation.set(0, 0, 0);
      } else if (ext === 'obj') {
        const loader = new OBJLoader();
        loader.setRequestHeader(authHeaders());
        obj = await loader.loadAsync(url);
        obj.traverse((o) => {
          if (o instanceof THREE.Mesh) o.material = mat;
        });
      } else {
        throw new Error(`${g.uri}: .${ext} is not drawn`);
      }
      inner.add(obj);
      inner.scale.set(g.scale[0] * 1000, g.scale[1] * 1000, g.scale[2] * 1000); // m -> mm
    } else if (g.type === 'box') {
      inner.add(new THREE.Mesh(new THREE.BoxGeometry(g.size[0] * 1000, g.size[1] * 1000, g.size[2] * 1000), mat));
    } else if (g.type === 'cylinder') {
      const m = new THREE.Mesh(new THREE.CylinderGeometry(g.radius * 1000, g.radius * 1000, g.length * 1000, 32), mat);
      m.rotation.x = Math.PI / 2; // three's cylinder stands on y, URDF's on z
      inner.add(m);
    } else {
      inner.add(new THREE.Mesh(new THREE.SphereGeometry(g.radius * 1000, 24, 16), mat));
    }
    // Each mesh its own materials: the jog highlight tints one link's, not every link's.
    inner.traverse((o) => {
      if (!(o instanceof THREE.Mesh)) return;
      o.material = Array.isArray(o.material) ? o.material.map((x: THREE.Material) => x.clone()) : o.material.clone();
    });
    const holder = new THREE.Group();
    holder.matrixAutoUpdate = false;
    holder.matrix.set(
      v.R[0][0], v.R[0][1], v.R[0][2], v.p[0],
      v.R[1][0], v.R[1][1], v.R[1][2], v.p[1],
      v.R[2][0], v.R[2][1], v.R[2][2], v.p[2],
      0, 0, 0, 1,
    );
    holder.add(inner);
    return holder;
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
    this.lastJoints = joints;
    const f = forward(this.robot.joints, this.robot.flange, joints, this.tcpOffset);
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
    if (this.meshesShown) {
      linkPoses(this.robot.joints, joints).forEach((L, k) => {
        const R = L.R;
        this.visualFrames[k].matrix.set(
          R[0][0], R[0][1], R[0][2], L.p[0],
          R[1][0], R[1][1], R[1][2], L.p[1],
          R[2][0], R[2][1], R[2][2], L.p[2],
          0, 0, 0, 1,
        );
        this.visualFrames[k].matrixWorldNeedsUpdate = true;
      });
    }

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
    this.placeSeparation(f);
    this.requestRender();
  }

  setPerson(d: PersonDrawing | null): void {
    if (d === null && this.personD === null && this.container.dataset.person === 'none') return;
    this.personD = d;
    this.personGroup.visible = d !== null;
    this.floor.visible = d !== null;
    if (d) {
      if (!this.widened) {
        // Once: step back so that the outer field fits in the view, about the base axis.
        this.widened = true;
        const target = new THREE.Vector3(0, 300, 0);
        const dir = this.camera.position.clone().sub(this.controls.target).normalize();
        const dist = Math.max(this.camera.position.distanceTo(this.controls.target), (d.outer_mm + 500) * 1.9);
        this.controls.target.copy(target);
        this.camera.position.copy(target.addScaledVector(dir, dist));
        this.controls.update();
      }
      for (const which of ['outer', 'inner'] as const) {
        const part = this.fieldParts[which];
        const r = which === 'outer' ? d.outer_mm : d.inner_mm;
        const on = which === 'outer' ? d.outerInterrupted : d.innerInterrupted;
        if (r !== part.r) {
          part.r = r;
          part.fill.scale.set(r, r, 1);
          part.edge.geometry.dispose();
          part.edge.geometry = new THREE.RingGeometry(Math.max(0, r - 30), r, 128); // a 30 mm edge at any radius
        }
        (part.fill.material as THREE.MeshBasicMaterial).opacity = on ? 0.3 : 0.06;
        (part.edge.material as THREE.MeshBasicMaterial).opacity = on ? 1 : 0.6;
        part.fill.userData.interrupted = on;
      }
      const p = d.person;
      this.body.visible = this.footprint.visible = p !== null;
      if (p) {
        this.body.position.set(p.x_mm, p.y_mm, 0);
        const torso = this.body.children[0];
        torso.scale.set(p.radius_mm * 0.72, 1, p.radius_mm * 0.72); // shoulders inside the floor circle
        this.footprint.position.set(p.x_mm, p.y_mm, 6);
        this.footprint.scale.set(p.radius_mm, p.radius_mm, 1);
        const text = sepText(p);
        if (text !== this.sepLabelText) {
          this.sepLabelText = text;
          const old = this.sepLabel.material.map;
          this.sepLabel.material.map = labelTexture(text, '#ffffff', false);
          this.sepLabel.material.needsUpdate = true;
          old?.dispose();
          const img = this.sepLabel.material.map.image as HTMLCanvasElement;
          this.sepLabel.scale.set(img.width * 4, img.height * 4, 1);
        }
      }
    }
    this.placeSeparation(forward(this.robot.joints, this.robot.flange, this.lastJoints, this.tcpOffset));
    this.exposePerson();
    this.requestRender();
  }

  private placeSeparation(f: Frames): void {
    const p = this.personD?.person ?? null;
    this.sepLine.visible = this.sepLabel.visible = p !== null;
    if (!p) return;
    const [a, b] = separationEnds(f, p);
    const pos = this.sepLine.geometry.getAttribute('position') as THREE.BufferAttribute;
    pos.setXYZ(0, ...a);
    pos.setXYZ(1, ...b);
    pos.needsUpdate = true;
    this.sepLine.geometry.computeBoundingSphere();
    this.sepLabel.position.set((a[0] + b[0]) / 2, (a[1] + b[1]) / 2, 140);
  }

  private exposePerson(): void {
    const d = this.personD;
    if (!d) {
      exposePerson(this.container, null);
      return;
    }
    const parts: THREE.Object3D[] = [...Object.values(this.fieldParts).flatMap((f) => [f.fill, f.edge]), ...this.body.children, this.footprint, this.sepLine, this.sepLabel];
    const shown = (o: THREE.Object3D) => o.visible && (o.parent === this.body ? this.body.visible : true);
    exposePerson(this.container, {
      present: this.body.visible,
      x_mm: this.body.position.x,
      y_mm: this.body.position.y,
      outer: this.fieldParts.outer.fill.userData.interrupted ? 'interrupted' : 'clear',
      inner: this.fieldParts.inner.fill.userData.interrupted ? 'interrupted' : 'clear',
      objects: parts.filter(shown).length,
      separation: this.sepLabel.visible ? this.sepLabelText : '',
    });
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
    // With meshes: the link the jogged axis moves glows.
    this.visualFrames.forEach((g, k) =>
      g.traverse((o) => {
        if (!(o instanceof THREE.Mesh)) return;
        for (const m of Array.isArray(o.material) ? o.material : [o.material]) {
          if (!('emissive' in m) || !(m.emissive instanceof THREE.Color)) continue;
          m.userData.emissive ??= m.emissive.getHex();
          m.emissive.setHex(k > 0 && k === axis ? 0x0b3c55 : m.userData.emissive);
        }
      }),
    );
    this.requestRender();
  }

  clearTrail(): void {
    this.trail.clear();
    this.writeTrail();
    this.requestRender();
  }

  setSafety(sd: SafetyDrawing | null): void {
    for (const p of this.zoneParts) {
      p.fill.geometry.dispose();
      (p.fill.material as THREE.Material).dispose();
      p.edges.geometry.dispose();
      (p.edges.material as THREE.Material).dispose();
      p.label.material.map?.dispose();
      p.label.material.dispose();
    }
    this.zoneGroup.clear();
    this.zoneParts = [];
    this.zones = sd?.zones ?? [];
    this.tcpOffset = sd ? sd.tcp_mm : (this.robot.tcp_offset as Vec3);
    const r = sd?.radius_mm ?? 0;
    this.toolSphere.visible = r > 0;
    this.toolSphere.scale.setScalar(Math.max(r, 1));
    for (const zone of this.zones) {
      const [x0, y0, z0] = zone.min_mm;
      const [x1, y1, z1] = zone.max_mm;
      const geom = new THREE.BoxGeometry(x1 - x0, y1 - y0, z1 - z0);
      const color = new THREE.Color(ZONE_STYLE[zone.kind]?.color ?? '#9e9e9e');
      const fill = new THREE.Mesh(geom, new THREE.MeshBasicMaterial({ color, transparent: true, depthWrite: false, side: THREE.DoubleSide }));
      const edges = new THREE.LineSegments(new THREE.EdgesGeometry(geom), new THREE.LineBasicMaterial({ color, transparent: true }));
      const centre = new THREE.Vector3((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2);
      fill.position.copy(centre);
      edges.position.copy(centre);
      fill.name = `zone:${zone.name}`;
      fill.renderOrder = 1; // translucent boxes after the arm
      const label = new THREE.Sprite(new THREE.SpriteMaterial({ depthTest: false, transparent: true }));
      // Where it stays in view: a keep-in box (the whole cell) by its corner nearest the
      // camera, on the floor; a low box above its top; a tall one at 60 % of its height.
      if (zone.kind === 'keep_in') label.position.set(x1, y0, Math.max(z0, 0) + 40);
      else label.position.set(centre.x, centre.y, z1 - z0 < 400 ? z1 + 60 : z0 + 0.6 * (z1 - z0));
      label.renderOrder = 2;
      this.zoneGroup.add(fill, edges, label);
      this.zoneParts.push({ fill, edges, label, zone });
    }
    this.marks = { violated: [], active: [] };
    this.paintZones();
    this.update(this.lastJoints);
  }

  markZones(m: ZoneMarks): void {
    if (sameMarks(m, this.marks)) return;
    this.marks = { violated: [...m.violated], active: [...m.active] };
    this.paintZones();
    this.requestRender();
  }

  private paintZones(): void {
    this.zoneParts.forEach((p, i) => {
      const bad = this.marks.violated.includes(i);
      const active = this.marks.active.includes(i);
      const style = ZONE_STYLE[p.zone.kind];
      const fill = p.fill.material as THREE.MeshBasicMaterial;
      // The keep-in box usually holds the whole cell: faint, so that it does not fog the arm.
      fill.opacity = bad ? 0.5 : p.zone.kind === 'keep_in' ? 0.04 : active ? 0.34 : 0.18;
      fill.color.set(bad ? VIOLATED_HEX : style?.color ?? '#9e9e9e');
      const edges = p.edges.material as THREE.LineBasicMaterial;
      edges.color.set(bad ? '#ffffff' : style?.color ?? '#9e9e9e');
      edges.opacity = bad ? 1 : 0.85;
      const text = bad ? `${p.zone.name}: VIOLATED` : active ? `${p.zone.name}: reduced speed` : p.zone.name;
      const old = p.label.material.map;
      p.label.material.map = labelTexture(text, bad ? '#ff1744' : style?.color ?? '#9e9e9e', bad);
      p.label.material.map.userData.active = active;
      p.label.material.needsUpdate = true;
      old?.dispose();
      const img = p.label.material.map.image as HTMLCanvasElement;
      p.label.scale.set(img.width * 2.2, img.height * 2.2, 1); // about 2 mm per pixel: readable in a 2 m cell
    });
    exposeZones(
      this.container,
      this.zoneParts.map((p) => ({
        name: p.zone.name,
        kind: p.zone.kind,
        violated: (p.fill.material as THREE.MeshBasicMaterial).color.getHex() === VIOLATED_HEX,
        active: p.label.material.map?.userData.active === true,
      })),
    );
  }
}

/** A zone's name as a sprite texture (mm-sized through the sprite's scale). */
function labelTexture(text: string, color: string, strong: boolean): THREE.CanvasTexture {
  const c = document.createElement('canvas');
  const g = c.getContext('2d')!;
  const font = `${strong ? 800 : 700} 30px system-ui, sans-serif`;
  g.font = font;
  const w = Math.ceil(g.measureText(text).width) + 24;
  c.width = w;
  c.height = 44;
  g.font = font;
  g.fillStyle = strong ? color : 'rgba(13, 17, 22, 0.78)';
  g.beginPath();
  g.roundRect(0, 0, w, 44, 8);
  g.fill();
  g.strokeStyle = color;
  g.lineWidth = 3;
  g.stroke();
  g.fillStyle = strong ? '#ffffff' : color;
  g.textBaseline = 'middle';
  g.fillText(text, 12, 23);
  const t = new THREE.CanvasTexture(c);
  t.colorSpace = THREE.SRGBColorSpace;
  return t;
}

// ------------------------------------------------------------------------- 2D fallback
class FlatArm implements ArmDrawing {
  readonly kind = '2d' as const;
  private canvas = document.createElement('canvas');
  private trail = new Trail();
  private last: Frames | null = null;
  private hot: number | null = null;
  private tcpOffset: Vec3;
  private lastJoints: number[] = [0, 0, 0, 0, 0, 0];
  private safety: SafetyDrawing | null = null;
  private marks: ZoneMarks = { violated: [], active: [] };
  private personD: PersonDrawing | null = null;

  constructor(
    private readonly container: HTMLElement,
    private readonly robot: Robot,
  ) {
    this.tcpOffset = robot.tcp_offset as Vec3;
    exposeArmDrawing(container, 'shapes', 0, '2D view');
    container.append(this.canvas);
    this.canvas.style.width = '100%';
    this.canvas.style.height = '100%';
    new ResizeObserver(() => this.draw()).observe(container);
  }

  update(joints: number[]): void {
    this.lastJoints = joints;
    this.last = forward(this.robot.joints, this.robot.flange, joints, this.tcpOffset);
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

  setSafety(sd: SafetyDrawing | null): void {
    this.safety = sd;
    this.tcpOffset = sd ? sd.tcp_mm : (this.robot.tcp_offset as Vec3);
    this.marks = { violated: [], active: [] };
    exposeZones(this.container, flatZones(sd?.zones ?? [], this.marks));
    this.update(this.lastJoints);
  }

  markZones(m: ZoneMarks): void {
    if (sameMarks(m, this.marks)) return;
    this.marks = { violated: [...m.violated], active: [...m.active] };
    exposeZones(this.container, flatZones(this.safety?.zones ?? [], this.marks));
    this.draw();
  }

  setPerson(d: PersonDrawing | null): void {
    if (d === null && this.personD === null && this.container.dataset.person === 'none') return;
    this.personD = d;
    const p = d?.person ?? null;
    exposePerson(
      this.container,
      d && {
        present: p !== null,
        x_mm: p?.x_mm ?? 0,
        y_mm: p?.y_mm ?? 0,
        outer: d.outerInterrupted ? 'interrupted' : 'clear',
        inner: d.innerInterrupted ? 'interrupted' : 'clear',
        objects: 4 + (p ? 5 : 0), // as the WebGL view counts: each field's fill and edge; body, head, footprint, line, label
        separation: p ? sepText(p) : '',
      },
    );
    this.draw();
  }

  private draw(): void {
    const c = this.canvas;
    const w = (c.width = this.container.clientWidth);
    const h = (c.height = this.container.clientHeight);
    const g = c.getContext('2d');
    if (!g || !this.last) return;
    // With the person's fields the floor to show is wider than the arm's reach.
    const s = Math.min(w, h) / (this.personD ? Math.max(1500, 1.6 * this.personD.outer_mm) : 1500);
    // Isometric projection of robot coordinates (x forward, y left, z up).
    const P = (p: Vec3): [number, number] => [
      w * 0.4 + (p[0] * 0.87 - p[1] * 0.87) * s,
      h * 0.8 - (p[2] + (p[0] + p[1]) * 0.5 * 0.5) * s,
    ];
    g.fillStyle = '#10151b';
    g.fillRect(0, 0, w, h);
    const d = this.personD;
    if (d) {
      // The fields as floor circles (outer amber, inner red; stronger when interrupted).
      for (const [r, on, st] of [
        [d.outer_mm, d.outerInterrupted, FIELD_STYLE.outer],
        [d.inner_mm, d.innerInterrupted, FIELD_STYLE.inner],
      ] as const) {
        floorCircle(g, P, 0, 0, r, 72);
        g.globalAlpha = on ? 0.3 : 0.07;
        g.fillStyle = st.css;
        g.fill();
        g.globalAlpha = 1;
        g.strokeStyle = st.css;
        g.lineWidth = on ? 3 : 1.5;
        g.stroke();
      }
      const p = d.person;
      if (p) {
        g.fillStyle = PERSON_CSS;
        g.globalAlpha = 0.45;
        floorCircle(g, P, p.x_mm, p.y_mm, p.radius_mm, 36);
        g.fill();
        g.globalAlpha = 1;
        const [a, b] = separationEnds(this.last, p);
        g.strokeStyle = '#ffffff';
        g.lineWidth = 1.5;
        g.beginPath();
        g.moveTo(...P(a));
        g.lineTo(...P(b));
        g.stroke();
        g.fillStyle = '#ffffff';
        g.font = '12px sans-serif';
        g.fillText(sepText(p), ...P([(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, 80]));
        g.strokeStyle = PERSON_CSS;
        g.lineWidth = Math.max(6, 2 * p.radius_mm * 0.72 * s);
        g.lineCap = 'round';
        g.beginPath();
        g.moveTo(...P([p.x_mm, p.y_mm, 0]));
        g.lineTo(...P([p.x_mm, p.y_mm, BODY_MM]));
        g.stroke();
        g.fillStyle = '#ffccbc';
        g.beginPath();
        g.arc(...P([p.x_mm, p.y_mm, 1700 - HEAD_MM]), Math.max(4, HEAD_MM * s), 0, 2 * Math.PI);
        g.fill();
      }
    }
    // Zones as wire boxes (the 12 edges of each), named.
    (this.safety?.zones ?? []).forEach((z, i) => {
      const bad = this.marks.violated.includes(i);
      const [a, b] = [z.min_mm, z.max_mm];
      const corner = (k: number): Vec3 => [k & 1 ? b[0] : a[0], k & 2 ? b[1] : a[1], k & 4 ? b[2] : a[2]];
      g.strokeStyle = bad ? '#ff1744' : ZONE_STYLE[z.kind]?.color ?? '#9e9e9e';
      g.lineWidth = bad ? 3 : 1.5;
      g.beginPath();
      for (let k = 0; k < 8; k++) {
        for (const bit of [1, 2, 4]) {
          if (k & bit) continue;
          g.moveTo(...P(corner(k)));
          g.lineTo(...P(corner(k | bit)));
        }
      }
      g.stroke();
      g.fillStyle = g.strokeStyle;
      g.font = bad ? 'bold 13px sans-serif' : '12px sans-serif';
      g.fillText(bad ? `${z.name}: VIOLATED` : z.name, ...P([(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, b[2]]));
    });
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
    const r = this.safety?.radius_mm ?? 0;
    if (r > 0) {
      g.strokeStyle = '#4dd0e1';
      g.lineWidth = 1;
      g.beginPath();
      g.arc(...P(this.last.tcp), Math.max(3, r * s), 0, 2 * Math.PI);
      g.stroke();
    }
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

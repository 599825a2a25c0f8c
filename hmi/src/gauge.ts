// TCP speed gauge (SVG). In T1 the scale is 0–300 mm/s with the 250 mm/s limit of
// ISO 10218-1 marked; in AUTO/T2 it is 0–2000 mm/s.
import type { Mode } from './api';
import { setAttr, setText } from './dom';

const NS = 'http://www.w3.org/2000/svg';
const T1_LIMIT = 250;
const CX = 100;
const CY = 96;
const R = 78;

function svg<K extends keyof SVGElementTagNameMap>(tag: K, attrs: Record<string, string | number>): SVGElementTagNameMap[K] {
  const el = document.createElementNS(NS, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  return el;
}

/** Point on the dial for a fraction 0..1 of the scale (left to right over the top). */
function at(frac: number, r = R): [number, number] {
  const a = Math.PI * (1 - Math.min(1, Math.max(0, frac)));
  return [CX + r * Math.cos(a), CY - r * Math.sin(a)];
}

function arc(f0: number, f1: number, r = R): string {
  const [x0, y0] = at(f0, r);
  const [x1, y1] = at(f1, r);
  return `M ${x0.toFixed(2)} ${y0.toFixed(2)} A ${r} ${r} 0 0 1 ${x1.toFixed(2)} ${y1.toFixed(2)}`;
}

export class SpeedGauge {
  readonly el: HTMLElement;
  private value: SVGPathElement;
  private over: SVGPathElement;
  private limitTick: SVGLineElement;
  private limitLabel: SVGTextElement;
  private scaleMax: SVGTextElement;
  private readout: SVGTextElement;
  private sub: HTMLElement;
  private fastest: HTMLElement;
  private max = 300;
  private mode: Mode | null = null;

  constructor() {
    this.el = document.createElement('div');
    this.el.className = 'gauge';
    this.el.id = 'speed-gauge';
    const s = svg('svg', { viewBox: '0 0 200 112', role: 'img', 'aria-label': 'TCP speed gauge' });
    s.append(svg('path', { d: arc(0, 1), class: 'g-track' }));
    this.over = svg('path', { d: arc(T1_LIMIT / 300, 1), class: 'g-over' });
    s.append(this.over);
    this.value = svg('path', { d: arc(0, 0.001), class: 'g-value' });
    s.append(this.value);
    this.limitTick = svg('line', { class: 'g-limit' });
    s.append(this.limitTick);
    this.limitLabel = svg('text', { class: 'g-limit-label', 'text-anchor': 'middle' });
    s.append(this.limitLabel);
    const zero = svg('text', { x: CX - R, y: CY + 14, class: 'g-scale', 'text-anchor': 'middle' });
    zero.textContent = '0';
    s.append(zero);
    this.scaleMax = svg('text', { x: CX + R, y: CY + 14, class: 'g-scale', 'text-anchor': 'middle' });
    s.append(this.scaleMax);
    this.readout = svg('text', { x: CX, y: CY - 10, class: 'g-readout', 'text-anchor': 'middle' });
    const unit = svg('text', { x: CX, y: CY + 6, class: 'g-unit', 'text-anchor': 'middle' });
    unit.textContent = 'mm/s';
    s.append(this.readout, unit);
    this.sub = document.createElement('div');
    this.sub.className = 'g-sub';
    this.fastest = document.createElement('div');
    this.fastest.className = 'g-sub';
    const title = document.createElement('div');
    title.className = 'g-title';
    title.textContent = 'TCP speed';
    this.el.append(title, s, this.sub, this.fastest);
    this.setMode('T1');
  }

  private setMode(mode: Mode): void {
    if (mode === this.mode) return;
    this.mode = mode;
    this.max = mode === 'T1' ? 300 : 2000;
    const f = T1_LIMIT / this.max;
    const [x0, y0] = at(f, R - 16);
    const [x1, y1] = at(f, R + 10);
    const [lx, ly] = at(f, R + 20);
    for (const [k, v] of Object.entries({ x1: x0, y1: y0, x2: x1, y2: y1 })) this.limitTick.setAttribute(k, v.toFixed(2));
    this.limitLabel.setAttribute('x', lx.toFixed(1));
    this.limitLabel.setAttribute('y', (ly + 4).toFixed(1));
    this.limitLabel.textContent = '250';
    this.over.setAttribute('d', arc(f, 1));
    this.over.style.display = mode === 'T1' ? '' : 'none';
    this.limitTick.style.display = mode === 'T1' ? '' : 'none';
    this.limitLabel.style.display = mode === 'T1' ? '' : 'none';
    this.scaleMax.textContent = String(this.max);
    this.el.dataset.mode = mode;
  }

  update(speed: number, mode: Mode, fastestPoint: number | undefined): void {
    this.setMode(mode);
    const frac = Math.min(1, speed / this.max);
    this.value.setAttribute('d', arc(0, Math.max(0.001, frac)));
    const tone = mode === 'T1' && speed > T1_LIMIT ? 'over' : mode === 'T1' && speed > 0.9 * T1_LIMIT ? 'near' : 'ok';
    setAttr(this.el, 'data-tone', tone);
    const txt = speed.toFixed(1);
    if (this.readout.textContent !== txt) this.readout.textContent = txt;
    const lim = mode === 'T1' ? 'T1 limit 250 mm/s' : `${mode}: speed not reduced`;
    setText(this.sub, lim);
    setText(this.fastest, fastestPoint !== undefined ? `fastest point ${fastestPoint.toFixed(1)} mm/s` : '');
    setAttr(this.sub, 'title', 'The T1 monitor checks the TCP and the origin of every link frame (SPEC rule 3).');
  }
}

// The jog panel: per axis a `−` and a `+` button that are hold-to-run. While a button is
// held, `jog` is sent every 50 ms as the keep-alive (SPEC rule 7: the core stops the jog
// when it is older than jog_timeout_ms, 100 ms). Release, pointer leave, pointer cancel,
// window blur, a hidden page or a lost connection end the hold with `jog_stop`.
// A refused jog ends the keep-alive at once (the refusal is shown, not repeated).
import type { Robot, SafetyJoint, Status } from './api';
import type { Link, Outcome } from './connection';
import { deg, h, setAttr, setText, toggleClass } from './dom';
import { barGeometry } from './safety-logic';

export const KEEPALIVE_MS = 50;

interface Hold {
  axis: number;
  dir: '+' | '-';
  btn: HTMLButtonElement;
  refused: boolean;
  next: number; // performance.now() of the next keep-alive
}

// The keep-alive is the most urgent work of the page: where the browser has a task
// scheduler, it runs at 'user-blocking' priority, ahead of status rendering.
type PostTask = (cb: () => void, opts: { priority: string; delay: number }) => Promise<void>;
const postTask: PostTask | null = (() => {
  const s = (globalThis as unknown as { scheduler?: { postTask?: PostTask } }).scheduler;
  return s?.postTask ? s.postTask.bind(s) : null;
})();

function after(ms: number, cb: () => void): void {
  if (postTask) void postTask(cb, { priority: 'user-blocking', delay: Math.max(0, ms) }).catch(() => undefined);
  else window.setTimeout(cb, Math.max(0, ms));
}

interface Row {
  row: HTMLElement;
  value: HTMLElement;
  state: HTMLElement;
  range: HTMLElement;
  bar: HTMLElement;
  band: HTMLElement;
  marker: HTMLElement;
}

export class JogPanel {
  readonly el: HTMLElement;
  private hold: Hold | null = null;
  private rows: Row[] = [];
  private speed: HTMLInputElement;
  private speedOut: HTMLElement;
  private note: HTMLElement;
  private robot: Robot | null = null;
  private safeJoints: SafetyJoint[] | null = null;
  private violated = new Map<number, string>(); // axis -> "JOINT_LIMIT", ...

  constructor(
    private readonly link: Link,
    private readonly onHold: (axis: number | null) => void,
  ) {
    this.speed = h('input', {
      type: 'range',
      min: 1,
      max: 100,
      step: 1,
      value: 10,
      id: 'jog-speed',
      'aria-label': 'Jog speed in percent',
    });
    this.speedOut = h('output', { class: 'jog-speed-out', for: 'jog-speed' }, '10 %');
    this.speed.addEventListener('input', () => setText(this.speedOut, `${this.speed.value} %`));
    const presets = h(
      'div',
      { class: 'jog-presets' },
      ...[1, 10, 25, 50, 100].map((p) =>
        h('button', { type: 'button', class: 'chip', onclick: () => this.setSpeed(p) }, `${p}`),
      ),
    );
    this.note = h('div', { class: 'jog-note', id: 'jog-note' }, 'Hold a button to jog; release to stop.');
    const list = h('div', { class: 'jog-rows' });
    for (let axis = 1; axis <= 6; axis++) list.append(this.row(axis));
    this.el = h(
      'div',
      { class: 'jog', id: 'jog' },
      h(
        'div',
        { class: 'panel-head' },
        h('h2', {}, 'Jog'),
        h('div', { class: 'jog-speed' }, h('label', { for: 'jog-speed' }, 'Speed'), this.speed, this.speedOut),
      ),
      presets,
      list,
      this.note,
    );

    const end = (why: string) => () => this.stop(why);
    window.addEventListener('blur', end('window lost focus'));
    document.addEventListener('visibilitychange', () => document.hidden && this.stop('page hidden'));
    window.addEventListener('pointerup', end('released'));
  }

  setRobot(robot: Robot): void {
    this.robot = robot;
    this.drawRanges();
  }

  /** The configured safe ranges (SPEC §10 config.joints), or null for the robot's own. */
  setSafety(joints: SafetyJoint[] | null): void {
    this.safeJoints = joints && joints.length === 6 ? joints : null;
    this.drawRanges();
  }

  /** Axes (1..6) whose safe limit is violated now (JOINT_LIMIT, SPEED_LIMIT axis.N). */
  setViolated(axes: number[], labels: Map<number, string>): void {
    this.violated = new Map(axes.map((a) => [a, labels.get(a) ?? 'violated']));
    this.rows.forEach((r, i) => {
      const label = this.violated.get(i + 1);
      toggleClass(r.row, 'violated', label !== undefined);
      setAttr(r.row, 'data-violation', label ?? null);
    });
  }

  private drawRanges(): void {
    const lim = this.robot?.joint_limits;
    this.rows.forEach((r, i) => {
      if (!lim?.[i]) return;
      const cfg = this.safeJoints?.[i] ?? null;
      const g = barGeometry(0, lim[i].min, lim[i].max, cfg);
      r.band.style.left = `${(g.lo * 100).toFixed(2)}%`;
      r.band.style.width = `${((g.hi - g.lo) * 100).toFixed(2)}%`;
      const rMin = deg(lim[i].min).toFixed(0);
      const rMax = deg(lim[i].max).toFixed(0);
      const text = cfg ? `safe ${cfg.min_deg}…${cfg.max_deg}°` : `${rMin}…${rMax}°`;
      setText(r.range, text);
      r.bar.dataset.min = String(cfg ? cfg.min_deg : Number(rMin));
      r.bar.dataset.max = String(cfg ? cfg.max_deg : Number(rMax));
      setAttr(
        r.bar,
        'title',
        cfg
          ? `Safe range ${cfg.min_deg}° … ${cfg.max_deg}° (the bright band; safety configuration), robot ${rMin}° … ${rMax}° (the whole bar)`
          : `Robot range ${rMin}° … ${rMax}°`,
      );
    });
  }

  private setSpeed(p: number): void {
    this.speed.value = String(p);
    setText(this.speedOut, `${p} %`);
  }

  private row(axis: number): HTMLElement {
    const btn = (dir: '+' | '-') => {
      const b = h(
        'button',
        {
          type: 'button',
          class: `jog-btn jog-${dir === '+' ? 'plus' : 'minus'}`,
          id: `jog-${axis}-${dir === '+' ? 'plus' : 'minus'}`,
          'data-axis': axis,
          'data-dir': dir,
          'aria-label': `Jog axis ${axis} ${dir === '+' ? 'plus' : 'minus'} (hold)`,
        },
        dir === '+' ? '+' : '−',
      );
      b.addEventListener('pointerdown', (e) => {
        if (e.button !== 0) return;
        e.preventDefault();
        this.start(axis, dir, b);
      });
      b.addEventListener('pointerup', () => this.stop('released'));
      b.addEventListener('pointerleave', () => this.stop('pointer left the button'));
      b.addEventListener('pointercancel', () => this.stop('pointer cancelled'));
      b.addEventListener('contextmenu', (e) => e.preventDefault());
      // Keyboard: hold Space or Enter.
      b.addEventListener('keydown', (e) => {
        if ((e.key === ' ' || e.key === 'Enter') && !e.repeat) {
          e.preventDefault();
          this.start(axis, dir, b);
        }
      });
      b.addEventListener('keyup', (e) => (e.key === ' ' || e.key === 'Enter') && this.stop('released'));
      b.addEventListener('blur', () => this.hold?.btn === b && this.stop('button lost focus'));
      return b;
    };
    const value = h('div', { class: 'jog-value', id: `joint-${axis}` }, '—');
    const state = h('span', { class: 'jog-axis-state' }, '');
    const range = h('span', { class: 'jog-range', id: `joint-${axis}-range` }, '');
    const marker = h('div', { class: 'jog-bar-marker' });
    const band = h('div', { class: 'jog-bar-band' });
    const bar = h('div', { class: 'jog-bar', id: `joint-${axis}-bar`, title: 'Position within the joint limits' }, band, marker);
    const row = h('div', { class: 'jog-row', 'data-axis': axis });
    this.rows.push({ row, value, state, range, bar, band, marker });
    row.append(
      btn('-'),
      h(
        'div',
        { class: 'jog-mid' },
        h('div', { class: 'jog-line' }, h('span', { class: 'jog-axis' }, `J${axis}`), value),
        bar,
        h('div', { class: 'jog-sub' }, state, range),
      ),
      btn('+'),
    );
    return row;
  }

  /** Keep-alive timing of the current or last hold (diagnostics, read by the browser test). */
  readonly stats = { sent: 0, maxGapMs: 0, last: 0 };

  private send(first: boolean): void {
    const hold = this.hold;
    if (!hold || hold.refused) return;
    const now = performance.now();
    if (first) {
      this.stats.sent = 0;
      this.stats.maxGapMs = 0;
    } else {
      this.stats.maxGapMs = Math.max(this.stats.maxGapMs, now - this.stats.last);
    }
    this.stats.sent++;
    this.stats.last = now;
    const args = { axis: hold.axis, dir: hold.dir, speed: Number(this.speed.value) };
    this.link.command('jog', args, first ? 'all' : 'refusals', (o: Outcome) => {
      if (o.result !== 'OK' && this.hold === hold) {
        hold.refused = true;
        hold.btn.classList.add('refused');
        setText(this.note, `Jog refused (${o.result}): release the button and fix the cause first.`);
      }
    });
  }

  private start(axis: number, dir: '+' | '-', btn: HTMLButtonElement): void {
    if (this.hold) this.stop('another button pressed');
    const hold: Hold = { axis, dir, btn, refused: false, next: performance.now() + KEEPALIVE_MS };
    this.hold = hold;
    btn.classList.add('held');
    this.onHold(axis);
    setText(this.note, `Jogging axis ${axis} ${dir === '+' ? 'plus' : 'minus'}: release to stop.`);
    this.send(true);
    this.tick(hold);
  }

  /** Every KEEPALIVE_MS on a fixed grid (a late tick does not push the next one back). */
  private tick(hold: Hold): void {
    after(hold.next - performance.now(), () => {
      if (this.hold !== hold || hold.refused) return;
      this.send(false);
      const now = performance.now();
      hold.next = Math.max(hold.next + KEEPALIVE_MS, now + 10);
      this.tick(hold);
    });
  }

  /** Ends a hold: stops the keep-alive and sends jog_stop (when connected). */
  stop(why: string): void {
    const hold = this.hold;
    if (!hold) return;
    this.hold = null;
    hold.btn.classList.remove('held', 'refused');
    this.onHold(null);
    if (this.link.connected) {
      // jog_stop is refused only outside MANUAL_JOGGING (SPEC §4, §5): the jog had already
      // ended (a refused jog, an E-stop, a stop, a mode change, the keep-alive). So its
      // answer goes to the history only, never shown as a refusal of the operator's; one
      // the controller did not take at all is said here (the keep-alive stops the jog).
      this.link.command('jog_stop', {}, 'none', (o: Outcome) => {
        if (o.result === 'QUEUE_FULL' || o.result === 'NOT_HELLO' || o.result === 'BAD_MESSAGE') {
          setText(this.note, `Jog stop not taken (${o.result}): the controller stops the jog by its keep-alive timeout.`);
        }
      });
      setText(this.note, `Jog stopped (${why}).`);
    } else {
      setText(this.note, 'Connection lost: the controller stops the jog by its keep-alive timeout.');
    }
  }

  get holding(): boolean {
    return this.hold !== null;
  }

  update(s: Status): void {
    const lim = this.robot?.joint_limits;
    for (let i = 0; i < 6; i++) {
      const r = this.rows[i];
      const q = s.joints[i] ?? 0;
      setText(r.value, `${deg(q).toFixed(2)}°`);
      const violation = this.violated.get(i + 1);
      setText(r.state, violation ?? s.axis_state?.[i] ?? '');
      if (lim?.[i]) {
        const g = barGeometry(q, lim[i].min, lim[i].max, this.safeJoints?.[i] ?? null);
        r.marker.style.left = `${(g.at * 100).toFixed(1)}%`;
        toggleClass(r.bar, 'near-limit', g.where === 'near');
        toggleClass(r.bar, 'outside', g.where === 'outside');
      }
    }
    const manual = s.mode === 'T1' || s.mode === 'T2';
    setAttr(this.el, 'data-manual', manual ? 'yes' : 'no');
    toggleClass(this.el, 'jogging', s.sub === 'MANUAL_JOGGING');
  }
}

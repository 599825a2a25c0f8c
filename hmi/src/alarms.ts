// Active alarms from GET /api/alarms, fetched again whenever status.alarms changes.
// `since` is the core's cycle number; with the status's cycle and the cycle period it
// becomes a wall-clock time.
import { type Alarm, fetchAlarms, type Status } from './api';
import { ago, clockTime, h, setText } from './dom';
import { SEVERITY_RANK } from './words';

export class AlarmList {
  readonly el: HTMLElement;
  private list: HTMLElement;
  private count: HTMLElement;
  private key: string | null = null;
  private alarms: { a: Alarm; at: number; el: HTMLElement; age: HTMLElement }[] = [];
  private inflight = false;
  private again = false;
  private lastStatus: Status | null = null;
  cyclePeriodMs = 1;
  /** Called with every fresh list (the Safety page and the 3D view highlight from it). */
  onAlarms: ((alarms: Alarm[]) => void) | null = null;

  constructor() {
    this.count = h('span', { class: 'count', id: 'alarm-count' }, '0');
    this.list = h('div', { class: 'alarm-list', id: 'alarm-list' });
    this.el = h(
      'div',
      { class: 'alarms' },
      h('div', { class: 'panel-head' }, h('h2', {}, 'Active alarms ', this.count)),
      this.list,
    );
    this.renderEmpty();
    window.setInterval(() => this.tick(), 1000);
  }

  private renderEmpty(): void {
    this.list.replaceChildren(h('div', { class: 'empty' }, 'No active alarms.'));
  }

  update(s: Status): void {
    this.lastStatus = s;
    const key = s.alarms.join(',');
    if (key !== this.key) {
      this.key = key;
      void this.refresh();
    }
  }

  /** Refetch (also after a reconnect). */
  async refresh(): Promise<void> {
    if (this.inflight) {
      this.again = true;
      return;
    }
    this.inflight = true;
    try {
      const alarms = await fetchAlarms();
      this.render(alarms);
    } catch (e) {
      this.list.replaceChildren(h('div', { class: 'empty error' }, `Cannot read the alarms: ${(e as Error).message}`));
    } finally {
      this.inflight = false;
      if (this.again) {
        this.again = false;
        void this.refresh();
      }
    }
  }

  private render(alarms: Alarm[]): void {
    this.onAlarms?.(alarms);
    setText(this.count, String(alarms.length));
    this.count.dataset.n = String(alarms.length);
    if (alarms.length === 0) {
      this.alarms = [];
      this.renderEmpty();
      return;
    }
    alarms.sort((x, y) => (SEVERITY_RANK[x.severity] ?? 9) - (SEVERITY_RANK[y.severity] ?? 9) || x.since - y.since);
    const now = Date.now();
    const t = this.lastStatus?.t ?? 0;
    this.alarms = alarms.map((a) => {
      const at = now - Math.max(0, t - a.since) * this.cyclePeriodMs;
      const age = h('span', { class: 'alarm-age' }, '');
      const el = h(
        'div',
        { class: `alarm sev-${a.severity}`, 'data-name': a.name },
        h(
          'div',
          { class: 'alarm-top' },
          h('span', { class: 'alarm-num' }, String(a.number)),
          h('span', { class: 'alarm-name' }, a.name),
          h('span', { class: `sev sev-${a.severity}` }, a.severity),
        ),
        h('div', { class: 'alarm-detail' }, a.detail || a.text),
        a.detail && a.detail !== a.text ? h('div', { class: 'alarm-text' }, a.text) : null,
        h('div', { class: 'alarm-remedy' }, h('b', {}, 'Remedy: '), a.remedy),
        h('div', { class: 'alarm-since' }, `since ${clockTime(new Date(at))} `, age, ` · cycle ${a.since}`),
      );
      return { a, at, el, age };
    });
    this.list.replaceChildren(...this.alarms.map((x) => x.el));
    this.tick();
  }

  private tick(): void {
    const now = Date.now();
    for (const x of this.alarms) setText(x.age, `(${ago(now - x.at)})`);
  }
}

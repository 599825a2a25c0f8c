// The event history: pages of GET /api/events (oldest first, `after` = id) shown newest
// first, and live `event` messages on the newest page. The API has no "latest" query,
// so the newest id is found by probing `after` with limit=1 (exponential, then binary).
// Runs of the same command with the same result (a jog's keep-alives) share one row.
import { fetchEvents, type HmiEvent } from './api';
import { h, setText } from './dom';
import { resultWords } from './words';

const PAGE = 200;
const MAX_ROWS = 120;

async function lastId(): Promise<number> {
  const has = async (after: number) => (await fetchEvents(after, 1)).length > 0;
  const first = await fetchEvents(0, 1);
  if (first.length === 0) return 0;
  let lo = first[0].id ?? 1; // lo < newest id + 1 (an event with id > lo - 1 exists)
  let step = 256;
  let hi = lo + step;
  while (await has(hi)) {
    lo = hi;
    step *= 4;
    hi = lo + step;
  }
  // has(lo - 1 or lo) true, has(hi) false: find the smallest `after` with no event.
  lo = Math.max(0, lo - 1);
  while (hi - lo > 1) {
    const mid = Math.floor((lo + hi) / 2);
    if (await has(mid)) lo = mid;
    else hi = mid;
  }
  return hi;
}

function time(e: HmiEvent): string {
  const d = new Date(e.time);
  if (Number.isNaN(d.getTime())) return e.time;
  const p = (n: number, w = 2) => String(n).padStart(w, '0');
  return `${p(d.getHours())}:${p(d.getMinutes())}:${p(d.getSeconds())}.${p(d.getMilliseconds(), 3)}`;
}

const str = (v: unknown): string => (v === null || v === undefined ? '' : String(v));

export function describeEvent(e: HmiEvent): { text: string; tone: string; kind: string } {
  const d = e.data;
  switch (e.kind) {
    case 'transition': {
      const stop = d.stop ? ` · ${str(d.stop)}` : '';
      const cause = d.cause ? ` — ${str(d.cause)}` : '';
      return { kind: 'state', text: `${str(d.from)} → ${str(d.to)}${stop}${cause}`, tone: d.stop ? 'stop' : 'info' };
    }
    case 'alarm':
      return {
        kind: 'alarm',
        text: `${str(d.number)} ${str(d.name)}: ${str(d.detail) || str(d.text)}`,
        tone: str(d.severity),
      };
    case 'alarm_cleared':
      return { kind: 'cleared', text: `${str(d.name)} cleared`, tone: 'ok' };
    case 'command': {
      const r = str(d.result);
      const ok = r === 'OK';
      const words = ok ? '' : ` — ${resultWords(r, str(d.cmd), null)}`;
      return { kind: 'cmd', text: `${str(d.cmd)} from ${str(d.from)}: ${r}${words}`, tone: ok ? 'ok' : 'refused' };
    }
    case 'config_validated':
      return {
        kind: 'safety',
        text: `Safety configuration ${str(d.checksum)} validated by ${str(d.client) || str(d.role)}`,
        tone: 'ok',
      };
  }
  return { kind: e.kind, text: JSON.stringify(d), tone: 'info' };
}

interface Row {
  first: HmiEvent; // oldest event of the run
  last: HmiEvent; // newest
  n: number;
  el: HTMLElement;
  count: HTMLElement;
  time: HTMLElement;
}

const runKey = (e: HmiEvent): string | null =>
  e.kind === 'command' ? `${String(e.data.cmd)}|${String(e.data.from)}|${String(e.data.result)}` : null;

export class History {
  readonly el: HTMLElement;
  private list: HTMLElement;
  private pos: HTMLElement;
  private rows: Row[] = []; // newest first
  private live = true;
  private newest = 0;
  private ready = false;
  private buffered: HmiEvent[] = [];
  private btnOlder: HTMLButtonElement;
  private btnNewer: HTMLButtonElement;
  private btnLatest: HTMLButtonElement;

  constructor() {
    this.list = h('div', { class: 'event-list', id: 'event-list' });
    this.pos = h('span', { class: 'page-pos' }, '');
    this.btnOlder = h('button', { type: 'button', class: 'btn small', id: 'events-older', onclick: () => void this.older() }, '◀ Older');
    this.btnNewer = h('button', { type: 'button', class: 'btn small', id: 'events-newer', onclick: () => void this.newer() }, 'Newer ▶');
    this.btnLatest = h('button', { type: 'button', class: 'btn small', id: 'events-latest', onclick: () => void this.latest() }, 'Latest');
    this.el = h(
      'div',
      { class: 'history' },
      h('div', { class: 'panel-head' }, h('h2', {}, 'History'), h('div', { class: 'pager' }, this.btnOlder, this.btnNewer, this.btnLatest)),
      this.pos,
      this.list,
    );
  }

  async latest(): Promise<void> {
    try {
      this.newest = Math.max(this.newest, await lastId());
      const page = await fetchEvents(Math.max(0, this.newest - PAGE), PAGE);
      this.live = true;
      this.show(page);
      this.ready = true;
      for (const e of this.buffered) this.push(e);
      this.buffered = [];
    } catch (e) {
      this.list.replaceChildren(h('div', { class: 'empty error' }, `Cannot read the event log: ${(e as Error).message}`));
    }
  }

  private async older(): Promise<void> {
    const oldest = this.rows[this.rows.length - 1]?.first.id;
    if (!oldest || oldest <= 1) return;
    const page = (await fetchEvents(Math.max(0, oldest - 1 - PAGE), PAGE)).filter((e) => (e.id ?? 0) < oldest);
    if (page.length === 0) return;
    this.live = false;
    this.show(page);
  }

  private async newer(): Promise<void> {
    const top = this.rows[0]?.last.id;
    if (!top) return;
    const page = await fetchEvents(top, PAGE);
    if (page.length < PAGE || (page[page.length - 1].id ?? 0) >= this.newest) {
      await this.latest();
      return;
    }
    this.show(page);
  }

  /** A live `event` message. */
  push(e: HmiEvent): void {
    if (e.id) this.newest = Math.max(this.newest, e.id);
    if (!this.ready) {
      this.buffered.push(e);
      return;
    }
    if (!this.live) {
      this.renderPos();
      return;
    }
    if (e.id && this.rows.some((r) => (r.last.id ?? 0) >= e.id!)) return;
    this.add(e, true);
    while (this.rows.length > MAX_ROWS) {
      this.rows.pop()?.el.remove();
    }
    this.renderPos();
  }

  /** Adds a newer event at the top (joining the top row's run when it continues it). */
  private add(e: HmiEvent, live: boolean): void {
    const top = this.rows[0];
    const key = runKey(e);
    if (top && key !== null && runKey(top.last) === key) {
      top.last = e;
      top.n++;
      setText(top.count, `×${top.n}`);
      setText(top.time, time(e));
      return;
    }
    const row = this.row(e);
    this.rows.unshift(row);
    if (live) this.list.querySelector('.empty')?.remove();
    this.list.prepend(row.el);
  }

  /** Shows a page of events, given oldest first. */
  private show(events: HmiEvent[]): void {
    this.rows = [];
    this.list.replaceChildren();
    for (const e of events) this.add(e, false);
    if (events.length === 0) this.list.append(h('div', { class: 'empty' }, 'No events yet.'));
    this.list.scrollTop = 0;
    this.renderPos();
  }

  private renderPos(): void {
    const top = this.rows[0]?.last.id ?? 0;
    const bottom = this.rows[this.rows.length - 1]?.first.id ?? 0;
    const where = this.live ? 'live' : `${this.newest - top} newer event(s) not shown`;
    setText(this.pos, this.rows.length ? `Events ${bottom}–${top} of ${this.newest} · ${where}` : '');
    this.btnOlder.disabled = bottom <= 1;
    this.btnNewer.disabled = this.live;
    this.btnLatest.disabled = this.live;
  }

  private row(e: HmiEvent): Row {
    const d = describeEvent(e);
    const bb = e.blackbox ? h('span', { class: 'bb', title: `black box stored: ${e.blackbox}` }, 'BB') : null;
    const count = h('span', { class: 'run-count' }, '');
    const t = h('span', { class: 'event-time', title: `cycle ${e.t}` }, time(e));
    const el = h(
      'div',
      { class: `event tone-${d.tone}`, 'data-kind': e.kind, 'data-id': e.id ?? '' },
      t,
      h('span', { class: `event-kind k-${d.kind}` }, d.kind),
      h('span', { class: 'event-text' }, d.text, ' ', count),
      bb ?? h('span', {}),
    );
    return { first: e, last: e, n: 1, el, count, time: t };
  }
}

// SafeState pendant: wires the WebSocket link, the banner, the commands and jog panel,
// the 3D view, alarms, history, the simulated cell and the real-time figures.
import './style.css';
import { AlarmList } from './alarms';
import { type Alarm, type ChannelStatus, fetchMetricsText, fetchRobot, fetchSafety, fetchStatus, type HmiEvent, type Robot, type SafetyInfo, type Status } from './api';
import { createArmView, type ArmDrawing } from './arm-view';
import { Link, type LinkState, type Outcome, type Role } from './connection';
import { $, deg, h, setAttr, setText, toggleClass } from './dom';
import { SpeedGauge } from './gauge';
import { History } from './history';
import { JogPanel } from './jog';
import { fmtSeconds, type Metrics, parseMetrics, quantile } from './metrics';
import { personDrawing } from './person';
import { SafetyPage } from './safety-page';
import { highlights, ZONE_STYLE } from './safety-logic';
import { SimPanel } from './sim-panel';
import {
  COMMAND_LABEL,
  ERROR_WORDS,
  MODE_WORDS,
  nextStep,
  resultWords,
  STATE_WORDS,
  STOP_WORDS,
  SUB_WORDS,
  toneOf,
} from './words';

// ------------------------------------------------------------------ shared state
let status: Status | null = null;
let statusAt = 0;
let linkState: LinkState = 'connecting';
let role: Role = null;
let linkNote = '';
let armView: ArmDrawing | null = null;
let robot: Robot | null = null;
const outcomes: Outcome[] = [];

interface Exposed {
  status: Status | null;
  link: { state: LinkState; role: Role };
  outcomes: Outcome[];
  view?: unknown;
}
const exposed = (): Exposed => {
  const w = window as unknown as { safestateHmi?: Exposed };
  w.safestateHmi ??= { status: null, link: { state: linkState, role }, outcomes };
  return w.safestateHmi;
};

// ------------------------------------------------------------------ link
const link = new Link({
  status: (s) => onStatus(s),
  event: (e) => onEvent(e),
  outcome: (o) => onOutcome(o),
  link: (st, r, note) => {
    linkState = st;
    role = r;
    linkNote = note;
    exposed().link = { state: st, role: r };
    if (st === 'closed') jog.stop('connection lost');
    if (st === 'open' && r === 'pendant') {
      $('token-error').hidden = true;
    }
    if (st === 'open') {
      void alarms.refresh();
      void history.latest();
      void loadSafety();
    }
    renderConnection();
    scheduleRender();
  },
  protocolError: (code, detail) => onProtocolError(code, detail),
});

// ------------------------------------------------------------------ commands panel
const resultBox = h(
  'div',
  { class: 'result', id: 'cmd-result', 'data-tone': 'idle', 'aria-live': 'polite' },
  h('div', { class: 'result-head', id: 'cmd-result-head' }, 'Command results appear here.'),
  h('div', { class: 'result-text', id: 'cmd-result-text' }, 'Every command gets exactly one answer from the controller.'),
);

const COMMANDS: { cmd: string; cls?: string }[] = [
  { cmd: 'reset', cls: 'reset' },
  { cmd: 'servo_on', cls: 'go' },
  { cmd: 'servo_off' },
  { cmd: 'start', cls: 'go' },
  { cmd: 'pause' },
  { cmd: 'resume', cls: 'go' },
  { cmd: 'stop' },
  { cmd: 'confirm_t2' },
];
const cmdButtons = new Map<string, HTMLButtonElement>();
const cmdGrid = h('div', { class: 'cmd-grid' });
for (const { cmd, cls } of COMMANDS) {
  const b = h(
    'button',
    { type: 'button', class: `btn cmd ${cls ?? ''}`, id: `cmd-${cmd.replace('_', '-')}`, 'data-cmd': cmd },
    cmd === 'reset' ? h('span', { class: 'lamp', id: 'reset-lamp', title: 'Reset lamp' }) : null,
    COMMAND_LABEL[cmd],
  );
  b.addEventListener('click', () => link.command(cmd));
  cmdButtons.set(cmd, b);
  cmdGrid.append(b);
}

const jog = new JogPanel(link, (axis) => armView?.highlight(axis));
(exposed() as unknown as Record<string, unknown>).jog = jog.stats;
const controls = $('controls');
controls.append(
  h('div', { class: 'panel-head' }, h('h2', {}, 'Commands'), h('span', { class: 'panel-hint', id: 'owner' }, '')),
  cmdGrid,
  resultBox,
  jog.el,
);

function showResult(tone: 'ok' | 'refused' | 'failed', head: string, text: string, code: string, cmd: string): void {
  resultBox.dataset.tone = tone;
  resultBox.dataset.result = code;
  resultBox.dataset.cmd = cmd;
  const headEl = $('cmd-result-head');
  headEl.replaceChildren(head, code && code !== 'OK' ? h('span', { class: 'result-code' }, code) : '');
  setText($('cmd-result-text'), text);
  resultBox.title = `${head} ${code}: ${text}`;
  resultBox.classList.remove('flash');
  void resultBox.offsetWidth; // restart the flash animation
  resultBox.classList.add('flash');
}

function onOutcome(o: Outcome): void {
  outcomes.push(o);
  if (outcomes.length > 100) outcomes.shift();
  const ok = o.result === 'OK';
  if (o.show === 'none' || (ok && o.show === 'refusals')) return;
  const label = o.kind === 'sim' ? `Simulated cell: ${o.cmd}` : COMMAND_LABEL[o.cmd] ?? o.cmd;
  if (ok) {
    showResult('ok', `${label}: accepted`, o.kind === 'sim' ? 'The simulated device changed.' : 'The controller accepted the command.', 'OK', o.cmd);
    return;
  }
  if (o.result === 'NOT_SENT') {
    showResult('failed', `${label}: not sent`, 'There is no connection to the controller: nothing was sent. Wait for the connection.', o.result, o.cmd);
  } else if (o.result === 'NO_REPLY') {
    showResult('failed', `${label}: no answer`, `The controller did not answer (${o.detail ?? ''}); check the state before trying again.`, o.result, o.cmd);
  } else if (o.kind === 'sim') {
    showResult('failed', `${label}: refused`, `${ERROR_WORDS[o.result] ?? o.result}${o.detail ? ` ${o.detail}` : ''}`, o.result, o.cmd);
  } else {
    showResult('refused', `${label} refused`, resultWords(o.result, o.cmd, status), o.result, o.cmd);
  }
}

function onProtocolError(code: string, detail: string): void {
  if (code === 'ROLE_TAKEN') {
    // On connecting this only makes the screen an observer; after "Take control" it answers it.
    if (role === 'observer') showResult('failed', 'Take control: refused', `${ERROR_WORDS.ROLE_TAKEN} ${detail}`, code, 'hello');
    return;
  }
  if (code === 'BAD_TOKEN') {
    const dlg = $('token-dialog') as HTMLDialogElement;
    const err = $('token-error');
    if (tokenTried) {
      err.textContent = 'That token was refused: check it and try again.';
      err.hidden = false;
    }
    if (!dlg.open) dlg.showModal();
    return;
  }
  if (code === 'NOT_HELLO') {
    showResult('failed', 'Connection closed', 'The controller closed the connection: the screen did not say hello in time. Reconnecting.', code, 'hello');
    return;
  }
  if (code === 'NOT_SIMULATED' || code === 'BAD_MESSAGE' || code === 'TOO_LARGE') return; // answered a sim (outcome)
  showResult('failed', 'Gateway error', `${ERROR_WORDS[code] ?? ''} ${detail}`.trim(), code, '');
}

let tokenTried = false;
($('token-form') as HTMLFormElement).addEventListener('submit', (e) => {
  const submitter = (e as SubmitEvent).submitter as HTMLButtonElement | null;
  const input = $('token-input') as HTMLInputElement;
  const token = input.value;
  input.value = '';
  if (submitter?.value === 'ok' && token) {
    tokenTried = true;
    link.setToken(token);
  }
});

// ------------------------------------------------------------------ view
const gauge = new SpeedGauge();
$('gauge-slot').append(gauge.el);
$('clear-trail').addEventListener('click', () => armView?.clearTrail());

const alarms = new AlarmList();
$('alarms-slot').append(alarms.el);
const history = new History();
$('history-slot').append(history.el);

const sim = new SimPanel(link);
$('sim-slot').append(sim.el);

// ------------------------------------------------------------------ safety (SPEC §10)
const safety = new SafetyPage(link);
$('safety-page').append(safety.el);
$('safety-strip-slot').append(safety.strip);
document.body.append(safety.dialog);
let safetyInfo: SafetyInfo | null = null;
let safetyLoading = false;
let safetyAgain = false;
let alarmObjects: Alarm[] = [];
let lastSafetyKey: string | null = null;

function showPage(page: 'operate' | 'safety'): void {
  const main = $('main');
  main.dataset.page = page;
  $('safety-page').hidden = page !== 'safety';
  setAttr($('tab-operate'), 'aria-selected', page === 'operate' ? 'true' : 'false');
  setAttr($('tab-safety'), 'aria-selected', page === 'safety' ? 'true' : 'false');
  if (page === 'operate') armView?.update(status?.joints ?? [0, 0, 0, 0, 0, 0]);
}
$('tab-operate').addEventListener('click', () => showPage('operate'));
$('tab-safety').addEventListener('click', () => showPage('safety'));
safety.strip.addEventListener('click', () => showPage('safety'));

/** GET /api/safety: at connection, when the checksum or validated changes, and after a
 * config_validated event (the confirmation's client and time). */
async function loadSafety(): Promise<void> {
  if (safetyLoading) {
    safetyAgain = true;
    return;
  }
  safetyLoading = true;
  try {
    const info = await fetchSafety();
    if (!info || typeof info !== 'object' || !info.config) throw new Error('the controller reports no safety configuration');
    safetyInfo = info;
    safety.setInfo(safetyInfo);
  } catch (e) {
    safetyInfo = null;
    safety.setInfo(null, (e as Error).message);
  } finally {
    safetyLoading = false;
  }
  applySafetyDrawing();
  if (safetyAgain) {
    safetyAgain = false;
    void loadSafety();
  }
}

function applySafetyDrawing(): void {
  const c = safetyInfo?.config;
  jog.setSafety(c?.joints ?? null);
  armView?.setSafety(
    c ? { zones: c.zones ?? [], tcp_mm: (c.tool?.tcp_mm ?? [0, 0, 0]) as [number, number, number], radius_mm: c.tool?.radius_mm ?? 0 } : null,
  );
  const legend = $('zone-legend');
  legend.hidden = !c;
  if (c) {
    const kinds = new Set(c.zones.map((z) => z.kind));
    legend.replaceChildren(
      ...Object.entries(ZONE_STYLE)
        .filter(([k]) => kinds.has(k as keyof typeof ZONE_STYLE))
        .map(([k, st]) => h('div', { class: 'legend-item', 'data-kind': k }, h('span', { class: 'swatch', style: `--c: ${st.color}` }), st.label)),
      c.tool.radius_mm > 0 ? h('div', { class: 'legend-item' }, h('span', { class: 'swatch round', style: '--c: #4dd0e1' }), `tool ⌀${c.tool.radius_mm * 2} mm`) : '',
    );
  }
  highlightKey = ''; // the view's marks were reset with its zones: mark them again
  applyHighlight();
}

let highlightKey = '';
function applyHighlight(): void {
  const zoneNames = safetyInfo?.config.zones.map((z) => z.name) ?? [];
  const hl = highlights(status?.alarms ?? [], alarmObjects, zoneNames);
  const key = JSON.stringify(hl);
  if (key === highlightKey) return;
  highlightKey = key;
  armView?.markZones({ violated: hl.zones, active: hl.activeZones });
  const labels = new Map<number, string>();
  for (const v of hl.violations) if (v.axis !== null) labels.set(v.axis, v.alarm);
  jog.setViolated(hl.joints, labels);
  safety.setHighlight(hl);
  (exposed() as unknown as Record<string, unknown>).highlight = hl;
}
alarms.onAlarms = (list) => {
  alarmObjects = list;
  safety.setAlarms(list);
  applyHighlight();
};

// TCP readout over the 3D view: X Y Z (mm), Rx Ry Rz.
const readout = ['X', 'Y', 'Z', 'Rx', 'Ry', 'Rz'].map((n) => h('b', { id: `tcp-${n.toLowerCase()}` }, '—'));
$('tcp-readout').append(
  h('div', { class: 'ro-title' }, 'TCP in base frame (mm, °)'),
  h(
    'div',
    { class: 'ro-grid' },
    ...[0, 3, 1, 4, 2, 5].flatMap((i) => [h('span', {}, ['X', 'Y', 'Z', 'Rx', 'Ry', 'Rz'][i]), readout[i]]),
  ),
);

// IO pills in the banner.
const io = {
  contactor: h('span', { class: 'pill', id: 'io-contactor' }),
  drives: h('span', { class: 'pill', id: 'io-drives' }),
  brakes: h('span', { class: 'pill', id: 'io-brakes' }),
  owner: h('span', { class: 'pill', id: 'io-owner' }),
  chA: h('span', { class: 'pill', id: 'io-channel-a', hidden: '' }),
  chB: h('span', { class: 'pill', id: 'io-channel-b', hidden: '' }),
};
$('b-io').append(io.contactor, io.drives, io.brakes, io.chA, io.chB, io.owner);

// SPEC §14: a channel's pill: whether it runs, answers and agrees with the other; the
// details (compiler, process, state, cycle, last digest) in its title.
function channelPill(el: HTMLElement, c: ChannelStatus | undefined): void {
  if (!c) {
    el.hidden = true;
    return;
  }
  el.hidden = false;
  const word = !c.running ? 'gone' : !c.answered ? 'silent' : !c.agree ? (c.differs_in ? `differs: ${c.differs_in}` : 'other lost') : 'agrees';
  pill(el, `Channel ${c.name} ${word}`, c.running && c.answered && c.agree,
    `Channel ${c.name} (${c.compiler ?? '?'}${c.pid ? `, pid ${c.pid}` : ''}): ${c.state}, cycle ${c.cycle}, ` +
    `digest ${c.digest}${c.agree ? ', agrees with the other channel' : ''}` +
    (c.late ? `, ${c.late} cycles late` : '') + (c.skipped ? `, ${c.skipped} skipped` : ''));
  setAttr(el, 'data-agree', c.running && c.answered && c.agree ? 'yes' : 'no');
}

function pill(el: HTMLElement, text: string, on: boolean, title: string): void {
  setText(el, text);
  toggleClass(el, 'on', on);
  setAttr(el, 'title', title);
}

// ------------------------------------------------------------------ rendering
// Status arrives at 50 Hz. A change of state, mode, stop, cause, alarms or outputs is
// drawn in the next frame; positions and speeds alone at most every MOTION_MS, which
// leaves the page's time to the jog keep-alive (the 3D view has its own frame cap).
const MOTION_MS = 66;
let renderQueued = false;
let lastRender = 0;
let trailing = 0;
let discreteKey = '';

function scheduleRender(): void {
  if (renderQueued) return;
  renderQueued = true;
  window.clearTimeout(trailing);
  trailing = 0;
  requestAnimationFrame(() => {
    renderQueued = false;
    lastRender = performance.now();
    render();
  });
}

function discrete(s: Status): string {
  return [s.state, s.sub, s.mode, s.mode_requested, s.stop, s.cause, s.target, s.arming_step, s.alarms.join(','),
    s.reset_lamp, s.contactor, s.drives, s.brakes, s.owner, s.t2_confirmed, s.simulated, s.shutting_down,
    JSON.stringify(s.contactors ?? null),
    (s.channels ?? []).map((c) => `${c.running}${c.answered}${c.agree}${c.state}`).join(',')].join('|');
}

function onStatus(s: Status): void {
  const first = status === null;
  status = s;
  statusAt = performance.now();
  exposed().status = s;
  alarms.update(s);
  sim.update(s);
  // The confirmation (client, time) and the file come from /api/safety: read again when
  // the core's checksum or validated changes.
  const safetyKey = s.safety ? `${s.safety.checksum}|${s.safety.validated}` : '';
  if (safetyKey !== lastSafetyKey) {
    if (lastSafetyKey !== null) void loadSafety();
    lastSafetyKey = safetyKey;
  }
  armView?.update(s.joints);
  armView?.setPerson(personDrawing(s));
  if (first) renderConnection();
  const key = discrete(s);
  const wait = lastRender + MOTION_MS - performance.now();
  if (key !== discreteKey || wait <= 0) {
    discreteKey = key;
    scheduleRender();
  } else if (!trailing && !renderQueued) {
    trailing = window.setTimeout(() => {
      trailing = 0;
      scheduleRender();
    }, wait);
  }
}

function onEvent(e: HmiEvent): void {
  history.push(e);
  if (e.kind === 'alarm' || e.kind === 'alarm_cleared') void alarms.refresh();
  if (e.kind === 'config_validated') void loadSafety();
}

function suggested(s: Status): Set<string> {
  const want = new Set<string>();
  const latched = s.reset_lamp === 'on';
  switch (s.state) {
    case 'ESTOP_RESET_NEEDED':
      want.add('reset');
      break;
    case 'IDLE':
      if (latched) want.add('reset');
      else if (s.mode === 'T2' && !s.t2_confirmed) want.add('confirm_t2');
      else if (s.mode !== 'NONE') want.add('servo_on');
      break;
    case 'OPERATIONAL':
      if (s.sub === 'AUTO_IDLE' || s.sub === 'MANUAL_IDLE') want.add('start');
      if (s.sub === 'AUTO_PAUSED') want.add('resume');
      if (s.sub === 'AUTO_RUNNING' || s.sub === 'MANUAL_RUNNING') want.add('pause').add('stop');
      break;
  }
  return want;
}

function render(): void {
  const banner = $('banner');
  const s = status;
  const online = linkState === 'open' && s !== null && performance.now() - statusAt < 1500;
  if (!s) {
    banner.dataset.tone = 'offline';
    return;
  }
  const tone = online ? toneOf(s) : 'offline';
  setAttr(banner, 'data-tone', tone);
  setAttr(banner, 'data-state', s.state);
  setText($('b-state'), s.state);
  let words = STATE_WORDS[s.state];
  if (s.state === 'STOPPING' && s.target) words += ` → ${s.target}`;
  if (s.state === 'ARMING' && s.arming_step) words += `: step ${s.arming_step}`;
  if (!online) words = `Last known state — ${linkState === 'open' ? 'no status from the controller' : 'not connected'}`;
  setText($('b-sub'), s.sub ?? '');
  if (s.sub && online) words = SUB_WORDS[s.sub] ?? words;
  setText($('b-state-words'), s.sub ? ` · ${words}` : words);
  const req = s.mode_requested && s.mode_requested !== s.mode ? ` (key: ${s.mode_requested})` : '';
  setText($('b-mode'), s.mode + req);
  let modeWords = MODE_WORDS[s.mode];
  if (s.mode === 'T2') modeWords += s.t2_confirmed ? ' · confirmed' : ' · not confirmed';
  setText($('b-mode-words'), modeWords);
  setAttr($('b-mode'), 'data-mode', s.mode);
  setText($('b-stop'), s.stop ?? '—');
  setText($('b-stop-words'), s.stop ? STOP_WORDS[s.stop] : 'no stop in progress');
  setText($('b-cause'), s.cause ?? 'none');
  let next = online ? nextStep(s) : 'Wait for the connection to the controller.';
  if (online && role === 'observer') next = `Read-only: another pendant has control. ${next}`;
  if (s.shutting_down) next = 'The controller is shutting down (Cat 1 stop).';
  setText($('b-next'), next);

  const k = s.contactors;
  if (k && k.k2 !== null) {
    pill(io.contactor, `K1 ${k.k1} · K2 ${k.k2}`, k.k1 === 'closed' && k.k2 === 'closed',
      'Power path: K1 (channel A) and K2 (channel B) in series, as their auxiliary contacts read');
  } else {
    pill(io.contactor, `Contactor ${s.contactor}`, s.contactor === 'closed', 'Main contactor');
  }
  const two = (s.channels ?? []).length === 2;
  channelPill(io.chA, two ? s.channels![0] : undefined);
  channelPill(io.chB, two ? s.channels![1] : undefined);
  pill(io.drives, `Drives ${s.drives}`, s.drives === 'enabled', 'Drive power stage (safe torque off when disabled)');
  pill(io.brakes, `Brakes ${s.brakes}`, s.brakes === 'released', 'Holding brakes');
  pill(io.owner, `Control: ${s.owner ?? 'nobody'}`, s.owner === 'pendant' && role === 'pendant', 'Single point of control (ISO 10218-1)');

  toggleClass($('reset-lamp'), 'on', s.reset_lamp === 'on');
  const want = suggested(s);
  for (const [cmd, b] of cmdButtons) toggleClass(b, 'suggested', want.has(cmd));
  toggleClass(cmdButtons.get('confirm_t2')!, 'dim', s.mode !== 'T2');
  setText($('owner'), role === 'pendant' ? 'This pendant has control' : role === 'observer' ? 'Read-only (observer)' : '');

  jog.update(s);
  safety.update(s, role, linkState);
  applyHighlight();
  gauge.update(s.tcp_speed, s.mode, s.max_point_speed);
  const [x, y, z, rx, ry, rz] = s.tcp;
  const ro = [x.toFixed(1), y.toFixed(1), z.toFixed(1), `${deg(rx).toFixed(1)}°`, `${deg(ry).toFixed(1)}°`, `${deg(rz).toFixed(1)}°`];
  ro.forEach((v, i) => setText(readout[i], v));
  const prog = $('program');
  if (s.program_length) {
    setText(prog, `Program waypoint ${s.program_index ?? 0} / ${s.program_length}`);
  }
  const simSlot = $('sim-slot');
  if (simSlot.hidden === !!s.simulated) simSlot.hidden = !s.simulated;
  document.body.dataset.simulated = s.simulated ? 'yes' : 'no';
}

function renderConnection(): void {
  const dot = $('conn-dot');
  const stale = linkState === 'open' && status !== null && performance.now() - statusAt > 1500;
  let text: string;
  let cls: string;
  if (linkState === 'open' && !stale) {
    text = role === 'pendant' ? 'Connected · pendant' : 'Read-only (observer)';
    cls = role === 'pendant' ? 'ok' : 'warn';
  } else if (stale) {
    text = `No status for ${((performance.now() - statusAt) / 1000).toFixed(0)} s`;
    cls = 'bad';
  } else {
    text = linkState === 'connecting' ? 'Connecting…' : 'Disconnected';
    cls = 'bad';
  }
  const age = status?.core_heartbeat_age_ms;
  let note = linkState === 'open' ? '' : linkNote;
  if (linkState === 'open' && age !== undefined && age > 200) {
    note = `Core not cycling for ${age.toFixed(0)} ms`;
    cls = 'bad';
  }
  setText($('conn-text'), text);
  setAttr(dot, 'data-state', cls);
  setAttr($('conn'), 'data-link', linkState);
  setAttr($('conn'), 'data-role', role ?? '');
  setAttr($('conn'), 'title', link.server ? `Gateway: ${link.server}` : 'Gateway');
  setText($('conn-note'), note);
  const actions = $('conn-actions');
  if (linkState === 'open' && role === 'observer' && !actions.firstChild) {
    actions.append(h('button', { type: 'button', class: 'btn small', id: 'take-control', onclick: () => link.takeControl() }, 'Take control'));
  } else if (!(linkState === 'open' && role === 'observer') && actions.firstChild) {
    actions.replaceChildren();
  }
}

window.setInterval(() => {
  renderConnection();
  if (status && performance.now() - statusAt > 1500) scheduleRender();
}, 250);

// ------------------------------------------------------------------ metrics
let prevMetrics: Metrics | null = null;
async function pollMetrics(): Promise<void> {
  const el = $('metrics');
  try {
    const m = parseMetrics(await fetchMetricsText());
    const sc = (k: string) => m.scalars.get(k);
    const period = sc('safestate_cycle_period_seconds');
    if (period) alarms.cyclePeriodMs = period * 1000;
    const win = (name: string) => {
      const now = m.hist.get(name);
      const before = prevMetrics?.hist.get(name);
      if (!now) return { avg: null, p99: null };
      const n = now.count - (before?.count ?? 0);
      const avg = n > 0 ? (now.sum - (before?.sum ?? 0)) / n : null;
      return { avg, p99: quantile(now, before, 0.99) };
    };
    const exec = win('safestate_cycle_exec_seconds');
    const late = win('safestate_cycle_lateness_seconds');
    const overruns = sc('safestate_overruns_total') ?? 0;
    const newOverruns = overruns - (prevMetrics?.scalars.get('safestate_overruns_total') ?? overruns);
    const prio = sc('safestate_rt_priority');
    const item = (label: string, value: string, cls = '', id = '') =>
      h('span', { class: `m-item ${cls}`, id: id || undefined }, h('span', { class: 'm-label' }, label), h('b', {}, value));
    el.replaceChildren(
      h('span', { class: 'm-title' }, 'Real-time'),
      item('cycle', fmtSeconds(period), '', 'm-period'),
      item('exec avg', fmtSeconds(exec.avg), '', 'm-exec'),
      item('exec max', fmtSeconds(sc('safestate_cycle_exec_max_seconds'))),
      item('lateness avg', fmtSeconds(late.avg), '', 'm-late'),
      item('p99 ≤', fmtSeconds(late.p99)),
      item('max', fmtSeconds(sc('safestate_cycle_lateness_max_seconds'))),
      item('overruns', `${overruns}${newOverruns > 0 ? ` (+${newOverruns})` : ''}`, newOverruns > 0 ? 'warn' : '', 'm-overruns'),
      item('watchdog trips', String(sc('safestate_watchdog_trips_total') ?? 0), (sc('safestate_watchdog_trips_total') ?? 0) > 0 ? 'warn' : ''),
      item('queue', String(sc('safestate_command_queue_depth') ?? 0)),
      item('RT prio', prio ? String(prio) : 'none', prio ? '' : 'warn'),
      item('clients', String(sc('safestate_ws_clients') ?? 0)),
    );
    el.dataset.updated = String(Date.now());
    prevMetrics = m;
  } catch (e) {
    el.replaceChildren(h('span', { class: 'm-title warn' }, `Real-time figures unavailable: ${(e as Error).message}`));
  } finally {
    window.setTimeout(() => void pollMetrics(), 2000);
  }
}

// ------------------------------------------------------------------ start
async function loadRobot(): Promise<void> {
  for (let attempt = 0; ; attempt++) {
    try {
      robot = await fetchRobot();
      break;
    } catch {
      await new Promise((r) => setTimeout(r, Math.min(5000, 500 * 2 ** attempt)));
    }
  }
  jog.setRobot(robot);
  safety.setRobot(robot);
  const container = $('arm');
  container.dataset.robot = robot.name;
  armView = createArmView(container, robot);
  container.dataset.renderer = armView.kind;
  applySafetyDrawing();
  armView.update(status?.joints ?? (await fetchStatus().catch(() => null))?.joints ?? [0, 0, 0, 0, 0, 0]);
  armView.setPerson(personDrawing(status));
}

link.connect();
void loadRobot();
void pollMetrics();

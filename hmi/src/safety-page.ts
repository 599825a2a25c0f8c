// The Safety page (SPEC §10): the active safety configuration as the controller holds it
// (GET /api/safety), its checksum large enough to read from a metre away, validated or not
// (status.safety, live), the limits (joints, TCP speeds, tool, orientation, zones), reduced
// mode and why, recovery, the violated limits named; and the validate dialog, where the
// operator types the checksum from the approved configuration record (`validate_config`,
// pendant only, IDLE, T1/T2: safety-logic.ts says when and why not).
// Also the strip under the banner that shows checksum, validated and reduced on every page.
// And the Collaborative section (SPEC §11): the protective fields, speed and separation
// monitoring, the TCP speed against the limit in force and why the robot is slow
// (safety-logic.ts slowWhy), collision detection with the contact force against F_qs, and a
// COLLISION alarm with its detail.
// And the Brake test section (SPEC §12): when it is due (overdue in red), the latest result
// and when it was recorded, the Run button (pendant, AUTO_IDLE/MANUAL_IDLE: safety-logic.ts
// brakeTestGate), the axes while it runs, and each axis' drift against max_drift_deg.
import type { Alarm, SafetyInfo, Status } from './api';
import type { Link, LinkState, Role } from './connection';
import { clockTime, deg, h, setAttr, setText, toggleClass } from './dom';
import { personWords } from './person';
import {
  brakeTestAxes,
  brakeTestDue,
  brakeTestGate,
  contactWords,
  hoursWords,
  lastPassAgeH,
  maxDriftDeg,
  type Highlight,
  reducedWords,
  slowWhy,
  typedCode,
  validateGate,
  validateReplyWords,
  violationLabel,
  ZONE_STYLE,
} from './safety-logic';
import { resultWords } from './words';

const fmt = (v: number, digits = 0) => (Number.isFinite(v) ? v.toFixed(digits) : '—');
const vec = (v: number[] | undefined) => (v ? `[${v.map((x) => fmt(x, Number.isInteger(x) ? 0 : 1)).join(', ')}]` : '—');

export class SafetyPage {
  readonly el: HTMLElement;
  readonly strip: HTMLElement;
  readonly dialog: HTMLDialogElement;
  private info: SafetyInfo | null = null;
  private infoError = '';
  private status: Status | null = null;
  private role: Role = null;
  private linkState: LinkState = 'closed';
  private hl: Highlight | null = null;
  private pendingSeq: number | null = null;
  private lastKey = '';
  private alarmObjects: Alarm[] = [];
  private brakeSeq: number | null = null;
  private e: Record<string, HTMLElement> = {};

  constructor(private readonly link: Link) {
    const el = (id: string, tag: keyof HTMLElementTagNameMap = 'div', cls = '', text = '') => {
      const x = h(tag, { id, class: cls }, text);
      this.e[id] = x;
      return x;
    };
    // ------------------------------------------------------------ strip
    this.strip = h(
      'button',
      { type: 'button', class: 'safety-strip', id: 'safety-strip', title: 'Open the Safety page' },
      h('span', { class: 'ss-label' }, 'Safety'),
      el('ss-checksum', 'b', 'ss-checksum', '—'),
      el('ss-valid', 'span', 'ss-valid', 'unknown'),
      el('ss-violation', 'span', 'ss-violation', ''),
      el('ss-reduced', 'span', 'ss-reduced', ''),
      el('ss-limit', 'span', 'ss-limit', ''),
    );

    // ------------------------------------------------------------ page
    const validateBtn = h('button', { type: 'button', class: 'btn primary', id: 'sp-validate' }, 'Validate…') as HTMLButtonElement;
    validateBtn.addEventListener('click', () => this.openDialog());
    this.e['sp-validate'] = validateBtn;
    this.el = h(
      'div',
      { class: 'safety-page-inner' },
      h(
        'div',
        { class: 'sp-top' },
        h(
          'div',
          { class: 'sp-id' },
          h('h2', {}, 'Safety configuration'),
          el('sp-name', 'div', 'sp-name', 'Loading…'),
          el('sp-source', 'div', 'sp-source', ''),
          el('sp-robot', 'div', 'sp-robot', ''),
        ),
        h(
          'div',
          { class: 'sp-checksum-box' },
          h('div', { class: 'sp-label' }, 'Checksum'),
          el('sp-checksum', 'div', 'sp-checksum', '—'),
        ),
        (this.e['sp-valid'] = h(
          'div',
          { class: 'sp-valid', id: 'sp-valid', 'data-validated': 'unknown' },
          el('sp-valid-word', 'div', 'sp-valid-word', '—'),
          el('sp-valid-text', 'div', 'sp-valid-text', ''),
          h('div', { class: 'sp-validate-line' }, validateBtn, el('sp-validate-why', 'div', 'sp-why', '')),
        )),
      ),
      el('sp-violations', 'div', 'sp-violations', ''),
      this.collabSection(el),
      this.brakeSection(el),
      h(
        'div',
        { class: 'sp-now' },
        h('div', { class: 'sp-card' }, h('div', { class: 'sp-label' }, 'TCP speed limit now'), el('sp-limit', 'div', 'sp-big', '—')),
        h(
          'div',
          { class: 'sp-card', id: 'sp-reduced-card' },
          h('div', { class: 'sp-label' }, 'Reduced speed'),
          el('sp-reduced', 'div', 'sp-big', '—'),
          el('sp-reduced-why', 'div', 'sp-small', ''),
        ),
        h(
          'div',
          { class: 'sp-card', id: 'sp-recovery-card' },
          h('div', { class: 'sp-label' }, 'Recovery'),
          el('sp-recovery', 'div', 'sp-big', '—'),
          el('sp-recovery-why', 'div', 'sp-small', ''),
        ),
      ),
      h(
        'div',
        { class: 'sp-cols' },
        h(
          'div',
          { class: 'sp-col' },
          h('h3', {}, 'Joint limits'),
          el('sp-joints', 'table', 'sp-table'),
        ),
        h(
          'div',
          { class: 'sp-col' },
          h('h3', {}, 'Zones (base frame, mm)'),
          el('sp-zones', 'table', 'sp-table'),
          el('sp-legend', 'div', 'sp-legend'),
          h('h3', {}, 'TCP, tool, orientation, stop'),
          el('sp-tcp', 'dl', 'sp-dl'),
        ),
      ),
    );

    // ------------------------------------------------------------ dialog
    const input = h('input', {
      id: 'validate-code',
      type: 'text',
      autocomplete: 'off',
      spellcheck: 'false',
      maxlength: 12,
      placeholder: '8 hex digits',
      'aria-label': 'Checksum (8 hex digits)',
    }) as HTMLInputElement;
    input.addEventListener('input', () => this.renderDialog());
    input.addEventListener('keydown', (ev) => {
      if (ev.key === 'Enter') {
        ev.preventDefault();
        this.send();
      }
    });
    this.e['validate-code'] = input;
    const send = h('button', { type: 'button', class: 'btn primary', id: 'validate-send' }, 'Validate') as HTMLButtonElement;
    send.addEventListener('click', () => this.send());
    this.e['validate-send'] = send;
    const close = h('button', { type: 'button', class: 'btn', id: 'validate-close' }, 'Close');
    close.addEventListener('click', () => this.dialog.close());
    this.dialog = h(
      'dialog',
      { id: 'validate-dialog', class: 'validate-dialog' },
      h('h2', {}, 'Validate the safety configuration'),
      h(
        'p',
        {},
        'Type the checksum written on the approved configuration record (the one the safety engineer signed, from ',
        h('code', {}, 'safestate safety check'),
        '), not the one on this screen. If they match, the controller runs the approved limits.',
      ),
      el('validate-config', 'p', 'vd-config', ''),
      input,
      el('validate-problem', 'div', 'vd-problem', ''),
      el('validate-why', 'div', 'vd-why', ''),
      el('validate-result', 'div', 'vd-result', ''),
      h('div', { class: 'dialog-actions' }, send, close),
    ) as HTMLDialogElement;
  }

  setInfo(info: SafetyInfo | null, error = ''): void {
    this.info = info;
    this.infoError = error;
    this.lastKey = '';
    this.renderConfig();
    this.render();
  }

  get config(): SafetyInfo['config'] | null {
    return this.info?.config ?? null;
  }

  update(s: Status | null, role: Role, linkState: LinkState): void {
    this.status = s;
    this.role = role;
    this.linkState = linkState;
    this.render();
  }

  /** The active alarms with their detail (GET /api/alarms): COLLISION's force. */
  setAlarms(list: Alarm[]): void {
    this.alarmObjects = list;
    this.renderCollab();
  }

  private collabSection(el: (id: string, tag?: keyof HTMLElementTagNameMap, cls?: string, text?: string) => HTMLElement): HTMLElement {
    const field = (which: 'outer' | 'inner', label: string) =>
      (this.e[`cb-field-${which}`] = h(
        'div',
        { class: 'cb-field', id: `cb-field-${which}`, 'data-state': 'unknown' },
        h('div', { class: 'sp-label' }, label),
        el(`cb-field-${which}-word`, 'div', 'cb-field-word', '—'),
      ));
    return (this.e['sp-collab'] = h(
      'section',
      { class: 'sp-collab', id: 'sp-collab', 'aria-label': 'Collaborative operation' },
      h('h3', {}, 'Collaborative operation (SPEC §11)', el('cb-enabled', 'span', 'cb-enabled', '')),
      Object.assign(el('cb-collision', 'div', 'cb-collision', ''), { hidden: true }),
      h(
        'div',
        { class: 'cb-grid' },
        h(
          'div',
          { class: 'sp-card cb-fields' },
          h('div', { class: 'sp-label' }, 'Protective fields (scanner)'),
          h('div', { class: 'cb-field-row' }, field('outer', 'Outer: slows'), field('inner', 'Inner: stops')),
          el('cb-person', 'div', 'sp-small', ''),
        ),
        h(
          'div',
          { class: 'sp-card' },
          h('div', { class: 'sp-label' }, 'Speed and separation'),
          el('cb-ssm', 'div', 'sp-big', '—'),
          el('cb-ssm-detail', 'div', 'sp-small', ''),
          el('cb-sim-person', 'div', 'sp-small cb-sim-person', ''),
        ),
        h(
          'div',
          { class: 'sp-card' },
          h('div', { class: 'sp-label' }, 'TCP speed / limit in force'),
          el('cb-speed', 'div', 'sp-big', '—'),
          h('div', { class: 'cb-bar' }, el('cb-speed-bar', 'div', 'cb-bar-fill', '')),
          el('cb-limit-by', 'div', 'sp-small', ''),
        ),
        h(
          'div',
          { class: 'sp-card' },
          h('div', { class: 'sp-label' }, 'Power and force limiting'),
          el('cb-pfl', 'div', 'sp-big', '—'),
          el('cb-force', 'div', 'cb-force', ''),
          h('div', { class: 'cb-bar' }, el('cb-force-bar', 'div', 'cb-bar-fill', '')),
        ),
      ),
      h('div', { class: 'sp-label cb-why-label' }, 'Why the robot is slow'),
      el('cb-why', 'ul', 'cb-why', ''),
    ));
  }

  private renderCollab(): void {
    const s = this.status;
    const sf = s?.safety;
    const collab = this.info?.config.collaborative as { enabled?: boolean } | undefined;
    setText(
      this.e['cb-enabled'],
      this.info ? (collab?.enabled ? ' · enabled in this configuration' : ' · not enabled in this configuration') : '',
    );
    for (const which of ['outer', 'inner'] as const) {
      const st = sf?.fields?.[which] ?? 'unknown';
      setAttr(this.e[`cb-field-${which}`], 'data-state', st);
      setText(this.e[`cb-field-${which}-word`], st === 'unknown' ? 'not reported' : st === 'clear' ? 'Clear' : 'INTERRUPTED');
    }
    const person = s?.alarms.includes('PERSON_IN_FIELD');
    setText(
      this.e['cb-person'],
      person
        ? 'PERSON_IN_FIELD: someone is in the inner field. The program pauses; it may not start or resume until both fields are clear.'
        : sf?.fields?.outer === 'interrupted'
          ? 'Someone is in the outer field: reduced speed while it lasts.'
          : sf?.fields
            ? 'Nobody in either field.'
            : '',
    );
    toggleClass(this.e['cb-person'], 'warn', !!person);
    // SSM
    if (sf && sf.v_allowed !== null && sf.v_allowed !== undefined) {
      setText(this.e['cb-ssm'], `${fmt(sf.v_allowed)} mm/s`);
      toggleClass(this.e['cb-ssm'], 'warn', sf.v_allowed <= 0);
      setText(
        this.e['cb-ssm-detail'],
        `v_allowed at a separation of ${sf.separation_mm != null ? `${fmt(sf.separation_mm)} mm` : 'unknown'}${sf.v_allowed <= 0 ? ': the robot holds' : ''}`,
      );
    } else {
      setText(this.e['cb-ssm'], sf ? 'not acting' : '—');
      toggleClass(this.e['cb-ssm'], 'warn', false);
      setText(this.e['cb-ssm-detail'], sf ? 'SSM acts with collaborative operation and SSM on, in AUTO.' : '');
    }
    setText(this.e['cb-sim-person'], personWords(s)); // the simulated person, where there is one
    // Speed against the limit in force, and why.
    const why = sf ? slowWhy(sf) : null;
    if (s && why) {
      setText(this.e['cb-speed'], `${fmt(s.tcp_speed)} / ${fmt(why.limit)} mm/s`);
      const frac = why.limit > 0 ? Math.min(1, s.tcp_speed / why.limit) : s.tcp_speed > 0.5 ? 1 : 0;
      this.e['cb-speed-bar'].style.width = `${(frac * 100).toFixed(1)}%`;
      toggleClass(this.e['cb-speed-bar'], 'over', frac >= 0.999 && s.tcp_speed > 0.5);
      const byWords: Record<string, string> = {
        normal: 'the normal TCP limit',
        reduced: 'the reduced-speed limit',
        pfl: 'the PFL cap v_pfl',
        ssm: 'v_allowed of speed and separation monitoring',
        'ssm-hold': 'SSM: v_allowed = 0, the robot holds',
      };
      setText(this.e['cb-limit-by'], `Limit set by ${byWords[why.by]}.`);
      setAttr(this.e['sp-collab'], 'data-limit-by', why.by);
    } else {
      setText(this.e['cb-speed'], '—');
      setText(this.e['cb-limit-by'], '');
    }
    const ul = this.e['cb-why'];
    const items = why ? (why.reasons.length ? why.reasons : ['It is not: the normal limits apply.']) : [];
    const key = items.join('\n');
    if (ul.dataset.key !== key) {
      ul.dataset.key = key;
      ul.replaceChildren(...items.map((t) => h('li', {}, t)));
    }
    // PFL and the contact force
    setText(this.e['cb-pfl'], sf ? (sf.pfl ? 'ON' : 'off') : '—');
    setText(this.e['cb-force'], sf ? contactWords(sf) : '');
    const f = sf?.pfl ? (sf.contact_force ?? 0) : 0;
    const lim = sf?.contact_force_limit ?? 0;
    const ff = lim > 0 ? Math.min(1, f / lim) : 0;
    this.e['cb-force-bar'].style.width = `${(ff * 100).toFixed(1)}%`;
    toggleClass(this.e['cb-force-bar'], 'over', ff >= 0.8);
    // COLLISION, with the core's detail (the force it saw).
    const collision = !!s?.alarms.includes('COLLISION');
    const box = this.e['cb-collision'];
    box.hidden = !collision;
    if (collision) {
      const a = this.alarmObjects.find((x) => x.name === 'COLLISION');
      setText(
        box,
        `COLLISION${a?.detail ? `: ${a.detail}` : ''}. The robot stops, backs off 10 mm along its path and holds. Clear the contact, then resume; a reset with the servos off clears the alarm.`,
      );
    }
  }

  private brakeSection(el: (id: string, tag?: keyof HTMLElementTagNameMap, cls?: string, text?: string) => HTMLElement): HTMLElement {
    const run = h('button', { type: 'button', class: 'btn primary', id: 'bt-run' }, 'Run brake test') as HTMLButtonElement;
    run.addEventListener('click', () => this.runBrakeTest());
    this.e['bt-run'] = run;
    const axes = el('bt-axes', 'ol', 'bt-axes', '');
    setAttr(axes, 'aria-label', 'Brake test, per axis');
    for (let a = 1; a <= 6; a++) {
      axes.append(
        (this.e[`bt-axis-${a}`] = h(
          'li',
          { class: 'bt-axis', id: `bt-axis-${a}`, 'data-phase': 'untested' },
          h('span', { class: 'bt-axis-name' }, `A${a}`),
          h('div', { class: 'cb-bar bt-bar' }, el(`bt-axis-${a}-bar`, 'div', 'cb-bar-fill', '')),
          el(`bt-axis-${a}-word`, 'span', 'bt-axis-word', '—'),
        )),
      );
    }
    return (this.e['sp-brake'] = h(
      'section',
      { class: 'sp-brake', id: 'sp-brake', 'aria-label': 'Brake test' },
      h('h3', {}, 'Brake test (SPEC §12)', el('bt-config', 'span', 'cb-enabled', '')),
      h(
        'div',
        { class: 'bt-grid' },
        h(
          'div',
          { class: 'sp-card' },
          h('div', { class: 'sp-label' }, 'Next test'),
          el('bt-due', 'div', 'sp-big', '—'),
          el('bt-due-detail', 'div', 'sp-small', ''),
        ),
        h(
          'div',
          { class: 'sp-card' },
          h('div', { class: 'sp-label' }, 'Latest result'),
          el('bt-last', 'div', 'sp-big', '—'),
          el('bt-last-when', 'div', 'sp-small', ''),
          h('div', { class: 'bt-run-line' }, run, el('bt-run-why', 'div', 'sp-why', '')),
          el('bt-reply', 'div', 'bt-reply', ''),
        ),
        h(
          'div',
          { class: 'sp-card bt-axes-card' },
          el('bt-axes-label', 'div', 'sp-label', 'Drift per axis'),
          (this.e['bt-progress'] = h('div', { class: 'cb-bar bt-progress', id: 'bt-progress' }, el('bt-progress-bar', 'div', 'cb-bar-fill', ''))),
          axes,
        ),
      ),
    ));
  }

  private renderBrake(): void {
    const s = this.status;
    const bt = s?.safety?.brake_test;
    const cfg = this.info?.config.brake_test as { interval_h?: number; grace_h?: number } | undefined;
    const maxDrift = maxDriftDeg(cfg);
    setText(
      this.e['bt-config'],
      this.info
        ? cfg
          ? ` · every ${cfg.interval_h ?? 8} h, grace ${cfg.grace_h ?? 1} h, max drift ${maxDrift}°`
          : ` · not required by this configuration, max drift ${maxDrift}°`
        : '',
    );
    const due = bt ? brakeTestDue(bt) : null;
    setText(this.e['bt-due'], due ? due.text : '—');
    setText(this.e['bt-due-detail'], due ? due.detail : 'The controller does not report the brake test.');
    setAttr(this.e['bt-due'], 'data-tone', due ? due.tone : null);
    const red = !!due && (due.tone === 'overdue' || due.tone === 'failed' || due.tone === 'never');
    toggleClass(this.e['bt-due'], 'bad', red);
    setAttr(this.e['bt-due'], 'role', red ? 'alert' : null);
    // The latest result, and when the log recorded it.
    const last = bt?.last ?? 'none';
    setText(this.e['bt-last'], !bt ? '—' : last === 'passed' ? 'Passed' : last === 'failed' ? `FAILED${bt.last_axis != null ? `: axis ${bt.last_axis}` : ''}` : 'Never tested');
    setAttr(this.e['bt-last'], 'data-result', bt ? last : null);
    toggleClass(this.e['bt-last'], 'bad', last === 'failed');
    const at = bt?.last_time ? new Date(bt.last_time) : null;
    let when = '';
    if (at && !Number.isNaN(at.getTime())) {
      const day = `${at.getFullYear()}-${String(at.getMonth() + 1).padStart(2, '0')}-${String(at.getDate()).padStart(2, '0')}`;
      when = `${last === 'failed' ? 'Failed' : 'Passed'} on ${day} at ${clockTime(at)}.`;
    } else if (bt && last !== 'none') {
      when = 'Time not reported.';
    }
    const passAge = last === 'failed' && bt ? lastPassAgeH(bt, cfg?.interval_h) : null;
    if (passAge !== null) when += ` The last pass was ${hoursWords(passAge)} ago.`;
    setText(this.e['bt-last-when'], when);
    // The button: pendant, servos on, idle.
    const gate = brakeTestGate({
      connected: this.linkState === 'open',
      role: this.role,
      state: s?.state ?? null,
      sub: s?.sub ?? null,
      mode: s?.mode ?? null,
      owner: s?.owner ?? null,
      running: !!bt?.running || s?.sub === 'BRAKE_TEST',
    });
    const run = this.e['bt-run'] as HTMLButtonElement;
    run.disabled = !gate.enabled || this.brakeSeq !== null || !bt;
    setText(
      this.e['bt-run-why'],
      gate.enabled ? 'At standstill: each brake in turn holds the test torque.' : `Disabled: ${gate.reasons.join(' ')}`,
    );
    setAttr(this.e['bt-run-why'], 'data-enabled', gate.enabled ? 'yes' : 'no');
    // Progress while running, else each axis' drift of the latest result.
    const running = !!bt?.running;
    setAttr(this.e['sp-brake'], 'data-running', running ? 'yes' : 'no');
    setText(
      this.e['bt-axes-label'],
      running ? `Testing axis ${bt?.axis ?? '?'} · ${bt?.progress ?? 0} %` : `Drift per axis (latest result, limit ${maxDrift}°)`,
    );
    this.e['bt-progress'].hidden = !running;
    this.e['bt-progress-bar'].style.width = `${running ? Math.min(100, Math.max(0, bt?.progress ?? 0)) : 0}%`;
    const rows = bt ? brakeTestAxes(bt, maxDrift) : [];
    const words: Record<string, string> = { done: 'done', testing: 'testing…', pending: 'pending', untested: 'not tested' };
    for (const r of rows) {
      setAttr(this.e[`bt-axis-${r.axis}`], 'data-phase', r.phase);
      setAttr(this.e[`bt-axis-${r.axis}`], 'aria-current', r.phase === 'testing' ? 'step' : null);
      const bar = this.e[`bt-axis-${r.axis}-bar`];
      bar.style.width = `${(running ? (r.phase === 'done' ? 1 : 0) : r.frac) * 100}%`;
      toggleClass(bar, 'over', r.phase === 'slipped');
      setText(
        this.e[`bt-axis-${r.axis}-word`],
        r.drift !== null ? `${r.drift.toFixed(3)}°${r.phase === 'slipped' ? ' SLIPPED' : ''}` : words[r.phase] ?? r.phase,
      );
    }
  }

  private runBrakeTest(): void {
    if (this.brakeSeq !== null) return;
    const reply = this.e['bt-reply'];
    setText(reply, 'Sending…');
    setAttr(reply, 'data-result', 'pending');
    this.brakeSeq = this.link.command('brake_test', {}, 'all', (o) => {
      this.brakeSeq = null;
      setText(reply, o.result === 'OK' ? 'Reply OK: the test started.' : `${o.result}: ${resultWords(o.result, 'brake_test', this.status)}`);
      setAttr(reply, 'data-result', o.result);
      this.renderBrake();
    });
    this.renderBrake();
  }

  setHighlight(hl: Highlight): void {
    this.hl = hl;
    this.render();
  }

  /**
   * The arm the configuration is for (issue 38): its name and the checksum of the
   * description's parameters (the robot's part of the configuration's checksum), from
   * /api/robot.
   */
  setRobot(r: { name: string; parameters_checksum?: string; source?: string }): void {
    setText(
      this.e['sp-robot'],
      `Robot: ${r.name}` + (r.parameters_checksum ? ` · description ${r.parameters_checksum}` : '') +
        (r.source ? ` (${r.source})` : ''),
    );
  }

  // ------------------------------------------------------------ rendering
  private render(): void {
    const s = this.status;
    const sf = s?.safety;
    const info = this.info;
    const checksum = sf?.checksum ?? info?.checksum ?? '—';
    const validated = sf ? sf.validated : info ? info.validated : null;
    const v = validated === null ? 'unknown' : validated ? 'yes' : 'no';

    // strip
    setText(this.e['ss-checksum'], checksum);
    setText(this.e['ss-valid'], validated === null ? 'not reported' : validated ? '✓ validated' : '✗ NOT validated');
    setAttr(this.e['ss-valid'], 'data-validated', v);
    setAttr(this.strip, 'data-validated', v);
    setText(this.e['ss-reduced'], sf?.reduced ? `Reduced speed: ${sf.reduced_by.join(' + ') || 'on'}` : sf ? 'Normal speed' : '');
    toggleClass(this.e['ss-reduced'], 'on', !!sf?.reduced);
    setText(this.e['ss-limit'], sf ? `TCP ≤ ${fmt(sf.speed_limit)} mm/s` : '');
    const viol = this.hl?.violations ?? [];
    setText(this.e['ss-violation'], viol.length ? `Violated: ${viol.map(violationLabel).join(', ')}` : sf?.recovery ? 'Recovery: a limit is violated' : '');
    toggleClass(this.e['ss-violation'], 'on', viol.length > 0 || !!sf?.recovery);

    // page head
    setText(this.e['sp-checksum'], checksum);
    setAttr(this.e['sp-valid'], 'data-validated', v);
    setText(this.e['sp-valid-word'], validated === null ? 'VALIDATION NOT REPORTED' : validated ? 'VALIDATED' : 'NOT VALIDATED');
    let vt = '';
    if (validated && info?.confirmation && info.confirmation.checksum === checksum) {
      const at = new Date(info.confirmation.time);
      const day = `${at.getFullYear()}-${String(at.getMonth() + 1).padStart(2, '0')}-${String(at.getDate()).padStart(2, '0')}`;
      vt = Number.isNaN(at.getTime())
        ? `Confirmed by "${info.confirmation.client}".`
        : `Confirmed by "${info.confirmation.client}" on ${day} at ${clockTime(at)}.`;
    } else if (validated) {
      vt = info?.source === 'built-in' ? 'The built-in configuration counts as validated.' : 'Confirmed.';
    } else if (validated === false) {
      vt = 'AUTO and T2 are refused until an operator confirms this checksum (T1 stays allowed for commissioning).';
      if (info?.confirmation) vt += ` The last confirmation in the log was for ${info.confirmation.checksum}.`;
    } else {
      vt = 'This controller does not report whether its configuration is validated.';
    }
    setText(this.e['sp-valid-text'], vt);

    const gate = validateGate({
      connected: this.linkState === 'open',
      role: this.role,
      state: s?.state ?? null,
      mode: s?.mode ?? null,
      hasSafety: !!sf,
    });
    const btn = this.e['sp-validate'] as HTMLButtonElement;
    btn.disabled = !gate.enabled;
    setText(btn, validated ? 'Validate again…' : 'Validate…');
    setText(this.e['sp-validate-why'], gate.enabled ? 'Type the checksum from the approved record.' : `Disabled: ${gate.reasons.join(' ')}`);
    setAttr(this.e['sp-validate-why'], 'data-enabled', gate.enabled ? 'yes' : 'no');

    // violations
    const vbox = this.e['sp-violations'];
    if (viol.length) {
      vbox.hidden = false;
      setText(vbox, `Violated limit: ${viol.map(violationLabel).join(', ')}. Reset, then in T1 jog back out of it.`);
    } else {
      vbox.hidden = true;
    }

    // now
    setText(this.e['sp-limit'], sf ? `${fmt(sf.speed_limit)} mm/s` : '—');
    setText(this.e['sp-reduced'], sf ? (sf.reduced ? 'ON' : 'off') : '—');
    toggleClass(this.e['sp-reduced'], 'warn', !!sf?.reduced);
    setText(this.e['sp-reduced-why'], sf?.reduced ? reducedWords(true, sf.reduced_by) : 'Normal speed limits apply.');
    setText(this.e['sp-recovery'], sf ? (sf.recovery ? 'YES' : 'no') : '—');
    toggleClass(this.e['sp-recovery'], 'warn', !!sf?.recovery);
    setText(
      this.e['sp-recovery-why'],
      sf?.recovery
        ? 'A limit is violated: in T1, Servo on is allowed and only motion back toward the limits; AUTO/T2 refuse Servo on.'
        : 'No limit violated.',
    );

    // live cells of the tables
    const key = `${this.hl?.joints.join()}|${this.hl?.zones.join()}|${this.hl?.activeZones.join()}`;
    if (key !== this.lastKey) {
      this.lastKey = key;
      this.markTables();
    }
    if (s && info) {
      s.joints.forEach((q, i) => {
        const cell = document.getElementById(`sp-joint-now-${i + 1}`);
        if (cell) setText(cell, `${deg(q).toFixed(1)}°`);
      });
    }
    this.renderCollab();
    this.renderBrake();
    this.renderDialog();
  }

  private renderConfig(): void {
    const info = this.info;
    const joints = this.e['sp-joints'];
    const zones = this.e['sp-zones'];
    const tcp = this.e['sp-tcp'];
    if (!info) {
      setText(this.e['sp-name'], this.infoError ? `Not available: ${this.infoError}` : 'Loading…');
      setText(this.e['sp-source'], '');
      joints.replaceChildren();
      zones.replaceChildren();
      tcp.replaceChildren();
      return;
    }
    const c = info.config;
    setText(this.e['sp-name'], info.name);
    setText(this.e['sp-source'], info.source === 'built-in' ? 'built-in configuration (no --safety file)' : `file: ${info.source}`);
    setText(this.e['validate-config'], `Active configuration: ${info.name} (${info.source})`);
    joints.replaceChildren(
      h('thead', {}, h('tr', {}, ...['Axis', 'min °', 'max °', 'max °/s', 'now'].map((t) => h('th', {}, t)))),
      h(
        'tbody',
        {},
        ...c.joints.map((j, i) =>
          h(
            'tr',
            { id: `sp-joint-${i + 1}` },
            h('td', {}, `J${i + 1}`),
            h('td', {}, fmt(j.min_deg, Number.isInteger(j.min_deg) ? 0 : 1)),
            h('td', {}, fmt(j.max_deg, Number.isInteger(j.max_deg) ? 0 : 1)),
            h('td', {}, fmt(j.max_speed_deg_s)),
            h('td', { id: `sp-joint-now-${i + 1}` }, '—'),
          ),
        ),
      ),
    );
    const o = c.orientation;
    const row = (k: string, v: string) => [h('dt', {}, k), h('dd', {}, v)];
    tcp.replaceChildren(
      ...row('TCP max speed', `${fmt(c.tcp_max_speed_mm_s)} mm/s`),
      ...row('Reduced', `${fmt(c.reduced.tcp_max_speed_mm_s)} mm/s, reached within ${fmt(c.reduced.ramp_ms)} ms`),
      ...row('Tool TCP', `${vec(c.tool.tcp_mm)} mm (flange frame)`),
      ...row('Tool sphere', `radius ${fmt(c.tool.radius_mm)} mm, payload ${c.tool.payload_kg} kg`),
      ...row('Orientation', o ? `tool z within ${fmt(o.max_deviation_deg)}° of ${vec(o.axis)}` : 'no limit'),
      ...row('Stop time', `≤ ${fmt(c.stop.max_time_ms)} ms`),
    );
    tcp.querySelectorAll('dd')[4]?.setAttribute('id', 'sp-orientation');
    tcp.querySelectorAll('dd')[0]?.setAttribute('id', 'sp-tcp-speed');
    if (c.zones.length === 0) {
      zones.replaceChildren(h('tbody', {}, h('tr', {}, h('td', { class: 'empty' }, 'No zones configured.'))));
    } else {
      zones.replaceChildren(
        h('thead', {}, h('tr', {}, ...['', 'Name', 'Kind', 'min [x, y, z]', 'max [x, y, z]'].map((t) => h('th', {}, t)))),
        h(
          'tbody',
          {},
          ...c.zones.map((z, i) =>
            h(
              'tr',
              { id: `sp-zone-${i}`, 'data-zone': z.name, 'data-kind': z.kind },
              h('td', {}, h('span', { class: 'swatch', style: `--c: ${ZONE_STYLE[z.kind]?.color ?? '#999'}` })),
              h('td', { class: 'zone-name' }, z.name),
              h('td', {}, ZONE_STYLE[z.kind]?.label ?? z.kind),
              h('td', {}, vec(z.min_mm)),
              h('td', {}, vec(z.max_mm)),
            ),
          ),
        ),
      );
    }
    this.e['sp-legend'].replaceChildren(
      ...Object.values(ZONE_STYLE).map((st) =>
        h('span', { class: 'legend-item' }, h('span', { class: 'swatch', style: `--c: ${st.color}` }), `${st.label}: ${st.words}`),
      ),
    );
    this.markTables();
  }

  private markTables(): void {
    const hl = this.hl;
    for (let a = 1; a <= 6; a++) {
      const tr = document.getElementById(`sp-joint-${a}`);
      if (tr) toggleClass(tr, 'violated', !!hl?.joints.includes(a));
    }
    this.info?.config.zones.forEach((_, i) => {
      const tr = document.getElementById(`sp-zone-${i}`);
      if (!tr) return;
      toggleClass(tr, 'violated', !!hl?.zones.includes(i));
      toggleClass(tr, 'active', !!hl?.activeZones.includes(i));
    });
    const or = document.getElementById('sp-orientation');
    if (or) toggleClass(or, 'violated', !!hl?.orientation);
    const sp = document.getElementById('sp-tcp-speed');
    if (sp) toggleClass(sp, 'violated', !!hl?.tcp);
  }

  // ------------------------------------------------------------ dialog
  private openDialog(): void {
    setText(this.e['validate-result'], '');
    setAttr(this.e['validate-result'], 'data-result', null);
    (this.e['validate-code'] as HTMLInputElement).value = '';
    if (!this.dialog.open) this.dialog.showModal();
    this.renderDialog();
    (this.e['validate-code'] as HTMLInputElement).focus();
  }

  private gateNow() {
    return validateGate({
      connected: this.linkState === 'open',
      role: this.role,
      state: this.status?.state ?? null,
      mode: this.status?.mode ?? null,
      hasSafety: !!this.status?.safety,
    });
  }

  private renderDialog(): void {
    if (!this.dialog.open) return;
    const gate = this.gateNow();
    const typed = typedCode((this.e['validate-code'] as HTMLInputElement).value);
    setText(this.e['validate-problem'], typed.problem);
    setText(this.e['validate-why'], gate.enabled ? '' : `Cannot validate now: ${gate.reasons.join(' ')}`);
    (this.e['validate-send'] as HTMLButtonElement).disabled = !gate.enabled || typed.code === null || this.pendingSeq !== null;
  }

  private send(): void {
    const typed = typedCode((this.e['validate-code'] as HTMLInputElement).value);
    if (!this.gateNow().enabled || typed.code === null || this.pendingSeq !== null) return;
    const code = typed.code;
    const result = this.e['validate-result'];
    setText(result, `Sending ${code}…`);
    setAttr(result, 'data-result', 'pending');
    this.pendingSeq = this.link.command('validate_config', { code }, 'all', (o) => {
      this.pendingSeq = null;
      const w = validateReplyWords(o.result, code);
      result.replaceChildren(h('b', { class: 'vd-code' }, o.result), ' ', w.text);
      setAttr(result, 'data-result', o.result);
      setAttr(result, 'data-tone', w.tone);
      if (o.result === 'OK') (this.e['validate-code'] as HTMLInputElement).value = '';
      this.renderDialog();
    });
    this.renderDialog();
  }
}

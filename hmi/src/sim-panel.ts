// The simulated cell's physical devices, shown only when status.simulated: E-stop
// mushroom (and its two channels), guard, 3-position enabling device, key switch, the
// cabinet's reset button, the area scanner's two protective fields and the distance sensor
// (SPEC §11), a walking person whose simulated scanner and distance sensor set those
// (issue 20 item 5, only on the in-process simulated cell: status.sim), and fault injection (with a contact force at the TCP), all as protocol `sim` messages in the
// vocabulary of the scenario format. The status does not report raw contacts, so the
// panel shows the positions it last set, starting from the cell's initial inputs
// (SPEC §6) and kept per core process across page reloads, corrected by what the status
// proves (the selected mode, an E-stop alarm, a drive-on state that needs the enabling
// device at centre or the guard closed).
import type { SimPerson, Status } from './api';
import type { Link } from './connection';
import { h, setAttr, setText, toggleClass } from './dom';
import { parseFields, parseSpeed, type PersonMessage, personWords, WALK_FROM_MM, WALK_TO_MM, walkIn, walkOut } from './person';

interface Devices {
  estopA: boolean; // contact closed = not pressed
  estopB: boolean;
  gate: 'closed' | 'open';
  enable: 'released' | 'centre' | 'panic';
  mode: 'AUTO' | 'T1' | 'T2';
  reducedA: boolean; // SPEC §10 reduced-speed input, NC: contact closed = normal speed
  reducedB: boolean;
  fieldOuter: 'clear' | 'interrupted'; // SPEC §11 protective fields, both channels together
  fieldInner: 'clear' | 'interrupted';
  separation: number; // mm, the distance sensor's reading last sent
  separationValid: boolean;
}

const INITIAL: Devices = {
  estopA: true,
  estopB: true,
  gate: 'closed',
  enable: 'released',
  mode: 'AUTO',
  reducedA: true,
  reducedB: true,
  fieldOuter: 'clear',
  fieldInner: 'clear',
  separation: 2000,
  separationValid: false, // no reading at start: unknown (SPEC §11)
};

/** The largest separation the slider offers (mm); the number field takes any integer >= 0. */
const SEPARATION_MAX = 5000;

function segmented<T extends string>(
  id: string,
  options: [T, string][],
  onPick: (v: T) => void,
): { el: HTMLElement; set: (v: T) => void } {
  const buttons = options.map(([v, label]) =>
    h('button', { type: 'button', class: 'seg-btn', id: `${id}-${v.toLowerCase()}`, 'data-value': v, onclick: () => onPick(v) }, label),
  );
  const el = h('div', { class: 'seg', id, role: 'radiogroup' }, ...buttons);
  return {
    el,
    set: (v: T) =>
      buttons.forEach((b) => {
        const on = b.dataset.value === v;
        toggleClass(b, 'on', on);
        setAttr(b, 'aria-checked', on ? 'true' : 'false');
      }),
  };
}

export class SimPanel {
  readonly el: HTMLElement;
  private d: Devices = { ...INITIAL };
  private corePid: number | null = null;
  private lastSetAt = 0;
  private mushroom: HTMLButtonElement;
  private chA: HTMLButtonElement;
  private chB: HTMLButtonElement;
  private gate: ReturnType<typeof segmented<'closed' | 'open'>>;
  private enable: ReturnType<typeof segmented<'released' | 'centre' | 'panic'>>;
  private key: ReturnType<typeof segmented<'AUTO' | 'T1' | 'T2'>>;
  private reduced: ReturnType<typeof segmented<'normal' | 'reduced'>>;
  private redA: HTMLButtonElement;
  private redB: HTMLButtonElement;
  private redNote: HTMLElement;
  private drive: HTMLSelectElement;
  private estopNote: HTMLElement;
  private fieldOuter: ReturnType<typeof segmented<'clear' | 'interrupted'>>;
  private fieldInner: ReturnType<typeof segmented<'clear' | 'interrupted'>>;
  private sepRange: HTMLInputElement;
  private sepNumber: HTMLInputElement;
  private sepValid: HTMLButtonElement;
  private sepNote: HTMLElement;
  private force: HTMLInputElement;
  private forceNote: HTMLElement;
  private personCell: HTMLElement;
  private personDir: HTMLSelectElement;
  private personSpeed: HTMLInputElement;
  private personOuter: HTMLInputElement;
  private personInner: HTMLInputElement;
  private personNote: HTMLElement;
  private personProblem = '';
  private personNow: SimPerson | null = null;
  private personNeeds: HTMLButtonElement[];
  private fieldsShown = false;

  constructor(private readonly link: Link) {
    this.mushroom = h(
      'button',
      { type: 'button', class: 'mushroom', id: 'sim-estop', 'aria-label': 'Emergency stop (press / twist to release)' },
      h('span', { class: 'mushroom-cap' }, 'STOP'),
    );
    this.mushroom.addEventListener('click', () => this.toggleEstop());
    this.chA = h('button', { type: 'button', class: 'switch', id: 'sim-estop-a', onclick: () => this.toggleChannel('a') }, 'Ch A');
    this.chB = h('button', { type: 'button', class: 'switch', id: 'sim-estop-b', onclick: () => this.toggleChannel('b') }, 'Ch B');
    this.estopNote = h('div', { class: 'sim-note' }, '');

    this.gate = segmented('sim-gate', [['closed', 'Closed'], ['open', 'Open']], (v) => {
      this.set({ gate: v }, { gate: v }, `guard ${v}`);
    });
    this.enable = segmented(
      'sim-enable',
      [['released', 'Released'], ['centre', 'Centre'], ['panic', 'Panic']],
      (v) => this.set({ enable: v }, { enable: v }, `enabling device ${v}`),
    );
    this.key = segmented('sim-mode', [['AUTO', 'AUTO'], ['T1', 'T1'], ['T2', 'T2']], (v) =>
      this.set({ mode: v }, { mode: v }, `key switch ${v}`),
    );

    // The reduced-speed input (scenario vocabulary: reduced=normal|reduced, raw reduced.a/.b).
    this.reduced = segmented('sim-reduced', [['normal', 'Normal'], ['reduced', 'Reduced']], (v) =>
      this.set(
        { reducedA: v === 'normal', reducedB: v === 'normal' },
        { reduced: v },
        `reduced-speed input ${v}`,
      ),
    );
    const redCh = (ch: 'a' | 'b') =>
      h(
        'button',
        { type: 'button', class: 'switch small', id: `sim-reduced-${ch}`, onclick: () => this.toggleReduced(ch) },
        ch.toUpperCase(),
      );
    this.redNote = h('div', { class: 'sim-note', id: 'sim-reduced-note' }, '');
    this.redA = redCh('a');
    this.redB = redCh('b');

    // SPEC §11: the area scanner's fields (scenario vocabulary field.outer/field.inner=clear|interrupted).
    this.fieldOuter = segmented('sim-field-outer', [['clear', 'Clear'], ['interrupted', 'Interrupted']], (v) =>
      this.set({ fieldOuter: v }, { 'field.outer': v }, `outer protective field ${v}`),
    );
    this.fieldInner = segmented('sim-field-inner', [['clear', 'Clear'], ['interrupted', 'Interrupted']], (v) =>
      this.set({ fieldInner: v }, { 'field.inner': v }, `inner protective field ${v}`),
    );
    // The distance sensor: separation_mm (an integer >= 0, a valid reading) and separation_valid.
    this.sepRange = h('input', {
      type: 'range', id: 'sim-separation-range', min: 0, max: SEPARATION_MAX, step: 10, 'aria-label': 'Separation (mm)',
    }) as HTMLInputElement;
    this.sepNumber = h('input', {
      type: 'number', id: 'sim-separation', min: 0, step: 1, class: 'num', 'aria-label': 'Separation (mm)',
    }) as HTMLInputElement;
    this.sepRange.addEventListener('input', () => {
      this.sepNumber.value = this.sepRange.value;
    });
    this.sepRange.addEventListener('change', () => this.sendSeparation(this.sepRange.value));
    this.sepNumber.addEventListener('change', () => this.sendSeparation(this.sepNumber.value));
    this.sepValid = h('button', { type: 'button', class: 'switch small', id: 'sim-separation-valid', onclick: () => this.toggleSepValid() }, '');
    this.sepNote = h('div', { class: 'sim-note', id: 'sim-separation-note' }, '');
    // A contact at the TCP (fault contact F, newtons, 0 removes it).
    this.force = h('input', {
      type: 'number', id: 'sim-contact-force', min: 0, max: 5000, step: 10, value: 150, class: 'num', 'aria-label': 'Contact force (N)',
    }) as HTMLInputElement;
    this.forceNote = h('div', { class: 'sim-note', id: 'sim-contact-note' }, '');

    // SPEC §11, the simulated person: walk it in and out along a direction; its scanner and
    // distance sensor then set the fields and the separation above.
    this.personDir = h('select', { id: 'sim-person-dir', 'aria-label': 'Direction the person walks in from' });
    for (const [deg, label] of [
      [0, '0° (+x, in front)'], [45, '45°'], [90, '90° (+y, left)'], [135, '135°'],
      [180, '180° (−x, behind)'], [225, '225°'], [270, '270° (−y, right)'], [315, '315°'],
    ] as const) {
      this.personDir.append(h('option', { value: deg }, label));
    }
    this.personDir.value = '90';
    this.personSpeed = h('input', {
      type: 'number', id: 'sim-person-speed', min: 1, max: 2000, step: 100, value: 1600, class: 'num', 'aria-label': 'Walking speed (mm/s)',
    }) as HTMLInputElement;
    this.personOuter = h('input', { type: 'number', id: 'sim-person-outer', min: 1, max: 20000, step: 100, value: 2000, class: 'num', 'aria-label': 'Outer field radius (mm)' }) as HTMLInputElement;
    this.personInner = h('input', { type: 'number', id: 'sim-person-inner', min: 1, max: 20000, step: 100, value: 1000, class: 'num', 'aria-label': 'Inner field radius (mm)' }) as HTMLInputElement;
    this.personNote = h('div', { class: 'sim-note', id: 'sim-person-note' }, '');
    const pbtn = (id: string, label: string, title: string, on: () => void, cls = '') =>
      h('button', { type: 'button', class: `btn small ${cls}`, id, title, onclick: on }, label);
    const walkOutBtn = pbtn('sim-person-out', 'Walk out', `Straight away from the robot to ${WALK_FROM_MM / 1000} m`, () => this.walkOut());
    const standBtn = pbtn('sim-person-stand', 'Stand', 'Stops where it is', () => this.person('stand', 'person stands'));
    const leaveBtn = pbtn('sim-person-leave', 'Leave', 'Out of the cell: the field and separation inputs above apply again', () => this.person('leave', 'person leaves'));
    this.personNeeds = [walkOutBtn, standBtn, leaveBtn];
    this.personCell = h(
      'div',
      { class: 'sim-cell sim-person', id: 'sim-person', hidden: true },
      h('div', { class: 'sim-label', title: 'SPEC §11: a person in the cell; while it is there its scanner and distance sensor set the fields and the separation' }, 'Person in the cell'),
      h(
        'div',
        { class: 'sim-sep-row' },
        h('label', { class: 'axis-pick', title: 'Direction it walks in from (about the base axis)' }, 'From', this.personDir),
        h('label', { class: 'axis-pick', title: 'Walking speed, up to 2000 mm/s' }, 'mm/s', this.personSpeed),
      ),
      h(
        'div',
        { class: 'sim-sep-row' },
        pbtn('sim-person-in', `Walk in (${WALK_FROM_MM / 1000} → ${WALK_TO_MM / 1000} m)`, `Enters ${WALK_FROM_MM / 1000} m away (or from where it stands) and walks to ${WALK_TO_MM / 1000} m from the base axis`, () => this.walkIn(), 'warn'),
        walkOutBtn,
        standBtn,
        leaveBtn,
      ),
      h(
        'div',
        { class: 'sim-sep-row', title: 'The scanner\'s two fields: circles about the base axis' },
        h('label', { class: 'axis-pick' }, 'Outer', this.personOuter),
        h('label', { class: 'axis-pick' }, 'Inner', this.personInner),
        pbtn('sim-person-fields', 'Set fields', 'The scanner\'s field radii (mm)', () => this.setFields()),
      ),
      this.personNote,
    );

    this.drive = h('select', { id: 'sim-axis', 'aria-label': 'Drive or brake number' });
    for (let i = 1; i <= 6; i++) this.drive.append(h('option', { value: i }, String(i)));
    const fault = (label: string, id: string, line: () => string, cls = '') =>
      h('button', { type: 'button', class: `btn small ${cls}`, id, onclick: () => this.fault(line()) }, label);
    const n = () => this.drive.value;

    const resetBtn = h('button', { type: 'button', class: 'btn small', id: 'sim-reset-button' }, 'Reset button (press and release)');
    resetBtn.addEventListener('click', () => this.pressResetButton());

    this.el = h(
      'div',
      { class: 'sim', id: 'sim-panel' },
      h(
        'div',
        { class: 'panel-head' },
        h('h2', {}, 'Simulated cell'),
        h(
          'span',
          { class: 'panel-hint', title: 'The status does not report raw contacts: the panel shows the positions last set here, and what the status proves.' },
          'Stands in for the physical devices',
        ),
      ),
      h(
        'div',
        { class: 'sim-grid' },
        h(
          'div',
          { class: 'sim-cell sim-estop' },
          h('div', { class: 'sim-label' }, 'E-stop'),
          this.mushroom,
          h('div', { class: 'sim-channels', title: 'Open one channel alone to inject a discrepancy' }, this.chA, this.chB),
          this.estopNote,
        ),
        h(
          'div',
          { class: 'sim-cell' },
          h('div', { class: 'sim-label' }, 'Key switch'),
          this.key.el,
          h('div', { class: 'sim-label' }, 'Enabling device'),
          this.enable.el,
          h('div', { class: 'sim-label' }, 'Guard'),
          this.gate.el,
          h('div', { class: 'sim-label', title: 'SPEC §10: two NC channels; either open asks for reduced speed' }, 'Reduced-speed input'),
          h(
            'div',
            { class: 'sim-reduced-row' },
            this.reduced.el,
            h('div', { class: 'sim-channels small', title: 'Open one channel alone: reduced speed stays on (the safe side)' }, this.redA, this.redB),
          ),
          this.redNote,
        ),
        h(
          'div',
          { class: 'sim-cell sim-collab', id: 'sim-collab' },
          h(
            'div',
            {},
            h('div', { class: 'sim-label', title: 'SPEC §11: an area scanner, two OSSD pairs per field' }, 'Outer field (slows)'),
            this.fieldOuter.el,
          ),
          h('div', {}, h('div', { class: 'sim-label' }, 'Inner field (stops)'), this.fieldInner.el),
          h(
            'div',
            {},
            h('div', { class: 'sim-label', title: 'SPEC §11 speed and separation monitoring: the distance sensor' }, 'Separation (mm)'),
            h('div', { class: 'sim-sep-row' }, this.sepRange, this.sepNumber, this.sepValid),
            this.sepNote,
          ),
          h(
            'div',
            {},
            h('div', { class: 'sim-label', title: 'SPEC §11 collision detection: a surface where the TCP next moves pushes back with this force' }, 'Contact at the TCP (N)'),
            h(
              'div',
              { class: 'sim-sep-row' },
              this.force,
              h('button', { type: 'button', class: 'btn small warn', id: 'sim-contact', onclick: () => this.contact(this.force.value) }, 'Contact'),
              h('button', { type: 'button', class: 'btn small', id: 'sim-contact-0', onclick: () => this.contact('0') }, 'Contact 0'),
            ),
            this.forceNote,
          ),
        ),
        this.personCell,
        h(
          'div',
          { class: 'sim-cell sim-faults' },
          h('div', { class: 'sim-label' }, 'Fault injection'),
          h(
            'div',
            { class: 'fault-grid' },
            h('label', { class: 'axis-pick', title: 'Drive or brake that the next fault goes to' }, 'Axis', this.drive),
            fault('Drive fault', 'sim-drive-fault', () => `drive ${n()} fault`, 'warn'),
            fault('Drive cause gone', 'sim-drive-clear', () => `drive ${n()} clear`),
            fault('Runaway', 'sim-drive-runaway', () => `drive ${n()} runaway`, 'warn'),
            fault('No stop', 'sim-drive-nostop', () => `drive ${n()} nostop`, 'warn'),
            fault('Brake stuck', 'sim-brake-stuck', () => `brake ${n()} stuck`, 'warn'),
            // SPEC §12: holds less than the brake test's torque, so the test fails on it.
            fault('Brake weak', 'sim-brake-weak', () => `brake ${n()} weak`, 'warn'),
            fault('Fieldbus lost', 'sim-fieldbus-lost', () => 'fieldbus lost', 'warn'),
            fault('Contactor stuck', 'sim-contactor-stuck', () => 'contactor stuck_open', 'warn'),
            fault('Clear all', 'sim-clear-all', () => 'clear all'),
          ),
          h('div', { class: 'sim-label' }, 'Cabinet'),
          resetBtn,
        ),
      ),
    );
    this.render();
  }

  private storageKey(): string {
    return `safestate.sim.${this.corePid ?? 0}`;
  }

  private save(): void {
    localStorage.setItem(this.storageKey(), JSON.stringify(this.d));
  }

  private set(change: Partial<Devices>, set: Record<string, string | number>, what: string): void {
    this.lastSetAt = performance.now();
    if (this.link.sim({ set }, what) !== null) {
      Object.assign(this.d, change);
      this.save();
      this.render();
    }
  }

  private fault(line: string): void {
    this.link.sim({ fault: line }, `fault: ${line}`);
  }

  private sendSeparation(text: string): void {
    const v = Number(text);
    if (text.trim() === '' || !Number.isInteger(v) || v < 0) {
      setText(this.sepNote, `"${text}" is not a separation: an integer number of mm, 0 or more. Nothing sent.`);
      setAttr(this.sepNote, 'data-problem', 'yes');
      this.render(false);
      return;
    }
    setAttr(this.sepNote, 'data-problem', null);
    // A distance given is a valid reading (protocol.md, SPEC §11).
    this.set({ separation: v, separationValid: true }, { separation_mm: v }, `separation ${v} mm`);
  }

  private toggleSepValid(): void {
    const valid = !this.d.separationValid;
    this.set(
      { separationValid: valid },
      valid ? { separation_mm: this.d.separation, separation_valid: 1 } : { separation_valid: 0 },
      valid ? `separation ${this.d.separation} mm valid` : 'separation invalid',
    );
  }

  private contact(text: string): void {
    const f = Number(text);
    if (text.trim() === '' || !Number.isFinite(f) || f < 0 || f > 5000) {
      setText(this.forceNote, `"${text}" is not a contact force: 0 to 5000 N. Nothing sent.`);
      setAttr(this.forceNote, 'data-problem', 'yes');
      return;
    }
    setAttr(this.forceNote, 'data-problem', null);
    this.fault(`contact ${f}`);
    setText(this.forceNote, f > 0 ? `Sent: a surface pushes back with ${f} N where the TCP next moves.` : 'Sent: contact removed.');
  }

  private person(person: PersonMessage, what: string): boolean {
    this.personProblem = '';
    return this.link.sim({ person }, what) !== null;
  }

  private refuse(problem: string): void {
    this.personProblem = `${problem} Nothing sent.`;
    this.renderPerson();
  }

  private walkIn(): void {
    const v = parseSpeed(this.personSpeed.value);
    if (typeof v === 'string') return this.refuse(v);
    const deg = Number(this.personDir.value);
    this.person(walkIn(deg, v, this.personNow !== null), `person walks in from ${deg}° at ${v} mm/s`);
  }

  private walkOut(): void {
    const v = parseSpeed(this.personSpeed.value);
    if (typeof v === 'string') return this.refuse(v);
    this.person(walkOut(this.personNow, Number(this.personDir.value), v), `person walks out at ${v} mm/s`);
  }

  private setFields(): void {
    const f = parseFields(this.personOuter.value, this.personInner.value);
    if (typeof f === 'string') return this.refuse(f);
    this.person({ fields: f }, `scanner fields ${f[0]} / ${f[1]} mm`);
  }

  private renderPerson(): void {
    for (const b of this.personNeeds) b.disabled = this.personNow === null;
    setAttr(this.personNote, 'data-problem', this.personProblem ? 'yes' : null);
    setAttr(this.personCell, 'data-person', this.personNow ? (this.personNow.walking ? 'walking' : 'standing') : 'absent');
  }

  private pressResetButton(): void {
    // SPEC §2: the reset button acts on its falling edge, so press and release.
    if (this.link.sim({ set: { reset_button: 1 } }, 'cabinet reset button pressed') !== null) {
      window.setTimeout(() => this.link.sim({ set: { reset_button: 0 } }, 'cabinet reset button released'), 200);
    }
  }

  private toggleEstop(): void {
    const pressed = !this.d.estopA || !this.d.estopB;
    if (pressed) {
      this.set({ estopA: true, estopB: true }, { estop: 'released' }, 'E-stop released');
    } else {
      this.set({ estopA: false, estopB: false }, { estop: 'pressed' }, 'E-stop pressed');
    }
  }

  private toggleChannel(ch: 'a' | 'b'): void {
    const key = ch === 'a' ? 'estopA' : 'estopB';
    const closed = !this.d[key];
    this.set({ [key]: closed }, { [`estop.${ch}`]: closed ? 1 : 0 }, `E-stop channel ${ch.toUpperCase()} ${closed ? 'closed' : 'opened'}`);
  }

  private toggleReduced(ch: 'a' | 'b'): void {
    const key = ch === 'a' ? 'reducedA' : 'reducedB';
    const closed = !this.d[key];
    this.set(
      { [key]: closed },
      { [`reduced.${ch}`]: closed ? 1 : 0 },
      `reduced-speed input channel ${ch.toUpperCase()} ${closed ? 'closed' : 'opened'}`,
    );
  }

  private render(inputs = true): void {
    this.fieldOuter.set(this.d.fieldOuter);
    this.fieldInner.set(this.d.fieldInner);
    if (inputs && document.activeElement !== this.sepNumber) this.sepNumber.value = String(this.d.separation);
    if (inputs && document.activeElement !== this.sepRange) this.sepRange.value = String(Math.min(this.d.separation, SEPARATION_MAX));
    toggleClass(this.sepValid, 'open', !this.d.separationValid);
    setText(this.sepValid, this.d.separationValid ? 'valid' : 'invalid');
    setAttr(this.sepValid, 'aria-pressed', this.d.separationValid ? 'true' : 'false');
    setAttr(this.sepValid, 'title', this.d.separationValid ? 'The reading is valid: click to make it invalid (counts as 0)' : 'No valid reading (counts as 0): click to send the distance as valid');
    if (this.sepNote.dataset.problem !== 'yes') {
      setText(this.sepNote, this.d.separationValid ? `Sensor reads ${this.d.separation} mm` : 'No valid reading: SSM counts it as 0 mm (holds)');
    }
    const pressed = !this.d.estopA && !this.d.estopB;
    const partial = this.d.estopA !== this.d.estopB;
    toggleClass(this.mushroom, 'pressed', pressed || partial);
    setAttr(this.mushroom, 'aria-pressed', pressed || partial ? 'true' : 'false');
    for (const [b, closed, name] of [
      [this.chA, this.d.estopA, 'A'],
      [this.chB, this.d.estopB, 'B'],
    ] as const) {
      toggleClass(b, 'open', !closed);
      setText(b, `Ch ${name}: ${closed ? 'closed' : 'open'}`);
    }
    setText(
      this.estopNote,
      pressed ? 'Pressed: click to twist out' : partial ? 'One channel open: discrepancy after 50 ms' : 'Released: click to press',
    );
    this.gate.set(this.d.gate);
    this.enable.set(this.d.enable);
    this.key.set(this.d.mode);
    const redBoth = this.d.reducedA && this.d.reducedB ? 'normal' : !this.d.reducedA && !this.d.reducedB ? 'reduced' : '';
    this.reduced.set(redBoth as 'normal' | 'reduced');
    for (const [b, closed, name] of [
      [this.redA, this.d.reducedA, 'A'],
      [this.redB, this.d.reducedB, 'B'],
    ] as const) {
      toggleClass(b, 'open', !closed);
      setText(b, name);
      setAttr(b, 'aria-pressed', closed ? 'false' : 'true');
      setAttr(b, 'title', `Channel ${name} ${closed ? 'closed (normal)' : 'open (asks for reduced)'}: click to ${closed ? 'open' : 'close'} it alone`);
    }
    setText(this.redNote, `Channel A ${this.d.reducedA ? 'closed' : 'open'}, B ${this.d.reducedB ? 'closed' : 'open'}`);
  }

  update(s: Status): void {
    // The person (status.sim: only the in-process simulated cell has one).
    this.personCell.hidden = !s.sim;
    this.personNow = s.sim?.person ?? null;
    if (s.sim && !this.fieldsShown) {
      this.fieldsShown = true;
      this.personOuter.value = String(s.sim.person_fields.outer_mm);
      this.personInner.value = String(s.sim.person_fields.inner_mm);
    }
    const over = this.personNow ? ' Its scanner and distance sensor set the fields and the separation above while it is in the cell.' : '';
    setText(this.personNote, this.personProblem || personWords(s) + over);
    this.renderPerson();
    if (s.core_pid !== undefined && s.core_pid !== this.corePid) {
      // A new core process starts from the initial inputs; a reload keeps what was set.
      this.corePid = s.core_pid;
      const saved = localStorage.getItem(this.storageKey());
      this.d = saved ? { ...INITIAL, ...(JSON.parse(saved) as Partial<Devices>) } : { ...INITIAL };
      this.render();
    }
    // What the status proves, once the last change from here has had time to show.
    if (performance.now() - this.lastSetAt < 600) return;
    const d = { ...this.d };
    const req = s.mode_requested;
    if (req === 'AUTO' || req === 'T1' || req === 'T2') d.mode = req;
    const estopAlarm = s.alarms.includes('ESTOP_PRESSED');
    if (estopAlarm && d.estopA && d.estopB) d.estopA = d.estopB = false;
    if (!estopAlarm && !s.alarms.includes('ESTOP_DISCREPANCY') && s.state !== 'ESTOP_ACTIVE') d.estopA = d.estopB = true;
    const powered = s.state === 'OPERATIONAL' || s.state === 'ARMING';
    if (powered && (s.mode === 'T1' || s.mode === 'T2')) d.enable = 'centre';
    if (powered && s.mode === 'AUTO') d.gate = 'closed';
    // Reduced mode not asked for by the input: both of its channels are closed. (Asked for
    // proves nothing about the contacts: a discrepancy keeps it on with both closed.)
    if (s.safety && !s.safety.reduced_by.includes('input')) d.reducedA = d.reducedB = true;
    // A field reads clear only once both of its channels are closed (SPEC §11).
    if (s.safety?.fields?.outer === 'clear') d.fieldOuter = 'clear';
    if (s.safety?.fields?.inner === 'clear') d.fieldInner = 'clear';
    if (JSON.stringify(d) !== JSON.stringify(this.d)) {
      this.d = d;
      this.save();
      this.render();
    }
  }
}

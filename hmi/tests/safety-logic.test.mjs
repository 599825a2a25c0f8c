// The pure rules of the Safety page (hmi/src/safety-logic.ts), unit-level: the very source
// file with its types stripped by Vite's own transform (hmi/node_modules), no build.
// Run: node --test hmi/tests/safety-logic.test.mjs
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { transformWithOxc } from 'vite';

const file = new URL('../src/safety-logic.ts', import.meta.url);
const { code } = await transformWithOxc(readFileSync(file, 'utf8'), file.pathname);
const L = await import(`data:text/javascript,${encodeURIComponent(code)}`);

const gate = (over) => L.validateGate({ connected: true, role: 'pendant', state: 'IDLE', mode: 'T1', hasSafety: true, ...over });

test('validate: enabled only for the pendant, in IDLE, with T1 or T2', () => {
  assert.deepEqual(gate({}), { enabled: true, reasons: [] });
  assert.equal(gate({ mode: 'T2' }).enabled, true);
  for (const over of [
    { role: 'observer' },
    { role: null },
    { mode: 'AUTO' },
    { mode: 'NONE' },
    { state: 'OPERATIONAL' },
    { state: 'ESTOP_RESET_NEEDED' },
    { state: 'ARMING' },
    { connected: false },
    { hasSafety: false },
  ]) {
    const g = gate(over);
    assert.equal(g.enabled, false, JSON.stringify(over));
    assert.ok(g.reasons.length >= 1, JSON.stringify(over));
  }
});

test('validate: the reasons say what is wrong, every one of them', () => {
  assert.match(gate({ role: 'observer' }).reasons.join(' '), /read-only.*pendant/i);
  assert.match(gate({ mode: 'AUTO' }).reasons.join(' '), /T1 or T2 \(now AUTO\)/);
  assert.match(gate({ state: 'OPERATIONAL' }).reasons.join(' '), /IDLE.*now OPERATIONAL/);
  const all = gate({ role: 'observer', mode: 'AUTO', state: 'OPERATIONAL' });
  assert.equal(all.reasons.length, 3, all.reasons.join(' | '));
  assert.deepEqual(gate({ connected: false }).reasons, ['Not connected to the controller.']);
});

test('the typed code: 8 hex digits, case and spaces do not matter', () => {
  assert.deepEqual(L.typedCode('3ad9012b'), { code: '3AD9012B', problem: '' });
  assert.deepEqual(L.typedCode(' 3AD9 012B '), { code: '3AD9012B', problem: '' });
  assert.equal(L.typedCode('').code, null);
  assert.match(L.typedCode('3AD9012').problem, /7 of 8/);
  assert.match(L.typedCode('3AD9012BC').problem, /9 of 8/);
  assert.match(L.typedCode('3AG9012B').problem, /"G" is not a hex digit/);
  assert.equal(L.typedCode('0x3AD901').code, null);
});

test('replies in words', () => {
  assert.equal(L.validateReplyWords('OK', '3AD9012B').tone, 'ok');
  const m = L.validateReplyWords('CHECKSUM_MISMATCH', '00000000');
  assert.equal(m.tone, 'refused');
  assert.match(m.text, /00000000 is not the checksum.*nothing changed/);
  assert.equal(L.validateReplyWords('NO_REPLY', 'X').tone, 'failed');
});

const ZONES = ['table', 'cell', 'loading', 'table 2'];

test('alarm -> highlight: by subject (axis.N, tcp, zone name)', () => {
  const h = L.highlights(
    ['JOINT_LIMIT', 'ZONE_VIOLATION', 'SPEED_LIMIT', 'ORIENTATION_LIMIT', 'ESTOP_PRESSED'],
    [
      { name: 'JOINT_LIMIT', detail: 'whatever', subject: 'axis.3' },
      { name: 'ZONE_VIOLATION', detail: 'x', subject: 'loading' },
      { name: 'SPEED_LIMIT', detail: 'x', subject: 'tcp' },
      { name: 'ORIENTATION_LIMIT', detail: 'Tool orientation outside its permitted cone', subject: '' },
      { name: 'ESTOP_PRESSED', detail: 'E-stop pressed', subject: 'estop.a' },
    ],
    ZONES,
  );
  assert.deepEqual(h.joints, [3]);
  assert.deepEqual(h.zones, [2]);
  assert.equal(h.tcp, true);
  assert.equal(h.orientation, true);
  assert.deepEqual(h.violations.map(L.violationLabel), [
    'JOINT_LIMIT · axis 3',
    'ZONE_VIOLATION · zone loading',
    'SPEED_LIMIT · TCP',
    'ORIENTATION_LIMIT · tool orientation',
  ]);
});

test('alarm -> highlight: from the words when there is no subject', () => {
  const h = L.highlights(
    ['JOINT_LIMIT', 'ZONE_VIOLATION', 'SPEED_LIMIT'],
    [
      { name: 'JOINT_LIMIT', detail: 'Axis 6 outside its safe range' },
      { name: 'ZONE_VIOLATION', detail: 'Zone table 2 (keep-out) violated' }, // the longest name wins
      { name: 'SPEED_LIMIT', detail: 'Axis 2 speed above its safe limit' },
    ],
    ZONES,
  );
  assert.deepEqual(h.joints, [6, 2]);
  assert.deepEqual(h.zones, [3]);
  assert.equal(h.tcp, false);
  const core = L.highlights(['ZONE_VIOLATION'], [{ name: 'ZONE_VIOLATION', detail: 'Zone 1 violated' }], ZONES);
  assert.deepEqual(core.zones, [0], "the core's own words number zones from 1");
  const tcp = L.highlights(['SPEED_LIMIT'], [{ name: 'SPEED_LIMIT', detail: 'TCP speed above the safe limit (1612 mm/s)' }], ZONES);
  assert.equal(tcp.tcp, true);
});

test('alarm -> highlight: a name without its object yet is still a violation; others are not', () => {
  const h = L.highlights(['ZONE_VIOLATION', 'DRIVE_FAULT', 'T1_SPEED_EXCEEDED'], [], ZONES);
  assert.equal(h.violations.length, 1);
  assert.equal(L.violationLabel(h.violations[0]), 'ZONE_VIOLATION');
  assert.deepEqual(h.zones, []);
  const stale = L.highlights([], [{ name: 'JOINT_LIMIT', detail: 'Axis 1 outside its safe range' }], ZONES);
  assert.equal(stale.violations.length, 0, 'an alarm the status no longer lists is not highlighted');
  const reduced = L.highlights(['REDUCED_SPEED'], [{ name: 'REDUCED_SPEED', detail: 'x', subject: 'loading' }], ZONES);
  assert.deepEqual(reduced.activeZones, [2]);
  assert.equal(reduced.violations.length, 0, 'reduced speed is not a violation');
});

test('joint bars: the configured range inside the robot range', () => {
  const r = Math.PI / 180;
  const g = L.barGeometry(0, -165 * r, 165 * r, { min_deg: -120, max_deg: 120, max_speed_deg_s: 200 });
  assert.ok(Math.abs(g.lo - 45 / 330) < 1e-9 && Math.abs(g.hi - 285 / 330) < 1e-9, JSON.stringify(g));
  assert.equal(g.at, 0.5);
  assert.equal(g.where, 'inside');
  assert.equal(L.barGeometry(119 * r, -165 * r, 165 * r, { min_deg: -120, max_deg: 120, max_speed_deg_s: 1 }).where, 'near');
  assert.equal(L.barGeometry(121 * r, -165 * r, 165 * r, { min_deg: -120, max_deg: 120, max_speed_deg_s: 1 }).where, 'outside');
  assert.equal(L.barGeometry(-130 * r, -165 * r, 165 * r, { min_deg: -120, max_deg: 120, max_speed_deg_s: 1 }).where, 'outside');
  const robot = L.barGeometry(0, -1, 1, null);
  assert.deepEqual([robot.lo, robot.hi], [0, 1]);
});

test('reduced mode in words; zone colours distinct', () => {
  assert.equal(L.reducedWords(false, ['input']), '');
  assert.match(L.reducedWords(true, ['zone', 'input']), /reduced zone and the reduced-speed input/);
  const colours = Object.values(L.ZONE_STYLE).map((s) => s.color);
  assert.equal(new Set(colours).size, 3);
});

// SPEC §11: why the robot is slow, from the status' safety object (slowWhy), and the
// contact force against F_qs (contactWords).
const sfBase = { reduced: false, reduced_by: [], speed_limit: 1500, v_allowed: null, fields: { outer: 'clear', inner: 'clear' },
  separation_mm: null, pfl: false, contact_force: null, contact_force_limit: null, pfl_speed_limit: null };
const sfOf = (over) => ({ ...sfBase, ...over });

test('why slow: the normal limit, nothing to say', () => {
  assert.deepEqual(L.slowWhy(sfBase), { limit: 1500, by: 'normal', reasons: [] });
});

test('why slow: every reduced source in words, the outer field as a person near', () => {
  const w = L.slowWhy(sfOf({ reduced: true, reduced_by: ['zone', 'input', 'field'], speed_limit: 250 }));
  assert.equal(w.by, 'reduced');
  assert.equal(w.limit, 250);
  assert.equal(w.reasons.length, 3);
  assert.match(w.reasons[0], /reduced zone/);
  assert.match(w.reasons[1], /reduced-speed input/);
  assert.match(w.reasons[2], /outer protective field is interrupted/);
  assert.doesNotMatch(w.reasons[2], /v_pfl/, 'the PFL cap is not the limit here');
  assert.match(L.slowWhy(sfOf({ reduced: true, reduced_by: [] })).reasons[0], /not reported/);
});

test('why slow: the PFL cap when v_pfl is the limit in force', () => {
  const w = L.slowWhy(sfOf({ reduced: true, reduced_by: ['field'], speed_limit: 1348, pfl: true, pfl_speed_limit: 1348.2, contact_force: 0 }));
  assert.equal(w.by, 'pfl');
  assert.match(w.reasons[0], /power and force limiting caps the TCP at v_pfl = 1348 mm\/s/);
  // The same cap without the field: the outer field is what makes it act.
  assert.equal(L.slowWhy(sfOf({ reduced: true, reduced_by: ['input'], speed_limit: 1348, pfl_speed_limit: 1348 })).by, 'reduced');
});

test('why slow: SSM slows below the limit, holds at v_allowed 0, says nothing above the limit', () => {
  const w = L.slowWhy(sfOf({ v_allowed: 344.8, separation_mm: 800 }));
  assert.equal(w.by, 'ssm');
  assert.equal(w.limit, 344.8);
  assert.match(w.reasons[0], /separation of 800 mm the TCP may move at 345 mm\/s/);
  const hold = L.slowWhy(sfOf({ v_allowed: 0, separation_mm: 500 }));
  assert.equal(hold.by, 'ssm-hold');
  assert.equal(hold.limit, 0);
  assert.match(hold.reasons[0], /holds the robot.*500 mm.*v_allowed is 0/);
  assert.match(L.slowWhy(sfOf({ v_allowed: 0, separation_mm: null })).reasons[0], /separation of unknown/);
  assert.deepEqual(L.slowWhy(sfOf({ v_allowed: 1500, separation_mm: 5000 })).reasons, [], 'v_allowed at the limit: not slower');
  // Reduced and SSM together: both reasons, the lower limit wins.
  const both = L.slowWhy(sfOf({ reduced: true, reduced_by: ['field'], speed_limit: 250, v_allowed: 100, separation_mm: 600 }));
  assert.equal(both.by, 'ssm');
  assert.equal(both.limit, 100);
  assert.equal(both.reasons.length, 2);
});

test('why slow: the inner field is named (rule 9)', () => {
  const w = L.slowWhy(sfOf({ fields: { outer: 'interrupted', inner: 'interrupted' }, reduced: true, reduced_by: ['field'], speed_limit: 250 }));
  assert.ok(w.reasons.some((r) => /inner protective field is interrupted.*rule 9/.test(r)), w.reasons.join(' | '));
});

test('contact force: off, the force alone, and against F_qs', () => {
  assert.equal(L.contactWords(sfBase), 'Collision detection off');
  assert.equal(L.contactWords(sfOf({ pfl: true, contact_force: 12.34 })), '12.3 N');
  assert.equal(L.contactWords(sfOf({ pfl: true, contact_force: 3, contact_force_limit: 140 })), '3.0 N of 140 N (F_qs, COLLISION above)');
  assert.equal(L.contactWords(sfOf({ pfl: false, contact_force: 3, contact_force_limit: 140 })), 'Collision detection off');
});

// ------------------------------------------------------------------ brake test (SPEC §12)
const bt = (over) => ({ due_in_h: 5.25, last: 'passed', running: false, axis: null, progress: null, due: false, required: false, ...over });

test('brake test due: in hours or minutes, overdue, failed naming the axis, never tested', () => {
  assert.deepEqual([L.brakeTestDue(bt({})).tone, L.brakeTestDue(bt({})).text], ['ok', 'Due in 5.3 h']);
  assert.equal(L.brakeTestDue(bt({ due_in_h: 0.5 })).text, 'Due in 30 min');
  const over = L.brakeTestDue(bt({ due_in_h: -1.5, due: true }));
  assert.deepEqual([over.tone, over.text], ['overdue', 'Overdue by 1.5 h']);
  assert.match(over.detail, /grace/);
  const gone = L.brakeTestDue(bt({ due_in_h: -2, due: true, required: true }));
  assert.match(gone.detail, /AUTO is refused/);
  const failed = L.brakeTestDue(bt({ last: 'failed', last_axis: 3, due_in_h: 7, required: true }));
  assert.deepEqual([failed.tone, failed.text], ['failed', 'Failed: axis 3']);
  const never = L.brakeTestDue(bt({ last: 'none', due_in_h: null, due: true, required: true }));
  assert.deepEqual([never.tone, never.text], ['never', 'Never tested']);
  assert.match(never.detail, /AUTO is refused/);
  assert.equal(L.brakeTestDue(bt({ last: 'none', due_in_h: null })).tone, 'not-required');
  assert.equal(L.brakeTestDue(bt({ last: 'passed', due_in_h: null })).tone, 'not-required');
  // Protocol.md's two fields alone (a gateway that predates the others).
  assert.equal(L.brakeTestDue({ due_in_h: -0.25, last: 'passed' }).text, 'Overdue by 15 min');
});

test('brake test: max_drift_deg from the configuration, else the SPEC default', () => {
  assert.equal(L.maxDriftDeg({ max_drift_deg: 0.2 }), 0.2);
  for (const c of [undefined, null, {}, { max_drift_deg: 'x' }, { max_drift_deg: -1 }, { max_drift_deg: 0 }]) {
    assert.equal(L.maxDriftDeg(c), 0.5, JSON.stringify(c));
  }
});

const btGate = (over) =>
  L.brakeTestGate({ connected: true, role: 'pendant', state: 'OPERATIONAL', sub: 'MANUAL_IDLE', mode: 'T1', owner: 'pendant', running: false, ...over });

test('brake test button: the pendant with control, AUTO_IDLE or MANUAL_IDLE, a valid mode', () => {
  assert.deepEqual(btGate({}), { enabled: true, reasons: [] });
  assert.equal(btGate({ sub: 'AUTO_IDLE', mode: 'AUTO' }).enabled, true);
  for (const over of [
    { role: 'observer' },
    { role: null },
    { owner: 'remote' },
    { owner: null },
    { mode: 'NONE' },
    { state: 'IDLE', sub: null },
    { sub: 'MANUAL_JOGGING' },
    { sub: 'AUTO_RUNNING' },
    { sub: 'BRAKE_TEST', running: true },
    { state: 'STOPPING', sub: null },
    { connected: false },
  ]) {
    const g = btGate(over);
    assert.equal(g.enabled, false, JSON.stringify(over));
    assert.ok(g.reasons.length >= 1, JSON.stringify(over));
  }
  assert.match(btGate({ owner: 'remote' }).reasons.join(' '), /remote has/);
  assert.match(btGate({ state: 'IDLE', sub: null }).reasons.join(' '), /now IDLE/);
  assert.equal(btGate({ role: 'observer', state: 'IDLE', sub: null, mode: 'NONE' }).reasons.length, 3);
});

test('brake test axes: progress while running, the current axis testing', () => {
  const rows = L.brakeTestAxes(bt({ running: true, axis: 3, progress: 45, drift_deg: [0, 0, 0, 0, 0, 0] }), 0.5);
  assert.deepEqual(
    rows.map((r) => r.phase),
    ['done', 'done', 'testing', 'pending', 'pending', 'pending'],
  );
  assert.ok(rows.every((r) => r.drift === null));
});

test('brake test axes: the drift of a pass against max_drift_deg; a failure stops at its axis', () => {
  const pass = L.brakeTestAxes(bt({ drift_deg: [0.01, 0.1, 0.25, 0, 0.5, 0.75] }), 0.5);
  assert.deepEqual(pass.map((r) => r.phase), Array(6).fill('held'));
  assert.deepEqual(pass.map((r) => r.drift), [0.01, 0.1, 0.25, 0, 0.5, 0.75]);
  assert.deepEqual(pass.map((r) => r.frac), [0.02, 0.2, 0.5, 0, 1, 1]);
  const fail = L.brakeTestAxes(bt({ last: 'failed', last_axis: 3, drift_deg: [0.01, 0.02, 1.2, 0, 0, 0] }), 0.5);
  assert.deepEqual(fail.map((r) => r.phase), ['held', 'held', 'slipped', 'untested', 'untested', 'untested']);
  assert.deepEqual(fail.map((r) => r.drift), [0.01, 0.02, 1.2, null, null, null]);
  assert.deepEqual(
    L.brakeTestAxes(bt({ last: 'none', drift_deg: null }), 0.5).map((r) => r.phase),
    Array(6).fill('untested'),
  );
  // A malformed drift list is not shown as a result.
  assert.ok(L.brakeTestAxes(bt({ drift_deg: [1, 2] }), 0.5).every((r) => r.phase === 'untested' && r.drift === null));
});

test('brake test: the age of the last pass from interval_h and due_in_h, also after a failure', () => {
  assert.equal(L.lastPassAgeH(bt({ due_in_h: 5.5 }), 8), 2.5);
  assert.equal(L.lastPassAgeH(bt({ last: 'failed', due_in_h: -1 }), 8), 9);
  assert.equal(L.lastPassAgeH(bt({ due_in_h: null }), 8), null);
  assert.equal(L.lastPassAgeH(bt({}), undefined), null, 'no brake_test key: no interval');
});

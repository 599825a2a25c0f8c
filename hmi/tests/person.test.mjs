// The simulated person's pure rules (hmi/src/person.ts, issue 20 item 5): what the panel
// sends, what it refuses before sending, what the 3D view draws and the words shown. The
// very source file with its types stripped by Vite's own transform (hmi/node_modules).
// Run: node --test hmi/tests/person.test.mjs
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { transformWithOxc } from 'vite';

const file = new URL('../src/person.ts', import.meta.url);
const { code } = await transformWithOxc(readFileSync(file, 'utf8'), file.pathname);
const P = await import(`data:text/javascript,${encodeURIComponent(code)}`);

const person = (over) => ({ x_mm: 0, y_mm: 1200, radius_mm: 250, speed_mm_s: 1600, walking: true, in_outer: true,
  in_inner: false, separation_mm: 700.4, nearest_point: 7, ...over });
const status = (sim, fields) => ({ sim, safety: fields ? { fields } : undefined });
const FIELDS = { outer_mm: 2000, inner_mm: 1000, scanner: true, distance_sensor: true };

test('walk in: enters 3 m away along the direction and walks to 0.8 m; from where it stands when present', () => {
  assert.deepEqual(P.walkIn(0, 1600, false), { at: [3000, 0], walk: [[800, 0, 1600]] });
  assert.deepEqual(P.walkIn(90, 2000, false), { at: [0, 3000], walk: [[0, 800, 2000]] });
  assert.deepEqual(P.walkIn(225, 500, false), { at: [-2121, -2121], walk: [[-566, -566, 500]] });
  assert.deepEqual(P.walkIn(180, 1600, true), { walk: [[-800, 0, 1600]] }, 'no jump for a person already in');
});

test('walk out: straight away from the base axis, from where the person is', () => {
  assert.deepEqual(P.walkOut(person({ x_mm: 0, y_mm: 800 }), 0, 1000), { walk: [[0, 3000, 1000]] });
  assert.deepEqual(P.walkOut(person({ x_mm: -500, y_mm: 0 }), 90, 1000), { walk: [[-3000, 0, 1000]] });
  assert.deepEqual(P.walkOut(person({ x_mm: 0, y_mm: 0 }), 270, 1000), { walk: [[0, -3000, 1000]] }, 'on the axis: the chosen direction');
});

test('a speed is (0, 2000] mm/s, field radii 0 < inner < outer <= 20000; anything else says why', () => {
  assert.equal(P.parseSpeed('1600'), 1600);
  assert.equal(P.parseSpeed('2000'), 2000);
  assert.match(P.parseSpeed('2000.5'), /over 2000/);
  assert.match(P.parseSpeed('0'), /not above 0/);
  assert.match(P.parseSpeed('-3'), /not above 0/);
  assert.match(P.parseSpeed(''), /not a speed/);
  assert.match(P.parseSpeed('fast'), /not a speed/);
  assert.deepEqual(P.parseFields('1500', '700'), [1500, 700]);
  assert.match(P.parseFields('700', '1500'), /0 < inner < outer/);
  assert.match(P.parseFields('30000', '1000'), /≤ 20000/);
  assert.match(P.parseFields('2000', '0'), /0 < inner/);
  assert.match(P.parseFields('', '1'), /numbers of mm/);
});

test('the drawing: none off the simulated cell; the fields as the core validated them, else as the scanner sees', () => {
  assert.equal(P.personDrawing(null), null);
  assert.equal(P.personDrawing(status(null)), null);
  const d = P.personDrawing(status({ person: person(), person_fields: FIELDS }, { outer: 'clear', inner: 'interrupted' }));
  assert.equal(d.outer_mm, 2000);
  assert.equal(d.inner_mm, 1000);
  assert.equal(d.outerInterrupted, false, 'the core\'s view wins');
  assert.equal(d.innerInterrupted, true);
  const e = P.personDrawing(status({ person: person(), person_fields: FIELDS }));
  assert.equal(e.outerInterrupted, true);
  assert.equal(e.innerInterrupted, false);
  assert.equal(P.personDrawing(status({ person: null, person_fields: FIELDS })).person, null);
});

test('the words: where, how fast, which field, the separation', () => {
  assert.equal(P.personWords(status(null)), '');
  assert.match(P.personWords(status({ person: null, person_fields: FIELDS })), /not in the cell/);
  assert.equal(P.personWords(status({ person: person(), person_fields: FIELDS })),
    'Simulated person: walking at 1.6 m/s, 1.20 m from the base axis, in the outer field; separation 0.70 m.');
  assert.match(P.personWords(status({ person: person({ walking: false, speed_mm_s: 0, in_inner: true }), person_fields: FIELDS })),
    /standing, .* in the inner field/);
});

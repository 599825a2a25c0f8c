// The OPC UA adapter's reconnect schedule (adapters/opcua/src/backoff.ts, issue 23), unit-level: the very
// source file, loaded as JavaScript (it uses no TypeScript-only syntax), no build needed.
// Run: node --test adapters/opcua/tests/backoff.test.mjs
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';

const src = readFileSync(new URL('../src/backoff.ts', import.meta.url), 'utf8');
const { retryCeilingMs, retryDelayMs, FIRST_RETRY_MS, MAX_RETRY_MS } =
  await import(`data:text/javascript,${encodeURIComponent(src)}`);

test('the ceiling doubles from 0.5 s up to 10 s', () => {
  const ceilings = [1, 2, 3, 4, 5, 6, 7, 8].map((f) => retryCeilingMs(f));
  assert.deepEqual(ceilings, [500, 1000, 2000, 4000, 8000, 10000, 10000, 10000]);
  assert.equal(FIRST_RETRY_MS, 500);
  assert.equal(MAX_RETRY_MS, 10000);
  assert.equal(retryCeilingMs(1e6), 10000, 'no overflow after many failures');
});

test('the delay is drawn from the upper half of the ceiling', () => {
  assert.equal(retryDelayMs(3, () => 0), 1000);
  assert.equal(retryDelayMs(3, () => 0.5), 1500);
  assert.equal(retryDelayMs(3, () => 0.9999999), 2000);
});

test('clients refused together come back spread out', () => {
  // A seeded generator (mulberry32), one stream shared by 500 clients like 500 adapters' Math.random.
  let a = 23;
  const rnd = () => {
    a = (a + 0x6d2b79f5) | 0;
    let t = Math.imul(a ^ (a >>> 15), 1 | a);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
  const delays = Array.from({ length: 500 }, () => retryDelayMs(2, rnd));
  assert.ok(Math.min(...delays) >= 500 && Math.max(...delays) <= 1000, `${Math.min(...delays)}..${Math.max(...delays)}`);
  assert.ok(Math.max(...delays) - Math.min(...delays) > 400, 'jitter spreads the clients');
  const perMs = new Map();
  for (const d of delays) perMs.set(d, (perMs.get(d) ?? 0) + 1);
  assert.ok(Math.max(...perMs.values()) < 10, 'no crowd in one millisecond');
});

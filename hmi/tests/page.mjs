// What the browser tests of the pendant share: waiting for a condition, and the state
// banner as the operator reads it, and where things are (environment: SAFESTATE_BIN,
// CHROMIUM, SAFESTATE_RUN_ARGS, SAFESTATE_HMI_ARTIFACTS). Used by browser.test.mjs and
// ecat_browser.test.mjs.
import net from 'node:net';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const HMI = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
export const ROOT = path.resolve(HMI, '..');
export const BIN = process.env.SAFESTATE_BIN || path.join(ROOT, 'build', 'bin', 'safestate');
export const DIST = path.join(HMI, 'dist');
export const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
// Default: the fieldbus watchdog at 1 s and SPEC §14's cross-check window at 50 cycles: these
// tests check the HMI, and a headless browser rendering WebGL in software on a 2-core machine
// must not lock the cell out through the watchdog or by keeping one channel's process from
// running for a few cycles (tests/integration/test_gateway.py STALL_TOLERANT_PAIR).
export const RUN_ARGS = (process.env.SAFESTATE_RUN_ARGS ?? '--watchdog-ms 1000 --cross-check-cycles 50').split(/\s+/).filter(Boolean);
export const ARTIFACTS = process.env.SAFESTATE_HMI_ARTIFACTS || path.join(ROOT, 'build', 'hmi-artifacts');

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// Polls fn until it returns something truthy (which is returned); a throw counts as "not yet".
export async function until(what, fn, timeoutMs = 10000, everyMs = 50) {
  const end = Date.now() + timeoutMs;
  let last;
  for (;;) {
    try {
      last = await fn();
      if (last) return last;
    } catch (e) {
      last = e;
    }
    if (Date.now() > end) throw new Error(`timeout (${timeoutMs} ms) waiting for ${what}; last: ${last}`);
    await sleep(everyMs);
  }
}

export const banner = (page) =>
  page.evaluate(() => ({
    state: document.getElementById('b-state').textContent,
    sub: document.getElementById('b-sub').textContent,
    mode: document.getElementById('b-mode').textContent,
    tone: document.getElementById('banner').dataset.tone,
    cause: document.getElementById('b-cause').textContent,
    next: document.getElementById('b-next').textContent,
  }));

export async function bannerUntil(page, what, pred, timeoutMs = 10000) {
  return until(`banner ${what}`, async () => {
    const b = await banner(page);
    return pred(b) ? b : JSON.stringify(b) && false;
  }, timeoutMs);
}

// A port free on loopback now (the cell under test binds it next).
export function freePort() {
  return new Promise((resolve, reject) => {
    const srv = net.createServer();
    srv.unref();
    srv.on('error', reject);
    srv.listen(0, '127.0.0.1', () => {
      const { port } = srv.address();
      srv.close(() => resolve(port));
    });
  });
}

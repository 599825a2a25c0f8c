// Browser tests of the pendant: Debian's Chromium driven by playwright-core against a
// live `safestate run` on a free port (its own temp event database, `--static hmi/dist`),
// stopped with SIGINT at the end. One walk through the cell as an operator would do it;
// a screenshot per step goes to build/hmi-artifacts/ (SAFESTATE_HMI_ARTIFACTS).
//
//   node --test hmi/tests/browser.test.mjs
//
// Environment: SAFESTATE_BIN (default build/bin/safestate), SAFESTATE_RUN_ARGS (extra
// options for `safestate run`; default `--watchdog-ms 1000`: this checks the HMI, and a
// headless browser rendering WebGL in software on a 2-core machine must not be able to
// lock the cell out through the fieldbus watchdog), CHROMIUM (default /usr/bin/chromium).
import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import { after, before, test } from 'node:test';
import { chromium } from 'playwright-core';
import {
  ARTIFACTS, BIN, CHROMIUM, DIST, ROOT, RUN_ARGS, banner as pageBanner, bannerUntil as pageBannerUntil, sleep, until,
} from './page.mjs';

const ESTOP_BANNER_MS = 200;

let tmp;
let cell; // { proc, port, log }
let ctx;
let page;
const pageErrors = [];

// ------------------------------------------------------------------ helpers
function freePort() {
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

function getJson(port, p) {
  return new Promise((resolve, reject) => {
    const req = http.get({ host: '127.0.0.1', port, path: p, timeout: 1000 }, (res) => {
      let body = '';
      res.on('data', (c) => (body += c));
      res.on('end', () => {
        try {
          resolve(JSON.parse(body));
        } catch (e) {
          reject(e);
        }
      });
    });
    req.on('timeout', () => req.destroy(new Error('timeout')));
    req.on('error', reject);
  });
}

async function shot(name) {
  const file = path.join(ARTIFACTS, `${name}.png`);
  await page.screenshot({ path: file });
  return file;
}

const banner = () => pageBanner(page);
const bannerUntil = (what, pred, timeoutMs) => pageBannerUntil(page, what, pred, timeoutMs);

const drawn = () => page.evaluate(() => JSON.parse(document.getElementById('arm').dataset.joints || 'null'));

async function result() {
  return page.evaluate(() => {
    const r = document.getElementById('cmd-result');
    return { code: r.dataset.result, cmd: r.dataset.cmd, tone: r.dataset.tone, text: r.innerText };
  });
}

// ------------------------------------------------------------------ set-up
before(async () => {
  assert.ok(fs.existsSync(path.join(DIST, 'index.html')), `${DIST}/index.html missing: run "npm run build" in hmi/ (make test does)`);
  assert.ok(fs.existsSync(BIN), `${BIN} not found (set SAFESTATE_BIN)`);
  assert.ok(fs.existsSync(CHROMIUM), `${CHROMIUM} not found: apt-get install chromium (make test does)`);
  fs.mkdirSync(ARTIFACTS, { recursive: true });
  tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'safestate-hmi-'));

  const port = await freePort();
  const logPath = path.join(tmp, 'run.log');
  const log = fs.openSync(logPath, 'w');
  const proc = spawn(BIN, ['run', '--port', String(port), '--db', path.join(tmp, 'events.db'), '--static', DIST, '--no-opcua', ...RUN_ARGS], {
    cwd: ROOT,
    stdio: ['ignore', log, log],
  });
  cell = { proc, port, logPath, exit: new Promise((r) => proc.on('exit', (code, signal) => r({ code, signal }))) };
  await until('GET /api/status after BOOT', async () => {
    if (proc.exitCode !== null) throw new Error(`safestate run exited: ${fs.readFileSync(logPath, 'utf8')}`);
    const s = await getJson(port, '/api/status');
    return s.state !== 'BOOT';
  }, 20000);

  ctx = await chromium.launchPersistentContext(fs.mkdtempSync(path.join(tmp, 'chromium-')), {
    executablePath: CHROMIUM,
    headless: true,
    viewport: { width: 1280, height: 800 },
    args: [
      '--headless',
      '--no-sandbox',
      '--disable-gpu',
      '--disable-quic',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
    ],
  });
  page = ctx.pages()[0] ?? (await ctx.newPage());
  page.on('pageerror', (e) => pageErrors.push(e.message));
});

after(async () => {
  await ctx?.close().catch(() => {});
  if (cell?.proc.exitCode === null) {
    cell.proc.kill('SIGINT');
    const done = await Promise.race([cell.exit, sleep(10000).then(() => null)]);
    if (!done) cell.proc.kill('SIGKILL');
  }
  if (tmp && !process.env.SAFESTATE_KEEP_TMP) fs.rmSync(tmp, { recursive: true, force: true });
});

// ------------------------------------------------------------------ the walk-through
test('the page loads and shows ESTOP_RESET_NEEDED with what to do', async () => {
  await page.goto(`http://127.0.0.1:${cell.port}/`);
  // The first state may come from GET /api/status before the WebSocket is open (tone
  // 'offline' until then): judge the tone once the page is connected.
  const b = await bannerUntil('ESTOP_RESET_NEEDED, connected', (x) => x.state === 'ESTOP_RESET_NEEDED' && x.tone !== 'offline');
  assert.equal(b.tone, 'amber', 'amber while a reset is needed');
  assert.match(b.next, /Release all E-stops, then press Reset/);
  await until('the 3D view of the arm', () => drawn());
  await until('connected as pendant', () => page.evaluate(() => window.safestateHmi?.link?.role === 'pendant'));
  await until('real-time figures from /metrics', () => page.evaluate(() => /ms|µs/.test(document.getElementById('m-period')?.textContent ?? '')));
  await until('the simulated-cell panel', () => page.evaluate(() => !document.getElementById('sim-slot').hidden));
  await shot('01-estop-reset-needed');
});

test('reset gives IDLE', async () => {
  await page.click('#cmd-reset');
  const b = await bannerUntil('IDLE', (x) => x.state === 'IDLE');
  assert.match(b.next, /Servo on/);
  await shot('02-idle');
});

test('key to T1: the help says to hold the enabling device; servo on without it is refused in words', async () => {
  await page.click('#sim-mode-t1');
  let b = await bannerUntil('mode T1', (x) => x.mode.startsWith('T1') && x.state === 'IDLE');
  assert.match(b.next, /Hold the enabling device at centre, then Servo on/);
  await page.click('#cmd-servo-on');
  const r = await until('the refusal of servo_on', async () => {
    const x = await result();
    return x.cmd === 'servo_on' && x.code !== 'OK' ? x : false;
  });
  assert.equal(r.code, 'ENABLING_NOT_HELD');
  assert.equal(r.tone, 'refused');
  assert.match(r.text, /ENABLING_NOT_HELD/);
  assert.match(r.text, /Hold the enabling device at the centre position/);
  await shot('03-refused-enabling-not-held');
});

test('enabling device to centre, servo on: MANUAL_IDLE', async () => {
  await page.click('#sim-enable-centre');
  await sleep(150);
  await page.click('#cmd-servo-on');
  const b = await bannerUntil('OPERATIONAL / MANUAL_IDLE', (x) => x.state === 'OPERATIONAL' && x.sub === 'MANUAL_IDLE');
  assert.equal(b.tone, 'green');
  await shot('04-manual-idle');
});

let jogStart;
// One hold of `+` on axis 1 for 1 s; the screenshot is taken while still holding.
async function holdAxis1Plus(shotName) {
  jogStart = await drawn();
  // Seen in the page itself, whatever the polling here: the banner showed MANUAL_JOGGING.
  await page.evaluate(() => {
    const sub = document.getElementById('b-sub');
    window.__sawJogging = false;
    window.__jogObserver?.disconnect();
    window.__jogObserver = new MutationObserver(() => {
      if (sub.textContent === 'MANUAL_JOGGING') window.__sawJogging = true;
    });
    window.__jogObserver.observe(sub, { childList: true, characterData: true, subtree: true });
  });
  const box = await page.locator('#jog-1-plus').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  const t0 = Date.now();
  await page.mouse.down();
  try {
    await until('MANUAL_JOGGING', () => page.evaluate(() => window.__sawJogging), 1000).catch(() => false);
    await sleep(Math.max(0, 1000 - (Date.now() - t0)));
    const b = await banner();
    const now = await drawn();
    const { stats, alarms, saw } = await page.evaluate(() => ({
      stats: window.safestateHmi.jog,
      alarms: window.safestateHmi.status.alarms,
      saw: window.__sawJogging,
    }));
    const moved = now[0] - jogStart[0];
    console.log(`jog: joint 1 moved ${moved.toFixed(3)} rad; ${stats.sent} keep-alives in ~1 s, largest gap ${stats.maxGapMs.toFixed(1)} ms; banner ${b.sub}`);
    if (shotName && moved > 0.1) await shot(shotName);
    return { saw, b, now, moved, linkLost: alarms.includes('JOG_LINK_LOST') };
  } finally {
    await page.mouse.up();
  }
}

test('hold + on axis 1 for one second: MANUAL_JOGGING, and joint 1 moves in the 3D view', async () => {
  let r = await holdAxis1Plus('05-jogging');
  if (r.linkLost) {
    // The core stopped the jog because a keep-alive came late (SPEC rule 7, 100 ms). With
    // the page sending every 50 ms, that is a stall of this machine (e.g. a parallel
    // build): the HMI must then stop and wait for a new press, which it did. Once more.
    console.log('jog: keep-alive lost (JOG_LINK_LOST) on a loaded machine; the jog stopped as it must; holding again');
    await bannerUntil('back to MANUAL_IDLE', (x) => x.sub === 'MANUAL_IDLE', 3000);
    r = await holdAxis1Plus('05-jogging');
  }
  assert.ok(r.saw, 'the banner showed MANUAL_JOGGING while the button was held');
  assert.ok(r.moved > 0.1, `drawn joint 1 moved ${r.moved.toFixed(4)} rad in 1 s (from ${jogStart[0]} to ${r.now[0]})`);
  for (let i = 1; i < 6; i++) assert.ok(Math.abs(r.now[i] - jogStart[i]) < 1e-3, `joint ${i + 1} must not move`);
});

test('release: the jog stops, and the drawn TCP is status.tcp', async () => {
  await bannerUntil('back to MANUAL_IDLE', (x) => x.sub === 'MANUAL_IDLE', 3000);
  const a = await drawn();
  await sleep(300);
  const b = await drawn();
  assert.ok(Math.abs(a[0] - b[0]) < 1e-4, `joint 1 still moving after release: ${a[0]} -> ${b[0]}`);
  const { view, status } = await page.evaluate(() => ({ view: window.safestateHmi.view, status: window.safestateHmi.status }));
  for (let i = 0; i < 6; i++) assert.ok(Math.abs(view.joints[i] - status.joints[i]) < 1e-6, 'drawn joints = status.joints');
  for (let i = 0; i < 3; i++) {
    assert.ok(Math.abs(view.tcp[i] - status.tcp[i]) < 0.5, `drawn TCP ${view.tcp} vs status.tcp ${status.tcp.slice(0, 3)} (mm)`);
  }
  assert.ok(b[0] - jogStart[0] > 0.1, 'joint 1 stays where the jog took it');
  await shot('06-released');
});

test(`pressing the E-stop shows the red banner with its cause within ${ESTOP_BANNER_MS} ms`, async () => {
  await page.evaluate(() => {
    const m = { click: 0, banner: 0 };
    window.__estop = m;
    const seen = () => {
      const tone = document.getElementById('banner').dataset.tone;
      const cause = document.getElementById('b-cause').textContent;
      if (m.click && !m.banner && tone === 'red' && /E-stop/.test(cause)) m.banner = performance.now();
    };
    document.getElementById('sim-estop').addEventListener('pointerdown', () => (m.click = performance.now()), { capture: true, once: true });
    new MutationObserver(seen).observe(document.getElementById('banner'), { attributes: true, childList: true, subtree: true, characterData: true });
  });
  await page.click('#sim-estop');
  await page.waitForFunction(() => window.__estop.banner > 0, null, { timeout: 3000, polling: 10 });
  const m = await page.evaluate(() => window.__estop);
  const latency = m.banner - m.click;
  console.log(`E-stop click to red banner: ${latency.toFixed(1)} ms`);
  const b = await banner();
  assert.equal(b.state, 'ESTOP_ACTIVE');
  assert.match(b.cause, /E-stop/);
  assert.match(b.next, /release/i);
  assert.ok(latency < ESTOP_BANNER_MS, `red banner after ${latency.toFixed(1)} ms`);
  await until('ESTOP_PRESSED in the alarm list', () => page.evaluate(() => !!document.querySelector('#alarm-list .alarm[data-name="ESTOP_PRESSED"]')));
  await shot('07-estop');
});

test('a refused command shows its code and a sentence', async () => {
  await page.click('#cmd-servo-on');
  const r = await until('the refusal', async () => {
    const x = await result();
    return x.cmd === 'servo_on' && x.code === 'ESTOP_ACTIVE' ? x : false;
  });
  assert.equal(r.tone, 'refused');
  assert.match(r.text, /Servo on refused\s*ESTOP_ACTIVE/);
  assert.match(r.text, /An E-stop is pressed/);
  await until('the refusal in the event history', () =>
    page.evaluate(() => [...document.querySelectorAll('#event-list .event[data-kind="command"]')].some((e) => /servo_on.*ESTOP_ACTIVE/.test(e.textContent))),
  );
  await shot('08-refused-estop-active');
});

test('releasing the E-stop asks for a reset again (amber)', async () => {
  await page.click('#sim-estop');
  const b = await bannerUntil('ESTOP_RESET_NEEDED', (x) => x.state === 'ESTOP_RESET_NEEDED');
  assert.equal(b.tone, 'amber');
  await shot('09-estop-released');
  assert.deepEqual(pageErrors, [], 'no script errors on the page');
});

test('safestate run stops on SIGINT with exit 0', async () => {
  await ctx.close();
  ctx = null;
  cell.proc.kill('SIGINT');
  const r = await Promise.race([cell.exit, sleep(15000).then(() => ({ code: 'timeout' }))]);
  assert.equal(r.code, 0, `exit ${JSON.stringify(r)}: ${fs.readFileSync(cell.logPath, 'utf8').slice(-2000)}`);
});

// ------------------------------------------------------------------ login (protocol.md "Access and admission")
test('with a pendant token the page asks for it in a login screen, never in the URL, and says when the link drops', async () => {
  const port = await freePort();
  const logPath = path.join(tmp, 'run-token.log');
  const log = fs.openSync(logPath, 'w');
  const token = 'hmi-login-token-7';
  const proc = spawn(BIN, ['run', '--port', String(port), '--db', path.join(tmp, 'events-token.db'), '--static', DIST, ...RUN_ARGS], {
    cwd: ROOT,
    stdio: ['ignore', log, log],
    env: { ...process.env, SAFESTATE_PENDANT_TOKEN: token },
  });
  const exit = new Promise((r) => proc.on('exit', (code, signal) => r({ code, signal })));
  const browser = await chromium.launchPersistentContext(fs.mkdtempSync(path.join(tmp, 'chromium-login-')), {
    executablePath: CHROMIUM,
    headless: true,
    viewport: { width: 1280, height: 800 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-networking'],
  });
  try {
    await until('GET /api/status after BOOT', async () => (await getJson(port, '/api/status')).state !== 'BOOT', 20000);
    const p = browser.pages()[0] ?? (await browser.newPage());
    await p.goto(`http://127.0.0.1:${port}/`);
    await until('the login screen', () => p.evaluate(() => document.getElementById('token-dialog').open));
    const why = await p.evaluate(() => document.getElementById('token-why').textContent);
    assert.match(why, /asks for the pendant token/);
    await until('read-only meanwhile', () => p.evaluate(() => document.getElementById('conn').dataset.role === 'observer'));

    await p.fill('#token-input', 'not-the-token');
    await p.click('#token-ok');
    await until('the wrong token said in words', () =>
      p.evaluate(() => !document.getElementById('token-error').hidden && /refused/.test(document.getElementById('token-error').textContent)),
    );
    await p.fill('#token-input', token);
    await p.click('#token-ok');
    await until('control as the pendant', () => p.evaluate(() => document.getElementById('conn').dataset.role === 'pendant'));
    assert.ok(!p.url().includes(token), `the token is in the URL: ${p.url()}`);
    const stored = await p.evaluate(() => sessionStorage.getItem('safestate.token'));
    assert.equal(stored, token);

    proc.kill('SIGINT'); // the controller goes away: the page says so in words
    await until('the dropped connection in words', () =>
      p.evaluate(() => document.getElementById('conn').dataset.link === 'closed' && /controller|connection/i.test(document.getElementById('conn-note').textContent)),
    15000);
  } finally {
    await browser.close().catch(() => {});
    if (proc.exitCode === null) proc.kill('SIGINT');
    const done = await Promise.race([exit, sleep(10000).then(() => null)]);
    if (!done) proc.kill('SIGKILL');
  }
});

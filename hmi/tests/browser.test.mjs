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
import { execFileSync, spawn } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import os from 'node:os';
import path from 'node:path';
import { after, before, test } from 'node:test';
import { chromium } from 'playwright-core';
import {
  ARTIFACTS, BIN, CHROMIUM, DIST, ROOT, RUN_ARGS, banner as pageBanner, bannerUntil as pageBannerUntil, freePort, sleep,
  until,
} from './page.mjs';

const ESTOP_BANNER_MS = 200;

let tmp;
let cell; // { proc, port, log }
let ctx;
let page;
const pageErrors = [];

// ------------------------------------------------------------------ helpers
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
  await collabCell.ctx?.close().catch(() => {});
  if (collabCell.proc && collabCell.proc.exitCode === null) {
    collabCell.proc.kill('SIGINT');
    const done = await Promise.race([collabCell.exit, sleep(10000).then(() => null)]);
    if (!done) collabCell.proc.kill('SIGKILL');
  }
  await stopCell(brakeCell);
  await safetyCell.ctx?.close().catch(() => {});
  if (safetyCell.proc && safetyCell.proc.exitCode === null) {
    safetyCell.proc.kill('SIGINT');
    const done = await Promise.race([safetyCell.exit, sleep(10000).then(() => null)]);
    if (!done) safetyCell.proc.kill('SIGKILL');
  }
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
  // Without --safety: the built-in configuration, which counts as validated (SPEC §10).
  const builtIn = await getJson(cell.port, '/api/safety');
  assert.equal(builtIn.source, 'built-in');
  await until('the built-in configuration in the safety strip, validated', () =>
    page.evaluate((c) => document.getElementById('ss-checksum').textContent === c && document.getElementById('ss-valid').dataset.validated === 'yes',
      builtIn.checksum));
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

// ------------------------------------------------------------------ the safety configuration (SPEC §10, issue 19)
// A cell of its own with `--safety hmi/tests/safety-cell.json`: a keep-in box, a keep-out
// "fixture" 15 mm beside the tool sphere at the start pose (+y, where a runaway of axis 1
// drives it within 2°, before its following error), a reduced zone elsewhere.
const SAFETY_FILE = path.join(ROOT, 'hmi', 'tests', 'safety-cell.json');
const safetyCell = {};

async function sp(fn, arg) {
  return safetyCell.page.evaluate(fn, arg);
}
const spStatus = () => sp(() => window.safestateHmi.status);
const spShot = (name) => safetyCell.page.screenshot({ path: path.join(ARTIFACTS, `${name}.png`) });

test('safety: the Safety page shows the configuration and its checksum in large type', async () => {
  const check = execFileSync(BIN, ['safety', 'check', SAFETY_FILE], { encoding: 'utf8' });
  safetyCell.checksum = /checksum:\s+([0-9A-F]{8})/.exec(check)[1];
  safetyCell.config = JSON.parse(fs.readFileSync(SAFETY_FILE, 'utf8'));
  const port = await freePort();
  const logPath = path.join(tmp, 'run-safety.log');
  const log = fs.openSync(logPath, 'w');
  const proc = spawn(BIN, ['run', '--port', String(port), '--db', path.join(tmp, 'events-safety.db'), '--static', DIST, '--no-opcua',
    '--safety', SAFETY_FILE, ...RUN_ARGS], { cwd: ROOT, stdio: ['ignore', log, log] });
  Object.assign(safetyCell, { proc, port, logPath, errors: [], exit: new Promise((r) => proc.on('exit', (code, signal) => r({ code, signal }))) });
  await until('GET /api/status after BOOT', async () => {
    if (proc.exitCode !== null) throw new Error(`safestate run --safety exited: ${fs.readFileSync(logPath, 'utf8')}`);
    return (await getJson(port, '/api/status')).state !== 'BOOT';
  }, 20000);
  safetyCell.ctx = await chromium.launchPersistentContext(fs.mkdtempSync(path.join(tmp, 'chromium-safety-')), {
    executablePath: CHROMIUM,
    headless: true,
    viewport: { width: 1280, height: 800 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-networking'],
  });
  const page = safetyCell.ctx.pages()[0] ?? (await safetyCell.ctx.newPage());
  safetyCell.page = page;
  page.on('pageerror', (e) => safetyCell.errors.push(e.message));
  await page.goto(`http://127.0.0.1:${port}/`);
  await until('connected as pendant', () => sp(() => window.safestateHmi?.link?.role === 'pendant'));
  const { checksum, config } = safetyCell;

  // On every page: the strip under the banner.
  await until('the checksum in the strip', () => sp(() => document.getElementById('ss-checksum').textContent) .then((t) => t === checksum));
  assert.equal(await sp(() => document.getElementById('ss-valid').dataset.validated), 'no', 'a fresh configuration is not validated');

  await page.click('#tab-safety');
  const head = await until('the Safety page filled in', () =>
    sp(() => {
      const el = document.getElementById('sp-checksum');
      const name = document.getElementById('sp-name').textContent;
      if (document.getElementById('safety-page').hidden || !document.getElementById('sp-zone-0')) return false;
      return { text: el.textContent, px: parseFloat(getComputedStyle(el).fontSize), h: el.getBoundingClientRect().height, name,
        valid: document.getElementById('sp-valid').dataset.validated, word: document.getElementById('sp-valid-word').textContent };
    }),
  );
  assert.equal(head.text, checksum, 'the checksum `safestate safety check` prints');
  assert.ok(head.px >= 48, `checksum font ${head.px} px: readable from 1 m`);
  assert.equal(head.name, config.name);
  assert.equal(head.valid, 'no');
  assert.match(head.word, /NOT VALIDATED/);
  const tables = await sp(() => ({
    joints: [...document.querySelectorAll('#sp-joints tbody tr')].map((tr) => [...tr.cells].slice(1, 4).map((c) => Number(c.textContent))),
    zones: [...document.querySelectorAll('#sp-zones tbody tr')].map((tr) => [tr.dataset.zone, tr.dataset.kind]),
    bar1: { ...document.getElementById('joint-1-bar').dataset, text: document.getElementById('joint-1-range').textContent },
  }));
  assert.deepEqual(tables.joints, config.joints.map((j) => [j.min_deg, j.max_deg, j.max_speed_deg_s]));
  assert.deepEqual(tables.zones, config.zones.map((z) => [z.name, z.kind]));
  // The joint bars: the configured range (J1 ±150°), not only the robot's (±165°).
  assert.deepEqual([Number(tables.bar1.min), Number(tables.bar1.max)], [-150, 150]);
  assert.match(tables.bar1.text, /-150…150°/);
  await spShot('11-safety-page');
});

test('safety: the validate dialog is disabled, saying why, for an observer and outside T1/T2 IDLE', async () => {
  const page = safetyCell.page;
  const why = () => sp(() => ({ disabled: document.getElementById('sp-validate').disabled, why: document.getElementById('sp-validate-why').textContent }));
  let w = await why();
  assert.equal(w.disabled, true, 'ESTOP_RESET_NEEDED in AUTO');
  assert.match(w.why, /T1 or T2 \(now AUTO\)/);
  assert.match(w.why, /IDLE/);
  await page.click('#cmd-reset');
  await page.click('#tab-operate'); // the simulated cell's panel is on the Operate page
  await page.click('#sim-mode-t1');
  await page.click('#tab-safety');
  await until('T1 IDLE', async () => {
    const s = await spStatus();
    return s.state === 'IDLE' && s.mode === 'T1';
  });
  w = await until('the dialog enabled for the pendant in T1 IDLE', async () => ((await why()).disabled ? false : why()));
  assert.equal(w.disabled, false);

  // A second screen is an observer: same state, and its button stays disabled, saying why.
  const obs = await safetyCell.ctx.newPage();
  try {
    await obs.goto(`http://127.0.0.1:${safetyCell.port}/`);
    await until('the second screen is an observer', () => obs.evaluate(() => window.safestateHmi?.link?.role === 'observer'));
    await obs.click('#tab-safety');
    const o = await until('the observer sees T1 IDLE', () =>
      obs.evaluate(() => (window.safestateHmi.status?.mode === 'T1' ? {
        disabled: document.getElementById('sp-validate').disabled, why: document.getElementById('sp-validate-why').textContent,
        checksum: document.getElementById('sp-checksum').textContent } : false)),
    );
    assert.equal(o.disabled, true, 'an observer may not validate');
    assert.match(o.why, /read-only \(observer\)/);
    assert.doesNotMatch(o.why, /T1 or T2|IDLE/, 'only the reason that applies');
    assert.equal(o.checksum, safetyCell.checksum, 'an observer reads the checksum too');
  } finally {
    await obs.close();
  }
});

test('safety: as the pendant in T1 IDLE, a wrong code is CHECKSUM_MISMATCH and the right one validates', async () => {
  const page = safetyCell.page;
  const { checksum } = safetyCell;
  await page.click('#sp-validate');
  await until('the dialog open', () => sp(() => document.getElementById('validate-dialog').open));
  const wrong = checksum.slice(0, 7) + (checksum[7] === '0' ? '1' : '0');
  await page.fill('#validate-code', '12345');
  assert.match(await sp(() => document.getElementById('validate-problem').textContent), /5 of 8/);
  assert.equal(await sp(() => document.getElementById('validate-send').disabled), true, 'an incomplete code is not sent');
  await page.fill('#validate-code', wrong);
  await page.click('#validate-send');
  const r1 = await until('the reply to the wrong code', () =>
    sp(() => { const r = document.getElementById('validate-result'); return r.dataset.result && r.dataset.result !== 'pending' ? { code: r.dataset.result, text: r.textContent } : false; }));
  assert.equal(r1.code, 'CHECKSUM_MISMATCH', r1.text);
  assert.match(r1.text, /nothing changed/);
  await sleep(200);
  assert.equal((await spStatus()).safety.validated, false, 'a wrong code changes nothing');
  assert.equal(await sp(() => document.getElementById('sp-valid').dataset.validated), 'no');
  await spShot('12-validate-mismatch');

  await page.fill('#validate-code', checksum.toLowerCase()); // case does not matter
  await page.click('#validate-send');
  const r2 = await until('the reply to the right code', () =>
    sp(() => { const r = document.getElementById('validate-result'); return r.dataset.result === 'OK' || r.dataset.result === 'CHECKSUM_MISMATCH' && r.textContent.includes(document.getElementById('sp-checksum').textContent) ? { code: r.dataset.result, text: r.textContent } : false; }));
  assert.equal(r2.code, 'OK', r2.text);
  const v = await until('validated on the page, with the confirmation', () =>
    sp(() => {
      const t = document.getElementById('sp-valid-text').textContent;
      return document.getElementById('sp-valid').dataset.validated === 'yes' && /Confirmed by/.test(t)
        ? { t, strip: document.getElementById('ss-valid').textContent } : false;
    }));
  assert.match(v.t, /Confirmed by "SafeState HMI"/);
  assert.match(v.strip, /validated/);
  await spShot('13-validated');
  await page.click('#validate-close');
  await until('the validation in the history', () =>
    sp((c) => [...document.querySelectorAll('#event-list .event')].some((e) => e.textContent.includes(`${c} validated`)), checksum));
});

test('safety: zones and the tool sphere drawn in the 3D view; the drawn TCP is the tool TCP', async () => {
  const page = safetyCell.page;
  await page.click('#tab-operate');
  const z = await until('the zones drawn', () =>
    sp(() => (document.getElementById('arm').dataset.zones === '3' ? {
      zones: window.safestateHmi.zones.map((x) => [x.name, x.kind]),
      legend: [...document.querySelectorAll('#zone-legend .legend-item')].map((e) => e.textContent),
    } : false)));
  assert.deepEqual(z.zones, safetyCell.config.zones.map((x) => [x.name, x.kind]));
  assert.deepEqual(z.legend, ['keep-in', 'keep-out', 'reduced', 'tool ⌀80 mm']);
  const { view, status } = await sp(() => ({ view: window.safestateHmi.view, status: window.safestateHmi.status }));
  for (let i = 0; i < 3; i++) {
    assert.ok(Math.abs(view.tcp[i] - status.tcp[i]) < 0.5, `drawn TCP ${view.tcp} vs status.tcp ${status.tcp.slice(0, 3)} (tool [0, 0, 120])`);
  }
});

const reducedIs = (want, by) => until(`reduced=${want}`, async () => {
  const s = await spStatus();
  return s.safety.reduced === want && (!by || s.safety.reduced_by.includes(by)) && s.alarms.includes('REDUCED_SPEED') === want ? s : false;
}, 5000);

test('safety: the simulated cell\'s reduced-speed input, both channels', async () => {
  const page = safetyCell.page;
  await page.click('#tab-operate');
  await page.click('#sim-reduced-reduced');
  await reducedIs(true, 'input');
  await until('reduced speed by input in the strip', () => sp(() => /Reduced speed: input/.test(document.getElementById('ss-reduced').textContent)), 3000);
  // The monitor applies the reduced limit once reduced.ramp_ms (500 ms) has passed.
  await until('the reduced limit in force in the strip', () => sp(() => /TCP ≤ 250 mm\/s/.test(document.getElementById('ss-limit').textContent)), 3000);
  await page.click('#sim-reduced-normal');
  await reducedIs(false);
});

test('safety: a runaway into the keep-out zone is highlighted with its name', async () => {
  const page = safetyCell.page;
  await page.click('#sim-mode-auto');
  await until('AUTO IDLE', async () => { const s = await spStatus(); return s.mode === 'AUTO' && s.state === 'IDLE'; });
  await page.click('#cmd-servo-on');
  await until('AUTO_IDLE (validated: AUTO allowed)', async () => (await spStatus()).sub === 'AUTO_IDLE', 10000).catch(async (e) => {
    throw new Error(`${e.message}; ${JSON.stringify(await spStatus())}; ${JSON.stringify((await sp(() => window.safestateHmi.outcomes)).slice(-3))}`);
  });
  await page.selectOption('#sim-axis', '1');
  await page.click('#sim-drive-runaway');
  const s = await until('ZONE_VIOLATION, Cat 0 to IDLE', async () => {
    const x = await spStatus();
    return x.state === 'IDLE' && x.alarms.includes('ZONE_VIOLATION') ? x : false;
  }, 10000).catch(async (e) => {
    throw new Error(`${e.message}; ${JSON.stringify(await spStatus())}`);
  });
  assert.ok(!s.alarms.includes('DRIVE_FAULT'), `the zone monitor trips first: ${s.alarms}`);
  const h = await until('the fixture highlighted', () =>
    sp(() => (document.getElementById('arm').dataset.zonesViolated === 'fixture' ? {
      strip: document.getElementById('ss-violation').textContent,
      zones: window.safestateHmi.zones.filter((z) => z.violated).map((z) => z.name),
    } : false)));
  assert.deepEqual(h.zones, ['fixture']);
  assert.match(h.strip, /ZONE_VIOLATION · zone fixture/);
  await spShot('14-zone-violation-3d');
  await page.click('#tab-safety');
  const p = await sp(() => ({
    row: document.getElementById('sp-zone-1').classList.contains('violated'),
    others: [0, 2].map((i) => document.getElementById(`sp-zone-${i}`).classList.contains('violated')),
    box: document.getElementById('sp-violations').hidden ? '' : document.getElementById('sp-violations').textContent,
  }));
  assert.equal(p.row, true, 'the fixture row is marked');
  assert.deepEqual(p.others, [false, false]);
  assert.match(p.box, /ZONE_VIOLATION · zone fixture/);
  await spShot('15-zone-violation-safety-page');

  // Reset: the alarm goes, the arm is still in the zone: recovery.
  await page.click('#tab-operate');
  await page.click('#sim-clear-all');
  await page.click('#cmd-reset');
  await until('recovery shown, highlight gone', () =>
    sp(() => document.getElementById('sp-recovery').textContent === 'YES' && document.getElementById('arm').dataset.zonesViolated === ''));
  assert.deepEqual(safetyCell.errors, [], 'no script errors on the page');
});

test('safety: one reduced-speed channel alone: reduced speed stays on (the safe side), also once it closes', async () => {
  const page = safetyCell.page;
  await page.click('#tab-operate');
  await page.click('#sim-reduced-a');
  await reducedIs(true, 'input');
  await until('channel A shown open alone', () => sp(() => /A open, B closed/.test(document.getElementById('sim-reduced-note').textContent)), 3000);
  await sleep(200); // longer than the discrepancy time (50 ms)
  await page.click('#sim-reduced-a');
  await until('channel A shown closed again', () => sp(() => /A closed, B closed/.test(document.getElementById('sim-reduced-note').textContent)));
  await sleep(300);
  const s = await reducedIs(true, 'input'); // SPEC §10: a discrepancy keeps reduced mode on, no lockout
  assert.notEqual(s.state, 'ERROR_LOCKOUT');
  assert.deepEqual(safetyCell.errors, [], 'no script errors on the page');
});

test('safety: safestate run --safety stops on SIGINT with exit 0', async () => {
  await safetyCell.ctx?.close();
  safetyCell.ctx = null;
  safetyCell.proc.kill('SIGINT');
  const r = await Promise.race([safetyCell.exit, sleep(15000).then(() => ({ code: 'timeout' }))]);
  assert.equal(r.code, 0, `exit ${JSON.stringify(r)}: ${fs.readFileSync(safetyCell.logPath, 'utf8').slice(-2000)}`);
});

// ------------------------------------------------------------------ collaborative operation (SPEC §11, issue 20)
// A cell of its own with hmi/tests/collab-cell.json, examples/safety/collaborative.json
// without its brake test (which would have to run before AUTO): fields, SSM with v_h 1600,
// a 2000, T_r 100 ms, C 200, Z 100; PFL for the hand: F_qs 140 N. The Safety page's
// Collaborative section and the simulated cell's field, separation and contact controls.
const COLLAB_FILE = path.join(ROOT, 'hmi', 'tests', 'collab-cell.json');
const collabCell = {};
const cp = (fn, arg) => collabCell.page.evaluate(fn, arg);
const cpStatus = () => cp(() => window.safestateHmi.status);
const cpShot = (name) => collabCell.page.screenshot({ path: path.join(ARTIFACTS, `${name}.png`), fullPage: true });
const collab = () => cp(() => {
  const t = (id) => document.getElementById(id)?.textContent ?? null;
  return {
    outer: document.getElementById('cb-field-outer')?.dataset.state, inner: document.getElementById('cb-field-inner')?.dataset.state,
    outerWord: t('cb-field-outer-word'), innerWord: t('cb-field-inner-word'), person: t('cb-person'),
    ssm: t('cb-ssm'), ssmDetail: t('cb-ssm-detail'), speed: t('cb-speed'), by: t('cb-limit-by'),
    limitBy: document.getElementById('sp-collab')?.dataset.limitBy,
    why: [...document.querySelectorAll('#cb-why li')].map((li) => li.textContent),
    pfl: t('cb-pfl'), force: t('cb-force'), enabled: t('cb-enabled'),
    collision: document.getElementById('cb-collision')?.hidden === false ? t('cb-collision') : '',
  };
});
const cpUntil = (what, pred, ms = 8000) => until(what, async () => {
  const c = await collab();
  const s = await cpStatus();
  return pred(c, s) ? { c, s } : false;
}, ms).catch(async (e) => {
  throw new Error(`${e.message}; section ${JSON.stringify(await collab())}; status ${JSON.stringify(await cpStatus())}`);
});

test('collaborative: the Safety page has the Collaborative section, fields clear, SSM and PFL as configured', async () => {
  const check = execFileSync(BIN, ['safety', 'check', COLLAB_FILE], { encoding: 'utf8' });
  collabCell.checksum = /checksum:\s+([0-9A-F]{8})/.exec(check)[1];
  const port = await freePort();
  const logPath = path.join(tmp, 'run-collab.log');
  const log = fs.openSync(logPath, 'w');
  const proc = spawn(BIN, ['run', '--port', String(port), '--db', path.join(tmp, 'events-collab.db'), '--static', DIST, '--no-opcua',
    '--safety', COLLAB_FILE, ...RUN_ARGS], { cwd: ROOT, stdio: ['ignore', log, log] });
  Object.assign(collabCell, { proc, port, logPath, errors: [], exit: new Promise((r) => proc.on('exit', (code, signal) => r({ code, signal }))) });
  await until('GET /api/status after BOOT', async () => {
    if (proc.exitCode !== null) throw new Error(`safestate run --safety exited: ${fs.readFileSync(logPath, 'utf8')}`);
    return (await getJson(port, '/api/status')).state !== 'BOOT';
  }, 20000);
  collabCell.ctx = await chromium.launchPersistentContext(fs.mkdtempSync(path.join(tmp, 'chromium-collab-')), {
    executablePath: CHROMIUM,
    headless: true,
    viewport: { width: 1280, height: 900 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-networking'],
  });
  const page = collabCell.ctx.pages()[0] ?? (await collabCell.ctx.newPage());
  collabCell.page = page;
  page.on('pageerror', (e) => collabCell.errors.push(e.message));
  await page.goto(`http://127.0.0.1:${port}/`);
  await until('connected as pendant', () => cp(() => window.safestateHmi?.link?.role === 'pendant'));
  await page.click('#tab-safety');
  const { c } = await cpUntil('the section filled in', (x) => x.outer === 'clear' && x.inner === 'clear' && /enabled/.test(x.enabled ?? ''));
  assert.match(c.enabled, /· enabled in this configuration/);
  assert.equal(c.outerWord, 'Clear');
  assert.match(c.person, /Nobody in either field/);
  assert.equal(c.pfl, 'ON');
  assert.match(c.force, /^\d+\.\d N of 140 N \(F_qs, COLLISION above\)$/, 'the force against the hand region\'s F_qs');
  // The panel has the controls (on the Operate page).
  for (const id of ['sim-field-outer-clear', 'sim-field-outer-interrupted', 'sim-field-inner-clear', 'sim-field-inner-interrupted',
    'sim-separation', 'sim-separation-range', 'sim-separation-valid', 'sim-contact-force', 'sim-contact', 'sim-contact-0']) {
    assert.ok(await cp((i) => !!document.getElementById(i), id), `#${id} in the simulated-cell panel`);
  }
  await page.click('#tab-operate');
  await cpShot('20-collab-panel');
  await page.click('#tab-safety');
});

test('collaborative: validated, AUTO, servo on: SSM holds at an unknown separation, says why, and follows the panel\'s separation', async () => {
  const page = collabCell.page;
  await page.click('#cmd-reset');
  await page.click('#tab-operate');
  await page.click('#sim-mode-t1');
  await until('T1 IDLE', async () => { const s = await cpStatus(); return s.state === 'IDLE' && s.mode === 'T1'; });
  await page.click('#tab-safety');
  await until('validate enabled', () => cp(() => !document.getElementById('sp-validate').disabled));
  await page.click('#sp-validate');
  await page.fill('#validate-code', collabCell.checksum);
  await page.click('#validate-send');
  await until('validated', async () => (await cpStatus()).safety.validated === true);
  await page.click('#validate-close');
  await page.click('#tab-operate');
  await page.click('#sim-mode-auto');
  await until('AUTO IDLE', async () => { const s = await cpStatus(); return s.state === 'IDLE' && s.mode === 'AUTO'; });
  await page.click('#cmd-servo-on');
  await until('AUTO_IDLE', async () => (await cpStatus()).sub === 'AUTO_IDLE', 10000);
  // No sensor reading yet: unknown counts as 0, SSM holds, and the section says so.
  let r = await cpUntil('SSM holding', (x) => x.limitBy === 'ssm-hold');
  assert.equal(r.c.ssm, '0 mm/s');
  assert.ok(r.c.why.some((w) => /holds the robot: at a separation of 0 mm, v_allowed is 0 mm\/s/.test(w)), r.c.why.join(' | '));
  assert.match(r.c.speed, /^0 \/ 0 mm\/s$/);
  // 800 mm from the panel's number field: v_allowed 344.8 mm/s (collaborative.md's worked example).
  await page.fill('#sim-separation', '800');
  await page.press('#sim-separation', 'Enter');
  await page.locator('#sim-separation').blur();
  // The separation the core believes rises at most 3.5 mm a cycle: wait for the section to show 800 mm.
  r = await cpUntil('v_allowed at 800 mm', (x, s) => s.safety.separation_mm === 800 && x.limitBy === 'ssm' && /separation of 800 mm/.test(x.ssmDetail));
  assert.equal(r.s.safety.v_allowed, 344.8);
  assert.equal(r.c.ssm, '345 mm/s');
  assert.match(r.c.ssmDetail, /separation of 800 mm/);
  assert.ok(r.c.why.some((w) => /separation of 800 mm the TCP may move at 345 mm\/s/.test(w)), r.c.why.join(' | '));
  assert.equal(await cp(() => document.getElementById('sim-separation-valid').textContent), 'valid');
  // A bad number is refused in the panel, nothing sent.
  await page.fill('#sim-separation', '-5');
  await page.locator('#sim-separation').blur();
  await until('the refusal in words', () => cp(() => /not a separation/.test(document.getElementById('sim-separation-note').textContent)));
  await sleep(200);
  assert.equal((await cpStatus()).safety.separation_mm, 800, 'nothing changed');
  await page.click('#tab-safety');
  await cpShot('21-collab-ssm-800');
  await page.click('#tab-operate');
  // Far away: the normal limit again.
  await page.fill('#sim-separation', '5000');
  await page.locator('#sim-separation').blur();
  await cpUntil('normal limit at 5000 mm', (x, s) => s.safety.separation_mm > 4000 && x.limitBy === 'normal', 10000);
});

// @req COL-SIM-PERSON
// Before the panel's manual field tests: after a manual outer-field episode the core trips
// SPEED_LIMIT (255 > 250 mm/s) 768 ms after a person walks in at 1.6 m/s (a core finding,
// reproduced by a replay scenario and reported with this branch). Open: after this test the
// manual outer-field test is followed by SPEED_LIMIT (611 mm/s) too, which the contact test
// below then shows (its wait now prints the status).
test('collaborative: a person walked in from the panel: drawn with both fields, the inner one pauses the robot; walked out, it resumes', async () => {
  const page = collabCell.page;
  const arm = () => cp(() => {
    const a = document.getElementById('arm');
    return { person: a.dataset.person, xy: a.dataset.personXy, fields: a.dataset.fields, objects: Number(a.dataset.personObjects ?? 0),
      note: document.getElementById('sim-person-note')?.textContent, line: document.getElementById('cb-sim-person')?.textContent };
  });
  const armUntil = (what, pred, ms = 8000) => until(what, async () => {
    const a = await arm();
    const s = await cpStatus();
    return pred(a, s) ? { a, s } : false;
  }, ms).catch(async (e) => {
    const s = await cpStatus();
    throw new Error(`${e.message}; arm ${JSON.stringify(await arm())}; status ${JSON.stringify({ state: s.state, sub: s.sub, alarms: s.alarms, cause: s.cause, sim: s.sim, safety: s.safety })}`);
  });
  if ((await cpStatus()).sub === 'AUTO_IDLE') await page.click('#cmd-start');
  await until('AUTO_RUNNING', async () => (await cpStatus()).sub === 'AUTO_RUNNING', 8000);
  let r = await armUntil('the fields drawn, nobody in the cell', (a) => a.person === 'absent' && a.fields === 'outer:clear,inner:clear');
  assert.equal(r.a.objects, 4, 'two fields, each a disc and its edge');
  assert.ok(await cp(() => document.getElementById('sim-person-leave').disabled), 'Leave needs a person');
  // A speed over 2 m/s is refused in the panel: nothing sent, nobody placed.
  await page.fill('#sim-person-speed', '2500');
  await page.click('#sim-person-in');
  await until('the refusal in words', () => cp(() => /over 2000.*Nothing sent/.test(document.getElementById('sim-person-note').textContent)));
  await sleep(300);
  assert.equal((await cpStatus()).sim.person, null, 'nothing changed');
  // In from the left (+y) at 1.6 m/s, from 3 m to 0.8 m.
  await page.fill('#sim-person-speed', '1600');
  await page.selectOption('#sim-person-dir', '90');
  await page.click('#sim-person-in');
  r = await armUntil('the person drawn walking', (a, s) => a.person === 'present' && s.sim.person?.walking);
  assert.equal(r.s.sim.person.speed_mm_s, 1600);
  assert.equal(r.a.objects, 9, 'fields, body, head, footprint, separation line and its label');
  r = await armUntil('reduced by the outer field, drawn interrupted', (a, s) => a.fields.startsWith('outer:interrupted') && s.safety.reduced_by.includes('field'));
  r = await armUntil('PERSON_IN_FIELD: the inner field drawn interrupted, the program paused',
    // The page draws from its own status, which may be one behind the API's: wait until it
    // has drawn the person where the status says it stopped (the CI run read 0,811).
    (a, s) => a.fields === 'outer:interrupted,inner:interrupted' && s.alarms.includes('PERSON_IN_FIELD') && s.sub === 'AUTO_PAUSED' &&
      !s.sim.person.walking && a.xy === `${s.sim.person.x_mm},${s.sim.person.y_mm}`, 8000);
  assert.equal(r.s.sim.person.x_mm, 0);
  assert.equal(r.s.sim.person.y_mm, 800);
  assert.match(r.a.note, /standing, 0\.80 m from the base axis, in the inner field/);
  assert.equal(r.s.safety.separation_mm === null || r.s.safety.separation_mm < 600, true, 'the distance sensor sees the person');
  await cpShot('25-collab-person-in');
  await page.click('#tab-safety');
  const c = await collab();
  assert.match(c.person, /PERSON_IN_FIELD/);
  assert.match(await cp(() => document.getElementById('cb-sim-person').textContent), /Simulated person: standing/);
  await cpShot('26-collab-person-safety-page');
  await page.click('#tab-operate');
  // Out along its own bearing to 3 m: both fields clear, the pause resumes by itself.
  await page.click('#sim-person-out');
  r = await armUntil('walked out, fields clear, running again', (a, s) => a.fields === 'outer:clear,inner:clear' && a.xy === '0,3000' &&
    s.sub === 'AUTO_RUNNING' && !s.alarms.includes('PERSON_IN_FIELD'), 10000);
  await page.click('#sim-person-leave');
  r = await armUntil('the person gone', (a, s) => a.person === 'absent' && s.sim.person === null);
  assert.equal(r.a.objects, 4);
  assert.match(r.a.note, /not in the cell/);
  // The panel's separation applies again (5000 mm, set above): the normal limit.
  await cpUntil('normal limit again', (x, s) => s.safety.separation_mm > 4000 && x.limitBy === 'normal', 10000);
  assert.deepEqual(collabCell.errors, [], 'no script errors on the page');
});

test('collaborative: the inner field from the panel while AUTO_RUNNING: PERSON_IN_FIELD, the field shown interrupted, resume when clear', async () => {
  const page = collabCell.page;
  await page.click('#cmd-start');
  await until('AUTO_RUNNING', async () => (await cpStatus()).sub === 'AUTO_RUNNING', 5000);
  await page.click('#sim-field-inner-interrupted');
  let r = await cpUntil('PERSON_IN_FIELD and the inner field interrupted',
    (x, s) => s.alarms.includes('PERSON_IN_FIELD') && x.inner === 'interrupted' && s.sub !== 'AUTO_RUNNING');
  assert.equal(r.c.innerWord, 'INTERRUPTED');
  assert.equal(r.c.outer, 'clear');
  assert.match(r.c.person, /PERSON_IN_FIELD/);
  assert.ok(r.c.why.some((w) => /inner protective field is interrupted/.test(w)), r.c.why.join(' | '));
  assert.ok(await cp(() => document.getElementById('sim-field-inner-interrupted').classList.contains('on')), 'the panel shows what it set');
  await page.click('#tab-safety');
  await cpShot('22-collab-person-in-field');
  await page.click('#tab-operate');
  await page.click('#sim-field-inner-clear');
  r = await cpUntil('resumed by itself after resume_delay_ms', (x, s) => s.sub === 'AUTO_RUNNING' && x.inner === 'clear', 8000);
  assert.ok(!r.s.alarms.includes('PERSON_IN_FIELD'));
});

test('collaborative: the outer field from the panel: reduced speed, and why in words', async () => {
  const page = collabCell.page;
  await page.click('#sim-field-outer-interrupted');
  const r = await cpUntil('reduced by the field', (x, s) => x.outer === 'interrupted' && s.safety.reduced_by.includes('field'));
  assert.ok(r.c.why.some((w) => /outer protective field is interrupted/.test(w)), r.c.why.join(' | '));
  assert.match(r.c.person, /outer field: reduced speed/);
  await page.click('#tab-safety');
  await cpShot('23-collab-outer-field');
  await page.click('#tab-operate');
  await page.click('#sim-field-outer-clear');
  await cpUntil('normal again', (x, s) => x.outer === 'clear' && !s.safety.reduced, 5000);
});

test('collaborative: a contact from the panel while running: COLLISION highlighted with its force, then contact 0', async () => {
  const page = collabCell.page;
  await until('AUTO_RUNNING at speed', async () => { const s = await cpStatus(); return s.sub === 'AUTO_RUNNING' && s.tcp_speed > 200; }, 10000)
    .catch(async (e) => { const s = await cpStatus(); throw new Error(`${e.message}; ${JSON.stringify({ state: s.state, sub: s.sub, alarms: s.alarms, cause: s.cause, tcp: s.tcp_speed, prog: [s.program_index, s.program_length], safety: s.safety })}`); });
  // Out of range: refused in the panel, nothing sent.
  await page.fill('#sim-contact-force', '6000');
  await page.click('#sim-contact');
  assert.match(await cp(() => document.getElementById('sim-contact-note').textContent), /not a contact force: 0 to 5000 N/);
  await page.fill('#sim-contact-force', '300');
  await page.click('#sim-contact');
  const r = await cpUntil('COLLISION in the section, with its detail', (x, s) => s.alarms.includes('COLLISION') && /^COLLISION: /.test(x.collision), 8000);
  assert.match(r.c.collision, /^COLLISION: .*\d+(\.\d)? N/, 'the core\'s detail with the force');
  assert.match(r.c.collision, /backs off 10 mm/);
  await page.click('#tab-safety');
  await cpShot('24-collab-collision');
  await page.click('#tab-operate');
  await page.click('#sim-contact-0');
  assert.match(await cp(() => document.getElementById('sim-contact-note').textContent), /contact removed/);
  assert.deepEqual(collabCell.errors, [], 'no script errors on the page');
});

test('collaborative: safestate run stops on SIGINT with exit 0', async () => {
  await collabCell.ctx?.close();
  collabCell.ctx = null;
  collabCell.proc.kill('SIGINT');
  const r = await Promise.race([collabCell.exit, sleep(15000).then(() => ({ code: 'timeout' }))]);
  assert.equal(r.code, 0, `exit ${JSON.stringify(r)}: ${fs.readFileSync(collabCell.logPath, 'utf8').slice(-2000)}`);
});

// ------------------------------------------------------------------ brake test (SPEC §12, issue 21 item 3)
// A cell of its own with tests/scenarios/configs/brake-test.json (a test every 8 h, 1 h grace,
// max drift 0.5°) and a fresh event log: never tested. The Safety page's Brake test section,
// its Run button as the pendant in T1, the axes while it runs, and a weak brake on axis 3
// from the simulated cell's panel.
const BRAKE_FILE = path.join(ROOT, 'tests', 'scenarios', 'configs', 'brake-test.json');
const brakeCell = {};

/** `safestate run --safety FILE` on a free port with its own log, and a headless page on it as the pendant. */
async function startCell(c, name, safetyFile) {
  const port = await freePort();
  const logPath = path.join(tmp, `run-${name}.log`);
  const log = fs.openSync(logPath, 'w');
  const proc = spawn(BIN, ['run', '--port', String(port), '--db', path.join(tmp, `events-${name}.db`), '--static', DIST, '--no-opcua',
    '--safety', safetyFile, ...RUN_ARGS], { cwd: ROOT, stdio: ['ignore', log, log] });
  Object.assign(c, { proc, port, logPath, errors: [], exit: new Promise((r) => proc.on('exit', (code, signal) => r({ code, signal }))) });
  await until('GET /api/status after BOOT', async () => {
    if (proc.exitCode !== null) throw new Error(`safestate run --safety exited: ${fs.readFileSync(logPath, 'utf8')}`);
    return (await getJson(port, '/api/status')).state !== 'BOOT';
  }, 20000);
  c.ctx = await chromium.launchPersistentContext(fs.mkdtempSync(path.join(tmp, `chromium-${name}-`)), {
    executablePath: CHROMIUM,
    headless: true,
    viewport: { width: 1280, height: 900 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-networking'],
  });
  c.page = c.ctx.pages()[0] ?? (await c.ctx.newPage());
  c.page.on('pageerror', (e) => c.errors.push(e.message));
  await c.page.goto(`http://127.0.0.1:${port}/`);
  await until('connected as pendant', () => c.page.evaluate(() => window.safestateHmi?.link?.role === 'pendant'));
}

/** Closes the page and stops the cell (SIGINT, then SIGKILL after 10 s); the exit. */
async function stopCell(c) {
  await c.ctx?.close().catch(() => {});
  c.ctx = null;
  if (!c.proc || c.proc.exitCode !== null) return c.exit;
  c.proc.kill('SIGINT');
  const done = await Promise.race([c.exit, sleep(10000).then(() => null)]);
  if (!done) c.proc.kill('SIGKILL');
  return done;
}

const bp = (fn, arg) => brakeCell.page.evaluate(fn, arg);
const bpStatus = () => bp(() => window.safestateHmi.status);
const bpShot = (name) => brakeCell.page.screenshot({ path: path.join(ARTIFACTS, `${name}.png`), fullPage: true });
const brakeSection = () => bp(() => {
  const t = (id) => document.getElementById(id)?.textContent ?? null;
  const due = document.getElementById('bt-due');
  return {
    due: t('bt-due'), dueTone: due?.dataset.tone, dueRed: !!due?.classList.contains('bad'), dueRole: due?.getAttribute('role'),
    dueDetail: t('bt-due-detail'), last: t('bt-last'), when: t('bt-last-when'), reply: t('bt-reply'), label: t('bt-axes-label'),
    run: !document.getElementById('bt-run')?.disabled, why: t('bt-run-why'), running: document.getElementById('sp-brake')?.dataset.running,
    axes: [1, 2, 3, 4, 5, 6].map((a) => ({ phase: document.getElementById(`bt-axis-${a}`)?.dataset.phase, word: t(`bt-axis-${a}-word`),
      current: document.getElementById(`bt-axis-${a}`)?.getAttribute('aria-current') })),
  };
});
const bpUntil = (what, pred, ms = 8000) => until(what, async () => {
  const b = await brakeSection();
  const s = await bpStatus();
  return pred(b, s) ? { b, s } : false;
}, ms).catch(async (e) => {
  throw new Error(`${e.message}; section ${JSON.stringify(await brakeSection())}; status ${JSON.stringify((await bpStatus())?.safety)}`);
});
const BRAKE_TEST_MS = 15000; // about 6.8 s of cycles

test('brake test: never tested, in red; the Run button disabled outside AUTO_IDLE/MANUAL_IDLE, saying why', async () => {
  await startCell(brakeCell, 'brake', BRAKE_FILE);
  await brakeCell.page.click('#tab-safety');
  const { b } = await bpUntil('never tested', (x) => x.due === 'Never tested');
  assert.equal(b.dueTone, 'never');
  assert.ok(b.dueRed, 'never tested with a test required: red');
  assert.equal(b.dueRole, 'alert');
  assert.match(b.dueDetail, /AUTO is refused/);
  assert.equal(b.last, 'Never tested');
  assert.equal(b.run, false);
  assert.match(b.why, /Disabled: .*servos on.*now ESTOP_RESET_NEEDED/);
  assert.ok(b.axes.every((a) => a.phase === 'untested' && a.word === 'not tested'), JSON.stringify(b.axes));
});

test('brake test: as the pendant in T1 the button runs it: each axis in turn, then passed with every axis\' drift', async () => {
  const page = brakeCell.page;
  await page.click('#cmd-reset');
  await page.click('#tab-operate');
  await page.click('#sim-mode-t1');
  await until('T1 IDLE', async () => { const s = await bpStatus(); return s.state === 'IDLE' && s.mode === 'T1'; });
  await page.click('#sim-enable-centre');
  await sleep(150);
  await page.click('#cmd-servo-on');
  await until('MANUAL_IDLE', async () => (await bpStatus()).sub === 'MANUAL_IDLE', 10000);
  await page.click('#tab-safety');
  await bpUntil('the button enabled', (x) => x.run);
  await page.click('#bt-run');
  // Axis 2 under test: axis 1 done, 3..6 pending, the overall progress shown.
  const mid = await bpUntil('axis 2 under test', (x, s) => s.sub === 'BRAKE_TEST' && x.axes[1].phase === 'testing', BRAKE_TEST_MS);
  assert.deepEqual(mid.b.axes.map((a) => a.phase), ['done', 'testing', 'pending', 'pending', 'pending', 'pending']);
  assert.equal(mid.b.axes[1].current, 'step');
  assert.match(mid.b.label, /^Testing axis 2 · \d+ %$/);
  assert.equal(mid.b.run, false, 'not while it runs');
  assert.match(mid.b.reply, /^Reply OK/);
  await bpShot('30-brake-test-running');
  const { b, s } = await bpUntil('passed', (x, st) => x.last === 'Passed' && st.sub === 'MANUAL_IDLE' && x.axes.every((a) => a.phase === 'held'), BRAKE_TEST_MS);
  assert.equal(b.due, 'Due in 8.0 h');
  assert.equal(b.dueTone, 'ok');
  assert.equal(b.dueRed, false);
  assert.match(b.when, /^Passed on \d{4}-\d\d-\d\d at \d\d:\d\d:\d\d\.$/);
  // Each axis' drift as the status carries it (the latest brake_test event), within 0.5°.
  assert.deepEqual(b.axes.map((a) => a.word), s.safety.brake_test.drift_deg.map((d) => `${d.toFixed(3)}°`));
  assert.ok(s.safety.brake_test.drift_deg.every((d) => d <= 0.5), JSON.stringify(s.safety.brake_test));
  assert.match(b.label, /limit 0.5°/);
  assert.equal(b.run, true, 'again possible');
  await bpShot('31-brake-test-passed');
});

test('brake test: a weak brake on axis 3 from the panel: failed naming axis 3, in red; cleared and reset', async () => {
  const page = brakeCell.page;
  await page.click('#tab-operate');
  await page.selectOption('#sim-axis', '3');
  await page.click('#sim-brake-weak');
  await page.click('#tab-safety');
  await page.click('#bt-run');
  // The page, not only the API, in IDLE: its status can be a message behind the poll's.
  const { b, s } = await bpUntil('failed on axis 3, the page in IDLE', (x, st) => x.last === 'FAILED: axis 3' && st.state === 'IDLE' && /now IDLE/.test(x.why), BRAKE_TEST_MS);
  assert.ok(s.alarms.includes('BRAKE_TEST_FAILED'), s.alarms.join());
  assert.equal(b.due, 'Failed: axis 3');
  assert.ok(b.dueRed);
  assert.match(b.dueDetail, /AUTO is refused/);
  assert.match(b.when, /^Failed on .* The last pass was \d+ min ago\.$/, 'the pass of the test before, minutes ago');
  assert.deepEqual(b.axes.map((a) => a.phase), ['held', 'held', 'slipped', 'untested', 'untested', 'untested']);
  assert.match(b.axes[2].word, /^\d+\.\d{3}° SLIPPED$/);
  assert.ok(Number.parseFloat(b.axes[2].word) > 0.5, b.axes[2].word);
  assert.equal(b.run, false);
  assert.match(b.why, /now IDLE/);
  await bpShot('32-brake-test-failed');
  await page.click('#tab-operate');
  await page.click('#sim-clear-all');
  await sleep(150);
  await page.click('#cmd-reset');
  await until('BRAKE_TEST_FAILED reset', async () => { const st = await bpStatus(); return st.state === 'IDLE' && !st.alarms.includes('BRAKE_TEST_FAILED'); });
  // The latest result stays the failure until a test passes.
  assert.equal((await brakeSection()).last, 'FAILED: axis 3');
  assert.deepEqual(brakeCell.errors, [], 'no script errors on the page');
});

test('brake test: safestate run stops on SIGINT with exit 0', async () => {
  const r = await Promise.race([stopCell(brakeCell), sleep(15000).then(() => ({ code: 'timeout' }))]);
  assert.equal(r?.code, 0, `exit ${JSON.stringify(r)}: ${fs.readFileSync(brakeCell.logPath, 'utf8').slice(-2000)}`);
});

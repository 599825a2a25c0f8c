// Issue 38 item 6: the pendant draws the arm from the URDF the gateway serves at /api/robot,
// with the description's visual meshes when its package provides them (example-robot-data's
// UR5: COLLADA meshes), simple shapes otherwise (the built-in IRB 120 names none; a mesh
// outside the description's package folder is not served). And the Safety page names the
// robot and the description's part of the checksum. Debian's Chromium (playwright-core)
// against a live `safestate run --robot FILE` per case, stopped with SIGINT.
//
//   node --test hmi/tests/robot_browser.test.mjs
//
// Environment as browser.test.mjs (page.mjs), and SAFESTATE_UR5_URDF: example-robot-data's
// ur5_robot.urdf (default: found through SAFESTATE_VENV_PY, else ROOT/.venv/bin/python, which
// `make test` installs tests/integration/requirements-robots.txt into).
import assert from 'node:assert/strict';
import { execFileSync, spawn } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import os from 'node:os';
import path from 'node:path';
import { after, before, test } from 'node:test';
import { chromium } from 'playwright-core';
import { ARTIFACTS, BIN, CHROMIUM, DIST, ROOT, RUN_ARGS, freePort, sleep, until } from './page.mjs';

let tmp;
let browser;
const cells = [];

function ur5Urdf() {
  if (process.env.SAFESTATE_UR5_URDF) return process.env.SAFESTATE_UR5_URDF;
  const py = process.env.SAFESTATE_VENV_PY || path.join(ROOT, '.venv', 'bin', 'python');
  const purelib = execFileSync(py, ['-c', "import sysconfig; print(sysconfig.get_paths()['purelib'])"], { encoding: 'utf8' }).trim();
  return path.join(purelib, 'cmeel.prefix/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf');
}

function get(port, p) {
  return new Promise((resolve, reject) => {
    const req = http.get({ host: '127.0.0.1', port, path: p, timeout: 5000 }, (res) => {
      const chunks = [];
      res.on('data', (c) => chunks.push(c));
      res.on('end', () => resolve({ status: res.statusCode, type: res.headers['content-type'], body: Buffer.concat(chunks) }));
    });
    req.on('timeout', () => req.destroy(new Error('timeout')));
    req.on('error', reject);
  });
}
const getJson = async (port, p) => JSON.parse((await get(port, p)).body.toString('utf8'));

async function startCell(name, robotFile) {
  const port = await freePort();
  const logPath = path.join(tmp, `${name}.log`);
  const log = fs.openSync(logPath, 'w');
  const args = ['run', '--robot', robotFile, '--port', String(port), '--db', path.join(tmp, `${name}.db`), '--static', DIST, '--no-opcua', ...RUN_ARGS];
  const proc = spawn(BIN, args, { cwd: ROOT, stdio: ['ignore', log, log] });
  const cell = { proc, port, logPath, exit: new Promise((r) => proc.on('exit', (code, signal) => r({ code, signal }))) };
  cells.push(cell);
  await until(`${name}: GET /api/status after BOOT`, async () => {
    if (proc.exitCode !== null) throw new Error(`safestate run exited: ${fs.readFileSync(logPath, 'utf8')}`);
    const s = await getJson(port, '/api/status');
    return s.state !== 'BOOT';
  }, 30000);
  return cell;
}

async function stopCell(cell) {
  if (cell.proc.exitCode !== null) return;
  cell.proc.kill('SIGINT');
  const done = await Promise.race([cell.exit, sleep(10000).then(() => null)]);
  if (!done) cell.proc.kill('SIGKILL');
}

/** Opens the pendant of `cell` and waits until the arm view has settled (not 'loading'). */
async function openPendant(cell, viewport = { width: 1280, height: 800 }) {
  const page = await browser.newPage({ viewport });
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto(`http://127.0.0.1:${cell.port}/`);
  const drawing = await until('the arm drawn (meshes or shapes)', () =>
    page.evaluate(() => {
      const a = document.getElementById('arm');
      const d = window.safestateHmi?.armDrawing;
      return a?.dataset.renderer && d && d.kind !== 'loading' && d.why !== 'not loaded yet' ? { ...d, renderer: a.dataset.renderer } : false;
    }), 90000, 200);
  return { page, errors, drawing };
}

async function robotLine(page) {
  await page.click('#tab-safety');
  return until('the robot on the Safety page', () =>
    page.evaluate(() => (document.getElementById('safety-page').hidden ? false : document.getElementById('sp-robot').textContent || false)));
}

before(async () => {
  assert.ok(fs.existsSync(path.join(DIST, 'index.html')), `${DIST}/index.html missing: run "npm run build" in hmi/ (make test does)`);
  assert.ok(fs.existsSync(BIN), `${BIN} not found (set SAFESTATE_BIN)`);
  assert.ok(fs.existsSync(CHROMIUM), `${CHROMIUM} not found: apt-get install chromium (make test does)`);
  fs.mkdirSync(ARTIFACTS, { recursive: true });
  tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'safestate-hmi-robot-'));
  browser = await chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync'],
  });
});

after(async () => {
  await browser?.close().catch(() => {});
  for (const c of cells) await stopCell(c);
  if (tmp && !process.env.SAFESTATE_KEEP_TMP) fs.rmSync(tmp, { recursive: true, force: true });
});

test('UR5 from example-robot-data: the gateway serves its seven visual meshes and the HMI draws them', async () => {
  const urdf = ur5Urdf();
  assert.ok(fs.existsSync(urdf), `${urdf} not found (tests/integration/requirements-robots.txt into the venv, or SAFESTATE_UR5_URDF)`);
  const cell = await startCell('ur5', urdf);
  const robot = await getJson(cell.port, '/api/robot');
  assert.equal(robot.name, 'ur5');
  assert.deepEqual(robot.meshes_refused, []);
  assert.equal(robot.meshes.length, 7, JSON.stringify(robot.meshes));
  // Each served mesh is the file the URDF names, byte for byte, below the package folder.
  const pkg = path.resolve(path.dirname(urdf), '..', '..', '..'); // .../share/example-robot-data
  for (const m of robot.meshes) {
    assert.match(m.uri, /^package:\/\/example-robot-data\/robots\/ur_description\/meshes\/ur5\/visual\/\w+\.dae$/);
    assert.match(m.url, /^\/api\/robot\/meshes\/\d+\.dae$/);
    const r = await get(cell.port, m.url);
    assert.equal(r.status, 200, m.url);
    assert.equal(r.type, 'model/vnd.collada+xml');
    assert.ok(r.body.equals(fs.readFileSync(path.join(pkg, m.uri.slice('package://example-robot-data/'.length)))), m.uri);
  }
  // Nothing else under the prefix: not the next index, not a path.
  for (const p of ['/api/robot/meshes/7.dae', '/api/robot/meshes/0.stl', '/api/robot/meshes/../../../etc/passwd', '/api/robot/meshes/%2e%2e%2fur5_robot.urdf']) {
    assert.equal((await get(cell.port, p)).status, 404, p);
  }

  const { page, errors, drawing } = await openPendant(cell, { width: 1600, height: 1100 });
  assert.equal(drawing.renderer, 'webgl');
  assert.equal(drawing.kind, 'meshes', `drawn as ${drawing.kind}: ${drawing.why}`);
  // Seven link meshes at least (a COLLADA file may hold several), and the shapes hidden.
  assert.ok(drawing.meshObjects >= 7, `${drawing.meshObjects} mesh objects`);
  assert.equal(await page.evaluate(() => document.getElementById('arm').dataset.armDrawing), 'meshes');
  // Closer to the arm (the view stands back for the simulated person's fields), then the view alone.
  const box = await page.locator('#arm').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  for (let k = 0; k < 5; k++) {
    await page.mouse.wheel(0, -200);
    await sleep(120);
  }
  await sleep(500);
  await page.screenshot({ path: path.join(ARTIFACTS, 'robot-ur5-page.png') });
  await page.locator('#arm').screenshot({ path: path.join(ARTIFACTS, 'robot-ur5-meshes.png') });
  const line = await robotLine(page);
  assert.ok(line.includes('Robot: ur5'), line);
  assert.ok(line.includes(`description ${robot.parameters_checksum}`), line);
  assert.match(robot.parameters_checksum, /^[0-9A-F]{8}$/);
  assert.deepEqual(errors, []);
  await page.close();
  await stopCell(cell);
});

test('the built-in IRB 120 names no meshes: simple shapes', async () => {
  const cell = await startCell('irb120', path.join(ROOT, 'examples', 'robots', 'abb_irb120.urdf'));
  const robot = await getJson(cell.port, '/api/robot');
  assert.deepEqual(robot.meshes, []);
  const { page, errors, drawing } = await openPendant(cell);
  assert.equal(drawing.kind, 'shapes');
  assert.equal(drawing.why, 'the description names no meshes');
  assert.equal(drawing.meshObjects, 0);
  const line = await robotLine(page);
  assert.ok(line.includes(`Robot: ${robot.name}`) && line.includes(`description ${robot.parameters_checksum}`), line);
  assert.deepEqual(errors, []);
  await page.close();
  await stopCell(cell);
});

test('a mesh outside the description\'s package folder is not served: simple shapes', async () => {
  // The UR5's URDF in a package folder of its own whose meshes point out of it (..), beside a
  // real file there: nothing outside is read, the pendant draws shapes and says why.
  const urdf = fs.readFileSync(ur5Urdf(), 'utf8');
  const pkg = path.join(tmp, 'mypkg');
  fs.mkdirSync(path.join(pkg, 'urdf'), { recursive: true });
  fs.writeFileSync(path.join(tmp, 'outside.stl'), 'solid outside\nendsolid outside\n');
  const file = path.join(pkg, 'urdf', 'arm.urdf');
  fs.writeFileSync(file, urdf.replaceAll(/package:\/\/example-robot-data\/[^"]+\.(dae|stl)/g, 'package://mypkg/../outside.stl'));
  const cell = await startCell('outside', file);
  const robot = await getJson(cell.port, '/api/robot');
  assert.deepEqual(robot.meshes, []);
  assert.equal(robot.meshes_refused.length, 1);
  assert.match(robot.meshes_refused[0].why, /outside the description's package folder/);
  assert.match(fs.readFileSync(cell.logPath, 'utf8'), /robot mesh not served/);
  const { page, errors, drawing } = await openPendant(cell);
  assert.equal(drawing.kind, 'shapes');
  assert.match(drawing.why, /^mesh not served: package:\/\/mypkg\/\.\.\/outside\.stl \(outside/);
  assert.deepEqual(errors, []);
  await page.close();
  await stopCell(cell);
});

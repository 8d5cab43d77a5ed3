// The web viewer in headless Chromium (Debian's /usr/bin/chromium, driven by playwright-core)
// against a real gateway and tesserad, as a user uses it: frames arrive, a drag orbits, the AA
// mode switches, a .glb is uploaded and rendered, the timing chart has data, the image can be
// saved, a broken .gltf gets the server's words, and the page comes back by itself when its
// gateway dies. Screenshots go to $TESSERA_WEB_ARTIFACTS (default: a temp directory).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import { createRequire } from 'node:module';
import { ASSETS, WEB_DIR, startGateway, startTesserad } from '../../clients/web/test/harness.js';

const require = createRequire(path.join(WEB_DIR, 'package.json'));
const { chromium } = require('playwright-core');

const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
const ARTIFACTS = process.env.TESSERA_WEB_ARTIFACTS || fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-web-artifacts-'));
fs.mkdirSync(ARTIFACTS, { recursive: true });

let tesserad, gateway, gatewayPort, browser, page;
const pageErrors = [];

async function freePort() {
  return new Promise((resolve) => {
    const s = net.createServer().listen(0, '127.0.0.1', () => {
      const { port } = s.address();
      s.close(() => resolve(port));
    });
  });
}

before(async () => {
  tesserad = await startTesserad();
  gatewayPort = await freePort();
  gateway = await startGateway(tesserad.address, ['--listen', `127.0.0.1:${gatewayPort}`]);
  browser = await chromium.launch({
    executablePath: CHROMIUM,
    args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
      '--disable-sync', '--no-first-run', '--disable-quic'],
  });
  const context = await browser.newContext({ viewport: { width: 800, height: 500 }, acceptDownloads: true });
  page = await context.newPage();
  page.on('pageerror', (err) => pageErrors.push(`pageerror: ${err.message}`));
  page.on('console', (msg) => { if (msg.type() === 'error') pageErrors.push(`console: ${msg.text()}`); });
  await page.goto(gateway.url);
});

after(async () => {
  await browser?.close();
  await gateway?.stop();
  await tesserad?.stop();
  console.log(`# screenshots in ${ARTIFACTS}`);
});

const lastFrame = () => page.evaluate(() => window.tessera.lastFrame);
const shot = (name) => page.screenshot({ path: path.join(ARTIFACTS, `${name}.png`) });

/** Polls the page until it has drawn a frame for which `predicate(frame)` holds; returns it. */
async function waitForFrame(predicate, what, timeout = 60_000) {
  const start = Date.now();
  let frame = null;
  while (Date.now() - start < timeout) {
    frame = await lastFrame();
    if (frame !== null && predicate(frame)) return frame;
    await new Promise((r) => setTimeout(r, 50));
  }
  const errors = await page.evaluate(() => window.tessera.errors);
  throw new Error(`no frame with ${what}: last frame ${JSON.stringify(frame)?.slice(0, 300)}; errors ${JSON.stringify(errors)}`);
}

const near = (a, b, eps = 1e-3) => Math.abs(a.x - b.x) < eps && Math.abs(a.y - b.y) < eps && Math.abs(a.z - b.z) < eps;

test('the page loads and shows the demo scene, with a settings panel built from the server', async () => {
  const frame = await waitForFrame((f) => f.scene_id === 'demo', 'the demo scene');
  assert.equal(await page.evaluate(() => window.tessera.connected), true);
  // The render size follows the canvas: device pixels x the resolution choice (50% on a CPU device).
  const canvas = await page.evaluate(() => {
    const c = document.getElementById('view');
    return { w: c.clientWidth * devicePixelRatio, h: c.clientHeight * devicePixelRatio, res: document.getElementById('resolution').value };
  });
  const scale = Number(canvas.res) / 100;
  assert.ok(Math.abs(frame.width - canvas.w * scale) <= 2, `frame ${frame.width} for canvas ${canvas.w} at ${canvas.res}%`);
  assert.ok(Math.abs(frame.height - canvas.h * scale) <= 2);
  // Every AA mode the server offers is in the panel, from GetServerInfo.
  const offered = await page.evaluate(() => window.tessera.info.choices.aa);
  const options = await page.$$eval('#setting-aa option', (os) => os.map((o) => o.value));
  assert.deepEqual(options.map((o) => o.replace(/^AA_/, '').toLowerCase()).sort(), [...offered].sort());
  for (const id of ['setting-culling', 'setting-debug_view', 'setting-synthetic_lights', 'setting-jpeg_quality', 'setting-shadows']) {
    assert.ok(await page.$(`#${id}`), `no #${id}`);
  }
  assert.equal(await page.$('#setting-width'), null, 'width is the viewport\'s, not a setting');
  // Labels, docs and ranges come from the server's settings table (ServerInfo.choices.settings).
  const bloom = await page.evaluate(() => {
    const input = document.getElementById('setting-bloom_strength');
    const label = document.querySelector('label[for="setting-bloom_strength"]');
    return { min: input.min, max: input.max, title: input.title, label: label.textContent };
  });
  assert.equal(bloom.label, 'Bloom strength');
  assert.equal(bloom.min, '0');
  assert.equal(bloom.max, '1');
  assert.match(bloom.title, /\(0\.\.1\)$/);
  const lightsMax = await page.$eval('#setting-synthetic_lights', (i) => i.max);
  const limit = await page.evaluate(() => window.tessera.info.limits.max_synthetic_lights);
  assert.equal(Number(lightsMax), Math.min(65536, Number(limit)));
  await shot('01-loaded');
});

test('dragging on the picture orbits the camera: the next frame has a new eye, and its event id', async () => {
  const before = await lastFrame();
  const box = await page.locator('#view').boundingBox();
  const x = box.x + box.width / 2, y = box.y + box.height / 2;
  await page.mouse.move(x, y);
  await page.mouse.down();
  for (let i = 1; i <= 8; i++) await page.mouse.move(x + 15 * i, y + 4 * i);
  await page.mouse.up();
  // The frames catch up with the camera the page sent last.
  const client = await page.evaluate(() => window.tessera.camera());
  const after = await waitForFrame((f) => near(f.camera.eye, client.eye), 'the camera after the drag');
  assert.ok(after.event_id > before.event_id);
  assert.ok(!near(after.camera.eye, before.camera.eye, 0.1), 'the drag did not move the camera');
  const target = (c) => [c.target.x, c.target.y, c.target.z];
  const dist = (c) => Math.hypot(c.eye.x - c.target.x, c.eye.y - c.target.y, c.eye.z - c.target.z);
  // An orbit: same target, same distance, another eye.
  target(after.camera).forEach((v, i) => assert.ok(Math.abs(v - target(before.camera)[i]) < 1e-3));
  assert.ok(Math.abs(dist(after.camera) - dist(before.camera)) < 1e-2 * dist(before.camera));
  await shot('02-orbited');
});

test('the wheel zooms toward the target', async () => {
  const before = await lastFrame();
  const box = await page.locator('#view').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.wheel(0, -300);
  const dist = (c) => Math.hypot(c.eye.x - c.target.x, c.eye.y - c.target.y, c.eye.z - c.target.z);
  const after = await waitForFrame((f) => dist(f.camera) < 0.95 * dist(before.camera), 'a closer camera');
  assert.ok(dist(after.camera) < dist(before.camera));
});

test('switching the AA mode shows in the frame\'s effective settings', async () => {
  await page.selectOption('#setting-aa', 'AA_FXAA');
  const fxaa = await waitForFrame((f) => f.settings.aa === 'AA_FXAA', 'aa = fxaa');
  assert.ok(fxaa.passes.some((p) => p.pass === 'fxaa'), `no fxaa pass in ${fxaa.passes.map((p) => p.pass)}`);
  await shot('03-fxaa');
  await page.selectOption('#setting-aa', 'AA_MSAA');
  const msaa = await waitForFrame((f) => f.settings.aa === 'AA_MSAA', 'aa = msaa');
  assert.equal(msaa.settings.samples > 1, true);
  assert.equal(await page.$eval('#setting-aa', (s) => s.value), 'AA_MSAA');
});

test('the render resolution follows the window', async () => {
  const before = await lastFrame();
  await page.setViewportSize({ width: 640, height: 480 });
  const after = await waitForFrame((f) => f.width !== before.width, 'a new width');
  const canvas = await page.evaluate(() => {
    const c = document.getElementById('view');
    return { w: c.clientWidth * devicePixelRatio, h: c.clientHeight * devicePixelRatio, res: Number(document.getElementById('resolution').value) };
  });
  assert.ok(Math.abs(after.width - canvas.w * canvas.res / 100) <= 2, `${after.width} vs ${canvas.w}`);
  assert.ok(Math.abs(after.height - canvas.h * canvas.res / 100) <= 2, `${after.height} vs ${canvas.h}`);
  assert.equal(after.settings.aa, 'AA_MSAA', 'a resize keeps the other settings');
});

test('the timing chart holds per-pass GPU times, fps, latency and frame size', async () => {
  const data = await page.evaluate(() => window.tessera.chartData());
  assert.ok(data.frames.length >= 4, `${data.frames.length} frames in the chart`);
  assert.ok(data.passes.includes('forward') || data.passes.includes('vis_shade'), data.passes.join());
  const last = data.frames.at(-1);
  const frame = await lastFrame();
  assert.equal(last.sequence, frame.sequence);
  for (const p of frame.passes) assert.ok(Math.abs(last.passes[p.pass] - p.gpu_ms) < 1e-9, p.pass);
  assert.ok(last.gpu_total_ms > 0);
  assert.equal(data.bytes, frame.bytes);
  assert.ok(data.fps > 0);
  assert.ok(data.latency_ms > 0 && data.latency_ms < 30_000, `latency ${data.latency_ms}`);
  const statsText = await page.textContent('#stats');
  assert.match(statsText, /fps/i);
  assert.match(statsText, /latency/i);
  await page.locator('#chart').screenshot({ path: path.join(ARTIFACTS, '04-chart.png') });
});

test('"save image" downloads the frame on screen as a JPEG', async () => {
  const frame = await lastFrame();
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#save')]);
  const file = path.join(ARTIFACTS, download.suggestedFilename());
  await download.saveAs(file);
  const bytes = fs.readFileSync(file);
  assert.equal(bytes[0], 0xff);
  assert.equal(bytes[1], 0xd8);
  assert.equal(bytes.length, frame.bytes);
  assert.match(download.suggestedFilename(), new RegExp(`^tessera-demo-${frame.sequence}\\.jpg$`));
});

test('a .glb picked in the file input is uploaded, listed and rendered', async () => {
  const glb = path.join(ASSETS, 'BoxTextured/glTF-Binary/BoxTextured.glb');
  await page.setInputFiles('#upload-input', glb);
  await page.waitForFunction(() => window.tessera.scene !== 'demo', null, { timeout: 60_000 });
  const scene = await page.evaluate(() => window.tessera.scene);
  assert.match(scene, /^[0-9a-f]{64}$/);
  const frame = await waitForFrame((f) => f.scene_id === scene, 'the uploaded scene');
  assert.equal(frame.settings.aa, 'AA_MSAA', 'settings carry over to the new scene');
  const options = await page.$$eval('#scene-select option', (os) => os.map((o) => [o.value, o.textContent]));
  assert.ok(options.some(([v, t]) => v === scene && /BoxTextured/.test(t)), JSON.stringify(options));
  assert.match(page.url(), new RegExp(`scene=${scene}`));
  await shot('05-uploaded');
});

test('a broken glTF is refused with the server\'s words, and the page carries on', async () => {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-broken-'));
  const file = path.join(dir, 'broken.gltf');
  fs.writeFileSync(file, JSON.stringify({
    asset: { version: '2.0' },
    meshes: [{ primitives: [{ attributes: { POSITION: 7 } }] }],
    nodes: [{ mesh: 0 }],
    scenes: [{ nodes: [0] }],
  }));
  const before = await page.evaluate(() => window.tessera.errors.length);
  await page.setInputFiles('#upload-input', file);
  await page.waitForFunction((n) => window.tessera.errors.length > n, before, { timeout: 30_000 });
  await page.waitForSelector('#error:not([hidden])');
  const text = await page.textContent('#error');
  // The hint in plain words, then the server's own message naming the file and the field.
  assert.match(text, /refused/i, text);
  assert.match(text, /broken\.gltf: meshes\[0\]\.primitives\[0\]\.attributes\.POSITION: accessor index 7 out of range/, text);
  await shot('06-error');
  fs.rmSync(dir, { recursive: true, force: true });
  await page.click('#error-dismiss');
  // Still live: a refresh of the view still brings frames.
  const n = await page.evaluate(() => window.tessera.frames);
  await page.click('#reset-view');
  await page.waitForFunction((k) => window.tessera.frames > k, n, { timeout: 30_000 });
});

test('a .gltf chosen without its files: one sentence on what to do, the files folded away', async () => {
  const before = await page.evaluate(() => window.tessera.errors.length);
  await page.setInputFiles('#upload-input', path.join(ASSETS, 'Sponza/glTF/Sponza.gltf'));
  await page.waitForFunction((n) => window.tessera.errors.length > n, before, { timeout: 30_000 });
  await page.waitForSelector('#error:not([hidden])');
  const text = await page.textContent('#error-text');
  assert.match(text, /Sponza\.gltf needs \d+ files that were not among the files chosen\. Choose the \.gltf together with all its files, or drop its whole folder\./, text);
  // One sentence in view; the file list is folded (closed <details>) and says how many.
  assert.equal(await page.locator('#error-text details').count(), 1);
  assert.equal(await page.locator('#error-text details').evaluate((d) => d.open), false);
  assert.match(await page.textContent('#error-text details summary'), /^\d+ files$/);
  await shot('06b-missing-files');
  await page.click('#error-dismiss');
});

test('the page reconnects by itself when its gateway dies, and resumes its session', async () => {
  const before = await lastFrame();
  gateway.proc.kill('SIGKILL');
  await page.waitForFunction(() => !window.tessera.connected, null, { timeout: 30_000 });
  const status = await page.textContent('#status');
  assert.match(status, /reconnect|connecting|offline|lost/i, status);
  await gateway.stop();
  gateway = await startGateway(tesserad.address, ['--listen', `127.0.0.1:${gatewayPort}`]);
  await page.waitForFunction(() => window.tessera.connected, null, { timeout: 60_000 });
  const after = await waitForFrame((f) => f.sequence > before.sequence, 'a frame after reconnecting');
  // tesserad parked the session when the gateway's connection vanished: same session, same scene.
  assert.equal(after.session_token, before.session_token);
  assert.equal(after.scene_id, before.scene_id);
  assert.equal(after.settings.aa, before.settings.aa);
  await shot('07-reconnected');
});

test('no script errors on the page', () => {
  // The reconnect test makes Chromium log the failed WebSocket attempts; those are the browser's
  // own lines, not the page's.
  const errors = pageErrors.filter((e) => !/WebSocket connection to .* failed/.test(e));
  assert.deepEqual(errors, []);
});

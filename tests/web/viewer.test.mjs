// The web viewer in headless Chromium (Debian's /usr/bin/chromium, driven by playwright-core)
// against a real gateway and tesserad, as a user uses it: frames arrive, a drag orbits, the AA
// mode switches, a .glb is uploaded and rendered, the stats overlay (key I) shows the timing
// chart, fps, latency and bitrate at 1280x800, the settings sit in sections, fullscreen, a
// scene the server has is not uploaded again (the page hashes it and asks HasScene), a link
// carries the camera, the image can be saved, a broken .gltf gets the server's words, and the
// page comes back by itself when its gateway dies. Screenshots go to $TESSERA_WEB_ARTIFACTS
// (default: a temp directory).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import {
  freePort, launchChromium, pageLastFrame, waitForPageFrame, watchErrors,
} from './browser.mjs';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { ASSETS, startGateway, startTesserad } from '../../clients/web/test/harness.js';


const ARTIFACTS = process.env.TESSERA_WEB_ARTIFACTS || fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-web-artifacts-'));
fs.mkdirSync(ARTIFACTS, { recursive: true });

let tesserad, gateway, gatewayPort, browser, context, page;
const pageErrors = [];
const opsSent = [];  // the "op" of every request the main page sent to the gateway

/** Collects a page's script errors (all pages of the test share the list). */
before(async () => {
  tesserad = await startTesserad();
  gatewayPort = await freePort();
  gateway = await startGateway(tesserad.address, ['--listen', `127.0.0.1:${gatewayPort}`]);
  browser = await launchChromium();
  context = await browser.newContext({ viewport: { width: 800, height: 500 }, acceptDownloads: true });
  page = await context.newPage();
  watchErrors(page, pageErrors);
  page.on('websocket', (ws) => ws.on('framesent', ({ payload }) => {
    if (typeof payload !== 'string') return;
    try {
      opsSent.push(JSON.parse(payload).op);
    } catch {}
  }));
  await page.goto(gateway.url);
});

after(async () => {
  await browser?.close();
  await gateway?.stop();
  await tesserad?.stop();
  console.log(`# screenshots in ${ARTIFACTS}`);
});

const lastFrame = (p = page) => pageLastFrame(p);
const shot = (name, p = page) => p.screenshot({ path: path.join(ARTIFACTS, `${name}.png`) });

/** Polls the page until it has drawn a frame for which `predicate(frame)` holds; returns it. */
const waitForFrame = (predicate, what, timeout = 60_000, p = page) =>
  waitForPageFrame(p, predicate, what, timeout);

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

test('the timing chart holds per-pass GPU times, fps, latency, bitrate and frame size', async () => {
  await page.setViewportSize({ width: 1280, height: 800 });  // the size of the screen, from here on
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
  assert.ok(data.bitrate_bps > 0, `bitrate ${data.bitrate_bps}`);
  assert.ok(data.latency_ms > 0 && data.latency_ms < 30_000, `latency ${data.latency_ms}`);
  const statsText = await page.textContent('#stats');
  assert.match(statsText, /fps/i);
  assert.match(statsText, /latency/i);
  assert.match(statsText, /bitrate.*Mbit\/s/i);
  await page.locator('#chart').screenshot({ path: path.join(ARTIFACTS, '04-chart.png') });
});

const inView = (box, { width, height }) =>
  box && box.width > 0 && box.height > 0 && box.x >= 0 && box.y >= 0 &&
  box.x + box.width <= width && box.y + box.height <= height;

test('at 1280x800 the stats overlay shows fps, latency, bitrate and the chart in view; I toggles it', async () => {
  const size = page.viewportSize();
  assert.deepEqual(size, { width: 1280, height: 800 });
  await waitForFrame(() => true, 'a frame');
  // The numbers and the chart, on the picture, below the toolbar, without scrolling anything.
  const overlay = await page.locator('#overlay').boundingBox();
  const toolbar = await page.locator('#toolbar').boundingBox();
  const chartBox = await page.locator('#chart').boundingBox();
  const legend = await page.locator('#chart-legend').boundingBox();
  const view = await page.locator('#view').boundingBox();
  for (const [what, box] of [['overlay', overlay], ['chart', chartBox], ['legend', legend]]) {
    assert.ok(inView(box, size), `${what} ${JSON.stringify(box)} not in the 1280x800 window`);
    assert.ok(box.x >= view.x && box.x + box.width <= view.x + view.width, `${what} is not over the picture`);
  }
  assert.ok(overlay.y >= toolbar.y + toolbar.height, `the overlay ${JSON.stringify(overlay)} covers the toolbar ${JSON.stringify(toolbar)}`);
  assert.ok(chartBox.height >= 80, `chart ${chartBox.height} px tall`);
  assert.ok(await page.locator('#chart-legend li').count() > 0, 'no legend');
  const text = await page.locator('#overlay').innerText();
  for (const re of [/fps/, /latency/, /bitrate\s+[\d.]+ Mbit\/s|bitrate\s+idle \(last [\d.]+ Mbit\/s\)/, /frame size/, /resolution\s+\d+ × \d+/]) {
    assert.match(text, re);
  }
  assert.equal(await page.getAttribute('#overlay-toggle', 'aria-pressed'), 'true');
  assert.equal(await page.evaluate(() => document.scrollingElement.scrollTop), 0);
  await shot('08-overlay-1280x800');

  // A drag that starts on the overlay still orbits: it takes no pointer events.
  const before = await page.evaluate(() => window.tessera.camera());
  const x = chartBox.x + chartBox.width / 2, y = chartBox.y + chartBox.height / 2;
  await page.mouse.move(x, y);
  await page.mouse.down();
  for (let i = 1; i <= 6; i++) await page.mouse.move(x - 12 * i, y + 3 * i);
  await page.mouse.up();
  const moved = await page.evaluate(() => window.tessera.camera());
  assert.ok(!near(moved.eye, before.eye, 1e-3), 'a drag on the overlay did not orbit');

  // I hides it (and is remembered); not while typing in a field; the button brings it back.
  await page.keyboard.press('i');
  await page.waitForSelector('#overlay', { state: 'hidden' });
  assert.equal(await page.getAttribute('#overlay-toggle', 'aria-pressed'), 'false');
  assert.equal(await page.evaluate(() => localStorage.getItem('tessera.overlay')), '0');
  await page.focus('#setting-exposure_ev');
  await page.keyboard.press('i');
  assert.equal(await page.isHidden('#overlay'), true, 'I typed in a field toggled the overlay');
  await page.evaluate(() => document.activeElement.blur());
  const second = await context.newPage();
  watchErrors(second, pageErrors);
  await second.goto(gateway.url);
  await second.waitForFunction(() => window.tessera.frames > 0, null, { timeout: 60_000 });
  assert.equal(await second.isHidden('#overlay'), true, 'the overlay state was not remembered');
  await second.close();
  await page.click('#overlay-toggle');
  await page.waitForSelector('#overlay', { state: 'visible' });
  assert.equal(await page.getAttribute('#overlay-toggle', 'aria-pressed'), 'true');
  await page.keyboard.press('I');
  await page.waitForSelector('#overlay', { state: 'hidden' });
  await page.keyboard.press('I');
  await page.waitForSelector('#overlay', { state: 'visible' });
});

test('the settings are in collapsible sections after the scene, in one label style', async () => {
  const sections = await page.$$eval('#panel details.group', (ds) => ds.map((d) => ({
    id: d.id, title: d.querySelector('summary').textContent, open: d.open, fields: d.querySelectorAll('.field').length,
  })));
  assert.deepEqual(sections.map((s) => s.title),
    ['Image', 'Lighting', 'Shadows', 'Post-processing', 'Encoding', 'Pipeline and debug', 'Interactive profile']);
  assert.ok(sections.every((s) => s.fields > 0), JSON.stringify(sections));
  // The visible headings: the Animation section is hidden for a scene without animations.
  assert.deepEqual(await page.$$eval('#panel h2', (hs) => hs.filter((h) => !h.closest('[hidden]')).map((h) => h.textContent)),
    ['Scene', 'Settings']);
  // Every control the server described is in a section (none left in "Other" today); the
  // page's own resolution choice heads "Image".
  const loose = await page.$$eval('[id^="setting-"]', (els) => els.filter((e) => !e.closest('details.group')).map((e) => e.id));
  assert.deepEqual(loose, []);
  assert.equal(await page.$eval('#resolution', (e) => e.closest('details').id), 'group-image');
  assert.equal(await page.$eval('#group-image .field', (e) => e.id), 'resolution-field');
  const labels = await page.$$eval('#panel .field label', (ls) => ls.map((l) => l.textContent));
  for (const label of labels) assert.match(label, /^[A-Z][^_]*$/, `label '${label}' is not in sentence case`);
  assert.ok(labels.includes('Light radius min (world units)'), labels.join(' | '));
  assert.equal(await page.$eval('#panel', (p) => getComputedStyle(p).overflowY), 'auto');
  // Folded sections open on a click, and stay as left.
  assert.equal(await page.isVisible('#setting-shadow_cache'), false);
  await page.click('#group-lighting summary');
  await page.click('#group-shadows summary');
  assert.equal(await page.isVisible('#setting-shadow_cache'), true);
  assert.equal(await page.isVisible('#setting-ibl'), false);
  await shot('09-settings-sections');
  await page.click('#group-image summary');
  await page.click('#group-shadows summary');
  await shot('09b-settings-folded');
  assert.deepEqual(JSON.parse(await page.evaluate(() => localStorage.getItem('tessera.sections'))),
    { 'group-image': false, 'group-lighting': false, 'group-shadows': false });
  await page.click('#group-image summary');
  await page.click('#group-lighting summary');
});

test('fullscreen: the button (and Enter) put the viewport, not the panel, on the whole screen', async () => {
  const enabled = await page.evaluate(() => document.fullscreenEnabled);
  assert.equal(await page.isVisible('#fullscreen'), enabled, 'the button shows exactly when fullscreen is possible');
  if (!enabled) return;
  await page.click('#fullscreen');
  const granted = await page.waitForFunction(() => document.fullscreenElement !== null, null, { timeout: 5000 })
    .then(() => true, () => false);
  if (!granted) {
    console.log('# headless Chromium did not grant fullscreen: only the button was checked');
    return;
  }
  assert.equal(await page.evaluate(() => document.fullscreenElement.id), 'viewport');
  // The button follows the fullscreenchange event (a frame after fullscreenElement is set).
  await page.waitForSelector('#fullscreen[aria-pressed="true"]', { timeout: 5000 });
  assert.equal(await page.textContent('#fullscreen'), 'Exit fullscreen');
  assert.equal(await page.isVisible('#panel-toggle'), false, 'the panel cannot show in fullscreen');
  // The canvas fills the screen and the render size follows it.
  const canvas = await page.evaluate(() => {
    const c = document.getElementById('view');
    return { w: c.clientWidth * devicePixelRatio, h: c.clientHeight * devicePixelRatio, screenW: innerWidth, res: Number(document.getElementById('resolution').value) };
  });
  assert.equal(canvas.w, canvas.screenW * (await page.evaluate(() => devicePixelRatio)));
  await waitForFrame((f) => Math.abs(f.width - canvas.w * canvas.res / 100) <= 2, 'a frame the size of the screen');
  await shot('08b-fullscreen');
  await page.click('#fullscreen');
  await page.waitForFunction(() => document.fullscreenElement === null);
  await page.waitForSelector('#fullscreen[aria-pressed="false"]', { timeout: 5000 });
  assert.equal(await page.textContent('#fullscreen'), 'Fullscreen');
  // Enter, with no button focused, does the same.
  await page.evaluate(() => document.activeElement?.blur());
  await page.keyboard.press('Enter');
  await page.waitForFunction(() => document.fullscreenElement !== null, null, { timeout: 5000 });
  await page.evaluate(() => document.exitFullscreen());
  await page.waitForFunction(() => document.fullscreenElement === null);
  await page.waitForFunction(() => document.getElementById('view').clientWidth < innerWidth);  // the panel is back
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

test('a scene the server has is not uploaded again: the page hashes it and asks HasScene', async () => {
  const dir = path.join(ASSETS, 'MultiUVTest/glTF');
  const files = fs.readdirSync(dir).map((n) => path.join(dir, n));
  assert.ok(files.length >= 4, files.join());
  // `tessera upload --json MultiUVTest.gltf` prints this id: the CLI, the server and the page
  // all hash the same way.
  const expected = '6ee6ae2ad53a1f796384aa426563c203807a4c1e0c1ff089089cfa25d8a4e89a';
  const count = (op) => opsSent.filter((o) => o === op).length;
  const uploads = count('upload');
  const checks = count('has_scene');
  await page.setInputFiles('#upload-input', files);
  await page.waitForFunction((id) => window.tessera.scene === id, expected, { timeout: 60_000 });
  await waitForFrame((f) => f.scene_id === expected, 'the multi-file scene');
  assert.equal(count('upload'), uploads + 1, 'the first time, it is uploaded');
  assert.equal(count('has_scene'), checks + 1, 'after asking');
  assert.match(await page.textContent('#upload-note'), /^Uploaded MultiUVTest\.gltf \(6ee6ae2a\)/);

  await page.selectOption('#scene-select', 'demo');
  await waitForFrame((f) => f.scene_id === 'demo', 'the demo scene again');
  await page.setInputFiles('#upload-input', files);
  await page.waitForFunction((id) => window.tessera.scene === id, expected, { timeout: 60_000 });
  await waitForFrame((f) => f.scene_id === expected, 'the same scene, selected');
  assert.equal(count('upload'), uploads + 1, 'the second time, nothing was uploaded');
  assert.equal(count('has_scene'), checks + 2);
  assert.match(await page.textContent('#upload-note'), /^MultiUVTest\.gltf is already on the server: not uploaded \(6ee6ae2a\)\./);
  assert.equal(await page.$eval('#scene-select', (s) => s.value), expected);
  assert.equal(await page.isHidden('#upload-box'), true);
  await shot('05b-not-uploaded-again');
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

/** A fresh page at 1280x800 opened on the gateway with `hash`. */
async function openPage(hash) {
  const p = await context.newPage();
  watchErrors(p, pageErrors);
  await p.setViewportSize({ width: 1280, height: 800 });
  await p.goto(`${gateway.url}${hash}`);
  return p;
}

test('a link carries scene and camera: it opens that view; a bad link gives a note and the default view', async () => {
  const plain = await openPage('#scene=demo');
  const framed = await waitForFrame((f) => f.scene_id === 'demo', 'demo, framed by the server', 60_000, plain);
  await plain.close();

  const linked = await openPage('#scene=demo&eye=4,3,6&target=0,0.5,0&fov=50');
  const shown = await waitForFrame((f) => f.scene_id === 'demo', 'the linked view', 60_000, linked);
  assert.ok(near(shown.camera.eye, { x: 4, y: 3, z: 6 }), JSON.stringify(shown.camera));
  assert.ok(near(shown.camera.target, { x: 0, y: 0.5, z: 0 }), JSON.stringify(shown.camera));
  assert.ok(Math.abs(shown.yfov - (50 * Math.PI) / 180) < 1e-4, `yfov ${shown.yfov}`);
  assert.ok(!near(shown.camera.eye, framed.camera.eye, 0.1), 'the link\'s camera was not used');
  assert.equal(await linked.isHidden('#link-note'), true);
  await shot('10-link-view', linked);

  // The URL follows the camera once it rests, and keeps the field of view.
  const box = await linked.locator('#view').boundingBox();
  await linked.mouse.move(box.x + 300, box.y + 400);
  await linked.mouse.down();
  for (let i = 1; i <= 6; i++) await linked.mouse.move(box.x + 300 + 15 * i, box.y + 400);
  await linked.mouse.up();
  await linked.waitForFunction(() => !location.hash.includes('eye=4,3,6'), null, { timeout: 10_000 });
  const hash = new URL(linked.url()).hash;
  const camera = await linked.evaluate(() => window.tessera.camera());
  const eye = /eye=([^&]+)/.exec(hash)[1].split(',').map(Number);
  assert.ok(near({ x: eye[0], y: eye[1], z: eye[2] }, camera.eye, 1e-3 * Math.hypot(...eye)), `${hash} vs ${JSON.stringify(camera.eye)}`);
  assert.match(hash, /^#scene=demo&eye=[^&]+&target=0,0\.5,0&fov=50$/);
  await waitForFrame((f) => Math.abs(f.yfov - (50 * Math.PI) / 180) < 1e-4 && near(f.camera.eye, camera.eye), 'the field of view kept while orbiting', 30_000, linked);

  // A hash edited in place moves the camera; "Copy link" copies the view's URL.
  await linked.evaluate(() => { location.hash = 'scene=demo&eye=-4,2,5&target=0,0.5,0&fov=50'; });
  await waitForFrame((f) => near(f.camera.eye, { x: -4, y: 2, z: 5 }), 'the camera of the edited hash', 30_000, linked);
  await context.grantPermissions(['clipboard-read', 'clipboard-write'], { origin: new URL(gateway.url).origin });
  await linked.click('#copy-link');
  await linked.waitForFunction(() => document.getElementById('copy-link').dataset.copied !== undefined);
  assert.equal(await linked.evaluate(() => navigator.clipboard.readText()), linked.url());
  assert.match(linked.url(), /#scene=demo&eye=-4,2,5&target=0,0\.5,0&fov=50$/);
  await linked.close();

  // Malformed values: a note says what was ignored; the server's framing is shown.
  const bad = await openPage('#scene=demo&eye=1,2&target=x,NaN,0&fov=1000');
  const badFrame = await waitForFrame((f) => f.scene_id === 'demo', 'demo after a bad link', 60_000, bad);
  assert.ok(near(badFrame.camera.eye, framed.camera.eye), `${JSON.stringify(badFrame.camera.eye)} is not the default view ${JSON.stringify(framed.camera.eye)}`);
  const note = await bad.textContent('#link-note');
  assert.equal(await bad.isVisible('#link-note'), true);
  assert.match(note, /^Ignored in the link: fov: wants degrees from 1 to 170; eye: wants three numbers x,y,z; target: wants three numbers x,y,z\.$/);
  await bad.waitForFunction(() => /^#scene=demo&eye=[-\d.e]+,[-\d.e]+,[-\d.e]+&/.test(location.hash), null, { timeout: 10_000 });
  assert.deepEqual(await bad.evaluate(() => window.tessera.errors), []);
  await shot('10b-bad-link', bad);
  await bad.close();

  // A scene this server does not have: "demo", framed, and a note.
  const missing = await openPage(`#scene=${'ab'.repeat(32)}&eye=4,3,6&target=0,0.5,0`);
  const missingFrame = await waitForFrame((f) => f.scene_id === 'demo', 'demo instead of a missing scene', 60_000, missing);
  assert.ok(near(missingFrame.camera.eye, framed.camera.eye), 'the missing scene\'s camera was used');
  assert.match(await missing.textContent('#link-note'), /The link's scene abababab is not on this server/);
  assert.deepEqual(await missing.evaluate(() => window.tessera.errors), []);
  await missing.close();
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

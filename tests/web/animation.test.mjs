// The web viewer's Animation section in headless Chromium (Debian's /usr/bin/chromium, driven by
// playwright-core) against a real gateway and tesserad, as a user uses it: the section is
// hidden for the demo scene and shows once the skinned cylinder (tests/gltf/make_animated.py:
// animation "bend", bone1 about +Z by 0, 90, 0 degrees at t = 0, 1, 2 s) is uploaded with the
// file input; picking "bend" and setting the slider to 1 s bends the cylinder in the picture;
// Play makes frames arrive by themselves with the time running, the slider and readout
// following; Pause holds the time; with Loop off the time stops at the animation's end; back
// on the demo scene the section hides. Each check reads the settings of the frame the page drew
// (window.tessera.lastFrame) and the pixels on its canvas. Screenshots go to
// $TESSERA_WEB_ARTIFACTS (default: a temp directory).
//
// The scene: $TESSERA_ANIMATED_DIR/skinned_cylinder.gltf and .bin (CMake sets the directory;
// by hand: python3 tests/gltf/make_animated.py /tmp/anim_scenes and TESSERA_ANIMATED_DIR=that).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { freePort, launchChromium, pageLastFrame, waitForPageFrame, watchErrors } from './browser.mjs';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { REPO, startGateway, startTesserad } from '../../clients/web/test/harness.js';

const ARTIFACTS = process.env.TESSERA_WEB_ARTIFACTS || fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-web-artifacts-'));
fs.mkdirSync(ARTIFACTS, { recursive: true });

const ANIMATED_DIR = process.env.TESSERA_ANIMATED_DIR || path.join(REPO, 'build/default/tests/animated');
const SCENE_FILES = ['skinned_cylinder.gltf', 'skinned_cylinder.bin'].map((n) => path.join(ANIMATED_DIR, n));
const DURATION = 2;  // "bend": keys at 0, 1 and 2 s

let tesserad, gateway, browser, page;
let sceneId = null;  // the uploaded skinned cylinder's
let restShape = null;  // the orange pixels of the cylinder at rest (no animation)
const pageErrors = [];
const eventsSent = [];  // the settings of every event the page sent, in order

before(async () => {
  for (const file of SCENE_FILES) {
    assert.ok(fs.existsSync(file), `no ${file}: run python3 tests/gltf/make_animated.py DIR and set TESSERA_ANIMATED_DIR=DIR`);
  }
  tesserad = await startTesserad();
  gateway = await startGateway(tesserad.address, ['--listen', `127.0.0.1:${await freePort()}`]);
  browser = await launchChromium();
  const context = await browser.newContext({ viewport: { width: 1100, height: 700 } });
  page = await context.newPage();
  watchErrors(page, pageErrors);
  page.on('websocket', (ws) => ws.on('framesent', ({ payload }) => {
    if (typeof payload !== 'string') return;
    try {
      const msg = JSON.parse(payload);
      if (msg.op === 'event') eventsSent.push(msg.event?.settings ?? null);
    } catch {}
  }));
  await page.goto(gateway.url);
  // The stats overlay off (the Stats button), so that the screenshots show the whole cylinder.
  await page.click('#overlay-toggle');
  await page.waitForSelector('#overlay', { state: 'hidden' });
});

after(async () => {
  await browser?.close();
  await gateway?.stop();
  await tesserad?.stop();
  console.log(`# screenshots in ${ARTIFACTS}`);
});

const lastFrame = () => pageLastFrame(page);
const shot = (name) => page.screenshot({ path: path.join(ARTIFACTS, `${name}.png`) });
/** The canvas's pixels alone (the frame as drawn, without the toolbar on top) as a PNG. */
async function canvasShot(name) {
  const url = await page.evaluate(() => document.getElementById('view').toDataURL('image/png'));
  fs.writeFileSync(path.join(ARTIFACTS, `${name}.png`), Buffer.from(url.slice(url.indexOf(',') + 1), 'base64'));
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/** Polls the page until it has drawn a frame for which `predicate(frame)` holds; returns it. */
const waitForFrame = (predicate, what, timeout = 30_000) => waitForPageFrame(page, predicate, what, timeout);

const near = (a, b, eps = 1e-3) => Math.abs(Number(a) - Number(b)) < eps;
/** The time a frame shows (its effective settings.scene_time; unset is 0). */
const timeOf = (frame) => Number(frame.settings.scene_time ?? 0);
/** The animation a frame's settings name ('none' when they name none). */
const animationOf = (frame) => frame.settings.animation || 'none';

/**
 * In one go, so that they belong together: the frame the page drew last, the orange pixels on
 * its canvas (count and bounding box, in canvas pixels) and the Animation section's controls.
 * The page draws a frame and reflects its settings in the same task, so they agree.
 */
const view = () => page.evaluate(() => {
  const canvas = document.getElementById('view');
  const { width, height } = canvas;
  const data = canvas.getContext('2d').getImageData(0, 0, width, height).data;
  let count = 0, minX = width, minY = height, maxX = -1, maxY = -1;
  for (let y = 0; y < height; y++) {
    for (let x = 0; x < width; x++) {
      const i = 4 * (y * width + x);
      const [r, g, b] = [data[i], data[i + 1], data[i + 2]];
      // The cylinder's orange (0.9, 0.45, 0.1), lit: red well above green well above blue.
      if (r > 90 && r > 1.3 * g && g > 1.5 * b + 10) {
        count++;
        minX = Math.min(minX, x); maxX = Math.max(maxX, x);
        minY = Math.min(minY, y); maxY = Math.max(maxY, y);
      }
    }
  }
  const $ = (id) => document.getElementById(id);
  return {
    frame: window.tessera.lastFrame,
    orange: { count, width: maxX - minX + 1, height: maxY - minY + 1, minX, maxX, minY, maxY },
    controls: {
      select: $('animation-select').value,
      play: $('animation-play').textContent,
      pressed: $('animation-play').getAttribute('aria-pressed'),
      playDisabled: $('animation-play').disabled,
      time: Number($('animation-time').value),
      max: $('animation-time').max,
      readout: $('animation-readout').textContent,
      loop: $('animation-loop').checked,
    },
  };
});

/** "1.25 / 2.00 s" -> 1.25 */
const readoutTime = (text) => Number(/^(-?[\d.]+) \/ [\d.]+ s$/.exec(text)?.[1]);

/** Sets the time slider to `seconds` as a user does (the input and change events of a range). */
const setSlider = (seconds) => page.locator('#animation-time').fill(String(seconds));

test('the Animation section is hidden for the demo scene and shown for the uploaded skinned cylinder', async () => {
  const demo = await waitForFrame((f) => f.scene_id === 'demo', 'the demo scene', 60_000);
  assert.equal(animationOf(demo), 'none');
  assert.equal(await page.isHidden('#animation'), true, 'the demo has no animations: the section is hidden');
  assert.equal(await page.isHidden('#animation-heading'), true);

  // The .gltf together with its .bin, picked in the file input, as a user does.
  await page.setInputFiles('#upload-input', SCENE_FILES);
  await page.waitForFunction(() => window.tessera.scene !== 'demo', null, { timeout: 60_000 });
  sceneId = await page.evaluate(() => window.tessera.scene);
  assert.match(sceneId, /^[0-9a-f]{64}$/);
  await waitForFrame((f) => f.scene_id === sceneId, 'the skinned cylinder', 60_000);
  const scenes = await page.$$eval('#scene-select option', (os) => os.map((o) => [o.value, o.textContent]));
  assert.ok(scenes.some(([v, t]) => v === sceneId && /skinned_cylinder/.test(t)), JSON.stringify(scenes));

  await page.waitForSelector('#animation', { state: 'visible', timeout: 10_000 });
  assert.equal(await page.isVisible('#animation-heading'), true);
  const options = await page.$$eval('#animation-select option', (os) => os.map((o) => ({ value: o.value, label: o.textContent, disabled: o.disabled })));
  assert.equal(options.length, 2, JSON.stringify(options));
  assert.deepEqual(options.map((o) => [o.value, o.disabled]), [['none', false], ['bend', false]]);
  assert.match(options[0].label, /^none/);
  assert.match(options[1].label, /^bend \(2(\.0+)? s\)$/, options[1].label);

  // "none" is picked: the rest pose, nothing to play or scrub.
  const rest = await view();
  assert.equal(rest.frame.scene_id, sceneId);
  assert.equal(animationOf(rest.frame), 'none');
  assert.equal(rest.controls.select, 'none');
  assert.equal(rest.controls.playDisabled, true, 'no animation: Play is disabled');
  assert.equal(await page.isDisabled('#animation-time'), true);
  assert.equal(rest.controls.pressed, 'false');
  assert.ok(rest.orange.count > 200, `the cylinder is not in the picture: ${JSON.stringify(rest.orange)}`);
  // Upright: taller than wide (0.5 wide, 2 tall).
  assert.ok(rest.orange.height > 1.5 * rest.orange.width, `the cylinder at rest: ${JSON.stringify(rest.orange)}`);
  restShape = rest.orange;
  await shot('anim-01-rest');
});

test('picking "bend" and setting the slider to 1.0 s shows the cylinder bent, in the frame\'s settings and the picture', async () => {
  assert.ok(sceneId, 'needs the uploaded scene');
  await page.selectOption('#animation-select', 'bend');
  const picked = await waitForFrame((f) => animationOf(f) === 'bend', 'animation = bend');
  assert.ok(near(timeOf(picked), 0), `a picked animation starts at 0, not ${timeOf(picked)}`);
  assert.notEqual(picked.settings.play, true);
  const start = await view();
  assert.equal(start.controls.playDisabled, false);
  assert.equal(start.controls.max, String(DURATION));
  assert.equal(start.controls.readout, '0.00 / 2.00 s');
  // At 0 s the bend is 0 degrees: still the rest pose.
  assert.ok(Math.abs(start.orange.width - restShape.width) <= 3 && Math.abs(start.orange.height - restShape.height) <= 3,
    `bend at 0 s ${JSON.stringify(start.orange)} vs rest ${JSON.stringify(restShape)}`);

  await setSlider(1);
  const bentFrame = await waitForFrame((f) => near(timeOf(f), 1) && animationOf(f) === 'bend', 'scene_time = 1 s');
  assert.equal(bentFrame.settings.play ?? false, false, 'setting the time does not play');
  const bent = await view();
  assert.ok(near(timeOf(bent.frame), 1));
  assert.equal(bent.controls.readout, '1.00 / 2.00 s');
  assert.ok(near(bent.controls.time, 1));
  assert.equal(bent.controls.play, 'Play');
  assert.equal(bent.controls.pressed, 'false');
  // bone1 turned 90 degrees about +Z: the top half lies sideways, so the cylinder is about as
  // wide as it is tall (1.25 x 1.25), where at rest it was four times taller than wide.
  const aspect = (o) => o.width / o.height;
  assert.ok(bent.orange.count > 200, JSON.stringify(bent.orange));
  assert.ok(aspect(bent.orange) > 2 * aspect(restShape),
    `not bent at 1 s: ${JSON.stringify(bent.orange)} vs rest ${JSON.stringify(restShape)}`);
  assert.ok(bent.orange.height < 0.9 * restShape.height, `the top did not come down: ${JSON.stringify(bent.orange)}`);
  await shot('anim-02-bent-1.0s-paused');
  await canvasShot('anim-02b-bent-1.0s-canvas');
});

test('Play: frames keep coming with the time running while the user does nothing; slider and readout follow', async () => {
  const before = await view();
  await page.click('#animation-play');
  assert.equal(await page.getAttribute('#animation-play', 'aria-pressed'), 'true');
  assert.equal(await page.textContent('#animation-play'), 'Pause');
  const first = await waitForFrame((f) => f.settings.play === true, 'play = true');
  const sent = eventsSent.length;
  // The user does nothing from here: no event is sent, yet frames come, each showing a later
  // time (it wraps at 2 s, the loop being on).
  const samples = [];
  const deadline = Date.now() + 20_000;
  while (samples.length < 4 && Date.now() < deadline) {
    const v = await view();
    if (v.frame.sequence > (samples.at(-1)?.frame.sequence ?? first.sequence)) samples.push(v);
    await sleep(100);
  }
  assert.ok(samples.length >= 4, `only ${samples.length} frames in 20 s of playing`);
  assert.equal(eventsSent.length, sent, `the page sent ${JSON.stringify(eventsSent.slice(sent))}`);
  let previous = first;
  for (const v of samples) {
    assert.equal(v.frame.event_id, first.event_id, 'frames of the same event, made by the clock');
    assert.equal(v.frame.settings.play, true);
    assert.equal(animationOf(v.frame), 'bend');
    const t = timeOf(v.frame);
    assert.ok(t >= 0 && t <= DURATION, `time ${t}`);
    const step = (t - timeOf(previous) + DURATION) % DURATION;
    assert.ok(step > 0, `from ${timeOf(previous)} s to ${t} s`);
    previous = v.frame;
    // The slider and the readout show the time of the frame on screen.
    assert.ok(Math.abs(v.controls.time - t) <= 0.011, `slider ${v.controls.time} for ${t}`);
    assert.ok(Math.abs(readoutTime(v.controls.readout) - t) <= 0.006, `readout '${v.controls.readout}' for ${t}`);
    assert.match(v.controls.readout, / \/ 2\.00 s$/);
    assert.equal(v.controls.play, 'Pause');
  }
  assert.notEqual(samples[0].controls.readout, samples.at(-1).controls.readout, 'the readout did not move');
  assert.ok(before.frame.sequence < samples.at(-1).frame.sequence);
  await shot('anim-03-playing');
});

test('Pause holds the time: later frames show the same time, and so does the readout', async () => {
  await page.click('#animation-play');
  assert.equal(await page.getAttribute('#animation-play', 'aria-pressed'), 'false');
  assert.equal(await page.textContent('#animation-play'), 'Play');
  const paused = await waitForFrame((f) => f.settings.play === false, 'play = false');
  const held = timeOf(paused);
  await sleep(700);  // the clock would have moved on by now
  const still = await view();
  assert.equal(timeOf(still.frame), held);
  assert.ok(Math.abs(readoutTime(still.controls.readout) - held) <= 0.006, `readout '${still.controls.readout}' for ${held}`);
  // Two more frames, from changes that are not the time (a zoom, then Loop off): same time.
  const first = still.frame;
  const box = await page.locator('#view').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.wheel(0, 100);
  const zoomed = await waitForFrame((f) => f.sequence > first.sequence, 'a frame after zooming out');
  await page.uncheck('#animation-loop');
  const unlooped = await waitForFrame((f) => f.sequence > zoomed.sequence && f.settings.loop === false, 'loop = false');
  for (const f of [zoomed, unlooped]) {
    assert.equal(timeOf(f), held, `a frame ${f.sequence} after the pause shows ${timeOf(f)} s, not ${held} s`);
    assert.equal(f.settings.play ?? false, false);
  }
  const after = await view();
  assert.ok(Math.abs(readoutTime(after.controls.readout) - held) <= 0.006, `readout '${after.controls.readout}' for ${held}`);
  assert.equal(after.controls.loop, false);
});

test('with Loop off, playing from near the end stops at the animation\'s end', async () => {
  assert.equal(await page.isChecked('#animation-loop'), false);
  await setSlider(1.8);
  await waitForFrame((f) => near(timeOf(f), 1.8) && f.settings.loop === false, 'scene_time = 1.8 s, loop off');
  await page.click('#animation-play');
  const playing = await waitForFrame((f) => f.settings.play === true, 'playing from 1.8 s');
  assert.ok(timeOf(playing) >= 1.8 - 1e-3, `${timeOf(playing)}`);
  // Watch every frame drawn until well after the end: the time only grows and stops at 2 s.
  const times = [];
  let last = playing;
  const deadline = Date.now() + 3000;
  while (Date.now() < deadline) {
    const f = await lastFrame();
    if (f.sequence !== last.sequence) times.push(timeOf(f));
    assert.ok(timeOf(f) >= timeOf(last) - 1e-6, `the time went back from ${timeOf(last)} to ${timeOf(f)}: it wrapped`);
    assert.ok(timeOf(f) <= DURATION + 1e-3, `the time ${timeOf(f)} is past the end`);
    last = f;
    await sleep(50);
  }
  assert.ok(times.length >= 2, `only ${times.length} frames while playing to the end`);
  const end = await waitForFrame((f) => near(timeOf(f), DURATION) && f.settings.play !== true,
    'the time at the end (2 s), play off', 10_000);
  await sleep(500);
  const still = await view();
  assert.ok(near(timeOf(still.frame), DURATION), `held at ${timeOf(still.frame)}; saw ${times}`);
  assert.equal(still.controls.readout, '2.00 / 2.00 s');
  assert.ok(near(still.controls.time, DURATION));
  // At 2 s the bend is back to 0 degrees: upright again.
  assert.ok(still.orange.height > 1.5 * still.orange.width, JSON.stringify(still.orange));
  assert.equal(animationOf(end), 'bend');
  await shot('anim-04-loop-off-end');

  // At its end the server stops playing (the frame there says play off) and renders no more
  // frames by itself; the button says Play, and one click plays again from the start.
  assert.equal(still.frame.sequence, end.sequence, 'no frames after the end without a change');
  assert.equal(still.controls.play, 'Play');
  await page.click('#animation-play');
  const again = await waitForFrame((f) => f.settings.play === true && timeOf(f) < 1.5, 'playing again from the start');
  assert.ok(again.settings.loop === false);
  await page.click('#animation-play');
  await waitForFrame((f) => f.settings.play === false, 'paused again');
});

test('switching back to the demo scene hides the section; the animation stays with its scene', async () => {
  await page.selectOption('#scene-select', 'demo');
  const demo = await waitForFrame((f) => f.scene_id === 'demo', 'the demo scene again', 60_000);
  await page.waitForSelector('#animation', { state: 'hidden', timeout: 10_000 });
  assert.equal(animationOf(demo), 'none', 'the animation was carried to a scene without it');
  assert.notEqual(demo.settings.play, true);
  const headings = await page.$$eval('#panel h2', (hs) => hs.filter((h) => !h.closest('[hidden]')).map((h) => h.textContent));
  assert.deepEqual(headings, ['Scene', 'Settings']);
  // Back on the cylinder: it starts at rest, "none" picked.
  await page.selectOption('#scene-select', sceneId);
  const again = await waitForFrame((f) => f.scene_id === sceneId, 'the cylinder again', 60_000);
  await page.waitForSelector('#animation', { state: 'visible', timeout: 10_000 });
  assert.equal(animationOf(again), 'none');
  assert.equal(await page.$eval('#animation-select', (s) => s.value), 'none');
  assert.equal(await page.isDisabled('#animation-play'), true);
});

test('no script errors on the page', async () => {
  assert.deepEqual(pageErrors, []);
  assert.deepEqual(await page.evaluate(() => window.tessera.errors), []);
});

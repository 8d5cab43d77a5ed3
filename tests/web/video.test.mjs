// The web viewer's H.264 stream in headless Chromium (WebCodecs) against a real gateway and
// tesserad: choosing H.264 in the panel streams video that starts with a keyframe and is decoded
// in the page; the picture on the canvas matches a lossless Render of the same view (PSNR); a
// resize starts a new video with a keyframe at an even size; "Save image" writes a PNG; a lost
// frame makes the page ask for a keyframe and carry on; a browser without WebCodecs stays on
// JPEG and says why; switching back to JPEG gives JPEG frames; no script errors. Screenshots go
// to $TESSERA_WEB_ARTIFACTS (default: a temp directory).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import {
  freePort, launchChromium, pageLastFrame, waitForPageFrame, watchErrors,
} from './browser.mjs';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {
  PageClient, splitBinary, startGateway, startTesserad,
} from '../../clients/web/test/harness.js';


const ARTIFACTS = process.env.TESSERA_WEB_ARTIFACTS || fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-web-artifacts-'));
fs.mkdirSync(ARTIFACTS, { recursive: true });
const MIN_PSNR_DB = 30;

let tesserad, gateway, gatewayPort, browser, context, page;
const pageErrors = [];
const received = [];  // headers of the frame messages the main page got, in order
const sentEvents = [];  // ClientEvents (and opens) the main page sent

before(async () => {
  tesserad = await startTesserad();
  gatewayPort = await freePort();  // a gateway started again comes back on the same address
  gateway = await startGateway(tesserad.address, ['--listen', `127.0.0.1:${gatewayPort}`]);
  browser = await launchChromium();
  context = await browser.newContext({ viewport: { width: 800, height: 500 }, acceptDownloads: true });
  page = await context.newPage();
  watchErrors(page, pageErrors);
  page.on('websocket', (ws) => {
    ws.on('framereceived', ({ payload }) => {
      if (typeof payload !== 'string') received.push(splitBinary(payload).header);
    });
    ws.on('framesent', ({ payload }) => {
      if (typeof payload !== 'string') return;
      const msg = JSON.parse(payload);
      if (msg.op === 'event') sentEvents.push(msg.event);
      if (msg.op === 'open') sentEvents.push({ open: msg.open });
    });
  });
  await page.goto(gateway.url);
});

after(async () => {
  await browser?.close();
  await gateway?.stop();
  await tesserad?.stop();
  console.log(`# screenshots in ${ARTIFACTS}`);
});

const lastFrame = (p = page) => pageLastFrame(p);
const shot = (name, p = page) => p.screenshot({ path: path.join(ARTIFACTS, `video-${name}.png`) });
const isVideo = (h) => h.frame?.encoding === 'VIDEO_H264';

/** Polls the page until it has drawn a frame for which `predicate(frame)` holds; returns it. */
const waitForFrame = (predicate, what, timeout = 60_000, p = page) =>
  waitForPageFrame(p, predicate, what, timeout);

/** Waits until no new frame has been drawn for `quietMs`; returns the frame shown. */
async function waitForRest(p = page, quietMs = 1000, timeout = 60_000) {
  const start = Date.now();
  let seq = -1;
  let since = Date.now();
  while (Date.now() - start < timeout) {
    const now = (await lastFrame(p))?.sequence ?? -1;
    if (now !== seq) {
      seq = now;
      since = Date.now();
    } else if (Date.now() - since >= quietMs) {
      return lastFrame(p);
    }
    await new Promise((r) => setTimeout(r, 50));
  }
  throw new Error('the stream did not come to rest');
}

async function drag(p, dx, dy, steps = 6) {
  const box = await p.locator('#view').boundingBox();
  const x = box.x + box.width / 2, y = box.y + box.height / 2;
  await p.mouse.move(x, y);
  await p.mouse.down();
  for (let i = 1; i <= steps; i++) await p.mouse.move(x + (dx * i) / steps, y + (dy * i) / steps);
  await p.mouse.up();
}

/** The canvas size in device pixels and the resolution choice. */
const canvasSize = (p = page) => p.evaluate(() => {
  const c = document.getElementById('view');
  return { w: c.width, h: c.height, res: Number(document.getElementById('resolution').value) };
});

/** Selects the codec in the panel's Encoding section (folded by default). */
async function chooseCodec(p, codec) {
  if (!(await p.isVisible('#codec'))) await p.click('#group-encoding summary');
  await p.selectOption('#codec', codec);
}

test('choosing H.264 streams video: a keyframe first, decoded by WebCodecs, the codec and decode time in the stats', async () => {
  const jpeg = await waitForFrame((f) => f.scene_id === 'demo', 'the demo scene');
  assert.equal(jpeg.encoding, 'IMAGE_JPEG', 'a new page streams JPEG');
  assert.equal(await page.evaluate(() => window.tessera.codec), 'jpeg');
  assert.equal(await page.isVisible('#crf-field'), false, 'the CRF is for H.264 only');

  await chooseCodec(page, 'h264');
  const frame = await waitForFrame(isVideoFrame, 'an H.264 frame drawn');
  const first = received.find(isVideo);
  assert.equal(first.frame.keyframe, true, 'the first H.264 frame is not a keyframe');
  assert.match(first.frame.codec, /^avc1\.[0-9a-f]{6}$/i);
  assert.match(first.frame.encoder, /^(libx264|h264_nvenc)$/);
  assert.equal(first.video_seq, 1);
  // The page asked in one event: the codec and a render size H.264 can code.
  const ask = sentEvents.find((e) => e.video?.codec === 'VIDEO_CODEC_H264');
  assert.ok(ask, JSON.stringify(sentEvents.slice(-3)));
  assert.equal(ask.video.crf, 23);
  assert.equal(ask.video.interactive_crf, 29);
  assert.equal(ask.settings.width % 2, 0);
  assert.equal(ask.settings.height % 2, 0);
  assert.equal(frame.width % 2, 0);
  assert.equal(frame.height % 2, 0);

  assert.equal(await page.evaluate(() => window.tessera.codec), 'h264');
  const decodeMs = await page.evaluate(() => window.tessera.decodeMs);
  assert.ok(Number.isFinite(decodeMs) && decodeMs >= 0 && decodeMs < 5000, `decode ${decodeMs} ms`);
  assert.equal(await page.isVisible('#crf-field'), true);
  assert.equal(await page.isHidden('#codec-note'), true);
  assert.deepEqual(JSON.parse(await page.evaluate(() => localStorage.getItem('tessera.video'))), { codec: 'h264', crf: 23, interactive_crf: 29 });

  // Orbiting gives frames that are not keyframes, decoded in order: the page never needs to
  // ask for a keyframe.
  const before = frame.sequence;
  await drag(page, 120, 30);
  const client = await page.evaluate(() => window.tessera.camera());
  const moved = await waitForFrame((f) => isVideoFrame(f) && f.sequence > before &&
    Math.abs(f.camera.eye.x - client.eye.x) < 1e-3 && Math.abs(f.camera.eye.z - client.eye.z) < 1e-3, 'the orbit, in H.264');
  const since = received.filter((h) => isVideo(h) && h.frame.sequence > before);
  assert.ok(since.some((h) => !h.frame.keyframe), 'no frame after the keyframe was a delta frame');
  assert.ok(since.every((h, i) => i === 0 || h.video_seq === since[i - 1].video_seq + 1), 'the gateway dropped frames');
  assert.equal(await page.evaluate(() => window.tessera.keyframeRequests), 0);
  assert.ok(moved.bytes > 0);

  await page.waitForFunction(() => /codec\s*h264 avc1\./.test(document.getElementById('stats').textContent));
  const stats = await page.locator('#overlay').innerText();
  assert.match(stats, new RegExp(`codec\\s+h264 ${first.frame.codec} \\(${first.frame.encoder}\\)`));
  assert.match(await page.textContent('#stats-more'), /decode\s*[\d.]+ ms/);  // folded under "More"
  assert.match(stats, /bitrate\s+([\d.]+|idle \(last [\d.]+) Mbit\/s/);
  await shot('01-h264');
});

function isVideoFrame(f) {
  return f.encoding === 'VIDEO_H264';
}

/**
 * PSNR in dB (RGB) between the #view canvas's backing store and `png` (a Render of the same
 * view) drawn the way the page draws frames, computed in the page.
 */
function canvasPsnr(png) {
  return page.evaluate(async (base64) => {
    const bytes = Uint8Array.from(atob(base64), (c) => c.charCodeAt(0));
    const reference = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
    const view = document.getElementById('view');
    const { width, height } = view;
    const shown = view.getContext('2d').getImageData(0, 0, width, height).data;
    const scratch = new OffscreenCanvas(width, height);
    const ctx = scratch.getContext('2d');
    ctx.imageSmoothingQuality = 'high';
    ctx.drawImage(reference, 0, 0, width, height);
    const want = ctx.getImageData(0, 0, width, height).data;
    let sum = 0;
    for (let i = 0; i < want.length; i += 4) {
      for (let c = 0; c < 3; c++) sum += (shown[i + c] - want[i + c]) ** 2;
    }
    const mse = sum / (width * height * 3);
    return { psnr: mse === 0 ? Infinity : 10 * Math.log10((255 * 255) / mse), width, height, referenceWidth: reference.width };
  }, png.toString('base64'));
}

/** A lossless Render through the gateway (as any page would ask) of the scene and `camera`. */
async function renderPng(frame, lookAt) {
  const client = await PageClient.connect(gateway.wsUrl);
  try {
    const reply = await client.request('render', {
      request: {
        scene_id: frame.scene_id,
        camera: { look_at: lookAt, yfov: frame.yfov, znear: frame.znear, zfar: frame.zfar },
        settings: frame.settings,
        encoding: 'IMAGE_PNG',
      },
    });
    assert.ok(reply.ok, JSON.stringify(reply.error));
    const message = client.frames.find((f) => f.header.id !== undefined);
    assert.equal(reply.result.frame.width, frame.width);
    assert.equal(reply.result.frame.encoding, 'IMAGE_PNG');
    return message.payload;
  } finally {
    client.close();
  }
}

test(`the picture on the canvas matches a lossless Render of the same view: PSNR >= ${MIN_PSNR_DB} dB`, async () => {
  // Render at the canvas's own size: the comparison is not softened by upscaling.
  await page.selectOption('#resolution', '100');
  const size = await canvasSize();
  await waitForFrame((f) => isVideoFrame(f) && Math.abs(f.width - size.w) <= 1 && Math.abs(f.height - size.h) <= 1, 'a full-resolution H.264 frame');
  const frame = await waitForRest();
  assert.equal(frame.encoding, 'VIDEO_H264');
  assert.equal(frame.profile, 'full');

  const same = await canvasPsnr(await renderPng(frame, frame.camera));
  console.log(`# PSNR of the H.264 picture on the canvas against a PNG Render: ${same.psnr.toFixed(2)} dB ` +
    `(${frame.width}x${frame.height} on a ${same.width}x${same.height} canvas, ${frame.bytes} bytes, crf 23)`);
  assert.equal(same.referenceWidth, frame.width);
  assert.ok(same.psnr >= MIN_PSNR_DB, `PSNR ${same.psnr.toFixed(2)} dB`);

  // The measure tells views apart: the same scene from a camera orbited a little is far off.
  const { eye, target } = frame.camera;
  const angle = 0.15;
  const dx = eye.x - target.x, dz = eye.z - target.z;
  const turned = {
    ...frame.camera,
    eye: { x: target.x + dx * Math.cos(angle) - dz * Math.sin(angle), y: eye.y, z: target.z + dx * Math.sin(angle) + dz * Math.cos(angle) },
  };
  const other = await canvasPsnr(await renderPng(frame, turned));
  console.log(`# PSNR against a Render orbited by ${angle} rad: ${other.psnr.toFixed(2)} dB`);
  assert.ok(other.psnr < MIN_PSNR_DB && other.psnr < same.psnr - 6, `another view scored ${other.psnr.toFixed(2)} dB`);
  await shot('02-full-resolution');
});

test('"save image" of an H.264 frame writes the picture as a PNG of the frame\'s size', async () => {
  const frame = await lastFrame();
  assert.equal(frame.encoding, 'VIDEO_H264');
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#save')]);
  assert.match(download.suggestedFilename(), new RegExp(`^tessera-demo-${frame.sequence}\\.png$`));
  const file = path.join(ARTIFACTS, `video-${download.suggestedFilename()}`);
  await download.saveAs(file);
  const png = fs.readFileSync(file);
  assert.deepEqual([...png.subarray(0, 8)], [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]);
  assert.equal(png.readUInt32BE(16), frame.width);  // IHDR
  assert.equal(png.readUInt32BE(20), frame.height);
});

test('the video quality (CRF) goes to the session and is remembered; a value out of range stays in the field', async () => {
  const crfEvents = () => sentEvents.filter((e) => e.video?.crf !== undefined && !e.video.codec);
  await page.fill('#video-crf', '60');
  await page.locator('#video-crf').dispatchEvent('change');
  assert.equal(await page.getAttribute('#video-crf', 'aria-invalid'), 'true');
  await page.fill('#video-crf', '30');
  await page.locator('#video-crf').dispatchEvent('change');
  assert.equal(await page.getAttribute('#video-crf', 'aria-invalid'), 'false');
  await page.waitForFunction(() => JSON.parse(localStorage.getItem('tessera.video')).crf === 30);
  const sent = crfEvents();
  assert.deepEqual(sent.map((e) => e.video), [{ crf: 30 }], 'a refused value was sent, or the change was not');
  // The server takes it (a bad value would end the stream) and renders with it.
  await waitForFrame((f) => f.event_id >= sent[0].event_id, 'the frame of the CRF change');
  assert.equal((await lastFrame()).encoding, 'VIDEO_H264');
  assert.deepEqual(await page.evaluate(() => window.tessera.errors), []);
});

test('the video quality while moving (interactive CRF) goes to the session and is remembered', async () => {
  const events = () => sentEvents.filter((e) => e.video?.interactive_crf !== undefined && !e.video.codec);
  if (!(await page.isVisible('#interactive-crf'))) await page.click('#group-interactive summary');
  assert.equal(await page.isVisible('#interactive-crf'), true, 'shown in an H.264 session');
  await page.fill('#interactive-crf', '0');
  await page.locator('#interactive-crf').dispatchEvent('change');
  assert.equal(await page.getAttribute('#interactive-crf', 'aria-invalid'), 'true');
  await page.fill('#interactive-crf', '35');
  await page.locator('#interactive-crf').dispatchEvent('change');
  await page.waitForFunction(() => JSON.parse(localStorage.getItem('tessera.video')).interactive_crf === 35);
  const sent = events();
  assert.deepEqual(sent.map((e) => e.video), [{ interactive_crf: 35 }], 'a refused value was sent, or the change was not');
  // The server takes it (a bad value would end the stream) and renders a frame for it.
  await waitForFrame((f) => f.event_id >= sent[0].event_id, 'the frame of the interactive CRF change');
  assert.equal((await lastFrame()).encoding, 'VIDEO_H264');
  assert.deepEqual(await page.evaluate(() => window.tessera.errors), []);
});

test('a resize starts a new video: a keyframe at the new size, rounded down to even', async () => {
  const before = await lastFrame();
  const old = await canvasSize();
  await page.setViewportSize({ width: 753, height: 467 });  // odd canvas sizes
  await page.waitForFunction((w) => document.getElementById('view').width !== w, old.w);
  const size = await canvasSize();
  assert.ok(size.w % 2 === 1 || size.h % 2 === 1, `canvas ${size.w}x${size.h}: not odd, the test proves nothing`);
  const after = await waitForFrame((f) => isVideoFrame(f) && f.width !== before.width, 'a frame of the new size');
  assert.equal(after.width, size.w - (size.w % 2));
  assert.equal(after.height, size.h - (size.h % 2));
  const firstOfSize = received.find((h) => isVideo(h) && h.frame.width === after.width && h.frame.sequence > before.sequence);
  assert.equal(firstOfSize.frame.keyframe, true, 'the first frame of the new size is not a keyframe');
  assert.equal(await page.evaluate(() => window.tessera.keyframeRequests), 0, 'the page had to ask for a keyframe');
  await shot('03-resized');
});

test('the page comes back when its gateway dies and resumes its H.264 session with a keyframe', async () => {
  const before = await lastFrame();
  assert.equal(before.encoding, 'VIDEO_H264');
  gateway.proc.kill('SIGKILL');
  await page.waitForFunction(() => !window.tessera.connected, null, { timeout: 30_000 });
  await gateway.stop();
  const seen = received.length;
  gateway = await startGateway(tesserad.address, ['--listen', `127.0.0.1:${gatewayPort}`]);
  await page.waitForFunction(() => window.tessera.connected, null, { timeout: 60_000 });
  const after = await waitForFrame((f) => f.sequence > before.sequence, 'a frame after reconnecting');
  // tesserad parked the session and resumed it: same session, a new video for the new decoder.
  assert.equal(after.session_token, before.session_token);
  assert.equal(after.encoding, 'VIDEO_H264');
  const firstBack = received.slice(seen).find(isVideo);
  assert.equal(firstBack.frame.keyframe, true, 'the first frame after the resume is not a keyframe');
  assert.equal(await page.evaluate(() => window.tessera.keyframeRequests), 0, 'the page had to ask for a keyframe');
  await drag(page, 50, 0, 3);
  const client = await page.evaluate(() => window.tessera.camera());
  const moved = await waitForFrame((f) => Math.abs(f.camera.eye.x - client.eye.x) < 1e-3, 'the orbit after the resume');
  assert.equal(moved.encoding, 'VIDEO_H264');
});

test('a frame lost on the way: the page notices the gap, asks for a keyframe and carries on', async () => {
  // A second page whose socket loses one H.264 frame that is not a keyframe. It opens with
  // H.264 at once: the choice is remembered.
  const lossy = await context.newPage();
  watchErrors(lossy, pageErrors);
  const toServer = [];
  let videoFrames = 0;
  let lost = null;
  await lossy.routeWebSocket(/\/ws$/, (ws) => {
    const server = ws.connectToServer();
    ws.onMessage((message) => {
      if (typeof message === 'string') toServer.push(JSON.parse(message));
      server.send(message);
    });
    server.onMessage((message) => {
      if (typeof message !== 'string') {
        const header = splitBinary(message).header;
        if (isVideo(header) && ++videoFrames >= 3 && !header.frame.keyframe && lost === null) {
          lost = header;
          return;
        }
      }
      ws.send(message);
    });
  });
  await lossy.goto(gateway.url);
  const first = await waitForFrame(isVideoFrame, 'an H.264 frame', 60_000, lossy);
  const open = toServer.find((m) => m.op === 'open');
  assert.equal(open.open.video?.codec, 'VIDEO_CODEC_H264');
  assert.equal(first.width % 2, 0);
  for (let i = 0; i < 6 && lost === null; i++) await drag(lossy, 40, 10, 3);
  assert.ok(lost, 'no frame was lost: the test proves nothing');
  await lossy.waitForFunction(() => window.tessera.keyframeRequests === 1, null, { timeout: 30_000 });
  const asked = toServer.filter((m) => m.op === 'event' && m.event.keyframe === true);
  assert.equal(asked.length, 1);
  // The keyframe comes and frames after it are drawn again.
  const recovered = await waitForFrame((f) => f.sequence > lost.frame.sequence && f.event_id >= asked[0].event.event_id, 'a frame after the keyframe', 30_000, lossy);
  assert.equal(recovered.encoding, 'VIDEO_H264');
  await drag(lossy, -60, 0, 3);
  const client = await lossy.evaluate(() => window.tessera.camera());
  await waitForFrame((f) => Math.abs(f.camera.eye.x - client.eye.x) < 1e-3, 'the orbit after the recovery', 30_000, lossy);
  assert.equal(await lossy.evaluate(() => window.tessera.keyframeRequests), 1);
  assert.deepEqual(await lossy.evaluate(() => window.tessera.errors), []);
  await lossy.close();
});

test('a browser without WebCodecs stays on JPEG and says why, in a note', async () => {
  const plain = await context.newPage();
  watchErrors(plain, pageErrors);
  await plain.addInitScript(() => { delete window.VideoDecoder; });
  await plain.goto(gateway.url);  // H.264 is remembered from the first page
  const frame = await waitForFrame((f) => f.scene_id === 'demo', 'a frame', 60_000, plain);
  assert.equal(frame.encoding, 'IMAGE_JPEG');
  assert.equal(await plain.evaluate(() => window.tessera.codec), 'jpeg');
  assert.equal(await plain.$eval('#codec', (s) => s.value), 'h264');
  assert.match(await plain.textContent('#codec-note'), /^H\.264 is not used: this browser has no WebCodecs video decoder\. Showing JPEG\.$/);
  assert.deepEqual(await plain.evaluate(() => window.tessera.errors), []);
  if (!(await plain.isVisible('#codec'))) await plain.click('#group-encoding summary');
  assert.equal(await plain.isVisible('#codec-note'), true);
  await shot('04-no-webcodecs', plain);
  await plain.close();
});

test('switching back to JPEG gives JPEG frames', async () => {
  const before = await lastFrame();
  await chooseCodec(page, 'jpeg');
  const jpeg = await waitForFrame((f) => f.encoding === 'IMAGE_JPEG' && f.sequence > before.sequence, 'a JPEG frame');
  assert.equal(await page.evaluate(() => window.tessera.codec), 'jpeg');
  const ask = sentEvents.filter((e) => e.video).at(-1);
  assert.deepEqual(ask.video, { codec: 'VIDEO_CODEC_JPEG' });
  await drag(page, -80, 0);
  const client = await page.evaluate(() => window.tessera.camera());
  const moved = await waitForFrame((f) => Math.abs(f.camera.eye.x - client.eye.x) < 1e-3, 'the orbit, in JPEG');
  assert.equal(moved.encoding, 'IMAGE_JPEG');
  assert.ok(moved.sequence > jpeg.sequence);
  assert.match(await page.locator('#overlay').innerText(), /codec\s+jpeg/);
  assert.deepEqual(await page.evaluate(() => window.tessera.errors), []);
});

test('no script errors on the pages', () => {
  // The reconnect makes Chromium log the failed WebSocket attempts: the browser's lines, not the page's.
  assert.deepEqual(pageErrors.filter((e) => !/WebSocket connection to .* failed/.test(e)), []);
});

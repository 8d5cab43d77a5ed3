// The gateway against a real tesserad: every operation of the protocol, the errors a page
// gets, and that nothing a page sends hurts the gateway or another page.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { webcrypto } from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';
import net from 'node:net';
import { ASSETS, PageClient, binaryMessage, startGateway, startTesserad } from './harness.js';
import { computeSceneId } from '../public/upload.js';

let tesserad, gateway;

before(async () => {
  tesserad = await startTesserad();
  gateway = await startGateway(tesserad.address, ['--max-upload-mb', '8']);
});

after(async () => {
  await gateway?.stop();
  await tesserad?.stop();
});

const SMALL = { width: 64, height: 48 };

test('info carries the server info and the RenderSettings schema with the offered choices', async () => {
  const page = await PageClient.connect(gateway.wsUrl);
  const hello = await page.waitFor(() => page.messages.find((m) => m.type === 'hello'), 'hello');
  assert.equal(hello.server, tesserad.address);
  const reply = await page.request('info');
  assert.ok(reply.ok, JSON.stringify(reply.error));
  const { info, schema } = reply.result;
  assert.match(info.device.name, /\S/);
  const byName = Object.fromEntries(schema.map((f) => [f.name, f]));
  // Every RenderSettings field of the proto, with its type.
  for (const name of ['width', 'aa', 'samples', 'culling', 'synthetic_lights', 'debug_view', 'jpeg_quality', 'exposure_ev', 'shadows']) {
    assert.ok(byName[name], `schema lacks ${name}`);
  }
  assert.equal(byName.shadows.type, 'bool');
  assert.equal(byName.exposure_ev.type, 'float');
  assert.equal(byName.aa.type, 'enum');
  assert.equal(byName.aa.enum, 'AaMode');
  assert.ok(!byName.aa.values.includes('AA_MODE_UNSPECIFIED'));
  // The server's lower-case choices, as proto names: all of them, and only real values.
  assert.equal(byName.aa.choices.length, info.choices.aa.length);
  assert.ok(byName.aa.choices.includes('AA_VIS_MLAA'));
  assert.ok(byName.aa.choices.every((c) => byName.aa.values.includes(c)));
  assert.deepEqual(byName.culling.choices, info.choices.culling.map((c) => `CULLING_${c.toUpperCase()}`));
  assert.deepEqual(byName.samples.choices, info.choices.samples);
  assert.equal(info.default_settings.aa, 'AA_NONE');
  // The server's settings table: one spec per RenderSettings field, with its range and label;
  // the one text field, animation, is outside the table (the page's Animation section has it).
  const specs = Object.fromEntries(info.choices.settings.map((s) => [s.name, s]));
  assert.deepEqual(Object.keys(specs).sort(), schema.filter((f) => f.type !== 'other').map((f) => f.name).sort());
  assert.deepEqual(schema.filter((f) => f.type === 'other').map((f) => f.name), ['animation']);
  assert.equal(specs.bloom_strength.type, 'float');
  assert.equal(specs.bloom_strength.max, 1);
  assert.equal(specs.jpeg_quality.min, 1);
  assert.equal(specs.jpeg_quality.default_value, '90');
  assert.equal(specs.aa.label, 'Anti-aliasing');
  assert.deepEqual(specs.aa.choices, info.choices.aa);
  page.close();
});

test('render returns a JPEG frame and its header; an unknown scene is NOT_FOUND in plain words', async () => {
  const page = await PageClient.connect(gateway.wsUrl);
  const reply = await page.request('render', { request: { scene_id: 'demo', settings: SMALL } });
  assert.ok(reply.ok, JSON.stringify(reply.error));
  const frame = page.frames.find((f) => f.header.id !== undefined);
  assert.ok(frame, 'no binary frame before the reply');
  assert.equal(frame.payload[0], 0xff);
  assert.equal(frame.payload[1], 0xd8);
  assert.equal(frame.header.frame.bytes, frame.payload.length);
  assert.equal(reply.result.frame.width, 64);
  assert.equal(reply.result.frame.settings.aa, 'AA_NONE');
  assert.ok(reply.result.frame.passes.length > 0);

  const missing = await page.request('render', { request: { scene_id: 'no-such-scene' } });
  assert.equal(missing.ok, false);
  assert.equal(missing.error.code, 'NOT_FOUND');
  assert.match(missing.error.message, /scene_id/);
  assert.equal(missing.error.hint, 'Not found on the server');

  const bad = await page.request('render', { request: { scene_id: 'demo', settings: { jpeg_quality: 0 } } });
  assert.equal(bad.error.code, 'INVALID_ARGUMENT');
  assert.match(bad.error.message, /jpeg_quality/);
  page.close();
});

test('a stream follows camera and settings events; a malformed event fails alone', async () => {
  const page = await PageClient.connect(gateway.wsUrl);
  const opened = await page.request('open', { open: { scene_id: 'demo', settings: SMALL } });
  assert.deepEqual(opened.result, { stream: 1, resumed: false }); // the stream is named by its open's id
  const sid = opened.result.stream;
  const first = await page.waitFor(() => page.frames.find((f) => f.header.stream === sid), 'the first frame');
  const eye = { x: 3, y: 4, z: 5 };
  page.ws.send(JSON.stringify({ id: 100, op: 'event', stream: sid,
    event: { event_id: 7, camera: { look_at: { eye, target: { x: 0, y: 0, z: 0 } } } } }));
  const moved = await page.waitFor(() => page.frames.find((f) => f.header.frame.event_id === 7), 'frame of event 7');
  assert.ok(Math.abs(moved.header.frame.camera.eye.x - 3) < 1e-4);
  assert.notDeepEqual(moved.header.frame.camera, first.header.frame.camera);

  const bad = await page.request('event', { stream: sid, event: { event_id: 8, camera: 5 } });
  assert.equal(bad.error.code, 'INVALID_ARGUMENT');
  assert.match(bad.error.message, /camera/);
  const unknown = await page.request('event', { stream: 999, event: {} });
  assert.equal(unknown.error.code, 'NOT_FOUND');

  page.ws.send(JSON.stringify({ id: 101, op: 'event', stream: sid, event: { event_id: 9, settings: { aa: 'AA_FXAA' } } }));
  const fxaa = await page.waitFor(() => page.frames.find((f) => f.header.frame.event_id === 9), 'frame of event 9');
  assert.equal(fxaa.header.frame.settings.aa, 'AA_FXAA');
  assert.match(fxaa.header.frame.session_token, /\S/);

  const closed = await page.request('close', { stream: sid });
  assert.ok(closed.ok);
  const end = await page.waitFor(() => page.messages.find((m) => m.type === 'stream_end' && m.stream === sid), 'stream_end');
  assert.equal(end.ok, true);
  page.close();
});

async function openAndGetToken(page) {
  const opened = await page.request('open', { open: { scene_id: 'demo', settings: SMALL } });
  const frame = await page.waitFor(() => page.frames.find((f) => f.header.stream === opened.result.stream), 'a frame');
  return frame.header.frame;
}

async function resume(page, token) {
  const r = await page.request('open', { open: { resume_token: token } });
  const sid = r.result.stream;
  const outcome = await page.waitFor(() => page.frames.find((f) => f.header.stream === sid)
    || page.messages.find((m) => m.type === 'stream_end' && m.stream === sid), 'resume outcome');
  return { reply: r.result, frame: outcome.header?.frame, end: outcome.header ? null : outcome };
}

test('a page that drops comes back to its session through the gateway', async () => {
  const a = await PageClient.connect(gateway.wsUrl);
  const first = await openAndGetToken(a);
  a.ws.terminate(); // the page's link drops; its stream with tesserad is fine
  const b = await PageClient.connect(gateway.wsUrl);
  const { reply, frame } = await resume(b, first.session_token);
  assert.equal(reply.resumed, true);
  assert.ok(frame, 'no frame after the resume');
  assert.equal(frame.session_token, first.session_token);
  assert.ok(frame.sequence > first.sequence, 'the resumed session continues its sequence');
  assert.equal(frame.width, 64);

  const bogus = await resume(b, 'nope');
  assert.equal(bogus.end.ok, false);
  assert.equal(bogus.end.error.code, 'NOT_FOUND');
  b.close();
});

test('a session outlives a gateway that dies: another gateway resumes it from tesserad', async () => {
  const doomed = await startGateway(tesserad.address);
  try {
    const a = await PageClient.connect(doomed.wsUrl);
    const first = await openAndGetToken(a);
    doomed.proc.kill('SIGKILL'); // tesserad sees the connection vanish and parks the session
    const b = await PageClient.connect(gateway.wsUrl);
    let resumed = null;
    for (let i = 0; i < 50 && !resumed; i++) {
      const r = await resume(b, first.session_token);
      if (r.frame) resumed = r;
      else await new Promise((res) => setTimeout(res, 100));
    }
    assert.ok(resumed, 'tesserad never offered the session for resume');
    assert.equal(resumed.reply.resumed, false); // not held by this gateway
    assert.equal(resumed.frame.session_token, first.session_token);
    b.close();
  } finally {
    await doomed.stop();
  }
});

async function uploadFile(page, name, data, chunk = 64 * 1024) {
  const id = page.nextId++;
  const done = page.request('upload', { files: [{ name, size: data.length }] }, id);
  for (let off = 0; off < data.length; off += chunk) {
    page.sendRaw(binaryMessage({ upload: id, file: 0, offset: off }, data.subarray(off, off + chunk)));
  }
  return { id, reply: await done };
}

test('upload: a .glb in chunks, with progress, is loaded and renders; a re-upload is free', async () => {
  const page = await PageClient.connect(gateway.wsUrl);
  const glb = fs.readFileSync(path.join(ASSETS, 'Box/glTF-Binary/Box.glb'));
  const { id, reply } = await uploadFile(page, 'Box.glb', glb, 512);
  assert.ok(reply.ok, JSON.stringify(reply.error));
  assert.match(reply.result.scene_id, /^[0-9a-f]{64}$/);
  assert.equal(reply.result.name, 'Box.glb');
  const phases = page.messages.filter((m) => m.type === 'progress' && m.id === id).map((m) => m.phase);
  assert.deepEqual([...new Set(phases)], ['receiving', 'sending', 'loading']);
  const last = page.messages.filter((m) => m.type === 'progress' && m.id === id && m.phase === 'receiving').pop();
  assert.equal(last.done, glb.length);

  const scenes = await page.request('scenes');
  assert.ok(scenes.result.scenes.some((s) => s.scene_id === reply.result.scene_id));
  const rendered = await page.request('render', { request: { scene_id: reply.result.scene_id, settings: SMALL } });
  assert.ok(rendered.ok);
  const again = await uploadFile(page, 'Box.glb', glb);
  assert.equal(again.reply.result.scene_id, reply.result.scene_id);
  page.close();
});

/**
 * A .glb of one triangle moved by glTF animations `names` (each: translation x 0 -> 1 over
 * `duration` seconds, linear; a name may be undefined: the animation has none).
 */
function animatedGlb(names, duration = 2) {
  const floats = [0, 0, 0, 1, 0, 0, 0, 1, 0, /* times */ 0, duration, /* translations */ 0, 0, 0, 1, 0, 0];
  const bin = Buffer.from(new Float32Array(floats).buffer);
  const gltf = {
    asset: { version: '2.0' },
    buffers: [{ byteLength: bin.length }],
    bufferViews: [
      { buffer: 0, byteOffset: 0, byteLength: 36, target: 34962 },
      { buffer: 0, byteOffset: 36, byteLength: 8 },
      { buffer: 0, byteOffset: 44, byteLength: 24 },
    ],
    accessors: [
      { bufferView: 0, componentType: 5126, count: 3, type: 'VEC3', min: [0, 0, 0], max: [1, 1, 0] },
      { bufferView: 1, componentType: 5126, count: 2, type: 'SCALAR', min: [0], max: [duration] },
      { bufferView: 2, componentType: 5126, count: 2, type: 'VEC3' },
    ],
    meshes: [{ primitives: [{ attributes: { POSITION: 0 } }] }],
    nodes: [{ mesh: 0 }],
    scenes: [{ nodes: [0] }],
    scene: 0,
    animations: names.map((name) => ({
      ...(name === undefined ? {} : { name }),
      channels: [{ sampler: 0, target: { node: 0, path: 'translation' } }],
      samplers: [{ input: 1, output: 2, interpolation: 'LINEAR' }],
    })),
  };
  let json = Buffer.from(JSON.stringify(gltf));
  json = Buffer.concat([json, Buffer.alloc((4 - (json.length % 4)) % 4, 0x20)]);
  const chunk = (type, data) => {
    const head = Buffer.alloc(8);
    head.writeUInt32LE(data.length, 0);
    head.writeUInt32LE(type, 4);
    return Buffer.concat([head, data]);
  };
  const body = Buffer.concat([chunk(0x4e4f534a, json), chunk(0x004e4942, bin)]);
  const header = Buffer.alloc(12);
  header.writeUInt32LE(0x46546c67, 0);
  header.writeUInt32LE(2, 4);
  header.writeUInt32LE(12 + body.length, 8);
  return Buffer.concat([header, body]);
}

test('animations: the scene list names them; a stream plays one and its frames say the time they show', async () => {
  const page = await PageClient.connect(gateway.wsUrl);
  const { reply } = await uploadFile(page, 'Slide.glb', animatedGlb(['Slide', 'Slide', undefined]));
  assert.ok(reply.ok, JSON.stringify(reply.error));
  const sceneId = reply.result.scene_id;
  // The page's Animation section reads SceneInfo.animations from the scene list.
  const listed = (await page.request('scenes')).result.scenes.find((s) => s.scene_id === sceneId);
  assert.deepEqual(listed.animations.map((a) => [a.name, a.duration_s, a.channels]),
    [['Slide', 2, 1], ['Slide', 2, 1], ['animation 2', 2, 1]]);

  const opened = await page.request('open', { open: { scene_id: sceneId, settings: SMALL } });
  const sid = opened.result.stream;
  const frames = () => page.frames.filter((f) => f.header.stream === sid).map((f) => f.header.frame);
  await page.waitFor(() => frames().length > 0, 'the first frame');
  assert.equal(frames()[0].settings.animation, undefined, 'no animation: not named');
  assert.equal(frames()[0].settings.play, false);
  const send = (event) => page.ws.send(JSON.stringify({ id: page.nextId++, op: 'event', stream: sid, event }));
  // The second "Slide" by its index, played from 0.5 s: frames come by themselves (target_fps
  // 0) and their time advances.
  send({ event_id: 2, settings: { animation: '1', scene_time: 0.5, play: true } });
  const playing = await page.waitFor(() => {
    const f = frames().filter((x) => x.event_id >= 2);
    return f.length >= 3 && f;
  }, 'frames of the playing animation');
  assert.equal(playing[0].settings.animation, '1');
  assert.equal(playing[0].settings.play, true);
  const times = playing.map((f) => f.settings.scene_time);
  assert.ok(times[0] >= 0.5 && times.at(-1) > times[0], `times ${times}`);
  // A time set while playing: the clock goes on from there. Pause keeps the time reached.
  send({ event_id: 3, settings: { scene_time: 1.75 } });
  const seek = await page.waitFor(() => frames().find((f) => f.event_id >= 3), 'a frame after the seek');
  assert.ok(seek.settings.scene_time >= 1.75 || seek.settings.scene_time < 0.5, `after the seek: ${seek.settings.scene_time}`);
  send({ event_id: 4, settings: { play: false } });
  const paused = await page.waitFor(() => frames().find((f) => f.event_id >= 4), 'a frame after the pause');
  assert.equal(paused.settings.play, false);
  assert.ok(paused.settings.scene_time >= 0 && paused.settings.scene_time <= 2);
  // An event without animation keeps it; an unknown name ends the stream, naming the field.
  send({ event_id: 5, settings: { loop: false, animation: '' } });
  const kept = await page.waitFor(() => frames().find((f) => f.event_id >= 5), 'a frame after event 5');
  assert.equal(kept.settings.animation, '1');
  assert.equal(kept.settings.loop, false);
  send({ event_id: 6, settings: { animation: 'Walk' } });
  const end = await page.waitFor(() => page.messages.find((m) => m.type === 'stream_end' && m.stream === sid), 'the refused event\'s end');
  assert.equal(end.error.code, 'INVALID_ARGUMENT');
  assert.match(end.error.message, /settings\.animation.*'Slide'/);
  page.close();
});

/** Uploads several files [{name, data}] with `main`; resolves to the reply. */
async function uploadFiles(page, files, main) {
  const id = page.nextId++;
  const done = page.request('upload', { files: files.map((f) => ({ name: f.name, size: f.data.length })), main_file: main }, id);
  files.forEach((f, index) => page.sendRaw(binaryMessage({ upload: id, file: index, offset: 0 }, f.data)));
  return done;
}

test('has_scene: the id the page computes is the server\'s, even for names JavaScript sorts otherwise', async () => {
  const page = await PageClient.connect(gateway.wsUrl);
  const dir = path.join(ASSETS, 'BoxTextured/glTF');
  // Names past U+FFFF sort before U+FF01 in UTF-16 but after it in UTF-8 (the server's order).
  const files = [
    { name: 'BoxTextured.gltf', data: fs.readFileSync(path.join(dir, 'BoxTextured.gltf')) },
    { name: 'BoxTextured0.bin', data: fs.readFileSync(path.join(dir, 'BoxTextured0.bin')) },
    { name: 'CesiumLogoFlat.png', data: fs.readFileSync(path.join(dir, 'CesiumLogoFlat.png')) },
    { name: '\u{1F600}.txt', data: Buffer.from('four-byte UTF-8') },
    { name: '\uFF01.txt', data: Buffer.from('three-byte UTF-8') },
    { name: 'caf\u00e9.txt', data: Buffer.from('two-byte UTF-8') },
  ];
  const plan = { main: 'BoxTextured.gltf', files: files.map((f) => ({ name: f.name, size: f.data.length, entry: { file: new Blob([f.data]) } })) };
  const computed = await computeSceneId(plan, { subtle: webcrypto.subtle });

  const before = await page.request('has_scene', { scene_id: computed });
  assert.ok(before.ok, JSON.stringify(before.error));
  assert.equal(before.result.present, false);
  const uploaded = await uploadFiles(page, files, plan.main);
  assert.ok(uploaded.ok, JSON.stringify(uploaded.error));
  assert.equal(uploaded.result.scene_id, computed);
  const after = await page.request('has_scene', { scene_id: computed });
  assert.equal(after.result.present, true);
  assert.equal(after.result.info.name, 'BoxTextured.gltf');
  assert.equal((await page.request('has_scene', { scene_id: 'demo' })).result.present, true);

  // Untrusted input: only a full id (or "demo") reaches tesserad.
  for (const bad of [computed.slice(0, 8), computed.toUpperCase(), `${computed}0`, 5, null, { toString: 1 }, '']) {
    const reply = await page.request('has_scene', { scene_id: bad });
    assert.equal(reply.ok, false, JSON.stringify(bad));
    assert.equal(reply.error.code, 'INVALID_ARGUMENT');
    assert.match(reply.error.message, /scene_id: .* is not a scene id/);
  }
  page.close();
});

test('upload errors name the field: bad offset, oversize, bad manifest, malformed glTF', async () => {
  const page = await PageClient.connect(gateway.wsUrl);
  const id = page.nextId++;
  const pending = page.request('upload', { files: [{ name: 'a.glb', size: 10 }] }, id);
  page.sendRaw(binaryMessage({ upload: id, file: 0, offset: 4 }, Buffer.alloc(3)));
  const offset = await pending;
  assert.equal(offset.error.code, 'INVALID_ARGUMENT');
  assert.match(offset.error.message, /offset: a\.glb continues at 0, not 4/);

  const big = await page.request('upload', { files: [{ name: 'big.glb', size: 9 * 1024 * 1024 }] });
  assert.equal(big.error.code, 'RESOURCE_EXHAUSTED');
  assert.match(big.error.message, /upload limit/);

  const dup = await page.request('upload', { files: [{ name: 'x.gltf', size: 1 }, { name: 'x.gltf', size: 1 }] });
  assert.match(dup.error.message, /appears twice/);
  const main = await page.request('upload', { files: [{ name: 'x.gltf', size: 1 }], main_file: 'y.gltf' });
  assert.match(main.error.message, /main_file/);

  const junk = await uploadFile(page, 'junk.gltf', Buffer.from('{"asset": 5}'));
  assert.equal(junk.reply.ok, false);
  assert.equal(junk.reply.error.code, 'INVALID_ARGUMENT');
  assert.match(junk.reply.error.message, /junk\.gltf/);
  page.close();
});

test('malformed messages get errors and leave the page and other pages working', async () => {
  const page = await PageClient.connect(gateway.wsUrl);
  const other = await PageClient.connect(gateway.wsUrl);
  const otherStream = await other.request('open', { open: { scene_id: 'demo', settings: SMALL } });
  await other.waitFor(() => other.frames.length > 0, 'other page frame');

  page.sendRaw('not json');
  page.sendRaw('[1,2]');
  page.sendRaw(JSON.stringify({ id: -1, op: 'info' }));
  page.sendRaw(Buffer.from([1, 2]));
  page.sendRaw(binaryMessage({ upload: 12345, file: 0, offset: 0 }, Buffer.alloc(4))); // no such upload: ignored
  await page.waitFor(() => page.messages.filter((m) => m.type === 'error').length >= 4, 'four errors');
  const errors = page.messages.filter((m) => m.type === 'error').map((m) => m.error.message);
  assert.match(errors[0], /not JSON/);
  assert.match(errors[1], /not a JSON object/);
  assert.match(errors[2], /id: wants a positive integer/);
  assert.match(errors[3], /shorter than its 4-byte header/);
  // Values of the wrong type where the gateway quotes or indexes them.
  page.sendRaw(JSON.stringify({ id: 7, op: { toString: 1 } }));
  const upId = 8;
  const up = page.request('upload', { files: [{ name: 'a.glb', size: 100 }] }, upId);
  page.sendRaw(binaryMessage({ upload: { toString: 1 }, file: 0, offset: 0 }, Buffer.alloc(4)));
  page.sendRaw(binaryMessage({ upload: upId, file: { toString: 1 }, offset: { valueOf: 1 } }, Buffer.alloc(4)));
  const upFailed = await up;
  assert.match(upFailed.error.message, /file: no file \{"toString":1\} in this upload/);
  await page.waitFor(() => page.messages.some((m) => m.type === 'error' && /not an upload id/.test(m.error.message)), 'upload id error');
  const unknownOp = await page.request('explode');
  assert.match(unknownOp.error.message, /op: unknown operation "explode"/);
  const badRender = await page.request('render', { request: { scene_id: 5, camera: 'x' } });
  assert.equal(badRender.error.code, 'INVALID_ARGUMENT');
  assert.ok((await page.request('info')).ok);

  other.ws.send(JSON.stringify({ id: 50, op: 'event', stream: otherStream.result.stream, event: { event_id: 3, refresh: true } }));
  await other.waitFor(() => other.frames.some((f) => f.header.frame.event_id === 3), 'other page still served');
  page.close();
  other.close();
});

test('a page that leaves: its session waits out the resume grace period, then ends', async () => {
  const server = await startTesserad(['--resume_grace_s=1']);
  const gw = await startGateway(server.address);
  try {
    const watcher = await PageClient.connect(gw.wsUrl);
    const sessions = async () => (await watcher.request('info')).result.info.active_sessions;
    const page = await PageClient.connect(gw.wsUrl);
    await openAndGetToken(page);
    assert.equal(await sessions(), 1);
    const left = Date.now();
    page.ws.terminate();
    await new Promise((r) => setTimeout(r, 300));
    assert.equal(await sessions(), 1, 'the session ended before its grace period');
    let now = 1;
    while (now !== 0 && Date.now() - left < 10_000) {
      await new Promise((r) => setTimeout(r, 100));
      now = await sessions();
    }
    assert.equal(now, 0, 'the session outlived its grace period');
    assert.ok(Date.now() - left >= 900);
    watcher.close();
  } finally {
    await gw.stop();
    await server.stop();
  }
});

test('a page that closes ends its session at once; one whose link breaks keeps it', async () => {
  const watcher = await PageClient.connect(gateway.wsUrl);
  const sessions = async () => (await watcher.request('info')).result.info.active_sessions;
  const base = await sessions();
  const page = await PageClient.connect(gateway.wsUrl);
  await openAndGetToken(page);
  assert.equal(await sessions(), base + 1);
  page.close(); // a tab closed or reloaded: close handshake, code 1000
  let now = base + 1;
  for (let i = 0; i < 50 && now !== base; i++) {
    await new Promise((r) => setTimeout(r, 100));
    now = await sessions();
  }
  assert.equal(now, base, 'a closed page left its session behind');
  watcher.close();
});

test('raw HTTP: an unparsable target is 400, a foreign Host 421, and the gateway lives on', async () => {
  const raw = (text) => new Promise((resolve, reject) => {
    const sock = net.connect(gateway.port, '127.0.0.1', () => sock.end(text));
    let out = '';
    sock.on('data', (d) => { out += d; });
    sock.on('end', () => resolve(out));
    sock.on('error', reject);
  });
  assert.match(await raw('GET //[ HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n'), /^HTTP\/1\.1 400/);
  // DNS rebinding: a page of evil.example resolved to 127.0.0.1 sends its own name as Host.
  assert.match(await raw('GET / HTTP/1.1\r\nHost: evil.example:8080\r\nConnection: close\r\n\r\n'), /^HTTP\/1\.1 421/);
  await assert.rejects(PageClient.connect(gateway.wsUrl, { headers: { host: 'evil.example' } }), /HTTP 421/);
  assert.match(await raw('GET / HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n'), /^HTTP\/1\.1 200/);
  assert.equal((await fetch(new URL('/healthz', gateway.url))).status, 200);
});

test('pages from another origin are refused; the page and /healthz are served, nothing else', async () => {
  await assert.rejects(PageClient.connect(gateway.wsUrl, { origin: 'http://evil.example' }), /HTTP 403/);
  const same = await PageClient.connect(gateway.wsUrl, { origin: `http://127.0.0.1:${gateway.port}` });
  same.close();

  const index = await fetch(gateway.url);
  assert.equal(index.status, 200);
  assert.match(index.headers.get('content-type'), /text\/html/);
  assert.match(index.headers.get('content-security-policy'), /default-src 'self'/);
  assert.equal((await fetch(new URL('/package.json', gateway.url))).status, 404);
  assert.equal((await fetch(new URL('/%2e%2e/package.json', gateway.url))).status, 404);
  assert.equal((await fetch(gateway.url, { method: 'POST' })).status, 405);
  const health = await fetch(new URL('/healthz', gateway.url));
  assert.equal(health.status, 200);
  assert.equal((await health.json()).ok, true);
});

test('/healthz is 503 and calls are UNAVAILABLE when tesserad is not there', async () => {
  const free = await new Promise((resolve) => {
    const s = net.createServer().listen(0, '127.0.0.1', () => { const p = s.address().port; s.close(() => resolve(p)); });
  });
  const orphan = await startGateway(`127.0.0.1:${free}`);
  try {
    const health = await fetch(new URL('/healthz', orphan.url));
    assert.equal(health.status, 503);
    const page = await PageClient.connect(orphan.wsUrl);
    const reply = await page.request('info');
    assert.equal(reply.error.code, 'UNAVAILABLE');
    assert.match(reply.error.hint, /cannot be reached/);
    page.close();
  } finally {
    await orphan.stop();
  }
});

// Live viewing across replicas (issue 30), through the web gateway: three tesserad processes on
// loopback ports sharing one --scene_store_dir and one gateway with --server a,b,c. Pages are
// plain WebSocket clients speaking the gateway's protocol (no browser).
//   - 8 pages opened at once are spread: no replica holds more than ceil(8/3)+1 sessions (each
//     replica's own GetServerInfo says), and each page's resume token names its replica;
//   - a scene uploaded through replica A (gRPC, directly) renders on B and C, and a page streams
//     it through the gateway wherever it is placed;
//   - SIGKILL of the replica holding the most sessions: every page gets a frame again within 5 s,
//     the moved ones on another replica with the camera and settings they had asked for (the
//     time from the kill to each moved page's first frame is printed as JSON);
//   - the token a moved page holds then resumes on a live replica, through this gateway and
//     through a second one; tokens naming no replica are refused;
//   - a replica that stops answering (SIGSTOP: its connections stay up) loses its sessions to
//     the others after two missed polls;
//   - the viewer page in headless Chromium, streaming H.264, carries on drawing after its
//     replica is killed: it is told of the move, starts a new decoder on the new session's
//     keyframe and says so in its status, with no error.
// Run: node --test tests/web/replicas.test.mjs (TESSERAD=build/default/server/tesserad).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import crypto from 'node:crypto';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {
  ASSETS, PageClient, REPO, TESSERAD, startGateway, startTesserad,
} from '../../clients/web/test/harness.js';
import { loadProto, makeClient, callMetadata } from '../../clients/web/lib/rpc.js';
import { unwrapToken, wrapToken } from '../../clients/web/lib/replicas.js';
import { CHROMIUM, launchChromium, pageLastFrame, waitForPageFrame, watchErrors } from './browser.mjs';

const SMALL = { width: 160, height: 120 };
// The viewer page's screenshots before and after its replica is killed (to look at).
const ARTIFACTS = process.env.TESSERA_WEB_ARTIFACTS || fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-web-artifacts-'));
const PAGES = 8;
const REPLICAS = 3;
const MAX_PER_REPLICA = Math.ceil(PAGES / REPLICAS) + 1;

// The shared scene store is a tesserad flag; an older binary runs the rest without it.
const helpText = (() => {
  try {
    return execFileSync(TESSERAD, ['--helpfull'], { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] });
  } catch (e) {
    return `${e.stdout ?? ''}${e.stderr ?? ''}`;
  }
})();
const STORE = /scene_store_dir/.test(helpText);

let storeDir, replicas = [], gateway, gateway2, api;
// The replica the SIGKILL test killed, for the tests after it (its process's signalCode is set
// only once its exit has been seen, which a loaded machine may not have done yet).
let killed;
const pages = [];  // {page, sid, index}

// The replica a page's token names (the gateway's own token format, lib/replicas.js).
const replicaOfToken = (token, among = replicas) => {
  const { address } = unwrapToken(String(token ?? ''));
  return among.find((r) => r.address === address) ?? null;
};

function unary(r, method, request, deadlineMs = 5000) {
  return new Promise((resolve, reject) => {
    r.client[method](request, callMetadata({}), { deadline: Date.now() + deadlineMs },
      (err, res) => (err ? reject(err) : resolve(res)));
  });
}

async function waitUntil(predicate, what, timeoutMs = 20_000, stepMs = 100) {
  const start = Date.now();
  for (;;) {
    const value = await predicate();
    if (value) return value;
    if (Date.now() - start > timeoutMs) throw new Error(`timed out waiting for ${what}`);
    await new Promise((r) => setTimeout(r, stepMs));
  }
}

/** The gateway's /healthz: every replica listed and ready. */
async function allReady(gw) {
  const res = await fetch(new URL('/healthz', gw.url));
  const body = await res.json();
  return body.replicas?.length === REPLICAS && body.replicas.every((r) => r.ready);
}

const framesOf = (p, sid, after = 0) => p.frames.filter((f) => f.header.stream === sid && f.at >= after);

/** A page whose frames are stamped with their arrival time. */
async function connectPage(gw) {
  const page = await PageClient.connect(gw.wsUrl);
  const push = page.frames.push.bind(page.frames);
  page.frames.push = (frame) => push({ ...frame, at: performance.now() });
  return page;
}

before(async () => {
  if (!STORE) console.log('# tesserad has no --scene_store_dir yet: the shared-store part is skipped');
  storeDir = fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-replicas-store-'));
  const args = STORE ? [`--scene_store_dir=${storeDir}`] : [];
  replicas = await Promise.all(Array.from({ length: REPLICAS }, () => startTesserad(args)));
  ({ api } = loadProto(path.join(REPO, 'proto')));
  for (const r of replicas) r.client = makeClient(api, r.address, {});
  gateway = await startGateway(replicas.map((r) => r.address).join(','));
  await waitUntil(() => allReady(gateway), 'the gateway to see every replica ready');
});

after(async () => {
  if (process.env.TESSERA_TEST_VERBOSE) console.log(gateway?.log());
  for (const { page } of pages) page.close();
  await gateway2?.stop();
  await gateway?.stop();
  for (const r of replicas) r.client?.close();
  await Promise.all(replicas.map((r) => r.stop()));
  fs.rmSync(storeDir, { recursive: true, force: true });
});

test(`${PAGES} pages opened at once are spread over the replicas`, async () => {
  const opened = await Promise.all(Array.from({ length: PAGES }, async (_, index) => {
    const page = await connectPage(gateway);
    const reply = await page.request('open', { open: { scene_id: 'demo', settings: SMALL } });
    assert.ok(reply.ok, JSON.stringify(reply.error));
    const sid = reply.result.stream;
    await page.waitFor(() => framesOf(page, sid).length > 0, `page ${index}'s first frame`, 30_000);
    return { page, sid, index };
  }));
  pages.push(...opened);
  const byTokens = replicas.map((r) => pages.filter((p) => replicaOfToken(framesOf(p.page, p.sid).at(-1).header.frame.session_token) === r).length);
  const infos = await Promise.all(replicas.map((r) => unary(r, 'GetServerInfo', {})));
  const sessions = infos.map((i) => i.active_sessions);
  console.log(`# sessions per replica: ${JSON.stringify(sessions)} (by the pages' tokens: ${JSON.stringify(byTokens)})`);
  assert.deepEqual(byTokens, sessions, 'each token names the replica that holds the session');
  assert.equal(sessions.reduce((a, b) => a + b, 0), PAGES);
  for (const n of sessions) assert.ok(n <= MAX_PER_REPLICA, `a replica holds ${n} sessions (> ${MAX_PER_REPLICA})`);
  if (STORE) for (const i of infos) assert.equal(i.scene_store, true);
});

test('a scene uploaded through one replica renders on the others', { skip: !STORE && 'tesserad lacks --scene_store_dir' }, async () => {
  const file = path.join(ASSETS, 'Box/glTF-Binary/Box.glb');
  const data = fs.readFileSync(file);
  const sha256 = crypto.createHash('sha256').update(data).digest('hex');
  const [a, b, c] = replicas;
  const info = await new Promise((resolve, reject) => {
    const call = a.client.UploadScene(callMetadata({}), (err, res) => (err ? reject(err) : resolve(res)));
    call.write({ manifest: { files: [{ name: 'Box.glb', size: data.length, sha256 }], main_file: 'Box.glb' } });
    call.write({ chunk: { file_index: 0, offset: 0, data } });
    call.end();
  });
  assert.match(info.scene_id, /^[0-9a-f]{64}$/);
  assert.equal((await unary(c, 'HasScene', { scene_id: info.scene_id })).present, true, 'C does not see the store');
  const frame = await unary(b, 'Render', { scene_id: info.scene_id, settings: SMALL }, 30_000);
  assert.equal(frame.scene_id, info.scene_id);
  assert.equal(frame.width, 160);
  // Through the gateway: wherever the session is placed, it streams.
  const page = await connectPage(gateway);
  const reply = await page.request('open', { open: { scene_id: info.scene_id, settings: SMALL } });
  assert.ok(reply.ok, JSON.stringify(reply.error));
  const first = await page.waitFor(() => framesOf(page, reply.result.stream)[0], 'a frame of the uploaded scene', 30_000);
  assert.equal(first.header.frame.scene_id, info.scene_id);
  console.log(`# uploaded on ${a.address}, rendered on ${b.address}, streamed from ${replicaOfToken(first.header.frame.session_token)?.address}`);
  await page.request('close', { stream: reply.result.stream });
  await page.waitFor(() => page.messages.find((m) => m.type === 'stream_end'), 'the stream to end');
  page.close();
});

test('SIGKILL of a replica: every page gets frames again within 5 s, moved ones with their camera and settings', async () => {
  assert.equal(pages.length, PAGES, 'the spreading test opened the pages');
  // Each page asks for its own camera and FXAA, so the move must carry the state.
  await Promise.all(pages.map(async (p) => {
    const eventId = 10 + p.index;
    p.eye = { x: 3 + p.index, y: 4, z: 5 };
    p.page.ws.send(JSON.stringify({ id: 1000, op: 'event', stream: p.sid, event: {
      event_id: eventId, camera: { look_at: { eye: p.eye, target: { x: 0, y: 0, z: 0 } } }, settings: { aa: 'AA_FXAA' } } }));
    await p.page.waitFor(() => framesOf(p.page, p.sid).find((f) => f.header.frame.event_id === eventId), `page ${p.index}'s event`);
  }));
  const holder = (p) => replicaOfToken(framesOf(p.page, p.sid).at(-1).header.frame.session_token);
  const counts = replicas.map((r) => pages.filter((p) => holder(p) === r).length);
  const victim = replicas[counts.indexOf(Math.max(...counts))];
  const moved = pages.filter((p) => holder(p) === victim);
  const stayed = pages.filter((p) => holder(p) !== victim);
  assert.ok(moved.length > 0);

  const killedAt = performance.now();
  victim.proc.kill('SIGKILL');
  killed = victim;
  // The others render on change only: a refresh shows they still stream.
  for (const p of stayed) {
    p.page.ws.send(JSON.stringify({ id: 1001, op: 'event', stream: p.sid, event: { event_id: 100, refresh: true } }));
  }
  const times = await Promise.all(pages.map(async (p) => {
    const f = await p.page.waitFor(() => framesOf(p.page, p.sid, killedAt).find((x) => replicaOfToken(x.header.frame.session_token) !== victim),
      `page ${p.index}'s frame after the kill`, 5000);
    return { p, ms: f.at - killedAt, frame: f.header.frame };
  }));
  for (const { p, ms, frame } of times) {
    assert.ok(ms < 5000, `page ${p.index} waited ${ms} ms`);
    const on = replicaOfToken(frame.session_token);
    assert.ok(on && on !== victim, `page ${p.index}'s frame is not from a live replica`);
    assert.ok(Math.abs(frame.camera.eye.x - p.eye.x) < 1e-3, `page ${p.index} lost its camera: ${JSON.stringify(frame.camera.eye)}`);
    assert.equal(frame.settings.aa, 'AA_FXAA', `page ${p.index} lost its settings`);
    assert.equal(frame.width, 160);
  }
  for (const p of moved) {
    const note = p.page.messages.find((m) => m.type === 'stream_moved' && m.stream === p.sid);
    assert.ok(note, `page ${p.index} was not told of the move`);
    assert.equal(note.from, victim.address);
    assert.notEqual(note.to, victim.address);
    assert.ok(!p.page.messages.some((m) => m.type === 'stream_end' && m.stream === p.sid), 'a moved stream ended');
  }
  const movedMs = times.filter(({ p }) => moved.includes(p)).map(({ ms }) => ms).sort((a, b) => a - b);
  const figure = {
    replicas: REPLICAS,
    pages: PAGES,
    moved_sessions: moved.length,
    kill_to_first_frame_ms: {
      median: Number(movedMs[Math.floor(movedMs.length / 2)].toFixed(1)),
      max: Number(movedMs.at(-1).toFixed(1)),
      each: movedMs.map((x) => Number(x.toFixed(1))),
    },
  };
  console.log(`# failover ${JSON.stringify(figure)}`);
  const live = replicas.filter((r) => r !== victim);
  const sessions = (await Promise.all(live.map((r) => unary(r, 'GetServerInfo', {})))).map((i) => i.active_sessions);
  assert.equal(sessions.reduce((a, b) => a + b, 0), PAGES, `the live replicas hold ${JSON.stringify(sessions)}`);
  for (const n of sessions) assert.ok(n <= Math.ceil(PAGES / live.length) + 1, `a live replica holds ${n}`);
});

test('after the kill, a moved page\'s token resumes on a live replica, through this gateway or another', async () => {
  const victim = killed;
  const moved = pages.filter((p) => p.page.messages.some((m) => m.type === 'stream_moved' && m.stream === p.sid));
  assert.ok(victim && moved.length > 0);

  // Through another gateway (its page reconnected elsewhere): routed by the token's replica.
  gateway2 = await startGateway(replicas.map((r) => r.address).join(','));
  await waitUntil(async () => {
    const body = await (await fetch(new URL('/healthz', gateway2.url))).json();
    return body.replicas?.filter((r) => r.ready).length === REPLICAS - 1;
  }, 'the second gateway to poll the replicas');
  const a = moved[0];
  const token = framesOf(a.page, a.sid).at(-1).header.frame.session_token;
  const home = replicaOfToken(token);
  assert.ok(home && home !== victim);
  const page2 = await connectPage(gateway2);
  const r2 = await page2.request('open', { open: { resume_token: token } });
  assert.ok(r2.ok, JSON.stringify(r2.error));
  assert.equal(r2.result.resumed, false, 'not held by the second gateway');
  const f2 = await page2.waitFor(() => framesOf(page2, r2.result.stream)[0], 'a frame of the resumed session', 10_000);
  assert.equal(replicaOfToken(f2.header.frame.session_token), home, 'the resume went to another replica');
  assert.equal(f2.header.frame.session_token, token, 'the same session');
  // The first gateway's stream lost its session to the resume: an end, never a move.
  const end = await a.page.waitFor(() => a.page.messages.find((m) => m.type === 'stream_end' && m.stream === a.sid), 'the taken-over stream to end');
  assert.equal(end.error?.code, 'ABORTED');
  page2.close();

  // Through this gateway, after the page's link broke (the stream waited here).
  if (moved.length > 1) {
    const b = moved[1];
    const tokenB = framesOf(b.page, b.sid).at(-1).header.frame.session_token;
    b.page.ws.terminate();
    const back = await connectPage(gateway);
    const rb = await back.request('open', { open: { resume_token: tokenB } });
    assert.ok(rb.ok, JSON.stringify(rb.error));
    assert.equal(rb.result.resumed, true);
    const fb = await back.waitFor(() => framesOf(back, rb.result.stream)[0], 'a frame after taking the stream over', 10_000);
    assert.notEqual(replicaOfToken(fb.header.frame.session_token), victim);
    back.close();
  }

  // Tokens a page makes up: an address that is no replica is never dialled; junk is refused.
  const probe = await connectPage(gateway);
  const foreign = await probe.request('open', { open: { resume_token: wrapToken('127.0.0.1:1', '0'.repeat(32)) } });
  assert.equal(foreign.error?.code, 'NOT_FOUND');
  assert.match(foreign.error.message, /open\.resume_token/);
  const junk = await probe.request('open', { open: { resume_token: 'not a token' } });
  assert.equal(junk.error?.code, 'INVALID_ARGUMENT');
  assert.match(junk.error.message, /open\.resume_token/);
  // A token of the dead replica: the session is gone with it; the page then opens afresh.
  const dead = await probe.request('open', { open: { resume_token: wrapToken(victim.address, '0'.repeat(32)) } });
  if (dead.ok) {
    const endDead = await probe.waitFor(() => probe.messages.find((m) => m.type === 'stream_end' && m.stream === dead.result.stream), 'the dead replica\'s resume to fail');
    assert.equal(endDead.ok, false);
  } else {
    assert.match(dead.error.code, /UNAVAILABLE|NOT_FOUND/);
  }
  probe.close();
});

test('a replica that stops answering (SIGSTOP) loses its sessions to the others within seconds', async () => {
  const victim = killed;
  const live = replicas.filter((r) => r !== victim);
  // The pages whose streams are still open, and the live replica with most of them.
  const open = pages.filter((p) => p.page.ws.readyState === 1 &&
    !p.page.messages.some((m) => m.type === 'stream_end' && m.stream === p.sid));
  const holder = (p) => replicaOfToken(framesOf(p.page, p.sid).at(-1).header.frame.session_token);
  const counts = live.map((r) => open.filter((p) => holder(p) === r).length);
  const frozen = live[counts.indexOf(Math.max(...counts))];
  const onIt = open.filter((p) => holder(p) === frozen);
  assert.ok(onIt.length > 0, 'no open stream on a live replica');
  const stoppedAt = performance.now();
  frozen.proc.kill('SIGSTOP');  // its connections stay up; only its answers stop
  try {
    const times = await Promise.all(onIt.map(async (p) => {
      const f = await p.page.waitFor(() => framesOf(p.page, p.sid, stoppedAt).find((x) => replicaOfToken(x.header.frame.session_token) !== frozen),
        `page ${p.index}'s frame from another replica`, 10_000);
      return f.at - stoppedAt;
    }));
    for (const p of onIt) {
      const note = p.page.messages.filter((m) => m.type === 'stream_moved' && m.stream === p.sid).at(-1);
      assert.equal(note.from, frozen.address);
      assert.match(note.reason, /stopped answering/);
    }
    console.log(`# a replica that stops answering: sessions moved after ${JSON.stringify(times.map((t) => Math.round(t)))} ms (two missed polls)`);
    assert.ok(Math.max(...times) < 8000);
  } finally {
    frozen.proc.kill('SIGKILL');
  }
});

test('the viewer page (H.264) carries on after its replica is killed: a note, a new decoder, no error', { skip: !fs.existsSync(CHROMIUM) && `no ${CHROMIUM}` }, async () => {
  const pair = await Promise.all([startTesserad(), startTesserad()]);
  const gw = await startGateway(pair.map((r) => r.address).join(','));
  let browser;
  try {
    await waitUntil(async () => {
      const body = await (await fetch(new URL('/healthz', gw.url))).json();
      return body.replicas?.filter((r) => r.ready).length === 2;
    }, 'the gateway to see both replicas');
    browser = await launchChromium();
    const context = await browser.newContext({ viewport: { width: 480, height: 320 } });
    await context.addInitScript(() => localStorage.setItem('tessera.video', JSON.stringify({ codec: 'h264', crf: 23, interactive_crf: 29 })));
    const page = await context.newPage();
    const errors = [];
    watchErrors(page, errors);
    await page.goto(gw.url);
    const first = await waitForPageFrame(page, (f) => f.encoding === 'VIDEO_H264', 'an H.264 frame', 30_000);
    const home = replicaOfToken(first.session_token, pair);
    assert.ok(home, `the token ${first.session_token} names no replica`);
    const other = pair.find((r) => r !== home);
    const drawn = await page.evaluate(() => window.tessera.frames);
    fs.mkdirSync(ARTIFACTS, { recursive: true });
    await page.screenshot({ path: path.join(ARTIFACTS, 'replicas-1-before-kill.png') });
    home.proc.kill('SIGKILL');
    const after = await waitForPageFrame(page, (f) => replicaOfToken(f.session_token, pair) === other, 'a frame from the other replica', 10_000);
    assert.equal(after.encoding, 'VIDEO_H264');
    assert.equal(await page.evaluate(() => window.tessera.moves), 1);
    // The new decoder started on the new session's first frame, a keyframe: nothing to ask for.
    assert.equal(await page.evaluate(() => window.tessera.keyframeRequests), 0);
    assert.ok(await page.evaluate(() => window.tessera.frames) > drawn);
    assert.match(await page.evaluate(() => window.tessera.status), /moved to another render server/);
    await page.screenshot({ path: path.join(ARTIFACTS, 'replicas-2-after-move.png') });
    console.log(`# screenshots in ${ARTIFACTS}`);
    assert.deepEqual(await page.evaluate(() => window.tessera.errors.map((e) => String(e.message ?? e))), []);
    assert.deepEqual(errors, []);
    assert.equal((await pageLastFrame(page)).width, after.width);
  } finally {
    await browser?.close();
    await gw.stop();
    await Promise.all(pair.map((r) => r.stop()));
  }
});

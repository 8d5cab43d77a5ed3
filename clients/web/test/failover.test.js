// Failover of a page's stream (lib/session.js, lib/streams.js BridgedStream, and the page's
// stream_moved in lib/connection.js) with fake replicas: the state kept for a move, when a
// stream moves and when it ends, the budget of moves, and what the page sees.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { EventEmitter } from 'node:events';
import path from 'node:path';
import { loadProto } from '../lib/rpc.js';
import { ReplicaSet, replicaTag } from '../lib/replicas.js';
import { BridgedStream } from '../lib/streams.js';
import { Connection, UploadBudget } from '../lib/connection.js';
import {
  MoveBudget, completeState, failoverDecision, followPlay, mergeEvent, openFromState, seenInFrame, stateFromOpen,
} from '../lib/session.js';
import { REPO, splitBinary } from './harness.js';

const { definition } = loadProto(path.join(REPO, 'proto'));
const STREAM = definition['tessera.v1.RenderService'].Stream;
/** A ClientEvent as the gateway keeps it: checked and parsed back by the proto. */
const norm = (event) => STREAM.requestDeserialize(STREAM.requestSerialize(event));

const UNAVAILABLE = 14;
const tick = () => new Promise((r) => setImmediate(r));

test('state: the open, then every event as tesserad applies it (camera replaces; settings, interactive, video merge set fields)', () => {
  let state = stateFromOpen(norm({ open: {
    scene_id: 'demo', settings: { width: 160, height: 120, aa: 'AA_MSAA', samples: 4 },
    interactive: { enabled: true, render_scale: 0.5 }, target_fps: 0,
  } }).open);
  assert.deepEqual(state, {
    scene_id: 'demo',
    settings: { width: 160, height: 120, aa: 'AA_MSAA', samples: 4 },
    interactive: { enabled: true, render_scale: 0.5 },
  });
  const eye = { x: 1, y: 2, z: 3 };
  state = mergeEvent(state, norm({ event_id: 2, camera: { look_at: { eye, target: { x: 0, y: 0, z: 0 } } } }));
  state = mergeEvent(state, norm({ event_id: 3, settings: { aa: 'AA_FXAA', shadows: false, exposure_ev: 0 } }));
  // Unset enums (UNSPECIFIED), absent fields and refresh/keyframe change nothing.
  state = mergeEvent(state, norm({ event_id: 4, settings: { aa: 'AA_MODE_UNSPECIFIED', width: 200 }, refresh: true, keyframe: true }));
  state = mergeEvent(state, norm({ event_id: 5, interactive: { jpeg_quality: 40 }, video: { codec: 'VIDEO_CODEC_H264', crf: 30 } }));
  state = mergeEvent(state, norm({ event_id: 6, video: { crf: 20 }, target_fps: 30 }));
  state = mergeEvent(state, norm({ event_id: 7, camera: { frame: {} } }));  // reset view: replaces
  assert.deepEqual(state.camera, { frame: { direction: null } });
  assert.deepEqual(state.settings, { width: 200, height: 120, aa: 'AA_FXAA', samples: 4, shadows: false, exposure_ev: 0 });
  assert.deepEqual(state.interactive, { enabled: true, render_scale: 0.5, jpeg_quality: 40 });
  assert.deepEqual(state.video, { codec: 'VIDEO_CODEC_H264', crf: 20 });
  assert.equal(state.target_fps, 30);
  assert.equal(mergeEvent(state, norm({ target_fps: 0 })).target_fps, undefined);
  assert.equal(mergeEvent(state, norm({ event_id: 8 })).target_fps, 30, 'an event without target_fps keeps it');
  // The open that carries it is a valid OpenSession without a resume token.
  const open = openFromState(state);
  assert.equal(open.resume_token, undefined);
  const again = norm({ open }).open;
  assert.equal(again.settings.aa, 'AA_FXAA');
  assert.equal(again.video.crf, 20);
  assert.equal(again.target_fps, 30);
  // The state never aliases what it was merged from.
  const before = JSON.stringify(state);
  mergeEvent(state, norm({ settings: { width: 1 } }));
  assert.equal(JSON.stringify(state), before);
});

test('state: the animation (a string) is remembered until an event names another; an empty one keeps it', () => {
  let state = stateFromOpen(norm({ open: { scene_id: 'demo', settings: { width: 64, animation: '' } } }).open);
  assert.deepEqual(state.settings, { width: 64 }, 'an empty animation in the open is none: not carried');
  state = mergeEvent(state, norm({ event_id: 2, settings: { animation: 'Walk', scene_time: 0, play: true } }));
  assert.deepEqual(state.settings, { width: 64, animation: 'Walk', scene_time: 0, play: true });
  state = mergeEvent(state, norm({ event_id: 3, settings: { loop: false } }));
  assert.equal(state.settings.animation, 'Walk', 'an event without animation leaves it');
  state = mergeEvent(state, norm({ event_id: 4, settings: { animation: '', scene_time: 1.5 } }));
  assert.equal(state.settings.animation, 'Walk', 'an empty animation leaves it (tesserad: unchanged)');
  assert.equal(state.settings.scene_time, 1.5);
  state = mergeEvent(state, norm({ event_id: 5, settings: { play: false } }));
  assert.deepEqual(state.settings, { width: 64, animation: 'Walk', scene_time: 1.5, play: false, loop: false });
  state = mergeEvent(state, norm({ event_id: 6, settings: { animation: 'none' } }));
  assert.equal(state.settings.animation, 'none');
  const again = norm({ open: openFromState(state) }).open;
  assert.equal(again.settings.animation, 'none');
  assert.equal(again.settings.play, false);
  assert.equal(again.settings.loop, false);
  // An empty VideoSettings.preset is not "unchanged" (tesserad refuses it): kept as sent.
  assert.equal(mergeEvent(state, norm({ video: { preset: '' } })).video.preset, '');
});

test('followPlay: a playing animation\'s state takes the time its newest frames show', () => {
  const state = { scene_id: 'demo', settings: { animation: 'Walk', scene_time: 0.5, play: true } };
  const frame = (event_id, settings) => ({ event_id, settings: { loop: true, ...settings } });
  const moved = followPlay(state, frame(4, { play: true, scene_time: 1.25 }), 4);
  assert.deepEqual(moved.settings, { animation: 'Walk', scene_time: 1.25, play: true });
  assert.equal(state.settings.scene_time, 0.5, 'not changed in place');
  // A frame older than the page's newest event (which may set the time) does not count.
  assert.equal(followPlay(state, frame(3, { play: true, scene_time: 1.25 }), 4), state);
  // Shown stopped while asked to play (tesserad stopped it at the end of a non-looping
  // animation): the state stops there too, so a move does not play it again.
  assert.deepEqual(followPlay(state, frame(4, { play: false, scene_time: 2 }), 4).settings,
    { animation: 'Walk', scene_time: 2, play: false });
  assert.equal(followPlay(state, frame(3, { play: false, scene_time: 2 }), 4), state, 'an older frame');
  // Paused (asked), or a frame without settings: the state as it is.
  const paused = { scene_id: 'demo', settings: { scene_time: 0.5, play: false } };
  assert.equal(followPlay(paused, frame(4, { play: true, scene_time: 1.25 }), 4), paused);
  assert.equal(followPlay({ scene_id: 'demo' }, frame(4, { play: true, scene_time: 1 }), 4).settings, undefined);
  assert.equal(followPlay(state, { event_id: 4 }, 4), state);
});

test('state of a resumed session: what the page resends, completed by what its frames say', () => {
  const seen = seenInFrame({ scene_id: 'ab'.repeat(32), camera: { eye: { x: 1, y: 1, z: 1 }, target: { x: 0, y: 0, z: 0 } }, yfov: 0.7, encoding: 'VIDEO_H264' });
  assert.deepEqual(completeState({ scene_id: '' }, seen), {
    scene_id: 'ab'.repeat(32),
    camera: { look_at: { eye: { x: 1, y: 1, z: 1 }, target: { x: 0, y: 0, z: 0 } }, yfov: 0.7 },
    video: { codec: 'VIDEO_CODEC_H264' },
  });
  const page = { scene_id: '', camera: { look_at: { eye: { x: 5, y: 5, z: 5 } } }, video: { codec: 'VIDEO_CODEC_JPEG' } };
  const done = completeState(page, seen);
  assert.deepEqual(done.camera, page.camera, 'the page\'s camera wins');
  assert.equal(done.video.codec, 'VIDEO_CODEC_JPEG');
});

test('failover decisions: only a lost replica moves a stream, and only while the page is there', () => {
  const lost = { code: UNAVAILABLE, details: 'Connection dropped' };
  assert.equal(failoverDecision(lost), 'move');
  for (const code of [0, 1, 3, 5, 8, 9, 10, 13, 16]) assert.equal(failoverDecision({ code }), 'end', `code ${code}`);
  assert.equal(failoverDecision(lost, { closing: true }), 'end');
  assert.equal(failoverDecision(lost, { cancelled: true }), 'end');
  assert.equal(failoverDecision(lost, { parked: true }), 'end');
  assert.equal(failoverDecision(lost, { stopping: true }), 'end');
  assert.equal(failoverDecision(lost, { single: true }), 'end');
  assert.equal(failoverDecision(lost, { sceneKnown: false }), 'end');
  assert.equal(failoverDecision(lost, { budgetLeft: false }), 'give_up');
  assert.equal(failoverDecision(null), 'end');
  // A replica found full at admission: moves like a lost one; other RESOURCE_EXHAUSTED ends.
  assert.equal(failoverDecision({ code: 8 }, { full: true }), 'move');
  assert.equal(failoverDecision({ code: 8 }, { full: false }), 'end');
  assert.equal(failoverDecision({ code: 3 }, { full: true }), 'end');

  let now = 0;
  const budget = new MoveBudget({ max: 3, windowMs: 60_000, now: () => now });
  assert.deepEqual([budget.take(), budget.take(), budget.take(), budget.take()], [true, true, true, false]);
  now = 59_999;
  assert.equal(budget.left, 0);
  now = 60_001;
  assert.equal(budget.left, 3);
});

/** Replicas with fake clients whose Stream calls the test drives. */
async function fakeReplicas(addresses, infos = {}) {
  const calls = [];  // {address, call}
  const set = new ReplicaSet({
    spec: addresses.join(','),
    log: () => {},
    makeClient: (address) => ({
      GetServerInfo(_r, _m, _o, cb) {
        setImmediate(() => {
          const v = infos[address] ?? { serving: true, accepting_sessions: true, active_sessions: 0, limits: { max_sessions: 8 } };
          if (v instanceof Error) cb(v);
          else cb(null, v);
        });
      },
      Stream() {
        const call = new EventEmitter();
        call.written = [];
        call.write = (e) => { call.written.push(e); return true; };
        call.end = () => { call.ended = true; };
        call.cancel = () => { call.cancelled = true; };
        calls.push({ address, call });
        return call;
      },
      close() {},
    }),
  });
  await set.start();
  set.stop();
  return { set, calls, infos };
}

function sink() {
  const s = { frames: [], ends: [], moves: [] };
  s.frame = (frame, videoSeq) => s.frames.push({ frame, videoSeq });
  s.end = (status) => s.ends.push(status);
  s.moved = (info) => s.moves.push(info);
  return s;
}

const makeStream = (set, logs = []) => new BridgedStream({ replicas: set, metadata: () => ({}), log: (l) => logs.push(l) }, { label: 'test stream' });

/** A page stream opened on scene demo, and the page's sink. */
async function opened(set) {
  const stream = makeStream(set);
  const page = sink();
  stream.attach(page);
  await stream.open(norm({ open: { scene_id: 'demo' } }));
  return { stream, page };
}

test('a stream whose replica is lost reopens its session elsewhere with what it was asked for', async () => {
  const { set, calls, infos } = await fakeReplicas(['a:1', 'b:1', 'c:1']);
  const logs = [];
  const stream = makeStream(set, logs);
  const page = sink();
  stream.attach(page);
  await stream.open(norm({ event_id: 1, open: { scene_id: 'demo', settings: { width: 160, height: 120 } } }));
  const first = calls[0];
  assert.deepEqual(first.call.written[0], { event_id: 1, open: { scene_id: 'demo', settings: { width: 160, height: 120 } } });
  first.call.emit('data', { sequence: 1, session_token: 'aaaa', scene_id: 'demo' });
  assert.equal(page.frames[0].frame.session_token, `${replicaTag(first.address)}.aaaa`);
  const event = { event_id: 7, camera: { look_at: { eye: { x: 3, y: 4, z: 5 }, target: { x: 0, y: 0, z: 0 } } }, settings: { aa: 'AA_FXAA' } };
  stream.write(event, norm(event));
  assert.deepEqual(first.call.written[1], event);

  infos[first.address] = Object.assign(new Error('gone'), { code: UNAVAILABLE, details: 'connect ECONNREFUSED' });
  first.call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  await tick();
  assert.equal(calls.length, 2);
  const second = calls[1];
  assert.notEqual(second.address, first.address);
  const reopen = second.call.written[0];
  assert.equal(reopen.event_id, 7, 'the newest event id: the page measures latency and camera resets by it');
  assert.equal(reopen.open.resume_token, undefined);
  assert.equal(reopen.open.scene_id, 'demo');
  assert.deepEqual(reopen.open.settings, { width: 160, height: 120, aa: 'AA_FXAA' });
  assert.deepEqual(reopen.open.camera.look_at.eye, { x: 3, y: 4, z: 5 });
  assert.deepEqual(page.moves, [{ from: first.address, to: second.address, reason: `replica ${first.address} lost: Connection dropped`, moves: 1 }]);
  assert.deepEqual(page.ends, []);
  assert.equal(set.byAddress.get(first.address).ready, false, 'no new sessions go to the lost replica');
  // Frames of the new session carry its token; the old call is not listened to any more.
  first.call.emit('data', { sequence: 9, session_token: 'late' });
  second.call.emit('data', { sequence: 1, session_token: 'bbbb', scene_id: 'demo' });
  assert.deepEqual(page.frames.map((f) => f.frame.sequence), [1, 1]);
  assert.equal(stream.token, `${replicaTag(second.address)}.bbbb`);
  assert.deepEqual(stream.tokens, [`${replicaTag(second.address)}.bbbb`, `${replicaTag(first.address)}.aaaa`]);
  // Events go to the new call.
  stream.write({ event_id: 8, refresh: true });
  assert.deepEqual(second.call.written.at(-1), { event_id: 8, refresh: true });
  assert.ok(logs.some((l) => /moved from a:1|moved from b:1|moved from c:1/.test(l)), logs.join('\n'));
  assert.ok(logs.some((l) => /first frame from .*ms after the loss/.test(l)), logs.join('\n'));
});

test('a playing animation survives a move: its animation, play and loop, from the time its frames had reached', async () => {
  const { set, calls, infos } = await fakeReplicas(['a:1', 'b:1', 'c:1']);
  const stream = makeStream(set);
  const page = sink();
  stream.attach(page);
  await stream.open(norm({ event_id: 1, open: { scene_id: 'demo', settings: { width: 160, height: 120 } } }));
  const first = calls[0];
  const play = { event_id: 2, settings: { animation: 'Walk', scene_time: 0.25, play: true, loop: false } };
  stream.write(play, norm(play));
  // The clock runs on the replica: its frames say the time they show.
  const shown = (event_id, scene_time) => ({ sequence: event_id, session_token: 't', scene_id: 'demo', event_id,
    settings: { width: 160, height: 120, scene_time, play: true, loop: false, animation: 'Walk' } });
  first.call.emit('data', shown(1, 0));
  first.call.emit('data', shown(2, 0.75));
  first.call.emit('data', shown(2, 1.5));
  // An event without animation settings leaves them as they are.
  const other = { event_id: 3, settings: { exposure_ev: 1 } };
  stream.write(other, norm(other));
  first.call.emit('data', shown(2, 1.55));  // before event 3: does not count
  infos[first.address] = Object.assign(new Error('gone'), { code: UNAVAILABLE, details: 'connect ECONNREFUSED' });
  first.call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  await tick();
  assert.equal(calls.length, 2);
  const reopen = calls[1].call.written[0];
  assert.deepEqual(reopen.open.settings,
    { width: 160, height: 120, animation: 'Walk', scene_time: 1.5, play: true, loop: false, exposure_ev: 1 });
  assert.equal(norm(reopen).open.settings.animation, 'Walk', 'a valid OpenSession');

  // On the new replica: the page sets a time; until frames show it, they do not move it back.
  const second = calls[1];
  const seek = { event_id: 4, settings: { scene_time: 0.5 } };
  stream.write(seek, norm(seek));
  second.call.emit('data', { ...shown(3, 1.6), sequence: 1 });
  second.call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  await tick();
  const last = calls.at(-1);
  assert.notEqual(last, second, 'moved again');
  assert.equal(last.call.written[0].open.settings.scene_time, 0.5, 'the time the page set wins');
  assert.equal(last.call.written[0].open.settings.play, true);
});

test('normal ends never move: OK, errors of the request, a page that closed or cancelled', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1']);
  for (const [status, prep] of [
    [{ code: 0, details: 'OK' }, () => {}],
    [{ code: 3, details: 'settings.width: 0 is out of range' }, () => {}],
    [{ code: 5, details: 'open.scene_id: unknown scene' }, () => {}],
    [{ code: 10, details: 'resumed elsewhere' }, () => {}],
    [{ code: UNAVAILABLE, details: 'closing' }, (s) => s.end()],
    [{ code: UNAVAILABLE, details: 'cancelled' }, (s) => s.cancel()],
  ]) {
    const stream = makeStream(set);
    const page = sink();
    stream.attach(page);
    await stream.open(norm({ open: { scene_id: 'demo' } }));
    const { call } = calls.at(-1);
    call.emit('data', { sequence: 1, session_token: 't' });
    prep(stream);
    const before = calls.length;
    call.emit('status', status);
    await tick();
    assert.equal(calls.length, before, `moved on ${status.details}`);
    assert.deepEqual(page.ends, [status]);
    assert.deepEqual(page.moves, []);
  }
});

test('a parked stream (its page away) and a resume that never had a frame end instead of moving', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1']);
  const parked = makeStream(set);
  await parked.open(norm({ open: { scene_id: 'demo' } }));
  let ended = false;
  parked.onEnded = () => { ended = true; };
  calls.at(-1).call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  await tick();
  assert.equal(ended, true);
  assert.equal(calls.length, 1);

  const resumed = makeStream(set);
  const page = sink();
  resumed.attach(page);
  await resumed.open(norm({ event_id: 4, open: { resume_token: 'x' } }), { replica: set.byAddress.get('b:1'), token: 'inner' });
  assert.deepEqual(calls.at(-1).call.written[0], { event_id: 4, open: { resume_token: 'inner' } });
  calls.at(-1).call.emit('status', { code: UNAVAILABLE, details: 'No connection established' });
  await tick();
  assert.equal(page.ends.length, 1, 'the page opens afresh itself');
  assert.equal(calls.length, 2);
});

test('a resumed session that loses its replica moves with the scene and camera its frames showed', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1']);
  const stream = makeStream(set);
  const page = sink();
  stream.attach(page);
  await stream.open(norm({ open: { resume_token: 'x' } }), { replica: set.byAddress.get('a:1'), token: 'inner' });
  const scene = 'cd'.repeat(32);
  calls[0].call.emit('data', { sequence: 40, session_token: 'inner', scene_id: scene, camera: { eye: { x: 9, y: 9, z: 9 }, target: { x: 0, y: 0, z: 0 } }, yfov: 0.6 });
  const resync = { event_id: 3, settings: { width: 320, height: 240 } };
  stream.write(resync, norm(resync));
  calls[0].call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  await tick();
  const open = calls[1].call.written[0].open;
  assert.equal(calls[1].address, 'b:1');
  assert.equal(open.scene_id, scene);
  assert.deepEqual(open.camera.look_at.eye, { x: 9, y: 9, z: 9 });
  assert.equal(open.camera.yfov, 0.6);
  assert.deepEqual(open.settings, { width: 320, height: 240 });
});

test('at most 3 moves a minute; then, or with no replica left, the page gets the error', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1', 'c:1']);
  const { stream, page } = await opened(set);
  for (let i = 0; i < 3; i++) {
    for (const r of set.replicas) r.update(null, { serving: true, accepting_sessions: true, active_sessions: 0, limits: {} });
    calls.at(-1).call.emit('status', { code: UNAVAILABLE, details: `drop ${i}` });
    await tick();
    assert.equal(calls.length, i + 2);
  }
  calls.at(-1).call.emit('status', { code: UNAVAILABLE, details: 'drop 3' });
  await tick();
  assert.equal(calls.length, 4);
  assert.equal(page.moves.length, 3);
  assert.equal(page.ends.length, 1);
  assert.equal(page.ends[0].code, UNAVAILABLE);
  assert.match(page.ends[0].details, /drop 3 \(the session moved 3 times in the last minute; the gateway gave up\)/);

  // Nowhere to go: the end names every replica and why.
  const { set: two, calls: twoCalls } = await fakeReplicas(['a:1', 'b:1'], { 'b:1': { serving: true, accepting_sessions: false, active_sessions: 8, limits: { max_sessions: 8 } } });
  const lonely = makeStream(two);
  const p2 = sink();
  lonely.attach(p2);
  await lonely.open(norm({ open: { scene_id: 'demo' } }));
  assert.equal(twoCalls[0].address, 'a:1');
  twoCalls[0].call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  await tick();
  assert.equal(p2.ends.length, 1);
  assert.match(p2.ends[0].details, /replica a:1 lost: Connection dropped; no tesserad replica takes new sessions now: a:1 lost; b:1 full \(8 of 8 sessions\)/);
});

test('a replica reported lost (no answer, not serving): its streams leave it before their calls end', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1']);
  const { stream, page } = await opened(set);
  const old = calls[0];
  const replica = set.byAddress.get(old.address);
  stream.replicaLost(replica, 'NOT_SERVING (render stalled)');
  await tick();
  assert.equal(old.call.cancelled, true, 'the session on the sick replica is let go');
  assert.equal(calls.length, 2);
  assert.equal(page.moves[0].reason, `replica ${old.address} NOT_SERVING (render stalled)`);
  old.call.emit('status', { code: 1, details: 'Cancelled' });  // its end is the old call's, not the page's
  assert.deepEqual(page.ends, []);
  assert.equal(replica.streams.has(stream), false);
  assert.equal(set.byAddress.get(calls[1].address).streams.has(stream), true);
  // A stream on another replica is not touched.
  stream.replicaLost(replica, 'again');
  assert.equal(calls.length, 2);
});

test('a replica full at admission (before any frame) passes the session to another; a token limit does not', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1']);
  const { stream, page } = await opened(set);
  const first = calls[0];
  first.call.emit('status', { code: 8, details: 'sessions: 8 open streams reach the max_sessions limit (8)' });
  await tick();
  assert.equal(calls.length, 2, 'placed again');
  assert.notEqual(calls[1].address, first.address);
  assert.deepEqual(page.ends, []);
  // A per-token limit is the user's, the same on every replica: the page gets it.
  const limited = makeStream(set);
  const p2 = sink();
  limited.attach(p2);
  await limited.open(norm({ open: { scene_id: 'demo' } }));
  calls.at(-1).call.emit('status', { code: 8, details: 'sessions: token "x" has its max_sessions (1) open' });
  await tick();
  assert.equal(p2.ends.length, 1);
});

test('missed polls do not move a stream whose frames keep coming (a slow replica, not a lost one)', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1']);
  const { stream, page } = await opened(set);
  const first = calls[0];
  const replica = set.byAddress.get(first.address);
  replica.update({ code: 4, details: 'Deadline exceeded' }, null, Date.now() - 1000);
  first.call.emit('data', { sequence: 1, scene_id: 'demo', data: Buffer.alloc(1) });
  replica.update({ code: 4, details: 'Deadline exceeded' });
  stream.replicaLost(replica, 'stopped answering (Deadline exceeded)');
  await tick();
  assert.equal(calls.length, 1, 'a frame came after the first missed poll: it stays');
  assert.equal(first.call.cancelled ?? false, false);
  // Without frames since then, it moves.
  const quiet = makeStream(set);
  quiet.attach(sink());
  await quiet.open(norm({ open: { scene_id: 'demo' } }));
  const q = calls.at(-1);
  const qr = set.byAddress.get(q.address);
  qr.failures = 0;
  qr.update({ code: 4, details: 'Deadline exceeded' }, null, Date.now() + 1000);
  qr.update({ code: 4, details: 'Deadline exceeded' });
  quiet.replicaLost(qr, 'stopped answering (Deadline exceeded)');
  await tick();
  assert.equal(q.call.cancelled, true);
});

test('events and a close while the stream is between replicas: kept for the new session, or it ends', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1']);
  const { stream, page } = await opened(set);
  calls[0].call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  const event = { event_id: 12, settings: { bloom: true } };
  stream.write(event, norm(event));  // before the move's placement resolved
  await tick();
  assert.equal(calls[1].call.written[0].open.settings.bloom, true);
  assert.equal(calls[1].call.written[0].event_id, 12);

  const closing = makeStream(set);
  const p2 = sink();
  closing.attach(p2);
  await closing.open(norm({ open: { scene_id: 'demo' } }));
  calls.at(-1).call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  closing.end();
  await tick();
  assert.deepEqual(p2.ends.map((s) => s.code), [0]);
  assert.deepEqual(p2.moves, []);
});

test('the page is told of the move after the old session\'s last frame, and waiting frames of it are dropped', async () => {
  const { set, calls } = await fakeReplicas(['a:1', 'b:1']);
  const ws = new EventEmitter();
  ws.OPEN = 1;
  ws.readyState = 1;
  ws.bufferedAmount = 0;
  ws.sent = [];
  const held = [];
  ws.send = (data, done) => {
    ws.sent.push(typeof data === 'string' ? JSON.parse(data) : splitBinary(data).header);
    if (done) held.push(done);
  };
  new Connection(ws, {
    replicas: set, definition, metadata: () => ({}), limits: async () => ({}), maxUploadBytes: 1 << 20,
    uploadBudget: new UploadBudget(1 << 20), parked: { take: () => null, park() {} }, stopping: () => false,
    log: () => {}, version: 'test', server: 'a:1,b:1', peer: 'test',
  });
  ws.emit('message', Buffer.from(JSON.stringify({ id: 3, op: 'open', open: { scene_id: 'demo' } })), false);
  await tick();
  assert.deepEqual(ws.sent.find((m) => m.id === 3)?.result, { stream: 3, resumed: false });
  const jpeg = (sequence) => ({ sequence, encoding: 'IMAGE_JPEG', session_token: 'old', data: Buffer.from([0xff, 0xd8]) });
  calls[0].call.emit('data', jpeg(1));  // in the socket
  calls[0].call.emit('data', jpeg(2));  // waits behind it
  calls[0].call.emit('status', { code: UNAVAILABLE, details: 'Connection dropped' });
  await tick();
  const moved = ws.sent.find((m) => m.type === 'stream_moved');
  assert.deepEqual(moved, { type: 'stream_moved', stream: 3, from: calls[0].address, to: calls[1].address, reason: `replica ${calls[0].address} lost: Connection dropped`, moves: 1 });
  while (held.length) held.shift()();
  calls[1].call.emit('data', { ...jpeg(1), session_token: 'new' });
  while (held.length) held.shift()();
  const order = ws.sent.filter((m) => m.type === 'stream_moved' || m.frame).map((m) => (m.frame ? `frame ${m.frame.sequence} ${m.frame.session_token.split('.')[1]}` : 'moved'));
  assert.deepEqual(order, ['frame 1 old', 'moved', 'frame 1 new'], 'frame 2 of the old session was dropped');
  assert.ok(!ws.sent.some((m) => m.type === 'stream_end'));
});

test('a parked stream is found by a token it had before it moved', async () => {
  const { ParkedStreams } = await import('../lib/streams.js');
  const parked = new ParkedStreams({ graceMs: () => 60_000, max: () => 4, log: () => {} });
  const stream = { token: 'b.new', tokens: ['b.new', 'a.old'], ended: false, detach() {}, cancel() { this.cancelled = true; } };
  parked.park(stream);
  assert.equal(parked.take('a.unknown'), null);
  assert.equal(parked.take('a.old'), stream);
  assert.equal(parked.size, 0);
  parked.park(stream);
  stream.token = 'c.newer';  // it moved while parked: its end still leaves the set
  stream.onEnded();
  assert.equal(parked.size, 0);
});

// Connection with a fake WebSocket and a fake tesserad client: orderings that are hard to reach
// against a real server.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { EventEmitter } from 'node:events';
import { Connection, UploadBudget } from '../lib/connection.js';
import { BridgedStream } from '../lib/streams.js';
import { binaryMessage, splitBinary } from './harness.js';

function fakePage() {
  const ws = new EventEmitter();
  ws.OPEN = 1;
  ws.readyState = 1;
  ws.bufferedAmount = 0;
  ws.sent = [];
  ws.send = (data, done) => { ws.sent.push(typeof data === 'string' ? JSON.parse(data) : data); done?.(); };
  ws.text = (msg) => ws.emit('message', Buffer.from(JSON.stringify(msg)), false);
  ws.binary = (header, payload) => ws.emit('message', binaryMessage(header, payload), true);
  ws.replies = (id) => ws.sent.filter((m) => m.id === id && m.ok !== undefined);
  return ws;
}

function fakeContext(overrides = {}) {
  const calls = { UploadScene: 0 };
  const client = {
    UploadScene() {
      calls.UploadScene++;
      const call = new EventEmitter();
      call.write = () => true;
      call.end = () => {};
      call.cancel = () => {};
      return call;
    },
  };
  // One server, as a plain --server HOST:PORT gives: every call goes to it.
  const replica = { address: 'fake:1', client, streams: new Set() };
  const replicas = {
    single: true,
    place: async () => replica,
    pickUnary: async () => replica,
    answering: async () => [replica],
    shared: () => true,
    forToken: (token) => ({ replica, token }),
    reportFailure() {},
  };
  return {
    calls,
    ctx: {
      client,
      replica,
      replicas,
      definition: {},
      metadata: () => ({}),
      limits: async () => ({ max_upload_files: 8, max_upload_bytes: 1 << 20, max_chunk_bytes: 1 << 16 }),
      maxUploadBytes: 1 << 20,
      uploadBudget: new UploadBudget(4 << 20),
      parked: { park() {} },
      stopping: () => false,
      log: () => {},
      version: 'test',
      server: 'fake',
      ...overrides,
    },
  };
}

test('an upload cancelled while the limits are fetched stays cancelled', async () => {
  let release;
  const slowLimits = new Promise((r) => { release = r; });
  const { ctx, calls } = fakeContext({ limits: () => slowLimits });
  const ws = fakePage();
  new Connection(ws, ctx);
  ws.text({ id: 1, op: 'upload', files: [{ name: 'a.glb', size: 3 }] });
  ws.binary({ upload: 1, file: 0, offset: 0 }, Buffer.from('abc'));
  ws.text({ id: 2, op: 'cancel', target: 1 });
  release({ max_upload_files: 8, max_upload_bytes: 1 << 20, max_chunk_bytes: 1 << 16 });
  await new Promise((r) => setTimeout(r, 20));
  assert.equal(calls.UploadScene, 0, 'the cancelled upload was sent to tesserad');
  assert.deepEqual(ws.replies(1).map((m) => m.error?.code), ['CANCELLED']);
  assert.equal(ctx.uploadBudget.used, 0);
});

test('a chunk in the same read as its upload request is not lost', async () => {
  const { ctx, calls } = fakeContext();
  const ws = fakePage();
  new Connection(ws, ctx);
  ws.text({ id: 1, op: 'upload', files: [{ name: 'a.glb', size: 3 }] });
  ws.binary({ upload: 1, file: 0, offset: 0 }, Buffer.from('abc'));
  await new Promise((r) => setTimeout(r, 20));
  assert.equal(calls.UploadScene, 1);
  assert.ok(ws.sent.some((m) => m.type === 'progress' && m.phase === 'loading'));
});

test('uploads beyond the gateway-wide budget are refused, and the budget comes back', async () => {
  const { ctx } = fakeContext({ uploadBudget: new UploadBudget(10) });
  const ws = fakePage();
  new Connection(ws, ctx);
  ws.text({ id: 1, op: 'upload', files: [{ name: 'a.glb', size: 8 }] });
  await new Promise((r) => setTimeout(r, 5));
  ws.text({ id: 2, op: 'upload', files: [{ name: 'b.glb', size: 8 }] });
  await new Promise((r) => setTimeout(r, 5));
  assert.equal(ws.replies(2)[0].error.code, 'RESOURCE_EXHAUSTED');
  ws.emit('close', 1000);
  assert.equal(ctx.uploadBudget.used, 0);
});

test('renders are refused while the page does not read its frames', async () => {
  const { ctx } = fakeContext();
  const ws = fakePage();
  ws.bufferedAmount = 64 << 20;
  new Connection(ws, ctx);
  ws.text({ id: 1, op: 'render', request: {} });
  await tick();
  assert.equal(ws.replies(1)[0].error.code, 'RESOURCE_EXHAUSTED');
  assert.match(ws.replies(1)[0].error.message, /not reading/);
});

/** A fake tesserad Stream call: what the gateway writes, and frames to emit. */
function fakeStreamCall() {
  const call = new EventEmitter();
  call.written = [];
  call.write = (event) => { call.written.push(event); return true; };
  call.end = () => { call.ended = true; };
  call.cancel = () => {};
  return call;
}

function streamContext(overrides = {}) {
  const { ctx } = fakeContext(overrides);
  const calls = [];
  ctx.client.Stream = () => {
    const call = fakeStreamCall();
    calls.push(call);
    return call;
  };
  return { ctx, calls };
}

const tick = () => new Promise((r) => setImmediate(r));

const h264 = (sequence, keyframe) => ({
  sequence, encoding: 'VIDEO_H264', keyframe, codec: 'avc1.64000d', data: Buffer.from([0, 0, 0, 1, sequence]),
});
const framesSent = (ws) => ws.sent.filter((m) => Buffer.isBuffer(m)).map((m) => splitBinary(m).header);

test('a page that falls behind on video: the gateway drops to the next keyframe and asks for it with the page\'s newest event id', async () => {
  const { ctx, calls } = streamContext();
  const ws = fakePage();
  const held = [];
  ws.send = (data, done) => {
    ws.sent.push(typeof data === 'string' ? JSON.parse(data) : data);
    if (done) held.push(done);  // frames stay in the socket until the test lets them go
  };
  new Connection(ws, ctx);
  ws.text({ id: 1, op: 'open', open: { scene_id: 'demo', video: { codec: 'VIDEO_CODEC_H264' } }, event_id: 3 });
  await tick();
  const call = calls[0];
  assert.deepEqual(call.written[0].open.video, { codec: 'VIDEO_CODEC_H264' });
  ws.text({ id: 2, op: 'event', stream: 1, event: { event_id: 9, refresh: true } });
  ws.text({ id: 3, op: 'event', stream: 1, event: { event_id: 'x7' } });  // not a number: not the newest
  call.emit('data', h264(1, true));
  for (let s = 2; s <= 6; s++) call.emit('data', h264(s, false));  // 3 wait, then one too many
  call.emit('data', h264(7, false));
  const asks = call.written.filter((e) => e.keyframe);
  assert.deepEqual(asks, [{ event_id: 9, keyframe: true }]);
  while (held.length > 0) held.shift()();
  assert.deepEqual(framesSent(ws).map((h) => [h.frame.sequence, h.video_seq]), [[1, 1]]);
  call.emit('data', h264(9, true));
  call.emit('data', { ...h264(10, false), encoding: 'IMAGE_JPEG', data: Buffer.from([0xff, 0xd8]) });
  while (held.length > 0) held.shift()();
  // The gap in video_seq (1 -> 8) lands on a keyframe; pictures carry no video_seq.
  assert.deepEqual(framesSent(ws).map((h) => [h.frame.sequence, h.video_seq]), [[1, 1], [9, 8], [10, undefined]]);
});

test('a page taking over its stream: refresh and keyframe in one event, and no video before the keyframe', () => {
  const { ctx, calls } = streamContext();
  const parked = new BridgedStream({ replicas: ctx.replicas, metadata: () => ({}), log: () => {} });
  parked.startCall(ctx.replica, { open: { scene_id: 'demo' } });
  const call = calls[0];
  call.emit('data', { ...h264(4, true), session_token: 'tok' });  // while its page was away
  assert.equal(parked.token, `${Buffer.from('fake:1').toString('base64url')}.tok`, 'the token names the replica');
  ctx.parked = { take: (token) => (token === parked.token ? parked : null), park() {} };
  const ws = fakePage();
  new Connection(ws, ctx);
  ws.text({ id: 5, op: 'open', open: { resume_token: parked.token }, event_id: 12 });
  assert.equal(calls.length, 1, 'a held stream was opened again at tesserad');
  assert.deepEqual(ws.replies(5)[0].result, { stream: 5, resumed: true });
  assert.deepEqual(call.written.slice(1), [{ event_id: 12, refresh: true, keyframe: true }]);
  call.emit('data', h264(5, false));  // made before the keyframe asked for: useless
  call.emit('data', h264(6, true));
  call.emit('data', h264(7, false));
  assert.deepEqual(framesSent(ws).map((h) => [h.stream, h.frame.sequence, h.video_seq, h.frame.keyframe]),
    [[5, 6, 3, true], [5, 7, 4, false]]);
  assert.equal(call.written.length, 2, 'the resume asked already');
});

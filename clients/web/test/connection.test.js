// Connection with a fake WebSocket and a fake tesserad client: orderings that are hard to reach
// against a real server.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { EventEmitter } from 'node:events';
import { Connection, UploadBudget } from '../lib/connection.js';
import { binaryMessage } from './harness.js';

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
  return {
    calls,
    ctx: {
      client,
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

test('renders are refused while the page does not read its frames', () => {
  const { ctx } = fakeContext();
  ctx.client.Render = { requestSerialize: () => Buffer.alloc(0) };
  const ws = fakePage();
  ws.bufferedAmount = 64 << 20;
  new Connection(ws, ctx);
  ws.text({ id: 1, op: 'render', request: {} });
  assert.equal(ws.replies(1)[0].error.code, 'RESOURCE_EXHAUSTED');
  assert.match(ws.replies(1)[0].error.message, /not reading/);
});

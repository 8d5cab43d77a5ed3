// LatestSender: at most one frame in the socket, the newest one waiting, never an older frame
// after a newer one.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { LatestSender, MAX_VIDEO_WAITING } from '../lib/latest.js';

function fakeSocket() {
  const sock = { written: [], pending: [] };
  sock.send = (data, done) => { sock.written.push(data); sock.pending.push(done); };
  sock.flush = (err) => sock.pending.shift()(err);
  return sock;
}

test('frames pass straight through while the socket keeps up', () => {
  const sock = fakeSocket();
  const s = new LatestSender(sock.send);
  for (let i = 1; i <= 3; i++) { s.push(i); sock.flush(); }
  assert.deepEqual(sock.written, [1, 2, 3]);
  assert.equal(s.dropped, 0);
});

test('a slow socket gets the newest frame next, and the ones in between are dropped', () => {
  const sock = fakeSocket();
  const s = new LatestSender(sock.send);
  s.push(1);
  s.push(2);
  s.push(3);
  s.push(4);
  assert.deepEqual(sock.written, [1]);
  sock.flush();
  assert.deepEqual(sock.written, [1, 4]);
  sock.flush();
  assert.equal(sock.pending.length, 0);
  assert.equal(s.dropped, 2);
  assert.equal(s.sent, 2);
});

test('an error drops the waiting frame; after close nothing more is sent', () => {
  const sock = fakeSocket();
  const s = new LatestSender(sock.send);
  s.push(1);
  s.push(2);
  sock.flush(new Error('gone'));
  assert.deepEqual(sock.written, [1]);
  s.push(3);
  s.close();
  s.push(4);
  assert.deepEqual(sock.written, [1, 3]);
});

// Video (VIDEO_H264): a non-key frame needs every frame since its keyframe, so video frames
// queue (up to MAX_VIDEO_WAITING) instead of replacing each other; past that, the sender drops
// until a keyframe and asks for one, once.
const K = { video: true, keyframe: true };
const D = { video: true, keyframe: false };

function videoSender() {
  const sock = fakeSocket();
  const asks = [];
  const s = new LatestSender(sock.send, { requestKeyframe: () => asks.push(sock.written.length) });
  return { sock, s, asks };
}

test('video frames are never replaced: up to 3 wait behind the one in flight, in order', () => {
  const { sock, s, asks } = videoSender();
  s.push('k1', K);
  s.push('d2', D);
  s.push('d3', D);
  s.push('d4', D);
  assert.equal(MAX_VIDEO_WAITING, 3);
  assert.equal(s.waiting, 3);
  while (sock.pending.length > 0) sock.flush();
  assert.deepEqual(sock.written, ['k1', 'd2', 'd3', 'd4']);
  assert.equal(s.dropped, 0);
  assert.deepEqual(asks, []);
});

test('a page falling behind: the waiting non-key frames and all up to the next keyframe are dropped, one keyframe asked for', () => {
  const { sock, s, asks } = videoSender();
  s.push('k1', K);
  s.push('d2', D);
  s.push('d3', D);
  s.push('d4', D);
  s.push('d5', D);  // a fourth would wait: d2..d5 go
  assert.equal(s.waiting, 0);
  assert.deepEqual(asks, [1]);
  s.push('d6', D);  // depends on what was dropped
  s.push('d7', D);
  assert.deepEqual(asks, [1], 'asked more than once for the same gap');
  sock.flush();     // k1 done: nothing waits
  assert.deepEqual(sock.written, ['k1']);
  s.push('k8', K);  // the keyframe asked for: sent, and the frames after it again
  s.push('d9', D);
  sock.flush();
  sock.flush();
  assert.deepEqual(sock.written, ['k1', 'k8', 'd9']);
  assert.equal(s.dropped, 6);
  assert.equal(s.keyframeRequests, 1);
  // A later gap asks again.
  for (const d of ['d10', 'd11', 'd12', 'd13']) s.push(d, D);
  s.push('d14', D);
  assert.deepEqual(asks, [1, 4]);  // d10 went out; d11..d13 waited
});

test('a waiting keyframe survives an overflow; a keyframe arriving replaces everything waiting', () => {
  const { sock, s, asks } = videoSender();
  s.push('d1', D);
  s.push('k2', K);
  s.push('d3', D);
  s.push('d4', D);
  s.push('d5', D);  // overflow: k2 stays, d3..d5 go
  assert.equal(asks.length, 1);
  s.push('k6', K);  // replaces k2
  s.push('d7', D);
  while (sock.pending.length > 0) sock.flush();
  assert.deepEqual(sock.written, ['d1', 'k6', 'd7']);

  const other = videoSender();
  other.s.push('k1', K);
  other.s.push('d2', D);
  other.s.push('k3', K);  // d2 is not needed by k3 nor anything after it
  other.s.push('d4', D);
  while (other.sock.pending.length > 0) other.sock.flush();
  assert.deepEqual(other.sock.written, ['k1', 'k3', 'd4']);
  assert.deepEqual(other.asks, [], 'a keyframe that replaced frames needs no other keyframe');
});

test('pictures stay latest-wins among video; a picture replacing non-key frames means wait for a keyframe', () => {
  const { sock, s, asks } = videoSender();
  s.push('j1');
  s.push('j2');
  s.push('d3', D);  // j2 is older and not needed by d3
  assert.equal(s.waiting, 1);
  s.push('j4');     // the codec switched to JPEG: the picture replaces d3
  s.push('d5', D);  // d5 would need d3: dropped, and a keyframe asked for
  assert.deepEqual(asks, [1]);
  while (sock.pending.length > 0) sock.flush();
  assert.deepEqual(sock.written, ['j1', 'j4']);
  assert.equal(s.dropped, 3);
});

test('a resumed stream waits for the keyframe its resume asked for; a page asking for one skips what it cannot use', () => {
  const sock = fakeSocket();
  const asks = [];
  const s = new LatestSender(sock.send, { requestKeyframe: () => asks.push(1), awaitKeyframe: true });
  s.push('d1', D);
  s.push('d2', D);
  assert.deepEqual(sock.written, []);
  assert.deepEqual(asks, [], 'the resume itself asked');
  s.push('k3', K);
  s.push('d4', D);
  s.push('d5', D);
  s.pageAskedKeyframe();  // its decoder failed: d4, d5 are of no use before the next keyframe
  s.push('d6', D);
  sock.flush();
  assert.deepEqual(sock.written, ['k3']);
  assert.deepEqual(asks, []);
  s.push('k7', K);
  sock.flush();
  assert.deepEqual(sock.written, ['k3', 'k7']);
  // A JPEG stream is not affected by any of it.
  const jpeg = new LatestSender(fakeSocket().send, { awaitKeyframe: true });
  jpeg.push('j1');
  assert.equal(jpeg.sent, 1);
});

// LatestSender: at most one frame in the socket, the newest one waiting, never an older frame
// after a newer one.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { LatestSender } from '../lib/latest.js';

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

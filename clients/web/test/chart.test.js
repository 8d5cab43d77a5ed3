// FpsMeter, BitrateMeter and statsRows: the rates while frames come, "idle" (with the last rate)
// once they stop.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import {
  BitrateMeter, FpsMeter, MAIN_STATS, formatBitrate, gridSteps, niceCeil, statsRows,
} from '../public/chart.js';

test('the rate while frames come, idle with the last rate when they stop', () => {
  const m = new FpsMeter(2000);
  assert.equal(m.label(0), '–');
  for (let t = 0; t <= 1000; t += 40) m.tick(t);  // 25 fps for a second
  assert.equal(m.label(1000), '25.0');
  assert.equal(m.fps(5000), 0);                    // the camera rests: no frames
  assert.equal(m.label(5000), 'idle (last 25.0)');
  m.tick(6000);
  m.tick(6100);                                    // moving again, at 10 fps
  assert.equal(m.label(6100), '10.0');
});

test('statsRows shows the label as given, or a number to one decimal', () => {
  assert.deepEqual(statsRows(null, { fps: 'idle (last 12.0)' })[0], ['fps', 'idle (last 12.0)']);
  assert.deepEqual(statsRows(null, { fps: 12.345 })[0], ['fps', '12.3']);
});

test('the bitrate: bytes of frames received per second over the window, in Mbit/s', () => {
  const m = new BitrateMeter(2000);
  assert.equal(m.label(0), '–');
  for (let t = 0; t < 2000; t += 100) m.add(t, 50_000);  // 20 frames of 50 kB in 2 s
  assert.equal(m.bitsPerSecond(1999), 4_000_000);
  assert.equal(m.label(1999), '4.00 Mbit/s');
  assert.equal(m.bitsPerSecond(5000), 0);                // the camera rests
  assert.equal(m.label(5000), 'idle (last 4.00 Mbit/s)');
  m.add(5000, Number.NaN);                               // a bad size counts as nothing
  assert.equal(m.bitsPerSecond(5000), 0);
  assert.equal(formatBitrate(42_000), '0.042 Mbit/s');
  assert.equal(formatBitrate(0), '0.00 Mbit/s');
  assert.equal(formatBitrate(Number.NaN), '–');
});

test('statsRows: fps, latency and bitrate first; the main rows of the overlay are among them', () => {
  const frame = { bytes: 2048, width: 640, height: 360, gpu_total_ms: 4 };
  const rows = statsRows(frame, { fps: 30, latencyMs: 12, bitrate: '1.20 Mbit/s' });
  assert.deepEqual(rows.slice(0, 3), [['fps', '30.0'], ['latency (median)', '12 ms'], ['bitrate', '1.20 Mbit/s']]);
  const labels = rows.map(([label]) => label);
  for (const main of MAIN_STATS) assert.ok(labels.includes(main), main);
  assert.deepEqual(rows.find(([l]) => l === 'resolution'), ['resolution', '640 × 360']);
});

test('the chart\'s grid lines fall on round numbers', () => {
  for (const [max, steps] of [[50, 5], [5, 5], [0.5, 5], [20, 4], [100, 4], [1, 4], [2, 4]]) {
    assert.equal(gridSteps(max), steps, String(max));
  }
  for (const v of [0.3, 3, 37, 180, 4200]) {
    const max = niceCeil(v);
    const step = max / gridSteps(max);
    assert.ok(Number.isInteger(Number((step * 100).toPrecision(6))), `${max}: step ${step}`);
  }
});

test('statsRows: the codec (with the video codec string and encoder) and the decode time', () => {
  const row = (frame, opts) => Object.fromEntries(statsRows(frame, opts));
  const jpeg = row({ encoding: 'IMAGE_JPEG', bytes: 100 }, { decodeMs: 2.345 });
  assert.equal(jpeg.codec, 'jpeg');
  assert.equal(jpeg.decode, '2.3 ms');
  assert.equal(row({ encoding: 'IMAGE_PNG' }).codec, 'png');
  assert.equal(row({ encoding: 'IMAGE_PNG' }).decode, '–');
  const video = row({ encoding: 'VIDEO_H264', codec: 'avc1.64001f', encoder: 'libx264', keyframe: false }, { decodeMs: 0.5 });
  assert.equal(video.codec, 'h264 avc1.64001f (libx264)');
  assert.equal(video.decode, '0.50 ms');
  assert.equal(row({ encoding: 'VIDEO_H264' }).codec, 'h264 ?');
  assert.ok(MAIN_STATS.has('codec'));
});

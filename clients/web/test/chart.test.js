// FpsMeter and statsRows: the rate while frames come, "idle" (with the last rate) once they stop.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { FpsMeter, statsRows } from '../public/chart.js';

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

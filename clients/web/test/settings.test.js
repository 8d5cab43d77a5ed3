// The settings panel's ranges, labels and docs come from the server's settings table
// (ServerInfo.choices.settings), with a plain fallback for a server that has none.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { settingSpec } from '../public/settings.js';

const INFO = {
  choices: {
    settings: [
      { name: 'bloom_strength', type: 'float', min: 0, max: 1, range: '0..1', label: 'Bloom strength', doc: 'how much of the glow is added' },
      { name: 'synthetic_lights', type: 'uint', min: 0, max: 65536, range: '0..65536', label: 'Synthetic lights', doc: 'random point lights' },
      { name: 'aa', type: 'enum', min: 0, max: 4, choices: ['none', 'msaa'], label: 'Anti-aliasing', doc: 'anti-aliasing mode' },
      { name: 'shadows', type: 'bool', min: 0, max: 1, label: 'Shadows', doc: '' },
    ],
  },
  limits: { max_synthetic_lights: 4096 },
};

test('numbers get the range, label and doc of their table row', () => {
  assert.deepEqual(settingSpec('bloom_strength', INFO),
    { label: 'Bloom strength', doc: 'how much of the glow is added (0..1)', min: 0, max: 1 });
});

test('the server limit on synthetic lights caps the table range', () => {
  assert.equal(settingSpec('synthetic_lights', INFO).max, 4096);
  const noLimit = { choices: INFO.choices };
  assert.equal(settingSpec('synthetic_lights', noLimit).max, 65536);
});

test('enums and bools get a label and doc but no numeric range', () => {
  const aa = settingSpec('aa', INFO);
  assert.equal(aa.label, 'Anti-aliasing');
  assert.equal(aa.min, undefined);
  assert.equal(settingSpec('shadows', INFO).max, undefined);
});

test('a field the server does not describe falls back to its name and no range', () => {
  assert.deepEqual(settingSpec('light_time', INFO), { label: 'light time', doc: '' });
  assert.deepEqual(settingSpec('tile_depth_mask', undefined), { label: 'tile depth mask', doc: '' });
});

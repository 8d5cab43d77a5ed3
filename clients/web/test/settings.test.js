// The settings panel's ranges, labels and docs come from the server's settings table
// (ServerInfo.choices.settings), with a plain fallback for a server that has none.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import {
  OTHER_SECTION, SETTING_SECTIONS, groupSettings, rangeUnit, settingLabel, settingSpec,
} from '../public/settings.js';

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
  assert.deepEqual(settingSpec('light_time', INFO), { label: 'Light time', doc: '' });
  assert.deepEqual(settingSpec('tile_depth_mask', undefined), { label: 'Tile depth mask', doc: '' });
});

// What tesserad sends (ServerInfo.choices.settings), in its table order, width/height aside.
const SERVER_SETTINGS = ['aa', 'samples', 'culling', 'scene_lights', 'synthetic_lights', 'light_seed',
  'tile_size', 'light_radius_min', 'light_radius_max', 'lights_animated', 'light_time', 'light_culling',
  'tile_depth_mask', 'light_binning', 'shadows', 'shadow_atlas_size', 'shadow_lights', 'shadow_cache', 'ssao',
  'ssao_radius', 'ssao_strength', 'ssao_half_res', 'bloom', 'bloom_strength', 'ibl', 'exposure_mode',
  'exposure_ev', 'tonemapper', 'pipeline', 'post_stage', 'vis_mlaa_coverage', 'debug_view', 'pass_timing',
  'jpeg_quality', 'jpeg_444'];

test('every setting the server sends lands in one named section, none in "Other"', () => {
  const groups = groupSettings(SERVER_SETTINGS);
  assert.deepEqual(groups.map((g) => g.title),
    ['Image', 'Lighting', 'Shadows', 'Post-processing', 'Encoding', 'Pipeline and debug']);
  const placed = groups.flatMap((g) => g.names);
  assert.deepEqual([...placed].sort(), [...SERVER_SETTINGS].sort());
  const section = (name) => groups.find((g) => g.names.includes(name)).id;
  assert.equal(section('aa'), 'image');
  assert.equal(section('tonemapper'), 'image');
  assert.equal(section('vis_mlaa_coverage'), 'image');
  assert.equal(section('exposure_ev'), 'image');
  assert.equal(section('ibl'), 'lighting');
  assert.equal(section('shadow_cache'), 'shadows');
  assert.equal(section('bloom_strength'), 'post');
  assert.equal(section('jpeg_444'), 'encoding');
  assert.equal(section('light_culling'), 'pipeline');
  assert.equal(section('debug_view'), 'pipeline');
  assert.equal(section('pass_timing'), 'pipeline');
  // A switch comes before its parameters.
  const post = groups.find((g) => g.id === 'post').names;
  assert.ok(post.indexOf('ssao') < post.indexOf('ssao_radius'));
  assert.ok(post.indexOf('bloom') < post.indexOf('bloom_strength'));
  assert.deepEqual(groups.map((g) => g.open), [true, true, false, false, false, false]);
});

test('a setting a newer server adds joins its family by name, or "Other": nothing is lost', () => {
  const groups = groupSettings(['aa', 'ssao_bias', 'shadow_bias', 'debug_grid', 'frobnicate', 'zeta',
    'tonemap_white', 'light_binning', 'spot_culling']);
  const byId = Object.fromEntries(groups.map((g) => [g.id, g.names]));
  assert.deepEqual(byId.image, ['aa', 'tonemap_white']);
  assert.deepEqual(byId.post, ['ssao_bias']);
  assert.deepEqual(byId.shadows, ['shadow_bias']);
  assert.deepEqual(byId.pipeline, ['light_binning', 'debug_grid', 'spot_culling']);
  assert.deepEqual(byId.other, ['frobnicate', 'zeta']);
  assert.equal(groups.at(-1).title, OTHER_SECTION.title);
  assert.deepEqual(groupSettings([]), []);
  // No name is listed in two sections.
  const listed = SETTING_SECTIONS.flatMap((s) => s.names);
  assert.equal(new Set(listed).size, listed.length);
});

test('labels: sentence case, the unit in parentheses when the range names one', () => {
  assert.equal(rangeUnit('0..1e6 world units, 0 = auto'), 'world units');
  assert.equal(rangeUnit('-20..20 stops'), 'stops');
  assert.equal(rangeUnit('0..1'), '');
  assert.equal(rangeUnit('1, 2, 4 or 8'), '');
  assert.equal(rangeUnit('a power of two, 512..8192'), '');
  assert.equal(settingLabel('Light radius min', '0..1e6 world units, 0 = auto'), 'Light radius min (world units)');
  assert.equal(settingLabel('Exposure (EV)', '-20..20 stops'), 'Exposure (EV)');  // has its unit
  assert.equal(settingLabel('light time', ''), 'Light time');
  assert.equal(settingLabel('SSAO strength', '0..4'), 'SSAO strength');
});

// The Animation section's logic (public/animation.js): the picker's options from
// SceneInfo.animations, what settings.animation each sends, the time readout, and the slider
// following the frames of a playing animation except while the user drags it.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import {
  ANIMATION_SETTINGS, NONE, animationChoices, chooseChange, choiceFor, findAnimation, followTime,
  formatReadout, formatSeconds, frameValue, playChange, sliderStep,
} from '../public/animation.js';
import { inPanel } from '../public/settings.js';

const anim = (name, duration_s, channels = 1) => ({ name, duration_s, channels });

test('the picker: "none", then each animation by name with its duration', () => {
  const choices = animationChoices([anim('Walk', 2.4, 30), anim('Run', 0.8333333, 30), anim('Wave', 10, 1)]);
  assert.deepEqual(choices.map((c) => [c.value, c.label]), [
    [NONE, 'none (rest pose)'],
    ['Walk', 'Walk (2.4 s)'],
    ['Run', 'Run (0.83 s)'],
    ['Wave', 'Wave (10 s)'],
  ]);
  assert.deepEqual(choices.map((c) => c.index), [-1, 0, 1, 2]);
  assert.equal(choices[1].duration, 2.4);
  // Key times are float32: the duration without its noise.
  assert.equal(animationChoices([anim('Walk', 2.4000000953674316)])[1].duration, 2.4);
  assert.equal(choices[1].title, '30 channels, 2.4 s');
  assert.equal(choices[3].title, '1 channel, 10 s');
  assert.ok(choices.every((c) => !c.disabled));
  // A scene without animations (or a server that does not list them): "none" alone.
  assert.deepEqual(animationChoices(undefined).map((c) => c.value), [NONE]);
  assert.deepEqual(animationChoices([]).map((c) => c.value), [NONE]);
});

test('an empty or duplicated name, or the name "none", is sent as the index', () => {
  const animations = [anim('Walk', 1), anim('', 2), anim('Walk', 3), anim('none', 4), anim('Idle', 5)];
  const choices = animationChoices(animations);
  assert.deepEqual(choices.map((c) => [c.value, c.label]), [
    [NONE, 'none (rest pose)'],
    ['0', 'Walk #0 (1 s)'],
    ['1', 'animation 1 (2 s)'],
    ['2', 'Walk #2 (3 s)'],
    ['3', 'none (4 s)'],
    ['Idle', 'Idle (5 s)'],
  ]);
  // Every value names its own animation the way the server looks it up.
  for (const c of choices) assert.equal(findAnimation(animations, c.value), c.index, c.value);
});

test('an index taken as another animation\'s name: the name where it names the animation, else disabled', () => {
  // Animation 0 is called "2": the index "2" would name it, not animation 2.
  const animations = [anim('2', 1), anim('Jump', 1), anim('Jump', 1), anim('', 1)];
  const choices = animationChoices(animations);
  assert.deepEqual(choices.map((c) => [c.value, c.disabled]), [
    [NONE, false], ['2', false], ['1', false], ['#2', true], ['3', false],
  ]);
  // Animation 1 is also the first "Jump": by index or by name, both name it.
  assert.equal(findAnimation(animations, 'Jump'), 1);
  assert.match(choices[3].title, /cannot be asked for/);
});

test('findAnimation looks up as tesserad does: none, a name first, then decimal digits', () => {
  const animations = [anim('Walk', 1), anim('7', 1)];
  assert.equal(findAnimation(animations, ''), -1);
  assert.equal(findAnimation(animations, undefined), -1);
  assert.equal(findAnimation(animations, 'none'), -1);
  assert.equal(findAnimation(animations, 'Walk'), 0);
  assert.equal(findAnimation(animations, '7'), 1);  // a name, not the index 7
  assert.equal(findAnimation(animations, '1'), 1);
  assert.equal(findAnimation(animations, '01'), 1);
  assert.equal(findAnimation(animations, '2'), null);  // out of range
  assert.equal(findAnimation(animations, 'Run'), null);
  assert.equal(findAnimation(animations, '-1'), null);
  // The choice a frame's settings.animation selects: by name or by index.
  const choices = animationChoices(animations);
  assert.equal(choiceFor(choices, animations, 'Walk').value, 'Walk');
  assert.equal(choiceFor(choices, animations, '0').value, 'Walk');
  assert.equal(choiceFor(choices, animations, undefined).value, NONE);
  assert.equal(choiceFor(choices, animations, 'Run'), null);
});

test('the readout and the slider step', () => {
  assert.equal(formatReadout(1.25, 2.4), '1.25 / 2.40 s');
  assert.equal(formatReadout(0, 0), '0.00 / 0.00 s');
  assert.equal(formatReadout(1.2500001, 2.4000001), '1.25 / 2.40 s');
  assert.equal(formatReadout(-0.001, 2), '0.00 / 2.00 s');
  assert.equal(formatReadout(NaN, 2), '– / 2.00 s');
  assert.equal(formatSeconds(2.4), '2.4');
  assert.equal(formatSeconds(0.041666), '0.04');
  assert.equal(formatSeconds(10), '10');
  assert.equal(sliderStep(2.4), '0.024');
  assert.equal(sliderStep(10), '0.1');
  assert.equal(sliderStep(0), 'any');
});

test('the slider follows the time each frame shows, not while dragged, not before the time set is shown', () => {
  const pending = new Map();
  const frame = (event_id, scene_time, extra = {}) => ({ event_id, settings: { scene_time, play: true, loop: true, ...extra } });
  assert.equal(followTime(frame(0, 0.5), pending), 0.5);
  assert.equal(followTime(frame(0, 0.5333333), pending), 0.533333, 'float32 noise tidied');
  assert.equal(followTime(frame(0, 0.6), pending, true), undefined, 'dragging: the slider is the user\'s');
  // The user set 1.5 s in event 9: frames of older events (still the old clock) are not shown.
  pending.set('scene_time', 9);
  assert.equal(followTime(frame(8, 0.7), pending), undefined);
  assert.equal(pending.get('scene_time'), 9);
  assert.equal(followTime(frame(9, 1.5), pending), 1.5);
  assert.equal(pending.has('scene_time'), false, 'shown: forgotten');
  assert.equal(followTime(frame(9, 1.53), pending), 1.53, 'then it follows the clock again');
  // While dragging, a reflected change is not forgotten either (the drag sends more).
  pending.set('scene_time', 12);
  assert.equal(followTime(frame(12, 2), pending, true), undefined);
  assert.equal(pending.get('scene_time'), 12);
  assert.equal(followTime({ event_id: 12 }, pending), undefined, 'a frame without settings');
});

test('frameValue: the frame\'s setting unless a newer change is pending; no animation named is none', () => {
  const pending = new Map([['play', 5]]);
  const frame = { event_id: 4, settings: { play: false, loop: true, scene_time: 0 } };
  assert.equal(frameValue(frame, 'play', pending), null);
  assert.deepEqual(frameValue(frame, 'loop', pending), { value: true });
  assert.deepEqual(frameValue(frame, 'animation', pending), { value: NONE });
  assert.deepEqual(frameValue({ event_id: 5, settings: { animation: 'Walk', play: true } }, 'animation', pending), { value: 'Walk' });
  assert.deepEqual(frameValue({ event_id: 5, settings: { play: true } }, 'play', pending), { value: true });
  assert.equal(pending.size, 0);
  assert.equal(frameValue({ event_id: 5, settings: {} }, 'loop', pending), null, 'a field the frame does not carry');
});

test('play, pause, and picking an animation send the settings the server wants', () => {
  assert.deepEqual(playChange({ playing: false, loop: true, time: 1, duration: 2 }), { play: true });
  assert.deepEqual(playChange({ playing: true, loop: true, time: 1, duration: 2 }), { play: false });
  // At the end of one that does not loop, play starts it again.
  assert.deepEqual(playChange({ playing: false, loop: false, time: 2, duration: 2 }), { play: true, scene_time: 0 });
  assert.deepEqual(playChange({ playing: false, loop: false, time: 1.5, duration: 2 }), { play: true });
  assert.deepEqual(playChange({ playing: false, loop: true, time: 2, duration: 2 }), { play: true });
  assert.deepEqual(chooseChange('Walk', true), { animation: 'Walk', scene_time: 0 });
  assert.deepEqual(chooseChange('3', false), { animation: '3', scene_time: 0 });
  assert.deepEqual(chooseChange(NONE, true), { animation: NONE, scene_time: 0, play: false });
  assert.deepEqual(chooseChange(NONE, false), { animation: NONE, scene_time: 0 });
});

test('the settings panel leaves the animation\'s fields to the Animation section', () => {
  for (const name of ANIMATION_SETTINGS) assert.equal(inPanel(name), false, name);
  assert.deepEqual([...ANIMATION_SETTINGS].sort(), ['animation', 'loop', 'play', 'scene_time']);
  assert.equal(inPanel('width'), false);
  assert.equal(inPanel('aa'), true);
  assert.equal(inPanel('light_time'), true);
});

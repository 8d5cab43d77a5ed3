// The Animation section: the scene's glTF animations (SceneInfo.animations) as a picker, a
// play/pause button, a time slider with its readout and a loop switch. They are the
// RenderSettings fields animation, play, scene_time and loop (proto/tessera/v1/settings.proto),
// sent as settings changes like every other setting; the generic settings panel leaves them to
// this section (settings.js). While the server plays an animation, each frame's settings say
// the time it shows, and the slider follows them, except while the user drags it.
// The logic above AnimationControls is DOM-free (node --test).

/** The RenderSettings fields this section owns. */
export const ANIMATION_SETTINGS = ['animation', 'scene_time', 'loop', 'play'];

/** The picker's value for "no animation" (the scene's rest pose). */
export const NONE = 'none';

/** Float32 values from the wire without their binary noise (1.2500001 -> 1.25). */
export const tidy = (v) => (Number.isFinite(v) ? Number(v.toPrecision(6)) : v);

/**
 * The animation a settings.animation value names, as tesserad looks it up (renderer.cpp
 * FindAnimation): -1 for none ("" or "none"), the first animation of that name, else an index
 * written as decimal digits; null when it names none of them (the server refuses it).
 */
export function findAnimation(animations, value) {
  const text = String(value ?? '');
  if (text === '' || text === NONE) return -1;
  const list = animations ?? [];
  const named = list.findIndex((a) => String(a?.name ?? '') === text);
  if (named >= 0) return named;
  if (/^[0-9]+$/.test(text)) {
    const index = Number(text);
    if (index < list.length) return index;
  }
  return null;
}

/** Seconds for a label: at most two decimals, no trailing zeros (2.4, 0.04, 10). */
export function formatSeconds(seconds) {
  const s = Number(seconds);
  return Number.isFinite(s) ? String(Number(s.toFixed(2)) + 0) : '?';  // + 0 turns -0 into 0
}

/**
 * The picker's options for SceneInfo.animations: "none" first, then each animation as
 * {value, label, title, index, duration, disabled}. `value` is what settings.animation gets:
 * the animation's name when that names it alone, else its index as digits (an empty or
 * duplicated name, or the name "none", which means no animation); where neither names it
 * (a name made of the digits of its index taken by another animation) the option is disabled.
 * Labels carry the duration ("Walk (2.4 s)"); a duplicated name also its index ("Walk #3").
 */
export function animationChoices(animations) {
  const list = animations ?? [];
  const count = new Map();
  for (const a of list) {
    const name = String(a?.name ?? '');
    count.set(name, (count.get(name) ?? 0) + 1);
  }
  const choices = [{ value: NONE, label: 'none (rest pose)', title: 'The scene without animation', index: -1, duration: 0, disabled: false }];
  list.forEach((a, index) => {
    const name = String(a?.name ?? '');
    const duplicated = name !== '' && count.get(name) > 1;
    const names = (v) => findAnimation(list, v) === index;
    const candidates = duplicated ? [String(index), name] : [name, String(index)];
    const value = candidates.find((v) => v !== '' && names(v));
    const duration = Math.max(0, tidy(Number(a?.duration_s)) || 0);  // float32 key times
    const shown = name === '' ? `animation ${index}` : duplicated ? `${name} #${index}` : name;
    const channels = Number(a?.channels ?? 0);
    choices.push({
      value: value ?? `#${index}`,
      label: `${shown} (${formatSeconds(duration)} s)`,
      title: `${channels} ${channels === 1 ? 'channel' : 'channels'}, ${formatSeconds(duration)} s` +
        (value === undefined ? '; the server cannot be asked for it by name or index' : ''),
      index,
      duration,
      disabled: value === undefined,
    });
  });
  return choices;
}

/** The choice that settings.animation `value` selects (the "none" choice for none), or null. */
export function choiceFor(choices, animations, value) {
  const index = findAnimation(animations, value);
  if (index === null) return null;
  return choices.find((c) => c.index === index) ?? null;
}

/** The time readout: "1.25 / 2.40 s". */
export function formatReadout(time, duration) {
  // Rounded before toFixed, so that -0.001 shows as 0.00, not -0.00.
  const fixed = (v) => (Number.isFinite(Number(v)) ? (Math.round(Number(v) * 100) / 100 + 0).toFixed(2) : '–');
  return `${fixed(time)} / ${fixed(duration)} s`;
}

/** The slider's step: a hundredth of the animation (any, for a zero-length one). */
export function sliderStep(duration) {
  const d = Number(duration);
  return d > 0 && Number.isFinite(d) ? String(tidy(d / 100)) : 'any';
}

/**
 * A setting as a frame shows it, unless the user changed it in an event the frame does not
 * reflect yet (`pendingFields`: name -> event id of its last change, as app.js keeps them; a
 * reflected change is forgotten): {value}, or null to leave the control as it is. A frame's
 * settings name the animation only when there is one: without it, it is "none".
 */
export function frameValue(frame, name, pendingFields) {
  const settings = frame?.settings;
  if (!settings || typeof settings !== 'object') return null;
  if (!(name in settings) && name !== 'animation') return null;
  const pending = pendingFields?.get(name);
  if (pending !== undefined && Number(frame.event_id ?? 0) < pending) return null;
  pendingFields?.delete(name);
  if (name === 'animation') return { value: String(settings.animation || NONE) };
  return { value: settings[name] };
}

/**
 * The time the slider and readout follow from a frame (its settings.scene_time: while playing,
 * the time the frame shows), or undefined to leave them: while the user drags the slider, and
 * until frames reflect the time the user set last.
 */
export function followTime(frame, pendingFields, dragging = false) {
  if (dragging) return undefined;
  const shown = frameValue(frame, 'scene_time', pendingFields);
  if (shown === null) return undefined;
  const t = Number(shown.value);
  return Number.isFinite(t) ? tidy(t) : undefined;
}

/**
 * The settings change of the play/pause button: play from where the time is, or pause (the
 * server keeps the time it reached). An animation that does not loop and has reached its end
 * plays again from the start.
 */
export function playChange({ playing, loop, time, duration }) {
  if (playing) return { play: false };
  const d = Number(duration);
  const atEnd = !loop && d > 0 && Number(time) >= d - Math.max(1e-3, d / 1000);
  return atEnd ? { play: true, scene_time: 0 } : { play: true };
}

/**
 * The settings change of picking an animation: it starts at time 0 (playing on if it played);
 * "none" also stops the clock.
 */
export function chooseChange(value, playing) {
  const change = { animation: String(value), scene_time: 0 };
  if (value === NONE && playing) change.play = false;
  return change;
}

/**
 * The section's controls: `elements` {section, select, play, time, readout, loop} (index.html);
 * `onChange(settings)` gets each change the user makes as RenderSettings fields to merge and
 * send; `guard(fn, context)` wraps the handlers (the page's error banner).
 */
export class AnimationControls {
  constructor(elements, onChange, guard = (fn) => fn) {
    this.ui = elements;
    this.onChange = onChange;
    this.sceneKey = null;
    this.animations = [];
    this.choices = animationChoices([]);
    this.value = NONE;       // settings.animation as the picker shows it
    this.time = 0;
    this.playing = false;
    this.loop = true;
    this.dragging = false;
    this.dragMoved = false;  // the slider moved during this drag
    this.scrubTimer = null;  // an animation frame that sends the newest scrubbed time
    this.scrubTime = null;

    const { select, play, time, loop } = elements;
    select.addEventListener('change', guard(() => this.#choose(select.value), 'Could not choose the animation'));
    play.addEventListener('click', guard(() => this.#togglePlay(), 'Could not play the animation'));
    loop.addEventListener('change', guard(() => {
      this.loop = loop.checked;
      this.#send({ loop: this.loop });
    }, 'Could not change the loop'));
    time.addEventListener('pointerdown', () => {
      this.dragging = true;
      this.dragMoved = false;
    });
    const release = guard(() => {
      if (!this.dragging) return;
      this.dragging = false;
      // Held still while playing, the picture played on from the last time sent: the play goes
      // on from where the slider was let go.
      if (this.dragMoved && this.playing && this.scrubTime === null) this.scrubTime = this.time;
      this.#flushScrub();
    }, 'Could not set the time');
    // The range input keeps the pointer while dragging; a release anywhere ends the drag.
    window.addEventListener('pointerup', release);
    window.addEventListener('pointercancel', release);
    time.addEventListener('input', guard(() => this.#scrub(Number(time.value)), 'Could not set the time'));
    time.addEventListener('change', guard(() => this.#flushScrub(), 'Could not set the time'));
    this.#render();
  }

  /** The animation picked now (its choice), or null when none is. */
  get current() {
    return this.choices.find((c) => c.value === this.value) ?? null;
  }

  /**
   * The scene shown (its SceneInfo, or null when the page has none): the picker lists its
   * animations, and the section shows only when it has some. A new scene starts at "none",
   * time 0, paused; the same scene again changes nothing.
   */
  setScene(info) {
    const animations = Array.isArray(info?.animations) ? info.animations : [];
    const key = JSON.stringify([info?.scene_id ?? '', animations]);
    if (key === this.sceneKey) return;
    this.sceneKey = key;
    this.animations = animations;
    this.choices = animationChoices(animations);
    this.value = NONE;
    this.time = 0;
    this.playing = false;
    this.dragging = false;
    this.#cancelScrub();
    const { select } = this.ui;
    select.replaceChildren(...this.choices.map((c) => {
      const option = new Option(c.label, c.value);
      option.title = c.title;
      option.disabled = c.disabled;
      return option;
    }));
    this.ui.section.hidden = animations.length === 0;
    this.#render();
  }

  /**
   * Shows a frame's effective settings: the animation, play, loop and the time it shows,
   * except what the user changed after the event the frame reflects, and the time while the
   * slider is dragged. Returns the time it showed, or undefined.
   */
  reflect(frame, pendingFields) {
    const animation = frameValue(frame, 'animation', pendingFields);
    if (animation) this.#showAnimation(animation.value);
    const play = frameValue(frame, 'play', pendingFields);
    if (play) this.playing = play.value === true;
    const loop = frameValue(frame, 'loop', pendingFields);
    if (loop) this.loop = loop.value !== false;
    const time = followTime(frame, pendingFields, this.dragging || this.scrubTimer !== null);
    if (time !== undefined) this.time = time;
    this.#render();
    return time;
  }

  /** Shows settings as they are now (after a refused change was put back). */
  show(settings) {
    this.#showAnimation(settings.animation || NONE);  // unset: none
    if ('play' in settings) this.playing = settings.play === true;
    if ('loop' in settings) this.loop = settings.loop !== false;
    if (Number.isFinite(Number(settings.scene_time)) && !this.dragging) this.time = tidy(Number(settings.scene_time));
    this.#render();
  }

  #showAnimation(value) {
    const choice = choiceFor(this.choices, this.animations, value);
    if (choice) this.value = choice.value;
  }

  #send(change) {
    this.onChange(change);
    this.#render();
  }

  #choose(value) {
    const choice = this.choices.find((c) => c.value === value);
    if (!choice || choice.disabled) {
      this.#render();
      return;
    }
    this.#cancelScrub();
    const change = chooseChange(choice.value, this.playing);
    this.value = choice.value;
    this.time = 0;
    if (change.play === false) this.playing = false;
    this.#send(change);
  }

  #togglePlay() {
    const current = this.current;
    if (!current || current.index < 0) return;
    this.#flushScrub();
    const change = playChange({ playing: this.playing, loop: this.loop, time: this.time, duration: current.duration });
    this.playing = change.play;
    if (change.scene_time !== undefined) this.time = change.scene_time;
    this.#send(change);
  }

  /** The slider moved: the readout at once, the time to the server once per animation frame. */
  #scrub(time) {
    if (!Number.isFinite(time)) return;
    this.time = time;
    this.scrubTime = time;
    if (this.dragging) this.dragMoved = true;
    this.#renderTime();
    if (this.scrubTimer === null) this.scrubTimer = requestAnimationFrame(() => this.#flushScrub());
  }

  #flushScrub() {
    if (this.scrubTimer !== null) cancelAnimationFrame(this.scrubTimer);
    this.scrubTimer = null;
    if (this.scrubTime === null) return;
    const time = this.scrubTime;
    this.scrubTime = null;
    this.onChange({ scene_time: time });
  }

  #cancelScrub() {
    if (this.scrubTimer !== null) cancelAnimationFrame(this.scrubTimer);
    this.scrubTimer = null;
    this.scrubTime = null;
  }

  #render() {
    const { select, play, loop } = this.ui;
    const current = this.current;
    const animated = current !== null && current.index >= 0;
    if (select.value !== this.value) select.value = this.value;
    play.disabled = !animated;
    play.textContent = this.playing ? 'Pause' : 'Play';
    play.setAttribute('aria-pressed', String(this.playing));
    play.title = this.playing ? 'Pause the animation (it keeps its time)' : 'Play the animation from the time shown';
    loop.checked = this.loop;
    this.#renderTime();
  }

  #renderTime() {
    const { time, readout } = this.ui;
    const current = this.current;
    const animated = current !== null && current.index >= 0;
    const duration = animated ? current.duration : 0;
    time.disabled = !animated || duration <= 0;
    time.max = String(duration);
    time.step = sliderStep(duration);
    if (!this.dragging) time.value = String(Math.min(Math.max(this.time, 0), duration));
    time.setAttribute('aria-valuetext', formatReadout(this.time, duration));
    readout.textContent = formatReadout(this.time, duration);
  }
}

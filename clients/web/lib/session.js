// What a live session was asked for, as the gateway keeps it to open the session again on
// another replica (failover), and when it does.
//
// The state is an OpenSession (scene, camera, settings, target_fps, interactive, video) that every
// ClientEvent the page sends updates the way tesserad updates its session (server/
// stream_session.cpp ApplyUpdateLocked, convert.cpp MergeProfile/MergeVideo, settings_wire.cpp
// MergeSettings): a camera replaces the camera; settings, interactive and video are merged field
// by field, set fields only (every field of the three is a scalar: proto3 `optional`, or an enum
// whose 0 value means "keep"; settings.animation, a string, is set when not empty: tesserad
// keeps the animation on an empty one); target_fps replaces when set. While an animation plays,
// the frames' scene time is kept too (followPlay), so a moved session goes on from there.
//
// Messages here are normalized: parsed by the proto's own deserializer after the serializer
// checked them (connection.js), so an unset optional field is absent, an unset enum is its
// *_UNSPECIFIED name and an unset message is null.

const MERGED = ['settings', 'interactive', 'video'];
// String fields whose empty value means "unchanged" to tesserad (settings_wire.cpp
// MergeSettings): the animation. (VideoSettings.preset is not one: "" is refused there.)
const EMPTY_KEEPS = { settings: new Set(['animation']) };

/** A set field of a normalized message: present, and not an enum's "unspecified" value. */
export function isSet(value) {
  if (value === undefined || value === null) return false;
  if (typeof value === 'string' && value.endsWith('_UNSPECIFIED')) return false;
  return true;
}

/**
 * `update`'s set fields over `base` (neither is changed); nested messages replace. Fields named
 * in `emptyKeeps` are not set by an empty string.
 */
export function mergeSet(base, update, emptyKeeps = null) {
  const out = { ...(base ?? {}) };
  if (update === null || typeof update !== 'object') return out;
  for (const [key, value] of Object.entries(update)) {
    if (!isSet(value) || (value === '' && emptyKeeps?.has(key))) continue;
    out[key] = value;
  }
  return out;
}

/** Only the set fields of a message (what an OpenSession needs to carry). */
export function setFields(message, emptyKeeps = null) {
  return mergeSet({}, message, emptyKeeps);
}

/** The state of a session opened with `open` (a normalized OpenSession). */
export function stateFromOpen(open) {
  const state = { scene_id: String(open?.scene_id ?? '') };
  if (isSet(open?.camera)) state.camera = open.camera;
  for (const key of MERGED) if (isSet(open?.[key])) state[key] = setFields(open[key], EMPTY_KEEPS[key]);
  const fps = Number(open?.target_fps ?? 0);
  if (fps > 0) state.target_fps = fps;
  return state;
}

/** The state after the page's `event` (a normalized ClientEvent); `state` is not changed. */
export function mergeEvent(state, event) {
  if (!event || typeof event !== 'object') return state;
  const next = { ...state };
  if (isSet(event.camera)) next.camera = event.camera;
  for (const key of MERGED) {
    if (isSet(event[key])) next[key] = mergeSet(next[key], event[key], EMPTY_KEEPS[key]);
  }
  if (event.target_fps !== undefined && event.target_fps !== null) {
    const fps = Number(event.target_fps);
    if (fps > 0) next.target_fps = fps;
    else delete next.target_fps;
  }
  return next;
}

/**
 * The state after a frame of the session: while its animation plays (settings.play, asked for
 * and shown), the scene time the frame shows becomes the state's scene_time, so a move opens the
 * session again where the animation had got to (tesserad starts the clock at the open's
 * scene_time) rather than where it was last set; a frame that shows it stopped (at the end of a
 * non-looping animation) stops it in the state too. Only a frame that reflects the newest event the
 * page sent (`newestEventId`) counts: a time the page set since then wins. Returns `state`
 * itself when nothing changes (it is never changed).
 */
export function followPlay(state, frame, newestEventId = 0) {
  const shown = frame?.settings;
  if (!shown || typeof shown.play !== 'boolean' || state?.settings?.play !== true) return state;
  if (Number(frame.event_id ?? 0) < Number(newestEventId ?? 0)) return state;
  const time = Number(shown.scene_time);
  if (!Number.isFinite(time)) return state;
  // Shown stopped while asked to play: a non-looping animation reached its end and tesserad
  // stopped it; a move must not play it again.
  if (shown.play === false) return { ...state, settings: { ...state.settings, play: false, scene_time: time } };
  if (state.settings.scene_time === time) return state;
  return { ...state, settings: { ...state.settings, scene_time: time } };
}

/**
 * What a frame says of its session, for a session the gateway resumed (it never saw the open):
 * the scene, the camera the frame was rendered with, and whether it is video.
 */
export function seenInFrame(frame) {
  const seen = { scene_id: String(frame.scene_id ?? '') };
  if (frame.camera) seen.camera = { look_at: frame.camera, ...(Number(frame.yfov) > 0 ? { yfov: Number(frame.yfov) } : {}) };
  if (frame.encoding === 'VIDEO_H264') seen.video = { codec: 'VIDEO_CODEC_H264' };
  return seen;
}

/**
 * The state of a resumed session: what the page sent since the resume (`state`; a page resends
 * its settings, size, video and camera at once), completed by what its frames said (`seen`).
 */
export function completeState(state, seen) {
  if (!seen) return state;
  const out = { ...state };
  if (!out.scene_id) out.scene_id = seen.scene_id;
  if (!out.camera && seen.camera) out.camera = seen.camera;
  if (seen.video) out.video = mergeSet(seen.video, out.video);
  return out;
}

/** The OpenSession that opens `state` again (no resume token: a new session). */
export function openFromState(state) {
  const open = { scene_id: state.scene_id };
  if (state.camera) open.camera = state.camera;
  for (const key of MERGED) if (state[key]) open[key] = { ...state[key] };
  if (state.target_fps > 0) open.target_fps = state.target_fps;
  return open;
}

/** The gRPC status codes the gateway's streams decide on. */
export const STATUS = Object.freeze({ OK: 0, CANCELLED: 1, RESOURCE_EXHAUSTED: 8, UNAVAILABLE: 14 });

/**
 * Whether a stream that ended with `status` moves to another replica:
 *   'move'    its replica is gone (UNAVAILABLE: killed, unreachable, shutting down) and the
 *             session can be opened again elsewhere;
 *   'give_up' it would, but it has moved too often lately;
 *   'end'     anything else: the end goes to the page. A normal end (OK, the page closed or
 *             cancelled it, a bad event: INVALID_ARGUMENT, NOT_FOUND...) never moves, nor does
 *             a stream whose page is away (parked), a resume that never had a frame (the page
 *             opens afresh), a gateway with one server or one that is stopping.
 */
export function failoverDecision(status, {
  closing = false, cancelled = false, parked = false, stopping = false, single = false,
  sceneKnown = true, budgetLeft = true, full = false,
} = {}) {
  // `full`: the replica refused the session at its max_sessions before any frame (it filled up
  // since the poll that placed it there): another replica may take it.
  const lost = status?.code === STATUS.UNAVAILABLE ||
    (full && status?.code === STATUS.RESOURCE_EXHAUSTED);
  if (!lost) return 'end';
  if (closing || cancelled || parked || stopping || single || !sceneKnown) return 'end';
  return budgetLeft ? 'move' : 'give_up';
}

/** At most `max` moves in any `windowMs`. */
export class MoveBudget {
  constructor({ max = 3, windowMs = 60_000, now = Date.now } = {}) {
    this.max = max;
    this.windowMs = windowMs;
    this.now = now;
    this.times = [];
  }

  prune() {
    const since = this.now() - this.windowMs;
    this.times = this.times.filter((t) => t > since);
  }

  get left() {
    this.prune();
    return this.max - this.times.length;
  }

  /** Spends one move; false when none is left. */
  take() {
    if (this.left <= 0) return false;
    this.times.push(this.now());
    return true;
  }
}

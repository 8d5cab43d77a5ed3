// Camera math for the viewer: an orbit camera (yaw/pitch/distance around a target) that also
// flies (WASD). Pure: no DOM, no globals, so it runs under `node --test`.
//
// Conventions: glTF's right-handed, Y-up world. The camera sits at
//   eye = target + distance * (cos(pitch) sin(yaw), sin(pitch), cos(pitch) cos(yaw))
// and looks at the target, with world +Y as its up. Pitch stays short of the poles so up is
// never parallel to the view direction (the server rejects that camera), and every entry
// point ignores non-finite input, so no NaN can reach the wire.

/** Largest |pitch|, radians: ~88.9 degrees, short of the poles. */
export const PITCH_LIMIT = Math.PI / 2 - 0.02;

/** Fly speed in orbit distances per second, and the Shift multiplier. */
export const FLY_SPEED = 0.6;
export const FLY_FAST = 4;

const EPSILON = 1e-9;
const WORLD_UP = Object.freeze({ x: 0, y: 1, z: 0 });
// The server's own framing direction (FrameBounds.direction default), used when a camera
// gives us nothing to go on (eye == target).
const DEFAULT_DIRECTION = Object.freeze({ x: 0.55, y: 0.45, z: 0.7 });

// ---- vectors: plain {x, y, z} objects, never mutated ----

export const vec3 = {
  of: (x, y, z) => ({ x, y, z }),
  add: (a, b) => ({ x: a.x + b.x, y: a.y + b.y, z: a.z + b.z }),
  sub: (a, b) => ({ x: a.x - b.x, y: a.y - b.y, z: a.z - b.z }),
  scale: (a, s) => ({ x: a.x * s, y: a.y * s, z: a.z * s }),
  dot: (a, b) => a.x * b.x + a.y * b.y + a.z * b.z,
  cross: (a, b) => ({
    x: a.y * b.z - a.z * b.y,
    y: a.z * b.x - a.x * b.z,
    z: a.x * b.y - a.y * b.x,
  }),
  length: (a) => Math.hypot(a.x, a.y, a.z),
  /** `a` scaled to length 1, or `fallback` when `a` is (nearly) zero or not finite. */
  normalize(a, fallback = { x: 0, y: 0, z: 1 }) {
    const len = vec3.length(a);
    return Number.isFinite(len) && len > EPSILON ? vec3.scale(a, 1 / len) : { ...fallback };
  },
  isFinite: (a) =>
    a != null && Number.isFinite(a.x) && Number.isFinite(a.y) && Number.isFinite(a.z),
};

/** A {x, y, z} from a proto Vec3 in JSON, where proto3 leaves zero fields out. */
export function toVec3(v) {
  const num = (n) => (Number.isFinite(Number(n)) ? Number(n) : 0);
  return { x: num(v?.x), y: num(v?.y), z: num(v?.z) };
}

const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
const finite = (...values) => values.every(Number.isFinite);

/** Unit vector from the target towards the eye for a yaw and pitch. */
function orbitDirection(yaw, pitch) {
  const c = Math.cos(pitch);
  return { x: c * Math.sin(yaw), y: Math.sin(pitch), z: c * Math.cos(yaw) };
}

export class OrbitCamera {
  // The eye exactly as fromLookAt got it, until the camera moves: yaw/pitch/distance
  // reproduce it only to rounding, and a camera nobody moved should be the server's own.
  #exactEye = null;

  /**
   * @param {object} o
   * @param {{x,y,z}} o.target  point orbited around
   * @param {number} o.distance eye-target distance, > 0
   * @param {number} o.yaw      radians around world Y
   * @param {number} o.pitch    radians above the horizon (clamped)
   * @param {number} [o.scale]  size of the scene (world units): bounds zoom and fly speed
   */
  constructor({ target = { x: 0, y: 0, z: 0 }, distance = 1, yaw = 0, pitch = 0, scale } = {}) {
    const d = Number.isFinite(distance) && distance > EPSILON ? distance : 1;
    this.target = vec3.isFinite(target) ? { ...target } : { x: 0, y: 0, z: 0 };
    this.scale = Number.isFinite(scale) && scale > EPSILON ? scale : d;
    this.distance = this.#clampDistance(d);
    this.yaw = Number.isFinite(yaw) ? yaw : 0;
    this.pitch = clamp(Number.isFinite(pitch) ? pitch : 0, -PITCH_LIMIT, PITCH_LIMIT);
  }

  /**
   * The orbit state that reproduces a LookAt {eye, target, up} (e.g. Frame.camera). The up
   * vector is not kept: the orbit always uses world +Y. Degenerate input (eye == target,
   * missing or non-finite fields) gives a usable camera, never NaN.
   */
  static fromLookAt(lookAt) {
    const eye = toVec3(lookAt?.eye);
    const target = toVec3(lookAt?.target);
    const offset = vec3.sub(eye, target);
    const length = vec3.length(offset);
    const degenerate = !(length > EPSILON && Number.isFinite(length));
    const distance = degenerate ? 1 : length;
    const dir = degenerate ? vec3.normalize(DEFAULT_DIRECTION) : vec3.scale(offset, 1 / length);
    const pitch = Math.asin(clamp(dir.y, -1, 1));
    const camera = new OrbitCamera({
      target, distance, yaw: Math.atan2(dir.x, dir.z), pitch, scale: distance,
    });
    // The given eye is the orbit's eye unless it was replaced or its pitch clamped.
    if (!degenerate && Math.abs(pitch) <= PITCH_LIMIT) camera.#exactEye = eye;
    return camera;
  }

  /** The eye position. */
  get eye() {
    if (this.#exactEye) return { ...this.#exactEye };
    return vec3.add(this.target, vec3.scale(orbitDirection(this.yaw, this.pitch), this.distance));
  }

  /** Unit view direction (eye -> target). */
  get forward() {
    return vec3.scale(orbitDirection(this.yaw, this.pitch), -1);
  }

  /** Unit vector to the right of the view, horizontal. */
  get right() {
    // Pitch never reaches the poles, so forward x up is never zero; the fallback is belt and braces.
    return vec3.normalize(vec3.cross(this.forward, WORLD_UP), { x: 1, y: 0, z: 0 });
  }

  /** Unit camera up (perpendicular to forward and right). */
  get up() {
    return vec3.normalize(vec3.cross(this.right, this.forward), WORLD_UP);
  }

  /** The camera as a proto LookAt: {eye, target, up}. */
  lookAt() {
    return { eye: this.eye, target: { ...this.target }, up: { ...WORLD_UP } };
  }

  /** Orbit around the target by yaw/pitch angles (radians). */
  orbit(dYaw, dPitch) {
    if (!finite(dYaw, dPitch)) return;
    this.#exactEye = null;
    this.yaw = wrapAngle(this.yaw + dYaw);
    this.pitch = clamp(this.pitch + dPitch, -PITCH_LIMIT, PITCH_LIMIT);
  }

  /** Multiply the eye-target distance by `factor` (< 1 moves closer). */
  dolly(factor) {
    if (!(Number.isFinite(factor) && factor > 0)) return;
    this.#exactEye = null;
    this.distance = this.#clampDistance(this.distance * factor);
  }

  /**
   * Move the target (and eye) in the view plane so the point under the cursor follows it:
   * a drag of (dx, dy) pixels on a viewport `viewportHeight` pixels tall with vertical field
   * of view `yfov` (radians). Screen y grows downwards.
   */
  pan(dx, dy, viewportHeight, yfov) {
    if (!finite(dx, dy, viewportHeight, yfov) || viewportHeight <= 0 || yfov <= 0) return;
    const worldPerPixel = (2 * this.distance * Math.tan(Math.min(yfov, 3) / 2)) / viewportHeight;
    const move = vec3.add(vec3.scale(this.right, -dx * worldPerPixel),
                          vec3.scale(this.up, dy * worldPerPixel));
    this.#moveTarget(vec3.add(this.target, move));
  }

  /** Fly mode: turn the view around the eye (the eye stays put). Same signs as orbit(). */
  look(dYaw, dPitch) {
    if (!finite(dYaw, dPitch)) return;
    const eye = this.eye;
    const yaw = wrapAngle(this.yaw + dYaw);
    const pitch = clamp(this.pitch + dPitch, -PITCH_LIMIT, PITCH_LIMIT);
    const target = vec3.sub(eye, vec3.scale(orbitDirection(yaw, pitch), this.distance));
    if (!vec3.isFinite(target)) return;
    this.#exactEye = null;
    this.yaw = yaw;
    this.pitch = pitch;
    this.target = target;
  }

  /**
   * Fly mode: move eye and target together for `dt` seconds. `move` is {forward, right, up},
   * each in -1..1 (forward along the view, right horizontal, up along world Y). The speed
   * follows the orbit distance, so it suits the scene's size and slows down after zooming in.
   */
  fly(move, dt, fast = false) {
    const { forward = 0, right = 0, up = 0 } = move ?? {};
    if (!finite(forward, right, up, dt) || dt <= 0) return;
    const speed = FLY_SPEED * this.distance * (fast ? FLY_FAST : 1);
    let v = vec3.add(vec3.scale(this.forward, forward), vec3.scale(this.right, right));
    v = vec3.add(v, vec3.scale(WORLD_UP, up));
    const len = vec3.length(v);
    if (!(len > EPSILON)) return;
    // Diagonals are not faster than straight moves.
    const step = (speed * dt) / Math.max(1, len);
    this.#moveTarget(vec3.add(this.target, vec3.scale(v, step)));
  }

  // Moves the target (the eye follows) unless that would overflow to a non-finite camera.
  #moveTarget(target) {
    const eye = vec3.add(target, vec3.sub(this.eye, this.target));
    if (vec3.isFinite(target) && vec3.isFinite(eye)) {
      this.target = target;
      if (this.#exactEye) this.#exactEye = eye;
    }
  }

  #clampDistance(d) {
    return clamp(d, this.scale * 1e-4, this.scale * 1e4);
  }
}

/** An angle wrapped into (-pi, pi], so yaw never grows without bound. */
function wrapAngle(a) {
  const twoPi = 2 * Math.PI;
  let r = a % twoPi;  // exact, even for huge angles
  if (r > Math.PI) r -= twoPi;
  if (r <= -Math.PI) r += twoPi;
  return r;
}

// ---- input helpers ----

/** Radians of orbit (or look) per pixel dragged on a viewport `heightPx` tall. */
export function anglePerPixel(heightPx) {
  return 2.5 / Math.max(100, Number.isFinite(heightPx) ? heightPx : 100);
}

/**
 * The dolly factor for a wheel event: deltaY in pixels, lines (deltaMode 1) or pages
 * (deltaMode 2). Scrolling down (positive) moves away; one notch (~100 px) is ~16%.
 */
export function wheelFactor(deltaY, deltaMode = 0, pageHeightPx = 800) {
  if (!Number.isFinite(deltaY)) return 1;
  const px = deltaMode === 1 ? deltaY * 16 : deltaMode === 2 ? deltaY * pageHeightPx : deltaY;
  return Math.exp(clamp(px, -500, 500) * 0.0015);
}

/**
 * Two-finger gesture between two pointer pairs ([{x, y}, {x, y}] before and after): the dolly
 * factor (fingers apart = closer) and the pan of their midpoint in pixels.
 */
export function pinchGesture(before, after) {
  const dist = (p) => Math.hypot(p[0].x - p[1].x, p[0].y - p[1].y);
  const mid = (p) => ({ x: (p[0].x + p[1].x) / 2, y: (p[0].y + p[1].y) / 2 });
  const d0 = dist(before);
  const d1 = dist(after);
  const factor = d0 > 1 && d1 > 1 ? d0 / d1 : 1;
  const m0 = mid(before);
  const m1 = mid(after);
  return { factor: Number.isFinite(factor) ? factor : 1, dx: m1.x - m0.x, dy: m1.y - m0.y };
}

/** Fly movement keys (KeyboardEvent.code) and what they add to {forward, right, up}. */
const FLY_KEYS = {
  KeyW: ['forward', 1],
  KeyS: ['forward', -1],
  KeyD: ['right', 1],
  KeyA: ['right', -1],
  KeyE: ['up', 1],
  KeyQ: ['up', -1],
  ArrowUp: ['forward', 1],
  ArrowDown: ['forward', -1],
  ArrowRight: ['right', 1],
  ArrowLeft: ['right', -1],
};

/** Whether a KeyboardEvent.code moves the camera in fly mode. */
export const isFlyKey = (code) => Object.hasOwn(FLY_KEYS, code);

/** The movement {forward, right, up} for a set of held key codes (opposites cancel). */
export function flyVector(heldCodes) {
  const v = { forward: 0, right: 0, up: 0 };
  for (const code of heldCodes) {
    const entry = FLY_KEYS[code];
    if (entry) v[entry[0]] += entry[1];
  }
  for (const k of Object.keys(v)) v[k] = clamp(v[k], -1, 1);
  return v;
}

/**
 * Pointer input (mouse, touch, pen) as camera moves. Pure: the page passes plain records
 * {id, x, y, button, shiftKey} in CSS pixels. One pointer orbits (pans with the right or
 * middle button or Shift; looks around in fly mode); two pointers pinch-zoom and pan.
 */
export class PointerGestures {
  constructor() {
    this.pointers = new Map();  // id -> {x, y}
    this.mode = null;           // 'orbit' | 'pan' | 'look' while one pointer drags
  }

  /** A pointer went down. */
  down({ id, x, y, button = 0, shiftKey = false }, fly = false) {
    this.pointers.set(id, { x, y });
    if (this.pointers.size === 1) {
      this.mode = button === 1 || button === 2 || shiftKey ? 'pan' : fly ? 'look' : 'orbit';
    }
  }

  /**
   * A pointer moved: applies the gesture to `camera` (when not null) for a viewport
   * `height` CSS pixels tall with field of view `yfov`. Returns whether the camera moved.
   */
  move({ id, x, y }, camera, { height, yfov }) {
    const prev = this.pointers.get(id);
    if (!prev || !finite(x, y)) return false;
    if (this.pointers.size >= 2) {
      const ids = [...this.pointers.keys()].slice(0, 2);  // a third finger is ignored
      if (!ids.includes(id)) return false;
      const before = ids.map((i) => this.pointers.get(i));
      this.pointers.set(id, { x, y });
      const after = ids.map((i) => this.pointers.get(i));
      if (!camera) return false;
      const g = pinchGesture(before, after);
      camera.dolly(g.factor);
      camera.pan(g.dx, g.dy, height, yfov);
      return true;
    }
    this.pointers.set(id, { x, y });
    if (!camera) return false;
    const dx = x - prev.x;
    const dy = y - prev.y;
    const k = anglePerPixel(height);
    // Dragging right turns the scene (orbit) or the view (look) to the right; dragging down
    // lifts the eye (orbit) or looks down (look).
    if (this.mode === 'pan') camera.pan(dx, dy, height, yfov);
    else if (this.mode === 'look') camera.look(-dx * k, dy * k);
    else camera.orbit(-dx * k, dy * k);
    return true;
  }

  /** A pointer went up or was cancelled; a finger left over from a pinch drags on. */
  up(id, fly = false) {
    this.pointers.delete(id);
    if (this.pointers.size === 1) this.mode = fly ? 'look' : 'orbit';
    if (this.pointers.size === 0) this.mode = null;
  }

  /** Fly mode turned on or off mid-drag. */
  setFly(fly) {
    if (this.mode === 'orbit' || this.mode === 'look') this.mode = fly ? 'look' : 'orbit';
  }
}

// ---- the view in the page's URL (location.hash) ----
//
//   #scene=<id>&eye=x,y,z&target=x,y,z[&up=x,y,z]&fov=<degrees>
//
// Every part is optional; `up` is written only when it is not +Y. Links come from anyone, so
// parsing checks everything and drops what it cannot use, saying why in `problems`.

/** The largest |coordinate| a link may carry (world units), and the longest link read. */
export const LINK_MAX_COORD = 1e7;
export const LINK_MAX_LENGTH = 2048;
/** Vertical field of view a link may ask for, in degrees (the server takes (0, 3.1) radians). */
export const LINK_FOV_MIN = 1;
export const LINK_FOV_MAX = 170;

const SCENE_ID = /^(demo|[0-9a-f]{8,64})$/;
const NUMBER = /^[+-]?(\d+\.?\d*|\.\d+)(e[+-]?\d+)?$/i;

/** A number as a link writes it: 6 significant digits, no exponent for link-sized values. */
const linkNumber = (v) => String(Number(v.toPrecision(6)) + 0);  // + 0 turns -0 into 0

/** "x,y,z" as a vector within the link's bounds, or a problem (a string). */
function linkVec3(text, key) {
  const parts = text.split(',');
  if (parts.length !== 3 || !parts.every((p) => NUMBER.test(p.trim()))) {
    return `${key}: wants three numbers x,y,z`;
  }
  const [x, y, z] = parts.map(Number);
  if (![x, y, z].every((v) => Number.isFinite(v) && Math.abs(v) <= LINK_MAX_COORD)) {
    return `${key}: numbers must be finite and within ±${LINK_MAX_COORD}`;
  }
  return { x, y, z };
}

/**
 * Reads a view from a URL hash ("#scene=...&eye=..."). Returns
 *   {sceneId?, lookAt?: {eye, target, up?}, yfov? (radians), problems: [string]}
 * with only the parts that are valid: a scene id (64 hex digits, an 8+ digit prefix, or
 * "demo"), eye and target together (distinct, finite, bounded), an up that is not zero or
 * parallel to the view, a field of view in [1, 170] degrees. Unknown keys are ignored. Never
 * throws.
 */
export function parseViewLink(hash) {
  const out = { problems: [] };
  const text = String(hash ?? '').replace(/^#/, '');
  if (text === '') return out;
  if (text.length > LINK_MAX_LENGTH) {
    out.problems.push(`the link's view is longer than ${LINK_MAX_LENGTH} characters`);
    return out;
  }
  const params = new Map();
  for (const pair of text.split('&')) {
    if (pair === '') continue;
    const at = pair.indexOf('=');
    const key = at < 0 ? pair : pair.slice(0, at);
    let value = at < 0 ? '' : pair.slice(at + 1);
    try {
      value = decodeURIComponent(value);
    } catch {
      out.problems.push(`${key}: not readable`);
      continue;
    }
    if (!params.has(key)) params.set(key, value);
  }

  if (params.has('scene')) {
    const id = params.get('scene');
    if (SCENE_ID.test(id)) out.sceneId = id;
    else out.problems.push('scene: not a scene id');
  }
  if (params.has('fov')) {
    const deg = NUMBER.test(params.get('fov')) ? Number(params.get('fov')) : NaN;
    if (deg >= LINK_FOV_MIN && deg <= LINK_FOV_MAX) out.yfov = (deg * Math.PI) / 180;
    else out.problems.push(`fov: wants degrees from ${LINK_FOV_MIN} to ${LINK_FOV_MAX}`);
  }
  const hasEye = params.has('eye');
  const hasTarget = params.has('target');
  if (!hasEye && !hasTarget) {
    if (params.has('up')) out.problems.push('up: needs eye and target');
    return out;
  }
  if (hasEye !== hasTarget) {
    out.problems.push(`${hasEye ? 'eye' : 'target'}: needs ${hasEye ? 'target' : 'eye'} too`);
    return out;
  }
  const eye = linkVec3(params.get('eye'), 'eye');
  const target = linkVec3(params.get('target'), 'target');
  const up = params.has('up') ? linkVec3(params.get('up'), 'up') : null;
  const bad = [eye, target, up].filter((v) => typeof v === 'string');
  if (bad.length > 0) {
    out.problems.push(...bad);
    return out;
  }
  const view = vec3.sub(target, eye);
  const size = Math.max(1, vec3.length(eye), vec3.length(target));
  if (!(vec3.length(view) > 1e-6 * size)) {
    out.problems.push('target: equals eye');
    return out;
  }
  if (up) {
    const side = vec3.length(vec3.cross(vec3.normalize(view), vec3.normalize(up, { x: 0, y: 0, z: 0 })));
    if (!(side > 1e-3)) {
      out.problems.push('up: zero or parallel to the view');
      return out;
    }
  }
  out.lookAt = up ? { eye, target, up } : { eye, target };
  return out;
}

/**
 * The hash for a view {sceneId, lookAt?: {eye, target, up?}, yfov? (radians)}, without the
 * '#': what parseViewLink reads back (to 6 significant digits). `up` is left out when +Y.
 */
export function formatViewLink({ sceneId, lookAt, yfov } = {}) {
  const parts = [];
  if (sceneId) parts.push(`scene=${encodeURIComponent(sceneId)}`);
  const vec = (v) => [v.x, v.y, v.z].map(linkNumber).join(',');
  if (lookAt && vec3.isFinite(lookAt.eye) && vec3.isFinite(lookAt.target)) {
    parts.push(`eye=${vec(lookAt.eye)}`, `target=${vec(lookAt.target)}`);
    const up = lookAt.up;
    if (vec3.isFinite(up) && !(up.x === 0 && up.z === 0 && up.y > 0)) parts.push(`up=${vec(up)}`);
  }
  if (Number.isFinite(yfov) && yfov > 0) parts.push(`fov=${linkNumber((yfov * 180) / Math.PI)}`);
  return parts.join('&');
}

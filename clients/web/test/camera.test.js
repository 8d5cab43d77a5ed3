// Unit tests of the viewer's camera math (public/camera.js): no browser needed.
import { test } from 'node:test';
import assert from 'node:assert/strict';

import {
  FLY_FAST, LINK_MAX_LENGTH, OrbitCamera, PITCH_LIMIT, PointerGestures, anglePerPixel, flyVector,
  formatViewLink, isFlyKey, parseViewLink, pinchGesture, vec3, wheelFactor,
} from '../public/camera.js';

const near = (a, b, eps = 1e-9, what = '') =>
  assert.ok(Math.abs(a - b) <= eps * Math.max(1, Math.abs(a), Math.abs(b)), `${what} ${a} != ${b}`);
const nearVec = (a, b, eps = 1e-9) => {
  near(a.x, b.x, eps, 'x');
  near(a.y, b.y, eps, 'y');
  near(a.z, b.z, eps, 'z');
};
const assertFiniteCamera = (cam) => {
  const { eye, target, up } = cam.lookAt();
  for (const v of [eye, target, up]) assert.ok(vec3.isFinite(v), JSON.stringify(cam.lookAt()));
  assert.ok(cam.distance > 0);
};
const sample = () => OrbitCamera.fromLookAt({
  eye: { x: 3, y: 2, z: 5 }, target: { x: 1, y: 0.5, z: -1 }, up: { x: 0, y: 1, z: 0 },
});

test('fromLookAt reproduces the eye and target it was given', () => {
  const cases = [
    [{ x: 0, y: 0, z: 5 }, { x: 0, y: 0, z: 0 }],
    [{ x: 3, y: 2, z: 5 }, { x: 1, y: 0.5, z: -1 }],
    [{ x: -10, y: -4, z: 0.5 }, { x: 2, y: 2, z: 2 }],
    [{ x: 1e-3, y: 2e-3, z: -1e-3 }, { x: 0, y: 0, z: 0 }],
  ];
  for (const [eye, target] of cases) {
    const cam = OrbitCamera.fromLookAt({ eye, target, up: { x: 0, y: 1, z: 0 } });
    assert.deepEqual(cam.lookAt().eye, eye);  // exactly, until the camera moves
    cam.orbit(0, 0);
    nearVec(cam.eye, eye, 1e-9);
    nearVec(cam.target, target);
    nearVec(cam.lookAt().up, { x: 0, y: 1, z: 0 });
  }
});

test('fromLookAt accepts proto3 JSON with zero fields left out', () => {
  const cam = OrbitCamera.fromLookAt({ eye: { z: 4 }, target: {} });
  nearVec(cam.eye, { x: 0, y: 0, z: 4 });
  nearVec(cam.target, { x: 0, y: 0, z: 0 });
});

test('degenerate cameras never give NaN', () => {
  const inputs = [
    { eye: { x: 1, y: 1, z: 1 }, target: { x: 1, y: 1, z: 1 } },  // eye == target
    {},
    null,
    { eye: { x: NaN, y: Infinity, z: 'a' }, target: { x: 0, y: 0, z: 0 } },
    { eye: { x: 0, y: 5, z: 0 }, target: { x: 0, y: 0, z: 0 } },   // straight above: a pole
    { eye: { x: 0, y: -5, z: 0 }, target: { x: 0, y: 0, z: 0 } },  // straight below
    { eye: { x: 1e308, y: 0, z: 0 }, target: { x: -1e308, y: 0, z: 0 } },  // overflowing distance
  ];
  for (const input of inputs) {
    const cam = OrbitCamera.fromLookAt(input);
    assertFiniteCamera(cam);
    assert.ok(Math.abs(cam.pitch) <= PITCH_LIMIT);
    // Up (world Y) is never parallel to the view direction.
    const { eye, target, up } = cam.lookAt();
    const along = Math.abs(vec3.dot(vec3.normalize(vec3.sub(target, eye)), up));
    assert.ok(along < 0.9999, `up parallel to the view for ${JSON.stringify(input)}`);
  }
});

test('the constructor repairs what it is given', () => {
  for (const distance of [NaN, -1, 0, Infinity]) assertFiniteCamera(new OrbitCamera({ distance }));
  assertFiniteCamera(new OrbitCamera({ target: { x: NaN, y: 0, z: 0 }, yaw: NaN, pitch: 99, scale: -3 }));
  assert.equal(new OrbitCamera({ pitch: 99 }).pitch, PITCH_LIMIT);
});

test('orbit keeps the target and distance, and stops short of the poles', () => {
  const cam = sample();
  const { distance } = cam;
  const target = { ...cam.target };
  cam.orbit(0.7, 0.3);
  nearVec(cam.target, target);
  near(vec3.length(vec3.sub(cam.eye, cam.target)), distance, 1e-9);
  cam.orbit(0, 100);
  assert.equal(cam.pitch, PITCH_LIMIT);
  cam.orbit(0, -100);
  assert.equal(cam.pitch, -PITCH_LIMIT);
  cam.orbit(1000, 0);  // yaw wraps instead of growing
  assert.ok(Math.abs(cam.yaw) <= Math.PI);
  cam.orbit(NaN, Infinity);  // ignored
  assertFiniteCamera(cam);
});

test('dolly is multiplicative and bounded', () => {
  const cam = sample();
  const d = cam.distance;
  cam.dolly(0.5);
  cam.dolly(0.5);
  near(cam.distance, d * 0.25);
  cam.dolly(4);
  near(cam.distance, d);
  for (const bad of [0, -1, NaN, Infinity, undefined]) cam.dolly(bad);
  near(cam.distance, d);
  for (let i = 0; i < 200; i++) cam.dolly(0.5);
  assert.ok(cam.distance > 0 && cam.distance >= d * 1e-4 * 0.999);
  for (let i = 0; i < 400; i++) cam.dolly(2);
  assert.ok(Number.isFinite(cam.distance) && cam.distance <= d * 1e4 * 1.001);
});

test('pan moves eye and target in the view plane, following the cursor', () => {
  const cam = OrbitCamera.fromLookAt({ eye: { x: 0, y: 0, z: 10 }, target: { x: 0, y: 0, z: 0 } });
  const yfov = 0.8;
  const height = 500;
  cam.pan(height, 0, height, yfov);  // drag right by one viewport height
  // The scene follows the cursor: the camera moves left, by the view's height at the target.
  near(cam.target.x, -2 * 10 * Math.tan(yfov / 2), 1e-9);
  near(cam.target.y, 0, 1e-12);
  near(cam.target.z, 0, 1e-12);
  near(cam.eye.z, 10);
  const before = { ...cam.target };
  cam.pan(0, 100, height, yfov);  // drag down: the camera moves up
  assert.ok(cam.target.y > before.y);
  const moved = vec3.sub(cam.target, before);
  near(vec3.dot(moved, cam.forward), 0, 1e-9);
  cam.pan(NaN, 1, height, yfov);
  cam.pan(1, 1, 0, yfov);
  assertFiniteCamera(cam);
});

test('look turns the view around a fixed eye, in the direction of the drag', () => {
  const cam = sample();
  const eye = cam.eye;
  const right = cam.right;
  const k = anglePerPixel(600);
  cam.look(-50 * k, 0);  // drag right
  nearVec(cam.eye, eye, 1e-9);
  assert.ok(vec3.dot(cam.forward, right) > 0, 'dragging right looks right');
  const fwdY = cam.forward.y;
  cam.look(0, 40 * k);  // drag down
  assert.ok(cam.forward.y < fwdY, 'dragging down looks down');
  cam.look(0, 100);
  nearVec(cam.eye, eye, 1e-9);
  assert.equal(cam.pitch, PITCH_LIMIT);
  assertFiniteCamera(cam);
});

test('fly moves eye and target together, at a speed that follows the orbit distance', () => {
  const cam = OrbitCamera.fromLookAt({ eye: { x: 0, y: 0, z: 10 }, target: { x: 0, y: 0, z: 0 } });
  const eye = cam.eye;
  cam.fly({ forward: 1 }, 1);
  const step = vec3.sub(cam.eye, eye);
  near(vec3.dot(vec3.normalize(step), cam.forward), 1, 1e-12);
  const slow = vec3.length(step);

  const far = OrbitCamera.fromLookAt({ eye: { x: 0, y: 0, z: 100 }, target: { x: 0, y: 0, z: 0 } });
  const farEye = far.eye;
  far.fly({ forward: 1 }, 1);
  near(vec3.length(vec3.sub(far.eye, farEye)), slow * 10, 1e-9);

  const fast = OrbitCamera.fromLookAt({ eye: { x: 0, y: 0, z: 10 }, target: { x: 0, y: 0, z: 0 } });
  fast.fly({ forward: 1 }, 1, true);
  near(vec3.length(vec3.sub(fast.eye, eye)), slow * FLY_FAST, 1e-9);

  const diagonal = OrbitCamera.fromLookAt({ eye: { x: 0, y: 0, z: 10 }, target: { x: 0, y: 0, z: 0 } });
  diagonal.fly({ forward: 1, right: 1 }, 1);
  near(vec3.length(vec3.sub(diagonal.eye, eye)), slow, 1e-9);

  const up = OrbitCamera.fromLookAt({ eye: { x: 0, y: 0, z: 10 }, target: { x: 0, y: 0, z: 0 } });
  up.fly({ up: 1 }, 0.5);
  assert.ok(up.eye.y > 0 && Math.abs(up.eye.x) < 1e-12);

  const still = sample();
  const stillEye = still.eye;
  still.fly({ forward: 1 }, 0);
  still.fly({ forward: NaN }, 1);
  still.fly({}, 1);
  nearVec(still.eye, stillEye);
});

test('no sequence of inputs produces NaN', () => {
  let seed = 42;
  const rand = () => ((seed = (seed * 1103515245 + 12345) % 2 ** 31) / 2 ** 31);
  const extreme = [0, -0, 1e-300, -1e300, 1e300, NaN, Infinity, -Infinity];
  const value = () => (rand() < 0.2 ? extreme[Math.floor(rand() * extreme.length)] : (rand() - 0.5) * 20);
  const cam = sample();
  for (let i = 0; i < 5000; i++) {
    switch (Math.floor(rand() * 5)) {
      case 0: cam.orbit(value(), value()); break;
      case 1: cam.dolly(Math.abs(value())); break;
      case 2: cam.pan(value(), value(), Math.abs(value()), Math.abs(value())); break;
      case 3: cam.look(value(), value()); break;
      default: cam.fly({ forward: value(), right: value(), up: value() }, Math.abs(value()), rand() < 0.5);
    }
    assertFiniteCamera(cam);
  }
});

test('vec3.normalize falls back on zero and non-finite vectors', () => {
  assert.deepEqual(vec3.normalize({ x: 0, y: 0, z: 0 }), { x: 0, y: 0, z: 1 });
  assert.deepEqual(vec3.normalize({ x: NaN, y: 0, z: 0 }, { x: 1, y: 0, z: 0 }), { x: 1, y: 0, z: 0 });
  near(vec3.length(vec3.normalize({ x: 3, y: 4, z: 12 })), 1);
});

test('fly keys: W/A/S/D/Q/E and arrows, opposites cancel', () => {
  assert.deepEqual(flyVector(new Set(['KeyW'])), { forward: 1, right: 0, up: 0 });
  assert.deepEqual(flyVector(new Set(['KeyS', 'KeyA', 'KeyQ'])), { forward: -1, right: -1, up: -1 });
  assert.deepEqual(flyVector(new Set(['KeyW', 'KeyS', 'KeyD', 'KeyE'])), { forward: 0, right: 1, up: 1 });
  assert.deepEqual(flyVector(new Set(['KeyW', 'ArrowUp'])), { forward: 1, right: 0, up: 0 });
  assert.deepEqual(flyVector(new Set(['ShiftLeft', 'KeyX'])), { forward: 0, right: 0, up: 0 });
  assert.ok(isFlyKey('KeyD') && !isFlyKey('KeyF') && !isFlyKey('toString'));
});

test('wheel: down moves away, up moves closer, any delta mode', () => {
  assert.ok(wheelFactor(100) > 1);
  assert.ok(wheelFactor(-100) < 1);
  near(wheelFactor(100) * wheelFactor(-100), 1);
  near(wheelFactor(3, 1), wheelFactor(48, 0));      // lines
  near(wheelFactor(1, 2, 400), wheelFactor(400, 0));  // pages
  assert.equal(wheelFactor(NaN), 1);
  assert.ok(Number.isFinite(wheelFactor(1e12)) && wheelFactor(1e12) > 1);
});

test('pinch: fingers apart zoom in; the midpoint pans', () => {
  const g = pinchGesture([{ x: 0, y: 0 }, { x: 100, y: 0 }], [{ x: -50, y: 10 }, { x: 150, y: 10 }]);
  near(g.factor, 0.5);
  near(g.dx, 0);
  near(g.dy, 10);
  const same = pinchGesture([{ x: 5, y: 5 }, { x: 5, y: 5 }], [{ x: 5, y: 5 }, { x: 9, y: 5 }]);
  assert.equal(same.factor, 1);  // coincident fingers: no zoom rather than infinity
});

test('pointer gestures: drag orbits, right-drag and Shift pan, two fingers pinch', () => {
  const view = { height: 600, yfov: 0.8 };
  const g = new PointerGestures();

  let cam = sample();
  const right = cam.right;
  let eye = cam.eye;
  g.down({ id: 1, x: 100, y: 100, button: 0 });
  assert.ok(g.move({ id: 1, x: 160, y: 100 }, cam, view));
  assert.ok(vec3.dot(vec3.sub(cam.eye, eye), right) < 0, 'dragging right moves the eye left');
  g.up(1);
  assert.equal(g.mode, null);

  for (const down of [{ button: 2 }, { button: 0, shiftKey: true }]) {
    cam = sample();
    const target = { ...cam.target };
    g.down({ id: 2, x: 0, y: 0, ...down });
    assert.equal(g.mode, 'pan');
    g.move({ id: 2, x: 30, y: 0 }, cam, view);
    assert.ok(vec3.dot(vec3.sub(cam.target, target), right) < 0);
    g.up(2);
  }

  cam = sample();
  const d = cam.distance;
  g.down({ id: 3, x: 100, y: 100 });
  g.down({ id: 4, x: 200, y: 100 });
  g.move({ id: 4, x: 300, y: 100 }, cam, view);
  near(cam.distance, d / 2, 1e-9);
  assert.equal(g.move({ id: 9, x: 0, y: 0 }, cam, view), false);  // unknown pointer
  g.up(4);
  assert.equal(g.mode, 'orbit');  // the finger left keeps orbiting
  eye = cam.eye;
  g.move({ id: 3, x: 120, y: 100 }, cam, view);
  assert.notDeepEqual(cam.eye, eye);
  g.up(3);

  // Fly mode: a drag looks around (the eye stays).
  cam = sample();
  eye = cam.eye;
  g.down({ id: 5, x: 0, y: 0 }, true);
  assert.equal(g.mode, 'look');
  g.move({ id: 5, x: 40, y: 10 }, cam, view);
  nearVec(cam.eye, eye, 1e-9);
  g.up(5, true);

  // Without a camera (not initialised yet) moves are tracked but change nothing.
  g.down({ id: 6, x: 0, y: 0 });
  assert.equal(g.move({ id: 6, x: 10, y: 0 }, null, view), false);
});

// ---- the view in the URL ----

const ID = '6ee6ae2ad53a1f796384aa426563c203807a4c1e0c1ff089089cfa25d8a4e89a';

test('a view link round-trips: scene, eye, target, fov; up only when it is not +Y', () => {
  const lookAt = { eye: { x: 3, y: 2.5, z: -5 }, target: { x: 0, y: 0.57, z: 0 }, up: { x: 0, y: 1, z: 0 } };
  const hash = formatViewLink({ sceneId: ID, lookAt, yfov: Math.PI / 3 });
  assert.equal(hash, `scene=${ID}&eye=3,2.5,-5&target=0,0.57,0&fov=60`);
  const back = parseViewLink(`#${hash}`);
  assert.deepEqual(back.problems, []);
  assert.equal(back.sceneId, ID);
  assert.deepEqual(back.lookAt, { eye: lookAt.eye, target: lookAt.target });
  near(back.yfov, Math.PI / 3, 1e-9);

  const tilted = { ...lookAt, up: { x: 1, y: 0, z: 0 } };
  const withUp = parseViewLink(formatViewLink({ sceneId: 'demo', lookAt: tilted }));
  assert.deepEqual(withUp.lookAt.up, { x: 1, y: 0, z: 0 });
  assert.equal(formatViewLink({ sceneId: 'demo' }), 'scene=demo');
  assert.deepEqual(parseViewLink(''), { problems: [] });
  assert.deepEqual(parseViewLink('#'), { problems: [] });
});

test('a view link carries 6 significant digits, never NaN, -0 or an exponent for ordinary values', () => {
  const cam = sample();
  cam.orbit(0.3, 0.1);
  const hash = formatViewLink({ sceneId: 'demo', lookAt: cam.lookAt(), yfov: 0.8 });
  assert.doesNotMatch(hash, /NaN|Infinity|e\+|-0[,&]/);
  const back = parseViewLink(hash);
  nearVec(back.lookAt.eye, cam.eye, 1e-5);
  assert.equal(formatViewLink({ lookAt: { eye: { x: -0, y: 1e-7, z: 0 }, target: { x: 0, y: 0, z: 1 } } }),
    'eye=0,1e-7,0&target=0,0,1');
});

test('hostile or malformed links: bad parts are dropped with a reason, never thrown', () => {
  const cases = [
    ['#eye=1,2&target=0,0,0', /eye: wants three numbers/],
    ['#eye=1,2,3,4&target=0,0,0', /eye: wants three numbers/],
    ['#eye=NaN,1,1&target=0,0,0', /eye: wants three numbers/],
    ['#eye=Infinity,1,1&target=0,0,0', /eye: wants three numbers/],
    ['#eye=0x10,1,1&target=0,0,0', /eye: wants three numbers/],
    ['#eye=1e300,1,1&target=0,0,0', /eye: numbers must be finite and within/],
    ['#eye=1,1,1&target=1,1,1', /target: equals eye/],
    ['#eye=1,1,1', /eye: needs target too/],
    ['#target=1,1,1', /target: needs eye too/],
    ['#eye=0,0,5&target=0,0,0&up=0,0,1', /up: zero or parallel/],
    ['#eye=0,0,5&target=0,0,0&up=0,0,0', /up: zero or parallel/],
    ['#up=0,1,0', /up: needs eye and target/],
    ['#fov=0', /fov: wants degrees/],
    ['#fov=180', /fov: wants degrees/],
    ['#fov=abc', /fov: wants degrees/],
    ['#scene=../../etc', /scene: not a scene id/],
    ['#scene=<script>', /scene: not a scene id/],
    ['#scene=ABCDEF12', /scene: not a scene id/],
    ['#scene=abc', /scene: not a scene id/],
    ['#eye=%E0%A4%A,1,1&target=0,0,0', /eye: not readable/],
    [`#scene=demo&x=${'a'.repeat(LINK_MAX_LENGTH)}`, /longer than/],
  ];
  for (const [hash, why] of cases) {
    const link = parseViewLink(hash);
    assert.equal(link.lookAt, undefined, hash);
    assert.ok(link.problems.some((p) => why.test(p)), `${hash}: ${JSON.stringify(link.problems)}`);
  }
  // What is valid in a partly bad link is kept; unknown keys are ignored; the first of a
  // repeated key counts.
  const partly = parseViewLink('#scene=demo&eye=0,1,5&target=0,0,0&fov=999&zoom=3&eye=9,9,9');
  assert.equal(partly.sceneId, 'demo');
  assert.deepEqual(partly.lookAt, { eye: { x: 0, y: 1, z: 5 }, target: { x: 0, y: 0, z: 0 } });
  assert.equal(partly.yfov, undefined);
  assert.deepEqual(partly.problems, ['fov: wants degrees from 1 to 170']);
  assert.equal(parseViewLink('#scene=6ee6ae2a').sceneId, '6ee6ae2a');  // a prefix, as ?scene= takes
  for (const junk of [null, undefined, 42, {}, '#&&&', '#=', '#eye', '#%']) {
    assert.doesNotThrow(() => parseViewLink(junk));
  }
});

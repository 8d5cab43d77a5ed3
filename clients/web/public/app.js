// Tessera's web viewer: the page's entry point. It wires the modules together:
//   protocol.js  the gateway's WebSocket (requests, frames, reconnects)
//   camera.js    orbit / fly camera math and pointer gestures
//   chart.js     per-pass timing chart, fps, latency and the stats text
//   upload.js    which files an upload needs, and sending them
// Sections below: state, errors and status, the stream session, frames, camera input,
// viewport size, settings panel, scenes and uploads, test hooks, start-up.
// Nothing is global except window.tessera (the hooks the headless-browser tests read).

import { Connection } from './protocol.js';
import { el } from './dom.js';
import { SettingsPanel, validNumber } from './settings.js';
import { OrbitCamera, PointerGestures, flyVector, isFlyKey, wheelFactor } from './camera.js';
import {
  FpsMeter, LatencyTracker, TimingChart, TimingHistory, statsRows,
} from './chart.js';
import {
  UploadError, checkLimits, collectDropped, collectInput, formatBytes, planUpload, readSceneJson,
  sendUpload,
} from './upload.js';

const $ = (id) => document.getElementById(id);
const ui = {
  view: $('view'), status: $('status'), flyToggle: $('fly-toggle'), resetView: $('reset-view'),
  save: $('save'), panelToggle: $('panel-toggle'), flyHelp: $('fly-help'),
  error: $('error'), errorText: $('error-text'), errorDismiss: $('error-dismiss'),
  dropOverlay: $('drop-overlay'),
  sceneSelect: $('scene-select'), uploadInput: $('upload-input'), uploadBox: $('upload-box'),
  uploadStatus: $('upload-status'), uploadProgress: $('upload-progress'),
  uploadCancel: $('upload-cancel'), uploadNote: $('upload-note'), sceneWarnings: $('scene-warnings'),
  resolution: $('resolution'), settings: $('settings'), notes: $('notes'),
  interactiveEnabled: $('interactive-enabled'), interactiveScale: $('interactive-scale'),
  interactiveQuality: $('interactive-quality'),
  chart: $('chart'), chartLegend: $('chart-legend'), stats: $('stats'),
};

const RESIZE_DEBOUNCE_MS = 150;
const RETRY_MIN_MS = 500;    // stream retries: 0.5 s doubling to 5 s (as the socket's)
const RETRY_MAX_MS = 5000;

// ---------------------------------------------------------------------------------------------
// State

const conn = new Connection(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`);
const timings = new TimingHistory();
const chart = new TimingChart(ui.chart, ui.chartLegend, timings);
const fps = new FpsMeter();
const latency = new LatencyTracker();
const gestures = new PointerGestures();

const state = {
  info: null,            // ServerInfo
  scenes: [],            // SceneInfo list
  sceneId: new URLSearchParams(location.search).get('scene') || 'demo',

  // The stream. `gen` grows whenever a stream starts or stops, so that late async results
  // (open replies, decodes, timers) can tell they belong to a stream that is gone.
  gen: 0,
  streamId: null,
  receiving: false,      // a frame has arrived on the current stream
  resuming: false,       // the current stream resumed a session and has had no frame yet
  token: null,           // the last Frame.session_token
  retryTimer: null,
  retryDelay: RETRY_MIN_MS,
  bootTimer: null,
  epoch: 0,              // grows when the socket closes: start-up steps of an old socket stop

  // What the user asked for; a fresh session is opened with it.
  userSettings: {},      // RenderSettings fields the user changed
  interactive: null,     // the InteractiveProfile the user set
  renderSize: null,      // {width, height} last sent
  confirmed: {},         // the last frame's effective settings
  pendingFields: new Map(),  // setting name -> event id of its last change
  sentEvents: new Map(),     // request id of a recent event -> {stream, names: settings changed}

  camera: null,          // OrbitCamera, once initialised from a frame
  cameraInitAfter: 0,    // > 0: re-initialise from the first frame reflecting this event id
  cameraDirty: false,
  yfov: 0.8,
  fly: false,
  keys: new Set(),       // KeyboardEvent.code values held (fly mode)

  drawnSeq: 0,           // sequence of the newest frame drawn on this stream
  framesDrawn: 0,
  lastFrame: null,       // FrameHeader of the frame shown
  lastPayload: null,     // its encoded bytes
  lastBitmap: null,
  decodeFailed: false,
  chartDirty: false,

  upload: null,          // {id, cancel, cancelled} while an upload runs
  errors: [],            // every error shown (test hook)
};
let nextEventId = 1;     // ClientEvent.event_id: one increasing counter for the page

// ---------------------------------------------------------------------------------------------
// Errors and status

/**
 * Shows an error in the banner: the gateway's hint (what it means for the user), then
 * `context: message` (the server's own words). The same error twice in a row shows once.
 */
function showError(err, context) {
  const shown = {
    code: err?.code ?? (err instanceof UploadError ? 'UPLOAD' : 'ERROR'),
    message: String(err?.message ?? err ?? 'unknown error'),
    hint: err?.hint ?? '',
    context,
  };
  const last = state.errors[state.errors.length - 1];
  if (!ui.error.hidden && last?.message === shown.message && last?.context === context) return;
  state.errors.push(shown);
  const parts = [];
  if (shown.hint) parts.push(el('strong', shown.hint));
  parts.push(document.createTextNode(`${context}: ${shown.message} `));
  if (!['UPLOAD', 'ERROR'].includes(shown.code)) parts.push(el('span', `(${shown.code})`, 'code'));
  if (err?.details?.length > 0) {  // many files: one line each, folded away
    const list = el('ul');
    for (const line of err.details) list.append(el('li', line));
    const details = el('details');
    details.append(el('summary', `${err.details.length} files`), list);
    parts.push(details);
  }
  ui.errorText.replaceChildren(...parts);
  ui.error.hidden = false;
}

/** Wraps a handler so that nothing it throws, or rejects with, escapes uncaught. */
function guard(fn, context = 'The page hit a problem') {
  return (...args) => {
    try {
      const result = fn(...args);
      if (typeof result?.catch === 'function') result.catch((err) => showError(err, context));
    } catch (err) {
      showError(err, context);
    }
  };
}

/** The status pill; `kind` is 'ok', 'busy' or 'bad'. */
function setStatus(text, kind = 'busy') {
  ui.status.textContent = text;
  ui.status.dataset.state = kind;
}

const isTransient = (code) => code === 'UNAVAILABLE' || code === 'CANCELLED';
const short = (id) => String(id ?? '').slice(0, 8);
const backoff = (delay) => Math.min(RETRY_MAX_MS, delay * 2);

// ---------------------------------------------------------------------------------------------
// Start-up on every (re)connection: server info, scenes, then the stream

async function onSocketOpen() {
  clearTimeout(state.bootTimer);
  const epoch = state.epoch;
  setStatus('loading…');
  let result;
  try {
    result = await conn.request('info');
  } catch (err) {
    if (epoch !== state.epoch) return;  // the socket closed: its reconnect starts over
    if (!isTransient(err.code)) showError(err, 'The server did not describe itself');
    setStatus(`server unavailable, retrying in ${(state.retryDelay / 1000).toFixed(1)} s`, 'bad');
    state.bootTimer = setTimeout(guard(onSocketOpen, 'Could not reach the server'), state.retryDelay);
    state.retryDelay = backoff(state.retryDelay);
    return;
  }
  const firstTime = state.info === null;
  state.info = result.info ?? {};
  if (firstTime) {
    // A CPU device (lavapipe) renders full device pixels slowly: start at half resolution.
    ui.resolution.value = state.info.device?.type === 'cpu' ? '50' : '100';
    panel.build(result.schema ?? [], state.info);
  }
  await refreshScenes();
  if (epoch === state.epoch) await startStream({ resume: true });
}

function onSocketState({ state: socketState, retryMs }) {
  if (socketState === 'connecting') {
    setStatus(state.info ? 'reconnecting…' : 'connecting…');
  } else if (socketState === 'open') {
    guard(onSocketOpen, 'Could not start')();
  } else if (socketState === 'closed') {
    state.epoch++;
    clearTimeout(state.bootTimer);
    stopStream();
    setStatus(`reconnecting… (in ${(retryMs / 1000).toFixed(1)} s)`, 'bad');
  }
}

// ---------------------------------------------------------------------------------------------
// The stream session: resume when we have a token, else open fresh; retry with backoff

/** The OpenSession of a fresh session: scene, the user's settings, the camera if any. */
function freshOpen() {
  const open = {
    scene_id: state.sceneId,
    settings: { ...state.userSettings, ...renderSize() },
    target_fps: 0,
  };
  // No camera on a new scene: the server frames its bounds and the first frame says how.
  if (state.camera && !state.cameraInitAfter) {
    open.camera = { look_at: state.camera.lookAt() };
  } else {
    // A re-frame still pending (its event went to a stream that died) is this open's job now:
    // its frames carry event id 0, so wait for any frame rather than for that event.
    state.camera = null;
    state.cameraInitAfter = 0;
  }
  if (state.interactive) open.interactive = { ...state.interactive };
  return open;
}

/** Forgets the current stream (closing it on the gateway) and any pending retry. */
function stopStream() {
  state.gen++;
  clearTimeout(state.retryTimer);
  state.retryTimer = null;
  if (state.streamId !== null) conn.notify('close', { stream: state.streamId });
  state.streamId = null;
  state.receiving = false;
  state.resuming = false;
  latency.reset();
}

/** Opens a stream on state.sceneId, resuming the last session when `resume` and possible. */
async function startStream({ resume }) {
  stopStream();
  const gen = state.gen;
  if (!conn.connected || !state.info) return;  // onSocketOpen starts it
  setStatus('opening the stream…');
  state.renderSize = renderSize();

  let streamId = null;
  let resumed = false;
  if (resume && state.token) {
    try {
      streamId = (await conn.request('open', { open: { resume_token: state.token } })).stream;
      resumed = true;
    } catch {
      if (gen !== state.gen) return;
      state.token = null;  // whatever went wrong, a fresh session with the same state follows
    }
  }
  if (streamId === null) {
    try {
      streamId = (await conn.request('open', { open: freshOpen() })).stream;
    } catch (err) {
      if (gen === state.gen) onStreamFailed(err);
      return;
    }
  }
  if (gen !== state.gen) {  // superseded while opening (scene switched, socket lost)
    conn.notify('close', { stream: streamId });
    return;
  }
  state.streamId = streamId;
  state.resuming = resumed;
  state.drawnSeq = 0;
  if (resumed) resyncSession();
}

/** After a resume, what changed while the stream was down goes to the session in one event. */
function resyncSession() {
  const event = { settings: { ...state.userSettings, ...renderSize() } };
  if (state.camera && !state.cameraInitAfter) event.camera = { look_at: state.camera.lookAt() };
  if (state.interactive) event.interactive = { ...state.interactive };
  state.cameraDirty = false;
  sendEvent(event);
}

/** An open that failed or a stream that ended with an error: explain, then try again. */
function onStreamFailed(err) {
  if (err.code === 'NOT_FOUND' && state.sceneId !== 'demo') {
    // The scene is gone (deleted, evicted, or the server restarted): show the built-in one.
    showError(err, `Scene ${short(state.sceneId)} is not on the server; showing "demo"`);
    switchScene('demo');
    guard(refreshScenes)();
    return;
  }
  if (err.code === 'ABORTED') state.token = null;  // another stream took the session over
  // Do not send a refused value again: first the settings, then (if those were not it) the camera.
  if (err.code === 'INVALID_ARGUMENT' && !revertSettings()) state.camera = null;
  if (!isTransient(err.code)) showError(err, 'The server could not stream the scene');
  if (!conn.connected) return;  // the socket reconnects and restarts the stream itself
  const delay = state.retryDelay;
  state.retryDelay = backoff(delay);
  const why = err.code === 'UNAVAILABLE' ? 'server unavailable, ' : '';
  setStatus(`reconnecting… (${why}retry in ${(delay / 1000).toFixed(1)} s)`, 'bad');
  const gen = state.gen;
  state.retryTimer = setTimeout(guard(() => {
    if (gen === state.gen) return startStream({ resume: true });
  }, 'Could not reopen the stream'), delay);
}

function onStreamEnd(msg) {
  if (msg.stream !== state.streamId) return;  // a stream we closed ourselves
  const resumeFailed = state.resuming;
  state.streamId = null;  // it has ended: nothing to close
  stopStream();
  if (resumeFailed) {
    // The session could not be resumed (unknown token, grace period over): start afresh.
    state.token = null;
    guard(startStream, 'Could not reopen the stream')({ resume: false });
  } else {
    // An ok end we did not ask for still leaves us without frames: same path as an error.
    onStreamFailed(msg.ok ? { code: 'UNAVAILABLE', message: 'the stream ended' }
                          : { code: 'UNKNOWN', message: 'the stream ended', ...msg.error });
  }
}

/** Switches scene: a new session with the same settings, framed by the server. */
function switchScene(sceneId) {
  state.sceneId = sceneId;
  state.token = null;
  state.camera = null;
  state.cameraInitAfter = 0;
  state.cameraDirty = false;
  syncSceneUi();
  guard(startStream, 'Could not open the scene')({ resume: false });
}

/** ?scene= in the URL and the picker follow the current scene. */
function syncSceneUi() {
  const url = new URL(location.href);
  if (url.searchParams.get('scene') !== state.sceneId) {
    url.searchParams.set('scene', state.sceneId);
    window.history.replaceState(window.history.state, '', url);
  }
  renderSceneOptions();
}

/** Sends a ClientEvent on the stream; returns its event id, or null without a stream. */
function sendEvent(fields) {
  if (state.streamId === null) return null;
  const eventId = nextEventId;
  const event = { event_id: eventId, ...fields };
  const requestId = conn.notify('event', { stream: state.streamId, event });
  if (requestId === null) return null;
  nextEventId++;
  latency.sent(eventId, performance.now());
  const names = Object.keys(fields.settings ?? {});
  for (const name of names) state.pendingFields.set(name, eventId);
  state.sentEvents.set(requestId, { stream: state.streamId, names });
  if (state.sentEvents.size > 200) state.sentEvents.delete(state.sentEvents.keys().next().value);
  return eventId;
}

/**
 * An error reply to a request that has no reply otherwise. For an event on the current
 * stream: its settings go back to what the server last confirmed, and the user is told.
 * Others (closing a stream that had just ended, an event racing its stream's end) are moot.
 */
function onOrphanError({ id, error }) {
  const sent = state.sentEvents.get(id);
  state.sentEvents.delete(id);
  if (!sent || sent.stream !== state.streamId) return;
  revertSettings(sent.names);
  showError(error, 'Change not applied');
}

/**
 * Puts settings (`names`, default all the user changed) back to the last confirmed values,
 * so a rejected value is not sent again. When nothing differed, forgets the user's settings
 * and profile altogether (the server's defaults are known to work). Returns whether
 * anything changed.
 */
function revertSettings(names = Object.keys(state.userSettings)) {
  let reverted = false;
  for (const name of names) {
    state.pendingFields.delete(name);
    if (!(name in state.userSettings)) continue;
    if (name in state.confirmed && state.confirmed[name] !== state.userSettings[name]) {
      state.userSettings[name] = state.confirmed[name];
      reverted = true;
    }
    panel.controls.get(name)?.write(state.userSettings[name]);
  }
  if (!reverted && names.length === Object.keys(state.userSettings).length) {
    reverted = names.length > 0 || state.interactive !== null;
    state.userSettings = {};
    state.interactive = null;
  }
  return reverted;
}

// ---------------------------------------------------------------------------------------------
// Frames: decode, draw in sequence order, then update what shows frame data

function onFrame({ header, payload }) {
  if (header.stream !== state.streamId || !header.frame) return;
  const frame = header.frame;
  if (!state.receiving) {
    state.receiving = true;
    state.resuming = false;
    state.retryDelay = RETRY_MIN_MS;
    setStatus('connected', 'ok');
  }
  if (frame.session_token) state.token = frame.session_token;
  if (frame.scene_id && frame.scene_id !== state.sceneId) {
    state.sceneId = frame.scene_id;  // e.g. an 8-character prefix resolved to the full id
    syncSceneUi();
  }
  const latencyMs = latency.frameArrived(Number(frame.event_id ?? 0), performance.now());
  maybeInitCamera(frame);
  decodeAndDraw(state.gen, frame, payload, latencyMs).catch((err) => {
    if (!state.decodeFailed) showError(err, 'A frame could not be shown');
    state.decodeFailed = true;  // once is enough: the next frames would say the same
  });
}

async function decodeAndDraw(gen, frame, payload, latencyMs) {
  const type = frame.encoding === 'IMAGE_PNG' ? 'image/png' : 'image/jpeg';
  const bitmap = await createImageBitmap(new Blob([payload], { type }));
  const sequence = Number(frame.sequence ?? 0);
  // Decodes finish out of order: never replace a newer frame, never draw an old stream's.
  if (gen !== state.gen || sequence <= state.drawnSeq) {
    bitmap.close();
    return;
  }
  state.drawnSeq = sequence;
  state.decodeFailed = false;
  state.lastBitmap?.close();
  state.lastBitmap = bitmap;
  drawLastFrame();
  state.framesDrawn++;
  state.lastFrame = frame;
  state.lastPayload = payload;
  ui.save.disabled = false;
  fps.tick(performance.now());
  timings.push(frame, latencyMs);
  state.chartDirty = true;
  requestTick();
  state.confirmed = { ...(frame.settings ?? {}) };
  panel.reflect(frame, state.pendingFields);
  renderStats();
}

function drawLastFrame() {
  const ctx = ui.view.getContext('2d');
  if (!state.lastBitmap || !ctx) return;
  ctx.imageSmoothingQuality = 'high';
  ctx.drawImage(state.lastBitmap, 0, 0, ui.view.width, ui.view.height);
}

/** The orbit starts from the server's camera: on a new stream, and after reset view. */
function maybeInitCamera(frame) {
  if (Number(frame.yfov) > 0) state.yfov = Number(frame.yfov);
  const waiting = state.camera === null || state.cameraInitAfter > 0;
  if (!waiting || !frame.camera || Number(frame.event_id ?? 0) < state.cameraInitAfter) return;
  state.camera = OrbitCamera.fromLookAt(frame.camera);
  state.cameraInitAfter = 0;
  state.cameraDirty = false;
}

function renderStats() {
  const rows = statsRows(state.lastFrame, {
    fps: fps.label(performance.now()),
    latencyMs: latency.median(),
  });
  const dl = el('dl');
  for (const [label, value] of rows) dl.append(el('dt', label), el('dd', value));
  ui.stats.replaceChildren(dl);
}

function saveImage() {
  const frame = state.lastFrame;
  if (!frame || !state.lastPayload) return;
  const png = frame.encoding === 'IMAGE_PNG';
  const blob = new Blob([state.lastPayload], { type: png ? 'image/png' : 'image/jpeg' });
  const url = URL.createObjectURL(blob);
  const a = el('a');
  a.href = url;
  const scene8 = short(frame.scene_id || state.sceneId);
  a.download = `tessera-${scene8}-${frame.sequence ?? 0}.${png ? 'png' : 'jpg'}`;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 60_000);  // revoking at once can cancel the download
}

// ---------------------------------------------------------------------------------------------
// Camera input: pointers, wheel and keys move the camera; at most one event per animation frame

const usable = () => state.camera !== null && state.cameraInitAfter === 0;
let tickPending = false;
let lastTickTime = 0;

function requestTick() {
  if (tickPending) return;
  tickPending = true;
  requestAnimationFrame(guard(tick, 'The camera update failed'));
}

function tick(now) {
  tickPending = false;
  const moving = state.fly && usable() && state.keys.size > 0;
  if (moving) {
    const dt = lastTickTime ? Math.min(0.1, (now - lastTickTime) / 1000) : 1 / 60;
    const fast = state.keys.has('ShiftLeft') || state.keys.has('ShiftRight');
    state.camera.fly(flyVector(state.keys), dt, fast);
    state.cameraDirty = true;
  }
  lastTickTime = moving ? now : 0;
  if (state.cameraDirty && usable() && state.streamId !== null) {
    sendEvent({ camera: { look_at: state.camera.lookAt() } });
    state.cameraDirty = false;
  }
  if (state.chartDirty) {
    chart.draw();
    state.chartDirty = false;
  }
  if (moving) requestTick();  // continuous movement while keys are held
}

function cameraChanged() {
  state.cameraDirty = true;
  requestTick();
}

const pointerOf = (e) => ({
  id: e.pointerId, x: e.clientX, y: e.clientY, button: e.button, shiftKey: e.shiftKey,
});

function onPointerDown(e) {
  ui.view.setPointerCapture?.(e.pointerId);
  gestures.down(pointerOf(e), state.fly);
  e.preventDefault();
}

function onPointerMove(e) {
  const view = { height: ui.view.clientHeight, yfov: state.yfov };
  if (gestures.move(pointerOf(e), usable() ? state.camera : null, view)) cameraChanged();
}

function onPointerUp(e) {
  gestures.up(e.pointerId, state.fly);
}

function onWheel(e) {
  e.preventDefault();
  if (!usable()) return;
  state.camera.dolly(wheelFactor(e.deltaY, e.deltaMode, ui.view.clientHeight));
  cameraChanged();
}

/** Whether keys typed now belong to a form control rather than to the camera. */
function typingIn(target) {
  if (!(target instanceof HTMLElement)) return false;
  if (target.isContentEditable || ['SELECT', 'TEXTAREA'].includes(target.tagName)) return true;
  return target.tagName === 'INPUT' && !['checkbox', 'radio', 'button', 'file'].includes(target.type);
}

function onKeyDown(e) {
  if (typingIn(e.target) || e.ctrlKey || e.metaKey || e.altKey) return;
  if (e.code === 'KeyF' && !e.repeat) {
    setFly(!state.fly);
    e.preventDefault();
  } else if (state.fly && (isFlyKey(e.code) || e.code.startsWith('Shift'))) {
    state.keys.add(e.code);
    requestTick();
    e.preventDefault();
  }
}

function setFly(on) {
  state.fly = on;
  state.keys.clear();
  gestures.setFly(on);
  ui.flyToggle.setAttribute('aria-pressed', String(on));
  ui.flyHelp.hidden = !on;
  document.body.classList.toggle('flying', on);
}

/** Reset view: the server frames the scene, and the orbit restarts from the frame it sends. */
function resetView() {
  state.cameraDirty = false;
  const eventId = sendEvent({ camera: { frame: {} } });
  if (eventId !== null) {
    state.cameraInitAfter = eventId;
  } else {
    state.camera = null;  // no stream now: the next session opens without a camera
    state.cameraInitAfter = 0;
  }
}

// ---------------------------------------------------------------------------------------------
// Viewport size: the canvas in device pixels; the render size follows it, debounced

let resizeTimer = null;

function onViewportResize() {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(ui.view.clientWidth * dpr));
  const h = Math.max(1, Math.round(ui.view.clientHeight * dpr));
  if (ui.view.width !== w || ui.view.height !== h) {
    ui.view.width = w;
    ui.view.height = h;
    drawLastFrame();  // resizing cleared the canvas
  }
  clearTimeout(resizeTimer);
  const apply = guard(applyRenderSize, 'Could not change the resolution');
  resizeTimer = setTimeout(apply, RESIZE_DEBOUNCE_MS);
}

/** Canvas pixels x the resolution choice, scaled down (same aspect) to the server's limits. */
function renderSize() {
  const scale = Number(ui.resolution.value) / 100 || 1;
  const width = Math.max(1, Math.round(ui.view.width * scale));
  const height = Math.max(1, Math.round(ui.view.height * scale));
  const maxW = Number(state.info?.limits?.max_width) || 16384;
  const maxH = Number(state.info?.limits?.max_height) || 16384;
  const fit = Math.min(1, maxW / width, maxH / height);
  return {
    width: Math.max(1, Math.min(maxW, Math.floor(width * fit))),
    height: Math.max(1, Math.min(maxH, Math.floor(height * fit))),
  };
}

function applyRenderSize() {
  const size = renderSize();
  const last = state.renderSize;
  if (last && last.width === size.width && last.height === size.height) return;
  if (sendEvent({ settings: size }) !== null) state.renderSize = size;
}

// ---------------------------------------------------------------------------------------------
// Settings

const panel = new SettingsPanel(ui.settings, ui.notes, (name, value) => {
  state.userSettings[name] = value;
  sendEvent({ settings: { [name]: value } });
}, guard);

/** The interactive-profile group: every change sends the whole profile. */
function onInteractiveChanged() {
  const render_scale = validNumber(ui.interactiveScale, { min: 0.25, max: 1 }, false);
  const jpeg_quality = validNumber(ui.interactiveQuality, { min: 1, max: 100 }, true);
  if (render_scale === undefined || jpeg_quality === undefined) return;
  state.interactive = { enabled: ui.interactiveEnabled.checked, render_scale, jpeg_quality };
  sendEvent({ interactive: { ...state.interactive } });
}

// ---------------------------------------------------------------------------------------------
// Scenes: the picker, and uploads (file input or drag and drop)

async function refreshScenes() {
  try {
    state.scenes = (await conn.request('scenes')).scenes ?? [];
  } catch (err) {
    if (!isTransient(err.code)) showError(err, 'The server did not list its scenes');
  }
  renderSceneOptions();
}

function renderSceneOptions() {
  const options = state.scenes.filter((s) => !s.deleted).map((s) => {
    const triangles = Number(s.counts?.triangles ?? 0).toLocaleString('en-US');
    const label = `${s.name || '(unnamed)'} · ${short(s.scene_id)} · ${triangles} triangles`;
    return new Option(label, s.scene_id);
  });
  // The current scene may be a prefix (?scene=) or not listed yet: select what matches it.
  let current = options.find((o) => o.value === state.sceneId) ??
    options.find((o) => o.value.startsWith(state.sceneId));
  if (!current) {
    current = new Option(state.sceneId, state.sceneId);
    options.push(current);
  }
  ui.sceneSelect.replaceChildren(...options);
  ui.sceneSelect.value = current.value;
}

const PHASES = {
  receiving: 'receiving: the gateway gets the files',
  sending: 'sending: the gateway passes them to the server',
  loading: 'loading: the server parses the scene',
};

function onUploadProgress({ phase, done, total }) {
  const known = Number(total) > 0;
  if (known) {
    ui.uploadProgress.max = Number(total);
    ui.uploadProgress.value = Math.min(Number(done) || 0, Number(total));
  } else {
    ui.uploadProgress.removeAttribute('value');  // indeterminate while the server loads
  }
  const amount = known ? ` (${formatBytes(Number(done) || 0)} of ${formatBytes(Number(total))})` : '';
  ui.uploadStatus.textContent = `${PHASES[phase] ?? phase}${amount}`;
}

/** Uploads a scene from file descriptors [{path, size, file}], then switches to it. */
async function uploadFiles(entries) {
  if (state.upload) throw new UploadError('An upload is already running; wait for it or cancel it.');
  if (entries.length === 0) return;
  const plan = await planUpload(entries, (e) => readSceneJson(e.file, e.path));
  checkLimits(plan, state.info?.limits);

  ui.sceneWarnings.hidden = true;
  ui.uploadNote.hidden = true;
  ui.uploadBox.hidden = false;
  ui.uploadProgress.value = 0;
  ui.uploadStatus.textContent = `starting ${plan.main} (${plan.files.length} files)…`;
  const upload = sendUpload(conn, plan, { onProgress: onUploadProgress });
  state.upload = { ...upload, cancelled: false };
  let scene;
  try {
    scene = await upload.result;
  } catch (err) {
    if (!state.upload.cancelled) showError(err, 'Upload failed');
    return;
  } finally {
    state.upload = null;
    ui.uploadBox.hidden = true;
  }

  const skipped = plan.unused.length
    ? ` ${plan.unused.length} file(s) the scene does not use were left out.` : '';
  ui.uploadNote.textContent = `Uploaded ${scene.name} (${short(scene.scene_id)}).${skipped}`;
  ui.uploadNote.hidden = false;
  const warnings = scene.warnings ?? [];
  ui.sceneWarnings.querySelector('ul').replaceChildren(...warnings.map((w) => el('li', w)));
  ui.sceneWarnings.hidden = warnings.length === 0;
  await refreshScenes();
  switchScene(scene.scene_id);
}

function cancelUpload() {
  if (!state.upload) return;
  state.upload.cancelled = true;
  state.upload.cancel();
  ui.uploadNote.textContent = 'Upload cancelled.';
  ui.uploadNote.hidden = false;
}

/** Drag and drop anywhere on the page; the overlay shows while files are over it. */
function installDropTarget() {
  let depth = 0;  // dragenter/dragleave also fire for every child element crossed
  const hasFiles = (e) => [...(e.dataTransfer?.types ?? [])].includes('Files');
  window.addEventListener('dragenter', (e) => {
    if (!hasFiles(e)) return;
    depth++;
    ui.dropOverlay.hidden = false;
  });
  window.addEventListener('dragleave', () => {
    depth = Math.max(0, depth - 1);
    if (depth === 0) ui.dropOverlay.hidden = true;
  });
  window.addEventListener('dragover', (e) => {
    if (!hasFiles(e)) return;
    e.preventDefault();  // allows the drop
    e.dataTransfer.dropEffect = 'copy';
  });
  window.addEventListener('drop', (e) => {
    depth = 0;
    ui.dropOverlay.hidden = true;
    if (!hasFiles(e)) return;
    e.preventDefault();  // no navigation to the file
    // The item list is only readable during this handler: collect synchronously, walk later.
    const collected = collectDropped(e.dataTransfer);
    guard(async () => uploadFiles(await collected), 'The upload could not start')();
  });
}

// ---------------------------------------------------------------------------------------------
// Test hooks for the headless-browser tests (keep the shape exactly)

window.tessera = {
  get connected() { return conn.connected && state.streamId !== null && state.receiving; },
  get frames() { return state.framesDrawn; },
  get lastFrame() { return state.lastFrame; },
  get info() { return state.info; },
  get scene() { return state.sceneId; },
  chartData() {
    return {
      passes: [...timings.passes],
      frames: timings.frames.map((f) => ({ ...f, passes: { ...f.passes } })),
      fps: fps.fps(performance.now()),
      latency_ms: latency.median(),
      bytes: state.lastFrame ? Number(state.lastFrame.bytes ?? state.lastPayload.byteLength) : null,
    };
  },
  camera() { return state.camera ? state.camera.lookAt() : null; },
  errors: state.errors,
};

// ---------------------------------------------------------------------------------------------
// Start-up

function wire() {
  conn.on('state', guard(onSocketState, 'Connection problem'));
  conn.on('frame', guard(onFrame, 'A frame could not be shown'));
  conn.on('stream_end', guard(onStreamEnd, 'The stream ended'));
  conn.on('orphan_error', guard(onOrphanError, 'Change not applied'));
  conn.on('protocol_error', (err) => showError(err, 'A message from the gateway was not understood'));
  conn.on('hello', (hello) => {
    ui.status.title = `gateway ${hello.gateway ?? '?'}, server ${hello.server ?? '?'}`;
  });

  const view = ui.view;
  view.addEventListener('pointerdown', guard(onPointerDown));
  view.addEventListener('pointermove', guard(onPointerMove));
  view.addEventListener('pointerup', guard(onPointerUp));
  view.addEventListener('pointercancel', guard(onPointerUp));
  view.addEventListener('wheel', guard(onWheel), { passive: false });
  view.addEventListener('contextmenu', (e) => e.preventDefault());  // right-drag pans
  view.addEventListener('dblclick', guard(resetView));
  window.addEventListener('keydown', guard(onKeyDown));
  window.addEventListener('keyup', (e) => state.keys.delete(e.code));
  window.addEventListener('blur', () => state.keys.clear());  // keys released elsewhere

  ui.flyToggle.addEventListener('click', () => setFly(!state.fly));
  ui.resetView.addEventListener('click', guard(resetView));
  ui.save.addEventListener('click', guard(saveImage, 'The image could not be saved'));
  ui.errorDismiss.addEventListener('click', () => { ui.error.hidden = true; });
  ui.panelToggle.addEventListener('click', () => {
    const collapsed = document.body.classList.toggle('panel-collapsed');
    ui.panelToggle.setAttribute('aria-expanded', String(!collapsed));
  });

  ui.sceneSelect.addEventListener('change', () => {
    if (ui.sceneSelect.value !== state.sceneId) switchScene(ui.sceneSelect.value);
  });
  ui.uploadInput.addEventListener('change', guard(async () => {
    const entries = collectInput(ui.uploadInput.files ?? []);
    ui.uploadInput.value = '';  // the same files can be picked again
    await uploadFiles(entries);
  }, 'The upload could not start'));
  ui.uploadCancel.addEventListener('click', cancelUpload);
  installDropTarget();

  ui.resolution.addEventListener('change', guard(onViewportResize));
  for (const input of [ui.interactiveEnabled, ui.interactiveScale, ui.interactiveQuality]) {
    input.addEventListener('change', guard(onInteractiveChanged, 'Could not apply the profile'));
  }

  new ResizeObserver(guard(onViewportResize)).observe(view);
  window.addEventListener('resize', guard(onViewportResize));  // devicePixelRatio changes (zoom)
  new ResizeObserver(() => { state.chartDirty = true; requestTick(); }).observe(ui.chart);
  setInterval(guard(renderStats), 500);  // fps decays while no frames come
}

// Phones and narrow windows start with the panel folded away.
if (window.matchMedia('(max-width: 720px)').matches) {
  document.body.classList.add('panel-collapsed');
  ui.panelToggle.setAttribute('aria-expanded', 'false');
}
wire();
onViewportResize();
renderStats();
renderSceneOptions();
conn.connect();

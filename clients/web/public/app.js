// Tessera's web viewer: the page's entry point. It wires the modules together:
//   protocol.js  the gateway's WebSocket (requests, frames, reconnects)
//   camera.js    orbit / fly camera math, pointer gestures, the view in the URL
//   chart.js     per-pass timing chart, fps, bitrate, latency and the stats text
//   settings.js  the settings panel, in sections, from the server's description
//   animation.js the Animation section: the scene's glTF animations, play/pause, time, loop
//   upload.js    which files an upload needs, its scene id, and sending them
//   video.js     H.264 streams: whether the browser decodes them, one VideoDecoder per stream
// Sections below: state, errors and status, the stream session, frames, camera input,
// the view in the URL, stats overlay and fullscreen, viewport size, settings panel, animation,
// the codec, scenes and uploads, test hooks, start-up.
// Nothing is global except window.tessera (the hooks the headless-browser tests read).

import { Connection } from './protocol.js';
import { el } from './dom.js';
import { SettingsPanel, validNumber } from './settings.js';
import { AnimationControls, NONE as NO_ANIMATION } from './animation.js';
import {
  OrbitCamera, PointerGestures, flyVector, formatViewLink, isFlyKey, parseViewLink, wheelFactor,
} from './camera.js';
import {
  BitrateMeter, FpsMeter, LatencyTracker, MAIN_STATS, TimingChart, TimingHistory, statsRows,
} from './chart.js';
import {
  UploadError, checkLimits, collectDropped, collectInput, computeSceneId, formatBytes, planUpload,
  readSceneJson, sendUpload,
} from './upload.js';
import { VideoStream, h264Unsupported } from './video.js';

const $ = (id) => document.getElementById(id);
const ui = {
  viewport: $('viewport'), toolbar: $('toolbar'),
  view: $('view'), status: $('status'), flyToggle: $('fly-toggle'), resetView: $('reset-view'),
  save: $('save'), panelToggle: $('panel-toggle'), flyHelp: $('fly-help'),
  copyLink: $('copy-link'), overlayToggle: $('overlay-toggle'), fullscreen: $('fullscreen'),
  overlay: $('overlay'), linkNote: $('link-note'),
  error: $('error'), errorText: $('error-text'), errorDismiss: $('error-dismiss'),
  dropOverlay: $('drop-overlay'),
  sceneSelect: $('scene-select'), uploadInput: $('upload-input'), uploadBox: $('upload-box'),
  uploadStatus: $('upload-status'), uploadProgress: $('upload-progress'),
  uploadCancel: $('upload-cancel'), uploadNote: $('upload-note'), sceneWarnings: $('scene-warnings'),
  resolution: $('resolution'), resolutionField: $('resolution-field'), settings: $('settings'),
  notes: $('notes'),
  codec: $('codec'), codecField: $('codec-field'), crf: $('video-crf'), crfField: $('crf-field'),
  codecNote: $('codec-note'),
  interactiveEnabled: $('interactive-enabled'), interactiveScale: $('interactive-scale'),
  interactiveQuality: $('interactive-quality'),
  interactiveCrf: $('interactive-crf'), interactiveCrfField: $('interactive-crf-field'),
  chart: $('chart'), chartLegend: $('chart-legend'), stats: $('stats'),
  animation: {
    section: $('animation'), select: $('animation-select'), play: $('animation-play'),
    time: $('animation-time'), readout: $('animation-readout'), loop: $('animation-loop'),
  },
};

const RESIZE_DEBOUNCE_MS = 150;
const LINK_DEBOUNCE_MS = 400;  // the URL follows the camera once it rests this long
const RETRY_MIN_MS = 500;    // stream retries: 0.5 s doubling to 5 s (as the socket's)
const RETRY_MAX_MS = 5000;
const MOVED_NOTE_MS = 4000;  // how long the status says the stream moved to another render server

// ---------------------------------------------------------------------------------------------
// State

const conn = new Connection(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`);
const timings = new TimingHistory();
const chart = new TimingChart(ui.chart, ui.chartLegend, timings);
const fps = new FpsMeter();
const bitrate = new BitrateMeter();
const latency = new LatencyTracker();
const gestures = new PointerGestures();

// The view a link asked for (#scene=…&eye=…, camera.js parseViewLink), applied once the scene
// list is known. ?scene= is what older links carry.
const startLink = parseViewLink(location.hash);

const state = {
  info: null,            // ServerInfo
  scenes: [],            // SceneInfo list
  scenesListed: false,   // state.scenes came from the server
  sceneId: startLink.sceneId || new URLSearchParams(location.search).get('scene') || 'demo',
  pendingLink: startLink,  // the page's link, until applied

  // The stream. `gen` grows whenever a stream starts or stops, so that late async results
  // (open replies, decodes, timers) can tell they belong to a stream that is gone.
  gen: 0,
  streamId: null,
  receiving: false,      // a frame has arrived on the current stream
  resuming: false,       // the current stream resumed a session and has had no frame yet
  token: null,           // the last Frame.session_token
  moves: 0,              // times the gateway moved the stream to another render server
  movedAt: -Infinity,    // when it last did (performance.now())
  movedNoteTimer: null,
  retryTimer: null,
  retryDelay: RETRY_MIN_MS,
  bootTimer: null,
  epoch: 0,              // grows when the socket closes: start-up steps of an old socket stop

  // What the user asked for; a fresh session is opened with it.
  userSettings: {},      // RenderSettings fields the user changed
  interactive: null,     // the InteractiveProfile the user set
  renderSize: null,      // {width, height} last sent
  videoWanted: 'jpeg',   // the Codec control: 'jpeg' or 'h264' (remembered)
  crf: 23,               // H.264 quality, 1..51 (remembered)
  interactiveCrf: 29,    // H.264 quality while the camera moves (the interactive profile)
  codec: 'jpeg',         // what the stream is asked for: 'h264' only where this browser decodes it
  h264Refused: '',       // why H.264 cannot be used after all (the decoder or the server refused)
  confirmed: {},         // the last frame's effective settings
  pendingFields: new Map(),  // setting name -> event id of its last change
  sentEvents: new Map(),     // request id of a recent event -> {stream, names: settings changed}

  camera: null,          // OrbitCamera, once initialised from a frame
  cameraInitAfter: 0,    // > 0: re-initialise from the first frame reflecting this event id
  cameraDirty: false,
  linkLookAt: null,      // a link's LookAt (its up may not be +Y), sent as is until the camera moves
  yfov: 0.8,
  fovSet: false,         // yfov came from a link: every camera message carries it
  fly: false,
  keys: new Set(),       // KeyboardEvent.code values held (fly mode)

  drawnSeq: 0,           // sequence of the newest frame drawn on this stream
  framesDrawn: 0,
  lastFrame: null,       // FrameHeader of the frame shown
  lastPayload: null,     // its encoded bytes
  lastImage: null,       // what is drawn: an ImageBitmap, or a VideoFrame (H.264), until replaced
  decodeMs: null,        // of the frame shown: payload in, picture out
  video: null,           // {gen, stream: VideoStream}: the current stream's H.264 decoder
  keyframeRequests: 0,   // keyframes the page asked for (its decoder lost its place)
  decodeFailed: false,
  chartDirty: false,

  upload: null,          // {id, cancel, cancelled} while an upload (or its check) runs
  overlay: true,         // the stats overlay shows
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
    panel.build(result.schema ?? [], state.info, {
      image: [ui.resolutionField],
      encoding: [ui.codecField, ui.crfField, ui.codecNote],
    });
    restoreSections();
  }
  await refreshScenes();
  if (state.pendingLink) {
    applyLink(state.pendingLink);
    state.pendingLink = null;
  }
  await resolveCodec();
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
    open.camera = cameraMessage();
  } else {
    // A re-frame still pending (its event went to a stream that died) is this open's job now:
    // its frames carry event id 0, so wait for any frame rather than for that event.
    state.camera = null;
    state.cameraInitAfter = 0;
    if (state.fovSet) open.camera = cameraMessage({});  // framed, with the link's field of view
  }
  if (state.interactive) open.interactive = { ...state.interactive };
  if (state.codec === 'h264') open.video = videoMessage();
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
  closeVideo();  // a new stream is a new video: its decoder starts from a keyframe
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
  const event = { settings: { ...state.userSettings, ...renderSize() }, video: videoMessage() };
  if (state.camera && !state.cameraInitAfter) event.camera = cameraMessage();
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
  if (state.codec === 'h264' && !isTransient(err.code) && /\bvideo\b|\bh264\b|H\.264/i.test(err.message ?? '')) {
    // The server cannot stream H.264 (no encoder, a refused video setting): pictures, then.
    fallBackToJpeg(`the server refused it (${err.message})`);
  } else if (err.code === 'INVALID_ARGUMENT' && !revertSettings()) {
    // Do not send a refused value again: first the settings, then (if those were not it) the camera.
    state.camera = null;
    state.linkLookAt = null;
    state.fovSet = false;
  }
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

/**
 * The gateway moved the stream's session to another render server (its own was lost): a new
 * session there with the same scene, camera and settings, on the same stream. Its frames count
 * from 1 and its video starts from a keyframe: decodes of the old session's frames are dropped
 * (a new generation) and the decoder starts again. A short note says what happened.
 */
function onStreamMoved(msg) {
  if (msg.stream !== state.streamId) return;
  state.gen++;
  closeVideo();
  state.drawnSeq = 0;
  state.receiving = false;  // the first frame of the new session says so
  state.moves++;
  state.movedAt = performance.now();
  setStatus('render server lost, moving…', 'busy');
}

/** The status once frames flow: with a note for a few seconds after a move. */
function showConnected() {
  clearTimeout(state.movedNoteTimer);
  const sinceMove = performance.now() - state.movedAt;
  if (sinceMove > MOVED_NOTE_MS) {
    setStatus('connected', 'ok');
    return;
  }
  setStatus('connected (moved to another render server)', 'ok');
  state.movedNoteTimer = setTimeout(() => {
    if (state.receiving) setStatus('connected', 'ok');
  }, MOVED_NOTE_MS - sinceMove);
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

/**
 * Switches scene: a new session with the same settings, framed by the server, or with the
 * camera of `link` (a parsed view link for this scene).
 */
function switchScene(sceneId, link = null) {
  state.sceneId = sceneId;
  state.token = null;
  // An animation (and its time and clock) belongs to the scene; the new one starts at rest.
  for (const name of ['animation', 'scene_time', 'play']) {
    delete state.userSettings[name];
    state.pendingFields.delete(name);
  }
  state.camera = null;
  state.cameraInitAfter = 0;
  state.cameraDirty = false;
  state.linkLookAt = null;
  if (link) applyLinkCamera(link);
  syncSceneUi();
  guard(startStream, 'Could not open the scene')({ resume: false });
}

/** The URL (#scene=…) and the picker follow the current scene. */
function syncSceneUi() {
  writeLink();
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
  // A frame's settings name the animation only when there is one.
  const confirmed = { animation: NO_ANIMATION, ...state.confirmed };
  for (const name of names) {
    state.pendingFields.delete(name);
    if (!(name in state.userSettings)) continue;
    if (name in confirmed && confirmed[name] !== state.userSettings[name]) {
      state.userSettings[name] = confirmed[name];
      reverted = true;
    }
    panel.controls.get(name)?.write(state.userSettings[name]);
  }
  if (!reverted && names.length === Object.keys(state.userSettings).length) {
    reverted = names.length > 0 || state.interactive !== null;
    state.userSettings = {};
    state.interactive = null;
  }
  animation.show({ ...confirmed, ...state.userSettings });
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
    showConnected();
  }
  if (frame.session_token) state.token = frame.session_token;
  if (frame.scene_id && frame.scene_id !== state.sceneId) {
    state.sceneId = frame.scene_id;  // e.g. an 8-character prefix resolved to the full id
    syncSceneUi();
  }
  const now = performance.now();
  bitrate.add(now, payload.byteLength);
  const latencyMs = latency.frameArrived(Number(frame.event_id ?? 0), now);
  maybeInitCamera(frame);
  if (frame.encoding === 'VIDEO_H264') {
    decodeVideo(state.gen, header, payload, latencyMs);
    return;
  }
  closeVideo();  // a picture: the video before it ended (the codec changed)
  decodeAndDraw(state.gen, frame, payload, latencyMs).catch((err) => {
    if (!state.decodeFailed) showError(err, 'A frame could not be shown');
    state.decodeFailed = true;  // once is enough: the next frames would say the same
  });
}

async function decodeAndDraw(gen, frame, payload, latencyMs) {
  const type = frame.encoding === 'IMAGE_PNG' ? 'image/png' : 'image/jpeg';
  const started = performance.now();
  const bitmap = await createImageBitmap(new Blob([payload], { type }));
  showImage(gen, bitmap, frame, payload, latencyMs, performance.now() - started);
}

/**
 * An H.264 frame to the stream's decoder (one per stream, from its first frame); what it
 * decodes is drawn by showImage. A decoder that lost its place asks for a keyframe while the
 * page wants H.264 (frames still coming after a switch to JPEG need none).
 */
function decodeVideo(gen, header, payload, latencyMs) {
  if (typeof window.VideoDecoder !== 'function') {
    fallBackToJpeg('this browser has no WebCodecs video decoder');
    return;
  }
  if (state.video?.gen !== gen) {
    closeVideo();
    const stream = new VideoStream({
      onFrame: (videoFrame, meta, decodeMs) =>
        showImage(gen, videoFrame, meta.frame, meta.payload, meta.latencyMs, decodeMs),
      onKeyframeNeeded: () => {
        if (gen !== state.gen || state.codec !== 'h264') return;
        if (sendEvent({ keyframe: true }) !== null) state.keyframeRequests++;
      },
      onUnsupported: (reason) => {
        if (gen === state.gen) fallBackToJpeg(reason);
      },
    });
    state.video = { gen, stream };
  }
  const frame = header.frame;
  state.video.stream.push(frame, header.video_seq, payload, { frame, payload, latencyMs });
}

function closeVideo() {
  state.video?.stream.close();
  state.video = null;
}

/**
 * Shows a decoded frame (an ImageBitmap, or a VideoFrame: either is closed once replaced)
 * unless a newer one is shown already, and updates what shows frame data.
 */
function showImage(gen, image, frame, payload, latencyMs, decodeMs) {
  const sequence = Number(frame.sequence ?? 0);
  // Decodes finish out of order: never replace a newer frame, never draw an old stream's.
  if (gen !== state.gen || sequence <= state.drawnSeq) {
    image.close();
    return;
  }
  state.drawnSeq = sequence;
  state.decodeFailed = false;
  state.lastImage?.close();
  state.lastImage = image;
  state.decodeMs = decodeMs;
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
  reflectAnimation(frame);
  renderStats();
}

function drawLastFrame() {
  const ctx = ui.view.getContext('2d');
  if (!state.lastImage || !ctx) return;
  ctx.imageSmoothingQuality = 'high';
  ctx.drawImage(state.lastImage, 0, 0, ui.view.width, ui.view.height);
}

/** The orbit starts from the server's camera: on a new stream, and after reset view. */
function maybeInitCamera(frame) {
  if (Number(frame.yfov) > 0) state.yfov = Number(frame.yfov);
  const waiting = state.camera === null || state.cameraInitAfter > 0;
  if (!waiting || !frame.camera || Number(frame.event_id ?? 0) < state.cameraInitAfter) return;
  state.camera = OrbitCamera.fromLookAt(frame.camera);
  state.cameraInitAfter = 0;
  state.cameraDirty = false;
  scheduleLinkUpdate();  // the server's framing is the view a link shares now
}

// The overlay's stats: the main rows, then the rest folded under "More" (kept open or shut
// across updates).
const statsMain = el('dl');
const statsMore = el('dl');
const statsMoreBox = el('details');
statsMoreBox.id = 'stats-more';
statsMoreBox.append(el('summary', 'More'), statsMore);
ui.stats.replaceChildren(statsMain, statsMoreBox);

function renderStats() {
  const now = performance.now();
  const rows = statsRows(state.lastFrame, {
    fps: fps.label(now),
    latencyMs: latency.median(),
    bitrate: bitrate.label(now),
    decodeMs: state.decodeMs,
  });
  const main = [];
  const more = [];
  for (const [label, value] of rows) {
    (MAIN_STATS.has(label) ? main : more).push(el('dt', label), el('dd', value));
  }
  statsMain.replaceChildren(...main);
  statsMore.replaceChildren(...more);
  statsMoreBox.hidden = more.length === 0;
}

/**
 * "Save image": the frame shown, as the server encoded it (JPEG or PNG); an H.264 frame is no
 * image file, so the picture decoded from it is saved as a PNG at the frame's size.
 */
async function saveImage() {
  const frame = state.lastFrame;
  if (!frame || !state.lastPayload) return;
  const name = `tessera-${short(frame.scene_id || state.sceneId)}-${frame.sequence ?? 0}`;
  if (frame.encoding === 'VIDEO_H264') {
    if (!state.lastImage) return;
    const canvas = el('canvas');
    canvas.width = Number(frame.width) || ui.view.width;
    canvas.height = Number(frame.height) || ui.view.height;
    canvas.getContext('2d').drawImage(state.lastImage, 0, 0, canvas.width, canvas.height);
    const blob = await new Promise((resolve) => canvas.toBlob(resolve, 'image/png'));
    if (!blob) throw new Error('the picture could not be encoded as PNG');
    download(blob, `${name}.png`);
    return;
  }
  const png = frame.encoding === 'IMAGE_PNG';
  download(new Blob([state.lastPayload], { type: png ? 'image/png' : 'image/jpeg' }), `${name}.${png ? 'png' : 'jpg'}`);
}

function download(blob, filename) {
  const url = URL.createObjectURL(blob);
  const a = el('a');
  a.href = url;
  a.download = filename;
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
    state.linkLookAt = null;
    state.cameraDirty = true;
    scheduleLinkUpdate();
  }
  lastTickTime = moving ? now : 0;
  if (state.cameraDirty && usable() && state.streamId !== null) {
    sendEvent({ camera: cameraMessage() });
    state.cameraDirty = false;
  }
  if (state.chartDirty && state.overlay) {  // a hidden chart is drawn when it shows again
    chart.draw();
    state.chartDirty = false;
  }
  if (moving) requestTick();  // continuous movement while keys are held
}

/** The user moved the camera: send it (next animation frame), and the URL follows at rest. */
function cameraChanged() {
  state.linkLookAt = null;
  state.cameraDirty = true;
  scheduleLinkUpdate();
  requestTick();
}

/**
 * A Camera message for the server: `placement` (default: the current LookAt, or a link's own
 * until the camera moves), with the link's field of view when one set it (the server takes a
 * camera without yfov as its default field of view).
 */
function cameraMessage(placement = { look_at: state.linkLookAt ?? state.camera.lookAt() }) {
  return state.fovSet ? { ...placement, yfov: state.yfov } : placement;
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

/** Whether Enter on this element is the element's own (a button, a link, a form control). */
function ownsEnter(target) {
  if (!(target instanceof HTMLElement)) return false;
  return ['BUTTON', 'A', 'SUMMARY', 'INPUT', 'SELECT', 'TEXTAREA'].includes(target.tagName) ||
    target.isContentEditable || target.getAttribute('role') === 'button';
}

/**
 * Keys: F fly, W A S D Q E (and arrows, Shift) move in fly mode, I the stats overlay, Enter
 * fullscreen (unless a button or field has the focus). None while typing in a field.
 */
function onKeyDown(e) {
  if (typingIn(e.target) || e.ctrlKey || e.metaKey || e.altKey) return;
  if (e.code === 'KeyF' && !e.repeat) {
    setFly(!state.fly);
    e.preventDefault();
  } else if ((e.key === 'i' || e.key === 'I') && !e.repeat) {
    setOverlay(!state.overlay);
    e.preventDefault();
  } else if (e.key === 'Enter' && !e.repeat && !ownsEnter(e.target) && !ui.fullscreen.hidden) {
    guard(toggleFullscreen, 'Fullscreen did not work')();
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
  state.linkLookAt = null;
  const eventId = sendEvent({ camera: cameraMessage({ frame: {} }) });
  if (eventId !== null) {
    state.cameraInitAfter = eventId;
  } else {
    state.camera = null;  // no stream now: the next session opens without a camera
    state.cameraInitAfter = 0;
  }
}

// ---------------------------------------------------------------------------------------------
// The view in the URL: #scene=<id>&eye=x,y,z&target=x,y,z[&up=x,y,z]&fov=<degrees>, written
// with replaceState once the camera rests, read on load and when the hash is edited

let linkTimer = null;
let linkWritten = null;  // the hash this page wrote last (a hashchange to it is our own)

/** A scene the server listed: the id, or a prefix of one. */
const sceneListed = (id) => id === 'demo' ||
  state.scenes.some((s) => !s.deleted && (s.scene_id === id || s.scene_id.startsWith(id)));

/** The current view as a hash (without '#'). */
function currentLink() {
  const lookAt = state.linkLookAt ?? (usable() ? state.camera.lookAt() : null);
  const yfov = lookAt || state.fovSet ? state.yfov : undefined;
  return formatViewLink({ sceneId: state.sceneId, lookAt, yfov });
}

/** Puts the current view in the URL now (no history entry, no navigation). */
function writeLink() {
  clearTimeout(linkTimer);
  linkTimer = null;
  const url = new URL(location.href);
  url.searchParams.delete('scene');  // older links' ?scene=: the hash has it now
  url.hash = currentLink();
  linkWritten = url.hash;
  if (url.href !== location.href) window.history.replaceState(window.history.state, '', url);
}

/** The URL follows the camera once it has rested LINK_DEBOUNCE_MS (not every frame). */
function scheduleLinkUpdate() {
  clearTimeout(linkTimer);
  linkTimer = setTimeout(guard(writeLink, 'Could not update the link'), LINK_DEBOUNCE_MS);
}

/** The note under the scene picker about the page's link; '' hides it. */
function setLinkNote(text) {
  ui.linkNote.textContent = text;
  ui.linkNote.hidden = text === '';
}

/** The camera and field of view of a parsed link (its scene is the caller's business). */
function applyLinkCamera(link) {
  if (link.yfov) {
    state.yfov = link.yfov;
    state.fovSet = true;
  }
  if (link.lookAt) {
    state.camera = OrbitCamera.fromLookAt(link.lookAt);
    state.cameraInitAfter = 0;
    state.linkLookAt = link.lookAt.up ? link.lookAt : null;  // the orbit itself keeps +Y up
  }
}

/**
 * Applies the page's link once the scenes are listed (before the first stream opens): its
 * scene when the server has it, then its camera instead of the server's framing. What cannot
 * be used is ignored, with a note.
 */
function applyLink(link) {
  const notes = [];
  if (link.problems.length > 0) notes.push(`Ignored in the link: ${link.problems.join('; ')}.`);
  if (link.sceneId && state.scenesListed && !sceneListed(link.sceneId)) {
    notes.push(`The link's scene ${short(link.sceneId)} is not on this server: showing "demo", ` +
      'framed by the server.');
    state.sceneId = 'demo';
    renderSceneOptions();
  } else {
    applyLinkCamera(link);
  }
  setLinkNote(notes.join(' '));
}

/** A hash edited by hand (or a link followed within the page): show that view. */
function onHashChange() {
  if (location.hash === linkWritten) return;
  const link = parseViewLink(location.hash);
  const notes = link.problems.length > 0 ? [`Ignored in the link: ${link.problems.join('; ')}.`] : [];
  if (link.sceneId && state.scenesListed && !sceneListed(link.sceneId)) {
    notes.push(`The link's scene ${short(link.sceneId)} is not on this server.`);
    setLinkNote(notes.join(' '));
    writeLink();  // the URL says what is shown
    return;
  }
  setLinkNote(notes.join(' '));
  if (link.sceneId && !state.sceneId.startsWith(link.sceneId)) {
    switchScene(link.sceneId, link);
    return;
  }
  applyLinkCamera(link);
  if (link.lookAt || link.yfov) {
    state.cameraDirty = true;
    requestTick();
  }
}

/** "Copy link": the current view's URL to the clipboard (or, failing that, in the note). */
async function copyLink() {
  writeLink();
  const url = location.href;
  let copied = false;
  try {
    await navigator.clipboard.writeText(url);
    copied = true;
  } catch {
    // No clipboard API (plain http) or no permission: the old way, then the note.
    const area = el('textarea');
    area.value = url;
    area.setAttribute('readonly', '');
    area.style.position = 'fixed';
    area.style.opacity = '0';
    document.body.append(area);
    area.select();
    try {
      copied = document.execCommand('copy');
    } catch {
      copied = false;
    }
    area.remove();
  }
  if (!copied) setLinkNote(`Copy this link: ${url}`);
  ui.copyLink.textContent = copied ? 'Link copied' : 'Copy link';
  ui.copyLink.dataset.copied = String(copied);
  setTimeout(() => { ui.copyLink.textContent = 'Copy link'; }, 1500);
}

// ---------------------------------------------------------------------------------------------
// Stats overlay (I) and fullscreen (Enter) of the viewport: canvas, toolbar and overlay

const STORAGE_OVERLAY = 'tessera.overlay';
const STORAGE_SECTIONS = 'tessera.sections';

/** localStorage, which may be missing or refuse (private modes, disabled storage). */
function loadStored(key) {
  try {
    return window.localStorage.getItem(key);
  } catch {
    return null;
  }
}
function saveStored(key, value) {
  try {
    window.localStorage.setItem(key, value);
  } catch {
    // not remembered: no harm
  }
}

function setOverlay(on, remember = true) {
  state.overlay = on;
  ui.overlay.hidden = !on;
  ui.overlayToggle.setAttribute('aria-pressed', String(on));
  if (remember) saveStored(STORAGE_OVERLAY, on ? '1' : '0');
  if (on) {
    renderStats();
    state.chartDirty = true;
    requestTick();
  }
}

/** Settings sections open or shut as the user left them. */
function restoreSections() {
  let saved = {};
  try {
    const parsed = JSON.parse(loadStored(STORAGE_SECTIONS) ?? '{}');
    if (parsed && typeof parsed === 'object') saved = parsed;
  } catch {
    // unreadable: the defaults
  }
  for (const details of document.querySelectorAll('#panel details.group')) {
    if (typeof saved[details.id] === 'boolean') details.open = saved[details.id];
    details.addEventListener('toggle', () => {
      saved[details.id] = details.open;
      saveStored(STORAGE_SECTIONS, JSON.stringify(saved));
    });
  }
}

async function toggleFullscreen() {
  if (document.fullscreenElement) await document.exitFullscreen();
  else await ui.viewport.requestFullscreen({ navigationUI: 'hide' });
}

/** The button follows the state (Esc, the browser's own controls); the canvas resizes itself. */
function onFullscreenChange() {
  const on = document.fullscreenElement === ui.viewport;
  ui.fullscreen.setAttribute('aria-pressed', String(on));
  ui.fullscreen.textContent = on ? 'Exit fullscreen' : 'Fullscreen';
}

/** The overlay and the error banner start below the toolbar, however many rows it wraps to. */
function onToolbarResize() {
  const bottom = ui.toolbar.offsetTop + ui.toolbar.offsetHeight;
  ui.viewport.style.setProperty('--hud-top', `${bottom + 8}px`);
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

/**
 * Canvas pixels x the resolution choice, scaled down (same aspect) to the server's limits; for
 * H.264 rounded down to even sizes of 16 or more, the only ones the server codes.
 */
function renderSize() {
  const scale = Number(ui.resolution.value) / 100 || 1;
  const width = Math.max(1, Math.round(ui.view.width * scale));
  const height = Math.max(1, Math.round(ui.view.height * scale));
  const maxW = Number(state.info?.limits?.max_width) || 16384;
  const maxH = Number(state.info?.limits?.max_height) || 16384;
  const fit = Math.min(1, maxW / width, maxH / height);
  const size = {
    width: Math.max(1, Math.min(maxW, Math.floor(width * fit))),
    height: Math.max(1, Math.min(maxH, Math.floor(height * fit))),
  };
  if (state.codec === 'h264') {
    const even = (v, max) => Math.min(max - (max % 2), Math.max(16, v - (v % 2)));
    size.width = even(size.width, maxW);
    size.height = even(size.height, maxH);
  }
  return size;
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
// Animation: the scene's glTF animations (SceneInfo.animations, from the scene list), played
// by the server; its fields are settings like the panel's, kept in state.userSettings

const animation = new AnimationControls(ui.animation, (change) => {
  Object.assign(state.userSettings, change);
  sendEvent({ settings: change });
}, guard);

/** The SceneInfo of the scene shown, as the server listed it; null when it did not. */
function currentSceneInfo(sceneId = state.sceneId) {
  return state.scenes.find((s) => s.scene_id === sceneId) ??
    state.scenes.find((s) => !s.deleted && s.scene_id.startsWith(sceneId)) ?? null;
}

/**
 * The section follows each frame (the slider the time a playing animation shows). Once the
 * user has played or timed an animation, the time shown is the one a new session starts from
 * (after a lost stream, a resume): the animation goes on where it was, not where it was set.
 */
function reflectAnimation(frame) {
  const time = animation.reflect(frame, state.pendingFields);
  const timed = 'play' in state.userSettings || 'scene_time' in state.userSettings;
  if (time !== undefined && timed) state.userSettings.scene_time = time;
  // A non-looping animation that reached its end was stopped by the server: the page's request
  // stops too, so a new session (after a lost stream) does not play it again.
  if (state.userSettings.play === true && !animation.playing && frame.settings?.play === false) {
    state.userSettings.play = false;
  }
}

// ---------------------------------------------------------------------------------------------
// The codec: JPEG pictures, or an H.264 video where this browser decodes it (WebCodecs)

const STORAGE_VIDEO = 'tessera.video';
let h264Check = null;  // the browser's answer, asked once

/** The VideoSettings the session gets: the codec in use, and the quality for H.264. */
function videoMessage() {
  return state.codec === 'h264'
    ? { codec: 'VIDEO_CODEC_H264', crf: state.crf, interactive_crf: state.interactiveCrf }
    : { codec: 'VIDEO_CODEC_JPEG' };
}

function saveVideoChoice() {
  saveStored(STORAGE_VIDEO, JSON.stringify({
    codec: state.videoWanted, crf: state.crf, interactive_crf: state.interactiveCrf,
  }));
}

/** The Codec choice and CRF as last left in this browser. */
function loadVideoChoice() {
  try {
    const saved = JSON.parse(loadStored(STORAGE_VIDEO) ?? 'null');
    if (saved?.codec === 'h264' || saved?.codec === 'jpeg') state.videoWanted = saved.codec;
    if (Number.isInteger(saved?.crf) && saved.crf >= 1 && saved.crf <= 51) state.crf = saved.crf;
    const ic = saved?.interactive_crf;
    if (Number.isInteger(ic) && ic >= 1 && ic <= 51) state.interactiveCrf = ic;
  } catch {
    // unreadable: the defaults
  }
  ui.codec.value = state.videoWanted;
  ui.crf.value = String(state.crf);
  ui.interactiveCrf.value = String(state.interactiveCrf);
  syncCodecUi();
}

function syncCodecUi() {
  ui.crfField.hidden = state.videoWanted !== 'h264';
  ui.crf.disabled = state.codec !== 'h264';
  ui.interactiveCrfField.hidden = state.videoWanted !== 'h264';
  ui.interactiveCrf.disabled = state.codec !== 'h264';
}

/** The note under the Codec control ('' hides it): why H.264 is not used. */
function setCodecNote(text) {
  ui.codecNote.textContent = text;
  ui.codecNote.hidden = text === '';
}

/**
 * Decides the codec the stream is asked for: H.264 when it is chosen, the server has an encoder
 * (ServerInfo.video_encoders; none from a server without video) and this browser decodes it;
 * else JPEG, with a note saying why. Returns whether it changed.
 */
async function resolveCodec() {
  let codec = 'jpeg';
  let why = '';
  if (state.videoWanted === 'h264') {
    h264Check ??= h264Unsupported(window);
    const encoders = Array.isArray(state.info?.video_encoders) ? state.info.video_encoders : [];
    if (state.h264Refused) why = state.h264Refused;
    else if (encoders.length === 0) why = 'the server has no H.264 encoder';
    else why = await h264Check;
    if (!why) codec = 'h264';
  }
  setCodecNote(why ? `H.264 is not used: ${why}. Showing JPEG.` : '');
  const changed = codec !== state.codec;
  state.codec = codec;
  syncCodecUi();
  return changed;
}

/** Tells the session the codec in use, with the render size it needs (even for H.264). */
function sendVideo() {
  const size = renderSize();
  if (sendEvent({ video: videoMessage(), settings: size }) !== null) state.renderSize = size;
}

async function onCodecChanged() {
  state.videoWanted = ui.codec.value === 'h264' ? 'h264' : 'jpeg';
  saveVideoChoice();
  if (await resolveCodec()) sendVideo();
}

function onCrfChanged() {
  const crf = validNumber(ui.crf, { min: 1, max: 51 }, true);
  if (crf === undefined) return;
  state.crf = crf;
  saveVideoChoice();
  if (state.codec === 'h264') sendEvent({ video: { crf } });
}

function onInteractiveCrfChanged() {
  const interactive_crf = validNumber(ui.interactiveCrf, { min: 1, max: 51 }, true);
  if (interactive_crf === undefined) return;
  state.interactiveCrf = interactive_crf;
  saveVideoChoice();
  if (state.codec === 'h264') sendEvent({ video: { interactive_crf } });
}

/** H.264 cannot be used after all (the decoder or the server refused it): JPEG, with a note. */
function fallBackToJpeg(reason) {
  state.h264Refused = reason;
  if (state.codec !== 'h264') return;
  state.codec = 'jpeg';
  setCodecNote(`H.264 is not used: ${reason}. Showing JPEG.`);
  syncCodecUi();
  closeVideo();
  sendVideo();
}

// ---------------------------------------------------------------------------------------------
// Scenes: the picker, and uploads (file input or drag and drop)

async function refreshScenes() {
  try {
    state.scenes = (await conn.request('scenes')).scenes ?? [];
    state.scenesListed = true;
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
  animation.setScene(currentSceneInfo(current.value));
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

/**
 * Whether the server already has a planned upload's scene: its id computed here (the content
 * hash, as the server and the CLI compute it), then HasScene. Resolves to the SceneInfo when
 * it does; null when it does not or cannot be asked (no WebCrypto outside https and
 * localhost, an older gateway or server, a file that cannot be read: the upload goes ahead and
 * says what is wrong); 'cancelled' when the user cancelled meanwhile.
 */
async function findOnServer(plan) {
  const subtle = window.isSecureContext ? globalThis.crypto?.subtle : undefined;
  if (!subtle) return null;
  const check = { id: null, cancelled: false, cancel: () => {} };
  state.upload = check;
  const total = plan.files.reduce((sum, f) => sum + f.size, 0);
  ui.uploadProgress.max = Math.max(1, total);
  ui.uploadProgress.value = 0;
  ui.uploadStatus.textContent = `checking: hashing ${plan.main}…`;
  try {
    const sceneId = await computeSceneId(plan, {
      subtle,
      onFile: (index, done) => {
        ui.uploadProgress.value = done;
        const next = plan.files[index + 1];
        if (next) ui.uploadStatus.textContent = `checking: hashing ${next.name}…`;
      },
    });
    if (check.cancelled) return 'cancelled';
    ui.uploadStatus.textContent = 'checking: does the server have it?';
    ui.uploadProgress.removeAttribute('value');
    const reply = await conn.request('has_scene', { scene_id: sceneId });
    if (check.cancelled) return 'cancelled';
    return reply.present ? { ...reply.info, scene_id: sceneId } : null;
  } catch {
    return check.cancelled ? 'cancelled' : null;
  } finally {
    state.upload = null;
  }
}

/**
 * Uploads a scene from file descriptors [{path, size, file}], then switches to it; a scene the
 * server already has (findOnServer) is selected without sending it again.
 */
async function uploadFiles(entries) {
  if (state.upload) throw new UploadError('An upload is already running; wait for it or cancel it.');
  if (entries.length === 0) return;
  const plan = await planUpload(entries, (e) => readSceneJson(e.file, e.path));
  checkLimits(plan, state.info?.limits);

  ui.sceneWarnings.hidden = true;
  ui.uploadNote.hidden = true;
  ui.uploadBox.hidden = false;
  const skipped = plan.unused.length
    ? ` ${plan.unused.length} file(s) the scene does not use were left out.` : '';
  const known = await findOnServer(plan);
  if (known) ui.uploadBox.hidden = true;
  if (known === 'cancelled') return;
  if (known) {
    ui.uploadNote.textContent =
      `${plan.main} is already on the server: not uploaded (${short(known.scene_id)}).${skipped}`;
    ui.uploadNote.hidden = false;
    showWarnings(known.warnings);
    await refreshScenes();
    switchScene(known.scene_id);
    return;
  }

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

  ui.uploadNote.textContent = `Uploaded ${scene.name} (${short(scene.scene_id)}).${skipped}`;
  ui.uploadNote.hidden = false;
  showWarnings(scene.warnings);
  await refreshScenes();
  switchScene(scene.scene_id);
}

/** The importer's warnings about the scene shown, if any. */
function showWarnings(warnings = []) {
  ui.sceneWarnings.querySelector('ul').replaceChildren(...warnings.map((w) => el('li', w)));
  ui.sceneWarnings.hidden = warnings.length === 0;
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
      bitrate_bps: bitrate.bitsPerSecond(performance.now()),
      latency_ms: latency.median(),
      bytes: state.lastFrame ? Number(state.lastFrame.bytes ?? state.lastPayload.byteLength) : null,
    };
  },
  camera() { return state.camera ? state.camera.lookAt() : null; },
  errors: state.errors,
  get codec() { return state.codec; },  // what the stream is asked for: 'jpeg' or 'h264'
  get decodeMs() { return state.decodeMs; },  // the frame shown: payload in, picture out
  get keyframeRequests() { return state.keyframeRequests; },
  get moves() { return state.moves; },  // times the gateway moved the stream to another replica
  get status() { return ui.status.textContent; },
};

// ---------------------------------------------------------------------------------------------
// Start-up

function wire() {
  conn.on('state', guard(onSocketState, 'Connection problem'));
  conn.on('frame', guard(onFrame, 'A frame could not be shown'));
  conn.on('stream_end', guard(onStreamEnd, 'The stream ended'));
  conn.on('stream_moved', guard(onStreamMoved, 'The stream moved'));
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
  ui.copyLink.addEventListener('click', guard(copyLink, 'The link could not be copied'));
  ui.overlayToggle.addEventListener('click', () => setOverlay(!state.overlay));
  ui.fullscreen.addEventListener('click', guard(toggleFullscreen, 'Fullscreen did not work'));
  document.addEventListener('fullscreenchange', onFullscreenChange);
  window.addEventListener('hashchange', guard(onHashChange, 'The link could not be shown'));
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
  ui.codec.addEventListener('change', guard(onCodecChanged, 'Could not change the codec'));
  ui.crf.addEventListener('change', guard(onCrfChanged, 'Could not change the video quality'));
  ui.interactiveCrf.addEventListener('change',
    guard(onInteractiveCrfChanged, 'Could not change the video quality while moving'));
  for (const input of [ui.interactiveEnabled, ui.interactiveScale, ui.interactiveQuality]) {
    input.addEventListener('change', guard(onInteractiveChanged, 'Could not apply the profile'));
  }

  new ResizeObserver(guard(onViewportResize)).observe(view);
  window.addEventListener('resize', guard(onViewportResize));  // devicePixelRatio changes (zoom)
  new ResizeObserver(() => { state.chartDirty = true; requestTick(); }).observe(ui.chart);
  new ResizeObserver(onToolbarResize).observe(ui.toolbar);
  setInterval(guard(renderStats), 500);  // fps decays while no frames come
}

// Phones and narrow windows start with the panel folded away, and without the overlay unless
// it was turned on there before.
const narrow = window.matchMedia('(max-width: 720px)').matches;
if (narrow) {
  document.body.classList.add('panel-collapsed');
  ui.panelToggle.setAttribute('aria-expanded', 'false');
}
const overlayStored = loadStored(STORAGE_OVERLAY);
setOverlay(overlayStored === null ? !narrow : overlayStored === '1', false);
ui.fullscreen.hidden = !document.fullscreenEnabled;  // iPhone Safari, some embedded views
if (startLink.problems.length > 0) setLinkNote(`Ignored in the link: ${startLink.problems.join('; ')}.`);
loadVideoChoice();
wire();
onViewportResize();
renderStats();
renderSceneOptions();
conn.connect();

// One browser page: a WebSocket whose requests become tesserad calls (README.md, "The
// WebSocket protocol"). Everything the page sends is untrusted: a malformed message gets an
// error reply naming what is wrong, and nothing a page does reaches another page's calls.
import crypto from 'node:crypto';
import { encodeBinary, decodeBinary } from './wire.js';
import { LatestSender } from './latest.js';
import { GatewayError, describeError, settingsSchema } from './rpc.js';
import { BridgedStream, safeEventId } from './streams.js';

// Per page, at once. A viewer needs one stream, one upload and a few renders.
const MAX_STREAMS = 4;
const MAX_RENDERS = 8;
const MAX_UPLOADS = 2;
const MAX_NAME_BYTES = 1024; // UploadFile.name
const RENDER_DEADLINE_MS = 120_000;
// Renders are refused while this much waits unsent to the page (a page that does not read).
const RENDER_BUFFER_BYTES = 16 << 20;
const PROGRESS_INTERVAL_MS = 100;
// An upload whose page stops sending chunks gives its memory back after this long.
const UPLOAD_IDLE_MS = 60_000;
// Chunks held while an upload waits for the server's limits (normally milliseconds).
const EARLY_CHUNK_BYTES = 8 << 20;

const RequestError = GatewayError;
const invalid = (message) => new RequestError('INVALID_ARGUMENT', message);

/** An untrusted value, quoted for a message: never throws, never long. */
function show(value) {
  let text;
  try {
    text = JSON.stringify(value) ?? typeof value;
  } catch {
    text = typeof value;
  }
  return text.length > 60 ? `${text.slice(0, 57)}...` : text;
}

/** The Frame as JSON, without its image: what a binary frame message's header carries. */
export function frameHeader(frame) {
  const { data, ...rest } = frame;
  return { ...rest, bytes: data ? data.length : 0 };
}

/** Uploads held in the gateway's memory across all pages, bounded. */
export class UploadBudget {
  constructor(bytes) {
    this.limit = bytes;
    this.used = 0;
  }
  take(n) {
    if (this.used + n > this.limit) return false;
    this.used += n;
    return true;
  }
  give(n) {
    this.used = Math.max(0, this.used - n);
  }
}

export class Connection {
  /**
   * @param ws       the page's WebSocket (ws library)
   * @param ctx      { replicas (ReplicaSet), definition, metadata(), limits(): Promise<Limits>,
   *                   maxUploadBytes, uploadBudget, parked (ParkedStreams), stopping(),
   *                   log, version, server, peer }
   */
  constructor(ws, ctx) {
    this.ws = ws;
    this.ctx = ctx;
    this.streams = new Map(); // id -> { stream: BridgedStream, sender: LatestSender }
    this.renders = new Map(); // id -> call
    this.uploads = new Map(); // id -> upload state
    this.closed = false;
    ws.on('message', (data, isBinary) => this.onMessage(data, isBinary));
    ws.on('close', (code) => this.onClose(code));
    ws.on('error', (err) => ctx.log(`websocket error: ${err.message}`));
    this.sendJson({ type: 'hello', gateway: ctx.version, server: ctx.server });
  }

  // ---- sending ----------------------------------------------------------------------------

  sendJson(message) {
    if (this.closed || this.ws.readyState !== this.ws.OPEN) return;
    this.ws.send(JSON.stringify(message));
  }

  reply(id, result) {
    this.sendJson({ id, ok: true, result });
  }

  fail(id, err, code) {
    const error = describeError(err, err instanceof RequestError ? err.code : code);
    if (id === undefined) this.sendJson({ type: 'error', error });
    else this.sendJson({ id, ok: false, error });
  }

  // ---- receiving --------------------------------------------------------------------------

  // Nothing a page sends may throw out of here: an exception escaping a ws listener would end
  // the process, and every other page with it.
  onMessage(data, isBinary) {
    try {
      if (isBinary) this.onChunk(data);
      else this.onText(data);
    } catch (err) {
      this.ctx.log(`message handling failed: ${err.stack ?? err}`);
      this.fail(undefined, invalid('message could not be handled'));
    }
  }

  onText(data) {
    let msg;
    try {
      msg = JSON.parse(data.toString('utf8'));
    } catch (e) {
      this.fail(undefined, invalid(`message is not JSON: ${e.message}`));
      return;
    }
    if (msg === null || typeof msg !== 'object' || Array.isArray(msg)) {
      this.fail(undefined, invalid('message is not a JSON object'));
      return;
    }
    const { id, op } = msg;
    if (!Number.isSafeInteger(id) || id <= 0) {
      this.fail(undefined, invalid('id: wants a positive integer'));
      return;
    }
    if (this.streams.has(id) || this.renders.has(id) || this.uploads.has(id)) {
      this.fail(id, invalid(`id: ${id} is still in use by another request`));
      return;
    }
    if (typeof op !== 'string' || !Object.hasOwn(this.handlers, op)) {
      this.fail(id, invalid(`op: unknown operation ${show(op)}`));
      return;
    }
    // Run synchronously: a binary chunk right behind an `upload` (often in the same TCP read)
    // must find the upload registered.
    try {
      const result = this.handlers[op].call(this, id, msg);
      if (result instanceof Promise) result.catch((err) => this.fail(id, err));
    } catch (err) {
      this.fail(id, err);
    }
  }

  handlers = {
    info: this.info,
    scenes: this.scenes,
    has_scene: this.hasScene,
    delete: this.deleteScene,
    render: this.render,
    open: this.open,
    event: this.event,
    close: this.closeStream,
    upload: this.upload,
    cancel: this.cancel,
  };

  /** A method of RenderService as the proto defines it (its serializers). */
  method(name) {
    return this.ctx.definition['tessera.v1.RenderService']?.[name];
  }

  /**
   * A unary call as a promise (rejects with the gRPC error): on `replica`, else on the replica
   * the replica set picks for it (a ready one; with the scene, where scenes are not shared).
   */
  async unary(method, request, { replica = null, sceneId = '', deadlineMs = 30_000 } = {}) {
    const target = replica ?? await this.ctx.replicas.pickUnary({ sceneId });
    return new Promise((resolve, reject) => {
      target.client[method](
        request,
        this.ctx.metadata(),
        { deadline: Date.now() + deadlineMs },
        (err, response) => (err ? reject(err) : resolve(response)),
      );
    });
  }

  /**
   * Serializes `message` as the request of `method` to check it, so a malformed one fails alone
   * (the call lives on). Returns it normalized: parsed back by the proto (unset fields absent or
   * *_UNSPECIFIED, unknown keys gone), which is what the stream's state keeps (session.js).
   */
  check(method, message, what) {
    if (message === null || typeof message !== 'object' || Array.isArray(message)) {
      throw invalid(`${what}: wants an object`);
    }
    const m = this.method(method);
    if (!m) return message;
    let bytes;
    try {
      bytes = m.requestSerialize(message);
    } catch (e) {
      throw invalid(`${what}: ${e.message}`);
    }
    try {
      return m.requestDeserialize(bytes);
    } catch {
      return message;
    }
  }

  // ---- unary calls ------------------------------------------------------------------------

  async info(id) {
    const info = await this.unary('GetServerInfo', {});
    this.reply(id, { info, schema: settingsSchema(this.ctx.definition, info.choices ?? {}) });
  }

  /** ListScenes; where the replicas do not share a store, every scene any of them has. */
  async scenes(id) {
    const replicas = await this.ctx.replicas.answering();
    if (this.ctx.replicas.shared(replicas)) {
      this.reply(id, await this.unary('ListScenes', {}));
      return;
    }
    const lists = await Promise.allSettled(replicas.map((replica) => this.unary('ListScenes', {}, { replica })));
    const ok = lists.filter((l) => l.status === 'fulfilled').map((l) => l.value);
    if (ok.length === 0) throw lists[0].reason;
    const byId = new Map();
    for (const list of ok) for (const scene of list.scenes ?? []) if (!byId.has(scene.scene_id)) byId.set(scene.scene_id, scene);
    this.reply(id, { ...ok[0], scenes: [...byId.values()] });
  }

  /**
   * HasScene: whether tesserad holds a scene id (the page asks before uploading). Where the
   * replicas do not share a store: whether any of them has it.
   */
  async hasScene(id, msg) {
    const sceneId = msg.scene_id;
    // The full content hash only (HasScene looks up no prefixes): 64 lowercase hex, or "demo".
    if (typeof sceneId !== 'string' || !(sceneId === 'demo' || /^[0-9a-f]{64}$/.test(sceneId))) {
      throw invalid(`scene_id: ${show(sceneId)} is not a scene id (64 lowercase hex digits, or "demo")`);
    }
    const replicas = await this.ctx.replicas.answering();
    if (this.ctx.replicas.shared(replicas)) {
      this.reply(id, await this.unary('HasScene', { scene_id: sceneId }));
      return;
    }
    const answers = await Promise.allSettled(replicas.map((replica) => this.unary('HasScene', { scene_id: sceneId }, { replica })));
    const ok = answers.filter((a) => a.status === 'fulfilled').map((a) => a.value);
    if (ok.length === 0) throw answers[0].reason;
    this.reply(id, ok.find((a) => a.present) ?? ok[0]);
  }

  /**
   * DeleteScene on every replica that answers (each drops its loaded copy; the shared store
   * loses it once): the first success, else the first error.
   */
  async deleteScene(id, msg) {
    if (typeof msg.scene_id !== 'string' || !msg.scene_id) throw invalid('scene_id: wants a scene id');
    const replicas = await this.ctx.replicas.answering();
    const results = await Promise.allSettled(replicas.map((replica) => this.unary('DeleteScene', { scene_id: msg.scene_id }, { replica })));
    const done = results.find((r) => r.status === 'fulfilled');
    if (!done) throw results[0].reason;
    this.reply(id, done.value);
  }

  async render(id, msg) {
    const request = msg.request ?? {};
    this.check('Render', request, 'request');
    if (this.ws.bufferedAmount > RENDER_BUFFER_BYTES) {
      throw new RequestError('RESOURCE_EXHAUSTED', 'render: the page is not reading its earlier frames');
    }
    if (this.renders.size >= MAX_RENDERS) {
      throw new RequestError('RESOURCE_EXHAUSTED', `renders: at most ${MAX_RENDERS} at once per page`);
    }
    // The id is taken while a replica is picked (a cancel then lands here).
    const pending = { cancelled: false, cancel() { this.cancelled = true; } };
    this.renders.set(id, pending);
    let replica;
    try {
      replica = await this.ctx.replicas.pickUnary({ sceneId: typeof request.scene_id === 'string' ? request.scene_id : '' });
    } finally {
      this.renders.delete(id);
    }
    if (pending.cancelled || this.closed) throw new RequestError('CANCELLED', 'render: cancelled');
    const call = replica.client.Render(
      request,
      this.ctx.metadata(),
      { deadline: Date.now() + RENDER_DEADLINE_MS },
      (err, frame) => {
        this.renders.delete(id);
        if (err) return this.fail(id, err);
        const header = frameHeader(frame);
        if (!this.closed && this.ws.readyState === this.ws.OPEN) {
          this.ws.send(encodeBinary({ id, frame: header }, frame.data));
        }
        this.reply(id, { frame: header });
      },
    );
    this.renders.set(id, call);
  }

  // ---- streams ----------------------------------------------------------------------------

  open(id, msg) {
    // Streams being closed (their last frame still to come) count only against a looser cap,
    // so a page switching scenes quickly is not refused.
    const open = [...this.streams.values()].filter((s) => !s.stream.closing).length;
    if (open >= MAX_STREAMS || this.streams.size >= 2 * MAX_STREAMS) {
      throw new RequestError('RESOURCE_EXHAUSTED', `streams: at most ${MAX_STREAMS} at once per page`);
    }
    const first = { event_id: msg.event_id ?? 0, open: msg.open ?? {} };
    const normalized = this.check('Stream', first, 'open');
    // A page coming back takes over the stream it left here; another token goes to the replica
    // it names (never to an address that is not one of the gateway's replicas).
    const token = first.open.resume_token;
    let stream = token ? this.ctx.parked.take(token) : null;
    const resumed = stream !== null;
    const target = token && !resumed ? this.ctx.replicas.forToken(token) : null;
    if (!stream) {
      stream = new BridgedStream(
        { replicas: this.ctx.replicas, metadata: this.ctx.metadata, log: this.ctx.log, stopping: this.ctx.stopping },
        { label: `page ${this.ctx.peer ?? '?'} stream ${id}` },
      );
    } else {
      stream.eventId = safeEventId(first.event_id) ?? 0; // this page's events count from here
    }
    const entry = { stream, sender: null };
    // A page that takes over a stream has a new decoder: video frames wait for the keyframe the
    // resume asks for below. The gateway's own events reuse the newest event id the page sent.
    entry.sender = new LatestSender((data, done) => {
      if (this.closed || this.ws.readyState !== this.ws.OPEN) return done(new Error('closed'));
      this.ws.send(data, done);
    }, {
      requestKeyframe: () => stream.write({ event_id: stream.eventId, keyframe: true }),
      awaitKeyframe: resumed,
    });
    this.streams.set(id, entry);
    stream.attach({
      frame: (frame, videoSeq) => {
        const header = { stream: id, frame: frameHeader(frame) };
        const video = videoSeq > 0;
        if (video) header.video_seq = videoSeq;
        entry.sender.push(encodeBinary(header, frame.data), { video, keyframe: frame.keyframe === true });
      },
      end: (status) => {
        this.streams.delete(id);
        const ok = status.code === 0;
        this.sendJson({ type: 'stream_end', stream: id, ok, ...(ok ? {} : { error: describeError(status) }) });
      },
      // Another replica has the session now: frames of the old one that wait are dropped, and
      // the page (told after the last of them) resets its decoder for the new session's first
      // frame, a full one (a keyframe for video).
      moved: (info) => {
        entry.sender.restart();
        this.sendJson({ type: 'stream_moved', stream: id, ...info });
      },
    });
    if (resumed) {
      // A resumed session gets a full frame at once, as after tesserad's own resume; for video
      // a keyframe, which the page's fresh decoder needs.
      stream.write({ event_id: first.event_id, refresh: true, keyframe: true });
      this.reply(id, { stream: id, resumed });
      return undefined;
    }
    // The reply goes before any frame can: frames come in later I/O callbacks.
    return stream.open(normalized, target).then(
      () => this.reply(id, { stream: id, resumed }),
      (err) => {
        if (this.streams.get(id) === entry) this.streams.delete(id);
        throw err;
      },
    );
  }

  event(id, msg) {
    const entry = this.streams.get(msg.stream);
    if (!entry) throw new RequestError('NOT_FOUND', `stream: no open stream ${show(msg.stream)}`);
    const event = msg.event ?? {};
    const normalized = this.check('Stream', event, 'event');
    if (event.open !== undefined && event.open !== null) {
      throw invalid('event.open: only the first event opens a session');
    }
    if (event.keyframe === true) entry.sender.pageAskedKeyframe();
    entry.stream.write(event, normalized);
  }

  closeStream(id, msg) {
    const entry = this.streams.get(msg.stream);
    if (!entry) throw new RequestError('NOT_FOUND', `stream: no open stream ${show(msg.stream)}`);
    entry.stream.end();
    this.reply(id, {});
  }

  cancel(id, msg) {
    const target = msg.target;
    this.streams.get(target)?.stream.cancel();
    this.renders.get(target)?.cancel();
    const upload = this.uploads.get(target);
    if (upload) this.endUpload(upload, new RequestError('CANCELLED', 'upload cancelled'));
    this.reply(id, {});
  }

  // ---- uploads ----------------------------------------------------------------------------

  async upload(id, msg) {
    if (this.uploads.size >= MAX_UPLOADS) {
      throw new RequestError('RESOURCE_EXHAUSTED', `uploads: at most ${MAX_UPLOADS} at once per page`);
    }
    // Claim the id now: chunks may arrive while the limits are fetched.
    const upload = { id, phase: 'waiting', files: [], total: 0, received: 0, budget: 0, early: [] };
    this.uploads.set(id, upload);
    try {
      const limits = await this.ctx.limits();
      if (upload.phase !== 'waiting') return; // cancelled, failed or the page left meanwhile
      this.startUpload(upload, msg, limits);
    } catch (err) {
      this.endUpload(upload, err);
      return;
    }
    for (const chunk of upload.early.splice(0)) this.onUploadChunk(upload, chunk);
  }

  startUpload(upload, msg, limits) {
    const { files, main_file: mainFile } = msg;
    const maxFiles = limits.max_upload_files || 1024;
    const maxBytes = Math.min(limits.max_upload_bytes || Infinity, this.ctx.maxUploadBytes);
    if (!Array.isArray(files) || files.length === 0) throw invalid('files: wants a list of {name, size}');
    if (files.length > maxFiles) {
      throw new RequestError('RESOURCE_EXHAUSTED', `files: ${files.length} files exceed the server's max_upload_files limit (${maxFiles})`);
    }
    const names = new Set();
    files.forEach((f, i) => {
      if (f === null || typeof f !== 'object') throw invalid(`files[${i}]: wants {name, size}`);
      if (typeof f.name !== 'string' || !f.name || Buffer.byteLength(f.name) > MAX_NAME_BYTES) {
        throw invalid(`files[${i}].name: wants a non-empty name of at most ${MAX_NAME_BYTES} bytes`);
      }
      if (names.has(f.name)) throw invalid(`files[${i}].name: '${f.name}' appears twice`);
      names.add(f.name);
      if (!Number.isSafeInteger(f.size) || f.size < 0) throw invalid(`files[${i}].size (${f.name}): wants a byte count`);
      upload.total += f.size;
      upload.files.push({ name: f.name, size: f.size, received: 0, pieces: [], hash: crypto.createHash('sha256') });
    });
    if (mainFile !== undefined && (typeof mainFile !== 'string' || !names.has(mainFile))) {
      throw invalid(`main_file: ${show(mainFile)} is not one of the files`);
    }
    upload.mainFile = mainFile ?? '';
    if (upload.total > maxBytes) {
      throw new RequestError('RESOURCE_EXHAUSTED', `files: ${upload.total} bytes exceed the upload limit (${maxBytes} bytes)`);
    }
    if (!this.ctx.uploadBudget.take(upload.total)) {
      throw new RequestError('RESOURCE_EXHAUSTED', 'upload: the gateway is holding other uploads now; try again shortly');
    }
    upload.budget = upload.total;
    upload.phase = 'receiving';
    upload.maxChunk = Math.max(1, Math.min(limits.max_chunk_bytes || 1 << 20, 1 << 20));
    upload.lastProgress = 0;
    this.armIdleTimer(upload);
    if (upload.total === upload.received) this.sendUpload(upload);
  }

  armIdleTimer(upload) {
    clearTimeout(upload.idleTimer);
    upload.idleTimer = setTimeout(() => {
      if (upload.phase !== 'receiving') return;
      this.endUpload(upload, new RequestError('DEADLINE_EXCEEDED',
        `upload: no data for ${UPLOAD_IDLE_MS / 1000} s (${upload.received} of ${upload.total} bytes came)`));
    }, UPLOAD_IDLE_MS);
    upload.idleTimer.unref?.(); // the listening socket keeps the gateway alive, not this
  }

  onChunk(data) {
    let header, payload;
    try {
      ({ header, payload } = decodeBinary(data));
    } catch (err) {
      this.fail(undefined, invalid(err.message));
      return;
    }
    if (!Number.isSafeInteger(header.upload)) {
      this.fail(undefined, invalid(`upload: not an upload id: ${show(header.upload)}`));
      return;
    }
    const upload = this.uploads.get(header.upload);
    // Chunks of an upload that already ended (failed or cancelled) are still on the wire.
    if (!upload) return;
    if (upload.phase === 'waiting') {
      upload.earlyBytes = (upload.earlyBytes ?? 0) + payload.length;
      if (upload.earlyBytes > EARLY_CHUNK_BYTES) {
        this.endUpload(upload, invalid('upload: chunks sent faster than the upload was accepted'));
      } else {
        upload.early.push({ header, payload });
      }
    } else this.onUploadChunk(upload, { header, payload });
  }

  onUploadChunk(upload, { header, payload }) {
    if (upload.phase !== 'receiving') return;
    // Index only with a number: a key that is an object runs its toString.
    const file = Number.isSafeInteger(header.file) ? upload.files[header.file] : undefined;
    let problem = null;
    if (!file) problem = `file: no file ${show(header.file)} in this upload`;
    else if (header.offset !== file.received) problem = `offset: ${file.name} continues at ${file.received}, not ${show(header.offset)}`;
    else if (payload.length === 0) problem = `chunk of ${file.name} is empty`;
    else if (file.received + payload.length > file.size) problem = `${file.name}: more bytes than its declared size (${file.size})`;
    if (problem) {
      this.endUpload(upload, invalid(problem));
      return;
    }
    file.pieces.push(payload);
    file.hash.update(payload);
    file.received += payload.length;
    upload.received += payload.length;
    this.armIdleTimer(upload);
    this.progress(upload, 'receiving', upload.received);
    if (upload.received === upload.total) this.sendUpload(upload);
  }

  progress(upload, phase, done, force = false) {
    const now = Date.now();
    if (!force && done !== upload.total && now - upload.lastProgress < PROGRESS_INTERVAL_MS) return;
    upload.lastProgress = now;
    this.sendJson({ type: 'progress', id: upload.id, phase, done, total: upload.total });
  }

  /** Streams the received files to UploadScene, with their SHA-256 so tesserad checks them. */
  async sendUpload(upload) {
    upload.phase = 'sending';
    // A ready replica: with a shared store the scene is then everyone's; without, the streams
    // of this scene are placed where it is (HasScene).
    let replica;
    try {
      replica = await this.ctx.replicas.pickUnary();
    } catch (err) {
      this.endUpload(upload, err);
      return;
    }
    if (upload.phase !== 'sending') return; // cancelled, or the page left, meanwhile
    const call = replica.client.UploadScene(this.ctx.metadata(), (err, info) => {
      upload.call = null;
      if (err) this.endUpload(upload, err);
      else this.endUpload(upload, null, info);
    });
    upload.call = call;
    // Waits for grpc-js to take more when its buffer is full; endUpload wakes a waiting write
    // (a cancelled call may never drain).
    const write = (message) =>
      new Promise((resolve) => {
        if (call.write(message)) return resolve();
        upload.wake = resolve;
        call.once('drain', resolve);
      });
    await write({
      manifest: {
        files: upload.files.map((f) => ({ name: f.name, size: f.size, sha256: f.hash.digest('hex') })),
        main_file: upload.mainFile,
      },
    });
    // The pieces as they came from the page (each under 2 MiB), cut to tesserad's chunk size:
    // no second copy of the upload.
    let sent = 0;
    for (let index = 0; index < upload.files.length; index++) {
      const file = upload.files[index];
      let offset = 0;
      while (file.pieces.length > 0) {
        const whole = file.pieces.shift();
        for (let at = 0; at < whole.length; at += upload.maxChunk) {
          if (upload.phase !== 'sending') return; // failed or cancelled meanwhile
          const piece = whole.subarray(at, at + upload.maxChunk);
          await write({ chunk: { file_index: index, offset, data: piece } });
          offset += piece.length;
          sent += piece.length;
          this.progress(upload, 'sending', sent);
        }
      }
    }
    if (upload.phase !== 'sending') return;
    upload.phase = 'loading';
    this.progress(upload, 'loading', upload.total, true);
    call.end();
  }

  endUpload(upload, err, info) {
    if (upload.phase === 'done') return;
    upload.phase = 'done';
    clearTimeout(upload.idleTimer);
    this.uploads.delete(upload.id);
    this.ctx.uploadBudget.give(upload.budget);
    upload.budget = 0;
    for (const f of upload.files) f.pieces = [];
    upload.early = [];
    if (upload.call) upload.call.cancel();
    upload.wake?.();
    if (err) this.fail(upload.id, err);
    else this.reply(upload.id, info);
  }

  // ---- teardown ---------------------------------------------------------------------------

  onClose(code) {
    this.closed = true;
    // A page whose link broke (1006: no close handshake) may come back: its sessions wait in
    // the parked set. A page that closed (a tab closed, a reload: 1000/1001) ends them now, so
    // they do not hold tesserad's sessions for nothing. While the gateway stops, the calls are
    // left to drop with its connection, and tesserad parks them itself.
    for (const { stream, sender } of this.streams.values()) {
      sender.close();
      if (this.ctx.stopping()) continue;
      if (code === 1006) this.ctx.parked.park(stream);
      else stream.cancel();
    }
    for (const call of this.renders.values()) call.cancel();
    for (const upload of [...this.uploads.values()]) this.endUpload(upload, new Error('page closed'));
    this.streams.clear();
    this.renders.clear();
  }
}

// The page's side of the gateway's WebSocket protocol (clients/web/README.md):
//   - requests {"id", "op", ...} matched to their one reply by id (a Promise per request);
//   - binary messages: uint32 LE header length, JSON header, payload (frames in, chunks out);
//   - reconnecting by itself with backoff (0.5 s doubling to 5 s) until close() is called.
// No DOM beyond the WebSocket class, which can be injected (tests, other runtimes).

/** A request that failed: the gateway's error ({code, message, hint}) or a lost connection. */
export class RequestError extends Error {
  constructor({ code = 'UNKNOWN', message = '', hint = '' } = {}) {
    super(message || code);
    this.name = 'RequestError';
    this.code = code;
    this.hint = hint;
  }
}

/** Errors of the connection itself, in the same shape as the gateway's. */
const lostConnection = () => new RequestError({
  code: 'UNAVAILABLE',
  message: 'the connection to the gateway closed before the reply',
  hint: 'The connection to the server was lost; it reconnects by itself.',
});
const notConnected = () => new RequestError({
  code: 'UNAVAILABLE',
  message: 'not connected to the gateway',
  hint: 'The page is not connected to the server right now; it reconnects by itself.',
});

/**
 * Splits a binary message into its JSON header and payload (a view, not a copy).
 * Throws an Error when the message is too short or the header is not JSON.
 */
export function decodeBinary(buffer) {
  const bytes = buffer instanceof Uint8Array ? buffer : new Uint8Array(buffer);
  if (bytes.byteLength < 4) throw new Error('binary message shorter than its length prefix');
  const headerLength = new DataView(bytes.buffer, bytes.byteOffset, 4).getUint32(0, true);
  if (4 + headerLength > bytes.byteLength) {
    throw new Error(`binary message header of ${headerLength} bytes overruns the message`);
  }
  const text = new TextDecoder().decode(bytes.subarray(4, 4 + headerLength));
  const header = JSON.parse(text);
  if (header === null || typeof header !== 'object') throw new Error('binary header is not an object');
  return { header, payload: bytes.subarray(4 + headerLength) };
}

/** One binary message: the length-prefixed JSON header, then the payload bytes. */
export function encodeBinary(header, payload) {
  const head = new TextEncoder().encode(JSON.stringify(header));
  const body = payload instanceof Uint8Array ? payload : new Uint8Array(payload ?? 0);
  const out = new Uint8Array(4 + head.byteLength + body.byteLength);
  new DataView(out.buffer).setUint32(0, head.byteLength, true);
  out.set(head, 4);
  out.set(body, 4 + head.byteLength);
  return out;
}

/**
 * A self-reconnecting connection to the gateway. Events (subscribe with on()):
 *   'state'      {state: 'connecting' | 'open' | 'closed', retryMs?}
 *   'hello'      the gateway's hello message
 *   'frame'      {header, payload} of a Stream frame (header.stream, header.frame)
 *   'stream_end' the gateway's stream_end message
 *   'stream_moved' the gateway's stream_moved message: the stream's session is on another
 *                replica now (a new session: its frames count from 1, video from a keyframe)
 *   'orphan_error' {id, error}: an error reply to a notify() (e.g. a malformed event)
 *   'protocol_error' Error: a message the page could not parse (dropped)
 */
export class Connection {
  #url;
  #WebSocket;
  #minDelay;
  #maxDelay;
  #ws = null;
  #delay;
  #retryTimer = null;
  #stopped = false;
  #nextId = 1;
  #pending = new Map();  // id -> {resolve, reject, onProgress, payload}
  #listeners = new Map();

  constructor(url, { WebSocket = globalThis.WebSocket, minDelayMs = 500, maxDelayMs = 5000 } = {}) {
    this.#url = url;
    this.#WebSocket = WebSocket;
    this.#minDelay = minDelayMs;
    this.#maxDelay = maxDelayMs;
    this.#delay = minDelayMs;
  }

  /** Subscribes to an event; returns the function that unsubscribes. */
  on(type, handler) {
    if (!this.#listeners.has(type)) this.#listeners.set(type, new Set());
    this.#listeners.get(type).add(handler);
    return () => this.#listeners.get(type)?.delete(handler);
  }

  /** Whether the socket is open now. */
  get connected() {
    return this.#ws !== null && this.#ws.readyState === 1;
  }

  /** Bytes queued in the socket and not yet sent (0 when closed). */
  get bufferedAmount() {
    return this.#ws?.bufferedAmount ?? 0;
  }

  /** Opens the socket; from then on it reopens by itself until close(). */
  connect() {
    this.#stopped = false;
    if (this.#ws === null && this.#retryTimer === null) this.#open();
  }

  /** Closes for good: no more reconnects; pending requests fail. */
  close() {
    this.#stopped = true;
    clearTimeout(this.#retryTimer);
    this.#retryTimer = null;
    const ws = this.#ws;
    this.#ws = null;
    if (ws) ws.close();
    this.#failPending();
  }

  /**
   * Sends a request. Returns {id, result}: `result` resolves to the reply's result (a Render
   * reply gets its binary frame as `payload`), or rejects with a RequestError. `onProgress`
   * receives the progress messages of this id (uploads).
   */
  call(op, fields = {}, { onProgress } = {}) {
    const id = this.#nextId++;
    if (!this.connected) return { id, result: Promise.reject(notConnected()) };
    const result = new Promise((resolve, reject) => {
      this.#pending.set(id, { resolve, reject, onProgress, payload: null });
    });
    this.#ws.send(JSON.stringify({ ...fields, id, op }));
    return { id, result };
  }

  /** call() for the result only. */
  request(op, fields, options) {
    return this.call(op, fields, options).result;
  }

  /**
   * Sends a request that gets no reply when it succeeds (op "event"); an error reply comes as
   * an 'orphan_error' event. Returns the request id, or null when not connected.
   */
  notify(op, fields = {}) {
    if (!this.connected) return null;
    const id = this.#nextId++;
    this.#ws.send(JSON.stringify({ ...fields, id, op }));
    return id;
  }

  /** Sends a binary message; false when not connected. */
  sendBinary(header, payload) {
    if (!this.connected) return false;
    this.#ws.send(encodeBinary(header, payload));
    return true;
  }

  /**
   * Resolves once the socket's send buffer holds at most `limitBytes` (WebSocket has no
   * drain event, so this polls); rejects when the connection is lost meanwhile.
   */
  async waitForBuffer(limitBytes, pollMs = 15) {
    const ws = this.#ws;
    while (ws !== null && ws === this.#ws && ws.readyState === 1) {
      if (ws.bufferedAmount <= limitBytes) return;
      await new Promise((resolve) => setTimeout(resolve, pollMs));
    }
    throw notConnected();
  }

  #emit(type, value) {
    for (const handler of [...(this.#listeners.get(type) ?? [])]) {
      try {
        handler(value);
      } catch (err) {
        // A listener's bug must not break the socket's message loop.
        console.error(`tessera: ${type} handler failed`, err);
      }
    }
  }

  #open() {
    this.#retryTimer = null;
    this.#emit('state', { state: 'connecting' });
    let ws;
    try {
      ws = new this.#WebSocket(this.#url);
    } catch (err) {
      this.#emit('protocol_error', err);
      this.#scheduleReconnect();
      return;
    }
    ws.binaryType = 'arraybuffer';
    this.#ws = ws;
    ws.onopen = () => this.#emit('state', { state: 'open' });
    ws.onmessage = (event) => this.#onMessage(event.data);
    ws.onerror = () => {};  // always followed by close, which is where we act
    ws.onclose = () => {
      if (this.#ws !== ws) return;  // close() already dealt with it
      this.#ws = null;
      this.#failPending();
      this.#scheduleReconnect();
    };
  }

  #scheduleReconnect() {
    if (this.#stopped) return;
    const retryMs = this.#delay;
    this.#delay = Math.min(this.#maxDelay, this.#delay * 2);
    this.#emit('state', { state: 'closed', retryMs });
    this.#retryTimer = setTimeout(() => this.#open(), retryMs);
  }

  #failPending() {
    const pending = [...this.#pending.values()];
    this.#pending.clear();
    for (const p of pending) p.reject(lostConnection());
  }

  #onMessage(data) {
    if (typeof data === 'string') {
      let msg;
      try {
        msg = JSON.parse(data);
      } catch (err) {
        this.#emit('protocol_error', new Error(`a text message is not JSON: ${err.message}`));
        return;
      }
      this.#onJson(msg);
      return;
    }
    let decoded;
    try {
      decoded = decodeBinary(data);
    } catch (err) {
      this.#emit('protocol_error', err);
      return;
    }
    const { header, payload } = decoded;
    if (header.stream !== undefined) {
      this.#emit('frame', decoded);
    } else if (this.#pending.has(header.id)) {
      this.#pending.get(header.id).payload = payload;  // a Render reply's frame: kept for its reply
    }
  }

  #onJson(msg) {
    if (msg === null || typeof msg !== 'object') return;
    if (msg.type === 'hello') {
      this.#delay = this.#minDelay;  // a gateway that talks to us: the next drop retries quickly
      this.#emit('hello', msg);
    } else if (msg.type === 'stream_end') {
      this.#emit('stream_end', msg);
    } else if (msg.type === 'stream_moved') {
      this.#emit('stream_moved', msg);
    } else if (msg.type === 'progress') {
      this.#pending.get(msg.id)?.onProgress?.(msg);
    } else if (msg.id !== undefined && msg.ok !== undefined) {
      const pending = this.#pending.get(msg.id);
      if (!pending) {
        if (!msg.ok) this.#emit('orphan_error', { id: msg.id, error: msg.error ?? {} });
        return;
      }
      this.#pending.delete(msg.id);
      if (msg.ok) {
        const result = msg.result ?? {};
        pending.resolve(pending.payload ? { ...result, payload: pending.payload } : result);
      } else {
        pending.reject(new RequestError(msg.error ?? {}));
      }
    }
  }
}

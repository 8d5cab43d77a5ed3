// A tesserad Stream as the gateway holds it, and the streams of pages that went away.
//
// A page's WebSocket can drop (a network blip, a laptop lid, a reload) while its session with
// tesserad is fine. The gateway then keeps the gRPC stream for the server's resume grace
// period; a page that comes back with the session token (Frame.session_token) takes it over
// and gets a full frame at once, as tesserad's own resume does. (tesserad parks sessions only
// when its client vanishes: a grpc-js client that cancels half-closes first, which tesserad
// rightly reads as a clean end. So the gateway parks on its side.)
import { wrapToken } from './replicas.js';
import { GatewayError } from './rpc.js';
import {
  MoveBudget, STATUS, completeState, failoverDecision, followPlay, mergeEvent, openFromState, seenInFrame,
  stateFromOpen,
} from './session.js';

const { OK, CANCELLED, RESOURCE_EXHAUSTED, UNAVAILABLE } = STATUS;
// Old tokens of a stream that moved, kept so a page that missed the new one can still take it
// over while it is parked.
const MAX_TOKENS = 4;

/** An event id as a number; null when it is not one (a page may send a string). */
export function safeEventId(value) {
  const n = Number(value ?? 0);
  return Number.isSafeInteger(n) && n >= 0 ? n : null;
}

/**
 * One page stream, bridged to a tesserad Stream call on one replica at a time. Frames and the
 * end go to whichever page is attached (`sink`). Video frames (VIDEO_H264) are counted as they
 * come from tesserad (1, 2, 3, ..., over the stream's life, parked time and moves included):
 * the page gets each with its number (`video_seq`), so it can tell a gap the gateway made
 * (always followed by a keyframe, see latest.js) from one it did not expect. Frame.sequence
 * cannot tell: tesserad skips sequence numbers for frames it replaced before encoding them.
 *
 * The frames' session_token names the replica (replicas.js wrapToken), so a page that comes
 * back, through this gateway or another, is sent to the replica that holds its session.
 *
 * Failover: the stream keeps what the session was asked for (session.js: the OpenSession and
 * every event since). When its replica is lost (the call ends UNAVAILABLE, or the replica set
 * reports it lost: no answer, or not serving), the session is opened again with that state on
 * another ready replica and attached to the same page stream; the page is told (sink.moved) and
 * the new session's first frame is a full one (a keyframe for video). At most 3 moves a minute;
 * past that the page gets the error.
 */
export class BridgedStream {
  /**
   * @param ctx { replicas: ReplicaSet, metadata(), log(line), stopping(): bool, now?() }
   * @param options.label  names the stream in the logs
   */
  constructor(ctx, { label = 'stream' } = {}) {
    this.ctx = ctx;
    this.label = label;
    this.call = null;
    this.replica = null;
    this.token = '';           // the newest session token, as the page gets it
    this.tokens = [];          // it and a few before it (a moved stream's)
    this.sink = null;          // { frame(frame, videoSeq), end(status), moved(info) }
    this.started = false;      // a call was made
    this.ended = false;
    this.onEnded = null;       // set while parked
    this.closing = false;      // the page half-closed it
    this.cancelled = false;
    this.videoFrames = 0;
    this.eventId = 0;          // the newest event id the page sent: the gateway's own events reuse it
    this.state = { scene_id: '' };  // what the session was asked for (session.js)
    this.resumed = false;      // opened by a resume token: the state comes partly from frames
    this.seen = null;          // ... what they said
    this.budget = new MoveBudget({ now: ctx.now });
    this.moves = 0;
    this.lostAt = 0;           // when the replica was lost, until the next frame
    this.lastDataAt = 0;       // when the last frame came
    this.framesOnCall = 0;
  }

  /**
   * Opens the session. `first` is the page's first ClientEvent (normalized: see session.js).
   * Without `target` the replica set places it; with `target` ({replica, token}: the replica a
   * resume token names and tesserad's token) it resumes there. Resolves once the call is
   * made; rejects with a GatewayError when no replica takes it or it was cancelled meanwhile.
   */
  async open(first, target = null) {
    this.eventId = safeEventId(first.event_id) ?? 0;
    if (target) {
      this.resumed = true;
      this.startCall(target.replica, { event_id: this.eventId, open: { resume_token: target.token } });
      return;
    }
    this.state = stateFromOpen(first.open);
    const replica = await this.ctx.replicas.place({ sceneId: this.state.scene_id });
    if (this.cancelled) throw new GatewayError('CANCELLED', 'open: cancelled');
    // Events the page sent meanwhile are in the state.
    this.startCall(replica, { event_id: this.eventId, open: openFromState(this.state) });
  }

  /** The session's state as the gateway knows it now. */
  currentState() {
    return this.resumed ? completeState(this.state, this.seen) : this.state;
  }

  startCall(replica, first) {
    const call = replica.client.Stream(this.ctx.metadata());
    this.started = true;
    this.call = call;
    this.replica = replica;
    this.framesOnCall = 0;
    replica.streams.add(this);
    call.on('data', (frame) => this.onData(call, frame));
    call.on('error', () => {}); // reported by 'status'
    call.on('status', (status) => this.onStatus(call, status));
    call.write(first);
    if (this.closing) call.end();
  }

  onData(call, frame) {
    if (call !== this.call) return; // a call the stream has left
    this.framesOnCall++;
    this.lastDataAt = this.ctx.now?.() ?? Date.now();
    if (frame.session_token) {
      frame.session_token = wrapToken(this.replica.address, frame.session_token);
      if (frame.session_token !== this.token) {
        this.token = frame.session_token;
        this.tokens = [this.token, ...this.tokens].slice(0, MAX_TOKENS);
      }
    }
    if (this.resumed) this.seen = seenInFrame(frame);
    else if (frame.scene_id) this.state.scene_id = frame.scene_id; // a prefix, resolved
    this.state = followPlay(this.state, frame, this.eventId); // a playing animation's time
    if (this.lostAt && this.framesOnCall === 1) {
      const ms = (this.ctx.now?.() ?? Date.now()) - this.lostAt;
      this.ctx.log(`${this.label}: first frame from ${this.replica.address}, ${ms} ms after the loss of its replica`);
      this.lostAt = 0;
    }
    const videoSeq = frame.encoding === 'VIDEO_H264' ? ++this.videoFrames : 0;
    this.sink?.frame(frame, videoSeq);
  }

  onStatus(call, status) {
    if (call !== this.call) return;
    this.call = null;
    this.replica.streams.delete(this);
    // Full before this session's first frame there: placed on a replica that filled up since
    // its last poll (other gateways, a burst of moves). The whole replica, not a token's limit.
    const full = status.code === RESOURCE_EXHAUSTED && this.framesOnCall === 0 &&
      /reach the max_sessions limit/.test(status.details ?? '');
    const decision = this.decide(status, full);
    if (decision === 'move') {
      this.ctx.replicas.reportFailure(this.replica, full ? `full (${status.details})` : `a stream there ended UNAVAILABLE (${status.details})`);
      this.move(this.replica, full ? `full: ${status.details}` : `lost: ${status.details}`);
    } else if (decision === 'give_up') {
      this.ctx.log(`${this.label}: ${this.replica.address} lost (${status.details}); moved ${this.budget.max} times in the last minute, giving up`);
      this.finish({ ...status, details: `${status.details} (the session moved ${this.budget.max} times in the last minute; the gateway gave up)` });
    } else {
      this.finish(status);
    }
  }

  decide(status, full = false) {
    return failoverDecision(status, {
      full,
      closing: this.closing,
      cancelled: this.cancelled,
      parked: this.sink === null,
      stopping: this.ctx.stopping?.() ?? false,
      single: this.ctx.replicas.single,
      sceneKnown: this.currentState().scene_id !== '',
      budgetLeft: this.budget.left > 0,
    });
  }

  /** The replica set says this stream's replica is lost (no answer, or not serving). */
  replicaLost(replica, why) {
    if (replica !== this.replica || this.call === null || this.ended) return;
    // Missed polls but frames still coming since the first missed one: the replica is slow to
    // answer, not gone, and this session is fine where it is.
    if (!replica.ok && this.lastDataAt >= (replica.failingSince ?? Infinity)) return;
    if (this.decide({ code: UNAVAILABLE }) !== 'move') return; // it ends by itself, or recovers
    const old = this.call;
    this.call = null;
    replica.streams.delete(this);
    old.cancel();
    this.move(replica, why);
  }

  /** Opens the session again on another ready replica; a failure ends the page's stream. */
  move(from, reason) {
    this.moveTo(from, reason).catch((err) => {
      this.ctx.log(`${this.label}: moving from ${from.address} failed: ${err?.stack ?? err}`);
      if (!this.ended) this.finish({ code: UNAVAILABLE, details: `moving the session failed: ${err?.message ?? err}` });
    });
  }

  /** Opens the session again on another ready replica, with the state it was asked for. */
  async moveTo(from, reason) {
    this.budget.take();
    this.moves++;
    this.lostAt = this.ctx.now?.() ?? Date.now();
    let to;
    try {
      to = await this.ctx.replicas.place({ sceneId: this.currentState().scene_id, exclude: new Set([from.address]) });
    } catch (err) {
      this.ctx.log(`${this.label}: ${from.address} ${reason}; cannot move: ${err.message}`);
      this.finish({ code: UNAVAILABLE, details: `replica ${from.address} ${reason}; ${err.message}` });
      return;
    }
    if (this.ended) return; // cancelled meanwhile
    if (this.closing) {
      this.finish({ code: OK, details: 'OK' });
      return;
    }
    this.ctx.log(`${this.label}: moved from ${from.address} (${reason}) to ${to.address}; ` +
      `move ${this.moves}, ${this.budget.left} more allowed this minute`);
    // A session the gateway resumed is opened by it now: its state is all known from here.
    this.state = this.currentState();
    this.resumed = false;
    this.seen = null;
    this.startCall(to, { event_id: this.eventId, open: openFromState(this.state) });
    this.sink?.moved({ from: from.address, to: to.address, reason: `replica ${from.address} ${reason}`, moves: this.moves });
  }

  /** An event from the page (or the gateway's own): kept in the state, sent to the replica. */
  write(event, normalized = event) {
    const id = safeEventId(event.event_id);
    if (id !== null && id > this.eventId) this.eventId = id;
    this.state = mergeEvent(this.state, normalized);
    if (this.call && !this.closing && !this.ended) this.call.write(event);
  }

  /** The page closed the stream: it ends after its last frame. */
  end() {
    if (this.closing || this.ended) return;
    this.closing = true;
    this.call?.end(); // while moving, the move ends it
  }

  /** Ends the stream now (the page cancelled, left, or its grace period ended). */
  cancel() {
    if (this.ended) return;
    this.cancelled = true;
    if (this.call) {
      this.call.cancel(); // its status ends the stream
    } else if (this.started) {
      this.finish({ code: CANCELLED, details: 'Cancelled' }); // between two replicas
    } else {
      this.ended = true; // still being placed: the open fails
    }
  }

  finish(status) {
    if (this.ended) return;
    this.ended = true;
    this.replica?.streams.delete(this);
    this.call = null;
    this.sink?.end(status);
    this.onEnded?.();
  }

  attach(sink) {
    this.sink = sink;
  }

  detach() {
    this.sink = null;
  }
}

/**
 * Streams whose page left, by session token, each until its grace period ends.
 * graceMs() and max() are read when a stream is parked (they follow tesserad's limits).
 */
export class ParkedStreams {
  constructor({ graceMs, max, log }) {
    this.graceMs = graceMs;
    this.max = max;
    this.log = log;
    this.byToken = new Map(); // token -> { stream, timer }
  }

  get size() {
    return this.byToken.size;
  }

  /** Keeps `stream` for a resume; a stream without a token yet (no frame) cannot be resumed. */
  park(stream) {
    stream.detach();
    if (stream.ended) return;
    if (!stream.token || this.graceMs() <= 0) {
      stream.cancel();
      return;
    }
    if (this.byToken.size >= this.max()) {
      const [oldest] = this.byToken.keys(); // Map keeps insertion order
      this.drop(oldest, 'the gateway holds too many parked sessions');
    }
    const key = stream.token; // its token may change while parked (a move under way)
    const timer = setTimeout(() => this.drop(key, 'its grace period ended'), this.graceMs());
    timer.unref?.();
    stream.onEnded = () => {
      clearTimeout(timer);
      this.byToken.delete(key);
    };
    this.byToken.set(key, { stream, timer });
  }

  /**
   * The parked stream with this token (its newest, or one it had before it moved to another
   * replica), taken out of the set; null if none.
   */
  take(token) {
    let key = token;
    if (!this.byToken.has(key)) {
      key = [...this.byToken.keys()].find((k) => this.byToken.get(k).stream.tokens?.includes(token));
    }
    const entry = key === undefined ? undefined : this.byToken.get(key);
    if (!entry) return null;
    clearTimeout(entry.timer);
    this.byToken.delete(key);
    entry.stream.onEnded = null;
    return entry.stream;
  }

  drop(token, why) {
    const stream = this.take(token);
    if (!stream) return;
    this.log?.(`parked session dropped: ${why}`);
    stream.cancel();
  }
}

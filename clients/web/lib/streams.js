// A tesserad Stream as the gateway holds it, and the streams of pages that went away.
//
// A page's WebSocket can drop (a network blip, a laptop lid, a reload) while its session with
// tesserad is fine. The gateway then keeps the gRPC stream for the server's resume grace
// period; a page that comes back with the session token (Frame.session_token) takes it over
// and gets a full frame at once, as tesserad's own resume does. (tesserad parks sessions only
// when its client vanishes: a grpc-js client that cancels half-closes first, which tesserad
// rightly reads as a clean end. So the gateway parks on its side.)

/**
 * One gRPC Stream call; frames and the end go to whichever page is attached. Video frames
 * (VIDEO_H264) are counted as they come from tesserad (1, 2, 3, ..., over the stream's life,
 * parked time included): the page gets each with its number (`video_seq`), so it can tell a gap
 * the gateway made (always followed by a keyframe, see latest.js) from one it did not expect.
 * Frame.sequence cannot tell: tesserad skips sequence numbers for frames it replaced before
 * encoding them, which no decoder missed.
 */
export class BridgedStream {
  constructor(call) {
    this.call = call;
    this.token = '';
    this.sink = null; // { frame(frame, videoSeq), end(status) }
    this.ended = false;
    this.onEnded = null; // set while parked
    this.videoFrames = 0;
    call.on('data', (frame) => {
      if (frame.session_token) this.token = frame.session_token;
      const videoSeq = frame.encoding === 'VIDEO_H264' ? ++this.videoFrames : 0;
      this.sink?.frame(frame, videoSeq);
    });
    call.on('error', () => {}); // reported by 'status'
    call.on('status', (status) => {
      this.ended = true;
      this.sink?.end(status);
      this.onEnded?.();
    });
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
      stream.call.cancel();
      return;
    }
    if (this.byToken.size >= this.max()) {
      const [oldest] = this.byToken.keys(); // Map keeps insertion order
      this.drop(oldest, 'the gateway holds too many parked sessions');
    }
    const timer = setTimeout(() => this.drop(stream.token, 'its grace period ended'), this.graceMs());
    timer.unref?.();
    stream.onEnded = () => {
      clearTimeout(timer);
      this.byToken.delete(stream.token);
    };
    this.byToken.set(stream.token, { stream, timer });
  }

  /** The parked stream with this token, taken out of the set; null if none. */
  take(token) {
    const entry = this.byToken.get(token);
    if (!entry) return null;
    clearTimeout(entry.timer);
    this.byToken.delete(token);
    entry.stream.onEnded = null;
    return entry.stream;
  }

  drop(token, why) {
    const stream = this.take(token);
    if (!stream) return;
    this.log?.(`parked session dropped: ${why}`);
    stream.call.cancel();
  }
}

// Delivery of one stream's frames to a WebSocket, as tesserad's own sessions do it: at most one
// frame is in the socket at a time per stream, and a slow browser gets fewer frames, never a
// backlog and never an old frame after a newer one.
//
// Pictures (JPEG, PNG) decode alone, so they are sent latest-wins: a frame that arrives while
// one is in flight waits in a single slot, and a newer one replaces it.
//
// Video (VIDEO_H264) cannot be thinned that way: a frame that is not a keyframe needs every
// frame since the last keyframe, so dropping one corrupts the picture until the next keyframe.
// Video frames therefore queue, up to MAX_VIDEO_WAITING behind the one in flight. When more
// arrive (the page reads too slowly), the waiting non-key frames are dropped, and so is every
// later non-key frame until a keyframe comes; the sender asks tesserad for that keyframe once
// (requestKeyframe). A keyframe replaces everything waiting: nothing before it is needed.
// So what a page receives always decodes: after a gap comes a keyframe.

/** Video frames that may wait behind the one in flight before the sender drops some. */
export const MAX_VIDEO_WAITING = 3;

export class LatestSender {
  /**
   * @param send (data, done) => void: writes `data` and calls done(err) once it is handed to
   *        the socket (ws's send callback).
   * @param options.requestKeyframe () => void: asks tesserad for a keyframe (the sender had
   *        to drop video frames).
   * @param options.awaitKeyframe   start as if frames had been dropped, with the keyframe
   *        already asked for: a page taking over a stream it left (its new decoder needs a
   *        keyframe; the resume asks for it).
   */
  constructor(send, { requestKeyframe = () => {}, awaitKeyframe = false } = {}) {
    this.send_ = send;
    this.requestKeyframe_ = requestKeyframe;
    this.inFlight_ = false;
    this.waiting_ = [];  // [{data, video, keyframe}]: a picture alone, or video frames in order
    this.closed_ = false;
    this.needKeyframe_ = awaitKeyframe;  // non-key video frames are dropped until a keyframe
    this.askedKeyframe_ = awaitKeyframe;  // ... and one has been asked for in this gap
    this.sent = 0;
    this.dropped = 0;
    this.keyframeRequests = 0;
  }

  /**
   * Queues `data`, the newest frame. `video`: a VIDEO_H264 frame; `keyframe`: one that decodes
   * alone. A picture (not video) replaces whatever waits.
   */
  push(data, { video = false, keyframe: key = false } = {}) {
    if (this.closed_) return;
    const keyframe = video && key;
    const item = { data, video, keyframe };
    if (video && !keyframe && this.needKeyframe_) {
      this.dropped++;
      this.askKeyframe_();
      return;
    }
    if (!this.inFlight_) {
      this.write_(item);
    } else if (!video || keyframe) {
      // Decodes alone: everything waiting is older and not needed for it.
      this.drop_(this.waiting_);
      this.waiting_ = [item];
    } else if (!this.queueVideo_(item)) {
      return;
    }
    if (keyframe) {
      this.needKeyframe_ = false;
      this.askedKeyframe_ = false;
    }
  }

  /**
   * A non-key video frame behind the one in flight: queued, or (the page falls behind)
   * dropped with the frames waiting that it depends on. Returns whether it was queued.
   */
  queueVideo_(item) {
    // A picture waiting is older than this frame and not needed by it.
    this.drop_(this.waiting_.filter((w) => !w.video));
    this.waiting_ = this.waiting_.filter((w) => w.video);
    if (this.waiting_.length < MAX_VIDEO_WAITING) {
      this.waiting_.push(item);
      return true;
    }
    // Keep a waiting keyframe (it decodes alone, and comes first: it replaced what waited
    // before it); drop the frames after it, this one, and every later one until a keyframe.
    const kept = this.waiting_[0].keyframe ? 1 : 0;
    this.drop_(this.waiting_.slice(kept));
    this.waiting_ = this.waiting_.slice(0, kept);
    this.dropped++;
    this.needKeyframe_ = true;
    this.askedKeyframe_ = false;
    this.askKeyframe_();
    return false;
  }

  /**
   * The page asked tesserad for a keyframe itself (its decoder lost its place): non-key
   * frames before that keyframe are of no use to it.
   */
  pageAskedKeyframe() {
    if (this.closed_ || this.waiting_.some((w) => w.keyframe)) return;  // one is on its way
    this.drop_(this.waiting_.filter((w) => w.video));
    this.waiting_ = this.waiting_.filter((w) => !w.video);
    this.needKeyframe_ = true;
    this.askedKeyframe_ = true;
  }

  /**
   * The stream moved to another replica: a new session, whose first frame is a full one (a
   * keyframe for video). What waits belongs to the old session and is dropped (the page resets
   * its decoder when told of the move, so it could not use it); video waits for the keyframe.
   */
  restart() {
    if (this.closed_) return;
    this.drop_(this.waiting_);
    this.waiting_ = [];
    this.needKeyframe_ = true;
    this.askedKeyframe_ = false;  // the new session sends one; a non-key frame first asks
  }

  /** Drops what waits; later pushes are ignored. */
  close() {
    this.closed_ = true;
    this.waiting_ = [];
  }

  /** Frames waiting behind the one in flight (tests). */
  get waiting() {
    return this.waiting_.length;
  }

  drop_(items) {
    for (const w of items) {
      this.dropped++;
      if (w.video && !w.keyframe) this.needKeyframe_ = true;
    }
  }

  askKeyframe_() {
    if (this.askedKeyframe_) return;
    this.askedKeyframe_ = true;
    this.keyframeRequests++;
    this.requestKeyframe_();
  }

  write_(item) {
    this.inFlight_ = true;
    this.sent++;
    this.send_(item.data, (err) => {
      this.inFlight_ = false;
      if (err || this.closed_) {
        // Nothing reaches this page any more; a page that resumes the stream asks anew.
        this.waiting_ = [];
        return;
      }
      const next = this.waiting_.shift();
      if (next !== undefined) this.write_(next);
    });
  }
}

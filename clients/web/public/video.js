// H.264 streams in the page: whether this browser can decode them (WebCodecs), and one
// VideoDecoder per stream fed with the gateway's VIDEO_H264 frames (clients/web/README.md).
//
// A frame that is not a keyframe needs every frame since the last keyframe, in order. The
// gateway never sends one after a gap it made (it drops to the next keyframe), and numbers the
// video frames it got from tesserad (`video_seq`), so a gap it did not promise shows. Whenever
// the decoder cannot go on (a non-key frame before any keyframe, a gap, a decode error) the
// stream resets, asks for a keyframe once, and drops frames until one comes.
// No DOM: the WebCodecs classes are injected (tests), and what is decoded goes to a callback.

/** The codec the page checks before asking for H.264 (High profile, level 3.1). */
export const H264_PROBE_CODEC = 'avc1.64001f';

// Decode errors in a row, without a picture decoded between them, before the page gives up on
// the stream (each one costs the server a keyframe).
const MAX_ERRORS_WITHOUT_OUTPUT = 3;

// An RFC 6381 AVC codec string: avc1 or avc3, then profile, constraints and level in hex.
const AVC_CODEC = /^avc[13]\.[0-9A-Fa-f]{6}$/;

/**
 * Why this browser cannot decode H.264 here ('' when it can): no WebCodecs (older browsers,
 * and pages outside a secure context: plain http off localhost), or no H.264 decoder.
 */
export async function h264Unsupported(env = globalThis, codec = H264_PROBE_CODEC) {
  if (typeof env.VideoDecoder !== 'function' || typeof env.EncodedVideoChunk !== 'function') {
    return env.isSecureContext === false
      ? 'this page is not a secure context (https or localhost), so the browser offers no WebCodecs video decoder'
      : 'this browser has no WebCodecs video decoder';
  }
  try {
    const { supported } = await env.VideoDecoder.isConfigSupported({ codec, optimizeForLatency: true });
    return supported ? '' : `this browser cannot decode H.264 (${codec})`;
  } catch (err) {
    return `this browser cannot decode H.264 (${codec}): ${err?.message ?? err}`;
  }
}

/** The decoder of one stream's VIDEO_H264 frames. */
export class VideoStream {
  /**
   * @param onFrame(videoFrame, meta, decodeMs)  a decoded frame; the callee owns it and must
   *        close() it. `meta` is what push() got with its chunk.
   * @param onKeyframeNeeded(reason)  the decoder needs a keyframe: ask the server for one.
   *        Called once per gap.
   * @param onUnsupported(reason)  this browser cannot decode the stream (a codec it refuses):
   *        the caller falls back to pictures.
   */
  constructor({
    onFrame, onKeyframeNeeded, onUnsupported = () => {},
    VideoDecoder = globalThis.VideoDecoder, EncodedVideoChunk = globalThis.EncodedVideoChunk,
    now = () => performance.now(),
  }) {
    this.onFrame = onFrame;
    this.onKeyframeNeeded = onKeyframeNeeded;
    this.onUnsupported = onUnsupported;
    this.VideoDecoder = VideoDecoder;
    this.EncodedVideoChunk = EncodedVideoChunk;
    this.now = now;
    this.decoder = null;
    this.config = null;       // {codec, codedWidth, codedHeight} the decoder has
    this.needKeyframe = true;  // nothing decodes until a keyframe
    this.asked = false;        // a keyframe was asked for since the decoder lost its place
    this.lastVideoSeq = null;
    this.nextTimestamp = 0;
    this.pending = new Map();  // chunk timestamp -> {meta, submitted}
    this.closed = false;
    this.keyframeRequests = 0;
    this.resets = 0;
    this.errorsSinceOutput = 0;  // decode errors with no picture between them
  }

  /**
   * Decodes one VIDEO_H264 frame: `frame` its FrameHeader, `videoSeq` the gateway's count
   * (undefined from a gateway that does not send it), `payload` the access unit (Annex B).
   */
  push(frame, videoSeq, payload, meta) {
    if (this.closed) return;
    const keyframe = frame.keyframe === true;
    const seq = Number.isSafeInteger(videoSeq) ? videoSeq : null;
    const previous = this.lastVideoSeq;
    this.lastVideoSeq = seq;
    if (!keyframe) {
      if (this.needKeyframe) {
        this.#askKeyframe('a frame that is not a keyframe came before any keyframe');
        return;
      }
      if (seq !== null && previous !== null && seq !== previous + 1) {
        this.#reset(`video frames are missing: frame ${seq} follows ${previous}`);
        return;
      }
    } else if (!this.#configure(frame)) {
      return;
    }
    const timestamp = this.nextTimestamp++;
    this.pending.set(timestamp, { meta, submitted: this.now() });
    try {
      this.decoder.decode(new this.EncodedVideoChunk({
        type: keyframe ? 'key' : 'delta', timestamp, data: payload,
      }));
    } catch (err) {
      this.#reset(`the decoder refused a frame: ${err?.message ?? err}`);
      return;
    }
    if (keyframe) {
      this.needKeyframe = false;
      this.asked = false;
    }
  }

  /** Frees the decoder; frames decoding now are dropped. */
  close() {
    this.closed = true;
    this.#dropDecoder();
  }

  /** A decoder configured for a keyframe: the same one unless its codec or size changed. */
  #configure(frame) {
    const codec = String(frame.codec ?? '');
    if (!AVC_CODEC.test(codec)) {
      // Another keyframe would name the same: not something a keyframe request mends.
      this.#dropDecoder();
      this.needKeyframe = true;
      this.onUnsupported(`the server named no H.264 codec (${JSON.stringify(codec.slice(0, 40))})`);
      return false;
    }
    const config = {
      codec,
      codedWidth: Number(frame.width) || undefined,
      codedHeight: Number(frame.height) || undefined,
      optimizeForLatency: true,  // one frame in, one out: no frames held back for reordering
    };
    const same = this.config && this.decoder?.state === 'configured' &&
      this.config.codec === config.codec && this.config.codedWidth === config.codedWidth &&
      this.config.codedHeight === config.codedHeight;
    if (same) return true;
    try {
      if (!this.decoder || this.decoder.state === 'closed') {
        this.decoder = new this.VideoDecoder({
          output: (videoFrame) => this.#output(videoFrame),
          error: (err) => this.#onError(err),
        });
      }
      // No description: the stream is Annex B, each keyframe carrying its SPS and PPS.
      this.decoder.configure(config);
      this.config = config;
      return true;
    } catch (err) {
      this.#dropDecoder();
      this.onUnsupported(`the video decoder refused ${codec}: ${err?.message ?? err}`);
      return false;
    }
  }

  #output(videoFrame) {
    this.errorsSinceOutput = 0;
    const entry = this.pending.get(videoFrame.timestamp);
    // Chunks before this one that gave no frame (the decoder may drop) are done with too.
    for (const t of this.pending.keys()) {
      if (t > videoFrame.timestamp) break;
      this.pending.delete(t);
    }
    if (!entry || this.closed) {
      videoFrame.close();
      return;
    }
    this.onFrame(videoFrame, entry.meta, this.now() - entry.submitted);
  }

  #onError(err) {
    // The decoder is closed now. A codec the browser cannot decode will not get better with a
    // keyframe; anything else (a corrupt or missing frame) does.
    this.decoder = null;
    this.config = null;
    if (this.closed) return;
    // So does a stream whose keyframes fail too, again and again: asking for more of them would
    // only load the server.
    if (err?.name === 'NotSupportedError' || ++this.errorsSinceOutput >= MAX_ERRORS_WITHOUT_OUTPUT) {
      this.#dropDecoder();
      this.needKeyframe = true;
      this.onUnsupported(`the video decoder cannot decode this stream: ${err?.message ?? err}`);
      return;
    }
    this.#reset(`decode error: ${err?.message ?? err}`);
  }

  /** Drops the decoder's state and waits for a keyframe (asking for one). */
  #reset(reason) {
    this.resets++;
    this.pending.clear();
    if (this.decoder?.state === 'configured') {
      try {
        this.decoder.reset();  // drops what is queued; the next keyframe configures it again
      } catch {
        this.decoder = null;
      }
    }
    this.config = null;
    this.needKeyframe = true;
    this.asked = false;
    this.#askKeyframe(reason);
  }

  #askKeyframe(reason) {
    this.needKeyframe = true;
    if (this.asked) return;
    this.asked = true;
    this.keyframeRequests++;
    this.onKeyframeNeeded(reason);
  }

  #dropDecoder() {
    this.pending.clear();
    if (this.decoder && this.decoder.state !== 'closed') {
      try {
        this.decoder.close();
      } catch {
        // closed already
      }
    }
    this.decoder = null;
    this.config = null;
  }
}

// VideoStream (public/video.js) with a fake WebCodecs decoder: what reaches the decoder, and when
// the page asks for a keyframe. The real decoder is exercised by tests/web/video.test.mjs.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { H264_PROBE_CODEC, VideoStream, h264Unsupported } from '../public/video.js';

class FakeDecoder {
  static made = [];
  constructor({ output, error }) {
    this.output = output;
    this.error = error;
    this.state = 'unconfigured';
    this.configs = [];
    this.chunks = [];
    FakeDecoder.made.push(this);
  }
  configure(config) {
    this.state = 'configured';
    this.configs.push(config);
  }
  decode(chunk) {
    if (this.state !== 'configured') throw new Error(`decode while ${this.state}`);
    this.chunks.push(chunk);
  }
  reset() {
    this.state = 'unconfigured';
  }
  close() {
    this.state = 'closed';
  }
  /** The decoder outputs the picture of its chunk `i`. */
  emit(i) {
    const frame = { timestamp: this.chunks[i].timestamp, closed: false, close() { this.closed = true; } };
    this.output(frame);
    return frame;
  }
  fail(name, message) {
    this.state = 'closed';
    this.error(Object.assign(new Error(message), { name }));
  }
}

class FakeChunk {
  constructor(init) {
    Object.assign(this, init);
  }
}

function setup() {
  FakeDecoder.made = [];
  let clock = 0;
  const got = { frames: [], asks: [], unsupported: [] };
  const stream = new VideoStream({
    VideoDecoder: FakeDecoder,
    EncodedVideoChunk: FakeChunk,
    now: () => clock,
    onFrame: (frame, meta, decodeMs) => got.frames.push({ frame, meta, decodeMs }),
    onKeyframeNeeded: (reason) => got.asks.push(reason),
    onUnsupported: (reason) => got.unsupported.push(reason),
  });
  return { stream, got, tick: (ms) => { clock += ms; }, decoder: () => FakeDecoder.made.at(-1) };
}

const key = (sequence, extra = {}) => ({ sequence, keyframe: true, codec: 'avc1.64000d', width: 320, height: 200, ...extra });
const delta = (sequence) => ({ sequence, keyframe: false, codec: 'avc1.64000d', width: 320, height: 200 });
const bytes = (n) => new Uint8Array([0, 0, 0, 1, n]);

test('a keyframe configures the decoder from its codec (Annex B: no description); frames decode in order', () => {
  const { stream, got, tick, decoder } = setup();
  stream.push(key(1), 1, bytes(1), 'm1');
  stream.push(delta(2), 2, bytes(2), 'm2');
  stream.push(delta(5), 3, bytes(3), 'm3');  // a sequence gap (tesserad replaced frames): fine
  const d = decoder();
  assert.deepEqual(d.configs, [{ codec: 'avc1.64000d', codedWidth: 320, codedHeight: 200, optimizeForLatency: true }]);
  assert.deepEqual(d.chunks.map((c) => [c.type, c.data[4]]), [['key', 1], ['delta', 2], ['delta', 3]]);
  tick(4);
  d.emit(0);
  d.emit(2);  // the decoder may skip one: its entry goes too
  assert.deepEqual(got.frames.map((f) => [f.meta, f.decodeMs]), [['m1', 4], ['m3', 4]]);
  assert.equal(stream.pending.size, 0);
  assert.deepEqual(got.asks, []);
  // The same codec and size at the next keyframe: the same decoder, not configured again.
  stream.push(key(6), 4, bytes(4));
  assert.equal(FakeDecoder.made.length, 1);
  assert.equal(d.configs.length, 1);
  stream.push(key(7, { width: 640, height: 400, codec: 'avc1.64001e' }), 5, bytes(5));
  assert.equal(d.configs.at(-1).codedWidth, 640);
  assert.equal(d.configs.at(-1).codec, 'avc1.64001e');
});

test('frames before any keyframe are dropped and one keyframe is asked for', () => {
  const { stream, got, decoder } = setup();
  stream.push(delta(1), 1, bytes(1));
  stream.push(delta(2), 2, bytes(2));
  assert.equal(got.asks.length, 1);
  assert.match(got.asks[0], /before any keyframe/);
  assert.equal(decoder(), undefined);
  stream.push(key(3), 3, bytes(3));
  stream.push(delta(4), 4, bytes(4));
  assert.deepEqual(decoder().chunks.map((c) => c.type), ['key', 'delta']);
  assert.equal(got.asks.length, 1);
});

test('a gap the gateway did not promise (a non-key frame after missing ones) resets and asks; a gap ending on a keyframe does not', () => {
  const { stream, got, decoder } = setup();
  stream.push(key(1), 1, bytes(1));
  stream.push(delta(2), 2, bytes(2));
  stream.push(key(9), 7, bytes(7));  // the gateway dropped 3..6 and said so: a keyframe follows
  assert.deepEqual(got.asks, []);
  stream.push(delta(10), 9, bytes(9));  // 8 is missing
  assert.equal(got.asks.length, 1);
  assert.match(got.asks[0], /frame 9 follows 7/);
  assert.equal(decoder().state, 'unconfigured', 'not reset');
  stream.push(delta(11), 10, bytes(10));  // consecutive again, but its references are gone
  assert.equal(got.asks.length, 1, 'asked twice for one gap');
  assert.equal(decoder().chunks.length, 3);
  stream.push(key(12), 11, bytes(11));
  stream.push(delta(13), 12, bytes(12));
  assert.equal(decoder().chunks.length, 5);
  assert.equal(stream.resets, 1);
  // Without video_seq (an older gateway) nothing is inferred from numbers.
  stream.push(delta(20), undefined, bytes(20));
  assert.equal(got.asks.length, 1);
});

test('a decode error asks for a keyframe and starts a new decoder; a codec the browser cannot decode falls back', () => {
  const { stream, got, decoder } = setup();
  stream.push(key(1), 1, bytes(1));
  const first = decoder();
  first.fail('EncodingError', 'corrupt slice');
  assert.equal(got.asks.length, 1);
  assert.match(got.asks[0], /decode error: corrupt slice/);
  stream.push(delta(2), 2, bytes(2));  // waits for the keyframe
  stream.push(key(3), 3, bytes(3));
  assert.equal(FakeDecoder.made.length, 2);
  assert.deepEqual(decoder().chunks.map((c) => c.type), ['key']);
  decoder().fail('NotSupportedError', 'no decoder for avc1.64000d');
  assert.equal(got.asks.length, 1, 'a keyframe does not help a codec the browser lacks');
  assert.match(got.unsupported[0], /no decoder for avc1\.64000d/);
});

test('a keyframe without a valid codec string never reaches configure: that is no H.264 this page can use', () => {
  const { stream, got, decoder } = setup();
  stream.push(key(1, { codec: 'vp09.00.10.08' }), 1, bytes(1));
  stream.push(key(2, { codec: 'avc1.64001f"><img' }), 2, bytes(2));
  assert.equal(decoder(), undefined);
  assert.deepEqual(got.asks, [], 'a keyframe request would bring the same codec string');
  assert.equal(got.unsupported.length, 2);
  assert.match(got.unsupported[0], /named no H\.264 codec \("vp09/);
  stream.push(key(3), 3, bytes(3));
  const d = decoder();
  const late = d.chunks.length;
  stream.close();
  assert.equal(d.state, 'closed');
  stream.push(key(4), 4, bytes(4));
  assert.equal(d.chunks.length, late);
  assert.equal(FakeDecoder.made.length, 1);
});

test('decode errors again and again, with no picture between: the page gives up rather than ask for keyframes forever', () => {
  const { stream, got, decoder } = setup();
  for (let i = 1; i <= 3; i++) {
    stream.push(key(i), i, bytes(i));
    decoder().fail('EncodingError', `bad ${i}`);
  }
  assert.equal(got.asks.length, 2);
  assert.deepEqual(got.unsupported.length, 1);
  assert.match(got.unsupported[0], /bad 3/);
  // A picture in between starts the count again.
  const other = setup();
  for (let i = 1; i <= 5; i++) {
    other.stream.push(key(i), i, bytes(i));
    other.decoder().emit(0);
    other.decoder().fail('EncodingError', `bad ${i}`);
  }
  assert.equal(other.got.asks.length, 5);
  assert.deepEqual(other.got.unsupported, []);
});

test('h264Unsupported says why H.264 cannot be used here, or nothing', async () => {
  assert.match(await h264Unsupported({ isSecureContext: false }), /not a secure context/);
  assert.match(await h264Unsupported({ isSecureContext: true }), /no WebCodecs video decoder/);
  const asked = [];
  const env = (supported) => ({
    EncodedVideoChunk: FakeChunk,
    VideoDecoder: Object.assign(function VideoDecoder() {}, {
      isConfigSupported: async (config) => {
        asked.push(config.codec);
        if (supported instanceof Error) throw supported;
        return { supported, config };
      },
    }),
  });
  assert.equal(await h264Unsupported(env(true)), '');
  assert.match(await h264Unsupported(env(false)), /cannot decode H\.264 \(avc1\.64001f\)/);
  assert.match(await h264Unsupported(env(new TypeError('bad config'))), /bad config/);
  assert.deepEqual(asked, [H264_PROBE_CODEC, H264_PROBE_CODEC, H264_PROBE_CODEC]);
});

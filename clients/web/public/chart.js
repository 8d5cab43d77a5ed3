// The live timing chart: per-pass GPU times of the last N frames as stacked bars, plus the
// small data models behind the stats (frame history, fps, bitrate, input-to-frame latency).
// The models are pure; TimingChart draws them on a <canvas> and fills a legend list.

/** Frames kept by the chart. */
export const HISTORY_FRAMES = 120;

// Distinct colours that read on a dark background; a pass keeps its colour for the page's
// life (assigned in the order passes are first seen, i.e. execution order).
const PALETTE = [
  '#4e9af1', '#f28e2b', '#59a14f', '#e15759', '#b07aa1', '#edc948',
  '#76b7b2', '#ff9da7', '#9c755f', '#bab0ac', '#86bc86', '#d4a6c8',
];

/** Median of an array of numbers, or null when empty. */
export function median(values) {
  if (values.length === 0) return null;
  const s = [...values].sort((a, b) => a - b);
  const mid = s.length >> 1;
  return s.length % 2 ? s[mid] : (s[mid - 1] + s[mid]) / 2;
}

/**
 * The last `capacity` frames as chart records:
 *   {sequence, event_id, passes: {name: gpu_ms}, gpu_total_ms, bytes, latency_ms}
 * and every pass name seen, in first-seen order, each with a stable colour.
 */
export class TimingHistory {
  constructor(capacity = HISTORY_FRAMES) {
    this.capacity = capacity;
    this.frames = [];
    this.passes = [];
    this.colors = new Map();
  }

  /** Adds a frame from its FrameHeader (and the latency measured for it, or null). */
  push(frame, latencyMs = null) {
    const passes = {};
    for (const p of frame.passes ?? []) {
      const name = String(p.pass ?? '');
      const ms = Number(p.gpu_ms);
      passes[name] = (passes[name] ?? 0) + (Number.isFinite(ms) && ms > 0 ? ms : 0);
      if (!this.colors.has(name)) {
        this.passes.push(name);
        const i = this.colors.size;
        // Past the palette, golden-angle hues stay apart from each other.
        this.colors.set(name, PALETTE[i] ?? `hsl(${(i * 137.5) % 360} 60% 62%)`);
      }
    }
    this.frames.push({
      sequence: Number(frame.sequence ?? 0),
      event_id: Number(frame.event_id ?? 0),
      passes,
      gpu_total_ms: Number(frame.gpu_total_ms ?? 0),
      bytes: Number(frame.bytes ?? 0),
      latency_ms: Number.isFinite(latencyMs) ? latencyMs : null,
    });
    if (this.frames.length > this.capacity) this.frames.splice(0, this.frames.length - this.capacity);
  }

  /** The tallest bar: the larger of a frame's pass sum and its gpu_total_ms. */
  maxStackMs() {
    let max = 0;
    for (const f of this.frames) {
      const sum = Object.values(f.passes).reduce((a, b) => a + b, 0);
      max = Math.max(max, sum, Number.isFinite(f.gpu_total_ms) ? f.gpu_total_ms : 0);
    }
    return max;
  }
}

/** Frames displayed per second over a sliding window (default 2 s). Times in ms. */
export class FpsMeter {
  constructor(windowMs = 2000) {
    this.windowMs = windowMs;
    this.times = [];
    this.last = 0;  // the newest non-zero rate: what the stream ran at before it went idle
  }

  tick(now) {
    this.times.push(now);
    this.#trim(now);
    const rate = this.fps(now);
    if (rate > 0) this.last = rate;
  }

  /** Frames per second at `now`; 0 when fewer than two frames are in the window. */
  fps(now) {
    this.#trim(now);
    if (this.times.length < 2) return 0;
    const span = now - this.times[0];
    return span > 0 ? (this.times.length - 1) / (span / 1000) : 0;
  }

  /**
   * The rate as the stats show it: "24.8" while frames come; "idle (last 24.8)" once they stop
   * (a resting camera gets no frames, which is not a frame rate of 0); "–" before any.
   */
  label(now) {
    const rate = this.fps(now);
    if (rate > 0) return rate.toFixed(1);
    return this.last > 0 ? `idle (last ${this.last.toFixed(1)})` : '–';
  }

  #trim(now) {
    while (this.times.length > 0 && this.times[0] < now - this.windowMs) this.times.shift();
  }
}

/** Bits per second as the stats show them: "3.52 Mbit/s" ("0.042 Mbit/s" below 0.1). */
export function formatBitrate(bitsPerSecond) {
  if (!Number.isFinite(bitsPerSecond) || bitsPerSecond < 0) return '–';
  const mbit = bitsPerSecond / 1e6;
  return `${mbit.toFixed(mbit > 0 && mbit < 0.1 ? 3 : 2)} Mbit/s`;
}

/**
 * The bitrate of the stream: bytes of frames received in a sliding window (default 2 s), per
 * second, in bits. Times in ms.
 */
export class BitrateMeter {
  constructor(windowMs = 2000) {
    this.windowMs = windowMs;
    this.samples = [];  // [time, bytes]
    this.last = 0;      // the rate when the newest frame came: what it ran at before going idle
  }

  add(now, bytes) {
    const n = Number(bytes);
    this.samples.push([now, Number.isFinite(n) && n > 0 ? n : 0]);
    this.last = this.bitsPerSecond(now);
  }

  /** Bits per second over the window ending at `now`; 0 when no frame came in it. */
  bitsPerSecond(now) {
    while (this.samples.length > 0 && this.samples[0][0] <= now - this.windowMs) this.samples.shift();
    const bytes = this.samples.reduce((sum, [, b]) => sum + b, 0);
    return (bytes * 8) / (this.windowMs / 1000);
  }

  /** "3.52 Mbit/s" while frames come; "idle (last 3.52 Mbit/s)" once they stop; "–" before any. */
  label(now) {
    const rate = this.bitsPerSecond(now);
    if (rate > 0) return formatBitrate(rate);
    return this.last > 0 ? `idle (last ${formatBitrate(this.last)})` : '–';
  }
}

/**
 * Input-to-frame latency. sent(id, t) remembers when each event left; frameArrived(eventId, t)
 * takes the newest pending event the frame reflects (id <= eventId), records t minus its send
 * time and forgets every event up to it (older ones were superseded, not rendered alone).
 */
export class LatencyTracker {
  constructor(samples = 30) {
    this.samples = samples;
    this.pending = new Map();  // event id -> send time, ids increasing
    this.recent = [];
  }

  sent(id, now) {
    this.pending.set(id, now);
    // A session that never answers must not grow this forever.
    if (this.pending.size > 1000) this.pending.delete(this.pending.keys().next().value);
  }

  /** The latency for a frame reflecting event `eventId` (ms), or null when none was pending. */
  frameArrived(eventId, now) {
    let match = null;
    for (const [id, t] of this.pending) {
      if (id > eventId) break;
      match = t;
      this.pending.delete(id);
    }
    if (match === null) return null;
    const latency = now - match;
    this.recent.push(latency);
    if (this.recent.length > this.samples) this.recent.shift();
    return latency;
  }

  /** Forget events that will not get a frame (the stream they went to ended). */
  reset() {
    this.pending.clear();
  }

  /** Median of the last `samples` latencies, or null. */
  median() {
    return median(this.recent);
  }
}

/** The smallest of 1, 2, 5 x 10^k that is >= v (an axis maximum that reads well). */
export function niceCeil(v) {
  if (!(v > 0) || !Number.isFinite(v)) return 1;
  const p = 10 ** Math.floor(Math.log10(v));
  for (const m of [1, 2, 5, 10]) if (m * p >= v) return m * p;
  return 10 * p;
}

/**
 * Grid lines for an axis from 0 to `max` (a niceCeil value): 5 steps for 5 x 10^k, else 4, so
 * every line is a round number (0, 10, 20, ... 50 rather than 0, 12.5, 25, ... 50).
 */
export function gridSteps(max) {
  const lead = max / 10 ** Math.floor(Math.log10(max));
  return Math.abs(lead - 5) < 1e-9 ? 5 : 4;
}

/** Draws a TimingHistory on a canvas and keeps a legend <ul> in step. */
export class TimingChart {
  constructor(canvas, legend, history) {
    this.canvas = canvas;
    this.legend = legend;
    this.history = history;
    this.legendKey = null;
    this.values = new Map();  // pass name -> its legend value <span>
  }

  /** Redraws everything (cheap: N bars). */
  draw() {
    this.#updateLegend();
    const { canvas, history } = this;
    const dpr = globalThis.devicePixelRatio || 1;
    const cssW = canvas.clientWidth || 300;
    const cssH = canvas.clientHeight || 150;
    const w = Math.round(cssW * dpr);
    const h = Math.round(cssH * dpr);
    if (canvas.width !== w || canvas.height !== h) {
      canvas.width = w;
      canvas.height = h;
    }
    const ctx = canvas.getContext('2d');
    if (!ctx) return;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, cssW, cssH);

    const left = 38;
    const right = 6;
    const top = 8;
    const bottom = 16;
    const plotW = Math.max(1, cssW - left - right);
    const plotH = Math.max(1, cssH - top - bottom);
    const yMax = niceCeil(history.maxStackMs());
    const y = (ms) => top + plotH - (ms / yMax) * plotH;

    // Grid lines and the ms scale.
    ctx.font = '10px system-ui, sans-serif';
    ctx.textAlign = 'right';
    ctx.textBaseline = 'middle';
    const steps = gridSteps(yMax);
    for (let i = 0; i <= steps; i++) {
      const ms = (yMax * i) / steps;
      const yy = Math.round(y(ms)) + 0.5;
      ctx.strokeStyle = i === 0 ? '#5a6270' : '#2c323c';
      ctx.beginPath();
      ctx.moveTo(left, yy);
      ctx.lineTo(left + plotW, yy);
      ctx.stroke();
      ctx.fillStyle = '#9aa3b2';
      ctx.fillText(formatMs(ms), left - 4, yy);
    }
    ctx.textAlign = 'left';
    ctx.textBaseline = 'alphabetic';
    ctx.fillText('ms', 2, cssH - 4);
    ctx.textAlign = 'right';
    ctx.fillText(`last ${history.capacity} frames`, left + plotW, cssH - 3);

    // Bars, newest at the right; passes stacked in execution order.
    const slot = plotW / history.capacity;
    const barW = Math.max(1, slot - (slot > 3 ? 1 : 0));
    const offset = history.capacity - history.frames.length;
    history.frames.forEach((frame, i) => {
      const x = left + (offset + i) * slot;
      let base = 0;
      for (const name of history.passes) {
        const ms = frame.passes[name];
        if (!ms) continue;
        ctx.fillStyle = history.colors.get(name);
        ctx.fillRect(x, y(base + ms), barW, y(base) - y(base + ms));
        base += ms;
      }
    });
  }

  // One <li> per pass (swatch, name, the newest frame's ms); rebuilt when the set changes.
  #updateLegend() {
    if (!this.legend) return;
    const { passes, colors, frames } = this.history;
    const key = passes.join('\n');
    if (key !== this.legendKey) {
      this.legendKey = key;
      const doc = this.legend.ownerDocument;
      this.values = new Map();
      this.legend.replaceChildren(...passes.map((name) => {
        const li = doc.createElement('li');
        const swatch = doc.createElement('span');
        swatch.className = 'swatch';
        swatch.style.background = colors.get(name);
        const value = doc.createElement('span');
        value.className = 'value';
        this.values.set(name, value);
        li.append(swatch, doc.createTextNode(name), value);
        return li;
      }));
    }
    const last = frames[frames.length - 1];
    for (const [name, span] of this.values) {
      const ms = last?.passes[name];
      span.textContent = ms === undefined ? '' : `${formatMs(ms)} ms`;
    }
  }
}

/** Milliseconds for an axis or a stat: 3 significant figures, no trailing noise. */
export function formatMs(ms) {
  if (!Number.isFinite(ms)) return '–';
  if (ms === 0) return '0';
  if (ms < 1) return ms.toFixed(2);
  if (ms < 10) return ms.toFixed(1);
  return ms.toFixed(0);
}

const count = (n) => (Number.isFinite(Number(n)) ? Number(n).toLocaleString('en-US') : '–');

/** The rows of statsRows the overlay always shows; the others fold away under "More". */
// (Each row more moves "More", which takes clicks, down over the picture's centre, where a
// drag should orbit: the decode time is folded away.)
export const MAIN_STATS = new Set([
  'fps', 'latency (median)', 'bitrate', 'codec', 'frame size', 'resolution', 'GPU total',
]);

/**
 * How a frame is coded, as the stats show it: "jpeg", "png", or for video the codec string and
 * the encoder, "h264 avc1.64001f (libx264)".
 */
export function codecLabel(frame) {
  if (frame.encoding === 'VIDEO_H264') {
    const encoder = frame.encoder ? ` (${frame.encoder})` : '';
    return `h264 ${frame.codec || '?'}${encoder}`;
  }
  return frame.encoding === 'IMAGE_PNG' ? 'png' : 'jpeg';
}

/**
 * The text stats of the frame shown, as [label, value] rows: fps, input-to-frame latency,
 * bitrate (a label from BitrateMeter), codec, decode time (the page's: payload in, picture
 * out), size, resolution, profile, GPU time and the frame's draw stats.
 */
export function statsRows(frame, { fps = 0, latencyMs = null, bitrate = '–', decodeMs = null } = {}) {
  const rows = [
    ['fps', typeof fps === 'string' ? fps : fps.toFixed(1)],
    ['latency (median)', latencyMs === null ? '–' : `${formatMs(latencyMs)} ms`],
    ['bitrate', bitrate],
  ];
  if (!frame) return rows;
  const bytes = Number(frame.bytes ?? 0);
  const size = (w, h) => `${w ?? '?'} × ${h ?? '?'}`;
  const shown = size(frame.width, frame.height);
  const rendered = size(frame.render_width ?? frame.width, frame.render_height ?? frame.height);
  const stats = frame.stats ?? {};
  const wallClock =
    frame.timing_source === 'TIMING_PASS_WALL_CLOCK' ? ' (wall clock)'
    : frame.timing_source === 'TIMING_FRAME_WALL_CLOCK' ? ' (wall clock, one submission)'
    : '';
  rows.push(
    ['codec', codecLabel(frame)],
    ['decode', Number.isFinite(decodeMs) ? `${formatMs(decodeMs)} ms` : '–'],
    ['frame size', `${(bytes / 1024).toFixed(1)} KB (${count(bytes)} bytes)`],
    ['resolution', rendered === shown ? shown : `${rendered} → ${shown}`],
    ['profile', frame.profile || 'full'],
    ['GPU total', `${formatMs(Number(frame.gpu_total_ms ?? 0))} ms${wallClock}`],
    ['CPU total', `${formatMs(Number(frame.cpu?.total_ms ?? 0))} ms`],
    ['triangles', count(stats.triangles_submitted ?? 0)],
    ['draws', count(stats.draws ?? 0)],
    ['drawn / drawables', `${count(stats.drawables_drawn ?? 0)} / ${count(stats.drawables ?? 0)}`],
    ['lights', `${count(stats.lights ?? 0)} (${count(stats.local_lights ?? 0)} local)`],
    ['frame', `#${frame.sequence ?? 0}, event ${frame.event_id ?? 0}`],
  );
  return rows;
}

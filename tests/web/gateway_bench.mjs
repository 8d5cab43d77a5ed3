#!/usr/bin/env node
// What the web gateway adds to a frame's input-to-frame latency: the same camera orbit streamed
// from one tesserad directly over gRPC (grpc-js, as the gateway itself talks to it) and through
// the gateway's WebSocket, one event per received frame, in alternating blocks so both see the
// same machine load. Prints JSON: per size and path, latency p50/p95 and frames/s; the
// gateway's added p50 in ms and as a ratio.
//   node tests/web/gateway_bench.mjs [--frames N] [--blocks B] [--sizes 320x180,1280x720] [--smoke]
import path from 'node:path';
import { PageClient, WEB_DIR, startGateway, startTesserad } from '../../clients/web/test/harness.js';
import { loadProto, makeClient, callMetadata } from '../../clients/web/lib/rpc.js';


function parseArgs(argv) {
  const o = { frames: 100, blocks: 4, sizes: ['320x180', '1280x720'], smoke: false };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--smoke') Object.assign(o, { smoke: true, frames: 5, blocks: 1, sizes: ['64x48'] });
    else if (a === '--frames') o.frames = Number(argv[++i]);
    else if (a === '--blocks') o.blocks = Number(argv[++i]);
    else if (a === '--sizes') o.sizes = argv[++i].split(',');
    else { console.error(`unknown argument ${a}`); process.exit(2); }
  }
  if (!(o.frames > 0 && o.blocks > 0)) { console.error('--frames and --blocks want positive numbers'); process.exit(2); }
  return o;
}

const quantile = (xs, q) => {
  const s = [...xs].sort((a, b) => a - b);
  return s.length ? s[Math.min(s.length - 1, Math.floor(q * s.length))] : null;
};
const round = (x, d = 2) => (x === null ? null : Number(x.toFixed(d)));

function orbitCamera(i) {
  const a = i * 0.05;
  return { look_at: { eye: { x: 12 * Math.cos(a), y: 8, z: 12 * Math.sin(a) }, target: { x: 0, y: 0.5, z: 0 } } };
}

/** Streams `frames` orbit steps directly over gRPC; returns latencies (ms) and wall time. */
async function directBlock(client, settings, frames, firstId) {
  const call = client.Stream(callMetadata({}));
  const latencies = [];
  let resolveFrame;
  call.on('data', (f) => resolveFrame?.(f));
  call.on('error', () => {});
  const next = (id) => new Promise((resolve) => {
    resolveFrame = (f) => { if (f.event_id >= id) resolve(f); };
  });
  let wait = next(0);
  call.write({ open: { scene_id: 'demo', settings, camera: orbitCamera(firstId) } });
  await wait;
  const start = performance.now();
  for (let i = 1; i <= frames; i++) {
    const id = firstId + i;
    wait = next(id);
    const sent = performance.now();
    call.write({ event_id: id, camera: orbitCamera(id) });
    await wait;
    latencies.push(performance.now() - sent);
  }
  const wall = performance.now() - start;
  call.end();
  return { latencies, wall };
}

/** The same through the gateway's WebSocket. */
async function gatewayBlock(wsUrl, settings, frames, firstId) {
  const page = await PageClient.connect(wsUrl);
  const opened = await page.request('open', { open: { scene_id: 'demo', settings, camera: orbitCamera(firstId) } });
  const sid = opened.result.stream;
  await page.waitFor(() => page.frames.length > 0, 'first frame');
  const latencies = [];
  const start = performance.now();
  for (let i = 1; i <= frames; i++) {
    const id = firstId + i;
    const sent = performance.now();
    page.ws.send(JSON.stringify({ id: 1000 + i, op: 'event', stream: sid, event: { event_id: id, camera: orbitCamera(id) } }));
    await page.waitFor(() => page.frames.at(-1)?.header.frame.event_id >= id, `frame ${id}`);
    latencies.push(performance.now() - sent);
    page.frames.length = 0; // keep memory flat; only the newest matters
  }
  const wall = performance.now() - start;
  page.close();
  return { latencies, wall };
}

const opts = parseArgs(process.argv.slice(2));
// Uncapped session rate (the default caps a session at 60 fps, which would hide the difference).
const tesserad = await startTesserad(['--max_session_fps=1000']);
const gateway = await startGateway(tesserad.address);
const { api } = loadProto(path.resolve(WEB_DIR, '../../proto'));
const client = makeClient(api, tesserad.address, {});
const results = [];
try {
  for (const size of opts.sizes) {
    const [width, height] = size.split('x').map(Number);
    const settings = { width, height };
    const acc = { direct: { lat: [], wall: 0, n: 0 }, gateway: { lat: [], wall: 0, n: 0 } };
    let id = 1;
    for (let b = 0; b < opts.blocks; b++) {
      // Alternate which path goes first, so neither always runs on a warmer machine.
      const order = b % 2 === 0 ? ['direct', 'gateway'] : ['gateway', 'direct'];
      for (const which of order) {
        const r = which === 'direct'
          ? await directBlock(client, settings, opts.frames, id)
          : await gatewayBlock(gateway.wsUrl, settings, opts.frames, id);
        id += opts.frames + 1;
        acc[which].lat.push(...r.latencies);
        acc[which].wall += r.wall;
        acc[which].n += r.latencies.length;
      }
    }
    const summary = (a) => ({
      frames: a.n,
      latency_ms_p50: round(quantile(a.lat, 0.5)),
      latency_ms_p95: round(quantile(a.lat, 0.95)),
      fps: round((1000 * a.n) / a.wall, 1),
    });
    const direct = summary(acc.direct), viaGateway = summary(acc.gateway);
    results.push({
      size,
      direct,
      gateway: viaGateway,
      added_latency_ms_p50: round(viaGateway.latency_ms_p50 - direct.latency_ms_p50),
      latency_ratio_p50: round(viaGateway.latency_ms_p50 / direct.latency_ms_p50, 3),
    });
  }
} finally {
  client.close();
  await gateway.stop();
  await tesserad.stop();
}
console.log(JSON.stringify({
  benchmark: 'web_gateway_latency',
  method: 'one camera event per received frame (orbit), demo scene, alternating blocks direct/gateway; medians over all frames',
  frames_per_block: opts.frames,
  blocks: opts.blocks,
  results,
}, null, 2));

#!/usr/bin/env node
// tessera-web: serves the browser viewer and bridges each page's WebSocket to tesserad's gRPC
// API. Flags and the protocol: README.md.
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { WebSocketServer } from 'ws';
import { loadProto, makeClient, callMetadata } from './lib/rpc.js';
import { ReplicaSet, parseServers } from './lib/replicas.js';
import { Connection, UploadBudget } from './lib/connection.js';
import { ParkedStreams } from './lib/streams.js';
import { loadStatic, serveStatic } from './lib/static.js';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const VERSION = JSON.parse(fs.readFileSync(path.join(HERE, 'package.json'), 'utf8')).version;

const USAGE = `usage: node gateway.js [flags]
  --listen HOST:PORT    where the page is served (default $TESSERA_WEB_LISTEN, else 127.0.0.1:8080;
                        port 0 picks a free one)
  --server LIST         tesserad (default $TESSERA_SERVER, else 127.0.0.1:50051): HOST:PORT, or
                        replicas: a comma-separated list of HOST:PORT and dns:///HOST:PORT
                        entries (dns:///: every A/AAAA record of the name is a replica, e.g. a
                        Kubernetes headless Service). Each new session goes to the ready replica
                        with the fewest sessions; when a replica is lost its sessions move.
  --refresh-s N         how often dns:/// names are resolved again, seconds (default 5)
  --token-file FILE     bearer token for tesserad, first line of FILE (or $TESSERA_TOKEN)
  --tls                 talk TLS to tesserad, trusting the system's CAs
  --tls-ca FILE         talk TLS to tesserad, trusting the CA certificate(s) in FILE
  --allow-origin URL    also accept pages from this origin (repeatable; the gateway's own
                        origin is always accepted)
  --allow-host NAME     also answer requests for this host name (repeatable); when listening on
                        loopback, only loopback names are answered otherwise (DNS rebinding)
  --max-upload-mb N     MiB one upload may hold in the gateway (default 512, or tesserad's
                        limit when lower)
  --upload-budget-mb N  MiB all uploads may hold in the gateway together (default 1024)
  --port-file FILE      write the bound port to FILE once listening
  --proto-dir DIR       the proto files (default ../../proto from this file)
  --public-dir DIR      the page's files (default public/ next to this file)
  -h, --help            this text
`;

function usageError(message) {
  process.stderr.write(`tessera-web: ${message}\n${USAGE}`);
  process.exit(2);
}

function parseFlags(argv) {
  const o = {
    listen: process.env.TESSERA_WEB_LISTEN || '127.0.0.1:8080',
    server: process.env.TESSERA_SERVER || '127.0.0.1:50051',
    refreshS: 5,
    token: (process.env.TESSERA_TOKEN || '').trim(),
    tls: false,
    tlsCaFile: '',
    allowOrigins: [],
    allowHosts: [],
    maxUploadMb: 512,
    uploadBudgetMb: 1024,
    portFile: '',
    protoDir: path.resolve(HERE, '../../proto'),
    publicDir: path.join(HERE, 'public'),
  };
  for (let i = 0; i < argv.length; i++) {
    const arg = argv[i];
    const [flag, inline] = arg.includes('=') ? [arg.slice(0, arg.indexOf('=')), arg.slice(arg.indexOf('=') + 1)] : [arg, undefined];
    const value = () => {
      if (inline !== undefined) return inline;
      if (i + 1 >= argv.length) usageError(`${flag} needs a value`);
      return argv[++i];
    };
    switch (flag) {
      case '--listen': o.listen = value(); break;
      case '--server': o.server = value(); break;
      case '--refresh-s': {
        const v = value();
        o.refreshS = Number(v);
        if (!(o.refreshS > 0)) usageError(`--refresh-s: not a positive number: '${v}'`);
        break;
      }
      case '--token-file': {
        const file = value();
        try {
          o.token = fs.readFileSync(file, 'utf8').split('\n')[0].trim();
        } catch (e) {
          usageError(`--token-file: cannot read ${file}: ${e.code ?? e.message}`);
        }
        if (!o.token) usageError(`--token-file: ${file} is empty`);
        break;
      }
      case '--tls': o.tls = true; break;
      case '--tls-ca': o.tlsCaFile = value(); o.tls = true; break;
      case '--allow-origin': o.allowOrigins.push(value().replace(/\/$/, '')); break;
      case '--allow-host': o.allowHosts.push(value().toLowerCase()); break;
      case '--max-upload-mb':
      case '--upload-budget-mb': {
        const v = value();
        const n = Number(v);
        if (!(n > 0)) usageError(`${flag}: not a positive number: '${v}'`);
        if (flag === '--max-upload-mb') o.maxUploadMb = n;
        else o.uploadBudgetMb = n;
        break;
      }
      case '--port-file': o.portFile = value(); break;
      case '--proto-dir': o.protoDir = path.resolve(value()); break;
      case '--public-dir': o.publicDir = path.resolve(value()); break;
      case '-h': case '--help': process.stdout.write(USAGE); process.exit(0); break;
      default: usageError(`unknown flag '${arg}'`);
    }
  }
  const m = /^(.*):(\d+)$/.exec(o.listen);
  if (!m || Number(m[2]) > 65535) usageError(`--listen: wants HOST:PORT, not '${o.listen}'`);
  o.host = m[1].replace(/^\[(.*)\]$/, '$1');
  o.port = Number(m[2]);
  try {
    parseServers(o.server);
  } catch (e) {
    usageError(e.message);
  }
  return o;
}

function log(message) {
  process.stderr.write(`${new Date().toISOString()} tessera-web: ${message}\n`);
}

const opts = parseFlags(process.argv.slice(2));
let proto, files;
try {
  proto = loadProto(opts.protoDir);
  files = loadStatic(opts.publicDir);
} catch (e) {
  usageError(e.message);
}
const metadata = () => callMetadata(opts);
// The replicas (one for a plain HOST:PORT): a client each, polled for their load and health.
// A replica reached by its IP under a DNS name keeps that name for TLS and as its authority.
const replicas = new ReplicaSet({
  spec: opts.server,
  makeClient: (address, { authority }) => makeClient(proto.api, address, opts, {
    // A replica that comes back is seen within seconds, not after grpc-js's 2-minute backoff.
    'grpc.max_reconnect_backoff_ms': 5000,
    ...(authority ? { 'grpc.default_authority': authority, 'grpc.ssl_target_name_override': authority.replace(/:\d+$/, '').replace(/^\[(.*)\]$/, '$1') } : {}),
  }),
  metadata,
  log,
  refreshMs: opts.refreshS * 1000,
});
// A replica that stops answering, or answers not serving: its sessions move to others.
replicas.on('lost', (replica, why) => {
  log(`replica ${replica.address} lost: ${why}; moving its ${replica.streams.size} sessions`);
  for (const stream of [...replica.streams]) stream.replicaLost(replica, why);
});
replicas.start().catch((e) => log(`replicas: ${e.stack ?? e}`));

// tesserad's limits, as the replicas last reported them (or asked when an upload needs them
// before any replica answered), kept for a minute.
let limitsCache = { at: 0, value: null };
async function limits() {
  const known = replicas.anyInfo();
  if (known) {
    limitsCache = { at: Date.now(), value: known.limits ?? {} };
    return limitsCache.value;
  }
  if (limitsCache.value && Date.now() - limitsCache.at < 60_000) return limitsCache.value;
  const replica = await replicas.pickUnary();
  return new Promise((resolve, reject) => {
    replica.client.GetServerInfo({}, metadata(), { deadline: Date.now() + 10_000 }, (err, info) => {
      if (err) return reject(err);
      limitsCache = { at: Date.now(), value: info.limits ?? {} };
      resolve(limitsCache.value);
    });
  });
}

// What uploads may hold in the gateway: one upload, and all of them together.
const maxUploadBytes = opts.maxUploadMb * 1024 * 1024;
const uploadBudget = new UploadBudget(Math.max(opts.uploadBudgetMb, opts.maxUploadMb) * 1024 * 1024);

// Sessions of pages that left, kept as long as tesserad would keep them (resume_grace_s).
// At most a quarter of the replicas' sessions wait here for pages to come back, so parked
// sessions never crowd out live ones.
const parked = new ParkedStreams({
  graceMs: () => 1000 * (limitsCache.value?.resume_grace_s ?? 30),
  max: () => {
    const known = replicas.replicas.filter((r) => r.ok && r.maxSessions > 0);
    const total = known.length ? known.reduce((n, r) => n + r.maxSessions, 0) : (limitsCache.value?.max_sessions || 64);
    return Math.max(1, Math.floor(total / 4));
  },
  log,
});
limits().catch(() => {}); // learn resume_grace_s early; errors show up where they matter

// 200 when a tesserad answers: the one server (asked now), or any replica (as last polled);
// the body lists the replicas and why those that take no sessions do not.
function healthz(res) {
  const send = (ok, body) => {
    res.writeHead(ok ? 200 : 503, { 'Content-Type': 'application/json', 'Cache-Control': 'no-store' });
    res.end(`${JSON.stringify({ ok, server: opts.server, ...body, replicas: replicas.replicas.map((r) => r.summary()) })}\n`);
  };
  if (!replicas.single) {
    const info = replicas.anyInfo();
    const ready = replicas.replicas.filter((r) => r.listed && r.ready).length;
    if (info) send(true, { version: info.version, device: info.device?.name, ready });
    else send(false, { error: replicas.unavailable('no tesserad replica answers').message, ready });
    return;
  }
  const [only] = replicas.replicas;
  only.client.GetServerInfo({}, metadata(), { deadline: Date.now() + 3000 }, (err, info) => {
    if (err) send(false, { error: err.details ?? err.message });
    else send(true, { version: info.version, device: info.device?.name });
  });
}

// DNS rebinding: a site can make its own name resolve to 127.0.0.1 and then talk to a gateway
// on loopback as "same origin". On loopback, only requests for loopback names are answered.
const LOOPBACK_NAMES = ['localhost', '127.0.0.1', '[::1]', '::1'];
const loopbackListen = ['localhost', '::1'].includes(opts.host) || opts.host.startsWith('127.');
function hostAllowed(req) {
  const host = String(req.headers.host ?? '').toLowerCase();
  const name = host.startsWith('[') ? host.slice(0, host.indexOf(']') + 1) : host.replace(/:\d+$/, '');
  if (opts.allowHosts.includes(name)) return true;
  if (!loopbackListen) return opts.allowHosts.length === 0;
  return LOOPBACK_NAMES.includes(name) || name === opts.host.toLowerCase();
}

const server = http.createServer((req, res) => {
  try {
    if (!hostAllowed(req)) {
      res.writeHead(421, { 'Content-Type': 'text/plain' }).end('host not served here\n');
      return;
    }
    let pathname;
    try {
      pathname = new URL(req.url, 'http://x').pathname;
    } catch {
      res.writeHead(400, { 'Content-Type': 'text/plain' }).end('bad request target\n');
      return;
    }
    if (pathname === '/healthz') return healthz(res);
    if (!serveStatic(files, pathname, req, res)) res.writeHead(404, { 'Content-Type': 'text/plain' }).end('not found\n');
  } catch (err) {
    log(`HTTP request failed: ${err.stack ?? err}`);
    if (!res.headersSent) res.writeHead(500).end();
  }
});

// A page from another site must not drive tesserad through a viewer's browser: WebSockets are
// not bound by the same-origin policy, so the Origin header is checked. Clients that are not
// browsers send none.
function originAllowed(req) {
  const origin = req.headers.origin;
  if (origin === undefined) return true;
  try {
    const url = new URL(origin);
    if (url.host === req.headers.host) return true;
  } catch {
    return false;
  }
  return opts.allowOrigins.includes(origin);
}

const wss = new WebSocketServer({
  server,
  path: '/ws',
  maxPayload: 2 * 1024 * 1024, // an upload chunk (<= 1 MiB) and its header
  verifyClient: ({ req }, done) => {
    if (!hostAllowed(req)) return done(false, 421, 'host not served here');
    if (originAllowed(req)) return done(true);
    log(`refused a WebSocket from origin ${req.headers.origin}`);
    done(false, 403, 'origin not allowed');
  },
});

wss.on('error', () => {}); // listen errors are reported by the HTTP server's handler

let pages = 0;
let stopping = false;
wss.on('connection', (ws, req) => {
  pages++;
  const peer = `${req.socket.remoteAddress}:${req.socket.remotePort}`;
  log(`page connected from ${peer} (${pages} open)`);
  ws.isAlive = true;
  ws.on('pong', () => { ws.isAlive = true; });
  ws.on('close', () => { pages--; log(`page ${peer} left (${pages} open)`); });
  new Connection(ws, {
    replicas, definition: proto.definition, metadata, limits,
    maxUploadBytes, parked, uploadBudget, stopping: () => stopping,
    log, version: VERSION, server: opts.server, peer,
  });
});

// Pages that vanished without closing (a sleeping laptop) are dropped after a missed ping.
const pinger = setInterval(() => {
  for (const ws of wss.clients) {
    if (!ws.isAlive) { ws.terminate(); continue; }
    ws.isAlive = false;
    ws.ping();
  }
}, 30_000);

server.on('error', (err) => {
  log(`cannot listen on ${opts.listen}: ${err.message}`);
  process.exit(1);
});
server.listen(opts.port, opts.host, () => {
  const { port } = server.address();
  if (opts.portFile) fs.writeFileSync(opts.portFile, `${port}\n`);
  const shown = opts.host.includes(':') ? `[${opts.host}]` : opts.host;
  const what = replicas.single ? `tesserad at ${opts.server}` : `the tesserad replicas ${opts.server}`;
  log(`serving the viewer on http://${shown}:${port}/ for ${what}`);
});

// On SIGTERM (a rolling restart) the gRPC calls are not ended: the process exits, its
// connection to tesserad drops, and tesserad parks every session, so the pages resume them
// through another gateway. Ending them would read to tesserad as a clean end.
function shutdown(signal) {
  if (stopping) return;
  stopping = true;
  log(`${signal}: closing (sessions stay with tesserad for their resume grace period)`);
  clearInterval(pinger);
  for (const ws of wss.clients) ws.close(1001, 'gateway shutting down');
  wss.close();
  server.close();
  setTimeout(() => process.exit(0), 300);
}
process.on('SIGINT', () => shutdown('SIGINT'));
process.on('SIGTERM', () => shutdown('SIGTERM'));

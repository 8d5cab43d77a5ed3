// The tesserad replicas the gateway serves pages from (--server LIST), how busy each is, where a
// new session goes, and which replica a resume token names.
//
// --server is a comma-separated list of HOST:PORT and dns:///HOST:PORT entries. A HOST:PORT is one
// replica (grpc-js resolves the name itself: a Kubernetes ClusterIP Service is one replica to
// the gateway). dns:///HOST:PORT is a headless Service: every A/AAAA record is a replica,
// re-resolved every --refresh-s. A single HOST:PORT behaves as a gateway with one tesserad always
// did: every call goes to it, whatever it reports.
//
// Each replica has its own gRPC client and is asked GetServerInfo every POLL_MS (a short
// deadline). It is ready when it answered, is serving and takes new sessions
// (ServerInfo.accepting_sessions). A new Stream session goes to the ready replica with the fewest
// sessions: active_sessions plus those this gateway placed there since the poll that counted
// them (a burst of opens does not all land on one); ties take turns. When the replicas do not
// share a scene store (ServerInfo.scene_store), replicas that have the scene (HasScene) come first.
//
// A replica that leaves DNS (Kubernetes takes a full or unready pod out of a headless Service)
// gets no new sessions, but keeps its client and its sessions; resume tokens may still name it
// for FORGET_MS (unpolled). The page is untrusted: a token is only ever routed to a replica in
// this set.
import dns from 'node:dns';
import { EventEmitter } from 'node:events';
import { GatewayError } from './rpc.js';

export const POLL_MS = 2000;
export const POLL_TIMEOUT_MS = 1500;
export const REFRESH_MS = 5000;
// A replica out of DNS and holding none of this gateway's sessions is forgotten after this long
// (and not polled meanwhile): Kubernetes may give its address to another pod, which must get
// neither the gateway's token nor pages' resume tokens. One with sessions stays known.
export const FORGET_MS = 60_000;
// Failed polls in a row before a replica counts as lost (its sessions move). One failed poll
// already keeps new sessions away.
export const DOWN_AFTER_FAILURES = 2;
// Placements younger than this when a poll was sent are still counted on top of its answer (the
// session may not have reached the replica yet).
const PLACEMENT_SLACK_MS = 250;
const HAS_SCENE_TIMEOUT_MS = 1500;
const MAX_TOKEN_CHARS = 1024;

const HOST_PORT = /^(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(\d{1,5})$/;

/**
 * The entries of --server: [{kind: 'static', address}] or [{kind: 'dns', host, port, name}].
 * Throws an Error naming the entry that is not HOST:PORT or dns:///HOST:PORT.
 */
export function parseServers(spec) {
  const entries = String(spec ?? '').split(',').map((s) => s.trim()).filter(Boolean);
  if (entries.length === 0) throw new Error('--server: wants HOST:PORT[,HOST:PORT...] or dns:///HOST:PORT');
  const seen = new Set();
  return entries.map((entry) => {
    const dnsEntry = entry.startsWith('dns:///');
    const target = dnsEntry ? entry.slice('dns:///'.length) : entry;
    const m = HOST_PORT.exec(target);
    // One server may be any gRPC target, as before replicas (e.g. unix:/run/tesserad.sock).
    if (!dnsEntry && entries.length === 1 && !m && /^[\x21-\x7e]+$/.test(target)) return { kind: 'static', address: target };
    if (!m || Number(m[2]) < 1 || Number(m[2]) > 65535) {
      throw new Error(`--server: '${entry}' is not HOST:PORT or dns:///HOST:PORT`);
    }
    if (seen.has(entry)) throw new Error(`--server: '${entry}' appears twice`);
    seen.add(entry);
    if (!dnsEntry) return { kind: 'static', address: target };
    return { kind: 'dns', host: m[1].replace(/^\[(.*)\]$/, '$1'), port: Number(m[2]), name: target };
  });
}

/** HOST:PORT of a resolved address ([v6]:port for IPv6). */
export function joinHostPort(ip, port) {
  return ip.includes(':') ? `[${ip}]:${port}` : `${ip}:${port}`;
}

/** The replica's part of a resume token: its address, base64url. */
export function replicaTag(address) {
  return Buffer.from(address, 'utf8').toString('base64url');
}

/** The token a page gets: `<replica tag>.<tesserad's token>`. */
export function wrapToken(address, token) {
  return token ? `${replicaTag(address)}.${token}` : '';
}

/**
 * A page's resume token taken apart: {address, token} (address null for a token without a
 * replica tag: one of tesserad's own, from a gateway before replicas). Throws a GatewayError
 * (INVALID_ARGUMENT naming open.resume_token) when it is malformed. Says nothing about whether
 * the address is a replica: the caller looks it up, it never connects to it.
 */
export function unwrapToken(token) {
  if (typeof token !== 'string' || token.length === 0 || token.length > MAX_TOKEN_CHARS) {
    throw new GatewayError('INVALID_ARGUMENT', `open.resume_token: wants a session token of 1..${MAX_TOKEN_CHARS} characters`);
  }
  if (!/^[\x21-\x7e]+$/.test(token)) {
    throw new GatewayError('INVALID_ARGUMENT', 'open.resume_token: a session token is printable ASCII without spaces');
  }
  const dot = token.indexOf('.');
  if (dot < 0) return { address: null, token };
  const tag = token.slice(0, dot);
  const inner = token.slice(dot + 1);
  let address = null;
  if (/^[A-Za-z0-9_-]{4,400}$/.test(tag) && inner.length > 0 && !inner.includes('.')) {
    const decoded = Buffer.from(tag, 'base64url').toString('utf8');
    // Canonical base64url only (no second spelling of one address), printable. Whether it is
    // a replica is the caller's lookup.
    if (replicaTag(decoded) === tag && /^[\x21-\x7e]{3,300}$/.test(decoded)) address = decoded;
  }
  if (address === null) {
    throw new GatewayError('INVALID_ARGUMENT', 'open.resume_token: not a session token of this gateway (<replica>.<token>)');
  }
  return { address, token: inner };
}

/** getaddrinfo's every address of `host` (A and AAAA; /etc/hosts too). */
export async function lookupAll(host) {
  const found = await dns.promises.lookup(host, { all: true, verbatim: true });
  return found.map((a) => a.address);
}

/** One tesserad: its client, what it last reported, and the sessions this gateway has there. */
export class Replica {
  constructor(address, client, { now = Date.now } = {}) {
    this.address = address;
    this.client = client;
    this.now = now;
    this.info = null;          // the last ServerInfo
    this.polled = false;       // a poll has answered or failed
    this.ok = false;           // the last poll answered
    this.error = '';           // why the last poll failed
    this.failures = 0;         // polls failed in a row
    this.knowsAccepting = false;  // has reported accepting_sessions (a server that has the field)
    this.listed = true;        // in --server, or in DNS at the last resolution
    this.listedAt = now();
    this.down = false;         // lost (its sessions were told to move) until it answers, serving
    this.streams = new Set();  // BridgedStreams on it now
    this.placements = [];      // times of sessions placed here since the poll that counts them
    this.polling = null;       // the poll in flight (a promise)
  }

  /** Takes a poll's answer (info) or failure (err); `sentAt` is when the poll was sent. */
  update(err, info, sentAt = this.now()) {
    this.polled = true;
    if (err) {
      if (this.failures === 0) this.failingSince = sentAt;  // the first poll that failed
      this.ok = false;
      this.failures++;
      this.error = String(err.details || err.message || err)
        .replace(/\.? Resolution note:.*$/s, '')
        .replace(/ \(\d{4}-\d\d-\d\dT[\d:.]+Z\)/g, '')
        .replace(/^No connection established\. Last error: (Error: )?/, '')
        .slice(0, 200);
      return;
    }
    this.ok = true;
    this.failures = 0;
    this.error = '';
    this.info = info;
    if (info.accepting_sessions === true) this.knowsAccepting = true;
    this.placements = this.placements.filter((t) => t >= sentAt - PLACEMENT_SLACK_MS);
  }

  /**
   * Serving as the poll said (an answer without health still takes sessions). A tesserad that is
   * NOT_SERVING always says why: `serving` false without an unhealthy_reason is a server older
   * than the field (proto3 reads it as false), which is serving.
   */
  get serving() {
    return this.ok && (this.info.serving === true || this.info.accepting_sessions === true ||
                       !this.info.unhealthy_reason);
  }

  get maxSessions() {
    return Number(this.info?.limits?.max_sessions ?? 0);
  }

  get sessions() {
    return Number(this.info?.active_sessions ?? 0);
  }

  /**
   * Takes new sessions. A server that reports accepting_sessions is taken at its word; one that
   * never has (older than the field: proto3 cannot tell false from absent) is judged by serving
   * and its session count against max_sessions.
   */
  get accepting() {
    if (!this.serving) return false;
    if (this.info.accepting_sessions === true) return true;
    if (this.knowsAccepting) return false;
    return this.maxSessions === 0 || this.sessions < this.maxSessions;
  }

  /** Reachable, serving and taking new sessions. */
  get ready() {
    return this.ok && this.accepting;
  }

  /** Sessions it has, and those placed here that its last answer did not count yet. */
  get load() {
    return this.sessions + this.placements.length;
  }

  /** Lost for its sessions: unreachable poll after poll, or reachable and not serving. */
  get lost() {
    return this.polled && ((!this.ok && this.failures >= DOWN_AFTER_FAILURES) || (this.ok && !this.serving));
  }

  /** Why it takes no session, in words ('' when it does). */
  get why() {
    if (!this.polled) return 'not asked yet';
    if (!this.ok) return `unreachable (${this.error || 'no answer'})`;
    if (!this.serving) return `NOT_SERVING${this.info.unhealthy_reason ? ` (${this.info.unhealthy_reason})` : ''}`;
    if (!this.accepting) {
      const max = this.maxSessions;
      return max > 0 && this.sessions >= max ? `full (${this.sessions} of ${max} sessions)` : 'not taking sessions (shutting down?)';
    }
    if (!this.listed) return 'no longer in DNS';
    return '';
  }

  /** What /healthz and the logs show of it. */
  summary() {
    return {
      address: this.address,
      ready: this.ready && this.listed,
      listed: this.listed,
      sessions: this.ok ? this.sessions : null,
      max_sessions: this.ok ? this.maxSessions : null,
      queue_depth: this.ok ? Number(this.info.queue_depth ?? 0) : null,
      scene_store: this.ok ? this.info.scene_store === true : null,
      streams: this.streams.size,
      ...(this.ready && this.listed ? {} : { why: this.why }),
    };
  }
}

/**
 * Of `candidates` (ready replicas), the one a new session goes to: the lowest load, ties in
 * turn by `turn` (a counter the caller advances) over the tied replicas in address order.
 */
export function choosePlacement(candidates, turn = 0) {
  if (candidates.length === 0) return null;
  const least = Math.min(...candidates.map((r) => r.load));
  const tied = candidates.filter((r) => r.load === least).sort((a, b) => (a.address < b.address ? -1 : a.address > b.address ? 1 : 0));
  return tied[turn % tied.length];
}

/**
 * The replicas of --server. Events: 'lost' (replica, reason) when a replica that was fine stops
 * answering or serving (its sessions move); 'log' is the `log` option.
 */
export class ReplicaSet extends EventEmitter {
  /**
   * @param options.spec         --server
   * @param options.makeClient   (address, {authority}) => a RenderService client
   * @param options.metadata     () => per-call metadata
   * @param options.lookup       (host) => Promise<[ip...]> (default: getaddrinfo, all records)
   */
  constructor({
    spec, makeClient, metadata = () => undefined, log = () => {}, lookup = lookupAll,
    pollMs = POLL_MS, pollTimeoutMs = POLL_TIMEOUT_MS, refreshMs = REFRESH_MS, forgetMs = FORGET_MS,
    now = Date.now,
  }) {
    super();
    this.spec = spec;
    this.entries = parseServers(spec);
    this.makeClient = makeClient;
    this.metadata = metadata;
    this.log = log;
    this.lookup = lookup;
    this.pollMs = pollMs;
    this.pollTimeoutMs = pollTimeoutMs;
    this.refreshMs = refreshMs;
    this.forgetMs = forgetMs;
    this.now = now;
    // One HOST:PORT: the gateway as it always was. Calls go to that server whatever it reports.
    this.single = this.entries.length === 1 && this.entries[0].kind === 'static';
    this.byAddress = new Map();
    this.dnsListed = new Map();  // dns entry name -> Set of addresses it resolved to last
    this.turn = 0;
    this.timers = [];
    this.started = null;
    this.refreshing = null;
    for (const e of this.entries) if (e.kind === 'static') this.add(e.address, {});
  }

  /** Every replica known now (listed or still holding sessions), in address order. */
  get replicas() {
    return [...this.byAddress.values()].sort((a, b) => (a.address < b.address ? -1 : 1));
  }

  add(address, { authority }) {
    let r = this.byAddress.get(address);
    if (!r) {
      r = new Replica(address, this.makeClient(address, { authority }), { now: this.now });
      this.byAddress.set(address, r);
      if (!this.single) this.log(`replica ${address} added${authority ? ` (${authority})` : ''}`);
    }
    return r;
  }

  /** Resolves, polls once, and keeps doing both. Resolves when the first round is in. */
  start() {
    if (this.started) return this.started;
    this.started = (async () => {
      await this.refresh();
      await this.pollAll();
    })();
    const poll = setInterval(() => this.pollAll(), this.pollMs);
    poll.unref?.();
    this.timers.push(poll);
    if (this.entries.some((e) => e.kind === 'dns')) {
      const refresh = setInterval(() => this.refresh(), this.refreshMs);
      refresh.unref?.();
      this.timers.push(refresh);
    }
    return this.started;
  }

  stop() {
    for (const t of this.timers) clearInterval(t);
    this.timers = [];
    for (const r of this.byAddress.values()) r.client.close?.();
  }

  /** Re-resolves the dns:/// entries: new addresses join, missing ones stop taking sessions. */
  refresh() {
    // One resolution at a time (a slow DNS server must not pile them up).
    this.refreshing ??= this.resolve().finally(() => { this.refreshing = null; });
    return this.refreshing;
  }

  async resolve() {
    const now = this.now();
    for (const e of this.entries.filter((x) => x.kind === 'dns')) {
      let ips;
      try {
        ips = await this.lookup(e.host);
      } catch (err) {
        // No records at all (every pod unready): nothing is listed. Other failures (a DNS
        // timeout) keep what the name resolved to before.
        if (err?.code !== 'ENOTFOUND' && err?.code !== 'ENODATA') {
          this.log(`cannot resolve ${e.name}: ${err?.code ?? err?.message ?? err}; keeping ${this.dnsListed.get(e.name)?.size ?? 0} replicas`);
          continue;
        }
        ips = [];
      }
      const addresses = new Set(ips.map((ip) => joinHostPort(ip, e.port)));
      for (const a of addresses) this.add(a, { authority: `${e.host}:${e.port}` });
      this.dnsListed.set(e.name, addresses);
    }
    const listedNow = new Set(this.entries.filter((e) => e.kind === 'static').map((e) => e.address));
    for (const set of this.dnsListed.values()) for (const a of set) listedNow.add(a);
    for (const r of [...this.byAddress.values()]) {
      const listed = listedNow.has(r.address);
      if (listed) {
        if (!r.listed) this.log(`replica ${r.address} is back in DNS`);
        r.listed = true;
        r.listedAt = now;
      } else if (r.listed) {
        r.listed = false;
        this.log(`replica ${r.address} left DNS: no new sessions there; its ${r.streams.size} sessions from this gateway stay`);
      } else if (now - r.listedAt > this.forgetMs && r.streams.size === 0) {
        this.byAddress.delete(r.address);
        r.client.close?.();
        this.log(`replica ${r.address} forgotten (out of DNS for ${Math.round((now - r.listedAt) / 1000)} s)`);
      }
    }
  }

  /** Asks every replica GetServerInfo (one poll in flight per replica). */
  async pollAll() {
    // Not a replica out of DNS that holds nothing of ours: its address may be another pod's.
    await Promise.all(this.replicas.filter((r) => r.listed || r.streams.size > 0).map((r) => this.poll(r)));
  }

  poll(r) {
    if (r.polling) return r.polling;
    const sentAt = this.now();
    let done;
    const polling = new Promise((resolve) => { done = resolve; });
    r.polling = polling;
    const finish = (err, info) => {
      if (r.polling === polling) r.polling = null;
      this.observe(r, err, info, sentAt);
      done();
    };
    try {
      r.client.GetServerInfo({}, this.metadata(), { deadline: Date.now() + this.pollTimeoutMs }, finish);
    } catch (err) {
      finish(err, null);
    }
    return polling;
  }

  /** A poll's outcome for `r`; tells the sessions there to move when it is newly lost. */
  observe(r, err, info, sentAt = this.now()) {
    const wasReady = r.polled && r.ready;
    r.update(err, info, sentAt);
    if (!this.single && r.polled && wasReady !== r.ready) {
      this.log(`replica ${r.address} ${r.ready ? 'ready' : `not ready: ${r.why}`}`);
    }
    // Every replica missing its polls at once says more about this gateway (its event loop
    // stalled, its network) than about them: nothing moves on missed polls then.
    const allMissing = !r.ok && [...this.byAddress.values()].every((x) => x.polled && !x.ok);
    if (r.lost && !r.down && !(allMissing && this.byAddress.size > 1)) {
      r.down = true;
      if (!this.single) this.emit('lost', r, r.ok ? r.why : `stopped answering (${r.error})`);
    } else if (!r.lost && r.ok) {
      r.down = false;
    }
  }

  /** A stream there ended UNAVAILABLE: no new sessions there until a poll says otherwise. */
  reportFailure(r, why) {
    if (this.single || !r.ok) return;
    r.ok = false;
    r.error = why;
    this.log(`replica ${r.address} not ready: ${why}`);
    this.poll(r);
  }

  /** The UNAVAILABLE error of "no replica will do", naming each and why. */
  unavailable(what, exclude = new Set()) {
    const parts = this.replicas.map((r) => {
      if (exclude.has(r.address)) return `${r.address} lost`;
      return `${r.address} ${r.why || 'ready'}`;
    });
    const listed = parts.length ? parts.join('; ') : `${this.spec} resolved to no address`;
    return new GatewayError('UNAVAILABLE', `${what}: ${listed}`);
  }

  /** The replicas, of `candidates`, that have `sceneId` (HasScene), or all of them when none does. */
  async preferScene(candidates, sceneId) {
    if (!sceneId || sceneId === 'demo' || candidates.length < 2) return candidates;
    if (candidates.every((r) => r.info?.scene_store === true)) return candidates;  // shared: all have it
    const answers = await Promise.all(candidates.map((r) => new Promise((resolve) => {
      try {
        r.client.HasScene({ scene_id: sceneId }, this.metadata(), { deadline: Date.now() + HAS_SCENE_TIMEOUT_MS },
          (err, res) => resolve(!err && res?.present === true));
      } catch {
        resolve(false);
      }
    })));
    const have = candidates.filter((_, i) => answers[i]);
    return have.length > 0 ? have : candidates;
  }

  /**
   * Where a new Stream session goes: the least loaded ready replica (not in `exclude`), one
   * that has the scene first when the store is not shared. Counts the placement. Throws
   * UNAVAILABLE naming every replica and why when none will do.
   */
  async place({ sceneId = '', exclude = new Set() } = {}) {
    await this.start();
    if (this.single) {
      const [only] = this.byAddress.values();
      if (exclude.has(only.address)) throw this.unavailable('no other tesserad to move the session to', exclude);
      return only;
    }
    let candidates = this.replicas.filter((r) => r.listed && r.ready && !exclude.has(r.address));
    if (candidates.length === 0) throw this.unavailable('no tesserad replica takes new sessions now', exclude);
    candidates = await this.preferScene(candidates, sceneId);
    // A replica may have gone while HasScene was asked.
    const still = candidates.filter((r) => r.listed && r.ready);
    const chosen = choosePlacement(still.length ? still : candidates, this.turn++);
    chosen.placements.push(this.now());
    this.log(`placed a session${sceneId ? ` of scene ${String(sceneId).slice(0, 12)}` : ''} on ${chosen.address} ` +
      `(${chosen.load} there now; ${this.loads(exclude)})`);
    return chosen;
  }

  /** "a=2 b=3 c=full" for the placement log. */
  loads(exclude = new Set()) {
    return this.replicas.map((r) => {
      if (exclude.has(r.address)) return `${r.address}=lost`;
      if (!r.listed) return `${r.address}=out of DNS`;
      return r.ready ? `${r.address}=${r.load}` : `${r.address}=${r.why.split(' ')[0]}`;
    }).join(' ');
  }

  /**
   * The replica a unary call goes to: a ready one (the least loaded; one with the scene first
   * when the store is not shared), else one that is up but full (it still renders and answers).
   */
  async pickUnary({ sceneId = '' } = {}) {
    await this.start();
    if (this.single) return this.byAddress.values().next().value;
    const listed = this.replicas.filter((r) => r.listed);
    let candidates = listed.filter((r) => r.ready);
    if (candidates.length === 0) candidates = listed.filter((r) => r.serving);
    if (candidates.length === 0) throw this.unavailable('no tesserad replica answers now');
    candidates = await this.preferScene(candidates, sceneId);
    return choosePlacement(candidates, this.turn++);
  }

  /** Every replica that answers (listed), for calls that go to all (ListScenes, DeleteScene). */
  async answering() {
    await this.start();
    if (this.single) return [this.byAddress.values().next().value];
    const up = this.replicas.filter((r) => r.listed && r.ok);
    if (up.length === 0) throw this.unavailable('no tesserad replica answers now');
    return up;
  }

  /** Whether the answering replicas share one scene store (or there is only one). */
  shared(replicas) {
    return this.single || replicas.length < 2 || replicas.every((r) => r.info?.scene_store === true);
  }

  /**
   * The replica a page's resume token names, and tesserad's token: {replica, token}. Throws
   * INVALID_ARGUMENT for a malformed token and NOT_FOUND for one that names no replica of this
   * gateway (gone, or never one: the gateway connects to no address a page names).
   */
  forToken(token) {
    const { address, token: inner } = unwrapToken(token);
    if (address === null) {
      // tesserad's own token, from a gateway without replica tags: only one server can hold it.
      if (this.single) return { replica: this.byAddress.values().next().value, token: inner };
      throw new GatewayError('NOT_FOUND', 'open.resume_token: names no replica (a token from an older gateway?)');
    }
    const replica = this.byAddress.get(address);
    if (!replica) {
      throw new GatewayError('NOT_FOUND', 'open.resume_token: the session\'s replica is not one of this gateway\'s (it may be gone)');
    }
    return { replica, token: inner };
  }

  /** ServerInfo of a replica that answered (a ready one first), or null. */
  anyInfo() {
    const rs = this.replicas.filter((r) => r.ok);
    return (rs.find((r) => r.ready) ?? rs[0])?.info ?? null;
  }
}

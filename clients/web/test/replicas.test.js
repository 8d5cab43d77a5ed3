// The replica set (lib/replicas.js) with fake tesserad clients: --server parsing, readiness from
// ServerInfo, placement, scene preference, DNS refresh, lost replicas, and resume tokens that name
// a replica (hostile ones included).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import {
  Replica, ReplicaSet, choosePlacement, parseServers, replicaTag, unwrapToken, wrapToken,
} from '../lib/replicas.js';

/** ServerInfo as a tesserad with the readiness fields reports it. */
const info = (over = {}) => ({
  serving: true, accepting_sessions: true, scene_store: false, active_sessions: 0, queue_depth: 0,
  unhealthy_reason: '', limits: { max_sessions: 8, resume_grace_s: 30 }, ...over,
});

/**
 * Fake clients by address: `infos[address]` is what GetServerInfo answers (an Error: it fails),
 * `scenes[address]` the scene ids HasScene says yes to.
 */
function fakeWorld() {
  const world = { infos: {}, scenes: {}, made: [], hasSceneCalls: 0 };
  world.makeClient = (address, { authority } = {}) => {
    world.made.push({ address, authority });
    return {
      GetServerInfo(_req, _md, _opts, cb) {
        setImmediate(() => {
          const v = world.infos[address];
          if (v instanceof Error || v === undefined) cb(v ?? Object.assign(new Error('no'), { code: 14, details: 'connect ECONNREFUSED' }));
          else cb(null, v);
        });
      },
      HasScene(req, _md, _opts, cb) {
        world.hasSceneCalls++;
        setImmediate(() => cb(null, { present: (world.scenes[address] ?? []).includes(req.scene_id) }));
      },
      close() { world.closed = [...(world.closed ?? []), address]; },
    };
  };
  return world;
}

function makeSet(spec, world, over = {}) {
  const logs = [];
  const set = new ReplicaSet({ spec, makeClient: world.makeClient, log: (l) => logs.push(l), ...over });
  set.logs = logs;
  return set;
}

test('--server: one target, lists, dns:/// names; malformed entries are named', () => {
  assert.deepEqual(parseServers('127.0.0.1:50051'), [{ kind: 'static', address: '127.0.0.1:50051' }]);
  assert.deepEqual(parseServers('unix:/run/tesserad.sock'), [{ kind: 'static', address: 'unix:/run/tesserad.sock' }]);
  assert.deepEqual(parseServers(' a:1 , [::1]:2,dns:///tesserad-headless.ns.svc:50051'), [
    { kind: 'static', address: 'a:1' },
    { kind: 'static', address: '[::1]:2' },
    { kind: 'dns', host: 'tesserad-headless.ns.svc', port: 50051, name: 'tesserad-headless.ns.svc:50051' },
  ]);
  assert.deepEqual(parseServers('dns:///[::1]:7'), [{ kind: 'dns', host: '::1', port: 7, name: '[::1]:7' }]);
  assert.throws(() => parseServers(''), /--server: wants/);
  assert.throws(() => parseServers('a:1,b'), /'b' is not HOST:PORT/);
  assert.throws(() => parseServers('a:1,a:99999'), /'a:99999'/);
  assert.throws(() => parseServers('dns:///name'), /'dns:\/\/\/name'/);
  assert.throws(() => parseServers('a:1,a:1'), /appears twice/);
});

test('resume tokens: the replica tag round-trips; hostile tokens are refused, never dialled', () => {
  const token = wrapToken('10.0.0.5:50051', '0123abcd');
  assert.equal(token, `${Buffer.from('10.0.0.5:50051').toString('base64url')}.0123abcd`);
  assert.deepEqual(unwrapToken(token), { address: '10.0.0.5:50051', token: '0123abcd' });
  assert.deepEqual(unwrapToken('0123abcd'), { address: null, token: '0123abcd' }); // tesserad's own
  assert.equal(wrapToken('a:1', ''), '');
  const tag = replicaTag('10.0.0.5:50051');
  for (const bad of [
    '', 'x'.repeat(1025), 'has space.abc', 'tab\t.x', 'ünï.x', '.abc', `${tag}.`, `${tag}.a.b`,
    'not-base64!.abc', `${tag}=.abc`, `${Buffer.from('\u0000\u0001').toString('base64url')}.abc`,
    `${Buffer.from('a b:1').toString('base64url')}.abc`, 5, null, {},
  ]) {
    assert.throws(() => unwrapToken(bad), (e) => e.code === 'INVALID_ARGUMENT' && /open\.resume_token/.test(e.message), JSON.stringify(bad));
  }
  // Base64url has one spelling per address here: a tag with trailing bits set is refused.
  const loose = `${tag.slice(0, -1)}${String.fromCharCode(tag.charCodeAt(tag.length - 1) + 1)}.abc`;
  assert.throws(() => unwrapToken(loose), /resume_token/);
});

test('forToken: only replicas of the set; tesserad\'s own tokens only with one server', async () => {
  const world = fakeWorld();
  const set = makeSet('127.0.0.1:1,127.0.0.1:2', world);
  const made = world.made.length;
  const { replica, token } = set.forToken(wrapToken('127.0.0.1:2', 'beef'));
  assert.equal(replica.address, '127.0.0.1:2');
  assert.equal(token, 'beef');
  assert.throws(() => set.forToken(wrapToken('169.254.169.254:80', 'beef')), (e) => e.code === 'NOT_FOUND' && /open\.resume_token/.test(e.message));
  assert.throws(() => set.forToken('beef'), (e) => e.code === 'NOT_FOUND');
  assert.throws(() => set.forToken('x.y'), (e) => e.code === 'INVALID_ARGUMENT');
  assert.equal(world.made.length, made, 'a client was made for an address a page named');

  const single = makeSet('tesserad:50051', fakeWorld());
  assert.equal(single.single, true);
  assert.deepEqual(single.forToken('beef').token, 'beef');
  assert.equal(single.forToken(wrapToken('tesserad:50051', 'beef')).replica.address, 'tesserad:50051');
  assert.throws(() => single.forToken(wrapToken('other:1', 'beef')), (e) => e.code === 'NOT_FOUND');
});

test('readiness: serving and taking sessions; full, NOT_SERVING, unreachable say why; older servers by their counts', () => {
  const r = new Replica('a:1', {});
  assert.equal(r.ready, false);
  assert.equal(r.why, 'not asked yet');
  r.update(null, info({ active_sessions: 3 }));
  assert.equal(r.ready, true);
  assert.equal(r.load, 3);
  r.update(null, info({ active_sessions: 8, accepting_sessions: false }));
  assert.equal(r.ready, false);
  assert.equal(r.why, 'full (8 of 8 sessions)');
  assert.equal(r.lost, false, 'a full replica keeps its sessions');
  r.update(null, info({ active_sessions: 2, accepting_sessions: false }));
  assert.match(r.why, /shutting down/);
  r.update(null, info({ serving: false, accepting_sessions: false, unhealthy_reason: 'render stalled 12 s' }));
  assert.equal(r.why, 'NOT_SERVING (render stalled 12 s)');
  assert.equal(r.lost, true);
  r.update({ code: 14, details: 'connect ECONNREFUSED 127.0.0.1:1. Resolution note: x' });
  assert.equal(r.why, 'unreachable (connect ECONNREFUSED 127.0.0.1:1)');
  assert.equal(r.lost, false, 'one missed poll is not a loss');
  r.update({ code: 4, details: 'Deadline exceeded' });
  assert.equal(r.lost, true);

  // A server older than accepting_sessions (proto3: absent reads as false): its counts decide.
  const old = new Replica('b:1', {});
  old.update(null, { serving: true, active_sessions: 3, limits: { max_sessions: 4 } });
  assert.equal(old.ready, true);
  old.update(null, { serving: true, active_sessions: 4, limits: { max_sessions: 4 } });
  assert.equal(old.ready, false);
  assert.equal(old.why, 'full (4 of 4 sessions)');
  // Older than `serving` too: absent reads as false, but a NOT_SERVING tesserad says why.
  const older = new Replica('c:1', {});
  older.update(null, { serving: false, unhealthy_reason: '', active_sessions: 1, limits: { max_sessions: 4 } });
  assert.equal(older.ready, true);
  assert.equal(older.lost, false);
});

/**
 * Two healthy replicas a:1 and b:1, polled once (then polled by hand); `lost` gets each loss as
 * `entry(replica, why)`.
 */
async function startedPair(entry) {
  const world = fakeWorld();
  const set = makeSet('a:1,b:1', world);
  world.infos = { 'a:1': info(), 'b:1': info() };
  const lost = [];
  set.on('lost', (r, why) => lost.push(entry(r, why)));
  await set.start();
  set.stop();
  return { world, set, lost };
}

test('every replica missing its polls at once moves nothing (the gateway stalled, not them)', async () => {
  const { world, set, lost } = await startedPair((r) => r.address);
  const down = Object.assign(new Error('x'), { code: 4, details: 'Deadline exceeded' });
  world.infos = { 'a:1': down, 'b:1': down };
  await set.pollAll();
  await set.pollAll();
  await set.pollAll();
  assert.deepEqual(lost, []);
  world.infos['b:1'] = info();  // b answers again: a alone is missing now (seen next round)
  await set.pollAll();
  await set.pollAll();
  assert.deepEqual(lost, ['a:1']);
});

test('placement: the fewest sessions, ties in turn, a burst spread by what this gateway placed', async () => {
  const world = fakeWorld();
  const set = makeSet('a:1,b:1,c:1', world);
  world.infos = { 'a:1': info({ active_sessions: 2 }), 'b:1': info(), 'c:1': info({ active_sessions: 1 }) };
  await set.start();
  set.stop();
  assert.equal((await set.place()).address, 'b:1');
  assert.equal((await set.place()).address, 'c:1'); // b: 0 + 1 placed, c: 1: tied, the next in turn
  const counts = { 'a:1': 2, 'b:1': 2, 'c:1': 1 };
  for (let i = 0; i < 7; i++) counts[(await set.place()).address]++;
  // 12 sessions over 3: none holds more than ceil(12/3)+1.
  assert.ok(Object.values(counts).every((n) => n <= 5), JSON.stringify(counts));
  assert.equal(Object.values(counts).reduce((a, b) => a + b), 12);
  // A poll sent after the placements counts them: they are no longer added on top.
  world.infos = { 'a:1': info({ active_sessions: counts['a:1'] }), 'b:1': info({ active_sessions: counts['b:1'] }), 'c:1': info({ active_sessions: counts['c:1'] }) };
  await new Promise((r) => setTimeout(r, 300));
  await set.pollAll();
  for (const r of set.replicas) assert.equal(r.load, counts[r.address]);
  assert.ok(set.logs.some((l) => /^placed a session on [abc]:1 \(\d+ there now; a:1=\d+ b:1=\d+ c:1=\d+\)$/.test(l)), set.logs.join('\n'));

  // Ties take turns.
  const tied = [new Replica('x:1', {}), new Replica('y:1', {}), new Replica('z:1', {})];
  for (const r of tied) r.update(null, info({ active_sessions: 1 }));
  assert.deepEqual([0, 1, 2, 3].map((t) => choosePlacement(tied, t).address), ['x:1', 'y:1', 'z:1', 'x:1']);
  assert.equal(choosePlacement([], 0), null);
});

test('placement: only ready replicas; none ready is UNAVAILABLE naming each and why', async () => {
  const world = fakeWorld();
  const set = makeSet('a:1,b:1,c:1,d:1', world);
  world.infos = {
    'a:1': info({ active_sessions: 8, accepting_sessions: false }),
    'b:1': info({ serving: false, accepting_sessions: false, unhealthy_reason: 'device lost' }),
    'd:1': info({ active_sessions: 7 }),
  };
  await set.start();
  set.stop();
  assert.equal((await set.place()).address, 'd:1');
  await assert.rejects(set.place({ exclude: new Set(['d:1']) }), (e) => {
    assert.equal(e.code, 'UNAVAILABLE');
    assert.match(e.message, /a:1 full \(8 of 8 sessions\)/);
    assert.match(e.message, /b:1 NOT_SERVING \(device lost\)/);
    assert.match(e.message, /c:1 unreachable \(connect ECONNREFUSED\)/);
    assert.match(e.message, /d:1 lost/);
    return true;
  });
  // Unary calls may still go to a full replica that serves.
  world.infos['d:1'] = new Error('gone');
  await set.pollAll();
  assert.equal((await set.pickUnary()).address, 'a:1');
});

test('placement: without a shared store, replicas that have the scene first; with one, no HasScene', async () => {
  const world = fakeWorld();
  const scene = 'ab'.repeat(32);
  const set = makeSet('a:1,b:1,c:1', world);
  world.infos = { 'a:1': info(), 'b:1': info({ active_sessions: 5 }), 'c:1': info() };
  world.scenes = { 'b:1': [scene] };
  await set.start();
  set.stop();
  assert.equal((await set.place({ sceneId: scene })).address, 'b:1');
  assert.equal((await set.pickUnary({ sceneId: scene })).address, 'b:1');
  assert.notEqual((await set.place({ sceneId: 'demo' })).address, 'b:1');
  // Nobody has it: any (the server then says NOT_FOUND).
  assert.ok(await set.place({ sceneId: 'cd'.repeat(32) }));

  const shared = makeSet('a:1,b:1', world);
  world.infos = { 'a:1': info({ scene_store: true }), 'b:1': info({ scene_store: true, active_sessions: 1 }) };
  await shared.start();
  shared.stop();
  const calls = world.hasSceneCalls;
  assert.equal((await shared.place({ sceneId: scene })).address, 'a:1');
  assert.equal(world.hasSceneCalls, calls);
  assert.equal(shared.shared(shared.replicas), true);
  assert.equal(set.shared(set.replicas), false);
});

test('dns:///: every record is a replica; one that leaves DNS takes no new session but stays known', async () => {
  const world = fakeWorld();
  let records = ['10.0.0.1', '10.0.0.2', 'fd00::3'];
  let now = 1_000_000;
  const set = makeSet('dns:///tesserad-headless:50051', world, {
    lookup: async (host) => {
      assert.equal(host, 'tesserad-headless');
      if (records instanceof Error) throw records;
      return records;
    },
    now: () => now,
  });
  assert.equal(set.single, false);
  for (const a of ['10.0.0.1:50051', '10.0.0.2:50051', '[fd00::3]:50051']) world.infos[a] = info();
  await set.start();
  set.stop();
  assert.deepEqual(set.replicas.map((r) => r.address).sort(), ['10.0.0.1:50051', '10.0.0.2:50051', '[fd00::3]:50051']);
  assert.ok(world.made.every((m) => m.authority === 'tesserad-headless:50051'), 'TLS and authority use the name');

  // 10.0.0.1 holds a session of ours and leaves DNS (full, unready).
  const gone = set.byAddress.get('10.0.0.1:50051');
  gone.streams.add({});
  records = ['10.0.0.2', 'fd00::3'];
  await set.refresh();
  assert.equal(gone.listed, false);
  for (let i = 0; i < 6; i++) assert.notEqual((await set.place()).address, '10.0.0.1:50051');
  assert.equal(set.forToken(wrapToken('10.0.0.1:50051', 'beef')).replica, gone, 'its sessions can still be resumed');
  assert.ok(set.logs.some((l) => /10\.0\.0\.1:50051 left DNS/.test(l)));

  // A DNS failure keeps what was resolved; no records at all lists nothing.
  records = Object.assign(new Error('timeout'), { code: 'ETIMEOUT' });
  await set.refresh();
  assert.equal(set.byAddress.get('10.0.0.2:50051').listed, true);
  records = Object.assign(new Error('none'), { code: 'ENOTFOUND' });
  await set.refresh();
  assert.ok(set.replicas.every((r) => !r.listed));
  await assert.rejects(set.place(), (e) => e.code === 'UNAVAILABLE' && /no longer in DNS/.test(e.message));

  // Out of DNS long enough and holding nothing: forgotten (its client closed); with a session: kept.
  now += 11 * 60_000;
  await set.refresh();
  assert.deepEqual(set.replicas.map((r) => r.address), ['10.0.0.1:50051']);
  assert.ok(world.closed.includes('10.0.0.2:50051'));
  assert.throws(() => set.forToken(wrapToken('10.0.0.2:50051', 'beef')), (e) => e.code === 'NOT_FOUND');
  // Back in DNS: listed again.
  records = ['10.0.0.1'];
  await set.refresh();
  assert.equal(gone.listed, true);
});

test('a replica that stops answering or serving is reported lost once; one stream failure only stops placement', async () => {
  const { world, set, lost } = await startedPair((r, why) => `${r.address}: ${why}`);
  const a = set.byAddress.get('a:1');
  set.reportFailure(a, 'a stream there ended UNAVAILABLE (Connection dropped)');
  assert.equal(a.ready, false);
  assert.equal((await set.place()).address, 'b:1');
  world.infos['a:1'] = Object.assign(new Error('x'), { code: 14, details: 'connect ECONNREFUSED' });
  await set.pollAll();
  assert.deepEqual(lost, []);
  await set.pollAll();
  assert.deepEqual(lost, ['a:1: stopped answering (connect ECONNREFUSED)']);
  await set.pollAll();
  assert.equal(lost.length, 1);
  world.infos['a:1'] = info();
  await set.pollAll();
  assert.equal(a.ready, true);
  world.infos['a:1'] = info({ serving: false, accepting_sessions: false, unhealthy_reason: 'render stalled' });
  await set.pollAll();
  assert.deepEqual(lost.slice(1), ['a:1: NOT_SERVING (render stalled)']);
  // One server: nothing to move to, nothing reported.
  const single = makeSet('a:1', world);
  single.on('lost', () => assert.fail('lost with one server'));
  await single.start();
  single.stop();
  assert.equal((await single.place()).address, 'a:1', 'one server takes every session, whatever it reports');
});

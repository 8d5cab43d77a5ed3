// Unit tests of the viewer's upload planning, scene id and sending (public/upload.js): no
// browser needed.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { webcrypto } from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';

import {
  UploadError, checkLimits, collectInput, compareUtf8, computeSceneId, externalUris, findMainFile,
  normalizePath, percentDecode, planUpload, readSceneJson, resolveUri, sceneIdText,
  sendUpload, uriProblem,
} from '../public/upload.js';
import { ASSETS } from './harness.js';

/** A file descriptor as the page makes them; `text` stands in for reading the file. */
const file = (path, size = 10, text) => ({ path, size, text });
const gltf = (json) => JSON.stringify({ asset: { version: '2.0' }, ...json });
const names = (plan) => plan.files.map((f) => f.name);

test('the main file: exactly one .glb or .gltf', () => {
  assert.equal(findMainFile([file('a.bin'), file('Box.GLB')]).path, 'Box.GLB');
  assert.equal(findMainFile([file('x/._Box.gltf'), file('x/Box.gltf')]).path, 'x/Box.gltf');
  assert.throws(() => findMainFile([file('a.bin'), file('b.png')]),
    (e) => e instanceof UploadError && /no \.glb or \.gltf file among 2 files/.test(e.message));
  assert.throws(() => findMainFile([file('a.png')]), /among 'a\.png'/);
  assert.throws(() => findMainFile([file('a.gltf'), file('b/c.glb')]),
    (e) => e instanceof UploadError && /2 scene files \('a\.gltf', 'b\/c\.glb'\)/.test(e.message));
});

test('paths are normalised to relative, /-separated', () => {
  assert.equal(normalizePath('/Sponza/./textures//a.png'), 'Sponza/textures/a.png');
  assert.equal(normalizePath('dir\\b.bin'), 'dir/b.bin');
  const entries = collectInput([{ name: 'a.glb', size: 3, webkitRelativePath: '' },
    { name: 'b.png', size: 4, webkitRelativePath: 'pick/tex/b.png' }]);
  assert.deepEqual(entries.map((e) => [e.path, e.size]), [['a.glb', 3], ['pick/tex/b.png', 4]]);
});

test('%-decoding matches the server: valid %XX only, + stays, UTF-8', () => {
  assert.equal(percentDecode('my%20file.png'), 'my file.png');
  assert.equal(percentDecode('a+b.png'), 'a+b.png');
  assert.equal(percentDecode('100%.png'), '100%.png');
  assert.equal(percentDecode('%zz%2'), '%zz%2');
  assert.equal(percentDecode('caf%C3%A9.png'), 'café.png');
  assert.equal(percentDecode('dir%2Fa.png'), 'dir/a.png');
});

test('external URIs: buffers and images, no data: URIs, each once', () => {
  const uris = externalUris({
    buffers: [{ uri: 'Box.bin' }, { uri: 'data:application/octet-stream;base64,AAAA' }, {}],
    images: [{ uri: 'tex/a%20b.png' }, { bufferView: 3 }, { uri: 'tex/a b.png' }, { uri: 7 }],
  });
  assert.deepEqual(uris.map((u) => u.uri), ['Box.bin', 'tex/a b.png']);
  assert.deepEqual(uris[1].uses, ['images[0]', 'images[2]']);
  assert.deepEqual(externalUris(null), []);
  assert.deepEqual(externalUris({ buffers: 'nope' }), []);
});

test('URIs the server cannot take are named', () => {
  assert.equal(uriProblem('textures/a.png'), null);
  assert.match(uriProblem('../a.png'), /outside/);
  assert.match(uriProblem('/etc/passwd'), /absolute/);
  assert.match(uriProblem('https://x/a.png'), /URL/);
  assert.match(uriProblem('./a.png'), /'\.'/);
  assert.match(uriProblem('a\\b.png'), /backslash/);
});

test('a .glb goes alone; other files are reported as unused', async () => {
  const plan = await planUpload([file('Helmet.glb', 1234), file('readme.txt')]);
  assert.equal(plan.main, 'Helmet.glb');
  assert.deepEqual(plan.files.map((f) => [f.name, f.size]), [['Helmet.glb', 1234]]);
  assert.deepEqual(plan.unused, ['readme.txt']);
});

test('a dropped folder: files found by their path relative to the .gltf', async () => {
  const text = gltf({
    buffers: [{ uri: 'Sponza.bin' }],
    images: [{ uri: 'textures/wall.png' }, { uri: 'textures/floor%20tile.jpg' }],
  });
  const entries = [
    file('Sponza/Sponza.gltf', 100, text), file('Sponza/Sponza.bin', 200),
    file('Sponza/textures/wall.png', 300), file('Sponza/textures/floor tile.jpg', 400),
    file('Sponza/other/wall.png', 5),   // same basename elsewhere: the exact path wins
    file('Sponza/notes.md', 6),
  ];
  const plan = await planUpload(entries);
  assert.equal(plan.main, 'Sponza.gltf');
  assert.deepEqual(plan.files.map((f) => [f.name, f.entry.path, f.size]), [
    ['Sponza.gltf', 'Sponza/Sponza.gltf', 100],
    ['Sponza.bin', 'Sponza/Sponza.bin', 200],
    ['textures/wall.png', 'Sponza/textures/wall.png', 300],
    ['textures/floor tile.jpg', 'Sponza/textures/floor tile.jpg', 400],
  ]);
  assert.deepEqual(plan.unused, ['Sponza/other/wall.png', 'Sponza/notes.md']);
});

test('files picked without their folders are matched by a unique basename', async () => {
  const text = gltf({ buffers: [{ uri: 'data/Box.bin' }], images: [{ uri: 'tex/a.png' }] });
  const plan = await planUpload([file('Box.gltf', 1, text), file('Box.bin', 2), file('a.png', 3)]);
  // Sent under the names the glTF uses, not their names on disk.
  assert.deepEqual(names(plan), ['Box.gltf', 'data/Box.bin', 'tex/a.png']);
  assert.deepEqual(plan.files.map((f) => f.entry.path), ['Box.gltf', 'Box.bin', 'a.png']);
});

test('missing, ambiguous and unusable files are all named before anything is sent', async () => {
  const text = gltf({ images: [{ uri: 'textures/foo.png' }] });
  await assert.rejects(planUpload([file('Sponza.gltf', 1, text)]), (e) => e instanceof UploadError &&
    e.message === "Sponza.gltf needs 'textures/foo.png', which was not among the files.");

  const two = gltf({ buffers: [{ uri: 'a.bin' }], images: [{ uri: 'x.png' }, { uri: '../up.png' }] });
  // Several problems: one sentence saying what is missing and how to fix it; each file in the
  // details (the page folds them away), not 71 sentences in the banner.
  await assert.rejects(
    planUpload([file('s.gltf', 1, two), file('p/x.png'), file('q/x.png')]),
    (e) => e.message === 's.gltf needs 1 file that was not among the files chosen and 2 files ' +
        'that cannot be used. Choose the .gltf together with all its files, or drop its whole ' +
        'folder.' &&
      e.details.length === 3 &&
      e.details.some((d) => /needs 'a\.bin', which was not among the files/.test(d)) &&
      e.details.some((d) => /needs 'x\.png', but several files are called 'x\.png' \('p\/x\.png', 'q\/x\.png'\)/.test(d)) &&
      e.details.some((d) => /needs '\.\.\/up\.png', which cannot be uploaded: it points outside/.test(d)));
  const many = gltf({ images: Array.from({ length: 71 }, (_, i) => ({ uri: `t/${i}.png` })) });
  await assert.rejects(planUpload([file('Sponza.gltf', 1, many)]), (e) =>
    e.message === 'Sponza.gltf needs 71 files that were not among the files chosen. Choose the ' +
      '.gltf together with all its files, or drop its whole folder.' && e.details.length === 71);
});

test('resolveUri: exact path first, then a unique basename', () => {
  const entries = [file('d/t/a.png'), file('a.png'), file('b.png')];
  assert.equal(resolveUri('t/a.png', 'd', entries).entry.path, 'd/t/a.png');
  assert.equal(resolveUri('x/b.png', 'd', entries).entry.path, 'b.png');
  assert.match(resolveUri('z/a.png', 'd', entries).problem, /several files/);
  assert.match(resolveUri('c.png', '', entries).problem, /not among/);
});

test('the glTF is read through the injected reader; bad JSON is an error', async () => {
  const read = [];
  const reader = async (entry) => {
    read.push(entry.path);
    return gltf({ buffers: [{ uri: 'b.bin' }] });
  };
  const plan = await planUpload([file('dir/a.gltf'), file('dir/b.bin')], reader);
  assert.deepEqual(read, ['dir/a.gltf']);
  assert.deepEqual(names(plan), ['a.gltf', 'b.bin']);

  await assert.rejects(planUpload([file('a.gltf', 1, '{ nope')]), /a\.gltf is not valid glTF JSON/);
  await assert.rejects(planUpload([file('a.gltf', 1)]), /a\.gltf could not be read/);
  await assert.rejects(planUpload([file('a.gltf')], () => { throw new Error('denied'); }),
    /a\.gltf could not be read: denied/);
});

test('limits: files and bytes per upload', () => {
  const plan = { main: 'a.gltf', files: [{ size: 600 }, { size: 600 }] };
  assert.doesNotThrow(() => checkLimits(plan, {}));
  assert.doesNotThrow(() => checkLimits(plan, { max_upload_files: 2, max_upload_bytes: 1200 }));
  assert.throws(() => checkLimits(plan, { max_upload_files: 1 }), /needs 2 files; the server takes at most 1/);
  assert.throws(() => checkLimits(plan, { max_upload_bytes: 1000 }),
    /1\.2 KB \(1,200 bytes\); the server takes at most 1\.0 KB \(1,000 bytes\) per upload/);
});

/** A minimal GLB: header, JSON chunk (padded), BIN chunk. */
function glb(json, binBytes = 8) {
  const text = new TextEncoder().encode(JSON.stringify(json));
  const jsonLen = Math.ceil(text.length / 4) * 4;
  const total = 12 + 8 + jsonLen + 8 + binBytes;
  const out = new Uint8Array(total);
  const dv = new DataView(out.buffer);
  dv.setUint32(0, 0x46546c67, true);
  dv.setUint32(4, 2, true);
  dv.setUint32(8, total, true);
  dv.setUint32(12, jsonLen, true);
  dv.setUint32(16, 0x4e4f534a, true);
  out.fill(0x20, 20, 20 + jsonLen);
  out.set(text, 20);
  dv.setUint32(20 + jsonLen, binBytes, true);
  dv.setUint32(24 + jsonLen, 0x004e4942, true);
  return new Blob([out]);
}

test('readSceneJson: a .glb JSON chunk, a .gltf text; not a GLB is an error', async () => {
  const json = { asset: { version: '2.0' }, images: [{ uri: 'ext.png' }] };
  const blob = glb(json);
  assert.deepEqual(JSON.parse(await readSceneJson(blob, 'x.glb')), json);
  const plan = await planUpload([{ path: 'x.glb', size: blob.size, file: blob }, file('ext.png', 3)],
    (e) => readSceneJson(e.file, e.path));
  assert.deepEqual(names(plan), ['x.glb', 'ext.png']);
  assert.equal(await readSceneJson(new Blob(['{"a":1}']), 'y.gltf'), '{"a":1}');
  await assert.rejects(readSceneJson(new Blob(['not a glb at all, really']), 'z.glb'),
    (e) => e instanceof UploadError && /z\.glb is not a binary glTF/.test(e.message));
});

/**
 * A stand-in for protocol.js's Connection: records what is sent; the test decides when the
 * upload's reply comes (resolve/reject) and how full the socket buffer is.
 */
function fakeConnection() {
  const conn = {
    calls: [], chunks: [], notes: [], buffered: 0, waits: 0, connected: true,
    call(op, fields, options) {
      const call = { id: 7, op, fields, options };
      call.result = new Promise((resolve, reject) => Object.assign(call, { resolve, reject }));
      conn.calls.push(call);
      return call;
    },
    notify(op, fields) { conn.notes.push({ op, fields }); return 8; },
    async waitForBuffer(limit) {
      conn.waits++;
      while (conn.buffered > limit) await new Promise((r) => setTimeout(r, 1));
    },
    sendBinary(header, data) {
      if (!conn.connected) return false;
      conn.chunks.push({ header, bytes: new Uint8Array(data) });
      return true;
    },
  };
  return conn;
}

const bytes = (n, seed) => Uint8Array.from({ length: n }, (_, i) => (i * 7 + seed) & 255);

test('sendUpload: manifest, then every file in ordered chunks of at most the chunk size', async () => {
  const a = bytes(10, 1);
  const b = bytes(4, 2);
  const plan = {
    main: 'a.gltf',
    files: [
      { name: 'a.gltf', size: a.length, entry: { file: new Blob([a]) } },
      { name: 'tex/b.png', size: b.length, entry: { file: new Blob([b]) } },
      { name: 'empty.bin', size: 0, entry: { file: new Blob([]) } },
    ],
  };
  const conn = fakeConnection();
  const progress = [];
  const upload = sendUpload(conn, plan, { chunkBytes: 4, onProgress: (p) => progress.push(p) });
  assert.equal(upload.id, 7);
  const [call] = conn.calls;
  assert.equal(call.op, 'upload');
  assert.deepEqual(call.fields, {
    files: [{ name: 'a.gltf', size: 10 }, { name: 'tex/b.png', size: 4 }, { name: 'empty.bin', size: 0 }],
    main_file: 'a.gltf',
  });
  call.options.onProgress({ phase: 'receiving', done: 1, total: 14 });
  assert.equal(progress.length, 1);

  while (conn.chunks.length < 4) await new Promise((r) => setTimeout(r, 1));
  call.resolve({ scene_id: 'abc', name: 'a.gltf' });
  assert.deepEqual(await upload.result, { scene_id: 'abc', name: 'a.gltf' });
  assert.deepEqual(conn.chunks.map((c) => c.header), [
    { upload: 7, file: 0, offset: 0 }, { upload: 7, file: 0, offset: 4 },
    { upload: 7, file: 0, offset: 8 }, { upload: 7, file: 1, offset: 0 },
  ]);
  assert.deepEqual([...conn.chunks[0].bytes, ...conn.chunks[1].bytes, ...conn.chunks[2].bytes], [...a]);
  assert.deepEqual([...conn.chunks[3].bytes], [...b]);
  assert.ok(conn.waits >= 4, 'waits for the socket buffer before each chunk');
  assert.deepEqual(conn.notes, []);
});

test('sendUpload: waits while the socket buffers too much', async () => {
  const plan = { main: 'a.glb', files: [{ name: 'a.glb', size: 8, entry: { file: new Blob([bytes(8, 0)]) } }] };
  const conn = fakeConnection();
  conn.buffered = 100;
  const upload = sendUpload(conn, plan, { chunkBytes: 4, maxBufferedBytes: 50 });
  await new Promise((r) => setTimeout(r, 20));
  assert.equal(conn.chunks.length, 0);
  conn.buffered = 0;
  while (conn.chunks.length < 2) await new Promise((r) => setTimeout(r, 1));
  conn.calls[0].resolve({ scene_id: 's' });
  assert.equal((await upload.result).scene_id, 's');
});

test('sendUpload: an early error reply stops the chunks and is the result', async () => {
  const plan = { main: 'a.glb', files: [{ name: 'a.glb', size: 1000, entry: { file: new Blob([bytes(1000, 0)]) } }] };
  const conn = fakeConnection();
  const upload = sendUpload(conn, plan, { chunkBytes: 10 });
  const refused = Object.assign(new Error('upload bytes 1000 > 10'), { code: 'RESOURCE_EXHAUSTED' });
  conn.calls[0].reject(refused);
  await assert.rejects(upload.result, (e) => e === refused);
  assert.ok(conn.chunks.length < 100, `${conn.chunks.length} chunks sent after the refusal`);
});

test('sendUpload: cancel tells the gateway and stops sending', async () => {
  const plan = { main: 'a.glb', files: [{ name: 'a.glb', size: 1000, entry: { file: new Blob([bytes(1000, 0)]) } }] };
  const conn = fakeConnection();
  const upload = sendUpload(conn, plan, { chunkBytes: 10 });
  upload.cancel();
  upload.cancel();  // once is enough
  assert.deepEqual(conn.notes, [{ op: 'cancel', fields: { target: 7 } }]);
  conn.calls[0].reject(Object.assign(new Error('cancelled'), { code: 'CANCELLED' }));
  await assert.rejects(upload.result, /cancelled/);
  assert.ok(conn.chunks.length < 100);
});

test('sendUpload: a file that cannot be read cancels the upload on the gateway', async () => {
  const broken = { slice: () => ({ arrayBuffer: () => Promise.reject(new Error('file changed on disk')) }) };
  const plan = { main: 'a.glb', files: [{ name: 'a.glb', size: 10, entry: { file: broken } }] };
  const conn = fakeConnection();
  const upload = sendUpload(conn, plan);
  await assert.rejects(upload.result, /file changed on disk/);
  assert.deepEqual(conn.notes, [{ op: 'cancel', fields: { target: 7 } }]);
});

// ---- the scene id (scene.proto SceneInfo.scene_id), computed before uploading ----

const { subtle } = webcrypto;  // globalThis.crypto only from Node 19

/** A plan as planUpload makes them, from {name: bytes}. */
const planOf = (main, contents) => ({
  main,
  files: Object.entries(contents).map(([name, data]) => ({
    name, size: data.length, entry: { file: new Blob([data]) },
  })),
});

test('names sort by UTF-8 bytes, as the server\'s std::map does, not by UTF-16 code units', () => {
  const names = ['\u{1F600}.bin', '\uFF01.bin', 'caf\u00e9.png', 'a.gltf', 'Z.bin'];
  assert.deepEqual([...names].sort(compareUtf8), ['Z.bin', 'a.gltf', 'caf\u00e9.png', '\uFF01.bin', '\u{1F600}.bin']);
  // JavaScript's own order differs here: the surrogate pair (0xD83D) sorts before U+FF01.
  assert.deepEqual([...names].sort().slice(3), ['\u{1F600}.bin', '\uFF01.bin']);
  assert.equal(compareUtf8('ab', 'abc') < 0, true);
  assert.equal(compareUtf8('same', 'same'), 0);
});

test('the text hashed for the id: name, file hash, newline each, sorted; then the main file', () => {
  assert.equal(sceneIdText([{ name: 'b.bin', sha256: '22' }, { name: 'a.gltf', sha256: '11' }], 'a.gltf'),
    'a.gltf\n11\nb.bin\n22\nmain a.gltf\n');
});

test('the scene id of a multi-file glTF is the one the server and the CLI give it', async () => {
  // `tessera upload --json MultiUVTest/glTF/MultiUVTest.gltf` against tesserad printed this id.
  const dir = path.join(ASSETS, 'MultiUVTest/glTF');
  const names = ['MultiUVTest.gltf', 'MultiUVTest.bin', 'uv0.png', 'uv1.png'];
  const plan = planOf('MultiUVTest.gltf', Object.fromEntries(names.map((n) => [n, fs.readFileSync(path.join(dir, n))])));
  const seen = [];
  const id = await computeSceneId(plan, { subtle, onFile: (index, done) => seen.push([index, done]) });
  assert.equal(id, '6ee6ae2ad53a1f796384aa426563c203807a4c1e0c1ff089089cfa25d8a4e89a');
  assert.deepEqual(seen.map(([i]) => i), [0, 1, 2, 3]);
  assert.equal(seen.at(-1)[1], plan.files.reduce((sum, f) => sum + f.size, 0));
});

test('the scene id with names outside ASCII matches the definition (computed with Python\'s hashlib)', async () => {
  const text = (t) => new TextEncoder().encode(t);
  const plan = planOf('a.gltf', {
    'a.gltf': text('{"asset":{"version":"2.0"}}'),
    '\u{1F600}.bin': text('four'),
    '\uFF01.bin': text('three'),
    'caf\u00e9.png': text('two'),
    'Z.bin': text(''),
  });
  assert.equal(await computeSceneId(plan, { subtle }), 'd5987ef009488a6cea1586edd786ce2686c9b05158f573475c4139bee0c3d51a');
});

test('no WebCrypto (plain http on another host): computeSceneId says so (the page then uploads)', async () => {
  await assert.rejects(computeSceneId(planOf('a.glb', { 'a.glb': new Uint8Array(1) }), { subtle: null }), /WebCrypto/);
});

// Collecting the files of an upload: which file is the scene, which other files it needs and
// under which names the server expects them.
//
// The pure part (planUpload and its helpers) works on descriptors {path, size, file?, text?}:
// `path` relative and '/'-separated (a dropped folder keeps its structure), `text` the glTF
// JSON when the caller has it. Reading is injected, so `node --test` runs it without a
// browser. The browser part (collectDropped, collectInput, readSceneJson) turns DOM objects
// into descriptors.
//
// The server resolves a glTF's external URIs only inside the uploaded file set, by the
// %-decoded URI exactly as written (scene.proto UploadFile.name), so each needed file is sent
// under that name whatever its path on the user's disk.

/** An upload that cannot go ahead; `message` is a plain sentence for the user. */
export class UploadError extends Error {
  /** `details`: one line per file when there are several problems (the page lists them). */
  constructor(message, details = []) {
    super(message);
    this.name = 'UploadError';
    this.details = details;
  }
}

const SCENE_EXTENSIONS = ['.glb', '.gltf'];

/** '/'-separated, no leading '/' or './', no empty segments. */
export function normalizePath(path) {
  const segments = String(path).replace(/\\/g, '/').split('/');
  return segments.filter((s) => s !== '' && s !== '.').join('/');
}

export const basename = (path) => path.slice(path.lastIndexOf('/') + 1);
export const dirname = (path) => (path.includes('/') ? path.slice(0, path.lastIndexOf('/')) : '');
// Hidden files (e.g. macOS's "._Sponza.gltf" resource forks) are never the scene.
const isScene = (path) =>
  !basename(path).startsWith('.') && SCENE_EXTENSIONS.some((ext) => path.toLowerCase().endsWith(ext));
const isGltf = (path) => path.toLowerCase().endsWith('.gltf');

/**
 * The one .glb or .gltf among `entries` ({path}), or an UploadError saying why there is not
 * exactly one.
 */
export function findMainFile(entries) {
  const scenes = entries.filter((e) => isScene(e.path));
  if (scenes.length === 1) return scenes[0];
  if (scenes.length === 0) {
    const what = entries.length === 1 ? `'${entries[0].path}'` : `${entries.length} files`;
    throw new UploadError(
      `There is no .glb or .gltf file among ${what}; a scene upload needs exactly one.`);
  }
  const names = scenes.map((e) => `'${e.path}'`).join(', ');
  throw new UploadError(
    `There are ${scenes.length} scene files (${names}); upload one scene at a time.`);
}

/**
 * %-decoding exactly as the server does it (RFC 3986: %XX with two hex digits becomes that
 * byte, anything else stays as written, '+' stays '+'), then read as UTF-8. Never throws,
 * unlike decodeURIComponent on a stray '%'.
 */
export function percentDecode(uri) {
  const bytes = new TextEncoder().encode(uri);
  const out = [];
  const hex = (b) => (b >= 48 && b <= 57) || (b >= 65 && b <= 70) || (b >= 97 && b <= 102);
  for (let i = 0; i < bytes.length; i++) {
    if (bytes[i] === 37 && i + 2 < bytes.length && hex(bytes[i + 1]) && hex(bytes[i + 2])) {
      out.push(parseInt(String.fromCharCode(bytes[i + 1], bytes[i + 2]), 16));
      i += 2;
    } else {
      out.push(bytes[i]);
    }
  }
  return new TextDecoder().decode(new Uint8Array(out));
}

/**
 * The external files a glTF JSON document refers to: the %-decoded URIs of buffers[] and
 * images[], data: URIs left out, each once, in document order, with where it is used.
 */
export function externalUris(gltf) {
  const found = new Map();  // decoded uri -> {uri, uses: ['buffers[0]', ...]}
  for (const array of ['buffers', 'images']) {
    const items = Array.isArray(gltf?.[array]) ? gltf[array] : [];
    items.forEach((item, index) => {
      const uri = item?.uri;
      if (typeof uri !== 'string' || uri.startsWith('data:')) return;
      const decoded = percentDecode(uri);
      if (!found.has(decoded)) found.set(decoded, { uri: decoded, uses: [] });
      found.get(decoded).uses.push(`${array}[${index}]`);
    });
  }
  return [...found.values()];
}

/** Why the server could not take a file under this name (see UploadFile.name), or null. */
export function uriProblem(uri) {
  if (uri === '') return 'it is empty';
  if (/^[a-zA-Z][a-zA-Z0-9+.-]*:/.test(uri)) {
    return 'it is a URL, and the server only reads uploaded files';
  }
  if (uri.startsWith('/')) return 'it is an absolute path';
  if (uri.includes('\\')) return "it contains a backslash (glTF paths use '/')";
  const segments = uri.split('/');
  if (segments.includes('..')) return "it points outside the glTF's folder ('..')";
  if (segments.includes('.') || segments.includes('')) {
    return "it has a '.' or empty path segment, which the server does not accept";
  }
  return null;
}

/**
 * The file a URI refers to: the entry at exactly `dir/uri`, else the only entry with the
 * same basename. Returns {entry} or {problem: plain words}.
 */
export function resolveUri(uri, dir, entries) {
  const wanted = dir ? `${dir}/${uri}` : uri;
  const exact = entries.find((e) => e.path === wanted);
  if (exact) return { entry: exact };
  const name = basename(uri);
  const same = entries.filter((e) => basename(e.path) === name);
  if (same.length === 1) return { entry: same[0] };
  if (same.length > 1) {
    const paths = same.map((e) => `'${e.path}'`).join(', ');
    return { problem: `several files are called '${name}' (${paths}) and none is at '${wanted}'` };
  }
  return { problem: 'it was not among the files' };
}

/**
 * Plans an upload from file descriptors [{path, size, ...}] (paths relative, '/'-separated).
 * `readJson(entry)` returns (or resolves to) the main file's glTF JSON text; by default the
 * entry's `text`. Resolves to
 *   {main: name, files: [{name, size, entry}], unused: [paths]}
 * with the main file first and every other file named by the URI the glTF uses; throws an
 * UploadError naming every missing or unusable file.
 */
export async function planUpload(entries, readJson = (e) => e.text) {
  const all = entries.map((e) => ({ ...e, path: normalizePath(e.path) }));
  const mainEntry = findMainFile(all);
  const mainName = basename(mainEntry.path);

  let text;
  try {
    text = await readJson(mainEntry);
  } catch (err) {
    throw new UploadError(`${mainName} could not be read: ${err?.message ?? err}.`);
  }
  let gltf = null;
  if (text != null) {
    try {
      gltf = JSON.parse(text);
    } catch (err) {
      throw new UploadError(`${mainName} is not valid glTF JSON (${err.message}).`);
    }
  } else if (isGltf(mainEntry.path)) {
    throw new UploadError(`${mainName} could not be read.`);
  }

  const dir = dirname(mainEntry.path);
  const others = all.filter((e) => e !== mainEntry);
  const files = [{ name: mainName, size: mainEntry.size, entry: mainEntry }];
  const problems = [];
  let missing = 0;
  for (const { uri } of externalUris(gltf)) {
    const bad = uriProblem(uri);
    if (bad) {
      problems.push(`${mainName} needs '${uri}', which cannot be uploaded: ${bad}.`);
      continue;
    }
    const found = resolveUri(uri, dir, others);
    if (found.entry) {
      files.push({ name: uri, size: found.entry.size, entry: found.entry });
    } else if (found.problem === 'it was not among the files') {
      problems.push(`${mainName} needs '${uri}', which was not among the files.`);
      ++missing;
    } else {
      problems.push(`${mainName} needs '${uri}', but ${found.problem}.`);
    }
  }
  if (problems.length === 1) throw new UploadError(problems[0]);
  if (problems.length > 1) throw new UploadError(missingSummary(mainName, missing, problems.length - missing), problems);

  const used = new Set(files.map((f) => f.entry));
  const unused = all.filter((e) => !used.has(e)).map((e) => e.path);
  return { main: mainName, files, unused };
}

/**
 * One sentence for many problems (a .gltf chosen without its files names every texture):
 * what is missing and how to fix it; the files themselves go in the error's details.
 */
function missingSummary(mainName, missing, other) {
  const parts = [];
  if (missing > 0) {
    parts.push(`${missing} ${missing === 1 ? 'file that was' : 'files that were'} not among the files chosen`);
  }
  if (other > 0) parts.push(`${other} ${other === 1 ? 'file' : 'files'} that cannot be used`);
  const fix = missing > 0
    ? ' Choose the .gltf together with all its files, or drop its whole folder.'
    : '';
  return `${mainName} needs ${parts.join(' and ')}.${fix}`;
}

/**
 * Checks a plan against ServerInfo.limits (max_upload_files, max_upload_bytes; absent or 0
 * means no limit) and throws an UploadError in plain words when it is over one.
 */
export function checkLimits(plan, limits = {}) {
  const maxFiles = Number(limits.max_upload_files) || 0;
  const maxBytes = Number(limits.max_upload_bytes) || 0;
  if (maxFiles > 0 && plan.files.length > maxFiles) {
    throw new UploadError(
      `${plan.main} needs ${plan.files.length} files; the server takes at most ${maxFiles} per upload.`);
  }
  const total = plan.files.reduce((sum, f) => sum + f.size, 0);
  if (maxBytes > 0 && total > maxBytes) {
    throw new UploadError(
      `${plan.main} and its files hold ${exactBytes(total)}; ` +
      `the server takes at most ${exactBytes(maxBytes)} per upload.`);
  }
}

/** Bytes as "812 B", "3.4 KB", "12.0 MB" (decimal units). */
export function formatBytes(n) {
  if (!Number.isFinite(n)) return '?';
  if (n < 1000) return `${n} B`;
  if (n < 1e6) return `${(n / 1e3).toFixed(1)} KB`;
  if (n < 1e9) return `${(n / 1e6).toFixed(1)} MB`;
  return `${(n / 1e9).toFixed(2)} GB`;
}

// ---- the scene id, computed before uploading (scene.proto SceneInfo.scene_id) ----

const utf8 = new TextEncoder();

/**
 * Orders names as the server does (std::map<std::string>: byte-wise on UTF-8). JavaScript's
 * own string order compares UTF-16 code units, which puts characters past U+FFFF before
 * U+E000..U+FFFF; byte order does not.
 */
export function compareUtf8(a, b) {
  const x = utf8.encode(a);
  const y = utf8.encode(b);
  const n = Math.min(x.length, y.length);
  for (let i = 0; i < n; i++) if (x[i] !== y[i]) return x[i] - y[i];
  return x.length - y.length;
}

const hex = (buffer) => [...new Uint8Array(buffer)].map((b) => b.toString(16).padStart(2, '0')).join('');

/**
 * The text the scene id hashes: for every file sorted by name (UTF-8 bytes),
 * `name "\n" sha256hex "\n"`, then `"main " main "\n"`. `hashes`: [{name, sha256}].
 */
export function sceneIdText(hashes, main) {
  const sorted = [...hashes].sort((a, b) => compareUtf8(a.name, b.name));
  return `${sorted.map((h) => `${h.name}\n${h.sha256}\n`).join('')}main ${main}\n`;
}

/**
 * The scene id the server will give a planned upload ({main, files: [{name, size, entry}]}):
 * lowercase hex SHA-256 of sceneIdText over the files' SHA-256s, the same content hash as
 * tesserad's and the CLI's. One digest per file (WebCrypto's digest takes the whole file);
 * `onFile(index, bytesDone)` after each. `subtle` is WebCrypto's SubtleCrypto (only in secure
 * contexts: https and localhost); `read(file)` gives a file's bytes.
 */
export async function computeSceneId(plan, {
  subtle = globalThis.crypto?.subtle,
  read = (file) => file.entry.file.arrayBuffer(),
  onFile = () => {},
} = {}) {
  if (!subtle) throw new Error('WebCrypto is not available here (it needs https or localhost)');
  const hashes = [];
  let done = 0;
  for (const [index, file] of plan.files.entries()) {
    const bytes = await read(file);
    hashes.push({ name: file.name, sha256: hex(await subtle.digest('SHA-256', bytes)) });
    done += file.size;
    onFile(index, done);
  }
  return hex(await subtle.digest('SHA-256', utf8.encode(sceneIdText(hashes, plan.main))));
}

// ---- sending (protocol: clients/web/README.md, "Uploads") ----

/** Bytes of file data in one chunk message, and the socket buffer level that pauses sending. */
export const CHUNK_BYTES = 256 * 1024;
export const MAX_BUFFERED_BYTES = 4 * 1024 * 1024;

/**
 * Sends a planned upload over `conn` (protocol.js Connection: call, notify, sendBinary,
 * waitForBuffer): the `upload` request, then each file as chunk messages in order, waiting
 * while the socket buffers more than `maxBufferedBytes`. Returns {id, result, cancel}:
 * `result` resolves to the SceneInfo of the reply, or rejects with its error (a cancelled
 * upload: the gateway's CANCELLED reply; a file that cannot be read: that error, after the
 * upload is cancelled on the gateway).
 */
export function sendUpload(conn, plan, {
  onProgress, chunkBytes = CHUNK_BYTES, maxBufferedBytes = MAX_BUFFERED_BYTES,
} = {}) {
  const files = plan.files.map(({ name, size }) => ({ name, size }));
  const call = conn.call('upload', { files, main_file: plan.main }, { onProgress });
  let done = false;  // a reply came (success or error), or the upload was cancelled
  const replied = call.result.finally(() => { done = true; });
  replied.catch(() => {});  // observed below; this only keeps an early error from going unhandled

  const sendAll = async () => {
    for (const [index, file] of plan.files.entries()) {
      for (let offset = 0; offset < file.size; offset += chunkBytes) {
        if (done) return;
        await conn.waitForBuffer(maxBufferedBytes);
        const end = Math.min(file.size, offset + chunkBytes);
        const data = await file.entry.file.slice(offset, end).arrayBuffer();
        if (done) return;
        // Not sent means not connected: the reply (rejected for the lost connection) says so.
        if (!conn.sendBinary({ upload: call.id, file: index, offset }, data)) return;
      }
    }
  };
  const cancel = () => {
    if (done) return;
    done = true;
    conn.notify('cancel', { target: call.id });
  };
  const result = sendAll().then(() => replied, (err) => {
    // A lost connection rejects the reply too, with its own words; anything else (an
    // unreadable file) would leave the gateway waiting, so the upload is cancelled there.
    if (done) return replied;
    cancel();
    throw err;
  });
  return { id: call.id, result, cancel };
}

/** "1.2 MB (1,234,567 bytes)": rounded for reading, exact for comparing. */
const exactBytes = (n) => `${formatBytes(n)} (${n.toLocaleString('en-US')} bytes)`;

// ---- reading (Blob/File: browsers and Node >= 18) ----

const GLB_MAGIC = 0x46546c67;       // "glTF"
const GLB_CHUNK_JSON = 0x4e4f534a;  // "JSON"

/**
 * The JSON text of a scene file (a Blob): a .gltf's whole text, or a .glb's JSON chunk, read
 * without loading the binary chunk. Throws an UploadError for a file that is not a GLB.
 */
export async function readSceneJson(blob, name) {
  if (isGltf(name)) return blob.text();
  const head = new DataView(await blob.slice(0, 20).arrayBuffer());
  if (head.byteLength < 20 || head.getUint32(0, true) !== GLB_MAGIC) {
    throw new UploadError(`${name} is not a binary glTF (.glb) file.`);
  }
  const jsonLength = head.getUint32(12, true);
  if (head.getUint32(16, true) !== GLB_CHUNK_JSON || 20 + jsonLength > blob.size) {
    throw new UploadError(`${name} is not a valid .glb: its first chunk is not the JSON chunk.`);
  }
  return blob.slice(20, 20 + jsonLength).text();
}

/** Descriptors for the files of an <input type=file> (a folder pick keeps its paths). */
export function collectInput(fileList) {
  return [...fileList].map((file) => ({
    path: normalizePath(file.webkitRelativePath || file.name),
    size: file.size,
    file,
  }));
}

/**
 * Descriptors for what was dropped: files, and folders walked recursively with
 * webkitGetAsEntry. Must be called synchronously in the drop handler (the item list is
 * emptied when the handler returns); the walk itself is asynchronous.
 */
export function collectDropped(dataTransfer) {
  const roots = [...(dataTransfer.items ?? [])]
    .filter((item) => item.kind === 'file')
    .map((item) => item.webkitGetAsEntry?.())
    .filter(Boolean);
  if (roots.length === 0) return Promise.resolve(collectInput(dataTransfer.files ?? []));
  return Promise.all(roots.map(walkEntry)).then((lists) => lists.flat());
}

async function walkEntry(entry) {
  if (entry.isFile) {
    const file = await new Promise((resolve, reject) => entry.file(resolve, reject));
    return [{ path: normalizePath(entry.fullPath || file.name), size: file.size, file }];
  }
  if (!entry.isDirectory) return [];
  const reader = entry.createReader();
  const children = [];
  // readEntries hands out a directory in batches; an empty batch means the end.
  for (;;) {
    const batch = await new Promise((resolve, reject) => reader.readEntries(resolve, reject));
    if (batch.length === 0) break;
    children.push(...batch);
  }
  const lists = await Promise.all(children.map(walkEntry));
  return lists.flat();
}

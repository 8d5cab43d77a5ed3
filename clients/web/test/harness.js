// Test harness: a real tesserad and a real gateway on free ports, and a WebSocket client that
// speaks the gateway's protocol. Used by test/*.test.js here and by tests/web (the browser tests).
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import WebSocket from 'ws';

const HERE = path.dirname(fileURLToPath(import.meta.url));
export const WEB_DIR = path.resolve(HERE, '..');
export const REPO = path.resolve(WEB_DIR, '../..');

export const TESSERAD = process.env.TESSERAD || path.join(REPO, 'build/default/server/tesserad');
export const ASSETS = process.env.TESSERA_ASSETS_DIR || path.resolve(REPO, '../shared/assets');

async function waitForFile(file, proc, what, timeoutMs = 60_000) {
  const start = Date.now();
  while (Date.now() - start < timeoutMs) {
    if (proc.exitCode !== null) throw new Error(`${what} exited with ${proc.exitCode} before it was ready`);
    try {
      const text = fs.readFileSync(file, 'utf8').trim();
      if (text) return Number(text);
    } catch {}
    await new Promise((r) => setTimeout(r, 100));
  }
  throw new Error(`${what} did not write ${file} within ${timeoutMs} ms`);
}

function spawnLogged(cmd, args, logFile, env = process.env) {
  const out = fs.openSync(logFile, 'w');
  const proc = spawn(cmd, args, { stdio: ['ignore', out, out], env });
  fs.closeSync(out);
  return proc;
}

async function stopProcess(proc) {
  if (proc.exitCode !== null || proc.signalCode !== null) return;
  const exited = new Promise((r) => proc.once('exit', r));
  proc.kill('SIGTERM');
  const timer = setTimeout(() => proc.kill('SIGKILL'), 10_000);
  await exited;
  clearTimeout(timer);
}

/** Starts tesserad on a free port. */
export async function startTesserad(args = []) {
  if (!fs.existsSync(TESSERAD)) throw new Error(`no tesserad at ${TESSERAD} (build it, or set TESSERAD)`);
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-web-test-'));
  const portFile = path.join(dir, 'port');
  const logFile = path.join(dir, 'tesserad.log');
  const proc = spawnLogged(TESSERAD, ['--listen=127.0.0.1:0', `--port_file=${portFile}`, '--log_level=warn', ...args], logFile);
  const port = await waitForFile(portFile, proc, 'tesserad');
  return {
    port,
    address: `127.0.0.1:${port}`,
    proc,
    log: () => fs.readFileSync(logFile, 'utf8'),
    async stop() {
      await stopProcess(proc);
      fs.rmSync(dir, { recursive: true, force: true });
    },
  };
}

/** Starts the gateway (gateway.js) on a free port, talking to `server`. */
export async function startGateway(server, args = []) {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'tessera-web-gw-'));
  const portFile = path.join(dir, 'port');
  const logFile = path.join(dir, 'gateway.log');
  const proc = spawnLogged(process.execPath,
    [path.join(WEB_DIR, 'gateway.js'), '--listen', '127.0.0.1:0', '--port-file', portFile, '--server', server, ...args],
    logFile);
  const port = await waitForFile(portFile, proc, 'the gateway');
  return {
    port,
    url: `http://127.0.0.1:${port}/`,
    wsUrl: `ws://127.0.0.1:${port}/ws`,
    proc,
    log: () => fs.readFileSync(logFile, 'utf8'),
    async stop() {
      await stopProcess(proc);
      fs.rmSync(dir, { recursive: true, force: true });
    },
  };
}

/** Splits a binary gateway message into { header, payload }. */
export function splitBinary(buf) {
  const n = buf.readUInt32LE(0);
  return { header: JSON.parse(buf.subarray(4, 4 + n).toString('utf8')), payload: buf.subarray(4 + n) };
}

export function binaryMessage(header, payload) {
  const json = Buffer.from(JSON.stringify(header));
  const prefix = Buffer.alloc(4);
  prefix.writeUInt32LE(json.length);
  return Buffer.concat([prefix, json, payload]);
}

/** A page, as far as the protocol goes: requests by id, and every message it got. */
export class PageClient {
  static async connect(url, options = {}) {
    const ws = new WebSocket(url, options);
    const client = new PageClient(ws);
    await new Promise((resolve, reject) => {
      ws.once('open', resolve);
      ws.once('error', reject);
      ws.once('unexpected-response', (_req, res) => reject(new Error(`HTTP ${res.statusCode}`)));
    });
    return client;
  }

  constructor(ws) {
    this.ws = ws;
    this.nextId = 1;
    this.messages = []; // JSON messages without an id (hello, progress, stream_end, error)
    this.frames = []; // { header, payload } of binary messages
    this.replies = new Map();
    this.waiters = [];
    ws.on('message', (data, isBinary) => {
      if (isBinary) this.frames.push(splitBinary(data));
      else {
        const msg = JSON.parse(data.toString());
        if (msg.id !== undefined && msg.ok !== undefined) this.replies.get(msg.id)?.(msg);
        else this.messages.push(msg);
      }
      for (const w of [...this.waiters]) w();
    });
  }

  /** Sends {id, op, ...fields}; resolves with the reply ({ok, result} or {ok: false, error}). */
  request(op, fields = {}, id = this.nextId++) {
    return new Promise((resolve) => {
      this.replies.set(id, (msg) => { this.replies.delete(id); resolve(msg); });
      this.ws.send(JSON.stringify({ id, op, ...fields }));
    });
  }

  sendRaw(data) {
    this.ws.send(data);
  }

  /** Resolves when predicate() is truthy (checked after every message), with its value. */
  waitFor(predicate, what, timeoutMs = 60_000) {
    return new Promise((resolve, reject) => {
      const check = () => {
        const value = predicate();
        if (value) {
          cleanup();
          resolve(value);
        }
      };
      const timer = setTimeout(() => { cleanup(); reject(new Error(`timed out waiting for ${what}`)); }, timeoutMs);
      const cleanup = () => {
        clearTimeout(timer);
        this.waiters = this.waiters.filter((w) => w !== check);
      };
      this.waiters.push(check);
      check();
    });
  }

  close() {
    this.ws.close();
  }
}

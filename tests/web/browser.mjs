// What the browser tests (viewer.test.mjs, video.test.mjs) share: a free loopback port, headless
// Debian Chromium (playwright-core from clients/web), a page's script errors collected, and
// waiting for the frame a page draws.
import net from 'node:net';
import path from 'node:path';
import { createRequire } from 'node:module';
import { WEB_DIR } from '../../clients/web/test/harness.js';

const require = createRequire(path.join(WEB_DIR, 'package.json'));
const { chromium } = require('playwright-core');

export const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';

/** A TCP port free on 127.0.0.1 now (a gateway started again can come back on it). */
export async function freePort() {
  return new Promise((resolve) => {
    const s = net.createServer().listen(0, '127.0.0.1', () => {
      const { port } = s.address();
      s.close(() => resolve(port));
    });
  });
}

/** Headless Chromium as the tests run it: no sandbox (containers), no GPU, no background traffic. */
export function launchChromium() {
  return chromium.launch({
    executablePath: CHROMIUM,
    args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
      '--disable-sync', '--no-first-run', '--disable-quic'],
  });
}

/** Collects page `p`'s script errors and console errors into `errors`. */
export function watchErrors(p, errors) {
  p.on('pageerror', (err) => errors.push(`pageerror: ${err.message}`));
  p.on('console', (msg) => { if (msg.type() === 'error') errors.push(`console: ${msg.text()}`); });
}

/** The newest frame page `p` drew (its header), or null. */
export function pageLastFrame(p) {
  return p.evaluate(() => window.tessera.lastFrame);
}

/** Polls page `p` until it has drawn a frame for which `predicate(frame)` holds; returns it. */
export async function waitForPageFrame(p, predicate, what, timeout = 60_000) {
  const start = Date.now();
  let frame = null;
  while (Date.now() - start < timeout) {
    frame = await pageLastFrame(p);
    if (frame !== null && predicate(frame)) return frame;
    await new Promise((r) => setTimeout(r, 50));
  }
  const errors = await p.evaluate(() => window.tessera.errors);
  throw new Error(`no frame with ${what}: last frame ${JSON.stringify(frame)?.slice(0, 300)}; errors ${JSON.stringify(errors)}`);
}

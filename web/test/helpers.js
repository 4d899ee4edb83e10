// Helpers of the browser tests: a static server that logs every request, Debian's Chromium
// through playwright-core, the native `riseg` binary, and a PNG reader for riseg's masks.

import { execFileSync } from 'node:child_process';
import { createHash } from 'node:crypto';
import { cpSync, mkdtempSync, readFileSync, statSync } from 'node:fs';
import { createServer } from 'node:http';
import { tmpdir } from 'node:os';
import { extname, join, normalize } from 'node:path';
import { inflateSync } from 'node:zlib';
import { chromium } from 'playwright-core';

const TYPES = {
  '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css', '.json': 'application/json',
  '.wasm': 'application/wasm', '.png': 'image/png',
};

// Serves `root` on 127.0.0.1 (a free port); `requests` lists every path asked for, in order.
export async function serve(root) {
  const requests = [];
  const server = createServer((req, res) => {
    const path = decodeURIComponent(new URL(req.url, 'http://x').pathname);
    requests.push(path);
    const file = normalize(join(root, path === '/' ? 'index.html' : path));
    if (!file.startsWith(root) || !statSync(file, { throwIfNoEntry: false })?.isFile()) {
      res.writeHead(404).end();
      return;
    }
    res.writeHead(200, { 'content-type': TYPES[extname(file)] ?? 'application/octet-stream' });
    res.end(readFileSync(file));
  });
  await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
  return { url: `http://127.0.0.1:${server.address().port}/`, requests, close: () => server.close() };
}

// Debian's Chromium (never a downloaded browser) with the flags of ../shared/TOOLCHAIN.md and
// a fresh profile.
export async function launchChromium() {
  const profile = mkdtempSync(join(tmpdir(), 'riseg-chromium-'));
  return chromium.launchPersistentContext(profile, {
    executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
    headless: true,
    viewport: { width: 1440, height: 900 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
}

// Runs the native riseg binary (RISEG_BIN, built by web/test.sh).
export function riseg(...args) {
  const bin = process.env.RISEG_BIN;
  if (!bin) throw new Error('RISEG_BIN is not set: run web/test.sh');
  return execFileSync(bin, args, { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] });
}

export function tempDir(tag) {
  return mkdtempSync(join(tmpdir(), `riseg-web-${tag}-`));
}

// Copies the scene folder `scene` to DATASET/scene_000 (the name `riseg eval` wants).
export function asDataset(scene, tag) {
  const dataset = tempDir(tag);
  cpSync(scene, join(dataset, 'scene_000'), { recursive: true });
  return join(dataset, 'scene_000');
}

// The pixels of a greyscale PNG (8- or 16-bit, not interlaced) as a Uint16Array.
export function readGrayPng(path) {
  const bytes = readFileSync(path);
  let pos = 8;
  let width; let height; let depth;
  const idat = [];
  while (pos < bytes.length) {
    const len = bytes.readUInt32BE(pos);
    const type = bytes.toString('latin1', pos + 4, pos + 8);
    const data = bytes.subarray(pos + 8, pos + 8 + len);
    if (type === 'IHDR') {
      [width, height, depth] = [data.readUInt32BE(0), data.readUInt32BE(4), data[8]];
      if (data[9] !== 0 || data[12] !== 0 || (depth !== 8 && depth !== 16)) {
        throw new Error(`${path}: not an 8/16-bit greyscale, non-interlaced PNG`);
      }
    } else if (type === 'IDAT') idat.push(data);
    pos += 12 + len;
  }
  const raw = inflateSync(Buffer.concat(idat));
  const bpp = depth / 8;
  const stride = width * bpp;
  const rows = Buffer.alloc(stride * height);
  for (let y = 0; y < height; y++) {
    const filter = raw[y * (stride + 1)];
    const line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let i = 0; i < stride; i++) {
      const a = i >= bpp ? rows[y * stride + i - bpp] : 0;
      const b = y > 0 ? rows[(y - 1) * stride + i] : 0;
      const c = i >= bpp && y > 0 ? rows[(y - 1) * stride + i - bpp] : 0;
      const p = a + b - c;
      const [pa, pb, pc] = [Math.abs(p - a), Math.abs(p - b), Math.abs(p - c)];
      const paeth = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      const add = [0, a, b, (a + b) >> 1, paeth][filter];
      if (add === undefined) throw new Error(`${path}: bad PNG filter ${filter}`);
      rows[y * stride + i] = (line[i] + add) & 0xff;
    }
  }
  const out = new Uint16Array(width * height);
  for (let i = 0; i < out.length; i++) {
    out[i] = depth === 16 ? (rows[2 * i] << 8) | rows[2 * i + 1] : rows[i];
  }
  return out;
}

// SHA-256 of 16-bit labels as little-endian bytes (what the page computes).
export function digest(u16) {
  const le = Buffer.alloc(u16.length * 2);
  u16.forEach((v, i) => le.writeUInt16LE(v, 2 * i));
  return createHash('sha256').update(le).digest('hex');
}

// Native `riseg run` on the scene folder `dir`: the digest of every frame's mask.
export function nativeDigests(dir, frames) {
  const pred = tempDir('pred');
  riseg('run', '--scene', dir, '--out', pred);
  const name = dir.split('/').pop();
  const digests = [];
  for (let t = 0; t < frames; t++) {
    digests.push(digest(readGrayPng(join(pred, name, 'label', `${String(t).padStart(6, '0')}.png`))));
  }
  return { pred, digests };
}

// `riseg eval --json` of the predictions `pred` against the dataset holding `dir`.
export function nativeEval(dir, pred) {
  const json = join(tempDir('eval'), 'eval.json');
  riseg('eval', '--gt', join(dir, '..'), '--pred', pred, '--json', json);
  return JSON.parse(readFileSync(json, 'utf8'));
}

// Drops the folder `dir` on the page as a user would (Chromium's drag-and-drop input, so the
// page sees a directory entry it has to walk).
export async function dropFolder(page, dir) {
  const cdp = await page.context().newCDPSession(page);
  const data = { items: [], files: [dir], dragOperationsMask: 1 };
  for (const type of ['dragEnter', 'dragOver', 'drop']) {
    await cdp.send('Input.dispatchDragEvent', { type, x: 600, y: 300, data });
  }
  await cdp.detach();
}

// Runs the open scene in the page to its end (the play button) and returns window.riseg.
export async function playToEnd(page) {
  await page.click('#play');
  await page.waitForFunction(() => ['done', 'error'].includes(window.riseg.status)
    && window.riseg.frames.length > 0, null, { timeout: 600_000 });
  return page.evaluate(() => ({
    status: window.riseg.status,
    error: window.riseg.error,
    scene: window.riseg.scene,
    frames: window.riseg.frames.map((f) => ({ t: f.t, digest: f.digest, time: f.time,
      metrics: f.metrics && { static: [...f.metrics.static], riseg: [...f.metrics.riseg] } })),
  }));
}

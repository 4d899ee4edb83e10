// Browser tests of the riseg demo in Debian's Chromium (web/test.sh builds and runs them):
// a bundled scene and a scene generated now run to the end in the page; every mask is
// computed in the browser (no mask is fetched), bit-identical to native `riseg run`; the
// metrics shown equal `riseg eval`'s; a corrupt PNG or a missing scene_camera.json gives an
// error naming the file and the page stays usable. A screenshot goes to $ARTIFACTS
// (default web/test-artifacts/).

import assert from 'node:assert/strict';
import { cpSync, mkdirSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { after, before, test } from 'node:test';
import { fileURLToPath } from 'node:url';
import {
  asDataset, dropFolder, launchChromium, nativeDigests, nativeEval, playToEnd, riseg, serve,
  tempDir,
} from './helpers.js';

const WEB = dirname(dirname(fileURLToPath(import.meta.url)));
const ARTIFACTS = process.env.ARTIFACTS ?? join(WEB, 'test-artifacts');
const INDEX = JSON.parse(readFileSync(join(WEB, 'scenes', 'index.json'), 'utf8'));

let server;
let browser;
let page;
const consoleErrors = [];

before(async () => {
  server = await serve(WEB);
  browser = await launchChromium();
  page = await browser.newPage();
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
  page.on('pageerror', (e) => consoleErrors.push(e.message));
  await page.goto(server.url);
  await page.waitForFunction(() => window.riseg.status === 'ready', null, { timeout: 60_000 });
});

after(async () => {
  await browser?.close();
  server?.close();
});

// The metrics the page shows for each frame equal `riseg eval`'s rows (one image per push),
// to the last bit: both are 100 × the same f64.
function assertMetricsEqual(frames, report) {
  assert.equal(report.pushes.length, frames.length);
  for (const [t, f] of frames.entries()) {
    const row = report.pushes[t];
    assert.equal(row.push, t);
    const m = f.metrics.riseg;
    const page = [m[0], m[1], m[2], m[3], m[4], m[5], m[6]].map((v) => 100 * v);
    const native = [row.overlap.p, row.overlap.r, row.overlap.f,
      row.boundary.p, row.boundary.r, row.boundary.f, row.objects_f75_pct];
    assert.deepEqual(page, native, `frame ${t}: page metrics differ from riseg eval`);
  }
}

// The page's mask digests equal native `riseg run`'s, and its metrics `riseg eval`'s.
function assertMatchesNative(sceneDir, frames) {
  const { pred, digests } = nativeDigests(sceneDir, frames.length);
  assert.deepEqual(frames.map((f) => f.digest), digests, 'wasm masks differ from riseg run');
  assertMetricsEqual(frames, nativeEval(sceneDir, pred));
}

test('a bundled scene runs to the end in the browser, bit-identical to riseg run, no mask fetched', async () => {
  for (const scene of INDEX.scenes) {
    await page.selectOption('#scene', scene.name);
    await page.waitForFunction((title) => window.riseg.scene === title && window.riseg.status === 'ready',
      scene.title);
    const before = server.requests.length;
    const run = await playToEnd(page);
    assert.equal(run.status, 'done', run.error ?? '');
    assert.equal(run.frames.length, 3, 'frames 0, 1, 2');
    // Everything was fetched before the run: the masks were computed, not downloaded.
    assert.deepEqual(server.requests.slice(before), [], 'requests during the run');
    for (const f of run.frames) {
      assert.ok(f.time.update >= 0 && f.time.segment > 0, `stage times of frame ${f.t}`);
      assert.equal(f.t > 0, f.time.flow > 0, `flow time of frame ${f.t}`);
    }
    assertMatchesNative(asDataset(join(WEB, 'scenes', scene.name), scene.name), run.frames);
    if (scene.name === 'packed') {
      mkdirSync(ARTIFACTS, { recursive: true });
      await page.screenshot({ path: join(ARTIFACTS, 'packed-end.png'), fullPage: true });
    }
  }
  // Every request was the page, the module or a scene input listed in index.json.
  const allowed = new Set(['/', '/main.js', '/style.css', '/pkg/riseg_wasm.js', '/pkg/riseg_wasm_bg.wasm',
    '/scenes/index.json', ...INDEX.scenes.flatMap((s) => s.files.map((f) => `/scenes/${s.name}/${f}`))]);
  const unexpected = server.requests.filter((r) => !allowed.has(r));
  assert.deepEqual(unexpected, [], 'requests other than the page, the module and scene inputs');
  assert.deepEqual(consoleErrors, []);
});

test('a scene generated now, picked as a folder, gives the masks and metrics of riseg run and eval', async () => {
  const out = tempDir('gen');
  riseg('gen', '--layout', 'packed', '--scenes', '1', '--pushes', '2', '--seed', '7', '--out', out);
  const dir = join(out, 'scene_000');
  rmSync(join(dir, 'flow'), { recursive: true }); // not read by the page; keeps the upload small
  await page.setInputFiles('#folder', dir); // the folder picker
  await page.waitForFunction(() => window.riseg.scene === 'scene_000 (your folder)');
  const run = await playToEnd(page);
  assert.equal(run.status, 'done', run.error ?? '');
  assert.equal(run.frames.length, 3);
  assertMatchesNative(dir, run.frames);
});

test('a corrupt PNG or a missing scene_camera.json dropped on the page is an error naming the file; the page stays usable', async () => {
  const good = join(tempDir('src'), 'scene_bad');
  riseg('gen', '--layout', 'loose', '--scenes', '1', '--pushes', '1', '--seed', '3', '--out', dirname(good));
  cpSync(join(dirname(good), 'scene_000'), good, { recursive: true });
  rmSync(join(good, 'flow'), { recursive: true });
  await page.selectOption('#scene', INDEX.scenes[0].name);
  await page.waitForFunction((title) => window.riseg.scene === title, INDEX.scenes[0].title);

  const cases = [
    ['corrupt PNG', (d) => writeFileSync(join(d, 'rgb', '000001.png'), 'not a png'),
      'scene_bad/rgb/000001.png: corrupt or unsupported PNG'],
    ['missing camera', (d) => rmSync(join(d, 'scene_camera.json')),
      'scene_bad/scene_camera.json: not found'],
  ];
  for (const [name, damage, message] of cases) {
    const bad = join(tempDir(name.replace(' ', '-')), 'scene_bad');
    cpSync(good, bad, { recursive: true });
    damage(bad);
    const previous = await page.evaluate(() => window.riseg.error);
    await dropFolder(page, bad);
    await page.waitForFunction((prev) => window.riseg.error !== prev, previous);
    assert.equal(await page.isVisible('#error'), true, `${name}: error shown`);
    const shown = await page.textContent('#error');
    assert.ok(shown.includes(message), `${name}: the error "${shown}" does not say "${message}"`);
    // Still usable: the scene that was open stays open and runs.
    assert.equal(await page.evaluate(() => window.riseg.scene), INDEX.scenes[0].title, name);
    await page.click('#restart');
    await page.click('#step');
    await page.waitForFunction(() => window.riseg.frames.length === 1 && window.riseg.status === 'ready');
  }
  // Dropping a good scene opens it and clears the error.
  await dropFolder(page, good);
  await page.waitForFunction(() => window.riseg.scene === 'scene_bad (dropped)');
  assert.equal(await page.isHidden('#error'), true);
});

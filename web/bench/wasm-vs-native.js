// Browser side of web/bench.sh: the same protocol as wasm/examples/bench_stages.rs (open the
// bundled packed scene; per run: restart, frame 0, segment frame 1, then time flow(1) and
// update(1) with performance.now()), in Debian's headless Chromium; prints the medians and
// the ratio to the native numbers in $NATIVE.
import { launchChromium, serve } from '../test/helpers.js';
import { dirname } from 'node:path';
import { fileURLToPath } from 'node:url';

const web = dirname(dirname(fileURLToPath(import.meta.url)));
const runs = Number(process.env.RUNS ?? 7);
const native = JSON.parse(process.env.NATIVE);
const server = await serve(web);
const browser = await launchChromium();
try {
  const page = await browser.newPage();
  await page.goto(server.url);
  await page.waitForFunction(() => window.riseg.status === 'ready', null, { timeout: 60_000 });
  const wasm = await page.evaluate(async (runs) => {
    const { SceneFiles, Session } = await import('./pkg/riseg_wasm.js');
    const index = await (await fetch('scenes/index.json')).json();
    const scene = index.scenes.find((s) => s.name === 'packed');
    const files = new SceneFiles();
    for (const f of scene.files) {
      files.add(`packed/${f}`, new Uint8Array(await (await fetch(`scenes/packed/${f}`)).arrayBuffer()));
    }
    const session = Session.open(files, 'packed');
    const flow = [];
    const update = [];
    for (let i = 0; i < runs; i++) {
      session.restart();
      session.segment(0);
      session.update(0);
      session.segment(1);
      let start = performance.now();
      session.flow(1);
      flow.push(performance.now() - start);
      start = performance.now();
      session.update(1);
      update.push(performance.now() - start);
    }
    const median = (v) => v.sort((a, b) => a - b)[v.length >> 1];
    return { flow_ms: median(flow), update_mask_ms: median(update) };
  }, runs);
  const ratio = (k) => (wasm[k] / native[k]).toFixed(2);
  console.log(`stage        native ms   chromium wasm ms   wasm/native   (median of ${runs}, 640x480)`);
  for (const k of ['flow_ms', 'update_mask_ms']) {
    console.log(`${k.padEnd(14)} ${native[k].toFixed(1).padStart(8)} ${wasm[k].toFixed(1).padStart(16)} ${ratio(k).padStart(12)}`);
  }
} finally {
  await browser.close();
  server.close();
}

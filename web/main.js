// The riseg browser demo: opens a recorded scene (bundled, picked or dropped), runs RISeg on
// it push by push in WebAssembly (riseg-wasm) and draws what each stage gave.
//
// This file only renders: every label, colour, picture, push and metric comes from
// riseg-wasm. It fetches the page, the wasm module and the scene's input files (colour,
// depth, ground truth, JSON) and nothing else; no mask is ever fetched. Each stage is timed
// here with performance.now() (wasm32 has no clock of its own).
//
// For the browser tests, window.riseg holds the page's state: status ("ready", "running",
// "done", "error"), the open scene, the last error message, and per computed frame the
// mask's SHA-256, the metrics (fractions, as riseg-wasm returns them) and the stage times.

import init, { BODY_FRAME_FLOATS, SceneFiles, Session, keyColour } from './pkg/riseg_wasm.js';

const $ = (id) => document.getElementById(id);
const state = { status: 'loading', scene: null, error: null, frames: [] };
window.riseg = state;

let session = null;
let crop = null; // [x0, y0, x1, y1] of the objects, set on frame 0
let shown = -1;
let playing = false;

function setStatus(status, text) {
  state.status = status;
  $('status').textContent = text;
}

function showError(message) {
  state.error = message;
  $('error').textContent = message;
  $('error').hidden = false;
}

function clearError() {
  $('error').hidden = true;
  $('error').textContent = '';
}

// --- opening scenes ------------------------------------------------------------------------

// `files`: [path, Uint8Array] with '/'-separated paths. The scene folder is the one holding
// scene_camera.json; without one, the top folder (riseg then names the missing file).
function sceneDir(paths) {
  const cameras = paths.filter((p) => p.split('/').pop() === 'scene_camera.json')
    .sort((a, b) => a.split('/').length - b.split('/').length);
  if (cameras.length > 0) return cameras[0].split('/').slice(0, -1).join('/');
  return paths.length > 0 ? paths[0].split('/')[0] : '';
}

// Opens a scene; on error the message is shown and the scene that was open stays open.
function openScene(files, label) {
  const dir = sceneDir(files.map(([p]) => p));
  const sceneFiles = new SceneFiles();
  let opened;
  try {
    for (const [path, bytes] of files) sceneFiles.add(path, bytes);
    opened = Session.open(sceneFiles, dir);
  } catch (e) {
    showError(`Could not open ${label}: ${e.message}`);
    setStatus(session ? 'ready' : 'error', session ? `still showing ${state.scene}` : 'no scene');
    return false;
  } finally {
    sceneFiles.free();
  }
  clearError();
  if (session) session.free();
  session = opened;
  state.scene = label;
  state.frames = [];
  state.error = null;
  crop = null;
  shown = -1;
  for (const id of ['metrics', 'timing']) $(id).querySelector('tbody').replaceChildren();
  $('digests').replaceChildren();
  setStatus('ready', `${label}: ${session.frames} frames, ${session.width}×${session.height}; press step or play`);
  return true;
}

async function openBundled(index, name) {
  const entry = index.scenes.find((s) => s.name === name);
  setStatus('loading', `loading ${entry.title}…`);
  const files = await Promise.all(entry.files.map(async (f) => {
    const response = await fetch(`scenes/${name}/${f}`);
    if (!response.ok) throw new Error(`scenes/${name}/${f}: HTTP ${response.status}`);
    return [`${name}/${f}`, new Uint8Array(await response.arrayBuffer())];
  }));
  return openScene(files, entry.title);
}

async function readPicked(fileList) {
  return Promise.all([...fileList].map(async (f) => [
    f.webkitRelativePath || f.name, new Uint8Array(await f.arrayBuffer())]));
}

// Every file below the dropped entries, with paths from the dropped folder's name.
async function readDropped(items) {
  const out = [];
  const walk = async (entry) => {
    if (entry.isFile) {
      const file = await new Promise((ok, fail) => entry.file(ok, fail));
      out.push([entry.fullPath.replace(/^\//, ''), new Uint8Array(await file.arrayBuffer())]);
    } else if (entry.isDirectory) {
      const reader = entry.createReader();
      for (;;) {
        const batch = await new Promise((ok, fail) => reader.readEntries(ok, fail));
        if (batch.length === 0) break;
        for (const e of batch) await walk(e);
      }
    }
  };
  const entries = [...items].map((i) => i.webkitGetAsEntry()).filter(Boolean);
  for (const e of entries) await walk(e);
  return out;
}

// --- running ---------------------------------------------------------------------------------

async function sha256(u16) {
  const digest = await crypto.subtle.digest('SHA-256', u16.buffer);
  return [...new Uint8Array(digest)].map((b) => b.toString(16).padStart(2, '0')).join('');
}

// Runs every stage of the next frame, timing each, and keeps what the page draws.
async function computeNext() {
  const t = session.nextFrame;
  const time = {};
  const timed = (name, f) => {
    const start = performance.now();
    const result = f();
    time[name] = performance.now() - start;
    return result;
  };
  timed('segment', () => session.segment(t));
  if (t > 0) timed('flow', () => session.flow(t));
  timed('update', () => session.update(t));
  timed('findAction', () => session.findAction());
  const metrics = session.hasTruth
    ? timed('metrics', () => ({ static: session.metricsStatic(), riseg: session.metricsRiseg() }))
    : null;
  if (t === 0) crop = session.cropBox();
  const mask = session.mask();
  const frame = {
    t,
    time,
    metrics,
    digest: await sha256(mask),
    pictures: {
      rgb: session.rgbPicture(t),
      static: session.staticPicture(),
      riseg: session.maskPicture(),
      truth: session.truthPicture(),
      heat: session.heatPicture(),
      flow: session.flowPicture(),
    },
    bodyFrames: session.bodyFrames(),
    chosenPush: session.chosenPush(),
    recordedPush: session.recordedPush(t),
    keys: session.colourKeys(),
  };
  state.frames.push(frame);
  addRows(frame);
  return frame;
}

async function step() {
  if (!session) return;
  if (shown + 1 < state.frames.length) {
    show(shown + 1);
    return;
  }
  if (session.nextFrame >= session.frames) return;
  setStatus('running', `computing frame ${session.nextFrame}…`);
  try {
    const frame = await computeNext();
    show(frame.t);
    const done = session.nextFrame >= session.frames;
    setStatus(done ? 'done' : 'ready', `${state.scene}: frame ${frame.t} of ${session.frames - 1}${done ? ' (end)' : ''}`);
  } catch (e) {
    showError(e.message);
    setStatus('error', 'stopped');
  }
}

async function play() {
  if (playing || !session) return;
  playing = true;
  try {
    while (session && (shown + 1 < state.frames.length || session.nextFrame < session.frames)) {
      await step();
      if (state.status === 'error') break;
      await new Promise((r) => setTimeout(r, 300));
    }
  } finally {
    playing = false;
  }
}

// --- drawing ---------------------------------------------------------------------------------

const pct = (v) => (100 * v).toFixed(1);

function addRows(frame) {
  const row = (cells) => {
    const tr = document.createElement('tr');
    for (const c of cells) {
      const td = document.createElement('td');
      td.textContent = c;
      tr.append(td);
    }
    return tr;
  };
  if (frame.metrics) {
    for (const [name, m] of [['static', frame.metrics.static], ['RISeg', frame.metrics.riseg]]) {
      const cells = [frame.t, name, ...[0, 1, 2, 3, 4, 5, 6].map((i) => pct(m[i]))];
      const tr = row(cells);
      tr.className = name === 'RISeg' ? 'riseg' : '';
      $('metrics').querySelector('tbody').append(tr);
    }
  }
  const ms = (v) => (v === undefined ? '–' : v.toFixed(1));
  const tm = frame.time;
  $('timing').querySelector('tbody').append(
    row([frame.t, ms(tm.segment), ms(tm.flow), ms(tm.update), ms(tm.findAction), ms(tm.metrics)]));
  const li = document.createElement('li');
  li.textContent = frame.digest.slice(0, 16) + '…';
  li.title = frame.digest;
  $('digests').append(li);
}

function drawPicture(canvas, rgba, missing = '') {
  const [x0, y0, x1, y1] = crop;
  canvas.width = x1 - x0;
  canvas.height = y1 - y0;
  const ctx = canvas.getContext('2d');
  ctx.fillStyle = '#222';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  if (rgba && rgba.length > 0) {
    const image = new ImageData(new Uint8ClampedArray(rgba.buffer, rgba.byteOffset, rgba.length),
      session.width, session.height);
    ctx.putImageData(image, -x0, -y0, x0, y0, x1 - x0, y1 - y0);
  } else {
    ctx.fillStyle = '#aaa';
    ctx.font = '14px sans-serif';
    ctx.fillText(missing, 10, 24);
  }
  return ctx;
}

const css = (rgb, alpha = 1) => `rgba(${rgb[0]}, ${rgb[1]}, ${rgb[2]}, ${alpha})`;

function arrow(ctx, p, colour, dashed) {
  const [x0, y0, x1, y1] = [p[0] - crop[0], p[1] - crop[1], p[2] - crop[0], p[3] - crop[1]];
  ctx.save();
  ctx.strokeStyle = colour;
  ctx.fillStyle = colour;
  ctx.lineWidth = 3;
  ctx.setLineDash(dashed ? [6, 4] : []);
  ctx.beginPath();
  ctx.moveTo(x0, y0);
  ctx.lineTo(x1, y1);
  ctx.stroke();
  const a = Math.atan2(y1 - y0, x1 - x0);
  ctx.setLineDash([]);
  ctx.beginPath();
  ctx.moveTo(x1, y1);
  ctx.lineTo(x1 - 10 * Math.cos(a - 0.45), y1 - 10 * Math.sin(a - 0.45));
  ctx.lineTo(x1 - 10 * Math.cos(a + 0.45), y1 - 10 * Math.sin(a + 0.45));
  ctx.closePath();
  ctx.fill();
  ctx.restore();
}

// Body frames as triangles, one colour per moving twist group (riseg's colours from 501 on,
// apart from the object colours), grey for static or ungrouped frames.
function bodyFrames(ctx, floats) {
  const n = BODY_FRAME_FLOATS();
  for (let i = 0; i + n <= floats.length; i += n) {
    const [ax, ay, bx, by, cx, cy, group, moving] = floats.subarray(i, i + n);
    const colour = group >= 0 && moving > 0 ? css(keyColour(501 + group), 0.9) : 'rgba(160,160,160,0.3)';
    ctx.strokeStyle = colour;
    ctx.lineWidth = 1;
    ctx.beginPath();
    ctx.moveTo(ax - crop[0], ay - crop[1]);
    ctx.lineTo(bx - crop[0], by - crop[1]);
    ctx.lineTo(cx - crop[0], cy - crop[1]);
    ctx.closePath();
    ctx.stroke();
  }
}

function show(t) {
  const frame = state.frames[t];
  shown = t;
  const before = t > 0 ? state.frames[t - 1] : null;
  const ctx = drawPicture($('before'), (before ?? frame).pictures.rgb);
  if (before) {
    bodyFrames(ctx, frame.bodyFrames);
    if (frame.recordedPush) arrow(ctx, frame.recordedPush, 'white', false);
    if (before.chosenPush) arrow(ctx, before.chosenPush, '#ffd400', true);
  }
  drawPicture($('after'), frame.pictures.rgb);
  drawPicture($('static'), frame.pictures.static);
  drawPicture($('riseg'), frame.pictures.riseg);
  drawPicture($('truth'), frame.pictures.truth, 'no ground truth (label/) in this scene');
  drawPicture($('flow'), frame.pictures.flow, 'first frame: no push yet');
  drawPicture($('heat'), frame.pictures.heat);
  for (const el of document.querySelectorAll('.prev-t')) el.textContent = before ? t - 1 : t;
  for (const el of document.querySelectorAll('.cur-t')) el.textContent = t;
  const legend = $('legend');
  legend.replaceChildren();
  for (const key of frame.keys) {
    const item = document.createElement('span');
    const swatch = document.createElement('i');
    swatch.style.background = css(keyColour(key));
    item.append(swatch, key < 1000 ? `object ${key}` : `piece ${key - 1000} (no object of its own)`);
    legend.append(item);
  }
  for (const tr of document.querySelectorAll('#metrics tbody tr, #timing tbody tr')) {
    tr.classList.toggle('current', tr.firstChild.textContent === String(t));
  }
}

function back() {
  if (shown > 0) show(shown - 1);
}

function restart() {
  if (!session) return;
  session.restart();
  const scene = state.scene;
  state.frames = [];
  shown = -1;
  crop = null;
  for (const id of ['metrics', 'timing']) $(id).querySelector('tbody').replaceChildren();
  $('digests').replaceChildren();
  setStatus('ready', `${scene}: restarted; press step or play`);
}

// --- wiring ----------------------------------------------------------------------------------

async function main() {
  await init();
  const index = await (await fetch('scenes/index.json')).json();
  const select = $('scene');
  for (const s of index.scenes) select.append(new Option(s.title, s.name));
  select.onchange = () => openBundled(index, select.value).catch((e) => showError(e.message));
  $('step').onclick = () => step();
  $('play').onclick = () => play();
  $('back').onclick = back;
  $('restart').onclick = restart;
  $('folder').onchange = async (ev) => {
    const files = await readPicked(ev.target.files);
    ev.target.value = '';
    if (files.length === 0) return;
    openScene(files, `${sceneDir(files.map(([p]) => p))} (your folder)`);
  };
  document.addEventListener('dragover', (ev) => {
    ev.preventDefault();
    $('drop').classList.add('hover');
  });
  document.addEventListener('dragleave', () => $('drop').classList.remove('hover'));
  document.addEventListener('drop', async (ev) => {
    ev.preventDefault();
    $('drop').classList.remove('hover');
    const files = await readDropped(ev.dataTransfer.items);
    if (files.length === 0) return;
    openScene(files, `${sceneDir(files.map(([p]) => p))} (dropped)`);
  });
  await openBundled(index, index.scenes[0].name);
}

main().catch((e) => {
  showError(`The page could not start: ${e.message}`);
  setStatus('error', 'failed');
});

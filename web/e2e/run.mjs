// End-to-end tests of the editor in real headless Chromium (Debian's package), driven by
// playwright-core. The editor is served by `inkwarp edit`, exactly as users get it.
//
//   node e2e/run.mjs            run every test (prints "N passed, M failed")
//   UPDATE_DOCS=1 node e2e/run.mjs   also refresh the screenshots in docs/guides/images/
//
// Timings are measured and reported (web/test-results/perf.json), never asserted.

import { spawn, spawnSync } from 'node:child_process';
import { copyFileSync, mkdirSync, mkdtempSync, readFileSync, renameSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

/** The tests' scratch folders, removed when the run ends (pass or fail). */
const scratch = [];
function scratchDir(prefix) {
  const dir = mkdtempSync(join(tmpdir(), prefix));
  scratch.push(dir);
  return dir;
}
process.on('exit', () => scratch.forEach((dir) => rmSync(dir, { recursive: true, force: true })));

const here = dirname(fileURLToPath(import.meta.url));
const repo = resolve(here, '../..');
const results = resolve(here, '../test-results');
const screens = join(results, 'screens');
const docsImages = join(repo, 'docs/guides/images');
const inkwarp = process.env.INKWARP ?? join(repo, '.venv/bin/inkwarp');
const only = process.argv[2] ?? null;
mkdirSync(screens, { recursive: true });

export const CHROMIUM_ARGS = [
  '--headless',
  '--no-sandbox',
  '--disable-gpu',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--no-first-run',
];

// ---------------------------------------------------------------------------------------
// A small runner.

const tests = [];
const test = (name, fn) => tests.push({ name, fn });
const perf = {};

class AssertionError extends Error {}
function assert(cond, message) {
  if (!cond) throw new AssertionError(message);
}

// ---------------------------------------------------------------------------------------
// The server and the browser.

function startServer(args = []) {
  return new Promise((resolvePromise, reject) => {
    const proc = spawn(inkwarp, ['edit', '--no-browser', '--port', '0', ...args], { stdio: ['ignore', 'pipe', 'pipe'] });
    let out = '';
    const timer = setTimeout(() => reject(new Error(`inkwarp edit printed no URL: ${out}`)), 20000);
    proc.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/http:\/\/127\.0\.0\.1:\d+\/\S*/);
      if (m) {
        clearTimeout(timer);
        resolvePromise({ proc, url: m[0] });
      }
    });
    proc.stderr.on('data', (d) => (out += d));
    proc.on('exit', (code) => reject(new Error(`inkwarp edit exited with ${code}: ${out}`)));
  });
}

async function openEditor(browser, url, viewport = { width: 1400, height: 900 }, profile = null) {
  const options = { viewport, acceptDownloads: true, deviceScaleFactor: 1 };
  // A profile on disk where asked (as a user's browser keeps its storage), else a fresh
  // context in memory.
  const context = profile
    ? await chromium.launchPersistentContext(profile, { executablePath: '/usr/bin/chromium', args: CHROMIUM_ARGS, ...options })
    : await browser.newContext(options);
  const page = context.pages()[0] ?? (await context.newPage());
  const errors = [];
  // "Open over unsaved work?" and "Leave the page?": the tests answer yes unless they set
  // `page.declineDialogs`; `page.dialogs` lists the kinds asked.
  page.dialogs = [];
  page.on('dialog', (d) => {
    page.dialogs.push(d.type());
    void (page.declineDialogs ? d.dismiss() : d.accept());
  });
  page.on('pageerror', (e) => errors.push(e.message));
  page.on('console', (m) => {
    if (m.type() === 'error' && !/GPU stall|Failed to load resource/.test(m.text())) errors.push(m.text());
  });
  // Bytes (pixels, files) leave the page as base64 (`pixelsB64`); `image` makes pixels of them here.
  await page.addInitScript(() => {
    window.pixelsB64 = (px) => {
      let s = '';
      for (let i = 0; i < px.length; i += 0x8000) s += String.fromCharCode(...px.subarray(i, i + 0x8000));
      return btoa(s);
    };
  });
  await page.goto(url);
  await page.waitForSelector('body[data-ready]', { timeout: 30000 });
  const state = await page.evaluate(() => document.body.dataset.ready);
  assert(state === 'true', `the editor did not start: ${await page.textContent('body')}`);
  await idle(page);
  return { page, context, errors };
}

/**
 * `body({ page, context, errors, own })` on the editor that a fresh `inkwarp edit ARGS` (`own`:
 * its process and URL) serves, in a browser context of its own; then no page errors. The
 * context and the server are closed after, whatever happened.
 */
async function withServedEditor(args, body, profile = null) {
  const own = await startServer(args);
  const { page, context, errors } = await openEditor(browser, own.url, undefined, profile);
  try {
    await body({ page, context, errors, own });
    assert(errors.length === 0, `page errors: ${errors.join('; ')}`);
  } finally {
    await context.close();
    own.proc.kill();
  }
}

const idle = (page) => page.evaluate(() => window.inkwarp.app.idle());
// Restores the offered work and waits for the restore to finish (its message), not only for
// its scene to show: the page marks it unsaved and points it at its file after that.
const restoreYes = async (page) => {
  await page.click('#restore-yes');
  await page.waitForFunction(() => /Restored the scene/.test(document.querySelector('#message')?.textContent ?? ''), null, { timeout: 10000 });
};
// The autosaver is the page's once its start settles (an IndexedDB read, later than ready).
const flush = async (page) => {
  await page.waitForFunction(() => window.inkwarp.autosave, null, { timeout: 10000 });
  await page.evaluate(() => window.inkwarp.autosave.flush());
};

/** Straight RGBA8 of `width × height` from the page's `pixelsB64`. */
const image = (width, height, b64) => ({ width, height, data: new Uint8Array(Buffer.from(b64, 'base64')) });

/** The frame on screen as straight RGBA8 (from the GPU renderer). */
async function frame(page) {
  const { w, h, b64 } = await page.evaluate(async () => {
    const { app } = window.inkwarp;
    await app.idle();
    app.renderNow();
    return { w: app.store.doc.width, h: app.store.doc.height, b64: window.pixelsB64(app.gl.readPixels()) };
  });
  return image(w, h, b64);
}

async function toClient(page, p) {
  return page.evaluate((q) => window.inkwarp.ui.toClient(q), p);
}

/** How long (ms) the measure's aimed drags rest on their point before pressing. */
const AIM_MS = 250;

async function click(page, p) {
  const [x, y] = await toClient(page, p);
  await page.mouse.click(x, y);
}

/**
 * Drags in `steps` moves, one per animation frame (as a hand would); with `restMs`, the
 * pointer first arrives on `from` and rests there that long before it presses, as a hand
 * aims.
 */
/** A point traced at canvas position `at`, in rest mode with the point tool. */
async function tracePoint(page, at) {
  await page.keyboard.press('r');
  await page.keyboard.press('p');
  await click(page, at);
}

async function drag(page, from, to, steps = 8, restMs = 0) {
  const [x0, y0] = await toClient(page, from);
  const [x1, y1] = await toClient(page, to);
  if (restMs > 0) await page.mouse.move(x0 - 6, y0 - 6);
  await page.mouse.move(x0, y0);
  if (restMs > 0) await page.waitForTimeout(restMs);
  await page.mouse.down();
  for (let i = 1; i <= steps; i++) {
    await page.mouse.move(x0 + ((x1 - x0) * i) / steps, y0 + ((y1 - y0) * i) / steps);
    await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => r())));
  }
  await page.mouse.up();
}

/**
 * The matte overlay turned on (and left on) and drawn now: which scene pixels it marks as
 * holes (magenta), row by row, with the scene's width and the mode. See `marked`.
 */
async function matteMarks(page) {
  return page.evaluate(async () => {
    const { ui, app, store } = window.inkwarp;
    ui.setOverlay({ matte: true, drawing: false });
    await app.idle();
    app.renderNow();
    const c = document.querySelector('canvas.overlay');
    const data = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    const w = store.doc.width, h = store.doc.height, s = c.width / w;
    const marks = [];
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
      const j = 4 * (Math.floor((y + 0.5) * s) * c.width + Math.floor((x + 0.5) * s));
      marks.push(data[j + 3] > 40 && data[j] > 200 && data[j + 1] < 60 && data[j + 2] > 100 ? 1 : 0);
    }
    return { width: w, height: h, marks, mode: store.view.mode };
  });
}

/** Whether `matteMarks` found scene pixel (x, y) marked as a hole. */
const marked = (m, x, y) => m.marks[y * m.width + x] === 1;

const overlayOff = (page) => page.evaluate(() => window.inkwarp.ui.setOverlay({ matte: false, drawing: true }));

// ---------------------------------------------------------------------------------------
// Pictures.

function grey(img, x, y) {
  const i = 4 * (y * img.width + x);
  return (img.data[i] + img.data[i + 1] + img.data[i + 2]) / 3;
}

/** Where a patch of `a` around (x, y) best matches in `b`, searching ±r horizontally/vertically. */
function track(a, b, x, y, r = 60, half = 6) {
  let best = { dx: 0, dy: 0, err: Infinity };
  for (let dy = -r; dy <= r; dy++) {
    for (let dx = -r; dx <= r; dx++) {
      let err = 0;
      for (let v = -half; v <= half; v++) {
        for (let u = -half; u <= half; u++) {
          const xa = x + u, ya = y + v, xb = x + u + dx, yb = y + v + dy;
          if (xb < 0 || yb < 0 || xb >= b.width || yb >= b.height) {
            err += 1e4;
            continue;
          }
          const i = 4 * (ya * a.width + xa);
          const j = 4 * (yb * b.width + xb);
          for (let c = 0; c < 3; c++) err += Math.abs(a.data[i + c] - b.data[j + c]);
        }
      }
      if (err < best.err) best = { dx, dy, err };
    }
  }
  return best;
}

/** Mean absolute difference over a rectangle, per channel. */
function meanDiff(a, b, x0, y0, x1, y1) {
  let s = 0, n = 0;
  for (let y = y0; y < y1; y++) for (let x = x0; x < x1; x++) {
    const i = 4 * (y * a.width + x);
    for (let c = 0; c < 4; c++) s += Math.abs(a.data[i + c] - b.data[i + c]);
    n += 4;
  }
  return s / n;
}

/** Compares two RGBA8 images; writes a diff PNG (through the page) when they differ. */
async function compareImages(page, a, b, name, { meanTol, p99Tol }) {
  assert(a.width === b.width && a.height === b.height, `${name}: sizes differ (${a.width}×${a.height} vs ${b.width}×${b.height})`);
  const diffs = new Float64Array(a.width * a.height);
  const diffImg = new Uint8Array(a.data.length);
  let sum = 0;
  for (let i = 0; i < diffs.length; i++) {
    let m = 0;
    for (let c = 0; c < 4; c++) m = Math.max(m, Math.abs(a.data[4 * i + c] - b.data[4 * i + c]));
    diffs[i] = m;
    sum += m;
    const v = Math.min(255, m * 8);
    diffImg.set([v, v > 0 ? 0 : 40, v > 0 ? 0 : 40, 255], 4 * i);
  }
  const sorted = Array.from(diffs).sort((x, y) => x - y);
  const stats = { mean: sum / diffs.length, p99: sorted[Math.floor(0.99 * (sorted.length - 1))], max: sorted[sorted.length - 1] };
  const ok = stats.mean <= meanTol && stats.p99 <= p99Tol;
  if (!ok) {
    await savePng(page, { width: a.width, height: a.height, data: diffImg }, join(results, `${name}-diff.png`));
    await savePng(page, a, join(results, `${name}-a.png`));
    await savePng(page, b, join(results, `${name}-b.png`));
  }
  return { ok, stats };
}

async function savePng(page, img, path) {
  const b64 = Buffer.from(img.data).toString('base64');
  const png = await page.evaluate(async ({ w, h, b64 }) => {
    const bytes = Uint8ClampedArray.from(atob(b64), (c) => c.charCodeAt(0));
    const c = new OffscreenCanvas(w, h);
    c.getContext('2d').putImageData(new ImageData(bytes, w, h), 0, 0);
    const blob = await c.convertToBlob({ type: 'image/png' });
    return window.pixelsB64(new Uint8Array(await blob.arrayBuffer()));
  }, { w: img.width, h: img.height, b64 });
  writeFileSync(path, Buffer.from(png, 'base64'));
}

/** Decodes a PNG file to RGBA8 through the page (exact bytes, no premultiplication). */
async function loadPng(page, path) {
  const b64 = readFileSync(path).toString('base64');
  const { w, h, data } = await page.evaluate(async (b64) => {
    const { decodeBlob } = window.inkwarp.images;
    const blob = new Blob([Uint8Array.from(atob(b64), (c) => c.charCodeAt(0))], { type: 'image/png' });
    const img = await decodeBlob(blob, 'render.png');
    return { w: img.width, h: img.height, data: window.pixelsB64(img.data) };
  }, b64);
  return image(w, h, data);
}

async function screenshot(page, name) {
  await idle(page);
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(() => r()))));
  await shot(page, name);
}

/** A screenshot of `pg` as it is now (no wait), copied into the docs with UPDATE_DOCS. */
async function shot(pg, name) {
  const path = join(screens, `editor-${name}.png`);
  await pg.screenshot({ path });
  if (process.env.UPDATE_DOCS && DOC_SCREENS.includes(name)) {
    mkdirSync(docsImages, { recursive: true });
    copyFileSync(path, join(docsImages, `editor-${name}.png`));
  }
}

/** The screenshots docs/guides/editor.md shows. */
const DOC_SCREENS = ['layer-offset', 'photo-proxy', 'photo-settled', 'photo-settled-100', 'ready-bar', 'marquee', 'keys-marquee', 'matte-posed', 'start', 'restore', 'timeline-keys', 'border-hold', 'keys-onion', 'zoomed', 'rest-mode', 'pose-mode', 'timeline', 'method-tps-exact', 'heat-map', 'mesh', 'help', 'bad-file', 'example-face'];

const median = (a) => (a.length ? [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)] : null);
const pct = (a, q) => (a.length ? [...a].sort((x, y) => x - y)[Math.min(a.length - 1, Math.floor(q * a.length))] : null);

// ---------------------------------------------------------------------------------------
// The tests. They share one page, in order, like a user's session.

let server, browser, page, errors;
const SPLINE = [[150, 190], [165, 256], [150, 322]];

test('the editor starts with the built-in example, WebGL2 on', async () => {
  const info = await page.evaluate(() => {
    const gl = window.inkwarp.app.gl.gl;
    const d = gl.getExtension('WEBGL_debug_renderer_info');
    return { renderer: d ? gl.getParameter(d.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER), layers: window.inkwarp.store.doc.layers.length };
  });
  perf.renderer = info.renderer;
  assert(info.layers === 1, 'the built-in example has one layer');
  await screenshot(page, 'start');
});

test('draw a spline in rest mode', async () => {
  await page.keyboard.press('r');
  await page.keyboard.press('s');
  for (const p of SPLINE) await click(page, p);
  await page.keyboard.press('Enter');
  const f = await page.evaluate(() => window.inkwarp.store.doc.features.find((g) => g.id === 'spline1'));
  assert(f && f.kind === 'spline' && f.rest.length === 3, `expected spline1 with 3 points, got ${JSON.stringify(f)}`);
  for (let i = 0; i < 3; i++) {
    assert(Math.hypot(f.rest[i][0] - SPLINE[i][0], f.rest[i][1] - SPLINE[i][1]) < 1, `point ${i} placed at ${f.rest[i]}, clicked at ${SPLINE[i]}`);
  }
  await page.keyboard.press('v');
  await screenshot(page, 'rest-mode');
});

test('drag it in pose mode: the picture follows, and does not cross the cut', async () => {
  await page.keyboard.press('e');
  const before = await frame(page);
  await drag(page, SPLINE[1], [SPLINE[1][0] + 40, SPLINE[1][1]]);
  const after = await frame(page);
  const key = await page.evaluate(() => window.inkwarp.store.doc.features.find((g) => g.id === 'spline1').keys);
  assert(key?.length === 1 && key[0].t === 0, `dragging keyed the feature at t=0: ${JSON.stringify(key)}`);
  // The picture under the dragged point moved with it (tracked from the pixels).
  const at = track(before, after, SPLINE[1][0], SPLINE[1][1]);
  assert(Math.abs(at.dx - 40) <= 2 && Math.abs(at.dy) <= 2, `the picture at the dragged point moved by (${at.dx}, ${at.dy}); expected (40, 0)`);
  // Just left of the cut (x = 307) the picture is pushed; just right of it, it barely moves.
  const cutX = 307;
  const left = track(before, after, cutX - 8, 256, 30);
  const right = track(before, after, cutX + 8, 256, 30);
  perf.cut = { left, right };
  assert(left.dx >= 4, `left of the cut the picture moved by ${left.dx} px; expected it to be pushed right`);
  assert(right.dx <= 1, `right of the cut the picture moved by (${right.dx}, ${right.dy}); it must not be carried along the pull across the cut`);
  assert(left.dx - right.dx >= 4, `the two sides of the cut moved by ${left.dx} and ${right.dx} px; the cut should open`);
  await screenshot(page, 'pose-mode');
});

test('set two keys and check the frame at the midpoint', async () => {
  // Key 1 at t=0 exists (the drag); key 2 at t=1 s, dragged 40 px further.
  await page.evaluate(() => window.inkwarp.ui.setTime(1));
  await drag(page, [SPLINE[1][0] + 40, SPLINE[1][1]], [SPLINE[1][0] + 80, SPLINE[1][1]]);
  const keys = await page.evaluate(() => window.inkwarp.store.doc.features.find((g) => g.id === 'spline1').keys.map((k) => k.t));
  assert(JSON.stringify(keys) === '[0,1]', `keys at ${keys}`);
  await page.evaluate(() => window.inkwarp.ui.setTime(0.5));
  const mid = await page.evaluate(() => window.inkwarp.store.doc.features.find((g) => g.id === 'spline1'));
  const shown = await page.evaluate(() => {
    const f = window.inkwarp.store.doc.features.find((g) => g.id === 'spline1');
    return window.inkwarp.scene.pointsAt(f, 0.5);
  });
  const expected = mid.keys[0].points.map((p, i) => [(p[0] + mid.keys[1].points[i][0]) / 2, (p[1] + mid.keys[1].points[i][1]) / 2]);
  for (let i = 0; i < 3; i++) assert(Math.hypot(shown[i][0] - expected[i][0], shown[i][1] - expected[i][1]) < 1e-6, `midpoint pose ${shown[i]} ≠ ${expected[i]}`);
  const restFrame = await page.evaluate(() => window.inkwarp.ui.setMode('rest'));
  void restFrame;
  const original = await frame(page);
  await page.evaluate(() => window.inkwarp.ui.setMode('pose'));
  const at = track(original, await frame(page), SPLINE[1][0], SPLINE[1][1], 80);
  assert(Math.abs(at.dx - 60) <= 3 && Math.abs(at.dy) <= 4, `at the midpoint the picture moved by (${at.dx}, ${at.dy}); expected (60, 0)`);
  await page.evaluate(() => window.inkwarp.store.setView({ selection: { feature: 'spline1', point: null } }));
  await screenshot(page, 'timeline');
});

test('a single late key is named, and one click keys the rest at 0 s', async () => {
  const spline = () => page.evaluate(() => window.inkwarp.store.doc.features.find((g) => g.id === 'spline1'));
  const before = await spline();
  await page.evaluate(() => window.inkwarp.store.setView({ selection: { feature: 'spline1', point: null } }));
  // Delete the key at 0 s (the first row): the 1 s pose then holds at every time.
  await page.click('button[title="Delete this key"]');
  await page.waitForSelector('#late-key', { timeout: 5000 });
  const text = await page.textContent('#late-key');
  assert(/1\.000 s/.test(text) && /every time/.test(text), `the late key's hint reads: ${text}`);
  await screenshot(page, 'late-key');
  await page.click('#key-rest');
  const after = await spline();
  assert(JSON.stringify(after.keys.map((k) => k.t)) === '[0,1]', `keys after "Key the rest at 0 s": ${after.keys.map((k) => k.t)}`);
  assert(JSON.stringify(after.keys[0].points) === JSON.stringify(after.rest), `the key at 0 s holds ${JSON.stringify(after.keys[0].points)}, not the rest ${JSON.stringify(after.rest)}`);
  assert(await page.$('#late-key') === null, 'the hint stays after the rest was keyed');
  // Both edits undo: the scene is as the earlier tests left it.
  await page.keyboard.press('Control+z');
  await page.keyboard.press('Control+z');
  const restored = await spline();
  assert(JSON.stringify(restored.keys) === JSON.stringify(before.keys), `undo left keys ${JSON.stringify(restored.keys)}`);
});

async function cpuFrame(page) {
  const r = await page.evaluate(async () => {
    const { app, engine } = window.inkwarp;
    await app.idle();
    const doc = app.store.doc;
    const layers = [];
    const grids = [];
    for (const l of doc.layers) {
      const rt = app.runtimes.get(l.name);
      const cuts = doc.features.filter((f) => f.kind === 'cut' && (!l.features || l.features.includes(f.id))).map((f) => f.rest);
      const grid = engine.grid(doc.width, doc.height, rt.matte, cuts);
      grids.push(grid);
      const n = doc.width * doc.height;
      layers.push({ image: rt.rgba.data, grid, field: rt.field ?? { width: doc.width, height: doc.height, dx: new Float32Array(n), dy: new Float32Array(n) }, offset: l.offset ?? [0, 0] });
    }
    const cpu = engine.renderCpu(doc.width, doc.height, doc.background ?? [255, 255, 255, 255], layers);
    grids.forEach((g) => g.free());
    return { w: doc.width, h: doc.height, b64: window.pixelsB64(cpu) };
  });
  return image(r.w, r.h, r.b64);
}

test('the GPU frame matches the CPU reference renderer', async () => {
  const cpu = await cpuFrame(page);
  const gpu = await frame(page);
  const { ok, stats } = await compareImages(page, gpu, cpu, 'gpu-vs-cpu', { meanTol: 1.0, p99Tol: 12 });
  perf.gpuVsCpu = stats;
  assert(ok, `GPU and CPU frames differ: mean ${stats.mean.toFixed(3)}, p99 ${stats.p99}, max ${stats.max} levels (tolerance: mean ≤ 1, p99 ≤ 12); see test-results/gpu-vs-cpu-diff.png`);
});

test('save the scene and render it with `inkwarp render`: same frame', async () => {
  const dir = scratchDir('inkwarp-e2e-');
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#save')]);
  const scenePath = join(dir, 'scene.json');
  await download.saveAs(scenePath);
  const doc = JSON.parse(readFileSync(scenePath, 'utf8'));
  assert(doc.inkwarp === 1 && doc.layers[0].image.startsWith('data:image/png;base64,'), 'the saved scene is one JSON file with data: URIs');
  const out = join(dir, 'frame.png');
  const run = spawnSync(inkwarp, ['render', scenePath, '--time', '0.5', '-o', out], { encoding: 'utf8' });
  assert(run.status === 0, `inkwarp render failed (${run.status}): ${run.stderr}`);
  const cli = await loadPng(page, out);
  const editor = await frame(page);
  const { ok, stats } = await compareImages(page, editor, cli, 'editor-vs-cli', { meanTol: 1.0, p99Tol: 12 });
  perf.editorVsCli = stats;
  assert(ok, `the editor's frame and inkwarp render's differ: mean ${stats.mean.toFixed(3)}, p99 ${stats.p99} (see test-results/editor-vs-cli-diff.png)`);
});

test('the method switch: each method draws its own frame, the one the CPU renderer and `inkwarp render` draw', async () => {
  const dir = scratchDir('inkwarp-methods-');
  const time = await page.evaluate(() => window.inkwarp.store.view.time);
  const tps = await frame(page);
  const { width, height } = tps;
  perf.methods = {};
  for (const m of ['tps-exact', 'triangulation', 'beier-neely', 'tps']) {
    await page.selectOption('#method', m);
    await idle(page);
    const shown = await frame(page);
    const info = await page.evaluate(() => ({
      method: window.inkwarp.store.doc.solver?.method,
      note: document.querySelector('#method-note')?.textContent ?? '',
      status: document.querySelector('#status')?.textContent ?? '',
      report: window.inkwarp.app.lastReport && { method: window.inkwarp.app.lastReport.report.method, ms: window.inkwarp.app.lastReport.ms },
    }));
    assert(info.method === m && info.report?.method === m, `after switching to ${m} the scene says ${info.method} and the last field is ${info.report?.method}`);
    assert(info.note.startsWith(`${m}:`), `the method note shows ${m}: ${info.note}`);
    // The methods that know nothing of cuts say so (the built-in example has one).
    assert(/ignores the continuity matte and cuts/.test(info.status) === (m !== 'tps'), `the engine's notes for ${m}: ${info.status}`);
    const changed = meanDiff(tps, shown, 0, 0, width, height);
    if (m === 'tps') assert(changed < 0.5, `back to tps the frame is the first one again (mean difference ${changed.toFixed(3)})`);
    else assert(changed > 1, `${m} draws the same frame as tps (mean difference ${changed.toFixed(3)})`);
    const gpu = await compareImages(page, shown, await cpuFrame(page), `gpu-vs-cpu-${m}`, { meanTol: 1.0, p99Tol: 12 });
    assert(gpu.ok, `${m}: GPU and CPU frames differ: mean ${gpu.stats.mean.toFixed(3)}, p99 ${gpu.stats.p99} (see test-results/gpu-vs-cpu-${m}-diff.png)`);
    // Saved, the scene keeps the method: `inkwarp render` (no --method) draws the same frame.
    const [download] = await Promise.all([page.waitForEvent('download'), page.click('#save')]);
    await page.click('#message'); // dismissed: it would cover the screenshots
    const scenePath = join(dir, `${m}.json`);
    await download.saveAs(scenePath);
    const saved = JSON.parse(readFileSync(scenePath, 'utf8'));
    assert(saved.solver?.method === m, `the saved scene has solver.method ${saved.solver?.method}, not ${m}`);
    const out = join(dir, `${m}.png`);
    const run = spawnSync(inkwarp, ['render', scenePath, '--time', String(time), '-o', out], { encoding: 'utf8' });
    assert(run.status === 0, `inkwarp render (${m}) failed (${run.status}): ${run.stderr}`);
    const cli = await compareImages(page, shown, await loadPng(page, out), `editor-vs-cli-${m}`, { meanTol: 1.0, p99Tol: 12 });
    assert(cli.ok, `${m}: the editor's frame and inkwarp render's differ: mean ${cli.stats.mean.toFixed(3)}, p99 ${cli.stats.p99} (see test-results/editor-vs-cli-${m}-diff.png)`);
    perf.methods[m] = { fullSolveMs: info.report.ms, changedFromTps: changed, gpuVsCpu: gpu.stats, editorVsCli: cli.stats };
    await screenshot(page, `method-${m}`);
  }
});

test('overlays: heat map, mesh, matte; help panel', async () => {
  await page.evaluate(() => window.inkwarp.ui.setOverlay({ heat: 'dx' }));
  await screenshot(page, 'heat-map');
  await page.evaluate(() => window.inkwarp.ui.setOverlay({ heat: 'off', mesh: true }));
  await screenshot(page, 'mesh');
  const meshDrawn = await page.evaluate(() => {
    const c = window.inkwarp.ui.overlayCanvas;
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++;
    return n / (c.width * c.height);
  });
  assert(meshDrawn > 0.02, `the mesh overlay drew on ${(meshDrawn * 100).toFixed(1)}% of the stage`);
  await page.evaluate(() => window.inkwarp.ui.setOverlay({ mesh: false }));
  await page.keyboard.press('?');
  assert(await page.isVisible('#help'), 'the help panel opens with ?');
  const rows = await page.$$eval('#help tr', (r) => r.length);
  assert(rows >= 10, 'the help panel lists the shortcuts');
  await screenshot(page, 'help');
  await page.keyboard.press('Escape');
  assert(!(await page.isVisible('#help')), 'Escape closes the help panel');
});

test('undo and redo from the keyboard', async () => {
  const n0 = await page.evaluate(() => window.inkwarp.store.doc.features.length);
  await tracePoint(page, [60, 440]);
  assert((await page.evaluate(() => window.inkwarp.store.doc.features.length)) === n0 + 1, 'a point was added');
  await page.keyboard.press('Control+z');
  assert((await page.evaluate(() => window.inkwarp.store.doc.features.length)) === n0, 'Ctrl+Z removed it');
  await page.keyboard.press('Control+Shift+z');
  assert((await page.evaluate(() => window.inkwarp.store.doc.features.length)) === n0 + 1, 'Ctrl+Shift+Z brought it back');
  await page.keyboard.press('v');
  await click(page, [60, 440]);
  await page.keyboard.press('Delete');
  assert((await page.evaluate(() => window.inkwarp.store.doc.features.length)) === n0, 'Delete removed the selected point');
  // While drawing, Ctrl+Z takes back the last click, not the feature before; another tool
  // finishes the feature being drawn (it dropped it).
  await page.keyboard.press('l');
  for (const p of [[60, 420], [90, 430], [120, 420]]) await click(page, p);
  await page.keyboard.press('Control+z');
  const drawing = await page.evaluate(() => ({ draft: window.inkwarp.store.view.draft.length, features: window.inkwarp.store.doc.features.length }));
  assert(drawing.draft === 2 && drawing.features === n0, `Ctrl+Z while drawing took back a click: ${JSON.stringify(drawing)}`);
  await page.keyboard.press('s');
  const kept = await page.evaluate(() => ({ draft: window.inkwarp.store.view.draft.length, last: window.inkwarp.store.doc.features.at(-1) }));
  assert(kept.draft === 0 && kept.last.kind === 'polyline' && kept.last.rest.length === 2, `another tool finished the polyline: ${JSON.stringify(kept)}`);
  await page.keyboard.press('Control+z');
  assert((await page.evaluate(() => window.inkwarp.store.doc.features.length)) === n0, 'Ctrl+Z took the finished polyline back');
  await page.keyboard.press('v');
});

test('bad files get a clear message with the JSON path', async () => {
  const bad = JSON.parse(await page.evaluate(() => window.inkwarp.scene.serializeScene(window.inkwarp.store.doc)));
  bad.features.find((f) => f.id === 'spline1').keys[0].points.pop();
  await page.setInputFiles('input[type=file][accept^=".json"]', { name: 'broken.json', mimeType: 'application/json', buffer: Buffer.from(JSON.stringify(bad)) });
  await page.waitForSelector('#message.error:not([hidden])');
  const text = await page.textContent('#message');
  assert(/broken\.json/.test(text) && /features\[\d+\]\.keys\[0\]\.points/.test(text), `message: ${text}`);
  await screenshot(page, 'bad-file');
  await page.setInputFiles('input[type=file][accept^=".json"]', { name: 'notes.png', mimeType: 'image/png', buffer: Buffer.from('this is not a picture') });
  await page.waitForFunction(() => /notes\.png/.test(document.querySelector('#message')?.textContent ?? ''));
  const text2 = await page.textContent('#message');
  // Once the file's name, one piece of advice (it read "notes.png: notes.png is not an image
  // … (use PNG or JPEG): … save it as PNG or JPEG"), and the PSDs Open… reads.
  assert(/^notes\.png: not a PNG or JPEG image .*; save it as PNG or JPEG \(Open… also reads a layered PSD\)$/.test(text2) && text2.split('notes.png').length === 2, `message: ${text2}`);
  await page.setInputFiles('input[type=file][accept^=".json"]', { name: 'readme.psd', mimeType: 'image/vnd.adobe.photoshop', buffer: Buffer.from('not a psd') });
  await page.waitForFunction(() => /readme\.psd/.test(document.querySelector('#message')?.textContent ?? ''));
  const text3 = await page.textContent('#message');
  assert(/^readme\.psd: not a readable PSD file/.test(text3) && text3.split('readme.psd').length === 2, `message: ${text3}`);
  await page.click('#message');
});

test('the GPU frame matches the CPU renderer around a hole that opens', async () => {
  await page.evaluate(async () => {
    const { ui, scene } = window.inkwarp;
    const size = 128;
    const c = new OffscreenCanvas(size, size);
    const ctx = c.getContext('2d');
    for (let y = 0; y < size; y += 8) for (let x = 0; x < size; x += 8) {
      ctx.fillStyle = `hsl(${(x * 3 + y * 5) % 360} 70% ${((x + y) / 8) % 2 ? 40 : 70}%)`;
      ctx.fillRect(x, y, 8, 8);
    }
    ctx.clearRect(48, 56, 32, 16); // a transparent slot: a hole in the continuity matte
    const uri = await window.inkwarp.images.blobToDataUri(await c.convertToBlob({ type: 'image/png' }));
    const doc = scene.emptyScene(size, size);
    doc.layers.push({ name: 'slotted', image: uri });
    doc.features.push(
      { id: 'a', kind: 'point', rest: [[8, 8]] }, { id: 'b', kind: 'point', rest: [[119, 8]] },
      { id: 'c', kind: 'point', rest: [[8, 119]] }, { id: 'd', kind: 'point', rest: [[119, 119]] },
      { id: 'lip', kind: 'polyline', rest: [[50, 75], [78, 75]], keys: [{ t: 0, points: [[50, 84], [78, 84]] }] },
    );
    await ui.openScene(doc, 'slotted.json');
    ui.setMode('pose');
  });
  await idle(page);
  const gpu = await frame(page);
  const cpu = await cpuFrame(page);
  // The slot opened: its lower lip moved down, leaving background where it was.
  const i = 4 * (76 * 128 + 64);
  assert(gpu.data[i] > 240 && gpu.data[i + 1] > 240 && gpu.data[i + 2] > 240, `the slot should open at (64, 76): ${gpu.data.subarray(i, i + 4)}`);
  const { ok, stats } = await compareImages(page, gpu, cpu, 'gpu-vs-cpu-hole', { meanTol: 1.5, p99Tol: 40 });
  perf.gpuVsCpuHole = stats;
  await screenshot(page, 'hole');
  assert(ok, `GPU and CPU frames differ around the hole: mean ${stats.mean.toFixed(3)}, p99 ${stats.p99}, max ${stats.max} (tolerance: mean ≤ 1.5, p99 ≤ 40); see test-results/gpu-vs-cpu-hole-diff.png`);
});

test('the GPU frame keeps the CPU renderer\'s order where a part is pushed over a hole\'s own pixels', async () => {
  // An opaque picture whose continuity matte has a hole (its pixels drawn on their own) and
  // a region below it pushed up over it: the part from further down the rest image is in
  // front. The GPU drew every skirt quarter (a hole's pixels among them) after every quad,
  // so the hole's own picture showed on top.
  await page.evaluate(async () => {
    const { ui, scene, images } = window.inkwarp;
    const size = 128;
    const c = new OffscreenCanvas(size, size);
    const ctx = c.getContext('2d');
    for (let y = 0; y < size; y += 8) for (let x = 0; x < size; x += 8) {
      ctx.fillStyle = `hsl(${(x * 3 + y * 5) % 360} 70% ${((x + y) / 8) % 2 ? 40 : 70}%)`;
      ctx.fillRect(x, y, 8, 8);
    }
    const uri = await images.blobToDataUri(await c.convertToBlob({ type: 'image/png' }));
    const m = new OffscreenCanvas(size, size);
    const mctx = m.getContext('2d');
    mctx.fillStyle = '#fff';
    mctx.fillRect(0, 0, size, size);
    mctx.fillStyle = '#000';
    mctx.beginPath();
    mctx.arc(64, 40, 12, 0, 2 * Math.PI);
    mctx.fill();
    const matte = await images.blobToDataUri(await m.convertToBlob({ type: 'image/png' }));
    const doc = scene.emptyScene(size, size);
    doc.layers.push({ name: 'plate', image: uri, continuity: matte });
    const square = [[52, 78], [76, 78], [76, 100], [52, 100]];
    doc.features.push(
      { id: 'a', kind: 'point', rest: [[8, 8]] }, { id: 'b', kind: 'point', rest: [[119, 8]] },
      { id: 'c', kind: 'point', rest: [[8, 119]] }, { id: 'd', kind: 'point', rest: [[119, 119]] },
      { id: 'patch', kind: 'region', rest: square, keys: [{ t: 0, points: square.map(([x, y]) => [x - 34, y - 40]) }] },
    );
    await ui.openScene(doc, 'pushed.json');
    ui.setMode('pose');
  });
  await idle(page);
  const gpu = await frame(page);
  const cpu = await cpuFrame(page);
  const { ok, stats } = await compareImages(page, gpu, cpu, 'gpu-vs-cpu-fold-over-hole', { meanTol: 1.5, p99Tol: 40 });
  perf.gpuVsCpuFoldOverHole = stats;
  await screenshot(page, 'fold-over-hole');
  assert(ok, `GPU and CPU frames differ where the region covers the hole: mean ${stats.mean.toFixed(3)}, p99 ${stats.p99}, max ${stats.max} (tolerance: mean ≤ 1.5, p99 ≤ 40); see test-results/gpu-vs-cpu-fold-over-hole-diff.png`);
  // The matte overlay, posed, marks holes only where the picture shows none of the surface:
  // not inside the stretched, turned surface below the region (it marked dots there).
  const m = await matteMarks(page);
  await overlayOff(page);
  const background = (x, y) => [0, 1, 2].every((c) => gpu.data[4 * (y * m.width + x) + c] > 250);
  let falseHoles = 0;
  for (let y = 1; y < m.height - 1; y++) for (let x = 1; x < m.width - 1; x++) {
    let near = false;
    for (let dy = -1; dy <= 1; dy++) for (let dx = -1; dx <= 1; dx++) near ||= background(x + dx, y + dy);
    if (!near && marked(m, x, y)) falseHoles++;
  }
  assert(falseHoles === 0, `the posed matte overlay marks ${falseHoles} pixels inside the drawn surface as holes`);
});

test('measure: drag latency, settle time and playback on 512×512 with a dozen features', async () => {
  // Reopen the example and trace a dozen features over it.
  await page.evaluate(() => window.inkwarp.ui.openExample('grid'));
  await page.evaluate(() => {
    const { store, state } = window.inkwarp;
    let doc = store.doc;
    const add = (kind, pts) => (doc = state.addFeature(doc, kind, pts).doc);
    add('spline', [[120, 150], [135, 256], [120, 360]]);
    add('polyline', [[200, 420], [256, 440], [312, 420]]);
    add('spline', [[200, 90], [256, 70], [312, 90]]);
    add('point', [[256, 256]]);
    add('point', [[420, 256]]);
    add('region', [[380, 330], [440, 330], [440, 390], [380, 390]]);
    add('polyline', [[60, 200], [60, 310]]);
    store.apply(doc);
  });
  await idle(page);
  await page.evaluate(() => {
    const a = window.inkwarp.app;
    a.stats.dragLatency.length = 0;
    a.stats.settle.length = 0;
    a.stats.draftSolveMs.length = 0;
    a.stats.finalSolveMs.length = 0;
    a.stats.followSolveMs.length = 0;
    a.stats.settleParts.length = 0;
    a.stats.dragParts.length = 0;
  });
  const count = await page.evaluate(() => window.inkwarp.store.doc.features.length);
  await page.keyboard.press('e');
  await idle(page);
  // Two quick drags, pressed as soon as the pointer is on the point, with pauses (each
  // pause lets the full-resolution solve land).
  const framesBefore = await page.evaluate(() => ({ ...window.inkwarp.app.stats.frames }));
  const askedBefore = await page.evaluate(() => ({ ...window.inkwarp.app.stats.probesAsked }));
  for (const [from, to] of [[[135, 256], [175, 246]], [[256, 70], [256, 40]]]) {
    await drag(page, from, to, 15);
    await idle(page);
  }
  const askedQuick = await page.evaluate(() => ({ ...window.inkwarp.app.stats.probesAsked }));
  // Each press probed its point at once (the pointer never rested on it).
  assert(askedQuick.press - askedBefore.press === 2 && askedQuick.rest === askedBefore.rest, `probes asked by the quick drags: ${JSON.stringify([askedBefore, askedQuick])}`);
  // The picture is drawn again only for a new field (a pointer move alone redraws the
  // overlay): at most a frame per field, plus the settles' multisampled frames.
  const frames = await page.evaluate((b) => {
    const { stats } = window.inkwarp.app;
    return { drawn: stats.frames.drawn - b.drawn, overlayOnly: stats.frames.overlayOnly - b.overlayOnly, fields: stats.draftSolveMs.length + stats.finalSolveMs.length };
  }, framesBefore);
  perf.dragFrames = frames;
  assert(frames.overlayOnly > 0 && frames.drawn <= frames.fields + 4, `pictures drawn during the drags: ${JSON.stringify(frames)}`);
  // Playback at 24 fps: two keys on one feature over a quarter second (6 frames). The first
  // pass solves frames as it plays (and ahead of the playhead); later passes play from
  // the solved fields.
  await page.evaluate(() => {
    const { store, state } = window.inkwarp;
    let doc = { ...store.doc, fps: 24, duration: 0.25 };
    doc = state.setKey(doc, 'spline1', 0, [[120, 150], [135, 256], [120, 360]]);
    doc = state.setKey(doc, 'spline1', 0.25, [[140, 150], [185, 256], [140, 360]]);
    store.apply(doc);
  });
  await idle(page);
  await page.evaluate(() => window.inkwarp.ui.setTime(0));
  await idle(page);
  const firstStart = Date.now();
  await page.evaluate(() => window.inkwarp.ui.togglePlay());
  await page.waitForFunction(() => window.inkwarp.app.cachedFrames() >= 6, null, { timeout: 180000, polling: 250 });
  perf.playbackFirstPass = { ...(await page.evaluate(() => window.inkwarp.app.stats.playback)), seconds: (Date.now() - firstStart) / 1000 };
  await page.evaluate(() => window.inkwarp.ui.togglePlay());
  await page.evaluate(() => window.inkwarp.ui.togglePlay());
  await page.waitForTimeout(2000);
  await page.evaluate(() => window.inkwarp.ui.togglePlay());
  // The GPU's own time for one 512×512 frame (with and without multisampling).
  perf.glFrameMs = await page.evaluate(() => {
    const { app } = window.inkwarp;
    const doc = app.store.doc;
    const layers = doc.layers.map((l) => ({ layer: app.runtimes.get(l.name).gl, offset: [0, 0] }));
    const time = (aa, draft) => {
      app.gl.render(doc.width, doc.height, [255, 255, 255, 255], layers, aa, draft);
      app.gl.readPixels();
      const t0 = performance.now();
      for (let i = 0; i < 3; i++) {
        app.gl.render(doc.width, doc.height, [255, 255, 255, 255], layers, aa, draft);
        app.gl.readPixels();
      }
      return (performance.now() - t0) / 3;
    };
    return { multisampled: time(true, false), single: time(false, false), draft: time(false, true), draftAa: time(true, true) };
  });
  const s = await page.evaluate(() => window.inkwarp.app.stats);
  perf.features = count;
  perf.dragLatencyMs = { median: median(s.dragLatency), p90: pct(s.dragLatency, 0.9), n: s.dragLatency.length };
  perf.settleMs = { median: median(s.settle), max: Math.max(...s.settle), n: s.settle.length };
  perf.draftSolveMs = { median: median(s.draftSolveMs), n: s.draftSolveMs.length };
  perf.finalSolveMs = { median: median(s.finalSolveMs), n: s.finalSolveMs.length };
  perf.followSolveMs = { median: median(s.followSolveMs), n: s.followSolveMs.length };
  perf.playback = s.playback;
  perf.settleParts = s.settleParts;
  perf.dragParts = Object.fromEntries(['queued', 'toWorker', 'solve', 'workerDraw', 'back', 'upload', 'toFrame', 'draw', 'gpu', 'total'].map((k) => [k, median(s.dragParts.map((p) => p[k]))]));
  assert(s.dragLatency.length > 0, 'frames were drawn during the drags');
  // The full-resolution solver followed the drags (how far it got by the release depends
  // on the drag's length: see the slower drag below).
  assert(s.followSolveMs.length > 0, 'the full-resolution solver followed the drags');
  // A slower drag (40 moves, most of a second, as a hand moves a point 40 px): the
  // full-resolution solver has caught up with the pointer by the release.
  await page.evaluate(() => window.inkwarp.ui.setTime(0));
  await idle(page);
  const settlesBefore = s.settle.length;
  const dragStart = Date.now();
  await drag(page, [135, 256], [175, 246], 40);
  const dragSeconds = (Date.now() - dragStart) / 1000;
  await idle(page);
  perf.slowDrag = await page.evaluate((k) => {
    const { stats } = window.inkwarp.app;
    return { settleMs: stats.settle.slice(k), parts: stats.settleParts.slice(k) };
  }, settlesBefore);
  perf.slowDrag.seconds = dragSeconds;
  assert(perf.slowDrag.parts.length === 1, `the slower drag settled once: ${JSON.stringify(perf.slowDrag.settleMs)}`);
  // The same quick drags as above (a quarter second), after the pointer has rested on the
  // point for a quarter of a second (`AIM_MS`) as a hand aims: meanwhile the full-resolution solver
  // probes the point (see `App.probe`).
  const probesBefore = (await page.evaluate(() => window.inkwarp.app.stats.probeSolveMs.length));
  const askedBeforeAim = await page.evaluate(() => ({ ...window.inkwarp.app.stats.probesAsked }));
  const aimedBefore = await page.evaluate(() => window.inkwarp.app.stats.settle.length);
  for (const [from, to] of [[[175, 246], [135, 256]], [[135, 256], [175, 246]]]) {
    await drag(page, from, to, 15, AIM_MS);
    await idle(page);
  }
  perf.aimedDrags = await page.evaluate(([k, p]) => {
    const { stats } = window.inkwarp.app;
    return { settleMs: stats.settle.slice(k), parts: stats.settleParts.slice(k), probes: stats.probeSolveMs.slice(p) };
  }, [aimedBefore, probesBefore]);
  assert(perf.aimedDrags.parts.length === 2, `each aimed drag settled once: ${JSON.stringify(perf.aimedDrags.settleMs)}`);
  assert(perf.aimedDrags.probes.length >= 2, `the resting pointer's point was probed before each aimed drag: ${JSON.stringify(perf.aimedDrags.probes)}`);
  // Asked while the pointer rested, not on the press (which found its point probed already).
  const askedAim = await page.evaluate(() => ({ ...window.inkwarp.app.stats.probesAsked }));
  assert(askedAim.rest - askedBeforeAim.rest === 2 && askedAim.press === askedBeforeAim.press, `probes asked by the aimed drags: ${JSON.stringify([askedBeforeAim, askedAim])}`);
  await screenshot(page, 'measured');
});

test('measure: dragging under each method on the same scene', async () => {
  perf.dragByMethod = {};
  await page.evaluate(() => window.inkwarp.ui.setTime(0.125));
  for (const m of ['tps-exact', 'triangulation', 'beier-neely', 'tps']) {
    await page.selectOption('#method', m);
    await idle(page);
    await page.evaluate(() => {
      const s = window.inkwarp.app.stats;
      for (const k of ['dragLatency', 'settle', 'draftSolveMs', 'finalSolveMs']) s[k].length = 0;
    });
    await drag(page, [256, 256], [276, 236], 15);
    await idle(page);
    const s = await page.evaluate(() => window.inkwarp.app.stats);
    perf.dragByMethod[m] = {
      dragLatencyMs: { median: median(s.dragLatency), n: s.dragLatency.length },
      settleMs: median(s.settle),
      draftSolveMs: median(s.draftSolveMs),
      finalSolveMs: median(s.finalSolveMs),
    };
    await page.keyboard.press('Control+z');
    await idle(page);
  }
});

test('a draft frame drawn during a drag looks like the full frame of the same field', async () => {
  // On the measured scene (12 features): hold a point and move it; the first frame drawn
  // from a draft field while the pointer is down is read back, then the same field is
  // drawn as a full frame, each draw timed (read back included, which waits for the GPU).
  await page.evaluate(() => {
    const { app } = window.inkwarp;
    window.draftProbe = null;
    const shown = app.onFrame;
    app.onFrame = () => {
      shown();
      // (The full-resolution worker may be following the drag meanwhile, on the other core.)
      if (window.draftProbe || !app.dragging || app.lastReport?.tag.quality !== 'draft') return;
      const timed = (draft) => {
        const t0 = performance.now();
        app.draw(draft);
        const px = app.gl.readPixels();
        return { ms: performance.now() - t0, px };
      };
      // The draft as shown: solved at the draft mesh's pixels only (a sparse draft).
      const doc = app.store.doc;
      const layer = doc.layers[0];
      const rt = app.runtimes.get(layer.name);
      const wasSparse = rt.gl.sparse;
      const cpu = app.gl.cpuDrafts;
      const sparse = timed(true);
      // The same sparse draft drawn by WebGL2 (where the CPU drew the one shown).
      app.gl.cpuDrafts = false;
      const sparseGl = timed(true);
      app.gl.cpuDrafts = cpu;
      // The same pose solved at every pixel by the page's own engine (the draft's options,
      // from a cold start), drawn as a draft and as a full frame.
      const { engine } = window.inkwarp;
      const cuts = doc.features.filter((f) => f.kind === 'cut' && (!layer.features || layer.features.includes(f.id))).map((f) => f.rest);
      const grid = engine.grid(doc.width, doc.height, rt.matte, cuts);
      const { field } = grid.solve(app.solveFeatures(layer, app.store.view.time), app.solverOptions(layer, 'draft'), null);
      grid.free();
      rt.gl.setField(field);
      const draft = timed(true);
      const full = timed(false);
      const again = timed(true); // the canvas shows the draft again
      const b64 = window.pixelsB64;
      window.draftProbe = { w: doc.width, h: doc.height, wasSparse, cpu, sparse: b64(sparse.px), sparseGl: b64(sparseGl.px), draft: b64(draft.px), full: b64(full.px), draftMs: Math.min(sparseGl.ms, draft.ms, again.ms), cpuDraftMs: sparse.ms, fullMs: full.ms };
    };
  });
  const [x0, y0] = await toClient(page, [256, 256]);
  const [x1, y1] = await toClient(page, [290, 226]);
  await page.mouse.move(x0, y0);
  await page.mouse.down();
  for (let i = 1; i <= 6; i++) {
    await page.mouse.move(x0 + ((x1 - x0) * i) / 6, y0 + ((y1 - y0) * i) / 6);
    await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => r())));
  }
  await page.waitForFunction(() => window.draftProbe !== null, null, { timeout: 60000, polling: 20 });
  await page.screenshot({ path: join(screens, 'editor-drag-draft.png') });
  await page.mouse.up();
  const probe = await page.evaluate(() => window.draftProbe);
  await page.evaluate(() => (window.inkwarp.app.onFrame = () => {}));
  const img = (b64) => image(probe.w, probe.h, b64);
  const draft = img(probe.draft);
  const full = img(probe.full);
  // The sparse draft is the draft of the field solved at every pixel (up to the solver's
  // tolerance: one started warm from the earlier drafts, the other cold).
  assert(probe.wasSparse, 'the draft shown during the drag was not a sparse draft');
  const sparse = img(probe.sparseGl);
  const same = await compareImages(page, sparse, draft, 'sparse-vs-draft', { meanTol: 0.2, p99Tol: 4 });
  perf.sparseVsDraft = same.stats;
  assert(same.ok, `the sparse draft differs from the draft of the full field: mean ${same.stats.mean.toFixed(3)}, p99 ${same.stats.p99} (tolerance: mean ≤ 0.2, p99 ≤ 4); see test-results/sparse-vs-draft-diff.png`);
  // On a software GPU the CPU draws the draft shown: the same triangles and colours as the
  // WebGL2 draft, up to the rounding of the rest positions and filter weights (a level at
  // high-contrast edges) and a few pixel centres on the cut's edges.
  if ((perf.renderer ?? '').includes('SwiftShader')) assert(probe.cpu, `CPU drafts off with ${perf.renderer}`);
  if (probe.cpu) {
    const c = await compareImages(page, img(probe.sparse), sparse, 'cpu-vs-gpu-draft', { meanTol: 0.5, p99Tol: 4 });
    perf.cpuVsGpuDraft = { ...c.stats, cpuMs: probe.cpuDraftMs };
    assert(c.ok, `the CPU's draft differs from the GPU's: mean ${c.stats.mean.toFixed(3)}, p99 ${c.stats.p99} (tolerance: mean ≤ 0.5, p99 ≤ 4); see test-results/cpu-vs-gpu-draft-diff.png`);
  }
  await savePng(page, draft, join(screens, 'frame-draft.png'));
  await savePng(page, full, join(screens, 'frame-draft-field-full.png'));
  // Loose: the draft bends the picture piecewise affinely over 8-pixel blocks and samples
  // once a pixel; the full frame follows the field at every pixel and is antialiased.
  const { ok, stats } = await compareImages(page, draft, full, 'draft-vs-full', { meanTol: 6, p99Tol: 255 });
  perf.draftVsFull = { ...stats, draftMs: probe.draftMs, fullMs: probe.fullMs };
  assert(ok, `a draft frame differs from the full frame of the same field: mean ${stats.mean.toFixed(2)} levels (tolerance: mean ≤ 6); see test-results/draft-vs-full-diff.png`);
  await screenshot(page, 'drag-settled');
  await page.keyboard.press('Control+z');
  await idle(page);
});

test('the fast full frame (fans where the field is smooth) matches the full frame of the same field', async () => {
  // After a drag settles, a software GPU shows the full-resolution field first through the
  // fans of `adaptiveTriangles`, single-sampled (drawn by the CPU there: `GlLayer.cpuFull`);
  // here it is drawn beside the full mesh's single-sampled WebGL2 frame of the same field.
  await drag(page, [135, 256], [185, 236], 6);
  await idle(page);
  const probe = await page.evaluate(() => {
    const { app } = window.inkwarp;
    const timed = (adaptive) => {
      const t0 = performance.now();
      app.draw(false, false, adaptive);
      const px = app.gl.readPixels();
      return { ms: performance.now() - t0, px };
    };
    timed(true); // uploads the triangles (the worker sent them with the field)
    const fast = timed(true);
    const full = timed(false);
    const count = [...app.runtimes.values()].reduce((n, rt) => [n[0] + rt.gl.adaptiveCount / 3, n[1] + rt.gl.count / 3], [0, 0]);
    const b64 = window.pixelsB64;
    app.renderNow();
    return { w: app.store.doc.width, h: app.store.doc.height, fast: b64(fast.px), full: b64(full.px), fastMs: fast.ms, fullMs: full.ms, triangles: count[0], fullTriangles: count[1] };
  });
  const img = (b64) => image(probe.w, probe.h, b64);
  const fast = img(probe.fast);
  const full = img(probe.full);
  await savePng(page, fast, join(screens, 'frame-fast-full.png'));
  // Every pixel is placed within 0.05 px of the full mesh's place: the differences are
  // antialiasing-free edge pixels whose centre falls on the other side of an edge.
  const { ok, stats } = await compareImages(page, fast, full, 'fast-vs-full', { meanTol: 0.5, p99Tol: 8 });
  perf.fastVsFull = { ...stats, fastMs: probe.fastMs, fullMs: probe.fullMs, triangles: probe.triangles, fullTriangles: probe.fullTriangles };
  assert(probe.triangles > 0 && probe.triangles < probe.fullTriangles, `the fast frame drew ${probe.triangles} triangles against ${probe.fullTriangles}`);
  assert(ok, `the fast full frame differs from the full frame: mean ${stats.mean.toFixed(2)}, p99 ${stats.p99} (tolerance: mean ≤ 0.5, p99 ≤ 8); see test-results/fast-vs-full-diff.png`);
  await page.keyboard.press('Control+z');
  await idle(page);
});

test('every bundled example opens', async () => {
  const names = await page.evaluate(async () => (await window.inkwarp.examples.listExamples()).map((e) => e.name));
  perf.examples = names;
  for (const name of names) {
    await page.evaluate((n) => window.inkwarp.ui.openExample(n), name);
    await idle(page);
    const state = await page.evaluate(() => ({
      layers: window.inkwarp.store.doc.layers.length,
      message: document.querySelector('#message.error:not([hidden])')?.textContent ?? null,
      loaded: [...window.inkwarp.app.runtimes.values()].every((rt) => rt.gridReady && !rt.error),
    }));
    assert(state.layers > 0 && state.loaded && state.message === null, `example ${name}: ${JSON.stringify(state)}`);
    if (name === 'face' || name === 'cat') {
      // Posed at a frame where the picture moves (the cat rests at half way): every layer
      // solves and draws without an error, and the frames compared below are warped.
      await page.evaluate(() => window.inkwarp.ui.setMode('pose'));
      let moved = 0;
      for (const at of [0.5, 0.4, 0.6, 0.3, 0.7]) {
        await page.evaluate((a) => window.inkwarp.ui.setTime(Math.round(window.inkwarp.store.doc.duration * 24 * a) / 24), at);
        await idle(page);
        moved = await page.evaluate(() => Math.max(0, ...[...window.inkwarp.app.runtimes.values()].map((rt) => (rt.field ? rt.field.dx.reduce((m, v, i) => Math.max(m, Math.abs(v), Math.abs(rt.field.dy[i])), 0) : 0))));
        if (moved > 1) break;
      }
      assert(moved > 1, `example ${name}: no frame tried moves the picture`);
      perf[`posedPx_${name}`] = moved;
      const ok = await page.evaluate(() => [...window.inkwarp.app.runtimes.values()].every((rt) => rt.field && !rt.error));
      assert(ok, `example ${name}: every layer has a field in pose mode`);
      const cmp = await compareImages(page, await frame(page), await cpuFrame(page), `gpu-vs-cpu-${name}`, { meanTol: 1.0, p99Tol: 12 });
      perf[`gpuVsCpu_${name}`] = cmp.stats;
      assert(cmp.ok, `example ${name}: GPU and CPU frames differ (mean ${cmp.stats.mean.toFixed(3)}, p99 ${cmp.stats.p99}); see test-results/gpu-vs-cpu-${name}-diff.png`);
      await screenshot(page, `example-${name}`);
      // Every layer's sparse draft of the same pose (solved by the page's engine at the
      // draft mesh's pixels), drawn by the CPU and by WebGL2: several layers and holes
      // (offsets and opacity are covered by the unit tests of the CPU's drafts).
      const drafts = await page.evaluate(() => {
        const { app, engine } = window.inkwarp;
        const doc = app.store.doc;
        for (const layer of doc.layers) {
          const rt = app.runtimes.get(layer.name);
          const grid = engine.grid(rt.gl.width, rt.gl.height, rt.matte, app.cutsOf(layer));
          grid.select(rt.gl.draftPixels);
          const { values } = grid.solveAt(app.solveFeatures(layer, app.store.view.time), app.solverOptions(layer, 'draft'));
          grid.free();
          rt.gl.setSparseField(values);
        }
        const read = (cpu) => {
          const was = app.gl.cpuDrafts;
          app.gl.cpuDrafts = cpu;
          app.draw(true);
          const px = app.gl.readPixels();
          app.gl.cpuDrafts = was;
          return window.pixelsB64(px);
        };
        // The CPU draws drafts only on a software GPU (elsewhere both reads would be WebGL2's).
        const onCpu = doc.layers.every((layer) => app.runtimes.get(layer.name).gl.onCpu);
        const out = { w: doc.width, h: doc.height, onCpu, software: app.gl.softwareGpu, cpu: read(true), gl: read(false) };
        for (const layer of doc.layers) {
          const rt = app.runtimes.get(layer.name);
          rt.gl.setField(rt.field);
        }
        app.draw(false);
        return out;
      });
      if (!drafts.onCpu) {
        // A hardware GPU: its drafts are WebGL2's, there is no CPU draft to compare.
        assert(!drafts.software, `example ${name}: the CPU does not draw every layer's draft on a software GPU`);
        continue;
      }
      const im = (b64) => image(drafts.w, drafts.h, b64);
      const dc = await compareImages(page, im(drafts.cpu), im(drafts.gl), `cpu-vs-gpu-draft-${name}`, { meanTol: 0.5, p99Tol: 4 });
      perf[`cpuVsGpuDraft_${name}`] = dc.stats;
      assert(dc.ok, `example ${name}: the CPU's draft differs from WebGL2's (mean ${dc.stats.mean.toFixed(3)}, p99 ${dc.stats.p99}); see test-results/cpu-vs-gpu-draft-${name}-diff.png`);
    }
  }
});

test('`inkwarp edit SCENE` opens the scene and Save writes it back', async () => {
  const dir = scratchDir('inkwarp-edit-');
  const png = await page.evaluate(async () => {
    const c = new OffscreenCanvas(64, 48);
    const ctx = c.getContext('2d');
    ctx.fillStyle = '#3a7';
    ctx.fillRect(0, 0, 64, 48);
    const buf = new Uint8Array(await (await c.convertToBlob({ type: 'image/png' })).arrayBuffer());
    return btoa(String.fromCharCode(...buf));
  });
  writeFileSync(join(dir, 'green.png'), Buffer.from(png, 'base64'));
  const scenePath = join(dir, 'small.json');
  writeFileSync(scenePath, JSON.stringify({ inkwarp: 1, width: 64, height: 48, fps: 12, duration: 1, layers: [{ name: 'green', image: 'green.png' }], features: [] }));
  const own = await startServer([scenePath]);
  try {
    const ed = await openEditor(browser, own.url);
    const doc = await ed.page.evaluate(() => window.inkwarp.store.doc);
    assert(doc.width === 64 && doc.layers[0].image.startsWith('data:image/png'), 'the scene opened with its image inlined');
    await ed.page.keyboard.press('p');
    await click(ed.page, [20, 20]);
    await ed.page.keyboard.press('Control+s');
    await ed.page.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    const saved = JSON.parse(readFileSync(scenePath, 'utf8'));
    assert(saved.layers[0].image === 'green.png', `the image keeps its path: ${saved.layers[0].image.slice(0, 40)}`);
    assert(saved.features.length === 1 && saved.features[0].kind === 'point', 'the new point was saved');
    // Export the frame as PNG: the file holds the frame on screen.
    const [png] = await Promise.all([ed.page.waitForEvent('download'), ed.page.click('#export-png')]);
    const pngPath = join(dir, 'frame.png');
    await png.saveAs(pngPath);
    const exported = await loadPng(ed.page, pngPath);
    const shown = await frame(ed.page);
    const cmp = await compareImages(ed.page, exported, shown, 'export-png', { meanTol: 0, p99Tol: 0 });
    assert(cmp.ok, `the exported PNG differs from the frame on screen (mean ${cmp.stats.mean})`);
    // Export the animation as WebM.
    const [webm] = await Promise.all([ed.page.waitForEvent('download', { timeout: 60000 }), ed.page.click('#export-webm')]);
    const webmPath = join(dir, 'anim.webm');
    await webm.saveAs(webmPath);
    const head = readFileSync(webmPath).subarray(0, 4);
    assert(head.equals(Buffer.from([0x1a, 0x45, 0xdf, 0xa3])) && readFileSync(webmPath).length > 200, `the WebM file is not a WebM video (${head.toString('hex')})`);
    // Drop a picture on the window: a new scene of its size.
    await ed.page.evaluate(async () => {
      const c = new OffscreenCanvas(40, 30);
      c.getContext('2d').fillRect(0, 0, 20, 30);
      const file = new File([await c.convertToBlob({ type: 'image/png' })], 'dropped.png', { type: 'image/png' });
      const dt = new DataTransfer();
      dt.items.add(file);
      window.dispatchEvent(new DragEvent('drop', { dataTransfer: dt, bubbles: true, cancelable: true }));
    });
    await ed.page.waitForFunction(() => window.inkwarp.store.doc.width === 40);
    await idle(ed.page);
    const dropped = await ed.page.evaluate(() => window.inkwarp.store.doc.layers.map((l) => l.name));
    assert(JSON.stringify(dropped) === '["dropped"]', `dropping a picture opened ${dropped}`);
    assert(ed.errors.length === 0, `the page logged errors: ${ed.errors.join('; ')}`);
    await ed.context.close();
  } finally {
    own.proc.kill();
  }
});

test('`inkwarp edit SCENE` on a scene with a mistake names the file and shows the example instead', async () => {
  const dir = scratchDir('inkwarp-edit-bad-');
  const black = new Uint8Array(64 * 48 * 4).map((_, i) => (i % 4 === 3 ? 255 : 0));
  await savePng(page, image(64, 48, Buffer.from(black).toString('base64')), join(dir, 'black.png'));
  const scenePath = join(dir, 'keycount.json');
  const bad = { inkwarp: 1, width: 64, height: 48, fps: 12, duration: 1, layers: [{ name: 'black', image: 'black.png' }],
    features: [{ id: 'arm', kind: 'polyline', rest: [[4, 4], [20, 4], [30, 10], [40, 20]], keys: [{ t: 0.5, points: [[4, 4], [20, 4], [30, 10]] }] }] };
  writeFileSync(scenePath, JSON.stringify(bad));
  const own = await startServer([scenePath]);
  try {
    const ed = await openEditor(browser, own.url);
    const said = await ed.page.evaluate(() => document.querySelector('#message')?.textContent ?? '');
    assert(said.startsWith(scenePath) && /features\[0\]\.keys\[0\]/.test(said), `the message names the file and the place: ${said}`);
    // The built-in example is drawn, not an empty stage (its picture was never loaded).
    const shown = await frame(ed.page);
    let coloured = 0;
    for (let i = 0; i < shown.data.length; i += 4) coloured += Math.max(shown.data[i], shown.data[i + 1], shown.data[i + 2]) - Math.min(shown.data[i], shown.data[i + 1], shown.data[i + 2]) > 60 ? 1 : 0;
    assert(coloured > shown.data.length / 40, `the example's picture is not drawn (${coloured} coloured pixels)`);
    await ed.context.close();
  } finally {
    own.proc.kill();
  }
});

// ---------------------------------------------------------------------------------------
// Trust: work is never lost, time behaves, the border holds.

test('a reload restores the work; leaving asks first; opening over unsaved work asks and Undo brings it back', async () => {
  const { page: p, context, errors: errs } = await openEditor(browser, server.url);
  try {
    await tracePoint(p, [100, 300]);
    await p.keyboard.press('e');
    await p.keyboard.press('v');
    await drag(p, [100, 300], [130, 290]);
    const before = await p.evaluate(() => JSON.stringify(window.inkwarp.store.doc.features));
    const viewBefore = await p.evaluate(() => ({ mode: window.inkwarp.store.view.mode, time: window.inkwarp.store.view.time }));
    assert(await p.evaluate(() => window.inkwarp.store.unsaved), 'the edits are unsaved');
    assert(!(await p.evaluate(() => document.querySelector('#undo').disabled)), 'Undo is enabled right after the drag');
    await flush(p);
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    assert(p.dialogs.includes('beforeunload'), `leaving with unsaved changes asked first (dialogs: ${p.dialogs})`);
    await p.waitForSelector('#restore');
    const question = await p.textContent('#restore span');
    assert(/^Restore the scene you were editing at \d\d:\d\d\?$/.test(question), `the offer reads: ${question}`);
    await screenshot(p, 'restore');
    await restoreYes(p);
    await p.waitForFunction((f) => JSON.stringify(window.inkwarp.store.doc.features) === f, before, { timeout: 10000 });
    const shown = await p.evaluate(() => ({ unsaved: window.inkwarp.store.unsaved, images: window.inkwarp.store.doc.layers.every((l) => !l.image || l.image.startsWith('data:')) }));
    assert(shown.unsaved && shown.images, `restored unsaved, with its images: ${JSON.stringify(shown)}`);
    const viewAfter = await p.evaluate(() => ({ mode: window.inkwarp.store.view.mode, time: window.inkwarp.store.view.time }));
    assert(viewBefore.mode === 'pose' && JSON.stringify(viewAfter) === JSON.stringify(viewBefore), `restored in the mode and at the time it was left: ${JSON.stringify([viewBefore, viewAfter])}`);
    // Opening over unsaved work asks; declined, nothing changes.
    p.declineDialogs = true;
    p.dialogs.length = 0;
    await p.evaluate(() => window.inkwarp.ui.openExample('builtin'));
    assert(p.dialogs.includes('confirm'), 'opening over unsaved work asked first');
    assert((await p.evaluate(() => JSON.stringify(window.inkwarp.store.doc.features))) === before, 'declined: the scene stayed');
    p.declineDialogs = false;
    await p.evaluate(() => window.inkwarp.ui.openExample('builtin'));
    assert((await p.evaluate(() => window.inkwarp.store.doc.features.length)) === 5, 'accepted: the example opened');
    const opened = await p.$eval('#message', (m) => (!m.hidden && m.classList.contains('info') ? m.textContent : null));
    await p.keyboard.press('Control+z');
    await idle(p);
    // The note about the scene just opened goes with it (it said "Opened ..." over the work brought back).
    const left = await p.$eval('#message', (m) => (m.hidden ? null : m.textContent));
    assert(opened !== null && left !== opened, `the opening's note left with it: ${JSON.stringify([opened, left])}`);
    assert((await p.evaluate(() => JSON.stringify(window.inkwarp.store.doc.features))) === before, 'Undo brought the work back after opening');
    // A saved scene is not offered again.
    await p.evaluate(() => window.inkwarp.store.markSaved());
    await flush(p);
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    await p.waitForTimeout(500);
    assert((await p.$('#restore')) === null, 'no offer after saving');
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
  }
});

test('a picture just opened is no unsaved work: no ●, and opening another asks nothing', async () => {
  const { page: p, context, errors: errs } = await openEditor(browser, server.url);
  try {
    // Two different pictures, so that the second open is waited for (a dialog would come before it).
    for (const [path, name] of [['checkerboard-hole/checkerboard.png', 'checkerboard'], ['face/face.png', 'face']]) {
      await p.setInputFiles('input[type=file][accept^=".json"]', join(repo, 'examples', path));
      await p.waitForFunction((n) => window.inkwarp.store.doc.layers[0]?.name === n, name);
      await idle(p);
    }
    const state = await p.evaluate(() => ({ unsaved: window.inkwarp.store.unsaved, title: document.title }));
    assert(!state.unsaved && !state.title.startsWith('●'), `opened, not marked: ${JSON.stringify(state)}`);
    assert(!p.dialogs.includes('confirm'), `opening over an untouched picture asked: ${p.dialogs}`);
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
  }
});

test('edits made while the restore offer waits: leaving asks, and the offered work stays', async () => {
  const { page: p, context, errors: errs } = await openEditor(browser, server.url);
  try {
    const rests = () => p.evaluate(() => JSON.stringify(window.inkwarp.store.doc.features.map((f) => f.rest)));
    await tracePoint(p, [100, 300]);
    await flush(p);
    const offered = await rests();
    await p.reload();
    await p.waitForSelector('#restore');
    // Not answered: the editor works meanwhile, and what is drawn now is unsaved work too,
    // marked in the title and kept in the browser apart from the offered copy (a crash
    // before the answer lost it).
    await p.keyboard.press('p');
    await click(p, [160, 320]);
    assert(await p.evaluate(() => window.inkwarp.store.unsaved), 'the edit made during the offer is unsaved');
    assert((await p.title()).startsWith('● '), `the title marks it: ${await p.title()}`);
    const kept = () => p.evaluate(() => new Promise((resolve, reject) => {
      const req = indexedDB.open('inkwarp-editor', 1);
      req.onerror = () => reject(req.error);
      req.onsuccess = () => {
        const all = {};
        const cursor = req.result.transaction('autosave').objectStore('autosave').openCursor();
        cursor.onsuccess = () => {
          const c = cursor.result;
          if (!c) { req.result.close(); resolve(all); return; }
          all[String(c.key)] = JSON.stringify(c.value.doc.features.map((f) => f.rest));
          c.continue();
        };
      };
    }));
    let copies = {};
    for (let i = 0; i < 40 && !Object.keys(copies).some((k) => k.includes('-meanwhile-')); i++) {
      await new Promise((r) => setTimeout(r, 100));
      copies = await kept();
    }
    const drawn = await rests();
    const meanwhile = Object.entries(copies).filter(([k]) => k.includes('-meanwhile-'));
    assert(drawn !== offered && meanwhile.length === 1 && meanwhile[0][1] === drawn, `the edit is kept apart: ${JSON.stringify(copies)}`);
    assert(Object.entries(copies).some(([k, r]) => !k.includes('-meanwhile-') && r === offered), `the offered copy stays as it was: ${JSON.stringify(copies)}`);
    p.dialogs.length = 0;
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    assert(p.dialogs.includes('beforeunload'), `leaving during the offer asked first (dialogs: ${p.dialogs})`);
    await p.waitForSelector('#restore');
    // Left by leaving the page, the copy apart stays, to be offered as a closed tab's work.
    const first = meanwhile[0][0];
    assert(first in (await kept()), 'the edits made during the first offer are still kept');
    // Answered on the page where they were made, this tab's own copy takes them over and
    // the copy apart goes.
    await p.keyboard.press('p');
    await click(p, [200, 340]);
    const now = await rests();
    const others = () => Object.keys(copies).filter((k) => k.includes('-meanwhile-') && k !== first);
    for (let i = 0; i < 40 && others().length === 0; i++) {
      await new Promise((r) => setTimeout(r, 100));
      copies = await kept();
    }
    assert(others().length === 1, `the new edits are kept apart too: ${JSON.stringify(copies)}`);
    await p.click('#restore-no');
    for (let i = 0; i < 40 && others().length > 0; i++) {
      await new Promise((r) => setTimeout(r, 100));
      copies = await kept();
    }
    assert(others().length === 0 && first in copies, `the copy apart is dropped once answered: ${JSON.stringify(copies)}`);
    assert(Object.entries(copies).some(([k, r]) => !k.includes('-meanwhile-') && r === now), `this tab's copy holds them: ${JSON.stringify(copies)}`);
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
  }
});

/** A scene file `name` in a new folder: the checkerboard picture beside it, no features. */
function checkerScene(name) {
  const dir = scratchDir('inkwarp-served-');
  copyFileSync(join(repo, 'examples/checkerboard-hole/checkerboard.png'), join(dir, 'checker.png'));
  const scenePath = join(dir, name);
  writeFileSync(scenePath, JSON.stringify({ inkwarp: 1, fps: 12, duration: 1, layers: [{ name: 'checker', image: 'checker.png' }], features: [] }));
  return scenePath;
}

test('a picture of the scene retouched by another program is told, the scene left as it was', async () => {
  const scenePath = checkerScene('retouch.json');
  await withServedEditor([scenePath], async ({ page: p }) => {
    const message = () => p.textContent('#message');
    assert(!/changed/.test(await message()), `nothing told at first: ${await message()}`);
    // Another program writes the picture (another PNG under the same name).
    copyFileSync(join(repo, 'examples/checkerboard-hole/matte-hole.png'), join(dirname(scenePath), 'checker.png'));
    await p.evaluate(() => window.dispatchEvent(new Event('focus')));
    await p.waitForFunction(() => /checker\.png of layer 'checker' was changed or removed on disk since this tab opened it/.test(document.querySelector('#message')?.textContent ?? ''), null, { timeout: 10000 });
    assert(/Reload the page to see it/.test(await message()), `what to do is said: ${await message()}`);
    // The scene file is as it was: still saved, and the notice is not repeated.
    assert(!(await p.evaluate(() => window.inkwarp.store.unsaved)), 'the scene stays saved');
    await p.evaluate(() => window.inkwarp.ui.message('seen', 'info'));
    await p.evaluate(() => window.inkwarp.ui.checkFile());
    assert(await message() === 'seen', `told once: ${await message()}`);
  });
});

test('a scene opened by inkwarp edit is where Undo stops, and Undo after a restore brings it back as saved', async () => {
  const scenePath = checkerScene('history.json');
  await withServedEditor([scenePath], async ({ page: p }) => {
    const state = () => p.evaluate(() => ({
      layer: window.inkwarp.store.doc.layers[0]?.name, features: window.inkwarp.store.doc.features.length,
      unsaved: window.inkwarp.store.unsaved, title: document.title, undo: !document.querySelector('#undo').disabled,
    }));
    // (Before, the built-in example shown while the scene loaded was an undo step: Ctrl+Z
    // swapped the scene for it, and a save then downloaded the example under its name.)
    let now = await state();
    assert(now.layer === 'checker' && !now.undo && !now.unsaved, `opened, nothing to undo: ${JSON.stringify(now)}`);
    await p.keyboard.press('Control+z');
    await idle(p);
    now = await state();
    assert(now.layer === 'checker' && !now.unsaved, `Ctrl+Z right after opening keeps the scene: ${JSON.stringify(now)}`);
    await p.keyboard.press('p');
    await click(p, [40, 40]);
    await idle(p);
    await flush(p);
    // Meanwhile another program writes the file (a longer duration): the restore says so.
    writeFileSync(scenePath, JSON.stringify({ inkwarp: 1, fps: 12, duration: 2, layers: [{ name: 'checker', image: 'checker.png' }], features: [] }));
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    await p.waitForSelector('#restore', { timeout: 10000 });
    await restoreYes(p);
    await p.waitForFunction(() => window.inkwarp.store.doc.features.length === 1, null, { timeout: 10000 });
    const said = await p.textContent('#message');
    assert(/history\.json was changed since \(by another tab or program\), so Save asks before writing over it/.test(said), `the restore says the file changed: ${said}`);
    now = await state();
    assert(now.unsaved && now.title.startsWith('● '), `restored, unsaved: ${JSON.stringify(now)}`);
    // Undo brings back the scene as its file has it: saved, unmarked; and nothing before it.
    await p.keyboard.press('Control+z');
    await idle(p);
    now = await state();
    assert(now.layer === 'checker' && now.features === 0 && !now.unsaved && !now.title.startsWith('● ') && !now.undo,
      `Undo after the restore: the file's scene, saved: ${JSON.stringify(now)}`);
    assert(await p.evaluate(() => window.inkwarp.store.doc.duration) === 2, 'as the file has it now');
    // The tab's checks of the file leave it so (the restored work's origin knew the older version).
    await p.evaluate(() => window.inkwarp.ui.checkFile());
    assert(!(await state()).unsaved, 'still saved after a check of the file');
  });
});

test('a scene opened by inkwarp edit: a reload offers its unsaved work back, which saves to the file', async () => {
  const scenePath = checkerScene('kept.json');
  await withServedEditor([scenePath], async ({ page: p, own }) => {
    await p.keyboard.press('p');
    await click(p, [40, 40]);
    await idle(p);
    assert(await p.evaluate(() => window.inkwarp.store.unsaved && window.inkwarp.store.doc.features.length === 1), 'a point was added, unsaved');
    await flush(p);
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    await p.waitForSelector('#restore', { timeout: 10000 });
    const question = await p.textContent('#restore span');
    assert(/^Restore the scene you were editing at \d\d:\d\d\?$/.test(question), `the offer reads: ${question}`);
    await restoreYes(p);
    await p.waitForFunction(() => window.inkwarp.store.doc.features.length === 1, null, { timeout: 10000 });
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    const saved = JSON.parse(readFileSync(scenePath, 'utf8'));
    assert(saved.features.length === 1 && saved.layers[0].image === 'checker.png', `the restored work went back to its file: ${JSON.stringify(saved).slice(0, 120)}`);
    // Its picture moved away, the file does not open; work kept from it is still its own
    // (it was offered as another scene's, and then saved only by download, for good).
    await p.keyboard.press('p');
    await click(p, [60, 60]);
    await idle(p);
    await flush(p);
    const picture = join(dirname(scenePath), 'checker.png');
    renameSync(picture, `${picture}.moved`);
    await p.reload();
    await p.waitForSelector('#restore', { timeout: 10000 });
    const again = await p.textContent('#restore span');
    assert(/^Restore the scene you were editing at \d\d:\d\d\?$/.test(again), `offered as the file's own: ${again}`);
    await p.click('#restore-yes');
    // From the moment the restored scene shows (a save then goes to its file, not a download).
    await p.waitForFunction(() => window.inkwarp.store.doc.features.length === 2, null, { timeout: 10000 });
    assert((await p.evaluate(() => window.inkwarp.store.origin.saveUrl)) !== null, 'it saves to its file');
    await p.waitForFunction(() => /Restored the scene/.test(document.querySelector('#message')?.textContent ?? ''), null, { timeout: 10000 });
    renameSync(`${picture}.moved`, picture);
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    assert(JSON.parse(readFileSync(scenePath, 'utf8')).features.length === 2, 'the work went back to its file');
  });
});

test('an edit is kept when the whole browser closes 0.4 s after it', async () => {
  // The kept copy was written 0.8 s after the last change (its picture read again each
  // time): closing or killing the browser sooner lost the edit. Now 0.15 s after a burst,
  // the picture read once.
  const scenePath = checkerScene('closed.json');
  const profile = scratchDir('inkwarp-profile-');
  const own = await startServer([scenePath]);
  try {
    const first = await openEditor(browser, own.url, undefined, profile);
    await flush(first.page); // the page's first copy (its picture read)
    await first.page.keyboard.press('p');
    await click(first.page, [60, 60]);
    await first.page.waitForTimeout(400);
    await first.context.close(); // no "Leave site?": the browser is closed, not the tab
    const again = await openEditor(browser, own.url, undefined, profile);
    try {
      await again.page.waitForSelector('#restore', { timeout: 10000 });
      await restoreYes(again.page);
      const n = await again.page.evaluate(() => window.inkwarp.store.doc.features.length);
      assert(n === 1, `the point drawn before the close came back: ${n} features`);
    } finally {
      await again.context.close();
    }
  } finally {
    own.proc.kill();
  }
});

test('a scene with a large picture: every reload offers its work back and keeps what is drawn after', async () => {
  // Its kept copy holds the picture (1.5 MB of noise here, as a photograph is): a browser
  // profile on disk stores so large a value apart, and its read outlasted a committed
  // transaction, so after the first reload the editor kept nothing and offered nothing.
  const dir = scratchDir('inkwarp-large-');
  const made = spawnSync(join(repo, '.venv/bin/python'), ['-c', `import numpy as np; from PIL import Image
Image.fromarray(np.random.default_rng(0).integers(0, 256, (700, 700, 3), dtype=np.uint8)).save('${join(dir, 'noise.png')}')`], { encoding: 'utf8' });
  assert(made.status === 0, `the picture was made: ${made.stderr}`);
  const scenePath = join(dir, 'large.json');
  writeFileSync(scenePath, JSON.stringify({ inkwarp: 1, fps: 12, duration: 1, layers: [{ name: 'noise', image: 'noise.png' }], features: [] }));
  await withServedEditor([scenePath], async ({ page: p, errors }) => {
    await p.waitForTimeout(1000);
    await p.reload(); // with nothing changed: the tab's own kept copy is read back
    await p.waitForSelector('body[data-ready]');
    await idle(p);
    for (const at of [[40, 40], [80, 80]]) {
      await p.keyboard.press('p');
      await click(p, at);
      await idle(p);
      await p.waitForFunction(() => document.title.startsWith('●'), null, { timeout: 10000 });
      const count = await p.evaluate(() => window.inkwarp.store.doc.features.length);
      await flush(p);
      await p.reload();
      await p.waitForSelector('body[data-ready]');
      await p.waitForSelector('#restore', { timeout: 10000 });
      await restoreYes(p);
      await p.waitForFunction((n) => window.inkwarp.store.doc.features.length === n, count, { timeout: 10000 });
      assert(errors.length === 0, `page errors after reload with ${count} features: ${errors.join('; ')}`);
    }
  }, scratchDir('inkwarp-profile-'));
});

test('a value typed into a field and not entered is kept when the page is left', async () => {
  const scenePath = checkerScene('typed.json');
  await withServedEditor([scenePath], async ({ page: p, own }) => {
    await p.fill('#duration', '0.5'); // no Enter, the field still focused
    assert((await p.evaluate(() => window.inkwarp.store.doc.duration)) === 1, 'not entered yet');
    // Leaving: the page's own handler enters the value, and then counts the scene unsaved
    // (so the browser asks, and the test answers Leave). The kept copy written as the page
    // goes is there for the next one: nothing flushed here beforehand.
    await p.reload();
    assert(p.dialogs.includes('beforeunload'), `leaving asks first: ${p.dialogs}`);
    await p.waitForSelector('#restore', { timeout: 20000 });
    await restoreYes(p);
    await p.waitForFunction(() => window.inkwarp.store.doc.duration === 0.5, null, { timeout: 10000 });
  });
});

test('the fps and duration fields show the largest values a scene may have whole', async () => {
  const scenePath = checkerScene('longest.json');
  await withServedEditor([scenePath], async ({ page: p }) => {
    // 1000 fps for 100000 s (1e8 frames, the most a scene may have), then with decimals.
    for (const [field, value] of [['#duration', '100000'], ['#fps', '1000'], ['#fps', '999.99'], ['#duration', '99999.95']]) {
      await p.fill(field, value);
      await p.press(field, 'Enter');
      await idle(p);
      const shown = await p.$eval(field, (el) => ({ value: el.value, scroll: el.scrollWidth, width: el.clientWidth }));
      assert(shown.value === value, `${field} took ${value}: ${JSON.stringify(shown)}`);
      assert(shown.scroll <= shown.width, `${field} shows ${value} whole: ${JSON.stringify(shown)}`);
    }
    const doc = await p.evaluate(() => window.inkwarp.store.doc);
    assert(doc.fps === 999.99 && doc.duration === 99999.95, `the scene has them: ${doc.fps} fps, ${doc.duration} s`);
  });
});

test('fields refuse what the scene format refuses, saying its range; kept work that does not open is kept, offered again and downloadable', async () => {
  const scenePath = checkerScene('limits.json');
  await withServedEditor([scenePath], async ({ page: p }) => {
    const message = () => p.textContent('#message');
    const enter = async (field, value) => {
      await p.fill(field, value);
      await p.press(field, 'Enter');
      await idle(p);
    };
    // Each field takes what the format takes (the engine's limits) and nothing more.
    await enter('#duration', '150000');
    assert((await p.evaluate(() => window.inkwarp.store.doc.duration)) === 1, 'a duration past 100000 s is refused');
    assert(/at most 100000 s/.test(await message()), `the refusal says the range: ${await message()}`);
    assert((await p.inputValue('#duration')) === '1', 'the field shows the scene\'s duration again');
    await enter('#fps', '0.0005');
    assert((await p.evaluate(() => window.inkwarp.store.doc.fps)) === 12, 'fewer than 0.001 fps is refused');
    assert(/from 0\.001 .* to 1000/.test(await message()), `the refusal says the range: ${await message()}`);
    await enter('#fps', '500');
    assert((await p.evaluate(() => window.inkwarp.store.doc.fps)) === 500, 'fps the format takes are taken (500)');
    await enter('#fps', '12');
    await enter('#layer-offset-x', '2000000');
    assert((await p.evaluate(() => window.inkwarp.store.doc.layers[0].offset)) === undefined, 'an offset past 1e6 px is refused');
    assert(/from -1000000 to 1000000/.test(await message()), `the refusal says the range: ${await message()}`);
    assert((await p.inputValue('#layer-offset-x')) === '0', 'the field shows the layer\'s offset again');
    // Work kept with a value the format refuses (as an earlier editor let through): its
    // restore fails, and the kept copy is neither written over nor dropped.
    await p.evaluate(() => document.activeElement?.blur());
    await p.keyboard.press('r');
    await p.keyboard.press('p');
    await click(p, [40, 40]);
    await idle(p);
    await p.evaluate(() => window.inkwarp.store.edit((d) => ({ ...d, duration: 150000 })));
    await flush(p);
    await p.reload();
    await p.waitForSelector('#restore', { timeout: 10000 });
    await p.click('#restore-yes');
    await p.waitForSelector('#unopened', { timeout: 10000 });
    const said = await p.textContent('#unopened span');
    assert(/could not be opened: at duration: .*at most 100000 s/.test(said) && /still kept in this browser/.test(said), `the failed restore says why and that the work is kept: ${said}`);
    const [download] = await Promise.all([p.waitForEvent('download'), p.click('#unopened-download')]);
    assert(download.suggestedFilename() === 'limits-kept.json', `named apart from the file: ${download.suggestedFilename()}`);
    const kept = JSON.parse(readFileSync(await download.path(), 'utf8'));
    assert(kept.duration === 150000 && kept.features.length === 1 && kept.layers[0].image.startsWith('data:'), `the download is the kept work: ${JSON.stringify(kept).slice(0, 160)}`);
    await p.click('#unopened-close');
    // The editor goes on with the file; the kept work is offered again on the next load.
    assert((await p.evaluate(() => window.inkwarp.store.doc.features.length)) === 0, 'the file is shown');
    await p.reload();
    await p.waitForSelector('#restore', { timeout: 10000 });
    await p.click('#restore-yes');
    await p.waitForSelector('#unopened', { timeout: 10000 });
    // Declined, it is forgotten.
    await p.reload();
    await p.waitForSelector('#restore', { timeout: 10000 });
    await p.click('#restore-no');
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    await p.waitForTimeout(500);
    assert((await p.$('#restore')) === null, 'nothing offered once discarded');
  });
});

test('a point, a feature, picked points or a layer dragged far off the picture stop where a scene\'s coordinates end: the work kept and the file saved open again', async () => {
  const scenePath = checkerScene('far.json');
  await withServedEditor([scenePath], async ({ page: p, own }) => {
    const shiftClick = async (at) => {
      await p.keyboard.down('Shift');
      await click(p, at);
      await p.keyboard.up('Shift');
    };
    await tracePoint(p, [20, 20]);
    for (const line of [[[100, 60], [140, 60]], [[100, 150], [150, 150]]]) {
      await p.keyboard.press('l');
      for (const at of line) await click(p, at);
      await p.keyboard.press('Enter');
    }
    await p.keyboard.press('v');
    // Each far past the 1e6 px a scene's coordinates may reach (the pointer 5e6 px away).
    await drag(p, [20, 20], [5e6, 5e6], 2);
    await drag(p, [120, 60], [120 - 5e6, 60], 2); // the first line by its line
    await shiftClick([100, 150]);
    await shiftClick([150, 150]);
    await drag(p, [150, 150], [150, 150 + 5e6], 2); // the second line's two points, picked
    // The layer, left and down: its offset stops at 1e6 px down, and at none left, where the
    // point at x = 1e6 would lie past 1e6 px in the layer's own pixels.
    await p.click('#layer-move');
    await drag(p, [128, 128], [128 - 5e6, 128 + 5e6], 2);
    await p.click('#layer-move');
    await idle(p);
    const doc = await p.evaluate(() => window.inkwarp.store.doc);
    const rests = doc.features.map((f) => f.rest);
    assert(JSON.stringify(rests) === JSON.stringify([[[1e6, 1e6]], [[-1e6, 60], [-1e6 + 40, 60]], [[100, 1e6], [150, 1e6]]]), `each stopped at the edge, the line whole: ${JSON.stringify(rests)}`);
    assert(JSON.stringify(doc.layers[0].offset) === JSON.stringify([0, 1e6]), `the layer too: ${JSON.stringify(doc.layers[0].offset)}`);
    // The work kept in the browser opens again, and the file saved validates.
    await flush(p);
    await p.reload();
    await p.waitForSelector('#restore', { timeout: 10000 });
    await restoreYes(p);
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    const check = spawnSync(inkwarp, ['validate', scenePath], { encoding: 'utf8' });
    assert(check.status === 0, `the saved scene validates: ${check.stdout}${check.stderr}`);
  });
});

test('kept work whose picture does not open names the picture by its file (else its layer), not by a data: URI, and says what to do', async () => {
  const scenePath = checkerScene('damaged.json');
  await withServedEditor([scenePath], async ({ page: p, own }) => {
    /** Restores the kept work on a fresh load of the editor; what the restore says. */
    const restored = async () => {
      await p.goto(own.url);
      await p.waitForSelector('#restore', { timeout: 10000 });
      await p.click('#restore-yes');
      await p.waitForSelector('#unopened', { timeout: 10000 });
      return p.textContent('#unopened span');
    };
    await tracePoint(p, [40, 40]);
    await idle(p);
    await flush(p);
    // The copy of checker.png kept with the work cut short, as a damaged browser store would
    // have it: from another page of the editor's address, once the editor's is gone.
    await p.goto(new URL('/no-such-page', own.url).href);
    await p.evaluate(() => new Promise((resolve, reject) => {
      const open = indexedDB.open('inkwarp-editor', 1);
      open.onsuccess = () => {
        const tx = open.result.transaction('autosave', 'readwrite');
        tx.objectStore('autosave').openCursor().onsuccess = (e) => {
          const cursor = e.target.result;
          if (!cursor) return;
          const kept = cursor.value;
          const layer = kept.doc.layers[0];
          layer.image = layer.image.slice(0, layer.image.indexOf(',') + 200);
          cursor.update(kept);
          cursor.continue();
        };
        tx.oncomplete = resolve;
        tx.onerror = () => reject(tx.error);
      };
    }));
    let said = await restored();
    assert(/could not be opened: at layers\[0\]\.image: cannot use checker\.png of layer 'checker' kept with it: /.test(said), `the picture is named by its file: ${said}`);
    assert(!/data:image/.test(said), `no data: URI is named: ${said}`);
    assert(said.includes(`download it, move it into the folder of ${scenePath} and, in a text editor, replace that picture's data: URI by the path of its file ("checker.png"), then open it with \`inkwarp edit SCENE\`.`), `it says what to do: ${said}`);
    // A picture that came from no file (cut short in the editor itself) is named by its layer.
    await p.evaluate(() => window.inkwarp.store.edit((d) => ({ ...d, layers: [{ ...d.layers[0], image: d.layers[0].image.slice(0, d.layers[0].image.indexOf(',') + 200) }] })));
    await flush(p);
    said = await restored();
    assert(/could not be opened: at layers\[0\]\.image: cannot use the picture of layer 'checker' kept with it: /.test(said), `the picture is named by its layer: ${said}`);
    assert(said.includes(`replace that picture's data: URI by the path of its file (from where you save the scene, as ${scenePath} names it), then open it with \`inkwarp edit SCENE\`.`), `it says what to do: ${said}`);
  });
});

test('a served picture the engine cannot use, on opening or later, is named by its file and layer', async () => {
  const dir = scratchDir('inkwarp-served-');
  // 40000 pixels wide: the server reads it, the engine refuses it (at most 32768 a side).
  const made = spawnSync(join(repo, '.venv/bin/python'), ['-c', 'import sys; from PIL import Image; Image.new("RGBA", (40000, 1)).save(sys.argv[1])', join(dir, 'strip.png')]);
  assert(made.status === 0, `the picture is made: ${made.stderr}`);
  copyFileSync(join(repo, 'examples/checkerboard-hole/checkerboard.png'), join(dir, 'checker.png'));
  const scenePath = join(dir, 'scene.json');
  const layers = [{ name: 'checker', image: 'checker.png' }, { name: 'strip', image: 'strip.png' }];
  writeFileSync(scenePath, JSON.stringify({ inkwarp: 1, width: 256, height: 256, fps: 12, duration: 1, layers, features: [] }));
  await withServedEditor([scenePath], async ({ page: p }) => {
    const message = () => p.textContent('#message');
    await p.waitForFunction(() => /at layers\[1\]\.image/.test(document.querySelector('#message')?.textContent ?? ''));
    assert((await message()).startsWith(`${scenePath}: at layers[1].image: cannot use strip.png of layer 'strip': the picture is 40000×1 pixels;`), `opening names the file: ${await message()}`);
    // Served without it, the scene opens; a picture that then fails to decode (the engine
    // out of memory, say) is named by its file, with what to do.
    writeFileSync(scenePath, JSON.stringify({ inkwarp: 1, fps: 12, duration: 1, layers: layers.slice(0, 1), features: [] }));
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    await idle(p);
    await p.evaluate(async () => {
      const { images, store, engine } = window.inkwarp;
      const image = store.doc.layers[0].image;
      images.forgetImage(image);
      images.useDecoder({ decode: () => { throw new Error('out of memory'); }, matteValues: (...a) => engine.matteValues(...a) });
      store.edit((d) => ({ ...d, layers: [{ ...d.layers[0], continuity: image }] }));
    });
    await p.waitForFunction(() => /out of memory/.test(document.querySelector('#message')?.textContent ?? ''));
    assert(await message() === "Cannot use checker.png of layer 'checker': out of memory. Reload the page to read it again.", `decoding names the file: ${await message()}`);
  });
});

test('a line being drawn: Save finishes it first (or says it is not saved); leaving asks, and it is kept to restore', async () => {
  const scenePath = checkerScene('drawing.json');
  await withServedEditor([scenePath], async ({ page: p }) => {
    const message = () => p.textContent('#message');
    await p.keyboard.press('r');
    await p.keyboard.press('l');
    for (const at of [[20, 20], [60, 30], [90, 60]]) await click(p, at);
    assert((await p.evaluate(() => window.inkwarp.store.view.draft.length)) === 3, 'three points drawn');
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    const saved = JSON.parse(readFileSync(scenePath, 'utf8'));
    assert(saved.features.length === 1 && saved.features[0].kind === 'polyline' && saved.features[0].rest.length === 3, `the line was finished and saved: ${JSON.stringify(saved.features)}`);
    assert(!(await p.evaluate(() => window.inkwarp.store.unsaved)), 'saved');
    // One point is no line: the save says it is not in the file.
    await click(p, [30, 80]);
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /is not in it/.test(document.querySelector('#message')?.textContent ?? ''));
    assert(/The polyline being drawn \(1 point\) is not in it/.test(await message()), `the save says so: ${await message()}`);
    // Leaving while a line is drawn asks, and the points come back with the restore.
    await click(p, [70, 90]);
    p.dialogs.length = 0;
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    assert(p.dialogs.includes('beforeunload'), `leaving while drawing asked first (dialogs: ${p.dialogs})`);
    await p.waitForSelector('#restore', { timeout: 10000 });
    await restoreYes(p);
    const view = await p.evaluate(() => ({ tool: window.inkwarp.store.view.tool, draft: window.inkwarp.store.view.draft }));
    assert(view.tool === 'polyline' && JSON.stringify(view.draft.map((q) => q.map(Math.round))) === '[[30,80],[70,90]]', `the line being drawn is back: ${JSON.stringify(view)}`);
    await p.keyboard.press('Enter');
    assert((await p.evaluate(() => window.inkwarp.store.doc.features.length)) === 2, 'and it finishes as it would have');
  });
});

test('a save cut off by a reload: no download as the page goes, the file it wrote is not offered back as unsaved, nor a conflict', async () => {
  const scenePath = checkerScene('cutoff.json');
  await withServedEditor([scenePath], async ({ page: p }) => {
    const downloads = [];
    p.on('download', (d) => downloads.push(d.suggestedFilename()));
    await p.keyboard.press('r');
    await p.keyboard.press('p');
    await click(p, [40, 40]);
    await idle(p);
    await flush(p);
    // The save reaches the server and writes the file; its answer is held back until the
    // page is reloaded, which cuts the request off (as a reload right after Ctrl+S does).
    let written;
    const wrote = new Promise((r) => (written = r));
    await p.route('**/*', async (route) => {
      if (route.request().method() !== 'PUT') return route.continue();
      await route.fetch();
      written();
    });
    await p.keyboard.press('Control+s');
    await wrote;
    assert(JSON.parse(readFileSync(scenePath, 'utf8')).features.length === 1, 'the save wrote the file');
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    await p.unroute('**/*');
    await p.waitForTimeout(1500);
    assert(downloads.length === 0, `nothing downloaded as the page went: ${downloads}`);
    assert((await p.$('#restore')) === null, 'the work the file holds is not offered back');
    const shown = await p.evaluate(() => ({ unsaved: window.inkwarp.store.unsaved, features: window.inkwarp.store.doc.features.length, title: document.title }));
    assert(!shown.unsaved && shown.features === 1 && !shown.title.startsWith('●'), `the file is shown, saved: ${JSON.stringify(shown)}`);
    // The next save is no conflict with "another tab or program".
    p.dialogs.length = 0;
    await p.keyboard.press('r');
    await p.keyboard.press('p');
    await click(p, [60, 60]);
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    assert(!p.dialogs.includes('confirm'), `no conflict asked: ${p.dialogs}`);
    assert(JSON.parse(readFileSync(scenePath, 'utf8')).features.length === 2, 'saved');
  });
});

test('work kept over a server restart takes the picture retouched on disk since, and saves it by its path', async () => {
  const scenePath = checkerScene('retouched.json');
  const picture = join(dirname(scenePath), 'checker.png');
  let own = await startServer([scenePath]);
  const port = new URL(own.url).port;
  const { page: p, context, errors: errs } = await openEditor(browser, own.url);
  // A point drawn and kept, `retouch` done to the picture in another program, the editor's
  // server started again (same port: the same browser storage), the kept work restored.
  const restoreAfter = async (at, retouch, features, restart = true) => {
    await p.keyboard.press('p');
    await click(p, at);
    await idle(p);
    await flush(p);
    retouch();
    if (restart) {
      own.proc.kill();
      await new Promise((r) => own.proc.on('exit', r));
      own = await startServer([scenePath, '--port', port]);
    }
    await p.goto(own.url);
    await p.waitForSelector('#restore', { timeout: 20000 });
    await restoreYes(p);
    await p.waitForFunction((n) => window.inkwarp.store.doc.features.length === n, features, { timeout: 10000 });
    return p.evaluate(() => document.querySelector('#message')?.textContent ?? '');
  };
  try {
    const python = join(repo, '.venv/bin/python');
    // Retouched in place: a green patch painted over the picture, the same size.
    const paint = () => spawnSync(python, ['-c', 'import sys; from PIL import Image; im = Image.open(sys.argv[1]); im.paste((0, 200, 0, 255), (100, 100, 160, 140)); im.save(sys.argv[1])', picture]);
    const said = await restoreAfter([40, 40], paint, 1);
    const shown = await p.evaluate(() => window.inkwarp.store.doc.layers[0].image);
    assert(shown === `data:image/png;base64,${readFileSync(picture).toString('base64')}`, 'the restored scene shows the picture as the file has it now');
    assert(/layer 'checker' changed on disk since, and is shown as the file has it now/.test(said), `the restore says so: ${said}`);
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    const saved = JSON.parse(readFileSync(scenePath, 'utf8'));
    assert(saved.features.length === 1 && saved.layers[0].image === 'checker.png', `the picture is saved by its path: ${JSON.stringify(saved).slice(0, 120)}`);
    // Retouched to another size, the file does not open (its picture no longer fits): the
    // work is restored with the kept copy of the picture.
    // Save writes that copy beside the changed file under a new name, and says so (never
    // inline in the scene, nor refused for the changed file's size), after a restart of the
    // server as in the same run (which read both pictures).
    const other = join(repo, 'examples/checkerboard-hole/checkerboard-plates.png');
    const misfitSaved = async (named, copy, restart) => {
      const kept = readFileSync(join(dirname(scenePath), named)).toString('base64');
      const features = JSON.parse(readFileSync(scenePath, 'utf8')).features.length + 1;
      const said = await restoreAfter([60 + features, 60], () => copyFileSync(other, join(dirname(scenePath), named)), features, restart);
      assert((await p.evaluate(() => window.inkwarp.store.doc.layers[0].image)) === `data:image/png;base64,${kept}`, 'the kept copy of the picture');
      assert(/(layer 'checker' changed on disk since and no longer fits the scene .*the copy kept with your work is shown\. Save writes that copy beside the changed file under a new name|its pictures are the copies kept with your work: Save writes any of them that changed on disk since beside its file under a new name)/.test(said), `the restore says what a save does: ${said}`);
      if (!restart) await p.screenshot({ path: join(screens, 'restore-misfit.png') });
      await p.keyboard.press('Control+s');
      await p.waitForFunction(() => /Saved to|Could not|Not saved/.test(document.querySelector('#message')?.textContent ?? ''));
      const saidSaved = await p.textContent('#message');
      assert(saidSaved.includes(`the kept copy of its picture was written beside it as ${copy} (${named} is left as it is)`), `the save says where the copy went: ${saidSaved}`);
      const saved = JSON.parse(readFileSync(scenePath, 'utf8'));
      assert(saved.layers[0].image === copy && saved.features.length === features, `the scene names the copy: ${JSON.stringify(saved).slice(0, 120)}`);
      assert(readFileSync(join(dirname(scenePath), copy)).toString('base64') === kept, 'the copy is the kept picture');
      assert(readFileSync(join(dirname(scenePath), named)).equals(readFileSync(other)), 'the changed file is left as it is');
    };
    await misfitSaved('checker.png', 'checker-kept.png', true);
    await misfitSaved('checker-kept.png', 'checker-kept-kept.png', false);
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
    own.proc.kill();
  }
});

test("work restored in a tab whose link an earlier run gave stays its file's, and saves back from the new run's page", async () => {
  const scenePath = checkerScene('restarted.json');
  let own = await startServer([scenePath]);
  const [port, stale] = [new URL(own.url).port, own.url];
  const { page: p, context, errors: errs } = await openEditor(browser, own.url);
  try {
    await tracePoint(p, [40, 40]);
    await idle(p);
    await flush(p);
    own.proc.kill();
    await new Promise((r) => own.proc.on('exit', r));
    own = await startServer([scenePath, '--port', port]);
    // A save from the tab still open on the earlier run's link is refused (another token):
    // the message says how the work gets back into its file.
    const [copy] = await Promise.all([p.waitForEvent('download'), p.keyboard.press('Control+s')]);
    await copy.delete();
    const refused = await p.textContent('#message');
    assert(/close this tab, then open \(or reload\) the URL the running inkwarp edit printed/.test(refused), `the way back: ${refused}`);
    // The tab reloaded on its old link (the earlier run's token: the file does not open), the
    // work restored there: a save cannot reach the file, but the kept copy still names it.
    await p.goto(stale);
    await p.waitForSelector('#restore', { timeout: 20000 });
    const said = await p.textContent('#message');
    assert(/link is not the running inkwarp edit's/.test(said), `a stale link is named so: ${said}`);
    assert((await p.title()) === 'grid.json — inkwarp editor', `the example shown meanwhile is not named as the file: ${await p.title()}`);
    await restoreYes(p);
    await flush(p);
    // The new run's link: offered as the file's own, restored into it, saved to it.
    await p.goto(own.url);
    await p.waitForSelector('#restore', { timeout: 20000 });
    const question = await p.textContent('#restore span');
    assert(/^Restore the scene you were editing at \d\d:\d\d\?$/.test(question), `offered as the file's own: ${question}`);
    await restoreYes(p);
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''), null, { timeout: 10000 });
    assert(JSON.parse(readFileSync(scenePath, 'utf8')).features.length === 1, 'the work went back to its file');
    assert(errs.filter((e) => !/403|Forbidden/.test(e)).length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
    own.proc.kill();
  }
});

test('an error said goes once a later action succeeds; a region with no area and a cut on one spot are refused and say why', async () => {
  const { page: p, context, errors: errs } = await openEditor(browser, server.url);
  const said = () => p.evaluate(() => { const m = document.querySelector('#message'); return m.hidden ? '' : `${m.className}: ${m.textContent}`; });
  try {
    await p.keyboard.press('r');
    // Two clicks on one spot: the cut is refused for its points' place, not their number.
    await p.keyboard.press('c');
    await click(p, [30, 30]);
    await click(p, [30, 30]);
    await p.keyboard.press('Enter');
    assert(/error: The cut's 2 points are all at one place \(30, 30\)/.test(await said()), `the cut: ${await said()}`);
    await p.screenshot({ path: join(screens, 'cut-one-spot.png') });
    await p.keyboard.press('Escape');
    // Three points on one line: a region with no area is refused.
    await p.keyboard.press('g');
    for (const at of [[20, 20], [40, 40], [60, 60]]) await click(p, at);
    await p.keyboard.press('Enter');
    assert(/error: A region needs an area, and its 3 points lie on one line/.test(await said()), `the region: ${await said()}`);
    assert((await p.evaluate(() => window.inkwarp.store.view.draft.length)) === 3, 'the draft is kept');
    // One more point off the line: the region is made, and the error goes.
    await click(p, [20, 60]);
    await p.keyboard.press('Enter');
    assert((await p.evaluate(() => window.inkwarp.store.doc.features.some((f) => f.kind === 'region'))), 'the region is made');
    assert((await said()) === '', `the error went: ${await said()}`);
    // A refused fps, then one taken.
    await p.fill('#fps', '5000');
    await p.press('#fps', 'Enter');
    assert(/error: Frames per second/.test(await said()), `fps refused: ${await said()}`);
    await p.fill('#fps', '30');
    await p.press('#fps', 'Enter');
    assert((await p.evaluate(() => window.inkwarp.store.doc.fps)) === 30 && (await said()) === '', `fps taken, the error gone: ${await said()}`);
    // A refused key time, then one taken.
    await p.evaluate(() => {
      const { store, state } = window.inkwarp;
      const id = store.doc.features.find((f) => f.kind === 'region').id;
      store.edit((d) => state.setKey(d, id, 0.5, d.features.find((f) => f.id === id).rest));
      store.setView({ selection: { feature: id, point: null } });
    });
    await p.waitForSelector('input.key-time');
    await p.fill('input.key-time', '-1');
    await p.press('input.key-time', 'Enter');
    assert(/error: A key's time/.test(await said()), `key time refused: ${await said()}`);
    await p.fill('input.key-time', '0.7');
    await p.press('input.key-time', 'Enter');
    assert((await said()) === '', `key time taken, the error gone: ${await said()}`);
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
  }
});

test('Discard forgets the kept work: the next reload offers nothing', async () => {
  const { page: p, context, errors: errs } = await openEditor(browser, server.url);
  try {
    await tracePoint(p, [100, 300]);
    await flush(p);
    await p.reload();
    await p.waitForSelector('#restore');
    await p.click('#restore-no');
    // The answer settled (no write of this tab's copy asked for: nothing changed since).
    await p.waitForFunction(() => window.inkwarp.autosave, null, { timeout: 10000 });
    await p.waitForTimeout(1000);
    await p.reload();
    await p.waitForSelector('body[data-ready]');
    // Settled with no offer, or offering.
    await p.waitForFunction(() => window.inkwarp.autosave || document.querySelector('#restore'), null, { timeout: 10000 });
    assert((await p.$('#restore')) === null, 'no offer after Discard');
    assert(!(await p.evaluate(() => window.inkwarp.store.unsaved)), 'a fresh, saved scene');
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
  }
});

test('Backspace or Delete while drawing takes back the last click, never a finished feature', async () => {
  const { page: p, context, errors: errs } = await openEditor(browser, server.url);
  try {
    const count = () => p.evaluate(() => window.inkwarp.store.doc.features.length);
    await p.keyboard.press('r');
    const before = await count();
    await p.keyboard.press('l');
    await click(p, [60, 60]);
    await click(p, [120, 80]);
    await p.keyboard.press('Enter');
    assert((await count()) === before + 1, 'the first line is drawn (and selected)');
    await p.keyboard.press('l');
    await click(p, [60, 160]);
    await click(p, [120, 180]);
    for (const key of ['Backspace', 'Delete']) {
      const draft = await p.evaluate(() => window.inkwarp.store.view.draft.length);
      await p.keyboard.press(key);
      assert((await p.evaluate(() => window.inkwarp.store.view.draft.length)) === draft - 1, `${key} took back a click`);
      assert((await count()) === before + 1, `${key} deleted no feature`);
    }
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
  }
});

test('Save writes each scene to its own file: undo past opening, two tabs, a file changed on disk, a server gone', async () => {
  const scenePath = checkerScene('mine.json');
  const own = await startServer([scenePath]);
  const a = await openEditor(browser, own.url);
  const b = await openEditor(browser, own.url);
  const features = () => JSON.parse(readFileSync(scenePath, 'utf8')).features.map((f) => f.rest[0]);
  const message = (p) => p.evaluate(() => document.querySelector('#message')?.textContent ?? '');
  try {
    const p = a.page;
    assert((await p.title()) === 'mine.json — inkwarp editor', `the title names the scene: ${await p.title()}`);
    // The opened scene is where Undo stops: Ctrl+Z keeps it, and its file.
    await p.keyboard.press('Control+z');
    await idle(p);
    const kept = await p.evaluate(() => ({ saveUrl: window.inkwarp.store.origin.saveUrl, layer: window.inkwarp.store.doc.layers[0].name }));
    assert(kept.saveUrl !== null && kept.layer === 'checker', `Ctrl+Z right after opening keeps the scene and its file: ${JSON.stringify(kept)}`);
    // An example opened over it saves nowhere; Save must not write it to mine.json.
    await p.evaluate(() => window.inkwarp.ui.openExample('builtin'));
    await idle(p);
    assert((await p.evaluate(() => window.inkwarp.store.origin.saveUrl)) === null, 'the example saves nowhere');
    const [example] = await Promise.all([p.waitForEvent('download'), p.keyboard.press('Control+s')]);
    assert(example.suggestedFilename() === 'grid.json', `the example downloads under its own name: ${example.suggestedFilename()}`);
    assert(/^Downloaded grid\.json/.test(await message(p)), `a download says so: ${await message(p)}`);
    assert(JSON.parse(readFileSync(scenePath, 'utf8')).layers[0].image === 'checker.png', 'mine.json was not overwritten by the example');
    // Undo past that open: mine.json again, saving to its file.
    await p.keyboard.press('Control+z');
    await idle(p);
    assert((await p.evaluate(() => window.inkwarp.store.origin.saveUrl)) !== null, 'Undo past the open brings back the scene with its file');
    // Tab A adds a point and saves; the title marks unsaved work until then.
    await p.keyboard.press('p');
    await click(p, [20, 20]);
    assert((await p.title()).startsWith('● '), `unsaved work is marked in the title: ${await p.title()}`);
    // Each save names the file the tab opened, which a server serving another one refuses.
    const named = [];
    p.on('request', (r) => { if (r.method() === 'PUT') named.push(r.headers()['x-inkwarp-scene']); });
    // Saved twice at once (a held Ctrl+S): the second waits for the first and knows its
    // version, so it is no conflict.
    await p.keyboard.press('Control+s');
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    await p.evaluate(() => window.inkwarp.ui.save());
    assert(!p.dialogs.includes('confirm') && /Saved to/.test(await message(p)), `two quick saves asked nothing: ${p.dialogs} ${await message(p)}`);
    assert(!(await p.title()).startsWith('● ') && features().length === 1, 'saved: one point, title unmarked');
    assert(named.length >= 2 && named.every((v) => decodeURIComponent(v) === scenePath), `the saves name ${scenePath}: ${named}`);
    // Tab B, open all along, adds its own point: its save is refused, not written over A's.
    const q = b.page;
    await q.keyboard.press('p');
    await click(q, [40, 30]);
    q.declineDialogs = true;
    await q.keyboard.press('Control+s');
    await q.waitForFunction(() => /^Not saved: .*changed on disk/.test(document.querySelector('#message')?.textContent ?? ''));
    assert(q.dialogs.includes('confirm') && features().length === 1, `tab B asked and kept A's save: ${JSON.stringify(features())}`);
    assert(await q.evaluate(() => window.inkwarp.store.unsaved), 'tab B keeps its work unsaved');
    // Told to overwrite, it does.
    q.declineDialogs = false;
    await q.keyboard.press('Control+s');
    await q.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? ''));
    assert(features().length === 1 && features()[0][0] > 30, `tab B's scene overwrote the file when told to: ${JSON.stringify(features())}`);
    // Tab A, marked saved, learns that its file no longer holds its scene (on coming back to
    // it, or within seconds): marked unsaved, so closing it asks, and told why.
    await p.evaluate(() => window.dispatchEvent(new Event('focus')));
    await p.waitForFunction(() => window.inkwarp.store.unsaved && /was changed by another tab or program/.test(document.querySelector('#message')?.textContent ?? ''), null, { timeout: 10000 });
    assert((await message(p)).startsWith(scenePath) && (await p.title()).startsWith('● '), `tab A says which file and marks the title: ${await message(p)} ${await p.title()}`);
    // Its Save asks before writing over tab B's, and Cancel keeps B's.
    const asked = p.dialogs.length;
    p.declineDialogs = true;
    await p.keyboard.press('Control+s');
    await p.waitForFunction(() => /^Not saved: .*changed on disk/.test(document.querySelector('#message')?.textContent ?? ''));
    assert(p.dialogs.length === asked + 1 && features()[0][0] > 30 && await p.evaluate(() => window.inkwarp.store.unsaved), `tab A asked and kept B's save: ${JSON.stringify(features())}`);
    p.declineDialogs = false;
    // Ctrl+S from a number field saves too, with the value just typed.
    await q.fill('#duration', '2');
    await q.focus('#duration');
    await q.keyboard.press('Control+s');
    await q.waitForFunction(() => /Saved to/.test(document.querySelector('#message')?.textContent ?? '') && !window.inkwarp.store.unsaved);
    assert(JSON.parse(readFileSync(scenePath, 'utf8')).duration === 2, 'Ctrl+S in the duration field saved the typed duration');
    // A duration that would leave keys past the end is refused, and the field shows the
    // scene's own again.
    await q.evaluate(() => window.inkwarp.store.edit((d) => ({ ...d, features: d.features.map((f, i) => (i ? f : { ...f, keys: [{ t: 1.5, points: f.rest }] })) })));
    await q.fill('#duration', '1');
    await q.press('#duration', 'Enter');
    await q.waitForFunction(() => /has keys past 1 s \(the last at 1\.5 s\)/.test(document.querySelector('#message')?.textContent ?? ''));
    assert((await q.evaluate(() => [window.inkwarp.store.doc.duration, document.querySelector('#duration').value])).join() === '2,2', 'the duration stayed 2 s, in the field too');
    // The server gone: the work stays unsaved (and in the browser's copy), a copy downloads.
    own.proc.kill();
    await new Promise((r) => setTimeout(r, 300));
    await q.keyboard.press('p');
    await click(q, [10, 40]);
    const [copy] = await Promise.all([q.waitForEvent('download'), q.keyboard.press('Control+s')]);
    assert(copy.suggestedFilename() === 'mine.json', `the copy downloads as mine.json: ${copy.suggestedFilename()}`);
    assert(/^Could not save to .*mine\.json .*kept in this browser, unsaved/.test(await message(q)), `the failure is said: ${await message(q)}`);
    assert(await q.evaluate(() => window.inkwarp.store.unsaved), 'a failed save leaves the work unsaved');
    assert(a.errors.length === 0 && b.errors.filter((e) => !/Failed to fetch|ERR_CONNECTION_REFUSED/.test(e)).length === 0, `page errors: ${[...a.errors, ...b.errors].join('; ')}`);
  } finally {
    await a.context.close();
    await b.context.close();
    own.proc.kill();
  }
});

test('two tabs closed with unsaved work: each is offered back, neither overwrites the other', async () => {
  const { page: a, context, errors: errs } = await openEditor(browser, server.url);
  try {
    // B starts as a duplicate of A (sessionStorage copied, with A's key): it takes its own.
    const aKey = await a.evaluate(() => sessionStorage.getItem('inkwarp-tab'));
    const b = await context.newPage();
    await b.addInitScript((key) => { if (!sessionStorage.getItem('inkwarp-tab')) sessionStorage.setItem('inkwarp-tab', key); }, aKey);
    b.on('dialog', (d) => void d.accept());
    await b.goto(server.url);
    await b.waitForSelector('body[data-ready]');
    const bKey = await b.evaluate(() => sessionStorage.getItem('inkwarp-tab'));
    assert(aKey && bKey && aKey !== bKey, `a duplicated tab keeps its own copy: ${aKey} ${bKey}`);
    for (const [p, at] of [[a, [100, 50]], [b, [300, 60]]]) {
      await p.keyboard.press('r');
      await p.keyboard.press('p');
      await click(p, at);
      await flush(p);
    }
    const last = (p) => p.evaluate(() => window.inkwarp.store.doc.features.at(-1).rest[0].map(Math.round));
    const wanted = new Set([JSON.stringify(await last(a)), JSON.stringify(await last(b))]);
    await a.close({ runBeforeUnload: false });
    await b.close({ runBeforeUnload: false });
    const found = new Set();
    for (let i = 0; i < 2; i++) {
      const p = await context.newPage();
      await p.goto(server.url);
      await p.waitForSelector('body[data-ready]');
      await p.waitForSelector('#restore', { timeout: 10000 });
      const question = await p.textContent('#restore span');
      assert(i === 1 || /1 more kept from other tabs/.test(question), `the first offer says another is kept: ${question}`);
      await restoreYes(p);
      found.add(JSON.stringify(await last(p)));
    }
    assert(JSON.stringify([...found].sort()) === JSON.stringify([...wanted].sort()), `both tabs' work came back: ${[...found]} of ${[...wanted]}`);
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
  }
});

/** Presses a key diamond of the timeline and moves the pointer `dx` px in 1 px steps. */
async function dragDiamond(p, feature, t, dx, opts = {}) {
  const box = await p.evaluate(([f, time]) => {
    const el = [...document.querySelectorAll('.tracks .key')].find((k) => k.dataset.feature === f && Math.abs(Number(k.dataset.t) - time) < 1e-6);
    const r = el.getBoundingClientRect();
    return [r.left + r.width / 2, r.top + r.height / 2];
  }, [feature, t]);
  if (opts.alt) await p.keyboard.down('Alt');
  await p.mouse.move(box[0], box[1]);
  await p.mouse.down();
  const step = opts.step ?? 1;
  for (let i = step; i < Math.abs(dx) + step; i += step) await p.mouse.move(box[0] + Math.sign(dx) * Math.min(i, Math.abs(dx)), box[1]);
  await p.mouse.up();
  if (opts.alt) await p.keyboard.up('Alt');
  return p.evaluate((f) => window.inkwarp.store.doc.features.find((g) => g.id === f).keys.map((k) => k.t), feature);
}

test('a 3 px key drag moves the key by at most one frame, onto a frame; keys stay within the animation', async () => {
  await page.evaluate(async () => {
    const { ui, store, examples } = window.inkwarp;
    await ui.openScene(await examples.builtinScene(), 'keys.json');
    store.edit((d) => ({ ...d, fps: 24, duration: 2 }));
    store.edit((d) => window.inkwarp.state.setKey(d, 'pin1', 0, [[30, 30]]));
    store.edit((d) => window.inkwarp.state.setKey(d, 'pin1', 0.75, [[60, 30]]));
    await window.inkwarp.app.idle();
  });
  const frame = 1 / 24;
  for (const [t, dx] of [[0, 3], [0.75, 3], [0.75, -3], [0, 2]]) {
    const before = await page.evaluate(() => window.inkwarp.store.doc.features.find((g) => g.id === 'pin1').keys.map((k) => k.t));
    const after = await dragDiamond(page, 'pin1', t, dx);
    const moved = after.find((x) => !before.some((b) => Math.abs(b - x) < 1e-9)) ?? t;
    perf.keyDrag = [...(perf.keyDrag ?? []), { from: t, dx, to: moved }];
    assert(Math.abs(moved - t) <= frame + 1e-9, `a ${dx} px drag moved the key at ${t} s to ${moved} s (more than one frame)`);
    assert(Math.abs(moved * 24 - Math.round(moved * 24)) < 1e-6, `the key landed off a frame: ${moved}`);
    // put it back
    await page.evaluate(([from, to]) => window.inkwarp.store.edit((d) => window.inkwarp.state.moveKey(d, 'pin1', from, to)), [moved, t]);
  }
  assert(!(await page.evaluate(() => document.querySelector('#undo').disabled)), 'Undo is enabled after a key drag');
  // A long drag to the right stops at the last frame.
  const wide = await page.evaluate(() => document.querySelector('.tracks .track').getBoundingClientRect().width);
  // A drag of 2.4 frames' width moves the key two frames, following the pointer.
  const two = await dragDiamond(page, 'pin1', 0.75, Math.round((2.4 / 48) * wide), { step: 4 });
  assert(two.some((t) => Math.abs(t - (0.75 + 2 / 24)) < 1e-9), `a drag of 2.4 frames moved the key to ${two}`);
  await page.evaluate(() => window.inkwarp.store.edit((d) => window.inkwarp.state.moveKey(d, 'pin1', 0.75 + 2 / 24, 0.75)));
  const far = await dragDiamond(page, 'pin1', 0.75, Math.round(wide), { step: 25 });
  assert(Math.max(...far) <= 2 + 1e-9, `a key dragged past the end stayed within the animation: ${far}`);
  // Typing a time past the end is refused with a message.
  const refused = await page.evaluate(() => {
    try {
      window.inkwarp.state.moveKey(window.inkwarp.store.doc, 'pin1', 0, 5);
      return null;
    } catch (e) {
      return e.message;
    }
  });
  assert(/past the end of the animation/.test(refused ?? ''), `moving a key to 5 s: ${refused}`);
  // Scrubbing the ruler lands on frames.
  const ruler = await page.evaluate(() => { const r = document.querySelector('.tracks .ruler').getBoundingClientRect(); return [r.left, r.top + r.height / 2, r.width]; });
  await page.mouse.click(ruler[0] + ruler[2] * 0.3183, ruler[1]);
  const tNow = await page.evaluate(() => window.inkwarp.store.view.time);
  assert(Math.abs(tNow * 24 - Math.round(tNow * 24)) < 1e-9, `scrubbing left the time off a frame: ${tNow}`);
  // Frame steps from the keyboard are counted, not summed: 18 of them at 24 fps are 0.75 s
  // exactly (summed, 0.7499999999999998, which a key set there wrote to the file).
  await page.evaluate(() => window.inkwarp.ui.setTime(0));
  for (let i = 0; i < 18; i++) await page.keyboard.press('ArrowRight');
  const stepped = await page.evaluate(() => window.inkwarp.store.view.time);
  assert(stepped === 0.75, `18 frame steps at 24 fps reached ${stepped} s`);
  await page.keyboard.press('ArrowLeft');
  assert((await page.evaluate(() => window.inkwarp.store.view.time)) === 17 / 24, 'a frame step back lands on frame 17');
  // End is the last frame `inkwarp render` draws (47 of 0-47 in 2 s at 24 fps), not 2 s.
  await page.keyboard.press('End');
  assert((await page.evaluate(() => window.inkwarp.store.view.time)) === 47 / 24, 'End goes to the last frame');
  assert(/frame 47 of 0–47/.test(await page.evaluate(() => document.querySelector('#time').textContent)), 'the last frame is frame 47, as inkwarp render counts');
  // A step past it, the ruler's right end and the slider's end are the last frame too (the
  // slider ran on to 2 s, a pose no frame shows, labelled frame 47).
  const now = () => page.evaluate(() => window.inkwarp.store.view.time);
  await page.keyboard.press('ArrowRight');
  assert((await now()) === 47 / 24, `a step past the last frame went to ${await now()} s`);
  await page.evaluate(() => window.inkwarp.ui.setTime(0));
  await page.mouse.click(ruler[0] + ruler[2] - 1, ruler[1]);
  assert((await now()) === 47 / 24, `the ruler's right end is ${await now()} s`);
  assert((await page.evaluate(() => Number(document.querySelector('#scrub').max))) === 47 / 24, 'the slider ends at the last frame');
  // A key at the scene's end is reached by a key step, and said to be past the last frame.
  await page.evaluate(() => window.inkwarp.store.edit((d) => window.inkwarp.state.setKey(d, 'pin1', 2, [[40, 30]])));
  await page.keyboard.press('Shift+ArrowRight');
  assert((await now()) === 2, `Shift+Right went to ${await now()} s, not the key at 2 s`);
  const label = await page.evaluate(() => document.querySelector('#time').textContent);
  assert(/2\.00 s · past the last frame \(47\)/.test(label), `at the key past the last frame the label reads ${label}`);
  await page.keyboard.press('ArrowRight');
  assert((await now()) === 2, `→ past the last frame went to ${await now()} s`);
  await page.keyboard.press('ArrowLeft');
  assert((await now()) === 47 / 24, `← from past the last frame went to ${await now()} s`);
  await screenshot(page, 'timeline-keys');
});

test('a held border stays within 0.5 px on a frame where the drawing pulls hard (free: it drifts)', async () => {
  const edge = async (border) => page.evaluate(async (b) => {
    const { ui, store, examples, app } = window.inkwarp;
    const doc = await examples.builtinScene(160);
    doc.features = [{ id: 'pull', kind: 'polyline', rest: [[30, 20], [30, 90]], keys: [{ t: 0, points: [[30, 20], [30, 90]] }, { t: 1, points: [[8, 6], [8, 76]] }] }];
    doc.duration = 1;
    if (b) doc.layers[0].border = b;
    await ui.openScene(doc, 'border.json');
    ui.setMode('pose');
    ui.setTime(1);
    await app.idle();
    const rt = [...app.runtimes.values()][0];
    const f = rt.field;
    const { width: w, height: h } = f;
    let worst = 0;
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
      if (x !== 0 && y !== 0 && x !== w - 1 && y !== h - 1) continue;
      worst = Math.max(worst, Math.hypot(f.dx[y * w + x], f.dy[y * w + x]));
    }
    return { worst, checked: document.querySelector('#border-hold')?.checked ?? null };
  }, border);
  const free = await edge(null);
  const held = await edge('hold');
  perf.border = { freePx: free.worst, heldPx: held.worst };
  assert(free.worst > 5, `without a held border this frame drags the edge: ${free.worst.toFixed(2)} px`);
  assert(held.worst <= 0.5, `the held border moved ${held.worst.toFixed(3)} px`);
  assert(held.checked === true && free.checked === false, 'the layer panel shows whether the border is held');
  await screenshot(page, 'border-hold');
});


/** The bundled ffmpeg of the Python environment (imageio-ffmpeg). */
function ffmpegExe() {
  const py = join(repo, '.venv/bin/python');
  const r = spawnSync(py, ['-c', 'import imageio_ffmpeg; print(imageio_ffmpeg.get_ffmpeg_exe())'], { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`no ffmpeg from imageio-ffmpeg: ${r.stderr}`);
  return r.stdout.trim();
}

test('WebM export: a 2.5 s, 24 fps scene lasts 2.5 s ± one frame and has 60 frames; transparency over white', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    const doc = await examples.builtinScene(96);
    doc.fps = 24;
    doc.duration = 2.5;
    doc.background = [0, 0, 0, 0]; // the picture pulled away from the top left leaves it clear
    doc.features = [{ id: 'dot', kind: 'point', rest: [[40, 40]], keys: [{ t: 0, points: [[40, 40]] }, { t: 2.5, points: [[60, 50]] }] }];
    await ui.openScene(doc, 'timing.json');
    await app.idle();
  });
  const [download] = await Promise.all([page.waitForEvent('download', { timeout: 300000 }), page.evaluate(() => window.inkwarp.ui.exportWebm())]);
  const dir = scratchDir('inkwarp-webm-');
  const file = join(dir, download.suggestedFilename());
  await download.saveAs(file);
  const r = spawnSync(ffmpegExe(), ['-hide_banner', '-i', file, '-f', 'null', '-'], { encoding: 'utf8' });
  const log = r.stderr;
  const frames = [...log.matchAll(/frame=\s*(\d+)/g)].map((m) => Number(m[1])).pop();
  const d = log.match(/Duration: (\d+):(\d+):([\d.]+)/);
  const duration = d ? Number(d[1]) * 3600 + Number(d[2]) * 60 + Number(d[3]) : NaN;
  perf.webm = { frames, duration, file: download.suggestedFilename() };
  assert(r.status === 0, `ffmpeg could not decode the WebM: ${log.slice(-400)}`);
  assert(frames === 60, `the WebM has ${frames} frames; expected 60`);
  assert(Math.abs(duration - 2.5) <= 1 / 24 + 1e-6, `the WebM lasts ${duration} s; expected 2.5 s ± one frame`);
  // The last frame's clear corner is white, as an MP4 from inkwarp render (it was black), and
  // the message says why.
  const last = spawnSync(ffmpegExe(), ['-v', 'error', '-i', file, '-vf', 'select=eq(n\\,59)', '-frames:v', '1', '-f', 'rawvideo', '-pix_fmt', 'rgb24', '-'], { maxBuffer: 1 << 24 });
  assert(last.status === 0 && last.stdout.length === 96 * 96 * 3, `the last frame decoded: ${last.stderr}`);
  const corner = [...last.stdout.subarray(3 * (2 * 96 + 2), 3 * (2 * 96 + 2) + 3)];
  assert(corner.every((v) => v >= 235), `the clear corner is white: ${corner}`);
  const said = await page.textContent('#message');
  assert(/transparent areas are white, as a WebM made in the browser keeps no alpha/.test(said), `the message says so: ${said}`);
});

test('a WebM export is cancelled by Escape or its button: no download, the editor as it was', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app, store } = window.inkwarp;
    const doc = await examples.builtinScene(96);
    doc.fps = 24;
    doc.duration = 10;
    doc.features = [{ id: 'dot', kind: 'point', rest: [[40, 40]], keys: [{ t: 0, points: [[40, 40]] }, { t: 10, points: [[60, 50]] }] }];
    await ui.openScene(doc, 'long.json');
    store.setView({ mode: 'rest', time: 0.5 });
    await app.idle();
  });
  let downloads = 0;
  const counted = () => downloads++;
  page.on('download', counted);
  try {
    for (const how of ['Escape', 'button']) {
      await page.click('#export-webm');
      await page.waitForFunction(() => /Exported 12 of 240/.test(document.querySelector('#message')?.textContent ?? ''), null, { timeout: 120000 });
      assert(await page.textContent('#export-webm') === 'Cancel', 'the export button offers to cancel');
      if (how === 'Escape') await page.keyboard.press('Escape');
      else await page.click('#export-webm');
      await page.waitForFunction(() => /cancelled/.test(document.querySelector('#message')?.textContent ?? ''), null, { timeout: 30000 });
      const after = await page.evaluate(() => ({
        message: document.querySelector('#message').textContent,
        button: document.querySelector('#export-webm').textContent,
        mode: window.inkwarp.store.view.mode,
        time: window.inkwarp.store.view.time,
        exporting: window.inkwarp.app.exporting,
      }));
      assert(/WebM export cancelled after (1[2-9]|[2-9]\d) of 240 frames; nothing was saved/.test(after.message), `${how}: ${after.message}`);
      assert(after.button === 'WebM' && after.mode === 'rest' && after.time === 0.5 && !after.exporting, `${how}: ${JSON.stringify(after)}`);
    }
    // Nothing was downloaded, and a later export runs to its end.
    await page.evaluate(() => {
      const { store } = window.inkwarp;
      store.edit((doc) => ({ ...doc, duration: 0.5 }));
    });
    const [download] = await Promise.all([page.waitForEvent('download', { timeout: 60000 }), page.click('#export-webm')]);
    assert(download.suggestedFilename() === 'long.webm', download.suggestedFilename());
    assert(downloads === 1, `${downloads} downloads; only the finished export's expected`);
  } finally {
    page.off('download', counted);
  }
});


test('zoom keeps the point under the pointer fixed; pan, Fit and 100 %; the stage keeps its size when rows are added', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    await ui.openScene(await examples.builtinScene(), 'zoom.json');
    await app.idle();
  });
  const stage0 = await page.evaluate(() => JSON.stringify(document.querySelector('.stage').getBoundingClientRect()));
  const scenePt = (x, y) => page.evaluate(([cx, cy]) => {
    const r = document.querySelector('canvas.overlay').getBoundingClientRect();
    const { width, height } = window.inkwarp.store.doc;
    return [((cx - r.left) / r.width) * width, ((cy - r.top) / r.height) * height];
  }, [x, y]);
  // whole CSS pixels: pointer events carry whole client coordinates
  const [cx, cy] = (await toClient(page, [150, 320])).map(Math.round);
  const before = await scenePt(cx, cy);
  await page.mouse.move(cx, cy);
  for (let i = 0; i < 4; i++) await page.mouse.wheel(0, -120);
  const z = await page.evaluate(() => window.inkwarp.ui.scale);
  const fit = await page.evaluate(() => window.inkwarp.ui.fitZoom());
  const after = await scenePt(cx, cy);
  perf.zoom = { from: fit, to: z, drift: Math.hypot(after[0] - before[0], after[1] - before[1]) };
  assert(z > fit * 1.5, `the wheel zoomed in: ${fit} → ${z}`);
  assert(perf.zoom.drift < 0.5, `the point under the pointer moved ${perf.zoom.drift.toFixed(3)} scene px: ${before} → ${after}`);
  // Space-drag pans by the pointer's motion.
  await page.keyboard.down('Space');
  await page.mouse.down();
  await page.mouse.move(cx + 40, cy + 25, { steps: 4 });
  await page.mouse.up();
  await page.keyboard.up('Space');
  const panned = await scenePt(cx + 40, cy + 25);
  assert(Math.hypot(panned[0] - before[0], panned[1] - before[1]) < 0.5, `Space-drag moved the picture with the pointer: ${panned} vs ${before}`);
  assert(!(await page.evaluate(() => window.inkwarp.store.view.playing)), 'Space held to pan does not play');
  await screenshot(page, 'zoomed');
  await page.click('#zoom-100');
  assert(Math.abs((await page.evaluate(() => window.inkwarp.ui.scale)) - 1) < 1e-9, '100 % is one scene pixel per CSS pixel');
  await page.click('#zoom-fit');
  assert((await page.evaluate(() => window.inkwarp.ui.zoom)) === null, 'Fit fits');
  // More timeline rows do not move or shrink the stage.
  await page.evaluate(() => {
    const { store, state } = window.inkwarp;
    for (let i = 0; i < 8; i++) store.edit((d) => state.addFeature(d, 'point', [[20 + 10 * i, 200]]).doc);
  });
  const stage1 = await page.evaluate(() => JSON.stringify(document.querySelector('.stage').getBoundingClientRect()));
  assert(stage0 === stage1, `the stage moved or changed size: ${stage0} → ${stage1}`);
});


test('keys: Shift-click picks several, they drag together, copy and paste; easing chooser; onion skin', async () => {
  await page.evaluate(async () => {
    const { ui, store, examples, state } = window.inkwarp;
    await ui.openScene(await examples.builtinScene(), 'multi.json');
    store.edit((d) => ({ ...d, fps: 24, duration: 2 }));
    store.edit((d) => state.setKey(d, 'pin1', 0.25, [[40, 40]]));
    store.edit((d) => state.setKey(d, 'pin1', 1, [[120, 60]]));
    store.edit((d) => state.setKey(d, 'pin2', 0.5, [[470, 40]]));
    ui.setMode('pose');
    await window.inkwarp.app.idle();
  });
  const diamond = (f, t) => page.evaluate(([id, time]) => {
    const el = [...document.querySelectorAll('.tracks .key')].find((k) => k.dataset.feature === id && Math.abs(Number(k.dataset.t) - time) < 1e-6);
    const r = el.getBoundingClientRect();
    return [r.left + r.width / 2, r.top + r.height / 2];
  }, [f, t]);
  const [ax, ay] = await diamond('pin1', 0.25);
  await page.mouse.click(ax, ay);
  const [bx, by] = await diamond('pin2', 0.5);
  await page.keyboard.down('Shift');
  await page.mouse.click(bx, by);
  await page.keyboard.up('Shift');
  const picked = await page.evaluate(() => window.inkwarp.store.view.keySelection);
  assert(picked.length === 2, `Shift-click picked two keys: ${JSON.stringify(picked)}`);
  const wide = await page.evaluate(() => document.querySelector('.tracks .track').getBoundingClientRect().width);
  await dragDiamond(page, 'pin2', 0.5, Math.round((3 / 48) * wide), { step: 4 });
  const times = await page.evaluate(() => Object.fromEntries(window.inkwarp.store.doc.features.filter((f) => f.keys).map((f) => [f.id, f.keys.map((k) => k.t)])));
  assert(Math.abs(times.pin1[0] - (0.25 + 3 / 24)) < 1e-9 && Math.abs(times.pin2[0] - (0.5 + 3 / 24)) < 1e-9 && times.pin1[1] === 1,
    `both picked keys moved three frames together, the other stayed: ${JSON.stringify(times)}`);
  // copy, paste at 1.5 s
  await page.keyboard.press('Control+c');
  await page.evaluate(() => window.inkwarp.ui.setTime(1.5));
  await page.keyboard.press('Control+v');
  const pasted = await page.evaluate(() => Object.fromEntries(window.inkwarp.store.doc.features.filter((f) => f.keys).map((f) => [f.id, f.keys.map((k) => [k.t, k.points])])));
  assert(pasted.pin1.some(([t, p]) => Math.abs(t - 1.5) < 1e-9 && p[0][0] === 40) && pasted.pin2.some(([t]) => Math.abs(t - 1.75) < 1e-9),
    `the keys were pasted at 1.5 s, keeping their spacing: ${JSON.stringify(pasted)}`);
  // the easing chooser of the feature panel
  await page.evaluate(() => window.inkwarp.store.setView({ selection: { feature: 'pin1', point: null } }));
  const options = await page.evaluate(() => [...document.querySelector('.key-interp').options].map((o) => o.value));
  assert(['ease-in', 'ease-out', 'ease-in-out'].every((m) => options.includes(m)), `the easing chooser offers ${options}`);
  await page.selectOption('.key-interp >> nth=0', 'ease-in-out');
  const interp = await page.evaluate(() => window.inkwarp.store.doc.features.find((f) => f.id === 'pin1').keys[0].interpolation);
  assert(interp === 'ease-in-out', `the first key eases in and out: ${interp}`);
  await page.evaluate(async () => {
    window.inkwarp.ui.setTime(0.7);
    await window.inkwarp.app.idle();
  });
  assert(await page.evaluate(() => window.inkwarp.store.view.onion), 'the onion skin is on by default');
  await screenshot(page, 'keys-onion');
  // An option chosen with the pointer gives the keys back: the shortcuts work after the
  // chooser, not in it.
  await page.focus('.key-interp >> nth=0');
  await page.dispatchEvent('.key-interp >> nth=0', 'pointerdown');
  await page.selectOption('.key-interp >> nth=0', 'ease-in');
  assert(await page.evaluate(() => document.activeElement?.tagName !== 'SELECT'), 'the chooser lets go of the focus');
  await page.keyboard.press('o');
  assert(!(await page.evaluate(() => window.inkwarp.store.view.onion)), 'O toggles the onion skin after the chooser');
  await page.keyboard.press('o');
  // Opened with the pointer and closed without a choice: the next key is a shortcut, and an
  // arrow does not change the scene's method.
  const method = await page.evaluate(() => window.inkwarp.store.doc.solver?.method ?? 'tps');
  await page.focus('#method');
  await page.dispatchEvent('#method', 'pointerdown');
  const t0 = await page.evaluate(() => window.inkwarp.store.view.time);
  await page.keyboard.press('ArrowRight');
  const after = await page.evaluate(() => ({ method: window.inkwarp.store.doc.solver?.method ?? 'tps', time: window.inkwarp.store.view.time, focus: document.activeElement?.id }));
  assert(after.method === method && after.time > t0 && after.focus !== 'method', `the arrow stepped a frame: ${JSON.stringify([method, t0, after])}`);
  // Caps Lock: K (no Shift) keys, Shift+K unkeys, Ctrl+Z with a capital undoes.
  const keysOf = () => page.evaluate(() => window.inkwarp.store.doc.features.find((f) => f.id === 'pin1').keys.length);
  const before = await keysOf();
  await page.keyboard.press('K');
  assert((await keysOf()) === before + 1, 'K with Caps Lock keys the feature, as k does');
  await page.keyboard.press('Shift+K');
  assert((await keysOf()) === before, 'Shift+K unkeys it');
  await page.keyboard.press('K');
  await page.keyboard.press('Control+Z');
  assert((await keysOf()) === before, 'Ctrl+Z with Caps Lock undoes');
  // Ctrl+Shift+C stays the browser's (the inspector): the editor neither copies nor says a word.
  await page.evaluate(() => window.inkwarp.ui.message('(marker)', 'info'));
  await page.keyboard.press('Control+Shift+C');
  assert((await page.textContent('#message')) === '(marker)', `Ctrl+Shift+C is left to the browser: ${await page.textContent('#message')}`);
});


test('frames are solved ahead while the editor is left alone: the ready bar fills without Play, then plays from them', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    const doc = await examples.builtinScene(96);
    doc.fps = 12;
    doc.duration = 1;
    doc.features = [{ id: 'dot', kind: 'point', rest: [[40, 40]], keys: [{ t: 0, points: [[40, 40]] }, { t: 1, points: [[60, 50]] }] }];
    doc.layers[0].border = 'hold';
    await ui.openScene(doc, 'ready.json');
    ui.setMode('pose');
    ui.setTime(6 / 12);
    await app.idle();
  });
  const before = Number(await page.getAttribute('#ready', 'data-count'));
  // An edit: every frame solved before it is stale, and solving ahead starts again.
  await page.evaluate(async () => {
    const { store, state, app } = window.inkwarp;
    app.stats.ahead = [];
    store.edit((d) => state.setKey(d, 'dot', 0.5, [[50, 60]]));
    await app.idle();
  });
  const afterEdit = Number(await page.getAttribute('#ready', 'data-count'));
  const order = [];
  const t0 = Date.now();
  while (Date.now() - t0 < 120000) {
    const frames = await page.getAttribute('#ready', 'data-frames');
    if (frames && !order.includes(frames)) order.push(frames);
    if (frames === '0-11') break;
    await page.waitForTimeout(50);
  }
  const ready = Number(await page.getAttribute('#ready', 'data-count'));
  assert(!(await page.evaluate(() => window.inkwarp.store.view.playing)), 'nothing pressed Play');
  assert(ready === 12, `every frame was solved ahead without Play: ${ready}/12 (${order.join(' → ')})`);
  assert(afterEdit < 12, `the edit made the solved frames stale (${afterEdit} ready after it)`);
  // Nearest the playhead first (frame 6; the settle's own solve caches frame 6 itself).
  const solvedAhead = await page.evaluate(() => [...window.inkwarp.app.stats.ahead]);
  const dist = solvedAhead.map((f) => Math.abs(f - 6));
  assert(solvedAhead.length >= 10 && dist.every((d, i) => i === 0 || d >= dist[i - 1]), `the frames nearest the playhead came first: ${solvedAhead.join(', ')}`);
  await page.evaluate(() => { window.inkwarp.app.stats.playback = { expected: 0, shown: 0, dropped: 0 }; });
  await page.keyboard.press('Space');
  await page.waitForTimeout(2000);
  const pb = await page.evaluate(() => ({ ...window.inkwarp.app.stats.playback }));
  await page.keyboard.press('Space');
  perf.readyPlayback = { readyBefore: before, afterEdit, ...pb };
  assert(pb.expected >= 12, `it played: ${JSON.stringify(pb)}`);
  await screenshot(page, 'ready-bar');
});

test('playing in Rest mode shows the drawing posed, as the picture plays; stopped, at rest again', async () => {
  // The picture played posed while the drawing stayed at rest, over the wrong places.
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    const doc = await examples.builtinScene(96);
    doc.features = [{ id: 'dot', kind: 'point', rest: [[20, 20]], keys: [{ t: 0, points: [[70, 70]] }, { t: 2, points: [[70, 70]] }] }];
    await ui.openScene(doc, 'rest-play.json');
    ui.setMode('rest');
    await app.idle();
    app.renderNow();
  });
  // How many overlay pixels about scene pixel (x, y) are drawn.
  const drawnAt = (x, y) => page.evaluate(([x, y]) => {
    const { ui, store } = window.inkwarp;
    const c = ui.overlayCanvas;
    const s = c.width / store.doc.width;
    const d = c.getContext('2d').getImageData(Math.floor((x + 0.5) * s) - 3, Math.floor((y + 0.5) * s) - 3, 7, 7).data;
    let n = 0;
    for (let i = 3; i < d.length; i += 4) if (d[i] > 128) n++;
    return n;
  }, [x, y]);
  const still = [await drawnAt(20, 20), await drawnAt(70, 70)];
  assert(still[0] > 0 && still[1] === 0, `at rest, the point at its rest place: ${still}`);
  await page.keyboard.press('Space');
  await page.waitForTimeout(400);
  const playing = [await page.evaluate(() => window.inkwarp.store.view.playing), await drawnAt(70, 70)];
  await page.keyboard.press('Space');
  await page.evaluate(() => window.inkwarp.app.idle());
  assert(playing[0] && playing[1] > 0, `playing, the point drawn at its pose: ${playing}`);
  const stopped = [await drawnAt(20, 20), await drawnAt(70, 70), await page.evaluate(() => window.inkwarp.store.view.mode)];
  assert(stopped[0] > 0 && stopped[1] === 0 && stopped[2] === 'rest', `stopped, at rest again: ${stopped}`);
});

test('playing frames not solved yet: the drawing is drawn with the picture shown, not ahead of it', async () => {
  // Before, the playhead's drawing ran ahead of an earlier frame's picture until the ready
  // bar filled: the point drawn where the picture had not moved yet.
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    const doc = await examples.builtinScene(1024);
    doc.fps = 12;
    doc.duration = 2;
    doc.features = [
      { id: 'dot', kind: 'point', rest: [[60, 256]], keys: [{ t: 0, points: [[60, 256]] }, { t: 1, points: [[960, 256]] }, { t: 2, points: [[60, 256]] }] },
      { id: 'pin', kind: 'point', rest: [[512, 700]], keys: [{ t: 0, points: [[512, 700]] }] },
    ];
    await ui.openScene(doc, 'lag.json');
    ui.setMode('pose');
    ui.setTime(0);
    await app.idle();
    // An edit just before Play: no frame is solved ahead for it (the dot passes up to 120 px a
    // frame, so a frame behind is well apart).
    const { store, state } = window.inkwarp;
    store.edit((d) => state.setKey(d, 'pin', 0, [[512, 702]]));
    ui.togglePlay();
  });
  const samples = await page.evaluate(() => new Promise((done) => {
    const { ui, store, app, scene } = window.inkwarp;
    const c = ui.overlayCanvas;
    const s = c.width / store.doc.width;
    const dot = store.doc.features.find((f) => f.id === 'dot');
    // Overlay pixels drawn about the dot's place at time t (it moves along y = 256).
    const drawnAt = (t) => {
      const [x, y] = scene.pointsAt(dot, t)[0];
      const d = c.getContext('2d').getImageData(Math.floor((x + 0.5) * s) - 3, Math.floor((y + 0.5) * s) - 3, 7, 7).data;
      let n = 0;
      for (let i = 3; i < d.length; i += 4) if (d[i] > 128) n++;
      return n;
    };
    const out = [];
    const t0 = performance.now();
    const tick = () => {
      ui.drawOverlay();
      const playhead = store.view.time, shown = app.shownTime;
      const apart = shown === null ? 0 : Math.abs(scene.pointsAt(dot, playhead)[0][0] - scene.pointsAt(dot, shown)[0][0]);
      out.push({ playhead, shown, apart, atShown: drawnAt(shown), atPlayhead: drawnAt(playhead) });
      if (performance.now() - t0 < 1500) requestAnimationFrame(tick);
      else done(out);
    };
    requestAnimationFrame(tick);
  }));
  await screenshot(page, 'playing-unsolved');
  await page.keyboard.press('Space');
  await page.evaluate(() => window.inkwarp.app.idle());
  const behind = samples.filter((x) => x.apart > 16); // the playhead a frame or more ahead, well apart on the picture
  perf.playingUnsolved = { samples: samples.length, behind: behind.length };
  assert(behind.length > 0, `some frames played before they were solved: ${JSON.stringify(samples.slice(0, 5))}`);
  const wrong = behind.filter((x) => !(x.atShown > 0 && x.atPlayhead === 0));
  assert(wrong.length === 0, `the dot drawn at the picture's time, not the playhead's: ${JSON.stringify(wrong.slice(0, 5))}`);
});

test('the ready bar of a scene of 1e8 frames (the most a scene may have) marks the frames solved ahead, each at least a pixel wide', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    const doc = await examples.builtinScene(96);
    doc.fps = 1000;
    doc.duration = 1e5;
    doc.features = [{ id: 'dot', kind: 'point', rest: [[40, 40]], keys: [{ t: 0, points: [[40, 40]] }, { t: 1e5, points: [[60, 50]] }] }];
    doc.layers[0].border = 'hold';
    await ui.openScene(doc, 'long.json');
    ui.setMode('pose');
    ui.setTime(5e4);
    await app.idle();
  });
  // Solved ahead nearest the playhead (frame 5e7) first: a run of frames around it (beside
  // frame 0, solved as the scene opened).
  await page.waitForFunction(() => Number(document.querySelector('#ready')?.dataset.count) >= 8, null, { timeout: 60000, polling: 250 });
  const bar = await page.evaluate(() => {
    const ready = document.querySelector('#ready');
    const r = ready.getBoundingClientRect();
    return { frames: ready.dataset.frames, marks: [...ready.children].map((s) => ({ at: (s.getBoundingClientRect().left - r.left) / r.width, px: s.getBoundingClientRect().width })) };
  });
  const runs = bar.frames.split(',').map((run) => run.split('-').map(Number));
  const mid = runs.findIndex(([a, b]) => a < 5e7 && 5e7 < b);
  assert(mid >= 0 && runs.length <= 2, `a run of frames around the playhead's: ${bar.frames.slice(0, 200)}`);
  assert(bar.marks.length === runs.length && bar.marks.every((m) => m.px >= 1) && Math.abs(bar.marks[mid].at - 0.5) < 0.005, `a mark a run, a pixel wide at least, the playhead's mid-ruler: ${JSON.stringify(bar.marks)}`);
  await screenshot(page, 'ready-long');
  // A short scene again: the fields kept for this one's frames are let go.
  await page.evaluate(async () => window.inkwarp.ui.openScene(await window.inkwarp.examples.builtinScene(96), 'short.json'));
});


test('a frame solved ahead on a grid torn by many cuts is the whole solve\'s; a press on the picture ends the one in flight', async () => {
  // 46 random cuts on 256 × 256 (the solver's oracle family), six points moving. Asked a few
  // cycles at a time, each request continuing from the last, such frames ended on a small
  // change 3–5 px from the answer, and were kept as solved.
  const python = join(repo, '.venv/bin/python');
  const dump = spawnSync(python, ['-c', [
    'import json, sys, numpy as np',
    'c = np.load(sys.argv[1])',
    'cuts = np.split(c["cut_points"], np.cumsum(c["cut_lengths"])[:-1])',
    'print(json.dumps({"points": c["points"].tolist(), "disp": (20 * c["displacements"]).tolist(), "cuts": [k.tolist() for k in cuts]}))',
  ].join('\n'), join(repo, 'tests/data/many_cuts_256_seed62.npz')], { encoding: 'utf8' });
  assert(dump.status === 0, `the case loads: ${dump.stderr}`);
  const torn = JSON.parse(dump.stdout);
  await page.evaluate(async (torn) => {
    const { ui, examples, app } = window.inkwarp;
    const doc = await examples.builtinScene(256);
    doc.fps = 12;
    doc.duration = 0.5;
    doc.features = [
      ...torn.cuts.map((rest, i) => ({ id: `cut${i}`, kind: 'cut', rest })),
      ...torn.points.map((p, i) => ({ id: `p${i}`, kind: 'point', rest: [p], keys: [
        { t: 0, points: [[p[0] + torn.disp[i][0], p[1] + torn.disp[i][1]]] },
        { t: 0.5, points: [[p[0] - torn.disp[i][0], p[1] + 2 * torn.disp[i][1]]] },
      ] })),
    ];
    app.stats.ahead = [];
    app.stats.aheadCancelled = 0;
    await ui.openScene(doc, 'torn.json');
    ui.setMode('pose');
    ui.setTime(0);
    await app.idle();
  }, torn);
  // The ready bar's frames once all six are in, or as they are after a minute.
  const allReady = async () => {
    const t0 = Date.now();
    let frames = '';
    while (Date.now() - t0 < 60000 && frames !== '0-5') {
      await page.waitForTimeout(100);
      frames = await page.getAttribute('#ready', 'data-frames');
    }
    return frames;
  };
  let frames = await allReady();
  assert(frames === '0-5', `every frame was solved ahead: ${frames}`);
  // Each cached frame against a solve from scratch to a tight tolerance, on a grid of its own.
  const worst = await page.evaluate(() => {
    const { app, engine } = window.inkwarp;
    const doc = app.store.doc;
    const layer = doc.layers[0];
    const rt = app.runtimes.get(layer.name);
    const grid = engine.grid(doc.width, doc.height, rt.matte, app.cutsOf(layer));
    const out = [];
    for (let f = 0; f < 6; f++) {
      const kept = app.cache.frames.get(f)?.get(layer.name);
      const { field, report } = grid.solve(app.solveFeatures(layer, f / doc.fps), { ...app.solverOptions(layer, 'final'), tolerance_px: 1e-3, max_cycles: 1000 }, null);
      let d = Infinity;
      if (kept && report.converged) {
        d = 0;
        for (let i = 0; i < field.dx.length; i++) d = Math.max(d, Math.abs(field.dx[i] - kept.dx[i]), Math.abs(field.dy[i] - kept.dy[i]));
      }
      out.push(d);
    }
    grid.free();
    return out;
  });
  assert(worst.every((d) => d <= 0.06), `the frames solved ahead are within the tolerance of the answer (px): ${worst.map((d) => d.toFixed(4)).join(', ')}`);
  // An edit makes them stale; a press on the picture while one is solved ends it.
  let cancelled = 0;
  for (let round = 0; round < 20 && cancelled === 0; round++) {
    await page.evaluate(async (round) => {
      const { store, state } = window.inkwarp;
      store.edit((d) => state.setKey(d, 'p0', 0.25, [[190 + round, 90]]));
    }, round);
    await page.waitForFunction(() => window.inkwarp.app.ahead?.busy, null, { timeout: 10000 }).catch(() => {});
    // Counted across the press alone (the edit may end a stale one too).
    cancelled = await page.evaluate(() => {
      const { app } = window.inkwarp;
      const before = app.stats.aheadCancelled;
      const c = document.querySelector('canvas.overlay');
      const r = c.getBoundingClientRect();
      c.dispatchEvent(new PointerEvent('pointerdown', { bubbles: true, button: 0, pointerId: 1, clientX: r.left + 5, clientY: r.top + 5 }));
      const after = app.stats.aheadCancelled;
      c.dispatchEvent(new PointerEvent('pointerup', { bubbles: true, button: 0, pointerId: 1, clientX: r.left + 5, clientY: r.top + 5 }));
      return after - before;
    });
  }
  assert(cancelled > 0, 'a press ended the frame being solved ahead');
  // Asked again once the editor is left alone, in a fresh worker.
  frames = await allReady();
  assert(frames === '0-5', `every frame was solved ahead again: ${frames}`);
  perf.aheadTorn = { worstPx: worst, cancelled };
});

/** Resident memory (MiB) of the browser's processes: every page, worker and the GPU process. */
function browserRssMiB() {
  const r = spawnSync('ps', ['-C', 'chromium', '-o', 'rss='], { encoding: 'utf8' });
  return r.stdout.split('\n').filter(Boolean).reduce((s, v) => s + Number(v), 0) / 1024;
}

// The browser's memory apart by process kind (browser, renderer = the page and its workers,
// gpu-process, utility, zygote): resident (RSS) and proportional (PSS: shared pages split
// between the processes that map them, so the sum counts each page once), in MiB. Only
// this run's browser is counted (the processes descended from this one): another browser
// on the machine would otherwise count too.
function browserMemoryByKind() {
  const r = spawnSync('ps', ['-e', '-o', 'pid=,ppid=,comm=,args='], { encoding: 'utf8' });
  const rows = r.stdout.split('\n').filter(Boolean).map((l) => l.trim().split(/\s+/));
  const ours = new Set([String(process.pid)]);
  for (let grew = true; grew; ) {
    grew = false;
    for (const [pid, ppid] of rows) if (ours.has(ppid) && !ours.has(pid)) { ours.add(pid); grew = true; }
  }
  const out = {};
  for (const [pid, , comm, ...args] of rows) {
    if (!ours.has(pid) || !comm.startsWith('chromium')) continue;
    const type = (args.find((a) => a.startsWith('--type=')) ?? '--type=browser').slice(7);
    let rss = 0, pss = 0;
    try {
      const t = readFileSync(`/proc/${pid}/smaps_rollup`, 'utf8');
      rss = Number(/^Rss:\s+(\d+)/m.exec(t)?.[1] ?? 0) / 1024;
      pss = Number(/^Pss:\s+(\d+)/m.exec(t)?.[1] ?? 0) / 1024;
    } catch { continue; }
    const o = (out[type] ??= { n: 0, rssMiB: 0, pssMiB: 0 });
    o.n++; o.rssMiB += rss; o.pssMiB += pss;
  }
  for (const o of Object.values(out)) { o.rssMiB = Math.round(o.rssMiB); o.pssMiB = Math.round(o.pssMiB); }
  return out;
}

// A 4000×3000 photograph (made in the page: gradients, shapes, texture and noise, saved as
// a JPEG) opened, dragged and settled; times and memory reported, never asserted.
test('a 4000×3000 photograph opens as a proxy, drags, and settles to the full-resolution frame', async () => {
  const rssBefore = browserRssMiB();
  const kindsBefore = browserMemoryByKind();
  const { page: p, context } = await openEditor(browser, server.url);
  try {
    // For comparison: the built-in 512 × 512 example opened the same way, in the same page.
    const small = await p.evaluate(async () => {
      const { ui, examples, app } = window.inkwarp;
      const doc = await examples.builtinScene();
      const t = performance.now();
      await ui.openScene(doc, 'small.json');
      await app.idle();
      return { openS: (performance.now() - t) / 1000, size: `${doc.width}×${doc.height}`, heapMiB: performance.memory ? performance.memory.usedJSHeapSize / 2 ** 20 : null };
    });
    const rssSmall = browserRssMiB();
    const t0 = Date.now();
    await p.evaluate(async () => {
      const c = new OffscreenCanvas(4000, 3000);
      const g = c.getContext('2d');
      const grad = g.createLinearGradient(0, 0, 4000, 3000);
      grad.addColorStop(0, '#8ab'); grad.addColorStop(0.5, '#db7'); grad.addColorStop(1, '#374');
      g.fillStyle = grad;
      g.fillRect(0, 0, 4000, 3000);
      for (let i = 0; i < 400; i++) {
        g.fillStyle = `hsl(${(i * 47) % 360} 60% ${30 + (i % 5) * 10}%)`;
        g.beginPath();
        g.arc((i * 7919) % 4000, (i * 104729) % 3000, 20 + (i % 13) * 9, 0, Math.PI * 2);
        g.fill();
      }
      // Texture: fine stripes and per-pixel noise, as a photograph has.
      const img = g.getImageData(0, 0, 4000, 3000);
      let seed = 7;
      for (let i = 0; i < img.data.length; i += 4) {
        seed = (seed * 1103515245 + 12345) & 0x7fffffff;
        const x = (i / 4) % 4000;
        const n = ((seed >> 16) % 25) - 12 + 10 * Math.sin(x / 3);
        img.data[i] += n; img.data[i + 1] += n; img.data[i + 2] += n;
      }
      g.putImageData(img, 0, 0);
      const blob = await c.convertToBlob({ type: 'image/jpeg', quality: 0.9 });
      window.__photo = new File([blob], 'photo.jpg', { type: 'image/jpeg' });
    });
    const made = Date.now();
    const firstFrame = await p.evaluate(async () => {
      const { app, ui } = window.inkwarp;
      const t = performance.now();
      let first = null;
      const was = app.onFrame;
      app.onFrame = () => { if (first === null && app.proxy > 1) first = performance.now() - t; was(); };
      await ui.openFile(window.__photo);
      await app.idle();
      app.onFrame = was;
      window.__openSteps = { ...app.stats.open, fullAtRest: app.stats.fullParts[0] };
      return first;
    });
    const opened = Date.now();
    const atOpen = await p.evaluate(() => {
      const { app, store } = window.inkwarp;
      return { proxy: app.proxy, frame: app.frameSize, gridStep: store.doc.solver?.grid_step, full: !!app.fullShown, note: document.querySelector('#proxy-note').hidden };
    });
    assert(atOpen.proxy === 4 && atOpen.frame.width === 1000 && atOpen.frame.height === 750, `a 1/4 proxy: ${JSON.stringify(atOpen)}`);
    assert(atOpen.gridStep === 4, `the scene's grid step is the proxy's factor, so inkwarp render solves the same: ${atOpen.gridStep}`);
    assert(atOpen.full && atOpen.note, `at rest the full-resolution picture shows and no proxy notice: ${JSON.stringify(atOpen)}`);
    // A patch of the picture as the full-resolution frame on screen shows it (a view of
    // it: its region of the frame drawn `shrink` times smaller, see `viewFor`).
    const patch = (x0, y0, size) => p.evaluate(({ x0, y0, size }) => {
      const f = window.inkwarp.app.fullShown;
      const k = f.view?.shrink ?? 1;
      const [rx0, ry0, rx1] = f.view?.region ?? [0, 0, f.width];
      const out = [];
      for (let y = y0; y < y0 + size; y++) for (let x = x0; x < x0 + size; x++) {
        const i = 4 * ((Math.floor(y / k) - ry0) * (rx1 - rx0) + Math.floor(x / k) - rx0);
        out.push(f.pixels[i], f.pixels[i + 1], f.pixels[i + 2]);
      }
      return out;
    }, { x0, y0, size });
    const restPatch = await patch(1950, 1350, 100);
    await p.evaluate(async () => {
      const { store, state, ui, app } = window.inkwarp;
      store.edit((d) => state.addFeature(d, 'spline', [[1200, 900], [2000, 1500], [2800, 2100]]).doc);
      store.edit((d) => state.addFeature(d, 'point', [[600, 2400]]).doc);
      ui.setMode('pose');
      ui.setTool('select');
      await app.idle();
      app.resetStats();
    });
    // The page's main thread during the drag: each scene change's synchronous work (the
    // views following the drawing) and each field's arrival, timed around them.
    // Page helpers for the timings below: `__timeCalls(obj, name, into)` times each call of
    // `obj[name]` into `into` (returns the undo), `__median(a)` the middle value.
    await p.evaluate(() => {
      window.__timeCalls = (obj, name, into) => {
        const was = obj[name];
        obj[name] = function (...args) { const t0 = performance.now(); try { return was.apply(this, args); } finally { into.push(performance.now() - t0); } };
        return () => { obj[name] = was; };
      };
      window.__median = (a) => { const b = [...a].sort((x, y) => x - y); return b.length ? b[b.length >> 1] : null; };
    });
    await p.evaluate(() => {
      const { app, store } = window.inkwarp;
      const t = (window.__dragTimes = { apply: [], receive: [] });
      const wrap = window.__timeCalls;
      const undo = [wrap(store, 'apply', t.apply), wrap(app, 'receive', t.receive)];
      window.__dragUndo = () => { for (const u of undo) u(); };
    });
    // The notice while dragging, sampled at each step of the drag.
    const [x0, y0] = await toClient(p, [2000, 1500]);
    const [x1, y1] = await toClient(p, [2200, 1300]);
    await p.mouse.move(x0, y0);
    await p.mouse.down();
    const notes = [];
    const drafts = [];
    // Background work while the pointer is down (it shares the cores with the drag's frames).
    const background = [];
    const sampleBackground = () => p.evaluate(() => {
      const { app } = window.inkwarp;
      return { full: !!app.full?.busy, ahead: !!app.ahead?.busy, renewals: (app.full?.renewals ?? 0) + (app.ahead?.renewals ?? 0) };
    });
    background.push(await sampleBackground());
    for (let i = 1; i <= 20; i++) {
      background.push(await sampleBackground());
      await p.mouse.move(x0 + ((x1 - x0) * i) / 20, y0 + ((y1 - y0) * i) / 20);
      await p.evaluate(() => new Promise((r) => requestAnimationFrame(() => r())));
      // The draft the CPU drew (a software GPU), at this step.
      drafts.push(await p.evaluate(() => {
        const c = document.querySelector('canvas.cpu-draft');
        return c && c.style.visibility === 'visible' ? `${c.width}×${c.height}` : '';
      }));
      notes.push(await p.evaluate(() => {
        const n = document.querySelector('#proxy-note');
        // The full-resolution frame of the rest pose must not cover the proxy's drafts.
        return document.querySelector('canvas.full').hidden ? (n.hidden ? '' : n.textContent) : 'the full-resolution canvas is shown';
      }));
    }
    const rssDrag = browserRssMiB();
    const kindsDrag = browserMemoryByKind();
    const workersDrag = await p.evaluate(() => window.inkwarp.app.memoryReport?.());
    if (process.env.SHOW_RSS) console.log(spawnSync('ps', ['-C', 'chromium', '-o', 'rss=,args='], { encoding: 'utf8' }).stdout.split('\n').map((l) => l.slice(0, 160).replace(/--[a-z-]+=\S{40,}/g, '')).join('\n'));
    await shot(p, 'photo-proxy');
    const dragMain = await p.evaluate(() => {
      window.__dragUndo();
      const t = window.__dragTimes;
      const med = window.__median;
      return { applyMs: med(t.apply), applyMaxMs: Math.max(0, ...t.apply), applies: t.apply.length, receiveMs: med(t.receive), receives: t.receive.length };
    });
    await p.mouse.up();
    const released = Date.now();
    const afterRelease = await p.evaluate(() => { const n = document.querySelector('#proxy-note'); return n.hidden ? '' : n.textContent; });
    await idle(p);
    const settled = Date.now();
    await p.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(() => r()))));
    await shot(p, 'photo-settled');
    const s = await p.evaluate(() => {
      const { stats, fullShown } = window.inkwarp.app;
      const mem = performance.memory ? { used: performance.memory.usedJSHeapSize, total: performance.memory.totalJSHeapSize, wasm: window.inkwarp.engine.x.memory.buffer.byteLength / 2 ** 20 } : null;
      const note = document.querySelector('#proxy-note');
      return { drag: [...stats.dragLatency], dragParts: stats.dragParts, draft: [...stats.draftSolveMs], final: [...stats.finalSolveMs], full: [...stats.fullMs], fullParts: stats.fullParts, heap: mem, open: window.__openSteps, fullShown: !!fullShown, note: note.hidden ? '' : note.textContent };
    });
    // Memory once the posed frame is drawn, and once the editor has been left alone long
    // enough for the full-resolution worker to be replaced by a fresh one (see
    // `RENEW_IDLE_MS`; waited for up to 15 s, and reported, never asserted).
    const rssSettled = browserRssMiB();
    const kindsSettled = browserMemoryByKind();
    const workersSettled = await p.evaluate(() => window.inkwarp.app.memoryReport?.());
    // The settled frame is drawn for the view: at Fit, the frame a whole factor smaller; it
    // looks like the whole full-resolution frame scaled down by that factor (each block's
    // premultiplied mean, as the canvas would show it), within a small difference.
    const viewCheck = await p.evaluate(async () => {
      const { app } = window.inkwarp;
      const v = app.fullShown.view;
      const whole = await app.wholeFrame();
      const k = v.shrink;
      const [x0, y0, x1, y1] = v.region;
      const d = [];
      for (let j = y0; j < y1; j++) for (let i = x0; i < x1; i++) {
        const acc = [0, 0, 0, 0];
        let n = 0;
        for (let y = j * k; y < Math.min(whole.height, (j + 1) * k); y++) for (let x = i * k; x < Math.min(whole.width, (i + 1) * k); x++) {
          const q = 4 * (y * whole.width + x);
          const a = whole.pixels[q + 3] / 255;
          acc[0] += whole.pixels[q] * a; acc[1] += whole.pixels[q + 1] * a; acc[2] += whole.pixels[q + 2] * a; acc[3] += a;
          n++;
        }
        const o = 4 * ((j - y0) * (x1 - x0) + i - x0);
        for (let c = 0; c < 3; c++) d.push(Math.abs(app.fullShown.pixels[o + c] - (acc[3] > 0 ? acc[c] / acc[3] : 0)));
      }
      d.sort((a, b) => a - b);
      return { view: v, wholeSize: [whole.width, whole.height], mean: d.reduce((a, b) => a + b, 0) / d.length, p99: d[Math.floor(d.length * 0.99)], max: d.at(-1), fullMiB: app.fullShown.pixels.byteLength / 2 ** 20 };
    });
    console.log(`  settled view against the whole frame scaled: ${JSON.stringify(viewCheck)}`);
    assert(viewCheck.view.shrink >= 2 && viewCheck.wholeSize[0] === 4000, `at Fit the settled frame is drawn smaller: ${JSON.stringify(viewCheck)}`);
    assert(viewCheck.mean < 3 && viewCheck.p99 < 40, `the settled view looks like the whole frame scaled down: ${JSON.stringify(viewCheck)}`);
    // Zoomed to 100 %: the view is drawn again (no solve) at the picture's own pixels, the
    // visible part only; back at Fit, smaller again.
    const zoomCheck = await p.evaluate(async () => {
      const { app, ui } = window.inkwarp;
      const wait = async (ok) => { for (let i = 0; i < 100 && !ok(); i++) await new Promise((r) => setTimeout(r, 100)); await app.idle(); };
      const fulls = app.stats.fullParts.length;
      ui.zoom100();
      await wait(() => app.fullShown?.view?.shrink === 1);
      const at100 = { view: app.fullShown?.view, solves: app.stats.fullParts.slice(fulls).map((q) => q.cycles.length), note: document.querySelector('#proxy-note').hidden ? '' : document.querySelector('#proxy-note').textContent };
      return at100;
    });
    await p.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(() => r()))));
    await shot(p, 'photo-settled-100');
    const backToFit = await p.evaluate(async () => {
      const { app, ui } = window.inkwarp;
      ui.zoomFit();
      for (let i = 0; i < 100 && !(app.fullShown?.view?.shrink > 1); i++) await new Promise((r) => setTimeout(r, 100));
      await app.idle();
      return app.fullShown?.view;
    });
    console.log(`  zoom: 100 % ${JSON.stringify(zoomCheck)}, back to Fit ${JSON.stringify(backToFit)}`);
    const [zx0, zy0, zx1, zy1] = zoomCheck.view?.region ?? [0, 0, 0, 0];
    assert(zoomCheck.view?.shrink === 1 && zx1 - zx0 < 4000 && zy1 - zy0 < 3000, `at 100 % the view is the visible part at the picture's pixels: ${JSON.stringify(zoomCheck)}`);
    assert(zoomCheck.solves.every((n) => n === 0), `the zoomed view is drawn from the kept fields, no solve: ${JSON.stringify(zoomCheck)}`);
    assert(backToFit?.shrink === viewCheck.view.shrink, `back at Fit the view is drawn smaller again: ${JSON.stringify(backToFit)}`);
    // A second drag of the same point a little further, soon after the first settle (the
    // full-resolution worker keeps its solver from one frame to the next): its settle.
    await drag(p, [2200, 1300], [2250, 1250], 5);
    const released2 = Date.now();
    await idle(p);
    const settle2S = (Date.now() - released2) / 1000;
    const settle2Parts = await p.evaluate(() => window.inkwarp.app.stats.fullParts.at(-1) ?? null);
    // Left alone past `RENEW_IDLE_MS` (8 s): the full-resolution worker keeps the fields of
    // the frame on screen (its solver), so it is not replaced, and a zoom then is still drawn
    // from them without a solve (see `RENEW_KEPT_BYTES`).
    const renewedBefore = await p.evaluate(() => window.inkwarp.app.full?.renewals ?? 0);
    const fullBeforeIdleMiB = (await p.evaluate(() => window.inkwarp.app.memoryReport?.()))?.full?.wasmMiB ?? null;
    const keptBoundMiB = await p.evaluate(() => window.inkwarp.app.full.renewal.keptBytes / 2 ** 20); // RENEW_KEPT_BYTES
    assert(keptBoundMiB > 0, `the full-resolution worker's kept-solver bound (RENEW_KEPT_BYTES) reads as ${keptBoundMiB} MiB`);
    const idleFrom = Date.now();
    await p.waitForTimeout(9500);
    const renewedAfterS = (Date.now() - idleFrom) / 1000;
    const rssIdle = browserRssMiB();
    const kindsIdle = browserMemoryByKind();
    const workersIdle = await p.evaluate(() => window.inkwarp.app.memoryReport?.());
    const renewals = await p.evaluate(() => window.inkwarp.app.full?.renewals ?? null);
    const zoomAfterIdle = await p.evaluate(async () => {
      const { app, ui } = window.inkwarp;
      const fulls = app.stats.fullParts.length;
      const t = performance.now();
      ui.zoom100();
      for (let i = 0; i < 100 && app.fullShown?.view?.shrink !== 1; i++) await new Promise((r) => setTimeout(r, 50));
      await app.idle();
      const ms = performance.now() - t;
      ui.zoomFit();
      for (let i = 0; i < 100 && !(app.fullShown?.view?.shrink > 1); i++) await new Promise((r) => setTimeout(r, 50));
      await app.idle();
      return { ms, solves: app.stats.fullParts.slice(fulls).map((q) => q.cycles.length) };
    });
    if (fullBeforeIdleMiB !== null && fullBeforeIdleMiB <= keptBoundMiB) {
      assert(renewals === renewedBefore, `left alone, the full-resolution worker holding the settled frame's solver (${fullBeforeIdleMiB} MiB) is kept: ${renewedBefore} → ${renewals}`);
      assert(zoomAfterIdle.solves.every((n) => n === 0), `a zoom after the pause is drawn from the kept fields, no solve: ${JSON.stringify(zoomAfterIdle)}`);
    } else {
      assert(renewals > renewedBefore, `left alone, a full-resolution worker grown past ${keptBoundMiB} MiB (${fullBeforeIdleMiB} MiB) is replaced: ${renewedBefore} → ${renewals}`);
    }
    const posedPatch = await patch(1950, 1350, 100);
    let diff = 0;
    for (let i = 0; i < restPatch.length; i++) diff += Math.abs(restPatch[i] - posedPatch[i]);
    diff /= restPatch.length;
    perf.photo = {
      openS: (opened - made) / 1000, firstProxyFrameS: firstFrame / 1000, openSteps: s.open, fullParts: s.fullParts,
      dragMedianMs: median(s.drag), dragP90Ms: pct(s.drag, 0.9), dragFrames: s.drag.length,
      dragParts: Object.fromEntries(['queued', 'toWorker', 'solve', 'workerDraw', 'back', 'upload', 'toFrame', 'draw', 'gpu', 'total'].map((k) => [k, median(s.dragParts.map((q) => q[k]))])),
      dragMain, background, draftSolveMedianMs: median(s.draft), proxySolveMs: s.final, fullFrameMs: s.full, settleS: (settled - released) / 1000, settle2S, settle2Parts,
      heapMiB: s.heap && s.heap.used / 2 ** 20, pageWasmMiB: s.heap?.wasm, browserRssMiB: rssDrag, browserRssSettledMiB: rssSettled, browserRssIdleMiB: rssIdle, idleWaitS: renewedAfterS, fullWorkerRenewals: renewals, fullBeforeIdleMiB, keptBoundMiB, zoomAfterIdle, browserRssBeforeMiB: rssBefore,
      makeS: (made - t0) / 1000, patchDiff: diff, viewCheck, zoomCheck, byKind: { before: kindsBefore, drag: kindsDrag, settled: kindsSettled, idle: kindsIdle }, workers: { drag: workersDrag, settled: workersSettled, idle: workersIdle }, small: { ...small, browserRssMiB: rssSmall },
    };
    console.log(`  photo: ${JSON.stringify(perf.photo)}`);
    assert(notes.every((n) => n.startsWith('Preview (1/4')), `the proxy notice shows while dragging, and the proxy: ${JSON.stringify(notes.slice(0, 3))}`);
    assert(afterRelease.startsWith('Preview (1/4'), `and while settling: ${afterRelease}`);
    // While dragging, the proxy's drafts are drawn at half its size (see `App.draftShrink`).
    const renderer = await p.evaluate(() => window.inkwarp.app.gl.cpuDrafts);
    assert(!renderer || drafts.includes('500×375'), `the drafts drawn while dragging are 500×375: ${JSON.stringify(drafts)}`);
    assert(s.fullShown && s.note === '' && !(await p.evaluate(() => document.querySelector('canvas.full').hidden)), `after the settle the full-resolution frame shows, no notice: ${s.note}`);
    assert(!s.heap || s.heap.wasm < 64, `the photograph was decoded off the page (its decoder's memory is not kept in the page's module): the page's module holds ${s.heap?.wasm} MiB`);
    assert(diff > 3, `the settled frame moved where the drag pulled (mean difference ${diff.toFixed(2)} from the rest picture)`);
    // Playback of the proxy from the fields solved ahead (a proxied scene keeps them
    // packed, in a smaller budget): 2 s played once every frame that fits is solved.
    let readyFrames = -1;
    for (const t = Date.now(); Date.now() - t < 30000; ) {
      const n = Number(await p.getAttribute('#ready', 'data-count'));
      if (n === readyFrames && !(await p.evaluate(() => window.inkwarp.app.ahead?.busy))) break;
      readyFrames = n;
      await p.waitForTimeout(1000);
    }
    const frameTotal = await p.evaluate(() => window.inkwarp.scene.frameCount(window.inkwarp.store.doc));
    // Where a played frame's time goes on the page's main thread: the time change (the
    // store's views, the cache's fields to the layers) and the frame's drawing, each timed
    // around its synchronous work, and the animation frames the page got in the 2 s.
    await p.evaluate(() => {
      const { app, store } = window.inkwarp;
      const t = (window.__playTimes = { setView: [], frameTick: [], rafs: 0 });
      const wrap = window.__timeCalls;
      const undo = [wrap(store, 'setView', t.setView), wrap(app, 'frameTick', t.frameTick)];
      let on = true;
      const raf = () => { if (!on) return; t.rafs++; requestAnimationFrame(raf); };
      requestAnimationFrame(raf);
      window.__playUndo = () => { on = false; for (const u of undo) u(); };
    });
    await p.keyboard.press('Space');
    await p.waitForTimeout(2000);
    const played = await p.evaluate(() => ({ ...window.inkwarp.app.stats.playback, cacheMiB: Math.round((window.inkwarp.app.cache?.bytes ?? 0) / 2 ** 20) }));
    await p.keyboard.press('Space');
    const playTimes = await p.evaluate(() => {
      window.__playUndo();
      const t = window.__playTimes;
      const med = window.__median;
      return { setViewMs: med(t.setView), frameTickMs: med(t.frameTick), frameTickMaxMs: Math.max(0, ...t.frameTick), ticks: t.frameTick.length, animationFrames: t.rafs };
    });
    played.mainThread = playTimes;
    // What playback shows (a draft drawn ahead), for a look: half a second into a second play.
    await p.keyboard.press('Space');
    await p.waitForTimeout(500);
    await shot(p, 'photo-playing');
    await p.keyboard.press('Space');
    perf.photo.playback = { readyFrames, frameTotal, ...played };
    console.log(`  photo playback: ${JSON.stringify(perf.photo.playback)}`);
    // Memory given back: where the CPU plays the proxy's frames (a software GPU), the fields
    // solved ahead are kept at the draft mesh's pixels only; once every frame is solved the
    // ahead worker is replaced by a fresh one (its module memory freed); and a change frees
    // the stale fields and frames drawn ahead at once.
    const freed = await p.evaluate(async () => {
      const { app, store, state } = window.inkwarp;
      for (let i = 0; i < 40 && !(app.ahead?.renewals > 0); i++) await new Promise((r) => setTimeout(r, 250));
      const before = { cpu: app.gl.cpuDrafts, renewals: app.ahead?.renewals ?? 0, cacheBytes: app.cache.bytes, frames: app.cache.frames.size, drawn: app.drawnFrames.frames.size };
      store.edit((d) => state.addFeature(d, 'point', [[400, 400]]).doc);
      return { ...before, afterEdit: { cacheBytes: app.cache.bytes, drawnBytes: app.drawnFrames.bytes } };
    });
    perf.photo.freed = freed;
    assert(!freed.cpu || (freed.frames >= 40 && freed.cacheBytes < 4 * 2 ** 20), `the proxy's fields solved ahead are kept at the draft mesh's pixels only: ${JSON.stringify(freed)}`);
    assert(freed.renewals >= 1, `every frame solved ahead, the ahead worker was replaced by a fresh one: ${JSON.stringify(freed)}`);
    assert(freed.afterEdit.cacheBytes === 0 && freed.afterEdit.drawnBytes === 0, `a change frees the stale fields and frames drawn ahead at once: ${JSON.stringify(freed.afterEdit)}`);
  } finally {
    await context.close();
  }
});


test('a layer smaller than the scene is placed by its offset (numeric fields, Move drag) and drawn as `inkwarp render` draws it', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app, store } = window.inkwarp;
    const doc = await examples.builtinScene(96);
    doc.duration = 1;
    doc.features = [{ id: 'pull', kind: 'point', rest: [[20, 12]], keys: [{ t: 0, points: [[20, 12]] }, { t: 1, points: [[26, 16]] }] }];
    await ui.openScene(doc, 'placed.json');
    ui.saveUrl = null;
    // A 40 × 24 sticker: red with a green square, opaque.
    const w = 40, h = 24, data = new Uint8Array(4 * w * h);
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
      const green = x >= 10 && x < 30 && y >= 6 && y < 18;
      data.set(green ? [30, 200, 60, 255] : [220, 40, 40, 255], 4 * (y * w + x));
    }
    await ui.addPlacedLayer({ width: w, height: h, data }, 'sticker.png');
    store.setView({ activeLayer: store.doc.layers.length - 1 });
    await app.idle();
  });
  const placed = await page.evaluate(async () => {
    const { store, images } = window.inkwarp;
    const l = store.doc.layers.at(-1);
    const img = await images.decodeImage(l.image);
    return { name: l.name, offset: l.offset, w: img.width, h: img.height };
  });
  assert(placed.name === 'sticker' && placed.w === 96 && placed.h === 96, `the layer is stored at the scene's size: ${JSON.stringify(placed)}`);
  assert(JSON.stringify(placed.offset) === '[28,36]', `a smaller picture starts centred: ${JSON.stringify(placed.offset)}`);
  // The numeric fields.
  await page.fill('#layer-offset-x', '10');
  await page.press('#layer-offset-x', 'Enter');
  await page.fill('#layer-offset-y', '60');
  await page.press('#layer-offset-y', 'Enter');
  const byField = await page.evaluate(() => window.inkwarp.store.doc.layers.at(-1).offset);
  assert(JSON.stringify(byField) === '[10,60]', `the offset fields set the offset: ${JSON.stringify(byField)}`);
  let img = await frame(page);
  const at = (im, x, y) => Array.from(im.data.subarray(4 * (y * im.width + x), 4 * (y * im.width + x) + 3));
  assert(at(img, 10 + 20, 60 + 12)[1] > 150 && at(img, 10 + 2, 60 + 2)[0] > 150, `the sticker is drawn at its offset: ${at(img, 30, 72)} ${at(img, 12, 62)}`);
  // Move: a drag on the picture moves the layer by as much.
  await page.click('#layer-move');
  await drag(page, [40, 70], [52, 64], 6);
  await page.click('#layer-move');
  const byDrag = await page.evaluate(() => window.inkwarp.store.doc.layers.at(-1).offset);
  assert(Math.abs(byDrag[0] - 22) <= 1 && Math.abs(byDrag[1] - 54) <= 1, `a Move drag of (12, −6) px moved the layer: ${JSON.stringify(byDrag)}`);
  // The matte overlay shows the layer's holes (its transparent margin) where the layer is
  // placed: none over the sticker itself.
  const m = await matteMarks(page);
  await overlayOff(page);
  const overlay = { sticker: marked(m, byDrag[0] + 20, byDrag[1] + 12), beside: marked(m, byDrag[0] + 45, byDrag[1] + 12) };
  assert(!overlay.sticker && overlay.beside, `the matte overlay at the layer's offset: ${JSON.stringify(overlay)}`);
  // A point traced over the green square's left edge where it is now, in the frame, and
  // moved 6 px right by t = 1: the sticker follows it (3 px at t = 0.5).
  const edge = [byDrag[0] + 10, byDrag[1] + 12];
  await page.evaluate(async (edge) => {
    const { ui, app, store } = window.inkwarp;
    // (It drives the sticker alone: with two points on the picture below, the editor's and
    // the command line's solves, each within the 0.05 px contract, differ at the rings'
    // sharp edges by more than this comparison's tolerance.)
    store.edit((d) => ({
      ...d,
      layers: d.layers.map((l, i) => (i === d.layers.length - 1 ? { ...l, features: ['prop'] } : { ...l, features: l.features ?? d.features.map((f) => f.id) })),
      features: [...d.features, { id: 'prop', kind: 'point', rest: [edge], keys: [{ t: 0, points: [edge] }, { t: 1, points: [[edge[0] + 6, edge[1]]] }] }],
    }));
    ui.setMode('pose');
    ui.setTime(0.5);
    await app.idle();
  }, edge);
  img = await frame(page);
  const left = at(img, edge[0] + 1, edge[1]), inside = at(img, edge[0] + 4, edge[1]);
  assert(left[0] > 150 && left[1] < 100 && inside[1] > 150, `the sticker follows the point traced over it in the frame: ${left} at x + 1 (red), ${inside} at x + 4 (green)`);
  await screenshot(page, 'layer-offset');
  // The same frame from the command line.
  const dir = scratchDir('inkwarp-e2e-');
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#save')]);
  const scenePath = join(dir, 'scene.json');
  await download.saveAs(scenePath);
  const out = join(dir, 'frame.png');
  const run = spawnSync(inkwarp, ['render', scenePath, '--time', '0.5', '-o', out], { encoding: 'utf8' });
  assert(run.status === 0, `inkwarp render failed (${run.status}): ${run.stderr}`);
  const cli = await loadPng(page, out);
  img = await frame(page);
  const { ok, stats } = await compareImages(page, img, cli, 'placed-layer-vs-cli', { meanTol: 1.0, p99Tol: 12 });
  perf.placedLayerVsCli = stats;
  assert(ok, `the editor's frame with the placed layer and inkwarp render's differ: mean ${stats.mean.toFixed(3)}, p99 ${stats.p99}`);
});


test('a layer moved under a cut builds its grid once, when the drag ends, torn where the cut is now', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    const doc = await examples.builtinScene(256);
    // A point beside the slit, pulled across where it will be once the layer has moved.
    doc.duration = 1;
    doc.features.push({ id: 'tug', kind: 'point', rest: [[170, 128]], keys: [{ t: 0, points: [[170, 128]] }, { t: 1, points: [[150, 120]] }] });
    await ui.openScene(doc, 'cut.json');
    ui.setMode('pose');
    ui.setTime(1);
    await app.idle();
    window.gridBuilds = 0;
    for (const c of app.clients) {
      const own = c.setGrid.bind(c);
      c.setGrid = (...a) => { window.gridBuilds++; return own(...a); };
    }
  });
  await page.click('#layer-move');
  await drag(page, [60, 60], [90, 70], 8);
  await page.click('#layer-move');
  const got = await page.evaluate(async () => {
    const { app, engine, store } = window.inkwarp;
    await app.idle();
    const doc = store.doc;
    const layer = doc.layers[0];
    const rt = app.runtimes.get(layer.name);
    const o = layer.offset ?? [0, 0];
    // The slit in the layer's own pixels: where the frame's cut now lies over the moved picture.
    const cuts = doc.features.filter((f) => f.kind === 'cut').map((f) => f.rest.map(([x, y]) => [x - o[0], y - o[1]]));
    const grid = engine.grid(doc.width, doc.height, rt.matte, cuts);
    const want = grid.links();
    grid.free();
    let differ = 0;
    for (let i = 0; i < want.length; i++) differ += want[i] !== rt.links[i] ? 1 : 0;
    // What is shown was solved on that grid, as the same scene opened afresh shows it: not
    // a field solved during the drag on the grid from before it, nor one kept for playback
    // (shown again after a step away and back).
    const { ui } = window.inkwarp;
    ui.setTime(0.5);
    await app.idle();
    ui.setTime(1);
    await app.idle();
    const shown = rt.field;
    await window.inkwarp.ui.openScene(structuredClone(doc), 'moved.json');
    window.inkwarp.ui.setMode('pose');
    window.inkwarp.ui.setTime(1);
    await app.idle();
    const fresh = app.runtimes.get(layer.name).field;
    let apart = 0;
    for (let i = 0; i < fresh.dx.length; i++) apart = Math.max(apart, Math.abs(fresh.dx[i] - shown.dx[i]), Math.abs(fresh.dy[i] - shown.dy[i]));
    return { builds: window.gridBuilds, clients: app.clients.length, offset: o, differ, apart };
  });
  assert(Math.abs(got.offset[0] - 30) <= 1 && Math.abs(got.offset[1] - 10) <= 1, `the drag moved the layer: ${JSON.stringify(got.offset)}`);
  assert(got.builds === got.clients, `one grid build per worker, at the drag's end: ${got.builds} builds for ${got.clients} workers`);
  assert(got.differ === 0, `the layer is torn where the cut lies over it now: ${got.differ} links differ`);
  assert(got.apart < 0.1, `the field shown after the drag is the one of the grid torn there: ${got.apart.toFixed(2)} px from the same scene opened afresh`);
});

test('a cut is not posed: a pose drag on it keys nothing and says why; Escape or a mode ends layer Move', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    await ui.openScene(await examples.builtinScene(256), 'cut.json');
    ui.setMode('pose');
    await app.idle();
  });
  // The slit runs from (154, 51) to (154, 205) on 256 px: drag its top end, then its line.
  const before = await page.evaluate(() => JSON.stringify(window.inkwarp.store.doc));
  await drag(page, [154, 51], [180, 60], 6);
  await drag(page, [154, 128], [170, 128], 6);
  const after = await page.evaluate(() => ({
    doc: JSON.stringify(window.inkwarp.store.doc),
    message: document.querySelector('#message').textContent,
    selected: window.inkwarp.store.view.selection.feature,
    panel: document.querySelector('#feature')?.textContent ?? '',
  }));
  assert(after.doc === before, 'a pose drag on a cut changed the scene (a cut with keys does not load)');
  assert(/A cut is not posed/.test(after.panel) && !/Drag it in pose mode/.test(after.panel), `the cut's panel: ${after.panel}`);
  assert(after.selected === 'slit' && /slit is a cut: it moves nothing/.test(after.message), `the drag said ${after.message}`);
  const keyed = await page.evaluate(() => {
    try {
      window.inkwarp.state.setKey(window.inkwarp.store.doc, 'slit', 0.5, [[160, 51], [154, 205]]);
      return null;
    } catch (e) {
      return e.message;
    }
  });
  assert(/is a cut/.test(keyed ?? ''), `a key on a cut was made: ${keyed}`);
  // Layer Move stays on until ended: Escape ends it, and so does a mode or a tool.
  const moving = () => page.evaluate(() => [window.inkwarp.ui.layerMove, document.querySelector('#layer-move').textContent]);
  for (const end of ['Escape', 'r', 'e']) {
    await page.click('#layer-move');
    assert(JSON.stringify(await moving()) === '[true,"Moving…"]', `Move is on before ${end}`);
    await page.keyboard.press(end);
    assert(JSON.stringify(await moving()) === '[false,"Move"]', `${end} left Move on: ${JSON.stringify(await moving())}`);
  }
  // Posed afterwards, a drag moves the feature, not the layer.
  await drag(page, [8, 8], [14, 10], 6);
  const state = await page.evaluate(() => ({ offset: window.inkwarp.store.doc.layers[0].offset ?? null, keys: window.inkwarp.store.doc.features[0].keys?.length ?? 0 }));
  assert(state.offset === null && state.keys === 1, `after Move ended, a pose drag: ${JSON.stringify(state)}`);
});


test('a drag stays one undo step through Ctrl+Z; Space keeps a line being drawn; Enter in a field keeps Tab for the fields', async () => {
  await page.evaluate(async () => {
    const { ui, examples, app } = window.inkwarp;
    await ui.openScene(await examples.builtinScene(256), 'undo.json');
    ui.setMode('pose');
    await app.idle();
  });
  const doc = () => page.evaluate(() => JSON.stringify(window.inkwarp.store.doc));
  const before = await doc();
  // Ctrl+Z in the middle of a pose drag waits for its end; the drag is then one step.
  const [x0, y0] = await toClient(page, [8, 8]);
  await page.mouse.move(x0, y0);
  await page.mouse.down();
  for (let i = 1; i <= 4; i++) await page.mouse.move(x0 + 3 * i, y0 + i);
  await page.keyboard.press('Control+z');
  const said = await page.evaluate(() => document.querySelector('#message').textContent);
  for (let i = 5; i <= 8; i++) await page.mouse.move(x0 + 3 * i, y0 + i);
  await page.mouse.up();
  assert(/wait for the drag to end/.test(said), `Ctrl+Z during a drag said: ${said}`);
  assert((await doc()) !== before, 'the drag keyed the feature');
  await page.keyboard.press('Control+z');
  assert((await doc()) === before, 'one Ctrl+Z after the drag undoes all of it');
  // Delete in the middle of a drag waits too (the release said "There is no feature ...").
  await page.mouse.move(x0, y0);
  await page.mouse.down();
  for (let i = 1; i <= 3; i++) await page.mouse.move(x0 + 3 * i, y0 + i);
  await page.keyboard.press('Delete');
  const saidDelete = await page.evaluate(() => document.querySelector('#message').textContent);
  await page.mouse.move(x0 + 12, y0 + 4);
  await page.mouse.up();
  const dragged = await page.evaluate(() => window.inkwarp.store.view.selection.feature);
  const kept = await page.evaluate((id) => window.inkwarp.store.doc.features.some((f) => f.id === id && f.keys?.length === 1), dragged);
  assert(/Deleting waits for the drag to end/.test(saidDelete) && kept, `Delete during a drag: ${saidDelete}, feature kept and keyed: ${kept}`);
  // A key time typed below 0 is refused as such (it said the feature had a key at 0 s).
  await page.fill('.key-time', '-1');
  await page.press('.key-time', 'Enter');
  const typed = await page.evaluate(() => ({ message: document.querySelector('#message').textContent, value: document.querySelector('.key-time').value }));
  assert(/A key's time is a number of seconds, 0 or more, not -1/.test(typed.message) && typed.value === '0.000', `a key time of -1: ${JSON.stringify(typed)}`);
  // A grid step refused shows the scene's step again.
  await page.fill('#grid-step', '0');
  await page.press('#grid-step', 'Enter');
  const step = await page.evaluate(() => ({ message: document.querySelector('#message').textContent, value: document.querySelector('#grid-step').value }));
  assert(/grid step is a whole number/.test(step.message) && step.value === '1', `a grid step of 0: ${JSON.stringify(step)}`);
  // Space while a spline is being drawn: the two points stay, and playback waits.
  await page.evaluate(() => { window.inkwarp.ui.setMode('rest'); window.inkwarp.ui.setTool('spline'); });
  for (const q of [[60, 60], [120, 80]]) {
    const [x, y] = await toClient(page, q);
    await page.mouse.click(x, y);
  }
  await page.keyboard.press('Space');
  const drawing = await page.evaluate(() => ({ draft: window.inkwarp.store.view.draft.length, playing: window.inkwarp.store.view.playing, message: document.querySelector('#message').textContent }));
  assert(drawing.draft === 2 && !drawing.playing && /Finish the line first/.test(drawing.message), `Space during a draft: ${JSON.stringify(drawing)}`);
  await page.keyboard.press('Escape');
  // Enter enters a field's value and leaves the focus there: Tab goes to the next field,
  // the mode stays.
  await page.fill('#layer-offset-x', '3');
  await page.press('#layer-offset-x', 'Enter');
  await page.keyboard.press('Tab');
  const after = await page.evaluate(() => ({ offset: window.inkwarp.store.doc.layers[0].offset, focus: document.activeElement?.id, mode: window.inkwarp.store.view.mode }));
  assert(JSON.stringify(after) === '{"offset":[3,0],"focus":"layer-offset-y","mode":"rest"}', `Enter then Tab in the offset: ${JSON.stringify(after)}`);
  for (const [id, value] of [['fps', '12'], ['duration', '3']]) {
    await page.fill(`#${id}`, value);
    await page.press(`#${id}`, 'Enter');
    await page.keyboard.press('Tab');
    const state = await page.evaluate(() => ({ focus: document.activeElement?.tagName, mode: window.inkwarp.store.view.mode }));
    assert(state.mode === 'rest' && state.focus !== 'BODY', `Enter then Tab in #${id}: ${JSON.stringify(state)}`);
  }
});

test('the frame ruler stays in view while many features\' rows scroll', async () => {
  const placed = await page.evaluate(async () => {
    const { ui, examples, store, state, app } = window.inkwarp;
    await ui.openScene(await examples.builtinScene(256), 'many.json');
    for (let k = 0; k < 24; k++) store.edit((d) => state.addFeature(d, 'point', [[10 + 9 * k, 30]], { id: `pin${k}` }).doc);
    await app.idle();
    const tracks = document.querySelector('#tracks');
    tracks.scrollTop = tracks.scrollHeight;
    await new Promise((r) => requestAnimationFrame(() => r()));
    const ruler = tracks.querySelector('.ruler-row').getBoundingClientRect();
    return { scrolled: tracks.scrollTop, top: tracks.getBoundingClientRect().top, ruler: ruler.top };
  });
  assert(placed.scrolled > 100 && Math.abs(placed.ruler - placed.top) < 1, `the ruler scrolled away: ${JSON.stringify(placed)}`);
});

test('a region is dragged by its fill: the whole region moves', async () => {
  await page.evaluate(async () => {
    const { ui, store, examples, state, app } = window.inkwarp;
    await ui.openScene(await examples.builtinScene(), 'region.json');
    store.edit((d) => state.addFeature(d, 'region', [[180, 180], [300, 180], [300, 300], [180, 300]], { id: 'blob' }).doc);
    ui.setMode('pose');
    ui.setTool('select');
    await app.idle();
  });
  await drag(page, [240, 240], [260, 250]);
  const key = await page.evaluate(() => window.inkwarp.store.doc.features.find((f) => f.id === 'blob').keys?.[0]?.points);
  const rest = [[180, 180], [300, 180], [300, 300], [180, 300]];
  assert(key && key.every((q, i) => Math.abs(q[0] - rest[i][0] - 20) < 1.01 && Math.abs(q[1] - rest[i][1] - 10) < 1.01), `every point of the region moved by (20, 10): ${JSON.stringify(key)}`);
});

test('a layered PSD opens as `inkwarp new` reads it: a layer each, PSD order, names, visibility, opacity in alpha, blend modes noted', async () => {
  const dir = scratchDir('inkwarp-psd-');
  const file = join(dir, 'figure.psd');
  const made = spawnSync(join(repo, '.venv/bin/python'), [join(here, 'make_psd.py'), file], { encoding: 'utf8' });
  assert(made.status === 0, `psd-tools wrote the PSD: ${made.stderr}`);
  await page.setInputFiles('input[type=file][accept^=".json"]', file);
  await page.waitForFunction(() => window.inkwarp.store.doc.layers.some((l) => l.name === 'arm'));
  await idle(page);
  const got = await page.evaluate(async () => {
    const { store, images, ui } = window.inkwarp;
    const doc = store.doc;
    const layers = [];
    for (const l of doc.layers) {
      const img = await images.decodeImage(l.image);
      const px = (x, y) => Array.from(img.data.subarray(4 * (y * img.width + x), 4 * (y * img.width + x) + 4));
      layers.push({ name: l.name, visible: l.visible !== false, offset: l.offset ?? [0, 0], size: [img.width, img.height], inside: px(12, 7), outside: px(1, 1) });
    }
    return { size: [doc.width, doc.height], background: doc.background, layers, notes: ui.psdNotes, message: document.querySelector('#message').textContent };
  });
  assert(JSON.stringify(got.size) === '[32,24]', `the scene is the PSD's size: ${got.size}`);
  assert(got.background[3] === 0, `the background is transparent: ${got.background}`);
  assert(JSON.stringify(got.layers.map((l) => l.name)) === '["sky","arm","notes"]', `a layer per pixel layer, bottom first, group flattened: ${got.layers.map((l) => l.name)}`);
  assert(JSON.stringify(got.layers.map((l) => l.visible)) === '[true,true,false]', `visibility kept: ${got.layers.map((l) => l.visible)}`);
  assert(got.layers.every((l) => l.size[0] === 32 && l.size[1] === 24 && l.offset[0] === 0 && l.offset[1] === 0), 'every layer is canvas-sized at [0, 0]');
  const [sky, arm, notes] = got.layers;
  assert(JSON.stringify(sky.inside) === '[20,40,200,255]' && JSON.stringify(sky.outside) === '[20,40,200,255]', `sky: ${sky.inside} ${sky.outside}`);
  assert(arm.inside[0] > 210 && arm.inside[1] < 40 && Math.abs(arm.inside[3] - 128) <= 1, `the arm is red at the group's 50 % opacity: ${arm.inside}`);
  assert(arm.outside[3] === 0, `the arm is transparent outside its box: ${arm.outside}`);
  assert(notes.inside[1] === 200 && notes.inside[3] === 255, `the hidden layer keeps its pixels: ${notes.inside}`);
  assert(got.notes.some((n) => /figure\.psd/.test(n) && /'figure \/ arm'/.test(n) && /Multiply/.test(n)), `the Multiply layer is named in a warning: ${got.notes}`);
  assert(/figure \/ arm/.test(got.message) && /Multiply/.test(got.message), `the page says so: ${got.message}`);
  await screenshot(page, 'psd-open');
  await page.click('#message');
});

test('transparent pixels show as a checkerboard inside the frame, apart from the stage around it', async () => {
  // The PSD's scene is open: hide its opaque sky so only the half-transparent arm is drawn.
  await page.evaluate(() => window.inkwarp.store.setView({ hidden: ['sky'] }));
  await idle(page);
  await screenshot(page, 'transparent');
  const box = await page.locator('.frame').boundingBox();
  const shot = join(results, 'transparent-frame.png');
  await page.screenshot({ path: shot, clip: { x: box.x, y: box.y, width: Math.min(96, box.width), height: Math.min(64, box.height) } });
  const img = await loadPng(page, shot);
  const tones = new Map();
  for (let i = 0; i < img.width * img.height; i++) {
    const [r, g, b] = img.data.subarray(4 * i, 4 * i + 3);
    const k = `${r},${g},${b}`;
    tones.set(k, (tones.get(k) ?? 0) + 1);
  }
  const common = [...tones.entries()].sort((a, b) => b[1] - a[1]).slice(0, 2).map(([k]) => k.split(',').map(Number));
  assert(common.length === 2 && common.every((c) => c[0] === c[1] && c[1] === c[2] && c[0] >= 180), `two light greys: ${JSON.stringify(common)}`);
  assert(Math.abs(common[0][0] - common[1][0]) >= 20, `they differ, a checkerboard: ${JSON.stringify(common)}`);
  assert(!common.some((c) => c[0] === 255), 'not white');
  await page.evaluate(() => window.inkwarp.store.setView({ hidden: [] }));
});

test('the matte overlay follows the picture in pose mode (at rest in rest mode)', async () => {
  // The PSD's scene: the arm layer's matte is its alpha, a hole around an 8×6 box at (10, 5).
  await page.evaluate(async () => {
    const { ui, store, state } = window.inkwarp;
    store.setView({ activeLayer: store.doc.layers.findIndex((l) => l.name === 'arm') });
    store.edit((d) => state.addFeature(d, 'point', [[14, 8]], { id: 'grip' }).doc);
    ui.setMode('pose');
    ui.setTool('select');
  });
  await idle(page);
  await drag(page, [14, 8], [20, 8]);
  const sample = async () => {
    const m = await matteMarks(page);
    const out = {};
    for (const x of [3, 10, 12, 14, 17, 20, 23, 27, 30]) out[x] = marked(m, x, 8);
    return { out, mode: m.mode };
  };
  // The posed overlay follows the layer's field, which the full-resolution worker may still
  // be solving on a loaded machine: sample until it arrives (at most about 5 s).
  let posed = await sample();
  for (let i = 0; i < 20 && !posed.out[10]; i++) {
    await new Promise((r) => setTimeout(r, 250));
    posed = await sample();
  }
  const d = await page.evaluate(() => {
    const k = window.inkwarp.store.doc.features.find((f) => f.id === 'grip').keys?.[0]?.points?.[0];
    return k ? k[0] - 14 : null;
  });
  assert(d !== null && Math.abs(d - 6) < 1.01, `the drag set a key 6 px right: ${d}`);
  await screenshot(page, 'matte-posed');
  await page.evaluate(() => window.inkwarp.ui.setMode('rest'));
  const rest = await sample();
  // At rest the arm's box (x 10–17) is no hole; posed, the field carries it 6 px right, and
  // where it was is a hole (the field is solved on connected pixels only).
  assert(!rest.out[10] && !rest.out[14] && !rest.out[17] && rest.out[20] && rest.out[3], `rest: ${JSON.stringify(rest.out)}`);
  assert(posed.out[10] && posed.out[12] && !posed.out[17] && !posed.out[20] && !posed.out[23] && posed.out[27] && posed.out[3], `posed: ${JSON.stringify(posed.out)}`);
  await overlayOff(page);
});

test('a marquee on empty stage picks the control points inside (Shift adds); picked points move together, at rest and posed', async () => {
  await page.evaluate(async () => {
    const { ui, store, examples, state, app } = window.inkwarp;
    await ui.openScene(await examples.builtinScene(), 'marquee.json');
    store.edit((d) => ({ ...d, features: [] }));
    store.edit((d) => state.addFeature(d, 'polyline', [[100, 100], [150, 100], [200, 100]], { id: 'bar' }).doc);
    store.edit((d) => state.addFeature(d, 'point', [[300, 300]], { id: 'pin' }).doc);
    ui.setMode('rest');
    ui.setTool('select');
    await app.idle();
  });
  const picked = () => page.evaluate(() => window.inkwarp.store.view.pointSelection.map((r) => `${r.feature}/${r.point}`).sort().join(' '));
  await drag(page, [80, 70], [170, 130]);
  assert((await picked()) === 'bar/0 bar/1', `the marquee picked the two points inside: ${await picked()}`);
  await page.keyboard.down('Shift');
  await drag(page, [280, 280], [320, 320]);
  await page.keyboard.up('Shift');
  assert((await picked()) === 'bar/0 bar/1 pin/0', `Shift added the pin: ${await picked()}`);
  await screenshot(page, 'marquee');
  await drag(page, [150, 100], [160, 105]);
  const rest = await page.evaluate(() => Object.fromEntries(window.inkwarp.store.doc.features.map((f) => [f.id, f.rest])));
  const near = (a, b) => a.every((q, i) => Math.abs(q[0] - b[i][0]) < 1.01 && Math.abs(q[1] - b[i][1]) < 1.01);
  assert(near(rest.bar, [[110, 105], [160, 105], [200, 100]]) && near(rest.pin, [[310, 305]]), `the picked points moved together, the third stayed: ${JSON.stringify(rest)}`);
  // A marquee over nothing picks nothing; in pose mode the drag sets a key on each feature.
  await drag(page, [400, 40], [440, 60]);
  assert((await picked()) === '', `an empty marquee: ${await picked()}`);
  await page.evaluate(() => window.inkwarp.ui.setMode('pose'));
  await drag(page, [90, 60], [220, 140]);
  assert((await picked()) === 'bar/0 bar/1 bar/2', `posed marquee: ${await picked()}`);
  await drag(page, [200, 100], [200, 120]);
  const keys = await page.evaluate(() => Object.fromEntries(window.inkwarp.store.doc.features.map((f) => [f.id, f.keys?.map((k) => k.points) ?? null])));
  assert(keys.bar && near(keys.bar[0], [[110, 125], [160, 125], [200, 120]]) && keys.pin === null, `a key on the bar only, every point 20 px down: ${JSON.stringify(keys)}`);
  await page.evaluate(() => window.inkwarp.ui.setMode('rest'));
});

test('a feature selected shows its timeline row, wherever the rows are scrolled', async () => {
  const { page: p, context, errors: errs } = await openEditor(browser, server.url);
  try {
    // More rows than the timeline shows; the last one traced, then the first selected.
    await p.evaluate(() => window.inkwarp.store.edit((d) => ({ ...d, features: [...d.features,
      ...Array.from({ length: 14 }, (_, i) => ({ id: `spot${i}`, kind: 'point', rest: [[20 + 10 * i, 40]] }))] })));
    const shown = (id) => p.evaluate((id) => {
      const box = document.querySelector('#tracks').getBoundingClientRect();
      const row = [...document.querySelectorAll('#tracks .track-row')].find((r) => r.textContent.startsWith(id));
      const b = row.getBoundingClientRect();
      return b.top >= box.top - 1 && b.bottom <= box.bottom + 1;
    }, id);
    for (const id of ['spot13', 'pin1', 'spot7']) {
      await p.evaluate((id) => window.inkwarp.store.setView({ selection: { feature: id, point: null } }), id);
      await p.waitForTimeout(100);
      assert(await shown(id), `${id}'s row is in view`);
    }
    assert(errs.length === 0, `page errors: ${errs.join('; ')}`);
  } finally {
    await context.close();
  }
});

test('a marquee on the timeline picks the keys inside it, on every row it crosses (Shift adds)', async () => {
  // The scene of the test before: the bar has a key at 0; give both features more.
  await page.evaluate(async () => {
    const { store, ui, app } = window.inkwarp;
    const keysAt = (f, ts) => ts.map((t, i) => ({ t, points: f.rest.map((q) => [q[0] + 5 * (i + 1), q[1]]) }));
    store.edit((d) => ({ ...d, features: d.features.map((f) => ({ ...f, keys: keysAt(f, f.id === 'bar' ? [0.5, 1.0] : [0.5, 1.5]) })) }));
    store.setView({ keySelection: [] });
    ui.setTime(0.25);
    await app.idle();
  });
  const picked = () => page.evaluate(() => window.inkwarp.store.view.keySelection.map((r) => `${r.feature}@${r.t}`).sort().join(' '));
  const rows = await page.evaluate(() => [...document.querySelectorAll('.tracks .track-row:not(.ruler-row) .track')].map((t) => {
    const b = t.getBoundingClientRect();
    return { left: b.left, width: b.width, top: b.top, bottom: b.bottom };
  }));
  assert(rows.length === 2, `two feature rows: ${rows.length}`);
  const x = (t) => rows[0].left + (t / 2) * rows[0].width;
  const press = async (a, b, shift = false) => {
    if (shift) await page.keyboard.down('Shift');
    await page.mouse.move(a[0], a[1]);
    await page.mouse.down();
    for (let i = 1; i <= 6; i++) await page.mouse.move(a[0] + ((b[0] - a[0]) * i) / 6, a[1] + ((b[1] - a[1]) * i) / 6);
    await page.mouse.up();
    if (shift) await page.keyboard.up('Shift');
  };
  await press([x(0.3), rows[0].top + 1], [x(1.2), rows[1].bottom - 1]);
  assert((await picked()) === 'bar@0.5 bar@1 pin@0.5', `the marquee picked the keys between 0.3 s and 1.2 s on both rows: ${await picked()}`);
  const t = await page.evaluate(() => window.inkwarp.store.view.time);
  assert(Math.abs(t - 0.25) < 1e-9, `a marquee leaves the time as it was: ${t}`);
  await press([x(1.3), rows[1].top + 1], [x(1.7), rows[1].bottom - 1], true);
  assert((await picked()) === 'bar@0.5 bar@1 pin@0.5 pin@1.5', `Shift added the pin's key at 1.5 s: ${await picked()}`);
  await screenshot(page, 'keys-marquee');
  await press([x(1.3), rows[0].top + 1], [x(1.45), rows[0].bottom - 1]);
  assert((await picked()) === '', `a marquee over no key picks none: ${await picked()}`);
  // A click on a track still sets the time.
  await page.mouse.click(x(0.75), (rows[0].top + rows[0].bottom) / 2);
  const t2 = await page.evaluate(() => window.inkwarp.store.view.time);
  assert(Math.abs(t2 - 0.75) < 0.03, `a click sets the time: ${t2}`);
});

async function main() {
  server = await startServer();
  browser = await chromium.launch({ executablePath: '/usr/bin/chromium', args: CHROMIUM_ARGS });
  ({ page, errors } = await openEditor(browser, server.url));
  let passed = 0, failed = 0;
  const t0 = Date.now();
  for (const t of tests) {
    if (only && !only.split('|').some((o) => t.name.includes(o))) continue;
    const start = Date.now();
    try {
      await t.fn();
      passed++;
      console.log(`PASS ${t.name} (${((Date.now() - start) / 1000).toFixed(1)} s)`);
    } catch (err) {
      failed++;
      console.log(`FAIL ${t.name}\n     ${err instanceof AssertionError ? err.message : err.stack}`);
      await page.screenshot({ path: join(results, `fail-${tests.indexOf(t)}.png`) }).catch(() => {});
    }
  }
  if (errors.length) {
    failed++;
    console.log(`FAIL the page logged errors:\n     ${errors.join('\n     ')}`);
  }
  await browser.close();
  server.proc.kill();
  writeFileSync(join(results, 'perf.json'), JSON.stringify(perf, null, 1));
  console.log('\nMeasured (reported, not asserted):');
  console.log(`  renderer: ${perf.renderer}`);
  if (perf.keyDrag) console.log(`  key drags: ${perf.keyDrag.map((k) => `${k.dx} px from ${k.from} s → ${k.to.toFixed(4)} s`).join('; ')}`);
  if (perf.border) console.log(`  border under a hard pull: free ${perf.border.freePx.toFixed(2)} px, held ${perf.border.heldPx.toFixed(3)} px`);
  if (perf.zoom) console.log(`  wheel zoom ${perf.zoom.from.toFixed(3)} → ${perf.zoom.to.toFixed(3)}: the point under the pointer moved ${perf.zoom.drift.toFixed(4)} scene px`);
  if (perf.readyPlayback) console.log(`  ready bar: ${perf.readyPlayback.readyBefore}/12 frames before playing; 2 s of play from solved frames: ${perf.readyPlayback.shown} shown, ${perf.readyPlayback.dropped} dropped of ${perf.readyPlayback.expected}`);
  if (perf.photo) console.log(`  4000×3000 photograph: open ${perf.photo.openS} s (proxy on screen at ${perf.photo.firstProxyFrameS?.toFixed(2)} s); drag frame median ${perf.photo.dragMedianMs?.toFixed(1)} ms (p90 ${perf.photo.dragP90Ms?.toFixed(1)}, n=${perf.photo.dragFrames}); settle ${perf.photo.settleS} s (a second drag's ${perf.photo.settle2S} s); page heap ${perf.photo.heapMiB?.toFixed(0)} MiB, browser RSS ${perf.photo.browserRssMiB.toFixed(0)} MiB dragging, ${perf.photo.browserRssSettledMiB.toFixed(0)} MiB settled, ${perf.photo.browserRssIdleMiB.toFixed(0)} MiB ${perf.photo.idleWaitS.toFixed(1)} s later (full-resolution worker replaced ${perf.photo.fullWorkerRenewals ?? 0} times; a zoom to 100 % then ${perf.photo.zoomAfterIdle?.ms.toFixed(0)} ms, solves ${JSON.stringify(perf.photo.zoomAfterIdle?.solves)}) (${perf.photo.browserRssBeforeMiB.toFixed(0)} before the photograph's page opened); the ${perf.photo.small.size} example opened in ${perf.photo.small.openS.toFixed(2)} s, browser RSS then ${perf.photo.small.browserRssMiB.toFixed(0)} MiB`);
  if (perf.webm) console.log(`  WebM export: ${perf.webm.frames} frames, ${perf.webm.duration} s`);
  if (perf.dragLatencyMs) {
    console.log(`  ${perf.features} features, 512×512: pointer move → frame median ${perf.dragLatencyMs.median?.toFixed(1)} ms (p90 ${perf.dragLatencyMs.p90?.toFixed(1)}, n=${perf.dragLatencyMs.n})`);
    console.log(`  settle (pointer rest → full-resolution frame): median ${perf.settleMs.median?.toFixed(1)} ms, max ${perf.settleMs.max?.toFixed(1)} ms`);
    for (const p of perf.settleParts ?? []) {
      const f = (v) => (typeof v === 'number' ? v.toFixed(1) : v);
      console.log(`    settle ${f(p.total)} ms = queued ${f(p.queued)} (behind ${p.behind ?? 'nothing'}) + to worker ${f(p.toWorker)} + solve ${f(p.solve)} (${p.cycles ?? '-'} cycles) + back ${f(p.back)} + upload ${f(p.upload)} + to frame ${f(p.toFrame)} + draw calls ${f(p.draw)} + GPU ${f(p.gpu)}; antialiased frame at ${f(p.antialiased)}`);
    }
    if (perf.slowDrag) {
      const f = (v) => (typeof v === 'number' ? v.toFixed(1) : v);
      for (const p of perf.slowDrag.parts) console.log(`  settle after a ${perf.slowDrag.seconds.toFixed(2)} s drag: ${f(p.total)} ms = queued ${f(p.queued)} (behind ${p.behind ?? 'nothing'}) + solve ${f(p.solve)} (${p.cycles ?? '-'} cycles${p.reused ? ', the followed field' : ''}) + GPU ${f(p.gpu)}`);
    }
    if (perf.aimedDrags) {
      const f = (v) => (typeof v === 'number' ? v.toFixed(1) : v);
      console.log(`  probes (pointer resting on a point): ${perf.aimedDrags.probes.map(f).join(', ')} ms`);
      for (const p of perf.aimedDrags.parts) console.log(`  settle after a quick drag aimed for ${AIM_MS} ms: ${f(p.total)} ms = queued ${f(p.queued)} (behind ${p.behind ?? 'nothing'}) + solve ${f(p.solve)} (${p.cycles ?? '-'} cycles${p.reused ? ', the followed field' : ''}) + GPU ${f(p.gpu)}`);
    }
    if (perf.dragParts) {
      const d = perf.dragParts;
      const f = (v) => (typeof v === 'number' ? v.toFixed(1) : v);
      console.log(`    drag frame medians: pointer → request sent ${f(d.queued)} + to worker ${f(d.toWorker)} + solve ${f(d.solve)} + drawn in the worker ${f(d.workerDraw)} + back ${f(d.back)} + upload ${f(d.upload)} + to frame ${f(d.toFrame)} + draw calls ${f(d.draw)} + GPU ${f(d.gpu)} (total ${f(d.total)})`);
    }
    console.log(`  solve: draft median ${perf.draftSolveMs.median?.toFixed(1)} ms, full median ${perf.finalSolveMs.median?.toFixed(1)} ms`);
    console.log(`  playback at 24 fps, 6 frames: first pass (solving) ${JSON.stringify(perf.playbackFirstPass)}; then 2 s from solved fields ${JSON.stringify(perf.playback)}`);
  }
  if (perf.glFrameMs) console.log(`  GPU frame (draw + read back): ${perf.glFrameMs.multisampled.toFixed(1)} ms with 4× multisampling, ${perf.glFrameMs.single.toFixed(1)} ms without, ${perf.glFrameMs.draft.toFixed(1)} ms draft (a vertex every 8 px where whole), ${perf.glFrameMs.draftAa.toFixed(1)} ms draft multisampled`);
  if (perf.fastVsFull) console.log(`  fast full frame: ${perf.fastVsFull.fastMs.toFixed(1)} ms (${perf.fastVsFull.triangles} triangles) against ${perf.fastVsFull.fullMs.toFixed(1)} ms (${perf.fastVsFull.fullTriangles}) single-sampled; mean ${perf.fastVsFull.mean.toFixed(3)}, p99 ${perf.fastVsFull.p99}, max ${perf.fastVsFull.max}`);
  if (perf.dragFrames) console.log(`  frames during the drags: ${perf.dragFrames.drawn} pictures drawn for ${perf.dragFrames.fields} fields, ${perf.dragFrames.overlayOnly} overlay-only frames`);
  if (perf.cpuVsGpuDraft) console.log(`  during a drag: the draft drawn by the CPU (${perf.cpuVsGpuDraft.cpuMs.toFixed(1)} ms, read back included) vs the same drawn by WebGL2: mean ${perf.cpuVsGpuDraft.mean.toFixed(3)}, p99 ${perf.cpuVsGpuDraft.p99}, max ${perf.cpuVsGpuDraft.max}`);
  if (perf.sparseVsDraft) console.log(`  during a drag: sparse draft vs the draft of the same pose solved at every pixel: mean ${perf.sparseVsDraft.mean.toFixed(3)}, p99 ${perf.sparseVsDraft.p99}, max ${perf.sparseVsDraft.max}`);
  if (perf.draftVsFull) console.log(`  during a drag: draft frame ${perf.draftVsFull.draftMs.toFixed(1)} ms, full frame of the same field ${perf.draftVsFull.fullMs.toFixed(1)} ms (draw + read back); draft vs full mean ${perf.draftVsFull.mean.toFixed(2)}, p99 ${perf.draftVsFull.p99}, max ${perf.draftVsFull.max}`);
  if (perf.gpuVsCpu) console.log(`  GPU vs CPU: mean ${perf.gpuVsCpu.mean.toFixed(3)}, p99 ${perf.gpuVsCpu.p99}, max ${perf.gpuVsCpu.max}`);
  if (perf.gpuVsCpuHole) console.log(`  GPU vs CPU around an opening hole (128×128): mean ${perf.gpuVsCpuHole.mean.toFixed(3)}, p99 ${perf.gpuVsCpuHole.p99}, max ${perf.gpuVsCpuHole.max}`);
  for (const ex of ['face', 'cat']) {
    const st = perf[`gpuVsCpu_${ex}`];
    if (st) console.log(`  GPU vs CPU, ${ex} example posed (moving up to ${perf[`posedPx_${ex}`]?.toFixed(1)} px): mean ${st.mean.toFixed(3)}, p99 ${st.p99}, max ${st.max}`);
    const dr = perf[`cpuVsGpuDraft_${ex}`];
    if (dr) console.log(`  draft drawn by the CPU vs by WebGL2, ${ex} example: mean ${dr.mean.toFixed(3)}, p99 ${dr.p99}, max ${dr.max}`);
  }
  if (perf.editorVsCli) console.log(`  editor vs inkwarp render: mean ${perf.editorVsCli.mean.toFixed(3)}, p99 ${perf.editorVsCli.p99}, max ${perf.editorVsCli.max}`);
  for (const [m, r] of Object.entries(perf.dragByMethod ?? {})) {
    console.log(`  drag under ${m}: pointer move → frame median ${r.dragLatencyMs.median?.toFixed(1)} ms (n=${r.dragLatencyMs.n}), settle ${r.settleMs?.toFixed(0)} ms; draft field ${r.draftSolveMs?.toFixed(1)} ms, full ${r.finalSolveMs?.toFixed(0)} ms`);
  }
  for (const [m, r] of Object.entries(perf.methods ?? {})) {
    console.log(`  method ${m}: full-resolution field ${r.fullSolveMs.toFixed(0)} ms; frame vs tps mean ${r.changedFromTps.toFixed(2)}; GPU vs CPU mean ${r.gpuVsCpu.mean.toFixed(3)}, p99 ${r.gpuVsCpu.p99}; editor vs inkwarp render mean ${r.editorVsCli.mean.toFixed(3)}, p99 ${r.editorVsCli.p99}`);
  }
  console.log(`\n${passed} passed, ${failed} failed  (${((Date.now() - t0) / 1000).toFixed(0)} s)`);
  process.exit(failed ? 1 : 0);
}

main().catch((err) => {
  console.error(err);
  try {
    server?.proc.kill();
  } catch {
    // already gone
  }
  process.exit(1);
});


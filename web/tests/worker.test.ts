// The solver worker's message path (`SolverWorker`, which `worker.ts` runs in a Web
// Worker), with the real engine: what the page is sent back for each kind of request.
import { beforeEach, describe, expect, it } from 'vitest';
import type { SolveFeature } from '../src/engine';
import { buildMesh, draftPixels, premultiply } from '../src/gl';
import type { DraftDraw, FromWorker, ToWorker } from '../src/protocol';
import type { Pt } from '../src/scene';
import { SolverWorker } from '../src/workercore';
import { loadEngine } from './wasm';

type Field = Extract<FromWorker, { type: 'field' }>;

let sent: FromWorker[];
let worker: SolverWorker;
let loads: number;

/** Sends `msg`, and returns what the worker sent back for it. */
async function send(msg: ToWorker): Promise<FromWorker[]> {
  const before = sent.length;
  await worker.handle(msg);
  return sent.slice(before);
}

async function field(msg: ToWorker): Promise<Field> {
  const out = await send(msg);
  expect(out.length).toBe(1);
  expect(out[0].type, JSON.stringify(out[0])).toBe('field');
  return out[0] as Field;
}

const W = 40;
const H = 32;
const pose = (x: number): SolveFeature[] => [
  { kind: 'spline', rest: [[5, 5], [20, 12], [35, 5]], pose: [[5, 5], [x, 14], [35, 5]] },
  { kind: 'point', rest: [[20, 28]], pose: [[20, 28]] },
];
const solve = (id: number, features: SolveFeature[], extra: Partial<Extract<ToWorker, { type: 'solve' }>> = {}): ToWorker => ({
  type: 'solve',
  id,
  key: 'L',
  features,
  options: { tolerance: 0.01 },
  warm: true,
  ...extra,
});

beforeEach(async () => {
  sent = [];
  loads = 0;
  worker = new SolverWorker(
    (msg) => sent.push(msg),
    async () => {
      loads++;
      return loadEngine();
    },
  );
  expect(await send({ type: 'init', wasmUrl: 'inkwarp.wasm' })).toEqual([{ type: 'ready' }]);
  const cuts: Pt[][] = [[[25.5, 10], [25.5, 31]]];
  const [links] = await send({ type: 'grid', key: 'L', width: W, height: H, matte: null, cuts });
  expect(links.type).toBe('links');
  if (links.type === 'links') {
    expect(links.links.length).toBe(W * H);
    expect(links.links[20 * W + 25] & 2).toBe(0); // the cut
  }
});

describe('the solver worker', () => {
  it('sends a full field, and the same field again without solving for the same request', async () => {
    const first = await field(solve(1, pose(24)));
    expect(first.id).toBe(1);
    expect(first.field?.dx.length).toBe(W * H);
    expect(first.report.converged).toBe(true);
    expect(first.reused).toBe(false);
    const again = await field(solve(2, pose(24)));
    expect(again.reused).toBe(true);
    expect(Array.from(again.field!.dx)).toEqual(Array.from(first.field!.dx));
    // A copy each time: the worker keeps its own as the next start.
    expect(again.field!.dx).not.toBe(first.field!.dx);
  });

  it('follows a pose without sending its field, then answers the settle on that pose with it', async () => {
    // On a grid with a cut too large to be solved whole (the small one's solves take one
    // cycle from any start), so that the starts' cycles can be compared.
    const [links] = await send({ type: 'grid', key: 'B', width: 4 * W, height: 4 * H, matte: null, cuts: [[[25.5, 10], [25.5, 127]]] });
    expect(links.type).toBe('links');
    const onB = { key: 'B' };
    await field(solve(1, pose(20), onB));
    const follow = await field(solve(2, pose(26), { follow: true, ...onB }));
    expect(follow.field).toBeNull();
    expect(follow.report.cycles).toBeGreaterThan(1);
    const settle = await field(solve(3, pose(26), { mesh: true, ...onB }));
    expect(settle.reused).toBe(true);
    expect(settle.field).not.toBeNull();
    // The fast full frame's triangles come with it when asked for.
    expect(settle.triangles!.length % 3).toBe(0);
    expect(settle.triangles!.length).toBeGreaterThan(0);
    // A later pose starts from the followed ones: fewer cycles than the follow took.
    const next = await field(solve(4, pose(28), onB));
    expect(next.reused).toBe(false);
    expect(next.report.cycles).toBeLessThan(follow.report.cycles!);
  });

  it('solves a sparse draft at the selected pixels only', async () => {
    const pixels = new Uint32Array([0, 5 * W + 5, 20 * W + 30, W * H - 1]);
    expect(await send({ type: 'select', key: 'L', pixels })).toEqual([]);
    const draft = await field(solve(1, pose(24), { sparse: true, options: { grid_step: 4 } }));
    expect(draft.field).toBeNull();
    expect(draft.sparse!.length).toBe(2 * pixels.length);
    expect(draft.gridStep).toBe(4);
  });

  it('draws the draft frame after a sparse draft, as the engine draws those values, and a frame from given values', async () => {
    const [links] = (await send({ type: 'grid', key: 'L', width: W, height: H, matte: null, cuts: [[[25.5, 10], [25.5, 31]]] })) as Extract<FromWorker, { type: 'links' }>[];
    const image = new Uint8Array(4 * W * H);
    for (let i = 0; i < W * H; i++) image.set([(i * 37) % 256, (i * 11) % 256, 90, i % 3 ? 255 : 140], 4 * i);
    const mesh = buildMesh(W, H, links.links, image);
    const pixels = draftPixels(W, H, mesh.coarse, mesh.skirts, mesh.innerSkirts);
    const index = new Uint32Array(W * H);
    pixels.forEach((p, k) => (index[p] = k));
    const geometry = { width: W, height: H, premultiplied: premultiply(image), coarse: mesh.coarse, skirts: mesh.skirts.slice(0, 6 * mesh.innerSkirts), links: mesh.links, index, reads: pixels.length };
    await send({ type: 'select', key: 'L', pixels });
    expect(await send({ type: 'draft-layer', key: 'L', geometry })).toEqual([]);
    const background: [number, number, number, number] = [20, 40, 60, 255];
    for (const shrink of [1, 2]) {
      const draw: DraftDraw = { width: W, height: H, background, shrink, layers: [{ key: 'L', offset: [1.5, -2], opacity: 0.8 }], seq: 7 + shrink, spec: `s${shrink}` };
      const draft = await field(solve(shrink, pose(24 + shrink), { sparse: true, options: { grid_step: 4 }, draw }));
      expect(draft.frame?.seqs).toEqual({ L: 7 + shrink });
      expect(draft.frame?.spec).toBe(`s${shrink}`);
      // What the page would have drawn from the same sparse draft.
      const engine = await loadEngine();
      const handle = engine.draftLayer(geometry);
      const out = new Uint8ClampedArray(4 * Math.ceil(W / shrink) * Math.ceil(H / shrink));
      engine.drawDraft(out, W, H, background, [{ draft: handle, values: draft.sparse!, offset: [1.5, -2], opacity: 0.8 }], shrink);
      expect(Array.from(draft.frame!.pixels)).toEqual(Array.from(out));
      // The same values given (a frame of the playback cache drawn ahead): the same pixels.
      const [drawn] = await send({ type: 'draw', id: 3, draw, values: { L: draft.sparse!.slice() } });
      expect(drawn.type).toBe('drawn');
      if (drawn.type === 'drawn') expect(Array.from(drawn.pixels!)).toEqual(Array.from(out));
    }
    // Values it cannot draw from (too few): the error, and still the answer the page waits for.
    const bad: DraftDraw = { width: W, height: H, background, shrink: 1, layers: [{ key: 'L', offset: [0, 0], opacity: 1 }], seq: 11, spec: '' };
    const failed = await send({ type: 'draw', id: 4, draw: bad, values: { L: new Float32Array(2) } });
    expect(failed.map((m) => m.type)).toEqual(['error', 'drawn']);
    expect(failed[1]).toEqual({ type: 'drawn', id: 4, pixels: null });
    // A layer the worker has no draft geometry for: no frame, the page draws it.
    const two: DraftDraw = { width: W, height: H, background, shrink: 1, layers: [{ key: 'L', offset: [0, 0], opacity: 1 }, { key: 'M', offset: [0, 0], opacity: 1 }], seq: 20, spec: '' };
    const lone = await field(solve(9, pose(22), { sparse: true, options: { grid_step: 4 }, draw: two }));
    expect(lone.frame).toBeUndefined();
    expect(lone.sparse!.length).toBe(2 * pixels.length);
    // A new grid forgets the layer's draft geometry.
    await send({ type: 'grid', key: 'L', width: W, height: H, matte: null, cuts: [] });
    await send({ type: 'select', key: 'L', pixels });
    const after = await field(solve(10, pose(23), { sparse: true, options: { grid_step: 4 }, draw: { ...two, layers: two.layers.slice(0, 1) } }));
    expect(after.frame).toBeUndefined();
  });

  it('answers a request it cannot solve with an error naming it, and goes on', async () => {
    const [bad] = await send(solve(7, [{ kind: 'polyline', rest: [[1, 1]], pose: [[1, 1]] }]));
    expect(bad).toMatchObject({ type: 'error', id: 7, key: 'L' });
    const [none] = await send({ ...solve(8, pose(24)), key: 'nobody' } as ToWorker);
    expect(none).toMatchObject({ type: 'error', id: 8, key: 'nobody', message: 'No grid for layer nobody.' });
    expect((await field(solve(9, pose(24)))).report.converged).toBe(true);
    // A dropped grid is gone.
    expect(await send({ type: 'drop', key: 'L' })).toEqual([]);
    const [gone] = await send(solve(10, pose(24)));
    expect(gone).toMatchObject({ type: 'error', id: 10, message: 'No grid for layer L.' });
    expect(loads).toBe(1);
  });
});

describe('full-resolution frames (a proxied scene)', () => {
  const image = () => {
    const data = new Uint8Array(4 * W * H);
    for (let i = 0; i < W * H; i++) data.set([(i * 37) % 256, (i * 11) % 256, 90, 255], 4 * i);
    return { width: W, height: H, data };
  };
  const render = (id: number, features: SolveFeature[] | null): ToWorker => ({
    type: 'full-render',
    id,
    width: W,
    height: H,
    background: [0, 0, 0, 255],
    layers: [{ key: 'P', features, options: { tolerance: 0.01, grid_step: 2, spacing_px: 2 }, offset: [0, 0] }],
  });

  it('draws the picture itself at rest, and the solved frame posed, as the engine renders it', async () => {
    const img = image();
    const cuts: Pt[][] = [[[25.5, 10], [25.5, 31]]];
    expect(await send({ type: 'full-layer', key: 'P', image: img, matte: new Uint8Array(W * H).fill(255), cuts })).toEqual([]);
    const [rest] = await send(render(1, null));
    expect(rest.type).toBe('full');
    if (rest.type !== 'full') return;
    expect(rest.id).toBe(1);
    expect(Array.from(rest.pixels)).toEqual(Array.from(img.data));
    const [posed] = await send(render(2, pose(26)));
    if (posed.type !== 'full') throw new Error(JSON.stringify(posed));
    expect(posed.cycles.length).toBe(1);
    // The same frame from the engine directly: a grid with the cut, a cold solve, the CPU renderer.
    const engine = await loadEngine();
    const grid = engine.grid(W, H, new Uint8Array(W * H).fill(255), cuts);
    const { field } = grid.solve(pose(26), { tolerance: 0.01, grid_step: 2, spacing_px: 2 }, null);
    const ref = engine.renderCpu(W, H, [0, 0, 0, 255], [{ image: img.data, grid, field, offset: [0, 0] }]);
    expect(Array.from(posed.pixels)).toEqual(Array.from(ref));
    expect(Array.from(posed.pixels)).not.toEqual(Array.from(img.data));
  });

  it('sends its layers back for a fresh worker, which draws the same frames from them', async () => {
    const img = image();
    const cuts: Pt[][] = [[[25.5, 10], [25.5, 31]]];
    const matte = new Uint8Array(W * H).fill(255);
    await send({ type: 'full-layer', key: 'P', image: img, matte, cuts });
    const [before] = await send(render(1, pose(26)));
    if (before.type !== 'full') throw new Error(JSON.stringify(before));
    const [out] = await send({ type: 'full-export' });
    if (out.type !== 'full-layers') throw new Error(JSON.stringify(out));
    expect(out.layers.map((l) => l.key)).toEqual(['P']);
    expect(Array.from(out.layers[0].image.data)).toEqual(Array.from(img.data));
    expect(out.layers[0].cuts).toEqual(cuts);
    // A fresh worker given them (its grid built as they arrive) draws the same frames.
    const got: FromWorker[] = [];
    const fresh = new SolverWorker((msg) => got.push(msg), loadEngine);
    await fresh.handle({ type: 'init', wasmUrl: 'inkwarp.wasm' });
    await fresh.handle({ type: 'full-layer', key: 'P', image: out.layers[0].image, matte: out.layers[0].matte, cuts, grid: true });
    await fresh.handle(render(2, pose(26)));
    await fresh.handle(render(3, null));
    const frames = got.filter((m) => m.type === 'full');
    expect(frames.length).toBe(2);
    expect(Array.from(frames[0].pixels)).toEqual(Array.from(before.pixels));
    expect(Array.from(frames[1].pixels)).toEqual(Array.from(img.data));
  });

  it('says which layer has no picture', async () => {
    const out = await send(render(3, null));
    expect(out[0].type).toBe('error');
    if (out[0].type === 'error') expect(out[0].message).toMatch(/layer P has no picture/);
  });
});

describe('pictures decoded in the worker (large ones, off the page)', () => {
  it('answers with the engine\'s own decoding, and with why when it cannot read the bytes', async () => {
    const { readFileSync } = await import('node:fs');
    const bytes = new Uint8Array(readFileSync(new URL('../../examples/face/eyes.png', import.meta.url)));
    const want = (await loadEngine()).decode(bytes);
    const [ok] = await send({ type: 'decode', id: 7, bytes: bytes.slice() });
    expect(ok.type).toBe('decoded');
    const got = ok as Extract<FromWorker, { type: 'decoded' }>;
    expect(got.id).toBe(7);
    expect(got.image && [got.image.width, got.image.height]).toEqual([want.width, want.height]);
    expect(got.image!.data).toEqual(want.data);
    const [bad] = await send({ type: 'decode', id: 8, bytes: new Uint8Array([1, 2, 3, 4]) });
    expect(bad.type).toBe('decoded');
    expect((bad as Extract<FromWorker, { type: 'decoded' }>).image).toBeNull();
    expect((bad as Extract<FromWorker, { type: 'decoded' }>).message).toBeTruthy();
  }, 30_000); // two engines compiled and a picture decoded: over the default 5 s on a busy 2-core machine
});

// Draft frames drawn by the CPU (the editor on a software GPU): the WebGL2 draft's
// triangles, every pixel centre inside one of them shaded once; and fast full frames (the
// triangles of `adaptiveTriangles`), held to the CPU reference renderer's full frame.
import { beforeAll, describe, expect, it } from 'vitest';
import type { DraftLayer, Engine } from '../src/engine';
import { adaptiveTriangles, buildMesh, draftPixels, premultiply } from '../src/gl';
import { loadEngine } from './wasm';

let engine: Engine;

beforeAll(async () => {
  engine = await loadEngine();
});

/** A `w × h` layer (a vertical cut at x = `cut` + ½ over rows 2..h−3, or none) of colours `rgba`, its sparse draft `field`. */
function layer(w: number, h: number, rgba: (x: number, y: number) => number[], field: (x: number, y: number) => [number, number], cut: number | null = null): DraftLayer {
  const links = new Uint8Array(w * h);
  for (let y = 0; y < h; y++) {
    for (let x = 0; x < w; x++) {
      const cutHere = cut !== null && x === cut && y >= 2 && y <= h - 3;
      links[y * w + x] = 1 | (x + 1 < w && !cutHere ? 2 : 0) | (y + 1 < h ? 4 : 0);
    }
  }
  const image = new Uint8Array(4 * w * h);
  for (let y = 0; y < h; y++) {
    for (let x = 0; x < w; x++) image.set(rgba(x, y), 4 * (y * w + x));
  }
  const premultiplied = premultiply(image);
  const mesh = buildMesh(w, h, links, image);
  const pixels = draftPixels(w, h, mesh.coarse, mesh.skirts, mesh.innerSkirts);
  const index = new Uint32Array(w * h);
  const values = new Float32Array(2 * pixels.length);
  pixels.forEach((p, k) => {
    index[p] = k;
    [values[2 * k], values[2 * k + 1]] = field(p % w, Math.floor(p / w));
  });
  const skirts = mesh.skirts.slice(0, 6 * mesh.innerSkirts);
  const draft = engine.draftLayer({ width: w, height: h, premultiplied, coarse: mesh.coarse, skirts, links: mesh.links, index, reads: pixels.length });
  return { draft, values, offset: [0, 0] };
}

const WHITE: [number, number, number, number] = [255, 255, 255, 255];

function draw(w: number, h: number, layers: DraftLayer[], background = WHITE): Uint8ClampedArray {
  const out = new Uint8ClampedArray(4 * w * h);
  engine.drawDraft(out, w, h, background, layers);
  return out;
}

const at = (out: Uint8ClampedArray, w: number, x: number, y: number) => Array.from(out.subarray(4 * (y * w + x), 4 * (y * w + x) + 4));

describe('draft frames drawn by the CPU', () => {
  it('reproduce an opaque layer under the identity field, pixel for pixel', () => {
    const w = 37, h = 29;
    const colour = (x: number, y: number) => [(x * 29) % 256, (y * 53) % 256, (x * y) % 256, 255];
    const L = layer(w, h, colour, () => [0, 0]);
    const out = draw(w, h, [L]);
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) expect(at(out, w, x, y)).toEqual(colour(x, y));
    L.draft.free();
  });

  it('drawn a whole number of times smaller: the mean of each block of the picture under the identity field, a translation moved by its share', () => {
    // 37 × 29 by 2: 19 × 15 pixels, the last column and row standing for one pixel of it.
    const w = 37, h = 29, k = 2;
    const colour = (x: number, y: number) => [(x * 29) % 256, (y * 53) % 256, (x * y) % 256, 255];
    const mean = (i: number, j: number) => {
      const sum = [0, 0, 0, 0];
      let n = 0;
      for (let y = k * j; y < Math.min(h, k * j + k); y++) {
        for (let x = k * i; x < Math.min(w, k * i + k); x++) {
          colour(x, y).forEach((c, q) => (sum[q] += c));
          n++;
        }
      }
      return sum.map((v) => Math.floor((v + Math.floor(n / 2)) / n));
    };
    const sw = Math.ceil(w / k), sh = Math.ceil(h / k);
    const still = layer(w, h, colour, () => [0, 0]);
    const out = new Uint8ClampedArray(4 * sw * sh);
    engine.drawDraft(out, w, h, WHITE, [still], k);
    for (let j = 0; j < sh; j++) for (let i = 0; i < sw; i++) expect(at(out, sw, i, j)).toEqual(mean(i, j));
    still.draft.free();
    // Moved by (4, 6) picture pixels: (2, 3) of the smaller frame's.
    const moved = layer(w, h, colour, () => [4, 6]);
    const big = 4 * (sw + 4) * (sh + 4);
    const out2 = new Uint8ClampedArray(big);
    engine.drawDraft(out2, w + 8, h + 8, WHITE, [moved], k);
    for (let j = 0; j < sh - 1; j++) for (let i = 0; i < sw - 1; i++) expect(at(out2, sw + 4, i + 2, j + 3)).toEqual(mean(i, j));
    expect(at(out2, sw + 4, 0, 0)).toEqual(WHITE);
    moved.draft.free();
  });

  it('drawn smaller, shade every pixel centre once across a bent field and a cut that opens', () => {
    const w = 64, h = 48, k = 3;
    const bend = (x: number, y: number): [number, number] => [3 * Math.sin(x / 9) + (x > 30 ? 6 : 0), 2 * Math.cos(y / 7) + (0.3 * x) / 10];
    const once = Math.round(255 - 128);
    const sw = Math.ceil((w + 8) / k), sh = Math.ceil((h + 8) / k);
    const L = layer(w, h, () => [255, 0, 0, 128], bend, 30);
    const out = new Uint8ClampedArray(4 * sw * sh);
    engine.drawDraft(out, w + 8, h + 8, WHITE, [L], k);
    let gap = 0;
    for (let y = 0; y < sh; y++) {
      for (let x = 0; x < sw; x++) {
        const g = out[4 * (y * sw + x) + 1];
        expect(g === 255 || Math.abs(g - once) <= 1, `(${x}, ${y}): green ${g}`).toBe(true);
        // The cut opens by about 6 pixels of the picture: 2 of the smaller frame.
        if (g === 255 && y > 4 && y < sh - 6 && x >= 10 && x <= 12) gap++;
      }
    }
    expect(gap).toBeGreaterThan(0);
    L.draft.free();
  });

  it('move the picture by a translation and by the layer offset', () => {
    const w = 40, h = 24;
    const colour = (x: number, y: number) => [(x * 29) % 256, (y * 53) % 256, 7, 255];
    const L = layer(w, h, colour, () => [5, 3]);
    const out = draw(50, 32, [{ ...L, offset: [2, 1] }]);
    for (let y = 4; y < h + 4; y++) for (let x = 7; x < w + 7; x++) expect(at(out, 50, x, y)).toEqual(colour(x - 7, y - 4));
    expect(at(out, 50, 0, 0)).toEqual(WHITE);
    expect(at(out, 50, 49, 31)).toEqual(WHITE);
    L.draft.free();
  });

  it('shade every pixel centre once, across a bent field and a cut that opens', () => {
    // A half-transparent red layer over white: a pixel shaded twice would come out redder.
    const w = 64, h = 48;
    const bend = (x: number, y: number): [number, number] => [3 * Math.sin(x / 9) + (x > 30 ? 2.5 : 0), 2 * Math.cos(y / 7) + (0.3 * x) / 10];
    const once = Math.round(255 - 128);
    for (const cut of [null, 30]) {
      const L = layer(w, h, () => [255, 0, 0, 128], bend, cut);
      const out = draw(w + 8, h + 8, [L]);
      let shaded = 0;
      let gap = 0;
      for (let y = 0; y < h + 8; y++) {
        for (let x = 0; x < w + 8; x++) {
          const g = out[4 * (y * (w + 8) + x) + 1];
          expect(g === 255 || Math.abs(g - once) <= 1, `(${x}, ${y}): green ${g}`).toBe(true);
          if (g !== 255) shaded++;
          // Across the cut (between columns 30 and 31, which the field moves to about 29.4
          // and 32.6, each side's skirt covering half a pixel) the background shows.
          else if (y > 10 && y < h - 10 && x >= 30 && x <= 32) gap++;
        }
      }
      expect(shaded).toBeGreaterThan(0.9 * w * h);
      expect(gap > 0).toBe(cut !== null);
      L.draft.free();
    }
  });

  it('composite layers back to front with their opacity, in 8 bits as a GPU target does', () => {
    const w = 16, h = 16;
    const red = layer(w, h, () => [255, 0, 0, 255], () => [0, 0]);
    const blue = layer(w, h, () => [0, 0, 255, 255], () => [0, 0]);
    const [r, g, b, a] = at(draw(w, h, [red, { ...blue, opacity: 0.5 }]), w, 8, 8);
    expect([Math.abs(r - 127.5) <= 1, g, Math.abs(b - 127.5) <= 1, a]).toEqual([true, 0, true, 255]);
    // A transparent background stays transparent around the layer, and straight inside it.
    const out = draw(w + 4, h, [{ ...red, offset: [4, 0] }], [0, 0, 0, 0]);
    expect(at(out, w + 4, 1, 5)).toEqual([0, 0, 0, 0]);
    expect(at(out, w + 4, 10, 5)).toEqual([255, 0, 0, 255]);
    red.draft.free();
    blue.draft.free();
  });

  it('take new triangles for a layer and draw with them, keeping the rest of it', () => {
    const w = 16, h = 12;
    const colour = (x: number, y: number) => [(x * 29) % 256, (y * 53) % 256, 90, 255];
    const L = layer(w, h, colour, () => [0, 0]);
    const before = draw(w, h, [L]);
    // The same layer's mesh (every pixel linked, as `layer` builds it without a cut).
    const { coarse } = buildMesh(w, h, null, null);
    L.draft.setTriangles(new Uint32Array(0));
    expect(at(draw(w, h, [L]), w, 8, 6)).toEqual([255, 255, 255, 255]);
    L.draft.setTriangles(coarse);
    expect(draw(w, h, [L])).toEqual(before);
    expect(() => L.draft.setTriangles(new Uint32Array([0, 1, w * h]))).toThrow(new RegExp(`pixel ${w * h} of a ${w}×${h} layer`));
    expect(() => L.draft.setTriangles(new Uint32Array([0, 1]))).toThrow(/whole triangles/);
    L.draft.free();
  });

  it('draw nothing of a layer with no pixel drawn, and the other layers as ever', () => {
    const w = 12, h = 10;
    const empty = new Uint8Array(4 * w * h);
    const mesh = buildMesh(w, h, new Uint8Array(w * h), empty);
    const pixels = draftPixels(w, h, mesh.coarse, mesh.skirts, mesh.innerSkirts);
    expect(pixels.length).toBe(0);
    const none = engine.draftLayer({ width: w, height: h, premultiplied: empty, coarse: mesh.coarse, skirts: mesh.skirts.slice(0, 6 * mesh.innerSkirts), links: mesh.links, index: new Uint32Array(w * h), reads: 0 });
    const red = layer(w, h, () => [255, 0, 0, 255], () => [0, 0]);
    const out = draw(w, h, [{ draft: none, values: new Float32Array(0), offset: [0, 0] }, red]);
    expect(at(out, w, 5, 5)).toEqual([255, 0, 0, 255]);
    none.free();
    red.draft.free();
  });

  it('refuse a sparse draft too short for the layer, and meshes off the layer or off its draft', () => {
    const L = layer(8, 8, () => [0, 0, 0, 255], () => [0, 0]);
    expect(() => engine.drawDraft(new Uint8ClampedArray(256), 8, 8, WHITE, [{ ...L, values: L.values.subarray(0, 4) }])).toThrow(/sparse draft of 4 values/);
    const geometry = { width: 8, height: 8, premultiplied: new Uint8Array(256), coarse: new Uint32Array(0), skirts: new Float32Array(0), links: new Uint8Array(64), index: new Uint32Array(64), reads: 1 };
    expect(() => engine.draftLayer({ ...geometry, coarse: new Uint32Array([0, 1, 99]) })).toThrow(/pixel 99 of a 8×8 layer/);
    expect(() => engine.draftLayer({ ...geometry, skirts: new Float32Array(36).fill(9) })).toThrow(/skirt quarter at \(9, 9\) is off the 8×8 layer/);
    expect(() => engine.draftLayer({ ...geometry, coarse: new Uint32Array([0, 1, 8]), index: new Uint32Array(64).fill(3), reads: 2 })).toThrow(/Pixel 0 of the draft mesh has no place among the 2 pixels/);
    L.draft.free();
  });
});

describe('fast full frames drawn by the CPU', () => {
  /**
   * A layer of `w × h` (a vertical cut between columns 30 and 31 over rows 2..h−3) under
   * `field`, drawn as the editor draws a fast full frame on a software GPU, and by the
   * core's reference renderer.
   */
  function both(w: number, h: number, colour: (x: number, y: number) => number[], field: (x: number, y: number) => [number, number]) {
    const grid = engine.grid(w, h, null, [[[30.5, 1.5], [30.5, h - 2.5]]]);
    const links = grid.links();
    const image = new Uint8Array(4 * w * h);
    const dx = new Float32Array(w * h);
    const dy = new Float32Array(w * h);
    const pairs = new Float32Array(2 * w * h);
    const index = new Uint32Array(w * h);
    for (let y = 0; y < h; y++) {
      for (let x = 0; x < w; x++) {
        const k = y * w + x;
        const c = colour(x, y);
        image.set(c, 4 * k);
        [dx[k], dy[k]] = field(x, y);
        [pairs[2 * k], pairs[2 * k + 1]] = [dx[k], dy[k]];
        index[k] = k;
      }
    }
    const premultiplied = premultiply(image);
    const f = { width: w, height: h, dx, dy };
    const mesh = buildMesh(w, h, links, image);
    const coarse = adaptiveTriangles(w, h, mesh.links, f);
    const draft = engine.draftLayer({ width: w, height: h, premultiplied, coarse, skirts: mesh.skirts, links: mesh.links, index, reads: w * h, pushBorder: false });
    const fast = draw(w, h, [{ draft, values: pairs, offset: [0, 0] }]);
    const every = engine.draftLayer({ width: w, height: h, premultiplied, coarse: mesh.quads, skirts: mesh.skirts, links: mesh.links, index, reads: w * h, pushBorder: false });
    const full = draw(w, h, [{ draft: every, values: pairs, offset: [0, 0] }]);
    every.free();
    const reference = engine.renderCpu(w, h, WHITE, [{ image, grid, field: f, offset: [0, 0] }]);
    draft.free();
    grid.free();
    return { fast, full, reference, triangles: coarse.length / 3 };
  }

  it('reproduce the layer under the identity field, border pixels included', () => {
    const w = 64, h = 48;
    const colour = (x: number, y: number) => [(x * 29) % 256, (y * 53) % 256, (x * y) % 256, 255];
    const { fast, triangles } = both(w, h, colour, () => [0, 0]);
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) expect(at(fast, w, x, y)).toEqual(colour(x, y));
    // Whole blocks are single elements: far fewer triangles than two a pixel quad.
    expect(triangles).toBeLessThan((w - 1) * (h - 1));
  });

  it('match the full mesh, and the reference renderer away from the edges, across a bent field and a cut', () => {
    const w = 64, h = 48;
    const colour = (x: number, y: number) => [128 + 100 * Math.sin(x / 5), 128 + 100 * Math.cos(y / 4), (x * 3) % 256, 255];
    // Gentle enough that most blocks are single elements, steep enough that some are not.
    const bend = (x: number, y: number): [number, number] => [0.8 * Math.sin(x / 12) + (x > 30 ? 2.5 : 0), 0.6 * Math.cos(y / 10) + 0.03 * x];
    const { fast, full, reference, triangles } = both(w, h, colour, bend);
    expect(triangles).toBeLessThan((w - 1) * (h - 1));
    const stats = (a: Uint8ClampedArray | Uint8Array, b: Uint8ClampedArray | Uint8Array, keep: (x: number, y: number) => boolean) => {
      const d: number[] = [];
      for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) if (keep(x, y)) for (let c = 0; c < 3; c++) d.push(Math.abs(a[4 * (y * w + x) + c] - b[4 * (y * w + x) + c]));
      d.sort((p, q) => p - q);
      return { mean: d.reduce((p, q) => p + q, 0) / d.length, p99: d[Math.floor(0.99 * d.length)] };
    };
    // The same rasteriser over every pixel quad: only the elements' approximation of the
    // field (within ADAPTIVE_TOLERANCE) tells them apart.
    const mesh = stats(fast, full, () => true);
    expect(mesh.mean).toBeLessThan(0.5);
    expect(mesh.p99).toBeLessThanOrEqual(4);
    // The reference renderer covers pixels by area where these sample their centres, which
    // differs along the border and the cut's sides (moved to about x = 33 by the field).
    const inside = stats(fast, reference, (x, y) => x > 4 && y > 4 && x < w - 5 && y < h - 5 && Math.abs(x - 33) > 4);
    expect(inside.mean).toBeLessThan(1);
    expect(inside.p99).toBeLessThanOrEqual(4);
  });
});

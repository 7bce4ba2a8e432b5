// The GPU mesh tiles the layer as the CPU renderer's does: whole quads where all four
// links exist, skirt quarters elsewhere, so every drawn pixel's unit square is covered once.
import { describe, expect, it } from 'vitest';
import { ADAPTIVE_TOLERANCE, adaptiveTriangles, buildMesh, draftPixels, draftQuads, FAN_BLOCK, sparseValuesAt } from '../src/gl';
import { packField } from '../src/proxy';

/** Rest-space area covered by a mesh: quads from their index rectangles, quarters ¼ each. */
function area(w: number, quads: Uint32Array, skirts: Float32Array): number {
  let a = 0;
  for (let q = 0; q < quads.length; q += 6) {
    const ks = Array.from(quads.subarray(q, q + 6));
    const xs = ks.map((k) => k % w);
    const ys = ks.map((k) => Math.floor(k / w));
    a += (Math.max(...xs) - Math.min(...xs)) * (Math.max(...ys) - Math.min(...ys));
  }
  return a + skirts.length / 6 / 6 / 4;
}

function links(w: number, h: number, active: (x: number, y: number) => boolean, cut = (_x: number, _y: number, _d: 'r' | 'd') => false): Uint8Array {
  const l = new Uint8Array(w * h);
  for (let y = 0; y < h; y++) {
    for (let x = 0; x < w; x++) {
      if (!active(x, y)) continue;
      let v = 1;
      if (x + 1 < w && active(x + 1, y) && !cut(x, y, 'r')) v |= 2;
      if (y + 1 < h && active(x, y + 1) && !cut(x, y, 'd')) v |= 4;
      l[y * w + x] = v;
    }
  }
  return l;
}

describe('the GPU mesh', () => {
  it('an open grid: whole quads inside, border quarters outside, area W×H', () => {
    const m = buildMesh(5, 4, null, null);
    expect(m.quads.length / 6).toBe(4 * 3);
    expect(m.skirts.length / 36).toBe(32); // corners 3 quarters each, other border pixels 2
    expect(area(5, m.quads, m.skirts)).toBe(20);
  });

  it('a cut keeps every pixel covered, the two sides meeting only at skirts', () => {
    const w = 8, h = 6;
    const l = links(w, h, () => true, (x, _y, d) => d === 'r' && x === 3);
    const m = buildMesh(w, h, l, null);
    expect(area(w, m.quads, m.skirts)).toBe(w * h);
    // No quad spans the cut.
    for (let q = 0; q < m.quads.length; q += 6) {
      const xs = Array.from(m.quads.subarray(q, q + 6)).map((k) => k % w);
      expect(Math.min(...xs) <= 3 && Math.max(...xs) >= 4).toBe(false);
    }
  });

  it('a transparent hole is not drawn; an inactive but visible pixel is a lone square', () => {
    const w = 7, h = 7;
    const hole = (x: number, y: number) => !(x === 3 && y === 3);
    const transparent = new Uint8Array(4 * w * h).fill(255);
    transparent[4 * (3 * w + 3) + 3] = 0;
    expect(area(w, buildMesh(w, h, links(w, h, hole), transparent).quads, buildMesh(w, h, links(w, h, hole), transparent).skirts)).toBe(w * h - 1);
    const opaque = new Uint8Array(4 * w * h).fill(255);
    const m = buildMesh(w, h, links(w, h, hole), opaque);
    expect(area(w, m.quads, m.skirts)).toBe(w * h);
  });

  it('the draft mesh covers exactly what the whole quads cover, without T-junctions', () => {
    const w = 33, h = 25;
    const l = links(w, h, (x, y) => !(x === 5 && y === 2), (x, y, d) => d === 'd' && y === 4 && x < 3);
    const m = buildMesh(w, h, l, null);
    expect(coverTri(w, h, m.coarse)).toEqual(wholeQuads(w, h, l));
    expect(tJunctions(w, m.coarse)).toBe(0);
    expect(m.coarse.length).toBeLessThan(0.6 * m.quads.length);
  });

  it('the draft mesh of an open grid is one quad per block, clipped at the edges', () => {
    const w = 21, h = 17; // 20 × 16 pixel quads: blocks of 8, 8 and 4 across, 8 and 8 down
    const q = draftQuads(w, h, buildMesh(w, h, null, null).links, 8);
    expect(q.length / 6).toBe(3 * 2);
    expect(cover(w, h, q)).toEqual(wholeQuads(w, h, buildMesh(w, h, null, null).links));
  });
});

/** How many times the quads of `indices` cover each pixel quad (their rest rectangles). */
function cover(w: number, h: number, indices: Uint32Array): Uint8Array {
  const c = new Uint8Array((w - 1) * (h - 1));
  for (let q = 0; q < indices.length; q += 6) {
    const ks = Array.from(indices.subarray(q, q + 6));
    const xs = ks.map((k) => k % w);
    const ys = ks.map((k) => Math.floor(k / w));
    // The last index of each triangle is the quad's top-left pixel (the provoking vertex).
    expect([ks[2], ks[5]]).toEqual([Math.min(...ys) * w + Math.min(...xs), Math.min(...ys) * w + Math.min(...xs)]);
    for (let y = Math.min(...ys); y < Math.max(...ys); y++) for (let x = Math.min(...xs); x < Math.max(...xs); x++) c[y * (w - 1) + x]++;
  }
  return c;
}

/** 1 for each pixel quad whose four links exist. */
function wholeQuads(w: number, h: number, l: Uint8Array): Uint8Array {
  const c = new Uint8Array((w - 1) * (h - 1));
  for (let y = 0; y + 1 < h; y++) {
    for (let x = 0; x + 1 < w; x++) {
      const k = y * w + x;
      c[y * (w - 1) + x] = (l[k] & 6) === 6 && (l[k + w] & 2) !== 0 && (l[k + 1] & 4) !== 0 ? 1 : 0;
    }
  }
  return c;
}

describe('the draft mesh (a vertex every few pixels where the surface is whole)', () => {
  it('a cut removes exactly the pixel quads across it; blocks away from it stay whole', () => {
    const w = 33, h = 17;
    // A vertical cut between columns 10 and 11, rows 0..11.
    const l = links(w, h, () => true, (x, y, d) => d === 'r' && x === 10 && y < 12);
    const q = draftQuads(w, h, l, 8);
    expect(coverTri(w, h, q)).toEqual(wholeQuads(w, h, l));
    expect(tJunctions(w, q)).toBe(0);
    const tris = Array.from({ length: q.length / 3 }, (_, k) => Array.from(q.subarray(3 * k, 3 * k + 3)));
    // Nothing spans the cut where it runs…
    for (const t of tris) {
      const xs = t.map((v) => v % w), ys = t.map((v) => Math.floor(v / w));
      if (Math.min(...ys) < 12) expect(Math.min(...xs) <= 10 && Math.max(...xs) >= 11).toBe(false);
    }
    // A fan of the block at (x, y): a triangle from two pixels of its border to its centre.
    const fan = (x: number, y: number) =>
      tris.some((t) => {
        const [px, py] = [t[0] % w, Math.floor(t[0] / w)];
        return t[2] === (y + 4) * w + x + 4 && (px === x || px === x + 8 || py === y || py === y + 8);
      });
    const plain = (x: number, y: number) => tris.some((t) => t[0] === y * w + x + 8 && t[1] === (y + 8) * w + x + 8 && t[2] === y * w + x);
    // …the block it crosses is split into pixel quads, its neighbours fan out to meet them,
    // and the blocks further away are two triangles each.
    expect(fan(8, 0) || fan(8, 8) || plain(8, 0) || plain(8, 8)).toBe(false);
    for (const [x, y] of [[0, 0], [16, 0], [0, 8], [16, 8]]) expect(fan(x, y)).toBe(true);
    expect(plain(24, 0) && plain(24, 8)).toBe(true);
    expect(q.length).toBeLessThan(0.4 * buildMesh(w, h, l, null).quads.length);
  });

  it('a hole removes the pixel quads around it and nothing else', () => {
    const w = 17, h = 17;
    const l = links(w, h, (x, y) => !(x === 10 && y === 5));
    const q = draftQuads(w, h, l, 8);
    const c = coverTri(w, h, q);
    expect(c).toEqual(wholeQuads(w, h, l));
    expect(tJunctions(w, q)).toBe(0);
    for (const [x, y] of [[9, 4], [10, 4], [9, 5], [10, 5]]) expect(c[y * (w - 1) + x]).toBe(0);
    expect(c.reduce((a, b) => a + b, 0)).toBe(16 * 16 - 4);
  });

  it('random cuts and holes: every whole pixel quad covered once, every other never, no T-junction', () => {
    let seed = 7;
    const rand = () => ((seed = (seed * 1103515245 + 12345) % 2 ** 31) / 2 ** 31);
    for (let trial = 0; trial < 20; trial++) {
      const w = 5 + Math.floor(rand() * 40), h = 5 + Math.floor(rand() * 40);
      const holes = new Set(Array.from({ length: 1 + Math.floor(rand() * 6) }, () => `${Math.floor(rand() * w)},${Math.floor(rand() * h)}`));
      const cutX = Math.floor(rand() * w);
      const l = links(w, h, (x, y) => !holes.has(`${x},${y}`), (x, y, d) => d === 'r' && x === cutX && y < h / 2);
      for (const block of [1, 2, 4, 8, 16]) {
        const q = draftQuads(w, h, l, block);
        expect(coverTri(w, h, q)).toEqual(wholeQuads(w, h, l));
        expect(tJunctions(w, q)).toBe(0);
      }
    }
  });
});

describe('the pixels a draft reads (sparse drafts)', () => {
  it('every draft vertex and every inner skirt pixel with its neighbours, sorted, once each', () => {
    let seed = 11;
    const rand = () => ((seed = (seed * 1103515245 + 12345) % 2 ** 31) / 2 ** 31);
    for (let trial = 0; trial < 12; trial++) {
      const w = 5 + Math.floor(rand() * 60), h = 5 + Math.floor(rand() * 60);
      const holes = new Set(Array.from({ length: Math.floor(rand() * 6) }, () => `${Math.floor(rand() * w)},${Math.floor(rand() * h)}`));
      const cutX = Math.floor(rand() * w);
      const l = links(w, h, (x, y) => !holes.has(`${x},${y}`), (x, y, d) => d === 'r' && x === cutX && y < h / 2);
      const { coarse, skirts, innerSkirts } = buildMesh(w, h, l, null);
      const px = draftPixels(w, h, coarse, skirts, innerSkirts);
      const set = new Set(px);
      expect(set.size).toBe(px.length);
      for (let k = 1; k < px.length; k++) expect(px[k]).toBeGreaterThan(px[k - 1]);
      for (const v of coarse) expect(set.has(v)).toBe(true);
      // The skirt shader reads its pixel and the neighbours it is linked to.
      for (let k = 0; k < innerSkirts; k++) {
        const [x, y] = [skirts[6 * k], skirts[6 * k + 1]];
        for (const [dx, dy] of [[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1]]) {
          const [i, j] = [x + dx, y + dy];
          if (i >= 0 && j >= 0 && i < w && j < h) expect(set.has(j * w + i)).toBe(true);
        }
      }
    }
    // An open 512 × 512 layer: the corners of its 8 × 8 blocks, 1.6 % of the pixels.
    const open = buildMesh(512, 512, null, null);
    expect(draftPixels(512, 512, open.coarse, open.skirts, open.innerSkirts).length).toBe(65 * 65);
  }, 30_000); // thousands of expects: over the default 5 s on a busy 2-core machine
});

/**
 * How many triangles of `t` hold a point inside each pixel quad (one off every line a
 * triangle's edge can take: the quad's diagonals, a fan's spokes).
 */
function coverTri(w: number, h: number, t: Uint32Array): Uint8Array {
  const c = new Uint8Array((w - 1) * (h - 1));
  for (let q = 0; q < t.length; q += 3) {
    const p = [t[q], t[q + 1], t[q + 2]].map((k) => [k % w, Math.floor(k / w)]);
    const side = (a: number[], b: number[], x: number, y: number) => (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
    const xs = p.map((v) => v[0]), ys = p.map((v) => v[1]);
    for (let y = Math.min(...ys); y < Math.max(...ys); y++) {
      for (let x = Math.min(...xs); x < Math.max(...xs); x++) {
        const [sx, sy] = [x + 0.37, y + 0.61];
        const s = [side(p[0], p[1], sx, sy), side(p[1], p[2], sx, sy), side(p[2], p[0], sx, sy)];
        if (s.every((v) => v > 0) || s.every((v) => v < 0)) c[y * (w - 1) + x]++;
      }
    }
  }
  return c;
}

/** How many vertices of the mesh `t` lie inside an edge of one of its triangles. */
function tJunctions(w: number, t: Uint32Array): number {
  const used = new Set(t);
  let n = 0;
  for (let q = 0; q < t.length; q += 3) {
    for (const [u, v] of [[t[q], t[q + 1]], [t[q + 1], t[q + 2]], [t[q + 2], t[q]]]) {
      const [ax, ay, bx, by] = [u % w, Math.floor(u / w), v % w, Math.floor(v / w)];
      const m = Math.max(Math.abs(bx - ax), Math.abs(by - ay));
      for (let s = 1; s < m; s++) {
        const [x, y] = [ax + ((bx - ax) * s) / m, ay + ((by - ay) * s) / m];
        if (Number.isInteger(x) && Number.isInteger(y) && used.has(y * w + x)) n++;
      }
    }
  }
  return n;
}

describe('the fast full mesh (fans where the field is nearly affine)', () => {
  /** A field that bends sharply around one point and gently elsewhere. */
  function bent(w: number, h: number): { width: number; height: number; dx: Float32Array; dy: Float32Array } {
    const dx = new Float32Array(w * h), dy = new Float32Array(w * h);
    for (let k = 0; k < w * h; k++) {
      const [x, y] = [k % w, Math.floor(k / w)];
      const r2 = (x - 20) ** 2 + (y - 24) ** 2;
      [dx[k], dy[k]] = [6 * Math.exp(-r2 / 30) + 0.0005 * x * x, -3 * Math.exp(-r2 / 50) + 0.01 * y];
    }
    return { width: w, height: h, dx, dy };
  }
  const at = (w: number, k: number) => [k % w, Math.floor(k / w)];

  it('covers every whole pixel quad once, has no T-junction, and puts every pixel within the tolerance', () => {
    const w = 65, h = 49;
    const l = links(w, h, () => true, (x, y, d) => d === 'r' && x === 40 && y > 10 && y < 30);
    const field = bent(w, h);
    const t = adaptiveTriangles(w, h, l, field);
    // Area in rest space: one per whole pixel quad.
    let area = 0;
    const used = new Set<number>();
    for (let q = 0; q < t.length; q += 3) {
      const [a, b, c] = [at(w, t[q]), at(w, t[q + 1]), at(w, t[q + 2])];
      area += Math.abs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])) / 2;
      for (let k = 0; k < 3; k++) used.add(t[q + k]);
    }
    expect(area).toBe(wholeQuads(w, h, l).reduce((s, v) => s + v, 0));
    // No vertex lies inside another triangle's edge.
    for (let q = 0; q < t.length; q += 3) {
      for (const [u, v] of [[t[q], t[q + 1]], [t[q + 1], t[q + 2]], [t[q + 2], t[q]]]) {
        const [a, b] = [at(w, u), at(w, v)];
        const n = Math.max(Math.abs(b[0] - a[0]), Math.abs(b[1] - a[1]));
        for (let s = 1; s < n; s++) {
          const [x, y] = [a[0] + ((b[0] - a[0]) * s) / n, a[1] + ((b[1] - a[1]) * s) / n];
          if (Number.isInteger(x) && Number.isInteger(y)) expect(used.has(y * w + x)).toBe(false);
        }
      }
    }
    // Every pixel inside a triangle is placed within the tolerance of the field there.
    let worst = 0;
    for (let q = 0; q < t.length; q += 3) {
      const [a, b, c] = [at(w, t[q]), at(w, t[q + 1]), at(w, t[q + 2])];
      const det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
      for (let y = Math.min(a[1], b[1], c[1]); y <= Math.max(a[1], b[1], c[1]); y++) {
        for (let x = Math.min(a[0], b[0], c[0]); x <= Math.max(a[0], b[0], c[0]); x++) {
          const lb = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (y - a[1])) / det;
          const lc = ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
          if (lb < -1e-9 || lc < -1e-9 || lb + lc > 1 + 1e-9) continue;
          for (const f of [field.dx, field.dy]) {
            const v = (1 - lb - lc) * f[t[q]] + lb * f[t[q + 1]] + lc * f[t[q + 2]];
            worst = Math.max(worst, Math.abs(v - f[y * w + x]));
          }
        }
      }
    }
    expect(worst).toBeLessThanOrEqual(ADAPTIVE_TOLERANCE + 1e-6);
    // Fans where the field is smooth, pixel quads around the bend and the cut.
    const full = buildMesh(w, h, l, null).quads.length / 3;
    expect(t.length / 3).toBeLessThan(0.5 * full);
    expect(t.length / 3).toBeGreaterThan((full * 32) / 128);
  });

  it('an affine field is the draft mesh', () => {
    const w = 21, h = 17;
    const dx = new Float32Array(w * h), dy = new Float32Array(w * h);
    for (let k = 0; k < w * h; k++) [dx[k], dy[k]] = [0.3 * (k % w) - 2, 0.1 * Math.floor(k / w) + 0.05 * (k % w)];
    const l = buildMesh(w, h, null, null).links;
    expect(adaptiveTriangles(w, h, l, { width: w, height: h, dx, dy })).toEqual(draftQuads(w, h, l, FAN_BLOCK));
  });
});

describe('a played frame read at the draft mesh pixels', () => {
  it('takes each pixel of a field, floats or packed for playback, in the draft pixels order', () => {
    const w = 5, h = 3, n = w * h;
    const dx = Float32Array.from({ length: n }, (_, i) => i / 4 - 1);
    const dy = Float32Array.from({ length: n }, (_, i) => 0.5 - i / 8);
    const pixels = new Uint32Array([7, 0, 14, 3]);
    const want = Array.from(pixels).flatMap((i) => [dx[i], dy[i]]);
    expect(Array.from(sparseValuesAt(pixels, { width: w, height: h, dx, dy }))).toEqual(want);
    const packed = packField({ width: w, height: h, dx, dy })!;
    expect(Array.from(sparseValuesAt(pixels, packed))).toEqual(want);
  });
});

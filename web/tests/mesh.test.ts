// The GPU mesh tiles the layer as the CPU renderer's does: whole quads where all four
// links exist, skirt quarters elsewhere, so every drawn pixel's unit square is covered once.
import { describe, expect, it } from 'vitest';
import { buildMesh } from '../src/gl';

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

  it('the draft mesh covers exactly what the whole quads cover', () => {
    const w = 9, h = 8;
    const l = links(w, h, (x, y) => !(x === 5 && y === 2), (x, y, d) => d === 'd' && y === 4 && x < 3);
    const m = buildMesh(w, h, l, null);
    expect(area(w, m.coarse, new Float32Array())).toBe(area(w, m.quads, new Float32Array()));
    expect(m.coarse.length).toBeLessThan(0.6 * m.quads.length);
  });
});

import { describe, expect, it } from 'vitest';
import { PACK_STEPS, downscaleMatte, downscaleRgba, keepForPlayback, keptBytes, packField, proxyFactor, proxySize, toProxy, unpackField, viewCovers, viewFor, VIEW_MARGIN_PX } from '../src/proxy';

describe('large pictures: the proxy', () => {
  it('scales a photograph down by a whole factor, and leaves pictures of screen size alone', () => {
    expect(proxyFactor(4000, 3000)).toBe(4);
    expect(proxySize(4000, 3000, 4)).toEqual({ width: 1000, height: 750 });
    expect(proxyFactor(3000, 2000)).toBe(3);
    expect(proxyFactor(1920, 1080)).toBe(1);
    expect(proxyFactor(512, 512)).toBe(1);
    // The last block is clipped.
    expect(proxySize(4001, 3001, 4)).toEqual({ width: 1001, height: 751 });
  });

  it('maps a scene point to the proxy pixel whose block it is in (centres to centres)', () => {
    // Proxy pixel 0 covers scene pixels 0…3: its centre is at scene coordinate 1.5.
    expect(toProxy([1.5, 1.5], 4)).toEqual([0, 0]);
    expect(toProxy([5.5, 9.5], 4)).toEqual([1, 2]);
    expect(toProxy([7, 3], 1)).toEqual([7, 3]);
  });

  it('averages each block (premultiplied) and keeps transparent blocks transparent', () => {
    const w = 4, h = 2;
    const data = new Uint8Array(4 * w * h);
    // Left block: two red opaque pixels and two transparent ones; right block: grey 100 and 200.
    const set = (x: number, y: number, px: number[]) => data.set(px, 4 * (y * w + x));
    set(0, 0, [255, 0, 0, 255]);
    set(1, 1, [255, 0, 0, 255]);
    set(0, 1, [0, 255, 0, 0]);
    set(1, 0, [0, 255, 0, 0]);
    set(2, 0, [100, 100, 100, 255]);
    set(3, 0, [100, 100, 100, 255]);
    set(2, 1, [200, 200, 200, 255]);
    set(3, 1, [200, 200, 200, 255]);
    const p = downscaleRgba({ width: w, height: h, data }, 2);
    expect(p.width).toBe(2);
    expect(p.height).toBe(1);
    // Colour from the opaque pixels only (the transparent ones' green does not bleed), alpha the mean.
    expect(Array.from(p.data.subarray(0, 4))).toEqual([255, 0, 0, 128]);
    expect(Array.from(p.data.subarray(4, 8))).toEqual([150, 150, 150, 255]);
  });

  it('takes a matte value at each block centre', () => {
    const w = 6, h = 3;
    const m = new Uint8Array(w * h).fill(255);
    m[1 * w + 4] = 0; // the centre pixel (4, 1) of the block x 3…5
    const p = downscaleMatte(m, w, h, 3);
    expect(Array.from(p)).toEqual([255, 0]);
  });

  it('packs a field solved ahead to 16 bits a value, within half a step, and keeps floats it cannot pack', () => {
    const n = 6;
    const dx = Float32Array.from([0, 0.3, -1.7, 2047.5, -2000.01, 1 / 3]);
    const dy = Float32Array.from([5.03125, -0.0312, 12.5, -7, 0.99, -2047.9]);
    const packed = packField({ width: 3, height: 2, dx, dy })!;
    expect(packed.packed.byteLength).toBe(4 * n);
    const back = unpackField(packed);
    for (let i = 0; i < n; i++) {
      expect(Math.abs(back.dx[i] - dx[i])).toBeLessThanOrEqual(0.5 / PACK_STEPS + 1e-6);
      expect(Math.abs(back.dy[i] - dy[i])).toBeLessThanOrEqual(0.5 / PACK_STEPS + 1e-6);
    }
    expect(back.dy[0]).toBe(5.0625);
    // Beyond ±2047 pixels, or not finite: left as floats.
    expect(packField({ width: 1, height: 1, dx: Float32Array.of(2048), dy: Float32Array.of(0) })).toBeNull();
    expect(packField({ width: 1, height: 1, dx: Float32Array.of(0), dy: Float32Array.of(NaN) })).toBeNull();
  });
});

describe('fields kept for playback', () => {
  const w = 40, h = 30, n = w * h;
  const dx = new Float32Array(n).map((_, i) => Math.sin(i / 7) * 12.3);
  const dy = new Float32Array(n).map((_, i) => Math.cos(i / 5) * -4.56);
  const solved = { width: w, height: h, dx, dy };

  it('a proxied scene played by the CPU keeps the values at the draft mesh\'s pixels only, exactly', () => {
    const pixels = new Uint32Array([0, 17, 41, n - 1]);
    const kept = keepForPlayback(solved, 4, pixels);
    expect('sparse' in kept).toBe(true);
    if (!('sparse' in kept)) return;
    expect(kept.pixels).toBe(pixels);
    expect(Array.from(kept.sparse)).toEqual([...pixels].flatMap((i) => [dx[i], dy[i]]));
    expect(keptBytes(kept)).toBe(8 * pixels.length);
  });

  it('a proxied scene on a real GPU (no draft pixels) keeps the whole field, packed', () => {
    for (const pixels of [null, new Uint32Array(0)]) {
      const kept = keepForPlayback(solved, 4, pixels);
      expect('packed' in kept).toBe(true);
      if (!('packed' in kept)) return;
      expect(keptBytes(kept)).toBe(4 * n);
      const back = unpackField(kept);
      for (let i = 0; i < n; i++) {
        expect(Math.abs(back.dx[i] - dx[i])).toBeLessThanOrEqual(0.5 / PACK_STEPS);
        expect(Math.abs(back.dy[i] - dy[i])).toBeLessThanOrEqual(0.5 / PACK_STEPS);
      }
    }
  });

  it('a scene at its own size keeps its floats as they are', () => {
    const kept = keepForPlayback(solved, 1, new Uint32Array([1, 2]));
    expect(kept).toBe(solved);
    expect(keptBytes(kept)).toBe(8 * n);
  });
});

describe('the settled frame drawn for the view', () => {
  const M = VIEW_MARGIN_PX;
  it('draws at Fit the picture a whole factor smaller, at or above the stage resolution', () => {
    // 4000 × 3000 shown at 0.25 device px per picture px (a 1000 × 750 stage): 4 times smaller, all of it.
    expect(viewFor(4000, 3000, 0.25, [0, 0, 4000, 3000])).toEqual({ shrink: 4, region: [0, 0, 1000, 750] });
    // 0.3 device px a picture px: 3 times smaller (never fewer pixels than the stage shows).
    expect(viewFor(4000, 3000, 0.3, [-50, -50, 4100, 3100])).toEqual({ shrink: 3, region: [0, 0, 1334, 1000] });
    // A stage a hair off 1/4 (rounding in the layout) still draws 4 times smaller.
    expect(viewFor(4000, 3000, 0.25000001, [0, 0, 4000, 3000])!.shrink).toBe(4);
  });

  it('draws at 100 % or closer the visible part at the picture resolution, with a margin', () => {
    expect(viewFor(4000, 3000, 1, [1500, 1000, 2500, 1750])).toEqual({ shrink: 1, region: [1500 - M, 1000 - M, 2500 + M, 1750 + M] });
    expect(viewFor(4000, 3000, 2.5, [100.5, 0.2, 500.7, 300])).toEqual({ shrink: 1, region: [100 - M, 0, 501 + M, 300 + M] });
    // Nothing of the picture on the stage.
    expect(viewFor(4000, 3000, 1, [5000, 0, 6000, 700])).toBe(null);
  });

  it('asks for a new view when the scale changes or a pan leaves the margin', () => {
    const at100 = viewFor(4000, 3000, 1, [1500, 1000, 2500, 1750])!;
    // The same view, and a pan within the margin: no new view.
    expect(viewCovers(at100, at100, 4000, 3000)).toBe(true);
    expect(viewCovers(at100, viewFor(4000, 3000, 1, [1500 + M - 1, 1000, 2500 + M - 1, 1750])!, 4000, 3000)).toBe(true);
    // Past the margin, or another scale: a new one.
    expect(viewCovers(at100, viewFor(4000, 3000, 1, [1500 + M + 1, 1000, 2500 + M + 1, 1750])!, 4000, 3000)).toBe(false);
    expect(viewCovers(at100, viewFor(4000, 3000, 0.5, [1500, 1000, 2500, 1750])!, 4000, 3000)).toBe(false);
    // The whole frame at Fit serves any pan at Fit; the whole frame at full resolution serves every view.
    const fit = viewFor(4000, 3000, 0.25, [0, 0, 4000, 3000])!;
    expect(viewCovers(fit, viewFor(4000, 3000, 0.25, [-300, 0, 3700, 3000])!, 4000, 3000)).toBe(true);
    expect(viewCovers(null, at100, 4000, 3000)).toBe(true);
  });
});

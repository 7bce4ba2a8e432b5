import { describe, expect, it } from 'vitest';
import { initializeCanvas, writePsd, type Layer } from 'ag-psd';
import { readLayeredPsd, uniqueNames } from '../src/psd';

// Node has no canvas: ag-psd only needs its pixel buffers here (the browser has both).
initializeCanvas(
  () => {
    throw new Error('no canvas in these tests');
  },
  (width: number, height: number) => ({ width, height, data: new Uint8ClampedArray(width * height * 4) }) as unknown as ImageData,
);

/** A w×h RGBA block of one colour. */
function block(w: number, h: number, rgba: number[]) {
  const data = new Uint8ClampedArray(w * h * 4);
  for (let i = 0; i < w * h; i++) data.set(rgba, 4 * i);
  return { width: w, height: h, data };
}

function psdBytes(children: Layer[]): ArrayBuffer {
  const buf = writePsd({ width: 8, height: 6, children, imageData: block(8, 6, [0, 0, 0, 255]) }, { noBackground: true, generateThumbnail: false });
  return buf;
}

describe('readLayeredPsd', () => {
  it('multiplies a layer mask and the opacities of the layer and its group into alpha', () => {
    const mask = block(4, 6, [0, 0, 0, 255]);
    const pic = readLayeredPsd(psdBytes([
      { name: 'back', imageData: block(8, 6, [10, 20, 30, 255]), left: 0, top: 0 },
      {
        name: 'g', opacity: 0.5, children: [
          // Masked out on its left half (the mask is black there), white elsewhere.
          { name: 'front', opacity: 0.5, imageData: block(4, 2, [200, 100, 50, 255]), left: 2, top: 1, mask: { imageData: mask, left: 0, top: 0, defaultColor: 255 } },
          { name: 'back', hidden: true, imageData: block(8, 6, [1, 2, 3, 255]), left: 0, top: 0 },
        ],
      },
    ]), 'test.psd');
    expect(pic.layers.map((l) => l.name)).toEqual(['back', 'front', 'back']);
    expect(uniqueNames(pic.layers.map((l) => l.name))).toEqual(['back', 'front', 'back (2)']);
    expect(pic.layers.map((l) => l.visible)).toEqual([true, true, false]);
    const front = pic.layers[1].image;
    expect([front.width, front.height]).toEqual([8, 6]);
    const px = (x: number, y: number) => Array.from(front.data.subarray(4 * (y * 8 + x), 4 * (y * 8 + x) + 4));
    expect(px(3, 1)).toEqual([200, 100, 50, 0]); // under the black mask
    expect(px(5, 1)).toEqual([200, 100, 50, 64]); // 255 · 0.5 · 0.5
    expect(px(0, 0)[3]).toBe(0); // outside the layer's box
    expect(pic.notes.some((n) => /group 'g' is flattened/.test(n))).toBe(true);
  });

  it('names a layer with a blend mode other than Normal, and refuses what is not a PSD', () => {
    const pic = readLayeredPsd(psdBytes([{ name: 'shade', blendMode: 'multiply', imageData: block(8, 6, [9, 9, 9, 255]), left: 0, top: 0 }]), 'a.psd');
    expect(pic.notes).toEqual([expect.stringMatching(/^a\.psd: layer 'shade' uses the blend mode Multiply; .*set it to Normal$/)]);
    expect(() => readLayeredPsd(new TextEncoder().encode('not a psd').buffer, 'b.psd')).toThrow(/b\.psd: not a readable PSD file/);
    expect(() => readLayeredPsd(psdBytes([{ name: 'empty', children: [] }]), 'c.psd')).toThrow(/c\.psd: the PSD has no pixel layers/);
  });
});

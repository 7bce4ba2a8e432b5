// Layered Photoshop documents, read the way `inkwarp new` reads them (python/inkwarp/importing.py):
// one layer per pixel layer in PSD order (bottom first), names and visibility kept, every layer
// a canvas-sized image at offset [0, 0], groups flattened into their layers (a group's opacity
// and visibility pass on to them), opacity and layer masks multiplied into alpha, and a note
// naming each layer or group whose blend mode is not Normal.

import { readPsd, type Layer } from 'ag-psd';
import { ImageFileError, type Rgba } from './images';

export interface PsdLayer {
  name: string;
  visible: boolean;
  image: Rgba;
}

export interface PsdPicture {
  width: number;
  height: number;
  layers: PsdLayer[];
  /** What reading it changed or could not keep, each naming the file and the layer. */
  notes: string[];
}

export function isPsdName(name: string): boolean {
  return /\.(psd|psb)$/i.test(name);
}

const NORMAL = new Set(['normal', 'pass through', undefined]);
const RGB = 3;

/** Reads a PSD file's bytes into canvas-sized straight RGBA8 layers. */
export function readLayeredPsd(bytes: ArrayBuffer, file: string): PsdPicture {
  let psd;
  try {
    psd = readPsd(bytes, { useImageData: true, skipCompositeImageData: true, skipThumbnail: true, skipLinkedFilesData: true });
  } catch (err) {
    const reason = (err as Error).message?.replace(/\s+/g, ' ') || String(err);
    throw new ImageFileError(`${file}: not a readable PSD file (${reason}); save it again from the painting app as a Photoshop document (RGB, 8 bits).`);
  }
  if (psd.colorMode !== undefined && (psd.colorMode as number) !== RGB) {
    throw new ImageFileError(`${file}: the PSD is not in RGB colour mode; convert it (Photoshop: Image > Mode > RGB Color) and save it again.`);
  }
  if (psd.bitsPerChannel !== undefined && psd.bitsPerChannel !== 8) {
    throw new ImageFileError(`${file}: the PSD has ${psd.bitsPerChannel} bits per channel; convert it to 8 (Photoshop: Image > Mode > 8 Bits/Channel) and save it again.`);
  }
  const { width, height } = psd;
  const layers: PsdLayer[] = [];
  const notes: string[] = [];

  const walk = (group: Layer[], path: string[], opacity: number, visible: boolean): void => {
    for (const layer of group) {
      const name = layer.name ?? '';
      const here = [...path, name].join(' / ');
      const shown = visible && !layer.hidden;
      const alpha = opacity * (layer.opacity ?? 1);
      const isGroup = layer.children !== undefined;
      if (!NORMAL.has(layer.blendMode) && shown) {
        const mode = layer.blendMode!.replace(/\b\w/g, (c) => c.toUpperCase());
        notes.push(`${file}: ${isGroup ? 'group' : 'layer'} '${here}' uses the blend mode ${mode}; inkwarp composites it as Normal, so it will look different: merge it into the layer below or set it to Normal`);
      }
      if (isGroup) {
        notes.push(`${file}: group '${here}' is flattened into its layers (names kept, its opacity and visibility applied to them)`);
        walk(layer.children!, [...path, name], alpha, shown);
        continue;
      }
      const data = new Uint8Array(width * height * 4);
      const src = layer.imageData;
      if (src) paste(data, width, height, src.data, src.width, src.height, layer.left ?? 0, layer.top ?? 0, false);
      const mask = layer.mask;
      if (mask && !mask.disabled) {
        const matte = new Uint8Array(width * height).fill(mask.defaultColor ?? 255);
        if (mask.imageData) paste(matte, width, height, mask.imageData.data, mask.imageData.width, mask.imageData.height, mask.left ?? 0, mask.top ?? 0, true);
        for (let i = 0; i < width * height; i++) data[4 * i + 3] = Math.floor((data[4 * i + 3] * matte[i]) / 255);
      }
      if (alpha < 1) for (let i = 0; i < width * height; i++) data[4 * i + 3] = Math.round(data[4 * i + 3] * alpha);
      layers.push({ name, visible: shown, image: { width, height, data } });
    }
  };
  walk(psd.children ?? [], [], 1, true);
  if (!layers.length) {
    throw new ImageFileError(`${file}: the PSD has no pixel layers; add a layer with the picture and save it again.`);
  }
  return { width, height, layers, notes };
}

/** Copies `src` (RGBA, w×h) into `dst` at (left, top), clipped; `grey` keeps only the red channel into a one-channel `dst`. */
function paste(dst: Uint8Array, dw: number, dh: number, src: ArrayLike<number>, sw: number, sh: number, left: number, top: number, grey: boolean): void {
  for (let y = Math.max(0, top); y < Math.min(dh, top + sh); y++) {
    for (let x = Math.max(0, left); x < Math.min(dw, left + sw); x++) {
      const s = 4 * ((y - top) * sw + (x - left));
      if (grey) dst[y * dw + x] = src[s];
      else {
        const d = 4 * (y * dw + x);
        dst[d] = src[s];
        dst[d + 1] = src[s + 1];
        dst[d + 2] = src[s + 2];
        dst[d + 3] = src[s + 3];
      }
    }
  }
}

/** Layer names made unique as `inkwarp new` does (a repeated name gets " (2)", " (3)", … appended). */
export function uniqueNames(names: string[]): string[] {
  const seen = new Map<string, number>();
  return names.map((n) => {
    const base = n.trim() || 'layer';
    let name = base;
    while (seen.has(name)) {
      seen.set(base, seen.get(base)! + 1);
      name = `${base} (${seen.get(base)})`;
    }
    if (!seen.has(name)) seen.set(name, 1);
    return name;
  });
}

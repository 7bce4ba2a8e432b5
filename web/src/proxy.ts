// Large pictures: the editor works on a proxy, the picture scaled down by a whole factor,
// and draws the full-resolution frame (solved and rendered as `inkwarp render` does) once
// the drawing rests.

import type { ViewSpec } from './engine';
import type { Rgba } from './images';
import type { Pt } from './scene';

/** A picture with more pixels than this is edited through a proxy. */
export const PROXY_ABOVE_PX = 2_100_000;
/** A proxy has about this many pixels (at most). */
export const PROXY_TARGET_PX = 800_000;

/**
 * The whole factor a picture of `width × height` is scaled down by to make its proxy (1:
 * no proxy). A 4000 × 3000 photograph gets 4 (a 1000 × 750 proxy); 1920 × 1080 gets none.
 */
export function proxyFactor(width: number, height: number): number {
  const n = width * height;
  return n > PROXY_ABOVE_PX ? Math.ceil(Math.sqrt(n / PROXY_TARGET_PX)) : 1;
}

/** The size of a frame drawn `f` times smaller (a proxy, a shrunk draft): every pixel stands for an `f × f` block (the last ones clipped). */
export function proxySize(width: number, height: number, f: number): { width: number; height: number } {
  return { width: Math.ceil(width / f), height: Math.ceil(height / f) };
}

/**
 * A scene point in proxy pixels: proxy pixel `j` covers scene pixels `f·j … f·j + f − 1`,
 * so its centre is at scene coordinate `f·j + (f − 1)/2`.
 */
export function toProxy(p: Pt, f: number): Pt {
  if (f === 1) return p;
  const c = (f - 1) / 2;
  return [(p[0] - c) / f, (p[1] - c) / f];
}

/** Straight RGBA8 scaled down by `f`: each block's premultiplied mean (a box filter). */
export function downscaleRgba(img: Rgba, f: number): Rgba {
  const { width: w, height: h, data } = img;
  const { width: pw, height: ph } = proxySize(w, h, f);
  const out = new Uint8Array(4 * pw * ph);
  const acc = new Float64Array(4 * pw);
  const count = new Uint32Array(pw);
  for (let py = 0; py < ph; py++) {
    acc.fill(0);
    count.fill(0);
    const y1 = Math.min(h, (py + 1) * f);
    for (let y = py * f; y < y1; y++) {
      let i = 4 * y * w;
      for (let x = 0; x < w; x++, i += 4) {
        const j = (x / f) | 0;
        const a = data[i + 3];
        acc[4 * j] += data[i] * a;
        acc[4 * j + 1] += data[i + 1] * a;
        acc[4 * j + 2] += data[i + 2] * a;
        acc[4 * j + 3] += a;
        count[j]++;
      }
    }
    for (let j = 0; j < pw; j++) {
      const o = 4 * (py * pw + j);
      const a = acc[4 * j + 3];
      if (a > 0) {
        out[o] = Math.round(acc[4 * j] / a);
        out[o + 1] = Math.round(acc[4 * j + 1] / a);
        out[o + 2] = Math.round(acc[4 * j + 2] / a);
        out[o + 3] = Math.round(a / count[j]);
      }
    }
  }
  return { width: pw, height: ph, data: out };
}

/**
 * A continuity matte scaled down by `f`: a proxy pixel takes the value at its block's
 * centre pixel (holes and connected strips keep their place; one narrower than `f` pixels
 * may fall between centres: the full-resolution frame has it).
 */
export function downscaleMatte(matte: Uint8Array, width: number, height: number, f: number): Uint8Array {
  const { width: pw, height: ph } = proxySize(width, height, f);
  const out = new Uint8Array(pw * ph);
  const half = f >> 1;
  for (let py = 0; py < ph; py++) {
    const y = Math.min(height - 1, py * f + half);
    for (let px = 0; px < pw; px++) out[py * pw + px] = matte[y * width + Math.min(width - 1, px * f + half)];
  }
  return out;
}

/** A field kept for playback of a proxied scene (see `packField`). */
export interface PackedField {
  width: number;
  height: number;
  /** Δx then Δy of every pixel, in 1/`PACK_STEPS` of a proxy pixel. */
  packed: Int16Array;
}

/** Steps a proxy pixel is cut into by `packField` (at factor 4 a step is a quarter of a picture pixel). */
export const PACK_STEPS = 16;

/**
 * A proxy's field packed to 16 bits a value, half the bytes of its floats: the fields
 * solved ahead for playback of a proxied scene (6 MB a frame at 1000 × 750 as floats) are
 * kept so. Each value moves by at most half a step (1/32 of a proxy pixel), far below what
 * a frame can show; a field with a value beyond ±2047 pixels, or one not finite, is not
 * packed (null: keep the floats).
 */
export function packField(f: { width: number; height: number; dx: Float32Array; dy: Float32Array }): PackedField | null {
  const n = f.width * f.height;
  const packed = new Int16Array(2 * n);
  const limit = 32767 / PACK_STEPS;
  for (const [plane, at] of [[f.dx, 0], [f.dy, n]] as const) {
    for (let i = 0; i < n; i++) {
      const v = plane[i];
      if (!(Math.abs(v) < limit)) return null;
      packed[at + i] = Math.round(v * PACK_STEPS);
    }
  }
  return { width: f.width, height: f.height, packed };
}

/** The floats of a packed field (`packField`). */
export function unpackField(p: PackedField): { width: number; height: number; dx: Float32Array; dy: Float32Array } {
  const n = p.width * p.height;
  const dx = new Float32Array(n);
  const dy = new Float32Array(n);
  const inv = 1 / PACK_STEPS;
  for (let i = 0; i < n; i++) {
    dx[i] = p.packed[i] * inv;
    dy[i] = p.packed[n + i] * inv;
  }
  return { width: p.width, height: p.height, dx, dy };
}

/** The floats of a packed field (`packField`) at `pixels` only, as (Δx, Δy) pairs in their order. */
export function unpackAt(p: PackedField, pixels: Uint32Array): Float32Array {
  const n = p.width * p.height;
  const out = new Float32Array(2 * pixels.length);
  const inv = 1 / PACK_STEPS;
  for (let k = 0; k < pixels.length; k++) {
    const i = pixels[k];
    out[2 * k] = p.packed[i] * inv;
    out[2 * k + 1] = p.packed[n + i] * inv;
  }
  return out;
}

/**
 * A field kept for playback as its values at a draft mesh's pixels only: all a played
 * frame of a proxied scene reads where the CPU draws drafts (a few thousand pixels of a
 * 1000 × 750 proxy: tens of kB a frame where the packed field takes 3 MB).
 */
export interface SparseKept {
  width: number;
  height: number;
  /** The draft mesh's pixels the values are at (the layer's `draftPixels` array itself: a new mesh makes it stale). */
  pixels: Uint32Array;
  /** (Δx, Δy) pairs at `pixels`, in their order. */
  sparse: Float32Array;
}

/** A field kept for playback: whole as floats, packed (`packField`) or at a draft mesh's pixels only (`SparseKept`). */
export type KeptField = { width: number; height: number; dx: Float32Array; dy: Float32Array } | PackedField | SparseKept;

/**
 * How a solved field is kept for playback. A proxied scene (`proxy` > 1) whose frames are
 * played as drafts drawn by the CPU (`draftPixels` given: a software GPU) keeps the values
 * at the draft mesh's pixels alone; one played on a real GPU, which draws the whole field,
 * keeps it packed (floats where it cannot be packed); a scene at its own size keeps the floats.
 */
export function keepForPlayback(
  field: { width: number; height: number; dx: Float32Array; dy: Float32Array },
  proxy: number,
  draftPixels: Uint32Array | null,
): KeptField {
  if (proxy <= 1) return field;
  if (draftPixels && draftPixels.length > 0) {
    const sparse = new Float32Array(2 * draftPixels.length);
    for (let k = 0; k < draftPixels.length; k++) {
      const i = draftPixels[k];
      sparse[2 * k] = field.dx[i];
      sparse[2 * k + 1] = field.dy[i];
    }
    return { width: field.width, height: field.height, pixels: draftPixels, sparse };
  }
  return packField(field) ?? field;
}

/** The bytes a kept field holds (the draft mesh's pixels of a `SparseKept` belong to its layer, not counted). */
export function keptBytes(k: KeptField): number {
  if ('sparse' in k) return k.sparse.byteLength;
  if ('packed' in k) return k.packed.byteLength;
  return k.dx.byteLength + k.dy.byteLength;
}

/** How many view pixels (of the smaller frame) a view takes beyond the stage's edges, so a small pan needs no new view. */
export const VIEW_MARGIN_PX = 32;

/**
 * The view of a `width × height` picture's full-resolution frame that a stage shows: the
 * frame drawn `shrink` times smaller, `shrink` the whole number of picture pixels per
 * device pixel (rounded down, at least 1: at 100 % or closer the picture's own pixels), so
 * the frame drawn has at least the stage's resolution and the browser scales it down by
 * less than 2; and its region the part of the picture on the stage (`visible`, scene
 * pixels `[x0, y0, x1, y1]`), `VIEW_MARGIN_PX` more each side, clipped to the frame. Null
 * when none of the picture is on the stage.
 */
export function viewFor(width: number, height: number, devicePxPerScenePx: number, visible: [number, number, number, number]): ViewSpec | null {
  const shrink = Math.max(1, Math.floor(1 / devicePxPerScenePx + 1e-6));
  const vw = Math.ceil(width / shrink);
  const vh = Math.ceil(height / shrink);
  const [x0, y0, x1, y1] = visible;
  if (!(x1 > Math.max(0, x0) && y1 > Math.max(0, y0) && x0 < width && y0 < height)) return null;
  const m = VIEW_MARGIN_PX;
  const region: [number, number, number, number] = [
    Math.max(0, Math.floor(x0 / shrink) - m),
    Math.max(0, Math.floor(y0 / shrink) - m),
    Math.min(vw, Math.ceil(x1 / shrink) + m),
    Math.min(vh, Math.ceil(y1 / shrink) + m),
  ];
  return { shrink, region };
}

/**
 * Whether a view drawn of a `width × height` frame (`have`; null: the whole frame, at the
 * picture's resolution) serves the view wanted: the same scale and a region holding the
 * wanted one's stage part (its region less the margin, where the frame's edge did not clip
 * it), so a pan within the margin needs no new view.
 */
export function viewCovers(have: ViewSpec | null, want: ViewSpec, width: number, height: number): boolean {
  if (!have) return true;
  if (have.shrink !== want.shrink) return false;
  const m = VIEW_MARGIN_PX;
  const vw = Math.ceil(width / want.shrink);
  const vh = Math.ceil(height / want.shrink);
  const [a0, b0, a1, b1] = have.region;
  const [x0, y0, x1, y1] = want.region;
  const inner = [x0 === 0 ? 0 : x0 + m, y0 === 0 ? 0 : y0 + m, x1 === vw ? vw : x1 - m, y1 === vh ? vh : y1 - m];
  return a0 <= inner[0] && b0 <= inner[1] && a1 >= inner[2] && b1 >= inner[3];
}

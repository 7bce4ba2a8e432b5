// Images in and out: decoding pictures to straight RGBA8, mattes, data: URIs, PNG export.

import type { Layer, SceneDoc } from './scene';

export interface Rgba {
  width: number;
  height: number;
  /** Straight (not premultiplied) RGBA8, rows top to bottom. */
  data: Uint8Array;
}

export class ImageFileError extends Error {
  /** `why`: what is wrong with the picture, without naming it. */
  constructor(message: string, readonly why = message) {
    super(message);
    this.name = 'ImageFileError';
  }
}

/** The engine's own decoder and matte rule, so the editor reads pictures as the CLI does. */
export interface Decoder {
  decode(input: Uint8Array): Rgba;
  matteValues(rgba: Uint8Array, width: number, height: number): Uint8Array;
}

let decoder: Decoder | null = null;
/** Decodes in a worker (see `useOffPageDecoder`). */
let offPage: ((bytes: Uint8Array) => Promise<Rgba>) | null = null;
/**
 * Pictures of at least this many bytes (a photograph) are decoded off the page where it
 * can: a 4000 × 3000 JPEG's decoding takes the engine's module memory to about 140 MB, and
 * a WebAssembly memory never shrinks.
 */
export const OFF_PAGE_DECODE_BYTES = 1 << 20;

export function useDecoder(d: Decoder): void {
  decoder = d;
}

/** Large pictures (`OFF_PAGE_DECODE_BYTES`) are decoded by `decode` (the same engine, in a worker); null: on the page. */
export function useOffPageDecoder(decode: ((bytes: Uint8Array) => Promise<Rgba>) | null): void {
  offPage = decode;
}

const cache = new Map<string, Promise<Rgba>>();
const enc = new TextEncoder();
/**
 * The file each picture came from (its path as the scene file names it), by its data: URI:
 * `inkwarp edit` inlines a scene's pictures, and says which file each one is.
 */
let files = new Map<string, string>();

/** Names the files pictures came from (`[data: URI, path]`), in place of those named before. */
export function nameFiles(named: Iterable<[string, string]>): void {
  files = new Map(named);
}

/** The file a picture came from (see `nameFiles`), where it is known. */
export function fileOf(src: string): string | undefined {
  return files.get(src);
}

/** The layer keys that hold pictures. */
export const PICTURE_KEYS = ['image', 'alpha', 'continuity'] as const;
export type PictureKey = (typeof PICTURE_KEYS)[number];

/** A layer's picture at `key`, by its layer's name: how kept work marks and names its pictures. */
export const pictureSlot = (layer: string, key: PictureKey): string => `${layer}\u0000${key}`;

/**
 * How a message names the picture at `key` of layer `layer`: by its file where it came from
 * one ("cat.png of layer 'cat'"), else by its layer ("the continuity matte of layer 'cat'").
 */
export function pictureName(layer: string, key: PictureKey, file?: string): string {
  return `${file ?? `the ${key === 'image' ? 'picture' : `${key} matte`}`} of layer '${layer}'`;
}

/** How the engine names a picture held inline: by its reference, a data: URI cut short. */
const INLINE_PICTURE = /the image in the data:[^,]*,\.\.\. URI/g;

/**
 * The engine's `message` about `path` of `doc` (a scene document, maybe not a sound one),
 * where that is a layer's picture ("layers[0].image"), with the picture named by
 * `name(layer, key)` instead of by its data: URI, which the user never saw.
 */
export function withPictureNamed(doc: unknown, path: string, message: string, name: (layer: Layer, key: PictureKey) => string): string {
  const at = new RegExp(`^layers\\[(\\d+)\\]\\.(${PICTURE_KEYS.join('|')})$`).exec(path);
  const layer = at && (doc as SceneDoc).layers?.[Number(at[1])];
  return layer ? message.replace(INLINE_PICTURE, () => name(layer, at[2] as PictureKey)) : message;
}

/** Decodes an image reference (a data: URI or a URL) to straight RGBA8, cached. */
export function decodeImage(src: string): Promise<Rgba> {
  let p = cache.get(src);
  if (!p) {
    p = decodeUncached(src);
    cache.set(src, p);
    p.catch(() => cache.delete(src));
  }
  return p;
}

/** Seeds the cache: `src` decodes to `img` (a picture just opened, decoded once). */
export function rememberImage(src: string, img: Rgba): void {
  cache.set(src, Promise.resolve(img));
}

/** Drops `src` from the cache (a large picture whose proxy is all the page keeps). */
export function forgetImage(src: string): void {
  cache.delete(src);
}

async function decodeUncached(src: string): Promise<Rgba> {
  if (src.startsWith('data:')) return decodeBytes(enc.encode(src), describe(src));
  let bytes: Uint8Array;
  try {
    const resp = await fetch(src);
    if (!resp.ok) throw new Error(`HTTP ${resp.status}`);
    bytes = new Uint8Array(await resp.arrayBuffer());
  } catch {
    throw new ImageFileError(`Could not read the image ${describe(src)}.`);
  }
  return decodeBytes(bytes, describe(src));
}

/** Decodes a picked or dropped file. */
export async function decodeBlob(blob: Blob, name: string): Promise<Rgba> {
  return decodeBytes(new Uint8Array(await blob.arrayBuffer()), name);
}

async function decodeBytes(bytes: Uint8Array, name: string): Promise<Rgba> {
  if (!decoder) throw new ImageFileError('The engine is not loaded yet.');
  try {
    return offPage && bytes.length >= OFF_PAGE_DECODE_BYTES ? await offPage(bytes) : decoder.decode(bytes);
  } catch (err) {
    const why = (err as Error).message;
    throw new ImageFileError(`${name}: ${why}`, why);
  }
}

function describe(src: string): string {
  if (src.startsWith('data:')) return `(${src.slice(5, src.indexOf(';') > 0 ? src.indexOf(';') : 20)} data URI)`;
  return src;
}

/** A continuity matte from an image: the engine's matte values (grey level × alpha). */
export function matteFromImage(img: Rgba): Uint8Array {
  return decoder!.matteValues(img.data, img.width, img.height);
}

/** The default continuity matte: the layer's alpha (nonzero = connected). */
export function matteFromAlpha(img: Rgba): Uint8Array {
  const n = img.width * img.height;
  const out = new Uint8Array(n);
  for (let i = 0; i < n; i++) out[i] = img.data[4 * i + 3];
  return out;
}

/** Replaces an image's alpha by an alpha matte's values, as the engine does. */
export function withAlpha(img: Rgba, alpha: Rgba): Rgba {
  const values = decoder!.matteValues(alpha.data, alpha.width, alpha.height);
  const data = img.data.slice();
  for (let i = 0; i < img.width * img.height; i++) data[4 * i + 3] = values[i];
  return { width: img.width, height: img.height, data };
}

/** Reads a File as a data: URI. */
export function fileToDataUri(file: Blob): Promise<string> {
  return new Promise((resolve, reject) => {
    const r = new FileReader();
    r.onload = () => resolve(r.result as string);
    r.onerror = () => reject(new ImageFileError('Could not read the file.'));
    r.readAsDataURL(file);
  });
}

/** Straight RGBA8 pixels as a PNG data: URI (for the matte overlay and exports). */
export function rgbaToCanvas(img: Rgba): OffscreenCanvas {
  const c = new OffscreenCanvas(img.width, img.height);
  const ctx = c.getContext('2d')!;
  ctx.putImageData(new ImageData(new Uint8ClampedArray(img.data), img.width, img.height), 0, 0);
  return c;
}

export async function rgbaToPngBlob(img: Rgba): Promise<Blob> {
  return rgbaToCanvas(img).convertToBlob({ type: 'image/png' });
}

export function blobToDataUri(blob: Blob): Promise<string> {
  return fileToDataUri(blob);
}

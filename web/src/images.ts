// Images in and out: decoding pictures to straight RGBA8, mattes, data: URIs, PNG export.

export interface Rgba {
  width: number;
  height: number;
  /** Straight (not premultiplied) RGBA8, rows top to bottom. */
  data: Uint8Array;
}

export class ImageFileError extends Error {
  constructor(message: string) {
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
    throw new ImageFileError(`${name} is not an image inkwarp can read (use PNG or JPEG): ${(err as Error).message}`);
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

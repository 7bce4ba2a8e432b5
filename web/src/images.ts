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

const cache = new Map<string, Promise<Rgba>>();

/**
 * Decodes an image (a data: URI or a URL) to straight RGBA8. The browser decodes; we ask
 * it not to premultiply or colour-convert so the bytes are the file's own, as the command
 * line reads them.
 */
export function decodeImage(src: string): Promise<Rgba> {
  let p = cache.get(src);
  if (!p) {
    p = decodeUncached(src);
    cache.set(src, p);
    p.catch(() => cache.delete(src));
  }
  return p;
}

async function decodeUncached(src: string): Promise<Rgba> {
  let blob: Blob;
  try {
    blob = await (await fetch(src)).blob();
  } catch {
    throw new ImageFileError(`Could not read the image ${describe(src)}.`);
  }
  return decodeBlob(blob, describe(src));
}

export async function decodeBlob(blob: Blob, name: string): Promise<Rgba> {
  let bitmap: ImageBitmap;
  try {
    bitmap = await createImageBitmap(blob, { premultiplyAlpha: 'none', colorSpaceConversion: 'none' });
  } catch {
    throw new ImageFileError(`${name} is not an image this browser can read (use PNG or JPEG).`);
  }
  // Read the pixels back through WebGL: a 2D canvas would premultiply and lose precision
  // in translucent pixels.
  const { width, height } = bitmap;
  const canvas = new OffscreenCanvas(width, height);
  const gl = canvas.getContext('webgl2', { premultipliedAlpha: false });
  if (!gl) throw new ImageFileError('This browser has no WebGL2.');
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
  gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, bitmap);
  const fbo = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
  const data = new Uint8Array(4 * width * height);
  gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, data);
  bitmap.close();
  gl.getExtension('WEBGL_lose_context')?.loseContext();
  return { width, height, data };
}

function describe(src: string): string {
  if (src.startsWith('data:')) return `(${src.slice(5, src.indexOf(';') > 0 ? src.indexOf(';') : 20)} data URI)`;
  return src;
}

/** A continuity matte from an image: grey level times alpha, nonzero = connected. */
export function matteFromImage(img: Rgba): Uint8Array {
  const n = img.width * img.height;
  const out = new Uint8Array(n);
  for (let i = 0; i < n; i++) {
    const d = img.data;
    const grey = (d[4 * i] + d[4 * i + 1] + d[4 * i + 2]) / 3;
    out[i] = Math.round((grey * d[4 * i + 3]) / 255) > 0 ? 1 : 0;
  }
  return out;
}

/** The default continuity matte: where the layer's alpha is > 0. */
export function matteFromAlpha(img: Rgba): Uint8Array {
  const n = img.width * img.height;
  const out = new Uint8Array(n);
  for (let i = 0; i < n; i++) out[i] = img.data[4 * i + 3] > 0 ? 1 : 0;
  return out;
}

/** Replaces an image's alpha by an alpha matte (its grey level times alpha). */
export function withAlpha(img: Rgba, alpha: Rgba): Rgba {
  const data = img.data.slice();
  for (let i = 0; i < img.width * img.height; i++) {
    const a = alpha.data;
    const grey = (a[4 * i] + a[4 * i + 1] + a[4 * i + 2]) / 3;
    data[4 * i + 3] = Math.round((grey * a[4 * i + 3]) / 255);
  }
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

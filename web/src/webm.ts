// WebM export with exact timing: every frame is encoded by WebCodecs with the timestamp
// `i / fps` (not the wall-clock time it took to solve), and muxed into a WebM file.

import { ArrayBufferTarget, Muxer } from 'webm-muxer';

/** The codecs tried, best first: (WebCodecs codec string, WebM codec id). */
const CODECS: [string, string][] = [
  ['vp09.00.10.08', 'V_VP9'],
  ['vp8', 'V_VP8'],
];

/** Whether this browser can encode video (WebCodecs' `VideoEncoder`). */
export function canEncodeWebm(): boolean {
  return typeof VideoEncoder !== 'undefined' && typeof VideoFrame !== 'undefined';
}

/** Alpha below this is transparency worth a word (as `inkwarp render` judges an MP4's frames): the
 * squeezed edges of an opaque picture come out at 252–254. */
const SEE_THROUGH_ALPHA = 250;

/**
 * Composites straight RGBA8 pixels over white in place, as `inkwarp render` flattens an MP4:
 * a WebM encoded in the browser keeps no alpha, and its transparent pixels came out black.
 * Whether any pixel was see-through (alpha below 250).
 */
export function overWhite(px: Uint8Array): boolean {
  let clear = false;
  for (let i = 3; i < px.length; i += 4) {
    const a = px[i];
    if (a === 255) continue;
    clear ||= a < SEE_THROUGH_ALPHA;
    for (let c = i - 3; c < i; c++) px[c] = Math.round((px[c] * a + 255 * (255 - a)) / 255);
    px[i] = 255;
  }
  return clear;
}

/** The microsecond timestamp of frame `i` at `fps`: exactly `i / fps` s, rounded once. */
export function frameTimestampUs(i: number, fps: number): number {
  return Math.round((i * 1e6) / fps);
}

/**
 * Encodes `count` frames of `width × height` as a WebM file: `frame(i)` draws frame `i`
 * and returns its straight RGBA8 pixels; `progress(i)` is told after each one. Frame `i`
 * is shown at `i / fps` seconds for `1 / fps` seconds, however long it took to draw.
 * Once `signal` is aborted no frame more is drawn and the promise rejects with its reason.
 */
export async function encodeWebm(
  width: number,
  height: number,
  fps: number,
  count: number,
  frame: (i: number) => Promise<Uint8Array>,
  progress: (i: number) => void = () => {},
  signal?: AbortSignal,
): Promise<Blob> {
  let chosen: [string, string] | null = null;
  for (const [codec, id] of CODECS) {
    const support = await VideoEncoder.isConfigSupported({ codec, width, height, bitrate: 8_000_000, framerate: fps });
    if (support.supported) {
      chosen = [codec, id];
      break;
    }
  }
  if (!chosen) throw new Error(`This browser cannot encode ${width}×${height} video as VP9 or VP8.`);
  const muxer = new Muxer({
    target: new ArrayBufferTarget(),
    video: { codec: chosen[1], width, height, frameRate: fps },
    firstTimestampBehavior: 'strict',
  });
  let failure: Error | null = null;
  const encoder = new VideoEncoder({
    output: (chunk, meta) => muxer.addVideoChunk(chunk, meta),
    error: (e) => (failure = e as Error),
  });
  encoder.configure({ codec: chosen[0], width, height, bitrate: 8_000_000, framerate: fps, latencyMode: 'quality' });
  const keyEvery = Math.max(1, Math.round(2 * fps));
  try {
    for (let i = 0; i < count; i++) {
      signal?.throwIfAborted();
      const pixels = await frame(i);
      signal?.throwIfAborted();
      if (failure) throw failure;
      const vf = new VideoFrame(pixels, {
        format: 'RGBA',
        codedWidth: width,
        codedHeight: height,
        timestamp: frameTimestampUs(i, fps),
        duration: frameTimestampUs(i + 1, fps) - frameTimestampUs(i, fps),
      });
      encoder.encode(vf, { keyFrame: i % keyEvery === 0 });
      vf.close();
      // keep memory flat: let the encoder catch up
      while (encoder.encodeQueueSize > 4) await new Promise((r) => setTimeout(r, 5));
      progress(i);
    }
    await encoder.flush();
    if (failure) throw failure;
    signal?.throwIfAborted();
  } finally {
    if (encoder.state !== 'closed') encoder.close();
  }
  muxer.finalize();
  return new Blob([muxer.target.buffer], { type: 'video/webm' });
}

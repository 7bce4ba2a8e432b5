// The scene format's ranges, as the editor's fields hold typed values to them and drags
// stop at them: a value a field takes, or a point dragged, is one a scene file may hold, so
// the work kept in the browser (and a saved file) always opens again. The numbers are the
// engine's own (`Engine.limits`, from inkwarp_core::limits), never a second copy here.

import { type Pt, type SceneDoc, layerFeatures } from './scene';

/** The ranges of `inkwarp_core::limits` that the editor's fields meet. */
export interface Limits {
  /** The largest |x| or |y| of a control point, a cut or an offset, in pixels. */
  max_coord_px: number;
  /** The longest duration (and the latest key), in seconds. */
  max_time_s: number;
  /** The fewest and the most frames per second. */
  min_fps: number;
  max_fps: number;
  /** The most frames a scene may have (duration × fps). */
  max_frames: number;
}

/** `v` for a message: as written when short, in scientific notation when huge (as the engine shows it). */
const show = (v: number): string => (Number.isFinite(v) && Math.abs(v) >= 1e7 ? v.toExponential().replace('e+', 'e') : String(v));

/** Why `duration × fps` is too many frames, or null. */
function framesProblem(duration: number, fps: number, l: Limits): string | null {
  return duration * fps > l.max_frames
    ? `${show(duration)} s at ${show(fps)} frames per second is more than the ${show(l.max_frames)} frames a scene may have: shorten it or lower fps.`
    : null;
}

/** Why a scene may not have `fps` frames per second (with its `duration`), or null when it may. */
export function fpsProblem(fps: number, duration: number, l: Limits): string | null {
  if (!(Number.isFinite(fps) && fps >= l.min_fps && fps <= l.max_fps)) {
    return `Frames per second must be from ${l.min_fps} (one frame every ${1 / l.min_fps} s) to ${l.max_fps}, not ${Number.isNaN(fps) ? 'that' : show(fps)}; e.g. 24.`;
  }
  return framesProblem(duration, fps, l);
}

/** Why a scene may not last `duration` seconds (at `fps`), or null when it may. */
export function durationProblem(duration: number, fps: number, l: Limits): string | null {
  if (!(Number.isFinite(duration) && duration > 0 && duration <= l.max_time_s)) {
    const hours = (l.max_time_s / 3600).toFixed(1);
    return `The duration must be more than 0 s and at most ${show(l.max_time_s)} s (about ${hours} hours), not ${Number.isNaN(duration) ? 'that' : `${show(duration)} s`}; split a longer animation into several scenes.`;
  }
  return framesProblem(duration, fps, l);
}

/** Why a layer's offset may not be `v` pixels (either way), or null when it may. */
export function offsetProblem(v: number, l: Limits): string | null {
  return Number.isFinite(v) && Math.abs(v) <= l.max_coord_px
    ? null
    : `The offset is a number of pixels from -${show(l.max_coord_px)} to ${show(l.max_coord_px)}, not ${Number.isNaN(v) ? 'that' : show(v)}.`;
}

/** The coordinates a point may have: the least and the most x and y. */
export type Box = [lo: Pt, hi: Pt];

const EVERYWHERE: Box = [[-Infinity, -Infinity], [Infinity, Infinity]];

/** `box` less what lies farther than `m` from `q` on either axis. */
function within([lo, hi]: Box, q: Pt, m: number): Box {
  return [[Math.max(lo[0], q[0] - m), Math.max(lo[1], q[1] - m)], [Math.min(hi[0], q[0] + m), Math.min(hi[1], q[1] + m)]];
}

/**
 * Where the points of feature `id` may be: within ±`max_coord_px` in the frame and in the
 * pixels of every layer it moves (a layer at offset `o` solves a point `p` at `p − o`), so
 * that the scene renders. Empty (its least past its most) only where two layers that move
 * it are placed more than twice that apart.
 */
export function featureBox(doc: SceneDoc, id: string, l: Limits): Box {
  const offsets = doc.layers.filter((layer) => !layer.features || layer.features.includes(id)).map((layer): Pt => layer.offset ?? [0, 0]);
  return [[0, 0] as Pt, ...offsets].reduce((box, o) => within(box, o, l.max_coord_px), EVERYWHERE);
}

/**
 * Where the offset of layer `index` may be: within ±`max_coord_px`, and near enough every
 * point of the features the layer moves (at rest and in each key) that each stays within
 * that in the layer's pixels.
 */
export function offsetBox(doc: SceneDoc, index: number, l: Limits): Box {
  const points = layerFeatures(doc, doc.layers[index]).flatMap((f) => [f.rest, ...(f.keys ?? []).map((k) => k.points)]).flat();
  return [[0, 0] as Pt, ...points].reduce((box, q) => within(box, q, l.max_coord_px), EVERYWHERE);
}

/** `p` held to `box` (a point or an offset dragged far out). */
export function clampPoint(p: Pt, [lo, hi]: Box): Pt {
  return [Math.min(hi[0], Math.max(lo[0], p[0])), Math.min(hi[1], Math.max(lo[1], p[1]))];
}

/**
 * `delta` shortened, on each axis, so that every one of `points` moved by it stays in
 * `box`: a feature (or the points picked) dragged far out stops whole at its edge, its
 * shape kept.
 */
export function clampMove(points: Pt[], delta: Pt, [lo, hi]: Box): Pt {
  const axis = (k: 0 | 1) => points.reduce((d, p) => Math.min(hi[k] - p[k], Math.max(lo[k] - p[k], d)), delta[k]);
  return [axis(0), axis(1)];
}

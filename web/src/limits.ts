// The scene format's ranges, as the editor's fields hold typed values to them: a value a
// field takes is one a scene file may hold, so the work kept in the browser (and a saved
// file) always opens again. The numbers are the engine's own (`Engine.limits`, from
// inkwarp_core::limits), never a second copy here.

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

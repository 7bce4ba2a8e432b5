// Probes: the full-resolution solve of a pose the pointer is about to make, when it rests or
// presses on a control point in pose mode (see `App.probe`).

import type { SolveFeature } from './engine';
import type { Pt } from './scene';

/**
 * How far (pixels, in x and in y) a probe moves what the pointer rests on. The thin plate
 * is linear in the pose, so any drag of that control point is a combination of the pose
 * before and the probe; a step of this size keeps the combination's weights moderate for
 * drags of a few dozen pixels (the warm-start history distrusts wild extrapolations).
 */
export const PROBE_PX = 24;

/**
 * The tolerance (pixels) a probe is solved to: it only has to bring the drag's first start
 * close, which then solves to the scene's own tolerance; a few cycles fewer than 0.01.
 */
export const PROBE_TOLERANCE_PX = 0.05;

/** How long (ms) the pointer rests on a control point before its probe is asked for. */
export const PROBE_DWELL_MS = 40;

/**
 * `features` with feature `id`'s control point `point` (every control point when null: the
 * whole feature, as a drag on its line moves it) moved by `d` pixels in x and in y; null
 * when no feature has that id.
 */
export function probedFeatures(features: SolveFeature[], id: string, point: number | null, d = PROBE_PX): SolveFeature[] | null {
  const k = features.findIndex((f) => f.id === id);
  if (k < 0) return null;
  const f = features[k];
  const pose = f.pose.map((q, i): Pt => (point === null || i === point ? [q[0] + d, q[1] + d] : [q[0], q[1]]));
  return features.map((g, i) => (i === k ? { ...g, pose } : g));
}

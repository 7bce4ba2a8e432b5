// The scene document: exactly the JSON that `inkwarp render` reads (DESIGN §8).
//
// The editor keeps the document as plain JSON and updates it immutably (every edit makes a
// new object along the changed path), so undo is a stack of references and unknown fields
// written by other tools survive a round trip.

export type Pt = [number, number];
export type Kind = 'point' | 'polyline' | 'spline' | 'region' | 'cut';
export type Interpolation = 'smooth' | 'linear' | 'hold' | 'ease-in' | 'ease-out' | 'ease-in-out';

export const KINDS: readonly Kind[] = ['point', 'polyline', 'spline', 'region', 'cut'];
export const INTERPOLATIONS: readonly Interpolation[] = ['smooth', 'linear', 'hold', 'ease-in', 'ease-out', 'ease-in-out'];

/**
 * The fraction of the way from a key to the next at the fraction `u` of the time between
 * them, for the spans that move along the straight line (the engine's
 * `Interpolation::progress`); null for smooth and hold.
 */
export function easedProgress(mode: Interpolation, u: number): number | null {
  switch (mode) {
    case 'linear':
      return u;
    case 'ease-in':
      return u * u;
    case 'ease-out':
      return 1 - (1 - u) * (1 - u);
    case 'ease-in-out':
      return u * u * (3 - 2 * u);
    default:
      return null;
  }
}

/** A straight span's speed at its start and end as multiples of its average speed. */
function endSpeeds(mode: Interpolation): [number, number] {
  switch (mode) {
    case 'linear':
      return [1, 1];
    case 'ease-in':
      return [0, 2];
    case 'ease-out':
      return [2, 0];
    default:
      return [0, 0];
  }
}
export const METHODS = ['tps', 'tps-exact', 'triangulation', 'beier-neely'] as const;
export type Method = (typeof METHODS)[number];

/** What each method is and what it makes of holes and cuts (DESIGN §6), for the UI. */
export const METHOD_NOTES: Record<Method, string> = {
  tps: 'tps: the grid thin plate of the paper. Holes in the continuity matte and cuts tear the surface.',
  'tps-exact':
    'tps-exact: the continuous thin-plate spline fitted to the samples. It ignores the continuity matte and cuts: the surface stays whole across holes.',
  triangulation:
    'triangulation: piecewise linear over a Delaunay triangulation of the samples and the image corners (held still). It ignores the continuity matte and cuts.',
  'beier-neely':
    'beier-neely: Beier–Neely line pairs along polylines, splines and region outlines, Shepard weights for points (weights a, b, p in the scene’s solver.beier_neely). It ignores the continuity matte and cuts.',
};

export interface Key {
  t: number;
  points: Pt[];
  /** How the feature moves from this key to the next (default smooth). */
  interpolation?: Interpolation;
  [extra: string]: unknown;
}

export interface Feature {
  id: string;
  kind: Kind;
  rest: Pt[];
  closed?: boolean;
  /** Regions only: the outline is a spline through the control points. */
  curve?: 'polyline' | 'spline';
  keys?: Key[];
  [extra: string]: unknown;
}

export interface Solver {
  method?: Method;
  tension?: number;
  tolerance?: number;
  grid_step?: number;
  max_cycles?: number;
  scheme?: 'multigrid' | 'southwell';
  /** Beier–Neely's weights (`beier-neely`). */
  beier_neely?: { a?: number; b?: number; p?: number };
  /** At most this many samples fitted (`tps-exact`). */
  tps_exact?: { max_samples?: number };
  [extra: string]: unknown;
}

export interface Layer {
  name: string;
  /** The picture; a layer without one draws nothing. */
  image?: string;
  alpha?: string;
  continuity?: string;
  offset?: Pt;
  /** `hold` keeps the layer's outer edge still (default `free`). */
  border?: 'free' | 'hold';
  /** The features that drive this layer (default: all). */
  features?: string[];
  solver?: Solver;
  [extra: string]: unknown;
}

export interface SceneDoc {
  inkwarp: 1;
  width: number;
  height: number;
  fps: number;
  duration: number;
  background?: [number, number, number, number];
  solver?: Solver;
  layers: Layer[];
  features: Feature[];
  [extra: string]: unknown;
}

/** The solver settings of a layer: the scene's, with the layer's overrides. */
export function layerSolver(doc: SceneDoc, layer: Layer): Solver {
  return { ...(doc.solver ?? {}), ...(layer.solver ?? {}) };
}

/** The method that computes a layer's field (the layer's override, else the scene's). */
export function layerMethod(doc: SceneDoc, layer: Layer): Method {
  return layerSolver(doc, layer).method ?? 'tps';
}

/** Minimum number of control points for a kind (the engine's own rule). */
export function minPoints(kind: Kind, closed = false): number {
  if (kind === 'point') return 1;
  if (kind === 'region') return 3;
  return closed ? 3 : 2;
}

/** Whether a feature's outline is closed (regions always are). */
export function isClosed(f: Feature): boolean {
  return f.kind === 'region' || !!f.closed;
}

/** A new empty scene of the given size. */
export function emptyScene(width: number, height: number): SceneDoc {
  return {
    inkwarp: 1,
    width,
    height,
    fps: 24,
    duration: 2,
    background: [255, 255, 255, 255],
    solver: { method: 'tps', tension: 0, tolerance: 0.01, grid_step: 1 },
    layers: [],
    features: [],
  };
}

/** The features that drive a layer, in document order. */
export function layerFeatures(doc: SceneDoc, layer: Layer): Feature[] {
  if (!layer.features) return doc.features;
  const wanted = new Set(layer.features);
  return doc.features.filter((f) => wanted.has(f.id));
}

/**
 * Points of the frame in the pixels of `layer`: the drawing is traced over the frame, and a
 * layer placed at `offset` reads it at `p − offset` (the displacements are the same).
 */
export function toLayer(layer: Layer): (pts: Pt[]) => Pt[] {
  const [dx, dy] = layer.offset ?? [0, 0];
  return dx === 0 && dy === 0 ? (pts) => pts : (pts) => pts.map(([x, y]) => [x - dx, y - dy] as Pt);
}

/** A fresh feature id of the form `<kind><n>`. */
export function freshId(doc: SceneDoc, kind: Kind): string {
  const used = new Set(doc.features.map((f) => f.id));
  for (let n = 1; ; n++) {
    const id = `${kind}${n}`;
    if (!used.has(id)) return id;
  }
}

/** Keys sorted by time (the document keeps them sorted; this does not trust it). */
export function sortedKeys(f: Feature): Key[] {
  return [...(f.keys ?? [])].sort((a, b) => a.t - b.t);
}

/** The number of frames of the animation: `ceil(duration × fps)`, as the engine counts. */
export function frameCount(doc: SceneDoc): number {
  return Math.max(1, Math.ceil(doc.duration * doc.fps - 1e-9));
}

/**
 * `frames` (frame numbers, any order, none twice) as runs of consecutive frames, `[first,
 * last]`, in order: a few runs tell which of a scene's frames (up to 1e8) are in a set that
 * is itself small, such as the frames solved for playback.
 */
export function frameRuns(frames: Iterable<number>): [number, number][] {
  const runs: [number, number][] = [];
  for (const f of [...frames].sort((a, b) => a - b)) {
    const last = runs.at(-1);
    if (last && f === last[1] + 1) last[1] = f;
    else runs.push([f, f]);
  }
  return runs;
}

const lerp = (a: Pt, b: Pt, s: number): Pt => [a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s];

/**
 * The control points of a feature at time `t`, exactly as the engine's `anim::points_at`
 * computes them (a test holds the two together): rest without keys; the first key at or
 * before its time, the last at or after its time; between two keys the interpolation of
 * the earlier key — `hold`; `linear`, `ease-in`, `ease-out`, `ease-in-out` along the
 * straight line with the timing of `easedProgress`; or `smooth`: a cubic Hermite span
 * whose velocity at each end key comes from the span on that key's other side (zero beside
 * a hold or at the first/last key, that span's own velocity there beside a straight one,
 * and beside a smooth one the derivative of the parabola through the key and its two
 * neighbours).
 */
export function pointsAt(f: Feature, t: number): Pt[] {
  const keys = sortedKeys(f);
  const copy = (pts: Pt[]) => pts.map((p) => [p[0], p[1]] as Pt);
  if (keys.length === 0) return copy(f.rest);
  const first = keys[0];
  const last = keys[keys.length - 1];
  if (Number.isNaN(t) || t <= first.t) return copy(first.points);
  if (t >= last.t) return copy(last.points);
  let i = 0;
  while (keys[i + 1].t <= t) i++;
  const a = keys[i];
  const b = keys[i + 1];
  if (t === a.t) return copy(a.points);
  const duration = b.t - a.t;
  const u = (t - a.t) / duration;
  const n = Math.min(a.points.length, b.points.length);
  const mode = a.interpolation ?? 'smooth';
  if (mode === 'hold') return copy(a.points);
  const w = easedProgress(mode, u);
  if (w !== null) return a.points.slice(0, n).map((p, j) => lerp(p, b.points[j], w));
  const u2 = u * u;
  const u3 = u2 * u;
  const h00 = 2 * u3 - 3 * u2 + 1;
  const h10 = u3 - 2 * u2 + u;
  const h01 = -2 * u3 + 3 * u2;
  const h11 = u3 - u2;
  const out: Pt[] = [];
  for (let j = 0; j < n; j++) {
    const m0 = velocity(keys, i, j, 'before');
    const m1 = velocity(keys, i + 1, j, 'after');
    const p0 = a.points[j];
    const p1 = b.points[j];
    out.push([
      h00 * p0[0] + h10 * duration * m0[0] + h01 * p1[0] + h11 * duration * m1[0],
      h00 * p0[1] + h10 * duration * m0[1] + h01 * p1[1] + h11 * duration * m1[1],
    ]);
  }
  return out;
}

function slope(a: Key, b: Key, j: number): Pt {
  const dt = b.t - a.t;
  return [(b.points[j][0] - a.points[j][0]) / dt, (b.points[j][1] - a.points[j][1]) / dt];
}

/** The velocity of control point `j` at key `k` for a smooth span before or after it. */
function velocity(keys: Key[], k: number, j: number, side: 'before' | 'after'): Pt {
  // The span on the key's other side: its start key.
  const s = side === 'before' ? (k >= 1 ? k - 1 : -1) : k + 1 < keys.length ? k : -1;
  if (s < 0) return [0, 0];
  const mode = keys[s].interpolation ?? 'smooth';
  if (mode === 'hold') return [0, 0];
  if (mode !== 'smooth') {
    const [start, end] = endSpeeds(mode);
    const factor = side === 'before' ? end : start;
    const v = slope(keys[s], keys[s + 1], j);
    return [factor * v[0], factor * v[1]];
  }
  const prev = keys[k - 1];
  const key = keys[k];
  const next = keys[k + 1];
  const dm = key.t - prev.t;
  const dp = next.t - key.t;
  const vm = slope(prev, key, j);
  const vp = slope(key, next, j);
  return [(dp * vm[0] + dm * vp[0]) / (dm + dp), (dp * vm[1] + dm * vp[1]) / (dm + dp)];
}

/** Parses scene JSON text; throws `SceneFileError` with a JSON path on structural errors. */
export class SceneFileError extends Error {
  constructor(
    message: string,
    readonly path: string = '',
  ) {
    super(path ? `${path}: ${message}` : message);
    this.name = 'SceneFileError';
  }
}

function isPt(v: unknown): v is Pt {
  return Array.isArray(v) && v.length === 2 && v.every((x) => typeof x === 'number' && Number.isFinite(x));
}

function checkPoints(v: unknown, path: string): void {
  if (!Array.isArray(v)) throw new SceneFileError('expected a list of [x, y] points.', path);
  v.forEach((p, i) => {
    if (!isPt(p)) throw new SceneFileError('expected a point [x, y] of two finite numbers.', `${path}[${i}]`);
  });
}

/**
 * A quick structural check of a scene so the editor can load it; the engine's validation
 * (run on the same document) is the authority and reports everything else.
 */
export function parseScene(text: string): SceneDoc {
  let raw: unknown;
  try {
    raw = JSON.parse(text);
  } catch (err) {
    throw new SceneFileError(`This is not a JSON file (${(err as Error).message}).`);
  }
  if (typeof raw !== 'object' || raw === null || Array.isArray(raw)) {
    throw new SceneFileError('A scene is a JSON object with "inkwarp": 1, a size, layers and features.');
  }
  const doc = raw as Record<string, unknown>;
  if (doc.inkwarp !== 1) throw new SceneFileError('expected 1 (the scene format version).', 'inkwarp');
  for (const k of ['width', 'height'] as const) {
    const v = doc[k];
    if (v === undefined) {
      doc[k] = 0; // the first layer image's size, filled in by the editor
    } else if (typeof v !== 'number' || !Number.isInteger(v) || v < 1) {
      throw new SceneFileError('expected a positive whole number of pixels.', k);
    }
  }
  if (doc.fps === undefined) doc.fps = 24;
  if (typeof doc.fps !== 'number' || !(doc.fps > 0)) throw new SceneFileError('expected a positive number.', 'fps');
  if (doc.duration !== undefined && (typeof doc.duration !== 'number' || !(doc.duration > 0))) {
    throw new SceneFileError('expected a number of seconds > 0.', 'duration');
  }
  if (!Array.isArray(doc.layers)) throw new SceneFileError('expected a list of layers.', 'layers');
  doc.layers.forEach((l: unknown, i: number) => {
    if (typeof l !== 'object' || l === null) throw new SceneFileError('expected a layer object.', `layers[${i}]`);
    const layer = l as Record<string, unknown>;
    if (layer.image !== undefined && typeof layer.image !== 'string') throw new SceneFileError('expected an image (path or data: URI).', `layers[${i}].image`);
    if (typeof layer.name !== 'string') layer.name = `layer${i + 1}`;
  });
  if (doc.features === undefined) doc.features = [];
  if (!Array.isArray(doc.features)) throw new SceneFileError('expected a list of features.', 'features');
  doc.features.forEach((f: unknown, i: number) => {
    const path = `features[${i}]`;
    if (typeof f !== 'object' || f === null) throw new SceneFileError('expected a feature object.', path);
    const feat = f as Record<string, unknown>;
    if (typeof feat.id !== 'string') throw new SceneFileError('expected a string id.', `${path}.id`);
    if (!KINDS.includes(feat.kind as Kind)) {
      throw new SceneFileError(`unknown kind ${JSON.stringify(feat.kind)}; use one of ${KINDS.join(', ')}.`, `${path}.kind`);
    }
    checkPoints(feat.rest, `${path}.rest`);
    const n = (feat.rest as Pt[]).length;
    if (feat.keys !== undefined) {
      if (!Array.isArray(feat.keys)) throw new SceneFileError('expected a list of keys.', `${path}.keys`);
      feat.keys.forEach((k: unknown, j: number) => {
        const kp = `${path}.keys[${j}]`;
        const key = k as Record<string, unknown>;
        if (typeof key?.t !== 'number' || !Number.isFinite(key.t)) throw new SceneFileError('expected a time in seconds.', `${kp}.t`);
        checkPoints(key.points, `${kp}.points`);
        if ((key.points as Pt[]).length !== n) {
          throw new SceneFileError(`has ${(key.points as Pt[]).length} points but the rest drawing has ${n}; a key moves the same control points.`, `${kp}.points`);
        }
      });
    }
  });
  if (doc.duration === undefined) {
    // The engine's default: up to and including the last key.
    const feats = doc.features as Feature[];
    const last = Math.max(0, ...feats.flatMap((f) => (f.keys ?? []).map((k) => k.t)));
    doc.duration = last + 1 / (doc.fps as number);
  }
  return doc as unknown as SceneDoc;
}

/** The scene as the JSON text the editor saves. */
export function serializeScene(doc: SceneDoc): string {
  // Drawing coordinates to a millionth of a pixel: a point dragged by a fraction is saved
  // as 10.622, not 10.622000000000002.
  const points = (pts: Pt[]) => pts.map(([x, y]) => [Math.round(x * 1e6) / 1e6, Math.round(y * 1e6) / 1e6]);
  const features = doc.features.map((f) => ({
    ...f,
    rest: points(f.rest),
    ...(f.keys ? { keys: f.keys.map((k) => ({ ...k, points: points(k.points) })) } : {}),
  }));
  return JSON.stringify({ ...doc, features }, null, 1);
}

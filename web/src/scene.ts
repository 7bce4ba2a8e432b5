// The scene document: exactly the JSON that `inkwarp render` reads (DESIGN §8).
//
// The editor keeps the document as plain JSON and updates it immutably (every edit makes a
// new object along the changed path), so undo is a stack of references and unknown fields
// written by other tools survive a round trip.

export type Pt = [number, number];
export type Kind = 'point' | 'polyline' | 'spline' | 'region' | 'cut';
export type Interpolation = 'smooth' | 'linear' | 'hold';

export const KINDS: readonly Kind[] = ['point', 'polyline', 'spline', 'region', 'cut'];
export const INTERPOLATIONS: readonly Interpolation[] = ['smooth', 'linear', 'hold'];
export const METHODS = ['tps', 'tps-exact', 'triangulation', 'beier-neely'] as const;
export type Method = (typeof METHODS)[number];

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
  [extra: string]: unknown;
}

export interface Layer {
  name: string;
  image: string;
  alpha?: string;
  continuity?: string;
  offset?: Pt;
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

/** The number of frames of the animation. */
export function frameCount(doc: SceneDoc): number {
  return Math.max(1, Math.round(doc.duration * doc.fps));
}

const lerp = (a: Pt, b: Pt, s: number): Pt => [a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s];

/**
 * The control points of a feature at time `t` (DESIGN §3 "Time"): rest without keys,
 * the first key before it, the last after it, and between two keys the interpolation of
 * the earlier key: `hold`, `linear`, or `smooth` — a cubic Hermite curve in time whose
 * tangents are the Catmull-Rom ones over the neighbouring keys' times (one-sided at the
 * ends), so the motion is C¹ through every smooth key.
 */
export function pointsAt(f: Feature, t: number): Pt[] {
  const keys = sortedKeys(f);
  if (keys.length === 0) return f.rest.map((p) => [p[0], p[1]]);
  if (t <= keys[0].t) return keys[0].points.map((p) => [p[0], p[1]]);
  const last = keys[keys.length - 1];
  if (t >= last.t) return last.points.map((p) => [p[0], p[1]]);
  let i = 0;
  while (keys[i + 1].t <= t) i++;
  const k0 = keys[i];
  const k1 = keys[i + 1];
  const s = (t - k0.t) / (k1.t - k0.t);
  const mode = k0.interpolation ?? 'smooth';
  if (mode === 'hold') return k0.points.map((p) => [p[0], p[1]]);
  if (mode === 'linear') return k0.points.map((p, j) => lerp(p, k1.points[j], s));
  const km = keys[i - 1];
  const kp = keys[i + 2];
  const dt = k1.t - k0.t;
  const h00 = 2 * s ** 3 - 3 * s ** 2 + 1;
  const h10 = s ** 3 - 2 * s ** 2 + s;
  const h01 = -2 * s ** 3 + 3 * s ** 2;
  const h11 = s ** 3 - s ** 2;
  return k0.points.map((p0, j) => {
    const p1 = k1.points[j];
    const out: Pt = [0, 0];
    for (let c = 0; c < 2; c++) {
      const m0 = km ? (p1[c] - km.points[j][c]) / (k1.t - km.t) : (p1[c] - p0[c]) / dt;
      const m1 = kp ? (kp.points[j][c] - p0[c]) / (kp.t - k0.t) : (p1[c] - p0[c]) / dt;
      out[c] = h00 * p0[c] + h10 * dt * m0 + h01 * p1[c] + h11 * dt * m1;
    }
    return out;
  });
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
    if (typeof v !== 'number' || !Number.isInteger(v) || v < 1) {
      throw new SceneFileError('expected a positive whole number of pixels.', k);
    }
  }
  if (doc.fps === undefined) doc.fps = 24;
  if (doc.duration === undefined) doc.duration = 2;
  if (typeof doc.fps !== 'number' || !(doc.fps > 0)) throw new SceneFileError('expected a positive number.', 'fps');
  if (typeof doc.duration !== 'number' || !(doc.duration >= 0)) {
    throw new SceneFileError('expected a number of seconds ≥ 0.', 'duration');
  }
  if (!Array.isArray(doc.layers)) throw new SceneFileError('expected a list of layers.', 'layers');
  doc.layers.forEach((l: unknown, i: number) => {
    if (typeof l !== 'object' || l === null) throw new SceneFileError('expected a layer object.', `layers[${i}]`);
    const layer = l as Record<string, unknown>;
    if (typeof layer.image !== 'string') throw new SceneFileError('expected an image (path or data: URI).', `layers[${i}].image`);
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
  return doc as unknown as SceneDoc;
}

/** The scene as the JSON text the editor saves. */
export function serializeScene(doc: SceneDoc): string {
  return JSON.stringify(doc, null, 1);
}

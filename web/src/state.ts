// The editor's state: the scene document, what the user is doing with it, and undo.
//
// Edits are pure functions `SceneDoc -> SceneDoc` (unit-tested without a browser); the
// `Store` applies them, keeps the undo history and tells the views.

import {
  type Feature,
  type Interpolation,
  type Key,
  type Kind,
  type Layer,
  type Method,
  type Pt,
  type SceneDoc,
  freshId,
  minPoints,
  pointsAt,
  sortedKeys,
} from './scene';

export type Mode = 'rest' | 'pose';
export type Tool = 'select' | Kind;
export type Heat = 'off' | 'dx' | 'dy';

/** Two key times closer than this are the same key (well under a frame at 1000 fps). */
export const KEY_EPS = 1e-4;

/**
 * A key's time to the nanosecond: times summed in floating point (fifteen frame steps of
 * 1/30 s make 0.49999999999999994) reach the scene file as 0.5.
 */
const tidyTime = (t: number): number => Math.round(t * 1e9) / 1e9;

export interface Selection {
  feature: string | null;
  /** A control point of the selected feature, or null for the whole feature. */
  point: number | null;
}

/** A key of a feature, by time. */
export interface KeyRef {
  feature: string;
  t: number;
}

/** Copied keys: each at `dt` seconds after the earliest one copied. */
export interface ClipKey {
  feature: string;
  dt: number;
  points: Pt[];
  interpolation?: Interpolation;
}

/** A control point: point `point` of feature `feature`. */
export interface PointRef {
  feature: string;
  point: number;
}

export interface View {
  /** The control points picked by a marquee or Shift-click: they move together. */
  pointSelection: PointRef[];
  /** The keys picked on the timeline (Shift-click adds and removes). */
  keySelection: KeyRef[];
  /** Show the selected feature's drawing at its previous and next keys (pose mode). */
  onion: boolean;
  mode: Mode;
  tool: Tool;
  time: number;
  selection: Selection;
  activeLayer: number;
  /** Points placed so far by a drawing tool (not yet a feature). */
  draft: Pt[];
  /** Names of the layers hidden in the view (not saved: every layer renders). */
  hidden: string[];
  overlays: { drawing: boolean; heat: Heat; mesh: boolean; matte: boolean };
  snap: boolean;
  playing: boolean;
}

export function initialView(): View {
  return {
    pointSelection: [],
    keySelection: [],
    onion: true,
    mode: 'rest',
    tool: 'select',
    time: 0,
    selection: { feature: null, point: null },
    activeLayer: 0,
    draft: [],
    hidden: [],
    overlays: { drawing: true, heat: 'off', mesh: false, matte: false },
    snap: false,
    playing: false,
  };
}

// ---------------------------------------------------------------------------------------
// Pure edits of the document.

function mapFeature(doc: SceneDoc, id: string, fn: (f: Feature) => Feature): SceneDoc {
  let found = false;
  const features = doc.features.map((f) => {
    if (f.id !== id) return f;
    found = true;
    return fn(f);
  });
  if (!found) throw new Error(`There is no feature ${id}.`);
  return { ...doc, features };
}

export function getFeature(doc: SceneDoc, id: string | null): Feature | undefined {
  return id === null ? undefined : doc.features.find((f) => f.id === id);
}

/**
 * Adds a feature traced in rest mode. When the layer lists its features explicitly the new
 * one is added to that list so it drives the layer it was drawn on.
 */
export function addFeature(
  doc: SceneDoc,
  kind: Kind,
  points: Pt[],
  opts: { closed?: boolean; curve?: 'polyline' | 'spline'; layer?: number; id?: string } = {},
): { doc: SceneDoc; id: string } {
  const closed = kind === 'region' ? undefined : opts.closed || undefined;
  if (points.length < minPoints(kind, !!closed)) {
    throw new Error(`A ${kind} needs at least ${minPoints(kind, !!closed)} points.`);
  }
  const flat = flatness(points);
  if (points.length > 1 && flat.spread < 1e-6) {
    const [x, y] = points[0];
    throw new Error(`The ${kind}'s ${points.length} points are all at one place (${+x.toFixed(2)}, ${+y.toFixed(2)}): click them apart along what it traces, or Escape to drop it.`);
  }
  if (kind === 'region' && flat.off < 1e-6) {
    throw new Error(`A region needs an area, and its ${points.length} points lie on one line: add a point off that line (trace around what it should hold), or Escape to drop it.`);
  }
  const id = opts.id ?? freshId(doc, kind);
  const feature: Feature = { id, kind, rest: points.map((p) => [p[0], p[1]] as Pt) };
  if (closed) feature.closed = true;
  if (kind === 'region' && opts.curve === 'spline') feature.curve = 'spline';
  let layers = doc.layers;
  if (opts.layer !== undefined && doc.layers[opts.layer]?.features) {
    layers = doc.layers.map((l, i) => (i === opts.layer ? { ...l, features: [...(l.features ?? []), id] } : l));
  }
  return { doc: { ...doc, layers, features: [...doc.features, feature] }, id };
}

/**
 * How far apart `points` are (`spread`: the largest distance from the first) and how far
 * the farthest lies off the line through the first and the one farthest from it (`off`).
 */
export function flatness(points: Pt[]): { spread: number; off: number } {
  const [x0, y0] = points[0] ?? [0, 0];
  let far: Pt = [x0, y0];
  let spread = 0;
  for (const p of points) {
    const d = Math.hypot(p[0] - x0, p[1] - y0);
    if (d > spread) [spread, far] = [d, p];
  }
  let off = 0;
  if (spread > 0) {
    const [ux, uy] = [(far[0] - x0) / spread, (far[1] - y0) / spread];
    for (const p of points) off = Math.max(off, Math.abs((p[0] - x0) * uy - (p[1] - y0) * ux));
  }
  return { spread, off };
}

/** Removes a feature and its mentions in layers. */
export function deleteFeature(doc: SceneDoc, id: string): SceneDoc {
  return {
    ...doc,
    features: doc.features.filter((f) => f.id !== id),
    layers: doc.layers.map((l) => (l.features ? { ...l, features: l.features.filter((x) => x !== id) } : l)),
  };
}

/** Removes one control point (rest and every key), keeping the kind's minimum. */
export function deletePoint(doc: SceneDoc, id: string, index: number): SceneDoc {
  return mapFeature(doc, id, (f) => {
    if (f.rest.length - 1 < minPoints(f.kind, !!f.closed)) {
      throw new Error(`A ${f.kind} needs at least ${minPoints(f.kind, !!f.closed)} points; delete the whole feature instead.`);
    }
    const drop = <T>(a: T[]) => a.filter((_, i) => i !== index);
    return { ...f, rest: drop(f.rest), keys: f.keys?.map((k) => ({ ...k, points: drop(k.points) })) };
  });
}

/** The index of the key at time `t` (within KEY_EPS), or -1. */
export function keyIndexAt(f: Feature, t: number): number {
  return (f.keys ?? []).findIndex((k) => Math.abs(k.t - t) < KEY_EPS);
}

/** The feature with `keys`, sorted, their times tidied (every key's write goes through here). */
function withKeys(f: Feature, keys: Key[]): Feature {
  const sorted = keys.map((k) => ({ ...k, t: tidyTime(k.t) })).sort((a, b) => a.t - b.t);
  const out: Feature = { ...f, keys: sorted };
  if (sorted.length === 0) delete out.keys;
  return out;
}

/** Sets (or adds) the key of a feature at time `t` with the given points. */
export function setKey(doc: SceneDoc, id: string, t: number, points: Pt[]): SceneDoc {
  return mapFeature(doc, id, (f) => {
    if (f.kind === 'cut') throw new Error(CUT_HAS_NO_KEYS(id));
    if (points.length !== f.rest.length) throw new Error(`A key of ${id} needs ${f.rest.length} points.`);
    const keys = [...(f.keys ?? [])];
    const i = keyIndexAt(f, t);
    const pts = points.map((p) => [p[0], p[1]] as Pt);
    if (i >= 0) keys[i] = { ...keys[i], points: pts };
    else keys.push({ t, points: pts });
    return withKeys(f, keys);
  });
}

/** Why a cut cannot be posed or keyed (the scene format refuses a cut with keys). */
export const CUT_HAS_NO_KEYS = (id: string) =>
  `${id} is a cut: it moves nothing (it tears the picture along its line), so it has no keys; change its line in rest mode (R).`;

/** Adds a key at `t` holding the feature where it is now (no-op if one is there). */
export function addKeyHere(doc: SceneDoc, id: string, t: number): SceneDoc {
  const f = getFeature(doc, id);
  if (!f || keyIndexAt(f, t) >= 0) return doc;
  return setKey(doc, id, t, pointsAt(f, t));
}

/**
 * Whether a feature's keys hold one pose at every time although it was keyed away from the
 * start: a single key, after 0 s (a single key poses the feature at every time, 0 s too).
 */
export function heldFromOneLateKey(f: Feature): boolean {
  return f.kind !== 'cut' && f.keys?.length === 1 && f.keys[0].t >= KEY_EPS;
}

/** Adds a key at 0 s holding the feature's rest points (no-op if one is there): it then moves from rest. */
export function keyRestAtStart(doc: SceneDoc, id: string): SceneDoc {
  const f = getFeature(doc, id);
  if (!f || keyIndexAt(f, 0) >= 0) return doc;
  return setKey(doc, id, 0, f.rest);
}

/** Deletes the key of a feature at time `t` (no-op without one). */
export function deleteKey(doc: SceneDoc, id: string, t: number): SceneDoc {
  return mapFeature(doc, id, (f) => {
    const i = keyIndexAt(f, t);
    if (i < 0) return f;
    return withKeys(f, (f.keys ?? []).filter((_, j) => j !== i));
  });
}

/** Moves a key from time `from` to time `to`; refuses to land on another key. */
export function moveKey(doc: SceneDoc, id: string, from: number, to: number): SceneDoc {
  return mapFeature(doc, id, (f) => {
    const i = keyIndexAt(f, from);
    if (i < 0) throw new Error(`${id} has no key at ${from.toFixed(3)} s.`);
    const t = Math.max(0, to);
    if (t > doc.duration + KEY_EPS) {
      throw new Error(`${t.toFixed(3)} s is past the end of the animation (${doc.duration} s); lengthen the duration first.`);
    }
    const j = keyIndexAt(f, t);
    if (j >= 0 && j !== i) throw new Error(`${id} already has a key at ${t.toFixed(3)} s.`);
    const keys = (f.keys ?? []).map((k, n) => (n === i ? { ...k, t } : k));
    return withKeys(f, keys);
  });
}

/** Whether `refs` holds the key `ref`. */
export function hasKeyRef(refs: KeyRef[], ref: KeyRef): boolean {
  return refs.some((r) => r.feature === ref.feature && Math.abs(r.t - ref.t) < KEY_EPS);
}

/** `refs` with `ref` added, or removed when it is there (Shift-click). */
export function toggleKeyRef(refs: KeyRef[], ref: KeyRef): KeyRef[] {
  return hasKeyRef(refs, ref) ? refs.filter((r) => !(r.feature === ref.feature && Math.abs(r.t - ref.t) < KEY_EPS)) : [...refs, ref];
}

/**
 * Moves every key of `refs` by `dt` seconds together: all or none. Refused (an error that
 * says why) when a key would leave the animation (`0 … duration`) or land on a key that
 * is not moving.
 */
export function moveKeys(doc: SceneDoc, refs: KeyRef[], dt: number): SceneDoc {
  if (dt === 0 || refs.length === 0) return doc;
  let out = doc;
  const byFeature = new Map<string, number[]>();
  for (const r of refs) byFeature.set(r.feature, [...(byFeature.get(r.feature) ?? []), r.t]);
  for (const [id, times] of byFeature) {
    out = mapFeature(out, id, (f) => {
      const moving = new Set<number>();
      for (const t of times) {
        const i = keyIndexAt(f, t);
        if (i < 0) throw new Error(`${id} has no key at ${t.toFixed(3)} s.`);
        moving.add(i);
      }
      const keys = (f.keys ?? []).map((k, i) => {
        if (!moving.has(i)) return k;
        const t = k.t + dt;
        if (t < -KEY_EPS || t > doc.duration + KEY_EPS) {
          throw new Error(`The keys would leave the animation (0 – ${doc.duration} s); ${id}'s key would be at ${t.toFixed(3)} s.`);
        }
        return { ...k, t: Math.min(doc.duration, Math.max(0, t)) };
      });
      keys.forEach((k, i) => {
        if (!moving.has(i)) return;
        if (keys.some((o, j) => j !== i && Math.abs(o.t - k.t) < KEY_EPS)) throw new Error(`${id} already has a key at ${k.t.toFixed(3)} s.`);
      });
      return withKeys(f, keys);
    });
  }
  return out;
}

/** The keys of `refs`, each timed from the earliest of them (for pasting elsewhere). */
export function copyKeys(doc: SceneDoc, refs: KeyRef[]): ClipKey[] {
  const found: { feature: string; key: Key }[] = [];
  for (const r of refs) {
    const f = getFeature(doc, r.feature);
    const i = f ? keyIndexAt(f, r.t) : -1;
    if (f && i >= 0) found.push({ feature: f.id, key: f.keys![i] });
  }
  if (found.length === 0) return [];
  const t0 = Math.min(...found.map((k) => k.key.t));
  return found
    .map(({ feature, key }) => {
      const clip: ClipKey = { feature, dt: key.t - t0, points: key.points.map((p) => [p[0], p[1]] as Pt) };
      if (key.interpolation) clip.interpolation = key.interpolation;
      return clip;
    })
    .sort((a, b) => a.dt - b.dt);
}

/**
 * Pastes copied keys with the earliest at time `t` (replacing keys already at those
 * times). Refused when a feature is gone or has another number of points, or when a key
 * would land past the end of the animation. Returns the document and the pasted keys.
 */
export function pasteKeys(doc: SceneDoc, clip: ClipKey[], t: number): { doc: SceneDoc; pasted: KeyRef[] } {
  let out = doc;
  const pasted: KeyRef[] = [];
  for (const c of clip) {
    const at = t + c.dt;
    if (at > doc.duration + KEY_EPS) throw new Error(`A pasted key of ${c.feature} would be at ${at.toFixed(3)} s, past the end (${doc.duration} s).`);
    const f = getFeature(out, c.feature);
    if (!f) throw new Error(`There is no feature ${c.feature} to paste its keys on.`);
    if (f.rest.length !== c.points.length) throw new Error(`${c.feature} has ${f.rest.length} points; the copied key has ${c.points.length}.`);
    out = setKey(out, c.feature, at, c.points);
    out = setInterpolation(out, c.feature, at, c.interpolation ?? 'smooth');
    pasted.push({ feature: c.feature, t: at });
  }
  return { doc: out, pasted };
}

/** The times of a feature's keys just before and just after `t` (not at it), for onion skins. */
export function neighbourKeys(f: Feature, t: number): { prev: Key | null; next: Key | null } {
  const keys = sortedKeys(f);
  let prev: Key | null = null;
  let next: Key | null = null;
  for (const k of keys) {
    if (k.t < t - KEY_EPS) prev = k;
    else if (k.t > t + KEY_EPS && !next) next = k;
  }
  return { prev, next };
}

/** Sets how the feature moves from its key at `t` to the next one. */
export function setInterpolation(doc: SceneDoc, id: string, t: number, interpolation: Interpolation): SceneDoc {
  return mapFeature(doc, id, (f) => {
    const i = keyIndexAt(f, t);
    if (i < 0) throw new Error(`${id} has no key at ${t.toFixed(3)} s.`);
    const keys = (f.keys ?? []).map((k, n) => {
      if (n !== i) return k;
      const out: Key = { ...k, interpolation };
      if (interpolation === 'smooth') delete out.interpolation;
      return out;
    });
    return withKeys(f, keys);
  });
}

/**
 * Moves control point `index` of a feature to `p`. In rest mode this retraces the rest
 * drawing (keys keep their poses); in pose mode it sets the key at `time`, creating it
 * from the current pose when there is none (auto-key).
 */
export function movePoint(doc: SceneDoc, mode: Mode, time: number, id: string, index: number, p: Pt): SceneDoc {
  const f = getFeature(doc, id);
  if (!f) throw new Error(`There is no feature ${id}.`);
  if (mode === 'rest') {
    return mapFeature(doc, id, (g) => ({ ...g, rest: g.rest.map((q, i) => (i === index ? [p[0], p[1]] : q)) }));
  }
  const pts = pointsAt(f, time);
  pts[index] = [p[0], p[1]];
  return setKey(doc, id, time, pts);
}

/** Moves a whole feature by `delta` (rest geometry, or the pose at `time`). */
export function moveFeature(doc: SceneDoc, mode: Mode, time: number, id: string, base: Pt[], delta: Pt): SceneDoc {
  const pts = base.map((q) => [q[0] + delta[0], q[1] + delta[1]] as Pt);
  if (mode === 'rest') return mapFeature(doc, id, (g) => ({ ...g, rest: pts }));
  return setKey(doc, id, time, pts);
}

/**
 * Moves several control points by `delta` together: `bases` holds each feature's points as
 * shown when the drag began, `picked` the indices moved. At rest the rest positions change;
 * in pose mode each feature gets a key at `time`.
 */
export function movePoints(doc: SceneDoc, mode: Mode, time: number, bases: Map<string, Pt[]>, picked: PointRef[], delta: Pt): SceneDoc {
  let out = doc;
  for (const [id, base] of bases) {
    const idx = new Set(picked.filter((r) => r.feature === id).map((r) => r.point));
    const pts = base.map((q, i) => (idx.has(i) ? [q[0] + delta[0], q[1] + delta[1]] as Pt : [q[0], q[1]] as Pt));
    out = mode === 'rest' ? mapFeature(out, id, (g) => ({ ...g, rest: pts })) : setKey(out, id, time, pts);
  }
  return out;
}

/** The control points inside the rectangle with corners `a` and `b` (cuts only at rest). */
export function pointsInRect(doc: SceneDoc, mode: Mode, time: number, a: Pt, b: Pt): PointRef[] {
  const [x0, x1] = [Math.min(a[0], b[0]), Math.max(a[0], b[0])];
  const [y0, y1] = [Math.min(a[1], b[1]), Math.max(a[1], b[1])];
  const out: PointRef[] = [];
  for (const f of doc.features) {
    if (mode === 'pose' && f.kind === 'cut') continue;
    shownPoints(f, mode, time).forEach((q, i) => {
      if (q[0] >= x0 && q[0] <= x1 && q[1] >= y0 && q[1] <= y1) out.push({ feature: f.id, point: i });
    });
  }
  return out;
}

export function hasPointRef(refs: PointRef[], ref: PointRef): boolean {
  return refs.some((r) => r.feature === ref.feature && r.point === ref.point);
}

/** The control points of a feature as shown in a mode at a time. */
export function shownPoints(f: Feature, mode: Mode, time: number): Pt[] {
  return mode === 'rest' ? f.rest : pointsAt(f, time);
}

export function setLayerFeatures(doc: SceneDoc, layer: number, features: string[] | undefined): SceneDoc {
  return {
    ...doc,
    layers: doc.layers.map((l, i) => {
      if (i !== layer) return l;
      const out: Layer = { ...l, features };
      if (features === undefined) delete out.features;
      return out;
    }),
  };
}

/** Moves layer `from` to index `to` (back to front order). */
export function reorderLayer(doc: SceneDoc, from: number, to: number): SceneDoc {
  const layers = [...doc.layers];
  const [l] = layers.splice(from, 1);
  layers.splice(Math.max(0, Math.min(layers.length, to)), 0, l);
  return { ...doc, layers };
}

export function updateLayer(doc: SceneDoc, index: number, patch: Partial<Layer>): SceneDoc {
  return {
    ...doc,
    layers: doc.layers.map((l, i) => {
      if (i !== index) return l;
      const out = { ...l, ...patch } as Layer;
      for (const [k, v] of Object.entries(patch)) if (v === undefined) delete out[k];
      return out;
    }),
  };
}

export function deleteLayer(doc: SceneDoc, index: number): SceneDoc {
  return { ...doc, layers: doc.layers.filter((_, i) => i !== index) };
}

export function setMethod(doc: SceneDoc, method: Method): SceneDoc {
  return { ...doc, solver: { ...(doc.solver ?? {}), method } };
}

/** Every key time of the scene, sorted and deduplicated (for the timeline ruler). */
export function allKeyTimes(doc: SceneDoc): number[] {
  const times: number[] = [];
  for (const f of doc.features) for (const k of sortedKeys(f)) if (!times.some((t) => Math.abs(t - k.t) < KEY_EPS)) times.push(k.t);
  return times.sort((a, b) => a - b);
}

// ---------------------------------------------------------------------------------------
// The store: document + view + undo.

export type Listener = (store: Store, docChanged: boolean) => void;

/**
 * Where a document came from and where Save puts it. Each opened scene gets its own (one
 * object, shared by every undo step of that scene, so a save's new version holds for all
 * of them); Undo and Redo bring a document back with its origin, so Save never writes one
 * scene into another's file.
 */
export interface Origin {
  /** The name a download takes. */
  fileName: string;
  /** The URL Save writes back to (a scene `inkwarp edit` serves), or null: Save downloads. */
  saveUrl: string | null;
  /** The file's path on the machine that serves it. */
  path: string | null;
  /** The version of that file the document was read from or last written as (its ETag). */
  version: string | null;
  /** The version another tab or program left in the file since (null: it could not be read), once noticed. */
  changedTo?: string | null;
}

/** Whether two documents hold the same values (edits share unchanged parts, so this walks only what differs). */
function same(a: unknown, b: unknown): boolean {
  if (a === b) return true;
  if (typeof a !== 'object' || typeof b !== 'object' || a === null || b === null || Array.isArray(a) !== Array.isArray(b)) return false;
  const [x, y] = [a as Record<string, unknown>, b as Record<string, unknown>];
  const keys = Object.keys(x);
  return keys.length === Object.keys(y).length && keys.every((k) => Object.prototype.hasOwnProperty.call(y, k) && same(x[k], y[k]));
}

/** A new origin: a scene Save downloads as `fileName`. */
export function downloadOrigin(fileName = 'scene.json'): Origin {
  return { fileName, saveUrl: null, path: null, version: null };
}

/** How many changes Undo goes back per scene (besides each scene an Open replaced, all kept). */
export const UNDO_STEPS = 500;

interface Step {
  doc: SceneDoc;
  origin: Origin;
  /** The document's revision, which Undo and Redo bring back with it. */
  revision: number;
}

export class Store {
  doc: SceneDoc;
  view: View;
  origin: Origin = downloadOrigin();
  private undoStack: Step[] = [];
  private redoStack: Step[] = [];
  private txBase: SceneDoc | null = null;
  private txRevision = 0;
  private listeners: Listener[] = [];
  /**
   * Names the document: a new one on every change (views compare it to know what to redo);
   * Undo and Redo bring back the revision of the document they restore, so a document
   * undone back to its saved state counts as saved again.
   */
  revision = 0;
  /** The last revision handed out: a changed document never takes an earlier one's. */
  private lastRevision = 0;
  /** The revision last saved to a file (or opened from one). */
  private savedRevision = 0;
  /** The saved revision before the last `load` (see `markUnsaved`). */
  private savedBeforeLoad = -1;

  constructor(doc: SceneDoc, view: View = initialView()) {
    this.doc = doc;
    this.view = view;
  }

  subscribe(fn: Listener): () => void {
    this.listeners.push(fn);
    return () => {
      this.listeners = this.listeners.filter((l) => l !== fn);
    };
  }

  private emit(docChanged: boolean): void {
    for (const l of this.listeners) l(this, docChanged);
  }

  /**
   * Replaces the document with a new one (undoable unless inside a transaction). One equal to
   * it (a key time typed again, a key pasted over itself) changes nothing: no undo step, not
   * marked unsaved.
   */
  apply(next: SceneDoc): void {
    if (next === this.doc || (this.txBase === null && same(next, this.doc))) return;
    if (this.txBase === null) this.pushUndo(this.doc);
    this.doc = next;
    this.revision = ++this.lastRevision;
    this.emit(true);
  }

  /** Applies an edit function; errors leave the document as it was and are rethrown. */
  edit(fn: (doc: SceneDoc) => SceneDoc): void {
    this.apply(fn(this.doc));
  }

  /** Starts a gesture (a drag): its many changes undo as one step. */
  begin(): void {
    if (this.txBase === null) [this.txBase, this.txRevision] = [this.doc, this.revision];
  }

  /** Ends a gesture. */
  commit(): void {
    const base = this.txBase;
    this.txBase = null;
    if (base !== null && base !== this.doc) {
      this.pushUndo(base, this.txRevision);
      // the gesture is now one undo step: the views show Undo as available
      this.emit(false);
    } else if (base !== null && this.revision !== this.txRevision) {
      // A drag that came back to where it started: the document it began with.
      this.revision = this.txRevision;
      this.emit(true);
    }
  }

  /** Whether the document has changed since it was last opened or saved. */
  get unsaved(): boolean {
    return this.revision !== this.savedRevision;
  }

  /** The document as it was at `revision` (default: now) has been written to its file. */
  markSaved(revision = this.revision): void {
    this.savedRevision = revision;
    this.emit(false);
  }

  /**
   * A save of the document at `revision` with origin `origin` wrote its file, which is now
   * at `version`: every step of the history on that file knows the new version, and the
   * document counts as saved if it is still that one's.
   */
  fileSaved(origin: Origin, version: string | null, revision: number): void {
    for (const o of [this.origin, ...this.undoStack.map((s) => s.origin), ...this.redoStack.map((s) => s.origin)]) {
      if (o.saveUrl === origin.saveUrl && o.path === origin.path) [o.version, o.changedTo] = [version, undefined];
    }
    if (this.origin === origin) this.markSaved(revision);
  }

  /**
   * The file the document saves to is now at `version` (null: it could not be read), written
   * by another tab or program: none of this history is what it holds, so the document counts as
   * unsaved, Undo included, until it is saved again. `origin.version` stays the one this tab
   * knew, so that save asks before it overwrites. (A saved revision of another origin on the
   * same file that is at `version`, a restore's opened file, still counts.) Returns whether this
   * is news and the document had counted as saved (what the editor then says).
   */
  fileChanged(version: string | null): boolean {
    const origin = this.origin;
    if (version === origin.version || origin.changedTo === version) return false;
    const wasSaved = !this.unsaved;
    origin.changedTo = version;
    const steps = [{ origin, revision: this.revision }, ...this.undoStack, ...this.redoStack];
    const saved = steps.find((step) => step.revision === this.savedRevision)?.origin;
    if (!saved || (saved.saveUrl === origin.saveUrl && saved.path === origin.path && saved.version !== version)) this.savedRevision = -1;
    this.emit(false);
    return wasSaved;
  }

  private pushUndo(doc: SceneDoc, base = this.revision): void {
    const steps = this.undoStack;
    steps.push({ doc, origin: this.origin, revision: base });
    if (steps.length > UNDO_STEPS) {
      // The oldest step but the last of its scene: that one is the scene an Open replaced,
      // which may be work in no file (dropped, Undo no longer reached it, without a word).
      const k = steps.findIndex((step, i) => i + 1 < steps.length && steps[i + 1].origin === step.origin);
      if (k >= 0) steps.splice(k, 1);
    }
    this.redoStack = [];
  }

  /**
   * The document as it is now is not in any file (a restored autosave): what was saved
   * before it was loaded still is, so Undo back to that counts as saved.
   */
  markUnsaved(): void {
    this.savedRevision = this.savedBeforeLoad;
    this.emit(false);
  }

  /**
   * The document now open is where the history starts: nothing before it to undo to (the
   * scene `inkwarp edit` opened, not the built-in example shown while it loaded).
   */
  startHistory(): void {
    this.undoStack = [];
    this.redoStack = [];
    this.savedBeforeLoad = -1;
    this.emit(false);
  }

  /** Abandons a gesture, restoring the document from before it. */
  cancel(): void {
    const base = this.txBase;
    this.txBase = null;
    if (base !== null && (base !== this.doc || this.revision !== this.txRevision)) {
      [this.doc, this.revision] = [base, this.txRevision];
      this.emit(true);
    }
  }

  get inGesture(): boolean {
    return this.txBase !== null;
  }

  canUndo(): boolean {
    return this.undoStack.length > 0;
  }

  canRedo(): boolean {
    return this.redoStack.length > 0;
  }

  undo(): void {
    this.commit();
    const prev = this.undoStack.pop();
    if (!prev) return;
    this.redoStack.push({ doc: this.doc, origin: this.origin, revision: this.revision });
    ({ doc: this.doc, origin: this.origin, revision: this.revision } = prev);
    this.fixSelection();
    this.emit(true);
  }

  redo(): void {
    const next = this.redoStack.pop();
    if (!next) return;
    this.undoStack.push({ doc: this.doc, origin: this.origin, revision: this.revision });
    ({ doc: this.doc, origin: this.origin, revision: this.revision } = next);
    this.fixSelection();
    this.emit(true);
  }

  /**
   * Replaces the whole document (opening a file) with its origin. Undo brings back the
   * document that was open before, with its own; the new one counts as saved.
   */
  load(doc: SceneDoc, origin: Origin = downloadOrigin()): void {
    this.commit();
    this.pushUndo(this.doc);
    this.savedBeforeLoad = this.savedRevision;
    this.doc = doc;
    this.origin = origin;
    this.view = { ...initialView(), overlays: this.view.overlays };
    this.revision = ++this.lastRevision;
    this.savedRevision = this.revision;
    this.emit(true);
  }

  /** Changes what the user is doing (not undoable). */
  setView(patch: Partial<View>): void {
    this.view = { ...this.view, ...patch };
    if (patch.tool !== undefined && patch.tool !== 'select') this.view.draft = [];
    this.emit(false);
  }

  private fixSelection(): void {
    const f = getFeature(this.doc, this.view.selection.feature);
    if (!f) this.view = { ...this.view, selection: { feature: null, point: null } };
    else if (this.view.selection.point !== null && this.view.selection.point >= f.rest.length) {
      this.view = { ...this.view, selection: { feature: f.id, point: null } };
    }
    if (this.view.activeLayer >= this.doc.layers.length) this.view = { ...this.view, activeLayer: Math.max(0, this.doc.layers.length - 1) };
    const kept = this.view.pointSelection.filter((r) => r.point < (getFeature(this.doc, r.feature)?.rest.length ?? 0));
    if (kept.length !== this.view.pointSelection.length) this.view = { ...this.view, pointSelection: kept };
  }

  // -- Tools ---------------------------------------------------------------------------

  /** A click of a drawing tool: adds a point to the draft (a point tool finishes at once). */
  placePoint(p: Pt): void {
    const tool = this.view.tool;
    if (tool === 'select') return;
    if (this.view.mode !== 'rest') throw new Error('Switch to rest mode (R) to trace new features.');
    if (tool === 'point') {
      this.finishDraft([p]);
      return;
    }
    this.setView({ draft: [...this.view.draft, [p[0], p[1]]] });
  }

  /**
   * Finishes the feature being drawn (Enter, double-click, or a click on the first point
   * which closes a polyline or spline). Too few points: the draft is kept and an error thrown.
   */
  finishDraft(points: Pt[] = this.view.draft, closed = false): string | null {
    const tool = this.view.tool;
    if (tool === 'select' || points.length === 0) return null;
    const kind: Kind = tool;
    const opts = {
      closed: kind === 'polyline' || kind === 'spline' ? closed : undefined,
      curve: kind === 'region' ? ('spline' as const) : undefined,
      layer: this.view.activeLayer,
    };
    const { doc, id } = addFeature(this.doc, kind, points, opts);
    this.apply(doc);
    this.view = { ...this.view, draft: [], selection: { feature: id, point: null } };
    this.emit(false);
    return id;
  }

  cancelDraft(): void {
    this.setView({ draft: [] });
  }

  /** Deletes the selection: the control point, else the feature. */
  deleteSelection(): void {
    const { feature, point } = this.view.selection;
    if (feature === null) return;
    const f = getFeature(this.doc, feature);
    if (point !== null && this.view.mode === 'rest' && f?.kind !== 'point') {
      this.apply(deletePoint(this.doc, feature, point));
      this.view = { ...this.view, selection: { feature, point: null } };
    } else {
      this.apply(deleteFeature(this.doc, feature));
      this.view = { ...this.view, selection: { feature: null, point: null } };
    }
    this.emit(false);
  }
}

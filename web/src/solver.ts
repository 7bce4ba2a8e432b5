// The page's side of the solver worker: one solve in flight at a time, and for each layer
// only the newest request waits (older ones are superseded), so a fast drag never builds a
// queue — the picture always catches up with the pointer.

import type { DraftGeometry, FieldData, SolveFeature, SolveOptions, SolveReport, ViewSpec } from './engine';
import type { DraftDraw, DraftFrame, FromWorker, FullLayerRequest, ToWorker } from './protocol';
import type { Pt } from './scene';

export interface SolveTag {
  /** When the request was made (performance.now()), for latency. */
  madeAt: number;
  /** Whatever the caller needs to know which picture this field belongs to. */
  [k: string]: unknown;
}

export interface FieldEvent {
  key: string;
  /** The field, or null for a sparse draft (`sparse`) or a solve that only follows (`follow`). */
  field: FieldData | null;
  /** A sparse draft's (dx, dy) pairs at the pixels `select` chose. */
  sparse?: Float32Array;
  report: SolveReport;
  /** The worker answered with its last field, solved for this very request (see `LastFields`). */
  reused?: boolean;
  ms: number;
  gridStep: number;
  /** The triangles of the field's fast full frame (full-resolution fields only). */
  triangles?: Uint32Array;
  /** The draft frame the worker drew (asked for by `SolveHow.draw`). */
  frame?: DraftFrame;
  tag: SolveTag;
  /** When (page's performance.now()) the request went to the worker, the worker began and
   * finished solving it, and its field arrived back. */
  times: { sent: number; began: number; ended: number; received: number };
}

/**
 * How a field is asked for: `warm` (default) starts from the worker's last field; `mesh`
 * also sends the triangles of its fast full frame (see `adaptiveTriangles`); `sparse`
 * solves at the pixels `select` chose only; `follow` keeps the field in the worker as the
 * next start and sends back its report only.
 */
export interface SolveHow {
  warm?: boolean;
  mesh?: boolean;
  sparse?: boolean;
  follow?: boolean;
  /** With `sparse`: the worker draws the draft frame too (see `DraftDraw`). */
  draw?: DraftDraw;
}

interface Request {
  key: string;
  features: SolveFeature[];
  options: SolveOptions;
  how: SolveHow;
  tag: SolveTag;
}

/** Resolves when `worker` has loaded the engine (rejects on its error); every message after
 *  that goes to `receive`. */
function engineReady(worker: Worker, receive: (msg: FromWorker) => void): Promise<void> {
  return new Promise<void>((resolve, reject) => {
    const first = (ev: MessageEvent<FromWorker>) => {
      if (ev.data.type === 'ready') resolve();
      else if (ev.data.type === 'error') reject(new Error(ev.data.message));
      else return;
      worker.removeEventListener('message', first);
      worker.addEventListener('message', (e: MessageEvent<FromWorker>) => receive(e.data));
    };
    worker.addEventListener('message', first);
  });
}

/** A worker's memory (see the `memory` message); null if it does not answer within a second. */
export function workerMemory(worker: Worker): Promise<{ wasmBytes: number; heapBytes: number | null } | null> {
  return new Promise((resolve) => {
    const done = (v: { wasmBytes: number; heapBytes: number | null } | null) => {
      clearTimeout(timer);
      worker.removeEventListener('message', on);
      resolve(v);
    };
    const on = (ev: MessageEvent<FromWorker>) => {
      if (ev.data.type === 'memory') done({ wasmBytes: ev.data.wasmBytes, heapBytes: ev.data.heapBytes });
    };
    const timer = setTimeout(() => done(null), 1000);
    worker.addEventListener('message', on);
    worker.postMessage({ type: 'memory' } satisfies ToWorker);
  });
}

export class SolverClient {
  private worker: Worker;
  readonly ready: Promise<void>;
  private inFlight: { id: number; req: Request; sentAt: number } | null = null;
  private pending = new Map<string, Request>();
  private nextId = 1;
  private linkWaiters = new Map<string, { resolve: (l: Uint8Array) => void; reject: (e: Error) => void }[]>();
  private idleWaiters: (() => void)[] = [];
  onField: (ev: FieldEvent) => void = () => {};
  onError: (key: string | null, message: string) => void = () => {};
  onReset: (message: string) => void = () => {};
  /** The answers to `draw` (see `draw`). */
  onDrawn: (id: number, pixels: Uint8ClampedArray | null) => void = () => {};

  /**
   * Each layer's setup in the worker (its grid, the pixels sparse solves compute, its draft
   * geometry), kept where the worker can be replaced (`renew`) for the fresh one.
   */
  private setup = new Map<string, ToWorker[]>();
  /** While the worker is being replaced (see `renew`): the messages for the fresh one. */
  private queue: { msg: ToWorker; transfer: Transferable[] }[] | null = null;
  /** Workers replaced so far (see `renew`). */
  renewals = 0;
  /** Pictures being decoded (see `decode`), by request. */
  private decodes = new Map<number, { resolve: (img: { width: number; height: number; data: Uint8Array }) => void; reject: (e: Error) => void }>();
  /** Scenes being checked (see `check`), by request. */
  private checks = new Map<number, (problems: { path: string; message: string }[]) => void>();

  /** `makeWorker`, when given, makes the fresh worker `renew` replaces this one by. */
  constructor(
    worker: Worker,
    private wasmUrl: string,
    private makeWorker: (() => Worker) | null = null,
  ) {
    this.worker = worker;
    this.ready = engineReady(worker, (msg) => this.receive(msg));
    this.worker.postMessage({ type: 'init', wasmUrl } satisfies ToWorker);
  }

  private send(msg: ToWorker, transfer: Transferable[] = []): void {
    if (this.makeWorker) this.record(msg);
    if (this.ended) void this.restart();
    if (this.queue) this.queue.push({ msg, transfer });
    else this.worker.postMessage(msg, transfer);
  }

  /** Keeps a layer's setup messages (`grid`, `select`, `draft-layer`; `drop` ends it): a new grid starts it again. */
  private record(msg: ToWorker): void {
    if (msg.type === 'grid') this.setup.set(msg.key, [msg]);
    else if (msg.type === 'drop') this.setup.delete(msg.key);
    else if (msg.type === 'select' || msg.type === 'draft-layer') {
      const list = (this.setup.get(msg.key) ?? []).filter((m) => m.type !== msg.type);
      this.setup.set(msg.key, [...list, msg]);
    }
  }

  /**
   * Decodes a picture file's bytes (or a data: URI's) in the worker, as the engine decodes
   * it (`Engine.decode`); the bytes are handed over. The decoder's memory (about 140 MB of
   * module memory for a 4000 × 3000 JPEG) is then the worker's, not the page's.
   */
  decode(bytes: Uint8Array): Promise<{ width: number; height: number; data: Uint8Array }> {
    // A picture being opened waits for no solve: one in flight is ended (see `cancel`).
    this.cancel();
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      this.decodes.set(id, { resolve, reject });
      this.send({ type: 'decode', id, bytes }, [bytes.buffer]);
    });
  }

  /**
   * Checks a scene document in the worker (`Engine.validate`, which decodes its pictures:
   * a photograph's decoder memory is then the worker's, not the page's).
   */
  check(json: string): Promise<{ path: string; message: string }[]> {
    this.cancel();
    const id = this.nextId++;
    return new Promise((resolve) => {
      this.checks.set(id, resolve);
      this.send({ type: 'check', id, json });
    });
  }

  /** Replaces the worker by a fresh one (`renew`) if its module memory is above `bytes` and it is idle. */
  async renewAbove(bytes: number): Promise<void> {
    if (!this.makeWorker || this.busy) return;
    const m = await this.memory();
    if (m && m.wasmBytes > bytes && !this.busy) await this.renew();
  }

  /** Whether the worker can be replaced by a fresh one (`renew`). */
  get renewable(): boolean {
    return this.makeWorker !== null;
  }

  /**
   * Replaces the worker by a fresh one holding the same layers' setup (their grids, solved
   * from scratch by the next request): a WebAssembly memory never shrinks, and ending a
   * worker is the one way to give it back. Only while nothing is solving; requests made
   * meanwhile wait for the fresh worker.
   */
  renew(): Promise<void> {
    if (!this.makeWorker || this.ended || this.queue || this.busy || this.decodes.size > 0 || this.checks.size > 0) return Promise.resolve();
    this.worker.terminate();
    return this.restart();
  }

  /** Set by `cancel`: the worker is ended; the fresh one starts with the next message. */
  private ended = false;

  /**
   * Ends the solve in flight, and drops the requests waiting, by ending the worker: a solve
   * in WebAssembly cannot be stopped otherwise. The fresh worker (as `renew` makes it, with
   * the layers' setup) starts with the next request, not now: the user who made the solve
   * stale is busy. Only a solve: not while a picture is decoded, a scene checked or a grid
   * built, whose answers are awaited. Returns whether a solve was ended.
   */
  cancel(): boolean {
    const waited = this.decodes.size > 0 || this.checks.size > 0 || this.linkWaiters.size > 0;
    if (!this.makeWorker || !this.inFlight || this.queue || waited) return false;
    this.worker.terminate();
    this.ended = true;
    this.inFlight = null;
    this.pending.clear();
    for (const w of this.idleWaiters.splice(0)) w();
    return true;
  }

  /** Starts a fresh worker in place of the one ended, with the layers' setup. */
  private restart(): Promise<void> {
    const make = this.makeWorker as () => Worker;
    this.ended = false;
    this.queue = [];
    // The layers' setup as it is now (`record` replaces a layer's list, never changes it).
    const before = new Map(this.setup);
    const fresh = make();
    this.worker = fresh;
    const go = (ok: boolean) => {
      if (ok) this.renewals++;
      else this.onError(null, 'A solver worker could not be restarted.');
      // That setup, less the layers whose grid was asked for or dropped meanwhile, then what
      // was asked meanwhile in order: each grid asked for is answered once.
      const queued = this.queue ?? [];
      this.queue = null;
      const superseded = new Set(queued.filter((q) => q.msg.type === 'grid' || q.msg.type === 'drop').map((q) => (q.msg as { key: string }).key));
      for (const [key, list] of before) if (!superseded.has(key)) for (const msg of list) fresh.postMessage(msg);
      for (const q of queued) fresh.postMessage(q.msg, q.transfer);
      this.pump();
    };
    const ready = engineReady(fresh, (msg) => this.receive(msg));
    fresh.postMessage({ type: 'init', wasmUrl: this.wasmUrl } satisfies ToWorker);
    return ready.then(() => go(true), () => go(false));
  }

  /** (Re)builds a layer's solve domain; resolves with its links (for the renderer). */
  setGrid(key: string, width: number, height: number, matte: Uint8Array | null, cuts: Pt[][]): Promise<Uint8Array> {
    const p = new Promise<Uint8Array>((resolve, reject) => {
      const list = this.linkWaiters.get(key) ?? [];
      list.push({ resolve, reject });
      this.linkWaiters.set(key, list);
    });
    this.send({ type: 'grid', key, width, height, matte: matte ? matte.slice() : null, cuts });
    return p;
  }

  /** Sends a layer's draft geometry (null: none), so the worker draws its drafts itself (`SolveHow.draw`). */
  draftLayer(key: string, geometry: DraftGeometry | null): void {
    this.send({ type: 'draft-layer', key, geometry });
  }

  /** Asks the worker to draw a draft frame from these sparse fields (answered through `onDrawn`). */
  draw(id: number, draw: DraftDraw, values: Record<string, Float32Array>): void {
    this.send({ type: 'draw', id, draw, values }, Object.values(values).map((v) => v.buffer));
  }

  /** Chooses the pixels that sparse solves on a layer's grid compute (after its `setGrid`). */
  select(key: string, pixels: Uint32Array): void {
    this.send({ type: 'select', key, pixels: pixels.slice() });
  }

  dropGrid(key: string): void {
    this.pending.delete(key);
    this.send({ type: 'drop', key });
  }

  /** Asks for a field (`how`: see `SolveHow`); supersedes any request for the same layer still waiting. */
  solve(key: string, features: SolveFeature[], options: SolveOptions, tag: SolveTag, how: SolveHow = {}): void {
    this.pending.set(key, { key, features, options, how, tag });
    this.pump();
  }

  /** The tag of the request being solved now, and when it was sent (null when idle). */
  get current(): { tag: SolveTag; sentAt: number } | null {
    return this.inFlight && { tag: this.inFlight.req.tag, sentAt: this.inFlight.sentAt };
  }

  get busy(): boolean {
    return this.inFlight !== null || this.pending.size > 0;
  }

  /** Resolves when nothing is waiting or being solved. */
  idle(): Promise<void> {
    if (!this.busy) return Promise.resolve();
    return new Promise((resolve) => this.idleWaiters.push(resolve));
  }

  private pump(): void {
    if (this.inFlight || this.pending.size === 0 || this.queue) return;
    const [key, req] = this.pending.entries().next().value as [string, Request];
    this.pending.delete(key);
    const id = this.nextId++;
    this.inFlight = { id, req, sentAt: performance.now() };
    const { warm = true, mesh, sparse, follow, draw } = req.how;
    this.send({ type: 'solve', id, key, features: req.features, options: req.options, warm, mesh, sparse, follow, draw });
  }

  /** The worker's memory (see `workerMemory`). */
  memory(): ReturnType<typeof workerMemory> {
    return this.ended ? Promise.resolve(null) : workerMemory(this.worker);
  }

  private receive(msg: FromWorker): void {
    if (msg.type === 'reset') {
      for (const list of this.linkWaiters.values()) for (const w of list) w.reject(new Error(msg.message));
      this.linkWaiters.clear();
      this.onReset(msg.message);
      return;
    }
    if (msg.type === 'drawn') {
      this.onDrawn(msg.id, msg.pixels);
      return;
    }
    if (msg.type === 'checked') {
      const waiter = this.checks.get(msg.id);
      this.checks.delete(msg.id);
      waiter?.(msg.problems);
      return;
    }
    if (msg.type === 'decoded') {
      const waiter = this.decodes.get(msg.id);
      this.decodes.delete(msg.id);
      if (msg.image) waiter?.resolve(msg.image);
      else waiter?.reject(new Error(msg.message ?? 'The picture could not be decoded.'));
      return;
    }
    if (msg.type === 'links') {
      const list = this.linkWaiters.get(msg.key) ?? [];
      const waiter = list.shift();
      if (list.length === 0) this.linkWaiters.delete(msg.key);
      waiter?.resolve(msg.links);
      return;
    }
    if (msg.type === 'field' || (msg.type === 'error' && msg.id !== null)) {
      // (An ended worker's answer, had it sent one, is no one's.)
      if (msg.id !== this.inFlight?.id) return;
      const done = this.inFlight;
      this.inFlight = null;
      if (msg.type === 'field' && done) {
        const origin = performance.timeOrigin;
        const times = { sent: done.sentAt, began: msg.began - origin, ended: msg.ended - origin, received: performance.now() };
        this.onField({ key: msg.key, field: msg.field, sparse: msg.sparse, frame: msg.frame, reused: msg.reused, triangles: msg.triangles, report: msg.report, ms: msg.ms, gridStep: msg.gridStep, tag: done.req.tag, times });
      } else if (msg.type === 'error') {
        this.onError(msg.key, msg.message);
      }
      this.pump();
      if (!this.busy) for (const w of this.idleWaiters.splice(0)) w();
      return;
    }
    if (msg.type === 'error') {
      const waiter = msg.key !== null ? this.linkWaiters.get(msg.key)?.shift() : undefined;
      if (waiter) waiter.reject(new Error(msg.message));
      else this.onError(msg.key, msg.message);
    }
  }
}

/** A frame solved and drawn at the picture's own resolution (see `FullClient`). */
export interface FullFrame {
  /** What it was asked for (`App.fullKey`): it is shown while that is what is on screen. */
  key: string;
  width: number;
  height: number;
  /** Straight RGBA8. */
  pixels: Uint8Array;
  /** From the request to its arrival, and the worker's solves and drawing (ms). */
  ms: number;
  solveMs: number;
  drawMs: number;
  cycles: number[];
  /** The worker's WebAssembly memory (bytes). */
  wasmBytes: number;
  /** The view drawn (`pixels` is its region of the frame drawn `view.shrink` times smaller); null: the whole frame. */
  view: ViewSpec | null;
}

export interface FullRequest {
  key: string;
  width: number;
  height: number;
  background: [number, number, number, number];
  layers: FullLayerRequest[];
  madeAt: number;
  /** Draw only this view of the frame (the fields stay in the worker for `FullClient.view`); absent: the whole frame. */
  view?: ViewSpec;
  /** Called with the frame instead of `onFrame` (null: it failed, reported to `onError`). */
  done?: (frame: FullFrame | null) => void;
}

/**
 * When the worker that draws full-resolution frames has grown its WebAssembly memory above
 * this (a posed 4000 × 3000 frame's solve and drawing take it to about 290 MB, where a
 * fresh worker holding the picture and its grid has about 100 MB, and a WebAssembly
 * memory never shrinks) and is then left alone `RENEW_IDLE_MS`, it is replaced
 * by a fresh worker holding only the layers' pictures: ending a worker is the one way its
 * memory is given back at once. Not sooner: the fresh worker's first posed frame solves
 * about a second slower (its memory is new to the system and faults in as the solve
 * first touches it), so a pause between two drags keeps the worker as it is.
 */
export const RENEW_BYTES = 256 * 2 ** 20;
export const RENEW_IDLE_MS = 8000;
/**
 * The bound instead of `RENEW_BYTES` while the worker keeps the fields of the frame on
 * screen (`keptKey`): its solver (the multigrid hierarchy and the last fields, about 180 MB
 * of a 4000 × 3000 photograph's 290) is what makes the next zoom's view a drawing without
 * a solve and the next drag's settle a few cycles from the last field. An animator who
 * looks at a settled frame for a while and then zooms or drags again keeps that speed.
 * A worker grown past this is replaced all the same: a 4000 × 3000 photograph's holds 283
 * MiB after one settle and 443 after two (a WebAssembly memory never shrinks), and
 * keeping that much would take the page's memory left alone past 1 GB.
 */
export const RENEW_KEPT_BYTES = 384 * 2 ** 20;

/**
 * The page's side of the worker that draws full-resolution frames of a proxied scene: it
 * holds every layer's picture, matte and grid at the picture's own resolution; one frame
 * in flight, and only the newest request waits.
 */
export class FullClient {
  readonly ready: Promise<void>;
  private worker: Worker;
  private inFlight: { id: number; req: FullRequest; viewOnly?: boolean } | null = null;
  private pending: FullRequest | null = null;
  private nextId = 1;
  /** While the worker is being replaced (see `renew`): the messages for the fresh one. */
  private queue: { msg: ToWorker; transfer: Transferable[] }[] | null = null;
  private renewTimer: ReturnType<typeof setTimeout> | null = null;
  /** Workers replaced so far (see `RENEW_BYTES`). */
  renewals = 0;
  onFrame: (frame: FullFrame) => void = () => {};
  onError: (message: string) => void = () => {};
  /**
   * Whether the worker may be replaced now (set by the page: not while the pointer is down
   * or playback runs, whose frames share the cores with the fresh worker's loading and the
   * pictures it is sent); when not, the renewal waits another `RENEW_IDLE_MS`.
   */
  mayRenew: () => boolean = () => true;

  /** `renewal`: when the worker is replaced (the defaults `RENEW_BYTES`, `RENEW_KEPT_BYTES`, `RENEW_IDLE_MS`). */
  constructor(
    private makeWorker: () => Worker,
    private wasmUrl: string,
    private renewal = { bytes: RENEW_BYTES, keptBytes: RENEW_KEPT_BYTES, idleMs: RENEW_IDLE_MS },
  ) {
    this.worker = makeWorker();
    this.ready = this.start(this.worker);
  }

  /** Loads the engine in `worker`; then its messages come to `receive`. */
  private start(worker: Worker): Promise<void> {
    const ready = engineReady(worker, (msg) => this.receive(msg));
    worker.postMessage({ type: 'init', wasmUrl: this.wasmUrl } satisfies ToWorker);
    return ready;
  }

  private send(msg: ToWorker, transfer: Transferable[] = []): void {
    if (this.queue) this.queue.push({ msg, transfer });
    else this.worker.postMessage(msg, transfer);
  }

  /** Sends a layer's picture (copied: the page keeps its own), matte and cuts; null keeps what the worker has. */
  setLayer(key: string, image: { width: number; height: number; data: Uint8Array } | null, matte: Uint8Array | null, cuts: Pt[][]): void {
    this.send({ type: 'full-layer', key, image, matte, cuts });
  }

  dropLayer(key: string): void {
    this.send({ type: 'full-drop', key });
  }

  render(req: FullRequest): void {
    this.pending = req;
    this.pendingView = null;
    this.pump();
  }

  /**
   * The request of the last frame drawn as a view whose fields the worker keeps (null: none,
   * or the worker was renewed since): `view` draws another view of it without a solve.
   */
  private kept: FullRequest | null = null;
  /** The last frame asked for (`render`), solved again for a view when the worker has lost its fields. */
  private last: FullRequest | null = null;
  /** The newest view asked for (`view`), waiting for the frame in flight. */
  private pendingView: { view: ViewSpec; madeAt: number } | null = null;

  /** The key of the frame a `view` would be drawn from (null: none kept, a view needs a `render`). */
  get keptKey(): string | null {
    return this.pending ? (this.pending.view ? this.pending.key : null) : this.inFlight ? (this.inFlight.req.view ? this.inFlight.req.key : null) : (this.kept?.key ?? null);
  }

  /** Another view of the frame `keptKey` names, drawn from the fields the worker keeps (no solve). */
  view(view: ViewSpec, madeAt: number): void {
    if (this.keptKey === null) return;
    if (this.pending) {
      this.pending = { ...this.pending, view };
    } else {
      this.pendingView = { view, madeAt };
    }
    this.pump();
  }

  get busy(): boolean {
    return this.inFlight !== null || this.pending !== null || this.pendingView !== null;
  }

  private pump(): void {
    if (this.renewTimer !== null) {
      clearTimeout(this.renewTimer);
      this.renewTimer = null;
    }
    if (this.inFlight || this.queue) return;
    if (!this.pending && this.pendingView) {
      const { view, madeAt } = this.pendingView;
      this.pendingView = null;
      if (!this.kept) {
        // The fields are gone (the worker was replaced, or could not draw the view): the
        // frame is solved again for the view.
        if (this.last) {
          this.pending = { ...this.last, view, madeAt, done: undefined };
          this.pump();
        }
        return;
      }
      const id = this.nextId++;
      this.inFlight = { id, req: { ...this.kept, view, madeAt, done: undefined }, viewOnly: true };
      this.worker.postMessage({ type: 'full-view', id, view } satisfies ToWorker);
      return;
    }
    if (!this.pending) return;
    const req = this.pending;
    this.pending = null;
    const id = this.nextId++;
    this.inFlight = { id, req };
    this.last = req;
    // A whole frame takes the fields the worker kept.
    this.kept = null;
    this.worker.postMessage({ type: 'full-render', id, width: req.width, height: req.height, background: req.background, layers: req.layers, view: req.view } satisfies ToWorker);
  }

  /**
   * Replaces the worker by a fresh one holding the same layers (their pictures sent back by
   * the old one and moved over); frames asked for meanwhile wait for it.
   */
  renew(): Promise<void> {
    if (this.queue || this.inFlight) return Promise.resolve();
    const old = this.worker;
    this.queue = [];
    // The fresh worker has no fields: the next view is solved again.
    this.kept = null;
    this.pendingView = null;
    return new Promise<void>((resolve) => {
      const exported = (ev: MessageEvent<FromWorker>) => {
        if (ev.data.type !== 'full-layers') return;
        old.removeEventListener('message', exported);
        old.terminate();
        const { layers } = ev.data;
        const fresh = this.makeWorker();
        this.worker = fresh;
        const go = (ok: boolean) => {
          if (ok) this.renewals++;
          else this.onError('The worker that draws full-resolution frames could not be restarted.');
          for (const l of layers) fresh.postMessage({ type: 'full-layer', key: l.key, image: l.image, matte: l.matte, cuts: l.cuts, grid: true } satisfies ToWorker, [l.image.data.buffer, l.matte.buffer]);
          const queued = this.queue ?? [];
          this.queue = null;
          for (const q of queued) fresh.postMessage(q.msg, q.transfer);
          this.pump();
          resolve();
        };
        this.start(fresh).then(() => go(true), () => go(false));
      };
      old.addEventListener('message', exported);
      old.postMessage({ type: 'full-export' } satisfies ToWorker);
    });
  }

  /** The worker's memory (see `workerMemory`). */
  memory(): ReturnType<typeof workerMemory> {
    return workerMemory(this.worker);
  }

  /** Replaces the worker once it has been left alone `RENEW_IDLE_MS` and the page allows it (`mayRenew`). */
  private renewLater(): void {
    this.renewTimer = setTimeout(() => {
      this.renewTimer = null;
      if (this.busy) return;
      if (this.mayRenew()) void this.renew();
      else this.renewLater();
    }, this.renewal.idleMs);
  }

  private receive(msg: FromWorker): void {
    const done = this.inFlight;
    if (msg.type === 'full' && done && msg.id === done.id) {
      this.inFlight = null;
      if (msg.view) this.kept = done.req;
      const frame: FullFrame = { key: done.req.key, width: msg.width, height: msg.height, pixels: msg.pixels, ms: performance.now() - done.req.madeAt, solveMs: msg.solveMs, drawMs: msg.drawMs, cycles: msg.cycles, wasmBytes: msg.wasmBytes, view: msg.view ?? null };
      if (done.req.done) done.req.done(frame);
      else this.onFrame(frame);
      this.pump();
      if (!this.busy && msg.wasmBytes > (this.kept ? this.renewal.keptBytes : this.renewal.bytes)) this.renewLater();
    } else if (msg.type === 'error') {
      if (done && msg.id === done.id) {
        this.inFlight = null;
        if (done.viewOnly) {
          // A view the worker could not draw from its fields (it has none): the frame is
          // solved again for it, unless a newer request came meanwhile.
          this.kept = null;
          if (!this.pending && !this.pendingView) this.pendingView = { view: done.req.view!, madeAt: done.req.madeAt };
          this.pump();
          return;
        }
        done.req.done?.(null);
      }
      this.onError(msg.message);
      this.pump();
    }
  }
}

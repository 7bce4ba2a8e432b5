// The editor's controller: keeps the engine (worker), the GPU layers and the views in step
// with the store.

import type { Engine, FieldData, SolveFeature, SolveOptions } from './engine';
import { type DrawLayer, GlRenderer, type GlLayer, holdsSparse, sparseValuesAt } from './gl';
import { decodeImage, fileOf, forgetImage, ImageFileError, matteFromAlpha, matteFromImage, OFF_PAGE_DECODE_BYTES, pictureName, type PictureKey, withAlpha, type Rgba } from './images';
import { type Quality, solverOptions } from './options';
export type { Quality } from './options';
import { type Layer, type Pt, type SceneDoc, frameCount, frameRuns, layerFeatures, pointsAt, toLayer } from './scene';
import type { FieldEvent, FullClient, FullFrame } from './solver';
import { viewCovers } from './proxy';
import type { ViewSpec } from './engine';
import type { FullLayerRequest } from './protocol';
import type { DraftDraw } from './protocol';
import type { SolverClient } from './solver';
import { PROBE_TOLERANCE_PX, probedFeatures } from './probe';
import { downscaleMatte, downscaleRgba, type KeptField, keepForPlayback, keptBytes, proxyFactor, proxySize, toProxy, unpackField } from './proxy';
import { Store } from './state';

/**
 * Whether a layer's full-resolution solves start warm from the earlier ones (the grid thin
 * plate by multigrid; the other methods solve from scratch): only theirs follow drags and
 * probe points.
 */
function startsWarm(options: SolveOptions): boolean {
  return options.method === 'tps' && options.scheme === 'multigrid';
}

/**
 * Whether a layer's picture sources are the same (`LayerRuntime.sig`), compared part by
 * part: an image is a data URI of up to several MB, kept as the same string from edit to
 * edit, so comparing it is at once (a signature joining it into a new string would copy
 * and compare its megabytes at every pointer move of a drag).
 */
function sameSources(a: unknown[], b: unknown[]): boolean {
  return a.length === b.length && a.every((v, i) => v === b[i]);
}

export interface LayerRuntime {
  name: string;
  /**
   * What the pictures were loaded from: image, alpha, continuity and the scene's size (see
   * `sameSources`; empty: load again).
   */
  sig: unknown[];
  cutsSig: string;
  rgba: Rgba | null;
  matte: Uint8Array | null;
  gl: GlLayer | null;
  links: Uint8Array | null;
  gridReady: boolean;
  /** Bumped when the grid is rebuilt: fields solved on an older grid are dropped. */
  gridGen: number;
  field: FieldData | null;
  /** The last request sent for this layer (to skip identical ones). */
  lastRequest: string;
  error: string | null;
  /** The engine's remarks on the layer's last field (e.g. a matte its method ignores). */
  notes: string[];
  /** The request number of the field shown: an older request's field never replaces it. */
  shownSeq: number;
  /** The grid generation whose draft pixels the draft worker has (sparse drafts). */
  selectedGen: number;
}

export interface Stats {
  /** Pointer move → frame on screen during drags (ms). */
  dragLatency: number[];
  /** Pointer rest/release → full-resolution frame on screen (ms). */
  settle: number[];
  draftSolveMs: number[];
  finalSolveMs: number[];
  /** The full-resolution solves that followed drags (see `App.follow`). */
  followSolveMs: number[];
  /** The full-resolution solves of probes (see `App.probe`). */
  probeSolveMs: number[];
  /** Probes asked for after the pointer rested on a point, and on a press without a rest. */
  probesAsked: { rest: number; press: number };
  playback: { expected: number; shown: number; dropped: number } | null;
  /** Where each settle's time went (ms; see `SettleParts`). */
  settleParts: SettleParts[];
  /** Where each drag frame's time went (ms): the same parts, `queued` from the pointer event. */
  dragParts: SettleParts[];
  /** Frames the GPU drew, and frames that only redrew the overlay (the picture unchanged). */
  frames: { drawn: number; overlayOnly: number };
  /** The frames solved ahead (see `App.scheduleAhead`), in the order they arrived. */
  ahead: number[];
  /** Frames being solved ahead that were ended (a press on the picture, a change: see `App.cancelAhead`). */
  aheadCancelled: number;
  /** Where opening the last layer's picture took its time (ms), by step. */
  open: Record<string, number>;
  /** The full-resolution frames of a proxied scene: request to arrival (ms). */
  fullMs: number[];
  /** Their solves and drawing in the worker (ms), and the solves' cycles. */
  fullParts: { solveMs: number; drawMs: number; cycles: number[]; wasmMiB: number }[];
}

/**
 * One settle, from the pointer's rest or release to the full-resolution frame on screen,
 * split into its consecutive parts (ms).
 */
export interface SettleParts {
  /** Waiting for the worker: the request queued behind the solve in flight (`behind`). */
  queued: number;
  behind: string | null;
  /** Posting the request to the worker until it starts solving. */
  toWorker: number;
  /**
   * The worker's solve (request in, field out), with the solver's cycle count; `reused`: the
   * worker had solved this very request already (following the drag) and sent that field.
   */
  solve: number;
  cycles: number | null;
  reused: boolean;
  /** The draft worker drawing the draft frame after its solve (0: the page drew it, see `DraftDraw`). */
  workerDraw: number;
  /** The field's trip back to the page. */
  back: number;
  /** Uploading the field to the GPU (interleaving and texture upload). */
  upload: number;
  /** Waiting for the next animation frame. */
  toFrame: number;
  /** Issuing the full frame's draw calls. */
  draw: number;
  /** The GPU drawing it, until it is on screen. */
  gpu: number;
  total: number;
  /** Until the antialiased (4× multisampled) frame that follows is on screen. */
  antialiased?: number;
}

/**
 * Where the time from `start` (a pointer event or a settle) to the frame that showed `ev`'s
 * field went: `upload` is the field's upload, `end` when the GPU finished the frame and
 * `drawn` when its draw calls began and ended.
 */
function frameParts(
  ev: FieldEvent,
  start: number,
  behind: string | null,
  upload: number,
  end: number,
  drawn: { start: number; end: number },
): SettleParts {
  const { times } = ev;
  const workerDraw = ev.frame?.drawMs ?? 0;
  return {
    queued: times.sent - start,
    behind,
    toWorker: times.began - times.sent,
    solve: times.ended - times.began - workerDraw,
    cycles: ev.report.cycles ?? null,
    reused: ev.reused ?? false,
    workerDraw,
    back: times.received - times.ended,
    upload,
    toFrame: drawn.start - (times.received + upload),
    draw: drawn.end - drawn.start,
    gpu: end - drawn.end,
    total: end - start,
  };
}

/** Called when a frame is on screen: when the GPU finished it, and when its draw calls began and ended. */
type FrameFn = (gpuDone: number, drawn: { start: number; end: number }) => void;

function emptyStats(): Stats {
  return { dragLatency: [], settle: [], draftSolveMs: [], finalSolveMs: [], followSolveMs: [], probeSolveMs: [], probesAsked: { rest: 0, press: 0 }, playback: null, settleParts: [], dragParts: [], frames: { drawn: 0, overlayOnly: 0 }, ahead: [], aheadCancelled: 0, open: {}, fullMs: [], fullParts: [] };
}

/** Fields kept for playback (a 512×512 layer's field is 2 MiB). */
const CACHE_BUDGET_BYTES = 384 * 2 ** 20;
/**
 * The same for a proxied scene, whose fields are kept packed (`packField`, 3 MB a frame
 * of a 1000 × 750 proxy): 64 frames of one layer, 2.7 s at 24 fps.
 */
const PROXY_CACHE_BUDGET_BYTES = 192 * 2 ** 20;
const SETTLE_MS = 120;
/** Draft frames of the playback cache drawn ahead (see `App.drawAhead`): about 130 frames of the photograph's proxy at half size. */
const DRAWN_BUDGET_BYTES = 96 * 2 ** 20;
/** How long the editor is left alone (ms) before frames are solved ahead (see `scheduleAhead`). */
const AHEAD_IDLE_MS = 400;
/** The ahead worker is replaced by a fresh one once it has nothing to solve and its module holds more than this (see `App.renewAhead`). */
export const AHEAD_RENEW_BYTES = 64 * 2 ** 20;
/** A multisampled full frame slower than this (ms) is preceded by a single-sampled one. */
const SLOW_ANTIALIAS_MS = 50;
/**
 * While dragging, a draft drawn by the CPU of a frame with more pixels than this is drawn
 * a whole number of times smaller (see `App.draftShrink`): 512 × 512 is not, a 4000 × 3000
 * photograph's 1000 × 750 proxy is, at half its size.
 */
const DRAFT_PIXELS = 400_000;
/** Nor is it drawn so small that one of its pixels covers more than this many screen pixels across. */
const DRAFT_MAX_SCREEN_PX = 2;

export class App {
  readonly store: Store;
  readonly gl: GlRenderer;
  readonly runtimes = new Map<string, LayerRuntime>();
  readonly stats: Stats = emptyStats();

  /** Forgets the engine panel's figures (a new scene: the old one's say nothing of it). */
  /**
   * Where the page's memory is, measured apart (MiB): the page's own module memory and
   * JavaScript heap, the large arrays it keeps (the layers' pictures and mattes, the fields
   * solved ahead, the full-resolution frame shown), and each worker's module memory and heap.
   */
  async memoryReport(): Promise<Record<string, unknown>> {
    const mib = (b: number | null | undefined) => (b == null ? null : Math.round(b / 2 ** 20));
    const heap = (performance as unknown as { memory?: { usedJSHeapSize: number } }).memory;
    let pictures = 0;
    for (const rt of this.runtimes.values()) pictures += (rt.rgba?.data.byteLength ?? 0) + (rt.matte?.byteLength ?? 0);
    const worker = async (c: { memory(): Promise<{ wasmBytes: number; heapBytes: number | null } | null> } | null) => {
      const m = c && (await c.memory());
      return m && { wasmMiB: mib(m.wasmBytes), heapMiB: mib(m.heapBytes) };
    };
    return {
      page: { wasmMiB: mib(this.engine.x.memory.buffer.byteLength), heapMiB: mib(heap?.usedJSHeapSize), picturesMiB: mib(pictures), fullFrameMiB: mib(this.fullShown?.pixels.byteLength ?? 0), fieldCacheMiB: mib(this.cache.bytes), drawnFramesMiB: mib(this.drawnFrames.bytes) },
      solver: await worker(this.solver),
      drafts: await worker(this.drafts),
      ahead: await worker(this.ahead),
      full: await worker(this.full),
    };
  }

  resetStats(): void {
    Object.assign(this.stats, emptyStats());
    this.lastReport = null;
    this.shownFromCache = false;
  }
  onMessage: (text: string, kind: 'error' | 'info') => void = () => {};
  onFrame: () => void = () => {};
  onSolved: (ev: FieldEvent) => void = () => {};
  private frameQueued = false;
  private settleTimer: number | null = null;
  private pendingLatency: number[] = [];
  private settleStart: number | null = null;
  /** What the worker was solving when the settle began. */
  private settleBehind: string | null = null;
  private waiters: (() => void)[] = [];
  /** A drag is live: solve drafts. */
  dragging = false;
  /** The last probe asked for (see `probe`): feature, point, time and revision. */
  private lastProbe = '';
  lastPointerAt = 0;
  /** When the pointer last moved or pressed on the picture (solving ahead waits after it). */
  lastActivityAt = 0;
  lastReport: FieldEvent | null = null;
  /** The frame shown now came from the playback cache (fields solved ahead), not from `lastReport`'s solve. */
  shownFromCache = false;
  /**
   * The scene time of the fields the picture shows (null before any): while playing, a frame
   * not solved yet keeps the picture of an earlier one, and the drawing is drawn at this
   * time, with the picture it moves, not ahead of it.
   */
  shownTime: number | null = null;
  /** Full-resolution fields by frame, for the document revision they were solved for. */
  private cache = { rev: -1, bytes: 0, frames: new Map<number, Map<string, KeptField>>() };

  /**
   * Draft frames of the playback cache drawn ahead by the draft worker (see `drawAhead`),
   * straight RGBA8 at the draft's size, for the scene revision and frame spec (`DraftDraw`)
   * they were drawn for.
   */
  private drawnFrames = { rev: -1, spec: '', bytes: 0, frames: new Map<number, Uint8ClampedArray>() };
  /** The frame the draft worker is drawing ahead now. */
  private drawingAhead: { id: number; frame: number; rev: number; spec: string } | null = null;
  private drawId = 0;

  /** Numbers every solve request: a layer shows the field of its newest request only. */
  private seq = 0;

  /**
   * `solver` solves full-resolution fields; `drafts` (a second worker), when given, the
   * drafts while dragging, so a draft never waits behind a full-resolution solve.
   */
  constructor(
    readonly engine: Engine,
    readonly solver: SolverClient,
    glCanvas: HTMLCanvasElement,
    store: Store,
    readonly drafts: SolverClient | null = null,
    readonly ahead: SolverClient | null = null,
    readonly full: FullClient | null = null,
  ) {
    this.store = store;
    this.gl = new GlRenderer(glCanvas);
    this.gl.useEngine(engine);
    if (full) {
      full.onFrame = (frame) => this.receiveFull(frame);
      full.onError = (message) => {
        this.onMessage(`Full-resolution frame: ${message}`, 'error');
        this.checkIdle();
      };
      // Its replacement (loading a fresh worker, sending it the pictures) waits while the
      // pointer is on the drawing or playback runs: it would take the cores from their frames.
      full.mayRenew = () => !this.dragging && !this.store.view.playing && !this.exporting && performance.now() - this.lastPointerAt >= AHEAD_IDLE_MS;
    }
    if (drafts) drafts.onDrawn = (id, pixels) => this.receiveDrawn(id, pixels);
    for (const client of this.clients) {
      client.onField = (ev) => this.receive(ev);
      client.onError = (key, message) => {
        const rt = key ? this.runtimes.get(key) : undefined;
        if (rt) rt.error = message;
        this.onMessage(key ? `Layer ${key}: ${message}` : message, 'error');
        this.checkIdle();
      };
      client.onReset = (message) => {
        this.onMessage(message, 'error');
        for (const layer of this.doc.layers) {
          const rt = this.runtimes.get(layer.name);
          if (rt) this.rebuildGrid(rt, layer);
        }
      };
    }
    store.subscribe((_, docChanged) => {
      // A drag that put off its grids has ended: build them, and what was solved on the
      // old ones is stale.
      const gridsNow = this.gridsDue && !store.inGesture;
      if (gridsNow) this.gridEpoch++;
      // Before the grids: a grid being rebuilt in the ahead worker keeps its solve going.
      if (docChanged) this.cancelAhead(false);
      if (docChanged || gridsNow) this.syncLayers();
      this.dropStale();
      this.scheduleAhead();
      this.requestSolve(this.dragging ? 'draft' : 'final');
      this.invalidate();
    });
  }

  get doc(): SceneDoc {
    return this.store.doc;
  }

  /** The solver workers (the draft worker, if any, second). */
  get clients(): SolverClient[] {
    return [this.solver, ...(this.drafts ? [this.drafts] : []), ...(this.ahead ? [this.ahead] : [])];
  }

  /** The worker that solves requests of this quality. */
  private solverFor(quality: Quality): SolverClient {
    return quality === 'draft' && this.drafts ? this.drafts : this.solver;
  }

  // -- Layers ---------------------------------------------------------------------------

  /**
   * The layer's cuts at rest, in its own pixels (`proxied`: in the proxy's pixels). The
   * drawing is in the frame; a layer at `offset` reads it at `p − offset`, as the engine does.
   */
  private cutsOf(layer: Layer, proxied = true): Pt[][] {
    const f = proxied ? this.proxy : 1;
    const onto = toLayer(layer);
    return layerFeatures(this.doc, layer)
      .filter((c) => c.kind === 'cut')
      .map((c) => onto(c.rest).map((p) => toProxy(p, f)));
  }

  /**
   * The factor the picture is scaled down by for editing (1: none; see `proxy.ts`). A
   * large picture is edited through its proxy: grids, drafts, full-resolution solves of
   * the proxy and playback all work on it, and the frame solved and rendered at the
   * picture's own resolution (`full`) replaces it once the drawing rests.
   */
  proxy = 1;

  /** Screen (device) pixels across one pixel of the scene as the stage shows it (set by the page's layout). */
  screenPxPerScenePx = 1;

  /**
   * How many times smaller a draft is drawn while dragging (1: at the frame's size): a
   * frame of more than `DRAFT_PIXELS` pixels (a large picture's proxy) is drawn by the
   * least whole factor that brings it within them, unless its pixels would then cover more
   * than `DRAFT_MAX_SCREEN_PX` screen pixels (zoomed in). The CPU's time for a draft, and
   * the page's to show it, go with its pixels; the full frame at rest is drawn at full size.
   */
  get draftShrink(): number {
    const { width, height } = this.frameSize;
    const n = width * height;
    if (n <= DRAFT_PIXELS) return 1;
    const want = Math.ceil(Math.sqrt(n / DRAFT_PIXELS));
    const most = Math.max(1, Math.floor(DRAFT_MAX_SCREEN_PX / Math.max(1e-6, this.screenPxPerScenePx * this.proxy)));
    return Math.max(1, Math.min(want, most));
  }

  /** The factor a frame is drawn smaller by: `draftShrink` for a draft while dragging or playing, else 1. */
  private shrinkFor(draft: boolean): number {
    return draft && (this.dragging || this.store.view.playing) ? this.draftShrink : 1;
  }

  /** The size the editor's grids and frames have: the scene's, or its proxy's. */
  get frameSize(): { width: number; height: number } {
    return proxySize(this.doc.width, this.doc.height, this.proxy);
  }

  /** A grid change waits for the drag that made it to end (see `syncLayers`). */
  private gridsDue = false;
  /** Bumped when grids wait for a drag's end are built: what was solved on the old ones is stale. */
  private gridEpoch = 0;

  /**
   * What the fields solved now are solved for: the document's revision, and the grids
   * built after a drag (the drag's last revision was solved on the grids from before it).
   */
  private get revision(): number {
    return this.store.revision + this.gridEpoch * 2 ** 32;
  }

  syncLayers(): void {
    this.gridsDue = false;
    const f = proxyFactor(this.doc.width, this.doc.height);
    if (f !== this.proxy) {
      // Every layer is loaded again at the new scale.
      this.proxy = f;
      for (const rt of this.runtimes.values()) rt.sig = [];
    }
    const names = new Set(this.doc.layers.map((l) => l.name));
    for (const [name, rt] of this.runtimes) {
      if (!names.has(name)) {
        rt.gl?.dispose();
        for (const client of this.clients) client.dropGrid(name);
        this.full?.dropLayer(name);
        this.runtimes.delete(name);
      }
    }
    for (const layer of this.doc.layers) {
      let rt = this.runtimes.get(layer.name);
      if (!rt) {
        rt = {
          name: layer.name,
          sig: [],
          cutsSig: '',
          rgba: null,
          matte: null,
          gl: null,
          links: null,
          gridReady: false,
          gridGen: 0,
          selectedGen: -1,
          field: null,
          lastRequest: '',
          error: null,
          notes: [],
          shownSeq: 0,
        };
        this.runtimes.set(layer.name, rt);
      }
      const sig = [layer.image, layer.alpha, layer.continuity, this.doc.width, this.doc.height];
      const cutsSig = JSON.stringify(this.cutsOf(layer));
      if (!sameSources(sig, rt.sig)) {
        rt.sig = sig;
        rt.cutsSig = cutsSig;
        void this.loadLayer(rt, layer);
      } else if (cutsSig !== rt.cutsSig) {
        // A drag (a layer moved under a cut, a cut's point moved) rebuilds the grid when it
        // ends: a build at every pointer move would redo the whole grid in every worker and
        // its mesh on the page, for a tear that shows only once posed. Meanwhile the layer
        // draws on its grid as it was.
        if (this.store.inGesture) {
          this.gridsDue = true;
          continue;
        }
        rt.cutsSig = cutsSig;
        if (rt.matte) this.rebuildGrid(rt, layer);
        if (this.full) this.full.setLayer(rt.name, null, null, this.cutsOf(layer, false));
      }
    }
  }

  private async loadLayer(rt: LayerRuntime, layer: Layer): Promise<void> {
    const sig = rt.sig;
    rt.gridReady = false;
    this.busyCount++;
    try {
      if (!layer.image) {
        // A layer without a picture draws nothing (its field is only for `inkwarp field`).
        rt.gl?.dispose();
        rt.gl = null;
        rt.rgba = null;
        return;
      }
      let mark = performance.now();
      const step = (name: string) => {
        const now = performance.now();
        this.stats.open[name] = (this.stats.open[name] ?? 0) + now - mark;
        mark = now;
      };
      this.stats.open = {};
      // A picture that does not decode is named by its file (the one to mend), else its layer.
      const decode = (key: PictureKey) => decodeImage(layer[key]!).catch((err: Error) => {
        const file = fileOf(layer[key]!);
        const why = (err instanceof ImageFileError ? err.why : err.message).replace(/[.\s]+$/, '');
        throw new ImageFileError(`Cannot use ${pictureName(layer.name, key, file)}: ${why}.${file ? ' Reload the page to read it again.' : ''}`);
      });
      let img = await decode('image');
      step('decode');
      const { width, height } = this.doc;
      const check = (what: string, im: Rgba) => {
        if (im.width !== width || im.height !== height) {
          throw new Error(`The ${what} of layer ${layer.name} is ${im.width}×${im.height} but the scene is ${width}×${height}; every image and matte has the scene's size.`);
        }
      };
      check('image', img);
      if (layer.alpha) {
        const a = await decode('alpha');
        check('alpha matte', a);
        img = withAlpha(img, a);
      }
      let matte: Uint8Array;
      if (layer.continuity) {
        const c = await decode('continuity');
        check('continuity matte', c);
        matte = matteFromImage(c);
      } else {
        matte = matteFromAlpha(img);
      }
      step('matte');
      if (rt.sig !== sig) return; // superseded while decoding
      const f = this.proxy;
      if (f > 1 && this.full) {
        // The picture itself goes to the worker that draws full-resolution frames; the
        // editor keeps its proxy.
        this.full.setLayer(rt.name, img, matte, this.cutsOf(layer, false));
        step('to full-resolution worker');
        img = downscaleRgba(img, f);
        matte = downscaleMatte(matte, width, height, f);
        forgetImage(layer.image);
        step('proxy');
      }
      rt.rgba = img;
      rt.matte = matte;
      rt.error = null;
      if (!rt.gl || rt.gl.width !== img.width || rt.gl.height !== img.height) {
        rt.gl?.dispose();
        rt.gl = this.gl.layer(img.width, img.height);
      }
      rt.gl.setImage(img.data);
      rt.gl.setField(null);
      rt.field = null;
      step('upload');
      this.rebuildGrid(rt, this.doc.layers.find((l) => l.name === rt.name) ?? layer);
    } catch (err) {
      rt.error = (err as Error).message;
      this.onMessage((err as Error).message, 'error');
    } finally {
      this.busyCount--;
      this.checkIdle();
    }
  }

  private busyCount = 0;

  private rebuildGrid(rt: LayerRuntime, layer: Layer): void {
    if (!rt.matte) return;
    const gen = ++rt.gridGen;
    rt.gridReady = false;
    rt.lastRequest = '';
    this.busyCount++;
    const cuts = this.cutsOf(layer);
    const t0 = performance.now();
    const { width, height } = this.frameSize;
    Promise.all(this.clients.map((c) => c.setGrid(rt.name, width, height, rt.matte, cuts)))
      .then(([links]) => {
        if (gen !== rt.gridGen) return;
        const t1 = performance.now();
        this.stats.open.grid = t1 - t0;
        rt.links = links;
        rt.gl?.setMesh(links, rt.rgba?.data ?? null);
        this.stats.open.mesh = performance.now() - t1;
        if (rt.gl && this.drafts) {
          // Drafts are solved at the draft mesh's pixels only (see `sparseDraft`).
          this.drafts.select(rt.name, rt.gl.draftPixels);
          // Where the CPU draws drafts, the draft worker draws them (see `draftDraw`).
          if (this.gl.cpuDrafts) this.drafts.draftLayer(rt.name, rt.gl.cpuDraftGeometry);
          rt.selectedGen = gen;
        }
        rt.gridReady = true;
        this.requestSolve('final');
        this.invalidate();
      })
      .catch((err: Error) => {
        rt.error = err.message;
        this.onMessage(`Layer ${rt.name}: ${err.message}`, 'error');
      })
      .finally(() => {
        this.busyCount--;
        this.checkIdle();
      });
  }

  // -- Solving --------------------------------------------------------------------------

  /** Whether the picture shows the drawing's pose (pose mode, or playing). */
  get posed(): boolean {
    return this.store.view.mode === 'pose' || this.store.view.playing;
  }

  /**
   * A layer's solve request settings (`proxied`: for the proxy, whose pixels are `proxy`
   * scene pixels: its grid step and sampling are the scene's divided by the factor, at
   * least 1, and its drafts' grid is as coarse as for a picture of the proxy's size).
   */
  solverOptions(layer: Layer, quality: Quality, proxied = true): SolveOptions {
    const f = proxied ? this.proxy : 1;
    if (f === 1) return solverOptions(this.doc, layer, quality);
    const { width, height } = this.frameSize;
    const scene = solverOptions(this.doc, layer, 'final');
    const base = Math.max(1, Math.round((scene.grid_step ?? 1) / f));
    const ps = solverOptions({ ...this.doc, width, height, solver: { ...this.doc.solver, grid_step: base } }, { ...layer, solver: layer.solver ? { ...layer.solver, grid_step: base } : undefined }, quality);
    return ps;
  }

  /**
   * A layer's features at `time` as the solver reads them: in the layer's own pixels (the
   * frame's, less its offset), `proxied`: in the proxy's.
   */
  solveFeatures(layer: Layer, time: number, proxied = true): SolveFeature[] {
    const f = proxied ? this.proxy : 1;
    const onto = toLayer(layer);
    const at = (pts: Pt[]) => (f === 1 ? onto(pts) : onto(pts).map((p) => toProxy(p, f)));
    return layerFeatures(this.doc, layer)
      .filter((c) => c.kind !== 'cut')
      .map((c) => ({
        id: c.id,
        kind: c.kind,
        rest: at(c.rest),
        pose: at(pointsAt(c, time)),
        closed: c.kind === 'region' || !!c.closed,
        spline_outline: c.kind === 'region' && c.curve === 'spline',
      }));
  }

  private frameOf(time: number): number | null {
    const f = time * this.doc.fps;
    return Math.abs(f - Math.round(f)) < 1e-6 ? Math.round(f) : null;
  }

  private cached(frame: number | null): Map<string, KeptField> | undefined {
    if (frame === null || this.cache.rev !== this.revision) return undefined;
    const fields = this.cache.frames.get(frame);
    return fields && this.doc.layers.every((l) => {
      const rt = this.runtimes.get(l.name);
      if (!rt?.gridReady) return true;
      const kept = fields.get(l.name);
      return kept !== undefined && (!('sparse' in kept) || this.showsSparse(rt, kept));
    }) ? fields : undefined;
  }

  /**
   * Whether a field kept at the draft mesh's pixels only (`SparseKept`) can show this
   * layer's frame now: drawn as a draft by the CPU from the same draft mesh, with no overlay
   * that needs the whole field and no export (which draws full frames). Else the frame is
   * solved as if nothing were kept.
   */
  private showsSparse(rt: LayerRuntime, kept: { pixels: Uint32Array }): boolean {
    return this.drawsCpuDraft(rt) && kept.pixels === rt.gl!.draftPixels;
  }

  /**
   * The draft mesh's pixels a proxied scene's fields are kept at for playback (see
   * `keepForPlayback`), where the CPU draws its played frames; null where the whole field
   * is kept (a real GPU draws it).
   */
  private keptPixels(rt: LayerRuntime | undefined): Uint32Array | null {
    return rt?.gl && this.gl.cpuDrafts && rt.gl.cpuDraftGeometry !== null && rt.gl.draftPixels.length > 0 ? rt.gl.draftPixels : null;
  }

  private remember(frame: number, key: string, solved: FieldData): void {
    if (this.cache.rev !== this.revision) this.cache = { rev: this.revision, bytes: 0, frames: new Map() };
    // A proxied scene's fields are kept at the draft mesh's pixels where the CPU plays them,
    // else packed, in a smaller budget (see `keepForPlayback`).
    const field = keepForPlayback(solved, this.proxy, this.keptPixels(this.runtimes.get(key)));
    const size = keptBytes(field);
    if (this.cache.bytes + size > (this.proxy > 1 ? PROXY_CACHE_BUDGET_BYTES : CACHE_BUDGET_BYTES)) return;
    let fields = this.cache.frames.get(frame);
    if (!fields) this.cache.frames.set(frame, (fields = new Map()));
    const had = fields.get(key);
    this.cache.bytes += size - (had ? keptBytes(had) : 0);
    fields.set(key, field);
  }

  /**
   * Frees the fields kept for playback and the frames drawn ahead as soon as a change of the
   * scene makes them stale (else they stayed until the next field kept or frame drawn ahead,
   * through a whole drag).
   */
  private dropStale(): void {
    const rev = this.revision;
    if (this.cache.rev !== rev && this.cache.frames.size > 0) this.cache = { rev, bytes: 0, frames: new Map() };
    if (this.drawnFrames.rev !== rev && this.drawnFrames.frames.size > 0) this.drawnFrames = { rev, spec: '', bytes: 0, frames: new Map() };
  }

  /**
   * The frames that have every layer's field cached, so they play at once (the timeline's
   * ready bar), as runs `[first, last]`: read from the cache, never frame by frame over the
   * scene (up to 1e8 frames).
   */
  readyRuns(): [number, number][] {
    return frameRuns([...this.cache.frames.keys()].filter((f) => this.cached(f)));
  }

  /** How many frames have every layer's field cached for playback. */
  cachedFrames(): number {
    let n = 0;
    for (const frame of this.cache.frames.keys()) if (this.cached(frame)) n++;
    return n;
  }

  /**
   * While playing: solves the next frames that are not cached yet, in order, each warm
   * from the one before, so a second pass through the animation drops no frame.
   */
  prefetch(): void {
    if (!this.store.view.playing || this.solver.busy) return;
    const n = frameCount(this.doc);
    const now = this.frameOf(this.store.view.time) ?? 0;
    for (let k = 1; k < n; k++) {
      const frame = (now + k) % n;
      if (this.cached(frame)) continue;
      const time = frame / this.doc.fps;
      for (const layer of this.doc.layers) {
        const rt = this.runtimes.get(layer.name);
        if (!rt?.gridReady || this.cache.frames.get(frame)?.has(layer.name)) continue;
        this.solver.solve(layer.name, this.solveFeatures(layer, time), this.solverOptions(layer, 'final'), {
          madeAt: performance.now(), quality: 'final', gen: rt.gridGen, time, rev: this.revision, frame, prefetch: true, seq: ++this.seq,
        });
      }
      return;
    }
  }

  private aheadTimer: number | null = null;

  /**
   * Solving ahead: once the editor has been left alone for `AHEAD_IDLE_MS` (no change, no
   * pointer on the drawing, nothing solving in the foreground, no full-resolution frame
   * being made: on two cores the ahead worker's solves would slow the settle's solve and
   * draw), the ahead worker solves the
   * frames not cached yet, nearest the playhead first, one at a time, each into the
   * playback cache (the ready bar fills in). Any change starts the wait again; a field
   * solved for an older revision of the scene is dropped. Playback then shows every ready
   * frame without a solve.
   */
  scheduleAhead(): void {
    if (!this.ahead) return;
    if (this.aheadTimer !== null) clearTimeout(this.aheadTimer);
    this.aheadTimer = window.setTimeout(() => {
      this.aheadTimer = null;
      this.solveAhead();
    }, AHEAD_IDLE_MS);
  }

  /**
   * The next frames, nearest the playhead first, that are not cached for every layer: each
   * found as it is asked for (a scene may have 1e8 frames, and the first is asked for).
   */
  private *aheadFrames(): Generator<number> {
    const n = frameCount(this.doc);
    const now = Math.min(n - 1, Math.max(0, Math.round(this.store.view.time * this.doc.fps)));
    for (let d = 0; d < n; d++) {
      if (now + d < n && !this.cached(now + d)) yield now + d;
      if (d > 0 && now - d >= 0 && !this.cached(now - d)) yield now - d;
    }
  }

  private solveAhead(): void {
    const ahead = this.ahead;
    if (!ahead || ahead.busy || this.dragging || this.store.view.playing) return;
    const now = performance.now();
    if (this.solver.busy || this.drafts?.busy || this.full?.busy || now - this.lastPointerAt < AHEAD_IDLE_MS || now - this.lastActivityAt < AHEAD_IDLE_MS) {
      this.scheduleAhead();
      return;
    }
    if (!this.doc.features.some((f) => (f.keys ?? []).length > 0)) {
      // Nothing to solve ahead (a picture just opened, say, whose decoding and checking
      // the ahead worker did).
      this.renewAhead();
      return;
    }
    for (const frame of this.aheadFrames()) {
      const time = frame / this.doc.fps;
      let asked = false;
      for (const layer of this.doc.layers) {
        const rt = this.runtimes.get(layer.name);
        if (!rt?.gridReady || !rt.gl || this.cache.rev === this.revision && this.cache.frames.get(frame)?.has(layer.name)) continue;
        // Solved whole, as `inkwarp render` solves the frame (with its report): a press on the
        // picture or a change of the scene meanwhile ends it (`cancelAhead`), so a drag never
        // waits for it. (Solved a few cycles a request instead, each continuing from the last,
        // the frame never reached the cycles that find a torn grid's slow modes, and a series
        // could end on a small change far from the answer.)
        ahead.solve(layer.name, this.solveFeatures(layer, time), this.solverOptions(layer, 'final'), {
          madeAt: performance.now(), quality: 'final', gen: rt.gridGen, time, rev: this.revision, frame, ahead: true, prefetch: true, seq: ++this.seq,
        });
        asked = true;
      }
      if (asked) return;
    }
    this.renewAhead();
  }

  /**
   * Ends the frame being solved ahead (see `SolverClient.cancel`) when `always` (a press on
   * the picture, Play: a drag or playback must not share the two cores with it) or when it
   * was asked for another revision of the scene. It is asked again once the editor is left
   * alone.
   */
  cancelAhead(always: boolean): void {
    const tag = this.ahead?.current?.tag;
    if (tag && (always || tag.rev !== this.revision) && this.ahead?.cancel()) {
      this.stats.aheadCancelled++;
      this.scheduleAhead();
    }
  }

  /**
   * A scene document's problems (`Engine.validate`, which decodes its pictures). A large one
   * (a photograph's data: URI) is checked by the ahead worker, so the decoder's memory
   * (about 140 MB for a 4000 × 3000 JPEG) is not kept in the page's module, whose memory
   * never shrinks; that worker is replaced by a fresh one once the editor is left alone
   * (`renewAhead`), not now: the scene's grids being built wait for every worker.
   */
  async checkScene(doc: unknown): Promise<{ path: string; message: string }[]> {
    const ahead = this.ahead;
    if (ahead?.renewable) {
      const json = JSON.stringify(doc);
      if (json.length >= OFF_PAGE_DECODE_BYTES) {
        return ahead.check(json);
      }
    }
    return this.engine.validate(doc);
  }

  /**
   * Every frame is solved ahead, or there is none to solve: the ahead worker's module
   * memory (the proxy's grids and its solves' warm-start history, about 140 MB for a
   * 4000 × 3000 photograph's proxy, or a picture's decoding, never given back) is freed by
   * replacing it with a fresh worker holding only the layers' grids. The next change's
   * frames are solved there, the first from scratch.
   */
  private renewAhead(): void {
    if (this.busy) {
      // Not while a picture opens or a frame is made: the grids being built wait for every
      // worker, the fresh one's loading included.
      this.scheduleAhead();
      return;
    }
    void this.ahead?.renewAbove(AHEAD_RENEW_BYTES);
  }

  private fullAsked = '';
  /** A video export is drawing frames: a large picture's are the proxy's (no full-resolution frames). */
  exporting = false;
  /** The full-resolution frame on screen (a proxied scene), or null while the proxy shows. */
  fullShown: FullFrame | null = null;
  /** Called when a full-resolution frame arrives for what is on screen (`fullShown`), or is taken away (null). */
  onFull: (frame: FullFrame | null) => void = () => {};

  /** What the frame on screen depends on: a full-resolution frame is shown for this only. */
  private fullKey(): string {
    const { view } = this.store;
    return JSON.stringify([this.revision, view.time, this.posed, view.hidden, this.doc.background ?? null]);
  }

  /**
   * A proxied scene at rest (no drag, no playback): asks the full-resolution worker for the
   * frame at the current time, every layer solved at the picture's own resolution with the
   * scene's settings and drawn by the engine's renderer, as `inkwarp render` draws it.
   */
  private requestFull(): void {
    const full = this.full;
    if (!full || this.proxy === 1 || this.dragging || this.store.view.playing || this.exporting) return;
    const key = this.fullKey();
    if (this.fullShown?.key === key || (key === this.fullAsked && full.busy)) return;
    this.fullAsked = key;
    const time = this.store.view.time;
    const layers = [];
    for (const layer of this.doc.layers) {
      const rt = this.runtimes.get(layer.name);
      if (!rt?.gl || layer.visible === false || this.store.view.hidden.includes(layer.name)) continue;
      layers.push({
        key: layer.name,
        features: this.posed ? this.solveFeatures(layer, time, false) : null,
        options: this.solverOptions(layer, 'final', false),
        offset: layer.offset ?? ([0, 0] as Pt),
      });
    }
    full.render({ key, width: this.doc.width, height: this.doc.height, background: this.doc.background ?? [255, 255, 255, 255], layers, madeAt: performance.now(), view: this.viewFor() ?? undefined });
  }

  /**
   * The part of the frame the stage shows and the scale it shows it at (see `viewFor` in
   * `proxy.ts`), set by the page's stage: a proxied scene's full-resolution frame is drawn
   * for it only. Null: the whole frame.
   */
  viewFor: () => ViewSpec | null = () => null;

  /**
   * The stage was zoomed or panned: a full-resolution frame on screen that does not cover
   * the new view at its scale is drawn again for it, from the fields the worker kept (no
   * solve), or solved again when the worker has none.
   */
  requestView(): void {
    const full = this.full;
    const shown = this.fullShown;
    if (!full || this.proxy === 1 || !shown || this.dragging || this.store.view.playing || this.exporting) return;
    const want = this.viewFor();
    if (!want || viewCovers(shown.view, want, this.doc.width, this.doc.height)) return;
    this.viewWanted = true;
    if (full.keptKey === shown.key && shown.key === this.fullKey()) full.view(want, performance.now());
    else {
      this.fullShown = null;
      this.requestFull();
    }
  }

  /** A view was asked for and has not come (the stage shows the one before, scaled). */
  viewWanted = false;

  /**
   * The whole full-resolution frame at the current time, solved and drawn at the picture's
   * resolution (a PNG's export): null when there is no full-resolution worker or it failed.
   */
  wholeFrame(): Promise<FullFrame | null> {
    const full = this.full;
    if (!full || this.proxy === 1) return Promise.resolve(null);
    const time = this.store.view.time;
    const layers: FullLayerRequest[] = [];
    for (const layer of this.doc.layers) {
      const rt = this.runtimes.get(layer.name);
      if (!rt?.gl || layer.visible === false || this.store.view.hidden.includes(layer.name)) continue;
      layers.push({ key: layer.name, features: this.posed ? this.solveFeatures(layer, time, false) : null, options: this.solverOptions(layer, 'final', false), offset: layer.offset ?? ([0, 0] as Pt) });
    }
    this.fullAsked = '';
    // Drawn as a view of all of it at its own scale, so the worker keeps the fields for the stage's next view.
    const view: ViewSpec = { shrink: 1, region: [0, 0, this.doc.width, this.doc.height] };
    return new Promise((done) => full.render({ key: this.fullKey(), width: this.doc.width, height: this.doc.height, background: this.doc.background ?? [255, 255, 255, 255], layers, madeAt: performance.now(), view, done }));
  }

  private receiveFull(frame: FullFrame): void {
    this.stats.fullMs.push(frame.ms);
    this.stats.fullParts.push({ solveMs: frame.solveMs, drawMs: frame.drawMs, cycles: frame.cycles, wasmMiB: frame.wasmBytes / 2 ** 20 });
    if (frame.key !== this.fullKey() || this.dragging || this.store.view.playing) {
      // Stale: ask again for what is on screen now.
      this.requestFull();
      this.checkIdle();
      return;
    }
    this.fullShown = frame;
    this.viewWanted = false;
    this.onFull(frame);
    // Zoomed or panned while it was drawn: the view on screen now.
    this.requestView();
    this.checkIdle();
  }

  /** Drops the full-resolution frame on screen (the scene, the time or the view changed). */
  private dropFull(): void {
    if (this.fullShown && this.fullShown.key !== this.fullKey()) {
      this.fullShown = null;
      this.onFull(null);
    }
  }

  /** Asks the worker for every layer's field at the current time. */
  requestSolve(quality: Quality): void {
    this.dropFull();
    if (quality === 'final') this.requestFull();
    const time = this.store.view.time;
    if (!this.posed) {
      for (const rt of this.runtimes.values()) {
        if (rt.field || rt.gl?.sparse) {
          rt.field = null;
          rt.gl?.setField(null);
          rt.lastRequest = '';
        }
      }
      this.invalidate();
      return;
    }
    if (quality === 'draft') {
      if (this.settleTimer !== null) clearTimeout(this.settleTimer);
      this.settleTimer = window.setTimeout(() => {
        this.settleTimer = null;
        this.beginSettle();
        this.requestSolve('final');
      }, SETTLE_MS);
    }
    const frame = this.frameOf(time);
    const hit = quality === 'final' ? this.cached(frame) : undefined;
    if (hit) {
      this.shownFromCache = true;
      this.shownTime = time;
      for (const [key, kept] of hit) {
        const rt = this.runtimes.get(key);
        if (!rt?.gl) continue;
        if ('sparse' in kept) {
          // Kept at the draft mesh's pixels only (`cached` checked it can be drawn so): a
          // draft, until the full-resolution frame at rest arrives.
          rt.field = null;
          rt.gl.setSparseField(kept.sparse);
        } else if (this.playsSparse(rt)) {
          // Played as a draft drawn by the CPU: only the draft mesh's pixels of the field
          // are read (see `playsSparse`).
          rt.field = null;
          rt.gl.setSparseField(sparseValuesAt(rt.gl.draftPixels, kept));
        } else {
          const field = 'packed' in kept ? unpackField(kept) : kept;
          rt.field = field;
          rt.gl.setField(field);
        }
        rt.lastRequest = '';
        rt.shownSeq = ++this.seq;
      }
      const drawn = this.store.view.playing ? this.drawnFrame(frame) : null;
      if (drawn && drawn.draw.layers.every((l) => this.runtimes.get(l.key)?.gl?.sparse)) {
        this.gl.draftShrink = drawn.draw.shrink;
        this.gl.offerDraft(drawn.pixels, drawn.draw.width, drawn.draw.height, drawn.draw.background, this.drawList());
      } else if (this.store.view.playing) {
        // Not drawn ahead for this view (zoomed since, say): drawn now for the next loop.
        this.drawAhead();
      }
      if (this.stats.playback && this.store.view.playing) this.stats.playback.shown++;
      this.invalidate();
      return;
    }
    for (const layer of this.doc.layers) {
      const rt = this.runtimes.get(layer.name);
      if (!rt || !rt.gridReady) continue;
      const features = this.solveFeatures(layer, time);
      const options = this.solverOptions(layer, quality);
      const sig = JSON.stringify([features, options]);
      if (sig === rt.lastRequest) {
        // Solved already, and played as a sparse draft (`receive`): playback stopped (or an
        // overlay wants the whole field), so the field is shown whole, as it is not asked again.
        if (quality === 'final' && rt.field && rt.gl?.sparse && !this.playsSparse(rt)) rt.gl.setField(rt.field);
        continue;
      }
      rt.lastRequest = sig;
      const seq = ++this.seq;
      const sparse = quality === 'draft' && this.sparseDraft(rt);
      this.solverFor(quality).solve(layer.name, features, options, {
        madeAt: performance.now(),
        seq,
        quality,
        gen: rt.gridGen,
        pointerAt: quality === 'draft' ? this.lastPointerAt : null,
        time,
        rev: this.revision,
        frame,
        settleStart: quality === 'final' ? this.settleStart : null,
      }, { mesh: quality === 'final' && this.slowAntialias, sparse, draw: sparse && this.largeFrame ? this.draftDraw(seq) : undefined });
      if (quality === 'draft') this.follow(rt, layer, features, time);
    }
  }

  /**
   * While a drag's drafts are drawn, the full-resolution solver follows the pointer: it
   * solves the newest pose each time it is free (only the newest waits), keeps the field as
   * its next start, and sends back nothing to draw. The engine keeps these solves as its
   * warm-start history, whose combination of the poses along the drag puts the settle's
   * start within a cycle or two of its answer, where the pose before the drag was a dozen
   * cycles away; a settle on the very pose it solved last is answered at once. Only the grid
   * thin plate starts warm (the other methods solve from scratch), so only it follows.
   */
  private follow(rt: LayerRuntime, layer: Layer, features: SolveFeature[], time: number): void {
    if (!this.drafts) return;
    const options = this.solverOptions(layer, 'final');
    if (!startsWarm(options)) return;
    this.keep(rt, layer, features, options, 'follow', time);
  }

  /** Asks the full-resolution solver for a pose it solves and keeps, sending back only its report. */
  private keep(rt: LayerRuntime, layer: Layer, features: SolveFeature[], options: SolveOptions, quality: 'follow' | 'probe', time: number): void {
    const tag = { madeAt: performance.now(), seq: ++this.seq, quality, gen: rt.gridGen, time, rev: this.revision };
    this.solver.solve(layer.name, features, options, tag, { follow: true });
  }

  /**
   * The pointer rests or presses on control point `point` of feature `id` (the whole feature
   * when null) in pose mode: while the full-resolution solver has nothing else to do, it solves the
   * pose with that point moved by `PROBE_PX` in x and y, and keeps it, as it keeps the poses
   * a drag follows, in its warm-start history. The thin plate is linear in the pose, so a
   * drag of that point starts from the combination of the pose before and the probe:
   * exact where the samples move linearly with the control point (points, polylines,
   * regions, a whole feature moved), close for a spline's point (its knots move with its
   * points). The drag's later solves and its settle then start a cycle or a few from their
   * answers, where the follows alone (the drag's first short step beside the pose before)
   * left a quick drag's settle waiting behind a dozen cycles. `on` says which (counted in
   * `stats.probesAsked`).
   */
  probe(id: string, point: number | null, on: 'rest' | 'press'): void {
    if (!this.drafts || !this.posed || this.dragging || this.store.view.playing || this.solver.busy) return;
    const time = this.store.view.time;
    const sig = JSON.stringify([id, point, time, this.revision]);
    if (sig === this.lastProbe) return;
    this.lastProbe = sig;
    let asked = false;
    for (const layer of this.doc.layers) {
      const rt = this.runtimes.get(layer.name);
      if (!rt?.gridReady) continue;
      const options = this.solverOptions(layer, 'final');
      if (!startsWarm(options)) continue;
      const features = probedFeatures(this.solveFeatures(layer, time), id, point);
      if (!features) continue;
      this.keep(rt, layer, features, { ...options, tolerance: Math.max(options.tolerance ?? 0, PROBE_TOLERANCE_PX) }, 'probe', time);
      asked = true;
    }
    if (asked) this.stats.probesAsked[on]++;
  }

  /**
   * Whether a layer's drafts come at the draft mesh's pixels only: all a draft frame reads
   * (a few percent of the pixels, so the worker upsamples, sends and the page uploads that
   * much), unless an overlay draws the whole field (the heat map, the displaced wireframe).
   */
  private sparseDraft(rt: LayerRuntime): boolean {
    const { heat, mesh } = this.store.view.overlays;
    return rt.gl !== null && rt.selectedGen === rt.gridGen && heat === 'off' && !mesh;
  }

  /**
   * Whether a drag's drafts are drawn by the draft worker (`draftDraw`): a frame of more
   * than `DRAFT_PIXELS` pixels (a large picture's proxy). A smaller frame's draft is quick
   * to draw on the page, and the worker, which shares the cores with the full-resolution
   * solves following the drag, drew it no sooner (measured in the editor guide, Large
   * pictures).
   */
  private get largeFrame(): boolean {
    const { width, height } = this.frameSize;
    return width * height > DRAFT_PIXELS;
  }

  /**
   * What the draft worker is asked to draw after a sparse draft (request `seq`), where the
   * CPU draws drafts: the frame of every visible layer, each from its last sparse draft in
   * that worker, at the size the page would draw it, so the page's main thread only puts
   * the pixels on its canvas, and the next field and pointer move do not wait for the
   * drawing. Also what a frame drawn ahead for playback is (see `drawAhead`). Undefined
   * where the page draws drafts on WebGL2.
   */
  private draftDraw(seq: number, shrink = this.shrinkFor(true)): DraftDraw | undefined {
    if (!this.drafts || !this.gl.cpuDrafts) return undefined;
    const { width, height } = this.frameSize;
    const background = this.doc.background ?? [255, 255, 255, 255];
    const layers = this.drawList().map(({ layer, offset, opacity }) => ({ key: this.nameOf(layer), offset, opacity: opacity ?? 1 }));
    return { width, height, background, shrink, layers, seq, spec: JSON.stringify([width, height, background, shrink, layers]) };
  }

  private nameOf(layer: GlLayer): string {
    for (const rt of this.runtimes.values()) if (rt.gl === layer) return rt.name;
    return '';
  }

  /**
   * Shows the draft frame the draft worker drew (`ev.frame`) if it is the frame the page
   * would draw now: drawn for the same layers, size, background and offsets, from each
   * layer's sparse draft on screen (the request numbers match).
   */
  private offerDraft(ev: FieldEvent): void {
    const frame = ev.frame;
    if (!frame) return;
    const now = this.draftDraw(0);
    if (!now || now.spec !== frame.spec) return;
    for (const l of now.layers) {
      const rt = this.runtimes.get(l.key);
      if (!rt?.gl?.sparse || frame.seqs[l.key] !== rt.shownSeq) return;
    }
    this.gl.draftShrink = now.shrink;
    this.gl.offerDraft(frame.pixels, now.width, now.height, now.background, this.drawList());
  }

  /**
   * Drawing ahead: where the CPU draws drafts, each frame of the playback cache that has
   * every layer's field is drawn as the draft playback shows (`playsSparse`, at the draft's
   * size) by the draft worker, one at a time while nothing is dragged, and kept within
   * `DRAWN_BUDGET_BYTES`. Playback then puts each frame's pixels on the canvas and draws
   * nothing: drawing a proxy's frame on the page took most of a frame's time at 24 fps
   * (see the editor guide, Large pictures).
   */
  private drawAhead(): void {
    const drafts = this.drafts;
    if (!drafts || !this.gl.cpuDrafts || this.drawingAhead || this.dragging || this.exporting) return;
    const spec = this.draftDraw(0, this.draftShrink);
    if (!spec || spec.layers.length === 0) return;
    const rev = this.revision;
    const kept = this.drawnFrames;
    if (kept.rev !== rev || kept.spec !== spec.spec) this.drawnFrames = { rev, spec: spec.spec, bytes: 0, frames: new Map() };
    const drawn = proxySize(spec.width, spec.height, spec.shrink);
    const size = 4 * drawn.width * drawn.height;
    if (this.drawnFrames.bytes + size > DRAWN_BUDGET_BYTES) return;
    for (const frame of [...this.cache.frames.keys()].sort((a, b) => a - b)) {
      if (this.drawnFrames.frames.has(frame)) continue;
      const fields = this.cached(frame);
      if (!fields) continue;
      const values: Record<string, Float32Array> = {};
      for (const l of spec.layers) {
        const rt = this.runtimes.get(l.key);
        const field = fields.get(l.key);
        if (!rt?.gl || !field || !this.sparseDraft(rt) || !rt.gl.cpuDraftGeometry) return;
        // A copy: the values go to the worker.
        values[l.key] = 'sparse' in field ? field.sparse.slice() : sparseValuesAt(rt.gl.draftPixels, field);
      }
      const id = ++this.drawId;
      this.drawingAhead = { id, frame, rev, spec: spec.spec };
      drafts.draw(id, spec, values);
      return;
    }
  }

  private receiveDrawn(id: number, pixels: Uint8ClampedArray | null): void {
    const asked = this.drawingAhead;
    if (!asked || asked.id !== id) return;
    this.drawingAhead = null;
    const kept = this.drawnFrames;
    if (!pixels || asked.rev !== kept.rev || asked.spec !== kept.spec || asked.rev !== this.revision) return;
    kept.frames.set(asked.frame, pixels);
    kept.bytes += pixels.byteLength;
    this.drawAhead();
  }

  /** The draft frame drawn ahead for `frame` (see `drawAhead`), if it is what playback shows now. */
  private drawnFrame(frame: number | null): { pixels: Uint8ClampedArray; draw: DraftDraw } | null {
    const kept = this.drawnFrames;
    const pixels = frame === null ? undefined : kept.frames.get(frame);
    if (!pixels || kept.rev !== this.revision) return null;
    const draw = this.draftDraw(0, this.draftShrink);
    return draw && draw.spec === kept.spec ? { pixels, draw } : null;
  }

  /**
   * Whether a frame played from the playback cache is shown as a sparse draft drawn by the
   * CPU (the draft mesh's pixels of the kept field, at the draft's size): where the CPU
   * draws drafts, the overlays need no whole field, and the layer's draft mesh is the
   * grid's. WebGL2 on a software GPU took most of a frame's time for a proxy, and the page
   * waited for it; the whole field's unpacking and upload went too.
   */
  private playsSparse(rt: LayerRuntime): boolean {
    return this.store.view.playing && this.drawsCpuDraft(rt);
  }

  /**
   * Whether this layer's frame can be a draft drawn by the CPU from the draft mesh's pixels
   * of its field: a software GPU, no overlay that needs the whole field, no export.
   */
  private drawsCpuDraft(rt: LayerRuntime): boolean {
    return !this.exporting && this.gl.cpuDrafts && this.sparseDraft(rt) && !this.store.view.overlays.matte && rt.gl!.cpuDraftGeometry !== null;
  }

  /** Whether a settle draws the fast full frame first (see `frameTick`). */
  private get slowAntialias(): boolean {
    return this.proxy > 1 || this.antialiasMs > SLOW_ANTIALIAS_MS;
  }

  /** The pointer stopped or was released: ask for full resolution now. */
  settle(): void {
    if (this.settleTimer !== null) clearTimeout(this.settleTimer);
    this.settleTimer = null;
    this.beginSettle();
    this.requestSolve('final');
  }

  private beginSettle(): void {
    this.settleStart = performance.now();
    const cur = this.solver.current;
    this.settleBehind = cur ? String(cur.tag.quality ?? 'other') : null;
  }

  private receive(ev: FieldEvent): void {
    const rt = this.runtimes.get(ev.key);
    if (ev.tag.quality === 'follow' || ev.tag.quality === 'probe') {
      (ev.tag.quality === 'follow' ? this.stats.followSolveMs : this.stats.probeSolveMs).push(ev.ms);
      this.checkIdle();
      return;
    }
    if (!ev.tag.ahead) {
      this.lastReport = ev;
      if (ev.tag.quality === 'draft') this.stats.draftSolveMs.push(ev.ms);
      else this.stats.finalSolveMs.push(ev.ms);
    }
    if (ev.field && ev.tag.quality === 'final' && typeof ev.tag.frame === 'number' && ev.tag.rev === this.revision) {
      this.remember(ev.tag.frame, ev.key, ev.field);
      this.drawAhead();
    }
    if (ev.tag.ahead) {
      // Solved ahead: into the cache (above) only, then the next frame.
      if (ev.tag.rev === this.revision && typeof ev.tag.frame === 'number') this.stats.ahead.push(ev.tag.frame);
      this.onSolved(ev);
      if (!this.ahead?.busy) this.solveAhead();
      this.checkIdle();
      return;
    }
    if (ev.tag.prefetch && ev.tag.time !== this.store.view.time) {
      this.checkIdle();
      return;
    }
    const seq = typeof ev.tag.seq === 'number' ? ev.tag.seq : 0;
    if (rt && ev.tag.gen === rt.gridGen && this.posed && rt.gl && seq > rt.shownSeq) {
      rt.shownSeq = seq;
      this.shownFromCache = false;
      this.shownTime = typeof ev.tag.time === 'number' ? ev.tag.time : null;
      rt.field = ev.field;
      rt.notes = ev.report.notes ?? [];
      rt.error = null;
      const up0 = performance.now();
      if (ev.sparse) rt.gl.setSparseField(ev.sparse);
      else if (ev.field && ev.tag.quality === 'final' && this.playsSparse(rt)) {
        // `rt.field` stays: the frame at rest shows it whole (see `requestSolve`).
        rt.gl.setSparseField(sparseValuesAt(rt.gl.draftPixels, ev.field));
      } else rt.gl.setField(ev.field, ev.triangles ?? null);
      if (ev.frame && this.dragging && !this.store.view.playing) this.offerDraft(ev);
      const upload = performance.now() - up0;
      if (typeof ev.tag.pointerAt === 'number' && ev.tag.pointerAt > 0) {
        const start = ev.tag.pointerAt;
        this.pendingLatency.push(start);
        this.afterFrame((end, drawn) => this.stats.dragParts.push(frameParts(ev, start, null, upload, end, drawn)));
      }
      const pb = this.stats.playback;
      if (pb && this.store.view.playing && ev.tag.time === this.store.view.time) pb.shown++;
      if (ev.tag.quality === 'final' && typeof ev.tag.settleStart === 'number') {
        const start = ev.tag.settleStart;
        const behind = this.settleBehind;
        const parts = {} as SettleParts;
        this.afterFrame((end, drawn) => {
          this.stats.settle.push(end - start);
          Object.assign(parts, frameParts(ev, start, behind, upload, end, drawn));
          this.stats.settleParts.push(parts);
        });
        this.afterFrame((aa) => (parts.antialiased = aa - start), true);
        this.settleStart = null;
      }
      // A draft during a drag is drawn at once, not at the next animation frame: the GPU
      // starts on it sooner, and the page shows it at that frame all the same.
      if (this.dragging && !this.store.view.playing && ev.tag.quality === 'draft') this.frameTick();
      else this.invalidate();
    }
    this.onSolved(ev);
    this.checkIdle();
  }

  // -- Drawing --------------------------------------------------------------------------

  private afterFrameFns: FrameFn[] = [];
  private afterAntialiasedFns: FrameFn[] = [];
  /** Calls `fn` with the time the GPU finished the next frame (`antialiased`: the next full multisampled frame) drawn. */
  private afterFrame(fn: FrameFn, antialiased = false): void {
    (antialiased ? this.afterAntialiasedFns : this.afterFrameFns).push(fn);
  }
  /** Frames drawn whose GPU completion is still awaited (for `busy`). */
  private gpuPending = 0;

  invalidate(): void {
    if (this.frameQueued) return;
    this.frameQueued = true;
    requestAnimationFrame(() => {
      this.frameQueued = false;
      this.frameTick();
    });
  }

  /** The GPU's time for the last multisampled full frame (ms; 0 until one is drawn). */
  private antialiasMs = 0;
  /** A single-sampled full frame is on screen and its multisampled one is due next. */
  private antialiasDue = false;

  /**
   * The frame of the animation loop: a draft during a drag or playback, else the full
   * frame. Where multisampling is slow (a software GPU: about 0.4 s at 512 × 512 against
   * 0.15 s for one sample a pixel), the full frame comes first single-sampled and the
   * multisampled one once the GPU has drawn it.
   */
  private frameTick(): void {
    // A change that leaves the picture as drawn (the drawing moved, its field not yet
    // solved: every pointer move of a drag) redraws only the overlay. A software GPU would
    // otherwise draw the same frame again, and the page would wait for it.
    // A sparse draft can only be drawn as a draft (its field is known at its pixels).
    const layers = this.drawList();
    const draft = this.dragging || this.store.view.playing || holdsSparse(layers);
    this.gl.draftShrink = this.shrinkFor(draft);
    const doc = this.doc;
    const { width, height } = this.frameSize;
    const same = this.gl.drawn(width, height, doc.background ?? [255, 255, 255, 255], layers, !draft, draft);
    if (same && !this.antialiasDue && !this.pendingLatency.length && !this.afterFrameFns.length) {
      this.stats.frames.overlayOnly++;
      this.onFrame();
      this.checkIdle();
      return;
    }
    if (draft) {
      this.antialiasDue = false;
      this.renderNow(true);
    } else if (this.proxy > 1) {
      // A proxy's full frame is drawn fast (one sample a pixel) and never multisampled:
      // the full-resolution frame replaces it, and the page must be free to show it.
      this.antialiasDue = false;
      this.afterAntialiasedFns.length = 0;
      this.renderNow(false, false, true);
    } else if (!this.antialiasDue && this.slowAntialias) {
      this.antialiasDue = true;
      // Once the GPU has drawn it (so the two frames do not share the GPU).
      this.afterFrame(() => this.invalidate());
      this.renderNow(false, false, true);
    } else {
      this.antialiasDue = false;
      this.renderNow(false);
    }
  }

  /** The visible layers, back to front, as the renderer draws them. */
  private drawList(): DrawLayer[] {
    const layers: DrawLayer[] = [];
    for (const layer of this.doc.layers) {
      const rt = this.runtimes.get(layer.name);
      if (!rt?.gl || layer.visible === false || this.store.view.hidden.includes(layer.name)) continue;
      const o = layer.offset ?? ([0, 0] as Pt);
      layers.push({ layer: rt.gl, offset: this.proxy === 1 ? o : [o[0] / this.proxy, o[1] / this.proxy] });
    }
    return layers;
  }

  /**
   * Draws the current fields: the full frame (the pixel mesh, 4× multisampled, what the
   * CPU renderer draws) or a draft (the coarse mesh of `draftQuads`, one sample a pixel).
   */
  draw(draft: boolean, antialias = !draft, adaptive = false): void {
    const doc = this.doc;
    const { width, height } = this.frameSize;
    this.gl.draftShrink = this.shrinkFor(draft);
    this.gl.render(width, height, doc.background ?? [255, 255, 255, 255], this.drawList(), antialias, draft, adaptive);
  }

  /**
   * Draws the frame now. Frames during a drag or playback are drafts by default: a
   * software GPU pays per vertex, per triangle and per sample. The full frame follows
   * when the pointer rests or playback stops; exports ask for it (`draft = false`).
   */
  renderNow(draft: boolean = this.dragging || this.store.view.playing, antialias = !draft, adaptive = false): void {
    // A layer holding a sparse draft is drawn as a draft whatever the caller asked (the
    // renderer would): not a full frame, whose time and callbacks belong to a real one.
    if (holdsSparse(this.drawList())) [draft, antialias] = [true, false];
    const start = performance.now();
    this.stats.frames.drawn++;
    this.draw(draft, antialias, adaptive);
    const drawn = { start, end: performance.now() };
    this.onFrame();
    const latency = this.pendingLatency.splice(0);
    const fns = this.afterFrameFns.splice(0);
    const full = !draft && antialias;
    if (full) fns.push(...this.afterAntialiasedFns.splice(0));
    if (latency.length || fns.length || full) {
      // Timed to when the frame is on screen: when the GPU has drawn it.
      this.gpuPending++;
      void this.gl.finished().then((done) => {
        if (full) this.antialiasMs = done - start;
        for (const t of latency) this.stats.dragLatency.push(done - t);
        for (const fn of fns) fn(done, drawn);
        this.gpuPending--;
        this.checkIdle();
      });
    }
    this.checkIdle();
  }

  // -- Waiting (tests, export) -----------------------------------------------------------

  get busy(): boolean {
    // Solving ahead (a worker of its own, see `scheduleAhead`) is background work: not busy.
    return this.busyCount > 0 || this.clients.some((c) => c !== this.ahead && c.busy) || !!this.full?.busy || this.frameQueued || this.settleTimer !== null || this.gpuPending > 0;
  }

  private checkIdle(): void {
    if (this.busy) return;
    for (const w of this.waiters.splice(0)) w();
  }

  /** Resolves when every layer is loaded, solved and drawn. */
  idle(): Promise<void> {
    return new Promise((resolve) => {
      this.waiters.push(resolve);
      setTimeout(() => this.checkIdle(), 0);
    });
  }
}

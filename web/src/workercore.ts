// The solver worker's work, apart from the worker itself (see `worker.ts`): it owns the
// engine's grids and the last field of every layer, answers each message from the page
// with messages of its own, and can run (and be tested) anywhere an `Engine` loads.

import { type DraftHandle, Engine, type FieldData, type GridHandle, type ImageHandle } from './engine';
import { adaptiveTriangles } from './gl';
import { LastFields } from './lastfields';
import type { DraftDraw, DraftFrame, FromWorker, ToWorker } from './protocol';
import { proxySize } from './proxy';
import type { Pt } from './scene';

/** Sends a message to the page, handing over the buffers in `transfer`. */
export type Post = (msg: FromWorker, transfer?: Transferable[]) => void;

export class SolverWorker {
  private engine: Engine | null = null;
  private wasmUrl = '';
  private grids = new Map<string, GridHandle>();
  private last = new LastFields();
  /** Each grid's links (per node: bit 0 active, bit 1 linked right, bit 2 linked down). */
  private linksOf = new Map<string, Uint8Array>();
  /** Each layer's draft geometry in the engine (`draft-layer`), for the drafts this worker draws. */
  private draftLayers = new Map<string, DraftHandle>();
  /** Each layer's last sparse draft, and the request number it answered. */
  private drafted = new Map<string, { values: Float32Array; seq: number }>();

  /** `load` makes an engine from the URL the page names in its `init` message. */
  constructor(
    private post: Post,
    private load: (wasmUrl: string) => Promise<Engine> = (url) => Engine.fromUrl(url),
  ) {}

  async handle(msg: ToWorker): Promise<void> {
    try {
      if (msg.type === 'init') {
        this.wasmUrl = msg.wasmUrl;
        this.engine = await this.load(msg.wasmUrl);
        this.post({ type: 'ready' });
        return;
      }
      if (msg.type === 'memory') {
        const heap = (performance as unknown as { memory?: { usedJSHeapSize: number } }).memory;
        this.post({ type: 'memory', wasmBytes: this.engine?.x.memory.buffer.byteLength ?? 0, heapBytes: heap ? heap.usedJSHeapSize : null });
        return;
      }
      const engine = this.engine;
      if (!engine) throw new Error('The engine is not loaded yet.');
      if (msg.type === 'decode') {
        this.answer(() => engine.decode(msg.bytes), () => null, (image, message) =>
          this.post({ type: 'decoded', id: msg.id, image, message }, image ? [image.data.buffer] : []));
      } else if (msg.type === 'check') {
        this.answer(() => engine.validate(JSON.parse(msg.json)), (message) => [{ path: '', message }], (problems) =>
          this.post({ type: 'checked', id: msg.id, problems }));
      } else if (msg.type === 'grid') {
        this.forgetDraft(msg.key);
        this.grids.get(msg.key)?.free();
        const grid = engine.grid(msg.width, msg.height, msg.matte, msg.cuts);
        this.grids.set(msg.key, grid);
        this.last.regrid(msg.key, msg.width, msg.height);
        const links = grid.links();
        this.linksOf.set(msg.key, links.slice());
        this.post({ type: 'links', key: msg.key, links }, [links.buffer]);
      } else if (msg.type === 'drop') {
        this.forgetDraft(msg.key);
        this.grids.get(msg.key)?.free();
        this.grids.delete(msg.key);
        this.last.forget(msg.key);
        this.linksOf.delete(msg.key);
      } else if (msg.type === 'select') {
        this.gridOf(msg.key).select(msg.pixels);
      } else if (msg.type === 'draw') {
        const pixels = this.drawFrom(msg.draw, (key) => msg.values[key]);
        this.post({ type: 'drawn', id: msg.id, pixels }, pixels ? [pixels.buffer] : []);
      } else if (msg.type === 'draft-layer') {
        this.forgetDraft(msg.key);
        if (msg.geometry) this.draftLayers.set(msg.key, engine.draftLayer(msg.geometry));
      } else if (msg.type === 'solve') {
        this.solve(msg);
      } else if (msg.type === 'full-layer') {
        this.fullLayer(msg);
      } else if (msg.type === 'full-drop') {
        this.fullDrop(msg.key);
      } else if (msg.type === 'full-render') {
        this.fullRender(msg);
      } else if (msg.type === 'full-view') {
        this.fullView(msg);
      } else if (msg.type === 'full-export') {
        this.fullExport();
      }
    } catch (err) {
      if (err instanceof WebAssembly.RuntimeError && this.wasmUrl) {
        // A trap leaves the module's state unusable: start a fresh instance.
        const why = this.engine?.panicMessage() || err.message;
        this.engine = await this.load(this.wasmUrl);
        this.grids.clear();
        this.fulls.clear();
        this.viewed = null;
        this.last.clear();
        this.linksOf.clear();
        this.draftLayers.clear();
        this.drafted.clear();
        this.post({ type: 'reset', message: `The engine stopped (${why}) and was restarted.` });
      }
      const id = msg.type === 'solve' || msg.type === 'full-render' || msg.type === 'full-view' ? msg.id : null;
      const key = 'key' in msg ? msg.key : null;
      this.post({ type: 'error', id, key, message: (err as Error).message ?? String(err) });
      // A frame asked to be drawn is always answered: the page draws ahead one at a time.
      if (msg.type === 'draw') this.post({ type: 'drawn', id: msg.id, pixels: null });
    }
  }

  /**
   * Layers at the picture's own resolution (a proxied scene's full-resolution frames): the
   * picture, kept in the module once (a 4000 × 3000 picture is 48 MB), and the matte and
   * cuts its grid is built from (when first drawn).
   */
  private fulls = new Map<string, { image: ImageHandle | null; matte: Uint8Array | null; cuts: Pt[][]; grid: GridHandle | null }>();

  private fullLayer(msg: Extract<ToWorker, { type: 'full-layer' }>): void {
    const engine = this.engine!;
    this.viewed = null;
    const had = this.fulls.get(msg.key);
    had?.grid?.free();
    let image = had?.image ?? null;
    if (msg.image) {
      image?.free();
      image = engine.image(msg.image.width, msg.image.height, msg.image.data);
    }
    const matte = msg.matte ?? had?.matte ?? null;
    const grid = msg.grid && image && matte ? engine.grid(image.width, image.height, matte, msg.cuts) : null;
    this.fulls.set(msg.key, { image, matte, cuts: msg.cuts, grid });
  }

  private fullDrop(key: string): void {
    this.viewed = null;
    const full = this.fulls.get(key);
    full?.grid?.free();
    full?.image?.free();
    this.fulls.delete(key);
  }

  /**
   * Runs `f` and always answers the page (which waits for it) through `post`, with
   * `failed(message)` and the message where `f` throws; a trap is rethrown after the answer,
   * so the engine restarts (see `handle`).
   */
  private answer<T>(f: () => T, failed: (message: string) => T, post: (value: T, message?: string) => void): void {
    let value: T;
    let message: string | undefined;
    let trap: unknown = null;
    try {
      value = f();
    } catch (err) {
      message = (err as Error).message ?? String(err);
      value = failed(message);
      if (err instanceof WebAssembly.RuntimeError) trap = err;
    }
    post(value, message);
    if (trap) throw trap;
  }

  /**
   * A full-resolution frame: each layer solved on its own grid with the scene's settings,
   * at rest the identity, then drawn by the engine's renderer over the background, as
   * `inkwarp render` draws the frame. The pictures and the fields stay in the module. Each
   * grid keeps its solver from one frame to the next (`iw_grid_solve_kept`): the multigrid
   * hierarchy of the drawing's rest pose, built by the frame at rest when pose mode begins,
   * and the last fields at the scene's grid step (6 MB each at 4000 × 3000, step 4), so a
   * drag's frame starts from the frames before it instead of from scratch.
   */
  private fullRender(msg: Extract<ToWorker, { type: 'full-render' }>): void {
    const engine = this.engine!;
    let gridMs = 0;
    const layers = [];
    for (const l of msg.layers) {
      const full = this.fulls.get(l.key);
      if (!full?.image || !full.matte) throw new Error(`The layer ${l.key} has no picture at full resolution.`);
      const t0 = performance.now();
      full.grid ??= engine.grid(full.image.width, full.image.height, full.matte, full.cuts);
      gridMs += performance.now() - t0;
      layers.push({ image: full.image, grid: full.grid, features: l.features, options: l.options, offset: l.offset });
    }
    // A view leaves the fields in the module for the next view; a whole frame takes them.
    this.viewed = null;
    const { pixels, reports, solveMs, drawMs } = engine.renderSolved(msg.width, msg.height, msg.background, layers, msg.view ?? null);
    if (msg.view) this.viewed = { width: msg.width, height: msg.height, background: msg.background, layers: msg.layers.map((l) => ({ key: l.key, offset: l.offset, rest: l.features === null })) };
    const cycles = reports.filter((r) => r !== null).map((r) => r!.cycles ?? 0);
    this.post({ type: 'full', id: msg.id, width: msg.width, height: msg.height, pixels, solveMs: solveMs + gridMs, drawMs, cycles, wasmBytes: engine.x.memory.buffer.byteLength, view: msg.view }, [pixels.buffer]);
  }

  /** The last frame drawn as a view (its fields kept in the module), for `full-view`. */
  private viewed: { width: number; height: number; background: [number, number, number, number]; layers: { key: string; offset: Pt; rest: boolean }[] } | null = null;

  /** Another view of the last frame drawn as a view, from the fields its grids keep: no solve. */
  private fullView(msg: Extract<ToWorker, { type: 'full-view' }>): void {
    const v = this.viewed;
    if (!v) throw new Error('There is no solved frame to draw a view of: ask for the frame (full-render with a view) first.');
    const layers = v.layers.map((l) => {
      const full = this.fulls.get(l.key);
      if (!full?.image || !full.grid) throw new Error(`The layer ${l.key} has no picture or grid at full resolution.`);
      return { image: full.image, grid: full.grid, offset: l.offset, rest: l.rest };
    });
    const t0 = performance.now();
    const pixels = this.engine!.drawView(v.width, v.height, v.background, layers, msg.view);
    this.post({ type: 'full', id: msg.id, width: v.width, height: v.height, pixels, solveMs: 0, drawMs: performance.now() - t0, cycles: [], wasmBytes: this.engine!.x.memory.buffer.byteLength, view: msg.view }, [pixels.buffer]);
  }

  /** Sends every full-resolution layer back (its picture copied out of the module), for a fresh worker. */
  private fullExport(): void {
    const layers = [];
    for (const [key, f] of this.fulls) {
      if (!f.image || !f.matte) continue;
      layers.push({ key, image: { width: f.image.width, height: f.image.height, data: f.image.read() }, matte: f.matte.slice(), cuts: f.cuts });
    }
    this.post({ type: 'full-layers', layers }, layers.flatMap((l) => [l.image.data.buffer, l.matte.buffer]));
  }

  private forgetDraft(key: string): void {
    this.draftLayers.get(key)?.free();
    this.draftLayers.delete(key);
    this.drafted.delete(key);
  }

  /**
   * The draft frame after layer `key`'s sparse draft `values`: every layer of `draw` from
   * its last sparse draft here, drawn as the page would draw it (`Engine.drawDraft`), so the
   * page's main thread only puts the pixels on its canvas. Undefined when a layer has no
   * draft geometry or no sparse draft yet (the page then draws the frame itself).
   */
  private drawDraft(key: string, values: Float32Array, draw: DraftDraw): DraftFrame | undefined {
    // A copy: `values` goes to the page.
    this.drafted.set(key, { values: values.slice(), seq: draw.seq });
    const seqs: Record<string, number> = {};
    for (const l of draw.layers) seqs[l.key] = this.drafted.get(l.key)?.seq ?? -1;
    const t0 = performance.now();
    const pixels = this.drawFrom(draw, (k) => this.drafted.get(k)?.values);
    return pixels ? { pixels, seqs, spec: draw.spec, drawMs: performance.now() - t0 } : undefined;
  }

  /** The draft frame of `draw`, each layer from `valuesOf` its sparse field; null when a layer has no draft geometry or field here. */
  private drawFrom(draw: DraftDraw, valuesOf: (key: string) => Float32Array | undefined): Uint8ClampedArray | null {
    const layers = [];
    for (const l of draw.layers) {
      const handle = this.draftLayers.get(l.key);
      const values = valuesOf(l.key);
      if (!handle || !values) return null;
      layers.push({ draft: handle, values, offset: l.offset, opacity: l.opacity });
    }
    const size = proxySize(draw.width, draw.height, draw.shrink);
    const pixels = new Uint8ClampedArray(4 * size.width * size.height);
    this.engine!.drawDraft(pixels, draw.width, draw.height, draw.background, layers, draw.shrink);
    return pixels;
  }

  private gridOf(key: string): GridHandle {
    const grid = this.grids.get(key);
    if (!grid) throw new Error(`No grid for layer ${key}.`);
    return grid;
  }

  private solve(msg: Extract<ToWorker, { type: 'solve' }>): void {
    const grid = this.gridOf(msg.key);
    const t0 = performance.now();
    const head = { type: 'field' as const, id: msg.id, key: msg.key, gridStep: msg.options.grid_step ?? 1, began: performance.timeOrigin + t0 };
    const ended = () => performance.timeOrigin + performance.now();
    if (msg.sparse) {
      // A draft at the draft mesh's pixels: nothing to keep, the drafts' own history (in
      // the engine) is the next one's start.
      const { values, report } = grid.solveAt(msg.features, msg.options);
      const ms = performance.now() - t0;
      const frame = msg.draw ? this.drawDraft(msg.key, values, msg.draw) : undefined;
      this.post({ ...head, field: null, sparse: values, frame, report, ms, ended: ended() }, frame ? [values.buffer, frame.pixels.buffer] : [values.buffer]);
      return;
    }
    const { field, report, reused } = this.last.solve(msg.key, grid, msg.features, msg.options, msg.warm);
    const ms = performance.now() - t0;
    if (msg.follow) {
      // Following a drag (or probing, see `App.probe`): the field stays here as the next
      // start, the page draws drafts.
      this.post({ ...head, field: null, report, ms, ended: ended() });
      return;
    }
    // Send copies: the worker keeps its own field as the next warm start.
    const out: FieldData = { width: field.width, height: field.height, dx: field.dx.slice(), dy: field.dy.slice() };
    // The page draws a full-resolution field first through these (on a software GPU),
    // and they take a pass over every pixel: built here, the page never waits for them.
    const links = msg.mesh ? this.linksOf.get(msg.key) : undefined;
    const triangles = links ? adaptiveTriangles(field.width, field.height, links, field) : undefined;
    this.post({ ...head, field: out, reused, triangles, report, ms, ended: ended() }, [
      out.dx.buffer,
      out.dy.buffer,
      ...(triangles ? [triangles.buffer] : []),
    ]);
  }
}

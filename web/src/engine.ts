// Typed wrapper over the WebAssembly build of inkwarp-core (crates/inkwarp-wasm).
//
// The module exports a plain C ABI: we copy arguments into its linear memory, call, and
// copy results out. JSON results come back through a result buffer.

import { proxySize } from './proxy';
import type { Limits } from './limits';
import type { Kind, Method, Pt } from './scene';

interface Exports {
  memory: WebAssembly.Memory;
  iw_alloc(len: number): number;
  iw_free(ptr: number, len: number): void;
  iw_result_ptr(): number;
  iw_result_len(): number;
  iw_grid_new(w: number, h: number, matte: number, matteLen: number, cuts: number, cutsLen: number): number;
  iw_grid_free(h: number): void;
  iw_grid_links(h: number, out: number, len: number): number;
  iw_solve(h: number, req: number, reqLen: number, initial: number, out: number): number;
  iw_grid_select(h: number, pixels: number, len: number): number;
  iw_solve_at(h: number, req: number, reqLen: number, out: number): number;
  iw_curve(req: number, len: number): number;
  iw_canvas_new(w: number, h: number, r: number, g: number, b: number, a: number): number;
  iw_canvas_free(h: number): void;
  iw_canvas_draw(c: number, g: number, image: number, field: number, ox: number, oy: number): number;
  iw_canvas_read(c: number, out: number, len: number): number;
  iw_image_new(ptr: number, w: number, h: number): number;
  iw_image_free(h: number): void;
  iw_image_read(h: number, out: number, len: number): number;
  iw_grid_solve_kept(g: number, req: number, reqLen: number): number;
  iw_frame_draw(req: number, reqLen: number, out: number, outLen: number): number;
  iw_view_draw(req: number, reqLen: number, out: number, outLen: number): number;
  iw_scene_check(json: number, len: number): number;
  iw_points_at(req: number, len: number): number;
  iw_methods(): number;
  iw_limits(): number;
  iw_decode(ptr: number, len: number): number;
  iw_decoded_take(out: number, len: number): number;
  iw_matte_values(rgba: number, w: number, h: number, out: number): number;
  iw_draft_new(w: number, h: number, pixels: number, coarse: number, coarseLen: number, skirts: number, skirtsLen: number, links: number, index: number, reads: number, pushBorder: number): number;
  iw_draft_set_triangles(h: number, coarse: number, coarseLen: number): number;
  iw_draft_free(h: number): void;
  iw_draft_draw(out: number, w: number, h: number, shrink: number, r: number, g: number, b: number, a: number, layers: number, count: number): number;
  iw_init(): void;
  iw_panic_ptr(): number;
  iw_panic_len(): number;
}

export class EngineError extends Error {
  constructor(message: string) {
    super(message);
    this.name = 'EngineError';
  }
}

/** One feature as the solver sees it: rest and posed control points. */
export interface SolveFeature {
  id?: string;
  kind: Kind;
  rest: Pt[];
  pose: Pt[];
  closed?: boolean;
  spline_outline?: boolean;
}

/** A request's solver settings, named as in the scene format's `solver`. */
export interface SolveOptions {
  /** The interpolant (default `tps`, the grid thin plate). */
  method?: Method;
  tension?: number;
  tolerance?: number;
  grid_step?: number;
  max_cycles?: number | null;
  /** How the grid thin plate is relaxed (default `multigrid`). */
  scheme?: 'multigrid' | 'southwell';
  /** A draft while dragging: `tps-exact` is then previewed on every `grid_step`-th pixel. */
  preview?: boolean;
  /** The interpolants' settings, as in the scene format's `solver`. */
  beier_neely?: { a?: number; b?: number; p?: number };
  tps_exact?: { max_samples?: number };
  /** Arc-length spacing of the samples (the scene engine uses the grid step). */
  spacing_px?: number;
  /** `hold`: the layer's outer edge stays put (the layer's `"border"`; default `free`). */
  border?: 'free' | 'hold';
}

/** What a solve did. */
export interface SolveReport {
  method: Method;
  /** Samples of the drawing (region interiors included). */
  samples: number;
  /** Full sentences worth showing (e.g. a continuity matte the method ignores). */
  notes: string[];
  // The grid thin plate (`tps`):
  cycles?: number;
  final_change_px?: number;
  residual?: number;
  constrained_nodes?: number;
  constrained_samples?: number;
  dropped_samples?: number;
  converged?: boolean;
  probe_cycles?: number; // a slow solve's probe for slow modes, beside `cycles`
  // The other methods:
  samples_used?: number;
  line_pairs_used?: number;
  dropped?: number;
  ignored_matte?: boolean;
}

/** A displacement field, planar: `dx[y * width + x]`, `dy[...]`. */
export interface FieldData {
  width: number;
  height: number;
  dx: Float32Array;
  dy: Float32Array;
}

const enc = new TextEncoder();
const dec = new TextDecoder();

/** A solve request as the module reads it (curves sampled every `grid_step` by default). */
function request(features: SolveFeature[], options: SolveOptions): Uint8Array {
  const { spacing_px, border, ...rest } = options;
  return enc.encode(JSON.stringify({ features, options: rest, spacing_px: spacing_px ?? rest.grid_step ?? 1, border: border ?? 'free' }));
}

/**
 * What a frame drawn by the CPU needs of a layer (`Engine.drawDraft`): its premultiplied
 * RGBA8, the triangles it draws (a draft's `draftQuads`, a fast full frame's
 * `adaptiveTriangles`), the skirt quarters it draws (a draft's inner ones, a fast full
 * frame's all; 6 vertices of 6 floats each a quarter), its links, and per pixel its place
 * among the `reads` pixels whose (dx, dy) pairs it is drawn from (`draftPixels`, or every
 * pixel).
 */
export interface DraftGeometry {
  width: number;
  height: number;
  premultiplied: Uint8Array;
  coarse: Uint32Array;
  skirts: Float32Array;
  links: Uint8Array;
  index: Uint32Array;
  reads: number;
  /**
   * Whether the triangles' vertices on the layer's border move out by half a pixel (true,
   * the default: a draft, which draws no skirts along the border), or stay (a fast full
   * frame, which passes every skirt quarter).
   */
  pushBorder?: boolean;
}

/** One layer of a frame drawn by the CPU (`Engine.drawDraft`): its handle, (dx, dy) pairs at the pixels it reads, offset and opacity. */
export interface DraftLayer {
  draft: DraftHandle;
  values: Float32Array;
  offset: Pt;
  opacity?: number;
}

/** A layer's draft geometry living in the module; free it when the layer's mesh or image changes. */
export class DraftHandle {
  constructor(
    readonly engine: Engine,
    readonly handle: number,
  ) {}

  /** Replaces the layer's triangles (pixel indices), keeping the rest of it. */
  setTriangles(coarse: Uint32Array): void {
    const e = this.engine;
    e.withCopies((copy) => e.check(e.x.iw_draft_set_triangles(this.handle, copy(coarse), coarse.length)));
  }

  free(): void {
    this.engine.x.iw_draft_free(this.handle);
  }
}

/**
 * A view of a frame (`Engine.drawView`): the frame drawn `shrink` times smaller (a whole
 * factor, 1: at the picture's resolution) and the region of it drawn, `[x0, y0, x1, y1]` in
 * the smaller frame's pixels (end exclusive).
 */
export interface ViewSpec {
  shrink: number;
  region: [number, number, number, number];
}

/** A picture (straight RGBA8) kept in the module, for `Engine.renderSolved`; free it when the layer goes away. */
export class ImageHandle {
  constructor(
    readonly engine: Engine,
    readonly handle: number,
    readonly width: number,
    readonly height: number,
  ) {}

  /** Its pixels, copied out. */
  read(): Uint8Array {
    const len = 4 * this.width * this.height;
    return this.engine.withBuffer(len, (ptr) => {
      this.engine.check(this.engine.x.iw_image_read(this.handle, ptr, len));
      return this.engine.u8(ptr, len).slice();
    });
  }

  free(): void {
    this.engine.x.iw_image_free(this.handle);
  }
}

/** A grid (solve domain) living in the module; free it when the layer goes away. */
export class GridHandle {
  constructor(
    readonly engine: Engine,
    readonly handle: number,
    readonly width: number,
    readonly height: number,
  ) {}

  /** Per node: bit 0 active, bit 1 linked right, bit 2 linked down. */
  links(): Uint8Array {
    const n = this.width * this.height;
    return this.engine.withBuffer(n, (ptr) => {
      this.engine.check(this.engine.x.iw_grid_links(this.handle, ptr, n));
      return this.engine.u8(ptr, n).slice();
    });
  }

  /** The drawing's field by `options.method`; `initial` warm-starts `tps` (planar dx then dy). */
  solve(features: SolveFeature[], options: SolveOptions, initial: FieldData | null): { field: FieldData; report: SolveReport } {
    const n = this.width * this.height;
    const e = this.engine;
    const req = request(features, options);
    const reqPtr = e.put(req);
    const fieldPtr = e.x.iw_alloc(8 * n);
    try {
      if (initial) {
        e.f32(fieldPtr, n).set(initial.dx);
        e.f32(fieldPtr + 4 * n, n).set(initial.dy);
      }
      const rc = e.x.iw_solve(this.handle, reqPtr, req.length, initial ? fieldPtr : 0, fieldPtr);
      const report = e.check(rc) as SolveReport;
      const field = {
        width: this.width,
        height: this.height,
        dx: e.f32(fieldPtr, n).slice(),
        dy: e.f32(fieldPtr + 4 * n, n).slice(),
      };
      return { field, report };
    } finally {
      e.x.iw_free(reqPtr, req.length);
      e.x.iw_free(fieldPtr, 8 * n);
    }
  }

  /** Chooses the pixels (row-major indices) that `solveAt` computes. */
  select(pixels: Uint32Array): void {
    const e = this.engine;
    e.withCopies((copy) => e.check(e.x.iw_grid_select(this.handle, copy(pixels), pixels.length)));
    this.selected = pixels.length;
  }

  /** Pixels chosen by `select`. */
  selected = 0;

  /**
   * `solve` at the pixels chosen by `select`: their (dx, dy) pairs. A grid thin plate at a
   * `grid_step` above 1 (a draft) is upsampled at those pixels alone, warm-started from the
   * earlier drafts; any other request is solved in full and read there.
   */
  solveAt(features: SolveFeature[], options: SolveOptions): { values: Float32Array; report: SolveReport } {
    const e = this.engine;
    const req = request(features, options);
    const reqPtr = e.put(req);
    const len = 2 * this.selected;
    const outPtr = e.x.iw_alloc(4 * len);
    try {
      const report = e.check(e.x.iw_solve_at(this.handle, reqPtr, req.length, outPtr)) as SolveReport;
      return { values: e.f32(outPtr, len).slice(), report };
    } finally {
      e.x.iw_free(reqPtr, req.length);
      e.x.iw_free(outPtr, 4 * len);
    }
  }

  free(): void {
    this.engine.x.iw_grid_free(this.handle);
  }
}

export class Engine {
  constructor(readonly x: Exports) {}

  static async fromBytes(bytes: BufferSource): Promise<Engine> {
    const { instance } = await WebAssembly.instantiate(bytes, {});
    const engine = new Engine(instance.exports as unknown as Exports);
    engine.x.iw_init();
    return engine;
  }

  /** The message of the engine's last panic (after a trap), or ''. */
  panicMessage(): string {
    const len = this.x.iw_panic_len();
    return len ? dec.decode(this.u8(this.x.iw_panic_ptr(), len)) : '';
  }

  static async fromUrl(url: string): Promise<Engine> {
    const resp = await fetch(url);
    if (!resp.ok) throw new EngineError(`Could not load the engine from ${url} (HTTP ${resp.status}).`);
    return Engine.fromBytes(await resp.arrayBuffer());
  }

  u8(ptr: number, len: number): Uint8Array {
    return new Uint8Array(this.x.memory.buffer, ptr, len);
  }

  f32(ptr: number, len: number): Float32Array {
    return new Float32Array(this.x.memory.buffer, ptr, len);
  }

  /** Copies bytes into a fresh allocation; the caller frees it with `len`. */
  put(bytes: Uint8Array): number {
    const ptr = this.x.iw_alloc(bytes.length);
    this.u8(ptr, bytes.length).set(bytes);
    return ptr;
  }

  /** Calls `fn` with `copy`, which copies an array into the module and returns where; all are freed after. */
  withCopies<T>(fn: (copy: (data: ArrayBufferView) => number) => T): T {
    const held: [number, number][] = [];
    try {
      return fn((data) => {
        const ptr = this.put(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
        held.push([ptr, data.byteLength]);
        return ptr;
      });
    } finally {
      for (const [ptr, len] of held) this.x.iw_free(ptr, len);
    }
  }

  withBuffer<T>(len: number, fn: (ptr: number) => T): T {
    const ptr = this.x.iw_alloc(len);
    try {
      return fn(ptr);
    } finally {
      this.x.iw_free(ptr, len);
    }
  }

  /** The result buffer parsed as JSON (null when empty). */
  result(): unknown {
    const len = this.x.iw_result_len();
    if (len === 0) return null;
    return JSON.parse(dec.decode(this.u8(this.x.iw_result_ptr(), len)));
  }

  /** Turns a status into the result or an EngineError. */
  check(status: number): unknown {
    const r = this.result();
    if (status !== 0) throw new EngineError((r as { error?: string })?.error ?? 'The engine failed.');
    return r;
  }

  grid(width: number, height: number, matte: Uint8Array | null, cuts: Pt[][]): GridHandle {
    const mattePtr = matte ? this.put(matte) : 0;
    const cutsBytes = enc.encode(cuts.length ? JSON.stringify(cuts) : '');
    const cutsPtr = cutsBytes.length ? this.put(cutsBytes) : 0;
    try {
      const h = this.x.iw_grid_new(width, height, mattePtr, matte ? matte.length : 0, cutsPtr, cutsBytes.length);
      if (h === 0) this.check(1);
      return new GridHandle(this, h, width, height);
    } finally {
      if (matte) this.x.iw_free(mattePtr, matte.length);
      if (cutsBytes.length) this.x.iw_free(cutsPtr, cutsBytes.length);
    }
  }

  /**
   * The engine's validation of a scene document: every problem with its JSON path (empty
   * when the scene is fine). Images are checked by the editor as it decodes them.
   */
  validate(doc: unknown): { path: string; message: string }[] {
    const bytes = enc.encode(JSON.stringify(doc));
    const ptr = this.put(bytes);
    try {
      return this.check(this.x.iw_scene_check(ptr, bytes.length)) as { path: string; message: string }[];
    } finally {
      this.x.iw_free(ptr, bytes.length);
    }
  }

  private json(fn: (ptr: number, len: number) => number, value: unknown): unknown {
    const bytes = enc.encode(JSON.stringify(value));
    const ptr = this.put(bytes);
    try {
      return this.check(fn(ptr, bytes.length));
    } finally {
      this.x.iw_free(ptr, bytes.length);
    }
  }

  /** The scene format's ranges (inkwarp_core::limits), which the editor's fields hold values to. */
  limits(): Limits {
    return (this.limitsKept ??= this.check(this.x.iw_limits()) as Limits);
  }

  private limitsKept: Limits | undefined;

  /** The field methods and whether this build computes them. */
  methods(): { name: Method; available: boolean }[] {
    return this.check(this.x.iw_methods()) as { name: Method; available: boolean }[];
  }

  /** A feature's control points at time `t` by the engine's keyframe interpolation. */
  pointsAt(rest: Pt[], keys: { t: number; points: Pt[]; interpolation?: string }[], t: number): Pt[] {
    return this.json((p, l) => this.x.iw_points_at(p, l), { rest, keys, t }) as Pt[];
  }

  /** Decodes a PNG/JPEG (bytes or a data: URI) with the engine's decoder: straight RGBA8. */
  decode(input: Uint8Array): { width: number; height: number; data: Uint8Array } {
    const ptr = this.put(input);
    let size: { width: number; height: number };
    try {
      size = this.check(this.x.iw_decode(ptr, input.length)) as { width: number; height: number };
    } finally {
      this.x.iw_free(ptr, input.length);
    }
    const len = 4 * size.width * size.height;
    const data = this.withBuffer(len, (out) => {
      this.check(this.x.iw_decoded_take(out, len));
      return this.u8(out, len).slice();
    });
    return { ...size, data };
  }

  /** The engine's matte values (grey × alpha) of a straight RGBA8 image. */
  matteValues(rgba: Uint8Array, width: number, height: number): Uint8Array {
    const n = width * height;
    const src = this.put(rgba);
    try {
      return this.withBuffer(n, (out) => {
        this.check(this.x.iw_matte_values(src, width, height, out));
        return this.u8(out, n).slice();
      });
    } finally {
      this.x.iw_free(src, rgba.length);
    }
  }

  /** The curve through control points as a dense polyline (for overlays). */
  curve(kind: Kind, points: Pt[], closed: boolean, splineOutline: boolean, spacingPx = 2): Pt[] {
    const req = enc.encode(JSON.stringify({ kind, points, closed, spline_outline: splineOutline, spacing_px: spacingPx }));
    const ptr = this.put(req);
    try {
      return this.check(this.x.iw_curve(ptr, req.length)) as Pt[];
    } finally {
      this.x.iw_free(ptr, req.length);
    }
  }

  /** A layer's draft geometry, copied into the module (see `drawDraft`). */
  draftLayer(g: DraftGeometry): DraftHandle {
    const n = g.width * g.height;
    if (g.premultiplied.length !== 4 * n || g.links.length !== n || g.index.length !== n) throw new EngineError('A draft layer needs its pixels, links and index at every pixel.');
    const h = this.withCopies((copy) =>
      this.x.iw_draft_new(g.width, g.height, copy(g.premultiplied), copy(g.coarse), g.coarse.length, copy(g.skirts), g.skirts.length, copy(g.links), copy(g.index), g.reads, g.pushBorder === false ? 0 : 1),
    );
    if (h === 0) this.check(1);
    return new DraftHandle(this, h);
  }

  /**
   * A draft frame drawn by the CPU into `out` (straight RGBA8, as an `ImageData` holds it):
   * the WebGL2 draft's triangles and colours, layers composited back to front over the
   * background (straight RGBA8), each from its sparse draft's (dx, dy) pairs. With `shrink`
   * above 1 the frame is drawn that many times smaller (`out` holds ⌈width / shrink⌉ ×
   * ⌈height / shrink⌉ pixels): the same triangles, coloured from the layers' pixels
   * box-filtered by that factor (see `iw_draft_draw`).
   */
  drawDraft(
    out: Uint8ClampedArray,
    width: number,
    height: number,
    background: [number, number, number, number],
    layers: DraftLayer[],
    shrink = 1,
  ): void {
    const drawn = proxySize(width, height, shrink);
    const len = 4 * drawn.width * drawn.height;
    this.withCopies((copy) => {
      const args = Float64Array.from(layers.flatMap((l) => [l.draft.handle, copy(l.values), l.values.length, l.offset[0], l.offset[1], l.opacity ?? 1]));
      const argPtr = copy(args);
      this.withBuffer(len, (ptr) => {
        const [r, g, b, a] = background;
        this.check(this.x.iw_draft_draw(ptr, width, height, shrink, r, g, b, a, argPtr, layers.length));
        out.set(this.u8(ptr, len));
      });
    });
  }

  /**
   * The reference CPU renderer: composites layers (straight RGBA8 images with their grids
   * and fields) over a background, returns straight RGBA8.
   */
  /** Keeps a picture (straight RGBA8) in the module, copied once. */
  image(width: number, height: number, data: Uint8Array): ImageHandle {
    if (data.length !== 4 * width * height) throw new EngineError(`A ${width} × ${height} picture needs ${4 * width * height} bytes of RGBA; it has ${data.length}.`);
    const ptr = this.put(data);
    try {
      const h = this.x.iw_image_new(ptr, width, height);
      if (h === 0) this.check(1);
      return new ImageHandle(this, h, width, height);
    } finally {
      this.x.iw_free(ptr, data.length);
    }
  }

  /**
   * `renderCpu` of layers whose pictures are kept in the module (`image`), each solved
   * in the module (`features` null: at rest; warm from the grid's earlier solves, see
   * `iw_grid_solve_kept`) and drawn straight from its field,
   * which never leaves the module: a large picture's frame without copies of its picture
   * or its field. Returns straight RGBA8, each layer's report (null at rest) and the time
   * the solves and the drawing took (ms).
   */
  renderSolved(
    width: number,
    height: number,
    background: [number, number, number, number],
    layers: { image: ImageHandle; grid: GridHandle; features: SolveFeature[] | null; options: SolveOptions; offset: Pt }[],
    view: ViewSpec | null = null,
  ): { pixels: Uint8Array; reports: (SolveReport | null)[]; solveMs: number; drawMs: number } {
    let solveMs = 0;
    const reports: (SolveReport | null)[] = [];
    // Every layer solved first, its field kept in the module; then the frame is drawn band
    // by band straight into RGBA8 (no canvas of the whole frame), each field taken as its
    // layer's positions.
    for (const l of layers) {
      if (l.image.width !== l.grid.width || l.image.height !== l.grid.height) throw new EngineError("A layer to render needs its picture at its grid's size.");
      const t0 = performance.now();
      if (l.features) {
        const req = request(l.features, l.options);
        const reqPtr = this.put(req);
        try {
          reports.push(this.check(this.x.iw_grid_solve_kept(l.grid.handle, reqPtr, req.length)) as SolveReport);
        } finally {
          this.x.iw_free(reqPtr, req.length);
        }
      } else {
        reports.push(null);
      }
      solveMs += performance.now() - t0;
    }
    const t1 = performance.now();
    if (view) {
      return { pixels: this.drawView(width, height, background, layers.map((l) => ({ ...l, rest: l.features === null })), view), reports, solveMs, drawMs: performance.now() - t1 };
    }
    const frame = enc.encode(
      JSON.stringify({ width, height, background, layers: layers.map((l) => ({ grid: l.grid.handle, image: l.image.handle, offset: l.offset })) }),
    );
    const framePtr = this.put(frame);
    try {
      const len = 4 * width * height;
      const pixels = this.withBuffer(len, (ptr) => {
        this.check(this.x.iw_frame_draw(framePtr, frame.length, ptr, len));
        return this.u8(ptr, len).slice();
      });
      return { pixels, reports, solveMs, drawMs: performance.now() - t1 };
    } finally {
      this.x.iw_free(framePtr, frame.length);
    }
  }

  /**
   * A region of the frame drawn `view.shrink` times smaller (`iw_view_draw`), each layer by
   * the field its grid keeps from its last `iw_grid_solve_kept` (left in the module, so the
   * view can be drawn again as it is zoomed and panned), or at rest (`rest`). Straight
   * RGBA8, `(x1 − x0) × (y1 − y0)` pixels of the smaller frame.
   */
  drawView(
    width: number,
    height: number,
    background: [number, number, number, number],
    layers: { image: ImageHandle; grid: GridHandle; offset: Pt; rest: boolean }[],
    view: ViewSpec,
  ): Uint8Array {
    const [x0, y0, x1, y1] = view.region;
    const req = enc.encode(
      JSON.stringify({ width, height, background, shrink: view.shrink, region: view.region, layers: layers.map((l) => ({ grid: l.grid.handle, image: l.image.handle, offset: l.offset, rest: l.rest })) }),
    );
    const reqPtr = this.put(req);
    try {
      const len = 4 * (x1 - x0) * (y1 - y0);
      return this.withBuffer(len, (ptr) => {
        this.check(this.x.iw_view_draw(reqPtr, req.length, ptr, len));
        return this.u8(ptr, len).slice();
      });
    } finally {
      this.x.iw_free(reqPtr, req.length);
    }
  }

  renderCpu(
    width: number,
    height: number,
    background: [number, number, number, number],
    layers: { image: Uint8Array; grid: GridHandle; field: FieldData; offset: Pt }[],
  ): Uint8Array {
    const [r, g, b, a] = background;
    const canvas = this.x.iw_canvas_new(width, height, r, g, b, a);
    try {
      for (const l of layers) {
        const n = l.grid.width * l.grid.height;
        if (l.field.dx.length !== n || l.field.dy.length !== n || l.image.length !== 4 * n) throw new EngineError('A layer to render needs its image and field at every pixel of its grid.');
        // The field as the adapter reads it, written straight into the module: the Δx
        // plane, then the Δy plane.
        this.withBuffer(8 * n, (planes) => {
          this.f32(planes, n).set(l.field.dx);
          this.f32(planes + 4 * n, n).set(l.field.dy);
          this.withCopies((copy) => this.check(this.x.iw_canvas_draw(canvas, l.grid.handle, copy(l.image), planes, l.offset[0], l.offset[1])));
        });
      }
      const len = 4 * width * height;
      return this.withBuffer(len, (ptr) => {
        this.check(this.x.iw_canvas_read(canvas, ptr, len));
        return this.u8(ptr, len).slice();
      });
    } finally {
      this.x.iw_canvas_free(canvas);
    }
  }
}

// Messages between the page and the solver worker.

import type { DraftGeometry, FieldData, SolveFeature, SolveOptions, SolveReport, ViewSpec } from './engine';
import type { Pt } from './scene';

export type ToWorker =
  | { type: 'init'; wasmUrl: string }
  | { type: 'grid'; key: string; width: number; height: number; matte: Uint8Array | null; cuts: Pt[][] }
  | { type: 'drop'; key: string }
  /**
   * A layer at the picture's own resolution, for full-resolution frames (a proxied scene):
   * its straight RGBA8 and continuity matte (null: keep the ones it has) and its cuts.
   */
  | { type: 'full-layer'; key: string; image: { width: number; height: number; data: Uint8Array } | null; matte: Uint8Array | null; cuts: Pt[][]; /** Build its grid now, not at its first frame. */ grid?: boolean }
  | { type: 'full-drop'; key: string }
  /** Every full-resolution layer's picture, matte and cuts, sent back (`full-layers`) to move them to a fresh worker. */
  | { type: 'full-export' }
  /** How much memory the worker holds (answered by `memory`). */
  | { type: 'memory' }
  /** A picture file's bytes (or a data: URI's) decoded by the engine (answered by `decoded`). */
  | { type: 'decode'; id: number; bytes: Uint8Array }
  /** A scene document (JSON text) checked by the engine, its pictures decoded (answered by `checked`). */
  | { type: 'check'; id: number; json: string }
  /** The frame of these layers (back to front; `features` null: at rest), solved and drawn at full resolution. */
  | {
      type: 'full-render';
      id: number;
      width: number;
      height: number;
      background: [number, number, number, number];
      layers: FullLayerRequest[];
      /** Draw only this view of the frame (`Engine.drawView`), keeping the fields for `full-view`; absent: the whole frame. */
      view?: ViewSpec;
    }
  /** Another view of the last `full-render` that drew a view, from the fields it kept (no solve; answered by `full`). */
  | { type: 'full-view'; id: number; view: ViewSpec }
  /** The pixels a sparse solve computes on this layer's grid (the draft mesh's, see `draftPixels`). */
  | { type: 'select'; key: string; pixels: Uint32Array }
  /**
   * What the draft worker needs to draw this layer's drafts itself (see `DraftDraw`): its
   * draft geometry on the CPU (null: it draws none of this layer's).
   */
  | { type: 'draft-layer'; key: string; geometry: DraftGeometry | null }
  /**
   * A draft frame drawn from these sparse fields (each layer's at its `draftPixels`), for a
   * frame of the playback cache drawn ahead (answered by `drawn`).
   */
  | { type: 'draw'; id: number; draw: DraftDraw; values: Record<string, Float32Array> }
  | {
      type: 'solve';
      id: number;
      key: string;
      features: SolveFeature[];
      options: SolveOptions;
      /** Start from the last field solved for this layer. */
      warm: boolean;
      /** Also send the triangles of the field's fast full frame (see `adaptiveTriangles`). */
      mesh?: boolean;
      /** Solve at the selected pixels only (a `sparse` field, not `field`). */
      sparse?: boolean;
      /**
       * Solve and keep the field as the next start, sending back only the report (`field`
       * null): the full-resolution solver following a drag (see `App.follow`) or probing a
       * point (see `App.probe`).
       */
      follow?: boolean;
      /** With a sparse solve: draw the draft frame too, and send its pixels (see `DraftDraw`). */
      draw?: DraftDraw;
    };

/**
 * A draft frame the draft worker draws itself after a sparse solve (on a software GPU, where
 * the CPU draws drafts): every layer from the last sparse field it solved for it, composited
 * as `Engine.drawDraft` does, so the page only puts the finished pixels on its canvas.
 */
export interface DraftDraw {
  width: number;
  height: number;
  background: [number, number, number, number];
  shrink: number;
  /** The layers back to front. */
  layers: { key: string; offset: Pt; opacity: number }[];
  /** The request's number (the page's `seq`), echoed per layer in `DraftFrame.seqs`. */
  seq: number;
  /** What the page compares the frame against before showing it (size, background, offsets, shrink). */
  spec: string;
}

/** A draft frame drawn by the draft worker (straight RGBA8, ⌈width / shrink⌉ × ⌈height / shrink⌉). */
export interface DraftFrame {
  pixels: Uint8ClampedArray;
  /** The request number of each layer's sparse field it was drawn from. */
  seqs: Record<string, number>;
  spec: string;
  /** The worker's time drawing it (ms). */
  drawMs: number;
}

/** One layer of a full-resolution frame. */
export interface FullLayerRequest {
  key: string;
  features: SolveFeature[] | null;
  options: SolveOptions;
  offset: Pt;
}

export type FromWorker =
  | { type: 'ready' }
  /** The engine trapped (a bug): it was reloaded and every grid must be sent again. */
  | { type: 'reset'; message: string }
  | { type: 'error'; id: number | null; key: string | null; message: string }
  | { type: 'links'; key: string; links: Uint8Array }
  /** The worker's WebAssembly memory and JavaScript heap in use (bytes; heap null where the browser does not say). */
  | { type: 'memory'; wasmBytes: number; heapBytes: number | null }
  /** The answer to `draw`, always sent: the frame's pixels (null: a layer's draft geometry was missing, or drawing failed, reported by an `error` first). */
  | { type: 'drawn'; id: number; pixels: Uint8ClampedArray | null }
  /** The answer to `decode`: straight RGBA8, or null and why the engine could not read it. */
  | { type: 'decoded'; id: number; image: { width: number; height: number; data: Uint8Array } | null; message?: string }
  /** The answer to `check`: the scene's problems (none: it is sound). */
  | { type: 'checked'; id: number; problems: { path: string; message: string }[] }
  /** The answer to `full-export`. */
  | { type: 'full-layers'; layers: { key: string; image: { width: number; height: number; data: Uint8Array }; matte: Uint8Array; cuts: Pt[][] }[] }
  /** A full-resolution frame (straight RGBA8), with the time its solves and its drawing took (ms). */
  | { type: 'full'; id: number; width: number; height: number; pixels: Uint8Array; solveMs: number; drawMs: number; cycles: number[]; wasmBytes: number; /** The view drawn (`pixels` is its region); absent: the whole frame. */ view?: ViewSpec }
  | {
      type: 'field';
      id: number;
      key: string;
      /** The field, or null for a sparse or a `follow` solve. */
      field: FieldData | null;
      /** A sparse solve's (dx, dy) pairs at the selected pixels, in their order. */
      sparse?: Float32Array;
      /** The field was the worker's last one, which answered this very request (no solve). */
      reused?: boolean;
      /** The triangles of the field's fast full frame, when asked for. */
      triangles?: Uint32Array;
      /** The draft frame, when asked for (`draw`) and every layer's draft was at hand. */
      frame?: DraftFrame;
      report: SolveReport;
      ms: number;
      gridStep: number;
      /** Wall-clock times (performance.timeOrigin + now) the worker began and finished. */
      began: number;
      ended: number;
    };

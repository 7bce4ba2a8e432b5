// Messages between the page and the solver worker.

import type { FieldData, SolveFeature, SolveOptions, SolveReport } from './engine';
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
  /** The frame of these layers (back to front; `features` null: at rest), solved and drawn at full resolution. */
  | { type: 'full-render'; id: number; width: number; height: number; background: [number, number, number, number]; layers: FullLayerRequest[] }
  /** The pixels a sparse solve computes on this layer's grid (the draft mesh's, see `draftPixels`). */
  | { type: 'select'; key: string; pixels: Uint32Array }
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
    };

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
  /** The answer to `full-export`. */
  | { type: 'full-layers'; layers: { key: string; image: { width: number; height: number; data: Uint8Array }; matte: Uint8Array; cuts: Pt[][] }[] }
  /** A full-resolution frame (straight RGBA8), with the time its solves and its drawing took (ms). */
  | { type: 'full'; id: number; width: number; height: number; pixels: Uint8Array; solveMs: number; drawMs: number; cycles: number[]; wasmBytes: number }
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
      report: SolveReport;
      ms: number;
      gridStep: number;
      /** Wall-clock times (performance.timeOrigin + now) the worker began and finished. */
      began: number;
      ended: number;
    };

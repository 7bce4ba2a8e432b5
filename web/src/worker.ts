// The solver worker: owns the engine's grids and the last field of every layer, so the page
// never blocks on a solve and every solve can start warm from the one before.

import { Engine, type FieldData, type GridHandle } from './engine';
import { adaptiveTriangles } from './gl';
import { LastFields } from './lastfields';
import type { FromWorker, ToWorker } from './protocol';

let engine: Engine | null = null;
let wasmUrl = '';
const grids = new Map<string, GridHandle>();
const last = new LastFields();
/** Each grid's links (per node: bit 0 active, bit 1 linked right, bit 2 linked down). */
const linksOf = new Map<string, Uint8Array>();

const post = (msg: FromWorker, transfer: Transferable[] = []) => (self as unknown as Worker).postMessage(msg, transfer);

self.onmessage = async (ev: MessageEvent<ToWorker>) => {
  const msg = ev.data;
  try {
    if (msg.type === 'init') {
      wasmUrl = msg.wasmUrl;
      engine = await Engine.fromUrl(msg.wasmUrl);
      post({ type: 'ready' });
      return;
    }
    if (!engine) throw new Error('The engine is not loaded yet.');
    if (msg.type === 'grid') {
      grids.get(msg.key)?.free();
      const grid = engine.grid(msg.width, msg.height, msg.matte, msg.cuts);
      grids.set(msg.key, grid);
      last.regrid(msg.key, msg.width, msg.height);
      const links = grid.links();
      linksOf.set(msg.key, links.slice());
      post({ type: 'links', key: msg.key, links }, [links.buffer]);
    } else if (msg.type === 'drop') {
      grids.get(msg.key)?.free();
      grids.delete(msg.key);
      last.forget(msg.key);
      linksOf.delete(msg.key);
    } else if (msg.type === 'select') {
      const grid = grids.get(msg.key);
      if (!grid) throw new Error(`No grid for layer ${msg.key}.`);
      grid.select(msg.pixels);
    } else if (msg.type === 'solve') {
      const grid = grids.get(msg.key);
      if (!grid) throw new Error(`No grid for layer ${msg.key}.`);
      const t0 = performance.now();
      const head = { type: 'field' as const, id: msg.id, key: msg.key, gridStep: msg.options.grid_step ?? 1, began: performance.timeOrigin + t0 };
      const ended = () => performance.timeOrigin + performance.now();
      if (msg.sparse) {
        // A draft at the draft mesh's pixels: nothing to keep, the drafts' own history (in
        // the engine) is the next one's start.
        const { values, report } = grid.solveAt(msg.features, msg.options);
        post({ ...head, field: null, sparse: values, report, ms: performance.now() - t0, ended: ended() }, [values.buffer]);
        return;
      }
      const { field, report, reused } = last.solve(msg.key, grid, msg.features, msg.options, msg.warm);
      const ms = performance.now() - t0;
      if (msg.follow) {
        // Following a drag: the field stays here as the next start, the page draws drafts.
        post({ ...head, field: null, report, ms, ended: ended() });
        return;
      }
      // Send copies: the worker keeps its own field as the next warm start.
      const out: FieldData = { width: field.width, height: field.height, dx: field.dx.slice(), dy: field.dy.slice() };
      // The page draws a full-resolution field first through these (on a software GPU),
      // and they take a pass over every pixel: built here, the page never waits for them.
      const links = msg.mesh ? linksOf.get(msg.key) : undefined;
      const triangles = links ? adaptiveTriangles(field.width, field.height, links, field) : undefined;
      post({ ...head, field: out, reused, triangles, report, ms, ended: ended() }, [
        out.dx.buffer,
        out.dy.buffer,
        ...(triangles ? [triangles.buffer] : []),
      ]);
    }
  } catch (err) {
    if (err instanceof WebAssembly.RuntimeError && wasmUrl) {
      // A trap leaves the module's state unusable: start a fresh instance.
      const why = engine?.panicMessage() || err.message;
      engine = await Engine.fromUrl(wasmUrl);
      grids.clear();
      last.clear();
      post({ type: 'reset', message: `The engine stopped (${why}) and was restarted.` });
    }
    const id = msg.type === 'solve' ? msg.id : null;
    const key = 'key' in msg ? msg.key : null;
    post({ type: 'error', id, key, message: (err as Error).message ?? String(err) });
  }
};

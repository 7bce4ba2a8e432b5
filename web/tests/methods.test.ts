// The method switch: the editor's state and requests carry the method, and the engine in
// WebAssembly computes every method's field, each a different surface, drawn by the CPU
// reference renderer.
import { beforeAll, describe, expect, it } from 'vitest';
import { type Engine, type FieldData, type SolveFeature, type SolveReport } from '../src/engine';
import { solverOptions } from '../src/options';
import { METHODS, emptyScene, layerMethod, parseScene, serializeScene, type Method, type Pt, type SceneDoc } from '../src/scene';
import { Store, setMethod } from '../src/state';
import { loadEngine } from './wasm';

let engine: Engine;

beforeAll(async () => {
  engine = await loadEngine();
});

const W = 40;
const H = 30;

/** A scene pinned at its corners with a bone pulled right, and a vertical cut at x = 25.5. */
function scene(): SceneDoc {
  const doc = emptyScene(W, H);
  doc.layers.push({ name: 'art', image: 'data:image/png;base64,AAAA' });
  doc.features.push(
    { id: 'a', kind: 'point', rest: [[1, 1]] },
    { id: 'b', kind: 'point', rest: [[38, 1]] },
    { id: 'c', kind: 'point', rest: [[1, 28]] },
    { id: 'd', kind: 'point', rest: [[38, 28]] },
    { id: 'bone', kind: 'polyline', rest: [[10, 8], [12, 22]], keys: [{ t: 0, points: [[14, 8], [16, 22]] }] },
    { id: 'tear', kind: 'cut', rest: [[25.5, -1], [25.5, 31]] },
  );
  return doc;
}

function features(doc: SceneDoc): SolveFeature[] {
  return doc.features
    .filter((f) => f.kind !== 'cut')
    .map((f) => ({ id: f.id, kind: f.kind, rest: f.rest, pose: f.keys?.[0]?.points ?? f.rest, closed: !!f.closed }));
}

function solveWith(doc: SceneDoc, method: Method): { field: FieldData; report: SolveReport } {
  const grid = engine.grid(W, H, null, [[[25.5, -1], [25.5, 31]] as Pt[]]);
  try {
    const options = solverOptions(setMethod(doc, method), doc.layers[0], 'final');
    expect(options.method).toBe(method);
    return grid.solve(features(doc), options, null);
  } finally {
    grid.free();
  }
}

describe('the method switch', () => {
  it('lists every method as available', () => {
    expect(engine.methods()).toEqual(METHODS.map((name) => ({ name, available: true })));
  });

  it('is saved in the scene and read back', () => {
    const s = new Store(scene());
    s.apply(setMethod(s.doc, 'triangulation'));
    expect(s.doc.solver?.method).toBe('triangulation');
    const back = parseScene(serializeScene(s.doc));
    expect(back.solver?.method).toBe('triangulation');
    expect(layerMethod(back, back.layers[0])).toBe('triangulation');
    s.undo();
    expect(s.doc.solver?.method).toBe('tps');
  });

  it('a layer override wins over the scene, as the engine reads it', () => {
    const doc = setMethod(scene(), 'tps-exact');
    doc.layers[0] = { ...doc.layers[0], solver: { method: 'beier-neely', scheme: 'southwell' } };
    const o = solverOptions(doc, doc.layers[0], 'final');
    expect(o.method).toBe('beier-neely');
    expect(o.scheme).toBe('southwell');
    // Drafts sample coarser; the method stays.
    const big = { ...doc, width: 512, height: 512 };
    expect(solverOptions(big, doc.layers[0], 'draft')).toMatchObject({ method: 'beier-neely', grid_step: 8, spacing_px: 8, preview: true });
    expect(solverOptions(big, doc.layers[0], 'final')).toMatchObject({ grid_step: 1, preview: false });
  });

  it('every method gives its own field; only tps tears along the cut', () => {
    const doc = scene();
    const at = (f: FieldData, x: number, y: number) => f.dx[y * W + x];
    const fields = new Map<Method, FieldData>();
    for (const m of METHODS) {
      const { field, report } = solveWith(doc, m);
      expect(report.method).toBe(m);
      fields.set(m, field);
      // The pulled bone moves by 4 px under every method (its vertices are samples).
      expect(at(field, 10, 8)).toBeCloseTo(4, 1);
      const ignores = report.notes.some((n) => /ignores the continuity matte/.test(n));
      expect(ignores).toBe(m !== 'tps');
    }
    // Across the cut (between x = 25 and 26) the grid thin plate jumps; the other surfaces
    // step no more than between two pixels beside it.
    const step = (m: Method, x: number) => Math.abs(at(fields.get(m)!, x + 1, 15) - at(fields.get(m)!, x, 15));
    expect(step('tps', 25)).toBeGreaterThan(0.3);
    expect(Math.abs(at(fields.get('tps')!, 26, 15))).toBeLessThan(0.05);
    for (const m of ['tps-exact', 'triangulation', 'beier-neely'] as const) {
      expect(step(m, 25)).toBeLessThan(2 * Math.max(step(m, 24), step(m, 26)) + 0.01);
    }
    // Four different surfaces, and four different pictures from the CPU renderer.
    const image = new Uint8Array(4 * W * H).map((_, i) => (i % 4 === 3 ? 255 : (i * 53) % 256));
    const frames = METHODS.map((m) => {
      const grid = engine.grid(W, H, null, [[[25.5, -1], [25.5, 31]]]);
      try {
        return engine.renderCpu(W, H, [255, 255, 255, 255], [{ image, grid, field: fields.get(m)!, offset: [0, 0] }]);
      } finally {
        grid.free();
      }
    });
    for (let i = 0; i < METHODS.length; i++) {
      for (let j = 0; j < i; j++) {
        expect(Array.from(fields.get(METHODS[i])!.dx)).not.toEqual(Array.from(fields.get(METHODS[j])!.dx));
        expect(Array.from(frames[i])).not.toEqual(Array.from(frames[j]));
      }
    }
  });

  it('a layer that nothing drives stays put under every method', () => {
    const doc = emptyScene(W, H);
    doc.layers.push({ name: 'art' });
    const grid = engine.grid(W, H, null, []);
    try {
      for (const m of METHODS) {
        const { field } = grid.solve([], solverOptions(setMethod(doc, m), doc.layers[0], 'final'), null);
        expect(field.dx.every((v) => v === 0) && field.dy.every((v) => v === 0)).toBe(true);
      }
    } finally {
      grid.free();
    }
  });

  it("the methods' settings in the scene reach the engine", () => {
    const doc = setMethod(scene(), 'beier-neely');
    const loose = { ...doc, solver: { ...doc.solver, beier_neely: { a: 20, b: 2 } } };
    expect(solverOptions(loose, doc.layers[0], 'final').beier_neely).toEqual({ a: 20, b: 2 });
    const grid = engine.grid(W, H, null, []);
    try {
      const f = features(doc);
      const tight = grid.solve(f, solverOptions(doc, doc.layers[0], 'final'), null).field;
      const looser = grid.solve(f, solverOptions(loose, doc.layers[0], 'final'), null).field;
      expect(Array.from(looser.dx)).not.toEqual(Array.from(tight.dx));
      const thinned = setMethod({ ...doc, solver: { ...doc.solver, tps_exact: { max_samples: 3 } } }, 'tps-exact');
      expect(grid.solve(f, solverOptions(thinned, doc.layers[0], 'final'), null).report.samples_used).toBe(3);
    } finally {
      grid.free();
    }
  });
});

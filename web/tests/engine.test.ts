// The WebAssembly build of the core, loaded in Node: the adapter's calls, and the editor's
// TypeScript keyframe interpolation held to the engine's.
import { beforeAll, describe, expect, it } from 'vitest';
import type { Engine } from '../src/engine';
import { pointsAt, type Feature, type Interpolation, type Pt } from '../src/scene';
import { loadEngine } from './wasm';

let engine: Engine;

beforeAll(async () => {
  engine = await loadEngine();
});

describe('the engine in WebAssembly', () => {
  it('solves a translation: one point moved, the whole piece follows', () => {
    const grid = engine.grid(32, 24, null, []);
    const { field, report } = grid.solve([{ kind: 'point', rest: [[10, 10]], pose: [[13, 8]] }], { tolerance: 0.01 }, null);
    expect(report.constrained_nodes).toBe(1);
    for (const i of [0, 100, 32 * 24 - 1]) {
      expect(field.dx[i]).toBeCloseTo(3, 2);
      expect(field.dy[i]).toBeCloseTo(-2, 2);
    }
    grid.free();
  });

  it('a cut separates: constraints on one side do not move the other', () => {
    // A vertical cut through the whole height splits the grid into two pieces.
    const grid = engine.grid(20, 10, null, [[[9.5, -1], [9.5, 11]]]);
    const links = grid.links();
    expect(links[5 * 20 + 9] & 2).toBe(0); // (9,5)–(10,5) is cut
    expect(links[5 * 20 + 8] & 2).toBe(2);
    const { field } = grid.solve([{ kind: 'point', rest: [[3, 5]], pose: [[5, 5]] }], {}, null);
    expect(field.dx[5 * 20 + 3]).toBeCloseTo(2, 2);
    expect(field.dx[5 * 20 + 15]).toBe(0);
    grid.free();
  });

  it('a warm start from the answer converges at once', () => {
    const grid = engine.grid(40, 40, null, []);
    const feats = [
      { kind: 'spline' as const, rest: [[5, 5], [20, 12], [35, 5]] as Pt[], pose: [[5, 8], [20, 18], [35, 8]] as Pt[] },
      { kind: 'point' as const, rest: [[20, 35]] as Pt[], pose: [[20, 35]] as Pt[] },
    ];
    const cold = grid.solve(feats, {}, null);
    const warm = grid.solve(feats, {}, cold.field);
    expect(warm.report.cycles).toBeLessThanOrEqual(1);
    grid.free();
  });

  it('a sparse draft is the full draft at the selected pixels', () => {
    // A cut, a draft of the grid thin plate at grid_step 4: the values at the chosen pixels
    // (the upsampling done there alone) are the full field's, from a fresh history each.
    const cuts: Pt[][] = [[[20.5, 2], [20.5, 30]]];
    const feats = [
      { kind: 'spline' as const, rest: [[5, 5], [15, 12], [30, 5]] as Pt[], pose: [[5, 8], [16, 15], [30, 8]] as Pt[] },
      { kind: 'point' as const, rest: [[30, 28]] as Pt[], pose: [[28, 30]] as Pt[] },
    ];
    const full = engine.grid(41, 33, null, cuts);
    const { field } = full.solve(feats, { grid_step: 4 }, null);
    const sparse = engine.grid(41, 33, null, cuts);
    const pixels = Uint32Array.from({ length: 41 * 33 }, (_, i) => i).filter((i) => i % 5 === 0 || Math.abs((i % 41) - 20) <= 1);
    sparse.select(pixels);
    const { values, report } = sparse.solveAt(feats, { grid_step: 4 });
    expect(values.length).toBe(2 * pixels.length);
    expect(report.converged).toBe(true);
    pixels.forEach((p, k) => {
      expect(values[2 * k]).toBeCloseTo(field.dx[p], 4);
      expect(values[2 * k + 1]).toBeCloseTo(field.dy[p], 4);
    });
    full.free();
    sparse.free();
  });

  it('a sparse draft holds a held border as the full solve does', () => {
    // One point pulled: free, the whole picture follows it; held, the edge stays put.
    const feats = [{ kind: 'point' as const, rest: [[20, 16]] as Pt[], pose: [[26, 20]] as Pt[] }];
    const pixels = Uint32Array.from({ length: 41 * 33 }, (_, i) => i);
    for (const border of ['free', 'hold'] as const) {
      const full = engine.grid(41, 33, null, []);
      const { field } = full.solve(feats, { grid_step: 4, spacing_px: 4, border }, null);
      const sparse = engine.grid(41, 33, null, []);
      sparse.select(pixels);
      const { values } = sparse.solveAt(feats, { grid_step: 4, spacing_px: 4, border });
      let edge = 0;
      pixels.forEach((p, k) => {
        expect(values[2 * k]).toBeCloseTo(field.dx[p], 4);
        expect(values[2 * k + 1]).toBeCloseTo(field.dy[p], 4);
        const x = p % 41, y = Math.floor(p / 41);
        if (x === 0 || y === 0 || x === 40 || y === 32) edge = Math.max(edge, Math.hypot(values[2 * k], values[2 * k + 1]));
      });
      if (border === 'hold') expect(edge).toBeLessThan(0.05);
      else expect(edge).toBeGreaterThan(1);
      full.free();
      sparse.free();
    }
  });

  it('errors come back as messages, not traps', () => {
    const grid = engine.grid(8, 8, null, []);
    expect(() => grid.solve([{ kind: 'polyline', rest: [[1, 1]], pose: [[1, 1]] }], {}, null)).toThrow(/polyline|points/i);
    expect(() => engine.grid(4, 4, new Uint8Array(3), [])).toThrow(/continuity matte has 3 values/);
    grid.free();
  });

  it('the CPU renderer reproduces a layer under the identity field', () => {
    const w = 6, h = 5;
    const image = new Uint8Array(4 * w * h).map((_, i) => (i * 37) % 256);
    for (let i = 3; i < image.length; i += 4) image[i] = 255;
    const grid = engine.grid(w, h, null, []);
    const zero = { width: w, height: h, dx: new Float32Array(w * h), dy: new Float32Array(w * h) };
    const out = engine.renderCpu(w, h, [0, 0, 0, 0], [{ image, grid, field: zero, offset: [0, 0] }]);
    expect(Array.from(out)).toEqual(Array.from(image));
    grid.free();
  });

  it('curves pass through their control points', () => {
    const pts: Pt[] = [[0, 0], [10, 5], [20, 0]];
    const line = engine.curve('spline', pts, false, false, 1);
    for (const p of pts) expect(line.some((q) => Math.hypot(q[0] - p[0], q[1] - p[1]) < 1e-9)).toBe(true);
  });
});

describe('keyframe interpolation agrees with the engine', () => {
  const modes: Interpolation[] = ['smooth', 'linear', 'hold', 'ease-in', 'ease-out', 'ease-in-out'];
  // A deterministic pseudo-random sequence.
  let seed = 12345;
  const rand = () => ((seed = (seed * 1103515245 + 12345) % 2 ** 31) / 2 ** 31);

  it('on random keys, interpolations and times', () => {
    for (let trial = 0; trial < 40; trial++) {
      const n = 1 + Math.floor(rand() * 3);
      const rest: Pt[] = Array.from({ length: n }, () => [rand() * 100, rand() * 100]);
      const nk = Math.floor(rand() * 5);
      let t = rand();
      const keys = Array.from({ length: nk }, () => {
        t += 0.1 + rand();
        return { t, points: rest.map(() => [rand() * 100, rand() * 100] as Pt), interpolation: modes[Math.floor(rand() * modes.length)] };
      });
      const f: Feature = { id: 'f', kind: 'polyline', rest, keys };
      for (let s = 0; s < 12; s++) {
        const time = rand() * (t + 1);
        const mine = pointsAt(f, time);
        const theirs = engine.pointsAt(rest, keys, time);
        mine.forEach((p, i) => {
          expect(p[0]).toBeCloseTo(theirs[i][0], 9);
          expect(p[1]).toBeCloseTo(theirs[i][1], 9);
        });
      }
    }
  });
});

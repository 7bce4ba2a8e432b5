// The solver worker's last fields: warm starts, the same request answered without a solve,
// and a drag followed at full resolution leaving its settle a cycle or two of work.
import { beforeAll, describe, expect, it } from 'vitest';
import { type Engine, type FieldData, type GridHandle, type SolveFeature, type SolveOptions } from '../src/engine';
import { LastFields } from '../src/lastfields';
import type { Pt } from '../src/scene';
import { loadEngine } from './wasm';

let engine: Engine;

beforeAll(async () => {
  engine = await loadEngine();
});

/** A grid whose solves are counted, with the start each one was given. */
function counted(grid: GridHandle) {
  const starts: (FieldData | null)[] = [];
  return {
    starts,
    solve(features: SolveFeature[], options: SolveOptions, initial: FieldData | null) {
      starts.push(initial);
      return grid.solve(features, options, initial);
    },
  };
}

/** A drawing on a `size`² layer: a spline whose middle control point is at `mid`, and two anchors. */
function drawing(size: number, mid: Pt): SolveFeature[] {
  const s = size / 128;
  const rest: Pt[] = [[30 * s, 30 * s], [34 * s, 64 * s], [30 * s, 98 * s]];
  return [
    { kind: 'spline', rest, pose: [rest[0], mid, rest[2]] },
    { kind: 'point', rest: [[100 * s, 20 * s]], pose: [[100 * s, 20 * s]] },
    { kind: 'polyline', rest: [[90 * s, 100 * s], [110 * s, 110 * s]], pose: [[90 * s, 100 * s], [110 * s, 110 * s]] },
  ];
}

describe('the worker keeps each layer its last field', () => {
  it('starts warm from it, and answers the same request with it', () => {
    const grid = engine.grid(48, 40, null, [[[24.5, 5], [24.5, 35]]]);
    const g = counted(grid);
    const last = new LastFields();
    const a = drawing(48, [15, 22]);
    const first = last.solve('L', g, a, {}, true);
    expect(first.reused).toBe(false);
    expect(g.starts).toEqual([null]);
    const again = last.solve('L', g, a, {}, true);
    expect(again.reused).toBe(true);
    expect(again.field).toBe(first.field);
    expect(again.report).toEqual(first.report);
    expect(g.starts).toHaveLength(1);
    // Another pose starts from that field; a cold request neither starts from nor reuses it.
    const b = drawing(48, [17, 24]);
    expect(last.solve('L', g, b, {}, true).reused).toBe(false);
    expect(g.starts[1]).toBe(first.field);
    expect(last.solve('L', g, b, {}, false).reused).toBe(false);
    expect(g.starts[2]).toBeNull();
    // Other options are another request; another layer has no field of its own yet.
    expect(last.solve('L', g, b, { tolerance: 0.001 }, true).reused).toBe(false);
    expect(last.solve('M', g, b, { tolerance: 0.001 }, true).reused).toBe(false);
    expect(g.starts[4]).toBeNull();
    grid.free();
  });

  it('never answers with a field whose solve stopped short of the tolerance', () => {
    const grid = engine.grid(48, 40, null, []);
    const g = counted(grid);
    const last = new LastFields();
    const short: SolveOptions = { tolerance: 1e-6, max_cycles: 1 };
    const a = drawing(48, [20, 20]);
    expect(last.solve('L', g, a, short, true).report.converged).toBe(false);
    expect(last.solve('L', g, a, short, true).reused).toBe(false);
    expect(g.starts).toHaveLength(2);
    grid.free();
  });

  it('after the grid is rebuilt, starts from the field but does not answer with it', () => {
    const grid = engine.grid(48, 40, null, []);
    const g = counted(grid);
    const last = new LastFields();
    const a = drawing(48, [20, 20]);
    const { field } = last.solve('L', g, a, {}, true);
    last.regrid('L', 48, 40);
    expect(last.solve('L', g, a, {}, true).reused).toBe(false);
    expect(g.starts[1]).toBe(field);
    last.regrid('L', 50, 40);
    last.solve('L', g, a, {}, true);
    expect(g.starts[2]).toBeNull();
    last.forget('L');
    last.solve('L', g, a, {}, true);
    expect(g.starts[3]).toBeNull();
    grid.free();
  });
});

describe('following a drag at full resolution', () => {
  it('leaves the settle a cycle or two, where the pose before the drag was many cycles away', () => {
    // A spline's control point dragged 24 px in 12 steps on a 128² layer with a cut; the
    // worker solves every step's pose (as it does while following) and then the settle's.
    const size = 128;
    const cuts: Pt[][] = [[[64.5, 20], [64.5, 100]]];
    const pose = (k: number): Pt => [34 + 2 * k, 64 - k];
    const followed = engine.grid(size, size, null, cuts);
    const last = new LastFields();
    last.solve('L', followed, drawing(size, pose(0)), {}, true);
    for (let k = 1; k <= 11; k++) last.solve('L', followed, drawing(size, pose(k)), {}, true);
    const settle = last.solve('L', followed, drawing(size, pose(12)), {}, true);

    const unfollowed = engine.grid(size, size, null, cuts);
    const before = new LastFields();
    before.solve('L', unfollowed, drawing(size, pose(0)), {}, true);
    const late = before.solve('L', unfollowed, drawing(size, pose(12)), {}, true);

    const tight = engine.grid(size, size, null, cuts);
    const exact = tight.solve(drawing(size, pose(12)), { tolerance: 1e-6, max_cycles: 500 }, null).field;
    const gap = (f: FieldData) => f.dx.reduce((m, v, i) => Math.max(m, Math.abs(v - exact.dx[i]), Math.abs(f.dy[i] - exact.dy[i])), 0);
    expect(gap(settle.field)).toBeLessThan(0.05);
    expect(gap(late.field)).toBeLessThan(0.05);
    expect(settle.report.cycles).toBeLessThanOrEqual(2);
    expect(late.report.cycles!).toBeGreaterThanOrEqual(3 * settle.report.cycles!);
    for (const g of [followed, unfollowed, tight]) g.free();
  });
});

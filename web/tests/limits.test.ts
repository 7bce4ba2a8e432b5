// The editor's fields refuse exactly the values the scene format refuses, and drags stop
// where the engine stops taking a point: each check here is held against the engine's own
// validation (and solves) of a scene with that value, at the edges of the ranges and past
// them, so that a value a field takes or a drag leaves always opens again (kept work too).
import { beforeAll, describe, expect, it } from 'vitest';
import type { Engine } from '../src/engine';
import { clampMove, clampPoint, durationProblem, featureBox, fpsProblem, offsetBox, offsetProblem, type Limits } from '../src/limits';
import { emptyScene, layerFeatures, toLayer, type Pt, type SceneDoc } from '../src/scene';
import { loadEngine } from './wasm';

let engine: Engine;
let limits: Limits;
beforeAll(async () => {
  engine = await loadEngine();
  limits = engine.limits();
});

/** A 4 × 4 grey PNG. */
const PNG = 'data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAQAAAAECAAAAACMmsGiAAAAC0lEQVR4nGNgwAQAABQAAX3+Hu4AAAAASUVORK5CYII=';

/**
 * Whether the engine refuses a scene of `fps`, `duration` and a layer at `offset` (JSON holds
 * no NaN or infinity: the fields refuse those, and a file cannot hold them).
 */
function formatRefuses(fps: number, duration: number, offset: [number, number] = [0, 0]): boolean {
  const doc = { inkwarp: 1, width: 4, height: 4, fps, duration, layers: [{ name: 'a', image: PNG, offset }], features: [] };
  return engine.validate(JSON.parse(JSON.stringify(doc))).length > 0;
}

describe('the fields hold values to the scene format', () => {
  it('reads the ranges from the engine (inkwarp_core::limits)', () => {
    expect(limits).toEqual({ max_coord_px: 1e6, max_time_s: 1e5, min_fps: 0.001, max_fps: 1000, max_frames: 1e8 });
  });

  it('fps: refused exactly where the format refuses it, with its range in the message', () => {
    for (const fps of [0, -1, 0.0005, 0.000999, 0.001, 0.5, 1, 24, 240, 241, 999.5, 1000, 1000.001, 1e9, NaN, Infinity]) {
      const why = fpsProblem(fps, 2, limits);
      expect(why !== null, `fps ${fps}`).toBe(!Number.isFinite(fps) || formatRefuses(fps, 2));
      if (why) expect(why).toContain('from 0.001 (one frame every 1000 s) to 1000');
    }
  });

  it('duration: refused exactly where the format refuses it, with its range in the message', () => {
    for (const duration of [0, -2, 1e-9, 0.05, 2, 99999.99, 1e5, 100000.01, 150000, 1e9, NaN, Infinity]) {
      const why = durationProblem(duration, 12, limits);
      expect(why !== null, `duration ${duration}`).toBe(!Number.isFinite(duration) || formatRefuses(12, duration));
      if (why) expect(why).toContain('at most 100000 s');
    }
  });

  it('duration × fps: no more frames than the format allows', () => {
    // At the limits' product exactly: allowed; the format refuses no value the fields take.
    expect(durationProblem(1e5, 1000, limits)).toBeNull();
    expect(formatRefuses(1000, 1e5)).toBe(false);
    const few = { ...limits, max_frames: 1000 };
    expect(durationProblem(100, 12, few)).toMatch(/more than the 1000 frames/);
    expect(fpsProblem(24, 100, few)).toMatch(/more than the 1000 frames/);
  });

  it('offset: refused exactly where the format refuses it, with its range in the message', () => {
    for (const v of [0, 1.5, -1e6, 1e6, 1e6 + 1, -2e6, 2000000, 1e308, NaN, -Infinity]) {
      const why = offsetProblem(v, limits);
      expect(why !== null, `offset ${v}`).toBe(!Number.isFinite(v) || formatRefuses(12, 2, [v, 0]));
      if (why) expect(why).toContain('from -1000000 to 1000000');
    }
  });
});

describe('drags stop where a scene\'s coordinates end', () => {
  /**
   * Whether the engine refuses `doc`: its validation, or the solve of a layer's features in
   * that layer's pixels (a point less its offset), as rendering solves them.
   */
  function refuses(doc: SceneDoc): boolean {
    if (engine.validate(JSON.parse(JSON.stringify(doc))).length > 0) return true;
    const grid = engine.grid(4, 4, null, []);
    try {
      return doc.layers.some((layer) => {
        const at = toLayer(layer);
        try {
          grid.solve(layerFeatures(doc, layer).map((f) => ({ kind: f.kind, rest: at(f.rest), pose: at(f.rest) })), {}, null);
          return false;
        } catch {
          return true;
        }
      });
    } finally {
      grid.free();
    }
  }
  /** A scene of a point and a polyline, its first layer at `offset` moving both, its second at [0, 500] the polyline alone. */
  function scene(point: Pt, line: Pt[], offset: Pt = [-300, 0]): SceneDoc {
    const doc = emptyScene(4, 4);
    doc.layers.push({ name: 'a', image: PNG, offset }, { name: 'b', image: PNG, offset: [0, 500], features: ['line'] });
    doc.features.push({ id: 'dot', kind: 'point', rest: [point] }, { id: 'line', kind: 'polyline', rest: line });
    return doc;
  }
  const line: Pt[] = [[10, 20], [110, 20], [60, -30]];

  it('a point dragged far out stops where the frame and every layer it moves hold it, and no further', () => {
    const doc = scene([0, 0], line);
    for (const [id, far, edge] of [['dot', [5e9, -5e9], [1e6 - 300, -1e6]], ['line', [-5e9, 5e9], [-1e6, 1e6]], ['line', [5e9, -5e9], [1e6 - 300, -1e6 + 500]]] as [string, Pt, Pt][]) {
      const q = clampPoint(far, featureBox(doc, id, limits));
      expect(q, `${id} to ${far}`).toEqual(edge);
      const at = (p: Pt) => (id === 'dot' ? scene(p, line) : scene([0, 0], [p, ...line.slice(1)]));
      expect(refuses(at(q))).toBe(false);
      // A pixel further on either axis, and the engine refuses it.
      expect(refuses(at([q[0] + Math.sign(far[0]), q[1]]))).toBe(true);
      expect(refuses(at([q[0], q[1] + Math.sign(far[1])]))).toBe(true);
    }
    // Where the engine takes the point, it is where the pointer put it.
    expect(clampPoint([12.5, -7], featureBox(doc, 'line', limits))).toEqual([12.5, -7]);
  });

  it('a feature dragged far out stops whole at the edge, its shape kept', () => {
    const delta = clampMove(line, [5e6, -5e6], featureBox(scene([0, 0], line), 'line', limits));
    expect(delta).toEqual([1e6 - 300 - 110, -1e6 + 500 + 30]);
    const moved = line.map((p) => [p[0] + delta[0], p[1] + delta[1]] as Pt);
    expect(refuses(scene([0, 0], moved))).toBe(false);
    expect(refuses(scene([0, 0], moved.map((p) => [p[0] + 1, p[1]])))).toBe(true);
    expect(refuses(scene([0, 0], moved.map((p) => [p[0], p[1] - 1])))).toBe(true);
    // A move the engine takes is made as asked.
    expect(clampMove(line, [-300, 40.25], featureBox(scene([0, 0], line), 'line', limits))).toEqual([-300, 40.25]);
  });

  it('a layer dragged far out stops where its offset, and the features it moves in its pixels, are held', () => {
    const doc = scene([1e6 - 10, 0], line);
    const o = clampPoint([-5e9, -5e9], offsetBox(doc, 0, limits));
    expect(o).toEqual([-10, -1e6 + 20]);
    expect(refuses(scene([1e6 - 10, 0], line, o))).toBe(false);
    expect(refuses(scene([1e6 - 10, 0], line, [o[0] - 1, o[1]]))).toBe(true);
    expect(refuses(scene([1e6 - 10, 0], line, [o[0], o[1] - 1]))).toBe(true);
    expect(clampPoint([5e9, 5e9], offsetBox(doc, 0, limits))).toEqual([1e6, 1e6 - 30]);
  });
});

// The editor's fields refuse exactly the values the scene format refuses: each check here is
// held against the engine's own validation of a scene with that value, at the edges of the
// ranges and past them, so that a value a field takes always opens again (kept work too).
import { beforeAll, describe, expect, it } from 'vitest';
import type { Engine } from '../src/engine';
import { durationProblem, fpsProblem, offsetProblem, type Limits } from '../src/limits';
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

// The page's side of the solver worker: one solve in flight, the newest request per layer
// waiting, so a fast drag never queues work.
import { describe, expect, it } from 'vitest';
import type { FromWorker, ToWorker } from '../src/protocol';
import { SolverClient, type FieldEvent } from '../src/solver';

class FakeWorker {
  sent: ToWorker[] = [];
  private listeners: ((ev: MessageEvent<FromWorker>) => void)[] = [];
  postMessage(msg: ToWorker): void {
    this.sent.push(msg);
  }
  addEventListener(_: string, fn: (ev: MessageEvent<FromWorker>) => void): void {
    this.listeners.push(fn);
  }
  removeEventListener(_: string, fn: (ev: MessageEvent<FromWorker>) => void): void {
    this.listeners = this.listeners.filter((l) => l !== fn);
  }
  reply(msg: FromWorker): void {
    for (const l of [...this.listeners]) l({ data: msg } as MessageEvent<FromWorker>);
  }
  solves(): Extract<ToWorker, { type: 'solve' }>[] {
    return this.sent.filter((m): m is Extract<ToWorker, { type: 'solve' }> => m.type === 'solve');
  }
}

const field = { width: 1, height: 1, dx: new Float32Array(1), dy: new Float32Array(1) };
const report = { method: 'tps' as const, notes: [], cycles: 1, final_change_px: 0, residual: 0, constrained_nodes: 1, constrained_samples: 1, dropped_samples: 0, converged: true, samples: 1 };

async function client() {
  const w = new FakeWorker();
  const c = new SolverClient(w as unknown as Worker, 'engine.wasm');
  w.reply({ type: 'ready' });
  await c.ready;
  return { w, c };
}

describe('solver scheduling', () => {
  it('one solve in flight; newer requests for a layer replace older ones', async () => {
    const { w, c } = await client();
    const got: FieldEvent[] = [];
    c.onField = (ev) => got.push(ev);
    for (let i = 0; i < 5; i++) c.solve('a', [], { grid_step: 8 }, { madeAt: i, n: i });
    expect(w.solves().map((m) => m.id)).toEqual([1]); // the first went out at once
    w.reply({ type: 'field', id: 1, key: 'a', field, report, ms: 1, gridStep: 8, began: 0, ended: 0 });
    // Requests 1–3 were superseded by 4 while 0 was solving.
    expect(w.solves()).toHaveLength(2);
    w.reply({ type: 'field', id: 2, key: 'a', field, report, ms: 1, gridStep: 8, began: 0, ended: 0 });
    expect(got.map((e) => e.tag.n)).toEqual([0, 4]);
    expect(c.busy).toBe(false);
    await c.idle();
  });

  it('layers take turns; an error frees the worker for the next request', async () => {
    const { w, c } = await client();
    const errors: string[] = [];
    c.onError = (_, m) => errors.push(m);
    c.solve('a', [], {}, { madeAt: 0 });
    c.solve('b', [], {}, { madeAt: 0 });
    w.reply({ type: 'error', id: 1, key: 'a', message: 'bad drawing' });
    expect(errors).toEqual(['bad drawing']);
    expect(w.solves().map((m) => m.key)).toEqual(['a', 'b']);
  });

  it('grids resolve with their links; a reset rejects waiting grids', async () => {
    const { w, c } = await client();
    const links = c.setGrid('a', 2, 1, null, []);
    w.reply({ type: 'links', key: 'a', links: new Uint8Array([3, 1]) });
    expect(Array.from(await links)).toEqual([3, 1]);
    const resets: string[] = [];
    c.onReset = (m) => resets.push(m);
    const lost = c.setGrid('b', 2, 1, null, []);
    w.reply({ type: 'reset', message: 'restarted' });
    await expect(lost).rejects.toThrow('restarted');
    expect(resets).toEqual(['restarted']);
  });
});

describe('solve timing', () => {
  it('a field event carries when it was sent, solved and received, on the page clock', async () => {
    const { w, c } = await client();
    const got: FieldEvent[] = [];
    c.onField = (ev) => got.push(ev);
    c.solve('a', [], {}, { madeAt: 0 });
    expect(c.current?.tag.madeAt).toBe(0);
    const origin = performance.timeOrigin;
    const now = performance.now();
    w.reply({ type: 'field', id: 1, key: 'a', field, report, ms: 5, gridStep: 1, began: origin + now, ended: origin + now + 5 });
    expect(c.current).toBeNull();
    const t = got[0].times;
    expect(t.ended - t.began).toBeCloseTo(5, 3);
    expect(t.began).toBeCloseTo(now, 3);
    expect(t.sent).toBeLessThanOrEqual(t.received);
  });
});

// The page's side of the solver worker: one solve in flight, the newest request per layer
// waiting, so a fast drag never queues work.
import { describe, expect, it } from 'vitest';
import type { FromWorker, ToWorker } from '../src/protocol';
import { SolverClient, type FieldEvent } from '../src/solver';

class FakeWorker {
  sent: ToWorker[] = [];
  terminated = false;
  terminate(): void {
    this.terminated = true;
  }
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

/** A client that can replace its worker (as the ahead worker's): the first worker, and those made since. */
async function renewable() {
  const made: FakeWorker[] = [];
  const first = new FakeWorker();
  const c = new SolverClient(first as unknown as Worker, 'engine.wasm', () => {
    const w = new FakeWorker();
    made.push(w);
    return w as unknown as Worker;
  });
  first.reply({ type: 'ready' });
  await c.ready;
  return { first, c, made };
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

describe('replacing a solver worker by a fresh one (the ahead worker, once every frame is solved)', () => {
  it('the fresh worker gets each layer\'s newest setup, then what was asked meanwhile', async () => {
    const { first, c, made } = await renewable();
    expect(c.renewable).toBe(true);
    void c.setGrid('a', 2, 1, null, []);
    c.select('a', new Uint32Array([0]));
    void c.setGrid('a', 3, 1, null, []); // a new grid: the old one and its selection are gone
    c.select('a', new Uint32Array([1, 2]));
    void c.setGrid('b', 2, 1, null, []);
    c.dropGrid('b');
    // Not while a solve is in flight.
    c.solve('a', [], {}, { madeAt: 0 });
    await c.renew();
    expect(made).toHaveLength(0);
    first.reply({ type: 'field', id: 1, key: 'a', field, report, ms: 1, gridStep: 1, began: 0, ended: 0 });
    const renewed = c.renew();
    expect(first.terminated).toBe(true);
    expect(made).toHaveLength(1);
    const fresh = made[0];
    // Asked while the fresh worker loads: waits for it.
    c.solve('a', [], {}, { madeAt: 1, n: 1 });
    expect(fresh.sent.map((m) => m.type)).toEqual(['init']);
    fresh.reply({ type: 'ready' });
    await renewed;
    expect(c.renewals).toBe(1);
    const setup = fresh.sent.slice(1, 3) as Extract<ToWorker, { type: 'grid' } | { type: 'select' }>[];
    expect(setup.map((m) => m.type)).toEqual(['grid', 'select']);
    expect((setup[0] as Extract<ToWorker, { type: 'grid' }>).width).toBe(3);
    expect(Array.from((setup[1] as Extract<ToWorker, { type: 'select' }>).pixels)).toEqual([1, 2]);
    expect(fresh.solves()).toHaveLength(1);
    expect(fresh.sent.length).toBe(4);
    const got: FieldEvent[] = [];
    c.onField = (ev) => got.push(ev);
    fresh.reply({ type: 'field', id: fresh.solves()[0].id, key: 'a', field, report, ms: 1, gridStep: 1, began: 0, ended: 0 });
    expect(got.map((e) => e.tag.n)).toEqual([1]);
    expect(c.busy).toBe(false);
  });

  it('a solve in flight is ended with its worker; the fresh one starts with the next request', async () => {
    const { first, c, made } = await renewable();
    expect(c.cancel()).toBe(false); // nothing in flight
    const links = c.setGrid('a', 2, 1, null, []);
    c.solve('a', [], {}, { madeAt: 0 });
    expect(c.cancel()).toBe(false); // not while a grid's links are awaited
    first.reply({ type: 'links', key: 'a', links: new Uint8Array([1, 0]) });
    await links;
    c.solve('b', [], {}, { madeAt: 0, n: 0 }); // waiting behind 'a'
    const got: FieldEvent[] = [];
    c.onField = (ev) => got.push(ev);
    const idle = c.idle();
    expect(c.cancel()).toBe(true);
    await idle;
    expect(first.terminated).toBe(true);
    expect(c.busy).toBe(false);
    expect(made).toHaveLength(0); // not until asked again
    expect(await c.memory()).toBeNull();
    // The ended worker's late answer (had it sent one) is no one's.
    first.reply({ type: 'field', id: 1, key: 'a', field, report, ms: 1, gridStep: 1, began: 0, ended: 0 });
    expect(got).toHaveLength(0);
    c.solve('a', [], {}, { madeAt: 1, n: 1 });
    expect(made).toHaveLength(1);
    const fresh = made[0];
    fresh.reply({ type: 'ready' });
    await Promise.resolve();
    await Promise.resolve();
    expect(fresh.sent.map((m) => m.type)).toEqual(['init', 'grid', 'solve']);
    fresh.reply({ type: 'field', id: fresh.solves()[0].id, key: 'a', field, report, ms: 1, gridStep: 1, began: 0, ended: 0 });
    expect(got.map((e) => e.tag.n)).toEqual([1]);
    expect(c.renewals).toBe(1);
  });

  it('grids asked for while the fresh worker starts are each answered once, in order', async () => {
    const { first, c, made } = await renewable();
    for (const key of ['a', 'b', 'c']) {
      const g = c.setGrid(key, 2, 1, null, []);
      first.reply({ type: 'links', key, links: new Uint8Array([1]) });
      await g;
    }
    c.solve('a', [], {}, { madeAt: 0 });
    expect(c.cancel()).toBe(true);
    // Meanwhile: layer a's grid twice (a cut, then its undo), b's dropped, c untouched.
    const a1 = c.setGrid('a', 3, 1, null, []);
    const a2 = c.setGrid('a', 2, 1, null, []);
    c.dropGrid('b');
    const fresh = made[0];
    fresh.reply({ type: 'ready' });
    await Promise.resolve();
    await Promise.resolve();
    const sent = fresh.sent.map((m) => `${m.type}${'key' in m ? ` ${m.key}` : ''}${m.type === 'grid' ? ` ${m.width}` : ''}`);
    expect(sent).toEqual(['init', 'grid c 2', 'grid a 3', 'grid a 2', 'drop b']);
    fresh.reply({ type: 'links', key: 'a', links: new Uint8Array([3]) });
    fresh.reply({ type: 'links', key: 'a', links: new Uint8Array([2]) });
    expect(Array.from(await a1)).toEqual([3]);
    expect(Array.from(await a2)).toEqual([2]);
  });

  it('a client without a way to make workers is never replaced', async () => {
    const { w, c } = await client();
    expect(c.renewable).toBe(false);
    await c.renew();
    expect((w as unknown as { terminated: boolean }).terminated).toBe(false);
  });
});

describe('pictures decoded by a solver worker', () => {
  it('resolves with the picture, rejects with the reason, and the worker is not replaced while one decodes', async () => {
    const { first, c, made } = await renewable();
    const p = c.decode(new Uint8Array([1, 2, 3]));
    const asked = first.sent.at(-1) as Extract<ToWorker, { type: 'decode' }>;
    expect(asked.type).toBe('decode');
    await c.renew();
    expect(made).toHaveLength(0);
    first.reply({ type: 'decoded', id: asked.id, image: { width: 1, height: 1, data: new Uint8Array([9, 8, 7, 6]) } });
    expect(Array.from((await p).data)).toEqual([9, 8, 7, 6]);
    const q = c.decode(new Uint8Array([0]));
    const again = first.sent.at(-1) as Extract<ToWorker, { type: 'decode' }>;
    first.reply({ type: 'decoded', id: again.id, image: null, message: 'not a PNG or JPEG' });
    await expect(q).rejects.toThrow('not a PNG or JPEG');
  });
});

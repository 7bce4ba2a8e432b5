// The page's side of the worker that draws a large picture's full-resolution frames
// (`FullClient`), over in-process workers running the real engine: replacing the worker
// keeps its layers and the frames asked for meanwhile.
import { describe, expect, it } from 'vitest';
import type { SolveFeature } from '../src/engine';
import type { FromWorker, ToWorker } from '../src/protocol';
import { FullClient, type FullFrame, type FullRequest } from '../src/solver';
import { SolverWorker } from '../src/workercore';
import { loadEngine } from './wasm';

/** A `Worker` running a `SolverWorker` in this thread, its messages in order. */
class LocalWorker {
  private listeners: ((ev: MessageEvent<FromWorker>) => void)[] = [];
  private chain: Promise<void> = Promise.resolve();
  terminated = false;
  private core = new SolverWorker((msg) => {
    if (!this.terminated) for (const l of [...this.listeners]) l({ data: msg } as MessageEvent<FromWorker>);
  }, loadEngine);
  postMessage(msg: ToWorker): void {
    this.chain = this.chain.then(() => (this.terminated ? undefined : this.core.handle(msg)));
  }
  addEventListener(_: 'message', fn: (ev: MessageEvent<FromWorker>) => void): void {
    this.listeners.push(fn);
  }
  removeEventListener(_: 'message', fn: (ev: MessageEvent<FromWorker>) => void): void {
    this.listeners = this.listeners.filter((l) => l !== fn);
  }
  terminate(): void {
    this.terminated = true;
  }
}

const W = 36;
const H = 28;
const pose = (x: number): SolveFeature[] => [
  { kind: 'spline', rest: [[5, 5], [18, 12], [31, 5]], pose: [[5, 5], [x, 14], [31, 5]] },
  { kind: 'point', rest: [[18, 24]], pose: [[18, 24]] },
];
const request = (key: string, features: SolveFeature[] | null): FullRequest => ({
  key,
  width: W,
  height: H,
  background: [0, 0, 0, 255],
  layers: [{ key: 'P', features, options: { tolerance: 0.01, grid_step: 2 }, offset: [0, 0] }],
  madeAt: 0,
});

/**
 * Collects `client`'s frames (`next()`: a promise of the next one) and gives it one layer
 * `P` of W × H with a cut; returns its picture too.
 */
function withLayer(client: FullClient): { frames: FullFrame[]; next: () => Promise<void>; data: Uint8Array } {
  const frames: FullFrame[] = [];
  let arrived: () => void = () => {};
  client.onFrame = (f) => {
    frames.push(f);
    arrived();
  };
  client.onError = (m) => {
    throw new Error(m);
  };
  const next = () => new Promise<void>((r) => (arrived = r));
  const data = new Uint8Array(4 * W * H);
  for (let i = 0; i < W * H; i++) data.set([(i * 29) % 256, (i * 7) % 256, 120, 255], 4 * i);
  client.setLayer('P', { width: W, height: H, data }, new Uint8Array(W * H).fill(255), [[[20.5, 8], [20.5, 27]]]);
  return { frames, next, data };
}

describe('FullClient', () => {
  it('replaces its worker by a fresh one with the same layers; a frame asked for meanwhile waits for it', async () => {
    const workers: LocalWorker[] = [];
    const client = new FullClient(() => {
      const w = new LocalWorker();
      workers.push(w);
      return w as unknown as Worker;
    }, 'inkwarp.wasm');
    await client.ready;
    const { frames, next, data } = withLayer(client);
    let got = next();
    client.render(request('a', pose(24)));
    await got;
    const renewing = client.renew();
    got = next();
    client.render(request('b', pose(24)));
    await Promise.all([renewing, got]);
    expect(client.renewals).toBe(1);
    expect(workers.length).toBe(2);
    expect(workers[0].terminated).toBe(true);
    expect(frames.map((f) => f.key)).toEqual(['a', 'b']);
    expect(Array.from(frames[1].pixels)).toEqual(Array.from(frames[0].pixels));
    got = next();
    client.render(request('c', null));
    await got;
    expect(Array.from(frames[2].pixels)).toEqual(Array.from(data));
  });

  it('draws a view of the frame, then other views from the fields it kept without a solve', async () => {
    const client = new FullClient(() => new LocalWorker() as unknown as Worker, 'inkwarp.wasm');
    await client.ready;
    const { frames, next } = withLayer(client);
    expect(client.keptKey).toBe(null);
    // The whole frame, for reference.
    let got = next();
    client.render(request('a', pose(24)));
    await got;
    const whole = frames[0].pixels;
    expect(frames[0].view).toBe(null);
    const region = (x0: number, y0: number, x1: number, y1: number) =>
      Array.from({ length: y1 - y0 }, (_, r) => Array.from(whole.subarray(4 * ((y0 + r) * W + x0), 4 * ((y0 + r) * W + x1)))).flat();
    // A view at the picture's scale: that region of the frame.
    got = next();
    client.render({ ...request('a', pose(24)), view: { shrink: 1, region: [3, 4, 20, 17] } });
    await got;
    expect(frames[1].view).toEqual({ shrink: 1, region: [3, 4, 20, 17] });
    expect(frames[1].cycles.length).toBe(1);
    expect(Array.from(frames[1].pixels)).toEqual(region(3, 4, 20, 17));
    expect(client.keptKey).toBe('a');
    // Panned: drawn from the kept field (no solve), the same frame's region.
    got = next();
    client.view({ shrink: 1, region: [10, 0, 36, 28] }, 0);
    await got;
    expect(frames[2].key).toBe('a');
    expect(frames[2].cycles).toEqual([]);
    expect(Array.from(frames[2].pixels)).toEqual(region(10, 0, 36, 28));
    // Zoomed out: the frame drawn twice smaller, ⌈W/2⌉ × ⌈H/2⌉ at most.
    got = next();
    client.view({ shrink: 2, region: [0, 0, 18, 14] }, 0);
    await got;
    expect(frames[3].pixels.length).toBe(4 * 18 * 14);
    // A fresh worker has no fields: no view is drawn from them, the next is solved again.
    await client.renew();
    expect(client.keptKey).toBe(null);
    client.view({ shrink: 1, region: [0, 0, 5, 5] }, 0);
    expect(client.busy).toBe(false);
    // A whole frame takes the fields: no view after it either.
    got = next();
    client.render({ ...request('b', pose(24)), view: { shrink: 1, region: [0, 0, 4, 4] } });
    await got;
    expect(client.keptKey).toBe('b');
    got = next();
    client.render(request('b', pose(24)));
    await got;
    expect(client.keptKey).toBe(null);
  });

  it('is replaced once left alone, not while the page forbids it, and not while it keeps the fields of the frame on screen', async () => {
    const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));
    // Any memory is "too much" for a worker without kept fields, none for one with them.
    const client = new FullClient(() => new LocalWorker() as unknown as Worker, 'inkwarp.wasm', { bytes: 0, keptBytes: Infinity, idleMs: 30 });
    await client.ready;
    const { next } = withLayer(client);
    // A view: the worker keeps its fields (its solver), so it is kept as it is.
    let got = next();
    client.render({ ...request('a', pose(24)), view: { shrink: 1, region: [0, 0, W, H] } });
    await got;
    await sleep(120);
    expect(client.renewals).toBe(0);
    // A whole frame keeps nothing: replaced once left alone, but not while the page says no
    // (the pointer down on the drawing, say).
    let allowed = false;
    client.mayRenew = () => allowed;
    got = next();
    client.render(request('b', pose(20)));
    await got;
    await sleep(120);
    expect(client.renewals).toBe(0);
    allowed = true;
    for (let i = 0; i < 50 && client.renewals === 0; i++) await sleep(20);
    expect(client.renewals).toBe(1);
  });
});

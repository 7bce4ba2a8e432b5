// The solver worker: owns the engine's grids and the last field of every layer, so the page
// never blocks on a solve and every solve can start warm from the one before (the work
// itself is `SolverWorker`'s).

import type { ToWorker } from './protocol';
import { SolverWorker } from './workercore';

const core = new SolverWorker((msg, transfer = []) => (self as unknown as Worker).postMessage(msg, transfer));

self.onmessage = (ev: MessageEvent<ToWorker>) => core.handle(ev.data);

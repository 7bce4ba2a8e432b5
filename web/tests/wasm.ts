// The WebAssembly build of the core, as the unit tests load it (`make editor` builds it).
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';
import { Engine } from '../src/engine';

/** The module's bytes. */
const wasmBytes = readFileSync(fileURLToPath(new URL('../src/generated/inkwarp.wasm', import.meta.url)));

/** A fresh engine instance of the module. */
export function loadEngine(): Promise<Engine> {
  return Engine.fromBytes(wasmBytes);
}

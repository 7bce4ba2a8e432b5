// The editor's entry point: loads the engine (on the page for curves and in a worker for
// solving), builds the page, and opens the scene named in the URL or the built-in example.

import { App } from './app';
import { Engine } from './engine';
import { builtinScene } from './examples';
import * as examples from './examples';
import * as images from './images';
import * as scene from './scene';
import { SolverClient } from './solver';
import * as state from './state';
import { Store } from './state';
import { Ui } from './ui';
import wasmUrl from './generated/inkwarp.wasm?url';
import './style.css';

async function start(): Promise<void> {
  const root = document.getElementById('app')!;
  const absWasm = new URL(wasmUrl, document.baseURI).href;
  const engine = await Engine.fromUrl(absWasm);
  images.useDecoder(engine);
  // Two workers: full-resolution fields, and drafts while dragging (never queued behind a
  // full-resolution solve, which takes a second or more at 512 × 512).
  const spawn = () => new SolverClient(new Worker(new URL('./worker.ts', import.meta.url), { type: 'module' }), absWasm);
  const solver = spawn();
  const drafts = spawn();
  await Promise.all([solver.ready, drafts.ready]);
  const params = new URLSearchParams(location.search);
  const sceneUrl = params.get('scene');
  const store = new Store(await builtinScene());
  const glCanvas = document.createElement('canvas');
  glCanvas.className = 'picture';
  const app = new App(engine, solver, glCanvas, store, drafts);
  const ui = new Ui(app, root);
  // Hooks for the end-to-end tests and for scripting the editor from the console.
  Object.assign(window, { inkwarp: { app, ui, store, engine, scene, state, images, examples } });
  if (sceneUrl) {
    try {
      const resp = await fetch(sceneUrl);
      if (!resp.ok) throw new Error(`HTTP ${resp.status}: ${await resp.text()}`);
      const name = resp.headers.get('X-Inkwarp-Name') ?? 'scene.json';
      await ui.openSceneText(await resp.text(), name);
      if (params.get('save') !== 'download') ui.saveUrl = sceneUrl;
    } catch (err) {
      ui.fileError(sceneUrl, err);
    }
  } else {
    app.syncLayers();
    ui.refresh(true);
  }
  document.body.dataset.ready = 'true';
}

start().catch((err) => {
  document.body.textContent = `The editor could not start: ${(err as Error).message}`;
  document.body.dataset.ready = 'failed';
});

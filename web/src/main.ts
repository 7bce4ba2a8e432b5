// The editor's entry point: loads the engine (on the page for curves and in a worker for
// solving), builds the page, and opens the scene named in the URL or the built-in example.

import { App } from './app';
import { Autosaver, IndexedDbStore, KEEP_DELAY_MS, MemoryStore, type Snapshot, type SnapshotStore, claimTab, clockTime, fetchDataUri, holdTab, pictureFiles, pictureMarks, restorePictures, restoreQuestion, sameScene, unopenedMessage } from './autosave';
import { Engine } from './engine';
import { builtinScene } from './examples';
import * as examples from './examples';
import * as images from './images';
import * as scene from './scene';
import { FullClient, SolverClient } from './solver';
import * as state from './state';
import { type Origin, Store } from './state';
import type { SceneDoc } from './scene';
import { Ui } from './ui';
import wasmUrl from './generated/inkwarp.wasm?url';
import './style.css';

/** How often a showing tab asks whether another tab or program wrote its scene's file (see `Ui.checkFile`). */
const FILE_CHECK_MS = 3000;

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
  // A third solves the animation's frames ahead while the editor is left alone (replaced by
  // a fresh one once they are all solved: see `App.renewAhead`).
  const makeWorker = () => new Worker(new URL('./worker.ts', import.meta.url), { type: 'module' });
  const ahead = new SolverClient(makeWorker(), absWasm, makeWorker);
  // Large pictures are decoded there too (and large scenes checked, see `App.checkScene`),
  // not in the page's module, which would keep the decoder's memory; the worker gives it
  // back when it is replaced (see `App.renewAhead`).
  images.useOffPageDecoder((bytes) => ahead.decode(bytes));
  // A fourth draws a large picture's full-resolution frames (see `proxy.ts`).
  const full = new FullClient(() => new Worker(new URL('./worker.ts', import.meta.url), { type: 'module' }), absWasm);
  await Promise.all([solver.ready, drafts.ready, ahead.ready, full.ready]);
  const params = new URLSearchParams(location.search);
  const sceneUrl = params.get('scene');
  const store = new Store(await builtinScene());
  // Named as the examples menu names it: not a scene file's name while a file failed to open.
  store.origin = state.downloadOrigin(`${examples.BUILTIN.name}.json`);
  const glCanvas = document.createElement('canvas');
  glCanvas.className = 'picture';
  const app = new App(engine, solver, glCanvas, store, drafts, ahead, full);
  const ui = new Ui(app, root);
  // Hooks for the end-to-end tests and for scripting the editor from the console.
  Object.assign(window, { inkwarp: { app, ui, store, engine, scene, state, images, examples } });
  // A scene that fails to open is named by its file, and the built-in example shown instead.
  let opened = false;
  // The file `inkwarp edit` serves, even where it could not be opened (a picture missing):
  // work kept from it is still its own, and saves back to it.
  let served: Served | null = null;
  if (sceneUrl) {
    let named = sceneUrl;
    try {
      const resp = await fetch(sceneUrl);
      const text = await resp.text();
      // Percent-encoded by the server: a header carries no other characters.
      const header = (name: string) => { const v = resp.headers.get(name); return v === null ? null : decodeURIComponent(v); };
      const path = header('X-Inkwarp-Path');
      if (path) served = { path, saveUrl: params.get('save') !== 'download' ? sceneUrl : null };
      if (!resp.ok) {
        // The server's message names the file (a stale link: what to open instead).
        const stale = resp.status === 403 ? ' This page\'s link is not the running inkwarp edit\'s (an earlier run\'s, or one copied without its token): the built-in example is shown instead.' : '';
        ui.message(text + stale, 'error');
      } else {
        named = path ?? sceneUrl;
        const files = JSON.parse(header('X-Inkwarp-Pictures') ?? '{}') as Record<string, string>;
        // The file it came from (its path on the machine `inkwarp edit` serves it from),
        // where the history starts.
        await ui.openSceneText(text, header('X-Inkwarp-Name') ?? 'scene.json', {
          origin: { path: named, version: resp.headers.get('ETag'), saveUrl: served?.saveUrl ?? null },
          first: true,
          files,
        });
        ui.watchPictures(JSON.parse(header('X-Inkwarp-Stamps') ?? '{}'), files);
        opened = true;
      }
    } catch (err) {
      ui.fileError(named, err);
    }
  }
  if (!opened) {
    app.syncLayers();
    ui.refresh(true);
  }
  document.body.dataset.ready = 'true';
  // What another tab or program writes to the scene's file is noticed: on coming back to this
  // tab, and every few seconds while it shows.
  const checkFile = () => { if (document.visibilityState === 'visible') void ui.checkFile(); };
  window.addEventListener('focus', checkFile);
  document.addEventListener('visibilitychange', checkFile);
  setInterval(checkFile, FILE_CHECK_MS);
  // After "ready": the restore offer waits for the user, the editor works meanwhile.
  await keepWork(store, ui, served, opened ? store.doc : null);
}

/** The page's title: the scene's name, marked while it holds changes not saved to a file. */
function showTitle(store: Store): void {
  const title = `${store.unsaved ? '● ' : ''}${store.origin.fileName} — inkwarp editor`;
  if (document.title !== title) document.title = title;
}

/**
 * Never lose work: the scene is kept in IndexedDB `KEEP_DELAY_MS` after each change (images
 * inlined), offered back on the next load when it held unsaved changes, and leaving the
 * page with unsaved changes asks first.
 */
/** The scene file `inkwarp edit` serves: its path, and the URL a save goes to (none where saves download). */
interface Served {
  path: string;
  saveUrl: string | null;
}

async function keepWork(store: Store, ui: Ui, served: Served | null, openedDoc: SceneDoc | null): Promise<void> {
  const source = served?.path ?? null; // the served file, opened or not
  // Leaving with unsaved changes asks from the start, while the restore offer waits for its
  // answer too (edits made meanwhile were lost without a word). The kept copy is written
  // once the offer is answered: before, it would write over the work the offer holds.
  let keeper: Autosaver | null = null;
  window.addEventListener('beforeunload', (e) => {
    // A value typed into a field and not yet entered (the field still focused) counts: the
    // blur enters it, as clicking elsewhere would.
    if (document.activeElement instanceof HTMLInputElement) document.activeElement.blur();
    // A feature being drawn is work too, kept with the scene (see `snapshot`).
    if (!store.unsaved && !store.view.draft.length) return;
    void keeper?.flush();
    e.preventDefault();
    e.returnValue = '';
  });
  window.addEventListener('pagehide', () => void keeper?.flush());
  let kept: SnapshotStore;
  try {
    kept = new IndexedDbStore(await holdTab());
    await kept.get();
  } catch {
    kept = new MemoryStore();
    ui.message('This browser keeps no copy of your work (IndexedDB is off): save often.', 'error');
  }
  // The served file's pictures as this page opened them: a later restore of this work can
  // tell a picture retouched on disk from one the work changed.
  let pictures = openedDoc ? pictureMarks(openedDoc) : undefined;
  // A file's work restored where it cannot be saved into that file (a page whose link is from
  // an earlier run of `inkwarp edit`, another scene's page): its kept copy still names that
  // file, so that the page the file opens next offers it as its own and saves it back.
  let carried: { origin: Origin; source: string; version: string | null; pictures?: Snapshot['pictures'] } | null = null;
  const snapshot = () => {
    const file = store.origin.saveUrl ? { source: store.origin.path, version: store.origin.version, pictures }
      : carried?.origin === store.origin ? carried : { source: null, version: null, pictures: undefined };
    // A feature being drawn is kept with it (and counts as unsaved: it is in no file).
    const { draft, tool } = store.view;
    const drawing = draft.length ? { tool, draft } : {};
    return { doc: store.doc, fileName: store.origin.fileName, unsaved: store.unsaved || draft.length > 0, view: { mode: store.view.mode, time: store.view.time, ...drawing }, source: file.source, version: file.version, pictures: file.pictures, files: pictureFiles(store.doc) };
  };
  const failed = (err: Error) => ui.message(`Could not keep a copy of the scene in the browser (${err.message}); save it to a file.`, 'error');
  const saver = new Autosaver(kept, snapshot, fetchDataUri, KEEP_DELAY_MS, failed);
  // Unsaved work is offered back whatever the page opened: it is the file's own (the same
  // path), or it names itself and what it would replace, and then saves by download. This
  // tab's own work (a reload) first, else the newest that a closed tab left.
  showTitle(store);
  let previous = await kept.get().catch(() => null);
  let left: Awaited<ReturnType<SnapshotStore['left']>> = [];
  // A closed tab's work is offered here while this tab holds its lock, so that no other new
  // tab offers it too; the lock goes when the offer is answered.
  let release: (() => void) | null = null;
  let claimed: string | null = null;
  if (!previous?.unsaved) {
    const closed = await kept.left().catch(() => []);
    // Closed tabs' saved scenes are in their files: only their unsaved work is kept.
    for (const c of closed.filter((c) => !c.snapshot.unsaved)) await kept.drop(c.key).catch(() => {});
    left = closed.filter((c) => c.snapshot.unsaved);
    for (const c of left) {
      if ((release = await claimTab(c.key))) {
        [claimed, previous] = [c.key, c.snapshot];
        break;
      }
    }
  }
  const own = (previous?.source ?? null) === source;
  // Work its file already holds (a save that reached the file as the page was left, a reload
  // right after Ctrl+S: its answer was never seen) is not offered: the page shows the file,
  // whose version a later save starts from (no conflict with the user's own save). A line
  // being drawn is in no file: work kept with one is offered.
  if (previous?.unsaved && own && openedDoc && !previous.view?.draft?.length && sameScene(previous.doc, openedDoc)) {
    if (claimed) await kept.drop(claimed).catch(() => {});
    else await kept.clear().catch(() => {});
    release?.();
    [previous, claimed, release] = [null, null, null];
  }
  const more = left.length > 1 ? ` (${left.length - 1} more kept from other tabs: open the editor in a new tab, with this one open, to be offered the next)` : '';
  // Edits made while the offer waits are kept too, apart: under a key of their own that this
  // tab holds, so the offered copy is not written over, and a crash leaves them to be
  // offered as a closed tab's work is. Once the offer is answered, this tab's copy takes over.
  let aside: { saver: Autosaver; key: string; release: (() => void) | null } | null = null;
  const watch = store.subscribe(() => {
    showTitle(store);
    if (!(store.unsaved || store.view.draft.length) || !(kept instanceof IndexedDbStore)) return;
    if (!aside) {
      const key = `${kept.key}-meanwhile-${Date.now().toString(36)}`;
      const made = { key, release: null as (() => void) | null, saver: new Autosaver(new IndexedDbStore(key), snapshot, fetchDataUri, KEEP_DELAY_MS, failed) };
      void claimTab(key).then((r) => { made.release = r; });
      aside = made;
      keeper = made.saver;
    }
    aside.saver.changed();
  });
  const restore = previous?.unsaved && (await ui.offerRestore(restoreQuestion(previous, Date.now(), own || !source ? undefined : source) + more));
  watch();
  // Another tab's work, once restored here or declined, is not offered again.
  let settled = !restore;
  if (previous?.unsaved && restore) {
    // The version of its file as this page opened it: another than the kept work's, the file changed since.
    const fileNow = own && openedDoc && store.origin.saveUrl ? store.origin.version : null;
    try {
      // Into its own file's page: pictures retouched on disk since come from the file.
      let { doc, taken, keys } = own && openedDoc && pictures ? restorePictures(previous.doc, previous.pictures, openedDoc, pictures) : { doc: previous.doc, taken: [] as string[], keys: [] as string[] };
      let misfit = '';
      // Back to its own file, which a save checks is still as the kept work found it: set
      // with the scene, so that a save made while the page settles goes to the file too.
      const back = { unsaved: true, ...(own && served?.saveUrl ? { origin: { saveUrl: served.saveUrl, path: served.path, version: previous.version ?? null } } : {}) };
      try {
        await ui.openScene(doc, previous.fileName, true, back);
      } catch (err) {
        // A picture retouched to another size no longer fits the kept scene: the kept copy,
        // which a save writes beside the changed file under a new name (never over it, nor
        // inline in the scene); kept marked so, a later restore (the server restarted) says
        // and does the same.
        if (!taken.length) throw err;
        const { width, height } = previous.doc;
        const save = back.origin ? 'Save writes that copy beside the changed file under a new name (which the save names), the changed file left as it is' : 'Save downloads the scene with that copy inside';
        misfit = `; the picture of ${taken.map((n) => `layer '${n}'`).join(', ')} changed on disk since and no longer fits the scene (${(err as Error).message}), so the copy kept with your work is shown. ${save}; to use the changed picture instead, bring it to ${width}×${height} pixels and reload`;
        pictures = { ...pictures, ...Object.fromEntries(keys.flatMap((k) => (previous.pictures?.[k] ? [[k, previous.pictures[k]]] : []))) };
        [doc, taken] = [previous.doc, []];
        await ui.openScene(doc, previous.fileName, true, back);
        ui.keptCopies = new Set(keys);
      }
      // Its file did not open as it is now (a picture changed on disk to another size, or
      // missing): the pictures the work did not change are the copies kept with it, which a
      // save writes beside their files where those changed since (never over them, nor
      // inline), and the next restore treats alike.
      const marks = pictureMarks(previous.doc);
      const unopened = own && !openedDoc && !misfit && previous.pictures ? Object.keys(previous.pictures).filter((k) => marks[k] === previous.pictures?.[k]) : [];
      if (unopened.length) {
        ui.keptCopies = new Set(unopened);
        pictures = previous.pictures;
        misfit = `; its file did not open as it is now, so its pictures are the copies kept with your work: ${back.origin ? 'Save writes any of them that changed on disk since beside its file under a new name (which the save names), the file left as it is' : 'Save downloads the scene with them inside'}`;
      }
      if (!store.origin.saveUrl && previous.source) carried = { origin: store.origin, source: previous.source, version: previous.version ?? null, pictures: previous.pictures };
      // Back where the editor was: pose mode stays pose mode, at the same time.
      if (previous.view) store.setView({ mode: previous.view.mode, time: previous.view.time });
      // With the feature that was being drawn, to go on clicking its points (a tool picked
      // clears the points drawn: they come back after).
      if (previous.view?.draft?.length && previous.view.tool && previous.view.mode === 'rest') {
        store.setView({ tool: previous.view.tool });
        store.setView({ draft: previous.view.draft });
      }
      const meanwhile = aside ? '; Ctrl+Z brings back what you drew while the question waited' : '';
      const changed = fileNow && previous.version && fileNow !== previous.version ? `; ${served?.path ?? 'its file'} was changed since (by another tab or program), so Save asks before writing over it (Ctrl+Z shows the file as it is now)` : '';
      const retouched = taken.length ? `; the picture of ${taken.map((n) => `layer '${n}'`).join(', ')} changed on disk since, and is shown as the file has it now` : '';
      ui.message(`Restored the scene from ${clockTime(previous.savedAt)}${retouched}${changed}${misfit}${meanwhile}.`, misfit ? 'error' : 'info');
      await saver.flush(); // now this tab's, before the other tab's copy goes
      settled = true;
    } catch (err) {
      // Kept work that does not open (a value the scene format refuses, from an older
      // editor): never written over nor dropped. This tab's own copy is set aside under a key
      // no tab writes to, offered again on a later load as a closed tab's work is (another
      // tab's copy stays where it is, not dropped); meanwhile it can be downloaded as it
      // was kept, to mend by hand and open.
      let where = 'It is still kept in this browser and offered again the next time the editor opens without other unsaved work';
      if (!claimed) {
        try {
          await kept.setAside(previous);
          await kept.clear();
        } catch {
          where = 'This browser could not keep it apart: download it now, as it will be written over';
        }
      }
      const why = err instanceof scene.SceneFileError && err.path ? `at ${err.path}: ${err.message.slice(err.path.length + 2)}` : String((err as Error)?.message ?? err);
      ui.offerUnopened(unopenedMessage(previous, why, where), previous.doc, previous.fileName);
    }
  }
  if (claimed && settled) await kept.drop(claimed).catch(() => {});
  // This tab's own copy, declined, is forgotten too: Discard starts afresh, and the next
  // reload offers nothing (edits made since are kept again below).
  if (previous?.unsaved && !restore && !claimed) await kept.clear().catch(() => {});
  release?.();
  let revision = store.revision;
  let unsaved = store.unsaved;
  let draft = JSON.stringify(store.view.draft);
  showTitle(store);
  store.subscribe(() => {
    showTitle(store);
    // The points of a feature being drawn are kept too (a click is work).
    const drawn = JSON.stringify(store.view.draft);
    if (store.revision === revision && store.unsaved === unsaved && drawn === draft) return;
    revision = store.revision;
    unsaved = store.unsaved;
    draft = drawn;
    // Saved to its file: the file's pictures are now the document's.
    if (!unsaved && store.origin.saveUrl && pictures) pictures = pictureMarks(store.doc);
    saver.changed();
  });
  if (store.unsaved || store.view.draft.length) saver.changed();
  keeper = saver;
  const apart = aside as { saver: Autosaver; key: string; release: (() => void) | null } | null;
  if (apart) {
    // This tab's copy now holds the scene (the restored one, or the edits made meanwhile).
    await apart.saver.flush();
    await saver.flush();
    await kept.drop(apart.key).catch(() => {});
    apart.release?.();
  }
  Object.assign((window as unknown as { inkwarp: object }).inkwarp, { autosave: saver });
}

start().catch((err) => {
  document.body.textContent = `The editor could not start: ${(err as Error).message}`;
  document.body.dataset.ready = 'failed';
});

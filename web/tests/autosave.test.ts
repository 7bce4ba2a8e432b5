import { describe, expect, it, vi } from 'vitest';
import { Autosaver, MemoryStore, clockTime, sameScene, inlineImages, pictureFiles, pictureMarks, restorePictures, restoreQuestion, unopenedMessage } from '../src/autosave';
import { nameFiles } from '../src/images';
import { emptyScene, serializeScene, type SceneDoc } from '../src/scene';
import { Store, copyKeys, moveKey, moveKeys, neighbourKeys, pasteKeys, setKey, toggleKeyRef } from '../src/state';
import { loadEngine } from './wasm';

function scene(): SceneDoc {
  const doc = emptyScene(20, 10);
  doc.layers.push({ name: 'a', image: 'data:image/png;base64,AAAA' }, { name: 'b', image: 'pictures/b.png', continuity: 'm.png' });
  return doc;
}

describe('autosave', () => {
  it('inlines every image that is not a data: URI', async () => {
    const seen: string[] = [];
    const out = await inlineImages(scene(), async (ref) => {
      seen.push(ref);
      return `data:image/png;base64,${ref.length}`;
    });
    expect(seen).toEqual(['pictures/b.png', 'm.png']);
    expect(out.layers[0].image).toBe('data:image/png;base64,AAAA');
    expect(out.layers[1].image).toBe('data:image/png;base64,14');
    expect(out.layers[1].continuity).toBe('data:image/png;base64,5');
  });

  it('writes once, a moment after a burst of changes, with the images and the time', async () => {
    vi.useFakeTimers();
    try {
      const kept = new MemoryStore();
      const store = new Store(scene());
      const saver = new Autosaver(kept, () => ({ doc: store.doc, fileName: 'x.json', unsaved: store.unsaved, view: { mode: store.view.mode, time: store.view.time } }), async () => 'data:,', 500, undefined, () => 1234);
      store.setView({ mode: 'pose', time: 0.5 });
      const put = vi.spyOn(kept, 'put');
      store.subscribe((_, changed) => changed && saver.changed());
      store.edit((d) => ({ ...d, fps: 12 }));
      store.edit((d) => ({ ...d, fps: 30 }));
      expect(saver.pending).toBe(true);
      await vi.advanceTimersByTimeAsync(499);
      expect(put).not.toHaveBeenCalled();
      await vi.advanceTimersByTimeAsync(10);
      expect(put).toHaveBeenCalledTimes(1);
      expect(kept.value?.doc.fps).toBe(30);
      expect(kept.value?.doc.layers[1].image).toBe('data:,');
      expect(kept.value?.unsaved).toBe(true);
      expect(kept.value?.savedAt).toBe(1234);
      expect(saver.lastSavedAt).toBe(1234);
      expect(kept.value?.view).toEqual({ mode: 'pose', time: 0.5 });
    } finally {
      vi.useRealTimers();
    }
  });

  it('a long burst of changes (a drag) is written as it goes, at most a second apart', async () => {
    vi.useFakeTimers();
    try {
      const kept = new MemoryStore();
      let fps = 1;
      const saver = new Autosaver(kept, () => ({ doc: { ...scene(), fps }, fileName: 'x', unsaved: true }), async () => 'data:,', 150);
      const put = vi.spyOn(kept, 'put');
      for (let i = 0; i < 30; i++) {
        fps = i + 1;
        saver.changed();
        await vi.advanceTimersByTimeAsync(100);
      }
      // 3 s of changes 0.1 s apart: a write each second, none waiting for the burst's end.
      expect(put.mock.calls.length).toBeGreaterThanOrEqual(2);
      expect(put.mock.calls.length).toBeLessThanOrEqual(3);
      await vi.advanceTimersByTimeAsync(150);
      expect(kept.value?.doc.fps).toBe(30);
    } finally {
      vi.useRealTimers();
    }
  });

  it('reads each picture once: a later write waits for no read (it begins as the page goes)', async () => {
    const kept = new MemoryStore();
    const reads: string[] = [];
    let hang = false;
    const inline = (ref: string) => {
      reads.push(ref);
      return hang ? new Promise<string>(() => {}) : Promise.resolve(`data:,${ref}`);
    };
    const saver = new Autosaver(kept, () => ({ doc: scene(), fileName: 'x', unsaved: true }), inline, 0);
    await saver.flush();
    hang = true; // a read now would never end: the second write must not need one
    const put = vi.spyOn(kept, 'put');
    await saver.flush();
    expect(put).toHaveBeenCalledTimes(1);
    expect(reads).toEqual(['pictures/b.png', 'm.png']);
    expect(kept.value?.doc.layers[1].continuity).toBe('data:,m.png');
  });

  it('a picture whose read failed is read again at the next write', async () => {
    const errors: string[] = [];
    const kept = new MemoryStore();
    let fail = true;
    const saver = new Autosaver(kept, () => ({ doc: scene(), fileName: 'x', unsaved: true }), async (ref) => {
      if (fail) throw new Error(`HTTP 404 for ${ref}`);
      return 'data:,ok';
    }, 0, (e) => errors.push(e.message));
    await saver.flush();
    expect(kept.value).toBeNull();
    fail = false;
    await saver.flush();
    expect(kept.value?.doc.layers[1].image).toBe('data:,ok');
    expect(errors).toEqual(['HTTP 404 for pictures/b.png']);
  });

  it('reports a failed write once and keeps trying', async () => {
    const errors: string[] = [];
    const kept = new MemoryStore();
    kept.put = async () => {
      throw new Error('quota');
    };
    const saver = new Autosaver(kept, () => ({ doc: scene(), fileName: 'x', unsaved: true }), async () => 'data:,', 0, (e) => errors.push(e.message));
    await saver.flush();
    await saver.flush();
    expect(errors).toEqual(['quota']);
  });

  it('each tab keeps its own snapshot; closed tabs\' are left behind, newest first, open tabs\' not', async () => {
    const shared = new Map();
    const openKeys = new Set(['b']);
    const open = async (keys: string[]) => new Set(keys.filter((k) => openKeys.has(k)));
    const [a, b, c, d] = ['a', 'b', 'c', 'd'].map((k) => new MemoryStore(k, shared, open));
    const snap = (fileName: string, savedAt: number, unsaved = true) => ({ doc: scene(), fileName, savedAt, unsaved });
    await a.put(snap('a.json', 1));
    await b.put(snap('b.json', 3));
    await c.put(snap('c.json', 2));
    await d.put(snap('d.json', 4, false));
    expect((await a.get())?.fileName).toBe('a.json');
    expect((await b.get())?.fileName).toBe('b.json'); // not overwritten by another tab
    const fresh = new MemoryStore('new', shared, open);
    expect(await fresh.get()).toBeNull();
    // b is still open: not left behind; the others newest first, saved ones too (to drop).
    expect((await fresh.left()).map((l) => l.key)).toEqual(['d', 'c', 'a']);
    await fresh.drop('c');
    expect((await fresh.left()).map((l) => l.key)).toEqual(['d', 'a']);
    expect(await c.get()).toBeNull();
  });

  it('a snapshot set aside (kept work that did not open) is never written over, and is offered as a closed tab\'s', async () => {
    const shared = new Map();
    const own = new MemoryStore('tab', shared);
    const refused = { doc: { ...scene(), duration: 150000 }, fileName: 'a.json', unsaved: true, savedAt: 1 };
    await own.put(refused);
    const key = await own.setAside(refused);
    await own.clear();
    await own.put({ doc: scene(), fileName: 'a.json', unsaved: false, savedAt: 2 });
    expect(key).not.toBe('tab');
    expect(shared.get(key)).toEqual(refused);
    // Another load of the page (this tab's key) finds it among the work left.
    expect((await new MemoryStore('tab', shared).left()).map((l) => l.snapshot)).toEqual([refused]);
  });

  it('kept work its file already holds is told apart from work the file lacks', () => {
    const doc = scene();
    doc.features.push({ id: 'p1', kind: 'point', rest: [[10.622000000000002, 3]] } as SceneDoc['features'][number]);
    // The file as the server wrote it: its keys in another order, points to a millionth.
    const { features: _, ...rest } = doc;
    const file = JSON.parse(JSON.stringify({ features: [{ rest: [[10.622, 3]], kind: 'point', id: 'p1' }], ...rest, layers: doc.layers.map((l) => ({ image: l.image, ...l })) }));
    expect(sameScene(doc, file)).toBe(true);
    expect(sameScene({ ...doc, duration: doc.duration + 1 }, file)).toBe(false);
    expect(sameScene({ ...doc, features: [] }, file)).toBe(false);
  });

  it('restored work takes the pictures retouched on disk since, and keeps those it changed itself', () => {
    const picture = (name: string, image: string) => ({ name, image });
    const opened = { ...emptyScene(20, 10), layers: [picture('face', 'data:image/png;base64,OLD'), picture('eyes', 'data:image/png;base64,E1')] };
    const marks = pictureMarks(opened);
    // The work: a point drawn, the eyes' picture replaced in the editor, a layer added.
    const kept = { ...opened, layers: [opened.layers[0], picture('eyes', 'data:image/png;base64,MINE'), picture('new', 'data:image/png;base64,N')] };
    // On disk since: both pictures retouched.
    const now = { ...opened, layers: [picture('face', 'data:image/png;base64,NEW'), picture('eyes', 'data:image/png;base64,E2')] };
    const { doc, taken, keys } = restorePictures(kept, marks, now);
    expect(doc.layers.map((l) => l.image)).toEqual(['data:image/png;base64,NEW', 'data:image/png;base64,MINE', 'data:image/png;base64,N']);
    expect(taken).toEqual(['face']);
    expect(keys).toEqual(['face\u0000image']);
    // Nothing changed on disk, or a snapshot from before pictures were marked: as kept.
    expect(restorePictures(kept, marks, opened)).toEqual({ doc: kept, taken: [], keys: [] });
    expect(restorePictures(kept, undefined, now)).toEqual({ doc: kept, taken: [], keys: [] });
    expect(pictureMarks(now)['face\u0000image']).not.toBe(marks['face\u0000image']);
  });

  it('asks to restore with the time of day', () => {
    const at = new Date(2026, 10, 27, 14, 32, 5).getTime();
    expect(clockTime(at)).toBe('14:32');
    const snap = { doc: scene(), fileName: 'x', savedAt: at, unsaved: true };
    expect(restoreQuestion(snap, at + 60_000)).toBe('Restore the scene you were editing at 14:32?');
    expect(restoreQuestion(snap, at + 3 * 86_400_000)).toMatch(/^Restore the scene you were editing at 14:32 on .+\?$/);
    // Work of another scene than the one the page opened names both.
    expect(restoreQuestion(snap, at + 60_000, 'scene.json')).toBe(`Restore the scene you were editing at 14:32 (${snap.fileName}) instead of scene.json?`);
    // Two files of one name are told apart by their paths.
    expect(restoreQuestion({ ...snap, source: '/shots/cat/scene.json' }, at + 60_000, '/shots/dog/scene.json'))
      .toBe('Restore the scene you were editing at 14:32 (/shots/cat/scene.json) instead of /shots/dog/scene.json?');
  });
});

describe('kept work that does not open', () => {
  /** A 4 × 4 grey PNG, and the same cut short (a damaged copy). */
  const PNG = 'data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAQAAAAECAAAAACMmsGiAAAAC0lEQVR4nGNgwAQAABQAAX3+Hu4AAAAASUVORK5CYII=';
  const CUT = PNG.slice(0, 40);
  const where = 'It is still kept in this browser';
  /** The restore's message for `doc` as kept work of `source`, from the engine's own problems. */
  async function said(doc: SceneDoc, source: string | null = '/shots/cat/scene.json', files?: Record<string, string>): Promise<string> {
    const problems = (await loadEngine()).validate(JSON.parse(serializeScene(doc)));
    expect(problems.length).toBeGreaterThan(0);
    const why = problems.map((p) => `at ${p.path}: ${p.message}`).join('\n');
    return unopenedMessage({ doc, fileName: 'scene.json', savedAt: new Date(2026, 10, 27, 14, 32).getTime(), unsaved: true, source, files }, why, where);
  }

  it('names a picture by its layer, never by the data: URI it is kept as, and says what to do', async () => {
    const doc = { ...emptyScene(4, 4), layers: [{ name: 'sky', image: PNG }, { name: 'cat', image: PNG, continuity: CUT }] };
    const message = await said(doc);
    expect(message).toMatch(/^The work kept from 14:32 could not be opened: at layers\[1\]\.continuity: cannot use the continuity matte of layer 'cat' kept with it: /);
    expect(message).not.toMatch(/data:image/);
    expect(message).toContain(`${where}; download it and, in a text editor, replace that picture's data: URI by the path of its file (from where you save the scene, as /shots/cat/scene.json names it), then open it with \`inkwarp edit SCENE\`.`);
    // A picture of another size than the scene's, of a scene made in the browser (no file).
    const wide = await said({ ...doc, width: 5, layers: [{ name: 'sky', image: PNG }] }, null);
    expect(wide).toMatch(/at layers\[0\]\.image: the picture of layer 'sky' kept with it is 4×4 pixels but the scene is 5×4/);
    expect(wide).toContain('by the path of its file (from where you save the scene), then');
  });

  it('names a picture that came from a file by that file, kept with the work, and says where to put the path', async () => {
    const doc = { ...emptyScene(4, 4), layers: [{ name: 'sky', image: PNG }, { name: 'cat', image: CUT, continuity: CUT }] };
    // The files the served scene's pictures came from, as the server named them; the work
    // keeps them by layer, so its copy of a picture, cut short since, is still named.
    nameFiles([[PNG, 'art/sky.png'], [CUT, 'art/cat.png']]);
    const files = pictureFiles(doc);
    nameFiles([]);
    expect(files).toEqual({ 'sky\u0000image': 'art/sky.png', 'cat\u0000image': 'art/cat.png', 'cat\u0000continuity': 'art/cat.png' });
    const message = await said(doc, '/shots/cat/scene.json', files);
    expect(message).toMatch(/^The work kept from 14:32 could not be opened: at layers\[1\]\.image: cannot use art\/cat\.png of layer 'cat' kept with it: .*\nat layers\[1\]\.continuity: cannot use art\/cat\.png of layer 'cat' kept with it: /s);
    expect(message).toContain(`${where}; download it, move it into the folder of /shots/cat/scene.json and, in a text editor, replace those pictures' data: URIs by the paths of their files ("art/cat.png"), then open it with \`inkwarp edit SCENE\`.`);
    // One whose file is not known (added in the editor) is named by its layer, as before.
    const mixed = await said(doc, '/shots/cat/scene.json', { 'cat\u0000image': 'art/cat.png' });
    expect(mixed).toMatch(/at layers\[1\]\.image: cannot use art\/cat\.png of layer 'cat' kept with it: .*at layers\[1\]\.continuity: cannot use the continuity matte of layer 'cat' kept with it: /s);
    expect(mixed).toContain("replace that picture's data: URI by the path of its file (from where you save the scene, as /shots/cat/scene.json names it)");
  });

  it('a value that is not a picture is named as the engine names it', async () => {
    const message = await said({ ...emptyScene(4, 4), duration: 150000, layers: [{ name: 'sky', image: PNG }] });
    expect(message).toMatch(/^The work kept from 14:32 could not be opened: at duration: .*at most 100000 s/);
    expect(message).toMatch(/; download it to mend that value in a text editor, then open the file\.$/);
  });
});

describe('unsaved changes and undo', () => {
  it('tracks whether the document is saved', () => {
    const store = new Store(scene());
    expect(store.unsaved).toBe(false);
    store.edit((d) => ({ ...d, fps: 12 }));
    expect(store.unsaved).toBe(true);
    store.markSaved();
    expect(store.unsaved).toBe(false);
    store.undo();
    expect(store.unsaved).toBe(true);
    store.markUnsaved();
    expect(store.unsaved).toBe(true);
  });

  it('opening a scene is undoable and counts as saved', () => {
    const first = scene();
    const store = new Store(first);
    store.edit((d) => ({ ...d, fps: 12 }));
    const edited = store.doc;
    const other = emptyScene(5, 5);
    store.load(other);
    expect(store.doc).toBe(other);
    expect(store.unsaved).toBe(false);
    expect(store.canUndo()).toBe(true);
    store.undo();
    expect(store.doc).toBe(edited);
    store.undo();
    expect(store.doc).toBe(first);
  });

  it('a gesture tells the views that Undo is available', () => {
    const store = new Store(scene());
    const seen: boolean[] = [];
    store.begin();
    store.edit((d) => ({ ...d, fps: 12 }));
    store.subscribe((s) => seen.push(s.canUndo()));
    store.commit();
    expect(seen).toEqual([true]);
  });

  it('refuses to move a key past the end of the animation', () => {
    let doc = emptyScene(10, 10);
    doc = { ...doc, duration: 2, features: [{ id: 'p', kind: 'point', rest: [[1, 1]] }] };
    doc = setKey(doc, 'p', 1, [[2, 2]]);
    expect(() => moveKey(doc, 'p', 1, 2.5)).toThrow(/past the end of the animation \(2 s\)/);
    expect(moveKey(doc, 'p', 1, 2).features[0].keys![0].t).toBe(2);
  });
});

describe('keys: selection, moving together, copy and paste, onion skin', () => {
  function doc2(): SceneDoc {
    let doc: SceneDoc = { ...emptyScene(10, 10), fps: 10, duration: 2, features: [{ id: 'a', kind: 'point', rest: [[1, 1]] }, { id: 'b', kind: 'polyline', rest: [[0, 0], [5, 5]] }] };
    doc = setKey(doc, 'a', 0.2, [[2, 2]]);
    doc = setKey(doc, 'a', 1, [[3, 3]]);
    doc = setKey(doc, 'b', 0.5, [[1, 0], [6, 5]]);
    return doc;
  }

  it('Shift-click toggles keys in and out of the selection', () => {
    let refs = toggleKeyRef([], { feature: 'a', t: 0.2 });
    refs = toggleKeyRef(refs, { feature: 'b', t: 0.5 });
    expect(refs).toHaveLength(2);
    refs = toggleKeyRef(refs, { feature: 'a', t: 0.2 + 1e-6 });
    expect(refs).toEqual([{ feature: 'b', t: 0.5 }]);
  });

  it('moves selected keys together, all or none', () => {
    const doc = doc2();
    const moved = moveKeys(doc, [{ feature: 'a', t: 0.2 }, { feature: 'b', t: 0.5 }], 0.3);
    expect(moved.features[0].keys!.map((k) => k.t)).toEqual([0.5, 1]);
    expect(moved.features[1].keys![0].t).toBeCloseTo(0.8, 12);
    // a's key at 0.2 would land on its key at 1.0: refused, nothing moves
    expect(() => moveKeys(doc, [{ feature: 'a', t: 0.2 }, { feature: 'b', t: 0.5 }], 0.8)).toThrow(/already has a key/);
    expect(() => moveKeys(doc, [{ feature: 'a', t: 1 }], 1.5)).toThrow(/leave the animation/);
    // both of a's keys moving past each other's old times is fine
    expect(moveKeys(doc, [{ feature: 'a', t: 0.2 }, { feature: 'a', t: 1 }], 0.8).features[0].keys!.map((k) => k.t)).toEqual([1, 1.8]);
  });

  it('copies keys relative to the earliest and pastes them at the time', () => {
    let doc = doc2();
    doc = { ...doc, features: doc.features.map((f) => (f.id === 'a' ? { ...f, keys: f.keys!.map((k) => ({ ...k, interpolation: 'ease-in' as const })) } : f)) };
    const clip = copyKeys(doc, [{ feature: 'b', t: 0.5 }, { feature: 'a', t: 0.2 }]);
    expect(clip.map((c) => [c.feature, c.dt])).toEqual([['a', 0], ['b', expect.closeTo(0.3, 12)]]);
    expect(clip[0].interpolation).toBe('ease-in');
    const { doc: out, pasted } = pasteKeys(doc, clip, 1.5);
    expect(pasted.map((p) => p.feature)).toEqual(['a', 'b']);
    const a = out.features[0].keys!;
    expect(a.map((k) => k.t)).toEqual([0.2, 1, 1.5]);
    expect(a[2]).toEqual({ t: 1.5, points: [[2, 2]], interpolation: 'ease-in' });
    expect(out.features[1].keys!.map((k) => k.t)).toEqual([0.5, expect.closeTo(1.8, 12)]);
    expect(() => pasteKeys(doc, clip, 1.9)).toThrow(/past the end/);
    expect(copyKeys(doc, [{ feature: 'zz', t: 0 }])).toEqual([]);
  });

  it('finds the keys before and after a time for the onion skin', () => {
    const a = doc2().features[0];
    expect(neighbourKeys(a, 0.6)).toMatchObject({ prev: { t: 0.2 }, next: { t: 1 } });
    expect(neighbourKeys(a, 0.2)).toMatchObject({ prev: null, next: { t: 1 } });
    expect(neighbourKeys(a, 1.5)).toMatchObject({ prev: { t: 1 }, next: null });
  });
});

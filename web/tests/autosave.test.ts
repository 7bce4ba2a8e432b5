import { describe, expect, it, vi } from 'vitest';
import { Autosaver, MemoryStore, clockTime, inlineImages, restoreQuestion } from '../src/autosave';
import { emptyScene, type SceneDoc } from '../src/scene';
import { Store, moveKey, setKey } from '../src/state';

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
      const saver = new Autosaver(kept, () => ({ doc: store.doc, fileName: 'x.json', unsaved: store.unsaved }), async () => 'data:,', 500, undefined, () => 1234);
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
    } finally {
      vi.useRealTimers();
    }
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

  it('asks to restore with the time of day', () => {
    const at = new Date(2026, 10, 27, 14, 32, 5).getTime();
    expect(clockTime(at)).toBe('14:32');
    const snap = { doc: scene(), fileName: 'x', savedAt: at, unsaved: true };
    expect(restoreQuestion(snap, at + 60_000)).toBe('Restore the scene you were editing at 14:32?');
    expect(restoreQuestion(snap, at + 3 * 86_400_000)).toMatch(/^Restore the scene you were editing at 14:32 on .+\?$/);
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

import { describe, expect, it } from 'vitest';
import { emptyScene, frameRuns, pointsAt, parseScene, serializeScene, type Pt, type SceneDoc } from '../src/scene';
import {
  UNDO_STEPS,
  Store,
  addFeature,
  addKeyHere,
  deleteKey,
  heldFromOneLateKey,
  keyRestAtStart,
  keyIndexAt,
  moveKey,
  moveKeys,
  movePoint,
  setInterpolation,
  setKey,
  downloadOrigin,
} from '../src/state';

function scene(): SceneDoc {
  const doc = emptyScene(64, 48);
  doc.layers.push({ name: 'art', image: 'data:image/png;base64,AAAA' });
  return doc;
}

describe('drawing tools', () => {
  it('a spline is drawn point by point and finished', () => {
    const s = new Store(scene());
    s.setView({ tool: 'spline' });
    s.placePoint([1, 2]);
    s.placePoint([10, 12]);
    s.placePoint([20, 5]);
    expect(s.view.draft).toHaveLength(3);
    const id = s.finishDraft();
    expect(id).toBe('spline1');
    expect(s.doc.features).toEqual([{ id: 'spline1', kind: 'spline', rest: [[1, 2], [10, 12], [20, 5]] }]);
    expect(s.view.draft).toEqual([]);
    expect(s.view.selection).toEqual({ feature: 'spline1', point: null });
  });

  it('a point tool finishes at once; regions are spline outlines', () => {
    const s = new Store(scene());
    s.setView({ tool: 'point' });
    s.placePoint([3, 4]);
    expect(s.doc.features[0]).toEqual({ id: 'point1', kind: 'point', rest: [[3, 4]] });
    s.setView({ tool: 'region' });
    for (const p of [[0, 0], [10, 0], [5, 8]] as Pt[]) s.placePoint(p);
    s.finishDraft();
    expect(s.doc.features[1]).toMatchObject({ id: 'region1', kind: 'region', curve: 'spline' });
  });

  it('too few points keep the draft and say why', () => {
    const s = new Store(scene());
    s.setView({ tool: 'region' });
    s.placePoint([0, 0]);
    s.placePoint([1, 0]);
    expect(() => s.finishDraft()).toThrow(/at least 3/);
    expect(s.view.draft).toHaveLength(2);
    expect(s.doc.features).toHaveLength(0);
  });

  it('a region with no area, or a line whose points are all at one place, is refused and says why', () => {
    const s = new Store(scene());
    s.setView({ tool: 'region' });
    for (const p of [[0, 0], [5, 5], [10, 10]] as Pt[]) s.placePoint(p);
    expect(() => s.finishDraft()).toThrow(/A region needs an area, and its 3 points lie on one line/);
    expect(s.view.draft).toHaveLength(3);
    expect(s.doc.features).toHaveLength(0);
    s.placePoint([0, 10]);
    expect(s.finishDraft()).toBe('region1');
    s.setView({ tool: 'cut' });
    s.placePoint([4, 4]);
    s.placePoint([4, 4]);
    expect(() => s.finishDraft()).toThrow("The cut's 2 points are all at one place (4, 4)");
    expect(() => addFeature(s.doc, 'polyline', [[1, 1], [1, 1], [1, 1]])).toThrow(/all at one place/);
    expect(s.doc.features).toHaveLength(1);
  });

  it('new features join a layer that lists its features', () => {
    const doc = scene();
    doc.layers[0].features = [];
    const { doc: d2, id } = addFeature(doc, 'cut', [[0, 0], [5, 5]], { layer: 0 });
    expect(d2.layers[0].features).toEqual([id]);
    expect(doc.layers[0].features).toEqual([]); // immutable
  });

  it('tracing is refused in pose mode', () => {
    const s = new Store(scene());
    s.setView({ tool: 'polyline', mode: 'pose' });
    expect(() => s.placePoint([1, 1])).toThrow(/rest mode/);
  });

  it('delete removes a control point in rest mode, else the feature', () => {
    const s = new Store(scene());
    s.setView({ tool: 'polyline' });
    for (const p of [[0, 0], [5, 0], [9, 9]] as Pt[]) s.placePoint(p);
    const id = s.finishDraft()!;
    s.setView({ tool: 'select', selection: { feature: id, point: 1 } });
    s.deleteSelection();
    expect(s.doc.features[0].rest).toEqual([[0, 0], [9, 9]]);
    s.setView({ selection: { feature: id, point: 0 } });
    expect(() => s.deleteSelection()).toThrow(/at least 2/);
    s.setView({ selection: { feature: id, point: null } });
    s.deleteSelection();
    expect(s.doc.features).toHaveLength(0);
  });
});

describe('keys', () => {
  const base = () => addFeature(scene(), 'polyline', [[0, 0], [10, 0]]).doc;

  it('dragging in pose mode auto-keys the current time', () => {
    let doc = movePoint(base(), 'pose', 0.5, 'polyline1', 1, [10, 5]);
    expect(doc.features[0].keys).toEqual([{ t: 0.5, points: [[0, 0], [10, 5]] }]);
    doc = movePoint(doc, 'pose', 0.5, 'polyline1', 0, [1, 1]);
    expect(doc.features[0].keys).toEqual([{ t: 0.5, points: [[1, 1], [10, 5]] }]);
    expect(doc.features[0].rest).toEqual([[0, 0], [10, 0]]);
  });

  it('rest mode moves the rest drawing only', () => {
    let doc = setKey(base(), 'polyline1', 1, [[0, 3], [10, 3]]);
    doc = movePoint(doc, 'rest', 1, 'polyline1', 0, [2, 2]);
    expect(doc.features[0].rest).toEqual([[2, 2], [10, 0]]);
    expect(doc.features[0].keys![0].points).toEqual([[0, 3], [10, 3]]);
  });

  it('keys stay sorted; move refuses to land on another key; delete removes', () => {
    let doc = setKey(base(), 'polyline1', 1, [[0, 1], [10, 1]]);
    doc = setKey(doc, 'polyline1', 0.25, [[0, 2], [10, 2]]);
    expect(doc.features[0].keys!.map((k) => k.t)).toEqual([0.25, 1]);
    doc = moveKey(doc, 'polyline1', 0.25, 1.5);
    expect(doc.features[0].keys!.map((k) => k.t)).toEqual([1, 1.5]);
    expect(() => moveKey(doc, 'polyline1', 1.5, 1)).toThrow(/already has a key/);
    doc = deleteKey(doc, 'polyline1', 1);
    expect(doc.features[0].keys!.map((k) => k.t)).toEqual([1.5]);
    doc = deleteKey(doc, 'polyline1', 1.5);
    expect(doc.features[0].keys).toBeUndefined();
  });

  it('key times summed in floating point are kept to the nanosecond', () => {
    // Fifteen frame steps at 30 fps: 0.49999999999999994, which the file kept as such.
    let t = 0;
    for (let i = 0; i < 15; i++) t += 1 / 30;
    expect(t).not.toBe(0.5);
    let doc = addKeyHere(setKey(base(), 'polyline1', 0.2, [[0, 1], [10, 1]]), 'polyline1', t);
    expect(doc.features[0].keys!.map((k) => k.t)).toEqual([0.2, 0.5]);
    // A drag by the difference of two frame times: 0.2 + (0.9 − 0.2) is 0.8999999999999999.
    doc = moveKeys(doc, [{ feature: 'polyline1', t: 0.2 }], 0.9 - 0.2);
    expect(doc.features[0].keys!.map((k) => k.t)).toEqual([0.5, 0.9]);
    doc = moveKey(doc, 'polyline1', 0.9, 0.1 + 0.2);
    expect(doc.features[0].keys!.map((k) => k.t)).toEqual([0.3, 0.5]);
  });

  it('a single late key is named, and keying the rest at 0 s makes the feature move from rest', () => {
    let doc = setKey(base(), 'polyline1', 1, [[0, 10], [10, 10]]);
    const rest = doc.features[0].rest;
    expect(heldFromOneLateKey(doc.features[0])).toBe(true);
    // One key poses every time, 0 s included.
    expect(pointsAt(doc.features[0], 0)).toEqual([[0, 10], [10, 10]]);
    doc = keyRestAtStart(doc, 'polyline1');
    const f = doc.features[0];
    expect(f.keys!.map((k) => k.t)).toEqual([0, 1]);
    expect(pointsAt(f, 0)).toEqual(rest);
    expect(pointsAt(f, 1)).toEqual([[0, 10], [10, 10]]);
    expect(heldFromOneLateKey(f)).toBe(false);
    // Again: a key is at 0 s already, nothing changes.
    expect(keyRestAtStart(doc, 'polyline1')).toBe(doc);
    // A key at 0 s alone holds the pose it was given: no late key.
    expect(heldFromOneLateKey(setKey(base(), 'polyline1', 0, [[0, 3], [10, 3]]).features[0])).toBe(false);
  });

  it('add key here holds the current pose', () => {
    let doc = setKey(base(), 'polyline1', 0, [[0, 0], [10, 0]]);
    doc = setKey(doc, 'polyline1', 1, [[0, 10], [10, 10]]);
    doc = setInterpolation(doc, 'polyline1', 0, 'linear');
    doc = addKeyHere(doc, 'polyline1', 0.5);
    const f = doc.features[0];
    expect(f.keys![keyIndexAt(f, 0.5)].points).toEqual([[0, 5], [10, 5]]);
  });

  it('interpolation: hold, linear, smooth; before first and after last key', () => {
    let doc = setKey(base(), 'polyline1', 1, [[0, 0], [10, 0]]);
    doc = setKey(doc, 'polyline1', 2, [[0, 8], [10, 8]]);
    const f = () => doc.features[0];
    expect(pointsAt(f(), 0)).toEqual([[0, 0], [10, 0]]);
    expect(pointsAt(f(), 3)).toEqual([[0, 8], [10, 8]]);
    // Two keys, smooth: eases out of the first and into the second, halfway at the middle.
    expect(pointsAt(f(), 1.5)[0][1]).toBeCloseTo(4, 9);
    expect(pointsAt(f(), 1.25)[0][1]).toBeLessThan(2);
    doc = setInterpolation(doc, 'polyline1', 1, 'hold');
    expect(pointsAt(f(), 1.99)[0][1]).toBe(0);
    expect(f().keys![0].interpolation).toBe('hold');
    doc = setInterpolation(doc, 'polyline1', 1, 'smooth');
    expect(f().keys![0].interpolation).toBeUndefined();
  });

  it('smooth motion passes through every key and is C1 at inner keys', () => {
    let doc = base();
    const ys = [0, 10, 4, 12];
    ys.forEach((y, i) => {
      doc = setKey(doc, 'polyline1', i * 0.5, [[0, y], [10, y]]);
    });
    const f = doc.features[0];
    ys.forEach((y, i) => expect(pointsAt(f, i * 0.5)[0][1]).toBeCloseTo(y, 9));
    const h = 1e-5;
    for (const t of [0.5, 1.0]) {
      const left = (pointsAt(f, t)[0][1] - pointsAt(f, t - h)[0][1]) / h;
      const right = (pointsAt(f, t + h)[0][1] - pointsAt(f, t)[0][1]) / h;
      expect(Math.abs(left - right)).toBeLessThan(1e-2);
    }
  });
});

describe('frames', () => {
  it('tells the frames ready to play as runs, from those frames alone (a scene may have 1e8)', () => {
    expect(frameRuns([])).toEqual([]);
    expect(frameRuns([5, 0, 2, 1, 99_999_999, 6, 99_999_998, 50_000_000])).toEqual([[0, 2], [5, 6], [50_000_000, 50_000_000], [99_999_998, 99_999_999]]);
    expect(frameRuns(new Set(Array.from({ length: 12 }, (_, i) => 11 - i)))).toEqual([[0, 11]]);
  });
});

describe('undo', () => {
  it('undo and redo walk the history; a drag is one step', () => {
    const s = new Store(scene());
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    s.placePoint([2, 2]);
    expect(s.doc.features).toHaveLength(2);
    s.begin();
    for (let i = 0; i < 10; i++) s.edit((d) => movePoint(d, 'rest', 0, 'point1', 0, [1 + i, 1]));
    s.commit();
    expect(s.doc.features[0].rest).toEqual([[10, 1]]);
    s.undo();
    expect(s.doc.features[0].rest).toEqual([[1, 1]]);
    s.undo();
    expect(s.doc.features).toHaveLength(1);
    s.redo();
    s.redo();
    expect(s.doc.features[0].rest).toEqual([[10, 1]]);
    expect(s.canRedo()).toBe(false);
  });

  it('an edit that changes nothing is no step and leaves the scene saved', () => {
    // A key time typed again, a key pasted over itself: a new document with the same values.
    const s = new Store(scene());
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    s.markSaved();
    const [steps, revision] = [s.canUndo(), s.revision];
    s.edit((d) => JSON.parse(JSON.stringify(d)));
    expect([s.unsaved, s.revision, s.canUndo()]).toEqual([false, revision, steps]);
    s.undo();
    expect(s.doc.features).toHaveLength(0);
    s.redo();
    s.edit((d) => ({ ...d, features: d.features.map((f) => ({ ...f, rest: [[2, 1]] as Pt[] })) }));
    expect([s.unsaved, s.doc.features[0].rest]).toEqual([true, [[2, 1]]]);
  });

  it('a new edit clears redo; cancel restores the gesture start', () => {
    const s = new Store(scene());
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    s.undo();
    s.placePoint([5, 5]);
    expect(s.canRedo()).toBe(false);
    s.begin();
    s.edit((d) => movePoint(d, 'rest', 0, 'point1', 0, [9, 9]));
    s.cancel();
    expect(s.doc.features[0].rest).toEqual([[5, 5]]);
  });

  it('undo and redo across opening a scene bring each document back with its own origin', () => {
    // Save writes to the current document's origin: one undo past opening a served file
    // must not make Save write the scene before it into that file, and back again the
    // file's own scene must save to the file (one origin object per opened scene, so a
    // save's new version holds for all its steps).
    const s = new Store(scene());
    const demo = s.origin;
    expect(demo.saveUrl).toBeNull();
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    const file = { ...downloadOrigin('cat.json'), saveUrl: '/api/scene', path: '/work/cat.json', version: '"v1"' };
    s.load(scene(), file);
    expect(s.origin).toBe(file);
    expect(s.unsaved).toBe(false);
    s.setView({ tool: 'point' });
    s.placePoint([2, 2]);
    file.version = '"v2"'; // saved
    s.undo();
    expect(s.origin).toBe(file);
    s.undo();
    expect(s.origin).toBe(demo);
    expect(s.doc.features).toHaveLength(1);
    expect(s.unsaved).toBe(true);
    s.redo();
    expect(s.origin).toBe(file);
    expect(s.origin.version).toBe('"v2"');
    // Opening another scene over unsaved work and undoing brings the work and its file back.
    s.redo();
    s.setView({ tool: 'point' });
    s.placePoint([3, 3]);
    s.load(scene(), downloadOrigin('face.json'));
    expect(s.origin.saveUrl).toBeNull();
    s.undo();
    expect(s.origin).toBe(file);
    expect(s.doc.features).toHaveLength(2);
    expect(s.unsaved).toBe(true);
  });

  it('past UNDO_STEPS changes Undo still reaches the scene an Open replaced', () => {
    // The oldest steps were dropped whatever they were: 500 clicks after opening a picture
    // over unsaved work, that work was out of Undo's reach and in no file.
    const s = new Store(scene());
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    const work = s.doc;
    s.load(scene(), downloadOrigin('face.json'));
    s.setView({ tool: 'point' });
    for (let i = 0; i < UNDO_STEPS + 5; i++) s.placePoint([2 + (i % 40), 2 + Math.floor(i / 40)]);
    let undos = 0;
    while (s.canUndo()) {
      s.undo();
      undos++;
    }
    expect(s.doc).toBe(work);
    expect(s.unsaved).toBe(true);
    // The picture's newest changes and its opening, UNDO_STEPS steps in all; the work's own
    // first step (the empty scene) was the oldest, and went.
    expect(undos).toBe(UNDO_STEPS);
  });

  it('markSaved marks the revision that was written, not edits made while it was written', () => {
    const s = new Store(scene());
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    const written = s.revision;
    s.placePoint([2, 2]);
    s.markSaved(written);
    expect(s.unsaved).toBe(true);
    s.markSaved();
    expect(s.unsaved).toBe(false);
  });

  it('a file another writer changed leaves no revision counted as saved, till a save of this tab', () => {
    const s = new Store(scene());
    s.origin = { fileName: 'a.json', saveUrl: '/api/scene', path: '/tmp/a.json', version: '"v1"' };
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    s.markSaved();
    // The file still at the version this tab knows: nothing changes.
    expect([s.fileChanged('"v1"'), s.unsaved]).toEqual([false, false]);
    // Another writer's version: news, and unsaved; Save still sends the version it knew (it asks).
    expect([s.fileChanged('"v2"'), s.unsaved, s.origin.version]).toEqual([true, true, '"v1"']);
    // Said once; a later writer's is recorded, not said again (the scene is unsaved already).
    expect([s.fileChanged('"v2"'), s.fileChanged('"v3"'), s.fileChanged(null)]).toEqual([false, false, false]);
    // Undo back to what this tab saved: still not in the file.
    s.placePoint([2, 2]);
    s.undo();
    expect(s.unsaved).toBe(true);
    // This tab's save writes the file again: saved, and its version the file's.
    s.fileSaved(s.origin, '"v4"', s.revision);
    expect([s.unsaved, s.origin.version, s.origin.changedTo]).toEqual([false, '"v4"', undefined]);
  });

  it('a restore from an older version of the file keeps the file as opened counted as saved', () => {
    // The page opens the file at v2; kept work made from v1 (another tab saved since) is
    // restored over it, unsaved. The file is at v2: Undo back to it is still saved.
    const s = new Store(scene());
    const file = { fileName: 'a.json', saveUrl: '/api/scene', path: '/tmp/a.json', version: '"v2"' };
    s.load(scene(), file);
    s.load({ ...scene(), duration: 3 }, { ...file, version: '"v1"' });
    s.markUnsaved();
    expect([s.fileChanged('"v2"'), s.unsaved]).toEqual([false, true]);
    s.undo();
    expect([s.origin, s.unsaved]).toEqual([file, false]);
  });

  it('a document undone or redone back to what was saved counts as saved', () => {
    const s = new Store(scene());
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    s.markSaved();
    s.placePoint([2, 2]);
    expect(s.unsaved).toBe(true);
    s.undo();
    expect(s.unsaved).toBe(false);
    s.redo();
    expect(s.unsaved).toBe(true);
    s.undo();
    s.undo();
    expect(s.unsaved).toBe(true);
    s.redo();
    expect(s.unsaved).toBe(false);
    // A new edit from there is a new document, never mistaken for the one undone away.
    const seen = new Set([s.revision]);
    s.undo();
    seen.add(s.revision);
    s.placePoint([3, 3]);
    expect(seen.has(s.revision)).toBe(false);
    expect(s.unsaved).toBe(true);
  });

  it('a drag undone, or cancelled, is the document from before it', () => {
    const s = new Store(scene());
    s.markSaved();
    s.begin();
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    s.commit();
    expect(s.unsaved).toBe(true);
    s.undo();
    expect(s.unsaved).toBe(false);
    s.begin();
    s.placePoint([2, 2]);
    s.cancel();
    expect(s.unsaved).toBe(false);
    // A drag that comes back to where it started (keys moved out and back).
    const start = s.doc;
    s.begin();
    s.apply({ ...start, duration: start.duration + 1 });
    s.apply(start);
    s.commit();
    expect(s.unsaved).toBe(false);
  });

  it('undo of a deletion brings the selection back to a valid state', () => {
    const s = new Store(scene());
    s.setView({ tool: 'point' });
    s.placePoint([1, 1]);
    s.undo();
    expect(s.view.selection.feature).toBeNull();
  });
});

describe('files', () => {
  it('round-trips and keeps unknown fields', () => {
    const doc = { ...scene(), custom: { a: 1 } };
    const back = parseScene(serializeScene(doc as SceneDoc));
    expect(back).toEqual(doc);
  });

  it('bad files name the JSON path', () => {
    expect(() => parseScene('nope')).toThrow(/not a JSON file/);
    const doc = scene();
    doc.features.push({ id: 'a', kind: 'spline', rest: [[0, 0], [1, 1]], keys: [{ t: 1, points: [[0, 0]] }] });
    expect(() => parseScene(JSON.stringify(doc))).toThrow(/features\[0\]\.keys\[0\]\.points: has 1 points/);
    (doc.features[0] as { kind: string }).kind = 'blob';
    expect(() => parseScene(JSON.stringify(doc))).toThrow(/features\[0\]\.kind: unknown kind "blob"/);
  });
});

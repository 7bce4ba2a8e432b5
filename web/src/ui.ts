// The editor's page: toolbar, layers, stage, inspector, timeline, help; pointer and keys.

import { App } from './app';
import { clear, h } from './dom';
import type { ViewSpec } from './engine';
import { BUILTIN, builtinScene, listExamples, type ExampleEntry } from './examples';
import { blobToDataUri, decodeBlob, decodeImage, fileOf, fileToDataUri, nameFiles, PICTURE_KEYS, type PictureKey, pictureName, pictureSlot, rememberImage, rgbaToPngBlob, type Rgba, withPictureNamed } from './images';
import { isPsdName, readLayeredPsd, uniqueNames } from './psd';
import { Overlay } from './overlay';
import type { FullFrame } from './solver';
import { proxyFactor, viewFor } from './proxy';
import { canEncodeWebm, encodeWebm, overWhite } from './webm';
import { PROBE_DWELL_MS } from './probe';
import { clampMove, clampPoint, durationProblem, featureBox, fpsProblem, offsetBox, offsetProblem } from './limits';
import {
  INTERPOLATIONS,
  METHODS,
  METHOD_NOTES,
  layerMethod,
  SceneFileError,
  emptyScene,
  frameCount,
  layerFeatures,
  parseScene,
  serializeScene,
  sortedKeys,
  type Interpolation,
  type Layer,
  type Method,
  type Pt,
  type SceneDoc,
} from './scene';
import {
  CUT_HAS_NO_KEYS,
  KEY_EPS,
  addKeyHere,
  deleteKey,
  getFeature,
  heldFromOneLateKey,
  keyRestAtStart,
  moveFeature,
  moveKey,
  moveKeys,
  copyKeys,
  pasteKeys,
  hasKeyRef,
  toggleKeyRef,
  type ClipKey,
  type KeyRef,
  movePoint,
  movePoints,
  pointsInRect,
  hasPointRef,
  type PointRef,
  reorderLayer,
  setInterpolation,
  setLayerFeatures,
  setMethod,
  shownPoints,
  updateLayer,
  deleteLayer,
  downloadOrigin,
  type Origin,
  type Tool,
} from './state';

export const TOOLS: { tool: Tool; key: string; label: string; title: string }[] = [
  { tool: 'select', key: 'v', label: 'Select', title: 'Select and move control points or whole features (V)' },
  { tool: 'point', key: 'p', label: 'Point', title: 'Point: pins or moves one spot (P)' },
  { tool: 'polyline', key: 'l', label: 'Polyline', title: 'Polyline: click the vertices, Enter to finish (L)' },
  { tool: 'spline', key: 's', label: 'Spline', title: 'Spline: click control points, Enter to finish (S)' },
  { tool: 'region', key: 'g', label: 'Region', title: 'Region: a filled shape that moves as a whole (G)' },
  { tool: 'cut', key: 'c', label: 'Cut', title: 'Cut: a line the picture tears along (C)' },
];

export const SHORTCUTS: [string, string][] = [
  ['V / P / L / S / G / C', 'Select, point, polyline, spline, region, cut tool'],
  ['R / E', 'Rest mode (trace) / pose mode (animate)'],
  ['Tab', 'Switch between rest and pose mode'],
  ['Click', 'Add a control point (drawing tools, rest mode)'],
  ['Enter or double-click', 'Finish the feature being drawn'],
  ['Click the first point', 'Close a polyline or spline'],
  ['Esc', 'Cancel the drawing or a WebM export / clear the selection'],
  ['Drag', 'Move a control point, or a whole feature by its line'],
  ['Drag on empty stage (Shift: add)', 'Marquee: pick the control points inside; drag one to move them all'],
  ['Shift-click a point', 'Add a control point to the picked ones, or take it out'],
  ['Delete / Backspace', 'Delete the selected point (rest mode) or feature; while drawing, the last click'],
  ['K / Shift+K', 'Add / delete the selected feature’s key at this time'],
  ['Space', 'Play / pause (hold and drag: pan)'],
  ['Wheel', 'Zoom about the pointer'],
  ['Middle-drag', 'Pan'],
  ['0 / 1', 'Fit the picture / 100 %'],
  ['Shift-click a key', 'Pick several keys (drag one: they move together)'],
  ['Drag on a feature row (Shift: add)', 'Marquee: pick the keys inside'],
  ['Ctrl+C / Ctrl+V', 'Copy the picked keys / paste them at the current time'],
  ['O', 'Onion skin: the selected feature at its previous and next keys'],
  ['← / →', 'Previous / next frame'],
  ['Shift+← / Shift+→', 'Previous / next key'],
  ['Home / End', 'First / last frame'],
  ['Ctrl+Z / Ctrl+Shift+Z (Ctrl+Y)', 'Undo / redo'],
  ['Ctrl+S / Ctrl+O', 'Save the scene / open a scene, an image or a layered PSD'],
  ['D / H / M / T', 'Drawing / heat map (ΔX, ΔY, off) / mesh / matte overlay'],
  ['?', 'This help'],
];

function download(blob: Blob, name: string): void {
  const a = h('a', { href: URL.createObjectURL(blob), download: name });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10_000);
}

/**
 * How a scene is opened: the file it came from (`origin`, merged over a download's), and
 * whether it is where the editor's history starts (`first`: the scene `inkwarp edit` serves).
 */
export interface Opened {
  origin?: Partial<Origin>;
  first?: boolean;
  /** Opened as unsaved work (a restore): marked so with the scene, before the page settles. */
  unsaved?: boolean;
  /** The file each picture came from, by its place ("0.image"): `inkwarp edit` says so. */
  files?: Record<string, string>;
}

/** A drag moves the drawing on at most one raw pointer update this often (ms). */
const RAW_GAP_MS = 4;
/** A number field wide enough for `max` with a point and two decimals (and its arrows). */
const fieldWidth = (max: number): string => `calc(${String(max).length + 3}ch + 34px)`;
const WEBM_TITLE = 'Export the animation as WebM video';

export class Ui {
  readonly overlay: Overlay;
  readonly stage: HTMLElement;
  readonly glCanvas: HTMLCanvasElement;
  readonly overlayCanvas: HTMLCanvasElement;
  private els: Record<string, HTMLElement> = {};
  /** Stops the WebM export in progress (null when none is). */
  private exportStop: AbortController | null = null;
  private examples: ExampleEntry[] = [BUILTIN];
  private drag: {
    id: string;
    point: number | null;
    start: Pt;
    base: Pt[];
    /** Where the pointer last moved the drawing to (scene pixels). */
    at: Pt | null;
    /** A drag of the picked points together: each feature's points when it began. */
    group?: Map<string, Pt[]>;
  } | null = null;
  /** A marquee being dragged on empty stage (scene pixels), and whether it adds (Shift). */
  private marquee: { start: Pt; add: boolean; base: PointRef[] } | null = null;
  private messageTimer: number | null = null;
  /** The name the scene downloads as (its origin's: see `Origin`). */
  get fileName(): string {
    return this.store.origin.fileName;
  }
  /** The save in progress: saves run one after another, each with the version the last one left. */
  private saving: Promise<void> = Promise.resolve();
  /**
   * Pictures ("layer name\0key") the scene holds a kept copy of, whose file changed on disk
   * since the work was kept (see main.ts): a save asks the server to write each beside its
   * file under a new name, never back over that file nor inline in the scene.
   */
  keptCopies = new Set<string>();
  /** Set when a field's value was refused (see `refuse`). */
  private refused = false;
  private playStart: { wall: number; time: number } | null = null;
  private lastShownFrame = -1;

  constructor(
    readonly app: App,
    root: HTMLElement,
  ) {
    this.glCanvas = app.gl.canvas as HTMLCanvasElement;
    this.overlayCanvas = h('canvas.overlay', { 'aria-label': 'drawing' });
    this.overlay = new Overlay(this.overlayCanvas, app.engine);
    const pictures = app.gl.draftCanvas ? [this.glCanvas, app.gl.draftCanvas] : [this.glCanvas];
    // A large picture's full-resolution frame, over the proxy's (see `App.requestFull`).
    this.fullCanvas = h('canvas.picture.full', { hidden: true }) as HTMLCanvasElement;
    this.proxyNote = h('div#proxy-note.proxy-note', { hidden: true }, '');
    this.stage = h('div.stage', {}, h('div.frame', {}, ...pictures, this.fullCanvas, this.overlayCanvas), this.proxyNote);
    this.build(root);
    app.onMessage = (t, k) => this.message(t, k);
    app.viewFor = () => this.viewSpec();
    app.onFull = (frame) => {
      this.showFull(frame);
      this.updateStatus();
    };
    app.onFrame = () => {
      this.drawOverlay();
      this.updateProxyNote();
    };
    app.onSolved = () => {
      this.updateStatus();
      this.renderReady();
    };
    app.store.subscribe((_, docChanged) => this.refresh(docChanged));
    new ResizeObserver(() => this.layout()).observe(this.stage);
    window.addEventListener('keydown', (e) => this.onKey(e));
    // A dropdown chosen from with the pointer gives the keys back: with the focus left on it,
    // the shortcuts went to it (an arrow key could change its choice). One stepped through
    // with the keyboard keeps the focus.
    let pointed: EventTarget | null = null;
    window.addEventListener('pointerdown', (e) => (pointed = e.target), true);
    window.addEventListener('keydown', (e) => {
      // One opened with the pointer and closed without a choice (Escape) gives them back at
      // the next key, which it must not take: an arrow changed the scene's method, a letter
      // opened an example.
      if (e.target instanceof HTMLSelectElement && e.target === pointed && e.key !== 'Tab') {
        e.preventDefault();
        e.target.blur();
      }
      pointed = null;
    }, true);
    window.addEventListener('change', (e) => e.target instanceof HTMLSelectElement && e.target === pointed && e.target.blur());
    this.bindPointer();
    this.bindZoomPan();
    this.bindDrop();
    // When the page was last asked to be left, and whether it is going (see `saveNow`).
    window.addEventListener('beforeunload', () => (this.leaving.askedAt = performance.now()));
    window.addEventListener('pagehide', () => (this.leaving.gone = true));
    window.addEventListener('pageshow', () => (this.leaving.gone = false));
    void listExamples().then((list) => {
      this.examples = list;
      this.refresh(true);
    });
  }

  get store() {
    return this.app.store;
  }

  // -- Building --------------------------------------------------------------------------

  private build(root: HTMLElement): void {
    // The scene format's ranges: the fields' spinners stop there (typed values are checked too).
    const limits = this.app.engine.limits();
    const fileInput = h('input', { type: 'file', accept: '.json,application/json,image/png,image/jpeg,.psd,image/vnd.adobe.photoshop', hidden: true, onchange: () => {
      const f = fileInput.files?.[0];
      if (f) void this.openFile(f);
      fileInput.value = '';
    } }) as HTMLInputElement;
    this.els.fileInput = fileInput;
    const layerInput = h('input', { type: 'file', accept: 'image/png,image/jpeg', hidden: true, onchange: () => {
      const f = layerInput.files?.[0];
      if (f) void this.addLayerFile(f);
      layerInput.value = '';
    } }) as HTMLInputElement;
    this.els.layerInput = layerInput;
    const matteInput = h('input', { type: 'file', accept: 'image/png,image/jpeg', hidden: true, onchange: () => {
      const f = matteInput.files?.[0];
      if (f) void this.setMatteFile(f);
      else this.showLayerAgain();
      matteInput.value = '';
    }, oncancel: () => this.showLayerAgain() }) as HTMLInputElement;
    this.els.matteInput = matteInput;

    const toolbar = h('header.toolbar', {},
      h('div.group', {},
        h('button#open', { title: 'Open a scene (.json), an image or a layered PSD (Ctrl+O)', onclick: () => fileInput.click() }, 'Open…'),
        (this.els.examples = h('select#examples', { title: 'Open a bundled example', onchange: (e: Event) => {
          const sel = e.target as HTMLSelectElement;
          if (sel.value) void this.openExample(sel.value);
          sel.value = '';
        } })),
        h('button#save', { title: 'Save the scene (Ctrl+S): back to its file when inkwarp edit SCENE opened it, else a download of one JSON file', onclick: () => void this.save() }, 'Save'),
        h('button#export-png', { title: 'Export the current frame as PNG', onclick: () => void this.exportPng() }, 'PNG'),
        (this.els.exportWebm = h('button#export-webm', { title: WEBM_TITLE, onclick: () => (this.exportStop ? this.cancelExport() : void this.exportWebm()) }, 'WebM')),
      ),
      h('div.group.modes', { role: 'radiogroup' },
        h('button#mode-rest', { title: 'Rest mode: trace features over the original picture (R)', onclick: () => this.setMode('rest') }, 'Rest'),
        h('button#mode-pose', { title: 'Pose mode: move the drawing, the picture follows (E)', onclick: () => this.setMode('pose') }, 'Pose'),
      ),
      h('div.group.tools', {}, ...TOOLS.map((t) => h('button', { id: `tool-${t.tool}`, title: t.title, onclick: () => this.setTool(t.tool) }, t.label))),
      h('div.group', {},
        h('label', { title: 'The interpolant that turns the drawing into a field (saved in the scene as solver.method)' }, 'Method ',
          (this.els.method = h('select#method', { onchange: (e: Event) => this.tryEdit((d) => setMethod(d, (e.target as HTMLSelectElement).value as Method)) },
            ...METHODS.map((m) => {
              const available = this.app.engine.methods().find((x) => x.name === m)?.available ?? false;
              return h('option', { value: m, disabled: !available, title: available ? METHOD_NOTES[m] : 'not in this build' }, available ? m : `${m} (not available)`);
            })))),
        h('label', { title: 'The grid thin plate is solved on every n-th pixel and interpolated between (saved in the scene as solver.grid_step, as inkwarp render reads it); a large picture starts with a step that keeps it quick' }, ' Grid step ',
          (this.els.gridStep = h('input#grid-step', { type: 'number', min: 1, max: 64, step: 1, onchange: (e: Event) => this.setGridStep(Number((e.target as HTMLInputElement).value)) }))),
      ),
      h('div.group.overlays', {},
        h('label', { title: 'Show the drawing (D)' }, (this.els.ovDrawing = h('input#ov-drawing', { type: 'checkbox', onchange: (e: Event) => this.setOverlay({ drawing: (e.target as HTMLInputElement).checked }) })), 'Drawing'),
        h('label', { title: 'Heat map of the displacement (H)' }, 'Heat ',
          (this.els.ovHeat = h('select#ov-heat', { onchange: (e: Event) => this.setOverlay({ heat: (e.target as HTMLSelectElement).value as 'off' }) },
            h('option', { value: 'off' }, 'off'), h('option', { value: 'dx' }, 'ΔX'), h('option', { value: 'dy' }, 'ΔY')))),
        h('label', { title: 'Mesh wireframe (M)' }, (this.els.ovMesh = h('input#ov-mesh', { type: 'checkbox', onchange: (e: Event) => this.setOverlay({ mesh: (e.target as HTMLInputElement).checked }) })), 'Mesh'),
        h('label', { title: 'Continuity matte: holes in magenta (T)' }, (this.els.ovMatte = h('input#ov-matte', { type: 'checkbox', onchange: (e: Event) => this.setOverlay({ matte: (e.target as HTMLInputElement).checked }) })), 'Matte'),
        h('label', { title: 'Snap control points to pixel centres' }, (this.els.snap = h('input#snap', { type: 'checkbox', onchange: (e: Event) => this.store.setView({ snap: (e.target as HTMLInputElement).checked }) })), 'Snap'),
      ),
      h('div.group', {},
        (this.els.undo = h('button#undo', { title: 'Undo (Ctrl+Z)', onclick: () => this.history('undo') }, '↶ Undo')),
        (this.els.redo = h('button#redo', { title: 'Redo (Ctrl+Shift+Z)', onclick: () => this.history('redo') }, '↷ Redo')),
        h('button#help-button', { title: 'Keyboard shortcuts (?)', onclick: () => this.toggleHelp() }, '?'),
      ),
      h('div.group.zoom', {},
        h('button#zoom-fit', { title: 'Fit the picture in the window (0)', onclick: () => this.zoomFit() }, 'Fit'),
        h('button#zoom-100', { title: 'One picture pixel per screen pixel (1)', onclick: () => this.zoom100() }, '100 %'),
        (this.els.zoomText = h('span#zoom.time', { title: 'Wheel: zoom about the pointer; Space-drag or middle-drag: pan' }, '')),
      ),
      fileInput, layerInput, matteInput,
    );

    const layers = h('aside.panel.left', {},
      h('h2', {}, 'Layers'),
      (this.els.layers = h('ul#layers.layers')),
      h('button#add-layer', { title: 'Add a layer from an image of the scene’s size', onclick: () => layerInput.click() }, '+ Layer…'),
      (this.els.layerDetail = h('div#layer-detail')),
    );
    const inspector = h('aside.panel.right', {},
      h('h2', {}, 'Feature'),
      (this.els.feature = h('div#feature')),
      h('h2', {}, 'Engine'),
      (this.els.methodNote = h('p#method-note.hint')),
      (this.els.status = h('div#status.status')),
    );
    const timeline = h('footer.timeline', {},
      h('div.transport', {},
        (this.els.play = h('button#play', { title: 'Play / pause (Space)', onclick: () => this.togglePlay() }, '▶')),
        (this.els.scrub = h('input#scrub', { type: 'range', min: 0, step: 'any', oninput: (e: Event) => this.setTime(this.snapTime(Number((e.target as HTMLInputElement).value)), true) })),
        (this.els.timeText = h('span#time.time')),
        h('label', {}, 'fps ', (this.els.fps = h('input#fps', { type: 'number', min: limits.min_fps, max: limits.max_fps, step: 'any', style: { width: fieldWidth(limits.max_fps) }, onchange: (e: Event) => this.setFps(Number((e.target as HTMLInputElement).value)) }))),
        h('label', {}, 'duration ', (this.els.duration = h('input#duration', { type: 'number', min: 0.05, max: limits.max_time_s, step: 0.05, style: { width: fieldWidth(limits.max_time_s) }, onchange: (e: Event) => this.setDuration(Number((e.target as HTMLInputElement).value)) })), ' s'),
        h('button#key-add', { title: 'Key the selected feature here (K)', onclick: () => this.keyHere() }, '◆ Key'),
        h('button#key-delete', { title: 'Delete the selected feature’s key here (Shift+K)', onclick: () => this.unkeyHere() }, '◇ Unkey'),
      ),
      (this.els.tracks = h('div#tracks.tracks')),
    );
    const help = (this.els.help = h('div#help.help', { hidden: true, onclick: (e: Event) => { if (e.target === help) this.toggleHelp(); } },
      h('div.help-box', {},
        h('h2', {}, 'Keyboard shortcuts'),
        h('table', {}, ...SHORTCUTS.map(([k, d]) => h('tr', {}, h('td', {}, h('kbd', {}, k)), h('td', {}, d)))),
        h('p', {}, 'Trace in rest mode; switch to pose mode and drag the drawing — every drag sets a key at the current time. Save writes the scene that ', h('code', {}, 'inkwarp render'), ' reads.'),
        h('button', { onclick: () => this.toggleHelp() }, 'Close'),
      )));
    this.els.message = h('div#message.message', { role: 'alert', hidden: true, onclick: () => (this.els.message.hidden = true) });
    this.els.dropHint = h('div.drop-hint', { hidden: true }, 'Drop a scene (.json) or a picture (PNG, JPEG, layered PSD)');
    root.append(toolbar, h('main', {}, layers, this.stage, inspector), timeline, help, this.els.message, this.els.dropHint);
  }

  // -- Refreshing views ------------------------------------------------------------------

  refresh(docChanged: boolean): void {
    const { doc, view } = this.store;
    document.querySelectorAll<HTMLButtonElement>('.tools button').forEach((b) => {
      b.classList.toggle('active', b.id === `tool-${view.tool}`);
      b.disabled = view.mode === 'pose' && b.id !== 'tool-select';
    });
    document.getElementById('mode-rest')!.classList.toggle('active', view.mode === 'rest');
    document.getElementById('mode-pose')!.classList.toggle('active', view.mode === 'pose');
    document.body.dataset.mode = view.mode;
    (this.els.method as HTMLSelectElement).value = doc.solver?.method ?? 'tps';
    if (document.activeElement !== this.els.gridStep) (this.els.gridStep as HTMLInputElement).value = String(doc.solver?.grid_step ?? 1);
    (this.els.ovDrawing as HTMLInputElement).checked = view.overlays.drawing;
    (this.els.ovHeat as HTMLSelectElement).value = view.overlays.heat;
    (this.els.ovMesh as HTMLInputElement).checked = view.overlays.mesh;
    (this.els.ovMatte as HTMLInputElement).checked = view.overlays.matte;
    (this.els.snap as HTMLInputElement).checked = view.snap;
    (this.els.undo as HTMLButtonElement).disabled = !this.store.canUndo();
    (this.els.redo as HTMLButtonElement).disabled = !this.store.canRedo();
    this.els.play.textContent = view.playing ? '❚❚' : '▶';
    const scrub = this.els.scrub as HTMLInputElement;
    const n = frameCount(doc);
    // The slider ends at the last frame `inkwarp render` draws, (n − 1) / fps, not at the
    // duration: a time past it (a key at the end) is shown by no frame.
    scrub.max = String((n - 1) / doc.fps);
    scrub.step = String(1 / doc.fps);
    scrub.value = String(view.time);
    const frame = Math.round(view.time * doc.fps);
    // Frames counted from 0, as `inkwarp render --frame`, `--frames a:b` and file names count them.
    this.els.timeText.textContent = frame < n
      ? `${view.time.toFixed(2)} s · frame ${frame} of 0–${n - 1}`
      : `${view.time.toFixed(2)} s · past the last frame (${n - 1})`;
    if (document.activeElement !== this.els.fps) (this.els.fps as HTMLInputElement).value = String(doc.fps);
    if (document.activeElement !== this.els.duration) (this.els.duration as HTMLInputElement).value = String(doc.duration);
    const ex = this.els.examples as HTMLSelectElement;
    if (ex.options.length !== this.examples.length + 1) {
      clear(ex);
      ex.append(h('option', { value: '' }, 'Examples…'), ...this.examples.map((e) => h('option', { value: e.name }, e.title)));
    }
    this.renderLayers();
    this.renderFeature();
    this.renderTracks();
    // Laid out again only for a new size: a drag changes the scene at every pointer move,
    // and a layout reads the stage's size (the browser lays the page out first) and
    // clears the overlay canvas.
    if (docChanged && (doc.width !== this.laidOut[0] || doc.height !== this.laidOut[1])) this.layout();
    this.drawOverlay();
    this.updateStatus();
    this.updateProxyNote();
  }

  /** What the layer panel was last built from (it is rebuilt only when that changes). */
  private layersShown: { layers: unknown; key: string } | null = null;

  private renderLayers(): void {
    const { doc, view } = this.store;
    // A drag changes the features at every pointer move, not the layers: the panel (its
    // inputs too, which a rebuild would take the focus from) stays as it is.
    const key = JSON.stringify([view.activeLayer, this.layerMove, doc.features.map((f) => f.id), doc.layers.map((l) => this.app.runtimes.get(l.name)?.error ?? '')]);
    const shown = this.layersShown;
    if (shown && shown.layers === doc.layers && shown.key === key) return;
    this.layersShown = { layers: doc.layers, key };
    // A field entered with Enter keeps the focus through the rebuild (its new copy takes
    // it), so Tab goes on to the next field instead of switching Rest and Pose.
    const focused = document.activeElement instanceof HTMLElement && this.els.layerDetail.contains(document.activeElement) ? document.activeElement.id : '';
    this.buildLayers();
    if (focused) (this.els.layerDetail.querySelector(`#${CSS.escape(focused)}`) as HTMLElement | null)?.focus();
  }

  private buildLayers(): void {
    const { doc, view } = this.store;
    clear(this.els.layers);
    // Listed front to back (the top of the list is drawn last, on top).
    for (let i = doc.layers.length - 1; i >= 0; i--) {
      const l = doc.layers[i];
      const rt = this.app.runtimes.get(l.name);
      const li = h('li', { class: i === view.activeLayer ? 'active' : '', onclick: () => this.store.setView({ activeLayer: i }) },
        h('input', { type: 'checkbox', title: 'Visible', checked: l.visible !== false, onclick: (e: Event) => e.stopPropagation(),
          onchange: (e: Event) => this.tryEdit((d) => updateLayer(d, i, { visible: (e.target as HTMLInputElement).checked ? undefined : false })) }),
        h('span.name', {}, l.name),
        rt?.error ? h('span.warn', { title: rt.error }, '⚠') : null,
        h('button.small', { title: 'Move up (drawn later)', disabled: i === doc.layers.length - 1, onclick: (e: Event) => { e.stopPropagation(); this.tryEdit((d) => reorderLayer(d, i, i + 1)); this.store.setView({ activeLayer: i + 1 }); } }, '▲'),
        h('button.small', { title: 'Move down (drawn earlier)', disabled: i === 0, onclick: (e: Event) => { e.stopPropagation(); this.tryEdit((d) => reorderLayer(d, i, i - 1)); this.store.setView({ activeLayer: i - 1 }); } }, '▼'),
        h('button.small', { title: 'Delete the layer', onclick: (e: Event) => { e.stopPropagation(); this.tryEdit((d) => deleteLayer(d, i)); } }, '✕'),
      );
      this.els.layers.append(li);
    }
    clear(this.els.layerDetail);
    const layer = doc.layers[view.activeLayer];
    if (!layer) {
      this.els.layerDetail.append(h('p.hint', {}, 'Open a picture (or drop one here) to start.'));
      return;
    }
    const i = view.activeLayer;
    const contSel = h('select#continuity', { onchange: (e: Event) => {
      const v = (e.target as HTMLSelectElement).value;
      if (v === 'alpha') this.tryEdit((d) => updateLayer(d, i, { continuity: undefined }));
      else this.els.matteInput.click();
    } }, h('option', { value: 'alpha' }, 'from alpha'), h('option', { value: 'image' }, layer.continuity ? 'from image' : 'from image…'));
    (contSel as HTMLSelectElement).value = layer.continuity ? 'image' : 'alpha';
    const all = layer.features === undefined;
    const feats = h('div.driving', {},
      h('label', {}, h('input#drive-all', { type: 'checkbox', checked: all, onchange: (e: Event) => this.tryEdit((d) => setLayerFeatures(d, i, (e.target as HTMLInputElement).checked ? undefined : d.features.map((f) => f.id))) }), 'all features'),
      ...(all ? [] : doc.features.map((f) => h('label', {}, h('input', { type: 'checkbox', checked: layer.features!.includes(f.id), onchange: (e: Event) => {
        const on = (e.target as HTMLInputElement).checked;
        this.tryEdit((d) => setLayerFeatures(d, i, on ? [...(d.layers[i].features ?? []), f.id] : (d.layers[i].features ?? []).filter((x) => x !== f.id)));
      } }), f.id))),
    );
    this.els.layerDetail.append(
      h('h3', {}, `Layer “${layer.name}”`),
      h('label.row', {}, 'Continuity ', contSel),
      h('p.hint', {}, 'Cut features tear the surface too; show the matte overlay (T) to see the holes.'),
      h('div.row', {}, 'Driven by'), feats,
      h('label.row', { title: 'Keep the layer’s outer edge still, so the picture never pulls away from the frame (the scene’s "border": "hold")' },
        h('input#border-hold', { type: 'checkbox', checked: layer.border === 'hold',
          onchange: (e: Event) => this.tryEdit((d) => updateLayer(d, i, { border: (e.target as HTMLInputElement).checked ? 'hold' : undefined })) }),
        'Hold the border'),
      h('div.row', { title: 'Where the layer’s top-left pixel is placed in the frame (the scene’s "offset", in pixels); Move: drag on the picture to move the layer' }, 'Offset ',
        ...([0, 1] as const).map((c) => h(`input#layer-offset-${c ? 'y' : 'x'}.offset`, { type: 'number', step: 1, value: String((layer.offset ?? [0, 0])[c]),
          onchange: (e: Event) => {
            const input = e.target as HTMLInputElement;
            const v = input.value.trim() === '' ? NaN : Number(input.value);
            const why = offsetProblem(v, this.app.engine.limits());
            if (why) {
              // The field shows the layer's offset again (a refused value is never kept).
              input.value = String((layer.offset ?? [0, 0])[c]);
              return this.message(why, 'error');
            }
            const o: Pt = [...(layer.offset ?? [0, 0])] as Pt;
            o[c] = v;
            this.tryEdit((d) => updateLayer(d, i, { offset: o[0] === 0 && o[1] === 0 ? undefined : o }));
          } })),
        ' px ',
        h('button#layer-move.small', { class: this.layerMove ? 'on' : '', title: 'Move the layer: drag on the picture (Alt: off whole pixels); click again, Escape or a mode or tool to stop', onclick: () => {
          this.layerMove = !this.layerMove;
          this.refresh(false);
        } }, this.layerMove ? 'Moving…' : 'Move')),
    );
  }

  /** Layer-move mode (the layer panel's Move): a drag on the stage moves the active layer. */
  layerMove = false;

  /** Ends layer-move mode (Escape, another mode or tool); true when it was on. */
  private endLayerMove(): boolean {
    if (!this.layerMove) return false;
    this.layerMove = false;
    this.refresh(false);
    return true;
  }

  /** Drags the active layer's offset with the pointer, from the press at `p` (one undo step). */
  private moveLayer(e: PointerEvent, p: Pt): void {
    const i = this.store.view.activeLayer;
    const layer = this.store.doc.layers[i];
    if (!layer) return;
    const o0 = layer.offset ?? [0, 0];
    this.store.begin();
    const move = (ev: PointerEvent) => {
      const q = this.toScene(ev.clientX, ev.clientY);
      let o: Pt = [o0[0] + q[0] - p[0], o0[1] + q[1] - p[1]];
      if (!ev.altKey) o = [Math.round(o[0]), Math.round(o[1])];
      o = clampPoint(o, offsetBox(this.store.doc, i, this.app.engine.limits()));
      this.store.apply(updateLayer(this.store.doc, i, { offset: o[0] === 0 && o[1] === 0 ? undefined : o }));
    };
    // (A cancelled pointer, a pen lifted out of range say, ends the drag as a release does.)
    const up = () => {
      window.removeEventListener('pointermove', move);
      window.removeEventListener('pointerup', up);
      window.removeEventListener('pointercancel', up);
      this.store.commit();
    };
    window.addEventListener('pointermove', move);
    window.addEventListener('pointerup', up);
    window.addEventListener('pointercancel', up);
    void e;
  }

  private renderFeature(): void {
    const { doc, view } = this.store;
    clear(this.els.feature);
    const f = getFeature(doc, view.selection.feature);
    if (!f) {
      this.els.feature.append(h('p.hint', {}, view.mode === 'rest' ? 'Pick a tool and click on the picture to trace a feature.' : 'Drag a feature: the picture follows, and a key is set at this time.'));
      return;
    }
    const keys = sortedKeys(f);
    this.els.feature.append(
      h('div.row', {}, h('b', {}, f.id), ` · ${f.kind}${f.kind === 'region' && f.curve === 'spline' ? ' (spline outline)' : ''} · ${f.rest.length} point${f.rest.length > 1 ? 's' : ''}`),
      view.selection.point !== null ? h('div.row.hint', {}, `control point ${view.selection.point + 1}`) : '',
      keys.length === 0 ? '' : h('table.keys', {},
        h('tr', {}, h('th', {}, 'key'), h('th', {}, 'time (s)'), h('th', {}, 'to next'), h('th', {})),
        ...keys.map((k, n) => h('tr', { class: Math.abs(k.t - view.time) < KEY_EPS ? 'current' : '' },
          h('td', {}, h('button.small', { title: 'Go to this key', onclick: () => this.setTime(k.t) }, `◆${n + 1}`)),
          h('td', {}, h('input.key-time', { type: 'number', step: 1 / doc.fps, min: 0, value: k.t.toFixed(3), onchange: (e: Event) => {
            const input = e.target as HTMLInputElement;
            const typed = input.value.trim();
            const t = typed === '' ? NaN : Number(typed);
            if (!(t >= 0)) {
              input.value = k.t.toFixed(3);
              return this.message(`A key's time is a number of seconds, 0 or more, not ${typed || 'nothing'}.`, 'error');
            }
            this.tryEdit((d) => moveKey(d, f.id, k.t, t));
          } })),
          h('td', {}, (() => {
            const sel = h('select.key-interp', { onchange: (e: Event) => this.tryEdit((d) => setInterpolation(d, f.id, k.t, (e.target as HTMLSelectElement).value as Interpolation)) },
              ...INTERPOLATIONS.map((m) => h('option', { value: m }, m))) as HTMLSelectElement;
            sel.value = k.interpolation ?? 'smooth';
            return sel;
          })()),
          h('td', {}, h('button.small', { title: 'Delete this key', onclick: () => this.tryEdit((d) => deleteKey(d, f.id, k.t)) }, '✕')),
        )),
      ),
      f.kind === 'cut'
        ? h('p.hint', {}, 'A cut is not posed: it tears the picture along its line at rest. Change it in rest mode.')
        : keys.length === 0 ? h('p.hint', {}, 'No keys: the feature stays at rest. Drag it in pose mode to key it.')
        : heldFromOneLateKey(f) ? h('p#late-key.hint', {}, `One key, at ${keys[0].t.toFixed(3)} s: its pose holds at every time, 0 s too. `,
          h('button.small#key-rest', {
            title: 'Add a key at 0 s holding the rest pose: the feature then moves from rest to this key',
            onclick: () => this.tryEdit((d) => keyRestAtStart(d, f.id)),
          }, 'Key the rest at 0 s'))
        : '',
    );
  }

  /** What the timeline's rows were last built from (they are rebuilt only when that changes). */
  private tracksShown = '';

  private renderTracks(): void {
    const { doc, view } = this.store;
    // A drag in pose mode changes the keyed points at every pointer move, not what the rows
    // show (the keys' times and easing, the selection, the time): those stay as they are.
    const key = JSON.stringify([doc.duration, doc.fps, view.time, view.selection.feature, view.keySelection,
      doc.features.map((f) => [f.id, f.kind, (f.keys ?? []).map((k) => [k.t, k.interpolation ?? null])])]);
    if (key === this.tracksShown && this.els.tracks.isConnected) {
      this.renderReady();
      return;
    }
    this.tracksShown = key;
    clear(this.els.tracks);
    const dur = Math.max(doc.duration, 1e-6);
    const pct = (t: number) => `${(100 * t) / dur}%`;
    const ruler = h('div.track.ruler', { onpointerdown: (e: PointerEvent) => this.scrubTrack(e) });
    const n = frameCount(doc);
    const every = Math.max(1, Math.round(n / 24));
    for (let i = 0; i < n; i += every) ruler.append(h('span.tick', { style: { left: pct(i / doc.fps) } }, i % (every * 4) === 0 ? String(i) : ''));
    ruler.append(h('span.playhead', { style: { left: pct(view.time) } }));
    this.els.ready = h('div#ready.ready', { title: 'Frames solved and ready to play (solved ahead while playing)' });
    ruler.append(this.els.ready);
    this.renderReady();
    this.els.tracks.append(h('div.track-row.ruler-row', {}, h('span.track-name', { title: 'Frame numbers; click or drag to set the time' }, 'frames'), ruler));
    for (const f of doc.features) {
      if (f.kind === 'cut') continue;
      const track = h('div.track', { onpointerdown: (e: PointerEvent) => this.scrubTrack(e, true) });
      for (const k of sortedKeys(f)) {
        const picked = hasKeyRef(view.keySelection, { feature: f.id, t: k.t });
        const diamond = h('span.key', {
          class: `key ${f.id === view.selection.feature ? 'selected' : ''} ${picked ? 'picked' : ''}`,
          title: `${f.id} at ${k.t.toFixed(3)} s (${k.interpolation ?? 'smooth'}); drag to move (Alt: off the frames), Shift-click to pick several, Ctrl+C / Ctrl+V to copy and paste`,
          style: { left: pct(k.t) },
          dataset: { feature: f.id, t: String(k.t) },
          onpointerdown: (e: PointerEvent) => this.dragKey(e, f.id, k.t, track),
        });
        track.append(diamond);
      }
      track.append(h('span.playhead', { style: { left: pct(view.time) } }));
      const row = h('div.track-row', { class: f.id === view.selection.feature ? 'selected' : '' },
        h('span.track-name', { onclick: () => this.store.setView({ selection: { feature: f.id, point: null } }) }, f.id), track);
      this.els.tracks.append(row);
      // A feature selected (on the stage, or just traced) shows its row, wherever the rows are scrolled.
      if (f.id === view.selection.feature && f.id !== this.tracksSelected) this.showRow(row);
    }
    this.tracksSelected = view.selection.feature;
  }

  /** The feature selected when the timeline's rows were last built. */
  private tracksSelected: string | null = null;

  /** Scrolls the timeline's rows (only them, never the page) so that `row` shows. */
  private showRow(row: HTMLElement): void {
    const box = this.els.tracks;
    const [r, b] = [row.getBoundingClientRect(), box.getBoundingClientRect()];
    if (r.top < b.top) box.scrollTop -= b.top - r.top;
    else if (r.bottom > b.bottom) box.scrollTop += r.bottom - b.bottom;
  }

  /**
   * The ready bar: a mark under every run of frames whose fields are solved (playback needs
   * no solve there), at least a pixel wide (a frame of a long scene is narrower).
   */
  renderReady(): void {
    const bar = this.els.ready;
    if (!bar) return;
    const runs = this.app.readyRuns();
    const key = runs.map(([a, b]) => `${a}-${b}`).join(',');
    if (bar.dataset.frames === key) return;
    bar.dataset.frames = key;
    bar.dataset.count = String(runs.reduce((sum, [a, b]) => sum + b - a + 1, 0));
    clear(bar);
    const n = frameCount(this.store.doc);
    for (const [a, b] of runs) bar.append(h('span', { style: { left: `${(100 * a) / n}%`, width: `${(100 * (b - a + 1)) / n}%` } }));
  }

  /**
   * A press on the ruler or a feature's track sets the time (dragging scrubs). On a feature's
   * track, a drag of more than a few pixels draws a marquee instead: it picks the keys inside
   * it, on every row it crosses (Shift adds them to the picked keys).
   */
  private scrubTrack(e: PointerEvent, marquee = false): void {
    // Measured once: the row is redrawn (a new element) at every change of time.
    const r = (e.currentTarget as HTMLElement).getBoundingClientRect();
    const time0 = this.store.view.time;
    const base = e.shiftKey ? this.store.view.keySelection : [];
    let box: HTMLElement | null = null;
    const move = (ev: PointerEvent) => {
      if (marquee && (box || Math.hypot(ev.clientX - e.clientX, ev.clientY - e.clientY) > 4)) {
        if (!box) {
          box = h('div.key-marquee', {});
          document.body.append(box);
          this.setTime(time0, true);
        }
        const [x0, x1] = [Math.min(e.clientX, ev.clientX), Math.max(e.clientX, ev.clientX)];
        const [y0, y1] = [Math.min(e.clientY, ev.clientY), Math.max(e.clientY, ev.clientY)];
        Object.assign(box.style, { left: `${x0}px`, top: `${y0}px`, width: `${x1 - x0}px`, height: `${y1 - y0}px` });
        const picked: KeyRef[] = [...base];
        for (const k of this.els.tracks.querySelectorAll<HTMLElement>('.key')) {
          const b = k.getBoundingClientRect();
          const cx = (b.left + b.right) / 2, cy = (b.top + b.bottom) / 2;
          const ref = { feature: k.dataset.feature!, t: Number(k.dataset.t) };
          if (cx >= x0 && cx <= x1 && cy >= y0 && cy <= y1 && !hasKeyRef(picked, ref)) picked.push(ref);
        }
        this.store.setView({ keySelection: picked });
        return;
      }
      const t = Math.max(0, Math.min(1, (ev.clientX - r.left) / r.width)) * this.store.doc.duration;
      this.setTime(ev.altKey ? t : this.snapTime(t), true);
    };
    move(e);
    const up = () => {
      window.removeEventListener('pointermove', move);
      window.removeEventListener('pointerup', up);
      box?.remove();
      this.app.settle();
    };
    window.addEventListener('pointermove', move);
    window.addEventListener('pointerup', up);
  }

  private dragKey(e: PointerEvent, id: string, t0: number, track: HTMLElement): void {
    e.stopPropagation();
    // Measured first: selecting and setting the time below redraw the row (a new element).
    const r = track.getBoundingClientRect();
    const ref = { feature: id, t: t0 };
    if (e.shiftKey) {
      this.store.setView({ keySelection: toggleKeyRef(this.store.view.keySelection, ref) });
      return;
    }
    // A picked key drags every picked key with it; another key is picked alone.
    const group = hasKeyRef(this.store.view.keySelection, ref) ? this.store.view.keySelection : [ref];
    this.store.setView({ selection: { feature: id, point: null }, keySelection: group });
    this.setTime(t0);
    this.dragKeys(e, group, t0, r);
  }

  /**
   * Drags the keys of `group` (one key, or every picked key) together, following the
   * pointer from where it was pressed on the key at `t0`, measured against the row as it
   * was then (the row is redrawn, a new element, at every change). The pressed key lands
   * on frames unless Alt is held, and the move stops where the first or last key of the
   * group reaches the start or the end of the animation; a move that would put a key on
   * another key that is not moving is not made (the keys stay where they were).
   */
  private dragKeys(e: PointerEvent, group: KeyRef[], t0: number, r: DOMRect): void {
    const base = this.store.doc;
    const x0 = e.clientX;
    const first = Math.min(...group.map((k) => k.t));
    const last = Math.max(...group.map((k) => k.t));
    let dt = 0;
    this.store.begin();
    const move = (ev: PointerEvent) => {
      const { duration } = this.store.doc;
      const raw = ((ev.clientX - x0) / Math.max(1, r.width)) * duration;
      // Onto frames, where a key at the scene's end (past the last frame) may go too.
      const to = ev.altKey ? t0 + raw : Math.round((t0 + raw) * this.store.doc.fps) / this.store.doc.fps;
      const next = Math.max(-first, Math.min(duration - last, to - t0));
      if (Math.abs(next - dt) < KEY_EPS) return;
      try {
        this.store.apply(moveKeys(base, group, next));
        dt = next;
        this.store.setView({ keySelection: group.map((k) => ({ feature: k.feature, t: k.t + dt })) });
        this.setTime(t0 + dt);
      } catch {
        // A key would land on another: stay put.
      }
    };
    const up = () => {
      window.removeEventListener('pointermove', move);
      window.removeEventListener('pointerup', up);
      this.store.commit();
    };
    window.addEventListener('pointermove', move);
    window.addEventListener('pointerup', up);
  }

  private fullCanvas: HTMLCanvasElement;
  private proxyNote: HTMLElement;

  /**
   * Shows a full-resolution frame over the proxy's, or (null) takes it away: a view (the
   * part of the frame on the stage, drawn at the stage's scale) is placed over the part of
   * the picture it shows, and stays there, scaled by the browser, as the stage is zoomed
   * and panned until the view for the new zoom arrives.
   */
  private showFull(frame: FullFrame | null): void {
    const c = this.fullCanvas;
    if (frame) {
      const { width: W, height: H } = frame;
      const k = frame.view?.shrink ?? 1;
      const [x0, y0, x1, y1] = frame.view?.region ?? [0, 0, W, H];
      const cw = Math.max(1, x1 - x0);
      const ch = Math.max(1, y1 - y0);
      if (c.width !== cw) c.width = cw;
      if (c.height !== ch) c.height = ch;
      if (x1 > x0 && y1 > y0) {
        const px = new Uint8ClampedArray(frame.pixels.buffer as ArrayBuffer, frame.pixels.byteOffset, frame.pixels.byteLength);
        c.getContext('2d')!.putImageData(new ImageData(px, x1 - x0, y1 - y0), 0, 0);
      }
      // Its place in the picture, in scene pixels (the last view pixels clipped by the picture's edge).
      const pct = (v: number, of: number) => `${(100 * v) / of}%`;
      c.style.left = pct(x0 * k, W);
      c.style.top = pct(y0 * k, H);
      c.style.width = pct(Math.min(W, x1 * k) - x0 * k, W);
      c.style.height = pct(Math.min(H, y1 * k) - y0 * k, H);
      // Drawn at least at the stage's resolution: scaled down smoothly, or up (zoomed past 100 %) pixel by pixel.
      c.style.imageRendering = k === 1 && this.scale * (window.devicePixelRatio || 1) > 1 ? 'pixelated' : 'auto';
    }
    c.hidden = !frame;
    this.updateProxyNote();
  }

  /** The view of the full-resolution frame the stage shows now (see `viewFor` in `proxy.ts`). */
  viewSpec(): ViewSpec | null {
    const { width, height } = this.store.doc;
    const frame = (this.stage.firstElementChild as HTMLElement).getBoundingClientRect();
    const st = this.stage.getBoundingClientRect();
    const z = frame.width / width;
    if (!(z > 0)) return null;
    const visible: [number, number, number, number] = [(st.left - frame.left) / z, (st.top - frame.top) / z, (st.right - frame.left) / z, (st.bottom - frame.top) / z];
    return viewFor(width, height, z * (window.devicePixelRatio || 1), visible);
  }

  private viewTimer: ReturnType<typeof setTimeout> | null = null;
  /** After a zoom or a pan has rested this long (ms), the full-resolution view is drawn for it. */
  static readonly VIEW_DEBOUNCE_MS = 150;

  /** The stage was zoomed, panned or resized: the full-resolution view follows once it rests. */
  private viewChanged(): void {
    if (this.app.proxy === 1) return;
    if (this.viewTimer !== null) clearTimeout(this.viewTimer);
    this.viewTimer = setTimeout(() => {
      this.viewTimer = null;
      this.app.requestView();
      this.updateProxyNote();
    }, Ui.VIEW_DEBOUNCE_MS);
  }

  /** Says when the picture on screen is the proxy of a large picture. */
  updateProxyNote(): void {
    const f = this.app.proxy;
    const note = this.proxyNote;
    const redrawing = f > 1 && this.app.fullShown !== null && this.app.viewWanted;
    const proxied = (f > 1 && !this.app.fullShown) || redrawing;
    // Written only when it changes: this runs at every frame.
    if (note.hidden !== !proxied) note.hidden = !proxied;
    if (!proxied) return;
    if (redrawing) {
      const text = 'Full resolution — redrawing for this zoom…';
      if (note.textContent !== text) note.textContent = text;
      return;
    }
    const { width, height } = this.app.frameSize;
    const what = `Preview (1/${f} picture, ${width}×${height})`;
    // A scene written by hand (or by a script) keeps its own step, often none: say why it settles slowly.
    const step = this.store.doc.solver?.grid_step ?? 1;
    const slow = step < f ? ` (grid step ${step}: the full picture takes a while; Grid step ${f} settles as quickly as this preview)` : '';
    const text = this.app.dragging || this.store.view.playing ? what : `${what} — settling…${slow}`;
    if (note.textContent !== text) note.textContent = text;
  }

  /** Copied keys (Ctrl+C), pasted at the current time by Ctrl+V. */
  clipboard: ClipKey[] = [];

  /** Copies the picked keys, or the selected feature's key at the current time. */
  copyKeys(): void {
    const { view, doc } = this.store;
    let refs = view.keySelection;
    if (refs.length === 0 && view.selection.feature) refs = [{ feature: view.selection.feature, t: view.time }];
    const clip = copyKeys(doc, refs);
    if (clip.length === 0) return this.message('Pick keys on the timeline (Shift-click for several) to copy them.', 'error');
    this.clipboard = clip;
    this.message(`Copied ${clip.length} key${clip.length > 1 ? 's' : ''}.`, 'info');
  }

  /** Pastes the copied keys, the earliest at the current time. */
  pasteKeys(): void {
    if (this.clipboard.length === 0) return this.message('Nothing copied: pick keys and press Ctrl+C first.', 'error');
    try {
      const { doc, pasted } = pasteKeys(this.store.doc, this.clipboard, this.store.view.time);
      this.store.apply(doc);
      this.store.setView({ keySelection: pasted });
    } catch (err) {
      this.message((err as Error).message, 'error');
    }
  }

  /** The nearest frame's time, up to the last frame's. */
  private snapTime(t: number): number {
    const doc = this.store.doc;
    return Math.min(frameCount(doc) - 1, Math.max(0, Math.round(t * doc.fps))) / doc.fps;
  }

  updateStatus(): void {
    const ev = this.app.lastReport;
    const s = this.app.stats;
    const med = (a: number[]) => (a.length ? [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)] : NaN);
    const { doc, view } = this.store;
    const layer = doc.layers[view.activeLayer] ?? doc.layers[0];
    const method = layer ? layerMethod(doc, layer) : (doc.solver?.method ?? 'tps');
    this.els.methodNote.textContent = METHOD_NOTES[method] ?? '';
    const r = ev?.report;
    const solved = this.app.shownFromCache && this.app.posed
      ? 'field solved ahead for this frame (kept for playback), not solved again'
      : !ev || !r
      ? 'no solve yet'
      : ev.reused
        ? `last field (${r.method}) already solved for this pose, not solved again · grid step ${ev.gridStep} · ${r.cycles} cycles · ${r.samples} samples`
        : r.method === 'tps'
        ? `last solve (tps) ${ev.ms.toFixed(1)} ms · grid step ${ev.gridStep} · ${r.cycles} cycles · ${r.samples} samples${r.dropped_samples ? ` · ${r.dropped_samples} dropped` : ''}`
        : `last solve (${r.method}) ${ev.ms.toFixed(1)} ms · ${r.samples} samples${r.samples_used !== undefined && r.samples_used !== r.samples ? `, ${r.samples_used} used` : ''}${r.line_pairs_used ? ` · ${r.line_pairs_used} line pairs` : ''}`;
    // The engine's remarks on the fields shown (each once, with the layers they concern).
    const notes = new Map<string, string[]>();
    if (this.app.posed) {
      for (const l of doc.layers) {
        for (const n of this.app.runtimes.get(l.name)?.notes ?? []) notes.set(n, [...(notes.get(n) ?? []), l.name]);
      }
    }
    const f = this.app.proxy;
    const parts = s.fullParts.at(-1);
    const full = f > 1
      ? `${this.app.fullShown ? 'full resolution shown' : `preview at 1/${f} (the proxy's solves above)`}${parts ? ` · last full-resolution frame: solve ${(parts.solveMs / 1000).toFixed(1)} s${parts.cycles.length ? ` (${parts.cycles.join(', ')} cycles)` : ''}, draw ${(parts.drawMs / 1000).toFixed(1)} s · grid step ${doc.solver?.grid_step ?? 1}` : ''}`
      : '';
    const lines = [
      this.app.posed ? 'pose: the picture follows the drawing' : 'rest: the original picture',
      solved,
      full,
      s.dragLatency.length ? `drag → frame median ${med(s.dragLatency).toFixed(0)} ms` : '',
      ...[...notes].map(([n, layers]) => `⚠ ${doc.layers.length > 1 ? `${layers.join(', ')}: ` : ''}${n}`),
    ];
    this.els.status.textContent = lines.filter(Boolean).join('\n');
  }

  // -- Stage -------------------------------------------------------------------------------

  /** The view's zoom (CSS px per scene px), or null to fit the picture in the stage. */
  zoom: number | null = null;
  /** How far the picture is moved from the stage's centre (CSS px). */
  pan: Pt = [0, 0];

  /** The zoom that fits the whole picture in the stage. */
  fitZoom(): number {
    const { width, height } = this.store.doc;
    const r = this.stage.getBoundingClientRect();
    const pad = 16;
    return Math.max(0.02, Math.min((r.width - pad) / width, (r.height - pad) / height, 4));
  }

  /** The zoom in use (CSS px per scene px). */
  get scale(): number {
    return this.zoom ?? this.fitZoom();
  }

  /** The scene size the stage was last laid out for. */
  private laidOut: [number, number] = [0, 0];
  /** The overlay's place on the page during a drag (see `toScene`). */
  private dragRect: DOMRect | null = null;

  layout(): void {
    const { width, height } = this.store.doc;
    this.laidOut = [width, height];
    this.dragRect = null;
    const z = this.scale;
    const frame = this.stage.firstElementChild as HTMLElement;
    frame.style.width = `${width * z}px`;
    frame.style.height = `${height * z}px`;
    frame.style.flex = 'none';
    frame.style.transform = `translate(${this.pan[0]}px, ${this.pan[1]}px)`;
    // The overlay is drawn at screen resolution, but never larger than a canvas may be.
    const dpr = window.devicePixelRatio || 1;
    const px = Math.min(width * z * dpr, 8192) / (width * z * dpr);
    const dens = Math.min(px, Math.min(height * z * dpr, 8192) / (height * z * dpr));
    const ow = Math.max(1, Math.round(width * z * dpr * dens));
    const oh = Math.max(1, Math.round(height * z * dpr * dens));
    if (this.overlayCanvas.width !== ow) this.overlayCanvas.width = ow;
    if (this.overlayCanvas.height !== oh) this.overlayCanvas.height = oh;
    this.app.screenPxPerScenePx = z * dpr;
    this.viewChanged();
    if (this.els.zoomText) this.els.zoomText.textContent = `${Math.round(z * 100)} %${this.zoom === null ? ' (fit)' : ''}`;
    this.drawOverlay();
  }

  /** Zooms to `z` keeping the scene point under client point (cx, cy) where it is. */
  zoomAbout(z: number, cx: number, cy: number): void {
    const r = this.overlayCanvas.getBoundingClientRect();
    const { width, height } = this.store.doc;
    // the scene point under the pointer, unsnapped
    const p: Pt = [((cx - r.left) / r.width) * width, ((cy - r.top) / r.height) * height];
    this.zoom = Math.max(0.02, Math.min(32, z));
    this.layout();
    const r2 = this.overlayCanvas.getBoundingClientRect();
    const nx = r2.left + (p[0] / width) * r2.width;
    const ny = r2.top + (p[1] / height) * r2.height;
    this.pan = [this.pan[0] + cx - nx, this.pan[1] + cy - ny];
    this.layout();
  }

  /** Fits the whole picture in the stage. */
  zoomFit(): void {
    this.zoom = null;
    this.pan = [0, 0];
    this.layout();
  }

  /** One scene pixel per screen pixel, about the stage's centre. */
  zoom100(): void {
    const r = this.stage.getBoundingClientRect();
    this.zoomAbout(1 / (window.devicePixelRatio || 1), r.left + r.width / 2, r.top + r.height / 2);
  }

  /** Wheel (and pinch, which arrives as a wheel with Ctrl) zooms about the pointer; Space-drag or middle-drag pans. */
  private bindZoomPan(): void {
    this.stage.addEventListener('wheel', (e) => {
      e.preventDefault();
      const unit = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? 400 : 1;
      this.zoomAbout(this.scale * Math.exp(-e.deltaY * unit * (e.ctrlKey ? 0.01 : 0.0015)), e.clientX, e.clientY);
    }, { passive: false });
    let space = false;
    window.addEventListener('keydown', (e) => {
      if (e.code === 'Space' && !(e.target instanceof HTMLInputElement && e.target.type !== 'checkbox' && e.target.type !== 'range')) space = true;
    });
    window.addEventListener('keyup', (e) => {
      if (e.code !== 'Space') return;
      space = false;
      if (this.spaceDown && !this.spacePanned) this.togglePlay();
      this.spaceDown = false;
      this.spacePanned = false;
    });
    this.stage.addEventListener('pointerdown', (e) => {
      if (!(e.button === 1 || (e.button === 0 && space))) return;
      e.preventDefault();
      e.stopPropagation();
      this.spacePanned = true;
      const start: Pt = [e.clientX, e.clientY];
      const base: Pt = [this.pan[0], this.pan[1]];
      const move = (ev: PointerEvent) => {
        this.pan = [base[0] + ev.clientX - start[0], base[1] + ev.clientY - start[1]];
        this.layout();
      };
      const up = () => {
        window.removeEventListener('pointermove', move);
        window.removeEventListener('pointerup', up);
      };
      window.addEventListener('pointermove', move);
      window.addEventListener('pointerup', up);
    }, { capture: true });
  }

  /** Set when Space was used to pan (so its key-up does not also play). */
  private spacePanned = false;
  /** Space went down as a shortcut (it plays when it comes up). */
  private spaceDown = false;

  drawOverlay(): void {
    const doc = this.store.doc;
    const layer = doc.layers[this.store.view.activeLayer];
    // Playing, the drawing goes with the picture: at the time of the frame shown, which a
    // frame not solved yet leaves behind the playhead.
    const shown = this.store.view.playing ? this.app.shownTime : null;
    this.overlay.draw(this.store, layer ? this.app.runtimes.get(layer.name) : undefined, doc.width, doc.height, this.app.proxy, shown ?? this.store.view.time);
  }

  /** Client (CSS px) → scene coordinates (pixel centres at integers). */
  toScene(clientX: number, clientY: number): Pt {
    // During a drag the stage stays where it was at the press (a layout forgets it): its
    // place is read once, not at every pointer move, which would make the browser lay the
    // page out again after each move's changes to the panels.
    const r = (this.drag && this.dragRect) || this.overlayCanvas.getBoundingClientRect();
    if (this.drag && !this.dragRect) this.dragRect = r;
    const { width, height } = this.store.doc;
    let p: Pt = [((clientX - r.left) / r.width) * width - 0.5, ((clientY - r.top) / r.height) * height - 0.5];
    // To a thousandth of a pixel, far finer than a pointer places it: a click on (10, 10) is
    // saved as 10, not 9.999996495.
    const to = this.store.view.snap ? 1 : 1000;
    p = [Math.round(p[0] * to) / to, Math.round(p[1] * to) / to];
    return p;
  }

  /** Scene coordinates → client (CSS px); the tests drive the pointer with this. */
  toClient(p: Pt): Pt {
    const r = this.overlayCanvas.getBoundingClientRect();
    const { width, height } = this.store.doc;
    return [r.left + ((p[0] + 0.5) / width) * r.width, r.top + ((p[1] + 0.5) / height) * r.height];
  }

  private cssPerScenePx(): number {
    return this.overlayCanvas.getBoundingClientRect().width / this.store.doc.width;
  }

  /** The control point or feature under the pointer. */
  hit(p: Pt): { id: string; point: number | null } | null {
    const { doc, view } = this.store;
    const tol = 9 / this.cssPerScenePx();
    let best: { id: string; point: number | null; d: number } | null = null;
    const features = [...doc.features].reverse();
    for (const f of features) {
      const pts = shownPoints(f, view.mode, view.time);
      pts.forEach((q, i) => {
        const d = Math.hypot(q[0] - p[0], q[1] - p[1]);
        if (d < tol && (!best || d < best.d)) best = { id: f.id, point: f.kind === 'point' ? 0 : i, d };
      });
    }
    if (best) return best;
    const lineTol = 6 / this.cssPerScenePx();
    for (const f of features) {
      if (f.kind === 'point') continue;
      const line = this.overlay.curve(f, shownPoints(f, view.mode, view.time));
      for (let i = 0; i + 1 < line.length; i++) {
        if (segDist(p, line[i], line[i + 1]) < lineTol) return { id: f.id, point: null };
      }
    }
    // A region is also picked up by its fill: the whole region moves.
    for (const f of features) {
      if (f.kind !== 'region') continue;
      if (insidePolygon(p, this.overlay.curve(f, shownPoints(f, view.mode, view.time)))) return { id: f.id, point: null };
    }
    return null;
  }

  /** When the last raw pointer update moved a drag (see `bindPointer`). */
  private rawAt = -Infinity;
  /** What the pointer rests on in pose mode (feature/point), for probes (see `hover`). */
  private hovered: string | null = null;

  /** Moves the dragged point or feature to where the pointer is (nothing when it is there already). */
  private dragTo(e: PointerEvent): void {
    const d = this.drag;
    if (!d) return;
    const p = this.toScene(e.clientX, e.clientY);
    if (d.at && d.at[0] === p[0] && d.at[1] === p[1]) return;
    d.at = p;
    const { mode, time } = this.store.view;
    this.app.lastPointerAt = e.timeStamp || performance.now();
    // Dragged far out, the points stop where a scene's coordinates end.
    const box = (id: string) => featureBox(this.store.doc, id, this.app.engine.limits());
    try {
      if (d.group) {
        let delta: Pt = [p[0] - d.start[0], p[1] - d.start[1]];
        if (this.store.view.snap && d.point !== null) {
          const base = d.base[d.point];
          delta[0] = Math.round(base[0] + delta[0]) - base[0];
          delta[1] = Math.round(base[1] + delta[1]) - base[1];
        }
        const picked = this.store.view.pointSelection;
        for (const [id, base] of d.group) delta = clampMove(base.filter((_, i) => hasPointRef(picked, { feature: id, point: i })), delta, box(id));
        this.store.edit((doc) => movePoints(doc, mode, time, d.group!, picked, delta));
      } else if (d.point !== null) {
        const base = d.base[d.point];
        const q: Pt = [base[0] + p[0] - d.start[0], base[1] + p[1] - d.start[1]];
        this.store.edit((doc) => movePoint(doc, mode, time, d.id, d.point!, clampPoint(this.store.view.snap ? [Math.round(q[0]), Math.round(q[1])] : q, box(d.id))));
      } else {
        this.store.edit((doc) => moveFeature(doc, mode, time, d.id, d.base, clampMove(d.base, [p[0] - d.start[0], p[1] - d.start[1]], box(d.id))));
      }
    } catch (err) {
      this.message((err as Error).message, 'error');
    }
  }

  private bindPointer(): void {
    const c = this.overlayCanvas;
    c.addEventListener('pointerdown', (e) => {
      this.app.lastActivityAt = performance.now();
      if (e.button !== 0) return;
      this.app.cancelAhead(true);
      c.setPointerCapture(e.pointerId);
      const p = this.toScene(e.clientX, e.clientY);
      const { view } = this.store;
      if (view.playing) this.togglePlay();
      if (this.layerMove) {
        this.moveLayer(e, p);
        return;
      }
      const drawing = view.tool !== 'select' && view.mode === 'rest';
      if (drawing) {
        // A click on the draft's first point closes it.
        const first = view.draft[0];
        if (first && view.draft.length >= 2 && Math.hypot(first[0] - p[0], first[1] - p[1]) < 9 / this.cssPerScenePx()) {
          this.finishDraft(view.tool === 'region' ? false : true);
          return;
        }
        try {
          this.store.placePoint(p);
          this.clearError();
        } catch (err) {
          this.message((err as Error).message, 'error');
        }
        return;
      }
      const hit = this.hit(p);
      if (!hit) {
        // Empty stage: a marquee picks the control points inside it (Shift adds to them).
        this.marquee = { start: p, add: e.shiftKey, base: e.shiftKey ? view.pointSelection : [] };
        this.store.setView({ selection: { feature: null, point: null }, pointSelection: this.marquee.base });
        return;
      }
      const f = getFeature(this.store.doc, hit.id)!;
      if (f.kind === 'cut' && view.mode === 'pose') {
        // Selected, to be seen, but not dragged: a cut is not posed.
        this.store.setView({ selection: { feature: hit.id, point: null }, pointSelection: [] });
        return this.message(CUT_HAS_NO_KEYS(hit.id), 'info');
      }
      const ref = hit.point !== null ? { feature: hit.id, point: hit.point } : null;
      let picked = view.pointSelection;
      if (ref && e.shiftKey) {
        // Shift-click adds a control point to the picked ones, or takes it out.
        const had = hasPointRef(picked, ref);
        picked = had ? picked.filter((r) => r.feature !== ref.feature || r.point !== ref.point) : [...picked, ref];
        this.store.setView({ selection: { feature: hit.id, point: hit.point }, pointSelection: picked });
        if (had) return;
      } else if (!ref || !hasPointRef(picked, ref)) {
        picked = [];
        this.store.setView({ selection: { feature: hit.id, point: hit.point }, pointSelection: [] });
      } else this.store.setView({ selection: { feature: hit.id, point: hit.point } });
      this.dragRect = null;
      this.drag = { id: hit.id, point: hit.point, start: p, base: shownPoints(f, view.mode, view.time).map((q) => [q[0], q[1]] as Pt), at: null };
      if (ref && picked.length > 1) {
        const group = new Map<string, Pt[]>();
        for (const r of picked) {
          const g = getFeature(this.store.doc, r.feature);
          if (g && !group.has(r.feature)) group.set(r.feature, shownPoints(g, view.mode, view.time).map((q) => [q[0], q[1]] as Pt));
        }
        this.drag.group = group;
      }
      // A press the pointer did not rest before: the probe starts now (see `hover`; the app
      // probes in pose mode only).
      this.app.probe(hit.id, hit.point, 'press');
      this.store.begin();
      this.app.dragging = view.mode === 'pose';
    });
    // A drag follows the pointer's raw updates where the browser has them: those arrive as
    // the input does, where pointer moves wait for the next animation frame (up to 17 ms
    // more before the draft is even asked for). A fast mouse reports up to a thousand a
    // second: one every RAW_GAP_MS at most moves the drawing, and the pointer move of the
    // next frame brings it to wherever the pointer is then.
    const raw = 'onpointerrawupdate' in c;
    if (raw) {
      c.addEventListener('pointerrawupdate' as 'pointermove', (e) => {
        if (this.drag && e.timeStamp - this.rawAt >= RAW_GAP_MS) {
          this.rawAt = e.timeStamp;
          this.dragTo(e);
        }
      });
    }
    c.addEventListener('pointermove', (e) => {
      // Solving ahead waits while the pointer moves over the picture (a drag may follow).
      this.app.lastActivityAt = performance.now();
      if (this.drag) {
        this.dragTo(e);
        return;
      }
      if (this.marquee) {
        const m = this.marquee;
        const q = this.toScene(e.clientX, e.clientY);
        const { doc, view } = this.store;
        const inside = pointsInRect(doc, view.mode, view.time, m.start, q);
        this.overlay.marquee = [m.start, q];
        this.store.setView({ pointSelection: [...m.base, ...inside.filter((r) => !hasPointRef(m.base, r))] });
        return;
      }
      const p = this.toScene(e.clientX, e.clientY);
      if (this.store.view.draft.length) {
        this.overlay.hover = p;
        this.drawOverlay();
      }
      this.hover(p);
    });
    const end = () => {
      if (this.marquee) {
        this.marquee = null;
        this.overlay.marquee = null;
        this.drawOverlay();
      }
      if (!this.drag) return;
      this.drag = null;
      this.dragRect = null;
      // The pose moved: the point under the pointer is probed again at its next move.
      this.hovered = null;
      this.store.commit();
      this.app.dragging = false;
      // Draft frames after this (scrubbing, playing) were not asked for by a pointer move
      // of a drag: they must not count as drag latency.
      this.app.lastPointerAt = 0;
      this.app.settle();
    };
    c.addEventListener('pointerup', end);
    c.addEventListener('pointercancel', end);
    c.addEventListener('dblclick', () => {
      if (this.store.view.draft.length) this.finishDraft(false);
    });
    c.addEventListener('pointerleave', () => {
      this.hovered = null;
      this.overlay.hover = null;
      this.drawOverlay();
    });
  }

  /**
   * The pointer moved without a button in pose mode: once it has rested on a control point
   * (or a feature's line) for `PROBE_DWELL_MS`, the full-resolution solver probes it (see
   * `App.probe`), so that a drag of it settles sooner.
   */
  private hover(p: Pt): void {
    if (this.store.view.mode !== 'pose' || this.store.view.playing) {
      this.hovered = null;
      return;
    }
    const hit = this.hit(p);
    const key = hit ? `${hit.id}/${hit.point}` : null;
    if (key === this.hovered) return;
    this.hovered = key;
    if (!hit) return;
    setTimeout(() => {
      if (this.hovered === key && !this.drag) this.app.probe(hit.id, hit.point, 'rest');
    }, PROBE_DWELL_MS);
  }

  /** Finishes the feature being drawn; returns why it could not be (also said), or null. */
  private finishDraft(closed: boolean): string | null {
    // A double-click also placed its point twice: drop exact repeats.
    const { draft } = this.store.view;
    const apart = draft.filter((p, i, a) => i === 0 || Math.hypot(p[0] - a[i - 1][0], p[1] - a[i - 1][1]) > 1e-6);
    // Clicks all on one spot are not too few: the feature is refused for its points' place.
    const pts = apart.length === 1 && draft.length > 1 ? draft : apart;
    try {
      this.store.finishDraft(pts, closed);
      this.clearError();
      return null;
    } catch (err) {
      this.message((err as Error).message, 'error');
      return (err as Error).message;
    }
  }

  private bindDrop(): void {
    const hint = this.els.dropHint;
    window.addEventListener('dragover', (e) => {
      e.preventDefault();
      hint.hidden = false;
    });
    window.addEventListener('dragleave', (e) => {
      if (e.relatedTarget === null) hint.hidden = true;
    });
    window.addEventListener('drop', (e) => {
      e.preventDefault();
      hint.hidden = true;
      const f = e.dataTransfer?.files?.[0];
      if (f) void this.openFile(f, true);
    });
  }

  // -- Commands ----------------------------------------------------------------------------

  tryEdit(fn: (d: SceneDoc) => SceneDoc): void {
    try {
      this.store.edit(fn);
      this.clearError();
    } catch (err) {
      this.message((err as Error).message, 'error');
      this.refresh(false);
    }
  }

  setMode(mode: 'rest' | 'pose'): void {
    this.endLayerMove();
    if (this.store.view.draft.length) this.finishDraft(false);
    this.store.setView({ mode, tool: mode === 'pose' ? 'select' : this.store.view.tool });
  }

  setTool(tool: Tool): void {
    this.endLayerMove();
    // A feature being drawn is finished first, as switching to pose mode does (another tool
    // dropped it without a word).
    if (tool !== this.store.view.tool && this.store.view.draft.length) this.finishDraft(false);
    if (tool !== 'select' && this.store.view.mode === 'pose') this.setMode('rest');
    this.store.setView({ tool });
  }

  setOverlay(patch: Partial<typeof this.store.view.overlays>): void {
    this.store.setView({ overlays: { ...this.store.view.overlays, ...patch } });
  }

  setTime(t: number, scrubbing = false): void {
    const doc = this.store.doc;
    const time = Math.max(0, Math.min(doc.duration, t));
    this.app.dragging = scrubbing;
    this.store.setView({ time });
    this.app.dragging = false;
  }

  /** A refused value: say why and show the scene's own value in its field again. */
  private refuse(why: string): void {
    this.refused = true;
    this.message(why, 'error');
    (this.els.fps as HTMLInputElement).value = String(this.store.doc.fps);
    (this.els.duration as HTMLInputElement).value = String(this.store.doc.duration);
  }

  private setFps(fps: number): void {
    // Exactly the scene format's range (the engine's limits): a value it refuses would make
    // the scene, and the work kept in the browser, impossible to open again.
    const why = fpsProblem(fps, this.store.doc.duration, this.app.engine.limits());
    if (why) return this.refuse(why);
    this.tryEdit((d) => ({ ...d, fps }));
  }

  private setDuration(duration: number): void {
    const why = durationProblem(duration, this.store.doc.fps, this.app.engine.limits());
    if (why) return this.refuse(why);
    // A key cannot leave the animation: a shorter duration would hide keys past its end.
    const past = this.store.doc.features.filter((f) => (f.keys ?? []).some((k) => k.t > duration + 1e-9));
    if (past.length) {
      const last = Math.max(...past.flatMap((f) => (f.keys ?? []).map((k) => k.t)));
      const names = past.slice(0, 3).map((f) => f.id).join(', ') + (past.length > 3 ? ', …' : '');
      return this.refuse(`${names} ${past.length === 1 ? 'has keys' : 'have keys'} past ${duration} s (the last at ${last} s): move or delete them first, or keep a duration of at least ${last} s.`);
    }
    this.tryEdit((d) => ({ ...d, duration }));
    if (this.store.view.time > duration) this.setTime(duration);
  }

  keyHere(): void {
    const id = this.store.view.selection.feature;
    if (!id) return this.message('Select a feature first, then key it.', 'info');
    this.tryEdit((d) => addKeyHere(d, id, this.store.view.time));
  }

  unkeyHere(): void {
    const id = this.store.view.selection.feature;
    if (!id) return;
    this.tryEdit((d) => deleteKey(d, id, this.store.view.time));
  }

  /** To the next or previous frame (k / fps, counted, not summed: on the frames exactly). */
  private stepFrame(dir: 1 | -1): void {
    const f = this.store.view.time * this.store.doc.fps;
    const to = this.snapTime((dir > 0 ? Math.floor(f + 1e-6) + 1 : Math.ceil(f - 1e-6) - 1) / this.store.doc.fps);
    // Past the last frame (a key at the end), → stays: the last frame is behind.
    if (dir < 0 || to > this.store.view.time) this.setTime(to);
  }

  private stepKey(dir: 1 | -1): void {
    const { doc, view } = this.store;
    const f = getFeature(doc, view.selection.feature);
    const times = (f ? sortedKeys(f).map((k) => k.t) : doc.features.flatMap((g) => (g.keys ?? []).map((k) => k.t))).sort((a, b) => a - b);
    const next = dir > 0 ? times.find((t) => t > view.time + KEY_EPS) : [...times].reverse().find((t) => t < view.time - KEY_EPS);
    if (next !== undefined) this.setTime(next);
  }

  togglePlay(): void {
    const playing = !this.store.view.playing;
    // A line being drawn is kept: only Escape drops it.
    if (playing && this.store.view.draft.length) {
      return this.message('Finish the line first (Enter, or a double click) or drop it (Escape), then play.', 'info');
    }
    this.store.setView({ playing });
    if (playing) {
      this.app.cancelAhead(true);
      const doc = this.store.doc;
      const start = this.store.view.time >= doc.duration - 1e-6 ? 0 : this.store.view.time;
      this.playStart = { wall: performance.now(), time: start };
      this.lastShownFrame = -1;
      this.app.stats.playback = { expected: 0, shown: 0, dropped: 0 };
      requestAnimationFrame((t) => this.playTick(t));
    } else {
      this.playStart = null;
      this.app.settle();
    }
  }

  private playTick(now: number): void {
    if (!this.store.view.playing || !this.playStart) return;
    const doc = this.store.doc;
    const n = frameCount(doc);
    // Frames since play was pressed (absolute, so skipped frames count as dropped), looped.
    const absolute = Math.floor((this.playStart.time + (now - this.playStart.wall) / 1000) * doc.fps + 1e-9);
    if (absolute !== this.lastShownFrame) {
      const pb = this.app.stats.playback!;
      if (this.lastShownFrame >= 0) {
        pb.expected += absolute - this.lastShownFrame;
        pb.dropped += Math.max(0, absolute - this.lastShownFrame - 1);
      } else {
        pb.expected += 1;
      }
      this.lastShownFrame = absolute;
      this.store.setView({ time: (absolute % n) / doc.fps });
    }
    this.app.prefetch();
    requestAnimationFrame((tt) => this.playTick(tt));
  }

  toggleHelp(): void {
    this.els.help.hidden = !this.els.help.hidden;
  }

  /** An error said before is stale once a later action succeeds: it goes. */
  clearError(): void {
    const m = this.els.message;
    if (m.hidden || !m.classList.contains('error')) return;
    m.hidden = true;
    if (this.messageTimer !== null) clearTimeout(this.messageTimer);
    this.messageTimer = null;
  }

  /** Undo or Redo; a note about the scene it leaves ("Opened face.png ...") goes with it. */
  private history(step: 'undo' | 'redo'): void {
    const origin = this.store.origin;
    this.store[step]();
    if (this.store.origin !== origin && this.els.message.classList.contains('info')) this.els.message.hidden = true;
  }

  message(text: string, kind: 'error' | 'info' = 'info'): void {
    const m = this.els.message;
    m.textContent = text;
    m.className = `message ${kind}`;
    m.hidden = false;
    if (this.messageTimer !== null) clearTimeout(this.messageTimer);
    this.messageTimer = window.setTimeout(() => (m.hidden = true), kind === 'error' ? 12000 : 4000);
  }

  private onKey(e: KeyboardEvent): void {
    const target = e.target as HTMLElement;
    const ctrl = e.ctrlKey || e.metaKey;
    // Letters by their key, whatever Caps Lock does to them (Shift is read on its own).
    const k = e.key.length === 1 ? e.key.toLowerCase() : e.key;
    const handled = () => e.preventDefault();
    const field = target && target === document.activeElement && (target.tagName === 'INPUT' || target.tagName === 'SELECT' || target.tagName === 'TEXTAREA') && (target as HTMLInputElement).type !== 'checkbox' && (target as HTMLInputElement).type !== 'range';
    if (field && ctrl && !e.shiftKey && k === 's') {
      // Save from a field too: leaving it first commits the value typed so far (a refused
      // one is said, and nothing is saved).
      handled();
      this.refused = false;
      target.blur();
      return this.refused ? undefined : void this.save();
    }
    if (field) return;
    if ((ctrl && k === 'z') || (ctrl && !e.shiftKey && k === 'y')) {
      handled();
      // A drag is one step: undone once it ends (undoing in the middle made the rest of it
      // a step per move).
      if (this.store.inGesture) return this.message('Undo and redo wait for the drag to end.', 'info');
      if (k === 'y') return this.history('redo');
      // While drawing, the last click goes (the feature before it stays).
      if (!e.shiftKey && this.store.view.draft.length) return this.store.setView({ draft: this.store.view.draft.slice(0, -1) });
      this.history(e.shiftKey ? 'redo' : 'undo');
      return;
    }
    // (Ctrl+Shift with these letters stays the browser's: bookmarks, the inspector.)
    const plain = ctrl && !e.shiftKey;
    if (plain && k === 's') return handled(), void this.save();
    if (plain && k === 'o') return handled(), this.els.fileInput.click();
    if (plain && k === 'c') return handled(), this.copyKeys();
    if (plain && k === 'v') return handled(), this.pasteKeys();
    if (ctrl || e.altKey) return;
    const tool = TOOLS.find((t) => t.key === k);
    if (tool && !e.shiftKey) return handled(), this.setTool(tool.tool);
    switch (k) {
      case 'r': return handled(), this.setMode('rest');
      case 'e': return handled(), this.setMode('pose');
      case 'Tab': return handled(), this.setMode(this.store.view.mode === 'rest' ? 'pose' : 'rest');
      case 'Enter': return handled(), void this.finishDraft(false);
      case 'Escape':
        handled();
        if (!this.els.help.hidden) return this.toggleHelp();
        if (this.exportStop) return this.cancelExport();
        if (this.endLayerMove()) return;
        if (this.store.view.draft.length) return this.store.cancelDraft();
        return this.store.setView({ selection: { feature: null, point: null }, pointSelection: [] });
      case 'Delete': case 'Backspace':
        handled();
        if (this.store.inGesture) return this.message('Deleting waits for the drag to end.', 'info');
        // While drawing, the last click goes (as Ctrl+Z takes it), never a finished feature.
        if (this.store.view.draft.length) return this.store.setView({ draft: this.store.view.draft.slice(0, -1) });
        try {
          this.store.deleteSelection();
        } catch (err) {
          this.message((err as Error).message, 'error');
        }
        return;
      case 'k': return handled(), e.shiftKey ? this.unkeyHere() : this.keyHere();
      // Space plays on release, unless it was held to pan (Space-drag).
      case ' ': handled(); this.spaceDown = true; return;
      case '0': return handled(), this.zoomFit();
      case '1': return handled(), this.zoom100();
      case 'ArrowLeft': return handled(), e.shiftKey ? this.stepKey(-1) : this.stepFrame(-1);
      case 'ArrowRight': return handled(), e.shiftKey ? this.stepKey(1) : this.stepFrame(1);
      case 'Home': return handled(), this.setTime(0);
      case 'End': return handled(), this.setTime((frameCount(this.store.doc) - 1) / this.store.doc.fps);
      case 'd': return handled(), this.setOverlay({ drawing: !this.store.view.overlays.drawing });
      case 'h': {
        handled();
        const order = ['off', 'dx', 'dy'] as const;
        return this.setOverlay({ heat: order[(order.indexOf(this.store.view.overlays.heat) + 1) % 3] });
      }
      case 'm': return handled(), this.setOverlay({ mesh: !this.store.view.overlays.mesh });
      case 'o': return handled(), this.store.setView({ onion: !this.store.view.onion });
      case 't': return handled(), this.setOverlay({ matte: !this.store.view.overlays.matte });
      case '?': return handled(), this.toggleHelp();
    }
  }

  // -- Files -------------------------------------------------------------------------------

  /** Opens a scene document: checks it, loads it, reports problems with their JSON path. */
  async openScene(doc: SceneDoc, name: string, validate = true, opened: Opened = {}): Promise<void> {
    if (validate) await this.throwProblems(doc);
    this.app.resetStats();
    this.store.load(doc, { ...downloadOrigin(name), ...opened.origin });
    this.keptCopies.clear();
    // At once, not after the wait below: the page takes edits meanwhile.
    if (opened.first) this.store.startHistory();
    if (opened.unsaved) this.store.markUnsaved();
    this.store.setView({ activeLayer: Math.max(0, doc.layers.length - 1) });
    await this.app.idle();
  }

  /**
   * Opens scene JSON text: the engine validates it (every message with its JSON path, as
   * `inkwarp validate` prints them), then the editor fills in the defaults it shows.
   */
  async openSceneText(text: string, name: string, opened: Opened = {}): Promise<void> {
    let raw: unknown;
    try {
      raw = JSON.parse(text);
    } catch (err) {
      throw new SceneFileError(`This is not a JSON file (${(err as Error).message}).`);
    }
    // Messages name the pictures `inkwarp edit` inlined by their files.
    if (opened.files) {
      const { layers } = raw as SceneDoc;
      nameFiles(Object.entries(opened.files).map(([at, file]) => {
        const [i, key] = at.split('.');
        return [layers[Number(i)][key as PictureKey]!, file];
      }));
    }
    await this.throwProblems(raw, true);
    const doc = parseScene(text);
    if (!doc.width || !doc.height) {
      const first = doc.layers.find((l) => l.image);
      const img = first?.image ? await decodeImage(first.image) : null;
      doc.width ||= img?.width ?? 1;
      doc.height ||= img?.height ?? 1;
    }
    await this.openScene(doc, name, false, opened);
  }

  /**
   * Throws `doc`'s problems, if any. `byFile`: a picture is named by its file (else its
   * layer), not by the data: URI it is held as (kept work, restored, names its own).
   */
  private async throwProblems(doc: unknown, byFile = false): Promise<void> {
    const name = (layer: Layer, key: PictureKey) => pictureName(layer.name, key, fileOf(layer[key]!));
    const problems = (await this.app.checkScene(doc)).map((p) => (byFile ? { ...p, message: withPictureNamed(doc, p.path, p.message, name) } : p));
    if (problems.length) {
      const [first] = problems;
      // Every problem, one a line, so that one round of fixes is enough.
      const more = problems.length > 1 ? `\n${problems.slice(1).map((p) => `${p.path ? `at ${p.path}: ` : ''}${p.message}`).join('\n')}` : '';
      // A browser cannot read files next to the scene: say how to open such a scene.
      const hint = problems.some((p) => /only use data: URIs/.test(p.message))
        ? ' — its images are files next to it: open it with `inkwarp edit SCENE`, which reads them.'
        : '';
      throw new SceneFileError(`${first.message}${more}${hint}`, first.path);
    }
  }

  /**
   * Whether opening `what` over the scene may go ahead: asks first when the scene has
   * changes that are not in a file (Undo also brings the scene back after opening).
   */
  confirmReplace(what: string): boolean {
    if (!this.store.unsaved) return true;
    return window.confirm(`Open ${what} instead of the scene you are editing? Its changes are not saved to a file (Undo, Ctrl+Z, brings it back).`);
  }

  async openFile(file: File, dropped = false): Promise<void> {
    try {
      const json = file.name.toLowerCase().endsWith('.json') || file.type === 'application/json';
      if (json && !this.confirmReplace(file.name)) return;
      if (json) {
        await this.openSceneText(await file.text(), file.name);
        this.message(`Opened ${file.name}.`, 'info');
        return;
      }
      if (isPsdName(file.name)) {
        await this.openPsd(file);
        return;
      }
      const uri = await fileToDataUri(file);
      const img = await decodeBlob(file, file.name);
      rememberImage(uri, img);
      if (dropped && this.store.doc.layers.length && img.width === this.store.doc.width && img.height === this.store.doc.height) {
        this.addLayerImage(uri, file.name);
        return;
      }
      if (!this.confirmReplace(file.name)) return;
      await this.openScene(this.sceneFromImage(uri, img, file.name), file.name.replace(/\.[^.]*$/, '') + '.json');
      this.message(`Opened ${file.name} (${img.width}×${img.height}). Pick a tool and trace.`, 'info');
    } catch (err) {
      // Open… reads layered PSDs too, which a picture's own message does not name.
      const psd = err instanceof Error && !isPsdName(file.name) && /PNG (or|and) JPEG/.test(err.message) ? ' (Open… also reads a layered PSD)' : '';
      this.fileError(file.name, err, psd);
    }
  }

  /** What opening the last PSD noted (flattened groups, blend modes), for the page and its tests. */
  psdNotes: string[] = [];

  /**
   * Opens a layered PSD as `inkwarp new` does: a layer per pixel layer, bottom first, each a
   * canvas-sized PNG at offset [0, 0]; groups flattened; opacity and masks in alpha.
   */
  async openPsd(file: File): Promise<void> {
    const picture = readLayeredPsd(await file.arrayBuffer(), file.name);
    if (!this.confirmReplace(file.name)) return;
    const doc = emptyScene(picture.width, picture.height);
    doc.background = [255, 255, 255, 0];
    const names = uniqueNames(picture.layers.map((l) => l.name));
    for (const [i, layer] of picture.layers.entries()) {
      const image = await blobToDataUri(await rgbaToPngBlob(layer.image));
      doc.layers.push(layer.visible ? { name: names[i], image } : { name: names[i], image, visible: false });
    }
    await this.openScene(doc, file.name.replace(/\.[^.]*$/, '') + '.json');
    this.psdNotes = picture.notes;
    for (const note of picture.notes) console.warn(note);
    const warned = picture.notes.filter((n) => /blend mode/.test(n));
    const summary = `Opened ${file.name} (${picture.width}×${picture.height}, ${picture.layers.length} layer${picture.layers.length === 1 ? '' : 's'}).`;
    this.message(warned.length ? `${summary} ${warned.join(' ')}` : `${summary} Pick a tool and trace.`, 'info');
  }

  fileError(name: string, err: unknown, more = ''): void {
    if (err instanceof SceneFileError) {
      this.message(`${name}: ${err.path ? `at ${err.path}: ` : ''}${err.message.slice(err.path ? err.path.length + 2 : 0)}${more}`, 'error');
    } else {
      // A message that names the file already is not prefixed with it again.
      const text = err instanceof Error ? err.message : String(err);
      this.message(`${text.startsWith(`${name}: `) ? text : `${name}: ${text}`}${more}`, 'error');
    }
  }

  /** Sets the scene's `solver.grid_step` (a whole number of pixels, 1 or more). */
  setGridStep(step: number): void {
    if (!Number.isInteger(step) || step < 1 || step > 64) {
      this.message(`The grid step is a whole number of pixels from 1 to 64, not ${step}.`, 'error');
      // The field shows the scene's step again (it keeps its own while focused).
      (this.els.gridStep as HTMLInputElement).value = String(this.store.doc.solver?.grid_step ?? 1);
      return;
    }
    this.tryEdit((d) => {
      const solver = { ...(d.solver ?? {}) };
      if (step === 1) delete solver.grid_step;
      else solver.grid_step = step;
      return { ...d, solver };
    });
  }

  sceneFromImage(uri: string, img: Rgba, name: string): SceneDoc {
    const doc = emptyScene(img.width, img.height);
    // A large picture is edited through a proxy scaled down by a factor (see `proxy.ts`),
    // and solved at full resolution on a grid of the same step, so that the frame that
    // replaces the proxy takes about as long to solve as the proxy and `inkwarp render`
    // draws the same frames (the step is saved in the scene).
    const f = proxyFactor(img.width, img.height);
    if (f > 1) doc.solver = { ...(doc.solver ?? {}), grid_step: f };
    // A photograph's edge stays put: the drawing never pulls the background into view.
    doc.layers.push({ name: name.replace(/\.[^.]*$/, '') || 'picture', image: uri, border: 'hold' });
    return doc;
  }

  private async addLayerFile(file: File): Promise<void> {
    try {
      const img = await decodeBlob(file, file.name);
      const uri = await fileToDataUri(file);
      if (this.store.doc.layers.length === 0) {
        await this.openScene(this.sceneFromImage(uri, img, file.name), 'scene.json');
        return;
      }
      const { width, height } = this.store.doc;
      if (img.width !== width || img.height !== height) {
        await this.addPlacedLayer(img, file.name);
        return;
      }
      this.addLayerImage(uri, file.name);
    } catch (err) {
      this.fileError(file.name, err);
    }
  }

  /**
   * Adds a picture of another size than the scene's as a layer placed by its offset: the
   * scene format's layer images have the scene's size (as `inkwarp render` reads them),
   * so the picture is stored on a transparent canvas of that size, top-left, and the
   * layer's offset puts it where it goes (centred to start with; a picture larger than the
   * scene is cropped to it, with a message). Transparent pixels are holes in the layer's
   * surface (continuity from alpha), so the padding neither draws nor bends.
   */
  async addPlacedLayer(img: Rgba, fileName: string, offset?: Pt): Promise<void> {
    const { width, height } = this.store.doc;
    const c = new OffscreenCanvas(width, height);
    const w = Math.min(width, img.width);
    const hgt = Math.min(height, img.height);
    const crop = new Uint8ClampedArray(4 * w * hgt);
    for (let y = 0; y < hgt; y++) crop.set(img.data.subarray(4 * y * img.width, 4 * (y * img.width + w)), 4 * y * w);
    c.getContext('2d')!.putImageData(new ImageData(crop, w, hgt), 0, 0);
    const uri = await blobToDataUri(await c.convertToBlob({ type: 'image/png' }));
    const at: Pt = offset ?? [Math.round((width - w) / 2), Math.round((height - hgt) / 2)];
    this.addLayerImage(uri, fileName, at[0] === 0 && at[1] === 0 ? undefined : at);
    const cropped = img.width > width || img.height > height;
    this.message(
      cropped
        ? `${fileName} (${img.width}×${img.height}) is larger than the scene (${width}×${height}): it was cropped to ${w}×${hgt}; scale it down first to keep all of it.`
        : `Added ${fileName} (${img.width}×${img.height}) at offset [${at[0]}, ${at[1]}]: set the offset in the layer panel, or Move and drag it.`,
      cropped ? 'error' : 'info',
    );
  }

  private addLayerImage(uri: string, fileName: string, offset?: Pt): void {
    const base = fileName.replace(/\.[^.]*$/, '') || 'layer';
    const names = new Set(this.store.doc.layers.map((l) => l.name));
    let name = base;
    for (let n = 2; names.has(name); n++) name = `${base}${n}`;
    this.tryEdit((d) => ({ ...d, layers: [...d.layers, offset ? { name, image: uri, offset } : { name, image: uri }] }));
    this.store.setView({ activeLayer: this.store.doc.layers.length - 1 });
  }

  private async setMatteFile(file: File): Promise<void> {
    try {
      const img = await decodeBlob(file, file.name);
      const { width, height } = this.store.doc;
      if (img.width !== width || img.height !== height) {
        throw new Error(`The matte ${file.name} is ${img.width}×${img.height}; it must be ${width}×${height} like the scene.`);
      }
      const uri = await fileToDataUri(file);
      const i = this.store.view.activeLayer;
      this.tryEdit((d) => updateLayer(d, i, { continuity: uri }));
      this.setOverlay({ matte: true });
    } catch (err) {
      this.fileError(file.name, err);
      this.showLayerAgain();
    }
  }

  /** The layer panel rebuilt from the scene (a dropdown left on a choice that did not happen). */
  private showLayerAgain(): void {
    this.layersShown = null;
    this.refresh(false);
  }

  async openExample(name: string): Promise<void> {
    const entry = this.examples.find((e) => e.name === name) ?? BUILTIN;
    if (!this.confirmReplace(`the example “${entry.title}”`)) return;
    try {
      let doc: SceneDoc;
      if (entry.url === null) doc = await builtinScene();
      else {
        await this.openSceneText(await (await fetch(entry.url)).text(), `${entry.name}.json`);
        return;
      }
      await this.openScene(doc, `${entry.name}.json`);
    } catch (err) {
      this.fileError(entry.title, err);
    }
  }

  /** When the page was last asked to be left (`performance.now()`), and whether it is going. */
  private leaving = { askedAt: -Infinity, gone: false };

  /**
   * Saves the scene where it came from: a scene `inkwarp edit` serves goes back to its
   * file, unless the file changed since it was read (another tab or program: the user
   * chooses whether to overwrite it); any other scene downloads. A save that could not
   * write the file leaves the work unsaved (the browser keeps its copy) and downloads a
   * copy (not one cut off by leaving the page, which may have written it).
   */
  save(): Promise<void> {
    // A feature being drawn (points clicked, Enter not yet pressed) is finished first, as
    // picking another tool does: a save never leaves it out without a word. One that cannot
    // be finished (too few points) stays drawn, and the save says it is not in the file.
    const drawn = this.store.view.draft.length;
    const why = drawn ? this.finishDraft(false) : null;
    const left = why === null ? '' : ` The ${this.store.view.tool} being drawn (${drawn} point${drawn > 1 ? 's' : ''}) is not in it: ${why.replace(/\.$/, '')}.`;
    this.saving = this.saving.catch(() => {}).then(() => this.saveNow(left));
    return this.saving;
  }

  /**
   * Asks `inkwarp edit` for the version of the file the scene saves to. One another tab or
   * program wrote since this tab read or saved it marks the scene unsaved (the file no longer
   * holds it: closing the tab asks, Save asks before overwriting), said once where the scene
   * had counted as saved. Quiet where nothing answers (no server, an older one, a stale link).
   * Queued with the saves, so a save in flight is never taken for another writer's.
   */
  checkFile(): Promise<void> {
    // One at a time: a server that hangs does not pile them up.
    if (this.checking) return this.saving;
    this.checking = true;
    this.saving = this.saving.catch(() => {}).then(() => this.checkFileNow()).catch(() => {}).finally(() => { this.checking = false; });
    return this.saving;
  }

  private checking = false;

  /**
   * The pictures the scene file `inkwarp edit` served names, by their paths: their stamps
   * when this tab opened it and the layer each is of (for `checkFile`, which tells a retouch).
   */
  private pictures = { path: null as string | null, stamps: new Map<string, { stamp: string; of: string }>() };

  /** Watches the pictures an opened scene file names (`stamps` by path, `files` by place: `{"0.image": "cat.png"}`). */
  watchPictures(stamps: Record<string, string>, files: Record<string, string>): void {
    this.pictures = { path: this.store.origin.path, stamps: new Map() };
    for (const [place, ref] of Object.entries(files)) {
      const [i, key] = place.split('.');
      const of = `layer '${this.store.doc.layers[Number(i)]?.name ?? i}'${key === 'image' ? '' : ` (its ${key})`}`;
      if (typeof stamps[ref] === 'string' && !this.pictures.stamps.has(ref)) this.pictures.stamps.set(ref, { stamp: stamps[ref], of });
    }
  }

  private async checkFileNow(): Promise<void> {
    const { origin } = this.store;
    if (!origin.saveUrl) return;
    const url = new URL(origin.saveUrl, location.href);
    url.pathname = `${url.pathname.replace(/\/$/, '')}/version`;
    const resp = await fetch(url, { cache: 'no-store' });
    // Only the file this tab opened (a server restarted on the port may serve another).
    const path = resp.headers.get('X-Inkwarp-Path');
    if ((resp.status !== 200 && resp.status !== 422) || path === null || decodeURIComponent(path) !== origin.path) return;
    const version = resp.status === 200 ? resp.headers.get('ETag') : null;
    if (this.store.origin !== origin) return;
    const said: string[] = [];
    const where = origin.path ?? origin.fileName;
    if (this.store.fileChanged(version)) {
      said.push(version === null
        ? `${where} can no longer be read (deleted, moved, or being written by another program?): the scene here is marked unsaved (●), as the file no longer holds it. Save asks before writing it there.`
        : `${where} was changed by another tab or program since this tab saved or opened it: the scene here is marked unsaved (●), as the file no longer holds it. Save asks before writing over it; open the file again to see what was written.`);
    }
    // Pictures another program retouched: told once for each change.
    const stamps = JSON.parse(decodeURIComponent(resp.headers.get('X-Inkwarp-Stamps') ?? '%7B%7D')) as Record<string, string>;
    const retouched = this.pictures.path === origin.path ? [...this.pictures.stamps].filter(([ref, p]) => typeof stamps[ref] === 'string' && stamps[ref] !== p.stamp) : [];
    for (const [ref, p] of retouched) p.stamp = stamps[ref];
    if (retouched.length) {
      const named = retouched.map(([ref, p]) => `${ref} of ${p.of}`).join(', ');
      const one = retouched.length === 1;
      said.push(`${named} ${one ? 'was' : 'were'} changed or removed on disk since this tab opened ${one ? 'it' : 'them'}: the editor shows ${one ? 'it' : 'them'} as ${one ? 'it was' : 'they were'} then, while the scene names the file${one ? '' : 's'}, so inkwarp render draws ${one ? 'it' : 'them'} as ${one ? 'it is' : 'they are'} now. Reload the page to see ${one ? 'it' : 'them'} (unsaved changes are kept and offered back).`);
    }
    if (said.length) this.message(said.join(' '), 'error');
  }

  /** Saves the scene (see `save`); `note` is added to what the save says. */
  private async saveNow(note = ''): Promise<void> {
    const { origin, revision } = this.store;
    const text = serializeScene(this.store.doc);
    const blob = () => new Blob([text], { type: 'application/json' });
    if (origin.saveUrl) {
      const where = origin.path ?? origin.fileName;
      let stale = false;
      try {
        // The file this tab opened goes with the save: a server restarted on the same port
        // with another scene refuses it instead of taking this scene into that file.
        const copies = this.store.doc.layers.flatMap((l, i) => PICTURE_KEYS
          .filter((k) => this.keptCopies.has(pictureSlot(l.name, k)) && l[k]?.startsWith('data:')).map((k) => `${i}.${k}`));
        const put = (version: string | null) => fetch(origin.saveUrl as string, {
          method: 'PUT', body: text, headers: {
            'Content-Type': 'application/json', ...(version ? { 'If-Match': version } : {}),
            ...(origin.path ? { 'X-Inkwarp-Scene': encodeURIComponent(origin.path) } : {}),
            ...(copies.length ? { 'X-Inkwarp-Kept-Copies': copies.join(',') } : {}),
          },
        });
        let resp = await put(origin.version);
        if (resp.status === 409) {
          const why = await resp.text();
          if (!window.confirm(`${why}.\n\nOverwrite it with the scene as the editor shows it? Cancel keeps your changes here, unsaved: open the file again to see what was written.`)) {
            this.message(`Not saved: ${why}; your changes are kept here, unsaved.`, 'error');
            return;
          }
          resp = await put('*');
        }
        if (resp.status === 403) stale = true; // a restarted `inkwarp edit` has another token
        if (!resp.ok) throw new Error(await resp.text());
        this.store.fileSaved(origin, resp.headers.get('ETag'), revision);
        const saved = resp.headers.get('X-Inkwarp-Path');
        const said = resp.headers.get('X-Inkwarp-Note');
        this.keptCopies.clear(); // written beside their files: the scene names them now
        this.message(`Saved to ${saved === null ? where : decodeURIComponent(saved)}${said ? `; ${decodeURIComponent(said)}` : ''}.${note}`, note ? 'error' : 'info');
      } catch (err) {
        // A request cut off by leaving the page (a reload or a closed tab right after
        // Ctrl+S) may well have written the file: no copy is downloaded as the page goes (the
        // next page shows the file, and offers the kept work only where the file lacks it).
        // A page that stays (its "Leave site?" answered Cancel) goes on as below.
        if (err instanceof TypeError && performance.now() - this.leaving.askedAt < 5000) {
          await new Promise((r) => setTimeout(r, 1000));
          if (this.leaving.gone) return;
        }
        download(blob(), origin.fileName);
        // The page a restarted server opens offers this tab's kept changes once this tab is closed.
        const next = stale ? ' To save into the file, close this tab, then open (or reload) the URL the running inkwarp edit printed: it offers these changes.' : '';
        this.message(`Could not save to ${where} (${(err as Error).message}). Your changes are kept in this browser, unsaved; a copy was downloaded as ${origin.fileName}.${next}${note}`, 'error');
      }
      return;
    }
    // The page cannot see whether the browser kept the download (a cancelled "Save as"
    // keeps nothing): the work stays unsaved, kept in this browser and asked about on leaving.
    download(blob(), origin.fileName);
    const kept = this.store.unsaved ? '; it stays marked unsaved (●) here, as the editor cannot see whether your browser kept it' : '';
    this.message(`Downloaded ${origin.fileName}${kept}. This scene is in no file the editor writes to (a scene file opened with inkwarp edit SCENE saves in place).${note}`, note ? 'error' : 'info');
  }

  /**
   * Offers the scene kept from an earlier visit ("Restore the scene you were editing at
   * 14:32?"); resolves true when the user restores it.
   */
  offerRestore(question: string): Promise<boolean> {
    return new Promise((resolve) => {
      const close = (answer: boolean) => {
        box.remove();
        resolve(answer);
      };
      const box = h('div#restore.restore', { role: 'dialog' },
        h('span', {}, question),
        h('button#restore-yes', { onclick: () => close(true) }, 'Restore'),
        h('button#restore-no', { onclick: () => close(false) }, 'Discard'),
      );
      document.body.append(box);
    });
  }

  /**
   * Work kept in the browser that could not be opened (`why`): says so, and that it is still
   * kept, with a button that downloads it as it was kept, a scene file to mend by hand and
   * open. The box stays until closed.
   */
  offerUnopened(why: string, doc: SceneDoc, fileName: string): void {
    document.querySelector('#unopened')?.remove();
    const name = fileName.replace(/(\.json)?$/i, '-kept.json');
    const box = h('div#unopened.restore.unopened', { role: 'alertdialog' },
      h('span', {}, why),
      h('button#unopened-download', { onclick: () => download(new Blob([serializeScene(doc)], { type: 'application/json' }), name) }, `Download ${name}`),
      h('button#unopened-close', { onclick: () => box.remove() }, 'Close'),
    );
    document.body.append(box);
  }

  private baseName(): string {
    return this.fileName.replace(/\.json$/, '');
  }

  async exportPng(): Promise<void> {
    // A frame played on a software GPU is drawn as a draft: stop, so the frame at rest is drawn in full.
    if (this.store.view.playing) this.store.setView({ playing: false });
    await this.app.idle();
    const { width, height } = this.store.doc;
    // A large picture's frame is the full-resolution one (its proxy's is smaller).
    // (The frame on screen may be a view of it: the whole frame is drawn for the file.)
    const shown = this.app.proxy > 1 ? this.app.fullShown : null;
    const full = shown && shown.view ? await this.app.wholeFrame() : shown;
    if (this.app.proxy > 1 && !full) return this.message('The full-resolution frame is not ready: try again when the picture has settled.', 'error');
    if (!full) this.app.renderNow(false);
    const blob = await rgbaToPngBlob({ width, height, data: full ? full.pixels : this.app.gl.readPixels() });
    download(blob, `${this.baseName()}-${Math.round(this.store.view.time * this.store.doc.fps)}.png`);
  }

  /**
   * Exports the animation as WebM: every frame solved at full resolution and encoded with
   * the timestamp `i / fps`, so the video plays at the scene's speed however long each
   * frame took to solve. Resolves to the file (also downloaded).
   */
  async exportWebm(): Promise<Blob | null> {
    if (!canEncodeWebm()) {
      this.message('This browser cannot encode video (no WebCodecs VideoEncoder); render with `inkwarp render scene.json -o out.mp4` instead.', 'error');
      return null;
    }
    if (this.exportStop) return null;
    const doc = this.store.doc;
    const wasMode = this.store.view.mode;
    const wasTime = this.store.view.time;
    const n = frameCount(doc);
    const stop = (this.exportStop = new AbortController());
    const button = this.els.exportWebm as HTMLButtonElement;
    [button.textContent, button.title] = ['Cancel', 'Stop the WebM export (Escape); nothing is downloaded'];
    let done = 0;
    let clear = false; // whether a frame had transparent pixels (drawn over white)
    this.app.exporting = true;
    this.store.setView({ mode: 'pose', playing: false });
    this.message(`Exporting ${n} frames… (Escape cancels)`, 'info');
    try {
      // A large picture's video is drawn at its proxy's size (see `proxy.ts`).
      const { width, height } = this.app.frameSize;
      const blob = await encodeWebm(width, height, doc.fps, n, async (i) => {
        this.store.setView({ time: i / doc.fps });
        await this.app.idle();
        this.app.renderNow(false);
        const pixels = this.app.gl.readPixels();
        clear = overWhite(pixels) || clear;
        return pixels;
      }, (i) => {
        done = i + 1;
        if (i % 12 === 11) this.message(`Exported ${i + 1} of ${n} frames… (Escape cancels)`, 'info');
      }, stop.signal);
      download(blob, `${this.baseName()}.webm`);
      const size = this.app.proxy > 1 ? ` at the preview's ${width}×${height}; \`inkwarp render scene.json -o out.mp4\` renders ${doc.width}×${doc.height}` : '';
      const white = clear ? '; its transparent areas are white, as a WebM made in the browser keeps no alpha (`inkwarp render scene.json -o out.webm` keeps it)' : '';
      this.message(`Exported ${n} frames as WebM (${(n / doc.fps).toFixed(2)} s at ${doc.fps} fps${size})${white}.`, 'info');
      return blob;
    } catch (err) {
      if (stop.signal.aborted) this.message(`WebM export cancelled after ${done} of ${n} frames; nothing was saved.`, 'info');
      else this.message(`The WebM export failed: ${(err as Error).message}`, 'error');
      return null;
    } finally {
      this.exportStop = null;
      [button.textContent, button.title] = ['WebM', WEBM_TITLE];
      this.app.exporting = false;
      this.store.setView({ mode: wasMode, time: wasTime });
    }
  }

  /** Stops a WebM export in progress (its button, or Escape): nothing is downloaded. */
  cancelExport(): void {
    this.exportStop?.abort(new DOMException('The export was cancelled.', 'AbortError'));
  }

  /** Names of the layers' features (for tests). */
  layerFeatureIds(i: number): string[] {
    const l = this.store.doc.layers[i];
    return l ? layerFeatures(this.store.doc, l).map((f) => f.id) : [];
  }
}

/** Whether `p` is inside the closed polygon `poly` (even-odd rule). */
export function insidePolygon(p: Pt, poly: Pt[]): boolean {
  let inside = false;
  for (let i = 0, j = poly.length - 1; i < poly.length; j = i++) {
    const [xi, yi] = poly[i];
    const [xj, yj] = poly[j];
    if (yi > p[1] !== yj > p[1] && p[0] < ((xj - xi) * (p[1] - yi)) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

function segDist(p: Pt, a: Pt, b: Pt): number {
  const dx = b[0] - a[0];
  const dy = b[1] - a[1];
  const len2 = dx * dx + dy * dy;
  const s = len2 === 0 ? 0 : Math.max(0, Math.min(1, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2));
  return Math.hypot(p[0] - a[0] - s * dx, p[1] - a[1] - s * dy);
}

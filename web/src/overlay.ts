// The 2D overlay over the picture: the drawing, the draft, the ΔX/ΔY heat map, the mesh
// wireframe and the continuity matte. Scene coordinates: pixel centres at integers.

import type { Engine } from './engine';
import type { LayerRuntime } from './app';
import { type Feature, type Pt, isClosed } from './scene';
import type { Store } from './state';
import { neighbourKeys, shownPoints } from './state';

const KIND_COLOURS: Record<string, string> = {
  point: '#ff3d7f',
  polyline: '#00b3ff',
  spline: '#ffb000',
  region: '#35d07f',
  cut: '#ff2a2a',
};

export class Overlay {
  private ctx: CanvasRenderingContext2D;
  private curveCache = new Map<string, Pt[]>();
  private heatCanvas: OffscreenCanvas | null = null;
  /** The pointer's scene position (for the draft's rubber band). */
  hover: Pt | null = null;

  constructor(
    readonly canvas: HTMLCanvasElement,
    private engine: Engine,
  ) {
    this.ctx = canvas.getContext('2d')!;
  }

  /** Scene px → overlay canvas px. */
  get scale(): number {
    return this.canvas.width / this.sceneWidth;
  }
  sceneWidth = 1;
  /** The marquee being dragged (scene pixels, two corners), drawn over the drawing. */
  marquee: [Pt, Pt] | null = null;

  toCanvas(p: Pt): Pt {
    const s = this.scale;
    return [(p[0] + 0.5) * s, (p[1] + 0.5) * s];
  }

  /** The dense curve through a feature's points (cached; the engine's own curves). */
  curve(f: Feature, pts: Pt[]): Pt[] {
    if (f.kind === 'point') return pts;
    const closed = isClosed(f);
    const spline = f.kind === 'spline' || (f.kind === 'region' && f.curve === 'spline');
    if (!spline) return closed ? [...pts, pts[0]] : pts;
    const key = JSON.stringify([f.kind, closed, pts]);
    let c = this.curveCache.get(key);
    if (!c) {
      try {
        c = this.engine.curve('spline', pts, closed, false, 2);
      } catch {
        c = pts;
      }
      if (this.curveCache.size > 500) this.curveCache.clear();
      this.curveCache.set(key, c);
    }
    return c;
  }

  private proxy = 1;
  /** Where the active layer's pixel (0, 0) is drawn, on the overlay canvas (its offset). */
  private shift: [number, number] = [0, 0];

  /**
   * Draws the overlays; `proxy` is the factor a large picture's layers are scaled down by
   * (their matte, links and field are the proxy's: see `proxy.ts`); the drawing is posed at
   * `time` (the scene's time unless given).
   */
  draw(store: Store, rt: LayerRuntime | undefined, sceneWidth: number, sceneHeight: number, proxy = 1, time = store.view.time): void {
    this.sceneWidth = sceneWidth;
    this.proxy = proxy;
    const pw = Math.ceil(sceneWidth / proxy), ph = Math.ceil(sceneHeight / proxy);
    const { ctx, canvas } = this;
    const view = store.view;
    // Playing shows the pose in either mode, the picture and the drawing alike.
    const mode = view.playing ? 'pose' : view.mode;
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    const s = this.scale;
    // The active layer's matte, field and mesh are in its own pixels: placed by its offset,
    // as the frame draws it (the drawing is in the frame's).
    const o = store.doc.layers[view.activeLayer]?.offset ?? [0, 0];
    this.shift = [o[0] * s, o[1] * s];
    if (rt && view.overlays.matte && rt.matte) this.drawMatte(rt, pw, ph, mode === 'pose');
    if (rt && view.overlays.heat !== 'off' && rt.field) this.drawHeat(rt, view.overlays.heat, pw, ph);
    if (rt && view.overlays.mesh && rt.links) {
      ctx.save();
      ctx.translate(...this.shift);
      this.drawMesh(rt, pw, ph);
      ctx.restore();
    }
    if (!view.overlays.drawing) return;
    const posed = mode === 'pose';
    for (const f of store.doc.features) {
      const selected = f.id === view.selection.feature;
      if (posed && f.kind !== 'cut') this.drawFeature(f, f.rest, s, false, true);
      if (posed && selected && view.onion && f.kind !== 'cut') {
        // Onion skin: where the feature was at its previous key (red) and will be at its next (green).
        const { prev, next } = neighbourKeys(f, time);
        if (prev) this.drawFeature(f, prev.points, s, false, true, '#ff5a5a');
        if (next) this.drawFeature(f, next.points, s, false, true, '#5aff7a');
      }
      const pts = shownPoints(f, mode, time);
      this.drawFeature(f, pts, s, selected, false);
      if (posed && f.keys?.some((k) => Math.abs(k.t - time) < 1e-4)) {
        const [x, y] = this.toCanvas(pts[0]);
        ctx.fillStyle = '#fff';
        ctx.strokeStyle = '#000';
        ctx.lineWidth = 1;
        ctx.beginPath();
        ctx.moveTo(x, y - 14);
        ctx.lineTo(x + 5, y - 9);
        ctx.lineTo(x, y - 4);
        ctx.lineTo(x - 5, y - 9);
        ctx.closePath();
        ctx.fill();
        ctx.stroke();
      }
    }
    // The picked control points (a marquee, Shift-click): a white ring each.
    for (const r of view.pointSelection) {
      const f = store.doc.features.find((g) => g.id === r.feature);
      const q = f && shownPoints(f, mode, time)[r.point];
      if (!q) continue;
      const [x, y] = this.toCanvas(q);
      ctx.lineWidth = 3;
      ctx.strokeStyle = '#000';
      ctx.beginPath();
      ctx.arc(x, y, 8, 0, Math.PI * 2);
      ctx.stroke();
      ctx.lineWidth = 1.5;
      ctx.strokeStyle = '#fff';
      ctx.stroke();
    }
    if (this.marquee) {
      const [a, b] = this.marquee.map((q) => this.toCanvas(q));
      ctx.fillStyle = 'rgba(255, 200, 60, 0.12)';
      ctx.fillRect(Math.min(a[0], b[0]), Math.min(a[1], b[1]), Math.abs(a[0] - b[0]), Math.abs(a[1] - b[1]));
      ctx.strokeStyle = '#ffc83c';
      ctx.lineWidth = 1;
      ctx.setLineDash([5, 3]);
      ctx.strokeRect(Math.min(a[0], b[0]) + 0.5, Math.min(a[1], b[1]) + 0.5, Math.abs(a[0] - b[0]), Math.abs(a[1] - b[1]));
      ctx.setLineDash([]);
    }
    if (view.draft.length) {
      ctx.strokeStyle = KIND_COLOURS[view.tool] ?? '#fff';
      ctx.setLineDash([6, 4]);
      ctx.lineWidth = 2;
      ctx.beginPath();
      const pts = this.hover ? [...view.draft, this.hover] : view.draft;
      pts.forEach((p, i) => {
        const [x, y] = this.toCanvas(p);
        if (i === 0) ctx.moveTo(x, y);
        else ctx.lineTo(x, y);
      });
      ctx.stroke();
      ctx.setLineDash([]);
      for (const p of view.draft) this.handle(p, '#fff', 4);
    }
  }

  private handle(p: Pt, colour: string, r: number): void {
    const [x, y] = this.toCanvas(p);
    const { ctx } = this;
    ctx.fillStyle = colour;
    ctx.strokeStyle = '#000';
    ctx.lineWidth = 1.5;
    ctx.fillRect(x - r, y - r, 2 * r, 2 * r);
    ctx.strokeRect(x - r, y - r, 2 * r, 2 * r);
  }

  private drawFeature(f: Feature, pts: Pt[], _s: number, selected: boolean, ghost: boolean, tint?: string): void {
    const { ctx } = this;
    const colour = tint ?? KIND_COLOURS[f.kind];
    ctx.save();
    if (ghost) {
      ctx.globalAlpha = 0.35;
      ctx.setLineDash([4, 4]);
    }
    if (f.kind === 'point') {
      const [x, y] = this.toCanvas(pts[0]);
      ctx.strokeStyle = '#000';
      ctx.fillStyle = colour;
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      ctx.arc(x, y, selected ? 7 : 5, 0, Math.PI * 2);
      if (!ghost) ctx.fill();
      ctx.stroke();
      ctx.restore();
      return;
    }
    const line = this.curve(f, pts).map((p) => this.toCanvas(p));
    ctx.beginPath();
    line.forEach(([x, y], i) => (i === 0 ? ctx.moveTo(x, y) : ctx.lineTo(x, y)));
    if (f.kind === 'region' && !ghost) {
      ctx.fillStyle = colour + '33';
      ctx.fill();
    }
    ctx.lineWidth = selected ? 4 : 2.5;
    ctx.strokeStyle = '#000';
    ctx.stroke();
    ctx.lineWidth = selected ? 2.5 : 1.5;
    ctx.strokeStyle = colour;
    if (f.kind === 'cut' && !ghost) ctx.setLineDash([7, 4]);
    ctx.stroke();
    ctx.setLineDash([]);
    if (!ghost) {
      const sel = selected ? 5 : 3.5;
      pts.forEach((p) => this.handle(p, selected ? '#fff' : colour, sel));
    }
    ctx.restore();
  }

  private drawHeat(rt: LayerRuntime, which: 'dx' | 'dy', w: number, h: number): void {
    const f = rt.field!;
    const v = which === 'dx' ? f.dx : f.dy;
    let max = 1e-6;
    for (let i = 0; i < v.length; i++) max = Math.max(max, Math.abs(v[i]));
    if (!this.heatCanvas || this.heatCanvas.width !== w || this.heatCanvas.height !== h) this.heatCanvas = new OffscreenCanvas(w, h);
    const img = new ImageData(w, h);
    for (let i = 0; i < v.length; i++) {
      const s = v[i] / max; // −1 … 1: blue … white … red
      const a = Math.abs(s);
      const [r, g, b] = s >= 0 ? [255, 255 * (1 - a), 255 * (1 - a)] : [255 * (1 - a), 255 * (1 - a), 255];
      const active = rt.matte ? rt.matte[i] : 1;
      img.data[4 * i] = r;
      img.data[4 * i + 1] = g;
      img.data[4 * i + 2] = b;
      img.data[4 * i + 3] = active ? 190 : 0;
    }
    this.heatCanvas.getContext('2d')!.putImageData(img, 0, 0);
    this.ctx.imageSmoothingEnabled = false;
    this.ctx.drawImage(this.heatCanvas, ...this.shift, this.canvas.width, this.canvas.height);
    // The scale, as a legend.
    const y0 = this.canvas.height - 26;
    this.ctx.fillStyle = 'rgba(0,0,0,0.7)';
    this.ctx.fillRect(4, y0, 200, 22);
    this.ctx.fillStyle = '#fff';
    this.ctx.font = '13px sans-serif';
    this.ctx.fillText(`${which === 'dx' ? 'ΔX' : 'ΔY'}: ±${max.toFixed(1)} px (blue − / red +)`, 9, y0 + 16);
  }

  /** The last posed matte drawn, kept while its field and matte are the same. */
  private posedMatte: { field: unknown; matte: Uint8Array; canvas: OffscreenCanvas } | null = null;

  /**
   * The continuity matte's holes in magenta: at rest, or in pose mode where the layer's field
   * leaves them, as the picture is drawn (holes open and move with the surface around them).
   */
  private drawMatte(rt: LayerRuntime, w: number, h: number, posed: boolean): void {
    const m = rt.matte!;
    const f = posed && rt.field && rt.field.width === w && rt.field.height === h ? rt.field : null;
    let c: OffscreenCanvas;
    if (f && this.posedMatte?.field === f && this.posedMatte.matte === m) c = this.posedMatte.canvas;
    else {
      c = new OffscreenCanvas(w, h);
      const img = new ImageData(w, h);
      const mark = (i: number) => {
        img.data[4 * i] = 255;
        img.data[4 * i + 1] = 0;
        img.data[4 * i + 2] = 160;
        img.data[4 * i + 3] = 110;
      };
      if (!f) {
        for (let i = 0; i < m.length; i++) if (!m[i]) mark(i);
      } else {
        // Posed, a hole is where no connected pixel lands: everything starts as a hole and
        // each connected pixel's cell (reaching half-way to the neighbours it is linked to,
        // half a pixel where it is not) clears the pixels whose centres fall inside it, at
        // the place the field takes it. The field is only solved on connected pixels.
        for (let i = 0; i < m.length; i++) mark(i);
        const links = rt.links;
        const linked = (i: number, j: number, bit: number): boolean => (links ? (links[i] & bit) !== 0 : m[j] !== 0);
        for (let y = 0; y < h; y++) {
          for (let x = 0; x < w; x++) {
            const i = y * w + x;
            if (!m[i]) continue;
            const px = x + f.dx[i], py = y + f.dy[i];
            let x0 = px - 0.5, x1 = px + 0.5, y0 = py - 0.5, y1 = py + 0.5;
            const reach = (j: number) => {
              const qx = (px + (j % w) + f.dx[j]) / 2, qy = (py + Math.floor(j / w) + f.dy[j]) / 2;
              x0 = Math.min(x0, qx);
              x1 = Math.max(x1, qx);
              y0 = Math.min(y0, qy);
              y1 = Math.max(y1, qy);
            };
            if (x + 1 < w && linked(i, i + 1, 2)) reach(i + 1);
            if (x > 0 && linked(i - 1, i - 1, 2)) reach(i - 1);
            if (y + 1 < h && linked(i, i + w, 4)) reach(i + w);
            if (y > 0 && linked(i - w, i - w, 4)) reach(i - w);
            for (let yy = Math.max(0, Math.ceil(y0 - 1e-6)); yy <= Math.min(h - 1, Math.floor(y1 + 1e-6)); yy++) {
              for (let xx = Math.max(0, Math.ceil(x0 - 1e-6)); xx <= Math.min(w - 1, Math.floor(x1 + 1e-6)); xx++) img.data[4 * (yy * w + xx) + 3] = 0;
            }
            // A whole block (four links) is a quad of the surface, stretched or turned: the
            // centres inside its two triangles are covered too (the cells alone left dots
            // at the middle of stretched, turned blocks).
            if (x + 1 < w && y + 1 < h && linked(i, i + 1, 2) && linked(i, i + w, 4) && linked(i + w, i + w + 1, 2) && linked(i + 1, i + w + 1, 4)) {
              const at = (j: number): [number, number] => [(j % w) + f.dx[j], Math.floor(j / w) + f.dy[j]];
              const [a, b, c, d] = [at(i), at(i + 1), at(i + w + 1), at(i + w)];
              clearTriangle(img.data, w, h, a, b, c);
              clearTriangle(img.data, w, h, a, c, d);
            }
          }
        }
      }
      c.getContext('2d')!.putImageData(img, 0, 0);
      if (f) this.posedMatte = { field: f, matte: m, canvas: c };
    }
    this.ctx.imageSmoothingEnabled = false;
    this.ctx.drawImage(c, ...this.shift, this.canvas.width, this.canvas.height);
  }

  private drawMesh(rt: LayerRuntime, w: number, h: number): void {
    const { ctx } = this;
    const f = rt.field;
    const links = rt.links!;
    const step = Math.max(4, Math.round(Math.max(w, h) / 48));
    // Proxy pixels to scene pixels (see `toProxy`).
    const k = this.proxy, c = (k - 1) / 2;
    const pos = (x: number, y: number): Pt => {
      const i = y * w + x;
      const [px, py] = f ? [x + f.dx[i], y + f.dy[i]] : [x, y];
      return this.toCanvas([px * k + c, py * k + c]);
    };
    ctx.strokeStyle = 'rgba(20, 20, 20, 0.55)';
    ctx.lineWidth = 1;
    ctx.beginPath();
    // Lines along rows and columns, broken where a link is missing.
    for (let y = 0; y < h; y += step) {
      ctx.moveTo(...pos(0, y));
      for (let x = 0; x + 1 < w; x++) {
        if (links[y * w + x] & 2) ctx.lineTo(...pos(x + 1, y));
        else ctx.moveTo(...pos(x + 1, y));
      }
    }
    for (let x = 0; x < w; x += step) {
      ctx.moveTo(...pos(x, 0));
      for (let y = 0; y + 1 < h; y++) {
        if (links[y * w + x] & 4) ctx.lineTo(...pos(x, y + 1));
        else ctx.moveTo(...pos(x, y + 1));
      }
    }
    ctx.stroke();
  }
}

/** Clears the overlay's alpha at the pixel centres inside (or on) the triangle `a b c`. */
function clearTriangle(data: Uint8ClampedArray, w: number, h: number, a: [number, number], b: [number, number], c: [number, number]): void {
  const area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
  if (!(Math.abs(area) > 1e-12)) return;
  const s = Math.sign(area);
  const edge = (p: [number, number], q: [number, number], x: number, y: number) => s * ((q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0]));
  const x0 = Math.max(0, Math.ceil(Math.min(a[0], b[0], c[0]) - 1e-6)), x1 = Math.min(w - 1, Math.floor(Math.max(a[0], b[0], c[0]) + 1e-6));
  const y0 = Math.max(0, Math.ceil(Math.min(a[1], b[1], c[1]) - 1e-6)), y1 = Math.min(h - 1, Math.floor(Math.max(a[1], b[1], c[1]) + 1e-6));
  for (let y = y0; y <= y1; y++) {
    for (let x = x0; x <= x1; x++) {
      if (edge(a, b, x, y) >= -1e-9 && edge(b, c, x, y) >= -1e-9 && edge(c, a, x, y) >= -1e-9) data[4 * (y * w + x) + 3] = 0;
    }
  }
}

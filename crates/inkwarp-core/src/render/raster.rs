//! The band rasteriser: canvas rows are cut into bands drawn in parallel; each band visits
//! every element that reaches it, in the global drawing order, so the result does not
//! depend on the banding or the number of threads.
//!
//! Per band and element:
//! - pixel centres inside the element (non-zero winding of its outline, top-left rule:
//!   an edge owns the centres with `y_lo ≤ Y < y_hi`, a span owns `x_left ≤ X < x_right`)
//!   get the element's colour at their preimage, priority 0, "over" what an earlier
//!   element put there (the last element is in front);
//! - edges of the element that are not cancelled by a neighbour of the same orientation
//!   (the outline of a piece, and fold lines) are accumulated as signed areas, whose
//!   running sum along a row is the coverage;
//! - elements with such edges also offer their colour to nearby centres outside them,
//!   ranked by the rest-space distance of the preimage (nearest wins).

use super::mesh::{
    cross, mid, quarter_corners, shade, shading_mask, sub, Layer, Plan, Rgba, ANY, BOTTOM, CHUNK,
    COMPLETE, LEFT, RIGHT, SIMPLE, TOP, V2,
};
use super::{unpremultiply, Canvas, RgbaImage};
use crate::{Field, Grid};
use rayon::prelude::*;
use std::cell::RefCell;

/// Canvas rows per band.
const BAND_ROWS: usize = 32;

/// How each edge of a skirt quarter meets its neighbours, per corner `k`, for the edges
/// top-left→top-right, top-right→bottom-right, bottom-right→bottom-left,
/// bottom-left→top-left of the quarter.
#[derive(Clone, Copy)]
enum EdgeKind {
    /// On the block's top or bottom side: the same pixel's element in the block above or below.
    HBlock,
    /// On the block's left or right side: the same pixel's element in the block beside.
    VBlock,
    /// Inside the block, towards the corner in the same row (a neighbour only if linked).
    HInner,
    /// Inside the block, towards the corner in the same column (a neighbour only if linked).
    VInner,
}

use EdgeKind::*;

const QUARTER_EDGES: [[EdgeKind; 4]; 4] = [
    [HBlock, HInner, VInner, VBlock],
    [HBlock, VBlock, VInner, HInner],
    [VInner, HInner, HBlock, VBlock],
    [VInner, VBlock, HBlock, HInner],
];

pub(super) fn draw_layer(canvas: &mut Canvas, image: &RgbaImage, field: &Field, grid: &Grid, offset: [f64; 2]) {
    let cw = canvas.width;
    if image.width == 0 || image.height == 0 || cw == 0 || canvas.height == 0 { return; }
    let layer = Layer::prepare(image, field.dx.clone(), field.dy.clone(), grid, offset);
    let layers = [(&layer, &layer.plan())];
    let bands = canvas.data.par_chunks_mut(BAND_ROWS * cw).enumerate();
    bands.for_each(|(band, dst)| draw_band(&layers, cw, band * BAND_ROWS, dst));
}

/// Composites `layers` (the empty ones left out) over `dst`, the canvas rows from `y0`
/// on (`width` pixels a row), in this thread's band buffers.
fn draw_band(layers: &[(&Layer<'_>, &Plan)], width: usize, y0: usize, dst: &mut [Rgba]) {
    SCRATCH.with(|scratch| {
        let mut b = scratch.borrow_mut();
        for (layer, plan) in layers.iter().filter(|(l, _)| l.w > 0 && l.h > 0) {
            b.reset(width, y0, dst.len() / width);
            b.render(layer, plan);
            b.composite(dst);
        }
    })
}

/// Draws `layers` back to front over `background` (premultiplied) into the canvas rows
/// from `y0` on that `out` holds (straight RGBA8, `width` pixels a row), band by band:
/// each band is composited in a reused buffer of its own and written out as RGBA8, so no
/// canvas of the whole frame is ever held. Each pixel goes through the same operations as
/// [`draw_layer`] on a [`Canvas`] then [`Canvas::to_rgba8`], so the bytes are the same.
pub(super) fn draw_frame(width: usize, background: Rgba, layers: &[(&Layer<'_>, &Plan)], y0: usize, out: &mut [u8]) {
    if width == 0 { return; }
    out.par_chunks_mut(4 * BAND_ROWS * width).enumerate().for_each(|(band, out)| {
        FRAME_BAND.with(|frame| {
            let mut dst = frame.borrow_mut();
            dst.clear();
            dst.resize(out.len() / 4, background);
            draw_band(layers, width, y0 + band * BAND_ROWS, &mut dst);
            out.chunks_exact_mut(4).zip(dst.iter()).for_each(|(o, &p)| o.copy_from_slice(&unpremultiply(p)));
        })
    });
}

thread_local! {
    /// Each worker thread reuses its band buffers from one layer to the next.
    static SCRATCH: RefCell<Band> = RefCell::new(Band::default());
    /// Each worker thread's band of the frame being composited (see [`draw_frame`]).
    static FRAME_BAND: RefCell<Vec<Rgba>> = const { RefCell::new(Vec::new()) };
}

/// Bounding box of some points.
#[derive(Clone, Copy)]
struct Bbox {
    x0: f32,
    x1: f32,
    y0: f32,
    y1: f32,
}

/// The smaller and the larger of two finite values (plain comparisons: `f32::min` would
/// pay for NaN).
#[inline]
fn lo(a: f32, b: f32) -> f32 { if b < a { b } else { a } }
#[inline]
fn hi(a: f32, b: f32) -> f32 { if b > a { b } else { a } }

#[inline]
fn bbox(points: &[V2; 4]) -> Bbox {
    let [a, b, c, d] = *points;
    Bbox {
        x0: lo(lo(a[0], b[0]), lo(c[0], d[0])),
        x1: hi(hi(a[0], b[0]), hi(c[0], d[0])),
        y0: lo(lo(a[1], b[1]), lo(c[1], d[1])),
        y1: hi(hi(a[1], b[1]), hi(c[1], d[1])),
    }
}

/// Whether the element of corner `k` in block `(bc, br)` is flipped.
#[inline]
fn flipped_at(plan: &Plan, w: usize, bc: usize, br: usize, k: usize) -> bool {
    let byte = plan.signs[br * (w + 1) + bc];
    let bit = if byte & COMPLETE != 0 { 0 } else { k };
    byte >> bit & 1 != 0
}

/// An element being drawn: its bilinear corners, its rest square inside its block, and
/// its shading.
struct Element {
    q: [V2; 4],
    u0: f32,
    v0: f32,
    size: f32,
    col: [Rgba; 4],
    mask: u8,
    own: usize,
}

impl Element {
    #[inline]
    fn colour(&self, s: f32, t: f32) -> Rgba {
        let u = (self.u0 + s * self.size).clamp(0.0, 1.0);
        let v = (self.v0 + t * self.size).clamp(0.0, 1.0);
        shade(&self.col, self.mask, self.own, u, v)
    }
}

/// The bilinear map of a quadrilateral `q` (corners top-left, top-right, bottom-right,
/// bottom-left of its rest square): `p = q0 + s·e + t·f + s·t·g`, `(s, t) ∈ [0, 1]²`.
struct Bilinear {
    q0: V2,
    e: V2,
    f: V2,
    g: V2,
    /// `cross(e, f)` and `cross(g, f)`, the constant parts of the quadratic in `t`.
    kef: f32,
    k2: f32,
    /// `1 / cross(e, f)` when the quad is a parallelogram (`g` negligible): the inverse
    /// is then affine. Zero otherwise.
    affine_inv: f32,
}

impl Bilinear {
    #[inline]
    fn new(q: &[V2; 4]) -> Bilinear {
        let e = sub(q[1], q[0]);
        let f = sub(q[3], q[0]);
        let g = [q[0][0] - q[1][0] + q[2][0] - q[3][0], q[0][1] - q[1][1] + q[2][1] - q[3][1]];
        let kef = cross(e, f);
        // Dropping `s·t·g` moves the preimage by about |g| / 4 of the quad's size: below
        // 1e-4 here, far below a level of colour.
        let scale = e[0].abs() + e[1].abs() + f[0].abs() + f[1].abs();
        let parallelogram = g[0].abs() + g[1].abs() <= 2e-4 * scale && kef != 0.0;
        let affine_inv = if parallelogram { 1.0 / kef } else { 0.0 };
        Bilinear { q0: q[0], e, f, g, kef, k2: cross(g, f), affine_inv }
    }

    /// The preimage of a point inside the quad, clamped to the unit square.
    #[inline]
    fn preimage_inside(&self, p: V2) -> Option<[f32; 2]> {
        if self.affine_inv != 0.0 {
            let h = sub(p, self.q0);
            let s = cross(h, self.f) * self.affine_inv;
            let t = cross(self.e, h) * self.affine_inv;
            return Some([s.clamp(0.0, 1.0), t.clamp(0.0, 1.0)]);
        }
        self.preimage(p).map(|([s, t], _)| [s.clamp(0.0, 1.0), t.clamp(0.0, 1.0)])
    }

    /// The preimage `(s, t)` of `p` nearest to the unit square (within a small
    /// tolerance), the larger `t` on a tie, with its squared distance from the unit square.
    #[inline]
    fn preimage(&self, p: V2) -> Option<([f32; 2], f32)> {
        const TOL: f32 = 1e-4;
        let outside = |v: f32, tol: f32| (-v - tol).max(v - 1.0 - tol).max(0.0);
        let distance = |s: f32, t: f32, tol: f32| outside(s, tol).powi(2) + outside(t, tol).powi(2);
        let Bilinear { e, f, g, k2, .. } = *self;
        let h = sub(p, self.q0);
        if self.affine_inv != 0.0 {
            let s = cross(h, f) * self.affine_inv;
            let t = cross(e, h) * self.affine_inv;
            return Some(([s, t], distance(s, t, 0.0)));
        }
        let k1 = self.kef + cross(h, g);
        let k0 = cross(h, e);
        let w = (k1 * k1 - 4.0 * k0 * k2).max(0.0).sqrt();
        // The numerically stable pair of roots: k0 / m and m / k2.
        let m = -0.5 * (k1 + w.copysign(k1));
        let solve_s = |t: f32| {
            let (dx, dy) = (e[0] + g[0] * t, e[1] + g[1] * t);
            if dx.abs() >= dy.abs() { (h[0] - f[0] * t) / dx } else { (h[1] - f[1] * t) / dy }
        };
        let mut best: Option<([f32; 2], f32)> = None;
        for t in [(m != 0.0).then(|| k0 / m), (k2 != 0.0).then(|| m / k2)].into_iter().flatten() {
            let s = solve_s(t);
            let d = distance(s, t, TOL);
            if s.is_finite() && t.is_finite() && best.map_or(true, |(r, bd)| d < bd || (d == bd && t > r[1])) {
                best = Some(([s, t], d));
            }
        }
        best.map(|([s, t], _)| ([s, t], distance(s, t, 0.0)))
    }
}

/// `⌈x⌉` as a float, without a libm call (baseline x86-64 has no rounding instruction)
/// and without branches. Only meaningful for |x| < 2²²; larger values are clamped there,
/// far outside any canvas.
#[inline]
fn ceil_f(x: f32) -> f32 {
    // Adding and removing 1.5·2²³ rounds to the nearest integer.
    const MAGIC: f32 = 12_582_912.0;
    let x = x.clamp(-4_194_304.0, 4_194_304.0);
    let r = (x + MAGIC) - MAGIC;
    r + f32::from(u8::from(r < x))
}

/// `⌈x⌉` (NaN gives 0).
#[inline]
fn ceil_i(x: f32) -> i64 { ceil_f(x) as i64 }

/// `⌊x⌋` without a libm call.
#[inline]
fn floor_i(x: f32) -> i64 { -ceil_i(-x) }

/// Where the edge between `a` and `b` crosses the scanline `y`, if it does: the edge owns
/// the scanlines with `lo.y ≤ y < hi.y` (`lo` its end with the smaller `y`), and the
/// crossing is computed from `(lo, hi)` alone, so every element beside an edge gets the
/// same value bit for bit. Returns `(x, direction)`, direction +1 where `a → b` runs
/// towards larger `y`.
#[inline]
fn crossing(a: V2, b: V2, y: f32) -> Option<(f32, i32)> {
    let (lo, hi, dir) = if a[1] < b[1] { (a, b, 1) } else { (b, a, -1) };
    (lo[1] <= y && y < hi[1]).then(|| (lo[0] + (y - lo[1]) * ((hi[0] - lo[0]) / (hi[1] - lo[1])), dir))
}

#[derive(Default)]
struct Band {
    cw: usize,
    y0: usize,
    rows: usize,
    /// Candidate colour per pixel, and its priority (0 = centre inside an element, higher
    /// for colours offered from outside, see [`Band::offer`]); the colour is meaningful
    /// only where the priority is finite.
    col: Vec<Rgba>,
    prio: Vec<f32>,
    /// Signed-area accumulator, `rows × stride`; the running row sum is the coverage.
    acc: Vec<f32>,
    stride: usize,
    /// Premultiplied colours of two picture rows, one per parity of the row, filled
    /// [`PIECE`] pixels at a time as the runs of quads need them, so that a pixel is
    /// premultiplied once per band rather than once per quad it is a corner of.
    pm: [Vec<Rgba>; 2],
    /// Per piece of [`Band::pm`], the picture row it holds plus one (0: none).
    pm_row: [Vec<u32>; 2],
}

/// Pixels per piece of [`Band::pm`].
const PIECE: usize = 32;

impl Band {
    fn reset(&mut self, cw: usize, y0: usize, rows: usize) {
        self.cw = cw;
        self.y0 = y0;
        self.rows = rows;
        self.stride = cw + 2;
        self.col.resize(rows * cw, [0.0; 4]);
        self.prio.clear();
        self.prio.resize(rows * cw, f32::INFINITY);
        self.acc.clear();
        self.acc.resize(rows * self.stride, 0.0);
    }

    /// Forgets the premultiplied rows of the layer drawn before, and sizes them for `layer`.
    fn forget_rows(&mut self, layer: &Layer) {
        let pieces = layer.w.div_ceil(PIECE);
        for k in 0..2 {
            self.pm[k].resize(layer.w, [0.0; 4]);
            self.pm_row[k].clear();
            self.pm_row[k].resize(pieces, 0);
        }
    }

    /// Premultiplies pixels `x0 ..= x1` of picture row `y` into [`Band::pm`] where they
    /// are not there yet.
    #[inline]
    fn premultiply_row(&mut self, layer: &Layer, y: usize, x0: usize, x1: usize) {
        let slot = y & 1;
        let tag = y as u32 + 1;
        for piece in x0 / PIECE..=x1 / PIECE {
            if self.pm_row[slot][piece] != tag {
                self.pm_row[slot][piece] = tag;
                let (a, b) = (piece * PIECE, ((piece + 1) * PIECE).min(layer.w));
                for (x, c) in (a..b).zip(&mut self.pm[slot][a..b]) {
                    *c = layer.col(y * layer.w + x);
                }
            }
        }
    }

    /// Rows of element geometry that can touch this band: centres `y0 .. y0 + rows` and
    /// their unit squares.
    #[inline]
    fn y_window(&self) -> (f32, f32) { (self.y0 as f32 - 1.0, (self.y0 + self.rows) as f32) }

    #[inline]
    fn reaches(&self, b: Bbox) -> bool {
        let (lo, hi) = self.y_window();
        // Elements left of the canvas still matter: their edges add coverage to the row.
        b.y1 >= lo && b.y0 <= hi && b.x0 <= self.cw as f32
    }

    fn render(&mut self, layer: &Layer, plan: &Plan) {
        let (lo, hi) = self.y_window();
        let bw = layer.w + 1;
        self.forget_rows(layer);
        let misses = |[ymin, ymax]: [f32; 2]| ymax < lo || ymin > hi;
        for br in 0..=layer.h {
            if misses(plan.row_ranges[br]) || crate::interrupt::requested() {
                continue; // A stop requested mid-draw (Ctrl-C) skips the rest: the image is refused.
            }
            for ch in 0..plan.nchunks {
                if misses(plan.ranges[br * plan.nchunks + ch]) {
                    continue;
                }
                let row = &plan.signs[br * bw..(br + 1) * bw];
                let (mut bc, end) = (ch * CHUNK, ((ch + 1) * CHUNK).min(bw));
                while bc < end {
                    let byte = row[bc];
                    if byte & SIMPLE != 0 {
                        // A run of interior quads (so `br ≥ 1` and `bc ≥ 1`).
                        let run_end = (bc + 1..end).find(|&i| row[i] & SIMPLE == 0).unwrap_or(end);
                        self.simple_run(layer, br, bc, run_end);
                        bc = run_end;
                        continue;
                    } else if byte & COMPLETE != 0 {
                        self.quad(layer, plan, bc, br, byte);
                    } else if byte & ANY != 0 {
                        self.partial(layer, plan, bc, br);
                    }
                    bc += 1;
                }
            }
        }
    }

    /// Quads inside a piece and away from folds, blocks `bc0 .. bc1` of block row `br`:
    /// colour the centres inside them. On a quad's core scanlines (below both top
    /// corners, above both bottom corners) only its left and right edges cross, so its
    /// centres there are the span between the two crossings; the crossing of the edge two
    /// neighbours share is computed once. Quads with other scanlines take the general path.
    #[inline(never)]
    fn simple_run(&mut self, layer: &Layer, br: usize, bc0: usize, bc1: usize) {
        let w = layer.w;
        let (band_first, band_end) = (self.y0 as f32, (self.y0 + self.rows) as f32);
        // Pixels bc0 - 1 ..= bc1 - 1 of rows br - 1 and br are the quads' corners.
        let (x0, x1) = (bc0 - 1, bc1 - 1);
        self.premultiply_row(layer, br - 1, x0, x1);
        self.premultiply_row(layer, br, x0, x1);
        let (top, bottom) = ((br - 1) & 1, br & 1);
        let (above, below) = ((br - 1) * w, br * w);
        let (ax, ay) = (&layer.px[above + x0..=above + x1], &layer.py[above + x0..=above + x1]);
        let (bx, by) = (&layer.px[below + x0..=below + x1], &layer.py[below + x0..=below + x1]);
        // The left corners of each quad are the right corners of the one before, and so
        // are their ⌈y⌉ (⌈⌉ commutes with min and max, so the scanlines below are those
        // of the corners' extremes).
        let mut left = ([ax[0], ay[0]], [bx[0], by[0]], ceil_f(ay[0]), ceil_f(by[0]));
        // The crossing of the left edge of quad `x` on scanline `y`, when known.
        let mut shared: Option<(usize, f32, f32)> = None;
        for x in x0..x1 {
            let j = x - x0 + 1;
            let (tr, br) = ([ax[j], ay[j]], [bx[j], by[j]]);
            let (ctr, cbr) = (ceil_f(tr[1]), ceil_f(br[1]));
            let (tl, bl, ctl, cbl) = std::mem::replace(&mut left, (tr, br, ctr, cbr));
            let (c_min, c_max) = (lo(lo(ctl, ctr), lo(cbl, cbr)), hi(hi(ctl, ctr), hi(cbl, cbr)));
            // Scanlines c_min ≤ Y < c_max: none of them in the band.
            if c_max <= band_first || c_min >= band_end {
                continue;
            }
            let corners = [self.pm[top][x], self.pm[top][x + 1], self.pm[bottom][x], self.pm[bottom][x + 1]];
            let colour = |s, t| shade(&corners, 0b1111, 0, s, t);
            let (first, end) = (hi(ctl, ctr), lo(cbl, cbr));
            if first != c_min || end != c_max {
                let q = [tl, tr, br, bl];
                self.fill(&q, &q, bbox(&q), colour);
                continue;
            }
            let (first, end) = (first.max(band_first), end.min(band_end));
            if first >= end {
                continue;
            }
            let map = Bilinear::new(&[tl, tr, br, bl]);
            let mut y = first;
            while y < end {
                let left = match shared {
                    Some((sx, sy, cx)) if sx == x && sy == y => Some(cx),
                    _ => crossing(bl, tl, y).map(|c| c.0),
                };
                let right = crossing(tr, br, y).map(|c| c.0);
                if let (Some(xl), Some(xr)) = (left, right) {
                    shared = Some((x + 1, y, xr));
                    let (x_from, x_to) = if xl <= xr { (xl, xr) } else { (xr, xl) };
                    self.span(y as i64, x_from, x_to, &map, &colour);
                }
                y += 1.0;
            }
        }
    }

    /// A complete block: one bilinear quad.
    #[inline(never)]
    fn quad(&mut self, layer: &Layer, plan: &Plan, bc: usize, br: usize, byte: u8) {
        let w = layer.w;
        let i = (br - 1) * w + bc - 1;
        let q = [layer.pos(i), layer.pos(i + 1), layer.pos(i + w + 1), layer.pos(i + w)];
        let bb = bbox(&q);
        if !self.reaches(bb) {
            return;
        }
        let bw = w + 1;
        let bi = br * bw + bc;
        // Neighbouring blocks top, right, bottom, left, and which of their corners are
        // this side's first and second end.
        let signs = &plan.signs;
        let neighbours = [(signs[bi - bw], 2, 3), (signs[bi + 1], 0, 2), (signs[bi + bw], 1, 0), (signs[bi - 1], 3, 1)];
        let col = [layer.col(i), layer.col(i + 1), layer.col(i + w), layer.col(i + w + 1)];
        let flipped = byte & 1 != 0;
        let (mut outline, mut n) = ([[0.0f32; 2]; 8], 0);
        let (mut edges, mut ne) = ([([0.0f32; 2], [0.0f32; 2]); 8], 0);
        // A side is an edge where the element beside it is the other way round.
        let mut edge = |e, neighbour_flipped: bool| {
            if neighbour_flipped != flipped {
                edges[ne] = e;
                ne += 1;
            }
        };
        for (side, &(nbyte, ka, kb)) in neighbours.iter().enumerate() {
            let (a, z) = (q[side], q[(side + 1) % 4]);
            outline[n] = a;
            n += 1;
            if nbyte & COMPLETE != 0 {
                edge((a, z), nbyte & 1 != 0);
            } else {
                // The neighbour is split into quarters at the link's midpoint: split here
                // too, so that both sides rasterise the same segments.
                let m = mid(a, z);
                outline[n] = m;
                n += 1;
                edge((a, m), nbyte >> ka & 1 != 0);
                edge((m, z), nbyte >> kb & 1 != 0);
            }
        }
        let last = outline[n - 1];
        outline[n..].fill(last);
        let el = Element { q, u0: 0.0, v0: 0.0, size: 1.0, col, mask: 0b1111, own: 0 };
        self.element(&outline, &el, bb, &edges[..ne], flipped);
    }

    /// A block that is not a complete quad: one skirt quarter per drawn pixel.
    #[inline(never)]
    fn partial(&mut self, layer: &Layer, plan: &Plan, bc: usize, br: usize) {
        let b = layer.block(bc, br);
        let s = layer.skirts(&b);
        let w = layer.w;
        let byte = plan.signs[br * (w + 1) + bc];
        for k in (0..4).filter(|k| b.present >> k & 1 != 0) {
            let q = quarter_corners(&b, &s, k);
            let bb = bbox(&q);
            if !self.reaches(bb) {
                continue;
            }
            let flipped = byte >> k & 1 != 0;
            let (mut edges, mut ne) = ([([0.0f32; 2], [0.0f32; 2]); 4], 0);
            for (e, kind) in QUARTER_EDGES[k].iter().enumerate() {
                let neighbour_flipped = match kind {
                    HBlock => Some(flipped_at(plan, w, bc, if k < 2 { br - 1 } else { br + 1 }, k ^ 2)),
                    VBlock => Some(flipped_at(plan, w, if k & 1 == 0 { bc - 1 } else { bc + 1 }, br, k ^ 1)),
                    HInner => (b.links & if k < 2 { TOP } else { BOTTOM } != 0)
                        .then(|| byte >> (k ^ 1) & 1 != 0),
                    VInner => (b.links & if k & 1 == 0 { LEFT } else { RIGHT } != 0)
                        .then(|| byte >> (k ^ 2) & 1 != 0),
                };
                if neighbour_flipped != Some(flipped) {
                    edges[ne] = (q[e], q[(e + 1) % 4]);
                    ne += 1;
                }
            }
            let (u0, v0) = ((k & 1) as f32 * 0.5, (k >> 1) as f32 * 0.5);
            let el = Element { q, u0, v0, size: 0.5, col: b.col, mask: shading_mask(b.present, b.links, k), own: k };
            self.element(&q, &el, bb, &edges[..ne], flipped);
        }
    }

    /// Draws an element: colours the centres inside `outline` (see [`Band::fill`]) and,
    /// when it has `edges` (outline or fold lines, in the order of its rest square's
    /// corners), adds their coverage the element's way round and offers its colour to the
    /// centres around it.
    fn element<const N: usize>(&mut self, outline: &[V2; N], el: &Element, bb: Bbox, edges: &[(V2, V2)], flip: bool) {
        self.fill(outline, &el.q, bb, |s, t| el.colour(s, t));
        if !edges.is_empty() {
            for &(a, z) in edges {
                if flip { self.accumulate(z, a) } else { self.accumulate(a, z) }
            }
            self.offer(el, bb);
        }
    }

    /// Colours the pixel centres inside an element (bilinear corners `q`, `outline` the
    /// corners plus any link midpoints that split its sides): the centres of each scanline
    /// where the winding number of `outline` is not zero, counting the edges that cross
    /// the scanline at or left of the centre (see [`crossing`]). Every element beside an
    /// edge sees the same crossing, so every centre has exactly one owner.
    fn fill<const N: usize>(&mut self, outline: &[V2; N], q: &[V2; 4], bb: Bbox, colour: impl Fn(f32, f32) -> Rgba) {
        // Scanlines with y0 ≤ Y < y1.
        let ya = ceil_i(bb.y0).max(self.y0 as i64);
        let yb = (ceil_i(bb.y1) - 1).min((self.y0 + self.rows) as i64 - 1);
        if ya > yb || bb.x1 < 0.0 {
            return;
        }
        let map = Bilinear::new(q);
        for row in ya..yb + 1 {
            let y = row as f32;
            let mut xs = [(0.0f32, 0i32); N];
            let mut n = 0;
            for k in 0..N {
                if let Some(c) = crossing(outline[(k + N - 1) % N], outline[k], y) {
                    // Insertion sort by x.
                    let mut j = n;
                    while j > 0 && xs[j - 1].0 > c.0 {
                        xs[j] = xs[j - 1];
                        j -= 1;
                    }
                    xs[j] = c;
                    n += 1;
                }
            }
            let mut winding = 0;
            for k in 0..n.saturating_sub(1) {
                winding += xs[k].1;
                if winding != 0 {
                    self.span(row, xs[k].0, xs[k + 1].0, &map, &colour);
                }
            }
        }
    }

    /// Colours the centres `x_from ≤ X < x_to` of scanline `row`.
    #[inline(always)]
    fn span(&mut self, row: i64, x_from: f32, x_to: f32, map: &Bilinear, colour: &impl Fn(f32, f32) -> Rgba) {
        let start = ceil_i(x_from).max(0);
        let end = ceil_i(x_to).min(self.cw as i64);
        let line = (row as usize - self.y0) * self.cw;
        let y = row as f32;
        for x in start..end {
            if let Some([s, t]) = map.preimage_inside([x as f32, y]) {
                let (i, c) = (line + x as usize, colour(s, t));
                let d = self.col[i];
                self.col[i] = if self.prio[i] == 0.0 { [0, 1, 2, 3].map(|k| c[k] + d[k] * (1.0 - c[3])) } else { c };
                self.prio[i] = 0.0;
            }
        }
    }

    /// Offers the element's colour to the centres of the pixels whose unit square meets
    /// its bounding box, for those not inside any element: elements whose block holds the
    /// preimage of the centre first, then by the rest-space distance of the preimage from
    /// the element.
    fn offer(&mut self, el: &Element, bb: Bbox) {
        let map = Bilinear::new(&el.q);
        let xa = ceil_i(bb.x0 - 0.5).max(0);
        let xb = floor_i(bb.x1 + 0.5).min(self.cw as i64 - 1);
        let ya = ceil_i(bb.y0 - 0.5).max(self.y0 as i64);
        let yb = floor_i(bb.y1 + 0.5).min((self.y0 + self.rows) as i64 - 1);
        for row in ya..=yb {
            for x in xa..=xb {
                let Some(([s, t], d2)) = map.preimage([x as f32, row as f32]) else {
                    continue;
                };
                // Elements of the block that holds the preimage come first (for a
                // translation that block's renormalised bilinear is the box filter), then
                // the nearest in rest space.
                let (u, v) = (el.u0 + s * el.size, el.v0 + t * el.size);
                let in_block = (0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v);
                let prio = if in_block { 1.0 } else { 4.0 } + d2 * el.size * el.size;
                let i = (row as usize - self.y0) * self.cw + x as usize;
                if prio <= self.prio[i] {
                    self.prio[i] = prio;
                    self.col[i] = el.colour(s, t);
                }
            }
        }
    }

    /// Adds the signed area that the directed segment `a → z` (canvas pixel coordinates)
    /// sweeps to the right of itself, cell by cell (the cell of pixel `(x, y)` is
    /// `[x - ½, x + ½] × [y - ½, y + ½]`). Each row piece is computed from the whole
    /// segment in canvas coordinates, so the result does not depend on the banding.
    fn accumulate(&mut self, a: V2, z: V2) {
        let (ax, ay) = (a[0] as f64 + 0.5, a[1] as f64 + 0.5);
        let (zx, zy) = (z[0] as f64 + 0.5, z[1] as f64 + 0.5);
        if ay == zy {
            return;
        }
        let (dir, (x0, y0), (x1, y1)) = if ay < zy { (1.0, (ax, ay), (zx, zy)) } else { (-1.0, (zx, zy), (ax, ay)) };
        let dxdy = (x1 - x0) / (y1 - y0);
        let (top, bottom) = (self.y0 as f64, (self.y0 + self.rows) as f64);
        let (ys, ye) = (y0.max(top), y1.min(bottom));
        if ys >= ye {
            return;
        }
        let mut row = ys.floor();
        while row < ye {
            let ya = row.max(ys);
            let yb = (row + 1.0).min(ye);
            if ya < yb {
                let xa = x0 + (ya - y0) * dxdy;
                let xb = x0 + (yb - y0) * dxdy;
                let r = row as usize - self.y0;
                let line = &mut self.acc[r * self.stride..(r + 1) * self.stride];
                accumulate_row(line, self.cw, xa, xb, (yb - ya) * dir);
            }
            row += 1.0;
        }
    }

    /// Coverage from the running sums, then colour × coverage "over" the canvas.
    fn composite(&self, dst: &mut [Rgba]) {
        for r in 0..self.rows {
            let mut sum = 0.0f32;
            for x in 0..self.cw {
                sum += self.acc[r * self.stride + x];
                let i = r * self.cw + x;
                let coverage = sum.abs().min(1.0);
                if coverage > 0.0 && self.prio[i] < f32::INFINITY {
                    let c = self.col[i];
                    let keep = 1.0 - c[3] * coverage;
                    let d = &mut dst[i];
                    for ch in 0..4 {
                        d[ch] = c[ch] * coverage + d[ch] * keep;
                    }
                }
            }
        }
    }
}

/// One row's piece of a segment, from `xa` to `xb` (cell coordinates, pixel `x` is cell
/// `[x, x + 1]`), of signed height `d`: each cell gets the area of the piece's trapezoid
/// that lies within it and to its right, as a difference to the cell on its left.
fn accumulate_row(line: &mut [f32], cw: usize, xa: f64, xb: f64, d: f64) {
    let (lo, hi) = (xa.min(xb), xa.max(xb));
    let right = cw as f64;
    if lo >= right {
        return; // right of the canvas: covers no cell
    }
    if hi <= 0.0 {
        line[0] += d as f32; // left of the canvas: the whole row to the right
        return;
    }
    if lo == hi {
        let i = lo.floor();
        let f = lo - i;
        let i = i as usize;
        line[i] += (d * (1.0 - f)) as f32;
        line[i + 1] += (d * f) as f32;
        return;
    }
    let span = hi - lo;
    let mut x = lo;
    if x < 0.0 {
        line[0] += (d * -x / span) as f32;
        x = 0.0;
    }
    let end = hi.min(right);
    while x < end {
        let cell = x.floor();
        let next = (cell + 1.0).min(end);
        let part = d * (next - x) / span;
        let centre = 0.5 * (x + next) - cell;
        let i = cell as usize;
        line[i] += (part * (1.0 - centre)) as f32;
        line[i + 1] += (part * centre) as f32;
        x = next;
    }
}

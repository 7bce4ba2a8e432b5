//! The band rasteriser: canvas rows are cut into bands drawn in parallel; each band visits
//! every element that reaches it, in the global drawing order, so the result does not
//! depend on the banding or the number of threads.
//!
//! Per band and element:
//! - pixel centres inside the element (non-zero winding of its outline, top-left rule:
//!   an edge owns the centres with `y_lo ≤ Y < y_hi`, a span owns `x_left ≤ X < x_right`)
//!   get the element's colour at their preimage, priority 0 (the last element wins);
//! - edges of the element that are not cancelled by a neighbour of the same orientation
//!   (the outline of a piece, and fold lines) are accumulated as signed areas, whose
//!   running sum along a row is the coverage;
//! - elements with such edges also offer their colour to nearby centres outside them,
//!   ranked by the rest-space distance of the preimage (nearest wins).

use super::mesh::{
    cross, shading_mask, mid, quarter_corners, shade, sub, Layer, Plan, Rgba, V2, ANY, BOTTOM, CHUNK,
    COMPLETE, LEFT, RIGHT, TOP,
};
use super::{Canvas, RgbaImage};
use crate::{Field, Grid};
use rayon::prelude::*;

/// Canvas rows per band.
const BAND_ROWS: usize = 16;

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
    if image.width == 0 || image.height == 0 || cw == 0 || canvas.height == 0 {
        return;
    }
    let layer = Layer::prepare(image, field, grid, offset);
    let plan = layer.plan();
    canvas.data.par_chunks_mut(BAND_ROWS * cw).enumerate().for_each(|(band, dst)| {
        let mut b = Band::new(cw, band * BAND_ROWS, dst.len() / cw);
        b.render(&layer, &plan);
        b.composite(dst);
    });
}

/// Whether the element of corner `k` in block `(bc, br)` is flipped.
#[inline]
fn flipped_at(plan: &Plan, w: usize, bc: usize, br: usize, k: usize) -> bool {
    let byte = plan.signs[br * (w + 1) + bc];
    if byte & COMPLETE != 0 {
        byte & 1 != 0
    } else {
        byte >> k & 1 != 0
    }
}

/// The element being drawn: its outline (corners, plus link midpoints where a neighbour
/// splits a side), its bilinear corners, its rest square inside its block, and its shading.
struct Element<'a> {
    outline: &'a [V2],
    q: [V2; 4],
    u0: f32,
    v0: f32,
    size: f32,
    col: &'a [Rgba; 4],
    mask: u8,
    own: usize,
}

impl Element<'_> {
    #[inline]
    fn colour(&self, s: f32, t: f32) -> Rgba {
        let u = (self.u0 + s * self.size).clamp(0.0, 1.0);
        let v = (self.v0 + t * self.size).clamp(0.0, 1.0);
        shade(self.col, self.mask, self.own, u, v)
    }
}

/// Preimages `(s, t)` of `p` under the bilinear map of `q` (corners top-left, top-right,
/// bottom-right, bottom-left): `p = q0 + s·e + t·f + s·t·g`. Picks the root nearest to the
/// unit square (within a small tolerance), the larger `t` on a tie; returns it with its
/// squared distance from the unit square.
#[inline]
fn preimage(q: &[V2; 4], p: V2) -> Option<([f32; 2], f32)> {
    let e = sub(q[1], q[0]);
    let f = sub(q[3], q[0]);
    let g = [q[0][0] - q[1][0] + q[2][0] - q[3][0], q[0][1] - q[1][1] + q[2][1] - q[3][1]];
    let h = sub(p, q[0]);
    let k2 = cross(g, f);
    let k1 = cross(e, f) + cross(h, g);
    let k0 = cross(h, e);
    let w = (k1 * k1 - 4.0 * k0 * k2).max(0.0).sqrt();
    // The numerically stable pair of roots: k0 / m and m / k2.
    let m = -0.5 * (k1 + w.copysign(k1));
    let mut best: Option<([f32; 2], f32, f32)> = None;
    let mut consider = |t: f32| {
        if !t.is_finite() {
            return;
        }
        let dx = e[0] + g[0] * t;
        let dy = e[1] + g[1] * t;
        let s = if dx.abs() >= dy.abs() { (h[0] - f[0] * t) / dx } else { (h[1] - f[1] * t) / dy };
        if !s.is_finite() {
            return;
        }
        const TOL: f32 = 1e-4;
        let out = |v: f32| (-v - TOL).max(v - 1.0 - TOL).max(0.0);
        let d_tol = out(s).powi(2) + out(t).powi(2);
        let better = match best {
            None => true,
            Some((r, _, bd)) => d_tol < bd || (d_tol == bd && t > r[1]),
        };
        if better {
            let exact = |v: f32| (-v).max(v - 1.0).max(0.0);
            best = Some(([s, t], exact(s).powi(2) + exact(t).powi(2), d_tol));
        }
    };
    if m != 0.0 {
        consider(k0 / m);
    }
    if k2 != 0.0 {
        consider(m / k2);
    }
    best.map(|(r, d, _)| (r, d))
}

struct Band {
    cw: usize,
    y0: usize,
    rows: usize,
    /// Candidate colour per pixel, and its priority (0 = centre inside an element, higher
    /// for colours offered from outside, see [`Band::offer`]).
    col: Vec<Rgba>,
    prio: Vec<f32>,
    /// Signed-area accumulator, `rows × stride`; the running row sum is the coverage.
    acc: Vec<f32>,
    stride: usize,
}

impl Band {
    fn new(cw: usize, y0: usize, rows: usize) -> Band {
        let stride = cw + 2;
        Band {
            cw,
            y0,
            rows,
            col: vec![[0.0; 4]; rows * cw],
            prio: vec![f32::INFINITY; rows * cw],
            acc: vec![0.0; rows * stride],
            stride,
        }
    }

    /// Rows of element geometry that can touch this band: centres `y0 .. y0 + rows` and
    /// their unit squares.
    #[inline]
    fn y_window(&self) -> (f32, f32) {
        (self.y0 as f32 - 1.0, (self.y0 + self.rows) as f32)
    }

    #[inline]
    fn reaches(&self, q: &[V2]) -> bool {
        let (lo, hi) = self.y_window();
        let (mut x0, mut x1, mut y0, mut y1) = (f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY);
        for p in q {
            x0 = x0.min(p[0]);
            x1 = x1.max(p[0]);
            y0 = y0.min(p[1]);
            y1 = y1.max(p[1]);
        }
        // Elements left of the canvas still matter: their edges add coverage to the row.
        y1 >= lo && y0 <= hi && x0 <= self.cw as f32
    }

    fn render(&mut self, layer: &Layer, plan: &Plan) {
        let (lo, hi) = self.y_window();
        let bw = layer.w + 1;
        for br in 0..=layer.h {
            for ch in 0..plan.nchunks {
                let [ymin, ymax] = plan.ranges[br * plan.nchunks + ch];
                if ymax < lo || ymin > hi {
                    continue;
                }
                for bc in ch * CHUNK..((ch + 1) * CHUNK).min(bw) {
                    let byte = plan.signs[br * bw + bc];
                    if byte & COMPLETE != 0 {
                        self.quad(layer, plan, bc, br);
                    } else if byte & ANY != 0 {
                        self.partial(layer, plan, bc, br);
                    }
                }
            }
        }
    }

    /// A complete block: one bilinear quad.
    fn quad(&mut self, layer: &Layer, plan: &Plan, bc: usize, br: usize) {
        let b = layer.block(bc, br);
        let q = [b.p[0], b.p[1], b.p[3], b.p[2]];
        if !self.reaches(&q) {
            return;
        }
        let bw = layer.w + 1;
        let flipped = plan.signs[br * bw + bc] & 1 != 0;
        // Sides top, right, bottom, left: the neighbouring block, and which of its corners
        // are this side's first and second end.
        let sides = [
            (bc, br - 1, 2, 3),
            (bc + 1, br, 0, 2),
            (bc, br + 1, 1, 0),
            (bc - 1, br, 3, 1),
        ];
        let mut outline = [[0.0f32; 2]; 8];
        let mut n = 0;
        let mut edges = [([0.0f32; 2], [0.0f32; 2]); 8];
        let mut ne = 0;
        for (side, &(nc, nr, ka, kb)) in sides.iter().enumerate() {
            let (a, z) = (q[side], q[(side + 1) % 4]);
            outline[n] = a;
            n += 1;
            let nbyte = plan.signs[nr * bw + nc];
            if nbyte & COMPLETE != 0 {
                if (nbyte & 1 != 0) != flipped {
                    edges[ne] = (a, z);
                    ne += 1;
                }
            } else {
                // The neighbour is split into quarters at the link's midpoint: split here
                // too, so that both sides rasterise the same segments.
                let m = mid(a, z);
                outline[n] = m;
                n += 1;
                if (nbyte >> ka & 1 != 0) != flipped {
                    edges[ne] = (a, m);
                    ne += 1;
                }
                if (nbyte >> kb & 1 != 0) != flipped {
                    edges[ne] = (m, z);
                    ne += 1;
                }
            }
        }
        let el = Element { outline: &outline[..n], q, u0: 0.0, v0: 0.0, size: 1.0, col: &b.col, mask: 0b1111, own: 0 };
        self.fill(&el);
        if ne > 0 {
            for &(a, z) in &edges[..ne] {
                if flipped { self.accumulate(z, a) } else { self.accumulate(a, z) }
            }
            self.offer(&el);
        }
    }

    /// A block that is not a complete quad: one skirt quarter per drawn pixel.
    fn partial(&mut self, layer: &Layer, plan: &Plan, bc: usize, br: usize) {
        let b = layer.block(bc, br);
        let s = layer.skirts(&b);
        let w = layer.w;
        let byte = plan.signs[br * (w + 1) + bc];
        for k in 0..4 {
            if b.present >> k & 1 == 0 {
                continue;
            }
            let q = quarter_corners(&b, &s, k);
            if !self.reaches(&q) {
                continue;
            }
            let flipped = byte >> k & 1 != 0;
            let mut edges = [([0.0f32; 2], [0.0f32; 2]); 4];
            let mut ne = 0;
            for (e, kind) in QUARTER_EDGES[k].iter().enumerate() {
                let neighbour_flipped = match kind {
                    HBlock => Some(flipped_at(plan, w, bc, if k < 2 { br - 1 } else { br + 1 }, k ^ 2)),
                    VBlock => Some(flipped_at(plan, w, if k & 1 == 0 { bc - 1 } else { bc + 1 }, br, k ^ 1)),
                    HInner => (b.links & if k < 2 { TOP } else { BOTTOM } != 0).then(|| byte >> (k ^ 1) & 1 != 0),
                    VInner => (b.links & if k & 1 == 0 { LEFT } else { RIGHT } != 0).then(|| byte >> (k ^ 2) & 1 != 0),
                };
                if neighbour_flipped != Some(flipped) {
                    edges[ne] = (q[e], q[(e + 1) % 4]);
                    ne += 1;
                }
            }
            let el = Element {
                outline: &q,
                q,
                u0: (k & 1) as f32 * 0.5,
                v0: (k >> 1) as f32 * 0.5,
                size: 0.5,
                col: &b.col,
                mask: shading_mask(b.present, b.links, k),
                own: k,
            };
            self.fill(&el);
            if ne > 0 {
                for &(a, z) in &edges[..ne] {
                    if flipped { self.accumulate(z, a) } else { self.accumulate(a, z) }
                }
                self.offer(&el);
            }
        }
    }

    /// Colours the pixel centres inside the element (non-zero winding of its outline).
    fn fill(&mut self, el: &Element) {
        let outline = el.outline;
        let (mut ymin, mut ymax) = (f32::INFINITY, f32::NEG_INFINITY);
        for p in outline {
            ymin = ymin.min(p[1]);
            ymax = ymax.max(p[1]);
        }
        // Centre rows with ymin ≤ Y < ymax, inside the band.
        let first = (ymin.ceil().max(self.y0 as f32)) as i64;
        let last = (ymax.ceil() - 1.0).min((self.y0 + self.rows - 1) as f32) as i64;
        let cw = self.cw as i64;
        for row in first..=last {
            let y = row as f32;
            let mut xs = [(0.0f32, 0i32); 8];
            let mut n = 0;
            for i in 0..outline.len() {
                let (a, z) = (outline[i], outline[(i + 1) % outline.len()]);
                let (lo, hi, dir) = if a[1] < z[1] {
                    (a, z, 1)
                } else if z[1] < a[1] {
                    (z, a, -1)
                } else {
                    continue;
                };
                if lo[1] <= y && y < hi[1] {
                    let x = lo[0] + (y - lo[1]) * (hi[0] - lo[0]) / (hi[1] - lo[1]);
                    // Insertion sort by x.
                    let mut j = n;
                    while j > 0 && xs[j - 1].0 > x {
                        xs[j] = xs[j - 1];
                        j -= 1;
                    }
                    xs[j] = (x, dir);
                    n += 1;
                }
            }
            let mut winding = 0;
            for i in 0..n.saturating_sub(1) {
                winding += xs[i].1;
                if winding == 0 {
                    continue;
                }
                let start = (xs[i].0.ceil() as i64).max(0);
                let end = (xs[i + 1].0.ceil() as i64 - 1).min(cw - 1);
                for x in start..=end {
                    if let Some(([s, t], _)) = preimage(&el.q, [x as f32, y]) {
                        let i = (row as usize - self.y0) * self.cw + x as usize;
                        self.col[i] = el.colour(s.clamp(0.0, 1.0), t.clamp(0.0, 1.0));
                        self.prio[i] = 0.0;
                    }
                }
            }
        }
    }

    /// Offers the element's colour to the centres of the pixels whose unit square meets
    /// its bounding box, for those not inside any element: elements whose block holds the
    /// preimage of the centre first, then by the rest-space distance of the preimage from
    /// the element.
    fn offer(&mut self, el: &Element) {
        let (mut x0, mut x1, mut y0, mut y1) = (f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY);
        for p in &el.q {
            x0 = x0.min(p[0]);
            x1 = x1.max(p[0]);
            y0 = y0.min(p[1]);
            y1 = y1.max(p[1]);
        }
        let xa = ((x0 - 0.5).ceil() as i64).max(0);
        let xb = ((x1 + 0.5).floor() as i64).min(self.cw as i64 - 1);
        let ya = ((y0 - 0.5).ceil() as i64).max(self.y0 as i64);
        let yb = ((y1 + 0.5).floor() as i64).min((self.y0 + self.rows) as i64 - 1);
        for row in ya..=yb {
            for x in xa..=xb {
                let Some(([s, t], d2)) = preimage(&el.q, [x as f32, row as f32]) else {
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
        let top = self.y0 as f64;
        let bottom = (self.y0 + self.rows) as f64;
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

//! The layer's mesh: displaced pixel positions, the links that survive, and the elements
//! (quads and skirt quarters) of each block, with their orientation and extent.

use super::{premultiply, RgbaImage};
use crate::Grid;
use rayon::prelude::*;

pub(super) type V2 = [f32; 2];
pub(super) type Rgba = [f32; 4];

/// Per-pixel link bits of [`Layer::links`].
pub(super) const LINK_RIGHT: u8 = 1;
pub(super) const LINK_DOWN: u8 = 2;

/// Block link bits of [`Block::links`]: which sides of the block are links.
pub(super) const TOP: u8 = 1; // top-left – top-right
pub(super) const BOTTOM: u8 = 2; // bottom-left – bottom-right
pub(super) const LEFT: u8 = 4; // top-left – bottom-left
pub(super) const RIGHT: u8 = 8; // top-right – bottom-right
/// Each side's bit, the corners at its ends, and the first end's link to the other.
const SIDES: [(u8, u8, usize, u8); 4] =
    [(TOP, 0b0011, 0, LINK_RIGHT), (BOTTOM, 0b1100, 2, LINK_RIGHT), (LEFT, 0b0101, 0, LINK_DOWN), (RIGHT, 0b1010, 1, LINK_DOWN)];

/// Bits of a block's byte in [`Plan::signs`].
pub(super) const COMPLETE: u8 = 0x80; // the block is one quad; bit 0 = the quad is flipped
pub(super) const ANY: u8 = 0x40; // some pixel of the block is drawn; bit k = quarter k flipped
/// A complete block whose four neighbours are complete with the same orientation: none of
/// its edges is an outline or a fold line, so only its centres need colouring.
pub(super) const SIMPLE: u8 = 0x20;

/// Blocks per chunk of a block row in [`Plan::ranges`].
pub(super) const CHUNK: usize = 32;

/// The displacement across the picture's edge (px) over which an edge pixel's reach to the
/// frame's edge fades out (see [`Layer::skirts`]).
const EDGE_REST_PX: f32 = 0.5;

/// A layer ready to be drawn: canvas positions, links, and the picture its premultiplied
/// colours are read from (premultiplied as they are read, the runs of quads inside a piece
/// a picture row at a time into a small cache of each band: a 4000 × 3000 layer would
/// otherwise hold 192 MB of them).
pub(super) struct Layer<'a> {
    pub w: usize,
    pub h: usize,
    /// Canvas position of each pixel (x plane, y plane: the field's own planes, moved in
    /// and overwritten); NaN where the pixel is not drawn.
    pub px: Vec<f32>,
    pub py: Vec<f32>,
    /// The straight RGBA8 picture.
    pub rgba: &'a [u8],
    /// `LINK_RIGHT | LINK_DOWN` bits of the grid links whose two ends are drawn.
    pub links: Vec<u8>,
    /// The layer's offset on the canvas (a pixel the field leaves where it is sits at its
    /// own coordinates plus this).
    pub offset: V2,
}

/// One block: the (up to) four pixels around a unit square of the rest plane, corners
/// numbered 0 = top-left, 1 = top-right, 2 = bottom-left, 3 = bottom-right.
pub(super) struct Block {
    pub present: u8,
    pub links: u8,
    pub p: [V2; 4],
    pub col: [Rgba; 4],
    /// Pixel coordinates of each corner (meaningful where present).
    pub xy: [(usize, usize); 4],
}

/// The points of a partial block's skirt quarters: for each present corner the point on
/// its horizontal side (`h`) and on its vertical side (`v`), and the centre point `c`
/// shared by the corners of its component (the corners linked to it within the block).
pub(super) struct Skirts {
    pub h: [V2; 4],
    pub v: [V2; 4],
    pub c: [V2; 4],
}

/// Per-block orientation bytes and per-chunk vertical extents of the elements.
pub(super) struct Plan {
    /// `(w + 1) × (h + 1)` bytes, block `(bc, br)` at `br * (w + 1) + bc`.
    pub signs: Vec<u8>,
    /// `[ymin, ymax]` of every element point in chunk `ch` of block row `br`, at
    /// `br * nchunks + ch`; `[inf, -inf]` when the chunk draws nothing.
    pub ranges: Vec<[f32; 2]>,
    pub nchunks: usize,
    /// `[ymin, ymax]` of every element point in block row `br` (the union of its chunks'
    /// ranges), so that a band skips the rows that do not reach it at once.
    pub row_ranges: Vec<[f32; 2]>,
}

#[inline]
pub(super) fn sub(a: V2, b: V2) -> V2 { [a[0] - b[0], a[1] - b[1]] }

#[inline]
pub(super) fn cross(a: V2, b: V2) -> f32 { a[0] * b[1] - a[1] * b[0] }

/// The midpoint of a link. Commutative bit for bit, so both blocks beside a link agree.
#[inline]
pub(super) fn mid(a: V2, b: V2) -> V2 { [(a[0] + b[0]) * 0.5, (a[1] + b[1]) * 0.5] }

/// Whether the quadrilateral `q` (corners in the order top-left, top-right, bottom-right,
/// bottom-left of its rest square) is flipped, i.e. has negative signed area.
#[inline]
pub(super) fn is_flipped(q: &[V2; 4]) -> bool {
    let a = sub(q[1], q[0]);
    let b = sub(q[2], q[0]);
    let c = sub(q[3], q[0]);
    cross(a, b) + cross(b, c) < 0.0
}

/// Corners of the skirt quarter of corner `k`, in the order top-left, top-right,
/// bottom-right, bottom-left of its rest square.
#[inline]
pub(super) fn quarter_corners(b: &Block, s: &Skirts, k: usize) -> [V2; 4] {
    let (p, h, v, c) = (b.p[k], s.h[k], s.v[k], s.c[k]);
    match k { 0 => [p, h, c, v], 1 => [h, p, v, c], 2 => [v, c, h, p], _ => [c, v, p, h] }
}

/// The pixels of the block connected to corner `k` through the block's own links.
#[inline]
pub(super) fn component(links: u8, k: usize) -> u8 {
    let mut m = 1u8 << k;
    for _ in 0..3 {
        for (side, ends, _, _) in SIDES {
            if links & side != 0 && m & ends != 0 {
                m |= ends;
            }
        }
    }
    m
}

/// The corners whose colours shade the skirt quarter of corner `k`: every drawn corner
/// that can be reached from `k` around the block's four sides without crossing a *broken*
/// side (both ends drawn, no link). Colour thus never leaks across a cut or onto an
/// unlinked pixel, while pixels that merely touch diagonally blend as the box filter does.
#[inline]
pub(super) fn shading_mask(present: u8, links: u8, k: usize) -> u8 {
    // The block's corners around its boundary, and the side from each to the next.
    const CYCLE: [usize; 4] = [0, 1, 3, 2];
    const SIDE: [u8; 4] = [TOP, RIGHT, BOTTOM, LEFT];
    let broken = |side: usize| {
        let (a, b) = (CYCLE[side], CYCLE[(side + 1) % 4]);
        present >> a & 1 != 0 && present >> b & 1 != 0 && links & SIDE[side] == 0
    };
    let start = CYCLE.iter().position(|&c| c == k).expect("corner index below 4");
    let mut mask = 1u8 << k;
    // Clockwise, then counter-clockwise, until a broken side.
    for step in (1..4).take_while(|step| !broken((start + step - 1) % 4)) {
        mask |= 1 << CYCLE[(start + step) % 4];
    }
    for step in (1..4).take_while(|step| !broken((start + 4 - step) % 4)) {
        mask |= 1 << CYCLE[(start + 4 - step) % 4];
    }
    mask & present
}

/// The premultiplied colour at block coordinates `(u, v)` ∈ [0, 1]²: bilinear weights of
/// the corners in `mask`, renormalised (plain bilinear when `mask` holds all four).
#[inline]
pub(super) fn shade(col: &[Rgba; 4], mask: u8, own: usize, u: f32, v: f32) -> Rgba {
    let w = [(1.0 - u) * (1.0 - v), u * (1.0 - v), (1.0 - u) * v, u * v];
    let (mut out, mut sum) = ([0.0f32; 4], 0.0f32);
    for k in (0..4).filter(|k| mask >> k & 1 != 0) {
        sum += w[k];
        for ch in 0..4 {
            out[ch] += w[k] * col[k][ch];
        }
    }
    if mask == 0b1111 {
        return out;
    }
    if sum > 1e-12 {
        let inv = 1.0 / sum;
        out.map(|c| c * inv)
    } else {
        col[own]
    }
}

impl<'a> Layer<'a> {
    /// The layer of `image` displaced by the field `(dx, dy)` (planes, row-major), which
    /// become its canvas positions in place.
    pub fn prepare(image: &'a RgbaImage, mut px: Vec<f32>, mut py: Vec<f32>, grid: &Grid, offset: [f64; 2]) -> Self {
        let (w, h) = (image.width, image.height);
        let (ox, oy) = (offset[0] as f32, offset[1] as f32);
        px.par_chunks_mut(w).zip(py.par_chunks_mut(w)).enumerate().for_each(|(y, (xrow, yrow))| {
            let r = y * w..(y + 1) * w;
            let alphas = image.data[4 * r.start..4 * r.end].chunks_exact(4);
            let inputs = grid.active[r].iter().zip(alphas);
            for (x, ((px, py), (&active, pixel))) in xrow.iter_mut().zip(yrow.iter_mut()).zip(inputs).enumerate() {
                let at = [x as f32 + *px + ox, y as f32 + *py + oy];
                let drawn = (active || pixel[3] > 0) && at[0].is_finite() && at[1].is_finite();
                (*px, *py) = if drawn { (at[0], at[1]) } else { (f32::NAN, f32::NAN) };
            }
        });
        let mut links = vec![0u8; w * h];
        links.par_chunks_mut(w).enumerate().for_each(|(y, lrow)| {
            let r = y * w..(y + 1) * w;
            let here = &px[r.clone()];
            let below = if y + 1 < h { &px[r.end..r.end + w] } else { here };
            let (right, down) = (&grid.link_right[r.clone()], &grid.link_down[r]);
            for x in (0..w).filter(|&x| !here[x].is_nan()) {
                let linked_right = x + 1 < w && right[x] && !here[x + 1].is_nan();
                let linked_down = y + 1 < h && down[x] && !below[x].is_nan();
                lrow[x] = (u8::from(linked_right) * LINK_RIGHT) | (u8::from(linked_down) * LINK_DOWN);
            }
        });
        Layer { w, h, px, py, rgba: &image.data, links, offset: [ox, oy] }
    }

    /// The canvas position of pixel `i` (NaN where it is not drawn).
    #[inline(always)]
    pub fn pos(&self, i: usize) -> V2 { [self.px[i], self.py[i]] }

    #[inline(always)]
    pub fn drawn(&self, i: usize) -> bool { !self.px[i].is_nan() }

    /// The premultiplied colour of pixel `i`.
    #[inline(always)]
    pub fn col(&self, i: usize) -> Rgba {
        let p = &self.rgba[4 * i..4 * i + 4];
        premultiply([p[0], p[1], p[2], p[3]])
    }

    /// Block `(bc, br)`, whose top-left pixel is `(bc - 1, br - 1)`; `bc ≤ w`, `br ≤ h`.
    #[inline]
    pub fn block(&self, bc: usize, br: usize) -> Block {
        let mut b = Block { present: 0, links: 0, p: [[0.0; 2]; 4], col: [[0.0; 4]; 4], xy: [(0, 0); 4] };
        let mut idx = [0usize; 4];
        for k in 0..4 {
            let x = (bc + (k & 1)).wrapping_sub(1);
            let y = (br + (k >> 1)).wrapping_sub(1);
            if x < self.w && y < self.h {
                let i = y * self.w + x;
                if self.drawn(i) {
                    b.present |= 1 << k;
                    b.p[k] = self.pos(i);
                    b.col[k] = self.col(i);
                    b.xy[k] = (x, y);
                    idx[k] = i;
                }
            }
        }
        for (side, ends, first, link) in SIDES {
            if b.present & ends == ends && self.links[idx[first]] & link != 0 {
                b.links |= side;
            }
        }
        b
    }

    /// The local frame `(ex, ey)` of pixel `(x, y)`: the displaced link to the right (or,
    /// failing that, from the left) and the one down (or from above); a missing one is the
    /// other turned by 90°, and both missing are the rest axes.
    pub fn frame(&self, x: usize, y: usize) -> (V2, V2) {
        let w = self.w;
        let i = y * w + x;
        let p = self.pos(i);
        // The link to the neighbour `step` on, or failing that from the one `step` back.
        let axis = |link: u8, step: usize, back: bool| {
            if self.links[i] & link != 0 {
                Some(sub(self.pos(i + step), p))
            } else if back && self.links[i - step] & link != 0 {
                Some(sub(p, self.pos(i - step)))
            } else {
                None
            }
        };
        match (axis(LINK_RIGHT, 1, x > 0), axis(LINK_DOWN, w, y > 0)) {
            (Some(a), Some(b)) => (a, b),
            (Some(a), None) => (a, [-a[1], a[0]]),
            (None, Some(b)) => ([b[1], -b[0]], b),
            (None, None) => ([1.0, 0.0], [0.0, 1.0]),
        }
    }

    /// The skirt points of a block that is not a complete quad.
    pub fn skirts(&self, b: &Block) -> Skirts {
        let mut s = Skirts { h: [[0.0; 2]; 4], v: [[0.0; 2]; 4], c: [[0.0; 2]; 4] };
        // The parallelogram completion of each corner.
        let mut completion = [[0.0f32; 2]; 4];
        for k in (0..4).filter(|k| b.present >> k & 1 != 0) {
            let p = b.p[k];
            let h_side = if k < 2 { TOP } else { BOTTOM };
            let v_side = if k & 1 == 0 { LEFT } else { RIGHT };
            let (x, y) = b.xy[k];
            let frame = (b.links & h_side == 0 || b.links & v_side == 0).then(|| self.frame(x, y));
            // Past the picture's edge, an edge pixel near its rest place across the edge reaches
            // out at least to the frame's edge: a held edge stays there however the picture
            // inside it is squeezed (half the squeezed link would pull it away). The reach fades
            // out over `EDGE_REST_PX` of displacement, so a moved edge keeps the plain rule.
            let reach = |past: bool, a: usize, coord: usize| {
                let moved = (p[a] - (coord as f32 + self.offset[a])).abs();
                if past { (1.0 - moved / EDGE_REST_PX).clamp(0.0, 1.0) } else { 0.0 }
            };
            let (reach_x, reach_y) = (
                reach(if k & 1 == 0 { x + 1 == self.w } else { x == 0 }, 0, x),
                reach(if k < 2 { y + 1 == self.h } else { y == 0 }, 1, y),
            );
            // The midpoint of the side towards corner `other` if it is a link, else half the
            // frame's axis `e` that way, its component `a` across the picture's edge at least `reach`.
            let towards = |side: u8, other: usize, e: fn((V2, V2)) -> V2, sign: f32, a: usize, reach: f32| {
                if b.links & side != 0 {
                    return mid(p, b.p[other]);
                }
                let mut e = e(frame.expect("frame computed for a missing side"));
                if e[a] > 0.0 { e[a] = e[a].max(reach) } // (not where the picture is turned over there)
                [p[0] + sign * e[0], p[1] + sign * e[1]]
            };
            s.h[k] = towards(h_side, k ^ 1, |f| f.0, if k & 1 == 0 { 0.5 } else { -0.5 }, 0, reach_x);
            s.v[k] = towards(v_side, k ^ 2, |f| f.1, if k < 2 { 0.5 } else { -0.5 }, 1, reach_y);
            completion[k] = [s.h[k][0] + s.v[k][0] - p[0], s.h[k][1] + s.v[k][1] - p[1]];
        }
        for k in (0..4).filter(|k| b.present >> k & 1 != 0) {
            let members = component(b.links, k);
            let (mut sum, mut n) = ([0.0f32; 2], 0.0f32);
            for j in (0..4).filter(|j| members >> j & 1 != 0) {
                sum = [sum[0] + completion[j][0], sum[1] + completion[j][1]];
                n += 1.0;
            }
            s.c[k] = [sum[0] / n, sum[1] / n];
        }
        s
    }

    /// Orientation of every element and vertical extent of every chunk of blocks.
    pub fn plan(&self) -> Plan {
        let (bw, bh) = (self.w + 1, self.h + 1);
        let nchunks = bw.div_ceil(CHUNK);
        let mut signs = vec![0u8; bw * bh];
        let mut ranges = vec![[f32::INFINITY, f32::NEG_INFINITY]; bh * nchunks];
        let w = self.w;
        signs.par_chunks_mut(bw).zip(ranges.par_chunks_mut(nchunks)).enumerate().for_each(|(br, (srow, rrow))| {
            let extend = |range: &mut [f32; 2], q: &[V2; 4]| {
                for p in q {
                    range[0] = if p[1] < range[0] { p[1] } else { range[0] };
                    range[1] = if p[1] > range[1] { p[1] } else { range[1] };
                }
            };
            // Rows above and below the block row, for the complete quads inside.
            let rows = (br >= 1 && br < self.h).then(|| {
                let (a, b) = ((br - 1) * w, br * w);
                (a, b, &self.links[a..a + w], &self.links[b..b + w])
            });
            for bc in 0..bw {
                if let Some((a, b, l0, l1)) = rows.filter(|_| bc >= 1 && bc < w) {
                    let x = bc - 1;
                    if l0[x] & (LINK_RIGHT | LINK_DOWN) == LINK_RIGHT | LINK_DOWN
                        && l0[x + 1] & LINK_DOWN != 0
                        && l1[x] & LINK_RIGHT != 0
                    {
                        let q = [self.pos(a + x), self.pos(a + x + 1), self.pos(b + x + 1), self.pos(b + x)];
                        srow[bc] = COMPLETE | ANY | is_flipped(&q) as u8;
                        extend(&mut rrow[bc / CHUNK], &q);
                        continue;
                    }
                }
                let b = self.block(bc, br);
                if b.present == 0 {
                    continue;
                }
                debug_assert!(b.links != TOP | BOTTOM | LEFT | RIGHT, "complete blocks are found above");
                let s = self.skirts(&b);
                let mut byte = ANY;
                for k in 0..4 {
                    if b.present >> k & 1 != 0 {
                        let q = quarter_corners(&b, &s, k);
                        byte |= (is_flipped(&q) as u8) << k;
                        extend(&mut rrow[bc / CHUNK], &q);
                    }
                }
                srow[bc] = byte;
            }
        });
        // Mark the quads inside pieces, away from folds.
        let plain = signs.clone();
        signs.par_chunks_mut(bw).enumerate().for_each(|(br, srow)| {
            if br == 0 || br + 1 >= bh {
                return;
            }
            let row = |r: usize| &plain[r * bw..(r + 1) * bw];
            let (above, here, below) = (row(br - 1), row(br), row(br + 1));
            for bc in 1..bw - 1 {
                let kind = here[bc] & (COMPLETE | 1);
                if here[bc] & COMPLETE != 0
                    && [above[bc], below[bc], here[bc - 1], here[bc + 1]].iter().all(|&n| n & (COMPLETE | 1) == kind)
                {
                    srow[bc] |= SIMPLE;
                }
            }
        });
        let row_ranges = ranges.chunks(nchunks).map(|row| {
            row.iter().fold([f32::INFINITY, f32::NEG_INFINITY], |[lo, hi], r| {
                [if r[0] < lo { r[0] } else { lo }, if r[1] > hi { r[1] } else { hi }]
            })
        }).collect();
        Plan { signs, ranges, nchunks, row_ranges }
    }
}

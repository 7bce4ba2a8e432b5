//! `grid_step = s > 1`: solve on every s-th node and upsample with a tensor-product cubic.
//!
//! Coarse node (X, Y) sits on pixel (min(sX, W−1), min(sY, H−1)) (so every pixel lies between coarse nodes),
//! active when that pixel is; two coarse neighbours are linked when every fine link between them is. A sample
//! constrains the nearest coarse node, which takes the nearest of its samples; the tension is scaled by s²
//! (the same continuous energy).
//!
//! Upsampling is Catmull-Rom in x and y, linear past the border. A pixel uses only the nodes of its 4 × 4
//! window it reaches through links within the window's block (a tear stays open even where its sides join
//! far around), renormalised and corrected to keep affine fields affine; else bilinear from the inner 2 × 2,
//! else the nearest value along the links. A piece with no coarse node takes its samples' mean displacement
//! or zero; a coarse piece no sample holds moves with the held one it joins on the full grid. Built for speed
//! (the editor's drag path, `docs/dev/multigrid.md`); a test holds it to the per-pixel loop (up to sums' order).

use std::collections::VecDeque;

use rayon::prelude::*;

use crate::clock::Instant;
use crate::field::{Field, FieldView};
use crate::geometry::Sample;
use crate::grid::{constrain, nearest_node, Grid};

use super::history::solve_from;
use super::level::coarse_links;
use super::{in_pool, validate, SolveError, SolveOptions, SolveReport, Solver};

/// The solve at `grid_step = s > 1`: on the coarse grid, then upsampled.
pub(crate) fn solve_coarse(
    grid: &Grid, samples: &[Sample], options: &SolveOptions, initial: Option<FieldView<'_>>, solver: &mut Solver, warm: bool,
) -> (Field, SolveReport) {
    if grid.is_empty() { return (Field::zeros(grid.width, grid.height), SolveReport { converged: true, ..Default::default() }) }
    let (fc, report) = solve_on_coarse_grid(grid, samples, options, initial, solver, warm, true);
    (upsample(grid, &Upsampling::new(grid, options.grid_step), &fc, samples), report)
}

/// The coarse solve of `grid_step = s` on a non-empty grid, from `initial` read at the coarse nodes, or from
/// the solver's history, which keeps the coarse fields (only their coarse nodes' values would ever be read).
fn solve_on_coarse_grid(
    grid: &Grid, samples: &[Sample], options: &SolveOptions, initial: Option<FieldView<'_>>, solver: &mut Solver, warm: bool, follow: bool,
) -> (Field, SolveReport) {
    let (l, sf) = (Layout::new(grid.width, grid.height, options.grid_step), options.grid_step as f64);
    let coarse = coarse_grid(grid, l.s);
    let at = |p: &Sample| Sample { rest: coarse_point(grid.width, grid.height, l.s, p.rest), ..*p };
    let coarse_samples: Vec<Sample> = samples.iter().filter(|p| nearest_node(grid, p.rest).is_some()).map(at).collect();
    let nearest: Vec<Sample> = coarse_samples.iter().zip(coarse_nodes(&coarse, &coarse_samples)).filter(|(_, n)| n.is_none_or(|n| n.1)).map(|(p, _)| *p).collect();
    let mut constraints = constrain(&coarse, &nearest);
    constraints.dropped_samples += samples.len() - coarse_samples.len();
    constraints.used_samples += coarse_samples.len() - nearest.len();
    let start = initial.map(|f| {
        let (dx, dy) = (0..l.wc * l.hc).map(|c| f.at_index(l.py(c / l.wc) * f.width() + l.px(c % l.wc))).map(|v| (v[0], v[1])).unzip();
        Field { width: l.wc, height: l.hc, dx, dy }
    });
    let options = SolveOptions { tension: options.tension * sf * sf, grid_step: 1, ..options.clone() };
    let (mut fc, report) = solve_from(&coarse, &constraints, &options, start.as_ref().map(FieldView::from), solver, warm);
    if follow { follow_held(grid, &l, &coarse, &constraints, &mut fc); }
    (fc, report)
}

/// The grid a solve at `grid_step = s` runs on (see the module docs).
pub fn coarse_grid(grid: &Grid, s: usize) -> Grid {
    let (width, height, [active, link_right, link_down]) = coarse_links(grid.width, grid.height, s, &grid.active, &grid.link_right, &grid.link_down);
    Grid { width, height, active, link_right, link_down }
}

/// Where a sample at pixel `rest` goes on the coarse grid of step `s` of a `w × h` grid, in coarse coordinates
/// (so that it goes to the coarse node nearest to it, in the last, shorter cell too).
pub fn coarse_point(w: usize, h: usize, s: usize, [x, y]: crate::geometry::Point) -> crate::geometry::Point {
    let l = Layout::new(w, h, s);
    let coarse = |(c, t): (usize, f64)| c as f64 + t;
    [coarse(cell_of(x, s, l.wc, |c| l.px(c))), coarse(cell_of(y, s, l.hc, |c| l.py(c)))]
}

/// The node of `coarse` each sample (at [`coarse_point`]) falls on and whether it holds it: a node takes the nearest
/// of its samples, ties together (averaged, as on a full grid's node); none where a sample lies off the grid or on an
/// inactive node, or is not finite. The mean of all is the displacement at their centre: up to s/2 off.
pub fn coarse_nodes(coarse: &Grid, samples: &[Sample]) -> Vec<Option<(usize, bool)>> {
    let nodes: Vec<Option<(usize, f64)>> = samples.iter().map(|p| nearest_node(coarse, p.rest).map(|(x, y)| (coarse.index(x, y), (p.rest[0] - x as f64).hypot(p.rest[1] - y as f64)))
        .filter(|&(i, _)| coarse.active[i] && p.displacement.iter().all(|d| d.is_finite()))).collect();
    let mut least = vec![f64::INFINITY; coarse.len()];
    nodes.iter().flatten().for_each(|&(i, d)| least[i] = least[i].min(d));
    nodes.iter().map(|n| n.map(|(i, d)| (i, d <= least[i] + 1e-9))).collect()
}

/// A coarse piece no sample holds that joins a held one on the full grid (a strand thinner than the step) moves
/// with the nearest held coarse node along the full grid's links. The drafts ([`solve_at`]) go without it.
fn follow_held(grid: &Grid, l: &Layout, coarse: &Grid, constraints: &crate::grid::Constraints, fc: &mut Field) {
    let (labels, count) = coarse.pieces();
    let mut held = vec![false; count];
    constraints.nodes.iter().for_each(|&c| held[labels[c] as usize] = true);
    let pixel = |c: usize| l.py(c / l.wc) * grid.width + l.px(c % l.wc);
    let loose = |c: usize| labels[c] != u32::MAX && !held[labels[c] as usize];
    if constraints.nodes.is_empty() || !(0..labels.len()).any(loose) { return; }
    // Breadth first over the full grid from the pixels of held coarse nodes: `from[p]` the coarse node reached.
    let mut from = vec![u32::MAX; grid.len()];
    let mut queue: VecDeque<u32> = (0..labels.len()).filter(|&c| labels[c] != u32::MAX && !loose(c)).map(|c| { from[pixel(c)] = c as u32; pixel(c) as u32 }).collect();
    while let Some(p) = queue.pop_front().map(|p| p as usize) {
        for q in grid.linked(p) {
            if q != usize::MAX && from[q] == u32::MAX {
                from[q] = from[p];
                queue.push_back(q as u32);
            }
        }
    }
    for c in (0..labels.len()).filter(|&c| loose(c) && from[pixel(c)] != u32::MAX) {
        let h = from[pixel(c)] as usize;
        (fc.dx[c], fc.dy[c]) = (fc.dx[h], fc.dy[h]);
    }
}

/// What upsampling a `grid_step` solve on one grid needs besides the coarse field: every pixel column's and
/// row's taps and the usable-tap masks of cells along missing links. Kept per grid and step, it also evaluates
/// chosen pixels only ([`Solver::solve_warm_at`]).
#[derive(Debug)]
pub struct Upsampling { layout: Layout, cols: Vec<Taps>, rows: Vec<Taps>, masks: Vec<Vec<u16>> }

impl Upsampling {
    /// The plan of `grid` at step `s` (at least 2) on a non-empty grid.
    pub fn new(grid: &Grid, s: usize) -> Upsampling {
        assert!(s > 1 && grid.width > 0 && grid.height > 0, "an upsampling plan needs a step above 1 and a non-empty grid");
        let layout = Layout::new(grid.width, grid.height, s);
        let cols = Taps::along(layout.w, layout.wc, s, |x| layout.px(x));
        let rows = Taps::along(layout.h, layout.hc, s, |y| layout.py(y));
        Upsampling { masks: mask_table(grid, &layout, &cols, &rows), layout, cols, rows }
    }

    /// The upsampled value of pixel `i` of `grid` (the plan's) from the coarse field `fc`: zero for an inactive pixel,
    /// `None` where its window has no usable node (the full upsampling then fills it along the links).
    fn at(&self, grid: &Grid, fc: &Field, i: usize) -> Option<[f32; 2]> {
        if !grid.active[i] { return Some([0.0; 2]); }
        let (x, y) = (i % self.layout.w, i / self.layout.w);
        window_value(fc, &self.rows[y], &self.cols[x], self.mask(x, y))
    }

    /// The usable taps of pixel (`x`, `y`) from its cell's masks ([`cell_masks`]; empty where the window is whole).
    fn mask(&self, x: usize, y: usize) -> u16 {
        let (l, cx, cy) = (&self.layout, self.cols[x].cell, self.rows[y].cell);
        let masks = &self.masks[cy * l.cells().0 + cx];
        if masks.is_empty() { return ALL_TAPS; }
        let ix0 = l.px(cx);
        masks[(y - l.py(cy)) * (l.px((cx + 1).min(l.wc - 1)) - ix0 + 1) + (x - ix0)]
    }
}

/// The body of [`Solver::solve_warm_at`].
pub(crate) fn solve_at(
    grid: &Grid, samples: &[Sample], options: &SolveOptions, solver: &mut Solver, plan: &Upsampling, pixels: &[u32], out: &mut [f32],
) -> Result<SolveReport, SolveError> {
    let start = Instant::now();
    if options.grid_step != plan.layout.s || plan.layout.w != grid.width || plan.layout.h != grid.height { return Err(SolveError::PlanMismatch) }
    if out.len() != 2 * pixels.len() || pixels.iter().any(|&p| p as usize >= grid.len()) { return Err(SolveError::BadPixels) }
    validate(grid, samples, options, None)?;
    let (fc, mut report) = in_pool(|| solve_on_coarse_grid(grid, samples, options, None, solver, true, false));
    if let Some(values) = pixels.iter().map(|&p| plan.at(grid, &fc, p as usize)).collect::<Option<Vec<_>>>() {
        out.copy_from_slice(values.as_flattened());
    } else {
        // A pixel whose window reaches no coarse node takes the full upsampling's fill.
        let field = upsample(grid, plan, &fc, samples);
        out.chunks_exact_mut(2).zip(pixels).for_each(|(o, &p)| o.copy_from_slice(&[field.dx[p as usize], field.dy[p as usize]]));
    }
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// Where the `wc × hc` coarse nodes of a `w × h` grid with step `s` sit.
#[derive(Clone, Copy, Debug)]
struct Layout { s: usize, w: usize, h: usize, wc: usize, hc: usize }

impl Layout {
    fn new(w: usize, h: usize, s: usize) -> Self { Layout { s, w, h, wc: (w - 1).div_ceil(s) + 1, hc: (h - 1).div_ceil(s) + 1 } }

    /// The pixel column of coarse column `xc`, and the pixel row of coarse row `yc`.
    fn px(&self, xc: usize) -> usize { (xc * self.s).min(self.w - 1) }
    fn py(&self, yc: usize) -> usize { (yc * self.s).min(self.h - 1) }

    /// Coarse cells across and down (at least one each, even on a one-node axis).
    fn cells(&self) -> (usize, usize) { (self.wc.saturating_sub(1).max(1), self.hc.saturating_sub(1).max(1)) }
}

/// The coarse cell (its first position, at most `nc − 2`) of pixel coordinate `x` along an axis of
/// `nc` coarse positions at pixels `pos(0..nc)`, `s` apart, and how far across it `x` lies.
fn cell_of(x: f64, s: usize, nc: usize, pos: impl Fn(usize) -> usize) -> (usize, f64) {
    if nc < 2 { return (0, 0.0); } // (one position: its value)
    let c = ((x / s as f64).max(0.0) as usize).min(nc - 2);
    let (a, b) = (pos(c) as f64, pos(c + 1) as f64);
    (c, (x - a) / (b - a))
}

/// The Catmull-Rom taps of one pixel along one axis: its coarse `cell` (its window spans coarse positions `cell − 1 ..=
/// cell + 2`), the cubic `weights` of the window's four positions, `t` how far across the cell it lies, and the `len`
/// used taps (inside the grid, nonzero weight): their window positions `slot` and coarse indices `at`. A window cut
/// short fits its plane with weights `plane` (zero outside the grid): the cubic's, in magnitude, at `near`, `t` at
/// least a pixel inside the cell, so that a pixel on a coarse line fits it over the lines beside too, not along its
/// own, and where none of its own line's nodes is usable, takes the value a pixel into the cell would.
#[derive(Clone, Copy, Debug)]
struct Taps { cell: usize, weights: [f64; 4], t: f64, len: usize, slot: [u8; 4], at: [usize; 4], plane: [f64; 4], near: f64 }

impl Taps {
    /// The taps of every pixel `0..n` along an axis with `nc` coarse positions at `pos(0..nc)`, `s` apart.
    fn along(n: usize, nc: usize, s: usize, pos: impl Fn(usize) -> usize) -> Vec<Taps> {
        (0..n).map(|x| {
            let (cell, t) = cell_of(x as f64, s, nc, &pos);
            let t = t.clamp(0.0, 1.0);
            let (first, last) = (cell == 0, cell + 2 >= nc);
            let weights = catmull_rom(t, first, last);
            let inside = |k: usize| (cell + k).checked_sub(1).is_some_and(|c| c < nc);
            let margin = (1.0 / s as f64).min(0.5);
            let near = if nc == 1 { t } else { t.clamp(margin, 1.0 - margin) };
            let plane = catmull_rom(near, first, last).map(f64::abs);
            let plane = std::array::from_fn(|k| if inside(k) { plane[k] } else { 0.0 });
            let mut taps = Taps { cell, weights, t, len: 0, slot: [0; 4], at: [0; 4], plane, near };
            for k in (0..4).filter(|&k| inside(k) && weights[k] != 0.0) {
                (taps.slot[taps.len], taps.at[taps.len]) = (k as u8, cell + k - 1);
                taps.len += 1;
            }
            taps
        }).collect()
    }
}

/// The bilinear weight of window position `k` (1 or 2) of a pixel `t` across its cell.
fn linear(k: usize, t: f64) -> f64 { if k == 1 { 1.0 - t } else { t } }

/// The Catmull-Rom weights of the window of a pixel `t` across its cell; in the `first` or `last` cell the position
/// past the border as the linear extrapolation of the two inside it, so the weights sum to 1 and keep linear functions.
fn catmull_rom(t: f64, first: bool, last: bool) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    let mut w = [0.5 * (-t3 + 2.0 * t2 - t), 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0), 0.5 * (-3.0 * t3 + 4.0 * t2 + t), 0.5 * (t3 - t2)];
    if first { (w[1], w[2], w[0]) = (w[1] + 2.0 * w[0], w[2] - w[0], 0.0) }
    if last { (w[2], w[1], w[3]) = (w[2] + 2.0 * w[3], w[1] - w[3], 0.0) }
    w
}

/// Every coarse node of a window's taps: the bit `4 kb + ka` stands for window position (`ka`, `kb`).
const ALL_TAPS: u16 = u16::MAX;

/// The usable-tap masks of every coarse cell ([`cell_masks`]) near one that a missing link or an inactive
/// pixel touches, empty (every tap usable) for the others.
fn mask_table(grid: &Grid, layout: &Layout, cols: &[Taps], rows: &[Taps]) -> Vec<Vec<u16>> {
    let (w, h, (cw, ch)) = (layout.w, layout.h, layout.cells());
    // Whether a missing link or an inactive pixel lies in each cell's closed block (stretches of a row
    // without any are skipped whole).
    let mut touched = vec![false; cw * ch];
    // The cells whose closed block holds pixel (x, y): one or two along each axis.
    let mut mark = |x: usize, y: usize| {
        let (cx, cy) = (cols[x].cell, rows[y].cell);
        let x0 = if cx > 0 && x == layout.px(cx) { cx - 1 } else { cx };
        let ys = if cy > 0 && y == layout.py(cy) { cy - 1..cy + 1 } else { cy..cy + 1 };
        ys.for_each(|yy| touched[yy * cw + x0..=yy * cw + cx].fill(true));
    };
    // Whether all of `flags` (a stretch of a row) are set, branch-free so that it vectorises.
    let all = |flags: &[bool]| flags.iter().fold(true, |a, &b| a & b);
    const CHUNK: usize = 64;
    for y in 0..h {
        let row = y * w;
        for x0 in (0..w).step_by(CHUNK) {
            let x1 = (x0 + CHUNK).min(w);
            let down_ok = y + 1 == h || all(&grid.link_down[row + x0..row + x1]);
            if down_ok && all(&grid.active[row + x0..row + x1]) && all(&grid.link_right[row + x0..row + x1.min(w - 1)]) {
                continue;
            }
            // The cell of a missing link to the right of (or below) a pixel holds the pixel.
            for x in x0..x1 {
                let i = row + x;
                if !grid.active[i] || (x + 1 < w && !grid.link_right[i]) || (y + 1 < h && !grid.link_down[i]) {
                    mark(x, y);
                }
            }
        }
    }
    let near_touched = |k: usize| {
        let (x0, y0) = (k % cw, k / cw);
        (y0.saturating_sub(1)..(y0 + 2).min(ch)).any(|y| (x0.saturating_sub(1)..(x0 + 2).min(cw)).any(|x| touched[y * cw + x]))
    };
    (0..cw * ch).into_par_iter().map_init(|| (Vec::new(), Vec::new()), |(label, stack), k| {
        if near_touched(k) { cell_masks(grid, layout, k % cw, k / cw, label, stack) } else { Vec::new() }
    }).collect()
}

/// The taps that each pixel of coarse cell (`cx`, `cy`) may use: the coarse nodes of its 4 × 4 window in
/// the pixel's connected component of the links inside the window's block of pixels (clipped to the
/// grid), as bits of [`ALL_TAPS`]. One mask per pixel of the cell's closed block, row by row; zero for
/// inactive pixels, [`ALL_TAPS`] for those reaching every node.
fn cell_masks(grid: &Grid, layout: &Layout, cx: usize, cy: usize, label: &mut Vec<u32>, stack: &mut Vec<usize>) -> Vec<u16> {
    let (wc, hc) = (layout.wc, layout.hc);
    let (bx0, bx1) = (layout.px(cx.saturating_sub(1)), layout.px((cx + 2).min(wc - 1)));
    let (by0, by1) = (layout.py(cy.saturating_sub(1)), layout.py((cy + 2).min(hc - 1)));
    let (ix0, ix1) = (layout.px(cx), layout.px((cx + 1).min(wc - 1)));
    let (iy0, iy1) = (layout.py(cy), layout.py((cy + 1).min(hc - 1)));
    let (bw, bh) = (bx1 - bx0 + 1, by1 - by0 + 1);
    label.clear();
    label.resize(bw * bh, u32::MAX);
    // Components of the block reached from the cell's pixels, depth first through links.
    let mut count = 0u32;
    for y in iy0..=iy1 {
        for x in ix0..=ix1 {
            let b = (y - by0) * bw + (x - bx0);
            if !grid.active[grid.index(x, y)] || label[b] != u32::MAX { continue; }
            label[b] = count;
            stack.push(b);
            while let Some(b) = stack.pop() {
                let (lx, ly) = (b % bw, b / bw);
                // Right, left, down, up (not linked where off the block).
                let (links, inside) = (grid.linked(grid.index(bx0 + lx, by0 + ly)), [lx + 1 < bw, lx > 0, ly + 1 < bh, ly > 0]);
                for (k, nb) in [b + 1, b.wrapping_sub(1), b + bw, b.wrapping_sub(bw)].into_iter().enumerate() {
                    if inside[k] && links[k] != usize::MAX && label[nb] == u32::MAX {
                        label[nb] = count;
                        stack.push(nb);
                    }
                }
            }
            count += 1;
        }
    }
    let (mut reach, mut full) = (vec![0u16; count as usize], 0u16);
    for bit in 0..16 {
        // Window node (bit % 4, bit / 4) at coarse position (nx, ny), if inside the grid.
        let (nx, ny) = ((cx + bit % 4).checked_sub(1).filter(|&n| n < wc), (cy + bit / 4).checked_sub(1).filter(|&n| n < hc));
        let (Some(nx), Some(ny)) = (nx, ny) else { continue };
        full |= 1 << bit;
        let l = label[(layout.py(ny) - by0) * bw + (layout.px(nx) - bx0)];
        if l != u32::MAX {
            reach[l as usize] |= 1 << bit;
        }
    }
    let mut masks = Vec::with_capacity((ix1 - ix0 + 1) * (iy1 - iy0 + 1));
    for y in iy0..=iy1 {
        for x in ix0..=ix1 {
            let l = label[(y - by0) * bw + (x - bx0)];
            let m = if l == u32::MAX { 0 } else { reach[l as usize] };
            masks.push(if m == full { ALL_TAPS } else { m });
        }
    }
    masks
}

/// One pixel's value from the coarse field `fc` (`ty`, `tx` its taps): a whole window's cubic (its weights sum to 1);
/// the taps allowed by `mask`, renormalised and corrected ([`Moments::value`]), or bilinear where they fall short.
fn window_value(fc: &Field, ty: &Taps, tx: &Taps, mask: u16) -> Option<[f32; 2]> {
    if mask == ALL_TAPS {
        let at = |f: &[f32], b: usize| (0..tx.len).map(|a| tx.weights[tx.slot[a] as usize] * f[ty.at[b] * fc.width + tx.at[a]] as f64).sum::<f64>();
        return Some([&fc.dx, &fc.dy].map(|f| (0..ty.len).map(|b| ty.weights[ty.slot[b] as usize] * at(f, b)).sum::<f64>() as f32));
    }
    let cubic = window_moments(fc, ty, tx, mask, |t, k| Some(t.weights[k]));
    cubic.value(0.5, &cubic.plane)
        .or_else(|| window_moments(fc, ty, tx, mask, |t, k| (1..3).contains(&k).then(|| linear(k, t.t))).value(1e-9, &cubic.plane))
        .or_else(|| (tx.near != tx.t || ty.near != ty.t).then(|| {
            // (corrected to the pixel's own place, not the one a pixel in)
            let mut near = window_moments(fc, ty, tx, mask, |t, k| (1..3).contains(&k).then(|| linear(k, t.near)));
            near.whole = [1.0, 1.0 + tx.t, 1.0 + ty.t];
            near.value(1e-9, &cubic.plane)
        }).flatten())
}

/// The [`Moments`] of `fc` over a window's taps, at window position (`ka`, `kb`) of weight
/// `weight(tx, ka) weight(ty, kb)` (none where either is `None`), those outside `mask` in the whole window only.
fn window_moments(fc: &Field, ty: &Taps, tx: &Taps, mask: u16, weight: impl Fn(&Taps, usize) -> Option<f64>) -> Moments {
    let mut m = Moments::default();
    for kb in (0..4).filter(|&kb| ty.plane[kb] != 0.0) {
        let row = (ty.cell + kb - 1) * fc.width;
        let Some(wy) = weight(ty, kb) else { continue };
        for ka in (0..4).filter(|&ka| tx.plane[ka] != 0.0) {
            let c = row + tx.cell + ka - 1;
            let Some(wx) = weight(tx, ka) else { continue };
            let f = (mask & (1 << (4 * kb + ka)) != 0).then(|| [fc.dx[c] as f64, fc.dy[c] as f64]);
            m.add(wx * wy, tx.plane[ka] * ty.plane[kb], [ka as f64, kb as f64], f);
        }
    }
    m
}

/// Sums over a window's taps: the whole window's weights and centre; the allowed taps' weights, values and centre,
/// and their moments weighted by `|w|` for a least-squares plane through them.
#[derive(Default)]
struct Moments { whole: [f64; 3], allowed: [f64; 5], plane: [f64; 12] }

impl Moments {
    /// A tap of weight `w` (`pw` in the plane's fit) at window position `at`, with its value `f` where it is allowed.
    fn add(&mut self, w: f64, pw: f64, [x, y]: [f64; 2], f: Option<[f64; 2]>) {
        self.whole = [self.whole[0] + w, self.whole[1] + w * x, self.whole[2] + w * y];
        let Some([fx, fy]) = f else { return };
        self.allowed.iter_mut().zip([w, w * fx, w * fy, w * x, w * y]).for_each(|(s, v)| *s += v);
        self.plane.iter_mut().zip([1.0, x, y, x * x, x * y, y * y, fx, x * fx, y * fx, fy, x * fy, y * fy]).for_each(|(s, v)| *s += pw * v);
    }

    /// The allowed taps' renormalised value where their weights sum to `least` or more, less the gradient of the
    /// least-squares plane `p` (the cubic window's) times the shift of their centre from the whole window's: an
    /// affine field's value, as a whole window gives.
    fn value(&self, least: f64, p: &[f64; 12]) -> Option<[f32; 2]> {
        let [sum, fx, fy, x, y] = self.allowed;
        if sum < least { return None; }
        let shift = [x / sum - self.whole[1] / self.whole[0], y / sum - self.whole[2] / self.whole[0]];
        let (mx, my) = (p[1] / p[0], p[2] / p[0]);
        let (cxx, cxy, cyy) = (p[3] / p[0] - mx * mx, p[4] / p[0] - mx * my, p[5] / p[0] - my * my);
        // The gradient along the taps' line where they lie on one (a ridge far below a cell's spread); none for one tap.
        let ridge = 1e-9 * (cxx + cyy);
        let det = (cxx + ridge) * (cyy + ridge) - cxy * cxy;
        let value = |f: f64, k: usize| if shift == [0.0; 2] || ridge < 1e-20 { f / sum } else {
            let b = [p[k + 1] / p[0] - mx * p[k] / p[0], p[k + 2] / p[0] - my * p[k] / p[0]];
            let g = [((cyy + ridge) * b[0] - cxy * b[1]) / det, ((cxx + ridge) * b[1] - cxy * b[0]) / det];
            f / sum - g[0] * shift[0] - g[1] * shift[1]
        };
        Some([value(fx, 6) as f32, value(fy, 9) as f32])
    }
}

/// The fine field from the coarse one (see the module docs) by `plan`, built for `grid`.
fn upsample(grid: &Grid, plan: &Upsampling, fc: &Field, samples: &[Sample]) -> Field {
    let Upsampling { layout, cols, rows, masks } = plan;
    let (w, h, wc, cw) = (layout.w, layout.h, layout.wc, layout.cells().0);
    // Each column's used weights from its first tap on (zero past the last).
    let flat: Vec<[f64; 4]> = cols.iter().map(|t| {
        let mut w = [0.0; 4];
        (0..t.len).for_each(|a| w[t.at[a] - t.at[0]] = t.weights[t.slot[a] as usize]);
        w
    }).collect();
    // The cells with masks in each row of cells, and each cell's pixels along x.
    let masked: Vec<Vec<usize>> = masks.chunks(cw).map(|row| (0..cw).filter(|&cx| !row[cx].is_empty()).collect()).collect();
    let mut cell_x = vec![(usize::MAX, 0); cw];
    cols.iter().enumerate().for_each(|(x, t)| cell_x[t.cell] = (cell_x[t.cell].0.min(x), x + 1));
    // Pixels using their whole window take the cubic in y once per coarse column (`along[c]`), then in x.
    let upsample_row = |y: usize, dx: &mut [f32], dy: &mut [f32], resolved: &mut [bool], along: &mut Vec<[f64; 2]>| -> usize {
        let (ty, active) = (&rows[y], &grid.active[y * w..(y + 1) * w]);
        along.clear();
        along.resize(wc + 3, [0.0; 2]);
        for b in 0..ty.len {
            let (wyb, row) = (ty.weights[ty.slot[b] as usize], ty.at[b] * wc);
            for (c, v) in along[..wc].iter_mut().enumerate() {
                v[0] += wyb * fc.dx[row + c] as f64;
                v[1] += wyb * fc.dy[row + c] as f64;
            }
        }
        // Every active pixel as if its whole window were usable ...
        for x in (0..w).filter(|&x| active[x]) {
            let (wx, v) = (flat[x], &along[cols[x].at[0]..cols[x].at[0] + 4]);
            dx[x] = (wx[0] * v[0][0] + wx[1] * v[1][0] + wx[2] * v[2][0] + wx[3] * v[3][0]) as f32;
            dy[x] = (wx[0] * v[0][1] + wx[1] * v[1][1] + wx[2] * v[2][1] + wx[3] * v[3][1]) as f32;
            resolved[x] = true;
        }
        // ... then the pixels of windows with a missing link: the taps each reaches inside its window.
        for &cx in &masked[ty.cell] {
            for x in cell_x[cx].0..cell_x[cx].1 {
                let mask = plan.mask(x, y);
                if active[x] && mask != ALL_TAPS {
                    (dx[x], dy[x], resolved[x]) = window_value(fc, ty, &cols[x], mask).map_or((0.0, 0.0, false), |[vx, vy]| (vx, vy, true));
                }
            }
        }
        // The active pixels left unresolved.
        active.iter().zip(&*resolved).filter(|(&a, &r)| a && !r).count()
    };

    let (mut field, mut resolved) = (Field::zeros(w, h), vec![false; w * h]);
    let chunks = field.dx.par_chunks_mut(w).zip(field.dy.par_chunks_mut(w)).zip(resolved.par_chunks_mut(w)).enumerate();
    let unresolved: usize = chunks.map_init(Vec::new, |along, (y, ((dx, dy), r))| upsample_row(y, dx, dy, r, along)).sum();
    if unresolved == 0 { return field; }
    // Pixels left over: nearest resolved value along the links, breadth first from the resolved pixels
    // next to an unresolved one (the only ones that spread), in index order.
    let pending = (0..w * h).filter(|&i| grid.active[i] && !resolved[i]);
    let mut seeds: Vec<usize> = pending.flat_map(|i| grid.linked(i).into_iter().filter(|&j| j != usize::MAX && resolved[j])).collect();
    seeds.sort_unstable();
    seeds.dedup();
    let mut queue = VecDeque::from(seeds);
    while let Some(i) = queue.pop_front() {
        for j in grid.linked(i) {
            if j != usize::MAX && !resolved[j] {
                resolved[j] = true;
                (field.dx[j], field.dy[j]) = (field.dx[i], field.dy[i]);
                queue.push_back(j);
            }
        }
    }
    // Pieces without a coarse node: their samples' mean displacement, else zero (labelled only here: rare).
    if (0..w * h).any(|i| grid.active[i] && !resolved[i]) {
        let (labels, count) = grid.pieces();
        let mean = piece_means(grid, &labels, count, samples);
        for i in (0..w * h).filter(|&i| grid.active[i] && !resolved[i]) {
            if let Some([mx, my]) = mean[labels[i] as usize] {
                (field.dx[i], field.dy[i]) = (mx, my);
            }
        }
    }
    field
}

/// Per piece: its samples' mean displacement, if it has any.
fn piece_means(grid: &Grid, labels: &[u32], count: usize, samples: &[Sample]) -> Vec<Option<[f32; 2]>> {
    let mut sum = vec![[0.0f64; 3]; count];
    for smp in samples {
        let Some((x, y)) = nearest_node(grid, smp.rest) else { continue };
        let l = labels[grid.index(x, y)];
        if l != u32::MAX {
            let m = &mut sum[l as usize];
            *m = [m[0] + smp.displacement[0], m[1] + smp.displacement[1], m[2] + 1.0];
        }
    }
    sum.iter().map(|m| (m[2] > 0.0).then(|| [(m[0] / m[2]) as f32, (m[1] / m[2]) as f32])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::tests::{sequence, torn_grid};
    use crate::solve::solve;

    /// How often each way of filling a pixel was taken by [`upsample_per_pixel`].
    #[derive(Debug, Default)]
    struct Paths {
        cubic: usize,
        bilinear: usize,
        along_links: usize,
        piece_mean: usize,
    }

    /// Which coarse nodes of its window a pixel may use.
    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Rule {
        /// Those it reaches through links inside the window's block of pixels (the rule).
        Local,
        /// Those in its connected piece (the earlier rule, which lets a pixel take values
        /// from across a cut with free ends).
        Piece,
    }

    /// The pixels that `from` reaches through links without leaving the block
    /// `x0..=x1 × y0..=y1` (a breadth-first search of its own), as flags over the block.
    fn reached(grid: &Grid, from: (usize, usize), block: [usize; 4]) -> impl Fn(usize, usize) -> bool {
        let [x0, x1, y0, y1] = block;
        let (w, bw) = (grid.width, x1 - x0 + 1);
        let mut seen = vec![false; bw * (y1 - y0 + 1)];
        let at = move |(x, y): (usize, usize)| (y - y0) * bw + (x - x0);
        seen[at(from)] = true;
        let mut queue = VecDeque::from([from]);
        while let Some((x, y)) = queue.pop_front() {
            let i = y * w + x;
            let mut next = Vec::new();
            if x < x1 && grid.link_right[i] {
                next.push((x + 1, y));
            }
            if x > x0 && grid.link_right[i - 1] {
                next.push((x - 1, y));
            }
            if y < y1 && grid.link_down[i] {
                next.push((x, y + 1));
            }
            if y > y0 && grid.link_down[i - w] {
                next.push((x, y - 1));
            }
            for p in next {
                if !seen[at(p)] {
                    seen[at(p)] = true;
                    queue.push_back(p);
                }
            }
        }
        move |x, y| seen[at((x, y))]
    }

    /// The straightforward upsampling, pixel by pixel, that [`upsample`] must reproduce to
    /// `f32` rounding (with [`Rule::Local`]): the taps computed for every pixel, every tap tested
    /// by the rule, the bilinear fallback accumulated alongside, the fill along links
    /// started from every resolved pixel.
    fn upsample_per_pixel(grid: &Grid, s: usize, fc: &Field, samples: &[Sample], rule: Rule) -> (Field, Paths) {
        let (w, h) = (grid.width, grid.height);
        let layout = Layout::new(w, h, s);
        let (wc, hc) = (layout.wc, layout.hc);
        let (px, py) = (|x| layout.px(x), |y| layout.py(y));
        let (_, _, [coarse_active, ..]) = coarse_links(w, h, s, &grid.active, &grid.link_right, &grid.link_down);
        let mut paths = Paths::default();
        let (labels, count) = grid.pieces();
        let clabel: Vec<u32> = (0..wc * hc)
            .map(|c| if coarse_active[c] { labels[grid.index(px(c % wc), py(c / wc))] } else { u32::MAX })
            .collect();
        let taps = |x: usize, n: usize, pos: &dyn Fn(usize) -> usize| -> (isize, [f64; 4], f64, [f64; 4], f64) {
            if n == 1 {
                return (-1, [0.0, 1.0, 0.0, 0.0], 0.0, [0.0, 1.0, 0.0, 0.0], 0.0);
            }
            let x0 = (x / s).min(n - 2);
            let (a, b) = (pos(x0) as f64, pos(x0 + 1) as f64);
            let t = ((x as f64 - a) / (b - a)).clamp(0.0, 1.0);
            let inside = (1.0 / s as f64).min(0.5);
            let near = t.clamp(inside, 1.0 - inside);
            let plane = catmull_rom(near, x0 == 0, x0 + 2 == n);
            (x0 as isize - 1, catmull_rom(t, x0 == 0, x0 + 2 == n), t, plane.map(f64::abs), near)
        };
        let lin = |t: f64, k: usize| if k == 1 { 1.0 - t } else { t };
        let mut field = Field::zeros(w, h);
        let mut resolved = vec![false; w * h];
        for y in 0..h {
            let (ys, wy, ty, qy, ny) = taps(y, hc, &py);
            for x in 0..w {
                let i = y * w + x;
                if !grid.active[i] {
                    continue;
                }
                let (xs, wx, tx, qx, nx) = taps(x, wc, &px);
                let local = (rule == Rule::Local).then(|| {
                    let clip = |lo: isize, n: usize, pos: &dyn Fn(usize) -> usize| {
                        (pos(lo.max(0) as usize), pos(((lo + 3) as usize).min(n - 1)))
                    };
                    let ((x0, x1), (y0, y1)) = (clip(xs, wc, &px), clip(ys, hc, &py));
                    reached(grid, (x, y), [x0, x1, y0, y1])
                });
                let (mut cubic, mut inner, mut near) = (Moments::default(), Moments::default(), Moments::default());
                for (b, &wyb) in wy.iter().enumerate() {
                    let cy = ys + b as isize;
                    if cy < 0 || cy >= hc as isize || (wyb == 0.0 && qy[b] == 0.0) {
                        continue;
                    }
                    for (a, &wxa) in wx.iter().enumerate() {
                        let cx = xs + a as isize;
                        if cx < 0 || cx >= wc as isize || (wxa == 0.0 && qx[a] == 0.0) {
                            continue;
                        }
                        let c = cy as usize * wc + cx as usize;
                        let usable = match rule {
                            Rule::Piece => clabel[c] == labels[i],
                            Rule::Local => {
                                coarse_active[c] && local.as_ref().is_some_and(|r| r(px(cx as usize), py(cy as usize)))
                            }
                        };
                        let f = usable.then(|| [fc.dx[c] as f64, fc.dy[c] as f64]);
                        cubic.add(wxa * wyb, qx[a] * qy[b], [a as f64, b as f64], f);
                        if (1..3).contains(&a) && (1..3).contains(&b) {
                            inner.add(lin(tx, a) * lin(ty, b), 0.0, [a as f64, b as f64], f);
                            near.add(lin(nx, a) * lin(ny, b), 0.0, [a as f64, b as f64], f);
                        }
                    }
                }
                if let Some([vx, vy]) = cubic.value(0.5, &cubic.plane) {
                    (field.dx[i], field.dy[i], resolved[i]) = (vx, vy, true);
                    paths.cubic += 1;
                } else if let Some([vx, vy]) = inner.value(1e-9, &cubic.plane) {
                    (field.dx[i], field.dy[i], resolved[i]) = (vx, vy, true);
                    paths.bilinear += 1;
                } else if let Some([vx, vy]) = (Moments { whole: [1.0, 1.0 + tx, 1.0 + ty], ..near })
                    .value(1e-9, &cubic.plane)
                    .filter(|_| (nx, ny) != (tx, ty))
                {
                    (field.dx[i], field.dy[i], resolved[i]) = (vx, vy, true);
                    paths.bilinear += 1;
                }
            }
        }
        let mut queue: VecDeque<usize> = (0..w * h).filter(|&i| resolved[i]).collect();
        while let Some(i) = queue.pop_front() {
            for j in grid.linked(i) {
                if j != usize::MAX && !resolved[j] {
                    resolved[j] = true;
                    field.dx[j] = field.dx[i];
                    field.dy[j] = field.dy[i];
                    queue.push_back(j);
                    paths.along_links += 1;
                }
            }
        }
        let mean = piece_means(grid, &labels, count, samples);
        for i in 0..w * h {
            if grid.active[i] && !resolved[i] {
                if let Some([mx, my]) = mean[labels[i] as usize] {
                    (field.dx[i], field.dy[i]) = (mx, my);
                    paths.piece_mean += 1;
                }
            }
        }
        (field, paths)
    }

    /// A `w × h` grid with random holes (a share `holes` of the nodes) and broken links,
    /// a coarse field of random values for step `s`, and a few samples.
    fn case(w: usize, h: usize, s: usize, holes: f64, breaks: f64, seed: u64) -> (Grid, Field, Vec<Sample>) {
        let mut rnd = sequence(seed);
        let grid = torn_grid(w, h, holes, breaks, &mut rnd);
        let layout = Layout::new(w, h, s);
        let n = layout.wc * layout.hc;
        let fc = Field {
            width: layout.wc,
            height: layout.hc,
            dx: (0..n).map(|_| (rnd() * 20.0 - 10.0) as f32).collect(),
            dy: (0..n).map(|_| (rnd() * 20.0 - 10.0) as f32).collect(),
        };
        let samples = (0..6)
            .map(|_| Sample {
                rest: [rnd() * w as f64 - 0.5, rnd() * h as f64 - 0.5],
                displacement: [rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0],
            })
            .collect();
        (grid, fc, samples)
    }

    /// The same field up to the rounding of the sums' order (the pixels with a whole window
    /// sum the cubic in y first, then in x): every value within a few units in the last
    /// place of `f32`, and a zero (inactive, unresolved) exactly where the other has one.
    fn assert_same_values(a: &Field, b: &Field, what: &str) {
        for (u, v) in a.dx.iter().zip(&b.dx).chain(a.dy.iter().zip(&b.dy)) {
            let close = (u - v).abs() <= 4.0 * f32::EPSILON * u.abs().max(v.abs()).max(1.0);
            assert!(close && (*u == 0.0) == (*v == 0.0) || u == v, "{what}: {u} against {v}");
        }
    }

    #[test]
    fn upsampling_reproduces_the_per_pixel_loop() {
        let mut total = Paths::default();
        let mut seed = 1;
        for s in 2..7 {
            for (w, h) in [(1, 9), (9, 1), (5, 5), (17, 13), (24, 31), (40, 7)] {
                for (holes, breaks) in [(0.0, 0.0), (0.0, 0.08), (0.15, 0.0), (0.35, 0.1), (0.6, 0.3)] {
                    seed += 1;
                    let (grid, fc, samples) = case(w, h, s, holes, breaks, seed);
                    let (expected, paths) = upsample_per_pixel(&grid, s, &fc, &samples, Rule::Local);
                    let got = upsample(&grid, &Upsampling::new(&grid, s), &fc, &samples);
                    assert_same_values(&got, &expected, &format!("{w}×{h}, s = {s}, holes {holes}, breaks {breaks}"));
                    total.cubic += paths.cubic;
                    total.bilinear += paths.bilinear;
                    total.along_links += paths.along_links;
                    total.piece_mean += paths.piece_mean;
                }
            }
        }
        // Every way of filling a pixel was exercised.
        assert!(
            total.cubic > 0 && total.bilinear > 0 && total.along_links > 0 && total.piece_mean > 0,
            "{total:?}"
        );
    }

    #[test]
    fn windows_cut_short_by_tears_keep_affine_fields_affine() {
        // A turned piece's field is affine; a pixel whose window lost taps to a hole or a broken link gives it
        // exactly all the same (renormalised alone, such pixels were up to 3.6 px off at step 4).
        let mut seed = 40;
        let mut cut_short = 0;
        for s in [2, 3, 4] {
            for (holes, breaks) in [(0.15, 0.0), (0.35, 0.1), (0.6, 0.3)] {
                seed += 1;
                let (w, h) = (8 * s + 1, 6 * s + 1);
                let (grid, mut fc, _) = case(w, h, s, holes, breaks, seed);
                let turn = |x: f64, y: f64| [-0.5 * x - 0.87 * y + 3.0, 0.87 * x - 0.5 * y - 2.0];
                for c in 0..fc.dx.len() {
                    let v = turn(((c % fc.width) * s) as f64, ((c / fc.width) * s) as f64);
                    (fc.dx[c], fc.dy[c]) = (v[0] as f32, v[1] as f32);
                }
                let plan = Upsampling::new(&grid, s);
                for i in (0..grid.len()).filter(|&i| grid.active[i]) {
                    let Some(v) = plan.at(&grid, &fc, i) else { continue };
                    let want = turn((i % w) as f64, (i / w) as f64);
                    let (x, y) = (i % w, i / w);
                    let (tx, ty) = (&plan.cols[x], &plan.rows[y]);
                    let mask = plan.mask(x, y);
                    // (Where the taps it may use lie on one line, the slope across it is unknown.)
                    let used: Vec<[usize; 2]> = (0..ty.len).flat_map(|b| (0..tx.len).map(move |a| [tx.slot[a] as usize, ty.slot[b] as usize]))
                        .filter(|&[a, b]| mask & (1 << (4 * b + a)) != 0).collect();
                    let d = |u: [usize; 2], k: usize| u[k] as isize - used[0][k] as isize;
                    if used.iter().all(|&u| used.iter().all(|&q| d(u, 0) * d(q, 1) == d(u, 1) * d(q, 0))) { continue; }
                    assert!((v[0] - want[0] as f32).abs() < 1e-4 && (v[1] - want[1] as f32).abs() < 1e-4, "s = {s}, pixel {i}: {v:?} against {want:?} mask {mask:016b} tx {tx:?} ty {ty:?}");
                    cut_short += usize::from(mask != ALL_TAPS);
                }
            }
        }
        assert!(cut_short > 100, "{cut_short} pixels with windows cut short");
    }

    #[test]
    fn the_plan_gives_the_field_at_any_pixel() {
        // Every pixel of torn and open grids, serial and parallel sizes: the plan's value is
        // the full upsampling's wherever its window has a usable node (None elsewhere: the
        // full upsampling fills those along the links; some must occur).
        let mut seed = 900;
        let mut unresolved = 0;
        for s in [2, 3, 5, 8] {
            for (w, h) in [(1, 9), (9, 1), (5, 5), (24, 31), (40, 7), (301, 187)] {
                for (holes, breaks) in [(0.0, 0.0), (0.0, 0.08), (0.35, 0.1), (0.6, 0.3)] {
                    seed += 1;
                    let (grid, fc, samples) = case(w, h, s, holes, breaks, seed);
                    let plan = Upsampling::new(&grid, s);
                    let full = upsample(&grid, &plan, &fc, &samples);
                    let what = format!("{w}×{h}, s = {s}, holes {holes}, breaks {breaks}");
                    let mut got = Field::zeros(w, h);
                    for i in 0..w * h {
                        match plan.at(&grid, &fc, i) {
                            Some([x, y]) => (got.dx[i], got.dy[i]) = (x, y),
                            None => {
                                // Filled from a neighbour or a piece's mean: take the field's.
                                unresolved += 1;
                                (got.dx[i], got.dy[i]) = (full.dx[i], full.dy[i]);
                            }
                        }
                    }
                    assert_same_values(&got, &full, &what);
                }
            }
        }
        assert!(unresolved > 0, "no pixel took the fill");
    }

    #[test]
    fn drafts_at_chosen_pixels_follow_the_full_drafts() {
        // A few frames of a drag over a grid with a cut and a hole, at every fourth pixel:
        // each the full draft's values, and the histories alike (same cycles).
        let (w, h, s) = (97, 75, 4);
        // A round hole of radius 6 around (70, 40).
        let outside = |i: usize| ((i % w) as i64 - 70).pow(2) + ((i / w) as i64 - 40).pow(2) >= 36;
        let mut grid = Grid::from_active(w, h, (0..w * h).map(outside).collect());
        grid.add_cut(&[[40.5, 10.0], [40.5, 60.0]]);
        let plan = Upsampling::new(&grid, s);
        let pixels: Vec<u32> = (0..grid.len() as u32).step_by(4).collect();
        let options = SolveOptions { grid_step: s, ..Default::default() };
        let (mut full_solver, mut sparse_solver) = (Solver::new(), Solver::new());
        for frame in 0..5 {
            let t = frame as f64;
            let samples: Vec<Sample> = [(20.0, 30.0), (60.0, 30.0), (85.0, 10.0), (10.0, 70.0), (30.0, 50.0)]
                .iter()
                .enumerate()
                .map(|(k, &(x, y))| Sample { rest: [x, y], displacement: [t * (k as f64 - 2.0), 0.5 * t] })
                .collect();
            let (field, full) = full_solver.solve_warm(&grid, &samples, &options, None).unwrap();
            let mut out = vec![0.0f32; 2 * pixels.len()];
            let sparse = sparse_solver.solve_warm_at(&grid, &samples, &options, &plan, &pixels, &mut out).unwrap();
            assert_eq!(sparse.cycles, full.cycles, "frame {frame}");
            let mut got = Field::zeros(w, h);
            let mut want = Field::zeros(w, h);
            for (k, &p) in pixels.iter().enumerate() {
                (got.dx[p as usize], got.dy[p as usize]) = (out[2 * k], out[2 * k + 1]);
                (want.dx[p as usize], want.dy[p as usize]) = (field.dx[p as usize], field.dy[p as usize]);
            }
            assert_same_values(&got, &want, &format!("frame {frame}"));
        }
        // A plan for another step is refused.
        let other = SolveOptions { grid_step: 8, ..Default::default() };
        let mut out = vec![0.0f32; 2 * pixels.len()];
        let err = Solver::new().solve_warm_at(&grid, &[], &other, &plan, &pixels, &mut out).unwrap_err();
        assert_eq!(err, SolveError::PlanMismatch);
        let err = Solver::new().solve_warm_at(&grid, &[], &options, &plan, &[w as u32 * h as u32], &mut [0.0; 2]).unwrap_err();
        assert_eq!(err, SolveError::BadPixels);
    }

    #[test]
    fn rows_in_parallel_give_the_same_field() {
        // Many rows over the threads, with holes, a cut and a slot thinner than a coarse cell.
        let (w, h, s) = (301, 187, 8);
        let (mut grid, fc, samples) = case(w, h, s, 0.02, 0.01, 99);
        grid.add_cut(&[[150.5, 10.0], [150.5, 170.0]]);
        for x in 40..200 {
            let i = 90 * w + x;
            grid.active[i] = false;
            grid.link_down[i - w] = false;
            grid.link_down[i] = false;
            grid.link_right[i] = false;
            grid.link_right[i - 1] = false;
        }
        assert!(grid.is_consistent());
        let (expected, _) = upsample_per_pixel(&grid, s, &fc, &samples, Rule::Local);
        assert_same_values(&upsample(&grid, &Upsampling::new(&grid, s), &fc, &samples), &expected, "301×187");
    }

    #[test]
    fn a_one_pixel_wide_strip_interpolates_along_its_length() {
        // One coarse column: its values hold across the strip (they used to be replaced by
        // the mean of the samples).
        let grid = Grid::new(1, 33);
        let s = |y: f64, d: f64| Sample { rest: [0.0, y], displacement: [d, 0.0] };
        let options = SolveOptions { grid_step: 4, ..Default::default() };
        let (field, _) = solve(&grid, &[s(0.0, 0.0), s(32.0, 8.0)], &options, None).unwrap();
        assert_eq!(field.dx[0], 0.0);
        assert_eq!(field.dx[32], 8.0);
        assert!((field.dx[16] - 4.0).abs() < 0.05, "middle: {}", field.dx[16]);
    }

    #[test]
    fn open_grids_upsample_as_before() {
        // Without a missing link every pixel may use its whole window, as under the earlier
        // piece rule: the same values (the earlier code was held to that loop bit for bit),
        // from the serial and the parallel rows alike.
        let mut seed = 500;
        for s in [2, 3, 4, 5, 8, 13] {
            for (w, h) in [(1, 9), (9, 1), (2, 2), (5, 5), (17, 13), (24, 31), (40, 7), (97, 65), (257, 131)] {
                seed += 1;
                let (grid, fc, samples) = case(w, h, s, 0.0, 0.0, seed);
                let (expected, paths) = upsample_per_pixel(&grid, s, &fc, &samples, Rule::Piece);
                assert_eq!(paths.along_links + paths.piece_mean, 0);
                let got = upsample(&grid, &Upsampling::new(&grid, s), &fc, &samples);
                assert_same_values(&got, &expected, &format!("open {w}×{h}, s = {s}"));
            }
        }
    }

    #[test]
    fn a_strand_thinner_than_the_step_moves_with_what_it_hangs_from() {
        // A 1 px diagonal staircase of hair off a held block: on the coarse grid at step 4
        // its nodes are cut off from the block (no straight path links them), and held by
        // nothing they stood still while the block moved 10 px right.
        let (w, h) = (80, 60);
        let mut active = vec![false; w * h];
        (10..50).for_each(|y| (5..30).for_each(|x| active[y * w + x] = true));
        for k in 0..25 {
            let (x, y) = (30 + k, 42 - k); // through coarse nodes (32, 40), (36, 36), …
            active[y * w + x] = true;
            active[(y - 1) * w + x] = true;
        }
        let grid = Grid::from_active(w, h, active);
        assert_eq!(grid.pieces().1, 1);
        let samples: Vec<Sample> = [(8.0, 12.0), (26.0, 12.0), (8.0, 46.0), (26.0, 46.0)]
            .iter().map(|&(x, y)| Sample { rest: [x, y], displacement: [10.0, 0.0] }).collect();
        let (full, _) = solve(&grid, &samples, &SolveOptions::default(), None).unwrap();
        let (coarse, report) = solve(&grid, &samples, &SolveOptions { grid_step: 4, ..Default::default() }, None).unwrap();
        assert!(report.converged, "{report:?}");
        for k in 0..25 {
            let i = (42 - k) * w + 30 + k;
            assert!((full.dx[i] - 10.0).abs() < 0.01, "step 1 at strand pixel {k}: {}", full.dx[i]);
            assert!((coarse.dx[i] - 10.0).abs() < 0.5, "step 4 at strand pixel {k}: {}", coarse.dx[i]);
        }
    }

    #[test]
    fn a_cut_with_free_ends_opens_at_a_coarse_step() {
        // A vertical cut through the middle that ends inside the grid (one piece), the
        // right side pulled down 10 px next to it, the left side held. Along the cut the
        // two sides move apart as in the full-resolution solve; the earlier piece rule
        // blended them (at step 4 the right side moved 2.4 px of the 10 it does at step 1).
        let n = 97;
        let mut grid = Grid::new(n, n);
        grid.add_cut(&[[48.5, 16.0], [48.5, 80.0]]);
        assert_eq!(grid.pieces().1, 1);
        let mut samples = Vec::new();
        for y in 36..=60 {
            samples.push(Sample { rest: [54.0, y as f64], displacement: [0.0, 10.0] });
            samples.push(Sample { rest: [42.0, y as f64], displacement: [0.0, 0.0] });
        }
        for (x, y) in [(4.0, 4.0), (92.0, 4.0), (4.0, 92.0), (92.0, 92.0)] {
            samples.push(Sample { rest: [x, y], displacement: [0.0, 0.0] });
        }
        // Mean vertical displacement just left (x = 48) and just right (x = 49) of the cut.
        let sides = |field: &Field| {
            let mean = |x: usize| (30..=66).map(|y| field.dy[y * n + x] as f64).sum::<f64>() / 37.0;
            (mean(48), mean(49))
        };
        let solve_at = |s: usize| solve(&grid, &samples, &SolveOptions { grid_step: s, ..Default::default() }, None).unwrap().0;
        let (left1, right1) = sides(&solve_at(1));
        assert!(left1.abs() < 1.5 && right1 > 9.0, "grid_step 1: left {left1}, right {right1}");
        for s in [4, 8] {
            let (left, right) = sides(&solve_at(s));
            eprintln!("grid_step {s}: left {left:.3}, right {right:.3} (grid_step 1: {left1:.3}, {right1:.3})");
            // Each side within 1 px (a tenth of the pull) of the full-resolution solve.
            assert!((left - left1).abs() < 1.0, "grid_step {s}: left of the cut {left}, full resolution {left1}");
            assert!((right - right1).abs() < 1.0, "grid_step {s}: right of the cut {right}, full resolution {right1}");
        }
    }
}

//! Exact solves on the thin parts of a piece: strands, teeth, slivers between cuts.
//!
//! A part a few pixels wide bends almost freely and the coarse levels (nodes 2ᵏ pixels apart) miss it: its
//! bending is a slow mode of every cycle. Nearly one-dimensional, its system is cheap to solve exactly, so
//! the preconditioner solves every connected set of *thin* nodes (a run of linked nodes along the row or the
//! column at most [`THIN`] long) with the rest held, before and after the cycle (block symmetric Gauss–Seidel).
//! Each set is ordered by reverse Cuthill–McKee and factored as `L D Lᵀ` in its envelope, its diagonal raised
//! by [`SHIFT`] (a straight strand's exactly); a vanishing pivot (a free function, at τ = 0) is dropped.

use super::level::{bit, Level, Operator, Real, V2, W2, WS};
use crate::grid::shorter_runs;

/// The longest run of linked nodes across a part that still makes it thin.
pub const THIN: usize = 16;

/// The most entries a node's row of a block's factor may hold on average.
const BAND: usize = 128;

/// The factors this large (entries) solve their two components on two threads.
const PAR_ENTRIES: usize = 1 << 16;

/// How many links a halved set's part reaches into its neighbours.
const OVERLAP: usize = 8;

/// The finest level's blocks not factored exactly are `A_SS + SHIFT · diag(A_SS)`: it bounds a compliant hair's
/// response to what the `f32` search direction can hold.
const SHIFT: f64 = 1e-8;

/// A pivot below this fraction of its diagonal entry is dropped (slivers' near-free functions: `docs/dev/ablation.md`).
const PIVOT: f64 = 1e-6;

/// A pivot below this fraction of its diagonal entry leaves a straight strand's exact factor for the shifted one
/// (a loose or very long strand, whose exact solve misled the stopping rule: `docs/dev/solver-correctness.md`).
const EXACT_PIVOT: f64 = 1e-9;

/// The `L D Lᵀ` factor of a symmetric matrix in its envelope: row `i` of `L` from column `first[i]`, at `at[i]`.
#[derive(Debug)]
pub(crate) struct Envelope {
    first: Vec<u32>,
    at: Vec<usize>,
    /// `L`'s rows (the diagonal slot left holding the matrix's entry) and `D⁻¹` (zero where a pivot was dropped).
    l: Vec<f64>,
    d_inv: Vec<f64>,
}

/// The thin nodes of a level, grouped in connected blocks with their factors.
#[derive(Debug)]
pub(crate) struct Strands {
    /// Padded indices, block by block, each in its elimination order.
    nodes: Vec<u32>,
    /// The operator's row of each node: `(q, a_pq)` from `at[i]` to `at[i + 1]`.
    taps: Vec<(u32, f64)>,
    at: Vec<usize>,
    blocks: Vec<Envelope>,
    /// The couplings `(i, j, a_ij)` of each node `i` to the nodes `j` of earlier blocks (a halved set's), by `i`.
    earlier: Vec<(u32, u32, f64)>,
    /// The finest level's first solve's correction (from [`Strands::before`] to [`Strands::after`]).
    first_pass: Vec<V2>,
    /// Whether a mesh of strands too wide a band to factor was left to the cycle. Halved instead (its parts
    /// overlapping by [`OVERLAP`] links, solved one after another: block Gauss–Seidel), it costs more than the
    /// cycles it saves unless they are many.
    pub wide: bool,
}

impl Strands {
    /// The thin nodes of `level`, or `None` when it has none; `halve`: meshes of strands too wide a band to
    /// factor whole are solved in parts ([`Strands::wide`]).
    pub fn new(level: &Level, halve: bool) -> Option<Strands> {
        let thin = thin_nodes_of(level);
        if !thin.contains(&true) { return None; }
        let sets = blocks_in_order(thin.len(), |p| thin[p], |p, out| level.taps(p, |q, _| if q != p && thin[q] { out.push(q) }));
        let fine = matches!(level.op, Operator::Fine { .. });
        let n = thin.len();
        let mut b = Builder { level, thin, fine, mark: vec![u32::MAX; n], last: vec![u32::MAX; if halve { n } else { 0 }], prev: Vec::new(), s: Strands { nodes: Vec::new(), taps: Vec::new(), at: vec![0], blocks: Vec::new(), earlier: Vec::new(), first_pass: Vec::new(), wide: false } };
        let mut todo: Vec<(Vec<u32>, bool)> = sets.into_iter().rev().map(|s| (s.into_iter().map(|p| p as u32).collect(), false)).collect();
        while let Some((ids, halved)) = todo.pop() {
            // A half overlaps its neighbours by [`OVERLAP`] links where its band allows.
            if halved {
                let wider = b.widened(&ids, OVERLAP);
                if b.keep(&wider) { continue; }
            }
            // A set too wide a band to factor is left to the cycle, but for a mesh of strands (holes wider than a
            // node; not a region riddled with pinholes, which the cycle serves well) halved where asked.
            if b.keep(&ids) || !(halved || fine && b.open_holes(&ids)) { continue; }
            if halve || halved {
                todo.extend(b.halves(&ids).into_iter().rev().map(|h| (h, true)));
            } else { b.s.wide = true }
        }
        (!b.s.nodes.is_empty() || b.s.wide).then_some(b.s)
    }

    /// Node `i`'s taps.
    fn row(&self, i: usize) -> &[(u32, f64)] { &self.taps[self.at[i]..self.at[i + 1]] }

    /// Before the finest level's cycle: solves the thin blocks on `r` (in order, each from the earlier ones'
    /// answers) and takes the correction's product out of the cycle's right-hand side `f` (`r` in `f32`).
    pub fn before(&mut self, level: &Level, r: &[V2], f: &mut [W2]) {
        self.first_pass.clear();
        self.first_pass.extend(self.nodes.iter().map(|&p| r[p as usize]));
        let (z, mut e, mut start) = (&mut self.first_pass, 0, 0);
        for b in &self.blocks {
            let end = start + b.d_inv.len();
            for &(i, j, a) in self.earlier[e..].iter().take_while(|c| (c.0 as usize) < end) {
                let zj = z[j as usize];
                z[i as usize] = [z[i as usize][0] - a * zj[0], z[i as usize][1] - a * zj[1]];
                e += 1;
            }
            b.solve(&mut z[start..end]);
            start = end;
        }
        for (i, z) in self.first_pass.iter().enumerate() {
            for &(q, a) in self.row(i).iter().filter(|&&(q, _)| level.inv_diag[q as usize] != 0.0) {
                f[q as usize][0] -= WS::of(a * z[0]);
                f[q as usize][1] -= WS::of(a * z[1]);
            }
        }
    }

    /// After the finest level's cycle: adds the first correction to its `x` and relaxes the blocks again, in
    /// reverse.
    pub fn after(&self, r: &[V2], x: &mut [W2]) {
        self.add(0, &self.first_pass, x);
        self.relax_from(|p| r[p], x);
    }

    /// One block relaxation of `A x = f` on a coarser level: `x_S += A_SS⁻¹ (f − A x)_S`.
    pub fn relax(&self, x: &mut [W2], f: &[W2]) {
        self.relax_from(|p| [f[p][0].get(), f[p][1].get()], x);
    }

    /// Each block `x_B += A_BB⁻¹ (b − A x)_B` in turn, the last first, `b(p)` the right-hand side at padded node `p`.
    fn relax_from(&self, b: impl Fn(usize) -> V2, x: &mut [W2]) {
        let (mut z, mut end) = (Vec::new(), self.nodes.len());
        for block in self.blocks.iter().rev() {
            let rows = end - block.d_inv.len()..end;
            end = rows.start;
            z.clear();
            z.extend(rows.clone().map(|i| {
                self.row(i).iter().fold(b(self.nodes[i] as usize), |s, &(q, a)| [s[0] - a * x[q as usize][0].get(), s[1] - a * x[q as usize][1].get()])
            }));
            block.solve(&mut z);
            self.add(rows.start, &z, x);
        }
    }

    /// `x_S += z` on the nodes from the `from`-th.
    fn add(&self, from: usize, z: &[V2], x: &mut [W2]) {
        for (&p, z) in self.nodes[from..].iter().zip(z) {
            let xp = &mut x[p as usize];
            *xp = [WS::of(xp[0].get() + z[0]), WS::of(xp[1].get() + z[1])];
        }
    }
}

/// [`Strands::new`]'s lists as they are made.
struct Builder<'a> {
    level: &'a Level,
    thin: Vec<bool>,
    fine: bool,
    /// A node's place in the set being tried (`u32::MAX` off it).
    mark: Vec<u32>,
    /// A node's last entry in the lists, and each entry's previous one of the same node (`u32::MAX`: none; empty
    /// where nothing is halved).
    last: Vec<u32>,
    prev: Vec<u32>,
    s: Strands,
}

impl Builder<'_> {
    /// Marks `ids` as the set tried, each by its place (`on`), or clears them.
    fn place(&mut self, ids: &[u32], on: bool) {
        ids.iter().enumerate().for_each(|(i, &p)| self.mark[p as usize] = if on { i as u32 } else { u32::MAX });
    }

    /// `ids`' nodes linked within the set tried (`same(p, q)`), in their places.
    fn links<'s>(&'s self, ids: &'s [u32], same: impl Fn(usize, usize) -> bool + 's) -> impl FnMut(usize, &mut Vec<usize>) + 's {
        move |i, out| {
            let p = ids[i] as usize;
            self.level.taps(p, |q, _| if q != p && self.mark[q] != u32::MAX && same(p, q) { out.push(self.mark[q] as usize) });
        }
    }

    /// Factors the set `ids` (an elimination order) and adds it to the lists, or `false` when its band is too wide.
    fn keep(&mut self, ids: &[u32]) -> bool {
        self.place(ids, true);
        let (level, wp) = (self.level, self.level.wp);
        let entries: Vec<_> = ids.iter().map(|&p| {
            let mut row = Vec::new();
            level.taps(p as usize, |q, a| if self.mark[q] != u32::MAX { row.push((self.mark[q] as usize, a)) });
            row
        }).collect();
        self.place(ids, false);
        // On the finest level a straight 1 px line is factored exactly (its pivots fall as its length cubed:
        // dropped or shifted, its slowest bending is left to the cycle); past [`EXACT_PIVOT`], shifted.
        let straight = ids.iter().all(|&p| p as usize % wp == ids[0] as usize % wp) || ids.iter().all(|&p| p as usize / wp == ids[0] as usize / wp);
        let max = BAND * ids.len();
        let exact = (self.fine && ids.len() > 1 && straight).then(|| Envelope::factor(&entries, 0.0, EXACT_PIVOT, max));
        let exact = exact.flatten().filter(|b| !b.dropped());
        let Some(block) = exact.or_else(|| Envelope::factor(&entries, if self.fine { SHIFT } else { 0.0 }, PIVOT, max)) else { return false };
        let s = &mut self.s;
        s.blocks.push(block);
        let base = s.nodes.len();
        for (i, &p) in ids.iter().enumerate() {
            level.taps(p as usize, |q, a| {
                s.taps.push((q as u32, a));
                let mut j = self.last.get(q).copied().unwrap_or(u32::MAX);
                while j != u32::MAX {
                    s.earlier.push(((base + i) as u32, j, a));
                    j = self.prev[j as usize];
                }
            });
            s.at.push(s.taps.len());
        }
        // (Only sets being halved can overlap.)
        let halving = !self.last.is_empty();
        for (i, &p) in ids.iter().enumerate().filter(|_| halving) {
            self.prev.push(self.last[p as usize]);
            self.last[p as usize] = (base + i) as u32;
        }
        s.nodes.extend(ids);
        true
    }

    /// Whether most holes beside `ids` (nodes across a side that are no unknowns) are wider than a node.
    fn open_holes(&self, ids: &[u32]) -> bool {
        let (d, wp) = (&self.level.inv_diag, self.level.wp);
        // Each side's next node `q` and the one past it, `r`.
        let sides = ids.iter().map(|&p| p as usize).flat_map(|p| [(p + 1, p + 2), (p - 1, p - 2), (p + wp, p + 2 * wp), (p - wp, p - 2 * wp)]);
        let (holes, open) = sides.filter(|&(q, _)| d[q] == 0.0).fold((0, 0), |(h, o), (_, r)| (h + 1, o + usize::from(d[r] == 0.0)));
        2 * open > holes
    }

    /// The connected parts of the halves of `ids` across the longer side of its box, each in its order.
    fn halves(&mut self, ids: &[u32]) -> Vec<Vec<u32>> {
        let wp = self.level.wp;
        let (mut lo, mut hi) = ([usize::MAX; 2], [0; 2]);
        for &p in ids {
            let c = [p as usize % wp, p as usize / wp];
            (0..2).for_each(|k| (lo[k], hi[k]) = (lo[k].min(c[k]), hi[k].max(c[k])));
        }
        let k = usize::from(hi[1] - lo[1] > hi[0] - lo[0]);
        let (mid, side) = ((lo[k] + hi[k]).div_ceil(2), move |p: usize| [p % wp, p / wp][k]);
        self.place(ids, true);
        let parts = blocks_in_order(ids.len(), |_| true, self.links(ids, |p, q| (side(q) >= mid) == (side(p) >= mid)));
        self.place(ids, false);
        parts.into_iter().map(|h| h.into_iter().map(|i| ids[i]).collect()).collect()
    }

    /// `ids` with the thin nodes `depth` links or fewer from it, in an elimination order.
    fn widened(&mut self, ids: &[u32], depth: usize) -> Vec<u32> {
        let mut all = ids.to_vec();
        self.place(&all, true);
        let mut from = 0;
        for _ in 0..depth {
            let to = all.len();
            for i in from..to {
                let p = all[i] as usize;
                self.level.taps(p, |q, _| if q != p && self.thin[q] && self.mark[q] == u32::MAX {
                    self.mark[q] = all.len() as u32;
                    all.push(q as u32);
                });
            }
            from = to;
        }
        let order = blocks_in_order(all.len(), |_| true, self.links(&all, |_, _| true));
        self.place(&all, false);
        order.into_iter().flatten().map(|i| all[i]).collect()
    }
}

/// The level's thin unknowns ([`thin_nodes`]) through its links: the operator's own on the finest level, the
/// geometry's between unknowns on coarser ones.
fn thin_nodes_of(level: &Level) -> Vec<bool> {
    match &level.op {
        Operator::Fine { flags, .. } => thin_nodes(level, |p, _| flags[p] & bit::RIGHT != 0, |p, _| flags[p] & bit::DOWN != 0),
        Operator::Stored { .. } => {
            let (g, d, wp) = (&level.geo, &level.inv_diag, level.wp);
            thin_nodes(level, |p, i| g.right[i] && d[p] != 0.0 && d[p + 1] != 0.0, |p, i| g.down[i] && d[p] != 0.0 && d[p + wp] != 0.0)
        }
    }
}

/// The thin nodes: the unknowns whose run of linked nodes along the row or the column is at most [`THIN`]
/// long, from `right(p, i)` and `down(p, i)` (padded and unpadded index: linked to the right, below).
fn thin_nodes(level: &Level, right: impl Fn(usize, usize) -> bool, down: impl Fn(usize, usize) -> bool) -> Vec<bool> {
    let (w, h) = (level.geo.w, level.geo.h);
    let runs = shorter_runs(w, h, |x, y| right(level.pidx(x, y), y * w + x), |x, y| down(level.pidx(x, y), y * w + x));
    let mut thin = vec![false; level.len_padded()];
    for (y, x) in (0..h).flat_map(|y| (0..w).map(move |x| (y, x))) {
        thin[level.pidx(x, y)] = level.inv_diag[level.pidx(x, y)] != 0.0 && runs[y * w + x] as usize <= THIN;
    }
    thin
}

/// The connected sets of the nodes `0..n` with `include` (`next(p, out)`: `p`'s neighbours, all included, pushed
/// to an empty `out`), each in reverse Cuthill–McKee order: breadth first from the last node of a breadth-first
/// search (a pseudo-peripheral one), reversed. Along a strand that keeps a factor's envelope narrow.
pub(crate) fn blocks_in_order(n: usize, include: impl Fn(usize) -> bool, mut next: impl FnMut(usize, &mut Vec<usize>)) -> Vec<Vec<usize>> {
    let mut bfs = |s: usize, seen: &mut [bool]| {
        let (mut order, mut buf, mut i) = (vec![s], Vec::new(), 0);
        seen[s] = true;
        while i < order.len() {
            next(order[i], &mut buf);
            order.extend(buf.drain(..).filter(|&q| !std::mem::replace(&mut seen[q], true)));
            i += 1;
        }
        order
    };
    let (mut seen, mut blocks) = (vec![false; n], Vec::new());
    for s in (0..n).filter(|&s| include(s)) {
        if seen[s] { continue; }
        let component = bfs(s, &mut seen);
        component.iter().for_each(|&p| seen[p] = false);
        let mut block = bfs(*component.last().expect("a search finds its start"), &mut seen);
        block.reverse();
        blocks.push(block);
    }
    blocks
}

impl Envelope {
    /// The factor of the matrix whose row `i` has the entries `entries[i]` (column, value; repeats add), its
    /// diagonal raised by `shift` times itself; a pivot not above `pivot` times its diagonal entry is
    /// dropped. `None` past `max_entries` entries.
    pub(crate) fn factor(entries: &[Vec<(usize, f64)>], shift: f64, pivot: f64, max_entries: usize) -> Option<Envelope> {
        let n = entries.len();
        let first: Vec<u32> = entries.iter().enumerate().map(|(i, e)| e.iter().map(|&(j, _)| j).min().unwrap_or(i).min(i) as u32).collect();
        let mut at = vec![0];
        for i in 0..n {
            at.push(at[i] + i + 1 - first[i] as usize);
        }
        if at[n] > max_entries { return None; }
        // Row i's entries up to the diagonal, which is summed in its slot (row i's last) and read out raised.
        let mut l = vec![0.0; at[n]];
        for (i, e) in entries.iter().enumerate() {
            e.iter().filter(|&&(j, _)| j <= i).for_each(|&(j, a)| l[at[i] + j - first[i] as usize] += a);
        }
        let diag: Vec<f64> = (0..n).map(|i| l[at[i + 1] - 1] * (1.0 + shift)).collect();
        let mut d_inv = vec![0.0; n];
        for i in 0..n {
            let fi = first[i] as usize;
            // g_ij = l_ij d_j, row i in place: g_ij = a_ij − Σ_k g_ik l_jk.
            for j in fi..i {
                let fj = first[j] as usize;
                let mut s = l[at[i] + j - fi];
                for k in fi.max(fj)..j {
                    s -= l[at[i] + k - fi] * l[at[j] + k - fj];
                }
                l[at[i] + j - fi] = s;
            }
            let mut di = diag[i];
            for j in fi..i {
                let g = l[at[i] + j - fi];
                let lij = g * d_inv[j];
                l[at[i] + j - fi] = lij;
                di -= g * lij;
            }
            d_inv[i] = if di > pivot * diag[i] { 1.0 / di } else { 0.0 };
        }
        Some(Envelope { first, at, l, d_inv })
    }

    /// Whether a pivot was dropped.
    pub(crate) fn dropped(&self) -> bool { self.d_inv.contains(&0.0) }

    /// `x = (L D Lᵀ)⁻¹ x`: a large factor's two components on two threads.
    pub(crate) fn solve(&self, x: &mut [V2]) {
        if self.l.len() < PAR_ENTRIES { return self.solve_lanes(x) }
        let (mut a, mut b): (Vec<[f64; 1]>, Vec<[f64; 1]>) = x.iter().map(|v| ([v[0]], [v[1]])).unzip();
        rayon::join(|| self.solve_lanes(&mut a), || self.solve_lanes(&mut b));
        x.iter_mut().zip(a.into_iter().zip(b)).for_each(|(x, (a, b))| *x = [a[0], b[0]]);
    }

    /// `x = (L D Lᵀ)⁻¹ x` for `C` components side by side (the same operations on each).
    fn solve_lanes<const C: usize>(&self, x: &mut [[f64; C]]) {
        for i in 0..x.len() {
            let fi = self.first[i] as usize;
            let mut s = x[i];
            for k in fi..i {
                let lik = self.l[self.at[i] + k - fi];
                (0..C).for_each(|c| s[c] -= lik * x[k][c]);
            }
            x[i] = s;
        }
        x.iter_mut().zip(&self.d_inv).for_each(|(x, &d)| x.iter_mut().for_each(|x| *x *= d));
        for i in (0..x.len()).rev() {
            let (fi, xi) = (self.first[i] as usize, x[i]);
            for k in fi..i {
                let lik = self.l[self.at[i] + k - fi];
                (0..C).for_each(|c| x[k][c] -= lik * xi[c]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{comb_grid, fine_level};
    use super::*;

    /// For each block of `s`: its size, and whether its solve answers the block's own system exactly and
    /// with the diagonal raised by [`SHIFT`].
    fn blocks_answer(level: &Level, s: &Strands) -> Vec<(usize, bool, bool)> {
        let rhs: Vec<V2> = (0..s.nodes.len()).map(|i| [(i % 7) as f64 - 3.0, (i % 5) as f64 * 0.5]).collect();
        let (mut z, mut start) = (rhs.clone(), 0);
        for b in &s.blocks {
            b.solve(&mut z[start..start + b.d_inv.len()]);
            start += b.d_inv.len();
        }
        let mut x = vec![[0.0; 2]; level.len_padded()];
        for (i, &p) in s.nodes.iter().enumerate() {
            x[p as usize] = z[i];
        }
        let mut start = 0;
        s.blocks.iter().map(|b| {
            let rows = start..start + b.d_inv.len();
            start = rows.end;
            let holds = |shift: f64| rows.clone().all(|i| {
                let p = s.nodes[i];
                // (Past the rounding of the row's sum: a compliant strand's answer is large.)
                let (mut ax, mut size) = ([0.0; 2], [0.0; 2]);
                for &(q, a) in s.row(i) {
                    let a = if q == p { a * (1.0 + shift) } else { a };
                    for k in 0..2 {
                        ax[k] += a * x[q as usize][k];
                        size[k] += (a * x[q as usize][k]).abs();
                    }
                }
                (0..2).all(|k| (ax[k] - rhs[i][k]).abs() < 1e-12 * size[k] + 1e-9 * (1.0 + rhs[i][k].abs()))
            });
            (b.d_inv.len(), holds(0.0), holds(SHIFT))
        }).collect()
    }

    /// An `n` × `n` grid of the nodes `keep(x, y)`, one in 97 fixed.
    fn matte_level(n: usize, keep: impl Fn(usize, usize) -> bool) -> Level {
        let grid = crate::grid::Grid::from_active(n, n, (0..n * n).map(|i| keep(i % n, i / n)).collect());
        fine_level(&grid, Some((0..n * n).map(|i| i * 31 % 97 == 0).collect()), 0.0)
    }

    #[test]
    fn a_mesh_of_strands_too_wide_a_band_is_halved_and_its_sweeps_converge() {
        // Diagonal strands 3 px wide 10 px apart, crossing: one thin set whose band is too wide, left to the
        // cycle, or, halved, solved in overlapping parts one after another; sweeps from zero (the rest held)
        // reach its own system's answer (to the rounding of `x` in `f32`, 5·10⁻⁴ of the start's residual after
        // 5 sweeps).
        let level = matte_level(600, |x, y| (x + y) % 10 < 3 || (x + 600 - y) % 10 < 3);
        let whole = Strands::new(&level, false).expect("the lines are thin");
        assert!(whole.wide && whole.blocks.is_empty(), "{} blocks", whole.blocks.len());
        let s = Strands::new(&level, true).expect("the lines are thin");
        assert!(!s.wide);
        assert!(s.blocks.len() > 2 && !s.earlier.is_empty(), "{} blocks", s.blocks.len());
        let mut on = vec![false; level.len_padded()];
        s.nodes.iter().for_each(|&p| on[p as usize] = true);
        assert!(s.nodes.len() > on.iter().filter(|&&o| o).count(), "the parts overlap");
        let f: Vec<W2> = (0..on.len()).map(|p| if on[p] { [WS::of((p % 7) as f64 - 3.0), WS::of((p % 5) as f64)] } else { [WS::of(0.0); 2] }).collect();
        let size = |x: &[W2]| {
            let mut r = vec![[WS::of(0.0); 2]; on.len()];
            level.residual(x, Some(&f), &mut r);
            (0..on.len()).filter(|&p| on[p]).map(|p| r[p][0].get().powi(2) + r[p][1].get().powi(2)).sum::<f64>().sqrt()
        };
        let mut x = vec![[WS::of(0.0); 2]; on.len()];
        let start = size(&x);
        (0..10).for_each(|_| s.relax(&mut x, &f));
        assert!(size(&x) < 2e-3 * start, "{} of {start}", size(&x));
    }

    #[test]
    fn a_region_riddled_with_pinholes_is_left_to_the_cycle() {
        let level = matte_level(300, |x, y| (x * 7 + y * 13) % 11 != 0);
        assert!(Strands::new(&level, true).is_none());
    }

    #[test]
    fn an_untorn_finest_level_wider_and_taller_than_thin_has_no_strands() {
        // `solve_piece` skips the search on such a level: it must find nothing there, with fixed nodes and tension
        // as with none; a side of `THIN` or less is all strand.
        let mut rnd = crate::grid::tests::sequence(29);
        for (w, h, tau) in [(THIN + 1, THIN + 1, 0.0), (THIN + 1, 90, 0.5), (70, THIN + 1, 0.0), (64, 48, 1e-3)] {
            for share in [0.0, 0.05, 0.6] {
                let fixed: Vec<bool> = (0..w * h).map(|_| rnd() < share).collect();
                assert!(Strands::new(&fine_level(&crate::grid::Grid::new(w, h), Some(fixed), tau), true).is_none(), "{w} × {h}, {share}");
            }
        }
        assert!(thin_nodes_of(&fine_level(&crate::grid::Grid::new(THIN, 40), None, 0.0)).iter().any(|&t| t));
    }

    #[test]
    fn the_blocks_solve_the_thin_nodes_own_system() {
        let grid = comb_grid(40, 30);
        let mut fixed = vec![false; grid.len()];
        for i in [grid.index(3, 1), grid.index(20, 3), grid.index(36, 0), grid.index(10, 34)] {
            fixed[i] = true;
        }
        let level = fine_level(&grid, Some(fixed), 0.0);
        let s = Strands::new(&level, false).expect("the teeth are thin");
        assert!(s.blocks.len() > 10 && s.blocks.iter().all(|b| b.d_inv.iter().all(|&d| d > 0.0)));
        // Each block answers its own system: the straight teeth exactly, the others shifted.
        let answers = blocks_answer(&level, &s);
        assert!(answers.iter().all(|&(_, exact, shifted)| exact || shifted), "{answers:?}");
        let teeth = || answers.iter().filter(|b| (29..=30).contains(&b.0));
        assert!(teeth().count() >= 18 && teeth().all(|b| b.1), "{answers:?}");
        // The bar's thin columns with their joints are no straight line: shifted, as before.
        let others = || answers.iter().filter(|b| b.0 > 30);
        assert!(others().count() >= 1 && others().all(|b| b.2 && !b.1), "{answers:?}");
    }

    #[test]
    fn teeth_too_compliant_for_an_exact_factor_are_shifted() {
        // Free straight 1 px teeth hanging from a bar: at 1,000 px factored exactly, at 2,600 px their pivots
        // fall past EXACT_PIVOT and the factor is the shifted one.
        for (len, exact_teeth) in [(1000, true), (2600, false)] {
            let grid = comb_grid(40, len);
            let mut fixed = vec![false; grid.len()];
            for i in [grid.index(3, 1), grid.index(20, 3), grid.index(36, 0)] {
                fixed[i] = true;
            }
            let level = fine_level(&grid, Some(fixed), 0.0);
            let s = Strands::new(&level, false).expect("the teeth are thin");
            let answers = blocks_answer(&level, &s);
            let teeth: Vec<_> = answers.iter().filter(|b| b.0 >= len).collect();
            assert_eq!(teeth.len(), 20, "{len}: {answers:?}");
            assert!(teeth.iter().all(|&&(_, exact, shifted)| if exact_teeth { exact } else { shifted && !exact }), "{len}: {teeth:?}");
            assert!(answers.iter().all(|b| b.1 || b.2), "{len}: {answers:?}");
        }
    }

    #[test]
    fn a_large_factor_solves_its_components_on_two_threads_as_it_does_both_side_by_side() {
        // A banded matrix with a factor past PAR_ENTRIES: its two components on two threads, bit for bit the
        // pair kernel's answer, which solves the system.
        let (n, band) = (2000usize, 40usize);
        let a = |i: usize, j: usize| if i == j { 4.0 * band as f64 } else { -1.0 - ((i * j) % 3) as f64 * 0.25 };
        let entries: Vec<Vec<(usize, f64)>> = (0..n).map(|i| (i.saturating_sub(band)..(i + band + 1).min(n)).map(|j| (j, a(i.min(j), i.max(j)))).collect()).collect();
        let factor = Envelope::factor(&entries, 0.0, PIVOT, usize::MAX).expect("no limit");
        assert!(factor.l.len() >= PAR_ENTRIES && !factor.dropped());
        let rhs: Vec<V2> = (0..n).map(|i| [(i % 7) as f64 - 3.0, (i % 5) as f64 * 0.5 + 1.0]).collect();
        let (mut threads, mut pairs) = (rhs.clone(), rhs.clone());
        factor.solve(&mut threads);
        factor.solve_lanes(&mut pairs);
        assert_eq!(threads, pairs);
        for (i, row) in entries.iter().enumerate() {
            let ax = row.iter().fold([0.0f64; 2], |s, &(j, v)| [s[0] + v * pairs[j][0], s[1] + v * pairs[j][1]]);
            assert!((0..2).all(|k| (ax[k] - rhs[i][k]).abs() < 1e-9), "row {i}: {ax:?} against {:?}", rhs[i]);
        }
    }
}

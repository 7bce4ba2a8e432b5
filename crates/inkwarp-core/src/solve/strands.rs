//! Exact solves on the thin parts of a piece: strands, teeth, slivers between cuts.
//!
//! A part a few pixels wide bends almost freely, and the geometric coarse levels, whose
//! nodes are 2ᵏ pixels apart, do not see it: its bending is a slow mode of every cycle, and
//! more of them, slower, the longer it is. Such parts are nearly one-dimensional, so their
//! own system is cheap to solve exactly: the preconditioner solves every connected set of
//! thin nodes with the rest held (a block of symmetric Gauss–Seidel), before and after the
//! cycle. The part then follows whatever the cycle does to what it hangs on, as the
//! minimiser would.
//!
//! A node is *thin* when its run of linked nodes along the row or along the column is at
//! most [`THIN`] long. Each connected set is ordered by reverse Cuthill–McKee and factored
//! as `L D Lᵀ` within its envelope; a pivot that vanishes (a set with a free function of
//! its own, at τ = 0) is dropped, which leaves that function to the cycle and the kernel
//! settlement.

use super::level::{bit, Level, Operator, Real, V2, W2, WS};

/// The longest run of linked nodes across a part that still makes it thin.
const THIN: usize = 16;

/// The most entries a node's row of a block's factor may hold on average.
const BAND: usize = 64;

/// A pivot below this fraction of its diagonal entry is dropped.
const PIVOT: f64 = 1e-8;

#[derive(Debug)]
struct Block {
    /// Range of the block's nodes in [`Strands::nodes`].
    start: usize,
    /// Per node (block order): first column of its envelope row, and where the row starts
    /// in `l`.
    first: Vec<u32>,
    at: Vec<usize>,
    /// `L`'s rows within the envelope (the diagonal slot unused) and `D⁻¹`.
    l: Vec<f64>,
    d_inv: Vec<f64>,
}

/// The thin nodes of a finest level, grouped in connected blocks with their factors.
#[derive(Debug)]
pub(crate) struct Strands {
    /// Padded indices, block by block, each in its elimination order.
    nodes: Vec<u32>,
    /// The operator's 5 × 5 stencil row of each node.
    rows: Vec<[f64; 25]>,
    blocks: Vec<Block>,
    /// Work: the first solve's correction and a right-hand side, per node.
    first_pass: Vec<V2>,
    rhs: Vec<V2>,
}

impl Strands {
    /// The thin nodes of `level` (the finest), or `None` when it has none.
    pub fn new(level: &Level) -> Option<Strands> {
        let Operator::Fine { flags, .. } = &level.op else { return None };
        let (w, h, wp) = (level.geo.w, level.geo.h, level.wp);
        let pidx = |x: usize, y: usize| level.pidx(x, y);
        // Run lengths along rows and columns (over active nodes joined by links).
        let mut across = vec![usize::MAX; wp * level.hp];
        for y in 0..h {
            let mut x = 0;
            while x < w {
                let mut e = x;
                while e + 1 < w && flags[pidx(e, y)] & bit::RIGHT != 0 {
                    e += 1;
                }
                for i in x..=e {
                    across[pidx(i, y)] = e - x + 1;
                }
                x = e + 1;
            }
        }
        for x in 0..w {
            let mut y = 0;
            while y < h {
                let mut e = y;
                while e + 1 < h && flags[pidx(x, e)] & bit::DOWN != 0 {
                    e += 1;
                }
                for i in y..=e {
                    let p = pidx(x, i);
                    across[p] = across[p].min(e - y + 1);
                }
                y = e + 1;
            }
        }
        let thin: Vec<bool> = (0..across.len()).map(|p| level.inv_diag.get(p).is_some_and(|&d| d != 0.0) && across[p] <= THIN).collect();
        if !thin.contains(&true) {
            return None;
        }
        let taps = |p: usize| -> [f64; 25] { level.row(p) };
        let off = |t: usize| -> isize { (t / 5) as isize * wp as isize + (t % 5) as isize - 2 * wp as isize - 2 };
        let neighbours = |p: usize, row: &[f64; 25], out: &mut Vec<usize>| {
            out.clear();
            for (t, &a) in row.iter().enumerate() {
                let q = (p as isize + off(t)) as usize;
                if a != 0.0 && q != p && thin[q] {
                    out.push(q);
                }
            }
        };
        let mut seen = vec![false; thin.len()];
        let mut nodes = Vec::new();
        let mut blocks = Vec::new();
        for s in 0..thin.len() {
            if !thin[s] || seen[s] {
                continue;
            }
            // The component, then a pseudo-peripheral start (the last node of a
            // breadth-first search from it) and the Cuthill–McKee order from there.
            let comp = bfs(s, &mut seen, |p, out| neighbours(p, &taps(p), out));
            for &p in &comp {
                seen[p] = false;
            }
            let far = *bfs(s, &mut seen, |p, out| neighbours(p, &taps(p), out)).last().unwrap();
            for &p in &comp {
                seen[p] = false;
            }
            let mut order = bfs(far, &mut seen, |p, out| neighbours(p, &taps(p), out));
            order.reverse();
            let start = nodes.len();
            nodes.extend(order.iter().map(|&p| p as u32));
            blocks.push(Block { start, first: Vec::new(), at: Vec::new(), l: Vec::new(), d_inv: Vec::new() });
        }
        let mut rows: Vec<[f64; 25]> = nodes.iter().map(|&p| taps(p as usize)).collect();
        let mut local = vec![u32::MAX; thin.len()];
        for (i, &p) in nodes.iter().enumerate() {
            local[p as usize] = i as u32;
        }
        let ends: Vec<usize> = blocks.iter().skip(1).map(|b| b.start).chain([nodes.len()]).collect();
        for (b, &end) in blocks.iter_mut().zip(&ends) {
            b.factor(&nodes, &rows, &local, end, &off);
        }
        // A set whose order is not a narrow band is two-dimensional (a region riddled
        // with pinholes, say), not a strand: the cycle serves it, and its factor would not
        // be cheap. Its nodes leave the lists.
        if blocks.iter().any(|b| b.l.is_empty() && !b.first.is_empty()) {
            let (mut kept_nodes, mut kept_rows, mut kept) = (Vec::new(), Vec::new(), Vec::new());
            for (mut b, &end) in blocks.into_iter().zip(&ends) {
                if b.l.is_empty() && !b.first.is_empty() {
                    continue;
                }
                let start = kept_nodes.len();
                kept_nodes.extend_from_slice(&nodes[b.start..end]);
                kept_rows.extend_from_slice(&rows[b.start..end]);
                b.start = start;
                kept.push(b);
            }
            (nodes, rows, blocks) = (kept_nodes, kept_rows, kept);
            if nodes.is_empty() {
                return None;
            }
        }
        let n = nodes.len();
        Some(Strands { nodes, rows, blocks, first_pass: vec![[0.0; 2]; n], rhs: vec![[0.0; 2]; n] })
    }

    /// Before the cycle: solves the thin blocks on `r` (the cycle's right-hand side `f`
    /// holds `r` in `f32`) and takes the correction's product out of `f`.
    pub fn before(&mut self, level: &Level, r: &[V2], f: &mut [W2]) {
        for (i, &p) in self.nodes.iter().enumerate() {
            self.rhs[i] = r[p as usize];
        }
        self.solve_blocks();
        let wp = level.wp;
        for (i, &p) in self.nodes.iter().enumerate() {
            let z = self.first_pass[i];
            for (t, &a) in self.rows[i].iter().enumerate() {
                if a == 0.0 {
                    continue;
                }
                let q = p as usize + (t / 5) * wp + t % 5 - 2 * wp - 2;
                if level.inv_diag[q] != 0.0 {
                    f[q][0] -= WS::of(a * z[0]);
                    f[q][1] -= WS::of(a * z[1]);
                }
            }
        }
    }

    /// After the cycle: adds the first correction to the cycle's `x` and solves the thin
    /// blocks again on the residual left.
    pub fn after(&mut self, level: &Level, r: &[V2], x: &mut [W2]) {
        for (i, &p) in self.nodes.iter().enumerate() {
            let z = self.first_pass[i];
            let xp = &mut x[p as usize];
            xp[0] = WS::of(xp[0].get() + z[0]);
            xp[1] = WS::of(xp[1].get() + z[1]);
        }
        let wp = level.wp;
        for (i, &p) in self.nodes.iter().enumerate() {
            let mut s = r[p as usize];
            for (t, &a) in self.rows[i].iter().enumerate() {
                if a != 0.0 {
                    let q = p as usize + (t / 5) * wp + t % 5 - 2 * wp - 2;
                    s[0] -= a * x[q][0].get();
                    s[1] -= a * x[q][1].get();
                }
            }
            self.rhs[i] = s;
        }
        self.solve_blocks();
        for (i, &p) in self.nodes.iter().enumerate() {
            let z = self.first_pass[i];
            let xp = &mut x[p as usize];
            xp[0] = WS::of(xp[0].get() + z[0]);
            xp[1] = WS::of(xp[1].get() + z[1]);
        }
    }

    /// `first_pass = A_SS⁻¹ rhs`, block by block.
    fn solve_blocks(&mut self) {
        let n = self.nodes.len();
        for (k, b) in self.blocks.iter().enumerate() {
            let end = self.blocks.get(k + 1).map_or(n, |nb| nb.start);
            let (rhs, out) = (&self.rhs[b.start..end], &mut self.first_pass[b.start..end]);
            b.solve(rhs, out);
        }
    }
}

/// Breadth-first order of the component of `s` (marking `seen`).
fn bfs(s: usize, seen: &mut [bool], mut next: impl FnMut(usize, &mut Vec<usize>)) -> Vec<usize> {
    let mut order = vec![s];
    seen[s] = true;
    let mut buf = Vec::new();
    let mut i = 0;
    while i < order.len() {
        next(order[i], &mut buf);
        for &q in &buf {
            if !seen[q] {
                seen[q] = true;
                order.push(q);
            }
        }
        i += 1;
    }
    order
}

impl Block {
    fn factor(&mut self, nodes: &[u32], rows: &[[f64; 25]], local: &[u32], end: usize, off: &impl Fn(usize) -> isize) {
        let n = end - self.start;
        // Envelope: the first column of each row (in block order).
        let mut entries: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        for i in 0..n {
            let p = nodes[self.start + i] as usize;
            for (t, &a) in rows[self.start + i].iter().enumerate() {
                let q = (p as isize + off(t)) as usize;
                let j = local[q];
                if a != 0.0 && j != u32::MAX && (j as usize) >= self.start && (j as usize) < end {
                    entries[i].push((j as usize - self.start, a));
                }
            }
        }
        self.first = entries.iter().enumerate().map(|(i, e)| e.iter().map(|&(j, _)| j).min().unwrap_or(i).min(i) as u32).collect();
        self.at = Vec::with_capacity(n);
        let mut total = 0;
        for i in 0..n {
            self.at.push(total);
            total += i + 1 - self.first[i] as usize;
        }
        if total > BAND * n {
            self.l = Vec::new();
            return;
        }
        let mut l = vec![0.0; total];
        let mut diag = vec![0.0; n];
        for i in 0..n {
            for &(j, a) in &entries[i] {
                if j < i {
                    l[self.at[i] + j - self.first[i] as usize] = a;
                } else if j == i {
                    diag[i] = a;
                }
            }
        }
        let mut d = vec![0.0; n];
        self.d_inv = vec![0.0; n];
        for i in 0..n {
            let fi = self.first[i] as usize;
            // g_ij = l_ij d_j, row i in place: g_ij = a_ij − Σ_k g_ik l_jk.
            for j in fi..i {
                let fj = self.first[j] as usize;
                let k0 = fi.max(fj);
                let mut s = l[self.at[i] + j - fi];
                for k in k0..j {
                    s -= l[self.at[i] + k - fi] * l[self.at[j] + k - fj];
                }
                l[self.at[i] + j - fi] = s;
            }
            let mut di = diag[i];
            for j in fi..i {
                let g = l[self.at[i] + j - fi];
                let lij = g * self.d_inv[j];
                l[self.at[i] + j - fi] = lij;
                di -= g * lij;
            }
            d[i] = di;
            self.d_inv[i] = if di > PIVOT * diag[i] { 1.0 / di } else { 0.0 };
        }
        self.l = l;
    }

    fn solve(&self, b: &[V2], x: &mut [V2]) {
        let n = b.len();
        for i in 0..n {
            let fi = self.first[i] as usize;
            let mut s = b[i];
            for k in fi..i {
                let lik = self.l[self.at[i] + k - fi];
                s[0] -= lik * x[k][0];
                s[1] -= lik * x[k][1];
            }
            x[i] = s;
        }
        for i in 0..n {
            x[i][0] *= self.d_inv[i];
            x[i][1] *= self.d_inv[i];
        }
        for i in (0..n).rev() {
            let fi = self.first[i] as usize;
            let xi = x[i];
            for k in fi..i {
                let lik = self.l[self.at[i] + k - fi];
                x[k][0] -= lik * xi[0];
                x[k][1] -= lik * xi[1];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{comb_grid, fine_level};
    use super::*;

    #[test]
    fn the_blocks_solve_the_thin_nodes_own_system() {
        let grid = comb_grid(40, 30);
        let mut fixed = vec![false; grid.len()];
        for i in [grid.index(3, 1), grid.index(20, 3), grid.index(36, 0), grid.index(10, 34)] {
            fixed[i] = true;
        }
        let level = fine_level(&grid, Some(fixed), 0.0);
        let mut s = Strands::new(&level).expect("the teeth are thin");
        assert!(s.blocks.len() > 10 && s.blocks.iter().all(|b| b.d_inv.iter().all(|&d| d > 0.0)));
        for (i, b) in s.rhs.iter_mut().enumerate() {
            *b = [(i % 7) as f64 - 3.0, (i % 5) as f64 * 0.5];
        }
        s.solve_blocks();
        let wp = level.wp;
        let mut x = vec![[0.0; 2]; level.len_padded()];
        for (i, &p) in s.nodes.iter().enumerate() {
            x[p as usize] = s.first_pass[i];
        }
        for (i, &p) in s.nodes.iter().enumerate() {
            let mut ax = [0.0; 2];
            for (t, &a) in s.rows[i].iter().enumerate() {
                let q = p as usize + (t / 5) * wp + t % 5 - 2 * wp - 2;
                ax[0] += a * x[q][0];
                ax[1] += a * x[q][1];
            }
            for k in 0..2 {
                assert!((ax[k] - s.rhs[i][k]).abs() < 1e-9 * (1.0 + s.rhs[i][k].abs()), "row {i}: {ax:?} against {:?}", s.rhs[i]);
            }
        }
    }
}

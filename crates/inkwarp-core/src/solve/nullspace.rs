//! The null space of a piece's constrained plate operator, and the τ → 0⁺ rule on it.
//!
//! A field has zero plate energy when every straight linked triple has a zero second difference and every
//! fully linked 2 × 2 cell a zero mixed difference. Full cells sharing an edge are then one affine function
//! (the rows or columns through both are straight triples), so such fields have few unknowns: three affine
//! coefficients per *cluster* of edge-connected full cells and one value per node in no full cell. They must
//! agree where clusters share a node, give a zero second difference on every triple not inside one cluster,
//! and vanish on the fixed nodes. That small sparse system's solutions span the null space `N` (a hinge's
//! turn, a strand's free bend, a ring's shear).
//!
//! At τ = 0 the contract's answer is the plate minimiser `u` plus the `n ∈ N` minimising `E_membrane(u + n)`.
//! At τ > 0 the same functions are the operator's smallest eigenvectors (eigenvalues of order τ), which an
//! iteration barely moves: an exact Galerkin correction in their span removes that error.

use std::{cmp::Reverse, collections::BinaryHeap};

use super::level::V2;
use super::strands::{blocks_in_order, Envelope};
use crate::grid::{find, join};

/// The most entries of a block's factor (a dense block of 1,500 functions): past it the rule is not applied and
/// the solve does not claim convergence.
pub(crate) const MAX_BLOCK_ENTRIES: usize = 1500 * 1501 / 2;

/// The most functions in all (each block's factor at most [`MAX_BLOCK_ENTRIES`], see [`Membrane`]).
pub(crate) const MAX_NULL: usize = 200_000;

/// A piece's geometry on its box: node `(x, y)` at `y · w + x`.
pub(crate) struct BoxGeo<'a> {
    pub w: usize,
    pub h: usize,
    pub active: &'a [bool],
    pub right: &'a [bool],
    pub down: &'a [bool],
}

/// A basis function: (node, value) pairs.
pub(crate) type Sparse = Vec<(usize, f64)>;

/// A basis of the fields of zero plate energy that vanish on `fixed`, or `None` past `max` functions.
pub(crate) fn plate_null_space(g: &BoxGeo, fixed: &[bool], max: usize) -> Option<Vec<Sparse>> {
    let (w, n) = (g.w, g.w * g.h);
    // Clusters: union-find over full cells joined through shared edges.
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let full: Vec<bool> = (0..n).map(|i| i % w + 1 < w && i / w + 1 < g.h && g.right[i] && g.down[i] && g.down[i + 1] && g.right[i + w]).collect();
    for i in (0..n).filter(|&i| full[i]) {
        let (x, y) = (i % w, i / w);
        for j in [(x > 0).then(|| i - 1), (y > 0).then(|| i - w)].into_iter().flatten().filter(|&j| full[j]) {
            join(&mut parent, i as u32, j as u32);
        }
    }
    // Cluster index per root, and each node's clusters (of the full cells it is a corner of).
    let mut cluster_of_root = vec![u32::MAX; n];
    let mut origin: Vec<[f64; 3]> = Vec::new(); // x0, y0, scale
    let mut member: Vec<[u32; 4]> = vec![[u32::MAX; 4]; n];
    for i in (0..n).filter(|&i| full[i]) {
        let r = find(&mut parent, i as u32) as usize;
        if cluster_of_root[r] == u32::MAX {
            cluster_of_root[r] = origin.len() as u32;
            origin.push([(r % w) as f64, (r / w) as f64, g.w.max(g.h) as f64]);
        }
        let c = cluster_of_root[r];
        // Slots fill in order: `c` is either before the first free one or absent.
        for j in [i, i + 1, i + w, i + w + 1] {
            if let Some(slot) = member[j].iter_mut().find(|s| **s == c || **s == u32::MAX) {
                *slot = c;
            }
        }
    }
    let clusters = origin.len();
    // Unknowns: three a cluster (its nodes those whose first cluster it is), then one per lone active node.
    let (mut lone, mut lone_nodes, mut nodes_of) = (vec![u32::MAX; n], Vec::new(), vec![Vec::new(); clusters]);
    for i in (0..n).filter(|&i| g.active[i]) {
        if member[i][0] != u32::MAX {
            nodes_of[member[i][0] as usize].push(i);
        } else {
            lone[i] = (3 * clusters + lone_nodes.len()) as u32;
            lone_nodes.push(i);
        }
    }
    let vars = 3 * clusters + lone_nodes.len();
    let in_cluster = |i: usize, c: u32| -> [(usize, f64); 3] {
        let o = origin[c as usize];
        let (x, y) = (((i % w) as f64 - o[0]) / o[2], ((i / w) as f64 - o[1]) / o[2]);
        let b = 3 * c as usize;
        [(b, 1.0), (b + 1, x), (b + 2, y)]
    };
    let mut elim = Echelon::new(vars);
    let mut row: Vec<(usize, f64)> = Vec::new();
    // The equation `Σ f u(node) + extra = 0` over `(node, f)` terms, each node's value its lone unknown or
    // its first cluster's affine function.
    let mut equation = |terms: &[(usize, f64)], extra: &[(usize, f64)]| {
        row.clear();
        for &(i, f) in terms {
            if lone[i] != u32::MAX {
                row.push((lone[i] as usize, f));
            } else {
                row.extend(in_cluster(i, member[i][0]).map(|(v, a)| (v, f * a)));
            }
        }
        row.extend_from_slice(extra);
        elim.add(&row);
    };
    for i in (0..n).filter(|&i| g.active[i]) {
        // Clusters sharing the node agree there.
        for &c in member[i].iter().skip(1).take_while(|&&c| c != u32::MAX) {
            equation(&[(i, 1.0)], &in_cluster(i, c).map(|(v, a)| (v, -a)));
        }
        if fixed[i] { equation(&[(i, 1.0)], &[]); }
        let shared = |a: usize, b: usize| member[i].iter().any(|&c| c != u32::MAX && member[a].contains(&c) && member[b].contains(&c));
        // The ends of the linked horizontal and vertical triples centred on `i`.
        let across = (i % w > 0 && g.right[i - 1] && g.right[i]).then(|| (i - 1, i + 1));
        let triples = across.into_iter().chain((i / w > 0 && g.down[i - w] && g.down[i]).then(|| (i - w, i + w)));
        for (a, b) in triples.filter(|&(a, b)| !shared(a, b)) {
            equation(&[(a, 1.0), (i, -2.0), (b, 1.0)], &[]);
        }
    }
    let basis = elim.null_space(max)?;
    // Expand to nodes: the nodes of the clusters a function involves, then its lone nodes.
    let mut qd = vec![0.0; 3 * clusters];
    let out = basis.into_iter().map(|mut q| {
        q.sort_unstable_by_key(|&(k, _)| k);
        let (affine, lone_values) = q.split_at(q.partition_point(|&(k, _)| k < 3 * clusters));
        affine.iter().for_each(|&(k, v)| qd[k] = v);
        let mut touched: Vec<usize> = affine.iter().map(|&(k, _)| k / 3).collect();
        touched.dedup();
        let mut z: Sparse = Vec::new();
        // A cluster's values are at most the sum of its coefficients (|x|, |y| ≤ 1): one whose sum is below
        // the cut of `retain` below adds nothing, and may hold every node.
        for c in touched.into_iter().filter(|&c| qd[3 * c..3 * c + 3].iter().map(|v| v.abs()).sum::<f64>() > 1e-13) {
            z.extend(nodes_of[c].iter().map(|&i| (i, in_cluster(i, c as u32).iter().map(|&(k, a)| a * qd[k]).sum::<f64>())));
        }
        z.extend(lone_values.iter().map(|&(k, v)| (lone_nodes[k - 3 * clusters], v)));
        affine.iter().for_each(|&(k, _)| qd[k] = 0.0);
        z.retain(|&(_, v)| v.abs() > 1e-13);
        z
    });
    Some(out.filter(|z| !z.is_empty()).collect())
}

/// Incremental sparse Gaussian elimination: rows normalised on their pivot, free of earlier pivots' columns.
struct Echelon {
    pivot_of: Vec<u32>,
    rows: Vec<(usize, Vec<(usize, f64)>)>,
    acc: Vec<f64>,
    touched: Vec<usize>,
    seen: Vec<bool>,
}

impl Echelon {
    fn new(vars: usize) -> Self {
        Echelon { pivot_of: vec![u32::MAX; vars], rows: Vec::new(), acc: vec![0.0; vars], touched: Vec::new(), seen: vec![false; vars] }
    }

    fn add(&mut self, row: &[(usize, f64)]) {
        let (mut heap, mut scale) = (BinaryHeap::new(), 0.0f64);
        let (seen, touched, pivot_of) = (&mut self.seen, &mut self.touched, &self.pivot_of);
        let mut visit = |c: usize, heap: &mut BinaryHeap<Reverse<u32>>| {
            if !std::mem::replace(&mut seen[c], true) {
                touched.push(c);
                if pivot_of[c] != u32::MAX {
                    heap.push(Reverse(pivot_of[c]));
                }
            }
        };
        for &(c, v) in row {
            visit(c, &mut heap);
            self.acc[c] += v;
            scale = scale.max(v.abs());
        }
        while let Some(Reverse(p)) = heap.pop() {
            let (pc, ref prow) = self.rows[p as usize];
            let f = self.acc[pc];
            if f == 0.0 { continue; }
            for &(c, v) in prow {
                visit(c, &mut heap);
                self.acc[c] -= f * v;
            }
            self.acc[pc] = 0.0;
        }
        let piv = self.touched.iter().copied().max_by(|&a, &b| self.acc[a].abs().total_cmp(&self.acc[b].abs()));
        if let Some(piv) = piv.filter(|&c| self.acc[c].abs() > 1e-9 * scale) {
            let d = self.acc[piv];
            let new = self.touched.iter().map(|&c| (c, self.acc[c] / d)).filter(|&(_, v)| v.abs() > 1e-12).collect();
            self.pivot_of[piv] = self.rows.len() as u32;
            self.rows.push((piv, new));
        }
        for c in self.touched.drain(..) {
            self.acc[c] = 0.0;
            self.seen[c] = false;
        }
    }

    /// One sparse basis vector per free column, or `None` past `max`. Back-substitution from the last row up
    /// visits only the rows that read an entry already nonzero (free columns and later rows' pivots).
    fn null_space(&self, max: usize) -> Option<Vec<Vec<(usize, f64)>>> {
        let vars = self.pivot_of.len();
        let free: Vec<usize> = (0..vars).filter(|&c| self.pivot_of[c] == u32::MAX).collect();
        if free.len() > max { return None; }
        let mut readers: Vec<Vec<u32>> = vec![Vec::new(); vars];
        for (r, (pc, prow)) in self.rows.iter().enumerate() {
            for &(c, _) in prow.iter().filter(|&&(c, _)| c != *pc) {
                readers[c].push(r as u32);
            }
        }
        let (mut q, mut queued) = (vec![0.0; vars], vec![false; self.rows.len()]);
        let basis = free.iter().map(|&f| {
            let (mut heap, mut visited) = (BinaryHeap::new(), Vec::new());
            let mut wake = |c: usize, heap: &mut BinaryHeap<u32>| {
                for &r in &readers[c] {
                    if !std::mem::replace(&mut queued[r as usize], true) {
                        visited.push(r);
                        heap.push(r);
                    }
                }
            };
            q[f] = 1.0;
            let mut nonzero = vec![f];
            wake(f, &mut heap);
            while let Some(r) = heap.pop() {
                let (pc, prow) = &self.rows[r as usize];
                let s: f64 = prow.iter().filter(|&&(c, _)| c != *pc).map(|&(c, v)| v * q[c]).sum();
                if s != 0.0 {
                    q[*pc] = -s;
                    nonzero.push(*pc);
                    wake(*pc, &mut heap);
                }
            }
            visited.into_iter().for_each(|r| queued[r as usize] = false);
            nonzero.iter().map(|&c| (c, std::mem::take(&mut q[c]))).collect()
        });
        Some(basis.collect())
    }
}

/// The membrane product `y = M z` for a sparse `z` into `y` (zero on entry); returns the nodes it touched.
/// `dense` is a zero scratch, left zero.
fn membrane_sparse(g: &BoxGeo, z: &Sparse, dense: &mut [f64], y: &mut [f64]) -> Vec<usize> {
    let w = g.w;
    z.iter().for_each(|&(i, v)| dense[i] = v);
    let mut touched = Vec::new();
    let mut link = |i: usize, j: usize| {
        let d = dense[i] - dense[j];
        y[i] += d;
        y[j] -= d;
        touched.extend([i, j]);
    };
    for &(i, _) in z {
        let (x, yy) = (i % w, i / w);
        g.right[i].then_some(i + 1).into_iter().chain(g.down[i].then_some(i + w)).for_each(|j| link(i, j));
        // Links from the left and above, where the other end is outside the support (inside, it lists them).
        let outer = [(x > 0 && g.right[i - 1]).then(|| i - 1), (yy > 0 && g.down[i - w]).then(|| i - w)];
        for j in outer.into_iter().flatten().filter(|&j| dense[j] == 0.0) {
            link(j, i);
        }
    }
    z.iter().for_each(|&(i, _)| dense[i] = 0.0);
    touched.sort_unstable();
    touched.dedup();
    touched
}

/// The τ → 0⁺ choice among the plate minimisers as a linear map `u ↦ u + n`, `n ∈ span(basis)` minimising
/// the membrane energy of `u + n`. The functions couple only where their supports meet, so the system falls
/// apart in blocks (one hair's free bends, one sliver's), each solved on its own. Built once per piece.
pub(crate) struct Membrane {
    basis: Vec<Sparse>,
    /// `M z_j` for each basis function `z_j`, on the nodes it touches.
    products: Vec<Sparse>,
    /// Each block's functions in its factor's order, and the factor of its membrane Gram matrix (none for a
    /// block too costly or singular, which is not settled).
    blocks: Vec<(Vec<usize>, Option<Envelope>)>,
}

impl Membrane {
    pub(crate) fn new(g: &BoxGeo, basis: Vec<Sparse>) -> Self {
        let (k, n) = (basis.len(), g.w * g.h);
        // Rows of the basis by node, `(function, value)` from `start[i]` to `start[i + 1]`.
        let mut start = vec![0; n + 1];
        basis.iter().flatten().for_each(|&(i, _)| start[i + 1] += 1);
        (0..n).for_each(|i| start[i + 1] += start[i]);
        let (mut rows, mut fill) = (vec![(0, 0.0); start[n]], start.clone());
        for (j, &(i, v)) in basis.iter().enumerate().flat_map(|(j, z)| z.iter().map(move |e| (j, e))) {
            rows[fill[i]] = (j, v);
            fill[i] += 1;
        }
        // The membrane Gram matrix by columns, its entries where two functions meet.
        let (mut gram, mut products): (Vec<Sparse>, Vec<Sparse>) = (vec![Vec::new(); k], Vec::with_capacity(k));
        let (mut dense, mut y) = (vec![0.0; n], vec![0.0; n]);
        let (mut acc, mut seen, mut hit) = (vec![0.0; k], vec![false; k], Vec::new());
        for (j, z) in basis.iter().enumerate() {
            let touched = membrane_sparse(g, z, &mut dense, &mut y);
            for &p in &touched {
                for &(i, v) in &rows[start[p]..start[p + 1]] {
                    if !std::mem::replace(&mut seen[i], true) {
                        hit.push(i);
                    }
                    acc[i] += v * y[p];
                }
            }
            products.push(touched.iter().map(|&p| (p, std::mem::take(&mut y[p]))).collect());
            for i in hit.drain(..) {
                gram[j].push((i, acc[i]));
                (acc[i], seen[i]) = (0.0, false);
            }
        }
        // Each block in an order keeping its envelope narrow; one with a dropped pivot (dependent functions)
        // is not settled.
        let mut local = vec![0; k];
        let blocks = blocks_in_order(k, |_| true, |j, out| out.extend(gram[j].iter().map(|e| e.0))).into_iter().map(|members| {
            members.iter().enumerate().for_each(|(l, &j)| local[j] = l);
            let entries: Vec<_> = members.iter().map(|&j| gram[j].iter().map(|&(i, v)| (local[i], v)).collect()).collect();
            (members, Envelope::factor(&entries, 0.0, 1e-12, MAX_BLOCK_ENTRIES).filter(|f| !f.dropped()))
        }).collect();
        Membrane { basis, products, blocks }
    }

    /// The nodes of the box's `n` the functions touch, in order.
    pub(crate) fn support(&self, n: usize) -> Vec<usize> {
        let mut on = vec![false; n];
        self.basis.iter().flatten().for_each(|&(i, _)| on[i] = true);
        (0..n).filter(|&i| on[i]).collect()
    }

    /// Whether every block is settled (none too large or singular).
    pub(crate) fn settles_all(&self) -> bool { self.blocks.iter().all(|b| b.1.is_some()) }

    /// How many functions there are.
    pub(crate) fn len(&self) -> usize { self.basis.len() }

    /// `n` for the field read by `read` (box node → value), added by `add(node, value)`; false when a block
    /// was not settled (too large or singular: it is left as it is).
    pub(crate) fn settle(&self, read: impl Fn(usize) -> V2, add: impl FnMut(usize, V2)) -> bool {
        self.add(self.coefficients(read), add)
    }

    /// Settles `u` (dense over the box); false when a block was not settled.
    pub(crate) fn apply(&self, u: &mut [V2]) -> bool {
        self.add(self.coefficients(|i| u[i]), |i, v| u[i] = [u[i][0] + v[0], u[i][1] + v[1]])
    }

    /// Each settled function's coefficient in `n` for the field read by `read`, block by block.
    fn coefficients(&self, read: impl Fn(usize) -> V2) -> Vec<(usize, V2)> {
        let mut coefficients = Vec::new();
        for (members, l) in self.blocks.iter().filter_map(|(m, l)| Some((m, l.as_ref()?))) {
            let mut c: Vec<V2> = members.iter().map(|&j| self.products[j].iter().fold([0.0; 2], |s, &(p, y)| {
                let v = read(p);
                [s[0] - y * v[0], s[1] - y * v[1]]
            })).collect();
            l.solve(&mut c);
            coefficients.extend(members.iter().copied().zip(c));
        }
        coefficients
    }

    /// `n = Σ c_j z_j` term by term through `add(node, value)` (no list of the terms: a hair's functions reach
    /// far, and their terms can outnumber the nodes many times); false when a block was not settled.
    fn add(&self, coefficients: Vec<(usize, V2)>, mut add: impl FnMut(usize, V2)) -> bool {
        for (j, c) in coefficients {
            self.basis[j].iter().for_each(|&(i, v)| add(i, [c[0] * v, c[1] * v]));
        }
        self.settles_all()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_block_folded_back_on_itself_keeps_a_narrow_envelope() {
        // A chain folded back on itself (a U-shaped strand: function j meets j ± 1 and
        // n − 1 − j), diagonally dominant: the order found keeps the envelope narrow (in
        // the functions' own order it would be n / 2 wide), and the solve matches the matrix.
        let n = 400;
        let mut rows: Vec<Vec<(usize, f64)>> = (0..n).map(|j| vec![(j, 4.0 + (j % 7) as f64 * 0.1)]).collect();
        let mut couple = |a: usize, b: usize, v: f64| {
            rows[a].push((b, v));
            rows[b].push((a, v));
        };
        for j in 0..n - 1 {
            couple(j, j + 1, -1.0);
        }
        for j in 0..n / 2 {
            couple(j, n - 1 - j, 0.5);
        }
        let blocks = blocks_in_order(n, |_| true, |j, out| *out = rows[j].iter().map(|e| e.0).collect());
        assert_eq!(blocks.len(), 1);
        let order = &blocks[0];
        let mut local = vec![0; n];
        order.iter().enumerate().for_each(|(l, &j)| local[j] = l);
        let entries: Vec<_> = order.iter().map(|&j| rows[j].iter().map(|&(i, v)| (local[i], v)).collect()).collect();
        let factor = Envelope::factor(&entries, 0.0, 1e-12, 8 * n).expect("an envelope within 8 entries a row");
        assert!(!factor.dropped());
        let b: Vec<V2> = (0..n).map(|r| [(r as f64).sin(), 1.0]).collect();
        let mut x = b.clone();
        factor.solve(&mut x);
        for r in 0..n {
            let ax = rows[order[r]].iter().fold([0.0; 2], |s, &(i, v)| [s[0] + v * x[local[i]][0], s[1] + v * x[local[i]][1]]);
            assert!((ax[0] - b[r][0]).abs() < 1e-12 && (ax[1] - b[r][1]).abs() < 1e-12, "row {r}: {ax:?} against {:?}", b[r]);
        }
    }
}

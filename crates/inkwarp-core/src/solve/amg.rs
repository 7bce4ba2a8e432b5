//! Smoothed aggregation: the coarse space of the solver.
//!
//! Level 0 is the plate operator on a piece's free nodes ([`super::matrix`]). Its nodes are
//! grouped into *aggregates*: the parts of each 3 × 3 block of nodes that links inside the
//! block connect (so both sides of a cut, a strand, a tooth, a square hinged at one node
//! fall into different aggregates). Each aggregate carries the restriction of the
//! near-null space `B = {1, x, y}` (the affine functions, which have no plate energy),
//! orthonormalised by a small QR (`B_agg = Q R`; rank 1–3 by the aggregate's shape): the
//! columns of `Q` are the tentative prolongation's columns and the rows of `R` the coarse
//! level's `B`, so every coarse level holds the affine motions of every part exactly. The
//! tentative prolongation is smoothed once by damped Jacobi, `P = (I − ω D⁻¹ A) P_tent`,
//! `ω = 4 / (3 ρ(D⁻¹A))`, so coarse functions bend into constraints, holes and cuts as
//! the operator wants; coarse operators are Galerkin `Pᵀ A P`. Coarser levels group the
//! aggregates of each 3 × 3 block of aggregate blocks that the coarse operator couples.
//! Smoothing is symmetric Gauss–Seidel; the coarsest level (a few hundred unknowns) is
//! solved by a dense Cholesky factorisation that skips zero pivots (the operator may be
//! semidefinite). The V-cycle preconditions conjugate gradients on level 0.

use super::matrix::{BoxGrid, Csr, V2};

/// Nodes per side of a level's blocks.
fn envn(k: &str, d: usize) -> usize { std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d) }
fn block_size() -> u32 { envn("AMG_BLOCK", 3) as u32 }
/// Stop coarsening at this many unknowns (solved densely).
const COARSEST: usize = 400;
/// Gauss–Seidel sweeps (forward and backward) before and after each coarse correction.
fn sweeps() -> usize { envn("AMG_SWEEPS", 1) }

struct Level {
    a: Csr,
    inv_diag: Vec<f64>,
    /// The prolongation from the next level and its transpose (empty on the coarsest).
    p: Csr,
    pt: Csr,
    x: Vec<V2>,
    b: Vec<V2>,
    r: Vec<V2>,
}

/// The multigrid hierarchy of one operator, with its work vectors.
pub(crate) struct Hierarchy {
    levels: Vec<Level>,
    coarse: Dense,
}

impl Hierarchy {
    /// Builds the hierarchy of `a`, the operator on the free nodes `node` of `g`.
    pub fn new(a: Csr, g: &BoxGrid, node: &[u32], dof: &[u32]) -> Hierarchy {
        let w = g.w;
        // Level 0: nodes are the free nodes, one unknown each, joined by links.
        let mut pos: Vec<(u32, u32)> = node.iter().map(|&p| ((p as usize % w) as u32, (p as usize / w) as u32)).collect();
        let scale = 1.0 / (g.w.max(g.h) as f64);
        let (cx, cy) = (g.w as f64 / 2.0, g.h as f64 / 2.0);
        let mut b: Vec<[f64; 3]> = pos.iter().map(|&(x, y)| [1.0, (x as f64 - cx) * scale, (y as f64 - cy) * scale]).collect();
        let mut node_of_dof: Vec<u32> = (0..node.len() as u32).collect();
        let mut edges: Vec<(u32, u32)> = Vec::new();
        for (i, &p) in node.iter().enumerate() {
            let p = p as usize;
            if g.right[p] && dof[p + 1] != u32::MAX {
                edges.push((i as u32, dof[p + 1]));
            }
            if g.down[p] && dof[p + w] != u32::MAX {
                edges.push((i as u32, dof[p + w]));
            }
        }
        let mut levels = Vec::new();
        let mut a = a;
        loop {
            let n = a.rows;
            let inv_diag: Vec<f64> = a.diagonal().iter().map(|&d| if d > 0.0 { 1.0 / d } else { 0.0 }).collect();
            let n_nodes = pos.len();
            if n <= COARSEST || levels.len() >= 16 {
                levels.push(Level::new(a, inv_diag, Csr::default()));
                break;
            }
            let (agg_of_node, agg_pos) = aggregate(n_nodes, &pos, &edges);
            let (p_tent, b_coarse, node_of_coarse) = tentative(&node_of_dof, &agg_of_node, agg_pos.len(), &b);
            if p_tent.cols as f64 > 0.9 * n as f64 {
                levels.push(Level::new(a, inv_diag, Csr::default()));
                break;
            }
            let mut p = p_tent;
            for _ in 0..envn("AMG_PSMOOTH", 1) {
                p = smooth(&a, &inv_diag, &p);
            }
            let coarse = p.transpose().mul(&a.mul(&p));
            // The next level's nodes are this level's aggregates, joined where the coarse
            // operator couples them.
            edges = couplings(&coarse, &node_of_coarse);
            pos = agg_pos;
            b = b_coarse;
            node_of_dof = node_of_coarse;
            levels.push(Level::new(a, inv_diag, p));
            a = coarse;
        }
        let coarse = Dense::factor(&levels.last().unwrap().a);
        if std::env::var_os("INKWARP_AMG_DEBUG").is_some() {
            for l in &levels {
                eprintln!("level: {} unknowns, {} nonzeros", l.a.rows, l.a.nnz());
            }
        }
        Hierarchy { levels, coarse }
    }

    /// Unknowns on each level.
    pub fn sizes(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.a.rows).collect()
    }

    /// `z = M⁻¹ r`: one V-cycle from zero.
    pub fn precondition(&mut self, r: &[V2], z: &mut [V2]) {
        self.levels[0].b.copy_from_slice(r);
        cycle(&mut self.levels, &self.coarse);
        z.copy_from_slice(&self.levels[0].x);
    }
}

impl Level {
    fn new(a: Csr, inv_diag: Vec<f64>, p: Csr) -> Level {
        let n = a.rows;
        let pt = if p.rows > 0 { p.transpose() } else { Csr::default() };
        Level { a, inv_diag, p, pt, x: vec![[0.0; 2]; n], b: vec![[0.0; 2]; n], r: vec![[0.0; 2]; n] }
    }
}

fn cycle(levels: &mut [Level], coarse: &Dense) {
    let (l, rest) = levels.split_first_mut().unwrap();
    if rest.is_empty() {
        coarse.solve(&l.b, &mut l.x);
        return;
    }
    l.x.iter_mut().for_each(|x| *x = [0.0; 2]);
    for _ in 0..sweeps() {
        gauss_seidel(&l.a, &l.inv_diag, &l.b, &mut l.x);
    }
    l.a.residual(&l.b, &l.x, &mut l.r);
    l.pt.apply(&l.r, &mut rest[0].b);
    cycle(rest, coarse);
    if rest.len() > 1 {
        for _ in 1..envn("AMG_GAMMA", 1) {
            // Another cycle on the coarse level's residual (a W-cycle).
            let c = &mut rest[0];
            let b0 = c.b.clone();
            let x0 = c.x.clone();
            c.a.residual(&b0, &x0, &mut c.b);
            cycle(rest, coarse);
            let c = &mut rest[0];
            for (x, x0) in c.x.iter_mut().zip(&x0) {
                x[0] += x0[0];
                x[1] += x0[1];
            }
            c.b = b0;
        }
    }
    l.p.apply(&rest[0].x, &mut l.r);
    for (x, c) in l.x.iter_mut().zip(&l.r) {
        x[0] += c[0];
        x[1] += c[1];
    }
    for _ in 0..sweeps() {
        gauss_seidel(&l.a, &l.inv_diag, &l.b, &mut l.x);
    }
}

/// One symmetric Gauss–Seidel sweep (forward, then backward).
fn gauss_seidel(a: &Csr, inv_diag: &[f64], b: &[V2], x: &mut [V2]) {
    let n = a.rows;
    let mut relax = |i: usize, x: &mut [V2]| {
        let d = inv_diag[i];
        if d == 0.0 {
            return;
        }
        let (c, v) = a.row(i);
        let mut s = b[i];
        for (&c, &v) in c.iter().zip(v) {
            let xc = x[c as usize];
            s[0] -= v * xc[0];
            s[1] -= v * xc[1];
        }
        x[i][0] += s[0] * d;
        x[i][1] += s[1] * d;
    };
    for i in 0..n {
        relax(i, x);
    }
    for i in (0..n).rev() {
        relax(i, x);
    }
}

struct UnionFind(Vec<u32>);

impl UnionFind {
    fn find(&mut self, mut i: u32) -> u32 {
        while self.0[i as usize] != i {
            let p = self.0[self.0[i as usize] as usize];
            self.0[i as usize] = p;
            i = p;
        }
        i
    }
    fn union(&mut self, a: u32, b: u32) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            self.0[a.max(b) as usize] = a.min(b);
        }
    }
}

/// Aggregates: the components of each block's nodes under `edges` within the block.
/// Returns each node's aggregate and each aggregate's block.
fn aggregate(n: usize, pos: &[(u32, u32)], edges: &[(u32, u32)]) -> (Vec<u32>, Vec<(u32, u32)>) {
    let bs = block_size();
    let block = |i: u32| (pos[i as usize].0 / bs, pos[i as usize].1 / bs);
    let mut uf = UnionFind((0..n as u32).collect());
    for &(i, j) in edges {
        if block(i) == block(j) {
            uf.union(i, j);
        }
    }
    let mut id = vec![u32::MAX; n];
    let mut agg_pos = Vec::new();
    let mut agg_of = vec![0u32; n];
    for i in 0..n as u32 {
        let root = uf.find(i) as usize;
        if id[root] == u32::MAX {
            id[root] = agg_pos.len() as u32;
            agg_pos.push(block(i));
        }
        agg_of[i as usize] = id[root];
    }
    (agg_of, agg_pos)
}

/// The tentative prolongation: each aggregate's `B` rows orthonormalised (`B_agg = Q R`).
/// Returns `P_tent`, the coarse `B` (the rows of every `R`) and each coarse unknown's
/// aggregate.
fn tentative(node_of_dof: &[u32], agg_of_node: &[u32], aggs: usize, b: &[[f64; 3]]) -> (Csr, Vec<[f64; 3]>, Vec<u32>) {
    let n = node_of_dof.len();
    // The unknowns of each aggregate, by a counting sort.
    let agg_of = |i: usize| agg_of_node[node_of_dof[i] as usize] as usize;
    let mut start = vec![0usize; aggs + 1];
    for i in 0..n {
        start[agg_of(i) + 1] += 1;
    }
    for k in 0..aggs {
        start[k + 1] += start[k];
    }
    let mut members = vec![0u32; n];
    let mut next = start.clone();
    for i in 0..n {
        let k = &mut next[agg_of(i)];
        members[*k] = i as u32;
        *k += 1;
    }
    let mut rows: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
    let mut b_coarse = Vec::new();
    let mut coarse_agg = Vec::new();
    for k in 0..aggs {
        let m = &members[start[k]..start[k + 1]];
        let mut q: Vec<Vec<f64>> = Vec::new();
        for j in 0..3 {
            let col: Vec<f64> = m.iter().map(|&i| b[i as usize][j]).collect();
            let norm0 = col.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm0 == 0.0 {
                continue;
            }
            let mut v = col;
            for _ in 0..2 {
                for qc in &q {
                    let d: f64 = qc.iter().zip(&v).map(|(a, b)| a * b).sum();
                    v.iter_mut().zip(qc).for_each(|(v, q)| *v -= d * q);
                }
            }
            let norm = v.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm > 1e-9 * norm0 {
                v.iter_mut().for_each(|v| *v /= norm);
                q.push(v);
            }
        }
        for qc in &q {
            let c = b_coarse.len() as u32;
            let mut r = [0.0; 3];
            for (t, &i) in m.iter().enumerate() {
                rows[i as usize].push((c, qc[t]));
                for (j, r) in r.iter_mut().enumerate() {
                    *r += qc[t] * b[i as usize][j];
                }
            }
            b_coarse.push(r);
            coarse_agg.push(k as u32);
        }
    }
    let mut p = Csr { rows: n, cols: b_coarse.len(), start: vec![0], col: Vec::new(), val: Vec::new() };
    for row in rows {
        for (c, v) in row {
            p.col.push(c);
            p.val.push(v);
        }
        p.start.push(p.col.len());
    }
    (p, b_coarse, coarse_agg)
}

/// `P = (I − ω D⁻¹ A) P_tent`, `ω = 4 / (3 ρ(D⁻¹A))`.
fn smooth(a: &Csr, inv_diag: &[f64], p_tent: &Csr) -> Csr {
    let rho = spectral_radius(a, inv_diag);
    let gersh = (0..a.rows).map(|i| a.row(i).1.iter().map(|v| v.abs()).sum::<f64>() * inv_diag[i]).fold(0.0, f64::max);
    if std::env::var_os("INKWARP_AMG_DEBUG").is_some() {
        eprintln!("rho {rho:.4} gershgorin {gersh:.4}");
    }
    let rho = if envn("AMG_GERSH", 0) == 1 { gersh } else { rho * envn("AMG_RHO_PCT", 100) as f64 / 100.0 };
    let omega = 4.0 / (3.0 * rho);
    let mut p = a.mul(p_tent);
    for i in 0..p.rows {
        let f = -omega * inv_diag[i];
        let r = p.start[i]..p.start[i + 1];
        p.val[r.clone()].iter_mut().for_each(|v| *v *= f);
        let (tc, tv) = p_tent.row(i);
        for (&c, &v) in tc.iter().zip(tv) {
            match p.col[r.clone()].binary_search(&c) {
                Ok(k) => p.val[r.start + k] += v,
                Err(_) => unreachable!("A has every diagonal entry of a row with P_tent entries"),
            }
        }
    }
    p
}

/// `ρ(D⁻¹A)` by power iteration (the Rayleigh quotient `xᵀAx / xᵀDx`, its largest).
fn spectral_radius(a: &Csr, inv_diag: &[f64]) -> f64 {
    let n = a.rows;
    let mut seed = 0x9e3779b97f4a7c15u64;
    let mut x: Vec<V2> = (0..n)
        .map(|_| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            [(seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5, 0.0]
        })
        .collect();
    let mut y = vec![[0.0; 2]; n];
    let mut rho = 0.0f64;
    for _ in 0..15 {
        a.apply(&x, &mut y);
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            if inv_diag[i] > 0.0 {
                num += x[i][0] * y[i][0];
                den += x[i][0] * x[i][0] / inv_diag[i];
            }
        }
        if den > 0.0 {
            rho = rho.max(num / den);
        }
        let mut norm = 0.0f64;
        for i in 0..n {
            x[i][0] = y[i][0] * inv_diag[i];
            norm = norm.max(x[i][0].abs());
        }
        if norm == 0.0 {
            break;
        }
        x.iter_mut().for_each(|v| v[0] /= norm);
    }
    if rho > 0.0 {
        rho
    } else {
        1.0
    }
}

/// Pairs of distinct nodes (aggregates) whose unknowns the operator couples.
fn couplings(a: &Csr, node_of_dof: &[u32]) -> Vec<(u32, u32)> {
    let diag = a.diagonal();
    let mut edges = Vec::new();
    for i in 0..a.rows {
        let (c, v) = a.row(i);
        for (&j, &v) in c.iter().zip(v) {
            let (ni, nj) = (node_of_dof[i], node_of_dof[j as usize]);
            if ni < nj && v.abs() > 1e-10 * (diag[i] * diag[j as usize]).abs().sqrt() {
                edges.push((ni, nj));
            }
        }
    }
    edges
}

/// A dense Cholesky factorisation that skips the pivots a semidefinite matrix leaves at
/// zero (their unknowns are set to 0: a solution of a consistent system).
struct Dense {
    n: usize,
    l: Vec<f64>,
    skip: Vec<bool>,
}

impl Dense {
    fn factor(a: &Csr) -> Dense {
        let n = a.rows;
        let mut l = vec![0.0; n * n];
        for i in 0..n {
            let (c, v) = a.row(i);
            for (&c, &v) in c.iter().zip(v) {
                l[i * n + c as usize] = v;
            }
        }
        let max_diag = (0..n).map(|i| l[i * n + i]).fold(0.0f64, f64::max);
        let mut skip = vec![false; n];
        for j in 0..n {
            let mut d = l[j * n + j];
            for k in 0..j {
                d -= l[j * n + k] * l[j * n + k];
            }
            if d <= 1e-12 * max_diag {
                skip[j] = true;
                for i in j..n {
                    l[i * n + j] = 0.0;
                }
                continue;
            }
            let d = d.sqrt();
            l[j * n + j] = d;
            for i in j + 1..n {
                let mut s = l[i * n + j];
                for k in 0..j {
                    s -= l[i * n + k] * l[j * n + k];
                }
                l[i * n + j] = s / d;
            }
        }
        Dense { n, l, skip }
    }

    fn solve(&self, b: &[V2], x: &mut [V2]) {
        let (n, l) = (self.n, &self.l);
        for i in 0..n {
            if self.skip[i] {
                x[i] = [0.0; 2];
                continue;
            }
            let mut s = b[i];
            for k in 0..i {
                s[0] -= l[i * n + k] * x[k][0];
                s[1] -= l[i * n + k] * x[k][1];
            }
            x[i] = [s[0] / l[i * n + i], s[1] / l[i * n + i]];
        }
        for i in (0..n).rev() {
            if self.skip[i] {
                continue;
            }
            let mut s = x[i];
            for k in i + 1..n {
                s[0] -= l[k * n + i] * x[k][0];
                s[1] -= l[k * n + i] * x[k][1];
            }
            x[i] = [s[0] / l[i * n + i], s[1] / l[i * n + i]];
        }
    }
}

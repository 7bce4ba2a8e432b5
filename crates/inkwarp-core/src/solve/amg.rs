//! Smoothed aggregation: an experimental coarse space for the solver, used only when the
//! environment variable `INKWARP_AMG` is set (not the default; see
//! `docs/dev/smoothed-aggregation.md` for what it measured and why it is not).
//!
//! Level 0 is the plate operator on a piece's free nodes ([`super::matrix`]). The
//! tentative prolongation is a partition of unity: bilinear hats of half width 3 on a
//! lattice every 3 nodes; each link-connected part of a hat's box is an aggregate (so both
//! sides of a cut, a strand, a tooth, a square hinged at one node fall into different
//! ones), carrying `hat · B` with the near-null space `B = {1, x, y}` orthonormalised by a
//! small QR (`hat · B_agg = Q R`, rank 1–3): `Q` gives the columns, the rows of `R` the
//! coarse level's `B`, so every level holds the affine motions of every part exactly.
//! (`AMG_PU=0` instead takes disjoint aggregates, the parts of each 3 × 3 block, the
//! textbook choice.) It is smoothed by damped Jacobi, `P = (I − ω D⁻¹ A) P_tent`,
//! `ω = 4 / (3 ρ(D⁻¹A))`; coarse operators are Galerkin `Pᵀ A P`, whose couplings join the
//! next level's parts. Symmetric Gauss–Seidel smoothing, a dense Cholesky factorisation
//! that skips zero pivots on the coarsest level (≤ 400 unknowns), and the V-cycle as the
//! preconditioner of conjugate gradients.

use super::matrix::{BoxGrid, Csr, V2};

/// Nodes per side of a level's blocks.
/// The measurement switches (read at each use; development only): `AMG_BLOCK` (lattice
/// spacing, 3), `AMG_SWEEPS` and `AMG_COARSE_SWEEPS` (Gauss–Seidel sweeps, 1), `AMG_PU` (1:
/// partition of unity, 0: disjoint blocks), `AMG_PSMOOTH` (Jacobi steps on `P`, 1) and
/// `AMG_PSMOOTH_LEVELS` (on how many levels), `AMG_GAMMA` (2: W-cycle), `AMG_GERSH` and
/// `AMG_RHO_PCT` (the `ρ` in `ω`).
fn envn(k: &str, d: usize) -> usize { std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d) }
fn block_size() -> u32 { envn("AMG_BLOCK", 3) as u32 }
/// Stop coarsening at this many unknowns (solved densely).
const COARSEST: usize = 400;
/// Gauss–Seidel sweeps (forward and backward) before and after each coarse correction.
fn sweeps() -> usize { envn("AMG_SWEEPS", 1) }

struct Level {
    depth: usize,
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
            let (p_tent, b_coarse, node_of_coarse, agg_pos) = if envn("AMG_PU", 1) == 1 {
                partition_of_unity(n_nodes, &pos, &edges, &node_of_dof, &b)
            } else {
                let (agg_of_node, agg_pos) = aggregate(n_nodes, &pos, &edges);
                let (p, b, c) = tentative(&node_of_dof, &agg_of_node, agg_pos.len(), &b);
                (p, b, c, agg_pos)
            };
            if p_tent.cols as f64 > 0.9 * n as f64 {
                levels.push(Level::new(a, inv_diag, Csr::default()));
                break;
            }
            let mut p = p_tent;
            for _ in 0..if levels.len() < envn("AMG_PSMOOTH_LEVELS", 99) { envn("AMG_PSMOOTH", 1) } else { 0 } {
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
        for (d, l) in levels.iter_mut().enumerate() {
            l.depth = d;
        }
        let coarse = Dense::factor(&levels.last().unwrap().a);
        if std::env::var_os("INKWARP_AMG_DEBUG").is_some() {
            for l in &levels {
                eprintln!("level: {} unknowns, {} nonzeros", l.a.rows, l.a.nnz());
            }
        }
        Hierarchy { levels, coarse }
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
        Level { depth: 0, a, inv_diag, p, pt, x: vec![[0.0; 2]; n], b: vec![[0.0; 2]; n], r: vec![[0.0; 2]; n] }
    }
}

fn cycle(levels: &mut [Level], coarse: &Dense) {
    let (l, rest) = levels.split_first_mut().unwrap();
    let sweeps = if l.depth == 0 { sweeps() } else { envn("AMG_COARSE_SWEEPS", sweeps()) };
    if rest.is_empty() {
        coarse.solve(&l.b, &mut l.x);
        return;
    }
    l.x.iter_mut().for_each(|x| *x = [0.0; 2]);
    for _ in 0..sweeps {
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
    for _ in 0..sweeps {
        gauss_seidel(&l.a, &l.inv_diag, &l.b, &mut l.x);
    }
}

/// One symmetric Gauss–Seidel sweep (forward, then backward).
fn gauss_seidel(a: &Csr, inv_diag: &[f64], b: &[V2], x: &mut [V2]) {
    let n = a.rows;
    let relax = |i: usize, x: &mut [V2]| {
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

/// The tentative prolongation as a partition of unity: lattice nodes every `H` positions,
/// each with the bilinear hat `Φ` of half width `H`; each link-connected part of a hat's
/// box (its nodes, joined by `edges` inside the box) is an aggregate, and its functions are
/// `Φ · B` orthonormalised (`Φ B_agg = Q R`, rank 1–3). The hats sum to one at every node
/// and each node lies in one part of each box, so `P_tent B_coarse = B` with `B_coarse` the
/// rows of every `R`. Returns `P_tent`, `B_coarse`, each coarse unknown's aggregate and each
/// aggregate's lattice position.
fn partition_of_unity(n: usize, pos: &[(u32, u32)], edges: &[(u32, u32)], node_of_dof: &[u32], b: &[[f64; 3]]) -> (Csr, Vec<[f64; 3]>, Vec<u32>, Vec<(u32, u32)>) {
    let hw = block_size();
    let counting = |keys: &mut dyn Iterator<Item = (usize, u32)>, buckets: usize, len: usize| {
        let items: Vec<(usize, u32)> = keys.collect();
        let mut start = vec![0usize; buckets + 1];
        for &(k, _) in &items {
            start[k + 1] += 1;
        }
        for k in 0..buckets {
            start[k + 1] += start[k];
        }
        let mut next = start.clone();
        let mut out = vec![0u32; len.max(items.len())];
        for &(k, v) in &items {
            out[next[k]] = v;
            next[k] += 1;
        }
        out.truncate(items.len());
        (start, out)
    };
    // Unknowns of each node, neighbours of each node.
    let (dof_start, dofs) = counting(&mut node_of_dof.iter().enumerate().map(|(i, &nd)| (nd as usize, i as u32)), n, node_of_dof.len());
    let (adj_start, adj) = counting(&mut edges.iter().flat_map(|&(i, j)| [(i as usize, j), (j as usize, i)]), n, 2 * edges.len());
    // The boxes each node lies in, with the hat's weight there.
    let nx = pos.iter().map(|p| p.0).max().unwrap_or(0) / hw + 2;
    let mut memberships: Vec<(usize, u32, f64)> = Vec::new();
    for (i, &(x, y)) in pos.iter().enumerate() {
        for bx in [x / hw, x / hw + 1] {
            let wx = 1.0 - (x as f64 - (bx * hw) as f64).abs() / hw as f64;
            for by in [y / hw, y / hw + 1] {
                let wy = 1.0 - (y as f64 - (by * hw) as f64).abs() / hw as f64;
                if wx > 0.0 && wy > 0.0 {
                    memberships.push(((by * nx + bx) as usize, i as u32, wx * wy));
                }
            }
        }
    }
    memberships.sort_by_key(|m| (m.0, m.1));
    let mut local = vec![u32::MAX; n];
    let mut triplets: Vec<(u32, u32, f64)> = Vec::new();
    let mut b_coarse = Vec::new();
    let mut coarse_agg = Vec::new();
    let mut agg_pos = Vec::new();
    let mut k = 0;
    while k < memberships.len() {
        let bid = memberships[k].0;
        let end = k + memberships[k..].iter().take_while(|m| m.0 == bid).count();
        let group = &memberships[k..end];
        for (t, m) in group.iter().enumerate() {
            local[m.1 as usize] = t as u32;
        }
        let mut uf = UnionFind((0..group.len() as u32).collect());
        for (t, m) in group.iter().enumerate() {
            let i = m.1 as usize;
            for &j in &adj[adj_start[i]..adj_start[i + 1]] {
                if local[j as usize] != u32::MAX {
                    uf.union(t as u32, local[j as usize]);
                }
            }
        }
        let roots: Vec<u32> = (0..group.len() as u32).map(|t| uf.find(t)).collect();
        let mut done = vec![false; group.len()];
        for t0 in 0..group.len() {
            if done[roots[t0] as usize] {
                continue;
            }
            done[roots[t0] as usize] = true;
            // The part's unknowns and their weights.
            let part: Vec<(u32, f64)> = (t0..group.len())
                .filter(|&t| roots[t] == roots[t0])
                .flat_map(|t| dofs[dof_start[group[t].1 as usize]..dof_start[group[t].1 as usize + 1]].iter().map(move |&d| (d, group[t].2)))
                .collect();
            let agg = agg_pos.len() as u32;
            agg_pos.push(((bid % nx as usize) as u32, (bid / nx as usize) as u32));
            let mut q: Vec<Vec<f64>> = Vec::new();
            for j in 0..3 {
                let mut v: Vec<f64> = part.iter().map(|&(d, wt)| wt * b[d as usize][j]).collect();
                let norm0 = v.iter().map(|v| v * v).sum::<f64>().sqrt();
                if norm0 == 0.0 {
                    continue;
                }
                for _ in 0..2 {
                    for qc in &q {
                        let d: f64 = qc.iter().zip(&v).map(|(a, b)| a * b).sum();
                        v.iter_mut().zip(qc).for_each(|(v, q)| *v -= d * q);
                    }
                }
                let norm = v.iter().map(|v| v * v).sum::<f64>().sqrt();
                if norm > 1e-7 * norm0 {
                    v.iter_mut().for_each(|v| *v /= norm);
                    q.push(v);
                }
            }
            for qc in &q {
                let c = b_coarse.len() as u32;
                let mut r = [0.0; 3];
                for (t, &(d, wt)) in part.iter().enumerate() {
                    triplets.push((d, c, qc[t]));
                    for (j, r) in r.iter_mut().enumerate() {
                        *r += qc[t] * wt * b[d as usize][j];
                    }
                }
                b_coarse.push(r);
                coarse_agg.push(agg);
            }
        }
        for m in group {
            local[m.1 as usize] = u32::MAX;
        }
        k = end;
    }
    triplets.sort_unstable_by_key(|t| (t.0, t.1));
    let rows = node_of_dof.len();
    let mut p = Csr { rows, cols: b_coarse.len(), start: vec![0; rows + 1], col: Vec::with_capacity(triplets.len()), val: Vec::with_capacity(triplets.len()) };
    for &(r, c, v) in &triplets {
        p.start[r as usize + 1] += 1;
        p.col.push(c);
        p.val.push(v);
    }
    for r in 0..rows {
        p.start[r + 1] += p.start[r];
    }
    (p, b_coarse, coarse_agg, agg_pos)
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
    let ap = a.mul(p_tent);
    let mut p = Csr { rows: ap.rows, cols: ap.cols, start: vec![0], col: Vec::with_capacity(ap.nnz()), val: Vec::with_capacity(ap.nnz()) };
    for i in 0..ap.rows {
        let f = -omega * inv_diag[i];
        let (ac, av) = ap.row(i);
        let (tc, tv) = p_tent.row(i);
        // Both rows' columns ascend: merge them.
        let (mut x, mut y) = (0, 0);
        while x < ac.len() || y < tc.len() {
            let take_a = y == tc.len() || (x < ac.len() && ac[x] <= tc[y]);
            let take_t = x == ac.len() || (y < tc.len() && tc[y] <= ac[x]);
            let c = if take_a { ac[x] } else { tc[y] };
            let mut v = 0.0;
            if take_a {
                v += f * av[x];
                x += 1;
            }
            if take_t {
                v += tv[y];
                y += 1;
            }
            p.col.push(c);
            p.val.push(v);
        }
        p.start.push(p.col.len());
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

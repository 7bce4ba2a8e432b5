//! A small extra coarse space along cuts and hole borders: on each side of them,
//! functions that run linearly up to the tear (see [`Deflation`]).

use rayon::prelude::*;

use super::level::{Level, PAD, V2, W2, WS};

/// Half widths of the hats, in nodes: one lattice for the tear's own scale and one for the
/// parts of the grid it nearly encloses.
const HALF_WIDTHS: [usize; 2] = [32, 96];
/// At most this many groups of three functions; past it the solve goes without (the dense
/// factorisation would cost more than the cycles it saves).
const MAX_GROUPS: usize = 240;
/// A side of a box with fewer unknowns than this gets no functions.
const MIN_NODES: usize = 16;

/// Functions `hat · {1, x, y}` on each side of a tear. `hat` is a bilinear hat of half width
/// `H` around a node of the `H`-spaced lattice whose box `[−H, H]²` holds a missing link
/// between active nodes (a cut) or the border of a thin hole (see [`Deflation::new`]), cut
/// off to one side: a part of the box connected by links inside it. Neither
/// coarse space of the hierarchy has these functions: the link-aware one extrapolates
/// constants at a tear and the plain one runs across it. They are what a few cycles leave
/// of the error there (a smooth motion of one side against the other, bending where they
/// join), and few: a solve uses them by deflation, each preconditioner application solving
/// exactly on their span first, `z = Q r + B (r − A Q r)` with `Q = Φ (ΦᵀAΦ)⁻¹ Φᵀ` and `B`
/// the cycle.
#[derive(Debug)]
pub(crate) struct Deflation {
    groups: Vec<Group>,
    /// Cholesky factor of `ΦᵀAΦ` (row-major, `n × n`, lower), with the functions that the
    /// others (nearly) span dropped (`keep` false: coefficient zero).
    chol: Vec<f64>,
    keep: Vec<bool>,
    /// `Φ` and `A Φ` node by node (see [`ByNode`]), for the passes that write the grid.
    phi: ByNode,
    aphi: ByNode,
}

/// A set of groups' functions stored node by node: the nodes they touch (ascending), and
/// for each the groups' values there (`start[k]..start[k + 1]` of `entries`). Writing node
/// by node, the passes run in parallel without two threads sharing a node.
#[derive(Debug, Default)]
struct ByNode {
    nodes: Vec<u32>,
    start: Vec<u32>,
    entries: Vec<(u32, [WS; 3])>,
}

impl ByNode {
    fn new<'a>(n: usize, groups: impl Iterator<Item = (&'a [u32], &'a [[WS; 3]])>) -> ByNode {
        let mut lists: Vec<Vec<(u32, [WS; 3])>> = vec![Vec::new(); n];
        for (g, (ids, vals)) in groups.enumerate() {
            for (&p, &v) in ids.iter().zip(vals) {
                lists[p as usize].push((g as u32, v));
            }
        }
        let mut out = ByNode::default();
        for (p, l) in lists.into_iter().enumerate() {
            if !l.is_empty() {
                out.nodes.push(p as u32);
                out.start.push(out.entries.len() as u32);
                out.entries.extend(l);
            }
        }
        out.start.push(out.entries.len() as u32);
        out
    }

    /// `v[p] += sign · Σ_groups values(p) · c[group]` at every node p.
    fn apply(&self, v: &mut [W2], c: &[V2], sign: WS) {
        const CHUNK: usize = 4096;
        let cw: Vec<[[WS; 3]; 2]> = c.chunks_exact(3).map(|c| [0, 1].map(|k| [c[0][k] as WS, c[1][k] as WS, c[2][k] as WS])).collect();
        // The nodes ascend, so chunks of them own disjoint stretches of `v`: (first node's
        // index in `nodes`, stretch, the stretch's offset in `v`).
        let mut stretches = Vec::new();
        let (mut rest, mut offset) = (v, 0);
        for k0 in (0..self.nodes.len()).step_by(CHUNK) {
            let end = self.nodes.get(k0 + CHUNK).map_or(rest.len() + offset, |&p| p as usize);
            let (head, tail) = rest.split_at_mut(end - offset);
            stretches.push((k0, head, offset));
            (rest, offset) = (tail, end);
        }
        stretches.into_par_iter().for_each(|(k0, out, offset)| {
            for k in k0..(k0 + CHUNK).min(self.nodes.len()) {
                let mut s = [0.0 as WS; 2];
                for &(g, a) in &self.entries[self.start[k] as usize..self.start[k + 1] as usize] {
                    let c = &cw[g as usize];
                    s[0] += a[0] * c[0][0] + a[1] * c[0][1] + a[2] * c[0][2];
                    s[1] += a[0] * c[1][0] + a[1] * c[1][1] + a[2] * c[1][2];
                }
                let o = &mut out[self.nodes[k] as usize - offset];
                o[0] += sign * s[0];
                o[1] += sign * s[1];
            }
        });
    }
}

/// The three functions `hat · {1, x, y}` (scaled by `1/H`) of one side of one box.
#[derive(Debug)]
struct Group {
    /// Padded indices of the unknowns of the side, ascending, and the functions there.
    ids: Vec<u32>,
    phi: Vec<[WS; 3]>,
}

impl Deflation {
    /// The space for `fine` (the finest level, its fixed nodes marked), or `None` when it
    /// has no tear, or so long a one that the space would be too large.
    pub fn new(fine: &Level) -> Option<Deflation> {
        let geo = &fine.geo;
        let (w, h, wp) = (geo.w, geo.h, fine.wp);
        let idx = |x: usize, y: usize| y * w + x;
        // Nodes beside a missing link between active nodes (a cut), and beside a thin hole:
        // a group of inactive nodes with at most four of them per link to an active node
        // (a strip up to about eight nodes wide). Wider holes have borders like the grid's
        // own edges, which the hierarchy handles.
        let (mut cut, mut rim) = (vec![false; w * h], vec![false; w * h]);
        let mut any = false;
        let (hole, holes) = geo.holes();
        for y in 0..h {
            for x in 0..w {
                let i = idx(x, y);
                if !geo.active[i] {
                    continue;
                }
                if x + 1 < w && geo.active[i + 1] && !geo.right[i] {
                    (cut[i], cut[i + 1], any) = (true, true, true);
                }
                if y + 1 < h && geo.active[i + w] && !geo.down[i] {
                    (cut[i], cut[i + w], any) = (true, true, true);
                }
                let around = [(x > 0).then(|| i - 1), (x + 1 < w).then(|| i + 1), (y > 0).then(|| i - w), (y + 1 < h).then(|| i + w)];
                if around.into_iter().flatten().any(|j| !geo.active[j] && holes[hole[j] as usize].thin) {
                    (rim[i], any) = (true, true);
                }
            }
        }
        if !any {
            return None;
        }
        let unknown = |p: usize| fine.inv_diag[p] != 0.0;
        let pidx = |x: usize, y: usize| (y + PAD) * wp + x + PAD;
        let mut groups = Vec::new();
        let mut label = vec![u32::MAX; w * h];
        for half in HALF_WIDTHS {
            let hf = half as f64;
            for cy in (0..h + half - 1).step_by(half) {
                for cx in (0..w + half - 1).step_by(half) {
                    let (x0, x1) = (cx.saturating_sub(half), (cx + half).min(w - 1));
                    let (y0, y1) = (cy.saturating_sub(half), (cy + half).min(h - 1));
                    let in_box = |f: &dyn Fn(usize) -> bool| (y0..=y1).any(|y| (x0..=x1).any(|x| f(idx(x, y))));
                    if !in_box(&|i| cut[i] || rim[i]) {
                        continue;
                    }
                    // The box's parts connected by links inside it, and whether each lies on
                    // a tear.
                    let mut parts: Vec<(Vec<(usize, usize)>, bool)> = Vec::new();
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            if !geo.active[idx(x, y)] || label[idx(x, y)] != u32::MAX {
                                continue;
                            }
                            let id = parts.len() as u32;
                            label[idx(x, y)] = id;
                            let (mut stack, mut nodes, mut torn) = (vec![(x, y)], Vec::new(), false);
                            while let Some((px, py)) = stack.pop() {
                                let i = idx(px, py);
                                nodes.push((px, py));
                                torn |= cut[i] || rim[i];
                                let mut go = |qx: usize, qy: usize| {
                                    if label[idx(qx, qy)] == u32::MAX {
                                        label[idx(qx, qy)] = id;
                                        stack.push((qx, qy));
                                    }
                                };
                                if px > x0 && geo.right[i - 1] {
                                    go(px - 1, py);
                                }
                                if px < x1 && geo.right[i] {
                                    go(px + 1, py);
                                }
                                if py > y0 && geo.down[i - w] {
                                    go(px, py - 1);
                                }
                                if py < y1 && geo.down[i] {
                                    go(px, py + 1);
                                }
                            }
                            parts.push((nodes, torn));
                        }
                    }
                    for (nodes, _) in &parts {
                        for &(x, y) in nodes {
                            label[idx(x, y)] = u32::MAX;
                        }
                    }
                    for (mut nodes, torn) in parts {
                        if !torn {
                            continue;
                        }
                        nodes.sort_unstable_by_key(|&(x, y)| (y, x));
                        let (mut ids, mut phi) = (Vec::new(), Vec::new());
                        for (x, y) in nodes {
                            let p = pidx(x, y);
                            let (dx, dy) = ((x as f64 - cx as f64) / hf, (y as f64 - cy as f64) / hf);
                            let hat = (1.0 - dx.abs()).max(0.0) * (1.0 - dy.abs()).max(0.0);
                            if unknown(p) && hat > 0.0 {
                                ids.push(p as u32);
                                phi.push([hat as WS, (hat * dx) as WS, (hat * dy) as WS]);
                            }
                        }
                        if ids.len() >= MIN_NODES {
                            groups.push(Group { ids, phi });
                        }
                    }
                }
            }
        }
        if groups.is_empty() || groups.len() > MAX_GROUPS {
            return None;
        }
        // A φ of each group on the unknowns within two nodes of its own (ascending).
        let n = fine.len_padded();
        let aphi: Vec<(Vec<u32>, Vec<[WS; 3]>)> = groups
            .par_iter()
            .map_init(
                || (vec![[0.0f64; 2]; n], vec![[0.0f64; 2]; n], vec![false; n]),
                |(a, b, seen), g| {
                    for (&p, v) in g.ids.iter().zip(&g.phi) {
                        a[p as usize] = [v[0] as f64, v[1] as f64];
                        b[p as usize] = [v[2] as f64, 0.0];
                    }
                    let mut reach = Vec::new();
                    for &p in &g.ids {
                        for dy in -2isize..=2 {
                            for dx in -2isize..=2 {
                                let q = (p as isize + dy * wp as isize + dx) as usize;
                                if !seen[q] && unknown(q) {
                                    seen[q] = true;
                                    reach.push(q);
                                }
                            }
                        }
                    }
                    reach.sort_unstable();
                    let mut vals = Vec::with_capacity(reach.len());
                    for &q in &reach {
                        seen[q] = false;
                        let (ra, rb) = (fine.fine_residual_at(a, q), fine.fine_residual_at(b, q));
                        vals.push([-ra[0] as WS, -ra[1] as WS, -rb[0] as WS]);
                    }
                    for &p in &g.ids {
                        a[p as usize] = [0.0; 2];
                        b[p as usize] = [0.0; 2];
                    }
                    (reach.into_iter().map(|q| q as u32).collect(), vals)
                },
            )
            .collect();
        // E = Φᵀ A Φ, dense, from the pairs of groups whose ranges of nodes overlap.
        let m = 3 * groups.len();
        let span = |ids: &[u32]| (ids[0], ids[ids.len() - 1]);
        let cols: Vec<Vec<f64>> = (0..groups.len())
            .into_par_iter()
            .map_init(
                || vec![[0.0f64; 3]; n],
                |dense, j| {
                    let (aids, avals) = &aphi[j];
                    for (&q, v) in aids.iter().zip(avals) {
                        dense[q as usize] = [v[0] as f64, v[1] as f64, v[2] as f64];
                    }
                    let (lo, hi) = span(aids);
                    let mut col = vec![0.0; 3 * m];
                    for (i, gi) in groups.iter().enumerate() {
                        let (a, b) = span(&gi.ids);
                        if b < lo || a > hi {
                            continue;
                        }
                        for (&p, f) in gi.ids.iter().zip(&gi.phi) {
                            let d = dense[p as usize];
                            for s in 0..3 {
                                for t in 0..3 {
                                    col[t * m + 3 * i + s] += f[s] as f64 * d[t];
                                }
                            }
                        }
                    }
                    for &q in aids {
                        dense[q as usize] = [0.0; 3];
                    }
                    col
                },
            )
            .collect();
        let e = |i: usize, j: usize| cols[j / 3][(j % 3) * m + i];
        // Cholesky, dropping functions that the earlier ones (nearly) span.
        let scale = (0..m).map(|i| e(i, i)).fold(0.0, f64::max);
        let mut chol = vec![0.0; m * m];
        let mut keep = vec![false; m];
        for j in 0..m {
            let mut d = e(j, j);
            for k in 0..j {
                d -= chol[j * m + k] * chol[j * m + k];
            }
            if d <= 1e-6 * scale {
                continue;
            }
            let l = d.sqrt();
            chol[j * m + j] = l;
            keep[j] = true;
            for i in j + 1..m {
                let mut s = 0.5 * (e(i, j) + e(j, i));
                for k in 0..j {
                    s -= chol[i * m + k] * chol[j * m + k];
                }
                chol[i * m + j] = s / l;
            }
        }
        let phi = ByNode::new(n, groups.iter().map(|g| (&g.ids[..], &g.phi[..])));
        let aphi = ByNode::new(n, aphi.iter().map(|(ids, vals)| (&ids[..], &vals[..])));
        Some(Deflation { groups, chol, keep, phi, aphi })
    }

    /// `Φᵀ v` per component, `v` read node by node through `at`.
    fn project(&self, at: impl Fn(usize) -> V2 + Sync) -> Vec<V2> {
        self.groups
            .par_iter()
            .flat_map_iter(|g| {
                let mut s = [[0.0f64; 2]; 3];
                for (&p, f) in g.ids.iter().zip(&g.phi) {
                    let v = at(p as usize);
                    for k in 0..3 {
                        s[k][0] += f[k] as f64 * v[0];
                        s[k][1] += f[k] as f64 * v[1];
                    }
                }
                s
            })
            .collect()
    }

    /// `c = (ΦᵀAΦ)⁻¹ Φᵀ r` per component (zero for dropped functions).
    pub fn coefficients(&self, r: &[V2]) -> Vec<V2> {
        let m = self.keep.len();
        let mut c = self.project(|p| r[p]);
        for a in 0..m {
            if !self.keep[a] {
                c[a] = [0.0; 2];
                continue;
            }
            for b in 0..a {
                let l = self.chol[a * m + b];
                c[a] = [c[a][0] - l * c[b][0], c[a][1] - l * c[b][1]];
            }
            let l = self.chol[a * m + a];
            c[a] = [c[a][0] / l, c[a][1] / l];
        }
        for a in (0..m).rev() {
            if !self.keep[a] {
                continue;
            }
            for b in a + 1..m {
                let l = self.chol[b * m + a];
                c[a] = [c[a][0] - l * c[b][0], c[a][1] - l * c[b][1]];
            }
            let l = self.chol[a * m + a];
            c[a] = [c[a][0] / l, c[a][1] / l];
        }
        c
    }

    /// `f ← f − A Φ c`.
    pub fn remove(&self, f: &mut [W2], c: &[V2]) {
        self.aphi.apply(f, c, -1.0);
    }

    /// `z ← z + Φ c`.
    pub fn add(&self, z: &mut [W2], c: &[V2]) {
        self.phi.apply(z, c, 1.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use crate::solve::tests::fine_level;

    /// `Φᵀ v` per component.
    fn project(d: &Deflation, v: &[W2]) -> Vec<V2> {
        d.project(|p| [v[p][0] as f64, v[p][1] as f64])
    }

    #[test]
    fn the_space_takes_out_every_part_of_the_residual_it_can_represent() {
        // After r ← r − A Φ c with c = (ΦᵀAΦ)⁻¹ Φᵀ r, what is left is orthogonal to the
        // functions kept. Three fixed corners pin the affine functions.
        let n = 100;
        let mut grid = Grid::new(n, n);
        grid.add_cut(&[[20.0, 30.5], [80.0, 60.5]]);
        let fixed = (0..n * n).map(|i| [0, n - 1, n * n - 1].contains(&i)).collect();
        let level = fine_level(&grid, Some(fixed), 0.0);
        let d = Deflation::new(&level).expect("a cut gets the space");
        let kept = d.keep.iter().filter(|&&k| k).count();
        assert!(kept >= 12, "{kept} functions kept of {}", d.keep.len());
        let r: Vec<V2> = (0..level.len_padded())
            .map(|p| if level.inv_diag[p] != 0.0 { [((p * 7919) % 101) as f64 - 50.0, ((p * 104729) % 97) as f64 - 48.0] } else { [0.0; 2] })
            .collect();
        let c = d.coefficients(&r);
        let mut left: Vec<W2> = r.iter().map(|v| [v[0] as WS, v[1] as WS]).collect();
        d.remove(&mut left, &c);
        let before = project(&d, &r.iter().map(|v| [v[0] as WS, v[1] as WS]).collect::<Vec<_>>());
        let after = project(&d, &left);
        let size = before.iter().map(|v| v[0].abs().max(v[1].abs())).fold(0.0, f64::max);
        let rest = after.iter().zip(&d.keep).filter(|(_, &k)| k).map(|(v, _)| v[0].abs().max(v[1].abs())).fold(0.0, f64::max);
        // The space is applied in f32, as the cycles are.
        assert!(rest < 1e-3 * size, "Φᵀ r: {size} before, {rest} after");
    }

    #[test]
    fn an_open_grid_and_a_wide_hole_get_no_space() {
        assert!(Deflation::new(&fine_level(&Grid::new(80, 80), None, 0.0)).is_none());
        // A hole covering the left half: its border is a natural boundary, one side only.
        let grid = Grid::from_active(80, 80, (0..80 * 80).map(|i| i % 80 >= 40).collect());
        assert!(Deflation::new(&fine_level(&grid, None, 0.0)).is_none());
    }
}

//! The first coarse level's operator applied as the Galerkin operator of the same grid
//! without fixed nodes, plus a few terms per fixed node.
//!
//! The finest level's fixed nodes have empty prolongation rows: `P = D P₀`, with `P₀` the
//! link-aware prolongation of the grid as if nothing were fixed and `D` zero on fixed nodes.
//! So the first coarse level is `A₁ = P₀ᵀ D A D P₀`, with `A` the energy's matrix over every
//! node. Written as `A₁ = P₀ᵀ A P₀ − P₀ᵀ C P₀`, where `C = A − D A D` keeps the entries of
//! `A` in a fixed node's row or column:
//!
//! ```text
//! P₀ᵀ C P₀ = Σ_p (u_p w_pᵀ + w_p u_pᵀ) − Σ_p Σ_q A_pq u_p u_qᵀ,   u_p = P₀ᵀ e_p, w_p = P₀ᵀ A e_p
//! ```
//!
//! over fixed nodes p, q: `u_p` reaches the (at most four) coarse corners of p, `w_p` the
//! corners of p's 5 × 5 neighbourhood, and `A_pq` is nonzero only for fixed nodes within two
//! nodes of each other. Every coarse node near a fixed one has a stencil of its own in
//! `A₁`, applied node by node from a table; `P₀ᵀ A P₀` instead has the regular stencil away
//! from borders, holes and cuts, which runs through the fast kernel of regular nodes, and
//! the terms per fixed node cost a few dozen products each. At 513 × 513 (two cores) the
//! first coarse level's product took 0.41–0.45 ms with 4000 fixed nodes, and 0.23 ms with
//! 1000, with every stencil from the table; 0.25 and 0.19 ms this way (0.13 ms with 10).
//! The terms are kept row by row with their nodes' columns, so a product visits them, not
//! every node of the level: 0.185 → 0.16 ms with 4000, 0.145 → 0.12 ms with 1000 (0.088
//! ms with 10; another day, the same machine).

use rayon::prelude::*;

use super::level::{fine_row, galerkin_for, Geometry, Level, Operator, Real};

/// Fewer fixed nodes make too few stencils irregular to pay for the second Galerkin
/// operator's setup.
const MIN_PINS: usize = 256;
/// From this many fixed nodes their terms are summed in parallel.
const PAR_MIN_PINS: usize = 2048;

/// The terms that turn the first coarse level of the grid without fixed nodes into the
/// first coarse level of the grid with them (see the module doc).
#[derive(Debug)]
pub(crate) struct Pinned {
    /// `P₀ᵀ A P₀`: the Galerkin operator of the grid with nothing fixed.
    pub open: Operator,
    /// Per fixed node: `u_p`, its coarse corners (padded index, weight; weights may be 0).
    corners: Vec<[(u32, f64); 4]>,
    /// Per fixed node: `w_p` (padded index, value), from `reach_start[k]`.
    reach_start: Vec<u32>,
    reach: Vec<(u32, f64)>,
    /// Per fixed node: the fixed nodes within reach and `A_pq` (itself included), from
    /// `near_start[k]`.
    near_start: Vec<u32>,
    near: Vec<(u32, f64)>,
    /// Per padded row of the level, from `row_start[r]`: its coarse nodes' terms, by node
    /// (padded column) and then by fixed node: the column, the fixed node whose terms
    /// reach it, and its weight in their `u` and in their `w`. Only unknowns of the level,
    /// so a product visits the terms, not every node of the level.
    row_start: Vec<u32>,
    gather: Vec<(u32, u32, f64, f64)>,
}

impl Pinned {
    /// The terms for `coarse`, the Galerkin level of the finest level `fine`, when it has
    /// fixed nodes far enough apart for them to cost less than the stencils they make
    /// irregular (each isolated fixed node makes about twenty coarse stencils its own).
    pub fn new(fine: &Level, coarse: &Level) -> Option<Pinned> {
        let Operator::Fine { flags, tau, .. } = &fine.op else { return None };
        let Operator::Stored { ids, .. } = &coarse.op else { return None };
        let g = &fine.geo;
        let fixed = g.fixed.as_ref()?;
        let (w, h) = (g.w, g.h);
        // A geometry with holes filled for the prolongation (`Level::with_holes_filled`) is
        // not the operator's: its filled nodes are free and have no diagonal.
        if (0..w * h).any(|i| g.active[i] && !fixed[i] && fine.inv_diag[fine.pidx(i % w, i / w)] == 0.0) {
            return None;
        }
        let pins: Vec<usize> = (0..w * h).filter(|&i| fixed[i] && g.active[i]).collect();
        let irregular = ids.iter().zip(&coarse.inv_diag).filter(|&(&id, &d)| id != 0 && d != 0.0).count();
        if pins.len() < MIN_PINS || 4 * pins.len() > irregular {
            return None;
        }
        let open_fine = Level::fine(Geometry::new(w, h, g.active.clone(), g.right.clone(), g.down.clone(), None), *tau);
        // Its runs of nodes with stencils of their own are those among this level's unknowns.
        let open = galerkin_for(&open_fine, Some(&coarse.inv_diag)).op;
        drop(open_fine);
        let mut pin_of = vec![u32::MAX; w * h];
        for (k, &i) in pins.iter().enumerate() {
            pin_of[i] = k as u32;
        }
        // P₀'s row of fine node (x, y): its coarse corners and weights.
        let corners_of = |x: usize, y: usize| -> [(u32, f64); 4] {
            let r = g.geo_row(x, y);
            let (cx, cy) = (x / 2, y / 2);
            let at = |dx: usize, dy: usize, v: f64| if v != 0.0 { (coarse.pidx(cx + dx, cy + dy) as u32, v) } else { (coarse.pidx(cx, cy) as u32, 0.0) };
            [at(0, 0, r[0]), at(1, 0, r[1]), at(0, 1, r[2]), at(1, 1, r[3])]
        };
        let mut corners = Vec::with_capacity(pins.len());
        let (mut reach_start, mut reach) = (vec![0u32], Vec::new());
        let (mut near_start, mut near) = (vec![0u32], Vec::new());
        for &i in &pins {
            let (x, y) = (i % w, i / w);
            corners.push(corners_of(x, y));
            let a = fine_row(flags, fine.pidx(x, y), fine.wp, *tau);
            let first = reach.len();
            for dy in -2isize..=2 {
                for dx in -2isize..=2 {
                    let v = a[((dy + 2) * 5 + dx + 2) as usize];
                    if v == 0.0 {
                        continue;
                    }
                    // A nonzero entry is an energy term's node: inside the grid and active.
                    let (jx, jy) = ((x as isize + dx) as usize, (y as isize + dy) as usize);
                    let j = jy * w + jx;
                    if pin_of[j] != u32::MAX {
                        near.push((pin_of[j], v));
                    }
                    for (c, wt) in corners_of(jx, jy) {
                        if wt == 0.0 {
                            continue;
                        }
                        match reach[first..].iter_mut().find(|e: &&mut (u32, f64)| e.0 == c) {
                            Some(e) => e.1 += v * wt,
                            None => reach.push((c, v * wt)),
                        }
                    }
                }
            }
            reach_start.push(reach.len() as u32);
            near_start.push(near.len() as u32);
        }
        // The same terms gathered by the coarse node they reach.
        let mut entries: Vec<(u32, u32, f64, f64)> = Vec::new();
        for k in 0..pins.len() {
            for &(c, wt) in &corners[k] {
                if wt != 0.0 {
                    entries.push((c, k as u32, wt, 0.0));
                }
            }
            for &(c, v) in &reach[reach_start[k] as usize..reach_start[k + 1] as usize] {
                entries.push((c, k as u32, 0.0, v));
            }
        }
        entries.retain(|e| coarse.inv_diag[e.0 as usize] != 0.0);
        entries.sort_unstable_by_key(|e| (e.0, e.1));
        let wp = coarse.wp;
        let mut row_start = vec![0u32; coarse.hp + 1];
        let mut gather: Vec<(u32, u32, f64, f64)> = Vec::with_capacity(entries.len());
        let mut last = (u32::MAX, u32::MAX);
        for (c, k, uw, ww) in entries {
            if (c, k) == last {
                let e = gather.last_mut().unwrap();
                e.2 += uw;
                e.3 += ww;
            } else {
                gather.push(((c as usize % wp) as u32, k, uw, ww));
                row_start[c as usize / wp + 1] += 1;
                last = (c, k);
            }
        }
        for r in 0..coarse.hp {
            row_start[r + 1] += row_start[r];
        }
        Some(Pinned { open, corners, reach_start, reach, near_start, near, row_start, gather })
    }

    /// Per fixed node p, for the product with `x`: `α_p = w_p·x − Σ_q A_pq u_q·x` and
    /// `β_p = u_p·x`, per component, as `[αx, αy, βx, βy]`. The product is then
    /// `P₀ᵀ A P₀ x − Σ_p (α_p u_p + β_p w_p)`.
    pub fn coefficients<T: Real>(&self, x: &[[T; 2]]) -> Vec<[f64; 4]> {
        let u = |c: &[(u32, f64); 4]| {
            let mut s = [0.0; 2];
            for &(i, wt) in c {
                let v = x[i as usize];
                s[0] += wt * v[0].get();
                s[1] += wt * v[1].get();
            }
            s
        };
        let parallel = self.corners.len() >= PAR_MIN_PINS;
        let t: Vec<[f64; 2]> = if parallel { self.corners.par_iter().map(u).collect() } else { self.corners.iter().map(u).collect() };
        let coef = |k: usize| {
            let mut s = [0.0; 2];
            for &(i, v) in &self.reach[self.reach_start[k] as usize..self.reach_start[k + 1] as usize] {
                let xv = x[i as usize];
                s[0] += v * xv[0].get();
                s[1] += v * xv[1].get();
            }
            for &(q, a) in &self.near[self.near_start[k] as usize..self.near_start[k + 1] as usize] {
                s[0] -= a * t[q as usize][0];
                s[1] -= a * t[q as usize][1];
            }
            [s[0], s[1], t[k][0], t[k][1]]
        };
        if parallel { (0..t.len()).into_par_iter().map(coef).collect() } else { (0..t.len()).map(coef).collect() }
    }

    /// Adds the fixed nodes' terms to `out`, padded row `r` of `f − P₀ᵀ A P₀ x`, which
    /// makes it that row of `f − A₁ x`; `coef` from
    /// [`Pinned::coefficients`] of the same `x`.
    pub fn correct_row<T: Real>(&self, coef: &[[f64; 4]], r: usize, out: &mut [[T; 2]]) {
        let terms = &self.gather[self.row_start[r] as usize..self.row_start[r + 1] as usize];
        let mut i = 0;
        while i < terms.len() {
            // One node's terms, summed in order, then added to its entry.
            let c = terms[i].0;
            let mut s = [0.0f64; 2];
            while i < terms.len() && terms[i].0 == c {
                let (_, k, uw, ww) = terms[i];
                let cf = &coef[k as usize];
                s[0] += uw * cf[0] + ww * cf[2];
                s[1] += uw * cf[1] + ww * cf[3];
                i += 1;
            }
            let o = &mut out[c as usize];
            *o = [o[0] + T::of(s[0]), o[1] + T::of(s[1])];
        }
    }
}

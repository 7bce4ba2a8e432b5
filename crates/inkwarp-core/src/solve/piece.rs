//! One piece's solve: conjugate gradients preconditioned by the smoothed-aggregation
//! V-cycle ([`super::amg`]), with the honest stopping rule.

use super::amg::Hierarchy;
use super::matrix::{BoxGrid, System, V2};
use super::{SolveMethod, SolveOptions, SolveReport};
use crate::field::FieldView;

/// Safety factor of the stopping rule on grids without holes or cuts, and with them.
const STOP_MARGIN: f64 = 1.5;
const TORN_STOP_MARGIN: f64 = 3.0;

/// The operator of one piece on its box and its hierarchy: everything that depends on the
/// geometry, the fixed nodes and the tension, not on the fixed nodes' values. Consecutive
/// frames of an animation (and drags in the editor) reuse it.
pub(crate) struct PieceSolver {
    pub w: usize,
    pub h: usize,
    pub active: Vec<bool>,
    pub right: Vec<bool>,
    pub down: Vec<bool>,
    pub tau: f64,
    sys: System,
    hier: Hierarchy,
    torn: bool,
    /// An orthonormal basis (over the unknowns) of the operator's null space: the
    /// preconditioner's output is kept orthogonal to it, so that the iteration never moves
    /// along the free functions (the τ → 0⁺ rule picks those afterwards).
    null: Vec<Vec<(u32, f64)>>,
}

impl PieceSolver {
    pub fn new(w: usize, h: usize, active: Vec<bool>, right: Vec<bool>, down: Vec<bool>, fixed: Vec<bool>, tau: f64, null: &[super::nullspace::Sparse]) -> PieceSolver {
        let g = BoxGrid { w, h, active: &active, right: &right, down: &down };
        let sys = System::new(&g, &fixed, tau);
        let t = std::time::Instant::now();
        let hier = Hierarchy::new(sys.a.clone(), &g, &sys.node, &sys.dof);
        if std::env::var_os("INKWARP_AMG_DEBUG").is_some() {
            eprintln!("setup {:.3}s", t.elapsed().as_secs_f64());
        }
        let torn = (0..w * h).any(|i| !active[i] || (i % w + 1 < w && !right[i]) || (i / w + 1 < h && !down[i]));
        // Only at τ = 0 are the free functions exact null vectors.
        let null = if tau == 0.0 { orthonormal(null, &sys.dof) } else { Vec::new() };
        PieceSolver { w, h, active, right, down, tau, sys, hier, torn, null }
    }

    /// Solves for the fixed nodes' values `value` from `initial` (a start on the box, read
    /// at `(x0, y0)` of its field). Returns every node of the box (`w · h`, zero off the
    /// piece) and the report's solver fields.
    pub fn solve(&mut self, value: &[(usize, V2)], initial: Option<(FieldView, usize, usize)>, options: &SolveOptions) -> (Vec<V2>, SolveReport) {
        let g = BoxGrid { w: self.w, h: self.h, active: &self.active, right: &self.right, down: &self.down };
        let b = self.sys.rhs(&g, value, self.tau);
        let a = &self.sys.a;
        let n = a.rows;
        let inv_diag: Vec<f64> = a.diagonal().iter().map(|&d| if d > 0.0 { 1.0 / d } else { 0.0 }).collect();
        let scaled_max = |r: &[V2]| r.iter().zip(&inv_diag).fold(0.0f64, |m, (r, d)| m.max(r[0].abs() * d).max(r[1].abs() * d));
        let mut report = SolveReport::default();
        let mut x = vec![[0.0; 2]; n];
        let mut r = vec![[0.0; 2]; n];
        let cold = scaled_max(&b);
        if let Some((field, x0, y0)) = initial {
            let fw = field.width();
            for (k, &p) in self.sys.node.iter().enumerate() {
                let (px, py) = (p as usize % self.w, p as usize / self.w);
                let v = field.at_index((y0 + py) * fw + x0 + px);
                x[k] = [v[0] as f64, v[1] as f64];
            }
            a.residual(&b, &x, &mut r);
            // A start worse than none (huge or unrelated values) is dropped for the cold
            // start.
            if !(scaled_max(&r) <= cold) {
                x.iter_mut().for_each(|v| *v = [0.0; 2]);
                r.copy_from_slice(&b);
            }
        } else {
            r.copy_from_slice(&b);
        }
        report.initial_residual = scaled_max(&r);
        let max_cycles = options.max_cycles.unwrap_or(100);
        let margin = if self.torn { TORN_STOP_MARGIN } else { STOP_MARGIN };
        let mut z = vec![[0.0; 2]; n];
        let mut q = vec![[0.0; 2]; n];
        if n == 0 || report.initial_residual == 0.0 {
            report.converged = true;
        } else if options.method == SolveMethod::Southwell {
            let budget = (options.southwell_sweeps * n as f64).round() as usize;
            let (passes, change, finished) = super::southwell::relax(a, &inv_diag, &b, &mut x, budget);
            report.cycles = passes;
            report.final_change_px = change;
            report.converged = finished;
        } else {
            self.hier.precondition(&r, &mut z);
            project(&self.null, &mut z);
            let mut p = z.clone();
            let mut rz = dot(&r, &z);
            let mut last_change = f64::INFINITY;
            let mut ratios = [0.0f64; 2];
            for cycle in 1..=max_cycles {
                if crate::interrupt::requested() {
                    break;
                }
                a.apply(&p, &mut q);
                let pq = dot(&p, &q);
                let alpha = [0, 1].map(|k| if pq[k] > 0.0 { rz[k] / pq[k] } else { 0.0 });
                let mut change = 0.0f64;
                for i in 0..n {
                    for k in 0..2 {
                        let d = alpha[k] * p[i][k];
                        x[i][k] += d;
                        r[i][k] -= alpha[k] * q[i][k];
                        change = change.max(d.abs());
                    }
                }
                report.cycles = cycle;
                report.final_change_px = change;
                // Geometric convergence at rate ρ leaves change·ρ/(1−ρ) to go. Conjugate-
                // gradient steps are not geometric, so ρ is the larger of the last two
                // ratios (0.5 before there is one), and the bound carries a safety margin.
                // A ratio of 0.99 or more (stagnation) never stops.
                let ratio = if last_change.is_finite() && last_change > 0.0 { change / last_change } else { 0.5 };
                ratios = [ratios[1], ratio];
                let rho = ratios[0].max(ratios[1]);
                last_change = change;
                if change.is_finite() && rho < 0.99 && margin * change * (rho / (1.0 - rho)).max(1.0) <= options.tolerance_px {
                    report.converged = true;
                    break;
                }
                self.hier.precondition(&r, &mut z);
                project(&self.null, &mut z);
                let rz_new = dot(&r, &z);
                let beta = [0, 1].map(|k| if rz[k] > 0.0 { rz_new[k] / rz[k] } else { 0.0 });
                for i in 0..n {
                    for k in 0..2 {
                        p[i][k] = z[i][k] + beta[k] * p[i][k];
                    }
                }
                rz = rz_new;
            }
        }
        a.residual(&b, &x, &mut r);
        report.residual = scaled_max(&r);
        let mut out = vec![[0.0; 2]; self.w * self.h];
        for &(i, v) in value {
            out[i] = v;
        }
        for (k, &p) in self.sys.node.iter().enumerate() {
            out[p as usize] = x[k];
        }
        (out, report)
    }
}

fn dot(a: &[V2], b: &[V2]) -> [f64; 2] {
    a.iter().zip(b).fold([0.0; 2], |s, (a, b)| [s[0] + a[0] * b[0], s[1] + a[1] * b[1]])
}

/// The functions of `basis` (on box nodes) that vanish on the fixed nodes (`dof` is
/// `u32::MAX` there and on inactive nodes, where every function is zero) as unknowns'
/// vectors, orthonormalised. (The basis is taken without the gauge pin of a piece whose
/// constraints lie on one line: combinations that move that node are eliminated.)
fn orthonormal(basis: &[super::nullspace::Sparse], dof: &[u32]) -> Vec<Vec<(u32, f64)>> {
    use std::collections::HashMap;
    let mut funcs: Vec<(HashMap<u32, f64>, HashMap<usize, f64>)> = basis
        .iter()
        .map(|f| {
            let (mut free, mut pinned) = (HashMap::new(), HashMap::new());
            for &(i, v) in f {
                if dof[i] != u32::MAX {
                    *free.entry(dof[i]).or_default() += v;
                } else if v != 0.0 {
                    *pinned.entry(i).or_default() += v;
                }
            }
            (free, pinned)
        })
        .collect();
    // Eliminate the values at fixed nodes.
    loop {
        let Some(node) = funcs.iter().find_map(|f| f.1.iter().find(|e| e.1.abs() > 1e-12).map(|e| *e.0)) else { break };
        let k = (0..funcs.len()).max_by(|&a, &b| funcs[a].1.get(&node).map_or(0.0, |v| v.abs()).total_cmp(&funcs[b].1.get(&node).map_or(0.0, |v| v.abs()))).unwrap();
        let pivot = funcs.swap_remove(k);
        let pv = pivot.1[&node];
        for f in &mut funcs {
            let c = f.1.get(&node).copied().unwrap_or(0.0) / pv;
            if c != 0.0 {
                for (&i, &v) in &pivot.0 {
                    *f.0.entry(i).or_default() -= c * v;
                }
                for (&i, &v) in &pivot.1 {
                    *f.1.entry(i).or_default() -= c * v;
                }
                f.1.remove(&node);
            }
        }
    }
    let mut out: Vec<Vec<(u32, f64)>> = Vec::new();
    for (mut dense, _) in funcs {
        let norm0 = dense.values().map(|v| v * v).sum::<f64>().sqrt();
        for _ in 0..2 {
            for q in &out {
                let d: f64 = q.iter().map(|&(i, v)| v * dense.get(&i).copied().unwrap_or(0.0)).sum();
                if d != 0.0 {
                    for &(i, v) in q {
                        *dense.entry(i).or_default() -= d * v;
                    }
                }
            }
        }
        let norm = dense.values().map(|v| v * v).sum::<f64>().sqrt();
        if norm > 1e-8 * norm0 {
            let mut q: Vec<(u32, f64)> = dense.iter().filter(|e| *e.1 != 0.0).map(|(&i, &v)| (i, v / norm)).collect();
            q.sort_unstable_by_key(|e| e.0);
            out.push(q);
        }
    }
    out
}

/// `z ← z − Q Qᵀ z` for the orthonormal sparse columns `q`.
fn project(q: &[Vec<(u32, f64)>], z: &mut [V2]) {
    for q in q {
        let mut d = [0.0; 2];
        for &(i, v) in q {
            d[0] += v * z[i as usize][0];
            d[1] += v * z[i as usize][1];
        }
        for &(i, v) in q {
            z[i as usize][0] -= d[0] * v;
            z[i as usize][1] -= d[1] * v;
        }
    }
}

//! Warm starts from several earlier frames. On a fixed grid with fixed constrained nodes (an animation) the
//! solution is linear in the constraint values: new values close to a combination `Σ αᵢ vᵢ` of earlier ones are
//! answered as closely by `Σ αᵢ uᵢ` of their fields (up to those solves' tolerance). [`WarmHistory`] starts each
//! solve from the least-squares combination of the last few frames (for smooth motion, an extrapolation in time).

use std::{array::from_fn, borrow::Cow, collections::VecDeque};

use crate::field::{Field, FieldView};
use crate::grid::{Constraints, Grid};

use rayon::prelude::*;

use super::{dense_solve, level::V2, solve_constrained, SolveOptions, SolveReport, Solver, CHUNK};

/// How many earlier frames a [`WarmHistory`] keeps.
pub const HISTORY_FRAMES: usize = 3;

/// The error (px) taken for each kept frame when weighing combinations: the default tolerance.
const FRAME_ERROR_PX: f64 = 0.01;

/// The last few solves of one animated surface: their constraint values and fields.
#[derive(Clone, Debug, Default)]
pub struct WarmHistory {
    /// The grid and constrained nodes the entries share.
    grid: Grid,
    nodes: Vec<usize>,
    /// Oldest first: (constraint values, field).
    entries: VecDeque<(Vec<[f64; 2]>, Field)>,
}

impl WarmHistory {
    /// An empty history (the next solve is cold).
    pub fn new() -> Self { Self::default() }

    /// Forgets every earlier frame.
    pub fn clear(&mut self) {
        self.entries.clear();
        self.nodes.clear();
    }

    /// Number of earlier frames kept.
    pub fn len(&self) -> usize { self.entries.len() }

    /// The latest frame's field.
    pub(crate) fn last(&self) -> Option<&Field> { self.entries.back().map(|e| &e.1) }

    /// Whether no frame is kept.
    pub fn is_empty(&self) -> bool { self.entries.is_empty() }

    /// The start for a solve of `c` on `grid`: the prediction or `given`, whichever misses the constraint values
    /// by less (largest difference at a constrained node); `None` when there is neither.
    pub fn start<'a>(&self, grid: &Grid, c: &Constraints, given: Option<&'a Field>) -> Option<Cow<'a, Field>> {
        let miss = |f: &Field| {
            c.nodes.iter().zip(&c.values).fold(0.0f64, |m, (&i, v)| m.max((f.dx[i] as f64 - v[0]).abs()).max((f.dy[i] as f64 - v[1]).abs()))
        };
        match (self.predict(grid, c), given) {
            (Some(p), Some(g)) => Some(if miss(&p) < miss(g) { Cow::Owned(p) } else { Cow::Borrowed(g) }),
            (p, g) => p.map(Cow::Owned).or(g.map(Cow::Borrowed)),
        }
    }

    /// The combination of the kept fields whose values best match `c`'s (per component, see `fit`), or the latest
    /// field when the frames pin other nodes or another grid; `None` when empty or kept for another grid size.
    pub fn predict(&self, grid: &Grid, c: &Constraints) -> Option<Field> {
        let last = self.last().filter(|f| (f.width, f.height) == (grid.width, grid.height))?;
        if self.entries.len() < 2 || *grid != self.grid || c.nodes != self.nodes { return Some(last.clone()) }
        let alpha = [self.fit(&c.values, 0), self.fit(&c.values, 1)];
        let mut out = Field::zeros(grid.width, grid.height);
        for (i, (_, f)) in self.entries.iter().enumerate() {
            let terms = [(&mut out.dx, &f.dx, alpha[0][i] as f32), (&mut out.dy, &f.dy, alpha[1][i] as f32)];
            for (out, v, a) in terms.into_iter().filter(|t| t.2 != 0.0) {
                out.iter_mut().zip(v).for_each(|(o, v)| *o += a * v);
            }
        }
        Some(out)
    }

    /// Least-squares weights of the kept frames' component `q` for `target`, where they beat the latest frame
    /// alone (`[0, …, 1]`) and stay moderate (`Σ|αᵢ| ≤ 16`: no amplifying the frames' errors). Where the fit
    /// through every frame is wild (frames nearly parallel), the fits through subsets are weighed instead, each
    /// by its root mean square miss at the constrained nodes plus `Σ|αᵢ|` × [`FRAME_ERROR_PX`].
    fn fit(&self, target: &[[f64; 2]], q: usize) -> [f64; HISTORY_FRAMES] {
        let k = self.entries.len();
        let latest: [f64; HISTORY_FRAMES] = from_fn(|i| if i + 1 == k { 1.0 } else { 0.0 });
        let dot = |x: &[[f64; 2]], y: &[[f64; 2]]| -> f64 { x.iter().zip(y).map(|(a, c)| a[q] * c[q]).sum() };
        let v = |i: usize| &self.entries[i].0;
        // The Gram matrix G (each product taken once) and b = (vᵢᵀt).
        let (mut g, mut b) = ([[0.0f64; HISTORY_FRAMES]; HISTORY_FRAMES], [0.0f64; HISTORY_FRAMES]);
        for i in 0..k {
            for j in 0..=i {
                g[i][j] = dot(v(i), v(j));
                g[j][i] = g[i][j];
            }
            b[i] = dot(v(i), target);
        }
        let tt = dot(target, target);
        let trace: f64 = (0..k).map(|i| g[i][i]).sum();
        if trace <= 0.0 || target.is_empty() { return latest; }
        let nodes = target.len() as f64;
        // The root mean square miss of weights `w`, from ‖t − Σ wᵢ vᵢ‖² = tᵀt − 2 wᵀb + wᵀG w, and their gain.
        let miss = |w: &[f64; HISTORY_FRAMES]| {
            let mut sq = tt;
            for i in 0..k {
                sq -= 2.0 * w[i] * b[i];
                (0..k).for_each(|j| sq += w[i] * g[i][j] * w[j]);
            }
            (sq.max(0.0) / nodes).sqrt()
        };
        let gain = |w: &[f64; HISTORY_FRAMES]| w[..k].iter().map(|a| a.abs()).sum::<f64>();
        let all = (1usize << k) - 1;
        let mut best = (miss(&latest) + FRAME_ERROR_PX, latest);
        // Every frame first, then the subsets.
        for subset in (1..=all).rev() {
            let frames: Vec<usize> = (0..k).filter(|&i| subset & (1 << i) != 0).collect();
            let ridge = |i: usize, j: usize| g[i][j] + if i == j { 1e-10 * trace } else { 0.0 };
            let m: Vec<Vec<f64>> = frames.iter().map(|&i| frames.iter().map(|&j| ridge(i, j)).collect()).collect();
            let rhs = frames.iter().map(|&i| [b[i], 0.0]).collect();
            let Some(x) = dense_solve(m, rhs).filter(|x| x.iter().all(|v| v[0].is_finite())) else { continue };
            let mut w = [0.0; HISTORY_FRAMES];
            frames.iter().zip(&x).for_each(|(&i, v)| w[i] = v[0]);
            if subset == all && gain(&w) <= 16.0 { return if miss(&w) < miss(&latest) { w } else { latest }; }
            let score = miss(&w) + FRAME_ERROR_PX * gain(&w);
            if score < best.0 { best = (score, w) }
        }
        best.1
    }

    /// Keeps the solve on `grid` with constraints `c` that gave `field`.
    pub fn record(&mut self, grid: &Grid, c: &Constraints, field: &Field) {
        if *grid != self.grid || c.nodes != self.nodes {
            self.entries.clear();
            self.grid = grid.clone();
            self.nodes = c.nodes.clone();
        }
        if self.entries.len() == HISTORY_FRAMES { self.entries.pop_front(); }
        self.entries.push_back((c.values.clone(), field.clone()));
    }
}

/// The solve of constraints `c` on `grid` (the coarse one at `grid_step` above 1) with `solver`, from its
/// history's start when `warm`, which then keeps the result; from `initial` otherwise.
pub(crate) fn solve_from(
    grid: &Grid, c: &Constraints, options: &SolveOptions, initial: Option<FieldView<'_>>, solver: &mut Solver, warm: bool,
) -> (Field, SolveReport) {
    solver.store.answers = !warm;
    if !warm { return solve_constrained(grid, c, options, initial, &mut solver.store); }
    let given = initial.map(|f| f.to_field());
    let start = solver.history.start(grid, c, given.as_deref());
    let (field, report) = solve_constrained(grid, c, options, start.as_deref().map(FieldView::from), &mut solver.store);
    solver.history.record(grid, c, &field);
    (field, report)
}

/// The most floats (fixed nodes × nodes) a piece's [`Answers`] may come to keep: 64 MB.
const ANSWER_FLOATS: usize = 1 << 24;

/// A start from [`Answers`] is taken where its estimated error is within this many tolerances (DESIGN §4's contract).
const CONTRACT: f64 = 5.0;

/// Values with less than this share of their size outside the span lie in it.
const INDEPENDENT: f64 = 1e-9;

/// A kept piece's earlier answers (one hierarchy: same grid, fixed nodes and tension), for its next solves'
/// starts. Each component of an answer is linear in its constraint values, so values in the span of earlier
/// ones are answered, up to those answers' errors, by the same combination of their fields. Kept as an
/// orthonormal basis of the values seen, the matching fields and each field's error per unit of value (the
/// stopping rule's estimates, combined in quadrature). The hierarchy's key holds the fixed nodes, so every
/// value lists the same nodes in the same order.
#[derive(Debug, Default)]
pub(crate) struct Answers { basis: Vec<Vec<f64>>, fields: Vec<Vec<f32>>, error: Vec<f64> }

impl Answers {
    /// The combination answering `value` (the constrained nodes and their values) where both components lie
    /// in the span of the values seen and its estimated error is within [`CONTRACT`] times `tolerance` (px).
    pub fn start(&self, value: &[(usize, V2)], tolerance: f64) -> Option<Vec<V2>> {
        if self.basis.is_empty() { return None }
        let mut coef = [Vec::new(), Vec::new()];
        for (q, c) in coef.iter_mut().enumerate() {
            let mut d: Vec<f64> = value.iter().map(|v| v.1[q]).collect();
            let size = norm(&d);
            *c = self.project(&mut d);
            if norm(&d) > INDEPENDENT * size || self.spread(c) > CONTRACT * tolerance { return None }
        }
        let mut u = vec![[0.0; 2]; self.fields[0].len()];
        u.par_chunks_mut(CHUNK).enumerate().for_each(|(k, u)| {
            for (i, f) in self.fields.iter().enumerate() {
                let (a, b) = (coef[0][i], coef[1][i]);
                u.iter_mut().zip(&f[k * CHUNK..]).for_each(|(u, &f)| (u[0], u[1]) = (u[0] + a * f as f64, u[1] + b * f as f64));
            }
        });
        Some(u)
    }

    /// Keeps the answer `u` to `value`, estimated within `error` px, where its values add to the span (while
    /// there is room). A nearly parallel value's field has a magnified error, which counts only as far as a later
    /// value lies along it; a value in the span refused a start for its error replaces the field that error
    /// mostly came from, if that makes it smaller (else a nudged point's field would stay for good).
    pub fn add(&mut self, value: &[(usize, V2)], u: &[V2], error: f64, tolerance: f64) {
        if value.len() * u.len() > ANSWER_FLOATS { return }
        for q in 0..2 {
            let mut d: Vec<f64> = value.iter().map(|v| v.1[q]).collect();
            let size = norm(&d);
            let c = self.project(&mut d);
            let (rest, spread) = (norm(&d), self.spread(&c));
            let spanned = rest <= INDEPENDENT * size;
            if (spanned && spread <= CONTRACT * tolerance) || (!spanned && self.basis.len() >= value.len()) { continue }
            // The field this answer replaces (none: it adds its value's own direction).
            let j = if spanned { (0..c.len()).max_by(|&a, &b| (c[a] * self.error[a]).abs().total_cmp(&(c[b] * self.error[b]).abs())) } else { None };
            // The field: the answer less the other fields' share, over its own coefficient; its error per unit
            // holds the answer's, its `f32` rounding's and (replacing one) the other fields'.
            let over = j.map_or(rest, |j| c[j]);
            let mut f: Vec<f64> = u.iter().map(|v| v[q]).collect();
            let rounding = f64::from(f32::EPSILON) * f.iter().fold(0.0, |m: f64, f| m.max(f.abs()));
            let others = j.map_or(spread, |j| (spread.powi(2) - (c[j] * self.error[j]).powi(2)).max(0.0).sqrt());
            let unit = (error + rounding).hypot(others) / over.abs();
            if over == 0.0 || j.is_some_and(|j| unit >= self.error[j]) { continue }
            for (i, (c, g)) in c.iter().zip(&self.fields).enumerate() {
                if Some(i) != j { f.par_iter_mut().zip(g).for_each(|(f, &g)| *f -= c * g as f64) }
            }
            let field = f.iter().map(|f| (f / over) as f32).collect();
            match j {
                Some(j) => (self.fields[j], self.error[j]) = (field, unit),
                None => {
                    self.basis.push(d.iter().map(|d| d / rest).collect());
                    self.fields.push(field);
                    self.error.push(unit);
                }
            }
        }
    }

    /// The estimated error of the fields' combination with coefficients `c`.
    fn spread(&self, c: &[f64]) -> f64 { c.iter().zip(&self.error).map(|(c, e)| (c * e).powi(2)).sum::<f64>().sqrt() }

    /// The coefficients of `d` on the basis, `d` left with what lies outside it (twice Gram–Schmidt).
    fn project(&self, d: &mut [f64]) -> Vec<f64> {
        debug_assert!(self.basis.iter().all(|b| b.len() == d.len()), "one piece's values list the same nodes");
        let mut c = vec![0.0; self.basis.len()];
        for _ in 0..2 {
            for (c, b) in c.iter_mut().zip(&self.basis) {
                let t: f64 = b.iter().zip(&*d).map(|(b, d)| b * d).sum();
                d.iter_mut().zip(b).for_each(|(d, b)| *d -= t * b);
                *c += t;
            }
        }
        c
    }
}

fn norm(d: &[f64]) -> f64 { d.iter().map(|d| d * d).sum::<f64>().sqrt() }

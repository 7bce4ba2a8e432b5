//! Warm starts from several earlier frames.
//!
//! On a fixed grid with fixed constrained nodes (an animation: the rest pose does not change between frames)
//! the solution is linear in the constraint values. So if the new values are close to a combination
//! `Σ αᵢ vᵢ` of earlier frames' values, the same combination of their fields `Σ αᵢ uᵢ` is as close to the
//! new solution (up to the earlier solves' tolerance). [`WarmHistory`] keeps the last few frames and starts
//! each solve from the least-squares combination: for smooth motion a polynomial extrapolation in time.

use std::{array::from_fn, borrow::Cow, collections::VecDeque};

use crate::field::{Field, FieldView};
use crate::grid::{Constraints, Grid};

use super::{dense_solve, solve_constrained, SolveOptions, SolveReport, Solver};

/// How many earlier frames a [`WarmHistory`] keeps.
pub const HISTORY_FRAMES: usize = 3;

/// The error (pixels) taken for each kept frame when weighing their combinations: the default tolerance,
/// which frames are usually solved to.
const FRAME_ERROR_PX: f64 = 0.01;

/// The last few solves of one animated surface: their constraint values and fields.
#[derive(Clone, Debug, Default)]
pub struct WarmHistory {
    /// The grid (its size, nodes and links) and constrained nodes the entries share.
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

    /// The start for a solve of constraints `c` on `grid`: the history's prediction or `given`, whichever
    /// misses the constraint values by less (the largest difference at a constrained node); `None` when there
    /// is neither.
    pub fn start<'a>(&self, grid: &Grid, c: &Constraints, given: Option<&'a Field>) -> Option<Cow<'a, Field>> {
        let miss = |f: &Field| {
            c.nodes.iter().zip(&c.values).fold(0.0f64, |m, (&i, v)| m.max((f.dx[i] as f64 - v[0]).abs()).max((f.dy[i] as f64 - v[1]).abs()))
        };
        match (self.predict(grid, c), given) {
            (Some(p), Some(g)) => Some(if miss(&p) < miss(g) { Cow::Owned(p) } else { Cow::Borrowed(g) }),
            (p, g) => p.map(Cow::Owned).or(g.map(Cow::Borrowed)),
        }
    }

    /// The combination of the kept fields whose constraint values best match `c`'s (per component, see
    /// `fit`), or the latest field when the earlier frames pin other nodes or another grid or do not help;
    /// `None` when empty or kept for another grid size.
    pub fn predict(&self, grid: &Grid, c: &Constraints) -> Option<Field> {
        let last = self.last().filter(|f| (f.width, f.height) == (grid.width, grid.height))?;
        if self.entries.len() < 2 || *grid != self.grid || c.nodes != self.nodes { return Some(last.clone()) }
        let alpha = [self.fit(&c.values, 0), self.fit(&c.values, 1)];
        let mut out = Field::zeros(grid.width, grid.height);
        for (i, (_, f)) in self.entries.iter().enumerate() {
            for (out, v, a) in [(&mut out.dx, &f.dx, alpha[0][i] as f32), (&mut out.dy, &f.dy, alpha[1][i] as f32)] {
                if a != 0.0 {
                    out.iter_mut().zip(v).for_each(|(o, v)| *o += a * v);
                }
            }
        }
        Some(out)
    }

    /// Least-squares weights of the kept frames' component `q` for `target`, when they match it better than
    /// the latest frame alone (`[0, …, 1]`, returned otherwise) and stay moderate (`Σ|αᵢ| ≤ 16`: no wild
    /// extrapolation that would amplify the earlier solves' errors). When the fit through every frame is
    /// wild (frames nearly parallel, as a drag's first short step beside a probe: see the editor), the fits through fewer frames are weighed instead, each by its root
    /// mean square miss at the constrained nodes plus the errors it amplifies (`Σ|αᵢ|` × [`FRAME_ERROR_PX`]).
    fn fit(&self, target: &[[f64; 2]], q: usize) -> [f64; HISTORY_FRAMES] {
        let k = self.entries.len();
        let latest: [f64; HISTORY_FRAMES] = from_fn(|i| if i + 1 == k { 1.0 } else { 0.0 });
        // Component q's products of the kept frames' values and the target's.
        let dot = |x: &[[f64; 2]], y: &[[f64; 2]]| -> f64 { x.iter().zip(y).map(|(a, c)| a[q] * c[q]).sum() };
        let v = |i: usize| &self.entries[i].0;
        // The Gram matrix G (symmetric: each product taken once) and b = (vᵢᵀt).
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
        // The root mean square miss of weights `w` at the constrained nodes, from ‖t − Σ wᵢ vᵢ‖² =
        // tᵀt − 2 wᵀb + wᵀG w; and how much they amplify the frames' errors.
        let miss = |w: &[f64; HISTORY_FRAMES]| {
            let mut sq = tt;
            for i in 0..k {
                sq -= 2.0 * w[i] * b[i];
                for j in 0..k {
                    sq += w[i] * g[i][j] * w[j];
                }
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
            if score < best.0 {
                best = (score, w);
            }
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
        if self.entries.len() == HISTORY_FRAMES {
            self.entries.pop_front();
        }
        self.entries.push_back((c.values.clone(), field.clone()));
    }
}

/// The solve of constraints `c` on `grid` (the coarse one at `grid_step` above 1) with `solver`, from its
/// history's start when `warm`, which then keeps the result; from `initial` otherwise.
pub(crate) fn solve_from(
    grid: &Grid, c: &Constraints, options: &SolveOptions, initial: Option<FieldView<'_>>, solver: &mut Solver, warm: bool,
) -> (Field, SolveReport) {
    if !warm { return solve_constrained(grid, c, options, initial, &mut solver.store); }
    let given = initial.map(|f| f.to_field());
    let start = solver.history.start(grid, c, given.as_deref());
    let (field, report) = solve_constrained(grid, c, options, start.as_deref().map(FieldView::from), &mut solver.store);
    solver.history.record(grid, c, &field);
    (field, report)
}

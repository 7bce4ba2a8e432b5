//! Multigrid cycles: Chebyshev–Jacobi smoothing, V- and K-cycles, the coarse-to-fine start, the coarsest solve.

use rayon::prelude::*;

use super::level::{dot, dot_pairs, galerkin, sub_scaled, prolong_add_scaled, restrict, Geometry, Level, Operator, Real, StepRule, PAD, V2, W2, WS};
use super::strands::Strands;

/// Ratio between the top of the smoothed spectrum of D⁻¹A and its bottom.
const CHEB_RATIO: f64 = 16.0;
/// Stop coarsening when a level has at most this many nodes.
const COARSEST_NODES: usize = 300;
/// A K-cycle takes its second step only when its first left more than this fraction of the coarse residual
/// (2-norm, per component): Notay's adaptive K-cycle (`docs/dev/ablation.md`, "Constants").
const K_SECOND_STEP: f64 = 0.3;
/// Lanczos steps of the estimate of the top of each level's spectrum.
const LANCZOS_STEPS: usize = 12;
/// Power steps of the finest level's Collatz–Wielandt bound.
const COLLATZ_STEPS: usize = 3;
/// An open finest level takes the bound of an open box at most this many nodes a side (`collatz_bound`).
const MODEL: usize = 64;
/// The smallest pivot of the coarsest factor, relative to its diagonal, not taken as zero: about the `f32` work
/// vectors' resolution, whose rounding a smaller one would magnify (`docs/dev/solver-correctness.md`, "Tiny tensions").
const PIVOT_FLOOR: f64 = 1e-7;

/// The grid hierarchy with its work vectors.
#[derive(Debug)]
pub(crate) struct Hierarchy {
    pub levels: Vec<Level>,
    work: Vec<Work>,
    coarsest: Banded,
    /// Smoothing steps on the finest level, and on the levels below it.
    degree: usize,
    coarse_degree: usize,
    /// Solve the coarse problems below the finest level by K-cycles ([`Hierarchy::k_correction`]), else V-cycles.
    pub k_cycles: bool,
    /// A second coarse space for the finest level ([`Level::into_plain`]), visited after the first.
    pub alt: Option<Box<Hierarchy>>,
    /// Whether the finest level has holes or cuts (see [`super::level::Geometry::torn`]).
    pub torn: bool,
    /// K-cycle coarse corrections that took their first step alone ([`K_SECOND_STEP`]) since the build.
    pub second_steps_skipped: std::sync::atomic::AtomicUsize,
    /// Exact solves on the finest level's thin parts around each cycle (see [`Strands`]).
    pub strands: Option<Strands>,
    /// The same on the coarser levels (index k for level k; none on the finest), relaxed right after the
    /// first smoothing and right before the second.
    pub level_strands: Vec<Option<Strands>>,
    /// The solve's finest-level vectors (the residual, the search direction's product, a warm start's cold
    /// alternative; `direction`: the search direction in `f32`), kept: fresh ones cost page faults every solve.
    pub spare: Vec<Vec<V2>>,
    pub direction: Vec<W2>,
    /// The finest level's affine functions, corrected exactly after every cycle (see [`Affine`]).
    pub affine: Option<Affine>,
    /// Whether a solve has probed its operator for slow modes (see `super::probe`), and converged: a warm start on
    /// it (not from earlier answers, whose combination is already judged) keeps its directions from its first
    /// cycle, as one on a new hierarchy does.
    pub probed: bool,
    /// Whether the finest level is the only one, solved by its banded factor.
    pub whole: bool,
    /// Where the last solve stood if its cycle limit stopped it, for the next to go on.
    pub paused: Option<Box<super::Paused>>,
    /// Slow modes a converged solve found, on which later weakly held claims are checked (`super::solve_piece`).
    pub checks: Option<super::deflate::Modes>,
    /// The earlier solves' answers, for starts.
    pub answers: super::history::Answers,
}

/// Work vectors of one level (`f32`: see the `level` module).
#[derive(Debug)]
struct Work {
    x: Vec<W2>,
    f: Vec<W2>,
    r: Vec<W2>,
    d: Vec<W2>,
    /// The first search direction of a K-cycle's coarse problem, and `A` times it (allocated when first used).
    z1: Vec<W2>,
    q1: Vec<W2>,
}

impl Hierarchy {
    /// A second coarse space for `fine`'s unknowns: the levels below it, by V-cycles (`fine` itself, smoothed
    /// by the hierarchy it serves, without work vectors or bound).
    pub fn coarse_space(fine: Level, degree: usize, exact_work: Option<usize>) -> Hierarchy {
        let mut h = Hierarchy { k_cycles: false, ..Hierarchy::new(fine, degree, degree, false, None, exact_work) };
        // Past the setup, the finest level only lends its prolongation.
        h.levels[0].keep_only_prolongation();
        h
    }

    /// The hierarchy below `fine`, smoothing by `degree` Chebyshev steps on `fine` and `coarse_degree` below; unless
    /// `smooth_fine`, `fine` gets no work vectors or bound. With `whole = Some(max)`, `fine` is the only level,
    /// solved by its banded factor, where that drops at most `max` pivots. Levels coarsen to at most
    /// [`COARSEST_NODES`] nodes, or with `exact_work = Some(work)` to the first below `fine` whose banded factor
    /// costs at most `work` ([`banded_work`]; `fine`'s own is for `whole` to judge: it may hold a soft part).
    pub fn new(fine: Level, degree: usize, coarse_degree: usize, smooth_fine: bool, whole: Option<usize>, exact_work: Option<usize>) -> Hierarchy {
        let mut levels = vec![fine];
        let factor = whole.and_then(|max| Some(Banded::new(&levels[0])).filter(|b| b.dropped.iter().filter(|&&d| d).count() <= max));
        let whole = factor.is_some();
        let coarser = |l: &Level, k: usize| {
            let n = l.geo.w * l.geo.h;
            exact_work.filter(|_| k > 0).map_or(n > COARSEST_NODES, |work| banded_work(n, l.geo.w, l.geo.h) > work)
        };
        while let Some(last) = levels.last().filter(|l| !whole && coarser(l, levels.len() - 1) && l.geo.w > 2 && l.geo.h > 2) {
            levels.push(galerkin(last));
        }
        let work = (0..levels.len()).map(|k| {
            let v = || vec![[0.0; 2]; if k == 0 && !smooth_fine { 0 } else { levels[k].len_padded() }];
            Work { x: v(), f: v(), r: v(), d: v(), z1: Vec::new(), q1: Vec::new() }
        }).collect();
        // Chebyshev needs the top of D⁻¹A's spectrum (two steps aimed at [λ/16, λ] amplify modes over 6.25 % above
        // λ). On the finest level, whose top mode alternates in sign as its molecule does, a Collatz–Wielandt bound
        // on |A| is safe and close; on Galerkin levels it is loose: there Lanczos's largest Ritz value, capped by
        // Gershgorin's.
        let bound = |(k, l): (usize, &mut Level)| l.lam_max = l.lam_max.min(if k == 0 { collatz_bound(l) } else { lanczos_estimate(l) });
        levels.iter_mut().enumerate().skip(if smooth_fine && !whole { 0 } else { 1 }).for_each(bound);
        let coarsest = factor.unwrap_or_else(|| Banded::new(levels.last().unwrap()));
        Hierarchy { levels, work, coarsest, degree, coarse_degree, k_cycles: true, alt: None, torn: false, second_steps_skipped: Default::default(), strands: None, level_strands: Vec::new(), spare: Vec::new(), direction: Vec::new(), affine: None, probed: false, whole, paused: None, checks: None, answers: Default::default() }
    }

    /// `z ≈ A⁻¹ r` on the finest level by one symmetric cycle from zero in `f32`, valid until the next call.
    pub fn precondition(&mut self, r: &[V2]) -> &[W2] {
        update(&mut self.work[0].f, r, |f, r| *f = [WS::of(r[0]), WS::of(r[1])]);
        if let Some(s) = &mut self.strands { s.before(&self.levels[0], r, &mut self.work[0].f); }
        let mut work = std::mem::take(&mut self.work);
        let mut alt_work = self.alt.as_mut().map(|a| std::mem::take(&mut a.work));
        self.solve_level(0, &mut work, true, alt_work.as_deref_mut());
        if let (Some(a), Some(w)) = (self.alt.as_mut(), alt_work) { a.work = w; }
        if let Some(s) = &self.strands { s.after(r, &mut work[0].x); }
        if let Some(a) = &self.affine { a.add(&self.levels[0], r, &mut work[0].x); }
        self.work = work;
        &self.work[0].x[..r.len()]
    }

    /// How many pivots the coarsest factor dropped (see [`Banded`]).
    pub fn dropped(&self) -> usize { self.coarsest.dropped.iter().filter(|&&d| d).count() }

    /// Level k's smoothing steps.
    fn steps_at(&self, k: usize) -> usize { if k == 0 { self.degree } else { self.coarse_degree } }

    /// Approximately solves `A_k x = f` on level k (x, f in `work[0]`, the slice from level k) by one cycle from
    /// `x` (zero when `x_zero`): a V-cycle, with K-cycle corrections on the levels between the finest and the one
    /// above the coarsest.
    fn solve_level(&self, k: usize, work: &mut [Work], x_zero: bool, alt_work: Option<&mut [Work]>) {
        let (level, coarsest) = (&self.levels[k], k + 1 == self.levels.len());
        // From zero, `x` is zeroed unless the first smoothing step writes all of it (or, fused with the second,
        // does not read it: `Level::second_step_from_zero`).
        if x_zero && (coarsest || self.steps_at(k) == 0 || level.lam_max <= 0.0) { fill_zero(&mut work[0].x); }
        if coarsest {
            self.coarsest.solve(&work[0].f, &mut work[0].x);
            return;
        }
        let (w, tail) = work.split_first_mut().expect("a level's work vectors");
        smooth(level, w, self.steps_at(k), x_zero);
        if let Some(Some(s)) = self.level_strands.get(k) { s.relax(&mut w.x, &w.f); }
        // From a given `x` (the coarse-to-fine start's whole answer) below the finest level in `f64` sums
        // (`Level::residual_f64`); from zero, `x` is one smoothing of `f`, its product's rounding small.
        if k > 0 && !x_zero {
            level.residual_f64(&w.x, Some(&w.f), &mut w.r);
        } else { level.residual(&w.x, Some(&w.f), &mut w.r); }
        // No K-cycle on the finest level (the conjugate gradient runs around the cycle) nor above the coarsest
        // (its coarse solve is exact).
        if k > 0 && k + 2 < self.levels.len() && self.k_cycles {
            self.k_correction(k, w, tail);
        } else {
            self.solve_below(k, &w.r, tail);
            // Line-searched below the finest level; unscaled on it (the conjugate gradient takes the step, and
            // above the coarsest of two levels the correction is exact).
            let alpha = if k > 0 { line_step(&self.levels[k + 1], &mut tail[0]) } else { [1.0; 2] };
            prolong_add_scaled(level, &self.levels[k + 1], &tail[0].x, &mut w.x, alpha);
        }
        if let (Some(alt), Some(aw)) = (self.alt.as_deref().filter(|a| a.levels.len() > 1), alt_work) {
            // The second coarse space, on the residual the first one left.
            level.residual(&w.x, Some(&w.f), &mut w.r);
            alt.solve_below(0, &w.r, &mut aw[1..]);
            // Line-searched: a soft mode of the plain space can make its answer far too large, undoing the first.
            let alpha = line_step(&alt.levels[1], &mut aw[1]);
            prolong_add_scaled(&alt.levels[0], &alt.levels[1], &aw[1].x, &mut w.x, alpha);
        }
        if let Some(Some(s)) = self.level_strands.get(k) { s.relax(&mut w.x, &w.f); }
        smooth(level, w, self.steps_at(k), false);
    }

    /// Level k + 1's cycle from zero on the restriction of level k's residual `r` (`tail`: from level k + 1).
    fn solve_below(&self, k: usize, r: &[W2], tail: &mut [Work]) {
        restrict(&self.levels[k], &self.levels[k + 1], r, &mut tail[0].f);
        self.solve_level(k + 1, tail, true, None);
    }

    /// Level k's coarse correction from its residual `w.r`: two steps of flexible conjugate gradients on
    /// `A_c e = Pᵀ r`, each preconditioned by one cycle of level k + 1, then `P e` added to `w.x`; the second
    /// only when the first left more than [`K_SECOND_STEP`] of the residual. Per component, `zᵢ` the cycles':
    ///
    /// ```text
    /// e = α₁ z₁ + α₂ d,   α₁ = z₁ᵀf / z₁ᵀA z₁,   d = z₂ − β z₁,   β = z₂ᵀA z₁ / z₁ᵀA z₁,
    /// α₂ = dᵀ(f − α₁ A z₁) / dᵀA d
    /// ```
    ///
    /// The second step minimises the energy over both directions and needs no fine residual (the coarse one
    /// is updated in place).
    fn k_correction(&self, k: usize, w: &mut Work, tail: &mut [Work]) {
        let (level, coarse) = (&self.levels[k], &self.levels[k + 1]);
        self.solve_below(k, &w.r, tail);
        let c = &mut tail[0];
        // z₁, z₂ are smooth and as large as the coarse error: their products in `f64` sums (`Level::residual_f64`).
        coarse.residual_f64(&c.x, None, &mut c.r); // −A z₁ on the unknowns
        let zaz = dot_w(&c.x, &c.r).map(|v| -v);
        let a1 = step(dot_w(&c.x, &c.f), zaz, 0.0);
        // Keep A z₁ (and z₁ below, if a second step follows); the right-hand side becomes f − α₁ A z₁.
        let a1w = a1.map(WS::of);
        c.q1.resize(c.r.len(), [WS::ZERO; 2]);
        let before = dot_w(&c.f, &c.f);
        update(&mut c.q1, &c.r, |q, r| *q = [WS::ZERO - r[0], WS::ZERO - r[1]]);
        update(&mut c.f, &c.r, |f, r| *f = [f[0] + a1w[0] * r[0], f[1] + a1w[1] * r[1]]);
        let after = dot_w(&c.f, &c.f);
        // The first step alone when it left little of the residual.
        let t2 = K_SECOND_STEP * K_SECOND_STEP;
        if after[0] <= t2 * before[0] && after[1] <= t2 * before[1] {
            self.second_steps_skipped.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            prolong_add_scaled(level, coarse, &c.x, &mut w.x, a1);
            return;
        }
        c.z1.clone_from(&c.x);
        self.solve_level(k + 1, tail, true, None);
        let c = &mut tail[0];
        coarse.residual_f64(&c.x, None, &mut c.r); // −A z₂
        let bw = step(dot_w(&c.x, &c.q1), zaz, 0.0).map(WS::of);
        // d = z₂ − β z₁ into x, A d = −r − β A z₁ into r.
        update(&mut c.x, &c.z1, |x, z1| *x = [x[0] - bw[0] * z1[0], x[1] - bw[1] * z1[1]]);
        update(&mut c.r, &c.q1, |r, q1| *r = [WS::ZERO - r[0] - bw[0] * q1[0], WS::ZERO - r[1] - bw[1] * q1[1]]);
        let a2w = step(dot_w(&c.x, &c.f), dot_w(&c.x, &c.r), 0.0).map(WS::of);
        update(&mut c.x, &c.z1, |x, z1| *x = [a1w[0] * z1[0] + a2w[0] * x[0], a1w[1] * z1[1] + a2w[1] * x[1]]);
        prolong_add_scaled(level, coarse, &c.x, &mut w.x, [1.0; 2]);
    }

    /// The coarse-to-fine start: the residual of `u` restricted to every level, solved on the coarsest, then
    /// interpolated and improved by one V-cycle per level below the finest; the correction is added to `u`.
    /// `r` is scratch, or already holds the residual of `u` when `r_ready` (it is left stale).
    pub fn coarse_to_fine(&mut self, u: &mut [V2], r: &mut [V2], r_ready: bool) {
        let nl = self.levels.len();
        if nl < 2 {
            // A one-level hierarchy: the exact solve of the finest level.
            self.levels[0].residual(u, None, r);
            let mut x = vec![[0.0; 2]; r.len()];
            self.coarsest.solve(r, &mut x);
            self.coarsest.map.iter().for_each(|&p| u[p] = [u[p][0] + x[p][0], u[p][1] + x[p][1]]);
            return;
        }
        let mut work = std::mem::take(&mut self.work);
        if !r_ready { self.levels[0].residual(u, None, r); }
        restrict(&self.levels[0], &self.levels[1], r, &mut work[1].f);
        for k in 1..nl - 1 {
            let (head, tail) = work.split_at_mut(k + 1);
            restrict(&self.levels[k], &self.levels[k + 1], &head[k].f, &mut tail[0].f);
        }
        let w = &mut work[nl - 1];
        self.coarsest.solve(&w.f, &mut w.x);
        for k in (1..nl - 1).rev() {
            let (head, tail) = work.split_at_mut(k + 1);
            fill_zero(&mut head[k].x);
            prolong_add_scaled(&self.levels[k], &self.levels[k + 1], &tail[0].x, &mut head[k].x, [1.0; 2]);
            self.solve_level(k, &mut work[k..], false, None);
        }
        prolong_add_scaled(&self.levels[0], &self.levels[1], &work[1].x, u, [1.0; 2]);
        self.work = work;
    }
}

/// The affine functions `W = (1, x − x₀, y − y₀)` on the finest level's unknowns, added to every cycle's output
/// by their Galerkin correction `z += W E⁻¹ Wᵀ r`, `E = Wᵀ A W`. On a torn piece the link-aware prolongation
/// reproduces them only where each side of a cut has room to extrapolate, so an affine motion the constraints
/// leave nearly free is a near-null mode the cycles barely move (`docs/dev/solver-correctness.md`, "Affine motions").
#[derive(Debug)]
pub(crate) struct Affine(Vec<Vec<f64>>);

/// A piece gets [`Affine`] where its weakest affine motion of size 1 at the box's edges has less energy than
/// this (a node held `d` off costs about `20 d²`: constrained nodes moved by about 1/50 of the motion's size).
const AFFINE_WEAK: f64 = 1e-2;

/// `W`'s values at padded node `p` of `level`: small integers (exact in `f32`), zero off the unknowns.
fn affine_at(level: &Level, p: usize) -> [f64; 3] {
    if level.inv_diag_w[p] == 0.0 { return [0.0; 3]; }
    [1.0, (p % level.wp) as f64 - (level.geo.w / 2 + PAD) as f64, (p / level.wp) as f64 - (level.geo.h / 2 + PAD) as f64]
}

/// `Wᵀ v` per component, the chunks' sums added in order.
fn affine_sums(level: &Level, v: &[V2]) -> [V2; 3] {
    let parts: Vec<[V2; 3]> = v.par_chunks(PASS_CHUNK).enumerate().map(|(c, v)| {
        v.iter().enumerate().fold([[0.0; 2]; 3], |s, (j, v)| {
            let w = affine_at(level, c * PASS_CHUNK + j);
            std::array::from_fn(|i| [s[i][0] + w[i] * v[0], s[i][1] + w[i] * v[1]])
        })
    }).collect();
    parts.iter().fold([[0.0; 2]; 3], |s, t| std::array::from_fn(|i| [s[i][0] + t[i][0], s[i][1] + t[i][1]]))
}

impl Affine {
    /// `None` unless the constraints leave an affine motion nearly free (not free: see `nullspace`). `x`, `q`: scratch.
    pub fn new(level: &Level, x: &mut [V2], q: &mut [V2]) -> Option<Affine> {
        let mut e = vec![vec![0.0; 3]; 3];
        for pair in [[1, 2], [0, 0]] {
            x.par_iter_mut().enumerate().for_each(|(p, v)| { let w = affine_at(level, p); *v = [w[pair[0]], w[pair[1]]] });
            level.residual(x, None, q); // −A W, exact but for the tension's terms
            let s = affine_sums(level, q);
            e.iter_mut().enumerate().for_each(|(i, row)| (row[pair[0]], row[pair[1]]) = (-s[i][0], -s[i][1]));
        }
        // E for W scaled to 1 at the edges: det / Σ principal 2 × 2 minors (1 / Σ 1/λᵢ) lies in [λ_min / 3, λ_min].
        let s = [1.0, 2.0 / level.geo.w.max(2) as f64, 2.0 / level.geo.h.max(2) as f64];
        let m = |i: usize, j: usize| e[i][j] * s[i] * s[j];
        let minor = |i: usize, j: usize| m(i, i) * m(j, j) - m(i, j) * m(i, j);
        let det = m(0, 0) * minor(1, 2) - m(0, 1) * (m(0, 1) * m(2, 2) - m(1, 2) * m(0, 2)) + m(0, 2) * (m(0, 1) * m(1, 2) - m(1, 1) * m(0, 2));
        let (minors, trace) = (minor(0, 1) + minor(0, 2) + minor(1, 2), m(0, 0) + m(1, 1) + m(2, 2));
        (det < AFFINE_WEAK * minors && det > 1e-12 * trace * minors).then_some(Affine(e))
    }

    /// `z += W E⁻¹ Wᵀ r` (each component) on the unknowns.
    fn add(&self, level: &Level, r: &[V2], z: &mut [W2]) {
        let Some(a) = super::dense_solve(self.0.clone(), affine_sums(level, r).to_vec()) else { return };
        z[..r.len()].par_chunks_mut(PASS_CHUNK).enumerate().for_each(|(c, z)| {
            for (j, z) in z.iter_mut().enumerate() {
                let w = affine_at(level, c * PASS_CHUNK + j);
                if w[0] != 0.0 {
                    *z = std::array::from_fn(|k| WS::of(z[k].get() + a[0][k] + a[1][k] * w[1] + a[2][k] * w[2]));
                }
            }
        });
    }
}

/// The energy-minimising step α (per component) of the correction `P e`, `e = c.x` solving `A_c e = c.f`:
/// α = ⟨P e, r⟩ / ⟨P e, A P e⟩ = ⟨e, f_c⟩ / ⟨e, A_c e⟩ (Galerkin), a coarse product. `c.r` is scratch.
fn line_step(coarse: &Level, c: &mut Work) -> [f64; 2] {
    coarse.residual(&c.x, None, &mut c.r); // −A_c e on the unknowns
    step(dot_w(&c.x, &c.f), dot_w(&c.x, &c.r).map(|v| -v), 1.0)
}

/// An upper bound of the largest eigenvalue of the finest level's D⁻¹A (Collatz–Wielandt): for any g > 0 on the
/// unknowns, λ_max(D⁻¹A) ≤ ρ(D⁻¹|A|) ≤ max_p (D⁻¹|A| g)_p / g_p; the least bound of [`COLLATZ_STEPS`] power steps
/// g ← D⁻¹|A| g from g = D^-1/2 𝟙. Where A's signs alternate as its top mode's do, |A| loses nothing.
/// The bound is the largest of a quantity each node takes from nodes a dozen away, and fixed nodes only lower ρ (a
/// principal submatrix): an open level takes that of an open box at most [`MODEL`] nodes a side, the same but for them.
pub(crate) fn collatz_bound(level: &Level) -> f64 {
    let (w, h) = (level.geo.w, level.geo.h);
    let open = (w.max(h) > MODEL).then(|| level.open_tension()).flatten();
    let model = open.map(|tau| Level::fine(Geometry::open(w.min(MODEL), h.min(MODEL)), tau));
    power_bound(model.as_ref().unwrap_or(level))
}

/// The bound of [`collatz_bound`] from the power steps on `level` itself.
fn power_bound(level: &Level) -> f64 {
    let inv_d = &level.inv_diag;
    let mut g: Vec<f64> = inv_d.par_iter().map(|&i| i.sqrt()).collect();
    let (mut y, mut bound) = (vec![0.0; g.len()], f64::INFINITY);
    for _ in 0..COLLATZ_STEPS {
        level.fine_abs_product(&g, &mut y);
        let chunks = g.par_chunks_mut(PASS_CHUNK).zip(y.par_chunks(PASS_CHUNK)).zip(inv_d.par_chunks(PASS_CHUNK));
        let top = chunks.map(|((g, y), d)| {
            let mut top: f64 = 0.0;
            for ((g, &y), &i) in g.iter_mut().zip(y).zip(d) {
                if i > 0.0 {
                    let next = y * i;
                    top = top.max(next / *g);
                    *g = next;
                }
            }
            top
        });
        bound = bound.min(top.reduce(|| 0.0, f64::max));
    }
    bound
}

/// Largest eigenvalue of D⁻¹A estimated by [`LANCZOS_STEPS`] Lanczos steps from a pseudo-random start (the largest
/// Ritz value, a lower bound). D⁻¹A is symmetric in `xᵀ D y`, so Lanczos runs in that inner product:
/// a step is one product (its dot product taken band by band) and one pass, unnormalised.
pub(crate) fn lanczos_estimate(level: &Level) -> f64 {
    let (n, inv_d) = (level.len_padded(), &level.inv_diag);
    // The start D^-1/2 v of a random v on the unknowns.
    let mut cur: Vec<V2> = (0..n).map(|p| {
        let h = |k: u64| ((p as u64 * 2 + k).wrapping_mul(0x9E3779B97F4A7C15) >> 40) as f64 / (1u64 << 24) as f64 - 0.5;
        let s = inv_d[p].sqrt();
        if inv_d[p] > 0.0 { [h(0) * s, h(1) * s] } else { [0.0; 2] }
    }).collect();
    // The norm `√(xᵀ D x)`: `cur` is the Lanczos vector times `c`, `prev` the one before it times `c_prev`.
    let mut c = cur.iter().zip(inv_d).map(|(x, &i)| if i > 0.0 { (x[0] * x[0] + x[1] * x[1]) / i } else { 0.0 }).sum::<f64>().sqrt();
    if c == 0.0 { return 0.0; }
    let (mut prev, mut out) = (vec![[0.0; 2]; n], vec![[0.0; 2]; n]);
    let (mut c_prev, mut b_prev) = (1.0, 0.0);
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    for _ in 0..LANCZOS_STEPS {
        let dot = level.residual_dot(&cur, &mut out); // −A cur and curᵀ(−A cur)
        let a = -(dot[0] + dot[1]) / (c * c);
        // The next vector, D⁻¹A v − a v − b v_prev, over `prev`, and its squared norm.
        let (sc, sp) = (1.0 / c, b_prev / c_prev);
        let chunks = prev.par_chunks_mut(PASS_CHUNK).zip(cur.par_chunks(PASS_CHUNK)).zip(out.par_chunks(PASS_CHUNK));
        let parts: Vec<f64> = chunks.zip(inv_d.par_chunks(PASS_CHUNK)).map(|(((w, v), r), d)| {
            let mut sum = 0.0;
            for (((w, v), r), &i) in w.iter_mut().zip(v).zip(r).zip(d) {
                for k in 0..2 {
                    w[k] = (-r[k] * i - a * v[k]) * sc - sp * w[k];
                }
                if i > 0.0 { sum += (w[0] * w[0] + w[1] * w[1]) / i; }
            }
            sum
        }).collect();
        alpha.push(a);
        let b = parts.iter().sum::<f64>().sqrt();
        if b <= 1e-12 * a.abs() { break; }
        beta.push(b);
        std::mem::swap(&mut prev, &mut cur);
        (c_prev, c, b_prev) = (c, b, b);
    }
    tridiagonal_max(&alpha, &beta[..alpha.len() - 1])
}

/// Largest eigenvalue of the symmetric tridiagonal matrix (diagonal `a`, off-diagonal `b`) by bisection.
fn tridiagonal_max(a: &[f64], b: &[f64]) -> f64 {
    let mut hi = (0..a.len()).map(|i| a[i] + if i > 0 { b[i - 1].abs() } else { 0.0 } + b.get(i).map_or(0.0, |v| v.abs())).fold(0.0, f64::max);
    let mut lo = 0.0;
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        // The top is above `mid` when not every eigenvalue is below it.
        (lo, hi) = if eigenvalues_below(a, b, mid) < a.len() { (mid, hi) } else { (lo, mid) };
    }
    hi
}

/// How many eigenvalues of the symmetric tridiagonal matrix (diagonal `a`, off-diagonal `b`) lie below `x`:
/// the negative pivots of the LDLᵀ factorisation of T − x (Sturm count).
pub(super) fn eigenvalues_below(a: &[f64], b: &[f64], x: f64) -> usize {
    let (mut count, mut d) = (0, 1.0);
    for i in 0..a.len() {
        d = a[i] - x - if i > 0 { b[i - 1] * b[i - 1] / d } else { 0.0 };
        if d == 0.0 { d = -1e-300; }
        count += usize::from(d < 0.0);
    }
    count
}

/// `num / den` per component, or `none` where the direction has no energy (`den ≤ 0`).
fn step(num: [f64; 2], den: [f64; 2], none: f64) -> [f64; 2] { [0, 1].map(|k| if den[k] > 0.0 { num[k] / den[k] } else { none }) }

/// Entries per task of this module's vector passes.
const PASS_CHUNK: usize = 4096;

/// `Σ a_i b_i` per component, in `f64`, the chunks' sums added in order so the result does not depend on the
/// threads (a parallel `reduce` adds in a tree shaped by work stealing).
fn dot_w(a: &[W2], b: &[W2]) -> [f64; 2] {
    let parts: Vec<[f64; 2]> = a.par_chunks(PASS_CHUNK).zip(b.par_chunks(PASS_CHUNK)).map(|(a, b)| dot_pairs::<WS>(a, b)).collect();
    parts.iter().fold([0.0; 2], |s, t| [s[0] + t[0], s[1] + t[1]])
}

/// `len` zeros in `v` where it has that length (a vector kept from an earlier solve), else in a new one.
pub(crate) fn zeros_in<T: Real>(v: Option<Vec<[T; 2]>>, len: usize) -> Vec<[T; 2]> {
    let Some(mut v) = v.filter(|v| v.len() == len) else { return vec![[T::ZERO; 2]; len] };
    fill_zero(&mut v);
    v
}

fn fill_zero<T: Real>(v: &mut [[T; 2]]) { v.par_chunks_mut(PASS_CHUNK).for_each(|v| v.fill([T::ZERO; 2])) }

/// `f(x_i, y_i)` on every entry of `x` (the vectors' lengths are equal).
fn update<S: Real, T: Real>(x: &mut [[T; 2]], y: &[[S; 2]], f: impl Fn(&mut [T; 2], [S; 2]) + Sync + Send) {
    x.par_chunks_mut(PASS_CHUNK).zip(y.par_chunks(PASS_CHUNK)).for_each(|(x, y)| x.iter_mut().zip(y).for_each(|(x, &y)| f(x, y)));
}

/// Chebyshev smoothing of `A x = f` (in `w`) preconditioned by the diagonal: `steps` steps aimed at `[λ/CHEB_RATIO, λ]`
/// of D⁻¹A's spectrum, one pass each ([`Level::smoothing_step`]). `w.r`, `w.d` are scratch; `x`, `r` may come back swapped.
fn smooth(level: &Level, w: &mut Work, mut steps: usize, x_zero: bool) {
    if steps == 0 || level.lam_max <= 0.0 { return; }
    let Work { x, f, r, d, .. } = w;
    let (b, a) = (level.lam_max, level.lam_max / CHEB_RATIO);
    let (theta, delta) = (0.5 * (b + a), 0.5 * (b - a));
    let (sigma, inv_theta) = (theta / delta, WS::of(1.0 / theta));
    let (mut rho, mut rule) = (1.0 / sigma, StepRule::First { inv_theta });
    // On the finest level the first two steps from zero are one pass (see `Level::second_step_from_zero`).
    let fused = x_zero && steps >= 2 && matches!(level.op, Operator::Fine { .. });
    if x_zero {
        // From x = 0 the first step is x = d = D⁻¹ f / θ: one pass writing x alone (the second step reads the
        // update there, `StepRule::Second`); fused, the second step's pass computes it itself.
        if !fused {
            let chunks = x.par_chunks_mut(PASS_CHUNK).zip(f.par_chunks(PASS_CHUNK).zip(level.inv_diag_w.par_chunks(PASS_CHUNK)));
            chunks.for_each(|(x, (f, g))| first_from_zero(x, f, g, inv_theta));
        }
        steps -= 1;
    }
    for k in 0..steps {
        if k > 0 || x_zero {
            let rho_new = 1.0 / (2.0 * sigma - rho);
            let (c1, c2) = (WS::of(rho_new * rho), WS::of(2.0 * rho_new / delta));
            rule = if k == 0 { StepRule::Second { c1, c2 } } else { StepRule::Next { c1, c2 } };
            rho = rho_new;
        }
        // The step writes x + d into r's vector, which then becomes x's; the last one's update is not kept.
        if fused && k == 0 {
            level.second_step_from_zero(f, inv_theta, d, r, rule, k + 1 < steps);
        } else { level.smoothing_step(x, Some(f), d, r, rule, k + 1 < steps); }
        std::mem::swap(x, r);
    }
}

super::wide::widest! {
    /// [`first_from_zero_body`] on the processor's widest vectors (see [`super::wide`]).
    pub(crate) fn first_from_zero(x: &mut [W2], f: &[W2], g: &[WS], inv_theta: WS) =>
    /// A smoothing's first step from zero, `x = D⁻¹ f / θ` (`g` the inverse diagonal; zero where it is).
    first_from_zero_body {
        for ((x, f), &g) in x.iter_mut().zip(f).zip(g) {
            // Computed everywhere, then chosen: a branch kept the loop scalar.
            let (keep, v) = (g != 0.0, [f[0] * g * inv_theta, f[1] * g * inv_theta]);
            let v = [if keep { v[0] } else { 0.0 }, if keep { v[1] } else { 0.0 }];
            // 0 + v, as `x += d` from zero gave (a −0 becomes +0).
            *x = [WS::ZERO + v[0], WS::ZERO + v[1]];
        }
    }
}

/// Banded Cholesky factor of the coarsest operator (unknowns by rows, or by columns where the level is wider
/// than tall). Pivots below [`PIVOT_FLOOR`] of their diagonal pin their unknown to zero: those of a singular,
/// consistent system, and of free functions whose energy is of order a tiny tension.
#[derive(Debug)]
struct Banded {
    /// The bandwidth: `l_km` is zero for `k − m > bw`.
    bw: usize,
    /// Row `k` of the factor at `l[k (bw + 1) ..]`: `l_km` at `m + bw − k`, `l_kk` last.
    l: Vec<f64>,
    /// Padded index of each unknown.
    map: Vec<usize>,
    dropped: Vec<bool>,
}

/// About the multiply-adds of [`Banded::new`]'s factor of `unknowns` on a `w × h` level (bandwidth ≤ 2 min(w, h) + 2).
pub(crate) fn banded_work(unknowns: usize, w: usize, h: usize) -> usize { unknowns.saturating_mul((2 * w.min(h) + 3).pow(2)) }

impl Banded {
    fn new(level: &Level) -> Banded {
        // The unknowns row by row, or column by column where that is shorter, and the number of each.
        let mut map: Vec<usize> = (0..level.len_padded()).filter(|&p| level.inv_diag[p] != 0.0).collect();
        if level.geo.w > level.geo.h { map.sort_by_key(|&p| (p % level.wp, p / level.wp)); }
        let mut number = vec![usize::MAX; level.len_padded()];
        map.iter().enumerate().for_each(|(k, &p)| number[p] = k);
        let n = map.len();
        // A 5 × 5 stencil reaches at most 2 rows (columns) ahead: bandwidth ≤ 2 min(w, h) + 2 (`number` is
        // `usize::MAX`, above every k, off the unknowns).
        let (mut bw, mut dropped) = (0, vec![false; n]);
        map.iter().enumerate().for_each(|(k, &p)| level.taps(p, |q, _| if number[q] < k { bw = bw.max(k - number[q]) }));
        // l_km's index in `l`.
        let at = |k: usize, m: usize| k * (bw + 1) + m + bw - k;
        let mut l = vec![0.0; n * (bw + 1)];
        map.iter().enumerate().for_each(|(k, &p)| level.taps(p, |q, a| if number[q] <= k { l[at(k, number[q])] = a }));
        for k in 0..n {
            let j0 = k.saturating_sub(bw);
            for j in j0..k {
                // l_kj = (a_kj - Σ_{j0 ≤ m < j} l_km l_jm) / l_jj (l_km is zero for m < j0)
                let s = l[at(k, j)] - dot(&l[at(k, j0)..at(k, j)], &l[at(j, j0)..at(j, j)]);
                l[at(k, j)] = if dropped[j] { 0.0 } else { s / l[at(j, j)] };
            }
            let row = &l[at(k, j0)..at(k, k)];
            let s = l[at(k, k)] - dot(row, row);
            if s <= PIVOT_FLOOR * level.row(map[k])[12].abs() || s <= 0.0 {
                dropped[k] = true;
                l[at(k, j0)..at(k, k)].fill(0.0);
                l[at(k, k)] = 1.0;
            } else { l[at(k, k)] = s.sqrt(); }
        }
        Banded { bw, l, map, dropped }
    }

    /// `x = A⁻¹ f` on the unknowns by the factor, in `f64`, a row for both components at a time (the backward
    /// solve by columns: the factor's rows are contiguous). Dropped unknowns are zero, as their rows and columns are.
    fn solve<T: Real>(&self, f: &[[T; 2]], x: &mut [[T; 2]]) {
        let (n, bw, l) = (self.map.len(), self.bw, &self.l);
        let at = |k: usize, m: usize| k * (bw + 1) + m + bw - k;
        let pivot = |k: usize, s: f64| if self.dropped[k] { 0.0 } else { s / l[at(k, k)] };
        let mut z = [0, 1].map(|c| self.map.iter().map(|&p| f[p][c].get()).collect::<Vec<f64>>());
        for k in 0..n {
            let j0 = k.saturating_sub(bw);
            z.iter_mut().for_each(|z| z[k] = pivot(k, z[k] - dot(&l[at(k, j0)..at(k, k)], &z[j0..k])));
        }
        for k in (0..n).rev() {
            let j0 = k.saturating_sub(bw);
            z.iter_mut().for_each(|z| {
                z[k] = pivot(k, z[k]);
                sub_scaled(&l[at(k, j0)..at(k, k)], z[k], &mut z[j0..k]);
            });
        }
        self.map.iter().enumerate().for_each(|(k, &p)| x[p] = [T::of(z[0][k]), T::of(z[1][k])]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use crate::solve::tests::fine_level;

    /// Coarse energy `½ eᵀA e − eᵀf` of `e`, per component.
    fn energy(level: &Level, e: &[W2], f: &[W2]) -> [f64; 2] {
        let mut r = vec![[0.0; 2]; e.len()];
        level.residual(e, None, &mut r); // −A e
        let (ear, ef) = (dot_w(e, &r), dot_w(e, f));
        [-0.5 * ear[0] - ef[0], -0.5 * ear[1] - ef[1]]
    }

    #[test]
    fn the_banded_factor_runs_across_the_shorter_side() {
        // A wide level is numbered column by column, a tall one row by row: either way the
        // band is about twice the shorter side (row by row, the wide one's would be 122).
        for (w, h) in [(60, 8), (8, 60)] {
            let banded = Banded::new(&fine_level(&Grid::new(w, h), None, 0.0));
            assert!(banded.bw <= 2 * w.min(h) + 2, "{w} × {h}: bandwidth {}", banded.bw);
        }
    }

    #[test]
    fn an_open_level_takes_the_small_open_box_bound() {
        // Open boxes wider or taller than the model, without fixed nodes: the model's bound is the level's own, bit
        // for bit. With fixed nodes (scattered, or a held border's whole outer ring) it stays above the top of the
        // spectrum and within 5 % of it; a level with a node off is not taken for an open one.
        let top = |level: &Level| {
            // A long power iteration on D⁻¹A from a pseudo-random start.
            let mut rnd = crate::grid::tests::sequence(7);
            let n = level.len_padded();
            let mut x: Vec<V2> = (0..n).map(|p| if level.inv_diag[p] != 0.0 { [rnd() - 0.5, rnd() - 0.5] } else { [0.0; 2] }).collect();
            let (mut y, mut top) = (vec![[0.0; 2]; n], 0.0);
            for _ in 0..1500 {
                level.residual(&x, None, &mut y);
                y.iter_mut().zip(&level.inv_diag).for_each(|(v, d)| *v = [-v[0] * d, -v[1] * d]);
                let norm = |v: &[V2]| v.iter().map(|v| v[0] * v[0] + v[1] * v[1]).sum::<f64>().sqrt();
                let ny = norm(&y);
                top = ny / norm(&x);
                x = y.iter().map(|v| [v[0] / ny, v[1] / ny]).collect();
            }
            top
        };
        for (w, h, tau) in [(200, 90, 0.0), (70, 300, 0.3), (65, 20, 1e-3)] {
            let level = fine_level(&Grid::new(w, h), None, tau);
            assert_eq!(level.open_tension(), Some(tau));
            assert_eq!(collatz_bound(&level).to_bits(), power_bound(&level).to_bits(), "{w} × {h}");
        }
        let mut rnd = crate::grid::tests::sequence(5);
        let (w, h) = (100, 80);
        let ring = (0..w * h).map(|i| i % w == 0 || i / w == 0 || i % w == w - 1 || i / w == h - 1).collect();
        for (name, fixed, tau) in [("scattered", (0..w * h).map(|_| rnd() < 0.05).collect(), 0.0), ("held border", ring, 0.3)] {
            let level = fine_level(&Grid::new(w, h), Some(fixed), tau);
            let (bound, top) = (collatz_bound(&level), top(&level));
            assert!(bound >= top * (1.0 - 1e-9) && bound <= 1.05 * top, "{name}: bound {bound} for the top {top}");
        }
        // Its bottom-right corner off: no link shows on that node itself, its neighbours lose theirs.
        let corner = Grid::from_active(100, 80, (0..8000).map(|i| i + 1 < 8000).collect());
        assert_eq!(fine_level(&corner, None, 0.0).open_tension(), None);
    }

    #[test]
    fn the_cycles_vector_copies_match_their_plain_bodies() {
        // A smoothing's first step from zero, by the dispatching function (the AVX2 copy
        // where the processor has it) and by its plain body, bit for bit.
        let mut rnd = crate::grid::tests::sequence(31);
        for n in [1, 9, 1001] {
            let f: Vec<W2> = (0..n).map(|_| [(rnd() - 0.5) as f32, (rnd() - 0.5) as f32]).collect();
            let g: Vec<WS> = (0..n).map(|_| if rnd() < 0.2 { 0.0 } else { rnd() as f32 }).collect();
            let (mut x1, mut x2) = (vec![[9.0f32; 2]; n], vec![[9.0f32; 2]; n]);
            first_from_zero(&mut x1, &f, &g, 0.37);
            first_from_zero_body(&mut x2, &f, &g, 0.37);
            let bits = |v: &[W2]| v.iter().flatten().map(|a| a.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&x1), bits(&x2), "{n}");
        }
    }

    #[test]
    fn the_banded_factor_solves_the_coarsest_system() {
        // A grid with a hole, a cut and scattered fixed nodes, and an open one with none
        // and no tension, whose affine functions cost nothing (singular: their pivots
        // vanish and pin an unknown each). For a consistent right-hand side f = A y, the
        // solve leaves a residual at rounding level, and the pinned unknowns zero.
        let mut rnd = crate::grid::tests::sequence(17);
        let fixed: Vec<bool> = (0..23 * 23).map(|_| rnd() < 0.05).collect();
        let torn = fine_level(&crate::solve::tests::torn_grid(23, true, true, 3.0), Some(fixed), 0.1);
        let open = fine_level(&Grid::new(13, 11), None, 0.0);
        for (name, level) in [("torn", &torn), ("open", &open)] {
            let banded = Banded::new(level);
            assert_eq!(banded.dropped.iter().filter(|&&d| d).count(), if name == "open" { 3 } else { 0 }, "{name}");
            let n = level.len_padded();
            let y: Vec<V2> = (0..n).map(|p| if level.inv_diag[p] != 0.0 { [rnd() - 0.5, rnd() - 0.5] } else { [0.0; 2] }).collect();
            let mut f = vec![[0.0; 2]; n];
            level.residual(&y, None, &mut f); // −A y
            f.iter_mut().for_each(|v| *v = [-v[0], -v[1]]);
            let mut x = vec![[0.0; 2]; n];
            banded.solve(&f, &mut x);
            let mut r = vec![[0.0; 2]; n];
            level.residual(&x, Some(&f), &mut r);
            let size = f.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            let off = r.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(off <= 1e-9 * size, "{name}: residual {off:e} of {size:e}");
            for (k, &p) in banded.map.iter().enumerate() {
                if banded.dropped[k] {
                    assert_eq!(x[p], [0.0; 2], "{name}: pinned unknown {k}");
                }
            }
        }
    }

    #[test]
    fn a_k_cycle_minimises_the_coarse_energy_over_both_directions() {
        // A grid with a hole and a cut, a few pinned nodes, a random fine residual: the
        // K-cycle's coarse correction must leave a residual orthogonal to its first
        // direction (the second direction is A-conjugate to it) and end at lower energy
        // than the first direction's line search alone.
        let (w, h) = (72usize, 66usize);
        let mut grid = Grid::from_active(w, h, (0..w * h).map(|i| ((i % w) as f64 - 40.0).hypot((i / w) as f64 - 30.0) > 7.0).collect());
        grid.add_cut(&[[10.5, 50.2], [45.3, 58.7]]);
        let mut fixed = vec![false; w * h];
        for i in [3 * w + 4, 20 * w + 60, 55 * w + 20, 64 * w + 70] {
            fixed[i] = true;
        }
        let mut hier = Hierarchy::new(fine_level(&grid, Some(fixed), 0.0), 2, 2, true, None, None);
        assert!(hier.levels.len() >= 4, "the test needs a level with a K-cycle below it");
        let mut rnd = crate::grid::tests::sequence(5);
        let k = 1;
        let level = &hier.levels[k];
        let mut work = std::mem::take(&mut hier.work);
        let (head, tail) = work.split_at_mut(k + 1);
        let wk = &mut head[k];
        for p in 0..wk.r.len() {
            wk.r[p] = if level.inv_diag[p] != 0.0 { [WS::of(rnd() - 0.5), WS::of(rnd() - 0.5)] } else { [WS::ZERO; 2] };
        }
        fill_zero(&mut wk.x);
        let coarse = &hier.levels[k + 1];
        let mut f = vec![[WS::ZERO; 2]; coarse.len_padded()];
        restrict(level, coarse, &wk.r, &mut f);

        hier.k_correction(k, wk, tail);
        let c = &tail[0];
        let e = c.x.clone();
        // The energy of α₁ z₁ alone: α₁ = z₁ᵀf / z₁ᵀA z₁ gives −½ (z₁ᵀf)² / z₁ᵀA z₁.
        let (zf, mut az) = (dot_w(&c.z1, &f), vec![[WS::ZERO; 2]; f.len()]);
        coarse.residual(&c.z1, None, &mut az);
        let zaz = dot_w(&c.z1, &az);
        let mut r = vec![[WS::ZERO; 2]; f.len()];
        coarse.residual(&e, Some(&f), &mut r);
        let (ek, rz, rr, ff) = (energy(coarse, &e, &f), dot_w(&r, &c.z1), dot_w(&r, &r), dot_w(&f, &f));
        let zz = dot_w(&c.z1, &c.z1);
        for q in 0..2 {
            let first = -0.5 * zf[q] * zf[q] / -zaz[q];
            assert!(ek[q] < first * 1.01, "component {q}: energy {} not 1 % below the first step's {first}", ek[q]);
            assert!(rz[q].abs() <= 1e-3 * (rr[q] * zz[q]).sqrt().max(1e-12 * ff[q]), "component {q}: residual not orthogonal to z₁: {}", rz[q]);
        }
        // And the correction reached the fine level.
        assert!(wk.x.iter().any(|v| v[0] != WS::ZERO));
        hier.work = work;
    }
}

//! The discrete thin plate (DESIGN §4) and its multigrid solver.
//!
//! [`solve`] minimises `E = E_plate + τ E_membrane` on the active nodes of a [`Grid`] for Δx and Δy (one matrix,
//! solved together) with the nodes that carry samples fixed ([`crate::grid::constrain`]). Where the minimiser is
//! not unique it returns the limit τ → 0⁺, piece by piece (a piece is a connected component of the links): a
//! piece with no constraint does not move, one with one constrained node translates with it, and the free
//! functions of the plate energy (the tilt about a line holding every constraint, the parts joined by one node)
//! are settled to their least membrane energy ([`nullspace`]).
//!
//! Every piece left to the iteration is solved apart, on the box around it, by a flexible conjugate gradient on
//! the finest level preconditioned by a geometric multigrid cycle (link-aware prolongation, Galerkin coarse
//! operators, Chebyshev–Jacobi smoothing, K-cycles, a banded Cholesky coarsest solve, a second coarse space and
//! the affine functions on torn grids, exact solves of the thin parts: [`strands`]) after a coarse-to-fine
//! start. `docs/concepts/thin-plate.md` explains the choices; `docs/dev/ablation.md` measures each optional
//! mechanism. The hierarchies a later solve can reuse are kept by the caller's [`Solver`], never by the process.

mod cycle;
pub(crate) mod deflate;
mod history;
mod level;
mod nullspace;
mod southwell;
mod strands;
mod upsample;
mod wide;

pub use history::{WarmHistory, HISTORY_FRAMES};
pub use strands::THIN;
pub use upsample::{coarse_grid, coarse_nodes, coarse_point, Upsampling};

use rayon::prelude::*;
use thiserror::Error;

use crate::{clock::Instant, field::{Field, FieldView}, geometry::Sample, grid::{constrain, Constraints, Grid}};
use cycle::Hierarchy;
use level::{larger, scaled_max, Geometry, Level, Real, PAD, V2, W2, WS};

/// How the linear system is relaxed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SolveMethod {
    /// Coarse-to-fine start plus V-cycles until the tolerance is met.
    #[default]
    Multigrid,
    /// The coarse-to-fine start plus a fixed budget of rounds, each one coarse correction and one sweep's worth
    /// of greedy single-node relaxations (Southwell), as the paper offers for a fixed amount of work.
    Southwell,
}

/// Options of [`solve`].
#[derive(Clone, Debug, PartialEq)]
pub struct SolveOptions {
    /// τ ≥ 0: weight of the membrane energy.
    pub tension: f64,
    /// Stop when the estimated largest remaining error of any node is below this (pixels).
    pub tolerance_px: f64,
    /// Solve on every `grid_step`-th node and upsample (1 = every pixel).
    pub grid_step: usize,
    /// At most this many cycles (default: 300).
    pub max_cycles: Option<usize>,
    pub method: SolveMethod,
    /// Southwell budget: single-node relaxations, in units of the number of unknowns.
    pub southwell_sweeps: f64,
    /// Mechanisms switched off, for the ablation benchmark only (`benchmarks/ablation.py`).
    #[doc(hidden)]
    pub off: Ablation,
}

/// The solver's optional mechanisms switched off (none by default), for paired benchmarks. Not part of the stable API.
#[doc(hidden)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Ablation(u32);

impl Ablation {
    /// The switches' names, in bit order.
    pub const NAMES: [&'static str; 14] = ["second", "kcycle", "cache", "fours", "deflate", "strands", "coarse_strands", "affine", "outside", "whole", "probe", "exact_coarsest", "answers", "relative"];

    /// The set named by a comma-separated list of [`Ablation::NAMES`] (empty: none).
    pub fn parse(text: &str) -> Result<Ablation, String> {
        let mut bits = 0;
        for name in text.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            let k = Self::NAMES.iter().position(|n| *n == name);
            bits |= 1 << k.ok_or_else(|| format!("unknown mechanism {name:?}; the switches are {}", Self::NAMES.join(", ")))?;
        }
        Ok(Ablation(bits))
    }

    /// Whether the mechanism `name` (one of [`Ablation::NAMES`]) is switched off.
    pub fn has(self, name: &str) -> bool { Self::NAMES.iter().position(|n| *n == name).is_some_and(|k| self.0 & (1 << k) != 0) }
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions { tension: 0.0, tolerance_px: 0.01, grid_step: 1, max_cycles: None, method: SolveMethod::Multigrid, southwell_sweeps: 10.0, off: Ablation::default() }
    }
}

/// What a solve did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SolveReport {
    /// Cycles run after the coarse-to-fine start (Southwell: rounds); with several pieces, the most any piece took.
    pub cycles: usize,
    /// Largest change of any node in the last cycle (pixels; of any piece).
    pub final_change_px: f64,
    /// Largest residual of any unknown after the solve, scaled by its diagonal
    /// (`max |r_i| / a_ii`, pixels: how far one relaxation would still move it).
    pub residual: f64,
    /// The same before the first cycle (after the start).
    pub initial_residual: f64,
    /// Nodes fixed by samples.
    pub constrained_nodes: usize,
    /// Samples that constrain a node.
    pub constrained_samples: usize,
    /// Samples outside the grid or on inactive nodes.
    pub dropped_samples: usize,
    /// Wall time of the whole solve.
    pub seconds: f64,
    /// Whether the tolerance was met (by the same error bound for Southwell; a spent budget is not convergence).
    pub converged: bool,
    /// Why the solve stopped ([`Stop::Converged`] exactly when `converged`; with several pieces, the first found).
    pub stop: Stop,
    /// Cycles of a slow solve's probe for its operator's slow modes (on `A x = 0`, from a random start), run
    /// beside `cycles` and not counted there nor against `max_cycles`; with several pieces, all of theirs.
    pub probe_cycles: usize,
}

/// Why a solve stopped: the rule found the tolerance met; `max_cycles` cycles (Southwell: rounds)
/// ran; Southwell's budget was spent; free parts (hinges, strands) too many to settle, or not settling;
/// a tolerance finer than the `f32` field's precision; a residual left above it; not finite; Ctrl+C.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Stop {
    #[default]
    Converged,
    MaxCycles, Budget, Unsettled, Precision, Residual, Breakdown, Interrupted,
}

impl SolveReport {
    /// Not converged, for `why` unless an earlier reason stands.
    fn fail(&mut self, why: Stop) {
        (self.stop, self.converged) = (if self.stop == Stop::Converged { why } else { self.stop }, false);
    }

    /// Takes in a piece's report: the most cycles, the largest change and residuals, its failure unless one stands.
    fn worst_of(&mut self, r: &SolveReport) {
        (self.cycles, self.probe_cycles) = (self.cycles.max(r.cycles), self.probe_cycles + r.probe_cycles);
        self.final_change_px = self.final_change_px.max(r.final_change_px);
        (self.residual, self.initial_residual) = (self.residual.max(r.residual), self.initial_residual.max(r.initial_residual));
        if !r.converged { self.fail(r.stop) }
    }
}

/// Why a solve was refused.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SolveError {
    #[error("The grid is inconsistent: its activity and link vectors must have width × height entries and links may only join active neighbours.")]
    InconsistentGrid,
    #[error("Sample {index} has a non-finite rest position or displacement; every number must be finite.")]
    NonFiniteSample { index: usize },
    #[error("The tension must be a number from 0 to {max:e}, got {0}; 0 is a pure thin plate.", max = crate::limits::MAX_TENSION)]
    BadTension(f64),
    #[error("The tolerance must be a finite number ≥ 0 (pixels), got {0}.")]
    BadTolerance(f64),
    #[error("The grid step must be at least 1, got 0.")]
    BadGridStep,
    #[error("The Southwell budget must be a finite number ≥ 0, got {0}.")]
    BadBudget(f64),
    #[error("The initial field is {got_w}×{got_h} but the grid is {want_w}×{want_h}; pass a field of the grid's size.")]
    InitialSize { got_w: usize, got_h: usize, want_w: usize, want_h: usize },
    #[error("The initial field holds {got} values, but a {w}×{h} field holds {want} (two a pixel).")]
    InitialLength { got: usize, want: usize, w: usize, h: usize },
    #[error("The initial field has non-finite values; every displacement must be finite.")]
    NonFiniteInitial,
    #[error("The upsampling plan was built for another grid or grid step; build one for this grid and step.")]
    PlanMismatch,
    #[error("The pixels must be indices into the grid, and the output two floats per pixel.")]
    BadPixels,
    #[error("The solve was interrupted (Ctrl-C or a stop request) before it finished.")]
    Interrupted,
}

/// Solves the thin plate on `grid` for the samples (see the module docs).
///
/// ```
/// use inkwarp_core::{solve::{solve, SolveOptions}, Grid, Sample};
/// let grid = Grid::new(33, 33);
/// // Three pinned corners and one pulled point.
/// let s = |x, y, dx, dy| Sample { rest: [x, y], displacement: [dx, dy] };
/// let samples = [s(0.0, 0.0, 0.0, 0.0), s(32.0, 0.0, 0.0, 0.0), s(0.0, 32.0, 0.0, 0.0),
///                s(16.0, 16.0, 4.0, -2.0)];
/// let (field, report) = solve(&grid, &samples, &SolveOptions::default(), None).unwrap();
/// assert!(report.converged);
/// let [dx, dy] = field.at(16, 16);
/// assert_eq!((dx, dy), (4.0, -2.0));
/// ```
pub fn solve(grid: &Grid, samples: &[Sample], options: &SolveOptions, initial: Option<&Field>) -> Result<(Field, SolveReport), SolveError> {
    Solver::new().solve(grid, samples, options, initial.map(FieldView::from))
}

/// [`solve`] with `solver`, its start taken from the solver's history when `warm`
/// ([`WarmHistory::start`]), which then keeps the result (see [`Solver::solve_warm`]).
pub(crate) fn solve_with(
    grid: &Grid, samples: &[Sample], options: &SolveOptions, initial: Option<FieldView<'_>>, solver: &mut Solver, warm: bool,
) -> Result<(Field, SolveReport), SolveError> {
    let start = Instant::now();
    let (field, mut report) = in_pool(|| {
        // On the pool, where its pass over the initial field runs in parallel.
        validate(grid, samples, options, initial)?;
        Ok(if options.grid_step > 1 {
            upsample::solve_coarse(grid, samples, options, initial, solver, warm)
        } else {
            history::solve_from(grid, &constrain(grid, samples), options, initial, solver, warm)
        })
    })?;
    if crate::interrupt::requested() { return Err(SolveError::Interrupted) }
    report.seconds = start.elapsed().as_secs_f64();
    Ok((field, report))
}

/// Runs `f` on a thread of the pool, where the caller of a parallel call takes part instead of sleeping through
/// two context switches (a solve makes hundreds a cycle). Public for callers that move large arrays around a solve
/// (the Python binding's conversion to numpy's layout): run there too, their parallel passes share the pool.
pub fn in_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() { f() } else { rayon::scope(|_| f()) }
}

pub(crate) fn validate(grid: &Grid, samples: &[Sample], options: &SolveOptions, initial: Option<FieldView<'_>>) -> Result<(), SolveError> {
    let bad = |v: f64| !(v.is_finite() && v >= 0.0);
    let refusals = [
        (!grid.is_consistent(), SolveError::InconsistentGrid),
        (bad(options.tension) || options.tension > crate::limits::MAX_TENSION, SolveError::BadTension(options.tension)),
        (bad(options.tolerance_px), SolveError::BadTolerance(options.tolerance_px)),
        (options.grid_step == 0, SolveError::BadGridStep),
        (bad(options.southwell_sweeps), SolveError::BadBudget(options.southwell_sweeps)),
    ];
    if let Some((_, e)) = refusals.into_iter().find(|r| r.0) { return Err(e) }
    if let Some(index) = samples.iter().position(|s| !s.rest.iter().chain(s.displacement.iter()).all(|v| v.is_finite())) {
        return Err(SolveError::NonFiniteSample { index });
    }
    let Some(f) = initial else { return Ok(()) };
    let (w, h) = (grid.width, grid.height);
    if (f.width(), f.height()) != (w, h) { return Err(SolveError::InitialSize { got_w: f.width(), got_h: f.height(), want_w: w, want_h: h }) }
    if !f.is_consistent() { return Err(SolveError::InitialLength { got: f.values(), want: 2 * w * h, w, h }) }
    // In parallel: every warm solve from Python reads its start here first.
    if f.all_finite() { Ok(()) } else { Err(SolveError::NonFiniteInitial) }
}

/// What the τ → 0⁺ rule makes of a connected piece.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Piece {
    Zero,
    Translate([f64; 2]),
    /// Constraints on the line through `a` with direction `d`; `gauge` is the pinned node (none where the whole
    /// piece lies on the line: the constraints pin it, as a general piece's do).
    Line { a: [i64; 2], d: [i64; 2], gauge: Option<usize> },
    General,
}

/// The solve with constraints already attached to nodes.
pub(crate) fn solve_constrained(
    grid: &Grid, constraints: &Constraints, options: &SolveOptions, initial: Option<FieldView<'_>>, store: &mut Store,
) -> (Field, SolveReport) {
    store.solve += 1;
    // A solve from exactly the field the latest returned when its cycle limit stopped a piece goes on (`Paused`).
    store.goes_on = store.written.take().zip(initial).is_some_and(|(f, i)| (0..f.dx.len()).all(|k| i.at_index(k) == [f.dx[k], f.dy[k]]));
    let (w, h) = (grid.width, grid.height);
    // A subnormal tension (its products underflow) is the τ → 0⁺ limit to far below any tolerance: taken as 0.
    let tau = if options.tension < f64::MIN_POSITIVE { 0.0 } else { options.tension };
    let (constrained_nodes, constrained_samples, dropped_samples) = (constraints.len(), constraints.used_samples, constraints.dropped_samples);
    let mut report = SolveReport { constrained_nodes, constrained_samples, dropped_samples, converged: true, ..Default::default() };
    if w * h == 0 { return (Field::zeros(w, h), report) }
    // An open grid (every node active, every link there: most grids) is one piece keyed as open (`BoxLinks::Open`).
    let (labels, count, open) = grid.pieces_and_open();
    // Constraints by piece (their mean: a one-line piece's gauge value without a warm start).
    let mut by_piece: Vec<Vec<usize>> = vec![Vec::new(); count];
    constraints.nodes.iter().enumerate().for_each(|(k, &i)| by_piece[labels[i] as usize].push(k));
    let mut pieces = classify(&by_piece, constraints, w, tau);
    let mut field = Field::zeros(w, h);
    // The largest value an exact answer (a translation, an affine map) holds, for the `f32` check.
    let mut exact = pieces.iter().map(|p| if let Piece::Translate(v) = p { v[0].abs().max(v[1].abs()) } else { 0.0 }).fold(0.0, f64::max);

    // Translated pieces take their constraint; the others are solved one by one, each on its box with its own
    // hierarchy and stopping rule (one iteration over several would share step lengths, and a far-off start would
    // hold back the others and fool the stopping rule). A one-line piece's node farthest from its line is its gauge.
    let mut boxes = vec![[usize::MAX, usize::MAX, 0, 0]; count];
    let mut farthest = vec![0i64; count];
    for (y, row) in labels.chunks_exact(w).enumerate() {
        for (x, l) in row.iter().enumerate().filter(|(_, &l)| l != u32::MAX).map(|(x, &l)| (x, l as usize)) {
            let grow = |b: &mut [usize; 4]| *b = [b[0].min(x), b[1].min(y), b[2].max(x + 1), b[3].max(y + 1)];
            match &mut pieces[l] {
                Piece::Zero => {}
                Piece::Translate(v) => (field.dx[y * w + x], field.dy[y * w + x]) = (v[0] as f32, v[1] as f32),
                Piece::Line { a, d, gauge } => {
                    let dist = cross(*a, *d, [x as i64, y as i64]).abs();
                    if dist > farthest[l] { (farthest[l], *gauge) = (dist, Some(y * w + x)) }
                    grow(&mut boxes[l]);
                }
                Piece::General => grow(&mut boxes[l]),
            }
        }
    }
    for (l, piece) in pieces.iter().enumerate() {
        let gauge = match *piece { Piece::Line { gauge, .. } => gauge, Piece::General => None, _ => continue };
        let [x0, y0, x1, y1] = boxes[l];
        let (bw, bh) = (x1 - x0, y1 - y0);
        let links = piece_links(grid, &labels, l as u32, boxes[l], open);
        let local = |i: usize| (i / w - y0) * bw + i % w - x0;
        // (node, value) of every fixed node: the constrained ones, then the gauge pin.
        let mut value: Vec<(usize, V2)> = by_piece[l].iter().map(|&k| (local(constraints.nodes[k]), constraints.values[k])).collect();
        // The constrained nodes alone (the gauge pin, off the line, is never one of them).
        let mut constrained_only = vec![false; bw * bh];
        value.iter().for_each(|&(j, _)| constrained_only[j] = true);
        let mut fixed = constrained_only.clone();
        // The gauge's value: a start's (finite) one there, else the constraints' mean, which a cold start takes.
        let cold_gauge = gauge.map(|g| {
            let mean = [0, 1].map(|k| value.iter().fold(0.0, |s, v| s + v.1[k]) / value.len() as f64);
            let v = initial.map(|f| f.at_index(g).map(f64::from)).filter(|v| v.iter().all(|x| x.is_finite()));
            fixed[local(g)] = true;
            value.push((local(g), v.unwrap_or(mean)));
            (local(g), mean)
        });
        // The free functions ([`Free`]) of a torn piece. On an open grid the only one is the tilt about a line holding
        // every constraint: at τ = 0 a one-line piece's gauge and `line_correction` take it, at τ > 0 settled below.
        let tilt = if open && tau > 0.0 && by_piece[l].len() > 1 { on_one_line(w, by_piece[l].iter().map(|&k| constraints.nodes[k])) } else { None };
        let key = CacheKey { at: [x0, y0], w: bw, h: bh, tau_bits: tau.to_bits(), links, fixed, off: options.off };
        let vectors = (!open).then(|| key.links.vectors(bw, bh));
        let geo = vectors.as_ref().map(|[active, right, down]| nullspace::BoxGeo { w: bw, h: bh, active, right, down });
        let (gauge_at, keep) = (gauge.map(local), geo.is_some() && !options.off.has("cache"));
        let kept = if keep { store.free.take(store.solve, &key, |f| f.gauge == gauge_at) } else { None };
        let free = kept.unwrap_or_else(|| Free::new(geo.as_ref(), &constrained_only, &key.fixed, gauge_at));
        // At τ = 0 with no free function left, constraints that one affine map fits (any three off one line) are
        // answered by it: zero plate energy, so the minimiser. Close together, their large map's slow mode would be
        // resolved late by the cycles and hidden from the stopping rule.
        let affine_only = tau == 0.0 && gauge.is_none() && free.count == Some(0);
        if let Some(m) = affine_only.then(|| affine_fit(&value, bw)).flatten() {
            let mut values: Vec<V2> = (0..bw * bh).map(|j| m(j % bw, j / bw)).collect();
            // The constrained nodes hold their values exactly, not to the map's rounding.
            value.iter().for_each(|&(j, v)| values[j] = v);
            exact = exact.max(largest(values.iter().copied()));
            write_piece(&mut field, &labels, l as u32, boxes[l], &BoxValues { values, stride: bw, first: 0 });
            if keep { store.free.put(store.solve, key, free) }
            continue;
        }
        // The iteration keeps to settled answers (`Settled`); with a gauge, to the free functions vanishing there.
        let kept_to = if gauge.is_some() { free.pinned.as_ref() } else { free.membrane.as_ref() };
        let again = (free.membrane.is_some() || tilt.is_some()).then(|| key.clone());
        let kept_key = keep.then(|| key.clone());
        // Where the cycles alone settle it (no free function, tilt or gauge), the answer is linear in the values and
        // may start from earlier ones (`history::Answers`).
        let spannable = free.count == Some(0) && tilt.is_none() && gauge.is_none();
        let (mut u, mut r) = solve_piece(key, &value, cold_gauge, initial.map(|f| (f, x0, y0)), options, store, kept_to, spannable);
        if let Some(key) = again {
            let (piece_box, labels) = (boxes[l], &labels);
            // The free functions' settling, or else the open grid's tilt's.
            let settle = |v: &mut Vec<V2>| match (&free.membrane, tilt) {
                (Some(m), _) => m.apply(v),
                (None, line) => {
                    let (a, d) = line.expect("a settled piece has free functions or a tilt");
                    let mut b = BoxValues { values: std::mem::take(v), stride: bw, first: 0 };
                    line_correction(grid, labels, l as u32, a, d, piece_box, &mut b);
                    *v = b.values;
                    true
                }
            };
            (u, r) = settle_null_space(key, geo.as_ref().map(|g| g.active), tau, &value, &settle, kept_to, u, r, options, store);
        } else if free.count.is_none() {
            // Too many free functions to settle: no claim of convergence.
            r.fail(Stop::Unsettled);
        }
        if let Some(key) = kept_key { store.free.put(store.solve, key, free) }
        if let (Piece::Line { a, d, .. }, Some(_)) = (*piece, gauge) {
            line_correction(grid, &labels, l as u32, a, d, boxes[l], &mut u);
        }
        write_piece(&mut field, &labels, l as u32, boxes[l], &u);
        report.worst_of(&r);
    }
    // No exact answer in the `f32` field is finer than its rounding (iterated ones: `solve_piece`).
    if options.tolerance_px < 0.5 * f64::from(f32::EPSILON) * exact { report.fail(Stop::Precision) }
    let constrained = pieces.iter().filter(|p| **p != Piece::Zero).count(); // translated ones keep theirs
    store.hierarchies.trim(store.solve, constrained);
    store.free.trim(store.solve, constrained);
    store.hierarchies.0.iter_mut().filter(|e| e.2 != store.solve).for_each(|e| e.1.paused = None); // none goes on but the latest's
    store.written = (report.stop == Stop::MaxCycles).then(|| field.clone());
    (field, report)
}

/// Brings a piece's iterated answer `u` to the contract where its plate operator has free functions `Z` (zero on
/// the constrained nodes): `settle` adds the least-membrane one to a box field (false where a block cannot be
/// settled). At τ = 0 that is the answer. At τ > 0 the answer still has `Zᵀ M u = 0` (`A_plate Z = 0` makes
/// `Zᵀ A u = τ Zᵀ M u`; taken from `A` it would be the plate's rounding over τ), and rounds of more cycles, counted
/// against `max_cycles`, finish the rest until the settled answer moves by at most a quarter of the tolerance.
/// Southwell settles once (more rounds would spend its budget again).
#[allow(clippy::too_many_arguments)]
fn settle_null_space(
    key: CacheKey, active: Option<&[bool]>, tau: f64, value: &[(usize, V2)], settle: &dyn Fn(&mut Vec<V2>) -> bool,
    membrane: Option<&nullspace::Membrane>, u: BoxValues, mut report: SolveReport, options: &SolveOptions, store: &mut Store,
) -> (BoxValues, SolveReport) {
    let (w, h) = (key.w, key.h);
    let mut dense = u.dense(w, h);
    dense.iter_mut().zip(active.unwrap_or_default()).filter(|(_, &a)| !a).for_each(|(d, _)| *d = [0.0; 2]);
    if tau == 0.0 || options.method == SolveMethod::Southwell {
        // A block of functions too large to settle: no claim of convergence.
        if !settle(&mut dense) { report.fail(Stop::Unsettled) }
        return (BoxValues { values: dense, stride: w, first: 0 }, report);
    }
    const ROUNDS: usize = 8;
    let budget = options.max_cycles.unwrap_or(DEFAULT_MAX_CYCLES);
    let mut settled = None;
    // The round before's settled answer (a solve kept to settled answers ends in the first round; one unprojected
    // may drift along the free functions). Every round, the last included, ends settled.
    let mut before = dense.clone();
    for round in 0..=ROUNDS {
        let all = settle(&mut dense);
        let moved = dense.iter().zip(&before).fold(0.0f64, |a, (u, b)| a.max((u[0] - b[0]).abs()).max((u[1] - b[1]).abs()));
        if !all || moved <= options.tolerance_px * 0.25 {
            settled = Some(if !all { Stop::Unsettled } else { report.stop });
            break;
        }
        if round == ROUNDS || report.cycles >= budget { break; }
        before.clone_from(&dense);
        let (dx, dy) = dense.iter().map(|v| (v[0] as f32, v[1] as f32)).unzip();
        let field = Field { width: w, height: h, dx, dy };
        let rest = SolveOptions { max_cycles: Some(budget - report.cycles), ..options.clone() };
        let (u2, r2) = solve_piece(key.clone(), value, None, Some((FieldView::from(&field), 0, 0)), &rest, store, membrane, false);
        // Every solve's cycles; the latest's change, residual and verdict; the rest (the start) the first's.
        let SolveReport { cycles, final_change_px, residual, converged, stop, probe_cycles, .. } = r2;
        let probe_cycles = report.probe_cycles + probe_cycles;
        report = SolveReport { cycles: report.cycles + cycles, final_change_px, residual, converged, stop, probe_cycles, ..report };
        dense = u2.dense(w, h);
    }
    // Rounds run out: the last solve's reason (`solve_piece`), else the cycles, else the rounds (never settled).
    let stop = settled.unwrap_or(if report.stop != Stop::Converged { report.stop } else if report.cycles >= budget { Stop::MaxCycles } else { Stop::Unsettled });
    (report.converged, report.stop) = (stop == Stop::Converged, stop);
    (BoxValues { values: dense, stride: w, first: 0 }, report)
}

/// The grid a piece's hierarchy is built on: the piece's nodes on its box (row-major, the box's width) and its
/// right and down links within the box, or [`BoxLinks::Open`] when the box is an open grid.
#[derive(Clone, Debug, PartialEq)]
enum BoxLinks {
    /// Every node active, every link there (none off the last column or row): nothing to copy into a key or compare.
    Open,
    /// `outside`: the box's nodes in no piece (off the matte), which the prolongation may fill (`Level::with_holes_filled`).
    Given { active: Vec<bool>, right: Vec<bool>, down: Vec<bool>, outside: Vec<bool> },
}

impl BoxLinks {
    /// The nodes and links on a `w × h` box, as [`Geometry::new`] takes them.
    fn vectors(&self, w: usize, h: usize) -> [Vec<bool>; 3] {
        match self {
            BoxLinks::Given { active, right, down, .. } => [active.clone(), right.clone(), down.clone()],
            BoxLinks::Open => { let g = Grid::new(w, h); [g.active, g.link_right, g.link_down] }
        }
    }

    /// The box's nodes off the matte (none on an open box).
    fn outside(&self) -> Option<&[bool]> { if let BoxLinks::Given { outside, .. } = self { Some(outside) } else { None } }
}

/// Piece `l`'s grid on its box `[x0, y0, x1, y1]` ([`BoxLinks`]); on an open grid (the box) the labels are not read.
fn piece_links(grid: &Grid, labels: &[u32], l: u32, [x0, y0, x1, y1]: [usize; 4], open: bool) -> BoxLinks {
    if open { return BoxLinks::Open; }
    let (w, bw, bh) = (grid.width, x1 - x0, y1 - y0);
    let (mut active, mut right, mut down, mut outside) = (vec![false; bw * bh], vec![false; bw * bh], vec![false; bw * bh], vec![false; bw * bh]);
    // Without short-circuits, so that the passes vectorise (every solve builds its key).
    for by in 0..bh {
        let (g, b) = ((y0 + by) * w + x0..(y0 + by) * w + x1, by * bw..(by + 1) * bw);
        for ((a, o), &lab) in active[b.clone()].iter_mut().zip(&mut outside[b.clone()]).zip(&labels[g.clone()]) {
            (*a, *o) = (lab == l, lab == u32::MAX);
        }
        let act = &active[b.clone()];
        for ((r, &link), &a) in right[b.clone()].iter_mut().zip(&grid.link_right[g.clone()]).zip(act).take(bw - 1) { *r = link & a }
        if by + 1 < bh {
            for ((d, &link), &a) in down[b].iter_mut().zip(&grid.link_down[g]).zip(act) { *d = link & a }
        }
    }
    BoxLinks::Given { active, right, down, outside }
}

/// A piece's solution on its box, node (x, y) at `values[first + y · stride + x]`: the solve's padded vector (no
/// copy) or an unpadded one (stride the box's width). Its nodes off the piece are not read.
struct BoxValues { values: Vec<V2>, stride: usize, first: usize }

impl BoxValues {
    /// Row `y` of the box, `w` nodes wide.
    fn row(&self, y: usize, w: usize) -> &[V2] { &self.values[self.first + y * self.stride..][..w] }

    /// The `w × h` box's values, unpadded.
    fn dense(&self, w: usize, h: usize) -> Vec<V2> { (0..h).flat_map(|y| self.row(y, w).to_vec()).collect() }
}

/// Solves one piece on its box: `key` the box's grid (the piece active, its links, its fixed nodes), `value` the
/// fixed nodes' values (`cold_gauge` a one-line piece's gauge node and value for the cold start), `initial` a start
/// (the whole grid's field, the box's first node x0, y0), `settled` what the iteration keeps to ([`Settled`]),
/// `spannable` whether it may start from earlier answers. Returns the box's solution and the report's solver fields.
#[allow(clippy::too_many_arguments)]
fn solve_piece(
    key: CacheKey, value: &[(usize, V2)], cold_gauge: Option<(usize, V2)>, initial: Option<(FieldView<'_>, usize, usize)>, options: &SolveOptions, store: &mut Store,
    settled: Option<&nullspace::Membrane>, spannable: bool,
) -> (BoxValues, SolveReport) {
    let (w, h, tau) = (key.w, key.h, f64::from_bits(key.tau_bits));
    let mut report = SolveReport::default();
    let kept = if options.off.has("cache") { None } else { store.hierarchies.take(store.solve, &key, |_| true) };
    let fresh = kept.is_none();
    store.built += u64::from(fresh);
    let mut hier = kept.unwrap_or_else(|| {
        let [active, right, down] = key.links.vectors(w, h);
        let geo = Geometry::new(w, h, active, right, down, Some(key.fixed.clone()));
        let fine = Level::fine(geo, tau);
        // Holes and cuts: wide holes are filled for the prolongation (`Level::with_holes_filled`), cuts crossed by
        // linear extrapolation (`Geometry::geo_row`); where inactive nodes remain (thin holes, holes open to the
        // border, other pieces in the box), a second coarse space (visited by V-cycles) runs smoothly across them.
        let torn = fine.geo.torn();
        let real = torn.then(|| fine.geo.clone());
        // A small torn piece is solved whole by its banded factor: exact, so no weakly held part's slow mode hides
        // from the stopping rule (`docs/dev/solver-correctness.md`, "Small torn pieces solved whole"). Not where it
        // drops a pivot no free function accounts for (a soft part's, such as a strand's tip, which it would hold
        // still; at τ > 0 a count cannot tell them apart).
        let unknowns = fine.inv_diag.iter().filter(|&&d| d != 0.0).count();
        let small = torn && cycle::banded_work(unknowns, w, h) <= DIRECT_WORK && !key.off.has("whole");
        let whole = small.then(|| if tau > 0.0 { 0 } else { settled.map_or(0, |m| m.len()) });
        // A piece torn by holes or its matte's edges alone coarsens only to the first level a `DIRECT_WORK` factor
        // solves (fewer cycles on hair, combs, characters); not one with a cut inside, whose parts' slow turns the
        // faster convergence hid from the stopping rule (`docs/dev/solver-correctness.md`, "A larger exact coarsest level").
        let exact_work = (torn && !fine.geo.cut_inside() && !key.off.has("exact_coarsest")).then_some(DIRECT_WORK);
        let fine = fine.with_holes_filled(key.links.outside().filter(|_| !key.off.has("outside")));
        let second = fine.geo.active.contains(&false) && !key.off.has("second");
        let coarse = if torn { SMOOTHING_STEPS } else { OPEN_COARSE_SMOOTHING };
        let mut hier = Hierarchy::new(fine, SMOOTHING_STEPS, coarse, true, whole, exact_work);
        let alt = (second && !hier.whole).then(|| Box::new(Hierarchy::coarse_space(Level::fine(real.unwrap(), tau).into_plain(), SMOOTHING_STEPS, exact_work)));
        (hier.k_cycles, hier.alt, hier.torn) = (!key.off.has("kcycle"), alt, torn);
        if !hier.whole && !key.off.has("strands") {
            // (An untorn finest level wider and taller than a strand has none.)
            hier.strands = (torn || w.min(h) <= strands::THIN).then(|| strands::Strands::new(&hier.levels[0], false)).flatten();
            if !key.off.has("coarse_strands") {
                hier.level_strands = hier.levels.iter().enumerate().map(|(k, l)| if k == 0 || k + 1 == hier.levels.len() { None } else { strands::Strands::new(l, false) }).collect();
            }
        }
        if torn && !hier.whole && settled.is_none() && !key.off.has("affine") {
            // Its two vectors become the solve's residual and product below.
            let (mut x, mut q) = (cycle::zeros_in(None, hier.levels[0].len_padded()), cycle::zeros_in(None, hier.levels[0].len_padded()));
            hier.affine = cycle::Affine::new(&hier.levels[0], &mut x, &mut q);
            hier.spare.extend([x, q]);
        }
        if key.off.has("fours") {
            hier.levels.iter_mut().chain(hier.alt.iter_mut().flat_map(|a| a.levels.iter_mut())).for_each(Level::drop_fours);
        }
        hier
    });
    let len = hier.levels[0].len_padded();
    let mut u: Vec<V2> = vec![[0.0; 2]; len];
    let fine = &hier.levels[0];
    if let Some((field, x0, y0)) = initial {
        // Row by row in parallel (zero off the unknowns); the padding stays zero.
        let wp = fine.wp;
        u[PAD * wp..(PAD + h) * wp].par_chunks_mut(wp).enumerate().for_each(|(y, row)| {
            let (g, p) = ((y0 + y) * field.width() + x0, fine.pidx(0, y));
            let row = row[PAD..PAD + w].iter_mut().zip(&fine.inv_diag[p..p + w]);
            let take = |d: f64, vx: f32, vy: f32| if d != 0.0 { [vx as f64, vy as f64] } else { [0.0; 2] };
            match field {
                FieldView::Planar(f) => row.zip(f.dx[g..].iter().zip(&f.dy[g..])).for_each(|((ux, &d), (&x, &y))| *ux = take(d, x, y)),
                FieldView::Interleaved { data, .. } => row.zip(data[2 * g..].chunks_exact(2)).for_each(|((ux, &d), v)| *ux = take(d, v[0], v[1])),
            }
        });
    }
    let pin = |u: &mut [V2]| value.iter().for_each(|&(i, v)| u[fine.pidx(i % w, i / w)] = v);
    pin(&mut u);
    // A capped solve goes on when the next starts from its answer (`solve_constrained`) with the same constraints
    // (not the gauge, whose value is the start's) and tolerance: started over, a series could stop far from the answer.
    let constraints = &value[..value.len() - usize::from(cold_gauge.is_some())];
    let resumed = hier.paused.take().filter(|p| {
        store.goes_on && options.method == SolveMethod::Multigrid && p.tolerance == options.tolerance_px && p.value == constraints
    });
    let mut r = match &resumed { Some(_) => Vec::new(), None => cycle::zeros_in(hier.spare.pop(), len) };
    // Values in the span of earlier ones start from their answers' combination (`Answers`) instead of `initial`,
    // unless that meets the tolerance already (a capped series solves converged pieces again) or no cycle runs.
    let linear = spannable && store.answers && options.method == SolveMethod::Multigrid && !hier.whole
        && options.max_cycles != Some(0) && !options.off.has("answers");
    let given = (initial.is_some() && resumed.is_none()).then(|| fine.residual_scaled_max(&u, &mut r));
    let spanned = resumed.is_none() && linear && !given.is_some_and(|g| g <= options.tolerance_px)
        && hier.answers.start(value, options.tolerance_px).map(|s| { u = s; pin(&mut u) }).is_some();
    // A cold solve starts coarse to fine, as does a warm one whose start leaves residuals above the tolerance (unless
    // no cycle may run); a closer start (earlier frames' prediction, earlier answers) first gets one cycle as it is,
    // and the coarse-to-fine correction only if that cycle did not finish.
    let (mut warm, cycles) = (initial.is_some() || spanned, options.max_cycles.unwrap_or(DEFAULT_MAX_CYCLES));
    let mut started = !warm;
    if let Some(p) = &resumed { started = p.started } else if warm {
        report.initial_residual = match given { Some(g) if !spanned => g, _ => fine.residual_scaled_max(&u, &mut r) };
        started = !spanned && (report.initial_residual > options.tolerance_px || report.initial_residual.is_nan()) && cycles > 0;
        if started {
            // A start worse than none (huge or unrelated values) gives way to the cold one (`docs/dev/solver-correctness.md`).
            let mut cold = cycle::zeros_in(hier.spare.pop(), len);
            pin(&mut cold);
            if let Some((i, v)) = cold_gauge { cold[fine.pidx(i % w, i / w)] = v }
            if report.initial_residual <= fine.residual_scaled_max(&cold, &mut r) {
                fine.residual_scaled_max(&u, &mut r);
            } else {
                std::mem::swap(&mut u, &mut cold);
                warm = false;
            }
            hier.spare.push(cold);
        }
    }
    if started && resumed.is_none() {
        // A warm start's residual is in r already.
        hier.coarse_to_fine(&mut u, &mut r, warm);
        report.initial_residual = hier.levels[0].residual_scaled_max(&u, &mut r);
    }
    // The last change, and the last two cycles' ratios of successive changes.
    let (mut last_change, mut ratios) = resumed.as_ref().map_or((f64::INFINITY, [0.0f64; 2]), |p| (p.last_change, p.ratios));
    let base = resumed.as_ref().map_or(0, |p| p.cycle); // the cycles run before it
    let margin = if hier.torn { TORN_STOP_MARGIN } else { STOP_MARGIN };
    // A torn piece's claim is relative to its largest constrained value; a warm start's on a new hierarchy (no earlier
    // solve's slow modes to check it on) to how far its constrained values move: the size of the correction it solves.
    let moved = |(f, x0, y0): (FieldView<'_>, usize, usize)| {
        largest(constraints.iter().map(|&(i, v)| {
            let o = f.at_index((y0 + i / w) * f.width() + x0 + i % w);
            [v[0] - o[0] as f64, v[1] - o[1] as f64]
        }))
    };
    let correction = initial.filter(|_| warm && fresh && !spanned).map_or(f64::INFINITY, moved);
    let scale = if !hier.torn || options.off.has("relative") { f64::INFINITY } else { largest(constraints.iter().map(|p| p.1)).min(correction) };
    let claim = options.tolerance_px.min((RELATIVE_CLAIM * scale).max(0.1 * options.tolerance_px));
    // A single level whose dropped pivots are all free functions' is an exact solve: after its first step only
    // rounding moves, in which neither the ratios nor the Lanczos floor tell a rate.
    let direct = hier.levels.len() == 1 && hier.dropped() <= settled.map_or(0, |m| m.len());
    // A torn piece's cold solve, or one from earlier answers (their errors are those solves' slow modes), never stops
    // after its first cycle: with no ratio yet, a slow mode the first step barely moved hides behind a small change.
    let first_may_stop = !hier.torn || (warm && !spanned) || direct;
    let mut tail = f64::INFINITY; // the stopping rule's last estimate of the error: the changes' geometric tail
    // A CG step takes `α·pᵀr` (`α·rᵀz` unprojected) off the error's squared energy norm, per component: where that
    // falls geometrically, the root of two successive steps' ratio estimates its rate (the larger component's).
    let (mut last_energy, mut energy_rates) = ([0.0f64; 2], [f64::INFINITY; 2]);
    let mut stop = |(change, rate): (f64, Option<f64>), cycle: usize, report: &mut SolveReport, (floor, settled): (f64, bool), energy: [f64; 2]| {
        let step_rate = (0..2).filter(|&c| last_energy[c] > 0.0 && energy[c] >= 0.0).map(|c| (energy[c] / last_energy[c]).sqrt()).reduce(f64::max);
        (last_energy, energy_rates) = (energy, [energy_rates[1], step_rate.unwrap_or(f64::INFINITY)]);
        (report.cycles, report.final_change_px) = (cycle - base, change);
        // Geometric convergence at rate ρ leaves change·ρ/(1−ρ) to go. CG steps are not geometric: ρ is the larger of
        // the last two ratios (0.5 before one; where the spectrum has settled and the last change fell, their geometric
        // mean, capped by the energy norm's larger rate over the last two steps, which long and short steps do not
        // swing), at least the Lanczos floor; 0.99 never stops.
        let ratio = rate.unwrap_or(if last_change.is_finite() && last_change > 0.0 { change / last_change } else { 0.5 });
        ratios = [ratios[1], ratio];
        let fell = settled && ratios[0] > 0.0 && ratio < 1.0;
        let two = if fell { (ratios[0] * ratios[1]).sqrt() } else { ratios[0].max(ratios[1]) };
        let two = if fell && rate.is_none() { two.min(energy_rates[0].max(energy_rates[1])) } else { two };
        let rho = if direct { 0.0 } else { floor.max(two) };
        (last_change, tail) = (change, change * (rho / (1.0 - rho)));
        (cycle > 1 || first_may_stop) && change.is_finite() && rho < 0.99 && margin * change.max(tail) <= claim
    };
    // The search direction p is kept in `f32` and its product `q = −A p` in `f64` (the concept doc's Precision).
    let (mut q, mut p) = if resumed.is_some() { (Vec::new(), std::mem::take(&mut hier.direction)) } else {
        (cycle::zeros_in(hier.spare.pop(), len), cycle::zeros_in(Some(std::mem::take(&mut hier.direction)), len))
    };
    let (mut southwell_spent, mut found, mut pause) = (false, false, None);
    match options.method {
        SolveMethod::Multigrid => {
            // Where every free function can be settled, the iteration keeps to settled answers (`Settled`).
            let membrane = settled;
            let settled = settled.and_then(|m| Settled::new(m, &hier.levels[0]));
            if let Some(s) = settled.as_ref().filter(|_| resumed.is_none()) {
                s.project(&hier.levels[0], &mut u);
                hier.levels[0].residual(&u, None, &mut r);
            }
            // (Not where free functions are left unsettled: the probe's start would keep them.)
            let unsettled = settled.is_none() && membrane.is_some_and(|m| m.len() > 0);
            let mut slow = deflate::Deflation::new(len, options.off.has("deflate"), hier.torn, warm && (fresh || hier.probed && !spanned));
            // (Nor where the deflation's budget leaves no room: nothing could use what it finds.)
            let may_probe = hier.torn && !hier.whole && !unsettled && !options.off.has("probe") && slow.on();
            let mut probe_now = false;
            let mut rz = if let Some(was) = resumed {
                (u, r, q, slow, found, hier.probed, probe_now) = (was.u, was.r, was.q, was.slow, was.found, was.probed_before, was.probe_now);
                report.initial_residual = scaled_max(&r, &hier.levels[0].inv_diag);
                was.rz
            } else {
                fresh_direction(&mut hier, &r, &mut p, settled.as_ref(), Some(&slow))
            };
            for cycle in base + 1..=base + cycles {
                if crate::interrupt::requested() { break; }
                if cycle == HALVE_AT && hier.strands.as_ref().is_some_and(|s| s.wide) {
                    // A slow solve whose finest level left meshes of strands to the cycle: solved in parts from here.
                    hier.strands = strands::Strands::new(&hier.levels[0], true);
                    rz = restart_directions(&mut hier, &mut u, &mut r, &mut p, settled.as_ref(), &mut slow);
                }
                // A slow solve probes, and so does a weakly held piece's first claim: each solve (`found` till the loop
                // ends), as no solve keeps the slow modes an earlier one's probe found.
                if may_probe && !found && (cycle == PROBE_AT || probe_now) {
                    (hier.probed, found) = (true, true);
                    if let Some(rest) = probe(&mut hier, settled.as_ref(), len, &mut report.probe_cycles) {
                        // Deflated here: what the probe left.
                        if let Some(modes) = deflate::Modes::with(rest, &hier.levels[0]) {
                            slow.adopt(&hier.levels[0], modes, &mut u, &mut r);
                            rz = restart_directions(&mut hier, &mut u, &mut r, &mut p, settled.as_ref(), &mut slow);
                        }
                    }
                }
                // Projected directions are no longer z + βp_old, and rᵀz can be far from pᵀr (the cycle magnifies the
                // near-null modes the projection takes out): the step is then the exact line search's, pᵀr / pᵀAp.
                let along = if slow.projects() || settled.is_some() { dot_z(&r, &p) } else { rz };
                let (change, alpha) = energy_step(&hier, &mut u, &mut r, &p, &mut q, along);
                if change.is_nan() {
                    // The directions broke down; the iterate stands, unconverged.
                    (report.cycles, report.final_change_px) = (cycle - base, f64::INFINITY);
                    report.fail(Stop::Breakdown);
                    break;
                }
                slow.step(alpha);
                if stop(slow.judged(change), cycle, &mut report, slow.rate_floor(), [alpha[0] * along[0], alpha[1] * along[1]]) {
                    // A claim is checked on the slow modes an earlier solve found (it goes on where they move it): a
                    // warm start's error can lie in them, unseen by the changes before and after this solve's own
                    // probe. A piece with free functions is weakly held: with nothing to check, it probes first.
                    let weak = may_probe && settled.is_some() && !found;
                    probe_now = weak && hier.checks.is_none();
                    if hier.checks.as_ref().map_or(!weak, |m| margin * m.largest_move(&r) <= claim) { report.converged = true; break }
                }
                if slow.record(cycle, &p, &q) {
                    // A window of directions kept: correct on the slow modes found, restart the directions deflated.
                    slow.restart(&hier.levels[0], &mut u, &mut r);
                    rz = restart_directions(&mut hier, &mut u, &mut r, &mut p, settled.as_ref(), &mut slow);
                    continue;
                }
                if !started {
                    started = true;
                    hier.coarse_to_fine(&mut u, &mut r, true);
                    if let Some(s) = &settled { s.project(&hier.levels[0], &mut u) }
                    hier.levels[0].residual(&u, None, &mut r);
                    slow.correct(&hier.levels[0], &mut u, &mut r);
                    rz = fresh_direction(&mut hier, &r, &mut p, settled.as_ref(), Some(&slow));
                    slow.beta(None);
                    continue;
                }
                let beta;
                (rz, beta) = next_direction(&mut hier, &r, &q, &mut p, (alpha, along), settled.as_ref(), Some(&slow));
                slow.beta(Some(beta));
            }
            if !report.converged && report.stop == Stop::Converged && report.cycles > 0 && !crate::interrupt::requested() {
                // Out of cycles: where it stands, for a next solve that goes on (its deflation its own). Its probe counts
                // for that solve only: the hierarchy is unprobed for any other.
                pause = Some(Paused { u: u.clone(), r: Vec::new(), q: Vec::new(), rz, slow, cycle: base + report.cycles, ratios, last_change, started, found, probed_before: hier.probed, probe_now, value: constraints.to_vec(), tolerance: options.tolerance_px });
                hier.probed = false;
            } else {
                found |= slow.restarts > 0;
                if report.converged && found && may_probe { hier.checks = slow.modes() }
            }
        }
        SolveMethod::Southwell => {
            // Rounds of one coarse correction and one sweep's worth of relaxations until the budget or `max_cycles`
            // runs out; converged only by the multigrid's bound or nothing left to relax, never by a spent budget.
            let unknowns = hier.levels[0].inv_diag.iter().filter(|&&d| d != 0.0).count().max(1);
            let mut left = (options.southwell_sweeps * unknowns as f64).round() as usize;
            let mut round = 0;
            while left > 0 && round < cycles && !crate::interrupt::requested() {
                let rz = fresh_direction(&mut hier, &r, &mut p, None, None);
                let (step, _) = energy_step(&hier, &mut u, &mut r, &p, &mut q, rz);
                let take = unknowns.min(left);
                let (relaxed, finished) = southwell::relax(&hier.levels[0], &mut u, take, unknowns);
                left -= take;
                round += 1;
                hier.levels[0].residual(&u, None, &mut r);
                // No node moved by more than the two parts' largest moves together.
                if stop((step + relaxed, None), round, &mut report, (0.0, false), [0.0; 2]) || finished {
                    report.converged = true;
                    break;
                }
            }
            southwell_spent = left == 0;
        }
    }
    // The conjugate-gradient residual is updated, not recomputed: it is the residual of u up to rounding. The
    // maxima pass over a NaN, so the same pass checks the field: one that is not finite is never converged.
    let (residual, finite, largest) = r.par_chunks(CHUNK).zip(hier.levels[0].inv_diag.par_chunks(CHUNK)).zip(u.par_chunks(CHUNK))
        .map(|((r, d), u)| {
            let finite = u.iter().all(|v| v[0].is_finite() && v[1].is_finite());
            (scaled_max(r, d), finite, u.iter().fold(0.0, |m, v| larger(larger(m, v[0].abs()), v[1].abs())))
        })
        .reduce(|| (0.0, true, 0.0), |a, b| (larger(a.0, b.0), a.1 && b.1, larger(a.2, b.2)));
    report.residual = residual;
    if !report.converged && report.stop == Stop::Converged {
        // The loop ran out: its cycles, the interrupt, or Southwell's budget.
        report.stop = if crate::interrupt::requested() { Stop::Interrupted } else if southwell_spent { Stop::Budget } else { Stop::MaxCycles };
    }
    // A field not finite, or a tolerance finer than its `f32` resolution, is the reason whatever stopped the loop (but
    // `max_cycles` 0, which ran none); a scaled residual above 4 tolerances fails too: |D⁻¹A e| ≤ 4 max|e| (each
    // energy term's coefficients sum to at most 4 times the one at the row's node).
    if !finite || (options.tolerance_px < FINEST_TOLERANCE * largest && (cycles > 0 || report.converged)) {
        (report.converged, report.stop) = (false, if finite { Stop::Precision } else { Stop::Breakdown });
    } else if residual > 4.0 * options.tolerance_px {
        report.fail(Stop::Residual);
    }
    // A solve that did not converge does not keep its probe (the next slow solve probes again).
    if found && !report.converged { (hier.probed, hier.checks) = (false, None) }
    if let Some(at) = pause.filter(|_| report.stop == Stop::MaxCycles) { hier.paused = Some(Box::new(Paused { r, q, ..at })) } else { hier.spare.extend([r, q]) }
    // Not from a hierarchy's first solve: a solver used once (or keeping no hierarchy) would only pay for it.
    if linear && report.converged && !fresh { hier.answers.add(value, &u, tail, options.tolerance_px) }
    hier.direction = p;
    let fine = &hier.levels[0];
    let out = BoxValues { values: u, stride: fine.wp, first: fine.pidx(0, 0) };
    if !options.off.has("cache") { store.hierarchies.put(store.solve, key, hier) }
    (out, report)
}

/// Where a piece's solve stood when its cycle limit stopped it: the iterate (in `f64`), residual, direction's
/// product, deflation, stopping rule and probe, and what it solved (the constrained values and the tolerance).
#[derive(Debug)]
pub(crate) struct Paused {
    u: Vec<V2>, r: Vec<V2>, q: Vec<V2>, rz: [f64; 2], slow: deflate::Deflation, cycle: usize, ratios: [f64; 2], last_change: f64,
    started: bool, found: bool, probed_before: bool, probe_now: bool, value: Vec<(usize, V2)>, tolerance: f64,
}

/// The cycle at which a torn piece's solve still running probes its operator (one with free functions probes before
/// its first claim if that comes sooner), and the probe's cycles.
const PROBE_AT: usize = 20;
const PROBE_CYCLES: usize = 24;

/// The cycle at which a solve still running halves the meshes of strands its finest level left to the cycle.
const HALVE_AT: usize = 2 * PROBE_AT;

/// What the iteration on `A x = 0` leaves of a pseudo-random start, by component: a torn piece's slow modes. The
/// start, unlike a residual, holds every mode (a weakly held part's bending, however little a right side shows it).
fn probe(hier: &mut Hierarchy, settled: Option<&Settled>, len: usize, ran: &mut usize) -> Option<Vec<Vec<f64>>> {
    let fine = &hier.levels[0];
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut u: Vec<V2> = fine.inv_diag.iter().map(|&d| if d != 0.0 { [next(), next()] } else { [0.0; 2] }).collect();
    if let Some(s) = settled { s.project(fine, &mut u) }
    let (mut r, mut q) = (vec![[0.0; 2]; len], vec![[0.0; 2]; len]);
    fine.residual(&u, None, &mut r);
    let mut p = cycle::zeros_in(None, len);
    let mut rz = fresh_direction(hier, &r, &mut p, settled, None);
    for _ in 0..PROBE_CYCLES {
        if crate::interrupt::requested() { return None; }
        *ran += 1;
        let along = if settled.is_some() { dot_z(&r, &p) } else { rz };
        let (change, alpha) = energy_step(hier, &mut u, &mut r, &p, &mut q, along);
        if !change.is_finite() { return None; }
        rz = next_direction(hier, &r, &q, &mut p, (alpha, along), settled, None).0;
    }
    Some((0..2).map(|c| u.iter().map(|v| v[c]).collect()).collect())
}

/// Piece `l`'s nodes of its box `[x0, y0, x1, y1]` from `u`, to the field.
fn write_piece(field: &mut Field, labels: &[u32], l: u32, [x0, y0, x1, y1]: [usize; 4], u: &BoxValues) {
    let (w, bw) = (field.width, x1 - x0);
    let (dx, dy) = (&mut field.dx[y0 * w..y1 * w], &mut field.dy[y0 * w..y1 * w]);
    dx.par_chunks_mut(w).zip(dy.par_chunks_mut(w)).enumerate().with_min_len(4).for_each(|(by, (dx, dy))| {
        let (lab, v) = (&labels[(y0 + by) * w + x0..(y0 + by) * w + x1], u.row(by, bw));
        for (((dx, dy), &lab), v) in dx[x0..x1].iter_mut().zip(&mut dy[x0..x1]).zip(lab).zip(v) {
            if lab == l { (*dx, *dy) = (v[0] as f32, v[1] as f32) }
        }
    });
}

/// The affine map `(x, y) ↦ value` that fits the constraints `value` (box nodes `bw` wide) to rounding, if any.
fn affine_fit(value: &[(usize, V2)], bw: usize) -> Option<impl Fn(usize, usize) -> V2> {
    let at = |j: usize| [(j % bw) as f64, (j / bw) as f64];
    // Coordinates about the first constraint, for conditioning.
    let o = at(value.first()?.0);
    let rel = |j: usize| [at(j)[0] - o[0], at(j)[1] - o[1]];
    let a = affine_least_squares(value.iter().map(|&(j, v)| (rel(j), v)))?;
    let map = move |[x, y]: [f64; 2]| [a[0][0] + a[1][0] * x + a[2][0] * y, a[0][1] + a[1][1] * x + a[2][1] * y];
    let scale = largest(value.iter().map(|p| p.1)).max(1.0);
    let fits = value.iter().all(|&(j, v)| {
        let p = map(rel(j));
        (p[0] - v[0]).abs().max((p[1] - v[1]).abs()) <= 1e-9 * scale
    });
    fits.then_some(move |x: usize, y: usize| map([x as f64 - o[0], y as f64 - o[1]]))
}

/// At most this many finest nodes of hierarchies, and as many of free functions, a solver keeps beyond its latest
/// solve's (`docs/dev/core-measurements.md` has what a node costs).
const KEPT_MAX_NODES: usize = 1 << 22;

/// The solver a caller keeps between the solves of one surface (an animated layer, the editor's drags): the
/// hierarchies and free functions of its recent solves' pieces (they depend on the grid, the fixed nodes and the
/// tension, never on the values, so an animation's frames share them; as many before them stay, for an undo),
/// each piece's converged answers (a later solve whose values they span starts from their
/// combination: `history::Answers`) and the warm-start history ([`WarmHistory`]). Nothing is kept between solves
/// outside it: [`solve`] uses a temporary one.
///
/// ```
/// use inkwarp_core::{solve::{Solver, SolveOptions}, Grid, Sample};
/// let grid = Grid::new(33, 33);
/// let s = |x, y, dx| Sample { rest: [x, y], displacement: [dx, 0.0] };
/// let mut solver = Solver::new();
/// for frame in 0..3 {
///     let samples = [s(0.0, 0.0, 0.0), s(32.0, 32.0, 0.0), s(16.0, 8.0, frame as f64)];
///     let (field, report) = solver.solve_warm(&grid, &samples, &SolveOptions::default(), None).unwrap();
///     assert!(report.converged);
///     assert_eq!(field.at(16, 8), [frame as f32, 0.0]);
/// }
/// assert_eq!(solver.history().len(), 3);
/// ```
#[derive(Default)]
pub struct Solver {
    store: Store,
    history: WarmHistory,
}

impl Solver {
    pub fn new() -> Solver { Solver::default() }

    /// [`solve`] from `initial`, keeping what the next solve can reuse (not the history).
    pub fn solve(&mut self, grid: &Grid, samples: &[Sample], options: &SolveOptions, initial: Option<FieldView<'_>>) -> Result<(Field, SolveReport), SolveError> {
        solve_with(grid, samples, options, initial, self, false)
    }

    /// [`solve`] started from the history and `initial` ([`WarmHistory::start`]: whichever
    /// is closer), which then keeps the result. With `grid_step` above 1 the history keeps
    /// and combines the coarse solves' fields, and `initial` is read at the coarse nodes
    /// only: a draft's start costs a pass over its coarse grid, not over every pixel.
    pub fn solve_warm(&mut self, grid: &Grid, samples: &[Sample], options: &SolveOptions, initial: Option<Field>) -> Result<(Field, SolveReport), SolveError> {
        solve_with(grid, samples, options, initial.as_ref().map(FieldView::from), self, true)
    }

    /// [`Solver::solve_warm`] for an animation's frame: after a multigrid frame that did not converge, or any that
    /// failed (an interrupt), the next starts afresh (from that answer the stopping rule can miss its error and claim
    /// convergence); Southwell's (a fixed budget) stay starts.
    pub fn solve_frame(&mut self, grid: &Grid, samples: &[Sample], options: &SolveOptions) -> Result<(Field, SolveReport), SolveError> {
        let solved = self.solve_warm(grid, samples, options, None);
        if solved.as_ref().map_or(true, |(_, r)| !r.converged && options.method == SolveMethod::Multigrid) { self.history.clear() }
        solved
    }

    /// [`Solver::solve_warm`] at `grid_step` > 1 evaluated at `pixels` only (row-major indices into `grid`): the
    /// coarse solve, from and into the history, then the upsampled field at those pixels, written to `out` as
    /// (Δx, Δy) pairs (`2 · pixels.len()` floats). The values are the full field's up to the rounding of the
    /// sums' order (a few units in the last place of `f32`). `plan` must have been built for `grid` and
    /// `options.grid_step`.
    pub fn solve_warm_at(
        &mut self, grid: &Grid, samples: &[Sample], options: &SolveOptions, plan: &Upsampling, pixels: &[u32], out: &mut [f32],
    ) -> Result<SolveReport, SolveError> {
        upsample::solve_at(grid, samples, options, self, plan, pixels, out)
    }

    /// The earlier solves a warm solve starts from.
    pub fn history(&self) -> &WarmHistory { &self.history }

    /// Forgets the history and the pieces' earlier answers (the next solve starts cold). The hierarchies, free
    /// functions and work vectors stay.
    pub fn clear(&mut self) {
        self.history.clear();
        self.store.hierarchies.0.iter_mut().for_each(|e| e.1.answers = Default::default());
    }

    /// Drops the hierarchies, free functions and work vectors (the history and the count of hierarchies built
    /// stay): for a caller short of memory between the solves of a large grid.
    pub fn release_levels(&mut self) { self.store = Store { built: self.store.built, ..Store::default() } }
}

impl std::fmt::Debug for Solver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (kept, built) = (self.store.hierarchies.0.len(), self.store.built);
        f.debug_struct("Solver").field("hierarchies", &kept).field("built", &built).field("history", &self.history.len()).finish()
    }
}

/// What a [`Solver`] keeps for reuse.
#[derive(Default)]
pub(crate) struct Store {
    hierarchies: Kept<Hierarchy>,
    free: Kept<Free>,
    /// The solves so far: each entry is marked with the last one that used it.
    solve: u64,
    /// The hierarchies built so far.
    built: u64,
    /// The field the latest solve returned if its cycle limit stopped it, and whether this solve starts from it.
    written: Option<Field>,
    goes_on: bool,
    /// Whether this solve starts from and keeps its pieces' answers (`history::Answers`): not an animation's
    /// frame, which starts from the frames before it as closely, and sooner, for less.
    answers: bool,
}

/// Entries by what they depend on, the least recently used first: what the latest solve that used any used, whatever
/// its size (an undo's too), and as many before within a node limit (the second field; [`Kept::room`], [`Kept::trim`]).
pub(crate) struct Kept<T>(Vec<(CacheKey, T, u64)>, usize);

impl<T> Default for Kept<T> { fn default() -> Self { Kept(Vec::new(), KEPT_MAX_NODES) } }

impl<T> Kept<T> {
    /// The latest entry of `key` that `also` accepts, taken out (back by [`Kept::put`]); if none, room is made for one.
    fn take(&mut self, solve: u64, key: &CacheKey, also: impl Fn(&T) -> bool) -> Option<T> {
        let pos = self.0.iter().rposition(|(k, t, _)| k == key && also(t));
        if pos.is_none() { self.room(solve, key) }
        pos.map(|pos| self.0.remove(pos).1)
    }

    /// Keeps `value`, used by solve number `solve`.
    fn put(&mut self, solve: u64, key: CacheKey, value: T) { self.0.push((key, value, solve)) }

    /// The finest nodes of every entry.
    fn nodes(&self) -> usize { self.0.iter().map(|e| e.0.w * e.0.h).sum() }

    /// Before solve number `solve` builds `key`'s entry, while it would not fit in the node limit: drops the oldest
    /// entry of the same piece (box's first node) from earlier, else the oldest that neither this solve nor the latest
    /// before it used (it may yet reach those).
    fn room(&mut self, solve: u64, key: &CacheKey) {
        let before = self.0.iter().map(|e| e.2).filter(|&s| s < solve).max().unwrap_or(0);
        while self.nodes() + key.w * key.h > self.1 {
            let Some(pos) = self.0.iter().position(|e| e.2 != solve && e.0.at == key.at).or_else(|| self.0.iter().position(|e| e.2 < before)) else { return };
            self.0.remove(pos);
        }
    }

    /// Once solve number `latest` (of `pieces` constrained pieces) used any: drops what is past the count limit,
    /// then the oldest unused while over the node limit.
    fn trim(&mut self, latest: u64, pieces: usize) {
        let used = self.0.iter().filter(|e| e.2 == latest).count();
        if used == 0 { return }
        self.0.drain(..self.0.len().saturating_sub(2 * used.max(pieces)));
        while self.nodes() > self.1 {
            let Some(pos) = self.0.iter().position(|e| e.2 != latest) else { return };
            self.0.remove(pos);
        }
    }
}

/// A torn piece's functions of zero plate energy that its constraints leave free (hinges, strands, thin rings, a
/// one-line piece's tilt): beyond the tilt, the iteration alone does not give the contract's answer (`nullspace`).
/// They depend on the piece's grid and fixed nodes alone, so a solver keeps them with the hierarchy.
pub(crate) struct Free {
    /// A one-line piece's gauge node (see [`Piece::Line`]).
    gauge: Option<usize>,
    /// How many there are (`None`: too many to settle).
    count: Option<usize>,
    /// Their least-membrane settling, where there are any beyond a one-line piece's tilt.
    membrane: Option<nullspace::Membrane>,
    /// A one-line piece's: the settling of those that vanish at its gauge node too.
    pinned: Option<nullspace::Membrane>,
}

impl Free {
    /// The free functions of the piece on `geo` (none on an open grid) with its constrained nodes, and with `gauge` too.
    fn new(geo: Option<&nullspace::BoxGeo>, constrained: &[bool], fixed: &[bool], gauge: Option<usize>) -> Free {
        let null = geo.map_or(Some(Vec::new()), |g| nullspace::plate_null_space(g, constrained, nullspace::MAX_NULL));
        let count = null.as_ref().map(Vec::len);
        let settling = null.filter(|b| b.len() > usize::from(gauge.is_some())).zip(geo);
        let pinned = gauge.and(settling.as_ref()).and_then(|(_, g)| nullspace::plate_null_space(g, fixed, nullspace::MAX_NULL));
        let pinned = pinned.filter(|b| !b.is_empty()).zip(geo).map(|(b, g)| nullspace::Membrane::new(g, b));
        Free { gauge, count, membrane: settling.map(|(b, g)| nullspace::Membrane::new(g, b)), pinned }
    }
}

/// Safety factors of the stopping rule on open grids and on grids with holes or cuts, where the slowest error moves
/// least per cycle (`docs/dev/ablation.md`, "Constants").
const STOP_MARGIN: f64 = 1.5;
const TORN_STOP_MARGIN: f64 = 3.0;
/// A torn piece's claim needs changes within this part of its largest constrained value too: a weakly held part's slow
/// mode hides for as many cycles whatever the displacements' size (`docs/dev/solver-correctness.md`).
const RELATIVE_CLAIM: f64 = 1e-3;
/// The finest tolerance a solve can claim, relative to its answer's largest displacement: about an `f32`'s resolution.
const FINEST_TOLERANCE: f64 = 1e-7;
/// The cycles a solve runs at most where `SolveOptions::max_cycles` does not say: well above what the slowest
/// families take, so that they converge and an animation's next frames start warm from them (a frame the cap
/// stopped makes the next start cold: `docs/dev/solver-correctness.md`, "The default cap").
pub(crate) const DEFAULT_MAX_CYCLES: usize = 300;
/// The largest banded factor's work (unknowns × bandwidth², multiply-adds) of a torn piece solved whole.
const DIRECT_WORK: usize = 1 << 25;
/// Smoothing steps before and after each coarse correction; below the finest level of an open grid one (across
/// holes and cuts one weakens the cycle too much: `docs/dev/ablation.md`, "Constants").
const SMOOTHING_STEPS: usize = 2;
const OPEN_COARSE_SMOOTHING: usize = 1;

/// What a hierarchy depends on (the operator: geometry, fixed nodes, tension; never the values) and its piece (its
/// box's first node `at`). Compared field by field in this order: the fixed nodes before the (larger) links.
#[derive(Clone, PartialEq)]
struct CacheKey { at: [usize; 2], w: usize, h: usize, tau_bits: u64, off: Ablation, fixed: Vec<bool>, links: BoxLinks }

/// The τ → 0⁺ rule's class of each piece of a grid `w` nodes wide, `members` its constraints; a one-line piece's
/// gauge is left to [`solve_constrained`]'s pass over the nodes.
fn classify(members: &[Vec<usize>], c: &Constraints, w: usize, tau: f64) -> Vec<Piece> {
    members.iter().map(|m| match m.len() {
        0 => Piece::Zero,
        // Equal values (a rest frame, a piece dragged whole): a translation has no energy.
        _ if m.iter().all(|&k| (0..2).all(|i| (c.values[k][i] - c.values[m[0]][i]).abs() <= 1e-9 * (1.0 + c.values[m[0]][i].abs()))) => Piece::Translate(c.values[m[0]]),
        _ if tau != 0.0 => Piece::General,
        _ => on_one_line(w, m.iter().map(|&k| c.nodes[k])).map_or(Piece::General, |(a, d)| Piece::Line { a, d, gauge: None }),
    }).collect()
}

/// The line `(a, d)` through every node of `nodes` (indices on a grid `w` wide, at least two distinct), if any.
fn on_one_line(w: usize, nodes: impl Iterator<Item = usize> + Clone) -> Option<([i64; 2], [i64; 2])> {
    let xy = |i: usize| [(i % w) as i64, (i / w) as i64];
    let a = xy(nodes.clone().next()?);
    let far = nodes.clone().map(xy).max_by_key(|p| (p[0] - a[0]).pow(2) + (p[1] - a[1]).pow(2))?;
    let d = [far[0] - a[0], far[1] - a[1]];
    nodes.map(xy).all(|p| cross(a, d, p) == 0).then_some((a, d))
}

/// The largest absolute component of a sequence of pairs (0 for none).
pub(crate) fn largest(values: impl Iterator<Item = V2>) -> f64 { values.fold(0.0, |s, v| s.max(v[0].abs()).max(v[1].abs())) }

/// `ℓ(p) = d × (p − a)`: zero on the line through `a` with direction `d`.
fn cross(a: [i64; 2], d: [i64; 2], p: [i64; 2]) -> i64 { d[0] * (p[1] - a[1]) - d[1] * (p[0] - a[0]) }

/// Adds `c·ℓ` to a one-line piece's values `u` on its box, `ℓ(p) = d × (p − a)`, with `c` minimising the
/// membrane energy: `c = −⟨u, ℓ⟩ / ⟨ℓ, ℓ⟩` over the piece's links (which stay in its box).
fn line_correction(grid: &Grid, labels: &[u32], piece: u32, a: [i64; 2], d: [i64; 2], [x0, y0, x1, y1]: [usize; 4], u: &mut BoxValues) {
    let (w, s, first) = (grid.width, u.stride, u.first);
    let at = |x: usize, y: usize| first + (y - y0) * s + x - x0;
    // The piece's nodes, in the grid's order.
    let nodes = || (y0..y1).flat_map(move |y| (x0..x1).map(move |x| (x, y))).filter(move |&(x, y)| labels[y * w + x] == piece);
    // ℓ(p + x̂) − ℓ(p) = −d_y, ℓ(p + ŷ) − ℓ(p) = d_x.
    let (lx, ly, v) = (-(d[1] as f64), d[0] as f64, &mut u.values);
    let (mut num, mut den) = ([0.0f64; 2], 0.0f64);
    for (x, y) in nodes() {
        let (i, j) = (y * w + x, at(x, y));
        for (_, q, l) in [(grid.link_right[i], j + 1, lx), (grid.link_down[i], j + s, ly)].into_iter().filter(|t| t.0) {
            num = [num[0] + (v[q][0] - v[j][0]) * l, num[1] + (v[q][1] - v[j][1]) * l];
            den += l * l;
        }
    }
    if den == 0.0 { return; }
    let c = [-num[0] / den, -num[1] / den];
    for (x, y) in nodes() {
        let l = cross(a, d, [x as i64, y as i64]) as f64;
        v[at(x, y)][0] += c[0] * l;
        v[at(x, y)][1] += c[1] * l;
    }
}

/// The least-squares affine map `p ↦ a₀ + a₁ p.x + a₂ p.y` (each `aᵢ` a pair) taking each
/// pair's point to its value, by the normal equations; none where they are singular.
pub(crate) fn affine_least_squares(pairs: impl Iterator<Item = ([f64; 2], V2)>) -> Option<Vec<V2>> {
    let (mut m, mut rhs) = (vec![vec![0.0; 3]; 3], vec![[0.0; 2]; 3]);
    for (p, v) in pairs {
        let b = [1.0, p[0], p[1]];
        for r in 0..3 {
            m[r].iter_mut().zip(b).for_each(|(m, c)| *m += b[r] * c);
            rhs[r] = [rhs[r][0] + b[r] * v[0], rhs[r][1] + b[r] * v[1]];
        }
    }
    dense_solve(m, rhs)
}

/// Gaussian elimination with partial pivoting for two right-hand sides.
pub(crate) fn dense_solve(mut m: Vec<Vec<f64>>, mut rhs: Vec<V2>) -> Option<Vec<V2>> {
    let k = m.len();
    for col in 0..k {
        let piv = (col..k).max_by(|&p, &q| m[p][col].abs().total_cmp(&m[q][col].abs()))?;
        if m[piv][col].abs() < 1e-300 { return None; }
        m.swap(col, piv);
        rhs.swap(col, piv);
        for r in col + 1..k {
            let f = m[r][col] / m[col][col];
            if f != 0.0 {
                for c in col..k { m[r][c] -= f * m[col][c] }
                rhs[r] = [rhs[r][0] - f * rhs[col][0], rhs[r][1] - f * rhs[col][1]];
            }
        }
    }
    // Back substitution in place: the solution's rows below r are final in `rhs`.
    for r in (0..k).rev() {
        let mut s = rhs[r];
        for c in r + 1..k { s = [s[0] - m[r][c] * rhs[c][0], s[1] - m[r][c] * rhs[c][1]] }
        rhs[r] = [s[0] / m[r][r], s[1] / m[r][r]];
    }
    Some(rhs)
}

/// Vector chunk for parallel loops (large enough that small grids stay on one thread).
const CHUNK: usize = 16_384;

/// The energy-minimising step along `p` (`rz = rᵀz` of the preconditioned residual it came from): `q = −A p`,
/// `u += α p`, `r += α q`. Returns the largest `|α p|` and `α`; NaN, and no step, where `p` or `q` overflowed.
fn energy_step(hier: &Hierarchy, u: &mut [V2], r: &mut [V2], p: &[W2], q: &mut [V2], rz: [f64; 2]) -> (f64, [f64; 2]) {
    let pq = hier.levels[0].fine_residual_dot_narrow(p, q);
    if !pq.iter().chain(&rz).all(|v| v.is_finite()) { return (f64::NAN, [0.0; 2]); }
    let alpha = [0, 1].map(|k| if pq[k] < 0.0 { -rz[k] / pq[k] } else { 0.0 });
    let chunks = u.par_chunks_mut(CHUNK).zip(r.par_chunks_mut(CHUNK)).zip(p.par_chunks(CHUNK).zip(q.par_chunks(CHUNK)));
    let change = chunks.map(|((u, r), (p, q))| {
        let mut m = 0.0f64;
        for (((u, r), p), q) in u.iter_mut().zip(r.iter_mut()).zip(p).zip(q) {
            for k in 0..2 {
                let d = alpha[k] * p[k].get();
                u[k] += d;
                r[k] += alpha[k] * q[k];
                m = larger(m, d.abs());
            }
        }
        m
    });
    (change.reduce(|| 0.0, f64::max), alpha)
}

/// The τ → 0⁺ settling as a projection the iteration keeps to: `v − Z (ZᵀMZ)⁻¹ ZᵀM v`, a field minus its
/// least-membrane free function; with the start settled and every direction projected, every iterate is settled.
/// At τ > 0 it is the exact Galerkin correction on the free functions (`A Z = τ M Z`, so `(ZᵀAZ)⁻¹ ZᵀA =
/// (ZᵀMZ)⁻¹ ZᵀM`): deflated CG, which never meets their eigenvalues of order τ. At τ = 0 it moves nothing the plate
/// energy sees, and the iteration no longer drifts along them.
struct Settled<'m> {
    membrane: &'m nullspace::Membrane,
    /// The box nodes the free functions touch, and each one's place among them by padded node (`u32::MAX` off them).
    nodes: Vec<usize>,
    slot: Vec<u32>,
}

impl<'m> Settled<'m> {
    /// `None` where a block cannot be settled (a factor past `nullspace::MAX_BLOCK_ENTRIES`, or singular).
    fn new(membrane: &'m nullspace::Membrane, level: &Level) -> Option<Self> {
        if !membrane.settles_all() { return None; }
        let w = level.geo.w;
        let nodes = membrane.support(w * level.geo.h);
        let mut slot = vec![u32::MAX; level.len_padded()];
        nodes.iter().enumerate().for_each(|(k, &i)| slot[level.pidx(i % w, i / w)] = k as u32);
        Some(Settled { membrane, nodes, slot })
    }

    /// Settles `v` (padded, on `level`'s nodes), each entry summed in `f64` and rounded once.
    fn project<T: Real>(&self, level: &Level, v: &mut [[T; 2]]) {
        let w = level.geo.w;
        let at = |i: usize| level.pidx(i % w, i / w);
        let read = |i: usize| [v[at(i)][0].get(), v[at(i)][1].get()];
        let mut moved: Vec<V2> = self.nodes.iter().map(|&i| read(i)).collect();
        self.membrane.settle(read, |i, c| {
            let m = &mut moved[self.slot[at(i)] as usize];
            *m = [m[0] + c[0], m[1] + c[1]];
        });
        self.nodes.iter().zip(&moved).for_each(|(&i, m)| v[at(i)] = [T::of(m[0]), T::of(m[1])]);
    }
}

/// `Σ a_i z_i` per component, `z` the preconditioner's `f32` output; the chunks' sums added in order, whatever the threads.
fn dot_z(a: &[V2], z: &[W2]) -> [f64; 2] {
    let parts: Vec<[f64; 2]> =
        a.par_chunks(CHUNK).zip(z.par_chunks(CHUNK)).map(|(a, z)| level::pair_sums(a.as_flattened(), z.as_flattened(), |x: f64, y: WS| x * y.get())).collect();
    parts.iter().fold([0.0; 2], |s, t| [s[0] + t[0], s[1] + t[1]])
}

/// `p = z + β p`, `z` the preconditioner's `f32` output and `p` the `f32` direction, summed in `f64`, rounded once.
fn widen_into(p: &mut [W2], z: &[W2], b: [f64; 2]) {
    p.par_chunks_mut(CHUNK).zip(z.par_chunks(CHUNK)).for_each(|(p, z)| {
        p.iter_mut().zip(z).for_each(|(p, z)| *p = [WS::of(z[0].get() + b[0] * p[0].get()), WS::of(z[1].get() + b[1] * p[1].get())])
    });
}

/// Restarts the directions: `p = z`, `z` the preconditioned `r`, kept to (see [`keep_to`]); returns `rᵀz`.
fn fresh_direction(hier: &mut Hierarchy, r: &[V2], p: &mut [W2], settled: Option<&Settled>, slow: Option<&deflate::Deflation>) -> [f64; 2] {
    let z = hier.precondition(r);
    p.copy_from_slice(z);
    let rz = dot_z(r, z);
    keep_to(&hier.levels[0], p, settled, slow);
    rz
}

/// After a deflating correction of `u`: settles it again (`f32` rounding puts free functions back) and restarts the
/// directions; returns `rᵀz`.
fn restart_directions(hier: &mut Hierarchy, u: &mut [V2], r: &mut [V2], p: &mut [W2], settled: Option<&Settled>, slow: &mut deflate::Deflation) -> [f64; 2] {
    if let Some(s) = settled {
        s.project(&hier.levels[0], u);
        hier.levels[0].residual(u, None, r);
    }
    slow.beta(None);
    fresh_direction(hier, r, p, settled, Some(slow))
}

/// The next direction `p = z + βp`, kept to ([`keep_to`]), after a step of `alpha` along `p` (`along` the step's
/// `rᵀz` or `pᵀr`); returns the new `rᵀz` and `β`. Flexible (Polak–Ribière, for the preconditioner's line searches):
/// β = zᵀ(r − r_old)/(r_oldᵀz_old), r − r_old = α q. Deflated, the projected z̃ has r_oldᵀz̃_old = `along` and
/// z̃ᵀq = zᵀq (Wᵀq = −WᵀA p_old = 0; for the settling Zᵀq = −τ ZᵀM p_old = 0): the deflated iteration's own, as
/// its Lanczos matrix (`rate_floor`) assumes.
fn next_direction(hier: &mut Hierarchy, r: &[V2], q: &[V2], p: &mut [W2], (alpha, along): ([f64; 2], [f64; 2]), settled: Option<&Settled>, slow: Option<&deflate::Deflation>) -> ([f64; 2], [f64; 2]) {
    let z = hier.precondition(r);
    let (rz, zq) = (dot_z(r, z), dot_z(q, z));
    let beta = [0, 1].map(|k| if along[k] > 0.0 { ((alpha[k] * zq[k]) / along[k]).max(0.0) } else { 0.0 });
    widen_into(p, z, beta);
    keep_to(&hier.levels[0], p, settled, slow);
    (rz, beta)
}

/// Keeps the direction `p` `A`-orthogonal to the kept slow modes and to the settled answers (settled last: the
/// `f32` rounding would put free functions back in).
fn keep_to(level: &Level, p: &mut [W2], settled: Option<&Settled>, slow: Option<&deflate::Deflation>) {
    if let Some(d) = slow { d.project(p) }
    if let Some(s) = settled { s.project(level, p) }
}

#[cfg(test)]
mod tests;

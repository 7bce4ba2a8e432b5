//! Deflation of the slow modes the outer conjugate gradient reveals (near-rigid motions of weakly attached
//! parts, which the cycle misses). Past [`START`] cycles the search directions of each window of [`WINDOW`]
//! cycles are kept with their Gram matrices; at the window's end a Rayleigh–Ritz step over the window and the
//! kept vectors (a thick restart, as in eigCG) keeps the [`KEEP`] Ritz vectors of the smallest eigenvalues as
//! `W` ([`KEEP_SLOW`] from the third step). The iterate is corrected on `span W` (`u += W E⁻¹ Wᵀ r`,
//! `E = Wᵀ A W`) and later directions made `A`-orthogonal to `W` (deflated CG, Saad et al. 2000). It also gives
//! the stopping rule a rate floor and the last window's largest change and rate. Memory: at most
//! `2·WINDOW + 2·KEEP_SLOW` `f32` vectors within [`BUDGET_BYTES`].

use rayon::prelude::*;

use super::level::{dot, Level, Real, V2, W2, WS};

/// Cycles before directions are kept (solves that end by then pay nothing). An `early` solve (a warm start on
/// a torn piece new to its hierarchy, or not from earlier answers on one an earlier solve probed: often all slow
/// modes) keeps them from its first cycle and, past it, stops only after its first look at them.
const START: usize = 10;
/// Cycles per window.
pub(crate) const WINDOW: usize = 4;
/// Rayleigh–Ritz steps a torn piece's slow solve waits for before it may stop where its rate floor exceeds
/// [`WAIT_RATE`] (an `early` one waits for one always).
const LOOKS: usize = 2;
const WAIT_RATE: f64 = 0.5;
/// The smallest Ritz value has settled when a cycle lowers it by less than 5 % (only before a deflating restart).
const SETTLED: f64 = 0.95;
/// Ritz vectors kept, and from the third Rayleigh–Ritz step on.
pub(crate) const KEEP: usize = 8;
const KEEP_SLOW: usize = 16;
/// Vectors a hierarchy keeps for later solves' checks.
pub(crate) const CHECKED: usize = 4;
/// Most bytes the kept vectors may take.
pub(crate) const BUDGET_BYTES: usize = 256 << 20;
/// Rayleigh quotients below this fraction of the largest diagonal entry are `f32` rounding ([`Modes::with`]).
const NULL_FLOOR: f64 = 1e-12;
/// Node chunk for the fused passes.
const CHUNK: usize = 4096;

/// Slow modes a probe or this solve's deflation found: the vectors `W`, their products and `Wᵀ A W`.
#[derive(Debug)]
pub(crate) struct Modes(Vec<Vec<f32>>, Vec<Vec<f32>>, Vec<Vec<f64>>);

#[derive(Debug, Default)]
pub(super) struct Deflation {
    on: bool,
    /// Stops wait for looks at the kept directions ([`Deflation::rate_floor`]), from the first cycle if `early`.
    wait: bool,
    early: bool,
    /// Ritz vectors the budget leaves room for.
    room: usize,
    /// The window's directions, one scalar vector per component and cycle.
    v: Vec<Vec<f32>>,
    /// The kept vectors and their products.
    w: Vec<Vec<f32>>,
    aw: Vec<Vec<f32>>,
    /// `Wᵀ A W`.
    e: Vec<Vec<f64>>,
    /// `Bᵀ A B` and `Bᵀ B` over the basis `B = [W, V]`.
    g: Vec<Vec<f64>>,
    m: Vec<Vec<f64>>,
    pub(super) restarts: usize,
    /// The conjugate gradient's step lengths and β per component since its last restart: its Lanczos matrix.
    steps: [Vec<(f64, f64)>; 2],
    /// The extreme Ritz values of the preconditioned operator seen in this solve.
    low: f64,
    high: f64,
    /// The smallest of the sequence before the last deflating restart.
    before: f64,
    /// The last changes (largest move of a node per cycle).
    changes: Vec<f64>,
}

/// How many vectors (each with its product, in `f32`) the budget holds on `len` nodes beside a window.
pub(crate) fn room(len: usize) -> usize { (BUDGET_BYTES / (4 * len).max(1)).saturating_sub(2 * WINDOW) / 2 }

impl Deflation {
    pub fn new(len: usize, off: bool, wait: bool, early: bool) -> Deflation {
        let room = room(len);
        Deflation { on: !off && room >= 4, wait, early: early && wait, room, low: f64::INFINITY, before: f64::INFINITY, ..Default::default() }
    }

    /// Whether vectors may be kept (not switched off, and the budget leaves room).
    pub fn on(&self) -> bool { self.on }

    /// Whether [`Deflation::project`] changes directions (vectors are kept).
    pub fn projects(&self) -> bool { !self.w.is_empty() }

    /// Makes the search direction `p` `A`-orthogonal to the kept vectors.
    pub fn project(&self, p: &mut [W2]) {
        if self.w.is_empty() { return; }
        let rhs = dots(&self.aw, p.len(), |i| [p[i][0].get(), p[i][1].get()]);
        let Some(mu) = super::dense_solve(self.e.clone(), rhs) else { return };
        p.par_chunks_mut(CHUNK).enumerate().for_each(|(c, p)| {
            let d = combination(&self.w, &mu, c * CHUNK, p.len());
            for (x, d) in p.iter_mut().zip(d).filter(|(_, d)| d[0] != 0.0 || d[1] != 0.0) {
                *x = [WS::of(x[0].get() - d[0]), WS::of(x[1].get() - d[1])];
            }
        });
    }

    /// Keeps the direction `p` of cycle `cycle` (`q = −A p`); true when [`Deflation::restart`] is due.
    pub fn record(&mut self, cycle: usize, p: &[W2], q: &[V2]) -> bool {
        if !self.on || cycle < if self.early { 1 } else { START } { return false; }
        let n = p.len();
        let nb = self.w.len() + self.v.len();
        let sums = chunked_sums(n, 4 * nb + 6, |a, b, out| {
            // The pair's rows −q₀, −q₁ (A x), x₀, x₁ against the basis, then among themselves.
            let rows: [Vec<f64>; 4] = std::array::from_fn(|t| (a..b).map(|i| if t < 2 { -q[i][t] } else { p[i][t - 2].get() }).collect());
            for (j, bv) in self.w.iter().chain(&self.v).enumerate() {
                (0..4).for_each(|t| out[4 * j + t] += dot(&rows[t], &bv[a..b]));
            }
            for (k, (s, t)) in [(0, 2), (1, 3), (0, 3), (2, 2), (3, 3), (2, 3)].into_iter().enumerate() {
                out[4 * nb + k] += dot(&rows[s], &rows[t]);
            }
        });
        if sums.iter().any(|s| !s.is_finite()) {
            self.on = false;
            return false;
        }
        let o = 4 * nb;
        // New rows and columns of G (t = 0, 1) and M (t = 2, 3) for the pair.
        let col = |t: usize, diag: [f64; 2]| -> Vec<f64> { (0..nb).map(|j| sums[4 * j + t]).chain(diag).collect() };
        let (g0, g1) = (col(0, [sums[o], sums[o + 2]]), col(1, [sums[o + 2], sums[o + 1]]));
        let (m0, m1) = (col(2, [sums[o + 3], sums[o + 5]]), col(3, [sums[o + 5], sums[o + 4]]));
        for j in 0..nb {
            self.g[j].extend([g0[j], g1[j]]);
            self.m[j].extend([m0[j], m1[j]]);
        }
        self.g.extend([g0, g1]);
        self.m.extend([m0, m1]);
        self.v.extend([0, 1].map(|c| p.par_iter().map(|x| x[c]).collect()));
        self.v.len() >= 2 * WINDOW
    }

    /// Rayleigh–Ritz over the kept vectors and the window: keeps the Ritz vectors of the smallest Ritz
    /// values, and corrects `u` and its residual `r` on their span.
    pub fn restart(&mut self, fine: &Level, u: &mut [V2], r: &mut [V2]) {
        let Some((theta, y)) = ritz(&self.g, &self.m) else { return self.clear() };
        self.restarts += 1;
        self.before = std::mem::replace(&mut self.low, f64::INFINITY);
        let k = (if self.restarts > LOOKS { KEEP_SLOW } else { KEEP }).min(self.room).min(theta.len());
        let n = u.len();
        // W = B Y, column by column, chunk by chunk in parallel; then the old vectors go (the budget).
        self.aw.clear();
        let mut w: Vec<Vec<f32>> = (0..k).map(|_| vec![0.0; n]).collect();
        for (l, col) in w.iter_mut().enumerate() {
            col.par_chunks_mut(CHUNK).enumerate().for_each(|(c, col)| {
                let mut acc = vec![0.0f64; col.len()];
                for (b, yj) in self.w.iter().chain(&self.v).zip(&y).filter(|(_, yj)| yj[l] != 0.0) {
                    acc.iter_mut().zip(&b[c * CHUNK..]).for_each(|(o, &bv)| *o += yj[l] * bv as f64);
                }
                col.iter_mut().zip(&acc).for_each(|(o, &x)| *o = x as f32);
            });
        }
        (self.w, self.v) = (Vec::new(), Vec::new());
        self.adopt(fine, Modes::of(fine, w), u, r);
    }

    /// Keeps `modes` (the Ritz vectors, or a probe's) as the vectors, a new basis (`Bᵀ B = I`,
    /// `Bᵀ A B = E`, no window), as many as the budget allows; corrects `u` and `r` on them.
    pub fn adopt(&mut self, fine: &Level, modes: Modes, u: &mut [V2], r: &mut [V2]) {
        if !self.on || modes.0[0].len() != u.len() { return; }
        let Modes(w, aw, e) = modes.first(self.room);
        self.m = (0..e.len()).map(|l| (0..e.len()).map(|j| if l == j { 1.0 } else { 0.0 }).collect()).collect();
        (self.w, self.aw, self.g, self.e) = (w, aw, e.clone(), e);
        self.v.clear();
        if !self.correct(fine, u, r) { self.clear() }
    }

    /// `u += W c` with `c = E⁻¹ Wᵀ r`, and `r` the residual of the corrected `u`, computed anew; false when `E`
    /// is singular. (Not `r −= A W c`: `A W` is kept in `f32`, whose rounding is far above the slow modes'
    /// eigenvalues, and the updated residual then parted from the true one, so that the iteration converged to a
    /// wrong answer and claimed it: 0.075 px off on a warm start among random cuts.)
    pub fn correct(&self, fine: &Level, u: &mut [V2], r: &mut [V2]) -> bool {
        if self.w.is_empty() { return true; }
        let Some(c) = coefficients(&self.w, &self.e, r) else { return false };
        u.par_chunks_mut(CHUNK).enumerate().for_each(|(ch, u)| {
            let d = combination(&self.w, &c, ch * CHUNK, u.len());
            for (u, d) in u.iter_mut().zip(d) {
                *u = [u[0] + d[0], u[1] + d[1]];
            }
        });
        fine.residual(u, None, r);
        true
    }

    /// The [`CHECKED`] slowest kept vectors and their `E`, for later solves' checks ([`Modes::largest_move`]).
    pub fn modes(&self) -> Option<Modes> { (!self.w.is_empty()).then(|| Modes(self.w[..self.w.len().min(CHECKED)].to_vec(), Vec::new(), self.e.clone()).first(CHECKED)) }

    /// The change the stopping rule is to judge and its rate a cycle: once deflated (changes in bursts), the
    /// last window's largest and the rate from the window before (a sliding maximum's ratios stay 1); else none.
    pub fn judged(&mut self, change: f64) -> (f64, Option<f64>) {
        if self.restarts == 0 { return (change, None); }
        self.changes.push(change);
        if self.changes.len() > 2 * WINDOW { self.changes.remove(0); }
        let (older, last) = self.changes.split_at(self.changes.len().saturating_sub(WINDOW));
        let [older, last] = [older, last].map(|c| c.iter().fold(0.0, |a: f64, &b| a.max(b)));
        (last, (self.changes.len() == 2 * WINDOW && older > 0.0).then(|| (last / older).powf(1.0 / WINDOW as f64)))
    }

    /// A step of length `alpha` taken (per component).
    pub fn step(&mut self, alpha: [f64; 2]) {
        for (c, &a) in alpha.iter().enumerate() {
            if a > 0.0 && a.is_finite() { self.steps[c].push((a, 0.0)) } else { self.steps[c].clear() }
        }
    }

    /// The next direction's `β` (per component); `None` when the directions restart.
    pub fn beta(&mut self, beta: Option<[f64; 2]>) {
        for c in 0..2 {
            match (beta, self.steps[c].last_mut()) {
                (Some(b), Some(last)) if b[c] > 0.0 => last.1 = b[c],
                _ => self.steps[c].clear(),
            }
        }
    }

    /// The least ratio of successive changes the stopping rule may assume, CG's rate `(√κ − 1)/(√κ + 1)` from
    /// the extreme Ritz values of its Lanczos matrix (since the deflating restart before the last), and whether
    /// the smallest has [`SETTLED`]. On a torn piece (`wait`) with a rate over [`WAIT_RATE`], a solve keeping
    /// directions gets 1 (no stop) until their [`LOOKS`]th Rayleigh–Ritz step: a nearly rigid part bounded by
    /// cuts can stall the changes while its error stays, and the Krylov space may reach it only later.
    pub fn rate_floor(&mut self) -> (f64, bool) {
        let (was, mut seen) = (self.low, false);
        for st in self.steps.iter().filter(|st| st.len() >= 2) {
            // T_jj = 1/α_j + β_{j−1}/α_{j−1}, T_{j−1,j} = √β_{j−1}/α_{j−1}.
            let n = st.len();
            let diag: Vec<f64> = (0..n).map(|j| 1.0 / st[j].0 + if j > 0 { st[j - 1].1 / st[j - 1].0 } else { 0.0 }).collect();
            let off: Vec<f64> = (1..n).map(|j| st[j - 1].1.sqrt() / st[j - 1].0).collect();
            if let Some((lo, hi)) = extremes(&diag, &off) {
                (self.low, self.high, seen) = (self.low.min(lo), self.high.max(hi), true);
            }
        }
        let settled = seen && self.restarts == 0 && self.low >= SETTLED * was;
        let low = self.low.min(self.before);
        let rate = if low > 0.0 && self.high > low { let k = (self.high / low).sqrt(); (k - 1.0) / (k + 1.0) } else { 0.0 };
        if self.wait && self.on && (self.early || rate > WAIT_RATE) && self.restarts < if self.early { 1 } else { LOOKS } && (self.restarts > 0 || !self.v.is_empty()) { return (1.0, false); }
        (rate, settled)
    }

    fn clear(&mut self) {
        [&mut self.v, &mut self.w, &mut self.aw].into_iter().for_each(Vec::clear);
        [&mut self.e, &mut self.g, &mut self.m].into_iter().for_each(Vec::clear);
    }
}

impl Modes {
    /// The modes spanned by `w` (orthonormal), with their products by `fine`'s operator.
    pub fn of(fine: &Level, w: Vec<Vec<f32>>) -> Modes {
        let (k, n) = (w.len(), w[0].len());
        // A W by the operator itself, two at a time (combining the window's products would cancel below `f32`).
        let mut aw: Vec<Vec<f32>> = Vec::with_capacity(k);
        let mut x: Vec<W2> = vec![[WS::of(0.0); 2]; n];
        let mut q: Vec<V2> = vec![[0.0; 2]; n];
        fine.clear_padding(&mut q);
        for pair in (0..k).step_by(2) {
            let other = (pair + 1).min(k - 1);
            x.par_iter_mut().zip(&w[pair][..]).zip(&w[other][..]).for_each(|((xi, &a), &b)| *xi = [a, b]);
            fine.fine_residual_dot_narrow(&x, &mut q);
            aw.extend((0..=other - pair).map(|t| q.par_iter().map(|v| -v[t] as f32).collect()));
        }
        // E = Wᵀ A W (upper triangle, mirrored), summed: a near-null vector's Rayleigh quotient is below `f32`'s
        // rounding of W. Wᵀ W is the identity up to that rounding.
        let sums = chunked_sums(n, k * k, |a, b, out| {
            for (l, j) in (0..k).flat_map(|l| (l..k).map(move |j| (l, j))) {
                out[l * k + j] += dot(&w[l][a..b], &aw[j][a..b]);
            }
        });
        let e = (0..k).map(|l| (0..k).map(|j| sums[l.min(j) * k + l.max(j)]).collect()).collect();
        Modes(w, aw, e)
    }

    /// The Ritz vectors of `A` over `vectors`, smallest first, less those below [`NULL_FLOOR`] of its largest
    /// diagonal entry or a hundredth of the box's smoothest plate mode (free functions: rounding by rounding).
    pub fn with(vectors: Vec<Vec<f64>>, fine: &Level) -> Option<Modes> {
        let unit = |v: Vec<f64>| { let n = v.iter().map(|x| x * x).sum::<f64>().sqrt(); v.into_iter().map(move |x| (x / n) as f32).collect() };
        let w: Vec<Vec<f32>> = vectors.into_iter().map(unit).filter(|v: &Vec<f32>| v.iter().all(|x| x.is_finite())).collect();
        let (k, n) = (w.len(), w.first()?.len());
        let sums = chunked_sums(n, k * k, |a, b, out| (0..k * k).for_each(|t| out[t] += dot(&w[t / k][a..b], &w[t % k][a..b])));
        let (theta, y) = ritz(&Modes::of(fine, w.clone()).2, &sums.chunks(k).map(<[f64]>::to_vec).collect::<Vec<_>>())?;
        let largest = fine.inv_diag.iter().filter(|&&d| d > 0.0).fold(0.0f64, |m, &d| m.max(1.0 / d));
        let floor = (NULL_FLOOR * largest).max(0.01 * (std::f64::consts::PI / fine.geo.w.max(fine.geo.h) as f64).powi(4));
        let w: Vec<Vec<f32>> = (0..theta.len()).filter(|&l| theta[l] > floor)
            .map(|l| (0..n).map(|i| w.iter().zip(&y).map(|(v, yj)| yj[l] * v[i] as f64).sum::<f64>() as f32).collect()).collect();
        (!w.is_empty()).then(|| Modes::of(fine, w))
    }

    /// The largest node move of the correction `W E⁻¹ Wᵀ r` on these modes (not made); infinite if `E` is singular.
    pub fn largest_move(&self, r: &[V2]) -> f64 {
        let Some(c) = coefficients(&self.0, &self.2, r) else { return f64::INFINITY };
        r.par_chunks(CHUNK).enumerate().map(|(ch, r)| {
            super::largest(combination(&self.0, &c, ch * CHUNK, r.len()).into_iter())
        }).reduce(|| 0.0, f64::max)
    }

    /// The first `k` modes.
    pub fn first(mut self, k: usize) -> Modes {
        [&mut self.0, &mut self.1].into_iter().for_each(|v| v.truncate(k));
        self.2.truncate(k);
        self.2.iter_mut().for_each(|r| r.truncate(k));
        self
    }
}

/// Sums of `len` nodes in chunks, each into its own `width` sums, added in order (independent of the threads).
fn chunked_sums(len: usize, width: usize, f: impl Fn(usize, usize, &mut [f64]) + Sync) -> Vec<f64> {
    let parts: Vec<Vec<f64>> = (0..len.div_ceil(CHUNK)).into_par_iter().map(|c| {
        let mut out = vec![0.0; width];
        f(c * CHUNK, ((c + 1) * CHUNK).min(len), &mut out);
        out
    }).collect();
    parts.iter().fold(vec![0.0; width], |mut s, p| {
        s.iter_mut().zip(p).for_each(|(s, p)| *s += p);
        s
    })
}

/// `Σ_i x(i) v_l(i)` per component for each of `vs`, `len` nodes (in [`chunked_sums`]' order).
fn dots(vs: &[Vec<f32>], len: usize, x: impl Fn(usize) -> V2 + Sync) -> Vec<V2> {
    let s = chunked_sums(len, 2 * vs.len(), |a, b, out| {
        let rows: [Vec<f64>; 2] = std::array::from_fn(|t| (a..b).map(|i| x(i)[t]).collect());
        for (l, v) in vs.iter().enumerate() {
            (0..2).for_each(|t| out[2 * l + t] += dot(&rows[t], &v[a..b]));
        }
    });
    s.chunks_exact(2).map(|d| [d[0], d[1]]).collect()
}

/// `c = E⁻¹ Wᵀ r` for the vectors `w` with `E = Wᵀ A W`, if `E` is regular.
fn coefficients(w: &[Vec<f32>], e: &[Vec<f64>], r: &[V2]) -> Option<Vec<V2>> {
    super::dense_solve(e.to_vec(), dots(w, r.len(), |i| r[i])).filter(|c| c.iter().all(|v| v[0].is_finite() && v[1].is_finite()))
}

/// `Σ_l c_l v_l` per component on the `len` nodes from `a`, `l` ascending, vector by vector (it vectorises).
fn combination(vs: &[Vec<f32>], c: &[V2], a: usize, len: usize) -> Vec<V2> {
    vs.iter().zip(c).fold(vec![[0.0; 2]; len], |mut s, (v, c)| {
        s.iter_mut().zip(&v[a..a + len]).for_each(|(s, &x)| *s = [s[0] + c[0] * x as f64, s[1] + c[1] * x as f64]);
        s
    })
}

/// Ritz pairs of `G y = θ M y` (`M` the Gram matrix of a basis that may be dependent, whose dependent
/// vectors are dropped): ascending Ritz values and the `M`-orthonormal coefficient columns `y[j][l]`.
fn ritz(g: &[Vec<f64>], m: &[Vec<f64>]) -> Option<(Vec<f64>, Vec<Vec<f64>>)> {
    let n = g.len();
    let d: Vec<f64> = (0..n).map(|i| if m[i][i] > 0.0 { 1.0 / m[i][i].sqrt() } else { 0.0 }).collect();
    // Cholesky of the scaled M = L Lᵀ, dropping vectors whose part independent of the earlier ones is
    // below f32's resolution.
    let (mut keep, mut l): (Vec<usize>, Vec<Vec<f64>>) = (Vec::new(), Vec::new()); // rows of L over `keep`
    for i in (0..n).filter(|&i| d[i] != 0.0) {
        let mut row = forward(&l, &keep.iter().map(|&j| m[i][j] * d[i] * d[j]).collect::<Vec<_>>());
        let diag = 1.0 - row.iter().map(|x| x * x).sum::<f64>();
        if diag < 1e-6 { continue; }
        row.push(diag.sqrt());
        keep.push(i);
        l.push(row);
    }
    let k = keep.len();
    if k == 0 { return None; }
    // C = L⁻¹ G_s L⁻ᵀ, G_s the scaled G over the kept vectors.
    let gs: Vec<Vec<f64>> = keep.iter().map(|&i| keep.iter().map(|&j| 0.5 * (g[i][j] + g[j][i]) * d[i] * d[j]).collect()).collect();
    // X = L⁻¹ G_s (columns), then C = L⁻¹ Xᵀ.
    let x: Vec<Vec<f64>> = (0..k).map(|j| forward(&l, &(0..k).map(|i| gs[i][j]).collect::<Vec<_>>())).collect(); // x[j] = column j
    let c: Vec<Vec<f64>> = (0..k).map(|i| forward(&l, &(0..k).map(|j| x[j][i]).collect::<Vec<_>>())).collect();
    let c = (0..k).map(|i| (0..k).map(|j| if i == j { c[i][i] } else { 0.5 * (c[i][j] + c[j][i]) }).collect()).collect();
    let (theta, vecs) = jacobi_eigen(c)?;
    // y = D L⁻ᵀ v for each eigenvector v.
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &b| theta[a].total_cmp(&theta[b]));
    let mut y = vec![vec![0.0; k]; n];
    for (col, &e) in order.iter().enumerate() {
        // Back substitution: Lᵀ z = v.
        let mut z = vec![0.0; k];
        for i in (0..k).rev() {
            z[i] = (i + 1..k).fold(vecs[i][e], |s, j| s - l[j][i] * z[j]) / l[i][i];
        }
        for (a, &i) in keep.iter().enumerate() { y[i][col] = z[a] * d[i]; }
    }
    Some((order.iter().map(|&e| theta[e]).collect(), y))
}

/// `L⁻¹ b` for the lower triangular `L` of rows `l` (at least `b.len()` of them).
fn forward(l: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    let mut x = Vec::with_capacity(b.len() + 1);
    for (i, &bi) in b.iter().enumerate() {
        x.push((0..i).fold(bi, |s, j| s - l[i][j] * x[j]) / l[i][i]);
    }
    x
}

/// Eigenvalues and eigenvectors (columns) of a small symmetric matrix by cyclic Jacobi rotations.
fn jacobi_eigen(mut a: Vec<Vec<f64>>) -> Option<(Vec<f64>, Vec<Vec<f64>>)> {
    let n = a.len();
    let mut v: Vec<Vec<f64>> = (0..n).map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect()).collect();
    for _ in 0..100 {
        let off: f64 = (0..n).flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j))).map(|(i, j)| a[i][j] * a[i][j]).sum();
        let scale: f64 = (0..n).map(|i| a[i][i] * a[i][i]).sum::<f64>();
        if off <= 1e-30 * scale.max(1e-300) { break; }
        for p in 0..n {
            for q in p + 1..n {
                if a[p][q].abs() < 1e-300 { continue; }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let cs = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * cs;
                let rotate = |x: f64, y: f64| (cs * x - sn * y, sn * x + cs * y);
                // Columns p and q of A and of V, then rows p and q of A.
                for row in a.iter_mut().chain(v.iter_mut()) {
                    (row[p], row[q]) = rotate(row[p], row[q]);
                }
                for k in 0..n { (a[p][k], a[q][k]) = rotate(a[p][k], a[q][k]); }
            }
        }
    }
    let d: Vec<f64> = (0..n).map(|i| a[i][i]).collect();
    d.iter().all(|x| x.is_finite()).then_some((d, v))
}

/// The smallest and largest eigenvalues of the symmetric tridiagonal matrix (`diag`, `off`) by bisection.
fn extremes(diag: &[f64], off: &[f64]) -> Option<(f64, f64)> {
    let n = diag.len();
    // Gershgorin's bounds.
    let radius = |i: usize| if i > 0 { off[i - 1].abs() } else { 0.0 } + if i + 1 < n { off[i].abs() } else { 0.0 };
    let lo = (0..n).map(|i| diag[i] - radius(i)).fold(f64::INFINITY, f64::min);
    let hi = (0..n).map(|i| diag[i] + radius(i)).fold(f64::NEG_INFINITY, f64::max);
    if !(lo.is_finite() && hi.is_finite()) { return None; }
    let find = |k: usize| {
        let (mut a, mut b) = (lo, hi);
        for _ in 0..100 {
            let m = 0.5 * (a + b);
            (a, b) = if super::cycle::eigenvalues_below(diag, off, m) > k { (a, m) } else { (m, b) };
            if b - a <= 1e-12 * b.abs().max(1e-300) { break; }
        }
        0.5 * (a + b)
    };
    Some((find(0), find(n - 1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_deflated_solve_is_judged_by_its_windows_rate_not_a_sliding_maximums() {
        // Changes falling by half a cycle in bursts (every other one small): the judged change
        // is the window's largest, and its rate a cycle the window-to-window one, 0.5 (the
        // sliding maximum's own ratio would be 1 on most cycles, which never stops).
        let mut d = Deflation { restarts: 1, ..Default::default() };
        let changes: Vec<f64> = (0..12).map(|k| 0.5f64.powi(k) * if k % 2 == 0 { 1.0 } else { 0.01 }).collect();
        let judged: Vec<(f64, Option<f64>)> = changes.iter().map(|&c| d.judged(c)).collect();
        assert!(judged[..7].iter().all(|j| j.1.is_none()), "{judged:?}");
        for (k, &(change, rate)) in judged.iter().enumerate().skip(7) {
            let largest = changes[k + 1 - WINDOW..=k].iter().fold(0.0f64, |a, &b| a.max(b));
            assert_eq!(change, largest);
            assert!((rate.unwrap() - 0.5).abs() < 1e-12, "cycle {k}: {rate:?}");
        }
        assert_eq!(Deflation::default().judged(0.3), (0.3, None));
    }

    #[test]
    fn a_deflation_is_off_where_its_budget_holds_fewer_than_four_vectors() {
        assert!(Deflation::new(4_100_000, false, true, false).on());
        assert!(!Deflation::new(4_300_000, false, true, false).on());
    }
}

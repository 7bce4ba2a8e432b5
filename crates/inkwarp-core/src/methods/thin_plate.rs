//! `tps-exact`: the continuous thin-plate spline, fitted exactly and evaluated at every
//! node.

use rayon::prelude::*;

use super::linalg::solve_dense;
use super::{is_finite_point, merge_samples, MethodError, MethodReport};
use crate::field::Field;
use crate::geometry::{bounds, sub, Point, Sample};

/// How many samples `tps-exact` fits at most by default. The fit costs `O(n³)` and the
/// evaluation `O(n)` per pixel, so a 513 × 513 field from 1000 samples takes about a
/// second on two cores.
pub const DEFAULT_MAX_SAMPLES: usize = 1000;

/// The continuous thin-plate spline map of the plane, `p ↦ p + f(p)`, where each
/// component of `f` is
///
/// ```text
/// f(p) = a₀ + a₁·x + a₂·y + Σᵢ wᵢ U(|p − cᵢ|),   U(r) = r² log r,
/// ```
///
/// the interpolant of minimal bending energy through the fitted displacements (Duchon's
/// thin plate; the paper's `d² log d` basis). Because the affine part is fitted exactly,
/// displacements taken from any affine map reproduce that map everywhere.
///
/// Coordinates are centred and scaled to the unit box before fitting (the spline does
/// not change under that, only the conditioning of its linear system improves), and the
/// `(n + 3)`-square system is solved by LU with partial pivoting in f64.
///
/// Degenerate inputs are defined, not errors: no sample gives the zero map, one distinct
/// position a translation, and positions on one line an affine part that is linear along
/// the line and constant across it.
///
/// ```
/// use inkwarp_core::methods::ThinPlateMap;
/// // Three points moved by a rotation plus a shift: the map is that affine map.
/// let src = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [4.0, 7.0]];
/// let dst: Vec<_> = src.iter().map(|p| [5.0 - p[1], 2.0 + p[0]]).collect();
/// let map = ThinPlateMap::fit(&src, &dst).unwrap();
/// let q = map.apply([3.0, -8.0]);
/// assert!((q[0] - 13.0).abs() < 1e-9 && (q[1] - 5.0).abs() < 1e-9);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct ThinPlateMap {
    /// Normalisation: `q = (p − origin) / scale`.
    origin: Point,
    scale: f64,
    /// Kernel centres in normalised coordinates, structure of arrays for the evaluator.
    cx: Vec<f64>,
    cy: Vec<f64>,
    /// Kernel weights of the Δx and Δy components (for `φ(r²) = r² ln r²`, i.e. `2U`).
    wx: Vec<f64>,
    wy: Vec<f64>,
    /// Affine part per component: `[a₀, a₁, a₂]` in normalised coordinates.
    affine: [[f64; 3]; 2],
}

/// What [`ThinPlateMap::fit_samples`] did with its input.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FitInfo {
    /// Samples handed in.
    pub given: usize,
    /// Samples with a non-finite coordinate, skipped.
    pub dropped: usize,
    /// Distinct positions after merging coincident samples.
    pub distinct: usize,
    /// Positions fitted (after thinning to `max_samples`).
    pub used: usize,
}

impl ThinPlateMap {
    /// The map taking every `source_points[i]` exactly to `target_points[i]`.
    /// Source points given more than once are merged, their targets averaged.
    ///
    /// # Errors
    /// Different counts, a non-finite coordinate, or a singular system (points that
    /// nearly, but not exactly, coincide).
    pub fn fit(source_points: &[Point], target_points: &[Point]) -> Result<Self, MethodError> {
        let (source_count, target_count) = (source_points.len(), target_points.len());
        if source_count != target_count {
            return Err(MethodError::CountMismatch { source_count, target_count });
        }
        for (which, pts) in [("source", source_points), ("target", target_points)] {
            if let Some((index, p)) = pts.iter().enumerate().find(|(_, p)| !is_finite_point(**p)) {
                return Err(MethodError::NonFinite { which, index, x: p[0], y: p[1] });
            }
        }
        let pairs = source_points.iter().zip(target_points);
        let samples: Vec<Sample> = pairs.map(|(&s, &t)| Sample { rest: s, displacement: sub(t, s) }).collect();
        Ok(Self::fit_samples(&samples, usize::MAX)?.0)
    }

    /// The spline through `samples` (rest position ↦ displacement).
    ///
    /// The reduction, in this order, and deterministic (independent of the samples'
    /// order): samples with a non-finite coordinate are skipped; samples at the same rest
    /// position are merged and their displacements averaged; if more than `max_samples`
    /// positions remain, they are thinned by **farthest-point sampling**: starting from
    /// the position that sorts first (smallest x, then y), repeatedly keep the position
    /// farthest from all kept ones (ties to the earlier in that order). This keeps
    /// isolated samples (a lone point feature) and spreads the rest evenly along dense
    /// curves; the dropped samples are then only approximated.
    ///
    /// # Errors
    /// `max_samples == 0`, or a singular system.
    pub fn fit_samples(samples: &[Sample], max_samples: usize) -> Result<(Self, FitInfo), MethodError> {
        if max_samples == 0 {
            return Err(MethodError::ZeroMaxSamples);
        }
        let (merged, dropped) = merge_samples(samples);
        let distinct = merged.len();
        let kept = if distinct > max_samples { farthest_point_subset(&merged, max_samples) } else { merged };
        let info = FitInfo { given: samples.len(), dropped, distinct, used: kept.len() };
        Ok((Self::fit_distinct(&kept)?, info))
    }

    fn fit_distinct(samples: &[Sample]) -> Result<Self, MethodError> {
        let n = samples.len();
        if n == 0 {
            let (cx, cy, wx, wy) = (vec![], vec![], vec![], vec![]);
            return Ok(ThinPlateMap { origin: [0.0, 0.0], scale: 1.0, cx, cy, wx, wy, affine: [[0.0; 3]; 2] });
        }
        let (lo, hi) = bounds(samples.iter().map(|s| &s.rest));
        let origin = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        let half = ((hi[0] - lo[0]).max(hi[1] - lo[1])) / 2.0;
        let scale = if half > 0.0 { half } else { 1.0 };
        let q: Vec<[f64; 2]> = samples.iter().map(|s| [(s.rest[0] - origin[0]) / scale, (s.rest[1] - origin[1]) / scale]).collect();

        // The polynomial part spans what the points can pin: constants for one position,
        // constants and the coordinate along the line for collinear positions, the full
        // affine space otherwise. `basis` holds the linear functionals as (dx, dy).
        let basis = linear_basis(&q);
        let m = 1 + basis.len();
        let size = n + m;
        let mut a = vec![0.0; size * size];
        for i in 0..n {
            for j in i + 1..n {
                let r2 = sq(q[i][0] - q[j][0]) + sq(q[i][1] - q[j][1]);
                let v = phi(r2);
                a[i * size + j] = v;
                a[j * size + i] = v;
            }
            let poly = std::iter::once(1.0).chain(basis.iter().map(|b| b[0] * q[i][0] + b[1] * q[i][1]));
            for (k, v) in poly.enumerate() {
                a[i * size + n + k] = v;
                a[(n + k) * size + i] = v;
            }
        }
        let mut rhs: Vec<f64> = samples.iter().flat_map(|s| s.displacement).collect();
        rhs.resize(size * 2, 0.0);
        let x = solve_dense(a, size, rhs, 2)
            .map_err(|e| MethodError::Singular { points: n, row: e.row, pivot: e.pivot })?;
        let mut affine = [[0.0; 3]; 2];
        for c in 0..2 {
            affine[c][0] = x[n * 2 + c];
            for (k, b) in basis.iter().enumerate() {
                let coef = x[(n + 1 + k) * 2 + c];
                affine[c][1] += coef * b[0];
                affine[c][2] += coef * b[1];
            }
        }
        Ok(ThinPlateMap {
            origin,
            scale,
            cx: q.iter().map(|p| p[0]).collect(),
            cy: q.iter().map(|p| p[1]).collect(),
            wx: (0..n).map(|i| x[i * 2]).collect(),
            wy: (0..n).map(|i| x[i * 2 + 1]).collect(),
            affine,
        })
    }

    /// Number of kernel centres.
    pub fn len(&self) -> usize { self.cx.len() }

    /// Whether the map was fitted to no sample (it is then the identity).
    pub fn is_empty(&self) -> bool { self.cx.is_empty() }

    /// The displacement `f(p)` at `p`.
    pub fn displacement(&self, p: Point) -> Point {
        let [qx, qy] = self.normalised(p);
        let (mut kx, mut ky) = (0.0, 0.0);
        for i in 0..self.cx.len() {
            let u = phi(sq(qx - self.cx[i]) + sq(qy - self.cy[i]));
            kx += self.wx[i] * u;
            ky += self.wy[i] * u;
        }
        let [ax, ay] = self.affine;
        [ax[0] + ax[1] * qx + ax[2] * qy + kx, ay[0] + ay[1] * qx + ay[2] * qy + ky]
    }

    /// Where the map takes `p`: `p + f(p)`.
    pub fn apply(&self, p: Point) -> Point {
        let d = self.displacement(p);
        [p[0] + d[0], p[1] + d[1]]
    }

    /// The Jacobian of the map `p ↦ p + f(p)` at `p`, `[[∂x'/∂x, ∂x'/∂y], [∂y'/∂x, ∂y'/∂y]]`.
    /// Its determinant is negative where the map turns the plane over (a fold).
    pub fn jacobian(&self, p: Point) -> [[f64; 2]; 2] {
        let [qx, qy] = self.normalised(p);
        let [ax, ay] = self.affine;
        // d/dq of φ(r²) = r² ln r² is 2 (ln r² + 1) (q − c), which tends to 0 at r = 0.
        let mut g = [[ax[1], ax[2]], [ay[1], ay[2]]];
        for i in 0..self.cx.len() {
            let (ux, uy) = (qx - self.cx[i], qy - self.cy[i]);
            let r2 = ux * ux + uy * uy;
            if r2 > 0.0 {
                let k = 2.0 * (r2.ln() + 1.0);
                g[0][0] += self.wx[i] * k * ux;
                g[0][1] += self.wx[i] * k * uy;
                g[1][0] += self.wy[i] * k * ux;
                g[1][1] += self.wy[i] * k * uy;
            }
        }
        self.identity_plus(g)
    }

    /// The Jacobian of the map's affine part alone (the same everywhere).
    pub fn affine_jacobian(&self) -> [[f64; 2]; 2] {
        let [ax, ay] = self.affine;
        self.identity_plus([[ax[1], ax[2]], [ay[1], ay[2]]])
    }

    /// `p` in the normalised coordinates of the fit.
    fn normalised(&self, p: Point) -> Point { [(p[0] - self.origin[0]) / self.scale, (p[1] - self.origin[1]) / self.scale] }

    /// `I + g / scale`: a gradient in normalised coordinates as a Jacobian in pixels.
    fn identity_plus(&self, g: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
        let s = self.scale;
        [[1.0 + g[0][0] / s, g[0][1] / s], [g[1][0] / s, 1.0 + g[1][1] / s]]
    }

    /// The displacement at every pixel centre of a `width × height` image, rows in
    /// parallel. Within a row the loop runs over pixels for one centre at a time, so that
    /// it vectorises (the kernel uses [`ln_fast`], accurate to ~1e-15 relative).
    pub fn field(&self, width: usize, height: usize) -> Field {
        let mut f = Field::zeros(width, height);
        if width == 0 {
            return f;
        }
        let [ax, ay] = self.affine;
        let qx: Vec<f64> = (0..width).map(|x| (x as f64 - self.origin[0]) / self.scale).collect();
        f.dx.par_chunks_mut(width).zip(f.dy.par_chunks_mut(width)).enumerate().for_each(
            |(y, (row_x, row_y))| {
                if crate::interrupt::requested() {
                    return; // the caller checks the flag and discards the field
                }
                let qy = (y as f64 - self.origin[1]) / self.scale;
                let mut acc_x: Vec<f64> = qx.iter().map(|&q| ax[0] + ax[1] * q + ax[2] * qy).collect();
                let mut acc_y: Vec<f64> = qx.iter().map(|&q| ay[0] + ay[1] * q + ay[2] * qy).collect();
                for i in 0..self.cx.len() {
                    let (cx, wx, wy) = (self.cx[i], self.wx[i], self.wy[i]);
                    let dy2 = sq(qy - self.cy[i]);
                    for ((sx, sy), &q) in acc_x.iter_mut().zip(acc_y.iter_mut()).zip(&qx) {
                        let u = phi_fast(sq(q - cx) + dy2);
                        *sx += wx * u;
                        *sy += wy * u;
                    }
                }
                row_x.iter_mut().zip(&acc_x).for_each(|(r, &a)| *r = a as f32);
                row_y.iter_mut().zip(&acc_y).for_each(|(r, &a)| *r = a as f32);
            },
        );
        f
    }
}

/// `tps-exact` as a field, recording what was fitted in `report`.
pub fn thin_plate_field(
    samples: &[Sample],
    width: usize,
    height: usize,
    max_samples: usize,
    report: &mut MethodReport,
) -> Result<Field, MethodError> {
    let (map, info) = ThinPlateMap::fit_samples(samples, max_samples)?;
    report.samples_given = info.given;
    report.dropped = info.dropped;
    report.samples_used = info.used;
    if info.used < info.distinct {
        report.notes.push(format!("tps-exact thinned {} distinct sample positions to {} by farthest-point sampling (max_samples).", info.distinct, info.used));
    }
    Ok(map.field(width, height))
}

#[inline]
fn sq(v: f64) -> f64 { v * v }

/// The kernel as a function of the squared distance: `φ = r² ln r² = 2 r² ln r`
/// (the factor 2 is absorbed by the weights), `φ(0) = 0`.
#[inline]
fn phi(r2: f64) -> f64 { if r2 > 0.0 { r2 * r2.ln() } else { 0.0 } }

/// [`phi`] without a branch or a library call, for the vectorised evaluator.
#[inline(always)]
fn phi_fast(r2: f64) -> f64 {
    // r2 = 0 gives 0 · ln(MIN_POSITIVE) = 0, as it should.
    r2 * ln_fast(r2.max(f64::MIN_POSITIVE))
}

/// The natural logarithm of a positive normal `x`, branch-free so that loops over it
/// vectorise: `x = m·2ᵉ` with `m ∈ [√½, √2)`, and `ln m = 2 atanh(s)`, `s = (m−1)/(m+1)`,
/// by its series to `s¹⁷` (`|s| ≤ 0.1716`, so the relative error is about 1e-15).
#[inline(always)]
pub(crate) fn ln_fast(x: f64) -> f64 {
    const TWO52_PLUS_BIAS: f64 = 4_503_599_627_370_496.0 + 1023.0;
    let bits = x.to_bits();
    // The biased exponent as a float, by the 2⁵² trick (no int → float conversion).
    let mut e = f64::from_bits((bits >> 52) | 0x4330_0000_0000_0000) - TWO52_PLUS_BIAS;
    let mut m = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | 0x3FF0_0000_0000_0000);
    let big = m > std::f64::consts::SQRT_2;
    m = if big { m * 0.5 } else { m };
    e = if big { e + 1.0 } else { e };
    let s = (m - 1.0) / (m + 1.0);
    let z = s * s;
    let series = 1.0
        + z * (1.0 / 3.0
            + z * (1.0 / 5.0
                + z * (1.0 / 7.0
                    + z * (1.0 / 9.0
                        + z * (1.0 / 11.0 + z * (1.0 / 13.0 + z * (1.0 / 15.0 + z * (1.0 / 17.0))))))));
    e * std::f64::consts::LN_2 + 2.0 * s * series
}

/// The directions `(dx, dy)` of the linear part the positions `q` determine: none for
/// one position, the principal direction for collinear positions, both axes otherwise.
fn linear_basis(q: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let n = q.len() as f64;
    let mx = q.iter().map(|p| p[0]).sum::<f64>() / n;
    let my = q.iter().map(|p| p[1]).sum::<f64>() / n;
    let [sxx, sxy, syy] = q.iter().fold([0.0; 3], |[xx, xy, yy], p| {
        let (dx, dy) = (p[0] - mx, p[1] - my);
        [xx + dx * dx, xy + dx * dy, yy + dy * dy]
    });
    // Eigenvalues of the 2 × 2 scatter matrix.
    let tr = sxx + syy;
    let disc = (sq(sxx - syy) + 4.0 * sxy * sxy).sqrt();
    let (big, small) = ((tr + disc) / 2.0, (tr - disc) / 2.0);
    if big <= 1e-24 {
        vec![]
    } else if small <= 1e-12 * big {
        let (vx, vy) = if sxy.abs() > 0.0 {
            (big - syy, sxy)
        } else if sxx >= syy {
            (1.0, 0.0)
        } else {
            (0.0, 1.0)
        };
        let len = vx.hypot(vy);
        vec![[vx / len, vy / len]]
    } else {
        vec![[1.0, 0.0], [0.0, 1.0]]
    }
}

/// Farthest-point sampling of `count` of the (sorted, distinct) `samples`.
fn farthest_point_subset(samples: &[Sample], count: usize) -> Vec<Sample> {
    let d2 = |a: Point, b: Point| sq(a[0] - b[0]) + sq(a[1] - b[1]);
    let mut nearest = vec![f64::INFINITY; samples.len()];
    let mut chosen = Vec::with_capacity(count);
    let mut next = 0;
    for _ in 0..count {
        chosen.push(next);
        let c = samples[next].rest;
        let mut best = (0, -1.0);
        for (i, s) in samples.iter().enumerate() {
            nearest[i] = nearest[i].min(d2(s.rest, c));
            if nearest[i] > best.1 {
                best = (i, nearest[i]);
            }
        }
        next = best.0;
    }
    chosen.sort_unstable();
    chosen.into_iter().map(|i| samples[i]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn affine(p: Point) -> Point {
        [0.3 + 1.1 * p[0] - 0.4 * p[1], -7.0 + 0.2 * p[0] + 0.9 * p[1]]
    }

    fn pseudo_random_points(n: usize, seed: u64, extent: f64) -> Vec<Point> {
        let mut state = seed;
        let mut rnd = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n).map(|_| [rnd() * extent, rnd() * extent]).collect()
    }

    #[test]
    fn the_jacobian_is_the_derivative_of_the_map() {
        let src = pseudo_random_points(30, 3, 100.0);
        let dst: Vec<Point> =
            src.iter().enumerate().map(|(i, p)| [p[0] + (i as f64).cos() * 6.0, p[1] + (i % 5) as f64]).collect();
        let map = ThinPlateMap::fit(&src, &dst).unwrap();
        let h = 1e-4;
        for p in pseudo_random_points(20, 11, 100.0).into_iter().chain([src[4]]) {
            let j = map.jacobian(p);
            let (px, mx) = (map.apply([p[0] + h, p[1]]), map.apply([p[0] - h, p[1]]));
            let (py, my) = (map.apply([p[0], p[1] + h]), map.apply([p[0], p[1] - h]));
            let fd = [
                [(px[0] - mx[0]) / (2.0 * h), (py[0] - my[0]) / (2.0 * h)],
                [(px[1] - mx[1]) / (2.0 * h), (py[1] - my[1]) / (2.0 * h)],
            ];
            for r in 0..2 {
                for c in 0..2 {
                    assert!((j[r][c] - fd[r][c]).abs() < 1e-5, "{p:?}: {j:?} vs {fd:?}");
                }
            }
        }
        // An affine map's Jacobian is its linear part, everywhere.
        let a: Vec<Point> = src.iter().map(|&p| affine(p)).collect();
        let map = ThinPlateMap::fit(&src, &a).unwrap();
        for j in [map.jacobian([12.0, 80.0]), map.affine_jacobian()] {
            let want = [[1.1, -0.4], [0.2, 0.9]];
            assert!((0..4).all(|k| (j[k / 2][k % 2] - want[k / 2][k % 2]).abs() < 1e-9), "{j:?}");
        }
    }

    #[test]
    fn interpolates_its_samples() {
        let src = pseudo_random_points(60, 7, 100.0);
        let samples: Vec<Sample> = src
            .iter()
            .enumerate()
            .map(|(i, p)| Sample { rest: *p, displacement: [(i as f64).sin() * 5.0, (i % 7) as f64] })
            .collect();
        let (map, info) = ThinPlateMap::fit_samples(&samples, 1000).unwrap();
        assert_eq!(info.used, 60);
        for s in &samples {
            let d = map.displacement(s.rest);
            assert!((d[0] - s.displacement[0]).abs() < 1e-8 && (d[1] - s.displacement[1]).abs() < 1e-8);
        }
        // The rasterised field agrees with the point evaluator at nodes.
        let f = map.field(101, 101);
        let d = map.displacement([37.0, 64.0]);
        let g = f.at(37, 64);
        assert!((g[0] as f64 - d[0]).abs() < 1e-4 && (g[1] as f64 - d[1]).abs() < 1e-4);
    }

    #[test]
    fn reproduces_affine_maps_on_every_node() {
        let src = pseudo_random_points(25, 3, 64.0);
        let dst: Vec<Point> = src.iter().map(|&p| affine(p)).collect();
        let map = ThinPlateMap::fit(&src, &dst).unwrap();
        let f = map.field(64, 48);
        for y in 0..48 {
            for x in 0..64 {
                let want = affine([x as f64, y as f64]);
                let got = f.at(x, y);
                assert!((got[0] as f64 - (want[0] - x as f64)).abs() < 1e-4);
                assert!((got[1] as f64 - (want[1] - y as f64)).abs() < 1e-4);
            }
        }
        assert!(map.wx.iter().chain(&map.wy).all(|w| w.abs() < 1e-9), "no bending for an affine map");
    }

    #[test]
    fn degenerate_inputs_are_defined() {
        let none = ThinPlateMap::fit(&[], &[]).unwrap();
        assert_eq!(none.apply([3.0, 4.0]), [3.0, 4.0]);
        let one = ThinPlateMap::fit(&[[1.0, 1.0], [1.0, 1.0]], &[[2.0, 1.0], [4.0, 1.0]]).unwrap();
        assert_eq!(one.apply([50.0, -3.0]), [52.0, -3.0]);
        // Collinear: linear along the line, constant across it.
        let line = [[0.0, 0.0], [10.0, 10.0], [20.0, 20.0]];
        let moved: Vec<Point> = line.iter().map(|p| [p[0] + p[0] * 0.5, p[1] + p[1] * 0.5]).collect();
        let map = ThinPlateMap::fit(&line, &moved).unwrap();
        let d = map.displacement([5.0, 5.0]);
        assert!((d[0] - 2.5).abs() < 1e-9 && (d[1] - 2.5).abs() < 1e-9);
        let across = map.displacement([15.0, 5.0]);
        assert!((across[0] - 5.0).abs() < 1e-9, "constant across the line: {across:?}");
    }

    #[test]
    fn fit_errors_name_the_problem() {
        let err = ThinPlateMap::fit(&[[0.0, 0.0]], &[]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "The thin-plate map needs as many target points as source points: got 1 source and 0 target points."
        );
        let err = ThinPlateMap::fit(&[[0.0, 0.0], [1.0, f64::NAN]], &[[0.0, 0.0], [1.0, 1.0]]).unwrap_err();
        assert!(err.to_string().starts_with("Point 1 of the source points is not finite"));
    }

    #[test]
    fn thinning_is_deterministic_and_keeps_isolated_points() {
        // A dense line of 400 samples and one lone point far away.
        let mut samples: Vec<Sample> = (0..400)
            .map(|i| Sample { rest: [i as f64 * 0.5, 10.0], displacement: [0.0, 0.0] })
            .collect();
        samples.push(Sample { rest: [100.0, 150.0], displacement: [4.0, -2.0] });
        let (map, info) = ThinPlateMap::fit_samples(&samples, 50).unwrap();
        assert_eq!((info.distinct, info.used), (401, 50));
        let d = map.displacement([100.0, 150.0]);
        assert!((d[0] - 4.0).abs() < 1e-8 && (d[1] + 2.0).abs() < 1e-8);
        let mut reversed = samples.clone();
        reversed.reverse();
        let (again, _) = ThinPlateMap::fit_samples(&reversed, 50).unwrap();
        assert_eq!(map, again);
    }

    #[test]
    fn fast_log_matches_the_library_log() {
        let mut x = f64::MIN_POSITIVE;
        while x < 1e300 {
            for k in [1.0, 1.1, 1.3, 1.41, 1.42, 1.7, 1.99] {
                let v = x * k;
                let (got, want) = (ln_fast(v), v.ln());
                assert!((got - want).abs() <= 4e-15 * want.abs().max(1.0), "ln({v}) = {want}, got {got}");
            }
            x *= 7.3;
        }
        assert_eq!(phi_fast(0.0), 0.0);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn any_affine_map_is_reproduced(
            m in proptest::array::uniform6(-2.0f64..2.0),
            seed in 0u64..1000,
            n in 3usize..40,
        ) {
            let src = pseudo_random_points(n, seed, 200.0);
            let f = |p: Point| [m[0] * 10.0 + m[1] * p[0] + m[2] * p[1], m[3] * 10.0 + m[4] * p[0] + m[5] * p[1]];
            let dst: Vec<Point> = src.iter().map(|&p| f(p)).collect();
            let map = ThinPlateMap::fit(&src, &dst).unwrap();
            for probe in [[0.0, 0.0], [123.0, 45.0], [-50.0, 300.0]] {
                let got = map.apply(probe);
                let want = f(probe);
                prop_assert!((got[0] - want[0]).abs() < 1e-6 && (got[1] - want[1]).abs() < 1e-6,
                    "{got:?} vs {want:?}");
            }
        }
    }
}

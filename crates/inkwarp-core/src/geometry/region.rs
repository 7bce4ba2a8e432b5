//! Regions: the grid nodes strictly inside an outline, and the mean-value-coordinate
//! interpolation of the outline's displacements at them.
//!
//! Mean value coordinates (Floater 2003) in the form of Hormann & Floater, "Mean value
//! coordinates for arbitrary planar polygons" (2006): for a point `x` not on a closed
//! polygon `v_0 … v_{m−1}` with values `f_i`,
//!
//! ```text
//! w_i = (tan(α_{i−1}/2) + tan(α_i/2)) / |v_i − x|,     f(x) = Σ w_i f_i / Σ w_i,
//! ```
//!
//! where `α_i` is the signed angle at `x` from `v_i` to `v_{i+1}`. It interpolates the
//! outline, reproduces every affine function exactly, is defined for non-convex (and
//! self-intersecting) outlines, and is unchanged when an edge is split at a point whose
//! value is linear along that edge.

use rayon::prelude::*;

use super::curve::{norm, sub};
use super::Point;
use crate::grid::Grid;

/// Distance, in pixels, under which a point counts as lying on the outline.
const ON_OUTLINE_PX: f64 = 1e-9;

/// The mean-value interpolation at `x` of `values` given at the vertices of the closed
/// polygon `polygon` (the last vertex joins the first): a [`MeanValueInterpolator`] for
/// one point.
///
/// On the polygon it returns the outline's own value: a vertex's value, or on an edge the
/// linear interpolation between its ends. Away from it the weights are computed with
/// half-angle formulas that stay accurate for points very close to an edge or on the line
/// through one. The result is undefined (NaN or ±∞) only where the weights sum to zero,
/// which cannot happen for points inside a simple polygon.
///
/// ```
/// use inkwarp_core::geometry::mean_value_interpolate;
/// let square = [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]];
/// // values of the affine map f(x, y) = (x + 2y, 3 − y) at the corners
/// let values: Vec<[f64; 2]> = square.iter().map(|p| [p[0] + 2.0 * p[1], 3.0 - p[1]]).collect();
/// let f = mean_value_interpolate(&square, &values, [1.0, 3.0]);
/// assert!((f[0] - 7.0).abs() < 1e-12 && (f[1] - 0.0).abs() < 1e-12);
/// ```
///
/// # Panics
/// If `polygon` and `values` have different lengths.
pub fn mean_value_interpolate(polygon: &[Point], values: &[Point], x: Point) -> Point {
    let mvc = MeanValueInterpolator::new(polygon.to_vec(), values.to_vec());
    mvc.value_at(x, &mut MvcScratch::default()).unwrap_or_else(|| mvc.outline_value(x))
}

/// Mean-value interpolation of one outline's values at many points.
///
/// The direct sum over every edge, laid out for speed (coordinates relative to the point
/// in structure-of-arrays form, branch-free half-angle tangents that the compiler can
/// vectorise): `O(m)` per point for an outline of `m` vertices. Points on or within
/// 1e-9 px of the outline have no value here; [`mean_value_interpolate`] gives them the
/// outline's own.
#[derive(Clone, Debug)]
pub struct MeanValueInterpolator {
    /// Vertex coordinates, with the first vertex repeated at the end.
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// Edge lengths `|v[i+1] − v[i]|`.
    lengths: Vec<f64>,
    vertices: Vec<Point>,
    values: Vec<Point>,
}

/// Per-thread scratch space of [`MeanValueInterpolator`].
#[derive(Clone, Debug, Default)]
pub struct MvcScratch {
    sx: Vec<f64>,
    sy: Vec<f64>,
    r: Vec<f64>,
    t: Vec<f64>,
}

impl MeanValueInterpolator {
    /// Prepares the interpolation of `values` given at the vertices of the closed polygon
    /// `vertices`.
    ///
    /// # Panics
    /// If the two have different lengths.
    pub fn new(vertices: Vec<Point>, values: Vec<Point>) -> Self {
        assert_eq!(vertices.len(), values.len(), "one value per polygon vertex");
        let m = vertices.len();
        let closed = || vertices.iter().chain(vertices.first());
        let (xs, ys) = (closed().map(|v| v[0]).collect(), closed().map(|v| v[1]).collect());
        let lengths = (0..m).map(|i| norm(sub(vertices[(i + 1) % m], vertices[i]))).collect();
        MeanValueInterpolator { xs, ys, lengths, vertices, values }
    }

    pub fn len(&self) -> usize { self.vertices.len() }

    pub fn is_empty(&self) -> bool { self.vertices.is_empty() }

    #[cfg(test)]
    /// The normalised mean value coordinates of `x` (one weight per vertex, summing to 1)
    /// written into `weights`, or `false` when `x` lies on the outline (within 1e-9 px) or
    /// the outline is empty.
    ///
    /// # Panics
    /// If `weights.len() != self.len()`.
    pub fn weights_at(&self, x: Point, scratch: &mut MvcScratch, weights: &mut [f64]) -> bool {
        match self.unnormalized_weights_at(x, scratch, weights) {
            Some(sum) => {
                let inv = 1.0 / sum;
                weights.iter_mut().for_each(|w| *w *= inv);
                true
            }
            None => false,
        }
    }

    /// The mean value weights of `x` before normalisation, and their sum.
    pub(crate) fn unnormalized_weights_at(&self, x: Point, scratch: &mut MvcScratch, weights: &mut [f64]) -> Option<f64> {
        let m = self.len();
        assert_eq!(weights.len(), m, "one weight per vertex");
        if m == 0 || !self.tangents(x, scratch) {
            return None;
        }
        let (r, t) = (&scratch.r[..m], &scratch.t[..m]);
        let weights = &mut weights[..m];
        weights[0] = (t[m - 1] + t[0]) / r[0];
        for i in 1..m {
            weights[i] = (t[i - 1] + t[i]) / r[i];
        }
        Some(weights.iter().sum())
    }

    /// The outline's own value at `x`, a point on it (where [`MeanValueInterpolator::value_at`]
    /// gives `None`): the value of the first vertex within 1e-9 px, or the linear
    /// interpolation along the first edge `x` lies on (by the test of `tangents`).
    fn outline_value(&self, x: Point) -> Point {
        let m = self.len();
        for a in 0..m {
            let (fa, fb) = (self.values[a], self.values[(a + 1) % m]);
            let (sa, sb) = (sub(self.vertices[a], x), sub(self.vertices[(a + 1) % m], x));
            let (ra, rb) = (norm(sa), norm(sb));
            if ra <= ON_OUTLINE_PX {
                return fa;
            }
            let det = sa[0] * sb[1] - sa[1] * sb[0];
            let dot = sa[0] * sb[0] + sa[1] * sb[1];
            if dot < 0.0 && det.abs() <= ON_OUTLINE_PX * self.lengths[a] + 4.0 * f64::EPSILON * ra * rb {
                let s = ra / (ra + rb);
                return [fa[0] + s * (fb[0] - fa[0]), fa[1] + s * (fb[1] - fa[1])];
            }
        }
        [f64::NAN; 2]
    }

    /// The interpolated value at `x`, or `None` when `x` lies on the outline (within
    /// 1e-9 px) or the outline is empty.
    pub fn value_at(&self, x: Point, scratch: &mut MvcScratch) -> Option<Point> {
        let m = self.len();
        if m == 0 || !self.tangents(x, scratch) {
            return None;
        }
        let (r, t) = (&scratch.r[..m], &scratch.t[..m]);
        let values = &self.values[..m];
        let w0 = (t[m - 1] + t[0]) / r[0];
        let (mut nx, mut ny, mut den) = (w0 * values[0][0], w0 * values[0][1], w0);
        for i in 1..m {
            let w = (t[i - 1] + t[i]) / r[i];
            nx += w * values[i][0];
            ny += w * values[i][1];
            den += w;
        }
        Some([nx / den, ny / den])
    }

    /// Fills `scratch.r` (distances to the vertices) and `scratch.t` (`tan(α_i/2)` of each
    /// edge); `false` when `x` lies on the outline.
    fn tangents(&self, x: Point, scratch: &mut MvcScratch) -> bool {
        let m = self.len();
        let MvcScratch { sx, sy, r, t } = scratch;
        sx.clear();
        sy.clear();
        r.clear();
        t.clear();
        sx.extend(self.xs.iter().map(|&v| v - x[0]));
        sy.extend(self.ys.iter().map(|&v| v - x[1]));
        r.extend(sx.iter().zip(sy.iter()).map(|(&a, &b)| (a * a + b * b).sqrt()));
        let (sx0, sx1) = (&sx[..m], &sx[1..=m]);
        let (sy0, sy1) = (&sy[..m], &sy[1..=m]);
        let (r0, r1) = (&r[..m], &r[1..=m]);
        let lengths = &self.lengths[..m];
        t.resize(m, 0.0);
        let mut on_outline = false;
        for i in 0..m {
            let det = sx0[i] * sy1[i] - sy0[i] * sx1[i];
            let dot = sx0[i] * sx1[i] + sy0[i] * sy1[i];
            let rr = r0[i] * r1[i];
            // tan(α/2) without cancellation: sin α / (1 + cos α) for acute angles,
            // (1 − cos α) / sin α for obtuse ones
            let acute = dot >= 0.0;
            let num = if acute { det } else { rr - dot };
            let den = if acute { rr + dot } else { det };
            // (bitwise, not short-circuit, so that the loop stays branch-free)
            on_outline |= (r0[i] <= ON_OUTLINE_PX)
                | (!acute & (det.abs() <= ON_OUTLINE_PX * lengths[i] + 4.0 * f64::EPSILON * rr));
            t[i] = num / den;
        }
        !on_outline
    }
}

/// The active nodes of `grid` strictly inside the closed polygon (non-zero winding rule),
/// row by row, left to right, by scanlines through the node rows. A node that lies on a
/// slanted edge may still be listed when rounding puts it a hair inside;
/// [`MeanValueInterpolator::value_at`] rejects those.
pub fn nodes_inside(polygon: &[Point], grid: &Grid) -> Vec<[usize; 2]> {
    let m = polygon.len();
    let mut nodes = Vec::new();
    if m < 3 || grid.width == 0 || grid.height == 0 {
        return nodes;
    }
    let (ymin, ymax) =
        polygon.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
    let first_row = ymin.ceil().max(0.0);
    let last_row = ymax.floor().min((grid.height - 1) as f64);
    if first_row > last_row || first_row.is_nan() || last_row.is_nan() {
        return nodes;
    }
    let mut crossings: Vec<(f64, i32)> = Vec::new();
    let mut flat: Vec<(f64, f64)> = Vec::new();
    for row in first_row as usize..=last_row as usize {
        let y = row as f64;
        crossings.clear();
        flat.clear();
        for i in 0..m {
            let (a, b) = (polygon[i], polygon[(i + 1) % m]);
            if a[1] == y && b[1] == y {
                // an edge along the scanline: its nodes are on the outline
                flat.push((a[0].min(b[0]), a[0].max(b[0])));
            }
            // half-open in y, so a vertex on the scanline is counted once
            if (a[1] <= y) != (b[1] <= y) {
                let x = a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
                crossings.push((x, if b[1] > a[1] { 1 } else { -1 }));
            }
        }
        crossings.sort_by(|p, q| p.0.total_cmp(&q.0));
        let mut winding = 0;
        for k in 0..crossings.len().saturating_sub(1) {
            winding += crossings[k].1;
            if winding == 0 {
                continue;
            }
            let (x0, x1) = (crossings[k].0, crossings[k + 1].0);
            // integer columns strictly between the crossings
            let c0 = (x0.floor() + 1.0).max(0.0);
            let c1 = (x1.ceil() - 1.0).min((grid.width - 1) as f64);
            if c0 > c1 {
                continue;
            }
            for col in c0 as usize..=c1 as usize {
                let on_flat_edge = flat.iter().any(|&(lo, hi)| lo <= col as f64 && col as f64 <= hi);
                if grid.active[grid.index(col, row)] && !on_flat_edge {
                    nodes.push([col, row]);
                }
            }
        }
    }
    nodes
}

/// The interior samples of a region: every active node strictly inside the outline
/// polygon `vertices`, with the mean-value interpolation of `values` there. Evaluated in
/// parallel; the order is row-major.
pub(crate) fn interior_samples(vertices: Vec<Point>, values: Vec<Point>, grid: &Grid) -> Vec<super::Sample> {
    let nodes = nodes_inside(&vertices, grid);
    let mvc = MeanValueInterpolator::new(vertices, values);
    par_map(&nodes, |&[col, row], scratch| {
        let rest = [col as f64, row as f64];
        mvc.value_at(rest, scratch).map(|displacement| super::Sample { rest, displacement })
    })
}

/// `f` of each item that gives a value, in order, evaluated in parallel chunks that each
/// have their own scratch space.
pub(crate) fn par_map<I: Sync, T: Send>(items: &[I], f: impl Fn(&I, &mut MvcScratch) -> Option<T> + Sync) -> Vec<T> {
    let pieces: Vec<Vec<T>> = items.par_chunks(256).map(|chunk| {
        let mut scratch = MvcScratch::default();
        chunk.iter().filter_map(|item| f(item, &mut scratch)).collect()
    }).collect();
    pieces.into_iter().flatten().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An independent reference for the interpolator: the mean-value sum written edge by
    /// edge, `tan(α/2)` from each edge's own angle (inside the outline only).
    fn per_edge_sum(polygon: &[Point], values: &[Point], x: Point) -> Point {
        let (mut num, mut den) = ([0.0f64; 2], 0.0f64);
        for a in 0..polygon.len() {
            let b = (a + 1) % polygon.len();
            let (sa, sb) = (sub(polygon[a], x), sub(polygon[b], x));
            let (ra, rb) = (norm(sa), norm(sb));
            let (det, dot) = (sa[0] * sb[1] - sa[1] * sb[0], sa[0] * sb[0] + sa[1] * sb[1]);
            let t = if dot >= 0.0 { det / (ra * rb + dot) } else { (ra * rb - dot) / det };
            let (wa, wb) = (t / ra, t / rb);
            for k in 0..2 {
                num[k] += wa * values[a][k] + wb * values[b][k];
            }
            den += wa + wb;
        }
        [num[0] / den, num[1] / den]
    }

    fn circle(n: usize, c: Point, r: f64) -> Vec<Point> {
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect()
    }

    #[test]
    fn on_the_outline_gives_the_outline_value() {
        let poly = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        let vals = [[1.0, 0.0], [3.0, 1.0], [7.0, 2.0], [5.0, 3.0]];
        assert_eq!(
            mean_value_interpolate(&poly, &vals, [10.0, 10.0]),
            [7.0, 2.0]
        );
        let mid = mean_value_interpolate(&poly, &vals, [10.0, 2.5]);
        assert!(
            (mid[0] - 4.0).abs() < 1e-12 && (mid[1] - 1.25).abs() < 1e-12,
            "{mid:?}"
        );
        // a hair inside an edge: the limit is the edge's linear interpolation
        let near = mean_value_interpolate(&poly, &vals, [5.0, 1e-7]);
        assert!(
            (near[0] - 2.0).abs() < 1e-5 && (near[1] - 0.5).abs() < 1e-5,
            "{near:?}"
        );
        let mvc = MeanValueInterpolator::new(poly.to_vec(), vals.to_vec());
        let mut scratch = MvcScratch::default();
        assert_eq!(mvc.value_at([10.0, 2.5], &mut scratch), None);
        assert_eq!(mvc.value_at([0.0, 0.0], &mut scratch), None);
        let near = mvc.value_at([5.0, 1e-7], &mut scratch).unwrap();
        assert!(
            (near[0] - 2.0).abs() < 1e-5 && (near[1] - 0.5).abs() < 1e-5,
            "{near:?}"
        );
    }

    #[test]
    fn splitting_an_edge_at_a_linear_value_changes_nothing() {
        let poly = [[0.0, 0.0], [10.0, 1.0], [8.0, 9.0], [-1.0, 7.0]];
        let vals = [[1.0, -2.0], [3.0, 1.0], [7.0, 2.0], [5.0, 3.0]];
        let mut fine_p = Vec::new();
        let mut fine_v = Vec::new();
        for i in 0..4 {
            let (a, b) = (poly[i], poly[(i + 1) % 4]);
            let (fa, fb) = (vals[i], vals[(i + 1) % 4]);
            for k in 0..7 {
                let s = k as f64 / 7.0;
                fine_p.push([a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])]);
                fine_v.push([fa[0] + s * (fb[0] - fa[0]), fa[1] + s * (fb[1] - fa[1])]);
            }
        }
        for x in [[3.0, 3.0], [0.1, 0.5], [8.0, 7.0], [5.0, 1.0]] {
            let a = mean_value_interpolate(&poly, &vals, x);
            let b = mean_value_interpolate(&fine_p, &fine_v, x);
            assert!(
                (a[0] - b[0]).abs() < 1e-11 && (a[1] - b[1]).abs() < 1e-11,
                "{a:?} {b:?}"
            );
        }
    }

    #[test]
    fn fast_path_matches_the_checked_sum_and_its_weights_reproduce_positions() {
        // a wobbly, non-convex outline with smooth, non-affine values
        let n = 700;
        let poly: Vec<Point> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                let r = 100.0 + 30.0 * (5.0 * a).sin();
                [128.0 + r * a.cos(), 128.0 + r * a.sin()]
            })
            .collect();
        let vals: Vec<Point> = poly
            .iter()
            .map(|p| {
                [
                    20.0 * (p[0] / 60.0).sin() + 0.001 * p[1] * p[1],
                    15.0 * (p[1] / 45.0).cos(),
                ]
            })
            .collect();
        let mvc = MeanValueInterpolator::new(poly.clone(), vals.clone());
        let mut scratch = MvcScratch::default();
        let mut weights = vec![0.0; n];
        for node in nodes_inside(&poly, &Grid::new(256, 256)).iter().step_by(41) {
            let x = [node[0] as f64, node[1] as f64];
            let direct = per_edge_sum(&poly, &vals, x);
            let fast = mvc.value_at(x, &mut scratch).unwrap();
            assert!((direct[0] - fast[0]).abs() < 1e-10 && (direct[1] - fast[1]).abs() < 1e-10);
            assert!(mvc.weights_at(x, &mut scratch, &mut weights));
            let sum: f64 = weights.iter().sum();
            let px: f64 = weights.iter().zip(&poly).map(|(w, p)| w * p[0]).sum();
            let py: f64 = weights.iter().zip(&poly).map(|(w, p)| w * p[1]).sum();
            assert!(
                (sum - 1.0).abs() < 1e-12 && (px - x[0]).abs() < 1e-9 && (py - x[1]).abs() < 1e-9
            );
        }
    }

    #[test]
    fn affine_data_is_reproduced_on_a_dense_outline() {
        let poly = circle(3000, [300.0, 200.0], 180.0);
        let f = |p: Point| {
            [
                0.3 * p[0] - 0.2 * p[1] + 4.0,
                0.1 * p[0] + 0.25 * p[1] - 7.0,
            ]
        };
        let vals: Vec<Point> = poly.iter().map(|&p| f(p)).collect();
        let mvc = MeanValueInterpolator::new(poly.clone(), vals);
        let mut scratch = MvcScratch::default();
        for node in nodes_inside(&poly, &Grid::new(600, 400)).iter().step_by(53) {
            let x = [node[0] as f64, node[1] as f64];
            let got = mvc.value_at(x, &mut scratch).unwrap();
            let want = f(x);
            assert!((got[0] - want[0]).abs() < 1e-9 && (got[1] - want[1]).abs() < 1e-9);
        }
    }

    #[test]
    fn inside_nodes_are_strict_and_follow_the_matte() {
        let square = [[1.0, 1.0], [4.0, 1.0], [4.0, 4.0], [1.0, 4.0]];
        let mut grid = Grid::new(6, 6);
        let nodes = nodes_inside(&square, &grid);
        assert_eq!(nodes, vec![[2, 2], [3, 2], [2, 3], [3, 3]]);
        let i = grid.index(3, 2);
        grid.active[i] = false;
        assert_eq!(nodes_inside(&square, &grid), vec![[2, 2], [2, 3], [3, 3]]);
        // clockwise and counter-clockwise alike
        let reversed: Vec<Point> = square.iter().rev().copied().collect();
        assert_eq!(nodes_inside(&reversed, &Grid::new(6, 6)), nodes);
    }
}

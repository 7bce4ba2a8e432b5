//! Curves made of spans (line segments or centripetal Catmull-Rom pieces), their arc
//! length, and the parameters at which they are sampled.

use super::Point;

/// A curve through control points, made of spans: span `i` runs from control point `i`
/// (at `u = 0`) to control point `i + 1` (at `u = 1`), wrapping to point 0 when closed.
///
/// Every span is stored in cubic Hermite form (end points and end tangents, the tangents
/// already scaled to the span's unit parameter), so a line segment and a Catmull-Rom span
/// are evaluated the same way; line segments are additionally marked so that their points
/// and lengths are computed exactly (a segment's parameter is the fraction of its length).
///
/// ```
/// use inkwarp_core::geometry::Curve;
/// let c = Curve::spline(&[[0.0, 0.0], [10.0, 5.0], [20.0, 0.0]], false);
/// assert_eq!(c.span_count(), 2);
/// assert_eq!(c.point_at(1, 0.0), [10.0, 5.0]); // it passes through its control points
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    spans: Vec<Span>,
    linear: bool,
    closed: bool,
}

/// One Hermite span: `p0`, `p1` the end points, `t0`, `t1` the derivatives with respect
/// to the span parameter `u ∈ [0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Span {
    p0: Point,
    t0: Point,
    t1: Point,
    p1: Point,
}

/// Where a sample lies on a curve: its span and the parameter `u ∈ [0, 1]` within it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveParameter {
    pub span: usize,
    pub u: f64,
}

impl Curve {
    /// The polyline through `points` (the closing segment back to the first point
    /// included when `closed`). Needs at least one point; one point gives no spans.
    pub fn polyline(points: &[Point], closed: bool) -> Self {
        let spans = span_ends(points.len(), closed)
            .map(|(a, b)| {
                let (p0, p1) = (points[a], points[b]);
                let d = sub(p1, p0);
                Span { p0, t0: d, t1: d, p1 }
            })
            .collect();
        Curve { spans, linear: true, closed }
    }

    /// The interpolating centripetal Catmull-Rom curve (α = ½) through `points`.
    ///
    /// Span `i` uses the four control points `i − 1, i, i + 1, i + 2`, with knot
    /// intervals `|P(j+1) − P(j)|^½` (Barry–Goldman). A closed curve takes its neighbours
    /// cyclically. An open curve's missing neighbour beyond each end is the reflection of
    /// the second point through the end point (`P(−1) = 2·P(0) − P(1)`), which makes the
    /// end tangent point along the first (last) chord: the curve leaves its end points
    /// straight, without the curl a doubled end point would give. Two points give the
    /// straight segment. Coincident consecutive control points are allowed: a zero-length
    /// span stays at its point, and its neighbours meet it with zero tangent.
    pub fn spline(points: &[Point], closed: bool) -> Self {
        let n = points.len();
        // `q` reflected through `p`
        let reflect = |p: Point, q: Point| [2.0 * p[0] - q[0], 2.0 * p[1] - q[1]];
        let at = |i: isize| -> Point {
            if closed {
                points[i.rem_euclid(n as isize) as usize]
            } else if i < 0 {
                reflect(points[0], points[1.min(n - 1)])
            } else if i as usize >= n {
                reflect(points[n - 1], points[n.saturating_sub(2)])
            } else {
                points[i as usize]
            }
        };
        let spans = span_ends(n, closed)
            .map(|(i, _)| i as isize)
            .map(|i| catmull_rom_span(at(i - 1), at(i), at(i + 1), at(i + 2)))
            .collect();
        Curve { spans, linear: false, closed }
    }

    /// The polyline or spline through `points`, as `spline` says.
    pub fn new(points: &[Point], closed: bool, spline: bool) -> Self {
        if spline { Self::spline(points, closed) } else { Self::polyline(points, closed) }
    }

    /// How many spans the curve has (`n − 1` open, `n` closed).
    pub fn span_count(&self) -> usize { self.spans.len() }

    /// The point at parameter `u ∈ [0, 1]` of span `span`.
    ///
    /// # Panics
    /// If `span >= self.span_count()`.
    pub fn point_at(&self, span: usize, u: f64) -> Point {
        let s = &self.spans[span];
        if self.linear {
            // exact at both ends, and the midpoint of a segment is its midpoint
            if u == 1.0 {
                return s.p1;
            }
            return [s.p0[0] + u * (s.p1[0] - s.p0[0]), s.p0[1] + u * (s.p1[1] - s.p0[1])];
        }
        hermite(s, u)
    }

    /// Span `span` in Hermite form: `[start, start tangent, end tangent, end]`, the
    /// tangents with respect to the span parameter, so that the point at `u` is
    /// `Σ hermite_basis(u)[k] · data[k]` (for a segment, its lerp).
    pub fn span_hermite(&self, span: usize) -> [Point; 4] {
        let s = &self.spans[span];
        [s.p0, s.t0, s.t1, s.p1]
    }

    #[cfg(test)]
    /// The length of span `span`, exact for line segments and to about 1e-12 relative
    /// for spline spans (composite Gauss–Legendre quadrature of the speed).
    pub fn span_length(&self, span: usize) -> f64 {
        let s = &self.spans[span];
        if self.linear {
            return norm(sub(s.p1, s.p0));
        }
        let k = subdivisions(s);
        (0..k)
            .map(|j| gauss_length(s, j as f64 / k as f64, (j + 1) as f64 / k as f64))
            .sum()
    }

    #[cfg(test)]
    /// The arc length of span `span` between parameters `u0 ≤ u1`.
    pub fn arc_length(&self, span: usize, u0: f64, u1: f64) -> f64 {
        let s = &self.spans[span];
        if self.linear {
            return (u1 - u0) * norm(sub(s.p1, s.p0));
        }
        let k = subdivisions(s);
        // the same sub-intervals as the sampling, so that lengths add up consistently
        let (j0, j1) = ((u0 * k as f64).floor() as usize, ((u1 * k as f64).ceil() as usize).min(k));
        (j0..j1.max(j0 + 1))
            .map(|j| {
                let a = (j as f64 / k as f64).max(u0);
                let b = ((j + 1) as f64 / k as f64).min(u1);
                if b > a {
                    gauss_length(s, a, b)
                } else {
                    0.0
                }
            })
            .sum()
    }

    /// The parameters at which the curve is sampled: along each span at equal arc length,
    /// no more than `spacing_px` apart (the span's length divided into
    /// `max(1, ⌈length / spacing⌉)` equal pieces), every span's start point included and,
    /// for an open curve, the final end point. A closed curve does not repeat its first
    /// point. A curve with no spans (one control point) gives no parameters.
    ///
    /// `spacing_px` must be positive and finite.
    pub fn sample_parameters(&self, spacing_px: f64) -> Vec<CurveParameter> {
        debug_assert!(spacing_px > 0.0 && spacing_px.is_finite());
        let mut out = Vec::new();
        for (i, s) in self.spans.iter().enumerate() {
            if self.linear {
                let len = norm(sub(s.p1, s.p0));
                let pieces = pieces_for(len, spacing_px);
                out.extend((0..pieces).map(|j| CurveParameter { span: i, u: j as f64 / pieces as f64 }));
            } else {
                equal_arc_parameters(s, i, spacing_px, &mut out);
            }
        }
        if !self.closed && !self.spans.is_empty() {
            out.push(CurveParameter { span: self.spans.len() - 1, u: 1.0 });
        }
        out
    }

    /// The curve as a dense polyline: its points at [`Curve::sample_parameters`], and for a
    /// closed curve the first point repeated at the end so that the polyline closes.
    pub fn to_polyline(&self, spacing_px: f64) -> Vec<Point> {
        let mut pts: Vec<Point> =
            self.sample_parameters(spacing_px).iter().map(|p| self.point_at(p.span, p.u)).collect();
        let first = pts.first().copied().filter(|_| self.closed);
        pts.extend(first);
        pts
    }
}

/// The (start, end) control-point indices of each span.
fn span_ends(n: usize, closed: bool) -> impl Iterator<Item = (usize, usize)> {
    let count = if n < 2 { 0 } else if closed { n } else { n - 1 };
    (0..count).map(move |i| (i, (i + 1) % n))
}

/// How many equal pieces a span of length `len` needs so that none exceeds `spacing`.
fn pieces_for(len: f64, spacing: f64) -> usize {
    let pieces = (len / spacing).ceil();
    if !(pieces.is_finite() && pieces >= 1.0) {
        return 1;
    }
    // a division that rounds up by one ulp must not leave a piece longer than spacing
    let n = pieces as usize;
    n + usize::from(len / n as f64 > spacing)
}

/// The centripetal Catmull-Rom span from `b` to `c` with neighbours `a` and `d`, in
/// Hermite form. With knot intervals `d0, d1, d2` (square roots of the chord lengths),
/// the derivative at `b` with respect to the knot is
/// `(b − a)/d0 − (c − a)/(d0 + d1) + (c − b)/d1` (the derivative of the parabola through
/// `a, b, c` at their knots), scaled by `d1` to the span's unit parameter; likewise at `c`.
fn catmull_rom_span(a: Point, b: Point, c: Point, d: Point) -> Span {
    let d0 = norm(sub(b, a)).sqrt();
    let d1 = norm(sub(c, b)).sqrt();
    let d2 = norm(sub(d, c)).sqrt();
    if d1 == 0.0 {
        return Span { p0: b, t0: [0.0; 2], t1: [0.0; 2], p1: c };
    }
    let chord = sub(c, b);
    // t0 = (c − b) + d1·[(b − a)/d0 − (c − a)/(d0 + d1)]. As a → b the bracket tends to
    // −(c − b)/d1 ((b − a)/d0 = |b − a|^½·e vanishes), so a coincident neighbour gives a
    // zero tangent.
    let t0 = if d0 > 0.0 { [0, 1].map(|k| chord[k] + d1 * ((b[k] - a[k]) / d0 - (c[k] - a[k]) / (d0 + d1))) } else { [0.0; 2] };
    // t1 = (c − b) − d1·(d − b)/(d1 + d2) + d1·(d − c)/d2
    let t1 = if d2 > 0.0 { [0, 1].map(|k| chord[k] + d1 * ((d[k] - c[k]) / d2 - (d[k] - b[k]) / (d1 + d2))) } else { [0.0; 2] };
    Span { p0: b, t0, t1, p1: c }
}

/// The cubic Hermite basis at `u`: the weights of start, start tangent, end tangent and
/// end (see [`Curve::span_hermite`]).
#[inline]
pub fn hermite_basis(u: f64) -> [f64; 4] {
    let u2 = u * u;
    let u3 = u2 * u;
    [2.0 * u3 - 3.0 * u2 + 1.0, u3 - 2.0 * u2 + u, u3 - u2, -2.0 * u3 + 3.0 * u2]
}

#[inline]
fn hermite(s: &Span, u: f64) -> Point {
    let [h00, h10, h11, h01] = hermite_basis(u);
    [0, 1].map(|k| h00 * s.p0[k] + h10 * s.t0[k] + h01 * s.p1[k] + h11 * s.t1[k])
}

#[inline]
fn speed(s: &Span, u: f64) -> f64 {
    let u2 = u * u;
    let g00 = 6.0 * u2 - 6.0 * u;
    let g10 = 3.0 * u2 - 4.0 * u + 1.0;
    let g01 = -g00;
    let g11 = 3.0 * u2 - 2.0 * u;
    let [dx, dy] = [0, 1].map(|k| g00 * s.p0[k] + g10 * s.t0[k] + g01 * s.p1[k] + g11 * s.t1[k]);
    (dx * dx + dy * dy).sqrt()
}

/// Five-point Gauss–Legendre nodes and weights on [-1, 1].
const GL_NODES: [f64; 5] = [
    -0.906_179_845_938_664,
    -0.538_469_310_105_683,
    0.0,
    0.538_469_310_105_683,
    0.906_179_845_938_664,
];
const GL_WEIGHTS: [f64; 5] = [
    0.236_926_885_056_189,
    0.478_628_670_499_366,
    0.568_888_888_888_889,
    0.478_628_670_499_366,
    0.236_926_885_056_189,
];

/// Arc length of the span between parameters `a` and `b`.
fn gauss_length(s: &Span, a: f64, b: f64) -> f64 {
    let half = 0.5 * (b - a);
    let mid = 0.5 * (a + b);
    half * GL_NODES.iter().zip(GL_WEIGHTS).map(|(&x, w)| w * speed(s, mid + half * x)).sum::<f64>()
}

/// How many equal parameter sub-intervals the quadrature of a span uses: enough that each
/// covers at most a quarter pixel of the span's Bézier control polygon (an upper bound of
/// its length), and at least 8.
fn subdivisions(s: &Span) -> usize {
    let b1 = [s.p0[0] + s.t0[0] / 3.0, s.p0[1] + s.t0[1] / 3.0];
    let b2 = [s.p1[0] - s.t1[0] / 3.0, s.p1[1] - s.t1[1] / 3.0];
    let bound = norm(sub(b1, s.p0)) + norm(sub(b2, b1)) + norm(sub(s.p1, b2));
    let k = (4.0 * bound).ceil();
    if k.is_finite() { (k as usize).clamp(8, 1 << 20) } else { 8 }
}

/// Appends the parameters that split span `s` into equal arc lengths no longer than
/// `spacing` (the start `u = 0` included, the end `u = 1` not).
fn equal_arc_parameters(s: &Span, span: usize, spacing: f64, out: &mut Vec<CurveParameter>) {
    let k = subdivisions(s);
    // cumulative[j] = arc length from u = 0 to u = j / k
    let mut cumulative = Vec::with_capacity(k + 1);
    cumulative.push(0.0);
    for j in 0..k {
        cumulative.push(cumulative[j] + gauss_length(s, j as f64 / k as f64, (j + 1) as f64 / k as f64));
    }
    let total = cumulative[k];
    let pieces = pieces_for(total, spacing);
    out.push(CurveParameter { span, u: 0.0 });
    let mut j = 0;
    for p in 1..pieces {
        let target = total * p as f64 / pieces as f64;
        while j + 1 < k && cumulative[j + 1] < target {
            j += 1;
        }
        let lo = j as f64 / k as f64;
        let hi = (j + 1) as f64 / k as f64;
        out.push(CurveParameter { span, u: invert_length(s, lo, hi, target - cumulative[j]) });
    }
}

/// The parameter `u ∈ [lo, hi]` at which the arc length from `lo` equals `want`:
/// Newton's method on the arc length, kept inside a shrinking bracket by bisection.
fn invert_length(s: &Span, lo: f64, hi: f64, want: f64) -> f64 {
    let (mut a, mut b) = (lo, hi);
    let mut u = if hi > lo { lo + (hi - lo) * 0.5 } else { lo };
    for _ in 0..60 {
        let f = gauss_length(s, lo, u) - want;
        if f.abs() <= 1e-13 * (1.0 + want) {
            break;
        }
        if f > 0.0 {
            b = u;
        } else {
            a = u;
        }
        let v = speed(s, u);
        let newton = u - f / v;
        u = if v > 0.0 && newton > a && newton < b { newton } else { 0.5 * (a + b) };
        if b - a <= 1e-16 {
            break;
        }
    }
    u
}

#[inline]
pub(crate) fn sub(a: Point, b: Point) -> Point { [a[0] - b[0], a[1] - b[1]] }

#[inline]
pub(crate) fn norm(a: Point) -> f64 { (a[0] * a[0] + a[1] * a[1]).sqrt() }

#[cfg(test)]
mod tests {
    use super::*;

    fn dist(a: Point, b: Point) -> f64 {
        norm(sub(a, b))
    }

    #[test]
    fn two_point_spline_is_the_straight_segment() {
        let c = Curve::spline(&[[1.0, 2.0], [11.0, 7.0]], false);
        for k in 0..=10 {
            let u = k as f64 / 10.0;
            let p = c.point_at(0, u);
            assert!(
                dist(p, [1.0 + 10.0 * u, 2.0 + 5.0 * u]) < 1e-12,
                "{p:?} at {u}"
            );
        }
        assert!((c.span_length(0) - 125f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn spline_span_length_matches_a_fine_polyline() {
        let c = Curve::spline(
            &[[0.0, 0.0], [30.0, 40.0], [60.0, -10.0], [65.0, 80.0]],
            false,
        );
        for i in 0..c.span_count() {
            let n = 200_000;
            let fine: f64 = (0..n)
                .map(|j| {
                    dist(
                        c.point_at(i, j as f64 / n as f64),
                        c.point_at(i, (j + 1) as f64 / n as f64),
                    )
                })
                .sum();
            // the chord sum underestimates by O(1/n²)
            assert!(
                (c.span_length(i) - fine).abs() < 1e-6,
                "{} vs {fine}",
                c.span_length(i)
            );
        }
    }

    #[test]
    fn open_end_tangent_follows_the_first_chord() {
        let c = Curve::spline(&[[0.0, 0.0], [10.0, 0.0], [20.0, 10.0]], false);
        let p = c.point_at(0, 1e-6);
        assert!(p[1].abs() < 1e-9 && p[0] > 0.0, "{p:?}");
    }

    #[test]
    fn coincident_control_points_are_finite() {
        let c = Curve::spline(
            &[[0.0, 0.0], [0.0, 0.0], [5.0, 5.0], [5.0, 5.0], [9.0, 1.0]],
            false,
        );
        for i in 0..c.span_count() {
            for k in 0..=8 {
                let p = c.point_at(i, k as f64 / 8.0);
                assert!(p[0].is_finite() && p[1].is_finite());
            }
            assert!(c.span_length(i).is_finite());
        }
        assert_eq!(c.point_at(0, 0.5), [0.0, 0.0]);
        assert_eq!(c.point_at(2, 0.3), [5.0, 5.0]);
        let params = c.sample_parameters(1.0);
        assert!(params.iter().all(|p| p.u.is_finite()));
    }

    #[test]
    fn parameters_split_spans_at_equal_arc_length() {
        let c = Curve::spline(&[[0.0, 0.0], [12.0, 30.0], [40.0, 2.0]], false);
        let params = c.sample_parameters(0.7);
        for w in params.windows(2) {
            let (p, q) = (w[0], w[1]);
            if p.span == q.span {
                let s = &c.spans[p.span];
                let arc = gauss_length(s, p.u, q.u);
                let expected =
                    c.span_length(p.span) / pieces_for(c.span_length(p.span), 0.7) as f64;
                assert!((arc - expected).abs() < 1e-9, "{arc} vs {expected}");
                assert!(arc <= 0.7 + 1e-12);
            }
        }
    }
}

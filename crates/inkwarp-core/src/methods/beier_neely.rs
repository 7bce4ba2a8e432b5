//! `beier-neely`: Beier & Neely's feature-based field ("Feature-Based Image
//! Metamorphosis", SIGGRAPH '92), with Shepard weights for points.

use rayon::prelude::*;

use super::{is_finite_point, LinePair, MethodError, MethodReport};
use crate::field::Field;
use crate::geometry::{sub, Point, Sample};

/// Beier & Neely's weight parameters. A primitive's weight at a pixel is
///
/// ```text
/// weight = (length^p / (a + dist))^b
/// ```
///
/// where `dist` is the pixel's distance to the primitive (to the segment for a line, to
/// the position for a point) and `length` the rest segment's length (1 for a point).
///
/// * `a` (px, > 0): how strongly a primitive holds what is on it. Near 0 the field
///   follows each line exactly on it (and gets cusps there); large values smooth the
///   field and loosen the lines. Default **1 px**.
/// * `b` (≥ 0): how fast influence falls off with distance. 0 weights every primitive
///   equally everywhere; Beier & Neely suggest 0.5–2. Default **2**.
/// * `p` (≥ 0): how much longer lines outweigh shorter ones; their range is 0–1.
///   Default **0**: every line weighs the same, and as much as a point. With `p > 0` a
///   long line (a held edge of 120 px, say) outweighs a point by `120^(p·b)` and the
///   points of a drawing barely move anything.
///
/// Points use the same formula with `length^p = 1`, i.e. Shepard's inverse-distance
/// weights `1 / (a + dist)^b`, so a drawing of points and lines is weighted
/// consistently.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeierNeelyParams {
    pub a: f64,
    pub b: f64,
    pub p: f64,
}

impl Default for BeierNeelyParams { fn default() -> Self { Self::DEFAULT } }

impl BeierNeelyParams {
    /// `a` 1 px, `b` 2, `p` 0 (see the type's documentation).
    pub const DEFAULT: BeierNeelyParams = BeierNeelyParams { a: 1.0, b: 2.0, p: 0.0 };

    /// Checks the ranges documented on the type.
    pub fn validate(&self) -> Result<(), MethodError> {
        use crate::limits::{MAX_BEIER_NEELY_A, MAX_BEIER_NEELY_EXPONENT};
        if !(self.a > 0.0 && self.a <= MAX_BEIER_NEELY_A) {
            return Err(MethodError::BadParameter { name: "a", value: self.a, hint: "it must be a number of pixels greater than 0 and at most 1e6 (default 1)" });
        }
        for (name, value, hint) in [("b", self.b, "it must be from 0 to 16 (default 2)"), ("p", self.p, "it must be from 0 to 16 (default 0)")] {
            if !(0.0..=MAX_BEIER_NEELY_EXPONENT).contains(&value) {
                return Err(MethodError::BadParameter { name, value, hint });
            }
        }
        Ok(())
    }
}

/// One line pair, prepared for evaluation.
struct Line {
    p: Point,
    d: Point,
    len2: f64,
    len: f64,
    pose_p: Point,
    pose_d: Point,
    pose_len: f64,
}

/// The `beier-neely` field, as a **forward** displacement on the rest image (the paper
/// renders every method by forward mapping; Beier & Neely's own formulation maps the
/// destination back to the source).
///
/// For a rest pixel `X` and a line pair `PQ → P'Q'`:
///
/// ```text
/// u  = (X − P)·(Q − P) / |Q − P|²              (position along the rest line)
/// v  = (X − P)·⊥(Q − P) / |Q − P|               (signed distance from it)
/// X' = P' + u (Q' − P') + v ⊥(Q' − P') / |Q' − P'|
/// ```
///
/// with `⊥(x, y) = (−y, x)`; the line pair's displacement is `X' − X` and its `dist` is
/// `|v|` for `0 ≤ u ≤ 1`, else the distance to the nearer end. A point moves `X` by its
/// own displacement. The field is the weighted mean ([`BeierNeelyParams`]) of all
/// primitives' displacements. One line pair moved rigidly therefore moves every pixel by
/// that same rigid motion; a posed segment of length 0 contributes only its translation.
/// A rest segment of length 0 is treated as a point.
///
/// # Errors
/// Parameters out of range, or no finite sample or line pair at all.
pub fn beier_neely_field(
    points: &[Sample],
    line_pairs: &[LinePair],
    width: usize,
    height: usize,
    params: &BeierNeelyParams,
    report: &mut MethodReport,
) -> Result<Field, MethodError> {
    params.validate()?;
    let BeierNeelyParams { a, b, p: len_power } = *params;
    let finite = |s: &&Sample| is_finite_point(s.rest) && is_finite_point(s.displacement);
    let mut pts: Vec<Sample> = points.iter().filter(finite).copied().collect();
    let mut dropped = points.len() - pts.len();
    let mut lines: Vec<Line> = Vec::new();
    for l in line_pairs {
        if !l.rest.iter().chain(&l.pose).all(|q| is_finite_point(*q)) {
            dropped += 1;
            continue;
        }
        let d = sub(l.rest[1], l.rest[0]);
        let len2 = dot(d, d);
        if len2 == 0.0 {
            pts.push(l.end_samples()[0]);
            continue;
        }
        let pose_d = sub(l.pose[1], l.pose[0]);
        let len = len2.sqrt();
        lines.push(Line { p: l.rest[0], d, len2, len, pose_p: l.pose[0], pose_d, pose_len: dot(pose_d, pose_d).sqrt() });
    }
    report.samples_given = points.len();
    report.samples_used = pts.len();
    report.line_pairs_used = lines.len();
    report.dropped = dropped;
    if pts.is_empty() && lines.is_empty() {
        return Err(MethodError::NoControls { method: "beier-neely", what: "point or line pair" });
    }

    // (a + dist)^-b, with the common b = 2 and b = 1 done without powf.
    let falloff = move |dist: f64| -> f64 {
        let base = 1.0 / (a + dist);
        if b == 2.0 { base * base } else if b == 1.0 { base } else { base.powf(b) }
    };
    // Strengths (len^p)^b over the longest line's, and the points' weights by the same
    // factor (it cancels): len^(p·b) itself overflows for long lines at large b and p.
    let longest = lines.iter().map(|l| l.len).fold(1.0, f64::max); // at least 1 px: a tiny one's inverse overflows
    let strength_b: Vec<f64> = lines.iter().map(|l| (l.len / longest).powf(len_power * b)).collect();
    let point_scale = if lines.is_empty() { 1.0 } else { longest.powf(-len_power * b) };

    let mut f = Field::zeros(width, height);
    let xs: Vec<f64> = (0..width).map(|x| x as f64).collect();
    // Row by row in parallel; within a row, one primitive at a time over all pixels,
    // so that the inner loops are branch-free and vectorise.
    f.dx.par_chunks_mut(width).zip(f.dy.par_chunks_mut(width)).enumerate().for_each(|(y, (row_x, row_y))| {
        if crate::interrupt::requested() {
            return; // `field` reports the stop
        }
        let yf = y as f64;
        let mut sx = vec![0.0f64; width];
        let mut sy = vec![0.0f64; width];
        let mut sw = vec![0.0f64; width];
        for (l, &sb) in lines.iter().zip(&strength_b) {
            let (pose_ux, pose_uy) = if l.pose_len > 0.0 {
                (l.pose_d[0] / l.pose_len, l.pose_d[1] / l.pose_len)
            } else {
                (0.0, 0.0)
            };
            let ry = yf - l.p[1];
            let qy = ry - l.d[1];
            for x in 0..width {
                let xf = xs[x];
                let rx = xf - l.p[0];
                let u = (rx * l.d[0] + ry * l.d[1]) / l.len2;
                let v = (ry * l.d[0] - rx * l.d[1]) / l.len; // r · ⊥d / |d|
                let tx = l.pose_p[0] + u * l.pose_d[0] - v * pose_uy;
                let ty = l.pose_p[1] + u * l.pose_d[1] + v * pose_ux;
                let qx = rx - l.d[0];
                let to_p = (rx * rx + ry * ry).sqrt();
                let to_q = (qx * qx + qy * qy).sqrt();
                let dist = if u < 0.0 { to_p } else if u > 1.0 { to_q } else { v.abs() };
                let w = sb * falloff(dist);
                sx[x] += w * (tx - xf);
                sy[x] += w * (ty - yf);
                sw[x] += w;
            }
        }
        for s in &pts {
            let dy = yf - s.rest[1];
            for x in 0..width {
                let dx = xs[x] - s.rest[0];
                let w = point_scale * falloff((dx * dx + dy * dy).sqrt());
                sx[x] += w * s.displacement[0];
                sy[x] += w * s.displacement[1];
                sw[x] += w;
            }
        }
        for x in 0..width {
            row_x[x] = (sx[x] / sw[x]) as f32;
            row_y[x] = (sy[x] / sw[x]) as f32;
        }
    });
    Ok(f)
}

#[inline]
fn dot(a: Point, b: Point) -> f64 { a[0] * b[0] + a[1] * b[1] }

#[cfg(test)]
mod tests {
    use super::*;

    fn run(points: &[Sample], lines: &[LinePair], w: usize, h: usize) -> Field {
        beier_neely_field(points, lines, w, h, &BeierNeelyParams::default(), &mut MethodReport::default()).unwrap()
    }

    fn rigid(p: Point) -> Point {
        let (c, s) = (0.6f64, 0.8f64); // a rotation by atan2(0.8, 0.6)
        [c * p[0] - s * p[1] + 7.0, s * p[0] + c * p[1] - 3.0]
    }

    #[test]
    fn a_single_line_pair_moves_everything_rigidly() {
        let rest = [[10.0, 12.0], [30.0, 20.0]];
        let pair = LinePair { rest, pose: rest.map(rigid) };
        let f = run(&[], &[pair], 48, 40);
        for y in 0..40 {
            for x in 0..48 {
                let want = rigid([x as f64, y as f64]);
                let got = f.at(x, y);
                assert!((got[0] as f64 - (want[0] - x as f64)).abs() < 1e-4, "({x}, {y})");
                assert!((got[1] as f64 - (want[1] - y as f64)).abs() < 1e-4, "({x}, {y})");
            }
        }
    }

    #[test]
    fn two_lines_moved_by_one_rigid_motion_give_that_motion() {
        let l1 = [[5.0, 5.0], [20.0, 8.0]];
        let l2 = [[30.0, 30.0], [12.0, 35.0]];
        let pairs = [l1, l2].map(|r| LinePair { rest: r, pose: r.map(rigid) });
        let f = run(&[], &pairs, 40, 40);
        let want = rigid([17.0, 23.0]);
        let got = f.at(17, 23);
        assert!((got[0] as f64 - (want[0] - 17.0)).abs() < 1e-4);
        assert!((got[1] as f64 - (want[1] - 23.0)).abs() < 1e-4);
    }

    #[test]
    fn the_largest_weights_allowed_stay_finite_and_keep_their_balance() {
        // (len^p)^b of a 345 px line at b = 8, p = 16 overflowed: every pixel NaN, at rest too.
        let long = LinePair { rest: [[10.0, 10.0], [300.0, 200.0]], pose: [[10.0, 10.0], [300.0, 200.0]] };
        let short = LinePair { rest: [[5.0, 30.0], [6.0, 30.0]], pose: [[9.0, 30.0], [10.0, 30.0]] };
        let dot = Sample { rest: [40.0, 5.0], displacement: [3.0, 0.0] };
        let params = BeierNeelyParams { a: 1.0, b: 16.0, p: 16.0 };
        let f = beier_neely_field(&[dot], &[long, short], 320, 240, &params, &mut MethodReport::default()).unwrap();
        assert!(f.dx.iter().chain(&f.dy).all(|v| v.is_finite()));
        // The long line at rest holds everything (the short one and the point weigh nothing beside it).
        assert!(f.dx.iter().chain(&f.dy).all(|v| v.abs() < 1e-3));
        // A line shorter than a pixel alone with a point: the point carries the field (the
        // inverse of a 0.05 px line's (len^p)^b overflowed).
        let tiny = LinePair { rest: [[50.0, 50.0], [50.05, 50.0]], pose: [[50.0, 50.0], [50.05, 50.0]] };
        let f = beier_neely_field(&[dot], &[tiny], 64, 64, &params, &mut MethodReport::default()).unwrap();
        assert!(f.dx.iter().chain(&f.dy).all(|v| v.is_finite()) && (f.at(10, 10)[0] - 3.0).abs() < 1e-3, "{:?}", f.at(10, 10));
        // The balance of a line and a point is the formula's: (len^p)^b (a + dist)^-b against
        // (a + dist)^-b, here at pixel (20, 30) for a translated line and a point.
        let p = BeierNeelyParams { a: 1.0, b: 2.0, p: 0.5 };
        let moved = LinePair { rest: [[10.0, 10.0], [30.0, 12.0]], pose: [[12.0, 11.0], [32.0, 13.0]] };
        let f = beier_neely_field(&[dot], &[moved], 64, 48, &p, &mut MethodReport::default()).unwrap();
        let len = 404.0f64.sqrt();
        let wl = len.powf(0.5 * 2.0) / (1.0 + 380.0 / len).powi(2);
        let wp = 1.0 / (1.0 + (400.0f64 + 625.0).sqrt()).powi(2);
        let want = [(wl * 2.0 + wp * 3.0) / (wl + wp), wl / (wl + wp)];
        let got = f.at(20, 30);
        assert!((got[0] as f64 - want[0]).abs() < 1e-5 && (got[1] as f64 - want[1]).abs() < 1e-5, "{got:?} {want:?}");
    }

    #[test]
    fn points_are_shepard_weighted() {
        let pts = [
            Sample { rest: [2.0, 2.0], displacement: [4.0, 0.0] },
            Sample { rest: [8.0, 2.0], displacement: [0.0, 4.0] },
        ];
        let f = run(&pts, &[], 11, 5);
        // Midway both weigh the same.
        assert_eq!(f.at(5, 2), [2.0, 2.0]);
        // On a point: weight (1/a)^2 = 1 against (1/7)^2 for the other.
        let w_far = 1.0 / 49.0;
        let want = 4.0 / (1.0 + w_far);
        assert!((f.at(2, 2)[0] as f64 - want).abs() < 1e-5);
    }

    #[test]
    fn lines_hold_what_is_on_them() {
        // A held line along the top and a point pulled below it: pixels on the line
        // barely move.
        let held = LinePair { rest: [[0.0, 0.0], [40.0, 0.0]], pose: [[0.0, 0.0], [40.0, 0.0]] };
        let pulled = [Sample { rest: [20.0, 20.0], displacement: [0.0, 10.0] }];
        let f = run(&pulled, &[held], 41, 41);
        assert!(f.at(20, 0)[1].abs() < 0.1, "{:?}", f.at(20, 0));
        assert!(f.at(20, 20)[1] > 9.0, "{:?}", f.at(20, 20));
    }

    #[test]
    fn bad_parameters_and_no_controls_are_errors() {
        let params = BeierNeelyParams { a: 0.0, ..Default::default() };
        let err = beier_neely_field(&[], &[], 4, 4, &params, &mut MethodReport::default()).unwrap_err();
        assert_eq!(
            err.to_string(),
            "Beier–Neely parameter a = 0 is out of range: it must be a number of pixels greater than 0 and at most 1e6 (default 1)."
        );
        let err = beier_neely_field(&[], &[], 4, 4, &BeierNeelyParams::default(), &mut MethodReport::default()).unwrap_err();
        assert_eq!(err.to_string(), "beier-neely needs at least one point or line pair; got none.");
    }
}

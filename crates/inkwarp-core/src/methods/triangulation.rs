//! `triangulation`: piecewise-linear interpolation over a Delaunay triangulation.

use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

use super::{merge_samples, MethodError, MethodReport};
use crate::field::Field;
use crate::geometry::Sample;

#[derive(Clone, Copy, Debug)]
struct Vertex {
    position: Point2<f64>,
    value: [f64; 2],
}

impl HasPosition for Vertex {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> { self.position }
}

/// The `triangulation` field: the Delaunay triangulation (spade's, with exact
/// predicates) of the samples' rest positions plus the four image corner pixels
/// `(0, 0)`, `(W−1, 0)`, `(0, H−1)`, `(W−1, H−1)` held at zero displacement, and in each
/// triangle the displacement interpolated linearly from its three vertices. This is the
/// "polygonal mapping" of the paper's plates: exact at the samples, continuous, and
/// creased along every triangle edge.
///
/// Samples at the same position are merged (displacements averaged); a sample on a
/// corner pixel replaces that corner's zero; samples with a non-finite coordinate are
/// skipped. Samples outside the image take part (they widen the hull).
///
/// A pixel centre on an edge shared by two triangles gets the same value from both
/// (the interpolant is continuous), so the raster order does not matter.
pub fn triangulation_field(samples: &[Sample], width: usize, height: usize, report: &mut MethodReport) -> Result<Field, MethodError> {
    let (mut merged, dropped) = merge_samples(samples);
    report.samples_given = samples.len();
    report.dropped = dropped;
    report.samples_used = merged.len();
    let (w1, h1) = ((width - 1) as f64, (height - 1) as f64);
    for corner in [[0.0, 0.0], [w1, 0.0], [0.0, h1], [w1, h1]] {
        if !merged.iter().any(|s| s.rest == corner) {
            merged.push(Sample { rest: corner, displacement: [0.0, 0.0] });
        }
    }
    let vertex = |s: &Sample| Vertex { position: Point2::new(s.rest[0], s.rest[1]), value: s.displacement };
    let vertices: Vec<Vertex> = merged.iter().map(vertex).collect();
    let why = |e: spade::InsertionError| match e {
        spade::InsertionError::TooSmall => "a point's coordinates are too close to zero (below 1e-100 pixels); round them to 0",
        spade::InsertionError::TooLarge => "a point's coordinates are too large; keep them within ±1e6 pixels",
        spade::InsertionError::NAN => "a point's coordinates are not numbers (NaN); give finite coordinates",
    };
    let tri: DelaunayTriangulation<Vertex> =
        DelaunayTriangulation::bulk_load_stable(vertices).map_err(|e| MethodError::Triangulation(why(e).into()))?;

    let mut f = Field::zeros(width, height);
    if tri.num_inner_faces() == 0 {
        // A one-pixel-wide image: the corners are collinear. Interpolate along the line
        // between the vertices, which all lie on it.
        fill_collinear(&tri, &mut f);
        return Ok(f);
    }
    for v in tri.inner_faces().map(|face| face.vertices()) {
        rasterize(&mut f, v.map(|h| [h.position().x, h.position().y]), v.map(|h| h.data().value));
    }
    Ok(f)
}

/// Writes the linear interpolant of `val` over triangle `p` to every pixel centre inside
/// it (or on its edges), row by row over the exact span of the triangle at that row.
fn rasterize(f: &mut Field, p: [[f64; 2]; 3], val: [[f64; 2]; 3]) {
    let area2 = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
    if area2.abs() < 1e-12 {
        return;
    }
    // Barycentric weights are affine in (x, y): λᵢ = (αᵢ + βᵢ x + γᵢ y) / area2.
    let coef = |i: usize| {
        let (a, b) = (p[(i + 1) % 3], p[(i + 2) % 3]);
        [a[0] * b[1] - b[0] * a[1], a[1] - b[1], b[0] - a[0]]
    };
    let c = [coef(0), coef(1), coef(2)];
    let eps = 1e-9;
    let (w, h) = (f.width as i64, f.height as i64);
    let ymin = (p.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min) - eps).ceil().max(0.0) as i64;
    let ymax = (p.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max) + eps).floor().min((h - 1) as f64) as i64;
    for y in ymin..=ymax {
        let yf = y as f64;
        // The span where all three barycentric weights are ≥ −eps: each is affine in x.
        let (mut lo, mut hi) = (0.0f64, (w - 1) as f64);
        let mut empty = false;
        for ci in &c {
            let k = (ci[0] + ci[2] * yf) / area2; // λ at x = 0
            let slope = ci[1] / area2;
            if slope.abs() < 1e-15 {
                empty |= k < -eps;
            } else if slope > 0.0 {
                lo = lo.max((-eps - k) / slope);
            } else {
                hi = hi.min((-eps - k) / slope);
            }
        }
        if empty || lo > hi {
            continue;
        }
        let (x0, x1) = (lo.ceil() as i64, hi.floor() as i64);
        for x in x0.max(0)..=x1.min(w - 1) {
            let xf = x as f64;
            let l = c.map(|ci| (ci[0] + ci[1] * xf + ci[2] * yf) / area2);
            let i = y as usize * f.width + x as usize;
            f.dx[i] = (l[0] * val[0][0] + l[1] * val[1][0] + l[2] * val[2][0]) as f32;
            f.dy[i] = (l[0] * val[0][1] + l[1] * val[1][1] + l[2] * val[2][1]) as f32;
        }
    }
}

fn fill_collinear(tri: &DelaunayTriangulation<Vertex>, f: &mut Field) {
    let mut pts: Vec<(f64, [f64; 2])> =
        tri.vertices().map(|v| (v.position().x + v.position().y, v.data().value)).collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    for y in 0..f.height {
        for x in 0..f.width {
            let t = (x + y) as f64;
            let k = pts.partition_point(|p| p.0 <= t);
            let v = if k == 0 {
                pts[0].1
            } else if k == pts.len() {
                pts[k - 1].1
            } else {
                let (a, b) = (pts[k - 1], pts[k]);
                let s = (t - a.0) / (b.0 - a.0);
                [a.1[0] + s * (b.1[0] - a.1[0]), a.1[1] + s * (b.1[1] - a.1[1])]
            };
            let i = y * f.width + x;
            f.dx[i] = v[0] as f32;
            f.dy[i] = v[1] as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(samples: &[Sample], w: usize, h: usize) -> Field {
        triangulation_field(samples, w, h, &mut MethodReport::default()).unwrap()
    }

    #[test]
    fn exact_at_samples_and_zero_at_corners() {
        let samples = [
            Sample { rest: [10.0, 12.0], displacement: [3.0, -1.0] },
            Sample { rest: [30.0, 20.0], displacement: [-2.0, 4.0] },
            Sample { rest: [18.0, 33.0], displacement: [0.5, 0.25] },
        ];
        let f = run(&samples, 41, 41);
        for s in &samples {
            let v = f.at(s.rest[0] as usize, s.rest[1] as usize);
            assert_eq!([v[0] as f64, v[1] as f64], s.displacement);
        }
        for (x, y) in [(0, 0), (40, 0), (0, 40), (40, 40)] {
            assert_eq!(f.at(x, y), [0.0, 0.0]);
        }
    }

    #[test]
    fn linear_inside_each_triangle() {
        // Samples of a linear function everywhere (corners included): the triangulation
        // reproduces it on every pixel, whatever the triangles are.
        let lin = |x: f64, y: f64| [0.25 * x - 0.5 * y + 3.0, 0.1 * x + 0.2 * y - 1.0];
        let mut samples: Vec<Sample> = [[0.0, 0.0], [63.0, 0.0], [0.0, 47.0], [63.0, 47.0], [20.0, 9.0], [41.0, 30.5], [7.3, 40.1]]
            .iter()
            .map(|p| Sample { rest: *p, displacement: lin(p[0], p[1]) })
            .collect();
        samples.push(Sample { rest: [50.0, 12.0], displacement: lin(50.0, 12.0) });
        let f = run(&samples, 64, 48);
        for y in 0..48 {
            for x in 0..64 {
                let want = lin(x as f64, y as f64);
                let got = f.at(x, y);
                assert!((got[0] as f64 - want[0]).abs() < 1e-4 && (got[1] as f64 - want[1]).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn one_sample_makes_a_tent_linear_along_each_edge() {
        let s = [Sample { rest: [8.0, 8.0], displacement: [4.0, 0.0] }];
        let f = run(&s, 17, 17);
        // Along the diagonal to a corner the tent falls linearly.
        for k in 0..=8 {
            let v = f.at(k, k)[0];
            assert!((v - 4.0 * k as f32 / 8.0).abs() < 1e-5, "{k}: {v}");
        }
        // Every pixel got a value (no gaps between triangles): the tent is positive
        // everywhere off the border.
        for y in 1..16 {
            for x in 1..16 {
                assert!(f.at(x, y)[0] > 0.0, "pixel ({x}, {y}) left empty");
            }
        }
    }

    #[test]
    fn one_pixel_wide_image() {
        let s = [Sample { rest: [0.0, 2.0], displacement: [1.0, 1.0] }];
        let f = run(&s, 1, 5);
        assert_eq!(f.at(0, 2), [1.0, 1.0]);
        assert_eq!(f.at(0, 1), [0.5, 0.5]);
        assert_eq!(f.at(0, 4), [0.0, 0.0]);
    }
}

//! Sampling properties: spacing along the rest curve, vertices kept, partners by
//! parameter, closed curves, region interiors, errors.

use proptest::prelude::*;

use super::*;

fn dist(a: Point, b: Point) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn opts(closed: bool, spacing_px: f64) -> SampleOptions {
    SampleOptions {
        closed,
        spline_outline: false,
        spacing_px,
    }
}

fn points_strategy(min: usize, max: usize) -> impl Strategy<Value = Vec<Point>> {
    prop::collection::vec(
        (-50.0..150.0f64, -50.0..150.0f64).prop_map(|(x, y)| [x, y]),
        min..max,
    )
}

/// Random star-shaped (hence simple) polygon around `c`, counter-clockwise.
fn star_polygon(radii: &[f64], c: Point) -> Vec<Point> {
    let n = radii.len();
    radii
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let a = std::f64::consts::TAU * (i as f64 + 0.3) / n as f64;
            [c[0] + r * a.cos(), c[1] + r * a.sin()]
        })
        .collect()
}

/// The curve parameters and the rest curve of a polyline or spline sampling.
fn params(rest: &[Point], closed: bool, spline: bool, h: f64) -> (Curve, Vec<CurveParameter>) {
    let c = Curve::new(rest, closed, spline);
    let p = c.sample_parameters(h);
    (c, p)
}

/// Arc length along `c` from parameter `p` to the next parameter `q` (which is on the
/// same span, or starts the next span, or is the first one of a closed curve).
fn arc_between(c: &Curve, p: CurveParameter, q: CurveParameter) -> f64 {
    if p.span == q.span && q.u >= p.u {
        c.arc_length(p.span, p.u, q.u)
    } else {
        let mut len = c.arc_length(p.span, p.u, 1.0);
        let mut s = (p.span + 1) % c.span_count();
        while s != q.span {
            len += c.span_length(s);
            s = (s + 1) % c.span_count();
        }
        len + c.arc_length(q.span, 0.0, q.u)
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn spacing_along_the_rest_curve_is_at_most_h(
        rest in points_strategy(2, 7), closed: bool, spline: bool, h in 0.3..4.0f64,
    ) {
        let (c, ps) = params(&rest, closed, spline, h);
        let mut pairs: Vec<(CurveParameter, CurveParameter)> = ps.windows(2).map(|w| (w[0], w[1])).collect();
        if closed {
            pairs.push((*ps.last().unwrap(), ps[0]));
        }
        for (p, q) in pairs {
            let arc = arc_between(&c, p, q);
            prop_assert!(arc <= h * (1.0 + 1e-9), "arc {} > h {} between {:?} and {:?}", arc, h, p, q);
        }
        // and no more samples than needed: each span has ⌈len/h⌉ pieces
        let expected: usize = (0..c.span_count()).map(|s| ((c.span_length(s) / h).ceil() as usize).max(1)).sum::<usize>()
            + usize::from(!closed);
        prop_assert!(ps.len() <= expected + c.span_count(), "{} samples for {} expected", ps.len(), expected);
    }

    #[test]
    fn every_vertex_and_end_point_is_a_sample(
        rest in points_strategy(2, 7), closed: bool, spline: bool, h in 0.3..4.0f64,
    ) {
        let kind = if spline { Kind::Spline } else { Kind::Polyline };
        let samples = sample_feature(kind, &rest, &rest, &opts(closed, h), None).unwrap();
        for v in &rest {
            // exactly: the spline passes through its control points
            prop_assert!(samples.iter().any(|s| s.rest == *v), "vertex {:?} missing", v);
        }
        prop_assert_eq!(samples[0].rest, rest[0]);
        if !closed {
            prop_assert_eq!(samples.last().unwrap().rest, *rest.last().unwrap());
        }
        // the pose equal to the rest moves nothing
        prop_assert!(samples.iter().all(|s| s.displacement == [0.0, 0.0]));
    }

    #[test]
    fn polyline_partners_have_the_same_fraction_of_their_segment(
        rest in points_strategy(2, 6), pose_offsets in points_strategy(6, 7), closed: bool, h in 0.5..3.0f64,
    ) {
        let pose: Vec<Point> = rest.iter().zip(&pose_offsets).map(|(r, o)| [r[0] + 0.3 * o[0], r[1] - 0.2 * o[1]]).collect();
        let (c, ps) = params(&rest, closed, false, h);
        let posed = Curve::polyline(&pose, closed);
        let samples = sample_feature(Kind::Polyline, &rest, &pose, &opts(closed, h), None).unwrap();
        prop_assert_eq!(samples.len(), ps.len());
        for (s, p) in samples.iter().zip(&ps) {
            let a = rest[p.span];
            let b = rest[(p.span + 1) % rest.len()];
            let a2 = pose[p.span];
            let b2 = pose[(p.span + 1) % pose.len()];
            // the sample is at fraction u of its rest segment ...
            prop_assert!(dist(s.rest, [a[0] + p.u * (b[0] - a[0]), a[1] + p.u * (b[1] - a[1])]) < 1e-9);
            // ... and its partner at fraction u of the posed segment
            let partner = [s.rest[0] + s.displacement[0], s.rest[1] + s.displacement[1]];
            prop_assert!(dist(partner, [a2[0] + p.u * (b2[0] - a2[0]), a2[1] + p.u * (b2[1] - a2[1])]) < 1e-9);
            prop_assert!(dist(partner, posed.point_at(p.span, p.u)) < 1e-9);
            let _ = &c;
        }
    }

    #[test]
    fn spline_partners_share_span_and_parameter(
        rest in points_strategy(3, 6), dx in -20.0..20.0f64, dy in -20.0..20.0f64, closed: bool,
    ) {
        // a translated pose: every partner is the sample moved by the translation
        let pose: Vec<Point> = rest.iter().map(|r| [r[0] + dx, r[1] + dy]).collect();
        let samples = sample_feature(Kind::Spline, &rest, &pose, &opts(closed, 1.0), None).unwrap();
        for s in &samples {
            prop_assert!((s.displacement[0] - dx).abs() < 1e-9 && (s.displacement[1] - dy).abs() < 1e-9);
        }
        // a deformed pose: partners are the posed curve's points at the same parameters
        let pose2: Vec<Point> = rest.iter().enumerate().map(|(i, r)| [r[0] + 3.0 * i as f64, r[1] * 0.8]).collect();
        let (c, ps) = params(&rest, closed, true, 1.0);
        let posed = Curve::spline(&pose2, closed);
        let samples = sample_feature(Kind::Spline, &rest, &pose2, &opts(closed, 1.0), None).unwrap();
        for (s, p) in samples.iter().zip(&ps) {
            prop_assert_eq!(s.rest, c.point_at(p.span, p.u));
            let partner = [s.rest[0] + s.displacement[0], s.rest[1] + s.displacement[1]];
            prop_assert!(dist(partner, posed.point_at(p.span, p.u)) < 1e-9);
        }
    }

    #[test]
    fn centripetal_spans_match_barry_goldman(pts in points_strategy(4, 5), u in 0.0..1.0f64) {
        // Barry–Goldman pyramid on knots t_{j+1} = t_j + |P_{j+1} − P_j|^½
        let (p0, p1, p2, p3) = (pts[0], pts[1], pts[2], pts[3]);
        let t0 = 0.0;
        let t1 = t0 + dist(p0, p1).sqrt();
        let t2 = t1 + dist(p1, p2).sqrt();
        let t3 = t2 + dist(p2, p3).sqrt();
        prop_assume!(t1 - t0 > 1e-3 && t2 - t1 > 1e-3 && t3 - t2 > 1e-3);
        let lerp = |a: Point, b: Point, ta: f64, tb: f64, t: f64| {
            let s = (t - ta) / (tb - ta);
            [a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])]
        };
        let t = t1 + u * (t2 - t1);
        let a1 = lerp(p0, p1, t0, t1, t);
        let a2 = lerp(p1, p2, t1, t2, t);
        let a3 = lerp(p2, p3, t2, t3, t);
        let b1 = lerp(a1, a2, t0, t2, t);
        let b2 = lerp(a2, a3, t1, t3, t);
        let want = lerp(b1, b2, t1, t2, t);
        let got = Curve::spline(&pts, false).point_at(1, u);
        prop_assert!(dist(got, want) < 1e-8 * (1.0 + dist(p1, p2)), "{:?} vs {:?}", got, want);
    }

    #[test]
    fn polyline_region_interior_follows_any_affine_map(
        radii in prop::collection::vec(8.0..30.0f64, 3..9),
        m in (0.5..1.5f64, -0.5..0.5f64, -0.5..0.5f64, 0.5..1.5f64, -10.0..10.0f64, -10.0..10.0f64),
    ) {
        let rest = star_polygon(&radii, [32.3, 31.7]);
        let f = |p: Point| [m.0 * p[0] + m.1 * p[1] + m.4, m.2 * p[0] + m.3 * p[1] + m.5];
        let pose: Vec<Point> = rest.iter().map(|&p| f(p)).collect();
        let grid = Grid::new(64, 64);
        let samples = sample_feature(Kind::Region, &rest, &pose, &opts(false, 1.0), Some(&grid)).unwrap();
        let interior = samples.iter().filter(|s| s.rest[0].fract() == 0.0 && s.rest[1].fract() == 0.0).count();
        prop_assert!(interior > 0);
        for s in &samples {
            let want = f(s.rest);
            prop_assert!((s.rest[0] + s.displacement[0] - want[0]).abs() < 1e-9);
            prop_assert!((s.rest[1] + s.displacement[1] - want[1]).abs() < 1e-9);
        }
    }

    #[test]
    fn spline_region_interior_follows_a_similarity(
        radii in prop::collection::vec(8.0..30.0f64, 3..9),
        angle in -3.0..3.0f64, scale in 0.5..2.0f64, tx in -10.0..10.0f64, ty in -10.0..10.0f64,
    ) {
        let rest = star_polygon(&radii, [32.3, 31.7]);
        let (c, s) = (scale * angle.cos(), scale * angle.sin());
        let f = |p: Point| [c * p[0] - s * p[1] + tx, s * p[0] + c * p[1] + ty];
        let pose: Vec<Point> = rest.iter().map(|&p| f(p)).collect();
        let grid = Grid::new(64, 64);
        let o = SampleOptions { closed: false, spline_outline: true, spacing_px: 1.0 };
        let samples = sample_feature(Kind::Region, &rest, &pose, &o, Some(&grid)).unwrap();
        for smp in &samples {
            let want = f(smp.rest);
            prop_assert!((smp.rest[0] + smp.displacement[0] - want[0]).abs() < 1e-8);
            prop_assert!((smp.rest[1] + smp.displacement[1] - want[1]).abs() < 1e-8);
        }
    }

    #[test]
    fn mvc_at_outline_points_is_the_outline_value(
        radii in prop::collection::vec(5.0..30.0f64, 3..9), vals in points_strategy(9, 10), s in 0.0..1.0f64,
    ) {
        let poly = star_polygon(&radii, [0.0, 0.0]);
        let vals = &vals[..poly.len()];
        for i in 0..poly.len() {
            prop_assert_eq!(mean_value_interpolate(&poly, vals, poly[i]), vals[i]);
            let j = (i + 1) % poly.len();
            let x = [poly[i][0] + s * (poly[j][0] - poly[i][0]), poly[i][1] + s * (poly[j][1] - poly[i][1])];
            let want = [vals[i][0] + s * (vals[j][0] - vals[i][0]), vals[i][1] + s * (vals[j][1] - vals[i][1])];
            let got = mean_value_interpolate(&poly, vals, x);
            prop_assert!(dist(got, want) < 1e-9 * (1.0 + dist(vals[i], vals[j])), "{:?} vs {:?}", got, want);
        }
    }
}

#[test]
fn midpoint_of_a_segment_maps_to_the_midpoint_of_the_posed_segment() {
    let rest = [[0.0, 0.0], [10.0, 0.0], [10.0, 6.0]];
    let pose = [[5.0, 5.0], [5.0, 25.0], [-1.0, 25.0]];
    let samples = sample_feature(Kind::Polyline, &rest, &pose, &opts(false, 1.0), None).unwrap();
    let mid = samples.iter().find(|s| s.rest == [5.0, 0.0]).unwrap();
    assert_eq!(mid.displacement, [0.0, 15.0]); // partner (5, 15)
    let mid2 = samples.iter().find(|s| s.rest == [10.0, 3.0]).unwrap();
    assert_eq!(mid2.displacement, [-8.0, 22.0]); // partner (2, 25)
    assert_eq!(samples.len(), 10 + 6 + 1);
}

#[test]
fn closed_polyline_wraps_through_its_closing_segment() {
    let square = [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]];
    let samples = sample_feature(Kind::Polyline, &square, &square, &opts(true, 1.0), None).unwrap();
    assert_eq!(samples.len(), 16);
    assert_eq!(samples[15].rest, [0.0, 1.0]);
    let open = sample_feature(Kind::Polyline, &square, &square, &opts(false, 1.0), None).unwrap();
    assert_eq!(open.len(), 13);
    assert_eq!(open[12].rest, [0.0, 4.0]);
}

#[test]
fn closed_spline_is_smooth_at_its_first_point() {
    let pts = [[0.0, 0.0], [20.0, -5.0], [25.0, 15.0], [3.0, 20.0]];
    let c = Curve::spline(&pts, true);
    let last = c.span_count() - 1;
    let e = 1e-6;
    let before = c.point_at(last, 1.0 - e);
    let after = c.point_at(0, e);
    let start = c.point_at(0, 0.0);
    // the direction in equals the direction out: C¹ in shape through the wrap
    let din = [(start[0] - before[0]) / e, (start[1] - before[1]) / e];
    let dout = [(after[0] - start[0]) / e, (after[1] - start[1]) / e];
    let cos =
        (din[0] * dout[0] + din[1] * dout[1]) / ((din[0].hypot(din[1])) * dout[0].hypot(dout[1]));
    assert!(cos > 1.0 - 1e-6, "cos {cos}");
}

#[test]
fn point_and_cut() {
    let s = sample_feature(
        Kind::Point,
        &[[3.5, 2.0]],
        &[[4.0, 0.0]],
        &SampleOptions::default(),
        None,
    )
    .unwrap();
    assert_eq!(
        s,
        vec![Sample {
            rest: [3.5, 2.0],
            displacement: [0.5, -2.0]
        }]
    );
    let cut = [[0.0, 0.0], [9.0, 9.0]];
    assert!(
        sample_feature(Kind::Cut, &cut, &cut, &SampleOptions::default(), None)
            .unwrap()
            .is_empty()
    );
}

#[test]
fn region_samples_outline_then_strict_interior_on_active_nodes() {
    let rest = [[1.0, 1.0], [5.0, 1.0], [5.0, 5.0], [1.0, 5.0]];
    let pose = [[2.0, 1.0], [6.0, 1.0], [6.0, 5.0], [2.0, 5.0]];
    let mut grid = Grid::new(8, 8);
    let i = grid.index(3, 3);
    grid.active[i] = false;
    let s = sample_feature(
        Kind::Region,
        &rest,
        &pose,
        &SampleOptions::default(),
        Some(&grid),
    )
    .unwrap();
    assert_eq!(s.len(), 16 + 8);
    let interior: Vec<Point> = s[16..].iter().map(|s| s.rest).collect();
    assert_eq!(
        interior,
        vec![
            [2.0, 2.0],
            [3.0, 2.0],
            [4.0, 2.0],
            [2.0, 3.0],
            [4.0, 3.0],
            [2.0, 4.0],
            [3.0, 4.0],
            [4.0, 4.0]
        ]
    );
    assert!(s
        .iter()
        .all(|s| (s.displacement[0] - 1.0).abs() < 1e-12 && s.displacement[1].abs() < 1e-12));
}

#[test]
fn region_with_a_dense_spline_outline_matches_the_direct_mvc() {
    let rest = star_polygon(&[60.0, 80.0, 70.0, 90.0, 65.0, 85.0], [100.0, 100.0]);
    let pose: Vec<Point> = rest
        .iter()
        .enumerate()
        .map(|(i, p)| [p[0] + 5.0 * (i as f64).sin(), p[1] + 0.001 * p[0] * p[0]])
        .collect();
    let grid = Grid::new(200, 200);
    let o = SampleOptions {
        closed: false,
        spline_outline: true,
        spacing_px: 1.0,
    };
    let s = sample_feature(Kind::Region, &rest, &pose, &o, Some(&grid)).unwrap();
    let m = Curve::spline(&rest, true).sample_parameters(1.0).len();
    let outline = &s[..m];
    let poly: Vec<Point> = outline.iter().map(|s| s.rest).collect();
    let vals: Vec<Point> = outline.iter().map(|s| s.displacement).collect();
    let mut worst: f64 = 0.0;
    for smp in s[m..].iter().step_by(37) {
        let d = mean_value_interpolate(&poly, &vals, smp.rest);
        worst = worst.max(dist(d, smp.displacement));
    }
    assert!(worst < 1e-10, "{worst}");
}

#[test]
fn region_needs_a_domain_and_cut_or_point_do_not() {
    let tri = [[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]];
    let err =
        sample_feature(Kind::Region, &tri, &tri, &SampleOptions::default(), None).unwrap_err();
    assert_eq!(err, GeometryError::RegionWithoutDomain);
}

#[test]
fn error_messages() {
    let o = SampleOptions::default();
    let msg = |r: Result<Vec<Sample>, GeometryError>| r.unwrap_err().to_string();
    assert_eq!(
        msg(sample_feature(
            Kind::Spline,
            &[[0.0, 0.0]],
            &[[0.0, 0.0]],
            &o,
            None
        )),
        "A spline needs at least 2 control points, but its rest geometry has 1."
    );
    assert_eq!(
        msg(sample_feature(
            Kind::Region,
            &[[0.0, 0.0], [1.0, 0.0]],
            &[[0.0, 0.0], [1.0, 0.0]],
            &o,
            None
        )),
        "A region needs at least 3 control points, but its rest geometry has 2."
    );
    assert_eq!(
        msg(sample_feature(
            Kind::Point,
            &[[0.0, 0.0], [1.0, 1.0]],
            &[[0.0, 0.0], [1.0, 1.0]],
            &o,
            None
        )),
        "A point feature has exactly one position, but its rest geometry has 2."
    );
    assert_eq!(
        msg(sample_feature(
            Kind::Polyline,
            &[[0.0, 0.0], [1.0, 1.0]],
            &[[0.0, 0.0]],
            &o,
            None
        )),
        "The posed geometry has 1 control points but the rest geometry has 2; \
         a pose must move the same control points the rest geometry has."
    );
    assert_eq!(
        msg(sample_feature(Kind::Polyline, &[[0.0, 0.0], [1.0, 1.0]], &[[0.0, 0.0], [f64::NAN, 1.0]], &o, None)),
        "Control point 1 of the posed geometry is (NaN, 1); every coordinate must be a finite number."
    );
    assert_eq!(
        msg(sample_feature(
            Kind::Polyline,
            &[[0.0, 0.0], [1.0, 1.0]],
            &[[0.0, 0.0], [1.0, 1.0]],
            &opts(false, 0.0),
            None
        )),
        "The sample spacing is 0 px; it must be a positive, finite number of pixels."
    );
    assert_eq!(
        msg(sample_feature(Kind::Region, &[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], &[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], &o, None)),
        "A region needs the grid (the image's width and height, and its matte) to find the nodes inside its outline, but none was given."
    );
    assert_eq!(
        "blob".parse::<Kind>().unwrap_err().to_string(),
        "Unknown feature kind \"blob\"; the kinds are point, polyline, spline, region and cut."
    );
}

#[test]
fn curve_polyline_by_kind() {
    let pts = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]];
    assert_eq!(
        curve_polyline(Kind::Polyline, &pts, false, false, 1.0),
        pts.to_vec()
    );
    assert_eq!(
        curve_polyline(Kind::Cut, &pts, false, false, 1.0),
        pts.to_vec()
    );
    assert_eq!(
        curve_polyline(Kind::Point, &pts[..1], false, false, 1.0),
        pts[..1].to_vec()
    );
    let closed = curve_polyline(Kind::Polyline, &pts, true, false, 1.0);
    assert_eq!(closed.len(), 4);
    assert_eq!(closed[3], closed[0]);
    let spline = curve_polyline(Kind::Spline, &pts, false, false, 0.5);
    assert!(spline.len() > 40);
    assert_eq!(spline[0], pts[0]);
    assert_eq!(*spline.last().unwrap(), pts[2]);
    assert!(spline.contains(&pts[1]));
    for w in spline.windows(2) {
        assert!(dist(w[0], w[1]) <= 0.5 + 1e-12);
    }
    let outline = curve_polyline(Kind::Region, &pts, false, true, 1.0);
    assert_eq!(outline[0], *outline.last().unwrap());
    // a bad spacing falls back to 1 px rather than looping forever
    assert_eq!(
        curve_polyline(Kind::Spline, &pts, false, false, 0.0),
        curve_polyline(Kind::Spline, &pts, false, false, 1.0)
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn feature_sampler_matches_sample_feature(
        radii in prop::collection::vec(6.0..25.0f64, 3..8),
        wobble in prop::collection::vec((-6.0..6.0f64, -6.0..6.0f64), 8),
        kind in prop_oneof![Just(Kind::Point), Just(Kind::Polyline), Just(Kind::Spline), Just(Kind::Region), Just(Kind::Cut)],
        closed: bool, spline_outline: bool, small_limit: bool,
    ) {
        let mut rest = star_polygon(&radii, [30.2, 29.6]);
        if kind == Kind::Point {
            rest.truncate(1);
        }
        let pose: Vec<Point> = rest.iter().zip(&wobble).map(|(p, w)| [p[0] + w.0, p[1] + w.1 + 0.01 * p[0] * p[0]]).collect();
        let o = SampleOptions { closed, spline_outline, spacing_px: 1.0 };
        let grid = Grid::new(60, 60);
        let limit = if small_limit { 10 } else { usize::MAX };
        let sampler = FeatureSampler::with_limit(kind, &rest, &o, Some(&grid), limit).unwrap();
        let fast = sampler.sample(&pose).unwrap();
        let slow = sample_feature(kind, &rest, &pose, &o, Some(&grid)).unwrap();
        prop_assert_eq!(fast.len(), slow.len());
        prop_assert_eq!(fast.len(), sampler.len());
        let scale = slow.iter().map(|s| s.displacement[0].abs().max(s.displacement[1].abs())).fold(1.0, f64::max);
        for (a, b) in fast.iter().zip(&slow) {
            prop_assert_eq!(a.rest, b.rest);
            prop_assert!(dist(a.displacement, b.displacement) < 1e-6 * scale, "{:?} vs {:?}", a, b);
        }
    }
}

#[test]
fn feature_sampler_checks_its_poses() {
    let rest = [[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]];
    let s = FeatureSampler::new(Kind::Spline, &rest, &SampleOptions::default(), None).unwrap();
    assert_eq!(
        s.sample(&rest[..2]).unwrap_err(),
        GeometryError::CountMismatch { rest: 3, pose: 2 }
    );
    let bad = [[0.0, 0.0], [5.0, f64::INFINITY], [5.0, 5.0]];
    assert!(matches!(
        s.sample(&bad).unwrap_err(),
        GeometryError::NonFinite { index: 1, .. }
    ));
    assert_eq!(
        FeatureSampler::new(Kind::Region, &rest, &SampleOptions::default(), None).unwrap_err(),
        GeometryError::RegionWithoutDomain
    );
}

#[test]
fn control_points_beyond_the_coordinate_limit_are_refused() {
    // A spline through (0, -1e308) overflowed to non-finite samples.
    let pts = [[0.0, -1e308], [-94.0, -1e308]];
    let err = sample_feature(Kind::Spline, &pts, &pts, &SampleOptions::default(), None).unwrap_err();
    assert!(matches!(err, GeometryError::OutOfRange { index: 0, .. }), "{err:?}");
    assert!(err.to_string().contains("within ±1e6 px"), "{err}");
}

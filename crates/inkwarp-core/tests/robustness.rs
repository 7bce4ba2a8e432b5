//! Bad input ends in an error, never a panic, an abort or a hang: the cases found by
//! probing the engine (issue 45), and property tests of the scene parser and the sampler.

use inkwarp_core::geometry::{sample_feature, Kind, SampleOptions};
use inkwarp_core::scene::{no_files, Scene};
use proptest::prelude::*;

fn scene(extra: &str) -> String {
    format!(
        r#"{{"inkwarp": 1, "width": 16, "height": 12, "layers": [{{"name": "main"}}],
            "features": [{{"id": "a", "kind": "point", "rest": [[4, 4]],
                          "keys": [{{"t": 0, "points": [[4, 4]]}}, {{"t": 1, "points": [[6, 5]]}}]}}]
            {extra}}}"#
    )
}

/// The scene's problems as "path: message" lines (empty when it loads).
fn problems(text: &str) -> String {
    match Scene::from_json(text, &mut no_files) {
        Ok(_) => String::new(),
        Err(err) => err.problems.iter().map(|p| format!("{}: {}\n", p.path, p.message)).collect(),
    }
}

#[test]
fn each_probed_case_is_a_clear_problem() {
    let cases = [
        (r#", "solver": {"tension": 1e300}"#, "solver.tension: the tension must be a number from 0 to 1e6, found 1e300"),
        (r#", "solver": {"method": "beier-neely", "beier_neely": {"b": 1e308}}"#, "solver.beier_neely.b"),
        (r#", "duration": 1e308"#, "duration: the duration may be at most 100000 s"),
        (r#", "fps": 1e9"#, "fps: frames per second must be a number from 0.001 (one frame every 1000 s) to 1000, found 1000000000.0"),
    ];
    for (extra, expected) in cases {
        let found = problems(&scene(extra));
        assert!(found.contains(expected), "{extra}: {found}");
    }
    let text = scene("").replace("[[4, 4]],\n", "[[18446744073709551616, 4]],\n");
    assert!(problems(&text).contains("features[0].rest[0][0]: coordinates may be at most 1e6"), "{}", problems(&text));
    let text = scene("").replace(r#"{"t": 1, "#, r#"{"t": 1e308, "#);
    assert!(problems(&text).contains("features[0].keys[1].t: key times may be at most"));
    let text = scene("").replace(r#"{"t": 1, "#, r#"{"t": 1e-300, "#);
    assert!(problems(&text).contains("apart, closer than 1e-6 s"), "{}", problems(&text));
    let cut = r#"{"id": "c", "kind": "cut", "rest": [[1e308, 0], [-1e308, 5]]}"#;
    let text = scene("").replace(r#""features": ["#, &format!(r#""features": [{cut}, "#));
    assert!(problems(&text).contains("features[0].rest[0][0]"), "{}", problems(&text));
    let poly = r#"{"id": "p", "kind": "polyline", "rest": [[0, 0], [1e8, 1e8]]}"#;
    let text = scene("").replace(r#""features": ["#, &format!(r#""features": [{poly}, "#));
    assert!(problems(&text).contains("features[0].rest[1][0]"));
    let big = scene("").replace(r#""width": 16, "height": 12"#, r#""width": 100000, "height": 100000"#);
    assert!(problems(&big).contains("width: the canvas is 100000×100000 pixels"));
}

#[test]
fn a_long_curve_at_a_fine_spacing_is_refused() {
    let rest = [[0.0, 0.0], [1e6, 1e6]];
    let opts = SampleOptions { spacing_px: 1e-3, ..SampleOptions::default() };
    let err = sample_feature(Kind::Polyline, &rest, &rest, &opts, None).unwrap_err();
    assert!(err.to_string().contains("use a larger spacing"), "{err}");
}

fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        -100.0..100.0f64,
        Just(0.0),
        Just(1e-300),
        Just(1e308),
        Just(-1e308),
        Just(1e6),
        Just(1e7),
        Just(18446744073709551616.0),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, failure_persistence: None, ..ProptestConfig::default() })]

    /// Any scene built from awkward numbers either loads and renders a frame, or gives
    /// problems; it never panics, and what validates also renders.
    #[test]
    fn the_parser_never_panics(
        w in 1u32..40, h in 1u32..40, fps in number(), t in number(), x in number(),
        y in number(), tension in number(), kind in 0usize..5, closed in any::<bool>(),
    ) {
        let kinds = ["point", "polyline", "spline", "region", "cut"];
        let rest = if kind == 0 { format!("[[{x}, {y}]]") } else { format!("[[1, 1], [{x}, {y}], [3, 7]]") };
        let key_points = if kind == 0 { "[[2, 2]]".to_string() } else { "[[1, 1], [2, 2], [3, 3]]".to_string() };
        let closed = if kind == 1 || kind == 2 { format!(r#", "closed": {closed}"#) } else { String::new() };
        let text = format!(
            r#"{{"inkwarp": 1, "width": {w}, "height": {h}, "fps": {fps:e},
                "solver": {{"tension": {tension:e}}}, "layers": [{{"name": "m"}}],
                "features": [{{"id": "f", "kind": "{}", "rest": {rest}{closed},
                               "keys": [{{"t": 0, "points": {key_points}}}, {{"t": {t:e}, "points": {key_points}}}]}}]}}"#,
            kinds[kind]
        );
        if let Ok(scene) = Scene::from_json(&text, &mut no_files) {
            prop_assert!(scene.frame_count() >= 1);
            let frame = scene.render(scene.frame_time_s(scene.frame_count() / 2));
            prop_assert!(frame.is_ok(), "validated but did not render: {text}: {:?}", frame.err());
        }
    }

    /// The sampler gives finite samples or an error for any control points and spacing.
    #[test]
    fn the_sampler_never_panics(
        pts in prop::collection::vec((number(), number()), 1..6),
        spacing in prop_oneof![Just(1e-9), Just(0.5), Just(1.0), Just(1e308), 0.01..10.0f64],
        kind in 0usize..3, closed in any::<bool>(),
    ) {
        let kind = [Kind::Point, Kind::Polyline, Kind::Spline][kind];
        let points: Vec<[f64; 2]> = pts.iter().map(|&(x, y)| [x, y]).collect();
        let opts = SampleOptions { closed, spacing_px: spacing, ..SampleOptions::default() };
        if let Ok(samples) = sample_feature(kind, &points, &points, &opts, None) {
            for s in samples {
                prop_assert!(s.rest.iter().chain(&s.displacement).all(|v| v.is_finite()));
            }
        }
    }
}

use std::collections::HashMap;
use std::sync::Arc;

use base64::Engine as _;
use serde_json::{json, Value};

use super::*;
use crate::solve::Stop;

/// PNG bytes of an RGBA image.
fn png(width: u32, height: u32, pixels: &[u8]) -> Vec<u8> {
    let mut bytes = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut bytes),
        pixels,
        width,
        height,
        image::ExtendedColorType::Rgba8,
    )
    .unwrap();
    bytes
}

/// A `width × height` picture: a red-to-green gradient, opaque except `holes`.
fn picture(width: u32, height: u32, hole: impl Fn(u32, u32) -> bool) -> Vec<u8> {
    let mut pixels = Vec::new();
    for y in 0..height {
        for x in 0..width {
            let a = if hole(x, y) { 0 } else { 255 };
            pixels.extend_from_slice(&[
                (x * 255 / width.max(1)) as u8,
                (y * 255 / height.max(1)) as u8,
                64,
                a,
            ]);
        }
    }
    png(width, height, &pixels)
}

fn data_uri(bytes: &[u8]) -> String {
    format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A loader over in-memory files.
fn files(entries: &[(&str, Vec<u8>)]) -> impl FnMut(&str) -> Result<Vec<u8>, String> {
    let map: HashMap<String, Vec<u8>> = entries
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect();
    move |reference: &str| {
        map.get(reference)
            .cloned()
            .ok_or_else(|| format!("no such file \"{reference}\""))
    }
}

fn valid_scene() -> Value {
    json!({
        "inkwarp": 1,
        "fps": 10,
        "duration": 1.0,
        "layers": [
            {"name": "back", "image": "back.png"},
            {"name": "front", "image": "front.png", "features": ["dot", "lid"], "offset": [1, 0]}
        ],
        "features": [
            {"id": "dot", "kind": "point", "rest": [[4, 4]],
             "keys": [{"t": 0, "points": [[4, 4]]}, {"t": 1, "points": [[6, 5]], "interpolation": "linear"}]},
            {"id": "lid", "kind": "spline", "rest": [[8, 2], [10, 3], [12, 2]],
             "keys": [{"t": 0, "points": [[8, 2], [10, 3], [12, 2]]},
                      {"t": 0.5, "points": [[8, 2], [10, 5], [12, 2]]}]},
            {"id": "edge", "kind": "cut", "rest": [[2.5, 7.5], [8.5, 7.5]]}
        ]
    })
}

fn valid_files() -> Vec<(&'static str, Vec<u8>)> {
    vec![
        ("back.png", picture(16, 12, |_, _| false)),
        ("front.png", picture(16, 12, |x, y| x < 3 && y < 3)),
    ]
}

/// Every problem of a scene (with the valid files) as `path: message` lines.
fn problems_of(scene: &Value) -> Vec<String> {
    problems_with(scene, valid_files())
}

fn problems_with(scene: &Value, entries: Vec<(&'static str, Vec<u8>)>) -> Vec<String> {
    let mut loader = files(&entries);
    match Scene::from_json(&scene.to_string(), &mut loader) {
        Ok(_) => Vec::new(),
        Err(err) => err.problems.iter().map(|p| p.to_string()).collect(),
    }
}

/// `scene` with the value at JSON pointer `pointer` set (an object's key may be new).
fn with(mut scene: Value, pointer: &str, value: Value) -> Value {
    let (parent, key) = pointer.rsplit_once('/').unwrap();
    match scene
        .pointer_mut(parent)
        .unwrap_or_else(|| panic!("no {parent}"))
    {
        Value::Object(map) => {
            map.insert(key.to_string(), value);
        }
        Value::Array(items) => items[key.parse::<usize>().unwrap()] = value,
        _ => panic!("{parent} is not a container"),
    }
    scene
}

fn paths_of(scene: &Value) -> Vec<String> {
    let mut loader = files(&valid_files());
    match Scene::from_json(&scene.to_string(), &mut loader) {
        Ok(_) => Vec::new(),
        Err(err) => err.problems.into_iter().map(|p| p.path).collect(),
    }
}

#[test]
fn the_valid_scene_resolves() {
    let mut loader = files(&valid_files());
    let scene = Scene::from_json(&valid_scene().to_string(), &mut loader).unwrap();
    assert_eq!(
        (scene.width(), scene.height(), scene.frame_count()),
        (16, 12, 10)
    );
    assert_eq!(scene.layers().len(), 2);
    assert_eq!(scene.layers()[0].drivers, vec![0, 1]);
    assert_eq!(scene.layers()[1].drivers, vec![0, 1]);
    // The cut breaks the back layer's links across y = 8 between x = 3 and x = 8 only.
    let back = &scene.layers()[0].grid;
    assert!(!back.link_down[back.index(4, 7)]);
    assert!(back.link_down[back.index(12, 7)]);
    // The front layer is not cut (it does not list the cut) but has a hole from its alpha.
    let front = &scene.layers()[1].grid;
    assert!(front.link_down[front.index(4, 7)]);
    assert!(!front.active[front.index(1, 1)]);
}

#[test]
fn every_kind_of_mistake_is_reported_with_its_path() {
    let cases: Vec<(&str, Value, &str)> = vec![
        (
            "unknown kind",
            with(valid_scene(), "/features/0/kind", json!("circle")),
            "features[0].kind",
        ),
        (
            "wrong key count",
            with(valid_scene(), "/features/1/keys/0/points", json!([[1, 1]])),
            "features[1].keys[0].points",
        ),
        (
            "too few points",
            with(
                valid_scene(),
                "/features/1",
                json!({"id": "lid", "kind": "spline", "rest": [[1, 1]]}),
            ),
            "features[1].rest",
        ),
        (
            "point with two points",
            with(
                valid_scene(),
                "/features/0",
                json!({"id": "dot", "kind": "point", "rest": [[1, 1], [2, 2]]}),
            ),
            "features[0].rest",
        ),
        (
            "keys out of order",
            with(valid_scene(), "/features/0/keys/1/t", json!(-1)),
            "features[0].keys[1].t",
        ),
        (
            "keys at equal times",
            with(valid_scene(), "/features/0/keys/1/t", json!(0)),
            "features[0].keys[1].t",
        ),
        (
            "unknown feature id",
            with(valid_scene(), "/layers/1/features/1", json!("lidd")),
            "layers[1].features[1]",
        ),
        (
            "duplicate feature id",
            with(valid_scene(), "/features/2/id", json!("dot")),
            "features[2].id",
        ),
        (
            "duplicate layer name",
            with(valid_scene(), "/layers/1/name", json!("back")),
            "layers[1].name",
        ),
        (
            "negative tension",
            with(valid_scene(), "/solver", json!({"tension": -1})),
            "solver.tension",
        ),
        (
            "zero tolerance",
            with(valid_scene(), "/solver", json!({"tolerance": 0})),
            "solver.tolerance",
        ),
        ("zero fps", with(valid_scene(), "/fps", json!(0)), "fps"),
        ("fps below the least", with(valid_scene(), "/fps", json!(1e-9)), "fps"),
        (
            "negative duration",
            with(valid_scene(), "/duration", json!(-2)),
            "duration",
        ),
        (
            "zero grid step",
            with(valid_scene(), "/solver", json!({"grid_step": 0})),
            "solver.grid_step",
        ),
        (
            "fractional grid step",
            with(valid_scene(), "/solver", json!({"grid_step": 1.5})),
            "solver.grid_step",
        ),
        (
            "layer override",
            with(valid_scene(), "/layers/0/solver", json!({"tension": -0.5})),
            "layers[0].solver.tension",
        ),
        (
            "unknown method",
            with(valid_scene(), "/solver", json!({"method": "rbf"})),
            "solver.method",
        ),
        (
            "Beier–Neely a of 0",
            with(valid_scene(), "/solver", json!({"beier_neely": {"a": 0}})),
            "solver.beier_neely.a",
        ),
        (
            "negative Beier–Neely b",
            with(valid_scene(), "/solver", json!({"beier_neely": {"b": -1}})),
            "solver.beier_neely.b",
        ),
        (
            "unknown Beier–Neely key",
            with(valid_scene(), "/solver", json!({"beier_neely": {"q": 1}})),
            "solver.beier_neely.q",
        ),
        (
            "zero max_samples",
            with(valid_scene(), "/solver", json!({"tps_exact": {"max_samples": 0}})),
            "solver.tps_exact.max_samples",
        ),
        (
            "max_samples over the limit",
            with(valid_scene(), "/solver", json!({"tps_exact": {"max_samples": 100000}})),
            "solver.tps_exact.max_samples",
        ),
        (
            "layer override of Beier–Neely",
            with(valid_scene(), "/layers/1/solver", json!({"beier_neely": {"p": -0.5}})),
            "layers[1].solver.beier_neely.p",
        ),
        (
            "unknown key",
            with(valid_scene(), "/layers/0/colour", json!("red")),
            "layers[0].colour",
        ),
        (
            "unknown top-level key",
            with(valid_scene(), "/frames", json!(3)),
            "frames",
        ),
        (
            "wrong version",
            with(valid_scene(), "/inkwarp", json!(2)),
            "inkwarp",
        ),
        (
            "wrong type",
            with(valid_scene(), "/features/0/rest/0/0", json!("4")),
            "features[0].rest[0][0]",
        ),
        (
            "three coordinates",
            with(valid_scene(), "/features/0/rest/0", json!([1, 2, 3])),
            "features[0].rest[0]",
        ),
        (
            "missing image",
            with(valid_scene(), "/layers/0/image", json!("nope.png")),
            "layers[0].image",
        ),
        (
            "curve on a spline",
            with(valid_scene(), "/features/1/curve", json!("spline")),
            "features[1].curve",
        ),
        (
            "background out of range",
            with(valid_scene(), "/background", json!([0, 0, 0, 300])),
            "background[3]",
        ),
    ];
    for (what, scene, path) in cases {
        let paths = paths_of(&scene);
        assert_eq!(
            paths,
            vec![path.to_string()],
            "{what}: {:?}",
            problems_of(&scene)
        );
    }
}

#[test]
fn missing_required_keys_are_named() {
    let mut scene = valid_scene();
    scene["features"][0].as_object_mut().unwrap().remove("rest");
    scene.as_object_mut().unwrap().remove("inkwarp");
    assert_eq!(paths_of(&scene), vec!["features[0].rest", "inkwarp"]);
}

#[test]
fn every_problem_is_reported_at_once() {
    let mut scene = valid_scene();
    scene["fps"] = json!(0);
    scene["features"][0]["kind"] = json!("circle");
    scene["features"][1]["keys"][0]["points"] = json!([[1, 1]]);
    scene["layers"][1]["features"][0] = json!("nobody");
    scene["layers"][0]["colour"] = json!("red");
    scene["layers"][0]["image"] = json!("missing.png");
    insta::assert_snapshot!(problems_of(&scene).join("\n"));
}

#[test]
fn messages_say_how_to_fix() {
    let cases = [
        with(valid_scene(), "/features/0/kind", json!("splin")),
        with(valid_scene(), "/features/1/keys/0/points", json!([[1, 1]])),
        with(
            valid_scene(),
            "/features/1",
            json!({"id": "lid", "kind": "spline", "rest": [[1, 1]]}),
        ),
        with(valid_scene(), "/features/0/keys/1/t", json!(-1)),
        with(valid_scene(), "/features/0/keys/1/t", json!(0)),
        with(valid_scene(), "/layers/1/features/1", json!("lidd")),
        with(valid_scene(), "/features/2/id", json!("dot")),
        with(valid_scene(), "/solver", json!({"tension": -1})),
        with(valid_scene(), "/fps", json!(0)),
        with(valid_scene(), "/solver", json!({"grid_step": 0})),
        with(valid_scene(), "/solver", json!({"beier_neely": {"a": 0, "b": -1}})),
        with(valid_scene(), "/solver", json!({"beier_neely": {"weight": 2}})),
        with(valid_scene(), "/solver", json!({"tps_exact": {"max_samples": 0}})),
        with(valid_scene(), "/solver", json!({"tps_exact": {"max_samples": 9000}})),
        with(valid_scene(), "/layers/0/visibel", json!(false)),
        with(valid_scene(), "/inkwarp", json!(2)),
        with(valid_scene(), "/features/0/rest/0/0", json!("4")),
        with(valid_scene(), "/features/0/rest/0", json!([1, 2, 3])),
        with(valid_scene(), "/layers/0/image", json!("nope.png")),
        with(valid_scene(), "/layers", json!([])),
        json!([1, 2]),
    ];
    let text: Vec<String> = cases.iter().flat_map(problems_of).collect();
    insta::assert_snapshot!(text.join("\n"));
}

#[test]
fn syntax_errors_give_line_and_column() {
    let err = parse_doc("{\"inkwarp\": 1,\n \"layers\": [}").unwrap_err();
    assert_eq!(err.problems.len(), 1);
    insta::assert_snapshot!(err.to_string(), @"the scene is not valid JSON: expected value at line 2 column 13");
}

#[test]
fn image_problems() {
    // Different sizes: the first image sets the size when width/height are absent.
    let wrong_size = vec![
        ("back.png", picture(16, 12, |_, _| false)),
        ("front.png", picture(8, 8, |_, _| false)),
    ];
    let problems = problems_with(&valid_scene(), wrong_size);
    insta::assert_snapshot!(problems.join("\n"), @"layers[1].image: \"front.png\" is 8×8 pixels but the scene is 16×12 (from layers[0].image); every image and matte must be the scene's size");
    // Explicit width/height win.
    let scene = with(
        with(valid_scene(), "/width", json!(20)),
        "/height",
        json!(12),
    );
    assert_eq!(problems_of(&scene).len(), 2);
    // Unreadable bytes and mattes of the wrong size.
    let scene = with(valid_scene(), "/layers/0/continuity", json!("matte.png"));
    let mut entries = valid_files();
    entries.push(("matte.png", b"GIF89a....".to_vec()));
    let problems = problems_with(&scene, entries);
    insta::assert_snapshot!(problems.join("\n"), @r#"layers[0].continuity: cannot use "matte.png": a Gif image; inkwarp reads PNG and JPEG, save it as one of those"#);
    // A layered PSD given as a picture: `inkwarp new` is what reads it.
    let scene = with(valid_scene(), "/layers/0/image", json!("art.psd"));
    let mut entries = valid_files();
    entries.push(("art.psd", b"8BPS\x00\x01....".to_vec()));
    insta::assert_snapshot!(problems_with(&scene, entries).join("\n"), @r#"layers[0].image: cannot use "art.psd": a Photoshop PSD, not a PNG or JPEG image; save it, or each of its layers, as PNG"#);
    let scene = with(
        valid_scene(),
        "/layers/1/alpha",
        json!(data_uri(&picture(3, 3, |_, _| false))),
    );
    assert_eq!(paths_of(&scene), vec!["layers[1].alpha"]);
    let scene = with(
        valid_scene(),
        "/layers/1/alpha",
        json!("data:image/png;base64,!!"),
    );
    assert_eq!(paths_of(&scene), vec!["layers[1].alpha"]);
    // No image anywhere and no size.
    let scene = json!({"inkwarp": 1, "layers": [{"name": "a"}]});
    assert_eq!(paths_of(&scene), vec!["width"]);
}

#[test]
fn non_finite_numbers_are_reported() {
    let mut doc: SceneDoc = serde_json::from_value(valid_scene()).unwrap();
    doc.features[1].keys[0].points[2][1] = f64::NAN;
    doc.features[0].rest[0][0] = f64::INFINITY;
    doc.layers[1].offset[0] = f64::NAN;
    doc.solver.tension = f64::NAN;
    doc.solver.beier_neely.p = f64::NAN;
    doc.solver.tps_exact.max_samples = 0;
    doc.fps = f64::INFINITY;
    let paths: Vec<String> = validate_doc(&doc).into_iter().map(|p| p.path).collect();
    assert_eq!(
        paths,
        [
            "fps",
            "solver.tension",
            "solver.beier_neely.p",
            "solver.tps_exact.max_samples",
            "features[0].rest[0][0]",
            "features[1].keys[0].points[2][1]",
            "layers[1].offset[0]"
        ]
    );
}

#[test]
fn numbers_too_large_for_json_are_a_syntax_error() {
    let text = valid_scene()
        .to_string()
        .replace("\"fps\":10", "\"fps\":1e999");
    let err = parse_doc(&text).unwrap_err();
    assert!(err.to_string().contains("not valid JSON"), "{err}");
}

#[test]
fn the_document_round_trips() {
    let doc = parse_doc(&valid_scene().to_string()).unwrap();
    let text = serde_json::to_string(&doc).unwrap();
    assert_eq!(parse_doc(&text).unwrap(), doc);
    // Defaults are filled in, and omitted again where they are the default.
    let value: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(value["solver"]["tolerance"], json!(0.01));
    assert!(value["layers"][0].get("visible").is_none());
    assert_eq!(
        value["features"][0]["keys"][1]["interpolation"],
        json!("linear")
    );
}

#[test]
fn the_schema_knows_every_field_and_accepts_the_valid_scene() {
    let schema = schema();
    assert_eq!(schema["properties"]["inkwarp"]["const"], json!(1));
    let kinds = &schema["$defs"]["FeatureKind"]["oneOf"];
    let names: Vec<&str> = kinds
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k["const"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["point", "polyline", "spline", "region", "cut"]);
    assert!(shape::check_detailed(&valid_scene(), &schema).0.is_empty());
}

#[test]
fn frame_count_and_default_duration() {
    let scene = json!({"inkwarp": 1, "width": 4, "height": 4, "fps": 24, "duration": 2.0, "layers": [{"name": "a"}]});
    let scene = Scene::from_json(&scene.to_string(), &mut no_files).unwrap();
    assert_eq!(scene.frame_count(), 48);
    // Without a duration: up to and including the last key.
    let mut doc = valid_scene();
    doc.as_object_mut().unwrap().remove("duration");
    let mut loader = files(&valid_files());
    let scene = Scene::from_json(&doc.to_string(), &mut loader).unwrap();
    assert_eq!(scene.frame_count(), 11);
    assert_eq!(scene.frame_time_s(10), 1.0);
}

// ---- the engine ---------------------------------------------------------------------------

fn small_scene() -> Arc<Scene> {
    let mut loader = files(&valid_files());
    let mut doc = valid_scene();
    doc["fps"] = json!(40);
    Arc::new(Scene::from_json(&doc.to_string(), &mut loader).unwrap())
}

#[test]
fn a_two_layer_scene_renders() {
    let scene = small_scene();
    let frame = scene.render(0.0).unwrap();
    assert_eq!(
        (frame.width, frame.height, frame.data.len()),
        (16, 12, 16 * 12 * 4)
    );
    // At t = 0 nothing has moved: the front layer covers the back one, shifted by its
    // offset (1, 0); its transparent corner shows the back layer.
    let front = image::load_from_memory(&valid_files()[1].1)
        .unwrap()
        .to_rgba8();
    let back = image::load_from_memory(&valid_files()[0].1)
        .unwrap()
        .to_rgba8();
    let at = |x: usize, y: usize| &frame.data[(y * 16 + x) * 4..(y * 16 + x) * 4 + 4];
    assert_eq!(at(8, 6), front.get_pixel(7, 6).0.as_slice());
    assert_eq!(at(1, 1), back.get_pixel(1, 1).0.as_slice());
    // The left column is not covered by the shifted front layer.
    assert_eq!(at(0, 6), back.get_pixel(0, 6).0.as_slice());
}

#[test]
fn layer_fields_follow_the_drawing() {
    let scene = small_scene();
    // At t = 1 the dot has moved by (2, 1).
    let solved = scene.layer_field(0, 1.0, None).unwrap();
    assert_eq!(solved.field.at(4, 4), [2.0, 1.0]);
    // The lid is at rest at t = 0 and its middle at (10, 5) at t = 0.5.
    let solved = scene.layer_field(0, 0.5, None).unwrap();
    let [dx, dy] = solved.field.at(10, 3);
    assert!(dx.abs() < 0.05 && (dy - 2.0).abs() < 0.05, "{dx} {dy}");
    // The front layer sits at offset (1, 0): it reads the drawing one pixel to the left in
    // its own grid, with the same displacements.
    let samples = scene.layer_samples(1, 0.5).unwrap();
    assert!(samples
        .iter()
        .any(|s| s.rest == [9.0, 3.0] && s.displacement == [0.0, 2.0]));
}

#[test]
fn a_layer_placed_by_its_offset_follows_the_drawing_traced_over_it_in_the_frame() {
    // A prop added at an offset, a point traced on it in the frame and dragged: the
    // layer's pixel under the point moves with it, and a cut drawn in the frame tears the
    // layer where it is drawn over it.
    let mut doc = valid_scene();
    doc["layers"][1]["offset"] = json!([5, 3]);
    doc["layers"][1]["features"] = json!(["dot", "edge"]);
    doc["features"][0]["rest"] = json!([[9, 7]]);
    doc["features"][0]["keys"] = json!([{"t": 0, "points": [[9, 7]]}, {"t": 1, "points": [[11, 8]], "interpolation": "linear"}]);
    let scene = Scene::from_json(&doc.to_string(), &mut files(&valid_files())).unwrap();
    let samples = scene.layer_samples(1, 1.0).unwrap();
    assert_eq!((samples[0].rest, samples[0].displacement), ([4.0, 4.0], [2.0, 1.0]));
    assert_eq!(scene.layer_field(1, 1.0, None).unwrap().field.at(4, 4), [2.0, 1.0]);
    // The back layer, at no offset, reads it where it is drawn.
    assert_eq!(scene.layer_samples(0, 1.0).unwrap()[0].rest, [9.0, 7.0]);
    // The cut from (2.5, 7.5) to (8.5, 7.5) in the frame: between rows 7 and 8 of the back
    // layer, columns 3 to 8; between rows 4 and 5 of the front one, columns 0 to 3.
    let down = |layer: usize, x: usize, y: usize| scene.layers()[layer].grid.link_down[y * 16 + x];
    assert!(!down(0, 5, 7) && down(0, 5, 4) && down(0, 1, 7));
    assert!(!down(1, 1, 4) && !down(1, 3, 4) && down(1, 5, 4) && down(1, 1, 7));
}

#[test]
fn every_method_reads_the_drawing_of_an_offset_layer_where_the_layer_shows() {
    // The same drawing traced over a layer at offset (5, 3), and over it at no offset with
    // the drawing shifted back: the same fields, method by method (Beier-Neely's lines
    // and regions read the features' points themselves).
    let shifted = |doc: &mut Value, by: [f64; 2]| {
        for f in doc["features"].as_array_mut().unwrap() {
            let mut lists = vec![f["rest"].clone()];
            lists.extend(f.get("keys").and_then(Value::as_array).into_iter().flatten().map(|k| k["points"].clone()));
            let moved: Vec<Value> = lists.iter().map(|pts| json!(pts.as_array().unwrap().iter().map(|p| [p[0].as_f64().unwrap() + by[0], p[1].as_f64().unwrap() + by[1]]).collect::<Vec<_>>())).collect();
            f["rest"] = moved[0].clone();
            if let Some(keys) = f.get_mut("keys").and_then(Value::as_array_mut) {
                for (k, pts) in keys.iter_mut().zip(&moved[1..]) {
                    k["points"] = pts.clone();
                }
            }
        }
    };
    let mut plain = valid_scene();
    plain["features"].as_array_mut().unwrap().extend([
        json!({"id": "bar", "kind": "polyline", "rest": [[3, 9], [12, 8]], "keys": [{"t": 1, "points": [[3, 10], [12, 10]]}]}),
        json!({"id": "patch", "kind": "region", "rest": [[9, 3], [13, 3], [13, 6], [9, 6]], "keys": [{"t": 1, "points": [[10, 3], [14, 4], [14, 7], [10, 6]]}]}),
    ]);
    plain["layers"][1]["features"] = json!(["dot", "lid", "bar", "patch", "edge"]);
    plain["layers"][1]["offset"] = json!([0, 0]);
    let mut placed = plain.clone();
    placed["layers"][1]["offset"] = json!([5, 3]);
    shifted(&mut placed, [5.0, 3.0]);
    let (plain, placed) = (Scene::from_json(&plain.to_string(), &mut files(&valid_files())).unwrap(),
                           Scene::from_json(&placed.to_string(), &mut files(&valid_files())).unwrap());
    assert_eq!(plain.layer_samples(1, 0.75).unwrap(), placed.layer_samples(1, 0.75).unwrap());
    for method in [None, Some(Method::TpsExact), Some(Method::Triangulation), Some(Method::BeierNeely)] {
        let want = plain.layer_field_overridden(1, 0.75, None, &SolverOverrides::method(method)).unwrap().field;
        let got = placed.layer_field_overridden(1, 0.75, None, &SolverOverrides::method(method)).unwrap().field;
        let worst = want.dx.iter().chain(&want.dy).zip(got.dx.iter().chain(&got.dy)).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        assert!(worst < 1e-4, "{method:?}: {worst}");
        assert!(want.dx.iter().any(|v| v.abs() > 0.5), "{method:?} moved nothing");
    }
}

#[test]
fn warm_started_frames_match_cold_frames() {
    let scene = small_scene();
    let mut animator = Animator::new(&scene);
    for i in 0..scene.frame_count() {
        let t = scene.frame_time_s(i);
        let warm = animator.layer_field(0, t).unwrap().field;
        let cold = scene.layer_field(0, t, None).unwrap().field;
        let worst = warm
            .dx
            .iter()
            .chain(&warm.dy)
            .zip(cold.dx.iter().chain(&cold.dy))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(
            worst < 0.05,
            "frame {i}: warm and cold fields differ by {worst} px"
        );
    }
}

#[test]
fn parallel_and_sequential_frames_are_identical() {
    let scene = small_scene();
    assert!(scene.frame_count() > 2 * WARM_CHAIN_FRAMES);
    let sequential: Vec<_> = scene.frames(0..usize::MAX, 1).map(|f| f.unwrap()).collect();
    let parallel: Vec<_> = scene.frames(0..usize::MAX, 3).map(|f| f.unwrap()).collect();
    assert_eq!(sequential.len(), scene.frame_count());
    assert_eq!(
        sequential.iter().map(|f| f.0).collect::<Vec<_>>(),
        (0..scene.frame_count()).collect::<Vec<_>>()
    );
    assert!(sequential == parallel);
    // A sub-range starting on a chain boundary gives the same frames.
    let part: Vec<_> = scene
        .frames(WARM_CHAIN_FRAMES..WARM_CHAIN_FRAMES + 5, 2)
        .map(|f| f.unwrap())
        .collect();
    assert!(part[..] == sequential[WARM_CHAIN_FRAMES..WARM_CHAIN_FRAMES + 5]);
}

#[test]
fn dropping_a_stream_early_stops_its_workers() {
    let scene = small_scene();
    let mut stream = scene.frames(0..usize::MAX, 4);
    assert_eq!(stream.next().unwrap().unwrap().0, 0);
    drop(stream);
    assert_eq!(Arc::strong_count(&scene), 1);
}

#[test]
fn invisible_and_imageless_layers_are_not_drawn() {
    let mut loader = files(&valid_files());
    let mut doc = valid_scene();
    doc["layers"][1]["visible"] = json!(false);
    let scene = Scene::from_json(&doc.to_string(), &mut loader).unwrap();
    let frame = scene.render(0.0).unwrap();
    let back = image::load_from_memory(&valid_files()[0].1)
        .unwrap()
        .to_rgba8();
    assert_eq!(frame.data, back.into_raw());
}

#[test]
fn alpha_and_continuity_mattes_apply() {
    let mut loader = files(&valid_files());
    let mut doc = valid_scene();
    // Alpha matte: black everywhere but the left half.
    let half: Vec<u8> = (0..12)
        .flat_map(|_| (0..16).flat_map(|x| if x < 8 { [255; 4] } else { [0, 0, 0, 255] }))
        .collect();
    doc["layers"][0]["alpha"] = json!(data_uri(&png(16, 12, &half)));
    doc["layers"][0]["continuity"] = json!(data_uri(&png(16, 12, &[255; 16 * 12 * 4])));
    doc["background"] = json!([0, 0, 255, 255]);
    doc["layers"][1]["visible"] = json!(false);
    let scene = Scene::from_json(&doc.to_string(), &mut loader).unwrap();
    let layer = &scene.layers()[0];
    assert!(
        layer.grid.active.iter().all(|&a| a),
        "the continuity matte replaces the alpha-derived one"
    );
    let frame = scene.render(0.0).unwrap();
    assert_eq!(
        &frame.data[(6 * 16 + 12) * 4..(6 * 16 + 12) * 4 + 4],
        &[0, 0, 255, 255]
    );
    assert_ne!(
        &frame.data[(6 * 16 + 2) * 4..(6 * 16 + 2) * 4 + 4],
        &[0, 0, 255, 255]
    );
}

#[test]
fn the_method_can_be_chosen_per_call() {
    let scene = small_scene();
    assert_eq!(
        scene.render_warned(0.7, Some(Method::Tps)).unwrap().0,
        scene.render(0.7).unwrap()
    );
    // Every method draws: the comparison interpolants differ from the grid thin plate.
    for method in [Method::TpsExact, Method::Triangulation, Method::BeierNeely] {
        let frame = scene.render_warned(0.7, Some(method)).unwrap().0;
        assert_eq!((frame.width, frame.height), (16, 12));
        assert_ne!(frame, scene.render(0.7).unwrap(), "{}", method.name());
    }
    let stream =
        FrameStream::new(Arc::clone(&scene), 0..3, 2, SolverOverrides::method(Some(Method::Triangulation)), None);
    assert_eq!(stream.filter(|f| f.is_ok()).count(), 3);
}

#[test]
fn method_settings_in_the_scene_reach_the_interpolants() {
    use crate::methods::scene::{feature_controls, method_params};
    use crate::methods::{controls_field, BeierNeelyParams, Interpolant, MethodParams, DEFAULT_MAX_SAMPLES};

    let mut loader = files(&valid_files());
    let mut doc = valid_scene();
    doc["solver"] = json!({"method": "beier-neely", "beier_neely": {"a": 4, "b": 1.5, "p": 0.5},
                           "tps_exact": {"max_samples": 3}});
    let scene = Scene::from_json(&doc.to_string(), &mut loader).unwrap();
    let plain = small_scene();
    let solver = &scene.layers()[0].solver;
    let params = method_params(solver);
    assert_eq!(
        params,
        MethodParams { max_samples: 3, beier_neely: BeierNeelyParams { a: 4.0, b: 1.5, p: 0.5 } }
    );
    assert_eq!(
        method_params(&plain.layers()[0].solver),
        MethodParams { max_samples: DEFAULT_MAX_SAMPLES, beier_neely: BeierNeelyParams::DEFAULT }
    );
    // Beier–Neely with the scene's weights: the field the methods module gives for them,
    // and not the default weights' field.
    let features = scene.layer_feature_samples(0, 1.0).unwrap();
    let controls = feature_controls(&scene, &features, 1.0, Interpolant::BeierNeely, [0.0, 0.0]).unwrap();
    let (want, _) = controls_field(Interpolant::BeierNeely, &controls, &scene.layers()[0].grid, &params).unwrap();
    let got = scene.layer_field(0, 1.0, None).unwrap();
    assert_eq!(got.field, want);
    assert_ne!(got.field, plain.layer_field_overridden(0, 1.0, None, &SolverOverrides::method(Some(Method::BeierNeely))).unwrap().field);
    // tps-exact thins to the scene's max_samples, and says so.
    let exact = scene.layer_field_overridden(0, 1.0, None, &SolverOverrides::method(Some(Method::TpsExact))).unwrap();
    let report = exact.method_report.as_ref().unwrap();
    assert_eq!(report.samples_used, 3);
    assert!(exact.notes().iter().any(|n| n.contains("thinned") && n.contains("to 3")), "{:?}", exact.notes());
    // A layer's own settings replace the scene's, as a whole.
    let mut doc = valid_scene();
    doc["solver"] = json!({"beier_neely": {"a": 4, "b": 1.5}});
    doc["layers"][1]["solver"] = json!({"beier_neely": {"p": 1}});
    let scene = Scene::from_json(&doc.to_string(), &mut loader).unwrap();
    assert_eq!(scene.layers()[0].solver.beier_neely.a, 4.0);
    assert_eq!(
        method_params(&scene.layers()[1].solver).beier_neely,
        BeierNeelyParams { a: 1.0, b: 2.0, p: 1.0 }
    );
}

#[test]
fn rendering_passes_the_interpolants_notes_up() {
    let scene = small_scene();
    // Both layers have a discontinuity (the back one a cut, the front one a hole), which
    // tps-exact ignores and says so, per layer.
    let overrides = SolverOverrides { method: Some(Method::TpsExact), ..SolverOverrides::default() };
    let rendered = scene.render_overridden(0.5, &overrides).unwrap();
    assert_eq!(rendered.image, scene.render_warned(0.5, Some(Method::TpsExact)).unwrap().0);
    assert_eq!(
        rendered.notes(&scene),
        [
            "layer \"back\": tps-exact ignores the continuity matte and cuts: its surface is continuous across holes.",
            "layer \"front\": tps-exact ignores the continuity matte and cuts: its surface is continuous across holes.",
        ]
    );
    // The grid thin plate has nothing to say; its solver reports instead.
    let rendered = scene.render_overridden(0.5, &SolverOverrides::default()).unwrap();
    assert!(rendered.notes(&scene).is_empty());
    assert!(rendered.layers.iter().all(|l| l.as_ref().unwrap().report.is_some()));
    // A layer that nothing drives stays put under every method.
    let mut loader = files(&valid_files());
    let mut doc = valid_scene();
    doc["layers"][0]["features"] = json!([]);
    let still = Scene::from_json(&doc.to_string(), &mut loader).unwrap();
    for method in Method::ALL {
        let solved = still.layer_field_overridden(0, 1.0, None, &SolverOverrides::method(Some(method))).unwrap();
        assert!(solved.field.dx.iter().chain(&solved.field.dy).all(|&v| v == 0.0), "{method}");
    }
    // Overrides are checked like a scene's solver settings.
    let bad = SolverOverrides {
        beier_neely: Some(BeierNeelyDoc { a: -1.0, b: 2.0, p: 0.0 }),
        ..SolverOverrides::default()
    };
    let problems = validate_overrides(&bad, "solver");
    assert_eq!(problems.len(), 1);
    assert_eq!(problems[0].path, "solver.beier_neely.a");
    let parsed = parse_overrides(r#"{"method": "beier-neely", "beier_neely": {"b": 1}}"#, "solver").unwrap();
    assert_eq!(parsed.beier_neely, Some(BeierNeelyDoc { a: 1.0, b: 1.0, p: 0.0 }));
    let err = parse_overrides(r#"{"beier_neely": {"b": "x"}}"#, "solver").unwrap_err();
    assert_eq!(err.path(), "solver.beier_neely.b");
    let err = parse_overrides(r#"{"tps_exact": {"max_samples": 0}}"#, "solver").unwrap_err();
    assert_eq!(err.path(), "solver.tps_exact.max_samples");
}

#[test]
fn samples_come_grouped_by_feature_in_curve_order() {
    let scene = small_scene();
    let groups = scene.layer_feature_samples(0, 0.5).unwrap();
    assert_eq!(
        groups
            .iter()
            .map(|g| (g.feature, scene.doc().features[g.feature].kind))
            .collect::<Vec<_>>(),
        [(0, crate::Kind::Point), (1, crate::Kind::Spline)]
    );
    let lid = &groups[1].samples;
    assert_eq!(
        (lid[0].rest, lid[lid.len() - 1].rest),
        ([8.0, 2.0], [12.0, 2.0])
    );
    assert_eq!(
        scene.layer_samples(0, 0.5).unwrap().len(),
        groups.iter().map(|g| g.samples.len()).sum::<usize>()
    );
}

/// The JSON pointer of a problem path such as `features[1].keys[0].t`.
fn pointer_of(path: &str) -> String {
    let mut out = String::new();
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let mut pieces = part.split('[');
        out.push('/');
        out.push_str(pieces.next().unwrap());
        for index in pieces {
            out.push('/');
            out.push_str(index.trim_end_matches(']'));
        }
    }
    out
}

/// Every leaf of `value` as a JSON pointer.
fn leaves(value: &Value, at: String, out: &mut Vec<String>) {
    match value {
        Value::Object(map) => map.iter().for_each(|(k, v)| leaves(v, format!("{at}/{k}"), out)),
        Value::Array(items) => items.iter().enumerate().for_each(|(i, v)| leaves(v, format!("{at}/{i}"), out)),
        _ => out.push(at),
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]

    /// Whatever single value is broken, checking never panics, and every problem points
    /// into the document: its path, or the object that misses the key, exists.
    #[test]
    fn problems_point_into_the_document(leaf in 0usize..1000, choice in 0usize..8, number in -1e6f64..1e6) {
        let mut scene = valid_scene();
        let mut all = Vec::new();
        leaves(&scene, String::new(), &mut all);
        let pointer = &all[leaf % all.len()];
        let replacement = match choice {
            0 => json!(number),
            1 => json!(-1),
            2 => json!("text"),
            3 => json!(null),
            4 => json!([]),
            5 => json!({"x": 1}),
            6 => json!(true),
            _ => json!(0),
        };
        *scene.pointer_mut(pointer).unwrap() = replacement;
        let mut loader = files(&valid_files());
        if let Err(err) = Scene::from_json(&scene.to_string(), &mut loader) {
            proptest::prop_assert!(!err.problems.is_empty());
            for problem in &err.problems {
                let full = pointer_of(&problem.path);
                let parent = full.rsplit_once('/').map_or("", |(p, _)| p);
                proptest::prop_assert!(
                    scene.pointer(&full).is_some() || scene.pointer(parent).is_some(),
                    "{} does not point into {}", problem, scene
                );
            }
        }
    }
}

#[test]
fn the_warning_says_why_the_solve_stopped() {
    // The reason the solve recorded, each with its own fix: the cycle cap, Southwell's
    // budget, free parts too many to settle (at a grid step: its thin parts), precision.
    let mut loader = files(&[("back.png", picture(64, 48, |_, _| false)), ("front.png", picture(64, 48, |_, _| false))]);
    let mut doc = valid_scene();
    doc["layers"][1]["solver"] = json!({"max_cycles": 7});
    doc["layers"][0]["solver"] = json!({"grid_step": 2});
    let scene = Scene::from_json(&doc.to_string(), &mut loader).unwrap();
    let warn = |layer: usize, stop: Stop, t: f64| {
        let report = Some(crate::solve::SolveReport { cycles: 3, converged: false, stop, ..Default::default() });
        scene.convergence_warning(layer, t, &LayerSolve { field: crate::field::Field::zeros(1, 1), report, method_report: None }).unwrap()
    };
    for (layer, stop, says) in [
        // The setting in effect named; a smaller step offered only where the cap is not low.
        (1, Stop::MaxCycles, "raise layers[1].solver.max_cycles (the layer's own, 7), or use another method"),
        (0, Stop::MaxCycles, "raise solver.max_cycles (the default, 300), or use another method"),
        (1, Stop::Budget, "fixed budget of relaxations"),
        // Not back to the cap the step was offered for without a way past it.
        (0, Stop::Unsettled, "at grid_step 2 parts of the matte thinner than the step (hair, strands) are too many to settle, so they may be torn apart; use grid_step 1 for this layer (with a higher solver.max_cycles if it stops there)"),
        (1, Stop::Unsettled, "1 px strands are too many to settle, or did not settle; hold those parts with points of their own, or"),
        (1, Stop::Precision, "too large for the field's precision (keys far off the picture?)"),
        (1, Stop::Residual, "residual stayed above the tolerance"),
        (1, Stop::Breakdown, "broke down"),
    ] {
        assert!(warn(layer, stop, 0.1).contains(says), "{stop:?}: {}", warn(layer, stop, 0.1));
    }
    assert!(warn(1, Stop::MaxCycles, 1.0 / 24.0).contains("at t = 0.0417 s:"), "{}", warn(1, Stop::MaxCycles, 1.0 / 24.0));
    assert!(warn(1, Stop::MaxCycles, -1e-9).contains("at t = 0 s"), "{}", warn(1, Stop::MaxCycles, -1e-9));
    doc["layers"][1]["solver"] = json!({"tension": 0.1});
    doc["solver"] = json!({"max_cycles": 400});
    let scene = Scene::from_json(&doc.to_string(), &mut loader).unwrap();
    let report = Some(crate::solve::SolveReport { cycles: 400, converged: false, stop: Stop::MaxCycles, ..Default::default() });
    let said = scene.convergence_warning(1, 0.1, &LayerSolve { field: crate::field::Field::zeros(1, 1), report, method_report: None }).unwrap();
    assert!(said.contains("raise solver.max_cycles (400), solve every other pixel (solver.grid_step 2: mattes with hair"), "{said}");
}

#[test]
fn a_solve_stopped_early_is_warned_about_with_its_layer_and_frame() {
    // Big enough that one cycle does not finish the solve (small grids solve directly).
    let mut loader = files(&[
        ("back.png", picture(64, 48, |_, _| false)),
        ("front.png", picture(64, 48, |x, y| x < 3 && y < 3)),
    ]);
    let mut doc = valid_scene();
    doc["layers"][1]["solver"] = json!({"max_cycles": 1, "tolerance": 1e-9});
    let scene = Arc::new(Scene::from_json(&doc.to_string(), &mut loader).unwrap());
    let (_, warnings) = scene.render_warned(0.3, None).unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].starts_with("layer \"front\" at t = 0.3 s (frame 3): "), "{}", warnings[0]);
    // One cycle, and the contract of its own tolerance (5 times 1e-9), not the default's.
    assert!(warnings[0].contains("did not converge (1 cycle, ") && warnings[0].contains("off by more than 5.0e-9 px"), "{}", warnings[0]);
    // Frames carry theirs, in parallel as in sequence; a converged scene has none.
    for threads in [1, 2] {
        let mut stream = scene.frames(1..4, threads);
        let mut seen = Vec::new();
        while let Some(frame) = stream.next() {
            frame.unwrap();
            seen.extend(stream.take_warnings());
        }
        assert_eq!(seen.len(), 3, "{seen:?}");
        assert!(seen[1].contains("(frame 2)"), "{}", seen[1]);
    }
    assert!(small_scene().render_warned(0.3, None).unwrap().1.is_empty());
}

#[test]
fn a_field_that_is_not_finite_is_an_error_not_a_blank_frame() {
    // A displacement past f32's range makes an infinite field; the engine refuses it
    // (by the solver's own checks or by the field's) instead of drawing a blank frame.
    use super::engine::{compute_field, FeatureSamples, Start};
    let mut loader = files(&valid_files());
    let scene = Scene::from_json(&valid_scene().to_string(), &mut loader).unwrap();
    let grid = crate::grid::Grid::new(16, 12);
    let samples = vec![crate::geometry::Sample { rest: [4.0, 4.0], displacement: [1e300, 0.0] }];
    let features = [FeatureSamples { feature: 0, samples }];
    for method in [super::doc::Method::Tps, super::doc::Method::BeierNeely] {
        let solver = super::doc::SolverDoc { method, ..super::doc::SolverDoc::default() };
        let result = compute_field(&scene, 0.0, &solver, &grid, &features, Start::Field(None), Default::default(), [0.0, 0.0]);
        match result {
            Err(message) => assert!(message.contains("is not finite"), "{method:?}: {message}"),
            Ok(layer) => panic!(
                "{method:?}: a field was returned: finite {}",
                layer.field.dx.iter().all(|v| v.is_finite())
            ),
        }
    }
}

#[test]
fn a_lone_layer_set_aside_for_its_problems_is_not_reported_missing() {
    // Its broken solver override was the one problem; "needs at least one layer" was a second.
    let mut scene = valid_scene();
    scene["layers"] = json!([{"name": "back", "image": "back.png", "solver": {"grid_step": 0}}]);
    assert_eq!(problems_of(&scene), ["layers[0].solver.grid_step: must be at least 1, found 0"]);
    scene["layers"][0]["solver"] = json!({"max_cycles": 1.5});
    assert_eq!(problems_of(&scene).len(), 1, "{:?}", problems_of(&scene));
    // No layer at all is still a problem, beside another one that sets a feature aside.
    scene["layers"] = json!([]);
    scene["features"][0]["keys"][0]["t"] = json!("soon");
    let problems = problems_of(&scene);
    assert!(problems.iter().any(|p| p.starts_with("layers: a scene needs at least one layer")), "{problems:?}");
    assert!(problems.iter().any(|p| p.starts_with("features[0].keys[0].t")), "{problems:?}");
}

#[test]
fn a_whole_number_written_as_a_float_is_told_how_to_write_it() {
    let scene = with(valid_scene(), "/solver", json!({"grid_step": 2.0}));
    assert_eq!(problems_of(&scene), ["solver.grid_step: expected a whole number, found the number 2.0; write it without a decimal point or exponent (2, not 2.0)"]);
    let scene = with(valid_scene(), "/solver", json!({"grid_step": 1.5}));
    assert_eq!(problems_of(&scene), ["solver.grid_step: expected a whole number, found the number 1.5"]);
}

#[test]
fn a_whole_number_past_64_bits_is_called_too_large_not_a_float() {
    // serde reads it as a float, however it was written; the decimal-point hint would send the user in a circle.
    let huge: Value = serde_json::from_str("100000000000000000000000000000").unwrap();
    for (pointer, path) in [("/width", "width"), ("/solver", "solver.grid_step")] {
        let value = if path == "width" { huge.clone() } else { json!({"grid_step": huge}) };
        let found = problems_of(&with(valid_scene(), pointer, value));
        assert_eq!(found, [format!("{path}: expected a whole number, found the number 1e+29, too large to be one here; use a smaller number")]);
    }
}

#[test]
fn places_in_messages_are_the_original_documents_past_a_layer_set_aside() {
    // The duplicate name's first use is layers[1]; the rebuilt document (without layers[0])
    // called it layers[0].
    let mut scene = valid_scene();
    scene["layers"] = json!([{"name": "x", "image": "back.png", "solver": {"grid_step": 0}},
                             {"name": "b", "image": "back.png"}, {"name": "b", "image": "front.png"}]);
    let problems = problems_of(&scene);
    assert!(problems.iter().any(|p| p.starts_with("layers[2].name:") && p.contains("layers[1]") && !p.contains("layers[0]")), "{problems:?}");
}

#[test]
fn an_id_or_name_shared_with_an_item_set_aside_is_reported_with_its_problems() {
    // Both at once: the misspelt kind set the first feature aside, and its id was checked
    // only after the kind was fixed.
    let mut scene = valid_scene();
    let mut features = scene["features"].as_array().unwrap().clone();
    features.insert(0, json!({"id": "dot", "kind": "splin", "rest": [[1, 1], [5, 5]]}));
    scene["features"] = json!(features);
    let problems = problems_of(&scene);
    assert!(problems.iter().any(|p| p.starts_with("features[0].kind: unknown kind \"splin\"")), "{problems:?}");
    assert!(problems.iter().any(|p| p == "features[1].id: the id \"dot\" is already used by features[0]; give each feature its own id"), "{problems:?}");
    // The same for a layer set aside and a later one with its name.
    let mut scene = valid_scene();
    scene["layers"] = json!([{"name": "b", "image": "back.png", "solver": {"grid_step": 0}}, {"name": "b", "image": "front.png"}]);
    let problems = problems_of(&scene);
    assert!(problems.iter().any(|p| p == "layers[1].name: the name \"b\" is already used by layers[0]; give each layer its own name"), "{problems:?}");
}

#[test]
fn a_layers_own_feature_list_is_named_by_its_full_path() {
    // "also at features[2]" was the layer's list, and was renumbered as the scene's
    // features once a broken feature was set aside.
    let mut scene = valid_scene();
    let features = scene["features"].as_array().unwrap().clone();
    scene["features"] = json!([{"id": "broken", "kind": "point", "rest": "nope"}]);
    scene["features"].as_array_mut().unwrap().extend(features);
    scene["layers"][1]["features"] = json!(["dot", "lid", "lid"]);
    let problems = problems_of(&scene);
    assert!(problems.iter().any(|p| p.contains("\"lid\" is listed twice (also at layers[1].features[1])")), "{problems:?}");
}

#[test]
fn a_drawing_programs_word_for_a_kind_is_suggested_as_that_kind() {
    // "dot" is nearer "cut" by its letters than "point".
    for (word, kind) in [("dot", "point"), ("curve", "spline"), ("line", "polyline"), ("shape", "region")] {
        let text = problems_of(&with(valid_scene(), "/features/0/kind", json!(word))).join("\n");
        assert!(text.contains(&format!("(did you mean \"{kind}\"?)")), "{text}");
    }
}

#[test]
fn a_key_written_as_time_is_suggested_as_t_and_a_hex_colour_as_a_list() {
    let mut scene = valid_scene();
    let key = scene["features"][0]["keys"][0].as_object_mut().unwrap();
    let t = key.remove("t").unwrap();
    key.insert("time".into(), t);
    let text = problems_of(&scene).join("\n");
    assert!(text.contains("did you mean \"t\"?"), "{text}");
    let text = problems_of(&with(valid_scene(), "/background", json!("#808080"))).join("\n");
    assert!(text.contains("write a colour as a list [r, g, b, a] of 0–255 (\"#ff8000\" is [255, 128, 0, 255])"), "{text}");
}

#[test]
fn a_name_written_without_its_hyphens_is_suggested() {
    let text = problems_of(&with(valid_scene(), "/features/0/keys/0/interpolation", json!("easeinout"))).join("\n");
    assert!(text.contains("(did you mean \"ease-in-out\"?)"), "{text}");
}

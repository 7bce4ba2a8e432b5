//! The meaning check: everything about a well-shaped [`SceneDoc`] that the schema cannot
//! say (counts, order, finiteness, references, uniqueness), every problem with its path.

use std::collections::HashMap;

use super::doc::{BeierNeelyDoc, SceneDoc, SolverOverrides, TpsExactDoc, FORMAT_VERSION};
use super::shape::did_you_mean;
use super::Problem;
use crate::geometry::{Kind, Point};
use crate::limits::{
    self, MAX_BEIER_NEELY_A, MAX_BEIER_NEELY_EXPONENT, MAX_COORD_PX, MAX_FPS, MAX_FRAMES, MIN_FPS,
    MAX_TENSION, MAX_TIME_S, MIN_KEY_SPACING_S,
};

/// Every problem of `doc` that does not need its images. Empty when the document is valid.
pub fn validate_doc(doc: &SceneDoc) -> Vec<Problem> { validate_doc_knowing(doc, &[], false) }

/// [`validate_doc`], taking `other_ids` as feature ids too, and no layer as none missing
/// where `layers_set_aside` (set aside because of shape problems already reported).
pub(crate) fn validate_doc_knowing(doc: &SceneDoc, other_ids: &[String], layers_set_aside: bool) -> Vec<Problem> {
    let mut p = Vec::new();
    if doc.inkwarp != FORMAT_VERSION {
        let why = format!("this inkwarp reads scene format {FORMAT_VERSION}, found {}; set \"inkwarp\": {FORMAT_VERSION} (and convert the scene if it was written for another format)", doc.inkwarp);
        p.push(Problem::new("inkwarp", why));
    }
    for (key, _) in [("width", doc.width), ("height", doc.height)].into_iter().filter(|e| e.1 == Some(0)) {
        p.push(Problem::new(key, format!("the frame {key} must be at least 1 pixel, found 0")));
    }
    if let (Some(w @ 1..), Some(h @ 1..)) = (doc.width, doc.height) {
        p.extend(limits::check_size("the canvas", w as usize, h as usize).err().map(|why| Problem::new("width", why)));
    }
    if !(doc.fps.is_finite() && (MIN_FPS..=MAX_FPS).contains(&doc.fps)) {
        p.push(Problem::new("fps", format!("frames per second must be a number from {MIN_FPS} (one frame every {} s) to {MAX_FPS}, found {:?}; use e.g. 24", 1.0 / MIN_FPS, doc.fps)));
    }
    if let Some(duration) = doc.duration {
        let why = if !(duration.is_finite() && duration > 0.0) {
            Some(format!("the duration must be a number of seconds > 0, found {duration}; leave it out to end at the last key"))
        } else if duration > MAX_TIME_S {
            Some(format!("the duration may be at most {MAX_TIME_S} s, found {}; split a longer animation into several scenes", limits::show(duration)))
        } else if doc.fps.is_finite() && doc.fps > 0.0 && duration * doc.fps > MAX_FRAMES as f64 {
            Some(format!("{duration} s at {} frames per second is more than {MAX_FRAMES} frames; shorten it or lower fps", doc.fps))
        } else {
            None
        };
        p.extend(why.map(|why| Problem::new("duration", why)));
    }
    // The scene's own settings, checked as overrides that give every key.
    let s = &doc.solver;
    let all = SolverOverrides {
        method: Some(s.method), tension: Some(s.tension), tolerance: Some(s.tolerance), grid_step: Some(s.grid_step),
        max_cycles: s.max_cycles, scheme: Some(s.scheme), beier_neely: Some(s.beier_neely), tps_exact: Some(s.tps_exact),
    };
    p.extend(validate_overrides(&all, "solver"));

    // Features.
    let mut first_with_id: HashMap<&str, usize> = HashMap::new();
    for (i, feature) in doc.features.iter().enumerate() {
        let path = format!("features[{i}]");
        check_unique(&feature.id, i, ("feature", "id", "features"), &mut first_with_id, &mut p);
        let kind = feature.kind;
        let (n, point) = (feature.rest.len(), kind == Kind::Point);
        // A point has exactly one control point; the other kinds have no most.
        if n < kind.min_points() || (point && n > 1) {
            let (wanted, s) =
                if point { ("exactly 1".to_string(), "") } else { (format!("at least {}", kind.min_points()), "s") };
            let hint = if point && n > 1 { "; use a polyline or a spline for several points" } else { "" };
            let why = format!("a {} needs {wanted} control point{s}, found {n}{hint}", kind.name());
            p.push(Problem::new(format!("{path}.rest"), why));
        }
        check_points(&feature.rest, &format!("{path}.rest"), &mut p);
        if feature.curve.is_some() && kind != Kind::Region {
            let hint = if kind == Kind::Polyline { " (or use kind \"spline\" for a curve)" } else { "" };
            let why = format!("\"curve\" applies to regions only, this feature is a {}; remove it{hint}", kind.name());
            p.push(Problem::new(format!("{path}.curve"), why));
        }
        if kind == Kind::Cut && !feature.keys.is_empty() {
            p.push(Problem::new(format!("{path}.keys"), "a cut does not move: it tears the surface along its rest line; remove \"keys\" (or make it a polyline to move the picture)"));
        }
        if kind == Kind::Cut && n >= 2 && feature.rest.windows(2).all(|s| s[0] == s[1]) {
            p.push(Problem::new(format!("{path}.rest"), "a cut of zero length tears nothing; give its points different positions"));
        }
        if feature.closed && point {
            p.push(Problem::new(format!("{path}.closed"), "a point cannot be closed; remove \"closed\""));
        }
        let mut previous_t: Option<f64> = None;
        for (k, key) in feature.keys.iter().enumerate() {
            // `j` is the key before, when there is a `previous_t`.
            let (key_path, t, j) = (format!("{path}.keys[{k}]"), key.time_s, k.wrapping_sub(1));
            let why = match previous_t {
                _ if !t.is_finite() => Some(format!("the key time must be a finite number of seconds, found {t}")),
                _ if t.abs() > MAX_TIME_S => Some(format!("key times may be at most {MAX_TIME_S} s (either side of 0), found {}; split a longer animation into several scenes", limits::show(t))),
                Some(b) if t > b && t - b < MIN_KEY_SPACING_S => Some(format!("keys[{j}] and keys[{k}] are {:e} s apart, closer than {MIN_KEY_SPACING_S:e} s; move them apart or remove one", t - b)),
                Some(b) if t == b => Some(format!("two keys at t = {b} s (keys[{j}] and keys[{k}]); give each key its own time or remove one")),
                Some(b) if t < b => Some(format!("keys must be in increasing time order, but t = {t} s follows t = {b} s (keys[{j}]); sort the keys by time")),
                _ => None,
            };
            p.extend(why.map(|why| Problem::new(format!("{key_path}.t"), why)));
            if t.is_finite() {
                previous_t = Some(t);
            }
            let m = key.points.len();
            if m != n {
                let s = if m == 1 { "" } else { "s" };
                let why = format!("this key has {m} control point{s} but the feature's rest has {n}; a key lists the same control points as rest, in the same order");
                p.push(Problem::new(format!("{key_path}.points"), why));
            }
            check_points(&key.points, &format!("{key_path}.points"), &mut p);
        }
    }

    // Layers.
    if doc.layers.is_empty() && !layers_set_aside {
        let why = "a scene needs at least one layer; add one such as {\"name\": \"main\", \"image\": \"picture.png\"}";
        p.push(Problem::new("layers", why));
    }
    let mut first_with_name: HashMap<&str, usize> = HashMap::new();
    for (j, layer) in doc.layers.iter().enumerate() {
        let path = format!("layers[{j}]");
        check_unique(&layer.name, j, ("layer", "name", "layers"), &mut first_with_name, &mut p);
        for (c, v) in layer.offset.iter().enumerate().filter(|(_, v)| !limits::coordinate_ok(**v)) {
            let why = format!("the offset must be a finite number of pixels within ±{MAX_COORD_PX:e}, found {}", limits::show(*v));
            p.push(Problem::new(format!("{path}.offset[{c}]"), why));
        }
        // The engine reads a layer's features in its own pixels (less its offset), so they must be within the limit there too.
        let listed = |f: &&super::doc::FeatureDoc| layer.features.as_ref().map_or(true, |ids| ids.contains(&f.id));
        let far = |q: &Point| q.iter().zip(layer.offset).any(|(&v, o)| limits::coordinate_ok(v) && o.is_finite() && !limits::coordinate_ok(v - o));
        if let Some(f) = doc.features.iter().filter(listed).find(|f| f.rest.iter().chain(f.keys.iter().flat_map(|k| &k.points)).any(far)) {
            let why = format!("feature \"{}\" lies more than {MAX_COORD_PX:e} px from this layer's origin once its offset is taken off; bring the offset and the feature's points closer", f.id);
            p.push(Problem::new(format!("{path}.offset"), why));
        }
        for (key, reference) in [("image", &layer.image), ("alpha", &layer.alpha), ("continuity", &layer.continuity)] {
            if reference.as_ref().is_some_and(|r| r.trim().is_empty()) {
                let why = "an empty image reference; give a path relative to the scene file or a data: URI";
                p.push(Problem::new(format!("{path}.{key}"), why));
            }
        }
        if let Some(ids) = &layer.features {
            let mut seen: HashMap<&str, usize> = HashMap::new();
            for (k, id) in ids.iter().enumerate() {
                let id_path = format!("{path}.features[{k}]");
                if other_ids.contains(id) {
                    continue;
                } else if !first_with_id.contains_key(id.as_str()) {
                    let ids = doc.features.iter().map(|f| f.id.as_str());
                    let known: Vec<&str> = ids.chain(other_ids.iter().map(String::as_str)).collect();
                    let hint = did_you_mean(id, known.iter().copied()).map(|s| format!("did you mean \"{s}\"? ")).unwrap_or_default();
                    let known = if known.is_empty() { "the scene has no features".to_string() } else { format!("the feature ids are {}", known.join(", ")) };
                    p.push(Problem::new(id_path, format!("no feature has the id \"{id}\"; {hint}{known}")));
                } else if let Some(&first) = seen.get(id.as_str()) {
                    let why = format!("\"{id}\" is listed twice (also at {path}.features[{first}]); list it once");
                    p.push(Problem::new(id_path, why));
                } else {
                    seen.insert(id, k);
                }
            }
        }
        p.extend(layer.solver.iter().flat_map(|overrides| validate_overrides(overrides, &format!("{path}.solver"))));
    }
    p
}

/// A problem when `value`, the `key` of `list[index]` (a `noun`), is blank or already used
/// by an earlier one (`first`: where each value was first seen).
fn check_unique<'d>(
    value: &'d str,
    index: usize,
    (noun, key, list): (&str, &str, &str),
    first: &mut HashMap<&'d str, usize>,
    p: &mut Vec<Problem>,
) {
    let path = format!("{list}[{index}].{key}");
    if value.trim().is_empty() {
        p.push(Problem::new(path, format!("a {noun} needs a non-empty {key}")));
    } else if let Some(&earlier) = first.get(value) {
        p.push(Problem::new(path, already_used(value, earlier, (noun, key, list))));
    } else {
        first.insert(value, index);
    }
}

/// The message for `value`, the `key` of a `noun` in `list`, used already by `list[earlier]`.
pub(crate) fn already_used(value: &str, earlier: usize, (noun, key, list): (&str, &str, &str)) -> String {
    format!("the {key} \"{value}\" is already used by {list}[{earlier}]; give each {noun} its own {key}")
}

/// Every problem of solver settings given outside a scene (by a caller that overrides
/// every layer's settings, as `inkwarp compare` does), with paths under `path`. A scene's
/// own settings and each layer's overrides are checked the same way.
pub fn validate_overrides(solver: &SolverOverrides, path: &str) -> Vec<Problem> {
    let mut p = Vec::new();
    let mut push = |key: &str, why: String| p.push(Problem::new(format!("{path}.{key}"), why));
    if let Some(tension) = solver.tension.filter(|t| !(t.is_finite() && (0.0..=MAX_TENSION).contains(t))) {
        let tension = limits::show(tension);
        push("tension", format!("the tension must be a number from 0 to {MAX_TENSION:e}, found {tension}; 0 is a pure thin plate"));
    }
    if let Some(tolerance) = solver.tolerance.filter(|t| !(t.is_finite() && *t > 0.0)) {
        push("tolerance", format!("the tolerance must be a number of pixels > 0, found {tolerance}; the default is 0.01"));
    }
    if let Some(step) = solver.grid_step.filter(|s| !(1..=64).contains(s)) {
        push("grid_step", format!("grid_step must be a whole number from 1 to 64, found {step}; 1 solves on every pixel"));
    }
    if solver.max_cycles == Some(0) {
        push("max_cycles", "max_cycles must be at least 1; leave it out for the default cap (300 cycles, or until the tolerance is met)".into());
    }
    // Beier–Neely's weights: the ranges of `methods::BeierNeelyParams::validate`, reported
    // the scene's way.
    if let Some(BeierNeelyDoc { a, b, p }) = solver.beier_neely {
        if !(a.is_finite() && a > 0.0 && a <= MAX_BEIER_NEELY_A) {
            let why = format!("Beier–Neely's a must be a number of pixels > 0 and at most {MAX_BEIER_NEELY_A:e}, found {}; the default is 1 (smaller values follow the drawing more tightly)", limits::show(a));
            push("beier_neely.a", why);
        }
        for (key, value, default) in [("b", b, 2), ("p", p, 0)] {
            if !(value.is_finite() && (0.0..=MAX_BEIER_NEELY_EXPONENT).contains(&value)) {
                let why = format!("Beier–Neely's {key} must be a number from 0 to {MAX_BEIER_NEELY_EXPONENT}, found {}; the default is {default}", limits::show(value));
                push(&format!("beier_neely.{key}"), why);
            }
        }
    }
    let limit = TpsExactDoc::MAX_SAMPLES_LIMIT;
    if let Some(n) = solver.tps_exact.map(|t| t.max_samples).filter(|n| !(1..=limit).contains(n)) {
        let why = format!("max_samples must be a whole number from 1 to {limit}, found {n}; the default is 1000 (the fit takes O(n³) time and O(n²) memory)");
        push("tps_exact.max_samples", why);
    }
    p
}

fn check_points(points: &[Point], path: &str, p: &mut Vec<Problem>) {
    for (i, point) in points.iter().enumerate() {
        for (c, &v) in point.iter().enumerate() {
            let why = if !v.is_finite() {
                format!("coordinates must be finite numbers of pixels, found {v}")
            } else if !limits::coordinate_ok(v) {
                let v = limits::show(v);
                format!("coordinates may be at most {MAX_COORD_PX:e} pixels from the origin, found {v}; is the point in pixels?")
            } else {
                continue;
            };
            p.push(Problem::new(format!("{path}[{i}][{c}]"), why));
        }
    }
}

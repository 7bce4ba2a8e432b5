//! Scenes (DESIGN §8–9): the file format, its validation, and the engine that turns a
//! scene into fields and frames.
//!
//! - [`doc`]: the format as serde types, and its JSON Schema.
//! - [`parse_doc`]: JSON text to a validated [`SceneDoc`], every problem reported as a
//!   [`Problem`] (a JSON path and a message that says how to fix it).
//! - [`Scene::from_json`]: a document plus its images (read by the front end through a
//!   loader callback; `data:` URIs decoded here) to a renderable scene.
//! - [`Scene::render`], [`Animator`], [`FrameStream`]: fields and frames, warm-started from
//!   frame to frame, in parallel across cores for whole animations.
//!
//! ```
//! use inkwarp_core::scene::{no_files, Scene};
//!
//! let json = r#"{"inkwarp": 1, "width": 8, "height": 6, "layers": [{"name": "main"}],
//!                "features": [{"id": "p", "kind": "point", "rest": [[3, 3]],
//!                              "keys": [{"t": 0, "points": [[3, 3]]},
//!                                       {"t": 1, "points": [[4, 3]]}]}]}"#;
//! let scene = Scene::from_json(json, &mut no_files).unwrap();
//! assert_eq!((scene.width(), scene.height(), scene.frame_count()), (8, 6, 25));
//! let frame = scene.render(0.5).unwrap();
//! assert_eq!(frame.data.len(), 8 * 6 * 4);
//! ```

pub mod doc;
mod engine;
pub mod images;
mod shape;
mod validate;

use std::collections::HashMap;
use std::fmt;
use std::sync::{Arc, OnceLock};

use serde::Serialize;
use serde_json::Value;

pub use doc::*;
pub use engine::{default_frame_threads, method_available, Animator, FeatureSamples, FrameStream, LayerSolve, RenderedFrame, WARM_CHAIN_FRAMES};
pub use crate::render::RgbaImage;
pub use validate::{validate_doc, validate_overrides};

use crate::geometry::{Kind, Point};
use crate::grid::Grid;

/// One thing wrong with a scene: where (a JSON path such as `features[3].keys[1].points`,
/// empty for the whole document) and what, with the fix where it is clear.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Problem {
    pub path: String,
    pub message: String,
}

impl Problem {
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Problem { path: path.into(), message: message.into() }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.is_empty() {
            write!(f, "{}", self.message)
        } else {
            write!(f, "{}: {}", self.path, self.message)
        }
    }
}

/// A scene that cannot be read or rendered, with every problem found (at least one).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct SceneError {
    pub problems: Vec<Problem>,
}

impl SceneError {
    pub fn one(path: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError { problems: vec![Problem::new(path, message)] }
    }

    /// The first problem's path.
    pub fn path(&self) -> &str { self.problems.first().map_or("", |p| p.path.as_str()) }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.problems.as_slice() {
            [] => write!(f, "the scene is invalid"),
            [one] => write!(f, "{one}"),
            many => {
                write!(f, "{} problems:", many.len())?;
                for problem in many {
                    write!(f, "\n  {problem}")?;
                }
                Ok(())
            }
        }
    }
}

/// The schema as a value, generated once.
fn cached_schema() -> &'static Value {
    static SCHEMA: OnceLock<Value> = OnceLock::new();
    SCHEMA.get_or_init(schema)
}

/// Parses and validates scene JSON text (everything but the images).
pub fn parse_doc(text: &str) -> Result<SceneDoc, SceneError> {
    let parsed = parse_json(text)?;
    match parsed.doc {
        Some(doc) if parsed.problems.is_empty() => Ok(doc),
        _ => Err(SceneError { problems: parsed.problems }),
    }
}

/// Solver settings given as JSON outside a scene file (by a caller that applies them over
/// every layer's own, as `inkwarp compare` does), checked as a scene's `solver` is; the
/// problems' paths start with `path`.
pub fn parse_overrides(text: &str, path: &str) -> Result<SolverOverrides, SceneError> {
    let mut de = serde_json::Deserializer::from_str(text);
    let overrides: SolverOverrides = serde_path_to_error::deserialize(&mut de).map_err(|err| {
        let inner = err.path().to_string();
        let at = if inner == "." { path.to_string() } else { format!("{path}.{inner}") };
        SceneError::one(at, err.into_inner().to_string())
    })?;
    match validate_overrides(&overrides, path) {
        problems if problems.is_empty() => Ok(overrides),
        problems => Err(SceneError { problems }),
    }
}

/// JSON text read by [`parse_value`]; an error only when the text is not JSON.
fn parse_json(text: &str) -> Result<Parsed, SceneError> {
    let value: Value = serde_json::from_str(text)
        .map_err(|err| SceneError::one("", format!("the scene is not valid JSON: {err}")))?;
    Ok(parse_value(&value))
}

/// The outcome of reading a document: the document (when one could be built), every
/// problem found, and for a document rebuilt without its broken features and layers, where
/// each kept one was in the original (so later problems get the original paths; empty:
/// the paths are the original ones).
#[derive(Default)]
struct Parsed {
    doc: Option<SceneDoc>,
    problems: Vec<Problem>,
    feature_origin: Vec<usize>,
    layer_origin: Vec<usize>,
}

impl Parsed {
    /// `path` (of the rebuilt document) as a path of the original one.
    fn original_path(&self, path: &str) -> String {
        for (prefix, origin) in [("features[", &self.feature_origin), ("layers[", &self.layer_origin)] {
            let split = path.strip_prefix(prefix).and_then(|rest| rest.split_once(']'));
            if let Some((&original, tail)) = split.and_then(|(index, tail)| Some((origin.get(index.parse::<usize>().ok()?)?, tail))) {
                return format!("{prefix}{original}]{tail}");
            }
        }
        path.to_string()
    }

    /// Adds problems of the rebuilt document, skipping places that already have one.
    fn extend(&mut self, problems: Vec<Problem>) {
        for mut problem in problems {
            problem.path = self.original_path(&problem.path);
            // And the places its message names (`layers[0]` of the rebuilt document is `layers[1]` past a broken one).
            problem.message = problem.message.split(' ').map(|word| self.original_path(word)).collect::<Vec<_>>().join(" ");
            if !self.problems.iter().any(|p| p.path == problem.path) {
                self.problems.push(problem);
            }
        }
    }
}

/// Shape check, then typed deserialization, then the meaning check.
fn parse_value(value: &Value) -> Parsed {
    let (problems, unknown_keys) = shape::check_detailed(value, cached_schema());
    let mut parsed = Parsed { problems, ..Parsed::default() };
    if parsed.problems.is_empty() {
        match serde_path_to_error::deserialize::<_, SceneDoc>(value) {
            Ok(doc) => {
                parsed.extend(validate_doc(&doc));
                parsed.doc = Some(doc);
            }
            Err(err) => {
                let path = err.path().to_string();
                let path = if path == "." { String::new() } else { path };
                parsed.problems.push(Problem::new(path, err.into_inner().to_string()));
            }
        }
        return parsed;
    }
    // With shape problems, rebuild the document without what is broken (unknown keys,
    // features and layers with problems, top-level values replaced by their defaults) so
    // that the meaning check and the images can report their problems too.
    let had_layers = value.get("layers").and_then(Value::as_array).is_some_and(|a| !a.is_empty());
    // The features' ids and the layers' names, for the uniqueness across items set aside below.
    let names = |list: &str, key: &str| -> Vec<Option<&str>> {
        value.get(list).and_then(Value::as_array).map_or(Vec::new(), |items| items.iter().map(|item| item.get(key).and_then(Value::as_str)).collect())
    };
    let (ids, layer_names) = (names("features", "id"), names("layers", "name"));
    let mut value = value.clone();
    let schema = cached_schema();
    strip_unknown_keys(&mut value, schema, schema);
    let Value::Object(mut map) = value else { return parsed };
    // A problem at exactly `path`, and one at or under `prefix` (unknown keys were set
    // aside, so they break nothing).
    let at = |path: &str| parsed.problems.iter().any(|p| p.path == path);
    let broken = |prefix: &str| {
        parsed.problems.iter().filter(|p| !unknown_keys.contains(&p.path)).any(|p| {
            p.path == prefix || p.path.starts_with(&format!("{prefix}.")) || p.path.starts_with(&format!("{prefix}["))
        })
    };
    // Keeps the items of the array `key` without problems and says where each kept one was;
    // the meaning check still knows the ids of the features set aside.
    let mut set_aside_ids = Vec::new();
    let mut keep = |map: &mut serde_json::Map<String, Value>, key: &str| {
        let mut origin = Vec::new();
        if let Some(Value::Array(items)) = map.get_mut(key) {
            for (i, item) in std::mem::take(items).into_iter().enumerate() {
                if !broken(&format!("{key}[{i}]")) {
                    items.push(item);
                    origin.push(i);
                } else if let Some(id) = item.get("id").and_then(Value::as_str).filter(|_| key == "features") {
                    set_aside_ids.push(id.to_string());
                }
            }
        }
        origin
    };
    parsed.feature_origin = keep(&mut map, "features");
    parsed.layer_origin = keep(&mut map, "layers");
    if let Some(Value::Object(solver)) = map.get_mut("solver") {
        // The method settings are objects of their own: drop only their broken keys (the
        // others keep their values for the meaning check), unless the object as a whole
        // is broken.
        solver.retain(|key, value| {
            let path = format!("solver.{key}");
            match value {
                Value::Object(_) if at(&path) => false,
                Value::Object(settings) => {
                    settings.retain(|inner, _| !broken(&format!("{path}.{inner}")));
                    true
                }
                _ => !broken(&path),
            }
        });
    }
    // Arrays and the solver were repaired element by element above; they are broken as a
    // whole only when the value itself has the wrong type.
    let repaired = |k: &str| matches!(k, "features" | "layers" | "solver");
    let broken_top: Vec<String> = map.keys().filter(|k| if repaired(k) { at(k) } else { broken(k) }).cloned().collect();
    for key in broken_top {
        match key.as_str() {
            "inkwarp" => map.insert(key, Value::from(FORMAT_VERSION)),
            "layers" | "features" => map.insert(key, Value::Array(Vec::new())),
            _ => map.remove(&key),
        };
    }
    map.entry("inkwarp").or_insert(Value::from(FORMAT_VERSION));
    map.entry("layers").or_insert(Value::Array(Vec::new()));
    if let Ok(doc) = serde_json::from_value::<SceneDoc>(Value::Object(map)) {
        // Layers set aside for their problems are no missing layer.
        parsed.extend(validate::validate_doc_knowing(&doc, &set_aside_ids, had_layers));
        parsed.doc = Some(doc);
    }
    // Ids and names are unique across every item: the meaning check saw the kept ones only, so
    // an item set aside for its problems and another with its id or name are told here.
    for (values, (noun, key, list)) in [(ids, ("feature", "id", "features")), (layer_names, ("layer", "name", "layers"))] {
        let origin = if list == "features" { &parsed.feature_origin } else { &parsed.layer_origin };
        let mut first = std::collections::HashMap::new();
        let mut found = Vec::new();
        for (i, value) in values.iter().enumerate() {
            let Some(value) = value.filter(|v| !v.trim().is_empty()) else { continue };
            match first.get(value) {
                Some(&j) if !(origin.contains(&i) && origin.contains(&j)) => {
                    found.push(Problem::new(format!("{list}[{i}].{key}"), validate::already_used(value, j, (noun, key, list))));
                }
                Some(_) => {}
                None => _ = first.insert(value, i),
            }
        }
        found.retain(|f| !parsed.problems.iter().any(|p| p.path == f.path));
        parsed.problems.extend(found);
    }
    parsed
}

/// Removes object keys that the schema does not know (they were reported already).
fn strip_unknown_keys(value: &mut Value, schema: &Value, root: &Value) {
    let schema = shape::resolve_ref(schema, root).0;
    if let Some(alternatives) = schema.get("anyOf").and_then(Value::as_array) {
        for alternative in alternatives {
            strip_unknown_keys(value, alternative, root);
        }
        return;
    }
    match (value, schema.get("properties").and_then(Value::as_object), schema.get("items")) {
        (Value::Object(map), Some(properties), _) => {
            map.retain(|key, _| properties.contains_key(key));
            for (key, child) in map.iter_mut() {
                strip_unknown_keys(child, &properties[key], root);
            }
        }
        (Value::Array(items), _, Some(item_schema)) => {
            for item in items {
                strip_unknown_keys(item, item_schema, root);
            }
        }
        _ => {}
    }
}

/// A scene ready to render: its document, its decoded images, and per layer the solve
/// domain (continuity matte and cuts) and the features that drive it.
#[derive(Debug)]
pub struct Scene {
    doc: SceneDoc,
    width: usize,
    height: usize,
    duration_s: f64,
    frame_count: usize,
    layers: Vec<Layer>,
}

/// A layer ready to render.
#[derive(Debug)]
pub struct Layer {
    /// The layer's name.
    pub name: String,
    /// The picture with the alpha matte applied, when the layer has one.
    pub image: Option<Arc<RgbaImage>>,
    /// Active nodes and links: the continuity matte with the layer's cuts applied.
    pub grid: Grid,
    /// Indices (into the scene's features) of the features that move this layer (cuts
    /// excluded: they are in `grid`).
    pub drivers: Vec<usize>,
    /// Where the layer is drawn in the frame.
    pub offset: [f64; 2],
    /// The scene's solver settings with the layer's overrides applied.
    pub solver: SolverDoc,
    /// Whether the layer is drawn.
    pub visible: bool,
    /// Whether the layer's outer edge is held still.
    pub border: Border,
    /// Per driver (same order as `drivers`): its rest geometry prepared for sampling on
    /// this layer's grid, built on first use.
    pub(crate) samplers: Vec<OnceLock<Result<crate::geometry::FeatureSampler, String>>>,
}

/// Reads the bytes behind an image reference that is not a `data:` URI (a path relative to
/// the scene file); returns a message saying why when it cannot.
pub type Loader<'a> = dyn FnMut(&str) -> Result<Vec<u8>, String> + 'a;

/// A [`Loader`] for scenes whose images are all `data:` URIs (or that have none).
pub fn no_files(reference: &str) -> Result<Vec<u8>, String> {
    Err(format!("this scene can only use data: URIs, not the path \"{reference}\""))
}

impl Scene {
    /// Parses, validates and resolves scene JSON text; `load` supplies the bytes of image
    /// paths (`data:` URIs are decoded here). Every problem is reported, images included.
    pub fn from_json(text: &str, load: &mut Loader<'_>) -> Result<Scene, SceneError> {
        let mut parsed = parse_json(text)?;
        let Some(doc) = parsed.doc.take() else { return Err(SceneError { problems: parsed.problems }) };
        let mut problems = Vec::new();
        // Decode every image once, keep the problems of each place that refers to it.
        let mut decoded: HashMap<String, Result<Arc<RgbaImage>, String>> = HashMap::new();
        let mut layer_images: Vec<[Option<Arc<RgbaImage>>; 3]> = Vec::new();
        let mut size = doc.width.zip(doc.height).filter(|&(w, h)| w > 0 && h > 0).map(|(w, h)| (w as usize, h as usize, "width and height".to_string()));
        for (j, layer) in doc.layers.iter().enumerate() {
            let mut slots: [Option<Arc<RgbaImage>>; 3] = [None, None, None];
            let references = [("image", &layer.image), ("alpha", &layer.alpha), ("continuity", &layer.continuity)];
            for (slot, (key, reference)) in references.into_iter().enumerate() {
                let Some(reference) = reference.as_deref().filter(|r| !r.trim().is_empty()) else {
                    continue;
                };
                let path = format!("layers[{j}].{key}");
                let result = decoded.entry(reference.to_string()).or_insert_with(|| {
                    let uri = images::is_data_uri(reference);
                    let bytes = if uri { images::data_uri_bytes(reference) } else { load(reference) };
                    bytes.and_then(|b| images::decode_image(&b)).map(Arc::new)
                }).clone();
                let image = match result {
                    Ok(image) => image,
                    Err(why) => {
                        let why = format!("cannot use {}: {why}", describe_reference(reference));
                        problems.push(Problem::new(&path, why));
                        continue;
                    }
                };
                match &size {
                    None => size = Some((image.width, image.height, path.clone())),
                    Some((w, h, from)) if (image.width, image.height) != (*w, *h) => {
                        let (what, iw, ih) = (describe_reference(reference), image.width, image.height);
                        problems.push(Problem::new(&path, format!("{what} is {iw}×{ih} pixels but the scene is {w}×{h} (from {from}); every image and matte must be the scene's size")));
                        continue;
                    }
                    Some(_) => {}
                }
                slots[slot] = Some(image);
            }
            layer_images.push(slots);
        }
        // A size given by one key alone: the images must agree with it, or the other is missing.
        let alone = match (doc.width, doc.height) { (Some(w), None) => Some(("width", "height", w, 0)), (None, Some(h)) => Some(("height", "width", h, 1)), _ => None };
        match (&size, alone) {
            (Some((w, h, from)), Some((key, _, given, axis))) if [*w, *h][axis] != given as usize => problems.push(Problem::new(key, format!("{given} does not match the images, which are {w}×{h} (from {from}); set both \"width\" and \"height\" to the images' size, or leave both out"))),
            (None, _) if !doc.layers.is_empty() && problems.is_empty() => problems.push(Problem::new(alone.map_or("width", |a| a.1), "no layer has an image to take the frame size from; set both \"width\" and \"height\"")),
            _ => {}
        }
        parsed.extend(problems);
        if !parsed.problems.is_empty() {
            return Err(SceneError { problems: parsed.problems });
        }
        let (width, height, _) = size.expect("checked above");

        let index_of: HashMap<&str, usize> = doc.features.iter().enumerate().map(|(i, f)| (f.id.as_str(), i)).collect();

        let mut layers = Vec::with_capacity(doc.layers.len());
        for (layer, [image, alpha, continuity]) in doc.layers.iter().zip(layer_images) {
            let image = match (image, alpha) {
                (Some(image), Some(alpha)) => {
                    let mut with_alpha = (*image).clone();
                    for (px, a) in with_alpha.data.chunks_exact_mut(4).zip(images::matte_values(&alpha)) {
                        px[3] = a;
                    }
                    Some(Arc::new(with_alpha))
                }
                (image, _) => image,
            };
            let mut grid = match (&continuity, &image) {
                (Some(matte), _) => Grid::from_matte(width, height, &images::matte_values(matte)),
                (None, Some(image)) => Grid::from_matte(width, height, &image.data.iter().skip(3).step_by(4).copied().collect::<Vec<_>>()),
                (None, None) => Grid::new(width, height),
            };
            let members: Vec<usize> = match &layer.features {
                Some(ids) => ids.iter().map(|id| index_of[id.as_str()]).collect(),
                None => (0..doc.features.len()).collect(),
            };
            let (cuts, drivers): (Vec<usize>, Vec<usize>) = members.into_iter().partition(|&i| doc.features[i].kind == Kind::Cut);
            for cut in cuts.iter().map(|&i| &doc.features[i]) {
                grid.add_cut(&crate::geometry::curve_polyline(Kind::Cut, &to_layer(&cut.rest, layer.offset), cut.closed, false, 0.5));
            }
            let (name, offset, visible, border) = (layer.name.clone(), layer.offset, layer.visible, layer.border);
            let solver = layer.solver.as_ref().map_or_else(|| doc.solver.clone(), |o| o.apply(&doc.solver));
            let samplers = drivers.iter().map(|_| OnceLock::new()).collect();
            layers.push(Layer { name, image, grid, drivers, offset, solver, visible, border, samplers });
        }

        let duration_s = doc.duration.unwrap_or_else(|| {
            doc.features.iter().flat_map(|f| f.keys.iter().map(|k| k.time_s)).fold(0.0, f64::max) + 1.0 / doc.fps
        });
        let frame_count = ((duration_s * doc.fps - 1e-9).ceil() as usize).max(1);
        Ok(Scene { doc, width, height, duration_s, frame_count, layers })
    }

    /// The document this scene was built from (defaults filled in).
    pub fn doc(&self) -> &SceneDoc { &self.doc }
    /// Frame width in pixels.
    pub fn width(&self) -> usize { self.width }
    /// Frame height in pixels.
    pub fn height(&self) -> usize { self.height }
    /// Frames per second.
    pub fn fps(&self) -> f64 { self.doc.fps }
    /// Length in seconds (the document's, or up to and including the last key).
    pub fn duration_s(&self) -> f64 { self.duration_s }
    /// Number of frames: `ceil(duration * fps)`, at least 1.
    pub fn frame_count(&self) -> usize { self.frame_count }
    /// The time of frame `i`: `i / fps` seconds.
    pub fn frame_time_s(&self, i: usize) -> f64 { i as f64 / self.doc.fps }
    /// The layers, back to front.
    pub fn layers(&self) -> &[Layer] { &self.layers }
}

fn describe_reference(reference: &str) -> String {
    if images::is_data_uri(reference) {
        let header: String = reference.chars().take_while(|&c| c != ',').take(40).collect();
        format!("the image in the {header},... URI")
    } else {
        format!("\"{reference}\"")
    }
}

/// `points` of the frame in the grid of a layer placed at `offset` (the drawing is traced in the frame).
pub(crate) fn to_layer(points: &[Point], offset: [f64; 2]) -> Vec<Point> { points.iter().map(|p| [p[0] - offset[0], p[1] - offset[1]]).collect() }

#[cfg(test)]
mod tests;

//! The scene file format, version 1 (DESIGN §8), as serde types.
//!
//! These types are the single source of truth for the format: the JSON Schema shipped with
//! the package is generated from them ([`schema`]), the shape check walks that schema, and
//! the reference documentation is checked against it. The `///` comments below become the
//! schema's descriptions, so they are written for animators reading the schema; so do those
//! of the types the engine shares with the format ([`Method`], [`Interpolation`], [`KeyDoc`]
//! and the feature kind, `geometry::Kind`).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::geometry::{Kind, Point};

/// The scene format version this engine reads and writes.
pub const FORMAT_VERSION: u32 = 1;

/// An inkwarp scene: images in layers, a drawing traced over them, and how the drawing
/// moves over time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "inkwarp scene", extend("$id" = "https://inkwarp.dev/schema/scene-1.json"))]
pub struct SceneDoc {
    /// The scene format version. Always 1.
    #[schemars(extend("const" = 1))]
    pub inkwarp: u32,
    /// Frame width in pixels. Default: the width of the first layer image; given without `height`, it must be that width.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1))]
    pub width: Option<u32>,
    /// Frame height in pixels. Default: the height of the first layer image; given without `width`, it must be that height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1))]
    pub height: Option<u32>,
    /// Frames per second, from 0.001 (one frame every 1000 s) to 1000. Frame `i` shows the drawing at time `i / fps` seconds.
    #[serde(default = "default_fps")]
    pub fps: f64,
    /// Length of the animation in seconds (> 0); it has `ceil(duration * fps)` frames.
    /// Default: up to and including the last key (one frame when there are no keys).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration: Option<f64>,
    /// Straight-alpha RGBA colour behind every layer, each 0–255.
    #[serde(default = "default_background")]
    pub background: [u8; 4],
    /// How the displacement field is computed (every layer, unless the layer overrides it).
    #[serde(default)]
    pub solver: SolverDoc,
    /// The layers, back to front: the first is drawn first, the last ends up on top.
    pub layers: Vec<LayerDoc>,
    /// The drawing: every feature, traced over the rest (original) images.
    #[serde(default)]
    pub features: Vec<FeatureDoc>,
}

pub use crate::anim::{Interpolation, Key as KeyDoc};
pub use crate::methods::Method;

/// How the grid thin plate is relaxed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Scheme {
    /// Multigrid cycles until the estimated largest error left at any pixel is below
    /// `tolerance`.
    #[default]
    Multigrid,
    /// Southwell (greedy residual) relaxation, as the paper describes.
    Southwell,
}

/// Solver settings for the whole scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SolverDoc {
    /// `tps` (the grid thin plate, default), `tps-exact`, `triangulation` or `beier-neely`.
    #[serde(default)]
    pub method: Method,
    /// Membrane weight τ ≥ 0 added to the thin-plate energy; 0 (default) is a pure plate,
    /// larger values make the surface tauter between features.
    #[serde(default)]
    #[schemars(range(min = 0.0))]
    pub tension: f64,
    /// Stop when the estimated largest error left at any pixel is below this many pixels
    /// (> 0).
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Solve on every `grid_step`-th pixel and upsample (≥ 1; 1 solves on every pixel).
    /// The drawing is also sampled every `grid_step` pixels. Parts of the matte thinner than the step (hair, 1–2 px strands) come apart on the coarse grid and move unbent with what they hang from, or, where strands cross or lie close, with a neighbouring strand (a point on one may be dropped): keep 1 where they must bend. Features closer than the step that move apart (lids that close, lips that part) share coarse nodes, each of which holds only one of them: the picture tears between them; `inkwarp validate` notes such pairs. Where `width − 1` or `height − 1` is no multiple of the step, the last coarse cell, r pixels wide, is solved as a full one: a motion that scales by k bends by up to k × (step − r) px along the right or bottom edge (0.6 px for a 10 % scale at step 7 on 65 × 65); choose such a size, or 1, where that matters.
    #[serde(default = "default_grid_step")]
    #[schemars(range(min = 1, max = 64))]
    pub grid_step: u32,
    /// At most this many cycles per solve (≥ 1; southwell: rounds). Default: 300, or fewer where `tolerance` is met first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1))]
    pub max_cycles: Option<u32>,
    /// `multigrid` (default) or `southwell`.
    #[serde(default)]
    pub scheme: Scheme,
    /// The weights of `beier-neely` (used when a layer's method is `beier-neely`, and by
    /// `inkwarp compare`). Default: `a` 1, `b` 2, `p` 0.
    #[serde(default, skip_serializing_if = "is_default")]
    #[schemars(extend("default" = {"a": 1.0, "b": 2.0, "p": 0.0}))]
    pub beier_neely: BeierNeelyDoc,
    /// The settings of `tps-exact` (used when a layer's method is `tps-exact`, and by
    /// `inkwarp compare`). Default: `max_samples` 1000.
    #[serde(default, skip_serializing_if = "is_default")]
    #[schemars(extend("default" = {"max_samples": 1000}))]
    pub tps_exact: TpsExactDoc,
}

impl Default for SolverDoc {
    fn default() -> Self {
        SolverDoc {
            method: Method::Tps,
            tension: 0.0,
            tolerance: default_tolerance(),
            grid_step: default_grid_step(),
            max_cycles: None,
            scheme: Scheme::Multigrid,
            beier_neely: BeierNeelyDoc::default(),
            tps_exact: TpsExactDoc::default(),
        }
    }
}

/// Beier & Neely's weights: a line or point at distance `d` from a pixel weighs
/// `(length^p / (a + d))^b` there (a point has `length^p` = 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BeierNeelyDoc {
    /// Pixels (> 0): how tightly a line or point holds what lies on it. Smaller values
    /// follow the drawing more exactly, with cusps on it; larger ones are smoother and
    /// looser.
    #[serde(default = "default_bn_a")]
    pub a: f64,
    /// How fast a primitive's influence falls off with distance (≥ 0; Beier & Neely
    /// suggest 0.5–2). 0 weights every primitive the same everywhere.
    #[serde(default = "default_bn_b")]
    #[schemars(range(min = 0.0))]
    pub b: f64,
    /// How much longer lines outweigh shorter ones (≥ 0; Beier & Neely use 0–1). 0 weighs
    /// every line the same as every other, and as a point.
    #[serde(default)]
    #[schemars(range(min = 0.0))]
    pub p: f64,
}

impl Default for BeierNeelyDoc {
    fn default() -> Self { BeierNeelyDoc { a: default_bn_a(), b: default_bn_b(), p: 0.0 } }
}

/// Settings of the continuous thin-plate spline.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TpsExactDoc {
    /// At most this many distinct sample positions are fitted (1–5000); more are thinned
    /// by farthest-point sampling, deterministically. The fit costs `O(n³)` time and
    /// `O(n²)` memory.
    #[serde(default = "default_max_samples")]
    #[schemars(range(min = 1, max = 5000))]
    pub max_samples: u32,
}

impl Default for TpsExactDoc { fn default() -> Self { TpsExactDoc { max_samples: default_max_samples() } } }

impl TpsExactDoc {
    /// The most `max_samples` a scene may ask for: the fit holds an `(n + 3)²` matrix of
    /// f64 (200 MB at 5000).
    pub const MAX_SAMPLES_LIMIT: u32 = 5000;
}

/// Per-layer solver overrides: each key given replaces the scene's `solver` value.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SolverOverrides {
    /// Overrides `solver.method`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<Method>,
    /// Overrides `solver.tension` (≥ 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub tension: Option<f64>,
    /// Overrides `solver.tolerance` (> 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Overrides `solver.grid_step` (≥ 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1, max = 64))]
    pub grid_step: Option<u32>,
    /// Overrides `solver.max_cycles` (≥ 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1))]
    pub max_cycles: Option<u32>,
    /// Overrides `solver.scheme`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scheme: Option<Scheme>,
    /// Overrides `solver.beier_neely` as a whole (keys left out take their defaults).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beier_neely: Option<BeierNeelyDoc>,
    /// Overrides `solver.tps_exact` as a whole (keys left out take their defaults).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tps_exact: Option<TpsExactDoc>,
}

impl SolverOverrides {
    /// The overrides that only change the method (none for `None`).
    pub fn method(method: Option<Method>) -> Self { SolverOverrides { method, ..Self::default() } }

    /// The scene's settings with these overrides applied.
    pub fn apply(&self, base: &SolverDoc) -> SolverDoc {
        SolverDoc {
            method: self.method.unwrap_or(base.method),
            tension: self.tension.unwrap_or(base.tension),
            tolerance: self.tolerance.unwrap_or(base.tolerance),
            grid_step: self.grid_step.unwrap_or(base.grid_step),
            max_cycles: self.max_cycles.or(base.max_cycles),
            scheme: self.scheme.unwrap_or(base.scheme),
            beier_neely: self.beier_neely.unwrap_or(base.beier_neely),
            tps_exact: self.tps_exact.unwrap_or(base.tps_exact),
        }
    }
}

/// One layer: an image that the drawing warps, composited over the layers before it.
///
/// Image references are paths relative to the scene file, or `data:` URIs
/// (`data:image/png;base64,...`). Every image and matte has the scene's size. A matte's
/// value at a pixel is its grey level times its alpha (black or transparent is 0).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LayerDoc {
    /// A name, unique among the layers (used by `scene.field(layer=...)`).
    pub name: String,
    /// The picture (PNG or JPEG). Without one the layer draws nothing but still has a field.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<String>,
    /// Alpha matte: replaces the image's own alpha channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<String>,
    /// Continuity matte: nonzero pixels are connected surface, zero pixels are holes the
    /// surface can tear along. Default: where the layer's alpha is > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub continuity: Option<String>,
    /// Where the warped layer is placed in the frame, `[dx, dy]` pixels. It reads the drawing
    /// (in the frame's coordinates) at `p − offset`: a drawing over it where it shows moves it.
    #[serde(default, skip_serializing_if = "is_default")]
    #[schemars(extend("default" = [0.0, 0.0]))]
    pub offset: [f64; 2],
    /// Ids of the features that drive this layer. Default: every feature.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub features: Option<Vec<String>>,
    /// Solver settings for this layer only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<SolverOverrides>,
    /// Whether the layer is drawn (its field can be computed either way).
    #[serde(default = "default_true", skip_serializing_if = "is_true")]
    #[schemars(extend("default" = true))]
    pub visible: bool,
    /// `free` (default): the layer's outer edge moves with the surface; `hold`: it stays
    /// put, so the picture never pulls away from the frame's edge.
    #[serde(default, skip_serializing_if = "is_default")]
    #[schemars(extend("default" = "free"))]
    pub border: Border,
}

/// The outline of a region.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Curve {
    /// Straight segments between the points (default).
    #[default]
    Polyline,
    /// A closed centripetal Catmull-Rom spline through the points.
    Spline,
}

/// One feature of the drawing: its rest geometry and its keys.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FeatureDoc {
    /// A name, unique among the features (layers list features by id).
    pub id: String,
    /// `point`, `polyline`, `spline`, `region` or `cut`.
    pub kind: Kind,
    /// Control points `[x, y]` traced over the original image, in the frame's coordinates
    /// (pixel centres at integer coordinates, y down).
    pub rest: Vec<Point>,
    /// Whether a polyline, spline or cut joins its last point back to its first (a closed
    /// cut frees what it encloses; regions are always closed).
    #[serde(default, skip_serializing_if = "is_default")]
    #[schemars(extend("default" = false))]
    pub closed: bool,
    /// Regions only: the outline through the points, `polyline` (default) or `spline`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub curve: Option<Curve>,
    /// The feature at other times, in increasing time order. Without keys it stays at rest;
    /// before the first key it holds the first, after the last it holds the last.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(extend("default" = []))]
    pub keys: Vec<KeyDoc>,
}

impl FeatureDoc {
    /// Whether its outline is a spline (`"curve": "spline"`, for regions).
    pub fn spline_outline(&self) -> bool { self.curve == Some(Curve::Spline) }
}

/// What holds a layer's outer edge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Border {
    /// Nothing: the edge moves with the surface like any other part of it.
    #[default]
    Free,
    /// The edge stays where it is: every node on the layer's outer edge is held at zero
    /// displacement (the paper's "four stationary lines along the edges").
    Hold,
}

fn default_fps() -> f64 { 24.0 }
fn default_background() -> [u8; 4] { [255, 255, 255, 255] }
fn default_tolerance() -> f64 { 0.01 }
fn default_grid_step() -> u32 { 1 }
fn default_bn_a() -> f64 { crate::methods::BeierNeelyParams::DEFAULT.a }
fn default_bn_b() -> f64 { crate::methods::BeierNeelyParams::DEFAULT.b }
fn default_max_samples() -> u32 { crate::methods::DEFAULT_MAX_SAMPLES as u32 }
fn default_true() -> bool { true }
fn is_true(v: &bool) -> bool { *v }
/// Whether a value is its type's default, which files leave out.
pub(crate) fn is_default<T: Default + PartialEq>(v: &T) -> bool { *v == T::default() }

/// The JSON Schema (draft 2020-12) of the scene format, generated from [`SceneDoc`].
pub fn schema() -> serde_json::Value {
    let settings = schemars::generate::SchemaSettings::draft2020_12();
    let schema = settings.into_generator().into_root_schema_for::<SceneDoc>();
    serde_json::to_value(schema).expect("a schema is always valid JSON")
}

/// [`schema`] as pretty-printed JSON text.
pub fn schema_json() -> String { serde_json::to_string_pretty(&schema()).expect("a schema is always valid JSON") }

//! The interpolants the paper compares the grid thin plate against (DESIGN §6).
//!
//! Every method turns the same controls (samples of the drawing, and for Beier–Neely
//! line pairs) into a displacement [`Field`] on the rest image, so that all of them feed
//! the same forward-mapping renderer and a comparison is only about the surface:
//!
//! | [`Interpolant`] | what it is | holes/cuts |
//! |---|---|---|
//! | [`Interpolant::TpsExact`] | the continuous thin-plate spline (`r² log r` kernel plus an affine part) fitted to the samples, evaluated at every node ([`ThinPlateMap`]) | ignored |
//! | [`Interpolant::Triangulation`] | Delaunay triangulation of the samples and the four image corners (held at zero), linear in each triangle | ignored |
//! | [`Interpolant::BeierNeely`] | Beier & Neely's line-pair field for segments, Shepard weights for points | ignored |
//!
//! The grid thin plate itself (`tps`, the default) lives in `solve`; [`Method`] names all
//! four for the scene format, the command line and the Python API.
//!
//! None of these methods knows about mattes or cuts: the paper's point is that the
//! continuous interpolants cannot be given holes. [`controls_field`] says so in its report
//! when the grid it was handed has any.
//!
//! ```
//! use inkwarp_core::methods::{field, Controls, Interpolant, MethodParams};
//! use inkwarp_core::Sample;
//!
//! // One sample pulled 3 px right, the corners held: a tent of triangles.
//! let controls = Controls::from_samples(vec![Sample { rest: [4.0, 4.0], displacement: [3.0, 0.0] }]);
//! let (f, _report) = field(Interpolant::Triangulation, &controls, 9, 9, &MethodParams::default()).unwrap();
//! assert_eq!(f.at(4, 4), [3.0, 0.0]);
//! assert_eq!(f.at(0, 0), [0.0, 0.0]);
//! ```

mod beier_neely;
mod linalg;
pub mod scene;
mod thin_plate;
mod triangulation;

use std::fmt;
use std::str::FromStr;
use crate::clock::Instant;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::field::Field;
use crate::geometry::{sub, Point, Sample};
use crate::grid::Grid;

pub use beier_neely::{beier_neely_field, BeierNeelyParams};
pub use thin_plate::{thin_plate_field, ThinPlateMap, DEFAULT_MAX_SAMPLES};
pub use triangulation::triangulation_field;

// Spelled in files, on the command line and in Python as "tps", "tps-exact",
// "triangulation" and "beier-neely" (see `Method::name`).
/// The interpolant that turns the drawing into a displacement field.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// The grid thin plate of the paper: respects holes in the continuity matte and cuts.
    #[default]
    Tps,
    /// The continuous thin-plate spline fitted to the samples (no mattes, no cuts).
    TpsExact,
    /// Piecewise linear over a Delaunay triangulation of the samples and image corners.
    Triangulation,
    /// Beier–Neely line pairs for segments and Shepard weights for points.
    BeierNeely,
}

impl Method {
    /// All methods, in the order comparisons show them.
    pub const ALL: [Method; 4] =
        [Method::Tps, Method::TpsExact, Method::Triangulation, Method::BeierNeely];

    /// The name used in files, on the command line and in Python.
    pub fn name(self) -> &'static str {
        match self {
            Method::Tps => "tps",
            Method::TpsExact => "tps-exact",
            Method::Triangulation => "triangulation",
            Method::BeierNeely => "beier-neely",
        }
    }

    /// The method called `name`, if there is one.
    pub fn from_name(name: &str) -> Option<Method> { Method::ALL.into_iter().find(|m| m.name() == name) }

    /// The interpolant of this module that implements the method, or `None` for `tps`
    /// (the grid solver).
    pub fn interpolant(self) -> Option<Interpolant> {
        [Interpolant::TpsExact, Interpolant::Triangulation, Interpolant::BeierNeely].into_iter().find(|&i| Method::from(i) == self)
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result { f.write_str(self.name()) }
}

impl FromStr for Method {
    type Err = MethodError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Method::from_name(s).ok_or_else(|| MethodError::UnknownMethod(s.to_string()))
    }
}

/// The three interpolants implemented here (every [`Method`] but the grid thin plate).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interpolant {
    /// The continuous thin-plate spline, see [`ThinPlateMap`].
    TpsExact,
    /// Delaunay triangulation, see [`triangulation_field`].
    Triangulation,
    /// Beier–Neely, see [`beier_neely_field`].
    BeierNeely,
}

impl From<Interpolant> for Method {
    fn from(i: Interpolant) -> Method {
        match i {
            Interpolant::TpsExact => Method::TpsExact,
            Interpolant::Triangulation => Method::Triangulation,
            Interpolant::BeierNeely => Method::BeierNeely,
        }
    }
}

/// A segment of the rest drawing and the same segment in the pose: Beier & Neely's
/// "line pair". Its displacement field moves the rest segment onto the posed one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinePair {
    /// End points `[P, Q]` on the rest image.
    pub rest: [Point; 2],
    /// The same end points `[P', Q']` in the pose.
    pub pose: [Point; 2],
}

impl LinePair {
    /// The two end points as samples (rest position and displacement).
    pub fn end_samples(&self) -> [Sample; 2] {
        let s = |i: usize| Sample { rest: self.rest[i], displacement: sub(self.pose[i], self.rest[i]) };
        [s(0), s(1)]
    }
}

/// What drives an interpolant: samples (points with displacements) and line pairs.
///
/// `tps-exact` and `triangulation` interpolate the samples together with the line pairs'
/// end points; `beier-neely` weights the samples as Shepard points and the line pairs with
/// its line formula. A scene therefore hands Beier–Neely its point features as samples
/// and its curves as line pairs (see [`line_pairs_from_chain`]), and hands the other two
/// every sample of the drawing.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Controls {
    pub samples: Vec<Sample>,
    pub line_pairs: Vec<LinePair>,
}

impl Controls {
    /// Controls made of samples only.
    pub fn from_samples(samples: Vec<Sample>) -> Self { Controls { samples, line_pairs: Vec::new() } }

    /// The samples plus both end points of every line pair.
    pub fn all_samples(&self) -> Vec<Sample> {
        let mut all = self.samples.clone();
        all.extend(self.line_pairs.iter().flat_map(|l| l.end_samples()));
        all
    }
}

/// Turns an ordered chain of samples along one curve (as `geometry` samples it: rest
/// positions in order, each with its displacement) into Beier–Neely line pairs, keeping a
/// sample only when it is at least `min_length_px` (along the rest chain) past the last
/// kept one; the chain's last sample is always kept. `closed` adds the pair from the last
/// kept sample back to the first.
///
/// Dense samples would make Beier–Neely both slow (its cost grows with the number of
/// primitives) and different in character (many tiny segments behave like points), so a
/// scene uses segments of about a control-point spacing.
pub fn line_pairs_from_chain(chain: &[Sample], closed: bool, min_length_px: f64) -> Vec<LinePair> {
    let pose = |s: &Sample| [s.rest[0] + s.displacement[0], s.rest[1] + s.displacement[1]];
    let mut kept: Vec<&Sample> = Vec::new();
    let mut run = 0.0;
    for (i, s) in chain.iter().enumerate() {
        if let Some(prev) = i.checked_sub(1).map(|j| &chain[j]) {
            run += dist(prev.rest, s.rest);
        }
        let last = i + 1 == chain.len();
        if kept.is_empty() || run >= min_length_px || (last && run > 0.0) {
            kept.push(s);
            run = 0.0;
        }
    }
    let pair = |a: &Sample, b: &Sample| LinePair { rest: [a.rest, b.rest], pose: [pose(a), pose(b)] };
    let mut pairs: Vec<LinePair> = kept.windows(2).map(|w| pair(w[0], w[1])).collect();
    if closed && kept.len() > 2 && dist(kept[kept.len() - 1].rest, kept[0].rest) > 0.0 {
        pairs.push(pair(kept[kept.len() - 1], kept[0]));
    }
    pairs
}

/// Settings of the interpolants. The defaults are what `inkwarp compare` uses.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodParams {
    /// `tps-exact`: at most this many samples are fitted; more are thinned by
    /// farthest-point sampling (see [`ThinPlateMap::fit_samples`]). Default
    /// [`DEFAULT_MAX_SAMPLES`].
    pub max_samples: usize,
    /// `beier-neely`: the weight parameters `a`, `b`, `p`.
    pub beier_neely: BeierNeelyParams,
}

impl Default for MethodParams {
    fn default() -> Self { MethodParams { max_samples: DEFAULT_MAX_SAMPLES, beier_neely: BeierNeelyParams::default() } }
}

/// What an interpolant did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MethodReport {
    /// The method that ran.
    pub method: Option<Method>,
    /// Samples handed in (line-pair end points included for `tps-exact` and
    /// `triangulation`).
    pub samples_given: usize,
    /// Distinct sample positions actually used (after merging samples at the same
    /// position and, for `tps-exact`, thinning).
    pub samples_used: usize,
    /// Line pairs used (`beier-neely`).
    pub line_pairs_used: usize,
    /// Samples or line pairs skipped because a coordinate was not finite.
    pub dropped: usize,
    /// Whether a continuity matte or cut of the grid was ignored ([`controls_field`]).
    pub ignored_matte: bool,
    /// Full-sentence remarks worth showing a user (thinning, an ignored matte).
    pub notes: Vec<String>,
    /// Wall time of the whole call.
    pub seconds: f64,
}

/// Why an interpolant could not produce a field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MethodError {
    #[error("Unknown method \"{0}\": use one of \"tps\", \"tps-exact\", \"triangulation\", \"beier-neely\".")]
    UnknownMethod(String),
    #[error("The field must be at least 1 × 1 pixels, got {width} × {height}.")]
    EmptyField { width: usize, height: usize },
    #[error("{method} needs at least one {what}; got none.")]
    NoControls { method: &'static str, what: &'static str },
    #[error("The thin-plate system for {points} distinct sample positions is singular (pivot {pivot:.3e} at row {row}); samples that nearly coincide make it so: merge them or lower max_samples.")]
    Singular { points: usize, row: usize, pivot: f64 },
    #[error("The thin-plate map needs as many target points as source points: got {source_count} source and {target_count} target points.")]
    CountMismatch { source_count: usize, target_count: usize },
    #[error("Point {index} of the {which} points is not finite ({x}, {y}); every coordinate must be a finite number.")]
    NonFinite { which: &'static str, index: usize, x: f64, y: f64 },
    #[error("max_samples must be at least 1, got 0.")]
    ZeroMaxSamples,
    #[error("Beier–Neely parameter {name} = {value} is out of range: {hint}.")]
    BadParameter { name: &'static str, value: f64, hint: &'static str },
    #[error("The drawing could not be triangulated: {0}.")]
    Triangulation(String),
    #[error("Stopped: interrupted (Ctrl-C or SIGTERM) before the field was finished.")]
    Interrupted,
}

/// The displacement field of `interpolant` for `controls` on a `width × height` image
/// (one node per pixel centre, DESIGN §2), with a report.
///
/// # Errors
/// An empty image; no usable controls for Beier–Neely (the other two give the zero
/// field, as the grid thin plate does); non-finite coordinates in a [`ThinPlateMap`] fit;
/// bad Beier–Neely parameters; a singular thin-plate system.
pub fn field(
    interpolant: Interpolant,
    controls: &Controls,
    width: usize,
    height: usize,
    params: &MethodParams,
) -> Result<(Field, MethodReport), MethodError> {
    let start = Instant::now();
    if width == 0 || height == 0 {
        return Err(MethodError::EmptyField { width, height });
    }
    let mut report = MethodReport { method: Some(interpolant.into()), ..Default::default() };
    let f = match interpolant {
        Interpolant::TpsExact => thin_plate_field(&controls.all_samples(), width, height, params.max_samples, &mut report),
        Interpolant::Triangulation => triangulation_field(&controls.all_samples(), width, height, &mut report),
        Interpolant::BeierNeely => beier_neely_field(&controls.samples, &controls.line_pairs, width, height, &params.beier_neely, &mut report),
    };
    // The dense loops skip their remaining rows (and the elimination its remaining pivots)
    // once a stop is requested.
    if crate::interrupt::requested() {
        return Err(MethodError::Interrupted);
    }
    let f = f?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok((f, report))
}

/// Sets [`MethodReport::ignored_matte`] and adds its note when `grid` has an inactive node
/// or a missing link between two active neighbours (the report's method names itself in
/// the note).
pub fn note_ignored_matte(report: &mut MethodReport, grid: &Grid) {
    if crate::grid::torn(grid.width, &grid.active, &grid.link_right, &grid.link_down) {
        report.ignored_matte = true;
        let method = report.method.map_or("the method", Method::name);
        report.notes.push(format!("{method} ignores the continuity matte and cuts: its surface is continuous across holes."));
    }
}

/// [`field`] of a layer's controls on the node grid of `grid`: the same field (these methods
/// have no notion of a continuity matte), with [`MethodReport::ignored_matte`] set and a
/// note when the grid has an inactive node or a broken link. A layer that nothing drives
/// stays where it is, whatever the method (Beier–Neely alone has no field without a primitive).
pub fn controls_field(
    interpolant: Interpolant,
    controls: &Controls,
    grid: &Grid,
    params: &MethodParams,
) -> Result<(Field, MethodReport), MethodError> {
    if controls.samples.is_empty() && controls.line_pairs.is_empty() {
        let report = MethodReport { method: Some(interpolant.into()), ..MethodReport::default() };
        return Ok((Field::zeros(grid.width, grid.height), report));
    }
    let (f, mut report) = field(interpolant, controls, grid.width, grid.height, params)?;
    note_ignored_matte(&mut report, grid);
    Ok((f, report))
}

#[inline]
pub(crate) fn dist(a: Point, b: Point) -> f64 { (a[0] - b[0]).hypot(a[1] - b[1]) }

#[inline]
pub(crate) fn is_finite_point(p: Point) -> bool { p[0].is_finite() && p[1].is_finite() }

/// Merges samples at exactly the same rest position (averaging their displacements, as
/// the grid constraints do) and drops samples with a non-finite coordinate. The result
/// is sorted by position, so it does not depend on the input order. Returns the merged
/// samples and the number dropped.
pub(crate) fn merge_samples(samples: &[Sample]) -> (Vec<Sample>, usize) {
    let mut finite: Vec<Sample> =
        samples.iter().copied().filter(|s| is_finite_point(s.rest) && is_finite_point(s.displacement)).collect();
    let dropped = samples.len() - finite.len();
    finite.sort_by(|a, b| a.rest[0].total_cmp(&b.rest[0]).then(a.rest[1].total_cmp(&b.rest[1])));
    let merged = finite.chunk_by(|a, b| a.rest == b.rest).map(|group| {
        let [sx, sy] = group.iter().fold([0.0; 2], |[sx, sy], s| [sx + s.displacement[0], sy + s.displacement[1]]);
        let n = group.len() as f64;
        Sample { rest: group[0].rest, displacement: [sx / n, sy / n] }
    }).collect();
    (merged, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_round_trip() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>().unwrap(), m);
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(json, format!("\"{}\"", m.name()));
            assert_eq!(serde_json::from_str::<Method>(&json).unwrap(), m);
        }
        let err = "bicubic".parse::<Method>().unwrap_err();
        assert!(err.to_string().contains("\"bicubic\""));
    }

    #[test]
    fn merge_averages_coincident_samples() {
        let s = |x: f64, d: f64| Sample { rest: [x, 1.0], displacement: [d, 0.0] };
        let nan = Sample { rest: [f64::NAN, 0.0], displacement: [0.0, 0.0] };
        let (m, dropped) = merge_samples(&[s(2.0, 1.0), s(1.0, 5.0), s(2.0, 3.0), nan]);
        assert_eq!(dropped, 1);
        assert_eq!(m, vec![s(1.0, 5.0), s(2.0, 2.0)]);
    }

    #[test]
    fn chain_to_line_pairs_decimates_and_closes() {
        let chain: Vec<Sample> = (0..=10)
            .map(|i| Sample { rest: [i as f64, 0.0], displacement: [0.0, i as f64] })
            .collect();
        let pairs = line_pairs_from_chain(&chain, false, 4.0);
        let ends: Vec<f64> = pairs.iter().map(|p| p.rest[1][0]).collect();
        assert_eq!(ends, vec![4.0, 8.0, 10.0]);
        assert_eq!(pairs[0].pose, [[0.0, 0.0], [4.0, 4.0]]);
        let closed = line_pairs_from_chain(&chain, true, 4.0);
        assert_eq!(closed.len(), 4);
        assert_eq!(closed[3].rest, [[10.0, 0.0], [0.0, 0.0]]);
    }

    #[test]
    fn controls_field_reports_an_ignored_matte() {
        let controls = Controls::from_samples(vec![Sample { rest: [2.0, 2.0], displacement: [1.0, 0.0] }]);
        let open = Grid::new(5, 5);
        let (_, r) = controls_field(Interpolant::TpsExact, &controls, &open, &MethodParams::default()).unwrap();
        assert!(!r.ignored_matte && r.notes.is_empty());
        let mut matte = vec![1u8; 25];
        matte[12] = 0;
        let holed = Grid::from_matte(5, 5, &matte);
        let (f, r) = controls_field(Interpolant::TpsExact, &controls, &holed, &MethodParams::default()).unwrap();
        assert!(r.ignored_matte);
        assert!(r.notes[0].contains("tps-exact ignores the continuity matte"));
        // One sample: a translation everywhere, hole or not.
        assert!(f.dx.iter().all(|&v| (v - 1.0).abs() < 1e-6));
    }

    #[test]
    fn empty_image_is_an_error() {
        let c = Controls::default();
        let err = field(Interpolant::Triangulation, &c, 0, 3, &MethodParams::default()).unwrap_err();
        assert_eq!(err.to_string(), "The field must be at least 1 × 1 pixels, got 0 × 3.");
    }
}

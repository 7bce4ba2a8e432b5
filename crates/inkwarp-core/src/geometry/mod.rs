//! Features and their sampling into (rest position, displacement) pairs (DESIGN §3).
//!
//! A feature's rest geometry is traced over the original image; its pose is the same
//! feature at some time. Sampling walks the rest geometry at arc-length spacing no larger
//! than the grid spacing, vertices and end points included, and pairs every sample with
//! the point of the posed geometry at the same primitive parameter (the same segment or
//! span, the same parameter within it). A region also samples the grid nodes inside its
//! rest outline, moved by mean value coordinates of the outline's displacements.

mod border;
mod curve;
mod region;
mod sampler;

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::grid::Grid;

pub use border::border_samples;
pub(crate) use curve::sub;
pub use curve::{hermite_basis, Curve, CurveParameter};
pub use region::{mean_value_interpolate, nodes_inside, MeanValueInterpolator, MvcScratch};
pub use sampler::FeatureSampler;

/// A position `(x, y)` in pixels: pixel centres at integer coordinates, y down.
pub type Point = [f64; 2];

/// One constraint taken from a drawing: a point on the rest geometry and how far its
/// partner on the posed geometry has moved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub rest: Point,
    pub displacement: Point,
}

/// What a feature is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "lowercase")]
#[schemars(rename = "FeatureKind")]
pub enum Kind {
    /// One position that pins or moves its spot.
    Point,
    /// A chain of line segments through ≥ 2 vertices, open or `closed`.
    Polyline,
    /// A centripetal Catmull-Rom curve through ≥ 2 control points, open or `closed`.
    Spline,
    /// A filled closed shape (≥ 3 points): outline and interior move together.
    Region,
    /// A polyline (≥ 2 points) that moves nothing and breaks the surface along its rest
    /// geometry; a `closed` one frees what it encloses.
    Cut,
}

impl Kind {
    /// Every kind, in the order the documentation lists them.
    pub const ALL: [Kind; 5] = [Kind::Point, Kind::Polyline, Kind::Spline, Kind::Region, Kind::Cut];

    /// The kind's name as scene files spell it (`"point"`, `"polyline"`, …).
    pub fn name(self) -> &'static str {
        match self {
            Kind::Point => "point",
            Kind::Polyline => "polyline",
            Kind::Spline => "spline",
            Kind::Region => "region",
            Kind::Cut => "cut",
        }
    }

    /// The fewest control points a feature of this kind has (a point has exactly one).
    pub fn min_points(self) -> usize {
        match self {
            Kind::Point => 1,
            Kind::Polyline | Kind::Spline | Kind::Cut => 2,
            Kind::Region => 3,
        }
    }

    /// Whether a feature of this kind, given `closed` and `spline_outline`, is drawn as a
    /// closed curve and as a spline: regions are always closed, and splines and
    /// spline-outlined regions are splines.
    pub(crate) fn curve_shape(self, closed: bool, spline_outline: bool) -> (bool, bool) {
        let region = self == Kind::Region;
        (closed || region, self == Kind::Spline || (region && spline_outline))
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result { f.write_str(self.name()) }
}

impl FromStr for Kind {
    type Err = GeometryError;

    /// Parses a kind name; anything else is [`GeometryError::UnknownKind`].
    ///
    /// ```
    /// use inkwarp_core::geometry::Kind;
    /// assert_eq!("spline".parse::<Kind>().unwrap(), Kind::Spline);
    /// assert!("blob".parse::<Kind>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Kind::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| GeometryError::UnknownKind(s.to_string()))
    }
}

/// How a feature is sampled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleOptions {
    /// A polyline or spline joins its last control point back to its first. Regions are
    /// always closed; points and cuts ignore it.
    pub closed: bool,
    /// A region's outline is a closed spline through its control points instead of a
    /// closed polyline. Other kinds ignore it.
    pub spline_outline: bool,
    /// The largest arc length between consecutive samples of a curve, in pixels (the grid
    /// spacing, 1 by default).
    pub spacing_px: f64,
}

impl Default for SampleOptions {
    /// Open, polyline outline, 1 px spacing.
    fn default() -> Self { SampleOptions { closed: false, spline_outline: false, spacing_px: 1.0 } }
}

/// Why a feature cannot be sampled.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum GeometryError {
    /// A kind name that is not one of the five.
    #[error("Unknown feature kind \"{0}\"; the kinds are point, polyline, spline, region and cut.")]
    UnknownKind(String),
    /// Fewer control points than the kind needs.
    #[error("A {kind} needs at least {needed} control points, but its {which} geometry has {got}.")]
    TooFewPoints { kind: Kind, which: &'static str, needed: usize, got: usize },
    /// A point feature with other than one position.
    #[error("A point feature has exactly one position, but its {which} geometry has {got}.")]
    NotOnePoint { which: &'static str, got: usize },
    /// The pose has a different number of control points than the rest geometry.
    #[error(
        "The posed geometry has {pose} control points but the rest geometry has {rest}; \
         a pose must move the same control points the rest geometry has."
    )]
    CountMismatch { rest: usize, pose: usize },
    /// A NaN or infinite coordinate.
    #[error("Control point {index} of the {which} geometry is ({x}, {y}); every coordinate must be a finite number.")]
    NonFinite { which: &'static str, index: usize, x: f64, y: f64 },
    /// A finite coordinate beyond the limit every coordinate shares
    /// ([`crate::limits::MAX_COORD_PX`]): curves through such points overflow.
    #[error("Control point {index} of the {which} geometry is ({x}, {y}); every coordinate must be within ±{limit:e} px.")]
    OutOfRange { which: &'static str, index: usize, x: f64, y: f64, limit: f64 },
    /// A spacing that is zero, negative or not finite.
    #[error("The sample spacing is {0} px; it must be a positive, finite number of pixels.")]
    BadSpacing(f64),
    /// A curve so long for its spacing that its samples would not fit in memory.
    #[error("{0}.")]
    TooManySamples(String),
    /// A region sampled without the grid its interior nodes live on.
    #[error("A region needs the grid (the image's width and height, and its matte) to find the nodes inside its outline, but none was given.")]
    RegionWithoutDomain,
}

/// Samples one feature: pairs of a rest position on the feature and the displacement of
/// its partner in the pose (DESIGN §3).
///
/// `rest` and `pose` are the control points (the same number of each). By kind:
///
/// - `Point`: one sample, the point and its motion.
/// - `Polyline` (≥ 2 vertices, open or `closed`): each segment split into
///   `⌈length / spacing⌉` equal pieces, so samples lie at most `spacing_px` apart along
///   the rest polyline with every vertex among them; the sample at fraction `s` of a rest
///   segment is partnered with the point at fraction `s` of the posed segment.
/// - `Spline` (≥ 2 control points, open or `closed`): the centripetal Catmull-Rom curve
///   of [`Curve::spline`]; each span split into pieces of equal arc length along the rest
///   curve, at most `spacing_px`, every control point a sample; the partner is the posed
///   curve's point on the same span at the same span parameter.
/// - `Region` (≥ 3 control points): its closed outline (a polyline, or a spline when
///   `spline_outline`) sampled like a curve, then every active node of `domain` strictly
///   inside the rest outline, with the mean-value-coordinate interpolation of the outline
///   samples' displacements (see [`MeanValueInterpolator`]; for a polyline outline the
///   control polygon gives the same interpolation, the displacement being linear along
///   each edge). An affine motion of a polyline outline, or a similarity of a spline
///   outline, moves the interior by the same map.
/// - `Cut`: no samples (a cut changes the grid, not the constraints).
///
/// Output order: curve samples in order along the curve, then interior nodes row-major.
///
/// ```
/// use inkwarp_core::geometry::{sample_feature, Kind, SampleOptions};
/// let rest = [[0.0, 0.0], [4.0, 0.0]];
/// let pose = [[0.0, 1.0], [4.0, 3.0]];
/// let s = sample_feature(Kind::Polyline, &rest, &pose, &SampleOptions::default(), None).unwrap();
/// assert_eq!(s.len(), 5); // x = 0, 1, 2, 3, 4
/// assert_eq!(s[2].rest, [2.0, 0.0]);
/// assert_eq!(s[2].displacement, [0.0, 2.0]); // the posed segment's midpoint is (2, 2)
/// ```
///
/// # Errors
/// Too few control points for the kind (or not exactly one for a point), a pose with a
/// different count, a non-finite coordinate, a spacing that is not positive and finite,
/// or a region without a `domain`.
pub fn sample_feature(
    kind: Kind,
    rest: &[Point],
    pose: &[Point],
    opts: &SampleOptions,
    domain: Option<&Grid>,
) -> Result<Vec<Sample>, GeometryError> {
    check_points(kind, rest, "rest")?;
    if pose.len() != rest.len() {
        return Err(GeometryError::CountMismatch { rest: rest.len(), pose: pose.len() });
    }
    check_points(kind, pose, "posed")?;
    let spacing = check_spacing(opts.spacing_px)?;
    let (closed, spline) = kind.curve_shape(opts.closed, opts.spline_outline);
    for points in [rest, pose] {
        crate::limits::check_curve_samples(points, closed, spacing)
            .map_err(|why| GeometryError::TooManySamples(why.replacen("sampling", "Sampling", 1)))?;
    }
    let curves = || curve_samples(&Curve::new(rest, closed, spline), &Curve::new(pose, closed, spline), spacing);
    Ok(match kind {
        Kind::Point => vec![Sample { rest: rest[0], displacement: sub(pose[0], rest[0]) }],
        Kind::Polyline | Kind::Spline => curves(),
        Kind::Region => {
            let grid = domain.ok_or(GeometryError::RegionWithoutDomain)?;
            let mut samples = curves();
            let (vertices, values): (Vec<Point>, Vec<Point>) = if spline {
                samples.iter().map(|s| (s.rest, s.displacement)).unzip()
            } else {
                rest.iter().zip(pose).map(|(&r, &p)| (r, sub(p, r))).unzip()
            };
            samples.extend(region::interior_samples(vertices, values, grid));
            samples
        }
        Kind::Cut => Vec::new(),
    })
}

/// The samples of a curve: the rest curve's points at its sample parameters, each with
/// the displacement to the posed curve's point at the same parameter.
fn curve_samples(rest: &Curve, pose: &Curve, spacing: f64) -> Vec<Sample> {
    rest.sample_parameters(spacing).into_iter().map(|p| {
        let r = rest.point_at(p.span, p.u);
        Sample { rest: r, displacement: sub(pose.point_at(p.span, p.u), r) }
    }).collect()
}

/// `spacing`, when it is positive and finite.
fn check_spacing(spacing: f64) -> Result<f64, GeometryError> {
    if spacing > 0.0 && spacing.is_finite() { Ok(spacing) } else { Err(GeometryError::BadSpacing(spacing)) }
}

fn check_points(kind: Kind, points: &[Point], which: &'static str) -> Result<(), GeometryError> {
    let got = points.len();
    if kind == Kind::Point && got != 1 {
        return Err(GeometryError::NotOnePoint { which, got });
    } else if kind != Kind::Point && got < kind.min_points() {
        return Err(GeometryError::TooFewPoints { kind, which, needed: kind.min_points(), got });
    }
    if let Some((index, p)) = points.iter().enumerate().find(|(_, p)| !(p[0].is_finite() && p[1].is_finite())) {
        return Err(GeometryError::NonFinite { which, index, x: p[0], y: p[1] });
    }
    let ok = crate::limits::coordinate_ok;
    if let Some((index, p)) = points.iter().enumerate().find(|(_, p)| !(ok(p[0]) && ok(p[1]))) {
        let limit = crate::limits::MAX_COORD_PX;
        return Err(GeometryError::OutOfRange { which, index, x: p[0], y: p[1], limit });
    }
    Ok(())
}

/// The smallest and the largest coordinates of `points`, each axis on its own (`+∞` and
/// `−∞` for no point).
pub(crate) fn bounds<'a>(points: impl IntoIterator<Item = &'a Point>) -> (Point, Point) {
    points.into_iter().fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
        ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
    })
}

/// The curve through `points` as a dense polyline, for overlays and cuts.
///
/// A point gives itself; a polyline or cut its vertices; a spline its samples at
/// `spacing_px` (see [`Curve::sample_parameters`]); a region its outline (`spline_outline`
/// picks a spline) and is always closed. A closed result repeats its first point at the
/// end, so that it can be drawn or cut as an ordinary polyline.
///
/// Degenerate input is passed through rather than rejected: a spacing that is not
/// positive and finite is taken as 1 px, and too few points give the points as they are.
///
/// ```
/// use inkwarp_core::geometry::{curve_polyline, Kind};
/// let square = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
/// let outline = curve_polyline(Kind::Region, &square, false, false, 1.0);
/// assert_eq!(outline.len(), 5);
/// assert_eq!(outline[4], outline[0]);
/// ```
pub fn curve_polyline(kind: Kind, points: &[Point], closed: bool, spline_outline: bool, spacing_px: f64) -> Vec<Point> {
    let spacing = check_spacing(spacing_px).unwrap_or(1.0);
    let (closed, spline) = kind.curve_shape(closed, spline_outline);
    if kind == Kind::Point || points.len() < 2 {
        return points.to_vec();
    }
    if spline {
        return Curve::spline(points, closed).to_polyline(spacing);
    }
    points.iter().copied().chain(closed.then_some(points[0])).collect()
}

#[cfg(test)]
mod tests;

//! Sampling one feature in many poses (the frames of an animation): everything that
//! depends only on the rest geometry is computed once.

use rayon::prelude::*;

use super::curve::{hermite_basis, sub, Curve, CurveParameter};
use super::region::{nodes_inside, par_map, MeanValueInterpolator, MvcScratch};
use super::{check_points, check_spacing, GeometryError, Kind, Point, Sample, SampleOptions};
use crate::grid::Grid;

/// Regions keep at most this many interpolation coefficients (128 MiB of `f32`); a bigger
/// region evaluates its mean value coordinates again for every pose instead.
const MAX_COEFFICIENTS: usize = 1 << 25;

/// A feature's rest geometry prepared for sampling many poses.
///
/// [`sample_feature`](super::sample_feature) does all its work for every call. An
/// animation samples the same rest geometry at every frame, and for a region most of
/// that work depends on the rest geometry alone: the interior nodes and their mean value
/// coordinates. A region's interior displacement is linear in the pose's curve data
/// (the control points' displacements, and for a spline outline also the change of each
/// span's Hermite tangents), so `FeatureSampler` keeps, for every interior node, the
/// coefficients of that linear map, and a pose then costs one short dot product per node
/// (`3 × control points` terms for a spline outline, `control points` for a polyline)
/// instead of a sum over the whole dense outline. The result equals `sample_feature`'s
/// to about 1e-6 of the displacement (coefficients are stored as `f32`).
///
/// ```
/// use inkwarp_core::geometry::{sample_feature, FeatureSampler, Kind, SampleOptions};
/// use inkwarp_core::Grid;
/// let rest = [[10.0, 10.0], [30.0, 12.0], [28.0, 30.0], [12.0, 28.0]];
/// let opts = SampleOptions { spline_outline: true, ..SampleOptions::default() };
/// let grid = Grid::new(40, 40);
/// let sampler = FeatureSampler::new(Kind::Region, &rest, &opts, Some(&grid)).unwrap();
/// let pose = [[11.0, 10.0], [31.0, 14.0], [27.0, 31.0], [12.0, 27.0]];
/// let fast = sampler.sample(&pose).unwrap();
/// let slow = sample_feature(Kind::Region, &rest, &pose, &opts, Some(&grid)).unwrap();
/// assert_eq!(fast.len(), slow.len());
/// ```
#[derive(Clone, Debug)]
pub struct FeatureSampler {
    kind: Kind,
    closed: bool,
    spline: bool,
    rest: Vec<Point>,
    rest_curve: Option<Curve>,
    params: Vec<CurveParameter>,
    rest_points: Vec<Point>,
    /// The Hermite basis at each sample's span parameter.
    hermite: Vec<[f64; 4]>,
    interior: Interior,
}

#[derive(Clone, Debug)]
enum Interior {
    None,
    /// `displacement(node) = Σ_k coefficients[node·width + k] · basis_change_k(pose)`.
    Coefficients { nodes: Vec<Point>, coefficients: Vec<f32>, width: usize },
    /// Mean value coordinates evaluated per pose over the outline polygon.
    Direct { nodes: Vec<Point>, vertices: Vec<Point> },
}

impl FeatureSampler {
    /// Prepares `rest` for sampling with `opts` (and, for a region, its interior nodes on
    /// `domain`).
    ///
    /// # Errors
    /// As [`sample_feature`](super::sample_feature) for the rest geometry and options.
    pub fn new(kind: Kind, rest: &[Point], opts: &SampleOptions, domain: Option<&Grid>) -> Result<Self, GeometryError> {
        Self::with_limit(kind, rest, opts, domain, MAX_COEFFICIENTS)
    }

    /// `new` with a different cap on the coefficients kept.
    pub(crate) fn with_limit(
        kind: Kind,
        rest: &[Point],
        opts: &SampleOptions,
        domain: Option<&Grid>,
        max_coefficients: usize,
    ) -> Result<Self, GeometryError> {
        check_points(kind, rest, "rest")?;
        let spacing = check_spacing(opts.spacing_px)?;
        let (closed, spline) = kind.curve_shape(opts.closed, opts.spline_outline);
        let rest_curve = matches!(kind, Kind::Polyline | Kind::Spline | Kind::Region).then(|| Curve::new(rest, closed, spline));
        let params: Vec<CurveParameter> = rest_curve.as_ref().map_or_else(Vec::new, |curve| curve.sample_parameters(spacing));
        let rest_points = rest_curve.iter().flat_map(|curve| params.iter().map(|p| curve.point_at(p.span, p.u))).collect();
        let hermite = params.iter().map(|p| hermite_basis(p.u)).collect();
        let (rest, interior) = (rest.to_vec(), Interior::None);
        let mut me = FeatureSampler { kind, closed, spline, rest, rest_curve, params, rest_points, hermite, interior };
        if kind == Kind::Region {
            let grid = domain.ok_or(GeometryError::RegionWithoutDomain)?;
            me.interior = me.prepare_interior(grid, max_coefficients);
        }
        Ok(me)
    }

    fn prepare_interior(&self, grid: &Grid, max_coefficients: usize) -> Interior {
        // The outline polygon whose mean value coordinates move the interior: the control
        // polygon of a polyline outline (the same interpolation as its dense samples, the
        // displacement being linear along each edge), the dense samples of a spline outline.
        let vertices = if self.spline { self.rest_points.clone() } else { self.rest.clone() };
        let nodes = nodes_inside(&vertices, grid);
        // How many pose-dependent basis vectors the interior is linear in.
        let width = if self.spline { 3 * self.rest.len() } else { self.rest.len() };
        let mvc = MeanValueInterpolator::new(vertices.clone(), vec![[0.0; 2]; vertices.len()]);
        if nodes.len().saturating_mul(width) > max_coefficients {
            // too big to keep: drop the nodes on the outline now, interpolate per pose
            let nodes = par_map(&nodes, |n, scratch| {
                let x = [n[0] as f64, n[1] as f64];
                mvc.value_at(x, scratch).map(|_| x)
            });
            return Interior::Direct { nodes, vertices };
        }
        let s = self.rest.len();
        // the outline samples of each span (consecutive, in span order)
        let mut spans = vec![0..0; s];
        for (j, p) in self.params.iter().enumerate() {
            let r = &mut spans[p.span];
            *r = if r.start == r.end { j..j + 1 } else { r.start..j + 1 };
        }
        let pieces: Vec<(Vec<Point>, Vec<f32>)> = nodes.par_chunks(256).map(|chunk| {
            let mut scratch = MvcScratch::default();
            let mut weights = vec![0.0; vertices.len()];
            let mut row = vec![0.0f64; width];
            let mut kept = Vec::with_capacity(chunk.len());
            let mut coefficients = Vec::with_capacity(chunk.len() * width);
            for n in chunk {
                let x = [n[0] as f64, n[1] as f64];
                let Some(sum) = mvc.unnormalized_weights_at(x, &mut scratch, &mut weights) else { continue };
                if self.spline {
                    // each outline sample's weight spread over its span's Hermite data
                    row.iter_mut().for_each(|c| *c = 0.0);
                    for (i, range) in spans.iter().enumerate() {
                        let mut acc = [0.0; 4];
                        for (&w, h) in weights[range.clone()].iter().zip(&self.hermite[range.clone()]) {
                            for k in 0..4 {
                                acc[k] += w * h[k];
                            }
                        }
                        row[i] += acc[0];
                        row[s + i] += acc[1];
                        row[2 * s + i] += acc[2];
                        row[(i + 1) % s] += acc[3];
                    }
                    coefficients.extend(row.iter().map(|&c| (c / sum) as f32));
                } else {
                    coefficients.extend(weights.iter().map(|&w| (w / sum) as f32));
                }
                kept.push(x);
            }
            (kept, coefficients)
        }).collect();
        let (nodes, coefficients): (Vec<Vec<Point>>, Vec<Vec<f32>>) = pieces.into_iter().unzip();
        Interior::Coefficients { nodes: nodes.concat(), coefficients: coefficients.concat(), width }
    }

    /// How many samples every pose gives.
    pub fn len(&self) -> usize {
        let curve = if self.kind == Kind::Point { 1 } else { self.params.len() };
        curve
            + match &self.interior {
                Interior::None => 0,
                Interior::Coefficients { nodes, .. } | Interior::Direct { nodes, .. } => nodes.len(),
            }
    }

    /// Whether poses give no samples (a cut).
    pub fn is_empty(&self) -> bool { self.len() == 0 }

    /// The samples of the feature in `pose`, in the order of
    /// [`sample_feature`](super::sample_feature).
    ///
    /// # Errors
    /// A pose with a different number of control points than the rest geometry, or a
    /// non-finite coordinate.
    pub fn sample(&self, pose: &[Point]) -> Result<Vec<Sample>, GeometryError> {
        if pose.len() != self.rest.len() {
            return Err(GeometryError::CountMismatch { rest: self.rest.len(), pose: pose.len() });
        }
        check_points(self.kind, pose, "posed")?;
        match self.kind {
            Kind::Cut => return Ok(Vec::new()),
            Kind::Point => return Ok(vec![Sample { rest: self.rest[0], displacement: sub(pose[0], self.rest[0]) }]),
            _ => {}
        }
        let mut out = Vec::with_capacity(self.len());
        let posed = Curve::new(pose, self.closed, self.spline);
        let curve = self.params.iter().zip(&self.rest_points);
        out.extend(curve.map(|(p, &r)| Sample { rest: r, displacement: sub(posed.point_at(p.span, p.u), r) }));
        match &self.interior {
            Interior::None => {}
            Interior::Coefficients { nodes, coefficients, width } => {
                let change = &self.basis_change(pose, &posed);
                debug_assert_eq!(change.len(), *width);
                let chunks = nodes.par_chunks(1024).zip(coefficients.par_chunks(1024 * width));
                out.par_extend(chunks.flat_map_iter(|(ns, cs)| {
                    ns.iter().zip(cs.chunks_exact(*width)).map(move |(&rest, row)| {
                        let (mut dx, mut dy) = (0.0, 0.0);
                        for (&c, b) in row.iter().zip(change) {
                            dx += c as f64 * b[0];
                            dy += c as f64 * b[1];
                        }
                        Sample { rest, displacement: [dx, dy] }
                    })
                }));
            }
            Interior::Direct { nodes, vertices } => {
                let values: Vec<Point> = if self.spline {
                    out.iter().map(|s| s.displacement).collect()
                } else {
                    self.rest.iter().zip(pose).map(|(&r, &p)| sub(p, r)).collect()
                };
                let mvc = MeanValueInterpolator::new(vertices.clone(), values);
                out.extend(par_map(nodes, |&rest, scratch| {
                    Some(Sample { rest, displacement: mvc.value_at(rest, scratch).unwrap_or([0.0; 2]) })
                }));
            }
        }
        Ok(out)
    }

    /// How the pose changes the basis vectors the interior is linear in: the control
    /// points' displacements, and for a spline outline each span's tangent changes.
    fn basis_change(&self, pose: &[Point], posed: &Curve) -> Vec<Point> {
        let s = self.rest.len();
        let mut change: Vec<Point> = self.rest.iter().zip(pose).map(|(&r, &p)| sub(p, r)).collect();
        if self.spline {
            let rest = self.rest_curve.as_ref().expect("curves have a rest curve");
            // the start tangents' changes, then the end tangents'
            for k in [1, 2] {
                change.extend((0..s).map(|i| sub(posed.span_hermite(i)[k], rest.span_hermite(i)[k])));
            }
        }
        change
    }
}

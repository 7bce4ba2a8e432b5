//! The interpolants driven by a scene's drawing: what each one is handed from a layer's
//! features at a time, and the layer's field (the scene engine's dispatch calls
//! [`features_field`] for every method but `tps`).

use super::{field_on_grid, line_pairs_from_chain, Controls, Interpolant, MethodParams, MethodReport};
use crate::field::Field;
use crate::geometry::{sample_feature, Kind, Sample, SampleOptions};
use crate::grid::Grid;
use crate::scene::{FeatureSamples, Scene};

/// Beier–Neely segments along a spline (or a spline region outline) are about this long:
/// short enough to follow the curve, long enough to act as lines rather than points.
pub const BEIER_NEELY_SEGMENT_PX: f64 = 8.0;

/// The interpolant of this module that computes `method`, or `None` for the grid thin
/// plate (`tps`, which `solve` computes).
pub fn interpolant_for(method: crate::scene::Method) -> Option<Interpolant> {
    use crate::scene::Method as M;
    match method {
        M::Tps => None,
        M::TpsExact => Some(Interpolant::TpsExact),
        M::Triangulation => Some(Interpolant::Triangulation),
        M::BeierNeely => Some(Interpolant::BeierNeely),
    }
}

/// The controls a layer's drawing gives `interpolant`, from the layer's samples grouped by
/// feature (as the scene engine makes them at `time_s`).
///
/// * `tps-exact` and `triangulation`: every sample the grid thin plate gets (curves
///   sampled at the layer's grid spacing, region interiors on the layer's grid).
/// * `beier-neely`: point features as Shepard points; each polyline, and each region with
///   a polyline outline, as line pairs between consecutive control points (closed ones
///   joined back to the first; the paper's "four lines along the edges" of a square); each
///   spline, and each region with a spline outline, as its curve cut into segments of
///   about [`BEIER_NEELY_SEGMENT_PX`]. Region interiors are not used.
pub fn feature_controls(
    scene: &Scene,
    features: &[FeatureSamples],
    time_s: f64,
    interpolant: Interpolant,
) -> Result<Controls, String> {
    if interpolant != Interpolant::BeierNeely {
        return Ok(Controls::from_samples(features.iter().flat_map(|f| f.samples.iter().copied()).collect()));
    }
    let mut controls = Controls::default();
    for f in features {
        let track = &scene.tracks()[f.feature];
        let closed = track.closed || track.kind == Kind::Region;
        match track.kind {
            Kind::Cut => {}
            Kind::Point => controls.samples.extend(f.samples.iter().copied()),
            Kind::Spline => {
                controls.line_pairs.extend(line_pairs_from_chain(&f.samples, closed, BEIER_NEELY_SEGMENT_PX));
            }
            Kind::Region if track.spline_outline => {
                let pose = scene.pose_at(f.feature, time_s);
                let options = SampleOptions { closed: true, spline_outline: false, spacing_px: 1.0 };
                let chain = sample_feature(Kind::Spline, &track.rest, &pose, &options, None)
                    .map_err(|e| format!("features[{}]: {e}", f.feature))?;
                controls.line_pairs.extend(line_pairs_from_chain(&chain, true, BEIER_NEELY_SEGMENT_PX));
            }
            Kind::Polyline | Kind::Region => {
                let pose = scene.pose_at(f.feature, time_s);
                let vertices: Vec<Sample> = track
                    .rest
                    .iter()
                    .zip(&pose)
                    .map(|(r, p)| Sample { rest: *r, displacement: [p[0] - r[0], p[1] - r[1]] })
                    .collect();
                controls.line_pairs.extend(line_pairs_from_chain(&vertices, closed && vertices.len() > 2, 0.0));
            }
        }
    }
    Ok(controls)
}

/// A layer's field by `interpolant`, from its samples grouped by feature: the scene
/// engine's dispatch for every method but `tps`. Uses the default [`MethodParams`].
pub fn features_field(
    scene: &Scene,
    grid: &Grid,
    features: &[FeatureSamples],
    time_s: f64,
    interpolant: Interpolant,
) -> Result<(Field, MethodReport), String> {
    let controls = feature_controls(scene, features, time_s, interpolant)?;
    field_on_grid(interpolant, &controls, grid, &MethodParams::default()).map_err(|e| e.to_string())
}

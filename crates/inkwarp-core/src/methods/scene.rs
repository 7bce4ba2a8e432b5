//! The interpolants driven by a scene's drawing: what each one is handed from a layer's
//! features at a time (the scene engine's dispatch for every method but `tps`).

use super::{line_pairs_from_chain, BeierNeelyParams, Controls, Interpolant, MethodParams};
use crate::geometry::{sample_feature, sub, Kind, Point, Sample, SampleOptions};
use crate::scene::{to_layer, BeierNeelyDoc, FeatureSamples, Scene, SolverDoc};

/// Beier–Neely segments along a spline (or a spline region outline) are about this long:
/// short enough to follow the curve, long enough to act as lines rather than points.
pub const BEIER_NEELY_SEGMENT_PX: f64 = 8.0;

/// The controls a layer's drawing gives `interpolant`, from the layer's samples grouped by
/// feature (as the scene engine makes them at `time_s`, for a layer placed at `offset`).
///
/// * `tps-exact` and `triangulation`: every sample the grid thin plate gets (curves
///   sampled at the layer's grid spacing, region interiors on the layer's grid).
/// * `beier-neely`: point features as Shepard points; each polyline, and each region with
///   a polyline outline, as line pairs between consecutive control points (closed ones
///   joined back to the first; the paper's "four lines along the edges" of a square); each
///   spline, and each region with a spline outline, as its curve cut into segments of
///   about [`BEIER_NEELY_SEGMENT_PX`]. Region interiors are not used.
pub fn feature_controls(scene: &Scene, features: &[FeatureSamples], time_s: f64, interpolant: Interpolant, offset: [f64; 2]) -> Result<Controls, String> {
    if interpolant != Interpolant::BeierNeely {
        return Ok(Controls::from_samples(features.iter().flat_map(|f| f.samples.iter().copied()).collect()));
    }
    let mut controls = Controls::default();
    for f in features {
        let feature = &scene.doc().features[f.feature];
        let (closed, _) = feature.kind.curve_shape(feature.closed, false);
        let placed = || (to_layer(&feature.rest, offset), to_layer(&scene.pose_at(f.feature, time_s), offset));
        match feature.kind {
            Kind::Cut => {}
            Kind::Point => controls.samples.extend(f.samples.iter().copied()),
            Kind::Spline => controls.line_pairs.extend(line_pairs_from_chain(&f.samples, closed, BEIER_NEELY_SEGMENT_PX)),
            Kind::Region if feature.spline_outline() => {
                let (rest, pose) = placed();
                let options = SampleOptions { closed: true, spline_outline: false, spacing_px: 1.0 };
                let chain = sample_feature(Kind::Spline, &rest, &pose, &options, None)
                    .map_err(|e| format!("features[{}]: {e}", f.feature))?;
                controls.line_pairs.extend(line_pairs_from_chain(&chain, true, BEIER_NEELY_SEGMENT_PX));
            }
            Kind::Polyline | Kind::Region => {
                let (rest, pose) = placed();
                let moved = |(&r, &p): (&Point, &Point)| Sample { rest: r, displacement: sub(p, r) };
                let vertices: Vec<Sample> = rest.iter().zip(&pose).map(moved).collect();
                controls.line_pairs.extend(line_pairs_from_chain(&vertices, closed && vertices.len() > 2, 0.0));
            }
        }
    }
    Ok(controls)
}

/// Adds a held border (a layer's `"border": "hold"`) to `controls`: for `beier-neely` the
/// four edges of the `width × height` grid as line pairs that stay put, for the others
/// [`border_samples`](crate::geometry::border_samples) every `spacing_px`.
pub fn hold_border(controls: &mut Controls, interpolant: Interpolant, width: usize, height: usize, spacing_px: f64) {
    if width == 0 || height == 0 { return; }
    if interpolant == Interpolant::BeierNeely {
        let (r, b) = ((width - 1) as f64, (height - 1) as f64);
        let corners = [[0.0, 0.0], [r, 0.0], [r, b], [0.0, b]];
        let edges = (0..4).map(|k| [corners[k], corners[(k + 1) % 4]]).filter(|e| e[0] != e[1]);
        controls.line_pairs.extend(edges.map(|edge| super::LinePair { rest: edge, pose: edge }));
    } else {
        controls.samples.extend(crate::geometry::border_samples(width, height, spacing_px));
    }
}

/// The interpolants' settings of a layer's solver settings (`solver.beier_neely`,
/// `solver.tps_exact`).
pub fn method_params(solver: &SolverDoc) -> MethodParams {
    let BeierNeelyDoc { a, b, p } = solver.beier_neely;
    MethodParams { max_samples: solver.tps_exact.max_samples as usize, beier_neely: BeierNeelyParams { a, b, p } }
}

/// The drawing of `doc` posed at `time_s`, for overlays: per feature its id, kind and its
/// curve as a polyline every `spacing_px` (a point feature as its one position; a cut at
/// its rest geometry, which never moves).
pub fn posed_drawing(doc: &crate::scene::SceneDoc, time_s: f64, spacing_px: f64) -> Vec<(String, Kind, Vec<Point>)> {
    let posed = |f: &crate::scene::FeatureDoc| {
        let pose = if f.kind == Kind::Cut { f.rest.clone() } else { crate::anim::points_at(&f.rest, &f.keys, time_s) };
        // (A point's polyline is its one position.)
        (f.id.clone(), f.kind, crate::geometry::curve_polyline(f.kind, &pose, f.closed, f.spline_outline(), spacing_px))
    };
    doc.features.iter().map(posed).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn posed_drawing_follows_the_keys() {
        let doc = crate::scene::parse_doc(
            r#"{"inkwarp": 1, "width": 20, "height": 20, "layers": [{"name": "a"}],
                "features": [
                  {"id": "p", "kind": "point", "rest": [[2, 2]], "keys": [{"t": 1, "points": [[4, 6]], "interpolation": "linear"}]},
                  {"id": "l", "kind": "polyline", "rest": [[0, 0], [10, 0]]}]}"#,
        )
        .unwrap();
        let drawing = posed_drawing(&doc, 1.0, 1.0);
        assert_eq!(drawing[0], ("p".to_string(), Kind::Point, vec![[4.0, 6.0]]));
        assert_eq!(drawing[1].2.first(), Some(&[0.0, 0.0]));
        assert_eq!(drawing[1].2.last(), Some(&[10.0, 0.0]));
    }
}

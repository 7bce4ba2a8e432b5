//! Animation transfer, the paper's cross-synthesis (DESIGN §7).
//!
//! A source drawing `S₀` with keys `Sₖ` and a target drawing `T₀` traced with the same
//! feature ids, kinds and control-point counts: the target's keys become `Tₖ = W(Sₖ)`,
//! where `W` is the continuous thin-plate map ([`ThinPlateMap`]) fitted from the
//! source's rest control points to the target's. The target then performs the source's
//! motion in its own proportions; where the two drawings differ by an affine map, the
//! keys differ by exactly that map.
//!
//! Matching rules: every source feature except `cut`s (which never move) must exist in
//! the target under the same id, with the same kind and the same number of rest control
//! points; the map is fitted to all of those features' rest control points (a source
//! position given twice is merged, its target positions averaged). Target features the
//! source lacks keep their own keys. Source features without keys still shape the map
//! and give their target counterpart no keys.
//!
//! [`transfer_keys`] works on plain features (the Python package maps scene documents).

use crate::geometry::{bounds, Kind, Point};
use crate::methods::{dist, MethodError, ThinPlateMap};

/// One feature of a drawing as transfer sees it: id, kind, rest control points and the
/// control points of each key (times and interpolation stay with the caller).
#[derive(Clone, Debug, PartialEq)]
pub struct TransferFeature {
    pub id: String,
    pub kind: Kind,
    pub rest: Vec<Point>,
    pub keys: Vec<Vec<Point>>,
}

/// Why two drawings cannot be matched.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransferError {
    #[error("Feature \"{id}\" (source features[{source_index}]) is not in the target drawing: transfer matches features by id, so trace it in the target under the same id, or remove it from the source.")]
    MissingFeature { id: String, source_index: usize },
    #[error("Feature \"{id}\" is a {source_kind} in the source (features[{source_index}]) but a {target_kind} in the target (features[{target_index}]): matched features must have the same kind.")]
    KindMismatch { id: String, source_index: usize, target_index: usize, source_kind: &'static str, target_kind: &'static str },
    #[error("Feature \"{id}\" has {source_count} rest control points in the source (features[{source_index}].rest) but {target_count} in the target (features[{target_index}].rest): matched features must have the same number of control points; give the target's feature {source_count} control points (an SVG path gets as many as its curve needs: draw it with the same nodes as the source's), or leave the feature out of the source.")]
    CountMismatch { id: String, source_index: usize, target_index: usize, source_count: usize, target_count: usize },
    #[error("Feature \"{id}\" (source features[{source_index}]) key {key} has {got} control points, its rest has {want}.")]
    KeyCount { id: String, source_index: usize, key: usize, got: usize, want: usize },
    #[error("The source and target drawings share no feature to fit the transfer map to.")]
    NothingShared,
    #[error("The transfer map from the source's rest drawing to the target's could not be fitted: {0}")]
    Map(#[from] MethodError),
}

/// The pairs `(source index, target index)` of matched features, checked.
fn match_features(source: &[TransferFeature], target: &[TransferFeature]) -> Result<Vec<(usize, usize)>, TransferError> {
    let mut pairs = Vec::new();
    for (si, s) in source.iter().enumerate() {
        if s.kind == Kind::Cut {
            continue;
        }
        let Some(ti) = target.iter().position(|t| t.id == s.id) else {
            return Err(TransferError::MissingFeature { id: s.id.clone(), source_index: si });
        };
        let t = &target[ti];
        let (id, source_index, target_index) = (s.id.clone(), si, ti);
        if t.kind != s.kind {
            let (source_kind, target_kind) = (s.kind.name(), t.kind.name());
            return Err(TransferError::KindMismatch { id, source_index, target_index, source_kind, target_kind });
        }
        if t.rest.len() != s.rest.len() {
            let (source_count, target_count) = (s.rest.len(), t.rest.len());
            return Err(TransferError::CountMismatch { id, source_index, target_index, source_count, target_count });
        }
        if let Some((key, k)) = s.keys.iter().enumerate().find(|(_, k)| k.len() != s.rest.len()) {
            return Err(TransferError::KeyCount { id, source_index, key, got: k.len(), want: s.rest.len() });
        }
        pairs.push((si, ti));
    }
    if pairs.is_empty() {
        return Err(TransferError::NothingShared);
    }
    Ok(pairs)
}

/// The map `W` from the source's rest drawing to the target's, fitted to the rest
/// control points of every matched feature, and the matched pairs.
fn rest_map(source: &[TransferFeature], target: &[TransferFeature]) -> Result<(ThinPlateMap, Vec<(usize, usize)>), TransferError> {
    let pairs = match_features(source, target)?;
    let matched = pairs.iter().flat_map(|&(si, ti)| source[si].rest.iter().copied().zip(target[ti].rest.iter().copied()));
    let (src, dst): (Vec<Point>, Vec<Point>) = matched.unzip();
    Ok((ThinPlateMap::fit(&src, &dst)?, pairs))
}

/// A place where the transfer map turns the source's drawing over: keys there come out
/// mirrored, and features that were apart cross each other. The usual cause is a matched
/// curve whose control points run the other way in the target (a brow traced outer end
/// first in one drawing and inner end first in the other).
#[derive(Clone, Debug, PartialEq)]
pub struct Fold {
    /// Where, in the source's coordinates: the point of the most negative Jacobian
    /// determinant (relative to the map's affine part) found.
    pub at: Point,
    /// The Jacobian determinant of the map there, signed so that < 0 is a fold.
    pub det: f64,
    /// The matched feature to check first: one that runs against the map (its first and
    /// last control points, or a closed one's turning direction, the other way round in
    /// the target), else the one with the control point nearest to `at`.
    pub feature: String,
}

impl std::fmt::Display for Fold {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "The map from the source's rest drawing to the target's folds over near ({:.0}, {:.0}) in the \
             source, by feature \"{}\": the keys there will be mirrored. Check that matched features run the \
             same way in both drawings (their control points in the same order).",
            self.at[0], self.at[1], self.feature
        )
    }
}

/// How finely [`find_fold`] looks: a grid of this many points along each side of the
/// bounding box of the matched rest control points.
pub const FOLD_GRID: usize = 64;

/// Where the map `W` (see the module docs) folds over within the source's drawing, if it
/// does: its Jacobian determinant on a [`FOLD_GRID`]² grid over the bounding box of the
/// matched rest control points, compared in sign with the determinant of the map's
/// affine part (so a target that is a mirror image of the source is no fold). `None` when
/// the map keeps its orientation everywhere there, or when the drawing has no area.
///
/// # Errors
/// As [`transfer_keys`].
pub fn find_fold(source: &[TransferFeature], target: &[TransferFeature]) -> Result<Option<Fold>, TransferError> {
    let (map, pairs) = rest_map(source, target)?;
    let points: Vec<(Point, usize)> =
        pairs.iter().flat_map(|&(si, _)| source[si].rest.iter().map(move |&p| (p, si))).collect();
    let (lo, hi) = bounds(points.iter().map(|(p, _)| p));
    let det = |j: [[f64; 2]; 2]| j[0][0] * j[1][1] - j[0][1] * j[1][0];
    let linear = map.affine_jacobian();
    let sign = det(linear).signum();
    if !(hi[0] > lo[0] && hi[1] > lo[1]) || sign == 0.0 {
        return Ok(None);
    }
    // The grid row by row; the first of equally deep folds.
    let t = |i: usize| i as f64 / (FOLD_GRID - 1) as f64;
    let point = |ix: usize, iy: usize| [lo[0] + t(ix) * (hi[0] - lo[0]), lo[1] + t(iy) * (hi[1] - lo[1])];
    let grid = (0..FOLD_GRID).flat_map(|iy| (0..FOLD_GRID).map(move |ix| point(ix, iy)));
    let worst = grid.map(|p| (p, sign * det(map.jacobian(p)))).filter(|&(_, d)| d < 0.0).min_by(|a, b| a.1.total_cmp(&b.1));
    Ok(worst.map(|(at, det)| {
        // The feature that runs against the affine map of all the others, among those where
        // leaving it out fits the others best by a map that keeps orientation (from four
        // points: three fit any map): the whole map's linear part is bent by the reversed
        // feature itself, and may make a correct one seem reversed.
        let against = pairs
            .iter()
            .filter(|&&(si, _)| source[si].rest.len() >= 2)
            .filter_map(|&(si, ti)| {
                let others: Vec<_> = pairs.iter().filter(|&&(sj, _)| sj != si).flat_map(|&(sj, tj)| source[sj].rest.iter().zip(&target[tj].rest)).collect();
                let (lin, misfit) = least_squares_affine(others.iter().copied()).filter(|_| others.len() >= 4)?;
                let keeps = lin[0][0] * lin[1][1] - lin[0][1] * lin[1][0] > 0.0;
                let turned = keeps && runs_against(&source[si], &target[ti], lin).is_some_and(|c| c < 0.0);
                turned.then_some((misfit, si))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .or_else(|| pairs.iter().find(|&&(si, ti)| runs_against(&source[si], &target[ti], linear).is_some_and(|c| c < 0.0)).map(|&(si, _)| (0.0, si)))
            .map(|(_, si)| si);
        let nearest = || {
            let near = points.iter().min_by(|a, b| dist(a.0, at).total_cmp(&dist(b.0, at)));
            near.map(|&(_, si)| source[si].id.clone()).unwrap_or_default()
        };
        let feature = against.map_or_else(nearest, |si| source[si].id.clone());
        Fold { at, det, feature }
    }))
}

/// The cosine between the target feature's first-to-last direction and the source's carried
/// by the linear map `linear` (below 0: turned by more than a right angle, which is what
/// listing the control points in reverse order does); none for a single point.
fn runs_against(source: &TransferFeature, target: &TransferFeature, linear: [[f64; 2]; 2]) -> Option<f64> {
    let (s, t) = (&source.rest, &target.rest);
    if s.len() < 2 || t.len() != s.len() {
        return None;
    }
    let v = [s[s.len() - 1][0] - s[0][0], s[s.len() - 1][1] - s[0][1]];
    let ds = [linear[0][0] * v[0] + linear[0][1] * v[1], linear[1][0] * v[0] + linear[1][1] * v[1]];
    let dt = [t[t.len() - 1][0] - t[0][0], t[t.len() - 1][1] - t[0][1]];
    let norms = (ds[0].hypot(ds[1]) * dt[0].hypot(dt[1])).max(f64::MIN_POSITIVE);
    Some((ds[0] * dt[0] + ds[1] * dt[1]) / norms)
}

/// The linear part of the least-squares affine map taking each pair's first point to its
/// second, and its mean squared misfit; none where the first points lie on one line.
fn least_squares_affine<'a>(pairs: impl Iterator<Item = (&'a Point, &'a Point)>) -> Option<([[f64; 2]; 2], f64)> {
    let pairs: Vec<_> = pairs.collect();
    let n = pairs.len() as f64;
    let mean = pairs.iter().fold([0.0; 2], |m, (p, _)| [m[0] + p[0] / n, m[1] + p[1] / n]);
    let c = pairs.iter().fold([0.0; 3], |c, (p, _)| {
        let d = [p[0] - mean[0], p[1] - mean[1]];
        [c[0] + d[0] * d[0], c[1] + d[1] * d[1], c[2] + d[0] * d[1]]
    });
    let spread = c[0] * c[1] - c[2] * c[2];
    if spread.is_nan() || spread <= 1e-9 * (c[0] + c[1]).powi(2) {
        return None; // on one line (or none): no linear map to tell
    }
    let a = crate::solve::affine_least_squares(pairs.iter().map(|(p, q)| (**p, **q)))?;
    let misfit = pairs.iter().map(|(p, q)| (0..2).map(|k| (a[0][k] + a[1][k] * p[0] + a[2][k] * p[1] - q[k]).powi(2)).sum::<f64>()).sum::<f64>() / n;
    Some(([[a[1][0], a[2][0]], [a[1][1], a[2][1]]], misfit))
}

/// The target's new keys: for each target feature (in order), `Some(keys)` with every
/// source key mapped through the map `W` (see the module docs) when the source has the feature, `None` (keep
/// your own) when it does not.
///
/// ```
/// use inkwarp_core::transfer::{transfer_keys, TransferFeature};
/// use inkwarp_core::Kind;
/// let f = |id: &str, rest: Vec<[f64; 2]>, keys: Vec<Vec<[f64; 2]>>| TransferFeature { id: id.into(), kind: Kind::Point, rest, keys };
/// // The target is the source drawn twice as large: the keys come out twice as large.
/// let source = vec![f("a", vec![[0.0, 0.0]], vec![]), f("b", vec![[10.0, 0.0]], vec![]),
///                   f("c", vec![[0.0, 10.0]], vec![vec![[1.0, 12.0]]])];
/// let target = vec![f("a", vec![[0.0, 0.0]], vec![]), f("b", vec![[20.0, 0.0]], vec![]),
///                   f("c", vec![[0.0, 20.0]], vec![]), f("own", vec![[5.0, 5.0]], vec![vec![[6.0, 6.0]]])];
/// let keys = transfer_keys(&source, &target).unwrap();
/// let c = &keys[2].as_ref().unwrap()[0][0];
/// assert!((c[0] - 2.0).abs() < 1e-9 && (c[1] - 24.0).abs() < 1e-9);
/// assert!(keys[3].is_none());
/// ```
pub fn transfer_keys(source: &[TransferFeature], target: &[TransferFeature]) -> Result<Vec<Option<Vec<Vec<Point>>>>, TransferError> {
    let (map, pairs) = rest_map(source, target)?;
    let mut out: Vec<Option<Vec<Vec<Point>>>> = vec![None; target.len()];
    for (si, ti) in pairs {
        out[ti] = Some(source[si].keys.iter().map(|k| k.iter().map(|&p| map.apply(p)).collect()).collect());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feat(id: &str, kind: Kind, rest: Vec<Point>, keys: Vec<Vec<Point>>) -> TransferFeature {
        TransferFeature { id: id.into(), kind, rest, keys }
    }

    fn drawing() -> Vec<TransferFeature> {
        vec![
            feat("nose", Kind::Point, vec![[50.0, 60.0]], vec![vec![[52.0, 61.0]], vec![[49.0, 58.0]]]),
            feat(
                "mouth",
                Kind::Spline,
                vec![[30.0, 80.0], [50.0, 90.0], [70.0, 80.0]],
                vec![vec![[30.0, 82.0], [50.0, 97.0], [70.0, 82.0]]],
            ),
            feat(
                "brow",
                Kind::Polyline,
                vec![[25.0, 30.0], [45.0, 25.0], [40.0, 40.0]],
                vec![vec![[25.0, 26.0], [45.0, 20.0], [40.0, 37.0]]],
            ),
            feat("gap", Kind::Cut, vec![[0.0, 0.0], [5.0, 5.0]], vec![]),
        ]
    }

    #[test]
    fn identical_rest_drawings_give_identical_keys() {
        let source = drawing();
        let target: Vec<TransferFeature> =
            source.iter().map(|f| TransferFeature { keys: vec![], ..f.clone() }).collect();
        let keys = transfer_keys(&source, &target).unwrap();
        for (f, k) in source.iter().zip(&keys) {
            if f.kind == Kind::Cut {
                assert!(k.is_none());
                continue;
            }
            let k = k.as_ref().unwrap();
            assert_eq!(k.len(), f.keys.len());
            for (got, want) in k.iter().flatten().zip(f.keys.iter().flatten()) {
                assert!((got[0] - want[0]).abs() < 1e-9 && (got[1] - want[1]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn an_affine_target_gets_the_affine_image_of_the_keys() {
        let affine = |p: Point| [12.0 + 1.3 * p[0] + 0.2 * p[1], -4.0 - 0.1 * p[0] + 0.8 * p[1]];
        let source = drawing();
        let target: Vec<TransferFeature> = source
            .iter()
            .map(|f| TransferFeature { rest: f.rest.iter().map(|&p| affine(p)).collect(), keys: vec![], ..f.clone() })
            .collect();
        let keys = transfer_keys(&source, &target).unwrap();
        for (f, k) in source.iter().zip(&keys).filter(|(f, _)| f.kind != Kind::Cut) {
            for (got, want) in k.as_ref().unwrap().iter().flatten().zip(f.keys.iter().flatten()) {
                let want = affine(*want);
                assert!((got[0] - want[0]).abs() < 1e-8 && (got[1] - want[1]).abs() < 1e-8, "{got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn mismatches_name_the_feature() {
        let source = drawing();
        let mut target = drawing();
        target.remove(1);
        assert_eq!(
            transfer_keys(&source, &target).unwrap_err().to_string(),
            "Feature \"mouth\" (source features[1]) is not in the target drawing: transfer matches features by id, so trace it in the target under the same id, or remove it from the source."
        );
        let mut target = drawing();
        target[2].kind = Kind::Spline;
        assert_eq!(
            transfer_keys(&source, &target).unwrap_err().to_string(),
            "Feature \"brow\" is a polyline in the source (features[2]) but a spline in the target (features[2]): matched features must have the same kind."
        );
        let mut target = drawing();
        target[1].rest.push([80.0, 70.0]);
        assert!(transfer_keys(&source, &target)
            .unwrap_err()
            .to_string()
            .starts_with("Feature \"mouth\" has 3 rest control points in the source (features[1].rest) but 4 in the target"));
    }

    #[test]
    fn the_reversed_feature_is_named_even_where_it_bends_the_whole_map() {
        // Two long features across the face: the one reversed bends the map's affine part
        // enough to make the other seem reversed against it; the others' fit without it does not.
        let source = vec![
            feat("nose", Kind::Point, vec![[100.0, 100.0]], vec![]),
            feat("brow", Kind::Spline, vec![[60.0, 60.0], [100.0, 50.0], [140.0, 60.0]], vec![]),
            feat("mouth", Kind::Polyline, vec![[70.0, 150.0], [100.0, 160.0], [130.0, 150.0]], vec![]),
            feat("eye", Kind::Region, vec![[80.0, 80.0], [90.0, 75.0], [100.0, 80.0], [90.0, 85.0]], vec![]),
            feat("chin", Kind::Point, vec![[100.0, 185.0]], vec![]),
        ];
        let wider = |id: &str, p: &Point| if id == "eye" { [2.0 * p[0] - 30.0, 1.6 * p[1] - 58.0] } else { [1.5 * p[0] + 30.0, 0.9 * p[1] + 2.0] };
        for reversed in ["brow", "mouth"] {
            let target: Vec<TransferFeature> = source
                .iter()
                .map(|f| {
                    let mut rest: Vec<Point> = f.rest.iter().map(|p| wider(&f.id, p)).collect();
                    if f.id == reversed { rest.reverse() }
                    TransferFeature { rest, ..f.clone() }
                })
                .collect();
            let fold = find_fold(&source, &target).unwrap().expect("a reversed feature folds the map");
            assert_eq!(fold.feature, reversed);
        }
        // Symmetric about the nose: the others without the mouth fit a mirror image exactly,
        // by which the correct mouth runs against; only a map that keeps orientation counts.
        let symmetric: Vec<TransferFeature> = source.iter().filter(|f| f.id != "eye").cloned().collect();
        let target: Vec<TransferFeature> = symmetric
            .iter()
            .map(|f| {
                let mut rest: Vec<Point> = f.rest.iter().map(|p| wider("", p)).collect();
                if f.id == "brow" { rest.reverse() }
                TransferFeature { rest, ..f.clone() }
            })
            .collect();
        assert_eq!(find_fold(&symmetric, &target).unwrap().expect("a fold").feature, "brow");
    }

    #[test]
    fn a_reversed_feature_folds_the_map_and_is_named() {
        let source = vec![
            feat("left", Kind::Polyline, vec![[10.0, 10.0], [30.0, 10.0], [50.0, 12.0]], vec![]),
            feat("right", Kind::Polyline, vec![[70.0, 12.0], [90.0, 10.0], [110.0, 10.0]], vec![]),
            feat("nose", Kind::Point, vec![[60.0, 40.0]], vec![]),
            feat("mouth", Kind::Spline, vec![[40.0, 70.0], [60.0, 75.0], [80.0, 70.0]], vec![]),
        ];
        // The same drawing, moved: no fold.
        let moved: Vec<TransferFeature> = source
            .iter()
            .map(|f| TransferFeature { rest: f.rest.iter().map(|p| [p[0] + 5.0, 1.2 * p[1]]).collect(), ..f.clone() })
            .collect();
        assert_eq!(find_fold(&source, &moved).unwrap(), None);
        // A mirror image is an affine map that turns everything over: no fold either.
        let mirrored: Vec<TransferFeature> = source
            .iter()
            .map(|f| TransferFeature { rest: f.rest.iter().map(|p| [200.0 - p[0], p[1]]).collect(), ..f.clone() })
            .collect();
        assert_eq!(find_fold(&source, &mirrored).unwrap(), None);
        // The left brow traced the other way round in the target.
        let mut reversed = moved.clone();
        reversed[0].rest.reverse();
        let fold = find_fold(&source, &reversed).unwrap().expect("a fold");
        assert_eq!(fold.feature, "left");
        assert!(fold.det < 0.0 && fold.at[0] < 60.0, "{fold:?}");
        assert!(fold.to_string().contains("by feature \"left\""), "{fold}");
    }

    #[test]
    fn target_only_features_keep_their_keys() {
        let source = drawing();
        let mut target = drawing();
        target.push(feat("tail", Kind::Point, vec![[90.0, 90.0]], vec![vec![[91.0, 95.0]]]));
        let keys = transfer_keys(&source, &target).unwrap();
        assert!(keys[4].is_none());
    }
}

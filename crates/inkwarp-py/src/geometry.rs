//! Bindings of `inkwarp_core::geometry`: sampling features into constraints, and the
//! dense polyline of a curve.

use inkwarp_core::geometry::{self, Kind, SampleOptions};
use inkwarp_core::{Grid, Point};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::input_error;

/// A pair of `(N, 2)` float64 arrays: points and displacements.
type PointPair<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

fn points_of(name: &str, a: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<Point>> {
    let shape = a.shape();
    if shape[1] != 2 {
        return Err(input_error(format!(
            "{name} must be an (N, 2) array of (x, y) control points; got shape ({}, {}).",
            shape[0], shape[1]
        )));
    }
    let v = a.as_array();
    crate::limits::check_coordinates(name, v.iter())?;
    Ok((0..shape[0]).map(|i| [v[[i, 0]], v[[i, 1]]]).collect())
}

fn array_of(
    py: Python<'_>,
    points: impl ExactSizeIterator<Item = Point>,
) -> Bound<'_, PyArray2<f64>> {
    let n = points.len();
    let flat: Vec<f64> = points.flatten().collect();
    Array2::from_shape_vec((n, 2), flat)
        .expect("n × 2 values")
        .into_pyarray(py)
}

/// sample_feature(kind, rest, pose, closed=False, spacing=1.0, spline_outline=False,
/// shape=None, mask=None) -> (points, displacements)
///
/// The engine's sampling of one feature; `inkwarp.sample` is the documented entry point.
#[pyfunction]
#[pyo3(signature = (kind, rest, pose, closed=false, spacing=1.0, spline_outline=false, shape=None, mask=None))]
fn sample_feature<'py>(
    py: Python<'py>,
    kind: &str,
    rest: PyReadonlyArray2<'py, f64>,
    pose: PyReadonlyArray2<'py, f64>,
    closed: bool,
    spacing: f64,
    spline_outline: bool,
    shape: Option<(usize, usize)>,
    mask: Option<PyReadonlyArray2<'py, u8>>,
) -> PyResult<PointPair<'py>> {
    let kind: Kind = kind.parse().map_err(input_error)?;
    let rest = points_of("rest", &rest)?;
    let pose = points_of("pose", &pose)?;
    crate::limits::check_sampling(&rest, closed, spacing)?;
    crate::limits::check_sampling(&pose, closed, spacing)?;
    if let Some((height, width)) = shape {
        crate::limits::check_grid(width, height)?;
    }
    let grid = match (shape, mask) {
        (Some((height, width)), Some(mask)) => {
            let s = mask.shape();
            if s != [height, width] {
                return Err(input_error(format!(
                    "mask has shape ({}, {}) but shape is ({height}, {width}); give a mask of the image's (H, W).",
                    s[0], s[1]
                )));
            }
            let m = mask.as_array();
            Some(Grid::from_matte(
                width,
                height,
                &m.iter().copied().collect::<Vec<u8>>(),
            ))
        }
        (Some((height, width)), None) => Some(Grid::new(width, height)),
        (None, Some(_)) => {
            return Err(input_error(
                "mask needs shape: pass shape=(H, W) with the mask.",
            ));
        }
        (None, None) => None,
    };
    let opts = SampleOptions {
        closed,
        spline_outline,
        spacing_px: spacing,
    };
    let samples = crate::errors::run_engine(py, || {
        geometry::sample_feature(kind, &rest, &pose, &opts, grid.as_ref())
    })?
    .map_err(input_error)?;
    Ok((
        array_of(py, samples.iter().map(|s| s.rest)),
        array_of(py, samples.iter().map(|s| s.displacement)),
    ))
}

/// curve_polyline(kind, points, closed=False, spline_outline=False, spacing=1.0) -> points
///
/// The curve through `points` as a dense (K, 2) polyline (a closed one repeats its first
/// point at the end).
#[pyfunction]
#[pyo3(signature = (kind, points, closed=false, spline_outline=false, spacing=1.0))]
fn curve_polyline<'py>(
    py: Python<'py>,
    kind: &str,
    points: PyReadonlyArray2<'py, f64>,
    closed: bool,
    spline_outline: bool,
    spacing: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let kind: Kind = kind.parse().map_err(input_error)?;
    let points = points_of("points", &points)?;
    crate::limits::check_sampling(&points, closed, spacing)?;
    let line = geometry::curve_polyline(kind, &points, closed, spline_outline, spacing);
    Ok(array_of(py, line.into_iter()))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sample_feature, m)?)?;
    m.add_function(wrap_pyfunction!(curve_polyline, m)?)?;
    Ok(())
}

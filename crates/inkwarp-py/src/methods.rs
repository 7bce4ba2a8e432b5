//! Bindings of `inkwarp_core::methods` and `inkwarp_core::transfer`: the comparison
//! interpolants, the continuous thin-plate map and animation transfer.

use inkwarp_core::methods::{self, BeierNeelyParams, Controls, LinePair, MethodParams, MethodReport};
use inkwarp_core::transfer::{self, TransferFeature};
use inkwarp_core::{Kind, Point, Sample};
use numpy::ndarray::{Array2, Array3};
use numpy::{PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::input_error;

fn points_of(name: &str, a: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<Point>> {
    let shape = a.shape();
    if shape[1] != 2 {
        return Err(input_error(format!(
            "{name} must have shape (N, 2) of (x, y) pairs; got shape ({}, {}).",
            shape[0], shape[1]
        )));
    }
    let v = a.as_array();
    crate::limits::check_coordinates(name, v.iter())?;
    Ok((0..shape[0]).map(|i| [v[[i, 0]], v[[i, 1]]]).collect())
}

fn segments_of(name: &str, a: &PyReadonlyArray3<'_, f64>) -> PyResult<Vec<[Point; 2]>> {
    let shape = a.shape();
    if shape[1] != 2 || shape[2] != 2 {
        return Err(input_error(format!(
            "{name} must have shape (L, 2, 2): L segments of two (x, y) end points; got shape ({}, {}, {}).",
            shape[0], shape[1], shape[2]
        )));
    }
    let v = a.as_array();
    Ok((0..shape[0]).map(|i| [[v[[i, 0, 0]], v[[i, 0, 1]]], [v[[i, 1, 0]], v[[i, 1, 1]]]]).collect())
}

fn report_dict<'py>(py: Python<'py>, r: &MethodReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("method", r.method.map(|m| m.name()))?;
    d.set_item("samples_given", r.samples_given)?;
    d.set_item("samples_used", r.samples_used)?;
    d.set_item("line_pairs_used", r.line_pairs_used)?;
    d.set_item("dropped", r.dropped)?;
    d.set_item("ignored_matte", r.ignored_matte)?;
    d.set_item("notes", r.notes.clone())?;
    d.set_item("seconds", r.seconds)?;
    Ok(d)
}

/// interpolate_field(method, points, displacements, height, width, lines_rest=None,
/// lines_pose=None, max_samples=1000, a=1.0, b=2.0, p=0.0) -> (field, report)
#[pyfunction]
#[pyo3(signature = (method, points, displacements, height, width, lines_rest=None, lines_pose=None, max_samples=methods::DEFAULT_MAX_SAMPLES, a=1.0, b=2.0, p=0.0))]
fn interpolate_field<'py>(
    py: Python<'py>,
    method: &str,
    points: PyReadonlyArray2<'py, f64>,
    displacements: PyReadonlyArray2<'py, f64>,
    height: usize,
    width: usize,
    lines_rest: Option<PyReadonlyArray3<'py, f64>>,
    lines_pose: Option<PyReadonlyArray3<'py, f64>>,
    max_samples: usize,
    a: f64,
    b: f64,
    p: f64,
) -> PyResult<(Bound<'py, PyArray3<f32>>, Bound<'py, PyDict>)> {
    crate::limits::check_grid(width, height)?;
    crate::limits::check_memory(width, height, crate::limits::INTERPOLATE_BYTES_PER_PIXEL, 0)?;
    let method: methods::Method = method.parse().map_err(input_error)?;
    let Some(interpolant) = method.interpolant() else {
        return Err(input_error(
            "interpolate_field does not run the grid thin plate: use thin_plate for method \"tps\".",
        ));
    };
    let rest = points_of("points", &points)?;
    let disp = points_of("displacements", &displacements)?;
    if rest.len() != disp.len() {
        return Err(input_error(format!(
            "points and displacements must have the same length; got {} points and {} displacements.",
            rest.len(),
            disp.len()
        )));
    }
    let samples: Vec<Sample> = rest.into_iter().zip(disp).map(|(r, d)| Sample { rest: r, displacement: d }).collect();
    let line_pairs = match (lines_rest, lines_pose) {
        (None, None) => Vec::new(),
        (Some(r), Some(q)) => {
            let (r, q) = (segments_of("lines_rest", &r)?, segments_of("lines_pose", &q)?);
            if r.len() != q.len() {
                return Err(input_error(format!(
                    "lines_rest and lines_pose must hold the same number of segments; got {} and {}.",
                    r.len(),
                    q.len()
                )));
            }
            r.into_iter().zip(q).map(|(rest, pose)| LinePair { rest, pose }).collect()
        }
        _ => {
            return Err(input_error(
                "give both lines_rest and lines_pose (the segments before and after), or neither.",
            ))
        }
    };
    let controls = Controls { samples, line_pairs };
    let params = MethodParams { max_samples, beier_neely: BeierNeelyParams { a, b, p } };
    let (field, report) = crate::errors::run_engine(py, || {
        methods::field(interpolant, &controls, width, height, &params)
    })?
    .map_err(|e| match e {
        methods::MethodError::Interrupted => crate::errors::interrupted("the interpolation"),
        e => input_error(e),
    })?;
    let arr = Array3::from_shape_vec((height, width, 2), field.to_interleaved()).map_err(input_error)?;
    Ok((PyArray3::from_owned_array(py, arr), report_dict(py, &report)?))
}

/// The continuous thin-plate map fitted from source points to target points.
#[pyclass(name = "ThinPlateMap", module = "inkwarp._inkwarp", frozen)]
struct PyThinPlateMap {
    map: methods::ThinPlateMap,
}

#[pymethods]
impl PyThinPlateMap {
    #[new]
    fn new(py: Python<'_>, source: PyReadonlyArray2<'_, f64>, target: PyReadonlyArray2<'_, f64>) -> PyResult<Self> {
        let src = points_of("source", &source)?;
        let dst = points_of("target", &target)?;
        // Its dense solve runs in parallel for many points: on the engine's pool.
        let map = crate::errors::run_engine(py, || methods::ThinPlateMap::fit(&src, &dst))?.map_err(input_error)?;
        Ok(PyThinPlateMap { map })
    }

    /// Maps (N, 2) points; returns (N, 2) float64.
    fn __call__<'py>(&self, py: Python<'py>, points: PyReadonlyArray2<'py, f64>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let pts = points_of("points", &points)?;
        let out: Vec<f64> = pts.iter().flat_map(|&p| self.map.apply(p)).collect();
        let arr = Array2::from_shape_vec((pts.len(), 2), out).map_err(input_error)?;
        Ok(PyArray2::from_owned_array(py, arr))
    }

    /// The displacement at every pixel of a (height, width) image, float32 (H, W, 2).
    fn field<'py>(&self, py: Python<'py>, height: usize, width: usize) -> PyResult<Bound<'py, PyArray3<f32>>> {
        crate::limits::check_grid(width, height)?;
        let f = crate::errors::run_engine(py, || self.map.field(width, height))?;
        let arr = Array3::from_shape_vec((height, width, 2), f.to_interleaved()).map_err(input_error)?;
        Ok(PyArray3::from_owned_array(py, arr))
    }

    fn __len__(&self) -> usize {
        self.map.len()
    }
}

fn kind_of(name: &str) -> PyResult<Kind> {
    name.parse().map_err(input_error)
}

type FeatureTuple = (String, String, Vec<Point>, Vec<Vec<Point>>);

fn features_of(list: Vec<FeatureTuple>) -> PyResult<Vec<TransferFeature>> {
    list.into_iter()
        .map(|(id, kind, rest, keys)| Ok(TransferFeature { id, kind: kind_of(&kind)?, rest, keys }))
        .collect()
}

/// transfer_keys(source, target) -> list of (list of key point lists) or None per target feature.
///
/// Each feature is a tuple `(id, kind, rest_points, [key_points, ...])`.
#[pyfunction]
fn transfer_keys(
    py: Python<'_>,
    source: Vec<FeatureTuple>,
    target: Vec<FeatureTuple>,
) -> PyResult<Vec<Option<Vec<Vec<Point>>>>> {
    let (s, t) = (features_of(source)?, features_of(target)?);
    crate::errors::run_engine(py, || transfer::transfer_keys(&s, &t))?.map_err(input_error)
}

/// transfer_fold(source, target) -> (x, y, feature_id, message) or None
///
/// Where the transfer map folds the source's drawing over (see `transfer::find_fold`).
#[pyfunction]
fn transfer_fold(
    py: Python<'_>,
    source: Vec<FeatureTuple>,
    target: Vec<FeatureTuple>,
) -> PyResult<Option<(f64, f64, String, String)>> {
    let (s, t) = (features_of(source)?, features_of(target)?);
    let fold = crate::errors::run_engine(py, || transfer::find_fold(&s, &t))?.map_err(input_error)?;
    Ok(fold.map(|f| (f.at[0], f.at[1], f.feature.clone(), f.to_string())))
}

/// One posed feature for overlays: id, kind and its polyline.
type DrawingLine<'py> = (String, &'static str, Bound<'py, PyArray2<f64>>);

/// posed_drawing(doc_json, time, spacing=1.0) -> list of (id, kind, (K, 2) float64 array)
///
/// The scene document's drawing at `time`, every curve as a dense polyline (overlays).
#[pyfunction]
#[pyo3(signature = (doc_json, time, spacing=1.0))]
fn posed_drawing<'py>(
    py: Python<'py>,
    doc_json: &str,
    time: f64,
    spacing: f64,
) -> PyResult<Vec<DrawingLine<'py>>> {
    let doc = inkwarp_core::scene::parse_doc(doc_json).map_err(input_error)?;
    methods::scene::posed_drawing(&doc, time, spacing)
        .into_iter()
        .map(|(id, kind, line)| {
            let n = line.len();
            let arr = Array2::from_shape_vec((n, 2), line.into_iter().flatten().collect()).map_err(input_error)?;
            Ok((id, kind.name(), PyArray2::from_owned_array(py, arr)))
        })
        .collect()
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(posed_drawing, m)?)?;
    m.add_function(wrap_pyfunction!(interpolate_field, m)?)?;
    m.add_function(wrap_pyfunction!(transfer_keys, m)?)?;
    m.add_function(wrap_pyfunction!(transfer_fold, m)?)?;
    m.add_class::<PyThinPlateMap>()?;
    Ok(())
}

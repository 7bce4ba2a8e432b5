//! `thin_plate_solve`: the grid thin plate for `inkwarp.thin_plate` (argument checking with
//! friendly messages happens in `inkwarp/plate.py`, but for the initial field's finiteness,
//! which the core checks in its own pass; this adapter converts and calls the core).

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use std::sync::{Arc, Mutex};

use inkwarp_core::solve::{in_pool, SolveError, SolveMethod, SolveOptions, Solver, Stop};
use inkwarp_core::{FieldView, Grid, Sample};

use crate::errors::input_error;

/// Earlier solves of one animated surface (`inkwarp.WarmStart`): the next solve starts
/// from the combination of their fields that best matches its displacements, and reuses
/// their hierarchy and work vectors (its [`Solver`]).
#[pyclass(name = "WarmStart", module = "inkwarp")]
#[derive(Debug, Default)]
pub struct PyWarmStart {
    solver: Mutex<Solver>,
}

#[pymethods]
impl PyWarmStart {
    #[new]
    fn new() -> Self {
        Self::default()
    }

    /// Forgets every earlier solve (the next one is cold).
    fn clear(&self) {
        self.lock().clear();
    }

    fn __len__(&self) -> usize {
        self.lock().history().len()
    }

    fn __repr__(&self) -> String {
        format!("WarmStart({} earlier solves)", self.lock().history().len())
    }
}

impl PyWarmStart {
    fn lock(&self) -> std::sync::MutexGuard<'_, Solver> {
        locked(&self.solver)
    }
}

/// The solver of a `WarmStart` or `Solver` (a panic in an earlier solve leaves it usable).
fn locked(solver: &Mutex<Solver>) -> std::sync::MutexGuard<'_, Solver> {
    solver.lock().unwrap_or_else(|e| e.into_inner())
}

/// A solver kept between calls (`inkwarp.Solver`): its hierarchies, free functions and work
/// vectors (of every piece of the last grids and constraints it solved) are reused by the
/// next solve on the same grid and points, which starts from its earlier answers where their
/// displacements span the new ones (see the core's `Solver`).
#[pyclass(name = "Solver", module = "inkwarp")]
#[derive(Debug, Default)]
pub struct PySolver {
    solver: Mutex<Solver>,
}

#[pymethods]
impl PySolver {
    #[new]
    fn new() -> Self {
        Self::default()
    }

    /// Forgets the pieces' earlier answers (the next solve starts from its `initial` or
    /// from scratch); the levels stay.
    fn clear(&self) {
        self.lock().clear();
    }

    fn __repr__(&self) -> String {
        "Solver()".to_string()
    }
}

impl PySolver {
    fn lock(&self) -> std::sync::MutexGuard<'_, Solver> {
        locked(&self.solver)
    }
}

/// The last grid without mask or cuts (most calls), kept by shape: building one allocates
/// three vectors of its size. At 513 × 513 that took about 0.4 ms in a native loop, on fresh
/// pages each time (0.035 ms with the allocator keeping its memory); from Python, where the
/// allocator kept more of it, keeping the grid took about 0.05 ms off the time around a
/// solve.
static OPEN_GRID: Mutex<Option<Arc<Grid>>> = Mutex::new(None);

fn open_grid(width: usize, height: usize) -> Arc<Grid> {
    let mut kept = OPEN_GRID.lock().unwrap_or_else(|e| e.into_inner());
    match &*kept {
        Some(g) if (g.width, g.height) == (width, height) => g.clone(),
        _ => kept.insert(Arc::new(Grid::new(width, height))).clone(),
    }
}

/// The grid of an `(H, W)` mask (nonzero: active), or a ValueError naming its shape.
pub(crate) fn matte_grid(mask: &PyReadonlyArray2<'_, u8>, width: usize, height: usize) -> PyResult<Grid> {
    if mask.shape() != [height, width] {
        return Err(input_error(format!(
            "mask has shape {:?} but the grid is ({height}, {width}); pass an (H, W) mask.",
            mask.shape()
        )));
    }
    Ok(Grid::from_matte(width, height, &mask.as_array().iter().copied().collect::<Vec<u8>>()))
}

/// Solves the thin plate; returns the float32 (H, W, 2) field and the report as a dict.
#[pyfunction]
#[pyo3(signature = (points, displacements, height, width, mask, cuts, tension, tolerance,
                    grid_step, initial, max_cycles, method, southwell_sweeps, warm=None, off="", solver=None))]
#[allow(clippy::too_many_arguments)]
fn thin_plate_solve<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    displacements: PyReadonlyArray2<'py, f64>,
    height: usize,
    width: usize,
    mask: Option<PyReadonlyArray2<'py, u8>>,
    cuts: Vec<PyReadonlyArray2<'py, f64>>,
    tension: f64,
    tolerance: f64,
    grid_step: usize,
    initial: Option<PyReadonlyArray3<'py, f32>>,
    max_cycles: Option<usize>,
    method: &str,
    southwell_sweeps: f64,
    warm: Option<PyRef<'py, PyWarmStart>>,
    off: &str,
    solver: Option<PyRef<'py, PySolver>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyDict>)> {
    let off = inkwarp_core::solve::Ablation::parse(off).map_err(|e| input_error(format!("_off: {e}.")))?;
    let method = match method {
        "multigrid" => SolveMethod::Multigrid,
        "southwell" => SolveMethod::Southwell,
        other => {
            return Err(input_error(format!(
                "method must be \"multigrid\" or \"southwell\", got {other:?}."
            )))
        }
    };
    crate::limits::check_grid(width, height)?;
    let pts = points.as_array();
    let disp = displacements.as_array();
    if pts.ncols() != 2 || disp.ncols() != 2 || pts.nrows() != disp.nrows() {
        return Err(input_error(
            "points and displacements must both be (N, 2) arrays of the same length.",
        ));
    }
    crate::limits::check_coordinates("points", pts.iter())?;
    crate::limits::check_coordinates("displacements", disp.iter())?;
    let samples: Vec<Sample> = (0..pts.nrows())
        .map(|k| Sample { rest: [pts[[k, 0]], pts[[k, 1]]], displacement: [disp[[k, 0]], disp[[k, 1]]] })
        .collect();
    let open = mask.is_none() && cuts.is_empty();
    let grid = if open {
        open_grid(width, height)
    } else {
        let mut grid = match &mask {
            Some(m) => matte_grid(m, width, height)?,
            None => Grid::new(width, height),
        };
        crate::limits::cuts_of(&cuts)?.iter().for_each(|p| grid.add_cut(p));
        Arc::new(grid)
    };
    // Thin parts and slow modes, on the grid the solve runs on. An open grid has none unless a side
    // is narrow: the kept open grid is not read again on every call.
    let extra = if open && width.min(height) > inkwarp_core::solve::THIN * grid_step.max(1) {
        0
    } else {
        crate::limits::solve_extra_bytes(&grid, grid_step)
    };
    crate::limits::check_memory(width, height, crate::limits::SOLVE_BYTES_PER_PIXEL, extra)?;
    if let Some(f) = &initial {
        if f.shape() != [height, width, 2] {
            return Err(input_error(format!(
                "initial has shape {:?} but must be ({height}, {width}, 2).",
                f.shape()
            )));
        }
    }
    // Read in place when in C order; any other layout is copied into it first.
    let initial = initial.as_ref().map(|f| f.as_array());
    let initial = initial.as_ref().map(|a| a.as_standard_layout());
    let initial = initial.as_ref().map(|c| c.as_slice().expect("standard layout is contiguous"));
    let options = SolveOptions { tension, tolerance_px: tolerance, grid_step, max_cycles, method, southwell_sweeps, off };
    let mut history = warm.as_ref().map(|w| std::mem::take(&mut *w.lock()));
    let mut kept = solver.as_ref().map(|s| std::mem::take(&mut *s.lock()));
    // Without the interpreter, and on the solver's pool with the answer's conversion (its
    // parallel pass would otherwise wake the pool from outside).
    let result = crate::errors::run_engine(py, || {
        in_pool(|| {
            // Read in place by the solve (no planar copy first).
            let initial = initial.map(|data| FieldView::Interleaved { width, height, data });
            let result = match (history.as_mut(), kept.as_mut()) {
                (Some(s), _) => s.solve_frame(&grid, &samples, &options),
                (None, Some(s)) => s.solve(&grid, &samples, &options, initial),
                (None, None) => Solver::new().solve(&grid, &samples, &options, initial),
            };
            result.map(|(field, report)| (field.to_interleaved(), report))
        })
    });
    if let (Some(w), Some(h)) = (&warm, history) {
        // Out of its lock while the solve ran.
        *w.lock() = h;
    }
    if let (Some(s), Some(k)) = (&solver, kept) {
        *s.lock() = k;
    }
    let (field, report) = result?.map_err(|e| match e {
        // `inkwarp.thin_plate` leaves this check to the core (one pass over the field fewer).
        SolveError::NonFiniteInitial => {
            input_error(
                "initial has NaN or infinite values (it is read as float32, where anything beyond \
                 ±3.4e38 is infinite); pass a finite field (or None).",
            )
        }
        SolveError::Interrupted => crate::errors::interrupted("the thin-plate solve"),
        e => input_error(e.to_string()),
    })?;
    let array = PyArray1::from_vec(py, field).reshape([height, width, 2])?;
    let d = PyDict::new(py);
    d.set_item("cycles", report.cycles)?;
    d.set_item("final_change", report.final_change_px)?;
    d.set_item("residual", report.residual)?;
    d.set_item("initial_residual", report.initial_residual)?;
    d.set_item("constrained_nodes", report.constrained_nodes)?;
    d.set_item("constrained_samples", report.constrained_samples)?;
    d.set_item("dropped_samples", report.dropped_samples)?;
    d.set_item("seconds", report.seconds)?;
    d.set_item("converged", report.converged)?;
    d.set_item("stop", stop_name(report.stop))?;
    d.set_item("probe_cycles", report.probe_cycles)?;
    Ok((array.into_any(), d))
}

/// The report's `stop`, as Python reads it.
fn stop_name(stop: Stop) -> &'static str {
    match stop {
        Stop::Converged => "converged",
        Stop::MaxCycles => "max_cycles",
        Stop::Budget => "budget",
        Stop::Unsettled => "unsettled",
        Stop::Precision => "precision",
        Stop::Residual => "residual",
        Stop::Breakdown => "breakdown",
        Stop::Interrupted => "interrupted",
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(thin_plate_solve, m)?)?;
    m.add_class::<PyWarmStart>()?;
    m.add_class::<PySolver>()?;
    Ok(())
}

//! The core's limits (`inkwarp_core::limits`) as Python errors, and the memory check that
//! needs the machine (how much memory is free), which the pure core cannot ask.

use inkwarp_core::limits;
use pyo3::prelude::*;

use crate::errors::input_error;

/// Rough peak memory of a grid solve per pixel (the field, its levels, work vectors and
/// matte): about 150 bytes on an open grid, 210 with a hole and a cut (2049 × 2049 and
/// 3840 × 2160, peak resident memory of the process). A matte's thin parts and a torn
/// grid's slow modes add `inkwarp_core::limits::thin_and_slow_bytes`.
pub const SOLVE_BYTES_PER_PIXEL: u64 = 220;
/// The same for the other methods' fields (`interpolate`): the field and the method's own
/// per-pixel work.
pub const INTERPOLATE_BYTES_PER_PIXEL: u64 = 48;

/// ValueError unless every value is finite and within `inkwarp_core::limits::MAX_COORD_PX`.
pub fn check_coordinates<'a>(name: &str, values: impl Iterator<Item = &'a f64>) -> PyResult<()> {
    for &v in values {
        if !limits::coordinate_ok(v) {
            return Err(input_error(format!(
                "{name} must be finite numbers of pixels within ±{:e}, found {}.",
                limits::MAX_COORD_PX,
                limits::show(v)
            )));
        }
    }
    Ok(())
}

/// The largest image file read (bigger files are refused before reading).
pub const MAX_IMAGE_FILE_BYTES: u64 = 1 << 30;

/// The cuts as polylines: each a (K, 2) array of (x, y) points within the coordinate limits.
pub fn cuts_of(cuts: &[numpy::PyReadonlyArray2<'_, f64>]) -> PyResult<Vec<Vec<[f64; 2]>>> {
    cuts.iter().enumerate().map(|(k, cut)| {
        let c = cut.as_array();
        if c.ncols() != 2 {
            return Err(input_error("every cut must be a (K, 2) array of (x, y) points."));
        }
        check_coordinates(&format!("cuts[{k}]"), c.iter())?;
        Ok((0..c.nrows()).map(|k| [c[[k, 0]], c[[k, 1]]]).collect())
    }).collect()
}

/// ValueError unless a `width × height` grid is within the core's limits.
pub fn check_grid(width: usize, height: usize) -> PyResult<()> {
    check_size("the grid", width, height)
}

/// ValueError unless a `width × height` picture or grid is within the core's limits, in the
/// core's words (`inkwarp_core::limits::check_size`; its message starts with `what`).
#[pyfunction]
pub fn check_size(what: &str, width: usize, height: usize) -> PyResult<()> {
    limits::check_size(what, width, height).map_err(input_error)
}

/// What a thin-plate solve on `grid` at `grid_step` needs beyond [`SOLVE_BYTES_PER_PIXEL`]:
/// the thin parts and slow modes of the grid it runs on (the coarse one at a step above 1).
pub fn solve_extra_bytes(grid: &inkwarp_core::Grid, grid_step: usize) -> u64 {
    let coarse = (grid_step > 1).then(|| inkwarp_core::solve::coarse_grid(grid, grid_step));
    limits::thin_and_slow_bytes([coarse.as_ref().unwrap_or(grid)])
}

/// The memory estimate `inkwarp.thin_plate` checks for a `width × height` grid with `mask`
/// (nonzero: active) and no cuts, solved at `grid_step`, in bytes: the benchmarks weigh it
/// against what a solve takes, from the engine's own count rather than a copy of it.
#[pyfunction]
#[pyo3(signature = (width, height, mask=None, grid_step=1))]
pub fn _solve_bytes(width: usize, height: usize, mask: Option<numpy::PyReadonlyArray2<'_, u8>>, grid_step: usize) -> PyResult<u64> {
    check_grid(width, height)?;
    let grid = match mask {
        Some(m) => crate::solve::matte_grid(&m, width, height)?,
        None => inkwarp_core::Grid::new(width, height),
    };
    Ok(needed_bytes(width, height, SOLVE_BYTES_PER_PIXEL, solve_extra_bytes(&grid, grid_step)))
}

/// The memory this machine has free for new work, in bytes (None when unknown).
pub fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// Why work needing about `needed` bytes cannot run here, if it cannot.
pub fn memory_problem(needed: u64) -> Option<String> {
    let free = available_bytes()?;
    (needed > free).then(|| {
        format!(
            "rendering this scene needs about {} GiB of memory but {} GiB is free; use a \
             larger solver.grid_step, fewer layers or a smaller picture",
            limits::gib(needed),
            limits::gib(free)
        )
    })
}

/// `bytes_per_pixel` for each of `width × height` pixels, and `extra`.
fn needed_bytes(width: usize, height: usize, bytes_per_pixel: u64, extra: u64) -> u64 {
    (width as u64).saturating_mul(height as u64).saturating_mul(bytes_per_pixel).saturating_add(extra)
}

/// ValueError unless a solve or field of `width × height` fits in free memory
/// (`bytes_per_pixel` of it per pixel, and `extra` bytes).
pub fn check_memory(width: usize, height: usize, bytes_per_pixel: u64, extra: u64) -> PyResult<()> {
    let needed = needed_bytes(width, height, bytes_per_pixel, extra);
    match available_bytes() {
        Some(free) if needed > free => Err(input_error(format!(
            "a {width}×{height} grid needs about {} GiB of memory but {} GiB is free; use \
             grid_step or a smaller grid",
            limits::gib(needed),
            limits::gib(free)
        ))),
        _ => Ok(()),
    }
}

/// ValueError unless the curve through `points` at `spacing` pixels stays under the
/// core's sample limit (`inkwarp_core::limits::MAX_CURVE_SAMPLES`).
pub fn check_sampling(points: &[[f64; 2]], closed: bool, spacing: f64) -> PyResult<()> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Ok(()); // the core says what is wrong with it
    }
    limits::check_curve_samples(points, closed, spacing).map_err(input_error)
}

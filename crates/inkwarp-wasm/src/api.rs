//! The exported calls: grids, solves, curves, the CPU renderer.

use std::cell::RefCell;

use inkwarp_core::geometry::{curve_polyline, sample_feature, SampleOptions};
use crate::stand_in::{Canvas, RgbaImage};
use crate::stand_in::{solve, SolveMethod, SolveOptions};
use inkwarp_core::{Field, Grid, Kind, Point, Sample};
use serde::Deserialize;

use crate::{bytes, bytes_mut, fail, floats, floats_mut, json_arg, ok_json};

thread_local! {
    static GRIDS: RefCell<Vec<Option<Grid>>> = const { RefCell::new(Vec::new()) };
    static CANVASES: RefCell<Vec<Option<Canvas>>> = const { RefCell::new(Vec::new()) };
}

fn insert<T>(store: &mut Vec<Option<T>>, value: T) -> u32 {
    if let Some(i) = store.iter().position(Option::is_none) {
        store[i] = Some(value);
        return i as u32 + 1;
    }
    store.push(Some(value));
    store.len() as u32
}

fn with_grid<R>(handle: u32, f: impl FnOnce(&Grid) -> R) -> Result<R, String> {
    GRIDS.with(|g| {
        let store = g.borrow();
        match store.get((handle as usize).wrapping_sub(1)).and_then(Option::as_ref) {
            Some(grid) => Ok(f(grid)),
            None => Err(format!("There is no grid with handle {handle}.")),
        }
    })
}

/// Builds the solve domain of a `width × height` layer: active nodes from the continuity
/// matte (`matte_len == 0`: every node active; else `width * height` bytes, nonzero =
/// connected), then the cut polylines in `cuts_json` (`[[[x, y], ...], ...]`, may be empty)
/// break the links they cross. Returns a handle (≥ 1), or 0 with the error in the result.
#[no_mangle]
pub extern "C" fn iw_grid_new(
    width: usize,
    height: usize,
    matte_ptr: *const u8,
    matte_len: usize,
    cuts_ptr: *const u8,
    cuts_len: usize,
) -> u32 {
    if width == 0 || height == 0 {
        fail("A layer needs a width and a height of at least 1 pixel.");
        return 0;
    }
    let mut grid = if matte_len == 0 {
        Grid::new(width, height)
    } else if matte_len != width * height {
        fail(format!(
            "The continuity matte has {matte_len} values but the layer is {width}×{height} = {} pixels.",
            width * height
        ));
        return 0;
    } else {
        Grid::from_matte(width, height, bytes(matte_ptr, matte_len))
    };
    if cuts_len > 0 {
        let cuts: Vec<Vec<Point>> = match json_arg(cuts_ptr, cuts_len) {
            Ok(c) => c,
            Err(e) => {
                fail(e);
                return 0;
            }
        };
        for cut in &cuts {
            crate::stand_in::add_cut(&mut grid, cut);
        }
    }
    GRIDS.with(|g| insert(&mut g.borrow_mut(), grid))
}

/// Frees a grid.
#[no_mangle]
pub extern "C" fn iw_grid_free(handle: u32) {
    GRIDS.with(|g| {
        if let Some(slot) = g.borrow_mut().get_mut((handle as usize).wrapping_sub(1)) {
            *slot = None;
        }
    });
}

/// Writes one byte per node into `out` (`width * height` bytes): bit 0 active, bit 1
/// linked to the right neighbour, bit 2 linked to the neighbour below. The WebGL renderer
/// drops the quads whose links are missing from this. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_grid_links(handle: u32, out_ptr: *mut u8, out_len: usize) -> i32 {
    let res = with_grid(handle, |grid| {
        let n = grid.width * grid.height;
        if out_len != n {
            return Err(format!("The link buffer has {out_len} bytes; the grid needs {n}."));
        }
        let out = bytes_mut(out_ptr, out_len);
        for i in 0..n {
            out[i] = grid.active[i] as u8 | (grid.link_right[i] as u8) << 1 | (grid.link_down[i] as u8) << 2;
        }
        Ok(())
    });
    match res {
        Ok(Ok(())) => 0,
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// One feature of a solve request: its kind, rest and posed control points.
#[derive(Debug, Deserialize)]
struct FeatureIn {
    kind: Kind,
    rest: Vec<Point>,
    pose: Vec<Point>,
    #[serde(default)]
    closed: bool,
    /// A region whose outline is a spline (`"curve": "spline"` in the scene).
    #[serde(default)]
    spline_outline: bool,
    /// The id, only for error messages.
    #[serde(default)]
    id: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(default)]
struct OptionsIn {
    tension: f64,
    tolerance: f64,
    grid_step: usize,
    max_cycles: Option<usize>,
    method: String,
}

impl Default for OptionsIn {
    fn default() -> Self {
        OptionsIn { tension: 0.0, tolerance: 0.01, grid_step: 1, max_cycles: None, method: "multigrid".into() }
    }
}

#[derive(Debug, Deserialize)]
struct SolveIn {
    features: Vec<FeatureIn>,
    #[serde(default)]
    options: OptionsIn,
    /// Arc-length sampling spacing in pixels (default 1).
    #[serde(default)]
    spacing_px: Option<f64>,
}

fn samples_of(features: &[FeatureIn], grid: &Grid, spacing_px: f64) -> Result<Vec<Sample>, String> {
    let mut samples = Vec::new();
    for (i, f) in features.iter().enumerate() {
        let opts = SampleOptions { closed: f.closed, spline_outline: f.spline_outline, spacing_px };
        let domain = (f.kind == Kind::Region).then_some(grid);
        match sample_feature(f.kind, &f.rest, &f.pose, &opts, domain) {
            Ok(s) => samples.extend(s),
            Err(e) => {
                let name = f.id.clone().unwrap_or_else(|| format!("#{i}"));
                return Err(format!("Feature {name}: {e}"));
            }
        }
    }
    Ok(samples)
}

/// Solves the thin plate for a drawing on a grid.
///
/// `req_json`: `{"features": [{"kind", "rest", "pose", "closed", "spline_outline"}],
/// "options": {"tension", "tolerance", "grid_step", "max_cycles", "method"}, "spacing_px"}`.
/// `initial` (`2 * width * height` floats, Δx plane then Δy plane, or null) warm-starts the
/// solve; the field is written to `out` in the same planar layout (the two may be the same
/// buffer). The result holds the solve report as JSON. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_solve(
    handle: u32,
    req_ptr: *const u8,
    req_len: usize,
    initial_ptr: *const f32,
    out_ptr: *mut f32,
) -> i32 {
    let req: SolveIn = match json_arg(req_ptr, req_len) {
        Ok(r) => r,
        Err(e) => return fail(e),
    };
    let res = with_grid(handle, |grid| -> Result<serde_json::Value, String> {
        let n = grid.width * grid.height;
        let samples = samples_of(&req.features, grid, req.spacing_px.unwrap_or(1.0))?;
        let method = match req.options.method.as_str() {
            "multigrid" => SolveMethod::Multigrid,
            "southwell" => SolveMethod::Southwell,
            other => return Err(format!("Unknown solver method {other:?}; use \"multigrid\" or \"southwell\".")),
        };
        let options = SolveOptions {
            tension: req.options.tension,
            tolerance_px: req.options.tolerance,
            grid_step: req.options.grid_step.max(1),
            max_cycles: req.options.max_cycles,
            method,
            ..SolveOptions::default()
        };
        let initial = (!initial_ptr.is_null()).then(|| {
            let data = floats(initial_ptr, 2 * n);
            Field { width: grid.width, height: grid.height, dx: data[..n].to_vec(), dy: data[n..].to_vec() }
        });
        let (field, report) = solve(grid, &samples, &options, initial.as_ref()).map_err(|e| e.to_string())?;
        let out = floats_mut(out_ptr, 2 * n);
        out[..n].copy_from_slice(&field.dx);
        out[n..].copy_from_slice(&field.dy);
        Ok(serde_json::json!({
            "cycles": report.cycles,
            "final_change_px": report.final_change_px,
            "residual": report.residual,
            "constrained_nodes": report.constrained_nodes,
            "constrained_samples": report.constrained_samples,
            "dropped_samples": report.dropped_samples,
            "converged": report.converged,
            "samples": samples.len(),
        }))
    });
    match res {
        Ok(Ok(v)) => ok_json(&v),
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

#[derive(Debug, Deserialize)]
struct CurveIn {
    kind: Kind,
    points: Vec<Point>,
    #[serde(default)]
    closed: bool,
    #[serde(default)]
    spline_outline: bool,
    #[serde(default)]
    spacing_px: Option<f64>,
}

/// The curve through a feature's control points as a dense polyline, for overlays and
/// cuts. `req_json`: `{"kind", "points", "closed", "spline_outline", "spacing_px"}`; the
/// result is `[[x, y], ...]`. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_curve(req_ptr: *const u8, req_len: usize) -> i32 {
    let req: CurveIn = match json_arg(req_ptr, req_len) {
        Ok(r) => r,
        Err(e) => return fail(e),
    };
    let line = curve_polyline(req.kind, &req.points, req.closed, req.spline_outline, req.spacing_px.unwrap_or(2.0));
    ok_json(&line)
}

fn with_canvas<R>(handle: u32, f: impl FnOnce(&mut Canvas) -> R) -> Result<R, String> {
    CANVASES.with(|c| {
        let mut store = c.borrow_mut();
        match store.get_mut((handle as usize).wrapping_sub(1)).and_then(Option::as_mut) {
            Some(canvas) => Ok(f(canvas)),
            None => Err(format!("There is no canvas with handle {handle}.")),
        }
    })
}

/// A CPU canvas (the reference renderer) of `width × height` filled with `background`
/// (straight RGBA8). Returns a handle ≥ 1.
#[no_mangle]
pub extern "C" fn iw_canvas_new(width: usize, height: usize, r: u8, g: u8, b: u8, a: u8) -> u32 {
    CANVASES.with(|c| insert(&mut c.borrow_mut(), Canvas::new(width, height, [r, g, b, a])))
}

/// Frees a canvas.
#[no_mangle]
pub extern "C" fn iw_canvas_free(handle: u32) {
    CANVASES.with(|c| {
        if let Some(slot) = c.borrow_mut().get_mut((handle as usize).wrapping_sub(1)) {
            *slot = None;
        }
    });
}

/// Forward-maps a layer onto a canvas: `image` is straight RGBA8 of the grid's size,
/// `field` planar (Δx plane, Δy plane), offset in pixels. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_canvas_draw(
    canvas: u32,
    grid: u32,
    image_ptr: *const u8,
    field_ptr: *const f32,
    offset_x: f64,
    offset_y: f64,
) -> i32 {
    let res = with_grid(grid, |grid| {
        let n = grid.width * grid.height;
        let image = RgbaImage { width: grid.width, height: grid.height, data: bytes(image_ptr, 4 * n).to_vec() };
        let data = floats(field_ptr, 2 * n);
        let field = Field { width: grid.width, height: grid.height, dx: data[..n].to_vec(), dy: data[n..].to_vec() };
        with_canvas(canvas, |c| c.draw_layer(&image, &field, grid, [offset_x, offset_y]))
    });
    match res {
        Ok(Ok(())) => 0,
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// Copies a canvas as straight RGBA8 into `out` (`4 * width * height` bytes). Status 0/1.
#[no_mangle]
pub extern "C" fn iw_canvas_read(canvas: u32, out_ptr: *mut u8, out_len: usize) -> i32 {
    let res = with_canvas(canvas, |c| {
        let img = c.to_rgba8();
        if img.data.len() != out_len {
            return Err(format!("The output buffer has {out_len} bytes; the canvas needs {}.", img.data.len()));
        }
        bytes_mut(out_ptr, out_len).copy_from_slice(&img.data);
        Ok(())
    });
    match res {
        Ok(Ok(())) => 0,
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

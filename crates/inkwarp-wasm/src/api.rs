//! The exported calls: grids, solves, curves, the CPU renderer.

use std::cell::RefCell;
use std::collections::HashMap;

use inkwarp_core::anim::{points_at, Interpolation, Key};
use inkwarp_core::geometry::{curve_polyline, sample_feature, FeatureSampler, SampleOptions};
use inkwarp_core::methods::scene::{method_params, BEIER_NEELY_SEGMENT_PX};
use inkwarp_core::methods::{
    controls_field, line_pairs_from_chain, note_ignored_matte, Controls, Interpolant, Method,
    MethodParams, MethodReport, ThinPlateMap,
};
use inkwarp_core::render::{draw_frame, draw_view, view_size, Canvas, PreparedLayer, RgbaImage, ViewLayer};
use inkwarp_core::scene::{images, BeierNeelyDoc, SolverDoc, TpsExactDoc};
use inkwarp_core::solve::{SolveMethod, SolveOptions, Solver, Upsampling};
use inkwarp_core::{Field, Grid, Kind, Point, Sample};
use serde::Deserialize;

use crate::{fail, insert, json_arg, ok_json, release, slot, slot_mut, view, view_mut};

/// The spacing at which the scene engine densifies a cut before breaking links.
const CUT_SPACING_PX: f64 = 0.5;

thread_local! {
    static DECODED: RefCell<Option<RgbaImage>> = const { RefCell::new(None) };
    static GRIDS: RefCell<Vec<Option<Domain>>> = const { RefCell::new(Vec::new()) };
    static CANVASES: RefCell<Vec<Option<Canvas>>> = const { RefCell::new(Vec::new()) };
    static IMAGES: RefCell<Vec<Option<RgbaImage>>> = const { RefCell::new(Vec::new()) };
    /// Fields kept in the module by `iw_grid_solve_kept`, by grid handle, until drawn.
    static SOLVED: RefCell<HashMap<u32, Field>> = RefCell::new(HashMap::new());
}

/// A grid and the features' rest geometry prepared on it (a region's interior nodes and
/// their mean-value coordinates are computed once, as the scene engine does, not per drag
/// event).
#[derive(Debug)]
struct Domain {
    grid: Grid,
    samplers: RefCell<HashMap<String, FeatureSampler>>,
    /// The thin plate's earlier solves per `grid_step` (drafts and full solves apart): a
    /// warm-started solve starts from their best combination (a [`Solver`]'s history), which
    /// during a drag is an extrapolation of the pointer's path.
    history: RefCell<HashMap<usize, Solver>>,
    /// The pixels `iw_solve_at` computes (`iw_grid_select`), and the upsampling plan of
    /// each `grid_step` it was asked for.
    selection: RefCell<Option<Selection>>,
}

#[derive(Debug)]
struct Selection {
    pixels: Vec<u32>,
    plans: HashMap<usize, Upsampling>,
}

/// Prepared samplers kept per grid; more than this and the cache starts over.
const MAX_SAMPLERS: usize = 256;

fn with_domain<R>(handle: u32, f: impl FnOnce(&Domain) -> R) -> Result<R, String> {
    GRIDS.with(|g| match slot(&g.borrow(), handle) {
        Some(domain) => Ok(f(domain)),
        None => Err(format!("There is no grid with handle {handle}.")),
    })
}

fn with_grid<R>(handle: u32, f: impl FnOnce(&Grid) -> R) -> Result<R, String> {
    with_domain(handle, |domain| f(&domain.grid))
}

/// Builds the solve domain of a `width × height` layer: active nodes from the continuity
/// matte (`matte_len == 0`: every node active; else `width * height` bytes, nonzero =
/// connected), then the cuts in `cuts_json` (their rest control points,
/// `[[[x, y], ...], ...]`, may be empty) break the links they cross — the cut's polyline
/// taken exactly as the scene engine takes it. Returns a handle (≥ 1), or 0 with the error in the result.
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
        Grid::from_matte(width, height, view(matte_ptr, matte_len))
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
            grid.add_cut(&curve_polyline(
                Kind::Cut,
                cut,
                false,
                false,
                CUT_SPACING_PX,
            ));
        }
    }
    GRIDS.with(|g| {
        insert(
            &mut g.borrow_mut(),
            Domain {
                grid,
                samplers: RefCell::new(HashMap::new()),
                history: RefCell::new(HashMap::new()),
                selection: RefCell::new(None),
            },
        )
    })
}

/// Frees a grid.
#[no_mangle]
pub extern "C" fn iw_grid_free(handle: u32) {
    GRIDS.with(|g| release(&mut g.borrow_mut(), handle));
    SOLVED.with(|s| s.borrow_mut().remove(&handle));
}

/// Writes one byte per node into `out` (`width * height` bytes): bit 0 active, bit 1
/// linked to the right neighbour, bit 2 linked to the neighbour below. The WebGL renderer
/// drops the quads whose links are missing from this. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_grid_links(handle: u32, out_ptr: *mut u8, out_len: usize) -> i32 {
    let res = with_grid(handle, |grid| {
        let n = grid.width * grid.height;
        if out_len != n {
            return Err(format!(
                "The link buffer has {out_len} bytes; the grid needs {n}."
            ));
        }
        let out = view_mut(out_ptr, out_len);
        for i in 0..n {
            out[i] = grid.active[i] as u8
                | (grid.link_right[i] as u8) << 1
                | (grid.link_down[i] as u8) << 2;
        }
        Ok(())
    });
    match res {
        Ok(Ok(())) => 0,
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// The core's solve options from a request's.
fn solve_options(options: &OptionsIn) -> Result<SolveOptions, String> {
    let scheme = match options.scheme.as_str() {
        "multigrid" => SolveMethod::Multigrid,
        "southwell" => SolveMethod::Southwell,
        other => {
            return Err(format!(
                "Unknown solver scheme {other:?}; use \"multigrid\" or \"southwell\"."
            ))
        }
    };
    Ok(SolveOptions {
        tension: options.tension,
        tolerance_px: options.tolerance,
        grid_step: options.grid_step.max(1),
        max_cycles: options.max_cycles,
        method: scheme,
        ..SolveOptions::default()
    })
}

/// The grid thin plate's report as JSON.
fn tps_report(report: &inkwarp_core::solve::SolveReport) -> serde_json::Value {
    serde_json::json!({
        "cycles": report.cycles,
        "final_change_px": report.final_change_px,
        "residual": report.residual,
        "constrained_nodes": report.constrained_nodes,
        "constrained_samples": report.constrained_samples,
        "dropped_samples": report.dropped_samples,
        "converged": report.converged,
        "probe_cycles": report.probe_cycles,
        "notes": Vec::<String>::new(),
    })
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

/// The solver settings of a request, named as in the scene format's `solver`.
#[derive(Debug, Deserialize)]
#[serde(default)]
struct OptionsIn {
    /// The interpolant: `tps` (the grid thin plate) or another method of DESIGN §6.
    method: String,
    tension: f64,
    tolerance: f64,
    grid_step: usize,
    max_cycles: Option<usize>,
    /// How the grid thin plate is relaxed: `multigrid` or `southwell`.
    scheme: String,
    /// A draft while a point is dragged: `tps-exact` may then be previewed on every
    /// `grid_step`-th pixel (the other methods are fast enough as they are).
    preview: bool,
    /// Beier–Neely's weights `a`, `b`, `p` (`beier-neely` only).
    beier_neely: BeierNeelyDoc,
    /// `max_samples` of `tps-exact`.
    tps_exact: TpsExactDoc,
}

impl OptionsIn {
    /// The interpolants' settings, read as the scene engine reads a layer's `solver`.
    fn method_params(&self) -> MethodParams {
        method_params(&SolverDoc {
            beier_neely: self.beier_neely,
            tps_exact: self.tps_exact,
            ..SolverDoc::default()
        })
    }
}

impl Default for OptionsIn {
    fn default() -> Self {
        OptionsIn {
            method: "tps".into(),
            tension: 0.0,
            tolerance: 0.01,
            grid_step: 1,
            max_cycles: None,
            scheme: "multigrid".into(),
            preview: false,
            beier_neely: BeierNeelyDoc::default(),
            tps_exact: TpsExactDoc::default(),
        }
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
    /// `"hold"`: the grid's outer edge stays put (a layer's `"border": "hold"`); default
    /// `"free"`.
    #[serde(default)]
    border: inkwarp_core::scene::Border,
}

/// Every feature's samples (for the grid thin plate, all of them together), prepared once
/// per rest geometry.
fn samples_of(
    features: &[FeatureIn],
    domain: &Domain,
    spacing_px: f64,
) -> Result<Vec<Vec<Sample>>, String> {
    let mut cache = domain.samplers.borrow_mut();
    if cache.len() > MAX_SAMPLERS {
        cache.clear();
    }
    let mut out = Vec::with_capacity(features.len());
    for (i, f) in features.iter().enumerate() {
        let key =
            serde_json::json!([f.kind, f.rest, f.closed, f.spline_outline, spacing_px]).to_string();
        if !cache.contains_key(&key) {
            let opts = SampleOptions {
                closed: f.closed,
                spline_outline: f.spline_outline,
                spacing_px,
            };
            let on = (f.kind == Kind::Region).then_some(&domain.grid);
            let sampler = FeatureSampler::new(f.kind, &f.rest, &opts, on)
                .map_err(|e| format!("Feature {}: {e}", f.name(i)))?;
            cache.insert(key.clone(), sampler);
        }
        let posed = cache[&key]
            .sample(&f.pose)
            .map_err(|e| format!("Feature {}: {e}", f.name(i)))?;
        out.push(posed);
    }
    Ok(out)
}

impl FeatureIn {
    fn name(&self, index: usize) -> String {
        self.id.clone().unwrap_or_else(|| format!("#{index}"))
    }
}

/// What the drawing hands `interpolant`, feature by feature, exactly as the scene engine
/// hands it (`inkwarp_core::methods::scene::feature_controls`, which works on a scene's
/// tracks rather than on posed features; a test holds the two together): every sample for
/// `tps-exact` and `triangulation`; for `beier-neely` points as Shepard points, polylines
/// and polyline regions as line pairs between control points, splines and spline regions
/// as their curve in segments of about `BEIER_NEELY_SEGMENT_PX`.
fn controls_of(
    features: &[FeatureIn],
    samples: Vec<Vec<Sample>>,
    interpolant: Interpolant,
) -> Result<Controls, String> {
    if interpolant != Interpolant::BeierNeely {
        return Ok(Controls::from_samples(samples.into_iter().flatten().collect()));
    }
    let mut controls = Controls::default();
    for (i, (f, samples)) in features.iter().zip(samples).enumerate() {
        let closed = f.closed || f.kind == Kind::Region;
        match f.kind {
            Kind::Cut => {}
            Kind::Point => controls.samples.extend(samples),
            Kind::Spline => controls.line_pairs.extend(line_pairs_from_chain(
                &samples,
                closed,
                BEIER_NEELY_SEGMENT_PX,
            )),
            Kind::Region if f.spline_outline => {
                let options = SampleOptions {
                    closed: true,
                    spline_outline: false,
                    spacing_px: 1.0,
                };
                let chain = sample_feature(Kind::Spline, &f.rest, &f.pose, &options, None)
                    .map_err(|e| format!("Feature {}: {e}", f.name(i)))?;
                controls.line_pairs.extend(line_pairs_from_chain(
                    &chain,
                    true,
                    BEIER_NEELY_SEGMENT_PX,
                ));
            }
            Kind::Polyline | Kind::Region => {
                let vertices: Vec<Sample> = f
                    .rest
                    .iter()
                    .zip(&f.pose)
                    .map(|(r, p)| Sample {
                        rest: *r,
                        displacement: [p[0] - r[0], p[1] - r[1]],
                    })
                    .collect();
                controls.line_pairs.extend(line_pairs_from_chain(
                    &vertices,
                    closed && vertices.len() > 2,
                    0.0,
                ));
            }
        }
    }
    Ok(controls)
}

/// Computes the displacement field of a drawing on a grid by the request's method.
///
/// `req_json`: `{"features": [{"kind", "rest", "pose", "closed", "spline_outline", "id"}],
/// "options": {"method", "tension", "tolerance", "grid_step", "max_cycles", "scheme",
/// "beier_neely", "tps_exact", "preview"}, "spacing_px"}` (options as in the scene
/// format's `solver`, `grid_step` only for `tps`, plus `preview` for a quick draft, see
/// [`tps_exact_preview`]; the curves are
/// sampled every `spacing_px`, default 1, as the scene engine samples them every
/// `grid_step`).
/// `initial` (`2 * width * height` floats, Δx plane then Δy plane, or null) warm-starts the
/// grid thin plate (the other methods have nothing to start from); the field is written to
/// `out` in the same planar layout (the two may be the same buffer).
///
/// The result is a report as JSON: `method`, `samples`, `notes` (full sentences worth
/// showing, such as a matte that the method ignores) and, for `tps`, the solver's report
/// (`cycles`, `final_change_px`, `residual`, `constrained_nodes`, `constrained_samples`,
/// `dropped_samples`, `converged`, `probe_cycles`); for the other methods `samples_used`,
/// `line_pairs_used`, `dropped` and `ignored_matte`. Status 0/1.
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
    let res = with_domain(handle, |domain| -> Result<serde_json::Value, String> {
        let n = domain.grid.width * domain.grid.height;
        let (field, report) = solve_request(domain, &req, Start::Given(initial_ptr))?;
        let out = view_mut(out_ptr, 2 * n);
        out[..n].copy_from_slice(&field.dx);
        out[n..].copy_from_slice(&field.dy);
        Ok(report)
    });
    match res {
        Ok(Ok(v)) => ok_json(&v),
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// Where a grid thin plate starts.
#[derive(Clone, Copy)]
enum Start {
    /// From the caller's field (`iw_solve`'s `initial`) or the earlier solves, whichever is
    /// closer; from scratch, the earlier solves forgotten, when the pointer is null.
    Given(*const f32),
    /// From the earlier solves of this grid and step ([`iw_grid_solve_kept`]), never
    /// forgotten: the editor's full-resolution frames after one drag and the next.
    Kept,
}

/// The field and report of a request (see [`iw_solve`]).
fn solve_request(domain: &Domain, req: &SolveIn, start: Start) -> Result<(Field, serde_json::Value), String> {
    let grid = &domain.grid;
    let method = method_of(req)?;
    let spacing_px = req.spacing_px.unwrap_or(1.0);
    let mut per_feature = samples_of(&req.features, domain, spacing_px)?;
    let held = req.border == inkwarp_core::scene::Border::Hold;
    let sample_count: usize = per_feature.iter().map(Vec::len).sum();
    let (field, report) = match method.interpolant() {
        None => {
            if held {
                per_feature.push(inkwarp_core::geometry::border_samples(grid.width, grid.height, spacing_px));
            }
            solve_tps(domain, per_feature, &req.options, start)?
        }
        Some(interpolant) => {
            let mut controls = controls_of(&req.features, per_feature, interpolant)?;
            if held {
                inkwarp_core::methods::scene::hold_border(&mut controls, interpolant, grid.width, grid.height, spacing_px);
            }
            let step = req.options.grid_step;
            let preview = req.options.preview && step > 1;
            let params = req.options.method_params();
            let (field, report) = if interpolant == Interpolant::TpsExact && preview {
                tps_exact_preview(&controls, grid, step, &params)?
            } else {
                controls_field(interpolant, &controls, grid, &params).map_err(|e| e.to_string())?
            };
            let json = serde_json::json!({
                "samples_used": report.samples_used,
                "line_pairs_used": report.line_pairs_used,
                "dropped": report.dropped,
                "ignored_matte": report.ignored_matte,
                "notes": report.notes,
            });
            (field, json)
        }
    };
    Ok((field, named(report, method, sample_count)))
}

/// A report with the method that made it and the number of samples it was given.
fn named(mut report: serde_json::Value, method: Method, samples: usize) -> serde_json::Value {
    report["method"] = method.name().into();
    report["samples"] = samples.into();
    report
}

fn method_of(req: &SolveIn) -> Result<Method, String> {
    Method::from_name(&req.options.method).ok_or_else(|| {
        format!(
            "Unknown method {:?}; use \"tps\", \"tps-exact\", \"triangulation\" or \"beier-neely\".",
            req.options.method
        )
    })
}

/// Selects the pixels that [`iw_solve_at`] computes: `len` row-major pixel indices at
/// `pixels_ptr` (`y · width + x`), each below `width · height`. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_grid_select(handle: u32, pixels_ptr: *const u32, len: usize) -> i32 {
    let pixels = view(pixels_ptr, len).to_vec();
    let res = with_domain(handle, |domain| {
        let n = domain.grid.width * domain.grid.height;
        if let Some(&p) = pixels.iter().find(|&&p| p as usize >= n) {
            return Err(format!("Pixel {p} is outside the {}×{} grid.", domain.grid.width, domain.grid.height));
        }
        *domain.selection.borrow_mut() = Some(Selection { pixels, plans: HashMap::new() });
        Ok(())
    });
    match res {
        Ok(Ok(())) => 0,
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// [`iw_solve`] at the pixels of [`iw_grid_select`] only: their (Δx, Δy) pairs to `out`
/// (`2 · len` floats for `len` selected pixels), the report as for `iw_solve`. A grid thin
/// plate at a `grid_step` above 1 (the editor's drafts) is upsampled at those pixels alone,
/// warm-started from the earlier solves at that step; any other request is solved in full
/// and read at them. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_solve_at(handle: u32, req_ptr: *const u8, req_len: usize, out_ptr: *mut f32) -> i32 {
    let req: SolveIn = match json_arg(req_ptr, req_len) {
        Ok(r) => r,
        Err(e) => return fail(e),
    };
    let res = with_domain(handle, |domain| -> Result<serde_json::Value, String> {
        let mut selection = domain.selection.borrow_mut();
        let selection = selection.as_mut().ok_or("No pixels are selected on this grid; call iw_grid_select first.")?;
        let out = view_mut(out_ptr, 2 * selection.pixels.len());
        let step = req.options.grid_step;
        if method_of(&req)?.interpolant().is_some() || step <= 1 {
            let (field, report) = solve_request(domain, &req, Start::Given(std::ptr::null()))?;
            for (o, &p) in out.chunks_exact_mut(2).zip(&selection.pixels) {
                o.copy_from_slice(&[field.dx[p as usize], field.dy[p as usize]]);
            }
            return Ok(report);
        }
        let grid = &domain.grid;
        let spacing_px = req.spacing_px.unwrap_or(1.0);
        let mut per_feature = samples_of(&req.features, domain, spacing_px)?;
        // A held border is held in drafts too, as in the full solve (`solve_request`).
        if req.border == inkwarp_core::scene::Border::Hold {
            per_feature.push(inkwarp_core::geometry::border_samples(grid.width, grid.height, spacing_px));
        }
        let samples: Vec<Sample> = per_feature.into_iter().flatten().collect();
        let options = solve_options(&req.options)?;
        let plan = selection.plans.entry(step).or_insert_with(|| Upsampling::new(grid, step));
        let mut histories = domain.history.borrow_mut();
        let history = histories.entry(step).or_default();
        let solved = history.solve_warm_at(grid, &samples, &options, plan, &selection.pixels, out);
        release_large(history, grid, step);
        let report = solved.map_err(|e| e.to_string())?;
        Ok(named(tps_report(&report), Method::Tps, samples.len()))
    });
    match res {
        Ok(Ok(v)) => ok_json(&v),
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// At most this many samples are fitted by a `tps-exact` preview (the final field fits up to
/// the scene's `solver.tps_exact.max_samples`): the fit costs their cube.
const PREVIEW_MAX_SAMPLES: usize = 250;

/// A quick `tps-exact` field for the editor's drafts while a point is dragged (a request
/// with `preview` and a `grid_step` above 1): the spline fitted to at most [`PREVIEW_MAX_SAMPLES`]
/// samples (thinned as the method thins them), evaluated on every `step`-th pixel and
/// interpolated bilinearly between. The full fit on every pixel takes seconds at
/// 512 × 512 in the browser; the final field (no `preview`) is [`controls_field`]'s.
fn tps_exact_preview(
    controls: &Controls,
    grid: &Grid,
    step: usize,
    params: &MethodParams,
) -> Result<(Field, MethodReport), String> {
    let (width, height) = (grid.width, grid.height);
    let samples = controls.all_samples();
    let max_samples = params.max_samples.min(PREVIEW_MAX_SAMPLES);
    let (map, info) =
        ThinPlateMap::fit_samples(&samples, max_samples).map_err(|e| e.to_string())?;
    let (wc, hc) = ((width - 1).div_ceil(step) + 1, (height - 1).div_ceil(step) + 1);
    let mut coarse = Field::zeros(wc, hc);
    for yc in 0..hc {
        for xc in 0..wc {
            let p = [
                (xc * step).min(width - 1) as f64,
                (yc * step).min(height - 1) as f64,
            ];
            let d = map.displacement(p);
            coarse.dx[yc * wc + xc] = d[0] as f32;
            coarse.dy[yc * wc + xc] = d[1] as f32;
        }
    }
    let mut report = MethodReport {
        method: Some(Method::TpsExact),
        samples_given: info.given,
        samples_used: info.used,
        dropped: info.dropped,
        ..MethodReport::default()
    };
    note_ignored_matte(&mut report, grid);
    Ok((Field::from_coarse(&coarse, step, width, height), report))
}

/// The grid thin plate of `iw_solve`, with its report as JSON.
fn solve_tps(
    domain: &Domain,
    per_feature: Vec<Vec<Sample>>,
    options: &OptionsIn,
    start: Start,
) -> Result<(Field, serde_json::Value), String> {
    let grid = &domain.grid;
    let n = grid.width * grid.height;
    let samples: Vec<Sample> = per_feature.into_iter().flatten().collect();
    let options = solve_options(options)?;
    let initial_ptr = match start {
        Start::Given(ptr) => ptr,
        Start::Kept => std::ptr::null(),
    };
    let initial = (!initial_ptr.is_null()).then(|| {
        let data = view(initial_ptr, 2 * n);
        Field {
            width: grid.width,
            height: grid.height,
            dx: data[..n].to_vec(),
            dy: data[n..].to_vec(),
        }
    });
    // A warm request starts from the page's field (often a draft of this very pose) or
    // the earlier solves' extrapolation, whichever is closer; a cold request (no initial
    // field) starts the series over; a kept one continues it.
    let mut histories = domain.history.borrow_mut();
    let history = histories.entry(options.grid_step).or_default();
    if initial.is_none() && matches!(start, Start::Given(_)) {
        history.clear();
    }
    let solved = history.solve_warm(grid, &samples, &options, initial);
    release_large(history, grid, options.grid_step);
    let (field, report) = solved.map_err(|e| e.to_string())?;
    let json = tps_report(&report);
    Ok((field, json))
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
    let line = curve_polyline(
        req.kind,
        &req.points,
        req.closed,
        req.spline_outline,
        req.spacing_px.unwrap_or(2.0),
    );
    ok_json(&line)
}

fn with_canvas<R>(handle: u32, f: impl FnOnce(&mut Canvas) -> R) -> Result<R, String> {
    CANVASES.with(|c| match slot_mut(&mut c.borrow_mut(), handle) {
        Some(canvas) => Ok(f(canvas)),
        None => Err(format!("There is no canvas with handle {handle}.")),
    })
}

/// A CPU canvas (the reference renderer) of `width × height` filled with `background`
/// (straight RGBA8). Returns a handle ≥ 1.
#[no_mangle]
pub extern "C" fn iw_canvas_new(width: usize, height: usize, r: u8, g: u8, b: u8, a: u8) -> u32 {
    CANVASES.with(|c| {
        insert(
            &mut c.borrow_mut(),
            Canvas::new(width, height, [r, g, b, a]),
        )
    })
}

/// Frees a canvas.
#[no_mangle]
pub extern "C" fn iw_canvas_free(handle: u32) {
    CANVASES.with(|c| release(&mut c.borrow_mut(), handle));
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
        let image = RgbaImage {
            width: grid.width,
            height: grid.height,
            data: view(image_ptr, 4 * n).to_vec(),
        };
        let data = view(field_ptr, 2 * n);
        let field = Field {
            width: grid.width,
            height: grid.height,
            dx: data[..n].to_vec(),
            dy: data[n..].to_vec(),
        };
        with_canvas(canvas, |c| {
            c.draw_layer(&image, &field, grid, [offset_x, offset_y])
        })
    });
    match res {
        Ok(Ok(())) => 0,
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// Copies a canvas as straight RGBA8 into `out` (`4 * width * height` bytes), pixel by
/// pixel as [`Canvas::to_rgba8`] converts them (no second copy of the frame). Status 0/1.
#[no_mangle]
pub extern "C" fn iw_canvas_read(canvas: u32, out_ptr: *mut u8, out_len: usize) -> i32 {
    let res = with_canvas(canvas, |c| {
        if 4 * c.data.len() != out_len {
            return Err(format!(
                "The output buffer has {out_len} bytes; the canvas needs {}.",
                4 * c.data.len()
            ));
        }
        let out = view_mut(out_ptr, out_len);
        for (o, &p) in out.chunks_exact_mut(4).zip(&c.data) {
            o.copy_from_slice(&inkwarp_core::render::unpremultiply(p));
        }
        Ok(())
    });
    match res {
        Ok(Ok(())) => 0,
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// Keeps a layer's picture (straight RGBA8, `4 * width * height` bytes, copied once) in
/// the module for [`iw_canvas_draw_solved`], so a frame does not copy it in again.
/// Returns a handle (≥ 1), or 0 with the error in the result.
#[no_mangle]
pub extern "C" fn iw_image_new(ptr: *const u8, width: usize, height: usize) -> u32 {
    if width == 0 || height == 0 {
        fail(format!("A picture needs at least 1 pixel; this one is {width} × {height}."));
        return 0;
    }
    let data = view(ptr, 4 * width * height).to_vec();
    IMAGES.with(|m| insert(&mut m.borrow_mut(), RgbaImage { width, height, data }))
}

/// Frees a picture kept by [`iw_image_new`].
#[no_mangle]
pub extern "C" fn iw_image_free(handle: u32) {
    IMAGES.with(|m| release(&mut m.borrow_mut(), handle));
}

/// Copies a kept picture's pixels into `out` (`4 * width * height` bytes). Status 0/1.
#[no_mangle]
pub extern "C" fn iw_image_read(handle: u32, out_ptr: *mut u8, out_len: usize) -> i32 {
    IMAGES.with(|m| match slot(&m.borrow(), handle) {
        Some(img) if img.data.len() == out_len => {
            view_mut(out_ptr, out_len).copy_from_slice(&img.data);
            0
        }
        Some(img) => fail(format!("The output buffer has {out_len} bytes; the picture needs {}.", img.data.len())),
        None => fail(format!("There is no picture with handle {handle}.")),
    })
}

/// The most nodes a grid thin plate of [`iw_grid_solve_kept`] may solve on (its grid's
/// pixels over `grid_step` squared) for the grid to keep its solver between calls.
const KEPT_SOLVER_MAX_NODES: u64 = 1 << 20;

/// The most nodes of a grid whose solver keeps its levels between [`iw_solve`] and
/// [`iw_solve_at`] requests.
const LEVELS_MAX_NODES: u64 = 1 << 22;

/// Drops `solver`'s levels (about 150 bytes a node; its history stays) when its grid, `grid`
/// at `step`, has more than [`LEVELS_MAX_NODES`] nodes: the module's memory is short.
fn release_large(solver: &mut Solver, grid: &Grid, step: usize) {
    if inkwarp_core::limits::solver_nodes(grid.width, grid.height, step) > LEVELS_MAX_NODES {
        solver.release_levels();
    }
}

/// Whether [`iw_grid_solve_kept`] keeps the solver of a `width × height` grid at `step`.
fn keeps_solver(width: usize, height: usize, step: usize) -> bool {
    inkwarp_core::limits::solver_nodes(width, height, step) <= KEPT_SOLVER_MAX_NODES
}

/// Solves a layer (the request as [`iw_solve`] takes it) and keeps the field in the
/// module for the next [`iw_canvas_draw_solved`] or [`iw_frame_draw`] on this grid,
/// instead of copying it out: a full-resolution field is 8 bytes a pixel.
///
/// A grid thin plate whose own grid has at most [`KEPT_SOLVER_MAX_NODES`] nodes (a
/// 4000 × 3000 picture at `grid_step` 4 has 750 000) keeps its solver on the grid: the
/// multigrid hierarchy (built for the drawing's rest pose, so one drag's frame and the
/// next share it) and the last few fields at its own nodes, from which the next call
/// starts ([`Solver::solve_warm`]). A larger one (`grid_step` 1 on a photograph) is solved
/// from scratch and keeps nothing: its fields are 8 bytes a pixel. The result is the
/// solve's report. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_grid_solve_kept(grid: u32, req_ptr: *const u8, req_len: usize) -> i32 {
    let req: SolveIn = match json_arg(req_ptr, req_len) {
        Ok(r) => r,
        Err(e) => return fail(e),
    };
    // The earlier kept field goes first, so two never live at once.
    SOLVED.with(|s| s.borrow_mut().remove(&grid));
    let res = with_domain(grid, |domain| {
        let step = req.options.grid_step.max(1);
        let keep = keeps_solver(domain.grid.width, domain.grid.height, step);
        // Only this step's solver stays: a changed grid step drops the other's.
        domain.history.borrow_mut().retain(|&s, _| keep && s == step);
        let solved = solve_request(domain, &req, if keep { Start::Kept } else { Start::Given(std::ptr::null()) });
        if !keep || solved.is_err() {
            domain.history.borrow_mut().clear();
        }
        solved
    });
    match res {
        Ok(Ok((field, report))) => {
            SOLVED.with(|s| s.borrow_mut().insert(grid, field));
            ok_json(&report)
        }
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

/// Forward-maps a kept picture ([`iw_image_new`]) onto the canvas by the field kept for
/// this grid by [`iw_grid_solve_kept`] (taken: it is freed after), or at rest (the zero
/// field) when none is kept: what `iw_solve` then [`iw_canvas_draw`] draw, with neither
/// the picture nor the field copied. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_canvas_draw_solved(canvas: u32, grid: u32, image: u32, offset_x: f64, offset_y: f64) -> i32 {
    let kept = SOLVED.with(|s| s.borrow_mut().remove(&grid));
    let res = with_grid(grid, |g| -> Result<(), String> {
        let field = match kept {
            Some(f) if f.width == g.width && f.height == g.height => f,
            Some(_) => return Err("The kept field is not of this grid's size.".into()),
            None => {
                let n = g.width * g.height;
                Field { width: g.width, height: g.height, dx: vec![0.0; n], dy: vec![0.0; n] }
            }
        };
        IMAGES.with(|m| match slot(&m.borrow(), image) {
            Some(img) if img.width == g.width && img.height == g.height => with_canvas(canvas, |c| {
                c.try_draw_layer(img, &field, g, [offset_x, offset_y]).map_err(|e| e.to_string())
            })?,
            Some(img) => Err(format!(
                "The picture is {} × {}; its grid is {} × {}.",
                img.width, img.height, g.width, g.height
            )),
            None => Err(format!("There is no picture with handle {image}.")),
        })
    });
    match res {
        Ok(Ok(())) => 0,
        Ok(Err(e)) | Err(e) => fail(e),
    }
}

#[derive(Debug, Deserialize)]
struct FrameIn {
    width: usize,
    height: usize,
    background: [u8; 4],
    /// The rows to draw, `[first, end)`; all of them when absent.
    #[serde(default)]
    rows: Option<[usize; 2]>,
    layers: Vec<FrameLayerIn>,
}

#[derive(Debug, Deserialize)]
struct FrameLayerIn {
    grid: u32,
    image: u32,
    offset: [f64; 2],
}

/// Draws a frame of kept pictures ([`iw_image_new`]) back to front over `background`,
/// each by the field kept for its grid by [`iw_grid_solve_kept`] (taken: it becomes the
/// layer's positions and is freed after), or at rest when none is kept, straight into
/// `out` as straight RGBA8 (`4 × width × rows` bytes): what [`iw_canvas_new`],
/// [`iw_canvas_draw_solved`] for each layer and [`iw_canvas_read`] give, byte for byte,
/// without a canvas of the whole frame (16 bytes a pixel): the renderer composites band
/// by band ([`inkwarp_core::render::draw_frame`]). `req_json`: `{"width", "height",
/// "background": [r, g, b, a], "rows": [first, end] (optional), "layers": [{"grid",
/// "image", "offset": [x, y]}]}`. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_frame_draw(req_ptr: *const u8, req_len: usize, out_ptr: *mut u8, out_len: usize) -> i32 {
    let req: FrameIn = match json_arg(req_ptr, req_len) {
        Ok(r) => r,
        Err(e) => return fail(e),
    };
    let res = GRIDS.with(|grids| {
        let grids = grids.borrow();
        IMAGES.with(|images| -> Result<(), String> {
            let images = images.borrow();
            let mut layers = Vec::with_capacity(req.layers.len());
            for (n, l) in req.layers.iter().enumerate() {
                let (g, img) = frame_layer(&grids, &images, "frame", n, l.grid, l.image)?;
                if (img.width, img.height) != (g.width, g.height) {
                    return Err(format!(
                        "Layer {n} of the frame: the picture is {} × {}; its grid is {} × {}.",
                        img.width, img.height, g.width, g.height
                    ));
                }
                let field = match SOLVED.with(|s| s.borrow_mut().remove(&l.grid)) {
                    Some(f) if (f.width, f.height) == (g.width, g.height) => f,
                    Some(_) => return Err(format!("Layer {n} of the frame: the kept field is not of its grid's size.")),
                    None => Field::zeros(g.width, g.height),
                };
                layers.push(PreparedLayer::new(img, field, g, l.offset).map_err(|e| e.to_string())?);
            }
            let rows = req.rows.map_or(0..req.height, |[a, b]| a..b);
            draw_frame(req.width, req.height, req.background, &layers, rows, view_mut(out_ptr, out_len))
                .map_err(|e| e.to_string())
        })
    });
    match res {
        Ok(()) => 0,
        Err(e) => fail(e),
    }
}

/// Layer `n` of a frame or a view (`what`): its grid and its picture, by their handles.
fn frame_layer<'a>(
    grids: &'a [Option<Domain>],
    images: &'a [Option<RgbaImage>],
    what: &str,
    n: usize,
    grid: u32,
    image: u32,
) -> Result<(&'a Grid, &'a RgbaImage), String> {
    let g = &slot(grids, grid).ok_or_else(|| format!("Layer {n} of the {what}: there is no grid with handle {grid}."))?.grid;
    let img = slot(images, image).ok_or_else(|| format!("Layer {n} of the {what}: there is no picture with handle {image}."))?;
    Ok((g, img))
}

#[derive(Debug, Deserialize)]
struct ViewIn {
    width: usize,
    height: usize,
    background: [u8; 4],
    /// The frame is drawn this many times smaller (1: at the picture's resolution).
    shrink: usize,
    /// `[x0, y0, x1, y1]` in the smaller frame's pixels (end exclusive); all of it when absent.
    #[serde(default)]
    region: Option<[usize; 4]>,
    layers: Vec<ViewLayerIn>,
}

#[derive(Debug, Deserialize)]
struct ViewLayerIn {
    grid: u32,
    image: u32,
    offset: [f64; 2],
    /// Drawn at rest (the zero field), whatever field its grid keeps.
    #[serde(default)]
    rest: bool,
}

/// Draws a region of a frame of kept pictures ([`iw_image_new`]) `shrink` times smaller
/// ([`draw_view`]), straight into `out` (straight RGBA8, `4 × (x1 − x0) × (y1 − y0)`
/// bytes): each layer by the field kept for its grid by [`iw_grid_solve_kept`], which it
/// reads and leaves in place (unlike [`iw_frame_draw`]), so the view can be drawn again as
/// the editor's view is zoomed and panned without a new solve; at rest (`"rest": true`, or
/// no field kept) by the zero field. At `shrink` 1 the bytes are those of
/// [`iw_frame_draw`]'s frame in the region. `req_json`: `{"width", "height", "background",
/// "shrink", "region": [x0, y0, x1, y1] (optional), "layers": [{"grid", "image", "offset",
/// "rest"}]}`. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_view_draw(req_ptr: *const u8, req_len: usize, out_ptr: *mut u8, out_len: usize) -> i32 {
    let req: ViewIn = match json_arg(req_ptr, req_len) {
        Ok(r) => r,
        Err(e) => return fail(e),
    };
    let res = GRIDS.with(|grids| {
        let grids = grids.borrow();
        IMAGES.with(|images| {
            SOLVED.with(|solved| -> Result<(), String> {
                let images = images.borrow();
                let solved = solved.borrow();
                // Each layer's grid, picture and, drawn at rest, its zero field.
                let mut found = Vec::with_capacity(req.layers.len());
                for (n, l) in req.layers.iter().enumerate() {
                    let (g, img) = frame_layer(&grids, &images, "view", n, l.grid, l.image)?;
                    let rest = (l.rest || !solved.contains_key(&l.grid)).then(|| Field::zeros(g.width, g.height));
                    found.push((g, img, rest));
                }
                let layers: Vec<ViewLayer> = found
                    .iter()
                    .zip(&req.layers)
                    .map(|((g, img, rest), l)| ViewLayer { image: img, field: rest.as_ref().unwrap_or_else(|| &solved[&l.grid]), grid: g, offset: l.offset })
                    .collect();
                let (vw, vh) = view_size(req.width, req.height, req.shrink);
                let region = req.region.unwrap_or([0, 0, vw, vh]);
                draw_view(req.width, req.height, req.background, &layers, req.shrink, region, view_mut(out_ptr, out_len))
                    .map_err(|e| format!("The view: {e}"))
            })
        })
    });
    match res {
        Ok(()) => 0,
        Err(e) => fail(e),
    }
}

#[derive(Debug, Deserialize)]
struct KeyIn {
    t: f64,
    points: Vec<Point>,
    #[serde(default)]
    interpolation: Option<String>,
}

#[derive(Debug, Deserialize)]
struct PoseIn {
    rest: Vec<Point>,
    #[serde(default)]
    keys: Vec<KeyIn>,
    t: f64,
}

/// A feature's control points at time `t`, by the engine's keyframe interpolation.
/// `req_json`: `{"rest": [[x, y], ...], "keys": [{"t", "points", "interpolation"}], "t"}`;
/// the result is `[[x, y], ...]`. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_points_at(req_ptr: *const u8, req_len: usize) -> i32 {
    let req: PoseIn = match json_arg(req_ptr, req_len) {
        Ok(r) => r,
        Err(e) => return fail(e),
    };
    let mut keys = Vec::with_capacity(req.keys.len());
    for k in req.keys {
        let interpolation = match k.interpolation.as_deref() {
            None | Some("smooth") => Interpolation::Smooth,
            Some("linear") => Interpolation::Linear,
            Some("hold") => Interpolation::Hold,
            Some("ease-in") => Interpolation::EaseIn,
            Some("ease-out") => Interpolation::EaseOut,
            Some("ease-in-out") => Interpolation::EaseInOut,
            Some(other) => {
                return fail(format!(
                    "Unknown interpolation {other:?}; use smooth, linear, hold, ease-in, ease-out or ease-in-out."
                ))
            }
        };
        keys.push(Key {
            time_s: k.t,
            points: k.points,
            interpolation,
        });
    }
    ok_json(&points_at(&req.rest, &keys, req.t))
}

/// Decodes an image (a `data:` URI, or the raw bytes of a PNG or JPEG when the input does
/// not start with `data:`) with the engine's decoder, exactly as the command line reads
/// it. The result is `{"width", "height"}`; the straight RGBA8 pixels are copied out with
/// [`iw_decoded_take`]. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_decode(ptr: *const u8, len: usize) -> i32 {
    let input = view(ptr, len);
    let raw = if input.starts_with(b"data:") {
        match std::str::from_utf8(input)
            .map_err(|e| e.to_string())
            .and_then(images::data_uri_bytes)
        {
            Ok(b) => b,
            Err(e) => return fail(format!("Cannot read the data: URI: {e}.")),
        }
    } else {
        input.to_vec()
    };
    match images::decode_image(&raw) {
        Ok(img) => {
            let (width, height) = (img.width, img.height);
            DECODED.with(|d| {
                *d.borrow_mut() = Some(RgbaImage {
                    width,
                    height,
                    data: img.data,
                })
            });
            ok_json(&serde_json::json!({ "width": width, "height": height }))
        }
        Err(e) => fail(e),
    }
}

/// Copies the last decoded image's pixels into `out` (`4 * width * height` bytes) and
/// forgets it. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_decoded_take(out_ptr: *mut u8, out_len: usize) -> i32 {
    match DECODED.with(|d| d.borrow_mut().take()) {
        Some(img) if img.data.len() == out_len => {
            view_mut(out_ptr, out_len).copy_from_slice(&img.data);
            0
        }
        Some(img) => fail(format!(
            "The output buffer has {out_len} bytes; the image needs {}.",
            img.data.len()
        )),
        None => fail("No image was decoded."),
    }
}

/// The engine's matte values of a straight RGBA8 image (grey level times alpha; 0 is a
/// hole), one byte per pixel into `out`. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_matte_values(
    rgba_ptr: *const u8,
    width: usize,
    height: usize,
    out_ptr: *mut u8,
) -> i32 {
    let n = width * height;
    let image = RgbaImage {
        width,
        height,
        data: view(rgba_ptr, 4 * n).to_vec(),
    };
    let values = images::matte_values(&image);
    view_mut(out_ptr, n).copy_from_slice(&values);
    0
}

/// Every problem of a scene document (validation with JSON paths, images decoded and
/// checked), as `[{"path", "message"}]`; empty when the scene is fine. Images must be
/// `data:` URIs (the editor inlines them). Status 0.
#[no_mangle]
pub extern "C" fn iw_scene_check(json_ptr: *const u8, json_len: usize) -> i32 {
    let text = match std::str::from_utf8(view(json_ptr, json_len)) {
        Ok(t) => t,
        Err(_) => {
            return ok_json(&[
                serde_json::json!({ "path": "", "message": "the scene is not UTF-8 text" }),
            ])
        }
    };
    let problems: Vec<serde_json::Value> =
        match inkwarp_core::scene::Scene::from_json(text, &mut inkwarp_core::scene::no_files) {
            Ok(_) => Vec::new(),
            Err(err) => err
                .problems
                .iter()
                .map(|p| serde_json::json!({ "path": p.path, "message": p.message }))
                .collect(),
        };
    ok_json(&problems)
}

/// The scene format's ranges (`inkwarp_core::limits`), which the editor's fields hold what
/// they take to, so that a value a field takes is one a scene may hold: `{"max_coord_px",
/// "max_time_s", "min_fps", "max_fps", "max_frames"}`. Status 0.
#[no_mangle]
pub extern "C" fn iw_limits() -> i32 {
    use inkwarp_core::limits::{MAX_COORD_PX, MAX_FPS, MAX_FRAMES, MAX_TIME_S, MIN_FPS};
    ok_json(&serde_json::json!({
        "max_coord_px": MAX_COORD_PX,
        "max_time_s": MAX_TIME_S,
        "min_fps": MIN_FPS,
        "max_fps": MAX_FPS,
        "max_frames": MAX_FRAMES,
    }))
}

/// The field methods of DESIGN §6 and whether this build computes them, as
/// `[{"name", "available"}]` in the scene format's names and in the order comparisons show
/// them. Status 0.
#[no_mangle]
pub extern "C" fn iw_methods() -> i32 {
    use inkwarp_core::scene::method_available;
    let list: Vec<serde_json::Value> = Method::ALL
        .iter()
        .map(|&m| serde_json::json!({ "name": m.name(), "available": method_available(m) }))
        .collect();
    ok_json(&list)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn put(data: &[u8]) -> (*mut u8, usize) {
        let ptr = crate::iw_alloc(data.len());
        view_mut(ptr, data.len()).copy_from_slice(data);
        (ptr, data.len())
    }

    fn result() -> serde_json::Value {
        serde_json::from_slice(view(crate::iw_result_ptr(), crate::iw_result_len())).unwrap()
    }

    #[test]
    fn the_limits_are_the_cores() {
        use inkwarp_core::limits::*;
        assert_eq!(iw_limits(), 0);
        let want = serde_json::json!({"max_coord_px": MAX_COORD_PX, "max_time_s": MAX_TIME_S,
            "min_fps": MIN_FPS, "max_fps": MAX_FPS, "max_frames": MAX_FRAMES});
        assert_eq!(result(), want);
    }

    /// A pulled point, a held one and a held border at grid step 4; `pull` moves the first.
    fn request(pull: [f64; 2]) -> serde_json::Value {
        serde_json::json!({"features": [
            {"kind": "point", "rest": [[30, 20]], "pose": [[30.0 + pull[0], 20.0 + pull[1]]]},
            {"kind": "spline", "rest": [[60, 50], [80, 40], [100, 55]], "pose": [[60, 50], [80, 40], [100, 55]]}],
            "options": {"grid_step": 4}, "spacing_px": 4, "border": "hold"})
    }

    /// `iw_grid_solve_kept` of `req` on `grid`: the report, and the field it kept (taken).
    fn solve_kept(grid: u32, req: &serde_json::Value) -> (serde_json::Value, Field) {
        let (r, r_len) = put(req.to_string().as_bytes());
        assert_eq!(iw_grid_solve_kept(grid, r, r_len), 0, "{}", result());
        let report = result();
        (report, SOLVED.with(|s| s.borrow_mut().remove(&grid)).expect("a kept field"))
    }

    fn max_difference(a: &Field, b: &Field) -> f32 {
        a.dx.iter().zip(&b.dx).chain(a.dy.iter().zip(&b.dy)).map(|(p, q)| (p - q).abs()).fold(0.0, f32::max)
    }

    #[test]
    fn a_kept_solve_after_a_drag_starts_from_the_last_and_gives_the_cold_field() {
        let (w, h) = (121, 90);
        let kept = iw_grid_new(w, h, std::ptr::null(), 0, std::ptr::null(), 0);
        // The frame at rest builds the solver the drags' frames then reuse.
        let (rest, field) = solve_kept(kept, &request([0.0, 0.0]));
        assert!(field.dx.iter().chain(&field.dy).all(|&v| v.abs() < 1e-6), "{rest}");
        let mut cold_cycles = Vec::new();
        for (k, pull) in [[6.0, -4.0], [7.0, -5.0], [8.0, -6.0]].into_iter().enumerate() {
            let req = request(pull);
            let (report, warm) = solve_kept(kept, &req);
            // The same pose solved from scratch on a fresh grid.
            let fresh = iw_grid_new(w, h, std::ptr::null(), 0, std::ptr::null(), 0);
            let (cold_report, cold) = solve_kept(fresh, &req);
            iw_grid_free(fresh);
            assert_eq!(report["converged"], true, "{report}");
            let diff = max_difference(&warm, &cold);
            // Within the solver's tolerance (the request's default, 0.01 px).
            assert!(diff < 0.01, "frame {k}: the kept solve is {diff} px from the cold one");
            cold_cycles.push(cold_report["cycles"].as_u64().unwrap());
            if k > 0 {
                // From the drags before: fewer cycles than from scratch.
                assert!(report["cycles"].as_u64().unwrap() < cold_cycles[k], "frame {k}: {report} against {cold_report}");
            }
        }
        // The same pose again starts at its answer: one cycle checks it.
        let (again, _) = solve_kept(kept, &request([8.0, -6.0]));
        assert!(again["cycles"].as_u64().unwrap() <= 1, "{again}");
        iw_grid_free(kept);
    }

    #[test]
    fn a_photograph_keeps_its_solver_at_grid_step_4_but_not_at_every_pixel() {
        assert!(keeps_solver(4000, 3000, 4));
        assert!(keeps_solver(6000, 4000, 6));
        assert!(!keeps_solver(4000, 3000, 1));
        assert!(!keeps_solver(4000, 3000, 2));
        // The solver's grid counts the last row and column: 1024 × 1024 nodes, then 1025².
        assert!(keeps_solver(2047, 2047, 2));
        assert!(!keeps_solver(2048, 2048, 2));
    }
}

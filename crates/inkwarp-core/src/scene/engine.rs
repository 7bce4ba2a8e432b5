//! The scene engine: the drawing at time t, its samples per layer, the layer's field (warm
//! started from the layer's earlier frames), and the frame composited back to front.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use super::doc::{Border, Method, Scheme, SolverDoc, SolverOverrides};
use crate::anim::points_at;
use crate::geometry::{FeatureSampler, SampleOptions};
use crate::render::{Canvas, RgbaImage};
use crate::solve::{SolveMethod, SolveOptions, SolveReport, Solver, Stop, DEFAULT_MAX_CYCLES};
use super::{to_layer, Scene, SceneError};
use crate::field::Field;
use crate::geometry::{Kind, Point, Sample};
use crate::grid::Grid;
use crate::methods::MethodReport;

/// Whether `method` can compute fields in this build: every method can (`tps` here, the
/// other interpolants of DESIGN §6 from the `methods` module through [`compute_field`]).
pub fn method_available(method: Method) -> bool { Method::ALL.contains(&method) }

/// Where a layer's thin-plate solve starts (the other methods start from nothing).
pub(super) enum Start<'a> {
    /// From this field (a warm start), or from zero.
    Field(Option<&'a Field>),
    /// From the layer's earlier frames in its solver, which then keeps this one.
    History(&'a mut Solver),
}

/// The one place where a layer's field is computed by its method: the grid thin plate
/// here, the other interpolants (DESIGN §6) through the `methods` module. They get the
/// samples grouped by feature, because Beier–Neely needs each curve's samples in order
/// (its line pairs) apart from the points.
pub(super) fn compute_field(
    scene: &Scene,
    time_s: f64,
    solver: &SolverDoc,
    grid: &Grid,
    features: &[FeatureSamples],
    start: Start<'_>,
    border: Border,
    offset: [f64; 2],
) -> Result<LayerSolve, String> {
    let held = border == Border::Hold;
    let spacing_px = solver.grid_step as f64;
    if crate::interrupt::requested() { return Err(crate::interrupt::STOPPED.to_string()); }
    let solved = match solver.method.interpolant() {
        None => {
            let mut samples: Vec<Sample> = features.iter().flat_map(|f| f.samples.iter().copied()).collect();
            if held {
                samples.extend(crate::geometry::border_samples(grid.width, grid.height, spacing_px));
            }
            match start {
                Start::History(s) => s.solve_frame(grid, &samples, &solve_options(solver)),
                Start::Field(initial) => Solver::new().solve(grid, &samples, &solve_options(solver), initial.map(Into::into)),
            }
            .map(|(field, report)| LayerSolve { field, report: Some(report), method_report: None })
            .map_err(|e| e.to_string())
        }
        Some(interpolant) => {
            use crate::methods::scene::{feature_controls, hold_border, method_params};
            let mut controls = feature_controls(scene, features, time_s, interpolant, offset)?;
            if held {
                hold_border(&mut controls, interpolant, grid.width, grid.height, spacing_px);
            }
            crate::methods::controls_field(interpolant, &controls, grid, &method_params(solver))
                .map_err(|e| e.to_string())
                .map(|(field, report)| LayerSolve { field, report: None, method_report: Some(report) })
        }
    };
    // A stop requested mid-solve may leave a partial field: never return it.
    if crate::interrupt::requested() { return Err(crate::interrupt::STOPPED.to_string()); }
    // A frame is never drawn from a field with NaN or infinity in it (it would come out
    // blank with no error): the limits refuse the inputs known to cause one, and this
    // catches any other.
    if solved.as_ref().is_ok_and(|layer| !layer.field.dx.iter().chain(&layer.field.dy).all(|v| v.is_finite())) {
        return Err(format!("the {} field at t = {time_s} s is not finite (NaN or infinity); check the keys and the solver settings near this time", solver.method.name()));
    }
    solved
}

/// One driving feature's samples at one time.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureSamples {
    /// Index of the feature in the scene.
    pub feature: usize,
    /// Its samples: a curve's in order along the curve (a region's outline first, then
    /// its interior nodes).
    pub samples: Vec<Sample>,
}

/// The engine's solve options for a layer's settings.
#[allow(clippy::needless_update)] // SolveOptions has more fields than the scene sets
pub(crate) fn solve_options(solver: &SolverDoc) -> SolveOptions {
    SolveOptions {
        tension: solver.tension,
        tolerance_px: solver.tolerance,
        grid_step: solver.grid_step as usize,
        max_cycles: solver.max_cycles.map(|c| c as usize),
        method: match solver.scheme { Scheme::Multigrid => SolveMethod::Multigrid, Scheme::Southwell => SolveMethod::Southwell },
        ..SolveOptions::default()
    }
}

/// A layer's field at one time, with the report of what computed it: the grid solver's
/// (`tps`) or the interpolant's (every other method).
#[derive(Clone, Debug)]
pub struct LayerSolve {
    pub field: Field,
    /// The grid thin plate's report (`tps` only).
    pub report: Option<SolveReport>,
    /// The interpolant's report (`tps-exact`, `triangulation`, `beier-neely`), with its
    /// notes (an ignored matte, a thinning).
    pub method_report: Option<MethodReport>,
}

impl LayerSolve {
    /// The remarks worth showing a user about this field (empty for `tps`).
    pub fn notes(&self) -> &[String] { self.method_report.as_ref().map_or(&[], |r| r.notes.as_slice()) }
}

/// A frame and, per layer, the solve that drew it (`None` for layers that are not drawn).
#[derive(Clone, Debug)]
pub struct RenderedFrame {
    pub image: RgbaImage,
    pub layers: Vec<Option<LayerSolve>>,
}

impl RenderedFrame {
    /// Every layer's notes, in layer order; each is prefixed with its layer's name when
    /// `scene` has more than one layer.
    pub fn notes(&self, scene: &Scene) -> Vec<String> {
        let notes = self.layers.iter().enumerate().filter_map(|(j, s)| s.as_ref().map(|s| scene.layer_notes(j, s)));
        notes.flatten().collect()
    }
}

/// Consecutive frames are solved in chains of this many, each chain starting cold at a
/// frame index that is a multiple of it and warm-starting every later frame from the one
/// before. Because the chains do not depend on how many threads render them, a frame's
/// pixels do not depend on the number of cores.
pub const WARM_CHAIN_FRAMES: usize = 16;

impl Scene {
    /// The control points of feature `feature` at time `time_s`.
    pub fn pose_at(&self, feature: usize, time_s: f64) -> Vec<Point> {
        let f = &self.doc().features[feature];
        points_at(&f.rest, &f.keys, time_s)
    }

    /// The constraints that drive layer `layer` at time `time_s`, feature by feature: every
    /// driving feature sampled at the layer's grid spacing, region interiors on its grid;
    /// read in the layer's own pixels (a layer at `offset` at `p − offset`).
    pub fn layer_feature_samples(&self, layer: usize, time_s: f64) -> Result<Vec<FeatureSamples>, SceneError> {
        let layer_ref = &self.layers()[layer];
        let spacing_px = layer_ref.solver.grid_step as f64;
        let drivers = layer_ref.drivers.iter().zip(&layer_ref.samplers);
        drivers.map(|(&i, sampler)| {
            let f = &self.doc().features[i];
            let fail = |e: String| SceneError::one(format!("features[{i}]"), format!("at t = {time_s} s: {e}"));
            // The rest geometry is prepared once per layer (for a region: its interior
            // nodes and their mean value coordinates); each frame only poses it.
            let sampler = sampler
                .get_or_init(|| {
                    let options = SampleOptions { closed: f.closed, spline_outline: f.spline_outline(), spacing_px };
                    let domain = (f.kind == Kind::Region).then_some(&layer_ref.grid);
                    FeatureSampler::new(f.kind, &to_layer(&f.rest, layer_ref.offset), &options, domain).map_err(|e| e.to_string())
                })
                .as_ref()
                .map_err(|e| fail(e.clone()))?;
            let pose = to_layer(&self.pose_at(i, time_s), layer_ref.offset);
            let samples = sampler.sample(&pose).map_err(|e| fail(e.to_string()))?;
            Ok(FeatureSamples { feature: i, samples })
        })
        .collect()
    }

    /// All the constraints that drive layer `layer` at time `time_s` (see
    /// [`Scene::layer_feature_samples`]).
    #[cfg(test)]
    pub fn layer_samples(&self, layer: usize, time_s: f64) -> Result<Vec<Sample>, SceneError> {
        Ok(self.layer_feature_samples(layer, time_s)?.into_iter().flat_map(|f| f.samples).collect())
    }

    /// The field of layer `layer` at time `time_s`, starting from `initial` (warm start)
    /// or from zero.
    pub fn layer_field(&self, layer: usize, time_s: f64, initial: Option<&Field>) -> Result<LayerSolve, SceneError> {
        self.layer_field_overridden(layer, time_s, initial, &SolverOverrides::default())
    }

    /// [`Scene::layer_field`] with `overrides` applied over the layer's own settings (a
    /// method, Beier–Neely's weights, ...: what `inkwarp compare` varies).
    pub fn layer_field_overridden(
        &self,
        layer: usize,
        time_s: f64,
        initial: Option<&Field>,
        overrides: &SolverOverrides,
    ) -> Result<LayerSolve, SceneError> {
        let initial = initial.filter(|f| f.width == self.width() && f.height == self.height());
        self.solve_layer(layer, time_s, Start::Field(initial), overrides)
    }

    /// Layer `layer`'s field at `time_s` with `overrides` over its settings, started from
    /// `start` (the thin plate; the other methods start from nothing).
    fn solve_layer(&self, layer: usize, time_s: f64, start: Start<'_>, overrides: &SolverOverrides) -> Result<LayerSolve, SceneError> {
        let layer_ref = &self.layers()[layer];
        let solver = overrides.apply(&layer_ref.solver);
        let features = self.layer_feature_samples(layer, time_s)?;
        compute_field(self, time_s, &solver, &layer_ref.grid, &features, start, layer_ref.border, layer_ref.offset)
            .map_err(|e| SceneError::one(format!("layers[{layer}]"), format!("at t = {time_s} s: {e}")))
    }

    /// The notes of `solved`, a field of layer `layer`, each prefixed with the layer's name
    /// when the scene has more than one layer.
    pub fn layer_notes(&self, layer: usize, solved: &LayerSolve) -> Vec<String> {
        let named = self.layers().len() > 1;
        let name = &self.layers()[layer].name;
        let note = |note: &String| if named { format!("layer \"{name}\": {note}") } else { note.clone() };
        solved.notes().iter().map(note).collect()
    }

    /// The frame at `time_s`, every drawn layer's field solved cold with `overrides`
    /// applied, together with those solves (their fields and reports).
    pub fn render_overridden(&self, time_s: f64, overrides: &SolverOverrides) -> Result<RenderedFrame, SceneError> {
        let layers = (0..self.layers().len())
            .map(|j| self.layer_is_drawn(j).then(|| self.layer_field_overridden(j, time_s, None, overrides)))
            .map(Option::transpose)
            .collect::<Result<Vec<_>, _>>()?;
        let fields: Vec<Option<Field>> = layers.iter().map(|l| l.as_ref().map(|s| s.field.clone())).collect();
        Ok(RenderedFrame { image: self.composite(&fields)?, layers })
    }

    /// The warning a user should see about `solved`, layer `layer`'s field at `time_s`:
    /// `Some` when its thin-plate solve stopped before it converged (the field may then be
    /// off by more than the accuracy contract), naming the layer and the time (and frame).
    pub fn convergence_warning(&self, layer: usize, time_s: f64, solved: &LayerSolve) -> Option<String> {
        let report = solved.report.as_ref().filter(|r| !r.converged)?;
        let name = &self.layers()[layer].name;
        let (frame, t) = (time_s * self.fps(), (time_s * 1e4).round() / 1e4 + 0.0);
        let when = if (frame - frame.round()).abs() < 1e-6 && frame >= 0.0 { format!("at t = {t} s (frame {})", frame.round() as u64) } else { format!("at t = {t} s") };
        let solver = &self.layers()[layer].solver;
        // Why it stopped, as the solve recorded it.
        let advice = match report.stop {
            Stop::Budget => "the southwell scheme stops after a fixed budget of relaxations; use the multigrid scheme to solve to the tolerance, or another method".to_string(),
            Stop::MaxCycles => {
                // The setting in effect: the layer's own, else the scene's (or the default).
                let cap = solver.max_cycles.map_or(DEFAULT_MAX_CYCLES, |n| n as usize);
                let setting = match self.doc().layers[layer].solver.as_ref().and_then(|o| o.max_cycles) {
                    Some(n) => format!("layers[{layer}].solver.max_cycles (the layer's own, {n})"),
                    None => format!("solver.max_cycles ({}{cap})", if solver.max_cycles.is_some() { "" } else { "the default, " }),
                };
                let step = if solver.grid_step == 1 && cap >= DEFAULT_MAX_CYCLES { ", solve every other pixel (solver.grid_step 2: mattes with hair need the most cycles)" } else { "" };
                format!("raise {setting}{step}, or use another method")
            }
            Stop::Unsettled if solver.grid_step > 1 => format!("at grid_step {} parts of the matte thinner than the step (hair, strands) are too many to settle, so they may be torn apart; use grid_step 1 for this layer (with a higher solver.max_cycles if it stops there), or hold those parts with points of their own", solver.grid_step),
            Stop::Unsettled => "parts of the surface joined to the rest at single points or by 1 px strands are too many to settle, or did not settle; hold those parts with points of their own, or use another method".to_string(),
            // (From the default tolerance up, only displacements of 10⁵ px and more reach the f32 field's precision.)
            Stop::Precision => if solver.tolerance >= 0.01 { "its displacements are too large for the field's precision (keys far off the picture?); scale such keys to the picture" } else { "the tolerance is finer than the field's precision at these displacements; use a coarser solver.tolerance (or scale keys far off the picture to it)" }.to_string(),
            Stop::Residual => "its residual stayed above the tolerance; lower solver.tolerance, or use another method".to_string(),
            Stop::Interrupted => "it was interrupted".to_string(),
            Stop::Breakdown | Stop::Converged => "its iteration broke down; give the layer a tension, or use another method".to_string(),
        };
        let bound = match 5.0 * solver.tolerance { c if c >= 1e-3 => format!("{}", (c * 1e4).round() / 1e4), c => format!("{c:.1e}") };
        Some(format!("layer \"{name}\" {when}: the thin-plate solve did not converge ({} cycle{}, last change {:.3} px), so its field may be off by more than {bound} px (5 times solver.tolerance); {advice}", report.cycles, if report.cycles == 1 { "" } else { "s" }, report.final_change_px))
    }

    /// Whether layer `layer` shows in frames (visible, with an image).
    pub fn layer_is_drawn(&self, layer: usize) -> bool {
        let l = &self.layers()[layer];
        l.visible && l.image.is_some()
    }

    /// Composites the drawn layers, back to front, each warped by its field (`fields[j]`
    /// for layer `j`; ignored for layers that are not drawn) over the background.
    pub fn composite(&self, fields: &[Option<Field>]) -> Result<RgbaImage, SceneError> {
        let mut canvas = Canvas::new(self.width(), self.height(), self.doc().background);
        for (j, layer) in self.layers().iter().enumerate() {
            if let (true, Some(image), Some(Some(field))) = (layer.visible, &layer.image, fields.get(j)) {
                canvas.draw_layer(image, field, &layer.grid, layer.offset);
            }
        }
        crate::interrupt::unless_requested(canvas.to_rgba8(), SceneError::one("", crate::interrupt::STOPPED))
    }

    /// The frame at time `time_s`, every field solved cold.
    pub fn render(&self, time_s: f64) -> Result<RgbaImage, SceneError> {
        Animator::new(self).render(time_s)
    }

    /// [`Scene::render`] with every layer's field computed by `method` instead of the
    /// layer's own, when given, and the warnings of its solves (see
    /// [`Scene::convergence_warning`]).
    pub fn render_warned(&self, time_s: f64, method: Option<Method>) -> Result<(RgbaImage, Vec<String>), SceneError> {
        let mut animator = Animator::with_overrides(self, SolverOverrides::method(method));
        let image = animator.render(time_s)?;
        Ok((image, animator.take_warnings()))
    }

    /// Frames `frames` rendered by up to `threads` threads (0: [`default_frame_threads`]),
    /// delivered in order. See [`WARM_CHAIN_FRAMES`] for how warm starts are chained.
    pub fn frames(self: &Arc<Self>, frames: Range<usize>, threads: usize) -> FrameStream {
        FrameStream::new(Arc::clone(self), frames, threads, SolverOverrides::default(), None)
    }
}

/// Renders frames one after another, starting each layer's solve from that layer's
/// earlier frames.
#[derive(Debug)]
pub struct Animator<'a> {
    scene: &'a Scene,
    /// Each drawn layer's field of the latest frame, composited into it.
    fields: Vec<Option<Field>>,
    /// Each layer's solver: its hierarchy and earlier frames, the start of its next solve.
    history: Vec<Solver>,
    overrides: SolverOverrides,
    /// Warnings of the solves since the last [`Animator::take_warnings`].
    warnings: Vec<String>,
}

impl<'a> Animator<'a> {
    /// An animator with no previous fields (the first solve is cold).
    pub fn new(scene: &'a Scene) -> Self { Self::with_overrides(scene, SolverOverrides::default()) }

    /// An animator that applies `overrides` over every layer's own settings.
    pub fn with_overrides(scene: &'a Scene, overrides: SolverOverrides) -> Self {
        let n = scene.layers().len();
        Animator { scene, fields: vec![None; n], history: (0..n).map(|_| Solver::new()).collect(), overrides, warnings: Vec::new() }
    }

    /// Forgets the previous fields, so that the next solves are cold.
    pub fn reset(&mut self) {
        self.fields.iter_mut().for_each(|f| *f = None);
        self.history.iter_mut().for_each(Solver::clear);
    }

    /// The frame at `time_s`: every drawn layer solved (warm) and composited.
    pub fn render(&mut self, time_s: f64) -> Result<RgbaImage, SceneError> {
        let scene = self.scene;
        for layer in (0..scene.layers().len()).filter(|&j| scene.layer_is_drawn(j)) {
            self.fields[layer] = Some(self.layer_field(layer, time_s)?.field);
        }
        scene.composite(&self.fields)
    }

    /// The warnings of the solves since the last call (a solve that did not converge).
    pub fn take_warnings(&mut self) -> Vec<String> { std::mem::take(&mut self.warnings) }

    /// The field of layer `layer` at `time_s`, started from the layer's earlier frames (the
    /// thin plate; the other methods start from nothing).
    pub fn layer_field(&mut self, layer: usize, time_s: f64) -> Result<LayerSolve, SceneError> {
        let solved = self.scene.solve_layer(layer, time_s, Start::History(&mut self.history[layer]), &self.overrides)?;
        self.warnings.extend(self.scene.convergence_warning(layer, time_s, &solved));
        Ok(solved)
    }
}

type FrameResult = Result<(usize, RgbaImage), SceneError>;
/// A frame as a worker sends it: with the warnings of its solves.
type WorkerResult = Result<(usize, RgbaImage, Vec<String>), SceneError>;

/// How many frames [`FrameStream`] renders at once when not told: one per four cores.
///
/// The solver and the renderer already spread each frame over every core (rayon), so
/// frame-level parallelism only fills their serial parts (coarse grids, sampling,
/// compositing) and does not pay on small machines: sequential there, a few chains at once
/// on big ones.
pub fn default_frame_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get() / 4).max(1)
}

/// A chain rendered on the calling thread: its frames still to come, and each layer's last
/// field (for compositing) and solve history.
type SequentialChain = (Range<usize>, Vec<Option<Field>>, Vec<Solver>);

/// An animation's frames, in order, as an iterator of `(index, image)`; rendered on
/// worker threads (one warm-start chain per thread at a time) when more than one thread is
/// allowed and there is more than one chain. Dropping it stops the workers.
#[derive(Debug)]
pub struct FrameStream {
    scene: Arc<Scene>,
    chains: Vec<Range<usize>>,
    next_chain: usize,
    /// Sequential mode: the chain being rendered here and its animator state.
    sequential: Option<SequentialChain>,
    overrides: SolverOverrides,
    receivers: Vec<Receiver<WorkerResult>>,
    /// Warnings of the frames delivered since the last [`FrameStream::take_warnings`].
    warnings: Vec<String>,
    workers: Vec<JoinHandle<()>>,
    failed: bool,
    /// Where frames render (`None`: rayon's global pool).
    pool: Option<&'static rayon::ThreadPool>,
}

impl FrameStream {
    /// Frames `frames` (clamped to the scene) by up to `threads` threads (0: the default,
    /// [`default_frame_threads`]), `overrides` applied over every layer's own settings; the
    /// frames render on `pool` (default: rayon's global pool), never the consumer's thread
    /// waiting on a worker: it may call `next` from outside any pool.
    pub fn new(scene: Arc<Scene>, frames: Range<usize>, threads: usize, overrides: SolverOverrides, pool: Option<&'static rayon::ThreadPool>) -> Self {
        let end = frames.end.min(scene.frame_count());
        let next = |start: usize| (start / WARM_CHAIN_FRAMES + 1) * WARM_CHAIN_FRAMES;
        let starts = std::iter::successors(Some(frames.start), |&start| Some(next(start))).take_while(|&start| start < end);
        let chains: Vec<Range<usize>> = starts.map(|start| start..next(start).min(end)).collect();
        let threads = if threads == 0 { default_frame_threads() } else { threads }.min(chains.len());
        let (receivers, workers, warnings) = (Vec::new(), Vec::new(), Vec::new());
        let mut stream =
            FrameStream { scene, chains, next_chain: 0, sequential: None, overrides, receivers, warnings, workers, failed: false, pool };
        if threads > 1 {
            stream.start_workers(threads);
        }
        stream
    }

    /// Number of frames this stream delivers in all.
    pub fn len(&self) -> usize { self.chains.iter().map(|c| c.len()).sum() }

    /// The warnings of the frames delivered since the last call (each names its layer and
    /// frame; see [`Scene::convergence_warning`]).
    pub fn take_warnings(&mut self) -> Vec<String> { std::mem::take(&mut self.warnings) }

    pub fn is_empty(&self) -> bool { self.len() == 0 }

    fn start_workers(&mut self, threads: usize) {
        let pool = self.pool;
        // Two frames of slack per chain bound the memory held by workers running ahead.
        let channels = self.chains.iter().map(|_| sync_channel::<WorkerResult>(2));
        let (senders, receivers): (Vec<_>, Vec<_>) = channels.map(|(tx, rx)| (Some(tx), rx)).unzip();
        self.receivers = receivers;
        let senders = Arc::new(Mutex::new(senders));
        let next = Arc::new(AtomicUsize::new(0));
        let chains = Arc::new(self.chains.clone());
        for _ in 0..threads {
            let (scene, senders, next, chains) = (Arc::clone(&self.scene), Arc::clone(&senders), Arc::clone(&next), Arc::clone(&chains));
            let overrides = self.overrides.clone();
            self.workers.push(std::thread::spawn(move || {
                let mut animator = Animator::with_overrides(&scene, overrides);
                loop {
                    let c = next.fetch_add(1, Ordering::Relaxed);
                    if c >= chains.len() {
                        return;
                    }
                    // Taking the sender means it is dropped when this worker finishes the
                    // chain or dies, which the consumer sees as a disconnection.
                    let Some(tx) = senders.lock().map(|mut s| s[c].take()).ok().flatten() else {
                        return;
                    };
                    animator.reset();
                    for i in chains[c].clone() {
                        let mut render = || animator.render(scene.frame_time_s(i)).map(|image| (i, image, animator.take_warnings()));
                        let frame = match pool { Some(pool) => pool.install(render), None => render() };
                        let stop = frame.is_err();
                        if tx.send(frame).is_err() || stop {
                            return;
                        }
                    }
                }
            }));
        }
    }

    fn next_sequential(&mut self) -> Option<FrameResult> {
        if self.sequential.as_ref().map_or(true, |(range, _, _)| range.is_empty()) {
            let chain = self.chains.get(self.next_chain)?.clone();
            self.next_chain += 1;
            let n = self.scene.layers().len();
            self.sequential = Some((chain, vec![None; n], (0..n).map(|_| Solver::new()).collect()));
        }
        let scene = Arc::clone(&self.scene);
        let (range, fields, history) = self.sequential.as_mut()?;
        let i = range.next()?;
        let (fields_taken, history_taken) = (std::mem::take(fields), std::mem::take(history));
        let overrides = self.overrides.clone();
        let mut animator = Animator { scene: &scene, fields: fields_taken, history: history_taken, overrides, warnings: Vec::new() };
        let mut render = || animator.render(scene.frame_time_s(i)).map(|image| (i, image));
        let frame = match self.pool { Some(pool) => pool.install(render), None => render() };
        self.warnings.extend(animator.take_warnings());
        *fields = animator.fields;
        *history = animator.history;
        Some(frame)
    }
}

impl Iterator for FrameStream {
    type Item = FrameResult;

    fn next(&mut self) -> Option<FrameResult> {
        if self.failed {
            return None;
        }
        let item = if self.receivers.is_empty() {
            self.next_sequential()
        } else {
            let c = self.next_chain;
            let receiver = self.receivers.get(c)?;
            let chain_end = self.chains[c].end;
            match receiver.recv() {
                Ok(item) => {
                    if matches!(&item, Ok((i, _, _)) if i + 1 == chain_end) {
                        self.next_chain += 1;
                    }
                    Some(item.map(|(i, image, warnings)| {
                        self.warnings.extend(warnings);
                        (i, image)
                    }))
                }
                Err(_) => Some(Err(SceneError::one("", "a rendering thread stopped unexpectedly (this is a bug in inkwarp)"))),
            }
        };
        self.failed = matches!(item, Some(Err(_)));
        item
    }
}

impl Drop for FrameStream {
    fn drop(&mut self) {
        // Dropping the receivers makes every blocked worker's send fail, so it exits.
        self.receivers.clear();
        for worker in self.workers.drain(..) {
            let _ = worker.join();
        }
    }
}

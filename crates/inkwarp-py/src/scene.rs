//! Scenes for Python: `SceneCore` (a resolved scene), its frame iterator, the schema and the
//! validator. Image paths are read here, relative to the scene's folder; the core only sees
//! bytes. Core `SceneError`s become `inkwarp.SceneError` with the file, path and problems.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use inkwarp_core::scene::{self, FrameStream, Method, Scene, SceneError, SolverOverrides};
use inkwarp_core::Field;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyIndexError;
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::errors::{input_error, run_engine};
use crate::limits::{available_bytes, memory_problem, MAX_IMAGE_FILE_BYTES};

/// Issues each of `messages` as an `inkwarp.errors.ConvergenceWarning` (an error when
/// the warnings filter turns warnings into errors).
fn warn_convergence(py: Python<'_>, messages: &[String]) -> PyResult<()> {
    if messages.is_empty() {
        return Ok(());
    }
    let errors = py.import("inkwarp.errors")?;
    let category = errors.getattr("ConvergenceWarning")?;
    // At the first line outside the package (the user's `inkwarp.render(...)`, not the loop in
    // `rendering.py` that drew the frames).
    let level: i32 = errors.getattr("caller_outside")?.call0()?.extract()?;
    for message in messages {
        let message = std::ffi::CString::new(message.replace('\0', " "))
            .expect("NUL bytes were replaced");
        PyErr::warn(py, &category, &message, level)?;
    }
    Ok(())
}

/// Raises `inkwarp.SceneError` for `err`, naming `file` when there is one.
fn scene_error(py: Python<'_>, err: &SceneError, file: Option<&str>) -> PyErr {
    let message = match file {
        Some(file) => format!("{file}: {err}"),
        None => err.to_string(),
    };
    let problems: Vec<(String, String)> = err
        .problems
        .iter()
        .map(|p| (p.path.clone(), p.message.clone()))
        .collect();
    let build = || -> PyResult<PyErr> {
        let class = py.import("inkwarp.errors")?.getattr("SceneError")?;
        let kwargs = pyo3::types::PyDict::new(py);
        kwargs.set_item("file", file)?;
        kwargs.set_item("path", err.path())?;
        kwargs.set_item("problems", PyList::new(py, problems)?)?;
        let instance = class.call((message.clone(),), Some(&kwargs))?;
        Ok(PyErr::from_value(instance))
    };
    build().unwrap_or_else(|e| e)
}

/// How to write a picture's path that was not found: the fix for the two ways it is
/// written wrong (a `file:` URI, a Windows path off Windows), else where a relative one is
/// read from (the scene's folder, or without one the current folder).
fn path_hint(reference: &str, scene_folder: bool) -> &'static str {
    if reference.starts_with("file:") {
        "; give a path, not a file: URI (art/cat.png beside the scene, or /home/me/cat.png)"
    } else if reference.contains('\\') && !cfg!(windows) {
        "; write the path with forward slashes (art/cat.png), which every system reads"
    } else if Path::new(reference).is_absolute() {
        ""
    } else if scene_folder {
        "; a relative path is read from the scene's folder"
    } else {
        "; a relative path is read from the current folder (give base_dir for another)"
    }
}

/// The pairs of features driving layer `layer` (`a ≤ b`, scene indices; `a == b`: two parts of
/// one feature, apart along it) that a solve at `grid_step = step`, on `coarse`, cannot both hold:
/// each coarse node holds the nearest of the samples it takes (ties together, as the solver does), and at
/// time 0 or at a key another sample there moves more than a pixel apart from it, so that feature
/// is let go there and the picture tears between them (lids that close, lips that part).
fn clashes(scene: &Scene, layer: usize, coarse: &inkwarp_core::Grid, step: usize) -> Result<Vec<(usize, usize)>, SceneError> {
    let (features, l) = (&scene.doc().features, &scene.layers()[layer]);
    let g = &l.grid;
    let mut times: Vec<f64> = l.drivers.iter().flat_map(|&f| features[f].keys.iter().map(|k| k.time_s)).chain([0.0]).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    // The samples rest where they are at every time: each coarse node's, as the solver assigns them
    // ([`inkwarp_core::solve::coarse_nodes`]), as (feature in the list, sample, whether it holds the node).
    // A held border's samples (the solver's, still) compete too, as feature `BORDER`: a node they hold lets every
    // feature there go, by the layer's choice, with no tear between features.
    const BORDER: usize = usize::MAX;
    let at_rest = scene.layer_feature_samples(layer, 0.0)?;
    let border = if l.border == inkwarp_core::scene::Border::Hold { inkwarp_core::geometry::border_samples(g.width, g.height, step as f64) } else { Vec::new() };
    let drawn = at_rest.iter().enumerate().flat_map(|(j, f)| f.samples.iter().enumerate().map(move |(k, p)| (j, k, p)));
    let on_grid: Vec<(usize, usize, inkwarp_core::Sample)> = drawn.chain(border.iter().map(|p| (BORDER, 0, p)))
        .filter(|(_, _, p)| inkwarp_core::grid::nearest_node(g, p.rest).is_some())
        .map(|(j, k, p)| (j, k, inkwarp_core::Sample { rest: inkwarp_core::solve::coarse_point(g.width, g.height, step, p.rest), ..*p }))
        .collect();
    let placed: Vec<inkwarp_core::Sample> = on_grid.iter().map(|e| e.2).collect();
    let mut nodes: std::collections::HashMap<usize, Vec<(usize, usize, bool)>> = Default::default();
    for (&(j, k, _), n) in on_grid.iter().zip(inkwarp_core::solve::coarse_nodes(coarse, &placed)) {
        if let Some((i, holds)) = n { nodes.entry(i).or_default().push((j, k, holds)); }
    }
    // Samples of one feature next to each other along it (a closed curve's wrap around) are one part of it; a
    // region's are never apart (its interior samples are every pixel's, and it moves as a whole).
    let apart = |(ja, ka): (usize, usize), (jb, kb): (usize, usize)| {
        let (f, n) = (&features[at_rest[ja].feature], at_rest[ja].samples.len());
        let d = ka.abs_diff(kb);
        ja != jb || (f.kind != inkwarp_core::Kind::Region && (if f.closed { d.min(n - d) } else { d }) > 2)
    };
    // A node's first holder with every other sample there apart from it (holders tie where features meet end to end:
    // one part, averaged).
    let pairs_at: Vec<((usize, usize), (usize, usize))> = nodes.values().flat_map(|here| {
        let &(ja, ka, _) = here.iter().find(|e| e.2).expect("a node's holder");
        let drawn = here.iter().filter(move |&&(jb, _, _)| ja != BORDER && jb != BORDER);
        drawn.filter(move |&&(jb, kb, _)| apart((ja, ka), (jb, kb))).map(move |&(jb, kb, _)| ((ja, ka), (jb, kb)))
    }).collect();
    if pairs_at.is_empty() { return Ok(Vec::new()) } // nothing to pose
    let mut pairs = std::collections::BTreeSet::new();
    for t in times {
        let now = if t == 0.0 { Cow::Borrowed(&at_rest) } else { Cow::Owned(scene.layer_feature_samples(layer, t)?) };
        for &((ja, ka), (jb, kb)) in &pairs_at {
            let (da, db) = (now[ja].samples[ka].displacement, now[jb].samples[kb].displacement);
            if (da[0] - db[0]).hypot(da[1] - db[1]) > 1.0 {
                let (a, b) = (at_rest[ja].feature, at_rest[jb].feature);
                pairs.insert((a.min(b), a.max(b)));
            }
        }
    }
    Ok(pairs.into_iter().collect())
}

/// Reads image references relative to `base_dir` (absolute paths as they are).
fn file_loader(base_dir: Option<PathBuf>) -> impl FnMut(&str) -> Result<Vec<u8>, String> {
    move |reference: &str| {
        let path = Path::new(reference);
        let full = match (&base_dir, path.is_absolute()) {
            (Some(base), false) => base.join(path),
            _ => path.to_path_buf(),
        };
        let describe = |e: std::io::Error| match e.kind() {
            std::io::ErrorKind::NotFound => format!("no such file (looked for {}){}", full.display(), path_hint(reference, base_dir.is_some())),
            _ => format!("cannot read {} ({e})", full.display()),
        };
        // Regular files only: reading a FIFO or a device could block forever or never end.
        let meta = std::fs::metadata(&full).map_err(describe)?;
        if !meta.is_file() {
            return Err(format!(
                "{} is not a regular file (a folder, FIFO or device); give a PNG or JPEG file",
                full.display()
            ));
        }
        if meta.len() > MAX_IMAGE_FILE_BYTES {
            return Err(format!(
                "{} is {} MiB, more than the {} MiB inkwarp reads; use a smaller picture",
                full.display(),
                meta.len() >> 20,
                MAX_IMAGE_FILE_BYTES >> 20
            ));
        }
        let bytes = std::fs::read(&full).map_err(describe)?;
        if let Some(video) = video_kind(&bytes) {
            let an = if matches!(video, "MP4" | "AVI") { "an" } else { "a" };
            return Err(format!("{} is {an} {video} video, not a picture; take the frame you want from it \
                                (inkwarp frame {} --frame N -o frame.png) and give that", full.display(), full.display()));
        }
        if jpeg_cut_short(&bytes) {
            // The decoder reads such a file without an error, the rest of the picture grey.
            return Err(format!("{} is a JPEG that ends before its end-of-image marker: the file is cut short \
                                (copied or synced only in part); copy or save it again", full.display()));
        }
        Ok(bytes)
    }
}

/// The kind of video `bytes` start as (MP4, MOV, WebM, Matroska, AVI), or None: the one rule the file
/// loader and the Python front end (`inkwarp.scene._video_kind`) tell a video by. An ISO file whose brand
/// is a picture's (HEIC, AVIF) is not one.
#[pyfunction]
pub(crate) fn video_kind(bytes: &[u8]) -> Option<&'static str> {
    let brand = bytes.get(8..12).unwrap_or_default();
    if bytes.get(4..8) == Some(b"ftyp") && ![&b"heic"[..], b"heix", b"mif1", b"msf1", b"avif", b"avis"].contains(&brand) {
        return Some(if brand.starts_with(b"qt") { "MOV" } else { "MP4" });
    }
    if bytes.starts_with(&[0x1A, 0x45, 0xDF, 0xA3]) {
        return Some(if bytes[..bytes.len().min(64)].windows(4).any(|w| w == b"webm") { "WebM" } else { "Matroska" });
    }
    (bytes.starts_with(b"RIFF") && brand == b"AVI ").then_some("AVI")
}

/// Whether `bytes` start as a JPEG whose marker segments and scans run out before its
/// end-of-image marker (FF D9). Walked from the start, segment by segment, so that a marker
/// inside an EXIF thumbnail or an ICC profile, or in data after the end (a motion photo's
/// video), counts for nothing.
pub(crate) fn jpeg_cut_short(bytes: &[u8]) -> bool {
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return false;
    }
    let mut i = 2;
    while i + 1 < bytes.len() {
        if bytes[i] != 0xFF {
            return false; // not a marker where one belongs: a damaged file, for the decoder to judge
        }
        match bytes[i + 1] {
            0xD9 => return false,
            0xFF => i += 1,                             // fill
            0x01 | 0xD0..=0xD7 => i += 2,               // markers without a length
            marker if i + 3 < bytes.len() => {
                i += 2 + (usize::from(bytes[i + 2]) << 8 | usize::from(bytes[i + 3]));
                if marker == 0xDA {
                    // Entropy-coded data up to the next marker (FF 00 and restarts belong to it).
                    while i + 1 < bytes.len() && !(bytes[i] == 0xFF && bytes[i + 1] != 0 && !(0xD0..=0xD7).contains(&bytes[i + 1])) {
                        i += 1;
                    }
                }
            }
            _ => break,
        }
    }
    true
}

/// The scene from JSON text and the rough peak memory of rendering it, refused when that
/// would not fit in free memory (so that validating and loading say so before a render aborts).
fn resolve_checked(text: &str, base_dir: Option<PathBuf>) -> Result<(Scene, u64), SceneError> {
    let mut load = file_loader(base_dir);
    let scene = Scene::from_json(text, &mut load)?;
    let bytes = render_bytes(&scene);
    match memory_problem(bytes) {
        Some(why) => Err(SceneError::one("width", why)),
        None => Ok((scene, bytes)),
    }
}

/// The rough peak memory of rendering `scene` ([`inkwarp_core::limits::render_bytes`], and
/// [`inkwarp_core::limits::thin_and_slow_bytes`] of the layers' solver grids).
fn render_bytes(scene: &Scene) -> u64 {
    let layers = scene.layers().iter().map(|l| ([l.grid.width, l.grid.height], l.solver.grid_step as usize));
    let grids: Vec<_> = scene.layers().iter().map(|l| match l.solver.grid_step as usize {
        1 => Cow::Borrowed(&l.grid),
        s => Cow::Owned(inkwarp_core::solve::coarse_grid(&l.grid, s)),
    }).collect();
    let solves = inkwarp_core::limits::thin_and_slow_bytes(grids.iter().map(|g| g.as_ref()));
    inkwarp_core::limits::render_bytes(scene.width(), scene.height(), layers).saturating_add(solves)
}

fn image_to_numpy<'py>(py: Python<'py>, image: scene::RgbaImage) -> PyResult<Bound<'py, PyAny>> {
    let (h, w) = (image.height, image.width);
    Ok(PyArray1::from_vec(py, image.data)
        .reshape([h, w, 4])?
        .into_any())
}

fn field_to_numpy<'py>(py: Python<'py>, field: &Field) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, field.to_interleaved())
        .reshape([field.height, field.width, 2])?
        .into_any())
}

/// The method called `name`; `None` for `None`.
fn method_named(name: Option<&str>) -> PyResult<Option<Method>> {
    name.map(|n| {
        Method::from_name(n).ok_or_else(|| {
            let names: Vec<String> = Method::ALL
                .iter()
                .map(|m| format!("\"{}\"", m.name()))
                .collect();
            input_error(format!(
                "unknown method \"{n}\"; use one of {}",
                names.join(", ")
            ))
        })
    })
    .transpose()
}

/// A resolved scene (images decoded, mattes and cuts applied), ready to render.
#[pyclass(module = "inkwarp._inkwarp", frozen)]
#[derive(Debug)]
pub struct SceneCore {
    scene: Arc<Scene>,
    file: Option<String>,
    /// The rough peak memory of rendering it, in bytes (found when it was loaded).
    render_bytes: u64,
}

impl SceneCore {
    fn check_layer(&self, layer: usize) -> PyResult<()> {
        if layer >= self.scene.layers().len() {
            return Err(PyIndexError::new_err(format!("layer index {layer} is out of range")));
        }
        Ok(())
    }
}

#[pymethods]
impl SceneCore {
    /// Parses, validates and resolves scene JSON; image paths are relative to `base_dir`.
    /// Raises `inkwarp.SceneError` with every problem.
    #[staticmethod]
    #[pyo3(signature = (text, base_dir=None, file=None))]
    fn from_json(
        py: Python<'_>,
        text: String,
        base_dir: Option<PathBuf>,
        file: Option<String>,
    ) -> PyResult<Self> {
        let result = run_engine(py, move || resolve_checked(&text, base_dir))?;
        match result {
            Ok((scene, render_bytes)) => Ok(SceneCore {
                scene: Arc::new(scene),
                file,
                render_bytes,
            }),
            Err(err) => Err(scene_error(py, &err, file.as_deref())),
        }
    }

    #[getter]
    fn width(&self) -> usize {
        self.scene.width()
    }

    #[getter]
    fn height(&self) -> usize {
        self.scene.height()
    }

    #[getter]
    fn fps(&self) -> f64 {
        self.scene.fps()
    }

    #[getter]
    fn duration(&self) -> f64 {
        self.scene.duration_s()
    }

    #[getter]
    fn frame_count(&self) -> usize {
        self.scene.frame_count()
    }

    /// The rough peak memory of rendering the scene in one process, in bytes.
    #[getter]
    fn render_bytes(&self) -> u64 {
        self.render_bytes
    }

    #[getter]
    fn layer_names(&self) -> Vec<String> {
        self.scene.layers().iter().map(|l| l.name.clone()).collect()
    }

    #[getter]
    fn feature_ids(&self) -> Vec<String> {
        self.scene
            .doc()
            .features
            .iter()
            .map(|f| f.id.clone())
            .collect()
    }

    /// The time of frame `frame` in seconds.
    fn frame_time(&self, frame: usize) -> f64 {
        self.scene.frame_time_s(frame)
    }

    /// Whether some layer (solved by `method` instead of its own, if given) starts each frame
    /// from the frames before it (the grid's thin plate): only then does a frame depend on them.
    #[pyo3(signature = (method=None))]
    fn warm_starts(&self, method: Option<&str>) -> PyResult<bool> {
        let method = method_named(method)?;
        Ok(self.scene.layers().iter().any(|l| method.unwrap_or(l.solver.method).interpolant().is_none()))
    }

    /// Per layer, whether its grid is torn (an inactive node, or a cut between two active
    /// neighbours: what `tps` tears and the other methods ignore).
    fn torn_layers(&self) -> Vec<bool> {
        self.scene.layers().iter().map(|l| inkwarp_core::grid::torn(l.grid.width, &l.grid.active, &l.grid.link_right, &l.grid.link_down)).collect()
    }

    /// Per layer: the features that drive it of which every sample is dropped (off the grid or on inactive nodes), or None at a
    /// `grid_step` above 1, whose samples go to the coarse nodes; and at such a step, the step,
    /// the pieces of its grid and of the coarse grid it is solved on and the features that
    /// clash there ([`clashes`]) (None at step 1); whether its picture is wholly transparent
    /// (it draws nothing); and whether its grid has no active node (nothing moves it).
    #[allow(clippy::type_complexity)]
    fn layer_checks(&self, py: Python<'_>) -> PyResult<Vec<(Option<Vec<usize>>, Option<(usize, usize, usize, Vec<(usize, usize)>)>, bool, bool)>> {
        let scene = Arc::clone(&self.scene);
        let checks = run_engine(py, move || {
            let check = |(i, layer): (usize, &scene::Layer)| -> Result<_, SceneError> {
                let g = &layer.grid;
                let (step, still) = (layer.solver.grid_step, !g.active.contains(&true));
                let blank = layer.image.as_ref().is_some_and(|im| im.data.chunks_exact(4).all(|p| p[3] == 0));
                if step > 1 {
                    let coarse = inkwarp_core::solve::coarse_grid(g, step as usize);
                    let clashing = clashes(&scene, i, &coarse, step as usize)?;
                    return Ok((None, Some((step as usize, g.pieces().1, coarse.pieces().1, clashing)), blank, still));
                }
                let features = scene.layer_feature_samples(i, 0.0)?;
                let dropped = features.iter().filter(|f| inkwarp_core::grid::constrain(g, &f.samples).used_samples == 0);
                Ok((Some(dropped.map(|f| f.feature).collect()), None, blank, still))
            };
            scene.layers().iter().enumerate().map(check).collect::<Result<Vec<_>, _>>()
        })?;
        checks.map_err(|err| scene_error(py, &err, self.file.as_deref()))
    }

    /// The document with its defaults filled in, as JSON text.
    fn doc_json(&self) -> String {
        serde_json::to_string(self.scene.doc()).expect("a scene document is always valid JSON")
    }

    /// The frame at `time` (seconds) as an RGBA uint8 array `(H, W, 4)`, solved cold, by
    /// `method` instead of each layer's own when given.
    #[pyo3(signature = (time, method=None))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        time: f64,
        method: Option<&str>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let method = method_named(method)?;
        let scene = Arc::clone(&self.scene);
        match run_engine(py, move || scene.render_warned(time, method))? {
            Ok((image, warnings)) => {
                warn_convergence(py, &warnings)?;
                image_to_numpy(py, image)
            }
            Err(err) => Err(scene_error(py, &err, self.file.as_deref())),
        }
    }

    /// The displacement field of layer `layer` (an index) at `time`, float32 `(H, W, 2)`.
    #[pyo3(signature = (layer, time, method=None))]
    fn field<'py>(
        &self,
        py: Python<'py>,
        layer: usize,
        time: f64,
        method: Option<&str>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let method = method_named(method)?;
        self.check_layer(layer)?;
        let scene = Arc::clone(&self.scene);
        let solved = run_engine(py, move || {
            let solved = scene.layer_field_overridden(layer, time, None, &SolverOverrides::method(method))?;
            let warning = scene.convergence_warning(layer, time, &solved);
            Ok::<_, SceneError>((solved, warning))
        })?;
        match solved {
            Ok((solved, warning)) => {
                warn_convergence(py, warning.as_slice())?;
                field_to_numpy(py, &solved.field)
            }
            Err(err) => Err(scene_error(py, &err, self.file.as_deref())),
        }
    }

    /// The frame at `time` with `overrides` (solver settings as JSON, applied over every
    /// layer's own, e.g. `{"method": "beier-neely", "beier_neely": {"a": 2}}`), the field
    /// of layer `layer` (an index) and the notes of every drawn layer's interpolant (and
    /// of layer `layer`'s): what `inkwarp.compare` shows. Bad overrides raise `inkwarp.SceneError` with their paths.
    #[pyo3(signature = (time, layer, overrides=None))]
    fn render_detailed<'py>(
        &self,
        py: Python<'py>,
        time: f64,
        layer: usize,
        overrides: Option<&str>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Vec<String>)> {
        self.check_layer(layer)?;
        let overrides: SolverOverrides = match overrides {
            None => SolverOverrides::default(),
            Some(text) => scene::parse_overrides(text, "solver").map_err(|e| scene_error(py, &e, None))?,
        };
        let scene = Arc::clone(&self.scene);
        let result = run_engine(py, move || -> Result<_, SceneError> {
            let rendered = scene.render_overridden(time, &overrides)?;
            let mut notes = rendered.notes(&scene);
            // A solve that stopped short is said, as `Scene.render` says it (and noted with the rest).
            let mut stopped: Vec<String> = rendered.layers.iter().enumerate()
                .filter_map(|(j, s)| s.as_ref().and_then(|s| scene.convergence_warning(j, time, s))).collect();
            let field = match rendered.layers[layer].as_ref() {
                Some(solved) => solved.field.clone(),
                None => {
                    // A layer that is not drawn (no image, or hidden) is solved here alone.
                    let solved = scene.layer_field_overridden(layer, time, None, &overrides)?;
                    notes.extend(scene.layer_notes(layer, &solved));
                    stopped.extend(scene.convergence_warning(layer, time, &solved));
                    solved.field
                }
            };
            notes.extend(stopped.iter().cloned());
            Ok((rendered.image, field, notes, stopped))
        })?;
        match result {
            Ok((image, field, notes, stopped)) => {
                warn_convergence(py, &stopped)?;
                Ok((image_to_numpy(py, image)?, field_to_numpy(py, &field)?, notes))
            }
            Err(err) => Err(scene_error(py, &err, self.file.as_deref())),
        }
    }

    /// Frames `start..stop`, warm-started, by up to `threads` threads (0: the default, as
    /// many as the free memory holds renders of the scene: each keeps its own solvers).
    #[pyo3(signature = (start, stop, threads=0, method=None))]
    fn frames(
        &self,
        start: usize,
        stop: usize,
        threads: usize,
        method: Option<&str>,
    ) -> PyResult<FrameIter> {
        let method = method_named(method)?;
        let threads = match (threads, available_bytes()) {
            (0, Some(free)) => {
                let fit = (free / self.render_bytes.max(1)).max(1);
                inkwarp_core::scene::default_frame_threads().min(fit as usize)
            }
            _ => threads,
        };
        // Its frames render on the engine's pool, this process's own (see `errors::pool`).
        let pool = crate::errors::engine_pool()?;
        let stream = FrameStream::new(Arc::clone(&self.scene), start..stop, threads, SolverOverrides::method(method), Some(pool));
        let remaining = stream.len();
        Ok(FrameIter {
            stream: Mutex::new(Some(stream)),
            remaining: Mutex::new(remaining),
            file: self.file.clone(),
        })
    }
}

/// The frames of a scene as RGBA uint8 arrays, in order.
#[pyclass(module = "inkwarp._inkwarp")]
#[derive(Debug)]
pub struct FrameIter {
    stream: Mutex<Option<FrameStream>>,
    remaining: Mutex<usize>,
    file: Option<String>,
}

#[pymethods]
impl FrameIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __len__(&self) -> usize {
        *self.remaining.lock().expect("frame counter")
    }

    /// The next `(index, frame)`; renders with the GIL released (on the pool: this waits
    /// outside it for the stream's workers).
    fn __next__<'py>(&self, py: Python<'py>) -> PyResult<Option<(usize, Bound<'py, PyAny>)>> {
        let next = crate::errors::run_engine_outside_pool(py, || {
            let mut guard = self.stream.lock().expect("frame stream");
            guard.as_mut().and_then(|stream| stream.next().map(|item| (item, stream.take_warnings())))
        });
        let next = match next {
            Ok(next) => next,
            Err(err) => {
                // Interrupted (or a panic): the stream stops here.
                self.close();
                return Err(err);
            }
        };
        match next {
            None => {
                self.close();
                Ok(None)
            }
            Some((Ok((index, image)), warnings)) => {
                {
                    let mut remaining = self.remaining.lock().expect("frame counter");
                    *remaining = remaining.saturating_sub(1);
                }
                warn_convergence(py, &warnings)?;
                Ok(Some((index, image_to_numpy(py, image)?)))
            }
            Some((Err(err), _)) => {
                self.close();
                Err(scene_error(py, &err, self.file.as_deref()))
            }
        }
    }

    /// Stops rendering (the worker threads finish their current frame and exit).
    fn close(&self) {
        let stream = self.stream.lock().expect("frame stream").take();
        *self.remaining.lock().expect("frame counter") = 0;
        drop(stream);
    }
}

/// The JSON Schema of the scene format, as JSON text.
#[pyfunction]
fn scene_schema() -> String {
    scene::schema_json()
}

/// Every problem of scene JSON text, images included, as `(path, message)` pairs.
#[pyfunction]
#[pyo3(signature = (text, base_dir=None))]
fn scene_problems(
    py: Python<'_>,
    text: String,
    base_dir: Option<PathBuf>,
) -> PyResult<Vec<(String, String)>> {
    run_engine(py, move || {
        match resolve_checked(&text, base_dir) {
            Ok(_) => Vec::new(),
            Err(err) => err
                .problems
                .into_iter()
                .map(|p| (p.path, p.message))
                .collect(),
        }
    })
}

/// Registers the scene API in the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SceneCore>()?;
    m.add_class::<FrameIter>()?;
    m.add_function(wrap_pyfunction!(scene_schema, m)?)?;
    m.add_function(wrap_pyfunction!(scene_problems, m)?)?;
    m.add_function(wrap_pyfunction!(video_kind, m)?)?;
    Ok(())
}

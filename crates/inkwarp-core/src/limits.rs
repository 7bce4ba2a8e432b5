//! The ranges inkwarp accepts, checked before any work starts.
//!
//! Every number a scene or a call gives is held to these before anything is allocated or
//! solved, so that bad input becomes a clear error instead of an abort (out of memory), a
//! panic (an overflowing size) or a silently wrong frame (NaN from keys too close in time).
//! `inkwarp validate` and rendering apply the same checks: a scene that validates renders.
//! docs/reference/limits.md lists them for users.

/// The largest |x| or |y| of a control point, a cut or an offset, in pixels.
pub const MAX_COORD_PX: f64 = 1e6;
/// The latest key time and the longest duration, in seconds (a little over 27 hours).
pub const MAX_TIME_S: f64 = 1e5;
/// The least time between two keys of one feature, in seconds.
pub const MIN_KEY_SPACING_S: f64 = 1e-6;
/// The most frames per second.
pub const MAX_FPS: f64 = 1000.0;
/// The fewest frames per second: one frame every 1000 s (about 17 minutes). A frame of a
/// slower scene would outlast what the formats hold in one frame (APNG's delay, 65535 s;
/// ffmpeg takes rates down to about 1e-6 only) and its derived length (the last key and one
/// frame) would run far past [`MAX_TIME_S`].
pub const MIN_FPS: f64 = 0.001;
/// The most frames a scene may have (duration × fps).
pub const MAX_FRAMES: usize = 100_000_000;
/// The widest or tallest picture, canvas or grid, in pixels.
pub const MAX_SIDE_PX: usize = 32_768;
/// The most pixels in a picture, canvas or grid (64 megapixels, such as 8192 × 8192).
pub const MAX_PIXELS: usize = 1 << 26;
/// The largest thin-plate tension (the membrane's weight against the plate's).
pub const MAX_TENSION: f64 = 1e6;
/// The largest Beier–Neely `a`, in pixels.
pub const MAX_BEIER_NEELY_A: f64 = 1e6;
/// The largest Beier–Neely `b` and `p` (exponents; the paper uses 0.5–2 and 0–1).
pub const MAX_BEIER_NEELY_EXPONENT: f64 = 16.0;
/// Rough peak memory of rendering, per pixel of the frame (its buffers and the process's
/// own; measured with `/usr/bin/time` on renders of 2048 × 2048 scenes).
pub const RENDER_BYTES_PER_PIXEL: u64 = 80;
/// And per pixel of each layer: its picture, its matte, its field and its grid.
pub const LAYER_BYTES_PER_PIXEL: u64 = 12;
/// And per node of each layer's solver grid ([`solver_nodes`]): the levels, free functions
/// and work vectors a render keeps for the layer's next frame.
pub const SOLVER_BYTES_PER_NODE: u64 = 148;

/// And per *thin* node of a solver grid (its run of linked nodes along the row or the column
/// at most 16 long: strands, teeth, outlines, slivers between cuts): the exact factor the
/// solver keeps for those parts (up to 128 entries a node, with its rows and order).
pub const THIN_BYTES_PER_NODE: u64 = 1_300;
/// And per node of a torn solver grid (a matte, a hole or a cut): the slow modes a long solve deflates, at most [`DEFLATION_MAX_BYTES`].
pub const DEFLATION_BYTES_PER_NODE: u64 = 160;
/// The most the deflated modes of one solve take.
pub const DEFLATION_MAX_BYTES: u64 = crate::solve::deflate::BUDGET_BYTES as u64;

/// And per node of a torn solver grid: the slowest modes its solver keeps to check later claims.
pub const CHECKED_BYTES_PER_NODE: u64 = 4 * crate::solve::deflate::CHECKED as u64;

/// What solving on `grids` needs beyond their bytes per node: every grid's thin nodes'
/// factors ([`THIN_BYTES_PER_NODE`]) and kept modes ([`CHECKED_BYTES_PER_NODE`]), and the
/// largest torn grid's deflated modes (one grid solves at a time).
pub fn thin_and_slow_bytes<'a>(grids: impl IntoIterator<Item = &'a crate::grid::Grid>) -> u64 {
    let [thin, slow] = grids.into_iter().fold([0u64; 2], |[thin, slow], g| {
        let torn = if g.is_open() { 0 } else { g.len() as u64 };
        let kept = (g.thin_nodes(crate::solve::THIN) as u64).saturating_mul(THIN_BYTES_PER_NODE).saturating_add(torn.saturating_mul(CHECKED_BYTES_PER_NODE));
        [thin.saturating_add(kept), slow.max(torn.saturating_mul(DEFLATION_BYTES_PER_NODE).min(DEFLATION_MAX_BYTES))]
    });
    thin.saturating_add(slow)
}

/// Checks a `width × height` size against [`MAX_SIDE_PX`] and [`MAX_PIXELS`]; the message
/// says what was found and what to do (it starts with `what`, such as "the canvas").
///
/// ```
/// use inkwarp_core::limits::check_size;
/// assert!(check_size("the canvas", 640, 480).is_ok());
/// assert!(check_size("the canvas", 100_000, 100_000).unwrap_err().contains("at most 32768"));
/// assert!(check_size("the canvas", 0, 10).is_err());
/// ```
pub fn check_size(what: &str, width: usize, height: usize) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("{what} is {width}×{height} pixels; both sides must be at least 1"));
    }
    if width > MAX_SIDE_PX || height > MAX_SIDE_PX {
        return Err(format!("{what} is {width}×{height} pixels; each side may be at most {MAX_SIDE_PX}; use a smaller picture"));
    }
    if width.saturating_mul(height) > MAX_PIXELS {
        return Err(format!("{what} is {width}×{height} pixels, more than the {} megapixels inkwarp handles; use a smaller picture", MAX_PIXELS >> 20));
    }
    Ok(())
}

/// `v` for a message: as written when short, in scientific notation when huge (1e308
/// would otherwise print as 309 digits).
///
/// ```
/// use inkwarp_core::limits::show;
/// assert_eq!((show(0.5), show(1e308), show(-2e9)), ("0.5".into(), "1e308".into(), "-2e9".into()));
/// ```
pub fn show(v: f64) -> String { if v.is_finite() && v.abs() >= 1e7 { format!("{v:e}") } else { format!("{v}") } }

/// The most samples one feature's curve may be cut into.
pub const MAX_CURVE_SAMPLES: f64 = 1e7;

/// Checks that the curve through `points`, sampled every `spacing_px`, stays under
/// [`MAX_CURVE_SAMPLES`] (a spline's length is taken as twice its control polygon's, a
/// bound for the centripetal Catmull-Rom curves inkwarp draws).
pub fn check_curve_samples(points: &[[f64; 2]], closed: bool, spacing_px: f64) -> Result<(), String> {
    let mut length: f64 = points.windows(2).map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1])).sum();
    if closed && points.len() > 2 {
        let (a, b) = (points[0], points[points.len() - 1]);
        length += (a[0] - b[0]).hypot(a[1] - b[1]);
    }
    let samples = 2.0 * length / spacing_px;
    if samples.is_nan() || samples > MAX_CURVE_SAMPLES {
        return Err(format!(
            "sampling this curve every {spacing_px} px would make about {samples:.0e} samples (at \
             most {MAX_CURVE_SAMPLES:e}); use a larger spacing or a shorter curve"
        ));
    }
    Ok(())
}

/// Whether `v` is a coordinate inkwarp accepts (finite, |v| ≤ [`MAX_COORD_PX`]).
pub fn coordinate_ok(v: f64) -> bool { v.is_finite() && v.abs() <= MAX_COORD_PX }

/// The nodes of the grid a `width × height` picture is solved on at `grid_step`: every
/// `grid_step`-th pixel each way, the last row and column included.
pub fn solver_nodes(width: usize, height: usize, grid_step: usize) -> u64 {
    let n = |p: usize| (p.saturating_sub(1).div_ceil(grid_step.max(1)) + 1) as u64;
    n(width).saturating_mul(n(height))
}

/// The rough peak memory, in bytes, of rendering a `width × height` frame with `layers`,
/// each given by its size and its `grid_step` (see [`RENDER_BYTES_PER_PIXEL`]), without
/// the layers' thin parts and slow modes ([`thin_and_slow_bytes`] of their solver grids).
pub fn render_bytes(width: usize, height: usize, layers: impl IntoIterator<Item = ([usize; 2], usize)>) -> u64 {
    let pixels = |w: usize, h: usize| (w as u64).saturating_mul(h as u64);
    layers.into_iter().fold(pixels(width, height).saturating_mul(RENDER_BYTES_PER_PIXEL), |sum, ([w, h], step)| {
        let solver = solver_nodes(w, h, step).saturating_mul(SOLVER_BYTES_PER_NODE);
        sum.saturating_add(pixels(w, h).saturating_mul(LAYER_BYTES_PER_PIXEL)).saturating_add(solver)
    })
}

/// `bytes` as a short figure in GiB, such as "9.4".
pub fn gib(bytes: u64) -> String { format!("{:.1}", bytes as f64 / (1u64 << 30) as f64) }

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_in_range_pass_and_others_say_why() {
        assert!(check_size("x", MAX_SIDE_PX, 1).is_ok());
        assert!(check_size("x", 8192, 8192).is_ok());
        assert!(check_size("x", 12_000, 12_000).unwrap_err().contains("megapixels"));
        assert!(check_size("x", 10_000, 10_000).unwrap_err().contains("megapixels"));
        assert!(check_size("x", usize::MAX, usize::MAX).is_err());
        assert!(check_size("x", 1 << 62, 4).unwrap_err().contains("at most"));
    }

    #[test]
    fn coordinates() {
        assert!(coordinate_ok(-MAX_COORD_PX) && coordinate_ok(0.5));
        assert!(!coordinate_ok(1e308) && !coordinate_ok(f64::NAN) && !coordinate_ok(2f64.powi(64)));
    }

    #[test]
    fn thin_parts_add_their_factors_and_torn_grids_their_slow_modes() {
        use crate::grid::Grid;
        // A bar 40 wide and 30 tall with ten teeth 1 px wide and 20 long below it.
        let (w, h) = (40, 60);
        let comb = Grid::from_active(w, h, (0..w * h).map(|i| i / w < 30 || (i % w % 4 == 0 && i / w < 50)).collect());
        let (teeth, nodes) = (200, (w * h) as u64);
        assert_eq!(comb.thin_nodes(16), teeth);
        let kept = teeth as u64 * THIN_BYTES_PER_NODE + nodes * CHECKED_BYTES_PER_NODE;
        let comb_bytes = kept + nodes * DEFLATION_BYTES_PER_NODE;
        assert_eq!(thin_and_slow_bytes([&comb]), comb_bytes);
        assert_eq!(thin_and_slow_bytes([&Grid::new(w, h)]), 0);
        // An open strip 10 nodes tall is thin throughout, with nothing torn.
        assert_eq!(thin_and_slow_bytes([&Grid::new(1000, 10)]), 10_000 * THIN_BYTES_PER_NODE);
        // Every grid's factors and kept modes; one solve's deflated modes (the largest), at most the budget.
        assert_eq!(thin_and_slow_bytes([&comb, &comb, &Grid::new(w, h)]), comb_bytes + kept);
        let big = Grid::from_active(2000, 1500, (0..3_000_000).map(|i| i != 0).collect());
        assert_eq!(thin_and_slow_bytes([&big, &comb]), DEFLATION_MAX_BYTES + 3_000_000 * CHECKED_BYTES_PER_NODE + kept);
    }

    #[test]
    fn memory_estimate_saturates() {
        assert_eq!(render_bytes(1, 1, [([1, 1], 1)]), RENDER_BYTES_PER_PIXEL + LAYER_BYTES_PER_PIXEL + SOLVER_BYTES_PER_NODE);
        // A 65 x 65 layer at grid step 4 keeps a solver of 17 x 17 nodes.
        let solver = render_bytes(65, 65, [([65, 65], 1)]) - render_bytes(65, 65, [([65, 65], 4)]);
        assert_eq!(solver, (65 * 65 - 17 * 17) * SOLVER_BYTES_PER_NODE);
        assert_eq!(render_bytes(usize::MAX, usize::MAX, [([usize::MAX, 2], 3)]), u64::MAX);
    }
}

//! TEMPORARY stand-ins (copied) until the core's real geometry/solve/render land.
//! Minimal stand-ins for interfaces that other modules provide (`anim`, `geometry`
//! sampling, `Grid::add_cut`, `solve`, `render`), with the same signatures. They keep the
//! scene engine compiling and testable until the real implementations land; the engine
//! imports everything it needs from other modules through this file only.
#![allow(dead_code)]

use inkwarp_core::{Field, Grid, Kind, Point, Sample};

// ---- anim -------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Interpolation {
    #[default]
    Smooth,
    Linear,
    Hold,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Key {
    pub t: f64,
    pub points: Vec<Point>,
    pub interpolation: Interpolation,
}

/// The control points at time `t` (hold before the first and after the last key).
pub fn points_at(rest: &[Point], keys: &[Key], t: f64) -> Vec<Point> {
    if keys.is_empty() {
        return rest.to_vec();
    }
    if t <= keys[0].t {
        return keys[0].points.clone();
    }
    let last = keys.len() - 1;
    if t >= keys[last].t {
        return keys[last].points.clone();
    }
    let i = keys.iter().rposition(|k| k.t <= t).unwrap();
    let (a, b) = (&keys[i], &keys[i + 1]);
    let u = (t - a.t) / (b.t - a.t);
    match a.interpolation {
        Interpolation::Hold => a.points.clone(),
        Interpolation::Linear => lerp_points(&a.points, &b.points, u),
        Interpolation::Smooth => {
            let p0 = if i > 0 { &keys[i - 1] } else { a };
            let p3 = if i + 2 <= last { &keys[i + 2] } else { b };
            let (t0, t1, t2, t3) = (p0.t, a.t, b.t, p3.t);
            (0..a.points.len())
                .map(|j| {
                    let mut out = [0.0; 2];
                    for c in 0..2 {
                        let (y0, y1, y2, y3) =
                            (p0.points[j][c], a.points[j][c], b.points[j][c], p3.points[j][c]);
                        let m1 = if t2 > t0 { (y2 - y0) / (t2 - t0) } else { 0.0 } * (t2 - t1);
                        let m2 = if t3 > t1 { (y3 - y1) / (t3 - t1) } else { 0.0 } * (t2 - t1);
                        let (u2, u3) = (u * u, u * u * u);
                        out[c] = (2.0 * u3 - 3.0 * u2 + 1.0) * y1
                            + (u3 - 2.0 * u2 + u) * m1
                            + (-2.0 * u3 + 3.0 * u2) * y2
                            + (u3 - u2) * m2;
                    }
                    out
                })
                .collect()
        }
    }
}

fn lerp_points(a: &[Point], b: &[Point], u: f64) -> Vec<Point> {
    a.iter()
        .zip(b)
        .map(|(p, q)| [p[0] + (q[0] - p[0]) * u, p[1] + (q[1] - p[1]) * u])
        .collect()
}

// ---- grid -------------------------------------------------------------------------------

/// Breaks every link whose segment crosses a segment of `polyline`.
pub fn add_cut(grid: &mut Grid, polyline: &[Point]) {
    fn cross(a: Point, b: Point, c: Point, d: Point) -> bool {
        let o = |p: Point, q: Point, r: Point| (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
        let (d1, d2) = (o(a, b, c), o(a, b, d));
        let (d3, d4) = (o(c, d, a), o(c, d, b));
        d1 * d2 <= 0.0 && d3 * d4 <= 0.0 && !(d1 == 0.0 && d2 == 0.0)
    }
    for seg in polyline.windows(2) {
        let (a, b) = (seg[0], seg[1]);
        let x0 = (a[0].min(b[0]).floor() as isize - 1).max(0) as usize;
        let y0 = (a[1].min(b[1]).floor() as isize - 1).max(0) as usize;
        let x1 = ((a[0].max(b[0]).ceil() as isize + 1).max(0) as usize).min(grid.width.saturating_sub(1));
        let y1 = ((a[1].max(b[1]).ceil() as isize + 1).max(0) as usize).min(grid.height.saturating_sub(1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let i = grid.index(x, y);
                let p = [x as f64, y as f64];
                if grid.link_right[i] && cross(a, b, p, [p[0] + 1.0, p[1]]) {
                    grid.link_right[i] = false;
                }
                if grid.link_down[i] && cross(a, b, p, [p[0], p[1] + 1.0]) {
                    grid.link_down[i] = false;
                }
            }
        }
    }
}

// ---- solve ------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolveMethod {
    Multigrid,
    Southwell,
}

#[derive(Clone, Debug)]
pub struct SolveOptions {
    pub tension: f64,
    pub tolerance_px: f64,
    pub grid_step: usize,
    pub max_cycles: Option<usize>,
    pub method: SolveMethod,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            tension: 0.0,
            tolerance_px: 0.01,
            grid_step: 1,
            max_cycles: None,
            method: SolveMethod::Multigrid,
        }
    }
}

#[derive(Clone, Debug, Default)]
pub struct SolveReport {
    pub cycles: usize,
    pub final_change_px: f64,
    pub residual: f64,
    pub constrained_nodes: usize,
    pub constrained_samples: usize,
    pub dropped_samples: usize,
    pub seconds: f64,
    pub converged: bool,
}

#[derive(Debug)]
pub struct SolveError(pub String);
impl std::fmt::Display for SolveError { fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result { f.write_str(&self.0) } }

/// Stand-in: Gauss-Seidel on the membrane (harmonic) problem over the links.
pub fn solve(
    grid: &Grid,
    samples: &[Sample],
    options: &SolveOptions,
    initial: Option<&Field>,
) -> Result<(Field, SolveReport), SolveError> {
    let (w, h) = (grid.width, grid.height);
    let n = w * h;
    let mut sum = vec![[0.0f64; 3]; n];
    let mut report = SolveReport::default();
    for s in samples {
        let (x, y) = (s.rest[0].round(), s.rest[1].round());
        if x < 0.0 || y < 0.0 || x >= w as f64 || y >= h as f64 {
            report.dropped_samples += 1;
            continue;
        }
        let i = grid.index(x as usize, y as usize);
        if !grid.active[i] {
            report.dropped_samples += 1;
            continue;
        }
        sum[i][0] += s.displacement[0];
        sum[i][1] += s.displacement[1];
        sum[i][2] += 1.0;
        report.constrained_samples += 1;
    }
    let mut field = match initial {
        Some(f) => f.clone(),
        None => Field::zeros(w, h),
    };
    let fixed: Vec<bool> = sum.iter().map(|s| s[2] > 0.0).collect();
    report.constrained_nodes = fixed.iter().filter(|&&f| f).count();
    for i in 0..n {
        if fixed[i] {
            field.dx[i] = (sum[i][0] / sum[i][2]) as f32;
            field.dy[i] = (sum[i][1] / sum[i][2]) as f32;
        }
    }
    let max_cycles = options.max_cycles.unwrap_or(300);
    loop {
        let mut change = 0.0f64;
        for y in 0..h {
            for x in 0..w {
                let i = grid.index(x, y);
                if fixed[i] || !grid.active[i] {
                    continue;
                }
                let mut acc = [0.0f64; 2];
                let mut count = 0.0;
                let mut add = |j: usize| {
                    acc[0] += field.dx[j] as f64;
                    acc[1] += field.dy[j] as f64;
                    count += 1.0;
                };
                if grid.link_right[i] {
                    add(i + 1);
                }
                if x > 0 && grid.link_right[i - 1] {
                    add(i - 1);
                }
                if grid.link_down[i] {
                    add(i + w);
                }
                if y > 0 && grid.link_down[i - w] {
                    add(i - w);
                }
                if count > 0.0 {
                    let (nx, ny) = ((acc[0] / count) as f32, (acc[1] / count) as f32);
                    change = change.max((nx - field.dx[i]).abs().max((ny - field.dy[i]).abs()) as f64);
                    field.dx[i] = nx;
                    field.dy[i] = ny;
                }
            }
        }
        report.cycles += 1;
        report.final_change_px = change;
        if change < options.tolerance_px * 0.01 || report.cycles >= max_cycles {
            report.converged = change < options.tolerance_px * 0.01;
            break;
        }
    }
    Ok((field, report))
}

// ---- render -----------------------------------------------------------------------------

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbaImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

#[derive(Clone, Debug)]
pub struct Canvas {
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl Canvas {
    pub fn new(width: usize, height: usize, background: [u8; 4]) -> Self {
        let a = background[3] as f32 / 255.0;
        let px = [
            background[0] as f32 / 255.0 * a,
            background[1] as f32 / 255.0 * a,
            background[2] as f32 / 255.0 * a,
            a,
        ];
        Canvas { width, height, data: px.repeat(width * height) }
    }

    /// Stand-in: splats every pixel to its nearest displaced position.
    pub fn draw_layer(&mut self, image: &RgbaImage, field: &Field, grid: &Grid, offset: [f64; 2]) {
        let _ = grid;
        for y in 0..image.height {
            for x in 0..image.width {
                let i = y * image.width + x;
                let tx = (x as f64 + field.dx[i] as f64 + offset[0]).round();
                let ty = (y as f64 + field.dy[i] as f64 + offset[1]).round();
                if tx < 0.0 || ty < 0.0 || tx >= self.width as f64 || ty >= self.height as f64 {
                    continue;
                }
                let j = (ty as usize * self.width + tx as usize) * 4;
                let s = &image.data[i * 4..i * 4 + 4];
                let a = s[3] as f32 / 255.0;
                for c in 0..3 {
                    self.data[j + c] = s[c] as f32 / 255.0 * a + self.data[j + c] * (1.0 - a);
                }
                self.data[j + 3] = a + self.data[j + 3] * (1.0 - a);
            }
        }
    }

    pub fn to_rgba8(&self) -> RgbaImage {
        let mut data = Vec::with_capacity(self.data.len());
        for px in self.data.chunks_exact(4) {
            let a = px[3];
            for c in 0..3 {
                let v = if a > 0.0 { px[c] / a } else { 0.0 };
                data.push((v * 255.0).round().clamp(0.0, 255.0) as u8);
            }
            data.push((a * 255.0).round().clamp(0.0, 255.0) as u8);
        }
        RgbaImage { width: self.width, height: self.height, data }
    }
}

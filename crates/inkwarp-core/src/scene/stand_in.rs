//! The interfaces the scene engine uses from the other modules, in one place. Cuts on the
//! grid and the solver are minimal stand-ins with the same signatures until those modules
//! land (the real `Grid::add_cut` and `solve::solve`).
#![allow(dead_code)]

pub use crate::anim::{points_at, Interpolation, Key};
pub use crate::geometry::{curve_polyline, FeatureSampler, SampleOptions};
pub use crate::render::{Canvas, RgbaImage};

use crate::field::Field;
use crate::geometry::{Point, Sample};
use crate::grid::Grid;

// ---- grid -------------------------------------------------------------------------------

/// Breaks every link whose segment crosses a segment of `polyline`.
pub fn add_cut(grid: &mut Grid, polyline: &[Point]) {
    fn cross(a: Point, b: Point, c: Point, d: Point) -> bool {
        let o = |p: Point, q: Point, r: Point| {
            (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
        };
        let (d1, d2) = (o(a, b, c), o(a, b, d));
        let (d3, d4) = (o(c, d, a), o(c, d, b));
        d1 * d2 <= 0.0 && d3 * d4 <= 0.0 && !(d1 == 0.0 && d2 == 0.0)
    }
    for seg in polyline.windows(2) {
        let (a, b) = (seg[0], seg[1]);
        let x0 = (a[0].min(b[0]).floor() as isize - 1).max(0) as usize;
        let y0 = (a[1].min(b[1]).floor() as isize - 1).max(0) as usize;
        let x1 = ((a[0].max(b[0]).ceil() as isize + 1).max(0) as usize)
            .min(grid.width.saturating_sub(1));
        let y1 = ((a[1].max(b[1]).ceil() as isize + 1).max(0) as usize)
            .min(grid.height.saturating_sub(1));
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

#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct SolveError(pub String);

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
    let max_cycles = options.max_cycles.unwrap_or(20_000);
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
                    change =
                        change.max((nx - field.dx[i]).abs().max((ny - field.dy[i]).abs()) as f64);
                    field.dx[i] = nx;
                    field.dy[i] = ny;
                }
            }
        }
        report.cycles += 1;
        report.final_change_px = change;
        if change < 1e-6 || report.cycles >= max_cycles {
            report.converged = change < 1e-6;
            break;
        }
    }
    Ok((field, report))
}

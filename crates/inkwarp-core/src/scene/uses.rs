//! The interfaces the scene engine uses from the other modules, gathered in one place.

pub use crate::anim::{points_at, Interpolation, Key};
pub use crate::geometry::{curve_polyline, FeatureSampler, SampleOptions};
pub use crate::render::{Canvas, RgbaImage};
pub use crate::solve::{solve, SolveMethod, SolveOptions, SolveReport};

use crate::geometry::Point;
use crate::grid::Grid;

/// Breaks every link whose segment crosses a segment of `polyline`.
pub fn add_cut(grid: &mut Grid, polyline: &[Point]) {
    grid.add_cut(polyline);
}

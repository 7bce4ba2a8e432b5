//! An interrupt request stops a solve, and a drawing, with its error. A process of its own
//! (and one test: the flag is global, and would stop the work of tests running beside it).

use inkwarp_core::render::{try_warp_image, RenderError, RgbaImage};
use inkwarp_core::solve::{solve, SolveError, SolveOptions, Solver};
use inkwarp_core::{Grid, Sample};

#[test]
fn an_interrupt_stops_the_solve_with_its_error() {
    let grid = Grid::new(65, 65);
    let samples: Vec<Sample> =
        (0..10).map(|k| Sample { rest: [(k * 6) as f64, (k * 5 % 64) as f64], displacement: [k as f64, 1.0] }).collect();
    inkwarp_core::interrupt::request();
    let result = solve(&grid, &samples, &SolveOptions::default(), None);
    inkwarp_core::interrupt::clear();
    assert_eq!(result.unwrap_err(), SolveError::Interrupted);
    let (field, report) = solve(&grid, &samples, &SolveOptions::default(), None).unwrap();
    assert!(report.converged);
    // An animation's frame cut short is no start for the next (from a partial answer the
    // next frame claimed convergence after one cycle, 0.63 px off).
    let mut frames = Solver::new();
    assert!(frames.solve_frame(&grid, &samples, &SolveOptions::default()).unwrap().1.converged);
    inkwarp_core::interrupt::request();
    let cut_short = frames.solve_frame(&grid, &samples, &SolveOptions::default());
    inkwarp_core::interrupt::clear();
    assert_eq!(cut_short.unwrap_err(), SolveError::Interrupted);
    assert!(frames.history().is_empty());
    // A drawing cut short is refused, never handed on as a whole picture.
    let image = RgbaImage::from_raw(65, 65, vec![200; 65 * 65 * 4]).unwrap();
    inkwarp_core::interrupt::request();
    let drawn = try_warp_image(&image, &field, &grid);
    inkwarp_core::interrupt::clear();
    assert_eq!(drawn.unwrap_err(), RenderError::Interrupted);
    assert!(try_warp_image(&image, &field, &grid).unwrap().data.iter().any(|&v| v != 0));
}

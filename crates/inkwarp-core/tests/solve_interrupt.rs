//! An interrupt request stops a solve with its error. A process of its own: the flag is
//! global, and would stop the unit tests' solves running beside it.

use inkwarp_core::solve::{solve, SolveError, SolveOptions};
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
    let (_, report) = solve(&grid, &samples, &SolveOptions::default(), None).unwrap();
    assert!(report.converged);
}

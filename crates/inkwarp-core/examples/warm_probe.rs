//! Development probe of a warm solve: after each cycle, its largest change and the true
//! largest error against a tight solve (513², random points, displacements nudged 2 %).
use inkwarp_core::field::FieldView;
use inkwarp_core::solve::{SolveOptions, Solver};
use inkwarp_core::{Field, Grid, Sample};

mod common;

fn gap(a: &Field, b: &Field) -> f64 {
    a.dx.iter().zip(&b.dx).chain(a.dy.iter().zip(&b.dy)).map(|(p, q)| (p - q).abs() as f64).fold(0.0, f64::max)
}

fn main() {
    let count: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    let n = 513;
    let grid = Grid::new(n, n);
    let samples = common::random_samples(count, n, n, 12345);
    let nudged: Vec<Sample> = samples.iter().map(|s| Sample { rest: s.rest, displacement: [s.displacement[0] * 1.02, s.displacement[1] * 1.02] }).collect();
    let mut solver = Solver::new();
    let (field, _) = solver.solve(&grid, &samples, &SolveOptions::default(), None).unwrap();
    let tight = SolveOptions { tolerance_px: 1e-7, max_cycles: Some(300), ..Default::default() };
    let (exact, _) = solver.solve(&grid, &nudged, &tight, None).unwrap();
    println!("start error {:.5}", gap(&field, &exact));
    for c in 1..=6 {
        let o = SolveOptions { max_cycles: Some(c), tolerance_px: 0.0, ..Default::default() };
        let (f, rep) = solver.solve(&grid, &nudged, &o, Some(FieldView::from(&field))).unwrap();
        println!("cycles {c} change {:.5} error {:.5}", rep.final_change_px, gap(&f, &exact));
    }
    let (f, rep) = solver.solve(&grid, &nudged, &SolveOptions::default(), Some(FieldView::from(&field))).unwrap();
    println!("default: cycles {} change {:.5} error {:.5}", rep.cycles, rep.final_change_px, gap(&f, &exact));
}

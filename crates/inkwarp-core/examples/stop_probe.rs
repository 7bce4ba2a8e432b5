//! Development probe of the stopping rule: per cycle, the largest change and the true
//! largest error against a tight solve, for several grids.
use inkwarp_core::solve::{solve, SolveOptions};
use inkwarp_core::{Field, Grid};

mod common;

fn gap(a: &Field, b: &Field) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..a.dx.len() {
        m = m.max((a.dx[i] - b.dx[i]).abs() as f64).max((a.dy[i] - b.dy[i]).abs() as f64);
    }
    m
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args[1].parse().unwrap();
    let count: usize = args[2].parse().unwrap();
    let mode = args.get(3).cloned().unwrap_or_default();
    let seed: u64 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(12345);
    let samples = common::random_samples(count, size, size, seed);
    let mut grid = Grid::new(size, size);
    if mode == "ring" || mode == "both" {
        let c = size as f64 / 2.0;
        let active: Vec<bool> = (0..size * size)
            .map(|i| {
                let (x, y) = ((i % size) as f64, (i / size) as f64);
                let r = ((x - c).powi(2) + (y - c).powi(2)).sqrt();
                !((r - size as f64 * 0.3).abs() < 1.5 && x < c + 20.0)
            })
            .collect();
        grid = Grid::from_active(size, size, active);
    }
    if mode == "cut" || mode == "both" {
        grid.add_cut(&[[size as f64 * 0.1, size as f64 * 0.8], [size as f64 * 0.5, size as f64 * 0.85]]);
    }
    let tight = SolveOptions { tolerance_px: 1e-7, max_cycles: Some(400), ..Default::default() };
    let exact = solve(&grid, &samples, &tight, None).unwrap().0;
    let (_, rep) = solve(&grid, &samples, &SolveOptions::default(), None).unwrap();

    print!("{size} N={count} {mode} seed={seed}: default {} cycles |", rep.cycles);
    for k in 0..=rep.cycles + 4 {
        let (f, r) = solve(&grid, &samples, &SolveOptions { tolerance_px: 0.0, max_cycles: Some(k), ..Default::default() }, None).unwrap();
        print!(" {k}:{:.4}/{:.4}", r.final_change_px, gap(&f, &exact));
    }
    println!();
}

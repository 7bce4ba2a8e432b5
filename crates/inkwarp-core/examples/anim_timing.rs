//! Development timing of an animation's solves started from earlier frames:
//! `cargo run --release -p inkwarp-core --example anim_timing -- 513 10` prints the median
//! per-frame solve of a smooth motion of N random points (each displacement swinging by
//! ±10 %), as `benchmarks/solve.py` measures its "animated" column.

use std::time::Instant;

mod common;

use inkwarp_core::solve::{SolveOptions, Solver};
use inkwarp_core::{Grid, Sample};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(513);
    let count: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(10);
    let frames: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(24);
    let mut rnd = common::rng(12345);
    let base: Vec<(Sample, f64)> = (0..count)
        .map(|_| {
            let s = Sample {
                rest: [rnd() * (size - 1) as f64, rnd() * (size - 1) as f64],
                displacement: [rnd() * 40.0 - 20.0, rnd() * 40.0 - 20.0],
            };
            (s, rnd() * std::f64::consts::TAU)
        })
        .collect();
    let grid = Grid::new(size, size);
    let opts = SolveOptions::default();
    let mut solver = Solver::new();
    let mut times = Vec::new();
    let mut cycles = Vec::new();
    for f in 0..frames {
        let samples: Vec<Sample> = base
            .iter()
            .map(|(s, phase)| {
                let k = 1.0 + 0.1 * (0.3 * f as f64 + phase).sin();
                Sample { rest: s.rest, displacement: [s.displacement[0] * k, s.displacement[1] * k] }
            })
            .collect();
        let t = Instant::now();
        let (_, report) = solver.solve_warm(&grid, &samples, &opts, None).unwrap();
        times.push(t.elapsed().as_secs_f64());
        cycles.push(report.cycles);
    }
    let mut steady = times[3..].to_vec();
    steady.sort_by(f64::total_cmp);
    println!(
        "{size}x{size} N={count}: median {:.1} ms per frame, cycles {:?}",
        steady[steady.len() / 2] * 1e3,
        &cycles[3..]
    );
}

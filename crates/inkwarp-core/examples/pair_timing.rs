//! One round of the two-build comparison of `benchmarks/pair_builds.py`: for mechanisms
//! that cannot be a runtime switch, the same problems are timed by a build with the
//! mechanism and one without, in alternating rounds. Prints one line per problem,
//! `name seconds cycles`, each the fastest of `REPS` solves (default 3).
//!
//! The problems, all 513 × 513: 10 and 4000 random points and the model problem
//! with a disc hole and a two-segment cut (10 points), each `cold` (a new `Solver`: the
//! hierarchy is built in the call), `kept` (the same call with the hierarchy kept) and
//! `warm` (a kept `Solver`, started from the previous answer with every displacement
//! changed by 2 %). `cargo run --release -p inkwarp-core --example pair_timing`.

use std::time::Instant;

use inkwarp_core::field::FieldView;
use inkwarp_core::solve::{SolveOptions, Solver};
use inkwarp_core::{Grid, Sample};

mod common;

/// The Python module's staggering of large blocks, over the system's allocator here (which copies where mimalloc
/// resizes in place).
#[global_allocator]
static ALLOCATOR: inkwarp_core::alloc::Staggered<std::alloc::System> = inkwarp_core::alloc::Staggered(std::alloc::System);

fn problem(name: &str, n: usize) -> (Grid, Vec<Sample>) {
    match name {
        "hole+cut" => {
            let s = n as f64 / 2049.0;
            let (cx, cy, r) = (1300.0 * s, 800.0 * s, 150.0 * s);
            let active = (0..n * n).map(|i| ((i % n) as f64 - cx).powi(2) + ((i / n) as f64 - cy).powi(2) > r * r).collect();
            let mut grid = Grid::from_active(n, n, active);
            grid.add_cut(&[[200.0 * s, 1400.3 * s], [900.0 * s, 1250.3 * s], [1600.0 * s, 1500.3 * s]]);
            let mut samples = common::random_samples(10, n, n, 2049);
            for smp in &mut samples {
                smp.displacement = [smp.displacement[0] * 0.25, smp.displacement[1] * 0.25];
            }
            (grid, samples)
        }
        _ => {
            let count = name.parse().unwrap();
            (Grid::new(n, n), common::random_samples(count, n, n, 12345))
        }
    }
}

fn main() {
    let n = 513;
    let reps: usize = std::env::var("REPS").ok().and_then(|v| v.parse().ok()).unwrap_or(3);
    let opts = SolveOptions::default();
    for name in ["10", "4000", "hole+cut"] {
        let (grid, samples) = problem(name, n);
        let nudged: Vec<Sample> =
            samples.iter().map(|s| Sample { rest: s.rest, displacement: [s.displacement[0] * 1.02, s.displacement[1] * 1.02] }).collect();
        let mut best = [(f64::INFINITY, 0usize); 3];
        for _ in 0..reps {
            let mut solver = Solver::new();
            let t = Instant::now();
            let (_, rep) = solver.solve(&grid, &samples, &opts, None).unwrap();
            let cold = (t.elapsed().as_secs_f64(), rep.cycles);
            let t = Instant::now();
            let (field, rep) = solver.solve(&grid, &samples, &opts, None).unwrap();
            let kept = (t.elapsed().as_secs_f64(), rep.cycles);
            let t = Instant::now();
            let (_, rep) = solver.solve(&grid, &nudged, &opts, Some(FieldView::from(&field))).unwrap();
            let warm = (t.elapsed().as_secs_f64(), rep.cycles);
            for (b, v) in best.iter_mut().zip([cold, kept, warm]) {
                if v.0 < b.0 {
                    *b = v;
                }
            }
        }
        for (kind, (s, c)) in ["cold", "kept", "warm"].iter().zip(best) {
            println!("{name}/{kind} {s:.6} {c}");
        }
    }
}

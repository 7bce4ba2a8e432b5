//! Cycles and time of the model problems (10 seeded points; a disc hole of radius
//! 150 s at (1300 s, 800 s); a two-segment cut through (200, 1400.3), (900, 1250.3),
//! (1600, 1500.3), times s = n / 2049) at the sizes given (default 257 513 1025).
use inkwarp_core::solve::{solve, SolveOptions};
use inkwarp_core::{Grid, Sample};

mod common;

fn main() {
    let mut sizes: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    if sizes.is_empty() {
        sizes = vec![257, 513, 1025];
    }
    let only = std::env::var("PROBLEM").ok();
    for (name, hole, cut) in [("open", false, false), ("hole", true, false), ("cut", false, true), ("hole+cut", true, true)] {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        print!("{name:9}");
        for &n in &sizes {
            let s = n as f64 / 2049.0;
            let mut grid = if hole {
                let active = (0..n * n)
                    .map(|i| {
                        let (x, y) = ((i % n) as f64, (i / n) as f64);
                        (x - 1300.0 * s).hypot(y - 800.0 * s) > 150.0 * s
                    })
                    .collect();
                Grid::from_active(n, n, active)
            } else {
                Grid::new(n, n)
            };
            if cut {
                grid.add_cut(&[[200.0 * s, 1400.3 * s], [900.0 * s, 1250.3 * s], [1600.0 * s, 1500.3 * s]]);
            }
            let samples: Vec<Sample> = common::random_samples(10, n, n, 2049)
                .into_iter()
                .map(|p| Sample { rest: p.rest, displacement: [p.displacement[0] * n as f64 / 100.0, p.displacement[1] * n as f64 / 100.0] })
                .collect();
            let t = std::time::Instant::now();
            let (_, r) = solve(&grid, &samples, &SolveOptions::default(), None).unwrap();
            print!(" | {n}: {:3}{} {:7.3}s", r.cycles, if r.converged { " " } else { "!" }, t.elapsed().as_secs_f64());
        }
        println!();
    }
}

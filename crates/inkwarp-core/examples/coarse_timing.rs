//! Development timing of the `grid_step` path (solve every s-th node, upsample to every
//! pixel), the path the editor takes while a point is dragged. The project's benchmarks live
//! in `benchmarks/`.
//!
//! `cargo run --release -p inkwarp-core --example coarse_timing -- 513 8`
//!
//! Prints, for an open grid, a grid with a cut and a grid with holes and a cut: the whole
//! solve (cold, then warm from the previous answer as a drag does), the same-size coarse
//! problem solved on its own, and the fine grid's piece labelling — so that the upsampling's
//! share is the difference. `RUNS` (default 20) sets the repetitions; the minimum is shown.

use std::time::Instant;

use inkwarp_core::solve::{solve, SolveOptions};
use inkwarp_core::{Grid, Sample};

fn best_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..runs {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    best
}

/// About a dozen features' worth of samples: curves across the picture and a few points.
fn drawing(size: usize) -> Vec<Sample> {
    let n = size as f64 - 1.0;
    let mut samples = Vec::new();
    let mut curve = |x0: f64, y0: f64, x1: f64, y1: f64, d: [f64; 2]| {
        let len = ((x1 - x0).hypot(y1 - y0)).ceil() as usize;
        for k in 0..=len {
            let t = k as f64 / len.max(1) as f64;
            let bend = (std::f64::consts::PI * t).sin();
            samples.push(Sample { rest: [x0 + (x1 - x0) * t, y0 + (y1 - y0) * t], displacement: [d[0] * bend, d[1] * bend] });
        }
    };
    for k in 0..8 {
        let y = n * (0.1 + 0.1 * k as f64);
        curve(n * 0.1, y, n * 0.45, y + n * 0.05, [6.0 - k as f64, 3.0]);
    }
    curve(n * 0.7, n * 0.2, n * 0.7, n * 0.8, [-8.0, 0.0]);
    for (x, y) in [(0.05, 0.05), (0.95, 0.05), (0.05, 0.95), (0.95, 0.95)] {
        samples.push(Sample { rest: [n * x, n * y], displacement: [0.0, 0.0] });
    }
    samples
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(513);
    let step: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(8);
    let runs: usize = std::env::var("RUNS").ok().and_then(|v| v.parse().ok()).unwrap_or(20);
    let n = size as f64 - 1.0;
    let samples = drawing(size);

    let open = Grid::new(size, size);
    let mut cut = Grid::new(size, size);
    cut.add_cut(&[[n * 0.6 + 0.5, n * 0.15], [n * 0.6 + 0.5, n * 0.85]]);
    let mut matte = vec![255u8; size * size];
    for y in 0..size {
        for x in 0..size {
            let (u, v) = (x as f64 / n - 0.55, y as f64 / n - 0.5);
            // a round hole, a thin slot and a ring: pieces smaller than a coarse cell
            let r = u.hypot(v);
            if r < 0.06 || (v.abs() < 0.004 && u > 0.1 && u < 0.35) || (r > 0.3 && r < 0.31) {
                matte[y * size + x] = 0;
            }
        }
    }
    let mut holes = Grid::from_matte(size, size, &matte);
    holes.add_cut(&[[n * 0.6 + 0.5, n * 0.15], [n * 0.6 + 0.5, n * 0.85]]);

    let coarse_size = (size - 1).div_ceil(step) + 1;
    let coarse = Grid::new(coarse_size, coarse_size);
    let coarse_samples: Vec<Sample> = samples
        .iter()
        .map(|s| Sample { rest: [s.rest[0] / step as f64, s.rest[1] / step as f64], displacement: s.displacement })
        .collect();
    let base = SolveOptions::default();
    let coarse_ms = best_ms(runs, || {
        solve(&coarse, &coarse_samples, &base, None).unwrap();
    });
    println!(
        "{size}×{size}, grid_step {step} ({coarse_size}×{coarse_size} coarse), {} samples; best of {runs}; {} threads",
        samples.len(),
        rayon::current_num_threads()
    );
    println!("  the {coarse_size}×{coarse_size} solve alone (open grid, cold): {coarse_ms:.2} ms");
    let opts = SolveOptions { grid_step: step, ..SolveOptions::default() };
    for (name, grid) in [("open", &open), ("cut", &cut), ("holes+cut", &holes)] {
        let pieces_ms = best_ms(runs, || {
            std::hint::black_box(grid.pieces());
        });
        let cold_ms = best_ms(runs, || {
            solve(grid, &samples, &opts, None).unwrap();
        });
        let (field, _) = solve(grid, &samples, &opts, None).unwrap();
        let nudged: Vec<Sample> = samples
            .iter()
            .map(|s| Sample { rest: s.rest, displacement: [s.displacement[0] * 1.01 + 0.2, s.displacement[1]] })
            .collect();
        let warm_ms = best_ms(runs, || {
            solve(grid, &nudged, &opts, Some(&field)).unwrap();
        });
        let checksum: f64 = field.dx.iter().chain(&field.dy).map(|&v| v as f64).sum();
        println!(
            "  {name:>9}: solve cold {cold_ms:6.2} ms, warm {warm_ms:6.2} ms; fine pieces() {pieces_ms:5.2} ms; checksum {checksum:.6}"
        );
    }
}

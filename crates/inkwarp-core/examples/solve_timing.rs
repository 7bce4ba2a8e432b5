//! Development timing of the thin-plate solve (the project's benchmarks live in
//! `benchmarks/`): `cargo run --release -p inkwarp-core --example solve_timing -- 513 10`.

use std::time::Instant;

use inkwarp_core::solve::{solve, SolveOptions};
use inkwarp_core::{Grid, Sample};

mod common;

/// CPU time of all threads of this process (ns), from /proc: wall time on a shared machine
/// says little.
fn cpu_ns() -> u64 {
    let mut total = 0;
    if let Ok(dir) = std::fs::read_dir("/proc/self/task") {
        for e in dir.flatten() {
            if let Ok(s) = std::fs::read_to_string(e.path().join("schedstat")) {
                total += s.split_whitespace().next().and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
            }
        }
    }
    total
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(513);
    let count: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(10);
    let height: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(size);
    let cycles: Option<usize> = args.get(4).and_then(|s| s.parse().ok());
    let samples = common::random_samples(count, size, height, 12345);
    let grid = Grid::new(size, height);
    let opts = SolveOptions { max_cycles: cycles, tolerance_px: if cycles.is_some() { 0.0 } else { 0.01 }, ..Default::default() };
    let runs: usize = std::env::var("RUNS").ok().and_then(|v| v.parse().ok()).unwrap_or(3);
    let (mut first, mut reuse, mut warm) = (f64::NAN, f64::INFINITY, f64::INFINITY);
    let (mut first_wall, mut reuse_wall, mut warm_wall) = (f64::NAN, f64::INFINITY, f64::INFINITY);
    let (mut cycles, mut warm_cycles) = (0, 0);
    for run in 0..runs {
        let (t, c) = (Instant::now(), cpu_ns());
        let (field, rep) = solve(&grid, &samples, &opts, None).unwrap();
        let (wall, cpu) = (t.elapsed().as_secs_f64(), (cpu_ns() - c) as f64 * 1e-9);
        if run == 0 {
            (first, first_wall, cycles) = (cpu, wall, rep.cycles);
        } else {
            reuse = reuse.min(cpu);
            reuse_wall = reuse_wall.min(wall);
        }
        // warm: from the answer with every displacement nudged by 0.5 %
        let nudged: Vec<Sample> = samples
            .iter()
            .map(|s| Sample { rest: s.rest, displacement: [s.displacement[0] * 1.005, s.displacement[1] * 1.005] })
            .collect();
        let (t, c) = (Instant::now(), cpu_ns());
        let (_, rep2) = solve(&grid, &nudged, &opts, Some(&field)).unwrap();
        warm = warm.min((cpu_ns() - c) as f64 * 1e-9);
        warm_wall = warm_wall.min(t.elapsed().as_secs_f64());
        warm_cycles = rep2.cycles;
    }
    println!(
        "{size}x{height} N={count}: cold first {:.1} ms cpu ({:.1} wall, {cycles} cycles) | cold, hierarchy reused {:.1} ms cpu ({:.1} wall) | warm {:.1} ms cpu ({:.1} wall, {warm_cycles} cycles)",
        first * 1e3, first_wall * 1e3, reuse * 1e3, reuse_wall * 1e3, warm * 1e3, warm_wall * 1e3
    );
}

//! Development probe: three pieces of a small grid (split by a cut and a hole column),
//! solved together and in pairs, with the error against a tight solve after k cycles:
//! `cargo run --release -p inkwarp-core --example strips -- [all|left|mid|pocket|lm|mp|lp]`.
use inkwarp_core::solve::{solve, SolveOptions};
use inkwarp_core::{Grid, Sample};
fn main() {
    let (w, h) = (40usize, 32usize);
    let mut grid = Grid::from_active(w, h, (0..w * h).map(|i| i % w != 30).collect());
    grid.add_cut(&[[19.5, -1.0], [19.5, h as f64 + 1.0]]);
    let pts = [[2.0, 2.0], [15.0, 4.0], [8.0, 28.0], [12.0, 15.0], [22.0, 3.0], [28.0, 27.0], [24.0, 15.0], [34.0, 10.0], [38.0, 20.0], [36.0, 2.0]];
    let disp = [[1.0, 2.0], [-3.0, 1.0], [2.0, 2.0], [5.0, -4.0], [0.5, 0.0], [1.0, 1.0], [0.0, -2.0], [3.0, 1.0], [2.0, 0.0], [1.0, 1.0]];
    let which = std::env::args().nth(1).unwrap_or_default();
    let samples: Vec<Sample> = pts.iter().zip(disp.iter()).enumerate()
        .filter(|(i, (p, _))| match which.as_str() { "left" => *i < 4, "mid" => *i >= 4 && *i < 7, "pocket" => p[0] > 30.0, "lm" => p[0] < 30.0, "mp" => p[0] > 20.0, "lp" => p[0] < 19.0 || p[0] > 30.0, _ => true })
        .map(|(_, (p, d))| Sample { rest: *p, displacement: *d }).collect();
    let exact = solve(&grid, &samples, &SolveOptions { tolerance_px: 1e-9, max_cycles: Some(3000), ..Default::default() }, None).unwrap();
    let (_, rep) = solve(&grid, &samples, &SolveOptions::default(), None).unwrap();
    if std::env::var("COLS").is_ok() { let (f, _) = solve(&grid, &samples, &SolveOptions { tolerance_px: 0.0, max_cycles: Some(10), ..Default::default() }, None).unwrap(); cols(&f, &exact.0); }
    print!("exact {} cycles; default {} cycles |", exact.1.cycles, rep.cycles);
    for k in [5, 10, 20, 40, 60, 80] {
        let (f, r) = solve(&grid, &samples, &SolveOptions { tolerance_px: 0.0, max_cycles: Some(k), ..Default::default() }, None).unwrap();
        let e = f.dx.iter().zip(&exact.0.dx).chain(f.dy.iter().zip(&exact.0.dy)).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        print!(" {k}: {e:.4} ({:.4})", r.final_change_px);
    }
    println!();
}
#[allow(dead_code)]
pub fn cols(a: &inkwarp_core::Field, b: &inkwarp_core::Field) {
    let (w, h) = (a.width, a.height);
    for x in 0..w {
        let mut m: f32 = 0.0;
        let mut v: f32 = 0.0;
        for y in 0..h { let i = y * w + x; m = m.max((a.dx[i] - b.dx[i]).abs()); v = v.max(b.dx[i].abs()); }
        print!("{x}:{m:.2}/{v:.1} ");
    }
    println!();
}

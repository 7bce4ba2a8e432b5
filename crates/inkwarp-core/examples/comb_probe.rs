//! Development probe: cycles of a cold solve on the comb family (teeth 1 or 2 px, 1 px gaps)
//! at a scale: `comb_probe TOOTH SCALE`.
use inkwarp_core::solve::{solve, SolveOptions};
use inkwarp_core::{Grid, Sample};

fn main() {
    let a: Vec<usize> = std::env::args().skip(1).map(|s| s.parse().unwrap()).collect();
    let (tooth, s) = (a[0], a[1]);
    let (h, w, bar) = (40 * s, 64 * s, 6 * s);
    let mut active = vec![false; w * h];
    for y in 2..2 + bar {
        for x in 2..w - 2 {
            active[y * w + x] = true;
        }
    }
    for x0 in (2..w - 2).step_by(tooth + 1) {
        for y in 2 + bar..h - 2 {
            for x in x0..(x0 + tooth).min(w) {
                active[y * w + x] = true;
            }
        }
    }
    let grid = Grid::from_active(w, h, active);
    let mut rest = vec![[5.0, 4.0], [w as f64 / 2.0, 5.0], [w as f64 - 6.0, 3.0]];
    rest.extend((2..w - 2).step_by(tooth + 1).step_by(4 * s).map(|x| [x as f64, h as f64 - 4.0]));
    let samples: Vec<Sample> = rest
        .iter()
        .enumerate()
        .map(|(i, &r)| Sample { rest: r, displacement: [((i * 7919) % 13) as f64 - 6.0, ((i * 104729) % 11) as f64 - 5.0] })
        .collect();
    let opts = SolveOptions { max_cycles: Some(3000), ..Default::default() };
    let t = std::time::Instant::now();
    let (_, rep) = solve(&grid, &samples, &opts, None).unwrap();
    println!("tooth {tooth} {w}x{h}: cycles {} converged {} {:.2} s", rep.cycles, rep.converged, t.elapsed().as_secs_f64());
}

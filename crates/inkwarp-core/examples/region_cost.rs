//! What a region costs to sample on a 512×512 grid: the one-shot `sample_feature`, and a
//! `FeatureSampler` prepared once then sampled per pose (an animation's frames).
//!
//! `cargo run --release -p inkwarp-core --example region_cost` (set `RAYON_NUM_THREADS`
//! to fix the number of threads).

use std::time::{Duration, Instant};

use inkwarp_core::geometry::{sample_feature, Curve, FeatureSampler, Kind, Point, SampleOptions};
use inkwarp_core::Grid;

fn outline(n: usize, radius: f64, wobble: f64) -> Vec<Point> {
    (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            let r = radius + wobble * (5.0 * a).sin();
            [256.0 + r * a.cos(), 256.0 + r * a.sin()]
        })
        .collect()
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn main() {
    let grid = Grid::new(512, 512);
    println!(
        "{:<34} {:>8} {:>8} {:>13} {:>12} {:>12}",
        "region (512×512 grid)", "outline", "interior", "sample_feature", "prepare", "per pose"
    );
    for (name, n, radius, wobble, spline) in [
        ("polyline, 24 points, r≈200", 24, 200.0, 40.0, false),
        ("spline, 24 points, r≈200", 24, 200.0, 40.0, true),
        ("spline, 12 points, r≈100", 12, 100.0, 15.0, true),
        ("spline, 8 points, r≈30", 8, 30.0, 5.0, true),
    ] {
        let rest = outline(n, radius, wobble);
        let pose: Vec<Point> = rest
            .iter()
            .map(|p| {
                [
                    p[0] + 20.0 * (p[1] / 60.0).sin(),
                    p[1] + 15.0 * (p[0] / 45.0).cos(),
                ]
            })
            .collect();
        let opts = SampleOptions {
            closed: true,
            spline_outline: spline,
            spacing_px: 1.0,
        };
        let t = Instant::now();
        let samples = sample_feature(Kind::Region, &rest, &pose, &opts, Some(&grid)).unwrap();
        let one_shot = t.elapsed();
        let t = Instant::now();
        let sampler = FeatureSampler::new(Kind::Region, &rest, &opts, Some(&grid)).unwrap();
        let prepare = t.elapsed();
        let per_pose = median(
            (0..7)
                .map(|_| {
                    let t = Instant::now();
                    std::hint::black_box(sampler.sample(&pose).unwrap());
                    t.elapsed()
                })
                .collect(),
        );
        let outline_len = Curve::new(&rest, true, spline).sample_parameters(1.0).len();
        println!(
            "{:<34} {:>8} {:>8} {:>11.1}ms {:>10.1}ms {:>10.2}ms",
            name,
            outline_len,
            samples.len() - outline_len,
            one_shot.as_secs_f64() * 1e3,
            prepare.as_secs_f64() * 1e3,
            per_pose.as_secs_f64() * 1e3
        );
    }
}

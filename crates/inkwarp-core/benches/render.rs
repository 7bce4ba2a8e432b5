//! Render timings: `cargo bench -p inkwarp-core --bench render` (prints medians; not a test).

use inkwarp_core::render::{Canvas, RgbaImage};
use inkwarp_core::{Field, Grid};
use std::time::Instant;

fn image(w: usize, h: usize) -> RgbaImage {
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let data = (0..w * h * 4)
        .map(|i| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            if i % 4 == 3 {
                255
            } else {
                (s >> 56) as u8
            }
        })
        .collect();
    RgbaImage::from_raw(w, h, data).unwrap()
}

fn field(w: usize, h: usize, f: impl Fn(f64, f64) -> [f64; 2]) -> Field {
    let mut out = Field::zeros(w, h);
    for y in 0..h {
        for x in 0..w {
            let d = f(x as f64, y as f64);
            out.dx[y * w + x] = d[0] as f32;
            out.dy[y * w + x] = d[1] as f32;
        }
    }
    out
}

/// CPU time of the whole process (all threads), in ms, from /proc (Linux; 0 elsewhere).
/// On a shared, loaded machine wall time says little; CPU time says what the work costs.
fn cpu_ms() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let after = &stat[stat.rfind(')').map_or(0, |i| i + 2)..];
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks: f64 = fields.get(11).and_then(|v| v.parse().ok()).unwrap_or(0.0)
        + fields.get(12).and_then(|v| v.parse().ok()).unwrap_or(0.0);
    ticks * 10.0 // USER_HZ is 100 on Linux
}

/// Median and minimum wall time and mean CPU time per call, in ms.
fn time_ms(runs: usize, mut f: impl FnMut()) -> (f64, f64, f64) {
    f();
    let cpu0 = cpu_ms();
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    let cpu = (cpu_ms() - cpu0) / runs as f64;
    t.sort_by(|a, b| a.partial_cmp(b).unwrap());
    (t[runs / 2], t[0], cpu)
}

fn main() {
    println!("threads: {}", rayon::current_num_threads());
    let sizes: &[(usize, usize, usize)] = if std::env::var_os("RENDER_BENCH_QUICK").is_some() {
        &[(512, 512, 21)]
    } else {
        &[(512, 512, 41), (1920, 1080, 11)]
    };
    let runs_override: Option<usize> = std::env::var("RENDER_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok());
    for &(w, h, runs) in sizes {
        let runs = runs_override.unwrap_or(runs);
        let img = image(w, h);
        let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
        let (s, c) = (0.2f64).sin_cos();
        let cases: Vec<(&str, Field)> = vec![
            ("identity", Field::zeros(w, h)),
            ("translation (0.3, -0.7)", field(w, h, |_, _| [0.3, -0.7])),
            (
                "rotation 0.2 rad",
                field(w, h, |x, y| {
                    let (u, v) = (x - cx, y - cy);
                    [c * u - s * v - u, s * u + c * v - v]
                }),
            ),
            (
                "sine warp (amplitude 6 px)",
                field(w, h, |x, y| {
                    [6.0 * (y / 40.0).sin(), 6.0 * (x / 40.0).sin()]
                }),
            ),
        ];
        let full = Grid::new(w, h);
        // A transparent hole, out of the continuity matte as well (the usual case: the
        // default matte is alpha > 0).
        let mut holed_img = img.clone();
        let mut holed = vec![1u8; w * h];
        for y in h / 3..h / 2 {
            for x in w / 3..w / 2 {
                holed[y * w + x] = 0;
                holed_img.data[(y * w + x) * 4..(y * w + x) * 4 + 4].copy_from_slice(&[0; 4]);
            }
        }
        let holed = Grid::from_matte(w, h, &holed);
        let only = std::env::var("RENDER_BENCH_CASE").ok();
        for (name, f) in &cases {
            if only.as_deref().is_some_and(|o| !name.starts_with(o)) {
                continue;
            }
            for (gname, grid, img) in [("open", &full, &img), ("hole", &holed, &holed_img)] {
                if only.is_some() && gname == "hole" {
                    continue;
                }
                let mut canvas = Canvas::new(w, h, [0, 0, 0, 0]);
                let (draw, draw_min, draw_cpu) =
                    time_ms(runs, || canvas.draw_layer(img, f, grid, [0.0, 0.0]));
                let (to8, _, _) = time_ms(runs, || {
                    std::hint::black_box(canvas.to_rgba8());
                });
                println!(
                    "{w}x{h} {name:<28} {gname}: draw_layer {draw:7.2} ms median, {draw_min:7.2} ms min, \
                     {draw_cpu:7.2} ms CPU; to_rgba8 {to8:5.2} ms"
                );
            }
        }
    }
}

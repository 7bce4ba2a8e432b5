//! One round of a two-build comparison of the renderer: the photograph-sized frame of the
//! editor's settle (4000 × 3000, a smooth warp of up to 30 px, a cut and a transparent
//! corner) drawn by `render::draw_frame` (the editor's full-resolution worker) and by
//! `Canvas::draw_layer` then `Canvas::to_rgba8` (`inkwarp render`). Prints one line per
//! path, `name seconds checksum`, each the fastest of `REPS` draws (default 3); the
//! checksum (FNV-1a of the frame's bytes) shows two builds draw the same bytes.
//! `AMP=k` scales the warp by `k`. `RAYON_NUM_THREADS=1` times one thread, as the browser's worker draws.
//! `cargo run --release -p inkwarp-core --example draw_timing [WIDTH HEIGHT]`.

use std::time::Instant;

use inkwarp_core::render::{draw_frame, Canvas, PreparedLayer, RgbaImage};
use inkwarp_core::{Field, Grid};

mod common;

fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let (w, h) = (args.first().copied().unwrap_or(4000), args.get(1).copied().unwrap_or(3000));
    let reps: usize = std::env::var("REPS").ok().and_then(|v| v.parse().ok()).unwrap_or(3);
    // `AMP=20` pulls hard enough to fold the mesh over itself (a check that two builds
    // draw the same bytes there too).
    let amp: f64 = std::env::var("AMP").ok().and_then(|v| v.parse().ok()).unwrap_or(1.0);
    let mut rnd = common::rng(7);
    let mut data = vec![0u8; w * h * 4];
    for y in 0..h {
        for x in 0..w {
            let i = 4 * (y * w + x);
            let n = (rnd() * 40.0) as u8;
            data[i] = ((x * 255 / w) as u8).saturating_add(n);
            data[i + 1] = ((y * 255 / h) as u8).saturating_add(n);
            data[i + 2] = if (x / 37 + y / 23) % 2 == 0 { 200 } else { 40 };
            // A transparent corner with a soft edge.
            let r = ((x * x + y * y) as f64).sqrt() / (w.min(h) as f64 * 0.2);
            data[i + 3] = if r < 0.9 { 0 } else if r < 1.0 { ((r - 0.9) * 2550.0) as u8 } else { 255 };
        }
    }
    let image = RgbaImage::from_raw(w, h, data).unwrap();
    let s = w as f64 / 4000.0;
    let mut grid = Grid::new(w, h);
    grid.add_cut(&[[1000.0 * s, 2000.3 * s], [1800.0 * s, 1700.3 * s], [2600.0 * s, 2100.3 * s]]);
    let mut field = Field::zeros(w, h);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f64 / w as f64, y as f64 / h as f64);
            let i = y * w + x;
            field.dx[i] = (amp * 30.0 * s * (std::f64::consts::TAU * fy).sin() * (3.0 * fx).cos()) as f32;
            field.dy[i] = (amp * 20.0 * s * (std::f64::consts::TAU * 1.5 * fx).sin() * (2.0 * fy).cos()) as f32;
        }
    }
    let background = [30, 40, 50, 255];
    let mut best = [(f64::INFINITY, 0u64); 3];
    for _ in 0..reps {
        let t = Instant::now();
        let layer = PreparedLayer::new(&image, field.clone(), &grid, [0.0, 0.0]).unwrap();
        let prepare = t.elapsed().as_secs_f64();
        let mut out = vec![0u8; 4 * w * h];
        let t = Instant::now();
        draw_frame(w, h, background, &[layer], 0..h, &mut out).unwrap();
        let draw = (prepare + t.elapsed().as_secs_f64(), fnv(&out));
        drop(out);
        let t = Instant::now();
        let mut canvas = Canvas::new(w, h, background);
        canvas.draw_layer(&image, &field, &grid, [0.0, 0.0]);
        let rgba = canvas.to_rgba8();
        let render = (t.elapsed().as_secs_f64(), fnv(&rgba.data));
        for (b, v) in best.iter_mut().zip([(prepare, 0), draw, render]) {
            if v.0 < b.0 {
                *b = v;
            }
        }
    }
    for (name, (secs, sum)) in ["prepare", "draw_frame", "render"].iter().zip(best) {
        println!("{name} {secs:.4} {sum:016x}");
    }
}

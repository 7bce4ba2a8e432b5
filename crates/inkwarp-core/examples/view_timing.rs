//! Times `draw_view` on a 4000 × 3000 layer with a smooth field: at Fit (shrink 4, the whole
//! frame) and at 100 % (shrink 1, a 1000 × 700 region in the middle). Prints `name seconds`,
//! each the fastest of `REPS` draws (default 3).
use std::time::Instant;

use inkwarp_core::render::{draw_view, RgbaImage, ViewLayer};
use inkwarp_core::{Field, Grid};

fn main() {
    let reps: usize = std::env::var("REPS").ok().and_then(|v| v.parse().ok()).unwrap_or(3);
    let (w, h) = (4000, 3000);
    let data = (0..4 * w * h).map(|i| if i % 4 == 3 { 255 } else { (i * 7 % 251) as u8 }).collect();
    let image = RgbaImage { width: w, height: h, data };
    let (mut dx, mut dy) = (vec![0f32; w * h], vec![0f32; w * h]);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            dx[y * w + x] = 40.0 * (3.0 * v).sin() * u;
            dy[y * w + x] = 30.0 * (2.0 * u).cos() * v;
        }
    }
    let field = Field { width: w, height: h, dx, dy };
    let grid = Grid::new(w, h);
    let layers = [ViewLayer { image: &image, field: &field, grid: &grid, offset: [0.0, 0.0] }];
    for (name, k, region) in [("fit", 4, [0, 0, 1000, 750]), ("100%", 1, [1500, 1150, 2500, 1850])] {
        let mut out = vec![0u8; 4 * (region[2] - region[0]) * (region[3] - region[1])];
        let best = (0..reps)
            .map(|_| {
                let t = Instant::now();
                draw_view(w, h, [0, 0, 0, 0], &layers, k, region, &mut out).unwrap();
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min);
        println!("{name} {best:.6}");
    }
}

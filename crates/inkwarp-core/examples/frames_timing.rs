//! Development timing of an animation's solves: `cargo run --release -p inkwarp-core
//! --example frames_timing -- examples/face/scene.json` prints each frame's solve cycles and
//! time with the earlier-frames start, with the previous-field start, and cold.

use std::time::Instant;

use inkwarp_core::scene::{Animator, Scene};

fn main() {
    let path = std::env::args().nth(1).expect("a scene file");
    let dir = std::path::Path::new(&path).parent().unwrap().to_path_buf();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut load = |r: &str| std::fs::read(dir.join(r)).map_err(|e| e.to_string());
    let scene = Scene::from_json(&text, &mut load).unwrap();
    let frames = scene.frame_count();
    for mode in ["history", "previous", "cold"] {
        let mut animator = Animator::new(&scene);
        let mut prev: Vec<Option<inkwarp_core::Field>> = vec![None; scene.layers().len()];
        let (mut total, mut cycles) = (0.0, 0usize);
        let mut times = Vec::new();
        for i in 0..frames {
            let t = scene.frame_time_s(i);
            for layer in 0..scene.layers().len() {
                let start = Instant::now();
                let solved = match mode {
                    "history" => animator.layer_field(layer, t).unwrap(),
                    "previous" => scene.layer_field(layer, t, prev[layer].as_ref()).unwrap(),
                    _ => scene.layer_field(layer, t, None).unwrap(),
                };
                let dt = start.elapsed().as_secs_f64();
                total += dt;
                times.push(dt);
                cycles += solved.report.map_or(0, |r| r.cycles);
                prev[layer] = Some(solved.field);
            }
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{mode:>8}: {frames} frames, {:.1} ms per frame (median solve {:.1} ms), {:.2} cycles per solve",
            total / frames as f64 * 1e3,
            times[times.len() / 2] * 1e3,
            cycles as f64 / times.len() as f64
        );
    }
}

//! Development probe: walk a scene's frames as a render's warm-start chain does and print each
//! frame's solve report: `cargo run --release -p inkwarp-core --example chain_probe -- SCENE [LAST]`. With `COLD`
//! set, each frame is compared with a cold solve of the same scene, or of the scene file `REF` names (the same
//! scene at a tighter tolerance, say).

use inkwarp_core::scene::{Animator, Scene};

fn main() {
    let path = std::env::args().nth(1).expect("a scene file");
    let last: usize = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(usize::MAX);
    let dir = std::path::Path::new(&path).parent().unwrap().to_path_buf();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut load = |r: &str| std::fs::read(dir.join(r)).map_err(|e| e.to_string());
    let scene = Scene::from_json(&text, &mut load).unwrap();
    let reference = std::env::var("REF").map(|r| Scene::from_json(&std::fs::read_to_string(r).unwrap(), &mut load).unwrap());
    let reference = reference.as_ref().unwrap_or(&scene);
    let mut animator = Animator::new(&scene);
    for i in 0..scene.frame_count().min(last.saturating_add(1)) {
        let t = scene.frame_time_s(i);
        for layer in 0..scene.layers().len() {
            let solved = animator.layer_field(layer, t).unwrap();
            let big = solved.field.dx.iter().chain(&solved.field.dy).fold(0f32, |m, v| m.max(v.abs()));
            let cold = if std::env::var("COLD").is_ok() { reference.layer_field(layer, t, None).ok() } else { None };
            if let Some(c) = &cold {
                let n = c.field.dx.len();
                let (mut gap, mut at) = (0f32, 0);
                for i in 0..n {
                    let g = (c.field.dx[i] - solved.field.dx[i]).abs().max((c.field.dy[i] - solved.field.dy[i]).abs());
                    if g > gap { (gap, at) = (g, i) }
                }
                let over = (0..n).filter(|&i| (c.field.dx[i] - solved.field.dx[i]).abs().max((c.field.dy[i] - solved.field.dy[i]).abs()) > 0.05).count();
                let r = c.report.as_ref().unwrap();
                let w = c.field.width;
                println!("   cold: cycles {} converged {} gap to chain {gap:.3} at ({}, {}) nodes over 0.05: {over}", r.cycles, r.converged, at % w, at / w);
            }
            if let Some(r) = solved.report {
                println!("frame {i} layer {layer}: cycles {} probe {} converged {} stop {:?} change {:.4} residual {:.3e} initial {:.3e} max|f| {big:.2} {:.2}s",
                    r.cycles, r.probe_cycles, r.converged, r.stop, r.final_change_px, r.residual, r.initial_residual, r.seconds);
            }
        }
    }
}

//! `grid_step = s > 1`: solve on every s-th node and upsample with a tensor-product cubic.
//!
//! The coarse node (X, Y) sits on pixel (min(sX, W−1), min(sY, H−1)) (the last row and
//! column are pulled onto the image border, so every pixel lies between coarse nodes). It is
//! active when that pixel is; two coarse neighbours are linked when every fine link on the
//! straight path between them is. A sample constrains the nearest coarse node. The tension
//! is scaled by s² so that the coarse energy approximates the same continuous energy.
//!
//! Upsampling is Catmull-Rom (interpolating, so coarse values are kept) in x and y, using
//! only coarse nodes in the pixel's own connected piece; weights of the others are dropped
//! and the rest renormalised (falling back to bilinear, then to the nearest value along the
//! links). A piece that holds no coarse node takes the mean displacement of its samples, or
//! stays at zero without any.

use std::collections::VecDeque;

use crate::field::Field;
use crate::geometry::Sample;
use crate::grid::{constrain, nearest_node, Grid};

use super::{solve_constrained, SolveOptions, SolveReport};

pub(crate) fn solve_coarse(
    grid: &Grid,
    samples: &[Sample],
    options: &SolveOptions,
    initial: Option<&Field>,
) -> (Field, SolveReport) {
    let s = options.grid_step;
    let (w, h) = (grid.width, grid.height);
    if w == 0 || h == 0 {
        return (Field::zeros(w, h), SolveReport { converged: true, ..Default::default() });
    }
    let wc = (w - 1).div_ceil(s) + 1;
    let hc = (h - 1).div_ceil(s) + 1;
    let px = |x: usize| (x * s).min(w - 1);
    let py = |y: usize| (y * s).min(h - 1);
    let mut active = vec![false; wc * hc];
    let mut right = vec![false; wc * hc];
    let mut down = vec![false; wc * hc];
    for yc in 0..hc {
        for xc in 0..wc {
            let c = yc * wc + xc;
            let (fx, fy) = (px(xc), py(yc));
            active[c] = grid.active[grid.index(fx, fy)];
            if xc + 1 < wc {
                right[c] = (fx..px(xc + 1)).all(|x| grid.link_right[grid.index(x, fy)]);
            }
            if yc + 1 < hc {
                down[c] = (fy..py(yc + 1)).all(|y| grid.link_down[grid.index(fx, y)]);
            }
        }
    }
    let coarse = Grid { width: wc, height: hc, active, link_right: right, link_down: down };
    let sf = s as f64;
    let mut outside = 0usize;
    let coarse_samples: Vec<Sample> = samples
        .iter()
        .filter_map(|smp| match nearest_node(grid, smp.rest) {
            Some(_) => Some(Sample {
                rest: [(smp.rest[0] / sf).min((wc - 1) as f64), (smp.rest[1] / sf).min((hc - 1) as f64)],
                displacement: smp.displacement,
            }),
            None => {
                outside += 1;
                None
            }
        })
        .collect();
    let mut constraints = constrain(&coarse, &coarse_samples);
    constraints.dropped_samples += outside;
    let init_c = initial.map(|f| {
        let mut c = Field::zeros(wc, hc);
        for yc in 0..hc {
            for xc in 0..wc {
                let v = f.at(px(xc), py(yc));
                c.dx[yc * wc + xc] = v[0];
                c.dy[yc * wc + xc] = v[1];
            }
        }
        c
    });
    let opts = SolveOptions { tension: options.tension * sf * sf, grid_step: 1, ..options.clone() };
    let (fc, report) = solve_constrained(&coarse, &constraints, &opts, init_c.as_ref());

    // Upsample within pieces.
    let (labels, count) = grid.pieces();
    let clabel: Vec<u32> = (0..wc * hc)
        .map(|c| if coarse.active[c] { labels[grid.index(px(c % wc), py(c / wc))] } else { u32::MAX })
        .collect();
    let taps = |x: usize, n: usize, pos: &dyn Fn(usize) -> usize| -> (isize, [f64; 4]) {
        if n == 1 {
            return (0, [0.0, 1.0, 0.0, 0.0]);
        }
        let x0 = (x / s).min(n - 2);
        let (a, b) = (pos(x0) as f64, pos(x0 + 1) as f64);
        let t = ((x as f64 - a) / (b - a)).clamp(0.0, 1.0);
        let (t2, t3) = (t * t, t * t * t);
        (
            x0 as isize - 1,
            [
                0.5 * (-t3 + 2.0 * t2 - t),
                0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
                0.5 * (-3.0 * t3 + 4.0 * t2 + t),
                0.5 * (t3 - t2),
            ],
        )
    };
    let mut field = Field::zeros(w, h);
    let mut resolved = vec![false; w * h];
    for y in 0..h {
        let (ys, wy) = taps(y, hc, &py);
        for x in 0..w {
            let i = y * w + x;
            if !grid.active[i] {
                continue;
            }
            let (xs, wx) = taps(x, wc, &px);
            let mut acc = [0.0f64; 2];
            let mut wsum = 0.0;
            let mut inner = [0.0f64; 3];
            for (b, &wyb) in wy.iter().enumerate() {
                let cy = ys + b as isize;
                if cy < 0 || cy >= hc as isize || wyb == 0.0 {
                    continue;
                }
                for (a, &wxa) in wx.iter().enumerate() {
                    let cx = xs + a as isize;
                    if cx < 0 || cx >= wc as isize || wxa == 0.0 {
                        continue;
                    }
                    let c = cy as usize * wc + cx as usize;
                    if clabel[c] != labels[i] {
                        continue;
                    }
                    let wv = wxa * wyb;
                    acc[0] += wv * fc.dx[c] as f64;
                    acc[1] += wv * fc.dy[c] as f64;
                    wsum += wv;
                    if (1..3).contains(&a) && (1..3).contains(&b) {
                        // bilinear fallback weights from the inner 2 × 2
                        let lw = lin(&wx, a) * lin(&wy, b);
                        inner[0] += lw * fc.dx[c] as f64;
                        inner[1] += lw * fc.dy[c] as f64;
                        inner[2] += lw;
                    }
                }
            }
            if wsum >= 0.5 {
                field.dx[i] = (acc[0] / wsum) as f32;
                field.dy[i] = (acc[1] / wsum) as f32;
                resolved[i] = true;
            } else if inner[2] > 1e-9 {
                field.dx[i] = (inner[0] / inner[2]) as f32;
                field.dy[i] = (inner[1] / inner[2]) as f32;
                resolved[i] = true;
            }
        }
    }
    // Pixels left over: nearest resolved value along the links.
    let mut queue: VecDeque<usize> = (0..w * h).filter(|&i| resolved[i]).collect();
    while let Some(i) = queue.pop_front() {
        let (x, y) = (i % w, i / w);
        let mut nbrs = [usize::MAX; 4];
        if grid.link_right[i] {
            nbrs[0] = i + 1;
        }
        if x > 0 && grid.link_right[i - 1] {
            nbrs[1] = i - 1;
        }
        if grid.link_down[i] {
            nbrs[2] = i + w;
        }
        if y > 0 && grid.link_down[i - w] {
            nbrs[3] = i - w;
        }
        for j in nbrs {
            if j != usize::MAX && !resolved[j] {
                resolved[j] = true;
                field.dx[j] = field.dx[i];
                field.dy[j] = field.dy[i];
                queue.push_back(j);
            }
        }
    }
    // Pieces without a coarse node: their samples' mean displacement, else zero.
    if (0..w * h).any(|i| grid.active[i] && !resolved[i]) {
        let mut mean = vec![[0.0f64; 3]; count];
        for smp in samples {
            if let Some((x, y)) = nearest_node(grid, smp.rest) {
                let l = labels[grid.index(x, y)];
                if l != u32::MAX {
                    mean[l as usize][0] += smp.displacement[0];
                    mean[l as usize][1] += smp.displacement[1];
                    mean[l as usize][2] += 1.0;
                }
            }
        }
        for i in 0..w * h {
            if grid.active[i] && !resolved[i] {
                let m = mean[labels[i] as usize];
                if m[2] > 0.0 {
                    field.dx[i] = (m[0] / m[2]) as f32;
                    field.dy[i] = (m[1] / m[2]) as f32;
                }
            }
        }
    }
    (field, report)
}

/// Linear weight of inner tap `k` (1 or 2) from the cubic weights' parameter: recovered as
/// the share of the two inner cubic weights (exact at t = 0 and t = 1).
fn lin(wts: &[f64; 4], k: usize) -> f64 {
    let s = wts[1] + wts[2];
    if s.abs() < 1e-12 {
        0.5
    } else {
        wts[k] / s
    }
}

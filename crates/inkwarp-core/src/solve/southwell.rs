//! Southwell relaxation with a fixed budget: relax the nodes whose relaxation lowers the
//! energy most first. Each pass finds the largest energy drop `e_max` any single relaxation
//! would bring (`e_i = |r_i|² / a_ii`) and relaxes, in order, every node whose drop is still
//! at least `e_max / 4` when it is reached; passes repeat until the budget of single-node
//! relaxations is spent or nothing is left to relax. (This is the thresholded form of
//! Southwell's greedy rule: each relaxed node is within a factor 4 of the greediest choice,
//! without a priority queue.)

use super::level::{Level, V2, PAD};

/// Spends at most `budget` relaxations on the finest level; returns the number of passes,
/// the largest single change made in the last pass, and whether it stopped because nothing
/// was left to relax (the residual at rounding) rather than because the budget ran out.
pub(crate) fn relax_level(level: &Level, u: &mut [V2], budget: usize) -> (usize, f64, bool) {
    let (w, h) = (level.geo.w, level.geo.h);
    let mut r = vec![[0.0; 2]; u.len()];
    let mut left = budget;
    let mut passes = 0;
    let mut last_change = 0.0f64;
    while left > 0 {
        level.residual(u, None, &mut r);
        let mut e_max = 0.0f64;
        for (p, ri) in r.iter().enumerate() {
            let d = level.inv_diag[p];
            e_max = e_max.max((ri[0] * ri[0] + ri[1] * ri[1]) * d);
        }
        if e_max <= 0.0 {
            return (passes, last_change, true);
        }
        let threshold = e_max / 4.0;
        passes += 1;
        last_change = 0.0;
        let left_before = left;
        'pass: for y in 0..h {
            for x in 0..w {
                let p = (y + PAD) * level.wp + x + PAD;
                let d = level.inv_diag[p];
                if d == 0.0 {
                    continue;
                }
                let ri = level.fine_residual_at(u, p);
                if (ri[0] * ri[0] + ri[1] * ri[1]) * d >= threshold {
                    u[p][0] += ri[0] * d;
                    u[p][1] += ri[1] * d;
                    last_change = last_change.max((ri[0] * d).abs()).max((ri[1] * d).abs());
                    left -= 1;
                    if left == 0 {
                        break 'pass;
                    }
                }
            }
        }
        // The largest drop can vanish before its node is reached (its neighbours were
        // relaxed first, or it is rounding noise): a pass that relaxes nothing is the end.
        if left == left_before {
            return (passes, last_change, true);
        }
    }
    (passes, last_change, false)
}

/// [`relax_level`] on the assembled system `A x = b` of the free nodes.
pub(crate) fn relax(a: &super::matrix::Csr, inv_diag: &[f64], b: &[V2], x: &mut [V2], budget: usize) -> (usize, f64, bool) {
    let n = a.rows;
    let mut r = vec![[0.0; 2]; n];
    let mut left = budget;
    let mut passes = 0;
    let mut last_change = 0.0f64;
    while left > 0 {
        a.residual(b, x, &mut r);
        let e_max = r.iter().zip(inv_diag).fold(0.0f64, |m, (r, d)| m.max((r[0] * r[0] + r[1] * r[1]) * d));
        if e_max <= 0.0 {
            return (passes, last_change, true);
        }
        let threshold = e_max / 4.0;
        passes += 1;
        last_change = 0.0;
        let left_before = left;
        for i in 0..n {
            let d = inv_diag[i];
            if d == 0.0 {
                continue;
            }
            let (c, v) = a.row(i);
            let mut s = b[i];
            for (&c, &v) in c.iter().zip(v) {
                s[0] -= v * x[c as usize][0];
                s[1] -= v * x[c as usize][1];
            }
            if (s[0] * s[0] + s[1] * s[1]) * d >= threshold {
                x[i][0] += s[0] * d;
                x[i][1] += s[1] * d;
                last_change = last_change.max((s[0] * d).abs()).max((s[1] * d).abs());
                left -= 1;
                if left == 0 {
                    break;
                }
            }
        }
        if left == left_before {
            return (passes, last_change, true);
        }
    }
    (passes, last_change, false)
}

//! Southwell relaxation with a fixed budget: relax first the nodes whose relaxation lowers the energy most.
//! Relaxing node `i` lowers the energy by `e_i = |r_i|² / a_ii`; each pass finds the `k`-th largest drop
//! (`k` a quarter of the unknowns, or what is left of the budget, charged `k` per pass) and relaxes, in
//! order, every node whose drop is still at least that when reached: Southwell's greedy rule in bulk, one
//! residual and one scan a pass where picking one node at a time would cost a search per relaxation.

use super::level::{Level, V2};

/// Spends at most `budget` relaxations on the finest level; returns the largest single change made, and
/// whether it stopped because nothing was left to relax (every residual exactly zero) rather than because
/// the budget ran out.
pub(crate) fn relax(level: &Level, u: &mut [V2], budget: usize, unknowns: usize) -> (f64, bool) {
    let (w, h) = (level.geo.w, level.geo.h);
    let mut r = vec![[0.0; 2]; u.len()];
    let (mut drops, mut left, mut largest) = (Vec::<f64>::new(), budget, 0.0f64);
    while left > 0 {
        level.residual(u, None, &mut r);
        drops.clear();
        drops.extend(r.iter().zip(&level.inv_diag).filter(|(_, &d)| d != 0.0).map(|(ri, &d)| (ri[0] * ri[0] + ri[1] * ri[1]) * d));
        // A quarter of the unknowns a pass; a remainder under two quarters goes in one.
        let quarter = (unknowns / 4).max(1);
        let k = (if left < 2 * quarter { left } else { quarter }).min(drops.len());
        if k == 0 { return (largest, true); }
        let (_, &mut kth, _) = drops.select_nth_unstable_by(k - 1, |a, b| b.total_cmp(a));
        // Fewer than k nodes have any drop at all: relax those that do.
        if kth <= 0.0 && drops.iter().all(|&e| e <= 0.0) { return (largest, true); }
        let threshold = kth.max(f64::MIN_POSITIVE);
        left -= k;
        let mut relaxed = 0;
        for p in (0..h).flat_map(|y| (0..w).map(move |x| level.pidx(x, y))) {
            let d = level.inv_diag[p];
            if d == 0.0 { continue; }
            let ri = level.fine_residual_at(u, p);
            if (ri[0] * ri[0] + ri[1] * ri[1]) * d >= threshold {
                u[p][0] += ri[0] * d;
                u[p][1] += ri[1] * d;
                largest = largest.max((ri[0] * d).abs()).max((ri[1] * d).abs());
                relaxed += 1;
                if relaxed == k { break; }
            }
        }
        // The largest drops can vanish before their nodes are reached (their neighbours relaxed first, or
        // rounding noise): a pass that relaxes nothing ends it, without a claim about the error left.
        if relaxed == 0 { return (largest, false); }
    }
    (largest, false)
}

//! Coarse levels held by constrained nodes all around, solved by smoothing alone.
//!
//! A coarse level's functions are interpolated onto the finest level and vanish at its
//! constrained nodes (their prolongation rows are empty). Where constrained nodes lie on
//! every side of a coarse node within a few of its cells, every function near it must bend
//! sharply to vanish there, so the level's energy has no smooth, low modes left near it: a
//! few Chebyshev steps (aimed lower than a smoother's) solve the level as well as a cycle
//! through the levels below it, at a fraction of the cost; the levels below it are never
//! visited. At 513 × 513 with 1000 random constrained nodes this holds from the fourth
//! coarse level (about four constrained nodes in each quadrant of a box of twice a coarse
//! node's reach), with 4000 from the third.
//!
//! The rule must also see where it does not hold. Constrained nodes all on one side leave
//! functions that run linearly away from them (a free margin around a large constrained
//! region bends like a cantilever along it): such a margin's coarse nodes lack constrained
//! nodes on their outer side, and they join up along it. So a level counts as held when
//! every coarse node has a constrained node in each quadrant of the box around it (of
//! half-width twice the node's reach, clipped to the grid), except in groups of at most
//! [`FREE_GROUP_MAX`] adjacent nodes: the small gaps of random constraints, not a margin
//! or a region left free. Only grids without holes or cuts: a box that reached across one
//! would count constrained nodes that do not hold the node.

use super::level::Level;

/// The largest group of adjacent coarse nodes without a constrained node in some quadrant
/// that a held level may have. With random constraints the largest groups were 17 and 18
/// nodes (513 × 513: 4000 points on the third coarse level, 1000 on the fourth); free
/// margins 6 to 40 nodes wide around constrained regions make groups of 128 and more along
/// the grid's border.
const FREE_GROUP_MAX: usize = 32;

/// The first level (from the second coarse one down) that constrained nodes hold all
/// around, if any: it and the levels below it are solved by smoothing alone. `levels[0]`
/// is the finest level, with its fixed nodes.
pub(crate) fn first_held(levels: &[Level]) -> Option<usize> {
    let g = &levels[0].geo;
    let fixed = g.fixed.as_ref()?;
    let (w, h) = (g.w, g.h);
    // Summed-area table of the constrained nodes: counts in boxes at constant cost.
    let mut sum = vec![0u32; (w + 1) * (h + 1)];
    for y in 0..h {
        for x in 0..w {
            let v = u32::from(fixed[y * w + x] && g.active[y * w + x]);
            sum[(y + 1) * (w + 1) + x + 1] = v + sum[y * (w + 1) + x + 1] + sum[(y + 1) * (w + 1) + x] - sum[y * (w + 1) + x];
        }
    }
    // Constrained nodes in columns x0..=x1 and rows y0..=y1.
    let count = |x0: usize, y0: usize, x1: usize, y1: usize| {
        sum[(y1 + 1) * (w + 1) + x1 + 1] + sum[y0 * (w + 1) + x0] - sum[y0 * (w + 1) + x1 + 1] - sum[(y1 + 1) * (w + 1) + x0]
    };
    for (k, level) in levels.iter().enumerate().skip(2) {
        // A level-k node sits on fine node (2ᵏX, 2ᵏY) and reaches 2ᵏ − 1 nodes each way.
        let step = 1usize << k;
        let half = 2 * step;
        let (lw, lh) = (level.geo.w, level.geo.h);
        let mut free = vec![false; lw * lh];
        for yc in 0..lh {
            for xc in 0..lw {
                if !level.geo.active[yc * lw + xc] {
                    continue;
                }
                // (Ghost coarse nodes past an even-sized grid's edge stand on its last node.)
                let (cx, cy) = ((xc * step).min(w - 1), (yc * step).min(h - 1));
                let (x0, x1, y0, y1) = (cx.saturating_sub(half), (cx + half).min(w - 1), cy.saturating_sub(half), (cy + half).min(h - 1));
                // A quadrant with no room past the grid's edge is not asked for.
                let quadrants = [
                    (cx > 0 && cy > 0, x0, y0, cx, cy),
                    (cx + 1 < w && cy > 0, cx, y0, x1, cy),
                    (cx > 0 && cy + 1 < h, x0, cy, cx, y1),
                    (cx + 1 < w && cy + 1 < h, cx, cy, x1, y1),
                ];
                free[yc * lw + xc] = quadrants.iter().any(|&(room, qx0, qy0, qx1, qy1)| room && count(qx0, qy0, qx1, qy1) == 0);
            }
        }
        if largest_group(&free, lw, lh) <= FREE_GROUP_MAX {
            return Some(k);
        }
    }
    None
}

/// The size of the largest 4-connected group of `true` cells of a `w` × `h` grid.
fn largest_group(cells: &[bool], w: usize, h: usize) -> usize {
    let mut seen = vec![false; w * h];
    let mut largest = 0;
    let mut stack = Vec::new();
    for start in 0..w * h {
        if !cells[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut size = 0;
        while let Some(i) = stack.pop() {
            size += 1;
            let (x, y) = (i % w, i / w);
            let next = [(x > 0, i.wrapping_sub(1)), (x + 1 < w, i + 1), (y > 0, i.wrapping_sub(w)), (y + 1 < h, i + w)];
            for (inside, j) in next {
                if inside && cells[j] && !seen[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        largest = largest.max(size);
    }
    largest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_are_counted_across_edges_not_corners() {
        #[rustfmt::skip]
        let cells = [
            true, true, false, false,
            false, true, false, true,
            false, false, true, true,
        ];
        assert_eq!(largest_group(&cells, 4, 3), 3);
        assert_eq!(largest_group(&[false; 6], 3, 2), 0);
        assert_eq!(largest_group(&[true; 6], 3, 2), 6);
    }
}

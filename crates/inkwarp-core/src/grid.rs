//! The solve domain: active nodes from the continuity matte, 4-neighbour links broken by
//! inactive nodes and by cuts, nearest-node constraints (DESIGN §4).
//!
//! # Cuts
//!
//! A link joins two 4-neighbour nodes; [`Grid::add_cut`] breaks every link whose straight
//! segment between the two node centres is crossed by a segment of the cut polyline. Every
//! decision is an exact orientation predicate (Shewchuk's adaptive `orient2d`, from the
//! `robust` crate) on the cut's own `f64` coordinates and the integer node centres, so a
//! cut cannot slip between two links through rounding. Touching and collinear cases are
//! decided as if every node centre were nudged by an infinitesimal `(+ε, +ε²)` (right, and
//! a far smaller amount down) while the cut stays put: a cut along a row of node centres
//! separates that row from the row above, one through a node passes just left of it, and a
//! polyline whose vertices sit on node centres separates its two sides with no gap and no
//! double cut. A cut never deactivates a node; segments with a non-finite end are skipped.
//! `docs/concepts/cuts.md` lists every case.

use crate::geometry::{Point, Sample};

/// Active nodes and links of a `width × height` node grid.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Grid {
    pub width: usize,
    pub height: usize,
    /// `active[y * width + x]`: the node exists (matte nonzero).
    pub active: Vec<bool>,
    /// `link_right[y * width + x]`: node `(x, y)` is linked to `(x + 1, y)`.
    pub link_right: Vec<bool>,
    /// `link_down[y * width + x]`: node `(x, y)` is linked to `(x, y + 1)`.
    pub link_down: Vec<bool>,
}

impl Grid {
    /// A grid whose nodes are all active and all linked.
    pub fn new(width: usize, height: usize) -> Self { Self::from_active(width, height, vec![true; width * height]) }

    /// A grid from a continuity matte (`nonzero = connected`), row-major `width × height`.
    ///
    /// # Panics
    /// If `matte.len() != width * height`.
    pub fn from_matte(width: usize, height: usize, matte: &[u8]) -> Self {
        assert_eq!(matte.len(), width * height, "matte has the wrong size");
        Self::from_active(width, height, matte.iter().map(|&m| m != 0).collect())
    }

    /// A grid from per-node activity: every pair of active 4-neighbours is linked.
    ///
    /// # Panics
    /// If `active.len() != width * height`.
    pub fn from_active(width: usize, height: usize, active: Vec<bool>) -> Self {
        assert_eq!(active.len(), width * height, "activity mask has the wrong size");
        let n = width * height;
        let (mut link_right, mut link_down) = (vec![false; n], vec![false; n]);
        // Row by row without branches, so that the passes vectorise (every solve from
        // Python builds its grid).
        for y in 0..height {
            let row = y * width..(y + 1) * width;
            let (a, r) = (&active[row.clone()], &mut link_right[row.clone()]);
            for ((l, &p), &q) in r.iter_mut().zip(a).zip(a.get(1..).unwrap_or_default()) { *l = p & q; }
            if y + 1 < height {
                let below = &active[row.start + width..row.end + width];
                for ((l, &p), &q) in link_down[row].iter_mut().zip(a).zip(below) { *l = p & q; }
            }
        }
        Grid { width, height, active, link_right, link_down }
    }

    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize { y * self.width + x }

    /// The nodes linked to node `i`: right, left, below, above (`usize::MAX` where there
    /// is no link).
    pub fn linked(&self, i: usize) -> [usize; 4] {
        let (w, right, down) = (self.width, &self.link_right, &self.link_down);
        let (left, up) = (i % w > 0 && right[i - 1], i >= w && down[i - w]);
        let links = [(right[i], i + 1), (left, i.wrapping_sub(1)), (down[i], i + w), (up, i.wrapping_sub(w))];
        links.map(|(linked, j)| if linked { j } else { usize::MAX })
    }

    /// Number of nodes (`width × height`).
    #[inline]
    pub fn len(&self) -> usize { self.width * self.height }

    /// `true` for a grid without nodes.
    #[inline]
    pub fn is_empty(&self) -> bool { self.len() == 0 }

    /// Whether the three vectors have `width × height` entries and every link joins two
    /// active nodes inside the grid. The solver checks this before it trusts a grid.
    pub fn is_consistent(&self) -> bool {
        let n = self.len();
        if self.active.len() != n || self.link_right.len() != n || self.link_down.len() != n { return false; }
        // Row by row without early exits, so the comparisons run side by side (every solve
        // checks its grid).
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 { return true; }
        let mut bad = false;
        for y in 0..h {
            let row = y * w..(y + 1) * w;
            let (a, right, down) = (&self.active[row.clone()], &self.link_right[row.clone()], &self.link_down[row]);
            bad |= right[w - 1];
            for x in 0..w - 1 { bad |= right[x] & !(a[x] & a[x + 1]); }
            if y + 1 < h {
                let below = &self.active[(y + 1) * w..(y + 2) * w];
                for x in 0..w { bad |= down[x] & !(a[x] & below[x]); }
            } else {
                bad |= down.iter().any(|&d| d);
            }
        }
        !bad
    }

    #[cfg(test)]
    /// Number of links (right plus down).
    pub fn link_count(&self) -> usize {
        self.link_right.iter().filter(|&&l| l).count() + self.link_down.iter().filter(|&&l| l).count()
    }

    /// Breaks every link whose segment is crossed by a segment of `polyline` (see the module
    /// docs for the touching and collinear rule). A polyline of fewer than two points breaks
    /// nothing; parts outside the grid are ignored.
    ///
    /// ```
    /// use inkwarp_core::Grid;
    /// let mut grid = Grid::new(4, 3);
    /// // A vertical cut between columns 1 and 2, through the whole grid.
    /// grid.add_cut(&[[1.5, -1.0], [1.5, 3.0]]);
    /// assert!((0..3).all(|y| !grid.link_right[grid.index(1, y)]));
    /// assert!(grid.link_right[grid.index(0, 0)] && grid.link_right[grid.index(2, 0)]);
    /// ```
    pub fn add_cut(&mut self, polyline: &[Point]) {
        for seg in polyline.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            if a.iter().chain(b.iter()).all(|v| v.is_finite()) { self.cut_segment(a, b); }
        }
    }

    fn cut_segment(&mut self, a: Point, b: Point) {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 || a == b { return; }
        // Horizontal links of row y lie on the line Y = y + ε²: the segment crosses it iff
        // exactly one end has a coordinate ≤ y (exact comparisons of a float with an
        // integer). Along the row the nudged nodes change side of the cut's line at most
        // once; the link where they do is the one crossed.
        for y in crossed_lines(a[1], b[1], h) {
            if let Some(x) = side_change(w, |x| node_side(a, b, x, y)) { self.link_right[y * w + x] = false; }
        }
        // Vertical links of column x lie on X = x + ε: crossed iff exactly one end has a
        // coordinate ≤ x.
        for x in crossed_lines(a[0], b[0], w) {
            if let Some(y) = side_change(h, |y| node_side(a, b, x, y)) { self.link_down[y * w + x] = false; }
        }
    }

    /// Whether every node is active and linked to each of its neighbours (no matte, no
    /// cut): one piece, the most common grid, which [`Grid::pieces`] answers at once.
    pub fn is_open(&self) -> bool { !self.is_empty() && !torn(self.width, &self.active, &self.link_right, &self.link_down) }

    /// How many active nodes are *thin*: their run of linked nodes along the row or the
    /// column is at most `longest` (strands, teeth, outlines, slivers between cuts).
    pub fn thin_nodes(&self, longest: usize) -> usize {
        let w = self.width;
        if self.is_open() { return if w.min(self.height) <= longest { self.len() } else { 0 }; }
        let runs = shorter_runs(w, self.height, |x, y| self.link_right[y * w + x], |x, y| self.link_down[y * w + x]);
        runs.iter().zip(&self.active).filter(|&(&r, &a)| a && r as usize <= longest).count()
    }

    /// Connected pieces: `labels[i]` is the piece of node `i` (`u32::MAX` for inactive
    /// nodes), pieces numbered `0..count` in order of their first node. Links are taken to
    /// join active nodes (as [`Grid::is_consistent`] checks).
    pub fn pieces(&self) -> (Vec<u32>, usize) {
        let (labels, count, _) = self.pieces_and_open();
        (labels, count)
    }

    /// [`Grid::pieces`], and whether the grid is open ([`Grid::is_open`]): the check that
    /// answers an open grid at once, told to the caller (the solver keys and writes an open
    /// grid's piece without reading labels).
    pub(crate) fn pieces_and_open(&self) -> (Vec<u32>, usize, bool) {
        if !self.is_empty() && self.is_open() { return (vec![0; self.len()], 1, true); }
        // Union-find over runs (maximal row segments joined by right links) rather than
        // nodes: a row of a connected picture is one run, so there are few elements and
        // each vertical link between the same two runs is looked at once.
        let (w, h) = (self.width, self.height);
        let n = self.len();
        let mut run = vec![u32::MAX; n];
        let mut parent: Vec<u32> = Vec::new();
        for y in 0..h {
            let row = y * w;
            let mut x = 0;
            while x < w {
                if self.active[row + x] {
                    let id = parent.len() as u32;
                    parent.push(id);
                    run[row + x] = id;
                    while x + 1 < w && self.link_right[row + x] && self.active[row + x + 1] {
                        x += 1;
                        run[row + x] = id;
                    }
                }
                x += 1;
            }
        }
        for y in 0..h.saturating_sub(1) {
            let mut last = (u32::MAX, u32::MAX);
            for i in y * w..(y + 1) * w {
                let pair = (run[i], run[i + w]);
                if !self.link_down[i] || pair == last || pair.0 == u32::MAX || pair.1 == u32::MAX { continue; }
                last = pair;
                join(&mut parent, pair.0, pair.1);
            }
        }
        // Runs are numbered in the order of their first node, so the first run of a piece
        // holds its first node.
        let mut run_label = vec![u32::MAX; parent.len()];
        let mut count = 0usize;
        for r in 0..parent.len() {
            let root = find(&mut parent, r as u32) as usize;
            if run_label[root] == u32::MAX {
                run_label[root] = count as u32;
                count += 1;
            }
            run_label[r] = run_label[root];
        }
        let labels = run.iter().map(|&r| if r == u32::MAX { u32::MAX } else { run_label[r as usize] }).collect();
        (labels, count, false)
    }
}

/// The side of the cut line through `a` and `b` on which node `(x, y)` lies, nudged by
/// `(+ε, +ε²)` (the module's tie rule): `true` for the positive side of the exact
/// orientation `orient(a, b, node)`. Never a tie for `a ≠ b`: a node exactly on the line is
/// decided by the nudge, `(b − a) × (ε, ε²) = (bx − ax)·ε² − (by − ay)·ε`, whose sign is that
/// of `ay − by`, or of `bx − ax` for a horizontal line.
fn node_side(a: Point, b: Point, x: usize, y: usize) -> bool {
    let c = |p: Point| robust::Coord { x: p[0], y: p[1] };
    let exact = robust::orient2d(c(a), c(b), c([x as f64, y as f64]));
    if exact != 0.0 && !exact.is_nan() {
        exact > 0.0
    } else if a[1] != b[1] {
        a[1] > b[1]
    } else {
        b[0] > a[0]
    }
}

/// The grid lines `k` in `0..count` (rows for `lo, hi` = the segment's y values, columns for
/// its x values) that a segment with these end coordinates crosses once the nodes are
/// nudged: exactly one end ≤ `k`.
fn crossed_lines(u: f64, v: f64, count: usize) -> std::ops::Range<usize> {
    let (lo, hi) = (u.min(v), u.max(v));
    // lo ≤ k < hi over the integers: k from ⌈lo⌉ to ⌈hi⌉ − 1, clamped to the grid (the
    // casts saturate, and the clamps keep far-off segments cheap).
    let first = lo.ceil().clamp(0.0, count as f64) as usize;
    let end = hi.ceil().clamp(0.0, count as f64) as usize;
    first..end.max(first)
}

/// The `k` such that `side(k) != side(k + 1)` for a side that changes at most once along
/// `0..count` (nodes of one grid line against one straight cut), found by bisection with
/// exact predicates; `None` when all nodes are on one side.
fn side_change(count: usize, side: impl Fn(usize) -> bool) -> Option<usize> {
    if count < 2 { return None; }
    let first = side(0);
    if side(count - 1) == first { return None; }
    // Invariant: side(lo) == first, side(hi) != first.
    let (mut lo, mut hi) = (0, count - 1);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if side(mid) == first {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(lo)
}

/// Samples attached to their nearest nodes (DESIGN §4).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Constraints {
    /// Constrained node indices, ascending, each once.
    pub nodes: Vec<usize>,
    /// The displacement of each constrained node: the mean of its samples' displacements.
    pub values: Vec<[f64; 2]>,
    /// Samples that landed on an active node (and were averaged into `values`).
    pub used_samples: usize,
    /// Samples that fell outside the grid, on an inactive node, or had non-finite numbers.
    pub dropped_samples: usize,
}

impl Constraints {
    pub fn len(&self) -> usize { self.nodes.len() }

    pub fn is_empty(&self) -> bool { self.nodes.is_empty() }
}

/// The node a sample at `point` constrains: `(⌊x + ½⌋, ⌊y + ½⌋)` (halves round towards +x
/// and +y), or `None` outside the grid.
pub fn nearest_node(grid: &Grid, point: Point) -> Option<(usize, usize)> {
    // Node (⌊x + ½⌋, ⌊y + ½⌋), from the truncation of a coordinate known to be ≥ 0 (where the
    // two agree): the floor is a library call on plain x86-64. The comparisons also reject
    // NaN and the infinities.
    let (x, y) = (point[0] + 0.5, point[1] + 0.5);
    if !(x >= 0.0 && y >= 0.0 && x < grid.width as f64 && y < grid.height as f64) { return None; }
    Some((x as usize, y as usize))
}

/// Attaches every sample to its nearest node ([`nearest_node`]). Several samples on one node
/// are averaged; samples outside the grid, on an inactive node, or with a non-finite rest
/// position or displacement are dropped and counted.
///
/// ```
/// use inkwarp_core::{grid::constrain, Grid, Sample};
/// let grid = Grid::new(5, 5);
/// let s = |x, y, d| Sample { rest: [x, y], displacement: [d, 0.0] };
/// let c = constrain(&grid, &[s(1.2, 1.0, 2.0), s(0.8, 1.4, 4.0), s(9.0, 0.0, 1.0)]);
/// assert_eq!(c.nodes, vec![grid.index(1, 1)]);
/// assert_eq!(c.values, vec![[3.0, 0.0]]);
/// assert_eq!((c.used_samples, c.dropped_samples), (2, 1));
/// ```
pub fn constrain(grid: &Grid, samples: &[Sample]) -> Constraints {
    // Each kept sample as its node and its own index in one integer (both under 2³², as any
    // grid or sample list that fits in memory is; checked), sorted: by node, and within a
    // node in the samples' order (so their average is summed in that order).
    assert!(grid.len() as u64 <= 1 << 32 && samples.len() as u64 <= 1 << 32, "a node or sample index past 2³²");
    let mut keyed: Vec<u64> = Vec::with_capacity(samples.len());
    keyed.extend(samples.iter().enumerate().filter_map(|(k, s)| {
        let i = nearest_node(grid, s.rest).map(|(x, y)| grid.index(x, y))?;
        let finite = s.displacement[0].is_finite() && s.displacement[1].is_finite();
        (finite && grid.active[i]).then_some(((i as u64) << 32) | k as u64)
    }));
    let used = keyed.len();
    keyed.sort_unstable();
    let mut out = Constraints { used_samples: used, dropped_samples: samples.len() - used, ..Default::default() };
    for group in keyed.chunk_by(|a, b| a >> 32 == b >> 32) {
        let sum = group.iter().fold([0.0f64; 2], |s, &key| {
            let d = samples[(key & 0xffff_ffff) as usize].displacement;
            [s[0] + d[0], s[1] + d[1]]
        });
        let count = group.len() as f64;
        out.nodes.push((group[0] >> 32) as usize);
        out.values.push([sum[0] / count, sum[1] / count]);
    }
    out
}

/// Each node's shorter run of linked nodes, along its row or along its column, on a `w × h` grid whose node
/// `(x, y)` is linked to the next by `right(x, y)` and to the one below by `down(x, y)`; indexed `y * w + x`.
pub(crate) fn shorter_runs(w: usize, h: usize, right: impl Fn(usize, usize) -> bool, down: impl Fn(usize, usize) -> bool) -> Vec<u32> {
    let mut runs = vec![u32::MAX; w * h];
    for y in 0..h { each_run(w, |x| right(x, y), |x, e| runs[y * w + x..=y * w + e].fill((e - x + 1) as u32)); }
    for x in 0..w {
        each_run(h, |y| down(x, y), |y, e| (y..=e).for_each(|i| runs[i * w + x] = runs[i * w + x].min((e - y + 1) as u32)));
    }
    runs
}

/// `f(start, end)` for each maximal run `start..=end` of `0..n` joined by `linked(i)` (`i` to `i + 1`).
fn each_run(n: usize, linked: impl Fn(usize) -> bool, mut f: impl FnMut(usize, usize)) {
    let mut s = 0;
    while s < n {
        let e = (s..n - 1).find(|&e| !linked(e)).unwrap_or(n - 1);
        f(s, e);
        s = e + 1;
    }
}

/// Whether a `w`-wide grid with activity `active` and links `right` and `down` (as in
/// [`Grid`]) has an inactive node or a missing link between two active neighbours.
pub fn torn(w: usize, active: &[bool], right: &[bool], down: &[bool]) -> bool {
    // Without early exits, so that the passes vectorise: every right link but the last
    // column's, every down link but the last row's.
    let (n, all) = (active.len(), |v: &[bool]| v.iter().fold(true, |a, &b| a & b));
    n > 0 && !(all(active) && right.chunks_exact(w).fold(true, |a, r| a & all(&r[..w - 1])) && all(&down[..n - w]))
}

/// The root of `i`'s set in a union-find forest (`parent[r] == r` at a root), halving the
/// path on the way.
pub(crate) fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[parent[i as usize] as usize];
        parent[i as usize] = p;
        i = p;
    }
    i
}

/// Joins the sets of `a` and `b` in a union-find forest under the smaller root.
pub(crate) fn join(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb { parent[ra.max(rb) as usize] = ra.min(rb); }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A deterministic pseudo-random sequence in [0, 1).
    pub(crate) fn sequence(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed | 1;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A `w × h` grid with random holes (a share `holes` of the nodes) and broken links (a
    /// share `breaks` of each direction), drawn from `rnd`.
    pub(crate) fn torn_grid(w: usize, h: usize, holes: f64, breaks: f64, rnd: &mut impl FnMut() -> f64) -> Grid {
        let mut g = Grid::from_active(w, h, (0..w * h).map(|_| rnd() >= holes).collect());
        for i in 0..w * h {
            if rnd() < breaks {
                g.link_right[i] = false;
            }
            if rnd() < breaks {
                g.link_down[i] = false;
            }
        }
        g
    }

    fn broken_right(g: &Grid) -> Vec<(usize, usize)> {
        let mut v = vec![];
        for y in 0..g.height {
            for x in 0..g.width - 1 {
                if !g.link_right[g.index(x, y)] {
                    v.push((x, y));
                }
            }
        }
        v
    }

    fn broken_down(g: &Grid) -> Vec<(usize, usize)> {
        let mut v = vec![];
        for y in 0..g.height - 1 {
            for x in 0..g.width {
                if !g.link_down[g.index(x, y)] {
                    v.push((x, y));
                }
            }
        }
        v
    }

    #[test]
    fn matte_deactivates_nodes_and_their_links() {
        let matte = [1, 1, 1, 1, 0, 1, 1, 1, 1];
        let g = Grid::from_matte(3, 3, &matte);
        assert!(!g.link_right[g.index(0, 1)] && !g.link_right[g.index(1, 1)]);
        assert!(!g.link_down[g.index(1, 0)] && !g.link_down[g.index(1, 1)]);
        assert!(g.link_right[g.index(0, 0)]);
        assert_eq!(g.link_count(), 8);
        assert!(g.is_consistent());
    }

    #[test]
    fn a_link_off_the_grid_or_to_an_inactive_node_is_inconsistent() {
        let matte = [1, 1, 1, 1, 0, 1, 1, 1, 1];
        let base = Grid::from_matte(3, 3, &matte);
        let mut bad = Vec::new();
        for (x, y, right) in [(0, 1, true), (1, 0, false), (2, 0, true), (0, 2, false), (1, 1, true)] {
            let mut g = base.clone();
            let i = g.index(x, y);
            if right {
                g.link_right[i] = true;
            } else {
                g.link_down[i] = true;
            }
            bad.push(g.is_consistent());
        }
        assert_eq!(bad, [false; 5]);
        let mut short = base.clone();
        short.active.pop();
        assert!(!short.is_consistent());
        assert!(Grid::new(0, 3).is_consistent() && Grid::new(4, 1).is_consistent());
    }

    #[test]
    fn vertical_cut_between_columns() {
        let mut g = Grid::new(5, 4);
        g.add_cut(&[[2.5, 0.5], [2.5, 2.5]]);
        assert_eq!(broken_right(&g), vec![(2, 1), (2, 2)]);
        assert!(broken_down(&g).is_empty());
    }

    #[test]
    fn cut_along_a_row_separates_it_from_the_row_above() {
        let mut g = Grid::new(4, 4);
        g.add_cut(&[[-1.0, 2.0], [5.0, 2.0]]);
        assert_eq!(broken_down(&g), (0..4).map(|x| (x, 1)).collect::<Vec<_>>());
        assert!(broken_right(&g).is_empty(), "collinear links stay");
        // The same line drawn the other way round gives the same result.
        let mut h = Grid::new(4, 4);
        h.add_cut(&[[5.0, 2.0], [-1.0, 2.0]]);
        assert_eq!(g, h);
    }

    #[test]
    fn cut_along_a_column_separates_it_from_the_column_left() {
        let mut g = Grid::new(4, 4);
        g.add_cut(&[[2.0, -1.0], [2.0, 5.0]]);
        assert_eq!(broken_right(&g), (0..4).map(|y| (1, y)).collect::<Vec<_>>());
        assert!(broken_down(&g).is_empty());
    }

    #[test]
    fn cut_ending_on_a_link_midpoint_follows_the_nudge() {
        // Ends at (1.5, 2.0), the midpoint of link (1,2)-(2,2). Nodes are nudged down by ε²,
        // so the link lies just below the end point: not crossed.
        let mut g = Grid::new(4, 4);
        g.add_cut(&[[1.5, -1.0], [1.5, 2.0]]);
        assert_eq!(broken_right(&g), vec![(1, 0), (1, 1)]);
        // Coming from below and ending at the same point crosses it.
        let mut h = Grid::new(4, 4);
        h.add_cut(&[[1.5, 5.0], [1.5, 2.0]]);
        assert_eq!(broken_right(&h), vec![(1, 2), (1, 3)]);
    }

    #[test]
    fn diagonal_through_node_centres_separates_without_gaps() {
        // y = x through nodes (0,0) ... (5,5): every node on the diagonal is nudged to the
        // upper-right side. Each lower-left node must be cut off from each upper-right one.
        let n = 6;
        let mut g = Grid::new(n, n);
        g.add_cut(&[[-1.0, -1.0], [2.0, 2.0], [6.0, 6.0]]);
        let side = |x: usize, y: usize| {
            // nudged: (x + ε) − (y + ε²) > 0 ⇔ upper-right (or on the line)
            x >= y
        };
        for y in 0..n {
            for x in 0..n {
                let i = g.index(x, y);
                if x + 1 < n {
                    assert_eq!(g.link_right[i], side(x, y) == side(x + 1, y), "right link at ({x},{y})");
                }
                if y + 1 < n {
                    assert_eq!(g.link_down[i], side(x, y) == side(x, y + 1), "down link at ({x},{y})");
                }
            }
        }
    }

    #[test]
    fn anti_diagonal_through_node_centres_separates_without_gaps() {
        let n = 6;
        let mut g = Grid::new(n, n);
        g.add_cut(&[[-1.0, 6.0], [2.0, 3.0], [6.0, -1.0]]);
        // line x + y = 5; nudged node sum x + y + ε + ε² > 5 for nodes on the line.
        let side = |x: usize, y: usize| x + y >= 5;
        for y in 0..n {
            for x in 0..n {
                let i = g.index(x, y);
                if x + 1 < n {
                    assert_eq!(g.link_right[i], side(x, y) == side(x + 1, y), "right link at ({x},{y})");
                }
                if y + 1 < n {
                    assert_eq!(g.link_down[i], side(x, y) == side(x, y + 1), "down link at ({x},{y})");
                }
            }
        }
    }

    #[test]
    fn closed_cut_isolates_its_inside() {
        let mut g = Grid::new(10, 10);
        g.add_cut(&[[2.3, 2.7], [7.1, 2.2], [6.6, 7.4], [2.9, 6.8], [2.3, 2.7]]);
        let (labels, count) = g.pieces();
        assert_eq!(count, 2);
        assert_ne!(labels[g.index(0, 0)], labels[g.index(5, 5)]);
    }

    #[test]
    fn degenerate_cuts_break_nothing() {
        let mut g = Grid::new(4, 4);
        g.add_cut(&[]);
        g.add_cut(&[[1.5, 1.5]]);
        g.add_cut(&[[1.5, 1.5], [1.5, 1.5]]);
        g.add_cut(&[[f64::NAN, 1.0], [2.0, 2.0]]);
        g.add_cut(&[[-10.0, -10.0], [-5.0, -3.0]]);
        assert_eq!(g, Grid::new(4, 4));
    }

    #[test]
    fn long_cut_outside_then_inside() {
        let mut g = Grid::new(8, 8);
        g.add_cut(&[[-100.0, 3.5], [100.0, 3.5]]);
        assert_eq!(broken_down(&g), (0..8).map(|x| (x, 3)).collect::<Vec<_>>());
        let (_, count) = g.pieces();
        assert_eq!(count, 2);
    }

    #[test]
    fn constraints_round_halves_up_and_count_drops() {
        let matte: Vec<u8> = (0..16).map(|i| if i == 5 { 0 } else { 1 }).collect();
        let g = Grid::from_matte(4, 4, &matte);
        let s = |x, y| Sample { rest: [x, y], displacement: [1.0, -1.0] };
        let c = constrain(
            &g,
            &[s(0.5, 0.5), s(-0.5, 0.0), s(-0.51, 0.0), s(3.49, 3.49), s(3.5, 0.0), s(1.0, 1.0), s(f64::NAN, 0.0)],
        );
        // (0.5,0.5)->(1,1) inactive; (-0.5,0)->(0,0); (-0.51,0) outside; (3.49,3.49)->(3,3);
        // (3.5,0)->(4,0) outside; (1,1) inactive; NaN dropped.
        assert_eq!(c.nodes, vec![g.index(0, 0), g.index(3, 3)]);
        assert_eq!((c.used_samples, c.dropped_samples), (2, 5));
    }

    #[test]
    fn constraints_match_their_plain_definition() {
        // The nearest node as ⌊p + ½⌋ with every check spelled out, and several samples on a
        // node averaged in the order given, against `nearest_node` and `constrain`, bit for
        // bit, on random points (many sharing nodes, some off the grid, some not finite)
        // and on edge values.
        let plain_nearest = |g: &Grid, p: [f64; 2]| {
            if !(p[0].is_finite() && p[1].is_finite()) {
                return None;
            }
            let (x, y) = ((p[0] + 0.5).floor(), (p[1] + 0.5).floor());
            (x >= 0.0 && y >= 0.0 && x < g.width as f64 && y < g.height as f64).then_some((x as usize, y as usize))
        };
        let matte: Vec<u8> = (0..7 * 5).map(|i| u8::from(i % 11 != 3)).collect();
        let g = Grid::from_matte(7, 5, &matte);
        let edges = [-0.5, -0.5000001, -0.49, 0.0, 6.49, 6.5, 4.5, 4.4999999, -1e300, 1e300, f64::INFINITY, f64::NEG_INFINITY, f64::NAN];
        for &a in &edges {
            for &b in &edges {
                assert_eq!(nearest_node(&g, [a, b]), plain_nearest(&g, [a, b]), "({a}, {b})");
            }
        }
        let mut rnd = sequence(3);
        let mut samples: Vec<Sample> = (0..400)
            .map(|_| Sample { rest: [rnd() * 9.0 - 1.0, rnd() * 7.0 - 1.0], displacement: [rnd() * 10.0 - 5.0, rnd() - 0.5] })
            .collect();
        samples[7].displacement[1] = f64::NAN;
        samples[9].rest[0] = f64::INFINITY;
        let mut sums: std::collections::BTreeMap<usize, ([f64; 2], f64)> = Default::default();
        let mut used = 0;
        for s in &samples {
            match plain_nearest(&g, s.rest) {
                Some((x, y)) if s.displacement.iter().all(|d| d.is_finite()) && g.active[g.index(x, y)] => {
                    let e = sums.entry(g.index(x, y)).or_insert(([0.0; 2], 0.0));
                    e.0 = [e.0[0] + s.displacement[0], e.0[1] + s.displacement[1]];
                    e.1 += 1.0;
                    used += 1;
                }
                _ => {}
            }
        }
        let c = constrain(&g, &samples);
        assert_eq!(c.nodes, sums.keys().copied().collect::<Vec<_>>());
        let bits = |v: &[[f64; 2]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&c.values), bits(&sums.values().map(|(s, n)| [s[0] / n, s[1] / n]).collect::<Vec<_>>()));
        assert_eq!((c.used_samples, c.dropped_samples), (used, samples.len() - used));
        assert!(sums.values().any(|&(_, n)| n >= 3.0) && used < samples.len() - 20);
    }

    #[test]
    fn pieces_label_in_order() {
        let g = Grid::from_matte(3, 1, &[1, 0, 1]);
        let (labels, count) = g.pieces();
        assert_eq!((labels, count), (vec![0, u32::MAX, 1], 2));
    }

    #[test]
    fn an_open_grid_is_one_piece_and_any_tear_makes_it_not_open() {
        for (w, h) in [(1, 1), (1, 5), (5, 1), (4, 3)] {
            let g = Grid::new(w, h);
            assert!(g.is_open());
            assert_eq!(g.pieces(), pieces_node_by_node(&g));
            for i in 0..w * h {
                let mut hole = g.clone();
                hole.active[i] = false;
                hole.link_right[i] = false;
                hole.link_down[i] = false;
                if i % w > 0 {
                    hole.link_right[i - 1] = false;
                }
                if i >= w {
                    hole.link_down[i - w] = false;
                }
                assert!(!hole.is_open());
                assert_eq!(hole.pieces(), pieces_node_by_node(&hole));
                for (right, present) in [(true, g.link_right[i]), (false, g.link_down[i])] {
                    if !present {
                        continue;
                    }
                    let mut cut = g.clone();
                    if right { cut.link_right[i] = false } else { cut.link_down[i] = false }
                    assert!(!cut.is_open());
                    assert_eq!(cut.pieces(), pieces_node_by_node(&cut));
                }
            }
        }
    }

    /// Pieces by union-find over every node, numbered by their first node.
    fn pieces_node_by_node(g: &Grid) -> (Vec<u32>, usize) {
        let n = g.len();
        let mut parent: Vec<usize> = (0..n).collect();
        fn find(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for i in 0..n {
            for (linked, j) in [(g.link_right[i], i + 1), (g.link_down[i], i + g.width)] {
                if linked {
                    let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
        let mut label_of_root = vec![u32::MAX; n];
        let mut labels = vec![u32::MAX; n];
        let mut count = 0;
        for i in (0..n).filter(|&i| g.active[i]) {
            let r = find(&mut parent, i);
            if label_of_root[r] == u32::MAX {
                label_of_root[r] = count;
                count += 1;
            }
            labels[i] = label_of_root[r];
        }
        (labels, count as usize)
    }

    /// Checks that a straight cut through the whole grid splits it into exactly the two
    /// link-components of its sides. `side(x, y)` is `Some(true/false)` for a node clearly on
    /// one side and `None` where the test cannot tell independently (left unchecked).
    fn assert_splits_in_two(g: &Grid, side: impl Fn(usize, usize) -> Option<bool>, what: &str) {
        let (labels, count) = g.pieces();
        let mut label_of = [None, None];
        for y in 0..g.height {
            for x in 0..g.width {
                if let Some(s) = side(x, y) {
                    let l = labels[g.index(x, y)];
                    let want = label_of[usize::from(s)].get_or_insert(l);
                    assert_eq!(*want, l, "{what}: node ({x},{y}) cut off from its side");
                }
            }
        }
        // A node on the line goes to a side by the tie rule; where no other node lies on
        // that side it is a piece of its own (a line through a corner node and past the grid).
        let mut on_line_only = vec![true; count];
        for y in 0..g.height {
            for x in 0..g.width {
                if side(x, y).is_some() {
                    on_line_only[labels[g.index(x, y)] as usize] = false;
                }
            }
        }
        let sides = label_of.iter().filter(|l| l.is_some()).count();
        let beside = count - on_line_only.iter().filter(|&&o| o).count();
        assert_eq!(beside, sides, "{what}: {beside} pieces off the line for {sides} sides");
        if let [Some(p), Some(q)] = label_of {
            assert_ne!(p, q, "{what}: the cut leaks");
        }
    }

    /// The side of node (x, y) of the line through integer points a, b, nudged by
    /// (+ε, +ε²), in exact integer arithmetic (the module's tie rule, written out).
    fn integer_side(a: [i64; 2], b: [i64; 2], x: i64, y: i64) -> bool {
        let o = (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
        let nudge = if b[1] != a[1] { a[1] - b[1] } else { b[0] - a[0] };
        if o != 0 { o > 0 } else { nudge > 0 }
    }

    #[test]
    fn the_cut_that_leaked_through_node_centres_separates() {
        // Its line passes through node centres up to rounding; the old crossing
        // abscissae, rounded differently for rows and columns, let the pieces touch.
        let mut g = Grid::new(64, 64);
        let (a, b) = ([-5.0, 40.7], [70.0, 33.2]);
        g.add_cut(&[a, b]);
        let side = |x: usize, y: usize| {
            let o = (b[0] - a[0]) * (y as f64 - a[1]) - (b[1] - a[1]) * (x as f64 - a[0]);
            (o.abs() > 1e-9).then_some(o > 0.0)
        };
        assert_splits_in_two(&g, side, "(-5, 40.7)-(70, 33.2)");
        assert_eq!(g.pieces().1, 2);
    }

    #[test]
    fn cuts_along_links_and_through_nodes_follow_the_one_rule() {
        // A horizontal cut along row 3, between nodes (1,3) and (4,3), both ends on nodes:
        // it lies on the links (1,3)-(2,3)-(3,3)-(4,3), breaks none of them, and breaks the
        // vertical links above nodes 1..=3 (the nodes are nudged right, so node 1, at the
        // cut's left end, moves under it and node 4, at its right end, past it).
        let mut g = Grid::new(6, 6);
        g.add_cut(&[[1.0, 3.0], [4.0, 3.0]]);
        assert!(broken_right(&g).is_empty());
        assert_eq!(broken_down(&g), vec![(1, 2), (2, 2), (3, 2)]);
        // A vertical cut along column 2 from node (2,1) to node (2,4) breaks the right links
        // left of nodes (2,1), (2,2), (2,3): nudged down, node (2,1) moves beside the cut
        // and node (2,4) below its end.
        let mut g = Grid::new(6, 6);
        g.add_cut(&[[2.0, 1.0], [2.0, 4.0]]);
        assert!(broken_down(&g).is_empty());
        assert_eq!(broken_right(&g), vec![(1, 1), (1, 2), (1, 3)]);
        // Through a node diagonally: the cut passes just left of node (2,2).
        let mut g = Grid::new(5, 5);
        g.add_cut(&[[0.5, 0.5], [3.5, 3.5]]);
        let i = g.index(2, 2);
        assert!(g.link_down[g.index(2, 1)] && !g.link_right[g.index(1, 2)] && g.link_right[i]);
        // A cut ending exactly on a vertical link's midpoint from the left does not reach
        // it (nodes nudged right); from the right it crosses it.
        let mut g = Grid::new(5, 5);
        g.add_cut(&[[-1.0, 2.5], [2.0, 2.5]]);
        assert_eq!(broken_down(&g), vec![(0, 2), (1, 2)]);
        let mut g = Grid::new(5, 5);
        g.add_cut(&[[6.0, 2.5], [2.0, 2.5]]);
        assert_eq!(broken_down(&g), vec![(2, 2), (3, 2), (4, 2)]);
        // A cut ending exactly on a node breaks the same links whichever way it is drawn.
        for (p, q) in [([0.3, -1.0], [2.0, 2.0]), ([4.7, 6.0], [2.0, 2.0]), ([-1.0, 2.0], [2.0, 2.0])] {
            let (mut g, mut h) = (Grid::new(5, 5), Grid::new(5, 5));
            g.add_cut(&[p, q]);
            h.add_cut(&[q, p]);
            assert_eq!(g, h, "{p:?}-{q:?}");
        }
    }

    #[test]
    fn cuts_along_the_border() {
        let (w, h) = (7, 5);
        // Along the top row and the left column: the nodes are nudged down and right,
        // inside the grid, so nothing is cut.
        let mut g = Grid::new(w, h);
        g.add_cut(&[[-1.0, 0.0], [8.0, 0.0]]);
        g.add_cut(&[[0.0, -1.0], [0.0, 6.0]]);
        assert_eq!(g, Grid::new(w, h));
        // Along the bottom row and the right column: that row and that column are cut off.
        let mut g = Grid::new(w, h);
        g.add_cut(&[[-1.0, 4.0], [8.0, 4.0]]);
        assert_eq!(broken_down(&g), (0..w).map(|x| (x, 3)).collect::<Vec<_>>());
        let mut g = Grid::new(w, h);
        g.add_cut(&[[6.0, 6.0], [6.0, -1.0]]);
        assert_eq!(broken_right(&g), (0..h).map(|y| (5, y)).collect::<Vec<_>>());
        // Around the whole border through the corner nodes: the bottom row and the right
        // column are one piece, the rest another.
        let mut g = Grid::new(w, h);
        g.add_cut(&[[0.0, 0.0], [6.0, 0.0], [6.0, 4.0], [0.0, 4.0], [0.0, 0.0]]);
        let (labels, count) = g.pieces();
        assert_eq!(count, 2);
        assert_eq!(labels[g.index(6, 0)], labels[g.index(0, 4)]);
        assert_ne!(labels[g.index(0, 0)], labels[g.index(6, 0)]);
    }

    #[test]
    fn cuts_far_outside_or_huge_break_nothing_and_never_panic() {
        let mut g = Grid::new(6, 6);
        g.add_cut(&[[-1e300, 2.5], [-1e299, 3.5]]);
        g.add_cut(&[[1e300, 1e300], [2e300, -1e300]]);
        g.add_cut(&[[f64::MAX, 0.0], [f64::MIN_POSITIVE, 1e-300]]);
        assert!(g.is_consistent());
        let mut open = Grid::new(6, 6);
        open.add_cut(&[[-1e300, 2.5], [-1e299, 3.5]]);
        assert_eq!(open, Grid::new(6, 6));
    }

    /// A point on the border of a `w × h` grid's box widened by `margin`, at parameter
    /// `t ∈ [0, 1)` around it, snapped to a multiple of `step`.
    fn border_point(w: usize, h: usize, margin: f64, t: f64, step: f64) -> [f64; 2] {
        let (x0, y0, x1, y1) = (-margin, -margin, (w - 1) as f64 + margin, (h - 1) as f64 + margin);
        let (bw, bh) = (x1 - x0, y1 - y0);
        let mut d = t * 2.0 * (bw + bh);
        let p = if d < bw {
            [x0 + d, y0]
        } else {
            d -= bw;
            if d < bh {
                [x1, y0 + d]
            } else {
                d -= bh;
                if d < bw { [x1 - d, y1] } else { [x0, y1 - (d - bw)] }
            }
        };
        p.map(|v| (v / step).round() * step)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(600))]

        #[test]
        fn a_border_to_border_cut_splits_the_grid_in_two(
            w in 2usize..70, h in 2usize..70, s in 0.0..1.0f64, t in 0.0..1.0f64, margin in 0.2..6.0f64,
        ) {
            // Endpoints at 0.1 px precision outside the grid: about 7 % of these leaked
            // with rounded crossing abscissae.
            let (a, b) = (border_point(w, h, margin, s, 0.1), border_point(w, h, margin, t, 0.1));
            let mut g = Grid::new(w, h);
            g.add_cut(&[a, b]);
            let side = |x: usize, y: usize| {
                let o = (b[0] - a[0]) * (y as f64 - a[1]) - (b[1] - a[1]) * (x as f64 - a[0]);
                (o.abs() > 1e-9).then_some(o > 0.0)
            };
            assert_splits_in_two(&g, side, &format!("{a:?}-{b:?} on {w}x{h}"));
        }

        #[test]
        fn a_cut_through_node_centres_splits_the_grid_exactly(
            w in 2usize..40, h in 2usize..40, s in 0.0..1.0f64, t in 0.0..1.0f64, margin in 1usize..4,
        ) {
            // Integer endpoints: the line runs through node centres wherever its slope
            // allows; every node is placed by the nudge, checked in exact integer arithmetic.
            let (a, b) = (border_point(w, h, margin as f64, s, 1.0), border_point(w, h, margin as f64, t, 1.0));
            let (ai, bi) = (a.map(|v| v as i64), b.map(|v| v as i64));
            let mut g = Grid::new(w, h);
            g.add_cut(&[a, b]);
            if ai != bi {
                assert_splits_in_two(&g, |x, y| Some(integer_side(ai, bi, x as i64, y as i64)), &format!("{a:?}-{b:?}"));
            }
        }

        #[test]
        fn a_cut_breaks_exactly_the_links_whose_nudged_nodes_it_separates(
            w in 2usize..20, h in 2usize..20, ax in -3i64..23, ay in -3i64..23, bx in -3i64..23, by in -3i64..23,
        ) {
            // Integer endpoints anywhere (inside the grid too): a link is broken iff its two
            // nudged nodes are on opposite sides of the line and the cut's ends are on
            // opposite sides of the link's nudged line.
            let (a, b) = ([ax, ay], [bx, by]);
            proptest::prop_assume!(a != b);
            let mut g = Grid::new(w, h);
            g.add_cut(&[[ax as f64, ay as f64], [bx as f64, by as f64]]);
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    let i = g.index(x as usize, y as usize);
                    let here = integer_side(a, b, x, y);
                    if x + 1 < w as i64 {
                        let crossed = here != integer_side(a, b, x + 1, y) && ((ay <= y) != (by <= y));
                        proptest::prop_assert_eq!(g.link_right[i], !crossed, "right link at ({},{})", x, y);
                    }
                    if y + 1 < h as i64 {
                        let crossed = here != integer_side(a, b, x, y + 1) && ((ax <= x) != (bx <= x));
                        proptest::prop_assert_eq!(g.link_down[i], !crossed, "down link at ({},{})", x, y);
                    }
                }
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]

        #[test]
        fn pieces_by_runs_match_pieces_node_by_node(
            w in 1usize..24, h in 1usize..24, seed: u64, holes in 0.0..0.6f64, breaks in 0.0..0.5f64,
        ) {
            let g = torn_grid(w, h, holes, breaks, &mut sequence(seed));
            proptest::prop_assert_eq!(g.pieces(), pieces_node_by_node(&g));
        }
    }
}

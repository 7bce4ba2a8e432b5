//! The grid hierarchy: the finest operator read off the links, link-aware prolongation, Galerkin coarse
//! operators stored per node, and the matrix-vector kernels. Vectors are padded by two inactive nodes around
//! the grid, so 5 × 5 stencils never leave the array; values are pairs (Δx, Δy) sharing every operator. The
//! solution and residual are `f64` ([`V2`]); the cycles that precondition them run in `f32` ([`W2`]): half
//! the memory streamed, twice the lanes. Operators are built in `f64`.

use std::ops::{Add, AddAssign, Mul, Sub};

use rayon::prelude::*;

use super::wide::widest;

/// Padding around every level's vectors.
pub(crate) const PAD: usize = 2;

/// Vector entry of the solution and residual: (Δx, Δy).
pub(crate) type V2 = [f64; 2];
/// Vector entry of the multigrid cycles' work vectors.
pub(crate) type W2 = [WS; 2];
/// The precision of the multigrid cycles.
pub(crate) type WS = f32;

/// The two precisions the kernels run in.
pub(crate) trait Real: Copy + Send + Sync + PartialEq + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + AddAssign + 'static {
    const ZERO: Self;
    fn of(v: f64) -> Self;
    fn get(self) -> f64;
    /// The table of a Galerkin level in this precision.
    fn table<'a>(wide: &'a [[f64; 25]], narrow: &'a [[f32; 25]]) -> &'a [[Self; 25]];
    /// The vector itself where `Self` is `f32` (the precision of [`Real::four_run`]).
    fn as_f32(v: &[[Self; 2]]) -> Option<&[[f32; 2]]>;
    fn as_f32_mut(v: &mut [[Self; 2]]) -> Option<&mut [[f32; 2]]>;
    /// Whether [`Real::four_run`] takes four nodes to a vector here.
    fn has_four_stencils() -> bool { false }
    /// `out[j] = f[q₀ + j] − Σₜ sⱼ[t] x[q₀ + j + offset(t)]` for the `4n + tail` nodes from `q₀` (`tail` < 4),
    /// in [`STORED_TAPS`] order, coefficients four nodes to a block of `blocks` ([`Fours`]).
    fn four_run(_x: &[[Self; 2]], _f: Option<&[[Self; 2]]>, _q0: usize, _n: usize, _tail: usize, _wp: usize, _blocks: &[FourBlock], _out: &mut [[Self; 2]]) {
        unreachable!("only where has_four_stencils")
    }
}

/// The taps of a Galerkin stencil, (row, column) in its 5 × 5 window: its corners are always zero.
const STORED_TAPS: [(usize, usize); 21] = [
    (0, 1), (0, 2), (0, 3),
    (1, 0), (1, 1), (1, 2), (1, 3), (1, 4),
    (2, 0), (2, 1), (2, 2), (2, 3), (2, 4),
    (3, 0), (3, 1), (3, 2), (3, 3), (3, 4),
    (4, 1), (4, 2), (4, 3),
];

impl Real for f64 {
    const ZERO: f64 = 0.0;
    #[inline(always)]
    fn of(v: f64) -> f64 { v }
    #[inline(always)]
    fn get(self) -> f64 { self }
    fn table<'a>(wide: &'a [[f64; 25]], _: &'a [[f32; 25]]) -> &'a [[f64; 25]] { wide }
    fn as_f32(_: &[[f64; 2]]) -> Option<&[[f32; 2]]> { None }
    fn as_f32_mut(_: &mut [[f64; 2]]) -> Option<&mut [[f32; 2]]> { None }
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    #[inline(always)]
    fn of(v: f64) -> f32 { v as f32 }
    #[inline(always)]
    fn get(self) -> f64 { self as f64 }
    fn table<'a>(_: &'a [[f64; 25]], narrow: &'a [[f32; 25]]) -> &'a [[f32; 25]] { narrow }
    fn as_f32(v: &[[f32; 2]]) -> Option<&[[f32; 2]]> { Some(v) }
    fn as_f32_mut(v: &mut [[f32; 2]]) -> Option<&mut [[f32; 2]]> { Some(v) }
    #[cfg(target_arch = "x86_64")]
    fn has_four_stencils() -> bool { super::wide::avx2() }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn four_run(x: &[[f32; 2]], f: Option<&[[f32; 2]]>, q0: usize, n: usize, tail: usize, wp: usize, blocks: &[FourBlock], out: &mut [[f32; 2]]) {
        // SAFETY: `has_four_stencils` (the only way here) found AVX2 on the processor.
        #[allow(unsafe_code)]
        unsafe { four_run_avx2(x, f, q0, n, tail, wp, blocks, out) }
    }
}

/// [`Real::four_run`] in `f32`, a four's two components the eight lanes of a 256-bit vector, multiplied then
/// added as the plain sums are (bit for bit theirs). Two fours at a time, so their addition chains overlap;
/// the tail's four reads past the run by zero coefficients.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(unsafe_code)]
unsafe fn four_run_avx2(x: &[[f32; 2]], f: Option<&[[f32; 2]]>, q0: usize, n: usize, tail: usize, wp: usize, blocks: &[FourBlock], out: &mut [[f32; 2]]) {
    use std::arch::x86_64::{
        __m256, _mm256_add_ps, _mm256_castps128_ps256, _mm256_loadu_ps, _mm256_mul_ps, _mm256_permutevar8x32_ps, _mm256_setr_epi32,
        _mm256_setzero_ps, _mm256_storeu_ps, _mm256_sub_ps, _mm_loadu_ps,
    };
    // Every load and store below stays within these: node q's taps reach q ± (2 wp + 2), the last node is q₀ + 4m − 1.
    let m = n + usize::from(tail > 0);
    assert!(tail < 4, "a tail of four nodes or more");
    assert!(q0 >= 2 * wp + 2 && q0 + 4 * m + 2 * wp + 2 <= x.len(), "a run's taps outside its level");
    assert!(blocks.len() >= m && out.len() >= 4 * n + tail && f.map_or(true, |f| q0 + 4 * n + tail <= f.len()), "a run longer than its blocks");
    let pairs = _mm256_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3);
    let (xs, coefs, outs) = (x.as_flattened().as_ptr(), blocks.as_ptr() as *const f32, out.as_flattened_mut().as_mut_ptr());
    // Four j's product at tap t (`first` its first tap's flattened index, `b` its block).
    // SAFETY: j < m, so every tap is within `x` and the block within `blocks` (asserted above).
    let tap = |first: usize, b: *const f32, t: usize| unsafe {
        let c = _mm256_permutevar8x32_ps(_mm256_castps128_ps256(_mm_loadu_ps(b.add(4 * t))), pairs);
        let (dy, dx) = STORED_TAPS[t];
        _mm256_mul_ps(c, _mm256_loadu_ps(xs.add(first + 2 * (dy * wp + dx))))
    };
    let first = |j: usize| 2 * (q0 + 4 * j - 2 * wp - 2);
    // Four j's residual, of its first `tail` nodes only for the tail's four (j = n).
    let put = |j: usize, acc: __m256| {
        if j < n {
            // SAFETY: j < n, so its eight values are within `out` and `f`.
            unsafe {
                let fv = f.map_or(_mm256_setzero_ps(), |f| _mm256_loadu_ps(f.as_flattened().as_ptr().add(2 * (q0 + 4 * j))));
                _mm256_storeu_ps(outs.add(8 * j), _mm256_sub_ps(fv, acc));
            }
            return;
        }
        let mut sums = [0.0f32; 8];
        // SAFETY: `sums` holds eight values.
        unsafe { _mm256_storeu_ps(sums.as_mut_ptr(), acc) };
        for k in 0..2 * tail {
            let fv = f.map_or(0.0, |f| f[q0 + 4 * n + k / 2][k % 2]);
            // SAFETY: k < 2 tail, so the value is within `out` (asserted above).
            unsafe { *outs.add(8 * n + k) = fv - sums[k] };
        }
    };
    let mut j = 0;
    while j + 2 <= m {
        let (fa, fb) = (first(j), first(j + 1));
        // SAFETY: j + 1 < m.
        let (ba, bb) = unsafe { (coefs.add(84 * j), coefs.add(84 * (j + 1))) };
        let (mut a, mut b) = (_mm256_setzero_ps(), _mm256_setzero_ps());
        for t in 0..21 {
            a = _mm256_add_ps(a, tap(fa, ba, t));
            b = _mm256_add_ps(b, tap(fb, bb, t));
        }
        put(j, a);
        put(j + 1, b);
        j += 2;
    }
    if j < m {
        // SAFETY: j < m.
        let ba = unsafe { coefs.add(84 * j) };
        let mut a = _mm256_setzero_ps();
        for t in 0..21 {
            a = _mm256_add_ps(a, tap(first(j), ba, t));
        }
        put(j, a);
    }
}

/// The coefficients of four consecutive nodes with own stencils, tap by tap, the four side by side.
pub(crate) type FourBlock = [[f32; 4]; 21];

/// A Galerkin level's own stencils in fours of nodes from each run's start (a short last four padded with
/// zeros), one [`FourBlock`] each, as [`band_residual`] takes them; empty without AVX2.
#[derive(Debug, Default)]
pub(crate) struct Fours {
    blocks: Vec<FourBlock>,
    /// The first block of each padded row.
    row_first: Vec<u32>,
}

impl Fours {
    /// The fours of the own stencils `ids` (into `narrow`) on the level's `runs`.
    pub(crate) fn new(ids: &[u32], narrow: &[[f32; 25]], runs: &Runs, wp: usize, h: usize) -> Fours {
        if !f32::has_four_stencils() { return Fours::default(); }
        let mut fours = Fours { blocks: Vec::new(), row_first: vec![0; h + 2 * PAD] };
        for r in PAD..PAD + h {
            fours.row_first[r] = fours.blocks.len() as u32;
            for run in runs.row(r).iter().filter(|run| run.kind == RunKind::Own) {
                let (c, e) = (run.start as usize, run.end as usize);
                for i in (c..e).step_by(4) {
                    let s: [Option<&[f32; 25]>; 4] = std::array::from_fn(|j| (i + j < e).then(|| &narrow[ids[r * wp + i + j] as usize]));
                    fours.blocks.push(std::array::from_fn(|t| {
                        let (dy, dx) = STORED_TAPS[t];
                        s.map(|s| s.map_or(0.0, |s| s[dy * 5 + dx]))
                    }));
                }
            }
        }
        fours
    }
}

/// How a level's product treats a run of nodes (see [`Runs`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RunKind {
    /// No unknowns: the product writes zeros.
    Skip,
    /// Unknowns that share the level's regular stencil (the finest level's interior molecule).
    Shared,
    /// Unknowns with stencils of their own (on the finest level, those not regular: see [`OwnStencils`]).
    Own,
}

/// One run of a row: padded columns `start..end`, all of one kind.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Run {
    pub start: u32,
    pub end: u32,
    pub kind: RunKind,
    /// On the finest level, a run of [`RunKind::Own`]: its first node's entry in [`OwnStencils::ids`].
    pub at: u32,
}

/// The stencils of the finest level's irregular nodes (at borders, holes and cuts), as 5 × 5 rows
/// ([`fine_row`]) in a table without repeats, summed as Galerkin ones.
#[derive(Clone, Debug, Default)]
pub(crate) struct OwnStencils {
    table: Vec<[f64; 25]>,
    narrow: Vec<[f32; 25]>,
    /// Each such node's stencil, the runs' nodes in order (see [`Run::at`]).
    ids: Vec<u32>,
}

impl OwnStencils {
    /// Numbers the [`RunKind::Own`] runs of `runs` (a level `wp` wide) and takes their nodes' stencils `row_of(p)`.
    fn new(runs: &mut Runs, wp: usize, row_of: impl Fn(usize) -> [f64; 25]) -> OwnStencils {
        let (mut distinct, mut ids) = (DistinctStencils::default(), Vec::new());
        for (r, ab) in runs.first.windows(2).enumerate() {
            for run in runs.runs[ab[0] as usize..ab[1] as usize].iter_mut().filter(|run| run.kind == RunKind::Own) {
                run.at = ids.len() as u32;
                ids.extend((run.start as usize..run.end as usize).map(|c| distinct.id(row_of(r * wp + c))));
            }
        }
        OwnStencils { narrow: distinct.table.iter().map(|s| s.map(|a| a as f32)).collect(), table: distinct.table, ids }
    }
}

/// Stencils stored once each (a constraint's, border's or cut's neighbourhood recurs all over a level), so
/// the table stays in cache; `index` finds an entry by its bits.
#[derive(Default)]
struct DistinctStencils {
    table: Vec<[f64; 25]>,
    index: std::collections::HashMap<[u64; 25], u32>,
}

impl DistinctStencils {
    /// The entry of stencil `s`, added if it is new.
    fn id(&mut self, s: [f64; 25]) -> u32 {
        let table = &mut self.table;
        *self.index.entry(s.map(f64::to_bits)).or_insert_with(|| {
            table.push(s);
            (table.len() - 1) as u32
        })
    }
}

/// Each row of a level split into runs of one [`RunKind`], so that the products do not test each node's kind.
#[derive(Clone, Debug, Default)]
pub(crate) struct Runs {
    /// Row r's runs are `runs[first[r]..first[r + 1]]` (padded rows; padding rows have none).
    first: Vec<u32>,
    runs: Vec<Run>,
}

impl Runs {
    /// The runs of the columns `PAD..PAD + w` of the `h` body rows of a level `wp` wide, node p of kind `kind(p)`.
    pub(crate) fn new(wp: usize, w: usize, h: usize, kind: impl Fn(usize) -> RunKind) -> Runs {
        let mut runs = Runs { first: vec![0; PAD + 1], runs: Vec::new() };
        for base in (PAD..PAD + h).map(|r| r * wp) {
            let mut c = PAD;
            while c < PAD + w {
                let k = kind(base + c);
                let e = (c + 1..PAD + w).find(|&e| kind(base + e) != k).unwrap_or(PAD + w);
                runs.runs.push(Run { start: c as u32, end: e as u32, kind: k, at: 0 });
                c = e;
            }
            runs.first.push(runs.runs.len() as u32);
        }
        runs.first.resize(h + 2 * PAD + 1, runs.runs.len() as u32);
        runs
    }

    #[inline]
    pub(crate) fn row(&self, r: usize) -> &[Run] { &self.runs[self.first[r] as usize..self.first[r + 1] as usize] }
}

/// Node flags of the finest level.
pub(crate) mod bit {
    /// Active and not fixed: an unknown.
    pub const FREE: u8 = 1;
    /// Horizontal, vertical triples centred here (links either side).
    pub const HTRI: u8 = 2;
    pub const VTRI: u8 = 4;
    /// 2 × 2 cell with this node as its top-left corner and all four links.
    pub const CELL: u8 = 8;
    /// Links to the right neighbour, to the one below.
    pub const RIGHT: u8 = 16;
    pub const DOWN: u8 = 32;
    /// Free, with every term of the interior 13-point molecule present.
    pub const REGULAR: u8 = 128;
}

/// Rows per parallel task; the transfers and Galerkin build of levels below `PAR_MIN_NODES` run on one thread.
const PAR_ROWS: usize = 16;
const PAR_MIN_NODES: usize = 4_000;

/// Geometry of one level: active nodes and links (unpadded, row-major).
#[derive(Clone, Debug)]
pub(crate) struct Geometry {
    pub w: usize,
    pub h: usize,
    pub active: Vec<bool>,
    pub right: Vec<bool>,
    pub down: Vec<bool>,
    /// Only on the finest level: fixed (Dirichlet) nodes, whose prolongation rows vanish.
    pub fixed: Option<Vec<bool>>,
    /// Prolongation rows in 24ths on the 2 × 2 coarse corners of each node, or [`EXT`] for a row in `ext`.
    pub prow: Vec<[u8; 4]>,
    /// The rows that reach past the 2 × 2 corners, by node index, sorted (see [`Geometry::geo_row`]).
    pub ext: Vec<(u32, [f64; 16])>,
    /// `plain_rows[y]`: every node of row y is active with the plain bilinear row (fixed or not), so
    /// [`restrict`] and [`prolong_add_scaled`] run the plain formulas there.
    pub plain_rows: Vec<bool>,
}

impl Geometry {
    /// An open `w × h` box: every node active and linked, none fixed.
    pub fn open(w: usize, h: usize) -> Geometry {
        let crate::grid::Grid { active, link_right, link_down, .. } = crate::grid::Grid::new(w, h);
        Geometry::new(w, h, active, link_right, link_down, None)
    }

    #[inline]
    fn idx(&self, x: usize, y: usize) -> usize { y * self.w + x }

    /// A geometry with its prolongation rows. A 2 × 2 row's weights are multiples of 1/24 (halves and
    /// averages of up to four): the codes are exact.
    pub fn new(w: usize, h: usize, active: Vec<bool>, right: Vec<bool>, down: Vec<bool>, fixed: Option<Vec<bool>>) -> Geometry {
        let mut g = Geometry { w, h, active, right, down, fixed, prow: Vec::with_capacity(w * h), ext: Vec::new(), plain_rows: Vec::new() };
        // A row's codes, its rows past the corners, and whether it is plain.
        type Row = (Vec<[u8; 4]>, Vec<(u32, [f64; 16])>, bool);
        let rows: Vec<Row> = (0..h).into_par_iter().with_min_len(PAR_ROWS).map(|y| {
            let (mut prow, mut ext, mut plain) = (vec![[0u8; 4]; w], Vec::new(), true);
            for x in 0..w {
                let i = g.idx(x, y);
                let fixed = g.fixed.as_ref().is_some_and(|f| f[i]);
                if g.linked_around(x, y) {
                    if !fixed { prow[x] = PLAIN_CODES[(y & 1) * 2 + (x & 1)]; }
                    continue;
                }
                let r = g.geo_row(x, y);
                plain &= g.active[i] && r == plain_row(x, y);
                if fixed { continue; }
                // Stored whole where codes cannot be: past the corners, negative, or on the far corner along
                // an even coordinate (the coded rows' loops take coarse c from fine 2c − 1).
                let far_corner = (x % 2 == 0 && (r[6] != 0.0 || r[10] != 0.0)) || (y % 2 == 0 && (r[9] != 0.0 || r[10] != 0.0));
                if far_corner || CORNERS.iter().map(|&k| r[k]).sum::<f64>() != r.iter().sum::<f64>() || r.iter().any(|&v| v < 0.0) {
                    prow[x] = [EXT; 4];
                    ext.push((i as u32, r));
                    continue;
                }
                for (c, &k) in prow[x].iter_mut().zip(&CORNERS) {
                    let n = (r[k] * 24.0).round();
                    debug_assert!((n / 24.0 - r[k]).abs() < 1e-12);
                    *c = n as u8;
                }
            }
            (prow, ext, plain)
        }).collect();
        for (prow, ext, plain) in rows {
            g.prow.extend(prow);
            g.ext.extend(ext);
            g.plain_rows.push(plain);
        }
        g
    }

    /// The next coarser geometry: node (X, Y) sits on (2X, 2Y) ([`coarse_links`] at step 2).
    pub fn coarsen(&self) -> Geometry {
        // ⌊n/2⌋ + 1 coarse nodes: for an even n the last is a ghost at fine position n, so the last fine node
        // sits between two coarse nodes and interpolation reproduces linear functions there.
        let (w, h, [active, right, down]) = coarse_links(self.w, self.h, 2, &self.active, &self.right, &self.down);
        Geometry::new(w, h, active, right, down, None)
    }

    /// Whether the geometry has inactive nodes or missing links between active neighbours.
    pub fn torn(&self) -> bool { crate::grid::torn(self.w, &self.active, &self.right, &self.down) }

    /// Whether two active neighbours are not linked: a cut inside the piece (holes and the matte's edges leave none).
    pub fn cut_inside(&self) -> bool {
        let (w, n) = (self.w, self.active.len());
        (0..n).any(|i| self.active[i] && ((i % w + 1 < w && self.active[i + 1] && !self.right[i]) || (i + w < n && self.active[i + w] && !self.down[i])))
    }

    /// Whether node (x, y) is active with every link its row reads: then its row is the plain bilinear one.
    fn linked_around(&self, x: usize, y: usize) -> bool {
        let r = |x: usize, y: usize| x + 1 == self.w || self.right[self.idx(x, y)];
        let d = |x: usize, y: usize| y + 1 == self.h || self.down[self.idx(x, y)];
        self.active[self.idx(x, y)]
            && match (x & 1, y & 1) {
                (0, 0) => true,
                (1, 0) => r(x - 1, y) && r(x, y),
                (0, 1) => d(x, y - 1) && d(x, y),
                _ => {
                    r(x - 1, y) && r(x, y) && d(x, y - 1) && d(x, y) && d(x - 1, y - 1) && d(x - 1, y) && r(x - 1, y - 1) && r(x, y - 1)
                        && (x + 1 == self.w || d(x + 1, y - 1) && d(x + 1, y))
                        && (y + 1 == self.h || r(x - 1, y + 1) && r(x, y + 1))
                }
            }
    }

    /// Link-aware prolongation row of node (x, y), fixed or not: weights of coarse nodes (x / 2 + ox, y / 2 + oy),
    /// ox, oy = −1..=2, at slot `(oy + 1) * 4 + ox + 1`. Between linked coarse neighbours, bilinear; at a missing
    /// link, the linear extrapolation from the node's own side (a free edge's zero second difference), or the
    /// linked neighbour's value where that side is too short; an odd–odd node averages its linked edge
    /// neighbours' rows. On the finest level, a node at a cut's vertex whose only link continues straight on
    /// takes that neighbour's row, within its own window (else no coarse function would move it;
    /// docs/dev/solver-correctness.md).
    pub fn geo_row(&self, x: usize, y: usize) -> [f64; 16] {
        let r = self.link_row(x, y);
        if r.iter().any(|&v| v != 0.0) || !self.active[self.idx(x, y)] || self.fixed.is_none() { return r; }
        let (w, i) = (self.w, self.idx(x, y));
        // The node's links (down, up, right, left), and whether each continues straight on.
        let links = [
            (self.down[i], y + 2 < self.h && self.down[i + w], (x, y + 1)),
            (y > 0 && self.down[i - w], y > 1 && self.down[i.wrapping_sub(2 * w)], (x, y.wrapping_sub(1))),
            (self.right[i], x + 2 < w && self.right[i + 1], (x + 1, y)),
            (x > 0 && self.right[i - 1], x > 1 && self.right[i.wrapping_sub(2)], (x.wrapping_sub(1), y)),
        ];
        let mut linked = links.iter().filter(|l| l.0);
        match (linked.next(), linked.next()) {
            // The neighbour's row moved to this node's window (its coarse cell may be the next one); weights
            // past the window dropped, the rest scaled to sum to one.
            (Some(&(_, true, (qx, qy))), None) => {
                let (dx, dy, mut moved) = ((qx / 2) as isize - (x / 2) as isize, (qy / 2) as isize - (y / 2) as isize, [0.0; 16]);
                for (s, &v) in self.link_row(qx, qy).iter().enumerate() {
                    let (i, j) = ((s % 4) as isize + dx, (s / 4) as isize + dy);
                    if (0..4).contains(&i) && (0..4).contains(&j) { moved[(j * 4 + i) as usize] = v }
                }
                let sum: f64 = moved.iter().sum();
                if sum.abs() < 0.5 { r } else { moved.map(|v| v / sum) }
            }
            _ => r,
        }
    }

    /// [`Geometry::geo_row`] from the node's own links alone.
    fn link_row(&self, x: usize, y: usize) -> [f64; 16] {
        let i = self.idx(x, y);
        let mut r = [0.0; 16];
        if !self.active[i] { return r; }
        match (x & 1, y & 1) {
            (0, 0) => r[5] = 1.0,
            (1, 0) => r = self.along(x, y, false, 0),
            (0, 1) => r = self.along(x, y, true, 0),
            _ => {
                // Its linked edge neighbours' rows (the first two along their column, the others along their
                // row); past the last column (row), the ghost coarse node's (see `coarsen`).
                let parts = [
                    self.right[i - 1].then_some((x - 1, y, 0)),
                    if x + 1 == self.w { Some((x, y, 1)) } else { self.right[i].then_some((x + 1, y, 1)) },
                    self.down[i - self.w].then_some((x, y - 1, 0)),
                    if y + 1 == self.h { Some((x, y, 1)) } else { self.down[i].then_some((x, y + 1, 1)) },
                ];
                let rows: [[f64; 16]; 4] = std::array::from_fn(|k| parts[k].map_or([0.0; 16], |(px, py, o)| self.along(px, py, k < 2, o)));
                let has = rows.map(|row| row.iter().sum::<f64>() > 0.0);
                // Opposite neighbours: their mean. One in each direction: the bilinear completion through the
                // coarse corner they share, when linked to it. Else the mean of what there is.
                let mean = |ks: &[usize], r: &mut [f64; 16]| {
                    for &k in ks { r.iter_mut().zip(&rows[k]).for_each(|(a, v)| *a += v / ks.len() as f64); }
                };
                match (has, (0..2).find(|&k| has[k]), (2..4).find(|&k| has[k])) {
                    ([true, true, true, true], ..) => mean(&[0, 1, 2, 3], &mut r),
                    ([true, true, ..], ..) => mean(&[0, 1], &mut r),
                    ([.., true, true], ..) => mean(&[2, 3], &mut r),
                    (_, Some(hk), Some(vk)) => {
                        // The corner (ox, oy) shared by the edge neighbours hk and vk.
                        let (ox, oy) = (hk, vk - 2);
                        let (cx, cy) = (x - 1 + 2 * ox, y - 1 + 2 * oy);
                        let ci = self.idx(cx.min(self.w - 1), cy.min(self.h - 1));
                        let linked = cx < self.w && cy < self.h && self.active[ci] && {
                            let (ex, ey) = (self.idx(cx, y), self.idx(x, cy));
                            (if oy == 0 { self.down[ci] } else { self.down[ex] }) && (if ox == 0 { self.right[ci] } else { self.right[ey] })
                        };
                        if linked {
                            for k in [hk, vk] { r.iter_mut().zip(&rows[k]).for_each(|(a, v)| *a += v); }
                            r[(oy + 1) * 4 + ox + 1] -= 1.0;
                        } else {
                            mean(&[hk, vk], &mut r);
                        }
                    }
                    (_, Some(k), None) | (_, None, Some(k)) => mean(&[k], &mut r),
                    _ => {}
                }
            }
        }
        r
    }

    /// The row of node (x, y), odd along its row (column when `vertical`), on window row (column) `o`
    /// ([`extend`]); the last node of an even-sized line has the ghost coarse node beyond it.
    fn along(&self, x: usize, y: usize, vertical: bool, o: usize) -> [f64; 16] {
        let i = self.idx(x, y);
        let (links, s, t, n) = if vertical { (&self.down, self.w, y, self.h) } else { (&self.right, 1, x, self.w) };
        // Linear across a cut (the node beyond the gap active) where two more links run away.
        let fa = t >= 3 && t + 1 < n && self.active[i + s] && links[i - 2 * s] && links[i - 3 * s];
        let fb = t + 3 < n && self.active[i - s] && links[i + s] && links[i + 2 * s];
        let mut r = [0.0; 16];
        for (k, v) in extend(links[i - s], t + 1 == n || links[i], fa, fb).into_iter().enumerate() {
            r[if vertical { k * 4 + o + 1 } else { (o + 1) * 4 + k }] = v;
        }
        r
    }

    /// `f(ox, oy, weight)` for each nonzero weight of node (x, y)'s prolongation row (none for a fixed node), offsets from (x / 2, y / 2).
    #[inline]
    pub fn p_row(&self, x: usize, y: usize, mut f: impl FnMut(isize, isize, f64)) {
        let i = self.idx(x, y);
        let c = self.prow[i];
        if c[0] == EXT {
            let k = self.ext.partition_point(|e| (e.0 as usize) < i);
            for (s, &v) in self.ext[k].1.iter().enumerate().filter(|e| *e.1 != 0.0) {
                f((s % 4) as isize - 1, (s / 4) as isize - 1, v);
            }
            return;
        }
        for (s, &v) in c.iter().enumerate().filter(|e| *e.1 != 0) { f((s & 1) as isize, (s >> 1) as isize, v as f64 / 24.0); }
    }

    /// The fine positions along one axis (`n` nodes) whose rows can reach coarse node `c`.
    pub fn children(&self, c: usize, n: usize) -> std::ops::RangeInclusive<usize> {
        let (below, above) = if !self.ext.is_empty() { (4, 3) } else { (1, 1) };
        (2 * c).saturating_sub(below)..=(2 * c + above).min(n - 1)
    }

    /// The weight of coarse node (xc, yc) in the row of node (x, y).
    pub fn weight(&self, x: usize, y: usize, xc: usize, yc: usize) -> f64 {
        let (ox, oy) = (xc as isize - (x / 2) as isize, yc as isize - (y / 2) as isize);
        if !(-1..3).contains(&ox) || !(-1..3).contains(&oy) { return 0.0; }
        let mut w = 0.0;
        self.p_row(x, y, |a, b, v| if (a, b) == (ox, oy) { w = v });
        w
    }
}

/// Summed-area table of flags on a `w × h` grid: how many lie in a window, in O(1).
pub(crate) struct Sat { w: usize, h: usize, table: Vec<u32> }

impl Sat {
    pub fn new(w: usize, h: usize, flag: impl Fn(usize) -> bool) -> Sat {
        let (mut table, v) = (vec![0u32; (w + 1) * (h + 1)], w + 1);
        for (y, x) in (0..h).flat_map(|y| (0..w).map(move |x| (y, x))) {
            table[(y + 1) * v + x + 1] = table[y * v + x + 1] + table[(y + 1) * v + x] - table[y * v + x] + flag(y * w + x) as u32;
        }
        Sat { w, h, table }
    }

    /// The flags in columns `x0..x1` and rows `y0..y1`, the window clipped to the grid.
    pub fn count(&self, [x0, y0]: [usize; 2], [x1, y1]: [usize; 2]) -> u32 {
        let at = |x: usize, y: usize| self.table[y.min(self.h) * (self.w + 1) + x.min(self.w)];
        at(x1, y1) + at(x0, y0) - at(x1, y0) - at(x0, y1)
    }
}

/// Whether a piece (`active`, linked `right` and `down` on its `w × h` box) is solid: its cuts stay more than
/// 4 nodes inside it, and its core (nodes whose 5 × 5 window lies in it, clear of cuts) is one 4-connected set
/// within 4 nodes of every node. Filling around anything narrower than 5 nodes, or a cut to the edge, would tie
/// it to its neighbours across the gap, its slow motions out of the coarse space (docs/dev/coarse-space.md, "Filling off the matte").
pub(crate) fn solid(w: usize, h: usize, active: &[bool], right: &[bool], down: &[bool]) -> bool {
    // The nodes at a cut: two active neighbours without their link.
    let mut cut = vec![false; w * h];
    for i in (0..w * h).filter(|&i| active[i]) {
        let across = [(i % w + 1 < w).then_some((i + 1, right[i])), (i + w < w * h).then_some((i + w, down[i]))];
        for (j, linked) in across.into_iter().flatten() {
            if active[j] && !linked { (cut[i], cut[j]) = (true, true); }
        }
    }
    // Whether any node of `v` lies within Chebyshev distance r.
    let near = |v: &[bool], r: usize| -> Vec<bool> {
        let sat = Sat::new(w, h, |i| v[i]);
        (0..w * h).map(|i| sat.count([(i % w).saturating_sub(r), (i / w).saturating_sub(r)], [i % w + r + 1, i / w + r + 1]) > 0).collect()
    };
    if cut.contains(&true) && near(&cut, 4).iter().zip(active).any(|(n, a)| *n && !a) { return false; }
    let core: Vec<bool> = near(&(0..w * h).map(|i| !active[i] || cut[i]).collect::<Vec<_>>(), 2).iter().map(|o| !o).collect();
    let reach = near(&core, 4);
    (0..w * h).all(|i| !active[i] || reach[i]) && crate::grid::Grid::from_active(w, h, core).pieces().1 == 1
}

/// Every `s`-th node of a `w × h` grid: node (X, Y) on (min(sX, w − 1), min(sY, h − 1)), active where that node
/// is; neighbours linked where every link of the straight path between them is.
pub(crate) fn coarse_links(w: usize, h: usize, s: usize, active: &[bool], right: &[bool], down: &[bool]) -> (usize, usize, [Vec<bool>; 3]) {
    let (wc, hc) = ((w - 1).div_ceil(s) + 1, (h - 1).div_ceil(s) + 1);
    let (px, py) = (|x: usize| (x * s).min(w - 1), |y: usize| (y * s).min(h - 1));
    let mut out = [vec![false; wc * hc], vec![false; wc * hc], vec![false; wc * hc]];
    for (yc, xc) in (0..hc).flat_map(|yc| (0..wc).map(move |xc| (yc, xc))) {
        let (c, fx, fy) = (yc * wc + xc, px(xc), py(yc));
        out[0][c] = active[fy * w + fx];
        out[1][c] = xc + 1 < wc && (fx..px(xc + 1)).all(|x| right[fy * w + x]);
        out[2][c] = yc + 1 < hc && (fy..py(yc + 1)).all(|y| down[y * w + fx]);
    }
    (wc, hc, out)
}

/// The code in [`Geometry::prow`] of a row stored in [`Geometry::ext`].
const EXT: u8 = u8::MAX;
/// The slots of the 2 × 2 corners in a 4 × 4 window row.
const CORNERS: [usize; 4] = [5, 6, 9, 10];
/// The codes of the plain bilinear rows (see [`plain_row`]), by `(y & 1) * 2 + (x & 1)`.
const PLAIN_CODES: [[u8; 4]; 4] = [[24, 0, 0, 0], [12, 12, 0, 0], [12, 0, 12, 0], [6, 6, 6, 6]];

/// The row of a fine node between coarse nodes 1 and 2 of a window line, linked to them as `a` and `b`; at a
/// missing link, the linked side's linear extrapolation if its far link (`fa`, `fb`: coarse 0–1, 2–3) exists,
/// else its value.
fn extend(a: bool, b: bool, fa: bool, fb: bool) -> [f64; 4] {
    match (a, b) {
        (true, true) => [0.0, 0.5, 0.5, 0.0],
        (true, false) if fa => [-0.5, 1.5, 0.0, 0.0],
        (true, false) => [0.0, 1.0, 0.0, 0.0],
        (false, true) if fb => [0.0, 0.0, 1.5, -0.5],
        (false, true) => [0.0, 0.0, 1.0, 0.0],
        _ => [0.0; 4],
    }
}

widest! {
    /// The largest `|r_i| / a_ii` of a residual (one Jacobi step's largest move), `inv_diag` the inverse
    /// diagonal. Eight running maxima: one would wait on the last at every entry.
    pub(crate) fn scaled_max<T: Real>(r: &[[T; 2]], inv_diag: &[f64]) -> f64 =>
    scaled_max_body {
        let mut m = [0.0f64; 8];
        let (dc, rc) = (inv_diag[..r.len()].chunks_exact(4), r.chunks_exact(4));
        let (dt, rt) = (dc.remainder(), rc.remainder());
        for (d, ri) in dc.zip(rc) {
            for l in 0..4 {
                m[2 * l] = larger(m[2 * l], ri[l][0].get().abs() * d[l]);
                m[2 * l + 1] = larger(m[2 * l + 1], ri[l][1].get().abs() * d[l]);
            }
        }
        for (d, ri) in dt.iter().zip(rt) {
            m[0] = larger(larger(m[0], ri[0].get().abs() * d), ri[1].get().abs() * d);
        }
        m.iter().fold(0.0, |a, &b| larger(a, b))
    }
}

/// The larger of two values, by a comparison: `f64::max` (which must skip a NaN) is a libm call on WebAssembly.
#[inline(always)]
pub(crate) fn larger(a: f64, b: f64) -> f64 { if b > a { b } else { a } }

widest! {
    /// `[Σ a₀b₀, Σ a₁b₁]` of two vectors of pairs, in `f64`, the products taken in `T`.
    pub(crate) fn dot_pairs<T: Real>(a: &[[T; 2]], b: &[[T; 2]]) -> [f64; 2] =>
    dot_pairs_body {
        pair_sums(a.as_flattened(), b.as_flattened(), |x: T, y: T| (x * y).get())
    }
}

widest! {
    /// `Σ_i a_i b_i` in `f64` on [`pair_sums`]' eight running sums.
    pub(crate) fn dot<A: Real, B: Real>(a: &[A], b: &[B]) -> f64 =>
    dot_body {
        let [even, odd] = pair_sums(a, b, |x: A, y: B| x.get() * y.get());
        even + odd
    }
}

widest! {
    /// `zⱼ −= lⱼ y` for every j.
    pub(crate) fn sub_scaled(l: &[f64], y: f64, z: &mut [f64]) => sub_scaled_body { z.iter_mut().zip(l).for_each(|(z, l)| *z -= l * y) }
}

/// `[Σ prod(a_j, b_j) over even j, the same over odd j]` of two flattened vectors of pairs (`b` at least as
/// long as `a`), on eight running sums: a single sum waits on its last addition at every entry.
#[inline(always)]
pub(crate) fn pair_sums<A: Copy, B: Copy>(a: &[A], b: &[B], prod: impl Fn(A, B) -> f64) -> [f64; 2] {
    let b = &b[..a.len()];
    let mut s = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            s[l] += prod(x[l], y[l]);
        }
    }
    // The remainder starts on an even index: entry j is component j % 2.
    for (j, (&x, &y)) in ra.iter().zip(rb).enumerate() {
        s[j % 2] += prod(x, y);
    }
    [(s[0] + s[2]) + (s[4] + s[6]), (s[1] + s[3]) + (s[5] + s[7])]
}

/// The plain bilinear prolongation row of node (x, y) (see [`Geometry::geo_row`]).
fn plain_row(x: usize, y: usize) -> [f64; 16] {
    let mut r = [0.0; 16];
    for (k, c) in CORNERS.into_iter().zip(PLAIN_CODES[(y & 1) * 2 + (x & 1)]) { r[k] = WEIGHTS[c as usize]; }
    r
}

/// The operator of one level.
#[derive(Debug)]
pub(crate) enum Operator {
    /// The finest level: energy terms read off per-node flags, applied as the interior molecule on runs of
    /// regular nodes and as the other nodes' own stencils.
    Fine { flags: Vec<u8>, tau: f64, runs: Runs, own: OwnStencils },
    /// A Galerkin level: a 5 × 5 stencil (dy outer) per padded node, an index into a table whose entry 0 is
    /// the stencil shared by every regular node (all zeros when there is none).
    Stored { ids: Vec<u32>, table: Vec<[f64; 25]>, narrow: Vec<[f32; 25]>, sym: Option<Sym>, fours: Fours, runs: Runs, far: Vec<Far> },
}

/// A tap past a Galerkin level's 5 × 5 stencils (at a cut's tips): `(p, q, a_pq)`, padded, sorted by `p`.
pub(crate) type Far = (u32, u32, f64);

fn far_of(far: &[Far], p: usize) -> &[Far] {
    let k0 = far.partition_point(|e| (e.0 as usize) < p);
    &far[k0..k0 + far[k0..].partition_point(|e| e.0 as usize == p)]
}

/// A shared stencil with the square's symmetries (as the finest operator has): five coefficients, for the
/// centre and the rings of 4 edge, 4 diagonal, 4 far and 8 knight's-move neighbours, so runs of regular
/// nodes sum neighbours first and multiply five times instead of 21.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sym([f64; 5]);

impl Sym {
    /// The finest level's interior molecule: the squared 5-point Laplacian (20, −8, 2, 1) plus τ times (4, −1).
    fn fine(tau: f64) -> Sym { Sym([20.0 + 4.0 * tau, -8.0 - tau, 2.0, 1.0, 0.0]) }

    /// The five coefficients of `s` (each its ring's mean) if it has the square's symmetries up to rounding.
    fn of(s: &[f64; 25]) -> Option<Sym> {
        // Each tap's ring by its |dx| and |dy| (none for the corners).
        let ring = |t: usize| [[Some(0), Some(1), Some(3)], [Some(1), Some(2), Some(4)], [Some(3), Some(4), None]][(t % 5).abs_diff(2)][(t / 5).abs_diff(2)];
        let (scale, mut c, mut n, taps) = (s.iter().fold(0.0f64, |m, a| m.max(a.abs())), [0.0; 5], [0.0; 5], || (0..25).filter_map(|t| Some((ring(t)?, s[t]))));
        taps().for_each(|(k, a)| (c[k], n[k]) = (c[k] + a, n[k] + 1.0));
        c.iter_mut().zip(n).for_each(|(c, n)| *c /= n);
        taps().all(|(k, a)| (a - c[k]).abs() <= 1e-13 * scale).then_some(Sym(c))
    }
}

/// One level of the hierarchy.
#[derive(Debug)]
pub(crate) struct Level {
    pub geo: Geometry,
    pub wp: usize,
    pub op: Operator,
    /// 1 / a_ii for unknowns, 0 elsewhere (padded).
    pub inv_diag: Vec<f64>,
    /// The same in `f32`, for the smoother (0 where it would not be finite).
    pub inv_diag_w: Vec<WS>,
    /// Upper bound of the spectrum of D⁻¹A (Gershgorin).
    pub lam_max: f64,
    /// `clean[y * w + x]`: active, linked right and down, not fixed, and (on Galerkin levels) regular. A coarse
    /// node whose 9 × 9 window here is all clean gets the shared coarse stencil.
    pub clean: Vec<bool>,
}

impl Level {
    #[inline]
    pub fn pidx(&self, x: usize, y: usize) -> usize { (y + PAD) * self.wp + x + PAD }

    pub fn len_padded(&self) -> usize { self.wp * (self.geo.h + 2 * PAD) }

    /// Zeroes the padding of a vector of this level.
    pub fn clear_padding<T: Real>(&self, v: &mut [[T; 2]]) {
        let (wp, w, h, zero) = (self.wp, self.geo.w, self.geo.h, [T::ZERO; 2]);
        v[..PAD * wp].fill(zero);
        v[(PAD + h) * wp..].fill(zero);
        for row in v[PAD * wp..(PAD + h) * wp].chunks_mut(wp) {
            row[..PAD].fill(zero);
            row[PAD + w..].fill(zero);
        }
    }

    /// The finest level from its geometry (with fixed nodes) and the tension.
    pub fn fine(geo: Geometry, tau: f64) -> Level {
        let (w, h) = (geo.w, geo.h);
        let (wp, n) = (w + 2 * PAD, (w + 2 * PAD) * (h + 2 * PAD));
        let fixed = |i: usize| geo.fixed.as_ref().is_some_and(|f| f[i]);
        let mut flags = vec![0u8; n];
        flags.par_chunks_mut(wp).skip(PAD).take(h).enumerate().for_each(|(y, row)| {
            for (x, i) in (0..w).map(|x| (x, geo.idx(x, y))).filter(|&(_, i)| geo.active[i]) {
                let (r, d) = (&geo.right, &geo.down);
                let bits = [(!fixed(i), bit::FREE), (r[i], bit::RIGHT), (d[i], bit::DOWN), (x > 0 && r[i - 1] && r[i], bit::HTRI),
                    (y > 0 && d[i - w] && d[i], bit::VTRI), (r[i] && d[i] && d[i + 1] && r[i + w], bit::CELL)];
                row[x + PAD] = bits.iter().filter(|b| b.0).fold(0, |f, b| f | b.1);
            }
        });
        // Row by row: the free nodes' diagonals (a regular node's, the interior molecule's, is the same everywhere)
        // and which are regular, marked in `flags` after.
        let molecule = fine_diag_and_abs(&[u8::MAX; 25], 12, 5, tau);
        let (mut inv_diag, mut regular) = (vec![0.0; n], vec![false; n]);
        let rows = inv_diag.par_chunks_mut(wp).zip(regular.par_chunks_mut(wp)).enumerate().skip(PAD).take(h);
        let lam_max = rows.map(|(y, (diag, regular))| {
            let has = |q: usize, b: u8| flags[q] & b != 0;
            let mut top = 0.0f64;
            for (x, p) in (PAD..PAD + w).map(|x| (x, y * wp + x)).filter(|&(_, p)| has(p, bit::FREE)) {
                regular[x] = [p - 1, p, p + 1].iter().all(|&q| has(q, bit::HTRI))
                    && [p - wp, p, p + wp].iter().all(|&q| has(q, bit::VTRI))
                    && [p, p - 1, p - wp, p - wp - 1].iter().all(|&q| has(q, bit::CELL));
                let (d, s) = if regular[x] { molecule } else { fine_diag_and_abs(&flags, p, wp, tau) };
                if d > 0.0 {
                    diag[x] = 1.0 / d;
                    top = top.max(s / d);
                }
            }
            top
        }).reduce(|| 0.0, f64::max);
        flags.iter_mut().zip(&regular).filter(|(_, &r)| r).for_each(|(f, _)| *f |= bit::REGULAR);
        let clean = (0..w * h).map(|i| geo.active[i] && geo.right[i] && geo.down[i] && !fixed(i)).collect();
        let kind = |f: u8| if f & bit::FREE == 0 { RunKind::Skip } else if f & bit::REGULAR != 0 { RunKind::Shared } else { RunKind::Own };
        let mut runs = Runs::new(wp, w, h, |p| kind(flags[p]));
        let own = OwnStencils::new(&mut runs, wp, |p| fine_row(&flags, p, wp, tau));
        Level { inv_diag_w: narrow_diag(&inv_diag), geo, wp, op: Operator::Fine { flags, tau, runs, own }, inv_diag, lam_max, clean }
    }

    /// The finest level's tension where its operator is the open box's (every node linked right and down but on the
    /// last column and row; fixed nodes aside). Links join active nodes, so an inactive corner shows too.
    pub fn open_tension(&self) -> Option<f64> {
        let (Operator::Fine { flags, tau, .. }, w, h) = (&self.op, self.geo.w, self.geo.h) else { return None };
        let linked = |f: u8, x: usize, y: usize| (x + 1 == w || f & bit::RIGHT != 0) && (y + 1 == h || f & bit::DOWN != 0);
        (0..h).all(|y| (0..w).all(|x| linked(flags[self.pidx(x, y)], x, y))).then_some(*tau)
    }

    /// This finest level with the plain bilinear prolongation of its box without holes or cuts: a coarse
    /// space of functions smooth across holes and cuts, where the link-aware one extrapolates a constant.
    pub fn into_plain(self) -> Level {
        let (w, h) = (self.geo.w, self.geo.h);
        self.with_prolongation(Geometry::open(w, h))
    }

    /// The level with the prolongation rows of `geo` (more nodes or links), zero on its inactive and fixed nodes.
    fn with_prolongation(mut self, geo: Geometry) -> Level {
        let real = std::mem::replace(&mut self.geo, geo);
        let zero = |i: usize| !real.active[i] || real.fixed.as_ref().is_some_and(|f| f[i]);
        (0..real.w * real.h).filter(|&i| zero(i)).for_each(|i| self.geo.prow[i] = [0; 4]);
        self.geo.ext.retain(|e| !zero(e.0 as usize));
        self
    }

    /// Drops the four-node layout of its own stencils (the ablation's switch `fours`).
    pub fn drop_fours(&mut self) { if let Operator::Stored { fours, .. } = &mut self.op { *fours = Fours::default(); } }

    /// The same level with the prolongation of a geometry whose wide holes (clear of the border, more than
    /// four nodes per link to an active node) are made active and linked all round. The operator stays the
    /// level's own (coarser levels keep the exact energy), but coarse functions run smoothly up to a hole's
    /// rim (docs/dev/coarse-space.md). Thin holes stay: filling would tie their sides together. On a [`solid`]
    /// piece the wide pieces of `outside` (box nodes off the matte) are filled too, border or not, so coarse
    /// functions stay affine to its edge.
    pub fn with_holes_filled(self, outside: Option<&[bool]>) -> Level {
        let g = &self.geo;
        let (w, h) = (g.w, g.h);
        // The wide pieces of `gap` nodes (inactive, or off the matte), clear of the border unless `border_too`.
        let wide_pieces = |gap: &dyn Fn(usize) -> bool, border_too: bool| -> Vec<bool> {
            let (hole, count) = crate::grid::Grid::from_active(w, h, (0..w * h).map(gap).collect()).pieces();
            let (mut size, mut edges, mut border) = (vec![0usize; count], vec![0usize; count], vec![false; count]);
            for i in (0..w * h).filter(|&i| gap(i)) {
                let (x, y, k) = (i % w, i / w, hole[i] as usize);
                size[k] += 1;
                border[k] |= x == 0 || y == 0 || x + 1 == w || y + 1 == h;
                let around = [(x > 0).then(|| i - 1), (x + 1 < w).then(|| i + 1), (y > 0).then(|| i - w), (y + 1 < h).then(|| i + w)];
                edges[k] += around.into_iter().flatten().filter(|&j| g.active[j]).count();
            }
            (0..w * h).map(|i| gap(i) && size[hole[i] as usize] > 4 * edges[hole[i] as usize] && (border_too || !border[hole[i] as usize])).collect()
        };
        let mut fill = if g.active.contains(&false) { wide_pieces(&|i| !g.active[i], false) } else { vec![false; w * h] };
        if let Some(o) = outside {
            let more = wide_pieces(&|i| o[i], true);
            if more.iter().zip(&fill).any(|(m, f)| *m && !f) && solid(w, h, &g.active, &g.right, &g.down) {
                fill.iter_mut().zip(more).for_each(|(f, m)| *f |= m);
            }
        }
        if !fill.contains(&true) { return self; }
        let active: Vec<bool> = (0..w * h).map(|i| g.active[i] || fill[i]).collect();
        let right = (0..w * h).map(|i| g.right[i] || (i % w + 1 < w && (fill[i] || fill[i + 1]) && active[i] && active[i + 1])).collect();
        let down = (0..w * h).map(|i| g.down[i] || (i + w < w * h && (fill[i] || fill[i + w]) && active[i] && active[i + w])).collect();
        let filled = Geometry::new(w, h, active, right, down, g.fixed.clone());
        let mut level = self.with_prolongation(filled);
        // Rows through a filled node are not plain: the transfers take the general path.
        level.geo.plain_rows.iter_mut().zip(fill.chunks(w)).for_each(|(plain, row)| *plain &= !row.contains(&true));
        level
    }

    /// Frees everything but the dimensions and the prolongation rows (all that transfers read).
    pub fn keep_only_prolongation(&mut self) {
        self.op = Operator::Fine { flags: Vec::new(), tau: 0.0, runs: Runs::default(), own: OwnStencils::default() };
        (self.inv_diag, self.inv_diag_w, self.clean) = (Vec::new(), Vec::new(), Vec::new());
        let g = &mut self.geo;
        (g.active, g.right, g.down, g.fixed) = (Vec::new(), Vec::new(), Vec::new(), None);
    }

    /// The stencil row of padded node `p` as a 5 × 5 array (dy outer, dx inner).
    pub fn row(&self, p: usize) -> [f64; 25] {
        match &self.op {
            Operator::Fine { flags, tau, .. } => fine_row(flags, p, self.wp, *tau),
            Operator::Stored { ids, table, .. } => table[ids[p] as usize],
        }
    }

    /// The far taps of row `p` (see [`Far`]).
    pub fn far(&self, p: usize) -> &[Far] { if let Operator::Stored { far, .. } = &self.op { far_of(far, p) } else { &[] } }

    /// `f(q, a_pq)` for every nonzero tap of row `p`: the stored stencil's and the far ones.
    pub fn taps(&self, p: usize, mut f: impl FnMut(usize, f64)) {
        let (row, wp) = (self.row(p), self.wp);
        for (t, &a) in row.iter().enumerate().filter(|e| *e.1 != 0.0) { f(p + (t / 5) * wp + t % 5 - 2 * wp - 2, a); }
        self.far(p).iter().for_each(|&(_, q, a)| f(q as usize, a));
    }

    /// `out_p = Σ_q |a_pq| g_q` on the finest level's unknowns (`g` zero off them; `out` zero there).
    pub(crate) fn fine_abs_product(&self, g: &[f64], out: &mut [f64]) {
        let Operator::Fine { flags, tau, runs, own } = &self.op else { unreachable!("a Galerkin level") };
        let wp = self.wp;
        let at = |p: usize, t: usize| p + (t / 5) * wp + t % 5 - 2 * wp - 2;
        out.par_chunks_mut(wp).enumerate().for_each(|(r, row)| {
            row.fill(0.0);
            for run in runs.row(r) {
                let (a, b, p) = (run.start as usize, run.end as usize, r * wp + run.start as usize);
                match run.kind {
                    RunKind::Skip => {}
                    // Tap by tap along the run: the interior molecule's products vectorise.
                    RunKind::Shared => {
                        for (t, c) in fine_row(flags, p, wp, *tau).iter().enumerate().filter(|(_, c)| **c != 0.0) {
                            for (o, g) in row[a..b].iter_mut().zip(&g[at(p, t)..at(p, t) + b - a]) {
                                *o += c.abs() * g;
                            }
                        }
                    }
                    RunKind::Own => {
                        for (c, id) in (a..b).zip(&own.ids[run.at as usize..]) {
                            row[c] = own.table[*id as usize].iter().enumerate().map(|(t, s)| s.abs() * g[at(r * wp + c, t)]).sum();
                        }
                    }
                }
            }
        });
    }

    /// `−(A x)_p` at one node of the finest level (its residual, the right-hand side being 0).
    pub fn fine_residual_at(&self, x: &[V2], p: usize) -> V2 {
        let Operator::Fine { flags, tau, .. } = &self.op else { unreachable!("only the finest level is relaxed node by node") };
        fine_apply(flags, x, p, self.wp, *tau).map(|a| -a)
    }

    /// `y = f − A x` on unknowns (zero elsewhere), rows in parallel for large levels.
    pub fn residual<T: Real>(&self, x: &[[T; 2]], f: Option<&[[T; 2]]>, out: &mut [[T; 2]]) {
        self.over_bands(out, false, |r0, _, chunk| {
            band_residual(self, x, f, r0, 0, chunk);
            [0.0; 2]
        });
    }

    /// `out = f − A x` on a Galerkin level summed in `f64`, rounded once: for smooth vectors as large as the answer
    /// or its error, whose product summed in `f32` would bury the residual in rounding noise
    /// (`docs/dev/solver-correctness.md`, "Coarse products in f64").
    pub fn residual_f64(&self, x: &[W2], f: Option<&[W2]>, out: &mut [W2]) {
        let Operator::Stored { runs, .. } = &self.op else { unreachable!("a Galerkin level") };
        let wp = self.wp;
        self.over_bands(out, false, |r0, _, chunk| {
            BAND_F64.with(|buf| {
                let mut buf = buf.borrow_mut();
                buf.resize(chunk.len(), [0.0; 2]);
                // −A x of the band in `f64`, then `f` added and each sum rounded.
                band_residual::<WS, f64>(self, x, None, r0, 0, &mut buf);
                for (k, (orow, brow)) in chunk.chunks_mut(wp).zip(buf.chunks(wp)).enumerate() {
                    let base = (r0 + k) * wp;
                    for &run in runs.row(r0 + k) {
                        let (c, e) = (run.start as usize, run.end as usize);
                        if run.kind == RunKind::Skip {
                            orow[c..e].fill([0.0; 2]);
                            continue;
                        }
                        for (j, (o, b)) in orow[c..e].iter_mut().zip(&brow[c..e]).enumerate() {
                            let fv = f.map_or([0.0; 2], |f| [f[base + c + j][0].get(), f[base + c + j][1].get()]);
                            *o = [WS::of(fv[0] + b[0]), WS::of(fv[1] + b[1])];
                        }
                    }
                }
            });
            [0.0; 2]
        });
    }

    /// `out = −A x` and `xᵀ out` per component, taken band by band while both are in cache.
    pub fn residual_dot<T: Real>(&self, x: &[[T; 2]], out: &mut [[T; 2]]) -> [f64; 2] {
        self.over_bands(out, false, |r0, r1, chunk| {
            band_residual(self, x, None, r0, 0, chunk);
            dot_pairs(&x[r0 * self.wp..r1 * self.wp], chunk)
        })
    }

    /// `out = −A x` in `f64` on the finest level for an `x` in `f32` (the search direction) and `xᵀ out` per
    /// component: bit for bit the `f64` product of the widened vector.
    pub fn fine_residual_dot_narrow(&self, x: &[W2], out: &mut [V2]) -> [f64; 2] {
        assert!(matches!(self.op, Operator::Fine { .. }), "the finest level");
        self.over_bands(out, false, |r0, r1, chunk| {
            band_residual(self, x, None, r0, 0, chunk);
            pair_sums(x[r0 * self.wp..r1 * self.wp].as_flattened(), chunk.as_flattened(), |a: WS, b: f64| a.get() * b)
        })
    }

    /// `out = −A x` and its largest entry scaled by the inverse diagonal ([`scaled_max`]), band by band.
    pub fn residual_scaled_max<T: Real>(&self, x: &[[T; 2]], out: &mut [[T; 2]]) -> f64 {
        self.over_bands(out, true, |r0, r1, chunk| {
            band_residual(self, x, None, r0, 0, chunk);
            [scaled_max(chunk, &self.inv_diag[r0 * self.wp..r1 * self.wp]), 0.0]
        })[0]
    }

    /// `band(r0, r1, rows)` on bands of [`PAR_ROWS`] padded rows `r0..r1` of `out`'s body, in parallel; the
    /// largest first entry of the results when `max`, else their sums, added in order (thread-independent).
    fn over_bands<U: Send>(&self, out: &mut [U], max: bool, band: impl Fn(usize, usize, &mut [U]) -> [f64; 2] + Sync + Send) -> [f64; 2] {
        let wp = self.wp;
        let body = &mut out[PAD * wp..(PAD + self.geo.h) * wp];
        let parts: Vec<[f64; 2]> = body.par_chunks_mut(PAR_ROWS * wp).enumerate().map(|(b, chunk)| {
            let r0 = b * PAR_ROWS + PAD;
            band(r0, r0 + chunk.len() / wp, chunk)
        }).collect();
        if max { return [parts.iter().fold(0.0, |m, p| larger(m, p[0])), 0.0]; }
        parts.iter().fold([0.0; 2], |a, b| [a[0] + b[0], a[1] + b[1]])
    }

    /// One smoothing step in one pass, band by band: `r = f − A x` (into `next`), the update `d` from it
    /// (`rule`), `next = x + d`; bit for bit the three passes. `next` must differ from `x` (bands read `x` two
    /// rows past their own); `d` is written only when `keep`, read only by [`StepRule::Next`].
    pub(crate) fn smoothing_step(&self, x: &[W2], f: Option<&[W2]>, d: &mut [W2], next: &mut [W2], rule: StepRule, keep: bool) {
        self.step_bands(d, next, |r0, _, chunk, dc| self.step_band(x, 0, f, r0, chunk, dc, rule, keep));
    }

    /// A smoothing's second step (`rule`) from zero on the finest level, the first iterate
    /// ([`super::cycle::first_from_zero`]) made band by band in a thread-local buffer: bit for bit the first
    /// step's pass then [`Level::smoothing_step`], one pass and one vector fewer.
    pub(crate) fn second_step_from_zero(&self, f: &[W2], inv_theta: WS, d: &mut [W2], next: &mut [W2], rule: StepRule, keep: bool) {
        assert!(matches!(self.op, Operator::Fine { .. }), "the finest level");
        let (wp, g) = (self.wp, &self.inv_diag_w[..]);
        self.step_bands(d, next, |r0, r1, chunk, dc| {
            // Rows a..z: the band's and the two each side its stencils reach.
            let (a, z) = (r0 - PAD, r1 + PAD);
            let n = (z - a) * wp;
            FIRST_ITERATE.with(|buf| {
                let mut buf = buf.borrow_mut();
                let len = buf.len().max(n);
                buf.resize(len, [0.0; 2]);
                // Every entry written (zero where the inverse diagonal is, the padding too).
                super::cycle::first_from_zero(&mut buf[..n], &f[a * wp..z * wp], &g[a * wp..z * wp], inv_theta);
                self.step_band(&buf[..n], a, Some(&f[a * wp..z * wp]), r0, chunk, dc, rule, keep);
            });
        });
    }

    /// `band(r0, r1, rows, d_rows)` on bands of [`PAR_ROWS`] padded rows of `next` and `d`, in parallel; then
    /// zeros in `next`'s padding rows.
    fn step_bands(&self, d: &mut [W2], next: &mut [W2], band: impl Fn(usize, usize, &mut [W2], &mut [W2]) + Sync + Send) {
        let (wp, body) = (self.wp, PAD * self.wp..(PAD + self.geo.h) * self.wp);
        let (nb, db) = (&mut next[body.clone()], &mut d[body.clone()]);
        nb.par_chunks_mut(PAR_ROWS * wp).zip(db.par_chunks_mut(PAR_ROWS * wp)).enumerate().for_each(|(b, (chunk, dc))| {
            let r0 = b * PAR_ROWS + PAD;
            band(r0, r0 + chunk.len() / wp, chunk, dc);
        });
        next[..body.start].fill([0.0; 2]);
        next[body.end..].fill([0.0; 2]);
    }

    /// One band of a smoothing step from padded row `r0` (`chunk`, `dc`: its rows of `next`, `d`); `x`, `f`
    /// hold the level's rows from padded row `shift` on.
    fn step_band(&self, x: &[W2], shift: usize, f: Option<&[W2]>, r0: usize, chunk: &mut [W2], dc: &mut [W2], rule: StepRule, keep: bool) {
        let (wp, w, g) = (self.wp, self.geo.w, &self.inv_diag_w[..]);
        band_residual(self, x, f, r0, shift, chunk);
        for (k, (orow, drow)) in chunk.chunks_mut(wp).zip(dc.chunks_mut(wp)).enumerate() {
            let (xb, gb) = ((r0 - shift + k) * wp + PAD, (r0 + k) * wp + PAD);
            orow[..PAD].fill([0.0; 2]);
            orow[PAD + w..].fill([0.0; 2]);
            step_row(&mut orow[PAD..PAD + w], &mut drow[PAD..PAD + w], &x[xb..xb + w], &g[gb..gb + w], rule, keep);
        }
    }
}

thread_local! {
    /// The first iterate's rows of a band (see [`Level::second_step_from_zero`]).
    static FIRST_ITERATE: std::cell::RefCell<Vec<W2>> = const { std::cell::RefCell::new(Vec::new()) };
    /// A band of `−A x` in `f64` (see [`Level::residual_f64`]).
    static BAND_F64: std::cell::RefCell<Vec<V2>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// A smoothing step's update `d` from the residual `r` and inverse diagonal `g`: `d = g r / θ` first,
/// `d = c₁ d + c₂ g r` later, `d = c₁ x + c₂ g r` second after a first from zero (whose update is its iterate).
#[derive(Clone, Copy, Debug)]
pub(crate) enum StepRule {
    First { inv_theta: WS },
    Next { c1: WS, c2: WS },
    Second { c1: WS, c2: WS },
}

widest! {
    /// `d` from the residual `r` (given in `out`) by `rule`, then `out = x + d`, along one row.
    fn step_row(out: &mut [W2], d: &mut [W2], x: &[W2], g: &[WS], rule: StepRule, keep: bool) =>
    step_row_body {
        let n = out.len();
        // On the flattened components: on pairs, the loops stayed scalar.
        let (o, d, x, g) = (out.as_flattened_mut(), d[..n].as_flattened_mut(), x[..n].as_flattened(), &g[..n]);
        macro_rules! each {
            (|$j:ident, $r:ident, $g:ident| $v:expr) => {
                if keep {
                    for i in 0..n {
                        let $g = g[i];
                        for $j in 2 * i..2 * i + 2 {
                            let $r = o[$j];
                            let v = $v;
                            d[$j] = v;
                            o[$j] = x[$j] + v;
                        }
                    }
                } else {
                    for i in 0..n {
                        let $g = g[i];
                        for $j in 2 * i..2 * i + 2 {
                            let $r = o[$j];
                            o[$j] = x[$j] + $v;
                        }
                    }
                }
            };
        }
        match rule {
            StepRule::First { inv_theta } => each!(|j, r, dd| r * dd * inv_theta),
            StepRule::Next { c1, c2 } => each!(|j, r, dd| c1 * d[j] + c2 * dd * r),
            StepRule::Second { c1, c2 } => each!(|j, r, dd| c1 * x[j] + c2 * dd * r),
        }
    }
}

widest! {
    /// `out = f − A x` on the unknowns of the band's rows from padded row `r0`: regular runs by the shared
    /// stencil, the others by their own, then a Galerkin level's far taps. `x`, `f` hold the level's rows from
    /// padded row `shift` on (0 but on the finest level). Summed in `T` ([`widened`]).
    #[inline(never)]
    fn band_residual<S: Real, T: Real>(level: &Level, x: &[[S; 2]], f: Option<&[[T; 2]]>, r0: usize, shift: usize, out: &mut [[T; 2]]) =>
    band_residual_body {
        let wp = level.wp;
        let rows = out.chunks_mut(wp).enumerate().map(|(k, orow)| (r0 + k, (r0 + k - shift) * wp, orow));
        match &level.op {
            Operator::Fine { tau, runs, own, .. } => {
                let (molecule, table) = (Sym::fine(*tau), T::table(&own.table, &own.narrow));
                for (r, base, orow) in rows {
                    for run in runs.row(r) {
                        let (c, e) = (run.start as usize, run.end as usize);
                        match run.kind {
                            RunKind::Shared => sym_run::<S, T, false>(x, f, &molecule, wp, base, c, e, orow),
                            RunKind::Own => {
                                let ids = &own.ids[run.at as usize..run.at as usize + e - c];
                                own_sums(x, f, wp, base, c, e, orow, |q| &table[ids[q - base - c] as usize]);
                            }
                            RunKind::Skip => orow[c..e].fill([T::ZERO; 2]),
                        }
                    }
                }
            }
            Operator::Stored { ids, table, narrow, sym, fours, runs, far } => {
                assert_eq!(shift, 0, "a Galerkin level's vectors whole");
                let table = T::table(table, narrow);
                let four = f32::has_four_stencils() && !fours.row_first.is_empty();
                for (r, base, orow) in rows {
                    let mut block = if four { fours.row_first[r] as usize } else { 0 };
                    for &run in runs.row(r) {
                        let (c, e) = (run.start as usize, run.end as usize);
                        match (run.kind, sym) {
                            (RunKind::Skip, _) => orow[c..e].fill([T::ZERO; 2]),
                            (RunKind::Shared, Some(sym)) => sym_run::<S, T, true>(x, f, sym, wp, base, c, e, orow),
                            // A shared stencil without the square's symmetries (not met in practice).
                            (RunKind::Shared, None) => own_sums(x, f, wp, base, c, e, orow, |_| &table[0]),
                            (RunKind::Own, _) => {
                                // In `f32` with AVX2, four nodes to a vector (see `four_run_avx2`).
                                let mut i = c;
                                if let (true, Some(xs), Some(o)) = (four, S::as_f32(x), T::as_f32_mut(orow)) {
                                    let (n, tail) = ((e - c) / 4, (e - c) % 4);
                                    let m = n + usize::from(tail > 0);
                                    // The tail's taps may pass the vectors' end: there it is summed below.
                                    let tail = if base + c + 4 * m + 2 * wp + 2 <= x.len() { tail } else { 0 };
                                    let blocks = &fours.blocks[block..block + m];
                                    f32::four_run(xs, f.and_then(T::as_f32), base + c, n, tail, wp, blocks, &mut o[c..c + 4 * n + tail]);
                                    block += m;
                                    i += 4 * n + tail;
                                }
                                own_sums(x, f, wp, base, i, e, orow, |q| &table[ids[q] as usize]);
                            }
                        }
                    }
                }
                subtract_far(far, r0 * wp, x, out);
            }
        }
    }
}

/// `out[j] −= a_pq x[q]` for the far taps `(p, q, a_pq)` of the nodes `p = a + j` that `out` covers.
fn subtract_far<S: Real, T: Real>(far: &[Far], a: usize, x: &[[S; 2]], out: &mut [[T; 2]]) {
    let (k0, b) = (far.partition_point(|e| (e.0 as usize) < a), a + out.len());
    for &(p, q, v) in far[k0..].iter().take_while(|e| (e.0 as usize) < b) {
        let (o, xq, v) = (&mut out[p as usize - a], x[q as usize], T::of(v));
        *o = [o[0] - v * widened::<S, T>(xq[0]), o[1] - v * widened::<S, T>(xq[1])];
    }
}

/// `out[c] = f[q] − Σₜ s_q[t] x[q + offset(t)]` for `q = base + c`, `c` in `c0..c1` of the row `out`, each
/// with its own stencil `s_q = stencil(q)` in [`STORED_TAPS`] order, four nodes side by side so that their
/// chains of additions overlap.
#[inline(always)]
fn own_sums<'a, S: Real, T: Real>(x: &[[S; 2]], f: Option<&[[T; 2]]>, wp: usize, base: usize, c0: usize, c1: usize, out: &mut [[T; 2]], stencil: impl Fn(usize) -> &'a [T; 25]) {
    let mut i = c0;
    while i < c1 {
        let (k, q0) = ((c1 - i).min(4), base + i);
        // Past the run's end the last node stands in (its sums are dropped).
        let [_, o1, o2, o3] = [0, 1, 2, 3].map(|j: usize| j.min(k - 1));
        let [s0, s1, s2, s3] = [0, o1, o2, o3].map(|j| stencil(q0 + j));
        let mut a = [[T::ZERO; 2]; 4];
        for &(dy, dx) in &STORED_TAPS {
            let (t, q) = (dy * 5 + dx, q0 + dy * wp + dx - 2 * wp - 2);
            let v = |p: usize| x[p].map(widened::<S, T>);
            let (x0, x1, x2, x3) = (v(q), v(q + o1), v(q + o2), v(q + o3));
            a[0] = [a[0][0] + s0[t] * x0[0], a[0][1] + s0[t] * x0[1]];
            a[1] = [a[1][0] + s1[t] * x1[0], a[1][1] + s1[t] * x1[1]];
            a[2] = [a[2][0] + s2[t] * x2[0], a[2][1] + s2[t] * x2[1]];
            a[3] = [a[3][0] + s3[t] * x3[0], a[3][1] + s3[t] * x3[1]];
        }
        for (j, a) in a.into_iter().take(k).enumerate() {
            let fv = f.map_or([T::ZERO; 2], |f| f[q0 + j]);
            out[i + j] = [fv[0] - a[0], fv[1] - a[1]];
        }
        i += k;
    }
}

/// A symmetric stencil ([`Sym`]) on columns `c0..c1` of the row `out` at `base`: a Galerkin level's shared one,
/// or (`KNIGHT` false) the finest interior molecule. On the flattened components: it vectorises across nodes.
#[inline(always)]
fn sym_run<S: Real, T: Real, const KNIGHT: bool>(x: &[[S; 2]], f: Option<&[[T; 2]]>, sym: &Sym, wp: usize, base: usize, c0: usize, c1: usize, out: &mut [[T; 2]]) {
    let n = 2 * (c1 - c0);
    let xf = x.as_flattened();
    let at = |dr: isize, dc: isize| -> &[S] {
        let s = 2 * ((base + c0) as isize + dr * wp as isize + dc) as usize;
        &xf[s..s + n]
    };
    let x0 = at(0, 0);
    let (e0, e1, e2, e3) = (at(0, -1), at(0, 1), at(-1, 0), at(1, 0));
    let (d0, d1, d2, d3) = (at(-1, -1), at(-1, 1), at(1, -1), at(1, 1));
    let (f0, f1, f2, f3) = (at(0, -2), at(0, 2), at(-2, 0), at(2, 0));
    let (k0, k1, k2, k3) = (at(-2, -1), at(-2, 1), at(2, -1), at(2, 1));
    let (k4, k5, k6, k7) = (at(-1, -2), at(-1, 2), at(1, -2), at(1, 2));
    let [c_0, c_e, c_d, c_f, c_k] = sym.0.map(T::of);
    // A macro, not a closure: the loops must inline it to vectorise.
    macro_rules! apply {
        ($j:expr) => {{
            let j = $j;
            let v = |s: &[S]| widened::<S, T>(s[j]);
            let e = v(e0) + v(e1) + v(e2) + v(e3);
            let d = v(d0) + v(d1) + v(d2) + v(d3);
            let fa = v(f0) + v(f1) + v(f2) + v(f3);
            let a = c_0 * v(x0) + c_e * e + c_d * d + c_f * fa;
            if KNIGHT {
                a + c_k * ((v(k0) + v(k1) + v(k2) + v(k3)) + (v(k4) + v(k5) + v(k6) + v(k7)))
            } else {
                a
            }
        }};
    }
    let o = &mut out[c0..c1].as_flattened_mut()[..n];
    match f {
        Some(f) => {
            let fz = &f[base + c0..base + c1].as_flattened()[..n];
            for j in 0..n {
                o[j] = fz[j] - apply!(j);
            }
        }
        None => {
            for j in 0..n {
                o[j] = T::ZERO - apply!(j);
            }
        }
    }
}

/// `s` in the precision `T` of a kernel's sums: itself, or widened exactly (no kernel narrows its input).
#[inline(always)]
fn widened<S: Real, T: Real>(s: S) -> T { T::of(s.get()) }

/// `(A x)_p` on the finest level from the energy terms that contain node p.
#[inline(always)]
fn fine_apply<T: Real>(flags: &[u8], x: &[[T; 2]], p: usize, wp: usize, tau: f64) -> [T; 2] {
    let m = |q: usize, b: u8| if (flags[q] & b) != 0 { T::of(1.0) } else { T::ZERO };
    let two = T::of(2.0);
    std::array::from_fn(|k| {
        let xv = |q: usize| x[q][k];
        // horizontal triples centred at p-1, p, p+1 (coefficient of p: 1, -2, 1)
        let th = |q: usize| m(q, bit::HTRI) * (xv(q - 1) - two * xv(q) + xv(q + 1));
        let tv = |q: usize| m(q, bit::VTRI) * (xv(q - wp) - two * xv(q) + xv(q + wp));
        let tc = |q: usize| m(q, bit::CELL) * (xv(q) - xv(q + 1) - xv(q + wp) + xv(q + wp + 1));
        let mut a = th(p - 1) - two * th(p) + th(p + 1) + tv(p - wp) - two * tv(p) + tv(p + wp)
            + two * (tc(p) - tc(p - 1) - tc(p - wp) + tc(p - wp - 1));
        if tau != 0.0 {
            let lr = |q: usize| m(q, bit::RIGHT) * (xv(q) - xv(q + 1));
            let ld = |q: usize| m(q, bit::DOWN) * (xv(q) - xv(q + wp));
            a += T::of(tau) * (lr(p) - lr(p - 1) + ld(p) - ld(p - wp));
        }
        a
    })
}

/// Diagonal a_pp and the row's Gershgorin sum Σ_t w_t |c_t(p)| Σ_j |c_t(j)| ≥ Σ_j |a_pj|.
fn fine_diag_and_abs(flags: &[u8], p: usize, wp: usize, tau: f64) -> (f64, f64) {
    let m = |q: usize, b: u8| ((flags[q] & b) != 0) as u8 as f64;
    let h = m(p - 1, bit::HTRI) + 4.0 * m(p, bit::HTRI) + m(p + 1, bit::HTRI);
    let v = m(p - wp, bit::VTRI) + 4.0 * m(p, bit::VTRI) + m(p + wp, bit::VTRI);
    let cells = m(p, bit::CELL) + m(p - 1, bit::CELL) + m(p - wp, bit::CELL) + m(p - wp - 1, bit::CELL);
    let links = m(p, bit::RIGHT) + m(p - 1, bit::RIGHT) + m(p, bit::DOWN) + m(p - wp, bit::DOWN);
    let hs = 4.0 * (m(p - 1, bit::HTRI) + 2.0 * m(p, bit::HTRI) + m(p + 1, bit::HTRI));
    let vs = 4.0 * (m(p - wp, bit::VTRI) + 2.0 * m(p, bit::VTRI) + m(p + wp, bit::VTRI));
    (h + v + 2.0 * cells + tau * links, hs + vs + 8.0 * cells + 2.0 * tau * links)
}

/// The 5 × 5 stencil row of the finest operator at padded node p.
pub(crate) fn fine_row(flags: &[u8], p: usize, wp: usize, tau: f64) -> [f64; 25] {
    let mut s = [0.0f64; 25];
    let m = |q: usize, b: u8| flags[q] & b != 0;
    let at = |dx: isize, dy: isize| ((dy + 2) * 5 + dx + 2) as usize;
    // The horizontal and vertical triples centred at p + d (d in -1..=1).
    for d in -1isize..=1 {
        let cp = if d == 0 { -2.0 } else { 1.0 };
        for (q, b, tap) in [(p as isize + d, bit::HTRI, (1, 0)), (p as isize + d * wp as isize, bit::VTRI, (0, 1))] {
            if m(q as usize, b) {
                for (o, c) in [(-1isize, 1.0), (0, -2.0), (1, 1.0)] { s[at(tap.0 * (d + o), tap.1 * (d + o))] += cp * c; }
            }
        }
    }
    // The cells with top-left corner at p − (ox, oy), ox, oy in {0, 1}.
    let sign = |cx: isize, cy: isize| if (cx + cy) % 2 == 0 { 1.0 } else { -1.0 };
    let corners = [(0isize, 0isize), (1, 0), (0, 1), (1, 1)];
    for (ox, oy) in corners.into_iter().filter(|&(ox, oy)| m(p - oy as usize * wp - ox as usize, bit::CELL)) {
        for (cx, cy) in corners { s[at(cx - ox, cy - oy)] += 2.0 * sign(ox, oy) * sign(cx, cy); }
    }
    if tau != 0.0 {
        let links = [(p, bit::RIGHT, 1, 0), (p - 1, bit::RIGHT, -1, 0), (p, bit::DOWN, 0, 1), (p - wp, bit::DOWN, 0, -1)];
        for (_, _, dx, dy) in links.into_iter().filter(|&(q, b, ..)| m(q, b)) {
            s[at(0, 0)] += tau;
            s[at(dx, dy)] -= tau;
        }
    }
    s
}

/// Galerkin coarse level `Pᵀ A P` of `fine` (`P` from `fine.geo`); coarse nodes with clean fine windows share one stencil.
pub(crate) fn galerkin(fine: &Level) -> Level {
    let geo = fine.geo.coarsen();
    let (wc, hc, fw, fh) = (geo.w, geo.h, fine.geo.w, fine.geo.h);
    let (wpc, hpc) = (wc + 2 * PAD, hc + 2 * PAD);
    let sat = Sat::new(fw, fh, |i| fine.clean[i]);
    // Extrapolating rows read links three nodes away: a wider window.
    let reach = if !fine.geo.ext.is_empty() { 10 } else { 4 };
    // Coarse node (xc, yc)'s window here, if it lies inside, and whether it is all clean.
    let window = |xc: usize, yc: usize| {
        let (x0, y0, x1, y1) = ((2 * xc).checked_sub(reach)?, (2 * yc).checked_sub(reach)?, 2 * xc + reach + 1, 2 * yc + reach + 1);
        (x1 <= fw && y1 <= fh).then_some(([x0, y0], [x1, y1]))
    };
    let regular = |xc: usize, yc: usize| window(xc, yc).is_some_and(|(a, b)| sat.count(a, b) as usize == (b[0] - a[0]) * (b[1] - a[1]));
    let shared = match &fine.op {
        // The finest level's: that of an open grid's interior, constrained or not.
        Operator::Fine { tau, .. } => galerkin_node(&Level::fine(Geometry::open(13, 13), *tau), 3, 3),
        _ => (0..hc * wc).find(|&c| regular(c % wc, c / wc)).map_or([0.0; 25], |c| galerkin_node(fine, c % wc, c / wc)),
    };
    let shared_scale = shared.iter().fold(0.0f64, |m, a| m.max(a.abs()));
    // On the finest level, coarse nodes whose windows are clean but for fixed nodes (linked right and down) take
    // the shared stencil less each fixed node's terms ([`fixed_terms`], from its rows of `A Q` and `A P`).
    let fixed: Vec<(usize, [[f64; 16]; 2])> = match &fine.op {
        // (In node order: `fixed_rows` finds a row's by bisection.)
        Operator::Fine { flags, .. } => (0..fw * fh)
            .filter(|&i| !fine.clean[i] && flags[fine.pidx(i % fw, i / fw)] & (bit::RIGHT | bit::DOWN | bit::FREE) == bit::RIGHT | bit::DOWN)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|f| {
                let code = |x: usize, y: usize, masked: bool| if masked && flags[fine.pidx(x, y)] & bit::FREE == 0 { [0; 4] } else { PLAIN_CODES[(y & 1) * 2 + (x & 1)] };
                (f, [false, true].map(|masked| narrow_ap_row(fine, f % fw, f / fw, |x, y| code(x, y, masked))))
            })
            .collect(),
        _ => Vec::new(),
    };
    let fixed_rows = |y0: usize, y1: usize| &fixed[fixed.partition_point(|f| f.0 < y0 * fw)..fixed.partition_point(|f| f.0 < y1 * fw)];
    // A stencil equal to the shared one up to rounding is regular (the window tests are conservative).
    let like_shared = |s: &[f64]| shared_scale > 0.0 && s.iter().zip(&shared).all(|(a, b)| (a - b).abs() <= 1e-12 * shared_scale);
    // Rows that reach past their 2 × 2 corners, or far taps here, need the wide windows.
    let wide = !fine.geo.ext.is_empty() || matches!(&fine.op, Operator::Stored { far, .. } if !far.is_empty());
    let n = if wide { WIDE } else { 5 };
    // A coarse row's stencils of their own (by column) and far taps.
    type RowOut = (Vec<(usize, [f64; 25])>, Vec<Far>);
    let build_row = |yc: usize| -> RowOut {
        let (mut own, mut far) = (Vec::new(), Vec::new());
        let irregular: Vec<usize> = (0..wc).filter(|&xc| geo.active[yc * wc + xc] && !regular(xc, yc)).collect();
        if irregular.is_empty() { return (own, far); }
        // Rows of A P for this coarse row's children, once per needed fine node: nonzeros only, in window order
        // (so the sums add as over the whole window, most of which is zero).
        let rows = fine.geo.children(yc, fh);
        let y_lo = *rows.start();
        let mut slot = vec![u32::MAX; (rows.end() - y_lo + 1) * fw];
        let (mut ap, mut nz, mut dense) = (Vec::new(), Vec::new(), Vec::new());
        let (mut acc, mut row) = (vec![0.0f64; n * n], vec![0.0f64; AP * AP]);
        // Wanted: the nodes whose windows hold clean and fixed nodes alone (these counted by column in its rows).
        let mut want = vec![false; wc];
        if let (Some(y0), false) = ((2 * yc).checked_sub(reach), fixed.is_empty()) {
            let mut cols = vec![0usize; fw + 1];
            fixed_rows(y0, (2 * yc + reach + 1).min(fh)).iter().for_each(|f| cols[f.0 % fw + 1] += 1);
            (0..fw).for_each(|x| cols[x + 1] += cols[x]);
            for &xc in &irregular {
                want[xc] = window(xc, yc).is_some_and(|(a, b)| sat.count(a, b) as usize + cols[b[0]] - cols[a[0]] == (b[0] - a[0]) * (b[1] - a[1]));
            }
        }
        let mut terms = vec![[0.0f64; 25]; if want.contains(&true) { wc } else { 0 }];
        if !terms.is_empty() {
            fixed_rows((2 * yc).saturating_sub(3), (2 * yc + 4).min(fh)).iter().for_each(|(f, ab)| fixed_terms(fw, *f, ab, yc, &want, &mut terms));
        }
        for &xc in &irregular {
            if want[xc] {
                // Every child fixed: no fine functions left, the row exactly zero.
                let s = if (shared[12] + terms[xc][12]).abs() <= 1e-9 * shared_scale { [0.0; 25] } else { std::array::from_fn(|k| shared[k] + terms[xc][k]) };
                if !like_shared(&s) { own.push((xc, s)); }
                continue;
            }
            acc.fill(0.0);
            if !wide {
                narrow_sums(fine, xc, yc, &mut slot, &mut dense, &mut acc);
            } else {
                for iy in rows.clone() {
                    for ix in fine.geo.children(xc, fw) {
                        let wi = fine.geo.weight(ix, iy, xc, yc);
                        if wi == 0.0 { continue; }
                        let k = (iy - y_lo) * fw + ix;
                        if slot[k] == u32::MAX {
                            slot[k] = ap.len() as u32;
                            let start = nz.len();
                            ap_row(fine, ix, iy, &mut row);
                            for (t, &v) in row.iter().enumerate().filter(|e| *e.1 != 0.0) {
                                nz.push(((t % AP) as isize - AP0, (t / AP) as isize - AP0, v));
                            }
                            ap.push(start..nz.len());
                        }
                        let (bx, by) = ((ix / 2) as isize - xc as isize, (iy / 2) as isize - yc as isize);
                        for &(ox, oy, v) in &nz[ap[slot[k] as usize].clone()] { acc[wide_at(bx + ox, by + oy)] += wi * v; }
                    }
                }
            }
            let (acc, far_taps) = split_taps(&acc, n);
            if far_taps.is_empty() && like_shared(&acc) { continue; }
            let p = (yc + PAD) * wpc + xc + PAD;
            for (dx, dy, a) in far_taps {
                let (qx, qy) = (xc as isize + dx, yc as isize + dy);
                // Past the level's nodes a tap only ever meets the padding's zeros.
                if (0..wc as isize).contains(&qx) && (0..hc as isize).contains(&qy) {
                    far.push((p as u32, ((qy as usize + PAD) * wpc + qx as usize + PAD) as u32, a));
                }
            }
            own.push((xc, acc));
        }
        (own, far)
    };
    let mut rows: Vec<RowOut> = vec![Default::default(); hc];
    each_row(fw * fh, &mut rows, 1, |yc, row| row[0] = build_row(yc));
    // Irregular stencils each stored once (see `DistinctStencils`), after the shared one.
    let mut ids = vec![0u32; wpc * hpc];
    let mut distinct = DistinctStencils { table: vec![shared], ..Default::default() };
    let mut far: Vec<Far> = Vec::new();
    for (yc, (own, row_far)) in rows.into_iter().enumerate() {
        for (xc, s) in own { ids[(yc + PAD) * wpc + xc + PAD] = distinct.id(s); }
        far.extend(row_far);
    }
    let table = distinct.table;
    let sums: Vec<f64> = table.iter().map(|s| s.iter().map(|a| a.abs()).sum()).collect();
    let (mut inv_diag, mut lam_max, mut clean) = (vec![0.0; wpc * hpc], 0.0f64, vec![false; wc * hc]);
    for i in (0..wc * hc).filter(|&i| geo.active[i]) {
        let p = (i / wc + PAD) * wpc + i % wc + PAD;
        let (s, far_p) = (&table[ids[p] as usize], far_of(&far, p));
        // A vanishing diagonal: the coarse node has no fine children left.
        if s[12] > 1e-300 {
            let sum = sums[ids[p] as usize] + far_p.iter().map(|e| e.2.abs()).sum::<f64>();
            inv_diag[p] = 1.0 / s[12];
            lam_max = lam_max.max(sum / s[12]);
        }
        clean[i] = ids[p] == 0 && far_p.is_empty() && geo.right[i] && geo.down[i];
    }
    let narrow: Vec<[f32; 25]> = table.iter().map(|s| s.map(|a| a as f32)).collect();
    let kind = |p: usize| if inv_diag[p] == 0.0 { RunKind::Skip } else if ids[p] == 0 { RunKind::Shared } else { RunKind::Own };
    let runs = Runs::new(wpc, wc, hc, kind);
    let fours = Fours::new(&ids, &narrow, &runs, wpc, hc);
    let op = Operator::Stored { sym: Sym::of(&table[0]), ids, table, narrow, fours, runs, far };
    Level { inv_diag_w: narrow_diag(&inv_diag), geo, wp: wpc, op, inv_diag, lam_max, clean }
}

fn narrow_diag(inv_diag: &[f64]) -> Vec<WS> {
    inv_diag.iter().map(|&d| if WS::of(d).get().is_finite() { WS::of(d) } else { 0.0 }).collect()
}

/// The stored taps of coarse stencil `(Pᵀ A P)(C, ·)`, C = (xc, yc), from the definition.
pub(crate) fn galerkin_node(fine: &Level, xc: usize, yc: usize) -> [f64; 25] {
    let (fw, fh) = (fine.geo.w, fine.geo.h);
    let mut acc = vec![0.0f64; WIDE * WIDE];
    for iy in fine.geo.children(yc, fh) {
        for ix in fine.geo.children(xc, fw) {
            let wi = fine.geo.weight(ix, iy, xc, yc);
            if wi == 0.0 { continue; }
            ap_terms(fine, ix, iy, [xc, yc], |dx, dy, a, wj| acc[wide_at(dx, dy)] += wi * a * wj);
        }
    }
    split_taps(&acc, WIDE).0
}

/// The Galerkin sums' windows where extrapolating rows meet (a level's reach `D` gives the next about `D / 2 + 3`):
/// a coarse stencil on `WIDE` × `WIDE` offsets centred on its node, a row of `A P` on `AP` × `AP` coarse nodes
/// from offset −`AP0` of `(ix / 2, iy / 2)`. Elsewhere, 5 × 5 ([`narrow_sums`]).
const WIDE: usize = 17;
const AP: usize = 14;
const AP0: isize = 6;

/// The entry of offset (dx, dy) in a coarse stencil's sums on the wide window.
#[inline]
fn wide_at(dx: isize, dy: isize) -> usize {
    let h = (WIDE / 2) as isize;
    assert!(dx.abs() <= h && dy.abs() <= h, "a coarse stencil reaching offset ({dx}, {dy})");
    ((dy + h) * WIDE as isize + dx + h) as usize
}

/// The 5 × 5 Galerkin sums of coarse node (xc, yc) into `acc` where every prolongation row sits on its 2 × 2
/// corners, from dense rows of `A P` made once per coarse row (`slot` as in [`galerkin`], into `dense`): the
/// general path's order, adding only exact zeros besides, so bit for bit its stencil.
fn narrow_sums(fine: &Level, xc: usize, yc: usize, slot: &mut [u32], dense: &mut Vec<[f64; 16]>, acc: &mut [f64]) {
    let (fw, fh, g) = (fine.geo.w, fine.geo.h, &fine.geo);
    let y_lo = (2 * yc).saturating_sub(1);
    for iy in g.children(yc, fh) {
        for ix in g.children(xc, fw) {
            let (bx, by) = (xc - ix / 2, yc - iy / 2);
            let wi = WEIGHTS[g.prow[iy * fw + ix][by * 2 + bx] as usize];
            if wi == 0.0 { continue; }
            let k = (iy - y_lo) * fw + ix;
            if slot[k] == u32::MAX {
                slot[k] = dense.len() as u32;
                dense.push(narrow_ap_row(fine, ix, iy, |x, y| g.prow[y * fw + x]));
            }
            // The row's window starts one coarse node left of and above (ix / 2, iy / 2).
            for (ky, line) in dense[slot[k] as usize].chunks_exact(4).enumerate() {
                let a = &mut acc[(ky + 1 - by) * 5 + 1 - bx..][..4];
                for (s, &v) in a.iter_mut().zip(line) {
                    *s += wi * v;
                }
            }
        }
    }
}

/// The terms of fixed node f of the finest level in the stencils of coarse row `yc` (into `terms`, by column) that
/// are wanted: where a window is clean but for fixed nodes, `P = M Q` (`Q` the plain bilinear prolongation, `M`
/// zeroing the fixed nodes' rows) and `Pᵀ A P = Qᵀ A Q − Σ_f (a_f q_fᵀ + q_f b_fᵀ)`, `q_f` row f of `Q`, `a_f` and
/// `b_f` row f of `A Q` and of `A P` (the second term drops row f of `Qᵀ A P`, the first column f of `Qᵀ A Q`,
/// which is the shared stencil there).
fn fixed_terms(fw: usize, f: usize, [a, b]: &[[f64; 16]; 2], yc: usize, want: &[bool], terms: &mut [[f64; 25]]) {
    let (wc, (fx, fy), y) = (terms.len(), (f % fw, f / fw), yc as isize);
    // Less u_c v_k at coarse node (cx, yc), k on the windows' 4 × 4 from offset −1 of (fx / 2, fy / 2).
    let mut sub = |cx: isize, k: usize, uv: f64| {
        if (0..wc as isize).contains(&cx) && want[cx as usize] {
            let (dx, dy) = ((fx / 2 + k % 4) as isize - 1 - cx, (fy / 2 + k / 4) as isize - 1 - y);
            terms[cx as usize][((dy + 2) * 5 + dx + 2) as usize] -= uv;
        }
    };
    for (s, w) in PLAIN_CODES[(fy & 1) * 2 + (fx & 1)].iter().map(|&c| WEIGHTS[c as usize]).enumerate().filter(|e| e.1 != 0.0) {
        let (qx, qy, ky) = (s & 1, s >> 1, y + 1 - (fy / 2) as isize);
        // q_f b_fᵀ in coarse row fy / 2 + qy; a_f q_fᵀ in the rows of a_f's window.
        if fy / 2 + qy == yc { b.iter().enumerate().for_each(|(k, &v)| sub((fx / 2 + qx) as isize, k, w * v)); }
        if (0..4).contains(&ky) { (0..4).for_each(|kx| sub((fx / 2 + kx) as isize - 1, (qy + 1) * 4 + qx + 1, a[ky as usize * 4 + kx] * w)); }
    }
}

/// Row `(ix, iy)` of `A P` on the 4 × 4 window from offset −1, dense, in the order of [`ap_row`], with node j's
/// row of `P` coded `codes(jx, jy)`.
fn narrow_ap_row(fine: &Level, ix: usize, iy: usize, codes: impl Fn(usize, usize) -> [u8; 4]) -> [f64; 16] {
    let row = fine.row(fine.pidx(ix, iy));
    let mut out = [0.0f64; 16];
    for (t, &a) in row.iter().enumerate().filter(|e| *e.1 != 0.0) {
        let (jx, jy) = (ix + t % 5 - 2, iy + t / 5 - 2);
        let c = codes(jx, jy);
        let (cx, cy) = (jx / 2 + 1 - ix / 2, jy / 2 + 1 - iy / 2);
        for (s, &v) in c.iter().enumerate() { out[(cy + (s >> 1)) * 4 + cx + (s & 1)] += a * WEIGHTS[v as usize]; }
    }
    out
}

/// The prolongation weights of the codes of [`Geometry::prow`] (24ths).
const WEIGHTS: [f64; 25] = {
    let (mut w, mut k) = ([0.0; 25], 0);
    while k < 25 {
        w[k] = k as f64 / 24.0;
        k += 1;
    }
    w
};

/// A summed stencil (on `n` × `n` offsets) split into its stored taps and the others (dx, dy, a).
fn split_taps(acc: &[f64], n: usize) -> ([f64; 25], Vec<(isize, isize, f64)>) {
    let (h, mut s, mut far) = ((n / 2) as isize, [0.0; 25], Vec::new());
    for (k, &a) in acc.iter().enumerate().filter(|e| *e.1 != 0.0) {
        let (dx, dy) = ((k % n) as isize - h, (k / n) as isize - h);
        if dx.abs() <= 2 && dy.abs() <= 2 && (dx.abs() < 2 || dy.abs() < 2) {
            s[((dy + 2) * 5 + dx + 2) as usize] = a;
        } else {
            far.push((dx, dy, a));
        }
    }
    (s, far)
}

/// Row `i = (ix, iy)` of `A P` into `out`: `Σ_j A_ij P_j` on the wide window's coarse nodes, row-major.
fn ap_row(fine: &Level, ix: usize, iy: usize, out: &mut [f64]) {
    out.fill(0.0);
    let n = AP as isize;
    ap_terms(fine, ix, iy, [ix / 2, iy / 2], |dx, dy, a, wj| {
        let (ox, oy) = (dx + AP0, dy + AP0);
        assert!((0..n).contains(&ox) && (0..n).contains(&oy), "a row of A P reaching past its window");
        out[(oy * n + ox) as usize] += a * wj;
    });
}

/// `f(dx, dy, a_ij, p_jc)` for each tap `a_ij` of fine row `i = (ix, iy)` and weight `p_jc` of row j of `P`,
/// (dx, dy) the offset of coarse node c from `base`.
fn ap_terms(fine: &Level, ix: usize, iy: usize, base: [usize; 2], mut f: impl FnMut(isize, isize, f64, f64)) {
    fine.taps(fine.pidx(ix, iy), |q, a| {
        let (jx, jy) = (q % fine.wp - PAD, q / fine.wp - PAD);
        let (cjx, cjy) = ((jx / 2) as isize - base[0] as isize, (jy / 2) as isize - base[1] as isize);
        fine.geo.p_row(jx, jy, |ox, oy, wj| f(cjx + ox, cjy + oy, a, wj));
    });
}

/// `coarse = Pᵀ fine_v` (restriction of a residual), in either precision.
pub(crate) fn restrict<S: Real, T: Real>(fine: &Level, coarse: &Level, v: &[[S; 2]], out: &mut [[T; 2]]) {
    let (fw, fh, wc, wpc) = (fine.geo.w, fine.geo.h, coarse.geo.w, coarse.wp);
    let (half, zero) = (T::of(0.5), [T::ZERO; 2]);
    let run = |yc: usize, orow: &mut [[T; 2]]| {
        orow.fill(zero);
        let acc = &mut orow[PAD..PAD + wc];
        let rows = (2 * yc).saturating_sub(1)..=(2 * yc + 1).min(fh - 1);
        if rows.clone().all(|iy| fine.geo.plain_rows[iy]) {
            // Full weighting. Fixed nodes need no care: `v` vanishes on them.
            for iy in rows {
                let wy = if iy == 2 * yc { T::of(1.0) } else { half };
                restrict_row(&v[fine.pidx(0, iy)..fine.pidx(0, iy) + fw], acc, wy);
            }
        } else {
            for iy in rows {
                // 1 for row 2 yc − 1, else 0.
                let sy = yc - iy / 2;
                let prow = &fine.geo.prow[iy * fw..(iy + 1) * fw];
                for ix in 0..fw {
                    let r = v[fine.pidx(ix, iy)].map(widened::<S, T>);
                    if r == zero || prow[ix][0] == EXT { continue; }
                    let cx = ix / 2;
                    for sx in 0..2 {
                        let wv = prow[ix][sy * 2 + sx];
                        if wv != 0 && cx + sx < wc {
                            let (o, wv) = (&mut acc[cx + sx], T::of(wv as f64 / 24.0));
                            *o = [o[0] + wv * r[0], o[1] + wv * r[1]];
                        }
                    }
                }
            }
        }
        // The rows reaching past their corners, wherever they sit (in the rows of the children).
        let (rows, ext) = (fine.geo.children(yc, fh), &fine.geo.ext);
        let at = |y: usize| ext.partition_point(|e| (e.0 as usize) < y * fw);
        for (i, row) in &ext[at(*rows.start())..at(*rows.end() + 1)] {
            let (ix, iy) = (*i as usize % fw, *i as usize / fw);
            let r = v[fine.pidx(ix, iy)].map(widened::<S, T>);
            let oy = yc as isize - (iy / 2) as isize;
            if r == zero || !(-1..3).contains(&oy) || fine.geo.prow[*i as usize][0] != EXT { continue; }
            for (s, &wv) in row[((oy + 1) * 4) as usize..((oy + 2) * 4) as usize].iter().enumerate().filter(|e| *e.1 != 0.0) {
                let (o, wv) = (&mut acc[ix / 2 + s - 1], T::of(wv));
                *o = [o[0] + wv * r[0], o[1] + wv * r[1]];
            }
        }
    };
    out[..PAD * wpc].fill(zero);
    each_row(fw * fh, &mut out[PAD * wpc..(PAD + coarse.geo.h) * wpc], wpc, run);
}

widest! {
    /// Full weighting of one plain fine row `vr` into the coarse row `acc`:
    /// `acc[X] += wy (v[2X] + ½ (v[2X − 1] + v[2X + 1]))`, a neighbour past either end left out.
    fn restrict_row<S: Real, T: Real>(vr: &[[S; 2]], acc: &mut [[T; 2]], wy: T) =>
    restrict_row_body {
        let fw = vr.len();
        let get = |a: [S; 2]| [T::of(a[0].get()), T::of(a[1].get())];
        let half = T::of(0.5);
        let add = |o: &mut [T; 2], l: [T; 2], c: [T; 2], r: [T; 2]| {
            let side = [l[0] + r[0], l[1] + r[1]];
            o[0] += wy * (c[0] + half * side[0]);
            o[1] += wy * (c[1] + half * side[1]);
        };
        // Coarse nodes 1..inner have both fine neighbours; the slices' lengths bound every index (no checks).
        let inner = (fw / 2).min(acc.len());
        let (head, v) = (&mut acc[..inner], &vr[..2 * inner]);
        for xc in 1..inner {
            let ix = 2 * xc;
            add(&mut head[xc], get(v[ix - 1]), get(v[ix]), get(v[ix + 1]));
        }
        // The others, a missing neighbour zero (fine node −1 wraps past the row's end).
        let at = |ix: usize| if ix < fw { get(vr[ix]) } else { [T::ZERO; 2] };
        for xc in (0..acc.len().min(1)).chain(inner.max(1)..acc.len()) {
            let ix = 2 * xc;
            add(&mut acc[xc], at(ix.wrapping_sub(1)), at(ix), at(ix + 1));
        }
    }
}

widest! {
    /// `x += α P e` on one plain fine row from coarse rows `c0` and `c1` (`odd`: halfway between them, else on
    /// `c0`), where its prolongation row `prow` is not empty.
    fn prolong_row<S: Real, T: Real>(c0: &[[S; 2]], c1: &[[S; 2]], odd: bool, prow: &[[u8; 4]], x: &mut [[T; 2]], alpha: V2) =>
    prolong_row_body {
        let fw = x.len();
        // Computed everywhere, then chosen: a branch kept the loop scalar.
        let add = |o: [T; 2], keep: bool, a: V2| {
            let new = [T::of(o[0].get() + alpha[0] * a[0]), T::of(o[1].get() + alpha[1] * a[1])];
            if keep { new } else { o }
        };
        let col = |a: [S; 2], b: [S; 2]| -> V2 {
            let (a, b) = ([a[0].get(), a[1].get()], [b[0].get(), b[1].get()]);
            if odd { [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])] } else { a }
        };
        let mid = |l: V2, r: V2| [0.5 * (l[0] + r[0]), 0.5 * (l[1] + r[1])];
        // Where 2X + 1 < fw: fine pairs (2X, 2X + 1) against coarse pairs (X, X + 1), slices of one length (no
        // checks in the loop); the rest one by one.
        let done = (fw / 2).min(c0.len().saturating_sub(1)).min(c1.len().saturating_sub(1));
        let fine = x[..2 * done].chunks_exact_mut(2).zip(prow[..2 * done].chunks_exact(2));
        let coarse = c0[..done + 1].windows(2).zip(c1[..done + 1].windows(2));
        for ((xs, ps), (a, b)) in fine.zip(coarse) {
            let (left, right) = (col(a[0], b[0]), col(a[1], b[1]));
            xs[0] = add(xs[0], ps[0] != [0; 4], left);
            xs[1] = add(xs[1], ps[1] != [0; 4], mid(left, right));
        }
        for xc in done..c0.len().min(fw.div_ceil(2)) {
            let (ix, left) = (2 * xc, col(c0[xc], c1[xc]));
            x[ix] = add(x[ix], prow[ix] != [0; 4], left);
            if ix + 1 < fw {
                x[ix + 1] = add(x[ix + 1], prow[ix + 1] != [0; 4], mid(left, col(c0[xc + 1], c1[xc + 1])));
            }
        }
    }
}

/// `fine_x += α P e` (prolongation of a coarse correction onto the unknowns), α per component.
pub(crate) fn prolong_add_scaled<S: Real, T: Real>(fine: &Level, coarse: &Level, e: &[[S; 2]], x: &mut [[T; 2]], alpha: V2) {
    let (fw, fh, wp) = (fine.geo.w, fine.geo.h, fine.wp);
    let run = |iy: usize, xrow: &mut [[T; 2]]| {
        let cy = iy / 2;
        if fine.geo.plain_rows[iy] {
            // Bilinear interpolation; fixed nodes (rows of zeros) keep their values.
            let (odd, row) = (iy & 1 == 1, |cy: usize| &e[coarse.pidx(0, cy)..coarse.pidx(0, cy) + coarse.geo.w]);
            prolong_row(row(cy), row(cy + usize::from(odd)), odd, &fine.geo.prow[iy * fw..(iy + 1) * fw], &mut xrow[PAD..PAD + fw], alpha);
            return;
        }
        for ix in 0..fw {
            let cx = ix / 2;
            let (mut acc, mut any) = ([0.0f64; 2], false);
            fine.geo.p_row(ix, iy, |ox, oy, wv| {
                let c = e[coarse.pidx((cx as isize + ox) as usize, (cy as isize + oy) as usize)].map(S::get);
                acc[0] += wv * c[0];
                acc[1] += wv * c[1];
                any = true;
            });
            if any {
                let o = &mut xrow[ix + PAD];
                *o = [T::of(o[0].get() + alpha[0] * acc[0]), T::of(o[1].get() + alpha[1] * acc[1])];
            }
        }
    };
    each_row(fw * fh, &mut x[PAD * wp..(PAD + fh) * wp], wp, run);
}

/// `f(y, row)` on each row (`wp` long) of `body`, on the pool's threads from [`PAR_MIN_NODES`] fine nodes.
fn each_row<U: Send>(fine_nodes: usize, body: &mut [U], wp: usize, f: impl Fn(usize, &mut [U]) + Sync + Send) {
    if fine_nodes >= PAR_MIN_NODES {
        body.par_chunks_mut(wp).enumerate().for_each(|(y, r)| f(y, r));
    } else {
        body.chunks_mut(wp).enumerate().for_each(|(y, r)| f(y, r));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use crate::solve::tests::{fine_level, torn_grid};

    #[test]
    fn the_wide_kernels_give_the_plain_kernels_results_bit_for_bit() {
        // Where the processor has AVX2 the stencil products run a copy compiled for it (see
        // `wide`): both copies must give the same bits, on the finest level and a Galerkin
        // level (regular runs, irregular stencils, fixed nodes), open and with a hole and a
        // cut, without and with tension, in both precisions; and the finest level's product
        // of an `f32` vector summed in `f64` (see `narrow_product_bits`).
        let mut rnd = crate::grid::tests::sequence(71);
        for (grid, tau) in [(Grid::new(67, 61), 0.0), (torn_grid(97, true, true, 5.0), 0.3)] {
            let (w, h) = (grid.width, grid.height);
            let fixed: Vec<bool> = (0..w * h).map(|_| rnd() < 0.02).collect();
            let fine = fine_level(&grid, Some(fixed), tau);
            let coarse = galerkin(&fine);
            for level in [&fine, &coarse] {
                let n = level.len_padded();
                let x: Vec<V2> = (0..n).map(|_| [rnd() - 0.5, rnd() - 0.5]).collect();
                let f: Vec<V2> = (0..n).map(|_| [rnd() - 0.5, rnd() - 0.5]).collect();
                let narrow = |v: &[V2]| -> Vec<W2> { v.iter().map(|a| [a[0] as f32, a[1] as f32]).collect() };
                same_bits(level, &x, &f);
                same_bits(level, &narrow(&x), &narrow(&f));
            }
            let x: Vec<W2> = (0..fine.len_padded()).map(|p| if fine.inv_diag[p] != 0.0 { [(rnd() - 0.5) as f32, (rnd() - 0.5) as f32] } else { [0.0; 2] }).collect();
            narrow_product_bits(&fine, &x, tau);
        }
    }

    /// The conjugate gradient keeps its search direction in `f32` and sums `A p` in `f64`
    /// from it: that must be bit for bit the `f64` product of the widened vector (and its
    /// dot product with it), so that `u += α p` and `r += α A p` move together; in the copy
    /// for the widest vectors and in the plain one.
    fn narrow_product_bits(fine: &Level, x: &[W2], tau: f64) {
        let (n, w, h) = (fine.len_padded(), fine.geo.w, fine.geo.h);
        let wide: Vec<V2> = x.iter().map(|a| [a[0] as f64, a[1] as f64]).collect();
        let (mut narrow_out, mut wide_out) = (vec![[0.0; 2]; n], vec![[0.0; 2]; n]);
        let narrow_dot = fine.fine_residual_dot_narrow(x, &mut narrow_out);
        let wide_dot = fine.residual_dot(&wide, &mut wide_out);
        assert!(narrow_out.iter().flatten().any(|&v| v != 0.0));
        let bits = |v: &[V2]| v.iter().flatten().map(|a| a.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&narrow_out), bits(&wide_out), "{w}×{h}, τ = {tau}: A p");
        assert_eq!(narrow_dot.map(f64::to_bits), wide_dot.map(f64::to_bits), "{w}×{h}, τ = {tau}: pᵀA p");
        let (wp, r0, r1) = (fine.wp, PAD, PAD + h);
        let mut plain = vec![[0.0; 2]; n];
        band_residual_body(fine, x, None, r0, 0, &mut plain[r0 * wp..r1 * wp]);
        assert_eq!(bits(&plain), bits(&narrow_out), "{w}×{h}, τ = {tau}: the plain copy");
    }

    #[test]
    fn a_second_step_from_zero_is_the_first_step_then_the_second() {
        // The fused pass against the first step's pass over the whole level and then the
        // second step, bit for bit: several bands, fixed nodes, a hole, with and without
        // tension, keeping the update or not; large enough for its bands to run on the
        // pool's threads (each with its own buffer).
        let mut rnd = crate::grid::tests::sequence(41);
        let (w, h) = (67, 61);
        assert!(w * h >= PAR_MIN_NODES);
        let grid = Grid::from_active(w, h, (0..w * h).map(|i| !((20..24).contains(&(i / w)) && (10..15).contains(&(i % w)))).collect());
        let bits = |v: &[W2]| v.iter().flatten().map(|a| a.to_bits()).collect::<Vec<_>>();
        for tau in [0.0, 0.7] {
            let fixed: Vec<bool> = (0..w * h).map(|_| rnd() < 0.05).collect();
            let level = fine_level(&grid, Some(fixed), tau);
            let len = level.len_padded();
            let mut f: Vec<W2> = (0..len).map(|_| [(rnd() - 0.5) as f32, (rnd() - 0.5) as f32]).collect();
            level.clear_padding(&mut f);
            let (inv_theta, rule) = (0.21, StepRule::Second { c1: 0.6, c2: 0.37 });
            for keep in [true, false] {
                let mut x = vec![[5.0f32; 2]; len];
                crate::solve::cycle::first_from_zero(&mut x, &f, &level.inv_diag_w, inv_theta);
                let (mut d1, mut next1) = (vec![[3.0f32; 2]; len], vec![[4.0f32; 2]; len]);
                level.smoothing_step(&x, Some(&f), &mut d1, &mut next1, rule, keep);
                let (mut d2, mut next2) = (vec![[3.0f32; 2]; len], vec![[4.0f32; 2]; len]);
                level.second_step_from_zero(&f, inv_theta, &mut d2, &mut next2, rule, keep);
                assert_eq!((bits(&next2), bits(&d2)), (bits(&next1), bits(&d1)), "tau {tau}, keep {keep}");
            }
        }
    }

    #[test]
    fn the_vector_passes_copies_match_their_plain_bodies() {
        // The smoothing step's update, the scaled maximum, the pairs' dot product and the
        // banded factor's update, by the dispatching functions (the AVX2 copy where the
        // processor has it) and by their plain bodies or definitions, bit for bit, on lengths
        // that leave remainders.
        let mut rnd = crate::grid::tests::sequence(29);
        let mut pairs = |n: usize| -> Vec<W2> { (0..n).map(|_| [(rnd() - 0.5) as f32, (rnd() - 0.5) as f32]).collect() };
        let bits = |v: &[W2]| v.iter().flatten().map(|a| a.to_bits()).collect::<Vec<_>>();
        for n in [1, 7, 64, 1003] {
            let (r, x, d0) = (pairs(n), pairs(n), pairs(n));
            let g: Vec<WS> = pairs(n).iter().map(|v| if v[0] > 0.3 { 0.0 } else { v[1] }).collect();
            let rules = [StepRule::First { inv_theta: 0.37 }, StepRule::Next { c1: 0.81, c2: -1.3 }, StepRule::Second { c1: 0.6, c2: 1.7 }];
            for rule in rules {
                for keep in [true, false] {
                    let (mut o1, mut d1, mut o2, mut d2) = (r.clone(), d0.clone(), r.clone(), d0.clone());
                    step_row(&mut o1, &mut d1, &x, &g, rule, keep);
                    step_row_body(&mut o2, &mut d2, &x, &g, rule, keep);
                    assert_eq!((bits(&o1), bits(&d1)), (bits(&o2), bits(&d2)), "{n}, {rule:?}, keep {keep}");
                    // And the update's definition, pair by pair.
                    let update = |i: usize, c: usize| match rule {
                        StepRule::First { inv_theta } => r[i][c] * g[i] * inv_theta,
                        StepRule::Next { c1, c2 } => c1 * d0[i][c] + c2 * g[i] * r[i][c],
                        StepRule::Second { c1, c2 } => c1 * x[i][c] + c2 * g[i] * r[i][c],
                    };
                    let d_def: Vec<W2> = (0..n).map(|i| if keep { [update(i, 0), update(i, 1)] } else { d0[i] }).collect();
                    let o_def: Vec<W2> = (0..n).map(|i| [x[i][0] + update(i, 0), x[i][1] + update(i, 1)]).collect();
                    assert_eq!((bits(&o1), bits(&d1)), (bits(&o_def), bits(&d_def)), "{n}, {rule:?}, keep {keep}: the definition");
                }
            }
            let diag: Vec<f64> = g.iter().map(|&v| f64::from(v).abs()).collect();
            assert_eq!(scaled_max(&r, &diag).to_bits(), scaled_max_body(&r, &diag).to_bits(), "{n}");
            assert_eq!(dot_pairs(&r, &x).map(f64::to_bits), dot_pairs_body(&r, &x).map(f64::to_bits), "{n}");
            // The banded factor's update, against its definition.
            let (l, z0): (Vec<f64>, Vec<f64>) = r.iter().map(|v| (f64::from(v[0]), f64::from(v[1]))).unzip();
            let mut z = z0.clone();
            sub_scaled(&l, 0.73, &mut z);
            assert!(z.iter().zip(&z0).zip(&l).all(|((z, z0), l)| z.to_bits() == (z0 - l * 0.73).to_bits()), "{n}");
        }
    }

    /// `f − A x` by the dispatching kernels and by their plain bodies, compared bit by bit.
    fn same_bits<T: Real>(level: &Level, x: &[[T; 2]], f: &[[T; 2]]) {
        let (n, wp, h) = (x.len(), level.wp, level.geo.h);
        let (mut wide, mut plain) = (vec![[T::ZERO; 2]; n], vec![[T::ZERO; 2]; n]);
        let (r0, r1) = (PAD, PAD + h);
        band_residual(level, x, Some(f), r0, 0, &mut wide[r0 * wp..r1 * wp]);
        band_residual_body(level, x, Some(f), r0, 0, &mut plain[r0 * wp..r1 * wp]);
        assert!(wide.iter().flatten().filter(|v| v.get() != 0.0).count() > n / 2, "most rows must be computed");
        for p in 0..n {
            for k in 0..2 {
                assert_eq!(wide[p][k].get().to_bits(), plain[p][k].get().to_bits(), "node {p}, component {k}: {:?} against {:?}", wide[p][k].get(), plain[p][k].get());
            }
        }
    }
}

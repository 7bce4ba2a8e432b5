//! The plate operator as a sparse matrix over a piece's free nodes, and the sparse products
//! the algebraic multigrid needs (`A x`, `Pᵀ`, `A B`).

use rayon::prelude::*;

/// A value of each component (Δx, Δy): both right-hand sides go through every product
/// together.
pub(crate) type V2 = [f64; 2];

/// Rows per parallel task.
const ROWS: usize = 2048;

/// A compressed-row sparse matrix.
#[derive(Clone, Debug, Default)]
pub(crate) struct Csr {
    pub rows: usize,
    pub cols: usize,
    pub start: Vec<usize>,
    pub col: Vec<u32>,
    pub val: Vec<f64>,
}

impl Csr {
    pub fn nnz(&self) -> usize {
        self.val.len()
    }

    pub fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let r = self.start[i]..self.start[i + 1];
        (&self.col[r.clone()], &self.val[r])
    }

    /// Assembles rows given as (columns, values) lists, in order.
    fn from_rows(rows: Vec<(Vec<u32>, Vec<f64>)>, cols: usize) -> Csr {
        let mut start = Vec::with_capacity(rows.len() + 1);
        start.push(0);
        for (c, _) in &rows {
            start.push(start.last().unwrap() + c.len());
        }
        let nnz = *start.last().unwrap();
        let (mut col, mut val) = (Vec::with_capacity(nnz), Vec::with_capacity(nnz));
        for (c, v) in rows {
            col.extend(c);
            val.extend(v);
        }
        Csr { rows: start.len() - 1, cols, start, col, val }
    }

    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.rows)
            .map(|i| {
                let (c, v) = self.row(i);
                c.iter().zip(v).find(|(&c, _)| c as usize == i).map_or(0.0, |(_, &v)| v)
            })
            .collect()
    }

    /// `y = A x`.
    pub fn apply(&self, x: &[V2], y: &mut [V2]) {
        y.par_chunks_mut(ROWS).enumerate().for_each(|(k, y)| {
            for (j, y) in y.iter_mut().enumerate() {
                let (c, v) = self.row(k * ROWS + j);
                let mut s = [0.0; 2];
                for (&c, &v) in c.iter().zip(v) {
                    let x = x[c as usize];
                    s[0] += v * x[0];
                    s[1] += v * x[1];
                }
                *y = s;
            }
        });
    }

    /// `r = b − A x`.
    pub fn residual(&self, b: &[V2], x: &[V2], r: &mut [V2]) {
        r.par_chunks_mut(ROWS).enumerate().for_each(|(k, r)| {
            for (j, r) in r.iter_mut().enumerate() {
                let i = k * ROWS + j;
                let (c, v) = self.row(i);
                let mut s = b[i];
                for (&c, &v) in c.iter().zip(v) {
                    let x = x[c as usize];
                    s[0] -= v * x[0];
                    s[1] -= v * x[1];
                }
                *r = s;
            }
        });
    }

    pub fn transpose(&self) -> Csr {
        let mut count = vec![0usize; self.cols + 1];
        for &c in &self.col {
            count[c as usize + 1] += 1;
        }
        for k in 0..self.cols {
            count[k + 1] += count[k];
        }
        let start = count.clone();
        let mut next = count;
        let (mut col, mut val) = (vec![0u32; self.nnz()], vec![0.0; self.nnz()]);
        for i in 0..self.rows {
            let (c, v) = self.row(i);
            for (&c, &v) in c.iter().zip(v) {
                let k = &mut next[c as usize];
                col[*k] = i as u32;
                val[*k] = v;
                *k += 1;
            }
        }
        Csr { rows: self.cols, cols: self.rows, start, col, val }
    }

    /// `self · b` (Gustavson's row-by-row product; columns of each row in ascending order).
    pub fn mul(&self, b: &Csr) -> Csr {
        let blocks: Vec<usize> = (0..self.rows).step_by(ROWS).collect();
        let parts: Vec<Vec<(Vec<u32>, Vec<f64>)>> = blocks
            .par_iter()
            .map(|&r0| {
                let mut acc = vec![0.0f64; b.cols];
                let mut seen = vec![false; b.cols];
                let mut cols: Vec<u32> = Vec::new();
                (r0..(r0 + ROWS).min(self.rows))
                    .map(|i| {
                        let (ca, va) = self.row(i);
                        for (&k, &a) in ca.iter().zip(va) {
                            let (cb, vb) = b.row(k as usize);
                            for (&j, &v) in cb.iter().zip(vb) {
                                if !seen[j as usize] {
                                    seen[j as usize] = true;
                                    cols.push(j);
                                }
                                acc[j as usize] += a * v;
                            }
                        }
                        cols.sort_unstable();
                        let vals = cols
                            .iter()
                            .map(|&j| {
                                seen[j as usize] = false;
                                std::mem::take(&mut acc[j as usize])
                            })
                            .collect();
                        (std::mem::take(&mut cols), vals)
                    })
                    .collect()
            })
            .collect();
        Csr::from_rows(parts.into_iter().flatten().collect(), b.cols)
    }
}

/// A piece's box: node `(x, y)` at `y · w + x`, its active nodes and links right and down.
pub(crate) struct BoxGrid<'a> {
    pub w: usize,
    pub h: usize,
    pub active: &'a [bool],
    pub right: &'a [bool],
    pub down: &'a [bool],
}

/// The operator of `E_plate + τ E_membrane` on the free nodes (active, not fixed), the
/// fixed nodes eliminated (their part goes to the right-hand side, [`System::rhs`]).
pub(crate) struct System {
    pub a: Csr,
    /// The box node of each unknown.
    pub node: Vec<u32>,
    /// The unknown of each box node (`u32::MAX`: fixed or inactive).
    pub dof: Vec<u32>,
}

impl System {
    pub fn new(g: &BoxGrid, fixed: &[bool], tau: f64) -> System {
        let w = g.w;
        let mut dof = vec![u32::MAX; w * g.h];
        let mut node = Vec::new();
        for i in 0..w * g.h {
            if g.active[i] && !fixed[i] {
                dof[i] = node.len() as u32;
                node.push(i as u32);
            }
        }
        let rows: Vec<(Vec<u32>, Vec<f64>)> = node
            .par_chunks(ROWS)
            .flat_map_iter(|nodes| {
                nodes.iter().map(|&p| {
                    let acc = molecule(g, p as usize, tau);
                    let (px, py) = ((p as usize % w) as isize, (p as usize / w) as isize);
                    let (mut c, mut v) = (Vec::with_capacity(13), Vec::with_capacity(13));
                    for dy in -2..=2isize {
                        for dx in -2..=2isize {
                            let a = acc[(dy + 2) as usize][(dx + 2) as usize];
                            let q = (py + dy) * w as isize + px + dx;
                            if a != 0.0 && dof[q as usize] != u32::MAX {
                                c.push(dof[q as usize]);
                                v.push(a);
                            }
                        }
                    }
                    (c, v)
                })
            })
            .collect();
        System { a: Csr::from_rows(rows, node.len()), node, dof }
    }

    /// `−A_free,fixed · u_fixed` for the fixed nodes' values `value` ((node, value) pairs).
    pub fn rhs(&self, g: &BoxGrid, value: &[(usize, V2)], tau: f64) -> Vec<V2> {
        let w = g.w as isize;
        let mut b = vec![[0.0; 2]; self.node.len()];
        // The operator is symmetric: row q's entry at p is row p's at q.
        for &(q, v) in value {
            let acc = molecule(g, q, tau);
            let (qx, qy) = ((q % g.w) as isize, (q / g.w) as isize);
            for dy in -2..=2isize {
                for dx in -2..=2isize {
                    let a = acc[(dy + 2) as usize][(dx + 2) as usize];
                    if a != 0.0 {
                        let d = self.dof[((qy + dy) * w + qx + dx) as usize];
                        if d != u32::MAX {
                            b[d as usize][0] -= a * v[0];
                            b[d as usize][1] -= a * v[1];
                        }
                    }
                }
            }
        }
        b
    }
}

/// Row `p` of the whole operator (every active node) as a 5 × 5 window around `p`:
/// `Σ_terms weight · c_p · c_q` over the energy's terms that hold `p`.
pub(crate) fn molecule(g: &BoxGrid, p: usize, tau: f64) -> [[f64; 5]; 5] {
    let (w, h) = (g.w as isize, g.h as isize);
    let (x, y) = ((p % g.w) as isize, (p / g.w) as isize);
    let at = |x: isize, y: isize| (y * w + x) as usize;
    let right = |x: isize, y: isize| x >= 0 && y >= 0 && x + 1 < w && y < h && g.right[at(x, y)];
    let down = |x: isize, y: isize| x >= 0 && y >= 0 && x < w && y + 1 < h && g.down[at(x, y)];
    let mut acc = [[0.0f64; 5]; 5];
    let mut add = |nodes: &[(isize, isize)], coef: &[f64], weight: f64| {
        let cp = nodes.iter().zip(coef).find(|(n, _)| **n == (x, y)).map(|(_, &c)| c).unwrap_or(0.0);
        for (&(qx, qy), &cq) in nodes.iter().zip(coef) {
            acc[(qy - y + 2) as usize][(qx - x + 2) as usize] += weight * cp * cq;
        }
    };
    for d in -1..=1 {
        // The horizontal triple centred at (x + d, y), the vertical one at (x, y + d).
        let c = x + d;
        if right(c - 1, y) && right(c, y) {
            add(&[(c - 1, y), (c, y), (c + 1, y)], &[1.0, -2.0, 1.0], 1.0);
        }
        let c = y + d;
        if down(x, c - 1) && down(x, c) {
            add(&[(x, c - 1), (x, c), (x, c + 1)], &[1.0, -2.0, 1.0], 1.0);
        }
    }
    for (ox, oy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let (cx, cy) = (x - ox, y - oy);
        if right(cx, cy) && down(cx, cy) && down(cx + 1, cy) && right(cx, cy + 1) {
            add(&[(cx, cy), (cx + 1, cy), (cx, cy + 1), (cx + 1, cy + 1)], &[1.0, -1.0, -1.0, 1.0], 2.0);
        }
    }
    if tau > 0.0 {
        for (a, b, linked) in [((x, y), (x + 1, y), right(x, y)), ((x - 1, y), (x, y), right(x - 1, y)), ((x, y), (x, y + 1), down(x, y)), ((x, y - 1), (x, y), down(x, y - 1))] {
            if linked {
                add(&[a, b], &[1.0, -1.0], tau);
            }
        }
    }
    acc
}

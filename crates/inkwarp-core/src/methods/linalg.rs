//! A dense linear solver for the thin-plate system: LU factorisation with partial
//! pivoting in f64, the trailing update spread over threads for large systems.

use rayon::prelude::*;

/// A zero (or negligible) pivot: the matrix is singular to working precision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SingularPivot {
    pub row: usize,
    pub pivot: f64,
}

/// Rows below this count are eliminated on one thread (the fork/join cost would
/// dominate).
const PARALLEL_ROWS: usize = 128;

/// Solves `A X = B` for the `n × n` matrix `a` (row-major) and `nrhs` right-hand sides
/// `b` (row-major `n × nrhs`), by Gaussian elimination with partial pivoting (the LU
/// factorisation `PA = LU` applied to `B` as it is formed) and back substitution.
/// Consumes both; returns `X` row-major `n × nrhs`.
///
/// A pivot smaller than `1e-13 ×` the largest entry of `a` in absolute value is
/// reported as singular.
pub(crate) fn solve_dense(a: Vec<f64>, n: usize, b: Vec<f64>, nrhs: usize) -> Result<Vec<f64>, SingularPivot> {
    assert_eq!(a.len(), n * n);
    assert_eq!(b.len(), n * nrhs);
    let cols = n + nrhs;
    // The augmented matrix [A | B], so that one elimination sweep updates both.
    let mut m = vec![0.0; n * cols];
    for i in 0..n {
        m[i * cols..i * cols + n].copy_from_slice(&a[i * n..(i + 1) * n]);
        m[i * cols + n..(i + 1) * cols].copy_from_slice(&b[i * nrhs..(i + 1) * nrhs]);
    }
    let scale = a.iter().fold(0.0f64, |acc, v| acc.max(v.abs()));
    let tiny = 1e-13 * scale.max(f64::MIN_POSITIVE);

    for k in 0..n {
        if crate::interrupt::requested() {
            // The caller sees the flag and reports the stop, not this pivot.
            return Err(SingularPivot { row: k, pivot: f64::NAN });
        }
        // Partial pivoting: the largest entry of column k at or below the diagonal.
        let column = (k..n).map(|i| (i, m[i * cols + k].abs()));
        let (p, pv) = column.fold((k, -1.0), |best, cur| if cur.1 > best.1 { cur } else { best });
        if pv.is_nan() || pv <= tiny {
            return Err(SingularPivot { row: k, pivot: pv.max(0.0) });
        }
        if p != k {
            let (top, bottom) = m.split_at_mut(p * cols);
            top[k * cols..(k + 1) * cols].swap_with_slice(&mut bottom[..cols]);
        }
        let (head, tail) = m.split_at_mut((k + 1) * cols);
        let pivot_row = &head[k * cols..];
        let diag = pivot_row[k];
        let eliminate = |row: &mut [f64]| {
            let l = row[k] / diag;
            if l != 0.0 {
                row[k] = 0.0;
                for (r, &pr) in row[k + 1..].iter_mut().zip(&pivot_row[k + 1..]) {
                    *r -= l * pr;
                }
            }
        };
        if n - k > PARALLEL_ROWS {
            tail.par_chunks_mut(cols).with_min_len(16).for_each(eliminate);
        } else {
            tail.chunks_mut(cols).for_each(eliminate);
        }
    }

    // Back substitution on the upper-triangular system.
    let mut x = vec![0.0; n * nrhs];
    for i in (0..n).rev() {
        let row = &m[i * cols..(i + 1) * cols];
        for r in 0..nrhs {
            let mut s = row[n + r];
            for j in i + 1..n {
                s -= row[j] * x[j * nrhs + r];
            }
            x[i * nrhs + r] = s / row[i];
        }
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_system_that_needs_pivoting() {
        // The leading entry is zero: without row exchanges elimination fails.
        let a = vec![0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 2.0, 0.0, 3.0];
        let x_true = [1.0, -2.0, 0.5, 3.0, 0.25, -1.0];
        let mut b = vec![0.0; 6];
        for i in 0..3 {
            for r in 0..2 {
                b[i * 2 + r] = (0..3).map(|j| a[i * 3 + j] * x_true[j * 2 + r]).sum();
            }
        }
        let x = solve_dense(a, 3, b, 2).unwrap();
        for (got, want) in x.iter().zip(x_true) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn large_system_matches_its_right_hand_side() {
        // Big enough for the threaded update: a diagonally weighted pseudo-random matrix.
        let n = 300;
        let mut state = 12345u64;
        let mut rnd = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a: Vec<f64> = (0..n * n).map(|_| rnd()).collect();
        let x_true: Vec<f64> = (0..n).map(|_| rnd()).collect();
        let b: Vec<f64> = (0..n).map(|i| (0..n).map(|j| a[i * n + j] * x_true[j]).sum()).collect();
        let x = solve_dense(a, n, b, 1).unwrap();
        let err = x.iter().zip(&x_true).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
        assert!(err < 1e-8, "max error {err}");
    }

    #[test]
    fn singular_matrix_is_reported() {
        let a = vec![1.0, 2.0, 2.0, 4.0];
        let err = solve_dense(a, 2, vec![1.0, 2.0], 1).unwrap_err();
        assert_eq!(err.row, 1);
    }
}

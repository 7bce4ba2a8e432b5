//! Displacement fields on the rest image (DESIGN §2).

use rayon::prelude::*;

/// Pixels per parallel task of the conversions to and from interleaved storage.
const BLOCK: usize = 1 << 15;

/// A displacement field defined on the rest (original) image.
///
/// Planar storage, row-major: pixel `(x, y)` (column `x`, row `y`) moves to
/// `(x + dx[y * width + x], y + dy[y * width + x])`. At the Python boundary it becomes
/// a float32 `(H, W, 2)` array with `[..., 0] = Δx` and `[..., 1] = Δy`.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    pub width: usize,
    pub height: usize,
    pub dx: Vec<f32>,
    pub dy: Vec<f32>,
}

/// A field read in place: the core's planar [`Field`], or interleaved `(H, W, 2)` storage
/// (`[Δx, Δy]` per pixel, row-major: a numpy array's), so that a solve's start given
/// either way is read without a copy ([`crate::solve::Solver::solve`]).
#[derive(Clone, Copy, Debug)]
pub enum FieldView<'a> {
    Planar(&'a Field),
    Interleaved { width: usize, height: usize, data: &'a [f32] },
}

impl<'a> From<&'a Field> for FieldView<'a> {
    fn from(field: &'a Field) -> Self { FieldView::Planar(field) }
}

impl<'a> FieldView<'a> {
    /// Pixels per row.
    pub fn width(&self) -> usize {
        match *self { FieldView::Planar(f) => f.width, FieldView::Interleaved { width, .. } => width }
    }

    /// Rows.
    pub fn height(&self) -> usize {
        match *self { FieldView::Planar(f) => f.height, FieldView::Interleaved { height, .. } => height }
    }

    /// How many values it holds: two for each of its `width × height` pixels when
    /// consistent.
    pub fn values(&self) -> usize {
        match *self {
            FieldView::Planar(f) => f.dx.len() + f.dy.len(),
            FieldView::Interleaved { data, .. } => data.len(),
        }
    }

    /// Whether it holds two values for each of its `width × height` pixels (for planar
    /// storage, one in each plane).
    pub fn is_consistent(&self) -> bool {
        let n = self.width() * self.height();
        match *self {
            FieldView::Planar(f) => f.dx.len() == n && f.dy.len() == n,
            FieldView::Interleaved { data, .. } => data.len() == 2 * n,
        }
    }

    /// The displacement of pixel `i` (row-major index).
    pub fn at_index(&self, i: usize) -> [f32; 2] {
        match *self {
            FieldView::Planar(f) => [f.dx[i], f.dy[i]],
            FieldView::Interleaved { data, .. } => [data[2 * i], data[2 * i + 1]],
        }
    }

    /// Whether every value is finite (blocks in parallel).
    pub fn all_finite(&self) -> bool {
        // Without early exits within a block, so that the pass vectorises.
        let finite = |v: &[f32]| v.iter().fold(true, |all, x| all & x.is_finite());
        match *self {
            FieldView::Planar(f) => f.dx.par_chunks(BLOCK).zip(f.dy.par_chunks(BLOCK)).all(|(a, b)| finite(a) & finite(b)),
            FieldView::Interleaved { data, .. } => data.par_chunks(2 * BLOCK).all(finite),
        }
    }

    /// As a planar field: borrowed, or copied from interleaved storage.
    pub fn to_field(&self) -> std::borrow::Cow<'a, Field> {
        match *self {
            FieldView::Planar(f) => std::borrow::Cow::Borrowed(f),
            FieldView::Interleaved { width, height, data } => std::borrow::Cow::Owned(Field::from_interleaved(width, height, data)),
        }
    }
}

impl Field {
    /// The identity field (no pixel moves).
    pub fn zeros(width: usize, height: usize) -> Self {
        Field { width, height, dx: vec![0.0; width * height], dy: vec![0.0; width * height] }
    }

    /// The displacement of node `(x, y)`.
    pub fn at(&self, x: usize, y: usize) -> [f32; 2] {
        let i = y * self.width + x;
        [self.dx[i], self.dy[i]]
    }

    /// Interleaved `(H, W, 2)` storage: `[Δx, Δy]` per pixel, row-major.
    pub fn to_interleaved(&self) -> Vec<f32> {
        // Collected in parallel straight into a vector of the final size, with no pass to
        // zero it first (every solve from Python returns its field this way).
        let pairs: Vec<[f32; 2]> = self.dx.par_iter().zip(&self.dy).with_min_len(BLOCK).map(|(&x, &y)| [x, y]).collect();
        pairs.into_flattened()
    }

    /// Builds a field from interleaved `(H, W, 2)` storage.
    ///
    /// # Panics
    /// If `data.len() != width * height * 2`.
    pub fn from_interleaved(width: usize, height: usize, data: &[f32]) -> Self {
        assert_eq!(data.len(), width * height * 2, "interleaved field has the wrong length");
        let mut f = Field::zeros(width, height);
        f.dx.par_chunks_mut(BLOCK).zip(f.dy.par_chunks_mut(BLOCK)).zip(data.par_chunks(2 * BLOCK)).for_each(|((dx, dy), d)| {
            for ((x, y), c) in dx.iter_mut().zip(dy.iter_mut()).zip(d.chunks_exact(2)) {
                *x = c[0];
                *y = c[1];
            }
        });
        f
    }

    /// The field at every pixel of a `width × height` image, interpolated bilinearly from
    /// `coarse`, its values on every `step`-th pixel: coarse node `(X, Y)` sits on pixel
    /// `(min(step·X, width − 1), min(step·Y, height − 1))`, the layout of the solver's
    /// `grid_step`. For surfaces without holes (a quick preview of a smooth interpolant);
    /// the solver's own upsampling respects the grid's pieces.
    ///
    /// ```
    /// use inkwarp_core::Field;
    /// // 2 × 2 coarse nodes over a 5 × 3 image: a ramp in x is kept exactly.
    /// let coarse = Field { width: 2, height: 2, dx: vec![0.0, 4.0, 0.0, 4.0], dy: vec![1.0; 4] };
    /// let f = Field::from_coarse(&coarse, 4, 5, 3);
    /// assert_eq!(f.at(1, 1), [1.0, 1.0]);
    /// assert_eq!(f.at(4, 2), [4.0, 1.0]);
    /// ```
    ///
    /// # Panics
    /// If `coarse` is not `((width − 1) / step + 1) × ((height − 1) / step + 1)` (rounding
    /// up) or `step == 0`.
    pub fn from_coarse(coarse: &Field, step: usize, width: usize, height: usize) -> Field {
        let nodes = |n: usize| if n == 0 { 0 } else { (n - 1).div_ceil(step) + 1 };
        assert!(
            step > 0 && coarse.width == nodes(width) && coarse.height == nodes(height),
            "a {}×{} coarse field does not cover {width}×{height} pixels every {step}",
            coarse.width,
            coarse.height
        );
        // Per pixel along an axis: the coarse node before it and the weight of the next.
        let taps = |n: usize, nc: usize| -> Vec<(usize, f32)> {
            (0..n)
                .map(|x| {
                    if nc < 2 { return (0, 0.0); }
                    let x0 = (x / step).min(nc - 2);
                    let (a, b) = (x0 * step, ((x0 + 1) * step).min(n - 1));
                    (x0, (x - a) as f32 / (b - a) as f32)
                })
                .collect()
        };
        let (cols, rows) = (taps(width, coarse.width), taps(height, coarse.height));
        let mut f = Field::zeros(width, height);
        let wc = coarse.width;
        for (y, &(y0, ty)) in rows.iter().enumerate() {
            let y1 = (y0 + 1).min(coarse.height - 1);
            for (x, &(x0, tx)) in cols.iter().enumerate() {
                let x1 = (x0 + 1).min(wc - 1);
                let mix = |v: &[f32]| {
                    let top = v[y0 * wc + x0] * (1.0 - tx) + v[y0 * wc + x1] * tx;
                    let bottom = v[y1 * wc + x0] * (1.0 - tx) + v[y1 * wc + x1] * tx;
                    top * (1.0 - ty) + bottom * ty
                };
                f.dx[y * width + x] = mix(&coarse.dx);
                f.dy[y * width + x] = mix(&coarse.dy);
            }
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn from_coarse_keeps_the_nodes_and_affine_fields() {
        // 11 × 7 pixels every 4: nodes at x = 0, 4, 8, 10 and y = 0, 4, 6.
        let (w, h, s) = (11, 7, 4);
        let pos = |i: usize, n: usize| (i * s).min(n - 1) as f32;
        let coarse = Field {
            width: 4,
            height: 3,
            dx: (0..12).map(|k| 0.5 * pos(k % 4, w) - 2.0 * pos(k / 4, h) + 3.0).collect(),
            dy: (0..12).map(|k| (k * k) as f32).collect(),
        };
        let f = Field::from_coarse(&coarse, s, w, h);
        for y in 0..h {
            for x in 0..w {
                let exact = 0.5 * x as f32 - 2.0 * y as f32 + 3.0;
                assert!((f.at(x, y)[0] - exact).abs() < 1e-5, "({x}, {y})");
            }
        }
        for k in 0..12 {
            let (x, y) = (pos(k % 4, w) as usize, pos(k / 4, h) as usize);
            assert_eq!(f.at(x, y)[1], (k * k) as f32);
        }
        // One coarse node: a constant field.
        let one = Field { width: 1, height: 1, dx: vec![2.0], dy: vec![-1.0] };
        assert!(Field::from_coarse(&one, 8, 1, 1).dx == vec![2.0]);
    }

    #[test]
    fn interleaved_storage_round_trips_across_blocks() {
        // More pixels than one block and not a whole number of them.
        let (w, h) = (300, 200);
        let f = Field { width: w, height: h, dx: (0..w * h).map(|i| i as f32).collect(), dy: (0..w * h).map(|i| -(i as f32) - 0.5).collect() };
        let data = f.to_interleaved();
        assert_eq!(data.len(), 2 * w * h);
        for i in [0, 1, super::BLOCK - 1, super::BLOCK, w * h - 1] {
            assert_eq!((data[2 * i], data[2 * i + 1]), (f.dx[i], f.dy[i]));
        }
        assert_eq!(Field::from_interleaved(w, h, &data), f);
    }
}

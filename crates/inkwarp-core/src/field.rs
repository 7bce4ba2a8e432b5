//! Displacement fields on the rest image (DESIGN §2).

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
        self.dx.iter().zip(&self.dy).flat_map(|(&x, &y)| [x, y]).collect()
    }

    /// Builds a field from interleaved `(H, W, 2)` storage.
    ///
    /// # Panics
    /// If `data.len() != width * height * 2`.
    pub fn from_interleaved(width: usize, height: usize, data: &[f32]) -> Self {
        assert_eq!(data.len(), width * height * 2, "interleaved field has the wrong length");
        Field {
            width,
            height,
            dx: data.iter().step_by(2).copied().collect(),
            dy: data.iter().skip(1).step_by(2).copied().collect(),
        }
    }
}

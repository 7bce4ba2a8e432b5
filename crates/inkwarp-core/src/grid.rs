//! The solve domain: active nodes from the continuity matte, 4-neighbour links broken by
//! inactive nodes and by cuts, nearest-node constraints (DESIGN §4).

/// Active nodes and links of a `width × height` node grid.
#[derive(Clone, Debug, PartialEq)]
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
    pub fn new(width: usize, height: usize) -> Self {
        Self::from_active(width, height, vec![true; width * height])
    }

    /// A grid from a continuity matte (`nonzero = connected`), row-major `width × height`.
    ///
    /// # Panics
    /// If `matte.len() != width * height`.
    pub fn from_matte(width: usize, height: usize, matte: &[u8]) -> Self {
        assert_eq!(matte.len(), width * height, "matte has the wrong size");
        Self::from_active(width, height, matte.iter().map(|&m| m != 0).collect())
    }

    fn from_active(width: usize, height: usize, active: Vec<bool>) -> Self {
        let n = width * height;
        let mut link_right = vec![false; n];
        let mut link_down = vec![false; n];
        for y in 0..height {
            for x in 0..width {
                let i = y * width + x;
                if !active[i] {
                    continue;
                }
                link_right[i] = x + 1 < width && active[i + 1];
                link_down[i] = y + 1 < height && active[i + width];
            }
        }
        Grid { width, height, active, link_right, link_down }
    }

    /// Index of node `(x, y)`.
    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize {
        y * self.width + x
    }
}
